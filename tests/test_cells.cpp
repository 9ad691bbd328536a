// Start cells and ropes (kdrt.h, START CELLS): every leaf's ropes name a node covering the face
// they cross, and a ray started from a cell (kdrt_hit.cell, kdrt_spawn_ray, kdrt_locate, or any
// hint at all) gets exactly the answer of the walk from the root: hit or miss, t, u, v and
// triangle bit for bit, for the nearest, any and k nearest hits and the query forms, on both
// kernels and every builder.
#include "test_support.hpp"
#include "common/random.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace {

using common::Mesh;
using kt::node_info;
using kt::random_direction;

const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();

// Every leaf's rope across each face names a node whose box covers the whole face, touching it
// from the other side; a face on the tree's boundary has none, and only those. Inner nodes have
// no ropes.
void check_ropes(const kdrt_tree *tree) {
    const kdrt_aabb bounds = kdrt_tree_bounds(tree);
    const uint32_t nodes = kdrt_tree_node_count(tree);
    size_t ropes = 0, bad = 0;
    for (uint32_t i = 0; i < nodes; ++i) {
        const kdrt_node_info leaf = node_info(tree, i);
        if (!leaf.is_leaf) {
            for (uint32_t r : leaf.ropes) bad += r != KDRT_INVALID_ID;
            continue;
        }
        for (int face = 0; face < 6; ++face) {
            const int axis = face / 2, high = face % 2;
            const float plane = high ? leaf.bounds.max[axis] : leaf.bounds.min[axis];
            const bool boundary = plane == (high ? bounds.max[axis] : bounds.min[axis]);
            const uint32_t r = leaf.ropes[face];
            if (r == KDRT_INVALID_ID) {
                if (!boundary) {
                    ++bad;
                    WARN("leaf " << i << " face " << face << ": no rope inside the tree");
                }
                continue;
            }
            ++ropes;
            if (r >= nodes) {
                ++bad;
                continue;
            }
            const kdrt_aabb n = node_info(tree, r).bounds;
            bool covers = (high ? n.min[axis] == plane : n.max[axis] == plane);
            for (int b = 0; b < 3; ++b)
                if (b != axis) covers = covers && n.min[b] <= leaf.bounds.min[b] && n.max[b] >= leaf.bounds.max[b];
            if (!covers) {
                ++bad;
                WARN("leaf " << i << " face " << face << ": rope " << r << " does not cover it");
            }
        }
    }
    CHECK(bad == 0);
    INFO("ropes checked: " << ropes);
}

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool same_answer(const kdrt_hit &a, int found_a, const kdrt_hit &b, int found_b) {
    if (found_a != found_b || a.triangle != b.triangle) return false;
    return !found_a || (same_bits(a.t, b.t) && same_bits(a.u, b.u) && same_bits(a.v, b.v));
}

// Compares every query of `hinted` with the same ray started at the root; counts the rays whose
// answers differ in any bit.
struct Compare {
    const kdrt_tree *tree;
    kdrt_query culled = kdrt_default_query();
    size_t rays = 0, different = 0, hinted_starts = 0;
    std::string first;

    explicit Compare(const kdrt_tree *t) : tree(t) { culled.flags = KDRT_QUERY_CULL_BACK_FACES; }

    void operator()(const kdrt_ray &hinted, const char *kind) {
        kdrt_ray root = hinted;
        root.cell = 0;
        kdrt_hit a, b, ka[4], kb[4];
        bool same = true;
        int fa = kdrt_intersect(tree, &hinted, &a), fb = kdrt_intersect(tree, &root, &b);
        same = same && same_answer(a, fa, b, fb);
        same = same && kdrt_occluded(tree, &hinted) == kdrt_occluded(tree, &root);
        fa = kdrt_intersect_query(tree, &hinted, &culled, &a), fb = kdrt_intersect_query(tree, &root, &culled, &b);
        same = same && same_answer(a, fa, b, fb);
        same = same && kdrt_occluded_query(tree, &hinted, &culled) == kdrt_occluded_query(tree, &root, &culled);
        const uint32_t na = kdrt_intersect_k(tree, &hinted, nullptr, ka, 4), nb = kdrt_intersect_k(tree, &root, nullptr, kb, 4);
        same = same && na == nb;
        for (uint32_t i = 0; same && i < na; ++i) same = same_answer(ka[i], 1, kb[i], 1);
        ++rays;
        if (!same && different++ == 0)
            first = std::string(kind) + " ray (" + std::to_string(hinted.org[0]) + ", " + std::to_string(hinted.org[1]) + ", " +
                    std::to_string(hinted.org[2]) + ") dir (" + std::to_string(hinted.dir[0]) + ", " + std::to_string(hinted.dir[1]) +
                    ", " + std::to_string(hinted.dir[2]) + ") cell " + std::to_string(hinted.cell);
    }
};

