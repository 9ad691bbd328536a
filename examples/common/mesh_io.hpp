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
    void corners(uint32_t triangle, double p[3][3]) const;
};

// Any file Assimp reads (OFF, OBJ, PLY, STL, glTF), all its meshes joined, polygons triangulated;
// name is the file stem. false with Assimp's message when the file is missing or malformed.
bool load_mesh(const std::string &path, Mesh &out, std::string &error);

// `levels` rounds of 4-to-1 midpoint subdivision (shared edges share their midpoint).
Mesh subdivided(const Mesh &mesh, unsigned levels);

// A closed, indexed torus centred at the origin around the y axis: `rings` steps around the axis
// times `sides` steps around the tube, two triangles per step, rings * sides vertices (the seams
// share theirs); radii `major` (axis to tube centre) and `minor` (tube); then turned by `tilt`
// radians about the x axis (positive tips the far side, -z, up). Named "generated torus".
Mesh torus(uint32_t rings, uint32_t sides, double major, double minor, double tilt = 0);

}  // namespace common
