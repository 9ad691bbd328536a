// common::load_mesh on bad input (examples/common/mesh_io.hpp): files that claim more than they
// hold are refused under the heap budget, paths that are not regular files are refused without
// blocking, and the geometry errors Assimp only logs are errors. The files are written here.
#include "common/heap_budget.hpp"
#include "common/mesh_io.hpp"
#include "temp_dir.hpp"

#include <catch2/catch.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <new>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;

namespace {

using kt::TempDir;


std::string le32(uint32_t v)
{
    return std::string{char(v), char(v >> 8), char(v >> 16), char(v >> 24)};
}
std::string le_float(float f)
{
    uint32_t v;
    std::memcpy(&v, &f, 4);
    return le32(v);
}

// Opens a FIFO for writing after `seconds` unless cancelled first, which ends a reader's wait
// with end-of-file: a loader that blocked on the FIFO comes back late instead of never.
// The constructor returns once the timer thread waits: the loader forks, and a thread still
// starting may hold an allocator lock that the child then waits on for ever (Clang 14's
// AddressSanitizer does not take its allocator's locks around fork, as glibc's malloc does).
class Unblocker {
public:
    Unblocker(std::string fifo, int seconds)
        : thread_([this, fifo, seconds] {
              std::unique_lock<std::mutex> lock(mutex_);
              waiting_ = true;
              cv_.notify_one();
              if (cv_.wait_for(lock, std::chrono::seconds(seconds), [this] { return cancelled_; })) return;
              fired_ = true;
              std::ofstream unblock(fifo);  // open, then close: EOF for the reader
          })
    {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return waiting_; });
    }
    bool fired()  // stops the timer; true when it had to unblock a reader
    {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            cancelled_ = true;
        }
        cv_.notify_one();
        if (thread_.joinable()) thread_.join();
        return fired_;
    }
    ~Unblocker() { fired(); }

private:
    std::mutex mutex_;
    std::condition_variable cv_;
    bool waiting_ = false;
    bool cancelled_ = false;
    std::atomic<bool> fired_{false};
    std::thread thread_;
};

// A billion of everything, in the few bytes of each format's header.
const std::string billion = "1000000000";

}  // namespace

