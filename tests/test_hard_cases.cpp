// Hard placements: axis-parallel rays, rays in split planes, rays starting on triangles,
// triangles in split planes, identical, coplanar and degenerate triangles, strided and unaligned
// vertex buffers, the tree's statistics and bytes, the deepest tree, the original's early-exit bug
// and scenes far from the origin. Every tree (leaf sizes 1..64) must answer bit for bit as
// max_leaf_size = 0 (test every triangle) does, which the header guarantees; that answer is
// checked against the double-precision oracle or against hand-computed hits.
//
// Real split planes come from a model of the median build described in kdrt.h (THE TREE); the
// model's node, leaf, reference and depth counts are required to equal the library's, so the
// planes it lists are the tree's.
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace {

using kt::kLeafSizes;
using kt::ray_of;
using kt::same_hit;

const float kInf = std::numeric_limits<float>::infinity();

std::string describe(const kdrt_ray &r) {
    std::ostringstream s;
    s.precision(9);
    s << "org=(" << r.org[0] << "," << r.org[1] << "," << r.org[2] << ") dir=(" << (std::signbit(r.dir[0]) ? "-" : "+")
      << std::fabs(r.dir[0]) << "," << (std::signbit(r.dir[1]) ? "-" : "+") << std::fabs(r.dir[1]) << ","
      << (std::signbit(r.dir[2]) ? "-" : "+") << std::fabs(r.dir[2]) << ") tmin=" << r.tmin << " tmax=" << r.tmax;
    return s.str();
}

std::string describe(const kdrt_hit &h) {
    std::ostringstream s;
    s.precision(9);
    if (h.triangle == KDRT_INVALID_ID) return "miss";
    s << "triangle " << h.triangle << " t=" << h.t << " u=" << h.u << " v=" << h.v;
    return s.str();
}

kt::TreePtr build_view(const kdrt_triangles &view, uint32_t leaf, uint32_t max_depth = 0) {
    kdrt_build_options o = kdrt_default_build_options();
    o.builder = KDRT_BUILDER_MEDIAN;  // the cases below are shaped around its splits
    o.max_leaf_size = leaf;
    o.max_depth = max_depth;
    kdrt_tree *tree = nullptr;
    kdrt_result r = kdrt_tree_build(&view, &o, &tree, nullptr);
    INFO("leaf size " << leaf << " max_depth " << max_depth << ": " << kdrt_result_string(r));
    REQUIRE(r == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

kdrt_hit trace(const kdrt_tree *tree, const kdrt_ray &ray) {
    kdrt_hit h;
    kdrt_intersect(tree, &ray, &h);
    return h;
}

// A soup assembled triangle by triangle.
// A leaf's blocks of 8 triangles, which the SAH prices (kdrt.h's THE TREE).
double blocks(uint32_t n) { return double((n + 7) / 8); }

struct Soup {
    common::Mesh mesh;
    explicit Soup(const std::string &name) { mesh.name = name; }
    uint32_t add(const float a[3], const float b[3], const float c[3]) {
        for (const float *p : {a, b, c}) mesh.positions.insert(mesh.positions.end(), p, p + 3);
        return mesh.triangle_count() - 1;
    }
    uint32_t add(float ax, float ay, float az, float bx, float by, float bz, float cx, float cy, float cz) {
        const float a[3] = {ax, ay, az}, b[3] = {bx, by, bz}, c[3] = {cx, cy, cz};
        return add(a, b, c);
    }
};

// ---- a model of the median build (kdrt.h, THE TREE) ----

struct Plane {
    int axis;
    float split;
    bool operator<(const Plane &o) const { return axis != o.axis ? axis < o.axis : split < o.split; }
};

struct Model {
    uint32_t triangles = 0;  // kept: every triangle but the zero-area ones
    uint32_t nodes = 0, leaves = 0, depth = 0;
    uint64_t refs = 0;
    std::vector<Plane> planes;  // in build order; planes[0] is the root's
    double sah_cost = 0;        // kdrt_tree_stats.sah_cost, from the model's own node boxes
};

uint32_t default_depth(uint32_t n) {
    uint32_t log2n = 0;
    while ((n >> log2n) > 1u) ++log2n;
    return std::min<uint32_t>(8u + (13u * log2n + 5u) / 10u, KDRT_MAX_DEPTH);
}

class MedianModel {
public:
    // max_depth is used as given (no clamping), so the model shows how deep a tree would go.
    // The SAH cost is priced with the given costs (kdrt.h's defaults unless told).
    MedianModel(const common::Mesh &mesh, uint32_t leaf, uint32_t max_depth,
                double traversal_cost = KDRT_DEFAULT_SAH_TRAVERSAL_COST,
                double intersection_cost = KDRT_DEFAULT_SAH_INTERSECTION_COST)
        : leaf_(leaf), max_depth_(max_depth), traversal_cost_(traversal_cost), intersection_cost_(intersection_cost) {
        uint32_t n = mesh.triangle_count();
        lo_.resize(size_t(n) * 3), hi_.resize(size_t(n) * 3), c_.resize(size_t(n) * 3);
        std::vector<uint32_t> kept;  // zero-area triangles are left out of the tree
        for (uint32_t t = 0; t < n; ++t) {
            double pd[3][3];
            mesh.corners(t, pd);
            double e1[3], e2[3];
            for (int a = 0; a < 3; ++a) e1[a] = pd[1][a] - pd[0][a], e2[a] = pd[2][a] - pd[0][a];
            if (e1[1] * e2[2] - e1[2] * e2[1] != 0 || e1[2] * e2[0] - e1[0] * e2[2] != 0 || e1[0] * e2[1] - e1[1] * e2[0] != 0)
                kept.push_back(t);
            float p[3][3];
            for (int k = 0; k < 3; ++k)
                for (int a = 0; a < 3; ++a) p[k][a] = float(pd[k][a]);
            for (int a = 0; a < 3; ++a) {
                lo_[t * 3 + a] = std::min({p[0][a], p[1][a], p[2][a]});
                hi_[t * 3 + a] = std::max({p[0][a], p[1][a], p[2][a]});
                float sum = p[0][a] + p[1][a];
                sum = sum + p[2][a];
                float c = sum * (1.0f / 3.0f);
                c_[t * 3 + a] = std::min(std::max(c, lo_[t * 3 + a]), hi_[t * 3 + a]);  // kept within the corners
            }
        }
        n = model_.triangles = uint32_t(kept.size());
        if (leaf == 0 || n == 0) {
            model_.nodes = model_.leaves = 1, model_.refs = n;
            model_.sah_cost = intersection_cost * blocks(n);  // one leaf holding everything
            return;
        }
        // The root box: the kept triangles' boxes (what kdrt_tree_bounds() reports).
        Box root;
        for (int a = 0; a < 3; ++a) {
            root.lo[a] = std::numeric_limits<float>::infinity(), root.hi[a] = -root.lo[a];
            for (uint32_t t : kept) root.lo[a] = std::min(root.lo[a], lo_[t * 3 + a]), root.hi[a] = std::max(root.hi[a], hi_[t * 3 + a]);
        }
        root_area_ = root.area();
        std::vector<uint32_t> lists[3];
        for (int a = 0; a < 3; ++a) {
            lists[a] = kept;
            std::sort(lists[a].begin(), lists[a].end(), [&](uint32_t x, uint32_t y) {
                float kx = c_[x * 3 + a], ky = c_[y * 3 + a];
                return kx != ky ? kx < ky : x < y;
            });
        }
        node(lists, 0, root);
    }
    const Model &result() const { return model_; }

private:
    struct Box {
        float lo[3], hi[3];
        double area() const {
            double d[3];
            for (int a = 0; a < 3; ++a) d[a] = double(hi[a]) - double(lo[a]);
            return 2 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0]);
        }
    };
    void node(std::vector<uint32_t> (&lists)[3], uint32_t depth, const Box &box) {
        ++model_.nodes;
        uint32_t n = uint32_t(lists[0].size());
        if (n <= leaf_ || depth >= max_depth_) return leaf(n, depth, box);
        int axis = 0;
        float split = 0;
        std::vector<unsigned char> below(n), above(n);
        bool found = false;
        for (uint32_t attempt = 0; attempt < 3 && !found; ++attempt) {
            axis = int((depth + attempt) % 3);
            split = c_[lists[axis][n / 2] * 3 + axis];
            uint32_t nb = 0, na = 0;
            for (uint32_t t : lists[0]) {
                float lo = lo_[t * 3 + axis], hi = hi_[t * 3 + axis];
                nb += (lo < split || hi <= split);
                na += (hi > split);
            }
            found = nb < n && na < n;
        }
        if (!found) return leaf(n, depth, box);
        model_.planes.push_back({axis, split});
        model_.sah_cost += traversal_cost_ * box.area() / root_area_;
        Box below_box = box, above_box = box;  // the node's box cut at the split
        below_box.hi[axis] = above_box.lo[axis] = split;
        std::vector<uint32_t> b[3], a[3];
        for (int k = 0; k < 3; ++k)
            for (uint32_t t : lists[k]) {
                float lo = lo_[t * 3 + axis], hi = hi_[t * 3 + axis];
                if (lo < split || hi <= split) b[k].push_back(t);
                if (hi > split) a[k].push_back(t);
            }
        node(b, depth + 1, below_box);
        node(a, depth + 1, above_box);
    }
    void leaf(uint32_t n, uint32_t depth, const Box &box) {
        ++model_.leaves;
        model_.refs += n;
        model_.depth = std::max(model_.depth, depth);
        model_.sah_cost += intersection_cost_ * blocks(n) * box.area() / root_area_;
    }
    uint32_t leaf_, max_depth_;
    double traversal_cost_, intersection_cost_, root_area_ = 0;
    std::vector<float> lo_, hi_, c_;
    Model model_;
};

// Checks a built tree's statistics for consistency and against the model. max_depth as given
// to the build (0: default).
void check_stats(const kdrt_tree *tree, const common::Mesh &mesh, uint32_t leaf, uint32_t max_depth) {
    kdrt_tree_stats s;
    kdrt_tree_get_stats(tree, &s);
    INFO(mesh.name << " leaf size " << leaf << " max_depth " << max_depth << ": nodes " << s.nodes << " leaves "
                   << s.leaves << " refs " << s.triangle_refs << " depth " << s.max_depth << " bytes " << s.bytes
                   << " SAH cost " << s.sah_cost);
    const uint32_t limit = std::min<uint32_t>(max_depth ? max_depth : default_depth(mesh.triangle_count()), KDRT_MAX_DEPTH);
    const Model m = MedianModel(mesh, leaf, limit).result();
    CHECK(s.triangles == m.triangles);
    CHECK(s.leaves >= 1);
    CHECK(s.leaves <= s.nodes);
    CHECK(s.nodes == 2 * s.leaves - 1);  // every inner node has two children
    CHECK(s.max_depth <= KDRT_MAX_DEPTH);
    CHECK(s.max_depth <= limit);
    if (leaf == 0) {
        CHECK(s.nodes == 1);
        CHECK(s.triangle_refs == s.triangles);
        CHECK(s.max_depth == 0);
    } else {
        CHECK(s.triangle_refs >= s.triangles);
    }
    CHECK(s.bytes > 0);
    CHECK(s.bytes >= size_t(s.nodes) * 8 + size_t(s.triangle_refs) * 4);
    CHECK(m.nodes == s.nodes);
    CHECK(m.leaves == s.leaves);
    CHECK(m.refs == s.triangle_refs);
    CHECK(m.depth == s.max_depth);
    CHECK(s.sah_cost == Approx(m.sah_cost).epsilon(1e-9));
}

// Traces rays through the brute force (leaf size 0), checks it against the oracle (when given),
// then requires every other leaf size to answer identically, for kdrt_intersect and
// kdrt_occluded. Returns the brute force's hits.
std::vector<kdrt_hit> check_against_brute_force(const kdrt_triangles &view, const common::Mesh *oracle_mesh,
                                                const std::vector<kdrt_ray> &rays, const std::string &label,
                                                uint32_t max_depth = 0) {
    INFO(label << ", " << rays.size() << " rays");
    kt::TreePtr base = build_view(view, 0);
    std::vector<kdrt_hit> expected = kt::trace_all(base.get(), rays);
    if (oracle_mesh) {
        oracle::Oracle oracle(*oracle_mesh);
        std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
        oracle::Agreement tally;
        for (size_t i = 0; i < rays.size(); ++i) oracle::check_hit(oracle, refs[i], rays[i], expected[i], tally);
        INFO("brute force vs oracle: " << tally.exact << " exact, " << tally.ambiguous << " ambiguous; " << tally.first_wrong);
        CHECK(tally.wrong == 0);
    }
    for (uint32_t leaf : kLeafSizes) {
        if (leaf == 0) continue;
        kt::TreePtr tree = build_view(view, leaf, max_depth);
        std::vector<kdrt_hit> hits = kt::trace_all(tree.get(), rays);
        size_t differ = 0, occluded_wrong = 0;
        std::string first;
        for (size_t i = 0; i < rays.size(); ++i) {
            if (!same_hit(hits[i], expected[i]) && differ++ == 0)
                first = describe(rays[i]) + ": tree " + describe(hits[i]) + ", brute force " + describe(expected[i]);
            int occ = kdrt_occluded(tree.get(), &rays[i]);
            if (occ != (expected[i].triangle != KDRT_INVALID_ID) && occluded_wrong++ == 0 && first.empty())
                first = describe(rays[i]) + ": occluded " + std::to_string(occ) + ", brute force " + describe(expected[i]);
        }
        INFO("leaf size " << leaf << ": " << differ << " differ, " << occluded_wrong << " occlusion answers wrong; first: " << first);
        CHECK(differ == 0);
        CHECK(occluded_wrong == 0);
    }
    return expected;
}

void require_hit(const kdrt_hit &h, uint32_t triangle, float t, float u, float v, float eps = 1e-5f) {
    INFO("got " << describe(h));
    REQUIRE(h.triangle == triangle);
    CHECK(h.t == Approx(t).margin(eps));
    CHECK(h.u == Approx(u).margin(eps));
    CHECK(h.v == Approx(v).margin(eps));
}

// Six axis directions with every combination of +0 and -0 in the other two components.
std::vector<std::array<float, 3>> axis_directions() {
    std::vector<std::array<float, 3>> dirs;
    for (int a = 0; a < 3; ++a)
        for (float s : {1.0f, -1.0f})
            for (float z1 : {0.0f, -0.0f})
                for (float z2 : {0.0f, -0.0f}) {
                    std::array<float, 3> d;
                    d[a] = s, d[(a + 1) % 3] = z1, d[(a + 2) % 3] = z2;
                    dirs.push_back(d);
                }
    return dirs;
}

// Axis-parallel rays on a lattice over the mesh's box (step `step`, starting outside and inside).
std::vector<kdrt_ray> lattice_axis_rays(const kdrt_aabb &box, float step, float margin) {
    std::vector<kdrt_ray> rays;
    for (const auto &d : axis_directions()) {
        int a = d[0] != 0 ? 0 : d[1] != 0 ? 1 : 2, b = (a + 1) % 3, c = (a + 2) % 3;
        for (float pb = box.min[b] - margin; pb <= box.max[b] + margin; pb += step)
            for (float pc = box.min[c] - margin; pc <= box.max[c] + margin; pc += step)
                for (int start = 0; start < 2; ++start) {
                    kdrt_ray r = ray_of(0, 0, 0, d[0], d[1], d[2]);
                    r.org[b] = pb, r.org[c] = pc;
                    float mid = 0.5f * (box.min[a] + box.max[a]);
                    r.org[a] = start == 0 ? (d[a] > 0 ? box.min[a] - 1 : box.max[a] + 1) : mid;
                    rays.push_back(r);
                }
    }
    return rays;
}

// A simple deterministic generator for the tests' own random numbers.
struct Lcg {
    uint64_t s;
    explicit Lcg(uint64_t seed) : s(seed * 6364136223846793005ull + 1442695040888963407ull) {}
    double next() {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        return double(s >> 11) * (1.0 / 9007199254740992.0);
    }
    float range(float lo, float hi) { return float(lo + (hi - lo) * next()); }
};

}  // namespace

