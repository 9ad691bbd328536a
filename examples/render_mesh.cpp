// kdrt-render-mesh: load a mesh, build a kd-tree over it, cast one primary ray per pixel through a
// pinhole camera that frames the mesh, shade hits with a headlight, write a PNG.
//
//   kdrt-render-mesh [MESH] [--size WxH] [--leaf-size N] -o OUT.png
//
// Reads what Assimp reads (OFF, OBJ, PLY, STL, glTF, ...). Without MESH it renders the Stanford
// bunny from the mesh folder (common::mesh_dir) when that exists, else a torus it generates itself.
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include "common/atomic_file.hpp"      // common::check_replaceable, common::write_file_atomically
#include "common/mesh_io.hpp"          // common::load_mesh (Assimp, guarded against malformed files), common::torus
#include "common/output.hpp"           // common::guarded_main, common::UsageError
#include "common/parse.hpp"            // common::parse_count, common::parse_size
#include "common/thread_scheduler.hpp" // common::ThreadScheduler: the SAH build's tasks on every core
#include "common/timing.hpp"           // common::Stopwatch, common::timed_parallel
#include "common/vec3.hpp"             // common::Vec3
#include <stb_image_write.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <unistd.h>

namespace {

const char *const kUsage =
    "usage: kdrt-render-mesh [MESH] [--size WxH] [--leaf-size N] -o OUT.png\n"
    "\n"
    "Renders MESH (any format Assimp reads: OFF, OBJ, PLY, STL, glTF, ...) with one primary ray\n"
    "per pixel traced through a kdrt kd-tree, and writes a PNG.\n"
    "\n"
    "  MESH           mesh file; default: the Stanford bunny, common/stanford-bunny.obj in\n"
    "                 the mesh folder, when it exists, else a generated torus\n"
    "  --size WxH     image size in pixels (default 800x600; sides 1..16384, at most 64 Mpixels)\n"
    "  --leaf-size N  kd-tree leaf size (default 4; 0 = no tree, every ray tests every triangle)\n"
    "  -o OUT.png     output file, a .png (required)\n"
    "  --help         this text\n"
    "\n"
    "The mesh folder: {MESH_DIR}.\n"
    "Tree statistics and build and trace times go to stderr.\n"
    "Exit status: 0 success, 1 failure (unreadable mesh, unwritable output), 2 a bad command line.\n";

using common::UsageError;
using common::Vec3;

bool file_exists(const std::string &path) { return !path.empty() && access(path.c_str(), R_OK) == 0; }

// Whether path's name ends in .png, in any case.
bool named_png(const std::string &path)
{
    const size_t n = path.size();
    if (n < 4) return false;
    std::string tail = path.substr(n - 4);
    for (char &c : tail) c = char(std::tolower(static_cast<unsigned char>(c)));
    return tail == ".png";
}

// Encodes the PNG in memory and writes it through a temporary file and a rename, so a failed run
// leaves no output file behind.
bool write_png(const std::string &path, int width, int height, const std::vector<unsigned char> &rgb,
               std::string &error)
{
    std::string png;
    const auto append = [](void *context, void *data, int size) {
        static_cast<std::string *>(context)->append(static_cast<const char *>(data), size_t(size));
    };
    if (!stbi_write_png_to_func(append, &png, width, height, 3, rgb.data(), width * 3)) {
        error = "cannot encode the PNG (out of memory?)";
        return false;
    }
    return common::write_file_atomically(path, png, error);
}

int fail(const std::string &message)
{
    std::fprintf(stderr, "kdrt-render-mesh: %s\n", message.c_str());
    return 1;
}

} // namespace