TEST_CASE("mesh loading: a file claiming more than it can hold is refused and the claim named", "[mesh_load]")
{
    TempDir dir;
    struct Case {
        const char *name;
        std::string bytes;
    };
    const std::string ply_vertices = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                     "element face 1\nproperty list uint int vertex_indices\nend_header\n";
    std::string three_floats;
    for (float f : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) three_floats += le_float(f);
    const std::vector<Case> cases = {
        // The file: Assimp's OFF reader allocates the faces and vertices the header claims.
        {"claims.off", "OFF\n" + billion + " " + billion + " 0\n0 0 0\n"},
        // A face whose index list claims 4,294,967,280 entries, in ASCII and in binary.
        {"list_ascii.ply", "ply\nformat ascii 1.0\n" + ply_vertices + "0 0 0\n1 0 0\n0 1 0\n4294967280 0 1 2\n"},
        {"list_binary.ply", "ply\nformat binary_little_endian 1.0\n" + ply_vertices + three_floats + le32(4294967280u) +
                                le32(0) + le32(1) + le32(2)},
        // DirectX, ASE, Collada and MD5 headers with vertex and face counts.
        {"claims.x", "xof 0302txt 0064\nMesh m {\n" + billion + ";\n0.0;0.0;0.0;;\n" + billion + ";\n3;0,0,0;;\n}\n"},
        {"claims.ase", "*3DSMAX_ASCIIEXPORT 200\n*GEOMOBJECT {\n*NODE_NAME \"a\"\n*MESH {\n*MESH_NUMVERTEX " + billion +
                           "\n*MESH_NUMFACES " + billion + "\n*MESH_VERTEX_LIST {\n*MESH_VERTEX 0 0 0 0\n}\n}\n}\n"},
        {"claims.dae",
         "<?xml version=\"1.0\"?>\n<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">"
         "<library_geometries><geometry id=\"g\"><mesh><source id=\"p\"><float_array id=\"pa\" count=\"3000000000\">0 0 0"
         "</float_array><technique_common><accessor source=\"#pa\" count=\"" + billion + "\" stride=\"3\">"
         "<param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/><param name=\"Z\" type=\"float\"/>"
         "</accessor></technique_common></source><vertices id=\"v\"><input semantic=\"POSITION\" source=\"#p\"/>"
         "</vertices><triangles count=\"" + billion + "\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/>"
         "<p>0 0 0</p></triangles></mesh></geometry></library_geometries><library_visual_scenes><visual_scene id=\"s\">"
         "<node><instance_geometry url=\"#g\"/></node></visual_scene></library_visual_scenes><scene>"
         "<instance_visual_scene url=\"#s\"/></scene></COLLADA>\n"},
        {"claims.md5mesh", "MD5Version 10\ncommandline \"\"\nnumJoints 1\nnumMeshes 1\njoints {\n\"root\" -1 ( 0 0 0 ) "
                           "( 0 0 0 )\n}\nmesh {\nshader \"a\"\nnumverts " + billion + "\nvert 0 ( 0 0 ) 0 1\nnumtris " +
                               billion + "\ntri 0 0 0 0\nnumweights " + billion + "\nweight 0 0 1.0 ( 0 0 0 )\n}\n"},
    };
    const std::regex refused("^refused: reading it asked for ([0-9,]+) bytes of memory.* that ([0-9,]+) bytes of "
                             "mesh file may take \\(128 times their size, plus 32 MiB\\)$");
    for (const Case &c : cases) {
        DYNAMIC_SECTION(c.name)
        {
            const std::string path = dir.write(c.name, c.bytes);
            common::Mesh mesh;
            std::string error;
            CHECK_FALSE(common::load_mesh(path, mesh, error));
            INFO(error);
            std::smatch m;
            REQUIRE(std::regex_match(error, m, refused));
            std::string asked = m[1], size = m[2];
            asked.erase(std::remove(asked.begin(), asked.end(), ','), asked.end());
            size.erase(std::remove(size.begin(), size.end(), ','), size.end());
            CHECK(std::stoull(asked) >= 1000000000ull);  // what the header claims, at least a byte each
            CHECK(std::stoull(size) == c.bytes.size());
            CHECK(mesh.triangle_count() == 0);
        }
    }
}

TEST_CASE("mesh loading: the heap budget refuses the request that would pass it on its own thread only", "[mesh_load]")
{
    const size_t mib = size_t(1) << 20;
    std::vector<char> before(mib);  // allocated before the budget, freed after it
    {
        common::HeapBudget budget(4 * mib);
        std::vector<char> small(mib);
        CHECK_THROWS_AS(std::vector<char>(4 * mib), std::bad_alloc);
        CHECK(budget.refused() == 4 * mib);
        CHECK(budget.live_at_refusal() >= mib);
        CHECK(new (std::nothrow) char[8 * mib] == nullptr);  // the nothrow forms return null
        CHECK(budget.refused() == 4 * mib);                   // the first refusal is the one kept
        // Another thread allocates freely.
        bool other = false;
        std::thread([&] { other = std::vector<char>(16 * mib).size() == 16 * mib; }).join();
        CHECK(other);
        budget.raise(8 * mib);
        CHECK_NOTHROW(std::vector<char>(8 * mib));
        CHECK(budget.limit() == 12 * mib);
        CHECK(budget.peak() >= 9 * mib);
        {
            common::HeapBudget inner(2 * mib);  // nested: the inner one rules while it lives
            CHECK_THROWS_AS(std::vector<char>(3 * mib), std::bad_alloc);
        }
        CHECK_NOTHROW(std::vector<char>(8 * mib));
    }
    CHECK_NOTHROW(std::vector<char>(64 * mib));  // disarmed
    {
        // Requests under large_request are held to twice the limit only.
        common::HeapBudget budget(4 * mib);
        std::vector<std::unique_ptr<char[]>> blocks;
        blocks.reserve(16 * 1024);
        for (int i = 0; i < 6 * 1024; ++i) blocks.emplace_back(new char[1024]);  // 6 MiB
        CHECK(budget.refused() == 0);
        CHECK_THROWS_AS(std::vector<char>(mib), std::bad_alloc);
        CHECK(budget.refused() == mib);
        CHECK_THROWS_AS([&] { for (int i = 0; i < 3 * 1024; ++i) blocks.emplace_back(new char[1024]); }(), std::bad_alloc);
        CHECK(budget.peak() <= 8 * mib);
    }
}

