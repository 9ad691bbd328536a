#include "oracle/hard_cases.hpp"
#include "common/random.hpp"
#include "common/timing.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <unordered_map>

#ifndef KDRT_MESH_DIR
#define KDRT_MESH_DIR ""
#endif

namespace oracle {

using common::Mesh;
using common::Rng;

namespace {

const float kInf = std::numeric_limits<float>::infinity();
const double kPi = 3.14159265358979323846;


double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void cross(const double a[3], const double b[3], double out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1], out[1] = a[2] * b[0] - a[0] * b[2], out[2] = a[0] * b[1] - a[1] * b[0];
}
double norm(const double a[3]) { return std::sqrt(dot(a, a)); }

kdrt_ray make_ray(const double o[3], const double d[3], float tmin = 0.0f, float tmax = kInf) {
    kdrt_ray r{};
    for (int a = 0; a < 3; ++a) r.org[a] = float(o[a]), r.dir[a] = float(d[a]);
    r.tmin = tmin, r.tmax = tmax;
    return r;
}

struct Box {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    void grow(const double p[3]) {
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    }
    double diagonal() const {
        double s = 0;
        for (int a = 0; a < 3; ++a) s += (hi[a] - lo[a]) * (hi[a] - lo[a]);
        return std::sqrt(s);
    }
};

Box box_of(const Mesh &m) {
    Box b;
    for (size_t i = 0; i + 2 < m.positions.size(); i += 3) {
        const double p[3] = {m.positions[i], m.positions[i + 1], m.positions[i + 2]};
        b.grow(p);
    }
    return b;
}

bool is_integer_mesh(const Mesh &m) {
    for (float x : m.positions)
        if (x != std::floor(x) || std::fabs(x) > 1e6f) return false;
    return true;
}

// ---- generated closed meshes ----


// The octahedron |x| + |y| + |z| = n, each face cut into n^2 triangles with integer corners: a
// closed mesh whose faces are tilted planes.
Mesh int_octahedron(int n) {
    Mesh m;
    m.name = "int_octahedron_" + std::to_string(n);
    std::unordered_map<int64_t, uint32_t> ids;
    auto vertex = [&](int x, int y, int z) {
        int64_t key = (int64_t(x + 1024) << 22) | (int64_t(y + 1024) << 11) | int64_t(z + 1024);
        auto found = ids.find(key);
        if (found != ids.end()) return found->second;
        uint32_t id = m.vertex_count();
        m.positions.insert(m.positions.end(), {float(x), float(y), float(z)});
        ids.emplace(key, id);
        return id;
    };
    for (int sx : {1, -1})
        for (int sy : {1, -1})
            for (int sz : {1, -1}) {
                // Face points (i, j, n - i - j) times the signs; outward winding for an even number of minus signs.
                bool flip = (sx * sy * sz) < 0;
                auto v = [&](int i, int j) { return vertex(sx * i, sy * j, sz * (n - i - j)); };
                for (int i = 0; i < n; ++i)
                    for (int j = 0; i + j < n; ++j) {
                        uint32_t a = v(i, j), b = v(i + 1, j), c = v(i, j + 1);
                        if (flip) std::swap(b, c);
                        m.indices.insert(m.indices.end(), {a, b, c});
                        if (i + j + 1 < n) {
                            uint32_t d = v(i + 1, j + 1);
                            uint32_t e = v(i + 1, j), f = v(i, j + 1);
                            if (flip) std::swap(e, f);
                            m.indices.insert(m.indices.end(), {e, d, f});
                        }
                    }
            }
    return m;
}

// The surface of the box [0, n]^3 on a unit grid, with the grid points inside each face pushed out
// by 0, 1 or 2: a closed, non-convex mesh with integer corners and many coplanar triangles.
Mesh int_bumpy_box(int n, uint64_t seed) {
    Rng rng(seed);
    Mesh m;
    m.name = "int_bumpy_box_" + std::to_string(n);
    std::unordered_map<int64_t, uint32_t> ids;  // by grid point (on the box, before pushing)
    auto vertex = [&](int p[3]) {
        int64_t key = (int64_t(p[0] + 64) << 16) | (int64_t(p[1] + 64) << 8) | int64_t(p[2] + 64);
        auto found = ids.find(key);
        if (found != ids.end()) return found->second;
        uint32_t id = m.vertex_count();
        float q[3] = {float(p[0]), float(p[1]), float(p[2])};
        // Strictly inside a face (exactly one coordinate at 0 or n): push along that face's normal.
        int on = 0, axis = -1;
        for (int a = 0; a < 3; ++a)
            if (p[a] == 0 || p[a] == n) ++on, axis = a;
        if (on == 1) q[axis] += float(p[axis] == 0 ? -1 : 1) * float(rng.below(3));
        m.positions.insert(m.positions.end(), {q[0], q[1], q[2]});
        ids.emplace(key, id);
        return id;
    };
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            int b = (axis + 1) % 3, c = (axis + 2) % 3;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    int p00[3], p10[3], p01[3], p11[3];
                    for (int *p : {p00, p10, p01, p11}) p[axis] = side * n;
                    p00[b] = i, p00[c] = j, p10[b] = i + 1, p10[c] = j, p01[b] = i, p01[c] = j + 1, p11[b] = i + 1, p11[c] = j + 1;
                    uint32_t a0 = vertex(p00), a1 = vertex(p10), a2 = vertex(p01), a3 = vertex(p11);
                    // Outward: (b x c) is +axis, so side 0 reverses the winding.
                    bool alt = (i + j) % 2 == 0;  // alternate the diagonal
                    uint32_t t[6];
                    if (alt) t[0] = a0, t[1] = a1, t[2] = a3, t[3] = a0, t[4] = a3, t[5] = a2;
                    else t[0] = a0, t[1] = a1, t[2] = a2, t[3] = a1, t[4] = a3, t[5] = a2;
                    if (side == 0) std::swap(t[1], t[2]), std::swap(t[4], t[5]);
                    m.indices.insert(m.indices.end(), t, t + 6);
                }
        }
    return m;
}