static int run(int argc, char **argv)
{
    std::string mesh_path, out_path;
    int width = 800, height = 600;
    unsigned long leaf_size = KDRT_DEFAULT_MAX_LEAF_SIZE;

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
        } else if (arg == "-o") {
            out_path = value();
        } else if (arg == "--size") {
            const std::string v = value();
            if (!common::parse_size(v, 16384, width, height) || uint64_t(width) * uint64_t(height) > (uint64_t(1) << 26))
                throw UsageError{"bad --size '" + v + "': expected WxH, each side 1..16384, at most 64 Mpixels"};
        } else if (arg == "--leaf-size") {
            const std::string v = value();
            if (!common::parse_count(v, 0xFFFFFFFFul, leaf_size))
                throw UsageError{"bad --leaf-size '" + v + "': expected a whole number"};
        } else if (arg.size() > 1 && arg[0] == '-') {
            throw UsageError{"unknown option '" + arg + "' (see --help)"};
        } else if (mesh_path.empty()) {
            mesh_path = arg;
        } else {
            throw UsageError{"one mesh at most ('" + mesh_path + "', then '" + arg + "')"};
        }
    }
    if (out_path.empty()) throw UsageError{"no output file: give -o OUT.png"};
    if (!named_png(out_path)) throw UsageError{"cannot write '" + out_path + "': it writes PNG only, named .png"};
    // An output that cannot be written is refused now, not after the build and the trace.
    std::string error;
    if (!common::check_replaceable(out_path, error)) return fail(error);

    // The mesh.
    common::Mesh mesh;
    if (mesh_path.empty()) {
        const std::string bunny = common::mesh_dir() + "/common/stanford-bunny.obj";
        if (file_exists(bunny)) {
            mesh_path = bunny;
        } else {
            mesh = common::torus(96, 48, 1.0, 0.35, 0.6);  // tilted towards the camera so its hole shows
            std::fprintf(stderr, "mesh: %s (no %s)\n", mesh.name.c_str(), bunny.c_str());
        }
    }
    if (!mesh_path.empty()) {
        if (!common::load_mesh(mesh_path, mesh, error)) return fail("cannot read '" + mesh_path + "': " + error);
        std::fprintf(stderr, "mesh: %s\n", mesh_path.c_str());
    }

    const kdrt_triangles view = mesh.view(); // borrows the mesh's arrays, which outlive the tree

    // The tree: the default (SAH) builder, its subtrees built on every core.
    common::ThreadScheduler build_threads;
    kdrt_build_options options = kdrt_default_build_options();
    options.max_leaf_size = uint32_t(leaf_size);
    options.scheduler = build_threads.hooks();
    kdrt_tree *tree = nullptr;
    kdrt_build_report report;
    const common::Stopwatch build_clock;
    const kdrt_result built = kdrt_tree_build(&view, &options, &tree, &report);
    const double build_seconds = build_clock.ms() / 1000;
    if (built != KDRT_SUCCESS) {
        // One line: the reason, and the corners of the first bad triangle.
        std::string message = "cannot build the tree over '" + (mesh_path.empty() ? mesh.name : mesh_path) +
                              "': " + kdrt_result_string(built);
        const uint32_t t = report.invalid_triangle;
        if (t != KDRT_INVALID_ID) message += "; first bad triangle " + std::to_string(t);
        for (int k = 0; k < 3 && t < view.triangle_count; ++k) {
            const uint32_t v = mesh.vertex(t, k);
            char corner[160];
            if (v < view.vertex_count)
                std::snprintf(corner, sizeof corner, "%s vertex %u (%g, %g, %g)", k ? "," : ":", v,
                              double(mesh.positions[size_t(v) * 3]), double(mesh.positions[size_t(v) * 3 + 1]),
                              double(mesh.positions[size_t(v) * 3 + 2]));
            else
                std::snprintf(corner, sizeof corner, "%s vertex %u out of range", k ? "," : ":", v);
            message += corner;
        }
        return fail(message);
    }

    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree, &stats);
    std::fprintf(stderr,
                 "tree: %u triangles, %u nodes, %u leaves, max depth %u, %llu triangle references "
                 "(%.2f per triangle), %.1f KiB, leaf size %u\n",
                 stats.triangles, stats.nodes, stats.leaves, stats.max_depth,
                 (unsigned long long)stats.triangle_refs,
                 stats.triangles ? double(stats.triangle_refs) / stats.triangles : 0.0, double(stats.bytes) / 1024.0,
                 options.max_leaf_size);
    std::fprintf(stderr, "build: %.3f s on %u threads\n", build_seconds, build_threads.threads());

    // The camera: looks at the centre of the mesh's box from the front (+z), a little from the
    // right and above, with +y up, far enough back that the box's bounding sphere fits the view.
    const kdrt_aabb box = kdrt_tree_bounds(tree);
    const Vec3 lo = {box.min[0], box.min[1], box.min[2]}, hi = {box.max[0], box.max[1], box.max[2]};
    const Vec3 center = 0.5 * (lo + hi);
    const double radius = std::max(0.5 * std::sqrt(dot(hi - lo, hi - lo)), 1e-30);
    const double pi = 3.14159265358979323846;
    const double half_fov = 0.5 * 35.0 * pi / 180.0; // vertical field of view: 35 degrees
    const double aspect = double(width) / height;
    const double tan_half = std::tan(half_fov);
    const double fit = std::min(tan_half, tan_half * aspect); // tangent of the narrower half-angle
    const double distance = 1.05 * radius * std::sqrt(1.0 + 1.0 / (fit * fit));
    const Vec3 back = normalize(Vec3{0.35, 0.25, 1.0});
    const Vec3 eye = center + distance * back;
    const Vec3 forward = -1.0 * back;
    const Vec3 right = normalize(cross(forward, Vec3{0, 1, 0}));
    const Vec3 up = cross(right, forward);

    // Trace: each thread a band of rows; the tree is const and shared.
    std::vector<unsigned char> rgb(size_t(width) * size_t(height) * 3);
    std::atomic<uint64_t> hits(0);
    const unsigned thread_count = common::all_cores();
    const double trace_seconds = common::timed_parallel(size_t(height), thread_count, [&](size_t y) {
        uint64_t row_hits = 0;
        for (int x = 0; x < width; ++x) {
            // Row 0 is the top of the image.
            const double sx = (2.0 * (x + 0.5) / width - 1.0) * tan_half * aspect;
            const double sy = (1.0 - 2.0 * (double(y) + 0.5) / height) * tan_half;
            const Vec3 d = normalize(forward + sx * right + sy * up);
            kdrt_ray ray = {};  // tmin 0, and the walk starts at the root
            ray.org[0] = float(eye.x), ray.org[1] = float(eye.y), ray.org[2] = float(eye.z);
            ray.dir[0] = float(d.x), ray.dir[1] = float(d.y), ray.dir[2] = float(d.z);
            ray.tmax = INFINITY;
            kdrt_hit hit;
            float n[3];
            double r = 0.30, g = 0.30, b = 0.32; // background
            if (kdrt_intersect(tree, &ray, &hit) && kdrt_hit_surface(tree, &hit, nullptr, n)) {
                ++row_hits;
                // Headlight: the light sits at the eye, so the Lambert term is |cos| between the
                // ray and the unit geometric normal (either side of the triangle is lit).
                const double shade = 0.08 + 0.92 * std::fabs(dot(Vec3{n[0], n[1], n[2]}, d));
                r = 0.95 * shade, g = 0.88 * shade, b = 0.78 * shade;
            }
            unsigned char *px = &rgb[(y * size_t(width) + size_t(x)) * 3];
            px[0] = (unsigned char)std::lround(255.0 * std::min(1.0, r));
            px[1] = (unsigned char)std::lround(255.0 * std::min(1.0, g));
            px[2] = (unsigned char)std::lround(255.0 * std::min(1.0, b));
        }
        hits += row_hits;
    }) / 1000;
    const double rays = double(width) * height;
    std::fprintf(stderr, "trace: %.3f s for %dx%d primary rays on %u threads (%.2f Mrays/s, %.1f%% hit)\n",
                 trace_seconds, width, height, thread_count, rays / std::max(trace_seconds, 1e-9) / 1e6,
                 100.0 * double(hits.load()) / rays);
    kdrt_tree_free(tree);

    if (!write_png(out_path, width, height, rgb, error)) return fail(error);
    std::fprintf(stderr, "wrote %s\n", out_path.c_str());
    return 0;
}

int main(int argc, char **argv)
{
    return common::guarded_main("kdrt-render-mesh", [&] { return run(argc, argv); });
}
