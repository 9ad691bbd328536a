// Scene files in YAML (format in scene_file.hpp). yaml-cpp builds the document; this file checks
// it against the Scene model, naming the line of every mistake through the nodes' marks.
#include "scene_file.hpp"

#include "common/regular_file.hpp"

#include <yaml-cpp/depthguard.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <utility>

namespace kr {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kMaxFileBytes = 64u << 20;  // far above any hand-written scene
constexpr std::size_t kMaxListLength = 65536;        // spheres and quads are tested one by one

// A map's entries in file order, keys checked: known, unique, scalar.
struct Field {
    std::string key;
    YAML::Node value;
};
struct Fields {
    YAML::Node map;
    std::string what;  // "sphere", "camera", ... for messages
    std::vector<Field> items;

    const YAML::Node *find(const char *key) const
    {
        for (const Field &f : items)
            if (f.key == key) return &f.value;
        return nullptr;
    }
};

enum class Need { required, optional };

// How a node looks in a message: a scalar quoted, a short list of scalars as written.
std::string describe(const YAML::Node &node)
{
    if (!node.IsDefined() || node.IsNull()) return "nothing";
    if (node.IsScalar()) {
        std::string text = node.Scalar();
        if (text.size() > 40) text = text.substr(0, 37) + "...";
        return "\"" + text + "\"";
    }
    if (node.IsMap()) return "a map";
    if (node.size() <= 4) {
        std::string out = "[";
        for (std::size_t i = 0; i < node.size(); ++i) {
            if (!node[i].IsScalar()) return "a list";
            out += (i ? ", " : "") + node[i].Scalar();
        }
        return out + "]";
    }
    return "a list of " + std::to_string(node.size());
}

// A plain (unquoted) scalar that is a whole finite number. YAML's .nan/.inf and strtod's
// nan/inf are refused by the finiteness test.
bool scalar_number(const YAML::Node &node, double &out)
{
    if (!node.IsScalar() || node.Tag() == "!") return false;  // "!" marks a quoted scalar
    const std::string &text = node.Scalar();
    if (text.empty()) return false;
    char *end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (*end != '\0' || !std::isfinite(v)) return false;
    out = v;
    return true;
}

// A message on one line, whatever text from the file it quotes: YAML's double quotes can put any
// character into a key or a value, so control characters are shown as escapes.
std::string one_line(const std::string &text)
{
    std::string out;
    for (const char c : text) {
        const auto u = static_cast<unsigned char>(c);
        if (c == '\n') out += "\\n";
        else if (c == '\r') out += "\\r";
        else if (c == '\t') out += "\\t";
        else if (u < 0x20 || u == 0x7f) {
            char hex[8];
            std::snprintf(hex, sizeof hex, "\\x%02x", u);
            out += hex;
        } else out += c;
    }
    return out;
}

// Names from a list (types, generated meshes) are taken in any case, as presets and settings are.
std::string lower(std::string text)
{
    for (char &c : text) c = char(std::tolower(static_cast<unsigned char>(c)));
    return text;
}

std::string quoted_list(const std::vector<std::string> &names)
{
    std::string out;
    for (const std::string &n : names) out += (out.empty() ? "" : ", ") + n;
    return out.empty() ? "none" : out;
}

class Reader {
public:
    Reader(std::string name, std::string base_dir) : name_(std::move(name)), base_dir_(std::move(base_dir)) {}

    const std::string &error() const { return error_; }

    // "file:line: message" from yaml-cpp's 0-based line; nodes it did not place (line -1) give line 1.
    bool fail_at(int line, const std::string &message)
    {
        error_ = one_line(name_ + ":" + std::to_string(std::max(line, 0) + 1) + ": " + message);
        return false;
    }
    bool fail(const YAML::Node &node, const std::string &message) { return fail_at(node.Mark().line, message); }

