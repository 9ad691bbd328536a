/* kdrt_intersect_counted (KDRT_TRAVERSAL_STATS), as strict C99: the counts are the work the
   traversal must do, and the answers are kdrt_intersect's. */
#define KDRT_TRAVERSAL_STATS
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <math.h>
#include <stdio.h>

#define ROWS 8 /* a height field of ROWS x ROWS squares, two triangles each, in z = 0 */

static int failures = 0;

static void check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "smoke_stats: FAILED: %s\n", what);
        ++failures;
    }
}

int main(void)
{
    float vertices[(ROWS + 1) * (ROWS + 1) * 3];
    uint32_t indices[ROWS * ROWS * 6];
    kdrt_triangles mesh = {0};
    kdrt_build_options options = kdrt_default_build_options();
    kdrt_tree *flat = NULL, *tree = NULL;
    kdrt_traversal_stats work = {0}, none = {0};
    kdrt_hit a, b;
    kdrt_ray down = {{2.3f, 5.6f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
    kdrt_ray away = {{2.3f, 5.6f, 1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY, 0};
    uint32_t x, y, n = 0;

    for (y = 0; y <= ROWS; ++y)
        for (x = 0; x <= ROWS; ++x) {
            float *v = &vertices[3 * (y * (ROWS + 1) + x)];
            v[0] = (float)x, v[1] = (float)y, v[2] = 0.01f * (float)((x * 7 + y * 3) % 5);
        }
    for (y = 0; y < ROWS; ++y)
        for (x = 0; x < ROWS; ++x) {
            uint32_t i = y * (ROWS + 1) + x;
            indices[n++] = i, indices[n++] = i + 1, indices[n++] = i + ROWS + 2;
            indices[n++] = i, indices[n++] = i + ROWS + 2, indices[n++] = i + ROWS + 1;
        }
    mesh.positions = vertices;
    mesh.vertex_count = (ROWS + 1) * (ROWS + 1);
    mesh.indices = indices;
    mesh.triangle_count = 2 * ROWS * ROWS;

    /* No tree: one leaf, every triangle tested once. */
    options.max_leaf_size = 0;
    check(kdrt_tree_build(&mesh, &options, &flat, NULL) == KDRT_SUCCESS, "build without a tree");
    check(kdrt_intersect_counted(flat, &down, &a, &work) == 1, "counted hit, no tree");
    check(work.inner_nodes == 0 && work.leaves == 1 && work.empty_leaves == 0, "no tree: one leaf");
    check(work.triangle_tests == 2 * ROWS * ROWS, "no tree: every triangle tested");
    check(kdrt_intersect(flat, &down, &b) == 1 && a.triangle == b.triangle && a.t == b.t, "same answer, no tree");

    /* A tree: fewer tests, the same answer, and counts that add up over calls. */
    options.max_leaf_size = 2;
    check(kdrt_tree_build(&mesh, &options, &tree, NULL) == KDRT_SUCCESS, "build a tree");
    work = none;
    check(kdrt_intersect_counted(tree, &down, &a, &work) == 1, "counted hit, tree");
    check(kdrt_intersect(tree, &down, &b) == 1 && a.triangle == b.triangle && a.t == b.t, "same answer, tree");
    check(work.inner_nodes > 0 && work.leaves > 0 && work.triangle_tests > 0, "a tree is walked");
    check(work.triangle_tests < 2 * ROWS * ROWS, "a tree tests fewer triangles");
    {
        kdrt_traversal_stats twice = work;
        check(kdrt_intersect_counted(tree, &down, &a, &twice) == 1, "counted again");
        check(twice.inner_nodes == 2 * work.inner_nodes && twice.triangle_tests == 2 * work.triangle_tests,
              "counts add up");
    }
    /* A ray leaving the field misses, and a NULL stats pointer is allowed. */
    check(kdrt_intersect_counted(tree, &away, &a, NULL) == 0, "a miss, stats NULL");

    kdrt_tree_free(tree);
    kdrt_tree_free(flat);
    if (failures) return 1;
    printf("smoke_stats: ok\n");
    return 0;
}
