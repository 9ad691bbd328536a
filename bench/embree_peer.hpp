// The same rays through Embree 3, the peer kdrt's speed is stated against. Optional: without
// Embree at configure time, embree_available() is false and the bench says so.
#pragma once

#include "bench.hpp"  // Call, Options
#include "kdrt.h"
#include "common/mesh_io.hpp"

#include <memory>
#include <string>
#include <vector>

namespace kb {

struct PeerRun {
    Call call = Call::single;
    double build_ms = 0, trace_ms = 0;
    std::vector<kdrt_hit> hits;  // in kdrt's terms: triangle, t, u, v (KDRT_INVALID_ID on a miss)
    std::vector<unsigned char> occluded;  // with occlusion: 1 where Embree found a hit
    bool traced = true;  // false: Embree refused the call (note says so), and there is no row
    std::string note;    // what the run should say about the call: not native on this CPU, refused
};

bool embree_available();
// Embree's build qualities kdrt-bench compares with: "low" (RTC_BUILD_QUALITY_LOW, a Morton
// build) and "medium" (RTC_BUILD_QUALITY_MEDIUM, binned SAH).
enum class PeerQuality { low, medium };
const char *peer_quality_name(PeerQuality quality);

// Builds at `quality` on a device of opt.build_threads threads (0: all cores), then traces the
// rays once with each of opt.calls in turn on opt.threads threads, a PeerRun each in `runs`
// (sharing the build): single with rtcIntersect1, batch with rtcIntersect1M on opt.batch_size
// rays at a time, packet8 and packet16 with rtcIntersect8 and rtcIntersect16 on consecutive rays
// (every lane valid, the last packet's missing lanes off); shadow rays (opt.rays) with the
// rtcOccluded forms. The batch and packet calls pass RTC_INTERSECT_CONTEXT_FLAG_COHERENT, and
// their rays are laid out in Embree's structures before the clock starts (rtcIntersect1 converts
// each ray as it goes, a few nanoseconds). false with a message if the build fails.
bool embree_run(const common::Mesh &mesh, const std::vector<kdrt_ray> &rays, const Options &opt, PeerQuality quality,
                std::vector<PeerRun> &runs, std::string &error);

struct SceneLayout;

// kdrt-bench --scene's Embree: a scene built once and traced many times, at MEDIUM quality on a
// device of build_threads threads (0: all cores), with rtcIntersect1 on `threads` threads.
class PeerScene {
public:
    PeerScene();
    ~PeerScene();
    PeerScene(const PeerScene &) = delete;
    PeerScene &operator=(const PeerScene &) = delete;

    // One triangle geometry, ID 0.
    bool build_mesh(const kdrt_triangles &mesh, unsigned build_threads, std::string &error);
    // The layout's geometries under their IDs: each instance an RTC_GEOMETRY_TYPE_INSTANCE of its
    // prototype's own RTCScene, placed by rtcSetGeometryTransform (a two-level scene), each mesh
    // geometry a triangle geometry.
    bool build_layout(const SceneLayout &layout, unsigned build_threads, std::string &error);
    double build_ms() const { return build_ms_; }  // the commits of the whole scene
    // As kb::median_commit_ms(): every instance moved (rtcSetGeometryTransform, rtcCommitGeometry),
    // then rtcCommitScene of the top level timed; the median of `times`, the scene as it began.
    double median_commit_ms(const SceneLayout &layout, unsigned times);
    // kdrt's terms: t, u, v, triangle (primID; KDRT_INVALID_ID on a miss), geometry (the instance's
    // ID, else the geometry's), instance (KDRT_INVALID_ID when none). Returns the wall time in ms.
    double trace(const std::vector<kdrt_ray> &rays, unsigned threads, std::vector<kdrt_hit> &hits) const;

private:
    struct State;
    std::unique_ptr<State> state_;
    double build_ms_ = 0;
};

// kdrt-bench --points's Embree: one triangle geometry (MEDIUM, a device of build_threads
// threads) and rtcPointQuery with the closest-point callback of Embree's closest_point
// tutorial: the nearest point of the triangle (Ericson's regions, in float), the query's radius
// shrunk to its distance when nearer.
class PeerPoints {
public:
    PeerPoints();
    ~PeerPoints();
    PeerPoints(const PeerPoints &) = delete;
    PeerPoints &operator=(const PeerPoints &) = delete;

    // Keeps a pointer to mesh, which must outlive the queries.
    bool build(const common::Mesh &mesh, unsigned build_threads, std::string &error);
    // rtcPointQuery from each point (x, y, z each), radius infinite, on one thread: the distance
    // (INFINITY when none) and the triangle of each. The wall time in ms.
    double closest(const std::vector<float> &points, std::vector<float> &distance, std::vector<uint32_t> &triangle) const;

private:
    struct State;
    std::unique_ptr<State> state_;
};

struct FramesWorld;

// kdrt-bench --scene frames's Embree (bench/README.md, "Frames"): the world as kdrt has it, a
// two-level scene on a device of `threads` threads: an RTCScene per prototype (MEDIUM) placed by
// instance geometries, the level's meshes in an RTCScene of their own placed once (MEDIUM), and
// the deforming mesh's own RTCScene, whose one triangle geometry reads the caller's vertex buffer
// (shared, never copied), placed by an instance geometry; every one under its kdrt geometry ID.
class PeerFrames {
public:
    PeerFrames();
    ~PeerFrames();
    PeerFrames(const PeerFrames &) = delete;
    PeerFrames &operator=(const PeerFrames &) = delete;

    // deformed: the deforming mesh's vertices (deformed_positions()' layout), which the caller
    // rewrites between frames and keeps alive; transforms: every instance's, 12 floats each.
    bool build(const FramesWorld &world, const std::vector<float> &deformed, const std::vector<float> &transforms,
               unsigned threads, std::string &error);
    // The build quality of the deforming mesh's scene and of the top level from now on.
    void set_quality(PeerQuality quality);
    // The deforming mesh rebuilt from the vertex buffer as it now is: rtcUpdateGeometryBuffer,
    // rtcCommitGeometry, rtcCommitScene of its scene. The wall time in ms.
    double rebuild();
    // Every instance moved (rtcSetGeometryTransform, rtcCommitGeometry; transforms as in build)
    // and the deforming mesh's instance committed again. The wall time in ms.
    double move(const std::vector<float> &transforms);
    // rtcCommitScene of the top level. The wall time in ms.
    double commit();
    // rtcIntersect1 on every ray (hits in PeerScene::trace's terms), rtcOccluded1 on every ray,
    // on `threads` threads. The wall time in ms.
    double trace(const std::vector<kdrt_ray> &rays, unsigned threads, std::vector<kdrt_hit> &hits) const;
    double occluded(const std::vector<kdrt_ray> &rays, unsigned threads, std::vector<unsigned char> &occluded) const;
    bool failed(std::string &error) const;  // an Embree error since the last call

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace kb
