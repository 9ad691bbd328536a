// libFuzzer target: kdrt_tree_load (and kdrt_saved_tree_read_info) on any bytes, as a saved tree
// over one of four small meshes made here (a closed sphere, a height field, the sphere as a soup,
// no triangles). The first input byte chooses the mesh (bits 0-1), a load in place from 64-byte
// aligned bytes (bit 2), the scalar kernel (bit 3), whether the file's checksums are made again
// before the load (bit 4: a forged file, which the structural checks must refuse, since a changed
// byte alone fails the checksums) and an allocation to fail (bits 5-7, 0: none); the rest is the
// file. The seeds (corpus/load) are real saved trees of those meshes, of every
// builder, quality, leaf size (0 included), intersector and depth, an empty tree among them.
// Checked: a load succeeds, or fails with a NULL tree and nothing left allocated, never
// allocating more than the file's size and a tree's struct; kdrt_saved_tree_read_info accepts
// every file a load accepts, with the same counts; a loaded tree describes every node and
// reference within range, answers rays (nearest and any agree, batches answer as single rays,
// hits name the mesh's triangles, spawned rays and located cells work) without allocating, and
// saves again to the very bytes it was loaded from (but for the three compile-time settings the
// header records and its checksum): a load accepts exactly what a save can write.
//
// The seeds are written by this file built with FUZZ_LOAD_WRITE_SEEDS, which adds a main:
//   clang++ -std=c++17 -O1 -DFUZZ_LOAD_WRITE_SEEDS -Iinclude -Itests/fuzz \
//     tests/fuzz/fuzz_load.cpp -o /tmp/write_seeds && /tmp/write_seeds tests/fuzz/corpus/load
#include "kdrt.h"
#ifndef FUZZ_LOAD_WRITE_SEEDS
#include "fuzz_support.hpp"
#include "../saved_format.hpp"
#else
#include <cstdio>
#include <cstdlib>
#define FUZZ_CHECK(cond, ...) \
    do {                      \
        if (!(cond)) std::abort(); \
    } while (0)
#endif

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct Mesh {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    kdrt_triangles view() const {
        kdrt_triangles v{};
        v.positions = positions.empty() ? nullptr : positions.data();
        v.vertex_count = uint32_t(positions.size() / 3);
        v.indices = indices.empty() ? nullptr : indices.data();
        v.triangle_count = uint32_t(indices.empty() ? positions.size() / 9 : indices.size() / 3);
        return v;
    }
};

// The four meshes, the same on every run.
struct Meshes {
    Mesh m[4];
};

const Mesh &mesh(int which) {
    static const Meshes meshes = [] {
        Meshes made;
        Mesh *m = made.m;
        const int rings = 5, segments = 8;
        for (int i = 0; i <= rings; ++i)
            for (int j = 0; j < segments; ++j) {
                const double th = 3.141592653589793 * i / rings, ph = 2 * 3.141592653589793 * j / segments;
                m[0].positions.insert(m[0].positions.end(),
                                      {float(std::sin(th) * std::cos(ph)), float(std::cos(th)), float(std::sin(th) * std::sin(ph))});
            }
        for (int i = 0; i < rings; ++i)
            for (int j = 0; j < segments; ++j) {
                const uint32_t a = uint32_t(i * segments + j), b = uint32_t(i * segments + (j + 1) % segments);
                const uint32_t c = a + segments, d = b + segments;
                if (i > 0) m[0].indices.insert(m[0].indices.end(), {a, c, b});
                if (i < rings - 1) m[0].indices.insert(m[0].indices.end(), {b, c, d});
            }
        for (int y = 0; y <= 4; ++y)
            for (int x = 0; x <= 4; ++x) m[1].positions.insert(m[1].positions.end(), {float(x), float(y), float((x * 7 + y * 3) % 5) * 0.25f});
        for (uint32_t y = 0; y < 4; ++y)
            for (uint32_t x = 0; x < 4; ++x) {
                const uint32_t a = y * 5 + x;
                m[1].indices.insert(m[1].indices.end(), {a, a + 1, a + 6, a, a + 6, a + 5});
            }
        for (uint32_t v : m[0].indices)
            m[2].positions.insert(m[2].positions.end(), m[0].positions.begin() + 3 * v, m[0].positions.begin() + 3 * v + 3);
        return made;
    }();
    return meshes.m[which & 3];
}

