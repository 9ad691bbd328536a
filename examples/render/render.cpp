// kdrt-render's tracer: a pinhole camera, Phong direct lighting with hard or soft shadows,
// mirrors, glass through kdrt's nested-media stack, the meshes in one kdrt scene (a mesh geometry
// each, its ID the mesh's index), small tiles of pixels on threads. A tile's camera rays are
// traced together (kdrt_scene_intersect_batch), and so are the shadow rays of their Phong hits
// (kdrt_scene_occluded_batch, a call per light); mirror and glass paths go on a ray at a time,
// through the same functions with batches of one.
//
// Geometry is double precision except where kdrt works in floats: mesh hits, the optics functions
// (kdrt_reflect, kdrt_refract, kdrt_fresnel_dielectric) and every secondary ray's origin, which
// kdrt_scene_spawn_ray (meshes) or kdrt_offset_ray_origin (spheres, quads: the same rule) moves
// off the surface it leaves. No fixed epsilon anywhere.
#include "kdrt.h"

#include "render.hpp"
#include "common/random.hpp"
#include "common/saved_tree.hpp"
#include "common/thread_scheduler.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>

namespace kr {
namespace {

const double kPi = 3.14159265358979323846;
const double kInf = std::numeric_limits<double>::infinity();

// Per-pixel random numbers: the stream of a hash of (seed, frame, pixel index), so a pixel's
// samples do not depend on which thread renders it or when.
common::Rng pixel_rng(uint64_t seed, uint64_t frame, uint64_t pixel)
{
    using common::splitmix64;
    return common::Rng::from_state(splitmix64(seed ^ splitmix64(frame ^ splitmix64(pixel))));
}
using common::Rng;

struct Ray {
    Vec3 origin, dir;  // dir unit length
    uint32_t cell = 0; // where its walk starts in the scene's mesh tree (kdrt.h, START CELLS); 0: the root
};

// Rays traced by this thread (every intersect and occluded call), for kdrt-view's MRays/s.
thread_local uint64_t t_rays = 0;

enum class HitKind { none, sphere, quad, mesh, light };

struct Hit {
    HitKind kind = HitKind::none;
    double t = kInf;
    int index = -1;          // sphere, quad, mesh or light index
    kdrt_hit mesh_hit{};     // meshes: a hit of the scene, mesh_hit.geometry == index
    Vec3 point;              // on the surface
    Vec3 normal;             // geometric, unit, as the object defines it (outwards for spheres)
    Vec3 shading_normal;     // interpolated on meshes when enabled, else the geometric one
    double u = 0, v = 0;     // texture coordinates
};

// A tile's pixels, row by row, make one batch of camera rays: 4x4, so rays 0-7 and 8-15 are
// blocks of 4x2 pixels, the 8 rays kdrt's packet walk takes together. 4x4 rather than 4x2:
// measured on PICTURE, BENCHMARKS and PHASE_4_KDTREE at 800x600 on 1 and 2 threads (best of 5,
// with the batch calls still ray by ray), 4x4 took the same CPU time or a little less (PICTURE:
// 2.30 s against 2.34 s) and no more wall time, with half the tiles to hand out and two packets
// a batch call.
const uint32_t kTileWidth = 4, kTileHeight = 4, kTileRays = kTileWidth * kTileHeight;

// One pixel of a tile: where it is, its random stream, the sum of its samples.
struct TilePixel {
    uint32_t x = 0, y = 0;
    Rng rng{0};
    Vec3 sum;
};

// One point on a light, seen from a Phong hit, and whether it lights the hit.
struct LightSample {
    Vec3 l;                  // unit, from the hit towards the point
    double n_dot_l = 0;      // with the shading normal facing the viewer
    bool lit = false;        // n_dot_l > 0 and, when a shadow ray is cast, nothing in between
    bool cast = false;       // a shadow ray is cast: n_dot_l > 0 and SHADOW_RAYS > 0
    Ray from;                // the shadow ray's start (spawn's), when cast
    Vec3 target;             // the point, when cast
};

// Each thread's buffers for the batches, kept from call to call so that tracing allocates
// nothing once they have grown. radiance() holds `samples` from its hits' light samples to
// their Phong sums; no other radiance() runs on the thread in between (a mirror's or glass's
// path is traced on before).
struct Scratch {
    std::vector<LightSample> samples;
    std::vector<kdrt_ray> rays;        // occluded()'s shadow rays into the meshes
    std::vector<uint32_t> which;       // the sample each of them is
    std::vector<uint8_t> blocked;      // and its answer
};
thread_local Scratch t_scratch;

Vec3 to_vec(const float f[3]) { return {f[0], f[1], f[2]}; }
void to_float(Vec3 v, float f[3]) { f[0] = float(v.x), f[1] = float(v.y), f[2] = float(v.z); }

// Nearest root t > 0 of |o + t d - c| = r (d unit), in the stable form.
double hit_sphere(Vec3 center, double radius, const Ray &ray, double tmax)
{
    const Vec3 oc = ray.origin - center;
    const double b = dot(oc, ray.dir), c = dot(oc, oc) - radius * radius;
    const double disc = b * b - c;
    if (!(disc >= 0)) return kInf;
    const double q = -b - std::copysign(std::sqrt(disc), b);  // the larger-magnitude root times 1
    double t0 = q, t1 = q != 0 ? c / q : 0;                  // t0 t1 = c
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > 0 && t0 < tmax) return t0;
    if (t1 > 0 && t1 < tmax) return t1;
    return kInf;
}

// t > 0 where the ray meets the parallelogram, with its (s, t) coordinates.
double hit_parallelogram(Vec3 corner, Vec3 eu, Vec3 ev, const Ray &ray, double tmax, double &s, double &tt)
{
    const Vec3 n = cross(eu, ev);
    const double denom = dot(ray.dir, n);
    if (denom == 0) return kInf;
    const double t = dot(corner - ray.origin, n) / denom;
    if (!(t > 0 && t < tmax)) return kInf;
    const Vec3 w = ray.origin + t * ray.dir - corner;
    const double nn = dot(n, n);
    s = dot(cross(w, ev), n) / nn;
    tt = dot(cross(eu, w), n) / nn;
    if (!(s >= 0 && s <= 1 && tt >= 0 && tt <= 1)) return kInf;
    return t;
}

struct MeshData {
    std::vector<Vec3> vertex_normals;  // area-weighted sums of face normals, unit
    Vec3 box_lo, box_hi;               // of its triangles of nonzero area: textured meshes' (u, v)
};

// The camera's frame for a width x height image, checked once a render.
struct View {
    uint32_t width = 0, height = 0;
    Vec3 position, forward, right, up;
    double tan_half = 0, aspect = 0;
    kdrt_media_stack air;
    uint32_t cell = 0; // the camera's start cell: every camera ray shares its one descent
};

bool make_view(const Scene &sc, uint32_t W, uint32_t H, View &view, std::string &error)
{
    if (W == 0 || H == 0) {
        error = "the image has no pixels";
        return false;
    }
    const Camera &cam = sc.camera;
    const Vec3 forward = normalize(cam.target - cam.position);
    const Vec3 right = normalize(cross(forward, cam.up));
    if (!(dot(forward, forward) > 0)) {
        error = "the camera's target is its position: it looks nowhere";
        return false;
    }
    if (!(dot(right, right) > 0)) {
        error = "the camera's up vector is zero or along its view direction";
        return false;
    }
    if (!(cam.fov_degrees > 0 && cam.fov_degrees < 180)) {
        error = "the camera's field of view must lie between 0 and 180 degrees";
        return false;
    }
    view.width = W, view.height = H;
    view.position = cam.position, view.forward = forward, view.right = right;
    view.up = cross(right, forward);
    view.tan_half = std::tan(0.5 * cam.fov_degrees * kPi / 180.0);
    view.aspect = double(W) / H;
    if (kdrt_media_init(&view.air, float(sc.settings.air_index_medium)) != KDRT_SUCCESS) {
        error = "AIR_INDEX_MEDIUM must be a positive finite index";
        return false;
    }
    return true;
}

// The tiles of render() and accumulate(): tile_width x tile_height pixels (smaller at the right
// and bottom edges), handed out in order to the scheduler's threads, a tile a task.
// tile_fn(pixels, n) gets the tile's n pixels, row by row, their x and y set. Each pixel only
// ever touches its own stream and slot, so the image does not depend on the threads.
template <typename TileFn>
void for_each_tile(common::ThreadScheduler &scheduler, uint32_t W, uint32_t H, uint32_t tile_width,
                   uint32_t tile_height, const TileFn &tile_fn)
{
    struct Job {
        uint32_t W, H, tile_width, tile_height, tiles_x;
        const TileFn *fn;
    };
    const uint32_t tiles_x = (W + tile_width - 1) / tile_width, tiles_y = (H + tile_height - 1) / tile_height;
    Job job{W, H, tile_width, tile_height, tiles_x, &tile_fn};
    const kdrt_scheduler hooks = scheduler.hooks();
    hooks.run(hooks.user, [](void *data, uint32_t t) {
        const Job &j = *static_cast<const Job *>(data);
        const uint32_t x0 = (t % j.tiles_x) * j.tile_width, y0 = (t / j.tiles_x) * j.tile_height;
        const uint32_t x1 = std::min(j.W, x0 + j.tile_width), y1 = std::min(j.H, y0 + j.tile_height);
        TilePixel pixels[kTileRays];
        uint32_t n = 0;
        for (uint32_t y = y0; y < y1; ++y)
            for (uint32_t x = x0; x < x1; ++x) pixels[n].x = x, pixels[n].y = y, ++n;
        (*j.fn)(pixels, n);
    }, &job, tiles_x * tiles_y);
}

}  // namespace

