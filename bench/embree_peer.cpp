#include "embree_peer.hpp"
#include "frames.hpp"
#include "scenes.hpp"
#include "common/timing.hpp"

#ifdef KDRT_BENCH_HAVE_EMBREE
#include <embree3/rtcore.h>
#include <algorithm>
#include <cmath>
#include <cstring>
#endif

namespace kb {

const char *peer_quality_name(PeerQuality quality) { return quality == PeerQuality::low ? "low" : "medium"; }

#ifndef KDRT_BENCH_HAVE_EMBREE

bool embree_available() { return false; }

bool embree_run(const common::Mesh &, const std::vector<kdrt_ray> &, const Options &, PeerQuality, std::vector<PeerRun> &,
                std::string &error) {
    error = "this kdrt-bench was built without Embree (install libembree-dev and configure again)";
    return false;
}

struct PeerScene::State {};
PeerScene::PeerScene() = default;
PeerScene::~PeerScene() = default;

bool PeerScene::build_mesh(const kdrt_triangles &, unsigned, std::string &error) {
    error = "this kdrt-bench was built without Embree (install libembree-dev and configure again)";
    return false;
}

bool PeerScene::build_layout(const SceneLayout &, unsigned, std::string &error) {
    return build_mesh(kdrt_triangles{}, 0, error);
}

static bool build_mesh_unavailable(std::string &error) {
    error = "this kdrt-bench was built without Embree (install libembree-dev and configure again)";
    return false;
}

double PeerScene::median_commit_ms(const SceneLayout &, unsigned) { return 0; }

double PeerScene::trace(const std::vector<kdrt_ray> &, unsigned, std::vector<kdrt_hit> &) const { return 0; }

struct PeerPoints::State {};
PeerPoints::PeerPoints() = default;
PeerPoints::~PeerPoints() = default;
bool PeerPoints::build(const common::Mesh &, unsigned, std::string &error) { return build_mesh_unavailable(error); }
double PeerPoints::closest(const std::vector<float> &, std::vector<float> &, std::vector<uint32_t> &) const { return 0; }

struct PeerFrames::State {};
PeerFrames::PeerFrames() = default;
PeerFrames::~PeerFrames() = default;
bool PeerFrames::build(const FramesWorld &, const std::vector<float> &, const std::vector<float> &, unsigned,
                       std::string &error) {
    return build_mesh_unavailable(error);
}
void PeerFrames::set_quality(PeerQuality) {}
double PeerFrames::rebuild() { return 0; }
double PeerFrames::move(const std::vector<float> &) { return 0; }
double PeerFrames::commit() { return 0; }
double PeerFrames::trace(const std::vector<kdrt_ray> &, unsigned, std::vector<kdrt_hit> &) const { return 0; }
double PeerFrames::occluded(const std::vector<kdrt_ray> &, unsigned, std::vector<unsigned char> &) const { return 0; }
bool PeerFrames::failed(std::string &) const { return false; }

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

// The ray with no hit yet, as rtcIntersect* want it.
static RTCRayHit rtc_ray_hit(const kdrt_ray &ray) {
    RTCRayHit rh;
    rh.ray = rtc_ray(ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

// Embree's answer in kdrt's terms (see PeerScene::trace).
static kdrt_hit kdrt_answer(const RTCRayHit &rh) {
    kdrt_hit h;
    const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    const bool instanced = hit && rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID;
    h.triangle = hit ? rh.hit.primID : KDRT_INVALID_ID;
    h.t = rh.ray.tfar, h.u = rh.hit.u, h.v = rh.hit.v;
    h.geometry = instanced ? rh.hit.instID[0] : hit ? rh.hit.geomID : 0;
    h.instance = instanced ? rh.hit.instID[0] : KDRT_INVALID_ID;
    h.cell = 0;
    return h;
}

// rtcIntersect1's answer for the ray, in kdrt's terms.
static kdrt_hit intersect(RTCScene scene, const kdrt_ray &ray) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh = rtc_ray_hit(ray);
    rtcIntersect1(scene, &context, &rh);
    return kdrt_answer(rh);
}

// The context of the batch and packet calls: the rays come in tiles or spawned in their primary
// rays' order, so the caller says they are coherent (Embree's fast coherent paths; a hint only).
static RTCIntersectContext coherent_context() {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    return context;
}

// rtcIntersect1 / rtcOccluded1, a call a ray.
static double trace_single(RTCScene scene, const std::vector<kdrt_ray> &rays, unsigned threads, bool occlusion, PeerRun &out) {
    if (occlusion)
        return common::timed_parallel(rays.size(), threads, [&](size_t i) {
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            RTCRay ray = rtc_ray(rays[i]);
            rtcOccluded1(scene, &context, &ray);
            out.occluded[i] = ray.tfar < 0;  // rtcOccluded1 sets tfar to -inf on a hit
        });
    return common::timed_parallel(rays.size(), threads, [&](size_t i) { out.hits[i] = intersect(scene, rays[i]); });
}

// rtcIntersect1M / rtcOccluded1M on batch_size consecutive rays at a time (the rays of a chunk
// on one thread), from arrays filled before the clock starts.
static double trace_stream(RTCScene scene, const std::vector<kdrt_ray> &rays, unsigned threads, bool occlusion,
                           uint32_t batch_size, PeerRun &out) {
    const size_t chunks = (rays.size() + batch_size - 1) / batch_size;
    const auto chunk_size = [&](size_t c) { return unsigned(std::min<size_t>(batch_size, rays.size() - c * batch_size)); };
    if (occlusion) {
        std::vector<RTCRay> stream(rays.size());
        for (size_t i = 0; i < rays.size(); ++i) stream[i] = rtc_ray(rays[i]);
        const double ms = common::timed_parallel(chunks, threads, [&](size_t c) {
            RTCIntersectContext context = coherent_context();
            rtcOccluded1M(scene, &context, &stream[c * batch_size], chunk_size(c), sizeof(RTCRay));
        });
        for (size_t i = 0; i < rays.size(); ++i) out.occluded[i] = stream[i].tfar < 0;
        return ms;
    }
    std::vector<RTCRayHit> stream(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) stream[i] = rtc_ray_hit(rays[i]);
    const double ms = common::timed_parallel(chunks, threads, [&](size_t c) {
        RTCIntersectContext context = coherent_context();
        rtcIntersect1M(scene, &context, &stream[c * batch_size], chunk_size(c), sizeof(RTCRayHit));
    });
    for (size_t i = 0; i < rays.size(); ++i) out.hits[i] = kdrt_answer(stream[i]);
    return ms;
}

// The packet calls, by width: Embree's SoA structures and its calls on them.
template <int K> struct Packet;
template <> struct Packet<8> {
    using Rays = RTCRay8;
    using RayHits = RTCRayHit8;
    static void intersect(const int *valid, RTCScene s, RTCIntersectContext *c, RayHits *p) { rtcIntersect8(valid, s, c, p); }
    static void occluded(const int *valid, RTCScene s, RTCIntersectContext *c, Rays *p) { rtcOccluded8(valid, s, c, p); }
};
template <> struct Packet<16> {
    using Rays = RTCRay16;
    using RayHits = RTCRayHit16;
    static void intersect(const int *valid, RTCScene s, RTCIntersectContext *c, RayHits *p) { rtcIntersect16(valid, s, c, p); }
    static void occluded(const int *valid, RTCScene s, RTCIntersectContext *c, Rays *p) { rtcOccluded16(valid, s, c, p); }
};

// Lane `lane` of a ray packet (RTCRay8 or RTCRay16) set to the ray.
template <typename Rays> static void set_lane(Rays &p, int lane, const kdrt_ray &r) {
    p.org_x[lane] = r.org[0], p.org_y[lane] = r.org[1], p.org_z[lane] = r.org[2];
    p.dir_x[lane] = r.dir[0], p.dir_y[lane] = r.dir[1], p.dir_z[lane] = r.dir[2];
    p.tnear[lane] = r.tmin, p.tfar[lane] = r.tmax, p.time[lane] = 0;
    p.mask[lane] = ~0u, p.id[lane] = 0, p.flags[lane] = 0;
}

// rtcIntersectK / rtcOccludedK on each K consecutive rays, from packets filled before the clock
// starts. Embree reads the valid masks with aligned loads: one 64-byte line each.
template <int K>
static double trace_packets(RTCScene scene, const std::vector<kdrt_ray> &rays, unsigned threads, bool occlusion, PeerRun &out) {
    struct alignas(64) Valid { int lane[16]; };
    const size_t packets = (rays.size() + K - 1) / K;
    std::vector<Valid> valid(packets);
    for (size_t p = 0; p < packets; ++p)
        for (int k = 0; k < K; ++k) valid[p].lane[k] = p * K + k < rays.size() ? -1 : 0;
    if (occlusion) {
        std::vector<typename Packet<K>::Rays> soa(packets);
        for (size_t i = 0; i < rays.size(); ++i) set_lane(soa[i / K], int(i % K), rays[i]);
        const double ms = common::timed_parallel(packets, threads, [&](size_t p) {
            RTCIntersectContext context = coherent_context();
            Packet<K>::occluded(valid[p].lane, scene, &context, &soa[p]);
        });
        for (size_t i = 0; i < rays.size(); ++i) out.occluded[i] = soa[i / K].tfar[i % K] < 0;
        return ms;
    }
    std::vector<typename Packet<K>::RayHits> soa(packets);
    for (size_t i = 0; i < rays.size(); ++i) {
        const size_t p = i / K;
        const int k = int(i % K);
        set_lane(soa[p].ray, k, rays[i]);
        soa[p].hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        soa[p].hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    const double ms = common::timed_parallel(packets, threads, [&](size_t p) {
        RTCIntersectContext context = coherent_context();
        Packet<K>::intersect(valid[p].lane, scene, &context, &soa[p]);
    });
    for (size_t i = 0; i < rays.size(); ++i) {  // each lane back as a single ray's answer
        const auto &packet = soa[i / K];
        const size_t k = i % K;
        RTCRayHit rh;
        rh.ray.tfar = packet.ray.tfar[k];
        rh.hit.u = packet.hit.u[k], rh.hit.v = packet.hit.v[k];
        rh.hit.primID = packet.hit.primID[k], rh.hit.geomID = packet.hit.geomID[k];
        rh.hit.instID[0] = packet.hit.instID[0][k];
        out.hits[i] = kdrt_answer(rh);
    }
    return ms;
}

// What the run should say about a packet width this CPU (or this Embree) lacks natively; Embree
// then splits each packet into narrower ones (rtcIntersect16 as two 8-wide packets on AVX2).
static std::string packet_note(RTCDevice device, Call call, bool occlusion) {
    const bool sixteen = call == Call::packet16;
    const RTCDeviceProperty native = sixteen ? RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED : RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED;
    if (rtcGetDeviceProperty(device, native)) return "";
    return std::string(occlusion ? "rtcOccluded" : "rtcIntersect") + (sixteen ? "16" : "8") +
           " is not native on this CPU or Embree build (" + (sixteen ? "no AVX-512" : "no AVX") +
           "): Embree traces each packet as narrower packets, and the " + call_name(call) + " rows measure that";
}

// A triangle geometry holding a copy of mesh (in Embree's own buffers: it reads vertex buffers 16
// bytes at a time, past a packed array's end), committed; NULL if Embree could not allocate.
static RTCGeometry new_triangle_geometry(RTCDevice device, const kdrt_triangles &mesh, RTCBuildQuality quality) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry, quality);
    auto *vertices = static_cast<float *>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                   3 * sizeof(float), mesh.vertex_count));
    auto *indices = static_cast<unsigned *>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                     3 * sizeof(unsigned), mesh.triangle_count));
    if (!vertices || !indices) {
        rtcReleaseGeometry(geometry);
        return nullptr;
    }
    const size_t stride = mesh.position_stride ? mesh.position_stride : 3 * sizeof(float);
    for (uint32_t v = 0; v < mesh.vertex_count; ++v)
        std::memcpy(vertices + 3 * size_t(v), reinterpret_cast<const char *>(mesh.positions) + v * stride, 3 * sizeof(float));
    for (uint32_t t = 0; t < mesh.triangle_count; ++t)
        for (int k = 0; k < 3; ++k) indices[3 * size_t(t) + k] = mesh.indices ? mesh.indices[3 * size_t(t) + k] : 3 * t + k;
    rtcCommitGeometry(geometry);
    return geometry;
}

