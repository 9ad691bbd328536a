// Saved trees (kdrt.h, SAVED TREES): kdrt_tree_save() and kdrt_tree_load() for every builder,
// quality, leaf size and kernel, empty trees and scenes' mesh trees; a loaded tree answers bit for
// bit what the saved one does (nearest, any, batches, k nearest, start cells); the bytes are the
// same on every run and kernel and are what the manual's format says (checked here with an
// xxHash and a checksum of the test's own); every failing allocation, wrong mesh, other version,
// other byte order, truncation, extra byte, changed header byte and forged field is refused with
// its result code and leaves nothing allocated.
#include "saved_format.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iterator>
#include <map>
#include <string>
#include <vector>

namespace {

using common::Mesh;
using Bytes = std::vector<unsigned char>;

// ---- the format as the manual describes it, written again here ----

// (saved_format.hpp: the words, XXH64 and the sections' checksum, as the manual gives them)
using namespace saved_format;

struct Layout {
    uint32_t meshes, nodes, leaves, blocks;
    size_t blocks_at, nodes_at, cells_at, refs_at, map_at, meshes_at;
};
Layout layout(const Bytes &f) {
    Layout l;
    l.meshes = get32(&f[20]), l.nodes = get32(&f[80]), l.leaves = get32(&f[84]), l.blocks = get32(&f[88]);
    l.blocks_at = kHeader;
    l.nodes_at = l.blocks_at + 320 * size_t(l.blocks);
    l.cells_at = l.nodes_at + 8 * size_t(l.nodes);
    l.refs_at = l.cells_at + 48 * size_t(l.leaves);
    l.map_at = l.refs_at + 4 * size_t(l.blocks);
    l.meshes_at = l.map_at + 4 * size_t(l.nodes);
    return l;
}

// A forged file: the checksums made again over whatever the bytes now say.
void reseal(Bytes &f) { saved_format::reseal(f.data(), f.size()); }

// ---- saving and loading ----

int append(void *user, const void *bytes, size_t size) {
    Bytes *out = static_cast<Bytes *>(user);
    out->insert(out->end(), static_cast<const unsigned char *>(bytes), static_cast<const unsigned char *>(bytes) + size);
    return 1;
}

Bytes save(const kdrt_tree *tree) {
    Bytes out;
    REQUIRE(kdrt_tree_save(tree, append, &out) == KDRT_SUCCESS);
    REQUIRE(out.size() == kdrt_tree_saved_size(tree));
    return out;
}

kdrt_result try_load(const Bytes &f, const kdrt_triangles &mesh, kdrt_tree **out, uint32_t flags = 0) {
    kdrt_build_options o = kdrt_default_build_options();
    o.flags = flags;
    kdrt_build_report report;
    *out = reinterpret_cast<kdrt_tree *>(&report);  // overwritten with NULL on failure
    static const unsigned char nothing = 0;         // an empty vector's data() may be NULL
    const kdrt_result r = kdrt_tree_load(f.empty() ? &nothing : f.data(), f.size(), &mesh, &o, out, &report);
    if (r != KDRT_SUCCESS) CHECK(*out == nullptr);
    CHECK(report.invalid_triangle == KDRT_INVALID_ID);
    return r;
}

kt::TreePtr load(const Bytes &f, const kdrt_triangles &mesh, uint32_t flags = 0) {
    kdrt_tree *t = nullptr;
    const kdrt_result r = try_load(f, mesh, &t, flags);
    INFO(kdrt_result_string(r));
    REQUIRE(r == KDRT_SUCCESS);
    return kt::TreePtr(t);
}

kdrt_result load_result(const Bytes &f, const kdrt_triangles &mesh) {
    kdrt_tree *t = nullptr;
    const kdrt_result r = try_load(f, mesh, &t);
    kdrt_tree_free(t);
    return r;
}

bool same_bits(const kdrt_hit &a, const kdrt_hit &b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// Every answer of b is a's, bit for bit: the nearest hit (every field of kdrt_hit, misses too),
// any hit, the batches, the 4 nearest, rays spawned from the hits with their start cells, and
// rays started from kdrt_locate()'s cells; the node descriptions and references too. Returns
// the rays traced, for the suite's count.
size_t check_same_answers(const kdrt_tree *a, const kdrt_tree *b, size_t ray_count, uint32_t seed) {
    kt::check_same_shape(a, b);
    kdrt_tree_stats sa, sb;
    kdrt_tree_get_stats(a, &sa), kdrt_tree_get_stats(b, &sb);
    CHECK(sa.triangles == sb.triangles);
    CHECK(sa.blocks == sb.blocks);
    for (uint32_t i = 0; i < sa.nodes; ++i) {
        const kdrt_node_info x = kt::node_info(a, i), y = kt::node_info(b, i);
        if (std::memcmp(&x, &y, sizeof x) != 0) {
            FAIL_CHECK("node " << i << " is described differently");
            break;
        }
    }
    kdrt_aabb box = kdrt_tree_bounds(a);
    if (sa.triangles == 0) box = kdrt_aabb{{-1, -1, -1}, {1, 1, 1}};
    std::vector<kdrt_ray> rays = kt::random_rays(box, ray_count, seed);
    const std::vector<kdrt_hit> ha = kt::trace_all(a, rays), hb = kt::trace_all(b, rays);
    const std::vector<unsigned char> oa = kt::occluded_all(a, rays), ob = kt::occluded_all(b, rays);
    size_t bad = 0;
    for (size_t i = 0; i < rays.size(); ++i)
        if (!same_bits(ha[i], hb[i]) || oa[i] != ob[i]) {
            if (bad++ == 0) FAIL_CHECK("ray " << i << " differs");
        }
    CHECK(bad == 0);
    // Batches, and the k nearest, on a share of the rays.
    const size_t n = std::min<size_t>(rays.size(), 4096);
    std::vector<kdrt_hit> ba(n), bb(n);
    kdrt_intersect_batch(a, rays.data(), uint32_t(n), nullptr, ba.data());
    kdrt_intersect_batch(b, rays.data(), uint32_t(n), nullptr, bb.data());
    std::vector<uint8_t> occ_a(n), occ_b(n);
    kdrt_occluded_batch(a, rays.data(), uint32_t(n), nullptr, occ_a.data());
    kdrt_occluded_batch(b, rays.data(), uint32_t(n), nullptr, occ_b.data());
    size_t bad_batch = 0;
    for (size_t i = 0; i < n; ++i) {
        bad_batch += !same_bits(ba[i], bb[i]) || occ_a[i] != occ_b[i];
        kdrt_hit ka[4], kb[4];
        const uint32_t ca = kdrt_intersect_k(a, &rays[i], nullptr, ka, 4), cb = kdrt_intersect_k(b, &rays[i], nullptr, kb, 4);
        bad_batch += ca != cb || std::memcmp(ka, kb, ca * sizeof *ka) != 0;
    }
    CHECK(bad_batch == 0);
    // Secondary rays from the hits, each tree spawning its own (with the cell of the hit), and
    // rays from the cells kdrt_locate() finds.
    common::Rng rng(seed ^ 0x5A5Au);
    std::vector<kdrt_ray> second;
    for (size_t i = 0; i < ha.size() && second.size() < rays.size() / 2; ++i) {
        if (ha[i].triangle == KDRT_INVALID_ID) continue;
        float dir[3];
        kt::random_direction(rng, dir);
        kdrt_ray ra, rb;
        REQUIRE(kdrt_spawn_ray(a, &ha[i], dir, &ra) == 1);
        REQUIRE(kdrt_spawn_ray(b, &hb[i], dir, &rb) == 1);
        if (std::memcmp(&ra, &rb, sizeof ra) != 0) ++bad;
        second.push_back(ra);
    }
    for (size_t i = 0; i < rays.size() / 8; ++i) {
        kdrt_ray r = rays[i];
        r.cell = kdrt_locate(a, r.org);
        if (r.cell != kdrt_locate(b, r.org)) ++bad;
        second.push_back(r);
    }
    CHECK(bad == 0);
    const std::vector<kdrt_hit> sa2 = kt::trace_all(a, second), sb2 = kt::trace_all(b, second);
    for (size_t i = 0; i < second.size(); ++i)
        if (!same_bits(sa2[i], sb2[i])) {
            if (bad++ == 0) FAIL_CHECK("secondary ray " << i << " differs");
        }
    CHECK(bad == 0);
    return rays.size() + second.size();
}

// ---- a counting allocator that fails on request (as tests/test_errors.cpp's) ----

struct Counter {
    size_t calls = 0, fail_at = 0, live = 0, peak_bytes = 0, live_bytes = 0, wrong_user = 0;
    std::map<void *, size_t> blocks;
    kdrt_allocator hooks() { return kdrt_allocator{&Counter::alloc_cb, &Counter::free_cb, this}; }
    static void *alloc_cb(void *user, size_t size) {
        Counter *c = static_cast<Counter *>(user);
        if (++c->calls == c->fail_at) return nullptr;
        void *p = std::malloc(size);
        if (!p) return nullptr;
        c->blocks[p] = size, ++c->live, c->live_bytes += size;
        c->peak_bytes = std::max(c->peak_bytes, c->live_bytes);
        return p;
    }
    static void free_cb(void *user, void *ptr) {
        Counter *c = static_cast<Counter *>(user);
        auto it = c->blocks.find(ptr);
        if (it == c->blocks.end()) {
            ++c->wrong_user;
            return;
        }
        --c->live, c->live_bytes -= it->second;
        c->blocks.erase(it);
        std::free(ptr);
    }
};

// A small tree for the refusal tests: a closed sphere, SAH, leaf size 4 (a few hundred nodes).
struct Small {
    Mesh mesh = kt::sphere(10, 20, 1.0);
    kdrt_triangles view = mesh.view();
    kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[2]);
    Bytes file = save(tree.get());
};

}  // namespace

