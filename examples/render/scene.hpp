// kdrt-render's scene model: exactly what the presets and scene files use, nothing more.
// Spheres, quads and triangle meshes (through one kdrt scene), sphere and quad lights, a pinhole
// camera; Phong, mirror and glass materials; the original's settings. Plain data: presets
// (presets.cpp) and scene files (scene_file.cpp) fill it, the renderer (render.cpp) reads it.
#pragma once

#include "common/mesh_io.hpp"  // common::Mesh
#include "common/vec3.hpp"     // common::Vec3

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace kr {

// The shared double vector (common/vec3.hpp), and its functions, as kr's own.
using common::Vec3;
using common::cross;
using common::dot;
using common::length;
using common::normalize;

// The original's global settings, by their names (--set KEY=VALUE, a scene file's "settings").
struct Settings {
    uint32_t nsamples = 1;          // NSAMPLES: jittered samples per pixel
    uint32_t max_bounces = 5;       // MAX_BOUNCES: mirror and glass depth
    uint32_t shadow_rays = 1;       // SHADOW_RAYS: 0 no shadows, 1 hard (light centre), >1 soft
    bool phong = true;              // PHONG: specular highlights (false: diffuse only)
    bool enable_mirror = true;      // ENABLE_MIRROR: false shades mirrors as Phong
    bool enable_glass = true;       // ENABLE_GLASS: false shades glass as Phong
    double air_index_medium = 1.0;  // AIR_INDEX_MEDIUM: the index at the bottom of every stack
    std::string mesh;               // MESH: the mesh the preset places ("" = the preset's own)
    bool enable_interpolation = true;  // ENABLE_INTERPOLATION: smooth vertex normals on meshes
    uint32_t max_leaf_size = 4;     // MAX_LEAF_SIZE: kd-tree leaf size (0 = no tree)
    bool enable_textures = true;    // ENABLE_TEXTURES: false uses the materials' plain colours
    bool fresnel = false;           // FRESNEL: glass reflects by Fresnel (false: pure refraction)
};

// A texture is an image (stb_image, sRGB file decoded to linear) or a procedural checkerboard.
struct Texture {
    std::string name;
    std::string file;                 // image path; empty for a checkerboard
    uint32_t width = 0, height = 0;   // the loaded image
    std::vector<float> rgb;           // linear, row-major from the top row
    Vec3 checker_a{0.9, 0.9, 0.9}, checker_b{0.1, 0.1, 0.1};
    double checker_scale = 8;         // squares per unit of (u, v)
};

enum class MaterialKind { phong, mirror, glass };

struct Material {
    std::string name;
    MaterialKind kind = MaterialKind::phong;
    // Phong: colour = ambient + sum over lights of diffuse * texture * max(0, n.l) + specular * max(0, r.v)^shininess.
    Vec3 ambient{0.05, 0.05, 0.05};
    Vec3 diffuse{0.8, 0.8, 0.8};
    Vec3 specular{0.2, 0.2, 0.2};
    double shininess = 32;
    int texture = -1;        // index into Scene::textures, -1 none; multiplies diffuse
    // Mirror: reflects `tint`; glass: refracts with index `ior` and filters by `tint`.
    double ior = 1.5;
    Vec3 tint{1, 1, 1};
};

struct Sphere {
    Vec3 center;
    double radius = 1;
    int material = 0;        // index into Scene::materials
};

// The parallelogram corner + s * edge_u + t * edge_v, s and t in [0, 1]; (s, t) are its texture
// coordinates; its front faces along cross(edge_u, edge_v) (both faces are lit).
struct Quad {
    Vec3 corner, edge_u, edge_v;
    int material = 0;
};

// A triangle mesh, read from `file` (anything Assimp reads) or generated, then placed: scaled so
// its bounding box's largest side is `size`, turned `rotate_y_degrees` about +y, and moved so the
// box's bottom centre sits at `position`.
struct MeshInstance {
    std::string file;        // "" keeps `mesh` as given (a generated stand-in)
    common::Mesh mesh;           // filled by the loader, in world space after placement
    std::string source;      // what was used, for the tool to say: a path, or "generated torus"
    Vec3 position;
    double size = 1;
    double rotate_y_degrees = 0;
    int material = 0;
};

// Hard shadows sample a light's centre, soft ones (SHADOW_RAYS > 1) points on its surface.
enum class LightKind { sphere, quad };

struct Light {
    LightKind kind = LightKind::sphere;
    Vec3 center;             // sphere
    double radius = 0.1;
    Vec3 corner, edge_u, edge_v;  // quad, as Quad
    Vec3 color{1, 1, 1};     // radiance times intensity
    // Lights are also seen by camera rays, as emitters of `color`.
};

struct Camera {
    Vec3 position{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
    double fov_degrees = 45;  // vertical
};

struct Scene {
    std::string name;        // preset name or scene file path
    Settings settings;
    Camera camera;
    Vec3 background{0, 0, 0};
    std::vector<Texture> textures;
    std::vector<Material> materials;
    std::vector<Sphere> spheres;
    std::vector<Quad> quads;
    std::vector<MeshInstance> meshes;
    std::vector<Light> lights;
};

// --set KEY=VALUE and a scene file's "settings": KEY is a Settings name as the original spelled it
// (NSAMPLES, MAX_BOUNCES, ...; case-insensitive), or GLASS_IOR, the index of every glass material
// (what the original's animation sweeps). Values: unsigned integers, numbers, true/false/1/0, or a
// mesh name or path for MESH. false with a message naming the key and what it expects.
bool apply_setting(Scene &scene, const std::string &key, const std::string &value, std::string &error);
// The setting names apply_setting takes, in the order --help lists them.
std::vector<std::string> setting_names();

// Loads and places every MeshInstance (file through Assimp, else the generated stand-in it holds),
// filling `mesh` and `source`. false with a message naming the file when one cannot be read.
bool load_meshes(Scene &scene, std::string &error);

}  // namespace kr
