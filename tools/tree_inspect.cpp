#include "tree_inspect.hpp"
#include "common/atomic_file.hpp"  // common::write_file_atomically
#include "common/vec3.hpp"         // common::Vec3

#include <stb_image_write.h>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace kdrt_tools {

namespace {

std::string format(const char *fmt, double x)
{
    char buf[64];
    std::snprintf(buf, sizeof buf, fmt, x);
    return buf;
}

std::string json_string(const std::string &s)
{
    std::string out = "\"";
    for (unsigned char c : s) {
        if (c == '"' || c == '\\') out += '\\', out += char(c);
        else if (c < 0x20) out += format("\\u%04x", c);
        else out += char(c);
    }
    return out + "\"";
}

// JSON has no NaN or infinity.
std::string json_number(double x)
{
    return std::isfinite(x) ? format("%.10g", x) : "null";
}

using common::Vec3;

// A box's corners, corner k having bit 0 for x, 1 for y, 2 for z (0: min, 1: max), and its 12
// edges as pairs of corners differing in one bit.
void box_corners(const kdrt_aabb &b, double out[8][3])
{
    for (int k = 0; k < 8; ++k)
        for (int a = 0; a < 3; ++a) out[k][a] = (k >> a) & 1 ? b.max[a] : b.min[a];
}
const int box_edges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                              {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

// Whether s ends with tail (lowercase), in any case: OUT.PNG is a PNG too.
bool ends_with(const std::string &s, const std::string &tail)
{
    if (s.size() < tail.size()) return false;
    for (size_t i = 0; i < tail.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(s[s.size() - tail.size() + i])) != tail[i]) return false;
    return true;
}

void append_png(void *context, void *data, int size)
{
    static_cast<std::string *>(context)->append(static_cast<const char *>(data), size_t(size));
}

// Calls visit(info) for every node in index order; false with kdrt_tree_node's error if one fails.
template <typename Visit>
bool for_each_node(const kdrt_tree *tree, std::string &error, Visit &&visit)
{
    const uint32_t count = kdrt_tree_node_count(tree);
    for (uint32_t i = 0; i < count; ++i) {
        kdrt_node_info n;
        const kdrt_result r = kdrt_tree_node(tree, i, &n);
        if (r != KDRT_SUCCESS) {
            error = "kdrt_tree_node(" + std::to_string(i) + "): " + kdrt_result_string(r);
            return false;
        }
        visit(n);
    }
    return true;
}

}  // namespace

bool walk_tree(const kdrt_tree *tree, TreeReport &report, std::string &error)
{
    kdrt_tree_get_stats(tree, &report.stats);
    report.inner_nodes = report.leaves = report.empty_leaves = report.references = 0;
    report.leaves_by_depth.clear();
    report.leaves_by_triangles.clear();
    const bool walked = for_each_node(tree, error, [&](const kdrt_node_info &n) {
        if (!n.is_leaf) {
            report.inner_nodes += 1;
            return;
        }
        report.leaves += 1;
        report.empty_leaves += n.triangle_count == 0;
        report.references += n.triangle_count;
        report.leaves_by_depth[n.depth] += 1;
        report.leaves_by_triangles[n.triangle_count] += 1;
    });
    if (!walked) return false;
    const kdrt_tree_stats &s = report.stats;
    if (report.inner_nodes + report.leaves != s.nodes || report.leaves != s.leaves ||
        report.references != s.triangle_refs) {
        error = "the walk found " + std::to_string(report.inner_nodes + report.leaves) + " nodes, " +
                std::to_string(report.leaves) + " leaves, " + std::to_string(report.references) +
                " references; kdrt_tree_get_stats says " + std::to_string(s.nodes) + ", " + std::to_string(s.leaves) +
                ", " + std::to_string(s.triangle_refs);
        return false;
    }
    return true;
}

