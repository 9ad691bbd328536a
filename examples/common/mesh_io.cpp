#include "common/mesh_io.hpp"

#include "common/heap_budget.hpp"
#include "common/regular_file.hpp"

#include <assimp/DefaultIOStream.h>
#include <assimp/DefaultIOSystem.h>
#include <assimp/DefaultLogger.hpp>
#include <assimp/Importer.hpp>
#include <assimp/LogStream.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <new>
#include <set>
#include <sstream>

#ifndef KDRT_MESH_DIR
#define KDRT_MESH_DIR ""
#endif

namespace common {

namespace {

// PLY headers Assimp's reader is not safe on, checked line by line before it sees them: one that
// does not end (it never returns), elements claimed by the billion with no data (a 58-byte file
// with "element vertex 1000000000" and no properties keeps it looping for minutes: any element
// takes at least a byte, or an ASCII line, so no count may exceed the file's size), and format,
// element and property lines that are not what PLY says (an element without a count made it read
// out of bounds).
bool check_ply_header(const std::string &path, std::string &error) {
    struct stat st;
    std::string why;
    FILE *file = open_regular_file(path.c_str(), st, why);
    if (!file) return true; // reported when Assimp opens it
    // What Assimp takes for PLY: "ply" first, in any case ("pLy" loads as well).
    auto is_ply = [](const std::string &text) {
        const size_t n = std::min<size_t>(3, text.size());
        for (size_t i = 0; i < n; ++i)
            if (std::tolower(static_cast<unsigned char>(text[i])) != "ply"[i]) return false;
        return n == 3 || text.size() == n;  // a prefix of "ply" may yet become it
    };
    std::string header;
    char buffer[4096];
    size_t n;
    while (header.size() < (1u << 20) && (n = std::fread(buffer, 1, sizeof buffer, file)) > 0) {
        header.append(buffer, n);
        if (!is_ply(header)) break;
        if (header.find("\nend_header") != std::string::npos) break;
    }
    std::fclose(file);
    if (header.size() < 3 || !is_ply(header)) return true;
    static const std::set<std::string> types = {"char",  "uchar",  "short", "ushort", "int",   "uint",
                                                "float", "double", "int8",  "uint8",  "int16", "uint16",
                                                "int32", "uint32", "float32", "float64"};
    const std::string formats = " ascii binary_little_endian binary_big_endian ";
    std::istringstream lines(header);
    std::string line;
    bool in_element = false;
    for (int number = 1; std::getline(lines, line); ++number) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (number == 1 && line.size() == 3) continue;  // "ply", in some case
        std::istringstream words(line);
        std::vector<std::string> w;
        for (std::string word; words >> word;) w.push_back(word);
        if (w.empty()) continue;
        if (w[0] == "end_header" && w.size() == 1) return true;
        bool ok = number > 1;  // comments, and other lines Assimp skips too (Blender 2.4 wrote one)
        if (w[0] == "format") {
            ok = w.size() == 3 && formats.find(" " + w[1] + " ") != std::string::npos;
        } else if (w[0] == "element") {
            ok = w.size() == 3 && w[2].find_first_not_of("0123456789") == std::string::npos && w[2].size() <= 19;
            if (ok && std::stoull(w[2]) > uint64_t(st.st_size)) {
                error = "malformed PLY file: its header claims " + w[2] + " " + w[1] + " elements, more than its " +
                        std::to_string(st.st_size) + " bytes can hold";
                return false;
            }
            in_element = ok;
        } else if (w[0] == "property") {
            ok = in_element && ((w.size() == 3 && types.count(w[1])) ||
                                (w.size() == 5 && w[1] == "list" && types.count(w[2]) && types.count(w[3])));
        }
        if (!ok) {
            for (char &c : line) c = std::isprint(static_cast<unsigned char>(c)) ? c : '?';
            error = "malformed PLY file: header line " + std::to_string(number) + " is not a PLY header line: '" +
                    line.substr(0, 60) + (line.size() > 60 ? "...'" : "'");
            return false;
        }
    }
    error = "malformed PLY file: its header has no end_header line";
    return false;
}

// Assimp's file access for one load: only regular files open (any other "does not exist", so a
// FIFO or device named by an OBJ's mtllib or a glTF's buffer cannot block the reader or feed it
// forever), and each distinct file opened raises the heap budget by `factor` times its size: the
// budget follows every byte the reader is given, .bin buffers and .mtl files included.
class GuardedFiles : public Assimp::DefaultIOSystem {
public:
    explicit GuardedFiles(uint64_t factor) : factor_(factor) {}
    void charge(HeapBudget *budget) { budget_ = budget; }  // the budget the files raise, from now on

