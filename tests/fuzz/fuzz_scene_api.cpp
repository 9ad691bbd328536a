// libFuzzer target: kdrt's scene API (SCENES in kdrt.h) on entries, options, moves and queries made
// from the input. Entries: meshes (up to 9 vertices and 6 triangles at some byte stride, any
// floats: NaN, infinite, huge, tiny; indices some out of range; rarely a NULL buffer or a count
// beyond what a tree can address), instances of a few small trees built once (a unit cube, the
// triangle 2e10 across, one whose corners are the largest floats, an empty tree, a tiny one, a
// soup, one built per input from any floats) or of no tree, entries of no known type; IDs small,
// repeated, any or KDRT_INVALID_ID; any masks; transforms of every kind: identity, huge and tiny
// scales (1e38, 1e-30, subnormal), mirrors, rotations, shears, singular and nearly singular
// matrices, any floats. Build options as the tree target makes them, sometimes with an allocator
// that fails one allocation. Then a sequence of kdrt_scene_set_transform(), kdrt_scene_attach()
// (meshes and instances made as the entries are), kdrt_scene_detach(), kdrt_scene_enable(),
// kdrt_scene_commit() and queries: every scene query on rays of any floats or aimed at what the scene holds, with
// masks, culled faces and filters (taking all, refusing all, taking some, running a query of
// their own on the same scene).
// Checked, as kdrt.h documents it:
//  - a build succeeds, or fails with *out_scene NULL and nothing left allocated; it fails exactly
//    where an entry is bad (an ID used twice or KDRT_INVALID_ID, no tree, a transform that is not
//    finite and invertible or carries its tree's box beyond float's range, an unknown type, a bad
//    mesh view) with the report naming the first bad geometry in ID order, or where one tree over
//    the meshes merged in ID order fails (the report naming the mesh and its own triangle);
//  - kdrt_scene_geometry() gives each entry back as given, with the committed transform; a
//    refused change changes nothing; a commit applies exactly the accepted changes, and one that
//    runs out of memory (or whose rebuilt mesh tree fails) leaves the scene as it was; no hit
//    names a disabled entry;
//  - kdrt_scene_bounds() is finite or empty, and holds every instance's transformed box;
//  - every hit lies in the ray's range with finite t, u, v and names a geometry of the scene
//    (through an instance: that instance) that the query's mask lets through, and a triangle it
//    has; kdrt_scene_occluded() agrees with kdrt_scene_intersect(), kdrt_scene_intersect_k()'s
//    hits are distinct, in order, within capacity, the first bit for bit kdrt_scene_intersect()'s;
//    the filter is shown the caller's ray and such candidates, and refusing everything leaves no
//    hit; kdrt_scene_hit_surface() gives a point in the scene's box and a unit normal, and
//    refuses a hit naming nothing; kdrt_scene_spawn_ray() a finite origin;
//  - queries allocate nothing;
// all of it under AddressSanitizer and UBSan.
#include "kdrt.h"
#include "fuzz_support.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace {

using fuzz::Heap;

// ---- the trees instances place ----

struct Object {
    const char *name;
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    kdrt_tree *tree = nullptr;
    uint32_t triangles = 0;
    kdrt_triangles view() const {
        kdrt_triangles v{};
        v.positions = positions.empty() ? nullptr : positions.data();
        v.vertex_count = uint32_t(positions.size() / 3);
        v.indices = indices.empty() ? nullptr : indices.data();
        v.triangle_count = indices.empty() ? uint32_t(positions.size() / 9) : uint32_t(indices.size() / 3);
        return v;
    }
    void build(const kdrt_build_options &options) {
        const kdrt_triangles v = view();
        triangles = v.triangle_count;
        const kdrt_result r = kdrt_tree_build(&v, &options, &tree, nullptr);
        if (r != KDRT_SUCCESS) std::fprintf(stderr, "fuzz_scene_api: cannot build the %s tree: %s\n", name, kdrt_result_string(r)), std::abort();
    }
};

// Built once, before the first input (LLVMFuzzerInitialize), and freed at exit; each input's
// scenes borrow them.
struct Objects {
    std::vector<Object> all;
    ~Objects() {
        for (Object &o : all) kdrt_tree_free(o.tree);
    }
};

std::vector<Object> &objects() {
    static Objects objects{[] {
        std::vector<Object> o(7);
        const float M = FLT_MAX;
        o[0].name = "unit cube";
        o[0].positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
        o[0].indices = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
        o[1].name = "wide triangle";  // 2e10 across
        o[1].positions = {-1e10f, -1e10f, 0, 1e10f, -1e10f, 0, 0, 1e10f, 1e10f};
        o[2].name = "largest floats";  // corners at the largest float: its widened box is not finite
        o[2].positions = {-M, -M, 0, M, -M, 0, 0, M, 1};
        o[3].name = "empty";
        o[4].name = "tiny triangle";
        o[4].positions = {1e-30f, 0, 0, 0, 1e-30f, 0, 0, 0, 1e-30f};
        o[5].name = "soup";
        o[5].positions = {-1, -1, 0, 1, -1, 0, 0, 1, 0, 0, 0, -1, 0, 0, 1, 0, 1, 0.5f, 2, 2, 2, 3, 2, 2, 2, 3, 2};
        o[6].name = "cube, median builder, scalar kernel";
        o[6].positions = o[0].positions, o[6].indices = o[0].indices;
        kdrt_build_options d = kdrt_default_build_options();
        for (int i = 0; i < 5; ++i) o[size_t(i)].build(d);
        kdrt_build_options every = d;
        every.max_leaf_size = 0;
        o[5].build(every);
        kdrt_build_options other = d;
        // Not KDRT_INTERSECTOR_FAST: a scale of 1e30 carries rays into a tree's space with directions
        // 1e-30 long, beyond the range where kdrt.h defines its answers.
        other.builder = KDRT_BUILDER_MEDIAN, other.flags = KDRT_BUILD_SCALAR_KERNEL;
        other.max_leaf_size = 1;
        o[6].build(other);
        return o;
    }()};
    return objects.all;
}

// ---- drawing from the input ----

float pick_scale(FuzzedDataProvider &in) {
    static const float scales[] = {1, 2, 0.5f, 1e30f, 1e-10f, 1e-30f, 1e20f, 1e38f, FLT_MAX, 1e-38f, 3e-39f, 0, 1e-20f, 1e10f, 3, 0.1f};
    const float s = scales[in.ConsumeIntegralInRange<int>(0, 15)];
    return in.ConsumeBool() ? -s : s;
}

float pick_offset(FuzzedDataProvider &in) {
    static const float offsets[] = {0, 5, -5, 1e30f, -1e30f, 1e38f, -FLT_MAX, 0.5f};
    const int k = in.ConsumeIntegralInRange<int>(0, 8);
    return k < 8 ? offsets[k] : fuzz::pick_float(in);
}

void identity(float xf[12]) {
    for (int i = 0; i < 12; ++i) xf[i] = (i % 5 == 0) ? 1.0f : 0.0f;
}

