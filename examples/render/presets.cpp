// The original's presets, each a scene and its settings. Which preset gets which scene:
//
//   PHASE_1                   the single quad     textured, diffuse only, no shadows
//   PHASE_2_NO_SHADOWS        the spheres         Phong, no shadows
//   PHASE_2_HARD_SHADOWS      the spheres         Phong, 1 shadow ray (the light's centre)
//   PHASE_2_SOFT_SHADOWS      the spheres         Phong, 16 shadow rays, 4 samples a pixel
//   PHASE_3_REFLECTION        the spheres         as soft shadows, with the mirror sphere on
//   PHASE_3_NO_INTERPOLATION  the two meshes      flat triangles
//   PHASE_3_INTERPOLATION     the two meshes      smooth vertex normals
//   PHASE_4_REFRACTION        the glass sphere    over a checkerboard: the refraction test
//   PHASE_4_KDTREE            the two meshes      everything on, 4 samples, soft shadows
//   PICTURE                   the Cornell box     glass, mirror, textured sphere, mesh, quad light
//   BENCHMARKS                the two meshes      one primary and one shadow ray a pixel
//
// The spheres scene holds a mirror sphere from the start: the phase 1 and 2 presets turn
// ENABLE_MIRROR off, so it is shaded as Phong until PHASE_3_REFLECTION, as the original's
// phases added features to one scene.
#include "render.hpp"

#include <cctype>

