// libFuzzer target: kdrt's scenes against a world-space brute force, on scenes and rays made from
// the input. A scene: up to 3 meshes and up to 6 instances of up to 3 small trees (each up to 8
// triangles, corners on a grid of quarters, built with any builder, leaf size, test and kernel),
// under moderate transforms (rotations, scales of 0.25 to 3, mirrors, shears, translations), with
// distinct IDs in any order and any masks; built with any options; then rays (aimed at points of
// the triangles, their edges and corners, or along grid directions), each with a query's rules
// (a mask, culled faces, a filter taking some triangles), and some instances moved and committed.
// Checked, as SCENES in kdrt.h promises:
//  - hits on the scene's meshes are bit for bit what one tree over the same triangles returns
//    (kdrt_tree_build() on the meshes merged in ID order, with the same options): the nearest hit
//    when it is a mesh's, no mesh hit nearer than an instance's, the mesh hits among the k nearest;
//  - every answer (nearest, any, k nearest) agrees with every triangle carried into the world in
//    double and intersected there: within float rounding of the world-space answer, not bit for
//    bit, as tests/test_scene.cpp judges it (a hit the reference has within its tolerance; no sure
//    hit missed or passed over; hits in order; culling judged in the world, where a mirror swaps
//    the faces), with wider margins, and rays that lie (almost) in a triangle's plane judged only
//    by its box, where kdrt.h says such hits lie;
//  - the first of the k nearest is the nearest hit (or kdrt.h's one exception), any-hit agrees.
#include "kdrt.h"
#include "fuzz_support.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <vector>

