// The steps of a kd-tree's construction, read back from a tree kdrt really built (through the
// inspection API), for kdrt-construction and its tests: each inner node's box, split and the side
// each of its triangles went to, as JSON that tools/construction_pictures.py draws.
#pragma once

#include "kdrt.h"

#include <cstdint>
#include <string>
#include <vector>

namespace kdrt_tools {

// Where a node's triangle went: the below child's subtree only, the above child's only, or both.
enum class Side { below, above, both };
const char *side_name(Side side);

struct ConstructionStep {
    uint32_t node = 0, depth = 0;
    kdrt_aabb box{};                  // the node's box
    int axis = 0;                     // 0 x, 1 y, 2 z
    float split = 0;
    uint32_t below = 0, above = 0;    // the children's node indices
    kdrt_aabb below_box{}, above_box{};
    std::vector<uint32_t> triangles;  // the node's triangles (those its leaves refer to), ascending
    std::vector<Side> sides;          // sides[i] is triangles[i]'s
    // The median builder splits at a triangle's centroid: that triangle (KDRT_INVALID_ID for SAH
    // or when none of the node's centroids lies on the plane) and its centroid, for the picture.
    uint32_t median_triangle = KDRT_INVALID_ID;
    float median_centroid[3] = {0, 0, 0};
};

struct ConstructionLeaf {
    uint32_t node = 0, depth = 0;
    kdrt_aabb box{};
    std::vector<uint32_t> triangles;
};

struct Construction {
    kdrt_builder builder = KDRT_BUILDER_MEDIAN;
    uint32_t leaf_size = 1;
    std::vector<float> positions;  // x, y, z of each triangle's three corners (a soup)
    kdrt_aabb root_box{};
    std::vector<ConstructionStep> steps;  // the inner nodes, breadth first (level by level, left to right)
    std::vector<ConstructionLeaf> leaves; // in the same order
};

// `count` triangles in the plane z = 0, seeded: corners within 1.6 of a centre drawn in
// [0, 10]^2, none of zero area. Same numbers on every platform (no std distributions).
std::vector<float> random_triangles_2d(uint32_t count, uint64_t seed);

// A text file of triangles, one a line: x0 y0 x1 y1 x2 y2 (in the plane z = 0) or nine numbers
// x0 y0 z0 ... ; blank lines and lines starting with # are skipped. false with a message naming
// the line on a malformed one, or when the file cannot be read or holds no triangle.
bool read_triangles(const std::string &path, std::vector<float> &positions, std::string &error);

// Builds a kdrt tree over the soup `positions` with `builder` and leaf size `leaf_size`, then
// walks it with the inspection API. false with kdrt's message when the build fails.
bool construct(const std::vector<float> &positions, kdrt_builder builder, uint32_t leaf_size, Construction &out,
               std::string &error);

// The construction as one JSON document (see tools/construction_pictures.py for the fields).
std::string construction_json(const Construction &construction);

// kdrt's centroid of a triangle: the corners' mean in float, kept within the corners.
void kdrt_centroid(const float corners[9], float out[3]);

}  // namespace kdrt_tools
