#include "test_support.hpp"

#include "oracle/hard_cases.hpp"
#include "common/random.hpp"
#include "common/timing.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <sstream>
#include <thread>

namespace kt {

using common::Mesh;
using common::Rng;
using oracle::Agreement;
using oracle::Oracle;
using oracle::Reference;

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

Mesh sphere(uint32_t rings, uint32_t segments, double radius) { return oracle::uv_sphere(rings, segments, radius, false); }

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

kdrt_ray ray_of(float ox, float oy, float oz, float dx, float dy, float dz, float tmin, float tmax) {
    kdrt_ray r{};
    r.org[0] = ox, r.org[1] = oy, r.org[2] = oz;
    r.dir[0] = dx, r.dir[1] = dy, r.dir[2] = dz;
    r.tmin = tmin, r.tmax = tmax;
    return r;
}

bool same_hit(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.triangle != b.triangle) return false;
    if (a.triangle == KDRT_INVALID_ID) return true;
    return a.t == b.t && a.u == b.u && a.v == b.v;
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
    // A flat scene (a plane, one triangle) has a box of zero thickness: every inside origin would
    // lie on the triangles themselves, at t = 0 where either answer is right. Thicken it.
    for (double &e : ext) e = std::max(e, 0.02 * diag);
    std::vector<kdrt_ray> rays(count);
    for (size_t i = 0; i < count; ++i) {
        kdrt_ray &r = rays[i];
        double o[3], d[3];
        if (i % 2 == 0) {
            for (int a = 0; a < 3; ++a) o[a] = c[a] + rng.range(-0.55, 0.55) * ext[a];
            rng.direction(d);
        } else {
            double u[3];
            rng.direction(u);
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

void random_direction(Rng &rng, float d[3]) {
    double v[3];
    rng.direction(v);
    for (int a = 0; a < 3; ++a) d[a] = float(v[a]);
}

kdrt_node_info node_info(const kdrt_tree *tree, uint32_t node) {
    kdrt_node_info info;
    REQUIRE(kdrt_tree_node(tree, node, &info) == KDRT_SUCCESS);
    return info;
}

std::vector<kdrt_hit> trace_all(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays) {
    std::vector<kdrt_hit> hits(rays.size());
    common::timed_parallel(rays.size(), common::all_cores(), [&](size_t i) { kdrt_intersect(tree, &rays[i], &hits[i]); });
    return hits;
}

std::vector<unsigned char> occluded_all(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays) {
    std::vector<unsigned char> occluded(rays.size());
    common::timed_parallel(rays.size(), common::all_cores(), [&](size_t i) { occluded[i] = (unsigned char)kdrt_occluded(tree, &rays[i]); });
    return occluded;
}

TreePtr build(const Mesh &mesh, uint32_t max_leaf_size, const Builder &builder, uint32_t flags) {
    kdrt_triangles view = mesh.view();
    kdrt_build_options options = kdrt_default_build_options();
    options.max_leaf_size = max_leaf_size;
    options.flags = flags;
    builder.apply(options);
    kdrt_tree *tree = nullptr;
    kdrt_result r = kdrt_tree_build(&view, &options, &tree, nullptr);
    INFO("build " << mesh.name << " builder " << builder.name << " leaf size " << max_leaf_size << ": "
                  << kdrt_result_string(r));
    REQUIRE(r == KDRT_SUCCESS);
    return TreePtr(tree);
}

TreePtr build(const Mesh &mesh, uint32_t max_leaf_size, kdrt_builder builder) {
    return build(mesh, max_leaf_size, Builder{builder, KDRT_BUILD_QUALITY_DEFAULT, builder == KDRT_BUILDER_MEDIAN ? "median" : "sah"});
}

namespace {

// The positive whole number the environment variable `name` holds, else `otherwise`.
size_t count_from_environment(const char *name, size_t otherwise) {
    const char *env = std::getenv(name);
    if (env && *env) {
        long v = std::strtol(env, nullptr, 10);
        if (v > 0) return size_t(v);
    }
    return otherwise;
}

}  // namespace

size_t reference_ray_count() { return count_from_environment("KDRT_TEST_RAYS", 100000); }

size_t drawn_count(size_t count) {
    return std::max(count / 5, count * reference_ray_count() / 100000);
}

kdrt_allocator CallCounter::hooks() {
    kdrt_allocator a;
    a.alloc = [](void *user, size_t size) {
        ++static_cast<CallCounter *>(user)->calls;
        return std::malloc(size ? size : 1);
    };
    a.free = [](void *user, void *ptr) {
        ++static_cast<CallCounter *>(user)->frees;
        std::free(ptr);
    };
    a.user = this;
    return a;
}

size_t shared_mesh_ray_count() { return count_from_environment("KDRT_TEST_MESH_RAYS", reference_ray_count()); }

size_t shared_mesh_max_triangles() { return count_from_environment("KDRT_TEST_MESH_TRIANGLES", 0); }

namespace {

std::string hex_ray(const kdrt_ray &r) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "org=(%a, %a, %a) dir=(%a, %a, %a) tmin=%a tmax=%a", r.org[0], r.org[1], r.org[2],
                  r.dir[0], r.dir[1], r.dir[2], r.tmin, r.tmax);
    return buf;
}

std::string hex_hit(const kdrt_hit &h) {
    if (h.triangle == KDRT_INVALID_ID) return "miss";
    char buf[256];
    std::snprintf(buf, sizeof buf, "triangle %u t=%a (%.9g) u=%a v=%a", h.triangle, h.t, h.t, h.u, h.v);
    return buf;
}

// Same answer bit for bit; on a miss only the triangle is specified.
bool same_answer(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.triangle != b.triangle) return false;
    return a.triangle == KDRT_INVALID_ID ||
           (std::memcmp(&a.t, &b.t, sizeof a.t) == 0 && std::memcmp(&a.u, &b.u, sizeof a.u) == 0 &&
            std::memcmp(&a.v, &b.v, sizeof a.v) == 0);
}

}  // namespace

