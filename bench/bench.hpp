// kdrt-bench's pieces, kept apart from main() so the tests can check them: options, the leaf-size
// stop rule, the benchmark scene and its rays, the CSV rows, and the --accuracy sets and rows.
#pragma once

#include "oracle/hard_cases.hpp"
#include "kdrt.h"
#include "common/mesh_io.hpp"
#include "oracle/reference.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace kb {

enum class RayKind { primary, diffuse, random, shadow };

// How the rays are handed to the tracer (--batch, the Call column): one call a ray
// (kdrt_intersect, rtcIntersect1); batch calls over --batch-size consecutive rays at a time
// (kdrt_intersect_batch, rtcIntersect1M with the COHERENT flag); or, Embree only, packets of 8 or
// 16 consecutive rays (rtcIntersect8, rtcIntersect16), every lane valid.
enum class Call { single, batch, packet8, packet16 };
const char *call_name(Call call);  // "single", "batch", "packet8", "packet16"
constexpr uint32_t kDefaultBatchSize = 4096;

// The SAH builder's cost constants (kdrt_build_options.sah_*): traversal K_T, intersection K_I,
// empty bonus EB.
struct SahCosts {
    float traversal = KDRT_DEFAULT_SAH_TRAVERSAL_COST;
    float intersection = KDRT_DEFAULT_SAH_INTERSECTION_COST;
    float empty_bonus = KDRT_DEFAULT_SAH_EMPTY_BONUS;
};
// "KT:KI:EB", each with %g ("30:20:0.1"): how --sah-costs reads a triple and SahCosts writes it.
std::string sah_costs_label(const SahCosts &costs);

struct Options {
    unsigned width = 800, height = 800;
    unsigned threads = 1;
    unsigned build_threads = 1;        // --build-threads: the SAH build's threads; 0: all cores
    unsigned repeat = 1;
    // --leaf-sizes; default kDefaultLeafSize, the original's list (sweep_leaf_sizes()) with --sweep
    std::vector<uint32_t> leaf_sizes;
    // "median" and/or "sah", in the order given; default sah, median with --sweep
    std::vector<std::string> builders;
    std::vector<SahCosts> sah_costs;   // --sah-costs: a SAH variant each; empty: kdrt.h's defaults
    std::vector<kdrt_build_quality> qualities;  // --quality: a SAH variant each; empty: the default
    // --kernel: "default", "avx512", "avx2" and/or "scalar", a variant of every kdrt build each,
    // in the order given (kernel_flags()); "default" is the build's own choice
    std::vector<std::string> kernels{"default"};
    std::vector<std::string> queries{"plain"};  // --query: "plain" and/or "filter", traced in turn
    // --start: "cell" and/or "root", traced in turn; empty: starts_for()'s default
    std::vector<std::string> starts;
    RayKind rays = RayKind::primary;
    std::vector<Call> calls{Call::single};  // --batch: each traced in turn, a row each
    uint32_t batch_size = kDefaultBatchSize;  // --batch-size: rays per batch call
    // The rays' order (ray_order()): tiles of tile_width x tile_height pixels, 1x1 being the
    // pixel order; --tile, or 4x2 when --batch is given; --shuffle shuffles them (seeded).
    unsigned tile_width = 1, tile_height = 1;
    bool shuffle = false;
    std::string output;                // "" means stdout
    // --compare embree or none. Not given: Embree when this kdrt-bench has it (main decides, as
    // only it links Embree), none with --sweep; compare_chosen says which.
    bool compare_embree = false;
    bool compare_chosen = false;
    // --sweep: the original course benchmark, the median builder at every leaf size of
    // sweep_leaf_sizes() and no Embree, unless --builder, --leaf-sizes or --compare say otherwise.
    bool sweep = false;
    bool quiet = false;                // --quiet: no progress lines on stderr, only what went wrong
    unsigned subdivide = 0;
    size_t reference_rays = 20000;     // rays checked against the reference per frame or set; 0: all
    // Ray/triangle tests to run; empty: watertight in the leaf-size CSV, both under --accuracy.
    std::vector<kdrt_intersector> intersectors;
    bool accuracy = false;             // --accuracy: error counts per intersector, not leaf sizes
    // --save-load: build (FAST and the default quality), save and load (copied, in place) timed
    // side by side on each mesh (saved_trees.hpp), not leaf sizes
    bool save_load = false;
    // --points: closest-point and overlap queries (points.hpp), --queries closest-point queries
    // per kind of point (a hundredth of that per overlap size); --reference-rays checks that many of
    // each against the brute force (1000 unless given).
    bool points = false;
    size_t point_queries = 100000;
    size_t hard_rays = 20000;          // --accuracy: rays per watertight and per hard-case set
    // --scene: "merged" and/or "field", in the order given (scenes.hpp), or "frames" alone
    // (frames.hpp); empty: not the scene mode.
    std::vector<std::string> scenes;
    uint32_t instances = 1000;         // --instances: the field's (the first of the list)
    // --scene frames: --instances and --build-threads as lists, each count measured in turn
    // (default 1000,10000 and 1,2; the other modes take one), and the frames timed (--frames).
    std::vector<uint32_t> instance_counts;
    std::vector<unsigned> build_thread_counts;
    unsigned frames = 30;
    uint32_t instance_triangles = 3000;  // --instance-triangles: each field mesh's, about; 0: whole
    double instance_spacing = 1;       // --instance-spacing: the field's grid pitch
    std::vector<std::string> inputs;   // mesh files or folders
    bool help = false;
};

