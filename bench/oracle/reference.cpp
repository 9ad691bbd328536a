#include "oracle/reference.hpp"
#include "common/timing.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace oracle {

using common::Mesh;

Oracle::Oracle(const Mesh &mesh) {
    uint32_t n = mesh.triangle_count();
    tri_.resize(size_t(n) * 9);
    size_t padded = (size_t(n) + kBallBlock - 1) / kBallBlock * kBallBlock;
    ball_x_.assign(padded, 0), ball_y_.assign(padded, 0), ball_z_.assign(padded, 0), ball_r2_.assign(padded, -1);
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (uint32_t t = 0; t < n; ++t) {
        double p[3][3];
        mesh.corners(t, p);
        for (int a = 0; a < 3; ++a) {
            tri_[size_t(t) * 9 + a] = p[0][a];
            tri_[size_t(t) * 9 + 3 + a] = p[1][a] - p[0][a];
            tri_[size_t(t) * 9 + 6 + a] = p[2][a] - p[0][a];
            for (auto &corner : p) lo[a] = std::min(lo[a], corner[a]), hi[a] = std::max(hi[a], corner[a]);
        }
        // Centroid and farthest corner, the radius widened far beyond the rounding of the test.
        double c[3], r2 = 0;
        for (int a = 0; a < 3; ++a) c[a] = (p[0][a] + p[1][a] + p[2][a]) / 3;
        for (auto &corner : p) {
            double dx = corner[0] - c[0], dy = corner[1] - c[1], dz = corner[2] - c[2];
            r2 = std::max(r2, dx * dx + dy * dy + dz * dz);
        }
        ball_x_[t] = c[0], ball_y_[t] = c[1], ball_z_[t] = c[2], ball_r2_[t] = r2 * (1 + 1e-6) + 1e-300;
    }
    // The scene's size sets the tolerances: relative, so that they mean the same at any scale.
    scene_size_ = n ? std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}) : 1.0;
    if (!(scene_size_ > 0)) scene_size_ = 1.0;  // every vertex in one point: t alone sets them
    // The balls in Morton order of their centres, so that a block holds neighbours whatever the
    // mesh's own order; order_ names each one's triangle. (Non-finite centres sort last.)
    std::vector<uint64_t> key(n);
    for (uint32_t t = 0; t < n; ++t) {
        uint64_t code = 0;
        const double c[3] = {ball_x_[t], ball_y_[t], ball_z_[t]};
        for (int bit = 9; bit >= 0; --bit)
            for (int a = 0; a < 3; ++a) {
                const double f = (c[a] - lo[a]) / std::max(hi[a] - lo[a], 1e-300);
                const uint64_t cell = f >= 0 && f <= 1 ? std::min<uint64_t>(1023, uint64_t(f * 1024)) : 1023;
                code = code << 1 | (cell >> bit & 1);
            }
        key[t] = std::isfinite(c[0] + c[1] + c[2]) ? code << 32 | t : ~uint64_t(0) << 32 | t;
    }
    std::sort(key.begin(), key.end());
    order_.assign(padded, 0);
    std::vector<double> x = ball_x_, y = ball_y_, z = ball_z_, r2 = ball_r2_;
    for (uint32_t k = 0; k < n; ++k) {
        const uint32_t t = uint32_t(key[k]);
        order_[k] = t, ball_x_[k] = x[t], ball_y_[k] = y[t], ball_z_[k] = z[t], ball_r2_[k] = r2[t];
    }
    // Each block's ball: centred on its balls' mean centre, reaching the far side of each. A
    // non-finite triangle makes its block's ball NaN, which no line is found to miss.
    const size_t blocks = padded / kBallBlock;
    block_x_.assign(blocks, 0), block_y_.assign(blocks, 0), block_z_.assign(blocks, 0), block_r2_.assign(blocks, 0);
    for (size_t b = 0; b < blocks; ++b) {
        const size_t begin = b * kBallBlock, end = std::min(size_t(n), begin + kBallBlock);
        double c[3] = {0, 0, 0}, r = 0;
        for (size_t j = begin; j < end; ++j) c[0] += ball_x_[j], c[1] += ball_y_[j], c[2] += ball_z_[j];
        for (double &x : c) x /= double(end - begin);
        for (size_t j = begin; j < end; ++j) {
            const double dx = ball_x_[j] - c[0], dy = ball_y_[j] - c[1], dz = ball_z_[j] - c[2];
            r = std::max(r, std::sqrt(dx * dx + dy * dy + dz * dz) + std::sqrt(ball_r2_[j]));
        }
        block_x_[b] = c[0], block_y_[b] = c[1], block_z_[b] = c[2], block_r2_[b] = r * r * (1 + 1e-6);
    }
}

