// kdrt-inspect: build kdrt's tree over a mesh and describe it: nodes, leaves, depth and leaf-size
// histograms, duplicated references, SAH cost, memory, build time; optionally its boxes down to a
// depth as a wireframe (OBJ or PLY) and a picture of them over the mesh. A saved tree (kdrt.h,
// SAVED TREES) is loaded over its mesh instead of built (--tree), or its header read alone; a
// built tree can be saved (--save-tree).
//
//   kdrt-inspect [MESH] [--builder median|sah] [--leaf-size N] [--save-tree OUT] [--json]
//                [--boxes OUT.obj|OUT.ply] [--depth D] [--picture OUT.png] [--size WxH]
//   kdrt-inspect [MESH] --tree FILE [--json] [--boxes ...] [--depth D] [--picture ...] [--size WxH]
#include "common/atomic_file.hpp"  // common::check_replaceable
#include "common/mesh_io.hpp"  // common::load_mesh, common::mesh_dir, common::torus
#include "common/output.hpp"  // common::guarded_main, common::UsageError
#include "common/parse.hpp"  // common::parse_count, common::parse_size
#include "common/saved_tree.hpp"  // common::read_saved_tree, common::saved_tree_refusal
#include "tree_inspect.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace {

const char *const usage =
    "usage: kdrt-inspect [MESH] [--builder median|sah] [--leaf-size N] [--save-tree OUT] [--json]\n"
    "                    [--boxes OUT.obj|OUT.ply] [--depth D] [--picture OUT.png] [--size WxH]\n"
    "       kdrt-inspect MESH --tree FILE [--json] [--boxes ...] [--picture ...] ...\n"
    "       kdrt-inspect --tree FILE [--json]\n"
    "Builds kdrt's kd-tree over MESH (anything Assimp reads) and prints its statistics: nodes,\n"
    "leaves (and empty ones), leaves by depth and by triangle count, references per triangle, SAH\n"
    "cost, bytes and build time. Without MESH: the Stanford bunny, common/stanford-bunny.obj in the\n"
    "mesh folder, else a generated torus.\n"
    "  --builder B     sah (the default) or median, in any case\n"
    "  --leaf-size N   most triangles in a leaf (default 4; 0: no tree)\n"
    "  --save-tree OUT the built tree saved to OUT (kdrt_tree_save), to load with --tree\n"
    "  --tree FILE     a saved tree (kdrt_tree_save, kdrt-render --save-tree of a one-mesh scene)\n"
    "                  loaded over MESH instead of built (kdrt_tree_load), and reported as a built\n"
    "                  one with its load time; its builder and leaf size are the file's. Without\n"
    "                  MESH, what the file's header says (kdrt_saved_tree_read_info): its meshes,\n"
    "                  build options, node counts and bounds. A file that is not a saved tree, of\n"
    "                  another format version, truncated, damaged or saved over another mesh is\n"
    "                  refused, with the reason\n"
    "  --json          the statistics as JSON on standard output\n"
    "  --boxes FILE    the boxes of the nodes down to --depth as a wireframe, .obj or .ply\n"
    "  --depth D       deepest level of boxes for --boxes and --picture (default 4)\n"
    "  --picture FILE  the mesh traced with kdrt and the boxes drawn over it, a .png\n"
    "  --size WxH      the picture's size (default 800x600)\n"
    "The mesh folder: {MESH_DIR}.\n"
    "Exit status: 0 success, 1 failure (unreadable mesh, a saved tree refused, unwritable output),\n"
    "2 a bad command line.\n";

using common::UsageError;

int fail(const std::string &message)
{
    std::fprintf(stderr, "kdrt-inspect: %s\n", message.c_str());
    return 1;
}

std::string lowercase(std::string s)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