// "watertight" or "fast", as --intersector and the Intersector column spell them.
const char *intersector_name(kdrt_intersector intersector);
// What the run traces with: opt.intersectors, or the default for its mode.
std::vector<kdrt_intersector> intersectors_for(const Options &opt);

// "fast", "medium", "high" as --quality and the Quality column spell them ("default" for 0).
const char *quality_name(kdrt_build_quality quality);

// The kdrt_build_options.flags that ask for a --kernel name's kernel: KDRT_BUILD_AVX2_KERNEL for
// "avx2", KDRT_BUILD_SCALAR_KERNEL for "scalar", 0 for "avx512" and "default" (the widest the CPU
// runs).
uint32_t kernel_flags(const std::string &kernel);
// "scalar", "avx2", "avx512": kdrt_tree_stats.kernel as the Kernel column spells it.
const char *kernel_name(kdrt_kernel kernel);
// runs: the kernel a tree built with kernel_flags(kernel) runs, from a tree of one triangle;
// false with a message when that tree does not build.
bool kernel_that_runs(const std::string &kernel, kdrt_kernel &runs, std::string &error);
// false with a message naming --kernel when a kernel of the list other than "default" is not the
// one a tree built with its kernel_flags() runs (the CPU, or this build of kdrt, lacks it: a tree
// asked for avx512 runs avx2 or scalar). Builds a tree of one triangle per name; nothing timed.
bool check_kernels(const std::vector<std::string> &kernels, std::string &error);

// What a run builds, in order: each builder of opt.builders, the SAH builder once per quality of
// opt.qualities (or once at the default) and triple of opt.sah_costs (or once with the defaults),
// each of those once per kernel of opt.kernels.
struct BuildVariant {
    std::string builder;          // Builder column: median or sah
    kdrt_build_options options;   // builder, SAH costs and kernel flags set; leaf size and intersector are not
    std::string sah_costs;        // SahCosts column: sah_costs_label() for sah, empty for median
    std::string quality;          // Quality column: quality_name() for sah, empty for median
    std::string kernel;           // the --kernel name asked for (the Kernel column says what ran)
};
std::vector<BuildVariant> build_variants(const Options &opt);

// opt.calls that kdrt has (single, batch), in order: the packets are Embree's alone.
std::vector<Call> kdrt_calls(const Options &opt);

// Where the traced rays start (--start): opt.starts, or "cell" and "root" for the rays that start
// on the surface (diffuse, shadow) and "root" for the others.
std::vector<std::string> starts_for(const Options &opt);

// The max leaf size of a run without --leaf-sizes or --sweep: kdrt's default.
constexpr uint32_t kDefaultLeafSize = KDRT_DEFAULT_MAX_LEAF_SIZE;
// The original benchmark's leaf sizes, --sweep's: 0 (no tree), 1, 2, 3, 4, 6, 8, ..., 768, 1024.
std::vector<uint32_t> sweep_leaf_sizes();
// The original's stop rule: sizes in order up to and including the first at or above the mesh's
// triangle count (larger leaves would all be the same single leaf).
std::vector<uint32_t> leaf_sizes_for(const std::vector<uint32_t> &sizes, uint32_t mesh_triangles);

// false with a message naming the bad argument.
bool parse_options(int argc, const char *const *argv, Options &out, std::string &error);
std::string usage();

