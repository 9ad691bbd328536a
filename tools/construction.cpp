// kdrt-construction: the construction steps of a kd-tree over a small 2D triangle set, as JSON for
// tools/construction_pictures.py. The tree is kdrt's own, read back with the inspection API.
//
//   kdrt-construction [TRIANGLES.txt] [--builder median|sah] [--leaf-size N] [--count N] [--seed S] -o OUT.json
#include "common/atomic_file.hpp"  // common::check_replaceable, common::write_file_atomically
#include "construction.hpp"
#include "common/output.hpp"  // common::guarded_main, common::UsageError, common::write_flushed
#include "common/parse.hpp"  // common::parse_count, common::parse_size
#include "tree_inspect.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <string>

namespace {

const char *const usage =
    "usage: kdrt-construction [TRIANGLES.txt] [--builder median|sah] [--leaf-size N] [--count N] [--seed S]\n"
    "                         -o OUT.json\n"
    "Builds kdrt's kd-tree over a small triangle set and writes each construction step (each inner\n"
    "node, breadth first: its box, split axis and position, the median centroid for the median\n"
    "builder, the side each of its triangles went to, the children's boxes) as one JSON document.\n"
    "  TRIANGLES.txt   one triangle a line: x0 y0 x1 y1 x2 y2 (or nine numbers with z); # comments\n"
    "                  default: --count seeded random triangles in the plane z = 0\n"
    "  --builder B     median (the default, the original's) or sah, in any case\n"
    "  --leaf-size N   most triangles in a leaf (default 1)\n"
    "  --count N       random triangles when no file is given (default 11)\n"
    "  --seed S        their seed (default 7)\n"
    "  -o OUT.json     where to write ('-': standard output)\n"
    "Exit status: 0 success, 1 failure (unreadable triangle file, unwritable output), 2 a bad\n"
    "command line.\n";

using common::UsageError;

int fail(const std::string &message)
{
    std::fprintf(stderr, "kdrt-construction: %s\n", message.c_str());
    return 1;
}

std::string lowercase(std::string s)
{
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
}

int run(int argc, char **argv)
{
    std::string input, output;
    kdrt_builder builder = KDRT_BUILDER_MEDIAN;
    unsigned long leaf_size = 1, count = 11, seed = 7;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError{arg + " needs a value (see --help)"};
            return argv[++i];
        };
        if (arg == "--help" || arg == "-h") {
            std::fputs(usage, stdout);
            return 0;
        } else if (arg == "--builder") {
            const std::string v = value(), b = lowercase(v);
            if (b == "median") builder = KDRT_BUILDER_MEDIAN;
            else if (b == "sah") builder = KDRT_BUILDER_SAH;
            else throw UsageError{"--builder wants median or sah, not '" + v + "'"};
        } else if (arg == "--leaf-size") {
            const std::string v = value();
            if (!common::parse_count(v, 1000000, leaf_size) || leaf_size == 0)
                throw UsageError{"--leaf-size wants a whole number from 1, not '" + v + "'"};
        } else if (arg == "--count") {
            const std::string v = value();
            if (!common::parse_count(v, 10000, count) || count == 0)
                throw UsageError{"--count wants a whole number from 1 to 10000, not '" + v + "'"};
        } else if (arg == "--seed") {
            const std::string v = value();
            if (!common::parse_count(v, 0xFFFFFFFFul, seed)) throw UsageError{"--seed wants a whole number, not '" + v + "'"};
        } else if (arg == "-o") {
            output = value();
        } else if (arg.size() > 1 && arg[0] == '-') {
            throw UsageError{"unknown option '" + arg + "' (see --help)"};
        } else if (input.empty()) {
            input = arg;
        } else {
            throw UsageError{"one triangle file at most ('" + input + "', then '" + arg + "')"};
        }
    }
    if (output.empty()) throw UsageError{"no output: give -o OUT.json (or -o - for standard output)"};
    std::string error;
    if (output != "-" && !common::check_replaceable(output, error)) return fail(error);

    std::vector<float> positions;
    if (input.empty()) positions = kdrt_tools::random_triangles_2d(uint32_t(count), seed);
    else if (!kdrt_tools::read_triangles(input, positions, error)) return fail(error);

    kdrt_tools::Construction construction;
    if (!kdrt_tools::construct(positions, builder, uint32_t(leaf_size), construction, error)) return fail(error);
    const std::string json = kdrt_tools::construction_json(construction);
    if (output == "-") {
        if (!common::write_flushed(stdout, json, "standard output", error)) return fail(error);
    } else {
        if (!common::write_file_atomically(output, json, error)) return fail(error);
        std::fprintf(stderr, "kdrt-construction: %zu triangles, %zu steps, %zu leaves -> %s\n", positions.size() / 9,
                     construction.steps.size(), construction.leaves.size(), output.c_str());
    }
    return 0;
}

}  // namespace

int main(int argc, char **argv)
{
    return common::guarded_main("kdrt-construction", [&] { return run(argc, argv); });
}
