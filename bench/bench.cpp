#include "bench.hpp"
#include "common/mesh_io.hpp"  // common::mesh_dir_help
#include "common/parse.hpp"
#include "common/random.hpp"
#include "common/timing.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <numeric>
#include <utility>

namespace kb {

using common::timed_parallel;

namespace {

// The ray sets' and samples' random stream, seeded as the bench has always seeded it, so a
// seed gives the rays of the CSVs in bench/results.
common::Rng seeded(uint32_t seed) { return common::Rng::from_state(0x243F6A8885A308D3ull ^ (uint64_t(seed) * 0x9E3779B97F4A7C15ull)); }

// The comma-separated items of an option's value, empty ones included ("a,,b" has three), which
// no option takes.
std::vector<std::string> list_items(const std::string &text) {
    std::vector<std::string> items;
    size_t start = 0;
    while (true) {
        size_t comma = text.find(',', start);
        items.push_back(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
        if (comma == std::string::npos) return items;
        start = comma + 1;
    }
}

std::string lower(std::string text) {
    for (char &c : text) c = char(std::tolower(static_cast<unsigned char>(c)));
    return text;
}

// A list of names, each one of `choices` in either case ("SAH" is "sah"), into their values in
// order; false when an item is none of them (an empty one included).
template <typename T>
bool parse_choices(const std::string &text, const std::vector<std::pair<std::string, T>> &choices,
                   std::vector<T> &out) {
    out.clear();
    for (const std::string &item : list_items(lower(text))) {
        auto found = std::find_if(choices.begin(), choices.end(), [&](const std::pair<std::string, T> &c) {
            return c.first == item;
        });
        if (found == choices.end()) return false;
        out.push_back(found->second);
    }
    return true;
}

// "KT:KI:EB,KT:KI:EB,...": K_T and K_I finite and above 0, EB in (0, 1). kdrt reads a zero cost
// or bonus as "use the default", so 0 is refused rather than silently replaced.
bool parse_sah_costs(const std::string &text, std::vector<SahCosts> &out, std::string &error) {
    out.clear();
    for (const std::string &item : list_items(text)) {
        float v[3];
        size_t field_start = 0;
        int fields = 0;
        for (; fields < 3; ++fields) {
            size_t colon = item.find(':', field_start);
            if ((fields < 2) != (colon != std::string::npos)) break;  // exactly two colons
            std::string field = item.substr(field_start, colon == std::string::npos ? std::string::npos : colon - field_start);
            if (field.empty() || std::isspace(static_cast<unsigned char>(field[0]))) break;
            char *end = nullptr;
            errno = 0;
            double d = std::strtod(field.c_str(), &end);
            if (errno != 0 || *end != '\0' || !(d == d)) break;
            v[fields] = float(d);
            field_start = colon + 1;
        }
        if (fields < 3) {
            error = "--sah-costs wants KT:KI:EB triples (traversal cost, intersection cost, empty bonus) separated "
                    "by commas, e.g. 15:20:0.2,1:80:0.5; got '" + text + "'";
            return false;
        }
        if (!(v[0] > 0 && v[0] <= 1e6f && v[1] > 0 && v[1] <= 1e6f && v[2] > 0 && v[2] < 1)) {
            error = "--sah-costs: in '" + item + "', KT and KI must be above 0 (at most 1e6) and EB between 0 and 1, "
                    "both excluded (kdrt reads 0 as its default)";
            return false;
        }
        SahCosts c;
        c.traversal = v[0], c.intersection = v[1], c.empty_bonus = v[2];
        out.push_back(c);
    }
    return true;
}

}  // namespace

std::string sah_costs_label(const SahCosts &costs) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%g:%g:%g", double(costs.traversal), double(costs.intersection), double(costs.empty_bonus));
    return buf;
}

const char *quality_name(kdrt_build_quality quality) {
    switch (quality) {
    case KDRT_BUILD_QUALITY_FAST: return "fast";
    case KDRT_BUILD_QUALITY_MEDIUM: return "medium";
    case KDRT_BUILD_QUALITY_HIGH: return "high";
    default: return "default";
    }
}

uint32_t kernel_flags(const std::string &kernel) {
    if (kernel == "avx2") return KDRT_BUILD_AVX2_KERNEL;
    if (kernel == "scalar") return KDRT_BUILD_SCALAR_KERNEL;
    return 0;  // avx512 and default: the widest kernel the CPU runs
}

const char *kernel_name(kdrt_kernel kernel) { return kdrt_kernel_string(kernel); }

bool kernel_that_runs(const std::string &kernel, kdrt_kernel &runs, std::string &error) {
    const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t indices[3] = {0, 1, 2};
    kdrt_triangles one = {};
    one.positions = positions;
    one.indices = indices;
    one.vertex_count = 3;
    one.triangle_count = 1;
    kdrt_build_options options = kdrt_default_build_options();
    options.flags = kernel_flags(kernel);
    kdrt_tree *tree = nullptr;
    const kdrt_result r = kdrt_tree_build(&one, &options, &tree, nullptr);
    if (r != KDRT_SUCCESS) {
        error = "--kernel " + kernel + ": a test tree of one triangle did not build: " + kdrt_result_string(r);
        return false;
    }
    kdrt_tree_stats stats;
    kdrt_tree_get_stats(tree, &stats);
    kdrt_tree_free(tree);
    runs = stats.kernel;
    return true;
}

bool check_kernels(const std::vector<std::string> &kernels, std::string &error) {
    for (const std::string &kernel : kernels) {
        if (kernel == "default") continue;
        kdrt_kernel runs = KDRT_KERNEL_SCALAR;
        if (!kernel_that_runs(kernel, runs, error)) return false;
        if (kernel_name(runs) != kernel) {
            error = "--kernel " + kernel + " is not available here: this CPU (or this build of kdrt) lacks it, and a "
                    "tree asked for it would run the " + kernel_name(runs) + " kernel";
            return false;
        }
    }
    return true;
}

std::vector<BuildVariant> build_variants(const Options &opt) {
    std::vector<BuildVariant> variants;
    const std::vector<SahCosts> triples = opt.sah_costs.empty() ? std::vector<SahCosts>(1) : opt.sah_costs;
    const std::vector<kdrt_build_quality> qualities =
        opt.qualities.empty() ? std::vector<kdrt_build_quality>{KDRT_BUILD_QUALITY_DEFAULT} : opt.qualities;
    const std::vector<std::string> kernels = opt.kernels.empty() ? std::vector<std::string>{"default"} : opt.kernels;
    const auto each_kernel = [&](BuildVariant v) {  // the build once per kernel, kernels innermost
        for (const std::string &kernel : kernels) {
            v.kernel = kernel;
            v.options.flags = kernel_flags(kernel);
            variants.push_back(v);
        }
    };
    for (const std::string &builder : opt.builders) {
        BuildVariant v;
        v.builder = builder;
        v.options = kdrt_default_build_options();
        if (builder != "sah") {
            v.options.builder = KDRT_BUILDER_MEDIAN;
            each_kernel(v);
            continue;
        }
        v.options.builder = KDRT_BUILDER_SAH;
        for (kdrt_build_quality quality : qualities)
            for (const SahCosts &c : triples) {
                v.options.quality = quality;
                v.options.sah_traversal_cost = c.traversal;
                v.options.sah_intersection_cost = c.intersection;
                v.options.sah_empty_bonus = c.empty_bonus;
                v.sah_costs = sah_costs_label(c);
                v.quality = quality_name(quality);
                each_kernel(v);
            }
    }
    return variants;
}

std::vector<uint32_t> sweep_leaf_sizes() {
    return {0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024};
}

std::vector<uint32_t> leaf_sizes_for(const std::vector<uint32_t> &sizes, uint32_t mesh_triangles) {
    std::vector<uint32_t> kept;
    for (uint32_t size : sizes) {
        kept.push_back(size);
        if (size >= mesh_triangles) break;
    }
    return kept;
}

const char *call_name(Call call) {
    switch (call) {
    case Call::batch: return "batch";
    case Call::packet8: return "packet8";
    case Call::packet16: return "packet16";
    default: return "single";
    }
}

std::vector<Call> kdrt_calls(const Options &opt) {
    std::vector<Call> calls;
    for (Call call : opt.calls)
        if (call == Call::single || call == Call::batch) calls.push_back(call);
    return calls;
}

const char *intersector_name(kdrt_intersector intersector) {
    return intersector == KDRT_INTERSECTOR_FAST ? "fast" : "watertight";
}

std::vector<kdrt_intersector> intersectors_for(const Options &opt) {
    if (!opt.intersectors.empty()) return opt.intersectors;
    if (opt.accuracy) return {KDRT_INTERSECTOR_FAST, KDRT_INTERSECTOR_WATERTIGHT};
    return {KDRT_INTERSECTOR_WATERTIGHT};
}

std::string usage() {
    return "usage: kdrt-bench [options] [MESH_OR_FOLDER ...]\n"
           "       kdrt-bench --sweep [options] [MESH_OR_FOLDER ...]\n"
           "       kdrt-bench --accuracy [options] [MESH_OR_FOLDER ...]\n"
           "       kdrt-bench --scene merged,field [options] [MESH ...]\n"
           "       kdrt-bench --scene frames [options] [MESH ...]\n"
           "       kdrt-bench --save-load [--repeat N] [--subdivide K] [MESH_OR_FOLDER ...]\n"
           "       kdrt-bench --points [options] [MESH_OR_FOLDER ...]\n"
           "\n"
           "Builds kdrt's default kd-tree (SAH builder, default quality, max leaf size 4) over each\n"
           "mesh and traces the benchmark frame: the mesh scaled to fill the view in front of a\n"
           "back wall, one primary ray per pixel, closest hit; then Embree 3's BVH over the same\n"
           "rays, when this kdrt-bench was built with Embree. Writes Mesh;MaxLeafSize;ElapsedMs;...\n"
           "as CSV, one row per build and repetition; SahCost is the tree's SAH cost\n"
           "(kdrt_tree_stats.sah_cost, with the build's costs). Progress goes to standard error, a\n"
           "line per mesh and build (--quiet: none).\n"
           "--sweep runs the original course benchmark instead: the median builder at every max\n"
           "leaf size 0 (no tree), 1, 2, 3, 4, 6, 8, 12, ..., 768, 1024, no Embree.\n"
           "Meshes: OFF, OBJ, PLY, STL, glTF files, or folders of them. Default: the original's\n"
           "meshes in the mesh folder's seed/ when present, else generated ones. hostile:KIND:N\n"
           "generates N triangles that push a kd-tree builder to its worst, KIND one of fan,\n"
           "cone, slivers, overlapping, identical (or soup: small random triangles, a big input).\n"
           "\n"
           "  --size WxH          frame size (default 800x800; 400x400 with --accuracy)\n"
           "  --threads N         tracing threads (default 1)\n"
           "  --build-threads N   threads of the SAH build (default 1, as Embree's; 0: all cores)\n"
           "  --repeat N          rows per mesh and leaf size (default 1); with --accuracy, timed\n"
           "                      passes per set and intersector, in turns, the fastest kept\n"
           "                      (default 3)\n"
           "  --sweep             the original benchmark: --builder median, --leaf-sizes\n"
           "                      0,1,2,3,4,6,8,12,...,768,1024, --compare none (each of them\n"
           "                      given as well overrides it: --sweep --builder sah)\n"
           "  --leaf-sizes LIST   comma-separated max leaf sizes, 0 = no tree (default 4; each mesh\n"
           "                      stops after the first size at or above its triangle count)\n"
           "  --builder LIST      sah (surface area heuristic, the default), median (the\n"
           "                      original's median split), or both: median,sah\n"
           "  --sah-costs LIST    SAH cost constants KT:KI:EB (traversal cost, intersection cost,\n"
           "                      empty bonus; KT, KI > 0, 0 < EB < 1), comma-separated: the SAH\n"
           "                      builder runs once per triple, named in the SahCosts column\n"
           "                      (default: kdrt.h's, 30:20:0.1; pbrt-v3's are 1:80:0.5)\n"
           "  --quality LIST      the SAH build's quality: fast, medium, high, comma-separated:\n"
           "                      the SAH builder runs once per level, named in the Quality\n"
           "                      column (default: kdrt.h's default level)\n"
           "  --query LIST        plain (kdrt_intersect, kdrt_occluded: the default) and/or filter\n"
           "                      (their _query forms with a filter that takes every hit: what\n"
           "                      an unused filter costs), comma-separated: each tree traced with\n"
           "                      each in turn, named in the Query column\n"
           "  --start LIST        cell (each ray starts in the leaf that holds its origin, as\n"
           "                      kdrt_spawn_ray() and kdrt_locate() give it: kdrt.h, START\n"
           "                      CELLS) and/or root (the walk from the root), comma-separated:\n"
           "                      each tree traced with each in turn, named in the Start column\n"
           "                      (default: cell,root for diffuse and shadow rays, root for the\n"
           "                      others, whose origin lies outside the tree)\n"
           "  --batch LIST        how the rays are handed over, comma-separated, a row each, named\n"
           "                      in the Call column: single (kdrt_intersect, rtcIntersect1: the\n"
           "                      default), batch (kdrt_intersect_batch and Embree's rtcIntersect1M\n"
           "                      with the COHERENT flag, on chunks of --batch-size rays), packet8,\n"
           "                      packet16 (Embree's rtcIntersect8, rtcIntersect16 on consecutive\n"
           "                      rays, every lane valid, COHERENT; no kdrt rows). Shadow rays: the\n"
           "                      occluded forms. Each kdrt batch answer must be the single call's,\n"
           "                      bit for bit, or the run fails. With --batch the rays come in\n"
           "                      tiles (--tile)\n"
           "  --batch-size N      rays per batch call, each chunk consecutive rays of the order\n"
           "                      (default 4096; the last chunk holds the rest)\n"
           "  --tile WxH          the rays' order: tiles of W x H pixels, tiles row by row, pixels\n"
           "                      row by row in each, diffuse and shadow rays in their primary\n"
           "                      rays' order (default with --batch: 4x2, 8 rays; 1x1 is the pixel\n"
           "                      order, the default without --batch)\n"
           "  --shuffle           the rays in a shuffled order (seeded): incoherent batches\n"
           "  --kernel LIST       the kernel kdrt's trees run, comma-separated, each build once\n"
           "                      per kernel: default (the build's choice, the widest the CPU\n"
           "                      runs: the default), avx512 (batches in packets of 16 rays; an\n"
           "                      error where the CPU lacks it), avx2 (KDRT_BUILD_AVX2_KERNEL:\n"
           "                      packets of 8), scalar (KDRT_BUILD_SCALAR_KERNEL). The Kernel\n"
           "                      column names the kernel that ran; Embree's rows come once,\n"
           "                      their Kernel empty\n"
           "  --rays KIND         primary | diffuse (cosine bounces from the primary hits, spawned\n"
           "                      with kdrt_spawn_ray) | random (uniform rays through the scene box)\n"
           "                      | shadow (from the primary hits to a point light above the\n"
           "                      scene: kdrt_occluded, and Embree's rtcOccluded1)\n"
           "  --reference-rays N  rays per frame or ray set checked against the double-precision\n"
           "                      brute-force reference (default 20000, seeded; 0: every ray)\n"
           "  --subdivide K       K levels of 4-to-1 subdivision of every mesh first\n"
           "  --compare embree|none  Embree 3 beside kdrt, or not (default: embree when this\n"
           "                      kdrt-bench was built with it, none with --sweep): its build on\n"
           "                      --build-threads threads at LOW quality for --quality fast,\n"
           "                      MEDIUM for the others (both when both are asked), its rays on\n"
           "                      --threads\n"
           "  --intersector LIST  watertight (the default), fast (Moeller-Trumbore), or both\n"
           "                      separated by a comma: a row for each, named in the last column\n"
           "  --accuracy          speed beside error counts for each intersector (see below)\n"
           "  --save-load         saved trees: build, save and load timed side by side (see below)\n"
           "  --points            closest-point queries (kdrt_closest_point against Embree's\n"
           "                      rtcPointQuery) from points near the surface, inside the mesh's\n"
           "                      box and far outside it, and overlap queries (kdrt_overlap_box,\n"
           "                      kdrt_overlap_sphere) by size, one thread (see below)\n"
           "  --queries N         with --points: closest-point queries per kind of point (default\n"
           "                      100000; overlap queries: a hundredth of that per size)\n"
           "  --scene LIST        merged, field or both: kdrt_scene against one tree; or frames:\n"
           "                      a game's frames against Embree (see below)\n"
           "  --instances N       with --scene field: instances in the field (default 1000); with\n"
           "                      --scene frames a list, each count in turn (default 1000,10000)\n"
           "  --frames N          with --scene frames: frames timed per count, threads and\n"
           "                      variant (default 30)\n"
           "  --instance-triangles N  with --scene field: each mesh simplified to about N\n"
           "                      triangles first (default 3000; 0: whole)\n"
           "  --instance-spacing D  with --scene field: the grid's pitch, in the unit the meshes\n"
           "                      are sized to (default 1: neighbours' boxes overlap)\n"
           "  --hard-rays N       with --accuracy: rays per watertight and per hard-case set\n"
           "                      (default 20000)\n"
           "  -o FILE             write the CSV to FILE (default: standard output): the rows go to\n"
           "                      FILE.partial, renamed over FILE when the run ends with a row\n"
           "  -q, --quiet         no progress lines on standard error, only what went wrong\n"
           "  --help              this text\n"
           "Option values are names in either case: --builder SAH is --builder sah.\n"
           "\n"
           "--accuracy traces these ray sets with each intersector (default fast,watertight), each\n"
           "through a tree of the default leaf size: every mesh's frame (frame-primary, and\n"
           "frame-diffuse: bounces from the primary hits), the frame moved 1e3, 1e5 and 1e7 away\n"
           "from the origin (far), rays at the vertices and edges of closed meshes (watertight), and\n"
           "the hard-case sets (hard). It writes Set;Scene;Intersector;Triangles;Rays;TraceMs;\n"
           "MRaysPerSec;Leaks;FalseHits;SelfHits;Mismatches;SpawnedRays;ReferenceRays;\n"
           "NaiveSelfHits, a row per set and intersector and an 'oracle' row timing the\n"
           "double-precision reference itself (one thread, on its sample), and a summary per set\n"
           "on standard error. Leaks: must-hit rays that miss (watertight sets; all rays).\n"
           "The other counts use a seeded sample of --reference-rays rays (ReferenceRays) per set:\n"
           "FalseHits and Mismatches, answers the reference contradicts; SelfHits, secondary rays\n"
           "kdrt_spawn_ray starts from the sample's hits (SpawnedRays: reflected, through and two\n"
           "grazing per hit) whose nearest hit is the triangle they leave; NaiveSelfHits, the same\n"
           "for the same rays started exactly at the hit point, with no offset.\n"
           "--sweep, --leaf-sizes, --rays, --compare, --sah-costs, --quality, --query, --start,\n"
           "--batch, --batch-size, --tile, --shuffle and --kernel do not apply.\n"
           "\n"           "--points builds kdrt's default tree (and Embree's MEDIUM BVH, with --compare embree)\n"
           "over each mesh and times, interleaved --repeat times (default 5; the medians kept),\n"
           "kdrt_closest_point and rtcPointQuery with the closest-point callback of Embree's\n"
           "tutorial on the same seeded points of each kind, then kdrt_overlap_box and\n"
           "kdrt_overlap_sphere around points near the surface, boxes and balls 1%, 3% and 10%\n"
           "of the mesh's box across. It writes Mesh;Triangles;Query;Kind;Size;Queries;KdrtMs;\n"
           "EmbreeMs;Ratio;Found;ReferenceQueries;KdrtMismatches;EmbreeMismatches;KdrtMaxError;\n"
           "EmbreeMaxError;Repeat;KdrtCpuMs;EmbreeCpuMs;CpuRatio, a row per mesh, query and kind\n"
           "or size; Ratio is EmbreeMs over KdrtMs, CpuRatio the same of the querying thread's CPU\n"
           "time. The first --reference-rays queries of each (default 1000, 100 for overlap)\n"
           "are checked against a double-precision brute force: a distance disagrees when it is\n"
           "off by more than 2^-20 of (the distance + the mesh box's diagonal), a ball's count\n"
           "when it differs. Only --repeat, --queries, --reference-rays, --subdivide, --compare,\n"
           "--build-threads, -o and --quiet apply.\n"
           "\n"
           "--scene merged,field measures kdrt_scene against one tree over the same triangles,\n"
           "with primary and diffuse rays (the frame's, made on the one tree) through both:\n"
           "  merged  the meshes (default: the bunny, the ogre and nefertiti of\n"
           "          the mesh folder's common/), each scaled to a unit box and set side by side, and\n"
           "          the back wall, as mesh geometries of one scene, against one tree of them all\n"
           "  field   --instances N (default 1000) of them, each simplified to about\n"
           "          --instance-triangles N triangles (default 3000; 0: whole), randomly turned,\n"
           "          scaled by 0.8 to 1.2 and placed on a grid of pitch --instance-spacing D\n"
           "          (seeded), and the wall, as instances of a tree per mesh, against one tree of\n"
           "          every instance's triangles in world space\n"
           "Each scene is also traced with a kdrt_query of every mask bit and with a filter that\n"
           "takes every hit, and through Embree (unless --compare none), as one triangle mesh and\n"
           "as the scene (its meshes, or a two-level scene of instances). --repeat N (default 5):\n"
           "timed passes, each tracing every variant in turn; each row holds the median. It\n"
           "writes Scene;Layout;Query;Rays;RayCount;Triangles;StoredTriangles;Instances;BuildMs;\n"
           "TraceMs;MRaysPerSec;Versus;VersusRatio;Mismatches;EmbreeBuildMs;EmbreeMRaysPerSec;\n"
           "EmbreeRatio;EmbreeMismatches (bench/README.md, \"Scenes\").\n"
           "\n"
           "--scene frames times a game's frames, kdrt beside Embree in the same run: a level (a\n"
           "floor, a wall and every mesh but the last, whole) as mesh geometries, --instances N\n"
           "moving instances of the meshes (simplified as the field's), and the last mesh\n"
           "(default nefertiti) deformed by a wave every frame. Each frame: the deformed mesh's\n"
           "tree rebuilt (kdrt FAST against Embree LOW, and MEDIUM against MEDIUM: the Variant)\n"
           "and swapped in, every instance moved and the scene committed, then primary rays\n"
           "(--size) and shadow rays from their hits to a point light, single calls. Each count of\n"
           "--instances at each of --build-threads (default 1,2: the kdrt build's scheduler,\n"
           "Embree's device threads and the tracing threads alike), --frames N frames a variant.\n"
           "It writes Phase;Instances;Threads;Variant;KdrtMs;EmbreeMs;Ratio;KdrtMaxMs;EmbreeMaxMs;\n"
           "Frames;Count;Mismatches;ComparedRays;EmbreeQuality, a row per phase (move, commit,\n"
           "rebuild, primary, shadow, frame), the medians over the frames, and a summary\n"
           "(bench/README.md, \"Frames\").\n"
           "\n"
           "--save-load times saved trees (kdrt.h, SAVED TREES) on each mesh, one thread: the\n"
           "SAH build at FAST and at the default quality, then for each tree the save into\n"
           "memory, the load (the sections copied), the load in place (KDRT_LOAD_IN_PLACE from a\n"
           "64-byte aligned buffer) and the mesh fingerprint alone (a load over the mesh with one\n"
           "index changed, refused). --repeat N (default 7) rounds, each timing every step in\n"
           "turn, the fastest of each kept; each loaded tree must save again to the file's bytes.\n"
           "It writes Mesh;Triangles;Quality;BuildMs;SaveMs;LoadMs;LoadInPlaceMs;FingerprintMs;\n"
           "TreeBytes;SavedBytes;FastBuildOverLoad;FastBuildOverLoadInPlace, a row per mesh and\n"
           "quality, and the same as a table (on standard output beside -o FILE, else on standard\n"
           "error). Only --repeat, --subdivide, -o and --quiet apply (bench/README.md, \"Saved\n"
           "trees\").\n"
           "\n"
           "The mesh folder: " + common::mesh_dir_help() + ".\n";
}

bool parse_options(int argc, const char *const *argv, Options &out, std::string &error) {
    out = Options();
    std::string csv_only_option;  // the last option that only the leaf-size CSV takes
    std::string not_scene_option;  // the last option that --scene has no use for
    std::string field_option;      // the last option that only --scene field takes
    bool hard_rays_given = false, repeat_given = false, size_given = false;
    bool frames_given = false, spacing_given = false, threads_given = false;
    bool batch_given = false, batch_size_given = false, tile_given = false;
    std::string not_save_load_option;  // the last option that --save-load has no use for
    bool queries_given = false, reference_given = false;
    std::string points_refused;  // the last option that --points has no use for
    for (int i = 1; i < argc; ++i) {
        std::string arg = argv[i];
        if (!arg.empty() && arg[0] == '-' && arg != "--save-load" && arg != "--repeat" && arg != "--subdivide" &&
            arg != "-o" && arg != "--output" && arg != "-q" && arg != "--quiet" && arg != "--help" && arg != "-h")
            not_save_load_option = arg;
        auto value = [&](std::string &v) {
            if (i + 1 >= argc) {
                error = arg + " needs a value";
                return false;
            }
            v = argv[++i];
            return true;
        };
        std::string v;
        unsigned long long n = 0;
        const bool ray_order_option = arg == "--batch" || arg == "--batch-size" || arg == "--tile" || arg == "--shuffle";
        if (arg == "--leaf-sizes" || arg == "--rays" || arg == "--compare" || arg == "--sah-costs" ||
            arg == "--quality" || arg == "--query" || arg == "--start" || arg == "--sweep" || arg == "--kernel" ||
            ray_order_option)
            csv_only_option = arg;
        if (arg == "--leaf-sizes" || arg == "--rays" || arg == "--sah-costs" || arg == "--quality" ||
            arg == "--query" || arg == "--start" || arg == "--builder" || arg == "--intersector" || arg == "--subdivide" ||
            arg == "--reference-rays" || arg == "--hard-rays" || arg == "--sweep" || arg == "--kernel" || ray_order_option)
            not_scene_option = arg;
        if (arg == "--instances" || arg == "--instance-triangles" || arg == "--instance-spacing") field_option = arg;
        if (arg == "--instance-spacing") spacing_given = true;
        threads_given = threads_given || arg == "--threads";
        reference_given = reference_given || arg == "--reference-rays";
        if (arg == "--leaf-sizes" || arg == "--rays" || arg == "--sah-costs" || arg == "--quality" || arg == "--query" ||
            arg == "--start" || arg == "--builder" || arg == "--intersector" || arg == "--hard-rays" || arg == "--sweep" ||
            arg == "--kernel" || arg == "--threads" || arg == "--size" || arg == "--accuracy" || arg == "--scene" ||
            arg == "--instances" || arg == "--instance-triangles" || arg == "--instance-spacing" || arg == "--frames" ||
            ray_order_option)
            points_refused = arg;
        repeat_given = repeat_given || arg == "--repeat";
        size_given = size_given || arg == "--size";
        if (arg == "--help" || arg == "-h") {
            out.help = true;
        } else if (arg == "--accuracy") {
            out.accuracy = true;
        } else if (arg == "--save-load") {
            out.save_load = true;
        } else if (arg == "--points") {
            out.points = true;
        } else if (arg == "--queries") {
            if (!value(v)) return false;
            if (!common::parse_count(v, 1ull << 30, n) || n == 0) {
                error = "--queries wants a whole number from 1, got '" + v + "'";
                return false;
            }
            out.point_queries = size_t(n);
            queries_given = true;
        } else if (arg == "--sweep") {
            out.sweep = true;
        } else if (arg == "--quiet" || arg == "-q") {
            out.quiet = true;
        } else if (arg == "--intersector") {
            if (!value(v)) return false;
            if (!parse_choices<kdrt_intersector>(
                    v, {{"watertight", KDRT_INTERSECTOR_WATERTIGHT}, {"fast", KDRT_INTERSECTOR_FAST}}, out.intersectors)) {
                error = "--intersector wants watertight, fast or both separated by a comma, got '" + v + "'";
                return false;
            }
        } else if (arg == "--hard-rays") {
            if (!value(v)) return false;
            if (!common::parse_count(v, 1ull << 32, n) || n == 0) {
                error = "--hard-rays wants a whole number from 1, got '" + v + "'";
                return false;
            }
            out.hard_rays = size_t(n);
            hard_rays_given = true;
        } else if (arg == "--size") {
            if (!value(v)) return false;
            unsigned long long w = 0, h = 0;
            if (!common::parse_size(v, 32768, w, h)) {
                error = "--size wants WxH with 1 <= W, H <= 32768, got '" + v + "'";
                return false;
            }
            out.width = unsigned(w), out.height = unsigned(h);
        } else if (arg == "--build-threads") {
            if (!value(v)) return false;
            out.build_thread_counts.clear();
            for (const std::string &item : list_items(v)) {
                if (!common::parse_count(item, 1024, n)) {
                    error = "--build-threads wants a whole number from 0 (all cores) to 1024 (with --scene frames a "
                            "comma-separated list of them), got '" + v + "'";
                    return false;
                }
                out.build_thread_counts.push_back(unsigned(n));
            }
            out.build_threads = out.build_thread_counts[0];
        } else if (arg == "--threads" || arg == "--repeat" || arg == "--subdivide") {
            if (!value(v)) return false;
            unsigned long long max = arg == "--subdivide" ? 8 : 1024;
            if (!common::parse_count(v, max, n) || (arg != "--subdivide" && n == 0)) {
                error = arg + " wants a whole number " + (arg == "--subdivide" ? "from 0" : "from 1") + " to " +
                        std::to_string(max) + ", got '" + v + "'";
                return false;
            }
            (arg == "--threads" ? out.threads : arg == "--repeat" ? out.repeat : out.subdivide) = unsigned(n);
        } else if (arg == "--reference-rays") {
            if (!value(v)) return false;
            if (!common::parse_count(v, 1ull << 40, n)) {
                error = "--reference-rays wants a whole number, got '" + v + "'";
                return false;
            }
            out.reference_rays = size_t(n);
        } else if (arg == "--leaf-sizes") {
            if (!value(v)) return false;
            out.leaf_sizes.clear();
            for (const std::string &item : list_items(v)) {
                if (!common::parse_count(item, KDRT_MAX_TRIANGLES, n)) {
                    error = "--leaf-sizes wants whole numbers separated by commas, got '" + v + "'";
                    return false;
                }
                out.leaf_sizes.push_back(uint32_t(n));
            }
        } else if (arg == "--builder") {
            if (!value(v)) return false;
            if (!parse_choices<std::string>(v, {{"median", "median"}, {"sah", "sah"}}, out.builders)) {
                error = "--builder wants median, sah or both separated by a comma, got '" + v + "'";
                return false;
            }
        } else if (arg == "--sah-costs") {
            if (!value(v) || !parse_sah_costs(v, out.sah_costs, error)) return false;
        } else if (arg == "--query") {
            if (!value(v)) return false;
            if (!parse_choices<std::string>(v, {{"plain", "plain"}, {"filter", "filter"}}, out.queries)) {
                error = "--query wants plain, filter or both separated by a comma, got '" + v + "'";
                return false;
            }
        } else if (arg == "--start") {
            if (!value(v)) return false;
            if (!parse_choices<std::string>(v, {{"cell", "cell"}, {"root", "root"}}, out.starts)) {
                error = "--start wants cell, root or both separated by a comma, got '" + v + "'";
                return false;
            }
        } else if (arg == "--batch") {
            if (!value(v)) return false;
            if (!parse_choices<Call>(v,
                                     {{"single", Call::single},
                                      {"batch", Call::batch},
                                      {"packet8", Call::packet8},
                                      {"packet16", Call::packet16}},
                                     out.calls)) {
                error = "--batch wants single, batch, packet8 or packet16, separated by commas, got '" + v + "'";
                return false;
            }
            batch_given = true;
        } else if (arg == "--batch-size") {
            if (!value(v)) return false;
            if (!common::parse_count(v, 1u << 30, out.batch_size) || out.batch_size == 0) {
                error = "--batch-size wants a whole number of rays from 1, got '" + v + "'";
                return false;
            }
            batch_size_given = true;
        } else if (arg == "--tile") {
            if (!value(v)) return false;
            if (!common::parse_size(v, 256, out.tile_width, out.tile_height)) {
                error = "--tile wants WxH with 1 <= W, H <= 256 (pixels), got '" + v + "'";
                return false;
            }
            tile_given = true;
        } else if (arg == "--shuffle") {
            out.shuffle = true;
        } else if (arg == "--kernel") {
            if (!value(v)) return false;
            if (!parse_choices<std::string>(
                    v, {{"default", "default"}, {"avx512", "avx512"}, {"avx2", "avx2"}, {"scalar", "scalar"}},
                    out.kernels)) {
                error = "--kernel wants default, avx512, avx2 or scalar, separated by commas, got '" + v + "'";
                return false;
            }
        } else if (arg == "--scene") {
            if (!value(v)) return false;
            if (!parse_choices<std::string>(v, {{"merged", "merged"}, {"field", "field"}, {"frames", "frames"}},
                                            out.scenes)) {
                error = "--scene wants merged, field or both separated by a comma, or frames, got '" + v + "'";
                return false;
            }
        } else if (arg == "--instances") {
            if (!value(v)) return false;
            out.instance_counts.clear();
            for (const std::string &item : list_items(v)) {
                uint32_t count = 0;
                if (!common::parse_count(item, 1000000, count) || count == 0) {
                    error = "--instances wants a whole number from 1 to 1000000 (with --scene frames a comma-separated "
                            "list of them), got '" + v + "'";
                    return false;
                }
                out.instance_counts.push_back(count);
            }
            out.instances = out.instance_counts[0];
        } else if (arg == "--frames") {
            if (!value(v)) return false;
            if (!common::parse_count(v, 100000, out.frames) || out.frames == 0) {
                error = "--frames wants a whole number from 1 to 100000, got '" + v + "'";
                return false;
            }
            frames_given = true;
        } else if (arg == "--instance-triangles") {
            if (!value(v)) return false;
            if (!common::parse_count(v, KDRT_MAX_TRIANGLES, out.instance_triangles)) {
                error = "--instance-triangles wants a whole number (0: the meshes whole), got '" + v + "'";
                return false;
            }
        } else if (arg == "--instance-spacing") {
            if (!value(v)) return false;
            char *end = nullptr;
            errno = 0;
            const double d = std::strtod(v.c_str(), &end);
            if (v.empty() || std::isspace(static_cast<unsigned char>(v[0])) || errno != 0 || *end != '\0' ||
                !(d >= 0.1 && d <= 100)) {
                error = "--instance-spacing wants a number from 0.1 to 100, got '" + v + "'";
                return false;
            }
            out.instance_spacing = d;
        } else if (arg == "--quality") {
            if (!value(v)) return false;
            if (!parse_choices<kdrt_build_quality>(v,
                                                   {{"fast", KDRT_BUILD_QUALITY_FAST},
                                                    {"medium", KDRT_BUILD_QUALITY_MEDIUM},
                                                    {"high", KDRT_BUILD_QUALITY_HIGH}},
                                                   out.qualities)) {
                error = "--quality wants fast, medium or high, separated by commas, got '" + v + "'";
                return false;
            }
        } else if (arg == "--rays") {
            if (!value(v)) return false;
            const std::string kind = lower(v);
            if (kind == "primary") out.rays = RayKind::primary;
            else if (kind == "diffuse") out.rays = RayKind::diffuse;
            else if (kind == "random") out.rays = RayKind::random;
            else if (kind == "shadow") out.rays = RayKind::shadow;
            else {
                error = "--rays wants primary, diffuse, random or shadow, got '" + v + "'";
                return false;
            }
        } else if (arg == "--compare") {
            if (!value(v)) return false;
            if (lower(v) != "embree" && lower(v) != "none") {
                error = "--compare wants embree or none, got '" + v + "'";
                return false;
            }
            out.compare_embree = lower(v) == "embree";
            out.compare_chosen = true;
        } else if (arg == "-o" || arg == "--output") {
            if (!value(out.output)) return false;
            if (out.output.empty()) {
                error = "-o wants a file name";
                return false;
            }
        } else if (!arg.empty() && arg[0] == '-') {
            error = "unknown option '" + arg + "' (see --help)";
            return false;
        } else {
            out.inputs.push_back(arg);
        }
    }
    if (out.save_load) {
        if (!not_save_load_option.empty()) {
            error = not_save_load_option + " does not apply to --save-load (it takes --repeat, --subdivide, -o and "
                                           "--quiet: each tree is kdrt's default but for the quality, one thread)";
            return false;
        }
        if (!repeat_given) out.repeat = 7;
        return true;
    }
    if (out.points) {
        if (!points_refused.empty()) {
            error = points_refused + " does not apply to --points (kdrt's default tree, one thread; see --help)";
            return false;
        }
        if (!repeat_given) out.repeat = 5;
        if (!reference_given) out.reference_rays = 1000;
        return true;
    }
    if (queries_given) {
        error = "--queries applies only to --points";
        return false;
    }
    // What the leaf-size CSV builds when not told: kdrt's default tree, or with --sweep the
    // original's run.
    if (out.builders.empty()) out.builders = {out.sweep ? "median" : "sah"};
    if (out.leaf_sizes.empty()) out.leaf_sizes = out.sweep ? sweep_leaf_sizes() : std::vector<uint32_t>{kDefaultLeafSize};
    if (out.sweep && !out.compare_chosen) out.compare_chosen = true;  // and no Embree
    const bool frames = std::find(out.scenes.begin(), out.scenes.end(), "frames") != out.scenes.end();
    if (frames_given && !frames) {
        error = "--frames applies only to --scene frames";
        return false;
    }
    if (!frames && out.instance_counts.size() > 1) {
        error = "--instances takes one count (a list only with --scene frames)";
        return false;
    }
    if (!frames && out.build_thread_counts.size() > 1) {
        error = "--build-threads takes one count (a list only with --scene frames)";
        return false;
    }
    if (frames) {
        if (out.scenes.size() > 1) {
            error = "--scene frames runs alone: give it without merged or field";
            return false;
        }
        if (out.accuracy) {
            error = "--scene and --accuracy are two modes: give one of them";
            return false;
        }
        std::string refused = not_scene_option;
        if (refused.empty() && repeat_given) refused = "--repeat";
        if (refused.empty() && threads_given) refused = "--threads";
        if (!refused.empty()) {
            error = refused + " does not apply to --scene frames (--frames N sets the frames timed, and --build-threads "
                              "the threads of every phase)";
            return false;
        }
        if (spacing_given) {
            error = "--instance-spacing applies only to --scene field";
            return false;
        }
        if (out.instance_counts.empty()) out.instance_counts = {1000, 10000};
        if (out.build_thread_counts.empty()) out.build_thread_counts = {1, 2};
        out.instances = out.instance_counts[0];
        out.build_threads = out.build_thread_counts[0];
        return true;
    }
    if (!out.scenes.empty()) {
        if (out.accuracy) {
            error = "--scene and --accuracy are two modes: give one of them";
            return false;
        }
        if (!not_scene_option.empty()) {
            error = not_scene_option + " does not apply to --scene (each scene is traced with primary and diffuse rays "
                                       "through trees of kdrt's default options)";
            return false;
        }
        if (!field_option.empty() && std::find(out.scenes.begin(), out.scenes.end(), "field") == out.scenes.end()) {
            error = field_option + " applies only to --scene field";
            return false;
        }
        if (!repeat_given) out.repeat = 5;
        return true;
    }
    if (!field_option.empty()) {
        error = field_option + " applies only to --scene field";
        return false;
    }
    if (out.accuracy && !csv_only_option.empty()) {
        error = csv_only_option + " does not apply to --accuracy (every set is traced once, median builder, default leaf size)";
        return false;
    }
    if (!out.sah_costs.empty() && std::find(out.builders.begin(), out.builders.end(), "sah") == out.builders.end()) {
        error = "--sah-costs applies only to the SAH builder: add --builder sah (or median,sah)";
        return false;
    }
    if (!out.qualities.empty() && std::find(out.builders.begin(), out.builders.end(), "sah") == out.builders.end()) {
        error = "--quality applies only to the SAH builder: add --builder sah (or median,sah)";
        return false;
    }
    if (batch_size_given && std::find(out.calls.begin(), out.calls.end(), Call::batch) == out.calls.end()) {
        error = "--batch-size applies only to the batch calls: add --batch batch (or single,batch)";
        return false;
    }
    if (batch_given && !tile_given) out.tile_width = 4, out.tile_height = 2;  // 8 rays, a packet's worth
    if (out.accuracy && !repeat_given) out.repeat = 3;
    if (out.accuracy && !size_given) out.width = out.height = 400;  // 30 frames: a few minutes in all
    if (!out.accuracy && hard_rays_given) {
        error = "--hard-rays applies only to --accuracy";
        return false;
    }
    return true;
}

Scene make_scene(const common::Mesh &mesh, const std::string &name) {
    Scene s;
    s.name = name;
    s.mesh_triangles = mesh.triangle_count();
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (size_t i = 0; i < mesh.positions.size(); ++i) lo[i % 3] = std::min(lo[i % 3], double(mesh.positions[i])), hi[i % 3] = std::max(hi[i % 3], double(mesh.positions[i]));
    if (mesh.positions.empty()) lo[0] = lo[1] = lo[2] = hi[0] = hi[1] = hi[2] = 0;
    double centre[3], across = std::max({hi[0] - lo[0], hi[1] - lo[1], 1e-30});
    for (int a = 0; a < 3; ++a) centre[a] = 0.5 * (lo[a] + hi[a]);
    double scale = 2.0 / across, half_depth = 0.5 * (hi[2] - lo[2]) * scale;

    s.geometry = mesh;
    s.geometry.name = name;
    if (s.geometry.indices.empty())
        for (uint32_t i = 0; i < mesh.vertex_count(); ++i) s.geometry.indices.push_back(i);
    for (size_t i = 0; i < s.geometry.positions.size(); ++i)
        s.geometry.positions[i] = float((s.geometry.positions[i] - centre[i % 3]) * scale);
    for (int a = 0; a < 3; ++a) s.centre[a] = centre[a];
    s.scale = scale;

    // Camera 3 units in front of the mesh's front face, its view holding [-1.05, 1.05] at z = 0.
    double eye_z = half_depth + 3.0, tan_half = 1.05 / eye_z;
    s.eye[2] = float(eye_z);
    s.tan_half_fov = float(tan_half);
    // The wall: behind the mesh, a little larger than the view at its depth.
    double wall_z = -half_depth - 0.25, wall_half = 1.2 * tan_half * (eye_z - wall_z);
    uint32_t base = s.geometry.vertex_count();
    const double corner[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (const auto &c : corner)
        s.geometry.positions.insert(s.geometry.positions.end(), {float(c[0] * wall_half), float(c[1] * wall_half), float(wall_z)});
    s.geometry.indices.insert(s.geometry.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    return s;
}

std::vector<kdrt_ray> make_rays(const Scene &scene, RayKind kind, unsigned width, unsigned height,
                                const kdrt_tree *tree, uint32_t seed, std::vector<uint32_t> *pixels) {
    std::vector<kdrt_ray> rays;
    std::vector<uint32_t> ignored;
    std::vector<uint32_t> &pixel_of = pixels ? *pixels : ignored;
    pixel_of.clear();
    if (kind == RayKind::random) {
        // Uniform rays through the scene's box: from a point on its bounding sphere to a point inside.
        kdrt_aabb box = kdrt_tree_bounds(tree);
        double c[3], e[3], radius = 0;
        for (int a = 0; a < 3; ++a) c[a] = 0.5 * (box.min[a] + box.max[a]), e[a] = box.max[a] - box.min[a], radius += 0.25 * e[a] * e[a];
        radius = std::sqrt(radius);
        common::Rng rng = seeded(seed);
        rays.resize(size_t(width) * height);
        for (kdrt_ray &r : rays) {
            double z = 2 * rng.uniform() - 1, phi = 2 * M_PI * rng.uniform(), s = std::sqrt(std::max(0.0, 1 - z * z));
            double u[3] = {s * std::cos(phi), s * std::sin(phi), z};
            for (int a = 0; a < 3; ++a) {
                r.org[a] = float(c[a] + u[a] * radius);
                r.dir[a] = float(c[a] + (rng.uniform() - 0.5) * e[a] - r.org[a]);
            }
            r.tmin = 0, r.tmax = INFINITY;
        }
        pixel_of.resize(rays.size());
        std::iota(pixel_of.begin(), pixel_of.end(), 0u);
        return rays;
    }

    rays.reserve(size_t(width) * height);
    double aspect = double(width) / height;
    for (unsigned y = 0; y < height; ++y)
        for (unsigned x = 0; x < width; ++x) {
            kdrt_ray r{};
            for (int a = 0; a < 3; ++a) r.org[a] = scene.eye[a];
            r.dir[0] = float((2.0 * (x + 0.5) / width - 1.0) * scene.tan_half_fov * aspect);
            r.dir[1] = float((1.0 - 2.0 * (y + 0.5) / height) * scene.tan_half_fov);
            r.dir[2] = -1.0f;
            r.tmin = 0, r.tmax = INFINITY;
            rays.push_back(r);
        }
    if (kind == RayKind::primary) {
        pixel_of.resize(rays.size());
        std::iota(pixel_of.begin(), pixel_of.end(), 0u);
        return rays;
    }

    if (kind == RayKind::shadow) {
        // From every primary hit towards the light, leaving the surface through kdrt_spawn_ray(),
        // then aimed from the origin it chose so that the light is at t = 1.
        std::vector<kdrt_ray> shadow;
        for (const kdrt_ray &r : rays) {
            const uint32_t pixel = uint32_t(&r - rays.data());
            kdrt_hit h;
            float point[3], dir[3];
            kdrt_ray s;
            if (!kdrt_intersect(tree, &r, &h) || !kdrt_hit_surface(tree, &h, point, nullptr)) continue;
            for (int a = 0; a < 3; ++a) dir[a] = kShadowLight[a] - point[a];
            if (!kdrt_spawn_ray(tree, &h, dir, &s)) continue;
            for (int a = 0; a < 3; ++a) s.dir[a] = kShadowLight[a] - s.org[a];
            s.tmin = 0, s.tmax = 1;
            shadow.push_back(s);
            pixel_of.push_back(pixel);
        }
        return shadow;
    }

    // Diffuse: a cosine-distributed bounce from every primary hit, on the side the ray came from,
    // leaving the surface through kdrt_spawn_ray() (no epsilon: the offset scales with the point).
    std::vector<kdrt_ray> bounces;
    common::Rng rng = seeded(seed);
    for (const kdrt_ray &r : rays) {
        const uint32_t pixel = uint32_t(&r - rays.data());
        kdrt_hit h;
        float normal[3];
        if (!kdrt_intersect(tree, &r, &h) || !kdrt_hit_surface(tree, &h, nullptr, normal)) continue;
        double n[3] = {normal[0], normal[1], normal[2]};
        double facing = n[0] * r.dir[0] + n[1] * r.dir[1] + n[2] * r.dir[2] > 0 ? -1 : 1;
        for (double &c : n) c *= facing;
        // Orthonormal frame around n (Duff et al. 2017), then a cosine-weighted direction.
        double sign = std::copysign(1.0, n[2]), a0 = -1.0 / (sign + n[2]), b0 = n[0] * n[1] * a0;
        double t1[3] = {1 + sign * n[0] * n[0] * a0, sign * b0, -sign * n[0]}, t2[3] = {b0, sign + n[1] * n[1] * a0, -n[1]};
        double r1 = rng.uniform(), r2 = rng.uniform(), radial = std::sqrt(r1), phi = 2 * M_PI * r2, up = std::sqrt(1 - r1);
        float dir[3];
        for (int a = 0; a < 3; ++a) dir[a] = float(radial * std::cos(phi) * t1[a] + radial * std::sin(phi) * t2[a] + up * n[a]);
        kdrt_ray b;
        if (kdrt_spawn_ray(tree, &h, dir, &b)) bounces.push_back(b), pixel_of.push_back(pixel);
    }
    return bounces;
}

std::vector<size_t> ray_order(const std::vector<uint32_t> &pixels, unsigned width, unsigned tile_width,
                              unsigned tile_height, bool shuffle, uint32_t seed) {
    std::vector<size_t> order(pixels.size());
    std::iota(order.begin(), order.end(), size_t(0));
    if (shuffle) {
        common::Rng rng(seed);  // a stream of its own: the ray sets and samples draw from seeded()
        for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[size_t(rng.uniform() * double(i))]);
        return order;
    }
    // A pixel's place: its tile's (tiles row by row), then its own within the tile (row by row).
    const uint64_t tiles_across = (uint64_t(width) + tile_width - 1) / tile_width;
    const auto place = [&](uint32_t pixel) {
        const uint64_t x = pixel % width, y = pixel / width;
        const uint64_t tile = (y / tile_height) * tiles_across + x / tile_width;
        return (tile * tile_height + y % tile_height) * tile_width + x % tile_width;
    };
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return place(pixels[a]) < place(pixels[b]); });
    return order;
}

