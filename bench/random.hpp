// The seeded generator behind every generated mesh and ray set of the tests and the bench:
// splitmix64, so the same seed gives the same numbers on every standard library.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace kt {

struct Rng {
    uint64_t state;
    explicit Rng(uint64_t seed) : state(0x9E3779B97F4A7C15ull ^ (seed * 0xD1B54A32D192ED03ull)) {}
    uint64_t next() {
        state += 0x9E3779B97F4A7C15ull;
        uint64_t z = state;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
    double range(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    uint32_t below(uint32_t n) { return uint32_t(uniform() * n); }
    // A uniformly distributed unit vector.
    void direction(double d[3]) {
        const double pi = 3.14159265358979323846;
        double z = range(-1, 1), phi = range(0, 2 * pi), r = std::sqrt(std::max(0.0, 1 - z * z));
        d[0] = r * std::cos(phi), d[1] = r * std::sin(phi), d[2] = z;
    }
};

}  // namespace kt
