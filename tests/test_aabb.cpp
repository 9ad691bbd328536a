// Boxes: kdrt_aabb_empty/grow/union, kdrt_aabb_of_triangles and kdrt_aabb_intersect_ray, on
// hand-computed cases. The slab test's exit distance is widened by a few ulps on purpose (it is
// conservative, see KDRT__T_SLACK), so exits are checked to lie in [exact, exact * (1 + 1e-6)].
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace {

using kt::ray_of;

const float kInf = std::numeric_limits<float>::infinity();
const float kNaN = std::numeric_limits<float>::quiet_NaN();

kdrt_aabb box_of(float x0, float y0, float z0, float x1, float y1, float z1) {
    kdrt_aabb b;
    b.min[0] = x0, b.min[1] = y0, b.min[2] = z0;
    b.max[0] = x1, b.max[1] = y1, b.max[2] = z1;
    return b;
}

bool same_box(const kdrt_aabb &a, const kdrt_aabb &b) {
    for (int i = 0; i < 3; ++i)
        if (a.min[i] != b.min[i] || a.max[i] != b.max[i]) return false;
    return true;
}

bool is_empty_box(const kdrt_aabb &b) { return same_box(b, kdrt_aabb_empty()); }

// Hit with an entry in [enter * (1 - 1e-6), enter] and an exit in [exit, exit * (1 + 1e-6)]:
// both widened by their rounding bound, never narrowed.
void require_hit(const kdrt_aabb &box, const kdrt_ray &ray, float enter, float exit) {
    float t0 = -123.0f, t1 = -123.0f;
    REQUIRE(kdrt_aabb_intersect_ray(&box, &ray, &t0, &t1) == 1);
    CHECK(t0 <= enter);
    CHECK(t0 >= enter * (1.0f - 1e-6f));
    CHECK(t1 >= exit);
    CHECK(t1 <= exit * (1.0f + 1e-6f));
}

void require_miss(const kdrt_aabb &box, const kdrt_ray &ray) {
    float t0 = 0, t1 = 0;
    CHECK(kdrt_aabb_intersect_ray(&box, &ray, &t0, &t1) == 0);
}

// Writes a float at an arbitrary byte offset (the buffers below have unaligned strides).
void put(std::vector<unsigned char> &buf, size_t offset, float x, float y, float z) {
    float v[3] = {x, y, z};
    std::memcpy(buf.data() + offset, v, sizeof v);
}

}  // namespace

TEST_CASE("aabb: empty box is min = +inf, max = -inf, and grow gives the point's box", "[aabb]") {
    kdrt_aabb e = kdrt_aabb_empty();
    for (int a = 0; a < 3; ++a) {
        CHECK(e.min[a] == kInf);
        CHECK(e.max[a] == -kInf);
    }
    const float p[3] = {1.5f, -2.0f, 3.25f};
    kdrt_aabb_grow(&e, p);
    CHECK(same_box(e, box_of(1.5f, -2.0f, 3.25f, 1.5f, -2.0f, 3.25f)));
    const float q[3] = {-1.0f, 4.0f, 3.0f};
    kdrt_aabb_grow(&e, q);
    CHECK(same_box(e, box_of(-1.0f, -2.0f, 3.0f, 1.5f, 4.0f, 3.25f)));
    const float inside[3] = {0.0f, 0.0f, 3.125f};
    kdrt_aabb_grow(&e, inside);
    CHECK(same_box(e, box_of(-1.0f, -2.0f, 3.0f, 1.5f, 4.0f, 3.25f)));
}