struct Renderer::Impl {
    const Scene *scene = nullptr;
    // Every mesh behind one query: geometry i is scene->meshes[i], so a hit's geometry is the
    // mesh's index and equal t goes to the lower index. NULL when the scene has no meshes.
    kdrt_scene *world = nullptr;
    std::vector<MeshData> meshes;
    kdrt_build_options options{};  // the build's (or the saved tree's), for tree_boxes()
    unsigned threads = 0;
    double build_seconds = 0;

    // Renderer::prepare and prepare_saved: built, or loaded from `saved` when not NULL.
    bool prepare(const Scene &scene, unsigned threads, std::string &error, TreeBuilder builder,
                 const std::vector<unsigned char> *saved, const std::string &saved_path);

    ~Impl() { clear(); }
    void clear()
    {
        kdrt_scene_free(world);
        world = nullptr;
        meshes.clear();
    }

    // Media-stack ids: spheres first, then meshes (quads are thin panes, see glass()).
    uint32_t sphere_object(int i) const { return uint32_t(i); }
    uint32_t mesh_object(int i) const { return uint32_t(scene->spheres.size() + size_t(i)); }

    // The batches take n <= N rays, N their arrays' size: kTileRays for a tile's camera rays, 1
    // for a lone ray (mirror and glass paths), which then sets up no tile's arrays.
    //
    // The nearest sphere, quad, mesh or light each of rays[0 .. n) meets (lights are seen by
    // every traced ray): the meshes' part in one batch call. The one-ray form is false for a miss.
    template <uint32_t N> void intersect(const Ray *rays, uint32_t n, Hit *hits) const;
    bool intersect(const Ray &ray, Hit &hit) const;
    void hit_surface(const Ray &ray, Hit &hit) const;
    void occluded(LightSample *samples, size_t count) const;
    uint32_t cell_of(Vec3 point) const;
    Ray spawn(const Hit &hit, Vec3 dir) const;
    Vec3 texture(int texture_index, double u, double v) const;
    void light_samples(const Hit &hit, Vec3 n, Rng &rng, LightSample *samples, size_t first, size_t stride) const;
    Vec3 phong(const Material &m, const Hit &hit, Vec3 view_dir, Vec3 n, const LightSample *samples, size_t first,
               size_t stride) const;

    // What a hit shows: a colour, or a Phong surface (`phong` its material, n its shading normal
    // facing the viewer), whose direct light waits for its shadow rays.
    struct Shade {
        Vec3 color;
        const Material *phong = nullptr;
        Vec3 n;
    };
    Shade shade(const Ray &ray, const Hit &hit, uint32_t bounces_left, const kdrt_media_stack &media, Rng &rng) const;
    // The colours rays[0 .. n) bring back, all starting in `media`, ray i drawing from *rngs[i].
    template <uint32_t N>
    void radiance(const Ray *rays, uint32_t n, uint32_t bounces_left, const kdrt_media_stack &media,
                  Rng *const *rngs, Vec3 *colors) const;
    Vec3 radiance(const Ray &ray, uint32_t bounces_left, const kdrt_media_stack &media, Rng &rng) const;
    // A camera ray: through the pixel's centre, or jittered over the pixel.
    Ray camera_ray(const View &view, uint32_t x, uint32_t y, bool jitter, Rng &rng) const;
    // `count` more samples for each of a tile's n pixels (n <= kTileRays), added to their sums.
    void trace_tile(const View &view, TilePixel *pixels, uint32_t n, uint32_t count, bool jitter) const;

