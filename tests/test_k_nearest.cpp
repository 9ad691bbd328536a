// kdrt_intersect_k(): the k nearest hits along a ray, sorted by (t, triangle), each triangle once.
// Checked against two brute forces: on small meshes, every triangle in a tree of its own traced
// with kdrt_intersect() (the validated nearest-hit query, sharing nothing of the k-nearest code
// but the triangle test), the hits sorted and cut at k; on large ones, the tree of leaf size 0,
// which tests every triangle in one leaf. Every builder and quality, both kernels.

#include "test_support.hpp"
#include "oracle/hard_cases.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace {

bool hit_before(const kdrt_hit &a, const kdrt_hit &b) {
    return a.t < b.t || (a.t == b.t && a.triangle < b.triangle);
}

// Every hit of the ray on the mesh, sorted: one single-triangle tree per triangle (its index in
// the mesh is the tree's index; the view's triangle 0 is mesh triangle `first`).
struct EveryTriangleTree {
    std::vector<kt::TreePtr> trees;
    explicit EveryTriangleTree(const common::Mesh &mesh) {
        for (uint32_t i = 0; i < mesh.triangle_count(); ++i) {
            kdrt_triangles view = mesh.view();
            if (view.indices) view.indices += 3 * size_t(i);
            else view.positions += 9 * size_t(i);
            view.triangle_count = 1;
            if (!view.indices) view.vertex_count = 3;
            kdrt_build_options o = kdrt_default_build_options();
            o.max_leaf_size = 0;
            kdrt_tree *tree = nullptr;
            REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
            trees.emplace_back(tree);
        }
    }
    std::vector<kdrt_hit> hits(const kdrt_ray &ray) const {
        std::vector<kdrt_hit> all;
        for (uint32_t i = 0; i < trees.size(); ++i) {
            kdrt_hit h;
            if (kdrt_intersect(trees[i].get(), &ray, &h)) h.triangle = i, all.push_back(h);
        }
        std::sort(all.begin(), all.end(), hit_before);
        return all;
    }
};

std::vector<kdrt_hit> k_nearest(const kdrt_tree *tree, const kdrt_ray &ray, uint32_t k) {
    std::vector<kdrt_hit> hits(k + 1);
    hits[k].triangle = 12345;  // a guard: nothing is written past capacity
    const uint32_t n = kdrt_intersect_k(tree, &ray, hits.data(), k);
    CHECK(hits[k].triangle == 12345u);
    CHECK(n <= k);
    hits.resize(n);
    return hits;
}

// Equal lists, bit for bit; describes the first difference.
bool same_list(const std::vector<kdrt_hit> &a, const std::vector<kdrt_hit> &b, std::string &why) {
    if (a.size() != b.size()) {
        why = std::to_string(a.size()) + " hits against " + std::to_string(b.size());
        return false;
    }
    for (size_t i = 0; i < a.size(); ++i)
        if (!kt::same_hit(a[i], b[i])) {
            why = "hit " + std::to_string(i) + ": triangle " + std::to_string(a[i].triangle) + " at t " +
                  std::to_string(a[i].t) + " against triangle " + std::to_string(b[i].triangle) + " at t " +
                  std::to_string(b[i].t);
            return false;
        }
    return true;
}

// Rays through the mesh's box, and some with a short range.
std::vector<kdrt_ray> rays_for(const common::Mesh &mesh, size_t count, uint32_t seed) {
    kdrt_aabb box;
    const kdrt_triangles view = mesh.view();
    REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
    return kt::random_rays(box, count, seed);
}

const uint32_t kCapacities[] = {1, 2, 3, 8, 64};

}  // namespace

TEST_CASE("k nearest: every hit of small meshes, against a tree per triangle", "[k-nearest]") {
    // Overlapping and identical triangles: many hits along a ray, and ties in t.
    const common::Mesh meshes[] = {kt::sphere(8, 16, 1.0), kt::random_soup(200, 4),
                                   oracle::hostile_mesh("overlapping", 150, 2),
                                   oracle::hostile_mesh("identical", 100, 3), kt::as_soup(kt::grid(8, 8, 5))};
    size_t most_of_all = 0;
    for (const common::Mesh &mesh : meshes) {
        const EveryTriangleTree every(mesh);
        const std::vector<kdrt_ray> rays = rays_for(mesh, 400, 21);
        size_t most = 0;
        for (const kt::Builder &builder : kt::kBuilders)
            for (uint32_t leaf : {0u, 1u, 4u})
                for (uint32_t flags : {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)}) {
                    INFO(mesh.name << ", " << builder.name << ", leaf size " << leaf
                                   << (flags ? ", scalar kernel" : ""));
                    kt::TreePtr tree = kt::build(mesh, leaf, builder, flags);
                    size_t wrong = 0;
                    std::string first;
                    for (size_t r = 0; r < rays.size(); ++r) {
                        const std::vector<kdrt_hit> all = every.hits(rays[r]);
                        most = std::max(most, all.size());
                        for (uint32_t k : kCapacities) {
                            std::vector<kdrt_hit> want(all.begin(), all.begin() + std::min<size_t>(k, all.size()));
                            std::string why;
                            if (!same_list(k_nearest(tree.get(), rays[r], k), want, why)) {
                                if (!wrong++) first = "ray " + std::to_string(r) + ", k " + std::to_string(k) + ": " + why;
                            }
                        }
                    }
                    INFO(first);
                    CHECK(wrong == 0);
                }
        INFO(mesh.name);
        CHECK(most >= 2);
        most_of_all = std::max(most_of_all, most);
    }
    CHECK(most_of_all > 64);  // the test means something: some rays have more hits than fit
}