TEST_CASE("mesh loading: a dense real-looking mesh loads under the heap budget", "[mesh_load]")
{
    // A 250 x 250 grid with integer coordinates as an OBJ: short lines, the largest ratio of heap to
    // file size measured on meshes that are not generated by the reader (tools/README.md).
    TempDir dir;
    const int n = 250;
    std::string obj;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) obj += "v " + std::to_string(i) + " " + std::to_string(j) + " " + std::to_string((i * 7 + j * 13) % 17) + "\n";
    for (int i = 0; i + 1 < n; ++i)
        for (int j = 0; j + 1 < n; ++j) {
            const int a = i * n + j + 1, b = a + 1, c = a + n, d = c + 1;
            obj += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(d) + "\nf " +
                   std::to_string(a) + " " + std::to_string(d) + " " + std::to_string(c) + "\n";
        }
    const std::string path = dir.write("grid.obj", obj);
    common::Mesh mesh;
    std::string error;
    common::MeshLoadStats stats;
    const bool loaded = common::load_mesh(path, mesh, error, common::mesh_heap_factor, common::mesh_heap_floor, &stats);
    INFO(error);
    REQUIRE(loaded);
    CHECK(mesh.triangle_count() == 2 * (n - 1) * (n - 1));
    CHECK(mesh.vertex_count() == n * n);
    CHECK(stats.file_bytes == obj.size());
    INFO("peak " << stats.peak_heap_bytes << " bytes for " << stats.file_bytes);
    CHECK(stats.peak_heap_bytes > 20 * stats.file_bytes);  // the budget measures something
}

TEST_CASE("mesh loading: a load the heap budget stops anywhere fails cleanly", "[mesh_load]")
{
    // The same small mesh as OFF, OBJ and binary PLY, loaded under 200 caps from nothing to the
    // heap the load takes: each stops at another allocation, in Assimp's readers, its
    // post-processing or the copy out, and must come back refused, with nothing thrown or broken
    // (or whole, small requests being held to twice the cap).
    TempDir dir;
    const int n = 12;
    std::string off = "OFF\n" + std::to_string(n * n) + " " + std::to_string(2 * (n - 1) * (n - 1)) + " 0\n", obj,
                ply = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n * n) +
                      "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                      std::to_string(2 * (n - 1) * (n - 1)) + "\nproperty list uchar int vertex_indices\nend_header\n";
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const std::string v = std::to_string(i) + " " + std::to_string(j) + " " + std::to_string((i * j) % 5);
            off += v + "\n", obj += "v " + v + "\n";
            for (float f : {float(i), float(j), float((i * j) % 5)}) ply += le_float(f);
        }
    for (int i = 0; i + 1 < n; ++i)
        for (int j = 0; j + 1 < n; ++j) {
            const int a = i * n + j, b = a + 1, c = a + n, d = c + 1;
            for (const auto &t : {std::array<int, 3>{a, b, d}, std::array<int, 3>{a, d, c}}) {
                off += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
                obj += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
                ply += std::string(1, char(3)) + le32(uint32_t(t[0])) + le32(uint32_t(t[1])) + le32(uint32_t(t[2]));
            }
        }
    for (const auto &file : {dir.write("grid.off", off), dir.write("grid.obj", obj), dir.write("grid.ply", ply)}) {
        common::Mesh mesh;
        std::string error;
        common::MeshLoadStats stats;
        REQUIRE(common::load_mesh(file, mesh, error, 0, uint64_t(1) << 30, &stats));
        const uint64_t peak = stats.peak_heap_bytes;
        unsigned refused = 0, whole = 0, tries = 0;
        for (uint64_t cap = 0; cap < peak; cap += peak / 200 + 1) {
            ++tries;
            common::Mesh partial;
            std::string why;
            bool loaded = false;
            CHECK_NOTHROW(loaded = common::load_mesh(file, partial, why, 0, cap, nullptr));
            refused += !loaded && why.compare(0, 9, "refused: ") == 0 && partial.triangle_count() == 0;
            whole += loaded && partial.triangle_count() == 2 * (n - 1) * (n - 1);  // small requests may pass the cap
        }
        INFO(file << ": peak " << peak << " bytes");
        CHECK(refused + whole == tries);
        CHECK(refused >= tries / 3);
        CHECK(common::load_mesh(file, mesh, error, 0, peak, nullptr));  // and at its peak it loads
        CHECK(mesh.triangle_count() == 2 * (n - 1) * (n - 1));
    }
}

