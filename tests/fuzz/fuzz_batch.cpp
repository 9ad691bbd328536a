// libFuzzer target: the batch calls (kdrt_intersect_batch, kdrt_occluded_batch and their scene
// forms) against the single-ray calls, on a small tree, a scene over it and a batch of rays made
// from the input. The mesh: up to 12 triangles with corners mostly on a grid of quarters (shared
// planes, edges and vertices), sometimes any floats, sometimes copies side by side; any builder,
// quality, intersector, leaf size and kernel. The scene: the same triangles as a mesh (any mask)
// and the tree as an instance (identity, moved, scaled, mirrored). The rays: packets of eight
// that share their directions' signs (from one origin or from nearby ones, the same ray eight
// times), with an odd ray or none, and rays of any floats; per lane NaN, infinite, zero and
// subnormal parts, any tmin and tmax (or just before, at and after the hit), and start cells
// (the located one, a rope, any node, any number, another tree's). The query: NULL or plain
// mostly, sometimes culled faces, a mask or a filter.
// Checked: every ray's kdrt_hit (every byte of a hit; of a miss, what kdrt.h specifies: not t, u,
// v) and its occluded 0 or 1 are what the single-ray calls give, for the batch whole and cut at any two points (packets starting at other offsets), and
// each batch returns how many of its rays hit; a batch writes nothing beside its outputs; the
// batch calls allocate nothing.
#include "kdrt.h"
#include "fuzz_support.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace {

using fuzz::Heap;

constexpr size_t kPacket = 8;

float pick_coordinate(FuzzedDataProvider &in) {
    return in.ConsumeIntegralInRange<int>(0, 7) == 0 ? fuzz::pick_float(in) : float(in.ConsumeIntegralInRange<int>(-8, 8)) * 0.25f;
}

struct Mesh {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    kdrt_triangles view() const {
        kdrt_triangles v{};
        v.positions = positions.empty() ? nullptr : positions.data();
        v.vertex_count = uint32_t(positions.size() / 3);
        v.indices = indices.empty() ? nullptr : indices.data();
        v.triangle_count = uint32_t(indices.size() / 3);
        return v;
    }
};

Mesh make_mesh(FuzzedDataProvider &in) {
    Mesh m;
    const uint32_t vertices = in.ConsumeIntegralInRange<uint32_t>(3, 12), triangles = in.ConsumeIntegralInRange<uint32_t>(1, 12);
    const uint32_t copies = in.ConsumeIntegralInRange<int>(0, 3) == 0 ? in.ConsumeIntegralInRange<uint32_t>(2, 6) : 1;
    std::vector<float> p(size_t(vertices) * 3);
    for (float &x : p) x = pick_coordinate(in);
    std::vector<uint32_t> t(size_t(triangles) * 3);
    for (uint32_t &i : t) i = in.ConsumeIntegralInRange<uint32_t>(0, vertices - 1);
    for (uint32_t c = 0; c < copies; ++c) {
        for (size_t i = 0; i < p.size(); ++i) m.positions.push_back(p[i] + (i % 3 == 0 ? 0.5f * float(c) : 0.0f));
        for (uint32_t i : t) m.indices.push_back(i + c * vertices);
    }
    return m;
}

kdrt_build_options make_options(FuzzedDataProvider &in) {
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = in.ConsumeBool() ? KDRT_BUILDER_SAH : KDRT_BUILDER_MEDIAN;
    o.quality = kdrt_build_quality(in.ConsumeIntegralInRange<int>(0, 3));
    o.intersector = in.ConsumeBool() ? KDRT_INTERSECTOR_WATERTIGHT : KDRT_INTERSECTOR_FAST;
    static const uint32_t leaves[] = {1, 2, 4, 8, 0};
    o.max_leaf_size = leaves[in.ConsumeIntegralInRange<int>(0, 4)];
    // The kernel: scalar, AVX2 (packets of 8 where the default is AVX-512), or the default.
    const int kernel = in.ConsumeIntegralInRange<int>(0, 3);
    o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES | (kernel == 0 ? uint32_t(KDRT_BUILD_SCALAR_KERNEL) : 0u) |
              (kernel == 1 ? uint32_t(KDRT_BUILD_AVX2_KERNEL) : 0u);
    return o;
}

