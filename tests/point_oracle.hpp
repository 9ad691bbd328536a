// The brute-force references for kdrt_closest_point() and the overlap queries (test_closest.cpp,
// test_overlap.cpp, fuzz/fuzz_queries.cpp): every triangle, in quadruple precision where the
// compiler has it (__float128: 113 bits, so the products and differences of floats these tests
// draw are exact), else long double. Written apart from kdrt.h's code and in other ways:
//  - the distance to a triangle is the least over the points that can be nearest: its corners,
//    the feet of the point on its edges when inside them, and the foot on its plane when inside
//    it (barycentrics from the Gram matrix);
//  - a triangle meets a box when no axis of the 13 separates their projections, each axis'
//    projections computed for all 3 corners and all 8 box corners;
//  - a triangle meets a ball when that distance is at most the radius.
#pragma once

#include "kdrt.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace oracle {

#if defined(__SIZEOF_FLOAT128__) && !defined(KDRT_ORACLE_LONG_DOUBLE)
__extension__ typedef __float128 Real;
#else
typedef long double Real;
#endif

struct Tri {
    float p[3][3];
};

// The triangles of a mesh (common::Mesh: positions and vertex(triangle, corner)) as floats.
template <class MeshT> std::vector<Tri> triangles_of(const MeshT &mesh) {
    std::vector<Tri> out(mesh.triangle_count());
    for (uint32_t i = 0; i < mesh.triangle_count(); ++i)
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) out[i].p[k][a] = mesh.positions[3 * size_t(mesh.vertex(i, k)) + size_t(a)];
    return out;
}

// Whether kdrt leaves t out of its trees: zero area, its edges' cross product exactly 0.
inline bool zero_area(const Tri &t) {
    Real e0[3], e1[3];
    for (int a = 0; a < 3; ++a) e0[a] = Real(t.p[1][a]) - t.p[0][a], e1[a] = Real(t.p[2][a]) - t.p[0][a];
    return e0[1] * e1[2] - e0[2] * e1[1] == 0 && e0[2] * e1[0] - e0[0] * e1[2] == 0 &&
           e0[0] * e1[1] - e0[1] * e1[0] == 0;
}