// ---------------------------------------------------------------------------------------------

TEST_CASE("save: every builder, quality and leaf size, both kernels: the loaded tree answers bit for bit", "[save]") {
    const std::vector<Mesh> meshes = {kt::sphere(24, 48, 2.0), kt::grid(40, 30, 7), kt::random_soup(1500, 3)};
    const uint32_t leaf_sizes[] = {0, 1, 4, 16};
    const uint32_t kernels[] = {0, KDRT_BUILD_SCALAR_KERNEL};
    // Over ten times the reference suites' ray count over the whole test (KDRT_TEST_RAYS): more
    // than a million rays by default, with the secondary ones, split among the trees; leaf size 0
    // tests every triangle, so it gets what kt::brute_force_rays allows.
    const size_t trees = meshes.size() * (1 + (std::size(leaf_sizes) - 1) * std::size(kt::kBuilders)) * std::size(kernels);
    const size_t per_tree = kt::reference_ray_count() * 9 / trees;
    size_t traced = 0;
    uint32_t seed = 1;
    for (const Mesh &mesh : meshes) {
        const kdrt_triangles view = mesh.view();
        for (uint32_t leaf : leaf_sizes)
            for (const kt::Builder &builder : kt::kBuilders) {
                if (leaf == 0 && &builder != &kt::kBuilders[0]) continue;  // no tree: one builder is all
                for (uint32_t kernel : kernels) {
                    INFO(mesh.name << ", leaf size " << leaf << ", " << builder.name << (kernel ? ", scalar kernel" : ""));
                    kt::TreePtr built = kt::build(mesh, leaf, builder, kernel);
                    const Bytes file = save(built.get());
                    // The load chooses the kernel from its own options: the other one here.
                    kt::TreePtr loaded = load(file, view, kernel ? 0u : uint32_t(KDRT_BUILD_SCALAR_KERNEL));
                    kdrt_tree_stats s;
                    kdrt_tree_get_stats(loaded.get(), &s);
                    if (!kernel) CHECK(s.kernel == KDRT_KERNEL_SCALAR);
                    const size_t rays = leaf == 0 ? kt::brute_force_rays(per_tree, view.triangle_count) : per_tree;
                    traced += check_same_answers(built.get(), loaded.get(), rays, seed++);
                    // Saving the loaded tree gives the same bytes.
                    CHECK(save(loaded.get()) == file);
                }
            }
    }
    WARN("save: " << traced << " rays traced through saved and loaded trees");
}

