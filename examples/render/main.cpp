// kdrt-render: the original course ray tracer's renderer on kdrt, as a command-line tool.
// Presets or a scene file, settings by name, PNG or OpenEXR, every core, IOR-sweep animations.
#include "common/atomic_file.hpp"  // common::check_replaceable
#include "common/mesh_io.hpp"  // common::mesh_dir_help
#include "common/output.hpp"  // common::guarded_main, UsageError
#include "common/parse.hpp"  // common::parse_count
#include "common/saved_tree.hpp"  // common::read_saved_tree, common::saved_tree_refusal
#include "render.hpp"
#include "command_line.hpp"
#include "scene_file.hpp"

#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <new>
#include <string>
#include <thread>
#include <vector>

namespace {

const char *const kUsage =
    "usage: kdrt-render [--preset NAME | --scene FILE] [--set KEY=VALUE]... [--size WxH]\n"
    "                   [--threads N] [--seed N] [--animate KEY=FROM:TO --frames N]\n"
    "                   [--reference REF.exr] [--exr-float] [--tree FILE | --save-tree FILE]\n"
    "                   -o OUT.png|OUT.exr\n"
    "       kdrt-render --list-presets | --help\n"
    "\n"
    "Renders a preset of the original ray tracer (default PICTURE) or a YAML scene file, and\n"
    "writes a PNG (sRGB, clamped) or an OpenEXR file (linear, half floats), by OUT's extension.\n"
    "\n"
    "  --preset NAME       one of --list-presets (names of presets and settings, and true and\n"
    "                      false, in any case)\n"
    "  --scene FILE        a YAML scene file (format: examples/render/scene_file.hpp)\n"
    "  --set KEY=VALUE     a setting, after the preset's or the file's own (repeatable):\n"
    "                      NSAMPLES, MAX_BOUNCES, SHADOW_RAYS, PHONG, ENABLE_MIRROR, ENABLE_GLASS,\n"
    "                      AIR_INDEX_MEDIUM, MESH, ENABLE_INTERPOLATION, MAX_LEAF_SIZE,\n"
    "                      ENABLE_TEXTURES, FRESNEL, GLASS_IOR\n"
    "  --size WxH          image size (default 800x600; sides 1..16384, at most 64 Mpixels)\n"
    "  --threads N         render and build threads (default: every core); the image is the same\n"
    "  --seed N            seed of the per-pixel random streams (default 0)\n"
    "  --animate KEY=FROM:TO --frames N\n"
    "                      N frames, frame i with KEY = FROM + (TO - FROM) i / (N - 1), written\n"
    "                      to OUT with -0000, -0001, ... before the extension\n"
    "  --reference REF     after writing OUT, print rmse=<value> (linear RGB, every pixel and\n"
    "                      channel) against REF (.exr or .png, the same size) on stdout\n"
    "  --exr-float         32-bit float EXR channels instead of half\n"
    "  --save-tree FILE    once the meshes' tree is built, save it to FILE (kdrt_scene_save_meshes),\n"
    "                      before the render\n"
    "  --tree FILE         load the meshes' tree from FILE (a --save-tree of the same scene)\n"
    "                      instead of building it: the same image. A file that is not a saved\n"
    "                      tree, of another format version, truncated, damaged, saved over other\n"
    "                      meshes or with another MAX_LEAF_SIZE is refused (exit status 1), never\n"
    "                      built around: bake it again with --save-tree\n"
    "  -o OUT              output file, .png or .exr (required)\n"
    "  --list-presets      the presets, one a line, in the original's order\n"
    "  --help              this text\n"
    "\n"
    "Meshes named by the presets and by MESH=NAME are DIR/common/NAME.obj, else DIR/seed/NAME.off,\n"
    "DIR being the mesh folder:\n"
    "  MESH_DIR;\n"
    "without that folder the presets use a generated torus.\n"
    "\n"
    "Every output file (--save-tree's too) is checked before the render: one that cannot be\n"
    "written is a failure at once. Exit status: 0 success, 1 failure (unreadable mesh or scene, a\n"
    "saved tree refused, unwritable output), 2 a bad\n"
    "command line, 128+N killed by signal N (130 SIGINT, 143 SIGTERM; the old output kept).\n";

using common::UsageError;

int fail(const std::string &message, int code)
{
    std::fprintf(stderr, "kdrt-render: %s\n", message.c_str());
    return code;
}

bool parse_double(const std::string &text, double &out)
{
    errno = 0;
    char *end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || errno != 0 || *end != '\0' || !std::isfinite(v)) return false;
    out = v;
    return true;
}

// anim.png -> anim-0007.png
std::string frame_path(const std::string &path, uint32_t frame)
{
    const size_t dot = path.find_last_of('.');
    char number[16];
    std::snprintf(number, sizeof number, "-%04u", frame);
    return path.substr(0, dot) + number + path.substr(dot);
}

