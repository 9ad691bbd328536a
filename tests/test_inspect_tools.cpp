// kdrt-inspect's core (tools/tree_inspect.hpp): the statistics of a walk, the boxes' wireframe as
// Assimp reads it back, the picture, and outputs that cannot be written.
#include "test_support.hpp"
#include "tree_inspect.hpp"
#include "temp_dir.hpp"

#include <assimp/Importer.hpp>
#include <assimp/scene.h>
#include <catch2/catch.hpp>
#include <stb_image.h>

#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <dirent.h>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace {

using kt::TempDir;


using Corner = std::array<float, 3>;

// The corners of the boxes, as distinct positions.
std::set<Corner> corners_of(const std::vector<kdrt_tools::DepthBox> &boxes)
{
    std::set<Corner> out;
    for (const auto &b : boxes)
        for (int k = 0; k < 8; ++k)
            out.insert({k & 1 ? b.box.max[0] : b.box.min[0], k & 2 ? b.box.max[1] : b.box.min[1],
                        k & 4 ? b.box.max[2] : b.box.min[2]});
    return out;
}

kt::TreePtr sah_tree(const common::Mesh &mesh, uint32_t leaf_size)
{
    return kt::build(mesh, leaf_size, KDRT_BUILDER_SAH);
}

}  // namespace

TEST_CASE("inspect tools: the report's walk agrees with the stats and with itself", "[inspect][tools]") {
    const common::Mesh mesh = kt::sphere(24, 32, 1.0);
    for (kdrt_builder builder : {KDRT_BUILDER_MEDIAN, KDRT_BUILDER_SAH}) {
        kt::TreePtr tree = kt::build(mesh, 4, builder);
        kdrt_tools::TreeReport r;
        std::string error;
        REQUIRE(kdrt_tools::walk_tree(tree.get(), r, error));
        CHECK(r.inner_nodes + r.leaves == r.stats.nodes);
        CHECK(r.leaves == r.stats.leaves);
        uint64_t leaves = 0, refs = 0, by_depth = 0;
        for (const auto &kv : r.leaves_by_triangles) leaves += kv.second, refs += uint64_t(kv.first) * kv.second;
        for (const auto &kv : r.leaves_by_depth) by_depth += kv.second;
        CHECK(leaves == r.leaves);
        CHECK(by_depth == r.leaves);
        CHECK(refs == r.stats.triangle_refs);
        CHECK(r.leaves_by_depth.rbegin()->first == r.stats.max_depth);
        const auto empty = r.leaves_by_triangles.find(0);
        CHECK(r.empty_leaves == (empty == r.leaves_by_triangles.end() ? 0 : empty->second));
        const std::string text = kdrt_tools::report_text(r), json = kdrt_tools::report_json(r);
        CHECK(text.find("nodes: " + std::to_string(r.stats.nodes) + " (") != std::string::npos);
        CHECK(json.find("\"nodes\": " + std::to_string(r.stats.nodes) + ",") != std::string::npos);
        CHECK(json.find("\"empty_leaves\": " + std::to_string(r.empty_leaves) + ",") != std::string::npos);
    }
}

TEST_CASE("inspect tools: boxes down to a depth", "[inspect][tools]") {
    const common::Mesh mesh = kt::random_soup(300, 4);
    kt::TreePtr tree = sah_tree(mesh, 2);
    std::vector<kdrt_tools::DepthBox> boxes;
    std::string error;
    REQUIRE(kdrt_tools::boxes_to_depth(tree.get(), 0, boxes, error));
    REQUIRE(boxes.size() == 1);
    const kdrt_aabb bounds = kdrt_tree_bounds(tree.get());
    CHECK(std::memcmp(&boxes[0].box, &bounds, sizeof bounds) == 0);
    for (uint32_t depth : {1u, 3u, 64u}) {
        REQUIRE(kdrt_tools::boxes_to_depth(tree.get(), depth, boxes, error));
        size_t expected = 0;
        for (uint32_t i = 0; i < kdrt_tree_node_count(tree.get()); ++i) {
            kdrt_node_info n;
            REQUIRE(kdrt_tree_node(tree.get(), i, &n) == KDRT_SUCCESS);
            expected += n.depth <= depth;
        }
        CHECK(boxes.size() == expected);
        for (size_t i = 1; i < boxes.size(); ++i) CHECK(boxes[i - 1].depth <= boxes[i].depth);
    }
    CHECK(boxes.size() == kdrt_tree_node_count(tree.get()));  // depth 64: every node
}

