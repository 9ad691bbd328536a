#include "common/mesh_io.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
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
        size_t vtx = indices.empty() ? size_t(triangle) * 3 + k : indices[size_t(triangle) * 3 + k];
        for (int a = 0; a < 3; ++a) p[k][a] = positions[vtx * 3 + a];
    }
}

namespace {

// Assimp's PLY reader never returns on a file that ends inside its header (no end_header line).
bool ply_header_complete(const std::string &path) {
    FILE *file = std::fopen(path.c_str(), "rb");
    if (!file) return true; // Assimp reports it
    char head[4] = {0, 0, 0, 0};
    bool ok = true;
    if (std::fread(head, 1, 3, file) == 3 && std::strncmp(head, "ply", 3) == 0) {
        std::string header;
        char buffer[4096];
        size_t n;
        while (header.find("end_header") == std::string::npos && header.size() < (1u << 20) &&
               (n = std::fread(buffer, 1, sizeof buffer, file)) > 0)
            header.append(buffer, n);
        ok = header.find("end_header") != std::string::npos;
    }
    std::fclose(file);
    return ok;
}

// Faces Assimp's readers leave behind on malformed input, which its triangulation step would
// abort on (Debian builds Assimp with its internal assertions on): a face without indices, an
// index out of range, or primitive-type flags that disagree with the faces.
bool check_faces(const aiScene *scene, std::string &error) {
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        aiMesh *mesh = scene->mMeshes[m];
        if (mesh->mNumFaces > 0 && (!mesh->mFaces || !mesh->mVertices)) {
            error = "mesh " + std::to_string(m) + " has faces but no vertex or face data";
            return false;
        }
        unsigned types = 0;
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const aiFace &face = mesh->mFaces[f];
            if (face.mNumIndices == 0 || !face.mIndices) {
                error = "face " + std::to_string(f) + " of mesh " + std::to_string(m) + " has no vertices";
                return false;
            }
            for (unsigned k = 0; k < face.mNumIndices; ++k) {
                if (face.mIndices[k] >= mesh->mNumVertices) {
                    error = "face " + std::to_string(f) + " of mesh " + std::to_string(m) +
                            " refers to a vertex that does not exist";
                    return false;
                }
            }
            types |= face.mNumIndices == 1   ? aiPrimitiveType_POINT
                     : face.mNumIndices == 2 ? aiPrimitiveType_LINE
                     : face.mNumIndices == 3 ? aiPrimitiveType_TRIANGLE
                                             : aiPrimitiveType_POLYGON;
        }
        mesh->mPrimitiveTypes = types;
    }
    return true;
}

}  // namespace

bool load_mesh(const std::string &path, Mesh &out, std::string &error) {
    if (!ply_header_complete(path)) {
        error = "malformed PLY file: its header has no end_header line";
        return false;
    }
    // Read and validate first, check what Assimp's validation lets through, then triangulate,
    // merge identical vertices and bake the node transforms into the vertices.
    Assimp::Importer importer;
    const aiScene *scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
    if (!scene) {
        error = importer.GetErrorString();
        if (error.empty()) error = "Assimp could not read it";
        return false;
    }
    if (!check_faces(scene, error)) {
        error = "malformed file: " + error;
        return false;
    }
    scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                         aiProcess_PreTransformVertices);
    if (!scene) {
        error = importer.GetErrorString();
        if (error.empty()) error = "Assimp could not process it";
        return false;
    }
    out = Mesh();
    out.name = std::filesystem::path(path).stem().string();
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
        const aiMesh *mesh = scene->mMeshes[mi];
        const size_t base = out.vertex_count();
        if (base + mesh->mNumVertices > KDRT_MAX_TRIANGLES) {
            error = "too many vertices";
            return false;
        }
        for (unsigned v = 0; v < mesh->mNumVertices; ++v)
            out.positions.insert(out.positions.end(), {mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z});
        for (unsigned f = 0; f < mesh->mNumFaces; ++f)
            if (mesh->mFaces[f].mNumIndices == 3)  // points and lines are not surfaces
                for (int k = 0; k < 3; ++k) out.indices.push_back(uint32_t(base + mesh->mFaces[f].mIndices[k]));
    }
    if (out.indices.empty()) {
        error = "it holds no triangles";
        return false;
    }
    return true;
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