bool embree_run(const common::Mesh &mesh, const std::vector<kdrt_ray> &rays, const Options &opt, PeerQuality quality,
                std::vector<PeerRun> &runs, std::string &error) {
    // Its build on as many threads as kdrt's ("threads=0": all cores, as --build-threads 0).
    const std::string config = "threads=" + std::to_string(opt.build_threads);
    const RTCBuildQuality rtc_quality = quality == PeerQuality::low ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_MEDIUM;
    RTCDevice device = rtcNewDevice(config.c_str());
    if (!device) {
        error = "rtcNewDevice failed";
        return false;
    }
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, rtc_quality);
    RTCGeometry geometry = new_triangle_geometry(device, mesh.view(), rtc_quality);
    if (!geometry) {
        error = "Embree could not allocate its buffers";
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
        return false;
    }
    rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);

    common::Stopwatch build_clock;
    rtcCommitScene(scene);
    const double build_ms = build_clock.ms();
    if (rtcGetDeviceError(device) != RTC_ERROR_NONE) {
        error = "Embree failed to build the scene";
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
        return false;
    }

    const bool occlusion = opt.rays == RayKind::shadow;
    runs.clear();
    for (Call call : opt.calls) {
        PeerRun out;
        out.call = call;
        out.build_ms = build_ms;
        if (occlusion) out.occluded.assign(rays.size(), 0);
        else out.hits.assign(rays.size(), kdrt_hit{});
        switch (call) {
        case Call::single: out.trace_ms = trace_single(scene, rays, opt.threads, occlusion, out); break;
        case Call::batch: out.trace_ms = trace_stream(scene, rays, opt.threads, occlusion, opt.batch_size, out); break;
        case Call::packet8: out.trace_ms = trace_packets<8>(scene, rays, opt.threads, occlusion, out); break;
        case Call::packet16: out.trace_ms = trace_packets<16>(scene, rays, opt.threads, occlusion, out); break;
        }
        if (call == Call::packet8 || call == Call::packet16) out.note = packet_note(device, call, occlusion);
        const RTCError refused = rtcGetDeviceError(device);  // e.g. an Embree built without packets
        if (refused != RTC_ERROR_NONE) {
            out.traced = false;
            out.note = std::string("Embree refused the ") + call_name(call) + " calls (RTCError " +
                       std::to_string(int(refused)) + "): no " + call_name(call) + " row";
        }
        runs.push_back(std::move(out));
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    return true;
}

