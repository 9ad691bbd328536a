// Batches (kdrt_intersect_batch, kdrt_occluded_batch and their scene forms): every ray of a batch
// gets exactly what the single-ray call gives it, every byte of its kdrt_hit on a hit (t, u, v,
// triangle, geometry, instance, cell) and what kdrt.h specifies of a miss, and its occluded 0 or
// 1, and a batch returns how many of its rays hit, whatever its size, order, alignment or
// coherence. The AVX2 packet walk takes
// consecutive eights of a batch whose directions share their signs, so the rays here are mostly
// such packets (pixel tiles and rows of a pinhole camera, shadow rays to one light), each batch
// also cut at random sizes so that packets start at every offset, and packets with one ray that
// must leave them or trip them: mixed signs, NaN, infinite, zero and subnormal parts, empty and
// per-lane ranges, split-plane origins, good and bad start cells. Both builders, intersectors and
// kernels, query rules, scenes, NULL arguments, no allocation, several threads at once.
#include "test_support.hpp"
#include "common/random.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <thread>
#include <vector>

namespace {

using common::Mesh;
using common::Rng;

const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();
const float kDenorm = std::numeric_limits<float>::denorm_min();
constexpr uint32_t kAllBits = 0xFFFFFFFFu;
constexpr size_t kPacket = 8;  // the AVX2 walk's packet

// ---- a tree or a scene, and its single-ray and batch calls ----

struct Target {
    const kdrt_tree *tree = nullptr;
    const kdrt_scene *scene = nullptr;
    bool is_scene = false;

    static Target of(const kdrt_tree *t) { return Target{t, nullptr, false}; }
    static Target of(const kdrt_scene *s) { return Target{nullptr, s, true}; }

