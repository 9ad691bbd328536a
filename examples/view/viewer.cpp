// kdrt-view's state: scenes loaded and their meshes' tree built through kdrt_render_core, frames
// of samples added by Renderer::accumulate on the viewer's ThreadScheduler, the camera moved about
// its target, and the window's pixels composed (image, kd-tree boxes, help).
#include "viewer.hpp"

#include "command_line.hpp"   // kr::apply_sets
#include "common/timing.hpp"  // common::Stopwatch
#include "font.hpp"
#include "scene_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace view {
namespace {

using kr::Vec3;

const double kPi = 3.14159265358979323846;

std::string upper(std::string s)
{
    for (char &c : s) c = char(std::toupper(static_cast<unsigned char>(c)));
    return s;
}

// v turned by angle (radians) about the unit axis k (Rodrigues).
Vec3 rotate(Vec3 v, Vec3 k, double angle)
{
    const double c = std::cos(angle), s = std::sin(angle);
    return c * v + s * kr::cross(k, v) + (kr::dot(k, v) * (1 - c)) * k;
}

std::string fixed(double v, int decimals)
{
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, v);
    return text;
}

// The camera's axes and where a world point lands on a width x height image (as the renderer's
// rays leave the camera); false behind the camera's near plane.
struct Projection {
    Vec3 position, forward, right, up;
    double tan_half = 1, aspect = 1, width = 1, height = 1;
    Projection(const kr::Camera &cam, uint32_t w, uint32_t h)
        : position(cam.position), forward(kr::normalize(cam.target - cam.position)),
          right(kr::normalize(kr::cross(forward, cam.up))), up(kr::cross(right, forward)),
          tan_half(std::tan(0.5 * cam.fov_degrees * kPi / 180.0)), aspect(double(w) / h), width(w), height(h)
    {
    }
    Vec3 to_camera(Vec3 p) const
    {
        const Vec3 d = p - position;
        return {kr::dot(d, right), kr::dot(d, up), kr::dot(d, forward)};
    }
    void to_screen(Vec3 c, double &x, double &y) const
    {
        x = (c.x / (c.z * tan_half * aspect) + 1) * 0.5 * width;
        y = (1 - c.y / (c.z * tan_half)) * 0.5 * height;
    }
};

// Liang-Barsky: clips the segment to [0, w) x [0, h); false when nothing is left.
bool clip(double &x0, double &y0, double &x1, double &y1, double w, double h)
{
    double t0 = 0, t1 = 1;
    const double dx = x1 - x0, dy = y1 - y0;
    const double p[4] = {-dx, dx, -dy, dy}, q[4] = {x0, w - 1 - x0, y0, h - 1 - y0};
    for (int i = 0; i < 4; ++i) {
        if (p[i] == 0) {
            if (q[i] < 0) return false;
            continue;
        }
        const double r = q[i] / p[i];
        if (p[i] < 0) t0 = std::max(t0, r);
        else t1 = std::min(t1, r);
        if (t0 > t1) return false;
    }
    x1 = x0 + t1 * dx, y1 = y0 + t1 * dy;
    x0 = x0 + t0 * dx, y0 = y0 + t0 * dy;
    return true;
}

}  // namespace

const std::vector<std::string> &key_names()
{
    static const std::vector<std::string> names = {
        "p", "P", "w", "a", "S", "d", "q", "e", "Up", "Down", "Left", "Right", "PageUp", "PageDown",
        "g", "m", "s", "i", "+", "-", "b", "k", "[", "]", "h", "F12", "F2", "Esc"};
    return names;
}

Viewer::Viewer(const Options &options) : options_(options) {}

bool Viewer::open(std::string &error, bool &usage_error)
{
    int index = -1;
    if (options_.scene_file.empty()) {
        const std::string name = upper(options_.preset.empty() ? "PICTURE" : options_.preset);
        const std::vector<std::string> names = kr::preset_names();
        const auto it = std::find(names.begin(), names.end(), name);
        if (it == names.end()) {
            kr::Scene unused;
            kr::make_preset(options_.preset, unused, error);  // its message lists the presets
            usage_error = true;
            return false;
        }
        index = int(it - names.begin());
    }
    return load(index, error, usage_error);
}

