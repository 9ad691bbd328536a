// kdrt_closest_point() and kdrt_scene_closest_point() against the brute force of
// point_oracle.hpp (every triangle, in quadruple precision): the distance within the manual's
// bound of the true minimum, the triangle a true minimum within that bound, the point on it at
// the distance returned; and against the tree of leaf size 0 (every triangle in one leaf, the
// same arithmetic) and the scalar kernel's tree: the same triangle and the same distance, bit for
// bit. Every builder and quality, leaf sizes 0 to 16, both kernels (this suite also runs in
// kdrt_scalar_tests); random points near the surface, inside the box and far outside it; points
// on vertices, on edges, on split planes; meshes scaled to 1e-20 and 1e20; slivers; NaN and
// infinite points refused; the walk's queue filling up. Scenes: meshes and instances under
// rotations, non-uniform scales, mirrors and shears, masks and disabled entries, checked against
// the world triangles' brute force.

#include "point_oracle.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <limits>
#include <string>
#include <vector>

namespace {

using oracle::Tri;

using oracle::triangles_of;
using oracle::zero_area;

// The true nearest triangle to q (ties to the lower index) among tris, skipping zero-area ones.
struct Nearest {
    uint32_t triangle = KDRT_INVALID_ID;
    oracle::Real d2 = -1;
    double distance = INFINITY;
};
Nearest brute_force(const std::vector<Tri> &tris, const float q[3]) {
    Nearest best;
    for (uint32_t i = 0; i < tris.size(); ++i) {
        if (zero_area(tris[i])) continue;
        const oracle::Real d2 = oracle::distance2(tris[i], q);
        if (best.d2 < 0 || d2 < best.d2) best.d2 = d2, best.triangle = i;
    }
    if (best.triangle != KDRT_INVALID_ID) best.distance = std::sqrt((long double)best.d2);
    return best;
}

// The worst error seen, in units of the bound, over a test (printed, so the margin shows).
// ratio: the worst error over the bound; near: the same where the point lies so near the surface
// that the reach term (the error of the arithmetic in double) is the bound, not the rounding of
// the result to float; exact: answers whose distance is the true one rounded to float.
struct Worst {
    double ratio = 0, near = 0;
    size_t answers = 0, exact = 0;
    void see(double error, double bound) { ratio = std::max(ratio, bound > 0 ? error / bound : (error > 0 ? INFINITY : 0)); }
    void see(double got, double truth, double reach) {
        const double bound = oracle::kRelative * truth + oracle::kReach * reach, error = std::fabs(got - truth);
        see(error, bound);
        if (oracle::kRelative * truth < oracle::kReach * reach / 64) near = std::max(near, error / (oracle::kReach * reach));
        ++answers, exact += float(truth) == float(got);
    }
    std::string text() const {
        return "worst error " + std::to_string(ratio) + " of the bound (" + std::to_string(near) +
               " of it on the surface), " + std::to_string(exact) + " of " + std::to_string(answers) +
               " answers the true distance rounded";
    }
};

// c (kdrt's answer for q over tris) against the brute force.
void check_answer(const std::vector<Tri> &tris, const float q[3], const kdrt_closest &c, const Nearest &truth,
                  Worst &worst, const std::string &what) {
    INFO(what << ": point (" << q[0] << ", " << q[1] << ", " << q[2] << ")");
    REQUIRE(truth.triangle != KDRT_INVALID_ID);
    REQUIRE(c.triangle < tris.size());
    const Tri &got = tris[c.triangle];
    const double reach = std::max(oracle::reach(tris[truth.triangle], q), oracle::reach(got, q));
    const double bound = oracle::kRelative * truth.distance + oracle::kReach * reach;
    INFO("kdrt: triangle " << c.triangle << " at " << c.distance << "; truth: triangle " << truth.triangle << " at "
                           << truth.distance << ", bound " << bound);
    CHECK(std::fabs(double(c.distance) - truth.distance) <= bound);
    worst.see(double(c.distance), truth.distance, reach);
    // The triangle named is a nearest one within the bound.
    CHECK(oracle::distance(got, q) <= truth.distance + 2 * oracle::kReach * reach);
    // The point lies on it (to float rounding), at the distance returned (to the bound).
    const double scale = std::max({std::fabs(double(c.point[0])), std::fabs(double(c.point[1])),
                                   std::fabs(double(c.point[2])), double(std::numeric_limits<float>::min())});
    CHECK(oracle::distance(got, c.point) <= 4 * oracle::kRelative * scale);
    double d2 = 0;
    for (int a = 0; a < 3; ++a) d2 += (double(c.point[a]) - q[a]) * (double(c.point[a]) - q[a]);
    CHECK(std::fabs(std::sqrt(d2) - double(c.distance)) <= 4 * oracle::kRelative * (scale + c.distance) + bound);
    CHECK(c.u >= 0.0f);
    CHECK(c.v >= 0.0f);
    CHECK(c.u + c.v <= 1.0f + 1e-6f);
    CHECK(c.geometry == 0);
    CHECK(c.instance == KDRT_INVALID_ID);
}

// Points for a mesh: near its surface (a point of a triangle moved by 1e-6 to 1 of its size),
// anywhere in its box and around it, far outside, exactly on vertices, on edges (midpoints
// rounded to float), and on the split planes of tree.
std::vector<std::array<float, 3>> points_for(const std::vector<Tri> &tris, const kdrt_tree *tree, size_t count,
                                             uint32_t seed) {
    common::Rng rng(seed);
    const kdrt_aabb box = kdrt_tree_bounds(tree);
    double size = 0;
    for (int a = 0; a < 3; ++a) size = std::max(size, double(box.max[a]) - box.min[a]);
    std::vector<std::array<float, 3>> pts;
    for (size_t i = 0; i < count; ++i) {
        std::array<float, 3> p{};
        const Tri &t = tris[rng.below(uint32_t(tris.size()))];
        double u = rng.uniform(), v = rng.uniform();
        if (u + v > 1) u = 1 - u, v = 1 - v;
        switch (i % 7) {
        case 0:
        case 1: {  // near the surface
            double d[3];
            rng.direction(d);
            const double off = size * std::pow(10.0, rng.range(-6, -1));
            for (int a = 0; a < 3; ++a)
                p[a] = float(t.p[0][a] + u * (double(t.p[1][a]) - t.p[0][a]) + v * (double(t.p[2][a]) - t.p[0][a]) + off * d[a]);
            break;
        }
        case 2:  // in and around the box
            for (int a = 0; a < 3; ++a) p[a] = float(rng.range(box.min[a] - 0.2 * size, box.max[a] + 0.2 * size));
            break;
        case 3: {  // far outside
            double d[3];
            rng.direction(d);
            for (int a = 0; a < 3; ++a) p[a] = float(0.5 * (double(box.min[a]) + box.max[a]) + 1e4 * size * d[a]);
            break;
        }
        case 4:  // a vertex
            for (int a = 0; a < 3; ++a) p[a] = t.p[rng.below(3)][a];
            break;
        case 5: {  // an edge's midpoint, rounded
            const int k = int(rng.below(3));
            for (int a = 0; a < 3; ++a) p[a] = float(0.5 * (double(t.p[k][a]) + t.p[(k + 1) % 3][a]));
            break;
        }
        default: {  // on a split plane (an inner node's), elsewhere in the node's box
            const uint32_t nodes = kdrt_tree_node_count(tree);
            kdrt_node_info info = kt::node_info(tree, rng.below(nodes));
            for (int a = 0; a < 3; ++a) p[a] = float(rng.range(info.bounds.min[a], info.bounds.max[a]));
            if (!info.is_leaf) p[size_t(info.axis)] = info.split;
            break;
        }
        }
        pts.push_back(p);
    }
    return pts;
}

using kt::drawn_count;

// Every builder and leaf size on mesh: each answer against the brute force and against leaf size 0.
void check_mesh(const common::Mesh &mesh, size_t count, uint32_t seed) {
    count = drawn_count(count);
    const std::vector<Tri> tris = triangles_of(mesh);
    kt::TreePtr scan = kt::build(mesh, 0);
    const std::vector<std::array<float, 3>> pts = points_for(tris, scan.get(), count, seed);
    std::vector<Nearest> truth;
    for (const auto &p : pts) truth.push_back(brute_force(tris, p.data()));
    std::vector<kdrt_closest> scanned(pts.size());
    Worst worst;
    for (size_t i = 0; i < pts.size(); ++i) {
        REQUIRE(kdrt_closest_point(scan.get(), pts[i].data(), INFINITY, &scanned[i]) == KDRT_SUCCESS);
        check_answer(tris, pts[i].data(), scanned[i], truth[i], worst, mesh.name + ", leaf size 0");
    }
    size_t differ = 0;
    for (const kt::Builder &b : kt::kBuilders)
        for (uint32_t leaf : {1u, 4u, 16u}) {
            kt::TreePtr tree = kt::build(mesh, leaf, b);
            // The scalar kernel's tree: its walk measures a triangle at a time where the AVX2
            // one measures 4 lanes at once, with the same answers bit for bit.
            kt::TreePtr scalar = kt::build(mesh, leaf, b, KDRT_BUILD_SCALAR_KERNEL);
            const std::string what = mesh.name + ", " + b.name + ", leaf size " + std::to_string(leaf);
            for (size_t i = 0; i < pts.size(); ++i) {
                kdrt_closest c, cs;
                REQUIRE(kdrt_closest_point(tree.get(), pts[i].data(), INFINITY, &c) == KDRT_SUCCESS);
                REQUIRE(kdrt_closest_point(scalar.get(), pts[i].data(), INFINITY, &cs) == KDRT_SUCCESS);
                if (std::memcmp(&c, &cs, sizeof c) != 0) ++differ;
                check_answer(tris, pts[i].data(), c, truth[i], worst, what);
                // The same answer as the scan, bit for bit (the walk prunes with a margin).
                if (c.triangle != scanned[i].triangle || std::memcmp(&c, &scanned[i], sizeof c) != 0) ++differ;
                // Within max_distance: the same answer at exactly its distance; nothing closer in.
                kdrt_closest m;
                REQUIRE(kdrt_closest_point(tree.get(), pts[i].data(), c.distance, &m) == KDRT_SUCCESS);
                CHECK(m.triangle == c.triangle);
                if (truth[i].distance > 1e-30) {
                    REQUIRE(kdrt_closest_point(tree.get(), pts[i].data(), float(truth[i].distance * 0.99), &m) == KDRT_SUCCESS);
                    CHECK(m.triangle == KDRT_INVALID_ID);
                    CHECK(m.distance == INFINITY);
                }
            }
        }
    CHECK(differ == 0);
    WARN(mesh.name << ": " << pts.size() << " points, " << worst.text());
}

common::Mesh scaled(common::Mesh mesh, float s, const char *suffix) {
    for (float &x : mesh.positions) x *= s;
    mesh.name += suffix;
    return mesh;
}

// Slivers: long thin triangles at every angle, some crossing, some nearly flat against each other.
common::Mesh slivers(uint32_t count, uint32_t seed) {
    common::Rng rng(seed);
    common::Mesh m;
    m.name = "slivers";
    for (uint32_t i = 0; i < count; ++i) {
        double c[3], d[3], e[3];
        for (double &x : c) x = rng.range(-10, 10);
        rng.direction(d), rng.direction(e);
        const double len = rng.range(1, 20), width = len * std::pow(10.0, rng.range(-7, -2));
        for (int a = 0; a < 3; ++a) m.positions.push_back(float(c[a] - len * d[a]));
        for (int a = 0; a < 3; ++a) m.positions.push_back(float(c[a] + len * d[a]));
        for (int a = 0; a < 3; ++a) m.positions.push_back(float(c[a] + width * e[a]));
    }
    return m;
}

}  // namespace

