// Meshes as plain arrays, read from files through Assimp, subdivided or generated. Shared by
// kdrt-bench, the examples and the tests.
#pragma once

#include "kdrt.h"

#include <cstdint>
#include <string>
#include <vector>

namespace common {

struct Mesh {
    std::string name;
    std::vector<float> positions;   // packed x, y, z
    std::vector<uint32_t> indices;  // 3 per triangle; empty: a soup (triangle i = vertices 3i..3i+2)

    uint32_t vertex_count() const { return uint32_t(positions.size() / 3); }
    uint32_t triangle_count() const { return uint32_t(indices.empty() ? positions.size() / 9 : indices.size() / 3); }
    kdrt_triangles view() const;  // borrows this mesh's vectors
    // The vertex at corner k (0..2) of a triangle, soup or indexed.
    uint32_t vertex(uint32_t triangle, int k) const {
        return indices.empty() ? 3 * triangle + uint32_t(k) : indices[3 * size_t(triangle) + size_t(k)];
    }
    void corners(uint32_t triangle, double p[3][3]) const;
};

// Any file Assimp reads (OFF, OBJ, PLY, STL, glTF), all its meshes joined, polygons triangulated;
// name is the file stem. false with a one-line message when the path is missing or not a regular
// file, when Assimp fails or logs one of the errors that mean it changed the geometry (a
// malformed file), or when reading it would take more heap than mesh_heap_factor times the bytes
// of the files Assimp opens for it plus mesh_heap_floor (twice that for requests under 1 MiB; the
// message names the request). Assimp runs in a child process (fork), which sends the mesh back:
// a reader that crashes on a malformed file ("Assimp crashed reading it") fails the load, not the
// program, and one that takes more than mesh_cpu_seconds of CPU time, plus one a MB of file, is
// stopped. Call it before starting threads where you can: under Clang 14's AddressSanitizer a
// fork while another thread allocates can leave the child waiting on the allocator's lock (glibc's
// malloc has no such problem). tools/README.md ("Mesh files") says what is refused and why.
bool load_mesh(const std::string &path, Mesh &out, std::string &error);

// The heap a load may take: this many times the size of the files it reads, plus the floor.
// tools/README.md gives the ratios measured on real meshes.
constexpr uint64_t mesh_heap_factor = 128;
constexpr uint64_t mesh_heap_floor = uint64_t(32) << 20;
// The CPU time a load may take: this many seconds, and one more per MB of the mesh file.
constexpr uint64_t mesh_cpu_seconds = 5;

// What a load took (kdrt-mesh-memory measures the ratios with it).
struct MeshLoadStats {
    uint64_t file_bytes = 0;       // of the distinct files Assimp opened
    uint64_t peak_heap_bytes = 0;  // the most live operator-new bytes while reading and copying
};
// load_mesh with other limits (heap_factor times the files' size plus heap_floor; cpu_seconds,
// and one more a MB), and what it took.
bool load_mesh(const std::string &path, Mesh &out, std::string &error, uint64_t heap_factor, uint64_t heap_floor,
               MeshLoadStats *stats, uint64_t cpu_seconds = mesh_cpu_seconds);

// The folder of shared meshes (seed/, common/): the environment variable KDRT_MESH_DIR when it is
// set and not empty, else the folder configured at build time (CMake's KDRT_MESH_DIR option);
// read on every call. Whether it exists is the caller's question.
std::string mesh_dir();
// The folder configured at build time ("" when none was).
const char *configured_mesh_dir();
// For --help: "$KDRT_MESH_DIR, else the one configured at build time: PATH".
std::string mesh_dir_help();

// `levels` rounds of 4-to-1 midpoint subdivision (shared edges share their midpoint).
Mesh subdivided(const Mesh &mesh, unsigned levels);

// A closed, indexed torus centred at the origin around the y axis: `rings` steps around the axis
// times `sides` steps around the tube, two triangles per step, rings * sides vertices (the seams
// share theirs); radii `major` (axis to tube centre) and `minor` (tube); then turned by `tilt`
// radians about the x axis (positive tips the far side, -z, up). Named "generated torus".
Mesh torus(uint32_t rings, uint32_t sides, double major, double minor, double tilt = 0);

}  // namespace common
