// The brute-force double-precision reference every kdrt answer is checked against, by the tests
// and by kdrt-bench's Mismatches column.
#pragma once

#include "kdrt.h"
#include "common/mesh_io.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace oracle {

struct Reference {
    bool sure_hit = false;          // some triangle is hit well inside its edges and the range
    double sure_t = 0;              // nearest such hit
    uint32_t sure_triangle = KDRT_INVALID_ID;
};

// Brute force in double precision over every triangle. A triangle is "surely" hit when its
// barycentrics clear its edges by kEdgeMargin (more for small triangles seen from afar, where the
// float test's barycentrics are less accurate); it is "possibly" hit when they are within that
// margin of them. Hits near an edge may go either way in single precision, so the check
// below accepts either answer for them, and counts how often that happened.
class Oracle {
public:
    static constexpr double kEdgeMargin = 1e-5;
    static constexpr double kRelativeT = 1e-5;  // |t - t_ref| <= kRelativeT * (t_ref + scene size / |dir|)
    // Moeller-Trumbore's t is a quotient by det = dir . (e1 x e2); its float rounding error grows
    // with the condition number |dir| |e1| |e2| / |det| = 1 / (cos(ray, normal) sin(e1, e2)).
    // kRelativeT (~170 float ulps) covers condition numbers up to kWellConditioned; beyond that
    // (grazing rays, slivers) the tolerance grows in proportion.
    static constexpr double kWellConditioned = 40;

    explicit Oracle(const common::Mesh &mesh);
    Reference trace(const kdrt_ray &ray) const;
    // t at which the ray meets the triangle's plane inside the barycentric margin and the range
    // (both widened by their tolerances, so t may be a hair below 0), or NaN.
    double possible_t(const kdrt_ray &ray, uint32_t triangle) const;
    // True when the ray lies exactly in the triangle's plane (parallel to it and through it, in
    // double precision), its line meets the triangle, and `t` is where the ray is within the
    // triangle's bounding box: what kdrt.h promises of such a hit (see there).
    bool in_plane_contact(const kdrt_ray &ray, uint32_t triangle, double t) const;
    // True when kdrt's watertight test, rounding as it does, may report this hit: it moves the
    // corners to the ray's origin and shears them so the ray runs along an axis, in float, each
    // coordinate within a few roundings of its terms (which, for corners far from the origin,
    // can be far more than the triangle is wide), then decides exactly. True when some such
    // rounding puts the ray in the triangle and t is what the test then computes: a convex
    // combination of the corners' distances along the ray where the sheared triangle is
    // degenerate within the rounding (a ray within rounding of the triangle's plane), else the
    // exact t within the rounding's effect on it.
    bool rounding_contact(const kdrt_ray &ray, uint32_t triangle, double t) const;
    // The t a kdrt hit on this triangle reported as kdrt_t should be near: possible_t(), or
    // kdrt_t itself for an in-plane or rounding contact; NaN when no such hit is possible. What
    // every check of a kdrt hit asks.
    double expected_t(const kdrt_ray &ray, uint32_t triangle, double kdrt_t) const;
    // Tolerance on t for a well-conditioned hit, and for a hit on a given triangle.
    double t_tolerance(const kdrt_ray &ray, double t) const;
    double t_tolerance(const kdrt_ray &ray, double t, uint32_t triangle) const;

private:
    std::vector<double> tri_;  // per triangle: p0, e1, e2 (9 doubles)
    // Per triangle, one array each (so the rejection test vectorises): a ball holding it.
    // Padded to whole blocks with balls of radius^2 -1, which every line misses.
    static constexpr size_t kBallBlock = 256;
    std::vector<double> ball_x_, ball_y_, ball_z_, ball_r2_;
    // The balls lie in Morton order of their centres; order_[k] is ball k's triangle.
    std::vector<uint32_t> order_;
    // Per block of kBallBlock balls (neighbours, in that order): a ball holding them, so that a
    // line that misses it skips them all.
    std::vector<double> block_x_, block_y_, block_z_, block_r2_;
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

// Reference for every ray, on all cores.
std::vector<Reference> reference_all(const Oracle &oracle, const std::vector<kdrt_ray> &rays);

}  // namespace oracle
