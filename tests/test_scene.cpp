// Scenes (SCENES in kdrt.h): many meshes and instances of built trees behind one query. Every
// answer is checked against a brute force. A scene of meshes against one tree of all their
// triangles merged in ID order that tests every triangle (leaf size 0), bit for bit once a merged
// index is mapped back to its geometry and local triangle, and against the double-precision
// oracle. Scenes with instances against every triangle carried into world space in double and
// intersected there: an instance's hit is exact only for the ray rounded into the tree's space
// (SCENES, "Exactness"), so those compare within that rounding. Masks, culled faces, filters and
// the k nearest hits, ties across geometries, moving instances, surface points and secondary
// rays, bad input, allocation failures, and both kernels.

#include "test_support.hpp"
#include "common/random.hpp"
#include "common/thread_scheduler.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <functional>
#include <iterator>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace {

using common::Mesh;

constexpr uint32_t kAllBits = 0xFFFFFFFFu;
const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();
const uint32_t kCapacities[] = {1, 3, 64};

// ---- vectors and affine maps, in double ----

using V3 = std::array<double, 3>;
V3 sub(const V3 &a, const V3 &b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
V3 add(const V3 &a, const V3 &b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
V3 mul(const V3 &a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(const V3 &a, const V3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 cross(const V3 &a, const V3 &b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double norm(const V3 &a) { return std::sqrt(dot(a, a)); }
V3 of(const float f[3]) { return {f[0], f[1], f[2]}; }

// World from object, x = R p + t, laid out as kdrt_geometry.transform is.
struct Affine {
    double m[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
    V3 apply(const V3 &p) const {
        V3 x;
        for (int i = 0; i < 3; ++i) x[i] = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
        return x;
    }
};

Affine operator*(const Affine &a, const Affine &b) {  // a after b
    Affine r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = j == 3 ? a.m[i][3] : 0.0;
            for (int k = 0; k < 3; ++k) s += a.m[i][k] * b.m[k][j];
            r.m[i][j] = s;
        }
    return r;
}
Affine translate(double x, double y, double z) {
    Affine a;
    a.m[0][3] = x, a.m[1][3] = y, a.m[2][3] = z;
    return a;
}
Affine scale(double x, double y, double z) {
    Affine a;
    a.m[0][0] = x, a.m[1][1] = y, a.m[2][2] = z;
    return a;
}
Affine rotate(double x, double y, double z, double angle) {  // about the axis (x, y, z)
    const double len = std::sqrt(x * x + y * y + z * z);
    x /= len, y /= len, z /= len;
    const double c = std::cos(angle), s = std::sin(angle), k = 1 - c;
    Affine a;
    const double r[3][3] = {{c + x * x * k, x * y * k - z * s, x * z * k + y * s},
                            {y * x * k + z * s, c + y * y * k, y * z * k - x * s},
                            {z * x * k - y * s, z * y * k + x * s, c + z * z * k}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) a.m[i][j] = r[i][j];
    return a;
}
Affine shear(double xy, double xz, double yz) {  // x += xy y + xz z, y += yz z
    Affine a;
    a.m[0][1] = xy, a.m[0][2] = xz, a.m[1][2] = yz;
    return a;
}

using Transform = std::array<float, 12>;
Transform to_float(const Affine &a) {
    Transform t;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) t[size_t(4 * i + j)] = float(a.m[i][j]);
    return t;
}
// The transform a scene holds, exactly (the reference uses the floats the scene was given).
Affine of_float(const float *f) {
    Affine a;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) a.m[i][j] = f[4 * i + j];
    return a;
}
double determinant(const Affine &a) {
    const auto &m = a.m;
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}
// |R| |R^-1| (Frobenius norms, the inverse from the cofactors): how much carrying a ray into the
// instance's space can magnify a relative rounding error.
double condition(const Affine &a) {
    const auto &m = a.m;
    double fwd = 0, cof = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            const double c = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
            fwd += m[i][j] * m[i][j], cof += c * c;
        }
    return std::sqrt(fwd * cof) / std::fabs(determinant(a));
}

// ---- printing, for the failure messages ----

std::string show(const kdrt_ray &r) {
    char buf[400];
    std::snprintf(buf, sizeof buf, "ray org=(%.9g, %.9g, %.9g) dir=(%.9g, %.9g, %.9g) tmin=%.9g tmax=%.9g [hex %a %a %a / %a %a %a]",
                  r.org[0], r.org[1], r.org[2], r.dir[0], r.dir[1], r.dir[2], r.tmin, r.tmax, r.org[0], r.org[1], r.org[2],
                  r.dir[0], r.dir[1], r.dir[2]);
    return buf;
}
std::string show(const kdrt_hit &h) {
    if (h.triangle == KDRT_INVALID_ID) return "a miss";
    char buf[200];
    std::snprintf(buf, sizeof buf, "geometry %u instance %d triangle %u t=%.9g (%a) u=%.9g v=%.9g", h.geometry,
                  h.instance == KDRT_INVALID_ID ? -1 : int(h.instance), h.triangle, h.t, h.t, h.u, h.v);
    return buf;
}

// The same answer bit for bit: found or not; on a hit the same t, u, v bits, geometry, instance
// and triangle.
bool identical(int fa, const kdrt_hit &a, int fb, const kdrt_hit &b) {
    if (fa != fb) return false;
    if (!fa) return true;
    return a.triangle == b.triangle && a.geometry == b.geometry && a.instance == b.instance &&
           std::memcmp(&a.t, &b.t, sizeof a.t) == 0 && std::memcmp(&a.u, &b.u, sizeof a.u) == 0 &&
           std::memcmp(&a.v, &b.v, sizeof a.v) == 0;
}
bool identical(const std::vector<kdrt_hit> &a, const std::vector<kdrt_hit> &b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i)
        if (!identical(1, a[i], 1, b[i])) return false;
    return true;
}
std::string show(const std::vector<kdrt_hit> &hits) {
    std::string s = std::to_string(hits.size()) + " hits";
    for (const kdrt_hit &h : hits) s += "; " + show(h);
    return s;
}

// ---- the world-space brute force ----

// A reference hit of a ray on a world triangle, in double precision.
struct RefHit {
    size_t tri = 0;        // World::tri()
    double t = 0, b1 = 0, b2 = 0;
    double inside = 0;     // the smallest barycentric: below 0 outside the triangle
    double margin = 0;     // how far inside (or outside) a hit must be for single precision to agree
    double tol = 0;        // tolerance on t
    double cos = 0;        // |cos| of the angle between the ray and the normal
    double facing = 0;     // dir . normal: below 0 on the front
};

// Every triangle of a scene in world space, in double: the meshes' as they are, the instances'
// corners carried by their (float) transforms, products of floats being exact in double.
class World {
public:
    struct Tri {
        V3 p0{}, e1{}, e2{}, n{};  // n = e1 x e2: the front, as kdrt.h defines it, in the world
        double min_edge = 0;
        double kappa = 1;          // condition() of the instance's transform; 1 for a mesh
        V3 anchor{};               // where an instance's object origin lies
        bool degenerate = false;   // zero area in its tree's own space: never hit
        uint32_t geometry = 0, instance = KDRT_INVALID_ID, triangle = 0, mask = kAllBits;
    };

    void add_mesh(uint32_t id, const Mesh &mesh, uint32_t mask) { add(id, false, mesh, Affine(), mask); }
    void add_instance(uint32_t id, const Mesh &object, const float *transform, uint32_t mask) {
        add(id, true, object, of_float(transform), mask);
    }

    const Tri &tri(size_t i) const { return tris_[i]; }
    size_t size() const { return tris_.size(); }
    // The triangle a hit names, or NULL.
    const Tri *find(uint32_t geometry, uint32_t triangle) const {
        const auto it = ranges_.find(geometry);
        if (it == ranges_.end() || triangle >= it->second.second) return nullptr;
        return &tris_[it->second.first + triangle];
    }
    uint32_t triangles_of(uint32_t geometry) const {
        const auto it = ranges_.find(geometry);
        return it == ranges_.end() ? 0 : uint32_t(it->second.second);
    }
    // The world box of every corner (rounded to float), and of every instance's object box
    // transformed: a scene's box lies between the two (SCENES: an instance's world box is its
    // tree's box transformed).
    kdrt_aabb box() const { return to_box(lo_, hi_); }
    kdrt_aabb loose_box() const { return to_box(loose_lo_, loose_hi_); }
    double extent() const { return std::max({hi_[0] - lo_[0], hi_[1] - lo_[1], hi_[2] - lo_[2], 1e-3}); }

    // Every hit the ray may have, in the ray's range widened by the tolerance, sorted by (t,
    // geometry, triangle): those within the margin of an edge included (either answer is right
    // for them), and, for each, whether it is sure.
    std::vector<RefHit> hits(const kdrt_ray &ray) const {
        const V3 o = of(ray.org), d = of(ray.dir);
        const double dlen = norm(d), lo = std::max(0.0, double(ray.tmin)), hi = ray.tmax;
        std::vector<RefHit> out;
        for (size_t i = 0; i < tris_.size(); ++i) {
            const Tri &tr = tris_[i];
            if (tr.degenerate) continue;
            // Moeller-Trumbore in double on the float ray as given.
            const V3 pv = cross(d, tr.e2);
            const double det = dot(tr.e1, pv);
            if (det == 0) continue;
            const V3 tv = sub(o, tr.p0);
            const double b1 = dot(tv, pv) / det;
            if (b1 < -0.25 || b1 > 1.25) continue;  // far outside: no rounding brings it in
            const V3 qv = cross(tv, tr.e1);
            const double b2 = dot(d, qv) / det, t = dot(tr.e2, qv) / det;
            const double inside = std::min({b1, b2, 1 - b1 - b2});
            if (inside < -0.25 || !std::isfinite(t)) continue;
            RefHit h;
            h.tri = i, h.t = t, h.b1 = b1, h.b2 = b2, h.inside = inside;
            h.facing = dot(d, tr.n);
            h.cos = std::fabs(h.facing) / (dlen * norm(tr.n));
            // As the oracle's edge_margin: a few roundings of the corners relative to the origin,
            // times the condition of the test; for an instance, of the ray carried into its space
            // too, which its transform's condition magnifies.
            const double cond = dlen * norm(tr.e1) * norm(tr.e2) / std::fabs(det);
            double reach = std::max({norm(tv), norm(sub(tv, tr.e1)), norm(sub(tv, tr.e2))});
            if (tr.instance != KDRT_INVALID_ID) reach = tr.kappa * (reach + norm(sub(o, tr.anchor)));
            h.margin = std::max(1e-5, 0x1p-20 * cond * reach / tr.min_edge);
            h.tol = std::max(1e-4 * std::fabs(t), 0x1p-18 * reach / dlen) * std::max(1.0, cond / 40);
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

    // Clear of the edges, of the range's ends, and not grazing: single precision must find it.
    static bool sure(const RefHit &h, const kdrt_ray &ray) {
        const double lo = std::max(0.0, double(ray.tmin)), hi = ray.tmax;
        return h.inside >= h.margin && h.cos >= 1e-3 && h.t >= lo + h.tol && h.t <= hi - h.tol;
    }

private:
    static kdrt_aabb to_box(const V3 &lo, const V3 &hi) {
        kdrt_aabb b;
        for (int a = 0; a < 3; ++a) b.min[a] = float(lo[size_t(a)]), b.max[a] = float(hi[size_t(a)]);
        return b;
    }
    static void grow(V3 &lo, V3 &hi, const V3 &p) {
        for (size_t a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    }
    void add(uint32_t id, bool instance, const Mesh &mesh, const Affine &xf, uint32_t mask) {
        ranges_[id] = {tris_.size(), mesh.triangle_count()};
        const double kappa = instance ? condition(xf) : 1.0;
        V3 object_lo = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, object_hi = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
        for (uint32_t i = 0; i < mesh.triangle_count(); ++i) {
            double p[3][3];
            mesh.corners(i, p);
            const V3 a = {p[0][0], p[0][1], p[0][2]}, b = {p[1][0], p[1][1], p[1][2]}, c = {p[2][0], p[2][1], p[2][2]};
            for (const V3 &q : {a, b, c}) grow(object_lo, object_hi, q), grow(lo_, hi_, xf.apply(q));
            Tri t;
            t.degenerate = norm(cross(sub(b, a), sub(c, a))) == 0;
            const V3 wa = xf.apply(a), wb = xf.apply(b), wc = xf.apply(c);
            t.p0 = wa, t.e1 = sub(wb, wa), t.e2 = sub(wc, wa), t.n = cross(t.e1, t.e2);
            t.min_edge = std::min({norm(t.e1), norm(t.e2), norm(sub(wc, wb))});
            t.kappa = kappa;
            t.anchor = xf.apply({0, 0, 0});
            t.geometry = id, t.instance = instance ? id : KDRT_INVALID_ID, t.triangle = i, t.mask = mask;
            tris_.push_back(t);
        }
        for (int corner = 0; corner < 8; ++corner)
            grow(loose_lo_, loose_hi_,
                 xf.apply({(corner & 1 ? object_hi : object_lo)[0], (corner & 2 ? object_hi : object_lo)[1],
                           (corner & 4 ? object_hi : object_lo)[2]}));
    }
    V3 lo_ = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi_ = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    V3 loose_lo_ = lo_, loose_hi_ = hi_;
    std::vector<Tri> tris_;
    std::map<uint32_t, std::pair<size_t, size_t>> ranges_;  // ID: first triangle, count
};

// ---- a query's rules, for the scene and the brute forces alike ----

struct Rules {
    std::string name;
    uint32_t flags = 0;
    uint32_t mask = kAllBits;
    std::function<bool(uint32_t geometry, uint32_t triangle)> keep;  // the filter; empty: none
};

// Whether a reference hit counts under the rules: 1 it does, 0 it does not, -1 either answer is
// right (a face too near edge-on to tell its front from its back in single precision).
int counts(const Rules &rules, const World::Tri &tri, const RefHit &h) {
    if (!(tri.mask & rules.mask)) return 0;
    if (rules.keep && !rules.keep(tri.geometry, tri.triangle)) return 0;
    const uint32_t cull = rules.flags & (KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES);
    if (cull == (KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES)) return 0;
    if (!cull) return 1;
    if (h.cos < 1e-4) return -1;
    const bool front = h.facing < 0;  // judged in the world: a mirror swaps the sides
    return cull == KDRT_QUERY_CULL_BACK_FACES ? int(front) : int(!front);
}

// The scene's filter for a query's rules (mask and flags go in the query itself). It also checks
// what it is shown: its user pointer, the caller's ray, and a candidate naming a triangle of the
// scene (instance set for an instance's triangle, KDRT_INVALID_ID for a mesh's) whose barycentrics
// put it on the ray at t.
struct SceneFilter {
    const Rules *rules = nullptr;
    const World *world = nullptr;
    kdrt_ray ray{};
    size_t calls = 0, wrong_user = 0, wrong_ray = 0, bad_candidates = 0;
    std::string first_bad;

    static SceneFilter *expected;
    static int call(void *user, const kdrt_ray *ray, const kdrt_hit *c) {
        SceneFilter &f = *expected;
        f.wrong_user += user != expected;
        ++f.calls;
        if (!ray || std::memcmp(ray, &f.ray, sizeof f.ray) != 0) ++f.wrong_ray;
        const World::Tri *tri = f.world ? f.world->find(c->geometry, c->triangle) : nullptr;
        bool good = tri && tri->instance == c->instance;
        if (good) {
            const V3 o = of(f.ray.org), d = of(f.ray.dir);
            const double cos = std::fabs(dot(d, tri->n)) / (norm(d) * norm(tri->n));
            const V3 on_triangle = add(tri->p0, add(mul(tri->e1, c->u), mul(tri->e2, c->v)));
            const V3 on_ray = add(o, mul(d, c->t));
            if (cos >= 1e-3)
                good = norm(sub(on_triangle, on_ray)) <= 1e-3 * (f.world->extent() + norm(o) + norm(mul(d, c->t)));
        }
        if (!good && f.bad_candidates++ == 0) f.first_bad = "candidate " + show(*c) + " for " + show(f.ray);
        return f.rules->keep(c->geometry, c->triangle) ? 1 : 0;
    }
};
SceneFilter *SceneFilter::expected = nullptr;

// ---- owning a scene ----

struct ScenePtr {
    kdrt_scene *scene = nullptr;
    ScenePtr() = default;
    explicit ScenePtr(kdrt_scene *s) : scene(s) {}
    ScenePtr(ScenePtr &&o) noexcept : scene(o.scene) { o.scene = nullptr; }
    ScenePtr &operator=(ScenePtr &&o) noexcept {
        std::swap(scene, o.scene);
        return *this;
    }
    ScenePtr(const ScenePtr &) = delete;
    ScenePtr &operator=(const ScenePtr &) = delete;
    ~ScenePtr() { kdrt_scene_free(scene); }
    kdrt_scene *get() const { return scene; }
};

// REQUIREs success, and a report naming nothing.
ScenePtr build_scene(const std::vector<kdrt_geometry> &entries, const kdrt_build_options *options = nullptr) {
    kdrt_scene *scene = nullptr;
    kdrt_build_report report;
    const kdrt_result r = kdrt_scene_build(entries.data(), uint32_t(entries.size()), options, &scene, &report);
    INFO(kdrt_result_string(r) << ": geometry " << report.invalid_geometry << ", triangle " << report.invalid_triangle);
    REQUIRE(r == KDRT_SUCCESS);
    REQUIRE(scene != nullptr);
    CHECK(report.invalid_geometry == KDRT_INVALID_ID);
    CHECK(report.invalid_triangle == KDRT_INVALID_ID);
    return ScenePtr(scene);
}

// The scene's queries under the rules (the filter checking what it is shown).
struct SceneQueries {
    const kdrt_scene *scene;
    SceneFilter filter;
    kdrt_query query;
    SceneQueries(const kdrt_scene *s, const Rules &rules, const World *world) : scene(s) {
        filter.rules = &rules, filter.world = world;
        query = kdrt_default_query();
        query.flags = rules.flags, query.mask = rules.mask;
        if (rules.keep) query.filter = &SceneFilter::call, query.user = &filter;
    }
    void aim(const kdrt_ray &ray) {
        filter.ray = ray;
        SceneFilter::expected = &filter;
    }
    int intersect(const kdrt_ray &ray, kdrt_hit &hit) {
        aim(ray);
        return kdrt_scene_intersect(scene, &ray, &query, &hit);
    }
    int occluded(const kdrt_ray &ray) {
        aim(ray);
        return kdrt_scene_occluded(scene, &ray, &query);
    }
    std::vector<kdrt_hit> nearest_k(const kdrt_ray &ray, uint32_t k) {
        aim(ray);
        std::vector<kdrt_hit> hits(k + 1);
        hits[k].triangle = 12345;  // a guard: nothing is written past capacity
        const uint32_t n = kdrt_scene_intersect_k(scene, &ray, &query, hits.data(), k);
        CHECK(hits[k].triangle == 12345u);
        CHECK(n <= k);
        hits.resize(std::min(n, k));
        return hits;
    }
    // Hits of any query (nearest, any, up to 8 nearest) summed over rays: 0 when nothing is seen.
    size_t anything(const std::vector<kdrt_ray> &rays) {
        size_t n = 0;
        for (const kdrt_ray &ray : rays) {
            kdrt_hit h{};
            n += size_t(intersect(ray, h) + occluded(ray)) + nearest_k(ray, 8).size();
        }
        return n;
    }
    // The filter saw what it should have (when there is one).
    void check_filter(size_t rays) const {
        if (!query.filter) return;
        INFO(filter.first_bad);
        CHECK(filter.calls > rays / 4);  // the test means something: the filter was asked
        CHECK(filter.wrong_user == 0);
        CHECK(filter.wrong_ray == 0);
        CHECK(filter.bad_candidates == 0);
    }
};

// ---- the meshes merged into one tree ----

// A scene's meshes merged into one mesh in ID order, and a tree over it that tests every triangle
// (leaf size 0): what a scene of those meshes must answer bit for bit, a merged index mapped back
// to its geometry and local triangle. Masks and filters become a filter on the merged index.
class Merged {
public:
    struct Part {
        uint32_t id;
        const Mesh *mesh;
        uint32_t mask;
    };
    explicit Merged(std::vector<Part> parts) : parts_(std::move(parts)) {
        std::sort(parts_.begin(), parts_.end(), [](const Part &a, const Part &b) { return a.id < b.id; });
        mesh_.name = "merged";
        for (const Part &p : parts_) {
            first_.push_back(mesh_.triangle_count());
            const uint32_t base = mesh_.vertex_count();
            mesh_.positions.insert(mesh_.positions.end(), p.mesh->positions.begin(), p.mesh->positions.end());
            for (uint32_t t = 0; t < p.mesh->triangle_count(); ++t)
                for (int k = 0; k < 3; ++k) mesh_.indices.push_back(base + p.mesh->vertex(t, k));
        }
        tree_ = kt::build(mesh_, 0, kt::kBuilders[0]);
    }
    const Mesh &mesh() const { return mesh_; }
    const kdrt_tree *tree() const { return tree_.get(); }

    // The scene's name for a merged hit, and the merged name for a scene's hit.
    kdrt_hit to_scene(kdrt_hit h) const {
        const size_t p = part_of(h.triangle);
        h.geometry = parts_[p].id, h.instance = KDRT_INVALID_ID, h.triangle -= first_[p];
        return h;
    }
    kdrt_hit to_merged(kdrt_hit h) const {
        for (size_t p = 0; p < parts_.size(); ++p)
            if (parts_[p].id == h.geometry) {
                h.triangle += first_[p];
                return h;
            }
        h.triangle = KDRT_INVALID_ID;  // names no mesh
        return h;
    }

    int intersect(const kdrt_ray &ray, const Rules &rules, kdrt_hit &hit) const {
        Data data{this, &rules};
        const kdrt_query q = query(data);
        const int found = kdrt_intersect_query(tree_.get(), &ray, &q, &hit);
        if (found) hit = to_scene(hit);
        return found;
    }
    int occluded(const kdrt_ray &ray, const Rules &rules) const {
        Data data{this, &rules};
        const kdrt_query q = query(data);
        return kdrt_occluded_query(tree_.get(), &ray, &q);
    }
    std::vector<kdrt_hit> nearest_k(const kdrt_ray &ray, const Rules &rules, uint32_t k) const {
        Data data{this, &rules};
        const kdrt_query q = query(data);
        std::vector<kdrt_hit> hits(k);
        hits.resize(kdrt_intersect_k(tree_.get(), &ray, &q, hits.data(), k));
        for (kdrt_hit &h : hits) h = to_scene(h);
        return hits;
    }

private:
    struct Data {
        const Merged *merged;
        const Rules *rules;
    };
    size_t part_of(uint32_t triangle) const {
        return size_t(std::upper_bound(first_.begin(), first_.end(), triangle) - first_.begin()) - 1;
    }
    static int filter(void *user, const kdrt_ray *, const kdrt_hit *c) {
        const Data &d = *static_cast<const Data *>(user);
        const size_t p = d.merged->part_of(c->triangle);
        const Part &part = d.merged->parts_[p];
        if (!(part.mask & d.rules->mask)) return 0;
        return !d.rules->keep || d.rules->keep(part.id, c->triangle - d.merged->first_[p]);
    }
    static kdrt_query query(Data &data) {
        kdrt_query q = kdrt_default_query();
        q.flags = data.rules->flags;
        q.filter = &Merged::filter, q.user = &data;
        return q;
    }
    std::vector<Part> parts_;
    std::vector<uint32_t> first_;  // each part's first merged triangle
    Mesh mesh_;
    kt::TreePtr tree_;
};

// ---- a scene under construction ----

// The meshes and the objects the instances place (kept here, at fixed addresses, as long as the
// scene borrows them), the trees, the scene's entries, the world-space brute force and the merged
// meshes of the same entries.
struct Fixture {
    std::deque<Mesh> meshes, objects;
    std::deque<std::vector<float>> strided;  // meshes given with a 16-byte stride
    std::vector<kt::TreePtr> trees, scalar_trees;  // per object: the default kernel's and the scalar one's
    std::vector<kdrt_geometry> entries;
    std::vector<size_t> object_of;  // per entry: its object, or SIZE_MAX for a mesh
    std::vector<Merged::Part> parts;
    World world;

    void add_mesh(uint32_t id, Mesh mesh, uint32_t mask = kAllBits, bool stride16 = false) {
        meshes.push_back(std::move(mesh));
        const Mesh &m = meshes.back();
        kdrt_triangles view = m.view();
        if (stride16) {
            // x, y, z and a NaN the scene must never read.
            std::vector<float> buffer;
            for (uint32_t v = 0; v < m.vertex_count(); ++v)
                buffer.insert(buffer.end(), {m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2], kNaN});
            strided.push_back(std::move(buffer));
            view.positions = strided.back().data(), view.position_stride = 16;
        }
        kdrt_geometry g = kdrt_mesh_geometry(id, &view);
        g.mask = mask;
        entries.push_back(g), object_of.push_back(SIZE_MAX);
        parts.push_back({id, &m, mask});
        world.add_mesh(id, m, mask);
    }
    size_t add_object(Mesh object, const kt::Builder &builder = kt::kBuilders[2]) {
        objects.push_back(std::move(object));
        trees.push_back(kt::build(objects.back(), 4, builder));
        scalar_trees.push_back(kt::build(objects.back(), 4, builder, KDRT_BUILD_SCALAR_KERNEL));
        return objects.size() - 1;
    }
    void add_instance(uint32_t id, size_t object, const Affine &xf, uint32_t mask = kAllBits) {
        const Transform t = to_float(xf);
        kdrt_geometry g = kdrt_instance_geometry(id, trees[object].get(), t.data());
        g.mask = mask;
        entries.push_back(g), object_of.push_back(object);
        world.add_instance(id, objects[object], t.data(), mask);
    }
    // scalar: the scene's meshes and the instances' trees on the scalar kernel.
    ScenePtr build(bool scalar = false) const {
        std::vector<kdrt_geometry> e = entries;
        kdrt_build_options o = kdrt_default_build_options();
        if (scalar) {
            o.flags = KDRT_BUILD_SCALAR_KERNEL;
            for (size_t i = 0; i < e.size(); ++i)
                if (object_of[i] != SIZE_MAX) e[i].tree = scalar_trees[object_of[i]].get();
        }
        return build_scene(e, &o);
    }
    std::vector<uint32_t> ids() const {
        std::vector<uint32_t> v;
        for (const kdrt_geometry &g : entries) v.push_back(g.id);
        return v;
    }
};

// The meshes of the mesh-only scenes: generated ones, a random soup, one given with a 16-byte
// stride, and one repeating the soup's first 100 triangles exactly (ties across geometries).
// Non-contiguous IDs, in no order.
void add_test_meshes(Fixture &f, const uint32_t masks[6]) {
    const Mesh soup = kt::random_soup(400, 11);
    Mesh repeat;
    repeat.name = "soup_repeated";
    repeat.positions.assign(soup.positions.begin(), soup.positions.begin() + 900);
    f.add_mesh(7, kt::translated(kt::sphere(12, 24, 3.0), 5, 5, 5), masks[0]);
    f.add_mesh(3, kt::grid(10, 10, 3), masks[1]);
    f.add_mesh(1000, soup, masks[2]);
    f.add_mesh(42, kt::translated(kt::as_soup(kt::sphere(8, 16, 2.0)), 3, 6, 4), masks[3], true);
    f.add_mesh(0, repeat, masks[4]);
    f.add_mesh(5, kt::translated(kt::grid(6, 6, 8), 2, 2, 4), masks[5]);
}

// ---- judging answers against the world-space brute force ----

enum Verdict { kExact, kAmbiguous, kWrong };

struct Tally {
    size_t checked = 0, exact = 0, ambiguous = 0, wrong = 0;
    std::string first_wrong;
    void add(Verdict v, const std::string &why, const kdrt_ray &ray) {
        ++checked;
        if (v == kExact) ++exact;
        if (v == kAmbiguous) ++ambiguous;
        if (v == kWrong && wrong++ == 0) first_wrong = why + "; " + show(ray);
    }
    std::string summary() const {
        return std::to_string(checked) + " checked: " + std::to_string(exact) + " exact, " + std::to_string(ambiguous) +
               " ambiguous, " + std::to_string(wrong) + " wrong";
    }
};

const RefHit *match(const World &w, const std::vector<RefHit> &refs, const std::vector<int> &rule, const kdrt_hit &h) {
    for (size_t i = 0; i < refs.size(); ++i) {
        const World::Tri &t = w.tri(refs[i].tri);
        if (rule[i] != 0 && t.geometry == h.geometry && t.instance == h.instance && t.triangle == h.triangle &&
            std::fabs(double(h.t) - refs[i].t) <= refs[i].tol)
            return &refs[i];
    }
    return nullptr;
}

std::string show(const World &w, const RefHit &r) {
    const World::Tri &t = w.tri(r.tri);
    char buf[200];
    std::snprintf(buf, sizeof buf, "geometry %u triangle %u at t=%.9g (inside by %.3g, margin %.3g, cos %.3g)", t.geometry,
                  t.triangle, r.t, r.inside, r.margin, r.cos);
    return buf;
}

// The nearest hit (found, hit) against the reference hits counted by rule (counts() of each).
Verdict judge_nearest(const World &w, const kdrt_ray &ray, const std::vector<RefHit> &refs, const std::vector<int> &rule,
                      int found, const kdrt_hit &hit, std::string &why) {
    const RefHit *first_sure = nullptr;
    bool any_possible = false;
    for (size_t i = 0; i < refs.size(); ++i) {
        any_possible |= rule[i] != 0;
        if (!first_sure && rule[i] == 1 && World::sure(refs[i], ray)) first_sure = &refs[i];
    }
    if (!found) {
        if (hit.triangle != KDRT_INVALID_ID) return why = "a miss with triangle " + std::to_string(hit.triangle), kWrong;
        if (first_sure) return why = "missed; the reference hits " + show(w, *first_sure), kWrong;
        return any_possible ? kAmbiguous : kExact;
    }
    const RefHit *m = match(w, refs, rule, hit);
    if (!m) return why = "got " + show(hit) + ", which the reference does not hit so", kWrong;
    if (first_sure && first_sure->t + first_sure->tol < m->t - m->tol)
        return why = "got " + show(hit) + ", but the reference hits " + show(w, *first_sure) + " first", kWrong;
    if (m->cos >= 1e-3 && (std::fabs(hit.u - m->b1) > 4 * m->margin + 1e-5 || std::fabs(hit.v - m->b2) > 4 * m->margin + 1e-5))
        return why = "got " + show(hit) + ", the reference's barycentrics are " + std::to_string(m->b1) + ", " +
                     std::to_string(m->b2),
               kWrong;
    const bool first = &refs[0] == m || std::none_of(refs.begin(), refs.begin() + (m - &refs[0]), [&](const RefHit &r) {
                           return rule[size_t(&r - &refs[0])] != 0;
                       });
    return first && World::sure(*m, ray) && rule[size_t(m - &refs[0])] == 1 ? kExact : kAmbiguous;
}

Verdict judge_occluded(const World &w, const kdrt_ray &ray, const std::vector<RefHit> &refs, const std::vector<int> &rule,
                       int occluded, std::string &why) {
    const RefHit *sure = nullptr;
    bool any_possible = false;
    for (size_t i = 0; i < refs.size(); ++i) {
        any_possible |= rule[i] != 0;
        if (!sure && rule[i] == 1 && World::sure(refs[i], ray)) sure = &refs[i];
    }
    if (!occluded && sure) return why = "not occluded; the reference hits " + show(w, *sure), kWrong;
    if (occluded && !any_possible) return why = "occluded; the reference hits nothing", kWrong;
    return (occluded && sure) || (!occluded && !any_possible) ? kExact : kAmbiguous;
}

// The k nearest: each a distinct reference hit counted by the rule, in (t, geometry, triangle)
// order, as many as the reference has (up to k, within the ambiguous ones), and no sure hit left
// out that is nearer than the last one returned.
Verdict judge_k(const World &w, const kdrt_ray &ray, const std::vector<RefHit> &refs, const std::vector<int> &rule,
                const std::vector<kdrt_hit> &got, uint32_t k, std::string &why) {
    std::vector<char> used(refs.size(), 0);
    size_t sure = 0, possible = 0;
    for (size_t i = 0; i < refs.size(); ++i) possible += rule[i] != 0, sure += rule[i] == 1 && World::sure(refs[i], ray);
    const RefHit *last = nullptr;
    for (size_t i = 0; i < got.size(); ++i) {
        const kdrt_hit &h = got[i];
        const RefHit *m = match(w, refs, rule, h);
        if (!m) return why = "k " + std::to_string(k) + ": hit " + std::to_string(i) + ", " + show(h) + ", is no reference hit", kWrong;
        if (used[size_t(m - &refs[0])]++) return why = "k " + std::to_string(k) + ": " + show(h) + " twice", kWrong;
        if (i > 0) {
            const kdrt_hit &p = got[i - 1];
            const bool ordered = p.t < h.t || (p.t == h.t && (p.geometry < h.geometry || (p.geometry == h.geometry && p.triangle < h.triangle)));
            if (!ordered) return why = "k " + std::to_string(k) + ": " + show(p) + " before " + show(h), kWrong;
        }
        last = m;
    }
    if (got.size() < std::min<size_t>(k, sure) || got.size() > std::min<size_t>(k, possible))
        return why = "k " + std::to_string(k) + ": " + std::to_string(got.size()) + " hits, the reference has " +
                     std::to_string(sure) + " sure of " + std::to_string(possible),
               kWrong;
    for (size_t i = 0; i < refs.size(); ++i) {
        const bool nearer = got.size() < k || (last && refs[i].t + refs[i].tol < last->t - last->tol);
        if (rule[i] == 1 && World::sure(refs[i], ray) && nearer && !used[i])
            return why = "k " + std::to_string(k) + ": " + show(got) + " leaves out " + show(w, refs[i]), kWrong;
    }
    for (size_t i = 0; i < refs.size(); ++i)
        if (rule[i] != 0 && (rule[i] == -1 || !World::sure(refs[i], ray)) && (!last || refs[i].t <= last->t + last->tol))
            return kAmbiguous;
    return kExact;
}

std::vector<int> rule_of(const World &w, const Rules &rules, const std::vector<RefHit> &refs) {
    std::vector<int> r(refs.size());
    for (size_t i = 0; i < refs.size(); ++i) r[i] = counts(rules, w.tri(refs[i].tri), refs[i]);
    return r;
}

// Nearest, any and k nearest hits of the scene under rules, against the world brute force.
struct Judged {
    Tally nearest, occluded, k;
    // A line for the log: how many answers were exact, ambiguous (either answer right), wrong.
    std::string summary() const {
        return "nearest: " + nearest.summary() + "\n  occluded: " + occluded.summary() + "\n  k nearest: " + k.summary();
    }
    void add(const Judged &o) {
        for (auto p : {std::make_pair(&nearest, &o.nearest), std::make_pair(&occluded, &o.occluded), std::make_pair(&k, &o.k)}) {
            p.first->checked += p.second->checked, p.first->exact += p.second->exact;
            p.first->ambiguous += p.second->ambiguous, p.first->wrong += p.second->wrong;
        }
    }
};
void judge_queries(SceneQueries &q, const World &w, const Rules &rules, const std::vector<kdrt_ray> &rays,
                   const std::vector<std::vector<RefHit>> &refs, Judged &out) {
    for (size_t r = 0; r < rays.size(); ++r) {
        const std::vector<int> rule = rule_of(w, rules, refs[r]);
        std::string why;
        kdrt_hit hit{};
        const int found = q.intersect(rays[r], hit);
        Verdict v = judge_nearest(w, rays[r], refs[r], rule, found, hit, why);  // before reading why
        out.nearest.add(v, "nearest: " + why, rays[r]);
        v = judge_occluded(w, rays[r], refs[r], rule, q.occluded(rays[r]), why);
        out.occluded.add(v, "occluded: " + why, rays[r]);
        for (uint32_t k : kCapacities) {
            const std::vector<kdrt_hit> got = q.nearest_k(rays[r], k);
            v = judge_k(w, rays[r], refs[r], rule, got, k, why);
            // The first of the k nearest is the nearest hit, bit for bit.
            if (v != kWrong && !identical(int(!got.empty()), got.empty() ? hit : got[0], found, hit))
                v = kWrong, why = "k " + std::to_string(k) + ": the first is " + show(got[0]) + ", the nearest " + show(hit);
            out.k.add(v, why, rays[r]);
        }
    }
}
void check_judged(const Judged &j, double ambiguous_share) {
    for (const Tally *t : {&j.nearest, &j.occluded, &j.k}) {
        INFO((t == &j.nearest ? "nearest: " : t == &j.occluded ? "occluded: " : "k nearest: ") << t->summary());
        INFO("first wrong: " << t->first_wrong);
        CHECK(t->wrong == 0);
        CHECK(double(t->ambiguous) <= ambiguous_share * double(t->checked));
    }
}

// Every hit counting: the scene's nearest, any and k nearest hits judged against refs, at most 2%
// of the answers ambiguous.
Judged judge_every_hit(const kdrt_scene *scene, const World &w, const std::vector<kdrt_ray> &rays,
                       const std::vector<std::vector<RefHit>> &refs) {
    const Rules all{"every hit", 0, kAllBits, {}};
    SceneQueries q(scene, all, &w);
    Judged j;
    judge_queries(q, w, all, rays, refs, j);
    check_judged(j, 0.02);
    return j;
}

// Rays at points well inside triangles (barycentrics at least 0.05) of the given geometries, from
// either side, at least 11 degrees off the triangle's plane, direction lengths from 0.3 to 3:
// every one must hit something.
std::vector<kdrt_ray> aimed_rays(const World &w, const std::vector<uint32_t> &ids, size_t count, uint32_t seed) {
    common::Rng rng(seed);
    const double reach = w.extent();
    std::vector<kdrt_ray> rays;
    while (rays.size() < count) {
        const uint32_t id = ids[rng.below(uint32_t(ids.size()))];
        const World::Tri *t = w.find(id, rng.below(w.triangles_of(id)));
        if (!t || t->degenerate) continue;
        const double u = rng.range(0.05, 0.9), v = rng.range(0.05, 0.95 - u);
        const V3 target = add(t->p0, add(mul(t->e1, u), mul(t->e2, v)));
        double d[3];
        rng.direction(d);
        const V3 dir = {d[0], d[1], d[2]};
        if (std::fabs(dot(dir, t->n)) < 0.2 * norm(t->n)) continue;
        const V3 org = sub(target, mul(dir, rng.range(0.3, 1.0) * reach));
        const V3 scaled = mul(dir, rng.range(0.3, 3.0));
        rays.push_back(kt::ray_of(float(org[0]), float(org[1]), float(org[2]), float(scaled[0]), float(scaled[1]), float(scaled[2])));
    }
    return rays;
}

std::vector<std::vector<RefHit>> reference_hits(const World &w, const std::vector<kdrt_ray> &rays) {
    std::vector<std::vector<RefHit>> refs(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) refs[i] = w.hits(rays[i]);
    return refs;
}

// kdrt_scene_hit_surface and kdrt_scene_spawn_ray for a hit: the point on the ray, the unit normal
// perpendicular to the world triangle and facing where its world corners wind counterclockwise
// (a mirror included), and secondary rays leaving it from the side they go to that do not hit the
// same triangle again. Empty when all is well, else what is not.
std::string check_surface(const kdrt_scene *scene, const World &w, const kdrt_ray &ray, const kdrt_hit &hit) {
    const World::Tri *tri = w.find(hit.geometry, hit.triangle);
    if (!tri) return "no such triangle";
    float point[3], normal[3];
    if (!kdrt_scene_hit_surface(scene, &hit, point, normal)) return "kdrt_scene_hit_surface refused the hit";
    const V3 o = of(ray.org), d = of(ray.dir), p = of(point), n = of(normal);
    const V3 ref_n = mul(tri->n, 1 / norm(tri->n));
    const double cos = std::fabs(dot(d, ref_n)) / norm(d);
    char buf[300];
    if (cos >= 1e-2 && norm(sub(p, add(o, mul(d, hit.t)))) > 1e-4 * (norm(o) + norm(mul(d, hit.t)) + w.extent())) {
        std::snprintf(buf, sizeof buf, "point (%.9g, %.9g, %.9g) is not org + t dir", p[0], p[1], p[2]);
        return buf;
    }
    if (std::fabs(norm(n) - 1) > 1e-5 || norm(cross(n, ref_n)) > 1e-4 || dot(n, ref_n) <= 0) {
        std::snprintf(buf, sizeof buf, "normal (%.9g, %.9g, %.9g), the world winding's (%.9g, %.9g, %.9g)", n[0], n[1], n[2],
                      ref_n[0], ref_n[1], ref_n[2]);
        return buf;
    }
    // Reflected, and straight on through the surface.
    const V3 reflected = sub(d, mul(n, 2 * dot(d, n)));
    for (const V3 &go : {reflected, d}) {
        const float dir[3] = {float(go[0]), float(go[1]), float(go[2])};
        kdrt_ray out;
        if (!kdrt_scene_spawn_ray(scene, &hit, dir, &out)) return "kdrt_scene_spawn_ray refused the hit";
        if (std::memcmp(out.dir, dir, sizeof dir) != 0 || out.tmin != 0.0f || out.tmax != kInf) return "spawned ray: " + show(out);
        const V3 so = of(out.org);
        if (norm(sub(so, p)) > 1e-3 * (1 + norm(p))) return "spawned ray far from the point: " + show(out);
        // Off the plane, on the side it goes to.
        const double side = dot(sub(so, tri->p0), ref_n), way = dot(of(dir), ref_n);
        if (!(side * way > 0)) {
            std::snprintf(buf, sizeof buf, "spawned origin %.3g from the plane, going %.3g: ", side, way);
            return buf + show(out);
        }
        kdrt_hit again{};
        if (kdrt_scene_intersect(scene, &out, nullptr, &again) && again.geometry == hit.geometry && again.triangle == hit.triangle)
            return "the spawned ray hits its own triangle again: " + show(again) + ", " + show(out);
    }
    return "";
}

// Nearest hits of a scene on rays, with the default query.
std::vector<std::pair<int, kdrt_hit>> trace(const kdrt_scene *scene, const std::vector<kdrt_ray> &rays) {
    std::vector<std::pair<int, kdrt_hit>> out(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) out[i].first = kdrt_scene_intersect(scene, &rays[i], nullptr, &out[i].second);
    return out;
}
size_t differences(const std::vector<std::pair<int, kdrt_hit>> &a, const std::vector<std::pair<int, kdrt_hit>> &b) {
    size_t n = 0;
    for (size_t i = 0; i < a.size(); ++i) n += !identical(a[i].first, a[i].second, b[i].first, b[i].second);
    return n;
}

bool same_box(const kdrt_aabb &a, const kdrt_aabb &b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The box holds `inner` and lies within `outer` widened by `slack` of its extent and position.
bool box_fits(const kdrt_aabb &box, const kdrt_aabb &inner, const kdrt_aabb &outer, double slack) {
    for (int a = 0; a < 3; ++a) {
        const double e = slack * (double(outer.max[a]) - outer.min[a] + std::max(std::fabs(outer.min[a]), std::fabs(outer.max[a])));
        if (!(box.min[a] <= inner.min[a] && box.max[a] >= inner.max[a])) return false;
        if (outer.min[a] - box.min[a] > e || box.max[a] - outer.max[a] > e) return false;
    }
    return true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

TEST_CASE("scene: meshes answer bit for bit what one tree over all their triangles does", "[scene]") {
    const uint32_t masks[6] = {kAllBits, kAllBits, kAllBits, kAllBits, kAllBits, kAllBits};
    Fixture f;
    add_test_meshes(f, masks);
    const Merged merged(f.parts);
    const ScenePtr scene = f.build(), scalar = f.build(true);
    const kt::TreePtr one_tree = kt::build(merged.mesh(), 4);  // a real tree, for kdrt_hit_surface

    // Its box is the meshes' box.
    const kdrt_triangles merged_view = merged.mesh().view();
    kdrt_aabb box;
    REQUIRE(kdrt_aabb_of_triangles(&merged_view, &box, nullptr) == KDRT_SUCCESS);
    CHECK(box_fits(kdrt_scene_bounds(scene.get()), box, box, 1e-6));

    const std::vector<kdrt_ray> rays = kt::random_rays(box, 3000, 5);
    const oracle::Oracle oracle(merged.mesh());
    const std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
    const Rules all{"every hit", 0, kAllBits, {}};

    oracle::Agreement tally;
    size_t hits = 0, not_merged = 0, not_scalar = 0, occluded_differs = 0, k_differs = 0, bad_instance = 0,
           surface_differs = 0, tree_hit_fields = 0, cross_geometry_ties = 0;
    std::string first_not_merged, first_k, first_surface;
    for (size_t i = 0; i < rays.size(); ++i) {
        const kdrt_ray &ray = rays[i];
        kdrt_hit got{}, want{}, other{};
        const int found = kdrt_scene_intersect(scene.get(), &ray, nullptr, &got);
        const int expected = merged.intersect(ray, all, want);
        hits += found;
        if (!identical(found, got, expected, want) && not_merged++ == 0)
            first_not_merged = show(ray) + ": the scene gives " + show(got) + ", the merged tree " + show(want);
        const int found_scalar = kdrt_scene_intersect(scalar.get(), &ray, nullptr, &other);
        not_scalar += !identical(found, got, found_scalar, other);
        occluded_differs += kdrt_scene_occluded(scene.get(), &ray, nullptr) != found;
        bad_instance += found && got.instance != KDRT_INVALID_ID;
        for (uint32_t k : kCapacities) {
            std::vector<kdrt_hit> list(k);
            list.resize(kdrt_scene_intersect_k(scene.get(), &ray, nullptr, list.data(), k));
            const std::vector<kdrt_hit> expected_list = merged.nearest_k(ray, all, k);
            if (!identical(list, expected_list) && k_differs++ == 0)
                first_k = show(ray) + ", k " + std::to_string(k) + ": " + show(list) + ", the merged tree " + show(expected_list);
            std::vector<kdrt_hit> list_scalar(k);
            list_scalar.resize(kdrt_scene_intersect_k(scalar.get(), &ray, nullptr, list_scalar.data(), k));
            not_scalar += !identical(list, list_scalar);
            for (size_t j = 1; j < list.size(); ++j) cross_geometry_ties += list[j].t == list[j - 1].t && list[j].geometry != list[j - 1].geometry;
        }
        // The oracle, in the merged numbering.
        oracle::check_hit(oracle, refs[i], ray, found ? merged.to_merged(got) : got, tally);
        if (found) {
            // The surface point and normal are the one tree's.
            float p[3], n[3], tp[3], tn[3];
            kdrt_hit as_merged = merged.to_merged(got);
            as_merged.geometry = 0;  // a one-tree hit
            const int a = kdrt_scene_hit_surface(scene.get(), &got, p, n), b = kdrt_hit_surface(one_tree.get(), &as_merged, tp, tn);
            bool same = a == 1 && b == 1;
            for (int c = 0; c < 3 && same; ++c)
                same = std::fabs(p[c] - tp[c]) <= 1e-6f * (1 + std::fabs(tp[c])) && std::fabs(n[c] - tn[c]) <= 1e-6f;
            if (!same && surface_differs++ == 0) first_surface = show(ray) + " at " + show(got);
            // A one-tree query names no geometry.
            kdrt_hit plain{};
            if (kdrt_intersect(one_tree.get(), &ray, &plain)) tree_hit_fields += plain.geometry != 0 || plain.instance != KDRT_INVALID_ID;
        }
    }
    INFO(hits << " hits of " << rays.size() << " rays; oracle: " << tally.exact << " exact, " << tally.ambiguous << " ambiguous");
    {
        INFO("first: " << first_not_merged);
        CHECK(not_merged == 0);
    }
    {
        INFO("first: " << first_k);
        CHECK(k_differs == 0);
    }
    {
        INFO("first wrong: " << tally.first_wrong);
        CHECK(tally.wrong == 0);
        CHECK(tally.ambiguous * 100 <= tally.rays);
    }
    {
        INFO("first: " << first_surface);
        CHECK(surface_differs == 0);
    }
    CHECK(not_scalar == 0);  // both kernels, bit for bit
    CHECK(occluded_differs == 0);
    CHECK(bad_instance == 0);
    CHECK(tree_hit_fields == 0);
    CHECK(hits > rays.size() / 3);
    CHECK(cross_geometry_ties > 0);  // the test means something: mesh 0 repeats mesh 1000's triangles
}

TEST_CASE("scene: masks, culled faces and filters on meshes: the one tree's answers, bit for bit", "[scene]") {
    // Mesh 0 has mask 0: no query ever hits it.
    const uint32_t masks[6] = {1, 2, 4 | 1, 8, 0, 2 | 8};
    Fixture f;
    add_test_meshes(f, masks);
    const Merged merged(f.parts);
    const ScenePtr scene = f.build();
    const kdrt_aabb box = kdrt_scene_bounds(scene.get());
    const std::vector<kdrt_ray> rays = kt::random_rays(box, 600, 6);  // times 13 rule sets against a brute force

    const auto odd_out = [](uint32_t, uint32_t triangle) { return triangle % 2 == 0; };
    const auto parity = [](uint32_t geometry, uint32_t triangle) { return (geometry + triangle) % 2 == 0; };
    const std::vector<Rules> cases = {
        {"mask 1", 0, 1, {}},
        {"mask 2", 0, 2, {}},
        {"mask 4", 0, 4, {}},
        {"mask 8", 0, 8, {}},
        {"mask 6", 0, 6, {}},
        {"mask of bits no geometry has", 0, 0xF0u, {}},
        {"cull back faces", KDRT_QUERY_CULL_BACK_FACES, kAllBits, {}},
        {"cull front faces", KDRT_QUERY_CULL_FRONT_FACES, kAllBits, {}},
        {"cull both", KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES, kAllBits, {}},
        {"filter: even triangles", 0, kAllBits, odd_out},
        {"filter: even geometry + triangle", 0, kAllBits, parity},
        {"mask 3, back faces culled, filter by parity", KDRT_QUERY_CULL_BACK_FACES, 3, parity},
        {"mask 8, front faces culled, even triangles", KDRT_QUERY_CULL_FRONT_FACES, 8, odd_out},
    };
    for (const Rules &rules : cases) {
        INFO(rules.name);
        SceneQueries q(scene.get(), rules, &f.world);
        size_t wrong = 0, hits = 0, hits_on_zero_mask = 0;
        std::string first;
        for (const kdrt_ray &ray : rays) {
            kdrt_hit got{}, want{};
            const int found = q.intersect(ray, got), expected = merged.intersect(ray, rules, want);
            hits += found;
            hits_on_zero_mask += found && got.geometry == 0;
            if (!identical(found, got, expected, want) && wrong++ == 0)
                first = "nearest: " + show(got) + ", the merged tree " + show(want) + "; " + show(ray);
            if (q.occluded(ray) != merged.occluded(ray, rules) && wrong++ == 0) first = "occluded; " + show(ray);
            for (uint32_t k : kCapacities) {
                const std::vector<kdrt_hit> list = q.nearest_k(ray, k), expected_list = merged.nearest_k(ray, rules, k);
                if (!identical(list, expected_list) && wrong++ == 0)
                    first = "k " + std::to_string(k) + ": " + show(list) + ", the merged tree " + show(expected_list) + "; " + show(ray);
                for (const kdrt_hit &h : list) hits_on_zero_mask += h.geometry == 0;
            }
        }
        INFO(hits << " hits; first wrong: " << first);
        CHECK(wrong == 0);
        CHECK(hits_on_zero_mask == 0);
        if (rules.mask == 0xF0u || rules.flags == (KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES)) CHECK(hits == 0);
        else CHECK(hits > rays.size() / 20);  // the test means something
        q.check_filter(rays.size());
    }

    // Query mask 0 hits nothing, whatever the geometries' masks.
    const Rules none{"mask 0", 0, 0, {}};
    SceneQueries q(scene.get(), none, &f.world);
    CHECK(q.anything(rays) == 0);
}

TEST_CASE("scene: instances under every kind of transform, against the world-space brute force", "[scene]") {
    struct Placement {
        const char *name;
        Affine xf;
    };
    const Placement placements[] = {
        {"translation", translate(20, -5, 3)},
        {"rotation", translate(1, 2, 3) * rotate(1, 2, 3, 0.7)},
        {"rotation by a large angle", rotate(-2, 0.5, 1, 2.9)},
        {"uniform scale", translate(-4, 0, 2) * scale(2.5, 2.5, 2.5) * rotate(0, 0, 1, 0.3)},
        {"small scale far out", translate(200, -100, 50) * scale(0.02, 0.02, 0.02)},
        {"non-uniform scale", translate(0, 6, 0) * rotate(1, 1, 0, 0.4) * scale(3, 0.5, 1.5)},
        {"mirror", translate(-6, 1, 0) * scale(-1, 1, 1)},
        {"mirror and rotation", translate(2, -7, 1) * rotate(0, 1, 1, 1.1) * scale(1, -2, 1)},
        {"point reflection", translate(1, 1, 1) * scale(-1, -1, -1)},
        {"shear", translate(3, 3, -3) * shear(0.7, -0.4, 0.3)},
        {"everything", translate(-3, 8, 5) * rotate(2, -1, 0.5, -1.3) * shear(0.5, 0.2, -0.6) * scale(1.7, -0.6, 0.9)},
    };
    // Two objects: a closed sphere, and an open height field about the origin; the second placed
    // beside the first, overlapping it.
    const Mesh sphere = kt::sphere(10, 20, 1.0);
    const Mesh field = kt::translated(kt::grid(5, 5, 4), -2.5, -2.5, -1.5);
    size_t mirrored = 0;
    Judged total;
    for (const Placement &pl : placements) {
        INFO(pl.name);
        Fixture f;
        const size_t a = f.add_object(sphere), b = f.add_object(field, kt::kBuilders[0]);
        f.add_instance(31, a, pl.xf);
        f.add_instance(8, b, pl.xf * translate(1.5, 0.5, 0) * rotate(1, 0, 0, 0.6));
        mirrored += determinant(of_float(f.entries[0].transform)) < 0;
        const ScenePtr scene = f.build(), scalar = f.build(true);

        // The box holds every world corner, and no more than the instances' boxes do.
        CHECK(box_fits(kdrt_scene_bounds(scene.get()), f.world.box(), f.world.loose_box(), 1e-4));

        std::vector<kdrt_ray> rays = aimed_rays(f.world, {31, 8}, 250, 7);
        const std::vector<kdrt_ray> random = kt::random_rays(f.world.box(), 150, 8);
        rays.insert(rays.end(), random.begin(), random.end());
        const std::vector<std::vector<RefHit>> refs = reference_hits(f.world, rays);
        total.add(judge_every_hit(scene.get(), f.world, rays, refs));

        size_t misses = 0, bad_ids = 0, surface_wrong = 0, kernels_differ = 0;
        std::string first_surface;
        for (size_t i = 0; i < rays.size(); ++i) {
            kdrt_hit hit{}, other{};
            const int found = kdrt_scene_intersect(scene.get(), &rays[i], nullptr, &hit);
            kernels_differ += !identical(found, hit, kdrt_scene_intersect(scalar.get(), &rays[i], nullptr, &other), other);
            if (!found) {
                misses += i < 250;  // an aimed ray must hit
                continue;
            }
            bad_ids += hit.geometry != hit.instance || (hit.geometry != 31 && hit.geometry != 8);
            const std::string why = check_surface(scene.get(), f.world, rays[i], hit);
            if (!why.empty() && surface_wrong++ == 0) first_surface = why + "; " + show(rays[i]) + " hits " + show(hit);
        }
        INFO("first: " << first_surface);
        CHECK(misses == 0);
        CHECK(bad_ids == 0);
        CHECK(surface_wrong == 0);
        CHECK(kernels_differ == 0);
    }
    CHECK(mirrored == 4);  // the test means something: four placements mirror
    WARN("instances under " << std::size(placements) << " transforms, against the world brute force:\n  " << total.summary());
}

namespace {

// Meshes and overlapping instances of two trees, mirrors among them. masks: the entries' masks in
// the order added (7 instances after 3 meshes), or all bits.
Fixture mixed_scene(const std::vector<uint32_t> &masks = {}) {
    auto mask = [&](size_t i) { return masks.empty() ? kAllBits : masks[i]; };
    Fixture f;
    f.add_mesh(11, kt::translated(kt::sphere(12, 24, 2.0), 5, 5, 5), mask(0));
    f.add_mesh(4, kt::grid(10, 10, 7), mask(1));
    f.add_mesh(900, kt::random_soup(300, 13), mask(2));
    const size_t ball = f.add_object(kt::sphere(10, 20, 1.5));
    const size_t soup = f.add_object(kt::translated(kt::random_soup(150, 17), -5, -5, -5), kt::kBuilders[0]);
    f.add_instance(2, ball, translate(3, 4, 5) * rotate(1, 0, 0, 0.5), mask(3));
    f.add_instance(17, ball, translate(8, 2, 6) * scale(1.5, 0.7, 1), mask(4));
    f.add_instance(33, ball, translate(5, 8, 3) * scale(-1, 1, 1), mask(5));
    f.add_instance(100, ball, translate(6, 6, 6) * shear(0.4, 0, 0.2), mask(6));  // inside mesh 11's sphere
    f.add_instance(5, soup, translate(5, 5, 5) * scale(0.4, 0.4, 0.4), mask(7));
    f.add_instance(64, soup, translate(4, 6, 4) * rotate(0, 1, 0, 2) * scale(-0.5, 0.5, 0.5), mask(8));
    f.add_instance(1u << 20, soup, translate(6, 4, 7) * scale(0.3, 0.6, 0.45), mask(9));
    return f;
}

// Random rays through the scene, rays aimed inside its triangles, and each of those again cut
// short before or after its first hit, or started past it.
std::vector<kdrt_ray> mixed_rays(const Fixture &f, size_t random, size_t aimed, uint32_t seed) {
    std::vector<kdrt_ray> rays = kt::random_rays(f.world.box(), random, seed);
    const std::vector<kdrt_ray> at = aimed_rays(f.world, f.ids(), aimed, seed + 1);
    rays.insert(rays.end(), at.begin(), at.end());
    const size_t n = rays.size();
    for (size_t i = 0; i < n; i += 3) {
        const std::vector<RefHit> refs = f.world.hits(rays[i]);
        if (refs.empty()) continue;
        const float t = float(refs[0].t);
        kdrt_ray r = rays[i];
        r.tmax = 0.5f * t, rays.push_back(r);
        r.tmax = 1.5f * t, rays.push_back(r);
        r.tmax = kInf, r.tmin = 1.01f * t, rays.push_back(r);
    }
    return rays;
}

}  // namespace

TEST_CASE("scene: meshes and overlapping instances of two trees, nearest, any and k nearest", "[scene]") {
    const Fixture f = mixed_scene();
    const ScenePtr scene = f.build(), scalar = f.build(true);
    CHECK(box_fits(kdrt_scene_bounds(scene.get()), f.world.box(), f.world.loose_box(), 1e-4));
    const std::vector<kdrt_ray> rays = mixed_rays(f, 1200, 800, 21);
    const std::vector<std::vector<RefHit>> refs = reference_hits(f.world, rays);
    const Judged j = judge_every_hit(scene.get(), f.world, rays, refs);
    WARN("meshes and instances, " << rays.size() << " rays, against the world brute force:\n  " << j.summary());

    size_t hits = 0, on_instances = 0, surface_wrong = 0, kernels_differ = 0, multiple = 0;
    std::string first_surface;
    for (size_t i = 0; i < rays.size(); ++i) {
        kdrt_hit hit{}, other{};
        const int found = kdrt_scene_intersect(scene.get(), &rays[i], nullptr, &hit);
        kernels_differ += !identical(found, hit, kdrt_scene_intersect(scalar.get(), &rays[i], nullptr, &other), other);
        std::vector<kdrt_hit> a(64), b(64);
        a.resize(kdrt_scene_intersect_k(scene.get(), &rays[i], nullptr, a.data(), 64));
        b.resize(kdrt_scene_intersect_k(scalar.get(), &rays[i], nullptr, b.data(), 64));
        kernels_differ += !identical(a, b);
        std::map<uint32_t, int> geometries;
        for (const kdrt_hit &h : a) geometries[h.geometry] = 1;
        multiple += geometries.size() >= 3;
        if (!found) continue;
        ++hits, on_instances += hit.instance != KDRT_INVALID_ID;
        const std::string why = check_surface(scene.get(), f.world, rays[i], hit);
        if (!why.empty() && surface_wrong++ == 0) first_surface = why + "; " + show(rays[i]) + " hits " + show(hit);
    }
    INFO(hits << " hits, " << on_instances << " on instances; first: " << first_surface);
    CHECK(surface_wrong == 0);
    CHECK(kernels_differ == 0);
    CHECK(on_instances > hits / 4);  // the test means something: instances and meshes both hit,
    CHECK(on_instances < hits);
    CHECK(multiple > rays.size() / 10);  // and rays pass through several
}

TEST_CASE("scene: masks, culled faces and filters across meshes and instances", "[scene]") {
    // Entries 11, 4, 900 (meshes), 2, 17, 33, 100, 5, 64, 2^20 (instances; 33 and 64 mirror).
    const Fixture f = mixed_scene({1, 2, 4, 1, 2, 4 | 8, 0, 8, 1 | 2, 4});
    const ScenePtr scene = f.build();
    const std::vector<kdrt_ray> rays = mixed_rays(f, 600, 400, 31);
    const std::vector<std::vector<RefHit>> refs = reference_hits(f.world, rays);

    const auto odd_out = [](uint32_t, uint32_t triangle) { return triangle % 2 == 0; };
    const auto parity = [](uint32_t geometry, uint32_t triangle) { return (geometry + triangle) % 2 == 0; };
    const std::vector<Rules> cases = {
        {"every hit", 0, kAllBits, {}},
        {"mask 1", 0, 1, {}},
        {"mask 2", 0, 2, {}},
        {"mask 4", 0, 4, {}},
        {"mask 8", 0, 8, {}},
        {"mask 5", 0, 5, {}},
        {"cull back faces", KDRT_QUERY_CULL_BACK_FACES, kAllBits, {}},
        {"cull front faces", KDRT_QUERY_CULL_FRONT_FACES, kAllBits, {}},
        {"filter: even triangles", 0, kAllBits, odd_out},
        {"filter: even geometry + triangle", 0, kAllBits, parity},
        {"mask 12, back faces culled, filter by parity", KDRT_QUERY_CULL_BACK_FACES, 12, parity},
        {"mask 3, front faces culled, even triangles", KDRT_QUERY_CULL_FRONT_FACES, 3, odd_out},
    };
    Judged total;
    for (const Rules &rules : cases) {
        INFO(rules.name);
        SceneQueries q(scene.get(), rules, &f.world);
        Judged j;
        judge_queries(q, f.world, rules, rays, refs, j);
        check_judged(j, 0.02);
        total.add(j);
        q.check_filter(rays.size());
        // Instance 100 has mask 0: never hit.
        size_t on_100 = 0, hits = 0;
        for (const kdrt_ray &ray : rays) {
            kdrt_hit h{};
            if (q.intersect(ray, h)) ++hits, on_100 += h.geometry == 100;
        }
        CHECK(on_100 == 0);
        CHECK(hits > rays.size() / 20);  // the test means something
    }

    WARN(cases.size() << " masks, culls and filters on meshes and instances, " << rays.size()
                      << " rays each, against the world brute force:\n  " << total.summary());

    const Rules both{"cull both", KDRT_QUERY_CULL_BACK_FACES | KDRT_QUERY_CULL_FRONT_FACES, kAllBits, {}};
    const Rules none{"mask 0", 0, 0, {}};
    for (const Rules *rules : {&both, &none}) {
        INFO(rules->name);
        SceneQueries q(scene.get(), *rules, &f.world);
        CHECK(q.anything(rays) == 0);
    }
}

TEST_CASE("scene: a mirroring instance's front is where its world corners wind counterclockwise", "[scene]") {
    // One triangle, counterclockwise seen from +z: its front faces +z. Mirrored in x by an
    // instance, its world corners wind counterclockwise seen from -z: the front faces -z.
    // Mirrored in z, across its own plane, its world corners are its own: the front stays +z.
    Mesh tri;
    tri.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const kt::TreePtr tree = kt::build(tri, 4);
    const Transform plain = to_float(translate(0, 0, 0)), mirror_x = to_float(translate(5, 0, 0) * scale(-1, 1, 1)),
                    mirror_z = to_float(translate(10, 0, 0) * scale(1, 1, -1));
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(1, nullptr), kdrt_instance_geometry(2, tree.get(), plain.data()),
                                          kdrt_instance_geometry(3, tree.get(), mirror_x.data()),
                                          kdrt_instance_geometry(4, tree.get(), mirror_z.data())};
    entries[0].mesh = tri.view();
    const ScenePtr scene = build_scene(entries);
    struct Case {
        float x;       // where the ray goes through z = 0 is x + 0.2
        uint32_t id;   // what it meets there
        float front;   // the z the front faces: +1 or -1
    };
    for (const Case c : {Case{0.25f, 1, 1.0f}, Case{0.25f, 2, 1.0f}, Case{4.35f, 3, -1.0f}, Case{10.25f, 4, 1.0f}}) {
        for (float from : {1.0f, -1.0f}) {  // from above, going down, and from below
            INFO("geometry " << c.id << " from z = " << from);
            const kdrt_ray ray = kt::ray_of(c.x, 0.25f, 2 * from, 0.1f, 0.05f, -from);
            const bool on_front = from * c.front > 0;
            kdrt_hit hit{};
            kdrt_query q;
            REQUIRE(kdrt_scene_intersect(scene.get(), &ray, nullptr, &hit) == 1);
            CHECK(hit.t == Approx(2.0f).epsilon(1e-6));
            // Mesh 1 and instance 2 lie in the same place: the lower ID wins.
            CHECK(hit.geometry == (c.id == 2 ? 1u : c.id));
            float n[3];
            REQUIRE(kdrt_scene_hit_surface(scene.get(), &hit, nullptr, n) == 1);
            CHECK(n[2] == Approx(c.front).epsilon(1e-6));
            for (uint32_t flags : {uint32_t(KDRT_QUERY_CULL_BACK_FACES), uint32_t(KDRT_QUERY_CULL_FRONT_FACES)}) {
                const bool kept = (flags == KDRT_QUERY_CULL_BACK_FACES) == on_front;
                q = kdrt_default_query();
                q.flags = flags;
                kdrt_hit h{};
                // Filter out the other geometries so that each is judged on its own.
                struct Only {
                    uint32_t id;
                    static int call(void *user, const kdrt_ray *, const kdrt_hit *cand) {
                        return cand->geometry == static_cast<Only *>(user)->id;
                    }
                } only{c.id};
                q.filter = &Only::call, q.user = &only;
                INFO((flags == KDRT_QUERY_CULL_BACK_FACES ? "back faces culled" : "front faces culled"));
                CHECK(kdrt_scene_intersect(scene.get(), &ray, &q, &h) == int(kept));
                if (kept) CHECK(h.geometry == c.id);
                CHECK(kdrt_scene_occluded(scene.get(), &ray, &q) == int(kept));
                kdrt_hit list[4];
                CHECK(kdrt_scene_intersect_k(scene.get(), &ray, &q, list, 4) == uint32_t(kept));
            }
        }
    }
}

TEST_CASE("scene: equal t goes to the lower geometry ID, then the lower triangle", "[scene]") {
    // One triangle six times: in meshes 9 and 5 (twice in 5), and as instances 7 and 3 of a tree
    // of it with the identity transform (carrying the ray into the tree's space changes nothing),
    // and 12 with an explicit identity. Every hit has the same t bits.
    Mesh one, twice;
    one.positions = {0.1f, 0.2f, 0.3f, 1.7f, 0.4f, 0.1f, 0.3f, 1.9f, -0.2f};
    twice.positions = one.positions;
    twice.positions.insert(twice.positions.end(), one.positions.begin(), one.positions.end());
    const kt::TreePtr tree = kt::build(one, 4);
    const Transform identity = to_float(Affine());
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(9, nullptr), kdrt_instance_geometry(7, tree.get(), nullptr),
                                          kdrt_mesh_geometry(5, nullptr), kdrt_instance_geometry(12, tree.get(), identity.data()),
                                          kdrt_instance_geometry(3, tree.get(), nullptr)};
    entries[0].mesh = one.view(), entries[2].mesh = twice.view();
    entries[4].mask = 2;  // instance 3 can be masked out
    const ScenePtr scene = build_scene(entries);

    struct Expect {
        uint32_t geometry, instance, triangle;
    };
    const Expect all[] = {{3, 3, 0}, {5, KDRT_INVALID_ID, 0}, {5, KDRT_INVALID_ID, 1}, {7, 7, 0}, {9, KDRT_INVALID_ID, 0}, {12, 12, 0}};
    common::Rng rng(3);
    size_t wrong = 0;
    std::string first;
    auto fail = [&](const std::string &why) {
        if (wrong++ == 0) first = why;
    };
    const V3 p0 = {one.positions[0], one.positions[1], one.positions[2]};
    const V3 normal = cross(sub({one.positions[3], one.positions[4], one.positions[5]}, p0),
                            sub({one.positions[6], one.positions[7], one.positions[8]}, p0));
    for (int i = 0; i < 200; ++i) {
        // Through a point inside the triangle, from either side, at least 6 degrees off its plane.
        const double u = rng.range(0.05, 0.9), v = rng.range(0.05, 0.95 - u);
        V3 p;
        for (int a = 0; a < 3; ++a)
            p[size_t(a)] = one.positions[size_t(a)] + u * (one.positions[size_t(3 + a)] - one.positions[size_t(a)]) +
                           v * (one.positions[size_t(6 + a)] - one.positions[size_t(a)]);
        double d[3];
        do rng.direction(d);
        while (std::fabs(dot({d[0], d[1], d[2]}, normal)) < 0.1 * norm(normal));
        const kdrt_ray ray = kt::ray_of(float(p[0] - 3 * d[0]), float(p[1] - 3 * d[1]), float(p[2] - 3 * d[2]), float(d[0]),
                                        float(d[1]), float(d[2]));
        kdrt_hit list[8];
        const uint32_t n = kdrt_scene_intersect_k(scene.get(), &ray, nullptr, list, 8);
        if (n != 6) {
            fail(show(ray) + ": " + std::to_string(n) + " hits");
            continue;
        }
        for (uint32_t k = 0; k < n; ++k)
            if (list[k].geometry != all[k].geometry || list[k].instance != all[k].instance || list[k].triangle != all[k].triangle ||
                std::memcmp(&list[k].t, &list[0].t, sizeof list[0].t) != 0)
                fail(show(ray) + ": hit " + std::to_string(k) + " is " + show(list[k]));
        kdrt_hit hit{};
        if (!kdrt_scene_intersect(scene.get(), &ray, nullptr, &hit) || !identical(1, hit, 1, list[0]))
            fail(show(ray) + ": nearest " + show(hit));
        // Shorter lists are the list's start.
        kdrt_hit three[3];
        if (kdrt_scene_intersect_k(scene.get(), &ray, nullptr, three, 3) != 3 || !identical(1, three[2], 1, list[2]))
            fail(show(ray) + ": k 3");
        // Instance 3 masked out: mesh 5's first triangle.
        kdrt_query q = kdrt_default_query();
        q.mask = 1;
        if (!kdrt_scene_intersect(scene.get(), &ray, &q, &hit) || hit.geometry != 5 || hit.triangle != 0)
            fail(show(ray) + ": masked, " + show(hit));
        // A filter refusing 3 and mesh 5's first: mesh 5's second.
        q = kdrt_default_query();
        q.filter = [](void *, const kdrt_ray *, const kdrt_hit *c) { return int(c->geometry != 3 && !(c->geometry == 5 && c->triangle == 0)); };
        if (!kdrt_scene_intersect(scene.get(), &ray, &q, &hit) || hit.geometry != 5 || hit.triangle != 1)
            fail(show(ray) + ": filtered, " + show(hit));
        if (kdrt_scene_intersect_k(scene.get(), &ray, &q, list, 8) != 4 || list[0].triangle != 1 || list[1].geometry != 7)
            fail(show(ray) + ": filtered k");
    }
    INFO("first: " << first);
    CHECK(wrong == 0);
}

TEST_CASE("scene: moving instances takes effect at the commit, and only then", "[scene]") {
    const Mesh sphere = kt::sphere(10, 20, 1.0), grid = kt::grid(4, 4, 2);
    const kt::TreePtr tree = kt::build(sphere, 4);
    const Mesh floor = kt::translated(grid, -2, -2, -10);  // well below everything
    int user_mesh = 0, user_a = 0, user_b = 0;
    const Transform at_origin = to_float(Affine()), beside = to_float(translate(10, 0, 0));
    const Transform moved = to_float(translate(0, 30, 0) * rotate(1, 1, 1, 0.8) * scale(1, 2, 1));
    const Transform moved_again = to_float(translate(0, -30, 0) * scale(-1, 1, 1));
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(1, nullptr), kdrt_instance_geometry(10, tree.get(), at_origin.data()),
                                          kdrt_instance_geometry(20, tree.get(), beside.data())};
    entries[0].mesh = floor.view();
    entries[0].user = &user_mesh, entries[1].user = &user_a, entries[2].user = &user_b;
    entries[1].mask = 6;
    ScenePtr scene = build_scene(entries);

    // The entries as built.
    const kdrt_geometry *g = kdrt_scene_geometry(scene.get(), 10);
    REQUIRE(g != nullptr);
    CHECK(g->type == KDRT_GEOMETRY_INSTANCE);
    CHECK(g->id == 10u);
    CHECK(g->user == &user_a);
    CHECK(g->mask == 6u);
    CHECK(g->tree == tree.get());
    CHECK(std::memcmp(g->transform, at_origin.data(), sizeof g->transform) == 0);
    const kdrt_geometry *m = kdrt_scene_geometry(scene.get(), 1);
    REQUIRE(m != nullptr);
    CHECK(m->type == KDRT_GEOMETRY_MESH);
    CHECK(m->user == &user_mesh);
    CHECK(m->mesh.positions == floor.positions.data());
    CHECK(m->mesh.triangle_count == floor.triangle_count());
    CHECK(kdrt_scene_geometry(scene.get(), 20)->user == &user_b);
    CHECK(kdrt_scene_geometry(scene.get(), 2) == nullptr);
    CHECK(kdrt_scene_geometry(scene.get(), KDRT_INVALID_ID) == nullptr);
    CHECK(kdrt_scene_geometry(nullptr, 10) == nullptr);

    // Up through where instance 10 is, and where it goes.
    const kdrt_ray old_place = kt::ray_of(0.1f, 0.05f, -3, 0, 0, 1), new_place = kt::ray_of(0.1f, 30.05f, -5, 0, 0, 1);
    auto geometry_hit = [&](const kdrt_ray &ray) {
        kdrt_hit h{};
        return kdrt_scene_intersect(scene.get(), &ray, nullptr, &h) ? h.geometry : KDRT_INVALID_ID;
    };
    REQUIRE(geometry_hit(old_place) == 10u);
    REQUIRE(geometry_hit(new_place) == KDRT_INVALID_ID);
    const kdrt_aabb bounds_before = kdrt_scene_bounds(scene.get());

    // Moved: nothing changes until the commit.
    REQUIRE(kdrt_scene_set_transform(scene.get(), 10, moved.data()) == KDRT_SUCCESS);
    CHECK(geometry_hit(old_place) == 10u);
    CHECK(geometry_hit(new_place) == KDRT_INVALID_ID);
    CHECK(std::memcmp(kdrt_scene_geometry(scene.get(), 10)->transform, at_origin.data(), sizeof at_origin) == 0);
    CHECK(same_box(kdrt_scene_bounds(scene.get()), bounds_before));
    REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    CHECK(geometry_hit(old_place) == KDRT_INVALID_ID);
    CHECK(geometry_hit(new_place) == 10u);
    CHECK(std::memcmp(kdrt_scene_geometry(scene.get(), 10)->transform, moved.data(), sizeof moved) == 0);
    CHECK(kdrt_scene_geometry(scene.get(), 10)->user == &user_a);
    CHECK(kdrt_scene_geometry(scene.get(), 10)->mask == 6u);
    CHECK(kdrt_scene_bounds(scene.get()).max[1] > 30.5f);

    // The moved scene answers exactly as one built with the new transforms, and as the world
    // brute force.
    auto compare_with_fresh = [&](const Transform &t10, const Transform &t20) {
        std::vector<kdrt_geometry> now = entries;
        std::memcpy(now[1].transform, t10.data(), sizeof now[1].transform);
        std::memcpy(now[2].transform, t20.data(), sizeof now[2].transform);
        const ScenePtr fresh = build_scene(now);
        CHECK(same_box(kdrt_scene_bounds(scene.get()), kdrt_scene_bounds(fresh.get())));
        World w;
        w.add_mesh(1, floor, kAllBits);
        w.add_instance(10, sphere, t10.data(), 6);
        w.add_instance(20, sphere, t20.data(), kAllBits);
        std::vector<kdrt_ray> rays = kt::random_rays(kdrt_scene_bounds(fresh.get()), 300, 41);
        const std::vector<kdrt_ray> at = aimed_rays(w, {10, 20}, 300, 42);
        rays.insert(rays.end(), at.begin(), at.end());
        CHECK(differences(trace(scene.get(), rays), trace(fresh.get(), rays)) == 0);
        judge_every_hit(scene.get(), w, rays, reference_hits(w, rays));
    };
    compare_with_fresh(moved, beside);

    // Several moves before a commit: the last counts; a commit with nothing to move changes nothing.
    REQUIRE(kdrt_scene_set_transform(scene.get(), 20, at_origin.data()) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_set_transform(scene.get(), 10, at_origin.data()) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_set_transform(scene.get(), 10, moved_again.data()) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    compare_with_fresh(moved_again, at_origin);

    // Refused moves change nothing, the commit after them included.
    const float singular[][12] = {{0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3},    // all zero
                                  {1, 2, 3, 0, 4, 5, 6, 0, 5, 7, 9, 0},    // third row the sum of the others
                                  {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0}};   // flattened in z
    const float not_finite[][12] = {{kNaN, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0},
                                    {1, 0, 0, kInf, 0, 1, 0, 0, 0, 0, 1, 0},
                                    {1, 0, 0, 0, 0, 1, -kInf, 0, 0, 0, 1, 0},
                                    {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, kNaN}};
    const std::vector<kdrt_ray> rays = kt::random_rays(kdrt_scene_bounds(scene.get()), 300, 43);
    const auto before = trace(scene.get(), rays);
    for (const auto *bad : {&singular[0], &singular[1], &singular[2], &not_finite[0], &not_finite[1], &not_finite[2], &not_finite[3]}) {
        INFO("transform " << (*bad)[0] << " " << (*bad)[1] << " ... " << (*bad)[11]);
        CHECK(kdrt_scene_set_transform(scene.get(), 10, *bad) == KDRT_ERROR_INVALID_TRANSFORM);
    }
    CHECK(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    CHECK(differences(trace(scene.get(), rays), before) == 0);
    CHECK(std::memcmp(kdrt_scene_geometry(scene.get(), 10)->transform, moved_again.data(), sizeof moved_again) == 0);
    // A refused move leaves a move made before it to the commit.
    REQUIRE(kdrt_scene_set_transform(scene.get(), 20, beside.data()) == KDRT_SUCCESS);
    CHECK(kdrt_scene_set_transform(scene.get(), 20, singular[1]) == KDRT_ERROR_INVALID_TRANSFORM);
    REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    CHECK(std::memcmp(kdrt_scene_geometry(scene.get(), 20)->transform, beside.data(), sizeof beside) == 0);

    // Only instances move.
    const auto now = trace(scene.get(), rays);
    CHECK(kdrt_scene_set_transform(scene.get(), 1, moved.data()) == KDRT_ERROR_INVALID_GEOMETRY_ID);  // a mesh
    CHECK(kdrt_scene_set_transform(scene.get(), 11, moved.data()) == KDRT_ERROR_INVALID_GEOMETRY_ID);  // no such ID
    CHECK(kdrt_scene_set_transform(scene.get(), KDRT_INVALID_ID, moved.data()) == KDRT_ERROR_INVALID_GEOMETRY_ID);
    CHECK(kdrt_scene_set_transform(nullptr, 10, moved.data()) != KDRT_SUCCESS);
    CHECK(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    CHECK(differences(trace(scene.get(), rays), now) == 0);
}

namespace {

// A scene's entries as they will be after its next commit, with what the world brute force needs
// of each: the mesh, or the object the instance places.
struct Model {
    struct Item {
        kdrt_geometry g;
        const Mesh *shape;
    };
    std::map<uint32_t, Item> items;

    kdrt_geometry mesh(uint32_t id, const Mesh &m) {
        const kdrt_triangles view = m.view();
        kdrt_geometry g = kdrt_mesh_geometry(id, &view);
        items[id] = {g, &m};
        return g;
    }
    kdrt_geometry instance(uint32_t id, const Mesh &object, const kdrt_tree *tree, const Affine &xf) {
        const Transform t = to_float(xf);
        kdrt_geometry g = kdrt_instance_geometry(id, tree, t.data());
        items[id] = {g, &object};
        return g;
    }
    std::vector<kdrt_geometry> entries() const {
        std::vector<kdrt_geometry> e;
        for (const auto &it : items) e.push_back(it.second.g);
        return e;
    }
    // The triangles a query may see: every enabled entry's.
    World world() const {
        World w;
        for (const auto &it : items) {
            const kdrt_geometry &g = it.second.g;
            if (g.flags & KDRT_GEOMETRY_DISABLED) continue;
            if (g.type == KDRT_GEOMETRY_MESH) w.add_mesh(g.id, *it.second.shape, g.mask);
            else w.add_instance(g.id, *it.second.shape, g.transform, g.mask);
        }
        return w;
    }
};

// After a commit: the scene answers bit for bit as one built from the model's entries, and as the
// world brute force; kdrt_scene_geometry names the model's entries and no others.
void check_committed(const kdrt_scene *scene, const Model &model, const std::vector<kdrt_ray> &rays, const std::vector<uint32_t> &ids) {
    const ScenePtr fresh = build_scene(model.entries());
    CHECK(differences(trace(scene, rays), trace(fresh.get(), rays)) == 0);
    CHECK(same_box(kdrt_scene_bounds(scene), kdrt_scene_bounds(fresh.get())));
    const World w = model.world();
    judge_every_hit(scene, w, rays, reference_hits(w, rays));
    for (uint32_t id : ids) {
        INFO("geometry " << id);
        const kdrt_geometry *g = kdrt_scene_geometry(scene, id);
        const auto it = model.items.find(id);
        REQUIRE((g != nullptr) == (it != model.items.end()));
        if (!g) continue;
        CHECK(g->type == it->second.g.type);
        CHECK(g->flags == it->second.g.flags);
        CHECK(g->tree == it->second.g.tree);
        CHECK(std::memcmp(g->transform, it->second.g.transform, sizeof g->transform) == 0);
    }
}

}  // namespace

TEST_CASE("scene: entries attached, detached, disabled and enabled take effect at the commit, and only then", "[scene]") {
    const Mesh ball = kt::sphere(10, 20, 1.5), soup = kt::translated(kt::random_soup(150, 17), -5, -5, -5);
    const Mesh floor = kt::grid(10, 10, 7), globe = kt::translated(kt::sphere(12, 24, 2.0), 5, 5, 5);
    const kt::TreePtr ball_tree = kt::build(ball, 4), soup_tree = kt::build(soup, 4, kt::kBuilders[0]);
    Model model;
    model.mesh(4, floor);
    model.instance(2, ball, ball_tree.get(), translate(3, 4, 5) * rotate(1, 0, 0, 0.5));
    model.instance(17, ball, ball_tree.get(), translate(8, 2, 6) * scale(1.5, 0.7, 1));
    model.instance(5, soup, soup_tree.get(), translate(5, 5, 5) * scale(0.4, 0.4, 0.4));
    ScenePtr scene = build_scene(model.entries());

    // Rays through everything any step below holds: random ones, and ones aimed at each entry.
    World all;
    all.add_mesh(4, floor, kAllBits), all.add_mesh(9, globe, kAllBits);
    const Transform t2 = to_float(translate(3, 4, 5) * rotate(1, 0, 0, 0.5));
    const Transform t17 = to_float(translate(8, 2, 6) * scale(1.5, 0.7, 1));
    const Transform t5 = to_float(translate(5, 5, 5) * scale(0.4, 0.4, 0.4));
    const Transform t40 = to_float(translate(4, 6, 4) * rotate(0, 1, 0, 2) * scale(-0.5, 0.5, 0.5));
    const Transform t41 = to_float(translate(6, 4, 7) * shear(0.4, 0, 0.2));
    all.add_instance(2, ball, t2.data(), kAllBits), all.add_instance(17, ball, t17.data(), kAllBits);
    all.add_instance(5, soup, t5.data(), kAllBits), all.add_instance(40, soup, t40.data(), kAllBits);
    all.add_instance(41, ball, t41.data(), kAllBits);
    std::vector<kdrt_ray> rays = kt::random_rays(all.box(), 300, 61);
    const std::vector<kdrt_ray> aimed = aimed_rays(all, {4, 9, 2, 17, 5, 40, 41}, 400, 62);
    rays.insert(rays.end(), aimed.begin(), aimed.end());
    const std::vector<uint32_t> ids = {2, 4, 5, 9, 17, 40, 41};
    check_committed(scene.get(), model, rays, ids);

    // Each step's changes, then: nothing shows before the commit, everything after it.
    auto step = [&](const char *what, const std::function<void()> &changes) {
        INFO(what);
        const auto before = trace(scene.get(), rays);
        changes();
        CHECK(differences(trace(scene.get(), rays), before) == 0);
        REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
        check_committed(scene.get(), model, rays, ids);
    };
    step("two instances attached, one moved before its first commit", [&] {
        const kdrt_geometry a = model.instance(40, soup, soup_tree.get(), translate(4, 6, 4) * rotate(0, 1, 0, 2) * scale(-0.5, 0.5, 0.5));
        REQUIRE(kdrt_scene_attach(scene.get(), &a) == KDRT_SUCCESS);
        const kdrt_geometry b = model.instance(41, ball, ball_tree.get(), Affine());
        REQUIRE(kdrt_scene_attach(scene.get(), &b) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_set_transform(scene.get(), 41, t41.data()) == KDRT_SUCCESS);
        std::memcpy(model.items[41].g.transform, t41.data(), sizeof t41);
        CHECK(kdrt_scene_geometry(scene.get(), 40) == nullptr);  // not yet
    });
    step("an instance detached, another disabled", [&] {
        REQUIRE(kdrt_scene_detach(scene.get(), 2) == KDRT_SUCCESS);
        model.items.erase(2);
        REQUIRE(kdrt_scene_enable(scene.get(), 17, 0) == KDRT_SUCCESS);
        model.items[17].g.flags = KDRT_GEOMETRY_DISABLED;
    });
    step("enabled again, a mesh disabled", [&] {
        REQUIRE(kdrt_scene_enable(scene.get(), 17, 1) == KDRT_SUCCESS);
        model.items[17].g.flags = 0;
        REQUIRE(kdrt_scene_enable(scene.get(), 4, 0) == KDRT_SUCCESS);
        model.items[4].g.flags = KDRT_GEOMETRY_DISABLED;
    });
    step("a mesh attached (the mesh tree rebuilt), the other enabled", [&] {
        const kdrt_geometry g = model.mesh(9, globe);
        REQUIRE(kdrt_scene_attach(scene.get(), &g) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_enable(scene.get(), 4, 1) == KDRT_SUCCESS);
        model.items[4].g.flags = 0;
    });
    step("a mesh detached; an ID detached and attached again to another tree; moves", [&] {
        REQUIRE(kdrt_scene_detach(scene.get(), 4) == KDRT_SUCCESS);
        model.items.erase(4);
        REQUIRE(kdrt_scene_detach(scene.get(), 40) == KDRT_SUCCESS);
        const kdrt_geometry g = model.instance(40, ball, ball_tree.get(), translate(4, 6, 4) * rotate(0, 1, 0, 2) * scale(-0.5, 0.5, 0.5));
        REQUIRE(kdrt_scene_attach(scene.get(), &g) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_set_transform(scene.get(), 5, t2.data()) == KDRT_SUCCESS);
        std::memcpy(model.items[5].g.transform, t2.data(), sizeof t2);
    });
    step("every instance disabled: the mesh alone", [&] {
        for (uint32_t id : {5u, 17u, 40u, 41u}) {
            REQUIRE(kdrt_scene_enable(scene.get(), id, 0) == KDRT_SUCCESS);
            model.items[id].g.flags = KDRT_GEOMETRY_DISABLED;
        }
    });
    step("attached disabled, then everything enabled", [&] {
        kdrt_geometry g = model.mesh(4, floor);
        g.flags = model.items[4].g.flags = KDRT_GEOMETRY_DISABLED;
        REQUIRE(kdrt_scene_attach(scene.get(), &g) == KDRT_SUCCESS);
        for (uint32_t id : {5u, 17u, 40u, 41u}) {
            REQUIRE(kdrt_scene_enable(scene.get(), id, 1) == KDRT_SUCCESS);
            model.items[id].g.flags = 0;
        }
    });
    step("every entry detached: an empty scene", [&] {
        for (uint32_t id : ids)
            if (model.items.count(id)) REQUIRE(kdrt_scene_detach(scene.get(), id) == KDRT_SUCCESS);
        model.items.clear();
    });
    CHECK(kdrt_scene_bounds(scene.get()).min[0] > kdrt_scene_bounds(scene.get()).max[0]);
    step("and filled again", [&] {
        const kdrt_geometry a = model.mesh(9, globe), b = model.instance(2, ball, ball_tree.get(), translate(3, 4, 5));
        REQUIRE(kdrt_scene_attach(scene.get(), &b) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_attach(scene.get(), &a) == KDRT_SUCCESS);
    });

    // Refused changes change nothing, the commit after them included.
    const auto before = trace(scene.get(), rays);
    kdrt_geometry dup = kdrt_instance_geometry(9, ball_tree.get(), nullptr), bad = dup;
    CHECK(kdrt_scene_attach(scene.get(), &dup) == KDRT_ERROR_INVALID_GEOMETRY_ID);  // 9 is a mesh's
    bad.id = KDRT_INVALID_ID;
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_INVALID_GEOMETRY_ID);
    bad = kdrt_instance_geometry(50, nullptr, nullptr);
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_NULL_ARGUMENT);
    bad = kdrt_instance_geometry(50, ball_tree.get(), nullptr);
    bad.transform[5] = kNaN;
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_INVALID_TRANSFORM);
    bad = kdrt_instance_geometry(50, ball_tree.get(), nullptr);
    bad.transform[0] = bad.transform[5] = bad.transform[10] = 1e38f, bad.transform[3] = 3e38f;  // a box beyond float's range
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_INVALID_TRANSFORM);
    bad = kdrt_instance_geometry(50, ball_tree.get(), nullptr);
    bad.flags = 2;
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_INVALID_OPTION);
    bad.flags = 0, bad.type = kdrt_geometry_type(7);
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_INVALID_OPTION);
    bad = kdrt_mesh_geometry(50, nullptr);
    bad.mesh.triangle_count = 3;  // and no buffers
    CHECK(kdrt_scene_attach(scene.get(), &bad) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_attach(scene.get(), nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_attach(nullptr, &dup) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_detach(scene.get(), 50) == KDRT_ERROR_INVALID_GEOMETRY_ID);
    CHECK(kdrt_scene_detach(nullptr, 9) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_enable(scene.get(), 50, 0) == KDRT_ERROR_INVALID_GEOMETRY_ID);
    CHECK(kdrt_scene_enable(nullptr, 9, 0) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_set_transform(scene.get(), 40, t2.data()) == KDRT_ERROR_INVALID_GEOMETRY_ID);  // detached
    CHECK(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    CHECK(differences(trace(scene.get(), rays), before) == 0);
    check_committed(scene.get(), model, rays, ids);

    // A mesh whose tree cannot be built fails the commit, which leaves the scene as it was and
    // the change pending; detached, the next commit goes through.
    Mesh broken = floor;
    broken.positions[4] = kNaN;
    const kdrt_geometry b = kdrt_mesh_geometry(60, nullptr);
    kdrt_geometry with_nan = b;
    with_nan.mesh = broken.view();
    REQUIRE(kdrt_scene_attach(scene.get(), &with_nan) == KDRT_SUCCESS);
    CHECK(kdrt_scene_commit(scene.get()) == KDRT_ERROR_NON_FINITE_VERTEX);
    CHECK(kdrt_scene_geometry(scene.get(), 60) == nullptr);
    CHECK(differences(trace(scene.get(), rays), before) == 0);
    CHECK(kdrt_scene_commit(scene.get()) == KDRT_ERROR_NON_FINITE_VERTEX);
    REQUIRE(kdrt_scene_detach(scene.get(), 60) == KDRT_SUCCESS);
    CHECK(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
    check_committed(scene.get(), model, rays, ids);
}

TEST_CASE("scene: instances far apart (1e-20 to 1e20) moved, added, removed, disabled and enabled", "[scene]") {
    const Mesh ball = kt::sphere(8, 16, 1.0), field = kt::translated(kt::grid(5, 5, 4), -2.5, -2.5, -1.5);
    const kt::TreePtr ball_tree = kt::build(ball, 4), field_tree = kt::build(field, 4, kt::kBuilders[0]);
    // Each scale's pair of instances, and rays from a few sizes away aimed at them.
    struct Place {
        uint32_t id;
        const Mesh *shape;
        const kdrt_tree *tree;
        Affine xf, moved;
    };
    std::vector<Place> places;
    std::vector<kdrt_ray> rays;
    common::Rng rng(71);
    uint32_t id = 1;
    for (double s : {1e-20, 1e-10, 1.0, 1e10, 1e20}) {
        const V3 at = {3 * s, -2 * s, s};
        places.push_back({id++, &ball, ball_tree.get(), translate(at[0], at[1], at[2]) * scale(s, s, s),
                          translate(at[0] + s, at[1], at[2]) * rotate(1, 2, 3, 0.7) * scale(s, 2 * s, s)});
        places.push_back({id++, &field, field_tree.get(), translate(at[0], at[1] + 2 * s, at[2]) * rotate(0, 1, 1, 1.1) * scale(-s, s, s),
                          translate(at[0], at[1] + 3 * s, at[2]) * shear(0.5, 0.2, -0.6) * scale(s, s, s)});
        for (int i = 0; i < 60; ++i) {
            double d[3], aim[3];
            rng.direction(d), rng.direction(aim);
            const V3 target = {at[0] + 1.5 * s * aim[0], at[1] + 1.5 * s * aim[1], at[2] + 1.5 * s * aim[2]};
            const V3 org = {target[0] - 6 * s * d[0], target[1] - 6 * s * d[1], target[2] - 6 * s * d[2]};
            rays.push_back(kt::ray_of(float(org[0]), float(org[1]), float(org[2]), float(d[0]), float(d[1]), float(d[2])));
        }
    }
    Model model;
    for (size_t i = 0; i < places.size(); i += 2) model.instance(places[i].id, *places[i].shape, places[i].tree, places[i].xf);
    ScenePtr scene = build_scene(model.entries());
    std::vector<uint32_t> ids;
    for (const Place &p : places) ids.push_back(p.id);
    check_committed(scene.get(), model, rays, ids);
    for (int round = 0; round < 3; ++round) {
        INFO("round " << round);
        for (size_t i = 0; i < places.size(); ++i) {
            const Place &p = places[i];
            const auto it = model.items.find(p.id);
            const uint32_t pick = rng.below(4);
            if (it == model.items.end()) {  // add it
                const kdrt_geometry g = model.instance(p.id, *p.shape, p.tree, pick & 1 ? p.moved : p.xf);
                REQUIRE(kdrt_scene_attach(scene.get(), &g) == KDRT_SUCCESS);
            } else if (pick == 0) {  // remove it
                REQUIRE(kdrt_scene_detach(scene.get(), p.id) == KDRT_SUCCESS);
                model.items.erase(it);
            } else if (pick == 1) {  // disable or enable it
                const int enable = (it->second.g.flags & KDRT_GEOMETRY_DISABLED) != 0;
                REQUIRE(kdrt_scene_enable(scene.get(), p.id, enable) == KDRT_SUCCESS);
                it->second.g.flags = enable ? 0u : uint32_t(KDRT_GEOMETRY_DISABLED);
            } else {  // move it
                const Transform t = to_float(pick == 2 ? p.moved : p.xf);
                REQUIRE(kdrt_scene_set_transform(scene.get(), p.id, t.data()) == KDRT_SUCCESS);
                std::memcpy(it->second.g.transform, t.data(), sizeof t);
            }
        }
        REQUIRE(kdrt_scene_commit(scene.get()) == KDRT_SUCCESS);
        check_committed(scene.get(), model, rays, ids);
    }
}

TEST_CASE("scene: the top level is the same on any scheduler, built and committed", "[scene]") {
    // Enough instances that the top level's subtrees and the instances' placing run as tasks.
    const Mesh ball = kt::sphere(4, 8, 1.0);
    const kt::TreePtr tree = kt::build(ball, 4);
    common::Rng rng(81);
    std::vector<kdrt_geometry> entries;
    for (uint32_t i = 0; i < 2500; ++i) {
        const Affine xf = translate(rng.range(0, 60), rng.range(0, 60), rng.range(0, 6)) * rotate(1, 2, 3, rng.range(0, 3)) *
                          scale(0.3, 0.3, rng.range(0.2, 0.8));
        entries.push_back(kdrt_instance_geometry(i * 3 + 1, tree.get(), to_float(xf).data()));
    }
    common::ThreadScheduler threads(3);
    struct Reverse {
        static void run(void *, kdrt_task_fn task, void *data, uint32_t count) {
            for (uint32_t i = count; i-- > 0;) task(data, i);
        }
    };
    kdrt_build_options on_threads = kdrt_default_build_options(), reversed = on_threads;
    on_threads.scheduler = threads.hooks();
    reversed.scheduler = kdrt_scheduler{&Reverse::run, nullptr};
    ScenePtr serial = build_scene(entries), parallel = build_scene(entries, &on_threads), backwards = build_scene(entries, &reversed);
    const std::vector<kdrt_ray> rays = kt::random_rays(kdrt_scene_bounds(serial.get()), 3000, 82);
    auto same_everywhere = [&] {
        const auto expected = trace(serial.get(), rays);
        CHECK(differences(trace(parallel.get(), rays), expected) == 0);
        CHECK(differences(trace(backwards.get(), rays), expected) == 0);
        CHECK(same_box(kdrt_scene_bounds(parallel.get()), kdrt_scene_bounds(serial.get())));
    };
    same_everywhere();
    // Every instance moved, a few detached and disabled.
    for (int round = 0; round < 2; ++round) {
        for (kdrt_geometry &g : entries) {
            Transform t;
            std::memcpy(t.data(), g.transform, sizeof t);
            t[3] += 0.25f, t[7] -= 0.125f;
            std::memcpy(g.transform, t.data(), sizeof t);
            for (const ScenePtr *s : {&serial, &parallel, &backwards}) REQUIRE(kdrt_scene_set_transform(s->get(), g.id, t.data()) == KDRT_SUCCESS);
        }
        for (const ScenePtr *s : {&serial, &parallel, &backwards}) {
            REQUIRE(kdrt_scene_commit(s->get()) == KDRT_SUCCESS);
        }
        same_everywhere();
    }
    for (const ScenePtr *s : {&serial, &parallel, &backwards}) {
        REQUIRE(kdrt_scene_detach(s->get(), entries[10].id) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_enable(s->get(), entries[20].id, 0) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_commit(s->get()) == KDRT_SUCCESS);
    }
    same_everywhere();
    // And against the world brute force, on rays aimed at a few of them.
    World w;
    for (const kdrt_geometry &g : entries)
        if (g.id != entries[10].id && g.id != entries[20].id) w.add_instance(g.id, ball, g.transform, kAllBits);
    std::vector<kdrt_ray> some(rays.begin(), rays.begin() + 150);
    const std::vector<kdrt_ray> aimed = aimed_rays(w, {entries[0].id, entries[500].id, entries[2499].id}, 150, 83);
    some.insert(some.end(), aimed.begin(), aimed.end());
    // These coarse, crowded balls leave more rays near an edge (either answer right) than the
    // other scenes: up to 10% ambiguous.
    const Rules all{"every hit", 0, kAllBits, {}};
    SceneQueries q(parallel.get(), all, &w);
    Judged j;
    judge_queries(q, w, all, some, reference_hits(w, some), j);
    check_judged(j, 0.1);
}

namespace {

// ---- the counting allocator (as test_errors.cpp's) ----

struct CountingAllocator {
    size_t calls = 0, fail_at = 0, frees = 0;  // fail_at: the 1-based call to fail, 0 never
    size_t live_blocks = 0, bad_frees = 0, wrong_user = 0;
    std::map<void *, size_t> blocks;

    kdrt_allocator hooks() {
        kdrt_allocator a;
        a.alloc = &CountingAllocator::alloc_cb, a.free = &CountingAllocator::free_cb, a.user = this;
        return a;
    }
    static CountingAllocator *expected;
    static CountingAllocator *self(void *user) {
        if (user != expected) ++expected->wrong_user;
        return expected;
    }
    static void *alloc_cb(void *user, size_t size) {
        CountingAllocator *c = self(user);
        if (++c->calls == c->fail_at) return nullptr;
        void *p = std::malloc(size ? size : 1);
        if (!p) return nullptr;
        c->blocks[p] = size, ++c->live_blocks;
        return p;
    }
    static void free_cb(void *user, void *ptr) {
        CountingAllocator *c = self(user);
        ++c->frees;
        const auto it = c->blocks.find(ptr);
        if (it == c->blocks.end()) {
            ++c->bad_frees;  // not ours: never free() it
            return;
        }
        --c->live_blocks, c->blocks.erase(it), std::free(ptr);
    }
};
CountingAllocator *CountingAllocator::expected = nullptr;

struct UseCounter {
    explicit UseCounter(CountingAllocator &c) { CountingAllocator::expected = &c; }
    ~UseCounter() { CountingAllocator::expected = nullptr; }
};

kdrt_scene *poison() {
    static int dummy;
    return reinterpret_cast<kdrt_scene *>(&dummy);
}

// kdrt_scene_build with the allocator, *out_scene poisoned first; the result, the scene in *scene.
kdrt_result try_build(const std::vector<kdrt_geometry> &entries, CountingAllocator &counter, kdrt_scene **scene,
                      kdrt_build_report &report, uint32_t flags = 0) {
    kdrt_build_options o = kdrt_default_build_options();
    o.allocator = counter.hooks(), o.flags = flags;
    *scene = poison();
    report.invalid_triangle = report.invalid_geometry = 77;
    return kdrt_scene_build(entries.data(), uint32_t(entries.size()), &o, scene, &report);
}

// A small valid scene: meshes 4 (indexed) and 8 (a soup), instances 6 and 2 of one tree.
struct SmallScene {
    Mesh indexed = kt::grid(6, 6, 5), soup = kt::as_soup(kt::translated(kt::grid(5, 5, 6), 0.5, 0.5, 1));
    Mesh ball = kt::sphere(6, 12, 1.0);
    kt::TreePtr tree = kt::build(ball, 4);
    Transform a = to_float(translate(2, 2, 3)), b = to_float(translate(4, 3, 2) * scale(-1, 0.5, 1));
    std::vector<kdrt_geometry> entries() const {
        std::vector<kdrt_geometry> e = {kdrt_mesh_geometry(4, nullptr), kdrt_instance_geometry(6, tree.get(), a.data()),
                                        kdrt_mesh_geometry(8, nullptr), kdrt_instance_geometry(2, tree.get(), b.data())};
        e[0].mesh = indexed.view(), e[2].mesh = soup.view();
        return e;
    }
};

}  // namespace

TEST_CASE("scene: kdrt_scene_build refuses bad input, names the geometry and frees everything", "[scene][errors]") {
    const SmallScene small;
    CountingAllocator counter;
    UseCounter use(counter);
    kdrt_scene *scene;
    kdrt_build_report report;

    // The valid scene, as a baseline.
    REQUIRE(try_build(small.entries(), counter, &scene, report) == KDRT_SUCCESS);
    REQUIRE(scene != nullptr);
    CHECK(report.invalid_geometry == KDRT_INVALID_ID);
    CHECK(report.invalid_triangle == KDRT_INVALID_ID);
    CHECK(counter.live_blocks > 0);
    kdrt_scene_free(scene);
    CHECK(counter.live_blocks == 0);
    CHECK(counter.frees == counter.calls);

    struct Bad {
        std::string what;
        std::vector<kdrt_geometry> entries;
        kdrt_result result;
        uint32_t geometry, triangle;
    };
    std::vector<Bad> cases;
    auto with = [&](const std::string &what, kdrt_result result, uint32_t geometry, uint32_t triangle,
                    const std::function<void(std::vector<kdrt_geometry> &)> &change) {
        std::vector<kdrt_geometry> e = small.entries();
        change(e);
        cases.push_back({what, e, result, geometry, triangle});
    };
    with("an instance without a tree", KDRT_ERROR_NULL_ARGUMENT, 6, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[1].tree = nullptr; });
    for (int entry = 0; entry < 12; ++entry)
        with("a NaN in the transform at " + std::to_string(entry), KDRT_ERROR_INVALID_TRANSFORM, 2, KDRT_INVALID_ID,
             [entry](std::vector<kdrt_geometry> &e) { e[3].transform[entry] = kNaN; });
    with("an infinite translation", KDRT_ERROR_INVALID_TRANSFORM, 6, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[1].transform[7] = kInf; });
    with("an infinite scale", KDRT_ERROR_INVALID_TRANSFORM, 6, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[1].transform[5] = -kInf; });
    with("an all-zero transform", KDRT_ERROR_INVALID_TRANSFORM, 2, KDRT_INVALID_ID,
         [](std::vector<kdrt_geometry> &e) { std::memset(e[3].transform, 0, sizeof e[3].transform); });
    with("a transform of rank 2", KDRT_ERROR_INVALID_TRANSFORM, 6, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) {
        const float rank2[12] = {1, 2, 3, 0, 4, 5, 6, 0, 5, 7, 9, 0};
        std::memcpy(e[1].transform, rank2, sizeof rank2);
    });
    with("two entries with ID 4", KDRT_ERROR_INVALID_GEOMETRY_ID, 4, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[2].id = 4; });
    with("a mesh and an instance with ID 6", KDRT_ERROR_INVALID_GEOMETRY_ID, 6, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[0].id = 6; });
    with("two instances with ID 2", KDRT_ERROR_INVALID_GEOMETRY_ID, 2, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[1].id = 2; });
    with("ID KDRT_INVALID_ID", KDRT_ERROR_INVALID_GEOMETRY_ID, KDRT_INVALID_ID, KDRT_INVALID_ID,
         [](std::vector<kdrt_geometry> &e) { e[2].id = KDRT_INVALID_ID; });
    for (int type : {2, 7, -1}) {
        with("type " + std::to_string(type), KDRT_ERROR_INVALID_OPTION, 8, KDRT_INVALID_ID, [type](std::vector<kdrt_geometry> &e) {
            std::memcpy(&e[2].type, &type, sizeof type);  // as a C caller could store any int
        });
    }
    // Mesh errors, as kdrt_tree_build names them, the triangle local to the mesh.
    std::vector<uint32_t> out_of_range = small.indexed.indices;
    out_of_range[3 * 5 + 1] = small.indexed.vertex_count();
    with("an index out of range in mesh 4's triangle 5", KDRT_ERROR_INDEX_OUT_OF_RANGE, 4, 5,
         [&](std::vector<kdrt_geometry> &e) { e[0].mesh.indices = out_of_range.data(); });
    std::vector<float> nan_vertex = small.soup.positions;
    nan_vertex[9 * 7 + 4] = kNaN;  // triangle 7's second corner
    with("a NaN in mesh 8's triangle 7", KDRT_ERROR_NON_FINITE_VERTEX, 8, 7,
         [&](std::vector<kdrt_geometry> &e) { e[2].mesh.positions = nan_vertex.data(); });
    with("a stride of 8 bytes", KDRT_ERROR_INVALID_STRIDE, 8, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[2].mesh.position_stride = 8; });
    with("a mesh without positions", KDRT_ERROR_NULL_ARGUMENT, 4, KDRT_INVALID_ID, [](std::vector<kdrt_geometry> &e) { e[0].mesh.positions = nullptr; });

    for (const Bad &c : cases) {
        INFO(c.what);
        counter.calls = counter.frees = 0;
        const kdrt_result r = try_build(c.entries, counter, &scene, report);
        CHECK(kdrt_result_string(r) == std::string(kdrt_result_string(c.result)));
        CHECK(scene == nullptr);
        CHECK(report.invalid_geometry == c.geometry);
        CHECK(report.invalid_triangle == c.triangle);
        if (r == KDRT_SUCCESS) kdrt_scene_free(scene);  // wrongly built: not a leak as well
        CHECK(counter.live_blocks == 0);
        CHECK(counter.bad_frees == 0);
    }
    // The mesh errors are kdrt_tree_build's own, for the mesh alone.
    for (size_t i = cases.size() - 4; i < cases.size(); ++i) {
        const kdrt_triangles view = cases[i].entries[cases[i].geometry == 4 ? 0 : 2].mesh;
        kdrt_tree *tree = nullptr;
        kdrt_build_report tree_report;
        CHECK(kdrt_tree_build(&view, nullptr, &tree, &tree_report) == cases[i].result);
        CHECK(tree_report.invalid_triangle == cases[i].triangle);
        CHECK(tree_report.invalid_geometry == KDRT_INVALID_ID);  // a tree has no geometry
    }

    // Skipping the bad triangles instead: the scene builds, and they are counted.
    std::vector<kdrt_geometry> skipping = small.entries();
    skipping[0].mesh.indices = out_of_range.data(), skipping[2].mesh.positions = nan_vertex.data();
    REQUIRE(try_build(skipping, counter, &scene, report, KDRT_BUILD_SKIP_INVALID_TRIANGLES) == KDRT_SUCCESS);
    CHECK(report.skipped_triangles == 2);
    kdrt_scene_free(scene);

    // Bad calls.
    const std::vector<kdrt_geometry> good = small.entries();
    scene = poison();
    CHECK(kdrt_scene_build(nullptr, 3, nullptr, &scene, &report) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(scene == nullptr);
    CHECK(kdrt_scene_build(good.data(), uint32_t(good.size()), nullptr, nullptr, &report) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_build(good.data(), uint32_t(good.size()), nullptr, nullptr, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    kdrt_build_options bad_builder = kdrt_default_build_options();
    const int builder = 99;
    std::memcpy(&bad_builder.builder, &builder, sizeof builder);
    scene = poison();
    CHECK(kdrt_scene_build(good.data(), uint32_t(good.size()), &bad_builder, &scene, &report) == KDRT_ERROR_INVALID_OPTION);
    CHECK(scene == nullptr);
    CHECK(counter.live_blocks == 0);
    CHECK(counter.wrong_user == 0);
}

TEST_CASE("scene: an instance whose world box leaves float's range is refused, built or moved", "[scene][errors]") {
    // The top level bins and clips instances' world boxes, which must be finite: a tree 1e10
    // across under a scale of 1e30 reaches 1e40; corners within 2^-20 of the largest float are
    // widened past it. Both are refused with the instance named, and a move there changes nothing.
    Mesh wide;
    wide.positions = {-1e10f, -1e10f, 0, 1e10f, -1e10f, 0, 0, 1e10f, 1e10f};
    const kt::TreePtr tree = kt::build(wide, 4);
    const float big[12] = {1e30f, 0, 0, 0, 0, 1e30f, 0, 0, 0, 0, 1e30f, 0};
    const float small[12] = {1e-10f, 0, 0, 5, 0, 1e-10f, 0, 0, 0, 0, 1e-10f, 0};
    const float large[12] = {1e27f, 0, 0, 0, 0, 1e27f, 0, 0, 0, 0, 1e27f, 0};  // 1e37 across: fine
    kdrt_build_report report;
    kdrt_scene *scene = poison();
    const kdrt_geometry overflowing[3] = {kdrt_instance_geometry(1, tree.get(), big), kdrt_instance_geometry(2, tree.get(), big),
                                          kdrt_instance_geometry(3, tree.get(), small)};
    CHECK(kdrt_scene_build(overflowing, 3, nullptr, &scene, &report) == KDRT_ERROR_INVALID_TRANSFORM);
    CHECK(scene == nullptr);
    CHECK(report.invalid_geometry == 1);

    Mesh edge;  // corners at the largest float: finite, but its widened box is not
    const float m = std::numeric_limits<float>::max();
    edge.positions = {-m, -m, 0, m, -m, 0, 0, m, 1};
    const kt::TreePtr edge_tree = kt::build(edge, 4);
    const kdrt_geometry at_the_edge[2] = {kdrt_instance_geometry(7, edge_tree.get(), nullptr),
                                          kdrt_instance_geometry(8, edge_tree.get(), nullptr)};
    scene = poison();
    CHECK(kdrt_scene_build(at_the_edge, 2, nullptr, &scene, &report) == KDRT_ERROR_INVALID_TRANSFORM);
    CHECK(scene == nullptr);
    CHECK(report.invalid_geometry == 7);

    // Within range the same tree builds, its bounds finite, and a move beyond is refused.
    const std::vector<kdrt_geometry> fine = {kdrt_instance_geometry(1, tree.get(), large), kdrt_instance_geometry(3, tree.get(), small)};
    const ScenePtr ok = build_scene(fine);
    const kdrt_aabb bounds = kdrt_scene_bounds(ok.get());
    for (int a = 0; a < 3; ++a) {
        CHECK(std::isfinite(bounds.min[a]));
        CHECK(std::isfinite(bounds.max[a]));
    }
    kdrt_ray down = {{5, 0, 1}, 0, {0, 0, -1}, kInf, 0};  // through instance 3 at z = 0.1
    kdrt_hit hit;
    REQUIRE(kdrt_scene_intersect(ok.get(), &down, nullptr, &hit));
    CHECK(hit.geometry == 3);
    CHECK(kdrt_scene_set_transform(ok.get(), 1, big) == KDRT_ERROR_INVALID_TRANSFORM);
    CHECK(kdrt_scene_commit(ok.get()) == KDRT_SUCCESS);
    CHECK(std::memcmp(kdrt_scene_geometry(ok.get(), 1)->transform, large, sizeof large) == 0);
    CHECK(kdrt_scene_intersect(ok.get(), &down, nullptr, &hit));
    CHECK(hit.geometry == 3);
}

TEST_CASE("scene: a skipped triangle is named by its mesh, a NULL query sees masks, far instances keep their normals", "[scene]") {
    // A successful build that skips a bad triangle names it as a failed one would: the mesh's
    // ID and its own index, not the mesh tree's number across the meshes.
    Mesh a, b;
    a.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    b.positions = {0, 0, 1, 1, 0, 1, 0, 1, 1, kNaN, 0, 1, 1, 0, 1, 0, 1, 1};
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(5, nullptr), kdrt_mesh_geometry(9, nullptr)};
    entries[0].mesh = a.view(), entries[1].mesh = b.view();
    kdrt_build_options skip = kdrt_default_build_options();
    skip.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
    kdrt_scene *raw = nullptr;
    kdrt_build_report report;
    REQUIRE(kdrt_scene_build(entries.data(), 2, &skip, &raw, &report) == KDRT_SUCCESS);
    const ScenePtr skipped(raw);
    CHECK(report.skipped_triangles == 1);
    CHECK(report.invalid_geometry == 9);
    CHECK(report.invalid_triangle == 1);

    // A NULL query is kdrt_default_query(): a mesh of mask 0 is seen by neither.
    entries[0].mask = 0;
    entries.resize(1);
    const ScenePtr masked = build_scene(entries);
    const kdrt_ray down = {{0.25f, 0.25f, 1}, 0, {0, 0, -1}, kInf, 0};
    const kdrt_query plain = kdrt_default_query();
    kdrt_hit hit, k[2];
    for (const kdrt_query *q : {static_cast<const kdrt_query *>(nullptr), &plain}) {
        INFO((q ? "kdrt_default_query()" : "NULL"));
        CHECK_FALSE(kdrt_scene_intersect(masked.get(), &down, q, &hit));
        CHECK_FALSE(kdrt_scene_occluded(masked.get(), &down, q));
        CHECK(kdrt_scene_intersect_k(masked.get(), &down, q, k, 2) == 0);
    }

    // A small ball mirrored and placed at x = 2e30: its world corners lose its shape to rounding,
    // but the normal is the tree's carried by the inverse transpose, unit length.
    const Mesh cube = kt::sphere(4, 6, 1.0);
    const kt::TreePtr tree = kt::build(cube, 4);
    const float far_mirror[12] = {-1, 0, 0, 2e30f, 0, 1, 0, 0, 0, 0, 1, 0};
    const ScenePtr far_away = build_scene({kdrt_instance_geometry(3, tree.get(), far_mirror)});
    for (uint32_t t = 0; t < cube.triangle_count(); ++t) {
        const kdrt_hit on = {0.0f, 0.25f, 0.25f, t, 3, 3, 0};
        float point[3], normal[3], object[3];
        REQUIRE(kdrt_scene_hit_surface(far_away.get(), &on, point, normal));
        REQUIRE(kdrt_hit_surface(tree.get(), &on, nullptr, object));
        INFO("triangle " << t);
        // Mirrored in x: the tree's normal with x negated, and turned with the winding.
        CHECK(normal[0] == object[0]);
        CHECK(normal[1] == -object[1]);
        CHECK(normal[2] == -object[2]);
    }
}

TEST_CASE("scene: kdrt_mesh_geometry and kdrt_instance_geometry fill in the defaults", "[scene]") {
    const Mesh m = kt::grid(2, 2, 1);
    const kdrt_triangles view = m.view();
    const kdrt_geometry g = kdrt_mesh_geometry(17, &view);
    CHECK(g.type == KDRT_GEOMETRY_MESH);
    CHECK(g.id == 17u);
    CHECK(g.mask == kAllBits);
    CHECK(g.user == nullptr);
    CHECK(g.mesh.positions == view.positions);
    CHECK(g.mesh.indices == view.indices);
    CHECK(g.mesh.triangle_count == view.triangle_count);
    const kt::TreePtr tree = kt::build(m, 4);
    const kdrt_geometry i = kdrt_instance_geometry(3, tree.get(), nullptr);
    CHECK(i.type == KDRT_GEOMETRY_INSTANCE);
    CHECK(i.id == 3u);
    CHECK(i.mask == kAllBits);
    CHECK(i.tree == tree.get());
    const Transform identity = to_float(Affine()), moved = to_float(translate(1, 2, 3) * rotate(0, 0, 1, 1));
    CHECK(std::memcmp(i.transform, identity.data(), sizeof i.transform) == 0);
    CHECK(std::memcmp(kdrt_instance_geometry(3, tree.get(), moved.data()).transform, moved.data(), sizeof moved) == 0);
    CHECK(kdrt_default_query().mask == kAllBits);
}

TEST_CASE("scene: allocations are freed, queries allocate nothing, and any one failing is survived", "[scene][errors]") {
    const SmallScene small;
    const std::vector<kdrt_geometry> entries = small.entries();
    const std::vector<kdrt_ray> rays = kt::random_rays(kdrt_aabb{{-1, -1, -1}, {7, 7, 5}}, 300, 51);
    CountingAllocator counter;
    UseCounter use(counter);
    kdrt_scene *scene;
    kdrt_build_report report;

    // Built: the answers to compare with, the allocations of a build, and queries allocate nothing.
    REQUIRE(try_build(entries, counter, &scene, report) == KDRT_SUCCESS);
    const size_t build_calls = counter.calls, live = counter.live_blocks;
    const auto expected = trace(scene, rays);
    size_t hits = 0;
    for (const kdrt_ray &ray : rays) {
        kdrt_hit list[8];
        hits += kdrt_scene_occluded(scene, &ray, nullptr) + kdrt_scene_intersect_k(scene, &ray, nullptr, list, 8);
        float p[3], n[3];
        kdrt_ray out;
        if (kdrt_scene_intersect(scene, &ray, nullptr, list)) {
            kdrt_scene_hit_surface(scene, list, p, n);
            kdrt_scene_spawn_ray(scene, list, ray.dir, &out);
        }
    }
    (void)kdrt_scene_bounds(scene);
    CHECK(hits > rays.size() / 4);
    CHECK(counter.calls == build_calls);
    CHECK(counter.live_blocks == live);
    kdrt_scene_free(scene);
    CHECK(counter.live_blocks == 0);

    // A commit that only moves instances reuses the scene's memory: it allocates nothing.
    const Transform moved = to_float(translate(3, 1, 2) * rotate(1, 0, 1, 0.5));
    REQUIRE(try_build(entries, counter, &scene, report) == KDRT_SUCCESS);
    const size_t live_built = counter.live_blocks;
    REQUIRE(kdrt_scene_set_transform(scene, 6, moved.data()) == KDRT_SUCCESS);
    counter.calls = 0;
    REQUIRE(kdrt_scene_commit(scene) == KDRT_SUCCESS);
    CHECK(counter.calls == 0);
    CHECK(counter.live_blocks == live_built);
    const auto expected_moved = trace(scene, rays);
    CHECK(differences(expected_moved, expected) > 0);  // the move shows
    kdrt_scene_free(scene);
    CHECK(counter.live_blocks == 0);

    // One that also attaches an instance, detaches a mesh and disables an instance allocates.
    const Transform third = to_float(translate(1, 5, 2) * scale(0.5, 0.5, 2));
    const kdrt_geometry attached = kdrt_instance_geometry(9, small.tree.get(), third.data());
    auto change = [&](kdrt_scene *s) {
        REQUIRE(kdrt_scene_set_transform(s, 6, moved.data()) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_attach(s, &attached) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_detach(s, 8) == KDRT_SUCCESS);
        REQUIRE(kdrt_scene_enable(s, 2, 0) == KDRT_SUCCESS);
    };
    REQUIRE(try_build(entries, counter, &scene, report) == KDRT_SUCCESS);
    change(scene);
    counter.calls = 0;
    REQUIRE(kdrt_scene_commit(scene) == KDRT_SUCCESS);
    const size_t commit_calls = counter.calls;
    const auto expected_changed = trace(scene, rays);
    CHECK(differences(expected_changed, expected_moved) > 0);
    kdrt_scene_free(scene);
    CHECK(counter.live_blocks == 0);
    INFO("a build makes " << build_calls << " allocations, a commit " << commit_calls);
    REQUIRE(build_calls > 0);
    REQUIRE(commit_calls > 0);

    // Failing each allocation of the build in turn: out of memory and nothing left, unless the
    // allocation was one a build may do without (shrinking an array to size), when the scene
    // must answer as usual.
    size_t survived = 0, mismatched = 0;
    for (size_t k = 1; k <= build_calls; ++k) {
        counter.calls = 0, counter.fail_at = k;
        const kdrt_result r = try_build(entries, counter, &scene, report);
        counter.fail_at = 0;
        INFO("failing allocation " << k << " of the build: " << kdrt_result_string(r));
        if (r == KDRT_SUCCESS) {
            ++survived;
            mismatched += differences(trace(scene, rays), expected);
            kdrt_scene_free(scene);
        } else {
            CHECK(r == KDRT_ERROR_OUT_OF_MEMORY);
            CHECK(scene == nullptr);
        }
        CHECK(counter.live_blocks == 0);
        CHECK(counter.bad_frees == 0);
        if (counter.live_blocks != 0) break;  // one report is enough
    }
    CHECK(mismatched == 0);
    CHECK(survived <= 4);

    // Failing each allocation of the commit: out of memory, the scene answering as before the
    // changes and holding what it held, the changes still pending for the next commit; a commit
    // may do without the same kind as a build (its mesh tree is rebuilt).
    size_t commit_survived = 0;
    for (size_t k = 1; k <= commit_calls; ++k) {
        REQUIRE(try_build(entries, counter, &scene, report) == KDRT_SUCCESS);
        REQUIRE(counter.live_blocks == live_built);
        change(scene);
        counter.calls = 0, counter.fail_at = k;
        const kdrt_result r = kdrt_scene_commit(scene);
        counter.fail_at = 0;
        INFO("failing allocation " << k << " of the commit: " << kdrt_result_string(r));
        if (r == KDRT_SUCCESS) {
            ++commit_survived;
            CHECK(differences(trace(scene, rays), expected_changed) == 0);
        } else {
            CHECK(r == KDRT_ERROR_OUT_OF_MEMORY);
            CHECK(differences(trace(scene, rays), expected) == 0);
            CHECK(std::memcmp(kdrt_scene_geometry(scene, 6)->transform, small.a.data(), sizeof small.a) == 0);
            CHECK(kdrt_scene_geometry(scene, 9) == nullptr);
            CHECK(kdrt_scene_geometry(scene, 8) != nullptr);
            CHECK(kdrt_scene_geometry(scene, 2)->flags == 0u);
            // The changes are still there for the next commit.
            REQUIRE(kdrt_scene_commit(scene) == KDRT_SUCCESS);
            CHECK(differences(trace(scene, rays), expected_changed) == 0);
        }
        kdrt_scene_free(scene);
        CHECK(counter.live_blocks == 0);
        CHECK(counter.bad_frees == 0);
        if (counter.live_blocks != 0) break;
    }
    CHECK(commit_survived <= 4);
    CHECK(counter.wrong_user == 0);
    WARN("failing each allocation: a scene build makes " << build_calls << " (" << survived << " survived failing), a commit "
                                                         << commit_calls << " (" << commit_survived << ")");
}

TEST_CASE("scene: empty scenes, one mesh, instances only, and NULL arguments", "[scene][errors]") {
    const kdrt_ray ray = kt::ray_of(0.3f, 0.2f, -5, 0, 0, 1);
    kdrt_hit hit{};
    kdrt_hit list[4];
    for (bool null_entries : {true, false}) {
        INFO((null_entries ? "NULL entries" : "no entries"));
        const kdrt_geometry unused = kdrt_mesh_geometry(1, nullptr);
        kdrt_scene *raw = poison();
        kdrt_build_report report;
        REQUIRE(kdrt_scene_build(null_entries ? nullptr : &unused, 0, nullptr, &raw, &report) == KDRT_SUCCESS);
        const ScenePtr empty(raw);
        REQUIRE(raw != nullptr);
        CHECK(same_box(kdrt_scene_bounds(empty.get()), kdrt_aabb_empty()));
        hit.triangle = 5;
        CHECK(kdrt_scene_intersect(empty.get(), &ray, nullptr, &hit) == 0);
        CHECK(hit.triangle == KDRT_INVALID_ID);
        CHECK(kdrt_scene_occluded(empty.get(), &ray, nullptr) == 0);
        CHECK(kdrt_scene_intersect_k(empty.get(), &ray, nullptr, list, 4) == 0);
        CHECK(kdrt_scene_geometry(empty.get(), 1) == nullptr);
        CHECK(kdrt_scene_commit(empty.get()) == KDRT_SUCCESS);
        const kdrt_hit made_up{1.0f, 0.2f, 0.2f, 0, 1, KDRT_INVALID_ID, 0};
        float p[3] = {-7, -7, -7};
        CHECK(kdrt_scene_hit_surface(empty.get(), &made_up, p, nullptr) == 0);
        CHECK(p[0] == -7.0f);
        kdrt_ray out;
        CHECK(kdrt_scene_spawn_ray(empty.get(), &made_up, ray.dir, &out) == 0);
    }

    // One mesh; and the same triangle as the only instance.
    Mesh tri;
    tri.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const kt::TreePtr tree = kt::build(tri, 4);
    const kdrt_triangles view = tri.view();
    const Transform lifted = to_float(translate(0, 0, 1));
    for (const kdrt_geometry &g : {kdrt_mesh_geometry(3, &view), kdrt_instance_geometry(3, tree.get(), lifted.data())}) {
        const bool instance = g.type == KDRT_GEOMETRY_INSTANCE;
        INFO((instance ? "one instance" : "one mesh"));
        const ScenePtr scene = build_scene({g});
        REQUIRE(kdrt_scene_intersect(scene.get(), &ray, nullptr, &hit) == 1);
        CHECK(hit.geometry == 3u);
        CHECK(hit.instance == (instance ? 3u : KDRT_INVALID_ID));
        CHECK(hit.triangle == 0u);
        CHECK(hit.t == Approx(instance ? 6.0f : 5.0f).epsilon(1e-6));
        CHECK(hit.u == Approx(0.3f));
        CHECK(hit.v == Approx(0.2f));
        const kdrt_aabb box = kdrt_scene_bounds(scene.get());
        CHECK(box.min[2] <= (instance ? 1.0f : 0.0f));
        CHECK(box.max[2] >= (instance ? 1.0f : 0.0f));
        // Made-up hits: an unknown geometry, a triangle out of range, a miss.
        float p[3] = {-7, -7, -7}, n[3];
        kdrt_ray out;
        kdrt_hit bad = hit;
        bad.geometry = 4;
        CHECK(kdrt_scene_hit_surface(scene.get(), &bad, p, n) == 0);
        CHECK(kdrt_scene_spawn_ray(scene.get(), &bad, ray.dir, &out) == 0);
        bad = hit, bad.triangle = 1;
        CHECK(kdrt_scene_hit_surface(scene.get(), &bad, p, n) == 0);
        bad = hit, bad.triangle = KDRT_INVALID_ID;
        CHECK(kdrt_scene_hit_surface(scene.get(), &bad, p, n) == 0);
        CHECK(p[0] == -7.0f);
        // Rays that can hit nothing.
        for (const kdrt_ray &r : {kt::ray_of(kNaN, 0.2f, -5, 0, 0, 1), kt::ray_of(0.3f, 0.2f, -5, 0, 0, 0),
                                  kt::ray_of(0.3f, 0.2f, -5, 0, kInf, 1), kt::ray_of(0.3f, 0.2f, -5, 0, 0, 1, 7, 3),
                                  kt::ray_of(0.3f, 0.2f, -5, 0, 0, 1, kNaN), kt::ray_of(0.3f, 0.2f, -5, 0, 0, 1, 0, 4)}) {
            INFO(show(r));
            CHECK(kdrt_scene_intersect(scene.get(), &r, nullptr, &hit) == 0);
            CHECK(kdrt_scene_occluded(scene.get(), &r, nullptr) == 0);
            CHECK(kdrt_scene_intersect_k(scene.get(), &r, nullptr, list, 4) == 0);
        }

        // NULL arguments give 0 and write nothing they should not.
        const kdrt_query q = kdrt_default_query();
        hit.triangle = 5;
        CHECK(kdrt_scene_intersect(nullptr, &ray, &q, &hit) == 0);
        CHECK(hit.triangle == KDRT_INVALID_ID);
        CHECK(kdrt_scene_intersect(scene.get(), nullptr, &q, &hit) == 0);
        CHECK(kdrt_scene_intersect(scene.get(), &ray, &q, nullptr) == 0);
        CHECK(kdrt_scene_occluded(nullptr, &ray, &q) == 0);
        CHECK(kdrt_scene_occluded(scene.get(), nullptr, &q) == 0);
        list[0].triangle = 77;
        CHECK(kdrt_scene_intersect_k(nullptr, &ray, &q, list, 4) == 0);
        CHECK(kdrt_scene_intersect_k(scene.get(), nullptr, &q, list, 4) == 0);
        CHECK(kdrt_scene_intersect_k(scene.get(), &ray, &q, nullptr, 4) == 0);
        CHECK(kdrt_scene_intersect_k(scene.get(), &ray, &q, list, 0) == 0);
        CHECK(list[0].triangle == 77u);
        REQUIRE(kdrt_scene_intersect(scene.get(), &ray, nullptr, &hit) == 1);
        CHECK(kdrt_scene_hit_surface(nullptr, &hit, p, n) == 0);
        CHECK(kdrt_scene_hit_surface(scene.get(), nullptr, p, n) == 0);
        CHECK(kdrt_scene_hit_surface(scene.get(), &hit, nullptr, nullptr) == 1);
        CHECK(kdrt_scene_spawn_ray(nullptr, &hit, ray.dir, &out) == 0);
        CHECK(kdrt_scene_spawn_ray(scene.get(), nullptr, ray.dir, &out) == 0);
    }
    kdrt_scene_free(nullptr);  // fine
}