// The benchmark frame: the mesh centred and scaled so its larger side across the view spans
// [-1, 1], a back-wall quad (two triangles, last in the buffers) behind it, and a pinhole camera
// on +z looking down -z whose view just holds [-1.05, 1.05] at z = 0.
struct Scene {
    std::string name;                  // upper-cased file stem: NEFERTITI, UNIT_SPHERE_N, ...
    common::Mesh geometry;                 // mesh + wall, what the tree is built over
    uint32_t mesh_triangles = 0;       // the mesh alone (the stop rule counts these)
    float eye[3] = {0, 0, 0};
    float tan_half_fov = 0;
    double centre[3] = {0, 0, 0};      // the mesh's vertex p went to (p - centre) * scale, in double,
    double scale = 1;                  // rounded to float once
};
Scene make_scene(const common::Mesh &mesh, const std::string &name);

// One ray per pixel centre (row-major), or the bounces or random rays built from them, or shadow
// rays: from every primary hit to the point light kShadowLight, which lies above and in front of
// the scene, over t in [0, 1] (the light at t = 1). tree is used for the primary hits. pixels,
// unless NULL, gets each ray's pixel (y * width + x; a random ray's is its index).
std::vector<kdrt_ray> make_rays(const Scene &scene, RayKind kind, unsigned width, unsigned height,
                                const kdrt_tree *tree, uint32_t seed, std::vector<uint32_t> *pixels = nullptr);

// The order to trace rays in, as a renderer hands them over: order[k] is the index (into pixels,
// make_rays' list) of the k-th ray. The frame is cut into tiles of tile_width x tile_height
// pixels, tiles row by row from the top left (those on the right and bottom edges cut short),
// pixels row by row within a tile, so a ray spawned at a hit comes where its primary ray came;
// 1x1 tiles give the pixel order. With shuffle, that order shuffled instead (seeded).
std::vector<size_t> ray_order(const std::vector<uint32_t> &pixels, unsigned width, unsigned tile_width,
                              unsigned tile_height, bool shuffle, uint32_t seed);
// "800x800 primary rays", and " in 4x2 tiles" or ", shuffled" when the order is not the pixels'.
std::string frame_rays(const Options &opt, RayKind kind);

// Rays whose two answers differ in any field, bit for bit (t, u, v, triangle, geometry, instance,
// cell; -0 is not 0): what a batch call must never give (kdrt.h, BATCHES). first: the first such
// ray's index, or SIZE_MAX when none does.
size_t count_differing_hits(const std::vector<kdrt_hit> &a, const std::vector<kdrt_hit> &b, size_t &first);
size_t count_differing_occlusion(const std::vector<unsigned char> &a, const std::vector<unsigned char> &b, size_t &first);
// "triangle 12 t 0x1.8p+0 u ... cell 7" (floats in hex, every bit shown), for the messages.
std::string describe_hit(const kdrt_hit &hit);

constexpr float kShadowLight[3] = {1.5f, 3.0f, 2.5f};

// A kdrt_filter_fn that takes every candidate: the answers of no filter, at the cost of asking
// (--query filter, and the scene mode's Query filter).
int take_every_hit(void *user, const kdrt_ray *ray, const kdrt_hit *candidate);

// Shadow rays (any hit) of the sample whose answer the reference contradicts: not occluded where
// a triangle is surely hit in the range, or occluded where no triangle can be hit at all.
size_t count_occlusion_mismatches(const oracle::Oracle &oracle, const std::vector<oracle::Reference> &refs,
                                  const std::vector<size_t> &sample, const std::vector<kdrt_ray> &rays,
                                  const std::vector<unsigned char> &occluded, uint32_t triangles);

// Sorted, distinct, seeded choice of `count` indices out of `total` (all of them if count is 0
// or at least total).
std::vector<size_t> reference_sample(size_t total, size_t count, uint32_t seed);

// Rays of the sample whose answer contradicts the reference (oracle::check_hit's "wrong"): a miss
// where a triangle is surely hit, a hit the ray cannot make, a t off the reference's, or a
// farther triangle where a nearer one is surely hit. refs[k] belongs to rays[sample[k]].
size_t count_mismatches(const oracle::Oracle &oracle, const std::vector<oracle::Reference> &refs,
                        const std::vector<size_t> &sample, const std::vector<kdrt_ray> &rays,
                        const std::vector<kdrt_hit> &hits);