// Any transform: kdrt must take the good ones and refuse the others.
void pick_transform(FuzzedDataProvider &in, float xf[12]) {
    identity(xf);
    switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0: break;
    case 1:  // a scale (any sign: mirrors) and a translation
        if (in.ConsumeBool()) {
            const float s = pick_scale(in);
            xf[0] = xf[5] = xf[10] = s;
        } else {
            for (int a = 0; a < 3; ++a) xf[5 * a] = pick_scale(in);
        }
        for (int a = 0; a < 3; ++a) xf[4 * a + 3] = pick_offset(in);
        break;
    case 2: {  // a rotation about an axis on a grid, by a multiple of 15 degrees, and a scale
        double axis[3], len = 0;
        for (double &x : axis) x = in.ConsumeIntegralInRange<int>(-2, 2), len += x * x;
        if (len == 0) axis[2] = 1, len = 1;
        len = std::sqrt(len);
        for (double &x : axis) x /= len;
        const double angle = in.ConsumeIntegralInRange<int>(0, 23) * M_PI / 12, c = std::cos(angle), s = std::sin(angle), k = 1 - c;
        const double scale = pick_scale(in);
        const double &x = axis[0], &y = axis[1], &z = axis[2];
        const double r[3][3] = {{c + x * x * k, x * y * k - z * s, x * z * k + y * s},
                                {y * x * k + z * s, c + y * y * k, y * z * k - x * s},
                                {z * x * k - y * s, z * y * k + x * s, c + z * z * k}};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) xf[4 * i + j] = float(r[i][j] * scale);
            xf[4 * i + 3] = pick_offset(in);
        }
        break;
    }
    case 3:  // shears
        for (int n = in.ConsumeIntegralInRange<int>(1, 3); n > 0; --n) {
            const int i = in.ConsumeIntegralInRange<int>(0, 2), j = (i + in.ConsumeIntegralInRange<int>(1, 2)) % 3;
            xf[4 * i + j] = fuzz::pick_float(in);
        }
        break;
    case 4: {  // singular: a zero row, a row repeated or scaled, or all zero
        const int i = in.ConsumeIntegralInRange<int>(0, 2), j = (i + in.ConsumeIntegralInRange<int>(1, 2)) % 3;
        switch (in.ConsumeIntegralInRange<int>(0, 2)) {
        case 0: xf[4 * i] = xf[4 * i + 1] = xf[4 * i + 2] = 0; break;
        case 1: {
            const float s = pick_scale(in);
            for (int k = 0; k < 3; ++k) xf[4 * i + k] = s * xf[4 * j + k];
            break;
        }
        default:
            for (int k = 0; k < 12; ++k) xf[k] = 0;
        }
        break;
    }
    case 5:  // any floats
        for (int k = 0; k < 12; ++k) xf[k] = fuzz::pick_float(in);
        break;
    case 6:  // one entry of any float
        xf[in.ConsumeIntegralInRange<int>(0, 11)] = fuzz::pick_float(in);
        break;
    default: {  // about as singular as kdrt accepts: |det| near 2^-40 of its rows' lengths
        static const float near[] = {0.5f, 1.0f, 2.0f, 0.999999f, 1.000001f};
        const float e = 0x1p-40f * near[in.ConsumeIntegralInRange<int>(0, 4)];
        xf[4] = 1, xf[5] = in.ConsumeBool() ? e : -e;
        if (in.ConsumeBool()) {  // the same, scaled
            const float s = pick_scale(in);
            for (int k = 0; k < 12; ++k) xf[k] *= s;
        }
    }
    }
}

// Whether kdrt must refuse a transform for this tree: 1 it must, 0 it must not, -1 either (within
// rounding of the limits kdrt.h states: |det R| at least 2^-40 times its rows' lengths, and the
// tree's box carried into the world and widened by 2^-20 of its extent and position within float's
// range).
int refuses(const kdrt_tree *tree, const float xf[12]) {
    for (int i = 0; i < 12; ++i)
        if (!std::isfinite(xf[i])) return 1;
    double m[12];
    for (int i = 0; i < 12; ++i) m[i] = xf[i];
    const double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) + m[2] * (m[4] * m[9] - m[5] * m[8]);
    double rows = 1;
    for (int i = 0; i < 3; ++i) rows *= std::sqrt(m[4 * i] * m[4 * i] + m[4 * i + 1] * m[4 * i + 1] + m[4 * i + 2] * m[4 * i + 2]);
    if (det == 0) return 1;
    const double ratio = std::fabs(det) / rows, limit = 0x1p-40;
    int verdict = 0;
    if (ratio < limit * (1 - 1e-6)) return 1;
    if (ratio <= limit * (1 + 1e-6)) verdict = -1;
    const kdrt_aabb b = kdrt_tree_bounds(tree);
    if (!(b.min[0] <= b.max[0])) return verdict;
    for (int i = 0; i < 3; ++i) {
        double lo = HUGE_VAL, hi = -HUGE_VAL;
        for (int k = 0; k < 8; ++k) {
            const double x = m[4 * i] * double(k & 1 ? b.max[0] : b.min[0]) + m[4 * i + 1] * double(k & 2 ? b.max[1] : b.min[1]) +
                             m[4 * i + 2] * double(k & 4 ? b.max[2] : b.min[2]) + m[4 * i + 3];
            lo = std::min(lo, x), hi = std::max(hi, x);
        }
        const double pad = 0x1p-20 * (hi - lo + std::max(std::fabs(lo), std::fabs(hi)));
        const double reach = std::max(std::fabs(lo - pad), std::fabs(hi + pad));
        if (reach > double(FLT_MAX) * (1 + 1e-9)) return 1;
        if (reach >= double(FLT_MAX) * (1 - 1e-9)) verdict = -1;
    }
    return verdict;
}

struct MeshInput {
    std::unique_ptr<unsigned char[]> positions;  // exactly as many bytes as the view reads
    std::vector<uint32_t> indices;
    kdrt_triangles view{};
};

void make_mesh(FuzzedDataProvider &in, MeshInput &m) {
    static const size_t strides[] = {0, 12, 16, 13, 4};
    const size_t stride = strides[in.ConsumeIntegralInRange<int>(0, 4)];
    const uint32_t vertices = in.ConsumeIntegralInRange<uint32_t>(0, 9);
    const size_t step = stride ? stride : 12, bytes = vertices ? (vertices - 1) * step + 12 : 0;
    if (bytes) m.positions.reset(new unsigned char[bytes]);
    for (uint32_t v = 0; v < vertices; ++v) {
        float p[3];
        for (float &x : p) x = fuzz::pick_float(in);
        std::memcpy(m.positions.get() + v * step, p, sizeof p);
    }
    const uint32_t triangles = in.ConsumeIntegralInRange<uint32_t>(0, 6);
    if (in.ConsumeBool()) {
        for (uint32_t i = 0; i < 3 * triangles; ++i) {
            const int k = in.ConsumeIntegralInRange<int>(0, 15);
            m.indices.push_back(k == 0 ? vertices : k == 1 ? in.ConsumeIntegral<uint32_t>()
                                                           : (vertices ? in.ConsumeIntegralInRange<uint32_t>(0, vertices - 1) : 0));
        }
    }
    m.view.positions = reinterpret_cast<const float *>(m.positions.get());
    m.view.position_stride = stride;
    m.view.vertex_count = vertices;
    m.view.indices = m.indices.empty() ? nullptr : m.indices.data();
    m.view.triangle_count = triangles;
    switch (in.ConsumeIntegralInRange<int>(0, 31)) {
    case 0: m.view.positions = nullptr; break;
    case 1: m.view.triangle_count = KDRT_MAX_TRIANGLES + in.ConsumeIntegralInRange<uint32_t>(1, 4); break;  // refused unread
    default: break;
    }
}

