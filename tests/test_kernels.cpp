// The kernels (KERNELS in kdrt.h): a tree built as usual runs the AVX-512 kernel where the CPU has
// AVX-512, else the AVX2 kernel where it has AVX2 (their single-ray queries are the same code; the
// batches' packets are compared in test_batch.cpp), the NEON kernel on aarch64 and the SIMD128
// kernel on WebAssembly built with -msimd128 (tests/platforms run them under qemu and node), one
// built with KDRT_BUILD_SCALAR_KERNEL the scalar kernel, and the SIMD and scalar kernels must
// return the
// same answers bit for bit (hit or miss, t, u, v, triangle; kdrt_occluded too) on every ray:
// random ones, the hard placements (in-plane, on-plane, axis-parallel, +-0 directions, grazing),
// rays at the vertices and edges of closed meshes, rays passing a hair inside or outside a
// triangle's edge (where the SIMD kernels' float filter must not decide wrongly), and rays with
// NaN or infinite parts. The KDRT_NO_SIMD build (kdrt_scalar_tests) has no SIMD kernel to
// compare: there this file checks only that every tree gets the scalar kernel, and the
// comparison is not registered at all, so that it is never reported as skipped for that.
#include "test_support.hpp"

#include "oracle/hard_cases.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

namespace {

kt::TreePtr build_with(const common::Mesh &mesh, kdrt_builder builder, uint32_t leaf, kdrt_intersector intersector,
                       uint32_t flags)
{
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = builder, o.max_leaf_size = leaf, o.intersector = intersector, o.flags = flags;
    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

kdrt_kernel kernel_of(uint32_t flags)
{
    common::Mesh one = kt::random_soup(1, 1);
    const kdrt_triangles view = one.view();
    kdrt_tree *tree = nullptr;
    kdrt_build_options o = kdrt_default_build_options();
    o.flags = flags;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    kdrt_tree_stats s;
    kdrt_tree_get_stats(tree, &s);
    kdrt_tree_free(tree);
    return s.kernel;
}


#if !defined(KDRT_NO_SIMD)  // what compares the kernels
// The default kernel is a SIMD one (AVX2, AVX-512, NEON or SIMD128).
bool simd_here() { return kernel_of(0) != KDRT_KERNEL_SCALAR; }

// Bit for bit: the same return value and, on a hit, the same bits of t, u, v and the same
// triangle (no -0 == +0 leniency here, unlike kt::same_hit).
bool identical(int ra, const kdrt_hit &a, int rb, const kdrt_hit &b)
{
    if (ra != rb || a.triangle != b.triangle) return false;
    if (!ra) return true;
    return std::memcmp(&a.t, &b.t, sizeof a.t) == 0 && std::memcmp(&a.u, &b.u, sizeof a.u) == 0 &&
           std::memcmp(&a.v, &b.v, sizeof a.v) == 0;
}

// Rays no random generator makes: every direction component in {-1, -0, +0, 1} from points on
// the box's corners and faces and its centre, and rays with a NaN or infinite part.
std::vector<kdrt_ray> special_rays(const kdrt_aabb &box)
{
    std::vector<kdrt_ray> rays;
    const float parts[] = {-1.0f, -0.0f, 0.0f, 1.0f};
    float centre[3];
    for (int a = 0; a < 3; ++a) centre[a] = 0.5f * (box.min[a] + box.max[a]);
    for (float dx : parts)
        for (float dy : parts)
            for (float dz : parts)
                for (int corner = 0; corner < 9; ++corner) {
                    float o[3];
                    for (int a = 0; a < 3; ++a)
                        o[a] = corner == 8 ? centre[a] : ((corner >> a) & 1 ? box.max[a] : box.min[a]);
                    rays.push_back(kt::ray_of(o[0], o[1], o[2], dx, dy, dz));
                }
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    rays.push_back(kt::ray_of(nan, centre[1], centre[2], 1, 0, 0));
    rays.push_back(kt::ray_of(centre[0], centre[1], centre[2], nan, 1, 0));
    rays.push_back(kt::ray_of(centre[0], centre[1], centre[2], 1, 1, 1, nan));
    rays.push_back(kt::ray_of(centre[0], centre[1], centre[2], 1, 1, 1, 0.0f, nan));
    rays.push_back(kt::ray_of(-inf, centre[1], centre[2], 1, 0, 0));
    rays.push_back(kt::ray_of(centre[0], centre[1], centre[2], inf, 0, 0));
    return rays;
}

// Compares the kernels on one scene for both builders at a few leaf sizes and both intersectors;
// returns the rays compared.
size_t compare_kernels(const common::Mesh &mesh, const std::vector<kdrt_ray> &rays)
{
    struct Config {
        kdrt_builder builder;
        uint32_t leaf;
    };
    const Config configs[] = {{KDRT_BUILDER_MEDIAN, 0}, {KDRT_BUILDER_MEDIAN, 1}, {KDRT_BUILDER_MEDIAN, 13},
                              {KDRT_BUILDER_SAH, 4}, {KDRT_BUILDER_SAH, 64}};
    size_t compared = 0;
    for (const Config &c : configs)
        for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST}) {
            INFO(mesh.name << ": builder " << c.builder << ", leaf size " << c.leaf << ", intersector " << intersector);
            kt::TreePtr simd = build_with(mesh, c.builder, c.leaf, intersector, 0);
            kt::TreePtr scalar = build_with(mesh, c.builder, c.leaf, intersector, KDRT_BUILD_SCALAR_KERNEL);
            kdrt_tree_stats ss, sc;
            kdrt_tree_get_stats(simd.get(), &ss);
            kdrt_tree_get_stats(scalar.get(), &sc);
            REQUIRE(ss.kernel != KDRT_KERNEL_SCALAR);
            REQUIRE(sc.kernel == KDRT_KERNEL_SCALAR);
            kt::check_same_shape(simd.get(), scalar.get());  // one tree format, two kernels
            size_t differ = 0, first = 0;
            for (size_t i = 0; i < rays.size(); ++i) {
                kdrt_hit a, b;
                const int ra = kdrt_intersect(simd.get(), &rays[i], &a), rb = kdrt_intersect(scalar.get(), &rays[i], &b);
                const bool same = identical(ra, a, rb, b) &&
                                  kdrt_occluded(simd.get(), &rays[i]) == kdrt_occluded(scalar.get(), &rays[i]);
                if (!same && differ++ == 0) first = i;
            }
            if (differ) {
                const kdrt_ray &r = rays[first];
                kdrt_hit a, b;
                kdrt_intersect(simd.get(), &r, &a), kdrt_intersect(scalar.get(), &r, &b);
                FAIL_CHECK(differ << " of " << rays.size() << " rays differ; the first, ray " << first << " ("
                                  << r.org[0] << ", " << r.org[1] << ", " << r.org[2] << ") dir (" << r.dir[0] << ", "
                                  << r.dir[1] << ", " << r.dir[2] << "): SIMD triangle " << a.triangle << " t " << a.t
                                  << ", scalar triangle " << b.triangle << " t " << b.t);
            }
            compared += rays.size();
        }
    return compared;
}