// ---- double-precision geometry over a whole mesh ----

struct Geometry {
    std::vector<double> tri;  // p0, e1, e2 per triangle
    explicit Geometry(const Mesh &m) {
        tri.resize(size_t(m.triangle_count()) * 9);
        for (uint32_t t = 0; t < m.triangle_count(); ++t) {
            double p[3][3];
            m.corners(t, p);
            for (int a = 0; a < 3; ++a) {
                tri[t * 9 + a] = p[0][a];
                tri[t * 9 + 3 + a] = p[1][a] - p[0][a];
                tri[t * 9 + 6 + a] = p[2][a] - p[0][a];
            }
        }
    }
    size_t size() const { return tri.size() / 9; }

    // Crossings of the half-line o + t d (t > 0) with the surface, mod 2; -1 when the half-line
    // passes too near an edge or vertex to tell.
    int parity(const double o[3], const double d[3]) const {
        int crossings = 0;
        for (size_t i = 0; i < size(); ++i) {
            const double *p0 = &tri[i * 9], *e1 = p0 + 3, *e2 = p0 + 6;
            double pv[3], tv[3], qv[3];
            cross(d, e2, pv);
            double det = dot(e1, pv);
            double scale = norm(e1) * norm(e2);
            if (std::fabs(det) <= 1e-12 * scale) continue;  // parallel (a random direction never lies in the plane)
            for (int a = 0; a < 3; ++a) tv[a] = o[a] - p0[a];
            double u = dot(tv, pv) / det;
            if (u < -1e-9 || u > 1 + 1e-9) continue;
            cross(tv, e1, qv);
            double v = dot(d, qv) / det, t = dot(e2, qv) / det;
            if (v < -1e-9 || u + v > 1 + 1e-9) continue;
            if (t <= 0) continue;
            if (u < 1e-9 || v < 1e-9 || u + v > 1 - 1e-9) return -1;
            ++crossings;
        }
        return crossings & 1;
    }

    // Distance from q to the nearest triangle (Ericson, Real-Time Collision Detection 5.1.5).
    double distance(const double q[3]) const {
        double best = 1e300;
        for (size_t i = 0; i < size(); ++i) {
            const double *a = &tri[i * 9], *ab = a + 3, *ac = a + 6;
            double ap[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
            double d1 = dot(ab, ap), d2 = dot(ac, ap), s, t;
            double bp[3] = {ap[0] - ab[0], ap[1] - ab[1], ap[2] - ab[2]};
            double d3 = dot(ab, bp), d4 = dot(ac, bp);
            double cp[3] = {ap[0] - ac[0], ap[1] - ac[1], ap[2] - ac[2]};
            double d5 = dot(ab, cp), d6 = dot(ac, cp);
            double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
            if (d1 <= 0 && d2 <= 0) s = 0, t = 0;
            else if (d3 >= 0 && d4 <= d3) s = 1, t = 0;
            else if (d6 >= 0 && d5 <= d6) s = 0, t = 1;
            else if (vc <= 0 && d1 >= 0 && d3 <= 0) s = d1 / (d1 - d3), t = 0;
            else if (vb <= 0 && d2 >= 0 && d6 <= 0) s = 0, t = d2 / (d2 - d6);
            else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
                double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
                s = 1 - w, t = w;
            } else {
                double denom = 1 / (va + vb + vc);
                s = vb * denom, t = vc * denom;
            }
            double c[3];
            for (int k = 0; k < 3; ++k) c[k] = a[k] + s * ab[k] + t * ac[k] - q[k];
            best = std::min(best, dot(c, c));
        }
        return std::sqrt(best);
    }

    // Strictly inside by three agreeing parity tests in random directions.
    bool inside(const double q[3], Rng &rng) const {
        int agree = 0;
        for (int attempt = 0; attempt < 8 && agree < 3; ++attempt) {
            double d[3];
            rng.direction(d);
            int p = parity(q, d);
            if (p == 0) return false;
            if (p == 1) ++agree;
        }
        return agree == 3;
    }
};

// Points well inside a closed mesh: near its triangles on either side, and anywhere in its box.
std::vector<std::array<double, 3>> inside_points(const Mesh &m, const Geometry &g, size_t want, Rng &rng) {
    const bool integer = is_integer_mesh(m);
    const Box box = box_of(m);
    const double diag = box.diagonal();
    const double clearance = std::max(1e-4 * diag, integer ? 0.25 : 0.0);
    std::vector<std::array<double, 3>> points;
    for (int attempt = 0; attempt < 4000 && points.size() < want; ++attempt) {
        double q[3];
        if (attempt % 3 == 2) {
            for (int a = 0; a < 3; ++a) q[a] = rng.range(box.lo[a], box.hi[a]);
        } else {
            size_t t = rng.below(uint32_t(g.size()));
            const double *p0 = &g.tri[t * 9], *e1 = p0 + 3, *e2 = p0 + 6;
            double n[3];
            cross(e1, e2, n);
            double len = norm(n), size = std::sqrt(0.5 * len);
            double step = (attempt % 2 ? 1 : -1) * rng.range(0.5, 3.0) * std::max(size, 2 * clearance) / len;
            for (int a = 0; a < 3; ++a) q[a] = p0[a] + (e1[a] + e2[a]) / 3 + step * n[a];
        }
        if (integer)
            for (double &x : q) x = std::round(x);
        for (double &x : q) x = double(float(x));
        if (g.distance(q) < clearance || !g.inside(q, rng)) continue;
        points.push_back({q[0], q[1], q[2]});
    }
    return points;
}

// ---- spawned rays ----

void reflect(const float d[3], const float n[3], double out[3]) {
    double dn = double(d[0]) * n[0] + double(d[1]) * n[1] + double(d[2]) * n[2];
    for (int a = 0; a < 3; ++a) out[a] = d[a] - 2 * dn * n[a];
}