uint32_t pick_id(FuzzedDataProvider &in, const std::vector<kdrt_geometry> &before) {
    switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 4: return before.empty() ? 0 : before[in.ConsumeIntegralInRange<size_t>(0, before.size() - 1)].id;
    case 5: return KDRT_INVALID_ID;
    case 6: return in.ConsumeIntegral<uint32_t>();
    case 7: return uint32_t(before.size());
    default: return in.ConsumeIntegralInRange<uint32_t>(0, 15);
    }
}

uint32_t pick_mask(FuzzedDataProvider &in) {
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0: return 0xFFFFFFFFu;
    case 1: return 1u << in.ConsumeIntegralInRange<int>(0, 3);
    case 2: return in.ConsumeIntegralInRange<uint32_t>(0, 15);
    default: return in.ConsumeIntegral<uint32_t>();
    }
}

kdrt_build_options make_options(FuzzedDataProvider &in) {
    kdrt_build_options o = kdrt_default_build_options();
    if (!in.ConsumeBool()) return o;
    o.builder = kdrt_builder(in.ConsumeIntegralInRange<int>(0, 3));
    o.quality = kdrt_build_quality(in.ConsumeIntegralInRange<int>(0, 4));
    o.intersector = kdrt_intersector(in.ConsumeIntegralInRange<int>(0, 3));
    static const uint32_t leaves[] = {4, 0, 1, 2, 8, 0xFFFFFFFFu};
    o.max_leaf_size = leaves[in.ConsumeIntegralInRange<int>(0, 5)];
    o.max_depth = in.ConsumeBool() ? 0 : in.ConsumeIntegralInRange<uint32_t>(0, 70);
    o.flags = in.ConsumeIntegralInRange<int>(0, 15) == 0 ? in.ConsumeIntegral<uint32_t>() : in.ConsumeIntegralInRange<uint32_t>(0, 3);
    if (in.ConsumeIntegralInRange<int>(0, 7) == 0) {
        o.sah_traversal_cost = fuzz::pick_float(in);
        o.sah_intersection_cost = fuzz::pick_float(in);
        o.sah_empty_bonus = fuzz::pick_float(in);
    }
    return o;
}

// An entry's type as an int: it may be no kdrt_geometry_type at all.
int type_of(const kdrt_geometry &g) {
    int type;
    static_assert(sizeof type == sizeof g.type, "kdrt_geometry_type is an int");
    std::memcpy(&type, &g.type, sizeof type);
    return type;
}

// The faults an entry may have of its own, as kdrt_scene_build() and kdrt_scene_attach() check
// it (0: it may pass).
std::set<int> own_faults(const kdrt_geometry &g) {
    std::set<int> f;
    if (g.id == KDRT_INVALID_ID) return std::set<int>{KDRT_ERROR_INVALID_GEOMETRY_ID};
    if (type_of(g) == KDRT_GEOMETRY_MESH) {
        const kdrt_triangles &v = g.mesh;
        if (v.position_stride != 0 && v.position_stride < 12) f.insert(KDRT_ERROR_INVALID_STRIDE);
        else if (v.triangle_count == 0) f.insert(0);
        else if (v.triangle_count > KDRT_MAX_TRIANGLES) f.insert(KDRT_ERROR_SIZE_OVERFLOW);
        else if (!v.positions) f.insert(KDRT_ERROR_NULL_ARGUMENT);
        else f.insert(0);
    } else if (type_of(g) == KDRT_GEOMETRY_INSTANCE) {
        if (!g.tree) return std::set<int>{KDRT_ERROR_NULL_ARGUMENT};
        const int must = refuses(g.tree, g.transform);
        if (must != 0) f.insert(KDRT_ERROR_INVALID_TRANSFORM);
        if (must != 1) f.insert(0);
    } else {
        f.insert(KDRT_ERROR_INVALID_OPTION);
    }
    return f;
}

// ---- what the scene holds, as the target expects it ----

struct Entry {
    kdrt_geometry given{};
    uint32_t triangles = 0;  // the mesh's, or the instance's tree's
    float committed[12] = {}, pending[12] = {};
    bool disabled = false;
};

struct Model {
    std::map<uint32_t, Entry> entries;  // by ID, as committed
    std::map<uint32_t, Entry> next;     // by ID, as the next commit will make them
    const Entry *find(uint32_t id) const {
        const auto it = entries.find(id);
        return it == entries.end() ? nullptr : &it->second;
    }
};

uint32_t triangles_of_tree(const kdrt_tree *tree) {
    if (!tree) return 0;
    for (const Object &o : objects())
        if (o.tree == tree) return o.triangles;
    return 0;  // set by the caller for the input's own tree
}

std::string describe_ray(const kdrt_ray &ray) {
    char s[256];
    std::snprintf(s, sizeof s, "ray org=(%a, %a, %a) dir=(%a, %a, %a) tmin=%a tmax=%a\n", ray.org[0], ray.org[1], ray.org[2],
                  ray.dir[0], ray.dir[1], ray.dir[2], ray.tmin, ray.tmax);
    return s;
}

std::string show(const kdrt_hit &h) {
    char s[200];
    std::snprintf(s, sizeof s, "geometry %u instance %d triangle %u t=%a u=%a v=%a", h.geometry,
                  h.instance == KDRT_INVALID_ID ? -1 : int(h.instance), h.triangle, h.t, h.u, h.v);
    return s;
}

std::string describe_transform(const float *m) {
    char s[400];
    std::snprintf(s, sizeof s, "[%a %a %a %a / %a %a %a %a / %a %a %a %a]", m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9],
                  m[10], m[11]);
    return s;
}