    bool Exists(const char *path) const override
    {
        struct stat st;
        return ::stat(path, &st) == 0 && S_ISREG(st.st_mode);
    }

    Assimp::IOStream *Open(const char *path, const char *mode) override
    {
        if (std::strpbrk(mode, "wa+")) return nullptr;  // readers only read
        struct stat st;
        std::string why;
        FILE *file = open_regular_file(path, st, why);
        if (!file) return nullptr;
        if (opened_.insert({uint64_t(st.st_dev), uint64_t(st.st_ino)}).second) {
            bytes_ += uint64_t(st.st_size);
            if (budget_) budget_->raise(factor_ * uint64_t(st.st_size));
        }
        return new Stream(file, path);
    }

    uint64_t bytes() const { return bytes_; }  // of the distinct files opened

private:
    struct Stream : Assimp::DefaultIOStream {  // its constructor from a FILE* is protected
        Stream(FILE *file, const std::string &name) : DefaultIOStream(file, name) {}
    };
    const uint64_t factor_;
    HeapBudget *budget_ = nullptr;
    uint64_t bytes_ = 0;
    std::set<std::pair<uint64_t, uint64_t>> opened_;  // (device, inode)
};

// Errors some of Assimp's readers log, and then carry on, after changing the geometry they read
// (from Assimp 5.2's source). Assimp logs many harmless things as errors too (an OBJ's missing
// material, an unsupported animation track: 23 of its test models that load log some), which are
// not these.
const char *const geometry_errors[] = {
    "OFF: Vertex index is out of range",                       // clamped to the last vertex
    "OFF: The number of verts in the header is incorrect",     // the missing ones left at the origin
    "OFF: The number of faces in the header is incorrect",     // the missing ones left empty
    "OFF: Faces with zero indices aren't allowed",             // the face dropped
    "STL: a facet with more than 3 vertices has been found",   // the extra corners dropped
    "OBJ: Not supported token in face description detected",   // the rest of the face dropped
};

// Catches those errors in Assimp's log, the only place they appear.
class ErrorLog : public Assimp::LogStream {
public:
    ErrorLog(std::string &first, unsigned &count) : first_(first), count_(count) {}
    void write(const char *message) override
    {
        const char *text = std::strstr(message, ": ");  // after Assimp's "Error, T0" prefix
        text = text ? text + 2 : message;
        for (const char *known : geometry_errors)
            if (std::strncmp(text, known, std::strlen(known)) == 0 && !count_++) first_ = known;
    }

private:
    std::string &first_;
    unsigned &count_;
};

// Assimp's logger is one global object: each loader process has its own.
struct LoggedErrors {
    std::string first;
    unsigned count = 0;
    LoggedErrors()
    {
        Assimp::DefaultLogger::create(nullptr, Assimp::Logger::NORMAL, 0);
        Assimp::DefaultLogger::get()->attachStream(new ErrorLog(first, count), Assimp::Logger::Err);
    }
    ~LoggedErrors() { Assimp::DefaultLogger::kill(); }
};

// Faces Assimp's readers leave behind on malformed input, which its triangulation step would
// abort on (Debian builds Assimp with its internal assertions on): a face without indices, an
// index out of range, or primitive-type flags that disagree with the faces.
bool check_faces(const aiScene *scene, std::string &error) {
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        aiMesh *mesh = scene->mMeshes[m];
        if (mesh->mNumFaces > 0 && (!mesh->mFaces || !mesh->mVertices)) {
            error = "mesh " + std::to_string(m) + " has faces but no vertex or face data";
            return false;
        }
        unsigned types = 0;
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
            const aiFace &face = mesh->mFaces[f];
            if (face.mNumIndices == 0 || !face.mIndices) {
                error = "face " + std::to_string(f) + " of mesh " + std::to_string(m) + " has no vertices";
                return false;
            }
            for (unsigned k = 0; k < face.mNumIndices; ++k) {
                if (face.mIndices[k] >= mesh->mNumVertices) {
                    error = "face " + std::to_string(f) + " of mesh " + std::to_string(m) +
                            " refers to a vertex that does not exist";
                    return false;
                }
            }
            types |= face.mNumIndices == 1   ? aiPrimitiveType_POINT
                     : face.mNumIndices == 2 ? aiPrimitiveType_LINE
                     : face.mNumIndices == 3 ? aiPrimitiveType_TRIANGLE
                                             : aiPrimitiveType_POLYGON;
        }
        mesh->mPrimitiveTypes = types;
    }
    return true;
}

