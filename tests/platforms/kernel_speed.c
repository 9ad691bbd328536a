/* The SIMD kernel against the scalar kernel on one build: the same rays traced by each on the
   same tree, their answers compared bit for bit, and their time.

     kernel_speed [RAYS [both|simd|scalar]]     default: 300000 both

   both: each kernel traces the rays (nearest hit, watertight test), one after the other, best of
   3 runs each; prints ms and rays/s for each, and exit 1 when any answer differs. simd or scalar:
   that kernel alone, once, its ms and rays/s too (tests/platforms/count_instructions.sh counts its instructions; RAYS 0
   builds the tree and traces nothing). Both print a checksum of the answers' bits, the same on
   every build whose compiler fuses no multiply-add in kdrt.h. The mesh is made here, from
   integer hashes and square roots (correctly rounded everywhere) with no multiply-add a compiler
   could fuse, so every target traces the same floats: a bumpy sphere of 49,152 triangles, and
   rays from a sphere around it aimed at points inside it. Strict C99, the header only. */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define SIDE 64 /* quads a side of each of the cube's faces */
#define VERTEX_COUNT (6 * (SIDE + 1) * (SIDE + 1))
#define TRIANGLE_COUNT (6 * SIDE * SIDE * 2)

/* A 32-bit integer hash (lowbias32): the same numbers everywhere. */
static uint32_t hash(uint32_t x)
{
    x ^= x >> 16, x *= 0x7feb352du, x ^= x >> 15, x *= 0x846ca68bu, x ^= x >> 16;
    return x;
}

/* A float in [-1, 1) from the hash of n, a multiple of 2^-23: exact everywhere. */
static float unit(uint32_t n) { return (float)(int32_t)(hash(n) >> 8) / 8388608.0f - 1.0f; }

/* v scaled to the length: in double, where the squares of floats are exact, so that a compiler
   that fuses multiplies and adds (Clang's default on aarch64) gets the same floats. */
static void normalise(float v[3], float length)
{
    const double squares = (double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2];
    const double scale = length / sqrt(squares);
    int a;
    for (a = 0; a < 3; ++a) v[a] = (float)(v[a] * scale);
}

/* A cube's faces, SIDE x SIDE quads each, pushed onto the unit sphere with bumps of 1.6%. */
static void make_sphere(float *positions, uint32_t *indices)
{
    uint32_t face, i, j, v = 0, t = 0;
    for (face = 0; face < 6; ++face) {
        const int axis = (int)(face % 3), sign = face < 3 ? 1 : -1;
        const uint32_t first = v;
        for (j = 0; j <= SIDE; ++j)
            for (i = 0; i <= SIDE; ++i, ++v) {
                float *p = &positions[3 * v];
                p[axis] = (float)sign;
                /* mirrored on the negative faces so every face winds outwards */
                p[(axis + 1) % 3] = (float)sign * (2.0f * (float)i / SIDE - 1.0f);
                p[(axis + 2) % 3] = 2.0f * (float)j / SIDE - 1.0f;
                normalise(p, 1.0f + unit(v) / 64.0f); /* an exact product: fused or not, the same */
            }
        for (j = 0; j < SIDE; ++j)
            for (i = 0; i < SIDE; ++i) {
                const uint32_t a = first + j * (SIDE + 1) + i, b = a + 1, c = a + SIDE + 1, d = c + 1;
                uint32_t *tri = &indices[3 * t];
                tri[0] = a, tri[1] = b, tri[2] = d, tri[3] = a, tri[4] = d, tri[5] = c;
                t += 2;
            }
    }
}