namespace {

constexpr uint32_t kAll = 0xFFFFFFFFu;

// ---- vectors in double ----

using V3 = std::array<double, 3>;
V3 sub(const V3 &a, const V3 &b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
V3 add(const V3 &a, const V3 &b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
V3 mul(const V3 &a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(const V3 &a, const V3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 cross(const V3 &a, const V3 &b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double norm(const V3 &a) { return std::sqrt(dot(a, a)); }
V3 of(const float f[3]) { return {f[0], f[1], f[2]}; }

using Transform = std::array<float, 12>;  // kdrt_geometry.transform
V3 apply(const Transform &m, const V3 &p) {
    V3 x;
    for (int i = 0; i < 3; ++i) x[size_t(i)] = double(m[size_t(4 * i)]) * p[0] + double(m[size_t(4 * i + 1)]) * p[1] + double(m[size_t(4 * i + 2)]) * p[2] + m[size_t(4 * i + 3)];
    return x;
}
// |R| |R^-1| (Frobenius): how much carrying a ray into the instance's space magnifies a rounding.
double condition(const Transform &t) {
    double m[3][3], fwd = 0, cof = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m[i][j] = t[size_t(4 * i + j)];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            const double c = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
            fwd += m[i][j] * m[i][j], cof += c * c;
        }
    const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                       m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    return std::sqrt(fwd * cof) / std::fabs(det);
}

struct Soup {
    std::vector<float> p;  // 9 floats a triangle
    uint32_t triangles() const { return uint32_t(p.size() / 9); }
    kdrt_triangles view() const {
        kdrt_triangles v{};
        v.positions = p.empty() ? nullptr : p.data();
        v.vertex_count = uint32_t(p.size() / 3);
        v.triangle_count = triangles();
        return v;
    }
    V3 corner(uint32_t t, int k) const { return {p[9 * t + 3 * size_t(k)], p[9 * t + 3 * size_t(k) + 1], p[9 * t + 3 * size_t(k) + 2]}; }
};

// ---- the world-space brute force (after tests/test_scene.cpp's World) ----

struct RefHit {
    size_t tri = 0;
    double t = 0, b1 = 0, b2 = 0, inside = 0, margin = 0, tol = 0, cos = 0, facing = 0;
    bool grazing = false;  // the ray (almost) in the triangle's plane: a hit anywhere in its box
};

class World {
public:
    struct Tri {
        V3 p0{}, e1{}, e2{}, n{};
        V3 lo{}, hi{};  // where a grazing hit may lie: the triangle's box, for an instance its object box carried over
        double min_edge = 0, kappa = 1;
        V3 anchor{};
        bool degenerate = false;
        bool fast = false;  // tested by KDRT_INTERSECTOR_FAST
        uint32_t geometry = 0, instance = KDRT_INVALID_ID, triangle = 0, mask = kAll;
    };
    void add(uint32_t id, bool instance, const Soup &s, const Transform &xf, uint32_t mask, bool fast) {
        const double kappa = instance ? condition(xf) : 1.0;
        for (uint32_t i = 0; i < s.triangles(); ++i) {
            const V3 a = s.corner(i, 0), b = s.corner(i, 1), c = s.corner(i, 2);
            Tri t;
            t.degenerate = norm(cross(sub(b, a), sub(c, a))) == 0;
            const V3 wa = apply(xf, a), wb = apply(xf, b), wc = apply(xf, c);
            t.p0 = wa, t.e1 = sub(wb, wa), t.e2 = sub(wc, wa), t.n = cross(t.e1, t.e2);
            t.min_edge = std::min({norm(t.e1), norm(t.e2), norm(sub(wc, wb))});
            t.kappa = kappa, t.anchor = apply(xf, {0, 0, 0});
            V3 olo = a, ohi = a;
            for (const V3 &q : {b, c})
                for (size_t k = 0; k < 3; ++k) olo[k] = std::min(olo[k], q[k]), ohi[k] = std::max(ohi[k], q[k]);
            t.lo = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, t.hi = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
            for (int k = 0; k < 8; ++k) {
                const V3 w = apply(xf, {(k & 1 ? ohi : olo)[0], (k & 2 ? ohi : olo)[1], (k & 4 ? ohi : olo)[2]});
                for (size_t x = 0; x < 3; ++x) t.lo[x] = std::min(t.lo[x], w[x]), t.hi[x] = std::max(t.hi[x], w[x]);
            }
            t.geometry = id, t.instance = instance ? id : KDRT_INVALID_ID, t.triangle = i, t.mask = mask, t.fast = fast;
            extent_ = std::max({extent_, norm(wa), norm(wb), norm(wc)});
            tris_.push_back(t);
        }
    }
    const Tri &tri(size_t i) const { return tris_[i]; }
    const Tri *find(uint32_t geometry, uint32_t triangle) const {
        for (const Tri &t : tris_)
            if (t.geometry == geometry && t.triangle == triangle) return &t;
        return nullptr;
    }
    double extent() const { return extent_; }

    // Every hit the ray may have, sorted by (t, geometry, triangle), as test_scene's World::hits,
    // the margins and tolerances kSafety times wider, and the rays (almost) in a triangle's plane
    // given the triangle's whole box.
    std::vector<RefHit> hits(const kdrt_ray &ray) const {
        const double kSafety = 16;
        const V3 o = of(ray.org), d = of(ray.dir);
        const double dlen = norm(d), lo = std::max(0.0, double(ray.tmin)), hi = ray.tmax;
        std::vector<RefHit> out;
        for (size_t i = 0; i < tris_.size(); ++i) {
            const Tri &tr = tris_[i];
            if (tr.degenerate) continue;
            const V3 pv = cross(d, tr.e2);
            const double det = dot(tr.e1, pv);
            RefHit h;
            h.tri = i;
            h.facing = dot(d, tr.n);
            h.cos = std::fabs(h.facing) / (dlen * norm(tr.n));
            if (det == 0 || h.cos < 1e-3) {
                // Where the ray is in the box, widened for the rounding.
                double t0 = -HUGE_VAL, t1 = HUGE_VAL;
                for (size_t a = 0; a < 3; ++a) {
                    const double slack = 1e-5 * (tr.hi[a] - tr.lo[a] + std::fabs(tr.lo[a]) + std::fabs(tr.hi[a]) + 1e-3);
                    const double bl = tr.lo[a] - slack, bh = tr.hi[a] + slack;
                    if (d[a] == 0) {
                        if (o[a] < bl || o[a] > bh) t0 = HUGE_VAL;
                        continue;
                    }
                    double ta = (bl - o[a]) / d[a], tb = (bh - o[a]) / d[a];
                    if (ta > tb) std::swap(ta, tb);
                    t0 = std::max(t0, ta), t1 = std::min(t1, tb);
                }
                // The fast test computes in float: for such a ray its barycentrics and t are
                // quotients of rounding errors, anywhere on the ray.
                if (tr.fast) t0 = lo, t1 = std::isfinite(hi) ? hi : std::max(lo, 1e30);
                if (!(t0 <= t1)) continue;
                const double pad = 1e-5 * (std::fabs(t0) + std::fabs(t1)) + 1e-6;
                if (t1 + pad < lo || t0 - pad > hi) continue;
                h.grazing = true, h.t = 0.5 * (t0 + t1), h.tol = 0.5 * (t1 - t0) + pad, h.inside = -HUGE_VAL;
                out.push_back(h);
                continue;
            }
            const V3 tv = sub(o, tr.p0);
            const double b1 = dot(tv, pv) / det;
            const V3 qv = cross(tv, tr.e1);
            const double b2 = dot(d, qv) / det, t = dot(tr.e2, qv) / det;
            const double inside = std::min({b1, b2, 1 - b1 - b2});
            if (!std::isfinite(t)) continue;
            const double cond = dlen * norm(tr.e1) * norm(tr.e2) / std::fabs(det);
            double reach = std::max({norm(tv), norm(sub(tv, tr.e1)), norm(sub(tv, tr.e2))});
            if (tr.instance != KDRT_INVALID_ID) reach = tr.kappa * (reach + norm(sub(o, tr.anchor)));
            h.b1 = b1, h.b2 = b2, h.t = t, h.inside = inside;
            h.margin = kSafety * std::max(1e-5, 0x1p-20 * cond * reach / tr.min_edge);
            h.tol = kSafety * std::max(1e-4 * std::fabs(t), 0x1p-18 * reach / dlen) * std::max(1.0, cond / 40);
            if (inside < -h.margin || t < lo - h.tol || t > hi + h.tol) continue;
            out.push_back(h);
        }
        std::sort(out.begin(), out.end(), [this](const RefHit &a, const RefHit &b) {
            const Tri &x = tris_[a.tri], &y = tris_[b.tri];
            if (a.t != b.t) return a.t < b.t;
            return x.geometry != y.geometry ? x.geometry < y.geometry : x.triangle < y.triangle;
        });
        return out;
    }
    // Clear of the edges and of the range's ends, and not grazing: single precision must find it.
    static bool sure(const RefHit &h, const kdrt_ray &ray) {
        const double lo = std::max(0.0, double(ray.tmin)), hi = ray.tmax;
        return !h.grazing && h.inside >= h.margin && h.cos >= 1e-3 && h.t >= lo + h.tol && h.t <= hi - h.tol;
    }

private:
    std::vector<Tri> tris_;
    double extent_ = 1;
};

// ---- a query's rules ----

struct Rules {
    uint32_t flags = 0, mask = kAll, salt = 0;
    bool filter = false;
    bool keep(uint32_t geometry, uint32_t triangle) const {
        const uint32_t x = (geometry * 0x9E3779B1u) ^ (triangle * 0x85EBCA77u) ^ salt;
        return !filter || ((x >> 9) & 1u) != 0;
    }
};

// 1 the reference hit counts under the rules, 0 it does not, -1 either (a face too near edge-on to
// tell its sides apart).
int counts(const Rules &r, const World::Tri &tri, const RefHit &h) {
    if (!(tri.mask & r.mask) || !r.keep(tri.geometry, tri.triangle)) return 0;
    const uint32_t cull = r.flags & 3u;
    if (cull == 3u) return 0;
    if (!cull) return 1;
    if (h.grazing || h.cos < 1e-3) return -1;
    const bool front = h.facing < 0;  // in the world: a mirror swaps the sides
    return cull == KDRT_QUERY_CULL_BACK_FACES ? int(front) : int(!front);
}

struct FilterData {
    const Rules *rules;
    const World *world;
    kdrt_ray ray;
};
int scene_filter(void *user, const kdrt_ray *ray, const kdrt_hit *c) {
    const FilterData &f = *static_cast<const FilterData *>(user);
    FUZZ_CHECK(ray && std::memcmp(ray, &f.ray, sizeof f.ray) == 0, "the filter was shown another ray");
    const World::Tri *tri = f.world->find(c->geometry, c->triangle);
    FUZZ_CHECK(tri && tri->instance == c->instance, "a candidate naming geometry %u triangle %u instance %u", c->geometry, c->triangle,
               c->instance);
    return f.rules->keep(c->geometry, c->triangle);
}

std::string show(const kdrt_hit &h) {
    if (h.triangle == KDRT_INVALID_ID) return "a miss";
    char s[200];
    std::snprintf(s, sizeof s, "geometry %u instance %d triangle %u t=%.9g (%a) u=%.9g v=%.9g", h.geometry,
                  h.instance == KDRT_INVALID_ID ? -1 : int(h.instance), h.triangle, h.t, h.t, h.u, h.v);
    return s;
}
std::string show(const World &w, const RefHit &r) {
    const World::Tri &t = w.tri(r.tri);
    char s[200];
    std::snprintf(s, sizeof s, "geometry %u triangle %u at t=%.9g +- %.3g (inside by %.3g, margin %.3g, cos %.3g%s)", t.geometry, t.triangle,
                  r.t, r.tol, r.inside, r.margin, r.cos, r.grazing ? ", grazing" : "");
    return s;
}
bool identical(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.triangle != b.triangle) return false;
    if (a.triangle == KDRT_INVALID_ID) return true;
    return a.geometry == b.geometry && a.instance == b.instance && std::memcmp(&a.t, &b.t, sizeof a.t) == 0 &&
           std::memcmp(&a.u, &b.u, sizeof a.u) == 0 && std::memcmp(&a.v, &b.v, sizeof a.v) == 0;
}
bool before(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.t != b.t) return a.t < b.t;
    if (a.geometry != b.geometry) return a.geometry < b.geometry;
    return a.triangle < b.triangle;
}

const RefHit *match(const World &w, const std::vector<RefHit> &refs, const std::vector<int> &rule, const kdrt_hit &h) {
    for (size_t i = 0; i < refs.size(); ++i) {
        const World::Tri &t = w.tri(refs[i].tri);
        if (rule[i] != 0 && t.geometry == h.geometry && t.instance == h.instance && t.triangle == h.triangle &&
            std::fabs(double(h.t) - refs[i].t) <= refs[i].tol)
            return &refs[i];
    }
    return nullptr;
}

// test_scene.cpp's judge_nearest, judge_occluded and judge_k: an empty string, or what is wrong.
std::string judge_nearest(const World &w, const kdrt_ray &ray, const std::vector<RefHit> &refs, const std::vector<int> &rule, int found,
                          const kdrt_hit &hit) {
    const RefHit *first_sure = nullptr;
    for (size_t i = 0; i < refs.size() && !first_sure; ++i)
        if (rule[i] == 1 && World::sure(refs[i], ray)) first_sure = &refs[i];
    if (!found) return first_sure ? "missed; the reference hits " + show(w, *first_sure) : "";
    const RefHit *m = match(w, refs, rule, hit);
    if (!m) return "got " + show(hit) + ", which the reference does not hit so";
    if (first_sure && first_sure->t + first_sure->tol < m->t - m->tol)
        return "got " + show(hit) + ", but the reference hits " + show(w, *first_sure) + " first";
    if (!m->grazing && m->cos >= 1e-3 &&
        (std::fabs(hit.u - m->b1) > 4 * m->margin + 1e-5 || std::fabs(hit.v - m->b2) > 4 * m->margin + 1e-5))
        return "got " + show(hit) + ", the reference's barycentrics are " + std::to_string(m->b1) + ", " + std::to_string(m->b2);
    return "";
}
std::string judge_occluded(const World &w, const kdrt_ray &ray, const std::vector<RefHit> &refs, const std::vector<int> &rule, int occluded) {
    const RefHit *sure = nullptr;
    bool possible = false;
    for (size_t i = 0; i < refs.size(); ++i) {
        possible |= rule[i] != 0;
        if (!sure && rule[i] == 1 && World::sure(refs[i], ray)) sure = &refs[i];
    }
    if (!occluded && sure) return "not occluded; the reference hits " + show(w, *sure);
    if (occluded && !possible) return "occluded; the reference hits nothing";
    return "";
}
std::string judge_k(const World &w, const kdrt_ray &ray, const std::vector<RefHit> &refs, const std::vector<int> &rule,
                    const std::vector<kdrt_hit> &got, uint32_t k) {
    std::vector<char> used(refs.size(), 0);
    size_t sure = 0, possible = 0;
    for (size_t i = 0; i < refs.size(); ++i) possible += rule[i] != 0, sure += rule[i] == 1 && World::sure(refs[i], ray);
    const RefHit *last = nullptr;
    const std::string K = "k " + std::to_string(k) + ": ";
    for (size_t i = 0; i < got.size(); ++i) {
        const RefHit *m = match(w, refs, rule, got[i]);
        if (!m) return K + "hit " + std::to_string(i) + ", " + show(got[i]) + ", is no reference hit";
        if (used[size_t(m - &refs[0])]++) return K + show(got[i]) + " twice";
        if (i > 0 && !before(got[i - 1], got[i])) return K + show(got[i - 1]) + " before " + show(got[i]);
        last = m;
    }
    if (got.size() < std::min<size_t>(k, sure) || got.size() > std::min<size_t>(k, possible))
        return K + std::to_string(got.size()) + " hits, the reference has " + std::to_string(sure) + " sure of " + std::to_string(possible);
    for (size_t i = 0; i < refs.size(); ++i) {
        const bool nearer = got.size() < k || (last && refs[i].t + refs[i].tol < last->t - last->tol);
        if (rule[i] == 1 && World::sure(refs[i], ray) && nearer && !used[i]) return K + "leaves out " + show(w, refs[i]);
    }
    return "";
}

// ---- drawing the scene ----

float grid(FuzzedDataProvider &in, int half, float step) { return float(in.ConsumeIntegralInRange<int>(-half, half)) * step; }

Soup make_soup(FuzzedDataProvider &in, uint32_t most) {
    Soup s;
    const uint32_t n = in.ConsumeIntegralInRange<uint32_t>(1, most);
    for (uint32_t i = 0; i < 9 * n; ++i) s.p.push_back(grid(in, 8, 0.25f));
    return s;
}

kdrt_build_options make_options(FuzzedDataProvider &in) {
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = kdrt_builder(in.ConsumeIntegralInRange<int>(0, 2));
    o.quality = kdrt_build_quality(in.ConsumeIntegralInRange<int>(0, 3));
    o.intersector = kdrt_intersector(in.ConsumeIntegralInRange<int>(0, 2));
    static const uint32_t leaves[] = {4, 1, 0, 2};
    o.max_leaf_size = leaves[in.ConsumeIntegralInRange<int>(0, 3)];
    if (in.ConsumeBool()) o.flags = KDRT_BUILD_SCALAR_KERNEL;
    return o;
}

// A rotation about a grid axis, scales of 0.25 to 3 (a negative one mirrors), a shear, a translation.
Transform make_transform(FuzzedDataProvider &in) {
    double axis[3], len = 0;
    for (double &x : axis) x = in.ConsumeIntegralInRange<int>(-2, 2), len += x * x;
    if (len == 0) axis[2] = 1, len = 1;
    for (double &x : axis) x /= std::sqrt(len);
    const double angle = in.ConsumeIntegralInRange<int>(0, 255) * (2 * M_PI / 256), c = std::cos(angle), s = std::sin(angle), k = 1 - c;
    const double &x = axis[0], &y = axis[1], &z = axis[2];
    const double r[3][3] = {{c + x * x * k, x * y * k - z * s, x * z * k + y * s},
                            {y * x * k + z * s, c + y * y * k, y * z * k - x * s},
                            {z * x * k - y * s, z * y * k + x * s, c + z * z * k}};
    static const double scales[] = {1, 2, 0.5, 3, 0.25, 1.5};
    double sc[3], sh[3] = {0, 0, 0};
    const bool uniform = in.ConsumeBool();
    for (int a = 0; a < 3; ++a) sc[a] = (a > 0 && uniform) ? sc[0] : scales[in.ConsumeIntegralInRange<int>(0, 5)] * (in.ConsumeIntegralInRange<int>(0, 5) == 0 ? -1 : 1);
    if (in.ConsumeIntegralInRange<int>(0, 3) == 0)
        for (double &v : sh) v = in.ConsumeIntegralInRange<int>(-2, 2) * 0.25;
    // M = R * Shear * Scale, Shear = [1 sh0 sh1; 0 1 sh2; 0 0 1]
    const double S[3][3] = {{sc[0], sh[0] * sc[1], sh[1] * sc[2]}, {0, sc[1], sh[2] * sc[2]}, {0, 0, sc[2]}};
    Transform t;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) t[size_t(4 * i + j)] = float(r[i][0] * S[0][j] + r[i][1] * S[1][j] + r[i][2] * S[2][j]);
        t[size_t(4 * i + 3)] = grid(in, 16, 0.5f);
    }
    return t;
}

uint32_t make_mask(FuzzedDataProvider &in) {
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0: return kAll;
    case 1: return 1u << in.ConsumeIntegralInRange<int>(0, 2);
    default: return in.ConsumeIntegralInRange<uint32_t>(0, 7);
    }
}