struct PeerScene::State {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;              // what the rays are traced through
    std::vector<RTCScene> prototypes;      // build_layout: a scene per prototype
    std::vector<RTCGeometry> instances;    // build_layout: kept to be moved
    ~State() {
        for (RTCGeometry g : instances) rtcReleaseGeometry(g);
        if (scene) rtcReleaseScene(scene);
        for (RTCScene s : prototypes) rtcReleaseScene(s);
        if (device) rtcReleaseDevice(device);
    }
    bool start(unsigned build_threads, std::string &error) {
        const std::string config = "threads=" + std::to_string(build_threads);
        device = rtcNewDevice(config.c_str());
        if (!device) error = "rtcNewDevice failed";
        return device != nullptr;
    }
    RTCScene new_scene() {
        RTCScene s = rtcNewScene(device);
        rtcSetSceneBuildQuality(s, RTC_BUILD_QUALITY_MEDIUM);
        return s;
    }
    // Attaches a triangle geometry of mesh to s under id; false when Embree could not allocate.
    bool attach_mesh(RTCScene s, const kdrt_triangles &mesh, uint32_t id, std::string &error) {
        RTCGeometry g = new_triangle_geometry(device, mesh, RTC_BUILD_QUALITY_MEDIUM);
        if (!g) {
            error = "Embree could not allocate its buffers";
            return false;
        }
        rtcAttachGeometryByID(s, g, id);
        rtcReleaseGeometry(g);
        return true;
    }
    bool failed(std::string &error) const {
        if (rtcGetDeviceError(device) == RTC_ERROR_NONE) return false;
        error = "Embree failed to build the scene";
        return true;
    }
};

