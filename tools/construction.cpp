// kdrt-construction: the construction steps of a kd-tree over a small 2D triangle set, as JSON for
// tools/construction_pictures.py. The tree is kdrt's own, read back with the inspection API.
//
//   kdrt-construction [TRIANGLES.txt] [--builder median|sah] [--leaf-size N] [--count N] [--seed S] -o OUT.json
#include "common/atomic_file.hpp"  // common::write_file_atomically
#include "construction.hpp"
#include "common/output.hpp"  // common::close_stdout, common::write_flushed
#include "common/parse.hpp"  // common::parse_count, common::parse_size
#include "tree_inspect.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
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
    "  --builder B     median (the default, the original's) or sah\n"
    "  --leaf-size N   most triangles in a leaf (default 1)\n"
    "  --count N       random triangles when no file is given (default 11)\n"
    "  --seed S        their seed (default 7)\n"
    "  -o OUT.json     where to write ('-': standard output)\n";

int fail(const std::string &message)
{
    std::fprintf(stderr, "kdrt-construction: %s\n", message.c_str());
    return 1;
}

int run(int argc, char **argv)
{
    std::string input, output;
    kdrt_builder builder = KDRT_BUILDER_MEDIAN;
    unsigned long leaf_size = 1, count = 11, seed = 7;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        const bool has_value = i + 1 < argc;
        if (arg == "--help" || arg == "-h") {
            std::fputs(usage, stdout);
            return 0;
        } else if (arg == "--builder" && has_value) {
            const std::string b = argv[++i];
            if (b == "median") builder = KDRT_BUILDER_MEDIAN;
            else if (b == "sah") builder = KDRT_BUILDER_SAH;
            else return fail("--builder wants median or sah, not '" + b + "'");
        } else if (arg == "--leaf-size" && has_value) {
            if (!common::parse_count(argv[++i], 1000000, leaf_size) || leaf_size == 0)
                return fail(std::string("--leaf-size wants a whole number from 1, not '") + argv[i] + "'");
        } else if (arg == "--count" && has_value) {
            if (!common::parse_count(argv[++i], 10000, count) || count == 0)
                return fail(std::string("--count wants a whole number from 1 to 10000, not '") + argv[i] + "'");
        } else if (arg == "--seed" && has_value) {
            if (!common::parse_count(argv[++i], 0xFFFFFFFFul, seed))
                return fail(std::string("--seed wants a whole number, not '") + argv[i] + "'");
        } else if (arg == "-o" && has_value) {
            output = argv[++i];
        } else if (arg.size() > 1 && arg[0] == '-') {
            return fail("unknown option or missing value: '" + arg + "'\n" + usage);
        } else if (input.empty()) {
            input = arg;
        } else {
            return fail("one triangle file at most ('" + input + "', then '" + arg + "')");
        }
    }
    if (output.empty()) return fail(std::string("no output: give -o OUT.json\n") + usage);

    std::vector<float> positions;
    std::string error;
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
    return common::close_stdout("kdrt-construction", run(argc, argv));
}