std::string frame_rays(const Options &opt, RayKind kind) {
    const char *names[] = {"primary", "diffuse", "random", "shadow"};
    std::string text = std::to_string(opt.width) + "x" + std::to_string(opt.height) + " " + names[int(kind)] + " rays";
    if (opt.shuffle) return text + ", shuffled";
    if (opt.tile_width * opt.tile_height > 1)
        text += " in " + std::to_string(opt.tile_width) + "x" + std::to_string(opt.tile_height) + " tiles";
    return text;
}

namespace {

uint32_t bits_of(float f) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    return u;
}

bool same_hit(const kdrt_hit &a, const kdrt_hit &b) {
    return bits_of(a.t) == bits_of(b.t) && bits_of(a.u) == bits_of(b.u) && bits_of(a.v) == bits_of(b.v) &&
           a.triangle == b.triangle && a.geometry == b.geometry && a.instance == b.instance && a.cell == b.cell;
}

}  // namespace

size_t count_differing_hits(const std::vector<kdrt_hit> &a, const std::vector<kdrt_hit> &b, size_t &first) {
    size_t differing = 0;
    first = SIZE_MAX;
    for (size_t i = 0; i < std::max(a.size(), b.size()); ++i)
        if (i >= a.size() || i >= b.size() || !same_hit(a[i], b[i])) {
            if (!differing++) first = i;
        }
    return differing;
}

