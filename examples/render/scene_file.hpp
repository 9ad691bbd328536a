// kdrt-render's scene files: a user's own scene in YAML, read into the Scene model of scene.hpp.
//
// Format. One YAML document: a map of the sections below. camera is required, and at least one
// sphere, quad or mesh; the other sections are optional, and `spheres:` with nothing after it is
// an empty list. Vectors are [x, y, z] of finite numbers, colours [r, g, b] of numbers >= 0;
// numbers are plain (unquoted) YAML numbers, never .nan or .inf. Unknown or repeated keys are
// errors, so a typo is reported rather than ignored. Textures and materials have names, and are
// referred to by name from anywhere in the file (those names and the keys are case-sensitive;
// the values named from a list, such as a type or `generated: torus`, are taken in any case).
// Keys marked (required) must be there; the others default to the values in scene.hpp.
//
//   settings:    {NSAMPLES: 16, SHADOW_RAYS: 4, ...}   # the original's settings as --set takes
//                # them (kr::apply_setting, names in any case); applied after the materials, so
//                # GLASS_IOR sets the ior of every glass material
//   camera:      {position: [0, 1, 4], target: [0, 1, 0], up: [0, 1, 0], fov: 40}
//                # position, target (required, apart); up: not along the view, default [0, 1, 0];
//                # fov: vertical, in degrees, in (0, 180), default 45
//   background:  [0, 0, 0]                 # the colour of rays that leave the scene
//   textures:                              # name (required) and one of file or checker
//     - {name: wood, file: wood.png}       # an image, relative to this file; it must be readable
//                                          # here, the renderer decodes it
//     - {name: floor, checker: {a: [0.9, 0.9, 0.9], b: [0.1, 0.1, 0.1], scale: 8}}
//                                          # a, b: colours; scale > 0: squares per unit of (u, v)
//   materials:                             # name (required)
//     - {name: white, type: phong, ambient: [.05, .05, .05], diffuse: [.8, .8, .8],
//        specular: [.2, .2, .2], shininess: 32, texture: floor}    # texture multiplies diffuse
//     - {name: chrome, type: mirror, tint: [0.9, 0.9, 0.9]}
//     - {name: glass, type: glass, ior: 1.5, tint: [1, 1, 1]}
//                # type: phong (default), mirror or glass. Every type takes the Phong keys (used
//                # when ENABLE_MIRROR or ENABLE_GLASS is off); shininess >= 0; tint (a colour in
//                # [0, 1]) only mirror and glass; ior (0.001 to 100) only glass
//   spheres:     [{center: [0, 1, 0], radius: 0.5, material: glass}]   # all required, radius > 0
//   quads:       [{corner: [-1, 0, -1], edge_u: [0, 0, 2], edge_v: [2, 0, 0], material: white}]
//                # all required: corner + s edge_u + t edge_v, edges neither zero nor parallel
//   meshes:                                # material and one of file or generated (required)
//     - {file: bunny.ply, position: [0, 0, 0], size: 1, rotate_y: 30, material: white}
//     - {generated: torus, position: [0, 0.2, 0], size: 0.8, material: white}
//                # file: anything Assimp reads, relative to this file, readable (the renderer
//                # loads it); generated: torus, 9,216 triangles. Scaled so its largest side is
//                # size (> 0, default 1), turned rotate_y degrees about +y (default 0), its
//                # bounding box's bottom centre at position (default [0, 0, 0])
//   lights:                                # type (required): sphere or quad
//     - {type: sphere, center: [0, 1.9, 0], radius: 0.1, color: [1, 1, 1]}
//                # center (required), radius > 0 (default 0.1)
//     - {type: quad, corner: [-.2, 1.99, -.2], edge_u: [.4, 0, 0], edge_v: [0, 0, .4], color: [1, 1, 1]}
//                # corner, edge_u, edge_v (required) as for quads; color: default [1, 1, 1]
//
// Limits: a file of at most 64 MB, at most 65536 entries in each list, YAML nested at most 499
// deep (yaml-cpp's guard).
//
// Errors: false, `scene` untouched, and `error` one line naming the file, the 1-based line and
// what was expected, e.g.  scenes/box.yaml:12: sphere 'radius' must be a number > 0, got "big"
// YAML syntax errors carry yaml-cpp's line and message; a scene file that cannot be read is
// named with the system's reason (no line).
#pragma once

#include "scene.hpp"

#include <string>

namespace kr {

// Reads the scene file at `path` (relative paths inside it are taken from its folder). On success
// fills `scene` (its name is `path`, its meshes' `file` resolved paths, to be loaded by
// load_meshes) and returns true.
bool load_scene_file(const std::string &path, Scene &scene, std::string &error);

// The same from text already in memory: errors name `name_for_errors`, and relative texture and
// mesh paths are taken from `base_dir` ("" for the current folder).
bool parse_scene_text(const std::string &text, const std::string &name_for_errors, const std::string &base_dir,
                      Scene &scene, std::string &error);

}  // namespace kr
