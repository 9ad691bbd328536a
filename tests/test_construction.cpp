// kdrt-construction's steps (tools/construction.hpp) checked two ways: against the tree kdrt
// builds, walked here on its own, and, for the median builder, against a re-implementation of
// the original's rule written from the manual: split at the median triangle centroid on the axis
// cycling x, y, z with depth, try the next axes when one leaves a child as large as the node (the
// z axis of a flat set always does), and send each triangle to every side its extent reaches.
#include "construction.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <set>
#include <string>
#include <unistd.h>
#include <vector>

using kdrt_tools::Side;

namespace {

struct RuleStep {
    uint32_t depth;
    int axis;
    float split;
    std::vector<uint32_t> triangles;
    std::vector<Side> sides;
};

// The original's median rule, breadth first (below before above), as kdrt_tools::construct orders
// its steps. Leaves go to `leaves` in the same order.
void median_rule(const std::vector<float> &pos, uint32_t leaf_size, std::vector<RuleStep> &steps,
                 std::vector<std::vector<uint32_t>> &leaves)
{
    const uint32_t n_all = uint32_t(pos.size() / 9);
    uint32_t log2n = 0;
    while ((n_all >> log2n) > 1) ++log2n;
    const uint32_t max_depth = 8 + (13 * log2n + 5) / 10;  // the manual's 8 + 1.3 log2(n), rounded
    auto corner = [&](uint32_t t, int k, int a) { return pos[size_t(t) * 9 + size_t(k) * 3 + size_t(a)]; };
    auto lo = [&](uint32_t t, int a) { return std::min({corner(t, 0, a), corner(t, 1, a), corner(t, 2, a)}); };
    auto hi = [&](uint32_t t, int a) { return std::max({corner(t, 0, a), corner(t, 1, a), corner(t, 2, a)}); };
    auto centroid = [&](uint32_t t, int a) {
        const float mean = (corner(t, 0, a) + corner(t, 1, a) + corner(t, 2, a)) * (1.0f / 3.0f);
        return std::min(std::max(mean, lo(t, a)), hi(t, a));  // kept within the corners, as kdrt does
    };

    std::vector<uint32_t> all(n_all);
    for (uint32_t t = 0; t < n_all; ++t) all[t] = t;
    std::deque<std::pair<std::vector<uint32_t>, uint32_t>> queue{{all, 0}};
    while (!queue.empty()) {
        const std::vector<uint32_t> tris = queue.front().first;
        const uint32_t depth = queue.front().second;
        queue.pop_front();
        const size_t n = tris.size();
        bool split_made = false;
        if (n > leaf_size && depth < max_depth) {
            for (uint32_t attempt = 0; attempt < 3 && !split_made; ++attempt) {
                const int axis = int((depth + attempt) % 3);
                std::vector<float> c;
                for (uint32_t t : tris) c.push_back(centroid(t, axis));
                std::sort(c.begin(), c.end());
                const float split = c[n / 2];
                RuleStep s{depth, axis, split, tris, {}};
                std::vector<uint32_t> below, above;
                for (uint32_t t : tris) {
                    const bool b = lo(t, axis) < split || hi(t, axis) <= split;  // in the plane: below
                    const bool a = hi(t, axis) > split;
                    if (b) below.push_back(t);
                    if (a) above.push_back(t);
                    s.sides.push_back(b && a ? Side::both : (b ? Side::below : Side::above));
                }
                if (below.size() < n && above.size() < n) {
                    steps.push_back(s);
                    queue.push_back({below, depth + 1});
                    queue.push_back({above, depth + 1});
                    split_made = true;
                }
            }
        }
        if (!split_made) leaves.push_back(tris);
    }
}

// A subtree's triangles, collected by a recursive walk of the library's tree.
std::set<uint32_t> subtree_triangles(const kdrt_tree *tree, uint32_t node)
{
    kdrt_node_info n;
    REQUIRE(kdrt_tree_node(tree, node, &n) == KDRT_SUCCESS);
    std::set<uint32_t> out;
    if (n.is_leaf) {
        for (uint32_t k = 0; k < n.triangle_count; ++k) {
            uint32_t t;
            REQUIRE(kdrt_tree_reference(tree, n.first_reference + k, &t) == KDRT_SUCCESS);
            out.insert(t);
        }
        return out;
    }
    out = subtree_triangles(tree, n.below);
    const std::set<uint32_t> above = subtree_triangles(tree, n.above);
    out.insert(above.begin(), above.end());
    return out;
}

struct Tree {
    kdrt_tree *tree = nullptr;
    Tree(const std::vector<float> &pos, kdrt_builder builder, uint32_t leaf_size)
    {
        kdrt_triangles mesh{};
        mesh.positions = pos.data();
        mesh.vertex_count = uint32_t(pos.size() / 3);
        mesh.triangle_count = uint32_t(pos.size() / 9);
        kdrt_build_options options = kdrt_default_build_options();
        options.builder = builder;
        options.max_leaf_size = leaf_size;
        REQUIRE(kdrt_tree_build(&mesh, &options, &tree, nullptr) == KDRT_SUCCESS);
    }
    ~Tree() { kdrt_tree_free(tree); }
};

// The steps against the library's tree: every inner node is a step once, with its axis, split,
// box and children's boxes, its triangles those its subtree refers to, each side the children's
// subtrees that refer to it, and a side that the triangle's extent reaches.
void check_against_tree(const kdrt_tools::Construction &c, const std::vector<float> &pos)
{
    Tree built(pos, c.builder, c.leaf_size);
    const kdrt_tree *tree = built.tree;
    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree, &stats);
    CHECK(c.steps.size() + c.leaves.size() == stats.nodes);
    CHECK(c.leaves.size() == stats.leaves);
    std::set<uint32_t> seen;
    uint32_t last_depth = 0;
    for (const kdrt_tools::ConstructionStep &s : c.steps) {
        INFO("step at node " << s.node);
        CHECK(seen.insert(s.node).second);
        CHECK(s.depth >= last_depth);  // breadth first
        last_depth = s.depth;
        kdrt_node_info n;
        REQUIRE(kdrt_tree_node(tree, s.node, &n) == KDRT_SUCCESS);
        REQUIRE(n.is_leaf == 0);
        CHECK(n.axis == s.axis);
        CHECK(n.split == s.split);
        CHECK(n.depth == s.depth);
        CHECK(std::memcmp(&n.bounds, &s.box, sizeof s.box) == 0);
        CHECK(s.below_box.max[s.axis] == s.split);
        CHECK(s.above_box.min[s.axis] == s.split);
        const std::set<uint32_t> below = subtree_triangles(tree, n.below), above = subtree_triangles(tree, n.above);
        std::set<uint32_t> held = below;
        held.insert(above.begin(), above.end());
        CHECK(std::vector<uint32_t>(held.begin(), held.end()) == s.triangles);
        REQUIRE(s.sides.size() == s.triangles.size());
        for (size_t i = 0; i < s.triangles.size(); ++i) {
            const uint32_t t = s.triangles[i];
            const bool b = below.count(t) != 0, a = above.count(t) != 0;
            CHECK(s.sides[i] == (b && a ? Side::both : (b ? Side::below : Side::above)));
            const float *p = &pos[size_t(t) * 9];
            const float lo = std::min({p[s.axis], p[3 + s.axis], p[6 + s.axis]});
            const float hi = std::max({p[s.axis], p[3 + s.axis], p[6 + s.axis]});
            if (b) CHECK(lo <= s.split);
            if (a) CHECK(hi >= s.split);
        }
        if (c.builder == KDRT_BUILDER_MEDIAN) {
            REQUIRE(s.median_triangle != KDRT_INVALID_ID);
            CHECK(s.median_centroid[s.axis] == s.split);
        }
    }
    if (stats.nodes == 1) {  // one leaf: nothing was split (the SAH: a split did not pay)
        CHECK(c.steps.empty());
        return;
    }
    REQUIRE(!c.steps.empty());
    CHECK(c.steps[0].node == 0);
    CHECK(c.steps[0].triangles.size() == stats.triangles);
}

}  // namespace

