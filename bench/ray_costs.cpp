// kdrt-ray-costs: where a ray's time goes, by kind of ray. For each mesh it traces the bench's
// frame (bench.hpp) with primary rays and their diffuse bounces, sorts the rays into classes
// (primary rays that hit the mesh, in pixel order and shuffled; bounces that leave the mesh and
// bounces that hit it again), and prints per class the work a ray does (nodes, leaves, triangle
// tests: counted by ray_counts.cpp) beside the time it takes (thread CPU time, best of
// --repeat passes). bench/README.md's analysis of diffuse rays comes from it.
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include "bench.hpp"
#include "common/mesh_io.hpp"
#include "common/output.hpp"
#include "common/parse.hpp"
#include "common/random.hpp"
#include "ray_counts.hpp"

#include <cctype>
#include <ctime>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

const char *const kUsage =
    "usage: kdrt-ray-costs [MESH...] [--size WxH] [--repeat N] [--subdivide N] [--tile WxH]\n"
    "                      [--kernel default|avx512|avx2|scalar]\n"
    "\n"
    "For each mesh (default: the seed nefertiti and the Stanford bunny from the mesh folder, else\n"
    "a generated torus), prints a Markdown table: per class of ray, the rays in it, the inner\n"
    "nodes, leaves (empty ones), triangle tests, rope steps (cells left through a face), rope\n"
    "nodes (inner nodes passed going down from a rope) and restarts (rope walks handed to the\n"
    "walk from the root) a ray takes on average, and its time in ns (thread CPU time, best of N\n"
    "passes). Diffuse and shadow rays from their start cells (kdrt_spawn_ray's) and from the\n"
    "root. SAH tree, leaf size 4, one thread; a line above the tables names the kernel it runs.\n"
    "Then a table of batches (kdrt_intersect_batch, kdrt_occluded_batch) of the frame's rays in\n"
    "tiles: per mesh and ray set, the share of rays that walked in packets, and per packet the\n"
    "inner nodes it stepped through, the lanes walking at a step, the leaves, the blocks culled and\n"
    "the triangles tested against its rays, beside the batch's and the single calls' ns per ray.\n"
    "  --size WxH   the frame (default 400x400)\n"
    "  --repeat N   timed passes per class, the fastest kept (default 5)\n"
    "  --subdivide N  split every triangle in 4, N times, before building (default 0)\n"
    "  --tile WxH   the batch table's ray order: tiles of W x H pixels, tiles row by row, pixels\n"
    "               row by row in each (default 4x4: 16 rays, an AVX-512 packet's worth)\n"
    "  --kernel K   the kernel the trees run (the timed one and the counting copy): default (the\n"
    "               build's choice, the widest the CPU runs), avx512 (an error where the CPU\n"
    "               lacks it), avx2 (KDRT_BUILD_AVX2_KERNEL), scalar (KDRT_BUILD_SCALAR_KERNEL)\n"
    "The mesh folder: {MESH_DIR}.\n"
    "Exit status: 0 success, 1 failure (unreadable mesh, lost output), 2 a bad command line.\n";

using common::UsageError;

double thread_cpu_ns()
{
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e9 + double(t.tv_nsec);
}

// locate: each ray's start cell is found first, kdrt_locate(), and timed with it.
double ns_per_ray(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, unsigned repeat, bool locate)
{
    double best = 0;
    for (unsigned pass = 0; pass < repeat; ++pass) {
        const double start = thread_cpu_ns();
        unsigned hits = 0;
        for (kdrt_ray ray : rays) {
            kdrt_hit hit;
            if (locate) ray.cell = kdrt_locate(tree, ray.org);
            hits += unsigned(kdrt_intersect(tree, &ray, &hit));
        }
        const double ns = (thread_cpu_ns() - start) / double(rays.size());
        if (hits > rays.size()) std::abort();  // keeps the loop's results alive
        if (pass == 0 || ns < best) best = ns;
    }
    return best;
}

