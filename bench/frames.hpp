// kdrt-bench --scene frames: a game's frames, kdrt beside Embree. The world (a static level,
// moving instances and one deforming mesh), where everything is in each frame, the camera's rays
// and the CSV rows, kept apart from main() so the tests can check them (bench/README.md, "Frames").
#pragma once

#include "bench.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace kb {

// Geometry IDs: the instances 0 .. movers.size() - 1, then the level's meshes, then the deforming
// mesh (an instance of its own tree, rebuilt every frame).
struct FramesWorld {
    std::vector<common::Mesh> prototypes;  // what the instances place, in object space
    struct Mover {
        uint32_t prototype = 0;
        double base[3] = {0, 0, 0};   // the centre it moves around
        double turn[9];               // its own random rotation, row-major
        double scale = 1;
        double phase = 0, speed = 1;  // along its circle
    };
    std::vector<Mover> movers;
    std::vector<common::Mesh> level;  // in world space: the floor, the wall, then the statues
    common::Mesh deforming;           // at rest, in object space (unit-sized)
    float deforming_transform[12];    // world from object
    double half = 1;                  // the field's half width
    float eye[3], forward[3], right[3], up[3];  // the camera: up and right scaled by the view's half size
    float light[3];                   // the point light of the shadow rays
    // first[id]: where geometry id's triangles would lie in one list of them all, so that
    // first[hit.geometry] + hit.triangle names a triangle of the world (count_scene_mismatches).
    std::vector<uint32_t> first;

    uint32_t level_id(uint32_t k) const { return uint32_t(movers.size()) + k; }
    uint32_t deforming_id() const { return uint32_t(movers.size() + level.size()); }
};

// A field of `count` instances of the prototypes (instance i of prototypes[i % n], a random
// rotation and a scale of 0.8 to 1.2, seeded), each at the centre of a cell of a grid of pitch 1.5
// on a floor; behind the field the statues (each a mesh of `statues`, unit_sized, whole) and the
// deforming mesh (unit_sized) in a row, each as tall as 0.9 of the field's half width; a wall
// behind them; the camera above the front edge looking over the field; the light above it.
FramesWorld frames_world(const std::vector<common::Mesh> &prototypes, const std::vector<common::Mesh> &statues,
                         const common::Mesh &deforming, uint32_t count, uint32_t seed);

// Instance i's transform (world from object, kdrt_geometry.transform's layout) at `frame`: frame
// 0 is where the world starts; from one frame to the next every instance moves along a circle of
// radius 0.25 around its base, bobs up and down and turns about the vertical.
void mover_transform(const FramesWorld &world, uint32_t i, unsigned frame, float out[12]);

// The deforming mesh's vertices at `frame` (3 floats a vertex, 4 floats of padding after them for
// Embree's 16-byte loads): every vertex displaced by a travelling wave of amplitude 0.02.
void deformed_positions(const FramesWorld &world, unsigned frame, std::vector<float> &out);

// One primary ray a pixel centre (row-major), from the camera, tmin 0, tmax infinity.
std::vector<kdrt_ray> frames_camera_rays(const FramesWorld &world, unsigned width, unsigned height);

// One row of the --scene frames CSV: a phase's medians over the frames of a count, thread count
// and variant.
struct FramesRow {
    std::string phase;            // move, commit, rebuild, primary, shadow, frame
    uint32_t instances = 0;
    unsigned threads = 1;
    std::string variant;          // kdrt's quality of the deforming mesh's build: fast, medium
    std::vector<double> kdrt_ms;  // a time per frame
    bool embree = false;
    std::vector<double> embree_ms;
    std::string embree_quality;   // low, medium
    uint64_t count = 0;           // what the phase handles a frame: instances, triangles, rays (the median)
    bool compared = false;        // primary and shadow rows with Embree: the answers compared
    uint64_t mismatches = 0, compared_rays = 0;  // summed over the frames
};
std::string frames_csv_header();
std::string frames_csv_row(const FramesRow &row);

}  // namespace kb
