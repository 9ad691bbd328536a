// The queries beyond kdrt_intersect(): kdrt_intersect_k(), the k nearest hits along a ray, sorted
// by (t, triangle), each triangle once; and kdrt_query, faces culled and a filter deciding each
// candidate, for the nearest hit, any hit and the k nearest. Checked against brute forces: on
// small meshes, every triangle in a tree of its own traced with kdrt_intersect() (the validated
// nearest-hit query, sharing nothing of this code but the triangle test), the hits sorted, kept
// as the query would keep them (the faces told apart by the double-precision normal) and cut at
// k; on large ones, the tree of leaf size 0, which tests every triangle in one leaf. Every
// builder and quality, both kernels.

#include "test_support.hpp"
#include "oracle/hard_cases.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <vector>

namespace {

bool hit_before(const kdrt_hit &a, const kdrt_hit &b) {
    return a.t < b.t || (a.t == b.t && a.triangle < b.triangle);
}

// Every hit of the ray on the mesh, sorted: one single-triangle tree per triangle, the tree's
// index the triangle's; and each triangle's normal in double, to tell its faces apart.
struct EveryTriangleTree {
    std::vector<kt::TreePtr> trees;
    std::vector<std::array<double, 3>> normals;
    explicit EveryTriangleTree(const common::Mesh &mesh, kdrt_intersector intersector = KDRT_INTERSECTOR_WATERTIGHT) {
        for (uint32_t i = 0; i < mesh.triangle_count(); ++i) {
            double p[3][3];
            mesh.corners(i, p);
            const double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
            const double e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
            normals.push_back({e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]});
            kdrt_triangles view = mesh.view();
            if (view.indices) view.indices += 3 * size_t(i);
            else view.positions += 9 * size_t(i);
            view.triangle_count = 1;
            if (!view.indices) view.vertex_count = 3;
            kdrt_build_options o = kdrt_default_build_options();
            o.max_leaf_size = 0;
            o.intersector = intersector;
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
    // 1 where the ray meets the triangle's front face, -1 its back, 0 too close to its plane to
    // tell in single precision (the cosine below 1e-4).
    int facing(const kdrt_ray &ray, uint32_t triangle) const {
        const std::array<double, 3> &n = normals[triangle];
        const double d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
        const double dot = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
        const double norms = std::sqrt((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]));
        return std::fabs(dot) < 1e-4 * norms ? 0 : dot < 0 ? 1 : -1;
    }
};

std::vector<kdrt_hit> k_nearest(const kdrt_tree *tree, const kdrt_ray &ray, uint32_t k) {
    std::vector<kdrt_hit> hits(k + 1);
    hits[k].triangle = 12345;  // a guard: nothing is written past capacity
    const uint32_t n = kdrt_intersect_k(tree, &ray, nullptr, hits.data(), k);
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
                    const uint32_t n = kdrt_intersect_k(tree.get(), &rays[r], nullptr, &one, 1);
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
        const uint32_t n = kdrt_intersect_k(tree.get(), &ray, nullptr, hits, 8);
        CHECK(n >= 2);
        if (n >= 2) CHECK(hits[0].t < hits[n - 1].t);
        // The segment ending inside the sphere crosses it once.
        kdrt_ray half = ray;
        half.tmax = 3.0f;
        CHECK(kdrt_intersect_k(tree.get(), &half, nullptr, hits, 8) >= 1);
    }
}

TEST_CASE("k nearest: NULL arguments and capacity 0 give 0 and write nothing", "[k-nearest]") {
    const common::Mesh mesh = kt::sphere(8, 16, 1.0);
    const kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[1]);
    const kdrt_ray ray = kt::ray_of(-3.0f, 0.1f, 0.1f, 1.0f, 0.0f, 0.0f);
    kdrt_hit hit;
    hit.triangle = 77;
    CHECK(kdrt_intersect_k(nullptr, &ray, nullptr, &hit, 1) == 0);
    CHECK(kdrt_intersect_k(tree.get(), nullptr, nullptr, &hit, 1) == 0);
    CHECK(kdrt_intersect_k(tree.get(), &ray, nullptr, nullptr, 1) == 0);
    CHECK(kdrt_intersect_k(tree.get(), &ray, nullptr, &hit, 0) == 0);
    CHECK(hit.triangle == 77u);
    CHECK(kdrt_intersect_k(tree.get(), &ray, nullptr, &hit, 1) == 1);
    kdrt_ray bad = ray;
    bad.dir[0] = std::nanf("");
    CHECK(kdrt_intersect_k(tree.get(), &bad, nullptr, &hit, 1) == 0);
}

