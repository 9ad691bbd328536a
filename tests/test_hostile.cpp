// Geometry chosen to hurt a kd-tree builder: meshes scaled to the edges of float's range, whose
// tree must not depend on the scale, and meshes that make a SAH build duplicate references
// without end, which the reference budget must hold to KDRT_SAH_REFERENCE_BUDGET per triangle.
// Every tree is also checked against max_leaf_size 0 (every triangle tested), bit for bit.

#include "test_support.hpp"
#include "common/thread_scheduler.hpp"
#include "oracle/hard_cases.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace {

// kdrt.h's default, which the suites' implementation is compiled with (kdrt_impl sets none).
constexpr uint32_t kReferenceBudget = 8;

common::Mesh scaled(const common::Mesh &mesh, double scale) {
    common::Mesh m = mesh;
    for (float &x : m.positions) x = float(double(x) * scale);
    return m;
}

kt::TreePtr build(const common::Mesh &mesh, const kt::Builder &builder, uint32_t leaf,
                  const kdrt_scheduler &scheduler = kdrt_scheduler{nullptr, nullptr}) {
    kdrt_build_options o = kdrt_default_build_options();
    builder.apply(o);
    o.max_leaf_size = leaf;
    o.scheduler = scheduler;
    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

// What a mesh's rays must get: the double-precision reference's answers and those of testing
// every triangle (leaf size 0), worked out once for the trees of every builder.
struct EveryTriangle {
    const oracle::Oracle reference;
    const std::vector<kdrt_ray> rays;
    const std::vector<oracle::Reference> refs;
    kt::TreePtr all;
    std::vector<kdrt_hit> want;
    std::vector<unsigned char> occluded;
    EveryTriangle(const common::Mesh &mesh, std::vector<kdrt_ray> r)
        : reference(mesh), rays(std::move(r)), refs(oracle::reference_all(reference, rays)),
          all(build(mesh, kt::kBuilders[0], 0)), want(kt::trace_all(all.get(), rays)),
          occluded(kt::occluded_all(all.get(), rays)) {}

    // The tree answers the rays as the reference does, exactly as testing every triangle does
    // (the header's promise), and the rays hit something.
    void check(const kdrt_tree *tree) const {
        const std::vector<kdrt_hit> got = kt::trace_all(tree, rays);
        oracle::Agreement tally;
        size_t differ = 0, hits = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            oracle::check_hit(reference, refs[i], rays[i], got[i], tally);
            differ += !kt::same_hit(want[i], got[i]);
            hits += want[i].triangle != KDRT_INVALID_ID;
        }
        INFO(tally.first_wrong);
        CHECK(tally.wrong == 0);
        CHECK(differ == 0);
        CHECK(hits > 0);
        CHECK(kt::occluded_all(tree, rays) == occluded);
    }
};

}  // namespace

// The SAH's costs were float areas: at coordinates of about 1e20 they overflowed, every cost was
// NaN, and the tree was one leaf. Costs are now worked out where every product of two floats is
// exact, so a power-of-two scale changes nothing but the splits' positions.
TEST_CASE("hostile: a mesh scaled by 2^-60 to 2^60 gets the same tree, node for node", "[hostile]") {
    const common::Mesh meshes[] = {kt::random_soup(6000, 3), kt::grid(30, 30, 4), kt::sphere(24, 48, 1.0),
                                   oracle::hostile_mesh("overlapping", 2000, 5)};
    for (const common::Mesh &mesh : meshes)
        for (const kt::Builder &builder : kt::kBuilders)
            for (uint32_t leaf : {1u, 4u}) {
                kt::TreePtr unit = build(mesh, builder, leaf);
                for (int power : {-60, -40, -20, 20, 40, 60}) {
                    INFO(mesh.name << ", " << builder.name << ", leaf size "
                                   << leaf << ", scaled by 2^" << power);
                    const double scale = std::ldexp(1.0, power);
                    kt::TreePtr big = build(scaled(mesh, scale), builder, leaf);
                    kt::check_same_shape(unit.get(), big.get(), scale);
                }
            }
}