// The scene as the target sees it, printed with a failed check.
std::string describe(const Model &model, const kdrt_tree *own_tree) {
    std::string text = "the scene:\n";
    char s[200];
    for (const auto &kv : model.entries) {
        const Entry &e = kv.second;
        if (e.given.type == KDRT_GEOMETRY_INSTANCE) {
            const char *name = e.given.tree == own_tree ? "the input's own tree" : "?";
            for (const Object &o : objects())
                if (o.tree == e.given.tree) name = o.name;
            std::snprintf(s, sizeof s, "  instance %u, mask %#x, of %s: ", kv.first, e.given.mask, name);
            text += s + describe_transform(e.committed) + "\n";
        } else {
            const kdrt_triangles &v = e.given.mesh;
            std::snprintf(s, sizeof s, "  mesh %u, mask %#x, %u triangles%s, stride %zu:", kv.first, e.given.mask, v.triangle_count,
                          v.indices ? " (indexed)" : "", v.position_stride);
            text += s;
            const size_t step = v.position_stride ? v.position_stride : 12;
            for (uint32_t i = 0; i < v.vertex_count && v.positions; ++i) {
                float p[3];
                std::memcpy(p, reinterpret_cast<const unsigned char *>(v.positions) + i * step, sizeof p);
                std::snprintf(s, sizeof s, " (%a, %a, %a)", p[0], p[1], p[2]);
                text += s;
            }
            for (uint32_t i = 0; v.indices && i < 3 * v.triangle_count; ++i) text += (i ? " " : " indices ") + std::to_string(v.indices[i]);
            text += "\n";
        }
    }
    return text;
}

bool same_hit(const kdrt_hit &a, const kdrt_hit &b) {
    return a.triangle == b.triangle && a.geometry == b.geometry && a.instance == b.instance &&
           std::memcmp(&a.t, &b.t, sizeof a.t) == 0 && std::memcmp(&a.u, &b.u, sizeof a.u) == 0 &&
           std::memcmp(&a.v, &b.v, sizeof a.v) == 0;
}

bool before(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.t != b.t) return a.t < b.t;
    if (a.geometry != b.geometry) return a.geometry < b.geometry;
    return a.triangle < b.triangle;
}

bool in_box(const kdrt_aabb &b, const float p[3]) {
    for (int a = 0; a < 3; ++a)
        if (!(p[a] >= b.min[a] && p[a] <= b.max[a])) return false;
    return true;
}

// A hit (or a filter's candidate) as kdrt.h describes one, for a query of this mask.
void check_names(const Model &model, const kdrt_ray &ray, const kdrt_hit &h, uint32_t mask, const char *what) {
    FUZZ_CHECK(std::isfinite(h.t) && h.t >= std::max(ray.tmin, 0.0f) && h.t <= ray.tmax, "%s: t=%a outside [%a, %a]", what, h.t,
               ray.tmin, ray.tmax);
    FUZZ_CHECK(std::isfinite(h.u) && std::isfinite(h.v), "%s: u=%a v=%a", what, h.u, h.v);
    const Entry *e = model.find(h.geometry);
    FUZZ_CHECK(e != nullptr, "%s: geometry %u is not in the scene", what, h.geometry);
    FUZZ_CHECK(!e->disabled, "%s: geometry %u is disabled", what, h.geometry);
    const bool instance = e->given.type == KDRT_GEOMETRY_INSTANCE;
    FUZZ_CHECK(instance ? h.instance == h.geometry : h.instance == KDRT_INVALID_ID, "%s: geometry %u (%s), instance %u", what,
               h.geometry, instance ? "an instance" : "a mesh", h.instance);
    FUZZ_CHECK((e->given.mask & mask) != 0, "%s: geometry %u of mask %#x, query mask %#x", what, h.geometry, e->given.mask, mask);
    FUZZ_CHECK(h.triangle < e->triangles, "%s: triangle %u of geometry %u, which has %u", what, h.triangle, h.geometry, e->triangles);
}

// ---- the filter ----

struct Filter {
    int kind = 0;  // 1 takes every candidate, 2 refuses every one, 3 takes some, 4 takes some after a query of its own
    const Model *model = nullptr;
    const kdrt_scene *scene = nullptr;
    kdrt_ray ray{};
    uint32_t mask = 0;
    size_t calls = 0;
    static int call(void *user, const kdrt_ray *ray, const kdrt_hit *c) {
        Filter &f = *static_cast<Filter *>(user);
        ++f.calls;
        FUZZ_CHECK(ray && std::memcmp(ray, &f.ray, sizeof f.ray) == 0, "the filter was shown another ray");
        FUZZ_CHECK(c != nullptr, "no candidate");
        check_names(*f.model, f.ray, *c, f.mask, "a filter's candidate");
        if (f.kind == 1) return 1;
        if (f.kind == 2) return 0;
        if (f.kind == 4) {
            // kdrt.h allows a filter to query the scene it filters.
            kdrt_hit inner;
            const int found = kdrt_scene_intersect(f.scene, ray, nullptr, &inner);
            FUZZ_CHECK(found == kdrt_scene_occluded(f.scene, ray, nullptr), "a filter's own queries disagree");
        }
        const uint32_t x = (c->geometry * 0x9E3779B1u) ^ (c->triangle * 0x85EBCA77u);
        return int((x >> 7) & 1u);
    }
};

// ---- one input ----

struct Run {
    FuzzedDataProvider &in;
    Heap heap;
    bool counted = false;
    Model model;
    kdrt_scene *scene = nullptr;
    std::vector<float> targets;  // world points rays are aimed at
    kdrt_tree *own_tree = nullptr;
    uint32_t own_triangles = 0;
    bool fast = false;  // the scene's meshes use KDRT_INTERSECTOR_FAST
    bool meshes_changed = false;  // since the last commit: its mesh tree is rebuilt
    std::vector<std::unique_ptr<MeshInput>> attached;  // the attached meshes' buffers
    explicit Run(FuzzedDataProvider &i) : in(i) {}

    uint32_t triangles_of(const kdrt_tree *tree) const { return tree && tree == own_tree ? own_triangles : triangles_of_tree(tree); }

    void check_geometry() const {
        for (const auto &kv : model.entries) {
            const Entry &e = kv.second;
            const kdrt_geometry *g = kdrt_scene_geometry(scene, kv.first);
            FUZZ_CHECK(g != nullptr, "kdrt_scene_geometry(%u) gave nothing", kv.first);
            FUZZ_CHECK(g->type == e.given.type && g->id == e.given.id && g->mask == e.given.mask && g->user == e.given.user,
                       "geometry %u came back changed", kv.first);
            FUZZ_CHECK(((g->flags & KDRT_GEOMETRY_DISABLED) != 0) == e.disabled, "geometry %u: flags %#x, disabled %d", kv.first,
                       g->flags, int(e.disabled));
            if (e.given.type == KDRT_GEOMETRY_MESH) {
                FUZZ_CHECK(std::memcmp(&g->mesh, &e.given.mesh, sizeof g->mesh) == 0, "mesh %u's view came back changed", kv.first);
            } else {
                FUZZ_CHECK(g->tree == e.given.tree, "instance %u's tree came back changed", kv.first);
                FUZZ_CHECK(std::memcmp(g->transform, e.committed, sizeof e.committed) == 0,
                           "instance %u: kdrt_scene_geometry's transform is not the committed one", kv.first);
            }
        }
        for (uint32_t id : {0u, 7u, 15u, 16u, KDRT_INVALID_ID})
            if (!model.find(id)) FUZZ_CHECK(kdrt_scene_geometry(scene, id) == nullptr, "kdrt_scene_geometry(%u) found something", id);
    }