TEST_CASE("construction: the default triangle set is 11 seeded flat triangles", "[construction]") {
    const std::vector<float> a = kdrt_tools::random_triangles_2d(11, 7), b = kdrt_tools::random_triangles_2d(11, 7);
    REQUIRE(a.size() == 11 * 9);
    CHECK(a == b);
    CHECK(a != kdrt_tools::random_triangles_2d(11, 8));
    for (size_t t = 0; t < 11; ++t) {
        const float *p = &a[t * 9];
        CHECK(p[2] == 0.0f);
        CHECK(p[5] == 0.0f);
        CHECK(p[8] == 0.0f);
        const double area = 0.5 * std::fabs(double(p[3] - p[0]) * (p[7] - p[1]) - double(p[6] - p[0]) * (p[4] - p[1]));
        CHECK(area >= 0.4);
    }
}

TEST_CASE("construction: the median steps follow the original's rule", "[construction]") {
    struct Case {
        uint32_t count, seed, leaf_size;
    };
    for (const Case &k : {Case{11, 7, 1}, Case{11, 3, 1}, Case{11, 7, 2}, Case{60, 5, 1}, Case{200, 9, 3}}) {
        INFO(k.count << " triangles, seed " << k.seed << ", leaf size " << k.leaf_size);
        const std::vector<float> pos = kdrt_tools::random_triangles_2d(k.count, k.seed);
        kdrt_tools::Construction c;
        std::string error;
        REQUIRE(kdrt_tools::construct(pos, KDRT_BUILDER_MEDIAN, k.leaf_size, c, error));
        std::vector<RuleStep> rule;
        std::vector<std::vector<uint32_t>> rule_leaves;
        median_rule(pos, k.leaf_size, rule, rule_leaves);
        REQUIRE(c.steps.size() == rule.size());
        for (size_t i = 0; i < rule.size(); ++i) {
            INFO("step " << i + 1);
            CHECK(c.steps[i].depth == rule[i].depth);
            CHECK(c.steps[i].axis == rule[i].axis);
            CHECK(c.steps[i].axis != 2);  // z = 0 everywhere: the rule never splits there
            CHECK(c.steps[i].split == rule[i].split);
            CHECK(c.steps[i].triangles == rule[i].triangles);
            CHECK(c.steps[i].sides == rule[i].sides);
        }
        REQUIRE(c.leaves.size() == rule_leaves.size());
        for (size_t i = 0; i < rule_leaves.size(); ++i) CHECK(c.leaves[i].triangles == rule_leaves[i]);
        check_against_tree(c, pos);
    }
}

