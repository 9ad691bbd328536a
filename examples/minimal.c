#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <math.h>
#include <stdio.h>

int main(void)
{
    /* Two triangles: the unit square in the plane z = 0. */
    static const float vertices[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    static const uint32_t indices[] = {0, 1, 2, 0, 2, 3};

    kdrt_triangles mesh = {0};
    mesh.positions = vertices;     /* borrowed: must outlive the tree */
    mesh.position_stride = 0;      /* 0: packed x, y, z */
    mesh.vertex_count = 4;
    mesh.indices = indices;        /* or NULL for a triangle soup */
    mesh.triangle_count = 2;

    kdrt_build_options options = kdrt_default_build_options();
    kdrt_tree *tree = NULL;
    kdrt_result r = kdrt_tree_build(&mesh, &options, &tree, NULL);
    if (r != KDRT_SUCCESS) {
        fprintf(stderr, "kdrt: %s\n", kdrt_result_string(r));
        return 1;
    }

    /* Straight down onto (0.75, 0.25): triangle 0, at distance 1. */
    kdrt_ray ray = {{0.75f, 0.25f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
    kdrt_hit hit;
    int ok = kdrt_intersect(tree, &ray, &hit) && hit.triangle == 0 && hit.t > 0.999f && hit.t < 1.001f;

    /* A shadow ray from (0.25, 0.75, 1) that stops at t = 0.5, above the square: not occluded. */
    kdrt_ray shadow = {{0.25f, 0.75f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, 0.5f, 0};
    ok = ok && !kdrt_occluded(tree, &shadow);

    kdrt_tree_free(tree);
    if (!ok) {
        fprintf(stderr, "unexpected result\n");
        return 1;
    }
    printf("hit triangle %u at t = %g, u = %g, v = %g\n", (unsigned)hit.triangle, hit.t, hit.u, hit.v);
    return 0;
}