    int intersect(const kdrt_ray *ray, const kdrt_query *q, kdrt_hit *hit) const {
        return is_scene ? kdrt_scene_intersect(scene, ray, q, hit) : kdrt_intersect_query(tree, ray, q, hit);
    }
    int occluded(const kdrt_ray *ray, const kdrt_query *q) const {
        return is_scene ? kdrt_scene_occluded(scene, ray, q) : kdrt_occluded_query(tree, ray, q);
    }
    uint32_t intersect_batch(const kdrt_ray *rays, uint32_t n, const kdrt_query *q, kdrt_hit *hits) const {
        return is_scene ? kdrt_scene_intersect_batch(scene, rays, n, q, hits) : kdrt_intersect_batch(tree, rays, n, q, hits);
    }
    uint32_t occluded_batch(const kdrt_ray *rays, uint32_t n, const kdrt_query *q, uint8_t *occluded) const {
        return is_scene ? kdrt_scene_occluded_batch(scene, rays, n, q, occluded) : kdrt_occluded_batch(tree, rays, n, q, occluded);
    }
    int surface(const kdrt_hit &hit, float point[3], float normal[3]) const {
        return is_scene ? kdrt_scene_hit_surface(scene, &hit, point, normal) : kdrt_hit_surface(tree, &hit, point, normal);
    }
    int spawn(const kdrt_hit &hit, const float dir[3], kdrt_ray *out) const {
        return is_scene ? kdrt_scene_spawn_ray(scene, &hit, dir, out) : kdrt_spawn_ray(tree, &hit, dir, out);
    }
    uint32_t locate(const float p[3]) const { return is_scene ? kdrt_scene_locate(scene, p) : kdrt_locate(tree, p); }
    kdrt_aabb bounds() const { return is_scene ? kdrt_scene_bounds(scene) : kdrt_tree_bounds(tree); }
};

std::string hex_ray(const kdrt_ray &r) {
    char s[320];
    std::snprintf(s, sizeof s, "org (%a, %a, %a) dir (%a, %a, %a) tmin %a tmax %a cell %u", r.org[0], r.org[1], r.org[2],
                  r.dir[0], r.dir[1], r.dir[2], r.tmin, r.tmax, r.cell);
    return s;
}

std::string hex_hit(const kdrt_hit &h) {
    char s[256];
    std::snprintf(s, sizeof s, "t %a u %a v %a triangle %u geometry %u instance %u cell %u", h.t, h.u, h.v, h.triangle,
                  h.geometry, h.instance, h.cell);
    return s;
}

// The start cell a ray's walk takes (START CELLS): a leaf of tree holding the origin strictly
// inside. Such rays' nearest-hit queries go one by one; other rays can walk in packets.
bool valid_cell(const kdrt_tree *tree, const kdrt_ray &r) {
    kdrt_node_info n;
    if (r.cell == 0 || kdrt_tree_node(tree, r.cell, &n) != KDRT_SUCCESS || !n.is_leaf) return false;
    for (int a = 0; a < 3; ++a)
        if (!(n.bounds.min[a] < r.org[a] && r.org[a] < n.bounds.max[a])) return false;
    return true;
}

// The batch's answer is the single call's: every byte of a hit; of a miss, what kdrt.h specifies
// (triangle KDRT_INVALID_ID, cell 0, and geometry and instance, which one-tree queries set to 0
// and KDRT_INVALID_ID), not t, u and v, which it leaves unspecified (the single call leaves the
// ray's tmax in t once the ray meets the tree's box, 0 before).
// Every field, misses included: a miss's t, u, v are unspecified, but the batch leaves the
// single-ray call's, so a caller sees no difference at all.
bool same_answer(const kdrt_hit &batch, const kdrt_hit &single) {
    return std::memcmp(&batch, &single, sizeof batch) == 0;
}

// A packet walks together when its directions are finite and nonzero and share their signs.
bool coherent_packet(const kdrt_ray *rays) {
    for (size_t k = 0; k < kPacket; ++k)
        for (int a = 0; a < 3; ++a) {
            const float d = rays[k].dir[a];
            if (!std::isfinite(d) || d == 0 || std::signbit(d) != std::signbit(rays[0].dir[a])) return false;
        }
    return true;
}

// Every batch call's answers against the single-ray calls', over ray sets; the first difference
// described.
struct Tally {
    size_t rays = 0, different = 0;
    size_t packet_rays = 0;            // in packets of eight that may walk together (any hit)
    size_t packet_nearest_rays = 0;    // of those, without a start cell (nearest hit)
    size_t hits = 0;
    std::string first;
    void differ(const std::string &what) {
        if (different++ == 0) first = what;
    }
};

// A plain query: the batch calls may walk packets for it.
bool plain(const kdrt_query *q) { return !q || (!q->flags && !q->filter && q->mask == kAllBits); }

// Checks the four batch calls (the tree's or the scene's two) on rays with query: all of rays as
// one batch, then cut into batches of random sizes (packets starting at every offset), each
// against the single-ray calls, with the batch's return value. A batch writes its own rays'
// answers and nothing next to them: the outputs are filled with other bytes first, and the
// neighbours checked after.
void check_batches(const Target &target, const std::vector<kdrt_ray> &rays, const kdrt_query *query, const std::string &kind,
                   Tally &tally, uint32_t seed) {
    const size_t n = rays.size();
    std::vector<kdrt_hit> want(n);
    std::vector<uint8_t> want_occluded(n);
    for (size_t i = 0; i < n; ++i) {
        std::memset(&want[i], 0xCD, sizeof want[i]);
        target.intersect(&rays[i], query, &want[i]);
        want_occluded[i] = uint8_t(target.occluded(&rays[i], query));
        tally.hits += want[i].triangle != KDRT_INVALID_ID;
    }
    tally.rays += n;
    if (target.tree && plain(query))
        for (size_t p = 0; p + kPacket <= n; p += kPacket) {
            if (!coherent_packet(&rays[p])) continue;
            tally.packet_rays += kPacket;
            for (size_t k = p; k < p + kPacket; ++k) tally.packet_nearest_rays += !valid_cell(target.tree, rays[k]);
        }

    std::vector<kdrt_hit> hits(n + 2);  // hits[1 + i]: ray i's; a guard each side
    std::vector<uint8_t> occluded(n + 2);
    std::memset(hits.data(), 0xAB, hits.size() * sizeof hits[0]);
    std::memset(occluded.data(), 0xAA, occluded.size());
    auto run = [&](size_t begin, size_t count, const char *how) {
        std::memset(&hits[1 + begin], 0x5A, count * sizeof hits[0]);
        std::memset(&occluded[1 + begin], 0x5A, count);
        const kdrt_hit before = hits[begin], after = hits[1 + begin + count];
        const uint8_t before_o = occluded[begin], after_o = occluded[1 + begin + count];
        const uint32_t got_hits = target.intersect_batch(rays.data() + begin, uint32_t(count), query, &hits[1 + begin]);
        const uint32_t got_occluded = target.occluded_batch(rays.data() + begin, uint32_t(count), query, &occluded[1 + begin]);
        const std::string where = kind + ", " + how + " batch of " + std::to_string(count) + " at " + std::to_string(begin);
        uint32_t hit_count = 0, occluded_count = 0;
        for (size_t i = begin; i < begin + count; ++i) {
            hit_count += want[i].triangle != KDRT_INVALID_ID;
            occluded_count += want_occluded[i];
            if (!same_answer(hits[1 + i], want[i]))
                tally.differ(where + ": ray " + std::to_string(i) + " " + hex_ray(rays[i]) + ": intersect batch " +
                             hex_hit(hits[1 + i]) + ", single " + hex_hit(want[i]));
            if (occluded[1 + i] != want_occluded[i])
                tally.differ(where + ": ray " + std::to_string(i) + " " + hex_ray(rays[i]) + ": occluded batch " +
                             std::to_string(occluded[1 + i]) + ", single " + std::to_string(want_occluded[i]));
        }
        if (got_hits != hit_count)
            tally.differ(where + ": intersect batch returned " + std::to_string(got_hits) + ", the rays hit " + std::to_string(hit_count));
        if (got_occluded != occluded_count)
            tally.differ(where + ": occluded batch returned " + std::to_string(got_occluded) + ", " + std::to_string(occluded_count) +
                         " rays are occluded");
        if (std::memcmp(&before, &hits[begin], sizeof before) != 0 || std::memcmp(&after, &hits[1 + begin + count], sizeof after) != 0 ||
            before_o != occluded[begin] || after_o != occluded[1 + begin + count])
            tally.differ(where + ": wrote outside its outputs");
    };
    run(0, n, "whole");
    Rng rng(seed);
    for (size_t begin = 0; begin < n;) {
        const size_t count = std::min(n - begin, size_t(1 + rng.below(rng.below(2) ? 8 : 40)));
        run(begin, count, "cut");
        begin += count;
    }
}

#define CHECK_TALLY(tally)                                                                           \
    do {                                                                                             \
        INFO((tally).rays << " rays, " << (tally).hits << " hits, " << (tally).packet_rays             \
                          << " in coherent packets; first difference: " << (tally).first);          \
        CHECK((tally).different == 0);                                                               \
    } while (0)

// ---- rays ----

// A pinhole camera at eye looking at a point, its view tan_half across each way.
struct Camera {
    float eye[3] = {0, 0, 0};
    double forward[3] = {0, 0, -1}, right[3] = {1, 0, 0}, up[3] = {0, 1, 0};
    double tan_half = 1;
    uint32_t cell = 0;
    kdrt_ray ray(unsigned x, unsigned y, unsigned w, unsigned h) const {
        const double sx = (2 * (x + 0.5) / w - 1) * tan_half, sy = (1 - 2 * (y + 0.5) / h) * tan_half;
        kdrt_ray r{};
        for (int a = 0; a < 3; ++a) {
            r.org[a] = eye[a];
            r.dir[a] = float(forward[a] + sx * right[a] + sy * up[a]);
        }
        r.tmax = kInf, r.cell = cell;
        return r;
    }
};

double box_radius(const kdrt_aabb &box, double centre[3]) {
    double r2 = 0;
    for (int a = 0; a < 3; ++a) {
        centre[a] = 0.5 * (double(box.min[a]) + box.max[a]);
        r2 += 0.25 * (double(box.max[a]) - box.min[a]) * (double(box.max[a]) - box.min[a]);
    }
    return std::max(std::sqrt(r2), 1e-3);
}

// From outside the box, along `from` from its centre, looking at its centre.
Camera outside_camera(const kdrt_aabb &box, const double from[3]) {
    double c[3], len = std::sqrt(from[0] * from[0] + from[1] * from[1] + from[2] * from[2]);
    const double radius = box_radius(box, c), distance = 2.5 * radius;
    Camera cam;
    for (int a = 0; a < 3; ++a) {
        cam.eye[a] = float(c[a] + from[a] / len * distance);
        cam.forward[a] = -from[a] / len;
    }
    // right = forward x (0, 1, 0) (or z when looking along y), up = right x forward
    const double ref[3] = {0, std::fabs(cam.forward[1]) > 0.9 ? 0.0 : 1.0, std::fabs(cam.forward[1]) > 0.9 ? 1.0 : 0.0};
    const double *f = cam.forward;
    double r[3] = {f[1] * ref[2] - f[2] * ref[1], f[2] * ref[0] - f[0] * ref[2], f[0] * ref[1] - f[1] * ref[0]};
    const double rl = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    for (double &x : r) x /= rl;
    const double u[3] = {r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
    std::copy(r, r + 3, cam.right), std::copy(u, u + 3, cam.up);
    cam.tan_half = 0.8 * radius / distance;  // the box's middle: most rays meet the mesh
    return cam;
}

// At the box's centre, wide, starting in the cell that holds the eye.
Camera inside_camera(const Target &target) {
    double c[3];
    box_radius(target.bounds(), c);
    Camera cam;
    for (int a = 0; a < 3; ++a) cam.eye[a] = float(c[a]);
    const double f[3] = {0.48, -0.6, -0.64};  // unit, no axis-parallel rays
    std::copy(f, f + 3, cam.forward);
    const double r[3] = {0.8, 0.6, 0}, u[3] = {r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
    std::copy(r, r + 3, cam.right), std::copy(u, u + 3, cam.up);
    cam.tan_half = 1.2;
    cam.cell = target.locate(cam.eye);
    return cam;
}

// The w x h pixels in tiles of tw x th (row-major in a tile, the tiles row-major); 1 x 1 is
// plain row-major order. w and h are multiples of the tile's.
std::vector<kdrt_ray> primary_rays(const Camera &cam, unsigned w, unsigned h, unsigned tw, unsigned th) {
    std::vector<kdrt_ray> rays;
    rays.reserve(size_t(w) * h);
    for (unsigned ty = 0; ty < h; ty += th)
        for (unsigned tx = 0; tx < w; tx += tw)
            for (unsigned y = ty; y < ty + th; ++y)
                for (unsigned x = tx; x < tx + tw; ++x) rays.push_back(cam.ray(x, y, w, h));
    return rays;
}

std::vector<kdrt_ray> shuffled(std::vector<kdrt_ray> rays, uint32_t seed) {
    Rng rng(seed);
    for (size_t i = rays.size(); i > 1; --i) std::swap(rays[i - 1], rays[rng.below(uint32_t(i))]);
    return rays;
}

// From every hit of primary, in order: a shadow ray to the light (kdrt_spawn_ray's, with its
// start cell) and a diffuse bounce (cosine about the normal on the ray's side).
struct Secondary {
    std::vector<kdrt_ray> shadow, bounce;
};
Secondary secondary_rays(const Target &target, const std::vector<kdrt_ray> &primary, const float light[3], uint32_t seed) {
    Rng rng(seed);
    Secondary out;
    for (const kdrt_ray &r : primary) {
        kdrt_hit hit;
        if (!target.intersect(&r, nullptr, &hit)) continue;
        float p[3], n[3];
        REQUIRE(target.surface(hit, p, n));
        kdrt_ray next;
        float d[3] = {light[0] - p[0], light[1] - p[1], light[2] - p[2]};
        if (target.spawn(hit, d, &next)) {
            for (int a = 0; a < 3; ++a) next.dir[a] = light[a] - next.org[a];
            next.tmax = 0.999f;
            out.shadow.push_back(next);
        }
        const float side = n[0] * r.dir[0] + n[1] * r.dir[1] + n[2] * r.dir[2] > 0 ? -1.0f : 1.0f;
        kt::random_direction(rng, d);
        for (int a = 0; a < 3; ++a) d[a] += side * n[a];
        if (d[0] != 0 || d[1] != 0 || d[2] != 0) {
            REQUIRE(target.spawn(hit, d, &next));
            out.bounce.push_back(next);
        }
    }
    return out;
}

std::vector<kdrt_ray> without_cells(std::vector<kdrt_ray> rays) {
    for (kdrt_ray &r : rays) r.cell = 0;
    return rays;
}

// A light above and in front of the box.
void light_for(const kdrt_aabb &box, float light[3]) {
    double c[3];
    const double radius = box_radius(box, c);
    const double off[3] = {0.7, 1.6, 1.3};
    for (int a = 0; a < 3; ++a) light[a] = float(c[a] + off[a] * radius);
}

// The coherent sets on one tree or scene, with `query`: a camera's primary rays in 2x4 and 4x4
// tiles, row-major and shuffled, an inside camera's from its cell, and the shadow rays (with
// their cells and with cell 0) and bounces from the tiled primary hits. side: the image's width
// and height, a multiple of 4.
void check_coherent(const Target &target, unsigned side, const kdrt_query *query, Tally &tally, uint32_t seed) {
    const kdrt_aabb box = target.bounds();
    const double from[3] = {0.35, 0.5, 1.0};
    const Camera cam = outside_camera(box, from);
    float light[3];
    light_for(box, light);
    const std::vector<kdrt_ray> tiles = primary_rays(cam, side, side, 2, 4);
    check_batches(target, tiles, query, "primary, 2x4 tiles", tally, seed);
    check_batches(target, primary_rays(cam, side, side, 4, 4), query, "primary, 4x4 tiles", tally, seed + 1);
    const std::vector<kdrt_ray> rows = primary_rays(cam, side, side, 1, 1);
    check_batches(target, rows, query, "primary, row-major", tally, seed + 2);
    check_batches(target, shuffled(rows, seed), query, "primary, shuffled", tally, seed + 3);
    check_batches(target, primary_rays(inside_camera(target), side / 2, side / 2, 2, 4), query, "inside camera, from its cell",
                  tally, seed + 4);
    const Secondary next = secondary_rays(target, tiles, light, seed);
    check_batches(target, next.shadow, query, "shadow, with cells", tally, seed + 5);
    check_batches(target, without_cells(next.shadow), query, "shadow, cell 0", tally, seed + 6);
    check_batches(target, next.bounce, query, "bounce", tally, seed + 7);
}

// The camera's side for `share` of the reference suites' ray count (KDRT_TEST_RAYS, default
// 100,000): about share / 6 of its square, as check_coherent traces about 6 rays a pixel. A
// multiple of 8, so that half of it takes whole 2x4 tiles.
unsigned side_for(double share) {
    const double pixels = share * double(kt::reference_ray_count()) / 6;
    return std::max(16u, unsigned(std::sqrt(pixels) / 8) * 8);
}

// ---- packets that must not walk as one ----

// Rays the packet walk must handle lane by lane, made from a coherent set `base` (2x4 tiles) and
// its single answers.
struct Special {
    std::string name;
    std::vector<kdrt_ray> rays;
};

float special_component(uint32_t kind) {
    switch (kind % 8) {
    case 0: return kNaN;
    case 1: return kInf;
    case 2: return -kInf;
    case 3: return 0.0f;
    case 4: return -0.0f;
    case 5: return kDenorm;
    case 6: return -3 * kDenorm;
    default: return std::numeric_limits<float>::min();
    }
}

std::vector<Special> special_sets(const kdrt_tree *tree, const kdrt_tree *other, const std::vector<kdrt_ray> &base, uint32_t seed) {
    Rng rng(seed);
    const size_t n = base.size();
    std::vector<kdrt_hit> hit(n);
    for (size_t i = 0; i < n; ++i) kdrt_intersect(tree, &base[i], &hit[i]);
    // t of the base ray's hit, or a length across the scene for a miss.
    const kdrt_aabb box = kdrt_tree_bounds(tree);
    double centre[3];
    const float across = float(2 * box_radius(box, centre));
    auto t_of = [&](size_t i) { return hit[i].triangle != KDRT_INVALID_ID ? hit[i].t : across; };
    std::vector<Special> sets;
    auto add = [&](const std::string &name, const std::function<void(size_t, kdrt_ray &)> &change) {
        Special s{name, base};
        for (size_t i = 0; i < n; ++i) change(i, s.rays[i]);
        sets.push_back(std::move(s));
    };

    add("every other ray reversed", [](size_t i, kdrt_ray &r) {
        if (i % 2)
            for (float &d : r.dir) d = -d;
    });
    add("every other ray with one axis flipped", [](size_t i, kdrt_ray &r) {
        if (i % 2) r.dir[(i / 2) % 3] = -r.dir[(i / 2) % 3];
    });
    // One odd ray in each packet, at each lane in turn, of each kind in turn.
    add("one odd ray a packet", [&](size_t i, kdrt_ray &r) {
        const size_t packet = i / kPacket;
        if (i % kPacket != packet % kPacket) return;
        const uint32_t kind = uint32_t(packet / kPacket) % 16;
        if (kind < 8) r.dir[packet % 3] = special_component(kind);
        else if (kind == 8) r.org[packet % 3] = kNaN;
        else if (kind == 9) r.dir[0] = r.dir[1] = r.dir[2] = 0;
        else if (kind == 10) r.dir[packet % 3] = -r.dir[packet % 3];
        else if (kind == 11) r.tmin = r.tmax = t_of(i);
        else if (kind == 12) r.tmin = 2 * t_of(i), r.tmax = t_of(i);
        else if (kind == 13) r.tmax = 0.5f * t_of(i);
        else if (kind == 14) {  // from inside, in its start cell
            for (int a = 0; a < 3; ++a) r.org[a] += 0.5f * t_of(i) * r.dir[a];
            r.cell = kdrt_locate(tree, r.org);
        }
        else r.cell = uint32_t(rng.next());
    });
    add("NaN, infinite and zero parts at random", [&](size_t, kdrt_ray &r) {
        if (rng.below(3)) return;
        float *part = rng.below(3) ? r.dir : r.org;
        part[rng.below(3)] = special_component(rng.below(8));
    });
    // Whole packets sharing a zero, subnormal or tiny component: every sign alike.
    for (int a = 0; a < 3; ++a) {
        const std::string axis = std::to_string(a);
        add("+0 in axis " + axis, [a](size_t, kdrt_ray &r) { r.dir[a] = 0.0f; });
        add("-0 in axis " + axis, [a](size_t, kdrt_ray &r) { r.dir[a] = -0.0f; });
        add("+0 and -0 in axis " + axis, [a](size_t i, kdrt_ray &r) { r.dir[a] = i % 3 ? 0.0f : -0.0f; });
        add("subnormal in axis " + axis, [a](size_t i, kdrt_ray &r) {
            r.dir[a] = std::copysign(float(1 + i % 5) * kDenorm, r.dir[a]);
        });
        add("subnormal and normal in axis " + axis, [a](size_t i, kdrt_ray &r) {
            if (i % 2) r.dir[a] = std::copysign(kDenorm, r.dir[a]);
        });
        add("smallest normal in axis " + axis, [a](size_t, kdrt_ray &r) {
            r.dir[a] = std::copysign(std::numeric_limits<float>::min(), r.dir[a]);
        });
        add("1e-30 in axis " + axis, [a](size_t, kdrt_ray &r) { r.dir[a] = std::copysign(1e-30f, r.dir[a]); });
    }
    add("zero directions", [](size_t, kdrt_ray &r) { r.dir[0] = r.dir[1] = r.dir[2] = 0; });
    add("NaN origins", [](size_t i, kdrt_ray &r) { r.org[i % 3] = kNaN; });
    add("NaN directions", [](size_t i, kdrt_ray &r) { r.dir[i % 3] = kNaN; });
    add("infinite origins", [](size_t i, kdrt_ray &r) { r.org[i % 3] = i % 2 ? kInf : -kInf; });
    add("far origins", [](size_t, kdrt_ray &r) {
        for (int a = 0; a < 3; ++a) r.org[a] -= 1e30f * r.dir[a];
    });
    add("tmin > tmax", [&](size_t i, kdrt_ray &r) { r.tmin = t_of(i), r.tmax = 0.5f * t_of(i); });
    add("tmin == tmax at the hit", [&](size_t i, kdrt_ray &r) { r.tmin = r.tmax = t_of(i); });
    add("tmin == tmax == 0", [](size_t, kdrt_ray &r) { r.tmin = r.tmax = 0; });
    add("NaN tmin or tmax", [](size_t i, kdrt_ray &r) { (i % 2 ? r.tmin : r.tmax) = kNaN; });
    add("negative tmin", [&](size_t i, kdrt_ray &r) { r.tmin = -float(1 + i % 3) * t_of(i); });
    // Each lane its own range, some ending just before the hit, at it or just after it.
    add("a tmax a lane", [&](size_t i, kdrt_ray &r) {
        const float t = t_of(i);
        const float limits[8] = {kInf, 2 * t, std::nextafter(t, kInf), t, std::nextafter(t, 0.0f), 0.5f * t, 0.0f, -1.0f};
        r.tmax = limits[i % kPacket];
    });
    add("a tmin a lane", [&](size_t i, kdrt_ray &r) {
        const float t = t_of(i);
        const float starts[8] = {0.0f, 0.5f * t, std::nextafter(t, 0.0f), t, std::nextafter(t, kInf), 2 * t, -kInf, kInf};
        r.tmin = starts[(i + 3) % kPacket];
    });
    add("a random range a lane", [&](size_t i, kdrt_ray &r) {
        const float t = t_of(i);
        r.tmin = rng.below(2) ? 0.0f : float(rng.range(0, 1.2)) * t;
        r.tmax = rng.below(4) == 0 ? kInf : float(rng.range(0.5, 1.5)) * t;
    });
    add("the same ray eight times", [&](size_t i, kdrt_ray &r) { r = base[i - i % kPacket]; });

    // Axis-parallel packets from a grid of origins before the box, each axis and sign, and
    // packets all but axis-parallel (the other parts tiny, of one sign).
    {
        Special axis{"axis-parallel", {}}, nearly{"all but axis-parallel", {}};
        for (int a = 0; a < 3; ++a)
            for (float sign : {1.0f, -1.0f})
                for (size_t i = 0; i < n / 6; ++i) {
                    kdrt_ray r{};
                    for (int b = 0; b < 3; ++b) r.org[b] = float(rng.range(box.min[b], box.max[b]));
                    r.org[a] = sign > 0 ? box.min[a] - 1 : box.max[a] + 1;
                    r.dir[a] = sign;
                    r.tmax = kInf;
                    r.dir[(a + 1) % 3] = (i / kPacket) % 2 ? -0.0f : 0.0f;
                    axis.rays.push_back(r);
                    r.dir[(a + 1) % 3] = 1e-7f, r.dir[(a + 2) % 3] = -1e-6f;
                    nearly.rays.push_back(r);
                }
        sets.push_back(std::move(axis));
        sets.push_back(std::move(nearly));
    }

    // Origins exactly on split planes (kdrt_tree_node's), in the node's box: packets crossing the
    // plane in one direction, and rays lying in it.
    {
        std::vector<kdrt_node_info> inner;
        for (uint32_t i = 0; i < kdrt_tree_node_count(tree); ++i) {
            const kdrt_node_info info = kt::node_info(tree, i);
            if (!info.is_leaf) inner.push_back(info);
        }
        Special crossing{"origins on split planes", {}}, lying{"rays in split planes", {}};
        for (size_t p = 0; p < n / kPacket && !inner.empty(); ++p) {
            const kdrt_node_info &node = inner[rng.below(uint32_t(inner.size()))];
            float dir[3];
            kt::random_direction(rng, dir);
            for (size_t k = 0; k < kPacket; ++k) {
                kdrt_ray r{};
                for (int b = 0; b < 3; ++b) r.org[b] = float(rng.range(node.bounds.min[b], node.bounds.max[b]));
                r.org[node.axis] = node.split;
                std::copy(dir, dir + 3, r.dir);
                r.tmax = kInf;
                r.cell = p % 2 ? kdrt_locate(tree, r.org) : 0;
                crossing.rays.push_back(r);
                r.dir[node.axis] = k % 2 ? -0.0f : 0.0f;
                lying.rays.push_back(r);
            }
        }
        sets.push_back(std::move(crossing));
        sets.push_back(std::move(lying));
    }

    // Packets from random interior points in one direction: with kdrt_locate's cells, with cell 0
    // and with bad hints (any number, inner nodes, past the end, another tree's cells).
    {
        Special located{"interior points, located", {}}, root{"interior points, cell 0", {}}, bad{"interior points, bad hints", {}};
        const uint32_t nodes = kdrt_tree_node_count(tree);
        for (size_t p = 0; p < n / kPacket; ++p) {
            float dir[3];
            kt::random_direction(rng, dir);
            for (size_t k = 0; k < kPacket; ++k) {
                kdrt_ray r{};
                for (int b = 0; b < 3; ++b) r.org[b] = float(rng.range(box.min[b], box.max[b]));
                std::copy(dir, dir + 3, r.dir);
                r.tmax = rng.below(4) ? kInf : float(rng.range(0, across));
                r.cell = kdrt_locate(tree, r.org);
                located.rays.push_back(r);
                r.cell = 0;
                root.rays.push_back(r);
                switch (rng.below(5)) {
                case 0: r.cell = uint32_t(rng.next()); break;
                case 1: r.cell = rng.below(nodes + 2); break;
                case 2: r.cell = nodes; break;
                case 3: r.cell = KDRT_INVALID_ID; break;
                default: r.cell = kdrt_locate(other, r.org); break;
                }
                bad.rays.push_back(r);
            }
        }
        sets.push_back(std::move(located));
        sets.push_back(std::move(root));
        sets.push_back(std::move(bad));
    }
    return sets;
}

// Every special set through check_batches, and the coherent base in batches of 0, 1, 7, 8, 9, 15,
// 16, 17 and a large odd size, at offsets 0 to 9.
void check_special(const kdrt_tree *tree, const kdrt_tree *other, unsigned side, const kdrt_query *query, Tally &tally, uint32_t seed) {
    const double from[3] = {-0.45, 0.3, 0.8};
    const std::vector<kdrt_ray> base = primary_rays(outside_camera(kdrt_tree_bounds(tree), from), side, side, 2, 4);
    const Target target = Target::of(tree);
    for (const Special &s : special_sets(tree, other, base, seed)) check_batches(target, s.rays, query, s.name, tally, seed);
    for (size_t size : {0, 1, 7, 8, 9, 15, 16, 17, 1001})
        for (size_t offset = 0; offset < 10 && offset + size <= base.size(); ++offset) {
            const std::vector<kdrt_ray> part(base.begin() + std::ptrdiff_t(offset), base.begin() + std::ptrdiff_t(offset + size));
            check_batches(target, part, query, "batch of " + std::to_string(size) + " from ray " + std::to_string(offset), tally,
                          seed + uint32_t(size));
        }
}

kt::TreePtr build_tree(const Mesh &mesh, uint32_t leaf, const kt::Builder &builder, kdrt_intersector intersector, uint32_t flags) {
    kdrt_build_options o = kdrt_default_build_options();
    o.max_leaf_size = leaf, o.intersector = intersector, o.flags = flags;
    builder.apply(o);
    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    INFO("build " << mesh.name << ", " << builder.name << ", leaf size " << leaf << ", intersector " << int(intersector));
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

const char *kernel_name(uint32_t flags) {
    return flags & KDRT_BUILD_SCALAR_KERNEL ? "scalar kernel" : flags & KDRT_BUILD_AVX2_KERNEL ? "AVX2 kernel" : "default kernel";
}

// The build flags that give each kernel this machine runs: the default (the widest), the AVX2
// kernel where the default is AVX-512, and the scalar kernel.
std::vector<uint32_t> kernel_flags() {
    const Mesh one = kt::random_soup(1, 1);
    const kt::TreePtr tree = build_tree(one, 4, kt::kBuilders[0], KDRT_INTERSECTOR_WATERTIGHT, 0);
    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree.get(), &stats);
    if (stats.kernel == KDRT_KERNEL_AVX512) return {0u, uint32_t(KDRT_BUILD_AVX2_KERNEL), uint32_t(KDRT_BUILD_SCALAR_KERNEL)};
    return {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)};
}

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A filter taking even triangles only: the answers change, and the batch must go one by one.
int take_even(void *, const kdrt_ray *, const kdrt_hit *candidate) { return (candidate->triangle & 1u) == 0; }
int take_none(void *, const kdrt_ray *, const kdrt_hit *) { return 0; }

// The queries a batch is asked with: plain ones (NULL, the default, every mask bit) and the ones
// that must go one by one (culled faces, a mask of some bits or none, filters).
struct NamedQuery {
    std::string name;
    kdrt_query query;
    bool null = false;
    bool hits_nothing = false;
    const kdrt_query *get() const { return null ? nullptr : &query; }
};
std::vector<NamedQuery> queries() {
    std::vector<NamedQuery> q;
    const kdrt_query d = kdrt_default_query();
    q.push_back({"NULL", d, true});
    q.push_back({"default", d});
    kdrt_query x = d;
    x.flags = KDRT_QUERY_CULL_BACK_FACES;
    q.push_back({"back faces culled", x});
    x.flags = KDRT_QUERY_CULL_FRONT_FACES;
    q.push_back({"front faces culled", x});
    x.flags = KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES;
    q.push_back({"both faces culled", x, false, true});
    x = d, x.mask = 1;
    q.push_back({"mask 1", x});
    x.mask = 2;
    q.push_back({"mask 2", x});
    x.mask = 0;
    q.push_back({"mask 0", x, false, true});
    x = d, x.filter = &take_even;
    q.push_back({"filter: even triangles", x});
    x.filter = &take_none;
    q.push_back({"filter: none", x, false, true});
    x = d, x.flags = KDRT_QUERY_CULL_BACK_FACES, x.filter = &take_even, x.mask = 3;
    q.push_back({"back faces culled, even triangles, mask 3", x});
    return q;
}


}  // namespace

TEST_CASE("batch: coherent and incoherent rays on generated meshes, bit for bit as one by one", "[batch]") {
    // About 12 times KDRT_TEST_RAYS per kernel: 1.2 million rays each by default.
    const auto start = std::chrono::steady_clock::now();
    struct Config {
        Mesh mesh;
        kt::Builder builder;
        kdrt_intersector intersector;
    };
    const Config configs[] = {{kt::sphere(64, 96, 2.0), kt::kSahBuilders[1], KDRT_INTERSECTOR_WATERTIGHT},
                              {kt::grid(96, 96, 5), kt::kBuilders[0], KDRT_INTERSECTOR_WATERTIGHT},
                              {kt::random_soup(20000, 7), kt::kSahBuilders[0], KDRT_INTERSECTOR_FAST}};
    const unsigned side = side_for(4);
    const std::vector<uint32_t> kernels = kernel_flags();
    std::vector<size_t> total(kernels.size(), 0);
    for (size_t k = 0; k < kernels.size(); ++k)
        for (const Config &c : configs) {
            const uint32_t flags = kernels[k];
            INFO(c.mesh.name << ", " << c.builder.name << ", " << kernel_name(flags) << ", " << side << " x " << side << " pixels");
            const kt::TreePtr tree = build_tree(c.mesh, 4, c.builder, c.intersector, flags);
            Tally tally;
            check_coherent(Target::of(tree.get()), side, nullptr, tally, 11 + flags);
            CHECK_TALLY(tally);
            CHECK(tally.hits > tally.rays / 5);
            CHECK(tally.packet_rays > tally.rays / 2);  // the packet walk's rays, mostly
            CHECK(tally.packet_nearest_rays > tally.rays / 3);
            total[k] += tally.rays;
        }
    for (size_t k = 0; k < kernels.size(); ++k) WARN("batch: " << total[k] << " rays on the " << kernel_name(kernels[k]));
    WARN("batch: in " << seconds_since(start) << " s");
    // About 6 rays a pixel on each of the 3 meshes (rounding the side down to whole tiles takes
    // fewer than 12 times KDRT_TEST_RAYS when that is small, as under qemu).
    CHECK(total[0] >= 16 * size_t(side) * side);
}

TEST_CASE("batch: coherent and incoherent rays on the shared meshes", "[batch][meshes]") {
    const std::string dir = kt::shared_mesh_dir();
    if (dir.empty()) {
        kt::skip_test("no shared meshes (KDRT_MESH_DIR absent)");
        return;
    }
    const auto start = std::chrono::steady_clock::now();
    const unsigned side = side_for(2);
    size_t total = 0;
    const kt::Builder builders[] = {kt::kSahBuilders[1], kt::kBuilders[0], kt::kSahBuilders[2]};
    const char *names[] = {"/common/stanford-bunny.obj", "/common/ogre.obj", "/common/nefertiti.obj"};
    for (int i = 0; i < 3; ++i) {
        Mesh mesh;
        std::string error;
        if (!common::load_mesh(dir + names[i], mesh, error)) {
            WARN(names[i] << ": " << error << ": skipped");
            continue;
        }
        INFO(names[i] << ", " << builders[i].name << ", " << side << " x " << side << " pixels");
        const kt::TreePtr tree = build_tree(mesh, 4, builders[i], i == 2 ? KDRT_INTERSECTOR_FAST : KDRT_INTERSECTOR_WATERTIGHT, 0);
        Tally tally;
        check_coherent(Target::of(tree.get()), side, nullptr, tally, 21 + uint32_t(i));
        CHECK_TALLY(tally);
        CHECK(tally.hits > tally.rays / 5);
        CHECK(tally.packet_rays > tally.rays / 2);
        total += tally.rays;
    }
    WARN("batch: " << total << " rays on the shared meshes in " << seconds_since(start) << " s");
}

TEST_CASE("batch: packets with an odd ray, mixed signs, special parts, per-lane ranges, split planes and hints", "[batch]") {
    const Mesh meshes[] = {kt::sphere(24, 36, 2.0), kt::grid(24, 24, 3)};
    const unsigned side = side_for(0.25);
    for (uint32_t flags : kernel_flags())
        for (const Mesh &mesh : meshes) {
            INFO(mesh.name << ", " << kernel_name(flags));
            const kt::TreePtr tree = build_tree(mesh, 4, kt::kSahBuilders[1], KDRT_INTERSECTOR_WATERTIGHT, flags);
            const kt::TreePtr other = build_tree(mesh, 1, kt::kBuilders[0], KDRT_INTERSECTOR_WATERTIGHT, flags);
            Tally tally;
            check_special(tree.get(), other.get(), side, nullptr, tally, 31);
            CHECK_TALLY(tally);
            CHECK(tally.packet_rays > tally.rays / 4);
        }
}

TEST_CASE("batch: every builder, quality, intersector and leaf size, and empty trees", "[batch]") {
    const Mesh meshes[] = {kt::sphere(12, 16, 1.0), kt::random_soup(300, 3)};
    const unsigned side = side_for(0.05);
    for (const Mesh &mesh : meshes)
        for (const kt::Builder &builder : kt::kBuilders)
            for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST})
                for (uint32_t leaf : {0u, 1u, 4u, 16u}) {
                    INFO(mesh.name << ", " << builder.name << ", intersector " << int(intersector) << ", leaf size " << leaf);
                    const kt::TreePtr tree = build_tree(mesh, leaf, builder, intersector, 0);
                    const kt::TreePtr other = build_tree(mesh, 2, kt::kBuilders[0], intersector, 0);
                    Tally tally;
                    check_coherent(Target::of(tree.get()), side, nullptr, tally, 41 + leaf);
                    check_special(tree.get(), other.get(), side / 2, nullptr, tally, 43 + leaf);
                    CHECK_TALLY(tally);
                    CHECK(tally.hits > 0);
                }

    // Empty trees: every triangle degenerate (zero area), and no triangles at all.
    Mesh degenerate;
    degenerate.name = "degenerate";
    for (int i = 0; i < 40; ++i) {
        const float line[9] = {float(i), 0, 0, float(i) + 1, 1, 1, float(i) + 2, 2, 2};  // collinear
        degenerate.positions.insert(degenerate.positions.end(), line, line + 9);
    }
    Mesh none;
    none.name = "no triangles";
    for (const Mesh *mesh : {&degenerate, &none})
        for (const kt::Builder &builder : {kt::kBuilders[0], kt::kSahBuilders[1]}) {
            INFO(mesh->name << ", " << builder.name);
            const kt::TreePtr tree = build_tree(*mesh, 4, builder, KDRT_INTERSECTOR_WATERTIGHT, 0);
            kdrt_tree_stats stats;
            kdrt_tree_get_stats(tree.get(), &stats);
            REQUIRE(stats.triangles == 0);
            kdrt_aabb box = {{-1, -1, -1}, {3, 3, 3}};
            const double from[3] = {0.35, 0.5, 1.0};
            std::vector<kdrt_ray> rays = primary_rays(outside_camera(box, from), 16, 16, 2, 4);
            const std::vector<kdrt_ray> random = kt::random_rays(box, 200, 5);
            rays.insert(rays.end(), random.begin(), random.end());
            Tally tally;
            for (const NamedQuery &q : queries()) check_batches(Target::of(tree.get()), rays, q.get(), q.name, tally, 51);
            CHECK_TALLY(tally);
            CHECK(tally.hits == 0);
        }
}

