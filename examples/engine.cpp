// kdrt inside a game engine: the engine's vertex layout, job system and allocator, and ray
// queries from several threads at once. Needs only kdrt.h and the C++ standard library.
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

// The engine's interleaved layout. kdrt reads only the positions, through the stride.
struct Vertex { float position[3]; float normal[3]; float uv[2]; };

// The engine's job system: worker threads taking jobs from one queue.
class JobSystem {
public:
    explicit JobSystem(unsigned workers) { while (workers--) threads_.emplace_back([this] { while (run_one(true)) {} }); }
    ~JobSystem() {
        { std::lock_guard<std::mutex> lock(mutex_); stop_ = true; }
        wake_.notify_all();
        for (std::thread &t : threads_) t.join();
    }
    // body(i) for each i in [0, count) on the workers and this thread; returns when all are done.
    void parallel_for(uint32_t count, const std::function<void(uint32_t)> &body) {
        std::atomic<uint32_t> left(count);
        std::unique_lock<std::mutex> lock(mutex_);
        for (uint32_t i = 0; i < count; ++i) jobs_.push_back([&body, &left, i] { body(i); --left; });
        lock.unlock();
        wake_.notify_all();
        while (left > 0) if (!run_one(false)) std::this_thread::yield(); // help rather than sleep
    }
    // kdrt_scheduler.run, kdrt's hook into it: the same contract, for the build's tasks.
    static void run(void *user, kdrt_task_fn task, void *data, uint32_t count) {
        static_cast<JobSystem *>(user)->parallel_for(count, [=](uint32_t i) { task(data, i); });
        static_cast<JobSystem *>(user)->build_tasks += count;
    }
    uint32_t build_tasks = 0;

private:
    bool run_one(bool wait) { // runs a queued job, waiting for one if asked; false: none, or stopping
        std::unique_lock<std::mutex> lock(mutex_);
        if (wait) wake_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
        if (jobs_.empty()) return false;
        std::function<void()> job = std::move(jobs_.front());
        jobs_.pop_front();
        lock.unlock();
        job();
        return true;
    }
    std::vector<std::thread> threads_;
    std::deque<std::function<void()>> jobs_;
    std::mutex mutex_; // guards jobs_ and stop_
    std::condition_variable wake_;
    bool stop_ = false;
};

// The engine's allocator, counting bytes in use. kdrt's free() is given no size, so a block
// keeps its own in a header that keeps malloc's alignment. The build's tasks call it on workers.
struct CountingAllocator {
    std::atomic<size_t> in_use{0};
    static void *alloc(void *user, size_t size) {
        if (size > SIZE_MAX - sizeof(std::max_align_t)) return nullptr;
        auto *block = static_cast<std::max_align_t *>(std::malloc(sizeof(std::max_align_t) + size));
        if (!block) return nullptr; // kdrt then fails with KDRT_ERROR_OUT_OF_MEMORY
        *reinterpret_cast<size_t *>(block) = size;
        static_cast<CountingAllocator *>(user)->in_use += size;
        return block + 1;
    }
    static void free(void *user, void *ptr) { // kdrt never passes NULL
        std::max_align_t *block = static_cast<std::max_align_t *>(ptr) - 1;
        static_cast<CountingAllocator *>(user)->in_use -= *reinterpret_cast<size_t *>(block);
        std::free(block);
    }
};

