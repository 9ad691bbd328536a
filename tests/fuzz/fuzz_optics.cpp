// libFuzzer target: kdrt's optics functions and medium stack on any floats (NaN, infinities,
// signed zeros, subnormals, the largest floats) and any sequence of stack operations.
// Checked, as kdrt.h documents them: reflected and refracted directions are finite unit vectors,
// or the incident direction itself on invalid input; total internal reflection gives
// kdrt_reflect()'s direction; writing over the input gives the same bits; reflectances lie in
// [0, 1], and are 0 on invalid input; the stack holds at most KDRT_MEDIA_STACK_CAPACITY media,
// its indices stay finite and positive, and an operation that fails leaves it as it was.
#include "kdrt.h"
#include "fuzz_support.hpp"


#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>

namespace {


void pick_vector(FuzzedDataProvider &in, float v[3]) {
    for (int a = 0; a < 3; ++a) v[a] = fuzz::pick_float(in);
}

bool valid_direction(const float v[3]) {
    return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]) && (v[0] != 0 || v[1] != 0 || v[2] != 0);
}
bool valid_ior(float x) { return std::isfinite(x) && x > 0; }

void check_unit(const char *what, const float v[3]) {
    const double length = std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]);
    FUZZ_CHECK(std::fabs(length - 1) < 1e-6, "%s (%a, %a, %a) has length %.9g", what, v[0], v[1], v[2], length);
}

bool same_bits(const float a[3], const float b[3]) { return std::memcmp(a, b, 3 * sizeof(float)) == 0; }

void check_directions(FuzzedDataProvider &in) {
    float i[3], n[3], out[3], mirror[3];
    pick_vector(in, i);
    pick_vector(in, n);
    const float eta = fuzz::pick_float(in);
    const bool valid = valid_direction(i) && valid_direction(n);

    kdrt_reflect(i, n, mirror);
    if (valid) check_unit("reflected", mirror);
    else FUZZ_CHECK(same_bits(mirror, i), "invalid input, yet reflected");
    float in_place[3] = {i[0], i[1], i[2]};
    kdrt_reflect(in_place, n, in_place);
    FUZZ_CHECK(same_bits(in_place, mirror), "kdrt_reflect in place differs");

    const int r = kdrt_refract(i, n, eta, out);
    FUZZ_CHECK(r == (valid && valid_ior(eta) ? r : -1) && r >= -1 && r <= 1, "kdrt_refract returned %d", r);
    if (r == 1) check_unit("refracted", out);
    if (r == 0) FUZZ_CHECK(same_bits(out, mirror), "total internal reflection is not kdrt_reflect's direction");
    if (r == -1) {
        FUZZ_CHECK(!(valid && valid_ior(eta)), "valid input refused");
        FUZZ_CHECK(same_bits(out, i), "invalid input, yet changed");
    }
    float again[3] = {i[0], i[1], i[2]};
    FUZZ_CHECK(kdrt_refract(again, n, eta, again) == r && same_bits(again, out), "kdrt_refract in place differs");
}

void check_reflectance(FuzzedDataProvider &in) {
    const float cos_i = fuzz::pick_float(in), eta = fuzz::pick_float(in);
    const bool valid = !std::isnan(cos_i) && valid_ior(eta);
    const float f = kdrt_fresnel_dielectric(cos_i, eta), s = kdrt_fresnel_schlick(cos_i, eta);
    float rs = -1, rp = -1;
    kdrt_fresnel_dielectric_sp(cos_i, eta, &rs, &rp);
    for (float x : {f, s, rs, rp}) FUZZ_CHECK(x >= 0 && x <= 1, "reflectance %a for cos_i=%a eta=%a", x, cos_i, eta);
    if (!valid || eta == 1) FUZZ_CHECK(f == 0 && s == 0 && rs == 0 && rp == 0, "no surface, yet reflectance");
}