// ---------------------------------------------------------------------------------------------

TEST_CASE("hard: axis-parallel rays with +0 and -0 components through a grid and a sphere", "[hard]") {
    SECTION("grid") {
        common::Mesh grid = kt::grid(16, 16, 4);
        kdrt_triangles view = grid.view();
        kdrt_aabb box;
        REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
        // Step 0.25 hits vertices, edges and diagonals exactly.
        std::vector<kdrt_ray> rays = lattice_axis_rays(box, 0.25f, 0.5f);
        std::vector<kdrt_ray> hand;
        // Straight down through (x + 0.75, y + 0.25): inside triangle (a, b, d) of cell (x, y).
        const uint32_t cells[][2] = {{0, 0}, {3, 7}, {15, 15}, {8, 2}};
        for (const auto &cell : cells)
            for (float zero : {0.0f, -0.0f}) hand.push_back(ray_of(cell[0] + 0.75f, cell[1] + 0.25f, 10, zero, -zero, -1));
        rays.insert(rays.end(), hand.begin(), hand.end());
        std::vector<kdrt_hit> hits = check_against_brute_force(view, &grid, rays, "grid axis rays");
        for (size_t i = 0; i < hand.size(); ++i) {
            const uint32_t x = cells[i / 2][0], y = cells[i / 2][1];
            const uint32_t a = y * 17 + x, b = a + 1, d = a + 18;
            const float za = grid.positions[a * 3 + 2], zb = grid.positions[b * 3 + 2], zd = grid.positions[d * 3 + 2];
            // p = p_a + u (p_b - p_a) + v (p_d - p_a): x: 0.75 = u + v, y: 0.25 = v.
            const float z = za + 0.5f * (zb - za) + 0.25f * (zd - za);
            require_hit(hits[rays.size() - hand.size() + i], (y * 16 + x) * 2, 10 - z, 0.5f, 0.25f);
        }
        size_t hit_count = 0;
        for (const kdrt_hit &h : hits) hit_count += h.triangle != KDRT_INVALID_ID;
        CHECK(hit_count > rays.size() / 4);
    }
    SECTION("sphere") {
        common::Mesh sphere = kt::sphere(12, 16, 2.0);
        kdrt_triangles view = sphere.view();
        kdrt_aabb box;
        REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
        // Offset by 1/32 so that no ray runs exactly along the silhouette (x = +-2 etc.), where a
        // tangent ray's t is ill-conditioned.
        std::vector<kdrt_ray> rays = lattice_axis_rays(box, 0.125f, 0.25f + 1.0f / 32);
        const size_t first_center = rays.size();
        for (const auto &d : axis_directions()) rays.push_back(ray_of(0, 0, 0, d[0], d[1], d[2]));
        std::vector<kdrt_hit> hits = check_against_brute_force(view, &sphere, rays, "sphere axis rays");
        // From the centre every axis direction meets a vertex at distance 2 (poles, equator).
        for (size_t i = first_center; i < rays.size(); ++i) {
            INFO(describe(rays[i]) << ": " << describe(hits[i]));
            REQUIRE(hits[i].triangle != KDRT_INVALID_ID);
            CHECK(hits[i].t == Approx(2.0f).margin(1e-6));
        }
    }
}