TEST_CASE("save: the bytes are the same on every run and every kernel, and the manual's format", "[save]") {
    const Mesh mesh = kt::sphere(12, 24, 1.0);
    const kdrt_triangles view = mesh.view();
    for (const kt::Builder &builder : kt::kBuilders) {
        INFO(builder.name);
        const Bytes first = save(kt::build(mesh, 4, builder).get());
        CHECK(save(kt::build(mesh, 4, builder).get()) == first);
        CHECK(save(kt::build(mesh, 4, builder, KDRT_BUILD_SCALAR_KERNEL).get()) == first);
        CHECK(save(kt::build(mesh, 4, builder, KDRT_BUILD_AVX2_KERNEL).get()) == first);

        // The header as the manual lays it out.
        const Layout l = layout(first);
        REQUIRE(first.size() > kHeader);
        CHECK(std::memcmp(first.data(), "KDRTTREE", 8) == 0);
        CHECK(get32(&first[8]) == 0x01020304u);
        CHECK((first[8] == 4 && first[11] == 1));
        CHECK(get32(&first[12]) == KDRT_SAVED_TREE_VERSION);
        CHECK(get32(&first[16]) == kHeader);
        CHECK(get64(&first[24]) == first.size());
        CHECK(l.meshes == 1);
        CHECK(get64(&first[32]) == kMeshRecord);
        CHECK(get64(&first[40]) == 8ull * l.nodes);
        CHECK(get64(&first[48]) == 320ull * l.blocks);
        CHECK(get64(&first[56]) == 4ull * l.blocks);
        CHECK(get64(&first[64]) == 48ull * l.leaves);
        CHECK(get64(&first[72]) == 4ull * l.nodes);
        CHECK(l.meshes_at + kMeshRecord == first.size());
        CHECK(get32(&first[112]) == uint32_t(builder.builder));
        CHECK(get32(&first[116]) == uint32_t(builder.quality));
        CHECK(get32(&first[124]) == 4u);
        CHECK(get64(&first[248]) == xxh64(first.data(), 248));
        CHECK(get64(&first[192]) == xxh64(&first[l.meshes_at], kMeshRecord));
        CHECK(get64(&first[200]) == sections_sum(&first[kHeader], l.meshes_at - kHeader));
        // The mesh record: ID 0, the counts, indexed, and XXH64 of the positions and indices.
        const unsigned char *record = &first[l.meshes_at];
        CHECK(get32(record) == 0u);
        CHECK(get32(record + 4) == view.triangle_count);
        CHECK(get32(record + 8) == view.vertex_count);
        CHECK(get32(record + 12) == 1u);
        CHECK(get64(record + 16) == xxh64(reinterpret_cast<const unsigned char *>(mesh.positions.data()), mesh.positions.size() * 4));
        CHECK(get64(record + 24) == xxh64(reinterpret_cast<const unsigned char *>(mesh.indices.data()), mesh.indices.size() * 4));

        // What kdrt_saved_tree_read_info() reads back.
        kdrt_saved_tree_info info;
        REQUIRE(kdrt_saved_tree_read_info(first.data(), first.size(), &info) == KDRT_SUCCESS);
        kdrt_tree_stats s;
        kt::TreePtr tree = kt::build(mesh, 4, builder);
        kdrt_tree_get_stats(tree.get(), &s);
        CHECK(info.version == KDRT_SAVED_TREE_VERSION);
        CHECK(info.size == first.size());
        CHECK(info.meshes == 1);
        CHECK(info.mesh_triangles == view.triangle_count);
        CHECK(info.options.builder == builder.builder);
        CHECK(info.options.quality == builder.quality);
        CHECK(info.options.max_leaf_size == 4);
        CHECK(info.stats.nodes == s.nodes);
        CHECK(info.stats.leaves == s.leaves);
        CHECK(info.stats.blocks == s.blocks);
        CHECK(info.stats.triangle_refs == s.triangle_refs);
        CHECK(info.stats.max_depth == s.max_depth);
        CHECK(info.stats.triangles == s.triangles);
        const kdrt_aabb bounds = kdrt_tree_bounds(tree.get());
        CHECK(std::memcmp(&info.bounds, &bounds, sizeof bounds) == 0);
        // Saved size within 5% of what the tree holds in memory.
        CHECK(double(first.size()) <= 1.05 * double(s.bytes));
        CHECK(double(first.size()) >= 0.95 * double(s.bytes));
    }
    // A strided view of the same positions is the same mesh to the fingerprint.
    std::vector<float> strided;
    for (size_t v = 0; v < mesh.positions.size() / 3; ++v)
        strided.insert(strided.end(), {mesh.positions[3 * v], mesh.positions[3 * v + 1], mesh.positions[3 * v + 2], -1.0f});
    kdrt_triangles view4 = view;
    view4.positions = strided.data(), view4.position_stride = 16;
    kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[2]);
    kt::TreePtr loaded = load(save(tree.get()), view4);
    check_same_answers(tree.get(), loaded.get(), 2000, 9);
}

