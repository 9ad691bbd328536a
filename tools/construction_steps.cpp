#include "construction.hpp"

#include "common/random.hpp"
#include "common/regular_file.hpp"  // common::open_regular_file

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <iterator>
#include <sstream>

namespace kdrt_tools {

const char *side_name(Side side)
{
    switch (side) {
    case Side::below: return "below";
    case Side::above: return "above";
    case Side::both: return "both";
    }
    return "?";
}

void kdrt_centroid(const float c[9], float out[3])
{
    for (int a = 0; a < 3; ++a) {
        const float lo = std::min({c[a], c[3 + a], c[6 + a]}), hi = std::max({c[a], c[3 + a], c[6 + a]});
        const float mean = (c[a] + c[3 + a] + c[6 + a]) * (1.0f / 3.0f);
        out[a] = mean < lo ? lo : (mean > hi ? hi : mean);
    }
}

namespace {

// Writes a float so that reading it back gives the same float.
void put_number(std::string &s, double x)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", x);
    s += buf;
}

void put_box_2d(std::string &s, const kdrt_aabb &b)
{
    s += "[[";
    put_number(s, b.min[0]);
    s += ", ";
    put_number(s, b.min[1]);
    s += "], [";
    put_number(s, b.max[0]);
    s += ", ";
    put_number(s, b.max[1]);
    s += "]]";
}

void put_indices(std::string &s, const std::vector<uint32_t> &v)
{
    s += "[";
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
    s += "]";
}

}  // namespace

std::vector<float> random_triangles_2d(uint32_t count, uint64_t seed)
{
    common::Rng random = common::Rng::from_state(seed);
    std::vector<float> positions;
    while (positions.size() < size_t(count) * 9) {
        const double cx = random.range(0.0, 10.0), cy = random.range(0.0, 10.0);
        float t[9];
        for (int k = 0; k < 3; ++k) {
            t[3 * k] = float(cx + random.range(-1.6, 1.6));
            t[3 * k + 1] = float(cy + random.range(-1.6, 1.6));
            t[3 * k + 2] = 0.0f;
        }
        // Slivers draw badly and say nothing: keep triangles of area at least 0.4.
        const double area = 0.5 * std::fabs(double(t[3] - t[0]) * (t[7] - t[1]) - double(t[6] - t[0]) * (t[4] - t[1]));
        if (area >= 0.4) positions.insert(positions.end(), t, t + 9);
    }
    return positions;
}

bool read_triangles(const std::string &path, std::vector<float> &positions, std::string &error)
{
    // Only a regular file: a FIFO would wait for a writer, /dev/zero would never end, and a folder
    // opens but fails on reading.
    struct stat st;
    std::string why;
    std::FILE *file = common::open_regular_file(path.c_str(), st, why);
    if (!file) {
        error = "cannot read '" + path + "': " + why;
        return false;
    }
    std::string text;
    char buffer[65536];
    for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, file)) > 0;) text.append(buffer, n);
    const bool failed = std::ferror(file) != 0;
    const int read_errno = errno;
    std::fclose(file);
    if (failed) {
        error = "cannot read '" + path + "': " + std::strerror(read_errno);
        return false;
    }
    positions.clear();
    std::istringstream in(text);
    std::string line;
    for (unsigned number = 1; std::getline(in, line); ++number) {
        const size_t first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos || line[first] == '#') continue;
        std::istringstream fields(line);
        std::vector<double> v;
        std::string field;
        while (fields >> field) {
            char *end = nullptr;
            const double x = std::strtod(field.c_str(), &end);
            if (end == field.c_str() || *end != '\0' || !std::isfinite(x) || std::fabs(x) > 3.0e38) {
                error = path + ":" + std::to_string(number) + ": '" + field + "' is not a finite number";
                return false;
            }
            v.push_back(x);
        }
        if (v.size() == 6) v = {v[0], v[1], 0, v[2], v[3], 0, v[4], v[5], 0};
        if (v.size() != 9) {
            error = path + ":" + std::to_string(number) + ": a triangle is 6 numbers (x y per corner) or 9 (x y z), not " +
                    std::to_string(v.size());
            return false;
        }
        for (double x : v) positions.push_back(float(x));
    }
    if (positions.empty()) {
        error = path + ": no triangles";
        return false;
    }
    return true;
}