TEST_CASE("batch: culled faces, masks and filters give the single-ray answers", "[batch]") {
    // The default kernel (kdrt_scalar_tests runs this on the scalar one): such queries go one by
    // one, and the batch must see that.
    const Mesh meshes[] = {kt::sphere(24, 36, 2.0), kt::random_soup(2000, 13)};
    const unsigned side = side_for(0.05);
    for (const Mesh &mesh : meshes) {
        const kt::TreePtr tree = build_tree(mesh, 4, kt::kSahBuilders[1], KDRT_INTERSECTOR_WATERTIGHT, 0);
        const kt::TreePtr other = build_tree(mesh, 1, kt::kBuilders[0], KDRT_INTERSECTOR_WATERTIGHT, 0);
        for (const NamedQuery &q : queries()) {
            INFO(mesh.name << ", query " << q.name);
            Tally tally;
            check_coherent(Target::of(tree.get()), side, q.get(), tally, 61);
            check_special(tree.get(), other.get(), side / 2, q.get(), tally, 63);
            CHECK_TALLY(tally);
            if (!q.hits_nothing) CHECK(tally.hits > 0);
        }
    }
}

TEST_CASE("batch: scenes of meshes, and of meshes and instances, as the single scene calls", "[batch][scene]") {
    const Mesh ball = kt::sphere(24, 36, 1.5), ground = kt::translated(kt::grid(24, 24, 5), -12, -12, -2);
    const Mesh soup = kt::translated(kt::random_soup(400, 3), -5, -5, -1);
    const unsigned side = side_for(0.1);
    const kt::TreePtr ball_tree = kt::build(ball, 4, kt::kSahBuilders[1]);
    const kt::TreePtr soup_tree = kt::build(soup, 4, kt::kBuilders[0]);
    const float placed[12] = {0.5f, 0, 0, 1.0f, 0, 0.5f, 0, 0.5f, 0, 0, 0.5f, 0.25f};
    const float mirrored[12] = {-1, 0, 0, -3, 0, 1, 0.2f, 2, 0, 0, 1, 0.5f};
    // Meshes only, every mask bit (the packet walk may take them); meshes of masks 1 and 2;
    // meshes and instances.
    std::vector<std::vector<kdrt_geometry>> scenes(3);
    scenes[0] = {kdrt_mesh_geometry(7, nullptr), kdrt_mesh_geometry(2, nullptr), kdrt_mesh_geometry(4, nullptr)};
    scenes[1] = scenes[0];
    scenes[2] = {kdrt_mesh_geometry(7, nullptr), kdrt_mesh_geometry(2, nullptr), kdrt_instance_geometry(3, ball_tree.get(), placed),
                 kdrt_instance_geometry(9, ball_tree.get(), mirrored), kdrt_instance_geometry(5, soup_tree.get(), nullptr)};
    for (auto &entries : scenes) entries[0].mesh = ball.view(), entries[1].mesh = ground.view();
    scenes[0][2].mesh = soup.view(), scenes[1][2].mesh = soup.view();
    scenes[1][0].mask = 1, scenes[1][1].mask = 2, scenes[1][2].mask = 3;
    scenes[2][3].mask = 2;
    const char *names[] = {"meshes", "meshes with masks", "meshes and instances"};
    for (size_t s = 0; s < scenes.size(); ++s) {
        kdrt_scene *scene = nullptr;
        REQUIRE(kdrt_scene_build(scenes[s].data(), uint32_t(scenes[s].size()), nullptr, &scene, nullptr) == KDRT_SUCCESS);
        for (const NamedQuery &q : queries()) {
            INFO(names[s] << ", query " << q.name);
            Tally tally;
            check_coherent(Target::of(scene), side, q.get(), tally, 71);
            CHECK_TALLY(tally);
            if (!q.hits_nothing) CHECK(tally.hits > 0);
        }
        kdrt_scene_free(scene);
    }
}