TEST_CASE("hard: rays lying exactly in split planes, with +0 and -0 across the plane", "[hard]") {
    std::vector<common::Mesh> meshes = {kt::grid(12, 12, 9), kt::sphere(10, 14, 3.0), kt::random_soup(300, 12)};
    for (const common::Mesh &mesh : meshes) {
        kdrt_triangles view = mesh.view();
        kdrt_aabb box;
        REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
        std::set<Plane> planes;
        for (uint32_t leaf : kLeafSizes) {
            if (leaf == 0) continue;
            kt::TreePtr tree = build_view(view, leaf);
            check_stats(tree.get(), mesh, leaf, 0);  // the model's planes are the tree's
            const Model m = MedianModel(mesh, leaf, default_depth(mesh.triangle_count())).result();
            planes.insert(m.planes.begin(), m.planes.end());
        }
        INFO(mesh.name << ": " << planes.size() << " distinct split planes");
        REQUIRE(planes.size() > 10);
        Lcg rng(planes.size());
        std::vector<kdrt_ray> rays;
        size_t index = 0;
        for (const Plane &p : planes) {
            if (planes.size() > 200 && index++ % (planes.size() / 200 + 1) != 0) continue;
            const int a = p.axis, b = (a + 1) % 3, c = (a + 2) % 3;
            for (int k = 0; k < 12; ++k) {
                kdrt_ray r = ray_of(0, 0, 0, 0, 0, 0);
                r.org[a] = p.split;
                r.org[b] = rng.range(box.min[b] - 1, box.max[b] + 1);
                r.org[c] = rng.range(box.min[c] - 1, box.max[c] + 1);
                r.dir[a] = (k & 1) ? -0.0f : 0.0f;
                switch (k / 2) {
                case 0: r.dir[b] = 1; break;
                case 1: r.dir[c] = -1; break;
                case 2: r.dir[b] = -1, r.dir[c] = 0.5f; break;
                case 3: r.dir[b] = box.min[b] + 0.5f * (box.max[b] - box.min[b]) - r.org[b], r.dir[c] = box.min[c] + 0.5f * (box.max[c] - box.min[c]) - r.org[c]; break;
                case 4: r.dir[b] = rng.range(-1, 1), r.dir[c] = rng.range(-1, 1); break;
                default:  // crossing the plane from a point on it
                    r.dir[a] = (k & 1) ? -1.0f : 1.0f, r.dir[b] = rng.range(-1, 1), r.dir[c] = rng.range(-1, 1);
                    break;
                }
                rays.push_back(r);
            }
        }
        check_against_brute_force(view, &mesh, rays, mesh.name + " split-plane rays");
    }
}

namespace {

// Triangles in the plane x = 5, which is the root's split plane (canonical coordinates: axis A
// of the world is x here, the next axis y, the one after z).
//   0..5    planar at x = 2, off to the side (y in [10, 16])
//   6..17   planar at x = 5: six unit squares, y in [k, k + 1], z in [0, 1], two triangles each:
//           6 + 2k = (5,k,0) (5,k+1,0) (5,k+1,1), 7 + 2k = (5,k,0) (5,k+1,1) (5,k,1)
//   18..23  planar at x = 8, off to the side (y in [20, 26])
//   24, 25  in the plane z = 3, straddling x = 5: (3,0,3) (7,0,3) (3,6,3) and (7,0,3) (7,6,3) (3,6,3)
// Sorted centroids x: 2 (x6), 4.33, 5 (x12), 5.67, 8 (x6): the median (index 13) is 5.
struct PlaneScene {
    int axis;
    common::Mesh mesh;
    explicit PlaneScene(int a) : axis(a) {
        Soup s("plane_scene_axis" + std::to_string(a));
        auto add = [&](float x0, float y0, float z0, float x1, float y1, float z1, float x2, float y2, float z2) {
            float p[3][3] = {{x0, y0, z0}, {x1, y1, z1}, {x2, y2, z2}};
            float w[3][3];
            for (int k = 0; k < 3; ++k) world(p[k], w[k]);
            s.add(w[0], w[1], w[2]);
        };
        for (int k = 0; k < 6; ++k) add(2, 10.f + k, 0, 2, 11.f + k, 0, 2, 10.f + k, 1);
        for (int k = 0; k < 6; ++k) {
            add(5, float(k), 0, 5, k + 1.f, 0, 5, k + 1.f, 1);
            add(5, float(k), 0, 5, k + 1.f, 1, 5, float(k), 1);
        }
        for (int k = 0; k < 6; ++k) add(8, 20.f + k, 0, 8, 21.f + k, 0, 8, 20.f + k, 1);
        add(3, 0, 3, 7, 0, 3, 3, 6, 3);
        add(7, 0, 3, 7, 6, 3, 3, 6, 3);
        mesh = s.mesh;
    }
    void world(const float c[3], float w[3]) const {
        w[axis] = c[0], w[(axis + 1) % 3] = c[1], w[(axis + 2) % 3] = c[2];
    }
    kdrt_ray ray(float ox, float oy, float oz, float dx, float dy, float dz, float tmin = 0) const {
        const float o[3] = {ox, oy, oz}, d[3] = {dx, dy, dz};
        kdrt_ray r = ray_of(0, 0, 0, 0, 0, 0, tmin);
        world(o, r.org);
        world(d, r.dir);
        return r;
    }
};

struct Expected {
    kdrt_ray ray;
    uint32_t triangle;  // KDRT_INVALID_ID: a miss
    float t, u, v;
};

}  // namespace