size_t count_differing_occlusion(const std::vector<unsigned char> &a, const std::vector<unsigned char> &b, size_t &first) {
    size_t differing = 0;
    first = SIZE_MAX;
    for (size_t i = 0; i < std::max(a.size(), b.size()); ++i)
        if (i >= a.size() || i >= b.size() || a[i] != b[i]) {
            if (!differing++) first = i;
        }
    return differing;
}

std::string describe_hit(const kdrt_hit &hit) {
    char buf[192];
    std::snprintf(buf, sizeof buf, "triangle %u t %a u %a v %a geometry %u instance %u cell %u", hit.triangle,
                  double(hit.t), double(hit.u), double(hit.v), hit.geometry, hit.instance, hit.cell);
    return buf;
}

int take_every_hit(void *, const kdrt_ray *, const kdrt_hit *) { return 1; }

std::vector<size_t> reference_sample(size_t total, size_t count, uint32_t seed) {
    std::vector<size_t> all(total);
    std::iota(all.begin(), all.end(), size_t(0));
    if (count == 0 || count >= total) return all;
    common::Rng rng = seeded(seed);
    for (size_t i = 0; i < count; ++i) std::swap(all[i], all[i + size_t(rng.uniform() * double(total - i))]);  // partial Fisher-Yates
    all.resize(count);
    std::sort(all.begin(), all.end());
    return all;
}