std::string format_value(double v)
{
    char text[40];
    std::snprintf(text, sizeof text, "%.17g", v);
    return text;
}

int run(int argc, char **argv)
{
    kr::SceneArgs args;
    std::string out, reference, animate, tree_path, save_tree_path;
    uint64_t frames = 0;
    bool exr_float = false, have_frames = false;

    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError{arg + " needs a value (see --help)"};
            return argv[++i];
        };
        if (kr::take_scene_arg(arg, value, args)) continue;
        if (arg == "--help" || arg == "-h") {
            std::string usage = kUsage;
            usage.replace(usage.find("MESH_DIR;"), 8, common::mesh_dir_help());
            std::fputs(usage.c_str(), stdout);
            return 0;
        } else if (arg == "--list-presets") {
            for (const std::string &p : kr::preset_names()) std::printf("%s\n", p.c_str());
            return 0;
        } else if (arg == "--animate") {
            animate = value();
        } else if (arg == "--frames") {
            const std::string v = value();
            if (!common::parse_count(v, 100000, frames) || frames == 0) throw UsageError{"bad --frames '" + v + "': expected 1..100000"};
            have_frames = true;
        } else if (arg == "--reference") {
            reference = value();
        } else if (arg == "--tree" || arg == "--save-tree") {
            (arg == "--tree" ? tree_path : save_tree_path) = value();
            if ((arg == "--tree" ? tree_path : save_tree_path).empty()) throw UsageError{arg + " needs a file, not ''"};
        } else if (arg == "--exr-float") {
            exr_float = true;
        } else if (arg == "-o") {
            out = value();
        } else {
            throw UsageError{"unknown argument '" + arg + "' (see --help)"};
        }
    }
    if (out.empty()) throw UsageError{"no output file: give -o OUT.png or -o OUT.exr"};
    std::string error;
    if (!kr::check_image_extension(out, error)) throw UsageError{error};
    if (!args.preset.empty() && !args.scene_file.empty()) throw UsageError{"give --preset or --scene, not both"};
    if (animate.empty() != !have_frames) throw UsageError{"--animate and --frames go together"};
    if (!animate.empty() && !reference.empty()) throw UsageError{"--reference compares one image: not with --animate"};
    if (!tree_path.empty() && !save_tree_path.empty())
        throw UsageError{"give --tree or --save-tree, not both: a loaded tree saves to the same bytes"};

    kr::RenderOptions options;
    options.width = args.width, options.height = args.height;
    options.threads = args.threads, options.seed = args.seed;

    // The scene, then the settings on top.
    kr::Scene scene;
    if (!args.scene_file.empty()) {
        if (!kr::load_scene_file(args.scene_file, scene, error)) return fail(error, 1);
    } else if (!kr::make_preset(args.preset.empty() ? "PICTURE" : args.preset, scene, error)) {
        throw UsageError{error};
    }
    if (!kr::apply_sets(args.sets, scene, error)) throw UsageError{error};

    // The animation's values, each checked before anything is rendered.
    std::string animate_key;
    std::vector<std::string> frame_values;
    if (!animate.empty()) {
        const size_t eq = animate.find('='), colon = animate.find(':', eq == std::string::npos ? 0 : eq);
        double from = 0, to = 0;
        if (eq == std::string::npos || eq == 0 || colon == std::string::npos ||
            !parse_double(animate.substr(eq + 1, colon - eq - 1), from) || !parse_double(animate.substr(colon + 1), to))
            throw UsageError{"bad --animate '" + animate + "': expected KEY=FROM:TO with numbers FROM and TO"};
        animate_key = animate.substr(0, eq);
        for (uint64_t f = 0; f < frames; ++f) {
            const double v = frames == 1 ? from : from + (to - from) * double(f) / double(frames - 1);
            frame_values.push_back(format_value(v));
            kr::Scene probe = scene;
            if (!kr::apply_setting(probe, animate_key, frame_values.back(), error))
                throw UsageError{"--animate frame " + std::to_string(f) + ": " + error};
            if (probe.settings.mesh != scene.settings.mesh) throw UsageError{"--animate: MESH is not a number"};
            if (probe.settings.max_leaf_size != scene.settings.max_leaf_size && !(tree_path + save_tree_path).empty())
                throw UsageError{std::string(tree_path.empty() ? "--save-tree" : "--tree") +
                                 " saves or loads one tree: not with --animate MAX_LEAF_SIZE"};
        }
    }
    if (scene.meshes.empty() && !(tree_path + save_tree_path).empty())
        throw UsageError{std::string(tree_path.empty() ? "--save-tree" : "--tree") + ": the scene " + scene.name +
                         " has no meshes, so no tree"};

    // Every output file is checked before the work: a folder of that name, a read-only file or a
    // folder no file can be created in fails now, not after the render.
    for (uint32_t f = 0; f < (frame_values.empty() ? 1u : uint32_t(frame_values.size())); ++f)
        if (!common::check_replaceable(frame_values.empty() ? out : frame_path(out, f), error)) return fail(error, 1);
    if (!save_tree_path.empty() && !common::check_replaceable(save_tree_path, error)) return fail(error, 1);

    // A saved tree is read and its header checked before the meshes are loaded: a file that is no
    // saved tree costs nothing; one of other meshes is found once they are loaded.
    std::vector<unsigned char> saved;
    if (!tree_path.empty()) {
        if (!common::read_saved_tree(tree_path, saved, error)) return fail(error, 1);
        kdrt_saved_tree_info info;
        const kdrt_result r = kdrt_saved_tree_read_info(saved.data(), saved.size(), &info);
        if (r != KDRT_SUCCESS) return fail(common::saved_tree_refusal(r, tree_path, saved, 0, 0), 1);
    }

    // The reference is read and its size checked before the render, not after it.
    kr::Image ref;
    if (!reference.empty()) {
        if (!kr::read_image(reference, ref, error)) return fail(error, 1);
        kr::Image sized;
        sized.width = options.width, sized.height = options.height;
        double unused = 0;
        if (!kr::image_rmse(sized, ref, unused, error)) return fail(error, 1);
    }

    if (!kr::load_meshes(scene, error)) return fail(error, 1);
    if (!kr::load_textures(scene, error)) return fail(error, 1);
    std::string mesh_source;
    for (const kr::MeshInstance &m : scene.meshes) mesh_source += (mesh_source.empty() ? "" : ", ") + m.source;

    const unsigned threads = options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    options.threads = threads;
    options.progress = isatty(STDERR_FILENO) != 0;
    kr::Renderer renderer;
    if (!(tree_path.empty() ? renderer.prepare(scene, threads, error)
                            : renderer.prepare_saved(scene, threads, saved, tree_path, error)))
        return fail(error, 1);
    if (!save_tree_path.empty()) {
        if (!renderer.save_tree(save_tree_path, error)) return fail(error, 1);
        std::fprintf(stderr, "kdrt-render: the meshes' tree saved -> %s\n", save_tree_path.c_str());
    }
    double build_seconds = renderer.build_seconds(), render_seconds = 0;
    uint32_t built_leaf_size = scene.settings.max_leaf_size;

    const uint32_t frame_count = frame_values.empty() ? 1 : uint32_t(frame_values.size());
    kr::Image image;
    for (uint32_t f = 0; f < frame_count; ++f) {
        std::string path = out;
        if (!frame_values.empty()) {
            if (!kr::apply_setting(scene, animate_key, frame_values[f], error)) return fail(error, 1);
            if (scene.settings.max_leaf_size != built_leaf_size) {  // a new tree for a new leaf size
                if (!renderer.prepare(scene, threads, error)) return fail(error, 1);
                build_seconds += renderer.build_seconds();
                built_leaf_size = scene.settings.max_leaf_size;
            }
            path = frame_path(out, f);
            options.frame = f;
        }
        const auto start = std::chrono::steady_clock::now();
        if (!renderer.render(options, image, error)) return fail(error, 1);
        render_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (!kr::write_image(path, image, exr_float, error)) return fail(error, 1);
        if (!frame_values.empty() && options.progress)
            std::fprintf(stderr, "kdrt-render: frame %u/%u, %s=%s: %s\n", f + 1, frame_count, animate_key.c_str(),
                         frame_values[f].c_str(), path.c_str());
    }

    std::fprintf(stderr,
                 "kdrt-render: %s, %ux%u, %u spp, %u threads, meshes: %s, tree %s %.3f s, render %.3f s%s -> %s\n",
                 scene.name.c_str(), options.width, options.height, scene.settings.nsamples, threads,
                 scene.meshes.empty() ? "none" : mesh_source.c_str(),
                 tree_path.empty() ? "build" : ("loaded from " + tree_path).c_str(), build_seconds, render_seconds,
                 frame_count > 1 ? (" (" + std::to_string(frame_count) + " frames)").c_str() : "",
                 frame_count > 1 ? frame_path(out, 0).c_str() : out.c_str());

    if (!reference.empty()) {
        double rmse = 0;
        if (!kr::image_rmse(image, ref, rmse, error)) return fail(error, 1);
        std::printf("rmse=%.9g\n", rmse);
    }
    return 0;
}

}  // namespace

int main(int argc, char **argv)
{
    return common::guarded_main("kdrt-render", [&] { return run(argc, argv); });
}