    // One glass surface: where the ray goes next, and how the stack changes. Shared by the
    // shading and trace_specular_path. `reflect` forces the reflected branch (FRESNEL).
    struct GlassStep {
        bool ok = false;          // false: the stack overflowed or the input was bad; end the path
        bool refracted = false;   // crossed into the next medium (or through a false surface)
        bool total_internal = false;
        Ray next;
        kdrt_media_stack media;
        double reflectance = 0;   // Fresnel reflectance of a real surface (0 for false ones)
    };
    GlassStep glass(const Ray &ray, const Hit &hit, const Material &m, const kdrt_media_stack &media,
                    bool reflect) const;

    void material_of(const Hit &hit, const Material *&m) const
    {
        int index = 0;
        if (hit.kind == HitKind::sphere) index = scene->spheres[size_t(hit.index)].material;
        else if (hit.kind == HitKind::quad) index = scene->quads[size_t(hit.index)].material;
        else if (hit.kind == HitKind::mesh) index = scene->meshes[size_t(hit.index)].material;
        m = index >= 0 && size_t(index) < scene->materials.size() ? &scene->materials[size_t(index)] : nullptr;
    }
};

template <uint32_t N>
void Renderer::Impl::intersect(const Ray *rays, uint32_t n, Hit *hits) const
{
    t_rays += n;
    const Scene &sc = *scene;
    for (uint32_t r = 0; r < n; ++r) {
        const Ray &ray = rays[r];
        Hit &hit = hits[r];
        hit = Hit();
        for (size_t i = 0; i < sc.spheres.size(); ++i) {
            const double t = hit_sphere(sc.spheres[i].center, sc.spheres[i].radius, ray, hit.t);
            if (t < hit.t) hit.t = t, hit.kind = HitKind::sphere, hit.index = int(i);
        }
        double s = 0, tt = 0;
        for (size_t i = 0; i < sc.quads.size(); ++i) {
            const Quad &q = sc.quads[i];
            const double t = hit_parallelogram(q.corner, q.edge_u, q.edge_v, ray, hit.t, s, tt);
            if (t < hit.t) hit.t = t, hit.kind = HitKind::quad, hit.index = int(i), hit.u = s, hit.v = tt;
        }
        for (size_t i = 0; i < sc.lights.size(); ++i) {
            const Light &l = sc.lights[i];
            const double t = l.kind == LightKind::sphere ? hit_sphere(l.center, l.radius, ray, hit.t)
                                                         : hit_parallelogram(l.corner, l.edge_u, l.edge_v, ray, hit.t, s, tt);
            if (t < hit.t) hit.t = t, hit.kind = HitKind::light, hit.index = int(i);
        }
    }
    if (world) {  // the meshes, nearer than those
        kdrt_ray krays[N] = {};  // zeroed: GCC cannot tell that the n read are all set
        for (uint32_t r = 0; r < n; ++r) {
            kdrt_ray &kray = krays[r];
            to_float(rays[r].origin, kray.org);
            to_float(rays[r].dir, kray.dir);
            kray.tmin = 0;
            kray.cell = rays[r].cell;
            kray.tmax = hits[r].t < kInf ? float(hits[r].t) : INFINITY;
        }
        kdrt_hit khits[N];
        kdrt_scene_intersect_batch(world, krays, n, nullptr, khits);
        for (uint32_t r = 0; r < n; ++r) {
            const kdrt_hit &kh = khits[r];
            Hit &hit = hits[r];
            if (kh.triangle != KDRT_INVALID_ID && kh.t < hit.t)
                hit.t = kh.t, hit.kind = HitKind::mesh, hit.index = int(kh.geometry), hit.mesh_hit = kh;
        }
    }
    for (uint32_t r = 0; r < n; ++r) hit_surface(rays[r], hits[r]);
}

bool Renderer::Impl::intersect(const Ray &ray, Hit &hit) const
{
    intersect<1>(&ray, 1, &hit);
    return hit.kind != HitKind::none;
}

// The hit's point, normals and texture coordinates (none for a light or a miss).
void Renderer::Impl::hit_surface(const Ray &ray, Hit &hit) const
{
    const Scene &sc = *scene;
    switch (hit.kind) {
    case HitKind::none:
    case HitKind::light:
        return;
    case HitKind::sphere: {
        const Sphere &sp = sc.spheres[size_t(hit.index)];
        hit.point = ray.origin + hit.t * ray.dir;
        hit.normal = normalize(hit.point - sp.center);
        // Spherical coordinates about +y.
        hit.u = 0.5 + std::atan2(hit.normal.z, hit.normal.x) / (2 * kPi);
        hit.v = std::acos(std::max(-1.0, std::min(1.0, hit.normal.y))) / kPi;
        break;
    }
    case HitKind::quad: {
        const Quad &q = sc.quads[size_t(hit.index)];
        hit.point = q.corner + hit.u * q.edge_u + hit.v * q.edge_v;
        hit.normal = normalize(cross(q.edge_u, q.edge_v));
        break;
    }
    case HitKind::mesh: {
        const MeshData &md = meshes[size_t(hit.index)];
        float p[3], n[3];
        kdrt_scene_hit_surface(world, &hit.mesh_hit, p, n);
        hit.point = to_vec(p), hit.normal = to_vec(n);
        // Meshes carry no texture coordinates: a textured mesh maps its box's x and z.
        const Vec3 size = md.box_hi - md.box_lo;
        hit.u = size.x > 0 ? (hit.point.x - md.box_lo.x) / size.x : 0;
        hit.v = size.z > 0 ? (hit.point.z - md.box_lo.z) / size.z : 0;
        break;
    }
    }
    hit.shading_normal = hit.normal;
    if (hit.kind == HitKind::mesh && sc.settings.enable_interpolation) {
        const common::Mesh &mesh = sc.meshes[size_t(hit.index)].mesh;
        const MeshData &md = meshes[size_t(hit.index)];
        const uint32_t t = hit.mesh_hit.triangle;
        const double b1 = hit.mesh_hit.u, b2 = hit.mesh_hit.v, b0 = 1 - b1 - b2;
        const Vec3 n = normalize(b0 * md.vertex_normals[mesh.vertex(t, 0)] + b1 * md.vertex_normals[mesh.vertex(t, 1)] +
                                 b2 * md.vertex_normals[mesh.vertex(t, 2)]);
        if (dot(n, n) > 0) hit.shading_normal = n;
    }
}