TEST_CASE("hard: triangles in the split plane, rays in it and rays starting on them", "[hard]") {
    for (int axis = 0; axis < 3; ++axis) {
        PlaneScene scene(axis);
        INFO("plane scene, axis " << axis);
        if (axis == 0) {
            const Model m = MedianModel(scene.mesh, 1, default_depth(26)).result();
            REQUIRE(!m.planes.empty());
            CHECK(m.planes[0].axis == 0);
            CHECK(m.planes[0].split == 5.0f);
        }
        std::vector<Expected> cases;
        for (int k = 0; k < 6; ++k) {
            const float y = float(k);
            const uint32_t lower = 6 + 2 * k, upper = 7 + 2 * k;
            // Perpendicular, from either side.
            cases.push_back({scene.ray(0, y + 0.25f, 0.5f, 1, 0, 0), upper, 5, 0.25f, 0.25f});
            cases.push_back({scene.ray(10, y + 0.75f, 0.25f, -1, 0, 0), lower, 5, 0.5f, 0.25f});
            cases.push_back({scene.ray(10, y + 0.75f, 0.25f, -2, 0, 0), lower, 2.5f, 0.5f, 0.25f});
            // In the plane x = 5 (dir.x = +0 and -0): the coplanar triangles are not hit, the
            // straddling ones at z = 3 are, at t = 7.
            for (float zero : {0.0f, -0.0f}) {
                if (k <= 2) cases.push_back({scene.ray(5, y + 0.5f, 10, zero, 0, -1), 24, 7, 0.5f, (y + 0.5f) / 6});
                else cases.push_back({scene.ray(5, y + 0.5f, 10, zero, 0, -1), 25, 7, (y - 2.5f) / 6, 0.5f});
                cases.push_back({scene.ray(5, -1, y * 0.2f, zero, 1, -zero), KDRT_INVALID_ID, 0, 0, 0});
                cases.push_back({scene.ray(5, y + 0.5f, -5, zero, 0, 1), k <= 2 ? 24u : 25u, 8, k <= 2 ? 0.5f : (y - 2.5f) / 6,
                                 k <= 2 ? (y + 0.5f) / 6 : 0.5f});
            }
            // Starting on a planar triangle: with tmin = 0 it is hit at t = 0 whichever way the
            // ray leaves; with tmin > 0 it is skipped.
            const float dirs[][3] = {{1, 0, 0}, {-1, 0, 0}, {0.5f, 0, 1}, {-0.5f, 0, 1}, {0.25f, 0.5f, -1}, {-3, -0.5f, 0.5f}};
            for (const auto &d : dirs) {
                cases.push_back({scene.ray(5, y + 0.25f, 0.5f, d[0], d[1], d[2]), upper, 0, 0.25f, 0.25f});
                cases.push_back({scene.ray(5, y + 0.75f, 0.25f, d[0], d[1], d[2]), lower, 0, 0.5f, 0.25f});
            }
            cases.push_back({scene.ray(5, y + 0.25f, 0.5f, 1, 0, 0, 1e-3f), KDRT_INVALID_ID, 0, 0, 0});
            cases.push_back({scene.ray(5, y + 0.25f, 0.5f, -1, 0, 0, 1e-3f), KDRT_INVALID_ID, 0, 0, 0});
            // ... and then meets a straddler at z = 3, t = 2.5, x = 6.25 or 3.75.
            if (k == 0) cases.push_back({scene.ray(5, y + 0.25f, 0.5f, 0.5f, 0, 1, 1e-3f), 24, 2.5f, 0.8125f, (y + 0.25f) / 6});
            else cases.push_back({scene.ray(5, y + 0.25f, 0.5f, 0.5f, 0, 1, 1e-3f), 25, 2.5f, (y + 0.25f - 1.125f) / 6, 0.1875f});
            if (k <= 4) cases.push_back({scene.ray(5, y + 0.25f, 0.5f, -0.5f, 0, 1, 1e-3f), 24, 2.5f, 0.1875f, (y + 0.25f) / 6});
            else cases.push_back({scene.ray(5, y + 0.25f, 0.5f, -0.5f, 0, 1, 1e-3f), 25, 2.5f, (y + 0.25f - 4.875f) / 6, 0.8125f});
        }
        // Starting on a straddler (in both children), leaving either way.
        for (float dx : {1.0f, -1.0f, 0.0f, -0.0f}) {
            cases.push_back({scene.ray(5, 1, 3, dx, 0, 1), 24, 0, 0.5f, 1.0f / 6});
            cases.push_back({scene.ray(4, 1, 3, dx, 0, -1), 24, 0, 0.25f, 1.0f / 6});
            cases.push_back({scene.ray(6, 5, 3, dx, 0.5f, -1), 25, 0, 3.5f / 6, 0.25f});
        }

        const kdrt_triangles view = scene.mesh.view();
        for (uint32_t leaf : kLeafSizes) {
            kt::TreePtr tree = build_view(view, leaf);
            if (leaf) check_stats(tree.get(), scene.mesh, leaf, 0);
            size_t wrong = 0;
            for (const Expected &e : cases) {
                kdrt_hit h = trace(tree.get(), e.ray);
                bool ok = h.triangle == e.triangle;
                if (ok && h.triangle != KDRT_INVALID_ID)
                    ok = std::fabs(h.t - e.t) <= 1e-5f && std::fabs(h.u - e.u) <= 1e-5f && std::fabs(h.v - e.v) <= 1e-5f;
                ok = ok && kdrt_occluded(tree.get(), &e.ray) == (e.triangle != KDRT_INVALID_ID);
                if (!ok) {
                    ++wrong;
                    UNSCOPED_INFO("leaf size " << leaf << ": " << describe(e.ray) << " expected triangle "
                                               << (e.triangle == KDRT_INVALID_ID ? std::string("none") : std::to_string(e.triangle))
                                               << " at t=" << e.t << " u=" << e.u << " v=" << e.v << ", got " << describe(h));
                    if (wrong >= 4) break;
                }
            }
            INFO("leaf size " << leaf << ", " << cases.size() << " hand-computed rays");
            CHECK(wrong == 0);
        }
        // And random rays against the oracle, for every leaf size.
        std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(kt::build(scene.mesh, 0, KDRT_BUILDER_MEDIAN).get()), 20000, 5 + axis);
        check_against_brute_force(view, &scene.mesh, rays, scene.mesh.name + " random rays");
    }
}

TEST_CASE("hard: many identical triangles: the build terminates, the lowest index wins", "[hard]") {
    SECTION("only identical triangles") {
        Soup s("identical_only");
        for (int i = 0; i < 500; ++i) s.add(0, 0, 0, 4, 0, 0, 0, 4, 1);
        for (uint32_t leaf : kLeafSizes) {
            kt::TreePtr tree = kt::build(s.mesh, leaf, KDRT_BUILDER_MEDIAN);
            check_stats(tree.get(), s.mesh, leaf, 0);
            kdrt_tree_stats st;
            kdrt_tree_get_stats(tree.get(), &st);
            CHECK(st.nodes == 1);  // nothing separates them
            CHECK(st.triangle_refs == 500);
            // (1, 1, 5) down: (1, 1, 0.25) = u (4, 0, 0) + v (0, 4, 1) with u = v = 0.25.
            kdrt_hit h = trace(tree.get(), ray_of(1, 1, 5, 0, 0, -1));
            require_hit(h, 0, 4.75f, 0.25f, 0.25f);
        }
    }
    SECTION("identical triangles among others, indexed and soup") {
        common::Mesh before = kt::random_soup(30, 31), after = kt::random_soup(20, 32);
        Soup s("identical_mixed");
        s.mesh.positions = before.positions;
        const uint32_t first = s.mesh.triangle_count();
        for (int i = 0; i < 1000; ++i) s.add(20, 0, 0, 20, 4, 0, 20, 0, 4);  // the plane x = 20, beyond the soups
        s.mesh.positions.insert(s.mesh.positions.end(), after.positions.begin(), after.positions.end());
        REQUIRE(first == 30);

        // The same, indexed, every copy sharing three vertices.
        common::Mesh indexed = s.mesh;
        indexed.name = "identical_mixed_indexed";
        indexed.positions.clear();
        for (uint32_t t = 0; t < s.mesh.triangle_count(); ++t) {
            if (t >= first && t < first + 1000) {
                if (t == first) indexed.positions.insert(indexed.positions.end(), s.mesh.positions.begin() + t * 9, s.mesh.positions.begin() + t * 9 + 9);
                uint32_t base = first * 3;
                indexed.indices.insert(indexed.indices.end(), {base, base + 1, base + 2});
            } else {
                uint32_t base = indexed.vertex_count();
                indexed.positions.insert(indexed.positions.end(), s.mesh.positions.begin() + t * 9, s.mesh.positions.begin() + t * 9 + 9);
                indexed.indices.insert(indexed.indices.end(), {base, base + 1, base + 2});
            }
        }
        for (const common::Mesh *mesh : {&s.mesh, &indexed}) {
            INFO(mesh->name);
            kdrt_triangles view = mesh->view();
            for (uint32_t leaf : kLeafSizes) {
                kt::TreePtr tree = build_view(view, leaf);
                check_stats(tree.get(), *mesh, leaf, 0);
                for (float zero : {0.0f, -0.0f}) {
                    // (20, 1, 1.5) = p0 + u (0, 4, 0) + v (0, 0, 4): u = 0.25, v = 0.375.
                    require_hit(trace(tree.get(), ray_of(30, 1, 1.5f, -1, zero, zero)), first, 10, 0.25f, 0.375f);
                    require_hit(trace(tree.get(), ray_of(40, 1, 1.5f, -2, zero, -zero)), first, 10, 0.25f, 0.375f);
                }
                // Oblique, from the other side: (10, 1, 1) + t (2, 0.125, 0.25), t = 5 at (20, 1.625, 2.25).
                require_hit(trace(tree.get(), ray_of(10, 1, 1, 2, 0.125f, 0.25f)), first, 5, 0.40625f, 0.5625f);
            }
            // Rays reaching the copies test all 1000 of them in every tree: keep the count modest.
            std::vector<kdrt_ray> rays = kt::random_rays(kdrt_aabb{{0, 0, 0}, {21, 10, 10}}, 4000, 8);
            std::vector<kdrt_hit> hits = check_against_brute_force(view, mesh, rays, mesh->name);
            size_t on_copy = 0, not_first = 0;
            for (const kdrt_hit &h : hits)
                if (h.triangle >= first && h.triangle < first + 1000) ++on_copy, not_first += h.triangle != first;
            CHECK(on_copy > 40);
            CHECK(not_first == 0);
        }
    }
}