PeerScene::PeerScene() : state_(new State) {}
PeerScene::~PeerScene() = default;

bool PeerScene::build_mesh(const kdrt_triangles &mesh, unsigned build_threads, std::string &error) {
    state_.reset(new State);
    if (!state_->start(build_threads, error)) return false;
    state_->scene = state_->new_scene();
    if (!state_->attach_mesh(state_->scene, mesh, 0, error)) return false;
    common::Stopwatch clock;
    rtcCommitScene(state_->scene);
    build_ms_ = clock.ms();
    return !state_->failed(error);
}

bool PeerScene::build_layout(const SceneLayout &layout, unsigned build_threads, std::string &error) {
    state_.reset(new State);
    State &s = *state_;
    if (!s.start(build_threads, error)) return false;
    for (const common::Mesh &mesh : layout.prototypes) {
        s.prototypes.push_back(s.new_scene());
        if (!s.attach_mesh(s.prototypes.back(), mesh.view(), 0, error)) return false;
    }
    s.scene = s.new_scene();
    for (uint32_t id = 0; id < layout.first.size(); ++id) {
        if (id >= layout.instances.size()) {
            if (!s.attach_mesh(s.scene, geometry_view(layout, id), id, error)) return false;
            continue;
        }
        RTCGeometry g = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, s.prototypes[layout.instances[id].prototype]);
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, layout.instances[id].transform);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(s.scene, g, id);
        s.instances.push_back(g);
    }
    common::Stopwatch clock;
    for (RTCScene prototype : s.prototypes) rtcCommitScene(prototype);
    rtcCommitScene(s.scene);
    build_ms_ = clock.ms();
    return !s.failed(error);
}