void skip_test(const std::string &why) { WARN("kdrt test skipped: " << why); }

size_t brute_force_rays(size_t ray_count, uint32_t triangles) {
    const double scale = double(ray_count) / 100000.0;
    const size_t fits = size_t(kBruteForceTests * scale / std::max(1u, triangles));
    const size_t floor = std::max<size_t>(100, size_t(2000 * scale));
    return std::min(ray_count, std::max(floor, fits));
}

void check_scene(const Mesh &mesh, size_t ray_count, uint32_t seed) {
    const auto start = std::chrono::steady_clock::now();
    kdrt_triangles view = mesh.view();
    kdrt_aabb box;
    REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
    const std::vector<kdrt_ray> rays = random_rays(box, ray_count, seed);
    const Oracle oracle(mesh);
    const std::vector<Reference> refs = reference_all(oracle, rays);
    const double oracle_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    std::ostringstream log;
    const size_t brute_rays = brute_force_rays(rays.size(), mesh.triangle_count());
    log << mesh.name << ": " << mesh.triangle_count() << " triangles, " << rays.size() << " rays (leaf size 0: the first "
        << brute_rays << ")\n"
        << "  tree            hits   exact  ambiguous  wrong  unlike leaf 0  occluded unlike hit  seconds";
    std::vector<kdrt_hit> brute;  // leaf size 0's answers
    std::vector<std::pair<Builder, uint32_t>> trees;  // leaf size 0 first
    for (uint32_t leaf : kLeafSizes) trees.emplace_back(kBuilders[0], leaf);
    for (const Builder &sah : kSahBuilders)
        for (uint32_t leaf : kSahLeafSizes) trees.emplace_back(sah, leaf);
    for (const auto &config : trees) {
        const Builder &builder = config.first;
        const uint32_t leaf = config.second;
        const char *name = builder.name;
        const auto tree_start = std::chrono::steady_clock::now();
        TreePtr tree = build(mesh, leaf, builder);
        // Leaf size 0 tests every triangle for every ray: it takes the first brute_rays.
        const std::vector<kdrt_ray> traced(rays.begin(), rays.begin() + std::ptrdiff_t(leaf == 0 ? brute_rays : rays.size()));
        const std::vector<kdrt_hit> hits = trace_all(tree.get(), traced);
        const std::vector<unsigned char> occluded = occluded_all(tree.get(), traced);
        if (leaf == 0) brute = hits;

        Agreement tally;
        size_t hit_count = 0, not_as_brute = 0, occluded_differs = 0;
        std::string first_not_as_brute, first_occluded_differs;
        for (size_t i = 0; i < traced.size(); ++i) {
            const kdrt_hit &h = hits[i];
            check_hit(oracle, refs[i], rays[i], h, tally);
            hit_count += h.triangle != KDRT_INVALID_ID;
            if (i < brute.size() && !same_answer(h, brute[i]) && not_as_brute++ == 0)
                first_not_as_brute = "ray " + std::to_string(i) + " " + hex_ray(rays[i]) + ": leaf size 0 gives " +
                                     hex_hit(brute[i]) + ", this tree gives " + hex_hit(h);
            if (bool(occluded[i]) != (h.triangle != KDRT_INVALID_ID) && occluded_differs++ == 0)
                first_occluded_differs = "ray " + std::to_string(i) + " " + hex_ray(rays[i]) + ": kdrt_occluded " +
                                         std::to_string(int(occluded[i])) + ", kdrt_intersect " + hex_hit(h);
        }
        char row[160];
        std::snprintf(row, sizeof row, "\n  %-10s %4u %7zu %7zu %10zu %6zu %14zu %20zu %8.1f", name, leaf, hit_count, tally.exact,
                      tally.ambiguous, tally.wrong, not_as_brute, occluded_differs,
                      std::chrono::duration<double>(std::chrono::steady_clock::now() - tree_start).count());
        log << row;

        INFO(mesh.name << ", " << name << " builder, leaf size " << leaf << ", " << traced.size() << " rays (seed " << seed << ")");
        {
            INFO("first wrong: " << tally.first_wrong);
            CHECK(tally.wrong == 0);
        }
        {
            INFO("ambiguous " << tally.ambiguous << " of " << tally.rays << " rays");
            CHECK(tally.ambiguous * 200 <= tally.rays);  // at most 0.5%
        }
        {
            INFO("first: " << first_not_as_brute);
            CHECK(not_as_brute == 0);
        }
        {
            INFO("first: " << first_occluded_differs);
            CHECK(occluded_differs == 0);
        }
    }
    char took[96];
    std::snprintf(took, sizeof took, "\n  (%.1f s, %.1f of them the oracle)",
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), oracle_s);
    log << took;
    WARN(log.str());
}