// A direction at `degrees` to the surface with unit normal n, on the side `side` (+1: along n),
// heading the way d runs along the surface.
void grazing(const float d[3], const float n[3], double degrees, double side, double out[3]) {
    double dn = double(d[0]) * n[0] + double(d[1]) * n[1] + double(d[2]) * n[2];
    double t[3] = {d[0] - dn * n[0], d[1] - dn * n[1], d[2] - dn * n[2]};
    double len = norm(t);
    if (!(len > 1e-6 * std::sqrt(double(d[0]) * d[0] + double(d[1]) * d[1] + double(d[2]) * d[2]))) {
        // d along the normal: any tangent will do
        double axis[3] = {std::fabs(n[0]) < 0.6 ? 1.0 : 0.0, std::fabs(n[0]) < 0.6 ? 0.0 : 1.0, 0.0};
        double nd[3] = {n[0], n[1], n[2]};
        cross(nd, axis, t);
        len = norm(t);
    }
    double c = std::cos(degrees * kPi / 180), s = std::sin(degrees * kPi / 180);
    for (int a = 0; a < 3; ++a) out[a] = c * t[a] / len + side * s * n[a];
}

std::string describe(const kdrt_ray &r) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "org=(%.9g, %.9g, %.9g) dir=(%.9g, %.9g, %.9g) tmin=%.9g tmax=%.9g", r.org[0], r.org[1],
                  r.org[2], r.dir[0], r.dir[1], r.dir[2], r.tmin, r.tmax);
    return buf;
}

// ---- hard sets ----

Mesh height_grid(uint32_t nx, uint32_t ny, Rng &rng) {
    Mesh m;
    m.name = "grid";
    for (uint32_t y = 0; y <= ny; ++y)
        for (uint32_t x = 0; x <= nx; ++x) m.positions.insert(m.positions.end(), {float(x), float(y), float(rng.below(4))});
    for (uint32_t y = 0; y < ny; ++y)
        for (uint32_t x = 0; x < nx; ++x) {
            uint32_t a = y * (nx + 1) + x, b = a + 1, c = a + nx + 1, d = c + 1;
            m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
        }
    return m;
}

Mesh soup(uint32_t triangles, double extent, double size, Rng &rng) {
    Mesh m;
    m.name = "soup";
    for (uint32_t i = 0; i < triangles; ++i) {
        double c[3] = {rng.range(0, extent), rng.range(0, extent), rng.range(0, extent)};
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) m.positions.push_back(float(c[a] + rng.range(-0.5, 0.5) * size));
    }
    return m;
}

void add_triangle(Mesh &m, const double p[3][3]) {
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) m.positions.push_back(float(p[k][a]));
}

// Random rays through the scene's box: from inside in any direction, or from outside aimed at a
// point inside.
void add_random_rays(std::vector<kdrt_ray> &rays, const Box &box, size_t count, Rng &rng) {
    double c[3], ext[3], diag = std::max(box.diagonal(), 1e-3);
    for (int a = 0; a < 3; ++a) c[a] = 0.5 * (box.lo[a] + box.hi[a]), ext[a] = std::max(box.hi[a] - box.lo[a], 0.02 * diag);
    for (size_t i = 0; i < count; ++i) {
        double o[3], d[3];
        if (i % 2 == 0) {
            for (int a = 0; a < 3; ++a) o[a] = c[a] + rng.range(-0.55, 0.55) * ext[a];
            rng.direction(d);
        } else {
            double u[3];
            rng.direction(u);
            for (int a = 0; a < 3; ++a) o[a] = c[a] + u[a] * diag, d[a] = c[a] + rng.range(-0.5, 0.5) * ext[a] - o[a];
        }
        rays.push_back(make_ray(o, d));
    }
}

// Every plane the median builder can split at (the float centroid coordinate of a triangle, as
// kdrt.h computes it), and every vertex coordinate plane (where a SAH builder splits).
std::vector<std::vector<float>> candidate_planes(const Mesh &m) {
    std::vector<std::set<float>> planes(3);
    for (uint32_t t = 0; t < m.triangle_count(); ++t) {
        double pd[3][3];
        m.corners(t, pd);
        for (int a = 0; a < 3; ++a) {
            float p0 = float(pd[0][a]), p1 = float(pd[1][a]), p2 = float(pd[2][a]);
            float sum = p0 + p1;
            sum = sum + p2;
            float c = sum * (1.0f / 3.0f);
            c = std::min(std::max(c, std::min({p0, p1, p2})), std::max({p0, p1, p2}));
            planes[a].insert(c);
            planes[a].insert(p0), planes[a].insert(p1), planes[a].insert(p2);
        }
    }
    std::vector<std::vector<float>> out(3);
    for (int a = 0; a < 3; ++a) out[a].assign(planes[a].begin(), planes[a].end());
    return out;
}

HardSet split_plane_set(const std::string &name, const Mesh &mesh, size_t count, Rng &rng) {
    HardSet set{name, mesh, {}};
    const Box box = box_of(mesh);
    const auto planes = candidate_planes(mesh);
    double c[3];
    for (int a = 0; a < 3; ++a) c[a] = 0.5 * (box.lo[a] + box.hi[a]);
    for (size_t i = 0; i < count; ++i) {
        int a = int(i % 3), b = (a + 1) % 3, cc = (a + 2) % 3;
        if (planes[a].empty()) continue;
        double o[3], d[3] = {0, 0, 0};
        o[a] = planes[a][rng.below(uint32_t(planes[a].size()))];
        o[b] = rng.range(box.lo[b] - 1, box.hi[b] + 1);
        o[cc] = rng.range(box.lo[cc] - 1, box.hi[cc] + 1);
        switch ((i / 3) % 6) {
        case 0: d[b] = rng.uniform() < 0.5 ? 1 : -1; break;                  // along an axis in the plane
        case 1: d[cc] = rng.uniform() < 0.5 ? 1 : -1; break;
        case 2: d[b] = c[b] - o[b], d[cc] = c[cc] - o[cc]; break;           // towards the middle
        case 3: d[b] = rng.range(-1, 1), d[cc] = rng.range(-1, 1); break;   // anywhere in the plane
        default:                                                               // crossing it from a point on it
            d[a] = rng.range(-1, 1), d[b] = rng.range(-1, 1), d[cc] = rng.range(-1, 1);
            break;
        }
        kdrt_ray r = make_ray(o, d);
        if (d[a] == 0 && (i / 18) % 2) r.dir[a] = -0.0f;
        set.rays.push_back(r);
    }
    return set;
}

