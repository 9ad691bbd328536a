#include "scenes.hpp"
#include "common/random.hpp"
#include "common/timing.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <set>
#include <unordered_map>

namespace kb {

namespace {

void mesh_box(const common::Mesh &mesh, double lo[3], double hi[3]) {
    for (int a = 0; a < 3; ++a) lo[a] = 1e300, hi[a] = -1e300;
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], double(mesh.positions[i]));
        hi[i % 3] = std::max(hi[i % 3], double(mesh.positions[i]));
    }
    if (mesh.positions.empty())
        for (int a = 0; a < 3; ++a) lo[a] = hi[a] = 0;
}

// The mesh's vertices merged per cell of a grid of `cells` cubes along its largest side.
common::Mesh cluster(const common::Mesh &mesh, uint32_t cells) {
    double lo[3], hi[3];
    mesh_box(mesh, lo, hi);
    const double side = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30}) / cells;
    std::unordered_map<uint64_t, uint32_t> cell_vertex;
    std::vector<uint32_t> remap(mesh.vertex_count());
    std::vector<double> sums;
    std::vector<uint32_t> counts;
    for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
        uint64_t key = 0;
        for (int a = 0; a < 3; ++a) {
            const double c = std::floor((double(mesh.positions[3 * size_t(v) + a]) - lo[a]) / side);
            key = key << 21 | uint64_t(std::min(std::max(c, 0.0), double(cells - 1)));
        }
        auto found = cell_vertex.emplace(key, uint32_t(counts.size()));
        if (found.second) sums.insert(sums.end(), {0.0, 0.0, 0.0}), counts.push_back(0);
        const uint32_t to = found.first->second;
        for (int a = 0; a < 3; ++a) sums[3 * size_t(to) + a] += mesh.positions[3 * size_t(v) + a];
        ++counts[to];
        remap[v] = to;
    }
    common::Mesh out;
    out.name = mesh.name;
    for (size_t i = 0; i < sums.size(); ++i) out.positions.push_back(float(sums[i] / counts[i / 3]));
    std::set<std::array<uint32_t, 3>> kept;
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
        const std::array<uint32_t, 3> c = {remap[mesh.vertex(t, 0)], remap[mesh.vertex(t, 1)], remap[mesh.vertex(t, 2)]};
        if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
        std::array<uint32_t, 3> sorted = c;
        std::sort(sorted.begin(), sorted.end());
        if (!kept.insert(sorted).second) continue;
        out.indices.insert(out.indices.end(), c.begin(), c.end());
    }
    return out;
}

// Appends `mesh` to `world`, each vertex p going to float(m p + t) (m row-major 3x3), computed in
// double.
void append_placed(common::Mesh &world, const common::Mesh &mesh, const double m[9], const double t[3]) {
    const uint32_t base = world.vertex_count();
    for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
        const float *p = &mesh.positions[3 * size_t(v)];
        for (int i = 0; i < 3; ++i)
            world.positions.push_back(float(m[3 * i] * p[0] + m[3 * i + 1] * p[1] + m[3 * i + 2] * p[2] + t[i]));
    }
    for (uint32_t tri = 0; tri < mesh.triangle_count(); ++tri)
        for (int k = 0; k < 3; ++k) world.indices.push_back(base + mesh.vertex(tri, k));
}

// The geometry IDs of a layout whose meshes are runs of frame.geometry: the first triangle of
// each, then the wall's (make_scene appends it to the world).
void finish_layout(SceneLayout &layout, const common::Mesh &world, const std::string &name) {
    layout.name = name;
    std::string upper = name;
    for (char &c : upper) c = char(std::toupper(static_cast<unsigned char>(c)));
    layout.frame = make_scene(world, upper);
    layout.first.push_back(world.triangle_count());
}

}  // namespace

common::Mesh unit_sized(const common::Mesh &mesh) {
    double lo[3], hi[3];
    mesh_box(mesh, lo, hi);
    const double scale = 1.0 / std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30});
    common::Mesh out = mesh;
    for (size_t i = 0; i < out.positions.size(); ++i)
        out.positions[i] = float((double(mesh.positions[i]) - 0.5 * (lo[i % 3] + hi[i % 3])) * scale);
    return out;
}

common::Mesh clustered(const common::Mesh &mesh, uint32_t target) {
    if (target == 0 || mesh.triangle_count() <= target) return mesh;
    // The finest grid within the target (the count grows with the grid, if not strictly).
    uint32_t coarse = 1, fine = 1u << 16;
    while (coarse < fine) {
        const uint32_t mid = coarse + (fine - coarse + 1) / 2;
        if (cluster(mesh, mid).triangle_count() <= target) coarse = mid;
        else fine = mid - 1;
    }
    return cluster(mesh, coarse);
}

