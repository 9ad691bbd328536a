// kdrt-bench's pieces, kept apart from main() so the tests can check them: options, the leaf-size
// stop rule, the benchmark scene and its rays, and the CSV rows.
#pragma once

#include "kdrt.h"
#include "mesh_io.hpp"
#include "reference.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace kb {

enum class RayKind { primary, diffuse, random };

struct Options {
    unsigned width = 800, height = 800;
    unsigned threads = 1;
    unsigned repeat = 1;
    std::vector<uint32_t> leaf_sizes;  // the original's list unless --leaf-sizes
    std::string builder = "median";
    RayKind rays = RayKind::primary;
    std::string output;                // "" means stdout
    bool compare_embree = false;
    unsigned subdivide = 0;
    size_t reference_rays = 20000;     // rays checked against the reference per frame; 0: all
    std::vector<std::string> inputs;   // mesh files or folders
    bool help = false;
};

// The original benchmark's leaf sizes: 0 (no tree), 1, 2, 3, 4, 6, 8, ..., 768, 1024.
std::vector<uint32_t> default_leaf_sizes();
// The original's stop rule: sizes in order up to and including the first at or above the mesh's
// triangle count (larger leaves would all be the same single leaf).
std::vector<uint32_t> leaf_sizes_for(const std::vector<uint32_t> &sizes, uint32_t mesh_triangles);

// false with a message naming the bad argument.
bool parse_options(int argc, const char *const *argv, Options &out, std::string &error);
std::string usage();

// The benchmark frame: the mesh centred and scaled so its larger side across the view spans
// [-1, 1], a back-wall quad (two triangles, last in the buffers) behind it, and a pinhole camera
// on +z looking down -z whose view just holds [-1.05, 1.05] at z = 0.
struct Scene {
    std::string name;                  // upper-cased file stem: NEFERTITI, UNIT_SPHERE_N, ...
    kt::Mesh geometry;                 // mesh + wall, what the tree is built over
    uint32_t mesh_triangles = 0;       // the mesh alone (the stop rule counts these)
    float eye[3] = {0, 0, 0};
    float tan_half_fov = 0;
};
Scene make_scene(const kt::Mesh &mesh, const std::string &name);

// One ray per pixel centre (row-major), or the bounces or random rays built from them.
// tree is used for the diffuse rays' primary hits.
std::vector<kdrt_ray> make_rays(const Scene &scene, RayKind kind, unsigned width, unsigned height,
                                const kdrt_tree *tree, uint32_t seed);

// Sorted, distinct, seeded choice of `count` indices out of `total` (all of them if count is 0
// or at least total).
std::vector<size_t> reference_sample(size_t total, size_t count, uint32_t seed);

// Rays of the sample whose answer contradicts the reference (kt::check_hit's "wrong"): a miss
// where a triangle is surely hit, a hit the ray cannot make, a t off the reference's, or a
// farther triangle where a nearer one is surely hit. refs[k] belongs to rays[sample[k]].
size_t count_mismatches(const kt::Oracle &oracle, const std::vector<kt::Reference> &refs,
                        const std::vector<size_t> &sample, const std::vector<kdrt_ray> &rays,
                        const std::vector<kdrt_hit> &hits);

struct Row {
    std::string mesh;
    int max_leaf_size = 0;             // -1 on Embree rows: not a kd-tree
    double trace_ms = 0, build_ms = 0;
    std::string builder;
    uint32_t triangles = 0;
    size_t rays = 0;
    bool has_tree_stats = false;       // Embree rows leave the tree columns empty
    kdrt_tree_stats stats{};
    size_t mismatches = 0, reference_rays = 0;
};
std::string csv_header();
std::string csv_row(const Row &row);

}  // namespace kb
