// The command-line options kdrt-render and kdrt-view share: which scene, its settings, the image
// size, the threads and the seed.
#pragma once

#include "scene.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace kr {

struct SceneArgs {
    std::string preset, scene_file;  // neither: PICTURE
    std::vector<std::string> sets;   // --set KEY=VALUE, after the preset's or the file's own settings
    uint32_t width = 800, height = 600;
    unsigned threads = 0;            // 0: every core
    uint64_t seed = 0;
};

// When arg is --preset, --scene, --set, --size (WxH, sides 1..16384, at most 64 Mpixels),
// --threads (1..1024) or --seed, reads its value with next() into args and returns true; a bad
// value throws common::UsageError, and so does an empty --preset or --scene (which would otherwise
// mean the default, PICTURE). Any other argument: false, args untouched.
bool take_scene_arg(const std::string &arg, const std::function<std::string()> &next, SceneArgs &args);

// Each --set KEY=VALUE applied to scene in turn (apply_setting). False at the first bad one, with
// "bad --set 'TEXT': expected KEY=VALUE" or "--set: " and apply_setting's message in error: a bad
// command line.
bool apply_sets(const std::vector<std::string> &sets, Scene &scene, std::string &error);

}  // namespace kr