// Single triangles at scales from 2^-60 to 2^60, and rays from random origins through points a
// relative 1e-9 to 1e-5 of the triangle inside or outside one of its edges: there an edge
// function is smaller than float's rounding of its products, so a float filter that could get
// its sign wrong (a fused multiply-add would) drops hits the exact test makes. Returns the
// rays compared.
size_t compare_edge_grazing_rays(size_t triangles, uint32_t seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double nudges[] = {1e-9, 1e-8, 3e-8, 1e-7, 3e-7, 1e-6, 1e-5};
    size_t compared = 0, differ = 0;
    for (size_t n = 0; n < triangles; ++n) {
        const double scale = std::ldexp(1.0, int(n % 121) - 60);
        common::Mesh mesh;
        mesh.name = "one triangle";
        double c[3][3];
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) {
                mesh.positions.push_back(float(scale * (unit(rng) - 0.5)));
                c[k][a] = mesh.positions.back();
            }
        kt::TreePtr simd = build_with(mesh, KDRT_BUILDER_SAH, 4, KDRT_INTERSECTOR_WATERTIGHT, 0);
        kt::TreePtr scalar = build_with(mesh, KDRT_BUILDER_SAH, 4, KDRT_INTERSECTOR_WATERTIGHT, KDRT_BUILD_SCALAR_KERNEL);
        for (int edge = 0; edge < 3; ++edge)
            for (double nudge : nudges)
                for (double side : {-1.0, 1.0}) {
                    // A point on edge (edge, edge + 1), moved toward (or away from) the third corner.
                    const double s = unit(rng);
                    float org[3], dir[3];
                    for (int a = 0; a < 3; ++a) {
                        const double on = c[edge][a] + s * (c[(edge + 1) % 3][a] - c[edge][a]);
                        const double target = on + side * nudge * (c[(edge + 2) % 3][a] - on);
                        org[a] = float(scale * (2.0 * unit(rng) - 1.0) * 4.0);
                        dir[a] = float(target - org[a]);
                    }
                    const kdrt_ray ray = kt::ray_of(org[0], org[1], org[2], dir[0], dir[1], dir[2]);
                    kdrt_hit a, b;
                    const int ra = kdrt_intersect(simd.get(), &ray, &a), rb = kdrt_intersect(scalar.get(), &ray, &b);
                    if (!identical(ra, a, rb, b)) ++differ;
                    ++compared;
                }
    }
    CHECK(differ == 0);
    return compared;
}
#endif

}  // namespace

