// Ray sets where single-precision ray tracing goes wrong if it can, and the counters that say how
// often it did. Shared by the hard-case tests and kdrt-bench --accuracy, so the figures the bench
// publishes come from the very rays the tests hold to zero.
#pragma once

#include "kdrt.h"
#include "mesh_io.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace kt {

// Closed surfaces (every edge shared by exactly two triangles): generated spheres, meshes with
// integer coordinates, so aims are exact, and the closed meshes of ../shared/meshes when present.
std::vector<Mesh> closed_meshes(bool include_shared);

// Rays that must hit: each starts outside the closed mesh's box, or at a point inside the mesh,
// and is aimed exactly at one of its vertices or at a point on one of its shared edges (so the
// ray crosses the surface there). A miss is a leak.
std::vector<kdrt_ray> rays_at_vertices_and_edges(const Mesh &closed, size_t count, uint64_t seed);

// The hard placements of the tests as ray sets over their own small scenes: rays in split planes,
// axis-parallel rays, rays parallel to a face, grazing rays under 1 degree to skinny triangles,
// needle and tiny triangles, coplanar overlapping triangles. Every answer is checked against the
// double-precision oracle (kt::Oracle).
struct HardSet {
    std::string name;
    Mesh mesh;
    std::vector<kdrt_ray> rays;
};
std::vector<HardSet> hard_sets(size_t rays_per_set, uint64_t seed);

// `mesh` moved by `offset` along (1, 1, 1) and scaled by `scale` about its own centre first.
Mesh translated(const Mesh &mesh, double offset, double scale);

// Error counts of one tree over one ray set.
struct ErrorCounts {
    size_t rays = 0;
    size_t leaks = 0;       // must-hit rays that missed
    size_t false_hits = 0;  // hits where the oracle says the ray surely misses that triangle
    size_t self_hits = 0;   // spawned rays that hit the triangle they leave
    size_t mismatches = 0;  // any disagreement with the oracle (includes false hits)
};

// Leaks: rays of rays_at_vertices_and_edges() that kdrt_intersect() says miss.
ErrorCounts count_leaks(const kdrt_tree *tree, const std::vector<kdrt_ray> &must_hit);

// Self-hits: for every ray that hits, kdrt_spawn_ray() a reflected ray and a ray continuing
// through the surface, and count those whose nearest hit is the triangle they leave.
ErrorCounts count_self_hits(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays);

}  // namespace kt