    void check_bounds() const {
        const kdrt_aabb b = kdrt_scene_bounds(scene), empty = kdrt_aabb_empty();
        const bool is_empty = std::memcmp(&b, &empty, sizeof b) == 0;
        bool finite = true;
        for (int a = 0; a < 3; ++a) finite = finite && std::isfinite(b.min[a]) && std::isfinite(b.max[a]) && b.min[a] <= b.max[a];
        FUZZ_CHECK(is_empty || finite, "kdrt_scene_bounds: (%a, %a, %a) to (%a, %a, %a)", b.min[0], b.min[1], b.min[2], b.max[0],
                   b.max[1], b.max[2]);
        // Every instance's tree box, carried into the world, lies in it.
        for (const auto &kv : model.entries) {
            const Entry &e = kv.second;
            if (e.given.type != KDRT_GEOMETRY_INSTANCE) continue;
            const kdrt_aabb t = kdrt_tree_bounds(e.given.tree);
            if (!(t.min[0] <= t.max[0])) continue;
            for (int k = 0; k < 8; ++k) {
                const double c[3] = {k & 1 ? t.max[0] : t.min[0], k & 2 ? t.max[1] : t.min[1], k & 4 ? t.max[2] : t.min[2]};
                for (int a = 0; a < 3; ++a) {
                    const float *m = &e.committed[4 * a];
                    const double x = m[0] * c[0] + m[1] * c[1] + m[2] * c[2] + m[3];
                    FUZZ_CHECK(x >= b.min[a] && x <= b.max[a], "instance %u's box reaches %.9g on axis %d, beyond the scene's [%a, %a]",
                               kv.first, x, a, b.min[a], b.max[a]);
                }
            }
        }
    }

