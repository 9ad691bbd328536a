// Every error path of kdrt_tree_build and the queries, and a counting allocator showing that
// builds free what they allocate (on success, on failure, and when any one allocation fails) and
// that queries allocate nothing.
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

static_assert(sizeof(kdrt_builder) == sizeof(int), "the builder test stores an int");

namespace {

using kt::kLeafSizes;
using kt::ray_of;
using kt::same_hit;

const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();

// A pointer that is not NULL and not a tree: a failed build must overwrite it with NULL.
kdrt_tree *poison() {
    static int dummy;
    return reinterpret_cast<kdrt_tree *>(&dummy);
}

// Builds, returning the result; *tree gets the tree (or NULL).
kdrt_result try_build(const kdrt_triangles &mesh, const kdrt_build_options &options, kdrt_tree **tree,
                      kdrt_build_report *report = nullptr) {
    *tree = poison();
    return kdrt_tree_build(&mesh, &options, tree, report);
}

kdrt_build_options options_with_leaf(uint32_t leaf) {
    kdrt_build_options o = kdrt_default_build_options();
    o.max_leaf_size = leaf;
    return o;
}

// ---- the counting allocator ----

struct CountingAllocator {
    size_t calls = 0;        // alloc calls, failed ones included
    size_t fail_at = 0;      // 1-based alloc call to fail; 0: never
    size_t live_blocks = 0, live_bytes = 0, frees = 0;
    size_t bad_frees = 0;    // frees of pointers this allocator did not hand out
    std::map<void *, size_t> blocks;

    kdrt_allocator hooks() {
        kdrt_allocator a;
        a.alloc = &CountingAllocator::alloc_cb;
        a.free = &CountingAllocator::free_cb;
        a.user = this;
        return a;
    }
    void reset_counts() { calls = 0, fail_at = 0, frees = 0; }

    static size_t wrong_user;  // callbacks that did not receive the expected user pointer
    static CountingAllocator *expected;

    static CountingAllocator *self(void *user) {
        if (user != expected) ++wrong_user;
        return expected;
    }
    static void *alloc_cb(void *user, size_t size) {
        CountingAllocator *c = self(user);
        if (++c->calls == c->fail_at) return nullptr;
        void *p = std::malloc(size);
        if (!p) return nullptr;
        c->blocks[p] = size;
        ++c->live_blocks;
        c->live_bytes += size;
        return p;
    }
    static void free_cb(void *user, void *ptr) {
        CountingAllocator *c = self(user);
        ++c->frees;
        auto it = c->blocks.find(ptr);
        if (it == c->blocks.end()) {
            ++c->bad_frees;  // never hand it to free(): it is not ours
            return;
        }
        --c->live_blocks;
        c->live_bytes -= it->second;
        c->blocks.erase(it);
        std::free(ptr);
    }
};
size_t CountingAllocator::wrong_user = 0;
CountingAllocator *CountingAllocator::expected = nullptr;

// Makes `counter` the one the callbacks expect for the scope.
struct UseCounter {
    explicit UseCounter(CountingAllocator &c) {
        CountingAllocator::expected = &c;
        CountingAllocator::wrong_user = 0;
    }
    ~UseCounter() { CountingAllocator::expected = nullptr; }
};

}  // namespace

// ---------------------------------------------------------------------------------------------