int append(void *user, const void *bytes, size_t size) {
    auto *out = static_cast<std::vector<unsigned char> *>(user);
    out->insert(out->end(), static_cast<const unsigned char *>(bytes), static_cast<const unsigned char *>(bytes) + size);
    return 1;
}

}  // namespace

#ifndef FUZZ_LOAD_WRITE_SEEDS

namespace {

// The fuzz::Heap of the other targets, also counting bytes: the most live at once.
struct Heap {
    size_t calls = 0, live = 0, fail_at = 0, live_bytes = 0, peak_bytes = 0;
    static void *alloc(void *user, size_t size) {
        Heap *h = static_cast<Heap *>(user);
        if (++h->calls == h->fail_at) return nullptr;
        size_t *p = static_cast<size_t *>(std::malloc(size + 16));
        if (!p) return nullptr;
        *p = size, ++h->live, h->live_bytes += size;
        h->peak_bytes = std::max(h->peak_bytes, h->live_bytes);
        return reinterpret_cast<unsigned char *>(p) + 16;
    }
    static void free(void *user, void *ptr) {
        Heap *h = static_cast<Heap *>(user);
        FUZZ_CHECK(ptr != nullptr, "free(NULL) through the allocator");
        size_t *p = reinterpret_cast<size_t *>(static_cast<unsigned char *>(ptr) - 16);
        --h->live, h->live_bytes -= *p;
        std::free(p);
    }
};

bool same_hit(const kdrt_hit &a, const kdrt_hit &b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The format's words and hashes, and forged files (../saved_format.hpp).
using saved_format::get32;
using saved_format::reseal;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    const uint8_t choice = data[0];
    const Mesh &m = mesh(choice & 3);
    const kdrt_triangles view = m.view();
    const bool in_place = (choice & 4) != 0;
    // The file, 64-byte aligned (in place needs it; a copy is loaded from it too).
    const size_t n = size - 1;
    std::vector<unsigned char> storage(n + 64);
    unsigned char *bytes = storage.data() + (64 - reinterpret_cast<uintptr_t>(storage.data()) % 64) % 64;
    if (n) std::memcpy(bytes, data + 1, n);
    if (choice & 16) reseal(bytes, n);

    Heap heap;
    heap.fail_at = choice >> 5;
    kdrt_build_options o = kdrt_default_build_options();
    o.allocator.alloc = Heap::alloc, o.allocator.free = Heap::free, o.allocator.user = &heap;
    o.flags = (in_place ? uint32_t(KDRT_LOAD_IN_PLACE) : 0u) | ((choice & 8) ? uint32_t(KDRT_BUILD_SCALAR_KERNEL) : 0u);
    kdrt_tree *tree = reinterpret_cast<kdrt_tree *>(&heap);
    kdrt_build_report report;
    const kdrt_result r = kdrt_tree_load(bytes, n, &view, &o, &tree, &report);
    FUZZ_CHECK(heap.peak_bytes <= n + 4096, "a load of %zu bytes took %zu", n, heap.peak_bytes);
    FUZZ_CHECK(report.invalid_triangle == KDRT_INVALID_ID && report.invalid_geometry == KDRT_INVALID_ID, "a load's report");
    kdrt_saved_tree_info info;
    const kdrt_result header = kdrt_saved_tree_read_info(bytes, n, &info);
    if (r != KDRT_SUCCESS) {
        FUZZ_CHECK(tree == nullptr, "failed load (%s) with a tree", kdrt_result_string(r));
        FUZZ_CHECK(heap.live == 0, "failed load (%s) left %zu blocks", kdrt_result_string(r), heap.live);
        FUZZ_CHECK(r != KDRT_ERROR_OUT_OF_MEMORY || heap.calls >= heap.fail_at, "out of memory with no allocation failed");
        return 0;
    }
    FUZZ_CHECK(tree != nullptr, "a load's tree");
    FUZZ_CHECK(header == KDRT_SUCCESS, "read_info refuses what a load takes: %s", kdrt_result_string(header));
    kdrt_tree_stats s;
    kdrt_tree_get_stats(tree, &s);
    FUZZ_CHECK(s.nodes == info.stats.nodes && s.leaves == info.stats.leaves && s.blocks == info.stats.blocks &&
                   s.triangle_refs == info.stats.triangle_refs && s.max_depth == info.stats.max_depth &&
                   s.triangles == info.stats.triangles,
               "read_info's counts");
    FUZZ_CHECK(s.max_depth <= KDRT_MAX_DEPTH && s.triangles <= view.triangle_count, "stats");
    FUZZ_CHECK(s.kernel == KDRT_KERNEL_SCALAR || !(choice & 8), "the scalar kernel asked for");
    const size_t calls = heap.calls;

    // Every node and reference.
    for (uint32_t i = 0; i < s.nodes; ++i) {
        kdrt_node_info node;
        FUZZ_CHECK(kdrt_tree_node(tree, i, &node) == KDRT_SUCCESS, "node %u", i);
        FUZZ_CHECK(node.depth <= s.max_depth, "node %u's depth", i);
        if (!node.is_leaf) FUZZ_CHECK(node.below == i + 1 && node.above > i + 1 && node.above < s.nodes, "node %u's children", i);
        for (uint32_t rope : node.ropes) FUZZ_CHECK(rope == KDRT_INVALID_ID || rope < s.nodes, "node %u's ropes", i);
    }
    for (uint64_t k = 0; k < s.triangle_refs; ++k) {
        uint32_t t = KDRT_INVALID_ID;
        FUZZ_CHECK(kdrt_tree_reference(tree, uint32_t(k), &t) == KDRT_SUCCESS && t < view.triangle_count, "reference %u", unsigned(k));
    }

    // Rays through the mesh's box: from the corners and faces towards points inside, and from
    // inside outwards.
    kdrt_aabb box = kdrt_tree_bounds(tree);
    if (s.triangles == 0) box = kdrt_aabb{{-1, -1, -1}, {1, 1, 1}};
    std::vector<kdrt_ray> rays;
    for (int i = 0; i < 24; ++i) {
        kdrt_ray ray{};
        for (int a = 0; a < 3; ++a) {
            const float lo = box.min[a], hi = box.max[a], mid = 0.5f * (lo + hi);
            const float from = (i >> a) & 1 ? hi + 1 : lo - 1, to = mid + (hi - lo) * 0.1f * float((i * (a + 3)) % 7 - 3);
            ray.org[a] = i < 16 ? from : mid;
            ray.dir[a] = i < 16 ? to - from : float((i * (a + 2)) % 5 - 2) + 0.25f;
        }
        ray.tmax = INFINITY;
        rays.push_back(ray);
    }
    std::vector<kdrt_hit> hits(rays.size()), batch(rays.size());
    std::vector<uint8_t> occluded(rays.size());
    kdrt_intersect_batch(tree, rays.data(), uint32_t(rays.size()), nullptr, batch.data());
    kdrt_occluded_batch(tree, rays.data(), uint32_t(rays.size()), nullptr, occluded.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        const int hit = kdrt_intersect(tree, &rays[i], &hits[i]);
        FUZZ_CHECK(kdrt_occluded(tree, &rays[i]) == hit, "ray %zu: occluded and intersect disagree", i);
        FUZZ_CHECK(occluded[i] == hit, "ray %zu: the occluded batch", i);
        FUZZ_CHECK(batch[i].triangle == hits[i].triangle && (!hit || same_hit(batch[i], hits[i])), "ray %zu: the batch", i);
        if (!hit) continue;
        FUZZ_CHECK(hits[i].triangle < view.triangle_count && hits[i].cell < s.nodes, "ray %zu's hit", i);
        float point[3], normal[3];
        FUZZ_CHECK(kdrt_hit_surface(tree, &hits[i], point, normal) == 1, "ray %zu's surface", i);
        const float dir[3] = {-rays[i].dir[0], rays[i].dir[1], -rays[i].dir[2]};
        kdrt_ray next;
        FUZZ_CHECK(kdrt_spawn_ray(tree, &hits[i], dir, &next) == 1, "ray %zu spawned", i);
        kdrt_hit again;
        kdrt_intersect(tree, &next, &again);
        kdrt_ray located = rays[i];
        located.org[0] = point[0], located.org[1] = point[1], located.org[2] = point[2];
        located.cell = kdrt_locate(tree, located.org);
        kdrt_occluded(tree, &located);
    }
    FUZZ_CHECK(heap.calls == calls, "queries allocated");

    // Saved again: the same bytes, but for the compile-time settings and the checksum.
    std::vector<unsigned char> saved;
    FUZZ_CHECK(kdrt_tree_save(tree, append, &saved) == KDRT_SUCCESS, "save");
    FUZZ_CHECK(saved.size() == n && saved.size() == kdrt_tree_saved_size(tree), "saved again: %zu bytes, loaded %zu", saved.size(), n);
    for (size_t i = 0; i < n; ++i)
        FUZZ_CHECK(saved[i] == bytes[i] || (i >= 152 && i < 164) || (i >= 248 && i < 256), "saved again: byte %zu differs", i);
    kdrt_tree_free(tree);
    FUZZ_CHECK(heap.live == 0, "the tree's free left %zu blocks", heap.live);
    return 0;
}

#else  // FUZZ_LOAD_WRITE_SEEDS: the seeds

int main(int argc, char **argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: write_seeds FOLDER\n");
        return 2;
    }
    struct Seed {
        const char *name;
        int mesh;
        kdrt_builder builder;
        kdrt_build_quality quality;
        uint32_t leaf, depth;
        kdrt_intersector intersector;
        uint8_t choice;  // the input's first byte beyond the mesh: in place, scalar, a failing allocation
    };
    const Seed seeds[] = {
        {"sphere_sah_medium_leaf4", 0, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_MEDIUM, 4, 0, KDRT_INTERSECTOR_WATERTIGHT, 0},
        {"sphere_sah_high_leaf1_in_place", 0, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_HIGH, 1, 0, KDRT_INTERSECTOR_WATERTIGHT, 4},
        {"sphere_median_leaf2_depth3", 0, KDRT_BUILDER_MEDIAN, KDRT_BUILD_QUALITY_DEFAULT, 2, 3, KDRT_INTERSECTOR_FAST, 8},
        {"grid_sah_fast_leaf2", 1, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_FAST, 2, 0, KDRT_INTERSECTOR_FAST, 0},
        {"grid_median_leaf1_fail3", 1, KDRT_BUILDER_MEDIAN, KDRT_BUILD_QUALITY_DEFAULT, 1, 0, KDRT_INTERSECTOR_WATERTIGHT, 0x60},
        {"grid_sah_high_leaf4_resealed", 1, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_HIGH, 4, 0, KDRT_INTERSECTOR_WATERTIGHT, 0x10},
        {"soup_leaf0", 2, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_DEFAULT, 0, 0, KDRT_INTERSECTOR_WATERTIGHT, 0},
        {"soup_sah_medium_leaf8_in_place", 2, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_MEDIUM, 8, 0, KDRT_INTERSECTOR_WATERTIGHT, 4},
        {"empty", 3, KDRT_BUILDER_SAH, KDRT_BUILD_QUALITY_DEFAULT, 4, 0, KDRT_INTERSECTOR_WATERTIGHT, 0},
    };
    for (const Seed &seed : seeds) {
        const kdrt_triangles view = mesh(seed.mesh).view();
        kdrt_build_options o = kdrt_default_build_options();
        o.builder = seed.builder, o.quality = seed.quality, o.max_leaf_size = seed.leaf, o.max_depth = seed.depth;
        o.intersector = seed.intersector;
        kdrt_tree *tree = nullptr;
        if (kdrt_tree_build(&view, &o, &tree, nullptr) != KDRT_SUCCESS) return 1;
        std::vector<unsigned char> file(1, uint8_t(seed.mesh | seed.choice));
        if (kdrt_tree_save(tree, append, &file) != KDRT_SUCCESS) return 1;
        kdrt_tree_free(tree);
        const std::string path = std::string(argv[1]) + "/" + seed.name;
        FILE *out = std::fopen(path.c_str(), "wb");
        if (!out || std::fwrite(file.data(), 1, file.size(), out) != file.size() || std::fclose(out) != 0) return 1;
    }
    return 0;
}

#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#endif