TEST_CASE("closest point: every builder and leaf size against the brute force", "[closest]") {
    check_mesh(kt::random_soup(300, 5), 140, 1);
    check_mesh(kt::grid(12, 12, 7), 140, 2);
    check_mesh(kt::sphere(10, 16, 3.0), 140, 3);
    check_mesh(slivers(150, 11), 140, 4);
}

TEST_CASE("closest point: near the centre of a fine sphere, where the walk's queue fills up", "[closest]") {
    // Every triangle is nearly as far as the nearest: the best-first walk finds more nodes worth
    // a look than its queue holds, leaves some out and goes over the tree again depth first
    // (kdrt__closest_walk_body). Its answers against the brute force and the scan, bit for bit.
    const common::Mesh mesh = kt::sphere(64, 128, 1.0);
    const std::vector<Tri> tris = triangles_of(mesh);
    kt::TreePtr scan = kt::build(mesh, 0);
    common::Rng rng(31);
    std::vector<std::array<float, 3>> pts{{{0, 0, 0}}};
    for (size_t i = 0; i < drawn_count(12); ++i) {
        std::array<float, 3> p{};
        for (float &x : p) x = float(rng.range(-1e-2, 1e-2));
        pts.push_back(p);
    }
    Worst worst;
    for (const kt::Builder &b : kt::kBuilders) {
        kt::TreePtr tree = kt::build(mesh, 4, b);
        for (const auto &p : pts) {
            kdrt_closest c, s;
            REQUIRE(kdrt_closest_point(tree.get(), p.data(), INFINITY, &c) == KDRT_SUCCESS);
            REQUIRE(kdrt_closest_point(scan.get(), p.data(), INFINITY, &s) == KDRT_SUCCESS);
            check_answer(tris, p.data(), c, brute_force(tris, p.data()), worst, mesh.name + ", " + b.name);
            CHECK(std::memcmp(&c, &s, sizeof c) == 0);
        }
    }
    WARN(mesh.name << ": " << pts.size() << " points, " << worst.text());
}