// The start cell of a ray from point in the scene's mesh tree (0 without meshes, or outside).
uint32_t Renderer::Impl::cell_of(Vec3 point) const
{
    float p[3];
    to_float(point, p);
    return world ? kdrt_scene_locate(world, p) : 0u;
}

// The shadow rays of samples[0 .. count) that are cast, each from its hit (its start cell too)
// to its point: blocked by any sphere, quad or mesh between (lights are not occluders; glass
// casts a full shadow, as in the original), the meshes' part in one batch call for them all.
void Renderer::Impl::occluded(LightSample *samples, size_t count) const
{
    std::vector<kdrt_ray> &krays = t_scratch.rays;
    std::vector<uint32_t> &which = t_scratch.which;
    krays.clear(), which.clear();
    const auto blocked_by_shapes = [this](const Ray &ray, double dist) {
        for (const Sphere &sp : scene->spheres)
            if (hit_sphere(sp.center, sp.radius, ray, dist) < dist) return true;
        double s, t;
        for (const Quad &q : scene->quads)
            if (hit_parallelogram(q.corner, q.edge_u, q.edge_v, ray, dist, s, t) < dist) return true;
        return false;
    };
    for (size_t i = 0; i < count; ++i) {
        LightSample &sample = samples[i];
        if (!sample.cast) continue;
        ++t_rays;
        const Vec3 origin = sample.from.origin;
        const Vec3 d = sample.target - origin;
        const double dist = length(d);
        if (!(dist > 0)) continue;
        if (blocked_by_shapes(Ray{origin, (1.0 / dist) * d}, dist)) {
            sample.lit = false;
            continue;
        }
        if (!world) continue;
        kdrt_ray kray{};
        to_float(origin, kray.org);
        to_float(d, kray.dir);  // target at t = 1 (kdrt_spawn_ray's rule for shadow rays)
        kray.tmin = 0;
        kray.tmax = 1;
        kray.cell = sample.from.cell;
        krays.push_back(kray);
        which.push_back(uint32_t(i));
    }
    if (krays.empty()) return;
    std::vector<uint8_t> &blocked = t_scratch.blocked;
    blocked.resize(krays.size());
    kdrt_scene_occluded_batch(world, krays.data(), uint32_t(krays.size()), nullptr, blocked.data());
    for (size_t j = 0; j < krays.size(); ++j)
        if (blocked[j]) samples[which[j]].lit = false;
}

// The next ray from a hit: its origin moved off the surface towards the side dir leaves on.
Ray Renderer::Impl::spawn(const Hit &hit, Vec3 dir) const
{
    float fdir[3];
    to_float(dir, fdir);
    Ray next;
    next.dir = normalize(dir);
    if (hit.kind == HitKind::mesh) {
        kdrt_ray kray;
        kdrt_scene_spawn_ray(world, &hit.mesh_hit, fdir, &kray);
        next.origin = to_vec(kray.org);
        next.cell = kray.cell;  // the hit's own cell, which kdrt_scene_spawn_ray checked
    } else {
        float p[3], n[3], out[3];
        to_float(hit.point, p);
        to_float(hit.normal, n);
        kdrt_offset_ray_origin(p, n, fdir, out);
        next.origin = to_vec(out);
        next.cell = cell_of(next.origin);
    }
    return next;
}

Vec3 Renderer::Impl::texture(int texture_index, double u, double v) const
{
    if (texture_index < 0 || size_t(texture_index) >= scene->textures.size()) return {1, 1, 1};
    const Texture &t = scene->textures[size_t(texture_index)];
    if (!t.rgb.empty() && t.width > 0 && t.height > 0) {
        // Nearest texel, repeating; v = 0 is the image's bottom row.
        const double fu = u - std::floor(u), fv = v - std::floor(v);
        const uint32_t x = std::min(t.width - 1, uint32_t(fu * t.width));
        const uint32_t y = std::min(t.height - 1, uint32_t((1 - fv) * t.height));
        const float *px = &t.rgb[(size_t(y) * t.width + x) * 3];
        return {px[0], px[1], px[2]};
    }
    const long cell = long(std::floor(u * t.checker_scale)) + long(std::floor(v * t.checker_scale));
    return (cell & 1) ? t.checker_b : t.checker_a;
}

// The points on the lights that may light a Phong hit whose shading normal, facing the viewer,
// is n: SHADOW_RAYS of them a light (one at least), light L's k-th at samples[first + L * stride
// + k], each with its shadow ray when one is to be cast. The hit's random numbers are drawn here,
// the same whatever the shadow rays find.
void Renderer::Impl::light_samples(const Hit &hit, Vec3 n, Rng &rng, LightSample *samples, size_t first,
                                   size_t stride) const
{
    const Settings &st = scene->settings;
    const uint32_t per_light = std::max(1u, st.shadow_rays);
    for (size_t i = 0; i < scene->lights.size(); ++i) {
        const Light &light = scene->lights[i];
        for (uint32_t k = 0; k < per_light; ++k) {
            Vec3 q;
            if (light.kind == LightKind::sphere) {
                q = light.center;
                if (st.shadow_rays > 1) {
                    // A uniform point on the light's disc as seen from the hit.
                    const Vec3 w = normalize(hit.point - light.center);
                    const Vec3 a = normalize(cross(std::fabs(w.x) > 0.5 ? Vec3{0, 1, 0} : Vec3{1, 0, 0}, w));
                    const Vec3 b = cross(w, a);
                    const double r = light.radius * std::sqrt(rng.uniform()), phi = 2 * kPi * rng.uniform();
                    q = q + (r * std::cos(phi)) * a + (r * std::sin(phi)) * b;
                }
            } else {
                const double s = st.shadow_rays > 1 ? rng.uniform() : 0.5, t = st.shadow_rays > 1 ? rng.uniform() : 0.5;
                q = light.corner + s * light.edge_u + t * light.edge_v;
            }
            LightSample &sample = samples[first + i * stride + k];
            sample.l = normalize(q - hit.point);
            sample.n_dot_l = dot(n, sample.l);
            sample.lit = !(sample.n_dot_l <= 0);
            sample.cast = sample.lit && st.shadow_rays > 0;
            if (sample.cast) sample.from = spawn(hit, sample.l), sample.target = q;
        }
    }
}

