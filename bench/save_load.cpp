// Saved trees (kdrt.h, SAVED TREES): for each OBJ mesh named, a FAST build, a default (MEDIUM)
// build, the save to memory and the load of each tree (copied, and KDRT_LOAD_IN_PLACE from a
// 64-byte aligned buffer), and what the load's mesh fingerprint costs alone; the fastest of
// --repeat runs (default 7: the machine may be shared), one thread, as a CSV row each. Not built
// by CMake: kdrt-bench will time save and load beside its builds; this is the program behind the
// manual's figures.
//   g++ -O2 -std=c++17 -Iinclude bench/save_load.cpp -o save_load
//   M=../shared/meshes/common
//   ./save_load $M/stanford-bunny.obj $M/ogre.obj --subdivide 2 $M/stanford-bunny.obj
// --subdivide N applies to the meshes after it: N rounds of 4-to-1 midpoint subdivision, as
// kdrt-bench --subdivide does (examples/common/mesh.cpp).
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

namespace {

struct Mesh {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    kdrt_triangles view() const {
        kdrt_triangles v{};
        v.positions = positions.data(), v.vertex_count = uint32_t(positions.size() / 3);
        v.indices = indices.data(), v.triangle_count = uint32_t(indices.size() / 3);
        return v;
    }
};

// v and f lines; polygons as fans; "f a/b/c" and negative indices.
bool read_obj(const char *path, Mesh &m) {
    std::ifstream in(path);
    if (!in) return false;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream s(line);
        std::string tag;
        s >> tag;
        if (tag == "v") {
            float x, y, z;
            s >> x >> y >> z;
            m.positions.insert(m.positions.end(), {x, y, z});
        } else if (tag == "f") {
            std::vector<uint32_t> face;
            std::string corner;
            while (s >> corner) {
                long i = std::strtol(corner.c_str(), nullptr, 10);
                face.push_back(uint32_t(i < 0 ? long(m.positions.size() / 3) + i : i - 1));
            }
            for (size_t k = 1; k + 1 < face.size(); ++k) m.indices.insert(m.indices.end(), {face[0], face[k], face[k + 1]});
        }
    }
    return !m.indices.empty();
}

Mesh subdivided(Mesh m, unsigned levels) {
    for (unsigned level = 0; level < levels; ++level) {
        std::unordered_map<uint64_t, uint32_t> midpoint;
        auto mid = [&](uint32_t a, uint32_t b) {
            uint64_t key = a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a);
            auto found = midpoint.find(key);
            if (found != midpoint.end()) return found->second;
            uint32_t index = uint32_t(m.positions.size() / 3);
            for (int k = 0; k < 3; ++k) m.positions.push_back(0.5f * (m.positions[size_t(a) * 3 + k] + m.positions[size_t(b) * 3 + k]));
            midpoint.emplace(key, index);
            return index;
        };
        std::vector<uint32_t> finer;
        for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
            uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
            uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
            finer.insert(finer.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
        }
        m.indices.swap(finer);
    }
    return m;
}

double now_ms() {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

template <class F> double fastest_ms(int repeat, F f) {
    double best = 1e300;
    for (int i = 0; i < repeat; ++i) {
        double a = now_ms();
        f();
        best = std::min(best, now_ms() - a);
    }
    return best;
}

int append(void *user, const void *bytes, size_t size) {
    auto *out = static_cast<std::vector<unsigned char> *>(user);
    out->insert(out->end(), static_cast<const unsigned char *>(bytes), static_cast<const unsigned char *>(bytes) + size);
    return 1;
}

}  // namespace

int main(int argc, char **argv) {
    int repeat = 7;
    unsigned subdivide = 0;
    std::printf("mesh,triangles,quality,build_ms,save_ms,load_ms,load_in_place_ms,fingerprint_ms,tree_bytes,saved_bytes,fast_build_over_load,fast_build_over_load_in_place\n");
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) { repeat = std::atoi(argv[++i]); continue; }
        if (!std::strcmp(argv[i], "--subdivide") && i + 1 < argc) { subdivide = unsigned(std::atoi(argv[++i])); continue; }
        Mesh mesh;
        if (!read_obj(argv[i], mesh)) { std::fprintf(stderr, "save_load: cannot read %s\n", argv[i]); return 1; }
        mesh = subdivided(mesh, subdivide);
        std::string name = argv[i];
        name = name.substr(name.find_last_of('/') + 1) + (subdivide ? "_SUB" + std::to_string(subdivide) : "");
        const kdrt_triangles view = mesh.view();
        double fast_build = 0;
        for (kdrt_build_quality q : {KDRT_BUILD_QUALITY_FAST, KDRT_BUILD_QUALITY_MEDIUM}) {
            kdrt_build_options o = kdrt_default_build_options();
            o.quality = q;
            kdrt_tree *tree = nullptr;
            const double build = fastest_ms(repeat, [&] {
                kdrt_tree_free(tree);
                if (kdrt_tree_build(&view, &o, &tree, nullptr) != KDRT_SUCCESS) std::abort();
            });
            if (q == KDRT_BUILD_QUALITY_FAST) fast_build = build;
            std::vector<unsigned char> bytes;
            const double save = fastest_ms(repeat, [&] {
                bytes.clear();
                if (kdrt_tree_save(tree, append, &bytes) != KDRT_SUCCESS) std::abort();
            });
            kdrt_tree *loaded = nullptr;
            const double load = fastest_ms(repeat, [&] {
                kdrt_tree_free(loaded);
                if (kdrt_tree_load(bytes.data(), bytes.size(), &view, nullptr, &loaded, nullptr) != KDRT_SUCCESS) std::abort();
            });
            // In place: the bytes in a 64-byte aligned buffer, which the tree then borrows.
            unsigned char *aligned = static_cast<unsigned char *>(std::aligned_alloc(64, (bytes.size() + 63) / 64 * 64));
            std::memcpy(aligned, bytes.data(), bytes.size());
            kdrt_build_options in_place = kdrt_default_build_options();
            in_place.flags = KDRT_LOAD_IN_PLACE;
            kdrt_tree *borrowed = nullptr;
            const double load_in_place = fastest_ms(repeat, [&] {
                kdrt_tree_free(borrowed);
                if (kdrt_tree_load(aligned, bytes.size(), &view, &in_place, &borrowed, nullptr) != KDRT_SUCCESS) std::abort();
            });
            kdrt_tree_free(borrowed);
            std::free(aligned);
            // The fingerprint alone: the load of the tree over a copy of the mesh whose last index
            // differs, which hashes its positions and indices, compares and refuses.
            Mesh other = mesh;
            other.indices.back() = other.indices[0];
            const kdrt_triangles other_view = other.view();
            const double fingerprint = fastest_ms(repeat, [&] {
                kdrt_tree *none = nullptr;
                if (kdrt_tree_load(bytes.data(), bytes.size(), &other_view, nullptr, &none, nullptr) != KDRT_ERROR_MESH_MISMATCH) std::abort();
            });
            kdrt_tree_stats s;
            kdrt_tree_get_stats(tree, &s);
            std::printf("%s,%u,%s,%.2f,%.2f,%.2f,%.2f,%.2f,%zu,%zu,%.1f,%.1f\n", name.c_str(), view.triangle_count,
                        q == KDRT_BUILD_QUALITY_FAST ? "fast" : "medium", build, save, load, load_in_place, fingerprint,
                        s.bytes, bytes.size(), fast_build / load, fast_build / load_in_place);
            std::fflush(stdout);
            kdrt_tree_free(loaded);
            kdrt_tree_free(tree);
        }
    }
    return 0;
}
