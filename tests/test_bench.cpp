// kdrt-bench's pieces: options, the original's leaf-size stop rule, the CSV format, the scene,
// and the reference comparison behind the Mismatches column.
#include "bench.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <set>
#include <sstream>

namespace {

bool parse(std::vector<const char *> args, kb::Options &opt, std::string &error) {
    args.insert(args.begin(), "kdrt-bench");
    return kb::parse_options(int(args.size()), args.data(), opt, error);
}

std::vector<std::string> split(const std::string &line, char sep) {
    std::vector<std::string> fields;
    std::stringstream in(line);
    std::string field;
    while (std::getline(in, field, sep)) fields.push_back(field);
    if (!line.empty() && line.back() == sep) fields.push_back("");
    return fields;
}

}  // namespace

TEST_CASE("leaf sizes stop after the first one at or above the mesh's triangle count", "[bench]") {
    const std::vector<uint32_t> all = kb::default_leaf_sizes();
    REQUIRE(all == std::vector<uint32_t>{0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024});
    // The original's CSV: TRIANGLE (1 triangle) has rows for 0 and 1; NEFERTITI (562) up to 768.
    CHECK(kb::leaf_sizes_for(all, 1) == std::vector<uint32_t>{0, 1});
    CHECK(kb::leaf_sizes_for(all, 562).back() == 768);
    CHECK(kb::leaf_sizes_for(all, 562).size() == 20);
    CHECK(kb::leaf_sizes_for(all, 512).back() == 512);
    CHECK(kb::leaf_sizes_for(all, 513).back() == 768);
    CHECK(kb::leaf_sizes_for(all, 30658) == all);  // PEGASO: every size
    CHECK(kb::leaf_sizes_for(all, 0) == std::vector<uint32_t>{0});
    CHECK(kb::leaf_sizes_for({8, 2, 64}, 4) == std::vector<uint32_t>{8});  // the given order is kept
}

TEST_CASE("bench options parse and reject bad values by name", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({}, opt, error));
    CHECK(opt.width == 800);
    CHECK(opt.height == 800);
    CHECK(opt.threads == 1);
    CHECK(opt.leaf_sizes == kb::default_leaf_sizes());

    REQUIRE(parse({"--size", "64x48", "--threads", "2", "--repeat", "3", "--leaf-sizes", "0,1,8", "--rays", "diffuse",
                   "-o", "x.csv", "--reference-rays", "0", "--subdivide", "2", "a.off", "dir"},
                  opt, error));
    CHECK(opt.width == 64);
    CHECK(opt.height == 48);
    CHECK(opt.threads == 2);
    CHECK(opt.repeat == 3);
    CHECK(opt.leaf_sizes == std::vector<uint32_t>{0, 1, 8});
    CHECK(opt.rays == kb::RayKind::diffuse);
    CHECK(opt.output == "x.csv");
    CHECK(opt.reference_rays == 0);
    CHECK(opt.subdivide == 2);
    CHECK(opt.inputs == std::vector<std::string>{"a.off", "dir"});

    const std::vector<std::vector<const char *>> bad = {
        {"--size", "800"},       {"--size", "0x10"},        {"--size", "10x-3"},   {"--size", "99999x2"},
        {"--threads", "0"},      {"--threads", "two"},      {"--repeat"},          {"--leaf-sizes", "1,,2"},
        {"--leaf-sizes", "-1"},  {"--rays", "sideways"},    {"--builder", "bvh"},  {"--compare", "tinybvh"},
        {"--subdivide", "99"},   {"--frobnicate"},          {"-o", ""}};
    for (const auto &args : bad) {
        INFO(args[0]);
        error.clear();
        CHECK_FALSE(parse(args, opt, error));
        CHECK(error.find(args[0]) != std::string::npos);  // the message names the option
    }
    CHECK_FALSE(parse({"--builder", "sah"}, opt, error));
    CHECK(error.find("not available") != std::string::npos);
}

TEST_CASE("CSV keeps the original's first three columns", "[bench]") {
    const std::string header = kb::csv_header();
    REQUIRE(header.rfind("Mesh;MaxLeafSize;ElapsedMs;", 0) == 0);
    const std::vector<std::string> columns = split(header, ';');
    REQUIRE(columns == std::vector<std::string>{"Mesh", "MaxLeafSize", "ElapsedMs", "Builder", "Triangles", "BuildMs",
                                                "TraceMs", "MRaysPerSec", "Nodes", "Leaves", "MaxDepth",
                                                "AvgLeafTriangles", "TreeBytes", "Mismatches", "ReferenceRays"});

    kb::Row row;
    row.mesh = "NEFERTITI";
    row.max_leaf_size = 8;
    row.trace_ms = 543.6;
    row.build_ms = 1.25;
    row.builder = "median";
    row.triangles = 564;
    row.rays = 640000;
    row.has_tree_stats = true;
    row.stats.nodes = 201;
    row.stats.leaves = 101;
    row.stats.max_depth = 9;
    row.stats.triangle_refs = 808;
    row.stats.bytes = 4096;
    row.mismatches = 0;
    row.reference_rays = 20000;
    const std::vector<std::string> f = split(kb::csv_row(row), ';');
    REQUIRE(f.size() == columns.size());
    CHECK(f[0] == "NEFERTITI");
    CHECK(f[1] == "8");
    CHECK(f[2] == "544");  // ElapsedMs: whole milliseconds, as the original wrote
    CHECK(f[3] == "median");
    CHECK(f[4] == "564");
    CHECK(f[5] == "1.250");
    CHECK(f[6] == "543.600");
    CHECK(std::stod(f[7]) == Approx(640000 / 543.6 / 1000).epsilon(1e-3));
    CHECK(f[8] == "201");
    CHECK(f[9] == "101");
    CHECK(f[10] == "9");
    CHECK(f[11] == "8.00");
    CHECK(f[12] == "4096");
    CHECK(f[13] == "0");
    CHECK(f[14] == "20000");

    row.builder = "embree";
    row.max_leaf_size = -1;
    row.has_tree_stats = false;
    const std::vector<std::string> e = split(kb::csv_row(row), ';');
    REQUIRE(e.size() == columns.size());
    CHECK(e[1] == "-1");
    for (int c = 8; c <= 12; ++c) CHECK(e[size_t(c)].empty());  // no kd-tree statistics for Embree
}

