// The SAH builder's parallel build: the tree depends only on the input, never on the scheduler.
// Each build below must equal the one built without a scheduler, node for node as far as the
// public API can see: the statistics, and the answer to every one of 20,000 random rays.

#include "test_support.hpp"
#include "thread_scheduler.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
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

kt::TreePtr build_sah(const kt::Mesh &mesh, uint32_t leaf, const kdrt_scheduler &scheduler) {
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = KDRT_BUILDER_SAH;
    o.max_leaf_size = leaf;
    o.scheduler = scheduler;
    kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

void check_same_tree(const kdrt_tree *a, const kdrt_tree *b, const std::vector<kdrt_ray> &rays) {
    kdrt_tree_stats sa, sb;
    kdrt_tree_get_stats(a, &sa);
    kdrt_tree_get_stats(b, &sb);
    CHECK(sa.triangles == sb.triangles);
    CHECK(sa.nodes == sb.nodes);
    CHECK(sa.leaves == sb.leaves);
    CHECK(sa.max_depth == sb.max_depth);
    CHECK(sa.triangle_refs == sb.triangle_refs);
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
        kt::Mesh mesh;
    };
    Scene scenes[] = {{"sphere, 40,000 triangles", kt::sphere(100, 200, 1.0)},
                      {"random soup, 30,000 triangles", kt::random_soup(30000, 5)},
                      {"random soup, 300 triangles (one task)", kt::random_soup(300, 6)}};
    for (Scene &scene : scenes) {
        for (uint32_t leaf : {1u, 4u}) {
            INFO(scene.name << ", leaf size " << leaf);
            kt::TreePtr serial = build_sah(scene.mesh, leaf, kdrt_scheduler{nullptr, nullptr});
            const std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(serial.get()), 20000, 11);

            ReverseScheduler reverse;
            kt::TreePtr reversed = build_sah(scene.mesh, leaf, reverse.hooks());
            CHECK(reverse.runs == 1);
            if (scene.mesh.triangle_count() > 20000) CHECK(reverse.tasks > 2);  // the test means something
            check_same_tree(serial.get(), reversed.get(), rays);

            for (unsigned threads : {1u, 2u, 3u, 8u}) {
                INFO(threads << " threads");
                kb::ThreadScheduler pool(threads);
                kt::TreePtr parallel = build_sah(scene.mesh, leaf, pool.hooks());
                check_same_tree(serial.get(), parallel.get(), rays);
            }
        }
    }
}