TEST_CASE("inspect tools: the wireframes open in Assimp", "[inspect][tools]") {
    const common::Mesh mesh = kt::sphere(16, 24, 1.0);
    kt::TreePtr tree = sah_tree(mesh, 4);
    std::vector<kdrt_tools::DepthBox> boxes;
    std::string error;
    REQUIRE(kdrt_tools::boxes_to_depth(tree.get(), 3, boxes, error));
    REQUIRE(boxes.size() > 4);
    const std::set<Corner> corners = corners_of(boxes);
    TempDir dir;

    SECTION("OBJ: 12 line primitives a box over the boxes' corners") {
        const std::string path = dir.file("boxes.obj");
        REQUIRE(kdrt_tools::write_boxes(boxes, path, error));
        Assimp::Importer importer;
        const aiScene *scene = importer.ReadFile(path, 0);
        REQUIRE(scene != nullptr);
        size_t lines = 0;
        std::set<Corner> read;
        for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
            const aiMesh *am = scene->mMeshes[m];
            CHECK(am->mPrimitiveTypes == aiPrimitiveType_LINE);
            for (unsigned f = 0; f < am->mNumFaces; ++f) CHECK(am->mFaces[f].mNumIndices == 2);
            lines += am->mNumFaces;
            for (unsigned v = 0; v < am->mNumVertices; ++v)
                read.insert({am->mVertices[v].x, am->mVertices[v].y, am->mVertices[v].z});
        }
        CHECK(lines == 12 * boxes.size());
        CHECK(read == corners);
    }
    SECTION("PLY: 8 vertices a box as Assimp reads them, 12 edges a box as the file declares") {
        const std::string path = dir.file("boxes.ply");
        REQUIRE(kdrt_tools::write_boxes(boxes, path, error));
        Assimp::Importer importer;
        const aiScene *scene = importer.ReadFile(path, 0);
        REQUIRE(scene != nullptr);
        REQUIRE(scene->mNumMeshes == 1);
        const aiMesh *am = scene->mMeshes[0];
        CHECK(am->mNumVertices == 8 * boxes.size());
        std::set<Corner> read;
        for (unsigned v = 0; v < am->mNumVertices; ++v) read.insert({am->mVertices[v].x, am->mVertices[v].y, am->mVertices[v].z});
        CHECK(read == corners);
        // Assimp keeps no PLY edges (it reads faces only), so the edges are checked from the file:
        // each joins two corners of one box that differ on exactly one axis.
        std::ifstream in(path);
        std::string line;
        size_t vertices = 0, edges = 0;
        std::vector<Corner> v;
        while (std::getline(in, line) && line != "end_header") {
            std::istringstream words(line);
            std::string a, b;
            size_t n = 0;
            words >> a >> b >> n;
            if (a == "element" && b == "vertex") vertices = n;
            if (a == "element" && b == "edge") edges = n;
        }
        CHECK(vertices == 8 * boxes.size());
        CHECK(edges == 12 * boxes.size());
        for (size_t i = 0; i < vertices; ++i) {
            Corner c;
            in >> c[0] >> c[1] >> c[2];
            v.push_back(c);
        }
        size_t good = 0;
        for (size_t i = 0; i < edges; ++i) {
            size_t a = 0, b = 0;
            in >> a >> b;
            REQUIRE(a < vertices);
            REQUIRE(b < vertices);
            CHECK(a / 8 == b / 8);
            const int differ = (v[a][0] != v[b][0]) + (v[a][1] != v[b][1]) + (v[a][2] != v[b][2]);
            good += differ <= 1 && (a ^ b) != 0;
        }
        CHECK(good == edges);
        CHECK(bool(in));
    }
}

