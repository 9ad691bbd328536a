/* The stack kdrt's calls need, for engines that run them on small fiber or job stacks: each
   call is made on a thread whose stack this program owns and filled with a pattern first, and
   the deepest byte changed is its high-water mark (less what an empty thread uses). Not a test:
   the figures of the manual (kdrt.h, PLATFORMS) come from it.
     cc -O2 -I include tests/platforms/stack_usage.c -o stack_usage -lm -lpthread && ./stack_usage
   Needs POSIX threads (pthread_attr_setstack). */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define STACK_BYTES (1u << 20)
#define RAYS 256u
#define PATTERN 0xAB

typedef enum call { EMPTY, BUILD_MEDIUM, BUILD_HIGH, INTERSECT, OCCLUDED, INTERSECT_K, BATCHES } call;
static const char *const call_names[] = {"(an empty thread)", "kdrt_tree_build, MEDIUM",
                                         "kdrt_tree_build, HIGH", "kdrt_intersect",
                                         "kdrt_occluded", "kdrt_intersect_k (16)",
                                         "kdrt_intersect_batch, kdrt_occluded_batch"};

typedef struct job {
    call what;
    const kdrt_triangles *mesh;
    const kdrt_tree *tree;
    uint32_t flags, depth, hits;
    const kdrt_ray *rays;
} job;

static void *run(void *arg)
{
    job *j = (job *)arg;
    static kdrt_hit hits[RAYS];
    static uint8_t occluded[RAYS];
    uint32_t i;
    if (j->what == BUILD_MEDIUM || j->what == BUILD_HIGH) {
        kdrt_build_options o = kdrt_default_build_options();
        kdrt_tree *tree = NULL;
        kdrt_tree_stats stats;
        o.quality = j->what == BUILD_HIGH ? KDRT_BUILD_QUALITY_HIGH : KDRT_BUILD_QUALITY_MEDIUM;
        o.max_depth = KDRT_MAX_DEPTH, o.flags = j->flags;
        if (kdrt_tree_build(j->mesh, &o, &tree, NULL) == KDRT_SUCCESS) {
            kdrt_tree_get_stats(tree, &stats);
            j->depth = stats.max_depth;
        }
        kdrt_tree_free(tree);
    }
    for (i = 0; i < RAYS; ++i) {
        if (j->what == INTERSECT) j->hits += (uint32_t)kdrt_intersect(j->tree, &j->rays[i], &hits[i]);
        if (j->what == OCCLUDED) j->hits += (uint32_t)kdrt_occluded(j->tree, &j->rays[i]);
        if (j->what == INTERSECT_K) j->hits += kdrt_intersect_k(j->tree, &j->rays[i], NULL, hits, 16);
    }
    if (j->what == BATCHES)
        j->hits = kdrt_intersect_batch(j->tree, j->rays, RAYS, NULL, hits) +
                  kdrt_occluded_batch(j->tree, j->rays, RAYS, NULL, occluded);
    return NULL;
}

/* The bytes of stack one job used, the thread's own start included. */
static size_t stack_used(unsigned char *stack, job *j)
{
    pthread_attr_t attr;
    pthread_t thread;
    size_t i = 0;
    memset(stack, PATTERN, STACK_BYTES);
    pthread_attr_init(&attr);
    if (pthread_attr_setstack(&attr, stack, STACK_BYTES) != 0 ||
        pthread_create(&thread, &attr, run, j) != 0) {
        fprintf(stderr, "stack_usage: cannot start a thread on its own stack\n");
        exit(1);
    }
    pthread_join(thread, NULL);
    pthread_attr_destroy(&attr);
    while (i < STACK_BYTES && stack[i] == PATTERN) ++i; /* the stack grows down */
    return STACK_BYTES - i;
}

int main(void)
{
    /* Triangles of every size, clustered at every scale (coordinates 2^-k apart), so that the
       builders go as deep as KDRT_MAX_DEPTH lets them. */
    enum { TRIANGLES = 100000 };
    static float v[9 * TRIANGLES];
    static kdrt_ray rays[RAYS];
    static const uint32_t kernels[] = {0u, KDRT_BUILD_AVX2_KERNEL, KDRT_BUILD_SCALAR_KERNEL};
    kdrt_triangles mesh;
    unsigned char *stack = (unsigned char *)malloc(STACK_BYTES);
    size_t empty;
    uint32_t i, k;
    int c;
    job j;
    if (!stack) return 1;
    for (i = 0; i < TRIANGLES; ++i) {
        const float scale = 1.0f / (float)(1u << (i % 20u)), x = (float)(i % 317u) * scale;
        const float y = (float)(i % 211u) * scale, z = (float)(i % 97u) * scale, s = scale / 4.0f;
        float *p = v + 9 * i;
        p[0] = x, p[1] = y, p[2] = z, p[3] = x + s, p[4] = y, p[5] = z + s, p[6] = x, p[7] = y + s;
        p[8] = z;
    }
    for (i = 0; i < RAYS; ++i) {
        kdrt_ray r = {{0.5f + (float)(i % 16u), 0.5f + (float)(i / 16u), -1.0f}, 0.0f,
                      {0.01f, 0.02f, 1.0f}, INFINITY, 0};
        rays[i] = r;
    }
    memset(&mesh, 0, sizeof mesh);
    mesh.positions = v, mesh.vertex_count = 3 * TRIANGLES, mesh.triangle_count = TRIANGLES;
    memset(&j, 0, sizeof j);
    empty = stack_used(stack, &j);
    printf("stack a call needs beyond an empty thread's %zu bytes (x86-64 or whatever this was "
           "built for; %d triangles):\n", empty, TRIANGLES);
    for (k = 0; k < sizeof kernels / sizeof *kernels; ++k) {
        kdrt_build_options o = kdrt_default_build_options();
        kdrt_tree *tree = NULL;
        kdrt_tree_stats stats;
        o.flags = kernels[k];
        if (kdrt_tree_build(&mesh, &o, &tree, NULL) != KDRT_SUCCESS) return 1;
        kdrt_tree_get_stats(tree, &stats);
        printf("kernel %d:\n", (int)stats.kernel);
        for (c = BUILD_MEDIUM; c <= BATCHES; ++c) {
            size_t used;
            memset(&j, 0, sizeof j);
            j.what = (call)c, j.mesh = &mesh, j.tree = tree, j.flags = kernels[k], j.rays = rays;
            used = stack_used(stack, &j);
            printf("  %-44s %6zu bytes", call_names[c], used - empty);
            if (j.depth) printf(" (a tree %u deep)", j.depth);
            printf("\n");
        }
        kdrt_tree_free(tree);
    }
    free(stack);
    return 0;
}