TEST_CASE("the benchmark scene: mesh fills the view, the wall sits behind it", "[bench]") {
    const kt::Mesh ball = kt::sphere(12, 24, 5.0);
    const kb::Scene scene = kb::make_scene(kt::translated(ball, 100, -40, 7), "BALL");
    REQUIRE(scene.mesh_triangles == ball.triangle_count());
    REQUIRE(scene.geometry.triangle_count() == ball.triangle_count() + 2);
    double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
    for (size_t i = 0; i < size_t(ball.vertex_count()) * 3; ++i)
        lo[i % 3] = std::min(lo[i % 3], double(scene.geometry.positions[i])), hi[i % 3] = std::max(hi[i % 3], double(scene.geometry.positions[i]));
    CHECK(std::max(hi[0] - lo[0], hi[1] - lo[1]) == Approx(2.0).epsilon(1e-5));
    CHECK(0.5 * (lo[0] + hi[0]) == Approx(0.0).margin(1e-5));

    // Every primary ray hits something (mesh or wall), and the centre pixel hits the mesh.
    kt::TreePtr tree = kt::build(scene.geometry, 4);
    const std::vector<kdrt_ray> rays = kb::make_rays(scene, kb::RayKind::primary, 33, 33, tree.get(), 1);
    REQUIRE(rays.size() == 33u * 33u);
    size_t mesh_hits = 0;
    for (const kdrt_ray &r : rays) {
        kdrt_hit h;
        REQUIRE(kdrt_intersect(tree.get(), &r, &h));
        mesh_hits += h.triangle < scene.mesh_triangles;
    }
    kdrt_hit centre;
    REQUIRE(kdrt_intersect(tree.get(), &rays[16 * 33 + 16], &centre));
    CHECK(centre.triangle < scene.mesh_triangles);
    CHECK(mesh_hits > rays.size() / 2);  // a sphere filling the view covers pi/4 of it

    // Diffuse bounces: one per primary hit, leaving on the side the camera sees.
    const std::vector<kdrt_ray> bounces = kb::make_rays(scene, kb::RayKind::diffuse, 33, 33, tree.get(), 1);
    CHECK(bounces.size() == rays.size());
    const std::vector<kdrt_ray> random = kb::make_rays(scene, kb::RayKind::random, 33, 33, tree.get(), 1);
    CHECK(random.size() == rays.size());
}

TEST_CASE("the reference sample is seeded, distinct and sorted", "[bench]") {
    const std::vector<size_t> a = kb::reference_sample(640000, 20000, 7), b = kb::reference_sample(640000, 20000, 7);
    REQUIRE(a == b);
    REQUIRE(a.size() == 20000);
    CHECK(std::set<size_t>(a.begin(), a.end()).size() == a.size());
    CHECK(std::is_sorted(a.begin(), a.end()));
    CHECK(a.back() < 640000);
    CHECK(kb::reference_sample(640000, 20000, 8) != a);
    CHECK(kb::reference_sample(10, 0, 1).size() == 10);
    CHECK(kb::reference_sample(10, 50, 1).size() == 10);
}

TEST_CASE("Mismatches counts answers that contradict the reference", "[bench]") {
    const kt::Mesh ball = kt::sphere(16, 32, 1.0);
    const kb::Scene scene = kb::make_scene(ball, "BALL");
    kt::TreePtr tree = kt::build(scene.geometry, 4);
    const std::vector<kdrt_ray> rays = kb::make_rays(scene, kb::RayKind::primary, 40, 40, tree.get(), 1);
    std::vector<kdrt_hit> hits(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) kdrt_intersect(tree.get(), &rays[i], &hits[i]);
    const kt::Oracle oracle(scene.geometry);
    const std::vector<size_t> sample = kb::reference_sample(rays.size(), 0, 1);
    const std::vector<kt::Reference> refs = kt::reference_all(oracle, rays);
    REQUIRE(kb::count_mismatches(oracle, refs, sample, rays, hits) == 0);

    // Break three answers in the three ways the column counts: a miss, a wrong t, a far triangle.
    std::vector<kdrt_hit> broken = hits;
    const size_t centre = 20 * 40 + 20;
    REQUIRE(broken[centre].triangle < scene.mesh_triangles);
    broken[centre].triangle = KDRT_INVALID_ID;  // missed the ball
    broken[centre + 1].t *= 1.01f;              // t off
    // The wall triangle behind the ball, at the distance the ray really meets it.
    kdrt_hit &behind = broken[centre + 2];
    for (uint32_t w = scene.mesh_triangles; w < scene.geometry.triangle_count(); ++w) {
        double t = oracle.possible_t(rays[centre + 2], w);
        if (t > 0) behind.triangle = w, behind.t = float(t);
    }
    REQUIRE(behind.triangle >= scene.mesh_triangles);
    CHECK(kb::count_mismatches(oracle, refs, sample, rays, broken) == 3);
}