double PeerScene::median_commit_ms(const SceneLayout &layout, unsigned times) {
    std::vector<double> ms;
    for (unsigned k = 0; k <= times; ++k) {
        const bool last = k == times;  // untimed: back where it began, as kb::median_commit_ms
        if (last && times % 2 == 0) break;
        for (size_t id = 0; id < state_->instances.size(); ++id) {
            float moved[12];
            std::memcpy(moved, layout.instances[id].transform, sizeof moved);
            if (k % 2 == 0) moved[3] += 0.01f;
            rtcSetGeometryTransform(state_->instances[id], 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, moved);
            rtcCommitGeometry(state_->instances[id]);
        }
        common::Stopwatch clock;
        rtcCommitScene(state_->scene);
        if (!last) ms.push_back(clock.ms());
    }
    return median(ms);
}

double PeerScene::trace(const std::vector<kdrt_ray> &rays, unsigned threads, std::vector<kdrt_hit> &hits) const {
    hits.resize(rays.size());
    RTCScene scene = state_->scene;
    return common::timed_parallel(rays.size(), threads, [&](size_t i) { hits[i] = intersect(scene, rays[i]); });
}

struct PeerPoints::State {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    const common::Mesh *mesh = nullptr;
    ~State() {
        if (scene) rtcReleaseScene(scene);
        if (device) rtcReleaseDevice(device);
    }
};

PeerPoints::PeerPoints() : state_(new State) {}
PeerPoints::~PeerPoints() = default;

