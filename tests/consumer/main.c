/* Links kdrt::kdrt from an installed package or a subdirectory (or gets kdrt's flags from
   pkg-config), makes one query and checks that kdrt_version() is the version macros' string. */
#define KDRT_IMPLEMENTATION
#include <kdrt.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

int main(void)
{
    static const float triangle[] = {-1, -1, 0, 1, -1, 0, 0, 1, 0};
    kdrt_triangles mesh = {0};
    kdrt_tree *tree = NULL;
    kdrt_ray ray = {{0.0f, 0.0f, -1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY, 0};
    kdrt_hit hit;
    kdrt_result r;
    int ok;
    char version[64];

    snprintf(version, sizeof version, "%d.%d.%d", KDRT_VERSION_MAJOR, KDRT_VERSION_MINOR, KDRT_VERSION_PATCH);
    if (strcmp(kdrt_version(), version) != 0 || strcmp(KDRT_VERSION_STRING, version) != 0) {
        fprintf(stderr, "kdrt_consumer: kdrt_version() says %s, KDRT_VERSION_STRING %s, the macros %s\n",
                kdrt_version(), KDRT_VERSION_STRING, version);
        return 1;
    }
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
    printf("kdrt_consumer: ok (kdrt %s)\n", kdrt_version());
    return 0;
}
