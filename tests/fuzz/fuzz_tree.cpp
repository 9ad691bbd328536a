// libFuzzer target: kdrt's tree API on a small mesh, build options and rays made from the input.
// The mesh: a vertex buffer at some byte stride (exactly as long as the view says, so ASan sees any
// read past it), optional indices (some out of range), coordinates that are often on a small grid
// (shared edges, planar and axis-parallel cases) and sometimes NaN, infinite, huge, tiny,
// subnormal or any bits; sometimes copies of it side by side. Options: builder,
// intersector, leaf size, depth, flags, SAH costs (any float), sometimes an allocator that fails
// one allocation and sometimes a scheduler. Rays: any floats, or aimed at a vertex or an edge of
// the mesh. The implementation is compiled with KDRT_SAH_EXACT_MAX=8 (tests/fuzz/CMakeLists.txt),
// so that small meshes take the SAH builder's binned sweep as well as its exact one.
// Checked:
//  - the build succeeds or fails with a NULL tree and nothing left allocated, and fails exactly
//    where a leaf-size-0 build of the same mesh does (and as kdrt_aabb_of_triangles does);
//  - the statistics agree with the nodes kdrt_tree_node() describes;
//  - a ray started from any cell (kdrt_ray.cell: located, random, a rope, any node) gets the
//    walk from the root's answer;
//  - every hit lies in the ray's range on an existing triangle, kdrt_occluded() agrees with
//    kdrt_intersect(), kdrt_hit_surface() gives a finite point and a unit normal;
//  - every tree returns bit for bit what max_leaf_size = 0 (every triangle tested) returns, but
//    for kdrt.h's one exception: a triangle the ray misses by less than the test's rounding error
//    may be "hit" by leaf size 0 and never tested by the tree. Where the two differ, leaf size 0's
//    triangle must not be one the double-precision oracle (bench/oracle) sees as surely hit, the
//    tree's answer must be farther, and the oracle must accept it.
#include "kdrt.h"
#include "common/mesh_io.hpp"
#include "oracle/reference.hpp"
#include "fuzz_support.hpp"


#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace {

using fuzz::Heap;

// Runs the tasks on this thread, last first: any order must give the same tree.
void run_reversed(void *, kdrt_task_fn task, void *data, uint32_t count) {
    for (uint32_t i = count; i-- > 0;) task(data, i);
}

bool same_answer(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.triangle != b.triangle) return false;
    return a.triangle == KDRT_INVALID_ID || (std::memcmp(&a.t, &b.t, sizeof a.t) == 0 &&
                                             std::memcmp(&a.u, &b.u, sizeof a.u) == 0 &&
                                             std::memcmp(&a.v, &b.v, sizeof a.v) == 0);
}

void print_hit(const char *what, const kdrt_hit &h) {
    if (h.triangle == KDRT_INVALID_ID) std::fprintf(stderr, "  %s: miss\n", what);
    else std::fprintf(stderr, "  %s: triangle %u t=%a u=%a v=%a\n", what, h.triangle, h.t, h.u, h.v);
}

struct Input {
    std::unique_ptr<unsigned char[]> positions;  // exactly as many bytes as the view reads
    std::vector<uint32_t> indices;
    kdrt_triangles view{};
};