double Oracle::t_tolerance(const kdrt_ray &ray, double t) const {
    double dlen = std::sqrt(double(ray.dir[0]) * ray.dir[0] + double(ray.dir[1]) * ray.dir[1] + double(ray.dir[2]) * ray.dir[2]);
    double reach = std::sqrt(double(ray.org[0]) * ray.org[0] + double(ray.org[1]) * ray.org[1] + double(ray.org[2]) * ray.org[2]);
    // Float coordinates carry an error relative to their magnitude, so far-from-origin scenes
    // get a tolerance that grows with the distance from the origin as well.
    return kRelativeT * (std::fabs(t) + (scene_size_ + reach) / dlen);
}

double Oracle::t_tolerance(const kdrt_ray &ray, double t, uint32_t triangle) const {
    const double *e1 = &tri_[size_t(triangle) * 9 + 3], *e2 = e1 + 3;
    const double d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double det = std::fabs(d[0] * n[0] + d[1] * n[1] + d[2] * n[2]);
    double condition = std::sqrt((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]) *
                                 (e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2])) / det;
    return t_tolerance(ray, t) * std::max(1.0, condition / kWellConditioned);
}

namespace {
// Double-precision Moeller-Trumbore on the float ray as given. False when the ray is parallel to
// the triangle's plane or a barycentric is below `margin`; each is tested as soon as it is known,
// because the brute-force reference spends nearly all its time rejecting triangles.
bool plane_hit(const double *tri, const double o[3], const double d[3], double margin, double &t, double &det, double &b1,
               double &b2) {
    const double *p0 = tri, *e1 = tri + 3, *e2 = tri + 6;
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0) return false;
    double tv[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
    b1 = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
    if (!(b1 >= margin)) return false;
    double qv[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2], tv[0] * e1[1] - tv[1] * e1[0]};
    b2 = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
    if (!(b2 >= margin) || !(1 - b1 - b2 >= margin)) return false;
    t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
    return std::isfinite(t);
}

// |cos| of the angle between the ray and the triangle's normal, from plane_hit's det.
double cosine(const double *tri, const double d[3], double det) {
    const double *e1 = tri + 3, *e2 = tri + 6;
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double nlen = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), dlen = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    return std::fabs(det) / (nlen * dlen);
}

// How far inside its edges a hit must be for the float test to agree. kEdgeMargin, unless the
// float barycentrics are worse: the corners relative to the origin are rounded to floats, which
// cancels when the origin is far from a small triangle (or a long sliver reaches far from it),
// leaving an error of a few roundings times cond |o - p| / |edge|, with |o - p| the farthest
// corner's distance and cond = |d| |e1| |e2| / |det|. (Seen: a 0.0035-wide triangle of
// rocker-arm.obj from 1.1 away, cond 8.5, with a float w of +3.9e-5 where the double one is
// -2.7e-5; a sliver 1.25 wide and 4e30 long hit 20 units off its side.)
double edge_margin(const double *tri, const double o[3], const double d[3], double det) {
    const double *p0 = tri, *e1 = tri + 3, *e2 = tri + 6;
    auto len = [](double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); };
    double l1 = len(e1[0], e1[1], e1[2]), l2 = len(e2[0], e2[1], e2[2]);
    double cond = len(d[0], d[1], d[2]) * l1 * l2 / std::fabs(det);
    double v[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
    double reach = std::max({len(v[0], v[1], v[2]), len(v[0] - e1[0], v[1] - e1[1], v[2] - e1[2]),
                             len(v[0] - e2[0], v[1] - e2[1], v[2] - e2[2])});
    return std::max(Oracle::kEdgeMargin, 4 * 0x1p-24 * cond * reach / std::min(l1, l2));
}
}  // namespace

