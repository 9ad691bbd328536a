// kdrt-render's YAML scene files: good files give exactly the model they describe; every kind of
// mistake gives one line naming the file and the line, and leaves the caller's Scene as it was.
#include <catch2/catch.hpp>  // main() is kdrt_catch_main's (tests/CMakeLists.txt)

#include "scene_file.hpp"
#include "temp_dir.hpp"

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace fs = std::filesystem;
using kr::Scene;

namespace {

using kt::TempDir;


// What the caller had before a failed read; it must still be there afterwards.
Scene callers_scene()
{
    Scene s;
    s.name = "the caller's scene";
    s.spheres.push_back({});
    s.spheres.back().radius = 42;
    return s;
}

void check_untouched(const Scene &s)
{
    CHECK(s.name == "the caller's scene");
    REQUIRE(s.spheres.size() == 1);
    CHECK(s.spheres[0].radius == 42);
    CHECK(s.materials.empty());
    CHECK(s.settings.nsamples == 1);
}

bool same(kr::Vec3 a, kr::Vec3 b) { return a.x == b.x && a.y == b.y && a.z == b.z; }

// The smallest good scene; error tests change one thing in it or add to it.
const std::string camera_line = "camera: {position: [0, 0, 5], target: [0, 0, 0]}\n";
const std::string minimal = camera_line +
                            "materials:\n"
                            "  - {name: white}\n"
                            "spheres:\n"
                            "  - {center: [0, 0, 0], radius: 1, material: white}\n";

// Parses `text` as "bad.yaml" (relative paths from `dir`) and checks the error starts with
// "bad.yaml:LINE: " and contains `expected`.
void check_error(const std::string &text, int line, const std::string &expected, const std::string &dir = "")
{
    Scene scene = callers_scene();
    std::string error;
    INFO("text:\n" << text);
    CHECK_FALSE(kr::parse_scene_text(text, "bad.yaml", dir, scene, error));
    INFO("error: " << error);
    CHECK(error.rfind("bad.yaml:" + std::to_string(line) + ": ", 0) == 0);
    CHECK(error.find(expected) != std::string::npos);
    CHECK(error.find('\n') == std::string::npos);
    check_untouched(scene);
}

Scene parse_good(const std::string &text, const std::string &dir = "")
{
    Scene scene;
    std::string error;
    INFO("text:\n" << text);
    const bool ok = kr::parse_scene_text(text, "good.yaml", dir, scene, error);
    INFO("error: " << error);
    REQUIRE(ok);
    CHECK(error.empty());
    return scene;
}

}  // namespace