TEST_CASE("construction: the SAH steps are the tree the library builds", "[construction]") {
    for (uint32_t seed : {7u, 3u}) {
        for (uint32_t count : {11u, 200u}) {
            INFO(count << " triangles, seed " << seed);
            const std::vector<float> pos = kdrt_tools::random_triangles_2d(count, seed);
            kdrt_tools::Construction c;
            std::string error;
            REQUIRE(kdrt_tools::construct(pos, KDRT_BUILDER_SAH, 1, c, error));
            check_against_tree(c, pos);
            for (const auto &s : c.steps) CHECK(s.median_triangle == KDRT_INVALID_ID);
        }
    }
}

TEST_CASE("construction: triangle files", "[construction]") {
    char dir_template[] = "/tmp/kdrt-construction-XXXXXX";
    REQUIRE(mkdtemp(dir_template) != nullptr);
    const std::string dir = dir_template, path = dir + "/triangles.txt";
    std::vector<float> pos;
    std::string error;
    {
        std::ofstream f(path);
        f << "# two flat and one with z\n0 0 1 0 0 1\n\n2 2 3 2 2 3\n0 0 1  1 0 1  0 1 1\n";
    }
    REQUIRE(kdrt_tools::read_triangles(path, pos, error));
    REQUIRE(pos.size() == 27);
    CHECK(pos[3] == 1.0f);
    CHECK(pos[2] == 0.0f);   // six numbers: z = 0
    CHECK(pos[20] == 1.0f);  // nine: z as given
    {
        std::ofstream f(path);
        f << "0 0 1 0 0 1\n0 0 1 0 0\n";
    }
    CHECK_FALSE(kdrt_tools::read_triangles(path, pos, error));
    CHECK(error == path + ":2: a triangle is 6 numbers (x y per corner) or 9 (x y z), not 5");
    {
        std::ofstream f(path);
        f << "0 0 1 0 0 nan\n";
    }
    CHECK_FALSE(kdrt_tools::read_triangles(path, pos, error));
    CHECK(error == path + ":1: 'nan' is not a finite number");
    {
        std::ofstream f(path);
        f << "# nothing\n";
    }
    CHECK_FALSE(kdrt_tools::read_triangles(path, pos, error));
    CHECK(error == path + ": no triangles");
    CHECK_FALSE(kdrt_tools::read_triangles(dir + "/missing.txt", pos, error));
    CHECK(error.find("cannot read '" + dir + "/missing.txt'") == 0);
    std::remove(path.c_str());
    rmdir(dir.c_str());
}