// Phong at a hit seen along view_dir, with n the shading normal facing the viewer, lit by its
// light samples as light_samples() laid them out and occluded() found them.
Vec3 Renderer::Impl::phong(const Material &m, const Hit &hit, Vec3 view_dir, Vec3 n, const LightSample *samples,
                           size_t first, size_t stride) const
{
    const Settings &st = scene->settings;
    const Vec3 tex = st.enable_textures ? texture(m.texture, hit.u, hit.v) : Vec3{1, 1, 1};
    Vec3 color = m.ambient;
    const Vec3 to_eye = -1.0 * view_dir;
    const uint32_t count = std::max(1u, st.shadow_rays);
    for (size_t i = 0; i < scene->lights.size(); ++i) {
        Vec3 sum;
        for (uint32_t k = 0; k < count; ++k) {
            const LightSample &sample = samples[first + i * stride + k];
            if (!sample.lit) continue;
            Vec3 c = sample.n_dot_l * (m.diffuse * tex);
            if (st.phong) {
                const Vec3 r = 2 * sample.n_dot_l * n - sample.l;  // l mirrored about n
                const double r_dot_v = dot(r, to_eye);
                if (r_dot_v > 0) c = c + std::pow(r_dot_v, m.shininess) * m.specular;
            }
            sum = sum + c;
        }
        color = color + (1.0 / count) * (scene->lights[i].color * sum);
    }
    return color;
}

Renderer::Impl::GlassStep Renderer::Impl::glass(const Ray &ray, const Hit &hit, const Material &m,
                                                 const kdrt_media_stack &media, bool reflect) const
{
    GlassStep step;
    step.media = media;
    float d[3], n[3], out[3];
    to_float(ray.dir, d);
    to_float(hit.shading_normal, n);
    const double cos_i = std::fabs(dot(ray.dir, hit.shading_normal));
    if (hit.kind == HitKind::quad) {
        // A quad is a thin pane: no medium inside, so the light goes straight through it.
        step.reflectance = kdrt_fresnel_dielectric(float(cos_i), float(kdrt_media_current_ior(&media) / m.ior));
        if (reflect) {
            kdrt_reflect(d, n, out);
            step.next = spawn(hit, to_vec(out));
        } else {
            step.refracted = true;
            step.next = spawn(hit, ray.dir);
        }
        step.ok = true;
        return step;
    }
    const uint32_t object = hit.kind == HitKind::sphere ? sphere_object(hit.index) : mesh_object(hit.index);
    const kdrt_media_crossing x = kdrt_media_at_surface(&media, object, float(m.ior), 0);
    int crossed = 1;  // a false surface: straight on
    Vec3 dir = ray.dir;
    if (x.real) {
        const float eta = x.eta_incident / x.eta_transmitted;
        step.reflectance = kdrt_fresnel_dielectric(float(cos_i), eta);
        if (reflect) {
            kdrt_reflect(d, n, out);
            crossed = 0;
        } else {
            crossed = kdrt_refract(d, n, eta, out);  // 0: total internal reflection, out mirrored
            if (crossed < 0) return step;             // bad input (a NaN direction): end the path
            step.total_internal = crossed == 0;
        }
        dir = to_vec(out);
    }
    if (crossed) {
        const kdrt_result r = x.entering ? kdrt_media_enter(&step.media, object, float(m.ior), 0)
                                         : kdrt_media_leave(&step.media, object);
        if (r != KDRT_SUCCESS) return step;  // a full stack: end the path
    }
    step.refracted = crossed != 0;
    step.next = spawn(hit, dir);
    step.ok = true;
    return step;
}

Renderer::Impl::Shade Renderer::Impl::shade(const Ray &ray, const Hit &hit, uint32_t bounces_left,
                                             const kdrt_media_stack &media, Rng &rng) const
{
    const Scene &sc = *scene;
    Shade out;  // black unless said otherwise
    if (hit.kind == HitKind::none) {
        out.color = sc.background;
        return out;
    }
    if (hit.kind == HitKind::light) {
        out.color = sc.lights[size_t(hit.index)].color;
        return out;
    }
    const Material *m = nullptr;
    material_of(hit, m);
    if (!m) return out;
    const Settings &st = sc.settings;
    const bool mirror = m->kind == MaterialKind::mirror && st.enable_mirror;
    const bool glass = m->kind == MaterialKind::glass && st.enable_glass;
    if (!mirror && !glass) {
        // Face the normals towards the viewer: both sides of every surface are lit.
        Vec3 n = hit.shading_normal;
        const bool back = dot(hit.normal, ray.dir) > 0;
        if (back) n = -1.0 * n;
        if (dot(n, ray.dir) > 0) n = back ? -1.0 * hit.normal : hit.normal;  // interpolation went past the silhouette
        out.phong = m, out.n = n;
        return out;
    }
    // Every mirror or glass surface met takes a bounce; out of bounces the path ends, black.
    if (bounces_left == 0) return out;
    if (mirror) {
        float d[3], n[3], reflected[3];
        to_float(ray.dir, d);
        to_float(hit.shading_normal, n);
        kdrt_reflect(d, n, reflected);
        out.color = m->tint * radiance(spawn(hit, to_vec(reflected)), bounces_left - 1, media, rng);
        return out;
    }
    const GlassStep through = this->glass(ray, hit, *m, media, false);
    if (!through.ok) return out;
    Vec3 color = radiance(through.next, bounces_left - 1, through.media, rng);
    if (through.refracted) color = m->tint * color;  // the glass filters what it lets through
    if (through.refracted && st.fresnel && through.reflectance > 0) {
        // FRESNEL: both branches, weighted by the exact reflectance: deterministic, no noise.
        const GlassStep mirrored = this->glass(ray, hit, *m, media, true);
        const double R = through.reflectance;
        color = (1 - R) * color;
        if (mirrored.ok) color = color + R * radiance(mirrored.next, bounces_left - 1, mirrored.media, rng);
    }
    out.color = color;
    return out;
}

template <uint32_t N>
void Renderer::Impl::radiance(const Ray *rays, uint32_t n, uint32_t bounces_left, const kdrt_media_stack &media,
                              Rng *const *rngs, Vec3 *colors) const
{
    Hit hits[N];
    intersect<N>(rays, n, hits);
    // Each ray's shading, mirror and glass paths traced on; the Phong hits wait for the lights.
    Shade shades[N];
    uint32_t lit[N], lit_count = 0;
    for (uint32_t r = 0; r < n; ++r) {
        shades[r] = shade(rays[r], hits[r], bounces_left, media, *rngs[r]);
        if (shades[r].phong) lit[lit_count++] = r;
        else colors[r] = shades[r].color;
    }
    if (lit_count == 0) return;
    // The Phong hits' light samples, light by light: light L's k-th sample of Phong hit j is
    // samples[j * per_light + L * stride + k], so each light's shadow rays from neighbouring
    // pixels lie side by side, traced in one batch. (No lights: no samples, and data() may be
    // null, so offsets are indices, not pointers.)
    const size_t per_light = std::max(1u, scene->settings.shadow_rays), stride = lit_count * per_light;
    std::vector<LightSample> &samples = t_scratch.samples;
    samples.resize(stride * scene->lights.size());
    for (uint32_t j = 0; j < lit_count; ++j) {
        const uint32_t r = lit[j];
        light_samples(hits[r], shades[r].n, *rngs[r], samples.data(), j * per_light, stride);
    }
    for (size_t light = 0; light < scene->lights.size(); ++light) occluded(samples.data() + light * stride, stride);
    for (uint32_t j = 0; j < lit_count; ++j) {
        const uint32_t r = lit[j];
        colors[r] = phong(*shades[r].phong, hits[r], rays[r].dir, shades[r].n, samples.data(), j * per_light, stride);
    }
}

