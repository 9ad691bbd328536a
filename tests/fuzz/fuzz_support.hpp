// What the fuzz targets share: the check that turns a broken promise into a finding, the
// floats they draw, weighted towards the values where float code goes wrong, and a counting
// allocator that can fail.
#pragma once

#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>

namespace fuzz {

// What is being checked (a ray, a triangle), printed with a failed check; empty when nothing is.
inline std::string &context()
{
    static std::string text;
    return text;
}

// NaN, infinities, signed zeros, the largest float, subnormals, the smallest normals, 1e30,
// coordinates far from the origin, any bits, and most often a coarse grid, where coincidences
// (shared planes, edges, vertices) are likely.
inline float pick_float(FuzzedDataProvider &in)
{
    switch (in.ConsumeIntegralInRange<int>(0, 15)) {
    case 0: return std::numeric_limits<float>::quiet_NaN();
    case 1: return in.ConsumeBool() ? INFINITY : -INFINITY;
    case 2: return in.ConsumeBool() ? 0.0f : -0.0f;
    case 3: return (in.ConsumeBool() ? 1 : -1) * std::numeric_limits<float>::max();
    case 4: return float(in.ConsumeIntegralInRange<int>(-4, 4)) * std::numeric_limits<float>::denorm_min();
    case 5: return float(in.ConsumeIntegralInRange<int>(-4, 4)) * std::numeric_limits<float>::min();
    case 6: return float(in.ConsumeIntegralInRange<int>(-4, 4)) * 1e30f;
    case 7: return float(in.ConsumeIntegralInRange<int>(-1000, 1000)) * 1e-3f + 1e5f;  // far from the origin
    case 8: {
        const uint32_t bits = in.ConsumeIntegral<uint32_t>();
        float f;
        std::memcpy(&f, &bits, sizeof f);
        return f;
    }
    default: return float(in.ConsumeIntegralInRange<int>(-8, 8)) * 0.25f;
    }
}

}  // namespace fuzz

// A broken promise: say which (and the context), and abort, which libFuzzer reports as a crash
// with the input.
#define FUZZ_CHECK(cond, ...)                                                                  \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            std::fprintf(stderr, "%s", fuzz::context().c_str());                               \
            std::fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);      \
            std::fprintf(stderr, __VA_ARGS__);                                                 \
            std::fprintf(stderr, "\n");                                                        \
            std::abort();                                                                      \
        }                                                                                      \
    } while (0)

namespace fuzz {

// An allocator for kdrt_allocator (user: the Heap) that counts live blocks and fails allocation
// number fail_at (1-based; 0: never), saying in failed that it did.
struct Heap {
    size_t calls = 0, live = 0, fail_at = 0;
    bool failed = false;
    static void *alloc(void *user, size_t size) {
        Heap *h = static_cast<Heap *>(user);
        if (++h->calls == h->fail_at) return h->failed = true, nullptr;
        void *p = std::malloc(size);
        if (p) ++h->live;
        return p;
    }
    static void free(void *user, void *p) {
        Heap *h = static_cast<Heap *>(user);
        FUZZ_CHECK(p != nullptr, "free(NULL) through the allocator");
        --h->live;
        std::free(p);
    }
};

}  // namespace fuzz