TEST_CASE("batch: NULL arguments give misses and 0, and count 0 writes nothing", "[batch][errors]") {
    const Mesh mesh = kt::sphere(12, 16, 1.0);
    const kt::TreePtr tree = kt::build(mesh, 4);
    kdrt_geometry entry = kdrt_mesh_geometry(1, nullptr);
    entry.mesh = mesh.view();
    kdrt_scene *scene = nullptr;
    REQUIRE(kdrt_scene_build(&entry, 1, nullptr, &scene, nullptr) == KDRT_SUCCESS);
    const double from[3] = {0.35, 0.5, 1.0};
    const std::vector<kdrt_ray> rays = primary_rays(outside_camera(kdrt_tree_bounds(tree.get()), from), 8, 4, 2, 4);
    const uint32_t n = uint32_t(rays.size());
    REQUIRE(std::any_of(rays.begin(), rays.end(), [&](const kdrt_ray &r) {  // a miss below is the NULL's
        kdrt_hit h;
        return kdrt_intersect(tree.get(), &r, &h) == 1;
    }));
    kdrt_hit miss;
    std::memset(&miss, 0xCD, sizeof miss);
    CHECK(kdrt_intersect_query(nullptr, &rays[0], nullptr, &miss) == 0);  // a single call's miss
    REQUIRE(miss.triangle == KDRT_INVALID_ID);

    for (const Target &target : {Target::of(static_cast<const kdrt_tree *>(nullptr)), Target::of(static_cast<const kdrt_scene *>(nullptr)),
                                 Target::of(tree.get()), Target::of(scene)}) {
        const bool null_target = !target.tree && !target.scene;
        INFO((target.is_scene ? "scene" : "tree") << (null_target ? " NULL" : ""));
        std::vector<kdrt_hit> hits(n);
        std::vector<uint8_t> occluded(n);
        for (const kdrt_ray *input : {null_target ? rays.data() : nullptr}) {  // NULL rays, or a NULL tree or scene
            std::memset(hits.data(), 0xAB, n * sizeof hits[0]);
            std::memset(occluded.data(), 0xAA, n);
            CHECK(target.intersect_batch(input, n, nullptr, hits.data()) == 0);
            CHECK(target.occluded_batch(input, n, nullptr, occluded.data()) == 0);
            for (uint32_t i = 0; i < n; ++i) {
                CHECK(hits[i].triangle == KDRT_INVALID_ID);
                CHECK(same_answer(hits[i], miss));
                CHECK(occluded[i] == 0);
            }
        }
        // NULL outputs: 0, nothing written, no crash.
        CHECK(target.intersect_batch(rays.data(), n, nullptr, nullptr) == 0);
        CHECK(target.occluded_batch(rays.data(), n, nullptr, nullptr) == 0);
        CHECK(target.intersect_batch(nullptr, n, nullptr, nullptr) == 0);
        CHECK(target.occluded_batch(nullptr, n, nullptr, nullptr) == 0);
        // Count 0: 0, and the outputs untouched.
        std::memset(hits.data(), 0xAB, n * sizeof hits[0]);
        std::memset(occluded.data(), 0xAA, n);
        const std::vector<kdrt_hit> before = hits;
        CHECK(target.intersect_batch(rays.data(), 0, nullptr, hits.data()) == 0);
        CHECK(target.occluded_batch(rays.data(), 0, nullptr, occluded.data()) == 0);
        CHECK(target.intersect_batch(nullptr, 0, nullptr, nullptr) == 0);
        CHECK(std::memcmp(hits.data(), before.data(), n * sizeof hits[0]) == 0);
        CHECK(std::count(occluded.begin(), occluded.end(), uint8_t(0xAA)) == std::ptrdiff_t(n));
    }
    kdrt_scene_free(scene);
}

