// The header with its implementation as strict C++11 (-std=c++11 -Wall -Wextra -pedantic
// -Werror), every function static (KDRT_STATIC): a tiny tree, one hit, one miss,
// kdrt_result_string, one refraction and the medium stack.
#define KDRT_STATIC
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace {

int failures = 0;

void check(bool ok, const char *what)
{
    if (!ok) {
        std::fprintf(stderr, "smoke_cpp11: FAILED: %s\n", what);
        ++failures;
    }
}

} // namespace

int main()
{
    // Two triangles: the unit square in the plane z = 0.
    static const float vertices[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    static const uint32_t indices[] = {0, 1, 2, 0, 2, 3};
    kdrt_triangles mesh = {};
    mesh.positions = vertices;
    mesh.vertex_count = 4;
    mesh.indices = indices;
    mesh.triangle_count = 2;

    kdrt_build_options options = kdrt_default_build_options();
    options.max_leaf_size = 1;
    kdrt_tree *tree = nullptr;
    const kdrt_result r = kdrt_tree_build(&mesh, &options, &tree, nullptr);
    check(r == KDRT_SUCCESS && tree != nullptr, "build");
    if (!tree) return 1;

    const kdrt_ray down = {{0.75f, 0.25f, 2.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
    const kdrt_ray beside = {{-0.5f, 0.5f, 2.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY, 0};
    kdrt_hit hit;
    check(kdrt_intersect(tree, &down, &hit) == 1, "hit");
    check(hit.triangle == 0, "hit: triangle 0");
    check(hit.t > 1.999f && hit.t < 2.001f, "hit: t = 2");
    check(kdrt_occluded(tree, &down) == 1, "occluded");
    check(kdrt_intersect(tree, &beside, &hit) == 0, "miss");
    check(hit.triangle == KDRT_INVALID_ID, "miss: triangle is KDRT_INVALID_ID");
    check(kdrt_occluded(tree, &beside) == 0, "miss: not occluded");
    kdrt_tree_free(tree);

    check(std::strcmp(kdrt_result_string(KDRT_SUCCESS), "success") == 0, "kdrt_result_string(KDRT_SUCCESS)");
    check(std::strcmp(kdrt_result_string(KDRT_ERROR_INVALID_STRIDE), kdrt_result_string(KDRT_SUCCESS)) != 0,
          "kdrt_result_string tells errors apart");

    // Into glass from air: sin(theta_t) = 0.6 / 1.5 = 0.4.
    const float from_above[3] = {0.6f, 0.0f, -0.8f}, up[3] = {0.0f, 0.0f, 1.0f};
    float refracted[3];
    check(kdrt_refract(from_above, up, 1.0f / 1.5f, refracted) == 1, "refract");
    check(std::fabs(refracted[0] - 0.4f) < 1e-6f && refracted[2] < 0.0f, "refract: sin(theta_t) = 0.4");
    kdrt_media_stack media;
    check(kdrt_media_init(&media, 1.0f) == KDRT_SUCCESS, "media: init");
    check(kdrt_media_enter(&media, 7, 1.5f, 0) == KDRT_SUCCESS && kdrt_media_current_ior(&media) == 1.5f,
          "media: in glass");
    check(kdrt_media_leave(&media, 8) == KDRT_ERROR_NOT_IN_MEDIUM, "media: leaving what was not entered");

    if (failures) return 1;
    std::printf("smoke_cpp11: ok (kdrt %s)\n", KDRT_VERSION_STRING);
    return 0;
}
