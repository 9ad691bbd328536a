// kdrt-bench --scene: a kdrt_scene (meshes, or instances of trees) against one tree over the same
// triangles in world space. The worlds, the geometries that describe them to kdrt and Embree, the
// comparison of their answers and the CSV rows, kept apart from main() so the tests can check them.
#pragma once

#include "bench.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace kb {

// The mesh centred on the origin and scaled so its largest side is 1.
common::Mesh unit_sized(const common::Mesh &mesh);

// Vertex clustering: the mesh's vertices merged in the cells of a grid of cubes over its box (each
// cell's vertices become their mean), with the finest grid that leaves at most `target`
// triangles; triangles that lose a corner, or repeat another's corners, are dropped. target 0, or
// at least the mesh's count: the mesh as it is.
common::Mesh clustered(const common::Mesh &mesh, uint32_t target);

// A world of several meshes in the benchmark frame, once as one mesh (frame.geometry: make_scene's
// frame, the back wall's two triangles last) and once as the geometries of a kdrt_scene. Geometry
// IDs: the instances 0 to instances.size() - 1, then the mesh geometries, each a run of
// frame.geometry's triangles. The wall is always the last mesh geometry.
struct SceneLayout {
    std::string name;                  // "merged" or "field": the Scene column
    Scene frame;                       // the one mesh, the camera and make_scene's placement
    std::vector<common::Mesh> prototypes;  // field: what the instances place, in object space
    struct Placement {
        uint32_t prototype = 0;
        float transform[12];           // frame from object, kdrt_geometry.transform's layout
    };
    std::vector<Placement> instances;  // field: one per instance, ID = index
    // first[id]: the first triangle of geometry id in frame.geometry (instances, where their
    // triangles lie flattened, then the mesh geometries); a hit's triangle there is
    // first[hit.geometry] + hit.triangle.
    std::vector<uint32_t> first;
};

// merged: the meshes, unit_sized, set on a grid side by side (about ceil(sqrt(n)) to a row, the last
// row centred, 0.1 apart), as mesh geometries 0 .. n-1; the wall is geometry n.
SceneLayout merged_layout(const std::vector<common::Mesh> &meshes);
// field: `count` instances, instance i of meshes[i % n] (taken as they are, in object space),
// turned by a uniformly random rotation, scaled by 0.8 to 1.2 and placed in the cell of a grid
// (about sqrt(count) cells a side, `spacing` apart) with a random offset of up to 0.15 across and
// 0.5 in depth, all from `seed`; the wall is geometry `count`.
SceneLayout field_layout(const std::vector<common::Mesh> &meshes, uint32_t count, uint32_t seed, double spacing = 1);

// Mesh geometry id's run of frame.geometry's triangles, borrowing its buffers.
kdrt_triangles geometry_view(const SceneLayout &layout, uint32_t id);
// The layout's kdrt geometries, instance i of trees[layout.instances[i].prototype], mesh geometries
// borrowing frame.geometry's buffers.
std::vector<kdrt_geometry> kdrt_geometries(const SceneLayout &layout, const std::vector<kdrt_tree *> &trees);
// Triangles of the scene's own trees: the mesh geometries' and every prototype's once.
uint64_t stored_triangles(const SceneLayout &layout);

// Where a hit lies in the one mesh: first[hit.geometry] + hit.triangle (a one-tree query's hit has
// geometry 0: first {0}); KDRT_INVALID_ID for a miss.
uint32_t flat_triangle(const kdrt_hit &hit, const std::vector<uint32_t> &first);
// Rays whose answers differ. tolerance 0: exactly, a hit against a miss, another triangle, or
// another t, u or v bit for bit. Above 0: a hit against a miss, or hits on other triangles whose t
// differ by more than tolerance times the larger.
size_t count_scene_mismatches(const std::vector<kdrt_hit> &a, const std::vector<uint32_t> &a_first,
                              const std::vector<kdrt_hit> &b, const std::vector<uint32_t> &b_first, double tolerance);

// The median time of kdrt_scene_commit() over `times` commits, each after moving every instance of
// the layout (by 0.01 along x, and back for the next): the top level rebuilt. The scene ends as
// it began. A negative time when a move or a commit failed (error says which).
double median_commit_ms(kdrt_scene *scene, const SceneLayout &layout, unsigned times, std::string &error);

double median(std::vector<double> values);

// One row of the --scene CSV.
struct SceneRow {
    std::string scene;                 // merged, field
    std::string layout;                // merged or flattened (one tree), meshes or instanced (a scene)
    std::string query;                 // none (a NULL query), mask (kdrt_default_query()), filter
    std::string rays;                  // primary, diffuse
    size_t ray_count = 0;
    uint64_t triangles = 0;            // in the world, the wall included
    uint64_t stored_triangles = 0;     // in kdrt's trees (an instanced mesh once)
    uint32_t instances = 0;
    double build_ms = 0;               // the tree's or the scene's build; instanced: a top-level commit
    double trace_ms = 0;
    std::string versus;                // the row the ratio and the mismatches are against; empty: none
    double versus_trace_ms = 0;
    size_t mismatches = 0;
    bool embree = false;               // Embree's columns filled
    double embree_build_ms = 0, embree_trace_ms = 0;
    size_t embree_mismatches = 0;      // against the scene's one tree, with the field's tolerance
};
std::string scene_csv_header();
std::string scene_csv_row(const SceneRow &row);

}  // namespace kb