TEST_CASE("hard: coplanar overlapping triangles: the lower caller index wins, whatever order the tree stores them in", "[hard]") {
    // The tree keeps its triangles in the order its leaves first refer to them (depth first,
    // below child first), not the caller's: here the big triangle (index 1) reaches far lower x
    // and y than the small one (index 0), so the leaves on the low side meet it first. Where they
    // overlap, in the plane z = 0, both are hit at the same t, and the answer must be index 0.
    Soup s("coplanar_reordered");
    const uint32_t small = s.add(8, 8, 0, 9, 8, 0, 8, 9, 0);
    const uint32_t big = s.add(-10, -10, 0, 20, -10, 0, -10, 20, 0);
    REQUIRE(small == 0);
    REQUIRE(big == 1);
    common::Mesh fillers = kt::random_soup(300, 77);  // in [0, 10]^3; moved to y in [30, 40]
    for (size_t i = 1; i < fillers.positions.size(); i += 3) fillers.positions[i] += 30;
    s.mesh.positions.insert(s.mesh.positions.end(), fillers.positions.begin(), fillers.positions.end());
    kdrt_triangles view = s.mesh.view();
    for (const kt::Builder &builder : kt::kBuilders)
        for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST})
            for (uint32_t leaf : kLeafSizes) {
                INFO("builder " << builder.name << " intersector " << intersector << " leaf size " << leaf);
                kdrt_build_options o = kdrt_default_build_options();
                builder.apply(o), o.intersector = intersector, o.max_leaf_size = leaf;
                kdrt_tree *raw = nullptr;
                REQUIRE(kdrt_tree_build(&view, &o, &raw, nullptr) == KDRT_SUCCESS);
                kt::TreePtr tree(raw);
                // (8.25, 8.5) = small's p0 + u (1, 0, 0) + v (0, 1, 0): u = 0.25, v = 0.5.
                require_hit(trace(tree.get(), ray_of(8.25f, 8.5f, 5, 0, 0, -1)), small, 5, 0.25f, 0.5f);
                require_hit(trace(tree.get(), ray_of(8.25f, 8.5f, -4, 0, 0, 2)), small, 2, 0.25f, 0.5f);
                // Beside the small one only the big one is there: (0, 0) = p0 + u (30, 0, 0) + v (0, 30, 0).
                require_hit(trace(tree.get(), ray_of(0, 0, 5, 0, 0, -1)), big, 5, 1.0f / 3, 1.0f / 3);
            }
}

TEST_CASE("hard: the tree's blocks: a soup costs what its indexed mesh does, left-out triangles nothing", "[hard]") {
    // THE TREE: nodes, and each leaf's triangles in blocks of 8 (320 bytes, 64-byte aligned) with
    // their first reference number (4 bytes); kdrt_tree_stats.bytes counts them and the tree
    // struct itself.
    common::Mesh mesh = kt::sphere(16, 24, 2.0);
    common::Mesh soup = kt::as_soup(mesh);
    // The same mesh with zero-area triangles and (skipped) ones indexing past the vertices.
    common::Mesh extra = mesh;
    extra.name = "sphere_with_left_out_triangles";
    for (uint32_t i = 0; i < 40; ++i) extra.indices.insert(extra.indices.end(), {i, i, i + 1});
    for (uint32_t i = 0; i < 10; ++i) extra.indices.insert(extra.indices.end(), {i, i + 1, mesh.vertex_count() + i});

    for (const kt::Builder &builder : kt::kBuilders)
        for (uint32_t leaf : kLeafSizes) {
            INFO("builder " << builder.name << " leaf size " << leaf);
            kdrt_build_options o = kdrt_default_build_options();
            builder.apply(o), o.max_leaf_size = leaf, o.flags = KDRT_BUILD_SKIP_INVALID_TRIANGLES;
            kdrt_tree_stats st[3];
            const common::Mesh *meshes[3] = {&mesh, &soup, &extra};
            for (int k = 0; k < 3; ++k) {
                kdrt_triangles view = meshes[k]->view();
                kdrt_tree *raw = nullptr;
                REQUIRE(kdrt_tree_build(&view, &o, &raw, nullptr) == KDRT_SUCCESS);
                kdrt_tree_get_stats(raw, &st[k]);
                kdrt_tree_free(raw);
            }
            // The cells: a leaf's box and ropes (48 bytes), and a node's cell number (4).
            const size_t counted = size_t(st[0].nodes) * (8 + 4) + size_t(st[0].blocks) * (320 + 4) + size_t(st[0].leaves) * 48;
            CHECK(st[0].triangles == mesh.triangle_count());
            CHECK(uint64_t(st[0].blocks) * 8 >= st[0].triangle_refs);  // 8 triangles to a block at most
            CHECK(st[0].blocks <= st[0].triangle_refs);                // and one at least
            CHECK(st[0].bytes >= counted);
            CHECK(st[0].bytes <= counted + 1024);  // the tree struct and the blocks' alignment
            for (int k = 1; k < 3; ++k) {
                INFO(meshes[k]->name);
                CHECK(st[k].triangles == st[0].triangles);
                CHECK(st[k].nodes == st[0].nodes);
                CHECK(st[k].triangle_refs == st[0].triangle_refs);
                CHECK(st[k].blocks == st[0].blocks);
                CHECK(st[k].bytes == st[0].bytes);
            }
        }
}

TEST_CASE("hard: degenerate triangles are never hit", "[hard]") {
    common::Mesh good = kt::random_soup(300, 8);
    Soup s("degenerate_mixed");
    std::vector<std::array<float, 3>> targets;  // points on the degenerate triangles
    Lcg rng(3);
    for (uint32_t g = 0; g < 60; ++g) {
        // A point inside good triangle g (rounded to float: on or very near its plane).
        double p[3][3];
        good.corners(g, p);
        // Near its centroid, on a 1/64 lattice so that c + k e and c + k f below are exact: the
        // "collinear" triangles are exactly collinear in float.
        float c[3];
        for (int a = 0; a < 3; ++a) c[a] = float(std::round((p[0][a] + p[1][a] + p[2][a]) / 3 * 64) / 64);
        const float e[3] = {0.5f, 0.25f, -0.75f};
        const float f[3] = {1, 2, 3};
        float c1[3], c2[3], c3[3], c7[3], p0[3], p1[3];
        for (int a = 0; a < 3; ++a) {
            c1[a] = c[a] + e[a], c2[a] = c[a] + 2 * e[a];
            c3[a] = c[a] + 3 * f[a], c7[a] = c[a] + 7 * f[a];
            p0[a] = float(p[0][a]), p1[a] = float(p[1][a]);
        }
        s.add(c, c, c);         // a point
        s.add(c, c, c1);        // two equal corners
        s.add(c1, c, c);
        s.add(c, c1, c);
        s.add(c, c1, c2);       // exactly collinear
        s.add(c2, c, c1);
        s.add(c, c3, c7);       // collinear, non-dyadic direction
        s.add(p0, p1, p0);      // along an edge of the good triangle
        s.add(p0, p0, p0);      // on its corner
        targets.push_back({c[0], c[1], c[2]});
        targets.push_back({c1[0], c1[1], c1[2]});
        float half[3], mid7[3];
        for (int a = 0; a < 3; ++a) half[a] = c[a] + 0.5f * e[a], mid7[a] = c[a] + 5 * f[a];
        targets.push_back({half[0], half[1], half[2]});
        targets.push_back({mid7[0], mid7[1], mid7[2]});
    }
    const uint32_t degenerate = s.mesh.triangle_count();
    s.mesh.positions.insert(s.mesh.positions.end(), good.positions.begin(), good.positions.end());

    std::vector<kdrt_ray> rays;
    for (const auto &tp : targets) {
        for (const auto &d : axis_directions()) {
            kdrt_ray r = ray_of(tp[0], tp[1], tp[2], d[0], d[1], d[2]);
            int a = d[0] != 0 ? 0 : d[1] != 0 ? 1 : 2;
            r.org[a] = tp[a] - 20 * d[a];  // passes exactly through the target
            rays.push_back(r);
            r.org[a] = tp[a];             // starts on it
            rays.push_back(r);
        }
        for (int k = 0; k < 8; ++k) {
            float o[3] = {rng.range(-5, 15), rng.range(-5, 15), rng.range(-5, 15)};
            rays.push_back(ray_of(o[0], o[1], o[2], tp[0] - o[0], tp[1] - o[1], tp[2] - o[2]));
        }
    }
    std::vector<kdrt_ray> random = kt::random_rays(kdrt_aabb{{0, 0, 0}, {10, 10, 10}}, 20000, 6);
    rays.insert(rays.end(), random.begin(), random.end());

    // Expected: the good triangles alone, tested one by one, renumbered.
    kt::TreePtr good_only = kt::build(good, 0, KDRT_BUILDER_MEDIAN);
    std::vector<kdrt_hit> expected = kt::trace_all(good_only.get(), rays);
    for (kdrt_hit &h : expected)
        if (h.triangle != KDRT_INVALID_ID) h.triangle += degenerate;
    {
        oracle::Oracle oracle(good);
        std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
        oracle::Agreement tally;
        for (size_t i = 0; i < rays.size(); ++i) {
            kdrt_hit h = expected[i];
            if (h.triangle != KDRT_INVALID_ID) h.triangle -= degenerate;
            oracle::check_hit(oracle, refs[i], rays[i], h, tally);
        }
        INFO(tally.first_wrong);
        CHECK(tally.wrong == 0);
    }
    const kdrt_triangles view = s.mesh.view();
    for (uint32_t leaf : kLeafSizes) {
        // Degenerate triangles are valid input: the build succeeds, counts them and leaves them out.
        kdrt_build_options options = kdrt_default_build_options();
        options.builder = KDRT_BUILDER_MEDIAN;  // check_stats knows the median tree's shape
        options.max_leaf_size = leaf;
        kdrt_build_report report;
        kdrt_tree *raw = nullptr;
        REQUIRE(kdrt_tree_build(&view, &options, &raw, &report) == KDRT_SUCCESS);
        kt::TreePtr tree(raw);
        CHECK(report.degenerate_triangles == degenerate);
        CHECK(report.skipped_triangles == 0);
        check_stats(tree.get(), s.mesh, leaf, 0);
        std::vector<kdrt_hit> hits = kt::trace_all(tree.get(), rays);
        size_t degenerate_hits = 0, differ = 0, good_hits = 0, by_kind[9] = {};
        std::string first;
        for (size_t i = 0; i < rays.size(); ++i) {
            if (hits[i].triangle < degenerate) ++by_kind[hits[i].triangle % 9];
            if (hits[i].triangle < degenerate && degenerate_hits++ == 0) {
                first = describe(rays[i]) + " hit degenerate " + describe(hits[i]);
                double p[3][3];
                s.mesh.corners(hits[i].triangle, p);
                std::ostringstream os;
                os.precision(9);
                for (auto &q : p) os << " (" << q[0] << "," << q[1] << "," << q[2] << ")";
                first += os.str();
            }
            if (!same_hit(hits[i], expected[i]) && differ++ == 0 && first.empty())
                first = describe(rays[i]) + ": " + describe(hits[i]) + ", good triangles alone: " + describe(expected[i]);
            good_hits += hits[i].triangle != KDRT_INVALID_ID && hits[i].triangle >= degenerate;
        }
        std::ostringstream kinds;
        for (size_t k = 0; k < 9; ++k) kinds << " " << by_kind[k];
        INFO("leaf size " << leaf << ": " << degenerate_hits << " degenerate hits (by kind:" << kinds.str() << "), " << differ
                          << " differ; " << first);
        CHECK(degenerate_hits == 0);
        CHECK(differ == 0);
        CHECK(good_hits > rays.size() / 10);
    }
}