// Reads, checks and copies out, under the caller's heap budget and error log.
bool read_mesh(Assimp::Importer &importer, const std::string &path, Mesh &out, std::string &error)
{
    // Read and validate first, check what Assimp's validation lets through, then triangulate,
    // merge identical vertices and bake the node transforms into the vertices.
    const aiScene *scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
    if (!scene) {
        error = importer.GetErrorString();
        if (error.empty()) error = "Assimp could not read it";
        return false;
    }
    if (!check_faces(scene, error)) {
        error = "malformed file: " + error;
        return false;
    }
    scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                         aiProcess_PreTransformVertices);
    if (!scene) {
        error = importer.GetErrorString();
        if (error.empty()) error = "Assimp could not process it";
        return false;
    }
    size_t vertices = 0, triangles = 0;
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
        const aiMesh *mesh = scene->mMeshes[mi];
        vertices += mesh->mNumVertices;
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) triangles += mesh->mFaces[f].mNumIndices == 3;
    }
    if (vertices > KDRT_MAX_TRIANGLES) {
        error = "too many vertices";
        return false;
    }
    out = Mesh();
    out.name = std::filesystem::path(path).stem().string();
    out.positions.reserve(3 * vertices);  // exact sizes: no doubling past the budget
    out.indices.reserve(3 * triangles);
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
        const aiMesh *mesh = scene->mMeshes[mi];
        const size_t base = out.vertex_count();
        for (unsigned v = 0; v < mesh->mNumVertices; ++v)
            out.positions.insert(out.positions.end(), {mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z});
        for (unsigned f = 0; f < mesh->mNumFaces; ++f)
            if (mesh->mFaces[f].mNumIndices == 3)  // points and lines are not surfaces
                for (int k = 0; k < 3; ++k) out.indices.push_back(uint32_t(base + mesh->mFaces[f].mIndices[k]));
    }
    if (out.indices.empty()) {
        error = "it holds no triangles";
        return false;
    }
    return true;
}

