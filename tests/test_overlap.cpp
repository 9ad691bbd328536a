// kdrt_overlap_box() and kdrt_overlap_sphere(), and their scene forms, against the brute force of
// point_oracle.hpp (every triangle, quadruple precision): each triangle that meets the box
// reported exactly once, those that only touch it included, the set equal to the brute force's
// with no tolerance; for balls, the same where a triangle is farther from the sphere's surface
// than the manual's bound, a corner on the sphere counting exactly, and the set equal to the scan
// of leaf size 0 (the same arithmetic) everywhere. Every builder and quality, leaf sizes 0 to 16,
// both kernels (this suite also runs in kdrt_scalar_tests); boxes of every size, flat, empty,
// inverted and half-infinite ones, boxes that are exactly a node's box or lie in a split plane;
// NaN boxes, NaN and infinite centres, negative and NaN radii refused; the callback stopping the
// query; scenes with instances under rotations, scales, mirrors and shears, and masks.

#include "point_oracle.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace {

using oracle::Tri;

using oracle::triangles_of;
using oracle::zero_area;

// What a query reported, in order, and how often it was called.
struct Collected {
    std::vector<kdrt_overlap> found;
    size_t stop_after = 0;  // 0: never stop
};
int collect(void *user, const kdrt_overlap *f) {
    Collected *c = static_cast<Collected *>(user);
    c->found.push_back(*f);
    return c->stop_after == 0 || c->found.size() < c->stop_after;
}

// The triangles a tree query reported, sorted; FAILs on a triangle reported twice.
std::vector<uint32_t> box_query(const kdrt_tree *tree, const kdrt_aabb &box) {
    Collected c;
    uint64_t count = 12345;
    REQUIRE(kdrt_overlap_box(tree, &box, collect, &c, &count) == KDRT_SUCCESS);
    REQUIRE(count == c.found.size());
    std::vector<uint32_t> ids;
    for (const kdrt_overlap &f : c.found) {
        CHECK(f.geometry == 0);
        CHECK(f.instance == KDRT_INVALID_ID);
        ids.push_back(f.triangle);
    }
    std::sort(ids.begin(), ids.end());
    CHECK(std::adjacent_find(ids.begin(), ids.end()) == ids.end());
    return ids;
}
std::vector<uint32_t> sphere_query(const kdrt_tree *tree, const float c[3], float r) {
    Collected col;
    uint64_t count = 12345;
    REQUIRE(kdrt_overlap_sphere(tree, c, r, collect, &col, &count) == KDRT_SUCCESS);
    REQUIRE(count == col.found.size());
    std::vector<uint32_t> ids;
    for (const kdrt_overlap &f : col.found) ids.push_back(f.triangle);
    std::sort(ids.begin(), ids.end());
    CHECK(std::adjacent_find(ids.begin(), ids.end()) == ids.end());
    return ids;
}

// The brute force: every triangle kdrt keeps that meets the closed box.
std::vector<uint32_t> box_truth(const std::vector<Tri> &tris, const kdrt_aabb &box) {
    std::vector<uint32_t> ids;
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        if (!(box.min[a] <= box.max[a]) || box.min[a] == INFINITY || box.max[a] == -INFINITY) return ids;
        lo[a] = std::max(box.min[a], -std::numeric_limits<float>::max());
        hi[a] = std::min(box.max[a], std::numeric_limits<float>::max());
    }
    for (uint32_t i = 0; i < tris.size(); ++i)
        if (!zero_area(tris[i]) && oracle::meets_box(tris[i], lo, hi)) ids.push_back(i);
    return ids;
}