SceneLayout merged_layout(const std::vector<common::Mesh> &meshes) {
    SceneLayout layout;
    common::Mesh world;
    const uint32_t n = uint32_t(meshes.size());
    const uint32_t columns = std::max(1u, uint32_t(std::ceil(std::sqrt(double(n)) - 1e-9)));
    const double pitch = 1.1;  // unit-sized meshes, 0.1 apart
    const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t row = i / columns, rows = (n + columns - 1) / columns;
        const uint32_t in_row = std::min(columns, n - row * columns);  // the last row may be short
        const double at[3] = {pitch * (double(i % columns) - 0.5 * (in_row - 1)), pitch * (0.5 * (rows - 1) - row), 0};
        layout.first.push_back(world.triangle_count());
        append_placed(world, unit_sized(meshes[i]), identity, at);
    }
    finish_layout(layout, world, "merged");
    return layout;
}

SceneLayout field_layout(const std::vector<common::Mesh> &meshes, uint32_t count, uint32_t seed, double spacing) {
    SceneLayout layout;
    layout.prototypes = meshes;
    common::Mesh world;
    common::Rng rng(seed);
    const uint32_t columns = std::max(1u, uint32_t(std::ceil(std::sqrt(double(count)) - 1e-9)));
    const uint32_t rows = (count + columns - 1) / columns;
    std::vector<std::array<double, 12>> placed(count);  // world from object, [m | t] row-major
    for (uint32_t i = 0; i < count && !meshes.empty(); ++i) {
        // A uniformly random rotation (Shoemake's unit quaternion from three uniforms).
        const double u1 = rng.uniform(), u2 = 2 * M_PI * rng.uniform(), u3 = 2 * M_PI * rng.uniform();
        const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
        const double x = a * std::sin(u2), y = a * std::cos(u2), z = b * std::sin(u3), w = b * std::cos(u3);
        const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
                             2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                             2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
        const double scale = rng.range(0.8, 1.2);
        const double t[3] = {spacing * (double(i % columns) - 0.5 * (columns - 1)) + rng.range(-0.15, 0.15),
                             spacing * (0.5 * (rows - 1) - double(i / columns)) + rng.range(-0.15, 0.15),
                             rng.range(-0.5, 0.5)};
        double m[9];
        for (int k = 0; k < 9; ++k) m[k] = scale * r[k];
        for (int row = 0; row < 3; ++row) {
            for (int col = 0; col < 3; ++col) placed[i][4 * row + col] = m[3 * row + col];
            placed[i][4 * row + 3] = t[row];
        }
        SceneLayout::Placement p;
        p.prototype = uint32_t(i % meshes.size());
        layout.instances.push_back(p);
        layout.first.push_back(world.triangle_count());
        append_placed(world, meshes[p.prototype], m, t);
    }
    finish_layout(layout, world, "field");
    // The instances' transforms in the frame: make_scene moved the world by p -> (p - centre) * scale.
    const Scene &f = layout.frame;
    for (uint32_t i = 0; i < layout.instances.size(); ++i)
        for (int row = 0; row < 3; ++row) {
            for (int col = 0; col < 3; ++col)
                layout.instances[i].transform[4 * row + col] = float(f.scale * placed[i][4 * row + col]);
            layout.instances[i].transform[4 * row + 3] = float(f.scale * (placed[i][4 * row + 3] - f.centre[row]));
        }
    return layout;
}

kdrt_triangles geometry_view(const SceneLayout &layout, uint32_t id) {
    kdrt_triangles view = layout.frame.geometry.view();
    const uint32_t end = id + 1 < layout.first.size() ? layout.first[id + 1] : view.triangle_count;
    view.indices += 3 * size_t(layout.first[id]);
    view.triangle_count = end - layout.first[id];
    return view;
}

std::vector<kdrt_geometry> kdrt_geometries(const SceneLayout &layout, const std::vector<kdrt_tree *> &trees) {
    std::vector<kdrt_geometry> geometries;
    for (uint32_t id = 0; id < layout.first.size(); ++id) {
        if (id < layout.instances.size()) {
            const SceneLayout::Placement &p = layout.instances[id];
            geometries.push_back(kdrt_instance_geometry(id, trees[p.prototype], p.transform));
        } else {
            const kdrt_triangles view = geometry_view(layout, id);
            geometries.push_back(kdrt_mesh_geometry(id, &view));
        }
    }
    return geometries;
}

uint64_t stored_triangles(const SceneLayout &layout) {
    uint64_t n = layout.frame.geometry.triangle_count();
    if (layout.instances.empty()) return n;
    n -= layout.first[layout.instances.size()];  // the meshes after the instances: the wall
    for (const common::Mesh &m : layout.prototypes) n += m.triangle_count();
    return n;
}