    // The world points rays are aimed at: the meshes' finite vertices and the instances' box centres.
    void gather_targets() {
        targets.clear();
        for (const auto &kv : model.entries) {
            const Entry &e = kv.second;
            if (e.given.type == KDRT_GEOMETRY_MESH) {
                const kdrt_triangles &v = e.given.mesh;
                if (!v.positions) continue;
                const size_t step = v.position_stride ? v.position_stride : 12;
                for (uint32_t i = 0; i < v.vertex_count && i < 9; ++i) {
                    float p[3];
                    std::memcpy(p, reinterpret_cast<const unsigned char *>(v.positions) + i * step, sizeof p);
                    if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) targets.insert(targets.end(), p, p + 3);
                }
            } else {
                const kdrt_aabb t = kdrt_tree_bounds(e.given.tree);
                if (!(t.min[0] <= t.max[0])) continue;
                for (int a = 0; a < 3; ++a) {
                    const float *m = &e.committed[4 * a];
                    double x = m[3];
                    for (int j = 0; j < 3; ++j) x += m[j] * 0.5 * (double(t.min[j]) + t.max[j]);
                    targets.push_back(float(x));
                }
            }
        }
    }

    kdrt_ray make_ray() {
        kdrt_ray r;
        for (float &x : r.org) x = fuzz::pick_float(in);
        if (!targets.empty() && in.ConsumeBool()) {
            const size_t k = in.ConsumeIntegralInRange<size_t>(0, targets.size() / 3 - 1);
            for (int a = 0; a < 3; ++a) r.dir[a] = targets[3 * k + a] - r.org[a];
        } else {
            for (float &x : r.dir) x = fuzz::pick_float(in);
        }
        r.tmin = in.ConsumeBool() ? 0.0f : fuzz::pick_float(in);
        r.tmax = in.ConsumeBool() ? INFINITY : fuzz::pick_float(in);
        return r;
    }

    // A hit kdrt_scene_hit_surface() and kdrt_scene_spawn_ray() must take.
    void check_surface(const kdrt_ray &ray, const kdrt_hit &h) const {
        float point[3], normal[3];
        FUZZ_CHECK(kdrt_scene_hit_surface(scene, &h, point, normal) == 1, "kdrt_scene_hit_surface refused a hit");
        FUZZ_CHECK(in_box(kdrt_scene_bounds(scene), point), "the hit point (%a, %a, %a) lies outside the scene's box", point[0],
                   point[1], point[2]);
        const double length = std::sqrt(double(normal[0]) * normal[0] + double(normal[1]) * normal[1] + double(normal[2]) * normal[2]);
        FUZZ_CHECK(std::fabs(length - 1) < 1e-6,
                   "normal (%a, %a, %a) of length %g", normal[0], normal[1], normal[2], length);
        kdrt_ray next;
        FUZZ_CHECK(kdrt_scene_spawn_ray(scene, &h, ray.dir, &next) == 1, "kdrt_scene_spawn_ray refused a hit");
        FUZZ_CHECK(std::isfinite(next.org[0]) && std::isfinite(next.org[1]) && std::isfinite(next.org[2]) && next.tmin == 0 &&
                       next.tmax == INFINITY,
                   "spawned ray org=(%a, %a, %a) tmin=%a tmax=%a", next.org[0], next.org[1], next.org[2], next.tmin, next.tmax);
        // The same hit naming what is not there.
        kdrt_hit bad = h;
        bad.triangle = model.find(h.geometry)->triangles;
        FUZZ_CHECK(kdrt_scene_hit_surface(scene, &bad, point, normal) == 0, "kdrt_scene_hit_surface took triangle %u", bad.triangle);
        bad = h;
        bad.instance = h.instance == KDRT_INVALID_ID ? h.geometry : KDRT_INVALID_ID;
        FUZZ_CHECK(kdrt_scene_hit_surface(scene, &bad, point, normal) == 0, "kdrt_scene_hit_surface took a hit with instance %u",
                   bad.instance);
        FUZZ_CHECK(kdrt_scene_spawn_ray(scene, &bad, ray.dir, &next) == 0, "kdrt_scene_spawn_ray took a hit with instance %u",
                   bad.instance);
    }

    void query_once() {
        const kdrt_ray ray = make_ray();
        char line[160];
        Filter filter;
        filter.model = &model, filter.scene = scene, filter.ray = ray;
        kdrt_query q = kdrt_default_query();
        const bool null_query = in.ConsumeIntegralInRange<int>(0, 7) == 0;
        if (!null_query) {
            if (in.ConsumeBool()) q.mask = pick_mask(in);
            q.flags = in.ConsumeIntegralInRange<uint32_t>(0, 3);
            filter.kind = in.ConsumeIntegralInRange<int>(0, 4);
            if (filter.kind) q.filter = &Filter::call, q.user = &filter;
        }
        filter.mask = q.mask;
        std::snprintf(line, sizeof line, "query: %s, mask %#x, flags %u, filter %d\n", null_query ? "NULL" : "given", q.mask, q.flags,
                      filter.kind);
        fuzz::context() = describe(model, own_tree) + line + describe_ray(ray);
        const kdrt_query *query = null_query ? nullptr : &q;
        const size_t calls = heap.calls, live = heap.live;

        kdrt_hit hit;
        const int found = kdrt_scene_intersect(scene, &ray, query, &hit);
        FUZZ_CHECK(found == (hit.triangle != KDRT_INVALID_ID), "found %d, triangle %u", found, hit.triangle);
        if (found) check_names(model, ray, hit, q.mask, "the nearest hit");
        FUZZ_CHECK(kdrt_scene_occluded(scene, &ray, query) == found, "kdrt_scene_occluded disagrees with kdrt_scene_intersect (%d)",
                   found);
        const uint32_t capacity = in.ConsumeIntegralInRange<uint32_t>(1, 9);
        std::vector<kdrt_hit> k(capacity + 1);
        k[capacity].triangle = 12345;
        const uint32_t n = kdrt_scene_intersect_k(scene, &ray, query, k.data(), capacity);
        FUZZ_CHECK(n <= capacity && k[capacity].triangle == 12345, "kdrt_scene_intersect_k: %u hits, capacity %u", n, capacity);
        FUZZ_CHECK((n > 0) == (found != 0), "kdrt_scene_intersect_k found %u, kdrt_scene_intersect %d", n, found);
        for (uint32_t i = 0; i < n; ++i) {
            check_names(model, ray, k[i], q.mask, "a k-nearest hit");
            if (i > 0) FUZZ_CHECK(before(k[i - 1], k[i]), "k-nearest hits %u and %u out of order (or repeated)", i - 1, i);
        }
        // The first of the k nearest is the nearest hit, bit for bit, but for kdrt.h's one
        // exception (QUERIES AND GUARANTEES): a triangle the ray misses by less than the test's
        // rounding error but still "hits", at its edge, can lie where the nearest hit's walk,
        // bounded by its best hit so far, never looks; the k nearest walk looks farther. The fast
        // test's answers are not defined beyond lengths of about 1e-9 to 1e12, which any floats
        // reach: they need not agree.
        if (n > 0 && !fast && !same_hit(k[0], hit)) {
            const double edge = std::min({double(k[0].u), double(k[0].v), 1.0 - k[0].u - k[0].v});
            FUZZ_CHECK(before(k[0], hit) && edge <= 1e-5, "the first of the k nearest, %s, is not the nearest hit, %s", show(k[0]).c_str(),
                       show(hit).c_str());
        }
        if ((filter.kind == 2) || (query && q.mask == 0) || q.flags == 3)
            FUZZ_CHECK(!found && n == 0, "a query that takes nothing hit geometry %u", hit.geometry);
        FUZZ_CHECK(heap.calls == calls && heap.live == live, "a query allocated");
        if (found) check_surface(ray, hit);
        fuzz::context().clear();
    }

    // Any ID: an instance's, a mesh's, one not in the scene (as the next commit makes it).
    uint32_t pick_next_id() {
        if (!model.next.empty() && in.ConsumeIntegralInRange<int>(0, 3) != 0) {
            auto it = model.next.begin();
            std::advance(it, in.ConsumeIntegralInRange<size_t>(0, model.next.size() - 1));
            return it->first;
        }
        return in.ConsumeIntegralInRange<int>(0, 15) == 0 ? KDRT_INVALID_ID : in.ConsumeIntegralInRange<uint32_t>(0, 20);
    }
    // kdrt_scene_attach() of a mesh or an instance made as the build's entries are.
    void attach_once() {
        const uint32_t id = pick_next_id();
        kdrt_geometry g;
        if (in.ConsumeBool()) {
            attached.emplace_back(new MeshInput);
            make_mesh(in, *attached.back());
            g = kdrt_mesh_geometry(id, &attached.back()->view);
        } else {
            const int t = in.ConsumeIntegralInRange<int>(0, 8);
            float xf[12];
            pick_transform(in, xf);
            g = kdrt_instance_geometry(id, t < 7 ? objects()[size_t(t)].tree : t == 7 ? own_tree : nullptr, xf);
        }
        if (in.ConsumeBool()) g.mask = pick_mask(in);
        if (in.ConsumeIntegralInRange<int>(0, 7) == 0) g.flags = in.ConsumeIntegralInRange<uint32_t>(0, 3);
        const bool failed_before = heap.failed;
        const kdrt_result r = kdrt_scene_attach(scene, &g);
        std::set<int> may;
        if (id == KDRT_INVALID_ID) may = {KDRT_ERROR_INVALID_GEOMETRY_ID};
        else if (g.flags > 1) may = {KDRT_ERROR_INVALID_OPTION};
        else may = own_faults(g);
        if (may.erase(0)) may.insert(model.next.count(id) ? KDRT_ERROR_INVALID_GEOMETRY_ID : KDRT_SUCCESS);
        if (r == KDRT_ERROR_OUT_OF_MEMORY && may.count(KDRT_SUCCESS))  // growing the pending entries
            FUZZ_CHECK(heap.failed && !failed_before, "kdrt_scene_attach(%u) ran out of memory that did not run out", id);
        else
            FUZZ_CHECK(may.count(r) != 0, "kdrt_scene_attach(%u): %s", id, kdrt_result_string(r));
        if (r == KDRT_SUCCESS) {
            Entry e;
            e.given = g;
            e.triangles = g.type == KDRT_GEOMETRY_MESH ? g.mesh.triangle_count : triangles_of(g.tree);
            std::memcpy(e.pending, g.transform, sizeof e.pending);
            e.disabled = g.flags != 0;
            model.next[id] = e;
            meshes_changed |= g.type == KDRT_GEOMETRY_MESH;
        }
        check_geometry();  // nothing is applied before the commit
    }
    void detach_once() {
        const uint32_t id = pick_next_id();
        const auto e = model.next.find(id);
        const kdrt_result r = kdrt_scene_detach(scene, id);
        FUZZ_CHECK(r == (e == model.next.end() ? KDRT_ERROR_INVALID_GEOMETRY_ID : KDRT_SUCCESS), "kdrt_scene_detach(%u): %s", id,
                   kdrt_result_string(r));
        if (r == KDRT_SUCCESS) {
            meshes_changed |= e->second.given.type == KDRT_GEOMETRY_MESH;
            model.next.erase(e);
        }
        check_geometry();
    }
    void enable_once() {
        const uint32_t id = pick_next_id();
        const bool enable = in.ConsumeBool();
        const auto e = model.next.find(id);
        const kdrt_result r = kdrt_scene_enable(scene, id, enable);
        FUZZ_CHECK(r == (e == model.next.end() ? KDRT_ERROR_INVALID_GEOMETRY_ID : KDRT_SUCCESS), "kdrt_scene_enable(%u): %s", id,
                   kdrt_result_string(r));
        if (r == KDRT_SUCCESS) e->second.disabled = !enable;
        check_geometry();
    }
    void set_transform_once() {
        const uint32_t id = pick_next_id();
        float xf[12];
        pick_transform(in, xf);
        const bool null = in.ConsumeIntegralInRange<int>(0, 31) == 0;
        const auto e = model.next.find(id);
        const kdrt_result r = kdrt_scene_set_transform(scene, id, null ? nullptr : xf);
        if (null) {
            FUZZ_CHECK(r == KDRT_ERROR_NULL_ARGUMENT, "kdrt_scene_set_transform(NULL): %s", kdrt_result_string(r));
        } else if (e == model.next.end() || e->second.given.type != KDRT_GEOMETRY_INSTANCE) {
            FUZZ_CHECK(r == KDRT_ERROR_INVALID_GEOMETRY_ID, "kdrt_scene_set_transform(%u), no instance: %s", id, kdrt_result_string(r));
        } else {
            const int must = refuses(e->second.given.tree, xf);
            FUZZ_CHECK(r == KDRT_SUCCESS || r == KDRT_ERROR_INVALID_TRANSFORM, "kdrt_scene_set_transform(%u): %s", id, kdrt_result_string(r));
            FUZZ_CHECK(must == -1 || (r == KDRT_ERROR_INVALID_TRANSFORM) == (must == 1),
                       "kdrt_scene_set_transform(%u): %s where it %s (%a %a %a %a / %a %a %a %a / %a %a %a %a)", id, kdrt_result_string(r),
                       must ? "must refuse" : "must not", xf[0], xf[1], xf[2], xf[3], xf[4], xf[5], xf[6], xf[7], xf[8], xf[9], xf[10],
                       xf[11]);
            if (r == KDRT_SUCCESS) std::memcpy(e->second.pending, xf, sizeof xf);
        }
        check_geometry();  // nothing is applied before the commit
    }

    void commit_once() {
        const bool failed_before = heap.failed;
        const kdrt_result r = kdrt_scene_commit(scene);
        if (r == KDRT_ERROR_OUT_OF_MEMORY) {
            FUZZ_CHECK(heap.failed && !failed_before, "kdrt_scene_commit ran out of memory that did not run out");
        } else if (r != KDRT_SUCCESS) {
            // Only a rebuilt mesh tree may fail otherwise, as a tree over bad triangles does.
            FUZZ_CHECK(meshes_changed && (r == KDRT_ERROR_NON_FINITE_VERTEX || r == KDRT_ERROR_INDEX_OUT_OF_RANGE),
                       "kdrt_scene_commit: %s", kdrt_result_string(r));
        } else {
            model.entries = model.next;
            for (auto &kv : model.entries) std::memcpy(kv.second.committed, kv.second.pending, sizeof kv.second.pending);
            meshes_changed = false;
        }
        // Failed or not, the pending changes are the next commit's.
        check_geometry();
        check_bounds();
        gather_targets();
    }
};

