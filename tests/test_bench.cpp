// kdrt-bench's pieces: options, the original's leaf-size stop rule, the CSV format, the scene,
// the reference comparison behind the Mismatches column, the diffuse rays' spawned origins, and
// the --accuracy sets, rows and summary, and the --scene worlds, their comparison and rows, and
// the --scene frames world and rows, and --save-load's options and rows.
#include "bench.hpp"
#include "frames.hpp"
#include "saved_trees.hpp"
#include "scenes.hpp"
#include "test_support.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <sstream>

namespace {

bool parse(std::vector<const char *> args, kb::Options &opt, std::string &error) {
    args.insert(args.begin(), "kdrt-bench");
    return kb::parse_options(int(args.size()), args.data(), opt, error);
}

// Each command line of bad is refused, with a message that names one of its options.
void check_refused(const std::vector<std::vector<const char *>> &bad) {
    kb::Options opt;
    std::string error;
    for (const auto &args : bad) {
        INFO(args[0] << " " << (args.size() > 1 ? args[1] : "") << " " << (args.size() > 2 ? args[2] : ""));
        error.clear();
        CHECK_FALSE(parse(args, opt, error));
        bool named = false;
        for (const char *arg : args) named = named || (arg[0] == '-' && error.find(arg) != std::string::npos);
        CHECK(named);
    }
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
    const std::vector<uint32_t> all = kb::sweep_leaf_sizes();
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
    CHECK(opt.leaf_sizes == std::vector<uint32_t>{4});

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
    REQUIRE(parse({"--builder", "sah"}, opt, error));
    CHECK(opt.builders == std::vector<std::string>{"sah"});
    REQUIRE(parse({"--builder", "median,sah"}, opt, error));
    CHECK(opt.builders == std::vector<std::string>{"median", "sah"});
    CHECK_FALSE(parse({"--builder", "sah,"}, opt, error));
}

TEST_CASE("bench defaults: kdrt's default tree beside Embree, and --sweep, the original's leaf-size run", "[bench]") {
    kb::Options opt;
    std::string error;
    // No option: the SAH builder at its default quality and costs, leaf size 4, once, and Embree
    // beside it unless the command line says (main() asks whether this kdrt-bench has Embree).
    REQUIRE(parse({}, opt, error));
    CHECK(opt.builders == std::vector<std::string>{"sah"});
    CHECK(opt.leaf_sizes == std::vector<uint32_t>{kb::kDefaultLeafSize});
    CHECK(kb::kDefaultLeafSize == kdrt_default_build_options().max_leaf_size);
    CHECK_FALSE(opt.sweep);
    CHECK_FALSE(opt.compare_chosen);
    CHECK_FALSE(opt.quiet);
    std::vector<kb::BuildVariant> v = kb::build_variants(opt);
    REQUIRE(v.size() == 1);
    CHECK(v[0].options.builder == KDRT_BUILDER_SAH);
    CHECK(v[0].options.quality == KDRT_BUILD_QUALITY_DEFAULT);
    CHECK(v[0].sah_costs == "30:20:0.1");
    REQUIRE(parse({"--compare", "none"}, opt, error));
    CHECK((opt.compare_chosen && !opt.compare_embree));
    REQUIRE(parse({"--compare", "embree"}, opt, error));
    CHECK((opt.compare_chosen && opt.compare_embree));

    // --sweep: the median builder over the original's leaf sizes, no Embree; an option given
    // beside it wins.
    REQUIRE(parse({"--sweep"}, opt, error));
    CHECK(opt.sweep);
    CHECK(opt.builders == std::vector<std::string>{"median"});
    CHECK(opt.leaf_sizes == kb::sweep_leaf_sizes());
    CHECK((opt.compare_chosen && !opt.compare_embree));
    REQUIRE(parse({"--builder", "sah", "--sweep", "--compare", "embree", "--repeat", "2"}, opt, error));
    CHECK(opt.builders == std::vector<std::string>{"sah"});
    CHECK(opt.leaf_sizes == kb::sweep_leaf_sizes());
    CHECK(opt.compare_embree);
    REQUIRE(parse({"--sweep", "--leaf-sizes", "0,4"}, opt, error));
    CHECK(opt.builders == std::vector<std::string>{"median"});
    CHECK(opt.leaf_sizes == std::vector<uint32_t>{0, 4});
    REQUIRE(parse({"--quiet"}, opt, error));
    CHECK(opt.quiet);
    REQUIRE(parse({"-q"}, opt, error));
    CHECK(opt.quiet);

    // The other modes have no leaf sizes to sweep.
    CHECK_FALSE(parse({"--accuracy", "--sweep"}, opt, error));
    CHECK(error.find("--sweep does not apply to --accuracy") != std::string::npos);
    CHECK_FALSE(parse({"--scene", "merged", "--sweep"}, opt, error));
    CHECK(error.find("--sweep does not apply to --scene") != std::string::npos);

    // --help says what the default run is and names the flag for the original's.
    const std::string help = kb::usage();
    CHECK(help.find("SAH builder, default quality, max leaf size 4") != std::string::npos);
    CHECK(help.find("--sweep             the original benchmark") != std::string::npos);
    CHECK(help.find("--compare embree|none") != std::string::npos);
}

TEST_CASE("bench option values are names in either case", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({"--builder", "SAH,Median", "--intersector", "Fast,WATERTIGHT", "--quality", "FAST,High", "--rays",
                   "Shadow", "--query", "PLAIN,Filter", "--compare", "EMBREE"},
                  opt, error));
    CHECK(opt.builders == std::vector<std::string>{"sah", "median"});
    CHECK(opt.intersectors == std::vector<kdrt_intersector>{KDRT_INTERSECTOR_FAST, KDRT_INTERSECTOR_WATERTIGHT});
    CHECK(opt.qualities == std::vector<kdrt_build_quality>{KDRT_BUILD_QUALITY_FAST, KDRT_BUILD_QUALITY_HIGH});
    CHECK(opt.rays == kb::RayKind::shadow);
    CHECK(opt.queries == std::vector<std::string>{"plain", "filter"});
    CHECK(opt.compare_embree);
    REQUIRE(parse({"--rays", "DIFFUSE", "--compare", "None"}, opt, error));
    CHECK(opt.rays == kb::RayKind::diffuse);
    CHECK((opt.compare_chosen && !opt.compare_embree));
    REQUIRE(parse({"--scene", "Merged,FIELD"}, opt, error));
    CHECK(opt.scenes == std::vector<std::string>{"merged", "field"});
    // A wrong name is still wrong, and named as it was given.
    CHECK_FALSE(parse({"--builder", "SAHH"}, opt, error));
    CHECK(error.find("'SAHH'") != std::string::npos);
    CHECK_FALSE(parse({"--rays", "Sideways"}, opt, error));
    CHECK(error.find("'Sideways'") != std::string::npos);
}