struct Counts { std::atomic<unsigned> hits{0}, bounce_hits{0}, shadow_rays{0}, occluded{0}; };
static const float kLight[3] = {-4.0f, 3.0f, 2.0f};
static float dot(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Brightness seen along a ray: ambient, plus the point light unless a shadow ray finds something
// on the way to it, plus (for a primary ray) what one mirror bounce sees.
static float shade(const kdrt_tree *tree, const kdrt_ray &ray, bool primary, Counts &counts) {
    kdrt_hit hit;
    if (!kdrt_intersect(tree, &ray, &hit)) return 0;
    ++(primary ? counts.hits : counts.bounce_hits);
    float p[3], n[3], to_light[3];
    kdrt_hit_surface(tree, &hit, p, n); // the point from the barycentrics, the unit geometric normal
    if (dot(n, ray.dir) > 0) for (float &c : n) c = -c; // two-sided: the normal faces the ray
    for (int k = 0; k < 3; ++k) to_light[k] = kLight[k] - p[k];
    float light = std::max(0.0f, dot(n, to_light) / std::sqrt(dot(to_light, to_light)));
    if (light > 0) { // only the lit side needs a shadow ray
        kdrt_ray shadow;
        kdrt_spawn_ray(tree, &hit, to_light, &shadow); // starts off the surface: no self-shadowing,
                                                       // and in the hit's cell: no descent (kdrt.h,
                                                       // START CELLS)
        for (int k = 0; k < 3; ++k) shadow.dir[k] = kLight[k] - shadow.org[k]; // t = 1 at the light,
        shadow.tmax = 0.999f;                                                  // so stop short of it
        ++counts.shadow_rays;
        if (kdrt_occluded(tree, &shadow)) light = 0, ++counts.occluded;
    }
    float result = 0.1f + 0.6f * light, mirror[3];
    if (primary) {
        kdrt_ray bounce;
        kdrt_reflect(ray.dir, n, mirror);
        kdrt_spawn_ray(tree, &hit, mirror, &bounce);
        result += 0.3f * shade(tree, bounce, false, counts);
    }
    return result;
}

int main() {
    // One vertex and one index buffer (kdrt takes 32-bit indices: widen 16-bit ones): a ground quad
    // and 24 x 24 boxes, enough triangles (6914) for the build to hand subtrees to the job system.
    std::vector<Vertex> vertices = {{{-4, 0, -4}, {0, 1, 0}, {0, 0}}, {{4, 0, -4}, {0, 1, 0}, {1, 0}},
                                    {{4, 0, 4}, {0, 1, 0}, {1, 1}}, {{-4, 0, 4}, {0, 1, 0}, {0, 1}}};
    std::vector<uint32_t> indices = {0, 2, 1, 0, 3, 2};
    const uint32_t faces[24] = {0, 2, 6, 4, 1, 3, 7, 5, 0, 1, 5, 4, 2, 3, 7, 6, 0, 1, 3, 2, 4, 5, 7, 6};
    for (uint32_t i = 0; i < 24 * 24; ++i) {
        const float x = 0.3f * (i % 24) - 3.6f, z = 0.3f * (i / 24) - 3.6f, height = 0.1f + 0.05f * (i * 7919 % 13);
        const uint32_t base = uint32_t(vertices.size());
        for (uint32_t c = 0; c < 8; ++c) // corner c: bit 0 is x, bit 1 y, bit 2 z
            vertices.push_back({{x + 0.2f * (c & 1), height * (c >> 1 & 1), z + 0.2f * (c >> 2 & 1)}, {0, 1, 0}, {0, 0}});
        for (const uint32_t *f = faces; f < faces + 24; f += 4)
            indices.insert(indices.end(), {base + f[0], base + f[1], base + f[2], base + f[0], base + f[2], base + f[3]});
    }

    kdrt_triangles mesh = {}; // borrowed: the buffers must outlive the tree
    mesh.positions = vertices[0].position;
    mesh.position_stride = sizeof(Vertex);
    mesh.vertex_count = uint32_t(vertices.size());
    mesh.indices = indices.data();
    mesh.triangle_count = uint32_t(indices.size() / 3);

    JobSystem jobs(3);
    CountingAllocator memory;
    kdrt_build_options options = kdrt_default_build_options();
    options.scheduler = {&JobSystem::run, &jobs};
    options.allocator = {&CountingAllocator::alloc, &CountingAllocator::free, &memory};
    kdrt_tree *tree = nullptr;
    const kdrt_result r = kdrt_tree_build(&mesh, &options, &tree, nullptr);
    if (r != KDRT_SUCCESS) {
        std::fprintf(stderr, "kdrt: %s\n", kdrt_result_string(r));
        return 1;
    }
    std::printf("built: %u triangles, %u tasks on the job system, %zu bytes in use\n", mesh.triangle_count,
                jobs.build_tasks, memory.in_use.load());

    // A 64 x 24 ASCII image from (0, 4, 6) looking at the origin, a row per job. The tree is
    // const and needs no lock: the workers and this thread query it at once.
    const int width = 64, height = 24;
    std::vector<char> image(size_t(width) * height);
    Counts counts;
    const auto camera_ray = [&](int x, int y) { // a character is about twice as tall as wide
        const float sx = (2.0f * (x + 0.5f) / width - 1) * 0.9f, sy = (1 - 2.0f * (y + 0.5f) / height) * 0.35f;
        return kdrt_ray{{0, 4, 6}, 0, {sx, -0.555f + 0.832f * sy, -0.832f - 0.555f * sy}, INFINITY, 0};
    };
    jobs.parallel_for(height, [&](uint32_t y) {
        for (int x = 0; x < width; ++x)
            image[size_t(y) * width + x] = " .:-=+*#%@"[std::min(9, int(10 * shade(tree, camera_ray(x, int(y)), true, counts)))];
    });

    // The same camera rays handed over at once, as a renderer hands them: in 4 x 4 pixel tiles,
    // whose 16 neighbouring rays walk the tree together (8 at a time with AVX2; kdrt.h, BATCHES).
    // Each answer is the single call's, bit for bit.
    std::vector<kdrt_ray> tiles;
    for (int ty = 0; ty < height; ty += 4)
        for (int tx = 0; tx < width; tx += 4)
            for (int y = ty; y < ty + 4; ++y)
                for (int x = tx; x < tx + 4; ++x) tiles.push_back(camera_ray(x, y));
    std::vector<kdrt_hit> tile_hits(tiles.size());
    const uint32_t tile_found = kdrt_intersect_batch(tree, tiles.data(), uint32_t(tiles.size()), nullptr, tile_hits.data());
    uint32_t tile_differ = 0;
    for (size_t i = 0; i < tiles.size(); ++i) {
        kdrt_hit one;
        kdrt_intersect(tree, &tiles[i], &one);
        tile_differ += std::memcmp(&one, &tile_hits[i], sizeof one) != 0;
    }
    std::printf("one batch: %u of %zu camera rays hit\n", tile_found, tiles.size());

    // Line of sight from an eye inside the level, between the boxes, to points on the ground:
    // kdrt_locate() finds the cell that holds the eye once, and every ray from there starts in it
    // instead of descending from the root. A cell is only a hint: the answers are the same.
    const float eye[3] = {0.25f, 0.3f, 0.25f};
    const uint32_t eye_cell = kdrt_locate(tree, eye);
    uint32_t visible = 0, differ = 0;
    for (int i = 0; i < 1000; ++i) {
        const float gx = 7.0f * (i % 40) / 39 - 3.5f, gz = 7.0f * (i / 40) / 24 - 3.5f;
        kdrt_ray sight = {{eye[0], eye[1], eye[2]}, 0, {gx - eye[0], 0.001f - eye[1], gz - eye[2]}, 1.0f, eye_cell};
        const int blocked = kdrt_occluded(tree, &sight);
        sight.cell = 0; // from the root, for the check
        differ += blocked != kdrt_occluded(tree, &sight);
        visible += !blocked;
    }
    std::printf("from an eye inside the level (cell %u): %u of 1000 ground points in sight\n", eye_cell, visible);
    kdrt_tree_free(tree);
    if (eye_cell == 0 || differ) {
        std::fprintf(stderr, "the eye's cell is %u, and %u answers from it differ from the root's\n", eye_cell, differ);
        return 1;
    }
    if (tile_differ || tile_found != counts.hits.load()) {
        std::fprintf(stderr, "%u batch answers differ from the single calls'\n", tile_differ);
        return 1;
    }

    for (int y = 0; y < height; ++y) std::printf("|%.*s|\n", width, &image[size_t(y) * width]);
    std::printf("%u of %d pixels hit, %u bounces hit, %u shadow rays, %.1f%% of them shadowed\n", counts.hits.load(),
                width * height, counts.bounce_hits.load(), counts.shadow_rays.load(),
                100.0 * counts.occluded / std::max(1u, counts.shadow_rays.load()));
    std::printf("after kdrt_tree_free: %zu bytes in use\n", memory.in_use.load());
    return memory.in_use == 0 ? 0 : 1;
}