bool construct(const std::vector<float> &positions, kdrt_builder builder, uint32_t leaf_size, Construction &out,
               std::string &error)
{
    out = Construction();
    out.builder = builder;
    out.leaf_size = leaf_size;
    out.positions = positions;
    kdrt_triangles mesh{};
    mesh.positions = out.positions.empty() ? nullptr : out.positions.data();
    mesh.vertex_count = uint32_t(out.positions.size() / 3);
    mesh.triangle_count = uint32_t(out.positions.size() / 9);
    kdrt_build_options options = kdrt_default_build_options();
    options.builder = builder;
    options.max_leaf_size = leaf_size;
    kdrt_tree *tree = nullptr;
    const kdrt_result built = kdrt_tree_build(&mesh, &options, &tree, nullptr);
    if (built != KDRT_SUCCESS) {
        error = std::string("kdrt_tree_build: ") + kdrt_result_string(built);
        return false;
    }
    out.root_box = kdrt_tree_bounds(tree);

    // Each node's triangles, children first: a node holds what its leaves refer to.
    const uint32_t count = kdrt_tree_node_count(tree);
    std::vector<kdrt_node_info> info(count);
    std::vector<std::vector<uint32_t>> held(count);
    kdrt_result r = KDRT_SUCCESS;
    for (uint32_t i = 0; i < count && r == KDRT_SUCCESS; ++i) r = kdrt_tree_node(tree, i, &info[i]);
    // Depth-first numbering puts children after their parent: walking backwards sees them first.
    for (uint32_t i = count; i-- > 0 && r == KDRT_SUCCESS;) {
        if (info[i].is_leaf) {
            for (uint32_t k = 0; k < info[i].triangle_count && r == KDRT_SUCCESS; ++k) {
                uint32_t tri = 0;
                r = kdrt_tree_reference(tree, info[i].first_reference + k, &tri);
                held[i].push_back(tri);
            }
            std::sort(held[i].begin(), held[i].end());
            held[i].erase(std::unique(held[i].begin(), held[i].end()), held[i].end());
        } else {
            const std::vector<uint32_t> &b = held[info[i].below], &a = held[info[i].above];
            std::set_union(b.begin(), b.end(), a.begin(), a.end(), std::back_inserter(held[i]));
        }
    }
    kdrt_tree_free(tree);
    if (r != KDRT_SUCCESS) {
        error = std::string("walking the tree: ") + kdrt_result_string(r);
        return false;
    }

    // Breadth first, below before above: the order of the original's figures.
    std::deque<uint32_t> queue{0};
    while (!queue.empty()) {
        const uint32_t i = queue.front();
        queue.pop_front();
        const kdrt_node_info &n = info[i];
        if (n.is_leaf) {
            ConstructionLeaf leaf;
            leaf.node = i, leaf.depth = n.depth, leaf.box = n.bounds, leaf.triangles = held[i];
            out.leaves.push_back(leaf);
            continue;
        }
        ConstructionStep s;
        s.node = i, s.depth = n.depth, s.box = n.bounds, s.axis = n.axis, s.split = n.split;
        s.below = n.below, s.above = n.above;
        s.below_box = info[n.below].bounds, s.above_box = info[n.above].bounds;
        s.triangles = held[i];
        const std::vector<uint32_t> &b = held[n.below], &a = held[n.above];
        for (uint32_t t : s.triangles) {
            const bool in_below = std::binary_search(b.begin(), b.end(), t);
            const bool in_above = std::binary_search(a.begin(), a.end(), t);
            s.sides.push_back(in_below && in_above ? Side::both : (in_below ? Side::below : Side::above));
        }
        if (builder == KDRT_BUILDER_MEDIAN) {
            // The triangle whose centroid the plane passes through: of those on it, the one at the
            // median of the order kdrt sorts by (centroid, then index).
            std::vector<std::pair<float, uint32_t>> order;
            for (uint32_t t : s.triangles) {
                float c[3];
                kdrt_centroid(&out.positions[size_t(t) * 9], c);
                order.push_back({c[s.axis], t});
            }
            std::sort(order.begin(), order.end());
            const auto &median = order[order.size() / 2];
            if (median.first == s.split) {
                s.median_triangle = median.second;
                kdrt_centroid(&out.positions[size_t(median.second) * 9], s.median_centroid);
            }
        }
        out.steps.push_back(s);
        queue.push_back(n.below);
        queue.push_back(n.above);
    }
    return true;
}