// kdrt_intersect_batch (kdrt_occluded_batch where any_hit) on the rays, as one batch.
double batch_ns_per_ray(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, unsigned repeat, bool any_hit)
{
    std::vector<kdrt_hit> hits(rays.size());
    std::vector<uint8_t> occluded(rays.size());
    const uint32_t n = uint32_t(rays.size());
    double best = 0;
    for (unsigned pass = 0; pass < repeat; ++pass) {
        const double start = thread_cpu_ns();
        const uint32_t found = any_hit ? kdrt_occluded_batch(tree, rays.data(), n, nullptr, occluded.data())
                                       : kdrt_intersect_batch(tree, rays.data(), n, nullptr, hits.data());
        const double ns = (thread_cpu_ns() - start) / double(rays.size());
        if (found > n) std::abort();
        if (pass == 0 || ns < best) best = ns;
    }
    return best;
}

// kdrt_occluded a ray at a time (ns_per_ray's kdrt_intersect, for shadow rays).
double occluded_ns_per_ray(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, unsigned repeat)
{
    double best = 0;
    for (unsigned pass = 0; pass < repeat; ++pass) {
        const double start = thread_cpu_ns();
        unsigned found = 0;
        for (const kdrt_ray &ray : rays) found += unsigned(kdrt_occluded(tree, &ray));
        const double ns = (thread_cpu_ns() - start) / double(rays.size());
        if (found > rays.size()) std::abort();
        if (pass == 0 || ns < best) best = ns;
    }
    return best;
}

std::string batches_error;

// The batch table's rows of one mesh: its frame's rays as a renderer hands them over (in tiles of
// tile_width x tile_height pixels), shuffled, the shadow rays of those pixels, and their diffuse
// bounces.
std::string batch_rows(const kb::Scene &scene, const kdrt_triangles &view, const kdrt_build_options &options,
                       const kdrt_tree *tree, unsigned width, unsigned height, unsigned repeat, unsigned tile_width,
                       unsigned tile_height)
{
    const std::string tiles = " in " + std::to_string(tile_width) + "x" + std::to_string(tile_height) + " tiles";
    struct Set {
        std::string name;
        kb::RayKind kind;
        bool shuffle, any_hit;
    } const sets[] = {{"primary rays" + tiles, kb::RayKind::primary, false, false},
                      {"the same, shuffled", kb::RayKind::primary, true, false},
                      {"shadow rays" + tiles + ", from the root", kb::RayKind::shadow, false, true},
                      {"diffuse rays" + tiles + ", from the root", kb::RayKind::diffuse, false, false}};
    std::string rows;
    for (const Set &set : sets) {
        std::vector<uint32_t> pixels;
        const std::vector<kdrt_ray> made = kb::make_rays(scene, set.kind, width, height, tree, 1, &pixels);
        std::vector<kdrt_ray> rays;
        for (size_t k : kb::ray_order(pixels, width, tile_width, tile_height, set.shuffle, 7)) {
            rays.push_back(made[k]);
            rays.back().cell = 0;  // hinted rays would take their rope walks, alone
        }
        if (rays.empty()) continue;
        kdrt_traversal_stats work;
        if (!kb::count_batch(view, options, rays, set.any_hit, work, batches_error)) return rows;
        const double n = double(rays.size()), packets = double(work.packets);
        char line[512], per_packet[256] = "- | - | - | - | -";
        if (work.packets)
            std::snprintf(per_packet, sizeof per_packet, "%.1f | %.2f | %.2f | %.2f | %.2f", work.packet_steps / packets,
                          double(work.packet_step_lanes) / double(work.packet_steps), work.packet_leaves / packets,
                          work.packet_blocks / packets, work.packet_triangles / packets);
        std::snprintf(line, sizeof line, "| %s | %s | %zu | %.0f%% | %s | %.0f | %.0f |\n", scene.name.c_str(), set.name.c_str(),
                      rays.size(), 100.0 * double(work.packet_lanes) / n, per_packet,
                      batch_ns_per_ray(tree, rays, repeat, set.any_hit),
                      set.any_hit ? occluded_ns_per_ray(tree, rays, repeat) : ns_per_ray(tree, rays, repeat, false));
        rows += line;
    }
    return rows;
}

int fail(const std::string &message)
{
    std::fprintf(stderr, "kdrt-ray-costs: %s\n", message.c_str());
    return 1;
}

