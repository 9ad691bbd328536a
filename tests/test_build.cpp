// The SAH builder's parallel build: the tree depends only on the input, never on the scheduler.
// Each build below must equal the one built without a scheduler, node for node as far as the
// public API can see: the statistics, every node and reference, and the answer to every one of
// 20,000 random rays.

#include "test_support.hpp"
#include "common/thread_scheduler.hpp"
#include "oracle/hard_cases.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cstring>
#include <vector>

namespace {

// Runs the tasks on the calling thread, last first, and remembers how many it was given.
struct ReverseScheduler {
    uint32_t tasks = 0, runs = 0;
    static void run(void *user, kdrt_task_fn task, void *data, uint32_t count) {
        ReverseScheduler *self = static_cast<ReverseScheduler *>(user);
        self->tasks = count, self->runs += 1;
        for (uint32_t i = count; i-- > 0;) task(data, i);
    }
    kdrt_scheduler hooks() { return kdrt_scheduler{&ReverseScheduler::run, this}; }
};

kt::TreePtr build_sah(const common::Mesh &mesh, const kt::Builder &builder, uint32_t leaf, const kdrt_scheduler &scheduler) {
    kdrt_build_options o = kdrt_default_build_options();
    builder.apply(o);
    o.max_leaf_size = leaf;
    o.scheduler = scheduler;
    kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

void check_same_tree(const kdrt_tree *a, const kdrt_tree *b, const std::vector<kdrt_ray> &rays) {
    kt::check_same_shape(a, b);
    kdrt_tree_stats sa, sb;
    kdrt_tree_get_stats(a, &sa);
    kdrt_tree_get_stats(b, &sb);
    CHECK(sa.triangles == sb.triangles);
    CHECK(sa.bytes == sb.bytes);
    std::vector<kdrt_hit> ha = kt::trace_all(a, rays), hb = kt::trace_all(b, rays);
    size_t differ = 0;
    for (size_t i = 0; i < rays.size(); ++i) differ += !kt::same_hit(ha[i], hb[i]);
    CHECK(differ == 0);
    CHECK(kt::occluded_all(a, rays) == kt::occluded_all(b, rays));
}

}  // namespace

TEST_CASE("build: the parallel SAH build gives the same tree on any scheduler", "[build][sah]") {
    struct Scene {
        const char *name;
        common::Mesh mesh;
    };
    // Above 20,000 triangles (checked below), the top is cut into tasks and binned in chunks.
    Scene scenes[] = {{"sphere, 22,500 triangles", kt::sphere(75, 150, 1.0)},
                      {"random soup, 22,000 triangles", kt::random_soup(22000, 5)},
                      {"random soup, 300 triangles (one task)", kt::random_soup(300, 6)}};
    for (Scene &scene : scenes) {
        for (const kt::Builder &builder : kt::kSahBuilders)
            for (uint32_t leaf : {1u, 4u}) {
                INFO(scene.name << ", " << builder.name << ", leaf size " << leaf);
                kt::TreePtr serial = build_sah(scene.mesh, builder, leaf, kdrt_scheduler{nullptr, nullptr});
                const std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(serial.get()), 20000, 11);

                ReverseScheduler reverse;
                kt::TreePtr reversed = build_sah(scene.mesh, builder, leaf, reverse.hooks());
                if (scene.mesh.triangle_count() > 20000) {
                    CHECK(reverse.tasks > 2);  // the test means something: the last run, the subtrees
                    // Before it, the large top nodes binned in chunks (not HIGH's: it sorts).
                    if (builder.quality != KDRT_BUILD_QUALITY_HIGH) CHECK(reverse.runs > 1);
                }
                check_same_tree(serial.get(), reversed.get(), rays);

                for (unsigned threads : {1u, 2u, 3u, 8u}) {
                    INFO(threads << " threads");
                    common::ThreadScheduler pool(threads);
                    kt::TreePtr parallel = build_sah(scene.mesh, builder, leaf, pool.hooks());
                    check_same_tree(serial.get(), parallel.get(), rays);
                }
            }
    }
}

// The builder bins with SSE2 where it is compiled in, and with scalar code under
// KDRT_BUILD_SCALAR_KERNEL: each lane must round and clamp as the scalar code does, so the two
// give the same tree. A box whose extent overflows to infinity has bin scale 0 on that axis, and
// infinity times 0 is NaN: such an axis is not costed, but its bins must stay in range (ASan).
// The planes between the bins are costed 8 at a time with AVX2 where the CPU has it, else 4 at
// a time with SSE2 (kdrt_sse2_tests runs this without AVX2), and must cost what the scalar loop
// does bit for bit: the fan's nodes also run into the reference budget, which rules planes
// out. The children's arrays are sized from the bins, so ASan checks those bounds here too.
TEST_CASE("build: SIMD and scalar binning and plane costing give the same tree", "[build][sah]") {
    common::Mesh huge = kt::random_soup(3000, 8);  // corners from -3e38 to 3e38: extents overflow
    for (float &p : huge.positions) p = float((p - 5.0) * 6e37);
    huge.name = "soup from -3e38 to 3e38";
    common::Mesh flat = kt::grid(80, 80, 2);  // z = 0 only: an axis of scale 0 at every node
    for (size_t i = 2; i < flat.positions.size(); i += 3) flat.positions[i] = 0.0f;
    const common::Mesh meshes[] = {kt::sphere(100, 200, 1.0), kt::random_soup(30000, 5), flat, huge,
                                   oracle::hostile_mesh("fan", 20000, 7)};
    for (const common::Mesh &mesh : meshes)
        for (const kt::Builder &builder : kt::kSahBuilders) {
            INFO(mesh.name << ", " << builder.name);
            kt::TreePtr a = kt::build(mesh, 4, builder), b = kt::build(mesh, 4, builder, KDRT_BUILD_SCALAR_KERNEL);
            if (&mesh != &meshes[3]) CHECK(kdrt_tree_node_count(a.get()) > 1);
            kt::check_same_shape(a.get(), b.get());
        }
}