TEST_CASE("hard: indexed and soup views with packed, 16, 20 and 13 byte strides agree exactly", "[hard]") {
    common::Mesh mesh = kt::grid(24, 24, 6);
    common::Mesh soup = kt::as_soup(mesh);

    // Copies of the vertices at a byte stride; the padding holds garbage (huge floats).
    struct Layout {
        std::string name;
        std::vector<unsigned char> bytes;
        kdrt_triangles view;
    };
    auto make = [](const common::Mesh &m, size_t stride, const std::string &name) {
        Layout l;
        l.name = name;
        l.view = m.view();
        if (stride != 0) {
            l.bytes.assign(stride * m.vertex_count() + 16, 0x7F);
            for (uint32_t i = 0; i < m.vertex_count(); ++i) std::memcpy(l.bytes.data() + i * stride, &m.positions[i * 3], 12);
            l.view.positions = reinterpret_cast<const float *>(l.bytes.data());
            l.view.position_stride = stride;
        }
        return l;
    };
    std::vector<Layout> layouts;
    layouts.push_back(make(mesh, 0, "indexed packed"));
    layouts.push_back(make(mesh, 20, "indexed stride 20"));
    layouts.push_back(make(mesh, 13, "indexed stride 13"));
    layouts.push_back(make(soup, 0, "soup packed"));
    layouts.push_back(make(soup, 16, "soup stride 16"));
    layouts.push_back(make(soup, 20, "soup stride 20"));
    layouts.push_back(make(soup, 13, "soup stride 13"));
    layouts[0].view = mesh.view();
    layouts[3].view = soup.view();

    const size_t count = kt::reference_ray_count();
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(kt::build(mesh, 4, KDRT_BUILDER_MEDIAN).get()), count, 2024);
    for (uint32_t leaf : kLeafSizes) {
        // The brute force gets fewer rays: it tests every triangle for each.
        std::vector<kdrt_ray> some(rays.begin(), rays.begin() + (leaf == 0 ? std::min<size_t>(count, 10000) : count));
        kt::TreePtr ref_tree = build_view(layouts[0].view, leaf);
        std::vector<kdrt_hit> expected = kt::trace_all(ref_tree.get(), some);
        if (leaf == 4) {
            oracle::Oracle oracle(mesh);
            std::vector<kdrt_ray> check(some.begin(), some.begin() + std::min<size_t>(some.size(), 20000));
            std::vector<oracle::Reference> refs = oracle::reference_all(oracle, check);
            oracle::Agreement tally;
            for (size_t i = 0; i < check.size(); ++i) oracle::check_hit(oracle, refs[i], check[i], expected[i], tally);
            INFO(tally.first_wrong);
            CHECK(tally.wrong == 0);
        }
        size_t hit_count = 0;
        for (const kdrt_hit &h : expected) hit_count += h.triangle != KDRT_INVALID_ID;
        CHECK(hit_count > some.size() / 4);
        kdrt_tree_stats ref_stats;
        kdrt_tree_get_stats(ref_tree.get(), &ref_stats);
        for (size_t l = 1; l < layouts.size(); ++l) {
            kt::TreePtr tree = build_view(layouts[l].view, leaf);
            kdrt_tree_stats st;
            kdrt_tree_get_stats(tree.get(), &st);
            CHECK(st.nodes == ref_stats.nodes);
            CHECK(st.triangle_refs == ref_stats.triangle_refs);
            std::vector<kdrt_hit> hits = kt::trace_all(tree.get(), some);
            size_t differ = 0;
            std::string first;
            for (size_t i = 0; i < some.size(); ++i)
                if (!same_hit(hits[i], expected[i]) && differ++ == 0)
                    first = describe(some[i]) + ": " + describe(hits[i]) + " vs " + describe(expected[i]);
            INFO(layouts[l].name << ", leaf size " << leaf << ": " << differ << " of " << some.size() << " differ; " << first);
            CHECK(differ == 0);
        }
    }
}

TEST_CASE("hard: tree statistics are consistent and follow the documented median build", "[hard]") {
    Soup identical("identical_with_others");
    for (int i = 0; i < 200; ++i) identical.add(1, 1, 1, 2, 1, 1, 1, 2, 1);
    common::Mesh extra = kt::random_soup(100, 41);
    identical.mesh.positions.insert(identical.mesh.positions.end(), extra.positions.begin(), extra.positions.end());
    std::vector<common::Mesh> meshes = {kt::grid(20, 20, 1), kt::sphere(16, 24, 2.0), kt::random_soup(1000, 3), identical.mesh,
                                    kt::random_soup(1, 1), kt::random_soup(2, 1)};
    for (const common::Mesh &mesh : meshes)
        for (uint32_t leaf : kLeafSizes)
            for (uint32_t max_depth : {0u, 1u, 3u, 10u, 64u, 65u, 200u}) {
                kdrt_triangles view = mesh.view();
                kt::TreePtr tree = build_view(view, leaf, max_depth);
                check_stats(tree.get(), mesh, leaf, max_depth);
                if (max_depth == 1 && leaf > 0 && mesh.triangle_count() > leaf) {
                    kdrt_tree_stats s;
                    kdrt_tree_get_stats(tree.get(), &s);
                    CHECK(s.nodes <= 3);  // at most one split
                }
            }
}