bool PeerPoints::build(const common::Mesh &mesh, unsigned build_threads, std::string &error) {
    state_.reset(new State);
    State &s = *state_;
    s.mesh = &mesh;
    const std::string config = "threads=" + std::to_string(build_threads);
    s.device = rtcNewDevice(config.c_str());
    if (!s.device) {
        error = "rtcNewDevice failed";
        return false;
    }
    s.scene = rtcNewScene(s.device);
    rtcSetSceneBuildQuality(s.scene, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry g = new_triangle_geometry(s.device, mesh.view(), RTC_BUILD_QUALITY_MEDIUM);
    if (!g) {
        error = "Embree could not allocate its buffers";
        return false;
    }
    rtcAttachGeometryByID(s.scene, g, 0);
    rtcReleaseGeometry(g);
    rtcCommitScene(s.scene);
    if (rtcGetDeviceError(s.device) != RTC_ERROR_NONE) {
        error = "Embree failed to build the scene";
        return false;
    }
    return true;
}

namespace {

struct P3 {
    float x, y, z;
};
inline P3 operator-(P3 a, P3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline P3 operator+(P3 a, P3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline P3 operator*(float s, P3 a) { return {s * a.x, s * a.y, s * a.z}; }
inline float dot(P3 a, P3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// The closest_point tutorial's closestPointTriangle (Ericson, Real-Time Collision Detection
// 5.1.5), in float as there.
P3 closest_point_triangle(P3 p, P3 a, P3 b, P3 c) {
    const P3 ab = b - a, ac = c - a, ap = p - a;
    const float d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.f && d2 <= 0.f) return a;
    const P3 bp = p - b;
    const float d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.f && d4 <= d3) return b;
    const float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.f && d1 >= 0.f && d3 <= 0.f) return a + (d1 / (d1 - d3)) * ab;
    const P3 cp = p - c;
    const float d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.f && d5 <= d6) return c;
    const float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.f && d2 >= 0.f && d6 <= 0.f) return a + (d2 / (d2 - d6)) * ac;
    const float va = d3 * d6 - d5 * d4;
    if (va <= 0.f && (d4 - d3) >= 0.f && (d5 - d6) >= 0.f) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
    const float denom = 1.f / (va + vb + vc), v = vb * denom, w = vc * denom;
    return a + v * ab + w * ac;
}

struct PointResult {
    const common::Mesh *mesh;
    float distance;
    uint32_t triangle;
};

// The tutorial's closestPointFunc, without instances (one level): the nearest point of the
// triangle, and the query's radius shrunk to its distance when it is nearer.
bool closest_point_func(RTCPointQueryFunctionArguments *args) {
    PointResult *result = static_cast<PointResult *>(args->userPtr);
    const common::Mesh &m = *result->mesh;
    const float *v = m.positions.data();
    const uint32_t t = args->primID;
    const uint32_t i0 = m.vertex(t, 0), i1 = m.vertex(t, 1), i2 = m.vertex(t, 2);
    const P3 a{v[3 * i0], v[3 * i0 + 1], v[3 * i0 + 2]}, b{v[3 * i1], v[3 * i1 + 1], v[3 * i1 + 2]},
        c{v[3 * i2], v[3 * i2 + 1], v[3 * i2 + 2]};
    const P3 q{args->query->x, args->query->y, args->query->z};
    const P3 d = q - closest_point_triangle(q, a, b, c);
    const float distance = std::sqrt(dot(d, d));
    if (distance < args->query->radius) {
        args->query->radius = distance;
        result->distance = distance;
        result->triangle = t;
        return true;  // the radius changed
    }
    return false;
}

}  // namespace