Vec3 Renderer::Impl::radiance(const Ray &ray, uint32_t bounces_left, const kdrt_media_stack &media, Rng &rng) const
{
    Rng *const rngs[1] = {&rng};
    Vec3 color;
    radiance<1>(&ray, 1, bounces_left, media, rngs, &color);
    return color;
}

Ray Renderer::Impl::camera_ray(const View &v, uint32_t x, uint32_t y, bool jitter, Rng &rng) const
{
    const uint32_t W = v.width, H = v.height;
    const double jx = jitter ? rng.uniform() : 0.5, jy = jitter ? rng.uniform() : 0.5;
    const double sx = (2.0 * (x + jx) / W - 1.0) * v.tan_half * v.aspect;
    const double sy = (1.0 - 2.0 * (y + jy) / H) * v.tan_half;
    return Ray{v.position, normalize(v.forward + sx * v.right + sy * v.up), v.cell};
}

void Renderer::Impl::trace_tile(const View &view, TilePixel *pixels, uint32_t n, uint32_t count, bool jitter) const
{
    Rng *rngs[kTileRays];
    for (uint32_t i = 0; i < n; ++i) rngs[i] = &pixels[i].rng;
    for (uint32_t s = 0; s < count; ++s) {
        Ray rays[kTileRays];
        for (uint32_t i = 0; i < n; ++i) rays[i] = camera_ray(view, pixels[i].x, pixels[i].y, jitter, pixels[i].rng);
        Vec3 colors[kTileRays];
        radiance<kTileRays>(rays, n, scene->settings.max_bounces, view.air, rngs, colors);
        for (uint32_t i = 0; i < n; ++i) pixels[i].sum = pixels[i].sum + colors[i];
    }
}

Renderer::Renderer() : impl_(new Impl) {}
Renderer::~Renderer() = default;

double Renderer::build_seconds() const { return impl_->build_seconds; }

bool Renderer::prepare(const Scene &scene, unsigned threads, std::string &error, TreeBuilder builder)
{
    return impl_->prepare(scene, threads, error, builder, nullptr, "");
}

bool Renderer::prepare_saved(const Scene &scene, unsigned threads, const std::vector<unsigned char> &saved,
                             const std::string &path, std::string &error)
{
    return impl_->prepare(scene, threads, error, TreeBuilder::sah, &saved, path);
}

bool Renderer::save_tree(const std::string &path, std::string &error) const
{
    if (!impl_->world) {
        error = "cannot save the tree to '" + path + "': the scene has no meshes";
        return false;
    }
    const auto save = [](const void *world, kdrt_write_fn write, void *user) {
        return kdrt_scene_save_meshes(static_cast<const kdrt_scene *>(world), write, user);
    };
    return common::write_saved_tree(path, save, impl_->world, error);
}

bool Renderer::Impl::prepare(const Scene &scene, unsigned threads, std::string &error, TreeBuilder builder,
                             const std::vector<unsigned char> *saved, const std::string &saved_path)
{
    Impl *const impl_ = this;
    impl_->clear();
    impl_->scene = &scene;
    for (const Sphere &s : scene.spheres)
        if (!(s.radius > 0)) {
            error = "a sphere has radius " + std::to_string(s.radius) + "; it must be positive";
            return false;
        }
    const size_t nm = scene.materials.size();
    auto bad_material = [&](int m) { return m < 0 || size_t(m) >= nm; };
    for (const Sphere &s : scene.spheres)
        if (bad_material(s.material)) { error = "a sphere's material " + std::to_string(s.material) + " does not exist"; return false; }
    for (const Quad &q : scene.quads)
        if (bad_material(q.material)) { error = "a quad's material " + std::to_string(q.material) + " does not exist"; return false; }
    for (const MeshInstance &m : scene.meshes)
        if (bad_material(m.material)) { error = "a mesh's material " + std::to_string(m.material) + " does not exist"; return false; }
    common::ThreadScheduler scheduler(threads);
    const auto start = std::chrono::steady_clock::now();
    std::vector<kdrt_geometry> geometries;
    for (const MeshInstance &mi : scene.meshes) {
        impl_->meshes.emplace_back();
        MeshData &md = impl_->meshes.back();
        const common::Mesh &mesh = mi.mesh;
        const kdrt_triangles view = mesh.view();
        geometries.push_back(kdrt_mesh_geometry(uint32_t(geometries.size()), &view));  // ID = mesh index
        // Vertex normals: the sum of the unnormalised face normals around a vertex weighs each
        // face by its area. The box holds the triangles of nonzero area, the ones kdrt keeps
        // (its zero-area test: this cross product of the float corners, in double, exactly 0).
        md.vertex_normals.assign(mesh.vertex_count(), Vec3{});
        Vec3 lo{kInf, kInf, kInf}, hi = -1.0 * lo;
        double p[3][3];
        for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
            mesh.corners(t, p);
            const Vec3 a{p[0][0], p[0][1], p[0][2]}, b{p[1][0], p[1][1], p[1][2]}, c{p[2][0], p[2][1], p[2][2]};
            const Vec3 face = cross(b - a, c - a);
            for (int k = 0; k < 3; ++k) {
                const uint32_t v = mesh.vertex(t, k);
                md.vertex_normals[v] = md.vertex_normals[v] + face;
            }
            if (face.x == 0 && face.y == 0 && face.z == 0) continue;
            for (const Vec3 &q : {a, b, c}) {
                lo = Vec3{std::min(lo.x, q.x), std::min(lo.y, q.y), std::min(lo.z, q.z)};
                hi = Vec3{std::max(hi.x, q.x), std::max(hi.y, q.y), std::max(hi.z, q.z)};
            }
        }
        for (Vec3 &n : md.vertex_normals) n = normalize(n);
        md.box_lo = lo, md.box_hi = hi;
    }
    // One scene for every mesh: one kd-tree over all their triangles, built with the options
    // one mesh's tree had.
    kdrt_build_options &options = impl_->options;
    options = kdrt_default_build_options();
    options.max_leaf_size = scene.settings.max_leaf_size;
    if (builder == TreeBuilder::median) options.builder = KDRT_BUILDER_MEDIAN;
    options.scheduler = scheduler.hooks();
    impl_->threads = threads;
    if (saved) {
        // The file's build options become the scene's (kdrt_scene_load), and tree_boxes()'.
        kdrt_saved_tree_info info;
        kdrt_result r = kdrt_saved_tree_read_info(saved->data(), saved->size(), &info);
        if (r == KDRT_SUCCESS && info.meshes != geometries.size()) r = KDRT_ERROR_MESH_MISMATCH;
        kdrt_build_report report{};
        report.invalid_geometry = KDRT_INVALID_ID;
        if (r == KDRT_SUCCESS && !geometries.empty())
            r = kdrt_scene_load(geometries.data(), uint32_t(geometries.size()), saved->data(), saved->size(), &options,
                                &impl_->world, &report);
        if (r != KDRT_SUCCESS) {
            uint64_t triangles = 0;
            for (const MeshInstance &mi : scene.meshes) triangles += mi.mesh.triangle_count();
            error = common::saved_tree_refusal(r, saved_path, *saved, triangles, uint32_t(geometries.size()));
            const uint32_t bad = report.invalid_geometry;
            if (r == KDRT_ERROR_MESH_MISMATCH && bad < scene.meshes.size())
                error += "; the first that differs: mesh " + std::to_string(bad) + ", " + scene.meshes[bad].source;
            impl_->clear();
            return false;
        }
        if (info.options.max_leaf_size != options.max_leaf_size) {
            error = "'" + saved_path + "' holds a tree of leaf size " + std::to_string(info.options.max_leaf_size) +
                    " and the scene asks MAX_LEAF_SIZE=" + std::to_string(options.max_leaf_size) +
                    " (save the tree again with --save-tree, or --set MAX_LEAF_SIZE=" +
                    std::to_string(info.options.max_leaf_size) + ")";
            impl_->clear();
            return false;
        }
        const kdrt_scheduler hooks = options.scheduler;
        options = info.options;
        options.scheduler = hooks;
    } else if (!geometries.empty()) {
        kdrt_build_report report;
        const kdrt_result r = kdrt_scene_build(geometries.data(), uint32_t(geometries.size()), &options,
                                               &impl_->world, &report);
        if (r != KDRT_SUCCESS) {
            const uint32_t bad = report.invalid_geometry;
            error = "cannot build the tree of " +
                    (bad < scene.meshes.size() ? "mesh " + scene.meshes[bad].source : std::string("the meshes")) +
                    ": " + kdrt_result_string(r);
            impl_->clear();
            return false;
        }
    }
    options.scheduler = kdrt_scheduler{};  // `scheduler` ends here; tree_boxes() makes its own
    impl_->build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return true;
}

