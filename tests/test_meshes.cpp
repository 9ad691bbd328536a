// Every query on the shared meshes (../shared/meshes/seed and common, when present) against the
// brute-force double-precision reference, for every leaf size (see kt::check_scene): every mesh,
// or those of at most KDRT_TEST_MESH_TRIANGLES triangles (the scalar copy, tests/CMakeLists.txt).
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>

TEST_CASE("shared meshes agree with the reference", "[meshes]") {
    const std::vector<std::string> files = kt::shared_mesh_files();
    if (files.empty()) {
        kt::skip_test("no shared meshes (configure with -DKDRT_MESH_DIR=<folder holding seed/ and common/>; "
                      "the default is ../shared/meshes next to the repository)");
        return;
    }
    size_t rays = kt::shared_mesh_ray_count();
    const size_t max_triangles = kt::shared_mesh_max_triangles();
    for (size_t i = 0; i < files.size(); ++i) {
        const std::string name = std::filesystem::path(files[i]).filename().string();
        DYNAMIC_SECTION(name) {
            common::Mesh mesh;
            std::string error;
            bool loaded = common::load_mesh(files[i], mesh, error);
            INFO("loading " << files[i] << ": " << error);
            REQUIRE(loaded);
            mesh.name = name;
            if (max_triangles != 0 && mesh.triangle_count() > max_triangles) {
                WARN(name << ": " << mesh.triangle_count() << " triangles, more than KDRT_TEST_MESH_TRIANGLES ("
                          << max_triangles << "): left out");
            } else {
                kt::check_scene(mesh, rays, 1000 + uint32_t(i));
            }
        }
    }
}