size_t count_mismatches(const oracle::Oracle &oracle, const std::vector<oracle::Reference> &refs,
                        const std::vector<size_t> &sample, const std::vector<kdrt_ray> &rays,
                        const std::vector<kdrt_hit> &hits) {
    oracle::Agreement tally;
    for (size_t k = 0; k < sample.size(); ++k) oracle::check_hit(oracle, refs[k], rays[sample[k]], hits[sample[k]], tally);
    return tally.wrong;
}

size_t count_occlusion_mismatches(const oracle::Oracle &oracle, const std::vector<oracle::Reference> &refs,
                                  const std::vector<size_t> &sample, const std::vector<kdrt_ray> &rays,
                                  const std::vector<unsigned char> &occluded, uint32_t triangles) {
    size_t wrong = 0;
    for (size_t k = 0; k < sample.size(); ++k) {
        const kdrt_ray &ray = rays[sample[k]];
        if (refs[k].sure_hit) {
            wrong += !occluded[sample[k]];
        } else if (occluded[sample[k]]) {
            bool possible = false;
            // possible_t widens the range by its tolerance; a shadow ray leaves a surface, which
            // it meets again at a hair below t = 0, and that is not a hit.
            for (uint32_t t = 0; t < triangles && !possible; ++t) {
                const double at = oracle.possible_t(ray, t);
                possible = at >= double(ray.tmin) && at <= double(ray.tmax);
            }
            wrong += !possible;
        }
    }
    return wrong;
}