TEST_CASE("kernels: KDRT_BUILD_SCALAR_KERNEL picks the scalar kernel, KDRT_BUILD_AVX2_KERNEL the AVX2 one, and the default the best one here", "[kernels]")
{
    common::Mesh mesh = kt::random_soup(100, 3);
    kt::TreePtr scalar = build_with(mesh, KDRT_BUILDER_SAH, 4, KDRT_INTERSECTOR_WATERTIGHT, KDRT_BUILD_SCALAR_KERNEL);
    kdrt_tree_stats s;
    kdrt_tree_get_stats(scalar.get(), &s);
    CHECK(s.kernel == KDRT_KERNEL_SCALAR);
    CHECK(s.blocks >= (s.triangle_refs + 7) / 8);
#if defined(KDRT_NO_SIMD)
    // Built without the SIMD kernels: the scalar one, whatever the CPU and the flags.
    CHECK(kernel_of(0) == KDRT_KERNEL_SCALAR);
    CHECK(kernel_of(KDRT_BUILD_AVX2_KERNEL) == KDRT_KERNEL_SCALAR);
#elif defined(__x86_64__)
    // Where kdrt.h compiles the SIMD kernels in, a CPU with AVX-512 gets the AVX-512 one, a CPU
    // with AVX2 alone the AVX2 one; KDRT_BUILD_AVX2_KERNEL stops at AVX2.
    const bool avx2 = __builtin_cpu_supports("avx2"), avx512 = avx2 && __builtin_cpu_supports("avx512f");
    CHECK(kernel_of(0) == (avx512 ? KDRT_KERNEL_AVX512 : avx2 ? KDRT_KERNEL_AVX2 : KDRT_KERNEL_SCALAR));
    CHECK(kernel_of(KDRT_BUILD_AVX2_KERNEL) == (avx2 ? KDRT_KERNEL_AVX2 : KDRT_KERNEL_SCALAR));
    CHECK(kernel_of(KDRT_BUILD_AVX2_KERNEL | KDRT_BUILD_SCALAR_KERNEL) == KDRT_KERNEL_SCALAR);
#elif defined(__aarch64__) || defined(__wasm_simd128__)
    // NEON is part of aarch64, SIMD128 of a -msimd128 build: chosen with no CPU check;
    // KDRT_BUILD_AVX2_KERNEL asks for nothing narrower there.
#if defined(__aarch64__)
    const kdrt_kernel simd = KDRT_KERNEL_NEON;
#else
    const kdrt_kernel simd = KDRT_KERNEL_SIMD128;
#endif
    CHECK(kernel_of(0) == simd);
    CHECK(kernel_of(KDRT_BUILD_AVX2_KERNEL) == simd);
    CHECK(kernel_of(KDRT_BUILD_AVX2_KERNEL | KDRT_BUILD_SCALAR_KERNEL) == KDRT_KERNEL_SCALAR);
#endif
}

#if !defined(KDRT_NO_SIMD)
TEST_CASE("kernels: the SIMD and scalar kernels answer every ray bit for bit alike", "[kernels]")
{
    if (!simd_here()) {
        kt::skip_test("no SIMD kernel here (a CPU without AVX2, or a target without one): only the scalar kernel runs");
        return;
    }
    // About 1.4 million rays at the default ray count (100,000), each traced by both kernels, on
    // 10 trees of each scene; KDRT_TEST_RAYS scales it.
    const size_t per_scene = kt::reference_ray_count() / 5;
    size_t compared = 0;
    std::vector<common::Mesh> scenes = {kt::random_soup(3000, 11), kt::grid(40, 40, 5), kt::as_soup(kt::sphere(24, 32, 3.0)),
                                        oracle::hostile_mesh("fan", 2000, 7), oracle::hostile_mesh("identical", 50, 7)};
    for (const common::Mesh &mesh : scenes) {
        kt::TreePtr tree = kt::build(mesh, 4);
        const kdrt_aabb box = kdrt_tree_bounds(tree.get());
        std::vector<kdrt_ray> rays = kt::random_rays(box, per_scene, 17);
        const std::vector<kdrt_ray> special = special_rays(box);
        rays.insert(rays.end(), special.begin(), special.end());
        compared += compare_kernels(mesh, rays);
    }
    for (const oracle::HardSet &set : oracle::hard_sets(per_scene / 8, 23)) compared += compare_kernels(set.mesh, set.rays);
    for (const common::Mesh &closed : oracle::closed_meshes(false))
        compared += compare_kernels(closed, oracle::rays_at_vertices_and_edges(closed, per_scene / 8, 29));
    compared += compare_edge_grazing_rays(per_scene / 20, 31);
    WARN("rays compared (each on both kernels): " << compared);
    CHECK(compared >= kt::reference_ray_count() * 10);
}
#endif