TEST_CASE("the shipped Cornell box reads as the scene it describes", "[scene_file]")
{
    const std::string path = std::string(KDRT_SCENES_DIR) + "/cornell.yaml";
    Scene scene = callers_scene();
    std::string error;
    REQUIRE(kr::load_scene_file(path, scene, error));
    CHECK(scene.name == path);
    CHECK(scene.settings.nsamples == 16);
    CHECK(scene.settings.shadow_rays == 8);
    CHECK(scene.settings.max_bounces == 8);
    CHECK(same(scene.camera.position, {0, 1, 3.6}));
    CHECK(same(scene.camera.target, {0, 1, 0}));
    CHECK(scene.camera.fov_degrees == 40);

    REQUIRE(scene.textures.size() == 1);
    CHECK(scene.textures[0].name == "checks");
    CHECK(scene.textures[0].file.empty());
    CHECK(same(scene.textures[0].checker_b, {0.15, 0.15, 0.6}));
    CHECK(scene.textures[0].checker_scale == 8);

    REQUIRE(scene.materials.size() == 7);
    CHECK(scene.materials[1].name == "red");
    CHECK(same(scene.materials[1].diffuse, {0.75, 0.1, 0.1}));
    CHECK(scene.materials[3].shininess == 64);
    CHECK(scene.materials[4].texture == 0);
    CHECK(scene.materials[5].kind == kr::MaterialKind::mirror);
    CHECK(same(scene.materials[5].tint, {0.9, 0.9, 0.9}));
    CHECK(scene.materials[6].kind == kr::MaterialKind::glass);
    CHECK(scene.materials[6].ior == 1.5);

    REQUIRE(scene.quads.size() == 5);
    CHECK(scene.quads[3].material == 1);  // left wall: red
    CHECK(scene.quads[4].material == 2);  // right wall: green
    for (const kr::Quad &q : scene.quads) {
        // Every wall faces into the box: its normal points towards the box's centre.
        const kr::Vec3 centre{0, 1, 0}, middle = q.corner + 0.5 * (q.edge_u + q.edge_v);
        CHECK(kr::dot(kr::cross(q.edge_u, q.edge_v), centre - middle) > 0);
    }
    REQUIRE(scene.spheres.size() == 3);
    CHECK(same(scene.spheres[0].center, {0.45, 0.35, 0.3}));
    CHECK(scene.spheres[0].radius == 0.35);
    CHECK(scene.spheres[0].material == 6);  // glass
    CHECK(scene.spheres[1].material == 5);  // chrome

    REQUIRE(scene.meshes.size() == 1);
    const kr::MeshInstance &torus = scene.meshes[0];
    CHECK(torus.file.empty());
    CHECK(torus.source == "generated torus");
    CHECK(torus.mesh.triangle_count() == 96 * 48 * 2);
    CHECK(same(torus.position, {0.35, 0, -0.5}));
    CHECK(torus.size == 0.7);
    CHECK(torus.rotate_y_degrees == 30);
    CHECK(torus.material == 3);  // gold

    REQUIRE(scene.lights.size() == 1);
    CHECK(scene.lights[0].kind == kr::LightKind::quad);
    CHECK(same(scene.lights[0].corner, {-0.25, 1.99, -0.25}));
    CHECK(scene.lights[0].edge_u.y == 0);
    CHECK(kr::cross(scene.lights[0].edge_u, scene.lights[0].edge_v).y < 0);  // faces down, into the box
}

TEST_CASE("the shipped refraction scene reads as the scene it describes", "[scene_file]")
{
    Scene scene;
    std::string error;
    REQUIRE(kr::load_scene_file(std::string(KDRT_SCENES_DIR) + "/refraction.yaml", scene, error));
    CHECK(scene.settings.nsamples == 4);
    CHECK(scene.settings.shadow_rays == 1);
    CHECK(same(scene.camera.up, {0, 1, 0}));  // the default
    CHECK(same(scene.background, {0.6, 0.75, 0.9}));
    REQUIRE(scene.materials.size() == 2);
    CHECK(scene.materials[0].kind == kr::MaterialKind::phong);  // the default type
    CHECK(scene.materials[0].texture == 0);
    CHECK(scene.materials[1].kind == kr::MaterialKind::glass);
    REQUIRE(scene.quads.size() == 1);
    CHECK(same(scene.quads[0].corner, {-4, 0, -4}));
    CHECK(scene.quads[0].material == 0);
    REQUIRE(scene.spheres.size() == 1);
    CHECK(scene.spheres[0].material == 1);
    REQUIRE(scene.lights.size() == 1);
    CHECK(scene.lights[0].kind == kr::LightKind::sphere);
    CHECK(same(scene.lights[0].center, {2, 5, 3}));
    CHECK(scene.lights[0].radius == 0.3);
    CHECK(scene.meshes.empty());
}

