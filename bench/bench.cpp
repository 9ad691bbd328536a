#include "bench.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numeric>

namespace kb {

namespace {

// Same splitmix64 stream on every platform, so ray sets and samples are reproducible.
struct Rng {
    uint64_t state;
    explicit Rng(uint32_t seed) : state(0x243F6A8885A308D3ull ^ (uint64_t(seed) * 0x9E3779B97F4A7C15ull)) {}
    uint64_t next() {
        uint64_t z = (state += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
};

bool parse_unsigned(const std::string &text, unsigned long long max, unsigned long long &out) {
    if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0]))) return false;
    char *end = nullptr;
    errno = 0;
    unsigned long long v = std::strtoull(text.c_str(), &end, 10);
    if (errno != 0 || *end != '\0' || v > max) return false;
    out = v;
    return true;
}

}  // namespace

std::vector<uint32_t> default_leaf_sizes() {
    return {0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024};
}

std::vector<uint32_t> leaf_sizes_for(const std::vector<uint32_t> &sizes, uint32_t mesh_triangles) {
    std::vector<uint32_t> kept;
    for (uint32_t size : sizes) {
        kept.push_back(size);
        if (size >= mesh_triangles) break;
    }
    return kept;
}

std::string usage() {
    return "usage: kdrt-bench [options] [MESH_OR_FOLDER ...]\n"
           "\n"
           "Builds a kd-tree over each mesh for each max leaf size and traces the benchmark frame:\n"
           "the mesh scaled to fill the view in front of a back wall, one primary ray per pixel,\n"
           "closest hit. Writes Mesh;MaxLeafSize;ElapsedMs;... as CSV, one row per repetition.\n"
           "Meshes: OFF, OBJ, PLY, STL, glTF files, or folders of them. Default: the original's\n"
           "meshes in ../shared/meshes/seed when present, else generated ones.\n"
           "\n"
           "  --size WxH          frame size (default 800x800)\n"
           "  --threads N         tracing threads (default 1)\n"
           "  --repeat N          rows per mesh and leaf size (default 1)\n"
           "  --leaf-sizes LIST   comma-separated max leaf sizes, 0 = no tree\n"
           "                      (default 0,1,2,3,4,6,8,12,...,768,1024; each mesh stops after the\n"
           "                      first size at or above its triangle count)\n"
           "  --builder NAME      median (the SAH builder is not available yet)\n"
           "  --rays KIND         primary | diffuse (cosine bounces from the primary hits) |\n"
           "                      random (uniform rays through the scene box)\n"
           "  --reference-rays N  rays per frame checked against the double-precision brute-force\n"
           "                      reference (default 20000, seeded; 0: every ray)\n"
           "  --subdivide K       K levels of 4-to-1 subdivision of every mesh first\n"
           "  --compare embree    also trace the same rays through Embree 3 (one thread)\n"
           "  -o FILE             write the CSV to FILE (default: standard output)\n"
           "  --help              this text\n";
}

bool parse_options(int argc, const char *const *argv, Options &out, std::string &error) {
    out = Options();
    out.leaf_sizes = default_leaf_sizes();
    for (int i = 1; i < argc; ++i) {
        std::string arg = argv[i];
        auto value = [&](std::string &v) {
            if (i + 1 >= argc) {
                error = arg + " needs a value";
                return false;
            }
            v = argv[++i];
            return true;
        };
        std::string v;
        unsigned long long n = 0;
        if (arg == "--help" || arg == "-h") {
            out.help = true;
        } else if (arg == "--size") {
            if (!value(v)) return false;
            size_t x = v.find('x');
            unsigned long long w = 0, h = 0;
            if (x == std::string::npos || !parse_unsigned(v.substr(0, x), 32768, w) ||
                !parse_unsigned(v.substr(x + 1), 32768, h) || w == 0 || h == 0) {
                error = "--size wants WxH with 1 <= W, H <= 32768, got '" + v + "'";
                return false;
            }
            out.width = unsigned(w), out.height = unsigned(h);
        } else if (arg == "--threads" || arg == "--repeat" || arg == "--subdivide") {
            if (!value(v)) return false;
            unsigned long long max = arg == "--subdivide" ? 8 : 1024;
            if (!parse_unsigned(v, max, n) || (arg != "--subdivide" && n == 0)) {
                error = arg + " wants a whole number " + (arg == "--subdivide" ? "from 0" : "from 1") + " to " +
                        std::to_string(max) + ", got '" + v + "'";
                return false;
            }
            (arg == "--threads" ? out.threads : arg == "--repeat" ? out.repeat : out.subdivide) = unsigned(n);
        } else if (arg == "--reference-rays") {
            if (!value(v)) return false;
            if (!parse_unsigned(v, 1ull << 40, n)) {
                error = "--reference-rays wants a whole number, got '" + v + "'";
                return false;
            }
            out.reference_rays = size_t(n);
        } else if (arg == "--leaf-sizes") {
            if (!value(v)) return false;
            out.leaf_sizes.clear();
            size_t start = 0;
            while (start <= v.size()) {
                size_t comma = v.find(',', start);
                std::string item = v.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
                if (!parse_unsigned(item, KDRT_MAX_TRIANGLES, n)) {
                    error = "--leaf-sizes wants whole numbers separated by commas, got '" + v + "'";
                    return false;
                }
                out.leaf_sizes.push_back(uint32_t(n));
                if (comma == std::string::npos) break;
                start = comma + 1;
            }
        } else if (arg == "--builder") {
            if (!value(v)) return false;
            if (v != "median") {
                error = v == "sah" ? "--builder sah: the SAH builder is not available yet; use median"
                                   : "--builder wants median, got '" + v + "'";
                return false;
            }
            out.builder = v;
        } else if (arg == "--rays") {
            if (!value(v)) return false;
            if (v == "primary") out.rays = RayKind::primary;
            else if (v == "diffuse") out.rays = RayKind::diffuse;
            else if (v == "random") out.rays = RayKind::random;
            else {
                error = "--rays wants primary, diffuse or random, got '" + v + "'";
                return false;
            }
        } else if (arg == "--compare") {
            if (!value(v)) return false;
            if (v != "embree") {
                error = "--compare wants embree, got '" + v + "'";
                return false;
            }
            out.compare_embree = true;
        } else if (arg == "-o" || arg == "--output") {
            if (!value(out.output)) return false;
            if (out.output.empty()) {
                error = "-o wants a file name";
                return false;
            }
        } else if (!arg.empty() && arg[0] == '-') {
            error = "unknown option '" + arg + "' (see --help)";
            return false;
        } else {
            out.inputs.push_back(arg);
        }
    }
    return true;
}

