// libFuzzer target: the closest-point and overlap queries (kdrt_closest_point, kdrt_overlap_box,
// kdrt_overlap_sphere and their scene forms) on a small tree, the tree of leaf size 0 over the
// same triangles, and a scene of them as a mesh and the tree as an instance.
// The mesh: up to 12 triangles, their corners on a grid of quarters (shared planes, edges and
// vertices) scaled by 2^-100, 2^-66, 1, 2^66 or 2^100, sometimes a little off it (slivers, near
// misses), sometimes any floats; any builder,
// quality, leaf size and kernel. The instance's transform: identity, a translation, a non-uniform
// scale, a mirror, a shear, a quarter turn or a mix, all of them dyadic, so the world's corners
// are exact. The queries: points, boxes and balls on the same grid (vertices, points of edges,
// split planes), or of any floats (NaN, infinite, inverted, flat, negative and NaN radii); any
// max_distance; any mask; a callback that stops after some triangles or runs a query itself.
// Checked, always: refusals exactly where kdrt.h says (a NaN or infinite point or centre, a NaN
// or negative max_distance or radius, a NaN bound); every tree answers as leaf size 0 does, bit
// for bit (closest point) and as the same set (overlap); no triangle reported twice; the count
// is the callback's calls, the stopping one included; the closest triangle is the lowest index
// (geometry ID) among those with its very corners; its point lies in its box; queries allocate
// nothing. On the grid (where point_oracle.hpp's brute force is exact): the box sets equal the
// brute force's; there, or with coordinates within 2^28 of each other (its distances exact but
// for the last roundings): the ball sets agree with it wherever a triangle is farther from the
// sphere than the closest-point bound, and the distance is within the bound (CLOSEST POINT AND
// OVERLAP) of the true one, the triangle named a nearest one within it; for the scene, against
// every world triangle.
#include "kdrt.h"
#include "fuzz_support.hpp"
#include "../point_oracle.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace {

using fuzz::Heap;
using oracle::Tri;

struct Mesh {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    kdrt_triangles view() const {
        kdrt_triangles v{};
        v.positions = positions.empty() ? nullptr : positions.data();
        v.vertex_count = uint32_t(positions.size() / 3);
        v.indices = indices.empty() ? nullptr : indices.data();
        v.triangle_count = uint32_t(indices.size() / 3);
        return v;
    }
    Tri triangle(uint32_t i) const {
        Tri t;
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) t.p[k][a] = positions[3 * size_t(indices[3 * size_t(i) + size_t(k)]) + size_t(a)];
        return t;
    }
};

// True when every corner is finite and the edges' cross product in double is not exactly zero:
// a triangle kdrt keeps (kdrt__zero_area's test, operation for operation).
bool kept(const Tri &t) {
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a)
            if (!std::isfinite(t.p[k][a])) return false;
    double e1[3], e2[3];
    for (int a = 0; a < 3; ++a) e1[a] = double(t.p[1][a]) - t.p[0][a], e2[a] = double(t.p[2][a]) - t.p[0][a];
    const double n0 = e1[1] * e2[2] - e1[2] * e2[1], n1 = e1[2] * e2[0] - e1[0] * e2[2], n2 = e1[0] * e2[1] - e1[1] * e2[0];
    return !(n0 == 0.0 && n1 == 0.0 && n2 == 0.0);
}

