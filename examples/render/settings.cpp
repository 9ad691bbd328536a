// The original's settings by name: --set KEY=VALUE and scene files' "settings" both come here.
#include "scene.hpp"

#include "common/parse.hpp"  // common::parse_count

#include <cctype>
#include <cerrno>
#include <cstdlib>

namespace kr {
namespace {

std::string upper(const std::string &text)
{
    std::string out = text;
    for (char &c : out) c = char(std::toupper(static_cast<unsigned char>(c)));
    return out;
}

bool parse_bool(const std::string &value, bool &out)
{
    const std::string v = upper(value);
    if (v == "1" || v == "TRUE" || v == "ON") out = true;
    else if (v == "0" || v == "FALSE" || v == "OFF") out = false;
    else return false;
    return true;
}

bool parse_number(const std::string &value, double lo, double hi, double &out)
{
    errno = 0;
    char *end = nullptr;
    const double v = std::strtod(value.c_str(), &end);
    if (value.empty() || errno != 0 || *end != '\0' || !(v >= lo && v <= hi)) return false;
    out = v;
    return true;
}

}  // namespace

std::vector<std::string> setting_names()
{
    return {"NSAMPLES", "MAX_BOUNCES", "SHADOW_RAYS", "PHONG", "ENABLE_MIRROR", "ENABLE_GLASS",
            "AIR_INDEX_MEDIUM", "MESH", "ENABLE_INTERPOLATION", "MAX_LEAF_SIZE", "ENABLE_TEXTURES",
            "FRESNEL", "GLASS_IOR"};
}

bool apply_setting(Scene &scene, const std::string &key, const std::string &value, std::string &error)
{
    Settings &s = scene.settings;
    const std::string k = upper(key);
    bool ok = true;
    std::string expected;
    if (k == "NSAMPLES") {
        uint32_t n = 0;
        ok = common::parse_count(value, 65536, n) && n > 0;
        expected = "an integer from 1 to 65536";
        if (ok) s.nsamples = n;
    }
    else if (k == "MAX_BOUNCES") { ok = common::parse_count(value, 64, s.max_bounces); expected = "an integer from 0 to 64"; }
    else if (k == "SHADOW_RAYS") { ok = common::parse_count(value, 4096, s.shadow_rays); expected = "an integer from 0 (no shadows) to 4096"; }
    else if (k == "PHONG") { ok = parse_bool(value, s.phong); expected = "true or false"; }
    else if (k == "ENABLE_MIRROR") { ok = parse_bool(value, s.enable_mirror); expected = "true or false"; }
    else if (k == "ENABLE_GLASS") { ok = parse_bool(value, s.enable_glass); expected = "true or false"; }
    else if (k == "AIR_INDEX_MEDIUM") { ok = parse_number(value, 1e-3, 100, s.air_index_medium); expected = "an index of refraction from 0.001 to 100"; }
    else if (k == "MESH") { ok = !value.empty(); if (ok) s.mesh = value; expected = "a mesh name (stanford-bunny, ...) or a file path"; }
    else if (k == "ENABLE_INTERPOLATION") { ok = parse_bool(value, s.enable_interpolation); expected = "true or false"; }
    else if (k == "MAX_LEAF_SIZE") { ok = common::parse_count(value, 1u << 20, s.max_leaf_size); expected = "an integer from 0 (no tree) to 1048576"; }
    else if (k == "ENABLE_TEXTURES") { ok = parse_bool(value, s.enable_textures); expected = "true or false"; }
    else if (k == "FRESNEL") { ok = parse_bool(value, s.fresnel); expected = "true or false"; }
    else if (k == "GLASS_IOR") {
        double ior = 0;
        ok = parse_number(value, 1e-3, 100, ior);
        expected = "an index of refraction from 0.001 to 100";
        if (ok)
            for (Material &m : scene.materials)
                if (m.kind == MaterialKind::glass) m.ior = ior;
    } else {
        error = "unknown setting '" + key + "'";
        return false;
    }
    if (!ok) error = "setting " + k + ": '" + value + "' is not " + expected;
    return ok;
}

}  // namespace kr
