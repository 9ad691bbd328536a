// The same rays through Embree 3, the peer kdrt's speed is stated against. Optional: without
// Embree at configure time, embree_available() is false and the bench says so.
#pragma once

#include "kdrt.h"
#include "common/mesh_io.hpp"

#include <string>
#include <vector>

namespace kb {

struct PeerRun {
    double build_ms = 0, trace_ms = 0;
    std::vector<kdrt_hit> hits;  // in kdrt's terms: triangle, t, u, v (KDRT_INVALID_ID on a miss)
    std::vector<unsigned char> occluded;  // with occlusion: 1 where rtcOccluded1 found a hit
};

bool embree_available();
// Embree's build qualities kdrt-bench compares with: "low" (RTC_BUILD_QUALITY_LOW, a Morton
// build) and "medium" (RTC_BUILD_QUALITY_MEDIUM, binned SAH).
enum class PeerQuality { low, medium };
const char *peer_quality_name(PeerQuality quality);

// Builds at `quality` on a device of build_threads threads (0: all cores), then traces with
// rtcIntersect1 (or, with occlusion, rtcOccluded1) on `threads` threads. false with a message if
// Embree fails.
bool embree_run(const common::Mesh &mesh, const std::vector<kdrt_ray> &rays, unsigned threads, bool occlusion,
                PeerQuality quality, unsigned build_threads, PeerRun &out, std::string &error);

}  // namespace kb