// Axis-parallel rays on a lattice over the box (both directions of every axis, every +-0
// combination of the other two components, starting outside the box and in its middle), at most
// `limit` of them, drawn at random from the whole lattice.
void add_axis_rays(std::vector<kdrt_ray> &rays, const Box &box, double step, double margin, double offset, size_t limit) {
    std::vector<kdrt_ray> all;
    for (int a = 0; a < 3; ++a)
        for (float s : {1.0f, -1.0f})
            for (int zeros = 0; zeros < 4; ++zeros) {
                int b = (a + 1) % 3, c = (a + 2) % 3;
                for (double pb = box.lo[b] - margin + offset; pb <= box.hi[b] + margin; pb += step)
                    for (double pc = box.lo[c] - margin + offset; pc <= box.hi[c] + margin; pc += step)
                        for (int start = 0; start < 2; ++start) {
                            kdrt_ray r{};
                            r.dir[a] = s, r.dir[b] = (zeros & 1) ? -0.0f : 0.0f, r.dir[c] = (zeros & 2) ? -0.0f : 0.0f;
                            r.org[b] = float(pb), r.org[c] = float(pc);
                            r.org[a] = float(start == 0 ? (s > 0 ? box.lo[a] - 1 : box.hi[a] + 1) : 0.5 * (box.lo[a] + box.hi[a]));
                            r.tmin = 0, r.tmax = kInf;
                            all.push_back(r);
                        }
            }
    const size_t take = std::min(limit, all.size());
    Rng rng(all.size());
    for (size_t k = 0; k < take; ++k) {  // a partial Fisher-Yates shuffle
        std::swap(all[k], all[k + rng.below(uint32_t(all.size() - k))]);
        rays.push_back(all[k]);
    }
}

HardSet axis_parallel_set(size_t count, Rng &rng) {
    // A 12 x 12 integer grid (lattice step 0.25: through vertices, edges and diagonals) and a
    // sphere beside it (lattice offset by 1/32 so no ray runs along a silhouette, where a tangent
    // ray's t is ill-conditioned).
    Mesh grid = height_grid(12, 12, rng);
    Mesh ball = uv_sphere(10, 16, 3.0, false);
    for (size_t i = 0; i < ball.positions.size(); i += 3) ball.positions[i] += 20, ball.positions[i + 1] += 6;
    HardSet set{"axis_parallel", grid, {}};
    const uint32_t base = grid.vertex_count();
    set.mesh.positions.insert(set.mesh.positions.end(), ball.positions.begin(), ball.positions.end());
    for (uint32_t idx : ball.indices) set.mesh.indices.push_back(base + idx);
    std::vector<kdrt_ray> grid_rays, ball_rays;
    Box gb = box_of(grid), bb = box_of(ball);
    add_axis_rays(grid_rays, gb, 0.25, 0.5, 0, count / 2);
    add_axis_rays(ball_rays, bb, 0.125, 0.25, 1.0 / 32, count - grid_rays.size());
    set.rays = grid_rays;
    set.rays.insert(set.rays.end(), ball_rays.begin(), ball_rays.end());
    return set;
}

// Integer triangles and rays exactly parallel to them: lying in their plane (in_plane) or lifted
// off it by a small multiple of the normal (parallel_to_face). In-plane rays touch the triangle
// along a segment or not at all; the oracle (det == 0) and kdrt.h's det == 0 test call that a miss.
void parallel_sets(size_t count, Rng &rng, HardSet &in_plane, HardSet &parallel) {
    in_plane = HardSet{"in_plane", {}, {}};
    in_plane.mesh.name = "integer_triangles";
    const int triangles = 48;
    std::vector<std::array<double, 9>> tris;
    while (int(tris.size()) < triangles) {
        double p[3][3], e1[3], e2[3], n[3];
        double c[3] = {double(rng.below(8)) * 8, double(rng.below(8)) * 8, double(rng.below(8)) * 8};
        for (auto &q : p)
            for (int a = 0; a < 3; ++a) q[a] = c[a] + double(int(rng.below(9)) - 4);
        for (int a = 0; a < 3; ++a) e1[a] = p[1][a] - p[0][a], e2[a] = p[2][a] - p[0][a];
        cross(e1, e2, n);
        if (norm(n) == 0) continue;
        add_triangle(in_plane.mesh, p);
        tris.push_back({p[0][0], p[0][1], p[0][2], e1[0], e1[1], e1[2], e2[0], e2[1], e2[2]});
    }
    parallel = HardSet{"parallel_to_face", in_plane.mesh, {}};
    for (size_t i = 0; in_plane.rays.size() < count || parallel.rays.size() < count; ++i) {
        const auto &t = tris[rng.below(triangles)];
        const double *p0 = &t[0], *e1 = &t[3], *e2 = &t[6];
        double n[3];
        cross(e1, e2, n);
        // An exact in-plane direction: a small integer combination of the edges.
        double ka = double(int(rng.below(5)) - 2), kb = double(int(rng.below(5)) - 2);
        if (ka == 0 && kb == 0) ka = 1;
        double d[3], o[3];
        for (int a = 0; a < 3; ++a) d[a] = ka * e1[a] + kb * e2[a];
        // Through a quarter-lattice point of the plane (exact) inside the triangle or beside it,
        // starting there or two steps of d before it.
        double u = double(rng.below(6)) / 4 - 0.25, v = double(rng.below(6)) / 4 - 0.25;
        double back = (i % 3 == 0) ? 0 : 2;
        const double lifts[] = {0x1p-20, -0x1p-20, -0x1p-12, 1.0 / 64};
        double lift = i % 2 ? 0 : lifts[(i / 2) % 4];
        for (int a = 0; a < 3; ++a) o[a] = p0[a] + u * e1[a] + v * e2[a] - back * d[a] + lift * n[a];
        HardSet &set = lift == 0 ? in_plane : parallel;
        if (set.rays.size() < count) set.rays.push_back(make_ray(o, d));
    }
}