// A ball's brute force: must[i] 1 (meets it: a corner in it exactly, or farther inside than the
// bound), -1 (misses it by more than the bound), 0 (within the bound of its surface: either).
std::vector<int> ball_truth(const std::vector<Tri> &tris, const float c[3], float r, size_t *undecided) {
    std::vector<int> must(tris.size(), -1);
    for (uint32_t i = 0; i < tris.size(); ++i) {
        if (zero_area(tris[i])) continue;
        const oracle::Real r2 = oracle::Real(r) * oracle::Real(r);
        bool corner = false;
        for (int k = 0; k < 3; ++k) {
            oracle::Real d2 = 0;
            for (int a = 0; a < 3; ++a) d2 += (oracle::Real(tris[i].p[k][a]) - c[a]) * (oracle::Real(tris[i].p[k][a]) - c[a]);
            corner = corner || d2 <= r2;
        }
        const double d = oracle::distance(tris[i], c), band = oracle::kReach * oracle::reach(tris[i], c);
        must[i] = corner || d < double(r) - band ? 1 : (d > double(r) + band ? -1 : 0);
        *undecided += must[i] == 0;
    }
    return must;
}

std::string box_text(const kdrt_aabb &b) {
    char s[256];
    std::snprintf(s, sizeof s, "box (%.9g %.9g %.9g) - (%.9g %.9g %.9g)", b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]);
    return s;
}

// Boxes for a mesh (see the file's comment), from its triangles and the nodes of tree.
std::vector<kdrt_aabb> boxes_for(const std::vector<Tri> &tris, const kdrt_tree *tree, size_t count, uint32_t seed) {
    common::Rng rng(seed);
    const kdrt_aabb all = kdrt_tree_bounds(tree);
    double size = 0;
    for (int a = 0; a < 3; ++a) size = std::max(size, double(all.max[a]) - all.min[a]);
    std::vector<kdrt_aabb> boxes;
    for (size_t i = 0; i < count; ++i) {
        kdrt_aabb b;
        const Tri &t = tris[rng.below(uint32_t(tris.size()))];
        const uint32_t vi = rng.below(3);
        const float *v = t.p[vi];
        const double half = size * std::pow(10.0, rng.range(-4, 0));
        for (int a = 0; a < 3; ++a) {
            const double c = rng.range(all.min[a], all.max[a]);
            b.min[a] = float(c - half * rng.uniform()), b.max[a] = float(c + half * rng.uniform());
        }
        switch (i % 8) {
        case 0: break;  // anywhere, of any size
        case 1:         // a corner of the box on a vertex: touching it
            for (int a = 0; a < 3; ++a)
                if (rng.below(2)) b.max[a] = v[a], b.min[a] = float(v[a] - half);
                else b.min[a] = v[a], b.max[a] = float(v[a] + half);
            break;
        case 2: {  // flat: a rectangle, a segment or a point, often through a vertex
            const uint32_t flat = 1 + rng.below(3);
            for (uint32_t k = 0; k < flat; ++k) {
                const uint32_t a = rng.below(3);
                b.min[a] = b.max[a] = rng.below(2) ? v[a] : float(rng.range(all.min[a], all.max[a]));
            }
            break;
        }
        case 3: {  // a node's box exactly, or a leaf's
            const kdrt_node_info info = kt::node_info(tree, rng.below(kdrt_tree_node_count(tree)));
            b = info.bounds;
            break;
        }
        case 4: {  // flat in a split plane, across the node
            const kdrt_node_info info = kt::node_info(tree, rng.below(kdrt_tree_node_count(tree)));
            b = info.bounds;
            if (!info.is_leaf) b.min[info.axis] = b.max[info.axis] = info.split;
            break;
        }
        case 5: {  // a box between two vertices of a triangle (its edge's box): touches the edge
            const float *w = t.p[(vi + 1 + rng.below(2)) % 3];
            for (int a = 0; a < 3; ++a) b.min[a] = std::min(v[a], w[a]), b.max[a] = std::max(v[a], w[a]);
            break;
        }
        case 6: {  // half-infinite or infinite on an axis
            const uint32_t a = rng.below(3);
            if (rng.below(2)) b.min[a] = -INFINITY;
            else b.max[a] = INFINITY;
            if (rng.below(4) == 0) b.min[a] = -INFINITY, b.max[a] = INFINITY;
            break;
        }
        default:  // the whole mesh, or beyond it
            b = all;
            if (rng.below(2))
                for (int a = 0; a < 3; ++a) b.min[a] -= float(size), b.max[a] += float(size);
            break;
        }
        boxes.push_back(b);
    }
    return boxes;
}