TEST_CASE("every key of the format lands in its field", "[scene_file]")
{
    TempDir dir;
    dir.write("maps/wood.png", "not decoded here");
    dir.write("models/thing.obj", "v 0 0 0\n");
    const Scene s = parse_good(
        // settings first: GLASS_IOR still reaches the glass defined below it
        "settings: {nsamples: 3, MAX_BOUNCES: 2, SHADOW_RAYS: 0, PHONG: false, FRESNEL: true, GLASS_IOR: 1.33}\n"
        "camera: {position: [1, 2, 3], target: [0, 1, 0], up: [0, 0, 1], fov: 60}\n"
        "background: [0.1, 0.2, 0.3]\n"
        "textures:\n"
        "  - {name: wood, file: maps/wood.png}\n"
        "  - {name: board, checker: {a: [1, 0, 0], b: [0, 0, 1], scale: 2.5}}\n"
        "materials:\n"
        "  - {name: m, type: phong, ambient: [0.1, 0.1, 0.1], diffuse: [0.5, 0.4, 0.3], specular: [1, 1, 1],"
        " shininess: 7, texture: board}\n"
        "  - {name: g, type: glass, ior: 2.4, tint: [0.5, 1, 1]}\n"
        "  - {name: chrome, type: mirror}\n"
        "spheres:\n"
        "  - {center: [1e-3, -2, 3.5], radius: 0.25, material: g}\n"
        "quads:\n"
        "  - {corner: [0, 0, 0], edge_u: [1, 0, 0], edge_v: [0, 1, 0], material: chrome}\n"
        "meshes:\n"
        "  - {file: models/thing.obj, position: [0, 1, 0], size: 2, rotate_y: -45, material: m}\n"
        "lights:\n"
        "  - {type: sphere, center: [0, 5, 0]}\n"
        "  - {type: quad, corner: [0, 4, 0], edge_u: [1, 0, 0], edge_v: [0, 0, 1], color: [2, 3, 4]}\n",
        dir.path.string());
    CHECK(s.name == "good.yaml");
    CHECK(s.settings.nsamples == 3);
    CHECK(s.settings.max_bounces == 2);
    CHECK(s.settings.shadow_rays == 0);
    CHECK_FALSE(s.settings.phong);
    CHECK(s.settings.fresnel);
    CHECK(same(s.camera.position, {1, 2, 3}));
    CHECK(same(s.camera.up, {0, 0, 1}));
    CHECK(s.camera.fov_degrees == 60);
    CHECK(same(s.background, {0.1, 0.2, 0.3}));

    REQUIRE(s.textures.size() == 2);
    CHECK(s.textures[0].file == (dir.path / "maps" / "wood.png").string());
    CHECK(s.textures[0].rgb.empty());  // images are the renderer's to load
    CHECK(s.textures[1].file.empty());
    CHECK(same(s.textures[1].checker_a, {1, 0, 0}));
    CHECK(s.textures[1].checker_scale == 2.5);

    REQUIRE(s.materials.size() == 3);
    CHECK(same(s.materials[0].ambient, {0.1, 0.1, 0.1}));
    CHECK(same(s.materials[0].diffuse, {0.5, 0.4, 0.3}));
    CHECK(same(s.materials[0].specular, {1, 1, 1}));
    CHECK(s.materials[0].shininess == 7);
    CHECK(s.materials[0].texture == 1);
    CHECK(s.materials[1].ior == 1.33);  // GLASS_IOR overrode 2.4
    CHECK(same(s.materials[1].tint, {0.5, 1, 1}));
    CHECK(s.materials[2].kind == kr::MaterialKind::mirror);
    CHECK(s.materials[2].texture == -1);

    REQUIRE(s.spheres.size() == 1);
    CHECK(same(s.spheres[0].center, {1e-3, -2, 3.5}));
    CHECK(s.spheres[0].material == 1);
    REQUIRE(s.quads.size() == 1);
    CHECK(same(s.quads[0].edge_v, {0, 1, 0}));
    CHECK(s.quads[0].material == 2);
    REQUIRE(s.meshes.size() == 1);
    CHECK(s.meshes[0].file == (dir.path / "models" / "thing.obj").string());
    CHECK(s.meshes[0].mesh.triangle_count() == 0);  // Assimp loads it later
    CHECK(s.meshes[0].size == 2);
    CHECK(s.meshes[0].rotate_y_degrees == -45);
    CHECK(s.meshes[0].material == 0);
    REQUIRE(s.lights.size() == 2);
    CHECK(s.lights[0].radius == 0.1);  // the default
    CHECK(same(s.lights[0].color, {1, 1, 1}));
    CHECK(s.lights[1].kind == kr::LightKind::quad);
    CHECK(same(s.lights[1].color, {2, 3, 4}));
}

TEST_CASE("relative paths are taken from the scene file's folder, not the working one", "[scene_file]")
{
    TempDir dir;
    dir.write("scenes/tex/grid.png", "x");
    const std::string path = dir.write("scenes/s.yaml", minimal + "textures: [{name: grid, file: tex/grid.png}]\n");
    Scene scene;
    std::string error;
    REQUIRE(kr::load_scene_file(path, scene, error));
    REQUIRE(scene.textures.size() == 1);
    CHECK(fs::equivalent(scene.textures[0].file, dir.path / "scenes" / "tex" / "grid.png"));
}