Reference Oracle::trace(const kdrt_ray &ray) const {
    Reference ref;
    const double o[3] = {ray.org[0], ray.org[1], ray.org[2]}, d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    double tmin = std::max(0.0, double(ray.tmin)), tmax = ray.tmax;
    const size_t n = tri_.size() / 9;
    // Still every triangle, but in blocks: first whether the ray's line meets the block's ball,
    // then for each triangle of a block it meets a cheap test that the line meets the
    // triangle's ball (|(c - o) x d|^2 <= r^2 |d|^2, a loop the compiler vectorises), then the
    // exact double-precision test for the few that pass. A sure hit lies strictly inside its
    // triangle, hence strictly inside the ball, so the cheap test never rejects one.
    const double o0 = o[0], o1 = o[1], o2 = o[2], d0 = d[0], d1 = d[1], d2 = d[2];
    double outside[kBallBlock];  // > 0: the line misses the ball (a double, so the loop vectorises)
    for (size_t begin = 0; begin < n; begin += kBallBlock) {
        {  // The block's ball first, with a slack far above the rounding of |v x d|^2.
            const size_t b = begin / kBallBlock;
            const double vx = block_x_[b] - o0, vy = block_y_[b] - o1, vz = block_z_[b] - o2;
            const double cx = vy * d2 - vz * d1, cy = vz * d0 - vx * d2, cz = vx * d1 - vy * d0;
            const double slack = 1e-12 * (vx * vx + vy * vy + vz * vz) * dd;
            if (cx * cx + cy * cy + cz * cz - block_r2_[b] * dd > slack) continue;
        }
        const double *bx = &ball_x_[begin], *by = &ball_y_[begin], *bz = &ball_z_[begin], *br2 = &ball_r2_[begin];
        for (size_t j = 0; j < kBallBlock; ++j) {  // the arrays are padded to whole blocks
            double vx = bx[j] - o0, vy = by[j] - o1, vz = bz[j] - o2;
            double cx = vy * d2 - vz * d1, cy = vz * d0 - vx * d2, cz = vx * d1 - vy * d0;
            outside[j] = cx * cx + cy * cy + cz * cz - br2[j] * dd;
        }
        for (size_t j = 0; j < kBallBlock && begin + j < n; ++j) {
            if (outside[j] > 0) continue;
            const size_t i = order_[begin + j];
            // Sure: clear of the edges, of the range ends, and not grazing (where the float
            // test's barycentrics lose their accuracy).
            double t, det, b1, b2;
            if (!plane_hit(&tri_[i * 9], o, d, kEdgeMargin, t, det, b1, b2)) continue;
            // The lower index keeps a tie (the balls are not in index order).
            if (ref.sure_hit && !(t < ref.sure_t || (t == ref.sure_t && i < ref.sure_triangle))) continue;
            double margin = edge_margin(&tri_[i * 9], o, d, det);
            if (b1 < margin || b2 < margin || 1 - b1 - b2 < margin) continue;
            double tol = t_tolerance(ray, t);
            if (t < tmin + tol || t > tmax - tol) continue;
            if (cosine(&tri_[i * 9], d, det) < 1e-3) continue;
            ref.sure_hit = true, ref.sure_t = t, ref.sure_triangle = uint32_t(i);
        }
    }
    return ref;
}

double Oracle::possible_t(const kdrt_ray &ray, uint32_t triangle) const {
    if (size_t(triangle) * 9 >= tri_.size()) return std::nan("");
    const double o[3] = {ray.org[0], ray.org[1], ray.org[2]}, d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
    double t, det, b1, b2;
    if (!plane_hit(&tri_[size_t(triangle) * 9], o, d, -INFINITY, t, det, b1, b2)) return std::nan("");
    double margin = edge_margin(&tri_[size_t(triangle) * 9], o, d, det);
    if (b1 < -margin || b2 < -margin || 1 - b1 - b2 < -margin) return std::nan("");
    double tol = t_tolerance(ray, t);
    if (t < std::max(0.0, double(ray.tmin)) - tol || t > double(ray.tmax) + tol) return std::nan("");
    return t;
}

