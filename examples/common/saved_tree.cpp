#include "common/saved_tree.hpp"

#include "common/atomic_file.hpp"
#include "common/regular_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace common {

namespace {

// The header's fields as kdrt.h's SAVED TREES lays them out (little-endian).
uint32_t get32(const std::vector<unsigned char> &b, size_t at)
{
    if (b.size() < at + 4) return 0;
    return uint32_t(b[at]) | uint32_t(b[at + 1]) << 8 | uint32_t(b[at + 2]) << 16 | uint32_t(b[at + 3]) << 24;
}

uint64_t get64(const std::vector<unsigned char> &b, size_t at) { return get32(b, at) | uint64_t(get32(b, at + 4)) << 32; }

std::string plural(uint64_t n, const char *one, const char *many)
{
    return std::to_string(n) + " " + (n == 1 ? one : many);
}

struct FileWriter {
    std::FILE *file;
    int error = 0;
};

int write_to_file(void *user, const void *bytes, size_t size)
{
    FileWriter &w = *static_cast<FileWriter *>(user);
    if (std::fwrite(bytes, 1, size, w.file) == size) return 1;
    w.error = errno ? errno : EIO;
    return 0;
}

}  // namespace

bool read_saved_tree(const std::string &path, std::vector<unsigned char> &bytes, std::string &error)
{
    struct stat st;
    std::string why;
    std::FILE *file = open_regular_file(path.c_str(), st, why);
    if (!file) {
        error = "cannot read '" + path + "': " + why;
        return false;
    }
    bytes.resize(size_t(st.st_size));
    const size_t got = bytes.empty() ? 0 : std::fread(bytes.data(), 1, bytes.size(), file);
    const bool failed = std::ferror(file) != 0;
    const int reason = errno;
    std::fclose(file);
    if (failed) {
        error = "cannot read '" + path + "': " + std::strerror(reason);
        return false;
    }
    bytes.resize(got);  // a file that shrank as it was read is judged as what was read
    if (bytes.empty()) {  // judged here: the loads take no bytes at all for a NULL argument
        error = "'" + path + "' is empty: not a saved kdrt tree";
        return false;
    }
    return true;
}

std::string saved_tree_refusal(kdrt_result result, const std::string &path, const std::vector<unsigned char> &bytes,
                               uint64_t mesh_triangles, uint32_t meshes)
{
    const std::string file = "'" + path + "'";
    switch (result) {
    case KDRT_ERROR_NOT_A_SAVED_TREE:
        return file + " is not a saved kdrt tree (it does not start with KDRTTREE" +
               (bytes.size() < 8 ? ": it holds " + plural(bytes.size(), "byte", "bytes") : std::string()) + ")";
    case KDRT_ERROR_FILE_VERSION:
        return file + " is a saved tree of format version " + std::to_string(get32(bytes, 12)) +
               "; this kdrt reads version " + std::to_string(KDRT_SAVED_TREE_VERSION) + " (save it again)";
    case KDRT_ERROR_FILE_BYTE_ORDER:
        return file + " is a saved tree whose byte order mark is not little-endian, which no kdrt writes";
    case KDRT_ERROR_FILE_SIZE: {
        const uint64_t recorded = get64(bytes, 24);
        if (bytes.size() < 256)
            return file + " is truncated: " + plural(bytes.size(), "byte", "bytes") + ", less than a saved tree's " +
                   "256-byte header";
        return file + (recorded > bytes.size() ? " is truncated" : " has bytes after its end") + ": its header records " +
               plural(recorded, "byte", "bytes") + " and the file has " + std::to_string(bytes.size());
    }
    case KDRT_ERROR_FILE_CORRUPT:
        return file + " is damaged: a field no save writes, or a checksum that does not match (save it again)";
    case KDRT_ERROR_MESH_MISMATCH: {
        kdrt_saved_tree_info info;
        std::string saved = "another mesh";
        if (kdrt_saved_tree_read_info(bytes.data(), bytes.size(), &info) == KDRT_SUCCESS)
            saved = plural(info.meshes, "mesh", "meshes") + " of " + plural(info.mesh_triangles, "triangle", "triangles");
        const std::string given = plural(meshes, "mesh", "meshes") + " of " + plural(mesh_triangles, "triangle", "triangles");
        if (saved == given)
            return file + " was saved over other meshes: " + saved + " as given, but their positions, indices or IDs " +
                   "differ (build the tree and save it again)";
        return file + " was saved over other meshes: " + saved + ", not the " + given +
               " given (build the tree and save it again)";
    }
    default:
        return file + ": " + kdrt_result_string(result);
    }
}

bool write_saved_tree(const std::string &path,
                      kdrt_result (*save)(const void *object, kdrt_write_fn write, void *user), const void *object,
                      std::string &error)
{
    return write_atomically(path, [&](const std::string &tmp, std::string &reason) {
        FileWriter w{std::fopen(tmp.c_str(), "wb")};
        if (!w.file) {
            reason = std::strerror(errno);
            return false;
        }
        const kdrt_result r = save(object, write_to_file, &w);
        const int write_errno = w.error;
        const bool closed = std::fclose(w.file) == 0;  // a full disk can show only here
        if (r != KDRT_SUCCESS || !closed) {
            reason = r == KDRT_ERROR_WRITE_FAILED || !closed ? std::strerror(write_errno ? write_errno : errno)
                                                             : kdrt_result_string(r);
            return false;
        }
        return true;
    }, error);
}

}  // namespace common