TEST_CASE("errors: NULL arguments to the build", "[errors]") {
    const float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    kdrt_triangles m{};
    m.positions = v, m.vertex_count = 3, m.triangle_count = 1;
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_tree *tree = poison();
    kdrt_build_report report;

    report.invalid_triangle = 5, report.skipped_triangles = 5;
    CHECK(kdrt_tree_build(nullptr, &o, &tree, &report) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(tree == nullptr);
    CHECK(report.invalid_triangle == KDRT_INVALID_ID);
    CHECK(report.skipped_triangles == 0);

    report.invalid_triangle = 5;
    CHECK(kdrt_tree_build(&m, &o, nullptr, &report) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(report.invalid_triangle == KDRT_INVALID_ID);
    CHECK(kdrt_tree_build(&m, &o, nullptr, nullptr) == KDRT_ERROR_NULL_ARGUMENT);

    kdrt_triangles no_positions = m;
    no_positions.positions = nullptr;
    CHECK(try_build(no_positions, o, &tree) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(tree == nullptr);
    const uint32_t idx[] = {0, 1, 2};
    no_positions.indices = idx;
    CHECK(try_build(no_positions, o, &tree) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(tree == nullptr);

    // The same view is fine with its pointer, and with NULL options (defaults).
    REQUIRE(try_build(m, o, &tree) == KDRT_SUCCESS);
    REQUIRE(tree != nullptr);
    kdrt_tree_free(tree);
    tree = poison();
    REQUIRE(kdrt_tree_build(&m, nullptr, &tree, nullptr) == KDRT_SUCCESS);
    REQUIRE(tree != nullptr);
    kdrt_tree_free(tree);
    kdrt_tree_free(nullptr);  // fine
}

TEST_CASE("errors: strides 1 to 11 are invalid, 0 and 12 are not", "[errors]") {
    const float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0};  // 48 bytes: enough for stride 16 as well
    kdrt_triangles m{};
    m.positions = v, m.vertex_count = 3, m.triangle_count = 1;
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_tree *tree;
    for (size_t stride = 1; stride < 12; ++stride) {
        INFO("stride " << stride);
        m.position_stride = stride;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_STRIDE);
        CHECK(tree == nullptr);
    }
    m.triangle_count = 0;  // checked even when there is nothing to read
    m.position_stride = 4;
    CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_STRIDE);
    m.triangle_count = 1;
    for (size_t stride : {size_t(0), size_t(12)}) {
        m.position_stride = stride;
        REQUIRE(try_build(m, o, &tree) == KDRT_SUCCESS);
        kdrt_ray r = ray_of(0.25f, 0.25f, 1, 0, 0, -1);
        kdrt_hit h;
        CHECK(kdrt_intersect(tree, &r, &h) == 1);
        CHECK(h.t == 1.0f);
        kdrt_tree_free(tree);
    }
}

TEST_CASE("errors: unknown builder or flag", "[errors]") {
    const float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    kdrt_triangles m{};
    m.positions = v, m.vertex_count = 3, m.triangle_count = 1;
    kdrt_tree *tree;
    for (int builder : {3, 4, 99, -1}) {
        INFO("builder " << builder);
        kdrt_build_options o = kdrt_default_build_options();
        int raw = builder;
        std::memcpy(&o.builder, &raw, sizeof raw);  // as a C caller could store any int
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_OPTION);
        CHECK(tree == nullptr);
    }
    for (uint32_t flags : {8u, 16u, 1u << 31, 0xFFFFFFFFu, 9u}) {
        INFO("flags " << flags);
        kdrt_build_options o = kdrt_default_build_options();
        o.flags = flags;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_OPTION);
        CHECK(tree == nullptr);
    }
    for (int quality : {4, -1, 1000}) {
        INFO("quality " << quality);
        kdrt_build_options o = kdrt_default_build_options();
        o.quality = kdrt_build_quality(quality);
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_OPTION);
        CHECK(tree == nullptr);
    }
    for (kdrt_builder builder : {KDRT_BUILDER_DEFAULT, KDRT_BUILDER_MEDIAN, KDRT_BUILDER_SAH})
        for (kdrt_build_quality quality : {KDRT_BUILD_QUALITY_DEFAULT, KDRT_BUILD_QUALITY_FAST, KDRT_BUILD_QUALITY_MEDIUM,
                                           KDRT_BUILD_QUALITY_HIGH}) {
            kdrt_build_options o = kdrt_default_build_options();
            o.builder = builder, o.quality = quality;
            o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
            REQUIRE(try_build(m, o, &tree) == KDRT_SUCCESS);
            kdrt_tree_free(tree);
        }
}

TEST_CASE("errors: SAH costs out of range", "[errors]") {
    const float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    kdrt_triangles m{};
    m.positions = v, m.vertex_count = 3, m.triangle_count = 1;
    kdrt_tree *tree;
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    for (float bad : {-1.0f, nan, inf}) {
        INFO("cost " << bad);
        kdrt_build_options o = kdrt_default_build_options();
        o.builder = KDRT_BUILDER_SAH;
        o.sah_traversal_cost = bad;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_OPTION);
        o = kdrt_default_build_options();
        o.sah_intersection_cost = bad;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_OPTION);
    }
    for (float bad : {-0.5f, 1.0f, 2.0f, nan}) {
        INFO("empty bonus " << bad);
        kdrt_build_options o = kdrt_default_build_options();
        o.sah_empty_bonus = bad;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_INVALID_OPTION);
        CHECK(tree == nullptr);
    }
}