TEST_CASE("YAML syntax errors are reported with their line", "[scene_file]")
{
    check_error(minimal + "quads:\n  - {corner: [0, 0, 0]\n  edge_u: [1, 0, 0]}\n", 8, "YAML syntax error");
    check_error(camera_line + "materials:\n  - name: white\n   type: mirror\n", 4, "YAML syntax error");
    check_error(camera_line + "spheres: [[[\n", 3, "YAML syntax error");  // ends inside an open list
}

TEST_CASE("unknown, repeated and misplaced keys are errors at their line", "[scene_file]")
{
    check_error(minimal + "lights:\n  - {type: sphere, center: [0, 1, 0], raduis: 2}\n", 7,
                "light: unknown key 'raduis' (expected one of: type, center, radius");
    check_error(minimal + "sphere:\n  - {center: [0, 0, 0], radius: 1, material: white}\n", 6,
                "scene: unknown key 'sphere'");
    check_error(minimal + "camera: {position: [1, 1, 1], target: [0, 0, 0]}\n", 6, "'camera' appears twice");
    check_error(camera_line + "materials:\n  - {name: m, ior: 1.3}\n" + "spheres: [{center: [0,0,0], radius: 1, material: m}]\n",
                3, "material 'ior' applies only to glass materials");
    check_error(minimal + "lights:\n  - {type: sphere, center: [0, 1, 0], edge_u: [1, 0, 0]}\n", 7,
                "light 'edge_u' applies only to quad lights");
}

TEST_CASE("text quoted from the file stays on the message's one line", "[scene_file]")
{
    // YAML's double quotes make any character, line breaks included, part of a key or a value.
    check_error(minimal + "lights:\n  - {type: sphere, center: [0, 1, 0], \"ra\\ndius\": 2}\n", 7,
                "light: unknown key 'ra\\ndius' (expected one of");
    check_error(camera_line + "materials: [{name: \"a\\tb\\x01\"}]\nspheres: [{center: [0, 0, 0], radius: 1, material: c}]\n",
                3, "no material named 'c' (defined: a\\tb\\x01)");
}

TEST_CASE("values of the wrong type are errors that show what was given", "[scene_file]")
{
    check_error(camera_line + "materials: [{name: white}]\nspheres:\n  - {center: [0, 0, 0], radius: big, material: white}\n",
                4, "sphere 'radius' must be a number > 0, got \"big\"");
    // Quoted, a number is a string: "1" is refused like big.
    check_error(camera_line + "materials: [{name: white}]\nspheres:\n  - {center: [0, 0, 0], radius: \"1\", material: white}\n",
                4, "sphere 'radius' must be a number > 0, got \"1\"");
    check_error(camera_line + "materials: [{name: white}]\nspheres:\n  - {center: [0, 0], radius: 1, material: white}\n",
                4, "sphere 'center' must be [x, y, z] of finite numbers, got [0, 0]");
    check_error(camera_line + "materials: {name: white}\n", 2, "'materials' must be a list of material maps, got a map");
    check_error(camera_line + "materials: [white]\n", 2, "material must be a map of keys, got \"white\"");
    check_error("camera: [0, 0, 5]\n", 1, "camera must be a map of keys, got [0, 0, 5]");
    check_error("just some words\n", 1, "a scene must be a map of sections (camera, materials, spheres, ...), got \"just some words\"");
    check_error("- camera\n- spheres\n", 1, "a scene must be a map of sections");
    check_error(minimal + "settings: {NSAMPLES: [1, 2]}\n", 6, "setting NSAMPLES must be a single value");
}