TEST_CASE("mesh loading: a path that is not a regular file is refused at once by what it is", "[mesh_load]")
{
    TempDir dir;
    common::Mesh mesh;
    std::string error;
    CHECK_FALSE(common::load_mesh(dir.file("missing.off"), mesh, error));
    CHECK(error == "no such file");
    fs::create_directory(dir.file("x.obj"));
    CHECK_FALSE(common::load_mesh(dir.file("x.obj"), mesh, error));
    CHECK(error == "it is a directory");
    CHECK_FALSE(common::load_mesh("/dev/zero", mesh, error));
    CHECK(error == "it is not a regular file (a character device)");

    const std::string fifo = dir.fifo("fifo.off");
    Unblocker unblocker(fifo, 10);
    CHECK_FALSE(common::load_mesh(fifo, mesh, error));
    CHECK(error == "it is not a regular file (a FIFO)");
    CHECK_FALSE(unblocker.fired());  // it did not wait for a writer
}

TEST_CASE("mesh loading: files a mesh names that are not regular files are not opened", "[mesh_load]")
{
    TempDir dir;
    common::Mesh mesh;
    std::string error;
    SECTION("an OBJ's material library")
    {
        // The materials are not needed: the mesh loads without them, and without waiting.
        const std::string fifo = dir.fifo("materials.mtl");
        const std::string obj = dir.write("a.obj", "mtllib materials.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        Unblocker unblocker(fifo, 10);
        CHECK(common::load_mesh(obj, mesh, error));
        CHECK(mesh.triangle_count() == 1);
        CHECK_FALSE(unblocker.fired());
    }
    SECTION("a glTF's buffer")
    {
        const std::string fifo = dir.fifo("data.bin");
        const std::string gltf = dir.write(
            "a.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0]}], \"nodes\": "
                      "[{\"mesh\": 0}], \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}}]}], "
                      "\"buffers\": [{\"uri\": \"data.bin\", \"byteLength\": 36}], \"bufferViews\": [{\"buffer\": 0, "
                      "\"byteLength\": 36}], \"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 3, "
                      "\"type\": \"VEC3\", \"min\": [0, 0, 0], \"max\": [1, 1, 0]}]}");
        Unblocker unblocker(fifo, 10);
        CHECK_FALSE(common::load_mesh(gltf, mesh, error));
        CHECK(error.find("data.bin") != std::string::npos);
        CHECK_FALSE(unblocker.fired());
    }
}

TEST_CASE("mesh loading: geometry Assimp changes and only logs an error about is refused", "[mesh_load]")
{
    TempDir dir;
    common::Mesh mesh;
    std::string error;
    // Assimp's OFF reader clamps an index past the last vertex to the last vertex.
    CHECK_FALSE(common::load_mesh(dir.write("index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 4000000000\n"), mesh, error));
    CHECK(error == "malformed file: OFF: Vertex index is out of range");
    // Its STL reader drops a facet's fourth corner.
    CHECK_FALSE(common::load_mesh(dir.write("four.stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                                                      "vertex 0 1 0\nvertex 1 1 0\nendloop\nendfacet\nendsolid a\n"),
                                  mesh, error));
    CHECK(error == "malformed file: STL: a facet with more than 3 vertices has been found");
    // Its OFF reader drops faces of no corners, counting each.
    CHECK_FALSE(common::load_mesh(dir.write("empty_faces.off", "OFF\n3 3 0\n0 0 0\n1 0 0\n0 1 0\n0\n3 0 1 2\n0\n"), mesh, error));
    CHECK(error == "malformed file: OFF: Faces with zero indices aren't allowed (and 1 more errors)");
    // An error Assimp logs about something else, a material it cannot find, is not the geometry's.
    CHECK(common::load_mesh(dir.write("material.obj", "usemtl nowhere\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), mesh, error));
    CHECK(mesh.triangle_count() == 1);
}

TEST_CASE("mesh loading: PLY headers Assimp loops or crashes on are refused", "[mesh_load]")
{
    TempDir dir;
    common::Mesh mesh;
    std::string error;
    // Elements with no properties, by the billion: Assimp's reader reads "each" one for minutes.
    CHECK_FALSE(common::load_mesh(dir.write("ascii.ply", "ply\nformat ascii 1.0\nelement vertex " + billion + "\nend_header\n"),
                                  mesh, error));
    CHECK(error == "malformed PLY file: its header claims 1000000000 vertex elements, more than its 58 bytes can hold");
    CHECK_FALSE(common::load_mesh(
        dir.write("binary.ply", "ply\nformat binary_little_endian 1.0\nelement vertex " + billion + "\nend_header\n"), mesh, error));
    CHECK(error == "malformed PLY file: its header claims 1000000000 vertex elements, more than its 73 bytes can hold");
    // A header that never ends, whatever the case of its "ply" (the fuzz target found "pLy").
    for (const char *magic : {"ply", "pLy", "PLY"}) {
        CHECK_FALSE(common::load_mesh(dir.write("open.ply", std::string(magic) + "\nformat ascii 1.0\nelement vertex 3\n"),
                                      mesh, error));
        CHECK(error == "malformed PLY file: its header has no end_header line");
    }
    // An element without a count (found by the fuzz target: Assimp's reader read out of bounds).
    std::string faces;
    for (uint32_t v : {3u, 0u, 1u, 2u}) faces += v == 3 ? std::string(1, char(3)) : le32(v);
    CHECK_FALSE(common::load_mesh(
        dir.write("no_count.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                                  "property float y\nproperty float z\nelement face vertex_indices\n"
                                  "property list uchar uint vertex_indices\nend_header\n" +
                                      std::string(36, '\0') + faces),
        mesh, error));
    CHECK(error == "malformed PLY file: header line 7 is not a PLY header line: 'element face vertex_indices'");
    // Lines PLY does not know are skipped, as Assimp skips them (Blender 2.4 wrote one).
    CHECK(common::load_mesh(dir.write("blender.ply", "ply\nformat ascii 1.0\nCreated by Blender3D 247\nelement vertex 3\n"
                                                     "property float x\nproperty float y\nproperty float z\n"
                                                     "element face 1\nproperty list uchar int vertex_indices\n"
                                                     "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
                            mesh, error));
    CHECK(mesh.triangle_count() == 1);
}

TEST_CASE("mesh loading: threads loading at once each get their own answer", "[mesh_load]")
{
#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define KDRT_TEST_UNDER_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(KDRT_TEST_UNDER_ASAN)
    // Each load forks; under Clang 14's AddressSanitizer a fork while another thread allocates can
    // leave the child waiting on the allocator's lock for ever (mesh_io.hpp). The Release build
    // runs this test.
    WARN("kdrt test skipped: loads from several threads at once can hang under AddressSanitizer's fork");
    return;
#endif
    TempDir dir;
    const std::string good = dir.write("good.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    const std::string bad = dir.write("bad.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
    const std::string huge = dir.write("huge.off", "OFF\n" + billion + " " + billion + " 0\n");
    std::atomic<int> wrong{0};
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&, t] {
            for (int i = 0; i < 10; ++i) {
                common::Mesh mesh;
                std::string error;
                const int which = (t + i) % 3;
                const bool ok = common::load_mesh(which == 0 ? good : which == 1 ? bad : huge, mesh, error);
                if (which == 0 ? !ok || mesh.triangle_count() != 1
                    : which == 1 ? ok || error != "malformed file: OFF: Vertex index is out of range"
                                 : ok || error.compare(0, 30, "refused: reading it asked for ") != 0)
                    ++wrong;
            }
        });
    for (std::thread &t : threads) t.join();
    CHECK(wrong == 0);
}

// Some of Assimp's readers free memory twice when the budget stops them at the wrong allocation:
// an ASE model from Debian's assimp-testmodels crashes at some 1 in 10 of the caps below its
// peak. Assimp reads in a child process, so a crash there fails that load and nothing else.
TEST_CASE("mesh loading: a reader that crashes fails the load and not the program", "[mesh_load]")
{
    const std::string model = "/usr/share/assimp/models/ASE/RotatingCube.ASE";
    struct stat st;
    if (::stat(model.c_str(), &st) != 0) {
        WARN("kdrt test skipped: " << model << " is absent (Debian's assimp-testmodels, tools/setup.sh installs it)");
        return;
    }
    common::Mesh mesh;
    std::string error;
    common::MeshLoadStats stats;
    REQUIRE(common::load_mesh(model, mesh, error, 0, uint64_t(1) << 30, &stats));
    const size_t triangles = mesh.triangle_count();
    unsigned crashed = 0, other = 0;
    for (uint64_t cap = 0; cap < stats.peak_heap_bytes; cap += stats.peak_heap_bytes / 200 + 1) {
        common::Mesh partial;
        std::string why;
        if (common::load_mesh(model, partial, why, 0, cap, nullptr)) {
            other += partial.triangle_count() != triangles;
            continue;
        }
        crashed += why.compare(0, 26, "Assimp crashed reading it ") == 0;
        other += why.compare(0, 9, "refused: ") != 0 && why.compare(0, 26, "Assimp crashed reading it ") != 0;
        other += partial.triangle_count() != 0 || why.find('\n') != std::string::npos;
    }
    CHECK(crashed > 0);  // the case is real: without the child process the test would not get here
    CHECK(other == 0);
}

// A reader that takes too long ends with its process: one OBJ face of 32,000 corners takes
// Assimp's triangulation about 4 s here (under the default 5 s); held to 1 s, it is refused.
TEST_CASE("mesh loading: a load past its CPU time is refused and the limit named", "[mesh_load]")
{
    TempDir dir;
    std::string obj;
    const int corners = 32000;
    for (int i = 0; i < corners; ++i)
        obj += "v " + std::to_string(std::cos(6.283185307179586 * i / corners)) + " " +
               std::to_string(std::sin(6.283185307179586 * i / corners)) + " 0\n";
    obj += "f";
    for (int i = 1; i <= corners; ++i) obj += " " + std::to_string(i);
    const std::string path = dir.write("big-face.obj", obj + "\n");
    common::Mesh mesh;
    std::string error;
    const auto start = std::chrono::steady_clock::now();
    CHECK_FALSE(common::load_mesh(path, mesh, error, common::mesh_heap_factor, common::mesh_heap_floor, nullptr, 1));
    CHECK(error == "refused: reading it took more than 1 s (1 s, and 1 s a MB of file)");
    CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(60));  // a generous bound, for a hang
}