TEST_CASE("bench option --sah-costs: a SAH variant per triple, named in SahCosts", "[bench]") {
    kb::Options opt;
    std::string error;
    // Without it: one SAH variant with kdrt.h's defaults, the median builder unpriced.
    REQUIRE(parse({"--builder", "median,sah"}, opt, error));
    CHECK(opt.sah_costs.empty());
    std::vector<kb::BuildVariant> v = kb::build_variants(opt);
    REQUIRE(v.size() == 2);
    CHECK(v[0].builder == "median");
    CHECK(v[0].options.builder == KDRT_BUILDER_MEDIAN);
    CHECK(v[0].sah_costs.empty());
    CHECK(v[1].builder == "sah");
    CHECK(v[1].options.builder == KDRT_BUILDER_SAH);
    CHECK(v[1].sah_costs == "30:20:0.1");
    CHECK(v[1].options.sah_traversal_cost == KDRT_DEFAULT_SAH_TRAVERSAL_COST);

    REQUIRE(parse({"--sah-costs", "1:80:0.5,15:20:0.2,2.5:40:1e-3", "--builder", "sah,median"}, opt, error));
    REQUIRE(opt.sah_costs.size() == 3);
    v = kb::build_variants(opt);
    REQUIRE(v.size() == 4);  // in the order given: three SAH variants, then the median
    CHECK(v[0].sah_costs == "1:80:0.5");
    CHECK(v[0].options.sah_traversal_cost == 1.0f);
    CHECK(v[0].options.sah_intersection_cost == 80.0f);
    CHECK(v[0].options.sah_empty_bonus == 0.5f);
    CHECK(v[1].sah_costs == "15:20:0.2");
    CHECK(v[2].sah_costs == "2.5:40:0.001");
    CHECK(v[2].options.sah_empty_bonus == 0.001f);
    CHECK(v[3].builder == "median");
    CHECK(v[3].sah_costs.empty());

    const std::vector<std::string> bad = {"15:20", "15:20:0.2:1", "15:20:0.2,", ",1:80:0.5", "a:20:0.2", "15::0.2",
                                          "15:20:0.2x", " 15:20:0.2", "0:20:0.2", "15:0:0.2", "15:20:0", "15:20:1",
                                          "-1:20:0.2", "15:20:-0.1", "nan:20:0.2", "inf:20:0.2", "15:2e6:0.2", ""};
    for (const std::string &costs : bad) {
        INFO("'" << costs << "'");
        error.clear();
        CHECK_FALSE(parse({"--builder", "sah", "--sah-costs", costs.c_str()}, opt, error));
        CHECK(error.find("--sah-costs") != std::string::npos);
    }
    // Only the SAH builder has cost constants, and --accuracy has no builder choice.
    REQUIRE(parse({"--sah-costs", "1:80:0.5"}, opt, error));  // the default builder is SAH's
    CHECK_FALSE(parse({"--builder", "median", "--sah-costs", "1:80:0.5"}, opt, error));
    CHECK(error.find("--builder sah") != std::string::npos);
    CHECK_FALSE(parse({"--sweep", "--sah-costs", "1:80:0.5"}, opt, error));
    CHECK(error.find("--builder sah") != std::string::npos);
    CHECK_FALSE(parse({"--accuracy", "--builder", "sah", "--sah-costs", "1:80:0.5"}, opt, error));
    CHECK(error.find("--sah-costs does not apply to --accuracy") != std::string::npos);
}

TEST_CASE("bench option --quality: a SAH variant per quality and triple, named in Quality", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({"--builder", "median,sah"}, opt, error));
    std::vector<kb::BuildVariant> v = kb::build_variants(opt);
    REQUIRE(v.size() == 2);
    CHECK(v[0].quality.empty());
    CHECK(v[1].quality == "default");
    CHECK(v[1].options.quality == KDRT_BUILD_QUALITY_DEFAULT);

    REQUIRE(parse({"--builder", "sah", "--quality", "high,fast", "--sah-costs", "1:80:0.5,15:20:0.2"}, opt, error));
    v = kb::build_variants(opt);
    REQUIRE(v.size() == 4);  // each quality in the order given, each with every triple
    CHECK((v[0].quality == "high" && v[0].options.quality == KDRT_BUILD_QUALITY_HIGH && v[0].sah_costs == "1:80:0.5"));
    CHECK((v[1].quality == "high" && v[1].sah_costs == "15:20:0.2"));
    CHECK((v[2].quality == "fast" && v[2].options.quality == KDRT_BUILD_QUALITY_FAST && v[2].sah_costs == "1:80:0.5"));
    CHECK((v[3].quality == "fast" && v[3].options.builder == KDRT_BUILDER_SAH));
    REQUIRE(parse({"--builder", "sah", "--quality", "medium"}, opt, error));
    CHECK(kb::build_variants(opt)[0].options.quality == KDRT_BUILD_QUALITY_MEDIUM);

    for (const char *bad : {"", "low", "fast,", "fast,,high", "FASTER", "medium high"}) {
        INFO("'" << bad << "'");
        error.clear();
        CHECK_FALSE(parse({"--builder", "sah", "--quality", bad}, opt, error));
        CHECK(error.find("--quality") != std::string::npos);
    }
    CHECK_FALSE(parse({"--builder", "median", "--quality", "fast"}, opt, error));  // the median builder has no quality
    CHECK(error.find("--builder sah") != std::string::npos);
    CHECK_FALSE(parse({"--accuracy", "--builder", "sah", "--quality", "fast"}, opt, error));
    CHECK(error.find("--quality does not apply to --accuracy") != std::string::npos);
}

TEST_CASE("bench options --intersector and --accuracy parse, with their defaults", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({}, opt, error));
    CHECK_FALSE(opt.accuracy);
    CHECK(opt.intersectors.empty());
    CHECK(kb::intersectors_for(opt) == std::vector<kdrt_intersector>{KDRT_INTERSECTOR_WATERTIGHT});
    CHECK(opt.repeat == 1);

    REQUIRE(parse({"--intersector", "fast"}, opt, error));
    CHECK(kb::intersectors_for(opt) == std::vector<kdrt_intersector>{KDRT_INTERSECTOR_FAST});
    REQUIRE(parse({"--intersector", "watertight,fast"}, opt, error));
    CHECK(kb::intersectors_for(opt) == std::vector<kdrt_intersector>{KDRT_INTERSECTOR_WATERTIGHT, KDRT_INTERSECTOR_FAST});
    CHECK(std::string(kb::intersector_name(KDRT_INTERSECTOR_FAST)) == "fast");
    CHECK(std::string(kb::intersector_name(KDRT_INTERSECTOR_WATERTIGHT)) == "watertight");
    CHECK(std::string(kb::intersector_name(KDRT_INTERSECTOR_DEFAULT)) == "watertight");

    // --accuracy: both intersectors, a smaller frame, three timed passes, unless told otherwise.
    REQUIRE(parse({"--accuracy"}, opt, error));
    CHECK(opt.accuracy);
    CHECK(kb::intersectors_for(opt) == std::vector<kdrt_intersector>{KDRT_INTERSECTOR_FAST, KDRT_INTERSECTOR_WATERTIGHT});
    CHECK(opt.width == 400);
    CHECK(opt.height == 400);
    CHECK(opt.repeat == 3);
    CHECK(opt.hard_rays == 20000);
    CHECK(opt.reference_rays == 20000);
    REQUIRE(parse({"--accuracy", "--size", "64x32", "--repeat", "1", "--hard-rays", "500", "--intersector", "fast",
                   "--reference-rays", "100", "-o", "acc.csv", "m.off"},
                  opt, error));
    CHECK(opt.width == 64);
    CHECK(opt.height == 32);
    CHECK(opt.repeat == 1);
    CHECK(opt.hard_rays == 500);
    CHECK(opt.reference_rays == 100);
    CHECK(kb::intersectors_for(opt) == std::vector<kdrt_intersector>{KDRT_INTERSECTOR_FAST});
    CHECK(opt.output == "acc.csv");
    CHECK(opt.inputs == std::vector<std::string>{"m.off"});

    const std::vector<std::vector<const char *>> bad = {
        {"--intersector", "double"}, {"--intersector", "fast,"}, {"--intersector", ""},  {"--intersector"},
        {"--hard-rays", "0"},        {"--hard-rays", "many"},    {"--hard-rays", "10"},  // without --accuracy
        {"--leaf-sizes", "1", "--accuracy"}, {"--accuracy", "--rays", "diffuse"}, {"--accuracy", "--compare", "embree"}};
    for (const auto &args : bad) {
        INFO(args[0] << " " << (args.size() > 1 ? args[1] : ""));
        error.clear();
        CHECK_FALSE(parse(args, opt, error));
        const bool named = error.find(args[0]) != std::string::npos || (args.size() > 1 && error.find(args[1]) != std::string::npos);
        CHECK(named);
    }
}