TEST_CASE("errors: an allocator with only alloc or only free", "[errors][alloc]") {
    const float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    kdrt_triangles m{};
    m.positions = v, m.vertex_count = 3, m.triangle_count = 1;
    CountingAllocator counter;
    UseCounter use(counter);
    kdrt_tree *tree;

    kdrt_build_options o = kdrt_default_build_options();
    o.allocator = counter.hooks();
    o.allocator.free = nullptr;
    CHECK(try_build(m, o, &tree) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(tree == nullptr);
    o.allocator = counter.hooks();
    o.allocator.alloc = nullptr;
    CHECK(try_build(m, o, &tree) == KDRT_ERROR_NULL_ARGUMENT);
    CHECK(tree == nullptr);
    CHECK(counter.calls == 0);
    CHECK(counter.frees == 0);

    // user alone (no callbacks) means the default allocator.
    o.allocator = kdrt_allocator{nullptr, nullptr, &counter};
    REQUIRE(try_build(m, o, &tree) == KDRT_SUCCESS);
    kdrt_tree_free(tree);
    CHECK(counter.calls == 0);
}

TEST_CASE("errors: indices out of range name the first bad triangle", "[errors]") {
    common::Mesh grid = kt::grid(6, 5, 3);  // 60 triangles, 42 vertices
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_tree *tree;
    kdrt_build_report report;

    SECTION("indexed") {
        for (uint32_t bad_value : {42u, 43u, 1000u, 0xFFFFFFFFu})
            for (int corner = 0; corner < 3; ++corner) {
                INFO("index " << bad_value << " at corner " << corner);
                common::Mesh m = grid;
                m.indices[17 * 3 + corner] = bad_value;
                m.indices[40 * 3 + 1] = 99;
                kdrt_triangles view = m.view();
                CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
                CHECK(tree == nullptr);
                CHECK(report.invalid_triangle == 17);
                CHECK(report.skipped_triangles == 0);
            }
        // vertex_count one short of what the last vertex needs.
        kdrt_triangles view = grid.view();
        uint32_t max_index = 0, first_user = KDRT_INVALID_ID;
        for (uint32_t i : grid.indices) max_index = std::max(max_index, i);
        for (size_t i = 0; i < grid.indices.size() && first_user == KDRT_INVALID_ID; ++i)
            if (grid.indices[i] == max_index) first_user = uint32_t(i / 3);
        view.vertex_count = max_index;
        CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
        CHECK(report.invalid_triangle == first_user);
        view.vertex_count = max_index + 1;
        REQUIRE(try_build(view, o, &tree, &report) == KDRT_SUCCESS);
        CHECK(report.invalid_triangle == KDRT_INVALID_ID);
        kdrt_tree_free(tree);
    }
    SECTION("soup with vertex_count < 3 * triangle_count") {
        common::Mesh soup = kt::as_soup(grid);
        kdrt_triangles view = soup.view();
        for (uint32_t short_by = 1; short_by <= 7; ++short_by) {
            INFO("short by " << short_by);
            view.vertex_count = 3 * 60 - short_by;
            CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
            CHECK(tree == nullptr);
            CHECK(report.invalid_triangle == (3 * 60 - short_by) / 3);  // first triangle missing a vertex
        }
        view.vertex_count = 0;
        CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
        CHECK(report.invalid_triangle == 0);
    }
}

TEST_CASE("errors: NaN and infinite coordinates name the first bad triangle", "[errors]") {
    common::Mesh soup = kt::random_soup(30, 11);
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_tree *tree;
    kdrt_build_report report;
    for (float bad : {kNaN, kInf, -kInf})
        for (int corner = 0; corner < 3; ++corner)
            for (int axis = 0; axis < 3; ++axis) {
                INFO("value " << bad << " corner " << corner << " axis " << axis);
                common::Mesh m = soup;
                m.positions[(size_t(9) * 3 + corner) * 3 + axis] = bad;  // triangle 9
                m.positions[(size_t(20) * 3 + 2) * 3 + 0] = kNaN;        // and triangle 20
                kdrt_triangles view = m.view();
                CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_NON_FINITE_VERTEX);
                CHECK(tree == nullptr);
                CHECK(report.invalid_triangle == 9);
                for (uint32_t leaf : {0u, 1u}) {
                    kdrt_build_options ol = options_with_leaf(leaf);
                    CHECK(try_build(view, ol, &tree, &report) == KDRT_ERROR_NON_FINITE_VERTEX);
                    CHECK(report.invalid_triangle == 9);
                }
            }

    SECTION("indexed: the first triangle using the bad vertex, unused bad vertices are fine") {
        common::Mesh grid = kt::grid(7, 7, 5);
        uint32_t vertex = 27;
        uint32_t first_user = KDRT_INVALID_ID;
        for (size_t i = 0; i < grid.indices.size() && first_user == KDRT_INVALID_ID; ++i)
            if (grid.indices[i] == vertex) first_user = uint32_t(i / 3);
        REQUIRE(first_user != KDRT_INVALID_ID);
        REQUIRE(first_user > 0);
        common::Mesh m = grid;
        m.positions[size_t(vertex) * 3 + 2] = -kInf;
        kdrt_triangles view = m.view();
        CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_NON_FINITE_VERTEX);
        CHECK(report.invalid_triangle == first_user);

        // A NaN vertex no triangle refers to is never read as part of a triangle.
        common::Mesh extra = grid;
        extra.positions.insert(extra.positions.end(), {kNaN, kNaN, kNaN});
        view = extra.view();
        REQUIRE(try_build(view, o, &tree, &report) == KDRT_SUCCESS);
        CHECK(report.invalid_triangle == KDRT_INVALID_ID);
        kdrt_tree_stats stats;
        kdrt_tree_get_stats(tree, &stats);
        CHECK(stats.triangles == grid.triangle_count());
        kdrt_tree_free(tree);
    }
}

