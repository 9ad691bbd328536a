/* The SAH builder on its own (bench/README.md, "Build quality"): each OBJ file built REPEAT
   times by kdrt_tree_build on the calling thread (leaf size 4, QUALITY 1 FAST, 2 MEDIUM, 3 HIGH),
   printing the median of the builds' thread CPU times, which other processes on the machine
   change less than wall time, and the tree's SAH cost. Not built by CMake: a program to compare
   builder changes in turns (a copy of kdrt.h with the change in another folder) and to run
   under callgrind. Its OBJ reader takes `v` and `f` lines only, polygons as fans.
     gcc -O2 -std=gnu99 -Iinclude bench/build_timer.c -o build_timer -lm
     ./build_timer 7 1 $M/stanford-bunny.obj $M/ogre.obj $M/nefertiti.obj   # REPEAT QUALITY OBJ... */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define MAX_REPEAT 99

static int by_value(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Appends v to a growing array of 4-byte values; returns 0 when out of memory. */
static int push(void **array, size_t *count, size_t *capacity, const void *v)
{
    if (*count == *capacity) {
        size_t grown = *capacity ? 2 * *capacity : 4096;
        void *p = realloc(*array, grown * 4);
        if (!p) return 0;
        *array = p, *capacity = grown;
    }
    memcpy((char *)*array + 4 * (*count)++, v, 4);
    return 1;
}

static double thread_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

int main(int argc, char **argv)
{
    const int repeat = argc > 1 ? atoi(argv[1]) : 0;
    const int quality = argc > 2 ? atoi(argv[2]) : 0;
    int f;
    if (argc < 4 || repeat < 1 || repeat > MAX_REPEAT || quality < 1 || quality > 3) {
        fprintf(stderr, "usage: build_timer REPEAT (1-%d) QUALITY (1 fast, 2 medium, 3 high) OBJ...\n",
                MAX_REPEAT);
        return 2;
    }
    for (f = 3; f < argc; ++f) {
        FILE *file = fopen(argv[f], "r");
        char line[1024];
        float *positions = NULL;
        uint32_t *indices = NULL;
        size_t floats = 0, float_room = 0, ints = 0, int_room = 0;
        double ms[MAX_REPEAT], sah = 0.0;
        kdrt_triangles mesh;
        kdrt_build_options options = kdrt_default_build_options();
        int r, ok = file != NULL;
        while (ok && fgets(line, sizeof line, file)) {
            if (line[0] == 'v' && line[1] == ' ') {
                float v[3] = {0, 0, 0};
                int k;
                sscanf(line + 2, "%f %f %f", &v[0], &v[1], &v[2]);
                for (k = 0; k < 3 && ok; ++k)
                    ok = push((void **)&positions, &floats, &float_room, &v[k]);
            } else if (line[0] == 'f' && line[1] == ' ') {
                uint32_t v[64];
                int n = 0, k;
                char *s = line + 2, *end;
                while (n < 64) { /* "7", "7/1" or "7/1/3": the vertex is the first number */
                    long i = strtol(s, &end, 10);
                    if (end == s) break;
                    v[n++] = (uint32_t)(i - 1);
                    for (s = end; *s && *s != ' ' && *s != '\t'; ++s) {}
                }
                for (k = 2; k < n && ok; ++k)
                    ok = push((void **)&indices, &ints, &int_room, &v[0]) &&
                         push((void **)&indices, &ints, &int_room, &v[k - 1]) &&
                         push((void **)&indices, &ints, &int_room, &v[k]);
            }
        }
        if (file) fclose(file);
        if (!ok) {
            fprintf(stderr, "build_timer: %s: cannot read it\n", argv[f]);
            return 1;
        }
        memset(&mesh, 0, sizeof mesh);
        mesh.positions = positions, mesh.vertex_count = (uint32_t)(floats / 3);
        mesh.indices = indices, mesh.triangle_count = (uint32_t)(ints / 3);
        options.builder = KDRT_BUILDER_SAH, options.max_leaf_size = 4;
        options.quality = (kdrt_build_quality)quality;
        for (r = 0; r < repeat; ++r) {
            kdrt_tree *tree = NULL;
            kdrt_tree_stats stats;
            const double start = thread_ms();
            kdrt_result result = kdrt_tree_build(&mesh, &options, &tree, NULL);
            ms[r] = thread_ms() - start;
            if (result != KDRT_SUCCESS) {
                fprintf(stderr, "build_timer: %s: %s\n", argv[f], kdrt_result_string(result));
                return 1;
            }
            kdrt_tree_get_stats(tree, &stats);
            sah = stats.sah_cost;
            kdrt_tree_free(tree);
        }
        qsort(ms, (size_t)repeat, sizeof ms[0], by_value);
        printf("%s %u triangles: %.2f ms, SAH cost %.1f\n", argv[f], mesh.triangle_count,
               ms[repeat / 2], sah);
        free(positions), free(indices);
    }
    return 0;
}