    bool read_scene(const YAML::Node &root, Scene &scene);

private:
    bool read_map(const YAML::Node &node, const std::string &what, std::initializer_list<const char *> allowed,
                  Fields &out);
    bool read_list(const Fields &parent, const char *key, const std::string &item, std::vector<Fields> &out,
                   std::initializer_list<const char *> allowed);
    template <class Ok>
    bool number(const Fields &f, const char *key, const char *expected, Ok ok, double &out, Need need);
    template <class Ok>
    bool vec3(const Fields &f, const char *key, const char *expected, Ok ok, Vec3 &out, Need need);
    bool position(const Fields &f, const char *key, Vec3 &out, Need need);
    bool colour(const Fields &f, const char *key, Vec3 &out, Need need);
    bool text(const Fields &f, const char *key, std::string &out, Need need);
    bool missing(const Fields &f, const char *key, const char *expected);
    bool name_ref(const Fields &f, const char *key, const std::map<std::string, int> &names, const char *kind,
                  int &out, Need need);
    bool readable_file(const Fields &f, const char *key, std::string &resolved);
    bool only_for(const Fields &f, const char *key, const char *kinds);
    bool edges(const Fields &f, Vec3 &corner, Vec3 &edge_u, Vec3 &edge_v);

    bool read_settings(const Fields &top, Scene &scene);
    bool read_camera(const Fields &top, Camera &camera);
    bool read_textures(const Fields &top, Scene &scene, std::map<std::string, int> &names);
    bool read_materials(const Fields &top, Scene &scene, const std::map<std::string, int> &textures,
                        std::map<std::string, int> &names);
    bool read_objects(const Fields &top, Scene &scene, const std::map<std::string, int> &materials);
    bool read_lights(const Fields &top, Scene &scene);

