// Command-line numbers, parsed one way for every tool (kdrt-bench, kdrt-render, kdrt-render-mesh,
// kdrt-inspect, kdrt-construction, kdrt-ray-costs, and kdrt-render's settings).
#pragma once

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <type_traits>

namespace common {

// A whole number in [0, max]: decimal digits only (no sign, no space, nothing after them).
// out is written only on success.
// (max is not used to deduce Int, so a literal bound fits any integer out.)
template <typename Int>
bool parse_count(const std::string &text, typename std::common_type<Int>::type max, Int &out)
{
    if (text.empty() || text[0] < '0' || text[0] > '9') return false;
    errno = 0;
    char *end = nullptr;
    const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
    if (errno != 0 || *end != '\0' || v > static_cast<unsigned long long>(max)) return false;
    out = static_cast<Int>(v);
    return true;
}

// "WxH" with both sides whole numbers in [1, max_side]; written only on success.
template <typename Int>
bool parse_size(const std::string &text, typename std::common_type<Int>::type max_side, Int &width, Int &height)
{
    const size_t x = text.find('x');
    Int w = 0, h = 0;
    if (x == std::string::npos || !parse_count(text.substr(0, x), max_side, w) ||
        !parse_count(text.substr(x + 1), max_side, h) || w == 0 || h == 0)
        return false;
    width = w, height = h;
    return true;
}

}  // namespace common