TEST_CASE("k nearest: large meshes against leaf size 0, and k = 1 is kdrt_intersect", "[k-nearest]") {
    const common::Mesh meshes[] = {kt::sphere(60, 120, 1.0), kt::random_soup(20000, 7),
                                   oracle::hostile_mesh("overlapping", 3000, 4)};
    for (const common::Mesh &mesh : meshes) {
        const std::vector<kdrt_ray> rays = rays_for(mesh, 1500, 33);
        const kt::TreePtr brute = kt::build(mesh, 0, kt::kBuilders[0]);
        std::vector<std::vector<kdrt_hit>> want(rays.size());
        for (size_t r = 0; r < rays.size(); ++r) want[r] = k_nearest(brute.get(), rays[r], 64);
        for (const kt::Builder &builder : kt::kBuilders)
            for (uint32_t flags : {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)}) {
                INFO(mesh.name << ", " << builder.name << (flags ? ", scalar kernel" : ""));
                kt::TreePtr tree = kt::build(mesh, 4, builder, flags);
                size_t wrong = 0, k1_wrong = 0;
                std::string first;
                for (size_t r = 0; r < rays.size(); ++r) {
                    for (uint32_t k : kCapacities) {
                        std::vector<kdrt_hit> cut(want[r].begin(), want[r].begin() + std::min<size_t>(k, want[r].size()));
                        std::string why;
                        if (!same_list(k_nearest(tree.get(), rays[r], k), cut, why) && !wrong++)
                            first = "ray " + std::to_string(r) + ", k " + std::to_string(k) + ": " + why;
                    }
                    kdrt_hit one, nearest;
                    const uint32_t n = kdrt_intersect_k(tree.get(), &rays[r], &one, 1);
                    const int found = kdrt_intersect(tree.get(), &rays[r], &nearest);
                    k1_wrong += n != uint32_t(found) || (found && !kt::same_hit(one, nearest));
                }
                INFO(first);
                CHECK(wrong == 0);
                CHECK(k1_wrong == 0);
            }
    }
}

TEST_CASE("k nearest: a ray through a closed mesh crosses it an even number of times", "[k-nearest]") {
    // From outside the sphere to beyond it: in and out, and the count says how many surfaces.
    const common::Mesh mesh = kt::sphere(40, 80, 1.0);
    const kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[2]);
    kdrt_hit hits[8];
    for (int i = 0; i < 200; ++i) {
        const float y = -0.9f + 1.8f * float(i) / 199.0f;
        const kdrt_ray ray = kt::ray_of(-3.0f, y, 0.1f, 1.0f, 0.0f, 0.0f);
        INFO("ray at y = " << y);
        const uint32_t n = kdrt_intersect_k(tree.get(), &ray, hits, 8);
        CHECK(n >= 2);
        if (n >= 2) CHECK(hits[0].t < hits[n - 1].t);
        // The segment ending inside the sphere crosses it once.
        kdrt_ray half = ray;
        half.tmax = 3.0f;
        CHECK(kdrt_intersect_k(tree.get(), &half, hits, 8) >= 1);
    }
}

TEST_CASE("k nearest: NULL arguments and capacity 0 give 0 and write nothing", "[k-nearest]") {
    const common::Mesh mesh = kt::sphere(8, 16, 1.0);
    const kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[1]);
    const kdrt_ray ray = kt::ray_of(-3.0f, 0.1f, 0.1f, 1.0f, 0.0f, 0.0f);
    kdrt_hit hit;
    hit.triangle = 77;
    CHECK(kdrt_intersect_k(nullptr, &ray, &hit, 1) == 0);
    CHECK(kdrt_intersect_k(tree.get(), nullptr, &hit, 1) == 0);
    CHECK(kdrt_intersect_k(tree.get(), &ray, nullptr, 1) == 0);
    CHECK(kdrt_intersect_k(tree.get(), &ray, &hit, 0) == 0);
    CHECK(hit.triangle == 77u);
    CHECK(kdrt_intersect_k(tree.get(), &ray, &hit, 1) == 1);
    kdrt_ray bad = ray;
    bad.dir[0] = std::nanf("");
    CHECK(kdrt_intersect_k(tree.get(), &bad, &hit, 1) == 0);
}