// A random unit direction and a random unit vector perpendicular to it.
void random_frame(Rng &rng, double along[3], double side[3]) {
    double tmp[3];
    rng.direction(along);
    rng.direction(tmp);
    cross(along, tmp, side);
    double length = norm(side);
    for (int a = 0; a < 3; ++a) side[a] /= length;
}

HardSet grazing_skinny_set(size_t count, Rng &rng) {
    HardSet set{"grazing_skinny", {}, {}};
    set.mesh.name = "skinny_triangles";
    std::vector<std::array<double, 9>> tris;
    for (int i = 0; i < 64; ++i) {
        double c[3] = {rng.range(0, 60), rng.range(0, 60), rng.range(0, 60)};
        double along[3], side[3];
        random_frame(rng, along, side);
        double length = rng.range(5, 20), width = length * std::pow(10.0, -rng.range(2, 3));  // aspect 100 to 1000
        double p[3][3];
        for (int a = 0; a < 3; ++a) {
            p[0][a] = c[a] - 0.5 * length * along[a];
            p[1][a] = c[a] + 0.5 * length * along[a];
            p[2][a] = c[a] + rng.range(-0.3, 0.3) * length * along[a] + width * side[a];
        }
        add_triangle(set.mesh, p);
        double q[3][3];
        set.mesh.corners(set.mesh.triangle_count() - 1, q);
        tris.push_back({q[0][0], q[0][1], q[0][2], q[1][0] - q[0][0], q[1][1] - q[0][1], q[1][2] - q[0][2], q[2][0] - q[0][0],
                        q[2][1] - q[0][1], q[2][2] - q[0][2]});
    }
    while (set.rays.size() < count) {
        const auto &t = tris[rng.below(uint32_t(tris.size()))];
        const double *p0 = &t[0], *e1 = &t[3], *e2 = &t[6];
        double n[3];
        cross(e1, e2, n);
        double nl = norm(n);
        for (double &x : n) x /= nl;
        // Target: inside, or on an edge line (u, v or w exactly 0 in double).
        double u = rng.uniform(), v = rng.uniform();
        if (u + v > 1) u = 1 - u, v = 1 - v;
        switch (rng.below(5)) {
        case 0: u = 0; break;
        case 1: v = 0; break;
        case 2: v = 1 - u; break;
        default: break;
        }
        double target[3], tangent[3], rnd[3];
        for (int a = 0; a < 3; ++a) target[a] = p0[a] + u * e1[a] + v * e2[a];
        rng.direction(rnd);
        double rn = dot(rnd, n);
        for (int a = 0; a < 3; ++a) tangent[a] = rnd[a] - rn * n[a];
        double tl = norm(tangent);
        double angle = rng.range(0.1, 1.0) * kPi / 180, side = rng.uniform() < 0.5 ? 1 : -1;
        double d[3], o[3], dist = rng.range(2, 20);
        for (int a = 0; a < 3; ++a) d[a] = std::cos(angle) * tangent[a] / tl + side * std::sin(angle) * n[a];
        for (int a = 0; a < 3; ++a) o[a] = target[a] - dist * d[a];
        set.rays.push_back(make_ray(o, d));
    }
    return set;
}

HardSet needles_tiny_set(size_t count, Rng &rng) {
    HardSet set{"needles_tiny", {}, {}};
    set.mesh.name = "needles_and_tiny";
    std::vector<std::array<double, 3>> targets;
    for (int i = 0; i < 96; ++i) {
        double c[3] = {rng.range(1, 10), rng.range(1, 10), rng.range(1, 10)};
        double along[3], side[3];
        random_frame(rng, along, side);
        double p[3][3];
        if (i % 2 == 0) {  // needle: length 1 to 4, width 1e-6 to 1e-4 of it
            double length = rng.range(1, 4), width = length * std::pow(10.0, -rng.range(4, 6));
            for (int a = 0; a < 3; ++a) {
                p[0][a] = c[a] - 0.5 * length * along[a];
                p[1][a] = c[a] + 0.5 * length * along[a];
                p[2][a] = c[a] + rng.range(-0.5, 0.5) * length * along[a] + width * side[a];
            }
        } else {  // tiny: 1e-6 to 1e-3 across
            double size = std::pow(10.0, -rng.range(3, 6));
            for (int a = 0; a < 3; ++a) {
                p[0][a] = c[a];
                p[1][a] = c[a] + size * along[a];
                p[2][a] = c[a] + 0.5 * size * along[a] + 0.7 * size * side[a];
            }
        }
        add_triangle(set.mesh, p);
        double q[3][3];
        set.mesh.corners(set.mesh.triangle_count() - 1, q);
        for (int k = 0; k < 8; ++k) {  // points inside and near the float triangle
            double u = rng.range(-0.05, 1.0), v = rng.range(-0.05, 1.0);
            if (u + v > 1.05) u = 1 - u, v = 1 - v;
            std::array<double, 3> tp;
            for (int a = 0; a < 3; ++a) tp[a] = q[0][a] + u * (q[1][a] - q[0][a]) + v * (q[2][a] - q[0][a]);
            targets.push_back(tp);
        }
    }
    while (set.rays.size() < count) {
        const auto &tp = targets[rng.below(uint32_t(targets.size()))];
        double d[3], o[3], dist = rng.range(0.5, 15);
        rng.direction(d);
        for (int a = 0; a < 3; ++a) o[a] = tp[a] - dist * d[a];
        set.rays.push_back(make_ray(o, d));
    }
    return set;
}

