// kdrt-bench: kdrt's default tree beside Embree on the benchmark frame, or with --sweep the
// original course ray tracer's leaf-size benchmark, with an error count beside every timing; with
// --accuracy, speed beside the error counts of each ray/triangle test on the frame and the
// hard-case ray sets; with --scene, kdrt_scene against one tree. See --help and bench/README.md.
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include "bench.hpp"
#include "embree_peer.hpp"
#include "frames.hpp"
#include "saved_trees.hpp"
#include "points.hpp"
#include "scenes.hpp"
#include "oracle/hard_cases.hpp"
#include "oracle/reference.hpp"
#include "common/atomic_file.hpp"
#include "common/interrupt.hpp"
#include "common/mesh_io.hpp"  // common::mesh_dir
#include "common/output.hpp"
#include "common/parse.hpp"
#include "common/thread_scheduler.hpp"
#include "common/timing.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iterator>
#include <memory>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;

struct Input {
    std::string label;  // CSV Mesh column
    common::Mesh mesh;
};

std::string upper_stem(const std::string &path) {
    std::string stem = fs::path(path).stem().string();
    for (char &c : stem) c = char(std::toupper(static_cast<unsigned char>(c)));
    return stem;
}

bool is_mesh_file(const fs::path &p) {
    std::string ext = p.extension().string();
    for (char &c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".off" || ext == ".obj" || ext == ".ply" || ext == ".stl" || ext == ".gltf" || ext == ".glb";
}

// Files named on the command line, and the mesh files inside named folders (sorted); a folder
// with none is named in `empty`.
std::vector<std::string> expand_inputs(const std::vector<std::string> &args, std::vector<std::string> &empty) {
    std::vector<std::string> files;
    for (const std::string &arg : args) {
        std::error_code ec;
        if (fs::is_directory(arg, ec)) {
            std::vector<std::string> inside;
            for (const auto &entry : fs::directory_iterator(arg, ec))
                if (entry.is_regular_file(ec) && is_mesh_file(entry.path())) inside.push_back(entry.path().string());
            std::sort(inside.begin(), inside.end());
            files.insert(files.end(), inside.begin(), inside.end());
            if (inside.empty()) empty.push_back(arg);
        } else {
            files.push_back(arg);  // a missing file is reported when it fails to load
        }
    }
    return files;
}

// Stand-ins when no mesh folder is around: a sphere and a torus of about 9,000 triangles each.
std::vector<Input> generated_inputs() {
    std::vector<Input> inputs(2);
    inputs[0].label = "GENERATED_SPHERE";
    inputs[0].mesh = oracle::uv_sphere(48, 96, 1.0, false);
    inputs[1].label = "GENERATED_TORUS";
    inputs[1].mesh = common::torus(96, 48, 1.0, 0.4);
    return inputs;
}

// Standard error: a progress line before each piece of work (a mesh's rays, each build and
// trace, each ray set), numbered out of the run's, with the time so far once it is more than a
// moment; the same on a terminal as in a log (one line each, no bar redrawn), as Embree's and
// tinybvh's benchmarks print theirs. --quiet keeps only the notes: what went wrong, and results.
struct Progress {
    size_t total = 0, done = 0;
    bool quiet = false;
    common::Stopwatch clock;
    // "kdrt-bench: [2/3] BUNNY: sah leaf 4: tracing 800x800 primary rays"
    void step(const std::string &what) {
        ++done;
        status("[" + std::to_string(done) + "/" + std::to_string(total) + "] " + what);
    }
    // A progress line without a number: "kdrt-bench: WHAT", and "(12 s so far)" after a second.
    void status(const std::string &what) {
        if (quiet) return;
        const double seconds = clock.ms() / 1000.0;
        char so_far[48] = "";
        if (seconds >= 1) std::snprintf(so_far, sizeof so_far, " (%.0f s so far)", seconds);
        std::fprintf(stderr, "kdrt-bench: %s%s\n", what.c_str(), so_far);
        std::fflush(stderr);
    }
    void note(const std::string &line) {
        std::fprintf(stderr, "%s\n", line.c_str());
        std::fflush(stderr);
    }
};

// expand_inputs(), each folder without a mesh file noted and counted as a failure.
std::vector<std::string> mesh_files(const std::vector<std::string> &args, Progress &progress, int &failures) {
    std::vector<std::string> empty_folders;
    std::vector<std::string> files = expand_inputs(args, empty_folders);
    for (const std::string &folder : empty_folders) {
        progress.note("kdrt-bench: skipping " + folder + ": a folder with no mesh files (.off, .obj, .ply, .stl, .gltf, .glb)");
        ++failures;
    }
    return files;
}

// Where the CSV goes: standard output, or with -o OUT a rows-so-far file OUT.partial beside OUT,
// flushed and checked row by row and renamed over OUT when the run ends with at least one row.
// A run that is interrupted, cannot write, or writes no row leaves OUT as it was, and its whole
// rows, if any, in OUT.partial (bench/README.md).
class Csv {
public:
    ~Csv()
    {
        if (file_) std::fclose(file_);
    }

    bool open(const std::string &output, std::string &error)
    {
        if (output.empty()) return true;
        output_ = output;
        partial_ = output + ".partial";
        if (!common::check_replaceable(output_, error) || !common::check_replaceable(partial_, error)) return false;
        // Until the first row a signal removes the partial file, which would hold only the header.
        slot_ = common::remove_on_signal(partial_);
        common::note_on_signal("kdrt-bench: interrupted before any row; '" + output_ + "' is as it was");
        file_ = std::fopen(partial_.c_str(), "w");
        if (!file_) {
            error = "cannot write '" + output_ + "': cannot create " + partial_ + ": " + std::strerror(errno);
            drop_signal_handling();
            return false;
        }
        return true;
    }

    // The header, then each row; false with the reason when any of it failed to reach the file.
    bool line(const std::string &text, std::string &error)
    {
        const bool row = started_;
        started_ = true;
        if (!file_) {
            if (!common::write_flushed(stdout, text + "\n", "standard output", error)) return false;
        } else if (!common::write_flushed(file_, text + "\n", "'" + partial_ + "'", error)) {
            abandon();
            error += "; " + where();
            return false;
        } else {
            whole_bytes_ = std::ftell(file_);
            if (row && rows_ == 0) {  // from now on a signal keeps the partial file, and says so
                common::forget_on_signal(slot_);
                slot_ = -1;
                common::note_on_signal("kdrt-bench: interrupted; the rows so far are in '" + partial_ + "', and '" +
                                       output_ + "' is as it was");
            }
        }
        rows_ += row;
        return true;
    }

    // The end of the run: OUT.partial becomes OUT if it holds a row; false with the reason if not.
    bool finish(std::string &error)
    {
        if (!rows_) {
            if (file_) abandon();
            error = "no row was written" + (output_.empty() ? std::string() : "; " + where());
            return false;
        }
        if (!file_) return true;  // standard output: close_stdout checks its end
        const bool closed = std::fclose(file_) == 0;
        const int reason = errno;
        file_ = nullptr;
        drop_signal_handling();
        if (!closed) {
            error = "cannot write '" + partial_ + "': " + std::strerror(reason);
        } else if (common::check_replaceable(output_, error)) {  // it may have changed since the start
            if (std::rename(partial_.c_str(), output_.c_str()) == 0) return true;
            error = "cannot rename '" + partial_ + "' over '" + output_ + "': " + std::strerror(errno);
        }
        error += "; " + where();
        return false;
    }

private:
    void drop_signal_handling()
    {
        common::forget_on_signal(slot_);
        slot_ = -1;
        common::note_on_signal("");
    }

    // After a failed write: the partial file cut back to its whole rows, or removed without any.
    void abandon()
    {
        const bool cut = ftruncate(fileno(file_), whole_bytes_) == 0;  // else it keeps its cut row
        (void)cut;
        std::fclose(file_);
        file_ = nullptr;
        if (!rows_) std::remove(partial_.c_str());
        drop_signal_handling();
    }

    std::string where() const
    {
        if (!rows_) return "'" + output_ + "' is as it was";
        return "the " + std::to_string(rows_) + " row(s) so far are in '" + partial_ + "', and '" + output_ +
               "' is as it was";
    }

    std::string output_, partial_;
    std::FILE *file_ = nullptr;
    long whole_bytes_ = 0;
    size_t rows_ = 0;
    bool started_ = false;
    int slot_ = -1;
};

// --accuracy: every ray set through every intersector, a CSV row each, the summary on stderr.
int run_accuracy(const kb::Options &opt, const std::vector<Input> &inputs, const std::vector<kdrt_intersector> &intersectors,
                 Csv &csv, Progress &progress, int failures) {
    const uint32_t seed = 1;
    const double offsets[] = {1e3, 1e5, 1e7};
    common::Stopwatch wall;
    progress.status("--accuracy: generating the watertight and hard-case ray sets");
    std::vector<kb::AccuracySet> extra = kb::watertight_sets(opt.hard_rays, seed);
    for (kb::AccuracySet &s : kb::hard_case_sets(opt.hard_rays, seed)) extra.push_back(std::move(s));
    progress.total = inputs.size() * (2 + std::size(offsets)) + extra.size();

    std::vector<kb::AccuracyRow> rows;
    std::string error, write_error;
    bool written = csv.line(kb::accuracy_csv_header(), write_error);
    auto run = [&](const kb::AccuracySet &set) {
        if (!written) return;  // the CSV cannot be written: the run is over
        progress.step(set.set + " " + set.scene + ": " + std::to_string(set.rays.size()) + " rays, " +
                      std::to_string(intersectors.size()) + " intersector(s)");
        const size_t first = rows.size();
        if (!kb::run_accuracy_set(set, intersectors, opt.reference_rays, opt.threads, opt.repeat, seed, true, rows, error)) {
            progress.note("kdrt-bench: " + error);
            ++failures;
        }
        for (size_t i = first; i < rows.size() && written; ++i) {
            written = csv.line(kb::accuracy_csv_row(rows[i]), write_error);
            if (!rows[i].errors.first.empty())
                progress.note(set.set + " " + set.scene + " " + rows[i].intersector + ": first error: " + rows[i].errors.first);
        }
    };
    for (const Input &in : inputs) {
        if (!written) break;
        const kb::Scene scene = kb::make_scene(in.mesh, in.label);
        for (const kb::AccuracySet &set : kb::frame_sets(scene, opt.width, opt.height, seed)) run(set);
        for (double offset : offsets) run(kb::far_set(scene, offset, opt.width, opt.height, seed));
    }
    for (const kb::AccuracySet &set : extra) run(set);
    if (!written) {
        progress.note("kdrt-bench: " + write_error);
        return 1;
    }

    std::fprintf(stderr, "\n%s", kb::accuracy_table(kb::accuracy_summary(rows)).c_str());
    std::fprintf(stderr, "kdrt-bench --accuracy: %.1f s\n", wall.ms() / 1000.0);
    if (failures) progress.note("kdrt-bench: " + std::to_string(failures) + " input(s) or set(s) failed; see above");
    if (!csv.finish(error)) {
        progress.note("kdrt-bench: " + error);
        return 1;
    }
    return failures ? 1 : 0;
}

// --scene: a tree and a scene, freed when they go out of scope.
using TreePtr = std::unique_ptr<kdrt_tree, decltype(&kdrt_tree_free)>;
using ScenePtr = std::unique_ptr<kdrt_scene, decltype(&kdrt_scene_free)>;

// The median of xs (not empty).
double median_of(std::vector<double> xs) {
    std::sort(xs.begin(), xs.end());
    const size_t n = xs.size();
    return n % 2 ? xs[n / 2] : 0.5 * (xs[n / 2 - 1] + xs[n / 2]);
}

// --points: closest-point queries of each kind against Embree's rtcPointQuery, then overlap
// queries by size, a CSV row each (bench/README.md, "Closest point and overlap").
int run_points(const kb::Options &opt, const std::vector<Input> &inputs, Csv &csv, Progress &progress, int failures) {
    const uint64_t seed = 1;
    const double sizes[] = {0.01, 0.03, 0.1};
    std::string error, write_error;
    bool written = csv.line(kb::points_csv_header(), write_error);
    progress.total = inputs.size() * (std::size(kb::kPointKinds) + 2 * std::size(sizes));
    auto emit = [&](const kb::PointsRow &row) {
        if (written) written = csv.line(kb::points_csv_row(row), write_error);
        char line[256];
        if (row.query == "closest")
            std::snprintf(line, sizeof line,
                          "%s closest %s: kdrt %.1f ms, Embree %.1f ms (%.2fx; CPU time %.2fx), "
                          "disagreements %zu / %zu of %zu",
                          row.mesh.c_str(), row.kind.c_str(), row.kdrt_ms, row.embree_ms, row.ratio, row.cpu_ratio,
                          row.kdrt_mismatches, row.embree_mismatches, row.reference);
        else
            std::snprintf(line, sizeof line, "%s %s %g%%: kdrt %.1f ms, %llu triangles, disagreements %zu of %zu",
                          row.mesh.c_str(), row.query.c_str(), 100 * row.size, row.kdrt_ms,
                          (unsigned long long)row.found, row.kdrt_mismatches, row.reference);
        progress.status(line);
    };
    for (const Input &in : inputs) {
        if (!written) break;
        const kdrt_triangles view = in.mesh.view();
        kdrt_tree *raw = nullptr;
        const kdrt_result r = kdrt_tree_build(&view, nullptr, &raw, nullptr);
        TreePtr tree(raw, kdrt_tree_free);
        if (r != KDRT_SUCCESS) {
            progress.note("kdrt-bench: " + in.label + ": the tree: " + kdrt_result_string(r));
            ++failures;
            continue;
        }
        kb::PeerPoints peer;
        if (opt.compare_embree && !peer.build(in.mesh, opt.build_threads, error)) {
            progress.note("kdrt-bench: " + in.label + ": Embree: " + error);
            ++failures;
            continue;
        }
        const double diagonal = kb::mesh_diagonal(in.mesh);
        const kdrt_aabb box = kdrt_tree_bounds(tree.get());
        for (kb::PointKind kind : kb::kPointKinds) {
            if (!written) break;
            progress.step(in.label + ": closest point from " + std::to_string(opt.point_queries) + " " +
                          kb::point_kind_name(kind) + " points");
            const std::vector<float> points = kb::make_points(in.mesh, kind, opt.point_queries, seed);
            const size_t n = opt.point_queries;
            std::vector<kdrt_closest> answers(n);
            std::vector<float> peer_distance;
            std::vector<uint32_t> peer_triangle;
            std::vector<double> kdrt_ms, peer_ms, kdrt_cpu, peer_cpu;
            for (unsigned rep = 0; rep < opt.repeat; ++rep) {
                auto run_kdrt = [&] {
                    const double cpu = kb::thread_cpu_ms();
                    kdrt_ms.push_back(common::timed_parallel(n, 1, [&](size_t i) {
                        kdrt_closest_point(tree.get(), &points[3 * i], INFINITY, &answers[i]);
                    }));
                    kdrt_cpu.push_back(kb::thread_cpu_ms() - cpu);
                };
                auto run_peer = [&] {
                    if (!opt.compare_embree) return;
                    const double cpu = kb::thread_cpu_ms();
                    peer_ms.push_back(peer.closest(points, peer_distance, peer_triangle));
                    peer_cpu.push_back(kb::thread_cpu_ms() - cpu);
                };
                if (rep % 2) run_peer(), run_kdrt();  // in turns: neither always runs first
                else run_kdrt(), run_peer();
            }
            kb::PointsRow row;
            row.mesh = in.label, row.triangles = in.mesh.triangle_count(), row.query = "closest";
            row.kind = kb::point_kind_name(kind), row.queries = n, row.repeat = opt.repeat;
            row.kdrt_ms = median_of(kdrt_ms);
            row.embree_ms = peer_ms.empty() ? 0 : median_of(peer_ms);
            row.ratio = peer_ms.empty() ? 0 : row.embree_ms / row.kdrt_ms;
            row.kdrt_cpu_ms = median_of(kdrt_cpu);
            row.embree_cpu_ms = peer_cpu.empty() ? 0 : median_of(peer_cpu);
            row.cpu_ratio = peer_cpu.empty() ? 0 : row.embree_cpu_ms / row.kdrt_cpu_ms;
            for (const kdrt_closest &a : answers) row.found += a.triangle != KDRT_INVALID_ID;
            row.reference = std::min(n, opt.reference_rays == 0 ? n : opt.reference_rays);
            for (size_t i = 0; i < row.reference; ++i) {
                const double ref = kb::brute_closest_distance(in.mesh, &points[3 * i]);
                const double e = kb::distance_error(answers[i].distance, ref, diagonal);
                row.kdrt_max_error = std::max(row.kdrt_max_error, e);
                row.kdrt_mismatches += !(e <= kb::kDistanceTolerance);
                if (!peer_ms.empty()) {
                    const double pe = kb::distance_error(peer_distance[i], ref, diagonal);
                    row.embree_max_error = std::max(row.embree_max_error, pe);
                    row.embree_mismatches += !(pe <= kb::kDistanceTolerance);
                }
            }
            emit(row);
        }
        // Overlap: boxes and balls around points near the surface, a hundredth as many queries.
        const size_t n = std::max<size_t>(1, opt.point_queries / 100);
        const std::vector<float> centres = kb::make_points(in.mesh, kb::PointKind::surface, n, seed + 1);
        for (int sphere = 0; sphere < 2 && written; ++sphere)
            for (double size : sizes) {
                if (!written) break;
                progress.step(in.label + ": " + std::to_string(n) + (sphere ? " balls " : " boxes ") +
                              std::to_string(size) + " of the box across");
                std::vector<uint64_t> counts(n);
                std::vector<double> ms, cpu_ms;
                const float radius = float(0.5 * size * diagonal);
                float half[3];
                for (int a = 0; a < 3; ++a) half[a] = float(0.5 * size * (double(box.max[a]) - box.min[a]));
                for (unsigned rep = 0; rep < opt.repeat; ++rep) {
                    const double cpu = kb::thread_cpu_ms();
                    ms.push_back(common::timed_parallel(n, 1, [&](size_t i) {
                        const float *c = &centres[3 * i];
                        if (sphere) {
                            kdrt_overlap_sphere(tree.get(), c, radius, nullptr, nullptr, &counts[i]);
                        } else {
                            kdrt_aabb b;
                            for (int a = 0; a < 3; ++a) b.min[a] = c[a] - half[a], b.max[a] = c[a] + half[a];
                            kdrt_overlap_box(tree.get(), &b, nullptr, nullptr, &counts[i]);
                        }
                    }));
                    cpu_ms.push_back(kb::thread_cpu_ms() - cpu);
                }
                kb::PointsRow row;
                row.mesh = in.label, row.triangles = in.mesh.triangle_count(), row.query = sphere ? "sphere" : "box";
                row.kind = "surface", row.size = size, row.queries = n, row.repeat = opt.repeat;
                row.kdrt_ms = median_of(ms);
                row.kdrt_cpu_ms = median_of(cpu_ms);
                for (uint64_t c : counts) row.found += c;
                if (sphere) {  // the balls' counts against the brute force
                    const size_t limit = opt.reference_rays == 0 ? n : std::max<size_t>(1, opt.reference_rays / 10);
                    row.reference = std::min(n, limit);
                    for (size_t i = 0; i < row.reference; ++i)
                        row.kdrt_mismatches += kb::brute_sphere_count(in.mesh, &centres[3 * i], radius) != counts[i];
                }
                emit(row);
            }
    }
    if (!written) {
        progress.note("kdrt-bench: " + write_error);
        return 1;
    }
    if (failures) progress.note("kdrt-bench: " + std::to_string(failures) + " input(s) failed; see above");
    if (!csv.finish(error)) {
        progress.note("kdrt-bench: " + error);
        return 1;
    }
    return failures ? 1 : 0;
}


// One way of tracing a scene's rays, timed in every pass.
struct SceneVariant {
    std::string layout, query;
    const std::vector<uint32_t> *first;  // where its hits lie in the one mesh (kb::flat_triangle)
    std::function<double(std::vector<kdrt_hit> &)> trace;  // the rays' answers; the wall time in ms
    std::vector<double> ms;
    std::vector<kdrt_hit> hits;
};

// One --scene: the one tree, the kdrt_scene and, with --compare embree, Embree's two, built; then
// for primary and diffuse rays, each variant traced in turn --repeat times, and the rows written
// (the medians). false when the CSV could not be written (write_error says why); a failed build
// is noted and counted in `failures`.
bool run_scene(const kb::Options &opt, const kb::SceneLayout &layout, const kdrt_build_options &options, Csv &csv,
               Progress &progress, int &failures, std::string &write_error) {
    const auto failed = [&](const std::string &what) {  // true: the CSV is fine, the run goes on
        progress.note("kdrt-bench: --scene " + layout.name + ": " + what);
        ++failures;
        return true;
    };
    const unsigned commits = 21;  // top-level rebuilds timed, of the field
    const uint32_t seed = 1;
    const bool instanced = !layout.instances.empty();
    const kdrt_triangles world = layout.frame.geometry.view();

    kdrt_tree *built = nullptr;
    common::Stopwatch clock;
    kdrt_result r = kdrt_tree_build(&world, &options, &built, nullptr);
    const double tree_ms = clock.ms();
    TreePtr tree(built, kdrt_tree_free);
    if (r != KDRT_SUCCESS) return failed(std::string("the one tree: ") + kdrt_result_string(r));
    std::vector<TreePtr> prototypes;
    std::vector<kdrt_tree *> prototype_trees;
    for (const common::Mesh &mesh : layout.prototypes) {
        const kdrt_triangles view = mesh.view();
        r = kdrt_tree_build(&view, &options, &built, nullptr);
        prototypes.emplace_back(built, kdrt_tree_free);
        prototype_trees.push_back(built);
        if (r != KDRT_SUCCESS) return failed("the tree of " + mesh.name + ": " + kdrt_result_string(r));
    }
    const std::vector<kdrt_geometry> geometries = kb::kdrt_geometries(layout, prototype_trees);
    kdrt_scene *made = nullptr;
    kdrt_build_report report;
    clock = common::Stopwatch();
    r = kdrt_scene_build(geometries.data(), uint32_t(geometries.size()), &options, &made, &report);
    const double scene_ms = clock.ms();
    ScenePtr scene(made, kdrt_scene_free);
    if (r != KDRT_SUCCESS)
        return failed(std::string("kdrt_scene_build: ") + kdrt_result_string(r) + " (geometry " +
                      std::to_string(report.invalid_geometry) + ")");
    std::string error;
    const double commit_ms = instanced ? kb::median_commit_ms(scene.get(), layout, commits, error) : scene_ms;
    if (commit_ms < 0) return failed(error);

    kb::PeerScene peer_tree, peer_scene;
    bool embree = opt.compare_embree;
    if (embree && (!peer_tree.build_mesh(world, opt.build_threads, error) ||
                   !peer_scene.build_layout(layout, opt.build_threads, error))) {
        failed("Embree: " + error);
        embree = false;
    }
    const double peer_scene_ms = !embree ? 0 : instanced ? peer_scene.median_commit_ms(layout, commits) : peer_scene.build_ms();
    char built_in[160];
    std::snprintf(built_in, sizeof built_in, "built in %.1f ms (one tree), %.1f ms (kdrt_scene_build)", tree_ms, scene_ms);
    progress.status("--scene " + layout.name + ": " + std::to_string(geometries.size()) + " geometries, " +
                    std::to_string(world.triangle_count) + " triangles; " + built_in);

    const std::string tree_layout = instanced ? "flattened" : "merged", scene_layout = instanced ? "instanced" : "meshes";
    const double tolerance = instanced ? 1e-4 : 0;  // instances are exact to float rounding only
    const std::vector<uint32_t> one_tree = {0};
    kdrt_query mask = kdrt_default_query();  // every mask bit, no filter
    kdrt_query filter = mask;
    filter.filter = kb::take_every_hit;
    for (kb::RayKind kind : {kb::RayKind::primary, kb::RayKind::diffuse}) {
        const std::vector<kdrt_ray> rays = kb::make_rays(layout.frame, kind, opt.width, opt.height, tree.get(), seed);
        const auto timed = [&](std::vector<kdrt_hit> &hits, auto &&query) {
            hits.resize(rays.size());
            return common::timed_parallel(rays.size(), opt.threads, [&](size_t i) { query(rays[i], hits[i]); });
        };
        const auto through_scene = [&](const kdrt_query *q) {
            return [&, q](std::vector<kdrt_hit> &hits) {
                return timed(hits, [&](const kdrt_ray &ray, kdrt_hit &hit) { kdrt_scene_intersect(scene.get(), &ray, q, &hit); });
            };
        };
        std::vector<SceneVariant> variants;
        variants.push_back({tree_layout, "none", &one_tree, [&](std::vector<kdrt_hit> &hits) {
            return timed(hits, [&](const kdrt_ray &ray, kdrt_hit &hit) { kdrt_intersect(tree.get(), &ray, &hit); });
        }, {}, {}});
        variants.push_back({scene_layout, "none", &layout.first, through_scene(nullptr), {}, {}});
        variants.push_back({scene_layout, "mask", &layout.first, through_scene(&mask), {}, {}});
        variants.push_back({scene_layout, "filter", &layout.first, through_scene(&filter), {}, {}});
        if (embree) {
            variants.push_back({tree_layout, "embree", &one_tree, [&](std::vector<kdrt_hit> &hits) {
                return peer_tree.trace(rays, opt.threads, hits);
            }, {}, {}});
            variants.push_back({scene_layout, "embree", &layout.first, [&](std::vector<kdrt_hit> &hits) {
                return peer_scene.trace(rays, opt.threads, hits);
            }, {}, {}});
        }
        // Every variant in turn, pass after pass, so that a busy moment of the machine falls on all.
        progress.step("--scene " + layout.name + ": tracing " + kb::frame_rays(opt, kind) + " through " +
                      std::to_string(variants.size()) + " variants, " + std::to_string(opt.repeat) +
                      (opt.repeat == 1 ? " pass" : " passes"));
        for (unsigned pass = 0; pass < opt.repeat; ++pass)
            for (SceneVariant &v : variants) v.ms.push_back(v.trace(v.hits));

        const SceneVariant &base = variants[0], &plain = variants[1];
        for (size_t k = 0; k < 4; ++k) {
            const SceneVariant &v = variants[k];
            kb::SceneRow row;
            row.scene = layout.name;
            row.layout = v.layout;
            row.query = v.query;
            row.rays = kind == kb::RayKind::primary ? "primary" : "diffuse";
            row.ray_count = rays.size();
            row.triangles = world.triangle_count;
            row.stored_triangles = k == 0 ? world.triangle_count : kb::stored_triangles(layout);
            row.instances = k == 0 ? 0 : uint32_t(layout.instances.size());
            row.build_ms = k == 0 ? tree_ms : commit_ms;
            row.trace_ms = kb::median(v.ms);
            if (k == 1) {  // the scene against the one tree
                row.versus = tree_layout;
                row.versus_trace_ms = kb::median(base.ms);
                row.mismatches = kb::count_scene_mismatches(v.hits, *v.first, base.hits, *base.first, tolerance);
            } else if (k > 1) {  // a query that changes nothing against none
                row.versus = "none";
                row.versus_trace_ms = kb::median(plain.ms);
                row.mismatches = kb::count_scene_mismatches(v.hits, *v.first, plain.hits, *plain.first, 0);
            }
            if (embree && k < 2) {
                const SceneVariant &peer = variants[4 + k];
                row.embree = true;
                row.embree_build_ms = k == 0 ? peer_tree.build_ms() : peer_scene_ms;
                row.embree_trace_ms = kb::median(peer.ms);
                row.embree_mismatches = kb::count_scene_mismatches(peer.hits, *peer.first, base.hits, *base.first, 1e-4);
            }
            if (!csv.line(kb::scene_csv_row(row), write_error)) return false;
        }
    }
    return true;
}

// --scene's meshes: those named (default: the bunny, the ogre and nefertiti of the shared folder,
// else generated ones); a file that fails to load is noted and counted in `failures`.
std::vector<common::Mesh> scene_meshes(const kb::Options &opt, Progress &progress, int &failures) {
    std::string error;
    std::vector<std::string> args = opt.inputs;
    if (args.empty()) {
        for (const char *name : {"stanford-bunny.obj", "ogre.obj", "nefertiti.obj"})
            args.push_back(common::mesh_dir() + "/common/" + name);
        std::error_code ec;
        if (!fs::is_regular_file(args[0], ec) || !fs::is_regular_file(args[1], ec) || !fs::is_regular_file(args[2], ec))
            args.clear();
    }
    std::vector<common::Mesh> meshes;
    if (args.empty()) {
        progress.note("kdrt-bench: no meshes given and " + common::mesh_dir() + "/common lacks stanford-bunny.obj, ogre.obj or "
                      "nefertiti.obj: using generated meshes");
        for (Input &in : generated_inputs()) meshes.push_back(std::move(in.mesh));
    }
    const std::vector<std::string> files = mesh_files(args, progress, failures);
    if (!files.empty()) progress.status("loading " + std::to_string(files.size()) + " mesh file(s)");
    for (const std::string &path : files) {
        common::Mesh mesh;
        if (!common::load_mesh(path, mesh, error)) {
            progress.note("kdrt-bench: skipping " + path + ": " + error);
            ++failures;
            continue;
        }
        meshes.push_back(std::move(mesh));
    }
    return meshes;
}

// --scene: each scene of opt.scenes measured by run_scene.
int run_scenes(const kb::Options &opt, Csv &csv, Progress &progress) {
    int failures = 0;
    std::string error, write_error;
    const std::vector<common::Mesh> meshes = scene_meshes(opt, progress, failures);
    if (meshes.empty()) {
        progress.note("kdrt-bench: --scene: no mesh to place");
        return 1;
    }
    if (!csv.line(kb::scene_csv_header(), write_error)) {
        progress.note("kdrt-bench: " + write_error);
        return 1;
    }
    common::ThreadScheduler build_pool(opt.build_threads);
    kdrt_build_options options = kdrt_default_build_options();
    if (build_pool.threads() > 1) options.scheduler = build_pool.hooks();
    progress.total = opt.scenes.size() * 2;
    for (const std::string &name : opt.scenes) {
        kb::SceneLayout layout;
        if (name == "merged") {
            layout = kb::merged_layout(meshes);
        } else {
            std::vector<common::Mesh> simplified;
            std::string counts;
            for (const common::Mesh &mesh : meshes) {
                simplified.push_back(kb::clustered(kb::unit_sized(mesh), opt.instance_triangles));
                counts += (counts.empty() ? "" : ", ") + mesh.name + " " + std::to_string(simplified.back().triangle_count());
            }
            progress.status("--scene field: " + std::to_string(opt.instances) + " instances of " + counts + " triangles");
            layout = kb::field_layout(simplified, opt.instances, 1, opt.instance_spacing);
        }
        if (!run_scene(opt, layout, options, csv, progress, failures, write_error)) {
            progress.note("kdrt-bench: " + write_error);
            return 1;
        }
    }
    if (failures) progress.note("kdrt-bench: " + std::to_string(failures) + " input(s) or run(s) failed; see above");
    if (!csv.finish(error)) {
        progress.note("kdrt-bench: " + error);
        return 1;
    }
    return failures ? 1 : 0;
}

// --scene frames: the deforming mesh's new tree in place of the old one from the next commit on.
kdrt_result swap_deforming(kdrt_scene *scene, const kb::FramesWorld &world, const kdrt_tree *tree) {
    const kdrt_result r = kdrt_scene_detach(scene, world.deforming_id());
    if (r != KDRT_SUCCESS) return r;
    const kdrt_geometry g = kdrt_instance_geometry(world.deforming_id(), tree, world.deforming_transform);
    return kdrt_scene_attach(scene, &g);
}

// --scene frames: the medians of one count, thread count and variant, for the summary.
struct FramesSummary {
    uint32_t instances = 0;
    unsigned threads = 1;
    std::string variant;
    std::vector<kb::FramesRow> rows;  // move, commit, rebuild, primary, shadow, frame
};

// The summary table: a line per count, thread count and variant, kdrt's median ms / Embree's per
// phase, and kdrt's frame speed over Embree's.
std::string frames_summary(const std::vector<FramesSummary> &runs, unsigned frames, bool embree) {
    std::string text = "kdrt-bench --scene frames: the median of " + std::to_string(frames) + " frames, ms" +
                       (embree ? ", kdrt / Embree; Speed: kdrt's frame rate over Embree's" : " (kdrt)") + "\n";
    char buf[256];
    std::snprintf(buf, sizeof buf, "%9s %7s %-13s", "Instances", "Threads", "Variant");
    text += buf;
    for (const char *phase : {"move", "commit", "rebuild", "primary", "shadow", "frame"}) {
        std::snprintf(buf, sizeof buf, " %17s", phase);
        text += buf;
    }
    text += embree ? "  Speed\n" : "\n";
    for (const FramesSummary &run : runs) {
        const std::string variant = run.variant + (run.rows[0].embree ? "/" + run.rows[0].embree_quality : "");
        std::snprintf(buf, sizeof buf, "%9u %7u %-13s", run.instances, run.threads, variant.c_str());
        text += buf;
        for (const kb::FramesRow &row : run.rows) {
            const double k = kb::median(row.kdrt_ms), e = kb::median(row.embree_ms);
            const int digits = k < 10 ? 2 : 1;
            if (row.embree) std::snprintf(buf, sizeof buf, " %8.*f/%-8.*f", digits, k, e < 10 ? 2 : 1, e);
            else if (embree) std::snprintf(buf, sizeof buf, " %8.*f/%-8s", digits, k, "-");  // Embree failed here
            else std::snprintf(buf, sizeof buf, " %17.*f", digits, k);
            text += buf;
        }
        if (embree && run.rows.back().embree) {
            const double k = kb::median(run.rows.back().kdrt_ms), e = kb::median(run.rows.back().embree_ms);
            std::snprintf(buf, sizeof buf, "  %.2f", k > 0 ? e / k : 0.0);
            text += buf;
        }
        text += "\n";
    }
    return text;
}

// --scene frames (bench/README.md, "Frames"): for each count of opt.instance_counts and of
// opt.build_thread_counts, the world built once on each side, then for each variant opt.frames
// frames, kdrt's and Embree's in turn, each phase timed; a row per phase.
int run_frames(const kb::Options &opt, Csv &csv, Progress &progress) {
    int failures = 0;
    std::string error, write_error;
    const auto write_failed = [&] {
        progress.note("kdrt-bench: " + write_error);
        return 1;
    };
    const std::vector<common::Mesh> meshes = scene_meshes(opt, progress, failures);
    if (meshes.empty()) {
        progress.note("kdrt-bench: --scene frames: no mesh to place");
        return 1;
    }
    const uint32_t seed = 1;
    // The instances: every mesh simplified as the field's; the statues: every mesh but the last,
    // whole; the deforming mesh: the last, whole.
    std::vector<common::Mesh> simplified;
    std::string counts;
    for (const common::Mesh &mesh : meshes) {
        simplified.push_back(kb::clustered(kb::unit_sized(mesh), opt.instance_triangles));
        counts += (counts.empty() ? "" : ", ") + mesh.name + " " + std::to_string(simplified.back().triangle_count());
    }
    const std::vector<common::Mesh> statues(meshes.begin(), meshes.end() - 1);
    const common::Mesh &deforming = meshes.back();
    progress.status("--scene frames: instances of " + counts + " triangles; deforming " + deforming.name + ", " +
                    std::to_string(deforming.triangle_count()) + " triangles");

    // The prototypes' trees, once: a tree is the same on any scheduler.
    std::vector<TreePtr> prototypes;
    std::vector<const kdrt_tree *> prototype_trees;
    for (const common::Mesh &mesh : simplified) {
        const kdrt_triangles view = mesh.view();
        kdrt_tree *built = nullptr;
        const kdrt_result r = kdrt_tree_build(&view, nullptr, &built, nullptr);
        prototypes.emplace_back(built, kdrt_tree_free);
        prototype_trees.push_back(built);
        if (r != KDRT_SUCCESS) {
            progress.note("kdrt-bench: --scene frames: the tree of " + mesh.name + ": " + kdrt_result_string(r));
            return 1;
        }
    }

    struct Variant {
        const char *name;
        kdrt_build_quality quality;
        kb::PeerQuality peer;
    };
    const Variant variants[] = {{"fast", KDRT_BUILD_QUALITY_FAST, kb::PeerQuality::low},
                                {"medium", KDRT_BUILD_QUALITY_MEDIUM, kb::PeerQuality::medium}};
    const char *phases[] = {"move", "commit", "rebuild", "primary", "shadow", "frame"};
    enum { kMove, kCommit, kRebuild, kPrimary, kShadow, kFrame };
    progress.total = opt.instance_counts.size() * opt.build_thread_counts.size() * std::size(variants);
    if (!csv.line(kb::frames_csv_header(), write_error)) return write_failed();
    std::vector<FramesSummary> summary;
    bool any_embree = false;

    for (uint32_t count : opt.instance_counts) {
        const kb::FramesWorld world = kb::frames_world(simplified, statues, deforming, count, seed);
        const std::vector<kdrt_ray> rays = kb::frames_camera_rays(world, opt.width, opt.height);
        uint64_t level_triangles = 0;
        for (const common::Mesh &mesh : world.level) level_triangles += mesh.triangle_count();
        for (unsigned asked : opt.build_thread_counts) {
            common::ThreadScheduler pool(asked);
            const unsigned threads = pool.threads();
            kdrt_build_options options = kdrt_default_build_options();
            if (threads > 1) options.scheduler = pool.hooks();
            const std::string where = "--scene frames: " + std::to_string(count) + " instances, " +
                                      std::to_string(threads) + (threads == 1 ? " thread" : " threads");
            const auto failed = [&](const std::string &what) {
                progress.note("kdrt-bench: " + where + ": " + what);
                ++failures;
            };

            // Frame 0, the world as it starts: the deforming mesh's first tree, the scene over
            // the instances, the level's meshes and that tree, and Embree's the same.
            unsigned frame = 0;
            std::vector<float> transforms(12 * size_t(count));
            for (uint32_t i = 0; i < count; ++i) kb::mover_transform(world, i, frame, &transforms[12 * size_t(i)]);
            std::vector<float> positions[2];  // the frame's vertices and the last frame's, which its tree reads
            kb::deformed_positions(world, frame, positions[0]);
            kdrt_triangles deformed_view = world.deforming.view();
            deformed_view.positions = positions[0].data();
            kdrt_tree *built = nullptr;
            kdrt_result r = kdrt_tree_build(&deformed_view, &options, &built, nullptr);
            TreePtr deformed(built, kdrt_tree_free);
            if (r != KDRT_SUCCESS) {
                failed(std::string("the deforming mesh's tree: ") + kdrt_result_string(r));
                continue;
            }
            std::vector<kdrt_geometry> geometries;
            for (uint32_t i = 0; i < count; ++i)
                geometries.push_back(kdrt_instance_geometry(i, prototype_trees[world.movers[i].prototype], &transforms[12 * size_t(i)]));
            std::vector<kdrt_triangles> level_views;
            for (const common::Mesh &mesh : world.level) level_views.push_back(mesh.view());
            for (uint32_t k = 0; k < world.level.size(); ++k) geometries.push_back(kdrt_mesh_geometry(world.level_id(k), &level_views[k]));
            geometries.push_back(kdrt_instance_geometry(world.deforming_id(), deformed.get(), world.deforming_transform));
            kdrt_scene *made = nullptr;
            kdrt_build_report report;
            common::Stopwatch clock;
            r = kdrt_scene_build(geometries.data(), uint32_t(geometries.size()), &options, &made, &report);
            const double scene_ms = clock.ms();
            ScenePtr scene(made, kdrt_scene_free);
            if (r != KDRT_SUCCESS) {
                failed(std::string("kdrt_scene_build: ") + kdrt_result_string(r) + " (geometry " +
                       std::to_string(report.invalid_geometry) + ")");
                continue;
            }
            std::vector<float> peer_vertices = positions[0];  // Embree's vertex buffer, shared: it outlives peer
            kb::PeerFrames peer;
            bool embree = opt.compare_embree;
            if (embree && !peer.build(world, peer_vertices, transforms, threads, error)) {
                failed("Embree: " + error);
                embree = false;
            }
            any_embree |= embree;
            char built_in[200];
            std::snprintf(built_in, sizeof built_in, "%zu geometries, %llu triangles in the level, %u deforming, %zu rays a "
                          "frame; kdrt_scene_build in %.1f ms", geometries.size(), (unsigned long long)level_triangles,
                          world.deforming.triangle_count(), rays.size(), scene_ms);
            progress.status(where + ": " + built_in);

            for (const Variant &variant : variants) {
                progress.step(where + ", " + variant.name + (embree ? std::string(" (Embree ") + kb::peer_quality_name(variant.peer) + ")" : "") +
                              ": " + std::to_string(opt.frames) + " frames of " + std::to_string(opt.width) + "x" +
                              std::to_string(opt.height) + " primary and shadow rays");
                if (embree) peer.set_quality(variant.peer);
                kdrt_build_options quality = options;
                quality.quality = variant.quality;
                std::vector<kb::FramesRow> rows(std::size(phases));
                for (size_t p = 0; p < rows.size(); ++p) {
                    rows[p].phase = phases[p];
                    rows[p].instances = count;
                    rows[p].threads = threads;
                    rows[p].variant = variant.name;
                    rows[p].embree = embree;
                    rows[p].embree_quality = kb::peer_quality_name(variant.peer);
                }
                rows[kMove].count = rows[kCommit].count = count;
                rows[kRebuild].count = world.deforming.triangle_count();
                rows[kPrimary].count = rays.size();
                rows[kPrimary].compared = rows[kShadow].compared = embree;
                std::vector<uint64_t> shadow_counts;
                std::vector<kdrt_hit> hits, peer_hits;
                std::vector<unsigned char> occluded, peer_occluded;
                std::vector<kdrt_ray> shadow;
                bool ok = true;
                for (unsigned f = 0; f < opt.frames && ok; ++f) {
                    // The frame's world, as a game writes it (untimed): where every instance is
                    // now, and the deforming mesh's vertices.
                    ++frame;
                    for (uint32_t i = 0; i < count; ++i) kb::mover_transform(world, i, frame, &transforms[12 * size_t(i)]);
                    std::vector<float> &now = positions[frame % 2];
                    kb::deformed_positions(world, frame, now);
                    double ms[std::size(phases)] = {};

                    // kdrt: the new tree, swapped in with the instances' moves, one commit.
                    deformed_view.positions = now.data();
                    clock = common::Stopwatch();
                    r = kdrt_tree_build(&deformed_view, &quality, &built, nullptr);
                    ms[kRebuild] = clock.ms();
                    TreePtr next(built, kdrt_tree_free);
                    if (r != KDRT_SUCCESS) {
                        failed(std::string("the deforming mesh's tree: ") + kdrt_result_string(r));
                        ok = false;
                        break;
                    }
                    clock = common::Stopwatch();
                    for (uint32_t i = 0; i < count && r == KDRT_SUCCESS; ++i)
                        r = kdrt_scene_set_transform(scene.get(), i, &transforms[12 * size_t(i)]);
                    if (r == KDRT_SUCCESS) r = swap_deforming(scene.get(), world, next.get());
                    ms[kMove] = clock.ms();
                    if (r != KDRT_SUCCESS) {
                        failed(std::string("moving the instances and swapping the deforming mesh's tree: ") + kdrt_result_string(r));
                        ok = false;
                        break;
                    }
                    clock = common::Stopwatch();
                    r = kdrt_scene_commit(scene.get());
                    ms[kCommit] = clock.ms();
                    if (r != KDRT_SUCCESS) {
                        failed(std::string("kdrt_scene_commit: ") + kdrt_result_string(r));
                        ok = false;
                        break;
                    }
                    deformed = std::move(next);  // the last frame's tree freed, the scene on the new one
                    hits.resize(rays.size());
                    ms[kPrimary] = common::timed_parallel(rays.size(), threads, [&](size_t i) {
                        kdrt_scene_intersect(scene.get(), &rays[i], nullptr, &hits[i]);
                    });
                    // Shadow rays from the primary hits to the light (untimed), as make_rays' are.
                    shadow.clear();
                    for (const kdrt_hit &h : hits) {
                        float point[3], dir[3];
                        kdrt_ray s;
                        if (h.triangle == KDRT_INVALID_ID || !kdrt_scene_hit_surface(scene.get(), &h, point, nullptr)) continue;
                        for (int a = 0; a < 3; ++a) dir[a] = world.light[a] - point[a];
                        if (!kdrt_scene_spawn_ray(scene.get(), &h, dir, &s)) continue;
                        for (int a = 0; a < 3; ++a) s.dir[a] = world.light[a] - s.org[a];
                        s.tmin = 0, s.tmax = 1;
                        shadow.push_back(s);
                    }
                    shadow_counts.push_back(shadow.size());
                    occluded.resize(shadow.size());
                    ms[kShadow] = common::timed_parallel(shadow.size(), threads, [&](size_t i) {
                        occluded[i] = (unsigned char)kdrt_scene_occluded(scene.get(), &shadow[i], nullptr);
                    });

                    double peer_ms[std::size(phases)] = {};
                    if (embree) {
                        // Embree: the vertex buffer written (untimed), its scene rebuilt, every
                        // instance moved, the top level committed, the same rays.
                        std::copy(now.begin(), now.end(), peer_vertices.begin());
                        peer_ms[kRebuild] = peer.rebuild();
                        peer_ms[kMove] = peer.move(transforms);
                        peer_ms[kCommit] = peer.commit();
                        peer_ms[kPrimary] = peer.trace(rays, threads, peer_hits);
                        peer_ms[kShadow] = peer.occluded(shadow, threads, peer_occluded);
                        if (peer.failed(error)) {
                            failed(error);
                            ok = false;
                            break;
                        }
                        rows[kPrimary].mismatches += kb::count_scene_mismatches(hits, world.first, peer_hits, world.first, 1e-4);
                        rows[kPrimary].compared_rays += rays.size();
                        size_t first = 0;
                        rows[kShadow].mismatches += kb::count_differing_occlusion(occluded, peer_occluded, first);
                        rows[kShadow].compared_rays += shadow.size();
                    }
                    for (size_t p = 0; p < kFrame; ++p) ms[kFrame] += ms[p], peer_ms[kFrame] += peer_ms[p];
                    for (size_t p = 0; p < rows.size(); ++p) {
                        rows[p].kdrt_ms.push_back(ms[p]);
                        if (embree) rows[p].embree_ms.push_back(peer_ms[p]);
                    }
                }
                if (!ok) break;
                {
                    std::vector<double> counts_as_ms(shadow_counts.begin(), shadow_counts.end());
                    rows[kShadow].count = uint64_t(kb::median(counts_as_ms));
                }
                rows[kFrame].count = rows[kPrimary].count + rows[kShadow].count;
                for (const kb::FramesRow &row : rows)
                    if (!csv.line(kb::frames_csv_row(row), write_error)) return write_failed();
                summary.push_back({count, threads, variant.name, rows});
            }
        }
    }
    if (!summary.empty()) {
        const std::string table = frames_summary(summary, opt.frames, any_embree);
        // Beside a CSV file on standard output; with the CSV there, on standard error.
        if (!opt.output.empty()) {
            if (!common::write_flushed(stdout, table, "standard output", error)) progress.note("kdrt-bench: " + error), ++failures;
        } else {
            std::fprintf(stderr, "\n%s", table.c_str());
        }
    }
    if (failures) progress.note("kdrt-bench: " + std::to_string(failures) + " input(s) or run(s) failed; see above");
    if (!csv.finish(error)) {
        progress.note("kdrt-bench: " + error);
        return 1;
    }
    return failures ? 1 : 0;
}

// --save-load (bench/README.md, "Saved trees"): every mesh measured by kb::measure_save_load, its
// two rows written as soon as it is done, and the table of them all at the end.
int run_save_load(const kb::Options &opt, const std::vector<Input> &inputs, Csv &csv, Progress &progress, int failures) {
    std::string error, write_error;
    if (!csv.line(kb::save_load_csv_header(), write_error)) {
        progress.note("kdrt-bench: " + write_error);
        return 1;
    }
    progress.total = inputs.size();
    std::vector<kb::SaveLoadRow> rows;
    for (const Input &in : inputs) {
        progress.step(in.label + ": " + std::to_string(in.mesh.triangle_count()) + " triangles: FAST and default (MEDIUM) builds, saves, "
                      "loads copied and in place, " + std::to_string(opt.repeat) + (opt.repeat == 1 ? " round" : " rounds"));
        const size_t first = rows.size();
        if (!kb::measure_save_load(in.mesh, in.label, opt.repeat, rows, error)) {
            progress.note("kdrt-bench: " + error);
            ++failures;
            continue;
        }
        for (size_t i = first; i < rows.size(); ++i)
            if (!csv.line(kb::save_load_csv_row(rows[i]), write_error)) {
                progress.note("kdrt-bench: " + write_error);
                return 1;
            }
    }
    if (!rows.empty()) {
        const std::string table = kb::save_load_table(rows);
        // Beside a CSV file on standard output; with the CSV there, on standard error.
        if (!opt.output.empty()) {
            if (!common::write_flushed(stdout, table, "standard output", error)) progress.note("kdrt-bench: " + error), ++failures;
        } else {
            std::fprintf(stderr, "\n%s", table.c_str());
        }
    }
    if (failures) progress.note("kdrt-bench: " + std::to_string(failures) + " input(s) failed; see above");
    if (!csv.finish(error)) {
        progress.note("kdrt-bench: " + error);
        return 1;
    }
    return failures ? 1 : 0;
}

// One trace's answers: hits (nearest hit) or, for shadow rays, occluded; a ray each.
struct Answers {
    std::vector<kdrt_hit> hits;
    std::vector<unsigned char> occluded;
};

// Traces the rays through tree as `call` hands them over, on opt.threads threads; the wall time
// in ms. single: kdrt_intersect (kdrt_occluded for shadow rays), or with rules their _query
// forms, a call a ray. batch: kdrt_intersect_batch (kdrt_occluded_batch) on opt.batch_size
// consecutive rays at a time, a chunk's rays on one thread.
double trace_kdrt(const kdrt_tree *tree, const std::vector<kdrt_ray> &rays, const kdrt_query *rules, kb::Call call,
                  const kb::Options &opt, Answers &out) {
    const bool shadow = opt.rays == kb::RayKind::shadow;  // any hit: kdrt_occluded
    out.hits.resize(shadow ? 0 : rays.size());
    out.occluded.resize(shadow ? rays.size() : 0);
    std::vector<kdrt_hit> &hits = out.hits;
    std::vector<unsigned char> &occluded = out.occluded;
    if (call == kb::Call::batch) {
        const size_t size = opt.batch_size, chunks = (rays.size() + size - 1) / size;
        return common::timed_parallel(chunks, opt.threads, [&](size_t c) {
            const uint32_t count = uint32_t(std::min(size, rays.size() - c * size));
            if (shadow) kdrt_occluded_batch(tree, &rays[c * size], count, rules, &occluded[c * size]);
            else kdrt_intersect_batch(tree, &rays[c * size], count, rules, &hits[c * size]);
        });
    }
    if (shadow && rules)
        return common::timed_parallel(rays.size(), opt.threads, [&](size_t i) { occluded[i] = (unsigned char)kdrt_occluded_query(tree, &rays[i], rules); });
    if (shadow)
        return common::timed_parallel(rays.size(), opt.threads, [&](size_t i) { occluded[i] = (unsigned char)kdrt_occluded(tree, &rays[i]); });
    if (rules)
        return common::timed_parallel(rays.size(), opt.threads, [&](size_t i) { kdrt_intersect_query(tree, &rays[i], rules, &hits[i]); });
    return common::timed_parallel(rays.size(), opt.threads, [&](size_t i) { kdrt_intersect(tree, &rays[i], &hits[i]); });
}

// The batch calls' promise (kdrt.h, BATCHES): each ray's answer is the single call's, bit for bit.
// Empty when it is kept; else what differs, for the run's failure message.
std::string batch_differences(const Answers &batch, const Answers &single, bool shadow) {
    size_t first = 0;
    const size_t differing = shadow ? kb::count_differing_occlusion(batch.occluded, single.occluded, first)
                                    : kb::count_differing_hits(batch.hits, single.hits, first);
    if (!differing) return "";
    const size_t rays = shadow ? single.occluded.size() : single.hits.size();
    std::string text = std::to_string(differing) + " of " + std::to_string(rays) + " rays answered otherwise by " +
                       (shadow ? "kdrt_occluded_batch than by kdrt_occluded" : "kdrt_intersect_batch than by kdrt_intersect") +
                       "; the first, ray " + std::to_string(first) + ": ";
    if (shadow)
        return text + "batch " + std::to_string(int(batch.occluded[first])) + ", single " + std::to_string(int(single.occluded[first]));
    return text + "batch " + kb::describe_hit(batch.hits[first]) + "; single " + kb::describe_hit(single.hits[first]);
}

// ", calls single, batch" for the progress lines, when --batch asks for more than the default.
std::string calls_label(const std::vector<kb::Call> &calls) {
    if (calls.size() == 1 && calls[0] == kb::Call::single) return "";
    std::string text;
    for (kb::Call call : calls) text += (text.empty() ? ", calls " : ", ") + std::string(kb::call_name(call));
    return text;
}

int run(int argc, char **argv) {
    kb::Options opt;
    std::string error;
    if (!kb::parse_options(argc, argv, opt, error)) {
        std::fprintf(stderr, "kdrt-bench: %s\n", error.c_str());
        return 2;
    }
    if (opt.help) {  // longer than stdio's buffer: checked as it is written, where errno says why
        if (common::write_flushed(stdout, kb::usage(), "standard output", error)) return 0;
        std::fprintf(stderr, "kdrt-bench: %s\n", error.c_str());
        return 1;
    }
    // A kernel this CPU cannot run is refused before any work, as a bad option is.
    if (!kb::check_kernels(opt.kernels, error)) {
        std::fprintf(stderr, "kdrt-bench: %s\n", error.c_str());
        return 2;
    }
    if (opt.compare_embree && !kb::embree_available()) {
        std::fprintf(stderr, "kdrt-bench: --compare embree is unavailable: this kdrt-bench was built without Embree "
                             "(install libembree-dev and configure again)\n");
        return 2;
    }
    Progress progress;
    progress.quiet = opt.quiet;
    if (!opt.compare_chosen && !opt.accuracy && !opt.save_load) {  // Embree beside kdrt where this kdrt-bench has it
        opt.compare_embree = kb::embree_available();
        if (!opt.compare_embree)
            progress.status("built without Embree: kdrt's rows only (install libembree-dev and configure again "
                            "to measure Embree beside kdrt)");
    }
    const bool packets = std::any_of(opt.calls.begin(), opt.calls.end(), [](kb::Call c) {
        return c == kb::Call::packet8 || c == kb::Call::packet16;
    });
    if (packets && !opt.compare_embree && opt.scenes.empty() && !opt.accuracy) {
        const bool kdrt_rows = !kb::kdrt_calls(opt).empty();
        std::fprintf(stderr, "kdrt-bench: --batch packet8 and packet16 time Embree's rtcIntersect8/16, and %s%s\n",
                     opt.compare_chosen ? "--compare none leaves Embree out" : "this kdrt-bench was built without Embree",
                     kdrt_rows ? ": drop them, or compare with Embree" : ": there would be no row");
        return 2;
    }
    // Open the output before any work, so an unwritable path costs nothing.
    Csv csv;
    if (!csv.open(opt.output, error)) {
        std::fprintf(stderr, "kdrt-bench: %s\n", error.c_str());
        return 1;
    }

    if (opt.scenes == std::vector<std::string>{"frames"}) return run_frames(opt, csv, progress);
    if (!opt.scenes.empty()) return run_scenes(opt, csv, progress);
    int failures = 0;
    std::vector<Input> inputs;
    std::vector<std::string> args = opt.inputs;
    if (args.empty() && fs::is_directory(common::mesh_dir() + "/seed")) args.push_back(common::mesh_dir() + "/seed");
    if (args.empty()) {
        progress.note("kdrt-bench: no meshes given and " + common::mesh_dir() + "/seed is absent: using generated meshes");
        inputs = generated_inputs();
    }
    const std::vector<std::string> files = mesh_files(args, progress, failures);
    if (!files.empty()) progress.status("loading " + std::to_string(files.size()) + " mesh file(s)");
    for (const std::string &path : files) {
        Input in;
        in.label = upper_stem(path);
        if (path.rfind("hostile:", 0) == 0) {  // hostile:KIND:TRIANGLES, generated
            const size_t colon = path.find(':', 8);
            const std::string kind = path.substr(8, colon == std::string::npos ? colon : colon - 8);
            uint32_t triangles = 0;
            const std::vector<std::string> kinds = oracle::hostile_kinds();
            if (colon == std::string::npos ||
                (kind != "soup" && std::find(kinds.begin(), kinds.end(), kind) == kinds.end()) ||
                !common::parse_count(path.substr(colon + 1), KDRT_MAX_TRIANGLES, triangles) || triangles == 0) {
                progress.note("kdrt-bench: skipping " + path + ": want hostile:KIND:TRIANGLES, KIND one of fan, cone, "
                              "slivers, overlapping, identical, soup");
                ++failures;
                continue;
            }
            in.mesh = oracle::hostile_mesh(kind, triangles, 1);
            in.label = "HOSTILE_" + kind + "_" + std::to_string(triangles);
            for (char &c : in.label) c = char(std::toupper(static_cast<unsigned char>(c)));
            inputs.push_back(std::move(in));
            continue;
        }
        if (!common::load_mesh(path, in.mesh, error)) {
            progress.note("kdrt-bench: skipping " + path + ": " + error);
            ++failures;
            continue;
        }
        inputs.push_back(std::move(in));
    }
    for (Input &in : inputs)
        if (opt.subdivide) in.mesh = common::subdivided(in.mesh, opt.subdivide), in.label += "_SUB" + std::to_string(opt.subdivide);

    if (opt.save_load) return run_save_load(opt, inputs, csv, progress, failures);
    const std::vector<kdrt_intersector> intersectors = kb::intersectors_for(opt);
    if (opt.accuracy) return run_accuracy(opt, inputs, intersectors, csv, progress, failures);
    if (opt.points) return run_points(opt, inputs, csv, progress, failures);

    const std::vector<kb::BuildVariant> variants = kb::build_variants(opt);
    // Embree at LOW quality beside kdrt's FAST builds, at MEDIUM beside the others.
    std::vector<kb::PeerQuality> peer_qualities;
    if (opt.compare_embree) {
        bool low = false, medium = false;
        for (const kb::BuildVariant &v : variants) {
            const bool fast = v.options.builder == KDRT_BUILDER_SAH && v.options.quality == KDRT_BUILD_QUALITY_FAST;
            low |= fast, medium |= !fast;
        }
        if (low) peer_qualities.push_back(kb::PeerQuality::low);
        if (medium) peer_qualities.push_back(kb::PeerQuality::medium);
    }
    // kdrt's calls of --batch (the packets are Embree's): with none, no kdrt build at all.
    const std::vector<kb::Call> kdrt_calls = kb::kdrt_calls(opt);
    const bool batched = std::find(kdrt_calls.begin(), kdrt_calls.end(), kb::Call::batch) != kdrt_calls.end();
    const std::vector<kb::BuildVariant> kdrt_variants = kdrt_calls.empty() ? std::vector<kb::BuildVariant>() : variants;
    std::vector<std::string> peer_notes;  // said once a run
    for (const Input &in : inputs)  // a progress line per build, before its repetitions
        progress.total += kb::leaf_sizes_for(opt.leaf_sizes, in.mesh.triangle_count()).size() * intersectors.size() *
                              kdrt_variants.size() +
                          peer_qualities.size();
    const std::string repetitions = opt.repeat > 1 ? ", " + std::to_string(opt.repeat) + " times" : "";
    // The progress lines name each build's kernel when --kernel asks for more than the default.
    const bool kernels_named = opt.kernels != std::vector<std::string>{"default"};

    std::string write_error;
    const auto write_failed = [&] {
        progress.note("kdrt-bench: " + write_error);
        return 1;
    };
    if (!csv.line(kb::csv_header(), write_error)) return write_failed();
    common::ThreadScheduler build_pool(opt.build_threads);
    const uint32_t seed = 1;
    for (const Input &in : inputs) {
        const kb::Scene scene = kb::make_scene(in.mesh, in.label);
        const kdrt_triangles view = scene.geometry.view();
        kdrt_tree *scout = nullptr;  // for the diffuse rays' primary hits and the random rays' box
        kdrt_build_report report;
        kdrt_result r = kdrt_tree_build(&view, nullptr, &scout, &report);
        if (r != KDRT_SUCCESS) {
            progress.note("kdrt-bench: skipping " + in.label + ": " + kdrt_result_string(r) +
                          (report.invalid_triangle != KDRT_INVALID_ID ? " (triangle " + std::to_string(report.invalid_triangle) + ")" : ""));
            ++failures;
            continue;
        }
        std::vector<uint32_t> pixels;
        std::vector<kdrt_ray> rays = kb::make_rays(scene, opt.rays, opt.width, opt.height, scout, seed, &pixels);
        kdrt_tree_free(scout);
        {  // in tiles, or shuffled, as --batch, --tile and --shuffle say (the pixel order by default)
            const std::vector<size_t> order =
                kb::ray_order(pixels, opt.width, opt.tile_width, opt.tile_height, opt.shuffle, seed);
            std::vector<kdrt_ray> ordered;
            ordered.reserve(rays.size());
            for (size_t i : order) ordered.push_back(rays[i]);
            rays.swap(ordered);
        }

        // The reference for a fixed sample of the rays, computed once for every row of this mesh.
        const oracle::Oracle oracle(scene.geometry);
        const std::vector<size_t> sample = kb::reference_sample(rays.size(), opt.reference_rays, seed);
        progress.status(in.label + ": " + std::to_string(scene.geometry.triangle_count()) + " triangles, " +
                        kb::frame_rays(opt, opt.rays) + ": the reference answers of " + std::to_string(sample.size()) +
                        " of them");
        std::vector<kdrt_ray> sampled;
        for (size_t i : sample) sampled.push_back(rays[i]);
        const std::vector<oracle::Reference> refs = oracle::reference_all(oracle, sampled);

        kb::Row row;
        row.mesh = in.label;
        row.triangles = scene.geometry.triangle_count();
        row.rays = rays.size();
        row.reference_rays = sample.size();
        const bool shadow = opt.rays == kb::RayKind::shadow;  // any hit: kdrt_occluded
        Answers single_answers, batch_answers;
        for (const kb::BuildVariant &variant : kdrt_variants)
        for (uint32_t leaf : kb::leaf_sizes_for(opt.leaf_sizes, in.mesh.triangle_count()))
            for (kdrt_intersector intersector : intersectors)
                for (unsigned rep = 0; rep < opt.repeat; ++rep) {
                    if (rep == 0)
                        progress.step(in.label + ": " + variant.builder +
                                      (opt.qualities.empty() ? "" : " " + variant.quality) +
                                      (opt.sah_costs.empty() ? "" : " " + variant.sah_costs) +
                                      (kernels_named ? " " + variant.kernel : "") + " leaf " +
                                      std::to_string(leaf) +
                                      (opt.intersectors.empty() ? "" : std::string(" ") + kb::intersector_name(intersector)) +
                                      ": building and tracing " + kb::frame_rays(opt, opt.rays) +
                                      calls_label(kdrt_calls) + repetitions);
                    kdrt_build_options options = variant.options;
                    options.max_leaf_size = leaf;
                    options.intersector = intersector;
                    if (build_pool.threads() > 1) options.scheduler = build_pool.hooks();
                    kdrt_tree *tree = nullptr;
                    common::Stopwatch build_clock;
                    r = kdrt_tree_build(&view, &options, &tree, nullptr);
                    row.build_ms = build_clock.ms();
                    if (r != KDRT_SUCCESS) {
                        progress.note("kdrt-bench: " + in.label + " leaf size " + std::to_string(leaf) + ": " + kdrt_result_string(r));
                        ++failures;
                        continue;
                    }
                    kdrt_tree_get_stats(tree, &row.stats);
                    row.builder = variant.builder;
                    row.sah_costs = variant.sah_costs;
                    row.quality = variant.quality;
                    row.kernel = kb::kernel_name(row.stats.kernel);  // the kernel that runs, as the tree says
                    row.intersector = kb::intersector_name(intersector);
                    row.build_threads = options.builder == KDRT_BUILDER_MEDIAN ? 1 : build_pool.threads();
                    row.max_leaf_size = int(leaf);
                    row.has_tree_stats = true;
                    for (const std::string &start : kb::starts_for(opt)) {
                    // The rays' start cells in this tree, as kdrt_spawn_ray() gives them from its
                    // hits (the cell that holds the origin), or none.
                    for (kdrt_ray &ray : rays) ray.cell = start == "cell" ? kdrt_locate(tree, ray.org) : 0u;
                    for (const std::string &query : opt.queries) {
                        // filter: the _query forms with a filter that takes every hit, the
                        // same answers as the plain queries at the cost of asking.
                        kdrt_query q = kdrt_default_query();
                        q.filter = kb::take_every_hit;
                        const kdrt_query *rules = query == "filter" ? &q : nullptr;
                        bool traced_single = false;
                        for (kb::Call call : kdrt_calls) {
                            Answers &answers = call == kb::Call::batch ? batch_answers : single_answers;
                            row.trace_ms = trace_kdrt(tree, rays, rules, call, opt, answers);
                            traced_single |= call == kb::Call::single;
                            row.query = query;
                            row.start = start;
                            row.call = kb::call_name(call);
                            row.mismatches = shadow ? kb::count_occlusion_mismatches(oracle, refs, sample, rays, answers.occluded, row.triangles)
                                                    : kb::count_mismatches(oracle, refs, sample, rays, answers.hits);
                            if (!csv.line(kb::csv_row(row), write_error)) {
                                kdrt_tree_free(tree);
                                return write_failed();
                            }
                        }
                        if (batched) {  // every run checks the batch against the single calls
                            if (!traced_single) trace_kdrt(tree, rays, rules, kb::Call::single, opt, single_answers);
                            const std::string differences = batch_differences(batch_answers, single_answers, shadow);
                            if (!differences.empty()) {
                                progress.note("kdrt-bench: " + in.label + ": " + variant.builder + " leaf " +
                                              std::to_string(leaf) + ", kernel " + row.kernel + ", start " + start +
                                              ", query " + query + ": " + differences);
                                ++failures;
                            }
                        }
                    }
                    }
                    kdrt_tree_free(tree);
                }
        for (kb::PeerQuality quality : peer_qualities)
            for (unsigned rep = 0; rep < opt.repeat; ++rep) {
                if (rep == 0)
                    progress.step(in.label + ": embree " + kb::peer_quality_name(quality) + ": building and tracing " +
                                  kb::frame_rays(opt, opt.rays) + calls_label(opt.calls) + repetitions);
                std::vector<kb::PeerRun> runs;
                if (!kb::embree_run(scene.geometry, rays, opt, quality, runs, error)) {
                    progress.note("kdrt-bench: " + in.label + ": Embree: " + error);
                    ++failures;
                    break;
                }
                for (const kb::PeerRun &peer : runs) {
                    if (!peer.note.empty() && std::find(peer_notes.begin(), peer_notes.end(), peer.note) == peer_notes.end()) {
                        peer_notes.push_back(peer.note);  // once a run
                        progress.note("kdrt-bench: Embree: " + peer.note);
                    }
                    if (!peer.traced) continue;
                    row.builder = "embree";
                    row.sah_costs.clear();
                    row.quality = kb::peer_quality_name(quality);
                    row.build_threads = build_pool.threads();  // the device's threads, as kdrt's build's
                    row.intersector.clear();  // Embree's own test
                    row.query.clear();
                    row.start.clear();
                    row.kernel.clear();  // Embree's own code: no kdrt kernel
                    row.max_leaf_size = -1;
                    row.has_tree_stats = false;
                    row.call = kb::call_name(peer.call);
                    row.build_ms = peer.build_ms;
                    row.trace_ms = peer.trace_ms;
                    row.mismatches = shadow ? kb::count_occlusion_mismatches(oracle, refs, sample, rays, peer.occluded, row.triangles)
                                            : kb::count_mismatches(oracle, refs, sample, rays, peer.hits);
                    if (!csv.line(kb::csv_row(row), write_error)) return write_failed();
                }
            }
    }
    if (failures) progress.note("kdrt-bench: " + std::to_string(failures) + " input(s) or run(s) failed; see above");
    if (!csv.finish(error)) {
        progress.note("kdrt-bench: " + error);
        return 1;
    }
    return failures ? 1 : 0;
}

}  // namespace

int main(int argc, char **argv) {
    return common::close_stdout("kdrt-bench", run(argc, argv));
}