int run(int argc, char **argv)
{
    std::vector<std::string> paths;
    unsigned width = 400, height = 400, repeat = 5, subdivide = 0, tile_width = 4, tile_height = 4;
    std::string kernel = "default";
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError{arg + " needs a value (see --help)"};
            return argv[++i];
        };
        if (arg == "--help" || arg == "-h") {
            std::string usage = kUsage;
            usage.replace(usage.find("{MESH_DIR}"), 10, common::mesh_dir_help());
            std::fputs(usage.c_str(), stdout);
            return 0;
        } else if (arg == "--size") {
            const std::string v = value();
            if (!common::parse_size(v, 8192, width, height)) throw UsageError{"--size wants WxH, got '" + v + "'"};
        } else if (arg == "--repeat") {
            const std::string v = value();
            if (!common::parse_count(v, 1000, repeat) || repeat == 0) throw UsageError{"--repeat wants 1 to 1000, got '" + v + "'"};
        } else if (arg == "--subdivide") {
            const std::string v = value();
            if (!common::parse_count(v, 4, subdivide)) throw UsageError{"--subdivide wants 0 to 4, got '" + v + "'"};
        } else if (arg == "--tile") {
            const std::string v = value();
            if (!common::parse_size(v, 256, tile_width, tile_height))
                throw UsageError{"--tile wants WxH with 1 <= W, H <= 256 (pixels), got '" + v + "'"};
        } else if (arg == "--kernel") {
            const std::string v = value();
            kernel = v;
            for (char &c : kernel) c = char(std::tolower(static_cast<unsigned char>(c)));
            if (kernel != "default" && kernel != "avx512" && kernel != "avx2" && kernel != "scalar")
                throw UsageError{"--kernel wants default, avx512, avx2 or scalar, got '" + v + "'"};
        } else if (arg.size() > 1 && arg[0] == '-') {
            throw UsageError{"unknown option '" + arg + "' (see --help)"};
        } else {
            paths.push_back(arg);
        }
    }
    // The kernel asked for, refused before any work where this CPU lacks it, as a bad option is;
    // the same flags reach the timed trees and the counting copy's (ray_counts.cpp).
    std::string kernel_error;
    kdrt_kernel runs = KDRT_KERNEL_SCALAR;
    if (!kb::check_kernels({kernel}, kernel_error)) throw UsageError{kernel_error};
    if (!kb::kernel_that_runs(kernel, runs, kernel_error)) return fail(kernel_error);
    std::vector<common::Mesh> meshes;
    if (paths.empty()) {
        for (const char *name : {"/seed/nefertiti.off", "/common/stanford-bunny.obj"}) {
            common::Mesh mesh;
            std::string error;
            if (common::load_mesh(common::mesh_dir() + name, mesh, error)) meshes.push_back(mesh);
        }
        if (meshes.empty()) meshes.push_back(common::torus(96, 48, 1.0, 0.35, 0.5));
    }
    for (const std::string &path : paths) {
        common::Mesh mesh;
        std::string error;
        if (!common::load_mesh(path, mesh, error)) return fail("cannot read '" + path + "': " + error);
        meshes.push_back(mesh);
    }

    std::vector<std::string> tables;
    std::printf("Kernel: %s (--kernel %s).\n\n", kb::kernel_name(runs), kernel.c_str());
    std::printf("| Mesh | Rays | Count | Inner nodes | Leaves (empty) | Triangle tests | Rope steps | Rope nodes | "
                "Restarts | ns per ray |\n");
    std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const common::Mesh &loaded : meshes) {
        const common::Mesh mesh = subdivide ? common::subdivided(loaded, subdivide) : loaded;
        const kb::Scene scene = kb::make_scene(mesh, mesh.name);
        const kdrt_triangles view = scene.geometry.view();
        kdrt_build_options options = kdrt_default_build_options();
        options.flags = kb::kernel_flags(kernel);  // passed on to the counting copy's builds too
        kdrt_tree *tree = nullptr;
        const kdrt_result built = kdrt_tree_build(&view, &options, &tree, nullptr);
        if (built != KDRT_SUCCESS) return fail("cannot build the tree over " + scene.name + ": " + kdrt_result_string(built));
        const auto primary = kb::make_rays(scene, kb::RayKind::primary, width, height, tree, 1);
        const auto diffuse = kb::make_rays(scene, kb::RayKind::diffuse, width, height, tree, 1);
        // The wall's two triangles come last: a hit below mesh_triangles is on the mesh.
        const auto on_mesh = [&](const kdrt_ray &ray) {
            kdrt_hit hit;
            return kdrt_intersect(tree, &ray, &hit) && hit.triangle < scene.mesh_triangles;
        };
        struct Class {
            const char *name;
            std::vector<kdrt_ray> rays;
            bool locate = false;
        } classes[11] = {{"primary, hitting the mesh, pixel order", {}},
                        {"the same, shuffled", {}},
                        {"primary, past the mesh to the wall", {}},
                        {"diffuse, leaving the mesh, from its start cell", {}},
                        {"diffuse, hitting the mesh again, from its start cell", {}},
                        {"diffuse, leaving the mesh, from the root", {}},
                        {"diffuse, hitting the mesh again, from the root", {}},
                        {"shadow, from its start cell", {}},
                        {"shadow, from the root", {}},
                        {"primary, hitting the mesh, from where it enters the tree, from the root", {}},
                        {"primary, hitting the mesh, from where it enters the tree, kdrt_locate'd", {}, true}};
        for (const kdrt_ray &ray : primary) classes[on_mesh(ray) ? 0 : 2].rays.push_back(ray);
        classes[1].rays = classes[0].rays;
        common::Rng rng(7);
        for (size_t i = classes[1].rays.size(); i > 1; --i) std::swap(classes[1].rays[i - 1], classes[1].rays[rng.below(uint32_t(i))]);
        for (const kdrt_ray &ray : diffuse) classes[on_mesh(ray) ? 4 : 3].rays.push_back(ray);
        // The same rays from the root: kdrt_spawn_ray gave them their start cells (kdrt.h, START
        // CELLS); shadow rays are timed with kdrt_intersect too, to the light at t = 1.
        for (int k = 0; k < 2; ++k)
            for (kdrt_ray ray : classes[3 + k].rays) ray.cell = 0, classes[5 + k].rays.push_back(ray);
        classes[7].rays = kb::make_rays(scene, kb::RayKind::shadow, width, height, tree, 1);
        for (kdrt_ray ray : classes[7].rays) ray.cell = 0, classes[8].rays.push_back(ray);
        // A camera outside the tree could start its rays in the cell where they enter it: the
        // same rays from a hair inside the box, walked from the root and from the cell that
        // kdrt_locate() finds there, the locate timed with the walk.
        const kdrt_aabb box = kdrt_tree_bounds(tree);
        for (kdrt_ray ray : classes[0].rays) {
            float t0, t1;
            if (!kdrt_aabb_intersect_ray(&box, &ray, &t0, &t1)) continue;
            const float t = t0 + (t1 - t0) * 1e-4f;
            for (int a = 0; a < 3; ++a) ray.org[a] += t * ray.dir[a];
            classes[9].rays.push_back(ray), classes[10].rays.push_back(ray);
        }
        for (const Class &c : classes) {
            if (c.rays.empty()) continue;
            kdrt_traversal_stats work;
            std::string error;
            std::vector<kdrt_ray> counted = c.rays;
            if (c.locate)
                for (kdrt_ray &ray : counted) ray.cell = kdrt_locate(tree, ray.org);
            if (!kb::count_traversal(view, options, counted, work, error)) return fail(error);
            const double n = double(c.rays.size());
            std::printf("| %s | %s | %zu | %.1f | %.1f (%.1f) | %.1f | %.1f | %.1f | %.3f | %.0f |\n", scene.name.c_str(),
                        c.name, c.rays.size(), work.inner_nodes / n, work.leaves / n, work.empty_leaves / n,
                        work.triangle_tests / n, work.rope_steps / n, work.rope_nodes / n, work.restarts / n,
                        ns_per_ray(tree, c.rays, repeat, c.locate));
        }
        tables.push_back(batch_rows(scene, view, options, tree, width, height, repeat, tile_width, tile_height));
        kdrt_tree_free(tree);
    }
    if (!batches_error.empty()) return fail(batches_error);
    // Where a batch's time goes: the packets' shared work beside the rays that went alone.
    std::printf("\n| Mesh | Batch of | Count | In packets | Steps a packet | Lanes a step | Leaves a packet | "
                "Blocks culled a packet | Triangles tested a packet | ns per ray, batch | ns per ray, single |\n");
    std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const std::string &rows : tables) std::fputs(rows.c_str(), stdout);
    return 0;
}

}  // namespace

int main(int argc, char **argv)
{
    return common::guarded_main("kdrt-ray-costs", [&] { return run(argc, argv); });
}