bool same_corners(const Tri &a, const Tri &b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Coordinates on the grid: k / 4 for k in [-8, 8] (times the scale), or any float.
float grid_coordinate(FuzzedDataProvider &in, float scale) { return float(in.ConsumeIntegralInRange<int>(-8, 8)) * 0.25f * scale; }

// A multiple of 1/64 (times scale) within 64 of 0, as the grid's points and the points of its
// edges are: where the oracle's sums of products are exact.
bool on_grid(float x, float scale) {
    const double k = double(x) / double(scale) * 64;
    return std::isfinite(x) && std::fabs(k) <= 4096 && k == std::floor(k);
}

struct Input {
    bool grid = true;  // every coordinate (mesh and queries) on the scaled grid: the oracle is exact
    float scale = 1;
};

float coordinate(FuzzedDataProvider &in, Input &input) {
    switch (in.ConsumeIntegralInRange<int>(0, 15)) {
    case 0: input.grid = false; return fuzz::pick_float(in);
    case 1:  // off the grid by a little (slivers, near misses): the oracle's distances stay exact
        input.grid = false;
        return grid_coordinate(in, input.scale) * (1 + float(in.ConsumeIntegralInRange<int>(-4096, 4096)) * 0x1p-20f) +
               float(in.ConsumeIntegralInRange<int>(-64, 64)) * 0x1p-12f * input.scale;
    default: return grid_coordinate(in, input.scale);
    }
}

Mesh make_mesh(FuzzedDataProvider &in, Input &input) {
    Mesh m;
    const uint32_t vertices = in.ConsumeIntegralInRange<uint32_t>(3, 10), triangles = in.ConsumeIntegralInRange<uint32_t>(1, 12);
    for (uint32_t i = 0; i < 3 * vertices; ++i) m.positions.push_back(coordinate(in, input));
    for (uint32_t i = 0; i < 3 * triangles; ++i) m.indices.push_back(in.ConsumeIntegralInRange<uint32_t>(0, vertices - 1));
    return m;
}

kdrt_build_options make_options(FuzzedDataProvider &in) {
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = in.ConsumeBool() ? KDRT_BUILDER_SAH : KDRT_BUILDER_MEDIAN;
    o.quality = kdrt_build_quality(in.ConsumeIntegralInRange<int>(0, 3));
    static const uint32_t leaves[] = {1, 2, 4, 8};
    o.max_leaf_size = leaves[in.ConsumeIntegralInRange<int>(0, 3)];
    const int kernel = in.ConsumeIntegralInRange<int>(0, 2);
    o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES | (kernel == 0 ? uint32_t(KDRT_BUILD_SCALAR_KERNEL) : 0u) |
              (kernel == 1 ? uint32_t(KDRT_BUILD_AVX2_KERNEL) : 0u);
    return o;
}

// A point for a query: a vertex, a point of an edge (quarters along it), a point on a split
// plane of tree, a grid point, or any floats.
void make_point(FuzzedDataProvider &in, Input &input, const Mesh &mesh, const kdrt_tree *tree, float p[3]) {
    const size_t vertices = mesh.positions.size() / 3;
    switch (in.ConsumeIntegralInRange<int>(0, 5)) {
    case 0: {
        const size_t v = in.ConsumeIntegralInRange<size_t>(0, vertices - 1);
        for (int a = 0; a < 3; ++a) p[a] = mesh.positions[3 * v + size_t(a)];
        break;
    }
    case 1: {  // on an edge: exact on the grid (a quarter of a difference of grid points)
        const size_t v = in.ConsumeIntegralInRange<size_t>(0, vertices - 1), w = in.ConsumeIntegralInRange<size_t>(0, vertices - 1);
        const float s = float(in.ConsumeIntegralInRange<int>(0, 4)) * 0.25f;
        for (int a = 0; a < 3; ++a)
            p[a] = mesh.positions[3 * v + size_t(a)] + s * (mesh.positions[3 * w + size_t(a)] - mesh.positions[3 * v + size_t(a)]);
        break;
    }
    case 2: {  // on a split plane
        for (int a = 0; a < 3; ++a) p[a] = grid_coordinate(in, input.scale);
        kdrt_node_info info;
        const uint32_t nodes = kdrt_tree_node_count(tree);
        if (nodes && kdrt_tree_node(tree, in.ConsumeIntegralInRange<uint32_t>(0, nodes - 1), &info) == KDRT_SUCCESS &&
            !info.is_leaf) {
            p[info.axis] = info.split;
            input.grid = input.grid && on_grid(info.split, input.scale);
        }
        break;
    }
    case 3:
        for (int a = 0; a < 3; ++a) p[a] = coordinate(in, input);
        break;
    default:
        for (int a = 0; a < 3; ++a) p[a] = grid_coordinate(in, input.scale);
        break;
    }
    for (int a = 0; a < 3; ++a) input.grid = input.grid && std::isfinite(p[a]);
}

// The transforms: dyadic, so the world's corners are exact.
void make_transform(FuzzedDataProvider &in, float m[12]) {
    static const float forms[][12] = {
        {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0},
        {1, 0, 0, 0.75f, 0, 1, 0, -1.25f, 0, 0, 1, 2},
        {2, 0, 0, 0, 0, 0.5f, 0, 0.25f, 0, 0, 4, 0},   // non-uniform scale
        {-1, 0, 0, 0.5f, 0, 1, 0, 0, 0, 0, 1, 0},      // mirror
        {1, 0.5f, 0, 0, 0, 1, 0.25f, 0, 0, 0, 1, -1},  // shears
        {0, -1, 0, 1, 1, 0, 0, 0, 0, 0, 1, 0},         // a quarter turn about z
        {0, 0, -2, 0, 0.5f, 0.5f, 0, 0.75f, 1, 0, 0.25f, 0},  // a mix with a mirror
    };
    std::memcpy(m, forms[in.ConsumeIntegralInRange<int>(0, 6)], 12 * sizeof(float));
}

// A triangle of the scene as its queries see it.
struct WorldTri {
    uint32_t geometry, triangle, instance, mask;
    Tri world;
};

// True when the nonzero coordinates of tris and q span at most 2^28 in magnitude: the
// differences then have at most 53 bits and their products at most 106, exact in quadruple
// precision, so the oracle's distances (and corners in a ball) are right but for its last
// roundings. (Its box test, with products of three, needs the grid.)
bool tame(const std::vector<WorldTri> &tris, const float q[3]) {
    int lo = 1000, hi = -1000;
    auto see = [&](float x) {
        if (!std::isfinite(x)) lo = -1000, hi = 1000;
        else if (x != 0) {
            int e;
            std::frexp(x, &e);
            lo = std::min(lo, e), hi = std::max(hi, e);
        }
    };
    for (const WorldTri &t : tris)
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) see(t.world.p[k][a]);
    for (int a = 0; a < 3; ++a) see(q[a]);
    return hi - lo <= 28;
}

