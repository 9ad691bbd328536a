/* Which kernel a tree runs here, and whether the kernels agree (tests/platforms/windows.sh runs it
   under wine, built by mingw-w64; it builds natively too). One height field, built three times:
   with default flags, with KDRT_BUILD_AVX2_KERNEL and with KDRT_BUILD_SCALAR_KERNEL, for each
   intersector. The same rays (a camera's, which the batches walk as packets, and scattered ones,
   which they walk one by one) are traced on each tree by the single-ray calls and the batches;
   every answer must be the scalar tree's single call's bit for bit, and the watertight test's
   nearest hits must match a double-precision brute force. Prints a line per tree:
       kernel default: avx512 (batches: 96 packets, 1536 lanes)
   with the packets its batches walked, a hash of the answers (the same from every compiler that
   rounds as IEEE says, without contracting), and "kernel_report: all checks passed", or what
   failed, and exits 1. */
#define KDRT_TRAVERSAL_STATS /* the batches' packet counts */
/* KERNEL_REPORT_LINKED: the implementation comes from another object, compiled with
   KDRT_TRAVERSAL_STATS (windows.sh: by clang for MSVC's target). */
#ifndef KERNEL_REPORT_LINKED
#define KDRT_IMPLEMENTATION
#endif
#include "kdrt.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define GRID 24 /* cells a side: 2 * GRID * GRID triangles */
#define VERTICES ((GRID + 1) * (GRID + 1))
#define TRIANGLES (2 * GRID * GRID)
#define CAMERA 64 /* rays a side of the camera's image */
#define SCATTERED 1024
#define RAYS (CAMERA * CAMERA + SCATTERED)

typedef struct scene {
    float vertices[3 * VERTICES];
    uint32_t indices[3 * TRIANGLES];
    kdrt_ray rays[RAYS];
} scene;

typedef struct answers {
    kdrt_hit hits[RAYS];
    uint8_t occluded[RAYS];
} answers;

/* A deterministic generator of floats in [0, 1): no libc state. */
static float next_unit(uint32_t *state)
{
    *state = *state * 1664525u + 1013904223u;
    return (float)(*state >> 8) / 16777216.0f;
}

static void make_scene(scene *s)
{
    uint32_t x, y, i, state = 12345u;
    for (y = 0; y <= GRID; ++y)
        for (x = 0; x <= GRID; ++x) {
            float *v = &s->vertices[3 * (y * (GRID + 1) + x)];
            v[0] = (float)x, v[1] = (float)y, v[2] = 0.1f * (float)((x * 7u + y * 3u) % 5u);
        }
    for (y = 0, i = 0; y < GRID; ++y)
        for (x = 0; x < GRID; ++x, i += 6) {
            const uint32_t a = y * (GRID + 1) + x, b = a + 1, c = a + GRID + 2, d = a + GRID + 1;
            s->indices[i + 0] = a, s->indices[i + 1] = b, s->indices[i + 2] = c;
            s->indices[i + 3] = a, s->indices[i + 4] = c, s->indices[i + 5] = d;
        }
    /* A camera high above the field looking down on it, its image a little wider than the
       field: most rays hit, those past the edges miss; a tmax that ends some above the surface,
       for the shadow rays' occluded answers. In 4x4 tiles, an AVX-512 packet's 16 rays (two
       AVX2 packets), as a renderer hands them over. */
    for (i = 0; i < CAMERA * CAMERA; ++i) {
        kdrt_ray *r = &s->rays[i];
        const uint32_t tile = i / 16u, tiles_a_row = CAMERA / 4u;
        const float px = (float)((tile % tiles_a_row) * 4u + i % 4u) + 0.5f;
        const float py = (float)((tile / tiles_a_row) * 4u + i % 16u / 4u) + 0.5f;
        r->org[0] = GRID * 0.5f, r->org[1] = -4.0f, r->org[2] = 40.0f;
        r->dir[0] = -2.0f + (GRID + 4.0f) * px / CAMERA - r->org[0];
        r->dir[1] = -2.0f + (GRID + 4.0f) * py / CAMERA - r->org[1];
        r->dir[2] = -r->org[2];
        r->tmin = 0.0f, r->tmax = (i % 3u) ? INFINITY : 0.99f, r->cell = 0;
    }
    /* Scattered rays: origins anywhere above and around the field, directions anywhere. */
    for (; i < RAYS; ++i) {
        kdrt_ray *r = &s->rays[i];
        r->org[0] = -4.0f + (GRID + 8.0f) * next_unit(&state);
        r->org[1] = -4.0f + (GRID + 8.0f) * next_unit(&state);
        r->org[2] = 0.5f + 6.0f * next_unit(&state);
        r->dir[0] = next_unit(&state) - 0.5f, r->dir[1] = next_unit(&state) - 0.5f;
        r->dir[2] = next_unit(&state) - 0.75f;
        r->tmin = 0.0f, r->tmax = (i % 4u) ? INFINITY : 2.0f * next_unit(&state), r->cell = 0;
    }
}

