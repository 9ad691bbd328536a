// kdrt-bench --save-load (bench/README.md, "Saved trees"): a mesh's tree built at FAST and at the
// default quality, saved, and loaded copied and in place (kdrt.h, SAVED TREES), side by side.
#pragma once

#include "kdrt.h"
#include "common/mesh_io.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace kb {

// One quality's row: the fastest of the runs of each step, in ms, one thread.
struct SaveLoadRow {
    std::string mesh;
    uint32_t triangles = 0;
    std::string quality;          // "fast", or the default's: "medium" (KDRT_BUILD_QUALITY_DEFAULT)
    double build_ms = 0;          // kdrt_tree_build
    double save_ms = 0;           // kdrt_tree_save into memory (a buffer of kdrt_tree_saved_size())
    double load_ms = 0;           // kdrt_tree_load, the sections copied
    double load_in_place_ms = 0;  // KDRT_LOAD_IN_PLACE from a 64-byte aligned buffer
    double fingerprint_ms = 0;    // a load over the mesh with one index changed: the hash and refusal
    uint64_t tree_bytes = 0;      // kdrt_tree_stats.bytes of the built tree
    uint64_t saved_bytes = 0;     // the file's
    double fast_build_ms = 0;     // the FAST row's build_ms, which the ratios divide
};

// Measures `mesh` (label: the Mesh column) at FAST and at kdrt's default quality, the SAH builder
// and the default options otherwise: `repeat` rounds, each timing every step of both qualities in
// turn (so a busy moment of the machine falls on all), the fastest of each kept. Checks what it
// times: each load succeeds, the copied and the in-place tree save again to the file's bytes,
// and the changed mesh is refused with KDRT_ERROR_MESH_MISMATCH. false with a message when a
// step fails (rows then holds nothing of this mesh).
bool measure_save_load(const common::Mesh &mesh, const std::string &label, unsigned repeat,
                       std::vector<SaveLoadRow> &rows, std::string &error);

std::string save_load_csv_header();
std::string save_load_csv_row(const SaveLoadRow &row);
// The rows as bench/README.md's table (Markdown), a line each, with its header.
std::string save_load_table(const std::vector<SaveLoadRow> &rows);

}  // namespace kb
