// Saved trees (kdrt.h, SAVED TREES) as files, for the programs: read whole, written whole or not
// at all, and a refusal said in one line a user can act on. kdrt-inspect --tree and kdrt-render
// --tree / --save-tree use them.
#pragma once

#include "kdrt.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace common {

// A saved tree's bytes, read whole from a regular file (open_regular_file: never a FIFO or a
// device). false with "cannot read 'PATH': REASON" (no such file, a directory, ...), or
// "'PATH' is empty: not a saved kdrt tree" for a file of no bytes.
bool read_saved_tree(const std::string &path, std::vector<unsigned char> &bytes, std::string &error);

// Why a load or kdrt_saved_tree_read_info() of `bytes` (from `path`) failed with `result`, as a
// message naming the file: "'PATH' is not a saved kdrt tree (it does not start with KDRTTREE)",
// "'PATH' is truncated: its header records N bytes and the file has M", "'PATH' is a saved tree
// of format version N; this kdrt reads version 1 (save it again)", "'PATH' is damaged: ...",
// and for KDRT_ERROR_MESH_MISMATCH "'PATH' was saved over other meshes: 1 mesh of N triangles,
// not the 1 mesh of M triangles given (...)", `meshes` and `mesh_triangles` being the number and
// the triangles of the meshes given. Any other result: "'PATH': " and its kdrt_result_string().
std::string saved_tree_refusal(kdrt_result result, const std::string &path, const std::vector<unsigned char> &bytes,
                               uint64_t mesh_triangles, uint32_t meshes);

// Writes `size` bytes, which `save` produces through the callback it is given (kdrt_tree_save,
// kdrt_scene_save_meshes), to `path` as write_atomically writes: whole or not at all.
bool write_saved_tree(const std::string &path,
                      kdrt_result (*save)(const void *object, kdrt_write_fn write, void *user), const void *object,
                      std::string &error);

}  // namespace common