std::vector<std::string> starts_for(const Options &opt) {
    if (!opt.starts.empty()) return opt.starts;
    if (opt.rays == RayKind::diffuse || opt.rays == RayKind::shadow) return {"cell", "root"};
    return {"root"};
}

std::string csv_header() {
    return "Mesh;MaxLeafSize;ElapsedMs;Builder;Triangles;BuildMs;TraceMs;MRaysPerSec;Nodes;Leaves;MaxDepth;"
           "AvgLeafTriangles;TreeBytes;Mismatches;ReferenceRays;Intersector;SahCost;SahCosts;BuildThreads;Quality;"
           "Query;Start;Call;Kernel";
}

std::string csv_row(const Row &row) {
    char buf[512];
    double mrays = row.trace_ms > 0 ? double(row.rays) / (row.trace_ms * 1000.0) : 0.0;
    int n = std::snprintf(buf, sizeof buf, "%s;%d;%lld;%s;%u;%.3f;%.3f;%.3f;", row.mesh.c_str(), row.max_leaf_size,
                          (long long)std::llround(row.trace_ms), row.builder.c_str(), row.triangles, row.build_ms,
                          row.trace_ms, mrays);
    std::string line(buf, size_t(n));
    if (row.has_tree_stats) {
        const kdrt_tree_stats &s = row.stats;
        double avg = s.leaves ? double(s.triangle_refs) / s.leaves : 0.0;
        n = std::snprintf(buf, sizeof buf, "%u;%u;%u;%.2f;%zu;", s.nodes, s.leaves, s.max_depth, avg, s.bytes);
        line.append(buf, size_t(n));
    } else {
        line += ";;;;;";  // Embree's BVH: no kd-tree statistics
    }
    n = std::snprintf(buf, sizeof buf, "%zu;%zu;", row.mismatches, row.reference_rays);
    line.append(buf, size_t(n));
    line += row.intersector + ";";
    if (row.has_tree_stats) {
        n = std::snprintf(buf, sizeof buf, "%.3f", row.stats.sah_cost);
        line.append(buf, size_t(n));
    }
    return line + ";" + row.sah_costs + ";" + std::to_string(row.build_threads) + ";" + row.quality + ";" +
           row.query + ";" + row.start + ";" + row.call + ";" + row.kernel;
}