Input make_mesh(FuzzedDataProvider &in) {
    Input m;
    static const size_t strides[] = {0, 12, 13, 16, 20, 24, 4, 11};
    const size_t stride = strides[in.ConsumeIntegralInRange<size_t>(0, 7)];
    const uint32_t base_vertices = in.ConsumeIntegralInRange<uint32_t>(0, 24);
    std::vector<float> coords(size_t(base_vertices) * 3);
    for (float &x : coords) x = fuzz::pick_float(in);
    const bool indexed = in.ConsumeBool();
    const uint32_t base_triangles = in.ConsumeIntegralInRange<uint32_t>(0, 16);
    std::vector<uint32_t> base_indices(indexed ? size_t(base_triangles) * 3 : 0);
    for (uint32_t &i : base_indices) {
        switch (in.ConsumeIntegralInRange<int>(0, 15)) {
        case 0: i = base_vertices; break;  // just out of range
        case 1: i = in.ConsumeIntegral<uint32_t>(); break;
        default: i = base_vertices ? in.ConsumeIntegralInRange<uint32_t>(0, base_vertices - 1) : 0;
        }
    }
    // Sometimes a few copies side by side, 0.5 apart in x, and rarely (they are slow) hundreds:
    // enough triangles for the SAH builder's parallel top levels (nodes of more than 4096).
    const int roll = in.ConsumeIntegralInRange<int>(0, 1023);
    const uint32_t copies = roll < 128 ? in.ConsumeIntegralInRange<uint32_t>(2, 8)
                            : roll == 128 ? in.ConsumeIntegralInRange<uint32_t>(257, 320) : 1;
    const uint32_t vertices = base_vertices * copies;
    const size_t step = stride ? stride : 12;
    const size_t bytes = vertices ? (vertices - 1) * step + 12 : 0;
    if (bytes) m.positions.reset(new unsigned char[bytes]);
    for (uint32_t c = 0; c < copies; ++c)
        for (uint32_t v = 0; v < base_vertices; ++v) {
            float p[3] = {coords[v * 3] + 0.5f * float(c), coords[v * 3 + 1], coords[v * 3 + 2]};
            std::memcpy(m.positions.get() + (size_t(c) * base_vertices + v) * step, p, sizeof p);
        }
    for (uint32_t c = 0; c < copies; ++c)
        for (uint32_t i : base_indices) m.indices.push_back(i < base_vertices ? i + c * base_vertices : i);
    m.view.positions = reinterpret_cast<const float *>(m.positions.get());
    m.view.position_stride = stride;
    m.view.vertex_count = vertices;
    m.view.indices = m.indices.empty() ? nullptr : m.indices.data();
    uint32_t triangles = base_triangles * copies;
    // A count beyond what a tree can address must be refused before the buffers are read.
    if (in.ConsumeIntegralInRange<int>(0, 31) == 0) triangles = KDRT_MAX_TRIANGLES + in.ConsumeIntegralInRange<uint32_t>(1, 4);
    m.view.triangle_count = triangles;
    if (in.ConsumeIntegralInRange<int>(0, 31) == 0) m.view.positions = nullptr;
    return m;
}

kdrt_build_options make_options(FuzzedDataProvider &in) {
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = kdrt_builder(in.ConsumeIntegralInRange<int>(0, 3));
    o.intersector = kdrt_intersector(in.ConsumeIntegralInRange<int>(0, 3));
    static const uint32_t leaves[] = {1, 2, 3, 4, 8, 64, 0xFFFFFFFFu};
    o.max_leaf_size = leaves[in.ConsumeIntegralInRange<int>(0, 6)];
    o.max_depth = in.ConsumeBool() ? 0 : in.ConsumeIntegralInRange<uint32_t>(0, 70);
    o.flags = in.ConsumeIntegralInRange<int>(0, 7) == 0 ? in.ConsumeIntegral<uint32_t>() : in.ConsumeIntegralInRange<uint32_t>(0, 1);
    if (in.ConsumeBool()) {
        o.sah_traversal_cost = in.ConsumeBool() ? 0.0f : fuzz::pick_float(in);
        o.sah_intersection_cost = in.ConsumeBool() ? 0.0f : fuzz::pick_float(in);
        o.sah_empty_bonus = in.ConsumeBool() ? 0.0f : fuzz::pick_float(in);
    }
    return o;
}

kdrt_ray make_ray(FuzzedDataProvider &in, const std::vector<float> &points) {
    kdrt_ray r{};
    for (float &x : r.org) x = fuzz::pick_float(in);
    if (!points.empty() && in.ConsumeBool()) {
        // Towards a vertex, or a point on an edge: where watertightness and ties are decided.
        const size_t a = in.ConsumeIntegralInRange<size_t>(0, points.size() / 3 - 1);
        const size_t b = in.ConsumeIntegralInRange<size_t>(0, points.size() / 3 - 1);
        const float s = float(in.ConsumeIntegralInRange<int>(0, 4)) * 0.25f;
        for (int k = 0; k < 3; ++k) r.dir[k] = points[a * 3 + k] + s * (points[b * 3 + k] - points[a * 3 + k]) - r.org[k];
    } else {
        for (float &x : r.dir) x = fuzz::pick_float(in);
    }
    r.tmin = in.ConsumeBool() ? 0.0f : fuzz::pick_float(in);
    r.tmax = in.ConsumeBool() ? INFINITY : fuzz::pick_float(in);
    return r;
}