std::string report_text(const TreeReport &r)
{
    const kdrt_tree_stats &s = r.stats;
    const double per_triangle = s.triangles ? double(s.triangle_refs) / s.triangles : 0.0;
    std::string t;
    t += "mesh: " + r.mesh + " (" + r.source + ")\n";
    if (r.tree_file.empty())
        t += "builder: " + r.builder + ", leaf size " + std::to_string(r.leaf_size) + ", built in " +
             format("%.2f", r.build_ms) + " ms on 1 thread\n";
    else
        t += "builder: " + r.builder + ", leaf size " + std::to_string(r.leaf_size) + ", loaded from " + r.tree_file +
             " in " + format("%.2f", r.build_ms) + " ms (not built)\n";
    t += "triangles: " + std::to_string(s.triangles) + " in the tree, of " + std::to_string(r.input_triangles);
    if (r.tree_file.empty())
        t += " (left out: " + std::to_string(r.degenerate_triangles) + " zero-area, " +
             std::to_string(r.skipped_triangles) + " with a NaN or infinite corner)\n";
    else
        t += "\n";
    t += "nodes: " + std::to_string(s.nodes) + " (" + std::to_string(r.inner_nodes) + " inner, " +
         std::to_string(r.leaves) + " leaves of which " + std::to_string(r.empty_leaves) + " empty)\n";
    t += "depth: " + std::to_string(s.max_depth) + " (deepest leaf)\n";
    t += "references: " + std::to_string(s.triangle_refs) + ", " + format("%.3f", per_triangle) +
         " per triangle (triangles split across leaves are referred to by each)\n";
    t += "SAH cost: " + format("%.2f", s.sah_cost) + " (default costs: traversal " +
         format("%g", KDRT_DEFAULT_SAH_TRAVERSAL_COST) + ", intersection " +
         format("%g", KDRT_DEFAULT_SAH_INTERSECTION_COST) + ")\n";
    t += "bytes: " + std::to_string(s.bytes) + " (" + format("%.1f", double(s.bytes) / 1024.0) + " KiB, " +
         format("%.1f", s.triangles ? double(s.bytes) / s.triangles : 0.0) + " per triangle)\n";
    auto histogram = [&](const char *title, const char *key, const std::map<uint32_t, uint64_t> &h) {
        uint64_t most = 1;
        for (const auto &kv : h) most = std::max(most, kv.second);
        t += std::string(title) + ":\n";
        char line[160];
        std::snprintf(line, sizeof line, "  %9s %8s\n", key, "leaves");
        t += line;
        for (const auto &kv : h) {
            const int bar = int(std::lround(40.0 * double(kv.second) / double(most)));
            std::snprintf(line, sizeof line, "  %9u %8llu%s%s\n", kv.first, (unsigned long long)kv.second,
                          bar ? " " : "", std::string(size_t(bar), '#').c_str());
            t += line;
        }
    };
    histogram("leaves by depth", "depth", r.leaves_by_depth);
    histogram("leaves by triangle count", "triangles", r.leaves_by_triangles);
    if (!r.tree_file.empty()) t += saved_tree_text(r.tree_file, r.saved_info, false);
    return t;
}

std::string report_json(const TreeReport &r)
{
    const kdrt_tree_stats &s = r.stats;
    std::string j = "{\n";
    j += "  \"mesh\": " + json_string(r.mesh) + ",\n";
    j += "  \"source\": " + json_string(r.source) + ",\n";
    j += "  \"builder\": " + json_string(r.builder) + ",\n";
    j += "  \"leaf_size\": " + std::to_string(r.leaf_size) + ",\n";
    if (r.tree_file.empty()) {
        j += "  \"build_ms\": " + json_number(r.build_ms) + ",\n";
    } else {
        j += "  \"tree_file\": " + json_string(r.tree_file) + ",\n";
        j += "  \"load_ms\": " + json_number(r.build_ms) + ",\n";
    }
    j += "  \"input_triangles\": " + std::to_string(r.input_triangles) + ",\n";
    j += "  \"triangles\": " + std::to_string(s.triangles) + ",\n";
    j += "  \"degenerate_triangles\": " + std::to_string(r.degenerate_triangles) + ",\n";
    j += "  \"skipped_triangles\": " + std::to_string(r.skipped_triangles) + ",\n";
    j += "  \"nodes\": " + std::to_string(s.nodes) + ",\n";
    j += "  \"inner_nodes\": " + std::to_string(r.inner_nodes) + ",\n";
    j += "  \"leaves\": " + std::to_string(r.leaves) + ",\n";
    j += "  \"empty_leaves\": " + std::to_string(r.empty_leaves) + ",\n";
    j += "  \"max_depth\": " + std::to_string(s.max_depth) + ",\n";
    j += "  \"references\": " + std::to_string(s.triangle_refs) + ",\n";
    j += "  \"references_per_triangle\": " + json_number(s.triangles ? double(s.triangle_refs) / s.triangles : 0.0) + ",\n";
    j += "  \"sah_cost\": " + json_number(s.sah_cost) + ",\n";
    j += "  \"bytes\": " + std::to_string(s.bytes) + ",\n";
    j += "  \"bytes_per_triangle\": " + json_number(s.triangles ? double(s.bytes) / s.triangles : 0.0) + ",\n";
    auto histogram = [&](const char *name, const char *key, const std::map<uint32_t, uint64_t> &h, bool last) {
        j += std::string("  \"") + name + "\": [";
        bool first = true;
        for (const auto &kv : h) {
            j += std::string(first ? "" : ", ") + "{\"" + key + "\": " + std::to_string(kv.first) +
                 ", \"leaves\": " + std::to_string(kv.second) + "}";
            first = false;
        }
        j += last ? "]\n" : "],\n";
    };
    histogram("leaves_by_depth", "depth", r.leaves_by_depth, false);
    histogram("leaves_by_triangles", "triangles", r.leaves_by_triangles, r.tree_file.empty());
    if (!r.tree_file.empty()) j += "  \"saved_tree\": " + saved_tree_json(r.tree_file, r.saved_info, 2) + "\n";
    return j + "}\n";
}

