#include "embree_peer.hpp"
#include "common/timing.hpp"

#ifdef KDRT_BENCH_HAVE_EMBREE
#include <embree3/rtcore.h>
#include <cstring>
#endif

namespace kb {

const char *peer_quality_name(PeerQuality quality) { return quality == PeerQuality::low ? "low" : "medium"; }

#ifndef KDRT_BENCH_HAVE_EMBREE

bool embree_available() { return false; }

bool embree_run(const common::Mesh &, const std::vector<kdrt_ray> &, unsigned, bool, PeerQuality, unsigned, PeerRun &,
                std::string &error) {
    error = "this kdrt-bench was built without Embree (install libembree-dev and configure again)";
    return false;
}

#else

bool embree_available() { return true; }

// kdrt's ray in Embree's terms.
static RTCRay rtc_ray(const kdrt_ray &r) {
    RTCRay ray;
    ray.org_x = r.org[0], ray.org_y = r.org[1], ray.org_z = r.org[2];
    ray.dir_x = r.dir[0], ray.dir_y = r.dir[1], ray.dir_z = r.dir[2];
    ray.tnear = r.tmin, ray.tfar = r.tmax, ray.time = 0, ray.mask = ~0u, ray.id = 0, ray.flags = 0;
    return ray;
}

bool embree_run(const common::Mesh &mesh, const std::vector<kdrt_ray> &rays, unsigned threads, bool occlusion,
                PeerQuality quality, unsigned build_threads, PeerRun &out, std::string &error) {
    // Its build on as many threads as kdrt's ("threads=0": all cores, as --build-threads 0).
    const std::string config = "threads=" + std::to_string(build_threads);
    const RTCBuildQuality rtc_quality = quality == PeerQuality::low ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_MEDIUM;
    RTCDevice device = rtcNewDevice(config.c_str());
    if (!device) {
        error = "rtcNewDevice failed";
        return false;
    }
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, rtc_quality);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry, rtc_quality);
    // Embree's own buffers (it reads vertex buffers 16 bytes at a time, past a packed array's end).
    auto *vertices = static_cast<float *>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                   3 * sizeof(float), mesh.vertex_count()));
    auto *indices = static_cast<unsigned *>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                     3 * sizeof(unsigned), mesh.triangle_count()));
    if (!vertices || !indices) {
        error = "Embree could not allocate its buffers";
        rtcReleaseGeometry(geometry);
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
        return false;
    }
    std::memcpy(vertices, mesh.positions.data(), mesh.positions.size() * sizeof(float));
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t)
        for (int k = 0; k < 3; ++k) indices[3 * t + k] = mesh.indices.empty() ? 3 * t + k : mesh.indices[3 * size_t(t) + k];
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);

    common::Stopwatch build_clock;
    rtcCommitScene(scene);
    out.build_ms = build_clock.ms();
    if (rtcGetDeviceError(device) != RTC_ERROR_NONE) {
        error = "Embree failed to build the scene";
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
        return false;
    }

    if (occlusion) {
        out.occluded.assign(rays.size(), 0);
        out.trace_ms = common::timed_parallel(rays.size(), threads, [&](size_t i) {
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            RTCRay ray = rtc_ray(rays[i]);
            rtcOccluded1(scene, &context, &ray);
            out.occluded[i] = ray.tfar < 0;  // rtcOccluded1 sets tfar to -inf on a hit
        });
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
        return true;
    }
    out.hits.assign(rays.size(), kdrt_hit{});
    out.trace_ms = common::timed_parallel(rays.size(), threads, [&](size_t i) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        RTCRayHit rh;
        rh.ray = rtc_ray(rays[i]);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &context, &rh);
        kdrt_hit &h = out.hits[i];
        bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        h.triangle = hit ? rh.hit.primID : KDRT_INVALID_ID;
        h.t = rh.ray.tfar, h.u = rh.hit.u, h.v = rh.hit.v;
    });
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    return true;
}

#endif

}  // namespace kb
