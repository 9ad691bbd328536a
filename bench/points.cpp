#include "points.hpp"

#include "common/random.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <time.h>

namespace kb {

const char *point_kind_name(PointKind kind) {
    switch (kind) {
    case PointKind::surface: return "surface";
    case PointKind::inside: return "inside";
    case PointKind::outside: return "outside";
    }
    return "?";
}

static void mesh_box(const common::Mesh &mesh, double lo[3], double hi[3]) {
    for (int a = 0; a < 3; ++a) lo[a] = 1e300, hi[a] = -1e300;
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], double(mesh.positions[i]));
        hi[i % 3] = std::max(hi[i % 3], double(mesh.positions[i]));
    }
    if (mesh.positions.empty())
        for (int a = 0; a < 3; ++a) lo[a] = hi[a] = 0;
}

double mesh_diagonal(const common::Mesh &mesh) {
    double lo[3], hi[3];
    mesh_box(mesh, lo, hi);
    return std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) + (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

std::vector<float> make_points(const common::Mesh &mesh, PointKind kind, size_t count, uint64_t seed) {
    common::Rng rng(seed * 3 + uint64_t(kind));
    double lo[3], hi[3];
    mesh_box(mesh, lo, hi);
    const double diagonal = mesh_diagonal(mesh);
    std::vector<float> out(3 * count);
    const uint32_t triangles = mesh.triangle_count();
    for (size_t i = 0; i < count; ++i) {
        double p[3];
        if (kind == PointKind::surface && triangles) {
            double c[3][3], n[3];
            mesh.corners(rng.below(triangles), c);
            double u = rng.uniform(), v = rng.uniform();
            if (u + v > 1) u = 1 - u, v = 1 - v;
            const double e0[3] = {c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]};
            const double e1[3] = {c[2][0] - c[0][0], c[2][1] - c[0][1], c[2][2] - c[0][2]};
            n[0] = e0[1] * e1[2] - e0[2] * e1[1], n[1] = e0[2] * e1[0] - e0[0] * e1[2], n[2] = e0[0] * e1[1] - e0[1] * e1[0];
            const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            const double offset = len > 0 ? rng.range(-0.01, 0.01) * diagonal / len : 0;
            for (int a = 0; a < 3; ++a) p[a] = c[0][a] + u * e0[a] + v * e1[a] + offset * n[a];
        } else if (kind == PointKind::outside) {
            double d[3];
            rng.direction(d);
            const double r = rng.range(2, 10) * diagonal;
            for (int a = 0; a < 3; ++a) p[a] = 0.5 * (lo[a] + hi[a]) + r * d[a];
        } else {
            for (int a = 0; a < 3; ++a) p[a] = rng.range(lo[a], hi[a]);
        }
        for (int a = 0; a < 3; ++a) out[3 * i + a] = float(p[a]);
    }
    return out;
}

static double dot(const double x[3], const double y[3]) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; }

double point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3]) {
    double ab[3], ac[3], ap[3], q[3];
    for (int k = 0; k < 3; ++k) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    auto at = [&](const double x[3]) {
        const double d[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
        return std::sqrt(dot(d, d));
    };
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return at(a);
    double bp[3];
    for (int k = 0; k < 3; ++k) bp[k] = p[k] - b[k];
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return at(b);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        const double v = d1 / (d1 - d3);
        for (int k = 0; k < 3; ++k) q[k] = a[k] + v * ab[k];
        return at(q);
    }
    double cp[3];
    for (int k = 0; k < 3; ++k) cp[k] = p[k] - c[k];
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return at(c);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        const double w = d2 / (d2 - d6);
        for (int k = 0; k < 3; ++k) q[k] = a[k] + w * ac[k];
        return at(q);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; ++k) q[k] = b[k] + w * (c[k] - b[k]);
        return at(q);
    }
    const double denom = 1 / (va + vb + vc), v = vb * denom, w = vc * denom;
    for (int k = 0; k < 3; ++k) q[k] = a[k] + ab[k] * v + ac[k] * w;
    return at(q);
}

bool zero_area(const double c[3][3]) {
    double e1[3], e2[3];
    for (int a = 0; a < 3; ++a) e1[a] = c[1][a] - c[0][a], e2[a] = c[2][a] - c[0][a];
    // Each component of e1 x e2 is 0 when its two products are equal (no fused multiply-add).
    return e1[1] * e2[2] == e1[2] * e2[1] && e1[2] * e2[0] == e1[0] * e2[2] && e1[0] * e2[1] == e1[1] * e2[0];
}

double brute_closest_distance(const common::Mesh &mesh, const float p[3]) {
    const double q[3] = {p[0], p[1], p[2]};
    double best = INFINITY;
    for (uint32_t t = 0, n = mesh.triangle_count(); t < n; ++t) {
        double c[3][3];
        mesh.corners(t, c);
        if (!zero_area(c)) best = std::min(best, point_triangle_distance(q, c[0], c[1], c[2]));
    }
    return best;
}

uint64_t brute_sphere_count(const common::Mesh &mesh, const float center[3], float radius) {
    const double q[3] = {center[0], center[1], center[2]};
    uint64_t count = 0;
    for (uint32_t t = 0, n = mesh.triangle_count(); t < n; ++t) {
        double c[3][3];
        mesh.corners(t, c);
        count += !zero_area(c) && point_triangle_distance(q, c[0], c[1], c[2]) <= radius;
    }
    return count;
}

std::string points_csv_header() {
    return "Mesh;Triangles;Query;Kind;Size;Queries;KdrtMs;EmbreeMs;Ratio;Found;ReferenceQueries;KdrtMismatches;"
           "EmbreeMismatches;KdrtMaxError;EmbreeMaxError;Repeat;KdrtCpuMs;EmbreeCpuMs;CpuRatio";
}

std::string points_csv_row(const PointsRow &r) {
    char buf[640];
    std::snprintf(buf, sizeof buf, "%s;%u;%s;%s;%g;%zu;%.3f;%.3f;%.3f;%llu;%zu;%zu;%zu;%.3g;%.3g;%u;%.3f;%.3f;%.3f", r.mesh.c_str(),
                  r.triangles, r.query.c_str(), r.kind.c_str(), r.size, r.queries, r.kdrt_ms, r.embree_ms, r.ratio,
                  (unsigned long long)r.found, r.reference, r.kdrt_mismatches, r.embree_mismatches, r.kdrt_max_error,
                  r.embree_max_error, r.repeat, r.kdrt_cpu_ms, r.embree_cpu_ms, r.cpu_ratio);
    return buf;
}

double thread_cpu_ms() {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

}  // namespace kb