TEST_CASE("values out of range are errors naming the range", "[scene_file]")
{
    const std::string head = camera_line + "materials: [{name: white}]\n";  // lines 1-2
    check_error(head + "spheres: [{center: [0, 0, 0], radius: 0, material: white}]\n", 3, "a number > 0, got \"0\"");
    check_error(head + "spheres: [{center: [0, 0, 0], radius: -1, material: white}]\n", 3, "a number > 0");
    check_error(head + "quads:\n  - {corner: [0, 0, 0], edge_u: [1, 0, 0],\n     edge_v: [2, 0, 0], material: white}\n",
                5, "'edge_u' and 'edge_v' must span an area");
    check_error(head + "quads: [{corner: [0, 0, 0], edge_u: [0, 0, 0], edge_v: [0, 1, 0], material: white}]\n", 3,
                "must span an area");
    check_error("camera: {position: [0, 0, 5], target: [0, 0, 0], fov: 180}\n", 1, "vertical degrees in (0, 180)");
    check_error("camera: {position: [0, 0, 5], target: [0, 0, 5]}\n", 1, "'target' must differ from its 'position'");
    check_error("camera: {position: [0, 0, 5], target: [0, 0, 0], up: [0, 0, 2]}\n", 1, "not along the view");
    check_error("camera: {position: [0, 5, 0], target: [0, 0, 0]}\n", 1, "got the default [0, 1, 0]");
    check_error(camera_line + "materials:\n  - {name: g, type: glass, ior: 0}\n", 3, "from 0.001 to 100, got \"0\"");
    check_error(camera_line + "materials:\n  - {name: g, type: glass, tint: [1, 1.5, 1]}\n", 3, "numbers from 0 to 1");
    check_error(camera_line + "materials:\n  - {name: w, diffuse: [0.5, -0.1, 0.5]}\n", 3, "numbers >= 0");
    check_error(camera_line + "materials:\n  - {name: w, type: wood}\n", 3, "phong, mirror or glass, got \"wood\"");
    check_error(minimal + "background: [0, 0, -1]\n", 6, "scene 'background' must be a colour");
    check_error(minimal + "meshes:\n  - {generated: teapot, material: white}\n", 7, "must be torus, got \"teapot\"");
    check_error(minimal + "lights:\n  - {type: point, center: [0, 1, 0]}\n", 7, "sphere or quad, got \"point\"");
    check_error(minimal + "settings:\n  NSAMPLES: 4\n  MAX_BOUNCES: 1000\n", 8,
                "setting MAX_BOUNCES: '1000' is not an integer from 0 to 64");
    check_error(minimal + "settings:\n  NSAMPLE: 4\n", 7, "unknown setting 'NSAMPLE' (known: NSAMPLES, MAX_BOUNCES,");
    check_error(minimal + "settings:\n  NSAMPLES: 0\n", 7, "setting NSAMPLES: '0' is not an integer from 1 to 65536");
}

TEST_CASE("a view direction that overflows or underflows is blamed on position and target, not up", "[scene_file]")
{
    // Each coordinate is finite; target - position, or its length, is not.
    check_error("camera: {position: [-1e308, 0, 0], target: [1e308, 0, 0]}\n", 1,
                "camera 'position' and 'target' are too far apart: target - position overflows, got [-1e308, 0, 0] "
                "and [1e308, 0, 0]");
    check_error("camera: {position: [0, 0, 0],\n         target: [1e200, 1e200, 0]}\n", 2, "too far apart");
    check_error("camera: {position: [0, 0, 0], target: [1e-200, 0, 0]}\n", 1,
                "camera 'target' is too close to its 'position'");
    check_error("camera: {position: [0, 0, 5], target: [0, 0, 0], up: [0, 1e200, 1e200]}\n", 1,
                "camera 'up' is too long: its length overflows");
    // Large but representable: still a scene.
    const Scene far = parse_good("camera: {position: [0, 0, 1e150], target: [0, 1e150, -1e150]}\n"
                                 "materials: [{name: white}]\n"
                                 "spheres: [{center: [0, 0, 0], radius: 1, material: white}]\n");
    CHECK(far.camera.target.y == 1e150);
}

