// The top level of a kdrt_scene on its own (bench/README.md, "The top level"): N instances
// (default 1,000) of a 3,200-triangle ellipsoid on a square grid of pitch P (default 1), random
// turns and scales; 21 commits after every instance moved (their median), then PASSES (default 3)
// passes of 400 x 400 camera rays from the front (their median). Not built by CMake: a program to
// run under callgrind, which counts the top level's instructions apart from the rest.
//   g++ -O2 -g -Iinclude bench/top_level_field.cpp -o top_level_field
//   valgrind --tool=callgrind ./top_level_field 10000 1 1     # N P PASSES
#define KDRT_IMPLEMENTATION
#include "kdrt.h"
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>
#include <cmath>
#include <algorithm>
int main(int argc, char **argv) {
    const uint32_t n = argc > 1 ? atoi(argv[1]) : 1000;
    const float pitch = argc > 2 ? atof(argv[2]) : 1.0f;
    std::vector<float> v; std::vector<uint32_t> idx;
    const int R = 40, S = 40;
    for (int i = 0; i <= R; ++i) for (int j = 0; j < S; ++j) {
        float th = 3.14159265f * i / R, ph = 2 * 3.14159265f * j / S;
        v.insert(v.end(), {0.6f * sinf(th) * cosf(ph), 0.45f * cosf(th), 0.5f * sinf(th) * sinf(ph)});
    }
    for (int i = 0; i < R; ++i) for (int j = 0; j < S; ++j) {
        uint32_t a = i * S + j, b = i * S + (j + 1) % S, c = (i + 1) * S + j, d = (i + 1) * S + (j + 1) % S;
        idx.insert(idx.end(), {a, c, b, b, c, d});
    }
    kdrt_triangles m = {}; m.positions = v.data(); m.vertex_count = v.size() / 3; m.indices = idx.data(); m.triangle_count = idx.size() / 3;
    kdrt_tree *t; kdrt_tree_build(&m, nullptr, &t, nullptr);
    std::vector<kdrt_geometry> g;
    srand(1);
    const int side = (int)std::ceil(std::sqrt((double)n));
    auto rnd = [] { return rand() / (float)RAND_MAX; };
    for (uint32_t i = 0; i < n; ++i) {
        float a = rnd() * 6.28f, s = 0.8f + 0.4f * rnd(), c = cosf(a) * s, sn = sinf(a) * s;
        float xf[12] = {c, 0, sn, pitch * (i % side) + 0.15f * rnd(), 0, s, 0, pitch * (i / side) + 0.15f * rnd(), -sn, 0, c, 0.5f * rnd()};
        g.push_back(kdrt_instance_geometry(i + 1, t, xf));
    }
    kdrt_scene *sc; if (kdrt_scene_build(g.data(), n, nullptr, &sc, nullptr)) return 1;
    std::vector<double> cm;
    for (int rep = 0; rep < 21; ++rep) {
        for (uint32_t i = 0; i < n; ++i) { g[i].transform[3] += (rep & 1) ? -0.01f : 0.01f; kdrt_scene_set_transform(sc, i + 1, g[i].transform); }
        auto a = std::chrono::steady_clock::now();
        kdrt_scene_commit(sc);
        cm.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
    }
    std::sort(cm.begin(), cm.end());
    kdrt_aabb b = kdrt_scene_bounds(sc); int hits = 0;
    const float cx = 0.5f * (b.min[0] + b.max[0]), cy = 0.5f * (b.min[1] + b.max[1]);
    const float ext = std::max(b.max[0] - b.min[0], b.max[1] - b.min[1]);
    std::vector<double> tm;
    const int passes = argc > 3 ? atoi(argv[3]) : 3;
    for (int pass = 0; pass < passes; ++pass) {
        auto a = std::chrono::steady_clock::now();
        for (int y = 0; y < 400; ++y) for (int x = 0; x < 400; ++x) {
            float dx = (x / 400.f - 0.5f) * ext, dy = (y / 400.f - 0.5f) * ext, dz = 1.2f * ext;
            kdrt_ray r = {{cx, cy, b.min[2] - 1.2f * ext}, 0, {dx * 0.9f, dy * 0.9f, dz}, INFINITY, 0};
            kdrt_hit h; hits += kdrt_scene_intersect(sc, &r, nullptr, &h);
        }
        tm.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
    }
    std::sort(tm.begin(), tm.end());
    printf("n=%u pitch %.1f: median commit %.3f ms; 160000 rays %.1f ms (median of %d passes), %d hits a pass\n", n, pitch,
           cm[10], tm.empty() ? 0.0 : tm[tm.size() / 2], passes, passes > 0 ? hits / passes : 0);
}
