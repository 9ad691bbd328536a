// kdrt-render's renderer: presets, textures, the tracer and image files, on the scene model of
// scene.hpp. The command line (main.cpp) and the tests use only this header and scene.hpp.
#pragma once

#include "scene.hpp"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

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
// Root mean square difference over every pixel and channel; the sizes must match.
bool image_rmse(const Image &a, const Image &b, double &rmse, std::string &error);

// ---- render.cpp ----

struct RenderOptions {
    uint32_t width = 800, height = 600;
    unsigned threads = 0;   // 0: every core
    uint64_t seed = 0;      // with frame and the pixel's index, seeds each pixel's random stream
    uint32_t frame = 0;
    bool progress = false;  // progress bar with ETA on stderr
};

// One point where a ray met a mirror or glass surface, and the direction it left in.
struct PathEvent {
    Vec3 point;
    Vec3 direction;     // unit; after reflection or refraction
    bool refracted = false;
    bool reflected = false;  // mirror or total internal reflection
};

// A scene made ready to trace: a kdrt tree and vertex normals per mesh. It reads the Scene it was
// prepared from, which must outlive it and whose meshes must not change; materials, lights,
// camera and settings other than MESH and MAX_LEAF_SIZE may change between renders (animation).
class Renderer {
public:
    Renderer();
    ~Renderer();
    Renderer(const Renderer &) = delete;
    Renderer &operator=(const Renderer &) = delete;

    // Builds the trees (on `threads` threads, 0 = every core), after load_meshes. false with a
    // message when a tree cannot be built.
    bool prepare(const Scene &scene, unsigned threads, std::string &error);
    double build_seconds() const;

    // Renders the scene into image (resized to options' size).
    bool render(const RenderOptions &options, Image &image, std::string &error) const;

    // Follows one ray through mirrors and glass the way the shading does (pure refraction:
    // FRESNEL is ignored), up to max_events surfaces; stops at a diffuse surface, a light or the
    // background. For the tests.
    std::vector<PathEvent> trace_specular_path(Vec3 origin, Vec3 direction, uint32_t max_events) const;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

}  // namespace kr