// ---- kdrt-bench --accuracy ----

namespace {

kdrt_tree *build_tree(const common::Mesh &mesh, kdrt_intersector intersector, std::string &error) {
    const kdrt_triangles view = mesh.view();
    kdrt_build_options options = kdrt_default_build_options();
    options.builder = KDRT_BUILDER_MEDIAN;  // bench/README.md's accuracy table: a median tree
    options.intersector = intersector;
    kdrt_tree *tree = nullptr;
    kdrt_build_report report;
    kdrt_result r = kdrt_tree_build(&view, &options, &tree, &report);
    if (r != KDRT_SUCCESS) {
        error = std::string(kdrt_result_string(r)) +
                (report.invalid_triangle != KDRT_INVALID_ID ? " (triangle " + std::to_string(report.invalid_triangle) + ")" : "");
        return nullptr;
    }
    return tree;
}

std::string offset_label(double offset) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.0e", offset);  // 1e+05
    std::string s = buf;
    size_t plus = s.find("e+");
    if (plus != std::string::npos) {
        size_t digits = plus + 2;
        while (digits + 1 < s.size() && s[digits] == '0') ++digits;
        s = s.substr(0, plus + 1) + s.substr(digits);  // 1e5
    }
    return s;
}

}  // namespace

std::vector<AccuracySet> frame_sets(const Scene &scene, unsigned width, unsigned height, uint32_t seed) {
    std::string error;
    kdrt_tree *scout = build_tree(scene.geometry, KDRT_INTERSECTOR_DEFAULT, error);
    std::vector<AccuracySet> sets(2);
    sets[0].set = "frame-primary", sets[1].set = "frame-diffuse";
    for (AccuracySet &s : sets) s.scene = scene.name, s.mesh = scene.geometry;
    if (!scout) return sets;  // no rays; run_accuracy_set reports the build's error
    sets[0].rays = make_rays(scene, RayKind::primary, width, height, scout, seed);
    sets[1].rays = make_rays(scene, RayKind::diffuse, width, height, scout, seed);
    kdrt_tree_free(scout);
    return sets;
}

