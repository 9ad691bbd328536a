// Every query on the shared meshes (../shared/meshes/seed and common, when present) against the
// brute-force double-precision reference, for every leaf size (see kt::check_scene).
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
    for (size_t i = 0; i < files.size(); ++i) {
        const std::string name = std::filesystem::path(files[i]).filename().string();
        DYNAMIC_SECTION(name) {
            common::Mesh mesh;
            std::string error;
            bool loaded = common::load_mesh(files[i], mesh, error);
            INFO("loading " << files[i] << ": " << error);
            REQUIRE(loaded);
            mesh.name = name;
            kt::check_scene(mesh, rays, 1000 + uint32_t(i));
        }
    }
}
