#include "test_support.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <sstream>
#include <thread>

namespace kt {

namespace {

// Small, portable generator (the same numbers on every standard library).
struct Rng {
    uint64_t state;
    explicit Rng(uint32_t seed) : state(0x9E3779B97F4A7C15ull ^ (uint64_t(seed) * 0xD1B54A32D192ED03ull)) {}
    uint64_t next() {
        state += 0x9E3779B97F4A7C15ull;  // splitmix64
        uint64_t z = state;
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
    double range(double lo, double hi) { return lo + (hi - lo) * uniform(); }
};

void unit_direction(Rng &rng, double d[3]) {
    double z = rng.range(-1, 1), phi = rng.range(0, 2 * M_PI), r = std::sqrt(std::max(0.0, 1 - z * z));
    d[0] = r * std::cos(phi), d[1] = r * std::sin(phi), d[2] = z;
}

template <typename F>
void parallel_for(size_t count, F &&body) {
    unsigned threads = std::max(1u, std::thread::hardware_concurrency());
    std::vector<std::thread> pool;
    for (unsigned w = 0; w < threads; ++w)
        pool.emplace_back([&, w] {
            for (size_t i = w; i < count; i += threads) body(i);
        });
    for (auto &t : pool) t.join();
}

}  // namespace

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

Mesh random_soup(uint32_t triangles, uint32_t seed) {
    Rng rng(seed);
    Mesh m;
    m.name = "random_soup_" + std::to_string(triangles);
    for (uint32_t i = 0; i < triangles; ++i) {
        double c[3] = {rng.range(0, 10), rng.range(0, 10), rng.range(0, 10)};
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) m.positions.push_back(float(c[a] + rng.range(-0.5, 0.5)));
    }
    return m;
}

Mesh grid(uint32_t nx, uint32_t ny, uint32_t seed) {
    Rng rng(seed);
    Mesh m;
    m.name = "grid_" + std::to_string(nx) + "x" + std::to_string(ny);
    for (uint32_t y = 0; y <= ny; ++y)
        for (uint32_t x = 0; x <= nx; ++x) {
            m.positions.push_back(float(x));
            m.positions.push_back(float(y));
            m.positions.push_back(float(std::floor(rng.range(0, 4))));  // integer heights: many coplanar cells
        }
    for (uint32_t y = 0; y < ny; ++y)
        for (uint32_t x = 0; x < nx; ++x) {
            uint32_t a = y * (nx + 1) + x, b = a + 1, c = a + nx + 1, d = c + 1;
            m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
        }
    return m;
}

Mesh sphere(uint32_t rings, uint32_t segments, double radius) {
    Mesh m;
    m.name = "sphere_" + std::to_string(rings) + "x" + std::to_string(segments);
    // Poles are single vertices so the surface is closed: every edge is shared by two triangles.
    m.positions.insert(m.positions.end(), {0.0f, 0.0f, float(radius)});
    for (uint32_t r = 1; r < rings; ++r) {
        double theta = M_PI * r / rings;
        for (uint32_t s = 0; s < segments; ++s) {
            double phi = 2 * M_PI * s / segments;
            m.positions.push_back(float(radius * std::sin(theta) * std::cos(phi)));
            m.positions.push_back(float(radius * std::sin(theta) * std::sin(phi)));
            m.positions.push_back(float(radius * std::cos(theta)));
        }
    }
    m.positions.insert(m.positions.end(), {0.0f, 0.0f, float(-radius)});
    uint32_t south = m.vertex_count() - 1;
    auto ring_vertex = [&](uint32_t r, uint32_t s) { return 1 + (r - 1) * segments + s % segments; };
    for (uint32_t s = 0; s < segments; ++s) {
        m.indices.insert(m.indices.end(), {0, ring_vertex(1, s), ring_vertex(1, s + 1)});
        m.indices.insert(m.indices.end(), {south, ring_vertex(rings - 1, s + 1), ring_vertex(rings - 1, s)});
    }
    for (uint32_t r = 1; r + 1 < rings; ++r)
        for (uint32_t s = 0; s < segments; ++s) {
            uint32_t a = ring_vertex(r, s), b = ring_vertex(r, s + 1), c = ring_vertex(r + 1, s), d = ring_vertex(r + 1, s + 1);
            m.indices.insert(m.indices.end(), {a, c, d, a, d, b});
        }
    return m;
}

Mesh translated(const Mesh &mesh, double dx, double dy, double dz) {
    Mesh m = mesh;
    m.name += "_moved";
    for (size_t i = 0; i < m.positions.size(); i += 3) {
        m.positions[i] = float(m.positions[i] + dx);
        m.positions[i + 1] = float(m.positions[i + 1] + dy);
        m.positions[i + 2] = float(m.positions[i + 2] + dz);
    }
    return m;
}

Mesh as_soup(const Mesh &indexed) {
    Mesh m;
    m.name = indexed.name + "_soup";
    for (uint32_t t = 0; t < indexed.triangle_count(); ++t) {
        double p[3][3];
        indexed.corners(t, p);
        for (auto &corner : p)
            for (double c : corner) m.positions.push_back(float(c));
    }
    return m;
}

bool load_mesh(const std::string &path, Mesh &out, std::string &error) {
    Assimp::Importer importer;
    const aiScene *scene = importer.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                                       aiProcess_PreTransformVertices | aiProcess_SortByPType);
    if (!scene) {
        error = importer.GetErrorString();
        return false;
    }
    out = Mesh();
    out.name = std::filesystem::path(path).stem().string();
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
        const aiMesh *mesh = scene->mMeshes[mi];
        uint32_t base = out.vertex_count();
        for (unsigned v = 0; v < mesh->mNumVertices; ++v)
            out.positions.insert(out.positions.end(), {mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z});
        for (unsigned f = 0; f < mesh->mNumFaces; ++f)
            if (mesh->mFaces[f].mNumIndices == 3)  // points and lines are not surfaces
                for (int k = 0; k < 3; ++k) out.indices.push_back(base + mesh->mFaces[f].mIndices[k]);
    }
    if (out.indices.empty()) {
        error = "no triangles";
        return false;
    }
    return true;
}

