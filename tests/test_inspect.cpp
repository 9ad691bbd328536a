// The inspection API (kdrt_tree_node_count, kdrt_tree_node, kdrt_tree_reference): a walk of every
// node must find what kdrt_tree_get_stats() counts, boxes and depths must be those a descent from
// the root gives, and every triangle must be reachable and lie where its leaves are.
#include "test_support.hpp"
#include "common/thread_scheduler.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstring>
#include <set>
#include <string>
#include <vector>

namespace {

kdrt_node_info node_at(const kdrt_tree *tree, uint32_t index)
{
    kdrt_node_info info;
    REQUIRE(kdrt_tree_node(tree, index, &info) == KDRT_SUCCESS);
    return info;
}

bool same_box(const kdrt_aabb &a, const kdrt_aabb &b)
{
    return std::memcmp(&a, &b, sizeof a) == 0;
}

double area(const kdrt_aabb &b)
{
    const double dx = double(b.max[0]) - b.min[0], dy = double(b.max[1]) - b.min[1], dz = double(b.max[2]) - b.min[2];
    return 2.0 * (dx * dy + dy * dz + dz * dx);
}

// What a recursive walk from the root finds, computed independently of kdrt_tree_node's descent.
struct Walk {
    uint64_t nodes = 0, leaves = 0, refs = 0;
    uint32_t max_leaf_depth = 0;
    double sah_cost = 0;  // with the default costs, as kdrt_tree_stats.sah_cost
    std::vector<int> visits;
    std::set<uint32_t> triangles;
};

void walk(const kdrt_tree *tree, const common::Mesh &mesh, uint32_t index, const kdrt_aabb &box, uint32_t depth,
          double root_area, Walk &w)
{
    const kdrt_node_info info = node_at(tree, index);
    INFO("node " << index);
    w.visits.at(index) += 1;
    w.nodes += 1;
    CHECK(info.depth == depth);
    CHECK(same_box(info.bounds, box));
    const double share = root_area > 0 ? area(box) / root_area : 0;
    if (info.is_leaf) {
        CHECK(info.axis == -1);
        CHECK(info.below == KDRT_INVALID_ID);
        CHECK(info.above == KDRT_INVALID_ID);
        w.leaves += 1;
        w.refs += info.triangle_count;
        w.max_leaf_depth = std::max(w.max_leaf_depth, depth);
        w.sah_cost += share * KDRT_DEFAULT_SAH_INTERSECTION_COST * double((info.triangle_count + 7) / 8);
        for (uint32_t k = 0; k < info.triangle_count; ++k) {
            uint32_t tri = KDRT_INVALID_ID;
            REQUIRE(kdrt_tree_reference(tree, info.first_reference + k, &tri) == KDRT_SUCCESS);
            REQUIRE(tri < mesh.triangle_count());
            w.triangles.insert(tri);
            // A triangle goes only to leaves its box touches (closed boxes).
            double p[3][3];
            mesh.corners(tri, p);
            for (int a = 0; a < 3; ++a) {
                const double lo = std::min({p[0][a], p[1][a], p[2][a]}), hi = std::max({p[0][a], p[1][a], p[2][a]});
                CHECK(lo <= box.max[a]);
                CHECK(hi >= box.min[a]);
            }
        }
        return;
    }
    REQUIRE(info.axis >= 0);
    REQUIRE(info.axis <= 2);
    CHECK(info.triangle_count == 0);
    CHECK(info.below == index + 1);
    CHECK(info.above > info.below);
    REQUIRE(info.above < kdrt_tree_node_count(tree));
    CHECK(info.split >= box.min[info.axis]);
    CHECK(info.split <= box.max[info.axis]);
    w.sah_cost += share * KDRT_DEFAULT_SAH_TRAVERSAL_COST;
    kdrt_aabb below = box, above = box;
    below.max[info.axis] = info.split;
    above.min[info.axis] = info.split;
    walk(tree, mesh, info.below, below, depth + 1, root_area, w);
    walk(tree, mesh, info.above, above, depth + 1, root_area, w);
}

// Walks the tree and compares with kdrt_tree_get_stats(); `expected_triangles` are the usable
// (non-degenerate) triangles, every one of which some leaf must refer to.
void check_walk(const kdrt_tree *tree, const common::Mesh &mesh, uint32_t expected_triangles)
{
    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree, &stats);
    REQUIRE(kdrt_tree_node_count(tree) == stats.nodes);
    REQUIRE(stats.nodes >= 1);
    Walk w;
    w.visits.assign(stats.nodes, 0);
    const kdrt_aabb bounds = kdrt_tree_bounds(tree);
    walk(tree, mesh, 0, bounds, 0, area(bounds), w);
    CHECK(w.nodes == stats.nodes);
    CHECK(std::count(w.visits.begin(), w.visits.end(), 1) == std::ptrdiff_t(stats.nodes));  // each once
    CHECK(w.leaves == stats.leaves);
    CHECK(w.refs == stats.triangle_refs);
    CHECK(w.max_leaf_depth == stats.max_depth);
    CHECK(w.triangles.size() == stats.triangles);
    CHECK(stats.triangles == expected_triangles);
    if (stats.triangles > 0 && area(bounds) > 0)
        CHECK(w.sah_cost == Approx(stats.sah_cost).epsilon(1e-9));
}

kt::TreePtr build_with(const common::Mesh &mesh, kdrt_builder builder, uint32_t leaf_size, const kdrt_scheduler *scheduler = nullptr)
{
    const kdrt_triangles view = mesh.view();
    kdrt_build_options options = kdrt_default_build_options();
    options.builder = builder;
    options.max_leaf_size = leaf_size;
    if (scheduler) options.scheduler = *scheduler;
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &options, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

}  // namespace