TEST_CASE("aabb: union", "[aabb]") {
    kdrt_aabb a = box_of(0, 1, 2, 3, 4, 5), b = box_of(-1, 2, 6, 1, 3, 7);
    CHECK(same_box(kdrt_aabb_union(a, b), box_of(-1, 1, 2, 3, 4, 7)));
    CHECK(same_box(kdrt_aabb_union(b, a), box_of(-1, 1, 2, 3, 4, 7)));
    CHECK(same_box(kdrt_aabb_union(a, a), a));
    kdrt_aabb inner = box_of(1, 2, 3, 2, 3, 4);
    CHECK(same_box(kdrt_aabb_union(a, inner), a));
    CHECK(same_box(kdrt_aabb_union(inner, a), a));

    SECTION("the empty box is the identity on both sides") {
        CHECK(same_box(kdrt_aabb_union(kdrt_aabb_empty(), a), a));
        CHECK(same_box(kdrt_aabb_union(a, kdrt_aabb_empty()), a));
        CHECK(is_empty_box(kdrt_aabb_union(kdrt_aabb_empty(), kdrt_aabb_empty())));
    }
}

TEST_CASE("aabb: kdrt_aabb_of_triangles", "[aabb]") {
    kdrt_aabb box;
    kdrt_build_report report;

    SECTION("indexed: only referenced vertices count") {
        // Vertex 3 is far away but no triangle uses it.
        const float v[] = {0, 0, 0, 1, 2, 3, -1, 5, 0.5f, 100, 100, 100, 2, -3, 1};
        const uint32_t idx[] = {0, 1, 2, 2, 4, 0};
        kdrt_triangles m{};
        m.positions = v, m.vertex_count = 5, m.indices = idx, m.triangle_count = 2;
        report.invalid_triangle = 7, report.skipped_triangles = 9;
        REQUIRE(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
        CHECK(same_box(box, box_of(-1, -3, 0, 2, 5, 3)));
        CHECK(report.invalid_triangle == KDRT_INVALID_ID);
        CHECK(report.skipped_triangles == 0);
        REQUIRE(kdrt_aabb_of_triangles(&m, &box, nullptr) == KDRT_SUCCESS);
        CHECK(same_box(box, box_of(-1, -3, 0, 2, 5, 3)));
    }
    SECTION("soup, packed") {
        const float v[] = {0, 0, 0, 1, 2, 3, -1, 5, 0.5f, 7, 0, 0, 7, 1, 0, 7, 0, -2};
        kdrt_triangles m{};
        m.positions = v, m.vertex_count = 6, m.triangle_count = 2;
        REQUIRE(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
        CHECK(same_box(box, box_of(-1, 0, -2, 7, 5, 3)));
        m.triangle_count = 1;  // the second triangle no longer counts
        REQUIRE(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
        CHECK(same_box(box, box_of(-1, 0, 0, 1, 5, 3)));
    }
    SECTION("strided, with padding that must be ignored") {
        for (size_t stride : {size_t(16), size_t(20), size_t(13)}) {
            INFO("stride " << stride);
            std::vector<unsigned char> buf(stride * 6 + 16);
            for (size_t i = 0; i < buf.size(); ++i) buf[i] = 0x7F;  // padding: 0x7F7F7F7F = 3.4e38
            put(buf, 0 * stride, 0, 0, 0);
            put(buf, 1 * stride, 1, 2, 3);
            put(buf, 2 * stride, -1, 5, 0.5f);
            put(buf, 3 * stride, 7, 0, 0);
            put(buf, 4 * stride, 7, 1, 0);
            put(buf, 5 * stride, 7, 0, -2);
            kdrt_triangles m{};
            m.positions = reinterpret_cast<const float *>(buf.data());
            m.position_stride = stride, m.vertex_count = 6, m.triangle_count = 2;
            REQUIRE(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
            CHECK(same_box(box, box_of(-1, 0, -2, 7, 5, 3)));
        }
    }
    SECTION("empty mesh gives the empty box") {
        kdrt_triangles m{};
        box = box_of(1, 1, 1, 2, 2, 2);
        REQUIRE(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
        CHECK(is_empty_box(box));
        const float v[] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
        m.positions = v, m.vertex_count = 3;  // vertices but no triangles
        box = box_of(1, 1, 1, 2, 2, 2);
        REQUIRE(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
        CHECK(is_empty_box(box));
    }
    SECTION("agrees with kdrt_tree_bounds") {
        common::Mesh mesh = kt::sphere(9, 13, 2.5);
        kdrt_triangles view = mesh.view();
        REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
        kt::TreePtr tree = kt::build(mesh, 4, KDRT_BUILDER_MEDIAN);
        CHECK(same_box(box, kdrt_tree_bounds(tree.get())));
        double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
        for (size_t i = 0; i < mesh.positions.size(); ++i)
            lo[i % 3] = std::min(lo[i % 3], double(mesh.positions[i])), hi[i % 3] = std::max(hi[i % 3], double(mesh.positions[i]));
        for (int a = 0; a < 3; ++a) {
            CHECK(box.min[a] == float(lo[a]));
            CHECK(box.max[a] == float(hi[a]));
        }
    }
    SECTION("errors propagate, naming the first bad triangle, and leave the empty box") {
        float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
        uint32_t idx[] = {0, 1, 2, 1, 2, 3, 0, 5, 1, 2, 3, 4, 0, 3, 9};  // triangles 2 and 4 out of range
        kdrt_triangles m{};
        m.positions = v, m.vertex_count = 5, m.indices = idx, m.triangle_count = 5;
        box = box_of(1, 1, 1, 2, 2, 2);
        CHECK(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
        CHECK(report.invalid_triangle == 2);
        CHECK(is_empty_box(box));
        CHECK(kdrt_aabb_of_triangles(&m, &box, nullptr) == KDRT_ERROR_INDEX_OUT_OF_RANGE);

        idx[7] = 4;                 // triangle 2 fine now; triangle 3 uses vertex 4...
        v[4 * 3 + 1] = kNaN;        // ...which is NaN; triangle 4 is still out of range
        CHECK(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_ERROR_NON_FINITE_VERTEX);
        CHECK(report.invalid_triangle == 2);  // triangle 2 = {0, 4, 1} uses vertex 4 as well
        CHECK(is_empty_box(box));

        m.triangle_count = 2;  // only the good ones
        CHECK(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_SUCCESS);
        CHECK(same_box(box, box_of(0, 0, 0, 1, 1, 1)));

        // Soup whose vertex_count is short of 3 * triangle_count.
        kdrt_triangles s{};
        s.positions = v, s.vertex_count = 5, s.triangle_count = 2;
        CHECK(kdrt_aabb_of_triangles(&s, &box, &report) == KDRT_ERROR_INDEX_OUT_OF_RANGE);
        CHECK(report.invalid_triangle == 1);
        CHECK(is_empty_box(box));
    }
    SECTION("argument errors") {
        const float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
        kdrt_triangles m{};
        m.positions = v, m.vertex_count = 3, m.triangle_count = 1;
        CHECK(kdrt_aabb_of_triangles(nullptr, &box, &report) == KDRT_ERROR_NULL_ARGUMENT);
        CHECK(kdrt_aabb_of_triangles(&m, nullptr, &report) == KDRT_ERROR_NULL_ARGUMENT);
        m.position_stride = 8;
        CHECK(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_ERROR_INVALID_STRIDE);
        m.position_stride = 0, m.positions = nullptr;
        CHECK(kdrt_aabb_of_triangles(&m, &box, &report) == KDRT_ERROR_NULL_ARGUMENT);
    }
}

TEST_CASE("aabb: ray hits with hand-computed entry and exit", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0), 1, 2);
    require_hit(b, ray_of(3, 3, 4.5f, -1, 0, 0), 1, 2);
    require_hit(b, ray_of(0, 0, 0, 1, 2, 3), 1, 2);       // enters all three slabs at t = 1
    require_hit(b, ray_of(0, 0, 0, 2, 4, 6), 0.5f, 1);    // unnormalised direction
    require_hit(b, ray_of(3, 5, 7, -1, -1, -1), 1, 2);    // slabs [1,2], [1,3], [1,4]
    require_hit(b, ray_of(0, 3, 2, 1, 0, 1), 1, 2);       // slabs x [1,2], z [1,4]
    require_hit(b, ray_of(1.5f, 3, 4.5f, 0, 0, 1), 0, 1.5f);  // origin inside
    require_hit(b, ray_of(1.5f, 3, 4.5f, 0, -4, 0), 0, 0.25f);

    // Misses: slab intervals that do not overlap, boxes behind the origin, rays beside the box.
    require_miss(b, ray_of(0, 0, 0, 1, 1, 1));            // x [1,2], y [2,4], z [3,6]
    require_miss(b, ray_of(0, 3, 0, 1, 0, 1));            // x [1,2], z [3,6]
    require_miss(b, ray_of(5, 3, 4.5f, 1, 0, 0));         // behind
    require_miss(b, ray_of(0, 5, 4.5f, 1, 0, 0));         // beside in y
    require_miss(b, ray_of(0, 3, 4.5f, -1, 0, 0));        // pointing away

    SECTION("t_enter and t_exit may be NULL") {
        kdrt_ray r = ray_of(0, 3, 4.5f, 1, 0, 0);
        float t = 0;
        CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 1);
        CHECK(kdrt_aabb_intersect_ray(&b, &r, &t, nullptr) == 1);
        CHECK(t <= 1.0f);
        CHECK(t >= 1.0f - 1e-6f);
        t = 0;
        CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, &t) == 1);
        CHECK(t >= 2.0f);
        CHECK(t <= 2.00001f);
        CHECK(kdrt_aabb_intersect_ray(nullptr, &r, &t, &t) == 0);
        CHECK(kdrt_aabb_intersect_ray(&b, nullptr, &t, &t) == 0);
    }
}

TEST_CASE("aabb: the ray's range clips the overlap", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, 1.25f), 1.25f, 2);
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, 0, 1.5f), 1, 1.5f);
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, 1.25f, 1.75f), 1.25f, 1.75f);
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, 0, 1), 1, 1);  // closed range: touches the entry face
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, 2, 5), 2, 2);  // starts on the exit face
    require_miss(b, ray_of(0, 3, 4.5f, 1, 0, 0, 0, 0.999f));
    require_miss(b, ray_of(0, 3, 4.5f, 1, 0, 0, 2.01f));
    require_miss(b, ray_of(0, 3, 4.5f, 1, 0, 0, 1.75f, 1.5f));  // tmin > tmax

    SECTION("negative tmin is treated as 0") {
        require_hit(b, ray_of(1.5f, 3, 4.5f, 0, 0, 1, -10), 0, 1.5f);
        require_hit(b, ray_of(1.5f, 3, 4.5f, 0, 0, 1, -kInf), 0, 1.5f);
        require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, -5), 1, 2);
        require_miss(b, ray_of(5, 3, 4.5f, 1, 0, 0, -10));  // box behind stays behind
        require_hit(b, ray_of(1.5f, 3, 4.5f, 0, 0, 1, -3, 1), 0, 1);
        require_miss(b, ray_of(1.5f, 3, 4.5f, 0, 0, 1, -3, -1));  // range entirely before 0
    }
}

