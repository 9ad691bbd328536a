// Optics: kdrt_reflect, kdrt_refract and the Fresnel functions against references computed here in
// double precision by other routes (Snell's law through angles and asin, transmittance from the
// transmission amplitudes), and exact decisions where the arithmetic can be made exact.
//
// Tolerance for directions: 2^-22 rad (about 2.4e-7, two float ulps at 1). Rounding three
// components to float moves a unit vector by at most about 2^-24 rad; the double arithmetic on
// either side adds at most about 1e-8 rad, even near the critical angle where cos(theta_t) comes
// out of a square root of a number close to 0.
#include "common/random.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

namespace {

using V = std::array<double, 3>;

const double kPi = 3.14159265358979323846;
const double kDirectionTolerance = std::ldexp(1.0, -22);
const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();

V of(const float f[3]) { return V{{f[0], f[1], f[2]}}; }
double dot(const V &a, const V &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V cross(const V &a, const V &b) {
    return V{{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}};
}
double norm(const V &a) { return std::sqrt(dot(a, a)); }
V scaled(const V &a, double s) { return V{{a[0] * s, a[1] * s, a[2] * s}}; }
V plus(const V &a, const V &b) { return V{{a[0] + b[0], a[1] + b[1], a[2] + b[2]}}; }
V unit(const V &a) { return scaled(a, 1.0 / norm(a)); }
// Angle between two directions, accurate at 0 as well (atan2 of |a x b| and a.b).
double angle(const V &a, const V &b) { return std::atan2(norm(cross(a, b)), dot(a, b)); }

// Snell's law in double for the directions of the given float vectors, through the angles.
struct Snell {
    double x;     // eta sin(theta_i): above 1 is total internal reflection
    double cos_i; // of the angle of incidence
    double cos_t; // of the angle of refraction (0 when x >= 1)
    V refracted;  // with theta_t = asin(min(x, 1))
    V mirror;
};

Snell snell(const float incident[3], const float normal[3], double eta) {
    V i = unit(of(incident)), n = unit(of(normal));
    if (dot(i, n) > 0) n = scaled(n, -1.0);
    Snell s;
    s.cos_i = -dot(i, n);
    s.x = eta * norm(cross(i, n));
    double theta_t = std::asin(std::min(s.x, 1.0));
    s.cos_t = std::cos(theta_t);
    V tangent = plus(i, scaled(n, s.cos_i));
    s.refracted = norm(tangent) > 0 ? plus(scaled(unit(tangent), std::sin(theta_t)), scaled(n, -s.cos_t))
                                    : scaled(n, -1.0);
    s.mirror = plus(i, scaled(n, 2.0 * s.cos_i));
    return s;
}

void to_float(const V &v, float f[3]) {
    for (int a = 0; a < 3; ++a) f[a] = static_cast<float>(v[a]);
}

// A random unit vector, and a random unit vector perpendicular to it.
V random_unit(common::Rng &rng) {
    V v;
    rng.direction(v.data());
    return v;
}
V random_perpendicular(const V &n, common::Rng &rng) {
    for (;;) {
        V v = random_unit(rng);
        V p = plus(v, scaled(n, -dot(v, n)));
        if (norm(p) > 1e-3) return unit(p);
    }
}

// The indices of refraction the sweeps use: water, glass, diamond, and nearly 1.
const float kIndices[] = {1.0001f, 1.333f, 1.5f, 2.42f};

// Every eta of the sweeps: each index from outside and from inside.
std::vector<float> sweep_etas() {
    std::vector<float> etas;
    for (float n : kIndices) etas.push_back(n), etas.push_back(1.0f / n);
    return etas;
}

// Exact decision for incident (1, 0, -t), normal (0, 0, 1): sin^2 = 1 / (1 + t^2), so total
// internal reflection is eta^2 > 1 + t^2, i.e. eta^2 - 1 > t^2. In double, eta^2 and t^2 are
// exact (48 significant bits), and so is eta^2 - 1 for 1 <= eta^2 < 2^47 (its bits lie between
// 2^0 and the last bit of eta^2, at most 48 of them): the comparison is exact.
bool exact_tir(float eta, float t) {
    double e2 = static_cast<double>(eta) * eta;
    REQUIRE(e2 >= 1.0);
    return e2 - 1.0 > static_cast<double>(t) * t;
}

// Exact decision for incident (s, 0, -t), normal (0, 0, 1), with integer-valued floats s, t below
// 2^24: total internal reflection is eta^2 s^2 > s^2 + t^2. eta^2, s^2 and s^2 + t^2 (< 2^49) are
// exact doubles; the product eta^2 s^2 is split exactly into hi + lo (Dekker's two-product); near
// the critical angle hi and s^2 + t^2 are within a factor 2, so hi - (s^2 + t^2) is exact
// (Sterbenz), and adding lo rounds once, which keeps the sign.
bool exact_tir_wide(float eta, float s, float t) {
    double e2 = static_cast<double>(eta) * eta, ss = static_cast<double>(s) * s;
    double sum = ss + static_cast<double>(t) * t;
    double hi = e2 * ss, lo = std::fma(e2, ss, -hi);
    REQUIRE((hi >= 0.5 * sum && hi <= 2.0 * sum));
    return (hi - sum) + lo > 0.0;
}

}  // namespace

TEST_CASE("optics: refraction matches Snell's law in double at every angle of incidence", "[optics]") {
    common::Rng rng(20260131);
    const int angles = 1000, normals = 48;
    double worst = 0.0;
    long cases = 0, tir = 0, either = 0;
    for (float eta : sweep_etas()) {
        double critical = eta > 1.0f ? std::asin(1.0 / eta) : -1.0;
        for (int k = 0; k < normals; ++k) {
            // The first normal is the z axis, the rest random; random lengths, either orientation.
            V n = k == 0 ? V{{0, 0, 1}} : random_unit(rng);
            V u = k == 0 ? V{{1, 0, 0}} : random_perpendicular(n, rng);
            double n_length = k == 0 ? 1.0 : rng.range(0.25, 8.0), i_length = k == 0 ? 1.0 : rng.range(0.25, 8.0);
            float normal[3];
            to_float(scaled(n, (k & 1) ? -n_length : n_length), normal);
            std::vector<double> thetas;
            for (int j = 0; j <= angles; ++j) thetas.push_back(kPi / 2 * j / angles);
            if (critical > 0)  // and closer and closer to the critical angle, from both sides
                for (double d = 1e-2; d > 1e-9; d /= 4) thetas.push_back(critical - d), thetas.push_back(critical + d);
            for (double theta : thetas) {
                float incident[3], out[3];
                to_float(scaled(plus(scaled(u, std::sin(theta)), scaled(n, -std::cos(theta))), i_length), incident);
                Snell ref = snell(incident, normal, eta);
                int r = kdrt_refract(incident, normal, eta, out);
                INFO("eta " << eta << ", theta " << theta << " rad, normal " << k);
                // Within 1e-14 of the critical angle, double rounding (about 1e-15 in x, here and
                // in kdrt) may decide either way. The float input lands anywhere within about
                // 1e-7 rad of theta, so the sweep's closest cases come down to around 1e-13.
                if (std::fabs(ref.x - 1.0) <= 1e-14)
                    ++either;
                else
                    REQUIRE(r == (ref.x > 1.0 ? 0 : 1));
                double error = angle(of(out), r ? ref.refracted : ref.mirror);
                CHECK(error <= kDirectionTolerance);
                CHECK(std::fabs(norm(of(out)) - 1.0) <= kDirectionTolerance);
                worst = std::max(worst, error);
                ++cases, tir += r == 0;
            }
        }
    }
    CHECK(either * 1000 <= cases);
    WARN("refraction: " << cases << " cases (" << tir << " totally reflected, " << either
                        << " within 1e-14 of critical), worst direction error " << worst
                        << " rad, tolerance " << kDirectionTolerance);
}

TEST_CASE("optics: total internal reflection exactly at and one ulp around the critical angle", "[optics]") {
    const float normal[3] = {0, 0, 1};
    SECTION("exactly critical: incident (1, 0, -0.75) from eta 1.25 refracts to the grazing direction") {
        // sin(theta_i) = 1 / 1.25 = 0.8: eta sin(theta_i) = 1 exactly (a 3-4-5 triangle).
        const float incidents[][3] = {{1, 0, -0.75f}, {4, 0, -3}, {0, -4, -3}, {-1, 0, 0.75f}};
        const float grazing[][3] = {{1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {-1, 0, 0}};
        for (int c = 0; c < 4; ++c) {
            float out[3] = {9, 9, 9};
            REQUIRE(kdrt_refract(incidents[c], normal, 1.25f, out) == 1);
            CHECK(out[0] == grazing[c][0]);
            CHECK(out[1] == grazing[c][1]);
            CHECK(std::fabs(out[2]) <= 1e-16f);
        }
        // eta = 1 at grazing incidence: k = 0 as well; the light goes straight on.
        const float along[3] = {0, 1, 0};
        float out[3];
        REQUIRE(kdrt_refract(along, normal, 1.0f, out) == 1);
        CHECK((out[0] == 0 && out[1] == 1 && out[2] == 0));
    }
    SECTION("one and two ulps either side of the 3-4-5 critical angle, in t and in eta") {
        float t = 0.75f, eta = 1.25f;
        float t_down = std::nextafter(t, 0.0f), t_up = std::nextafter(t, 1.0f);
        float eta_down = std::nextafter(eta, 0.0f), eta_up = std::nextafter(eta, 2.0f);
        struct { float eta, t; int expected; } cases[] = {
            {eta, t_down, 0}, {eta, std::nextafter(t_down, 0.0f), 0},
            {eta, t_up, 1}, {eta, std::nextafter(t_up, 1.0f), 1},
            {eta_up, t, 0}, {std::nextafter(eta_up, 2.0f), t, 0},
            {eta_down, t, 1}, {std::nextafter(eta_down, 0.0f), t, 1}};
        for (auto c : cases) {
            const float incident[3] = {1, 0, -c.t};
            float out[3];
            INFO("eta " << c.eta << ", t " << c.t);
            CHECK(exact_tir(c.eta, c.t) == (c.expected == 0));
            CHECK(kdrt_refract(incident, normal, c.eta, out) == c.expected);
        }
    }
    SECTION("k nonzero but below one rounding of eta^2 |i x n|^2: the fma still decides right") {
        // Found offline with exact rational arithmetic (continued-fraction convergents t/s of
        // sqrt(eta^2 - 1)): each is total internal reflection by about 1e-17 of eta^2 s^2, and
        // |i|^2 |n|^2 - eta^2 |i x n|^2 with the product rounded first comes out exactly 0.
        struct { float eta, s, t; } cases[] = {
            {2.9650495052337646f, 5779912, 16133637}, {1.0905953645706177f, 16254965, 7074146},
            {1.5425435304641724f, 13560430, 15926669}, {1.0578174591064453f, 15389746, 5308409},
            {1.7680059671401978f, 9182521, 13388371}, {2.030590295791626f, 3847701, 6799985}};
        for (auto c : cases) {
            const float incident[3] = {c.s, 0, -c.t};
            double e2 = static_cast<double>(c.eta) * c.eta, ss = static_cast<double>(c.s) * c.s;
            volatile double product = e2 * ss;  // rounded on its own, as without an fma
            float out[3];
            INFO("eta " << c.eta << ", s " << c.s << ", t " << c.t);
            REQUIRE(exact_tir_wide(c.eta, c.s, c.t));
            REQUIRE(ss + static_cast<double>(c.t) * c.t - product == 0.0);
            CHECK(kdrt_refract(incident, normal, c.eta, out) == 0);
        }
    }
    SECTION("2,000 random etas: the floats t nearest the critical t* = sqrt(eta^2 - 1) and 3 ulps around") {
        common::Rng rng(7);
        int decided = 0, reflected = 0;
        for (int k = 0; k < 2000; ++k) {
            float eta = float(rng.range(1.001, 4.0));
            float t = static_cast<float>(std::sqrt(static_cast<double>(eta) * eta - 1.0));
            for (int s = 0; s < 3; ++s) t = std::nextafter(t, 0.0f);
            for (int s = 0; s < 7; ++s, t = std::nextafter(t, 100.0f)) {
                // The same geometry turned to each axis and mirrored: all exact operations.
                for (int axis = 0; axis < 3; ++axis) {
                    float incident[3] = {0, 0, 0}, axis_normal[3] = {0, 0, 0}, out[3];
                    incident[axis] = -t, axis_normal[axis] = (k & 1) ? -1.0f : 1.0f;
                    incident[(axis + 1) % 3] = (k & 2) ? -1.0f : 1.0f;
                    bool tir = exact_tir(eta, t);
                    INFO("eta " << eta << ", t " << t << ", axis " << axis);
                    REQUIRE(kdrt_refract(incident, axis_normal, eta, out) == (tir ? 0 : 1));
                    ++decided, reflected += tir;
                }
            }
        }
        WARN("critical angle: " << decided << " decisions matched the exact ones (" << reflected << " reflections)");
    }
}

TEST_CASE("optics: normal incidence goes straight through, and eta = 1 changes nothing", "[optics]") {
    common::Rng rng(3);
    for (float eta : sweep_etas()) {
        // Along an axis the result is exact.
        const float down[3] = {0, 0, -1}, up[3] = {0, 0, 1};
        float out[3];
        REQUIRE(kdrt_refract(down, up, eta, out) == 1);
        CHECK((out[0] == 0 && out[1] == 0 && out[2] == -1));
        REQUIRE(kdrt_refract(down, down, eta, out) == 1);  // the normal facing away from the light
        CHECK((out[0] == 0 && out[1] == 0 && out[2] == -1));
        for (int k = 0; k < 200; ++k) {
            V n = random_unit(rng);
            float normal[3], incident[3];
            to_float(n, normal);
            to_float(scaled(n, (k & 1) ? 3.0 : -0.5), incident);
            REQUIRE(kdrt_refract(incident, normal, eta, out) == 1);
            CHECK(angle(of(out), unit(of(incident))) <= kDirectionTolerance);
        }
    }
    for (int k = 0; k < 2000; ++k) {
        float normal[3], incident[3], out[3];
        to_float(random_unit(rng), normal);
        to_float(scaled(random_unit(rng), 1.0 + k), incident);
        REQUIRE(kdrt_refract(incident, normal, 1.0f, out) == 1);
        // Rounding the unit vector incident / |incident| to float: half an ulp per component.
        CHECK(angle(of(out), of(incident)) <= std::ldexp(1.0, -23));
    }
}

TEST_CASE("optics: refracting back returns the original direction", "[optics]") {
    // Out through the surface with eta and back with 1/eta (as a float) must give -incident. The
    // first trip's rounding is magnified on the way back by d(theta_i)/d(theta_t) =
    // cos(theta_t) / (eta cos(theta_i)), and a float 1/eta is off by up to 2^-24, which moves
    // theta_i by tan(theta_i) times that.
    common::Rng rng(11);
    const float etas[] = {0.5f, 2.0f, 1.0f / 1.5f, 1.5f, 1.0f / 1.333f, 1.333f};
    int checked = 0;
    for (float eta : etas) {
        float back = 1.0f / eta;
        double reciprocal_error = std::fabs(static_cast<double>(eta) * back - 1.0);
        for (int k = 0; k < 4000; ++k) {
            V n = random_unit(rng), u = random_perpendicular(n, rng);
            double theta = (89.0 * kPi / 180.0) * (k + 0.5) / 4000;
            float normal[3], incident[3], there[3], minus_there[3], again[3];
            to_float(n, normal);
            to_float(plus(scaled(u, std::sin(theta)), scaled(n, -std::cos(theta))), incident);
            Snell ref = snell(incident, normal, eta);
            if (kdrt_refract(incident, normal, eta, there) != 1) {
                CHECK(ref.x > 1.0);
                continue;
            }
            for (int a = 0; a < 3; ++a) minus_there[a] = -there[a];
            INFO("eta " << eta << ", theta " << theta);
            REQUIRE(kdrt_refract(minus_there, normal, back, again) == 1);
            double tolerance = kDirectionTolerance * (1.0 + ref.cos_t / (eta * ref.cos_i)) +
                               2.0 * reciprocal_error * std::tan(theta);
            CHECK(angle(of(again), scaled(of(incident), -1.0)) <= tolerance);
            ++checked;
        }
    }
    // All of the first trips from the less dense side; from the denser side those below the
    // critical angle (30, 41.8 and 48.6 of the 89 degrees for 2, 1.5 and 1.333).
    CHECK(checked > 17000);
}

TEST_CASE("optics: reflection mirrors about the normal, whichever way it faces", "[optics]") {
    const float incident[3] = {3, -4, 0}, up[3] = {0, 2, 0}, down[3] = {0, -0.5f, 0};
    float out[3];
    kdrt_reflect(incident, up, out);
    CHECK((out[0] == 0.6f && out[1] == 0.8f && out[2] == 0));
    kdrt_reflect(incident, down, out);
    CHECK((out[0] == 0.6f && out[1] == 0.8f && out[2] == 0));
    // In place, and what kdrt_refract writes on total internal reflection, bit for bit.
    common::Rng rng(5);
    for (int k = 0; k < 1000; ++k) {
        float normal[3], dir[3], mirror[3], refracted[3];
        to_float(random_unit(rng), normal);
        to_float(scaled(random_unit(rng), 0.1 + k), dir);
        V expected = snell(dir, normal, 1.0).mirror;
        kdrt_reflect(dir, normal, mirror);
        CHECK(angle(of(mirror), expected) <= kDirectionTolerance);
        CHECK(std::fabs(norm(of(mirror)) - 1.0) <= kDirectionTolerance);
        if (kdrt_refract(dir, normal, 100.0f, refracted) == 0)
            CHECK(std::memcmp(refracted, mirror, sizeof mirror) == 0);
        kdrt_reflect(dir, normal, dir);
        CHECK(std::memcmp(dir, mirror, sizeof mirror) == 0);
    }
}

TEST_CASE("optics: bad input gives the documented output, never a crash or a new NaN", "[optics]") {
    const float good[3] = {0.6f, 0, -0.8f}, normal[3] = {0, 0, 1}, zero[3] = {0, 0, 0};
    const float nan_v[3] = {0, kNaN, 1}, inf_v[3] = {kInf, 0, 1};
    const float *vectors[] = {zero, nan_v, inf_v};
    for (const float *bad : vectors) {
        float out[3];
        REQUIRE(kdrt_refract(bad, normal, 1.5f, out) == -1);
        CHECK(std::memcmp(out, bad, sizeof out) == 0);
        REQUIRE(kdrt_refract(good, bad, 1.5f, out) == -1);
        CHECK(std::memcmp(out, good, sizeof out) == 0);
        kdrt_reflect(bad, normal, out);
        CHECK(std::memcmp(out, bad, sizeof out) == 0);
        kdrt_reflect(good, bad, out);
        CHECK(std::memcmp(out, good, sizeof out) == 0);
    }
    const float bad_etas[] = {0.0f, -0.0f, -1.5f, kNaN, kInf, -kInf};
    for (float eta : bad_etas) {
        float out[3];
        CHECK(kdrt_refract(good, normal, eta, out) == -1);
        CHECK(std::memcmp(out, good, sizeof out) == 0);
        CHECK(kdrt_fresnel_dielectric(0.5f, eta) == 0.0f);
        CHECK(kdrt_fresnel_schlick(0.5f, eta) == 0.0f);
    }
    CHECK(kdrt_fresnel_dielectric(kNaN, 1.5f) == 0.0f);
    CHECK(kdrt_fresnel_schlick(kNaN, 1.5f) == 0.0f);
    float out[3] = {7, 7, 7};
    CHECK(kdrt_refract(nullptr, normal, 1.5f, out) == -1);
    CHECK(kdrt_refract(good, nullptr, 1.5f, out) == -1);
    CHECK(out[0] == 7);
    CHECK(kdrt_refract(good, normal, 1.5f, nullptr) == -1);
    kdrt_reflect(nullptr, normal, out);
    kdrt_reflect(good, normal, nullptr);
    CHECK(out[0] == 7);
    kdrt_fresnel_dielectric_sp(0.5f, 1.5f, nullptr, nullptr);
    // Extreme but valid: finite results, unit length, whatever the magnitudes.
    const float huge[3] = {3e38f, -3e38f, -3e38f}, tiny[3] = {1e-45f, 0, -1e-45f};
    const float extreme_etas[] = {1e-45f, 1e-20f, 1e20f, 3.4e38f};
    const float *extremes[] = {huge, tiny, good};
    for (const float *a : extremes)
        for (const float *b : extremes)
            for (float eta : extreme_etas) {
                int r = kdrt_refract(a, b, eta, out);
                CHECK((r == 0 || r == 1));
                CHECK((std::isfinite(out[0]) && std::isfinite(out[1]) && std::isfinite(out[2])));
                CHECK(std::fabs(norm(of(out)) - 1.0) < 1e-6);
                float rs, rp;
                kdrt_fresnel_dielectric_sp(a[2] / 3e38f, eta, &rs, &rp);
                CHECK((rs >= 0 && rs <= 1 && rp >= 0 && rp <= 1));
            }
}

TEST_CASE("optics: Fresnel reflectance plus transmittance is 1, from both sides", "[optics]") {
    // The transmittances come from the transmission amplitudes t_s = 2 eta c / (eta c + c_t),
    // t_p = 2 eta c / (c + eta c_t), weighted by the beam's change of width and speed,
    // c_t / (eta c): T_s = 4 eta c c_t / (eta c + c_t)^2, T_p = 4 eta c c_t / (c + eta c_t)^2.
    const double tolerance = std::ldexp(1.0, -23);  // R is a float in [0, 1]: half an ulp at 1
    int transmitted = 0;
    for (float eta : sweep_etas()) {
        for (int k = 0; k <= 10000; ++k) {
            float cos_i = k / 10000.0f, rs, rp;
            kdrt_fresnel_dielectric_sp(cos_i, eta, &rs, &rp);
            float r = kdrt_fresnel_dielectric(cos_i, eta);
            INFO("eta " << eta << ", cos_i " << cos_i);
            // cos^2(theta_t) = 1 - eta^2 (1 - c^2), rounded once: near the critical angle R
            // depends steeply on cos_t, so a reference cos_t rounded twice would be too rough.
            double c = cos_i, e = eta, ct2 = std::fma(e * e, c * c, 1.0 - e * e);
            if (ct2 < 0.0) {  // total internal reflection: nothing is transmitted
                CHECK((rs == 1.0f && rp == 1.0f && r == 1.0f));
                continue;
            }
            double ct = std::sqrt(ct2);
            double ts = 4 * e * c * ct / ((e * c + ct) * (e * c + ct));
            double tp = 4 * e * c * ct / ((c + e * ct) * (c + e * ct));
            CHECK(std::fabs(rs + ts - 1.0) <= tolerance);
            CHECK(std::fabs(rp + tp - 1.0) <= tolerance);
            CHECK(std::fabs(r - 0.5 * (rs + rp)) <= std::ldexp(1.0, -24));
            ++transmitted;
            // Stokes: the same reflectance from the other side, at the angle of refraction. The
            // float cos_t and 1/eta are rounded, and near a critical angle or for eta near 1 R is
            // steep in both, so the tolerance adds four times the change of R over one float ulp
            // of each.
            if (cos_i > 0) {
                float ct_f = static_cast<float>(ct), back = 1.0f / eta;
                float other = kdrt_fresnel_dielectric(ct_f, back);
                double slope = std::fabs(kdrt_fresnel_dielectric(std::nextafter(ct_f, 2.0f), back) - other) +
                               std::fabs(kdrt_fresnel_dielectric(ct_f, std::nextafter(back, 2.0f)) - other);
                CHECK(std::fabs(other - r) <= 1e-6 + 4 * slope);
            }
        }
    }
    CHECK(transmitted > 50000);
    // Grazing incidence reflects everything; eta = 1 is no surface at all.
    CHECK(kdrt_fresnel_dielectric(0.0f, 1.0f / 1.5f) == 1.0f);
    CHECK(kdrt_fresnel_dielectric(0.0f, 1.5f) == 1.0f);
    for (int k = 0; k <= 100; ++k) {
        CHECK(kdrt_fresnel_dielectric(k / 100.0f, 1.0f) == 0.0f);
        CHECK(kdrt_fresnel_schlick(k / 100.0f, 1.0f) == 0.0f);
    }
    // Only the magnitude of cos_i counts, and it is at most 1.
    CHECK(kdrt_fresnel_dielectric(-0.3f, 1.5f) == kdrt_fresnel_dielectric(0.3f, 1.5f));
    CHECK(kdrt_fresnel_dielectric(1.5f, 1.5f) == kdrt_fresnel_dielectric(1.0f, 1.5f));
}

TEST_CASE("optics: textbook reflectances at normal incidence and at Brewster's angle", "[optics]") {
    SECTION("normal incidence: ((n - 1) / (n + 1))^2 from either side") {
        // Glass and n = 2 with their values written out, water and diamond from the formula.
        struct { float n; double r; } book[] = {{1.5f, 0.04}, {2.0f, 1.0 / 9.0},
                                                {1.333f, (0.333 / 2.333) * (0.333 / 2.333)},
                                                {2.42f, (1.42 / 3.42) * (1.42 / 3.42)}};
        for (auto b : book) {
            INFO("n " << b.n);
            CHECK(kdrt_fresnel_dielectric(1.0f, b.n) == Approx(b.r).epsilon(1e-6));
            CHECK(kdrt_fresnel_dielectric(1.0f, 1.0f / b.n) == Approx(b.r).epsilon(1e-6));
            CHECK(kdrt_fresnel_schlick(1.0f, b.n) == Approx(b.r).epsilon(1e-6));
            CHECK(kdrt_fresnel_schlick(1.0f, 1.0f / b.n) == Approx(b.r).epsilon(1e-6));
            float rs, rp;
            kdrt_fresnel_dielectric_sp(1.0f, b.n, &rs, &rp);
            CHECK(rs == rp);
        }
        CHECK(kdrt_fresnel_dielectric(1.0f, 1.5f) == 0.04f);
    }
    SECTION("Brewster: rp = 0 at tan(theta) = 1 / eta, and rs = ((1 - eta^2) / (1 + eta^2))^2") {
        const float etas[] = {1.0f / 1.5f, 1.5f, 1.0f / 1.333f, 1.333f, 1.0f / 2.42f, 2.42f};
        for (float eta : etas) {
            double e = eta, cos_b = e / std::sqrt(1.0 + e * e);
            float c = static_cast<float>(cos_b), rs, rp, rs_far, rp_far;
            kdrt_fresnel_dielectric_sp(c, eta, &rs, &rp);
            INFO("eta " << eta << ", cos " << c << ": rs " << rs << ", rp " << rp);
            // The float nearest cos_b misses Brewster's angle by up to half an ulp, which leaves
            // rp of order (2^-24 times the amplitude's slope)^2; both float neighbours are farther.
            CHECK(rp <= 1e-12f);
            for (float neighbour : {std::nextafter(c, 0.0f), std::nextafter(c, 1.0f)}) {
                float rs_n, rp_n;
                kdrt_fresnel_dielectric_sp(neighbour, eta, &rs_n, &rp_n);
                CHECK(rp <= rp_n);
            }
            CHECK(rs == Approx((1 - e * e) * (1 - e * e) / ((1 + e * e) * (1 + e * e))).epsilon(1e-6));
            for (float step : {-1e-3f, 1e-3f}) {
                kdrt_fresnel_dielectric_sp(c + step, eta, &rs_far, &rp_far);
                CHECK(rp_far > 1e-8f);  // a minimum, not a flat stretch
            }
        }
    }
}

TEST_CASE("optics: Schlick's approximation is off by no more than the header says", "[optics]") {
    // The header states 0.036 for glass (eta 1.5 or 1/1.5) and 0.060 for water (1.333); the
    // measured maxima must be within 3% of those figures, so the statement is neither false nor slack.
    struct { float n; double stated; } cases[] = {{1.5f, 0.036}, {1.333f, 0.060}};
    for (auto c : cases) {
        for (float eta : {c.n, 1.0f / c.n}) {
            double worst = 0.0, worst_cos = 0.0;
            for (int k = 0; k <= 1000000; ++k) {
                float cos_i = k / 1000000.0f;
                double error = std::fabs(static_cast<double>(kdrt_fresnel_schlick(cos_i, eta)) -
                                         kdrt_fresnel_dielectric(cos_i, eta));
                if (error > worst) worst = error, worst_cos = cos_i;
            }
            WARN("Schlick, eta " << eta << ": largest error " << worst << " at "
                                 << std::acos(worst_cos) * 180 / kPi << " degrees");
            CHECK(worst <= c.stated);
            CHECK(worst >= 0.97 * c.stated);
        }
    }
    // Exact where it is defined to be: normal incidence (R0), grazing incidence and total
    // internal reflection (1).
    CHECK(kdrt_fresnel_schlick(0.0f, 1.0f / 1.5f) == 1.0f);
    CHECK(kdrt_fresnel_schlick(0.5f, 1.5f) == 1.0f);
}

// ---- the medium stack ----

namespace {

struct Crossing {
    int entering, real;
    float eta_incident, eta_transmitted;
};

// Classifies the surface, checks it against what is expected, then crosses it as the manual's
// loop does (a real surface is taken as transmitted), checking the current index afterwards.
void cross(kdrt_media_stack &stack, uint32_t object, float ior, int priority, Crossing expected) {
    kdrt_media_crossing x = kdrt_media_at_surface(&stack, object, ior, priority);
    INFO("object " << object << ": expected entering " << expected.entering << ", real " << expected.real
                   << ", eta " << expected.eta_incident << " -> " << expected.eta_transmitted);
    CHECK(x.entering == expected.entering);
    CHECK(x.real == expected.real);
    CHECK(x.eta_incident == expected.eta_incident);
    CHECK(x.eta_transmitted == expected.eta_transmitted);
    CHECK(kdrt_media_current_ior(&stack) == expected.eta_incident);
    kdrt_result r = x.entering ? kdrt_media_enter(&stack, object, ior, priority) : kdrt_media_leave(&stack, object);
    REQUIRE(r == KDRT_SUCCESS);
    CHECK(kdrt_media_current_ior(&stack) == expected.eta_transmitted);
    CHECK(kdrt_media_contains(&stack, object) == expected.entering);
}

const float kAir = 1.000293f, kWater = 1.333f, kGlass = 1.5f, kFlint = 1.62f;

}  // namespace

TEST_CASE("media: a glass ball in water, entered and left along a ray", "[optics]") {
    kdrt_media_stack stack;
    REQUIRE(kdrt_media_init(&stack, kAir) == KDRT_SUCCESS);
    CHECK(kdrt_media_current_ior(&stack) == kAir);
    CHECK(kdrt_media_current_object(&stack) == KDRT_INVALID_ID);
    const uint32_t water = 1, ball = 2;
    cross(stack, water, kWater, 0, {1, 1, kAir, kWater});
    cross(stack, ball, kGlass, 0, {1, 1, kWater, kGlass});
    CHECK(kdrt_media_current_object(&stack) == ball);
    // A total internal reflection inside the ball changes nothing: the next hit is the ball again.
    kdrt_media_crossing inside = kdrt_media_at_surface(&stack, ball, kGlass, 0);
    CHECK((inside.entering == 0 && inside.real == 1));
    cross(stack, ball, kGlass, 0, {0, 1, kGlass, kWater});
    cross(stack, water, kWater, 0, {0, 1, kWater, kAir});
    CHECK(stack.count == 0);
    CHECK(kdrt_media_current_ior(&stack) == kAir);
}

TEST_CASE("media: two touching and two overlapping spheres, crossed in either order", "[optics]") {
    const uint32_t a = 10, b = 20;
    kdrt_media_stack stack;
    REQUIRE(kdrt_media_init(&stack, 1.0f) == KDRT_SUCCESS);
    SECTION("overlapping: in A, in B, out of A, out of B; B, the latest, fills the overlap") {
        cross(stack, a, kGlass, 0, {1, 1, 1.0f, kGlass});
        cross(stack, b, kFlint, 0, {1, 1, kGlass, kFlint});
        cross(stack, a, kGlass, 0, {0, 0, kFlint, kFlint});  // A's surface inside B: false
        CHECK(kdrt_media_current_object(&stack) == b);
        cross(stack, b, kFlint, 0, {0, 1, kFlint, 1.0f});
    }
    SECTION("overlapping: in A, in B, out of B, out of A") {
        cross(stack, a, kGlass, 0, {1, 1, 1.0f, kGlass});
        cross(stack, b, kFlint, 0, {1, 1, kGlass, kFlint});
        cross(stack, b, kFlint, 0, {0, 1, kFlint, kGlass});
        cross(stack, a, kGlass, 0, {0, 1, kGlass, 1.0f});
    }
    SECTION("touching: at the common point the hits come out of A first, or into B first") {
        kdrt_media_stack other = stack;
        cross(stack, a, kGlass, 0, {1, 1, 1.0f, kGlass});
        cross(stack, a, kGlass, 0, {0, 1, kGlass, 1.0f});
        cross(stack, b, kFlint, 0, {1, 1, 1.0f, kFlint});
        cross(other, a, kGlass, 0, {1, 1, 1.0f, kGlass});
        cross(other, b, kFlint, 0, {1, 1, kGlass, kFlint});
        cross(other, a, kGlass, 0, {0, 0, kFlint, kFlint});
        // Either way the ray ends up in B alone.
        CHECK((stack.count == 1 && other.count == 1));
        CHECK(std::memcmp(&stack.media[0], &other.media[0], sizeof stack.media[0]) == 0);
        cross(stack, b, kFlint, 0, {0, 1, kFlint, 1.0f});
    }
}

TEST_CASE("media: Schmidt and Budge priorities, a glass of water with overlapping surfaces", "[optics]") {
    // The water's volume overlaps the glass's walls; the glass has the higher priority, so the
    // water's surfaces inside the walls are false, and the walls' inner surfaces are glass/water.
    const uint32_t glass = 1, water = 2;
    kdrt_media_stack stack;
    REQUIRE(kdrt_media_init(&stack, kAir) == KDRT_SUCCESS);
    cross(stack, glass, kGlass, 2, {1, 1, kAir, kGlass});     // into the side wall
    cross(stack, water, kWater, 1, {1, 0, kGlass, kGlass});   // the water's side, inside the wall
    cross(stack, glass, kGlass, 2, {0, 1, kGlass, kWater});   // the wall's inner face
    cross(stack, glass, kGlass, 2, {1, 1, kWater, kGlass});   // into the bottom
    cross(stack, water, kWater, 1, {0, 0, kGlass, kGlass});   // the water's bottom, inside it
    cross(stack, glass, kGlass, 2, {0, 1, kGlass, kAir});     // out of the bottom
    CHECK(stack.count == 0);
    // Equal priorities: the plain stack, where the latest entered medium is current.
    cross(stack, glass, kGlass, 0, {1, 1, kAir, kGlass});
    cross(stack, water, kWater, 0, {1, 1, kGlass, kWater});
    // A higher priority entered later wins at once; a lower one entered later is false.
    cross(stack, 3, kFlint, 5, {1, 1, kWater, kFlint});
    cross(stack, 4, 2.0f, -1, {1, 0, kFlint, kFlint});
    CHECK(kdrt_media_current_object(&stack) == 3);
}

TEST_CASE("media: a full stack and leaving an object not entered are errors that change nothing", "[optics]") {
    kdrt_media_stack stack;
    REQUIRE(kdrt_media_init(&stack, 1.0f) == KDRT_SUCCESS);
    for (uint32_t k = 0; k < KDRT_MEDIA_STACK_CAPACITY; ++k)
        REQUIRE(kdrt_media_enter(&stack, 100 + k, 1.0f + k / 64.0f, 0) == KDRT_SUCCESS);
    kdrt_media_stack before = stack;
    CHECK(kdrt_media_enter(&stack, 999, 1.5f, 0) == KDRT_ERROR_MEDIA_STACK_FULL);
    CHECK(std::memcmp(&stack, &before, sizeof stack) == 0);
    CHECK(kdrt_media_leave(&stack, 999) == KDRT_ERROR_NOT_IN_MEDIUM);
    CHECK(std::memcmp(&stack, &before, sizeof stack) == 0);
    CHECK(kdrt_media_enter(&stack, 999, kNaN, 0) == KDRT_ERROR_INVALID_IOR);
    for (kdrt_result r : {KDRT_ERROR_MEDIA_STACK_FULL, KDRT_ERROR_NOT_IN_MEDIUM, KDRT_ERROR_INVALID_IOR})
        CHECK(std::strcmp(kdrt_result_string(r), "unknown kdrt_result") != 0);
    // Leaving from the middle keeps the others in order; after that there is room again.
    REQUIRE(kdrt_media_leave(&stack, 105) == KDRT_SUCCESS);
    CHECK(stack.count == KDRT_MEDIA_STACK_CAPACITY - 1);
    for (uint32_t k = 0; k + 1 < KDRT_MEDIA_STACK_CAPACITY; ++k)
        CHECK(stack.media[k].object == 100 + k + (k >= 5));
    CHECK(kdrt_media_enter(&stack, 999, 1.5f, 0) == KDRT_SUCCESS);

    kdrt_media_stack empty;
    REQUIRE(kdrt_media_init(&empty, 1.0f) == KDRT_SUCCESS);
    before = empty;
    CHECK(kdrt_media_leave(&empty, 7) == KDRT_ERROR_NOT_IN_MEDIUM);
    CHECK(std::memcmp(&empty, &before, sizeof empty) == 0);
}

TEST_CASE("media: bad arguments and a corrupted count never crash", "[optics]") {
    kdrt_media_stack stack;
    for (float bad : {0.0f, -1.0f, kNaN, kInf}) {
        CHECK(kdrt_media_init(&stack, bad) == KDRT_ERROR_INVALID_IOR);
        CHECK((stack.count == 0 && kdrt_media_current_ior(&stack) == 1.0f));  // usable: vacuum
        CHECK(kdrt_media_enter(&stack, 1, bad, 0) == KDRT_ERROR_INVALID_IOR);
        CHECK(stack.count == 0);
    }
    CHECK(kdrt_media_init(nullptr, 1.0f) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_media_enter(nullptr, 1, 1.5f, 0) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_media_leave(nullptr, 1) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_media_current_ior(nullptr) == 1.0f);
    CHECK(kdrt_media_current_object(nullptr) == KDRT_INVALID_ID);
    CHECK(kdrt_media_contains(nullptr, 1) == 0);
    kdrt_media_crossing x = kdrt_media_at_surface(nullptr, 1, 1.5f, 0);
    CHECK((x.entering == 1 && x.real == 1 && x.eta_incident == 1.0f && x.eta_transmitted == 1.5f));
    // The same object entered twice is held twice, and left one entry at a time.
    REQUIRE(kdrt_media_init(&stack, 1.0f) == KDRT_SUCCESS);
    REQUIRE(kdrt_media_enter(&stack, 3, 1.5f, 0) == KDRT_SUCCESS);
    REQUIRE(kdrt_media_enter(&stack, 3, 1.6f, 0) == KDRT_SUCCESS);
    CHECK(kdrt_media_current_ior(&stack) == 1.6f);
    REQUIRE(kdrt_media_leave(&stack, 3) == KDRT_SUCCESS);
    CHECK((kdrt_media_contains(&stack, 3) == 1 && kdrt_media_current_ior(&stack) == 1.5f));
    // A count beyond the capacity (memory the caller scribbled over) reads no further than the array.
    stack.count = 0xFFFFFFF0u;
    CHECK(kdrt_media_enter(&stack, 4, 1.5f, 0) == KDRT_ERROR_MEDIA_STACK_FULL);
    (void)kdrt_media_current_ior(&stack);
    (void)kdrt_media_at_surface(&stack, 5, 1.5f, 0);
    CHECK(kdrt_media_leave(&stack, 3) == KDRT_SUCCESS);
    CHECK(stack.count == KDRT_MEDIA_STACK_CAPACITY - 1);
}

TEST_CASE("media: through parallel slabs of water and glass the ray leaves as it came", "[optics]") {
    // Air, a water layer, a glass plate inside it, and back out, all faces parallel to z = 0:
    // n sin(theta) is the same in every layer, so the direction out equals the direction in.
    const uint32_t water = 1, plate = 2;
    const float up[3] = {0, 0, 1};
    const uint32_t faces[] = {water, plate, plate, water};
    const float iors[] = {0, kWater, kGlass};
    common::Rng rng(17);
    for (int k = 0; k < 500; ++k) {
        V u = random_perpendicular(V{{0, 0, 1}}, rng);
        double theta = (80.0 * kPi / 180.0) * k / 500;
        float start[3], dir[3];
        to_float(plus(scaled(u, std::sin(theta)), V{{0, 0, -std::cos(theta)}}), start);
        std::memcpy(dir, start, sizeof dir);
        kdrt_media_stack stack;
        REQUIRE(kdrt_media_init(&stack, kAir) == KDRT_SUCCESS);
        for (uint32_t obj : faces) {
            kdrt_media_crossing x = kdrt_media_at_surface(&stack, obj, iors[obj], 0);
            REQUIRE(x.real == 1);
            REQUIRE(kdrt_refract(dir, up, x.eta_incident / x.eta_transmitted, dir) == 1);
            REQUIRE((x.entering ? kdrt_media_enter(&stack, obj, iors[obj], 0) : kdrt_media_leave(&stack, obj)) ==
                    KDRT_SUCCESS);
        }
        CHECK(stack.count == 0);
        // Four refractions, each within the direction tolerance; an error made in a layer of
        // index n reaches the way out magnified by n cos(theta_n) / cos(theta) <= n / cos(theta).
        INFO("theta " << theta);
        double magnification = (kWater + kGlass + kWater + 1.0) / std::cos(theta);
        CHECK(angle(of(dir), of(start)) <= magnification * kDirectionTolerance);
    }
}