TEST_CASE("errors: KDRT_BUILD_SKIP_INVALID_TRIANGLES leaves bad triangles out and never hits them", "[errors]") {
    // An indexed soup: triangle i uses vertices 3i..3i+2. The position buffer holds a second copy
    // of every vertex past vertex_count, so a triangle whose index points there has real geometry
    // (if the library used it, it would be hit exactly where the original triangle is).
    common::Mesh base = kt::random_soup(400, 21);
    const uint32_t n = base.triangle_count(), nv = base.vertex_count();
    common::Mesh m = base;
    m.positions.insert(m.positions.end(), base.positions.begin(), base.positions.end());
    for (uint32_t i = 0; i < 3 * n; ++i) m.indices.push_back(i);
    std::set<uint32_t> bad;
    for (uint32_t t = 5; t < n; t += 7) {
        bad.insert(t);
        uint32_t corner = t % 3;
        switch ((t / 7) % 4) {
        case 0: m.indices[t * 3 + corner] = nv + t * 3 + corner; break;  // out of range, but readable
        case 1: m.positions[(size_t(t) * 3 + corner) * 3 + (t % 3)] = kNaN; break;
        case 2: m.positions[(size_t(t) * 3 + corner) * 3 + ((t + 1) % 3)] = kInf; break;
        default: m.positions[(size_t(t) * 3 + corner) * 3 + ((t + 2) % 3)] = -kInf; break;
        }
    }
    kdrt_triangles view = m.view();
    view.vertex_count = nv;  // the copies lie past the end

    // The good subset as its own mesh, with the map back to the original indices.
    common::Mesh good;
    good.name = "good subset";
    std::vector<uint32_t> good_to_orig;
    for (uint32_t t = 0; t < n; ++t)
        if (!bad.count(t)) {
            good_to_orig.push_back(t);
            good.positions.insert(good.positions.end(), base.positions.begin() + size_t(t) * 9,
                                  base.positions.begin() + size_t(t) * 9 + 9);
        }
    oracle::Oracle oracle(good);
    kt::TreePtr reference = kt::build(good, 0, KDRT_BUILDER_MEDIAN);

    // Rays: random ones, and one aimed at each bad triangle's centroid (the original geometry).
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(reference.get()), 20000, 77);
    for (uint32_t t : bad) {
        double p[3][3];
        base.corners(t, p);
        float c[3];
        for (int a = 0; a < 3; ++a) c[a] = float((p[0][a] + p[1][a] + p[2][a]) / 3);
        rays.push_back(ray_of(c[0] - 20, c[1] + 3, c[2] - 7, 20, -3, 7));
        rays.push_back(ray_of(c[0], c[1], c[2] + 30, 0, 0, -1));
    }
    std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
    std::vector<kdrt_hit> expected = kt::trace_all(reference.get(), rays);

    for (uint32_t leaf : kLeafSizes) {
        INFO("leaf size " << leaf);
        kdrt_build_options o = options_with_leaf(leaf);
        kdrt_tree *tree;
        kdrt_build_report report;
        CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);  // the first bad one is t = 5
        CHECK(report.invalid_triangle == 5);
        o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
        REQUIRE(try_build(view, o, &tree, &report) == KDRT_SUCCESS);
        kt::TreePtr owner(tree);
        CHECK(report.skipped_triangles == bad.size());
        CHECK(report.invalid_triangle == *bad.begin());
        kdrt_tree_stats stats;
        kdrt_tree_get_stats(tree, &stats);
        CHECK(stats.triangles == n - bad.size());

        std::vector<kdrt_hit> hits = kt::trace_all(tree, rays);
        oracle::Agreement tally;
        size_t bad_hits = 0, differ = 0, hits_count = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            kdrt_hit h = hits[i];
            if (h.triangle != KDRT_INVALID_ID) {
                ++hits_count;
                if (bad.count(h.triangle)) {
                    ++bad_hits;
                    continue;
                }
            }
            kdrt_hit mapped = expected[i];
            if (mapped.triangle != KDRT_INVALID_ID) mapped.triangle = good_to_orig[mapped.triangle];
            differ += !same_hit(h, mapped);
            // Oracle check on the good subset, in its numbering.
            kdrt_hit local = h;
            if (local.triangle != KDRT_INVALID_ID)
                local.triangle = uint32_t(std::lower_bound(good_to_orig.begin(), good_to_orig.end(), h.triangle) - good_to_orig.begin());
            oracle::check_hit(oracle, refs[i], rays[i], local, tally);
        }
        INFO(tally.first_wrong);
        CHECK(bad_hits == 0);
        CHECK(differ == 0);
        CHECK(tally.wrong == 0);
        CHECK(hits_count > rays.size() / 10);  // the good triangles are really hit
    }

    {  // every triangle bad: an empty tree
        kdrt_triangles all_bad = view;
        all_bad.vertex_count = 2;
        kdrt_build_options o = options_with_leaf(4);
        o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
        kdrt_tree *tree;
        kdrt_build_report report;
        REQUIRE(try_build(all_bad, o, &tree, &report) == KDRT_SUCCESS);
        kt::TreePtr owner(tree);
        CHECK(report.skipped_triangles == n);
        CHECK(report.invalid_triangle == 0);
        kdrt_tree_stats stats;
        kdrt_tree_get_stats(tree, &stats);
        CHECK(stats.triangles == 0);
        CHECK(stats.triangle_refs == 0);
        size_t hit_count = 0;
        for (const kdrt_ray &r : rays) {
            kdrt_hit h;
            h.triangle = 3;
            hit_count += kdrt_intersect(tree, &r, &h) + kdrt_occluded(tree, &r) + (h.triangle != KDRT_INVALID_ID);
        }
        CHECK(hit_count == 0);
    }
}

TEST_CASE("errors: counts too large to address give KDRT_ERROR_SIZE_OVERFLOW without reading", "[errors]") {
    // A 9-float buffer: reading past it would trip AddressSanitizer.
    float *v = new float[9]{0, 0, 0, 1, 0, 0, 0, 1, 0};
    kdrt_triangles m{};
    m.positions = v, m.vertex_count = 3;
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_tree *tree;
    kdrt_aabb box;
    for (uint32_t count : {KDRT_MAX_TRIANGLES + 1u, 0x80000000u, 0xFFFFFFFFu}) {
        INFO("triangle_count " << count);
        m.triangle_count = count;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_SIZE_OVERFLOW);
        CHECK(tree == nullptr);
        o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_SIZE_OVERFLOW);
        o.flags = 0;
        CHECK(kdrt_aabb_of_triangles(&m, &box, nullptr) == KDRT_ERROR_SIZE_OVERFLOW);
    }
    m.triangle_count = 1;
    const size_t max = std::numeric_limits<size_t>::max();
    for (size_t stride : {max / 3 + 1, max / 2, max}) {
        INFO("stride " << stride);
        m.position_stride = stride;
        CHECK(try_build(m, o, &tree) == KDRT_ERROR_SIZE_OVERFLOW);
        CHECK(tree == nullptr);
        CHECK(kdrt_aabb_of_triangles(&m, &box, nullptr) == KDRT_ERROR_SIZE_OVERFLOW);
    }
    // The same stride with one vertex does not overflow (the soup then lacks vertices); two do.
    m.position_stride = max / 2 + 1;
    m.vertex_count = 1;
    CHECK(try_build(m, o, &tree) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
    m.vertex_count = 2;
    CHECK(try_build(m, o, &tree) == KDRT_ERROR_SIZE_OVERFLOW);
    delete[] v;
}

