#include "saved_trees.hpp"
#include "bench.hpp"  // quality_name
#include "common/timing.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

namespace kb {

namespace {

using TreePtr = std::unique_ptr<kdrt_tree, decltype(&kdrt_tree_free)>;

// A save into memory: the bytes appended to a vector reserved beforehand.
int append(void *user, const void *bytes, size_t size) {
    auto *out = static_cast<std::vector<unsigned char> *>(user);
    const unsigned char *p = static_cast<const unsigned char *>(bytes);
    out->insert(out->end(), p, p + size);
    return 1;
}

kdrt_result save(const kdrt_tree *tree, std::vector<unsigned char> &bytes) {
    bytes.clear();
    bytes.reserve(kdrt_tree_saved_size(tree));
    return kdrt_tree_save(tree, append, &bytes);
}

// One quality's state across the rounds.
struct Quality {
    kdrt_build_options options;
    SaveLoadRow row;
    TreePtr tree{nullptr, kdrt_tree_free};
    std::vector<unsigned char> bytes;
    std::unique_ptr<unsigned char, decltype(&std::free)> aligned{nullptr, std::free};
};

}  // namespace

bool measure_save_load(const common::Mesh &mesh, const std::string &label, unsigned repeat,
                       std::vector<SaveLoadRow> &rows, std::string &error) {
    const kdrt_triangles view = mesh.view();
    // The same mesh but for one index (or, for a soup, one coordinate): the fingerprint differs.
    common::Mesh other = mesh;
    if (!other.indices.empty() && other.vertex_count() > 1)
        other.indices.back() = (other.indices.back() + 1) % other.vertex_count();
    else if (!other.positions.empty())
        other.positions.back() = std::nextafter(other.positions.back(), INFINITY);
    const kdrt_triangles other_view = other.view();
    const bool can_differ = !mesh.positions.empty();

    Quality q[2];
    const kdrt_build_quality qualities[2] = {KDRT_BUILD_QUALITY_FAST, kdrt_default_build_options().quality};
    for (int k = 0; k < 2; ++k) {
        q[k].options = kdrt_default_build_options();
        q[k].options.quality = qualities[k];
        q[k].row.mesh = label;
        q[k].row.triangles = mesh.triangle_count();
        // KDRT_BUILD_QUALITY_DEFAULT is MEDIUM (kdrt.h), named as the builds name it.
        q[k].row.quality = k == 0 ? "fast" : qualities[k] == KDRT_BUILD_QUALITY_DEFAULT ? "medium" : quality_name(qualities[k]);
        q[k].row.build_ms = q[k].row.save_ms = q[k].row.load_ms = q[k].row.load_in_place_ms = q[k].row.fingerprint_ms = INFINITY;
    }
    const auto failed = [&](const std::string &what, kdrt_result r) {
        error = label + ": " + what + ": " + kdrt_result_string(r);
        return false;
    };
    kdrt_build_options in_place = kdrt_default_build_options();
    in_place.flags = KDRT_LOAD_IN_PLACE;
    std::vector<unsigned char> again;
    for (unsigned round = 0; round < std::max(repeat, 1u); ++round) {
        for (Quality &s : q) {  // build
            kdrt_tree *built = nullptr;
            common::Stopwatch clock;
            const kdrt_result r = kdrt_tree_build(&view, &s.options, &built, nullptr);
            s.row.build_ms = std::min(s.row.build_ms, clock.ms());
            s.tree.reset(built);
            if (r != KDRT_SUCCESS) return failed(std::string("the ") + s.row.quality + " build", r);
        }
        for (Quality &s : q) {  // save
            common::Stopwatch clock;
            const kdrt_result r = save(s.tree.get(), s.bytes);
            s.row.save_ms = std::min(s.row.save_ms, clock.ms());
            if (r != KDRT_SUCCESS) return failed("the save", r);
            if (!s.aligned) {  // the in-place load's buffer: 64-byte aligned, as it asks
                s.aligned.reset(static_cast<unsigned char *>(std::aligned_alloc(64, (s.bytes.size() + 63) / 64 * 64)));
                if (!s.aligned) return failed("the in-place load's buffer", KDRT_ERROR_OUT_OF_MEMORY);
                std::memcpy(s.aligned.get(), s.bytes.data(), s.bytes.size());
            }
        }
        for (Quality &s : q) {  // load, copied
            kdrt_tree *loaded = nullptr;
            common::Stopwatch clock;
            const kdrt_result r = kdrt_tree_load(s.bytes.data(), s.bytes.size(), &view, nullptr, &loaded, nullptr);
            s.row.load_ms = std::min(s.row.load_ms, clock.ms());
            TreePtr tree(loaded, kdrt_tree_free);
            if (r != KDRT_SUCCESS) return failed("the load", r);
            if (round == 0 && (save(tree.get(), again) != KDRT_SUCCESS || again != s.bytes)) {
                error = label + ": the loaded tree does not save to the file's bytes";
                return false;
            }
        }
        for (Quality &s : q) {  // load in place
            kdrt_tree *loaded = nullptr;
            common::Stopwatch clock;
            const kdrt_result r = kdrt_tree_load(s.aligned.get(), s.bytes.size(), &view, &in_place, &loaded, nullptr);
            s.row.load_in_place_ms = std::min(s.row.load_in_place_ms, clock.ms());
            TreePtr tree(loaded, kdrt_tree_free);
            if (r != KDRT_SUCCESS) return failed("the load in place", r);
            if (round == 0 && (save(tree.get(), again) != KDRT_SUCCESS || again != s.bytes)) {
                error = label + ": the tree loaded in place does not save to the file's bytes";
                return false;
            }
        }
        for (Quality &s : q) {  // the fingerprint: a load over the changed mesh, refused
            if (!can_differ) {
                s.row.fingerprint_ms = 0;
                continue;
            }
            kdrt_tree *none = nullptr;
            common::Stopwatch clock;
            const kdrt_result r = kdrt_tree_load(s.bytes.data(), s.bytes.size(), &other_view, nullptr, &none, nullptr);
            s.row.fingerprint_ms = std::min(s.row.fingerprint_ms, clock.ms());
            kdrt_tree_free(none);
            if (r != KDRT_ERROR_MESH_MISMATCH)
                return failed("a load over a changed mesh was not refused as another mesh", r);
        }
    }
    for (Quality &s : q) {
        kdrt_tree_stats stats;
        kdrt_tree_get_stats(s.tree.get(), &stats);
        s.row.tree_bytes = stats.bytes;
        s.row.saved_bytes = s.bytes.size();
        s.row.fast_build_ms = q[0].row.build_ms;
        rows.push_back(s.row);
    }
    return true;
}

std::string save_load_csv_header() {
    return "Mesh;Triangles;Quality;BuildMs;SaveMs;LoadMs;LoadInPlaceMs;FingerprintMs;TreeBytes;SavedBytes;"
           "FastBuildOverLoad;FastBuildOverLoadInPlace";
}

std::string save_load_csv_row(const SaveLoadRow &r) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s;%u;%s;%.3f;%.3f;%.3f;%.3f;%.3f;%llu;%llu;%.1f;%.1f", r.mesh.c_str(), r.triangles,
                  r.quality.c_str(), r.build_ms, r.save_ms, r.load_ms, r.load_in_place_ms, r.fingerprint_ms,
                  (unsigned long long)r.tree_bytes, (unsigned long long)r.saved_bytes,
                  r.load_ms > 0 ? r.fast_build_ms / r.load_ms : 0.0,
                  r.load_in_place_ms > 0 ? r.fast_build_ms / r.load_in_place_ms : 0.0);
    return buf;
}

std::string save_load_table(const std::vector<SaveLoadRow> &rows) {
    std::string t = "| mesh | triangles | quality | build ms | save ms | load ms | in place ms | hash ms | file bytes | "
                    "tree bytes | FAST build / load | FAST build / in place |\n"
                    "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    char buf[512];
    for (const SaveLoadRow &r : rows) {
        std::snprintf(buf, sizeof buf, "| %s | %u | %s | %.2f | %.2f | %.2f | %.2f | %.2f | %llu | %llu | %.1f | %.1f |\n",
                      r.mesh.c_str(), r.triangles, r.quality.c_str(), r.build_ms, r.save_ms, r.load_ms,
                      r.load_in_place_ms, r.fingerprint_ms, (unsigned long long)r.saved_bytes,
                      (unsigned long long)r.tree_bytes, r.load_ms > 0 ? r.fast_build_ms / r.load_ms : 0.0,
                      r.load_in_place_ms > 0 ? r.fast_build_ms / r.load_in_place_ms : 0.0);
        t += buf;
    }
    return t;
}

}  // namespace kb