inline Real dot(const Real a[3], const Real b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// The squared distance from q to the triangle t, and the barycentrics (u, v) of the nearest point.
inline Real distance2(const Tri &t, const float q[3], Real *u_out = nullptr, Real *v_out = nullptr) {
    Real a[3], e0[3], e1[3], w[3];
    for (int k = 0; k < 3; ++k) {
        a[k] = Real(t.p[0][k]);
        e0[k] = Real(t.p[1][k]) - Real(t.p[0][k]);
        e1[k] = Real(t.p[2][k]) - Real(t.p[0][k]);
        w[k] = Real(q[k]) - a[k];
    }
    Real best = -1, bu = 0, bv = 0;
    auto consider = [&](Real u, Real v) {
        Real d[3];
        for (int k = 0; k < 3; ++k) d[k] = a[k] + u * e0[k] + v * e1[k] - Real(q[k]);
        const Real d2 = dot(d, d);
        if (best < 0 || d2 < best) best = d2, bu = u, bv = v;
    };
    consider(0, 0), consider(1, 0), consider(0, 1);
    // Edges: a + s e0, a + s e1, b + s (c - b).
    const Real ee0 = dot(e0, e0), ee1 = dot(e1, e1), e01 = dot(e0, e1);
    const Real we0 = dot(w, e0), we1 = dot(w, e1);
    if (ee0 > 0 && we0 > 0 && we0 < ee0) consider(we0 / ee0, 0);
    if (ee1 > 0 && we1 > 0 && we1 < ee1) consider(0, we1 / ee1);
    {
        Real e2[3], wb[3];
        for (int k = 0; k < 3; ++k) e2[k] = e1[k] - e0[k], wb[k] = w[k] - e0[k];
        const Real ee2 = dot(e2, e2), s = dot(wb, e2);
        if (ee2 > 0 && s > 0 && s < ee2) consider(1 - s / ee2, s / ee2);
    }
    // The face: the Gram system [ee0 e01; e01 ee1] (u, v) = (we0, we1).
    const Real det = ee0 * ee1 - e01 * e01;
    if (det > 0) {
        const Real u = (we0 * ee1 - we1 * e01) / det, v = (we1 * ee0 - we0 * e01) / det;
        if (u >= 0 && v >= 0 && u + v <= 1) consider(u, v);
    }
    if (u_out) *u_out = bu;
    if (v_out) *v_out = bv;
    return best;
}

inline double distance(const Tri &t, const float q[3]) { return std::sqrt((long double)distance2(t, q)); }

// The largest distance from q to a corner of t: the scale of kdrt's error bound.
inline double reach(const Tri &t, const float q[3]) {
    double r = 0;
    for (int k = 0; k < 3; ++k) {
        double d2 = 0;
        for (int a = 0; a < 3; ++a) d2 += (double(t.p[k][a]) - q[a]) * (double(t.p[k][a]) - q[a]);
        r = std::max(r, std::sqrt(d2));
    }
    return r;
}

// 1 when t meets the closed box [lo, hi] (lo <= hi, finite): no separating axis among the 13.
inline bool meets_box(const Tri &t, const float lo[3], const float hi[3]) {
    Real c[8][3], v[3][3];
    for (int i = 0; i < 8; ++i)
        for (int a = 0; a < 3; ++a) c[i][a] = Real((i >> a) & 1 ? hi[a] : lo[a]);
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) v[k][a] = Real(t.p[k][a]);
    auto separates = [&](const Real axis[3]) {
        if (axis[0] == 0 && axis[1] == 0 && axis[2] == 0) return false;
        Real tmin = dot(axis, v[0]), tmax = tmin, bmin = dot(axis, c[0]), bmax = bmin;
        for (int k = 1; k < 3; ++k) tmin = std::min(tmin, dot(axis, v[k])), tmax = std::max(tmax, dot(axis, v[k]));
        for (int i = 1; i < 8; ++i) bmin = std::min(bmin, dot(axis, c[i])), bmax = std::max(bmax, dot(axis, c[i]));
        return tmax < bmin || bmax < tmin;
    };
    Real e[3][3];
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) e[k][a] = v[(k + 1) % 3][a] - v[k][a];
    for (int a = 0; a < 3; ++a) {
        Real axis[3] = {0, 0, 0};
        axis[a] = 1;
        if (separates(axis)) return false;
    }
    {
        const Real n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                           e[0][0] * e[1][1] - e[0][1] * e[1][0]};
        if (separates(n)) return false;
    }
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) {
            Real unit[3] = {0, 0, 0};
            unit[a] = 1;
            const Real axis[3] = {e[k][1] * unit[2] - e[k][2] * unit[1], e[k][2] * unit[0] - e[k][0] * unit[2],
                                  e[k][0] * unit[1] - e[k][1] * unit[0]};
            if (separates(axis)) return false;
        }
    return true;
}

// An instance's triangle in the world, as kdrt's queries define it: each corner carried by the
// transform in double, in this order, and rounded to float.
inline Tri placed(const Tri &t, const float m[12]) {
    Tri w;
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a)
            w.p[k][a] = float(double(m[4 * a]) * t.p[k][0] + double(m[4 * a + 1]) * t.p[k][1] +
                              double(m[4 * a + 2]) * t.p[k][2] + double(m[4 * a + 3]));
    return w;
}

// The stated accuracy of kdrt_closest_point() (CLOSEST POINT AND OVERLAP): the returned distance
// within 2^-24 of the true minimum plus 2^-44 of the reach of the triangles compared.
constexpr double kRelative = 5.9604644775390625e-08;  // 2^-24
constexpr double kReach = 5.684341886080802e-14;      // 2^-44

}  // namespace oracle