Scene make_scene(const kt::Mesh &mesh, const std::string &name) {
    Scene s;
    s.name = name;
    s.mesh_triangles = mesh.triangle_count();
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (size_t i = 0; i < mesh.positions.size(); ++i) lo[i % 3] = std::min(lo[i % 3], double(mesh.positions[i])), hi[i % 3] = std::max(hi[i % 3], double(mesh.positions[i]));
    if (mesh.positions.empty()) lo[0] = lo[1] = lo[2] = hi[0] = hi[1] = hi[2] = 0;
    double centre[3], across = std::max({hi[0] - lo[0], hi[1] - lo[1], 1e-30});
    for (int a = 0; a < 3; ++a) centre[a] = 0.5 * (lo[a] + hi[a]);
    double scale = 2.0 / across, half_depth = 0.5 * (hi[2] - lo[2]) * scale;

    s.geometry = mesh;
    s.geometry.name = name;
    if (s.geometry.indices.empty())
        for (uint32_t i = 0; i < mesh.vertex_count(); ++i) s.geometry.indices.push_back(i);
    for (size_t i = 0; i < s.geometry.positions.size(); ++i)
        s.geometry.positions[i] = float((s.geometry.positions[i] - centre[i % 3]) * scale);

    // Camera 3 units in front of the mesh's front face, its view holding [-1.05, 1.05] at z = 0.
    double eye_z = half_depth + 3.0, tan_half = 1.05 / eye_z;
    s.eye[2] = float(eye_z);
    s.tan_half_fov = float(tan_half);
    // The wall: behind the mesh, a little larger than the view at its depth.
    double wall_z = -half_depth - 0.25, wall_half = 1.2 * tan_half * (eye_z - wall_z);
    uint32_t base = s.geometry.vertex_count();
    const double corner[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (const auto &c : corner)
        s.geometry.positions.insert(s.geometry.positions.end(), {float(c[0] * wall_half), float(c[1] * wall_half), float(wall_z)});
    s.geometry.indices.insert(s.geometry.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    return s;
}

std::vector<kdrt_ray> make_rays(const Scene &scene, RayKind kind, unsigned width, unsigned height,
                                const kdrt_tree *tree, uint32_t seed) {
    std::vector<kdrt_ray> rays;
    if (kind == RayKind::random) {
        // Uniform rays through the scene's box: from a point on its bounding sphere to a point inside.
        kdrt_aabb box = kdrt_tree_bounds(tree);
        double c[3], e[3], radius = 0;
        for (int a = 0; a < 3; ++a) c[a] = 0.5 * (box.min[a] + box.max[a]), e[a] = box.max[a] - box.min[a], radius += 0.25 * e[a] * e[a];
        radius = std::sqrt(radius);
        Rng rng(seed);
        rays.resize(size_t(width) * height);
        for (kdrt_ray &r : rays) {
            double z = 2 * rng.uniform() - 1, phi = 2 * M_PI * rng.uniform(), s = std::sqrt(std::max(0.0, 1 - z * z));
            double u[3] = {s * std::cos(phi), s * std::sin(phi), z};
            for (int a = 0; a < 3; ++a) {
                r.org[a] = float(c[a] + u[a] * radius);
                r.dir[a] = float(c[a] + (rng.uniform() - 0.5) * e[a] - r.org[a]);
            }
            r.tmin = 0, r.tmax = INFINITY;
        }
        return rays;
    }

    rays.reserve(size_t(width) * height);
    double aspect = double(width) / height;
    for (unsigned y = 0; y < height; ++y)
        for (unsigned x = 0; x < width; ++x) {
            kdrt_ray r;
            for (int a = 0; a < 3; ++a) r.org[a] = scene.eye[a];
            r.dir[0] = float((2.0 * (x + 0.5) / width - 1.0) * scene.tan_half_fov * aspect);
            r.dir[1] = float((1.0 - 2.0 * (y + 0.5) / height) * scene.tan_half_fov);
            r.dir[2] = -1.0f;
            r.tmin = 0, r.tmax = INFINITY;
            rays.push_back(r);
        }
    if (kind == RayKind::primary) return rays;

    // Diffuse: a cosine-distributed bounce from every primary hit, on the side the ray came from,
    // leaving the surface through kdrt_spawn_ray() (no epsilon: the offset scales with the point).
    std::vector<kdrt_ray> bounces;
    Rng rng(seed);
    for (const kdrt_ray &r : rays) {
        kdrt_hit h;
        float normal[3];
        if (!kdrt_intersect(tree, &r, &h) || !kdrt_hit_surface(tree, &h, nullptr, normal)) continue;
        double n[3] = {normal[0], normal[1], normal[2]};
        double facing = n[0] * r.dir[0] + n[1] * r.dir[1] + n[2] * r.dir[2] > 0 ? -1 : 1;
        for (double &c : n) c *= facing;
        // Orthonormal frame around n (Duff et al. 2017), then a cosine-weighted direction.
        double sign = std::copysign(1.0, n[2]), a0 = -1.0 / (sign + n[2]), b0 = n[0] * n[1] * a0;
        double t1[3] = {1 + sign * n[0] * n[0] * a0, sign * b0, -sign * n[0]}, t2[3] = {b0, sign + n[1] * n[1] * a0, -n[1]};
        double r1 = rng.uniform(), r2 = rng.uniform(), radial = std::sqrt(r1), phi = 2 * M_PI * r2, up = std::sqrt(1 - r1);
        float dir[3];
        for (int a = 0; a < 3; ++a) dir[a] = float(radial * std::cos(phi) * t1[a] + radial * std::sin(phi) * t2[a] + up * n[a]);
        kdrt_ray b;
        if (kdrt_spawn_ray(tree, &h, dir, &b)) bounces.push_back(b);
    }
    return bounces;
}

std::vector<size_t> reference_sample(size_t total, size_t count, uint32_t seed) {
    std::vector<size_t> all(total);
    std::iota(all.begin(), all.end(), size_t(0));
    if (count == 0 || count >= total) return all;
    Rng rng(seed);
    for (size_t i = 0; i < count; ++i) std::swap(all[i], all[i + size_t(rng.uniform() * double(total - i))]);  // partial Fisher-Yates
    all.resize(count);
    std::sort(all.begin(), all.end());
    return all;
}

size_t count_mismatches(const kt::Oracle &oracle, const std::vector<kt::Reference> &refs,
                        const std::vector<size_t> &sample, const std::vector<kdrt_ray> &rays,
                        const std::vector<kdrt_hit> &hits) {
    kt::Agreement tally;
    for (size_t k = 0; k < sample.size(); ++k) kt::check_hit(oracle, refs[k], rays[sample[k]], hits[sample[k]], tally);
    return tally.wrong;
}

std::string csv_header() {
    return "Mesh;MaxLeafSize;ElapsedMs;Builder;Triangles;BuildMs;TraceMs;MRaysPerSec;Nodes;Leaves;MaxDepth;"
           "AvgLeafTriangles;TreeBytes;Mismatches;ReferenceRays";
}

std::string csv_row(const Row &row) {
    char buf[512];
    double mrays = row.trace_ms > 0 ? double(row.rays) / (row.trace_ms * 1000.0) : 0.0;
    int n = std::snprintf(buf, sizeof buf, "%s;%d;%lld;%s;%u;%.3f;%.3f;%.3f;", row.mesh.c_str(), row.max_leaf_size,
                          (long long)std::llround(row.trace_ms), row.builder.c_str(), row.triangles, row.build_ms,
                          row.trace_ms, mrays);
    std::string line(buf, size_t(n));
    if (row.has_tree_stats) {
        const kdrt_tree_stats &s = row.stats;
        double avg = s.leaves ? double(s.triangle_refs) / s.leaves : 0.0;
        n = std::snprintf(buf, sizeof buf, "%u;%u;%u;%.2f;%zu;", s.nodes, s.leaves, s.max_depth, avg, s.bytes);
        line.append(buf, size_t(n));
    } else {
        line += ";;;;;";  // Embree's BVH: no kd-tree statistics
    }
    n = std::snprintf(buf, sizeof buf, "%zu;%zu", row.mismatches, row.reference_rays);
    line.append(buf, size_t(n));
    return line;
}

}  // namespace kb
