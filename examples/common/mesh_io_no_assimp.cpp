// common::load_mesh in the build without Assimp (KDRT_CORE_TESTS_ONLY, tests/platforms): it reads
// no file, and says so. Its suites configure no mesh folder, so those that load meshes skip.
#include "common/mesh_io.hpp"

namespace common {

bool load_mesh(const std::string &path, Mesh &out, std::string &error, uint64_t, uint64_t, MeshLoadStats *stats,
               uint64_t) {
    out = Mesh();
    if (stats) *stats = MeshLoadStats();
    error = "cannot read '" + path + "': this build has no mesh loader (configured with KDRT_CORE_TESTS_ONLY, without Assimp)";
    return false;
}

bool load_mesh(const std::string &path, Mesh &out, std::string &error) {
    return load_mesh(path, out, error, mesh_heap_factor, mesh_heap_floor, nullptr);
}

}  // namespace common