namespace {

kt::TreePtr build_priced(const common::Mesh &mesh, const kt::Builder &builder, uint32_t leaf, float traversal,
                         float intersection, float empty_bonus = 0) {
    kdrt_triangles view = mesh.view();
    kdrt_build_options o = kdrt_default_build_options();
    builder.apply(o);
    o.max_leaf_size = leaf;
    o.sah_traversal_cost = traversal;
    o.sah_intersection_cost = intersection;
    o.sah_empty_bonus = empty_bonus;
    kdrt_tree *tree = nullptr;
    REQUIRE(kdrt_tree_build(&view, &o, &tree, nullptr) == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

kt::TreePtr build_priced(const common::Mesh &mesh, kdrt_builder builder, uint32_t leaf, float traversal, float intersection,
                         float empty_bonus = 0) {
    return build_priced(mesh, kt::Builder{builder, KDRT_BUILD_QUALITY_DEFAULT, "default"}, leaf, traversal, intersection,
                        empty_bonus);
}

kdrt_tree_stats stats_of(const kt::TreePtr &tree) {
    kdrt_tree_stats s;
    kdrt_tree_get_stats(tree.get(), &s);
    return s;
}

}  // namespace

TEST_CASE("hard: sah_cost is the SAH cost of the built tree, priced with the build's costs", "[hard]") {
    // Three triangles: x in [0, 1] (z = 0), the plane x = 2 (y, z in [0, 1]), x in [3, 4] (z = 0).
    // Root box [0,4]x[0,1]x[0,1], area 2 (4 + 1 + 4) = 18. The median build splits at the middle
    // centroid, x = 2 (the planar triangle goes below), and with leaf size 2 stops there: two
    // leaves of area 2 (2 + 1 + 2) = 10, holding 2 and 1 triangles, a block each. Cost:
    // K_T + K_I (1 + 1) 10 / 18, K_I pricing a test of a block of up to 8 triangles.
    Soup three("three");
    three.add(0, 0, 0, 1, 0, 0, 0, 1, 0);
    three.add(2, 0, 0, 2, 1, 0, 2, 0, 1);
    three.add(3, 0, 0, 4, 0, 0, 3, 1, 0);
    {
        kdrt_tree_stats s = stats_of(build_priced(three.mesh, KDRT_BUILDER_MEDIAN, 2, 0, 0));  // 0: defaults
        REQUIRE(s.nodes == 3);
        CHECK(s.sah_cost == Approx(double(KDRT_DEFAULT_SAH_TRAVERSAL_COST) + double(KDRT_DEFAULT_SAH_INTERSECTION_COST) * 20 / 18).epsilon(1e-12));
        s = stats_of(build_priced(three.mesh, KDRT_BUILDER_MEDIAN, 2, 15, 20));  // Wald & Havran's
        CHECK(s.sah_cost == Approx(15.0 + 20.0 * 20 / 18).epsilon(1e-12));
        s = stats_of(build_priced(three.mesh, KDRT_BUILDER_MEDIAN, 2, 1, 80));  // pbrt-v3's
        CHECK(s.sah_cost == Approx(1.0 + 80.0 * 20 / 18).epsilon(1e-12));
        s = stats_of(build_priced(three.mesh, KDRT_BUILDER_MEDIAN, 4, 1, 80));  // one leaf
        REQUIRE(s.nodes == 1);
        CHECK(s.sah_cost == Approx(80.0 * 1).epsilon(1e-12));  // one block
    }

    // Eight copies of a triangle with x in [0, 1] and one with x in [9, 10], y in [0, 1], z = 0:
    // root area 2 (10 x 1) = 20. A leaf of all nine is two blocks, 2 K_I. The SAH build with leaf
    // size 1 splits at x = 1 or x = 9 (either leaves areas 2 and 18, a block each) when
    // K_T + K_I (2 + 18) / 20 = K_T + K_I is cheaper than the leaf, that is when K_T < K_I: with
    // Wald & Havran's and pbrt-v3's costs, not with kdrt's defaults (K_T = 1.5 K_I).
    Soup nine("nine");
    for (int k = 0; k < 8; ++k) nine.add(0, 0, 0, 1, 0, 0, 0, 1, 0);
    nine.add(9, 0, 0, 10, 0, 0, 9, 1, 0);
    {
        kdrt_tree_stats s = stats_of(build_priced(nine.mesh, KDRT_BUILDER_SAH, 1, 15, 20, 0.2f));
        REQUIRE(s.nodes == 3);
        CHECK(s.sah_cost == Approx(15.0 + 20.0).epsilon(1e-12));
        s = stats_of(build_priced(nine.mesh, KDRT_BUILDER_SAH, 1, 0, 0));  // defaults: the leaf is cheaper
        REQUIRE(s.nodes == 1);
        CHECK(s.sah_cost == Approx(2.0 * KDRT_DEFAULT_SAH_INTERSECTION_COST).epsilon(1e-12));
        s = stats_of(build_priced(nine.mesh, KDRT_BUILDER_SAH, 1, 1, 80, 0.5f));
        REQUIRE(s.nodes == 3);
        CHECK(s.sah_cost == Approx(1.0 + 80.0).epsilon(1e-12));
        s = stats_of(build_priced(nine.mesh, KDRT_BUILDER_SAH, 0, 1, 80));
        CHECK(s.sah_cost == Approx(160.0).epsilon(1e-12));
    }
    // Two triangles are one block: no split pays, whatever the costs.
    Soup two("two");
    two.add(0, 0, 0, 1, 0, 0, 0, 1, 0);
    two.add(9, 0, 0, 10, 0, 0, 9, 1, 0);
    CHECK(stats_of(build_priced(two.mesh, KDRT_BUILDER_SAH, 1, 1, 80, 0.5f)).nodes == 1);

    // No tree (leaf size 0): K_I per block of 8 triangles, whatever the builder; the empty tree
    // costs nothing.
    const common::Mesh ball = kt::sphere(16, 24, 2.0);
    for (const kt::Builder &builder : kt::kBuilders) {
        INFO("builder " << builder.name);
        kdrt_tree_stats s = stats_of(build_priced(ball, builder, 0, 0, 0));
        CHECK(s.sah_cost == Approx(20.0 * ((s.triangles + 7) / 8)).epsilon(1e-12));
        s = stats_of(build_priced(ball, builder, 0, 3, 7));
        CHECK(s.sah_cost == Approx(7.0 * ((s.triangles + 7) / 8)).epsilon(1e-12));
        // A real tree costs less than testing everything, and more than one traversal step.
        s = stats_of(build_priced(ball, builder, 4, 0, 0));
        CHECK(s.sah_cost < 20.0 * ((s.triangles + 7) / 8));
        CHECK(s.sah_cost > KDRT_DEFAULT_SAH_TRAVERSAL_COST);
    }
    Soup flat("one_degenerate");
    flat.add(0, 0, 0, 1, 1, 1, 2, 2, 2);
    CHECK(stats_of(build_priced(flat.mesh, KDRT_BUILDER_SAH, 4, 0, 0)).sah_cost == 0.0);

    // Deeper median trees with other costs, against the model's own boxes (check_stats does the
    // default costs on many more).
    for (const common::Mesh &mesh : {kt::random_soup(500, 5), kt::grid(12, 12, 3), ball})
        for (uint32_t leaf : {1u, 4u, 16u}) {
            INFO(mesh.name << " leaf size " << leaf);
            const Model m = MedianModel(mesh, leaf, default_depth(mesh.triangle_count()), 2.5, 40).result();
            kdrt_tree_stats s = stats_of(build_priced(mesh, KDRT_BUILDER_MEDIAN, leaf, 2.5f, 40));
            REQUIRE(s.nodes == m.nodes);
            CHECK(s.sah_cost == Approx(m.sah_cost).epsilon(1e-9));
            CHECK(s.sah_cost != Approx(MedianModel(mesh, leaf, default_depth(mesh.triangle_count())).result().sah_cost));
        }
}

namespace {

// A tree that would grow deeper than KDRT_MAX_DEPTH. All triangles span y and z in [0, 1] with
// centroids 0.5 there, so only x ever separates anything. D + 3 small "fillers" sit far left;
// D + 1 "markers" span x in [-1000, 1000] with centroids 0, -1, ..., -D; pairs with left end at
// 0.5 - d reach to x = 1000 (centroids far right). At depth d the median centroid is marker d,
// the pair d lies right of it and leaves the below child, which stays almost as large: the
// below chain goes D + 1 levels deep while every above child is a leaf.
common::Mesh deep_scene(int D) {
    Soup s("deep_" + std::to_string(D));
    auto add = [&](float x0, float x1, float x2) { s.add(x0, 0, 0, x1, 1, 0.5f, x2, 0.5f, 1); };
    const float big = 1000;
    for (int i = 0; i < D + 3; ++i) {
        float f = float(-D - 10 - i);
        add(f, f, f);
    }
    for (int j = 0; j <= D; ++j) add(-big, big, -3.0f * j);
    for (int d = 0; d <= D; ++d) {
        float lo = 0.5f - d;
        add(lo, big, big);
        add(lo, big, big);
    }
    return s.mesh;
}

}  // namespace

TEST_CASE("hard: a tree deeper than KDRT_MAX_DEPTH is clamped and traversed correctly", "[hard]") {
    const int D = 70;
    common::Mesh mesh = deep_scene(D);
    const uint32_t n = mesh.triangle_count();
    REQUIRE(n == uint32_t(4 * D + 6));
    // Unclamped, the median build would go past the limit.
    CHECK(MedianModel(mesh, 1, 1000).result().depth > KDRT_MAX_DEPTH);

    kdrt_triangles view = mesh.view();
    for (uint32_t leaf : {1u, 4u, 16u, 64u}) {
        INFO("leaf size " << leaf);
        kt::TreePtr at_limit = build_view(view, leaf, KDRT_MAX_DEPTH);
        kt::TreePtr asked_200 = build_view(view, leaf, 200);
        kdrt_tree_stats a, b;
        kdrt_tree_get_stats(at_limit.get(), &a);
        kdrt_tree_get_stats(asked_200.get(), &b);
        CHECK(b.max_depth == KDRT_MAX_DEPTH);
        CHECK(a.max_depth == b.max_depth);
        CHECK(a.nodes == b.nodes);
        CHECK(a.leaves == b.leaves);
        CHECK(a.triangle_refs == b.triangle_refs);
        check_stats(asked_200.get(), mesh, leaf, 200);

        // Left to right along the whole chain (every level pushes its far child): the first hit
        // is the leftmost filler (index D + 2, at x = -2D - 12), at (0.5, 0.5) inside it.
        for (float zero : {0.0f, -0.0f}) {
            kdrt_hit h = trace(asked_200.get(), ray_of(-2000, 0.5f, 0.5f, 1, zero, -zero));
            require_hit(h, uint32_t(D + 2), float(2000 - 2 * D - 12), 1.0f / 3, 1.0f / 3);
        }
    }

    // Random rays, rays in the split planes and axis rays, against the oracle and the brute force
    // (leaf sizes 1..64 built with max_depth = 200).
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_aabb{{-160, 0, 0}, {10, 1, 1}}, 20000, 70);
    Lcg rng(70);
    const Model model = MedianModel(mesh, 1, KDRT_MAX_DEPTH).result();
    for (const Plane &p : model.planes)
        for (int k = 0; k < 4; ++k) {
            kdrt_ray r = ray_of(p.split, rng.range(0, 1), rng.range(0, 1), (k & 1) ? -0.0f : 0.0f, rng.range(-1, 1), rng.range(-1, 1));
            rays.push_back(r);
            rays.push_back(ray_of(p.split - 50, r.org[1], r.org[2], 1, 0, 0, 0, k < 2 ? kInf : 50.0f));
        }
    check_against_brute_force(view, &mesh, rays, "deep scene", 200);
}

TEST_CASE("hard: a hit beyond the near child's box does not hide a nearer one in the far child", "[hard]") {
    // Root split: x = 5 (median of the centroids 1, 2.67, 4, 5 x5, 6, 7.33).
    //  0      filler at x = 1 (far away in y)
    //  1..5   planar fillers at x = 5 (far away in y)
    //  6      big: (4,-0.5,-5) (4,-0.5,5) (14,2,0), in both children; the ray below meets it at x = 8
    //  7      near: planar at x = 6, above only; the ray meets it at x = 6
    //  8, 9   the mirror image (x -> 10 - x) around z = 20: big at x = 2, near at x = 4
    Soup s("beyond_the_leaf");
    s.add(1, 50, 0, 1, 51, 0, 1, 50, 1);
    for (int j = 0; j < 5; ++j) s.add(5, 60.f + j, 0, 5, 61.f + j, 0, 5, 60.f + j, 1);
    s.add(4, -0.5f, -5, 4, -0.5f, 5, 14, 2, 0);
    s.add(6, -1, -1, 6, 3, -1, 6, -1, 3);
    s.add(6, -0.5f, 15, 6, -0.5f, 25, -4, 2, 20);
    s.add(4, -1, 19, 4, 3, 19, 4, -1, 23);
    const common::Mesh &mesh = s.mesh;

    const Model m = MedianModel(mesh, 1, default_depth(mesh.triangle_count())).result();
    REQUIRE(!m.planes.empty());
    REQUIRE(m.planes[0].axis == 0);
    REQUIRE(m.planes[0].split == 5.0f);

    const kdrt_triangles view = mesh.view();
    for (uint32_t leaf : kLeafSizes) {
        INFO("leaf size " << leaf);
        kt::TreePtr tree = build_view(view, leaf);
        check_stats(tree.get(), mesh, leaf, 0);
        for (float zero : {0.0f, -0.0f}) {
            // (6, 0.5, 0.5) = (6,-1,-1) + u (0,4,0) + v (0,0,4): u = v = 0.375.
            require_hit(trace(tree.get(), ray_of(0, 0.5f, 0.5f, 1, zero, zero)), 7, 6, 0.375f, 0.375f);
            require_hit(trace(tree.get(), ray_of(10, 0.5f, 20.5f, -1, zero, -zero)), 9, 6, 0.375f, 0.375f);
            // Past the near triangles, the big ones: (8, 0.5, 0.5) = p0 + 0.35 e1 + 0.4 e2.
            require_hit(trace(tree.get(), ray_of(0, 0.5f, 0.5f, 1, zero, zero, 6.5f)), 6, 8, 0.35f, 0.4f);
            require_hit(trace(tree.get(), ray_of(10, 0.5f, 20.5f, -1, zero, -zero, 6.5f)), 8, 8, 0.35f, 0.4f);
        }
        kdrt_ray shadow = ray_of(0, 0.5f, 0.5f, 1, 0, 0, 0, 5.5f);
        CHECK(kdrt_occluded(tree.get(), &shadow) == 0);
        shadow.tmax = 6;
        CHECK(kdrt_occluded(tree.get(), &shadow) == 1);
        // Oblique rays through the same pair: from (0, 0.5, 0.5) towards (6, y, z) inside "near"
        // (for y > 0 the big triangle's plane x = 6 + 4y is met only past x = 6).
        for (float y : {0.25f, 0.5f, 0.75f})
            for (float z : {-0.5f, 0.25f, 0.75f, 1.0f}) {
                kdrt_hit h = trace(tree.get(), ray_of(0, 0.5f, 0.5f, 6, y - 0.5f, z - 0.5f));
                INFO("towards (6, " << y << ", " << z << "): " << describe(h));
                CHECK(h.triangle == 7);
                CHECK(h.t == Approx(1.0f).margin(1e-6));
            }
    }
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_aabb{{-1, -1, -5}, {11, 3, 25}}, 20000, 99);
    check_against_brute_force(view, &mesh, rays, mesh.name);
}