// Rays of every kind the start cells meet, `count` of them about, each compared with its walk
// from the root: rays spawned off hits (bounces and shadow rays to a point), rays from random
// interior points with kdrt_locate's cell, axis-parallel and in-plane rays, +-0 and NaN parts,
// tmin > 0 and finite tmax, starts exactly on cells' faces and corners, and bad hints (random
// numbers, inner nodes, a neighbouring cell, another tree's cells).
void compare_hinted(const kdrt_tree *tree, const kdrt_tree *other, size_t count, uint32_t seed) {
    common::Rng rng(seed);
    Compare compare(tree);
    const kdrt_aabb box = kdrt_tree_bounds(tree);
    const uint32_t nodes = kdrt_tree_node_count(tree);
    std::vector<uint32_t> leaves;
    for (uint32_t i = 0; i < nodes; ++i)
        if (node_info(tree, i).is_leaf) leaves.push_back(i);
    float extent = 0;
    for (int a = 0; a < 3; ++a) extent = std::max(extent, box.max[a] - box.min[a]);
    auto interior = [&](float p[3]) {
        for (int a = 0; a < 3; ++a) p[a] = float(rng.range(box.min[a], box.max[a]));
    };

    // Spawned rays: a bounce in a random direction and a shadow ray to a random point.
    const std::vector<kdrt_ray> primary = kt::random_rays(box, count / 4, seed + 1);
    size_t spawned = 0;
    for (const kdrt_ray &r : primary) {
        kdrt_hit hit;
        if (!kdrt_intersect(tree, &r, &hit)) continue;
        kdrt_ray next;
        float dir[3];
        random_direction(rng, dir);
        REQUIRE(kdrt_spawn_ray(tree, &hit, dir, &next));
        compare(next, "bounce");
        float q[3];
        interior(q);
        for (int a = 0; a < 3; ++a) dir[a] = q[a] - next.org[a];
        if (kdrt_spawn_ray(tree, &hit, dir, &next)) {
            for (int a = 0; a < 3; ++a) next.dir[a] = q[a] - next.org[a];
            next.tmax = 0.999f;
            compare(next, "shadow");
        }
        spawned += 2;
        compare.hinted_starts += next.cell != 0;
    }

    for (size_t i = 0; i < count / 2; ++i) {
        kdrt_ray r{};
        interior(r.org);
        random_direction(rng, r.dir);
        const uint32_t kind = rng.below(8);
        if (kind == 1) {  // axis-parallel, the other components +0 or -0
            const int a = int(rng.below(3));
            for (int b = 0; b < 3; ++b) r.dir[b] = rng.below(2) ? -0.0f : 0.0f;
            r.dir[a] = rng.below(2) ? 1.0f : -1.0f;
        } else if (kind == 2) {  // in a plane of two axes
            r.dir[rng.below(3)] = rng.below(2) ? -0.0f : 0.0f;
        } else if (kind == 3) {  // a NaN part
            r.dir[rng.below(3)] = kNaN;
        }
        r.tmin = rng.below(4) == 0 ? float(rng.range(0, extent)) : 0.0f;
        r.tmax = rng.below(4) == 0 ? float(rng.range(0, 2 * extent)) : kInf;
        r.cell = kdrt_locate(tree, r.org);
        compare(r, "interior");
        compare.hinted_starts += r.cell != 0;
    }

    // Starts on cells' faces, edges and corners, with that cell and with the located one.
    for (size_t i = 0; i < count / 8 && !leaves.empty(); ++i) {
        const uint32_t leaf = leaves[rng.below(uint32_t(leaves.size()))];
        const kdrt_aabb cell = node_info(tree, leaf).bounds;
        kdrt_ray r{};
        for (int a = 0; a < 3; ++a) {
            const uint32_t where = rng.below(3);  // the low face, inside, the high face
            r.org[a] = where == 0 ? cell.min[a] : where == 2 ? cell.max[a] : float(rng.range(cell.min[a], cell.max[a]));
            if (!std::isfinite(r.org[a])) r.org[a] = 0;
        }
        random_direction(rng, r.dir);
        if (rng.below(3) == 0) r.dir[rng.below(3)] = 0.0f;
        r.tmax = kInf;
        r.cell = leaf;
        compare(r, "on a face");
        r.cell = kdrt_locate(tree, r.org);
        compare(r, "on a face, located");
    }

    // Bad hints: any number, an inner node, a neighbour, another tree's cell of the same point.
    for (size_t i = 0; i < count / 8; ++i) {
        kdrt_ray r{};
        interior(r.org);
        random_direction(rng, r.dir);
        r.tmax = kInf;
        const uint32_t kind = rng.below(4);
        if (kind == 0) r.cell = uint32_t(rng.next());
        else if (kind == 1) r.cell = rng.below(nodes + 4);
        else if (kind == 2) {
            const uint32_t at = kdrt_locate(tree, r.org);
            const kdrt_node_info info = node_info(tree, at);
            r.cell = info.is_leaf ? info.ropes[rng.below(6)] : 0;
        } else {
            r.cell = kdrt_locate(other, r.org);
        }
        compare(r, "bad hint");
    }

    INFO(compare.rays << " rays, " << spawned << " spawned, " << compare.hinted_starts << " with a start cell; first difference: "
                      << compare.first);
    CHECK(compare.different == 0);
    if (nodes > 1) CHECK(compare.hinted_starts > compare.rays / 4);  // the rope walk really ran
}

}  // namespace