TEST_CASE("errors: zero triangles is a valid empty tree", "[errors]") {
    kdrt_triangles m{};  // positions NULL, no indices, no triangles
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_aabb{{-1, -1, -1}, {1, 1, 1}}, 2000, 3);
    float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t idx[] = {0, 1, 2};
    for (int variant = 0; variant < 3; ++variant)
        for (uint32_t leaf : kLeafSizes) {
            INFO("variant " << variant << " leaf size " << leaf);
            kdrt_triangles view = m;
            if (variant >= 1) view.positions = v, view.vertex_count = 3;  // vertices, but no triangles
            if (variant == 2) view.indices = idx;
            kdrt_build_options o = options_with_leaf(leaf);
            kdrt_tree *tree;
            kdrt_build_report report;
            REQUIRE(try_build(view, o, &tree, &report) == KDRT_SUCCESS);
            REQUIRE(tree != nullptr);
            kt::TreePtr owner(tree);
            CHECK(report.invalid_triangle == KDRT_INVALID_ID);
            CHECK(report.skipped_triangles == 0);
            kdrt_tree_stats stats;
            kdrt_tree_get_stats(tree, &stats);
            CHECK(stats.triangles == 0);
            CHECK(stats.triangle_refs == 0);
            CHECK(stats.max_depth == 0);
            CHECK(stats.nodes <= 1);
            CHECK(stats.leaves <= stats.nodes);
            CHECK(stats.bytes > 0);
            kdrt_aabb b = kdrt_tree_bounds(tree);
            CHECK(b.min[0] > b.max[0]);
            size_t hits = 0;
            for (const kdrt_ray &r : rays) {
                kdrt_hit h;
                h.triangle = 0;
                hits += kdrt_intersect(tree, &r, &h) + kdrt_occluded(tree, &r) + (h.triangle != KDRT_INVALID_ID);
            }
            CHECK(hits == 0);
        }
}

// A tree whose triangles are all zero-area or skipped has a box but no references at all: rays
// through that box reach its one empty leaf (Clang's UBSan once caught the traversal forming a
// pointer into the missing reference array there).
TEST_CASE("errors: a tree of only degenerate or skipped triangles answers rays through its box", "[errors]") {
    const float v[] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, NAN};  // a collinear triangle, then a NaN corner
    const uint32_t collinear[] = {0, 1, 2}, with_nan[] = {0, 1, 3};
    const kdrt_ray rays[] = {{{-1, -1, -1}, 0, {1, 1, 1}, INFINITY, 0},  // through (0, 0, 0)
                             {{0.5f, 0, -1}, 0, {0, 0, 1}, INFINITY, 0},
                             {{-1, 0, 0}, 0, {1, 0, 0}, INFINITY, 0}};  // along the triangle
    for (const uint32_t *indices : {collinear, with_nan})
        for (const kt::Builder &builder : kt::kBuilders)
            for (uint32_t leaf : kLeafSizes) {
                INFO((indices == collinear ? "collinear" : "NaN corner, skipped") << ", builder " << builder.name
                                                                                 << ", leaf size " << leaf);
                kdrt_triangles m{};
                m.positions = v, m.vertex_count = 4, m.indices = indices, m.triangle_count = 1;
                kdrt_build_options o = options_with_leaf(leaf);
                builder.apply(o);
                o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
                kdrt_tree *tree;
                REQUIRE(try_build(m, o, &tree) == KDRT_SUCCESS);
                kt::TreePtr owner(tree);
                kdrt_tree_stats stats;
                kdrt_tree_get_stats(tree, &stats);
                CHECK(stats.triangle_refs == 0);
                for (const kdrt_ray &r : rays) {
                    kdrt_hit h;
                    CHECK(kdrt_intersect(tree, &r, &h) == 0);
                    CHECK(h.triangle == KDRT_INVALID_ID);
                    CHECK(kdrt_occluded(tree, &r) == 0);
                }
            }
}

TEST_CASE("errors: kdrt_result_string names every code distinctly", "[errors]") {
    std::set<std::string> seen;
    for (int code = KDRT_SUCCESS; code <= KDRT_ERROR_OUT_OF_MEMORY; ++code) {
        const char *s = kdrt_result_string(static_cast<kdrt_result>(code));
        REQUIRE(s != nullptr);
        CHECK(std::strlen(s) > 0);
        seen.insert(s);
    }
    CHECK(seen.size() == size_t(KDRT_ERROR_OUT_OF_MEMORY) + 1);
    // A value past the enum, as a C caller could pass.
    volatile int unknown = 7;
    unknown = unknown + 1;
    const char *s = kdrt_result_string(static_cast<kdrt_result>(unknown));
    REQUIRE(s != nullptr);
    CHECK(std::strlen(s) > 0);
    CHECK(seen.count(s) == 0);
}