TEST_CASE("batch: the batch calls allocate nothing", "[batch][alloc]") {
    const Mesh mesh = kt::sphere(24, 36, 2.0), ground = kt::translated(kt::grid(16, 16, 5), -8, -8, -3);
    kt::CallCounter counter;
    kdrt_build_options o = kdrt_default_build_options();
    o.allocator = counter.hooks();
    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr, *other = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    REQUIRE(kdrt_tree_build(&view, nullptr, &other, nullptr) == KDRT_SUCCESS);
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(1, nullptr), kdrt_mesh_geometry(2, nullptr),
                                          kdrt_instance_geometry(3, tree, nullptr)};
    entries[0].mesh = mesh.view(), entries[1].mesh = ground.view(), entries[1].mask = 2;
    kdrt_scene *scene = nullptr;
    REQUIRE(kdrt_scene_build(entries.data(), uint32_t(entries.size()), &o, &scene, nullptr) == KDRT_SUCCESS);
    const size_t calls = counter.calls, frees = counter.frees;

    const double from[3] = {0.35, 0.5, 1.0};
    std::vector<kdrt_ray> rays = primary_rays(outside_camera(kdrt_tree_bounds(tree), from), 32, 32, 2, 4);
    float light[3];
    light_for(kdrt_tree_bounds(tree), light);
    const Secondary next = secondary_rays(Target::of(tree), rays, light, 3);
    rays.insert(rays.end(), next.shadow.begin(), next.shadow.end());
    rays.insert(rays.end(), next.bounce.begin(), next.bounce.end());
    for (const Special &s : special_sets(tree, other, std::vector<kdrt_ray>(rays.begin(), rays.begin() + 256), 5))
        rays.insert(rays.end(), s.rays.begin(), s.rays.end());
    std::vector<kdrt_hit> hits(rays.size());
    std::vector<uint8_t> occluded(rays.size());
    uint32_t found = 0;
    const uint32_t n = uint32_t(rays.size());
    for (const NamedQuery &q : queries()) {
        found += kdrt_intersect_batch(tree, rays.data(), n, q.get(), hits.data());
        found += kdrt_occluded_batch(tree, rays.data(), n, q.get(), occluded.data());
        found += kdrt_scene_intersect_batch(scene, rays.data(), n, q.get(), hits.data());
        found += kdrt_scene_occluded_batch(scene, rays.data(), n, q.get(), occluded.data());
    }
    CHECK(found > n);
    CHECK(counter.calls == calls);
    CHECK(counter.frees == frees);
    kdrt_scene_free(scene);
    kdrt_tree_free(tree);
    kdrt_tree_free(other);
    CHECK(counter.frees == counter.calls);
}