HardSet coplanar_overlap_set(size_t count, Rng &rng) {
    HardSet set{"coplanar_overlap", {}, {}};
    set.mesh.name = "coplanar_stacks";
    // Six planes: three axis-aligned, three tilted (integer normals); in each, 12 overlapping
    // triangles around a centre, and one triangle repeated with rotated and reversed corners.
    const double normals[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {1, 2, 3}, {-2, 1, 1}};
    for (int k = 0; k < 6; ++k) {
        const double *n = normals[k];
        double c[3] = {double(k % 3) * 20, double(k / 3) * 20, 10.0 * (k % 2)};
        double t1[3], t2[3], helper[3] = {n[1] == 0 && n[2] == 0 ? 0.0 : 1.0, n[1] == 0 && n[2] == 0 ? 1.0 : 0.0, 0.0};
        cross(n, helper, t1);
        cross(n, t1, t2);  // integer in-plane axes: corners stay exact
        auto corner = [&](double a, double b, double out[3]) {
            for (int x = 0; x < 3; ++x) out[x] = c[x] + a * t1[x] + b * t2[x];
        };
        for (int j = 0; j < 12; ++j) {
            double p[3][3];
            corner(double(int(rng.below(5))) - 4, double(int(rng.below(5))) - 4, p[0]);
            corner(double(rng.below(5)) + 1, double(int(rng.below(7))) - 3, p[1]);
            corner(double(int(rng.below(7))) - 3, double(rng.below(5)) + 1, p[2]);
            add_triangle(set.mesh, p);
        }
        double p[3][3];
        corner(-3, -2, p[0]), corner(3, -1, p[1]), corner(-1, 3, p[2]);
        const int orders[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
        for (const auto &o : orders) {
            double q[3][3];
            for (int x = 0; x < 3; ++x) std::memcpy(q[x], p[o[x]], sizeof q[x]);
            add_triangle(set.mesh, q);
        }
    }
    // Rays at the stacks' triangles from either side, at any angle.
    while (set.rays.size() < count) {
        uint32_t t = rng.below(set.mesh.triangle_count());
        double q[3][3];
        set.mesh.corners(t, q);
        double u = rng.range(-0.1, 1.0), v = rng.range(-0.1, 1.0);
        if (u + v > 1.1) u = 1 - u, v = 1 - v;
        double target[3], d[3], o[3], dist = rng.range(1, 30);
        for (int a = 0; a < 3; ++a) target[a] = q[0][a] + u * (q[1][a] - q[0][a]) + v * (q[2][a] - q[0][a]);
        rng.direction(d);
        for (int a = 0; a < 3; ++a) o[a] = target[a] - dist * d[a];
        set.rays.push_back(make_ray(o, d));
    }
    return set;
}

}  // namespace

Mesh uv_sphere(uint32_t rings, uint32_t segments, double radius, bool integer) {
    Mesh m;
    m.name = std::string(integer ? "int_sphere_" : "sphere_") + std::to_string(rings) + "x" + std::to_string(segments);
    auto put = [&](double x, double y, double z) {
        for (double c : {x, y, z}) m.positions.push_back(float(integer ? std::round(c) : c));
    };
    put(0, 0, radius);
    for (uint32_t r = 1; r < rings; ++r) {
        double theta = kPi * r / rings;
        for (uint32_t s = 0; s < segments; ++s) {
            double phi = 2 * kPi * s / segments;
            put(radius * std::sin(theta) * std::cos(phi), radius * std::sin(theta) * std::sin(phi), radius * std::cos(theta));
        }
    }
    put(0, 0, -radius);
    uint32_t south = m.vertex_count() - 1;
    auto ring = [&](uint32_t r, uint32_t s) { return 1 + (r - 1) * segments + s % segments; };
    for (uint32_t s = 0; s < segments; ++s) {
        m.indices.insert(m.indices.end(), {0, ring(1, s), ring(1, s + 1)});
        m.indices.insert(m.indices.end(), {south, ring(rings - 1, s + 1), ring(rings - 1, s)});
    }
    for (uint32_t r = 1; r + 1 < rings; ++r)
        for (uint32_t s = 0; s < segments; ++s) {
            uint32_t a = ring(r, s), b = ring(r, s + 1), c = ring(r + 1, s), d = ring(r + 1, s + 1);
            m.indices.insert(m.indices.end(), {a, c, d, a, d, b});
        }
    return m;
}

// ---------------------------------------------------------------------------------------------

std::vector<std::string> hostile_kinds() { return {"fan", "cone", "slivers", "overlapping", "identical"}; }

Mesh hostile_mesh(const std::string &kind, uint32_t triangles, uint64_t seed) {
    Mesh m;
    m.name = "hostile_" + kind;
    Rng rng(seed);
    double p[3][3];
    for (uint32_t i = 0; i < triangles; ++i) {
        if (kind == "fan" || kind == "cone") {
            const double a0 = 2 * kPi * i / triangles, a1 = 2 * kPi * (i + 1) / triangles;
            const double corners[3][3] = {{0, 0, kind == "cone" ? 1.0 : 0.0},
                                          {std::cos(a0), std::sin(a0), 0},
                                          {std::cos(a1), std::sin(a1), 0}};
            std::memcpy(p, corners, sizeof p);
        } else if (kind == "slivers") {
            // From one face of the cube to the opposite one on axis `along` (x or y), at a
            // random height on the other two.
            const int along = int(i % 2), across = 1 - along;
            const double at = rng.uniform(), z = rng.uniform(), w = 1e-3;
            const double from[2] = {0, 1}, side[3] = {at, at + w, at};
            for (int k = 0; k < 3; ++k) {
                p[k][along] = from[k > 0];
                p[k][across] = side[k];
                p[k][2] = k == 2 ? z + w : z;
            }
        } else if (kind == "overlapping") {
            double o[3];
            for (double &x : o) x = 0.7 * rng.uniform();
            for (auto &corner : p)
                for (int k = 0; k < 3; ++k) corner[k] = o[k] + 0.3 * rng.uniform();
        } else if (kind == "soup") {
            // Small random triangles filling the unit cube, about as many across as there are
            // triangles to a side: the plainest big input, for build time and memory.
            const double size = 2.0 / std::cbrt(double(triangles));
            double o[3];
            for (double &x : o) x = rng.uniform();
            for (auto &corner : p)
                for (int k = 0; k < 3; ++k) corner[k] = o[k] + size * rng.uniform();
        } else if (kind == "identical") {
            const double corners[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0.5}};
            std::memcpy(p, corners, sizeof p);
        } else {
            return Mesh();
        }
        add_triangle(m, p);
    }
    return m;
}

