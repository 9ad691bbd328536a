// Shared by the tests: generated meshes, mesh files through Assimp, random rays, and the
// brute-force double-precision reference that every query is checked against.
#pragma once

#include "kdrt.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace kt {

struct Mesh {
    std::string name;
    std::vector<float> positions;   // packed x, y, z
    std::vector<uint32_t> indices;  // 3 per triangle; empty: a soup (triangle i = vertices 3i..3i+2)

    uint32_t vertex_count() const { return uint32_t(positions.size() / 3); }
    uint32_t triangle_count() const { return uint32_t(indices.empty() ? positions.size() / 9 : indices.size() / 3); }
    kdrt_triangles view() const;  // borrows this mesh's vectors
    void corners(uint32_t triangle, double p[3][3]) const;
};

// Generated scenes (deterministic for a seed).
Mesh random_soup(uint32_t triangles, uint32_t seed);                  // triangles of size ~1 in a 10^3 box
Mesh grid(uint32_t nx, uint32_t ny, uint32_t seed);                   // indexed height field over integer x, y
Mesh sphere(uint32_t rings, uint32_t segments, double radius);         // closed, indexed, centred at the origin
Mesh translated(const Mesh &mesh, double dx, double dy, double dz);
Mesh as_soup(const Mesh &indexed);                                     // same triangles, one vertex per corner

// Any file Assimp reads (OFF, OBJ, PLY, STL, glTF), all its meshes joined, polygons triangulated.
bool load_mesh(const std::string &path, Mesh &out, std::string &error);
// KDRT_MESH_DIR if that folder exists, else "" (the caller skips with a message).
std::string shared_mesh_dir();
// Every mesh file under shared_mesh_dir()'s seed/ and common/, sorted; empty when absent.
std::vector<std::string> shared_mesh_files();

// Random rays for a scene box: half start inside the box with a uniform direction, half start
// outside it and aim at a uniform point inside; some carry a finite tmin or tmax.
std::vector<kdrt_ray> random_rays(const kdrt_aabb &box, size_t count, uint32_t seed);

struct Reference {
    bool sure_hit = false;          // some triangle is hit well inside its edges and the range
    double sure_t = 0;              // nearest such hit
    uint32_t sure_triangle = KDRT_INVALID_ID;
};

// Brute force in double precision over every triangle. A triangle is "surely" hit when its
// barycentrics clear its edges by kEdgeMargin; it is "possibly" hit when they are within
// kEdgeMargin of them. Hits near an edge may go either way in single precision, so the check
// below accepts either answer for them, and counts how often that happened.
class Oracle {
public:
    static constexpr double kEdgeMargin = 1e-5;
    static constexpr double kRelativeT = 1e-5;  // |t - t_ref| <= kRelativeT * (t_ref + scene size / |dir|)

    explicit Oracle(const Mesh &mesh);
    Reference trace(const kdrt_ray &ray) const;
    // t at which the ray meets the triangle's plane inside the barycentric margin, or -1.
    double possible_t(const kdrt_ray &ray, uint32_t triangle) const;
    double t_tolerance(const kdrt_ray &ray, double t) const;

private:
    std::vector<double> tri_;  // per triangle: p0, e1, e2 (9 doubles)
    double scene_size_ = 1;
};

struct Agreement {
    size_t rays = 0;
    size_t exact = 0;       // same hit or miss, same triangle, t within tolerance
    size_t ambiguous = 0;   // accepted: a near-edge or equal-distance case either answer fits
    size_t wrong = 0;       // contradicts the reference
    std::string first_wrong; // description of the first wrong ray
};

// Checks one kdrt answer (a miss when h.triangle is KDRT_INVALID_ID) against the reference the
// oracle computed for that ray, and tallies it.
void check_hit(const Oracle &oracle, const Reference &ref, const kdrt_ray &ray, const kdrt_hit &h, Agreement &tally);

// Traces rays through tree on all cores (threads share the const tree), returning hits in order.
std::vector<kdrt_hit> trace_all(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays);
// Reference for every ray, on all cores.
std::vector<Reference> reference_all(const Oracle &oracle, const std::vector<kdrt_ray> &rays);

// Builds with the given leaf size (other options default); REQUIREs success.
struct TreePtr {
    kdrt_tree *tree = nullptr;
    TreePtr() = default;
    explicit TreePtr(kdrt_tree *t) : tree(t) {}
    TreePtr(TreePtr &&o) noexcept : tree(o.tree) { o.tree = nullptr; }
    TreePtr &operator=(TreePtr &&o) noexcept { std::swap(tree, o.tree); return *this; }
    TreePtr(const TreePtr &) = delete;
    TreePtr &operator=(const TreePtr &) = delete;
    ~TreePtr() { kdrt_tree_free(tree); }
    kdrt_tree *get() const { return tree; }
};
TreePtr build(const Mesh &mesh, uint32_t max_leaf_size);

// How many rays the reference suites trace: 100,000, or what KDRT_TEST_RAYS says.
size_t reference_ray_count();

}  // namespace kt
