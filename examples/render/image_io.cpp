// Image files: OpenEXR (linear, half or float) and PNG (sRGB, clamped), written atomically
// (common/atomic_file.hpp): a temporary file beside the output, renamed over it once complete.
#include "render.hpp"

#include "common/atomic_file.hpp"  // common::write_atomically, common::write_file_atomically

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImathBox.h>
#include <half.h>
#include <stb_image.h>
#include <stb_image_write.h>


#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>

namespace kr {
namespace {

std::string lower_extension(const std::string &path)
{
    const size_t slash = path.find_last_of('/');
    const size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot);
    for (char &c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

float srgb8_to_linear(unsigned char v)
{
    const double c = v / 255.0;
    return float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

bool write_png(const std::string &path, const Image &image, std::string &error)
{
    std::vector<unsigned char> rgb(image.rgb.size());
    for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = linear_to_srgb8(image.rgb[i]);
    return write_png8(path, image.width, image.height, rgb, {}, error);
}

// PNG's CRC-32 (ISO 3309, the polynomial 0xEDB88320 reflected), of a chunk's type and data.
uint32_t png_crc(const std::string &bytes)
{
    uint32_t crc = 0xFFFFFFFFu;
    for (const unsigned char b : bytes) {
        crc ^= b;
        for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}

void append_be32(std::string &out, uint32_t v)
{
    for (int shift = 24; shift >= 0; shift -= 8) out.push_back(char((v >> shift) & 0xFF));
}

bool write_exr(const std::string &tmp, const Image &image, bool exr_float, std::string &error)
{
    try {
        Imf::Header header(int(image.width), int(image.height));
        const Imf::PixelType type = exr_float ? Imf::FLOAT : Imf::HALF;
        for (const char *c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(type));
        Imf::FrameBuffer frame;
        // OpenEXR converts pixel types when reading, not when writing: half channels get halves.
        std::vector<half> halves;
        char *base = reinterpret_cast<char *>(const_cast<float *>(image.rgb.data()));
        size_t component = sizeof(float);
        if (!exr_float) {
            halves.assign(image.rgb.begin(), image.rgb.end());  // rounded to nearest
            base = reinterpret_cast<char *>(halves.data());
            component = sizeof(half);
        }
        const size_t xs = 3 * component, ys = xs * image.width;
        frame.insert("R", Imf::Slice(type, base, xs, ys));
        frame.insert("G", Imf::Slice(type, base + component, xs, ys));
        frame.insert("B", Imf::Slice(type, base + 2 * component, xs, ys));
        Imf::OutputFile file(tmp.c_str(), header);
        file.setFrameBuffer(frame);
        file.writePixels(int(image.height));
    } catch (const std::exception &e) {
        error = e.what();  // write_atomically names the user's path for the temporary
        return false;
    }
    return true;
}

bool read_exr(const std::string &path, Image &image, std::string &error)
{
    try {
        Imf::InputFile file(path.c_str());
        const Imath::Box2i dw = file.header().dataWindow();
        const long w = long(dw.max.x) - dw.min.x + 1, h = long(dw.max.y) - dw.min.y + 1;
        if (w <= 0 || h <= 0 || w > 65536 || h > 65536) {
            error = path + ": unusable data window";
            return false;
        }
        image.width = uint32_t(w), image.height = uint32_t(h);
        image.rgb.assign(size_t(w) * size_t(h) * 3, 0.0f);
        Imf::FrameBuffer frame;
        const size_t xs = 3 * sizeof(float), ys = xs * size_t(w);
        // The slice's origin is pixel (0, 0) of the file's coordinates, which may lie outside.
        char *base = reinterpret_cast<char *>(image.rgb.data()) - (long(dw.min.x) * long(xs) + long(dw.min.y) * long(ys));
        const char *names[3] = {"R", "G", "B"};
        for (int c = 0; c < 3; ++c) {
            if (!file.header().channels().findChannel(names[c])) {
                error = path + ": no " + names[c] + " channel";
                return false;
            }
            frame.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xs, ys));
        }
        file.setFrameBuffer(frame);
        file.readPixels(dw.min.y, dw.max.y);
    } catch (const std::exception &e) {
        error = "cannot read " + path + ": " + e.what();
        return false;
    }
    return true;
}

}  // namespace

unsigned char linear_to_srgb8(float v)
{
    const double c = std::min(1.0, std::max(0.0, double(v)));  // clamp: no tone curve beyond it
    const double s = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055;
    return (unsigned char)std::lround(255.0 * s);
}

// The PNG encoded in memory, then written whole by common::write_file_atomically.
bool write_png8(const std::string &path, uint32_t width, uint32_t height, const std::vector<unsigned char> &rgb,
                const std::vector<std::pair<std::string, std::string>> &text, std::string &error)
{
    if (width == 0 || height == 0 || rgb.size() != size_t(width) * height * 3) {
        error = "cannot write '" + path + "': the image is empty or inconsistent";
        return false;
    }
    std::string png;
    const auto append = [](void *context, void *data, int size) {
        static_cast<std::string *>(context)->append(static_cast<const char *>(data), size_t(size));
    };
    if (!stbi_write_png_to_func(append, &png, int(width), int(height), 3, rgb.data(), int(width) * 3)) {
        error = "cannot write '" + path + "': cannot encode the PNG";
        return false;
    }
    // tEXt chunks go after IHDR (the 8-byte signature, then IHDR's 4 + 4 + 13 + 4 bytes).
    std::string chunks;
    for (const auto &kv : text) {
        if (kv.first.empty() || kv.first.size() > 79 || kv.first.find('\0') != std::string::npos ||
            kv.second.find('\0') != std::string::npos) {
            error = "cannot write '" + path + "': bad PNG text keyword '" + kv.first + "'";
            return false;
        }
        const std::string body = "tEXt" + kv.first + '\0' + kv.second;
        append_be32(chunks, uint32_t(body.size() - 4));
        chunks += body;
        append_be32(chunks, png_crc(body));
    }
    png.insert(33, chunks);
    return common::write_file_atomically(path, png, error);
}

bool check_image_extension(const std::string &path, std::string &error)
{
    const std::string ext = lower_extension(path);
    if (ext == ".png" || ext == ".exr") return true;
    error = "cannot write '" + path + "': the extension must be .png or .exr";
    return false;
}

bool write_image(const std::string &path, const Image &image, bool exr_float, std::string &error)
{
    if (!check_image_extension(path, error)) return false;
    if (image.width == 0 || image.height == 0 || image.rgb.size() != size_t(image.width) * image.height * 3) {
        error = "cannot write '" + path + "': the image is empty or inconsistent";
        return false;
    }
    if (lower_extension(path) == ".png") return write_png(path, image, error);
    return common::write_atomically(path, [&](const std::string &tmp, std::string &reason) {
        return write_exr(tmp, image, exr_float, reason);
    }, error);
}

bool read_image(const std::string &path, Image &image, std::string &error)
{
    const std::string ext = lower_extension(path);
    if (ext == ".exr") return read_exr(path, image, error);
    if (ext == ".png") return read_srgb_image(path, image, error);
    error = "cannot read '" + path + "': the extension must be .png or .exr";
    return false;
}

bool read_srgb_image(const std::string &path, Image &image, std::string &error)
{
    int w = 0, h = 0, channels = 0;
    unsigned char *pixels = stbi_load(path.c_str(), &w, &h, &channels, 3);
    if (!pixels) {
        error = "cannot read " + path + ": " + (stbi_failure_reason() ? stbi_failure_reason() : "unknown error");
        return false;
    }
    image.width = uint32_t(w), image.height = uint32_t(h);
    image.rgb.resize(size_t(w) * size_t(h) * 3);
    for (size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = srgb8_to_linear(pixels[i]);
    stbi_image_free(pixels);
    return true;
}

bool image_rmse(const Image &a, const Image &b, double &rmse, std::string &error)
{
    if (a.width != b.width || a.height != b.height) {
        error = "the reference is " + std::to_string(b.width) + "x" + std::to_string(b.height) + ", the image " +
                std::to_string(a.width) + "x" + std::to_string(a.height) + ": sizes must match";
        return false;
    }
    double sum = 0;
    for (size_t i = 0; i < a.rgb.size(); ++i) {
        const double d = double(a.rgb[i]) - double(b.rgb[i]);
        sum += d * d;
    }
    rmse = a.rgb.empty() ? 0 : std::sqrt(sum / double(a.rgb.size()));
    return true;
}

}  // namespace kr
