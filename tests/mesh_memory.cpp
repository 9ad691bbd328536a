// kdrt-mesh-memory: loads every file under the given folders (or the given files) through
// common::load_mesh as the tools do, and checks the heap cap refuses no real mesh: a file it
// refuses is loaded again under a loose cap (1024 times the files' size plus 1 GiB), and one that
// loads then was refused unexpectedly (exit 1), unless it is named with --expect-refused: a file
// whose reader generates geometry beyond what its bytes hold (a subdivision level, say), which
// the cap is there to refuse. With --ratios, every file is loaded under the loose cap too, and
// the peak heap of each load against the size of its files is printed, with the largest per
// format (the measurement in tools/README.md).
//
//   kdrt-mesh-memory [--ratios] [--expect-refused NAME]... FOLDER|FILE...
#include "common/mesh_io.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace fs = std::filesystem;

int main(int argc, char **argv)
{
    std::vector<std::string> files, expected;
    bool ratios = false;
    for (int i = 1; i < argc; ++i) {
        std::error_code ec;
        if (std::string(argv[i]) == "--ratios") {
            ratios = true;
        } else if (std::string(argv[i]) == "--expect-refused" && i + 1 < argc) {
            expected.push_back(argv[++i]);
        } else if (fs::is_directory(argv[i], ec)) {
            for (fs::recursive_directory_iterator it(argv[i], ec), end; !ec && it != end; it.increment(ec))
                if (it->is_regular_file(ec)) files.push_back(it->path().string());
        } else {
            files.push_back(argv[i]);
        }
    }
    if (files.empty()) {
        std::fputs("usage: kdrt-mesh-memory [--ratios] [--expect-refused NAME]... FOLDER|FILE...\n", stderr);
        return 2;
    }
    std::sort(files.begin(), files.end());

    struct Worst {
        double ratio = 0;
        std::string file;
        unsigned loaded = 0;
    };
    std::map<std::string, Worst> by_format;
    unsigned loaded = 0, unexpected = 0;
    if (ratios) std::printf("%10s %12s %12s  %-6s %s\n", "peak/size", "peak", "size", "loads", "file");
    for (const std::string &file : files) {
        common::Mesh mesh;
        std::string error, loose_error;
        const bool ok = common::load_mesh(file, mesh, error);
        loaded += ok;
        const bool known = std::find(expected.begin(), expected.end(), fs::path(file).filename()) != expected.end();
        const bool capped = !ok && error.compare(0, 9, "refused: ") == 0;
        if (!ratios && !(capped && !known)) {
            std::printf("%-6s %s%s%s\n", ok ? "loads" : "no", file.c_str(), ok ? "" : ": ", error.c_str());
            continue;
        }
        common::MeshLoadStats stats;
        const bool loose = common::load_mesh(file, mesh, loose_error, 1024, uint64_t(1) << 30, &stats);
        if (ratios) {
            const double ratio = stats.file_bytes ? double(stats.peak_heap_bytes) / double(stats.file_bytes) : 0;
            std::printf("%10.2f %12llu %12llu  %-6s %s%s%s\n", ratio, (unsigned long long)stats.peak_heap_bytes,
                        (unsigned long long)stats.file_bytes, loose ? "yes" : "no", file.c_str(), loose ? "" : ": ",
                        loose ? "" : loose_error.c_str());
            if (loose) {
                std::string format = fs::path(file).extension().string();
                std::transform(format.begin(), format.end(), format.begin(), [](unsigned char c) { return char(std::tolower(c)); });
                Worst &w = by_format[format];
                ++w.loaded;
                if (ratio > w.ratio) w.ratio = ratio, w.file = file;
            }
        }
        if (capped && loose) {
            std::printf("%s: %s: %s\n", known ? "refused, as expected" : "REFUSED", file.c_str(), error.c_str());
            unexpected += !known;
        }
    }
    if (ratios) {
        std::printf("\n%-8s %6s %10s  %s\n", "format", "loaded", "peak/size", "largest, in");
        for (const auto &f : by_format)
            std::printf("%-8s %6u %10.2f  %s\n", f.first.c_str(), f.second.loaded, f.second.ratio, f.second.file.c_str());
    }
    std::printf("%u of %zu files loaded; %u refused by the heap cap (%llu times their size plus %llu MiB) that "
                "load under a loose one, and should not be\n",
                loaded, files.size(), unexpected, (unsigned long long)common::mesh_heap_factor,
                (unsigned long long)(common::mesh_heap_floor >> 20));
    std::fflush(stdout);  // before LeakSanitizer's report at exit, which ends the process
    return unexpected ? 1 : 0;
}