namespace kr {
namespace {

int add_checker(Scene &scene, const std::string &name, Vec3 a, Vec3 b, double scale)
{
    Texture t;
    t.name = name;
    t.checker_a = a;
    t.checker_b = b;
    t.checker_scale = scale;
    scene.textures.push_back(t);
    return int(scene.textures.size()) - 1;
}

int add_phong(Scene &scene, const std::string &name, Vec3 diffuse, int texture = -1, Vec3 specular = {0.3, 0.3, 0.3},
              double shininess = 48)
{
    Material m;
    m.name = name;
    m.kind = MaterialKind::phong;
    m.ambient = 0.08 * diffuse;
    m.diffuse = diffuse;
    m.specular = specular;
    m.shininess = shininess;
    m.texture = texture;
    scene.materials.push_back(m);
    return int(scene.materials.size()) - 1;
}

int add_mirror(Scene &scene, Vec3 tint)
{
    Material m;
    m.name = "mirror";
    m.kind = MaterialKind::mirror;
    m.diffuse = {0.6, 0.6, 0.65};  // what ENABLE_MIRROR=false shows
    m.ambient = 0.08 * m.diffuse;
    m.tint = tint;
    scene.materials.push_back(m);
    return int(scene.materials.size()) - 1;
}

int add_glass(Scene &scene, double ior, Vec3 tint)
{
    Material m;
    m.name = "glass";
    m.kind = MaterialKind::glass;
    m.diffuse = {0.5, 0.6, 0.7};  // what ENABLE_GLASS=false shows
    m.ambient = 0.08 * m.diffuse;
    m.ior = ior;
    m.tint = tint;
    m.specular = {0.6, 0.6, 0.6};
    m.shininess = 96;
    scene.materials.push_back(m);
    return int(scene.materials.size()) - 1;
}

void add_quad(Scene &scene, Vec3 corner, Vec3 edge_u, Vec3 edge_v, int material)
{
    Quad q;
    q.corner = corner, q.edge_u = edge_u, q.edge_v = edge_v, q.material = material;
    scene.quads.push_back(q);
}

void add_sphere(Scene &scene, Vec3 center, double radius, int material)
{
    Sphere s;
    s.center = center, s.radius = radius, s.material = material;
    scene.spheres.push_back(s);
}

void add_sphere_light(Scene &scene, Vec3 center, double radius, Vec3 color)
{
    Light l;
    l.kind = LightKind::sphere;
    l.center = center, l.radius = radius, l.color = color;
    scene.lights.push_back(l);
}

void add_mesh(Scene &scene, const std::string &file, Vec3 position, double size, double rotate_y, int material)
{
    MeshInstance m;
    m.file = file;  // a name in the mesh folder; load_meshes falls back to a torus without it
    m.position = position, m.size = size, m.rotate_y_degrees = rotate_y, m.material = material;
    scene.meshes.push_back(m);
}

// A textured quad seen at an angle, lit by a small sphere light in front of it.
void single_quad(Scene &scene)
{
    scene.camera = {{0, 0.6, 4}, {0, 0, 0}, {0, 1, 0}, 40};
    scene.background = {0.05, 0.05, 0.07};
    const int checker = add_checker(scene, "quad checker", {0.95, 0.8, 0.2}, {0.15, 0.25, 0.7}, 6);
    const int mat = add_phong(scene, "quad", {1, 1, 1}, checker);
    // Turned 30 degrees about y and tipped back, so its shading varies across it.
    add_quad(scene, {-1.3, -1.0, 0.5}, {2.25, 0, -1.3}, {0, 2.0, -0.5}, mat);
    add_sphere_light(scene, {-0.8, 1.2, 2.0}, 0.12, {1.1, 1.1, 1.1});
}

// Three textured spheres and a mirror sphere on a checkered floor, a sphere light above.
void spheres(Scene &scene)
{
    scene.camera = {{0, 1.6, 6.5}, {0, 0.6, 0}, {0, 1, 0}, 40};
    scene.background = {0.25, 0.3, 0.4};
    const int floor_tex = add_checker(scene, "floor checker", {0.85, 0.85, 0.85}, {0.25, 0.25, 0.25}, 8);
    const int red_tex = add_checker(scene, "red checker", {0.9, 0.2, 0.15}, {0.95, 0.9, 0.8}, 8);
    const int green_tex = add_checker(scene, "green checker", {0.2, 0.75, 0.3}, {0.1, 0.2, 0.1}, 12);
    const int blue_tex = add_checker(scene, "blue checker", {0.2, 0.35, 0.9}, {0.9, 0.9, 0.3}, 6);
    add_quad(scene, {-4, 0, 3}, {8, 0, 0}, {0, 0, -8}, add_phong(scene, "floor", {1, 1, 1}, floor_tex, {0.1, 0.1, 0.1}));
    add_sphere(scene, {-1.6, 0.7, 0.3}, 0.7, add_phong(scene, "red", {1, 1, 1}, red_tex));
    add_sphere(scene, {0.0, 0.9, -0.6}, 0.9, add_mirror(scene, {0.9, 0.9, 0.9}));
    add_sphere(scene, {1.6, 0.6, 0.4}, 0.6, add_phong(scene, "green", {1, 1, 1}, green_tex));
    add_sphere(scene, {0.3, 0.35, 1.4}, 0.35, add_phong(scene, "blue", {1, 1, 1}, blue_tex));
    add_sphere_light(scene, {2.0, 4.0, 2.5}, 0.4, {1.0, 0.97, 0.9});
}

// Two meshes standing before a checkered wall, on a plain floor.
void two_meshes(Scene &scene)
{
    scene.camera = {{0, 1.1, 4.2}, {0, 0.55, 0}, {0, 1, 0}, 38};
    scene.background = {0.2, 0.2, 0.25};
    const int wall_tex = add_checker(scene, "wall checker", {0.8, 0.75, 0.65}, {0.45, 0.2, 0.15}, 10);
    add_quad(scene, {-3, 0, -1.2}, {6, 0, 0}, {0, 3, 0}, add_phong(scene, "wall", {1, 1, 1}, wall_tex, {0, 0, 0}));
    add_quad(scene, {-3, 0, 2.5}, {6, 0, 0}, {0, 0, -3.7}, add_phong(scene, "floor", {0.7, 0.7, 0.7}, -1, {0, 0, 0}));
    // The first mesh is the one MESH replaces; the second stays (its own stand-in without meshes).
    add_mesh(scene, "stanford-bunny", {-0.7, 0, 0.1}, 1.15, 0, add_phong(scene, "gold", {0.85, 0.65, 0.25}));
    add_mesh(scene, "spot", {0.75, 0, 0.2}, 1.1, 145, add_phong(scene, "cow", {0.6, 0.65, 0.9}));
    add_sphere_light(scene, {-1.5, 3.0, 3.0}, 0.3, {1, 1, 1});
}

// A glass sphere hovering over a checkerboard floor: the floor seen through it is inverted and
// magnified by the index of refraction (the original's IOR animation sweeps it).
void refraction(Scene &scene)
{
    scene.camera = {{0, 2.2, 5.5}, {0, 0.9, 0}, {0, 1, 0}, 38};
    scene.background = {0.55, 0.65, 0.8};
    const int checker = add_checker(scene, "floor checker", {0.9, 0.9, 0.9}, {0.1, 0.1, 0.1}, 10);
    add_quad(scene, {-5, 0, 4}, {10, 0, 0}, {0, 0, -10}, add_phong(scene, "floor", {1, 1, 1}, checker, {0, 0, 0}));
    add_sphere(scene, {0, 1.1, 0}, 1.0, add_glass(scene, 1.5, {1, 1, 1}));
    add_sphere_light(scene, {3.0, 6.0, 4.0}, 0.5, {1, 1, 1});
}

// The Cornell box: red left wall, green right, white others, a quad light under the ceiling; a
// glass sphere, a mirror sphere, a textured sphere and a mesh.
void cornell_box(Scene &scene)
{
    scene.camera = {{0, 1, 3.9}, {0, 1, 0}, {0, 1, 0}, 38};
    scene.background = {0, 0, 0};
    const Vec3 none{0, 0, 0};
    const int white = add_phong(scene, "white", {0.75, 0.75, 0.75}, -1, none);
    const int red = add_phong(scene, "red", {0.7, 0.12, 0.1}, -1, none);
    const int green = add_phong(scene, "green", {0.15, 0.6, 0.15}, -1, none);
    add_quad(scene, {-1, 0, 1}, {2, 0, 0}, {0, 0, -2}, white);     // floor
    add_quad(scene, {-1, 2, -1}, {2, 0, 0}, {0, 0, 2}, white);     // ceiling
    add_quad(scene, {-1, 0, -1}, {2, 0, 0}, {0, 2, 0}, white);     // back
    add_quad(scene, {-1, 0, 1}, {0, 0, -2}, {0, 2, 0}, red);       // left
    add_quad(scene, {1, 0, -1}, {0, 0, 2}, {0, 2, 0}, green);      // right
    const int checker = add_checker(scene, "ball checker", {0.95, 0.85, 0.3}, {0.2, 0.3, 0.8}, 8);
    add_sphere(scene, {0.05, 0.3, 0.55}, 0.3, add_glass(scene, 1.5, {1, 1, 1}));
    add_sphere(scene, {-0.5, 0.4, -0.45}, 0.4, add_mirror(scene, {0.92, 0.92, 0.92}));
    add_sphere(scene, {0.55, 0.25, -0.55}, 0.25, add_phong(scene, "ball", {1, 1, 1}, checker));
    add_mesh(scene, "stanford-bunny", {-0.55, 0, 0.35}, 0.6, 20, add_phong(scene, "bunny", {0.8, 0.8, 0.8}));
    Light light;
    light.kind = LightKind::quad;
    light.corner = {-0.3, 1.995, -0.3};
    light.edge_u = {0.6, 0, 0};
    light.edge_v = {0, 0, 0.6};
    light.color = {1.1, 1.05, 0.95};
    scene.lights.push_back(light);
}

std::string upper(std::string s)
{
    for (char &c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

}  // namespace

std::vector<std::string> preset_names()
{
    return {"PHASE_1",
            "PHASE_2_NO_SHADOWS",
            "PHASE_2_HARD_SHADOWS",
            "PHASE_2_SOFT_SHADOWS",
            "PHASE_3_REFLECTION",
            "PHASE_3_NO_INTERPOLATION",
            "PHASE_3_INTERPOLATION",
            "PHASE_4_REFRACTION",
            "PHASE_4_KDTREE",
            "PICTURE",
            "BENCHMARKS"};
}

bool make_preset(const std::string &name, Scene &scene, std::string &error)
{
    const std::string n = upper(name);
    scene = Scene();
    scene.name = n;
    Settings &s = scene.settings;
    if (n == "PHASE_1") {
        single_quad(scene);
        s.phong = false, s.shadow_rays = 0, s.enable_mirror = false, s.enable_glass = false;
    } else if (n == "PHASE_2_NO_SHADOWS" || n == "PHASE_2_HARD_SHADOWS" || n == "PHASE_2_SOFT_SHADOWS" ||
               n == "PHASE_3_REFLECTION") {
        spheres(scene);
        s.enable_mirror = n == "PHASE_3_REFLECTION";
        s.enable_glass = false;
        s.shadow_rays = n == "PHASE_2_NO_SHADOWS" ? 0 : n == "PHASE_2_HARD_SHADOWS" ? 1 : 16;
        s.nsamples = s.shadow_rays > 1 ? 4 : 1;
    } else if (n == "PHASE_3_NO_INTERPOLATION" || n == "PHASE_3_INTERPOLATION") {
        two_meshes(scene);
        s.enable_interpolation = n == "PHASE_3_INTERPOLATION";
    } else if (n == "PHASE_4_REFRACTION") {
        refraction(scene);
        s.nsamples = 4, s.max_bounces = 8;
    } else if (n == "PHASE_4_KDTREE") {
        two_meshes(scene);
        s.nsamples = 4, s.shadow_rays = 8;
    } else if (n == "PICTURE") {
        cornell_box(scene);
        s.nsamples = 8, s.shadow_rays = 4, s.max_bounces = 8, s.fresnel = true;
    } else if (n == "BENCHMARKS") {
        two_meshes(scene);
        s.enable_textures = false;
    } else {
        std::string list;
        for (const std::string &p : preset_names()) list += (list.empty() ? "" : ", ") + p;
        error = "unknown preset '" + name + "' (presets: " + list + ")";
        return false;
    }
    return true;
}

}  // namespace kr