TEST_CASE("hard: scenes far from the origin", "[hard]") {
    const std::vector<common::Mesh> meshes = {kt::grid(16, 16, 2), kt::sphere(12, 18, 4.0), kt::random_soup(500, 14)};
    for (double offset : {1e3, 1e5})
        for (const common::Mesh &original : meshes) {
            common::Mesh mesh = kt::translated(original, offset, -offset, 0.5 * offset);
            mesh.name = original.name + " moved by " + std::to_string(offset);
            kdrt_triangles view = mesh.view();
            kdrt_aabb box;
            REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
            std::vector<kdrt_ray> rays = kt::random_rays(box, 20000, uint32_t(offset) + 1);
            std::vector<kdrt_hit> hits = check_against_brute_force(view, &mesh, rays, mesh.name);
            size_t hit_count = 0;
            for (const kdrt_hit &h : hits) hit_count += h.triangle != KDRT_INVALID_ID;
            CHECK(hit_count > rays.size() / 10);
        }
}

TEST_CASE("hard: a range ending at a hit's t still finds it, on a flat tree's box too", "[hard]") {
    // One triangle in the plane y = 0.5: the tree's box is flat, and a ray's rounded entry into it
    // can lie a few ulps past the triangle's own t. The walk's clip to the box is widened for
    // that, so tmax = t (or any tmax past it) keeps the hit.
    common::Mesh flat;
    flat.positions = {-1.5f, 0.5f, 0.5f, 0.5f, 0.5f, -1.25f, 0.5f, 0.5f, 0.5f};
    const kdrt_ray found = {{0x1.0a4fc8p+3f, 0x1.3dd608p+2f, -0x1.2p+4f}, 0, {-0x1.183b4cp+4f, -0x1.1dd60ap+3f, 0x1.26999ap+5f}, kInf, 0};
    common::Mesh sheet = kt::grid(8, 8, 2);  // flat in z, many leaves
    std::vector<kdrt_ray> rays = kt::random_rays(kdrt_tree_bounds(kt::build(sheet, 0, KDRT_BUILDER_MEDIAN).get()), 20000, 77);
    for (const kt::Builder &builder : kt::kBuilders)
        for (uint32_t leaf : {0u, 2u, 4u})
            for (uint32_t flags : {0u, uint32_t(KDRT_BUILD_SCALAR_KERNEL)}) {
                INFO(builder.name << " leaf size " << leaf << " flags " << flags);
                const kt::TreePtr one = kt::build(flat, leaf, builder, flags);
                kdrt_hit hit, again;
                REQUIRE(kdrt_intersect(one.get(), &found, &hit));
                kdrt_ray bounded = found;
                bounded.tmax = hit.t;
                CHECK(kdrt_intersect(one.get(), &bounded, &again));
                CHECK(again.t == hit.t);
                bounded.tmax = std::nextafter(hit.t, kInf);
                CHECK(kdrt_occluded(one.get(), &bounded));
                const kt::TreePtr many = kt::build(sheet, leaf, builder, flags);
                size_t lost = 0;
                for (const kdrt_ray &r : rays) {
                    if (!kdrt_intersect(many.get(), &r, &hit)) continue;
                    bounded = r, bounded.tmax = hit.t;
                    lost += !kdrt_intersect(many.get(), &bounded, &again) || again.t != hit.t || again.triangle != hit.triangle;
                }
                CHECK(lost == 0);
            }
}