// The caller's triangles as a common::Mesh for the oracle: the triangles a build would skip (an
// index out of range, a non-finite corner) become a single point, which no ray hits.
common::Mesh oracle_mesh(const kdrt_triangles &view) {
    common::Mesh mesh;
    const size_t step = view.position_stride ? view.position_stride : 12;
    const unsigned char *base = reinterpret_cast<const unsigned char *>(view.positions);
    for (uint32_t t = 0; t < view.triangle_count; ++t) {
        float p[3][3] = {};
        bool ok = true;
        for (int k = 0; k < 3 && ok; ++k) {
            const uint64_t v = view.indices ? view.indices[size_t(t) * 3 + k] : uint64_t(t) * 3 + k;
            ok = v < view.vertex_count;
            if (ok) std::memcpy(p[k], base + v * step, sizeof p[k]);
            for (int a = 0; a < 3 && ok; ++a) ok = std::isfinite(p[k][a]);
        }
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) mesh.positions.push_back(ok ? p[k][a] : 0.0f);
    }
    return mesh;
}

bool is_hit(const kdrt_hit &h) { return h.triangle != KDRT_INVALID_ID; }

// What kdrt_tree_node() says must add up to the statistics.
void check_stats(const kdrt_tree *tree, const kdrt_triangles &view, const kdrt_build_report &report) {
    kdrt_tree_stats s;
    kdrt_tree_get_stats(tree, &s);
    FUZZ_CHECK(uint64_t(s.triangles) + report.skipped_triangles + report.degenerate_triangles == view.triangle_count,
               "%u in the tree, %u skipped, %u degenerate, of %u", s.triangles, report.skipped_triangles,
               report.degenerate_triangles, view.triangle_count);
    FUZZ_CHECK(kdrt_tree_node_count(tree) == s.nodes, "%u nodes counted, stats say %u", kdrt_tree_node_count(tree), s.nodes);
    FUZZ_CHECK(s.nodes >= 1 && s.leaves >= 1 && s.leaves <= s.nodes, "%u nodes, %u leaves", s.nodes, s.leaves);
    FUZZ_CHECK(s.max_depth <= KDRT_MAX_DEPTH, "depth %u", s.max_depth);
    FUZZ_CHECK(std::isfinite(s.sah_cost) && s.sah_cost >= 0, "sah_cost %g", s.sah_cost);
    FUZZ_CHECK(s.bytes > 0, "no bytes");
    uint32_t leaves = 0, depth = 0;
    uint64_t refs = 0;
    for (uint32_t i = 0; i < s.nodes; ++i) {
        kdrt_node_info n;
        FUZZ_CHECK(kdrt_tree_node(tree, i, &n) == KDRT_SUCCESS, "node %u", i);
        if (n.is_leaf) {
            ++leaves;
            depth = std::max(depth, n.depth);
            FUZZ_CHECK(n.first_reference == refs, "leaf %u starts at reference %u, expected %llu", i, n.first_reference,
                       (unsigned long long)refs);
            refs += n.triangle_count;
        } else {
            FUZZ_CHECK(n.below == i + 1 && n.above > i + 1 && n.above < s.nodes && n.axis >= 0 && n.axis < 3,
                       "node %u: below %u above %u axis %d", i, n.below, n.above, n.axis);
        }
    }
    kdrt_node_info none;
    FUZZ_CHECK(kdrt_tree_node(tree, s.nodes, &none) == KDRT_ERROR_INDEX_OUT_OF_RANGE, "node past the end");
    FUZZ_CHECK(leaves == s.leaves && refs == s.triangle_refs && depth == s.max_depth,
               "walked %u leaves, %llu references, depth %u; stats %u, %llu, %u", leaves, (unsigned long long)refs, depth,
               s.leaves, (unsigned long long)s.triangle_refs, s.max_depth);
    for (uint64_t r = 0; r < refs; ++r) {
        uint32_t t;
        FUZZ_CHECK(kdrt_tree_reference(tree, uint32_t(r), &t) == KDRT_SUCCESS && t < view.triangle_count, "reference %llu",
                   (unsigned long long)r);
    }
    uint32_t t;
    FUZZ_CHECK(refs >= 0xFFFFFFFFu || kdrt_tree_reference(tree, uint32_t(refs), &t) == KDRT_ERROR_INDEX_OUT_OF_RANGE,
               "reference past the end");
}

std::string describe_ray(const kdrt_ray &ray) {
    char s[256];
    std::snprintf(s, sizeof s, "ray org=(%a, %a, %a) dir=(%a, %a, %a) tmin=%a tmax=%a\n", ray.org[0], ray.org[1], ray.org[2],
                  ray.dir[0], ray.dir[1], ray.dir[2], ray.tmin, ray.tmax);
    return s;
}

