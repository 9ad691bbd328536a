// libFuzzer target: kdrt-render's scene-file reader (examples/render/scene_file.*) on any text.
// Checked: it returns, without a crash, a leak or undefined behaviour; a refused file gets one
// line of error that names the file; an accepted one has a camera and something to see.
// Relative texture and mesh paths resolve in a folder of this process's own that holds two empty
// files, t.png and m.obj (the reader only checks that a file can be opened): others are missing.
#include "scene_file.hpp"
#include "fuzz_support.hpp"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>
#include <system_error>
#include <unistd.h>

namespace {

// The folder, removed at exit.
struct BaseDir {
    std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("kdrt-fuzz-scene-" + std::to_string(getpid()));
    BaseDir() {
        std::filesystem::create_directories(path);
        for (const char *name : {"t.png", "m.obj"}) std::ofstream(path / name).put('\n');
    }
    ~BaseDir() {
        std::error_code ignored;
        std::filesystem::remove_all(path, ignored);
    }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    const std::string text(reinterpret_cast<const char *>(data), size);
    kr::Scene scene;
    std::string error;
    static const BaseDir dir;
    if (kr::parse_scene_text(text, "fuzz.yaml", dir.path.string(), scene, error)) {
        FUZZ_CHECK(error.empty(), "accepted with an error: %s", error.c_str());
        FUZZ_CHECK(!scene.spheres.empty() || !scene.quads.empty() || !scene.meshes.empty(), "accepted an empty scene");
    } else {
        FUZZ_CHECK(!error.empty(), "refused without a message");
        FUZZ_CHECK(error.find('\n') == std::string::npos, "a message of more than one line: %s", error.c_str());
        FUZZ_CHECK(error.rfind("fuzz.yaml", 0) == 0, "a message that does not name the file: %s", error.c_str());
    }
    return 0;
}