namespace {

// What a query gets, from the brute force's hits: those it counts, in order, cut at k.
std::vector<kdrt_hit> kept(const std::vector<kdrt_hit> &all, const std::function<bool(const kdrt_hit &)> &counts, size_t k) {
    std::vector<kdrt_hit> out;
    for (const kdrt_hit &h : all)
        if (out.size() < k && counts(h)) out.push_back(h);
    return out;
}

// A filter taking even triangles only, which also checks what it is given.
struct EvenFilter {
    const kdrt_ray *ray = nullptr;  // the ray it must be shown
    size_t calls = 0, wrong_ray = 0;
    static int call(void *user, const kdrt_ray *ray, const kdrt_hit *candidate) {
        EvenFilter &f = *static_cast<EvenFilter *>(user);
        f.calls += 1, f.wrong_ray += ray != f.ray;
        return candidate->triangle % 2 == 0;
    }
};

// Each query of `query` on tree against the brute force's hits kept by `counts`: the nearest
// hit, any hit, and the k nearest for each of kCapacities. Returns the number of wrong answers;
// first describes the first.
size_t check_query(const kdrt_tree *tree, const kdrt_ray &ray, kdrt_query query, const std::vector<kdrt_hit> &all,
                   const std::function<bool(const kdrt_hit &)> &counts, std::string &first) {
    size_t wrong = 0;
    auto fail = [&](const std::string &what) {
        if (!wrong++) first = what;
    };
    const std::vector<kdrt_hit> want = kept(all, counts, 64);
    kdrt_hit hit;
    const int found = kdrt_intersect_query(tree, &ray, &query, &hit);
    if (found != !want.empty() || (found && !kt::same_hit(hit, want[0])))
        fail("nearest: " + (found ? "triangle " + std::to_string(hit.triangle) : std::string("a miss")) + " against " +
             (want.empty() ? std::string("a miss") : "triangle " + std::to_string(want[0].triangle)));
    if (kdrt_occluded_query(tree, &ray, &query) != !want.empty()) fail("any hit");
    for (uint32_t k : kCapacities) {
        std::vector<kdrt_hit> got(k);
        got.resize(kdrt_intersect_k(tree, &ray, &query, got.data(), k));
        std::string why;
        if (!same_list(got, std::vector<kdrt_hit>(want.begin(), want.begin() + std::min<size_t>(k, want.size())), why))
            fail("k " + std::to_string(k) + ": " + why);
    }
    return wrong;
}

}  // namespace

TEST_CASE("query: culled faces are those the double-precision normal says, both tests", "[query]") {
    const common::Mesh meshes[] = {kt::sphere(8, 16, 1.0), kt::random_soup(200, 4), oracle::hostile_mesh("overlapping", 150, 2)};
    size_t checked = 0, grazing = 0;
    for (const common::Mesh &mesh : meshes)
        for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST}) {
            const EveryTriangleTree every(mesh, intersector);
            const std::vector<kdrt_ray> rays = rays_for(mesh, 300, 41);
            for (const kt::Builder &builder : kt::kBuilders)
                for (uint32_t flags : {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)}) {
                    INFO(mesh.name << ", " << builder.name << (intersector ? ", fast test" : ", watertight test")
                                   << (flags ? ", scalar kernel" : ""));
                    kdrt_build_options o = kdrt_default_build_options();
                    builder.apply(o);
                    o.max_leaf_size = 4, o.flags = flags, o.intersector = intersector;
                    const kdrt_triangles view = mesh.view();
                    kdrt_tree *built = nullptr;
                    REQUIRE(kdrt_tree_build(&view, &o, &built, nullptr) == KDRT_SUCCESS);
                    const kt::TreePtr tree(built);
                    size_t wrong = 0;
                    std::string first;
                    for (const kdrt_ray &ray : rays) {
                        const std::vector<kdrt_hit> all = every.hits(ray);
                        bool ambiguous = false;
                        for (const kdrt_hit &h : all) ambiguous |= every.facing(ray, h.triangle) == 0;
                        if (ambiguous) {
                            ++grazing;
                            continue;
                        }
                        ++checked;
                        const struct {
                            uint32_t flags;
                            int facing;  // the face that counts, 0 for neither
                        } cases[] = {{KDRT_QUERY_CULL_BACK_FACES, 1}, {KDRT_QUERY_CULL_FRONT_FACES, -1},
                                     {KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES, 0}};
                        for (const auto &c : cases) {
                            kdrt_query query = kdrt_default_query();
                            query.flags = c.flags;
                            wrong += check_query(tree.get(), ray, query, all,
                                                 [&](const kdrt_hit &h) { return every.facing(ray, h.triangle) == c.facing; }, first);
                        }
                    }
                    INFO(first);
                    CHECK(wrong == 0);
                }
        }
    CHECK(grazing * 50 < checked);  // few rays left out as too close to a triangle's plane
}