const char *builder_name(kdrt_builder builder)
{
    return builder == KDRT_BUILDER_MEDIAN ? "median" : "sah";
}

const char *quality_name(kdrt_build_quality quality)
{
    return quality == KDRT_BUILD_QUALITY_FAST ? "fast" : quality == KDRT_BUILD_QUALITY_HIGH ? "high" : "medium";
}

namespace {

const char *intersector_name(kdrt_intersector intersector)
{
    return intersector == KDRT_INTERSECTOR_FAST ? "fast" : "watertight";
}

// The bounds' six floats, %.9g (each float's own value, read back the same).
std::string bounds_list(const kdrt_aabb &b)
{
    std::string t;
    for (int k = 0; k < 6; ++k) t += (k ? ", " : "") + format("%.9g", double(k < 3 ? b.min[k] : b.max[k - 3]));
    return t;
}

}  // namespace

std::string saved_tree_text(const std::string &path, const kdrt_saved_tree_info &info, bool header_only)
{
    const kdrt_build_options &o = info.options;
    const kdrt_tree_stats &s = info.stats;
    // Loaded over its mesh, the lines follow the walk's report, indented under the file's name.
    const std::string in = header_only ? "" : "  ";
    std::string t;
    t += "saved tree: " + path + " (" + std::to_string(info.size) + " bytes, format version " +
         std::to_string(info.version) + ")" + (header_only ? "" : ", its header:") + "\n";
    t += in + "meshes: " + std::to_string(info.meshes) + ", " + std::to_string(info.mesh_triangles) + " triangles\n";
    t += in + "built by: " + std::string(builder_name(o.builder)) +
         (o.builder == KDRT_BUILDER_MEDIAN ? std::string() : std::string(" ") + quality_name(o.quality) + " quality") +
         ", leaf size " + std::to_string(o.max_leaf_size) + ", depth limit " + std::to_string(info.depth_limit) +
         ", " + intersector_name(o.intersector) + " intersector" +
         (o.flags & KDRT_BUILD_SKIP_INVALID_TRIANGLES ? ", invalid triangles skipped" : "") + "\n";
    t += in + "triangles: " + std::to_string(s.triangles) + " in the tree\n";
    t += in + "nodes: " + std::to_string(s.nodes) + " (" + std::to_string(s.nodes - s.leaves) + " inner, " +
         std::to_string(s.leaves) + " leaves), " + std::to_string(s.blocks) + " blocks\n";
    t += in + "depth: " + std::to_string(s.max_depth) + " (deepest leaf)\n";
    t += in + "references: " + std::to_string(s.triangle_refs) + ", " +
         format("%.3f", s.triangles ? double(s.triangle_refs) / s.triangles : 0.0) + " per triangle\n";
    t += in + "bounds: " + bounds_list(info.bounds) + " (min x y z, max x y z)\n";
    if (header_only)
        t += "the header only: give the mesh it was saved over (kdrt-inspect MESH --tree FILE) to load the tree and walk it\n";
    return t;
}

