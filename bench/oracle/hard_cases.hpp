// Ray sets where single-precision ray tracing goes wrong if it can, and the counters that say how
// often it did. Shared by the hard-case tests and kdrt-bench --accuracy, so the figures the bench
// publishes come from the very rays the tests hold to zero. Everything is deterministic for a seed.
#pragma once

#include "kdrt.h"
#include "common/mesh_io.hpp"
#include "oracle/reference.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace oracle {

// Closed surfaces (every edge shared by exactly two triangles, see is_closed): generated spheres
// (float coordinates), meshes with small integer coordinates (so aims at their vertices and at
// dyadic points of their edges are exact), and, when include_shared is true, the meshes of
// ../shared/meshes (KDRT_MESH_DIR, seed/ and common/) that pass is_closed, largest last. Loading
// those takes a few seconds; files that are missing or open are skipped silently.
std::vector<common::Mesh> closed_meshes(bool include_shared);

// A closed UV sphere centred at the origin: single-vertex poles, `rings` bands of `segments`
// quads (two triangles each); integer: every coordinate rounded to a whole number.
common::Mesh uv_sphere(uint32_t rings, uint32_t segments, double radius, bool integer);

// Meshes that drive a kd-tree builder to its worst, `triangles` triangles each, deterministic for
// a seed; `kind` is one of hostile_kinds(): "fan" (a flat disk of triangles round one shared
// vertex: every plane near the centre cuts most of them), "cone" (the same fan with its centre
// lifted), "slivers" (needles 1e-3 thick across the whole unit cube, half along x and half along
// y, crossing each other), "overlapping" (triangles about 0.3 across anywhere in the unit cube)
// and "identical" (one triangle, many times); or "soup" (small random triangles filling the unit
// cube), not hostile, only a big input for kdrt-bench. A soup; named "hostile_KIND".
std::vector<std::string> hostile_kinds();
common::Mesh hostile_mesh(const std::string &kind, uint32_t triangles, uint64_t seed);

// True when every edge, with vertices matched by equal coordinates (as the watertight test
// matches them), belongs to exactly two triangles and no triangle has zero area. Otherwise false,
// with the reason in *why when given.
bool is_closed(const common::Mesh &mesh, std::string *why = nullptr);

// Rays that must hit: each is aimed at one of the closed mesh's vertices or at a point on one of
// its edges (exactly for integer meshes; else the float nearest such a point) and starts either
// at a point well inside the mesh, or outside its box on the line from such an inside point
// through the target, beyond the target. Either way the ray has to cross the surface (from the
// inside it must get out; from outside it passes the target and then the inside point), so a miss
// is a leak. tmin = 0, tmax = infinity, dir = target - origin (the target is at t = 1).
// Inside points are found by a double-precision parity test and are kept 1e-4 of the box's
// diagonal (integer meshes: 0.25 and integer coordinates) away from every triangle.
std::vector<kdrt_ray> rays_at_vertices_and_edges(const common::Mesh &closed, size_t count, uint64_t seed);

// The hard placements of the tests as ray sets over their own small scenes, about rays_per_set
// rays each: "split_planes_grid" / "split_planes_soup" (rays lying in every plane the median
// builder can split at, i.e. every triangle centroid coordinate, and in every vertex coordinate
// plane, with +0 and -0 across it, and rays crossing those planes from a point on them),
// "axis_parallel" (axis-aligned rays with +-0 components on lattices through a grid's vertices and
// edges and over a sphere), "parallel_to_face" (rays exactly parallel to integer triangles, lifted
// 2^-20 to 1/64 of the normal off their plane), "in_plane" (the same, lying exactly in the plane:
// they touch the triangle along a segment or not at all, and the oracle, det == 0, calls both a
// miss), "grazing_skinny" (rays 0.1 to 1 degree off the plane of skinny
// triangles, aimed inside them and at their edges), "needles_tiny" (needle triangles and
// triangles down to 1e-6 across), "coplanar_overlap" (stacks of coplanar overlapping triangles,
// including the same triangle with rotated and reversed corners). Every answer is to be checked
// against the double-precision oracle (oracle::Oracle; count_mismatches).
struct HardSet {
    std::string name;
    common::Mesh mesh;
    std::vector<kdrt_ray> rays;
};
std::vector<HardSet> hard_sets(size_t rays_per_set, uint64_t seed);

// `mesh` scaled by `scale` about the centre of its box, then moved by `offset` along (1, 1, 1),
// rounded to float. Far out, keep the scene large against a float ulp there (at 1e7 the ulp is 1):
// scale by about offset * 1e-4 so its triangles stay triangles.
common::Mesh translated(const common::Mesh &mesh, double offset, double scale);

// Error counts of one tree over one ray set.
struct ErrorCounts {
    size_t rays = 0;
    size_t leaks = 0;       // must-hit rays that missed
    size_t false_hits = 0;  // hits where the oracle says the ray surely misses that triangle
    size_t self_hits = 0;   // spawned rays that hit the triangle they leave
    size_t mismatches = 0;  // any disagreement with the oracle (includes false hits)
    std::string first;      // a description of the first counted error, "" when none
};

// Leaks: rays of rays_at_vertices_and_edges() that kdrt_intersect() says miss. Fills rays, leaks.
// Runs on all cores.
ErrorCounts count_leaks(const kdrt_tree *tree, const std::vector<kdrt_ray> &must_hit);

// How a secondary ray's origin is placed: kdrt_spawn_ray() (offset off the surface), or the
// naive org + t * dir with no offset (the comparison that shows self-hits are real).
enum class Spawn { kdrt, naive };

// Secondary rays: for every ray that hits, four rays from the hit: reflected, continuing through
// the surface, and two grazing ones leaving at 0.5 degrees to the surface on either side; in the
// order of the rays they come from. `from` is the triangle they leave, `primary` the ray's index.
struct SpawnedRay {
    kdrt_ray ray;
    uint32_t from;
    size_t primary;
};
std::vector<SpawnedRay> spawn_rays(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, Spawn spawn = Spawn::kdrt);

// Self-hits: the spawn_rays() whose nearest hit is the triangle they leave (a plane is met once,
// so any such hit is a self-hit). Fills rays (spawned rays) and self_hits. Runs on all cores.
ErrorCounts count_self_hits(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, Spawn spawn = Spawn::kdrt);

// Oracle disagreements: traces every ray, checks it with check_hit against refs (from
// reference_all(oracle, rays), computed once per ray set and reused across trees). Fills rays,
// mismatches (check_hit's wrong) and false_hits; the hits and the tally go to *hits / *tally when
// given.
ErrorCounts count_mismatches(const kdrt_tree *tree, const Oracle &oracle, const std::vector<Reference> &refs,
                             const std::vector<kdrt_ray> &rays, std::vector<kdrt_hit> *hits = nullptr,
                             Agreement *tally = nullptr);

}  // namespace oracle