int take_even(void *, const kdrt_ray *, const kdrt_hit *candidate) { return (candidate->triangle & 1u) == 0; }

kdrt_query make_query(FuzzedDataProvider &in, bool &null) {
    kdrt_query q = kdrt_default_query();
    null = false;
    switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0: case 1: case 2: null = true; break;
    case 3: break;
    case 4: q.flags = in.ConsumeIntegralInRange<uint32_t>(1, 3); break;
    case 5: q.mask = in.ConsumeBool() ? in.ConsumeIntegralInRange<uint32_t>(0, 3) : in.ConsumeIntegral<uint32_t>(); break;
    case 6: q.filter = &take_even; break;
    default:
        q.flags = in.ConsumeIntegralInRange<uint32_t>(0, 3), q.mask = in.ConsumeIntegral<uint32_t>();
        if (in.ConsumeBool()) q.filter = &take_even;
    }
    return q;
}

// A point of the mesh (a vertex, or on an edge between two) or of the grid.
void pick_point(FuzzedDataProvider &in, const Mesh &mesh, float p[3]) {
    const size_t vertices = mesh.positions.size() / 3;
    if (in.ConsumeBool()) {
        const size_t a = in.ConsumeIntegralInRange<size_t>(0, vertices - 1), b = in.ConsumeIntegralInRange<size_t>(0, vertices - 1);
        const float s = float(in.ConsumeIntegralInRange<int>(0, 4)) * 0.25f;
        for (int k = 0; k < 3; ++k) p[k] = mesh.positions[a * 3 + k] + s * (mesh.positions[b * 3 + k] - mesh.positions[a * 3 + k]);
    } else {
        for (int k = 0; k < 3; ++k) p[k] = pick_coordinate(in);
    }
}

kdrt_ray any_ray(FuzzedDataProvider &in, const Mesh &mesh) {
    kdrt_ray r{};
    float q[3];
    for (float &x : r.org) x = in.ConsumeBool() ? fuzz::pick_float(in) : float(in.ConsumeIntegralInRange<int>(-12, 12)) * 0.25f;
    pick_point(in, mesh, q);
    for (int k = 0; k < 3; ++k) r.dir[k] = in.ConsumeIntegralInRange<int>(0, 3) == 0 ? fuzz::pick_float(in) : q[k] - r.org[k];
    r.tmax = INFINITY;
    return r;
}

// Eight rays whose directions share their signs: from one origin or from nearby ones, each
// direction the first's with every part scaled by a positive factor, or the same ray eight times.
void coherent_packet(FuzzedDataProvider &in, const Mesh &mesh, std::vector<kdrt_ray> &rays) {
    kdrt_ray first = any_ray(in, mesh);
    for (float &d : first.dir)
        if (d == 0 || !std::isfinite(d)) d = in.ConsumeBool() ? 0.5f : -0.5f;
    static const float factors[] = {1, 0.5f, 2, 0.75f, 1.25f, 1e-3f, 1e3f, 0x1p-100f};
    const int kind = in.ConsumeIntegralInRange<int>(0, 2);
    for (size_t k = 0; k < kPacket; ++k) {
        kdrt_ray r = first;
        if (kind != 2) {
            for (float &d : r.dir) d *= factors[in.ConsumeIntegralInRange<int>(0, 7)];
            if (kind == 1)
                for (float &o : r.org) o += float(in.ConsumeIntegralInRange<int>(-4, 4)) * 0.125f;
        }
        rays.push_back(r);
    }
}

float special_part(FuzzedDataProvider &in) {
    static const float parts[] = {NAN, INFINITY, -INFINITY, 0.0f, -0.0f, std::numeric_limits<float>::denorm_min(),
                                  -std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::min()};
    return in.ConsumeBool() ? parts[in.ConsumeIntegralInRange<int>(0, 7)] : fuzz::pick_float(in);
}