    std::string name_, base_dir_, error_;
};

bool Reader::read_map(const YAML::Node &node, const std::string &what, std::initializer_list<const char *> allowed,
                      Fields &out)
{
    if (!node.IsMap()) return fail(node, what + " must be a map of keys, got " + describe(node));
    out.map = node;
    out.what = what;
    out.items.clear();
    for (const auto &entry : node) {
        const YAML::Node &key = entry.first;
        if (!key.IsScalar()) return fail(key, what + ": keys must be names, got " + describe(key));
        const std::string k = key.Scalar();
        if (allowed.size() && std::find_if(allowed.begin(), allowed.end(), [&](const char *a) { return k == a; }) ==
                                  allowed.end()) {
            std::string known;
            for (const char *a : allowed) known += (known.empty() ? "" : ", ") + std::string(a);
            return fail(key, what + ": unknown key '" + k + "' (expected one of: " + known + ")");
        }
        for (const Field &f : out.items)
            if (f.key == k) return fail(key, what + ": '" + k + "' appears twice");
        out.items.push_back({k, entry.second});
    }
    return true;
}

// A section that is a list of maps; `key: ` with nothing after it is an empty list.
bool Reader::read_list(const Fields &parent, const char *key, const std::string &item, std::vector<Fields> &out,
                       std::initializer_list<const char *> allowed)
{
    out.clear();
    const YAML::Node *list = parent.find(key);
    if (!list || list->IsNull()) return true;
    if (!list->IsSequence())
        return fail(*list, std::string("'") + key + "' must be a list of " + item + " maps, got " + describe(*list));
    if (list->size() > kMaxListLength)
        return fail(*list, std::string("'") + key + "' has " + std::to_string(list->size()) + " entries, at most " +
                               std::to_string(kMaxListLength) + " are read");
    for (const YAML::Node &node : *list) {
        out.emplace_back();
        if (!read_map(node, item, allowed, out.back())) return false;
    }
    return true;
}

bool Reader::missing(const Fields &f, const char *key, const char *expected)
{
    return fail(f.map, f.what + " needs '" + key + "' (" + expected + ")");
}

template <class Ok>
bool Reader::number(const Fields &f, const char *key, const char *expected, Ok ok, double &out, Need need)
{
    const YAML::Node *node = f.find(key);
    if (!node) return need == Need::optional || missing(f, key, expected);
    double v = 0;
    if (!scalar_number(*node, v) || !ok(v))
        return fail(*node, f.what + " '" + key + "' must be " + expected + ", got " + describe(*node));
    out = v;
    return true;
}

template <class Ok>
bool Reader::vec3(const Fields &f, const char *key, const char *expected, Ok ok, Vec3 &out, Need need)
{
    const YAML::Node *node = f.find(key);
    if (!node) return need == Need::optional || missing(f, key, expected);
    double v[3] = {0, 0, 0};
    bool good = node->IsSequence() && node->size() == 3;
    for (std::size_t i = 0; good && i < 3; ++i) good = scalar_number((*node)[i], v[i]) && ok(v[i]);
    if (!good) return fail(*node, f.what + " '" + key + "' must be " + expected + ", got " + describe(*node));
    out = {v[0], v[1], v[2]};
    return true;
}

bool Reader::position(const Fields &f, const char *key, Vec3 &out, Need need)
{
    return vec3(f, key, "[x, y, z] of finite numbers", [](double) { return true; }, out, need);
}

bool Reader::colour(const Fields &f, const char *key, Vec3 &out, Need need)
{
    return vec3(f, key, "a colour [r, g, b] of numbers >= 0", [](double c) { return c >= 0; }, out, need);
}

bool Reader::text(const Fields &f, const char *key, std::string &out, Need need)
{
    const YAML::Node *node = f.find(key);
    if (!node) return need == Need::optional || missing(f, key, "a name");
    if (!node->IsScalar() || node->Scalar().empty())
        return fail(*node, f.what + " '" + key + "' must be a non-empty name, got " + describe(*node));
    out = node->Scalar();
    return true;
}

bool Reader::name_ref(const Fields &f, const char *key, const std::map<std::string, int> &names, const char *kind,
                      int &out, Need need)
{
    std::string name;
    if (!text(f, key, name, need)) return false;
    if (name.empty()) return true;  // optional and absent
    const auto it = names.find(name);
    if (it == names.end()) {
        std::vector<std::string> known;
        for (const auto &n : names) known.push_back(n.first);
        return fail(*f.find(key), f.what + " '" + key + "': no " + kind + " named '" + name + "' (defined: " +
                                      quoted_list(known) + ")");
    }
    out = it->second;
    return true;
}

// Textures and meshes are loaded by the renderer; a path that cannot be read is reported here,
// with its line, instead of after the scene was accepted.
bool Reader::readable_file(const Fields &f, const char *key, std::string &resolved)
{
    std::string given;
    if (!text(f, key, given, Need::required)) return false;
    fs::path path(given);
    if (path.is_relative() && !base_dir_.empty()) path = fs::path(base_dir_) / path;
    resolved = path.lexically_normal().string();
    const std::string where = f.what + " '" + key + "': '" + given + "'" +
                              (resolved != given ? " (" + resolved + ")" : std::string());
    std::error_code ec;
    if (fs::is_directory(path, ec)) return fail(*f.find(key), where + " is a folder, not a file");
    std::string why;  // a FIFO or a device is refused: opening it could block, reading it never end
    struct stat st;
    std::FILE *file = common::open_regular_file(resolved.c_str(), st, why);
    if (!file) return fail(*f.find(key), where + " cannot be read: " + why);
    std::fclose(file);
    return true;
}

bool Reader::only_for(const Fields &f, const char *key, const char *kinds)
{
    const YAML::Node *node = f.find(key);
    return !node || fail(*node, f.what + " '" + key + "' applies only to " + kinds);
}

// A parallelogram's corner and edges, the edges neither zero nor parallel.
bool Reader::edges(const Fields &f, Vec3 &corner, Vec3 &edge_u, Vec3 &edge_v)
{
    if (!position(f, "corner", corner, Need::required) || !position(f, "edge_u", edge_u, Need::required) ||
        !position(f, "edge_v", edge_v, Need::required))
        return false;
    const double lu = length(edge_u), lv = length(edge_v);
    if (!(length(cross(edge_u, edge_v)) > 1e-9 * lu * lv) || lu == 0 || lv == 0)
        return fail(*f.find("edge_v"), f.what + " 'edge_u' and 'edge_v' must span an area (neither zero nor "
                                                "parallel), got " + describe(*f.find("edge_u")) + " and " +
                                           describe(*f.find("edge_v")));
    return true;
}

bool Reader::read_settings(const Fields &top, Scene &scene)
{
    const YAML::Node *node = top.find("settings");
    if (!node || node->IsNull()) return true;
    Fields settings;
    if (!read_map(*node, "settings", {}, settings)) return false;
    for (const Field &s : settings.items) {
        if (!s.value.IsScalar())
            return fail(s.value, "setting " + s.key + " must be a single value, got " + describe(s.value));
        std::string message;
        if (!apply_setting(scene, s.key, s.value.Scalar(), message)) {
            if (message.rfind("unknown setting", 0) == 0) {  // a typo: say what is there
                std::vector<std::string> names = setting_names();
                message += " (known: " + quoted_list(names) + ")";
            }
            return fail(s.value, message);
        }
    }
    return true;
}

bool Reader::read_camera(const Fields &top, Camera &camera)
{
    const YAML::Node *node = top.find("camera");
    if (!node) return missing(top, "camera", "a map with position, target, up, fov");
    Fields f;
    if (!read_map(*node, "camera", {"position", "target", "up", "fov"}, f)) return false;
    if (!position(f, "position", camera.position, Need::required) ||
        !position(f, "target", camera.target, Need::required) || !position(f, "up", camera.up, Need::optional) ||
        !number(f, "fov", "vertical degrees in (0, 180)", [](double v) { return v > 0 && v < 180; },
                camera.fov_degrees, Need::optional))
        return false;
    // The renderer normalizes target - position and up in double: their lengths must be finite
    // and non-zero there, and a failure is the fault of the vectors that cause it.
    const Vec3 view = camera.target - camera.position;
    const YAML::Node &target = *f.find("target");
    if (!std::isfinite(length(view)))
        return fail(target, "camera 'position' and 'target' are too far apart: target - position overflows, got " +
                                describe(*f.find("position")) + " and " + describe(target));
    if (view.x == 0 && view.y == 0 && view.z == 0)
        return fail(target, "camera 'target' must differ from its 'position'");
    if (!(length(view) > 0))
        return fail(target, "camera 'target' is too close to its 'position': the length of target - position "
                            "underflows, got " + describe(*f.find("position")) + " and " + describe(target));
    if (!std::isfinite(length(camera.up)))
        return fail(*f.find("up"), "camera 'up' is too long: its length overflows, got " + describe(*f.find("up")));
    if (!(length(cross(normalize(view), normalize(camera.up))) > 1e-6))
        return fail(f.find("up") ? *f.find("up") : f.map,
                    "camera 'up' must be a non-zero vector not along the view direction, got " +
                        (f.find("up") ? describe(*f.find("up")) : std::string("the default [0, 1, 0]")));
    return true;
}

bool Reader::read_textures(const Fields &top, Scene &scene, std::map<std::string, int> &names)
{
    std::vector<Fields> list;
    if (!read_list(top, "textures", "texture", list, {"name", "file", "checker"})) return false;
    for (const Fields &f : list) {
        Texture t;
        if (!text(f, "name", t.name, Need::required)) return false;
        if (names.count(t.name)) return fail(*f.find("name"), "texture '" + t.name + "' is defined twice");
        const YAML::Node *checker = f.find("checker");
        if (f.find("file") && checker)
            return fail(*checker, "texture '" + t.name + "' has both 'file' and 'checker': give one");
        if (f.find("file")) {
            if (!readable_file(f, "file", t.file)) return false;
        } else if (checker) {
            Fields c;
            if (!read_map(*checker, "texture 'checker'", {"a", "b", "scale"}, c) ||
                !colour(c, "a", t.checker_a, Need::optional) || !colour(c, "b", t.checker_b, Need::optional) ||
                !number(c, "scale", "a number > 0", [](double v) { return v > 0; }, t.checker_scale, Need::optional))
                return false;
        } else {
            return fail(f.map, "texture '" + t.name + "' needs 'file' (an image) or 'checker' (a map)");
        }
        names[t.name] = int(scene.textures.size());
        scene.textures.push_back(std::move(t));
    }
    return true;
}

bool Reader::read_materials(const Fields &top, Scene &scene, const std::map<std::string, int> &textures,
                            std::map<std::string, int> &names)
{
    std::vector<Fields> list;
    if (!read_list(top, "materials", "material", list,
                   {"name", "type", "ambient", "diffuse", "specular", "shininess", "texture", "ior", "tint"}))
        return false;
    for (const Fields &f : list) {
        Material m;
        if (!text(f, "name", m.name, Need::required)) return false;
        if (names.count(m.name)) return fail(*f.find("name"), "material '" + m.name + "' is defined twice");
        std::string type = "phong";
        if (!text(f, "type", type, Need::optional)) return false;
        if (lower(type) == "phong") m.kind = MaterialKind::phong;
        else if (lower(type) == "mirror") m.kind = MaterialKind::mirror;
        else if (lower(type) == "glass") m.kind = MaterialKind::glass;
        else return fail(*f.find("type"), "material 'type' must be phong, mirror or glass, got \"" + type + "\"");
        if (!colour(f, "ambient", m.ambient, Need::optional) || !colour(f, "diffuse", m.diffuse, Need::optional) ||
            !colour(f, "specular", m.specular, Need::optional) ||
            !number(f, "shininess", "a number >= 0", [](double v) { return v >= 0; }, m.shininess, Need::optional) ||
            !name_ref(f, "texture", textures, "texture", m.texture, Need::optional))
            return false;
        if (m.kind != MaterialKind::glass && !only_for(f, "ior", "glass materials")) return false;
        if (m.kind == MaterialKind::phong && !only_for(f, "tint", "mirror and glass materials")) return false;
        if (!number(f, "ior", "an index of refraction from 0.001 to 100",
                    [](double v) { return v >= 1e-3 && v <= 100; }, m.ior, Need::optional) ||
            !vec3(f, "tint", "a colour [r, g, b] of numbers from 0 to 1", [](double c) { return c >= 0 && c <= 1; },
                  m.tint, Need::optional))
            return false;
        names[m.name] = int(scene.materials.size());
        scene.materials.push_back(std::move(m));
    }
    return true;
}

bool Reader::read_objects(const Fields &top, Scene &scene, const std::map<std::string, int> &materials)
{
    std::vector<Fields> list;
    if (!read_list(top, "spheres", "sphere", list, {"center", "radius", "material"})) return false;
    for (const Fields &f : list) {
        Sphere s;
        if (!position(f, "center", s.center, Need::required) ||
            !number(f, "radius", "a number > 0", [](double v) { return v > 0; }, s.radius, Need::required) ||
            !name_ref(f, "material", materials, "material", s.material, Need::required))
            return false;
        scene.spheres.push_back(s);
    }
    if (!read_list(top, "quads", "quad", list, {"corner", "edge_u", "edge_v", "material"})) return false;
    for (const Fields &f : list) {
        Quad q;
        if (!edges(f, q.corner, q.edge_u, q.edge_v) ||
            !name_ref(f, "material", materials, "material", q.material, Need::required))
            return false;
        scene.quads.push_back(q);
    }
    if (!read_list(top, "meshes", "mesh", list, {"file", "generated", "position", "size", "rotate_y", "material"}))
        return false;
    for (const Fields &f : list) {
        MeshInstance m;
        const YAML::Node *generated = f.find("generated");
        if (f.find("file") && generated) return fail(*generated, "mesh has both 'file' and 'generated': give one");
        if (f.find("file")) {
            if (!readable_file(f, "file", m.file)) return false;
        } else if (generated) {
            if (!generated->IsScalar() || lower(generated->Scalar()) != "torus")
                return fail(*generated, "mesh 'generated' must be torus, got " + describe(*generated));
            // The same stand-in torus kdrt-render-mesh and kdrt-bench generate; placement rescales it.
            m.mesh = common::torus(96, 48, 1.0, 0.35);
            m.source = "generated torus";
        } else {
            return fail(f.map, "mesh needs 'file' (a mesh file) or 'generated' (torus)");
        }
        if (!position(f, "position", m.position, Need::optional) ||
            !number(f, "size", "a number > 0", [](double v) { return v > 0; }, m.size, Need::optional) ||
            !number(f, "rotate_y", "a finite number of degrees", [](double) { return true; }, m.rotate_y_degrees,
                    Need::optional) ||
            !name_ref(f, "material", materials, "material", m.material, Need::required))
            return false;
        scene.meshes.push_back(std::move(m));
    }
    if (scene.spheres.empty() && scene.quads.empty() && scene.meshes.empty())
        return fail(top.map, "the scene has nothing to render: give at least one of spheres, quads, meshes");
    return true;
}

bool Reader::read_lights(const Fields &top, Scene &scene)
{
    std::vector<Fields> list;
    if (!read_list(top, "lights", "light", list, {"type", "center", "radius", "corner", "edge_u", "edge_v", "color"}))
        return false;
    for (const Fields &f : list) {
        Light l;
        std::string type;
        if (!text(f, "type", type, Need::required)) return false;
        if (lower(type) == "sphere") {
            l.kind = LightKind::sphere;
            if (!only_for(f, "corner", "quad lights") || !only_for(f, "edge_u", "quad lights") ||
                !only_for(f, "edge_v", "quad lights") || !position(f, "center", l.center, Need::required) ||
                !number(f, "radius", "a number > 0", [](double v) { return v > 0; }, l.radius, Need::optional))
                return false;
        } else if (lower(type) == "quad") {
            l.kind = LightKind::quad;
            if (!only_for(f, "center", "sphere lights") || !only_for(f, "radius", "sphere lights") ||
                !edges(f, l.corner, l.edge_u, l.edge_v))
                return false;
        } else {
            return fail(*f.find("type"), "light 'type' must be sphere or quad, got \"" + type + "\"");
        }
        if (!colour(f, "color", l.color, Need::optional)) return false;
        scene.lights.push_back(l);
    }
    return true;
}

bool Reader::read_scene(const YAML::Node &root, Scene &scene)
{
    if (!root.IsDefined() || root.IsNull())
        return fail_at(root.IsDefined() ? root.Mark().line : 0,
                       "the scene is empty: expected a map of sections (camera, materials, spheres, ...)");
    if (!root.IsMap())
        return fail(root, "a scene must be a map of sections (camera, materials, spheres, ...), got " + describe(root));
    Fields top;
    if (!read_map(root, "scene",
                  {"settings", "camera", "background", "textures", "materials", "spheres", "quads", "meshes", "lights"},
                  top))
        return false;
    std::map<std::string, int> textures, materials;
    // Materials before settings, so GLASS_IOR reaches them; names before their users, whatever the
    // order of sections in the file.
    return read_camera(top, scene.camera) && colour(top, "background", scene.background, Need::optional) &&
           read_textures(top, scene, textures) && read_materials(top, scene, textures, materials) &&
           read_objects(top, scene, materials) && read_lights(top, scene) && read_settings(top, scene);
}

// Where a second YAML document starts, if the text has one: yaml-cpp's parser asked for two
// documents, never for all of them. yaml-cpp 0.7's LoadAll loops for ever, allocating, on a
// token no document can start with (a lone ',': upstream issue 1040), because each call returns
// an empty document without reading it; Load reads one document and ignores the rest.
class SecondDocument : public YAML::EventHandler {
public:
    // False when nothing follows the first document. `start` is the mark of the second's first
    // token ('---', or the token the first document stopped at), `node` its first node's.
    static bool find(const std::string &text, YAML::Mark &start, YAML::Mark &node)
    {
        std::istringstream in(text);
        YAML::Parser parser(in);
        SecondDocument events;
        if (!parser.HandleNextDocument(events) || !parser) return false;
        try {
            parser.HandleNextDocument(events);
        } catch (const YAML::Exception &) {  // a broken second document is still a second one
        }
        start = events.start_, node = events.node_;
        return true;
    }