bool Viewer::load(int preset_index, std::string &error, bool &usage_error)
{
    usage_error = false;
    kr::Scene next;
    if (preset_index < 0) {
        if (!kr::load_scene_file(options_.scene_file, next, error)) return false;
    } else if (!kr::make_preset(kr::preset_names()[size_t(preset_index)], next, error)) {
        usage_error = true;
        return false;
    }
    if (!kr::apply_sets(options_.sets, next, error)) {
        usage_error = true;
        return false;
    }
    scheduler_.reset();  // no threads of ours while load_mesh forks (see viewer.hpp)
    const bool loaded = kr::load_meshes(next, error) && kr::load_textures(next, error);
    scheduler_.reset(new common::ThreadScheduler(options_.threads));
    if (!loaded) return false;
    std::string sources;
    for (const kr::MeshInstance &m : next.meshes) sources += (sources.empty() ? "" : ", ") + m.source;
    std::fprintf(stderr, "kdrt-view: %s, meshes: %s\n", next.name.c_str(), sources.empty() ? "none" : sources.c_str());
    // The renderer reads the scene it was prepared from: a new one before the scene is replaced.
    renderer_.reset(new kr::Renderer);
    scene_ = std::move(next);
    preset_index_ = preset_index;
    soft_shadow_rays_ = scene_.settings.shadow_rays > 1 ? scene_.settings.shadow_rays : 8;
    return rebuild(error);
}

bool Viewer::rebuild(std::string &error)
{
    if (!renderer_->prepare(scene_, options_.threads, error, builder_)) return false;
    build_ms_ = 1000 * renderer_->build_seconds();
    uint64_t triangles = 0;
    for (const kr::MeshInstance &m : scene_.meshes) triangles += m.mesh.triangle_count();
    if (!scene_.meshes.empty())
        std::fprintf(stderr, "kdrt-view: %s: tree built in %.1f ms (%s, max leaf size %u, %llu triangles)\n",
                     scene_.name.c_str(), build_ms_, builder_ == kr::TreeBuilder::sah ? "SAH" : "median",
                     scene_.settings.max_leaf_size, (unsigned long long)triangles);
    boxes_valid_ = false;
    restart();
    return true;
}

bool Viewer::key(const std::string &name, KeyResult &result, std::string &error)
{
    result = KeyResult::handled;
    kr::Settings &st = scene_.settings;
    const int presets = int(kr::preset_names().size());
    bool usage_error = false;
    if (name == "p" || name == "P") {
        const int step = name == "p" ? 1 : presets - 1;
        const int next = preset_index_ < 0 ? (name == "p" ? 0 : presets - 1) : (preset_index_ + step) % presets;
        return load(next, error, usage_error);
    }
    if (name == "w") move(1, 0, 0);
    else if (name == "S") move(-1, 0, 0);
    else if (name == "a") move(0, -1, 0);
    else if (name == "d") move(0, 1, 0);
    else if (name == "q") move(0, 0, -1);
    else if (name == "e") move(0, 0, 1);
    else if (name == "Up") move(1, 0, 0);
    else if (name == "Down") move(-1, 0, 0);
    else if (name == "Left") move(0, -1, 0);
    else if (name == "Right") move(0, 1, 0);
    else if (name == "PageUp") move(0, 0, 1);
    else if (name == "PageDown") move(0, 0, -1);
    else if (name == "g") st.enable_glass = !st.enable_glass, restart();
    else if (name == "m") st.enable_mirror = !st.enable_mirror, restart();
    else if (name == "s") st.shadow_rays = st.shadow_rays == 0 ? 1 : st.shadow_rays == 1 ? soft_shadow_rays_ : 0, restart();
    else if (name == "i") st.enable_interpolation = !st.enable_interpolation, restart();
    else if (name == "+" || name == "-") {
        const uint32_t old = st.max_leaf_size;
        // 1 to 64 (0, no tree, only from --set: too slow to show a mesh in a window).
        st.max_leaf_size = name == "+" ? std::min(64u, old + 1) : old > 1 ? old - 1 : old;
        if (st.max_leaf_size != old) return rebuild(error);
    } else if (name == "b") {
        builder_ = builder_ == kr::TreeBuilder::sah ? kr::TreeBuilder::median : kr::TreeBuilder::sah;
        return rebuild(error);
    } else if (name == "k") show_boxes_ = !show_boxes_;
    else if (name == "[") box_depth_ = box_depth_ > 0 ? box_depth_ - 1 : 0, boxes_valid_ = false;
    else if (name == "]") box_depth_ = std::min(16u, box_depth_ + 1), boxes_valid_ = false;
    else if (name == "h") show_help_ = !show_help_;
    else if (name == "F12" || name == "F2") result = KeyResult::screenshot;
    else if (name == "Esc") result = KeyResult::quit;
    else {
        error = "unknown key '" + name + "'";
        return false;
    }
    return true;
}

void Viewer::orbit(double dx, double dy)
{
    kr::Camera &cam = scene_.camera;
    const Vec3 up = kr::normalize(cam.up);
    Vec3 offset = cam.position - cam.target;
    offset = rotate(offset, up, -0.01 * dx);
    // Pitch, stopping short of the poles, where the view direction would meet the up vector.
    const Vec3 right = kr::normalize(kr::cross(-1.0 * offset, up));
    const Vec3 pitched = rotate(offset, right, -0.01 * dy);
    const double c = kr::dot(kr::normalize(pitched), up);
    if (std::fabs(c) < 0.995) offset = pitched;
    cam.position = cam.target + offset;
    restart();
}