AccuracySet far_set(const Scene &scene, double offset, unsigned width, unsigned height, uint32_t seed) {
    AccuracySet s;
    s.set = "far";
    s.scene = scene.name + "@" + offset_label(offset);
    const double scale = std::max(1.0, offset / 1000.0);
    s.mesh = oracle::translated(scene.geometry, offset, scale);
    s.mesh.name = s.scene;
    s.rays = make_rays(scene, RayKind::primary, width, height, nullptr, seed);
    // The camera moves with the scene: p -> scale p + shift, the shift read off the last vertex
    // (a wall corner; make_scene always adds the wall) to within its float rounding.
    const size_t last = s.mesh.positions.size() - 3;
    float eye[3];
    for (int a = 0; a < 3; ++a)
        eye[a] = float(scale * scene.eye[a] + (double(s.mesh.positions[last + a]) - scale * double(scene.geometry.positions[last + a])));
    for (kdrt_ray &r : s.rays)
        for (int a = 0; a < 3; ++a) r.org[a] = eye[a];
    return s;
}

std::vector<AccuracySet> watertight_sets(size_t rays, uint64_t seed) {
    std::vector<AccuracySet> sets;
    for (common::Mesh &mesh : oracle::closed_meshes(true)) {
        AccuracySet s;
        s.set = "watertight";
        s.scene = mesh.name;
        s.rays = oracle::rays_at_vertices_and_edges(mesh, rays, seed);
        s.mesh = std::move(mesh);
        s.must_hit = true;
        sets.push_back(std::move(s));
    }
    return sets;
}

