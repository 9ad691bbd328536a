// kdrt-bench --points: closest-point and overlap queries (bench/README.md, "Closest point and
// overlap"). The seeded point sets, the double-precision brute force the answers are checked
// against, and the CSV rows; main.cpp times kdrt and Embree on them.
#pragma once

#include "common/mesh_io.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace kb {

// Where the query points lie: near the surface (a point of a random triangle moved along its
// normal by up to 1% of the mesh box's diagonal, either way), anywhere inside the mesh's box
// (uniform), or far outside it (2 to 10 diagonals from the box's centre, uniform directions).
enum class PointKind { surface, inside, outside };
const char *point_kind_name(PointKind kind);  // "surface", "inside", "outside"
constexpr PointKind kPointKinds[] = {PointKind::surface, PointKind::inside, PointKind::outside};

// count seeded points of the kind around mesh, x, y, z each.
std::vector<float> make_points(const common::Mesh &mesh, PointKind kind, size_t count, uint64_t seed);

// The diagonal of mesh's box, in double.
double mesh_diagonal(const common::Mesh &mesh);

// The distance from p to the triangle (a, b, c), all in double (Ericson's regions, Real-Time
// Collision Detection 5.1.5).
double point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3]);

// Whether the triangle with corners c (floats, widened) has zero area as kdrt's build decides it:
// the edges' cross product, in double, exactly 0. kdrt leaves those out of its trees, so the
// brute forces below leave them out too.
bool zero_area(const double c[3][3]);

// The brute force: the distance from p to the nearest triangle of mesh (zero-area ones left
// out), every triangle in double.
double brute_closest_distance(const common::Mesh &mesh, const float p[3]);

// The brute force of an overlap query: the triangles of mesh (zero-area ones left out) within
// radius of center, in double.
uint64_t brute_sphere_count(const common::Mesh &mesh, const float center[3], float radius);

// A distance d disagrees with the reference ref when |d - ref| exceeds kDistanceTolerance times
// (ref + the mesh's diagonal): 2^-20, about 8 float ulps of the mesh's size.
constexpr double kDistanceTolerance = 9.5367431640625e-07;
inline double distance_error(double d, double ref, double diagonal) { return (d > ref ? d - ref : ref - d) / (ref + diagonal); }

// One row of the --points CSV.
struct PointsRow {
    std::string mesh;
    uint32_t triangles = 0;
    std::string query;       // closest, box, sphere
    std::string kind;        // closest: the PointKind; box, sphere: surface (their centres')
    double size = 0;         // box, sphere: the box's edge or the ball's diameter over the mesh box's (per axis for the box)
    size_t queries = 0;
    double kdrt_ms = 0, embree_ms = 0;  // medians of the repetitions; embree_ms 0: not measured
    double ratio = 0;                   // embree_ms / kdrt_ms: above 1, kdrt is faster
    // The same passes' CPU time of the querying thread (CLOCK_THREAD_CPUTIME_ID), medians: on a
    // shared machine, the time without the other programs' turns on the core.
    double kdrt_cpu_ms = 0, embree_cpu_ms = 0, cpu_ratio = 0;
    uint64_t found = 0;                 // closest: points with an answer; box, sphere: triangles found
    size_t reference = 0;               // queries checked against the brute force
    size_t kdrt_mismatches = 0, embree_mismatches = 0;
    double kdrt_max_error = 0, embree_max_error = 0;  // the largest distance_error() seen
    unsigned repeat = 0;
};
std::string points_csv_header();
std::string points_csv_row(const PointsRow &row);

// The CPU time of the calling thread, in milliseconds.
double thread_cpu_ms();

}  // namespace kb
