// The accuracy promises of kdrt.h (QUERIES AND GUARANTEES) on the ray sets of
// bench/oracle/hard_cases.hpp, which kdrt-bench --accuracy runs too:
//  - watertightness: no ray aimed at a vertex or an edge of a closed mesh slips through it, for
//    every builder and several leaf sizes, with the default (watertight) intersector; and
//    KDRT_INTERSECTOR_FAST (Moeller-Trumbore) does leak on the same rays, so the test can fail;
//  - the hard placements (split planes, axis-parallel, parallel to a face, grazing, needles, tiny
//    and coplanar triangles) agree with the double-precision oracle for both intersectors, and
//    every leaf size answers bit for bit as leaf size 0;
//  - far from the origin, secondary rays from kdrt_spawn_ray() never hit the triangle they leave,
//    while the naive origin org + t * dir does, and primary hits still agree with the oracle.
// Ray counts follow KDRT_TEST_RAYS (kt::reference_ray_count(), 100,000 by default): the
// watertight test traces ten times that many rays at each leaf size.
#include "oracle/hard_cases.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace {

// Builders under test: kt::kBuilders, the median one and the SAH one at each quality.
using kt::kBuilders;
const char *intersector_name(kdrt_intersector i) { return i == KDRT_INTERSECTOR_FAST ? "fast" : "watertight"; }

// Leaf sizes 1, 4 and 16 put split planes through vertices and edges (median centroids of small
// integer triangles are often vertex coordinates); 0 tests every triangle.
const uint32_t kWatertightLeafSizes[] = {0, 1, 4, 16};

kt::TreePtr build_tree(const common::Mesh &mesh, const kt::Builder &builder, kdrt_intersector intersector, uint32_t leaf) {
    kdrt_triangles view = mesh.view();
    kdrt_build_options options = kdrt_default_build_options();
    builder.apply(options);
    options.intersector = intersector;
    options.max_leaf_size = leaf;
    kdrt_tree *tree = nullptr;
    kdrt_result r = kdrt_tree_build(&view, &options, &tree, nullptr);
    INFO("build " << mesh.name << " " << builder.name << " " << intersector_name(intersector) << " leaf size " << leaf
                  << ": " << kdrt_result_string(r));
    REQUIRE(r == KDRT_SUCCESS);
    return kt::TreePtr(tree);
}

double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Same triangle and the same bits of t, u and v (a miss: only the triangle is specified).
bool identical(const kdrt_hit &a, const kdrt_hit &b) {
    if (a.triangle != b.triangle) return false;
    return a.triangle == KDRT_INVALID_ID || (std::memcmp(&a.t, &b.t, sizeof a.t) == 0 && std::memcmp(&a.u, &b.u, sizeof a.u) == 0 &&
                                             std::memcmp(&a.v, &b.v, sizeof a.v) == 0);
}

std::string hex_hit(const kdrt_hit &h) {
    if (h.triangle == KDRT_INVALID_ID) return "miss";
    char buf[160];
    std::snprintf(buf, sizeof buf, "triangle %u t=%a (%.9g) u=%a v=%a", h.triangle, h.t, h.t, h.u, h.v);
    return buf;
}

std::string hex_ray(const kdrt_ray &r) {
    char buf[400];
    std::snprintf(buf, sizeof buf, "org=(%a, %a, %a) dir=(%a, %a, %a) tmin=%a tmax=%a", r.org[0], r.org[1], r.org[2], r.dir[0],
                  r.dir[1], r.dir[2], r.tmin, r.tmax);
    return buf;
}

}  // namespace