void check_same_shape(const kdrt_tree *a, const kdrt_tree *b, double scale) {
    kdrt_tree_stats sa, sb;
    kdrt_tree_get_stats(a, &sa);
    kdrt_tree_get_stats(b, &sb);
    REQUIRE(sa.nodes == sb.nodes);
    REQUIRE(sa.triangle_refs == sb.triangle_refs);
    CHECK(sa.leaves == sb.leaves);
    CHECK(sa.max_depth == sb.max_depth);
    CHECK(sa.sah_cost == sb.sah_cost);
    size_t differ = 0;
    for (uint32_t i = 0; i < sa.nodes; ++i) {
        kdrt_node_info x, y;
        REQUIRE(kdrt_tree_node(a, i, &x) == KDRT_SUCCESS);
        REQUIRE(kdrt_tree_node(b, i, &y) == KDRT_SUCCESS);
        const bool same = x.is_leaf == y.is_leaf && x.axis == y.axis && double(x.split) * scale == double(y.split) &&
                          x.above == y.above && x.triangle_count == y.triangle_count &&
                          x.first_reference == y.first_reference;
        if (!same && differ++ == 0) FAIL_CHECK("node " << i << " differs");
    }
    CHECK(differ == 0);
    for (uint64_t r = 0; r < sa.triangle_refs; ++r) {
        uint32_t ta = 0, tb = 1;
        kdrt_tree_reference(a, uint32_t(r), &ta);
        kdrt_tree_reference(b, uint32_t(r), &tb);
        if (ta != tb) {
            FAIL_CHECK("reference " << r << " differs");
            break;
        }
    }
}

}  // namespace kt