TEST_CASE("aabb: +0 and -0 direction components are exact, boundary included", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    const float zeros[2] = {0.0f, -0.0f};
    for (float zy : zeros)
        for (float zz : zeros) {
            INFO("dir.y = " << (std::signbit(zy) ? "-0" : "+0") << ", dir.z = " << (std::signbit(zz) ? "-0" : "+0"));
            // Along x, parallel to the y and z slabs.
            require_hit(b, ray_of(0, 3, 4.5f, 1, zy, zz), 1, 2);
            require_hit(b, ray_of(0, 4, 4.5f, 1, zy, zz), 1, 2);   // on the y = max face
            require_hit(b, ray_of(0, 2, 4.5f, 1, zy, zz), 1, 2);   // on the y = min face
            require_hit(b, ray_of(0, 3, 6, 1, zy, zz), 1, 2);      // on the z = max face
            require_hit(b, ray_of(0, 3, 3, 1, zy, zz), 1, 2);      // on the z = min face
            require_miss(b, ray_of(0, std::nextafter(4.0f, kInf), 4.5f, 1, zy, zz));
            require_miss(b, ray_of(0, std::nextafter(2.0f, -kInf), 4.5f, 1, zy, zz));
            require_miss(b, ray_of(0, 3, std::nextafter(6.0f, kInf), 1, zy, zz));
            require_miss(b, ray_of(0, 3, std::nextafter(3.0f, -kInf), 1, zy, zz));
            require_hit(b, ray_of(3, 3, 4.5f, -1, zy, zz), 1, 2);
            // Along z: the x and y slabs are parallel.
            require_hit(b, ray_of(1.5f, 3, 0, zy, zz, 1), 3, 6);
            require_hit(b, ray_of(2, 4, 0, zy, zz, 1), 3, 6);      // along the x = max, y = max edge
            require_hit(b, ray_of(1, 2, 10, zy, zz, -2), 2, 3.5f);  // along the x = min, y = min edge
            require_miss(b, ray_of(std::nextafter(2.0f, kInf), 3, 0, zy, zz, 1));
            // Origin inside, parallel to two slabs.
            require_hit(b, ray_of(1.5f, 3, 4.5f, zy, 1, zz), 0, 1);
            require_hit(b, ray_of(1.5f, 3, 4.5f, zy, -1, zz), 0, 1);
        }
}