struct Instance {
    uint32_t id, object, mask;
    Transform xf;
};

std::string describe_transform(const Transform &m) {
    char s[400];
    std::snprintf(s, sizeof s, "[%a %a %a %a / %a %a %a %a / %a %a %a %a]", m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10],
                  m[11]);
    return s;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    FuzzedDataProvider in(data, size);
    fuzz::context().clear();
    // IDs: distinct, from 0 to 15 in the input's order.
    std::vector<uint32_t> free_ids;
    for (uint32_t i = 0; i < 16; ++i) free_ids.push_back(i);
    auto take_id = [&]() {
        const size_t k = in.ConsumeIntegralInRange<size_t>(0, free_ids.size() - 1);
        const uint32_t id = free_ids[k];
        free_ids.erase(free_ids.begin() + long(k));
        return id;
    };

    // The objects and their trees.
    const uint32_t object_count = in.ConsumeIntegralInRange<uint32_t>(1, 3);
    std::vector<Soup> objects;
    std::vector<kdrt_tree *> trees;
    std::vector<bool> fast;
    std::string text = "the scene:\n";
    for (uint32_t i = 0; i < object_count; ++i) {
        objects.push_back(make_soup(in, 8));
        const kdrt_build_options o = make_options(in);
        const kdrt_triangles v = objects.back().view();
        kdrt_tree *t = nullptr;
        FUZZ_CHECK(kdrt_tree_build(&v, &o, &t, nullptr) == KDRT_SUCCESS, "an object's tree");
        trees.push_back(t);
        fast.push_back(o.intersector == KDRT_INTERSECTOR_FAST);
        char s[120];
        std::snprintf(s, sizeof s, "  object %u: builder %d, intersector %d, leaf size %u, flags %u:", i, int(o.builder), int(o.intersector),
                      o.max_leaf_size, o.flags);
        text += s;
        for (float x : objects.back().p) text += " " + std::to_string(x);
        text += "\n";
    }
    // The meshes, the instances, the options.
    std::vector<kdrt_geometry> entries;
    std::vector<Soup> meshes;
    std::map<uint32_t, const Soup *> mesh_of;
    std::map<uint32_t, uint32_t> mesh_mask;
    const uint32_t mesh_count = in.ConsumeIntegralInRange<uint32_t>(0, 3);
    meshes.reserve(mesh_count);
    for (uint32_t i = 0; i < mesh_count; ++i) meshes.push_back(make_soup(in, 8));
    std::vector<kdrt_triangles> views(mesh_count);
    for (uint32_t i = 0; i < mesh_count; ++i) {
        views[i] = meshes[i].view();
        kdrt_geometry g = kdrt_mesh_geometry(take_id(), &views[i]);
        g.mask = make_mask(in);
        mesh_of[g.id] = &meshes[i], mesh_mask[g.id] = g.mask;
        entries.push_back(g);
        text += "  mesh " + std::to_string(g.id) + ", mask " + std::to_string(g.mask) + ":";
        for (float x : meshes[i].p) text += " " + std::to_string(x);
        text += "\n";
    }
    std::vector<Instance> instances(in.ConsumeIntegralInRange<uint32_t>(0, 6));
    for (Instance &x : instances) {
        x.id = take_id(), x.object = in.ConsumeIntegralInRange<uint32_t>(0, object_count - 1), x.mask = make_mask(in), x.xf = make_transform(in);
        kdrt_geometry g = kdrt_instance_geometry(x.id, trees[x.object], x.xf.data());
        g.mask = x.mask;
        entries.push_back(g);
    }
    std::reverse(entries.begin() + long(mesh_count) / 2, entries.end());  // the entries in no order
    const kdrt_build_options options = make_options(in);
    {
        char s[120];
        std::snprintf(s, sizeof s, "  options: builder %d, quality %d, intersector %d, leaf size %u, flags %u\n", int(options.builder),
                      int(options.quality), int(options.intersector), options.max_leaf_size, options.flags);
        text += s;
    }

    kdrt_scene *scene = nullptr;
    FUZZ_CHECK(kdrt_scene_build(entries.data(), uint32_t(entries.size()), &options, &scene, nullptr) == KDRT_SUCCESS, "the scene's build");

    // One tree over the meshes merged in ID order, with the scene's options.
    Soup merged;
    std::vector<std::pair<uint32_t, uint32_t>> first;  // (first merged triangle, ID)
    for (const auto &kv : mesh_of) {
        first.push_back({merged.triangles(), kv.first});
        merged.p.insert(merged.p.end(), kv.second->p.begin(), kv.second->p.end());
    }
    kdrt_tree *merged_tree = nullptr;
    if (!mesh_of.empty()) {
        const kdrt_triangles v = merged.view();
        FUZZ_CHECK(kdrt_tree_build(&v, &options, &merged_tree, nullptr) == KDRT_SUCCESS, "the merged tree's build");
    }
    auto part_of = [&](uint32_t triangle) {
        size_t p = 0;
        while (p + 1 < first.size() && first[p + 1].first <= triangle) ++p;
        return p;
    };
    struct MergedData {
        const Rules *rules;
        const std::vector<std::pair<uint32_t, uint32_t>> *first;
        const std::map<uint32_t, uint32_t> *mask;
    };
    auto merged_filter = [](void *user, const kdrt_ray *, const kdrt_hit *c) -> int {
        const MergedData &d = *static_cast<const MergedData *>(user);
        size_t p = 0;
        while (p + 1 < d.first->size() && (*d.first)[p + 1].first <= c->triangle) ++p;
        const uint32_t id = (*d.first)[p].second;
        return (d.mask->at(id) & d.rules->mask) && d.rules->keep(id, c->triangle - (*d.first)[p].first);
    };
    auto to_scene = [&](kdrt_hit h) {
        const size_t p = part_of(h.triangle);
        h.geometry = first[p].second, h.instance = KDRT_INVALID_ID, h.triangle -= first[p].first;
        return h;
    };

    const int rounds = in.ConsumeIntegralInRange<int>(1, 2);
    for (int round = 0; round < rounds; ++round) {
        if (round > 0) {  // move some instances
            for (Instance &x : instances)
                if (in.ConsumeBool()) {
                    x.xf = make_transform(in);
                    FUZZ_CHECK(kdrt_scene_set_transform(scene, x.id, x.xf.data()) == KDRT_SUCCESS, "a move");
                }
            FUZZ_CHECK(kdrt_scene_commit(scene) == KDRT_SUCCESS, "the commit");
        }
        World world;
        for (const auto &kv : mesh_of)
            world.add(kv.first, false, *kv.second, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}, mesh_mask[kv.first],
                      options.intersector == KDRT_INTERSECTOR_FAST);
        std::string scene_text = text;
        for (const Instance &x : instances) {
            world.add(x.id, true, objects[x.object], x.xf, x.mask, fast[x.object]);
            scene_text += "  instance " + std::to_string(x.id) + " of object " + std::to_string(x.object) + ", mask " + std::to_string(x.mask) +
                          ": " + describe_transform(x.xf) + "\n";
        }
        // Points to aim at: on the world triangles.
        std::vector<const World::Tri *> all;
        for (const auto &kv : mesh_of)
            for (uint32_t t = 0; t < kv.second->triangles(); ++t) all.push_back(world.find(kv.first, t));
        for (const Instance &x : instances)
            for (uint32_t t = 0; t < objects[x.object].triangles(); ++t) all.push_back(world.find(x.id, t));

        const int rays = in.ConsumeIntegralInRange<int>(1, 12);
        for (int r = 0; r < rays; ++r) {
            kdrt_ray ray;
            for (float &x : ray.org) x = grid(in, 24, 0.5f);
            if (!all.empty() && in.ConsumeIntegralInRange<int>(0, 3) != 0) {
                const World::Tri &t = *all[in.ConsumeIntegralInRange<size_t>(0, all.size() - 1)];
                static const double bary[] = {0, 1, 0.5, 0.25, 1.0 / 3, 0.75, 0.1, 0.05};
                const double b1 = bary[in.ConsumeIntegralInRange<int>(0, 7)], b2 = (1 - b1) * bary[in.ConsumeIntegralInRange<int>(0, 7)];
                const V3 p = add(t.p0, add(mul(t.e1, b1), mul(t.e2, b2)));
                const double s = in.ConsumeIntegralInRange<int>(1, 4) * 0.5;
                for (size_t a = 0; a < 3; ++a) ray.dir[a] = float((p[a] - ray.org[a]) * s);
            } else {
                for (float &x : ray.dir) x = grid(in, 4, 0.5f);
            }
            if (ray.dir[0] == 0 && ray.dir[1] == 0 && ray.dir[2] == 0) ray.dir[2] = -1;
            ray.tmin = in.ConsumeIntegralInRange<int>(0, 3) == 0 ? grid(in, 4, 0.125f) : 0.0f;
            ray.tmax = in.ConsumeBool() ? INFINITY : grid(in, 16, 0.25f);
            Rules rules;
            rules.flags = in.ConsumeIntegralInRange<uint32_t>(0, 3) == 3 ? 0 : in.ConsumeIntegralInRange<uint32_t>(0, 2);
            rules.mask = in.ConsumeBool() ? kAll : in.ConsumeIntegralInRange<uint32_t>(0, 7);
            rules.filter = in.ConsumeBool();
            rules.salt = in.ConsumeIntegral<uint8_t>();
            char line[400];
            std::snprintf(line, sizeof line, "ray org=(%a, %a, %a) dir=(%a, %a, %a) tmin=%a tmax=%a; rules: flags %u mask %#x filter %d salt %u\n",
                          ray.org[0], ray.org[1], ray.org[2], ray.dir[0], ray.dir[1], ray.dir[2], ray.tmin, ray.tmax, rules.flags, rules.mask,
                          int(rules.filter), rules.salt);
            fuzz::context() = scene_text + line;

            FilterData fd{&rules, &world, ray};
            kdrt_query q = kdrt_default_query();
            q.flags = rules.flags, q.mask = rules.mask;
            if (rules.filter) q.filter = &scene_filter, q.user = &fd;
            kdrt_hit hit;
            const int found = kdrt_scene_intersect(scene, &ray, &q, &hit);
            const int occluded = kdrt_scene_occluded(scene, &ray, &q);
            const uint32_t k = in.ConsumeIntegralInRange<uint32_t>(1, 6);
            std::vector<kdrt_hit> got(k);
            got.resize(kdrt_scene_intersect_k(scene, &ray, &q, got.data(), k));

            // The meshes, bit for bit.
            if (merged_tree) {
                MergedData md{&rules, &first, &mesh_mask};
                kdrt_query mq = kdrt_default_query();
                mq.flags = rules.flags;
                const bool plain = !rules.filter && rules.mask == kAll &&
                                   std::all_of(mesh_mask.begin(), mesh_mask.end(), [](const std::pair<const uint32_t, uint32_t> &m) { return m.second == kAll; });
                if (!plain) mq.filter = merged_filter, mq.user = &md;
                kdrt_hit m;
                const int mf = kdrt_intersect_query(merged_tree, &ray, &mq, &m);
                if (mf) m = to_scene(m);
                if (found && hit.instance == KDRT_INVALID_ID)
                    FUZZ_CHECK(mf && identical(hit, m), "the scene's mesh hit %s; one tree of the meshes: %s", show(hit).c_str(), mf ? show(m).c_str() : "a miss");
                else if (mf)
                    FUZZ_CHECK(found && before(hit, m), "the scene: %s; one tree of the meshes: %s, nearer", found ? show(hit).c_str() : "a miss",
                               show(m).c_str());
                std::vector<kdrt_hit> mk(k);
                mk.resize(kdrt_intersect_k(merged_tree, &ray, &mq, mk.data(), k));
                size_t j = 0;
                for (const kdrt_hit &h : got) {
                    if (h.instance != KDRT_INVALID_ID) continue;
                    FUZZ_CHECK(j < mk.size() && identical(h, to_scene(mk[j])), "k %u: the scene's mesh hit %s is not one tree's %zu-th, %s", k,
                               show(h).c_str(), j, j < mk.size() ? show(to_scene(mk[j])).c_str() : "none");
                    ++j;
                }
            }

            // Everything, against the world.
            const std::vector<RefHit> refs = world.hits(ray);
            std::vector<int> rule(refs.size());
            for (size_t i = 0; i < refs.size(); ++i) rule[i] = counts(rules, world.tri(refs[i].tri), refs[i]);
            std::string why = judge_nearest(world, ray, refs, rule, found, hit);
            FUZZ_CHECK(why.empty(), "nearest: %s", why.c_str());
            why = judge_occluded(world, ray, refs, rule, occluded);
            FUZZ_CHECK(why.empty(), "occluded: %s", why.c_str());
            why = judge_k(world, ray, refs, rule, got, k);
            FUZZ_CHECK(why.empty(), "%s", why.c_str());
            FUZZ_CHECK(occluded == found, "occluded %d, nearest %s", occluded, show(hit).c_str());
            FUZZ_CHECK(got.empty() == !found, "k %u: %zu hits, nearest %s", k, got.size(), show(hit).c_str());
            if (!got.empty() && !identical(got[0], hit)) {
                // kdrt.h's one exception: a hit at an edge, within the rounding, where the nearest
                // hit's bounded walk does not look.
                const double edge = std::min({double(got[0].u), double(got[0].v), 1.0 - got[0].u - got[0].v});
                FUZZ_CHECK(before(got[0], hit) && edge <= 1e-5, "the first of the k nearest, %s, is not the nearest, %s", show(got[0]).c_str(),
                           show(hit).c_str());
            }
        }
    }
    fuzz::context().clear();
    kdrt_scene_free(scene);
    kdrt_tree_free(merged_tree);
    for (kdrt_tree *t : trees) kdrt_tree_free(t);
    return 0;
}