TEST_CASE("inspect tools: outputs that cannot be written leave no file", "[inspect][tools]") {
    const common::Mesh mesh = kt::sphere(8, 12, 1.0);
    kt::TreePtr tree = sah_tree(mesh, 4);
    std::vector<kdrt_tools::DepthBox> boxes;
    std::string error;
    REQUIRE(kdrt_tools::boxes_to_depth(tree.get(), 2, boxes, error));
    TempDir dir;

    CHECK_FALSE(kdrt_tools::write_boxes(boxes, "/nonexistent-dir/boxes.obj", error));
    CHECK(error.find("cannot write '/nonexistent-dir/boxes.obj': ") == 0);
    CHECK_FALSE(kdrt_tools::write_boxes(boxes, dir.file("boxes.stl"), error));
    CHECK(error.find("as .obj or .ply") != std::string::npos);
    CHECK_FALSE(kdrt_tools::write_boxes_picture(mesh, tree.get(), boxes, 32, 24, "/nonexistent-dir/boxes.png", error));
    CHECK(error.find("cannot write '/nonexistent-dir/boxes.png': ") == 0);

    // A directory where the file should go: refused, and the temporary file is gone.
    const std::string occupied = dir.file("taken.ply");
    REQUIRE(mkdir(occupied.c_str(), 0700) == 0);
    CHECK_FALSE(kdrt_tools::write_boxes(boxes, occupied, error));
    CHECK(error == "cannot write '" + occupied + "': it exists and is not a regular file");
    CHECK(dir.entries() == std::vector<std::string>{"taken.ply"});
}

TEST_CASE("inspect tools: the extension is read in any case", "[inspect][tools]") {
    const common::Mesh mesh = kt::sphere(8, 12, 1.0);
    kt::TreePtr tree = sah_tree(mesh, 4);
    std::vector<kdrt_tools::DepthBox> boxes;
    std::string error;
    REQUIRE(kdrt_tools::boxes_to_depth(tree.get(), 1, boxes, error));
    TempDir dir;
    const auto first_line = [](const std::string &path) {
        std::ifstream in(path);
        std::string line;
        std::getline(in, line);
        return line;
    };
    REQUIRE(kdrt_tools::write_boxes(boxes, dir.file("BOXES.PLY"), error));
    CHECK(first_line(dir.file("BOXES.PLY")) == "ply");
    REQUIRE(kdrt_tools::write_boxes(boxes, dir.file("boxes.Obj"), error));
    CHECK(first_line(dir.file("boxes.Obj")).rfind("# kdrt kd-tree boxes", 0) == 0);
    REQUIRE(kdrt_tools::write_boxes_picture(mesh, tree.get(), boxes, 8, 6, dir.file("boxes.PNG"), error));
    CHECK(first_line(dir.file("boxes.PNG")).rfind("\x89PNG", 0) == 0);
}

TEST_CASE("inspect tools: the picture shows the mesh and the root box", "[inspect][tools]") {
    const common::Mesh mesh = kt::sphere(16, 24, 1.0);
    kt::TreePtr tree = sah_tree(mesh, 4);
    std::vector<kdrt_tools::DepthBox> boxes;
    std::string error;
    REQUIRE(kdrt_tools::boxes_to_depth(tree.get(), 1, boxes, error));
    TempDir dir;
    const std::string path = dir.file("boxes.png");
    REQUIRE(kdrt_tools::write_boxes_picture(mesh, tree.get(), boxes, 160, 120, path, error));
    int w = 0, h = 0, channels = 0;
    unsigned char *px = stbi_load(path.c_str(), &w, &h, &channels, 3);
    REQUIRE(px != nullptr);
    CHECK(w == 160);
    CHECK(h == 120);
    size_t red = 0, grey = 0, page = 0;
    for (int i = 0; i < w * h; ++i) {
        const unsigned char *p = px + 3 * i;
        if (p[0] == 217 && p[1] == 26 && p[2] == 26) ++red;                    // the root box's colour
        else if (p[0] == 247 && p[1] == 247 && p[2] == 247) ++page;            // background
        else if (p[0] == p[1] && p[1] == p[2] && p[0] < 240) ++grey;           // the shaded sphere
    }
    stbi_image_free(px);
    CHECK(red > 100);   // 12 edges, several pixels each
    CHECK(grey > 1000); // the sphere fills a good part of the frame
    CHECK(page > 1000);
    CHECK(dir.entries() == std::vector<std::string>{"boxes.png"});  // no temporary left behind
}