TEST_CASE("hostile: a 200,000-triangle grid at 1e20 and 1e-20 gets a tree as good as at 1", "[hostile]") {
    const common::Mesh grid = kt::grid(317, 316, 8);
    REQUIRE(grid.triangle_count() >= 200000);
    kdrt_tree_stats base[3];
    for (int b = 0; b < 3; ++b) kdrt_tree_get_stats(build(grid, kt::kSahBuilders[b], 4).get(), &base[b]);
    kdrt_aabb box;
    const kdrt_triangles view = grid.view();
    REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
    const std::vector<kdrt_ray> unit_rays = kt::random_rays(box, 300, 9);
    for (double scale : {1e20, 1e-20}) {
        INFO("scaled by " << scale);
        const common::Mesh far = scaled(grid, scale);
        std::vector<kdrt_ray> rays = unit_rays;  // the same rays, scaled with the scene
        for (kdrt_ray &r : rays)
            for (int a = 0; a < 3; ++a) r.org[a] = float(r.org[a] * scale), r.dir[a] = float(r.dir[a] * scale);
        const EveryTriangle every(far, rays);
        for (int b = 0; b < 3; ++b) {
            INFO(kt::kSahBuilders[b].name);
            kt::TreePtr tree = build(far, kt::kSahBuilders[b], 4);
            kdrt_tree_stats s;
            kdrt_tree_get_stats(tree.get(), &s);
            // Not a power of two: rounding moves some vertices, so the trees may differ a little.
            CHECK(s.nodes > base[b].nodes / 2);
            CHECK(s.sah_cost < base[b].sah_cost * 1.01);
            every.check(tree.get());
        }
    }
}

// Without a budget, a SAH build of a 40,000-triangle fan made 229 million references (5,731 a
// triangle) in 386 s. With it, every one of these meshes stays within the budget, on one thread
// and on two (the same tree), and answers rays as testing every triangle does. The meshes have
// 100,000 triangles at the default KDRT_TEST_RAYS, fewer with fewer rays, never under 20,000
// (kt::drawn_count): the sanitizer build's, where their builds took most of the suite's time.
TEST_CASE("hostile: fans, slivers, overlapping and identical triangles stay within the reference budget",
          "[hostile]") {
    const uint32_t n = uint32_t(kt::drawn_count(100000));
    for (const std::string &kind : oracle::hostile_kinds()) {
        const common::Mesh mesh = oracle::hostile_mesh(kind, n, 12);
        REQUIRE(mesh.triangle_count() == n);
        kdrt_aabb box;
        const kdrt_triangles view = mesh.view();
        REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
        const EveryTriangle every(mesh, kt::random_rays(box, 400, 13));
        for (const kt::Builder &builder : kt::kSahBuilders)
            for (uint32_t leaf : {1u, 4u}) {
                INFO(mesh.name << ", " << builder.name << ", leaf size " << leaf);
                kt::TreePtr tree = build(mesh, builder, leaf);
                kdrt_tree_stats s;
                kdrt_tree_get_stats(tree.get(), &s);
                CHECK(s.triangles == n);
                CHECK(s.triangle_refs <= uint64_t(kReferenceBudget) * n);
                WARN(mesh.name << ", " << builder.name << ", leaf size " << leaf << ": " << s.triangle_refs / double(n) << " references, "
                               << s.nodes / double(n) << " nodes and " << s.bytes / double(n)
                               << " bytes a triangle, depth " << s.max_depth);
                common::ThreadScheduler pool(2);
                kt::TreePtr parallel = build(mesh, builder, leaf, pool.hooks());
                kt::check_same_shape(tree.get(), parallel.get(), 1.0);
                every.check(tree.get());
            }
    }
}