TEST_CASE("batch: several threads batching on one tree and one scene at once get the single-ray answers", "[batch][threads]") {
    const Mesh mesh = kt::sphere(48, 64, 2.0), ground = kt::translated(kt::grid(16, 16, 5), -8, -8, -3);
    const kt::TreePtr tree = kt::build(mesh, 4);
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(1, nullptr), kdrt_mesh_geometry(2, nullptr)};
    entries[0].mesh = mesh.view(), entries[1].mesh = ground.view();
    kdrt_scene *scene = nullptr;
    REQUIRE(kdrt_scene_build(entries.data(), uint32_t(entries.size()), nullptr, &scene, nullptr) == KDRT_SUCCESS);
    const unsigned side = side_for(0.5);
    const double from[3] = {0.35, 0.5, 1.0};
    std::vector<kdrt_ray> rays = primary_rays(outside_camera(kdrt_tree_bounds(tree.get()), from), side, side, 2, 4);
    float light[3];
    light_for(kdrt_tree_bounds(tree.get()), light);
    const Secondary next = secondary_rays(Target::of(tree.get()), rays, light, 9);
    rays.insert(rays.end(), next.shadow.begin(), next.shadow.end());
    const size_t n = rays.size();

    const Target targets[] = {Target::of(tree.get()), Target::of(scene)};
    std::vector<kdrt_hit> want[2];
    std::vector<uint8_t> want_occluded[2];
    for (int t = 0; t < 2; ++t) {
        want[t].resize(n), want_occluded[t].resize(n);
        for (size_t i = 0; i < n; ++i) {
            std::memset(&want[t][i], 0xCD, sizeof(kdrt_hit));
            targets[t].intersect(&rays[i], nullptr, &want[t][i]);
            want_occluded[t][i] = uint8_t(targets[t].occluded(&rays[i], nullptr));
        }
    }
    // Each thread its own batch sizes, twice over the rays, on the tree and on the scene in turns.
    const unsigned threads = 3;
    std::vector<size_t> different(threads, 0);
    std::vector<std::thread> pool;
    for (unsigned k = 0; k < threads; ++k)
        pool.emplace_back([&, k] {
            std::vector<kdrt_hit> hits(n);
            std::vector<uint8_t> occluded(n);
            const size_t batch = k == 0 ? n : 8 * k + 5;
            for (int pass = 0; pass < 4; ++pass) {
                const int t = (pass + int(k)) % 2;
                std::memset(hits.data(), 0xAB, n * sizeof hits[0]);
                for (size_t begin = 0; begin < n; begin += batch) {
                    const uint32_t count = uint32_t(std::min(batch, n - begin));
                    targets[t].intersect_batch(&rays[begin], count, nullptr, &hits[begin]);
                    targets[t].occluded_batch(&rays[begin], count, nullptr, &occluded[begin]);
                }
                for (size_t i = 0; i < n; ++i)
                    different[k] += !same_answer(hits[i], want[t][i]) || occluded[i] != want_occluded[t][i];
            }
        });
    for (std::thread &t : pool) t.join();
    for (unsigned k = 0; k < threads; ++k) {
        INFO("thread " << k << ", " << n << " rays four times");
        CHECK(different[k] == 0);
    }
    kdrt_scene_free(scene);
}