    void OnDocumentStart(const YAML::Mark &mark) override
    {
        if (++documents_ == 2) start_ = node_ = mark;
    }
    void OnDocumentEnd() override {}
    void OnNull(const YAML::Mark &mark, YAML::anchor_t) override { first_node(mark); }
    void OnAlias(const YAML::Mark &mark, YAML::anchor_t) override { first_node(mark); }
    void OnScalar(const YAML::Mark &mark, const std::string &, YAML::anchor_t, const std::string &) override
    {
        first_node(mark);
    }
    void OnSequenceStart(const YAML::Mark &mark, const std::string &, YAML::anchor_t, YAML::EmitterStyle::value) override
    {
        first_node(mark);
    }
    void OnSequenceEnd() override {}
    void OnMapStart(const YAML::Mark &mark, const std::string &, YAML::anchor_t, YAML::EmitterStyle::value) override
    {
        first_node(mark);
    }
    void OnMapEnd() override {}

private:
    void first_node(const YAML::Mark &mark)
    {
        if (documents_ == 2 && !seen_node_) node_ = mark, seen_node_ = true;
    }
    int documents_ = 0;
    bool seen_node_ = false;
    YAML::Mark start_, node_;
};

}  // namespace

bool parse_scene_text(const std::string &text, const std::string &name_for_errors, const std::string &base_dir,
                      Scene &scene, std::string &error)
{
    Reader reader(name_for_errors, base_dir);
    if (text.size() > kMaxFileBytes) {
        error = name_for_errors + ": " + std::to_string(text.size()) + " bytes, more than the 64 MB a scene file may be";
        return false;
    }
    // yaml-cpp reads up to a NUL as if the text ended there: say where the binary data starts.
    const std::size_t nul = text.find('\0');
    if (nul != std::string::npos) {
        reader.fail_at(int(std::count(text.begin(), text.begin() + long(nul), '\n')), "a NUL byte: this is not a text file");
        error = reader.error();
        return false;
    }
    Scene local;
    local.name = name_for_errors;
    try {
        const YAML::Node root = YAML::Load(text);
        YAML::Mark start, node;
        if (SecondDocument::find(text, start, node)) {
            const std::size_t from = std::min(text.size(), std::size_t(std::max(start.pos, 0)));
            if (text.compare(from, 3, "---") == 0) {
                reader.fail_at(node.line, "a second YAML document ('---'): a scene file holds one");
            } else {  // a token yaml-cpp 0.7 ends the first document at (a stray ','), or more after '...'
                const std::string rest = text.substr(from, std::min<std::size_t>(20, text.find('\n', from) - from));
                reader.fail_at(start.line, "YAML syntax error: unexpected '" + rest + "'");
            }
        } else if (reader.read_scene(root, local)) {
            scene = std::move(local);
            return true;
        }
    } catch (const YAML::DeepRecursion &e) {  // its own message is a bare "bad file"
        reader.fail_at(e.mark.line, "YAML nested more than " + std::to_string(e.depth() - 1) +
                                        " levels deep: not a scene");
    } catch (const YAML::Exception &e) {
        reader.fail_at(e.mark.line, "YAML syntax error: " + e.msg);
    } catch (const std::exception &e) {  // bad_alloc and the like: still a clean refusal
        reader.fail_at(0, std::string("cannot read the scene: ") + e.what());
    }
    error = reader.error();
    return false;
}

bool load_scene_file(const std::string &path, Scene &scene, std::string &error)
{
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (ec || !fs::exists(status)) {
        error = path + ": cannot read the scene file: " + (ec ? ec.message() : std::string("No such file or directory"));
        return false;
    }
    if (fs::is_directory(status)) {
        error = path + ": is a folder, not a scene file";
        return false;
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        error = path + ": cannot read the scene file: " + std::strerror(errno);
        return false;
    }
    // Read at most one byte past the limit, so a huge (or endless, like a pipe) input is refused
    // without being held in memory.
    std::string text;
    char buffer[1 << 16];
    while (in.read(buffer, sizeof buffer) || in.gcount() > 0) {
        text.append(buffer, std::size_t(in.gcount()));
        if (text.size() > kMaxFileBytes) {
            error = path + ": larger than the 64 MB a scene file may be";
            return false;
        }
    }
    if (in.bad()) {
        error = path + ": read error";
        return false;
    }
    std::string base = fs::path(path).parent_path().string();
    return parse_scene_text(text, path, base, scene, error);
}

}  // namespace kr