TEST_CASE("diffuse rays leave their primary hit through kdrt_spawn_ray, near and far from the origin", "[bench]") {
    const common::Mesh ball = kt::sphere(16, 32, 1.0);
    const kb::Scene scene = kb::make_scene(ball, "BALL");
    // The same frame moved 1e5 along (1, 1, 1) (scaled by 100, as the far accuracy set does):
    // there a float step is 1/128, and a fixed offset of 1e-4 along the normal rounds away.
    const kb::AccuracySet far = kb::far_set(scene, 1e5, 24, 24, 1);
    kb::Scene moved = scene;
    moved.geometry = far.mesh;
    std::memcpy(moved.eye, far.rays[0].org, sizeof moved.eye);
    for (const kb::Scene *s : {&scene, static_cast<const kb::Scene *>(&moved)}) {
        INFO("eye z " << s->eye[2]);
        kt::TreePtr tree = kt::build(s->geometry, 4, KDRT_BUILDER_MEDIAN);
        const std::vector<kdrt_ray> primary = kb::make_rays(*s, kb::RayKind::primary, 24, 24, tree.get(), 1);
        const std::vector<kdrt_ray> bounces = kb::make_rays(*s, kb::RayKind::diffuse, 24, 24, tree.get(), 1);
        REQUIRE(bounces.size() == primary.size());  // every primary ray hits the ball or the wall
        size_t moved_off = 0, self_hits = 0, ball_hits = 0;
        for (size_t i = 0; i < primary.size(); ++i) {
            kdrt_hit h, b;
            REQUIRE(kdrt_intersect(tree.get(), &primary[i], &h));
            ball_hits += h.triangle < s->mesh_triangles;
            float point[3], normal[3], expected[3];
            REQUIRE(kdrt_hit_surface(tree.get(), &h, point, normal));
            // The origin is kdrt_offset_ray_origin's, on the side the camera sees.
            kdrt_offset_ray_origin(point, normal, bounces[i].dir, expected);
            CHECK(std::memcmp(expected, bounces[i].org, sizeof expected) == 0);
            moved_off += std::memcmp(point, bounces[i].org, sizeof point) != 0;
            double side = 0, towards = 0;
            for (int a = 0; a < 3; ++a)
                side += double(normal[a]) * bounces[i].dir[a], towards += double(normal[a]) * primary[i].dir[a];
            CHECK(side * towards < 0);  // the bounce goes back to the side the primary ray came from
            CHECK(bounces[i].tmin == 0);
            CHECK(bounces[i].tmax == INFINITY);
            if (kdrt_intersect(tree.get(), &bounces[i], &b)) self_hits += b.triangle == h.triangle;
        }
        CHECK(moved_off == primary.size());  // no bounce starts at its primary hit point
        CHECK(self_hits == 0);
        CHECK(ball_hits > primary.size() / 2);
    }
}

TEST_CASE("accuracy sets: the frame, the frame moved far away with its camera", "[bench]") {
    const common::Mesh ball = kt::sphere(12, 24, 1.0);
    const kb::Scene scene = kb::make_scene(ball, "BALL");
    const std::vector<kb::AccuracySet> frame = kb::frame_sets(scene, 20, 20, 1);
    REQUIRE(frame.size() == 2);
    CHECK(frame[0].set == "frame-primary");
    CHECK(frame[1].set == "frame-diffuse");
    kt::TreePtr tree = kt::build(scene.geometry, 4, KDRT_BUILDER_MEDIAN);
    const std::vector<kdrt_ray> primary = kb::make_rays(scene, kb::RayKind::primary, 20, 20, tree.get(), 1);
    const std::vector<kdrt_ray> diffuse = kb::make_rays(scene, kb::RayKind::diffuse, 20, 20, tree.get(), 1);
    for (const kb::AccuracySet &s : frame) {
        CHECK(s.scene == "BALL");
        CHECK_FALSE(s.must_hit);
        CHECK(s.mesh.positions == scene.geometry.positions);
        const std::vector<kdrt_ray> &expected = &s == &frame[0] ? primary : diffuse;
        REQUIRE(s.rays.size() == expected.size());
        for (size_t i = 0; i < expected.size(); ++i) {  // the rays, not their start cells, which name another tree's
            kdrt_ray a = s.rays[i], b = expected[i];
            a.cell = b.cell = 0;
            CHECK(std::memcmp(&a, &b, sizeof a) == 0);
        }
    }

    // Moved far away, the camera moves along: the rays see what they saw near the origin.
    std::vector<kdrt_hit> near_hits = kt::trace_all(tree.get(), primary);
    for (double offset : {1e3, 1e5, 1e7}) {
        INFO("offset " << offset);
        const kb::AccuracySet far = kb::far_set(scene, offset, 20, 20, 1);
        CHECK(far.set == "far");
        CHECK(far.scene.rfind("BALL@1e", 0) == 0);
        REQUIRE(far.mesh.triangle_count() == scene.geometry.triangle_count());
        REQUIRE(far.rays.size() == primary.size());
        for (int a = 0; a < 3; ++a) CHECK(far.mesh.positions[size_t(a)] > 0.9 * offset);
        kt::TreePtr moved = kt::build(far.mesh, 4, KDRT_BUILDER_MEDIAN);
        const std::vector<kdrt_hit> far_hits = kt::trace_all(moved.get(), far.rays);
        size_t same = 0;
        for (size_t i = 0; i < far_hits.size(); ++i) same += far_hits[i].triangle == near_hits[i].triangle;
        CHECK(same >= far_hits.size() * 9 / 10);
    }
    CHECK(kb::far_set(scene, 1e5, 20, 20, 1).scene == "BALL@1e5");
}

TEST_CASE("accuracy CSV: header, the oracle row, counters in their columns", "[bench]") {
    const std::vector<std::string> columns = split(kb::accuracy_csv_header(), ';');
    REQUIRE(columns == std::vector<std::string>{"Set", "Scene", "Intersector", "Triangles", "Rays", "TraceMs", "MRaysPerSec",
                                                "Leaks", "FalseHits", "SelfHits", "Mismatches", "SpawnedRays",
                                                "ReferenceRays", "NaiveSelfHits"});
    kb::AccuracyRow row;
    row.set = "watertight";
    row.scene = "cow";
    row.intersector = "fast";
    row.triangles = 5804;
    row.rays = 20000;
    row.trace_ms = 80;
    row.counts_leaks = true;
    row.errors.leaks = 7;
    row.errors.false_hits = 1;
    row.errors.self_hits = 2;
    row.errors.mismatches = 3;
    row.spawned_rays = 79000;
    row.reference_rays = 5000;
    row.naive_self_hits = 4000;
    std::vector<std::string> f = split(kb::accuracy_csv_row(row), ';');
    REQUIRE(f.size() == columns.size());
    CHECK(f == std::vector<std::string>{"watertight", "cow", "fast", "5804", "20000", "80.000", "0.250", "7", "1", "2", "3",
                                        "79000", "5000", "4000"});
    row.counts_leaks = false;  // a set whose rays need not hit: no leak count, not a zero
    f = split(kb::accuracy_csv_row(row), ';');
    REQUIRE(f.size() == columns.size());
    CHECK(f[7].empty());
    CHECK(f[8] == "1");
    row.measured = false;  // the oracle's row: its speed only
    row.intersector = "oracle";
    f = split(kb::accuracy_csv_row(row), ';');
    REQUIRE(f.size() == columns.size());
    CHECK(f[2] == "oracle");
    CHECK(f[6] == "0.250");
    for (size_t c = 7; c < f.size(); ++c) CHECK(f[c].empty());
}