namespace {

// One triangle (corners c, 9 floats) and one ray; REQUIREs a successful build.
kdrt_hit trace_one(const float c[9], const kdrt_ray &ray, kdrt_intersector intersector, kt::TreePtr &tree) {
    kdrt_triangles m{};
    m.positions = c, m.vertex_count = 3, m.triangle_count = 1;
    kdrt_build_options o = kdrt_default_build_options();
    o.intersector = intersector;
    kdrt_tree *t = nullptr;
    REQUIRE(kdrt_tree_build(&m, &o, &t, nullptr) == KDRT_SUCCESS);
    tree = kt::TreePtr(t);
    kdrt_hit h;
    kdrt_intersect(t, &ray, &h);
    return h;
}

bool finite_hit(const kdrt_hit &h) { return std::isfinite(h.t) && std::isfinite(h.u) && std::isfinite(h.v); }

}  // namespace

// Found by the C API's fuzz target: with float edge functions the watertight test returned hits at
// t = infinity (and infinite or NaN barycentrics) on triangles 1e-20 or 1e13 across, and
// kdrt_hit_surface an infinite point beside a corner at the largest float.
TEST_CASE("hostile: queries at the ends of float's range give finite hits or none", "[hostile]") {
    const float M = std::numeric_limits<float>::max();
    for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST}) {
        const bool watertight = intersector == KDRT_INTERSECTOR_WATERTIGHT;
        INFO((watertight ? "watertight" : "fast"));
        kt::TreePtr tree;
        for (float s : {1e-22f, 1e-20f}) {  // straight down onto a tiny triangle: t = 1
            const float c[9] = {0, 0, 0, s, 0, 0, 0, s, 0};
            const kdrt_hit h = trace_one(c, kt::ray_of(s / 4, s / 4, 1, 0, 0, -1), intersector, tree);
            INFO("triangle " << s << " across");
            if (watertight) CHECK((h.triangle == 0 && h.t == 1.0f && h.u == 0.25f && h.v == 0.25f));
            CHECK((h.triangle == KDRT_INVALID_ID || finite_hit(h)));
        }
        for (float s : {1e13f, 1e16f, 1e19f, 1e25f}) {  // a plane z = s seen from the origin: t = s
            const float c[9] = {0, 0, s, s, 0, s, 0, s, s};
            const kdrt_hit h = trace_one(c, kt::ray_of(0, 0, 0, 0.25f, 0.25f, 1), intersector, tree);
            INFO("triangle at " << s);
            if (watertight) CHECK((h.triangle == 0 && std::fabs(h.t - s) <= 1e-6 * s));
            CHECK((h.triangle == KDRT_INVALID_ID || finite_hit(h)));
        }
        {  // all but in the triangle's plane x = 0.75 (dir.x subnormal): hit or miss, never t = inf
            const float c[9] = {0.75f, 0.75f, 0.75f, 0.75f, 0.25f, -2, 0.75f, -2, -2};
            const kdrt_hit h = trace_one(c, kt::ray_of(0.75f, 0.75f, 0.25f, 0x1p-147f, -2, -2), intersector, tree);
            CHECK((h.triangle == KDRT_INVALID_ID || finite_hit(h)));
        }
        {  // corners at the largest float: differences overflow, so a miss is allowed, not inf
            const float c[9] = {M, M, 0, -M, M, 0, M, -M, 0};
            const kdrt_hit h = trace_one(c, kt::ray_of(M / 2, M / 2, 1, 0, 0, -1), intersector, tree);
            CHECK((h.triangle == KDRT_INVALID_ID || finite_hit(h)));
        }
    }
    // kdrt_hit_surface keeps the point in the triangle's box when u + v comes out a hair over 1.
    const float c[9] = {0, 0, 0, M, 0, 0, M, M, 0};
    kdrt_triangles m{};
    m.positions = c, m.vertex_count = 3, m.triangle_count = 1;
    kdrt_tree *t = nullptr;
    REQUIRE(kdrt_tree_build(&m, nullptr, &t, nullptr) == KDRT_SUCCESS);
    kt::TreePtr owner(t);
    kdrt_hit h{1.0f, 1.0f, 1e-7f, 0, 0, KDRT_INVALID_ID, 0};
    float point[3], normal[3];
    REQUIRE(kdrt_hit_surface(t, &h, point, normal));
    CHECK(point[0] == M);
    CHECK((point[1] >= 0 && point[1] <= M && point[2] == 0));
    CHECK((normal[0] == 0 && normal[1] == 0 && normal[2] == 1));
}