// 12000000016 -> "12,000,000,016"
std::string grouped(uint64_t n)
{
    const std::string digits = std::to_string(n);
    std::string out;
    for (size_t i = 0; i < digits.size(); ++i) {
        if (i && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

// load_mesh's work, in the calling process (load_mesh runs it in a child).
bool load_here(const std::string &path, Mesh &out, std::string &error, uint64_t heap_factor, uint64_t heap_floor,
               MeshLoadStats *stats) {
    LoggedErrors logged;
    Assimp::Importer importer;
    GuardedFiles *files = new GuardedFiles(heap_factor);
    importer.SetIOHandler(files);  // the importer owns it
    Mesh mesh;
    bool ok;
    uint64_t refused, in_use, limit;
    {
        // Assimp allocates what a header claims before it reads the data (a 34-byte OFF file asks
        // for 28 GB): what it allocates is capped in proportion to the bytes it is given.
        HeapBudget budget(heap_floor);
        files->charge(&budget);
        try {
            ok = read_mesh(importer, path, mesh, error);
        } catch (const std::bad_alloc &) {  // refused in our own copy; Assimp catches its own
            ok = false;
        }
        files->charge(nullptr);
        refused = budget.refused(), in_use = budget.live_at_refusal(), limit = budget.limit();
        if (stats) stats->file_bytes = files->bytes(), stats->peak_heap_bytes = budget.peak();
    }
    const uint64_t file_bytes = files->bytes();
    if (refused) {
        const std::string allowed = " that " + grouped(file_bytes) + " bytes of mesh file may take (" +
                                    std::to_string(heap_factor) + " times their size, plus " +
                                    std::to_string(heap_floor >> 20) + " MiB)";
        if (refused >= HeapBudget::large_request)
            error = "refused: reading it asked for " + grouped(refused) + " bytes of memory" +
                    (refused > limit ? std::string(" at once") : " with " + grouped(in_use) + " in use") +
                    ", more than the " + grouped(limit) + allowed;
        else
            error = "refused: reading it took more than twice the " + grouped(limit) + " bytes of memory" + allowed;
        return false;
    }
    if (!ok) return false;
    if (logged.count) {
        error = "malformed file: " + logged.first +
                (logged.count > 1 ? " (and " + std::to_string(logged.count - 1) + " more errors)" : "");
        return false;
    }
    out = std::move(mesh);
    return true;
}

// The loader process's answer, on a pipe: a magic word and success, then the message, the mesh's
// name, positions and indices, each length first, and the load's statistics.
const uint64_t answer_magic = 0x6b6472746d657368;  // "kdrtmesh"

bool write_all(int fd, const void *data, size_t size) {
    const char *p = static_cast<const char *>(data);
    while (size > 0) {
        const ssize_t n = ::write(fd, p, size);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        p += n, size -= size_t(n);
    }
    return true;
}

template <class T> bool write_array(int fd, const T *items, size_t count) {
    const uint64_t n = count;
    return write_all(fd, &n, sizeof n) && write_all(fd, items, count * sizeof(T));
}

bool write_answer(int fd, bool ok, const std::string &error, const Mesh &mesh, const MeshLoadStats &stats) {
    const uint64_t head[2] = {answer_magic, ok};
    return write_all(fd, head, sizeof head) && write_array(fd, error.data(), error.size()) &&
           write_array(fd, mesh.name.data(), mesh.name.size()) &&
           write_array(fd, mesh.positions.data(), mesh.positions.size()) &&
           write_array(fd, mesh.indices.data(), mesh.indices.size()) && write_all(fd, &stats, sizeof stats);
}

// Reads the answer back; false where it is cut short (the loader died) or does not add up.
struct AnswerReader {
    const std::string &data;
    size_t at = 0;
    bool get(void *out, size_t size) {
        if (data.size() - at < size) return false;
        if (size) std::memcpy(out, data.data() + at, size);
        at += size;
        return true;
    }
    template <class T> bool get_array(T &items) {  // a std::string or std::vector
        const size_t item = sizeof(typename T::value_type);
        uint64_t n;
        if (!get(&n, sizeof n) || n > (data.size() - at) / item) return false;
        items.resize(size_t(n));
        return get(items.data(), size_t(n) * item);
    }
};

}  // namespace

bool load_mesh(const std::string &path, Mesh &out, std::string &error) {
    return load_mesh(path, out, error, mesh_heap_factor, mesh_heap_floor, nullptr);
}

// Assimp reads in a child process: some of its readers free memory twice when the heap budget
// stops them (3DS, ASE, DirectX, glTF, LWO, MD5, NFF and SMD were seen to), and others may crash on
// a malformed file in ways no check here foresees. In the child that is a file refused; in the
// tool it would be the tool's end. The child keeps the budget's rule and sends the mesh back.
bool load_mesh(const std::string &path, Mesh &out, std::string &error, uint64_t heap_factor, uint64_t heap_floor,
               MeshLoadStats *stats, uint64_t cpu_limit) {
    if (stats) *stats = MeshLoadStats();
    struct stat st;
    if (::stat(path.c_str(), &st) != 0) {
        error = errno == ENOENT ? "no such file" : std::strerror(errno);
        return false;
    }
    if (!(error = not_regular(st)).empty()) return false;
    if (!check_ply_header(path, error)) return false;

    // A reader that loops ends with the child: it may take mesh_cpu_seconds, and one more a MB.
    const uint64_t cpu_seconds = cpu_limit + uint64_t(st.st_size >> 20);
    int pipe_fds[2];
    if (::pipe(pipe_fds) != 0) {
        error = std::string("cannot start the loader process: ") + std::strerror(errno);
        return false;
    }
    const pid_t child = ::fork();
    if (child < 0) {
        error = std::string("cannot start the loader process: ") + std::strerror(errno);
        ::close(pipe_fds[0]), ::close(pipe_fds[1]);
        return false;
    }
    if (child == 0) {  // the loader: one thread, a copy of everything; it never returns
        ::close(pipe_fds[0]);
        // The tool's handlers are the tool's: its cleanup, a test framework's crash reports.
        for (int signal : {SIGINT, SIGTERM, SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGXCPU})
            std::signal(signal, SIG_DFL);
        const rlimit cpu = {rlim_t(cpu_seconds), rlim_t(cpu_seconds + 1)};  // then SIGXCPU
        ::setrlimit(RLIMIT_CPU, &cpu);
        Mesh mesh;
        std::string why;
        MeshLoadStats took;
        const bool ok = load_here(path, mesh, why, heap_factor, heap_floor, &took);
        ::_exit(write_answer(pipe_fds[1], ok, why, mesh, took) ? 0 : 1);  // no atexit, no stdio flush
    }
    ::close(pipe_fds[1]);
    std::string data;
    std::vector<char> buffer(1 << 16);
    for (;;) {
        const ssize_t n = ::read(pipe_fds[0], buffer.data(), buffer.size());
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        data.append(buffer.data(), size_t(n));
    }
    ::close(pipe_fds[0]);
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {}

    AnswerReader answer{data};
    uint64_t head[2];
    std::string message;
    Mesh mesh;
    MeshLoadStats took;
    if (!answer.get(head, sizeof head) || head[0] != answer_magic || !answer.get_array(message) ||
        !answer.get_array(mesh.name) || !answer.get_array(mesh.positions) || !answer.get_array(mesh.indices) ||
        !answer.get(&took, sizeof took) || answer.at != data.size()) {
        if (WIFSIGNALED(status) && WTERMSIG(status) == SIGXCPU)
            error = "refused: reading it took more than " + std::to_string(cpu_seconds) + " s (" +
                    std::to_string(cpu_limit) + " s, and 1 s a MB of file)";
        else  // a signal, or a sanitizer's report and exit
            error = "Assimp crashed reading it (" +
                    (WIFSIGNALED(status) ? std::string(strsignal(WTERMSIG(status)))
                                         : "exit status " + std::to_string(WEXITSTATUS(status))) + ")";
        return false;
    }
    if (stats) *stats = took;
    if (!head[1]) {
        error = message;
        return false;
    }
    out = std::move(mesh);
    return true;
}

std::string mesh_dir()
{
    const char *from_environment = std::getenv("KDRT_MESH_DIR");
    return from_environment && *from_environment ? from_environment : KDRT_MESH_DIR;
}

const char *configured_mesh_dir()
{
    return KDRT_MESH_DIR;
}

std::string mesh_dir_help()
{
    return std::string("$KDRT_MESH_DIR, else the one configured at build time: ") +
           (*KDRT_MESH_DIR ? KDRT_MESH_DIR : "(none)");
}

}  // namespace common