/* Ray n: from a point on the sphere of radius 3 towards a point in the cube [-1, 1]^3. */
static kdrt_ray make_ray(uint32_t n)
{
    kdrt_ray r;
    int a;
    memset(&r, 0, sizeof r);
    for (a = 0; a < 3; ++a) r.org[a] = unit(6u * n + (uint32_t)a + 1000000u);
    normalise(r.org, 3.0f);
    for (a = 0; a < 3; ++a) r.dir[a] = unit(6u * n + (uint32_t)a + 1000003u) - r.org[a];
    r.tmin = 0.0f, r.tmax = INFINITY;
    return r;
}

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static uint32_t bits_of(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

/* The answers' bits (triangle, t, u, v) folded into one number. */
static uint32_t checksum(const kdrt_hit *hits, uint32_t count)
{
    uint32_t i, sum = 0;
    for (i = 0; i < count; ++i)
        sum = hash(sum ^ hits[i].triangle) ^ bits_of(hits[i].t) ^ (bits_of(hits[i].u) * 3u) ^
              (bits_of(hits[i].v) * 5u);
    return sum;
}

/* Traces the rays on tree into hits, runs times; returns the best run's milliseconds. */
static double trace(const kdrt_tree *tree, const kdrt_ray *rays, uint32_t count, kdrt_hit *hits,
                    int runs, uint32_t *hit_count)
{
    double best = 0.0;
    int run;
    for (run = 0; run < runs; ++run) {
        const double start = now_ms();
        uint32_t i, found = 0;
        double ms;
        for (i = 0; i < count; ++i) found += (uint32_t)kdrt_intersect(tree, &rays[i], &hits[i]);
        ms = now_ms() - start;
        if (run == 0 || ms < best) best = ms;
        *hit_count = found;
    }
    return best;
}

int main(int argc, char **argv)
{
    const long asked = argc > 1 ? strtol(argv[1], NULL, 10) : 300000;
    const char *which = argc > 2 ? argv[2] : "both";
    const int both = strcmp(which, "both") == 0;
    float *positions = (float *)malloc(sizeof(float) * 3 * VERTEX_COUNT);
    uint32_t *indices = (uint32_t *)malloc(sizeof(uint32_t) * 3 * TRIANGLE_COUNT);
    kdrt_ray *rays;
    kdrt_hit *hits[2];
    kdrt_triangles mesh;
    kdrt_tree *trees[2] = {NULL, NULL};
    uint32_t count, i, k, differ = 0;
    int kernels = both ? 2 : 1;
    if (asked < 0 || asked > 10000000 || (!both && strcmp(which, "simd") && strcmp(which, "scalar"))) {
        fprintf(stderr, "usage: kernel_speed [RAYS (0 to 10000000) [both|simd|scalar]]\n");
        return 2;
    }
    count = (uint32_t)asked;
    rays = (kdrt_ray *)malloc(sizeof(kdrt_ray) * (count ? count : 1u));
    hits[0] = (kdrt_hit *)malloc(sizeof(kdrt_hit) * (count ? count : 1u));
    hits[1] = (kdrt_hit *)malloc(sizeof(kdrt_hit) * (count ? count : 1u));
    if (!positions || !indices || !rays || !hits[0] || !hits[1]) {
        fprintf(stderr, "kernel_speed: out of memory\n");
        return 1;
    }
    make_sphere(positions, indices);
    for (i = 0; i < count; ++i) rays[i] = make_ray(i);
    memset(&mesh, 0, sizeof mesh);
    mesh.positions = positions, mesh.vertex_count = VERTEX_COUNT;
    mesh.indices = indices, mesh.triangle_count = TRIANGLE_COUNT;
    for (k = 0; k < (uint32_t)kernels; ++k) {
        kdrt_build_options options = kdrt_default_build_options();
        kdrt_tree_stats stats;
        uint32_t found = 0;
        double ms;
        const int scalar = both ? k == 1 : strcmp(which, "scalar") == 0;
        options.flags = scalar ? KDRT_BUILD_SCALAR_KERNEL : 0u;
        if (kdrt_tree_build(&mesh, &options, &trees[k], NULL) != KDRT_SUCCESS) {
            fprintf(stderr, "kernel_speed: the build failed\n");
            return 1;
        }
        kdrt_tree_get_stats(trees[k], &stats);
        ms = trace(trees[k], rays, count, hits[k], both ? 3 : 1, &found);
        printf("kernel %s: %u triangles, %u rays, %u hits, checksum %08x", kdrt_kernel_string(stats.kernel),
               stats.triangles, count, found, checksum(hits[k], count));
        printf(", %.1f ms, %.0f rays/s", ms, ms > 0.0 ? count / (ms * 1e-3) : 0.0);
        printf("\n");
    }
    if (both) {
        for (i = 0; i < count; ++i)
            differ += hits[0][i].triangle != hits[1][i].triangle || bits_of(hits[0][i].t) != bits_of(hits[1][i].t) ||
                      bits_of(hits[0][i].u) != bits_of(hits[1][i].u) || bits_of(hits[0][i].v) != bits_of(hits[1][i].v);
        printf("answers: %u of %u differ between the kernels\n", differ, count);
    }
    for (k = 0; k < 2; ++k) kdrt_tree_free(trees[k]), free(hits[k]);
    free(rays), free(indices), free(positions);
    return differ ? 1 : 0;
}