std::string describe_triangle(const common::Mesh &mesh, uint32_t triangle) {
    double p[3][3];
    mesh.corners(triangle, p);
    char s[256];
    std::snprintf(s, sizeof s, "triangle %u: (%a, %a, %a) (%a, %a, %a) (%a, %a, %a)\n", triangle, p[0][0], p[0][1],
                  p[0][2], p[1][0], p[1][1], p[1][2], p[2][0], p[2][1], p[2][2]);
    return s;
}

// KDRT_INTERSECTOR_FAST computes in float, and kdrt.h documents its range: beyond lengths of
// about 1e-9 to 1e12 (the direction's, the triangle's edges', the origin's distance from it) its
// products of three overflow or underflow and its answer is not defined. A fast tree's answers
// involving such a triangle are not compared.
bool fast_defined(const common::Mesh &mesh, uint32_t triangle, const kdrt_ray &ray) {
    double p[3][3];
    mesh.corners(triangle, p);
    auto length = [](double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); };
    const double lengths[] = {length(ray.dir[0], ray.dir[1], ray.dir[2]),
                              length(p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]),
                              length(p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]),
                              length(ray.org[0] - p[0][0], ray.org[1] - p[0][1], ray.org[2] - p[0][2])};
    for (double l : lengths)
        if (l != 0 && !(l >= 1e-9 && l <= 1e12)) return false;
    return true;
}