TEST_CASE("accuracy run on tiny sets: rows per intersector, leaks counted on must-hit sets", "[bench]") {
    // The frame of a small ball: every counter zero for both intersectors.
    const kb::Scene scene = kb::make_scene(kt::sphere(8, 16, 1.0), "BALL");
    const std::vector<kdrt_intersector> both = {KDRT_INTERSECTOR_FAST, KDRT_INTERSECTOR_WATERTIGHT};
    std::vector<kb::AccuracyRow> rows;
    std::string error;
    for (const kb::AccuracySet &set : kb::frame_sets(scene, 16, 16, 1))
        REQUIRE(kb::run_accuracy_set(set, both, 100, 1, 2, 1, true, rows, error));
    REQUIRE(rows.size() == 6);  // oracle, fast, watertight for each set
    for (size_t i = 0; i < rows.size(); ++i) {
        INFO(rows[i].set << " " << rows[i].intersector);
        CHECK(rows[i].intersector == (i % 3 == 0 ? "oracle" : i % 3 == 1 ? "fast" : "watertight"));
        CHECK(rows[i].scene == "BALL");
        CHECK(rows[i].set == (i < 3 ? "frame-primary" : "frame-diffuse"));
        CHECK(rows[i].triangles == scene.geometry.triangle_count());
        CHECK(rows[i].trace_ms > 0);
        CHECK(split(kb::accuracy_csv_row(rows[i]), ';').size() == split(kb::accuracy_csv_header(), ';').size());
        if (i % 3 == 0) {
            CHECK_FALSE(rows[i].measured);
            CHECK(rows[i].rays == 100);  // the oracle times its sample
            continue;
        }
        CHECK(rows[i].rays == 256);  // every primary ray hits the ball or the wall, and bounces once
        CHECK(rows[i].reference_rays == 100);
        CHECK_FALSE(rows[i].counts_leaks);
        CHECK(rows[i].errors.mismatches == 0);
        CHECK(rows[i].errors.false_hits == 0);
        CHECK(rows[i].errors.self_hits == 0);
        CHECK(rows[i].spawned_rays > 0);
    }
    CHECK(rows[1].naive_self_hits > 0);  // spawning at the hit point with no offset does self-hit

    // Rays at the vertices and edges of a closed sphere: Moeller-Trumbore lets some through, the
    // watertight test none; both rows say so in Leaks.
    const std::vector<common::Mesh> closed = oracle::closed_meshes(false);
    REQUIRE_FALSE(closed.empty());
    kb::AccuracySet must;
    must.set = "watertight";
    must.scene = closed[0].name;
    must.mesh = closed[0];
    must.rays = oracle::rays_at_vertices_and_edges(must.mesh, 3000, 1);
    must.must_hit = true;
    rows.clear();
    REQUIRE(kb::run_accuracy_set(must, both, 500, 1, 1, 1, false, rows, error));
    REQUIRE(rows.size() == 2);  // no oracle row when not asked
    CHECK(rows[0].intersector == "fast");
    CHECK(rows[0].counts_leaks);
    CHECK(rows[0].errors.leaks > 0);
    CHECK(rows[1].intersector == "watertight");
    CHECK(rows[1].errors.leaks == 0);
    CHECK_FALSE(split(kb::accuracy_csv_row(rows[0]), ';')[7].empty());

    // The summary adds rows of a set and intersector up, in the order first seen.
    std::vector<kb::AccuracyRow> sum_in = rows;
    sum_in.push_back(rows[0]);
    sum_in.back().scene = "other";
    const std::vector<kb::AccuracyRow> sum = kb::accuracy_summary(sum_in);
    REQUIRE(sum.size() == 2);
    CHECK(sum[0].intersector == "fast");
    CHECK(sum[0].scene == "2 scenes");
    CHECK(sum[0].rays == 2 * rows[0].rays);
    CHECK(sum[0].errors.leaks == 2 * rows[0].errors.leaks);
    CHECK(sum[0].trace_ms == Approx(2 * rows[0].trace_ms));
    CHECK(sum[1].scene == "1 scene");
    const std::string table = kb::accuracy_table(sum);
    CHECK(table.find("MRays/s") != std::string::npos);
    CHECK(table.find(std::to_string(sum[0].errors.leaks)) != std::string::npos);
}

TEST_CASE("CSV keeps the original's first three columns", "[bench]") {
    const std::string header = kb::csv_header();
    REQUIRE(header.rfind("Mesh;MaxLeafSize;ElapsedMs;", 0) == 0);
    const std::vector<std::string> columns = split(header, ';');
    REQUIRE(columns == std::vector<std::string>{"Mesh", "MaxLeafSize", "ElapsedMs", "Builder", "Triangles", "BuildMs",
                                                "TraceMs", "MRaysPerSec", "Nodes", "Leaves", "MaxDepth",
                                                "AvgLeafTriangles", "TreeBytes", "Mismatches", "ReferenceRays",
                                                "Intersector", "SahCost", "SahCosts", "BuildThreads", "Quality",
                                                "Query", "Start", "Call", "Kernel"});

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
    row.stats.sah_cost = 123.45678;
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
    CHECK(f[15] == "watertight");  // the default; new columns go last so the columns before keep their places
    CHECK(f[16] == "123.457");
    CHECK(f[17].empty());  // median: no cost constants of its own
    CHECK(f[19].empty());  // nor a quality
    CHECK(f[22] == "single");  // a call a ray, unless the row says otherwise
    CHECK(f[23].empty());      // Kernel: what the row says, main's kernel_name() of the tree's
    row.call = kb::call_name(kb::Call::batch);
    CHECK(split(kb::csv_row(row), ';')[22] == "batch");
    row.call = "single";
    row.kernel = kb::kernel_name(KDRT_KERNEL_AVX2);
    CHECK(split(kb::csv_row(row), ';').back() == "avx2");
    row.kernel.clear();
    row.quality = "fast";
    CHECK(split(kb::csv_row(row), ';')[19] == "fast");
    row.quality.clear();
    row.builder = "sah";
    row.sah_costs = "1:80:0.5";
    CHECK(split(kb::csv_row(row), ';')[17] == "1:80:0.5");
    row.builder = "median";
    row.sah_costs.clear();
    row.intersector = kb::intersector_name(KDRT_INTERSECTOR_FAST);
    CHECK(split(kb::csv_row(row), ';')[15] == "fast");

    row.builder = "embree";
    row.max_leaf_size = -1;
    row.has_tree_stats = false;
    const std::vector<std::string> e = split(kb::csv_row(row), ';');
    REQUIRE(e.size() == columns.size());
    CHECK(e[1] == "-1");
    for (int c : {8, 9, 10, 11, 12, 16, 23}) CHECK(e[size_t(c)].empty());  // no kd-tree statistics or kernel for Embree
    row.intersector.clear();  // Embree's own triangle test
    CHECK(split(kb::csv_row(row), ';')[15].empty());
}

TEST_CASE("bench option --batch: the calls, a row each, and the rays in tiles", "[bench]") {
    kb::Options opt;
    std::string error;
    // Without it: a call a ray, in the pixel order, as the runs before batches.
    REQUIRE(parse({}, opt, error));
    CHECK(opt.calls == std::vector<kb::Call>{kb::Call::single});
    CHECK(kb::kdrt_calls(opt) == std::vector<kb::Call>{kb::Call::single});
    CHECK((opt.tile_width == 1 && opt.tile_height == 1 && !opt.shuffle));
    CHECK(opt.batch_size == kb::kDefaultBatchSize);
    CHECK(kb::frame_rays(opt, kb::RayKind::primary) == "800x800 primary rays");

    // Given, the rays come in 4x2 tiles; kdrt has the single and batch calls, Embree all four.
    REQUIRE(parse({"--batch", "Batch,single,packet16,PACKET8", "--batch-size", "64"}, opt, error));
    CHECK(opt.calls == std::vector<kb::Call>{kb::Call::batch, kb::Call::single, kb::Call::packet16, kb::Call::packet8});
    CHECK(kb::kdrt_calls(opt) == std::vector<kb::Call>{kb::Call::batch, kb::Call::single});
    CHECK((opt.tile_width == 4 && opt.tile_height == 2));
    CHECK(opt.batch_size == 64);
    CHECK(kb::frame_rays(opt, kb::RayKind::shadow) == "800x800 shadow rays in 4x2 tiles");
    REQUIRE(parse({"--batch", "single", "--tile", "4x4"}, opt, error));
    CHECK((opt.tile_width == 4 && opt.tile_height == 4));
    REQUIRE(parse({"--tile", "2x4"}, opt, error));  // the order alone, for the single calls
    CHECK(opt.calls == std::vector<kb::Call>{kb::Call::single});
    CHECK((opt.tile_width == 2 && opt.tile_height == 4));
    REQUIRE(parse({"--batch", "packet8", "--shuffle"}, opt, error));
    CHECK(kb::kdrt_calls(opt).empty());
    CHECK(opt.shuffle);
    CHECK(kb::frame_rays(opt, kb::RayKind::diffuse) == "800x800 diffuse rays, shuffled");
    for (kb::Call call : {kb::Call::single, kb::Call::batch, kb::Call::packet8, kb::Call::packet16}) {
        std::vector<const char *> args = {"--batch", kb::call_name(call)};
        REQUIRE(parse(args, opt, error));
        CHECK(opt.calls == std::vector<kb::Call>{call});
    }

    const std::vector<std::vector<const char *>> bad = {
        {"--batch", "stream"},     {"--batch", "single,"},  {"--batch", ""},        {"--batch"},
        {"--batch-size", "0"},     {"--batch-size", "x"},   {"--batch-size", "64"},  // without the batch calls
        {"--tile", "4"},           {"--tile", "0x2"},       {"--tile", "4x300"},
        {"--accuracy", "--batch", "batch"}, {"--accuracy", "--shuffle"}, {"--scene", "merged", "--tile", "4x2"}};
    check_refused(bad);
}