std::string shared_mesh_dir() {
    std::error_code ec;
    return std::filesystem::is_directory(KDRT_MESH_DIR, ec) ? std::string(KDRT_MESH_DIR) : std::string();
}

std::vector<std::string> shared_mesh_files() {
    std::vector<std::string> files;
    std::string dir = shared_mesh_dir();
    if (dir.empty()) return files;
    for (const char *sub : {"seed", "common"}) {
        std::error_code ec;
        for (const auto &entry : std::filesystem::directory_iterator(dir + "/" + sub, ec)) {
            std::string ext = entry.path().extension().string();
            if (ext == ".off" || ext == ".obj" || ext == ".ply" || ext == ".stl") files.push_back(entry.path().string());
        }
    }
    std::sort(files.begin(), files.end());
    return files;
}

std::vector<kdrt_ray> random_rays(const kdrt_aabb &box, size_t count, uint32_t seed) {
    Rng rng(seed);
    double c[3], ext[3], diag = 0;
    for (int a = 0; a < 3; ++a) {
        c[a] = 0.5 * (double(box.min[a]) + box.max[a]);
        ext[a] = double(box.max[a]) - box.min[a];
        diag += ext[a] * ext[a];
    }
    diag = std::max(std::sqrt(diag), 1e-3);
    std::vector<kdrt_ray> rays(count);
    for (size_t i = 0; i < count; ++i) {
        kdrt_ray &r = rays[i];
        double o[3], d[3];
        if (i % 2 == 0) {
            for (int a = 0; a < 3; ++a) o[a] = c[a] + rng.range(-0.55, 0.55) * ext[a];
            unit_direction(rng, d);
        } else {
            double u[3];
            unit_direction(rng, u);
            for (int a = 0; a < 3; ++a) {
                o[a] = c[a] + u[a] * diag;
                double target = c[a] + rng.range(-0.5, 0.5) * ext[a];
                d[a] = target - o[a];
            }
        }
        for (int a = 0; a < 3; ++a) r.org[a] = float(o[a]), r.dir[a] = float(d[a]);
        double dlen = std::sqrt(double(r.dir[0]) * r.dir[0] + double(r.dir[1]) * r.dir[1] + double(r.dir[2]) * r.dir[2]);
        r.tmin = 0.0f;
        r.tmax = std::numeric_limits<float>::infinity();
        if (i % 8 == 3) r.tmax = float(rng.range(0, 1.5) * diag / dlen);  // range ends inside the scene
        if (i % 8 == 5) r.tmin = float(rng.range(0, 0.7) * diag / dlen);  // range starts inside the scene
    }
    return rays;
}