using kt::drawn_count;

// Every builder and leaf size on mesh: boxes and balls against the brute force.
void check_mesh(const common::Mesh &mesh, size_t count, uint32_t seed) {
    count = drawn_count(count);
    const std::vector<Tri> tris = triangles_of(mesh);
    kt::TreePtr scan = kt::build(mesh, 0);
    kt::TreePtr shaped = kt::build(mesh, 4, kt::kSahBuilders[1]);
    const std::vector<kdrt_aabb> boxes = boxes_for(tris, shaped.get(), count, seed);
    std::vector<std::vector<uint32_t>> truth;
    size_t touching = 0, reported = 0;
    for (const kdrt_aabb &b : boxes) truth.push_back(box_truth(tris, b));
    // Balls: around random points, vertices and edges, of every size; some just touching a corner.
    common::Rng rng(seed + 1000);
    const kdrt_aabb all = kdrt_tree_bounds(scan.get());
    double size = 0;
    for (int a = 0; a < 3; ++a) size = std::max(size, double(all.max[a]) - all.min[a]);
    struct Ball {
        float c[3], r;
    };
    std::vector<Ball> balls;
    for (size_t i = 0; i < count; ++i) {
        Ball b;
        const Tri &t = tris[rng.below(uint32_t(tris.size()))];
        const float *v = t.p[rng.below(3)], *w = t.p[rng.below(3)];
        b.r = float(size * std::pow(10.0, rng.range(-4, 0)));
        for (int a = 0; a < 3; ++a) b.c[a] = float(rng.range(all.min[a], all.max[a]));
        switch (i % 4) {
        case 0: break;
        case 1:  // centred on a vertex, radius 0 or reaching exactly to another corner along an axis
            for (int a = 0; a < 3; ++a) b.c[a] = v[a];
            if (rng.below(2)) b.r = 0.0f;
            else {
                const int a = int(rng.below(3));
                b.c[a] = v[a] + b.r;  // then the corner v lies on the sphere when the sum is exact
                if (double(b.c[a]) - double(v[a]) != double(b.r)) b.c[a] = v[a];
            }
            break;
        case 2:  // on an edge's midpoint
            for (int a = 0; a < 3; ++a) b.c[a] = float(0.5 * (double(v[a]) + w[a]));
            break;
        default:
            if (rng.below(8) == 0) b.r = INFINITY;
            break;
        }
        balls.push_back(b);
    }
    std::vector<std::vector<uint32_t>> scanned_balls;
    size_t undecided = 0, checked = 0;
    for (const Ball &b : balls) scanned_balls.push_back(sphere_query(scan.get(), b.c, b.r));
    std::vector<std::vector<int>> ball_musts;
    for (const Ball &b : balls) ball_musts.push_back(ball_truth(tris, b.c, b.r, &undecided));

    auto check_tree = [&](const kdrt_tree *tree, const std::string &what) {
        for (size_t i = 0; i < boxes.size(); ++i) {
            INFO(what << ", " << box_text(boxes[i]));
            const std::vector<uint32_t> got = box_query(tree, boxes[i]);
            CHECK(got == truth[i]);
            reported += got.size();
        }
        for (size_t i = 0; i < balls.size(); ++i) {
            INFO(what << ", ball (" << balls[i].c[0] << ", " << balls[i].c[1] << ", " << balls[i].c[2] << ") r " << balls[i].r);
            const std::vector<uint32_t> got = sphere_query(tree, balls[i].c, balls[i].r);
            CHECK(got == scanned_balls[i]);  // the same decisions as every triangle tested
            std::vector<char> in(tris.size(), 0);
            for (uint32_t t : got) in[t] = 1;
            for (uint32_t t = 0; t < tris.size(); ++t) {
                if (ball_musts[i][t] == 0) continue;
                INFO("triangle " << t);
                CHECK(bool(in[t]) == (ball_musts[i][t] > 0));
                ++checked;
            }
        }
    };
    check_tree(scan.get(), mesh.name + ", leaf size 0");
    for (const kt::Builder &b : kt::kBuilders)
        for (uint32_t leaf : {1u, 4u, 16u}) {
            kt::TreePtr tree = kt::build(mesh, leaf, b);
            check_tree(tree.get(), mesh.name + ", " + b.name + ", leaf size " + std::to_string(leaf));
        }
    for (size_t i = 0; i < boxes.size(); ++i) touching += !truth[i].empty();
    WARN(mesh.name << ": " << boxes.size() << " boxes (" << touching << " meeting triangles, " << reported
                   << " reports), " << balls.size() << " balls, " << checked << " ball decisions checked, "
                   << undecided << " within the bound of the surface");
}

