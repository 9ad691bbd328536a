// kdrt-view's state, without the window: the scene (a kdrt-render preset or scene file, through
// kdrt_render_core), the progressive image, the camera moves, the keys and what the window shows.
// main.cpp owns the SDL window and feeds it events (or the --keys replay).
#pragma once

#include "common/thread_scheduler.hpp"
#include "render.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace view {

struct Options {
    std::string preset, scene_file;  // neither: PICTURE
    std::vector<std::string> sets;   // KEY=VALUE, after each preset's or the file's own settings
    unsigned threads = 0;            // 0: every core
    uint64_t seed = 0;
};

// The key names main.cpp translates SDL's keys to, and --keys takes.
const std::vector<std::string> &key_names();

class Viewer {
public:
    // No image is taken past this many samples a pixel: the viewer then idles.
    static const uint32_t kMaxSamples = 4096;

    explicit Viewer(const Options &options);

    // Loads the first scene (--preset, --scene or PICTURE). false with a message; usage_error
    // then says whether the command line was at fault (an unknown preset, a bad --set: exit
    // status 2) or a file (1).
    bool open(std::string &error, bool &usage_error);

    enum class KeyResult { handled, quit, screenshot };
    // One key by name (key_names()); false with a message when it failed (the view stays usable).
    bool key(const std::string &name, KeyResult &result, std::string &error);

    // The mouse, in window pixels: orbit about the target, pan, zoom (wheel steps).
    void orbit(double dx, double dy);
    void pan(double dx, double dy, uint32_t height);
    void zoom(double steps);

    // Adds a frame of samples for a width x height window, unless converged. A preview (the
    // camera being dragged) is rendered at half the width and height, one sample a pixel, and
    // shown doubled; the image starts again at full size when the preview ends (or at a new size).
    bool render(uint32_t width, uint32_t height, bool preview, std::string &error);
    bool converged() const { return acc_.width != 0 && acc_.samples >= kMaxSamples; }
    // What the window shows (0xAARRGGBB, rows from the top, width() x height()): the image, then
    // the kd-tree's boxes (k) and the help (h).
    const std::vector<uint32_t> &compose();
    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }
    uint32_t image_width() const { return acc_.width; }   // the image rendered: half while previewing
    uint32_t image_height() const { return acc_.height; }

    // compose()'s pixels as a PNG written atomically, with the scene's name and the samples in
    // its text chunks (Title, Comment, Software).
    bool screenshot(const std::string &path, std::string &error);

    const std::string &scene_name() const { return scene_.name; }
    uint32_t samples() const { return acc_.samples; }
    double render_ms() const { return render_ms_; }           // the last frame's accumulate()
    uint64_t rays() const { return acc_.rays; }                // the last frame's rays
    // The title bar's line: the frame's (preset, samples, ms, MRays/s), then the tree's (builder,
    // leaf size, build time).
    std::string status() const;
    std::string frame_status() const;
    std::string tree_status() const;

private:
    bool load(int preset_index, std::string &error, bool &usage_error);
    bool rebuild(std::string &error);
    void restart() { acc_.samples = 0; }
    void move(double forward, double right, double up);
    void draw_boxes();
    void draw_help();

    Options options_;
    // Frames' tiles run on these threads. They are stopped while meshes load: common::load_mesh
    // forks a loader process, and a thread starting at that moment (holding the allocator's lock,
    // as ASan's does while a thread sets up) would leave the child deadlocked.
    std::unique_ptr<common::ThreadScheduler> scheduler_;
    int preset_index_ = -1;            // into kr::preset_names(); -1: the scene file
    kr::Scene scene_;
    std::unique_ptr<kr::Renderer> renderer_;
    kr::TreeBuilder builder_ = kr::TreeBuilder::sah;
    uint32_t soft_shadow_rays_ = 8;    // what `s` cycles to after 0 and 1
    kr::Accumulation acc_;
    double render_ms_ = 0;
    double build_ms_ = 0;
    bool show_boxes_ = false, show_help_ = false;
    uint32_t box_depth_ = 4;
    std::vector<kr::TreeBox> boxes_;   // to box_depth_, for the current tree
    bool boxes_valid_ = false;
    uint32_t width_ = 0, height_ = 0;  // the window's
    std::vector<uint32_t> pixels_;
};

}  // namespace view