TEST_CASE("cells: every rope names a node covering its face, and boundary faces have none", "[cells]") {
    const std::vector<Mesh> meshes = {kt::sphere(16, 24, 2.0), kt::grid(12, 12, 3), kt::random_soup(400, 5)};
    for (const Mesh &mesh : meshes)
        for (const kt::Builder &builder : kt::kBuilders)
            for (uint32_t leaf : {0u, 1u, 4u, 16u}) {
                INFO(mesh.name << ", " << builder.name << ", leaf size " << leaf);
                const kt::TreePtr tree = kt::build(mesh, leaf, builder);
                check_ropes(tree.get());
            }
    const size_t max_triangles = kt::shared_mesh_max_triangles();  // KDRT_TEST_MESH_TRIANGLES
    for (const std::string &path : kt::shared_mesh_files()) {
        Mesh mesh;
        std::string error;
        if (!common::load_mesh(path, mesh, error)) continue;
        if (max_triangles != 0 && mesh.triangle_count() > max_triangles) continue;
        for (const kt::Builder &builder : kt::kBuilders) {
            INFO(path << ", " << builder.name);
            check_ropes(kt::build(mesh, 4, builder).get());
        }
    }
}

TEST_CASE("cells: a ray started from any cell gets the root walk's answer, bit for bit", "[cells]") {
    // At least a million rays per kernel in the Release suites (KDRT_TEST_RAYS, default 100,000:
    // 6 trees of 1.7 times that each).
    const size_t count = kt::reference_ray_count() * 17 / 10;
    const std::vector<Mesh> meshes = {kt::sphere(32, 48, 2.0), kt::grid(40, 40, 7), kt::random_soup(3000, 9)};
    const kt::Builder builders[] = {kt::kBuilders[0], kt::kSahBuilders[1]};
    for (uint32_t flags : {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)})
        for (const Mesh &mesh : meshes)
            for (const kt::Builder &builder : builders) {
                INFO(mesh.name << ", " << builder.name << (flags ? ", scalar kernel" : ", default kernel"));
                const kt::TreePtr tree = kt::build(mesh, 4, builder, flags);
                const kt::TreePtr other = kt::build(mesh, 1, kt::kSahBuilders[0], flags);  // another tree's cells
                compare_hinted(tree.get(), other.get(), count / 2, 100 + flags);
            }
}

TEST_CASE("cells: the other builders, qualities and leaf sizes, and stale cells after a rebuild", "[cells]") {
    const size_t count = kt::reference_ray_count() / 10;
    const Mesh mesh = kt::sphere(24, 36, 2.0);
    for (const kt::Builder &builder : kt::kBuilders)
        for (uint32_t leaf : {0u, 1u, 16u}) {
            INFO(builder.name << ", leaf size " << leaf);
            const kt::TreePtr tree = kt::build(mesh, leaf, builder);
            const Mesh moved = kt::translated(mesh, 0.3, -0.2, 0.1);
            const kt::TreePtr before = kt::build(moved, 4, builder);  // stale: another mesh's cells
            compare_hinted(tree.get(), before.get(), count, 7 + leaf);
        }
}

