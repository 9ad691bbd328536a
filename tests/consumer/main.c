/* Links kdrt::kdrt from an installed package or a subdirectory, and makes one query. */
#define KDRT_IMPLEMENTATION
#include <kdrt.h>

#include <math.h>
#include <stdio.h>

int main(void)
{
    static const float triangle[] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
    kdrt_triangles mesh = {0};
    kdrt_tree *tree = NULL;
    kdrt_ray ray = {{0.0f, 0.0f, -1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY, 0};
    kdrt_hit hit;
    kdrt_result r;
    int ok;

    mesh.positions = triangle;
    mesh.vertex_count = 3;
    mesh.triangle_count = 1;
    r = kdrt_tree_build(&mesh, NULL, &tree, NULL);
    if (r != KDRT_SUCCESS) {
        fprintf(stderr, "kdrt_consumer: %s\n", kdrt_result_string(r));
        return 1;
    }
    ok = kdrt_intersect(tree, &ray, &hit) && hit.triangle == 0;
    kdrt_tree_free(tree);
    if (!ok) {
        fprintf(stderr, "kdrt_consumer: the ray missed\n");
        return 1;
    }
    printf("kdrt_consumer: ok (kdrt %s)\n", KDRT_VERSION_STRING);
    return 0;
}
