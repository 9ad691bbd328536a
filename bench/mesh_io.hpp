// Meshes as plain arrays, read from files through Assimp. Shared by kdrt-bench and the tests.
#pragma once

#include "kdrt.h"

#include <cstdint>
#include <string>
#include <vector>

namespace kt {

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

}  // namespace kt