TEST_CASE("bench option --kernel: a variant of every kdrt build per kernel, named in Kernel", "[bench]") {
    kb::Options opt;
    std::string error;
    // Without it: the build's own choice, one variant, no kernel flag.
    REQUIRE(parse({}, opt, error));
    CHECK(opt.kernels == std::vector<std::string>{"default"});
    std::vector<kb::BuildVariant> v = kb::build_variants(opt);
    REQUIRE(v.size() == 1);
    CHECK(v[0].kernel == "default");
    CHECK(v[0].options.flags == 0u);

    // In the order given, in either case; each build once per kernel, kernels innermost.
    REQUIRE(parse({"--kernel", "AVX2,scalar,Avx512,default"}, opt, error));
    CHECK(opt.kernels == std::vector<std::string>{"avx2", "scalar", "avx512", "default"});
    REQUIRE(parse({"--kernel", "avx2,avx512", "--builder", "median,sah", "--quality", "fast,high"}, opt, error));
    v = kb::build_variants(opt);
    REQUIRE(v.size() == 6);  // median, sah fast, sah high: each with avx2 then avx512
    CHECK((v[0].builder == "median" && v[0].kernel == "avx2" && v[0].options.flags == KDRT_BUILD_AVX2_KERNEL));
    CHECK((v[1].builder == "median" && v[1].kernel == "avx512" && v[1].options.flags == 0u));
    CHECK((v[2].quality == "fast" && v[2].kernel == "avx2"));
    CHECK((v[3].quality == "fast" && v[3].kernel == "avx512"));
    CHECK((v[5].quality == "high" && v[5].options.builder == KDRT_BUILDER_SAH && v[5].kernel == "avx512"));
    CHECK(kb::kernel_flags("scalar") == KDRT_BUILD_SCALAR_KERNEL);
    CHECK(kb::kernel_flags("avx2") == KDRT_BUILD_AVX2_KERNEL);
    CHECK(kb::kernel_flags("avx512") == 0u);
    CHECK(kb::kernel_flags("default") == 0u);
    CHECK(std::string(kb::kernel_name(KDRT_KERNEL_SCALAR)) == "scalar");
    CHECK(std::string(kb::kernel_name(KDRT_KERNEL_AVX2)) == "avx2");
    CHECK(std::string(kb::kernel_name(KDRT_KERNEL_AVX512)) == "avx512");

    // The kernels a tree built with each name's flags runs: the scalar kernel is always there, and
    // a named kernel passes the check exactly when such a tree runs it.
    CHECK(kb::check_kernels({"default", "scalar"}, error));
    const common::Mesh sphere = kt::sphere(4, 8, 1.0);  // the trees borrow its buffers
    for (const char *kernel : {"avx2", "avx512"}) {
        kt::TreePtr tree = kt::build(sphere, 4, kt::kSahBuilders[0], kb::kernel_flags(kernel));
        kdrt_tree_stats stats;
        kdrt_tree_get_stats(tree.get(), &stats);
        const bool runs = std::string(kb::kernel_name(stats.kernel)) == kernel;
        INFO(kernel << " runs here: " << runs);
        error.clear();
        CHECK(kb::check_kernels({kernel}, error) == runs);
        if (!runs) CHECK(error.find("--kernel " + std::string(kernel)) != std::string::npos);
    }

    const std::vector<std::vector<const char *>> bad = {
        {"--kernel", "avx"},  {"--kernel", "avx2,"}, {"--kernel", ""}, {"--kernel"}, {"--kernel", "sse"},
        {"--accuracy", "--kernel", "avx2"}, {"--scene", "merged", "--kernel", "scalar"}};
    for (const auto &args : bad) {
        INFO(args[0] << " " << (args.size() > 1 ? args[1] : ""));
        error.clear();
        CHECK_FALSE(parse(args, opt, error));
        CHECK(error.find("--kernel") != std::string::npos);  // the message names the option
    }
    CHECK_FALSE(parse({"--kernel", "AVX3"}, opt, error));
    CHECK(error.find("'AVX3'") != std::string::npos);  // named as it was given
}

TEST_CASE("ray order: tiles row by row, pixels row by row in each, shadow and diffuse rays with their pixels", "[bench]") {
    // A 6x3 frame in 4x2 tiles: two tiles across (the right one 2 wide), two down (the lower 1 high).
    std::vector<uint32_t> pixels(18);
    for (uint32_t i = 0; i < 18; ++i) pixels[i] = i;
    std::vector<uint32_t> ordered;
    for (size_t i : kb::ray_order(pixels, 6, 4, 2, false, 1)) ordered.push_back(pixels[i]);
    CHECK(ordered == std::vector<uint32_t>{0, 1, 2, 3, 6, 7, 8, 9, 4, 5, 10, 11, 12, 13, 14, 15, 16, 17});
    // 1x1 tiles: the pixel order; rays of some pixels only (those whose primary ray hit) keep it.
    const std::vector<uint32_t> some = {1, 4, 5, 8, 13, 17};
    std::vector<size_t> identity(some.size());
    for (size_t i = 0; i < identity.size(); ++i) identity[i] = i;
    CHECK(kb::ray_order(some, 6, 1, 1, false, 1) == identity);
    ordered.clear();
    for (size_t i : kb::ray_order(some, 6, 4, 2, false, 1)) ordered.push_back(some[i]);
    CHECK(ordered == std::vector<uint32_t>{1, 8, 4, 5, 13, 17});
    // Shuffled: every ray once, the same order for the same seed, not the pixel order.
    std::vector<size_t> shuffled = kb::ray_order(pixels, 6, 4, 2, true, 1);
    CHECK(shuffled == kb::ray_order(pixels, 6, 4, 2, true, 1));
    CHECK(shuffled != kb::ray_order(pixels, 6, 1, 1, false, 1));
    std::sort(shuffled.begin(), shuffled.end());
    CHECK(shuffled == kb::ray_order(pixels, 6, 1, 1, false, 1));

    // make_rays names each ray's pixel: a shadow ray's is its primary ray's.
    const kb::Scene scene = kb::make_scene(kt::sphere(8, 16, 1.0), "BALL");
    kt::TreePtr tree = kt::build(scene.geometry, 4, KDRT_BUILDER_MEDIAN);
    std::vector<uint32_t> primary_pixels, shadow_pixels;
    const std::vector<kdrt_ray> primary = kb::make_rays(scene, kb::RayKind::primary, 12, 8, tree.get(), 1, &primary_pixels);
    const std::vector<kdrt_ray> shadow = kb::make_rays(scene, kb::RayKind::shadow, 12, 8, tree.get(), 1, &shadow_pixels);
    REQUIRE(primary_pixels.size() == primary.size());
    for (size_t i = 0; i < primary.size(); ++i) CHECK(primary_pixels[i] == i);
    REQUIRE(shadow_pixels.size() == shadow.size());
    REQUIRE_FALSE(shadow.empty());
    for (size_t i = 0; i < shadow.size(); ++i) {
        kdrt_hit h;
        REQUIRE(kdrt_intersect(tree.get(), &primary[shadow_pixels[i]], &h));
        float point[3];
        REQUIRE(kdrt_hit_surface(tree.get(), &h, point, nullptr));
        double gap = 0;  // the shadow ray starts at its primary ray's hit, offset by a hair
        for (int a = 0; a < 3; ++a) gap = std::max(gap, std::fabs(double(shadow[i].org[a]) - point[a]));
        CHECK(gap < 1e-4);
    }
    std::vector<uint32_t> diffuse_pixels;
    const std::vector<kdrt_ray> diffuse = kb::make_rays(scene, kb::RayKind::diffuse, 12, 8, tree.get(), 1, &diffuse_pixels);
    REQUIRE(diffuse_pixels.size() == diffuse.size());
    CHECK(std::is_sorted(diffuse_pixels.begin(), diffuse_pixels.end()));  // in their primary rays' order
}