uint32_t flat_triangle(const kdrt_hit &hit, const std::vector<uint32_t> &first) {
    if (hit.triangle == KDRT_INVALID_ID || hit.geometry >= first.size()) return KDRT_INVALID_ID;
    return first[hit.geometry] + hit.triangle;
}

size_t count_scene_mismatches(const std::vector<kdrt_hit> &a, const std::vector<uint32_t> &a_first,
                              const std::vector<kdrt_hit> &b, const std::vector<uint32_t> &b_first, double tolerance) {
    size_t wrong = 0;
    for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
        const uint32_t ta = flat_triangle(a[i], a_first), tb = flat_triangle(b[i], b_first);
        if (ta == KDRT_INVALID_ID || tb == KDRT_INVALID_ID) {
            wrong += ta != tb;
        } else if (tolerance == 0) {
            wrong += ta != tb || std::memcmp(&a[i].t, &b[i].t, sizeof(float)) != 0 ||
                     std::memcmp(&a[i].u, &b[i].u, sizeof(float)) != 0 || std::memcmp(&a[i].v, &b[i].v, sizeof(float)) != 0;
        } else if (ta != tb) {
            const double t0 = a[i].t, t1 = b[i].t;
            wrong += !(std::fabs(t0 - t1) <= tolerance * std::max(std::fabs(t0), std::fabs(t1)));
        }
    }
    return wrong + (a.size() > b.size() ? a.size() - b.size() : b.size() - a.size());
}

double median(std::vector<double> values) {
    if (values.empty()) return 0;
    std::sort(values.begin(), values.end());
    const size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double median_commit_ms(kdrt_scene *scene, const SceneLayout &layout, unsigned times, std::string &error) {
    std::vector<double> ms;
    for (unsigned k = 0; k <= times; ++k) {
        const bool last = k == times;  // untimed: back where it began, if the last timed move left it
        if (last && times % 2 == 0) break;
        for (uint32_t id = 0; id < layout.instances.size(); ++id) {
            float moved[12];
            std::memcpy(moved, layout.instances[id].transform, sizeof moved);
            if (k % 2 == 0) moved[3] += 0.01f;
            const kdrt_result r = kdrt_scene_set_transform(scene, id, moved);
            if (r != KDRT_SUCCESS) {
                error = "kdrt_scene_set_transform(" + std::to_string(id) + "): " + kdrt_result_string(r);
                return -1;
            }
        }
        common::Stopwatch clock;
        const kdrt_result r = kdrt_scene_commit(scene);
        if (!last) ms.push_back(clock.ms());
        if (r != KDRT_SUCCESS) {
            error = std::string("kdrt_scene_commit: ") + kdrt_result_string(r);
            return -1;
        }
    }
    return median(ms);
}

std::string scene_csv_header() {
    return "Scene;Layout;Query;Rays;RayCount;Triangles;StoredTriangles;Instances;BuildMs;TraceMs;MRaysPerSec;Versus;"
           "VersusRatio;Mismatches;EmbreeBuildMs;EmbreeMRaysPerSec;EmbreeRatio;EmbreeMismatches";
}

std::string scene_csv_row(const SceneRow &row) {
    const auto mrays = [&](double ms) { return ms > 0 ? double(row.ray_count) / (ms * 1000.0) : 0.0; };
    char buf[512];
    int n = std::snprintf(buf, sizeof buf, "%s;%s;%s;%s;%zu;%llu;%llu;%u;%.3f;%.3f;%.3f;", row.scene.c_str(),
                          row.layout.c_str(), row.query.c_str(), row.rays.c_str(), row.ray_count,
                          (unsigned long long)row.triangles, (unsigned long long)row.stored_triangles, row.instances,
                          row.build_ms, row.trace_ms, mrays(row.trace_ms));
    std::string line(buf, size_t(n));
    if (!row.versus.empty()) {
        const double ratio = row.trace_ms > 0 ? row.versus_trace_ms / row.trace_ms : 0.0;  // speed over speed
        n = std::snprintf(buf, sizeof buf, "%s;%.3f;%zu;", row.versus.c_str(), ratio, row.mismatches);
        line.append(buf, size_t(n));
    } else {
        line += ";;;";
    }
    if (row.embree) {
        const double ratio = row.trace_ms > 0 ? row.embree_trace_ms / row.trace_ms : 0.0;
        n = std::snprintf(buf, sizeof buf, "%.3f;%.3f;%.3f;%zu", row.embree_build_ms, mrays(row.embree_trace_ms), ratio,
                          row.embree_mismatches);
        line.append(buf, size_t(n));
    } else {
        line += ";;;";
    }
    return line;
}

}  // namespace kb