TEST_CASE("aabb: rays along and grazing box edges", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    require_hit(b, ray_of(0, 2, 3, 1, 0, 0), 1, 2);   // along the min/min edge
    require_hit(b, ray_of(0, 4, 6, 1, 0, 0), 1, 2);   // along the max/max edge
    require_hit(b, ray_of(1, 0, 6, 0, 1, 0), 2, 4);   // along the x = min, z = max edge
    // Through the edge x = 2, y = 2 only, at t = 1: slabs x [0, 1], y [1, 3].
    require_hit(b, ray_of(1, 1, 4.5f, 1, 1, 0), 1, 1);
    // Through the corner (2, 4, 6) only, at t = 1: slabs x [1, 2], y [-1, 1], z [-2, 1].
    require_hit(b, ray_of(3, 3, 5, -1, 1, 1), 1, 1);
    // Past the edge (by more than the exit's few ulps of widening).
    require_miss(b, ray_of(1, 0.999f, 4.5f, 1, 1, 0));
    require_miss(b, ray_of(3, 3, 5.001f, -1, 1, 1));
}

TEST_CASE("aabb: NaN anywhere in the ray or the box gives 0", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    const kdrt_ray good = ray_of(0, 3, 4.5f, 1, 0.25f, 0.25f);
    REQUIRE(kdrt_aabb_intersect_ray(&b, &good, nullptr, nullptr) == 1);  // the baseline hits
    for (int a = 0; a < 3; ++a) {
        INFO("axis " << a);
        kdrt_ray r = good;
        r.org[a] = kNaN;
        CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 0);
        r = good;
        r.dir[a] = kNaN;
        CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 0);
        kdrt_aabb nb = b;
        nb.min[a] = kNaN;
        CHECK(kdrt_aabb_intersect_ray(&nb, &good, nullptr, nullptr) == 0);
        nb = b;
        nb.max[a] = kNaN;
        CHECK(kdrt_aabb_intersect_ray(&nb, &good, nullptr, nullptr) == 0);
    }
    kdrt_ray r = good;
    r.tmax = kNaN;
    CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 0);
    SECTION("NaN tmin") {
        r = good;
        r.tmin = kNaN;
        CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 0);
    }
}

