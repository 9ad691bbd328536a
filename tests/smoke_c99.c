/* The header with its implementation as strict C99 (-std=c99 -Wall -Wextra -pedantic -Werror):
   a tiny tree, one hit, one miss, a query with culling and a filter, the k nearest hits, walking the tree, kdrt_result_string and kdrt_kernel_string, kdrt_version against the version macros, one refraction and the medium stack. */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static int failures = 0;

static void check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "smoke_c99: FAILED: %s\n", what);
        ++failures;
    }
}

/* A filter taking only triangle 0. */
static int only_triangle_0(void *user, const kdrt_ray *ray, const kdrt_hit *candidate)
{
    (void)user, (void)ray;
    return candidate->triangle == 0;
}

int main(void)
{
    /* Two triangles: the unit square in the plane z = 0. */
    static const float vertices[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    static const uint32_t indices[] = {0, 1, 2, 0, 2, 3};
    kdrt_triangles mesh = {0};
    kdrt_build_options options = kdrt_default_build_options();
    kdrt_build_report report;
    kdrt_tree *tree = NULL;
    kdrt_ray down = {{0.25f, 0.75f, 2.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
    kdrt_ray beside = {{1.5f, 0.5f, 2.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
    kdrt_hit hit;
    kdrt_result r;
    const float from_above[3] = {0.6f, 0.0f, -0.8f}, up[3] = {0.0f, 0.0f, 1.0f};
    float refracted[3];
    kdrt_media_stack media;
    kdrt_media_crossing crossing;
    kdrt_tree_stats stats;
    kdrt_node_info node;
    uint32_t triangle = 0, i, k;
    uint64_t refs = 0;
    char version[64];

    mesh.positions = vertices;
    mesh.vertex_count = 4;
    mesh.indices = indices;
    mesh.triangle_count = 2;
    options.max_leaf_size = 1;
    r = kdrt_tree_build(&mesh, &options, &tree, &report);
    check(r == KDRT_SUCCESS && tree != NULL, "build");
    if (!tree) return 1;

    check(kdrt_intersect(tree, &down, &hit) == 1, "hit");
    check(hit.triangle == 1, "hit: triangle 1");
    check(hit.t > 1.999f && hit.t < 2.001f, "hit: t = 2");
    check(kdrt_occluded(tree, &down) == 1, "occluded");
    check(kdrt_intersect(tree, &beside, &hit) == 0, "miss");
    check(hit.triangle == KDRT_INVALID_ID, "miss: triangle is KDRT_INVALID_ID");
    check(kdrt_occluded(tree, &beside) == 0, "miss: not occluded");
    {
        /* The square faces +z (counterclockwise seen from above): down hits its front. */
        kdrt_query query = kdrt_default_query();
        kdrt_hit hits[2];
        query.flags = KDRT_QUERY_CULL_FRONT_FACES;
        check(kdrt_intersect_query(tree, &down, &query, &hit) == 0, "query: the front face culled");
        query.flags = KDRT_QUERY_CULL_BACK_FACES;
        check(kdrt_occluded_query(tree, &down, &query) == 1, "query: back faces culled, a front hit");
        query.filter = only_triangle_0;
        check(kdrt_intersect_query(tree, &down, &query, &hit) == 0, "query: the filter refuses triangle 1");
        check(kdrt_intersect_k(tree, &down, NULL, hits, 2) == 1 && hits[0].triangle == 1, "k nearest: one hit");
    }

    /* Inspection: walking every node finds the references kdrt_tree_get_stats() counts, each
       naming one of the two triangles. */
    kdrt_tree_get_stats(tree, &stats);
    check(kdrt_tree_node_count(tree) == stats.nodes && stats.nodes > 0, "inspection: node count");
    for (i = 0; i < kdrt_tree_node_count(tree); ++i) {
        check(kdrt_tree_node(tree, i, &node) == KDRT_SUCCESS, "inspection: kdrt_tree_node");
        if (!node.is_leaf) continue;
        for (k = 0; k < node.triangle_count; ++k) {
            check(kdrt_tree_reference(tree, node.first_reference + k, &triangle) == KDRT_SUCCESS && triangle < 2,
                  "inspection: a leaf's reference names a triangle");
            ++refs;
        }
    }
    check(refs == stats.triangle_refs, "inspection: references walked = kdrt_tree_stats.triangle_refs");
    {
        /* A scene: the square as mesh 4, and the tree mirrored in x (onto itself) and raised to
           z = 1 as instance 9, so a ray down meets the instance first, on its back face (the
           mirror turns the winding). */
        const float mirror_up[12] = {-1, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 1};
        const kdrt_ray off_diagonal = {{0.25f, 0.6f, 2.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
        kdrt_geometry geometries[2];
        kdrt_scene *scene = NULL;
        kdrt_query query = kdrt_default_query();
        kdrt_hit hits[2];
        float normal[3];
        geometries[0] = kdrt_mesh_geometry(4, &mesh);
        geometries[1] = kdrt_instance_geometry(9, tree, mirror_up);
        check(kdrt_scene_build(geometries, 2, NULL, &scene, NULL) == KDRT_SUCCESS, "scene: build");
        check(kdrt_scene_intersect(scene, &down, NULL, &hit) == 1 && hit.geometry == 9 && hit.instance == 9 &&
                  hit.t > 0.999f && hit.t < 1.001f, "scene: the instance is hit first");
        check(kdrt_scene_hit_surface(scene, &hit, NULL, normal) == 1 && normal[2] < -0.999f,
              "scene: the mirrored instance faces down");
        query.flags = KDRT_QUERY_CULL_BACK_FACES;
        check(kdrt_scene_intersect(scene, &down, &query, &hit) == 1 && hit.geometry == 4 &&
                  hit.instance == KDRT_INVALID_ID, "scene: back faces culled, the mesh is hit");
        check(kdrt_scene_intersect_k(scene, &off_diagonal, NULL, hits, 2) == 2 && hits[0].geometry == 9 &&
                  hits[1].geometry == 4, "scene: k nearest");
        query = kdrt_default_query();
        query.mask = 0;
        check(kdrt_scene_occluded(scene, &down, &query) == 0, "scene: mask 0 sees nothing");
        kdrt_scene_free(scene);
    }
    check(kdrt_tree_node(tree, stats.nodes, &node) == KDRT_ERROR_INDEX_OUT_OF_RANGE, "inspection: node out of range");
    check(kdrt_tree_reference(tree, (uint32_t)stats.triangle_refs, &triangle) == KDRT_ERROR_INDEX_OUT_OF_RANGE,
          "inspection: reference out of range");
    kdrt_tree_free(tree);

    check(strcmp(kdrt_result_string(KDRT_SUCCESS), "success") == 0, "kdrt_result_string(KDRT_SUCCESS)");
    check(strcmp(kdrt_result_string(KDRT_ERROR_OUT_OF_MEMORY), "out of memory") == 0,
          "kdrt_result_string(KDRT_ERROR_OUT_OF_MEMORY)");
    check(strcmp(kdrt_kernel_string(stats.kernel), "unknown") != 0 &&
              strcmp(kdrt_kernel_string(KDRT_KERNEL_NEON), "neon") == 0 &&
              strcmp(kdrt_kernel_string((kdrt_kernel)99), "unknown") == 0,
          "kdrt_kernel_string");
    snprintf(version, sizeof version, "%d.%d.%d", KDRT_VERSION_MAJOR, KDRT_VERSION_MINOR, KDRT_VERSION_PATCH);
    check(strcmp(version, KDRT_VERSION_STRING) == 0, "KDRT_VERSION_STRING is MAJOR.MINOR.PATCH");
    check(strcmp(kdrt_version(), KDRT_VERSION_STRING) == 0, "kdrt_version() is KDRT_VERSION_STRING");
    check(kdrt_tree_build(NULL, &options, &tree, NULL) == KDRT_ERROR_NULL_ARGUMENT && tree == NULL,
          "NULL mesh is KDRT_ERROR_NULL_ARGUMENT");

    /* Into glass from air: sin(theta_t) = 0.6 / 1.5 = 0.4. */
    check(kdrt_refract(from_above, up, 1.0f / 1.5f, refracted) == 1, "refract");
    check(fabs(refracted[0] - 0.4) < 1e-6 && refracted[2] < 0.0f, "refract: sin(theta_t) = 0.4");
    check(kdrt_fresnel_dielectric(1.0f, 1.5f) > 0.0399f && kdrt_fresnel_dielectric(1.0f, 1.5f) < 0.0401f,
          "Fresnel: 0.04 at normal incidence");
    check(kdrt_media_init(&media, 1.0f) == KDRT_SUCCESS, "media: init");
    crossing = kdrt_media_at_surface(&media, 7, 1.5f, 0);
    check(crossing.entering && crossing.real && crossing.eta_transmitted == 1.5f, "media: entering glass");
    check(kdrt_media_enter(&media, 7, 1.5f, 0) == KDRT_SUCCESS && kdrt_media_current_ior(&media) == 1.5f,
          "media: in glass");
    check(kdrt_media_leave(&media, 8) == KDRT_ERROR_NOT_IN_MEDIUM, "media: leaving what was not entered");

    if (failures) return 1;
    printf("smoke_c99: ok (kdrt %s)\n", KDRT_VERSION_STRING);
    return 0;
}