TEST_CASE("errors: queries with NULL arguments", "[errors]") {
    common::Mesh mesh = kt::sphere(6, 8, 1.0);
    kt::TreePtr tree = kt::build(mesh, 2, KDRT_BUILDER_MEDIAN);
    kdrt_ray r = ray_of(0, 0, 0, 0.3f, 0.2f, 0.9f);
    kdrt_hit h;
    REQUIRE(kdrt_intersect(tree.get(), &r, &h) == 1);  // the baseline hits
    REQUIRE(kdrt_occluded(tree.get(), &r) == 1);

    h.triangle = 3;
    CHECK(kdrt_intersect(nullptr, &r, &h) == 0);
    CHECK(h.triangle == KDRT_INVALID_ID);
    h.triangle = 3;
    CHECK(kdrt_intersect(tree.get(), nullptr, &h) == 0);
    CHECK(h.triangle == KDRT_INVALID_ID);
    CHECK(kdrt_intersect(tree.get(), &r, nullptr) == 0);
    CHECK(kdrt_intersect(nullptr, nullptr, nullptr) == 0);
    CHECK(kdrt_occluded(nullptr, &r) == 0);
    CHECK(kdrt_occluded(tree.get(), nullptr) == 0);
    CHECK(kdrt_occluded(nullptr, nullptr) == 0);

    kdrt_tree_stats stats;
    std::memset(&stats, 0xAB, sizeof stats);
    kdrt_tree_get_stats(nullptr, &stats);
    CHECK(stats.triangles == 0);
    CHECK(stats.nodes == 0);
    kdrt_tree_get_stats(tree.get(), nullptr);  // no crash
    kdrt_aabb b = kdrt_tree_bounds(nullptr);
    CHECK(b.min[0] > b.max[0]);
}

TEST_CASE("errors: rays that can hit nothing miss", "[errors]") {
    // From inside a closed sphere every valid ray hits.
    common::Mesh mesh = kt::sphere(8, 12, 1.0);
    const kdrt_ray good = ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f);
    std::vector<std::pair<std::string, kdrt_ray>> bad;
    for (int a = 0; a < 3; ++a)
        for (float x : {kNaN, kInf, -kInf}) {
            kdrt_ray r = good;
            r.org[a] = x;
            bad.emplace_back("org[" + std::to_string(a) + "] = " + std::to_string(x), r);
            r = good;
            r.dir[a] = x;
            bad.emplace_back("dir[" + std::to_string(a) + "] = " + std::to_string(x), r);
        }
    bad.emplace_back("zero direction", ray_of(0.1f, 0.05f, -0.02f, 0, 0, 0));
    bad.emplace_back("-0 direction", ray_of(0.1f, 0.05f, -0.02f, -0.0f, 0.0f, -0.0f));
    bad.emplace_back("tmin > tmax", ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f, 2, 1));
    bad.emplace_back("tmin > tmax, both below the hit", ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f, 0.5f, 0.25f));
    bad.emplace_back("tmax NaN", ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f, 0, kNaN));
    bad.emplace_back("tmax -inf", ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f, 0, -kInf));
    bad.emplace_back("tmin +inf", ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f, kInf, kInf));
    bad.emplace_back("tmax negative", ray_of(0.1f, 0.05f, -0.02f, 0.3f, 0.5f, 0.8f, -5, -1));

    for (uint32_t leaf : kLeafSizes) {
        kt::TreePtr tree = kt::build(mesh, leaf, KDRT_BUILDER_MEDIAN);
        kdrt_hit h;
        REQUIRE(kdrt_intersect(tree.get(), &good, &h) == 1);
        REQUIRE(kdrt_occluded(tree.get(), &good) == 1);
        for (const auto &c : bad) {
            INFO("leaf size " << leaf << ": " << c.first);
            h.triangle = 1;
            CHECK(kdrt_intersect(tree.get(), &c.second, &h) == 0);
            CHECK(h.triangle == KDRT_INVALID_ID);
            CHECK(kdrt_occluded(tree.get(), &c.second) == 0);
        }
    }
}

// ---- the counting allocator ----

TEST_CASE("alloc: a build then kdrt_tree_free leaves nothing allocated, user reaches both callbacks", "[errors][alloc]") {
    common::Mesh mesh = kt::random_soup(700, 5);
    kdrt_triangles view = mesh.view();
    for (uint32_t leaf : kLeafSizes) {
        INFO("leaf size " << leaf);
        CountingAllocator counter;
        UseCounter use(counter);
        kdrt_build_options o = options_with_leaf(leaf);
        o.allocator = counter.hooks();
        kdrt_tree *tree;
        REQUIRE(try_build(view, o, &tree) == KDRT_SUCCESS);
        CHECK(counter.calls > 0);
        CHECK(counter.live_blocks > 0);
        kdrt_tree_stats stats;
        kdrt_tree_get_stats(tree, &stats);
        CHECK(stats.bytes <= counter.live_bytes);  // what it reports it owns, it holds
        kdrt_tree_free(tree);
        CHECK(counter.live_blocks == 0);
        CHECK(counter.live_bytes == 0);
        CHECK(counter.bad_frees == 0);
        CHECK(counter.frees == counter.calls);
        CHECK(CountingAllocator::wrong_user == 0);
    }
}