uint32_t pick_cell(FuzzedDataProvider &in, const kdrt_tree *tree, const kdrt_tree *other, const kdrt_ray &r) {
    const uint32_t at = kdrt_locate(tree, r.org);
    kdrt_node_info info;
    switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0: case 1: return at;
    case 2: return in.ConsumeIntegral<uint32_t>();
    case 3: return kdrt_tree_node(tree, at, &info) == KDRT_SUCCESS && info.is_leaf ? info.ropes[in.ConsumeIntegralInRange<int>(0, 5)] : 0;
    case 4: return in.ConsumeIntegralInRange<uint32_t>(0, kdrt_tree_node_count(tree));
    case 5: return kdrt_locate(other, r.org);
    default: return 0;
    }
}

// Per-lane changes: a special part, a range (any floats, or about the single hit's t), a cell.
void change_lanes(FuzzedDataProvider &in, const kdrt_tree *tree, const kdrt_tree *other, std::vector<kdrt_ray> &rays, size_t from) {
    for (size_t i = from; i < rays.size(); ++i) {
        kdrt_ray &r = rays[i];
        switch (in.ConsumeIntegralInRange<int>(0, 7)) {
        case 0: r.dir[in.ConsumeIntegralInRange<int>(0, 2)] = special_part(in); break;
        case 1: r.org[in.ConsumeIntegralInRange<int>(0, 2)] = special_part(in); break;
        default: break;
        }
        switch (in.ConsumeIntegralInRange<int>(0, 5)) {
        case 0: r.tmin = fuzz::pick_float(in); break;
        case 1: r.tmax = fuzz::pick_float(in); break;
        case 2: {  // about the hit: a range ending or starting just before, at or just after it
            kdrt_hit h;
            if (!kdrt_intersect(tree, &r, &h)) break;
            const float t = h.t, near[] = {std::nextafter(t, 0.0f), t, std::nextafter(t, INFINITY), 0.5f * t, 2 * t};
            const float x = near[in.ConsumeIntegralInRange<int>(0, 4)];
            if (in.ConsumeBool()) r.tmax = x;
            else r.tmin = x;
            if (in.ConsumeBool()) r.tmin = r.tmax;
            break;
        }
        default: break;
        }
        r.cell = pick_cell(in, tree, other, r);
    }
}

std::string describe(const kdrt_ray &r) {
    char s[320];
    std::snprintf(s, sizeof s, "ray org=(%a, %a, %a) dir=(%a, %a, %a) tmin=%a tmax=%a cell %u", r.org[0], r.org[1], r.org[2],
                  r.dir[0], r.dir[1], r.dir[2], r.tmin, r.tmax, r.cell);
    return s;
}

std::string describe(const kdrt_hit &h) {
    char s[256];
    std::snprintf(s, sizeof s, "t=%a u=%a v=%a triangle %u geometry %u instance %u cell %u", h.t, h.u, h.v, h.triangle,
                  h.geometry, h.instance, h.cell);
    return s;
}

// The tree's or the scene's calls.
struct Target {
    const kdrt_tree *tree;
    const kdrt_scene *scene;
    const char *name;
    int intersect(const kdrt_ray *r, const kdrt_query *q, kdrt_hit *h) const {
        return scene ? kdrt_scene_intersect(scene, r, q, h) : kdrt_intersect_query(tree, r, q, h);
    }
    int occluded(const kdrt_ray *r, const kdrt_query *q) const {
        return scene ? kdrt_scene_occluded(scene, r, q) : kdrt_occluded_query(tree, r, q);
    }
    uint32_t intersect_batch(const kdrt_ray *r, uint32_t n, const kdrt_query *q, kdrt_hit *h) const {
        return scene ? kdrt_scene_intersect_batch(scene, r, n, q, h) : kdrt_intersect_batch(tree, r, n, q, h);
    }
    uint32_t occluded_batch(const kdrt_ray *r, uint32_t n, const kdrt_query *q, uint8_t *o) const {
        return scene ? kdrt_scene_occluded_batch(scene, r, n, q, o) : kdrt_occluded_batch(tree, r, n, q, o);
    }
};