double PeerPoints::closest(const std::vector<float> &points, std::vector<float> &distance,
                           std::vector<uint32_t> &triangle) const {
    const size_t n = points.size() / 3;
    distance.assign(n, INFINITY);
    triangle.assign(n, KDRT_INVALID_ID);
    RTCScene scene = state_->scene;
    const common::Mesh *mesh = state_->mesh;
    return common::timed_parallel(n, 1, [&](size_t i) {
        RTCPointQuery query;
        query.x = points[3 * i], query.y = points[3 * i + 1], query.z = points[3 * i + 2];
        query.time = 0.f, query.radius = INFINITY;
        RTCPointQueryContext context;
        rtcInitPointQueryContext(&context);
        PointResult result{mesh, INFINITY, KDRT_INVALID_ID};
        rtcPointQuery(scene, &query, &context, closest_point_func, &result);
        distance[i] = result.distance, triangle[i] = result.triangle;
    });
}

struct PeerFrames::State {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;              // the top level
    std::vector<RTCScene> prototypes;      // a scene per prototype
    std::vector<RTCGeometry> instances;    // kept to be moved
    RTCScene deforming_scene = nullptr;
    RTCGeometry deforming = nullptr;       // its triangle geometry, on the caller's vertex buffer
    RTCGeometry deforming_instance = nullptr;
    RTCScene level_scene = nullptr;        // the level's meshes under their IDs
    unsigned level_instance = 0;           // the ID of its instance in the top level
    ~State() {
        for (RTCGeometry g : instances) rtcReleaseGeometry(g);
        if (deforming) rtcReleaseGeometry(deforming);
        if (deforming_instance) rtcReleaseGeometry(deforming_instance);
        if (scene) rtcReleaseScene(scene);
        if (deforming_scene) rtcReleaseScene(deforming_scene);
        if (level_scene) rtcReleaseScene(level_scene);
        for (RTCScene s : prototypes) rtcReleaseScene(s);
        if (device) rtcReleaseDevice(device);
    }
};

PeerFrames::PeerFrames() : state_(new State) {}
PeerFrames::~PeerFrames() = default;

bool PeerFrames::build(const FramesWorld &world, const std::vector<float> &deformed, const std::vector<float> &transforms,
                       unsigned threads, std::string &error) {
    state_.reset(new State);
    State &s = *state_;
    const std::string config = "threads=" + std::to_string(threads);
    s.device = rtcNewDevice(config.c_str());
    if (!s.device) {
        error = "rtcNewDevice failed";
        return false;
    }
    const auto new_scene = [&] {
        RTCScene scene = rtcNewScene(s.device);
        rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
        return scene;
    };
    const auto attach_mesh = [&](RTCScene scene, const kdrt_triangles &mesh, uint32_t id) {
        RTCGeometry g = new_triangle_geometry(s.device, mesh, RTC_BUILD_QUALITY_MEDIUM);
        if (!g) {
            error = "Embree could not allocate its buffers";
            return false;
        }
        rtcAttachGeometryByID(scene, g, id);
        rtcReleaseGeometry(g);
        return true;
    };
    for (const common::Mesh &mesh : world.prototypes) {
        s.prototypes.push_back(new_scene());
        if (!attach_mesh(s.prototypes.back(), mesh.view(), 0)) return false;
        rtcCommitScene(s.prototypes.back());
    }
    s.scene = new_scene();
    for (uint32_t id = 0; id < world.movers.size(); ++id) {
        RTCGeometry g = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, s.prototypes[world.movers[id].prototype]);
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &transforms[12 * size_t(id)]);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(s.scene, g, id);
        s.instances.push_back(g);
    }
    // The level, static: a scene of its own placed once, as Embree advises for what does not
    // move, so that the top level's commit rebuilds only the BVH over the instances (a scene's
    // commit rebuilds the BVH over its triangle geometries too when they sit beside the
    // instances: 130 ms a frame for this level at MEDIUM).
    s.level_scene = new_scene();
    for (uint32_t k = 0; k < world.level.size(); ++k)
        if (!attach_mesh(s.level_scene, world.level[k].view(), world.level_id(k))) return false;
    rtcCommitScene(s.level_scene);
    s.level_instance = world.deforming_id() + 1;
    RTCGeometry level = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(level, s.level_scene);
    rtcCommitGeometry(level);  // the identity transform
    rtcAttachGeometryByID(s.scene, level, s.level_instance);
    rtcReleaseGeometry(level);

    // The deforming mesh: its vertices the caller's buffer, its indices copied once.
    const common::Mesh &mesh = world.deforming;
    s.deforming_scene = new_scene();
    s.deforming = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(s.deforming, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, deformed.data(), 0,
                               3 * sizeof(float), mesh.vertex_count());
    auto *indices = static_cast<unsigned *>(rtcSetNewGeometryBuffer(s.deforming, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                     3 * sizeof(unsigned), mesh.triangle_count()));
    if (!indices) {
        error = "Embree could not allocate its buffers";
        return false;
    }
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t)
        for (int k = 0; k < 3; ++k) indices[3 * size_t(t) + k] = mesh.vertex(t, k);
    rtcCommitGeometry(s.deforming);
    rtcAttachGeometryByID(s.deforming_scene, s.deforming, 0);
    rtcCommitScene(s.deforming_scene);
    s.deforming_instance = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(s.deforming_instance, s.deforming_scene);
    rtcSetGeometryTransform(s.deforming_instance, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, world.deforming_transform);
    rtcCommitGeometry(s.deforming_instance);
    rtcAttachGeometryByID(s.scene, s.deforming_instance, world.deforming_id());
    rtcCommitScene(s.scene);
    return !failed(error);
}