namespace {

// Whether the triangle meets the box [lo - margin, hi + margin] (margin < 0 shrinks it): the
// triangle clipped to the box's six half spaces in double, Sutherland-Hodgman, is not empty.
bool triangle_meets_box(const double tri[3][3], const kdrt_aabb &box, double margin) {
    std::vector<std::array<double, 3>> poly = {{tri[0][0], tri[0][1], tri[0][2]},
                                               {tri[1][0], tri[1][1], tri[1][2]},
                                               {tri[2][0], tri[2][1], tri[2][2]}};
    for (int k = 0; k < 3; ++k)
        for (int side = 0; side < 2; ++side) {
            double plane = side ? box.max[k] + margin : box.min[k] - margin, sign = side ? -1.0 : 1.0;
            std::vector<std::array<double, 3>> out;
            for (size_t i = 0; i < poly.size(); ++i) {
                const auto &s = poly[i], &e = poly[(i + 1) % poly.size()];
                double ds = sign * (s[k] - plane), de = sign * (e[k] - plane);
                if (ds >= 0.0) out.push_back(s);
                if ((ds < 0.0 && de > 0.0) || (ds > 0.0 && de < 0.0)) {
                    std::array<double, 3> x;
                    for (int a = 0; a < 3; ++a) x[a] = s[a] + ds / (ds - de) * (e[a] - s[a]);
                    out.push_back(x);
                }
            }
            poly.swap(out);
            if (poly.empty()) return false;
        }
    return true;
}

}  // namespace

// Perfect splits (MEDIUM, HIGH): a triangle the plane cuts is clipped to each child's box, so a
// leaf refers to a triangle only if some of it lies in the leaf's box (within rounding), and, for
// the tree to be right at all, to every triangle that reaches into the box. Splitting the
// triangles' boxes alone (FAST) keeps the second half only, and breaks the first on these curved
// meshes.
TEST_CASE("build: SAH leaves refer to exactly the triangles that meet their boxes", "[build][sah]") {
    const common::Mesh meshes[] = {kt::sphere(16, 32, 1.0), kt::random_soup(600, 11), kt::grid(12, 12, 5)};
    size_t fast_outside = 0;
    for (const common::Mesh &mesh : meshes) {
        for (const kt::Builder &builder : kt::kSahBuilders)
            for (uint32_t leaf : {1u, 4u}) {
                kt::TreePtr tree = kt::build(mesh, leaf, builder);
                kdrt_aabb bounds = kdrt_tree_bounds(tree.get());
                double extent = 0.0;
                for (int k = 0; k < 3; ++k) extent = std::max(extent, double(bounds.max[k]) - bounds.min[k]);
                const double margin = 1e-5 * extent;
                size_t leaves = 0, references = 0, outside = 0, missing = 0;
                std::vector<unsigned char> referenced(mesh.triangle_count());
                for (uint32_t i = 0; i < kdrt_tree_node_count(tree.get()); ++i) {
                    kdrt_node_info info;
                    REQUIRE(kdrt_tree_node(tree.get(), i, &info) == KDRT_SUCCESS);
                    if (!info.is_leaf) continue;
                    ++leaves;
                    std::fill(referenced.begin(), referenced.end(), 0);
                    for (uint32_t r = 0; r < info.triangle_count; ++r) {
                        uint32_t t = KDRT_INVALID_ID;
                        REQUIRE(kdrt_tree_reference(tree.get(), info.first_reference + r, &t) == KDRT_SUCCESS);
                        double p[3][3];
                        mesh.corners(t, p);
                        referenced[t] = 1, ++references;
                        outside += !triangle_meets_box(p, info.bounds, margin);
                    }
                    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
                        double p[3][3];
                        mesh.corners(t, p);
                        missing += !referenced[t] && triangle_meets_box(p, info.bounds, -margin);
                    }
                }
                INFO(mesh.name << ", " << builder.name << ", leaf size " << leaf << ": " << leaves << " leaves, " << references
                               << " references");
                CHECK(leaves > (builder.quality == KDRT_BUILD_QUALITY_FAST ? 4u : 10u));  // the test means something
                if (builder.quality == KDRT_BUILD_QUALITY_FAST) fast_outside += outside;
                else CHECK(outside == 0);
                CHECK(missing == 0);
            }
    }
    CHECK(fast_outside > 0);  // FAST really splits boxes, not triangles
}