Oracle::Oracle(const Mesh &mesh) {
    uint32_t n = mesh.triangle_count();
    tri_.resize(size_t(n) * 9);
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (uint32_t t = 0; t < n; ++t) {
        double p[3][3];
        mesh.corners(t, p);
        for (int a = 0; a < 3; ++a) {
            tri_[size_t(t) * 9 + a] = p[0][a];
            tri_[size_t(t) * 9 + 3 + a] = p[1][a] - p[0][a];
            tri_[size_t(t) * 9 + 6 + a] = p[2][a] - p[0][a];
            for (auto &corner : p) lo[a] = std::min(lo[a], corner[a]), hi[a] = std::max(hi[a], corner[a]);
        }
    }
    scene_size_ = n ? std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-6}) : 1.0;
}

double Oracle::t_tolerance(const kdrt_ray &ray, double t) const {
    double dlen = std::sqrt(double(ray.dir[0]) * ray.dir[0] + double(ray.dir[1]) * ray.dir[1] + double(ray.dir[2]) * ray.dir[2]);
    double reach = std::sqrt(double(ray.org[0]) * ray.org[0] + double(ray.org[1]) * ray.org[1] + double(ray.org[2]) * ray.org[2]);
    // Float coordinates carry an error relative to their magnitude, so far-from-origin scenes
    // get a tolerance that grows with the distance from the origin as well.
    return kRelativeT * (std::fabs(t) + (scene_size_ + reach) / dlen);
}

namespace {
// Double-precision Moeller-Trumbore; returns false when the ray is parallel to the plane.
bool plane_hit(const double *tri, const kdrt_ray &ray, double &t, double &b0, double &b1, double &b2, double &cosine) {
    const double *p0 = tri, *e1 = tri + 3, *e2 = tri + 6;
    double d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0) return false;
    double tv[3] = {ray.org[0] - p0[0], ray.org[1] - p0[1], ray.org[2] - p0[2]};
    double qv[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2], tv[0] * e1[1] - tv[1] * e1[0]};
    b1 = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
    b2 = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
    b0 = 1 - b1 - b2;
    t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double nlen = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), dlen = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    cosine = std::fabs(det) / (nlen * dlen);
    return std::isfinite(t);
}
}  // namespace

Reference Oracle::trace(const kdrt_ray &ray) const {
    Reference ref;
    double tmin = std::max(0.0, double(ray.tmin)), tmax = ray.tmax;
    size_t n = tri_.size() / 9;
    for (size_t i = 0; i < n; ++i) {
        double t, b0, b1, b2, cosine;
        if (!plane_hit(&tri_[i * 9], ray, t, b0, b1, b2, cosine)) continue;
        double tol = t_tolerance(ray, t);
        // Sure: clear of the edges, of the range ends, and not grazing (where the float test's
        // barycentrics lose their accuracy).
        if (b0 < kEdgeMargin || b1 < kEdgeMargin || b2 < kEdgeMargin || cosine < 1e-3) continue;
        if (t < tmin + tol || t > tmax - tol) continue;
        if (!ref.sure_hit || t < ref.sure_t) ref.sure_hit = true, ref.sure_t = t, ref.sure_triangle = uint32_t(i);
    }
    return ref;
}