TEST_CASE("a token no YAML document can start with is an error, never an endless loop", "[scene_file]")
{
    // yaml-cpp 0.7 ends a document at such a token without reading it; asked for every document,
    // it returns empty ones for ever.
    check_error(",", 1, "YAML syntax error: unexpected ','");
    check_error("{camera: {position: [0, 0, 5], target: [0, 0, 0]}}\n, more\n", 2, "YAML syntax error: unexpected ', more'");
    check_error(minimal + "...\nspheres: []\n", 7, "YAML syntax error: unexpected 'spheres: []'");
    check_error(minimal + "---\n", 7, "a second YAML document");

    // Every input of one or two bytes, and of three from YAML's indicators and a few others: each
    // is refused with one line (ctest's TIMEOUT catches a hang).
    std::vector<std::string> inputs;
    for (int a = 0; a < 256; ++a) {
        inputs.push_back(std::string(1, char(a)));
        for (int b = 0; b < 256; ++b) inputs.push_back(std::string{char(a), char(b)});
    }
    const std::string alphabet = ",[]{}:-?#&*!|>'\"%@` \n\ta0.";
    for (char a : alphabet)
        for (char b : alphabet)
            for (char c : alphabet) inputs.push_back(std::string{a, b, c});
    size_t refused = 0;
    for (const std::string &text : inputs) {
        Scene scene;
        std::string error;
        if (!kr::parse_scene_text(text, "tiny.yaml", "", scene, error) && error.rfind("tiny.yaml:", 0) == 0 &&
            error.find('\n') == std::string::npos)
            ++refused;
        else
            FAIL_CHECK("input of " << text.size() << " bytes: " << (error.empty() ? "accepted" : error));
    }
    CHECK(refused == inputs.size());
}

TEST_CASE("NaN and infinity are refused in every spelling", "[scene_file]")
{
    for (const char *bad : {".nan", ".NaN", "nan", ".inf", "-.inf", "inf", "1e999"}) {
        check_error(camera_line + "materials: [{name: white}]\nspheres:\n  - {center: [0, " + bad +
                        ", 0], radius: 1, material: white}\n",
                    4, "sphere 'center' must be [x, y, z] of finite numbers");
        check_error(camera_line + "materials: [{name: white}]\nspheres:\n  - {center: [0, 0, 0], radius: " + bad +
                        ", material: white}\n",
                    4, "sphere 'radius' must be a number > 0");
    }
}

TEST_CASE("names that refer to nothing are errors listing what is defined", "[scene_file]")
{
    check_error(camera_line + "materials: [{name: white}, {name: red}]\nspheres:\n  - {center: [0, 0, 0], radius: 1, material: glass}\n",
                4, "sphere 'material': no material named 'glass' (defined: red, white)");
    check_error(camera_line + "materials:\n  - {name: w, texture: wood}\n", 3,
                "material 'texture': no texture named 'wood' (defined: none)");
    check_error(camera_line + "materials:\n  - {name: w}\n  - {name: w}\n", 4, "material 'w' is defined twice");
}

TEST_CASE("a missing required field is an error at the line of its map", "[scene_file]")
{
    check_error(camera_line + "materials: [{name: white}]\nspheres:\n  - {center: [0, 0, 0], material: white}\n", 4,
                "sphere needs 'radius' (a number > 0)");
    check_error(minimal + "quads:\n  - corner: [0, 0, 0]\n    edge_u: [1, 0, 0]\n    material: white\n", 7,
                "quad needs 'edge_v'");
    check_error(camera_line + "materials:\n  - {type: glass}\n", 3, "material needs 'name'");
    check_error(minimal + "meshes:\n  - {position: [0, 0, 0], material: white}\n", 7,
                "mesh needs 'file' (a mesh file) or 'generated' (torus)");
    check_error(minimal + "textures:\n  - {name: t}\n", 7, "texture 't' needs 'file' (an image) or 'checker'");
    check_error("materials: [{name: white}]\nspheres: [{center: [0, 0, 0], radius: 1, material: white}]\n", 1,
                "scene needs 'camera'");
    check_error("camera: {target: [0, 0, 0]}\n", 1, "camera needs 'position'");
    check_error(camera_line + "materials: [{name: white}]\n", 1, "the scene has nothing to render");
}