// ---------------------------------------------------------------------------------------------

bool is_closed(const Mesh &mesh, std::string *why) {
    auto fail = [&](const std::string &reason) {
        if (why) *why = mesh.name + ": " + reason;
        return false;
    };
    if (mesh.triangle_count() == 0) return fail("no triangles");
    // Weld by coordinates (-0 and +0 are the same point).
    struct Key {
        float x, y, z;
        bool operator==(const Key &o) const { return x == o.x && y == o.y && z == o.z; }
    };
    struct Hash {
        size_t operator()(const Key &k) const {
            uint32_t b[3];
            float f[3] = {k.x + 0.0f, k.y + 0.0f, k.z + 0.0f};
            std::memcpy(b, f, sizeof b);
            return size_t(b[0] * 73856093u ^ b[1] * 19349663u ^ b[2] * 83492791u);
        }
    };
    std::unordered_map<Key, uint32_t, Hash> ids;
    std::unordered_map<uint64_t, uint32_t> edges;
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        double p[3][3];
        mesh.corners(t, p);
        double e1[3], e2[3], n[3];
        for (int a = 0; a < 3; ++a) e1[a] = p[1][a] - p[0][a], e2[a] = p[2][a] - p[0][a];
        cross(e1, e2, n);
        if (n[0] == 0 && n[1] == 0 && n[2] == 0) return fail("triangle " + std::to_string(t) + " has zero area");
        uint32_t v[3];
        for (int k = 0; k < 3; ++k) {
            Key key{float(p[k][0]), float(p[k][1]), float(p[k][2])};
            v[k] = ids.emplace(key, uint32_t(ids.size())).first->second;
        }
        for (int k = 0; k < 3; ++k) {
            uint32_t a = v[k], b = v[(k + 1) % 3];
            if (a == b) return fail("triangle " + std::to_string(t) + " has two equal corners");
            ++edges[a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a)];
        }
    }
    size_t open = 0, over = 0;
    for (const auto &e : edges) open += e.second == 1, over += e.second > 2;
    if (open || over)
        return fail(std::to_string(open) + " edges with one triangle, " + std::to_string(over) + " with more than two");
    return true;
}

std::vector<Mesh> closed_meshes(bool include_shared) {
    std::vector<Mesh> meshes;
    meshes.push_back(uv_sphere(24, 48, 1.0, false));
    meshes.push_back(uv_sphere(7, 9, 5.0, false));
    meshes.push_back(uv_sphere(5, 96, 2.5, false));  // 96 triangles meet at each pole
    meshes.push_back(int_octahedron(12));
    meshes.push_back(int_bumpy_box(10, 7));
    meshes.push_back(uv_sphere(16, 32, 40.0, true));
    if (include_shared) {
        std::vector<std::string> files;
        std::error_code ec;
        const std::string dir = KDRT_MESH_DIR;
        if (!dir.empty() && std::filesystem::is_directory(dir, ec))
            for (const char *sub : {"seed", "common"})
                for (const auto &entry : std::filesystem::directory_iterator(dir + "/" + sub, ec)) {
                    std::string ext = entry.path().extension().string();
                    if (ext == ".off" || ext == ".obj" || ext == ".ply" || ext == ".stl") files.push_back(entry.path().string());
                }
        std::sort(files.begin(), files.end());
        std::vector<Mesh> shared;
        for (const std::string &file : files) {
            Mesh m;
            std::string error;
            if (load_mesh(file, m, error) && is_closed(m)) shared.push_back(std::move(m));
        }
        std::stable_sort(shared.begin(), shared.end(),
                         [](const Mesh &a, const Mesh &b) { return a.triangle_count() < b.triangle_count(); });
        for (Mesh &m : shared) meshes.push_back(std::move(m));
    }
    return meshes;
}

std::vector<kdrt_ray> rays_at_vertices_and_edges(const Mesh &closed, size_t count, uint64_t seed) {
    std::vector<kdrt_ray> rays;
    if (closed.triangle_count() == 0 || count == 0) return rays;
    Rng rng(seed);
    const Geometry g(closed);
    const bool integer = is_integer_mesh(closed);
    const auto inside = inside_points(closed, g, 32, rng);
    if (inside.empty()) return rays;
    const Box box = box_of(closed);
    const double diag = box.diagonal();
    rays.reserve(count);
    for (size_t i = 0; i < count; ++i) {
        const auto &p = inside[rng.below(uint32_t(inside.size()))];
        double q[3][3], target[3];
        closed.corners(rng.below(closed.triangle_count()), q);
        const int k = int(rng.below(3));
        if (i % 2 == 0) {
            for (int a = 0; a < 3; ++a) target[a] = q[k][a];
        } else {
            // A dyadic point of the edge: exact for integer corners.
            const double s = integer ? double(1 + rng.below(7)) / 8 : rng.range(0.001, 0.999);
            for (int a = 0; a < 3; ++a) target[a] = double(float(q[k][a] + s * (q[(k + 1) % 3][a] - q[k][a])));
        }
        double o[3], d[3];
        if (i % 4 < 2) {
            for (int a = 0; a < 3; ++a) o[a] = p[a];
        } else {
            // Beyond the target on the line from the inside point: outside the box.
            double away[3] = {target[0] - p[0], target[1] - p[1], target[2] - p[2]};
            double f = 2 * diag / norm(away) * rng.range(1, 3);
            if (integer) f = std::ceil(f);
            for (int a = 0; a < 3; ++a) o[a] = double(float(target[a] + f * away[a]));
        }
        for (int a = 0; a < 3; ++a) d[a] = target[a] - o[a];
        rays.push_back(make_ray(o, d));
    }
    return rays;
}

