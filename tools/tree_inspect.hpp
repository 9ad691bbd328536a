// What kdrt-inspect computes, as functions its tests call: a built tree's statistics from a walk
// with the inspection API, its boxes down to a depth as a wireframe (OBJ or PLY), and a picture of
// those boxes over the mesh, rendered with kdrt rays.
#pragma once

#include "kdrt.h"
#include "common/mesh_io.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace kdrt_tools {

struct TreeReport {
    std::string mesh;        // its name
    std::string source;      // where it came from (a path, or why it was generated)
    std::string builder;     // "median" or "sah"
    uint32_t leaf_size = 0;
    uint32_t input_triangles = 0;
    // Left out of the tree (kdrt_build_report): zero-area ones, and, under
    // KDRT_BUILD_SKIP_INVALID_TRIANGLES, those with a NaN or infinite corner.
    uint32_t degenerate_triangles = 0, skipped_triangles = 0;
    double build_ms = 0;     // kdrt_tree_build on the calling thread, or kdrt_tree_load's time
    // Non-empty: the tree was loaded from this saved tree (kdrt_tree_load), not built; builder and
    // leaf_size are then the file's, build_ms the load's time, and saved_info the file's header
    // (kdrt_saved_tree_read_info), which the report prints after the walk's statistics.
    std::string tree_file;
    kdrt_saved_tree_info saved_info{};
    kdrt_tree_stats stats{}; // kdrt_tree_get_stats
    // From the walk:
    uint64_t inner_nodes = 0, leaves = 0, empty_leaves = 0, references = 0;
    std::map<uint32_t, uint64_t> leaves_by_depth;     // depth -> leaves
    std::map<uint32_t, uint64_t> leaves_by_triangles; // triangles in the leaf -> leaves
};

// Walks `tree` and fills the walk's fields of `report` and its stats. false with a message if
// the walk disagrees with kdrt_tree_get_stats (which would be a kdrt bug) or the API fails.
bool walk_tree(const kdrt_tree *tree, TreeReport &report, std::string &error);

std::string report_text(const TreeReport &report);
std::string report_json(const TreeReport &report);

// What a saved tree's header says (kdrt_saved_tree_read_info): kdrt-inspect --tree FILE without
// its mesh (header_only: with a last line saying how to load the tree), and the end of
// report_text() for a loaded tree. saved_tree_json: a JSON object, indented by `indent` spaces
// (report_json()'s "saved_tree" at 2), its closing brace without a newline.
std::string saved_tree_text(const std::string &path, const kdrt_saved_tree_info &info, bool header_only);
std::string saved_tree_json(const std::string &path, const kdrt_saved_tree_info &info, int indent = 0);
// "sah", "median" (the default builder resolved as a build resolves it); "fast", "medium", "high".
const char *builder_name(kdrt_builder builder);
const char *quality_name(kdrt_build_quality quality);

// The boxes of every node at depth <= max_depth, shallowest first (depth-first within a level).
struct DepthBox {
    kdrt_aabb box;
    uint32_t depth;
};
bool boxes_to_depth(const kdrt_tree *tree, uint32_t max_depth, std::vector<DepthBox> &out, std::string &error);

// Wireframe of the boxes: 8 corners and 12 edges each, corners not shared between boxes. The
// format follows the extension: .obj (v and l lines) or .ply (ASCII, vertex and edge elements).
// Written to a temporary file renamed over path, so a failure leaves no file.
bool write_boxes(const std::vector<DepthBox> &boxes, const std::string &path, std::string &error);

// The mesh traced with kdrt rays (a headlight, as kdrt-render-mesh) and the boxes' edges drawn
// over it, coloured by depth; a PNG written as write_boxes writes.
bool write_boxes_picture(const common::Mesh &mesh, const kdrt_tree *tree, const std::vector<DepthBox> &boxes, int width,
                         int height, const std::string &path, std::string &error);


}  // namespace kdrt_tools
