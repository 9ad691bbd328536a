// Meshes and textures of a scene, read from files: kr::load_meshes and kr::load_textures.
#include "render.hpp"

#include <algorithm>
#include <cmath>
#include <sys/stat.h>

namespace kr {
namespace {

bool is_file(const std::string &path)
{
    struct stat st;
    return !path.empty() && stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

bool is_dir(const std::string &path)
{
    struct stat st;
    return !path.empty() && stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

// A mesh named without a folder or extension, and not a file of that name, is looked up in the
// mesh folder: common/NAME.obj, then seed/NAME.off. Anything else is a path.
bool is_bare_name(const std::string &file)
{
    return file.find('/') == std::string::npos && file.find('.') == std::string::npos && !is_file(file);
}

// Scale so the box's largest side is `size`, turn about +y, put the box's bottom centre at
// `position`.
void place(MeshInstance &m)
{
    std::vector<float> &p = m.mesh.positions;
    if (p.empty()) return;
    double lo[3] = {p[0], p[1], p[2]}, hi[3] = {p[0], p[1], p[2]};
    for (size_t i = 0; i < p.size(); i += 3)
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], double(p[i + a])), hi[a] = std::max(hi[a], double(p[i + a]));
    const double largest = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    const double scale = largest > 0 ? m.size / largest : 1.0;
    const double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]);
    const double angle = m.rotate_y_degrees * 3.14159265358979323846 / 180.0;
    const double c = std::cos(angle), s = std::sin(angle);
    for (size_t i = 0; i < p.size(); i += 3) {
        const double x = (p[i] - cx) * scale, y = (p[i + 1] - lo[1]) * scale, z = (p[i + 2] - cz) * scale;
        p[i] = float(m.position.x + c * x + s * z);
        p[i + 1] = float(m.position.y + y);
        p[i + 2] = float(m.position.z - s * x + c * z);
    }
}

}  // namespace

bool load_meshes(Scene &scene, std::string &error)
{
    const std::string dir = common::mesh_dir();  // the environment's KDRT_MESH_DIR, else the configured one
    for (size_t i = 0; i < scene.meshes.size(); ++i) {
        MeshInstance &m = scene.meshes[i];
        // MESH replaces the scene's first mesh (the presets put their main one first).
        const std::string file = i == 0 && !scene.settings.mesh.empty() ? scene.settings.mesh : m.file;
        std::string path;
        if (file.empty()) {
            // A generated mesh the scene holds already.
            if (m.mesh.positions.empty()) {
                error = "mesh " + std::to_string(i) + " has neither a file nor triangles";
                return false;
            }
            if (m.source.empty()) m.source = m.mesh.name.empty() ? "generated" : m.mesh.name;
        } else if (is_bare_name(file)) {
            const std::string obj = dir + "/common/" + file + ".obj", off = dir + "/seed/" + file + ".off";
            if (is_file(obj)) path = obj;
            else if (is_file(off)) path = off;
            else if (!is_dir(dir)) {
                // No mesh folder at all: the generated stand-in, so the scene still renders.
                m.mesh = common::torus(64, 32, 1.0, 0.35, 0.6);
                m.source = "generated torus (no mesh folder " + (dir.empty() ? std::string("configured") : dir) +
                           " for " + file + ")";
            } else {
                error = "no mesh named '" + file + "' in " + dir + "/common (.obj) or " + dir + "/seed (.off)";
                return false;
            }
        } else {
            path = file;  // common::load_mesh says what is wrong with it: missing, a directory, a FIFO...
        }
        if (!path.empty()) {
            std::string why;
            common::Mesh loaded;
            if (!common::load_mesh(path, loaded, why)) {
                error = "cannot load mesh " + path + ": " + why;
                return false;
            }
            if (loaded.triangle_count() == 0) {
                error = "mesh " + path + " has no triangles";
                return false;
            }
            m.mesh = std::move(loaded);
            m.source = path;
        }
        place(m);
    }
    return true;
}

bool load_textures(Scene &scene, std::string &error)
{
    for (Texture &t : scene.textures) {
        if (t.file.empty() || !t.rgb.empty()) continue;
        Image image;
        if (!read_srgb_image(t.file, image, error)) {
            error = "texture " + t.name + ": " + error;
            return false;
        }
        t.width = image.width, t.height = image.height;
        t.rgb = std::move(image.rgb);
    }
    return true;
}

}  // namespace kr