TEST_CASE("watertight: the generated closed meshes are closed and their must-hit rays are well formed", "[hard][watertight]") {
    for (const common::Mesh &mesh : oracle::closed_meshes(false)) {
        std::string why;
        INFO(mesh.name);
        CHECK(oracle::is_closed(mesh, &why));
        INFO(why);
        const std::vector<kdrt_ray> rays = oracle::rays_at_vertices_and_edges(mesh, 2000, 1);
        REQUIRE(rays.size() == 2000);
        for (const kdrt_ray &r : rays) {
            REQUIRE(std::isfinite(r.org[0] + r.org[1] + r.org[2] + r.dir[0] + r.dir[1] + r.dir[2]));
            REQUIRE((r.dir[0] != 0 || r.dir[1] != 0 || r.dir[2] != 0));
        }
        // Deterministic for a seed.
        const std::vector<kdrt_ray> again = oracle::rays_at_vertices_and_edges(mesh, 2000, 1);
        CHECK(std::memcmp(rays.data(), again.data(), rays.size() * sizeof(kdrt_ray)) == 0);
    }
    // is_closed sees an open mesh and a hole.
    common::Mesh open = kt::grid(4, 4, 1);
    CHECK_FALSE(oracle::is_closed(open));
    common::Mesh holed = oracle::closed_meshes(false).front();
    holed.indices.resize(holed.indices.size() - 3);
    CHECK_FALSE(oracle::is_closed(holed));
    // The torus kdrt-bench and kdrt-render-mesh generate is closed, its seams shared, tilted or not.
    for (double tilt : {0.0, 0.6}) {
        const common::Mesh ring = common::torus(12, 8, 1.0, 0.3, tilt);
        CHECK(ring.vertex_count() == 96);
        CHECK(ring.triangle_count() == 192);
        CHECK(oracle::is_closed(ring));
    }
}

TEST_CASE("watertight: no ray aimed at a vertex or an edge slips through a closed mesh", "[hard][watertight]") {
    const auto start = std::chrono::steady_clock::now();
    // 10x the reference count of distinct rays (10^6 by default), shared evenly by the meshes;
    // every ray is traced at leaf sizes 1, 4 and 16, and as many as the brute force affords
    // (about 2 * 10^6 triangle tests per mesh by default) at leaf size 0. KDRT_INTERSECTOR_FAST
    // takes the same rays at leaf size 4 and the brute force's share at leaf size 0.
    const size_t total = 10 * kt::reference_ray_count();
    const double scale = double(kt::reference_ray_count()) / 100000.0;
    std::vector<common::Mesh> meshes = oracle::closed_meshes(true);
    const size_t generated = oracle::closed_meshes(false).size();
    REQUIRE(meshes.size() >= generated);
    if (meshes.size() == generated) WARN("no closed shared meshes (KDRT_MESH_DIR absent?): generated meshes only");
    // Scaled-down runs (the sanitizer build) leave out the shared meshes over 20,000 triangles,
    // whose builds and traversals would dominate them.
    if (scale < 1)
        meshes.erase(std::remove_if(meshes.begin() + std::ptrdiff_t(generated), meshes.end(),
                                    [](const common::Mesh &m) { return m.triangle_count() > 20000; }),
                     meshes.end());

    std::ostringstream log;
    log << "rays at vertices and edges of " << meshes.size() << " closed meshes; leaks\n"
        << "  (watertight: all leaf sizes; fast: leaf size 0 on the brute rays, 4 on all)\n"
        << "  mesh               triangles    rays   brute  watertight  fast 0  fast 4";
    size_t distinct = 0, traced = 0, fast_leaks = 0;
    for (const common::Mesh &mesh : meshes) {
        std::string why;
        INFO(mesh.name);
        REQUIRE(oracle::is_closed(mesh, &why));
        const size_t count = std::max<size_t>(total / meshes.size() + 1, 1000);
        const std::vector<kdrt_ray> rays = oracle::rays_at_vertices_and_edges(mesh, count, 0xC0FFEE);
        REQUIRE(rays.size() == count);
        distinct += count;
        const size_t brute = std::min(count, std::max<size_t>(size_t(2e6 * scale / mesh.triangle_count()), 100));
        const std::vector<kdrt_ray> brute_rays(rays.begin(), rays.begin() + std::ptrdiff_t(brute));
        size_t tight_leaks = 0, fast_leaks_brute = 0, fast_leaks_tree = 0;
        for (const kt::Builder &builder : kBuilders)
            for (uint32_t leaf : kWatertightLeafSizes) {
                const std::vector<kdrt_ray> &set = leaf == 0 ? brute_rays : rays;
                kt::TreePtr tight = build_tree(mesh, builder, KDRT_INTERSECTOR_WATERTIGHT, leaf);
                const oracle::ErrorCounts w = oracle::count_leaks(tight.get(), set);
                traced += w.rays;
                tight_leaks += w.leaks;
                INFO(builder.name << " builder, leaf size " << leaf << ", " << w.rays << " rays: " << w.leaks
                                           << " leaks; first: " << w.first);
                CHECK(w.leaks == 0);
                CHECK(w.rays == set.size());
                if (leaf == 0 || leaf == 4) {
                    kt::TreePtr fast = build_tree(mesh, builder, KDRT_INTERSECTOR_FAST, leaf);
                    (leaf == 0 ? fast_leaks_brute : fast_leaks_tree) += oracle::count_leaks(fast.get(), set).leaks;
                }
            }
        fast_leaks += fast_leaks_brute + fast_leaks_tree;
        char row[160];
        std::snprintf(row, sizeof row, "\n  %-18s %9u %7zu %7zu %11zu %7zu %7zu", mesh.name.substr(0, 18).c_str(), mesh.triangle_count(),
                      count, brute, tight_leaks, fast_leaks_brute, fast_leaks_tree);
        log << row;
    }
    char tail[200];
    std::snprintf(tail, sizeof tail, "\n  %zu distinct rays, %zu watertight traces, %zu fast leaks; %.1f s", distinct, traced,
                  fast_leaks, seconds_since(start));
    log << tail;
    WARN(log.str());
    CHECK(distinct >= total);
    // The rays are hard enough that Moeller-Trumbore lets some through: the test can fail.
    CHECK(fast_leaks > 0);
}