void PeerFrames::set_quality(PeerQuality quality) {
    const RTCBuildQuality q = quality == PeerQuality::low ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_MEDIUM;
    rtcSetGeometryBuildQuality(state_->deforming, q);
    rtcSetSceneBuildQuality(state_->deforming_scene, q);
    rtcSetSceneBuildQuality(state_->scene, q);
}

double PeerFrames::rebuild() {
    common::Stopwatch clock;
    rtcUpdateGeometryBuffer(state_->deforming, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(state_->deforming);
    rtcCommitScene(state_->deforming_scene);
    return clock.ms();
}

double PeerFrames::move(const std::vector<float> &transforms) {
    common::Stopwatch clock;
    for (size_t id = 0; id < state_->instances.size(); ++id) {
        rtcSetGeometryTransform(state_->instances[id], 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &transforms[12 * id]);
        rtcCommitGeometry(state_->instances[id]);
    }
    rtcCommitGeometry(state_->deforming_instance);  // its scene changed: as kdrt's detach and attach
    return clock.ms();
}

double PeerFrames::commit() {
    common::Stopwatch clock;
    rtcCommitScene(state_->scene);
    return clock.ms();
}

double PeerFrames::trace(const std::vector<kdrt_ray> &rays, unsigned threads, std::vector<kdrt_hit> &hits) const {
    hits.resize(rays.size());
    RTCScene scene = state_->scene;
    const unsigned level = state_->level_instance;
    return common::timed_parallel(rays.size(), threads, [&](size_t i) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        RTCRayHit rh = rtc_ray_hit(rays[i]);
        rtcIntersect1(scene, &context, &rh);
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID && rh.hit.instID[0] == level)
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;  // a level mesh, under its own ID as in kdrt's scene
        hits[i] = kdrt_answer(rh);
    });
}

double PeerFrames::occluded(const std::vector<kdrt_ray> &rays, unsigned threads, std::vector<unsigned char> &occluded) const {
    occluded.resize(rays.size());
    RTCScene scene = state_->scene;
    return common::timed_parallel(rays.size(), threads, [&](size_t i) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        RTCRay ray = rtc_ray(rays[i]);
        rtcOccluded1(scene, &context, &ray);
        occluded[i] = ray.tfar < 0;  // rtcOccluded1 sets tfar to -inf on a hit
    });
}

bool PeerFrames::failed(std::string &error) const {
    const RTCError e = rtcGetDeviceError(state_->device);
    if (e == RTC_ERROR_NONE) return false;
    error = "Embree failed (RTCError " + std::to_string(int(e)) + ")";
    return true;
}

#endif

}  // namespace kb