TEST_CASE("mesh and texture files that cannot be read are errors at their line", "[scene_file]")
{
    TempDir dir;
    dir.write("present.obj", "v 0 0 0\n");
    fs::create_directories(dir.path / "a_folder.png");
    const std::string d = dir.path.string();
    check_error(minimal + "meshes:\n  - {file: missing.obj, material: white}\n", 7,
                "mesh 'file': 'missing.obj' (" + (dir.path / "missing.obj").string() +
                    ") cannot be read: No such file or directory",
                d);
    check_error(minimal + "textures:\n  - name: t\n    file: nowhere/t.png\n", 8, "cannot be read", d);
    check_error(minimal + "textures:\n  - {name: t, file: a_folder.png}\n", 7, "is a folder, not a file", d);
    check_error(minimal + "meshes:\n  - {file: present.obj, generated: torus, material: white}\n", 7,
                "mesh has both 'file' and 'generated'", d);
    if (geteuid() != 0) {  // root reads anything
        const std::string locked = dir.write("locked.png", "x");
        fs::permissions(locked, fs::perms::none);
        check_error(minimal + "textures: [{name: t, file: locked.png}]\n", 6, "Permission denied", d);
    }
}

TEST_CASE("scene files that are missing, folders, empty, cut short or not text are refused", "[scene_file]")
{
    TempDir dir;
    Scene scene = callers_scene();
    std::string error;

    const std::string missing = (dir.path / "no_such.yaml").string();
    CHECK_FALSE(kr::load_scene_file(missing, scene, error));
    CHECK(error == missing + ": cannot read the scene file: No such file or directory");
    check_untouched(scene);

    CHECK_FALSE(kr::load_scene_file(dir.path.string(), scene, error));
    CHECK(error == dir.path.string() + ": is a folder, not a scene file");
    check_untouched(scene);

    const std::string empty = dir.write("empty.yaml", "");
    CHECK_FALSE(kr::load_scene_file(empty, scene, error));
    CHECK(error == empty + ":1: the scene is empty: expected a map of sections (camera, materials, spheres, ...)");
    check_untouched(scene);
    check_error("# only a comment\n\n", 1, "the scene is empty");

    // The Cornell box cut in the middle of a line: a flow map left open.
    std::ifstream in(std::string(KDRT_SCENES_DIR) + "/cornell.yaml");
    const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t cut = whole.find("edge_v: [0, 2, 0], material: green");
    REQUIRE(cut != std::string::npos);
    const std::string truncated = dir.write("truncated.yaml", whole.substr(0, cut + 10));
    CHECK_FALSE(kr::load_scene_file(truncated, scene, error));
    INFO(error);
    const int cut_line = 1 + int(std::count(whole.begin(), whole.begin() + long(cut), '\n'));
    CHECK(error.rfind(truncated + ":" + std::to_string(cut_line) + ": ", 0) == 0);
    CHECK(error.find("YAML syntax error") != std::string::npos);
    check_untouched(scene);

    // Cut between entries the YAML is whole, but the box has no lights: still a scene, so the
    // cut must lose a required part to be caught. Here it loses the torus's material.
    const std::size_t cut2 = whole.find(", material: gold");
    REQUIRE(cut2 != std::string::npos);
    const int torus_line = 1 + int(std::count(whole.begin(), whole.begin() + long(cut2), '\n'));
    check_error(whole.substr(0, cut2) + "}\n", torus_line, "mesh needs 'material'");

    check_error(minimal + "---\n" + minimal, 7, "a second YAML document");  // where it starts
    check_error(minimal + std::string("\0\1\2", 3), 6, "a NUL byte");
    // yaml-cpp's parser recurses; its depth guard turns a deep nest into an error, not a crash.
    check_error(minimal + "background: " + std::string(100000, '[') + std::string(100000, ']') + "\n", 6,
                "YAML nested more than");
}

TEST_CASE("files above 64 MB are refused before they are parsed", "[scene_file]")
{
    TempDir dir;
    const std::string big = dir.write("big.yaml", minimal);
    fs::resize_file(big, (64u << 20) + 1);  // sparse: costs no disk
    Scene scene = callers_scene();
    std::string error;
    CHECK_FALSE(kr::load_scene_file(big, scene, error));
    CHECK(error == big + ": larger than the 64 MB a scene file may be");
    check_untouched(scene);

    std::string text = minimal;
    text.resize((64u << 20) + 1, ' ');
    CHECK_FALSE(kr::parse_scene_text(text, "big.yaml", "", scene, error));
    CHECK(error == "big.yaml: 67108865 bytes, more than the 64 MB a scene file may be");
    check_untouched(scene);
}
