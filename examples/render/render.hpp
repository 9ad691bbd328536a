// kdrt-render's renderer: presets, textures, the tracer and image files, on the scene model of
// scene.hpp. The command line (main.cpp), kdrt-view (examples/view) and the tests use only this
// header and scene.hpp.
#pragma once

#include "scene.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace common {
class ThreadScheduler;  // common/thread_scheduler.hpp
}

namespace kr {

// ---- presets.cpp ----

// The original's presets, in its order (the order a viewer cycles them with p/P).
std::vector<std::string> preset_names();
// Fills scene with the named preset's scene and settings (name case-insensitive). false with a
// message listing the names when there is no such preset.
bool make_preset(const std::string &name, Scene &scene, std::string &error);

// ---- meshes.cpp (beside load_meshes, declared in scene.hpp) ----

// Loads the pixels of every Texture that names a file and has none yet, through stb_image,
// converting sRGB to linear. false with a message naming the file.
bool load_textures(Scene &scene, std::string &error);

// ---- image_io.cpp ----

// Linear RGB, row-major from the top row, 3 floats a pixel.
struct Image {
    uint32_t width = 0, height = 0;
    std::vector<float> rgb;
};

// .png (sRGB, clamped to [0, 1], 8 bits) or .exr (linear, half or float), chosen by the path's
// extension (case-insensitive). Written to a temporary file in the same directory and renamed
// over path, so on failure no output and no temporary file exist.
bool write_image(const std::string &path, const Image &image, bool exr_float, std::string &error);
// Reads a .exr (OpenEXR, its R, G and B channels) or .png (stb_image, sRGB decoded to linear).
bool read_image(const std::string &path, Image &image, std::string &error);
// Any 8-bit image stb_image reads (PNG, JPEG, BMP, TGA, ...), sRGB decoded to linear: PNGs for
// read_image, and textures.
bool read_srgb_image(const std::string &path, Image &image, std::string &error);
// true when path ends in .png or .exr; else false with a message.
bool check_image_extension(const std::string &path, std::string &error);
// An 8-bit sRGB image (3 bytes a pixel, rows from the top) as a PNG, written atomically as
// write_image's PNGs are (whose bytes are these for the pixels linear_to_srgb8 gives), with one
// tEXt chunk per (keyword, text) pair after the header (Latin-1 keywords of 1 to 79 characters).
bool write_png8(const std::string &path, uint32_t width, uint32_t height, const std::vector<unsigned char> &rgb,
                const std::vector<std::pair<std::string, std::string>> &text, std::string &error);
// A linear value as write_image's PNGs store it: clamped to [0, 1], sRGB-encoded, rounded.
unsigned char linear_to_srgb8(float v);
// Root mean square difference over every pixel and channel; the sizes must match.
bool image_rmse(const Image &a, const Image &b, double &rmse, std::string &error);

// ---- render.cpp ----

struct RenderOptions {
    uint32_t width = 800, height = 600;
    unsigned threads = 0;   // 0: every core
    uint64_t seed = 0;      // with frame and the pixel's index, seeds each pixel's random stream
    uint32_t frame = 0;
    bool progress = false;  // progress bar with ETA on stderr
    // Pixels are traced in tiles of 4x4, a batch of camera rays each; true makes every tile one
    // pixel (the same image, bit for bit: the tests' reference for the tiles).
    bool one_pixel_tiles = false;
};

// Progressive rendering (kdrt-view): the sums of each pixel's samples so far and where its random
// stream stopped, so that frame after frame adds samples to the same image.
struct Accumulation {
    uint32_t width = 0, height = 0;
    uint32_t samples = 0;               // samples a pixel so far; set to 0 to start again
    std::vector<double> sum;            // 3 a pixel
    std::vector<uint64_t> stream;       // each pixel's random stream (common::Rng's state)
    std::vector<unsigned char> srgb;    // the mean, as linear_to_srgb8 encodes it, 3 bytes a pixel
    uint64_t rays = 0;                  // rays the last accumulate() traced (camera, bounce, shadow)
};

// The kd-tree's node boxes, for drawing them (kdrt-view's `k`).
struct TreeBox {
    Vec3 lo, hi;
    uint32_t depth = 0;
    bool leaf = false;
};

enum class TreeBuilder { sah, median };

// One point where a ray met a mirror or glass surface, and the direction it left in.
struct PathEvent {
    Vec3 point;
    Vec3 direction;     // unit; after reflection or refraction
    bool refracted = false;
    bool reflected = false;  // mirror or total internal reflection
};

// A scene made ready to trace: one kdrt_scene over every mesh (a mesh geometry each, its ID the
// mesh's index; one kd-tree over all their triangles, one query for them all) and vertex normals
// per mesh. It reads the Scene it was prepared from, which must outlive it and whose meshes must
// not change; materials, lights, camera and settings other than MESH and MAX_LEAF_SIZE may change
// between renders (animation).
class Renderer {
public:
    Renderer();
    ~Renderer();
    Renderer(const Renderer &) = delete;
    Renderer &operator=(const Renderer &) = delete;

    // Builds the meshes' scene (on `threads` threads, 0 = every core; by the SAH unless told
    // otherwise), after load_meshes. false with a message when it cannot be built.
    bool prepare(const Scene &scene, unsigned threads, std::string &error, TreeBuilder builder = TreeBuilder::sah);
    // The same with the meshes' tree loaded (kdrt_scene_load) from `saved`, the bytes of
    // save_tree()'s file at `path` (for the messages), instead of built: the builder and leaf size
    // are the file's. false with a message naming the file and why it was refused: not a saved
    // tree, another format version, truncated, damaged, or saved over other meshes (naming the
    // first that differs), or of another leaf size than the scene's MAX_LEAF_SIZE.
    bool prepare_saved(const Scene &scene, unsigned threads, const std::vector<unsigned char> &saved,
                       const std::string &path, std::string &error);
    // Seconds prepare() took to build the tree, or prepare_saved() to load it.
    double build_seconds() const;
    // The meshes' tree as prepared, saved to path (kdrt_scene_save_meshes, written whole or not
    // at all). false with a message when there are no meshes or it cannot be written.
    bool save_tree(const std::string &path, std::string &error) const;

    // Renders the scene into image (resized to options' size): NSAMPLES samples a pixel, one at
    // the pixel's centre, more jittered over it, in 4x4 tiles on options.threads threads: each
    // sample's camera rays of a tile traced in one batch, and their shadow rays in one a light.
    bool render(const RenderOptions &options, Image &image, std::string &error) const;

    // Adds samples to acc (restarted at options' size when its size differs), through the same
    // tiles on `scheduler`'s threads, and fills acc.srgb. The first call takes one sample a pixel,
    // the second starts again with two, every later one adds one: after n calls the mean is, bit
    // for bit, render()'s image with NSAMPLES = n (same seed and frame). NSAMPLES is not read.
    bool accumulate(const RenderOptions &options, Accumulation &acc, common::ThreadScheduler &scheduler,
                    std::string &error) const;

    // The node boxes of the meshes' kd-tree down to max_depth (the root is depth 0), parents
    // first; none without meshes. Built again for the purpose (the scene does not show its tree),
    // from the same triangles with the same options.
    std::vector<TreeBox> tree_boxes(uint32_t max_depth) const;

    // Follows one ray through mirrors and glass the way the shading does (pure refraction:
    // FRESNEL is ignored), up to max_events surfaces; stops at a diffuse surface, a light or the
    // background. For the tests.
    std::vector<PathEvent> trace_specular_path(Vec3 origin, Vec3 direction, uint32_t max_events) const;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

}  // namespace kr