std::string construction_json(const Construction &c)
{
    static const char *const axes[3] = {"x", "y", "z"};
    std::string s = "{\n  \"builder\": \"";
    s += c.builder == KDRT_BUILDER_MEDIAN ? "median" : "sah";
    s += "\",\n  \"leaf_size\": " + std::to_string(c.leaf_size) + ",\n  \"triangles\": [";
    for (size_t t = 0; t < c.positions.size() / 9; ++t) {
        s += t ? ",\n    [" : "\n    [";
        for (int k = 0; k < 3; ++k) {
            s += k ? ", [" : "[";
            for (int a = 0; a < 3; ++a) {
                if (a) s += ", ";
                put_number(s, c.positions[t * 9 + size_t(k) * 3 + size_t(a)]);
            }
            s += "]";
        }
        s += "]";
    }
    s += "\n  ],\n  \"root_box\": ";
    put_box_2d(s, c.root_box);
    s += ",\n  \"steps\": [";
    for (size_t i = 0; i < c.steps.size(); ++i) {
        const ConstructionStep &st = c.steps[i];
        s += i ? ",\n    {" : "\n    {";
        s += "\"step\": " + std::to_string(i + 1) + ", \"node\": " + std::to_string(st.node) +
             ", \"depth\": " + std::to_string(st.depth) + ", \"axis\": \"" + axes[st.axis] + "\", \"split\": ";
        put_number(s, st.split);
        s += ",\n     \"box\": ";
        put_box_2d(s, st.box);
        s += ", \"below_box\": ";
        put_box_2d(s, st.below_box);
        s += ", \"above_box\": ";
        put_box_2d(s, st.above_box);
        s += ",\n     \"triangles\": ";
        put_indices(s, st.triangles);
        s += ", \"sides\": [";
        for (size_t k = 0; k < st.sides.size(); ++k) s += std::string(k ? ", \"" : "\"") + side_name(st.sides[k]) + "\"";
        s += "]";
        if (st.median_triangle != KDRT_INVALID_ID) {
            s += ",\n     \"median_triangle\": " + std::to_string(st.median_triangle) + ", \"median_centroid\": [";
            put_number(s, st.median_centroid[0]);
            s += ", ";
            put_number(s, st.median_centroid[1]);
            s += "]";
        }
        s += "}";
    }
    s += "\n  ],\n  \"leaves\": [";
    for (size_t i = 0; i < c.leaves.size(); ++i) {
        const ConstructionLeaf &l = c.leaves[i];
        s += i ? ",\n    {" : "\n    {";
        s += "\"node\": " + std::to_string(l.node) + ", \"depth\": " + std::to_string(l.depth) + ", \"box\": ";
        put_box_2d(s, l.box);
        s += ", \"triangles\": ";
        put_indices(s, l.triangles);
        s += "}";
    }
    s += "\n  ]\n}\n";
    return s;
}

}  // namespace kdrt_tools