TEST_CASE("save: empty trees, soups, and trees whose every triangle is left out", "[save]") {
    const float degenerate[] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    kdrt_triangles empty{}, flat{};
    flat.positions = degenerate, flat.vertex_count = 6, flat.triangle_count = 2;
    for (const kdrt_triangles *mesh : {&empty, &flat})
        for (uint32_t leaf : {0u, 4u}) {
            kdrt_build_options o = kdrt_default_build_options();
            o.max_leaf_size = leaf;
            kdrt_tree *built = nullptr;
            REQUIRE(kdrt_tree_build(mesh, &o, &built, nullptr) == KDRT_SUCCESS);
            kt::TreePtr owner(built);
            const Bytes file = save(built);
            kt::TreePtr loaded = load(file, *mesh);
            check_same_answers(built, loaded.get(), 500, 3);
            CHECK(save(loaded.get()) == file);
            kdrt_ray ray = kt::ray_of(0.5f, 0.2f, -1, 0, 0, 1);
            kdrt_hit hit;
            CHECK(kdrt_intersect(loaded.get(), &ray, &hit) == 0);
        }
    // A soup is not its indexed mesh, though its triangles are the same.
    const Mesh indexed = kt::sphere(6, 12, 1.0), soup = kt::as_soup(indexed);
    const Bytes file = save(kt::build(soup, 4, kt::kBuilders[1]).get());
    load(file, soup.view());
    CHECK(load_result(file, indexed.view()) == KDRT_ERROR_MESH_MISMATCH);
}

TEST_CASE("save: in place, the tree borrows the bytes and answers the same", "[save]") {
    const Mesh mesh = kt::grid(30, 30, 5);
    kt::TreePtr tree = kt::build(mesh, 4, kt::kBuilders[2]);
    const Bytes file = save(tree.get());
    unsigned char *aligned = static_cast<unsigned char *>(std::malloc(file.size() + 128));
    REQUIRE(aligned != nullptr);
    unsigned char *at64 = aligned + (64 - reinterpret_cast<uintptr_t>(aligned) % 64) % 64;
    for (unsigned char *at : {at64, at64 + 4}) {  // aligned: borrowed; else copied
        std::memcpy(at, file.data(), file.size());
        Counter counter;
        kdrt_build_options o = kdrt_default_build_options();
        o.flags = KDRT_LOAD_IN_PLACE, o.allocator = counter.hooks();
        kdrt_tree *loaded = nullptr;
        const kdrt_triangles view = mesh.view();
        REQUIRE(kdrt_tree_load(at, file.size(), &view, &o, &loaded, nullptr) == KDRT_SUCCESS);
        kdrt_tree_stats s;
        kdrt_tree_get_stats(loaded, &s);
        if (at == at64) {
            CHECK(counter.calls == 1);  // the tree's own struct only
            CHECK(s.bytes < 1024);
        } else {
            CHECK(counter.calls > 1);
        }
        check_same_answers(tree.get(), loaded, 5000, 11);
        kdrt_tree_free(loaded);
        CHECK(counter.live == 0);
    }
    std::free(aligned);
}

TEST_CASE("save: each allocation of a load failing in turn: out of memory, nothing left", "[save]") {
    Small s;
    for (uint32_t flags : {0u, uint32_t(KDRT_LOAD_IN_PLACE)}) {
        // In place needs 64-byte aligned bytes: a copy there.
        unsigned char *raw = static_cast<unsigned char *>(std::malloc(s.file.size() + 64));
        unsigned char *at = raw + (64 - reinterpret_cast<uintptr_t>(raw) % 64) % 64;
        std::memcpy(at, s.file.data(), s.file.size());
        size_t successes = 0;
        for (size_t k = 1; successes == 0 && k < 100; ++k) {
            Counter counter;
            counter.fail_at = k;
            kdrt_build_options o = kdrt_default_build_options();
            o.allocator = counter.hooks(), o.flags = flags;
            kdrt_tree *tree = nullptr;
            const kdrt_result r = kdrt_tree_load(at, s.file.size(), &s.view, &o, &tree, nullptr);
            INFO("allocation " << k << ": " << kdrt_result_string(r));
            if (counter.calls < k) {
                CHECK(r == KDRT_SUCCESS);  // no allocation left to fail
                ++successes;
            } else {
                CHECK(r == KDRT_ERROR_OUT_OF_MEMORY);
                CHECK(tree == nullptr);
            }
            // Memory bounded by the file's size (and a tree's struct).
            CHECK(counter.peak_bytes <= s.file.size() + 1024);
            kdrt_tree_free(tree);
            CHECK(counter.live == 0);
            CHECK(counter.wrong_user == 0);
        }
        CHECK(successes == 1);
        std::free(raw);
    }
}