std::vector<HardSet> hard_sets(size_t rays_per_set, uint64_t seed) {
    Rng rng(seed);
    std::vector<HardSet> sets;
    sets.push_back(split_plane_set("split_planes_grid", height_grid(16, 16, rng), rays_per_set, rng));
    sets.push_back(split_plane_set("split_planes_soup", soup(400, 10, 1, rng), rays_per_set, rng));
    sets.push_back(axis_parallel_set(rays_per_set, rng));
    HardSet in_plane, parallel;
    parallel_sets(rays_per_set, rng, in_plane, parallel);
    sets.push_back(std::move(parallel));
    sets.push_back(std::move(in_plane));
    sets.push_back(grazing_skinny_set(rays_per_set, rng));
    sets.push_back(needles_tiny_set(rays_per_set, rng));
    sets.push_back(coplanar_overlap_set(rays_per_set, rng));
    for (HardSet &s : sets) {
        // A tenth more rays at random through each scene, so the sets also show ordinary hits.
        add_random_rays(s.rays, box_of(s.mesh), rays_per_set / 10, rng);
        s.mesh.name = s.name;
    }
    return sets;
}

Mesh translated(const Mesh &mesh, double offset, double scale) {
    Mesh m = mesh;
    const Box box = box_of(mesh);
    char suffix[64];
    std::snprintf(suffix, sizeof suffix, "_at_%g", offset);
    m.name += suffix;
    for (size_t i = 0; i + 2 < m.positions.size(); i += 3)
        for (int a = 0; a < 3; ++a) {
            double c = 0.5 * (box.lo[a] + box.hi[a]);
            m.positions[i + a] = float((double(mesh.positions[i + a]) - c) * scale + c + offset);
        }
    return m;
}

ErrorCounts count_leaks(const kdrt_tree *tree, const std::vector<kdrt_ray> &must_hit) {
    ErrorCounts counts;
    counts.rays = must_hit.size();
    std::atomic<size_t> leaks{0};
    std::atomic<size_t> first{SIZE_MAX};
    common::timed_parallel(must_hit.size(), common::all_cores(), [&](size_t i) {
        kdrt_hit h;
        if (!kdrt_intersect(tree, &must_hit[i], &h)) {
            ++leaks;
            size_t cur = first.load();
            while (i < cur && !first.compare_exchange_weak(cur, i)) {}
        }
    });
    counts.leaks = leaks;
    if (counts.leaks) counts.first = "ray " + std::to_string(first.load()) + " " + describe(must_hit[first.load()]) + " missed";
    return counts;
}

std::vector<SpawnedRay> spawn_rays(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, Spawn spawn) {
    const int per_hit = 4;
    std::vector<SpawnedRay> slots(rays.size() * per_hit);
    std::vector<unsigned char> used(slots.size(), 0);
    common::timed_parallel(rays.size(), common::all_cores(), [&](size_t i) {
        kdrt_hit h;
        if (!kdrt_intersect(tree, &rays[i], &h)) return;
        float point[3], normal[3];
        if (!kdrt_hit_surface(tree, &h, point, normal)) return;
        const float *d = rays[i].dir;
        double dirs[per_hit][3];
        reflect(d, normal, dirs[0]);
        for (int a = 0; a < 3; ++a) dirs[1][a] = d[a];
        grazing(d, normal, 0.5, 1, dirs[2]);
        grazing(d, normal, 0.5, -1, dirs[3]);
        for (int k = 0; k < per_hit; ++k) {
            const float df[3] = {float(dirs[k][0]), float(dirs[k][1]), float(dirs[k][2])};
            SpawnedRay &s = slots[i * per_hit + k];
            if (spawn == Spawn::kdrt) {
                if (!kdrt_spawn_ray(tree, &h, df, &s.ray)) continue;
            } else {
                for (int a = 0; a < 3; ++a) s.ray.org[a] = rays[i].org[a] + h.t * rays[i].dir[a], s.ray.dir[a] = df[a];
                s.ray.tmin = 0, s.ray.tmax = kInf;
            }
            s.from = h.triangle, s.primary = i;
            used[i * per_hit + k] = 1;
        }
    });
    std::vector<SpawnedRay> out;
    for (size_t j = 0; j < slots.size(); ++j)
        if (used[j]) out.push_back(slots[j]);
    return out;
}

ErrorCounts count_self_hits(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, Spawn spawn) {
    const std::vector<SpawnedRay> spawned = spawn_rays(tree, rays, spawn);
    std::vector<kdrt_hit> hits(spawned.size());
    common::timed_parallel(spawned.size(), common::all_cores(), [&](size_t j) { kdrt_intersect(tree, &spawned[j].ray, &hits[j]); });
    ErrorCounts counts;
    counts.rays = spawned.size();
    for (size_t j = 0; j < spawned.size(); ++j) {
        if (hits[j].triangle != spawned[j].from) continue;
        if (counts.self_hits++ == 0) {
            char buf[160];
            std::snprintf(buf, sizeof buf, " hits triangle %u; spawned ray ", spawned[j].from);
            counts.first = "ray " + std::to_string(spawned[j].primary) + " " + describe(rays[spawned[j].primary]) + buf +
                           describe(spawned[j].ray) + " hits it again at t=" + std::to_string(hits[j].t);
        }
    }
    return counts;
}

ErrorCounts count_mismatches(const kdrt_tree *tree, const Oracle &oracle, const std::vector<Reference> &refs,
                             const std::vector<kdrt_ray> &rays, std::vector<kdrt_hit> *hits_out, Agreement *tally_out) {
    std::vector<kdrt_hit> hits(rays.size());
    common::timed_parallel(rays.size(), common::all_cores(), [&](size_t i) { kdrt_intersect(tree, &rays[i], &hits[i]); });
    ErrorCounts counts;
    Agreement tally;
    for (size_t i = 0; i < rays.size() && i < refs.size(); ++i) {
        check_hit(oracle, refs[i], rays[i], hits[i], tally);
        if (hits[i].triangle != KDRT_INVALID_ID && std::isnan(oracle.expected_t(rays[i], hits[i].triangle, hits[i].t)))
            ++counts.false_hits;
    }
    counts.rays = tally.rays;
    counts.mismatches = tally.wrong;
    counts.first = tally.first_wrong;
    if (hits_out) *hits_out = std::move(hits);
    if (tally_out) *tally_out = tally;
    return counts;
}

}  // namespace oracle