// A hit's every byte; a miss's triangle, cell, geometry and instance (kdrt.h leaves a miss's t,
// u and v unspecified).
bool same_answer(const kdrt_hit &batch, const kdrt_hit &single) {
    if (single.triangle != KDRT_INVALID_ID) return std::memcmp(&batch, &single, sizeof batch) == 0;
    return batch.triangle == KDRT_INVALID_ID && batch.cell == single.cell && batch.geometry == single.geometry &&
           batch.instance == single.instance;
}

// The batch calls on rays[begin, end) against the single answers, outputs guarded each side.
void check_range(const Target &target, const std::vector<kdrt_ray> &rays, const kdrt_query *q, const std::vector<kdrt_hit> &want,
                 const std::vector<uint8_t> &want_occluded, size_t begin, size_t end) {
    const size_t n = end - begin;
    std::vector<kdrt_hit> hits(n + 2);
    std::vector<uint8_t> occluded(n + 2);
    std::memset(hits.data(), 0xAB, hits.size() * sizeof hits[0]);
    std::memset(occluded.data(), 0xAA, occluded.size());
    const uint32_t found = target.intersect_batch(rays.data() + begin, uint32_t(n), q, &hits[1]);
    const uint32_t blocked = target.occluded_batch(rays.data() + begin, uint32_t(n), q, &occluded[1]);
    uint32_t want_found = 0, want_blocked = 0;
    for (size_t i = begin; i < end; ++i) {
        want_found += want[i].triangle != KDRT_INVALID_ID, want_blocked += want_occluded[i];
        const kdrt_hit &got = hits[1 + i - begin];
        if (!same_answer(got, want[i])) {
            std::fprintf(stderr, "%s, batch [%zu, %zu) of %zu, ray %zu: %s\n  batch:  %s\n  single: %s\n", target.name, begin, end,
                         rays.size(), i, describe(rays[i]).c_str(), describe(got).c_str(), describe(want[i]).c_str());
            FUZZ_CHECK(false, "a batch's hit differs from the single-ray call's");
        }
        FUZZ_CHECK(occluded[1 + i - begin] == want_occluded[i], "%s, batch [%zu, %zu), ray %zu: %s: occluded %d, single %d",
                   target.name, begin, end, i, describe(rays[i]).c_str(), occluded[1 + i - begin], want_occluded[i]);
    }
    FUZZ_CHECK(found == want_found, "%s, batch [%zu, %zu): intersect returned %u, %u rays hit", target.name, begin, end, found, want_found);
    FUZZ_CHECK(blocked == want_blocked, "%s, batch [%zu, %zu): occluded returned %u, %u rays occluded", target.name, begin, end,
               blocked, want_blocked);
    kdrt_hit guard;
    std::memset(&guard, 0xAB, sizeof guard);
    FUZZ_CHECK(std::memcmp(&hits[0], &guard, sizeof guard) == 0 && std::memcmp(&hits[n + 1], &guard, sizeof guard) == 0 &&
                   occluded[0] == 0xAA && occluded[n + 1] == 0xAA,
               "%s, batch [%zu, %zu): wrote beside its outputs", target.name, begin, end);
}