TEST_CASE("watertight: rays lying exactly in a triangle's plane hit it only where its box meets them, and none slips through beside it", "[hard][watertight]") {
    // kdrt.h's rule: a ray lying exactly in a triangle's plane and meeting it may hit it (at a t
    // within the triangle's bounding box) or miss it. The watertight test shears the corners with the rounded
    // dir[kx] / dir[kz], so the projected triangle is a sliver a rounding wide rather than a
    // segment, and about 14% of in-plane rays that touch their triangle come out as hits there
    // (found by the in_plane set of oracle::hard_sets). Refusing those hits is no fix: the second half
    // below is a ray that leaves the closed int_bumpy_box_10 through the edge (12,2,5)-(11,2,6)
    // shared by triangles 230 and 250, whose plane holds the ray; in the sheared coordinates it
    // lies inside 250's sliver and outside 230, so refusing in-plane hits lets it slip through.
    // So: in-plane hits must be rays whose line meets the triangle, at a t within its bounding
    // box (the oracle's in_plane_contact), never elsewhere, and the edge-on exit must still hit.
    struct Case {
        float p[9];
        kdrt_ray ray;
    };
    const Case cases[] = {
        {{-3, 2, 3, -4, -2, -3, -1, -3, -2}, kt::ray_of(-2.5f, 20.25f, 27.25f, 0, -13, -17)},  // through the midpoint of edge 1-2 at t = 1.75
        {{3, -1, 1, -2, -3, 3, -3, -1, -2}, kt::ray_of(32, 1, 11, -17, -2, -4)},               // through corner 1 at t = 2
        {{-2, -4, 0, -1, -3, 1, -4, -1, -3}, kt::ray_of(7.75f, -13, 13.5f, -5, 5, -7)},        // through edge 0-2 at t = 2.25
    };
    size_t in_plane_hits = 0;
    for (const Case &c : cases) {
        common::Mesh mesh;
        mesh.name = "one_triangle";
        mesh.positions.assign(c.p, c.p + 9);
        double e1[3], e2[3];
        for (int a = 0; a < 3; ++a) e1[a] = double(c.p[3 + a]) - c.p[a], e2[a] = double(c.p[6 + a]) - c.p[a];
        const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        const double along = n[0] * c.ray.dir[0] + n[1] * c.ray.dir[1] + n[2] * c.ray.dir[2];
        const double off = n[0] * (c.ray.org[0] - c.p[0]) + n[1] * (c.ray.org[1] - c.p[1]) + n[2] * (c.ray.org[2] - c.p[2]);
        REQUIRE(along == 0);  // parallel to the plane, exactly
        REQUIRE(off == 0);    // and in it
        const oracle::Oracle oracle(mesh);
        CHECK(std::isnan(oracle.possible_t(c.ray, 0)));  // no crossing: only in-plane contact
        // The rule can fail: contact points off the segment are refused.
        CHECK_FALSE(oracle.in_plane_contact(c.ray, 0, 100.0));
        CHECK_FALSE(oracle.in_plane_contact(c.ray, 0, -1.0));
        for (kdrt_intersector intersector : {KDRT_INTERSECTOR_FAST, KDRT_INTERSECTOR_WATERTIGHT})
            for (uint32_t leaf : {0u, 1u}) {
                kt::TreePtr tree = build_tree(mesh, kt::kBuilders[0], intersector, leaf);
                kdrt_hit h;
                const int hit = kdrt_intersect(tree.get(), &c.ray, &h);
                in_plane_hits += hit;
                INFO(intersector_name(intersector) << " intersector, leaf size " << leaf << ": " << hex_ray(c.ray) << " gives "
                                                   << hex_hit(h));
                if (hit) CHECK(oracle.in_plane_contact(c.ray, 0, h.t));
                CHECK(kdrt_occluded(tree.get(), &c.ray) == hit);
            }
    }
    WARN("in-plane rays reported as hits (within the triangle's box): " << in_plane_hits << " of 12");

    // The second half: no leak where the ray leaves through an edge of a triangle whose plane
    // holds it (ray 17181 of rays_at_vertices_and_edges(int_bumpy_box_10, ..., 0xC0FFEE)).
    const std::vector<common::Mesh> closed = oracle::closed_meshes(false);
    const auto box = std::find_if(closed.begin(), closed.end(), [](const common::Mesh &m) { return m.name == "int_bumpy_box_10"; });
    REQUIRE(box != closed.end());
    const kdrt_ray out = kt::ray_of(5, 3, 10, 6.75f, -1, -4.75f);  // from inside, through (11.75, 2, 5.25) at t = 1
    {
        // The setting: 250 = (12,2,5) (10,3,5) (11,2,6) holds the ray in its plane; 230 shares its edge.
        double p[3][3], q[3][3];
        box->corners(250, p);
        box->corners(230, q);
        const double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
        const double e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
        const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        REQUIRE(n[0] * out.dir[0] + n[1] * out.dir[1] + n[2] * out.dir[2] == 0);
        REQUIRE(n[0] * (out.org[0] - p[0][0]) + n[1] * (out.org[1] - p[0][1]) + n[2] * (out.org[2] - p[0][2]) == 0);
        REQUIRE((p[0][0] == 12 && p[0][1] == 2 && p[0][2] == 5 && p[2][0] == 11 && p[2][1] == 2 && p[2][2] == 6));
        REQUIRE((q[1][0] == 12 && q[1][1] == 2 && q[1][2] == 5 && q[2][0] == 11 && q[2][1] == 2 && q[2][2] == 6));
    }
    for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST})
        for (uint32_t leaf : kWatertightLeafSizes) {
            kt::TreePtr tree = build_tree(*box, kt::kBuilders[0], intersector, leaf);
            kdrt_hit h;
            const int hit = kdrt_intersect(tree.get(), &out, &h);
            INFO(intersector_name(intersector) << " intersector, leaf size " << leaf << ": " << hex_hit(h));
            CHECK(hit == 1);
            CHECK(h.t <= 1.0f);
        }
}