/* The nearest t > tmin within the ray's range over all triangles, in double (Moeller-Trumbore
   without epsilon), or -1 for none. */
static double brute_force_t(const scene *s, const kdrt_ray *r)
{
    double best = -1.0;
    uint32_t i;
    int a;
    for (i = 0; i < TRIANGLES; ++i) {
        double p[3][3], e1[3], e2[3], pv[3], tv[3], qv[3], d[3], det, u, v, t;
        int k;
        for (k = 0; k < 3; ++k)
            for (a = 0; a < 3; ++a) p[k][a] = s->vertices[3 * s->indices[3 * i + (uint32_t)k] + (uint32_t)a];
        for (a = 0; a < 3; ++a)
            e1[a] = p[1][a] - p[0][a], e2[a] = p[2][a] - p[0][a], tv[a] = r->org[a] - p[0][a],
            d[a] = r->dir[a];
        pv[0] = d[1] * e2[2] - d[2] * e2[1], pv[1] = d[2] * e2[0] - d[0] * e2[2];
        pv[2] = d[0] * e2[1] - d[1] * e2[0];
        det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (det == 0.0) continue;
        u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
        if (u < 0.0 || u > 1.0) continue;
        qv[0] = tv[1] * e1[2] - tv[2] * e1[1], qv[1] = tv[2] * e1[0] - tv[0] * e1[2];
        qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
        v = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
        if (v < 0.0 || u + v > 1.0) continue;
        t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
        if (t >= r->tmin && t <= r->tmax && (best < 0.0 || t < best)) best = t;
    }
    return best;
}

/* FNV-1a over the answers' bits: the nearest hits' t, u, v, triangle and cell (the triangle
   alone for a miss) and the occluded answers, so that builds by other compilers can be compared
   bit for bit. */
static uint32_t answers_hash(uint32_t hash, const answers *a)
{
    uint32_t i;
    size_t k;
    for (i = 0; i < RAYS; ++i) {
        unsigned char bytes[sizeof(kdrt_hit) + 1];
        const size_t n = a->hits[i].triangle == KDRT_INVALID_ID ? sizeof(uint32_t) : sizeof(kdrt_hit);
        if (n == sizeof(kdrt_hit)) memcpy(bytes, &a->hits[i], n);
        else memcpy(bytes, &a->hits[i].triangle, n);
        bytes[n] = a->occluded[i];
        for (k = 0; k <= n; ++k) hash = (hash ^ bytes[k]) * 16777619u;
    }
    return hash;
}

/* Whether two nearest-hit answers are the same: both misses, or the same hit bit for bit. */
static int same_hit(const kdrt_hit *a, const kdrt_hit *b)
{
    if (a->triangle == KDRT_INVALID_ID || b->triangle == KDRT_INVALID_ID)
        return a->triangle == b->triangle;
    return memcmp(a, b, sizeof *a) == 0;
}

/* Traces every ray of s on tree by the single-ray calls and by the batches, counted and not;
   the batches must answer as the single calls do. Returns the failures; *work: the counted
   batches' work, whose packets say which packet code ran. */
static int trace(const kdrt_tree *tree, const scene *s, answers *out, const char *label,
                 kdrt_traversal_stats *work)
{
    static kdrt_hit batch_hits[RAYS], counted_hits[RAYS];
    static uint8_t batch_occluded[RAYS], counted_occluded[RAYS];
    int failures = 0;
    uint32_t i;
    for (i = 0; i < RAYS; ++i) {
        if (!kdrt_intersect(tree, &s->rays[i], &out->hits[i]))
            out->hits[i].triangle = KDRT_INVALID_ID;
        out->occluded[i] = (uint8_t)kdrt_occluded(tree, &s->rays[i]);
    }
    kdrt_intersect_batch(tree, s->rays, RAYS, NULL, batch_hits);
    kdrt_occluded_batch(tree, s->rays, RAYS, NULL, batch_occluded);
    memset(work, 0, sizeof *work);
    kdrt_intersect_batch_counted(tree, s->rays, RAYS, counted_hits, work);
    kdrt_occluded_batch_counted(tree, s->rays, RAYS, counted_occluded, work);
    for (i = 0; i < RAYS; ++i) {
        if (!same_hit(&out->hits[i], &batch_hits[i]) || out->occluded[i] != batch_occluded[i] ||
            !same_hit(&out->hits[i], &counted_hits[i]) || out->occluded[i] != counted_occluded[i]) {
            if (failures++ < 5)
                fprintf(stderr, "kernel_report: FAILED: %s: ray %u: the batch's answer differs from the single call's\n",
                        label, (unsigned)i);
        }
        if ((out->hits[i].triangle != KDRT_INVALID_ID) != (out->occluded[i] != 0)) {
            if (failures++ < 5)
                fprintf(stderr, "kernel_report: FAILED: %s: ray %u: kdrt_intersect and kdrt_occluded disagree\n",
                        label, (unsigned)i);
        }
    }
    return failures;
}