TEST_CASE("closest point: meshes at 1e-20 and 1e20", "[closest]") {
    check_mesh(scaled(kt::random_soup(150, 8), 1e-20f, " at 1e-20"), 70, 5);
    check_mesh(scaled(kt::random_soup(150, 8), 1e20f, " at 1e20"), 70, 6);
    check_mesh(scaled(kt::sphere(8, 12, 1.0), 1e-20f, " at 1e-20"), 70, 7);
    check_mesh(scaled(kt::sphere(8, 12, 1.0), 1e20f, " at 1e20"), 70, 8);
}

TEST_CASE("closest point: exact answers where they are exact", "[closest]") {
    // A unit right triangle and its mirror sharing the hypotenuse: the ties go to the lower index.
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    const uint32_t idx[] = {0, 1, 2, 1, 3, 2};
    kdrt_triangles view{};
    view.positions = pos, view.vertex_count = 4, view.indices = idx, view.triangle_count = 2;
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr tree(raw);
    kdrt_closest c;
    const float above[3] = {0.25f, 0.25f, 2.0f};
    REQUIRE(kdrt_closest_point(tree.get(), above, INFINITY, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    CHECK(c.distance == 2.0f);
    CHECK(c.u == 0.25f);
    CHECK(c.v == 0.25f);
    CHECK(c.point[0] == 0.25f);
    CHECK(c.point[1] == 0.25f);
    CHECK(c.point[2] == 0.0f);
    // On the shared edge, and on the shared corner: both at 0, the lower index wins.
    const float on_edge[3] = {0.5f, 0.5f, 0.0f}, on_corner[3] = {1.0f, 0.0f, 0.0f};
    REQUIRE(kdrt_closest_point(tree.get(), on_edge, INFINITY, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    CHECK(c.distance == 0.0f);
    REQUIRE(kdrt_closest_point(tree.get(), on_corner, 0.0f, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    CHECK(c.distance == 0.0f);
    CHECK(c.u == 1.0f);
    // Beyond the far corner: the corner, from the triangle that has it (1), at sqrt(2).
    const float beyond[3] = {2.0f, 2.0f, 0.0f};
    REQUIRE(kdrt_closest_point(tree.get(), beyond, INFINITY, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 1);
    CHECK(c.distance == float(std::sqrt(2.0)));
    CHECK(c.point[0] == 1.0f);
    CHECK(c.point[1] == 1.0f);
    // max_distance: closed at the distance itself, nothing found below it.
    REQUIRE(kdrt_closest_point(tree.get(), above, 2.0f, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    REQUIRE(kdrt_closest_point(tree.get(), above, 1.9999999f, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == KDRT_INVALID_ID);
    CHECK(c.distance == INFINITY);
}

TEST_CASE("closest point: a corner of a triangle whose rounding makes its areas all 0", "[closest]") {
    // Found by fuzz_queries: from the corner p0, the edge p2 - p1 rounds to -(p1 - p0) (the 1e5
    // swallows the rest), so all three signed areas come out 0, and their sum was a divisor:
    // NaN barycentrics. The edges decide such a point now.
    const float pos[] = {-0x1.8p-101f, -0x1.8p-101f, 0x1p-102f,  -0x1.cp-100f, -0x1.8p-101f, 0x1.86a0a6p+16f,
                         -0x1.8p-101f, -0x1.8p-101f, -0x1.4p-100f};
    kdrt_triangles view{};
    view.positions = pos, view.vertex_count = 3, view.triangle_count = 1;
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr tree(raw);
    for (int k = 0; k < 3; ++k) {
        kdrt_closest c;
        REQUIRE(kdrt_closest_point(tree.get(), pos + 3 * k, 0.0f, &c) == KDRT_SUCCESS);
        INFO("corner " << k);
        CHECK(c.triangle == 0);
        CHECK(c.distance == 0.0f);
        CHECK(c.u == (k == 1 ? 1.0f : 0.0f));
        CHECK(c.v == (k == 2 ? 1.0f : 0.0f));
        for (int a = 0; a < 3; ++a) CHECK(c.point[a] == pos[3 * k + a]);
    }
}

TEST_CASE("closest point: refused and empty queries", "[closest]") {
    const common::Mesh soup = kt::random_soup(20, 1);  // the tree borrows its buffers
    kt::TreePtr tree = kt::build(soup, 4);
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = INFINITY;
    const float ok[3] = {1, 2, 3};
    kdrt_closest c;
    for (const float bad : {nan, inf, -inf}) {
        for (int a = 0; a < 3; ++a) {
            float p[3] = {1, 2, 3};
            p[a] = bad;
            c.triangle = 0;
            CHECK(kdrt_closest_point(tree.get(), p, INFINITY, &c) == KDRT_ERROR_INVALID_QUERY);
            CHECK(c.triangle == KDRT_INVALID_ID);
        }
    }
    CHECK(kdrt_closest_point(tree.get(), ok, nan, &c) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_closest_point(tree.get(), ok, -1.0f, &c) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_closest_point(tree.get(), ok, -0.0f, &c) == KDRT_SUCCESS);
    CHECK(kdrt_closest_point(nullptr, ok, INFINITY, &c) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(c.triangle == KDRT_INVALID_ID);
    CHECK(kdrt_closest_point(tree.get(), nullptr, INFINITY, &c) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_closest_point(tree.get(), ok, INFINITY, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(std::string(kdrt_result_string(KDRT_ERROR_INVALID_QUERY)).find("query") != std::string::npos);
    // An empty tree finds nothing.
    kdrt_triangles none{};
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&none, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr empty(raw);
    REQUIRE(kdrt_closest_point(empty.get(), ok, INFINITY, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == KDRT_INVALID_ID);
}

// ---- scenes ----

namespace {

struct Placed {
    uint32_t id, triangle, instance;
    Tri world;
    uint32_t mask;
};

// Transforms that instances are tested under: identity, rotations, non-uniform scales, a mirror,
// shears and their mixtures, each with a translation.
std::vector<std::array<float, 12>> transforms() {
    std::vector<std::array<float, 12>> out;
    out.push_back({1, 0, 0, 5, 0, 1, 0, -3, 0, 0, 1, 2});
    const double c = std::cos(0.7), s = std::sin(0.7);
    out.push_back({float(c), float(-s), 0, 20, float(s), float(c), 0, 0, 0, 0, 1, 0});              // rotation
    out.push_back({8, 0, 0, -20, 0, 0.125f, 0, 4, 0, 0, 1, 0});                                    // scales
    out.push_back({-1, 0, 0, 0, 0, 1, 0, 30, 0, 0, 1, 0});                                         // mirror
    out.push_back({1, 3, 0, 0, 0, 1, 0, 0, 0, 0.5f, 1, -25});                                      // shears
    out.push_back({float(3 * c), float(-s), 0.2f, 7, float(s), float(0.3 * c), 0, -9, 1, 0, 4, 11}); // mixed
    return out;
}

}  // namespace

TEST_CASE("closest point: scenes with instances, masks and disabled entries", "[closest][scene]") {
    const common::Mesh a = kt::random_soup(60, 21), b = kt::sphere(6, 10, 2.0), ground = kt::grid(6, 6, 3);
    kt::TreePtr ta = kt::build(a, 4), tb = kt::build(b, 1, kt::kSahBuilders[2]);
    const auto ts = transforms();
    std::vector<kdrt_geometry> geos;
    std::vector<Placed> world;
    kdrt_triangles gview = ground.view();
    geos.push_back(kdrt_mesh_geometry(7, &gview));
    geos.back().mask = 1;
    {
        const auto tg = triangles_of(ground);
        for (uint32_t i = 0; i < tg.size(); ++i) world.push_back({7, i, KDRT_INVALID_ID, tg[i], 1});
    }
    const auto tris_a = triangles_of(a), tris_b = triangles_of(b);
    for (uint32_t k = 0; k < ts.size(); ++k) {
        const bool use_b = k % 2 == 1;
        const uint32_t id = 100 + 3 * k;
        geos.push_back(kdrt_instance_geometry(id, use_b ? tb.get() : ta.get(), ts[k].data()));
        geos.back().mask = k % 3 == 0 ? 2u : 4u;
        const auto &tris = use_b ? tris_b : tris_a;
        for (uint32_t i = 0; i < tris.size(); ++i)
            world.push_back({id, i, id, oracle::placed(tris[i], ts[k].data()), geos.back().mask});
    }
    kdrt_scene *raw = nullptr;
    REQUIRE(kdrt_scene_build(geos.data(), uint32_t(geos.size()), nullptr, &raw, nullptr) == KDRT_SUCCESS);
    struct Free {
        void operator()(kdrt_scene *s) const { kdrt_scene_free(s); }
    };
    std::unique_ptr<kdrt_scene, Free> scene(raw);
    const kdrt_aabb box = kdrt_scene_bounds(scene.get());
    common::Rng rng(77);
    Worst worst;
    uint32_t disabled = KDRT_INVALID_ID;
    for (int round = 0; round < 2; ++round) {
        if (round == 1) {  // an instance disabled: no query sees it
            disabled = 100 + 3 * 2;
            REQUIRE(kdrt_scene_enable(scene.get(), disabled, 0) == KDRT_SUCCESS);
            REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
        }
        for (int i = 0; i < int(drawn_count(300)); ++i) {
            float q[3];
            if (i % 3 == 0) {
                const Placed &p = world[rng.below(uint32_t(world.size()))];
                for (int a = 0; a < 3; ++a) q[a] = p.world.p[i % 2][a] + float(rng.range(-0.3, 0.3));
            } else {
                for (int a = 0; a < 3; ++a) q[a] = float(rng.range(box.min[a] - 5, box.max[a] + 5));
            }
            const uint32_t mask = i % 4 == 0 ? 0xFFFFFFFFu : (i % 4 == 1 ? 1u : (i % 4 == 2 ? 2u : 6u));
            // The brute force over the world triangles the query sees: (distance, geometry, triangle).
            const Placed *best = nullptr;
            oracle::Real best_d2 = -1;
            for (const Placed &p : world) {
                if (!(p.mask & mask) || p.id == disabled || zero_area(p.world)) continue;
                const oracle::Real d2 = oracle::distance2(p.world, q);
                if (!best || d2 < best_d2) best = &p, best_d2 = d2;
            }
            kdrt_closest c;
            REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, mask, &c) == KDRT_SUCCESS);
            REQUIRE(best);
            INFO("point " << q[0] << ", " << q[1] << ", " << q[2] << " mask " << mask << ": kdrt " << c.geometry << "/"
                          << c.triangle << " at " << c.distance << ", truth " << best->id << "/" << best->triangle);
            const Placed *got = nullptr;
            for (const Placed &p : world)
                if (p.id == c.geometry && p.triangle == c.triangle) got = &p;
            REQUIRE(got);
            CHECK(c.instance == got->instance);
            CHECK((got->mask & mask) != 0);
            CHECK(got->id != disabled);
            const double truth = std::sqrt((long double)best_d2);
            const double reach = std::max(oracle::reach(best->world, q), oracle::reach(got->world, q));
            const double bound = oracle::kRelative * truth + oracle::kReach * reach;
            CHECK(std::fabs(double(c.distance) - truth) <= bound);
            CHECK(oracle::distance(got->world, q) <= truth + 2 * oracle::kReach * reach);
            worst.see(double(c.distance), truth, reach);
            const double scale = std::max({std::fabs(double(c.point[0])), std::fabs(double(c.point[1])),
                                           std::fabs(double(c.point[2])), 1e-30});
            CHECK(oracle::distance(got->world, c.point) <= 4 * oracle::kRelative * scale);
        }
    }
    // Mask 0 sees nothing; refusals as on trees.
    const float q[3] = {0, 0, 0};
    kdrt_closest c;
    REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, 0, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == KDRT_INVALID_ID);
    const float bad[3] = {0, std::numeric_limits<float>::quiet_NaN(), 0};
    CHECK(kdrt_scene_closest_point(scene.get(), bad, INFINITY, 1, &c) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_scene_closest_point(scene.get(), q, -2.0f, 1, &c) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_scene_closest_point(nullptr, q, INFINITY, 1, &c) == KDRT_ERROR_NULL_ARGUMENT);
    WARN("scene: " << worst.text());
}

TEST_CASE("closest point: a non-uniform scale, where the object-space answer is wrong", "[closest][scene]") {
    // Two triangles in one tree: A, a unit square's half at x = 1 facing +x, and B, at y = 1.5
    // facing +y. Under the scale (10, 1, 1) the point (0, 0, 0) is 1.5 from B in the world but 10
    // from A, although in the tree's space A (at 1) is nearer than B (at 1.5).
    const float pos[] = {1, -1, -1, 1, 1, -1, 1, -1, 1,   // A
                         -1, 1.5f, -1, 1, 1.5f, -1, -1, 1.5f, 1};  // B
    kdrt_triangles view{};
    view.positions = pos, view.vertex_count = 6, view.triangle_count = 2;
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr tree(raw);
    const float m[12] = {10, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    kdrt_geometry g = kdrt_instance_geometry(3, tree.get(), m);
    kdrt_scene *sraw = nullptr;
    REQUIRE(kdrt_scene_build(&g, 1, nullptr, &sraw, nullptr) == KDRT_SUCCESS);
    const float q[3] = {0, 0, 0};
    kdrt_closest c;
    REQUIRE(kdrt_closest_point(tree.get(), q, INFINITY, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    REQUIRE(kdrt_scene_closest_point(sraw, q, INFINITY, 0xFFFFFFFFu, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 1);
    CHECK(c.geometry == 3);
    CHECK(c.instance == 3);
    CHECK(c.distance == 1.5f);
    CHECK(c.point[1] == 1.5f);
    kdrt_scene_free(sraw);
}

// ---- ties, range and allocation ----

namespace {

struct SceneFree {
    void operator()(kdrt_scene *s) const { kdrt_scene_free(s); }
};


int count_and_query(void *user, const kdrt_overlap *) {
    // A query from inside the callback, as the declaration allows.
    const kdrt_tree *tree = static_cast<const kdrt_tree *>(user);
    const float p[3] = {0.5f, 0.5f, 0.5f};
    kdrt_closest c;
    return kdrt_closest_point(tree, p, INFINITY, &c) == KDRT_SUCCESS;
}

}  // namespace

TEST_CASE("closest point: ties go to the lower triangle, then the lower geometry ID", "[closest][scene]") {
    // Triangles 0 and 2 are one triangle twice, 1 another one far away; a
    // mesh of them (ID 9) and the tree of them placed twice as it is (IDs 7 and 5): every
    // distance is tied three ways in the scene and two ways in each.
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5, 6, 5, 5, 5, 6, 5};
    const uint32_t idx[] = {0, 1, 2, 3, 4, 5, 0, 1, 2};
    kdrt_triangles view{};
    view.positions = pos, view.vertex_count = 6, view.indices = idx, view.triangle_count = 3;
    const float q[3] = {0.25f, 0.25f, 0.5f};
    for (const kt::Builder &b : kt::kBuilders)
        for (uint32_t leaf : {0u, 1u, 4u}) {
            kdrt_build_options o = kdrt_default_build_options();
            o.builder = b.builder, o.quality = b.quality, o.max_leaf_size = leaf;
            kdrt_tree *raw = nullptr;
            REQUIRE(kdrt_tree_build(&view, &o, &raw, nullptr) == KDRT_SUCCESS);
            kt::TreePtr tree(raw);
            kdrt_closest c;
            REQUIRE(kdrt_closest_point(tree.get(), q, INFINITY, &c) == KDRT_SUCCESS);
            CHECK(c.triangle == 0);
            CHECK(c.distance == 0.5f);
            std::vector<kdrt_geometry> geos = {kdrt_mesh_geometry(9, &view), kdrt_instance_geometry(7, tree.get(), nullptr),
                                               kdrt_instance_geometry(5, tree.get(), nullptr)};
            geos[2].mask = 2;
            kdrt_scene *sraw = nullptr;
            REQUIRE(kdrt_scene_build(geos.data(), 3, &o, &sraw, nullptr) == KDRT_SUCCESS);
            std::unique_ptr<kdrt_scene, SceneFree> scene(sraw);
            REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, 0xFFFFFFFFu, &c) == KDRT_SUCCESS);
            CHECK(c.geometry == 5);
            CHECK(c.instance == 5);
            CHECK(c.triangle == 0);
            REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, 1, &c) == KDRT_SUCCESS);  // 5 masked out
            CHECK(c.geometry == 7);
            CHECK(c.triangle == 0);
            REQUIRE(kdrt_scene_enable(scene.get(), 7, 0) == KDRT_SUCCESS);
            REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
            REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, 1, &c) == KDRT_SUCCESS);  // the mesh's turn
            CHECK(c.geometry == 9);
            CHECK(c.instance == KDRT_INVALID_ID);
            CHECK(c.triangle == 0);
            // The overlap queries report each of the tied triangles, each once.
            uint64_t n = 0;
            const kdrt_aabb box = {{0, 0, 0}, {0.5f, 0.5f, 0}};
            REQUIRE(kdrt_scene_overlap_box(scene.get(), &box, 0xFFFFFFFFu, nullptr, nullptr, &n) == KDRT_SUCCESS);
            CHECK(n == 4);  // triangles 0 and 2 of the mesh and of instance 5 (7 is disabled)
            // The mesh disabled too: mask 1 sees nothing, mask 2 instance 5 alone.
            REQUIRE(kdrt_scene_enable(scene.get(), 9, 0) == KDRT_SUCCESS);
            REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
            REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, 1, &c) == KDRT_SUCCESS);
            CHECK(c.triangle == KDRT_INVALID_ID);
            REQUIRE(kdrt_scene_overlap_box(scene.get(), &box, 1, nullptr, nullptr, &n) == KDRT_SUCCESS);
            CHECK(n == 0);
            REQUIRE(kdrt_scene_overlap_box(scene.get(), &box, 0xFFFFFFFFu, nullptr, nullptr, &n) == KDRT_SUCCESS);
            CHECK(n == 2);
        }
}

TEST_CASE("closest point: a scene's top level keeps an instance whose sliver measures nearer than its box", "[closest][scene]") {
    // A sliver 2^-100 across with a corner 1.6e5 away: from q its measured distance is 0 (its
    // error grows with the far corner, CLOSEST POINT AND OVERLAP), its box 2^-100 away. Beside it
    // a small triangle 2^-101 from q, measured exactly. One tree of both names the sliver; so
    // must a scene of the small triangle as a mesh and the sliver's tree as an instance, though
    // the best the mesh gives is nearer than the sliver's box: the top level prunes by instances'
    // world boxes, widened by far more than such an error.
    const float q[3] = {-0x1p-100f, 0x1.8p-101f, -0x1.cp-100f};
    const float sliver[] = {-0x1p-100f, -0x1p-102f, -0x1.cp-100f, -0x1p-100f, -0x1.cp-100f, -0x1.cp-100f,
                            0x1p-101f,  -0x1.36f852p+17f, -0x1p-102f};
    const float x = q[0] + 0x1p-101f;  // the small triangle's plane, x = -2^-101
    const float small[] = {x, q[1] - 0x1p-100f, q[2] - 0x1p-100f, x, q[1] + 0x1p-100f, q[2] - 0x1p-100f,
                           x, q[1], q[2] + 0x1p-100f};
    float both[18];
    std::copy(sliver, sliver + 9, both);
    std::copy(small, small + 9, both + 9);
    const auto view_of = [](const float *pos, uint32_t triangles) {
        kdrt_triangles v{};
        v.positions = pos, v.vertex_count = 3 * triangles, v.triangle_count = triangles;
        return v;
    };
    const kdrt_triangles sliver_view = view_of(sliver, 1), small_view = view_of(small, 1), both_view = view_of(both, 2);
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&both_view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr tree_of_both(raw);
    kdrt_closest expected;
    REQUIRE(kdrt_closest_point(tree_of_both.get(), q, INFINITY, &expected) == KDRT_SUCCESS);
    REQUIRE(expected.triangle == 0);  // the sliver, measured nearer than the small triangle
    REQUIRE(expected.distance < 0x1p-101f);
    REQUIRE(kdrt_tree_build(&sliver_view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr sliver_tree(raw);
    const kdrt_geometry geos[] = {kdrt_mesh_geometry(1, &small_view), kdrt_instance_geometry(2, sliver_tree.get(), nullptr)};
    kdrt_scene *sraw = nullptr;
    REQUIRE(kdrt_scene_build(geos, 2, nullptr, &sraw, nullptr) == KDRT_SUCCESS);
    std::unique_ptr<kdrt_scene, SceneFree> scene(sraw);
    kdrt_closest c;
    REQUIRE(kdrt_scene_closest_point(scene.get(), q, INFINITY, 0xFFFFFFFFu, &c) == KDRT_SUCCESS);
    CHECK(c.geometry == 2);
    CHECK(c.instance == 2);
    CHECK(c.triangle == 0);
    CHECK(c.distance == expected.distance);
}

TEST_CASE("closest point: distances beyond float's range", "[closest]") {
    // A triangle near -3e38 and a point at +3e38: about 6e38 apart, beyond the largest float.
    const float big = 3e38f, pos[] = {-big, -big, 0, -big, 0, 0, -big, -big, 1e38f};
    kdrt_triangles view{};
    view.positions = pos, view.vertex_count = 3, view.triangle_count = 1;
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr tree(raw);
    const float q[3] = {big, -big, 0};
    kdrt_closest c;
    REQUIRE(kdrt_closest_point(tree.get(), q, INFINITY, &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    CHECK(c.distance == INFINITY);
    CHECK(c.point[0] == -big);
    REQUIRE(kdrt_closest_point(tree.get(), q, std::numeric_limits<float>::max(), &c) == KDRT_SUCCESS);
    CHECK(c.triangle == KDRT_INVALID_ID);
    // Just within the largest float: found, finite.
    const float near_q[3] = {0, -big, 0};
    REQUIRE(kdrt_closest_point(tree.get(), near_q, std::numeric_limits<float>::max(), &c) == KDRT_SUCCESS);
    CHECK(c.triangle == 0);
    CHECK(c.distance == big);
}

TEST_CASE("closest point and overlap: the queries allocate nothing", "[closest][overlap][alloc]") {
    const common::Mesh mesh = kt::sphere(12, 18, 2.0), ground = kt::translated(kt::grid(8, 8, 5), -4, -4, -3);
    kt::CallCounter counter;
    kdrt_build_options o = kdrt_default_build_options();
    o.allocator = counter.hooks();
    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    const float shear[12] = {1, 0.5f, 0, 6, 0, 2, 0, 0, 0, 0, -1, 1};
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(1, nullptr), kdrt_instance_geometry(3, tree, shear)};
    entries[0].mesh = ground.view();
    kdrt_scene *scene = nullptr;
    REQUIRE(kdrt_scene_build(entries.data(), uint32_t(entries.size()), &o, &scene, nullptr) == KDRT_SUCCESS);
    const size_t calls = counter.calls, frees = counter.frees;
    common::Rng rng(3);
    uint64_t total = 0;
    for (int i = 0; i < 200; ++i) {
        float p[3];
        for (float &x : p) x = float(rng.range(-8, 8));
        const float r = float(rng.range(0, 3));
        const kdrt_aabb box = {{p[0] - r, p[1] - r, p[2]}, {p[0] + r, p[1], p[2] + r}};
        kdrt_closest c;
        uint64_t n = 0;
        REQUIRE(kdrt_closest_point(tree, p, INFINITY, &c) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_closest_point(scene, p, i % 2 ? INFINITY : r, 0xFFFFFFFFu, &c) == KDRT_SUCCESS);
        REQUIRE(kdrt_overlap_box(tree, &box, count_and_query, tree, &n) == KDRT_SUCCESS);
        total += n;
        REQUIRE(kdrt_overlap_sphere(tree, p, r, nullptr, nullptr, &n) == KDRT_SUCCESS);
        total += n;
        REQUIRE(kdrt_scene_overlap_box(scene, &box, 0xFFFFFFFFu, count_and_query, tree, &n) == KDRT_SUCCESS);
        total += n;
        REQUIRE(kdrt_scene_overlap_sphere(scene, p, r, 0xFFFFFFFFu, nullptr, nullptr, &n) == KDRT_SUCCESS);
        total += n;
    }
    CHECK(total > 200);
    CHECK(counter.calls == calls);
    CHECK(counter.frees == frees);
    kdrt_scene_free(scene);
    kdrt_tree_free(tree);
    CHECK(counter.frees == counter.calls);
}
