// Shared by the tests: generated meshes, the shared mesh folder, random rays, and the checks
// against the brute-force double-precision reference (bench/oracle/reference.hpp, which kdrt-bench
// uses for its Mismatches column too).
#pragma once

#include "kdrt.h"
#include "common/mesh_io.hpp"
#include "common/random.hpp"
#include "oracle/reference.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace kt {

// Generated scenes (deterministic for a seed).
common::Mesh random_soup(uint32_t triangles, uint32_t seed);                  // triangles of size ~1 in a 10^3 box
common::Mesh grid(uint32_t nx, uint32_t ny, uint32_t seed);                   // indexed height field over integer x, y
common::Mesh sphere(uint32_t rings, uint32_t segments, double radius);         // closed, indexed, centred at the origin
common::Mesh translated(const common::Mesh &mesh, double dx, double dy, double dz);
common::Mesh as_soup(const common::Mesh &indexed);                                     // same triangles, one vertex per corner

// KDRT_MESH_DIR if that folder exists, else "" (the caller skips with a message).
std::string shared_mesh_dir();
// Every mesh file under shared_mesh_dir()'s seed/ and common/, sorted; empty when absent.
std::vector<std::string> shared_mesh_files();

// A ray from (ox, oy, oz) along (dx, dy, dz) over [tmin, tmax].
kdrt_ray ray_of(float ox, float oy, float oz, float dx, float dy, float dz, float tmin = 0.0f,
                float tmax = std::numeric_limits<float>::infinity());
// Same hit or miss with equal t, u, v (-0 equals +0); on a miss only the triangle is specified.
bool same_hit(const kdrt_hit &a, const kdrt_hit &b);

// Random rays for a scene box: half start inside the box with a uniform direction, half start
// outside it and aim at a uniform point inside; some carry a finite tmin or tmax.
std::vector<kdrt_ray> random_rays(const kdrt_aabb &box, size_t count, uint32_t seed);

// A uniformly distributed unit direction, rounded to float.
void random_direction(common::Rng &rng, float d[3]);

// kdrt_tree_node()'s description of node; REQUIREs success.
kdrt_node_info node_info(const kdrt_tree *tree, uint32_t node);

// Traces rays through tree on all cores (threads share the const tree), returning hits in order.
std::vector<kdrt_hit> trace_all(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays);

// kdrt_occluded() for every ray, on all cores (1: occluded).
std::vector<unsigned char> occluded_all(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays);

// Owns a built tree: kdrt_tree_free() when it goes.
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

// A builder under test: the median builder, or the SAH builder at one quality.
struct Builder {
    kdrt_builder builder;
    kdrt_build_quality quality;
    const char *name;  // "median", "sah-fast", "sah-medium", "sah-high"
    void apply(kdrt_build_options &o) const { o.builder = builder, o.quality = quality; }
};
// The SAH builder at each quality, and every builder: what the suites build.
constexpr Builder kSahBuilders[] = {{KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_FAST, "sah-fast"},
                                    {KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_MEDIUM, "sah-medium"},
                                    {KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_HIGH, "sah-high"}};
constexpr Builder kBuilders[] = {{KDRT_BUILDER_MEDIAN, KDRT_BUILD_QUALITY_DEFAULT, "median"}, kSahBuilders[0],
                                 kSahBuilders[1], kSahBuilders[2]};

// A tree of `mesh` built with kdrt_default_build_options() but for the leaf size, builder and
// flags (kdrt_build_flags); the builder defaults to the library's (KDRT_BUILDER_DEFAULT).
// REQUIREs success.
TreePtr build(const common::Mesh &mesh, uint32_t max_leaf_size, kdrt_builder builder = KDRT_BUILDER_DEFAULT);
TreePtr build(const common::Mesh &mesh, uint32_t max_leaf_size, const Builder &builder, uint32_t flags = 0);

// b is a's tree with every coordinate multiplied by scale (a power of two, or 1): the same
// statistics, nodes, splits and references, in the same order, and the same SAH cost. FAILs with
// the first node or reference that differs.
void check_same_shape(const kdrt_tree *a, const kdrt_tree *b, double scale = 1.0);

// Reports that the running test cannot run here (no mesh folder, say) and why; the test returns
// right after. It prints "kdrt test skipped: WHY", which tests/CMakeLists.txt makes ctest show as
// skipped, not passed (SKIP_REGULAR_EXPRESSION).
void skip_test(const std::string &why);

// How many rays the reference suites trace: 100,000, or what KDRT_TEST_RAYS says.
size_t reference_ray_count();
// How many points, boxes or balls the closest-point and overlap suites draw for a check of count
// at the default KDRT_TEST_RAYS (100,000): in proportion to reference_ray_count() (the sanitizer
// build's 20,000: a fifth), never under a fifth.
size_t drawn_count(size_t count);

// An allocator (kdrt_allocator) counting its calls, for "allocates nothing" checks.
struct CallCounter {
    size_t calls = 0, frees = 0;
    kdrt_allocator hooks();
};

// How many the shared meshes' reference suite traces a mesh: what KDRT_TEST_MESH_RAYS says, else
// reference_ray_count(). CI's sanitizer build gives it fewer than the others, in the same ctest run.
size_t shared_mesh_ray_count();
// The most triangles a shared mesh may have for that suite, and the ropes' check of every shared
// mesh (test_cells.cpp), to build it: what KDRT_TEST_MESH_TRIANGLES says, else no limit (0).
// The scalar copy of that suite and CI's sanitizer build check the smaller meshes only.
size_t shared_mesh_max_triangles();

// The leaf sizes the reference suites build; 0 (no tree: every triangle tested) comes first.
constexpr uint32_t kLeafSizes[] = {0, 1, 2, 4, 8, 16, 64};
// The leaf sizes they build with the SAH builder too.
constexpr uint32_t kSahLeafSizes[] = {1, 4, 16};

// The reference suites' check of one scene, with ray_count random_rays(seed) over its box, for
// every leaf size in kLeafSizes (median builder) and kSahLeafSizes (SAH builder):
//  (a) kdrt_intersect() agrees with the oracle on every ray, and few rays are ambiguous;
//  (b) it returns bit for bit what leaf size 0 returns (the header's tie-breaking promise);
//  (c) kdrt_occluded() reports a hit exactly when kdrt_intersect() finds one.
// Leaf size 0 (every triangle for every ray) traces only the first brute_force_rays() rays, so
// (b) and (c) hold on those at leaf size 0; every other tree answers every ray for (a) to (c).
// Fails with CHECKs naming the leaf size and the first bad ray; WARNs a line of counts per leaf
// size so the log shows exact / ambiguous / wrong for every scene.
void check_scene(const common::Mesh &mesh, size_t ray_count, uint32_t seed);

// How many of ray_count rays leaf size 0 traces on a mesh of `triangles`: all of them while that
// takes at most kBruteForceTests triangle tests, else as many as fit, at least 2,000; budget and
// floor scale with ray_count / 100,000, so that KDRT_TEST_RAYS shortens this as it shortens the
// rest (the floor not below 100 rays).
constexpr double kBruteForceTests = 1e8;
size_t brute_force_rays(size_t ray_count, uint32_t triangles);

}  // namespace kt