TEST_CASE("hard sets: every answer agrees with the oracle and every leaf size answers as leaf size 0", "[hard]") {
    const auto start = std::chrono::steady_clock::now();
    const size_t per_set = std::max<size_t>(kt::reference_ray_count() / 5, 1000);
    const std::vector<oracle::HardSet> sets = oracle::hard_sets(per_set, 2026);
    REQUIRE(sets.size() >= 8);
    std::ostringstream log;
    log << "hard sets, " << per_set << " rays each and a tenth more at random; the worst over\n"
        << "  leaf sizes 0..64 (unlike: answers unlike leaf size 0's, summed)\n"
        << "  set                intersector  hits  exact  ambig  wrong  false  unlike";
    for (const oracle::HardSet &set : sets) {
        INFO(set.name << ": " << set.mesh.triangle_count() << " triangles, " << set.rays.size() << " rays");
        REQUIRE(!set.rays.empty());
        const oracle::Oracle oracle(set.mesh);
        const std::vector<oracle::Reference> refs = oracle::reference_all(oracle, set.rays);
        for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST})
            for (const kt::Builder &builder : kBuilders) {
                std::vector<kdrt_hit> brute;
                size_t hit_count = 0, exact = 0, ambiguous = 0, wrong = 0, false_hits = 0, unlike_total = 0;
                for (uint32_t leaf : kt::kLeafSizes) {
                    kt::TreePtr tree = build_tree(set.mesh, builder, intersector, leaf);
                    std::vector<kdrt_hit> hits;
                    oracle::Agreement tally;
                    const oracle::ErrorCounts e = oracle::count_mismatches(tree.get(), oracle, refs, set.rays, &hits, &tally);
                    if (leaf == 0) brute = hits;
                    size_t unlike = 0, hit_now = 0;
                    std::string first_unlike;
                    for (size_t i = 0; i < hits.size(); ++i) {
                        hit_now += hits[i].triangle != KDRT_INVALID_ID;
                        if (!identical(hits[i], brute[i]) && unlike++ == 0)
                            first_unlike = "ray " + std::to_string(i) + " " + hex_ray(set.rays[i]) + ": leaf size 0 gives " +
                                           hex_hit(brute[i]) + ", this tree " + hex_hit(hits[i]);
                    }
                    hit_count = std::max(hit_count, hit_now), exact = std::max(exact, tally.exact);
                    ambiguous = std::max(ambiguous, tally.ambiguous), wrong = std::max(wrong, e.mismatches);
                    false_hits = std::max(false_hits, e.false_hits), unlike_total += unlike;
                    INFO(intersector_name(intersector) << " intersector, " << builder.name << " builder, leaf size " << leaf);
                    {
                        INFO("first wrong: " << e.first);
                        CHECK(e.mismatches == 0);
                        CHECK(e.false_hits == 0);
                    }
                    {
                        // kdrt.h's exception to "as leaf size 0": a rounding-error hit on a
                        // triangle beyond a split plane the ray never crosses. Moeller-Trumbore
                        // makes them at edges a hair off the ray (axis_parallel: an edge at
                        // z = 1.8e-16 over a ray at z = 0, which leaf size 0 "hits" and the SAH
                        // tree rightly culls). Both answers agree with the oracle (checked above).
                        INFO("first: " << first_unlike);
                        if (intersector == KDRT_INTERSECTOR_WATERTIGHT || builder.builder == KDRT_BUILDER_MEDIAN) CHECK(unlike == 0);
                        else CHECK(unlike * 1000 <= hits.size());
                    }
                    CHECK(hit_now > 0);
                }
                char row[160];
                std::snprintf(row, sizeof row, "\n  %-18s %-11s %5zu %6zu %6zu %6zu %6zu %7zu", set.name.c_str(), intersector_name(intersector),
                              hit_count, exact, ambiguous, wrong, false_hits, unlike_total);
                log << row;
            }
    }
    char tail[64];
    std::snprintf(tail, sizeof tail, "\n  %.1f s", seconds_since(start));
    log << tail;
    WARN(log.str());
}

