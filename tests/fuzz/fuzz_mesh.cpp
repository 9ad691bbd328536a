// libFuzzer target: the mesh loader (common::load_mesh, examples/common/mesh_io.*) on any bytes.
// The first byte picks the file's extension, and so Assimp's reader: '0' .off, '1' .obj, '2' .ply,
// '3' .stl, '4' .gltf, '5' .glb (the byte modulo 6); the rest is the file. Checked: load_mesh
// returns, without a crash, a leak or undefined behaviour in our code (Assimp is the system's,
// not instrumented); a refusal has a message; an accepted mesh has whole triangles whose indices
// are in range, and kdrt builds a tree over it or says why not.
#include "kdrt.h"
#include "common/mesh_io.hpp"
#include "fuzz_support.hpp"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <unistd.h>

namespace {

// A folder of this process's own for the input file, removed at exit.
struct WorkDir {
    std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("kdrt-fuzz-mesh-" + std::to_string(getpid()));
    WorkDir() { std::filesystem::create_directories(path); }
    ~WorkDir() {
        std::error_code ignored;
        std::filesystem::remove_all(path, ignored);
    }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size == 0) return 0;
    static const char *const extensions[] = {"off", "obj", "ply", "stl", "gltf", "glb"};
    static const WorkDir dir;
    const std::string path = (dir.path / (std::string("input.") + extensions[data[0] % 6])).string();
    {
        std::ofstream file(path, std::ios::binary | std::ios::trunc);
        file.write(reinterpret_cast<const char *>(data + 1), std::streamsize(size - 1));
        FUZZ_CHECK(file.good(), "cannot write %s", path.c_str());
    }
    common::Mesh mesh;
    std::string error;
    if (!common::load_mesh(path, mesh, error)) {
        FUZZ_CHECK(!error.empty(), "refused without a message");
        return 0;
    }
    FUZZ_CHECK(mesh.positions.size() % 3 == 0 && mesh.indices.size() % 3 == 0, "%zu coordinates, %zu indices",
               mesh.positions.size(), mesh.indices.size());
    for (uint32_t i : mesh.indices) FUZZ_CHECK(i < mesh.vertex_count(), "index %u of %u vertices", i, mesh.vertex_count());
    if (mesh.indices.empty()) FUZZ_CHECK(mesh.positions.size() % 9 == 0, "a soup of %zu coordinates", mesh.positions.size());

    // What every tool does next. Non-finite coordinates are the file's, and refused by name.
    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    kdrt_build_report report;
    const kdrt_result r = kdrt_tree_build(&view, nullptr, &tree, &report);
    FUZZ_CHECK(r == KDRT_SUCCESS || r == KDRT_ERROR_NON_FINITE_VERTEX, "kdrt_tree_build: %s", kdrt_result_string(r));
    kdrt_tree_free(tree);
    return 0;
}