TEST_CASE("cells: kdrt_locate and the hit's cell hold their point, and a miss has cell 0", "[cells]") {
    const Mesh mesh = kt::sphere(16, 24, 2.0);
    const kt::TreePtr tree = kt::build(mesh, 4);
    const float inside[3] = {0.1f, 0.2f, -0.3f}, outside[3] = {5, 0, 0}, nan[3] = {kNaN, 0, 0};
    const uint32_t cell = kdrt_locate(tree.get(), inside);
    const kdrt_node_info info = node_info(tree.get(), cell);
    REQUIRE(info.is_leaf);
    for (int a = 0; a < 3; ++a) CHECK((info.bounds.min[a] <= inside[a] && inside[a] <= info.bounds.max[a]));
    CHECK(kdrt_locate(tree.get(), outside) == 0);
    CHECK(kdrt_locate(tree.get(), nan) == 0);
    CHECK(kdrt_locate(nullptr, inside) == 0);
    CHECK(kdrt_locate(tree.get(), nullptr) == 0);

    // A hit's cell is a leaf whose box holds the hit point, give or take rounding (its box
    // widened by 1e-5 of the scene).
    size_t hits = 0, far = 0;
    for (const kdrt_ray &r : kt::random_rays(kdrt_tree_bounds(tree.get()), 5000, 3)) {
        kdrt_hit hit;
        if (!kdrt_intersect(tree.get(), &r, &hit)) {
            CHECK(hit.cell == 0);
            continue;
        }
        ++hits;
        const kdrt_node_info c = node_info(tree.get(), hit.cell);
        REQUIRE(c.is_leaf);
        for (int a = 0; a < 3; ++a) {
            const float p = r.org[a] + hit.t * r.dir[a];
            far += p < c.bounds.min[a] - 4e-5f || p > c.bounds.max[a] + 4e-5f;
        }
    }
    CHECK(hits > 1000);
    CHECK(far == 0);
}

TEST_CASE("cells: scene queries from the mesh tree's cells get the root walk's answers", "[cells][scene]") {
    // Two meshes in the scene's tree and an instance beside and through them: the world ray's
    // cell is the mesh tree's (kdrt_scene_locate, kdrt_scene_spawn_ray); instances start at their
    // root. Nearest, any and k nearest hits bit for bit with and without it.
    const Mesh ball = kt::sphere(24, 36, 1.5), ground = kt::translated(kt::grid(24, 24, 5), -12, -12, -2);
    const kt::TreePtr ball_tree = kt::build(ball, 4);
    const float placed[12] = {0.5f, 0, 0, 1.0f, 0, 0.5f, 0, 0.5f, 0, 0, 0.5f, 0.25f};
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(1, nullptr), kdrt_mesh_geometry(2, nullptr),
                                          kdrt_instance_geometry(3, ball_tree.get(), placed)};
    entries[0].mesh = ball.view(), entries[1].mesh = ground.view();
    kdrt_scene *scene = nullptr;
    REQUIRE(kdrt_scene_build(entries.data(), uint32_t(entries.size()), nullptr, &scene, nullptr) == KDRT_SUCCESS);
    const kdrt_aabb box = kdrt_scene_bounds(scene);
    common::Rng rng(11);
    size_t rays = 0, different = 0, with_cell = 0;
    auto compare = [&](const kdrt_ray &hinted) {
        kdrt_ray root = hinted;
        root.cell = 0;
        kdrt_hit a, b, ka[3], kb[3];
        const int fa = kdrt_scene_intersect(scene, &hinted, nullptr, &a), fb = kdrt_scene_intersect(scene, &root, nullptr, &b);
        bool same = same_answer(a, fa, b, fb) && (!fa || (a.geometry == b.geometry && a.instance == b.instance));
        same = same && kdrt_scene_occluded(scene, &hinted, nullptr) == kdrt_scene_occluded(scene, &root, nullptr);
        const uint32_t na = kdrt_scene_intersect_k(scene, &hinted, nullptr, ka, 3), nb = kdrt_scene_intersect_k(scene, &root, nullptr, kb, 3);
        same = same && na == nb;
        for (uint32_t i = 0; same && i < na; ++i) same = same_answer(ka[i], 1, kb[i], 1) && ka[i].geometry == kb[i].geometry;
        ++rays, different += !same, with_cell += hinted.cell != 0;
    };
    const size_t count = std::max<size_t>(kt::reference_ray_count() / 4, 2000);
    for (size_t i = 0; i < count; ++i) {
        kdrt_ray r{};
        for (int a = 0; a < 3; ++a) r.org[a] = float(rng.range(box.min[a], box.max[a]));
        random_direction(rng, r.dir);
        r.tmax = kInf;
        r.cell = kdrt_scene_locate(scene, r.org);
        compare(r);
        kdrt_hit hit;
        if (!kdrt_scene_intersect(scene, &r, nullptr, &hit)) continue;
        float dir[3];
        random_direction(rng, dir);
        kdrt_ray next;
        REQUIRE(kdrt_scene_spawn_ray(scene, &hit, dir, &next));
        compare(next);
    }
    kdrt_scene_free(scene);
    INFO(rays << " rays, " << with_cell << " with a start cell");
    CHECK(different == 0);
    CHECK(with_cell > rays / 4);
}