int main(void)
{
    static scene s;
    static answers reference, other;
    static const uint32_t flags[3] = {0u, KDRT_BUILD_AVX2_KERNEL, KDRT_BUILD_SCALAR_KERNEL};
    static const char *const flag_names[3] = {"default", "KDRT_BUILD_AVX2_KERNEL",
                                              "KDRT_BUILD_SCALAR_KERNEL"};
    static const kdrt_intersector intersectors[2] = {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST};
    static const char *const intersector_names[2] = {"watertight", "fast"};
    kdrt_triangles mesh;
    int failures = 0, f, m;
    uint32_t i, hits = 0, misses = 0, occluded = 0, hash = 2166136261u;
    make_scene(&s);
    memset(&mesh, 0, sizeof mesh);
    mesh.positions = s.vertices, mesh.vertex_count = VERTICES;
    mesh.indices = s.indices, mesh.triangle_count = TRIANGLES;
    for (m = 0; m < 2; ++m) {
        /* the scalar tree's single calls first: the answers the others must give */
        for (f = 2; f >= 0; --f) {
            kdrt_build_options options = kdrt_default_build_options();
            kdrt_tree *tree = NULL;
            kdrt_tree_stats stats;
            kdrt_traversal_stats work;
            char label[96];
            kdrt_result r;
            options.intersector = intersectors[m];
            options.flags = flags[f];
            r = kdrt_tree_build(&mesh, &options, &tree, NULL);
            if (r != KDRT_SUCCESS) {
                fprintf(stderr, "kernel_report: FAILED: build: %s\n", kdrt_result_string(r));
                return 1;
            }
            kdrt_tree_get_stats(tree, &stats);
            snprintf(label, sizeof label, "%s, %s (%s kernel)", flag_names[f], intersector_names[m],
                     kdrt_kernel_string(stats.kernel));
            failures += trace(tree, &s, f == 2 ? &reference : &other, label, &work);
            if (m == 0)
                printf("kernel %s: %s (batches: %llu packets, %llu lanes)\n", flag_names[f],
                       kdrt_kernel_string(stats.kernel), (unsigned long long)work.packets,
                       (unsigned long long)work.packet_lanes);
            /* The packet code of the kernel ran: 16 lanes wide (more than 8 a packet on average:
               the camera's rays make full packets) with AVX-512, 8 with AVX2, none scalar. */
            if (stats.kernel == KDRT_KERNEL_SCALAR ? work.packets != 0
                : stats.kernel == KDRT_KERNEL_AVX2 ? work.packets == 0 || work.packet_lanes > 8u * work.packets
                                                   : work.packet_lanes <= 8u * work.packets) {
                fprintf(stderr, "kernel_report: FAILED: %s: %llu packets of %llu lanes in all\n", label,
                        (unsigned long long)work.packets, (unsigned long long)work.packet_lanes);
                ++failures;
            }
            if (f != 2)
                for (i = 0; i < RAYS; ++i)
                    if (!same_hit(&reference.hits[i], &other.hits[i]) ||
                        reference.occluded[i] != other.occluded[i]) {
                        if (failures++ < 5)
                            fprintf(stderr, "kernel_report: FAILED: %s: ray %u: not the scalar kernel's answer\n",
                                    label, (unsigned)i);
                    }
            kdrt_tree_free(tree);
        }
        hash = answers_hash(hash, &reference);
        /* The watertight scalar answers against the brute force: the same t within float's
           rounding (a ray through a shared edge may take either triangle, at the same t). The
           fast test promises no hit on an edge, so it is compared with the others alone. */
        for (i = 0; m == 0 && i < RAYS; ++i) {
            const double t = brute_force_t(&s, &s.rays[i]);
            const kdrt_hit *h = &reference.hits[i];
            const int hit = h->triangle != KDRT_INVALID_ID;
            if (hit != (t >= 0.0) || (hit && fabs(h->t - t) > 1e-5 * (1.0 + t))) {
                if (failures++ < 5)
                    fprintf(stderr, "kernel_report: FAILED: %s: ray %u: t %g, the brute force's %g\n",
                            intersector_names[m], (unsigned)i, hit ? (double)h->t : -1.0, t);
            }
            hits += (uint32_t)hit, misses += (uint32_t)!hit, occluded += reference.occluded[i];
        }
    }
    printf("rays: %u, %u hit, %u miss, %u occluded (on 6 trees: single calls, batches, counted batches)\n",
           (unsigned)RAYS, (unsigned)hits, (unsigned)misses, (unsigned)occluded);
    printf("answers: %08x\n", (unsigned)hash);
    /* rays that all missed or all hit would check little */
    if (hits < RAYS / 4 || misses < RAYS / 20) {
        fprintf(stderr, "kernel_report: FAILED: too few hits or misses to compare\n");
        ++failures;
    }
    if (failures) {
        fprintf(stderr, "kernel_report: %d failures\n", failures);
        return 1;
    }
    printf("kernel_report: all checks passed\n");
    return 0;
}