bool Oracle::in_plane_contact(const kdrt_ray &ray, uint32_t triangle, double t) const {
    if (size_t(triangle) * 9 >= tri_.size()) return false;
    const double *p0 = &tri_[size_t(triangle) * 9], *e1 = p0 + 3, *e2 = p0 + 6;
    const double o[3] = {ray.org[0], ray.org[1], ray.org[2]}, d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double tv[3] = {o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
    if (n[0] * d[0] + n[1] * d[1] + n[2] * d[2] != 0 || n[0] * tv[0] + n[1] * tv[1] + n[2] * tv[2] != 0) return false;
    // In 2D, dropping the normal's largest axis: the t interval where all three edge functions
    // (linear in t) have the triangle's orientation.
    int drop = 0;
    for (int a = 1; a < 3; ++a)
        if (std::fabs(n[a]) > std::fabs(n[drop])) drop = a;
    const int x = (drop + 1) % 3, y = (drop + 2) % 3;
    const double corner[3][2] = {{0, 0}, {e1[x], e1[y]}, {e2[x], e2[y]}};
    const double orient = n[drop] > 0 ? 1 : -1;  // sign of the projected triangle's area
    double lo = std::max(0.0, double(ray.tmin)), hi = ray.tmax;
    for (int k = 0; k < 3; ++k) {
        const double *a = corner[k], *b = corner[(k + 1) % 3];
        const double ex = b[0] - a[0], ey = b[1] - a[1];
        // orient * cross(b - a, q(t) - a) >= 0 with q(t) = (o - p0) + t d, projected
        const double c0 = orient * (ex * (tv[y] - a[1]) - ey * (tv[x] - a[0])), c1 = orient * (ex * d[y] - ey * d[x]);
        if (c1 > 0) lo = std::max(lo, -c0 / c1);
        else if (c1 < 0) hi = std::min(hi, -c0 / c1);
        else if (c0 < 0) return false;
    }
    const double tol = t_tolerance(ray, t);
    if (!(lo <= hi + tol)) return false;  // the ray's line passes beside the triangle
    // kdrt's t for such a hit is a quotient of two rounding errors: all kdrt.h promises is that
    // it lies where the ray is within the triangle's bounding box.
    double blo = std::max(0.0, double(ray.tmin)), bhi = ray.tmax;
    for (int a = 0; a < 3; ++a) {
        double lo_a = std::min({0.0, e1[a], e2[a]}) + p0[a], hi_a = std::max({0.0, e1[a], e2[a]}) + p0[a];
        if (d[a] == 0) {
            if (o[a] < lo_a || o[a] > hi_a) return false;
            continue;
        }
        double ta = (lo_a - o[a]) / d[a], tb = (hi_a - o[a]) / d[a];
        blo = std::max(blo, std::min(ta, tb)), bhi = std::min(bhi, std::max(ta, tb));
    }
    return t >= blo - tol && t <= bhi + tol;
}

bool Oracle::rounding_contact(const kdrt_ray &ray, uint32_t triangle, double t) const {
    if (size_t(triangle) * 9 >= tri_.size()) return false;
    const double *p0 = &tri_[size_t(triangle) * 9], *e1 = p0 + 3, *e2 = p0 + 6;
    const float *d = ray.dir;
    // The test's frame, as kdrt.h sets it up: kz the axis of the largest |dir| (the first of
    // equals), kx and ky the next two, swapped when dir[kz] < 0; the shear in float.
    int kz = 0;
    for (int a = 1; a < 3; ++a)
        if (std::fabs(d[a]) > std::fabs(d[kz])) kz = a;
    int kx = (kz + 1) % 3, ky = (kx + 1) % 3;
    if (d[kz] < 0) std::swap(kx, ky);
    if (d[kz] == 0) return false;
    const float sx = d[kx] / d[kz], sy = d[ky] / d[kz], sz = 1.0f / d[kz];
    // Each corner's sheared coordinates, exactly, and how far the float ones can be from them:
    // a rounding of the difference, the product and the result, each at most 2^-24 of its size.
    const double u = 0x1p-22;  // four such roundings, with room to spare
    double x[3], y[3], z[3], dxe[3], dye[3], dze[3];
    for (int k = 0; k < 3; ++k) {
        const double *add = k == 0 ? nullptr : (k == 1 ? e1 : e2);
        double p[3];
        for (int a = 0; a < 3; ++a) p[a] = p0[a] + (add ? add[a] : 0.0);
        const double dx = p[kx] - ray.org[kx], dy = p[ky] - ray.org[ky], dz = p[kz] - ray.org[kz];
        x[k] = dx - sx * dz, y[k] = dy - sy * dz, z[k] = sz * dz;
        dxe[k] = u * (std::fabs(dx) + std::fabs(sx * dz)), dye[k] = u * (std::fabs(dy) + std::fabs(sy * dz));
        dze[k] = u * std::fabs(z[k]);
    }
    // The edge functions (kdrt forms them in double from the float coordinates) and their
    // error bounds.
    double e[3], err[3];
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3, k = (i + 2) % 3;  // e[i] = x[k] y[j] - y[k] x[j], i's opposite edge
        e[i] = x[k] * y[j] - y[k] * x[j];
        err[i] = (std::fabs(x[k]) + dxe[k]) * dye[j] + dxe[k] * std::fabs(y[j]) + (std::fabs(y[k]) + dye[k]) * dxe[j] +
                 dye[k] * std::fabs(x[j]) + 0x1p-50 * (std::fabs(x[k] * y[j]) + std::fabs(y[k] * x[j]));
    }
    const bool may_be_inside = (e[0] >= -err[0] && e[1] >= -err[1] && e[2] >= -err[2]) ||
                               (e[0] <= err[0] && e[1] <= err[1] && e[2] <= err[2]);
    if (!may_be_inside) return false;
    const double det = e[0] + e[1] + e[2], det_err = err[0] + err[1] + err[2];
    const double z_lo = std::min({z[0] - dze[0], z[1] - dze[1], z[2] - dze[2]});
    const double z_hi = std::max({z[0] + dze[0], z[1] + dze[1], z[2] + dze[2]});
    const double slack = 0x1p-22 * std::max(std::fabs(z_lo), std::fabs(z_hi));
    if (std::fabs(det) <= det_err)  // degenerate within the rounding: any convex combination
        return t >= z_lo - slack && t <= z_hi + slack;
    const double exact = (e[0] * z[0] + e[1] * z[1] + e[2] * z[2]) / det;
    double spread = 0;
    for (int k = 0; k < 3; ++k) spread += err[k] * std::fabs(z[k] - exact) + std::fabs(e[k]) * dze[k];
    spread /= std::fabs(det) - det_err;
    return std::fabs(t - exact) <= spread + t_tolerance(ray, exact, triangle);
}