TEST_CASE("aabb: infinite components", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    const kdrt_ray good = ray_of(0, 3, 4.5f, 1, 0.25f, 0.25f);
    for (int a = 0; a < 3; ++a)
        for (float inf : {kInf, -kInf}) {
            INFO("axis " << a << " value " << inf);
            kdrt_ray r = good;
            r.org[a] = inf;
            CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 0);
            r = good;
            r.dir[a] = inf;
            CHECK(kdrt_aabb_intersect_ray(&b, &r, nullptr, nullptr) == 0);
        }
    // Infinite range ends are ordinary.
    require_hit(b, ray_of(0, 3, 4.5f, 1, 0, 0, -kInf, kInf), 1, 2);
    require_miss(b, ray_of(0, 3, 4.5f, 1, 0, 0, kInf, kInf));
    require_miss(b, ray_of(0, 3, 4.5f, 1, 0, 0, 0, -kInf));
    // Infinite boxes.
    const kdrt_aabb all = box_of(-kInf, -kInf, -kInf, kInf, kInf, kInf);
    float t0 = -1, t1 = -1;
    kdrt_ray r = ray_of(0, 0, 0, 1, 0, 0);
    REQUIRE(kdrt_aabb_intersect_ray(&all, &r, &t0, &t1) == 1);
    CHECK(t0 == 0.0f);
    CHECK(t1 == kInf);
    r = ray_of(5, -7, 1e30f, 0.5f, -2, 3, 0, 10);
    REQUIRE(kdrt_aabb_intersect_ray(&all, &r, &t0, &t1) == 1);
    CHECK(t0 == 0.0f);
    CHECK(t1 == 10.0f);
    const kdrt_aabb half = box_of(0, -kInf, -kInf, kInf, kInf, kInf);
    r = ray_of(-2, 5, 5, 1, 0, 0);
    REQUIRE(kdrt_aabb_intersect_ray(&half, &r, &t0, &t1) == 1);
    CHECK(t0 <= 2.0f);
    CHECK(t0 >= 2.0f * (1.0f - 1e-6f));
    CHECK(t1 == kInf);
    r = ray_of(-2, 5, 5, -1, 0, 0);
    CHECK(kdrt_aabb_intersect_ray(&half, &r, &t0, &t1) == 0);
}