double Oracle::possible_t(const kdrt_ray &ray, uint32_t triangle) const {
    if (size_t(triangle) * 9 >= tri_.size()) return -1;
    double t, b0, b1, b2, cosine;
    if (!plane_hit(&tri_[size_t(triangle) * 9], ray, t, b0, b1, b2, cosine)) return -1;
    double tol = t_tolerance(ray, t);
    if (b0 < -kEdgeMargin || b1 < -kEdgeMargin || b2 < -kEdgeMargin) return -1;
    if (t < std::max(0.0, double(ray.tmin)) - tol || t > double(ray.tmax) + tol) return -1;
    return t;
}

void check_hit(const Oracle &oracle, const Reference &ref, const kdrt_ray &ray, const kdrt_hit &h, Agreement &tally) {
    bool hit = h.triangle != KDRT_INVALID_ID;
    std::ostringstream why;
    ++tally.rays;
    if (!hit) {
        if (ref.sure_hit) why << "kdrt missed, reference hits triangle " << ref.sure_triangle << " at t=" << ref.sure_t;
        else ++tally.exact;  // near-edge misses are fine either way; none is surely hit
    } else {
        double pt = oracle.possible_t(ray, h.triangle);
        if (pt < 0) why << "kdrt hit triangle " << h.triangle << " at t=" << h.t << ", which the ray misses";
        else if (std::fabs(h.t - pt) > oracle.t_tolerance(ray, pt)) why << "kdrt t=" << h.t << " on triangle " << h.triangle << ", reference t=" << pt;
        else if (ref.sure_hit && h.t > ref.sure_t + oracle.t_tolerance(ray, ref.sure_t))
            why << "kdrt hit triangle " << h.triangle << " at t=" << h.t << ", but triangle " << ref.sure_triangle << " is nearer at t=" << ref.sure_t;
        else if (ref.sure_hit && h.triangle == ref.sure_triangle) ++tally.exact;
        else ++tally.ambiguous;
    }
    std::string w = why.str();
    if (!w.empty()) {
        if (tally.wrong++ == 0) {
            std::ostringstream r;
            r.precision(9);
            r << w << "; ray org=(" << ray.org[0] << "," << ray.org[1] << "," << ray.org[2] << ") dir=(" << ray.dir[0] << ","
              << ray.dir[1] << "," << ray.dir[2] << ") tmin=" << ray.tmin << " tmax=" << ray.tmax;
            tally.first_wrong = r.str();
        }
    }
}

std::vector<kdrt_hit> trace_all(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays) {
    std::vector<kdrt_hit> hits(rays.size());
    parallel_for(rays.size(), [&](size_t i) { kdrt_intersect(tree, &rays[i], &hits[i]); });
    return hits;
}

std::vector<Reference> reference_all(const Oracle &oracle, const std::vector<kdrt_ray> &rays) {
    std::vector<Reference> refs(rays.size());
    parallel_for(rays.size(), [&](size_t i) { refs[i] = oracle.trace(rays[i]); });
    return refs;
}

TreePtr build(const Mesh &mesh, uint32_t max_leaf_size) {
    kdrt_triangles view = mesh.view();
    kdrt_build_options options = kdrt_default_build_options();
    options.max_leaf_size = max_leaf_size;
    kdrt_tree *tree = nullptr;
    kdrt_result r = kdrt_tree_build(&view, &options, &tree, nullptr);
    INFO("build " << mesh.name << " leaf size " << max_leaf_size << ": " << kdrt_result_string(r));
    REQUIRE(r == KDRT_SUCCESS);
    return TreePtr(tree);
}

size_t reference_ray_count() {
    const char *env = std::getenv("KDRT_TEST_RAYS");
    if (env && *env) {
        long v = std::strtol(env, nullptr, 10);
        if (v > 0) return size_t(v);
    }
    return 100000;
}

}  // namespace kt