// What an overlap query reported; stop_after 0: never stop; reenter: run a closest-point query
// from inside the callback.
struct Collected {
    std::vector<kdrt_overlap> found;
    size_t stop_after = 0;
    const kdrt_tree *reenter = nullptr;
    const float *point = nullptr;
};
int collect(void *user, const kdrt_overlap *f) {
    Collected *c = static_cast<Collected *>(user);
    c->found.push_back(*f);
    if (c->reenter) {
        kdrt_closest inner;
        FUZZ_CHECK(kdrt_closest_point(c->reenter, c->point, INFINITY, &inner) == KDRT_SUCCESS, "a query inside the callback failed");
    }
    return c->stop_after == 0 || c->found.size() < c->stop_after;
}

uint64_t key(uint32_t geometry, uint32_t triangle) { return uint64_t(geometry) << 32 | triangle; }

std::string text(const float p[3]) {
    char s[128];
    std::snprintf(s, sizeof s, "(%a, %a, %a)", p[0], p[1], p[2]);
    return s;
}

// The closest-point answer c for q over tris (the triangles the query sees), against the
// oracle when exact (grid), and its sanity always.
void check_closest(const std::vector<WorldTri> &tris, const float q[3], float max_distance, const kdrt_closest &c, bool grid,
                   const char *what) {
    const WorldTri *got = nullptr;
    for (const WorldTri &t : tris)
        if (t.geometry == c.geometry && t.triangle == c.triangle) got = &t;
    if (c.triangle == KDRT_INVALID_ID) {
        FUZZ_CHECK(c.distance == INFINITY && c.instance == KDRT_INVALID_ID, "%s: no triangle, yet a distance %a", what, c.distance);
    } else {
        FUZZ_CHECK(got != nullptr, "%s: triangle %u of geometry %u is not one the query sees", what, c.triangle, c.geometry);
        FUZZ_CHECK(c.instance == got->instance, "%s: instance %u, not %u", what, c.instance, got->instance);
        FUZZ_CHECK(c.distance <= max_distance, "%s: distance %a beyond max_distance %a", what, c.distance, max_distance);
        FUZZ_CHECK(c.distance >= 0, "%s: distance %a", what, c.distance);
        FUZZ_CHECK(c.u >= 0 && c.v >= 0 && c.u + c.v <= 1.0f + 1e-6f, "%s: barycentrics %a %a on %u/%u %s %s %s at %a", what, c.u,
                   c.v, c.geometry, c.triangle, text(got->world.p[0]).c_str(), text(got->world.p[1]).c_str(),
                   text(got->world.p[2]).c_str(), c.distance);
        for (int a = 0; a < 3; ++a) {
            const float lo = std::min({got->world.p[0][a], got->world.p[1][a], got->world.p[2][a]});
            const float hi = std::max({got->world.p[0][a], got->world.p[1][a], got->world.p[2][a]});
            FUZZ_CHECK(c.point[a] >= lo && c.point[a] <= hi, "%s: the point %s outside its triangle's box", what, text(c.point).c_str());
        }
        // Ties: no triangle before it in (geometry, triangle) order has its very corners.
        for (const WorldTri &t : tris)
            FUZZ_CHECK(!(key(t.geometry, t.triangle) < key(c.geometry, c.triangle) && same_corners(t.world, got->world)),
                       "%s: %u/%u chosen over %u/%u, the same corners", what, c.geometry, c.triangle, t.geometry, t.triangle);
    }
    if (!grid && !tame(tris, q)) return;
    // The brute force: the true nearest (exact sums, but for the last roundings).
    const WorldTri *best = nullptr;
    oracle::Real best_d2 = -1;
    for (const WorldTri &t : tris) {
        const oracle::Real d2 = oracle::distance2(t.world, q);
        if (!best || d2 < best_d2) best = &t, best_d2 = d2;
    }
    if (!best) {
        FUZZ_CHECK(c.triangle == KDRT_INVALID_ID, "%s: a triangle where there is none", what);
        return;
    }
    const double truth = std::sqrt((long double)best_d2);
    const double reach = std::max(oracle::reach(best->world, q), got ? oracle::reach(got->world, q) : 0.0);
    const double bound = oracle::kRelative * truth + oracle::kReach * reach;
    if (c.triangle == KDRT_INVALID_ID) {
        // Nothing within max_distance: the truth lies beyond it (by at most the bound).
        FUZZ_CHECK(truth + bound >= double(max_distance), "%s: nothing found, yet %u/%u at %.17g within %a", what, best->geometry,
                   best->triangle, truth, max_distance);
        return;
    }
    FUZZ_CHECK(std::fabs(double(c.distance) - truth) <= bound, "%s: point %s: distance %.9g to %u/%u, truly %.17g to %u/%u (bound %.3g)",
               what, text(q).c_str(), double(c.distance), c.geometry, c.triangle, truth, best->geometry, best->triangle, bound);
    FUZZ_CHECK(oracle::distance(got->world, q) <= truth + 2 * oracle::kReach * reach, "%s: %u/%u is not a nearest triangle", what,
               c.geometry, c.triangle);
    // max_distance below the truth by more than the bound finds nothing: checked by the caller.
}