void Viewer::pan(double dx, double dy, uint32_t height)
{
    kr::Camera &cam = scene_.camera;
    const Projection pr(cam, 1, std::max(1u, height));
    const double scale = 2 * kr::length(cam.target - cam.position) * pr.tan_half / std::max(1u, height);
    const Vec3 shift = (-dx * scale) * pr.right + (dy * scale) * pr.up;
    cam.position = cam.position + shift, cam.target = cam.target + shift;
    restart();
}

void Viewer::zoom(double steps)
{
    kr::Camera &cam = scene_.camera;
    const Vec3 offset = std::pow(0.9, steps) * (cam.position - cam.target);
    if (kr::length(offset) > 1e-3) cam.position = cam.target + offset;
    restart();
}

// A step of a twentieth of the distance to the target, position and target together.
void Viewer::move(double forward, double right, double up)
{
    kr::Camera &cam = scene_.camera;
    const Projection pr(cam, 1, 1);
    const double step = 0.05 * kr::length(cam.target - cam.position);
    const Vec3 shift = (forward * step) * pr.forward + (right * step) * pr.right + (up * step) * pr.up;
    cam.position = cam.position + shift, cam.target = cam.target + shift;
    restart();
}

bool Viewer::render(uint32_t width, uint32_t height, bool preview, std::string &error)
{
    width_ = width, height_ = height;
    const uint32_t w = preview ? std::max(1u, width / 2) : width, h = preview ? std::max(1u, height / 2) : height;
    if (preview) restart();  // a preview is always one sample a pixel
    if (converged() && w == acc_.width && h == acc_.height) return true;
    kr::RenderOptions options;
    options.width = w, options.height = h, options.seed = options_.seed;
    const common::Stopwatch clock;
    if (!renderer_->accumulate(options, acc_, *scheduler_, error)) return false;
    render_ms_ = clock.ms();
    return true;
}

std::string Viewer::frame_status() const
{
    const double mrays = render_ms_ > 0 ? double(acc_.rays) / (render_ms_ * 1000) : 0;
    return scene_.name + ", " + std::to_string(acc_.samples) + (acc_.samples == 1 ? " sample, " : " samples, ") +
           fixed(render_ms_, 1) + " ms a frame, " + fixed(mrays, 2) + " MRays/s";
}

std::string Viewer::tree_status() const
{
    if (scene_.meshes.empty()) return "no meshes: no kd-tree";
    return std::string("tree: ") + (builder_ == kr::TreeBuilder::sah ? "SAH" : "median") + ", leaf size " +
           std::to_string(scene_.settings.max_leaf_size) + ", built in " + fixed(build_ms_, 1) + " ms";
}

std::string Viewer::status() const { return "kdrt-view: " + frame_status() + "; " + tree_status(); }

const std::vector<uint32_t> &Viewer::compose()
{
    if (width_ == 0) width_ = acc_.width, height_ = acc_.height;
    pixels_.resize(size_t(width_) * height_);
    // The image's pixel under each window pixel (the same one but in a preview).
    for (uint32_t y = 0; y < height_; ++y)
        for (uint32_t x = 0; x < width_; ++x) {
            const uint32_t ix = uint32_t(uint64_t(x) * acc_.width / width_), iy = uint32_t(uint64_t(y) * acc_.height / height_);
            const unsigned char *p = &acc_.srgb[3 * (size_t(iy) * acc_.width + ix)];
            pixels_[size_t(y) * width_ + x] = 0xFF000000u | uint32_t(p[0]) << 16 | uint32_t(p[1]) << 8 | p[2];
        }
    if (show_boxes_) draw_boxes();
    if (show_help_) draw_help();
    return pixels_;
}