std::string saved_tree_json(const std::string &path, const kdrt_saved_tree_info &info, int indent)
{
    const kdrt_build_options &o = info.options;
    const kdrt_tree_stats &s = info.stats;
    const std::string in(size_t(indent) + 2, ' ');
    std::string j = "{\n";
    j += in + "\"tree_file\": " + json_string(path) + ",\n";
    j += in + "\"bytes\": " + std::to_string(info.size) + ",\n";
    j += in + "\"version\": " + std::to_string(info.version) + ",\n";
    j += in + "\"meshes\": " + std::to_string(info.meshes) + ",\n";
    j += in + "\"mesh_triangles\": " + std::to_string(info.mesh_triangles) + ",\n";
    j += in + "\"builder\": " + json_string(builder_name(o.builder)) + ",\n";
    j += in + "\"quality\": " + json_string(quality_name(o.quality)) + ",\n";
    j += in + "\"leaf_size\": " + std::to_string(o.max_leaf_size) + ",\n";
    j += in + "\"depth_limit\": " + std::to_string(info.depth_limit) + ",\n";
    j += in + "\"intersector\": " + json_string(intersector_name(o.intersector)) + ",\n";
    j += in + "\"triangles\": " + std::to_string(s.triangles) + ",\n";
    j += in + "\"nodes\": " + std::to_string(s.nodes) + ",\n";
    j += in + "\"leaves\": " + std::to_string(s.leaves) + ",\n";
    j += in + "\"blocks\": " + std::to_string(s.blocks) + ",\n";
    j += in + "\"max_depth\": " + std::to_string(s.max_depth) + ",\n";
    j += in + "\"references\": " + std::to_string(s.triangle_refs) + ",\n";
    j += in + "\"bounds\": [";  // null for the empty box's infinities
    for (int k = 0; k < 6; ++k)
        j += (k ? ", " : "") + json_number(double(k < 3 ? info.bounds.min[k] : info.bounds.max[k - 3]));
    j += "]\n";
    return j + std::string(size_t(indent), ' ') + "}";
}

bool boxes_to_depth(const kdrt_tree *tree, uint32_t max_depth, std::vector<DepthBox> &out, std::string &error)
{
    out.clear();
    if (!for_each_node(tree, error, [&](const kdrt_node_info &n) {
            if (n.depth <= max_depth) out.push_back({n.bounds, n.depth});
        }))
        return false;
    std::stable_sort(out.begin(), out.end(), [](const DepthBox &a, const DepthBox &b) { return a.depth < b.depth; });
    return true;
}

bool write_boxes(const std::vector<DepthBox> &boxes, const std::string &path, std::string &error)
{
    const bool obj = ends_with(path, ".obj"), ply = ends_with(path, ".ply");
    if (!obj && !ply) {
        error = "cannot write '" + path + "': the boxes are written as .obj or .ply, by the name's extension";
        return false;
    }
    std::string text;
    char line[160];
    if (obj) {
        text = "# kdrt kd-tree boxes: 8 corners (v) and 12 edges (l) per box, shallowest first\n";
    } else {
        text = "ply\nformat ascii 1.0\ncomment kdrt kd-tree boxes: 8 corners and 12 edges per box\n";
        text += "element vertex " + std::to_string(boxes.size() * 8) + "\nproperty float x\nproperty float y\n"
                "property float z\nelement edge " + std::to_string(boxes.size() * 12) +
                "\nproperty int vertex1\nproperty int vertex2\nend_header\n";
    }
    for (const DepthBox &b : boxes) {
        double c[8][3];
        box_corners(b.box, c);
        for (auto &p : c) {
            std::snprintf(line, sizeof line, obj ? "v %.9g %.9g %.9g\n" : "%.9g %.9g %.9g\n", p[0], p[1], p[2]);
            text += line;
        }
    }
    for (size_t i = 0; i < boxes.size(); ++i) {
        if (obj) text += "g depth" + std::to_string(boxes[i].depth) + "\n";
        for (const auto &e : box_edges) {
            // OBJ counts vertices from 1, PLY from 0.
            const size_t a = i * 8 + size_t(e[0]) + (obj ? 1 : 0), b = i * 8 + size_t(e[1]) + (obj ? 1 : 0);
            std::snprintf(line, sizeof line, obj ? "l %zu %zu\n" : "%zu %zu\n", a, b);
            text += line;
        }
    }
    return common::write_file_atomically(path, text, error);
}