TEST_CASE("far from the origin: spawned rays never hit the triangle they leave", "[hard][far]") {
    const auto start = std::chrono::steady_clock::now();
    const size_t count = std::max<size_t>(kt::reference_ray_count() / 10, 1000);
    // Closed, open and soup scenes of size ~10 around the origin.
    const std::vector<common::Mesh> scenes = {kt::sphere(16, 24, 4.0), kt::grid(16, 16, 3), kt::random_soup(1000, 15)};
    std::ostringstream log;
    log << "far from the origin: " << count << " primary rays per scene, 4 spawned per hit;\n"
        << "  wrong: primary / spawned rays unlike the oracle; self-hits summed over\n"
        << "  leaf sizes 0 (a twentieth of the rays), 1, 4, 16\n"
        << "  scene         offset scale  intersector  wrong  wrong2  self  naive  spawned";
    size_t naive_far[2] = {0, 0};  // naive self-hits at 1e5 and 1e7
    for (const common::Mesh &original : scenes)
        for (double offset : {0.0, 1e3, 1e5, 1e7}) {
            // Far out the scene grows with its offset: at 1e7 a float ulp is 1, and a scene of size
            // 10 would collapse onto a few lattice points. At 1e-4 of the offset (1000 times larger
            // at 1e7, 10 times at 1e5) its corners keep their places to 1e-3 of its size.
            const double scale = std::max(1.0, offset * 1e-4);
            const common::Mesh mesh = oracle::translated(original, offset, scale);
            INFO(mesh.name << " (scale " << scale << ")");
            kdrt_triangles view = mesh.view();
            kdrt_aabb box;
            REQUIRE(kdrt_aabb_of_triangles(&view, &box, nullptr) == KDRT_SUCCESS);
            kdrt_build_report report;
            kdrt_tree *probe = nullptr;
            REQUIRE(kdrt_tree_build(&view, nullptr, &probe, &report) == KDRT_SUCCESS);
            kdrt_tree_free(probe);
            CHECK(report.degenerate_triangles == 0);  // the scaled scene is still a valid mesh
            const std::vector<kdrt_ray> rays = kt::random_rays(box, count, uint32_t(std::log10(offset + 1)) + 17);
            const oracle::Oracle oracle(mesh);
            const std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
            for (kdrt_intersector intersector : {KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST})
                for (const kt::Builder &builder : kBuilders) {
                    // The secondary rays, spawned once from the leaf size 4 tree's hits (every leaf
                    // size hits the same), and their own references.
                    std::vector<kdrt_ray> spawned;
                    {
                        kt::TreePtr tree = build_tree(mesh, builder, intersector, 4);
                        for (const oracle::SpawnedRay &s : oracle::spawn_rays(tree.get(), rays)) spawned.push_back(s.ray);
                    }
                    const std::vector<oracle::Reference> spawned_refs = oracle::reference_all(oracle, spawned);
                    size_t wrong = 0, wrong_spawned = 0, self = 0, naive = 0, spawned_count = 0;
                    for (uint32_t leaf : {0u, 1u, 4u, 16u}) {
                        // Leaf size 0 (every triangle for every ray) takes a twentieth of the rays.
                        const size_t n = leaf == 0 ? count / 20 : count;
                        const std::vector<kdrt_ray> some(rays.begin(), rays.begin() + std::ptrdiff_t(n));
                        const std::vector<oracle::Reference> some_refs(refs.begin(), refs.begin() + std::ptrdiff_t(n));
                        kt::TreePtr tree = build_tree(mesh, builder, intersector, leaf);
                        const oracle::ErrorCounts m = oracle::count_mismatches(tree.get(), oracle, some_refs, some);
                        const oracle::ErrorCounts m2 = leaf == 0 ? oracle::ErrorCounts() : oracle::count_mismatches(tree.get(), oracle, spawned_refs, spawned);
                        const oracle::ErrorCounts s = oracle::count_self_hits(tree.get(), some, oracle::Spawn::kdrt);
                        const oracle::ErrorCounts nv = oracle::count_self_hits(tree.get(), some, oracle::Spawn::naive);
                        wrong += m.mismatches, wrong_spawned += m2.mismatches, self += s.self_hits, naive += nv.self_hits;
                        spawned_count += s.rays;
                        if (offset == 1e5) naive_far[0] += nv.self_hits;
                        if (offset == 1e7) naive_far[1] += nv.self_hits;
                        INFO(intersector_name(intersector) << " intersector, " << builder.name << " builder, leaf size " << leaf);
                        {
                            INFO("first wrong: " << m.first);
                            CHECK(m.mismatches == 0);
                        }
                        {
                            INFO("spawned rays: first wrong: " << m2.first);
                            CHECK(m2.mismatches == 0);
                        }
                        {
                            INFO(s.self_hits << " self-hits of " << s.rays << " spawned rays; first: " << s.first);
                            CHECK(s.self_hits == 0);
                        }
                        CHECK(s.rays * 10 > n * 4);  // a tenth of the rays hit, or more
                        CHECK(s.rays == nv.rays);
                    }
                    char row[160];
                    std::snprintf(row, sizeof row, "\n  %-13s %6.0e %5.0f  %-11s %5zu %7zu %5zu %6zu %8zu", original.name.substr(0, 13).c_str(),
                                  offset, scale, intersector_name(intersector), wrong, wrong_spawned, self, naive, spawned_count);
                    log << row;
                }
        }
    char tail[160];
    std::snprintf(tail, sizeof tail, "\n  naive self-hits: %zu at 1e5, %zu at 1e7; %.1f s", naive_far[0], naive_far[1], seconds_since(start));
    log << tail;
    WARN(log.str());
    // Without the offset, far-away secondary rays do hit their own triangle: the test can fail.
    CHECK(naive_far[0] > 0);
    CHECK(naive_far[1] > 0);
}