TEST_CASE("query: a filter decides each candidate, for the nearest, any and k nearest hits", "[query]") {
    const common::Mesh meshes[] = {kt::sphere(8, 16, 1.0), oracle::hostile_mesh("overlapping", 150, 2),
                                   oracle::hostile_mesh("identical", 100, 3)};
    for (const common::Mesh &mesh : meshes) {
        const EveryTriangleTree every(mesh);
        const std::vector<kdrt_ray> rays = rays_for(mesh, 300, 43);
        for (const kt::Builder &builder : kt::kBuilders)
            for (uint32_t flags : {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)}) {
                INFO(mesh.name << ", " << builder.name << (flags ? ", scalar kernel" : ""));
                const kt::TreePtr tree = kt::build(mesh, 4, builder, flags);
                EvenFilter filter;
                kdrt_query query = kdrt_default_query();
                query.filter = &EvenFilter::call, query.user = &filter;
                size_t wrong = 0;
                std::string first;
                for (const kdrt_ray &ray : rays) {
                    filter.ray = &ray;
                    wrong += check_query(tree.get(), ray, query, every.hits(ray),
                                         [](const kdrt_hit &h) { return h.triangle % 2 == 0; }, first);
                    // Without a filter, the query is the plain one.
                    kdrt_hit a, b;
                    const kdrt_query none = kdrt_default_query();
                    const int fa = kdrt_intersect_query(tree.get(), &ray, &none, &a), fb = kdrt_intersect(tree.get(), &ray, &b);
                    wrong += fa != fb || (fa && !kt::same_hit(a, b));
                    wrong += kdrt_intersect_query(tree.get(), &ray, nullptr, &a) != fb;
                    wrong += kdrt_occluded_query(tree.get(), &ray, nullptr) != kdrt_occluded(tree.get(), &ray);
                }
                INFO(first);
                CHECK(wrong == 0);
                CHECK(filter.calls > rays.size());  // the test means something: the filter was asked
                CHECK(filter.wrong_ray == 0);
            }
    }
}

TEST_CASE("query: a filter that refuses every hit leaves nothing, and a NULL hit or tree", "[query]") {
    const common::Mesh mesh = kt::sphere(8, 16, 1.0);
    const kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[1]);
    kdrt_query none = kdrt_default_query();
    CHECK(none.flags == 0u);
    CHECK(none.filter == nullptr);
    kdrt_query refuse = kdrt_default_query();
    refuse.filter = [](void *, const kdrt_ray *, const kdrt_hit *) { return 0; };
    const kdrt_ray ray = kt::ray_of(-3.0f, 0.1f, 0.1f, 1.0f, 0.0f, 0.0f);
    kdrt_hit hit, hits[4];
    CHECK(kdrt_intersect_query(tree.get(), &ray, &none, &hit) == 1);
    CHECK(kdrt_intersect_query(tree.get(), &ray, &refuse, &hit) == 0);
    CHECK(hit.triangle == KDRT_INVALID_ID);
    CHECK(kdrt_occluded_query(tree.get(), &ray, &refuse) == 0);
    CHECK(kdrt_intersect_k(tree.get(), &ray, &refuse, hits, 4) == 0);
    CHECK(kdrt_intersect_query(nullptr, &ray, &none, &hit) == 0);
    CHECK(hit.triangle == KDRT_INVALID_ID);
    CHECK(kdrt_intersect_query(tree.get(), &ray, &none, nullptr) == 0);
    CHECK(kdrt_occluded_query(nullptr, &ray, &none) == 0);
}
