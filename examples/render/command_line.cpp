#include "command_line.hpp"

#include "common/output.hpp"  // common::UsageError
#include "render.hpp"         // make_preset
#include "common/parse.hpp"   // common::parse_count, common::parse_size

namespace kr {

bool take_scene_arg(const std::string &arg, const std::function<std::string()> &next, SceneArgs &args)
{
    using common::UsageError;
    if (arg == "--preset") {
        // An empty name is no preset, refused as an unknown one is, not the default.
        args.preset = next();
        Scene unused;
        std::string error;
        if (args.preset.empty() && !make_preset(args.preset, unused, error)) throw UsageError{error};
    } else if (arg == "--scene") {
        args.scene_file = next();
        if (args.scene_file.empty()) throw UsageError{"--scene needs a file, not ''"};
    } else if (arg == "--set") {
        args.sets.push_back(next());
    } else if (arg == "--size") {
        const std::string v = next();
        uint32_t w = 0, h = 0;
        if (!common::parse_size(v, 16384, w, h) || uint64_t(w) * h > (uint64_t(1) << 26))
            throw UsageError{"bad --size '" + v + "': expected WxH, each side 1..16384, at most 64 Mpixels"};
        args.width = w, args.height = h;
    } else if (arg == "--threads") {
        const std::string v = next();
        uint64_t n = 0;
        if (!common::parse_count(v, 1024, n) || n == 0) throw UsageError{"bad --threads '" + v + "': expected 1..1024"};
        args.threads = unsigned(n);
    } else if (arg == "--seed") {
        const std::string v = next();
        if (!common::parse_count(v, UINT64_MAX, args.seed)) throw UsageError{"bad --seed '" + v + "': expected an unsigned integer"};
    } else {
        return false;
    }
    return true;
}

bool apply_sets(const std::vector<std::string> &sets, Scene &scene, std::string &error)
{
    for (const std::string &s : sets) {
        const size_t eq = s.find('=');
        if (eq == std::string::npos || eq == 0) {
            error = "bad --set '" + s + "': expected KEY=VALUE";
            return false;
        }
        if (!apply_setting(scene, s.substr(0, eq), s.substr(eq + 1), error)) {
            error = "--set: " + error;
            return false;
        }
    }
    return true;
}

}  // namespace kr