TEST_CASE("aabb: zero direction, empty box, inverted box", "[aabb]") {
    const kdrt_aabb b = box_of(1, 2, 3, 2, 4, 6);
    require_miss(b, ray_of(1.5f, 3, 4.5f, 0, 0, 0));      // inside, but no direction
    require_miss(b, ray_of(1.5f, 3, 4.5f, -0.0f, 0, -0.0f));
    const kdrt_aabb empty = kdrt_aabb_empty();
    require_miss(empty, ray_of(0, 0, 0, 1, 0, 0));
    require_miss(empty, ray_of(0, 0, 0, 1, 1, 1, -kInf, kInf));
    require_miss(empty, ray_of(0, 0, 0, 0, 0, 1));
    kdrt_aabb inverted = b;
    inverted.min[1] = 5;  // min.y > max.y
    require_miss(inverted, ray_of(0, 3, 4.5f, 1, 0, 0));
    require_miss(inverted, ray_of(0, 4.5f, 4.5f, 1, 0, 0));
}

TEST_CASE("aabb: flat and point boxes", "[aabb]") {
    const kdrt_aabb flat = box_of(1, 2, 3, 1, 4, 6);  // the plane x = 1
    require_hit(flat, ray_of(0, 3, 4.5f, 1, 0, 0), 1, 1);
    require_hit(flat, ray_of(2, 3, 4.5f, -2, 0, 0), 0.5f, 0.5f);
    require_hit(flat, ray_of(0, 0, 0, 1, 3, 4.5f), 1, 1);
    require_hit(flat, ray_of(1, 0, 4.5f, 0, 1, 0), 2, 4);       // in the plane
    require_hit(flat, ray_of(1, 0, 4.5f, -0.0f, 1, 0), 2, 4);
    require_miss(flat, ray_of(std::nextafter(1.0f, kInf), 0, 4.5f, 0, 1, 0));
    require_miss(flat, ray_of(0, 5, 4.5f, 1, 0, 0));
    const kdrt_aabb point = box_of(1, 2, 3, 1, 2, 3);
    require_hit(point, ray_of(0, 2, 3, 1, 0, 0), 1, 1);
    require_hit(point, ray_of(0, 0, 0, 1, 2, 3), 1, 1);
    require_hit(point, ray_of(1, 2, 3, 0, 0, -1), 0, 0);         // starts on it
    require_miss(point, ray_of(0, 2, std::nextafter(3.0f, kInf), 1, 0, 0));
    require_miss(point, ray_of(0, 0, 0, 1, 2, 3.0001f));
}