struct Row {
    std::string mesh;
    int max_leaf_size = 0;             // -1 on Embree rows: not a kd-tree
    double trace_ms = 0, build_ms = 0;
    std::string builder;
    std::string intersector = "watertight";  // empty on Embree rows
    uint32_t triangles = 0;
    size_t rays = 0;
    bool has_tree_stats = false;       // Embree rows leave the tree columns empty
    kdrt_tree_stats stats{};
    size_t mismatches = 0, reference_rays = 0;
    std::string sah_costs;             // "KT:KI:EB" on SAH rows, empty otherwise
    unsigned build_threads = 1;        // threads the build ran on (Embree's too)
    std::string quality;               // the SAH build's quality, or Embree's ("low", "medium")
    std::string query;                 // Query column: "plain" or "filter"; empty on Embree rows
    std::string start;                 // Start column: "cell" or "root"; empty on Embree rows
    std::string call = "single";       // Call column: call_name() of how the rays were handed over
    std::string kernel;                // Kernel column: kernel_name() of the tree's kernel; empty on Embree rows
};
std::string csv_header();
std::string csv_row(const Row &row);

// ---- kdrt-bench --accuracy ----

// One ray set of the accuracy run over its own scene.
struct AccuracySet {
    std::string set;              // Set column: frame-primary, frame-diffuse, watertight, hard, far
    std::string scene;            // Scene column: the mesh, hard case, or moved mesh
    common::Mesh mesh;
    std::vector<kdrt_ray> rays;
    bool must_hit = false;        // every ray crosses the surface: a miss is a leak
};

// The benchmark frame of a scene: its primary rays ("frame-primary") and a cosine bounce from
// every primary hit ("frame-diffuse", spawned with kdrt_spawn_ray()). Both ray sets are made with
// a default (watertight) tree so every intersector traces the very same rays.
std::vector<AccuracySet> frame_sets(const Scene &scene, unsigned width, unsigned height, uint32_t seed);
// The frame's primary rays with the scene and the camera moved by `offset` along (1, 1, 1)
// (oracle::translated), and scaled by max(1, offset / 1000), so the scene spans about as many float
// steps at each offset (20,000 to 33,000) and its triangles stay triangles ("far").
AccuracySet far_set(const Scene &scene, double offset, unsigned width, unsigned height, uint32_t seed);
// oracle::closed_meshes(true) with oracle::rays_at_vertices_and_edges() ("watertight", must hit), and
// oracle::hard_sets() ("hard"), `rays` rays each.
std::vector<AccuracySet> watertight_sets(size_t rays, uint64_t seed);
std::vector<AccuracySet> hard_case_sets(size_t rays, uint64_t seed);

struct AccuracyRow {
    std::string set, scene;
    std::string intersector;      // watertight, fast, or "oracle" for the reference row
    uint32_t triangles = 0;
    size_t rays = 0;              // rays traced and timed
    double trace_ms = 0;
    bool measured = true;         // false on oracle rows: it is the reference, no errors counted
    bool counts_leaks = false;    // only must-hit sets can leak
    oracle::ErrorCounts errors;       // leaks, false hits, self-hits, mismatches; first: the first error
    size_t reference_rays = 0;    // the sample: rays compared with the oracle, and spawned from
    size_t spawned_rays = 0;      // secondary rays oracle::count_self_hits() spawned from the sample
    size_t naive_self_hits = 0;   // self-hits of the same rays started at the hit, no offset
};
std::string accuracy_csv_header();
std::string accuracy_csv_row(const AccuracyRow &row);

// Traces one set with each intersector (a default-leaf-size median tree each, on `threads`
// threads, timed_passes passes taking turns, the fastest kept) and counts its errors: leaks over
// all rays (must-hit sets, oracle::count_leaks); on a seeded sample of `reference_rays` rays (0: all),
// false hits and mismatches against the double-precision oracle (oracle::count_mismatches) and the
// self-hits of the secondary rays oracle::count_self_hits() spawns from the sample's hits, with
// kdrt_spawn_ray and, for comparison, with no offset. With oracle_row, a first row times the
// oracle itself (brute force in double precision, one thread, over the sample). Appends a row per
// intersector; false with a message when a build fails.
bool run_accuracy_set(const AccuracySet &set, const std::vector<kdrt_intersector> &intersectors, size_t reference_rays,
                      unsigned threads, unsigned timed_passes, uint32_t seed, bool oracle_row, std::vector<AccuracyRow> &rows,
                      std::string &error);

// Rows summed per Set and Intersector, in first-seen order: MRaysPerSec over all their rays.
std::vector<AccuracyRow> accuracy_summary(const std::vector<AccuracyRow> &rows);
// The summary as an aligned text table (kdrt-bench prints it on stderr).
std::string accuracy_table(const std::vector<AccuracyRow> &summary);

}  // namespace kb