TEST_CASE("batch answers are compared with the single calls' bit for bit", "[bench]") {
    kdrt_hit a{};
    a.t = 1.5f, a.u = 0.25f, a.v = 0.5f, a.triangle = 7, a.geometry = 0, a.instance = KDRT_INVALID_ID, a.cell = 3;
    const std::vector<kdrt_hit> single(5, a);
    size_t first = 0;
    CHECK(kb::count_differing_hits(single, single, first) == 0);
    CHECK(first == SIZE_MAX);
    // Each field, and a zero of the other sign, which == would call equal.
    std::vector<kdrt_hit> batch = single;
    batch[1].cell = 4;
    batch[2].u = std::nextafter(a.u, 1.0f);
    batch[4].t = 0.0f;
    std::vector<kdrt_hit> zero = single;
    zero[4].t = -0.0f;
    CHECK(kb::count_differing_hits(batch, single, first) == 3);
    CHECK(first == 1);
    CHECK(kb::count_differing_hits(batch, zero, first) == 3);
    CHECK(first == 1);
    for (int field = 0; field < 4; ++field) {
        std::vector<kdrt_hit> one = single;
        if (field == 0) one[3].v = -a.v;
        if (field == 1) one[3].triangle = 8;
        if (field == 2) one[3].geometry = 1;
        if (field == 3) one[3].instance = 0;
        CHECK(kb::count_differing_hits(one, single, first) == 1);
        CHECK(first == 3);
    }
    CHECK(kb::count_differing_hits(std::vector<kdrt_hit>(4, a), single, first) == 1);  // one answer missing
    CHECK(first == 4);
    CHECK(kb::describe_hit(a) == "triangle 7 t 0x1.8p+0 u 0x1p-2 v 0x1p-1 geometry 0 instance 4294967295 cell 3");

    const std::vector<unsigned char> occluded = {1, 0, 1, 1};
    CHECK(kb::count_differing_occlusion(occluded, occluded, first) == 0);
    CHECK(kb::count_differing_occlusion({1, 0, 0, 1}, occluded, first) == 1);
    CHECK(first == 2);
}

TEST_CASE("the benchmark scene: mesh fills the view, the wall sits behind it", "[bench]") {
    const common::Mesh ball = kt::sphere(12, 24, 5.0);
    const kb::Scene scene = kb::make_scene(kt::translated(ball, 100, -40, 7), "BALL");
    REQUIRE(scene.mesh_triangles == ball.triangle_count());
    REQUIRE(scene.geometry.triangle_count() == ball.triangle_count() + 2);
    double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
    for (size_t i = 0; i < size_t(ball.vertex_count()) * 3; ++i)
        lo[i % 3] = std::min(lo[i % 3], double(scene.geometry.positions[i])), hi[i % 3] = std::max(hi[i % 3], double(scene.geometry.positions[i]));
    CHECK(std::max(hi[0] - lo[0], hi[1] - lo[1]) == Approx(2.0).epsilon(1e-5));
    CHECK(0.5 * (lo[0] + hi[0]) == Approx(0.0).margin(1e-5));

    // Every primary ray hits something (mesh or wall), and the centre pixel hits the mesh.
    kt::TreePtr tree = kt::build(scene.geometry, 4, KDRT_BUILDER_MEDIAN);
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

    // Shadow rays: one per primary hit, ending at the light (t = 1), which the ball hides from
    // the wall behind it but not from its own lit side.
    const std::vector<kdrt_ray> shadow = kb::make_rays(scene, kb::RayKind::shadow, 33, 33, tree.get(), 1);
    CHECK(shadow.size() == rays.size());
    size_t blocked = 0;
    for (const kdrt_ray &s : shadow) {
        for (int a = 0; a < 3; ++a) CHECK(s.org[a] + s.dir[a] == Approx(kb::kShadowLight[a]).epsilon(1e-5));
        CHECK(s.tmax == 1.0f);
        kdrt_hit h;
        const int occluded = kdrt_occluded(tree.get(), &s);
        CHECK(occluded == kdrt_intersect(tree.get(), &s, &h));
        blocked += size_t(occluded);
    }
    CHECK(blocked > 0);
    CHECK(blocked < shadow.size());
}

TEST_CASE("Mismatches of shadow rays count occlusion the reference contradicts", "[bench]") {
    const common::Mesh ball = kt::sphere(16, 32, 1.0);
    const kb::Scene scene = kb::make_scene(ball, "BALL");
    kt::TreePtr tree = kt::build(scene.geometry, 4, KDRT_BUILDER_MEDIAN);
    const std::vector<kdrt_ray> rays = kb::make_rays(scene, kb::RayKind::shadow, 40, 40, tree.get(), 1);
    std::vector<unsigned char> occluded(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) occluded[i] = (unsigned char)kdrt_occluded(tree.get(), &rays[i]);
    const oracle::Oracle oracle(scene.geometry);
    const std::vector<size_t> sample = kb::reference_sample(rays.size(), 0, 1);
    const std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
    const uint32_t triangles = scene.geometry.triangle_count();
    REQUIRE(kb::count_occlusion_mismatches(oracle, refs, sample, rays, occluded, triangles) == 0);
    // Every answer turned round: each surely blocked ray now unblocked, each clear one blocked.
    std::vector<unsigned char> flipped(occluded.size());
    size_t sure = 0, clear = 0;
    for (size_t i = 0; i < occluded.size(); ++i) {
        flipped[i] = (unsigned char)!occluded[i];
        sure += refs[i].sure_hit;
        clear += !occluded[i];
    }
    REQUIRE(sure > 0);
    REQUIRE(clear > 0);
    INFO("sure " << sure << " clear " << clear);
    CHECK(kb::count_occlusion_mismatches(oracle, refs, sample, rays, flipped, triangles) >= sure + clear * 9 / 10);
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
    const common::Mesh ball = kt::sphere(16, 32, 1.0);
    const kb::Scene scene = kb::make_scene(ball, "BALL");
    kt::TreePtr tree = kt::build(scene.geometry, 4, KDRT_BUILDER_MEDIAN);
    const std::vector<kdrt_ray> rays = kb::make_rays(scene, kb::RayKind::primary, 40, 40, tree.get(), 1);
    std::vector<kdrt_hit> hits(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) kdrt_intersect(tree.get(), &rays[i], &hits[i]);
    const oracle::Oracle oracle(scene.geometry);
    const std::vector<size_t> sample = kb::reference_sample(rays.size(), 0, 1);
    const std::vector<oracle::Reference> refs = oracle::reference_all(oracle, rays);
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

TEST_CASE("bench option --scene: merged, field, their options, and what does not apply", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({}, opt, error));
    CHECK(opt.scenes.empty());
    CHECK(opt.instances == 1000);
    CHECK(opt.instance_triangles == 3000);

    REQUIRE(parse({"--scene", "merged,field"}, opt, error));
    CHECK(opt.scenes == std::vector<std::string>{"merged", "field"});
    CHECK(opt.repeat == 5);  // timed passes, the median kept
    CHECK(opt.instance_spacing == 1);
    REQUIRE(parse({"--scene", "field", "--instances", "20", "--instance-triangles", "0", "--instance-spacing", "1.5",
                   "--repeat", "2", "--size", "32x32", "--threads", "2", "--build-threads", "2", "--compare", "embree",
                   "-o", "s.csv", "a.obj"},
                  opt, error));
    CHECK(opt.instance_spacing == 1.5);
    CHECK(opt.scenes == std::vector<std::string>{"field"});
    CHECK(opt.instances == 20);
    CHECK(opt.instance_triangles == 0);
    CHECK(opt.repeat == 2);
    CHECK(opt.compare_embree);
    CHECK(opt.inputs == std::vector<std::string>{"a.obj"});

    const std::vector<std::vector<const char *>> bad = {
        {"--scene", "forest"},        {"--scene", "merged,"},          {"--scene"},
        {"--instances", "0"},         {"--instances", "2000000"},      {"--instance-triangles", "-1"},
        {"--scene", "field", "--instance-spacing", "0"}, {"--scene", "field", "--instance-spacing", "2x"},
        {"--scene", "field", "--instance-spacing", "nan"},
        {"--instances", "5"},         {"--scene", "merged", "--instances", "5"},  // only the field has instances
        {"--scene", "field", "--accuracy"}, {"--scene", "merged", "--rays", "shadow"},
        {"--scene", "merged", "--leaf-sizes", "4"}, {"--scene", "field", "--builder", "sah"}};
    check_refused(bad);
}