bool write_boxes_picture(const common::Mesh &mesh, const kdrt_tree *tree, const std::vector<DepthBox> &boxes, int width,
                         int height, const std::string &path, std::string &error)
{
    if (!ends_with(path, ".png")) {
        error = "cannot write '" + path + "': the picture is a PNG, named .png";
        return false;
    }
    // kdrt-render-mesh's camera: the box's centre seen from the front (+z), a little from the
    // right and above, far enough back that the bounding sphere fits.
    const kdrt_aabb box = kdrt_tree_bounds(tree);
    const Vec3 lo = {box.min[0], box.min[1], box.min[2]}, hi = {box.max[0], box.max[1], box.max[2]};
    const Vec3 center = 0.5 * (lo + hi);
    const double radius = std::max(0.5 * std::sqrt(dot(hi - lo, hi - lo)), 1e-30);
    const double tan_half = std::tan(0.5 * 35.0 * 3.14159265358979323846 / 180.0), aspect = double(width) / height;
    const double fit = std::min(tan_half, tan_half * aspect);
    const double distance = 1.05 * radius * std::sqrt(1.0 + 1.0 / (fit * fit));
    const Vec3 back = normalize(Vec3{0.35, 0.25, 1.0});
    const Vec3 eye = center + distance * back, forward = -1.0 * back;
    const Vec3 right = normalize(cross(forward, Vec3{0, 1, 0})), up = cross(right, forward);

    std::vector<double> rgb(size_t(width) * size_t(height) * 3);
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            const double sx = (2.0 * (x + 0.5) / width - 1.0) * tan_half * aspect;
            const double sy = (1.0 - 2.0 * (y + 0.5) / height) * tan_half;
            const Vec3 d = normalize(forward + sx * right + sy * up);
            kdrt_ray ray = {};  // tmin 0, and the walk starts at the root
            ray.org[0] = float(eye.x), ray.org[1] = float(eye.y), ray.org[2] = float(eye.z);
            ray.dir[0] = float(d.x), ray.dir[1] = float(d.y), ray.dir[2] = float(d.z);
            ray.tmax = INFINITY;
            kdrt_hit hit;
            double *px = &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
            px[0] = px[1] = px[2] = 0.97;  // a white page, so the boxes' colours read
            if (kdrt_intersect(tree, &ray, &hit)) {
                double p[3][3];
                mesh.corners(hit.triangle, p);
                const Vec3 a = {p[0][0], p[0][1], p[0][2]}, b = {p[1][0], p[1][1], p[1][2]}, c = {p[2][0], p[2][1], p[2][2]};
                const double shade = 0.15 + 0.75 * std::fabs(dot(normalize(cross(b - a, c - a)), d));  // headlight
                px[0] = px[1] = px[2] = shade;
            }
        }
    }
    // Edges: deepest first, so the shallow boxes lie on top; one colour per depth, blended.
    static const double palette[6][3] = {{0.85, 0.10, 0.10}, {0.95, 0.55, 0.05}, {0.15, 0.60, 0.15},
                                         {0.10, 0.45, 0.85}, {0.55, 0.25, 0.75}, {0.05, 0.65, 0.65}};
    auto project = [&](const double p[3], double &u, double &v) {
        const Vec3 q = Vec3{p[0], p[1], p[2]} - eye;
        const double z = dot(q, forward);
        if (!(z > 1e-9 * distance)) return false;  // behind the eye: not drawn (the camera sees the whole box)
        u = (dot(q, right) / (z * tan_half * aspect) + 1.0) * 0.5 * width;
        v = (1.0 - dot(q, up) / (z * tan_half)) * 0.5 * height;
        return true;
    };
    for (size_t i = boxes.size(); i-- > 0;) {
        const double *colour = palette[boxes[i].depth % 6];
        const double alpha = boxes[i].depth == 0 ? 1.0 : 0.8;
        double c[8][3];
        box_corners(boxes[i].box, c);
        for (const auto &e : box_edges) {
            double u0, v0, u1, v1;
            if (!project(c[e[0]], u0, v0) || !project(c[e[1]], u1, v1)) continue;
            const int steps = int(std::ceil(std::max(std::fabs(u1 - u0), std::fabs(v1 - v0)))) + 1;
            if (steps > 100000) continue;  // a degenerate projection; nothing sensible to draw
            for (int s = 0; s <= steps; ++s) {
                const double t = double(s) / steps;
                const int x = int(std::floor(u0 + t * (u1 - u0))), y = int(std::floor(v0 + t * (v1 - v0)));
                if (x < 0 || y < 0 || x >= width || y >= height) continue;
                double *px = &rgb[(size_t(y) * size_t(width) + size_t(x)) * 3];
                for (int k = 0; k < 3; ++k) px[k] = (1 - alpha) * px[k] + alpha * colour[k];
            }
        }
    }
    std::vector<unsigned char> bytes(rgb.size());
    for (size_t i = 0; i < rgb.size(); ++i) bytes[i] = (unsigned char)std::lround(255.0 * std::min(1.0, std::max(0.0, rgb[i])));
    std::string png;
    if (!stbi_write_png_to_func(append_png, &png, width, height, 3, bytes.data(), width * 3)) {
        error = "cannot encode the PNG (out of memory?)";
        return false;
    }
    return common::write_file_atomically(path, png, error);
}

}  // namespace kdrt_tools