double Oracle::expected_t(const kdrt_ray &ray, uint32_t triangle, double kdrt_t) const {
    double t = possible_t(ray, triangle);
    const bool close = !std::isnan(t) && std::fabs(kdrt_t - t) <= t_tolerance(ray, t, triangle);
    // See kdrt.h: a ray in the triangle's plane, or within its test's rounding of a hit.
    if (!close && (in_plane_contact(ray, triangle, kdrt_t) || rounding_contact(ray, triangle, kdrt_t))) t = kdrt_t;
    return t;
}

void check_hit(const Oracle &oracle, const Reference &ref, const kdrt_ray &ray, const kdrt_hit &h, Agreement &tally) {
    bool hit = h.triangle != KDRT_INVALID_ID;
    std::ostringstream why;
    ++tally.rays;
    if (!hit) {
        if (ref.sure_hit) why << "kdrt missed, reference hits triangle " << ref.sure_triangle << " at t=" << ref.sure_t;
        else ++tally.exact;  // near-edge misses are fine either way; none is surely hit
    } else {
        double pt = oracle.expected_t(ray, h.triangle, h.t);
        if (std::isnan(pt)) why << "kdrt hit triangle " << h.triangle << " at t=" << h.t << ", which the ray misses";
        else if (std::fabs(h.t - pt) > oracle.t_tolerance(ray, pt, h.triangle)) why << "kdrt t=" << h.t << " on triangle " << h.triangle << ", reference t=" << pt;
        else if (ref.sure_hit && h.t > ref.sure_t + oracle.t_tolerance(ray, ref.sure_t, ref.sure_triangle))
            why << "kdrt hit triangle " << h.triangle << " at t=" << h.t << ", but triangle " << ref.sure_triangle << " is nearer at t=" << ref.sure_t;
        else if (ref.sure_hit && h.triangle == ref.sure_triangle) ++tally.exact;
        else ++tally.ambiguous;
    }
    std::string w = why.str();
    if (!w.empty()) {
        if (tally.wrong++ == 0) {
            std::ostringstream r;
            r.precision(9);
            r << w << "; ray org=(" << ray.org[0] << "," << ray.org[1] << "," << ray.org[2] << ") dir=(" << ray.dir[0] << ","
              << ray.dir[1] << "," << ray.dir[2] << ") tmin=" << ray.tmin << " tmax=" << ray.tmax;
            tally.first_wrong = r.str();
        }
    }
}

std::vector<Reference> reference_all(const Oracle &oracle, const std::vector<kdrt_ray> &rays) {
    std::vector<Reference> refs(rays.size());
    common::timed_parallel(rays.size(), common::all_cores(), [&](size_t i) { refs[i] = oracle.trace(rays[i]); });
    return refs;
}

}  // namespace oracle