TEST_CASE("scene worlds: unit-sized meshes, clustering, and their layouts as one mesh and as geometries", "[bench]") {
    const common::Mesh ball = kt::sphere(16, 32, 3.0), ring = common::torus(48, 24, 1.0, 0.4);
    const common::Mesh unit = kb::unit_sized(kt::translated(ball, 5, -2, 1));
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (size_t i = 0; i < unit.positions.size(); ++i)
        lo[i % 3] = std::min(lo[i % 3], unit.positions[i]), hi[i % 3] = std::max(hi[i % 3], unit.positions[i]);
    for (int a = 0; a < 3; ++a) {
        CHECK(std::fabs(lo[a] + hi[a]) < 1e-6);
        CHECK(hi[a] - lo[a] == Approx(1.0).epsilon(1e-6));
    }

    // Clustering: at most the target, fewer vertices, no triangle with a repeated corner.
    CHECK(kb::clustered(ring, 0).indices == ring.indices);
    CHECK(kb::clustered(ring, 1u << 20).indices == ring.indices);
    const common::Mesh coarse = kb::clustered(ring, 500);
    CHECK(coarse.triangle_count() <= 500);
    CHECK(coarse.triangle_count() > 250);
    CHECK(coarse.vertex_count() < ring.vertex_count());
    for (uint32_t t = 0; t < coarse.triangle_count(); ++t) {
        const uint32_t *c = &coarse.indices[3 * size_t(t)];
        CHECK((c[0] != c[1] && c[1] != c[2] && c[0] != c[2]));
    }

    // merged: the meshes' runs of triangles in order, then the wall, and its views cover them.
    const kb::SceneLayout merged = kb::merged_layout({ball, ring});
    const uint32_t total = merged.frame.geometry.triangle_count();
    REQUIRE(merged.first == std::vector<uint32_t>{0, ball.triangle_count(), ball.triangle_count() + ring.triangle_count()});
    CHECK(total == ball.triangle_count() + ring.triangle_count() + 2);
    CHECK(merged.instances.empty());
    CHECK(kb::stored_triangles(merged) == total);
    CHECK(kb::geometry_view(merged, 1).triangle_count == ring.triangle_count());
    CHECK(kb::geometry_view(merged, 2).triangle_count == 2);
    CHECK(kb::geometry_view(merged, 2).indices == &merged.frame.geometry.indices[3 * size_t(total - 2)]);

    // field: seeded; instance i of mesh i % 2, its transform taking the mesh to its run of the one
    // mesh to float rounding.
    const kb::SceneLayout field = kb::field_layout({ball, coarse}, 7, 3), again = kb::field_layout({ball, coarse}, 7, 3);
    REQUIRE(field.instances.size() == 7);
    REQUIRE(field.first.size() == 8);
    CHECK(field.frame.geometry.positions == again.frame.geometry.positions);
    CHECK(kb::stored_triangles(field) == ball.triangle_count() + coarse.triangle_count() + 2);
    CHECK(field.frame.geometry.triangle_count() == 4 * ball.triangle_count() + 3 * coarse.triangle_count() + 2);
    for (uint32_t i = 0; i < 7; ++i) {
        const kb::SceneLayout::Placement &p = field.instances[i];
        CHECK(p.prototype == i % 2);
        const common::Mesh &mesh = field.prototypes[p.prototype];
        for (uint32_t t = 0; t < mesh.triangle_count(); t += 37)
            for (int k = 0; k < 3; ++k) {
                const float *o = &mesh.positions[3 * size_t(mesh.indices[3 * size_t(t) + k])];
                const uint32_t w = field.frame.geometry.indices[3 * size_t(field.first[i] + t) + k];
                for (int a = 0; a < 3; ++a) {
                    const float *m = &p.transform[4 * a];
                    const double x = double(m[0]) * o[0] + double(m[1]) * o[1] + double(m[2]) * o[2] + m[3];
                    CHECK(std::fabs(x - field.frame.geometry.positions[3 * size_t(w) + a]) < 1e-5);
                }
            }
    }
}

TEST_CASE("scene mismatches: exact for the merged meshes, to a tolerance for instances", "[bench]") {
    const auto hit = [](uint32_t geometry, uint32_t triangle, float t) {
        kdrt_hit h{};
        h.geometry = geometry, h.triangle = triangle, h.t = t, h.u = 0.25f, h.v = 0.5f;
        h.instance = KDRT_INVALID_ID;
        return h;
    };
    kdrt_hit miss = hit(0, KDRT_INVALID_ID, INFINITY);
    const std::vector<uint32_t> one = {0}, parts = {0, 10, 30};
    CHECK(kb::flat_triangle(hit(2, 4, 1), parts) == 34);
    CHECK(kb::flat_triangle(hit(0, 4, 1), one) == 4);
    CHECK(kb::flat_triangle(miss, parts) == KDRT_INVALID_ID);
    CHECK(kb::flat_triangle(hit(3, 0, 1), parts) == KDRT_INVALID_ID);  // no such geometry

    const std::vector<kdrt_hit> tree = {hit(0, 12, 2.0f), hit(0, 34, 3.0f), miss, hit(0, 5, 1.0f)};
    const std::vector<kdrt_hit> scene = {hit(1, 2, 2.0f), hit(2, 4, 3.0f), miss, hit(0, 5, 1.0f)};
    CHECK(kb::count_scene_mismatches(scene, parts, tree, one, 0) == 0);
    std::vector<kdrt_hit> off = scene;
    off[0].t = std::nextafter(2.0f, 3.0f);  // one ulp: exact counts it, the tolerance does not
    off[1].u = 0.125f;
    CHECK(kb::count_scene_mismatches(off, parts, tree, one, 0) == 2);
    CHECK(kb::count_scene_mismatches(off, parts, tree, one, 1e-4) == 0);
    off[2] = hit(0, 1, 5.0f);           // a hit against a miss
    off[3] = hit(1, 0, 1.00001f);       // another triangle at the same t: a shared edge
    CHECK(kb::count_scene_mismatches(off, parts, tree, one, 1e-4) == 1);
    off[3] = hit(1, 0, 1.001f);         // another triangle, farther
    CHECK(kb::count_scene_mismatches(off, parts, tree, one, 1e-4) == 2);
    CHECK(kb::count_scene_mismatches(tree, one, {tree[0]}, one, 0) == 3);  // missing answers count

    kb::SceneRow row;
    row.scene = "field", row.layout = "instanced", row.query = "none", row.rays = "primary", row.ray_count = 1000;
    row.triangles = 3002, row.stored_triangles = 1502, row.instances = 2, row.build_ms = 0.5, row.trace_ms = 2;
    CHECK(kb::scene_csv_row(row) == "field;instanced;none;primary;1000;3002;1502;2;0.500;2.000;0.500;;;;;;;");
    row.versus = "flattened", row.versus_trace_ms = 3, row.mismatches = 1;
    row.embree = true, row.embree_build_ms = 0.25, row.embree_trace_ms = 1, row.embree_mismatches = 4;
    CHECK(kb::scene_csv_row(row) == "field;instanced;none;primary;1000;3002;1502;2;0.500;2.000;0.500;flattened;1.500;1;"
                                    "0.250;1.000;0.500;4");
    CHECK(split(kb::scene_csv_header(), ';').size() == split(kb::scene_csv_row(row), ';').size());
}

TEST_CASE("scene worlds through kdrt_scene answer as the one tree over their triangles", "[bench]") {
    const common::Mesh ball = kt::sphere(16, 32, 1.0), ring = common::torus(48, 24, 1.0, 0.4);
    for (bool instanced : {false, true}) {
        INFO((instanced ? "field" : "merged"));
        const kb::SceneLayout layout = instanced ? kb::field_layout({ball, ring}, 20, 1) : kb::merged_layout({ball, ring});
        const kdrt_triangles world = layout.frame.geometry.view();
        kdrt_tree *one = nullptr;
        REQUIRE(kdrt_tree_build(&world, nullptr, &one, nullptr) == KDRT_SUCCESS);
        kt::TreePtr tree(one);
        std::vector<kt::TreePtr> owned;
        std::vector<kdrt_tree *> prototypes;
        for (const common::Mesh &mesh : layout.prototypes) {
            owned.push_back(kt::build(mesh, 4, KDRT_BUILDER_SAH));
            prototypes.push_back(owned.back().get());
        }
        const std::vector<kdrt_geometry> geometries = kb::kdrt_geometries(layout, prototypes);
        REQUIRE(geometries.size() == layout.first.size());
        kdrt_scene *scene = nullptr;
        REQUIRE(kdrt_scene_build(geometries.data(), uint32_t(geometries.size()), nullptr, &scene, nullptr) == KDRT_SUCCESS);
        std::string error;
        CHECK(kb::median_commit_ms(scene, layout, instanced ? 3 : 0, error) >= 0);
        for (uint32_t i = 0; i < layout.instances.size(); ++i)  // moved and back
            CHECK(std::memcmp(kdrt_scene_geometry(scene, i)->transform, layout.instances[i].transform, 48) == 0);
        for (kb::RayKind kind : {kb::RayKind::primary, kb::RayKind::diffuse}) {
            const std::vector<kdrt_ray> rays = kb::make_rays(layout.frame, kind, 48, 48, tree.get(), 1);
            std::vector<kdrt_hit> a(rays.size()), b(rays.size());
            size_t hits = 0;
            for (size_t i = 0; i < rays.size(); ++i) {
                kdrt_intersect(tree.get(), &rays[i], &a[i]);
                hits += kdrt_scene_intersect(scene, &rays[i], nullptr, &b[i]);
            }
            if (kind == kb::RayKind::primary) CHECK(hits == rays.size());  // the wall is behind everything
            const std::vector<uint32_t> one_tree = {0};
            CHECK(kb::count_scene_mismatches(b, layout.first, a, one_tree, instanced ? 1e-4 : 0) == 0);
        }
        kdrt_scene_free(scene);
    }
}

