// The saved-tree format's words and hashes as the manual (kdrt.h, SAVED TREES) describes them,
// written again from that text rather than taken from the header: the tests (test_save.cpp) check
// saves against them, and both they and the load fuzz target (fuzz/fuzz_load.cpp) forge files
// with them (the checksums made again over whatever the bytes now say).
#pragma once

#include <cstddef>
#include <cstdint>

namespace saved_format {

constexpr size_t kHeader = 256, kMeshRecord = 32, kBlock = 320, kNode = 8, kCell = 48;

inline uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
inline uint32_t get32(const unsigned char *p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}
inline uint64_t get64(const unsigned char *p) { return uint64_t(get32(p)) | uint64_t(get32(p + 4)) << 32; }
inline void put32(unsigned char *p, uint32_t x) {
    for (int i = 0; i < 4; ++i) p[i] = (unsigned char)(x >> (8 * i));
}
inline void put64(unsigned char *p, uint64_t x) {
    for (int i = 0; i < 8; ++i) p[i] = (unsigned char)(x >> (8 * i));
}

// XXH64 with seed 0, from its specification.
inline uint64_t xxh64(const unsigned char *p, size_t n) {
    const uint64_t P1 = 0x9E3779B185EBCA87ull, P2 = 0xC2B2AE3D27D4EB4Full, P3 = 0x165667B19E3779F9ull,
                   P4 = 0x85EBCA77C2B2AE63ull, P5 = 0x27D4EB2F165667C5ull;
    auto round = [&](uint64_t acc, uint64_t in) { return rotl(acc + in * P2, 31) * P1; };
    const unsigned char *end = p + n;
    uint64_t h;
    if (n >= 32) {
        uint64_t v[4] = {P1 + P2, P2, 0, 0 - P1};
        for (; p + 32 <= end; p += 32)
            for (int k = 0; k < 4; ++k) v[k] = round(v[k], get64(p + 8 * k));
        h = rotl(v[0], 1) + rotl(v[1], 7) + rotl(v[2], 12) + rotl(v[3], 18);
        for (int k = 0; k < 4; ++k) h = (h ^ round(0, v[k])) * P1 + P4;
    } else {
        h = P5;
    }
    h += n;
    for (; p + 8 <= end; p += 8) h = rotl(h ^ round(0, get64(p)), 27) * P1 + P4;
    if (p + 4 <= end) h = rotl(h ^ uint64_t(get32(p)) * P1, 23) * P2 + P3, p += 4;
    for (; p < end; ++p) h = rotl(h ^ *p * P5, 11) * P1;
    h ^= h >> 33, h *= P2, h ^= h >> 29, h *= P3;
    return h ^ (h >> 32);
}

// The sections' checksum: eight 32-bit Fletcher lanes, ended by XXH64.
inline uint64_t sections_sum(const unsigned char *p, size_t bytes) {
    uint32_t a[8] = {}, b[8] = {};
    const size_t words = bytes / 4;
    for (size_t i = 0; i < words; ++i) a[i % 8] += get32(p + 4 * i), b[i % 8] += a[i % 8];
    unsigned char end[72];
    for (int k = 0; k < 8; ++k) put32(end + 4 * k, a[k]), put32(end + 32 + 4 * k, b[k]);
    put64(end + 64, words);
    return xxh64(end, sizeof end);
}

// Where the mesh records start, from the header's counts (the sections before them back to back).
inline uint64_t mesh_records_at(const unsigned char *f) {
    const uint64_t nodes = get32(f + 80), leaves = get32(f + 84), blocks = get32(f + 88);
    return kHeader + kBlock * blocks + kNode * nodes + kCell * leaves + 4 * blocks + 4 * nodes;
}

// A forged file of n bytes: its three checksums made again over what the bytes say, where the
// header's counts fit the size (else only the header's own).
inline void reseal(unsigned char *f, size_t n) {
    if (n < kHeader) return;
    const uint64_t records = mesh_records_at(f), meshes = get32(f + 20);
    if (records + kMeshRecord * meshes == n) {
        put64(f + 192, xxh64(f + records, size_t(kMeshRecord * meshes)));
        put64(f + 200, sections_sum(f + kHeader, size_t(records - kHeader)));
    }
    put64(f + 248, xxh64(f, 248));
}

} // namespace saved_format
