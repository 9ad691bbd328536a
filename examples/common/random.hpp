// The one seeded random stream of the programs around kdrt (generated meshes, ray sets, the
// renderer's samples): splitmix64 (Steele, Lea & Flood 2014), so the same seed gives the same
// numbers with every compiler and standard library, unlike std's distributions.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace common {

// splitmix64's output function: a bijective hash of 64 bits, also good for mixing seeds.
inline uint64_t splitmix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

struct Rng {
    uint64_t state;
    // The stream of `seed`, mixed so that neighbouring seeds give unrelated streams.
    explicit Rng(uint64_t seed) : state(0x9E3779B97F4A7C15ull ^ (seed * 0xD1B54A32D192ED03ull)) {}
    // The stream that starts from `state` as it is (for a caller that mixes its own seed).
    static Rng from_state(uint64_t state)
    {
        Rng rng(0);
        rng.state = state;
        return rng;
    }
    uint64_t next() { return splitmix64(state += 0x9E3779B97F4A7C15ull); }
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
    double range(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    uint32_t below(uint32_t n) { return uint32_t(uniform() * n); }
    // A uniformly distributed unit vector.
    void direction(double d[3])
    {
        const double pi = 3.14159265358979323846;
        double z = range(-1, 1), phi = range(0, 2 * pi), r = std::sqrt(std::max(0.0, 1 - z * z));
        d[0] = r * std::cos(phi), d[1] = r * std::sin(phi), d[2] = z;
    }
};

}  // namespace common