// Each node box's 12 edges, clipped to the near plane and the image; deeper nodes drawn later,
// over their parents, in colours that cycle with depth.
void Viewer::draw_boxes()
{
    if (!boxes_valid_) boxes_ = renderer_->tree_boxes(box_depth_), boxes_valid_ = true;
    static const uint32_t colours[] = {0xFFFFFFFFu, 0xFFFFD040u, 0xFF40FF60u, 0xFF40C0FFu, 0xFFFF60C0u, 0xFFFF8040u};
    const int W = int(width_), H = int(height_);
    const Projection pr(scene_.camera, width_, height_);
    const double near = 1e-3 * std::max(1e-9, kr::length(scene_.camera.target - scene_.camera.position));
    for (const kr::TreeBox &b : boxes_) {
        const uint32_t colour = colours[b.depth % 6];
        Vec3 corner[8];
        for (int c = 0; c < 8; ++c)
            corner[c] = pr.to_camera({c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y, c & 4 ? b.hi.z : b.lo.z});
        for (int c = 0; c < 8; ++c)
            for (int bit = 1; bit < 8; bit <<= 1) {
                if (c & bit) continue;
                Vec3 a = corner[c], e = corner[c | bit];
                if (a.z < near && e.z < near) continue;
                if (a.z < near) a = a + ((near - a.z) / (e.z - a.z)) * (e - a);
                if (e.z < near) e = e + ((near - e.z) / (a.z - e.z)) * (a - e);
                double x0, y0, x1, y1;
                pr.to_screen(a, x0, y0);
                pr.to_screen(e, x1, y1);
                if (!clip(x0, y0, x1, y1, W, H)) continue;
                const double steps = std::max(std::fabs(x1 - x0), std::fabs(y1 - y0));
                const int count = int(std::ceil(steps)) + 1;
                for (int i = 0; i < count; ++i) {
                    const double t = count > 1 ? double(i) / (count - 1) : 0;
                    const int x = int(std::lround(x0 + t * (x1 - x0))), y = int(std::lround(y0 + t * (y1 - y0)));
                    if (x >= 0 && y >= 0 && x < W && y < H) pixels_[size_t(y) * size_t(W) + size_t(x)] = colour;
                }
            }
    }
}

void Viewer::draw_help()
{
    const kr::Settings &st = scene_.settings;
    const auto on = [](bool b) { return b ? "on" : "off"; };
    std::string text = frame_status() + "\n" + tree_status() + "\n";
    text += std::string("glass ") + on(st.enable_glass) + ", mirrors " + on(st.enable_mirror) + ", shadow rays " +
            std::to_string(st.shadow_rays) + ",\ninterpolation " + on(st.enable_interpolation) +
            (show_boxes_ ? ", boxes to depth " + std::to_string(box_depth_) : std::string()) + "\n\n";
    text +=
        "p shift+p  next, previous preset\n"
        "drag  orbit   right drag  pan   wheel  zoom\n"
        "w a shift+s d q e, arrows  move\n"
        "g glass  m mirrors  s shadows  i interpolation\n"
        "+ -  leaf size   b  median/SAH builder\n"
        "k  tree boxes   [ ]  their depth\n"
        "F12 F2  screenshot   h  help   Esc  quit";
    const int W = int(width_), H = int(height_);
    int lines = 1, longest = 0, column = 0;
    for (const char c : text) {
        if (c == '\n') ++lines, column = 0;
        else longest = std::max(longest, ++column);
    }
    const int scale = W >= (4 * longest + 4) * 2 ? 2 : 1;  // doubled where the lines fit
    // Darken the panel under the text, then draw it.
    const int pw = std::min(W, (4 * longest + 4) * scale), ph = std::min(H, (7 * lines + 3) * scale);
    for (int y = 0; y < ph; ++y)
        for (int x = 0; x < pw; ++x) {
            uint32_t &p = pixels_[size_t(y) * size_t(W) + size_t(x)];
            p = 0xFF000000u | ((p >> 2) & 0x003F3F3Fu);
        }
    draw_text(pixels_, W, H, 2 * scale, 2 * scale, scale, 0xFFFFFFFFu, text);
}

bool Viewer::screenshot(const std::string &path, std::string &error)
{
    if (acc_.width == 0) {
        error = "cannot write '" + path + "': nothing rendered yet";
        return false;
    }
    // A key may have started the image again since the last frame (p then F12): render it first.
    if (acc_.samples == 0 && !render(width_, height_, false, error)) return false;
    compose();
    std::vector<unsigned char> rgb(pixels_.size() * 3);
    for (size_t i = 0; i < pixels_.size(); ++i) {
        rgb[3 * i] = (unsigned char)(pixels_[i] >> 16), rgb[3 * i + 1] = (unsigned char)(pixels_[i] >> 8);
        rgb[3 * i + 2] = (unsigned char)pixels_[i];
    }
    const std::string comment = std::to_string(acc_.samples) + (acc_.samples == 1 ? " sample" : " samples") +
                                " a pixel, seed " + std::to_string(options_.seed);
    if (!kr::write_png8(path, width_, height_, rgb,
                        {{"Title", scene_.name}, {"Comment", comment}, {"Software", "kdrt-view"}}, error))
        return false;
    std::fprintf(stderr, "kdrt-view: screenshot %s: %s, %ux%u, %u sample%s a pixel\n", path.c_str(), scene_.name.c_str(),
                 width_, height_, acc_.samples, acc_.samples == 1 ? "" : "s");
    return true;
}

}  // namespace view