TEST_CASE("alloc: queries allocate nothing", "[errors][alloc]") {
    common::Mesh mesh = kt::sphere(16, 24, 2.0);
    kdrt_triangles view = mesh.view();
    CountingAllocator counter;
    UseCounter use(counter);
    kdrt_build_options o = options_with_leaf(4);
    o.allocator = counter.hooks();
    kdrt_tree *tree;
    REQUIRE(try_build(view, o, &tree) == KDRT_SUCCESS);
    const size_t calls = counter.calls, frees = counter.frees, live = counter.live_blocks;
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(tree), 20000, 9);
    rays.push_back(ray_of(kNaN, 0, 0, 1, 0, 0));
    rays.push_back(ray_of(0, 0, 0, 0, 0, 0));
    size_t hits = 0;
    for (const kdrt_ray &r : rays) {
        kdrt_hit h;
        hits += kdrt_intersect(tree, &r, &h);
        hits += kdrt_occluded(tree, &r);
    }
    CHECK(hits > rays.size() / 2);
    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree, &stats);
    (void)kdrt_tree_bounds(tree);
    CHECK(counter.calls == calls);
    CHECK(counter.frees == frees);
    CHECK(counter.live_blocks == live);
    kdrt_tree_free(tree);
    CHECK(counter.live_blocks == 0);
    CHECK(CountingAllocator::wrong_user == 0);
}

namespace {

// Fails each allocation of a build in turn. A successful build made `total` allocations; failing
// any of them must give KDRT_ERROR_OUT_OF_MEMORY (or `other` when the build fails anyway), a NULL
// tree and nothing left allocated. The build's two allocations before its last two (the cells
// and their map) trim the node and reference arrays to size, which the builder may skip when
// they fail (the tree keeps its larger arrays); then the build succeeds and the tree must answer
// exactly as a normally built one.
// Fails each allocation of a build in turn (the first `first` of them, if not 0).
void fail_each_allocation(const kdrt_triangles &view, kdrt_build_options o, kdrt_result expected_result,
                          kdrt_result other, const std::vector<kdrt_ray> &rays, size_t first = 0) {
    CountingAllocator counter;
    UseCounter use(counter);
    o.allocator = counter.hooks();
    kdrt_tree *tree;
    kdrt_build_report report;
    REQUIRE(try_build(view, o, &tree, &report) == expected_result);
    const size_t total = counter.calls;
    const uint32_t invalid = report.invalid_triangle;
    REQUIRE(total > 0);
    std::vector<kdrt_hit> reference;
    if (tree) {
        reference = kt::trace_all(tree, rays);
        kdrt_tree_free(tree);
    }
    REQUIRE(counter.live_blocks == 0);

    size_t survived = 0, mismatched = 0;
    for (size_t k = 1; k <= (first ? std::min(first, total) : total); ++k) {
        counter.reset_counts();
        counter.fail_at = k;
        kdrt_result r = try_build(view, o, &tree, &report);
        INFO("failing allocation " << k << " of " << total << ": " << kdrt_result_string(r));
        if (r == KDRT_SUCCESS) {
            CHECK(expected_result == KDRT_SUCCESS);
            CHECK(k + 4 > total);  // only the trims may fail harmlessly, not the cells after them
            CHECK(k + 2 <= total);
            ++survived;
            REQUIRE(tree != nullptr);
            std::vector<kdrt_hit> hits = kt::trace_all(tree, rays);
            for (size_t i = 0; i < rays.size(); ++i) mismatched += !same_hit(hits[i], reference[i]);
            kdrt_tree_free(tree);
        } else {
            if (r != KDRT_ERROR_OUT_OF_MEMORY) CHECK(r == other);
            CHECK(tree == nullptr);
            if (r == KDRT_ERROR_OUT_OF_MEMORY)  // the first bad triangle, if the scan got that far
                CHECK((report.invalid_triangle == invalid || report.invalid_triangle == KDRT_INVALID_ID));
        }
        CHECK(counter.live_blocks == 0);
        CHECK(counter.live_bytes == 0);
        CHECK(counter.bad_frees == 0);
        if (counter.live_blocks != 0) break;  // one report is enough
    }
    CHECK(survived <= 2);
    CHECK(mismatched == 0);
    CHECK(CountingAllocator::wrong_user == 0);
}

}  // namespace