TEST_CASE("inspect: bad arguments are errors and leave the output untouched", "[inspect]") {
    const common::Mesh mesh = kt::random_soup(50, 7);
    kt::TreePtr tree = build_with(mesh, KDRT_BUILDER_SAH, 2);
    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree.get(), &stats);

    kdrt_node_info info;
    std::memset(&info, 0x5A, sizeof info);
    const kdrt_node_info before = info;
    CHECK(kdrt_tree_node_count(nullptr) == 0);
    CHECK(kdrt_tree_node(nullptr, 0, &info) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_node(tree.get(), 0, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_node(tree.get(), stats.nodes, &info) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
    CHECK(kdrt_tree_node(tree.get(), KDRT_INVALID_ID, &info) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
    CHECK(std::memcmp(&info, &before, sizeof info) == 0);
    CHECK(kdrt_tree_node(tree.get(), stats.nodes - 1, &info) == KDRT_SUCCESS);  // the last one is fine

    uint32_t tri = 12345;
    CHECK(kdrt_tree_reference(nullptr, 0, &tri) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_reference(tree.get(), 0, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_reference(tree.get(), uint32_t(stats.triangle_refs), &tri) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
    CHECK(tri == 12345);
    CHECK(kdrt_tree_reference(tree.get(), uint32_t(stats.triangle_refs - 1), &tri) == KDRT_SUCCESS);
    CHECK(tri < 50);
}

TEST_CASE("inspect: a walk finds what kdrt_tree_get_stats counts, both builders", "[inspect]") {
    const common::Mesh soup = kt::random_soup(600, 3), ball = kt::sphere(16, 24, 1.0), field = kt::grid(20, 15, 5);
    for (const common::Mesh *mesh : {&soup, &ball, &field}) {
        for (kdrt_builder builder : {KDRT_BUILDER_MEDIAN, KDRT_BUILDER_SAH}) {
            for (uint32_t leaf_size : {1u, 4u, 16u}) {
                INFO(mesh->name << ", builder " << int(builder) << ", leaf size " << leaf_size);
                kt::TreePtr tree = build_with(*mesh, builder, leaf_size);
                kdrt_tree_stats stats;
                kdrt_tree_get_stats(tree.get(), &stats);
                CHECK(stats.nodes > 1);  // a real tree, not one leaf
                check_walk(tree.get(), *mesh, mesh->triangle_count());
            }
        }
    }
}

TEST_CASE("inspect: the parallel SAH build's joined tree walks the same", "[inspect]") {
    // Over 4096 triangles, so the top is cut into tasks and joined (see THE TREE).
    const common::Mesh ball = kt::sphere(64, 96, 1.0);
    common::ThreadScheduler pool(2);
    const kdrt_scheduler hooks = pool.hooks();
    kt::TreePtr tree = build_with(ball, KDRT_BUILDER_SAH, 4, &hooks);
    check_walk(tree.get(), ball, ball.triangle_count());
}

TEST_CASE("inspect: no tree, an empty mesh and zero-area triangles", "[inspect]") {
    const common::Mesh soup = kt::random_soup(40, 11);
    SECTION("max_leaf_size 0 is one leaf with every triangle") {
        kt::TreePtr tree = build_with(soup, KDRT_BUILDER_MEDIAN, 0);
        REQUIRE(kdrt_tree_node_count(tree.get()) == 1);
        const kdrt_node_info root = node_at(tree.get(), 0);
        CHECK(root.is_leaf == 1);
        CHECK(root.triangle_count == 40);
        CHECK(root.first_reference == 0);
        check_walk(tree.get(), soup, 40);
    }
    SECTION("an empty mesh is one empty leaf") {
        common::Mesh empty;
        kt::TreePtr tree = build_with(empty, KDRT_BUILDER_SAH, 4);
        REQUIRE(kdrt_tree_node_count(tree.get()) == 1);
        const kdrt_node_info root = node_at(tree.get(), 0);
        CHECK(root.is_leaf == 1);
        CHECK(root.triangle_count == 0);
        uint32_t tri;
        CHECK(kdrt_tree_reference(tree.get(), 0, &tri) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
    }
    SECTION("zero-area triangles are in no leaf") {
        common::Mesh with_degenerate = soup;
        const float line[9] = {0, 0, 0, 1, 1, 1, 2, 2, 2};  // collinear: zero area
        with_degenerate.positions.insert(with_degenerate.positions.end(), line, line + 9);
        for (kdrt_builder builder : {KDRT_BUILDER_MEDIAN, KDRT_BUILDER_SAH}) {
            kt::TreePtr tree = build_with(with_degenerate, builder, 1);
            check_walk(tree.get(), with_degenerate, 40);  // the 41st never appears
        }
    }
}

TEST_CASE("inspect: the shared meshes walk as their stats say", "[inspect][meshes]") {
    const std::string dir = kt::shared_mesh_dir();
    if (dir.empty()) {
        kt::skip_test("no shared meshes (KDRT_MESH_DIR absent)");
        return;
    }
    for (const char *name : {"/common/spot.obj", "/seed/knot.off"}) {
        common::Mesh mesh;
        std::string error;
        if (!common::load_mesh(dir + name, mesh, error)) {
            WARN(name << ": " << error << ": skipped");
            continue;
        }
        for (kdrt_builder builder : {KDRT_BUILDER_MEDIAN, KDRT_BUILDER_SAH}) {
            INFO(name << ", builder " << int(builder));
            kt::TreePtr tree = build_with(mesh, builder, 4);
            kdrt_tree_stats stats;
            kdrt_tree_get_stats(tree.get(), &stats);
            check_walk(tree.get(), mesh, stats.triangles);
        }
    }
}