void check_target(const Target &target, const std::vector<kdrt_ray> &rays, const kdrt_query *q, size_t cut1, size_t cut2) {
    const size_t n = rays.size();
    std::vector<kdrt_hit> want(n);
    std::vector<uint8_t> want_occluded(n);
    for (size_t i = 0; i < n; ++i) {
        std::memset(&want[i], 0xCD, sizeof want[i]);
        target.intersect(&rays[i], q, &want[i]);
        want_occluded[i] = uint8_t(target.occluded(&rays[i], q));
    }
    check_range(target, rays, q, want, want_occluded, 0, n);
    const size_t a = std::min(cut1, cut2) % (n + 1), b = std::max(cut1, cut2) % (n + 1);
    const size_t lo = std::min(a, b), hi = std::max(a, b);
    check_range(target, rays, q, want, want_occluded, 0, lo);
    check_range(target, rays, q, want, want_occluded, lo, hi);
    check_range(target, rays, q, want, want_occluded, hi, n);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    FuzzedDataProvider in(data, size);
    fuzz::context().clear();
    const Mesh mesh = make_mesh(in);
    const kdrt_triangles view = mesh.view();
    kdrt_build_options options = make_options(in);
    Heap heap;
    options.allocator = kdrt_allocator{&Heap::alloc, &Heap::free, &heap};
    kdrt_tree *tree = nullptr, *other = nullptr;
    if (kdrt_tree_build(&view, &options, &tree, nullptr) != KDRT_SUCCESS) return 0;  // only an impossible vertex, say
    kdrt_build_options other_options = options;
    other_options.builder = KDRT_BUILDER_MEDIAN, other_options.max_leaf_size = 1;
    FUZZ_CHECK(kdrt_tree_build(&view, &other_options, &other, nullptr) == KDRT_SUCCESS, "a second build failed");

    // The scene: the triangles as a mesh, and the tree as an instance.
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(in.ConsumeIntegralInRange<uint32_t>(0, 9), &view)};
    entries[0].mask = in.ConsumeBool() ? 0xFFFFFFFFu : in.ConsumeIntegralInRange<uint32_t>(0, 3);
    if (in.ConsumeBool()) {
        float xf[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: break;
        case 1: xf[3] = float(in.ConsumeIntegralInRange<int>(-8, 8)) * 0.25f, xf[7] = 0.5f; break;
        case 2: xf[0] = xf[5] = xf[10] = 2; break;
        default: xf[0] = -1, xf[11] = 0.25f; break;
        }
        entries.push_back(kdrt_instance_geometry(10 + in.ConsumeIntegralInRange<uint32_t>(0, 9), tree, xf));
        entries.back().mask = in.ConsumeBool() ? 0xFFFFFFFFu : in.ConsumeIntegralInRange<uint32_t>(0, 3);
    }
    kdrt_scene *scene = nullptr;
    if (kdrt_scene_build(entries.data(), uint32_t(entries.size()), &options, &scene, nullptr) != KDRT_SUCCESS) scene = nullptr;

    // The rays: packets, coherent or not, each maybe with an odd ray, then a tail of any rays.
    std::vector<kdrt_ray> rays;
    const int packets = in.ConsumeIntegralInRange<int>(0, 6);
    for (int p = 0; p < packets; ++p) {
        const size_t from = rays.size();
        if (in.ConsumeIntegralInRange<int>(0, 3) == 0) {
            for (size_t k = 0; k < kPacket; ++k) rays.push_back(any_ray(in, mesh));
        } else {
            coherent_packet(in, mesh, rays);
            if (in.ConsumeBool()) rays[from + in.ConsumeIntegralInRange<size_t>(0, kPacket - 1)] = any_ray(in, mesh);
        }
        if (in.ConsumeBool()) change_lanes(in, tree, other, rays, from);
    }
    const size_t tail_from = rays.size();
    for (int k = in.ConsumeIntegralInRange<int>(0, 9); k > 0; --k) rays.push_back(any_ray(in, mesh));
    if (in.ConsumeBool()) change_lanes(in, tree, other, rays, tail_from);

    bool null_query = false;
    const kdrt_query query = make_query(in, null_query);
    const kdrt_query *q = null_query ? nullptr : &query;
    const size_t cut1 = in.ConsumeIntegral<uint8_t>(), cut2 = in.ConsumeIntegral<uint8_t>();
    const size_t calls = heap.calls, live = heap.live;
    check_target(Target{tree, nullptr, "tree"}, rays, q, cut1, cut2);
    if (scene) check_target(Target{nullptr, scene, "scene"}, rays, q, cut1, cut2);
    FUZZ_CHECK(heap.calls == calls && heap.live == live, "a batch call allocated");

    kdrt_scene_free(scene);
    kdrt_tree_free(tree);
    kdrt_tree_free(other);
    FUZZ_CHECK(heap.live == 0, "%zu blocks left", heap.live);
    return 0;
}