TEST_CASE("spawn: kdrt_offset_ray_origin moves a point off its surface towards dir at any magnitude, and takes odd input", "[hard][far]") {
    const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
    const float normal[3] = {0.6f, -0.8f, 0.0f};
    for (float scale : {0.0f, -0.0f, 1e-3f, -1e-3f, 0.03f, 1.0f, -1.0f, 1e3f, -1e5f, 1e7f, -1e7f, 3e38f, -3e38f}) {
        const float point[3] = {scale, -scale, 0.5f * scale};
        for (float side : {1.0f, -1.0f}) {
            const float dir[3] = {side * normal[0], side * normal[1], 0.25f};
            float out[3];
            kdrt_offset_ray_origin(point, normal, dir, out);
            INFO("point magnitude " << scale << ", side " << side << ": out " << out[0] << " " << out[1] << " " << out[2]);
            double along = 0;
            for (int a = 0; a < 3; ++a) {
                CHECK(std::isfinite(out[a]));
                along += (double(out[a]) - point[a]) * normal[a];
            }
            // Moved off the plane through point, to dir's side (next to FLT_MAX nothing can move).
            if (std::fabs(scale) < 1e38f) CHECK(along * side > 0);
            else CHECK(along * side >= 0);
            // By a few hundred ulps at most: relative to the point's magnitude.
            for (int a = 0; a < 3; ++a)
                CHECK(std::fabs(double(out[a]) - point[a]) <= std::max(1.0 / 65536, 512 * std::fabs(double(point[a])) * 0x1p-23));
        }
    }
    // Odd input leaves the point where it is: no normal, a NaN or infinite normal.
    const float p[3] = {1, 2, 3}, d[3] = {0, 0, 1};
    for (const std::array<float, 3> &bad : {std::array<float, 3>{0, 0, 0}, std::array<float, 3>{nan, 1, 0}, std::array<float, 3>{0, inf, 0}}) {
        float out[3];
        kdrt_offset_ray_origin(p, bad.data(), d, out);
        CHECK((out[0] == 1 && out[1] == 2 && out[2] == 3));
    }
}