// An overlap query's reports as sorted keys, each checked once and against the mask.
std::vector<uint64_t> keys_of(const Collected &c, const char *what) {
    std::vector<uint64_t> keys;
    for (const kdrt_overlap &f : c.found) keys.push_back(key(f.geometry, f.triangle));
    std::sort(keys.begin(), keys.end());
    FUZZ_CHECK(std::adjacent_find(keys.begin(), keys.end()) == keys.end(), "%s: a triangle reported twice", what);
    return keys;
}

// Box or ball against the brute force over tris (grid only); want_all: the box's exact set.
void check_overlap(const std::vector<WorldTri> &tris, const std::vector<uint64_t> &got, bool sphere, const kdrt_aabb &box,
                   const float centre[3], float radius, const char *what) {
    if (!sphere) {
        std::vector<uint64_t> want;
        float lo[3], hi[3];
        bool empty = false;
        for (int a = 0; a < 3; ++a) {
            empty = empty || !(box.min[a] <= box.max[a]) || box.min[a] == INFINITY || box.max[a] == -INFINITY;
            lo[a] = std::max(box.min[a], -std::numeric_limits<float>::max());
            hi[a] = std::min(box.max[a], std::numeric_limits<float>::max());
        }
        if (!empty)
            for (const WorldTri &t : tris)
                if (oracle::meets_box(t.world, lo, hi)) want.push_back(key(t.geometry, t.triangle));
        std::sort(want.begin(), want.end());
        if (got != want) {
            std::fprintf(stderr, "%s: box (%a %a %a) - (%a %a %a): %zu reported, %zu meet it\n", what, box.min[0], box.min[1], box.min[2],
                         box.max[0], box.max[1], box.max[2], got.size(), want.size());
            for (uint64_t k : got) std::fprintf(stderr, "  reported %u/%u\n", unsigned(k >> 32), unsigned(k & 0xFFFFFFFFu));
            for (uint64_t k : want) std::fprintf(stderr, "  meets    %u/%u\n", unsigned(k >> 32), unsigned(k & 0xFFFFFFFFu));
            FUZZ_CHECK(false, "%s: the box's set is not the brute force's", what);
        }
        return;
    }
    for (const WorldTri &t : tris) {
        const oracle::Real r2 = oracle::Real(radius) * oracle::Real(radius);
        bool corner = false;
        for (int k = 0; k < 3; ++k) {
            oracle::Real d2 = 0;
            for (int a = 0; a < 3; ++a) d2 += (oracle::Real(t.world.p[k][a]) - centre[a]) * (oracle::Real(t.world.p[k][a]) - centre[a]);
            corner = corner || d2 <= r2;
        }
        const double d = oracle::distance(t.world, centre), band = oracle::kReach * oracle::reach(t.world, centre);
        const bool in = std::binary_search(got.begin(), got.end(), key(t.geometry, t.triangle));
        if (corner || radius == INFINITY || d < double(radius) - band)
            FUZZ_CHECK(in, "%s: ball %s r %a: %u/%u (at %.17g) not reported", what, text(centre).c_str(), radius, t.geometry, t.triangle, d);
        else if (d > double(radius) + band)
            FUZZ_CHECK(!in, "%s: ball %s r %a: %u/%u (at %.17g) reported", what, text(centre).c_str(), radius, t.geometry, t.triangle, d);
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    FuzzedDataProvider in(data, size);
    fuzz::context().clear();
    Input input;
    static const float scales[] = {0x1p-100f, 0x1p-66f, 1.0f, 0x1p66f, 0x1p100f};
    input.scale = scales[in.ConsumeIntegralInRange<int>(0, 4)];
    const Mesh mesh = make_mesh(in, input);
    const kdrt_triangles view = mesh.view();
    kdrt_build_options options = make_options(in);
    Heap heap;
    options.allocator = kdrt_allocator{&Heap::alloc, &Heap::free, &heap};
    kdrt_tree *tree = nullptr, *scan = nullptr;
    if (kdrt_tree_build(&view, &options, &tree, nullptr) != KDRT_SUCCESS) return 0;
    kdrt_build_options scan_options = options;
    scan_options.max_leaf_size = 0;
    FUZZ_CHECK(kdrt_tree_build(&view, &scan_options, &scan, nullptr) == KDRT_SUCCESS, "leaf size 0 failed where the tree did not");

    // The triangles as each target sees them.
    std::vector<WorldTri> own;
    for (uint32_t i = 0; i < view.triangle_count; ++i)
        if (kept(mesh.triangle(i))) own.push_back({0, i, KDRT_INVALID_ID, 0xFFFFFFFFu, mesh.triangle(i)});
    const uint32_t mesh_id = in.ConsumeIntegralInRange<uint32_t>(0, 9), instance_id = in.ConsumeIntegralInRange<uint32_t>(0, 9) + (in.ConsumeBool() ? 10 : 0);
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(mesh_id, &view)};
    entries[0].mask = in.ConsumeBool() ? 0xFFFFFFFFu : in.ConsumeIntegralInRange<uint32_t>(0, 3);
    float m[12];
    make_transform(in, m);
    for (int a = 0; a < 3; ++a) m[4 * a + 3] *= input.scale;  // the translation on the grid too
    const bool with_instance = instance_id != mesh_id;
    if (with_instance) {
        entries.push_back(kdrt_instance_geometry(instance_id, tree, m));
        entries.back().mask = in.ConsumeBool() ? 0xFFFFFFFFu : in.ConsumeIntegralInRange<uint32_t>(0, 3);
    }
    std::vector<WorldTri> world;
    for (const WorldTri &t : own) world.push_back({mesh_id, t.triangle, KDRT_INVALID_ID, entries[0].mask, t.world});
    if (with_instance)
        for (const WorldTri &t : own) world.push_back({instance_id, t.triangle, instance_id, entries[1].mask, oracle::placed(t.world, m)});
    kdrt_scene *scene = nullptr;
    if (kdrt_scene_build(entries.data(), uint32_t(entries.size()), &options, &scene, nullptr) != KDRT_SUCCESS) scene = nullptr;
    const size_t calls = heap.calls;

    for (int round = in.ConsumeIntegralInRange<int>(1, 6); round > 0 && in.remaining_bytes() > 0; --round) {
        float q[3];
        Input qi = input;
        if (in.ConsumeIntegralInRange<int>(0, 7) == 0)
            for (int a = 0; a < 3; ++a) q[a] = fuzz::pick_float(in), qi.grid = false;
        else
            make_point(in, qi, mesh, tree, q);
        const uint32_t mask = in.ConsumeBool() ? 0xFFFFFFFFu : in.ConsumeIntegralInRange<uint32_t>(0, 3);
        const bool finite = std::isfinite(q[0]) && std::isfinite(q[1]) && std::isfinite(q[2]);
        fuzz::context() = "point " + text(q) + "\n";
        switch (in.ConsumeIntegralInRange<int>(0, 2)) {
        case 0: {  // closest point
            float max_distance = INFINITY;
            switch (in.ConsumeIntegralInRange<int>(0, 3)) {
            case 0: max_distance = fuzz::pick_float(in); break;
            case 1: max_distance = float(in.ConsumeIntegralInRange<int>(0, 8)) * 0.25f * input.scale; break;
            default: break;
            }
            const bool valid = finite && max_distance >= 0;
            kdrt_closest c, s;
            std::memset(&c, 0xCD, sizeof c);
            const kdrt_result r = kdrt_closest_point(tree, q, max_distance, &c);
            FUZZ_CHECK(r == (valid ? KDRT_SUCCESS : KDRT_ERROR_INVALID_QUERY), "closest point: %s for max_distance %a",
                       kdrt_result_string(r), max_distance);
            if (!valid) {
                FUZZ_CHECK(c.triangle == KDRT_INVALID_ID, "a refused query named a triangle");
                break;
            }
            FUZZ_CHECK(kdrt_closest_point(scan, q, max_distance, &s) == KDRT_SUCCESS, "leaf size 0 refused what the tree took");
            FUZZ_CHECK(std::memcmp(&c, &s, sizeof c) == 0, "tree: %u at %a, leaf size 0: %u at %a", c.triangle, c.distance, s.triangle,
                       s.distance);
            check_closest(own, q, max_distance, c, qi.grid, "tree");
            if (scene) {
                std::vector<WorldTri> seen;
                for (const WorldTri &t : world)
                    if (t.mask & mask) seen.push_back(t);
                std::memset(&c, 0xCD, sizeof c);
                FUZZ_CHECK(kdrt_scene_closest_point(scene, q, max_distance, mask, &c) == KDRT_SUCCESS, "the scene refused a query");
                check_closest(seen, q, max_distance, c, qi.grid, "scene");
            }
            break;
        }
        default: {  // a box or a ball
            const bool sphere = in.ConsumeBool();
            kdrt_aabb box;
            float radius = 0;
            bool valid = true;
            if (sphere) {
                switch (in.ConsumeIntegralInRange<int>(0, 3)) {
                case 0: radius = fuzz::pick_float(in); break;  // the oracle's ball is exact for any radius
                case 1: radius = 0; break;
                default: radius = float(in.ConsumeIntegralInRange<int>(0, 16)) * 0.25f * input.scale; break;
                }
                if (in.ConsumeIntegralInRange<int>(0, 15) == 0) radius = INFINITY;
                valid = finite && radius >= 0;
            } else {
                float w[3];
                make_point(in, qi, mesh, tree, w);
                for (int a = 0; a < 3; ++a) box.min[a] = std::min(q[a], w[a]), box.max[a] = std::max(q[a], w[a]);
                switch (in.ConsumeIntegralInRange<int>(0, 5)) {
                case 0:  // inverted on an axis
                    std::swap(box.min[in.ConsumeIntegralInRange<int>(0, 2)], box.max[in.ConsumeIntegralInRange<int>(0, 2)]);
                    break;
                case 1: {  // flat
                    const int a = in.ConsumeIntegralInRange<int>(0, 2);
                    box.max[a] = box.min[a];
                    break;
                }
                case 2: {  // a special bound
                    const int a = in.ConsumeIntegralInRange<int>(0, 2);
                    static const float special[] = {INFINITY, -INFINITY, NAN};
                    (in.ConsumeBool() ? box.min : box.max)[a] = special[in.ConsumeIntegralInRange<int>(0, 2)];
                    break;
                }
                case 3: {  // a node's box
                    kdrt_node_info info;
                    if (kdrt_tree_node(tree, in.ConsumeIntegralInRange<uint32_t>(0, kdrt_tree_node_count(tree)), &info) == KDRT_SUCCESS)
                        box = info.bounds;
                    break;
                }
                default: break;
                }
                // The oracle is exact for bounds on the grid and infinite ones (taken as the
                // largest float, whose products dwarf the rest).
                for (int a = 0; a < 3; ++a) {
                    valid = valid && !std::isnan(box.min[a]) && !std::isnan(box.max[a]);
                    qi.grid = qi.grid && (std::isinf(box.min[a]) || on_grid(box.min[a], input.scale)) &&
                              (std::isinf(box.max[a]) || on_grid(box.max[a], input.scale));
                }
            }
            fuzz::context() = sphere ? "ball " + text(q) + " r " + std::to_string(radius) + "\n"
                                     : "box " + text(box.min) + " - " + text(box.max) + "\n";
            auto run = [&](const kdrt_tree *t, const kdrt_scene *s, Collected &col, uint64_t &n) {
                n = 12345;
                if (s)
                    return sphere ? kdrt_scene_overlap_sphere(s, q, radius, mask, collect, &col, &n)
                                  : kdrt_scene_overlap_box(s, &box, mask, collect, &col, &n);
                return sphere ? kdrt_overlap_sphere(t, q, radius, collect, &col, &n) : kdrt_overlap_box(t, &box, collect, &col, &n);
            };
            Collected col, all;
            uint64_t n = 0, n_all = 0;
            const kdrt_result r = run(tree, nullptr, all, n_all);
            FUZZ_CHECK(r == (valid ? KDRT_SUCCESS : KDRT_ERROR_INVALID_QUERY), "overlap: %s", kdrt_result_string(r));
            if (!valid) {
                FUZZ_CHECK(n_all == 0 && all.found.empty(), "a refused query reported triangles");
                break;
            }
            FUZZ_CHECK(n_all == all.found.size(), "count %llu, %zu calls", (unsigned long long)n_all, all.found.size());
            const std::vector<uint64_t> got = keys_of(all, "tree");
            FUZZ_CHECK(run(scan, nullptr, col, n) == KDRT_SUCCESS && keys_of(col, "leaf size 0") == got,
                       "the tree's set (%zu) is not leaf size 0's (%zu)", got.size(), col.found.size());
            if (qi.grid || (sphere && tame(own, q))) check_overlap(own, got, sphere, box, q, radius, "tree");
            // Stopped after some: the count includes the stopping call, the reports are some of all.
            Collected part;
            part.stop_after = in.ConsumeIntegralInRange<size_t>(1, 4);
            if (in.ConsumeBool() && finite) part.reenter = tree, part.point = q;  // (a node's box may come with any q)
            FUZZ_CHECK(run(tree, nullptr, part, n) == KDRT_SUCCESS, "a stopped query failed");
            FUZZ_CHECK(n == std::min<uint64_t>(part.stop_after, got.size()) && n == part.found.size(),
                       "stopped after %zu of %zu: count %llu, %zu calls", part.stop_after, got.size(), (unsigned long long)n,
                       part.found.size());
            for (const uint64_t k : keys_of(part, "stopped"))
                FUZZ_CHECK(std::binary_search(got.begin(), got.end(), k), "a stopped query reported another triangle");
            if (scene) {
                Collected sc;
                FUZZ_CHECK(run(nullptr, scene, sc, n) == KDRT_SUCCESS && n == sc.found.size(), "the scene's query failed");
                const std::vector<uint64_t> sgot = keys_of(sc, "scene");
                for (const kdrt_overlap &f : sc.found) {
                    const WorldTri *t = nullptr;
                    for (const WorldTri &w : world)
                        if (w.geometry == f.geometry && w.triangle == f.triangle) t = &w;
                    FUZZ_CHECK(t && (t->mask & mask) && f.instance == t->instance, "the scene reported %u/%u (instance %u)", f.geometry,
                               f.triangle, f.instance);
                }
                // The mesh's part of it is the tree's set (the same triangles, the same arithmetic).
                std::vector<uint64_t> mesh_part;
                for (uint64_t k : sgot)
                    if (k >> 32 == mesh_id) mesh_part.push_back(k & 0xFFFFFFFFu);
                if (entries[0].mask & mask) FUZZ_CHECK(mesh_part == got, "the scene's mesh set is not the tree's");
                else FUZZ_CHECK(mesh_part.empty(), "a masked mesh reported");
                std::vector<WorldTri> seen;
                for (const WorldTri &t : world)
                    if (t.mask & mask) seen.push_back(t);
                if (qi.grid || (sphere && tame(seen, q))) check_overlap(seen, sgot, sphere, box, q, radius, "scene");
            }
            break;
        }
        }
    }
    FUZZ_CHECK(heap.calls == calls, "the queries allocated");
    kdrt_scene_free(scene);
    kdrt_tree_free(scan);
    kdrt_tree_free(tree);
    FUZZ_CHECK(heap.live == 0, "%zu blocks left allocated", heap.live);
    return 0;
}