std::vector<PathEvent> Renderer::trace_specular_path(Vec3 origin, Vec3 direction, uint32_t max_events) const
{
    const Impl &im = *impl_;
    std::vector<PathEvent> path;
    kdrt_media_stack media;
    kdrt_media_init(&media, float(im.scene->settings.air_index_medium));
    Ray ray{origin, normalize(direction), im.cell_of(origin)};
    for (uint32_t i = 0; i < max_events; ++i) {
        Hit hit;
        if (!im.intersect(ray, hit) || hit.kind == HitKind::light) break;
        const Material *m = nullptr;
        im.material_of(hit, m);
        if (!m) break;
        PathEvent e;
        e.point = hit.point;
        if (m->kind == MaterialKind::mirror && im.scene->settings.enable_mirror) {
            float d[3], n[3], out[3];
            to_float(ray.dir, d);
            to_float(hit.shading_normal, n);
            kdrt_reflect(d, n, out);
            ray = im.spawn(hit, to_vec(out));
            e.reflected = true;
        } else if (m->kind == MaterialKind::glass && im.scene->settings.enable_glass) {
            const Impl::GlassStep step = im.glass(ray, hit, *m, media, false);
            if (!step.ok) break;
            ray = step.next;
            media = step.media;
            e.refracted = step.refracted;
            e.reflected = step.total_internal;
        } else {
            break;
        }
        e.direction = ray.dir;
        path.push_back(e);
    }
    return path;
}

bool Renderer::render(const RenderOptions &options, Image &image, std::string &error) const
{
    const Impl &im = *impl_;
    if (!im.scene) {
        error = "render before prepare";
        return false;
    }
    const Scene &sc = *im.scene;
    View view;
    if (!make_view(sc, options.width, options.height, view, error)) return false;
    view.cell = im.cell_of(view.position);
    const uint32_t W = options.width, H = options.height;
    image.width = W, image.height = H;
    image.rgb.assign(size_t(W) * H * 3, 0.0f);
    const Settings &st = sc.settings;

    const uint32_t tile_width = options.one_pixel_tiles ? 1 : kTileWidth;
    const uint32_t tile_height = options.one_pixel_tiles ? 1 : kTileHeight;
    const uint32_t tiles = ((W + tile_width - 1) / tile_width) * ((H + tile_height - 1) / tile_height);
    std::atomic<uint32_t> done_tiles(0);
    std::mutex progress_mutex;
    const auto start = std::chrono::steady_clock::now();
    auto last_report = start;
    bool all_joined = false;
    auto report = [&](uint32_t done) {
        if (!options.progress || (done == tiles && !all_joined)) return;  // 100% once, at the end
        std::unique_lock<std::mutex> lock(progress_mutex, std::try_to_lock);
        if (!lock.owns_lock()) return;
        const auto now = std::chrono::steady_clock::now();
        if (done < tiles && now - last_report < std::chrono::milliseconds(200)) return;
        last_report = now;
        const double elapsed = std::chrono::duration<double>(now - start).count();
        const double fraction = double(done) / tiles;
        const double eta = fraction > 0 ? elapsed * (1 - fraction) / fraction : 0;
        const int width = 30, filled = int(fraction * width);
        std::fprintf(stderr, "\r[%.*s%.*s] %3d%%  %.1f s, ETA %.1f s ", filled, "##############################",
                     width - filled, "..............................", int(100 * fraction), elapsed, eta);
        std::fflush(stderr);
    };
    common::ThreadScheduler scheduler(options.threads);
    for_each_tile(scheduler, W, H, tile_width, tile_height, [&](TilePixel *pixels, uint32_t n) {
        for (uint32_t i = 0; i < n; ++i)
            pixels[i].rng = pixel_rng(options.seed, options.frame, uint64_t(pixels[i].y) * W + pixels[i].x);
        im.trace_tile(view, pixels, n, st.nsamples, st.nsamples > 1);
        for (uint32_t i = 0; i < n; ++i) {
            const Vec3 sum = pixels[i].sum;
            float *px = &image.rgb[(uint64_t(pixels[i].y) * W + pixels[i].x) * 3];
            px[0] = float(sum.x / st.nsamples), px[1] = float(sum.y / st.nsamples), px[2] = float(sum.z / st.nsamples);
        }
        report(++done_tiles);
    });
    if (options.progress) {
        all_joined = true;
        report(tiles);
        std::fputc('\n', stderr);
    }
    return true;
}