std::vector<AccuracySet> hard_case_sets(size_t rays, uint64_t seed) {
    std::vector<AccuracySet> sets;
    for (oracle::HardSet &h : oracle::hard_sets(rays, seed)) {
        AccuracySet s;
        s.set = "hard";
        s.scene = h.name;
        s.mesh = std::move(h.mesh);
        s.rays = std::move(h.rays);
        sets.push_back(std::move(s));
    }
    return sets;
}

bool run_accuracy_set(const AccuracySet &set, const std::vector<kdrt_intersector> &intersectors, size_t reference_rays,
                      unsigned threads, unsigned timed_passes, uint32_t seed, bool oracle_row, std::vector<AccuracyRow> &rows,
                      std::string &error) {
    const oracle::Oracle oracle(set.mesh);
    const std::vector<size_t> sample = reference_sample(set.rays.size(), reference_rays, seed);
    std::vector<kdrt_ray> sampled;
    for (size_t i : sample) sampled.push_back(set.rays[i]);
    AccuracyRow base;
    base.set = set.set;
    base.scene = set.scene;
    base.triangles = set.mesh.triangle_count();

    std::vector<oracle::Reference> refs;
    if (oracle_row) {
        // The reference is computed anyway; on one thread, its time is the oracle's row.
        AccuracyRow row = base;
        row.intersector = "oracle";
        row.measured = false;
        row.rays = sampled.size();
        refs.resize(sampled.size());
        row.trace_ms = timed_parallel(sampled.size(), 1, [&](size_t i) { refs[i] = oracle.trace(sampled[i]); });
        rows.push_back(row);
    } else {
        refs = oracle::reference_all(oracle, sampled);
    }

    // One tree per intersector, timed in turns (fast, watertight, fast, ...) so that a busy
    // moment of the machine does not land on one intersector only; the fastest pass counts.
    std::vector<kdrt_tree *> trees;
    for (kdrt_intersector intersector : intersectors) {
        trees.push_back(build_tree(set.mesh, intersector, error));
        if (!trees.back()) {
            error = set.set + " " + set.scene + ": " + error;
            for (kdrt_tree *t : trees) kdrt_tree_free(t);
            return false;
        }
    }
    std::vector<double> fastest(trees.size(), INFINITY);
    std::vector<kdrt_hit> hits(set.rays.size());  // the timed passes' answers (the counters trace again)
    for (unsigned pass = 0; pass < std::max(1u, timed_passes); ++pass)
        for (size_t m = 0; m < trees.size(); ++m) {
            const kdrt_tree *tree = trees[m];
            double ms = timed_parallel(set.rays.size(), threads, [&](size_t i) { kdrt_intersect(tree, &set.rays[i], &hits[i]); });
            fastest[m] = std::min(fastest[m], ms);
        }
    for (size_t m = 0; m < trees.size(); ++m) {
        AccuracyRow row = base;
        row.intersector = intersector_name(intersectors[m]);
        row.rays = set.rays.size();
        row.trace_ms = set.rays.empty() ? 0.0 : fastest[m];
        row.counts_leaks = set.must_hit;
        std::string first;  // the first error found, for the run's log
        if (set.must_hit) {
            const oracle::ErrorCounts leaked = oracle::count_leaks(trees[m], set.rays);
            row.errors.leaks = leaked.leaks;
            first = leaked.first;
        }
        const oracle::ErrorCounts checked = oracle::count_mismatches(trees[m], oracle, refs, sampled);
        row.errors.false_hits = checked.false_hits;
        row.errors.mismatches = checked.mismatches;
        row.reference_rays = sample.size();
        if (first.empty()) first = checked.first;
        // Secondary rays from the sample's hits: 4 per hit, traced twice (spawned and naive).
        const oracle::ErrorCounts spawned = oracle::count_self_hits(trees[m], sampled);
        row.errors.self_hits = spawned.self_hits;
        row.spawned_rays = spawned.rays;
        if (first.empty()) first = spawned.first;
        row.naive_self_hits = oracle::count_self_hits(trees[m], sampled, oracle::Spawn::naive).self_hits;
        row.errors.rays = row.rays;
        row.errors.first = first;
        rows.push_back(row);
    }
    for (kdrt_tree *t : trees) kdrt_tree_free(t);
    return true;
}

std::string accuracy_csv_header() {
    return "Set;Scene;Intersector;Triangles;Rays;TraceMs;MRaysPerSec;Leaks;FalseHits;SelfHits;Mismatches;SpawnedRays;"
           "ReferenceRays;NaiveSelfHits";
}

std::string accuracy_csv_row(const AccuracyRow &row) {
    char buf[256];
    double mrays = row.trace_ms > 0 ? double(row.rays) / (row.trace_ms * 1000.0) : 0.0;
    int n = std::snprintf(buf, sizeof buf, ";%s;%u;%zu;%.3f;%.3f;", row.intersector.c_str(), row.triangles, row.rays,
                          row.trace_ms, mrays);
    std::string line = row.set + ";" + row.scene + std::string(buf, size_t(n));
    if (!row.measured) return line + ";;;;;;";  // the oracle is the reference: nothing to count
    const oracle::ErrorCounts &e = row.errors;
    line += row.counts_leaks ? std::to_string(e.leaks) : "";  // only must-hit sets can leak
    n = std::snprintf(buf, sizeof buf, ";%zu;%zu;%zu;%zu;%zu;%zu", e.false_hits, e.self_hits, e.mismatches,
                      row.spawned_rays, row.reference_rays, row.naive_self_hits);
    return line + std::string(buf, size_t(n));
}

std::vector<AccuracyRow> accuracy_summary(const std::vector<AccuracyRow> &rows) {
    std::vector<AccuracyRow> sums;
    std::vector<size_t> scenes;
    for (const AccuracyRow &row : rows) {
        auto it = std::find_if(sums.begin(), sums.end(), [&](const AccuracyRow &s) { return s.set == row.set && s.intersector == row.intersector; });
        if (it == sums.end()) {
            AccuracyRow s;
            s.set = row.set;
            s.intersector = row.intersector;
            s.measured = row.measured;
            sums.push_back(s);
            scenes.push_back(0);
            it = sums.end() - 1;
        }
        AccuracyRow &s = *it;
        ++scenes[size_t(it - sums.begin())];
        s.triangles += row.triangles;
        s.rays += row.rays;
        s.trace_ms += row.trace_ms;
        s.counts_leaks = s.counts_leaks || row.counts_leaks;
        s.errors.leaks += row.errors.leaks;
        s.errors.false_hits += row.errors.false_hits;
        s.errors.self_hits += row.errors.self_hits;
        s.errors.mismatches += row.errors.mismatches;
        s.spawned_rays += row.spawned_rays;
        s.naive_self_hits += row.naive_self_hits;
        s.reference_rays += row.reference_rays;
    }
    for (size_t i = 0; i < sums.size(); ++i) sums[i].scene = std::to_string(scenes[i]) + (scenes[i] == 1 ? " scene" : " scenes");
    return sums;
}

std::string accuracy_table(const std::vector<AccuracyRow> &summary) {
    std::string text;
    char buf[256];
    std::snprintf(buf, sizeof buf, "%-14s %-11s %-10s %10s %9s %7s %10s %17s %17s %14s\n", "Set", "Intersector", "Scenes",
                  "Rays", "MRays/s", "Leaks", "FalseHits", "SelfHits/Spawned", "Mismatches/Ref", "NaiveSelfHits");
    text += buf;
    for (const AccuracyRow &s : summary) {
        double mrays = s.trace_ms > 0 ? double(s.rays) / (s.trace_ms * 1000.0) : 0.0;
        if (!s.measured) {
            std::snprintf(buf, sizeof buf, "%-14s %-11s %-10s %10zu %9.3f %7s %10s %17s %17s %14s\n", s.set.c_str(),
                          s.intersector.c_str(), s.scene.c_str(), s.rays, mrays, "-", "-", "-", "(reference)", "-");
        } else {
            std::string leaks = s.counts_leaks ? std::to_string(s.errors.leaks) : "-";
            std::string self = std::to_string(s.errors.self_hits) + "/" + std::to_string(s.spawned_rays);
            std::string wrong = std::to_string(s.errors.mismatches) + "/" + std::to_string(s.reference_rays);
            std::snprintf(buf, sizeof buf, "%-14s %-11s %-10s %10zu %9.3f %7s %10zu %17s %17s %14zu\n", s.set.c_str(),
                          s.intersector.c_str(), s.scene.c_str(), s.rays, mrays, leaks.c_str(), s.errors.false_hits, self.c_str(),
                          wrong.c_str(), s.naive_self_hits);
        }
        text += buf;
    }
    return text;
}

}  // namespace kb