TEST_CASE("save: write failures and NULL arguments", "[save]") {
    Small s;
    struct Failing {
        size_t calls = 0, fail_at = 0;
        Bytes out;
    };
    auto failing = [](void *user, const void *bytes, size_t size) -> int {
        Failing *f = static_cast<Failing *>(user);
        if (++f->calls == f->fail_at) return 0;
        append(&f->out, bytes, size);
        return 1;
    };
    size_t calls = 0;
    {
        Failing all;
        REQUIRE(kdrt_tree_save(s.tree.get(), failing, &all) == KDRT_SUCCESS);
        CHECK(all.out == s.file);
        calls = all.calls;
    }
    CHECK(calls >= 2);
    for (size_t k = 1; k <= calls; ++k) {
        Failing f;
        f.fail_at = k;
        CHECK(kdrt_tree_save(s.tree.get(), failing, &f) == KDRT_ERROR_WRITE_FAILED);
        CHECK(f.calls == k);  // nothing written after the failure
    }
    CHECK(kdrt_tree_save(nullptr, append, &calls) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_save(s.tree.get(), nullptr, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_saved_size(nullptr) == 0);
    kdrt_tree *tree = nullptr;
    CHECK(kdrt_tree_load(nullptr, 10, &s.view, nullptr, &tree, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_load(s.file.data(), s.file.size(), nullptr, nullptr, &tree, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_tree_load(s.file.data(), s.file.size(), &s.view, nullptr, nullptr, nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    kdrt_build_options bad = kdrt_default_build_options();
    bad.flags = 1u << 20;
    CHECK(kdrt_tree_load(s.file.data(), s.file.size(), &s.view, &bad, &tree, nullptr) == KDRT_ERROR_INVALID_OPTION);
    CHECK(tree == nullptr);
    kdrt_saved_tree_info info;
    CHECK(kdrt_saved_tree_read_info(s.file.data(), s.file.size(), nullptr) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_saved_tree_read_info(nullptr, 0, &info) == KDRT_ERROR_NULL_ARGUMENT);
}

TEST_CASE("save: another mesh, version, byte order, size, or a changed byte: refused, each with its code", "[save]") {
    Small s;
    load(s.file, s.view);

    SECTION("another mesh") {
        Mesh moved = s.mesh;
        moved.positions[7] = std::nextafter(moved.positions[7], 10.0f);
        CHECK(load_result(s.file, moved.view()) == KDRT_ERROR_MESH_MISMATCH);
        Mesh reindexed = s.mesh;
        std::swap(reindexed.indices[3], reindexed.indices[4]);
        CHECK(load_result(s.file, reindexed.view()) == KDRT_ERROR_MESH_MISMATCH);
        kdrt_triangles fewer = s.view;
        fewer.triangle_count -= 1;
        CHECK(load_result(s.file, fewer) == KDRT_ERROR_MESH_MISMATCH);
        kdrt_triangles more_vertices = s.view;
        more_vertices.vertex_count -= 1;
        CHECK(load_result(s.file, more_vertices) == KDRT_ERROR_MESH_MISMATCH);
        CHECK(load_result(s.file, kt::sphere(10, 20, 1.5).view()) == KDRT_ERROR_MESH_MISMATCH);
        kdrt_triangles bad_stride = s.view;
        bad_stride.position_stride = 4;
        CHECK(load_result(s.file, bad_stride) == KDRT_ERROR_INVALID_STRIDE);
    }
    SECTION("another version, another byte order, not a saved tree") {
        Bytes f = s.file;
        put32(&f[12], KDRT_SAVED_TREE_VERSION + 1);
        CHECK(load_result(f, s.view) == KDRT_ERROR_FILE_VERSION);
        reseal(f);  // a well-formed file of a version to come
        CHECK(load_result(f, s.view) == KDRT_ERROR_FILE_VERSION);
        f = s.file;
        f[8] = 1, f[9] = 2, f[10] = 3, f[11] = 4;  // a big-endian writer's mark
        CHECK(load_result(f, s.view) == KDRT_ERROR_FILE_BYTE_ORDER);
        f = s.file;
        f[0] = 'k';
        CHECK(load_result(f, s.view) == KDRT_ERROR_NOT_A_SAVED_TREE);
        const Bytes text(s.file.size(), 'x');
        CHECK(load_result(text, s.view) == KDRT_ERROR_NOT_A_SAVED_TREE);
        kdrt_saved_tree_info info;
        CHECK(kdrt_saved_tree_read_info(text.data(), text.size(), &info) == KDRT_ERROR_NOT_A_SAVED_TREE);
    }
    SECTION("every truncation, and bytes after the end") {
        for (size_t n = 0; n < s.file.size(); ++n) {
            const Bytes cut(s.file.begin(), s.file.begin() + ptrdiff_t(n));
            const kdrt_result r = load_result(cut, s.view);
            if (r != KDRT_ERROR_FILE_SIZE) {
                FAIL_CHECK("the first " << n << " bytes: " << kdrt_result_string(r));
                break;
            }
        }
        for (size_t extra : {1, 7, 64}) {
            Bytes longer = s.file;
            longer.insert(longer.end(), extra, 0);
            CHECK(load_result(longer, s.view) == KDRT_ERROR_FILE_SIZE);
        }
    }
    SECTION("every single-byte change of the header, and of every byte of the file") {
        std::map<kdrt_result, size_t> codes;
        for (size_t i = 0; i < s.file.size(); ++i)
            for (unsigned char x : {0x01, 0x80, 0xFF}) {
                if (i >= kHeader && x != 0x01) continue;  // the sections: one change a byte
                Bytes f = s.file;
                f[i] ^= x;
                const kdrt_result r = load_result(f, s.view);
                ++codes[r];
                kdrt_result expected = KDRT_ERROR_FILE_CORRUPT;
                if (i < 8) expected = KDRT_ERROR_NOT_A_SAVED_TREE;
                else if (i >= 12 && i < 16) expected = KDRT_ERROR_FILE_VERSION;
                if (r != expected) {
                    FAIL_CHECK("byte " << i << " ^ " << int(x) << ": " << kdrt_result_string(r));
                    return;
                }
            }
        CHECK(codes.size() == 3);
    }
}

TEST_CASE("save: forged files, their checksums made again: every field that no save writes is refused", "[save]") {
    Small s;
    const Layout l = layout(s.file);
    REQUIRE(l.nodes > 8);
    // The first inner node, and the first leaf with a padded block.
    uint32_t inner = 0, leaf = 0, padded_block = 0, leaf_index = 0, padded_leaf = 0;
    bool found = false;
    for (uint32_t i = 0, b = 0, leaves = 0; i < l.nodes; ++i) {
        const uint32_t bits = get32(&s.file[l.nodes_at + 8 * i + 4]);
        if ((bits & 3) != 3) continue;
        const uint32_t count = bits >> 2;
        if (!found && count % 8 != 0) found = true, padded_leaf = i, padded_block = b + (count - 1) / 8, leaf_index = leaves;
        b += (count + 7) / 8, ++leaves;
    }
    REQUIRE(found);
    (void)leaf;
    REQUIRE((get32(&s.file[l.nodes_at + 4]) & 3) != 3);  // the root is split
    auto forged = [&](const char *what, const std::function<void(Bytes &)> &change) {
        Bytes f = s.file;
        change(f);
        reseal(f);
        INFO(what);
        CHECK(load_result(f, s.view) == KDRT_ERROR_FILE_CORRUPT);
    };
    auto node_word = [&](uint32_t node, int word) { return l.nodes_at + 8 * size_t(node) + 4 * size_t(word); };
    const uint32_t root_bits = get32(&s.file[node_word(inner, 1)]);
    forged("above child past the last node", [&](Bytes &f) { put32(&f[node_word(0, 1)], (l.nodes << 2) | (root_bits & 3)); });
    forged("above child before its parent: a cycle", [&](Bytes &f) { put32(&f[node_word(0, 1)], (0u << 2) | (root_bits & 3)); });
    forged("above child the below one", [&](Bytes &f) { put32(&f[node_word(0, 1)], (1u << 2) | (root_bits & 3)); });
    forged("above child one node off", [&](Bytes &f) { put32(&f[node_word(0, 1)], root_bits + 4); });
    forged("a NaN split", [&](Bytes &f) { put32(&f[node_word(0, 0)], 0x7FC00000u); });
    forged("a split outside the node's box", [&](Bytes &f) { put32(&f[node_word(0, 0)], 0x4B000000u); });  // 2^23
    forged("the root a leaf", [&](Bytes &f) { put32(&f[node_word(0, 1)], (4u << 2) | 3u); });
    forged("a leaf's count one more", [&](Bytes &f) { put32(&f[node_word(padded_leaf, 1)], get32(&f[node_word(padded_leaf, 1)]) + 4); });
    forged("a leaf's first block off", [&](Bytes &f) { put32(&f[node_word(padded_leaf, 0)], get32(&f[node_word(padded_leaf, 0)]) + 1); });
    forged("a lane's triangle past the mesh", [&](Bytes &f) { put32(&f[l.blocks_at + 320 * size_t(padded_block) + 288], s.view.triangle_count); });
    forged("a padding lane's triangle", [&](Bytes &f) { f[l.blocks_at + 320 * size_t(padded_block) + 288 + 28] ^= 1; });
    forged("a padding lane's corner", [&](Bytes &f) { f[l.blocks_at + 320 * size_t(padded_block) + 28] ^= 1; });
    forged("a block's first reference", [&](Bytes &f) { put32(&f[l.refs_at + 4 * size_t(padded_block)], 12345); });
    forged("a cell's box", [&](Bytes &f) { f[l.cells_at + 48 * size_t(leaf_index) + 12] ^= 1; });
    forged("a rope past the last node", [&](Bytes &f) { put32(&f[l.cells_at + 48 * size_t(leaf_index) + 24 + 8], l.nodes); });
    forged("a leaf's cell number", [&](Bytes &f) { put32(&f[l.map_at + 4 * size_t(padded_leaf)], leaf_index + 1); });
    forged("an inner node's cell number", [&](Bytes &f) { put32(&f[l.map_at], 0); });
    forged("a node count one less", [&](Bytes &f) { put32(&f[80], l.nodes - 1); });
    forged("a leaf count one less", [&](Bytes &f) { put32(&f[84], l.leaves - 1); });
    forged("the references one more", [&](Bytes &f) { put64(&f[96], get64(&f[96]) + 1); });
    forged("the deepest leaf deeper", [&](Bytes &f) { put32(&f[104], get32(&f[104]) + 1); });
    forged("the depth limit", [&](Bytes &f) { put32(&f[132], get32(&f[132]) + 1); });
    forged("the depth limit below the tree's depth", [&](Bytes &f) { put32(&f[128], 1), put32(&f[132], 1); });
    forged("an unknown builder", [&](Bytes &f) { put32(&f[112], 9); });
    forged("a NaN cost", [&](Bytes &f) { put32(&f[140], 0x7FC00000u); });
    forged("a kernel flag", [&](Bytes &f) { put32(&f[136], KDRT_BUILD_SCALAR_KERNEL); });
    forged("infinite bounds", [&](Bytes &f) { put32(&f[164], 0xFF800000u); });
    forged("a reserved word", [&](Bytes &f) { put32(&f[220], 1); });
    forged("a section's size", [&](Bytes &f) { put64(&f[40], get64(&f[40]) + 8); });
    // A forged file with consistent checksums but a changed corner passes every structural test
    // and loads (its answers are its own): the checksum is for damage, not for forgery.
    Bytes corner = s.file;
    corner[l.blocks_at] ^= 1;
    reseal(corner);
    kdrt_tree *t = nullptr;
    CHECK(try_load(corner, s.view, &t) == KDRT_SUCCESS);
    kdrt_tree_free(t);
    // A record that no longer names the mesh: the records' hash first, then the mesh.
    Bytes record = s.file;
    record[l.meshes_at + 16] ^= 1;
    CHECK(load_result(record, s.view) == KDRT_ERROR_FILE_CORRUPT);
    reseal(record);
    CHECK(load_result(record, s.view) == KDRT_ERROR_MESH_MISMATCH);
}

TEST_CASE("save: a deep tree's depth is checked against its limit and KDRT_MAX_DEPTH", "[save]") {
    // Slivers in a fan make the median builder go deep.
    const Mesh mesh = kt::random_soup(3000, 21);
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = KDRT_BUILDER_MEDIAN, o.max_leaf_size = 1, o.max_depth = KDRT_MAX_DEPTH;
    kdrt_tree *built = nullptr;
    const kdrt_triangles view = mesh.view();
    REQUIRE(kdrt_tree_build(&view, &o, &built, nullptr) == KDRT_SUCCESS);
    kt::TreePtr owner(built);
    Bytes file = save(built);
    kt::TreePtr loaded = load(file, mesh.view());
    check_same_answers(built, loaded.get(), 2000, 4);
    kdrt_tree_stats s;
    kdrt_tree_get_stats(built, &s);
    REQUIRE(s.max_depth > 4);
    // A limit the tree passes, the deepest leaf recorded as within it: the walk finds it deeper.
    put32(&file[128], s.max_depth - 1), put32(&file[132], s.max_depth - 1), put32(&file[104], s.max_depth - 1);
    reseal(file);
    CHECK(load_result(file, mesh.view()) == KDRT_ERROR_FILE_CORRUPT);
}

TEST_CASE("save: a scene's mesh tree, saved and loaded into a scene without a build", "[save]") {
    const Mesh a = kt::sphere(10, 20, 1.0), b = kt::translated(kt::grid(12, 12, 3), 2, 0, 0), c = kt::translated(kt::sphere(6, 12, 0.5), -2, 1, 0);
    const Mesh small = kt::sphere(8, 16, 0.3);  // the instanced tree borrows its buffers
    kt::TreePtr instanced = kt::build(small, 4);
    const float shift[12] = {1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1, 0};
    const kdrt_triangles va = a.view(), vb = b.view(), vc = c.view();
    std::vector<kdrt_geometry> entries = {kdrt_mesh_geometry(5, &va), kdrt_mesh_geometry(2, &vb),
                                          kdrt_instance_geometry(7, instanced.get(), shift), kdrt_mesh_geometry(9, &vc)};
    entries[3].mask = 0x0F;
    kdrt_build_options o = kdrt_default_build_options();
    o.intersector = KDRT_INTERSECTOR_FAST, o.max_leaf_size = 2;
    kdrt_scene *built = nullptr;
    REQUIRE(kdrt_scene_build(entries.data(), uint32_t(entries.size()), &o, &built, nullptr) == KDRT_SUCCESS);
    Bytes file;
    REQUIRE(kdrt_scene_save_meshes(built, append, &file) == KDRT_SUCCESS);
    CHECK(file.size() == kdrt_scene_saved_size(built));
    kdrt_saved_tree_info info;
    REQUIRE(kdrt_saved_tree_read_info(file.data(), file.size(), &info) == KDRT_SUCCESS);
    CHECK(info.meshes == 3);
    CHECK(info.options.intersector == KDRT_INTERSECTOR_FAST);

    // The same entries in another order, defaults for options: the file's shape and intersector.
    std::vector<kdrt_geometry> shuffled = {entries[3], entries[2], entries[0], entries[1]};
    Counter counter;
    kdrt_build_options load_options = kdrt_default_build_options();
    load_options.allocator = counter.hooks();
    kdrt_scene *loaded = nullptr;
    kdrt_build_report report;
    REQUIRE(kdrt_scene_load(shuffled.data(), 4, file.data(), file.size(), &load_options, &loaded, &report) == KDRT_SUCCESS);
    Bytes again;
    REQUIRE(kdrt_scene_save_meshes(loaded, append, &again) == KDRT_SUCCESS);
    CHECK(again == file);
    const kdrt_aabb box = kdrt_scene_bounds(built), loaded_box = kdrt_scene_bounds(loaded);
    CHECK(std::memcmp(&box, &loaded_box, sizeof box) == 0);
    const std::vector<kdrt_ray> rays = kt::random_rays(box, 20000, 17);
    size_t bad = 0;
    kdrt_query masked = kdrt_default_query();
    masked.mask = 0xF0;
    for (const kdrt_ray &ray : rays) {
        kdrt_hit x, y;
        const int hx = kdrt_scene_intersect(built, &ray, nullptr, &x), hy = kdrt_scene_intersect(loaded, &ray, nullptr, &y);
        bad += hx != hy || !same_bits(x, y);
        bad += kdrt_scene_occluded(built, &ray, &masked) != kdrt_scene_occluded(loaded, &ray, &masked);
        if (hx) {
            kdrt_ray sx, sy;
            const float dir[3] = {ray.dir[1], -ray.dir[0], ray.dir[2]};
            kdrt_scene_spawn_ray(built, &x, dir, &sx), kdrt_scene_spawn_ray(loaded, &y, dir, &sy);
            bad += std::memcmp(&sx, &sy, sizeof sx) != 0;
            kdrt_scene_intersect(built, &sx, nullptr, &x), kdrt_scene_intersect(loaded, &sy, nullptr, &y);
            bad += !same_bits(x, y);
        }
    }
    CHECK(bad == 0);
    // Later commits build, with the file's options: a mesh attached, then detached again.
    const Mesh d = kt::translated(kt::sphere(5, 10, 0.4), 0, -2, 0);
    const kdrt_triangles vd = d.view();
    const kdrt_geometry extra = kdrt_mesh_geometry(11, &vd);
    REQUIRE(kdrt_scene_attach(loaded, &extra) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_commit(loaded) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_detach(loaded, 11) == KDRT_SUCCESS);
    REQUIRE(kdrt_scene_commit(loaded) == KDRT_SUCCESS);
    again.clear();
    REQUIRE(kdrt_scene_save_meshes(loaded, append, &again) == KDRT_SUCCESS);
    CHECK(again == file);  // rebuilt as it was built: the same tree
    kdrt_scene_free(loaded);
    CHECK(counter.live == 0);

    // Other meshes: named in the report.
    auto refused = [&](std::vector<kdrt_geometry> e, kdrt_result expected, uint32_t geometry) {
        kdrt_scene *s = nullptr;
        kdrt_build_report r;
        CHECK(kdrt_scene_load(e.data(), uint32_t(e.size()), file.data(), file.size(), nullptr, &s, &r) == expected);
        CHECK(s == nullptr);
        CHECK(r.invalid_geometry == geometry);
    };
    std::vector<kdrt_geometry> other = entries;
    other[3].id = 10;  // mesh 9 under another ID
    refused(other, KDRT_ERROR_MESH_MISMATCH, 10);
    other = entries;
    other[0].mesh = vc;  // ID 5 with mesh c
    refused(other, KDRT_ERROR_MESH_MISMATCH, 5);
    other = {entries[0], entries[1]};
    refused(other, KDRT_ERROR_MESH_MISMATCH, KDRT_INVALID_ID);
    other = entries;
    other.push_back(kdrt_mesh_geometry(1, &vd));
    refused(other, KDRT_ERROR_MESH_MISMATCH, KDRT_INVALID_ID);
    Bytes cut(file.begin(), file.end() - 1);
    kdrt_scene *s = nullptr;
    CHECK(kdrt_scene_load(entries.data(), 4, cut.data(), cut.size(), nullptr, &s, nullptr) == KDRT_ERROR_FILE_SIZE);
    // A one-tree file is a scene file of one mesh with ID 0, and a scene's is no tree's file.
    CHECK(load_result(file, a.view()) == KDRT_ERROR_MESH_MISMATCH);
    const Bytes tree_file = save(kt::build(a, 4).get());
    const kdrt_geometry only = kdrt_mesh_geometry(0, &va);
    REQUIRE(kdrt_scene_load(&only, 1, tree_file.data(), tree_file.size(), nullptr, &s, nullptr) == KDRT_SUCCESS);
    kdrt_scene_free(s);
    kdrt_scene_free(built);

    // A scene without meshes saves a file of none, which only such a scene loads.
    const kdrt_geometry just_instance = entries[2];
    REQUIRE(kdrt_scene_build(&just_instance, 1, nullptr, &built, nullptr) == KDRT_SUCCESS);
    Bytes none;
    REQUIRE(kdrt_scene_save_meshes(built, append, &none) == KDRT_SUCCESS);
    CHECK(none.size() == kHeader);
    CHECK(none.size() == kdrt_scene_saved_size(built));
    REQUIRE(kdrt_scene_load(&just_instance, 1, none.data(), none.size(), nullptr, &s, nullptr) == KDRT_SUCCESS);
    const kdrt_ray down = kt::ray_of(0, 3, 5, 0, 0, -1);
    kdrt_hit x, y;
    CHECK(kdrt_scene_intersect(built, &down, nullptr, &x) == 1);
    CHECK(kdrt_scene_intersect(s, &down, nullptr, &y) == 1);
    CHECK(same_bits(x, y));
    kdrt_scene_free(s);
    kdrt_scene_free(built);
    CHECK(kdrt_scene_load(entries.data(), 4, none.data(), none.size(), nullptr, &s, nullptr) == KDRT_ERROR_MESH_MISMATCH);
    CHECK(load_result(none, a.view()) == KDRT_ERROR_MESH_MISMATCH);
    CHECK(kdrt_scene_save_meshes(nullptr, append, &none) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(kdrt_scene_saved_size(nullptr) == 0);
}

TEST_CASE("save: the shared meshes, saved and loaded", "[save]") {
    const std::string dir = kt::shared_mesh_dir();
    if (dir.empty()) {
        kt::skip_test("no shared mesh folder (KDRT_MESH_DIR)");
        return;
    }
    for (const char *name : {"/common/stanford-bunny.obj", "/common/fandisk.obj", "/seed/unit_sphere_n.off"}) {
        Mesh mesh;
        std::string error;
        if (!common::load_mesh(dir + name, mesh, error)) continue;
        INFO(name);
        for (kdrt_build_quality q : {KDRT_BUILD_QUALITY_FAST, KDRT_BUILD_QUALITY_MEDIUM}) {
            kdrt_build_options o = kdrt_default_build_options();
            o.quality = q;
            kdrt_tree *built = nullptr;
            const kdrt_triangles view = mesh.view();
            REQUIRE(kdrt_tree_build(&view, &o, &built, nullptr) == KDRT_SUCCESS);
            kt::TreePtr owner(built);
            const Bytes file = save(built);
            kdrt_tree_stats s;
            kdrt_tree_get_stats(built, &s);
            CHECK(double(file.size()) <= 1.05 * double(s.bytes));
            CHECK(double(file.size()) >= 0.95 * double(s.bytes));
            kt::TreePtr loaded = load(file, mesh.view());
            check_same_answers(built, loaded.get(), kt::reference_ray_count() / 10, 5);
        }
    }
}
