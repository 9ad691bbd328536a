// common::Mesh and the meshes made in code (subdivided, torus): all of mesh_io.hpp that needs no
// Assimp, so that the core test suites and the oracle build without it (KDRT_CORE_TESTS_ONLY).
// Reading mesh files is mesh_io.cpp's.
#include "common/mesh_io.hpp"

#include <cmath>
#include <unordered_map>

namespace common {

kdrt_triangles Mesh::view() const {
    kdrt_triangles v{};
    v.positions = positions.empty() ? nullptr : positions.data();
    v.position_stride = 0;
    v.vertex_count = vertex_count();
    v.indices = indices.empty() ? nullptr : indices.data();
    v.triangle_count = triangle_count();
    return v;
}

void Mesh::corners(uint32_t triangle, double p[3][3]) const {
    for (int k = 0; k < 3; ++k) {
        const size_t vtx = vertex(triangle, k);
        for (int a = 0; a < 3; ++a) p[k][a] = positions[vtx * 3 + a];
    }
}

Mesh subdivided(const Mesh &mesh, unsigned levels) {
    Mesh m = mesh;
    if (m.indices.empty())  // a soup: give every corner its own index first
        for (uint32_t i = 0; i < m.vertex_count(); ++i) m.indices.push_back(i);
    for (unsigned level = 0; level < levels; ++level) {
        std::unordered_map<uint64_t, uint32_t> midpoint;  // edge (lo << 32 | hi) -> new vertex
        auto mid = [&](uint32_t a, uint32_t b) {
            uint64_t key = a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a);
            auto found = midpoint.find(key);
            if (found != midpoint.end()) return found->second;
            uint32_t index = m.vertex_count();
            for (int k = 0; k < 3; ++k) m.positions.push_back(0.5f * (m.positions[size_t(a) * 3 + k] + m.positions[size_t(b) * 3 + k]));
            midpoint.emplace(key, index);
            return index;
        };
        std::vector<uint32_t> finer;
        finer.reserve(m.indices.size() * 4);
        for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
            uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
            uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
            finer.insert(finer.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
        }
        m.indices.swap(finer);
    }
    return m;
}

Mesh torus(uint32_t rings, uint32_t sides, double major, double minor, double tilt) {
    const double pi = 3.14159265358979323846;
    Mesh m;
    m.name = "generated torus";
    for (uint32_t i = 0; i < rings; ++i) {
        const double a = 2 * pi * i / rings;
        for (uint32_t j = 0; j < sides; ++j) {
            const double b = 2 * pi * j / sides, r = major + minor * std::cos(b);
            const double x = r * std::cos(a), y = minor * std::sin(b), z = r * std::sin(a);
            m.positions.insert(m.positions.end(), {float(x), float(y * std::cos(tilt) - z * std::sin(tilt)),
                                                   float(y * std::sin(tilt) + z * std::cos(tilt))});
        }
    }
    for (uint32_t i = 0; i < rings; ++i)
        for (uint32_t j = 0; j < sides; ++j) {
            const uint32_t v00 = i * sides + j, v01 = i * sides + (j + 1) % sides;
            const uint32_t v10 = (i + 1) % rings * sides + j, v11 = (i + 1) % rings * sides + (j + 1) % sides;
            m.indices.insert(m.indices.end(), {v00, v10, v11, v00, v11, v01});
        }
    return m;
}

}  // namespace common