TEST_CASE("bench option --scene frames: its lists, --frames, and what does not apply", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({"--scene", "frames"}, opt, error));
    CHECK(opt.scenes == std::vector<std::string>{"frames"});
    CHECK(opt.frames == 30);
    CHECK(opt.instance_counts == std::vector<uint32_t>{1000, 10000});
    CHECK(opt.build_thread_counts == std::vector<unsigned>{1, 2});
    REQUIRE(parse({"--scene", "frames", "--frames", "4", "--instances", "7,9", "--build-threads", "2", "--size", "16x8",
                   "--instance-triangles", "100", "--compare", "none"},
                  opt, error));
    CHECK(opt.frames == 4);
    CHECK(opt.instance_counts == std::vector<uint32_t>{7, 9});
    CHECK(opt.instances == 7);
    CHECK(opt.build_thread_counts == std::vector<unsigned>{2});
    CHECK(opt.build_threads == 2);
    // The other modes take one count, as before.
    REQUIRE(parse({"--scene", "field", "--instances", "20", "--build-threads", "2"}, opt, error));
    CHECK(opt.instances == 20);
    CHECK(opt.build_threads == 2);

    const std::vector<std::vector<const char *>> bad = {
        {"--scene", "frames,field"},  {"--scene", "frames", "--frames", "0"}, {"--scene", "field", "--frames", "3"},
        {"--frames", "3"},            {"--scene", "field", "--instances", "5,6"}, {"--build-threads", "1,2"},
        {"--scene", "frames", "--instances", "5,"}, {"--scene", "frames", "--repeat", "2"},
        {"--scene", "frames", "--threads", "2"}, {"--scene", "frames", "--instance-spacing", "1.5"},
        {"--scene", "frames", "--rays", "shadow"}, {"--scene", "frames", "--accuracy"}};
    check_refused(bad);
}

TEST_CASE("the frames world: IDs, moves, the deformed mesh and the rows", "[bench]") {
    const common::Mesh ball = kt::sphere(4, 8, 1.0);
    const uint32_t n = ball.triangle_count();
    const kb::FramesWorld world = kb::frames_world({ball, ball}, {ball}, ball, 7, 1);
    REQUIRE(world.movers.size() == 7);
    REQUIRE(world.level.size() == 3);  // the floor, the wall, one statue
    CHECK(world.level_id(0) == 7);
    CHECK(world.deforming_id() == 10);
    REQUIRE(world.first.size() == 11);  // every ID, and a triangle's place in one list of them all
    for (uint32_t id = 0; id < 7; ++id) CHECK(world.first[id] == n * id);
    CHECK(world.first[10] - world.first[9] == n);  // the statue

    float a[12], b[12], again[12];
    kb::mover_transform(world, 3, 0, a);
    kb::mover_transform(world, 3, 1, b);
    kb::mover_transform(world, 3, 0, again);
    CHECK(std::memcmp(a, again, sizeof a) == 0);  // a frame's place depends on the frame alone
    CHECK(std::memcmp(a, b, sizeof a) != 0);      // and every instance moves from frame to frame
    const double moved = std::hypot(a[3] - b[3], a[11] - b[11]);
    CHECK(moved > 0);
    CHECK(moved < 0.1);

    std::vector<float> p0, p1;
    kb::deformed_positions(world, 0, p0);
    kb::deformed_positions(world, 1, p1);
    REQUIRE(p0.size() == world.deforming.positions.size() + 4);  // Embree's padding
    CHECK(p0 != p1);
    for (size_t i = 0; i < world.deforming.positions.size(); ++i) CHECK(std::fabs(p0[i] - world.deforming.positions[i]) <= 0.021f);

    const std::vector<kdrt_ray> rays = kb::frames_camera_rays(world, 4, 3);
    CHECK(rays.size() == 12);

    kb::FramesRow row;
    row.phase = "primary", row.instances = 7, row.threads = 2, row.variant = "fast";
    row.kdrt_ms = {2, 4, 3};
    row.count = 12;
    CHECK(kb::frames_csv_row(row) == "primary;7;2;fast;3.000;;;4.000;;3;12;;;");
    row.embree = true, row.embree_ms = {1, 1.5, 2}, row.embree_quality = "low";
    row.compared = true, row.mismatches = 1, row.compared_rays = 36;
    CHECK(kb::frames_csv_row(row) == "primary;7;2;fast;3.000;1.500;0.500;4.000;2.000;3;12;1;36;low");
    CHECK(split(kb::frames_csv_header(), ';').size() == split(kb::frames_csv_row(row), ';').size());
}

TEST_CASE("bench --save-load: its options, and a row a quality with every step timed and the file's size", "[bench]") {
    kb::Options opt;
    std::string error;
    REQUIRE(parse({"--save-load", "mesh.obj"}, opt, error));
    CHECK(opt.save_load);
    CHECK(opt.repeat == 7);
    REQUIRE(parse({"--save-load", "--repeat", "2", "--subdivide", "1", "-q", "-o", "out.csv"}, opt, error));
    CHECK((opt.repeat == 2 && opt.subdivide == 1 && opt.quiet && opt.output == "out.csv"));
    check_refused({{"--save-load", "--size", "8x8"}, {"--save-load", "--accuracy"}, {"--save-load", "--scene", "merged"},
                   {"--save-load", "--builder", "median"}, {"--save-load", "--leaf-sizes", "1"},
                   {"--save-load", "--threads", "2"}, {"--compare", "none", "--save-load"}});

    // A torus (indexed) and its soup: two rows each, FAST then MEDIUM, the file a little smaller
    // than the tree's memory, and the ratios the FAST build's time over the loads'.
    const common::Mesh torus = common::torus(24, 12, 1.0, 0.4);
    common::Mesh soup = torus;
    soup.indices.clear();
    for (uint32_t t = 0; t < torus.triangle_count(); ++t)
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) soup.positions.push_back(torus.positions[3 * size_t(torus.vertex(t, k)) + size_t(a)]);
    soup.positions.erase(soup.positions.begin(), soup.positions.begin() + std::ptrdiff_t(torus.positions.size()));
    REQUIRE(soup.triangle_count() == torus.triangle_count());
    std::vector<kb::SaveLoadRow> rows;
    REQUIRE(kb::measure_save_load(torus, "TORUS", 2, rows, error));
    REQUIRE(kb::measure_save_load(soup, "SOUP", 1, rows, error));
    REQUIRE(rows.size() == 4);
    for (size_t i = 0; i < rows.size(); ++i) {
        const kb::SaveLoadRow &r = rows[i];
        INFO(kb::save_load_csv_row(r));
        CHECK(r.mesh == (i < 2 ? "TORUS" : "SOUP"));
        CHECK(r.quality == (i % 2 == 0 ? "fast" : "medium"));
        CHECK(r.triangles == torus.triangle_count());
        for (double ms : {r.build_ms, r.save_ms, r.load_ms, r.load_in_place_ms, r.fingerprint_ms})
            CHECK((std::isfinite(ms) && ms >= 0));
        CHECK(r.fast_build_ms == rows[i - i % 2].build_ms);
        CHECK((r.saved_bytes > 288 && r.saved_bytes < r.tree_bytes));
        const std::vector<std::string> fields = split(kb::save_load_csv_row(r), ';');
        CHECK(fields.size() == split(kb::save_load_csv_header(), ';').size());
    }
    // The soup holds the same corners in the same order: the same tree, a file of the same size.
    CHECK(rows[0].saved_bytes == rows[2].saved_bytes);
    const std::string table = kb::save_load_table(rows);
    CHECK(std::count(table.begin(), table.end(), '\n') == 6);
    CHECK(table.find("| SOUP | " + std::to_string(torus.triangle_count()) + " | medium | ") != std::string::npos);
}