int run(int argc, char **argv)
{
    std::string mesh_path, boxes_path, picture_path, tree_path, save_path, builder_name = "sah";
    std::string build_option;  // the last of --builder and --leaf-size, which --tree refuses
    unsigned long leaf_size = 4, depth = 4, width = 800, height = 600;
    bool json = false;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError{arg + " needs a value (see --help)"};
            return argv[++i];
        };
        if (arg == "--help" || arg == "-h") {
            std::string text = usage;
            text.replace(text.find("{MESH_DIR}"), 10, common::mesh_dir_help());
            std::fputs(text.c_str(), stdout);
            return 0;
        } else if (arg == "--json") {
            json = true;
        } else if (arg == "--tree") {
            tree_path = value();
            if (tree_path.empty()) throw UsageError{"--tree needs a file, not ''"};
        } else if (arg == "--save-tree") {
            save_path = value();
            if (save_path.empty()) throw UsageError{"--save-tree needs a file, not ''"};
        } else if (arg == "--builder") {
            build_option = arg;
            const std::string v = value();
            builder_name = lowercase(v);
            if (builder_name != "sah" && builder_name != "median")
                throw UsageError{"--builder wants median or sah, not '" + v + "'"};
        } else if (arg == "--leaf-size") {
            build_option = arg;
            const std::string v = value();
            if (!common::parse_count(v, KDRT_MAX_TRIANGLES, leaf_size))
                throw UsageError{"--leaf-size wants a whole number, not '" + v + "'"};
        } else if (arg == "--depth") {
            const std::string v = value();
            if (!common::parse_count(v, KDRT_MAX_DEPTH, depth))
                throw UsageError{"--depth wants a whole number from 0 to 64, not '" + v + "'"};
        } else if (arg == "--boxes") {
            boxes_path = value();
        } else if (arg == "--picture") {
            picture_path = value();
        } else if (arg == "--size") {
            const std::string v = value();
            if (!common::parse_size(v, 8192, width, height))
                throw UsageError{"--size wants WxH, each from 1 to 8192, not '" + v + "'"};
        } else if (arg.size() > 1 && arg[0] == '-') {
            throw UsageError{"unknown option '" + arg + "' (see --help)"};
        } else if (mesh_path.empty()) {
            mesh_path = arg;
        } else {
            throw UsageError{"one mesh at most ('" + mesh_path + "', then '" + arg + "')"};
        }
    }
    if (!tree_path.empty()) {
        if (!build_option.empty())
            throw UsageError{build_option + " does not apply to --tree: the saved tree is loaded as it was built"};
        if (!save_path.empty()) throw UsageError{"give --tree or --save-tree, not both: a loaded tree saves to the same bytes"};
        if (mesh_path.empty() && (!boxes_path.empty() || !picture_path.empty()))
            throw UsageError{std::string(boxes_path.empty() ? "--picture" : "--boxes") +
                             " needs the tree loaded over its mesh: kdrt-inspect MESH --tree FILE"};
    }
    // Refuse bad output names, and outputs that cannot be written, before the build.
    const auto extension = [](const std::string &p) { return lowercase(std::filesystem::path(p).extension().string()); };
    if (!boxes_path.empty() && extension(boxes_path) != ".obj" && extension(boxes_path) != ".ply")
        throw UsageError{"--boxes wants a file named .obj or .ply, not '" + boxes_path + "'"};
    if (!picture_path.empty() && extension(picture_path) != ".png")
        throw UsageError{"--picture wants a file named .png, not '" + picture_path + "'"};
    std::string error;
    for (const std::string &output : {boxes_path, picture_path, save_path})
        if (!output.empty() && !common::check_replaceable(output, error)) return fail(error);

    // A saved tree is read, and its header checked, before the mesh: a bad file costs no load.
    std::vector<unsigned char> saved;
    kdrt_saved_tree_info info{};
    if (!tree_path.empty()) {
        if (!common::read_saved_tree(tree_path, saved, error)) return fail(error);
        const kdrt_result r = kdrt_saved_tree_read_info(saved.data(), saved.size(), &info);
        if (r != KDRT_SUCCESS) return fail(common::saved_tree_refusal(r, tree_path, saved, 0, 0));
        if (mesh_path.empty()) {
            const std::string text = json ? kdrt_tools::saved_tree_json(tree_path, info) + "\n"
                                          : kdrt_tools::saved_tree_text(tree_path, info, true);
            std::fputs(text.c_str(), stdout);
            return 0;
        }
    }

    kdrt_tools::TreeReport report;
    common::Mesh mesh;
    if (mesh_path.empty()) {
        const std::string bunny =
            (std::filesystem::path(common::mesh_dir()) / "common" / "stanford-bunny.obj").lexically_normal().string();
        std::error_code ec;
        if (std::filesystem::is_regular_file(bunny, ec) && common::load_mesh(bunny, mesh, error)) {
            report.source = bunny + ", the default";
        } else {
            // Say why: no bunny at all, or one that would not load.
            report.source = "generated: no MESH given and " +
                            (error.empty() ? "no " + bunny : bunny + " did not load: " + error);
            mesh = common::torus(96, 48, 1.0, 0.35, 0.6);
        }
    } else {
        if (!common::load_mesh(mesh_path, mesh, error)) return fail("cannot read '" + mesh_path + "': " + error);
        report.source = mesh_path;
    }
    report.mesh = mesh.name;
    report.builder = builder_name;
    report.leaf_size = uint32_t(leaf_size);
    report.input_triangles = mesh.triangle_count();

    const kdrt_triangles view = mesh.view();
    kdrt_tree *tree = nullptr;
    if (!tree_path.empty()) {  // loaded over the mesh: the file's builder and leaf size
        report.tree_file = tree_path;
        report.saved_info = info;
        report.builder = kdrt_tools::builder_name(info.options.builder);
        report.leaf_size = info.options.max_leaf_size;
        const auto start = std::chrono::steady_clock::now();
        const kdrt_result loaded = kdrt_tree_load(saved.data(), saved.size(), &view, nullptr, &tree, nullptr);
        report.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        if (loaded != KDRT_SUCCESS)
            return fail(common::saved_tree_refusal(loaded, tree_path, saved, view.triangle_count, 1));
    } else {
        kdrt_build_options options = kdrt_default_build_options();
        options.builder = builder_name == "median" ? KDRT_BUILDER_MEDIAN : KDRT_BUILDER_SAH;
        options.max_leaf_size = uint32_t(leaf_size);
        options.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;  // inspect what can be built
        kdrt_build_report build_report;
        const auto start = std::chrono::steady_clock::now();
        const kdrt_result built = kdrt_tree_build(&view, &options, &tree, &build_report);
        report.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        if (built != KDRT_SUCCESS) return fail(std::string("cannot build the tree: ") + kdrt_result_string(built));
        report.degenerate_triangles = build_report.degenerate_triangles;
        report.skipped_triangles = build_report.skipped_triangles;
    }

    int status = 0;
    std::vector<kdrt_tools::DepthBox> boxes;
    if (!kdrt_tools::walk_tree(tree, report, error)) {
        status = fail(error);
    } else {
        std::fputs((json ? kdrt_tools::report_json(report) : kdrt_tools::report_text(report)).c_str(), stdout);
    }
    if (status == 0 && (!boxes_path.empty() || !picture_path.empty()) &&
        !kdrt_tools::boxes_to_depth(tree, uint32_t(depth), boxes, error))
        status = fail(error);
    if (status == 0 && !boxes_path.empty()) {
        if (!kdrt_tools::write_boxes(boxes, boxes_path, error)) status = fail(error);
        else std::fprintf(stderr, "kdrt-inspect: %zu boxes (depth 0 to %lu) -> %s\n", boxes.size(), depth, boxes_path.c_str());
    }
    if (status == 0 && !save_path.empty()) {
        const auto save = [](const void *t, kdrt_write_fn write, void *user) {
            return kdrt_tree_save(static_cast<const kdrt_tree *>(t), write, user);
        };
        if (!common::write_saved_tree(save_path, save, tree, error)) status = fail(error);
        else std::fprintf(stderr, "kdrt-inspect: saved tree (%zu bytes) -> %s\n", kdrt_tree_saved_size(tree), save_path.c_str());
    }
    if (status == 0 && !picture_path.empty()) {
        if (!kdrt_tools::write_boxes_picture(mesh, tree, boxes, int(width), int(height), picture_path, error))
            status = fail(error);
        else std::fprintf(stderr, "kdrt-inspect: picture -> %s\n", picture_path.c_str());
    }
    kdrt_tree_free(tree);
    return status;
}

}  // namespace

int main(int argc, char **argv)
{
    // A report lost to a full disk is a failure too (close_stdout).
    return common::guarded_main("kdrt-inspect", [&] { return run(argc, argv); });
}