// Big triangles across many leaves among small ones: each big one is referred to by many leaves.
common::Mesh big_and_small(uint32_t seed) {
    common::Mesh m = kt::random_soup(200, seed);
    const float big[] = {-50, -50, 1, 1100, -50, 2, -50, 1100, 3, 0, 500, -10, 1000, 510, 900, 400, 0, 1000};
    m.positions.insert(m.positions.end(), big, big + 18);
    m.name = "big_and_small";
    return m;
}

}  // namespace

TEST_CASE("overlap: every builder and leaf size against the brute force", "[overlap]") {
    check_mesh(kt::random_soup(250, 9), 120, 1);
    check_mesh(kt::grid(10, 10, 4), 120, 2);
    check_mesh(kt::sphere(8, 14, 3.0), 120, 3);
    check_mesh(big_and_small(12), 120, 4);
}

TEST_CASE("overlap: meshes at 1e-20 and 1e20", "[overlap]") {
    for (const float s : {1e-20f, 1e20f}) {
        common::Mesh m = kt::random_soup(120, 3);
        for (float &x : m.positions) x *= s;
        m.name += s < 1 ? " at 1e-20" : " at 1e20";
        check_mesh(m, 60, 9);
    }
}

TEST_CASE("overlap: touching, flat, empty and refused shapes", "[overlap]") {
    // One unit right triangle in z = 0.
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    kdrt_triangles view{};
    view.positions = pos, view.vertex_count = 3, view.triangle_count = 1;
    kdrt_tree *raw = nullptr;
    REQUIRE(kdrt_tree_build(&view, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr tree(raw);
    auto count_box = [&](float x0, float y0, float z0, float x1, float y1, float z1) {
        kdrt_aabb b = {{x0, y0, z0}, {x1, y1, z1}};
        uint64_t n = 99;
        REQUIRE(kdrt_overlap_box(tree.get(), &b, nullptr, nullptr, &n) == KDRT_SUCCESS);
        return n;
    };
    CHECK(count_box(-1, -1, 0, 2, 2, 0) == 1);              // flat, in the triangle's plane
    CHECK(count_box(0.5f, 0.5f, -1, 1, 1, 1) == 1);         // touching the hypotenuse at (0.5, 0.5)
    CHECK(count_box(0.5f, 0.50000006f, -1, 1, 1, 1) == 0);  // a float beyond it
    CHECK(count_box(1, 0, 0, 1, 0, 0) == 1);                // the corner itself, a point box
    CHECK(count_box(0.25f, 0.25f, 0, 0.25f, 0.25f, 0) == 1);  // a point inside
    CHECK(count_box(0.25f, 0.25f, 1e-30f, 0.25f, 0.25f, 1) == 0);  // just above it
    CHECK(count_box(0.25f, 0.25f, -1, 0.25f, 0.25f, 1) == 1);      // a segment through it
    CHECK(count_box(2, 2, 2, 1, 1, 1) == 0);                // inverted: empty
    CHECK(count_box(INFINITY, -1, -1, INFINITY, 1, 1) == 0);  // at +infinity: empty
    CHECK(count_box(-INFINITY, -INFINITY, -INFINITY, 0, 0, 0) == 1);  // a half-space corner
    const float nan = std::numeric_limits<float>::quiet_NaN();
    kdrt_aabb bad = {{0, 0, 0}, {1, nan, 1}};
    uint64_t n = 99;
    CHECK(kdrt_overlap_box(tree.get(), &bad, nullptr, nullptr, &n) == KDRT_ERROR_INVALID_QUERY);
    CHECK(n == 0);
    CHECK(kdrt_overlap_box(nullptr, &bad, nullptr, nullptr, &n) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_overlap_box(tree.get(), nullptr, nullptr, nullptr, &n) == KDRT_ERROR_NULL_ARGUMENT);
    // Balls: touching the corner (1, 0, 0) from (2, 0, 0) and from (1, 0, 1); the edge from below.
    auto count_ball = [&](float x, float y, float z, float r) {
        const float c[3] = {x, y, z};
        uint64_t k = 99;
        REQUIRE(kdrt_overlap_sphere(tree.get(), c, r, nullptr, nullptr, &k) == KDRT_SUCCESS);
        return k;
    };
    CHECK(count_ball(2, 0, 0, 1) == 1);
    CHECK(count_ball(2, 0, 0, 0.99999994f) == 0);
    CHECK(count_ball(1, 0, 1, 1) == 1);
    CHECK(count_ball(0.5f, -1, 0, 1) == 1);  // touching the edge y = 0 at (0.5, 0, 0)
    CHECK(count_ball(0.25f, 0.25f, 0, 0) == 1);  // radius 0 on the triangle
    CHECK(count_ball(0, 0, 0, 0) == 1);          // radius 0 on its corner
    CHECK(count_ball(0.25f, 0.25f, 2, 1.9999999f) == 0);
    CHECK(count_ball(0.25f, 0.25f, 2, 2) == 1);
    CHECK(count_ball(1e30f, 0, 0, INFINITY) == 1);
    const float c[3] = {0, 0, 0}, cbad[3] = {0, INFINITY, 0};
    CHECK(kdrt_overlap_sphere(tree.get(), c, -1.0f, nullptr, nullptr, &n) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_overlap_sphere(tree.get(), c, nan, nullptr, nullptr, &n) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_overlap_sphere(tree.get(), cbad, 1.0f, nullptr, nullptr, &n) == KDRT_ERROR_INVALID_QUERY);
    const float cnan[3] = {nan, 0, 0};
    CHECK(kdrt_overlap_sphere(tree.get(), cnan, 1.0f, nullptr, nullptr, &n) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_overlap_sphere(tree.get(), nullptr, 1.0f, nullptr, nullptr, &n) == KDRT_ERROR_NULL_ARGUMENT);
    // An empty tree meets nothing.
    kdrt_triangles none{};
    REQUIRE(kdrt_tree_build(&none, nullptr, &raw, nullptr) == KDRT_SUCCESS);
    kt::TreePtr empty(raw);
    kdrt_aabb everything = {{-INFINITY, -INFINITY, -INFINITY}, {INFINITY, INFINITY, INFINITY}};
    CHECK(kdrt_overlap_box(empty.get(), &everything, nullptr, nullptr, &n) == KDRT_SUCCESS);
    CHECK(n == 0);
}

TEST_CASE("overlap: the callback stops the query", "[overlap]") {
    const common::Mesh mesh = kt::grid(8, 8, 1);
    for (const kt::Builder &b : kt::kBuilders) {
        kt::TreePtr tree = kt::build(mesh, 4, b);
        const kdrt_aabb all = {{-INFINITY, -INFINITY, -INFINITY}, {INFINITY, INFINITY, INFINITY}};
        for (size_t stop : {size_t(1), size_t(2), size_t(17), size_t(127), size_t(128), size_t(500)}) {
            Collected c;
            c.stop_after = stop;
            uint64_t n = 0;
            REQUIRE(kdrt_overlap_box(tree.get(), &all, collect, &c, &n) == KDRT_SUCCESS);
            CHECK(n == std::min<size_t>(stop, mesh.triangle_count()));
            CHECK(c.found.size() == n);
            Collected s;
            s.stop_after = stop;
            const float centre[3] = {4, 4, 0};
            REQUIRE(kdrt_overlap_sphere(tree.get(), centre, INFINITY, collect, &s, &n) == KDRT_SUCCESS);
            CHECK(n == std::min<size_t>(stop, mesh.triangle_count()));
            CHECK(s.found.size() == n);
        }
    }
}

// ---- scenes ----

TEST_CASE("overlap: scenes with instances and masks against the world's brute force", "[overlap][scene]") {
    const common::Mesh a = kt::random_soup(50, 2), b = kt::sphere(5, 9, 2.0), ground = kt::grid(5, 5, 8);
    kt::TreePtr ta = kt::build(a, 4, kt::kSahBuilders[0]), tb = kt::build(b, 2, kt::kBuilders[0]);
    const double c = std::cos(1.1), s = std::sin(1.1);
    const std::array<float, 12> ts[] = {
        {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0},
        {float(c), 0, float(s), 10, 0, 1, 0, 2, float(-s), 0, float(c), -4},  // rotation
        {6, 0, 0, -8, 0, 0.25f, 0, 3, 0, 0, 2, 1},                            // scales
        {1, 0, 0, 5, 0, -1, 0, 0, 0, 0, 1, 6},                                // mirror
        {1, 2, 0, -3, 0, 1, 0.5f, 0, 0.25f, 0, 1, 9},                         // shears
    };
    struct Placed {
        uint32_t id, triangle, instance, mask;
        Tri world;
    };
    std::vector<kdrt_geometry> geos;
    std::vector<Placed> world;
    kdrt_triangles gview = ground.view();
    geos.push_back(kdrt_mesh_geometry(4, &gview));
    geos.back().mask = 1;
    {
        const auto tg = triangles_of(ground);
        for (uint32_t i = 0; i < tg.size(); ++i) world.push_back({4, i, KDRT_INVALID_ID, 1, tg[i]});
    }
    const auto tris_a = triangles_of(a), tris_b = triangles_of(b);
    for (uint32_t k = 0; k < 5; ++k) {
        const uint32_t id = 50 + k;
        const bool use_b = k % 2 == 0;
        geos.push_back(kdrt_instance_geometry(id, use_b ? tb.get() : ta.get(), ts[k].data()));
        geos.back().mask = k < 3 ? 2u : 4u;
        const auto &tris = use_b ? tris_b : tris_a;
        for (uint32_t i = 0; i < tris.size(); ++i)
            world.push_back({id, i, id, geos.back().mask, oracle::placed(tris[i], ts[k].data())});
    }
    kdrt_scene *raw = nullptr;
    REQUIRE(kdrt_scene_build(geos.data(), uint32_t(geos.size()), nullptr, &raw, nullptr) == KDRT_SUCCESS);
    struct Free {
        void operator()(kdrt_scene *p) const { kdrt_scene_free(p); }
    };
    std::unique_ptr<kdrt_scene, Free> scene(raw);
    const kdrt_aabb all = kdrt_scene_bounds(scene.get());
    common::Rng rng(5);
    size_t reports = 0, checked = 0;
    for (int i = 0; i < int(drawn_count(400)); ++i) {
        const uint32_t mask = i % 3 == 0 ? 0xFFFFFFFFu : (i % 3 == 1 ? 2u : 5u);
        const Placed &near = world[rng.below(uint32_t(world.size()))];
        const double half = std::pow(10.0, rng.range(-3, 1.3));
        float centre[3];
        for (int a = 0; a < 3; ++a)
            centre[a] = i % 2 ? near.world.p[0][a] : float(rng.range(all.min[a], all.max[a]));
        Collected col;
        uint64_t n = 0;
        auto key = [](uint32_t g, uint32_t t) { return (uint64_t(g) << 32) | t; };
        std::vector<uint64_t> got, want;
        if (i % 4 < 2) {
            kdrt_aabb box;
            for (int a = 0; a < 3; ++a) box.min[a] = float(centre[a] - half * rng.uniform()), box.max[a] = float(centre[a] + half * rng.uniform());
            if (i % 8 == 1) box.max[2] = box.min[2];  // flat
            REQUIRE(kdrt_scene_overlap_box(scene.get(), &box, mask, collect, &col, &n) == KDRT_SUCCESS);
            for (const Placed &p : world)
                if ((p.mask & mask) && !zero_area(p.world) && oracle::meets_box(p.world, box.min, box.max))
                    want.push_back(key(p.id, p.triangle));
            for (const kdrt_overlap &f : col.found) got.push_back(key(f.geometry, f.triangle));
            std::sort(got.begin(), got.end());
            INFO(box_text(box) << " mask " << mask);
            CHECK(std::adjacent_find(got.begin(), got.end()) == got.end());
            CHECK(got == want);
            checked += want.size();
        } else {
            const float r = float(half);
            REQUIRE(kdrt_scene_overlap_sphere(scene.get(), centre, r, mask, collect, &col, &n) == KDRT_SUCCESS);
            for (const kdrt_overlap &f : col.found) got.push_back(key(f.geometry, f.triangle));
            std::sort(got.begin(), got.end());
            CHECK(std::adjacent_find(got.begin(), got.end()) == got.end());
            for (const Placed &p : world) {
                if (!(p.mask & mask) || zero_area(p.world)) continue;
                const double d = oracle::distance(p.world, centre), band = oracle::kReach * oracle::reach(p.world, centre);
                const bool in = std::binary_search(got.begin(), got.end(), key(p.id, p.triangle));
                INFO("ball " << centre[0] << ", " << centre[1] << ", " << centre[2] << " r " << r << ": " << p.id << "/" << p.triangle << " at " << d);
                if (d < r - band) {
                    CHECK(in);
                    ++checked;
                } else if (d > r + band) {
                    CHECK(!in);
                    ++checked;
                }
            }
        }
        CHECK(n == col.found.size());
        for (const kdrt_overlap &f : col.found) {
            CHECK(f.instance == (f.geometry == 4 ? KDRT_INVALID_ID : f.geometry));
            const Placed *p = nullptr;
            for (const Placed &q : world)
                if (q.id == f.geometry && q.triangle == f.triangle) p = &q;
            REQUIRE(p);
            CHECK((p->mask & mask) != 0);
        }
        reports += col.found.size();
    }
    // The callback stops a scene query too; mask 0 finds nothing; refusals.
    const kdrt_aabb everything = {{-INFINITY, -INFINITY, -INFINITY}, {INFINITY, INFINITY, INFINITY}};
    Collected col;
    col.stop_after = 3;
    uint64_t n = 0;
    REQUIRE(kdrt_scene_overlap_box(scene.get(), &everything, 0xFFFFFFFFu, collect, &col, &n) == KDRT_SUCCESS);
    CHECK(n == 3);
    REQUIRE(kdrt_scene_overlap_box(scene.get(), &everything, 0, collect, &col, &n) == KDRT_SUCCESS);
    CHECK(n == 0);
    REQUIRE(kdrt_scene_overlap_box(scene.get(), &everything, 0xFFFFFFFFu, nullptr, nullptr, &n) == KDRT_SUCCESS);
    size_t kept = 0;
    for (const Placed &p : world) kept += !zero_area(p.world);
    CHECK(n == kept);
    const float centre[3] = {0, 0, 0};
    CHECK(kdrt_scene_overlap_sphere(scene.get(), centre, -1.0f, 1, nullptr, nullptr, &n) == KDRT_ERROR_INVALID_QUERY);
    CHECK(kdrt_scene_overlap_sphere(nullptr, centre, 1.0f, 1, nullptr, nullptr, &n) == KDRT_ERROR_NULL_ARGUMENT);
    WARN("scene: " << reports << " reports, " << checked << " decisions checked");
}