// A hit of `tree` on `ray`, as kdrt.h describes one; `mesh` is oracle_mesh().
void check_hit_shape(const kdrt_tree *tree, const kdrt_ray &ray, const kdrt_hit &h, const common::Mesh &mesh) {
    if (!is_hit(h)) return;
    const uint32_t triangles = mesh.triangle_count();
    FUZZ_CHECK(h.triangle < triangles, "triangle %u of %u", h.triangle, triangles);
    fuzz::context() = describe_ray(ray) + describe_triangle(mesh, h.triangle);
    double p[3][3];
    mesh.corners(h.triangle, p);
    FUZZ_CHECK(h.t >= std::max(ray.tmin, 0.0f) && h.t <= ray.tmax && std::isfinite(h.t), "t=%a outside [%a, %a]", h.t,
               ray.tmin, ray.tmax);
    FUZZ_CHECK(std::isfinite(h.u) && std::isfinite(h.v), "u=%a v=%a", h.u, h.v);
    float point[3], normal[3];
    FUZZ_CHECK(kdrt_hit_surface(tree, &h, point, normal) == 1, "kdrt_hit_surface refused a hit");
    const double length = std::sqrt(double(normal[0]) * normal[0] + double(normal[1]) * normal[1] + double(normal[2]) * normal[2]);
    FUZZ_CHECK(std::fabs(length - 1) < 1e-6, "normal (%a, %a, %a) of length %g", normal[0], normal[1], normal[2], length);
    // The point lies in the triangle's box, up to rounding.
    for (int a = 0; a < 3; ++a) {
        const double lo = std::min({p[0][a], p[1][a], p[2][a]}), hi = std::max({p[0][a], p[1][a], p[2][a]});
        const double slack = 0x1p-20 * std::max({std::fabs(lo), std::fabs(hi), hi - lo});
        FUZZ_CHECK(point[a] >= lo - slack && point[a] <= hi + slack, "point (%a, %a, %a)", point[0], point[1], point[2]);
    }
    kdrt_ray next;
    FUZZ_CHECK(kdrt_spawn_ray(tree, &h, ray.dir, &next) == 1, "kdrt_spawn_ray refused a hit");
    FUZZ_CHECK(std::isfinite(next.org[0]) && std::isfinite(next.org[1]) && std::isfinite(next.org[2]),
               "spawned origin (%a, %a, %a)", next.org[0], next.org[1], next.org[2]);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    FuzzedDataProvider in(data, size);
    fuzz::context().clear();
    Input mesh = make_mesh(in);
    const kdrt_triangles &view = mesh.view;
    kdrt_build_options options = make_options(in);
    Heap heap;
    const bool counted = in.ConsumeBool();
    if (counted) {
        heap.fail_at = in.ConsumeBool() ? 0 : in.ConsumeIntegralInRange<size_t>(1, 64);
        options.allocator = kdrt_allocator{&Heap::alloc, &Heap::free, &heap};
    }
    if (in.ConsumeBool()) options.scheduler = kdrt_scheduler{&run_reversed, nullptr};

    // Leaf size 0, every triangle tested: the answer every tree must give.
    kdrt_build_options brute_options = options;
    brute_options.max_leaf_size = 0;
    brute_options.allocator = kdrt_allocator{};
    kdrt_tree *brute = nullptr;
    kdrt_build_report brute_report;
    const kdrt_result brute_result = kdrt_tree_build(&view, &brute_options, &brute, &brute_report);
    FUZZ_CHECK((brute_result == KDRT_SUCCESS) == (brute != nullptr), "%s with tree %p", kdrt_result_string(brute_result),
               static_cast<void *>(brute));

    kdrt_tree *tree = reinterpret_cast<kdrt_tree *>(&heap);  // a failed build must set it to NULL
    kdrt_build_report report;
    const kdrt_result result = kdrt_tree_build(&view, &options, &tree, &report);
    if (result != KDRT_SUCCESS) {
        FUZZ_CHECK(tree == nullptr, "a failed build (%s) left a tree", kdrt_result_string(result));
        FUZZ_CHECK(heap.live == 0, "a failed build (%s) left %zu blocks allocated", kdrt_result_string(result), heap.live);
    }
    // Leaf size 0 fails exactly where the tree does, but for running out of memory.
    if (result != KDRT_ERROR_OUT_OF_MEMORY) {
        FUZZ_CHECK(result == brute_result, "the tree: %s; leaf size 0: %s", kdrt_result_string(result),
                   kdrt_result_string(brute_result));
        FUZZ_CHECK(report.invalid_triangle == brute_report.invalid_triangle &&
                       report.skipped_triangles == brute_report.skipped_triangles &&
                       report.degenerate_triangles == brute_report.degenerate_triangles,
                   "reports differ");
    }
    if (brute_result != KDRT_ERROR_INVALID_OPTION) {
        kdrt_aabb box;
        kdrt_build_report box_report;
        const kdrt_result box_result = kdrt_aabb_of_triangles(&view, &box, &box_report);
        FUZZ_CHECK(box_result == brute_result || (brute_result == KDRT_SUCCESS && (options.flags & KDRT_BUILD_SKIP_INVALID_TRIANGLES)),
                   "kdrt_aabb_of_triangles: %s, the build: %s", kdrt_result_string(box_result), kdrt_result_string(brute_result));
    }
    if (!brute || !tree) {
        kdrt_tree_free(brute);
        kdrt_tree_free(tree);
        FUZZ_CHECK(heap.live == 0, "%zu blocks left", heap.live);
        return 0;
    }
    check_stats(brute, view, brute_report);
    check_stats(tree, view, report);

    // Rays, some aimed at the mesh's vertices and edges.
    std::vector<float> points;
    const common::Mesh as_mesh = oracle_mesh(view);
    for (size_t i = 0; i + 2 < as_mesh.positions.size(); i += 3)
        if (as_mesh.positions[i] != 0 || as_mesh.positions[i + 1] != 0 || as_mesh.positions[i + 2] != 0)
            points.insert(points.end(), &as_mesh.positions[i], &as_mesh.positions[i] + 3);
    std::unique_ptr<oracle::Oracle> oracle;  // made when first needed
    const size_t live_before_queries = heap.live, calls_before_queries = heap.calls;
    const int rays = in.ConsumeIntegralInRange<int>(1, 8);
    for (int i = 0; i < rays; ++i) {
        const kdrt_ray ray = make_ray(in, points);
        kdrt_hit h0, h;
        const int hit0 = kdrt_intersect(brute, &ray, &h0);
        const int hit = kdrt_intersect(tree, &ray, &h);
        FUZZ_CHECK(hit0 == is_hit(h0) && hit == is_hit(h), "return value and hit.triangle disagree");
        FUZZ_CHECK(kdrt_occluded(brute, &ray) == hit0, "leaf size 0: kdrt_occluded disagrees with kdrt_intersect");
        FUZZ_CHECK(kdrt_occluded(tree, &ray) == hit, "kdrt_occluded disagrees with kdrt_intersect");
        check_hit_shape(brute, ray, h0, as_mesh);
        check_hit_shape(tree, ray, h, as_mesh);
        fuzz::context().clear();

        // A start cell is only a hint (START CELLS): the located one, any number, a rope of the
        // located leaf, any node. The answer is the walk from the root's, bit for bit, but for
        // the one exception, a triangle missed by less than the rounding that still "hits".
        kdrt_ray hinted = ray;
        const uint32_t at = kdrt_locate(tree, ray.org), nodes = kdrt_tree_node_count(tree);
        kdrt_node_info info;
        switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: hinted.cell = at; break;
        case 1: hinted.cell = in.ConsumeIntegral<uint32_t>(); break;
        case 2:
            hinted.cell = kdrt_tree_node(tree, at, &info) == KDRT_SUCCESS && info.is_leaf ? info.ropes[in.ConsumeIntegralInRange<int>(0, 5)] : 0;
            break;
        default: hinted.cell = in.ConsumeIntegralInRange<uint32_t>(0, nodes); break;
        }
        kdrt_hit hh;
        const int hit_hinted = kdrt_intersect(tree, &hinted, &hh);
        FUZZ_CHECK(kdrt_occluded(tree, &hinted) == hit_hinted, "hinted: kdrt_occluded disagrees with kdrt_intersect");
        if (!same_answer(hh, h)) {
            check_hit_shape(tree, hinted, hh, as_mesh);
            const bool undefined = options.intersector == KDRT_INTERSECTOR_FAST &&
                                   ((hit && !fast_defined(as_mesh, h.triangle, ray)) || (hit_hinted && !fast_defined(as_mesh, hh.triangle, ray)));
            if (!oracle) oracle.reset(new oracle::Oracle(as_mesh));
            const oracle::Reference ref = oracle->trace(ray);
            oracle::Agreement tally;
            oracle::check_hit(*oracle, ref, ray, h, tally);
            oracle::check_hit(*oracle, ref, ray, hh, tally);
            const bool sure = ref.sure_hit && hit && hit_hinted && ref.sure_triangle == h.triangle && ref.sure_triangle == hh.triangle;
            if (!undefined && (tally.wrong != 0 || sure)) {
                std::fprintf(stderr, "%s", describe_ray(ray).c_str());
                std::fprintf(stderr, "  start cell %u\n", hinted.cell);
                print_hit("from the root", h);
                print_hit("from the cell", hh);
            }
            FUZZ_CHECK(undefined || (tally.wrong == 0 && !sure), "the answer from start cell %u differs from the root's", hinted.cell);
        }
        if (same_answer(h, h0)) continue;
        if (options.intersector == KDRT_INTERSECTOR_FAST &&
            ((hit0 && !fast_defined(as_mesh, h0.triangle, ray)) || (hit && !fast_defined(as_mesh, h.triangle, ray))))
            continue;

        // The one exception: leaf size 0 "hit" a triangle the ray misses by less than the test's
        // rounding error, which lies where the tree never looks.
        if (!oracle) oracle.reset(new oracle::Oracle(as_mesh));
        const oracle::Reference ref = oracle->trace(ray);
        oracle::Agreement tally;
        oracle::check_hit(*oracle, ref, ray, h, tally);
        const bool farther = !hit || h.t > h0.t || (h.t == h0.t && h.triangle > h0.triangle);
        const bool exception = hit0 && farther && !(ref.sure_hit && ref.sure_triangle == h0.triangle) && tally.wrong == 0;
        if (!exception) {
            std::fprintf(stderr, "options: builder %d, intersector %d, max leaf size %u, max depth %u, costs %a %a %a\n",
                         int(options.builder), int(options.intersector), options.max_leaf_size, options.max_depth,
                         options.sah_traversal_cost, options.sah_intersection_cost, options.sah_empty_bonus);
            std::fprintf(stderr, "%s", describe_ray(ray).c_str());
            print_hit("leaf size 0", h0);
            print_hit("the tree", h);
            for (const kdrt_hit *x : {&h0, &h})
                if (is_hit(*x)) std::fprintf(stderr, "  %s", describe_triangle(as_mesh, x->triangle).c_str());
            if (ref.sure_hit) std::fprintf(stderr, "  oracle: triangle %u at t=%.17g\n", ref.sure_triangle, ref.sure_t);
            if (!tally.first_wrong.empty()) std::fprintf(stderr, "  oracle: %s\n", tally.first_wrong.c_str());
        }
        FUZZ_CHECK(exception, "the tree's answer differs from leaf size 0's");
    }
    FUZZ_CHECK(heap.live == live_before_queries && heap.calls == calls_before_queries, "a query allocated");
    kdrt_tree_free(brute);
    kdrt_tree_free(tree);
    FUZZ_CHECK(heap.live == 0, "kdrt_tree_free left %zu blocks", heap.live);
    return 0;
}