// The outcomes a build may have: a result and the geometry its report names.
using Outcomes = std::set<std::pair<int, uint32_t>>;

std::string show(const Outcomes &o) {
    std::string s;
    for (const auto &x : o) s += std::string(s.empty() ? "" : ", ") + kdrt_result_string(kdrt_result(x.first)) + " at " + std::to_string(x.second);
    return s;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int *, char ***) {
    objects();
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    FuzzedDataProvider in(data, size);
    fuzz::context().clear();
    Run run(in);
    Heap &heap = run.heap;

    kdrt_build_options options = make_options(in);
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
    case 0: break;  // KDRT_MALLOC
    case 1: heap.fail_at = in.ConsumeIntegralInRange<size_t>(1, 40); [[fallthrough]];
    default: options.allocator = kdrt_allocator{&Heap::alloc, &Heap::free, &heap}, run.counted = true;
    }

    // The input's own tree, of any floats (its bad triangles skipped).
    MeshInput own_mesh;
    if (in.ConsumeBool()) {
        make_mesh(in, own_mesh);
        if (own_mesh.view.triangle_count <= 6 && own_mesh.view.positions) {
            kdrt_build_options o = kdrt_default_build_options();
            o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
            if (kdrt_tree_build(&own_mesh.view, &o, &run.own_tree, nullptr) == KDRT_SUCCESS)
                run.own_triangles = own_mesh.view.triangle_count;
        }
    }

    // The entries.
    const uint32_t count = in.ConsumeIntegralInRange<uint32_t>(0, 8);
    std::vector<kdrt_geometry> entries;
    std::vector<std::unique_ptr<MeshInput>> meshes;
    static int user_tags[8];
    for (uint32_t i = 0; i < count; ++i) {
        const int kind = in.ConsumeIntegralInRange<int>(0, 15);
        const uint32_t id = pick_id(in, entries);
        kdrt_geometry g;
        if (kind < 7) {
            meshes.emplace_back(new MeshInput);
            make_mesh(in, *meshes.back());
            g = kdrt_mesh_geometry(id, &meshes.back()->view);
        } else {
            const int t = in.ConsumeIntegralInRange<int>(0, 8);
            const kdrt_tree *tree = t < 7 ? objects()[size_t(t)].tree : t == 7 ? run.own_tree : nullptr;
            float xf[12];
            pick_transform(in, xf);
            g = kdrt_instance_geometry(id, tree, in.ConsumeIntegralInRange<int>(0, 15) == 0 ? nullptr : xf);
            if (kind == 15) {  // no known type, as a C caller may write it (C++ may not name it)
                const int type = in.ConsumeBool() ? 2 : -1;
                std::memcpy(&g.type, &type, sizeof type);
            }
        }
        if (in.ConsumeBool()) g.mask = pick_mask(in);
        g.user = &user_tags[i];
        entries.push_back(g);
    }
    const bool null_entries = count > 0 && in.ConsumeIntegralInRange<int>(0, 31) == 0;

    // What the build may answer. The options are checked first, as kdrt_tree_build() checks them.
    Outcomes expected;
    bool may_build = false;  // the entries may all pass
    kdrt_build_report merged_report{};
    kdrt_result merged_result = KDRT_SUCCESS;
    std::vector<std::pair<uint32_t, uint32_t>> merged_first;  // (first merged triangle, ID) per mesh
    {
        kdrt_build_options probe = options;
        if (run.counted) probe.allocator = kdrt_allocator{};
        const kdrt_triangles none{};
        kdrt_tree *t = nullptr;
        const kdrt_result r = kdrt_tree_build(&none, &probe, &t, nullptr);
        kdrt_tree_free(t);
        if (null_entries) {
            expected.insert({KDRT_ERROR_NULL_ARGUMENT, KDRT_INVALID_ID});
        } else if (r != KDRT_SUCCESS) {
            expected.insert({r, KDRT_INVALID_ID});
        } else {
            // Each ID in ascending order: an entry's own fault, and a repeated ID once the first
            // of the repeats (either) has passed.
            std::vector<const kdrt_geometry *> sorted;
            for (const kdrt_geometry &g : entries) sorted.push_back(&g);
            std::stable_sort(sorted.begin(), sorted.end(), [](const kdrt_geometry *a, const kdrt_geometry *b) { return a->id < b->id; });
            auto own = own_faults;
            may_build = true;
            for (size_t i = 0; i < sorted.size() && may_build;) {
                size_t j = i + 1;
                while (j < sorted.size() && sorted[j]->id == sorted[i]->id) ++j;
                const uint32_t id = sorted[i]->id;
                if (j - i > 1 || id == KDRT_INVALID_ID) {
                    for (size_t k = i; k < j; ++k)
                        for (int f : own(*sorted[k]))
                            if (f) expected.insert({f, id});
                    expected.insert({KDRT_ERROR_INVALID_GEOMETRY_ID, id});
                    may_build = false;
                } else {
                    const std::set<int> f = own(*sorted[i]);
                    for (int x : f)
                        if (x) expected.insert({x, id});
                    may_build = f.count(0) != 0;
                }
                i = j;
            }
            if (may_build) {
                // The meshes merged in ID order into one indexed mesh, bad triangles kept bad: the
                // scene's mesh tree must fail where a tree over it fails.
                std::vector<float> positions;
                std::vector<uint32_t> indices;
                for (const kdrt_geometry *g : sorted) {
                    if (type_of(*g) != KDRT_GEOMETRY_MESH) continue;
                    const kdrt_triangles &v = g->mesh;
                    merged_first.push_back({uint32_t(indices.size() / 3), g->id});
                    if (v.triangle_count == 0) continue;
                    const size_t step = v.position_stride ? v.position_stride : 12;
                    const uint32_t base = uint32_t(positions.size() / 3);
                    for (uint32_t k = 0; k < v.vertex_count; ++k) {
                        float p[3];
                        std::memcpy(p, reinterpret_cast<const unsigned char *>(v.positions) + k * step, sizeof p);
                        positions.insert(positions.end(), p, p + 3);
                    }
                    for (uint32_t t = 0; t < v.triangle_count; ++t)
                        for (uint32_t c = 0; c < 3; ++c) {
                            const uint64_t x = v.indices ? v.indices[3 * t + c] : uint64_t(3) * t + c;
                            // A soup's triangle runs past the end when its last corner does.
                            const bool out = v.indices ? x >= v.vertex_count : uint64_t(3) * t + 2 >= v.vertex_count;
                            indices.push_back(out ? KDRT_INVALID_ID : base + uint32_t(x));
                        }
                }
                kdrt_triangles merged{};
                merged.positions = positions.empty() ? nullptr : positions.data();
                merged.vertex_count = uint32_t(positions.size() / 3);
                merged.indices = indices.empty() ? nullptr : indices.data();
                merged.triangle_count = uint32_t(indices.size() / 3);
                kdrt_tree *t2 = nullptr;
                merged_result = kdrt_tree_build(&merged, &probe, &t2, &merged_report);
                kdrt_tree_free(t2);
                // The report names the mesh holding the first bad triangle and the triangle within
                // it, whether the build fails there or skips it.
                uint32_t geometry = KDRT_INVALID_ID;
                if (merged_report.invalid_triangle != KDRT_INVALID_ID) {
                    size_t p = 0;
                    while (p + 1 < merged_first.size() && merged_first[p + 1].first <= merged_report.invalid_triangle) ++p;
                    geometry = merged_first[p].second;
                    merged_report.invalid_triangle -= merged_first[p].first;
                }
                merged_report.invalid_geometry = geometry;
                expected.insert({merged_result, geometry});
            }
        }
    }

    kdrt_scene *scene = reinterpret_cast<kdrt_scene *>(&heap);  // a failed build must set it to NULL
    kdrt_build_report report;
    const kdrt_result result = kdrt_scene_build(null_entries ? nullptr : entries.data(), count, &options, &scene, &report);
    FUZZ_CHECK((result == KDRT_SUCCESS) == (scene != nullptr), "%s with scene %p", kdrt_result_string(result), static_cast<void *>(scene));
    if (result != KDRT_SUCCESS) FUZZ_CHECK(heap.live == 0, "a refused build (%s) left %zu blocks allocated", kdrt_result_string(result), heap.live);
    if (result == KDRT_ERROR_OUT_OF_MEMORY) {
        FUZZ_CHECK(heap.failed, "out of memory without running out");
    } else {
        FUZZ_CHECK(expected.count({result, report.invalid_geometry}) != 0, "kdrt_scene_build: %s at geometry %u; expected %s",
                   kdrt_result_string(result), report.invalid_geometry, show(expected).c_str());
        if (may_build && result == merged_result)
            FUZZ_CHECK(report.invalid_triangle == merged_report.invalid_triangle, "report: triangle %u of geometry %u; expected %u of %u",
                       report.invalid_triangle, report.invalid_geometry, merged_report.invalid_triangle, merged_report.invalid_geometry);
        else
            FUZZ_CHECK(report.invalid_triangle == KDRT_INVALID_ID, "%s names triangle %u", kdrt_result_string(result), report.invalid_triangle);
        if (result == KDRT_SUCCESS)
            FUZZ_CHECK(report.skipped_triangles == merged_report.skipped_triangles &&
                           report.degenerate_triangles == merged_report.degenerate_triangles,
                       "skipped %u, degenerate %u; one tree of the meshes: %u, %u", report.skipped_triangles, report.degenerate_triangles,
                       merged_report.skipped_triangles, merged_report.degenerate_triangles);
    }

    if (scene) {
        run.scene = scene;
        run.fast = options.intersector == KDRT_INTERSECTOR_FAST;
        for (const kdrt_geometry &g : entries) {
            Entry e;
            e.given = g;
            e.triangles = g.type == KDRT_GEOMETRY_MESH ? g.mesh.triangle_count : run.triangles_of(g.tree);
            std::memcpy(e.committed, g.transform, sizeof e.committed);
            std::memcpy(e.pending, g.transform, sizeof e.pending);
            run.model.entries[g.id] = e;
        }
        run.model.next = run.model.entries;
        run.check_geometry();
        run.check_bounds();
        run.gather_targets();
        const int ops = in.ConsumeIntegralInRange<int>(1, 24);
        for (int i = 0; i < ops; ++i) {
            switch (in.ConsumeIntegralInRange<int>(0, 10)) {
            case 0: run.set_transform_once(); break;
            case 1: run.commit_once(); break;
            case 2: run.attach_once(); break;
            case 3: run.detach_once(); break;
            case 4: run.enable_once(); break;
            default: run.query_once();
            }
        }
        // NULL arguments.
        kdrt_hit h;
        kdrt_ray r{};
        FUZZ_CHECK(kdrt_scene_intersect(nullptr, &r, nullptr, &h) == 0 && h.triangle == KDRT_INVALID_ID, "NULL scene");
        FUZZ_CHECK(kdrt_scene_intersect(scene, nullptr, nullptr, &h) == 0 && h.triangle == KDRT_INVALID_ID, "NULL ray");
        FUZZ_CHECK(kdrt_scene_occluded(scene, nullptr, nullptr) == 0 && kdrt_scene_intersect_k(scene, &r, nullptr, nullptr, 4) == 0 &&
                       kdrt_scene_intersect_k(scene, &r, nullptr, &h, 0) == 0 && kdrt_scene_hit_surface(scene, nullptr, nullptr, nullptr) == 0,
                   "NULL arguments");
        kdrt_scene_free(scene);
    }
    kdrt_tree_free(run.own_tree);
    FUZZ_CHECK(heap.live == 0, "kdrt_scene_free left %zu blocks", heap.live);
    return 0;
}