TEST_CASE("alloc: failing any one allocation of a build frees everything", "[errors][alloc]") {
    common::Mesh mesh = kt::random_soup(500, 17);
    kdrt_triangles view = mesh.view();
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_aabb{{0, 0, 0}, {10, 10, 10}}, 500, 4);
    for (uint32_t leaf : kLeafSizes) {
        INFO("leaf size " << leaf);
        fail_each_allocation(view, options_with_leaf(leaf), KDRT_SUCCESS, KDRT_ERROR_OUT_OF_MEMORY, rays);
    }
    {  // indexed mesh, skipping invalid triangles
        common::Mesh grid = kt::grid(20, 15, 2);
        grid.positions[3 * 50 + 1] = kNaN;
        grid.indices[3 * 100] = 100000;
        kdrt_triangles gv = grid.view();
        for (uint32_t leaf : {0u, 1u, 4u}) {
            INFO("leaf size " << leaf);
            kdrt_build_options o = options_with_leaf(leaf);
            o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
            fail_each_allocation(gv, o, KDRT_SUCCESS, KDRT_ERROR_OUT_OF_MEMORY, rays);
        }
    }
    {  // empty mesh
        kdrt_triangles empty{};
        fail_each_allocation(empty, options_with_leaf(4), KDRT_SUCCESS, KDRT_ERROR_OUT_OF_MEMORY, rays);
    }
    {  // the SAH builder allocates per node: a smaller soup keeps the k-th-failure loop short
        common::Mesh small = kt::random_soup(60, 18);
        kdrt_triangles sv = small.view();
        for (const kt::Builder &builder : kt::kSahBuilders)
            for (uint32_t leaf : {1u, 4u}) {
                INFO(builder.name << ", leaf size " << leaf);
                kdrt_build_options o = options_with_leaf(leaf);
                builder.apply(o);
                fail_each_allocation(sv, o, KDRT_SUCCESS, KDRT_ERROR_OUT_OF_MEMORY, rays);
            }
    }
    // SAH builds at each quality whose tasks run here in reverse order: the first allocations
    // (or all) of a build of `triangles`.
    const auto in_tasks = [&rays](uint32_t triangles, uint32_t seed, size_t first) {
        common::Mesh soup = kt::random_soup(triangles, seed);
        kdrt_triangles sv = soup.view();
        for (const kt::Builder &builder : kt::kSahBuilders) {
            kdrt_build_options o = options_with_leaf(4);
            builder.apply(o);
            // Reversed, and counting the most tasks handed out at once (in *user).
            o.scheduler.run = [](void *user, kdrt_task_fn task, void *data, uint32_t count) {
                uint32_t &most = *static_cast<uint32_t *>(user);
                most = std::max(most, count);
                for (uint32_t i = count; i-- > 0;) task(data, i);
            };
            uint32_t most_tasks = 0;
            o.scheduler.user = &most_tasks;
            INFO(builder.name << " in tasks, " << triangles << " triangles");
            fail_each_allocation(sv, o, KDRT_SUCCESS, KDRT_ERROR_OUT_OF_MEMORY, rays, first);
            CHECK(most_tasks >= 2);
        }
    };
    // Large enough for the SAH build to cut its top into tasks (nodes of more than 4,096
    // references: its two halves), small enough that failing each of its allocations in turn,
    // a build each, stays short.
    in_tasks(5000, 19, 0);
    // Large enough for the top's nodes to be binned (HIGH: sorted) and the triangles prepared
    // and packed in chunks on the scheduler: the first 40 allocations, where those happen.
    in_tasks(20000, 20, 40);
}

TEST_CASE("alloc: a build failing on a bad triangle frees everything", "[errors][alloc]") {
    common::Mesh mesh = kt::random_soup(500, 17);
    std::vector<kdrt_ray> rays;
    for (uint32_t bad_triangle : {0u, 250u, 499u}) {
        common::Mesh m = mesh;
        m.positions[size_t(bad_triangle) * 9 + 4] = kInf;
        kdrt_triangles view = m.view();
        for (uint32_t leaf : {0u, 1u, 4u}) {
            INFO("bad triangle " << bad_triangle << " leaf size " << leaf);
            CountingAllocator counter;
            {
                UseCounter use(counter);
                kdrt_build_options o = options_with_leaf(leaf);
                o.allocator = counter.hooks();
                kdrt_tree *tree;
                kdrt_build_report report;
                CHECK(try_build(view, o, &tree, &report) == KDRT_ERROR_NON_FINITE_VERTEX);
                CHECK(tree == nullptr);
                CHECK(report.invalid_triangle == bad_triangle);
                CHECK(counter.live_blocks == 0);
                CHECK(counter.frees == counter.calls);
                CHECK(CountingAllocator::wrong_user == 0);
            }
            kdrt_build_options o = options_with_leaf(leaf);
            fail_each_allocation(view, o, KDRT_ERROR_NON_FINITE_VERTEX, KDRT_ERROR_NON_FINITE_VERTEX, rays);
        }
    }
    // Index out of range in a soup (vertex_count short), found after the first allocations.
    kdrt_triangles view = mesh.view();
    view.vertex_count -= 1;
    fail_each_allocation(view, options_with_leaf(2), KDRT_ERROR_INDEX_OUT_OF_RANGE, KDRT_ERROR_INDEX_OUT_OF_RANGE, rays);
}

TEST_CASE("errors: kdrt_hit_surface and kdrt_spawn_ray refuse a made-up hit on a skipped triangle", "[errors]") {
    common::Mesh grid = kt::grid(4, 4, 3);
    grid.indices[3 * 5 + 1] = 1000000;  // triangle 5: an index far out of range, skipped
    grid.positions[3 * grid.indices[3 * 7]] = kNaN;  // triangle 7 (and its neighbours): NaN, skipped
    kdrt_triangles view = grid.view();
    kdrt_build_options o = kdrt_default_build_options();
    o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
    kdrt_tree *raw = nullptr;
    REQUIRE(try_build(view, o, &raw) == KDRT_SUCCESS);
    kt::TreePtr tree(raw);
    const float dir[3] = {0, 0, 1};
    for (uint32_t skipped : {5u, 7u}) {
        INFO("triangle " << skipped);
        kdrt_hit hit{1.0f, 0.25f, 0.25f, skipped, 0, KDRT_INVALID_ID, 0};
        float point[3] = {-1, -1, -1}, normal[3] = {-1, -1, -1};
        CHECK(kdrt_hit_surface(tree.get(), &hit, point, normal) == 0);
        CHECK(point[0] == -1.0f);  // nothing written
        kdrt_ray ray;
        CHECK(kdrt_spawn_ray(tree.get(), &hit, dir, &ray) == 0);
    }
    kdrt_hit good{1.0f, 0.25f, 0.25f, 0, 0, KDRT_INVALID_ID, 0};
    float point[3];
    CHECK(kdrt_hit_surface(tree.get(), &good, point, nullptr) == 1);
}