namespace {

// linear_to_srgb8 without its pow: the 255 linear values where its result steps up, found once by
// bisection over the floats (the function rises with v), then 8 comparisons a channel.
struct SrgbSteps {
    float step[256];  // step[k]: the least float that encodes to k or more (step[0] unused)
    SrgbSteps()
    {
        for (int k = 1; k < 256; ++k) {
            // Non-negative floats order as their bit patterns; bisect on those.
            uint32_t lo = 0, hi = 0x3F800000u;  // encodes 0 .. 1.0f (255)
            while (lo < hi) {
                const uint32_t mid = lo + (hi - lo) / 2;
                float f;
                std::memcpy(&f, &mid, sizeof f);
                if (linear_to_srgb8(f) >= k) hi = mid;
                else lo = mid + 1;
            }
            std::memcpy(&step[k], &lo, sizeof lo);
        }
    }
    unsigned char encode(float v) const
    {
        int k = 0;  // the last step v reaches; none for negatives and NaN, which encode to 0
        for (int bit = 128; bit > 0; bit >>= 1)
            if (k + bit <= 255 && v >= step[k + bit]) k += bit;
        return (unsigned char)k;
    }
};

}  // namespace

bool Renderer::accumulate(const RenderOptions &options, Accumulation &acc, common::ThreadScheduler &scheduler,
                          std::string &error) const
{
    static const SrgbSteps srgb;
    const Impl &im = *impl_;
    if (!im.scene) {
        error = "render before prepare";
        return false;
    }
    View view;
    if (!make_view(*im.scene, options.width, options.height, view, error)) return false;
    view.cell = im.cell_of(view.position);
    const uint32_t W = options.width, H = options.height;
    if (acc.width != W || acc.height != H || acc.sum.size() != size_t(W) * H * 3) {
        acc.width = W, acc.height = H, acc.samples = 0;
        acc.sum.assign(size_t(W) * H * 3, 0.0);
        acc.stream.assign(size_t(W) * H, 0);
        acc.srgb.assign(size_t(W) * H * 3, 0);
    }
    // render()'s NSAMPLES = 1 is the pixel's centre and more are jittered, so the second call
    // starts again with two jittered samples; the sums add in render()'s order.
    const bool restart = acc.samples <= 1;
    const uint32_t count = acc.samples == 1 ? 2 : 1;
    const uint32_t total = restart ? count : acc.samples + 1;
    const bool jitter = total > 1;
    std::atomic<uint64_t> rays(0);
    const uint32_t tile_width = options.one_pixel_tiles ? 1 : kTileWidth;
    const uint32_t tile_height = options.one_pixel_tiles ? 1 : kTileHeight;
    for_each_tile(scheduler, W, H, tile_width, tile_height, [&](TilePixel *pixels, uint32_t n) {
        const uint64_t rays_before = t_rays;
        for (uint32_t i = 0; i < n; ++i) {
            const uint64_t pixel = uint64_t(pixels[i].y) * W + pixels[i].x;
            const double *px = &acc.sum[pixel * 3];
            pixels[i].rng = restart ? pixel_rng(options.seed, options.frame, pixel) : Rng::from_state(acc.stream[pixel]);
            if (!restart) pixels[i].sum = Vec3{px[0], px[1], px[2]};
        }
        im.trace_tile(view, pixels, n, count, jitter);
        for (uint32_t i = 0; i < n; ++i) {
            const uint64_t pixel = uint64_t(pixels[i].y) * W + pixels[i].x;
            const Vec3 sum = pixels[i].sum;
            double *px = &acc.sum[pixel * 3];
            px[0] = sum.x, px[1] = sum.y, px[2] = sum.z;
            acc.stream[pixel] = pixels[i].rng.state;
            unsigned char *out = &acc.srgb[pixel * 3];
            out[0] = srgb.encode(float(sum.x / total));
            out[1] = srgb.encode(float(sum.y / total));
            out[2] = srgb.encode(float(sum.z / total));
        }
        rays += t_rays - rays_before;
    });
    acc.samples = total;
    acc.rays = rays;
    return true;
}

std::vector<TreeBox> Renderer::tree_boxes(uint32_t max_depth) const
{
    // A scene does not show its tree, so the boxes are those of the same build, options and all,
    // over the same triangles: the meshes' one after another, in the order of their IDs.
    const Impl &im = *impl_;
    std::vector<TreeBox> boxes;
    if (!im.world) return boxes;
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    for (const MeshInstance &mi : im.scene->meshes) {
        const common::Mesh &mesh = mi.mesh;
        const uint32_t base = uint32_t(positions.size() / 3);
        positions.insert(positions.end(), mesh.positions.begin(), mesh.positions.end());
        for (uint32_t t = 0; t < mesh.triangle_count(); ++t)
            for (int k = 0; k < 3; ++k) indices.push_back(base + mesh.vertex(t, k));
    }
    kdrt_triangles all = {};
    all.positions = positions.data();
    all.vertex_count = uint32_t(positions.size() / 3);
    all.indices = indices.data();
    all.triangle_count = uint32_t(indices.size() / 3);
    common::ThreadScheduler scheduler(im.threads);
    kdrt_build_options options = im.options;
    options.scheduler = scheduler.hooks();
    kdrt_tree *tree = nullptr;
    if (kdrt_tree_build(&all, &options, &tree, nullptr) != KDRT_SUCCESS) return boxes;
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
        const uint32_t index = stack.back();
        stack.pop_back();
        kdrt_node_info info;
        if (kdrt_tree_node(tree, index, &info) != KDRT_SUCCESS) continue;
        boxes.push_back({to_vec(info.bounds.min), to_vec(info.bounds.max), info.depth, info.is_leaf != 0});
        if (!info.is_leaf && info.depth < max_depth) stack.push_back(info.above), stack.push_back(info.below);
    }
    kdrt_tree_free(tree);
    return boxes;
}

}  // namespace kr