// A sequence of operations on one stack, each checked against what kdrt.h says it does.
void check_stack(FuzzedDataProvider &in) {
    kdrt_media_stack stack;
    const float outside = fuzz::pick_float(in);
    const kdrt_result init = kdrt_media_init(&stack, outside);
    FUZZ_CHECK(init == (valid_ior(outside) ? KDRT_SUCCESS : KDRT_ERROR_INVALID_IOR), "kdrt_media_init: %s", kdrt_result_string(init));
    FUZZ_CHECK(stack.count == 0 && valid_ior(stack.outside_ior), "kdrt_media_init left count %u, outside %a", stack.count,
               stack.outside_ior);
    const int steps = in.ConsumeIntegralInRange<int>(0, 64);
    bool written = false;  // count written by hand: entries it exposes may hold anything
    for (int step = 0; step < steps; ++step) {
        const uint32_t object = in.ConsumeBool() ? in.ConsumeIntegralInRange<uint32_t>(0, 3) : in.ConsumeIntegral<uint32_t>();
        const float ior = in.ConsumeBool() ? float(in.ConsumeIntegralInRange<int>(1, 8)) * 0.25f : fuzz::pick_float(in);
        const int priority = in.ConsumeBool() ? in.ConsumeIntegralInRange<int>(0, 2) : in.ConsumeIntegral<int>();
        const kdrt_media_stack before = stack;
        switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: {
            const kdrt_result r = kdrt_media_enter(&stack, object, ior, priority);
            if (!valid_ior(ior)) FUZZ_CHECK(r == KDRT_ERROR_INVALID_IOR, "entered with ior %a", ior);
            else if (before.count >= KDRT_MEDIA_STACK_CAPACITY) FUZZ_CHECK(r == KDRT_ERROR_MEDIA_STACK_FULL, "entered a full stack");
            else FUZZ_CHECK(r == KDRT_SUCCESS && stack.count == before.count + 1, "kdrt_media_enter: %s", kdrt_result_string(r));
            if (r != KDRT_SUCCESS) FUZZ_CHECK(std::memcmp(&stack, &before, sizeof stack) == 0, "a failed enter changed the stack");
            break;
        }
        case 1: {
            const bool held = kdrt_media_contains(&stack, object);
            const kdrt_result r = kdrt_media_leave(&stack, object);
            FUZZ_CHECK(r == (held ? KDRT_SUCCESS : KDRT_ERROR_NOT_IN_MEDIUM), "kdrt_media_leave: %s", kdrt_result_string(r));
            if (r != KDRT_SUCCESS) FUZZ_CHECK(std::memcmp(&stack, &before, sizeof stack) == 0, "a failed leave changed the stack");
            else if (!written) FUZZ_CHECK(stack.count + 1 == before.count, "leave: count %u after %u", stack.count, before.count);
            break;
        }
        case 2: {
            const kdrt_media_crossing x = kdrt_media_at_surface(&stack, object, ior, priority);
            FUZZ_CHECK(std::memcmp(&stack, &before, sizeof stack) == 0, "kdrt_media_at_surface changed the stack");
            FUZZ_CHECK(x.entering == !kdrt_media_contains(&stack, object), "entering %d", x.entering);
            FUZZ_CHECK(x.eta_incident == kdrt_media_current_ior(&stack), "eta_incident %a", x.eta_incident);
            if (!x.real) FUZZ_CHECK(x.eta_transmitted == x.eta_incident, "a false surface changes the index");
            else if (!written && (!x.entering || valid_ior(ior)))
                FUZZ_CHECK(valid_ior(x.eta_transmitted), "eta_transmitted %a", x.eta_transmitted);
            break;
        }
        default:  // plain data: the caller may have written anything into count
            stack.count = in.ConsumeIntegral<uint32_t>();
            written = true;
            break;
        }
        if (written) continue;  // only no crash and no read past the array (ASan) then
        FUZZ_CHECK(valid_ior(kdrt_media_current_ior(&stack)), "current index %a", kdrt_media_current_ior(&stack));
        const uint32_t current = kdrt_media_current_object(&stack);
        FUZZ_CHECK(current == KDRT_INVALID_ID || kdrt_media_contains(&stack, current), "current object %u not held", current);
    }
    FUZZ_CHECK(kdrt_media_current_ior(nullptr) == 1.0f && kdrt_media_current_object(nullptr) == KDRT_INVALID_ID, "NULL stack");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    FuzzedDataProvider in(data, size);
    const int rounds = in.ConsumeIntegralInRange<int>(1, 8);
    for (int k = 0; k < rounds; ++k) {
        check_directions(in);
        check_reflectance(in);
    }
    check_stack(in);
    return 0;
}
