// What a game engine does with a kdrt_scene: the static level as mesh geometries (one tree over
// all of them), a few meshes built once as trees, and dozens of instances of them moving every
// frame. A frame sets the moved transforms and commits, which rebuilds only the small top level
// over the instances' boxes; then it traces camera rays from inside the player's own box
// (a filter skips it) and shadow rays that a mask bit lets some objects stay out of. Last, a
// crate is spawned, hidden, shown and destroyed, each at the next commit. The program
// checks what it shows and exits 1 when a check fails. Needs only kdrt.h and the C++ library.
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

struct Mesh {
    std::vector<float> positions;  // x, y, z a vertex
    std::vector<uint32_t> indices; // 3 a triangle
    kdrt_triangles view() const {
        kdrt_triangles m = {};
        m.positions = positions.data(), m.vertex_count = uint32_t(positions.size() / 3);
        m.indices = indices.data(), m.triangle_count = uint32_t(indices.size() / 3);
        return m;
    }
};

// The box from (x0, y0, z0) to (x1, y1, z1): 8 corners (bits 0, 1, 2 of a corner's number: x, y, z).
static Mesh box(float x0, float y0, float z0, float x1, float y1, float z1) {
    static const uint32_t faces[24] = {0, 2, 6, 4, 1, 3, 7, 5, 0, 1, 5, 4, 2, 3, 7, 6, 0, 1, 3, 2, 4, 5, 7, 6};
    Mesh m;
    for (uint32_t c = 0; c < 8; ++c)
        m.positions.insert(m.positions.end(), {c & 1 ? x1 : x0, c & 2 ? y1 : y0, c & 4 ? z1 : z0});
    for (const uint32_t *f = faces; f < faces + 24; f += 4)
        m.indices.insert(m.indices.end(), {f[0], f[1], f[2], f[0], f[2], f[3]}); // a face, 2 triangles
    return m;
}

// A surface of nu x rows vertices, at(i, j) each; u wraps round (and v too when wrap_v). The
// seams share vertices by index, so the mesh is closed and no ray slips through it.
template <typename At> static Mesh grid(uint32_t nu, uint32_t nv, bool wrap_v, At at) {
    Mesh m;
    const uint32_t rows = wrap_v ? nv : nv + 1;
    for (uint32_t j = 0; j < rows; ++j)
        for (uint32_t i = 0; i < nu; ++i) at(i, j, m.positions);
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            const uint32_t row = j * nu, next_row = (j + 1) % rows * nu, next = (i + 1) % nu;
            m.indices.insert(m.indices.end(), {row + i, next_row + i, row + next, row + next, next_row + i, next_row + next});
        }
    return m;
}

static const float kPi = 3.14159265f;
static Mesh sphere(float r) { // the poles exact (one point each: their rows' zero-area triangles are left out)
    return grid(24, 12, false, [r](uint32_t i, uint32_t j, std::vector<float> &p) {
        const float ring = j == 0 || j == 12 ? 0 : r * std::sin(kPi * j / 12), a = 2 * kPi * i / 24;
        p.insert(p.end(), {ring * std::cos(a), r * std::cos(kPi * j / 12), ring * std::sin(a)});
    });
}
static Mesh torus(float major, float minor) { // about the y axis
    return grid(32, 12, true, [=](uint32_t i, uint32_t j, std::vector<float> &p) {
        const float a = 2 * kPi * i / 32, b = 2 * kPi * j / 12, d = major + minor * std::cos(b);
        p.insert(p.end(), {d * std::cos(a), minor * std::sin(b), d * std::sin(a)});
    });
}

// Turned by yaw about y after pitch about x, then moved to (x, y, z): kdrt's 3x4 [R | t], row-major.
static void place(float out[12], float yaw, float pitch, float x, float y, float z) {
    const float c = std::cos(yaw), s = std::sin(yaw), cp = std::cos(pitch), sp = std::sin(pitch);
    const float m[12] = {c, s * sp, s * cp, x, 0, cp, -sp, y, -s, c * sp, c * cp, z};
    for (int k = 0; k < 12; ++k) out[k] = m[k];
}

// Geometry IDs are the engine's own, and so are the mask bits: what each kind of ray may see.
static const uint32_t kGround = 1, kWallNorth = 2, kWallEast = 3, kPlayer = 10, kFirstAgent = 100, kAgents = 36;
static const uint32_t kSeen = 1, kCastsShadow = 2, kPickable = 4;
static const uint32_t kTarget = kFirstAgent; // the crate the checks follow, the only pickable thing
enum Kind { kGroundKind, kWall, kPlayerKind, kCrate, kOrb, kRing, kSky, kKinds };
static const char *const kKindNames[kKinds] = {"ground", "walls", "player", "crates", "orbs", "rings", "sky"};
static Kind kind_of(uint32_t id) {
    if (id == kGround) return kGroundKind;
    if (id == kWallNorth || id == kWallEast) return kWall;
    return id == kPlayer ? kPlayerKind : Kind(kCrate + (id - kFirstAgent) % 3);
}

// Agent a walks round ring a / 12 (radius 4, 7 or 10), each ring at its own speed, spinning as
// it goes; a ring's agents keep their spacing, so no two ever overlap. Every third is an orb,
// bobbing; the tori stand upright.
static void agent_pose(uint32_t a, int frame, float out[12], float *x = nullptr, float *z = nullptr) {
    const uint32_t ring = a / 12;
    const float radius = 4.0f + 3.0f * ring, speed = ring == 0 ? 0.35f : ring == 1 ? -0.2f : 0.12f;
    const float angle = 2 * kPi * (a % 12) / 12 + speed * frame;
    const float px = radius * std::cos(angle), pz = radius * std::sin(angle);
    const float y = a % 3 == 0 ? 0.5f : a % 3 == 1 ? 1.2f + 0.3f * std::sin(0.7f * frame + a) : 0.6f;
    place(out, 0.3f * frame + a, a % 3 == 2 ? kPi / 2 : 0, px, y, pz);
    if (x) *x = px, *z = pz;
}

// The filter: every candidate counts except those of one geometry, the surface a ray leaves
// (here the player's own body, which the camera sits in).
static int skip_geometry(void *user, const kdrt_ray *, const kdrt_hit *candidate) {
    return candidate->geometry != *static_cast<const uint32_t *>(user);
}

static int failures = 0;
static void check(bool ok, const char *what, int frame) {
    if (!ok) std::printf("FAILED, frame %d: %s\n", frame, what), ++failures;
}
// Does a ray straight down at (x, z) hit geometry id? Only the pickable bit: nothing else counts.
static bool picks(const kdrt_scene *scene, uint32_t id, float x, float z) {
    const kdrt_ray ray = {{x, 10, z}, 0, {0, -1, 0}, INFINITY, 0};
    kdrt_query pick = kdrt_default_query();
    pick.mask = kPickable;
    kdrt_hit hit;
    return kdrt_scene_intersect(scene, &ray, &pick, &hit) && hit.geometry == id;
}
static bool picks_target(const kdrt_scene *scene, float x, float z) { return picks(scene, kTarget, x, z); }

int main() {
    // The level, static: its meshes go into one tree together when the scene is built.
    const Mesh ground = box(-15, -0.5f, -15, 15, 0, 15);
    const Mesh north = box(-14, 0, -14, 14, 3, -13), east = box(13, 0, -13, 14, 3, 14); // walls
    // The props, each built once as a tree and placed any number of times.
    const Mesh shapes[3] = {box(-0.5f, -0.5f, -0.5f, 0.5f, 0.5f, 0.5f), sphere(0.5f), torus(0.4f, 0.15f)};
    kdrt_tree *trees[3] = {};
    for (int k = 0; k < 3; ++k) {
        const kdrt_triangles view = shapes[k].view();
        if (kdrt_tree_build(&view, nullptr, &trees[k], nullptr) != KDRT_SUCCESS) return std::printf("build failed\n"), 1;
    }
    const kdrt_triangles level[3] = {ground.view(), north.view(), east.view()};
    std::vector<kdrt_geometry> geometries = {kdrt_mesh_geometry(kGround, &level[0]),
                                             kdrt_mesh_geometry(kWallNorth, &level[1]),
                                             kdrt_mesh_geometry(kWallEast, &level[2])};
    // The player: the unit crate scaled to 0.6 x 1.8 x 0.6 (scales need not be uniform), standing
    // at the origin.
    const float player_pose[12] = {0.6f, 0, 0, 0, 0, 1.8f, 0, 0.9f, 0, 0, 0.6f, 0};
    geometries.push_back(kdrt_instance_geometry(kPlayer, trees[0], player_pose));
    float pose[12];
    for (uint32_t a = 0; a < kAgents; ++a) {
        agent_pose(a, 0, pose);
        geometries.push_back(kdrt_instance_geometry(kFirstAgent + a, trees[a % 3], pose));
        // Orbs glow: the camera sees them, the sun does not (no shadow bit).
        geometries.back().mask = a % 3 == 1 ? kSeen : kSeen | kCastsShadow | (kFirstAgent + a == kTarget ? kPickable : 0);
    }
    for (kdrt_geometry &g : geometries) if (g.id < kFirstAgent) g.mask = kSeen | kCastsShadow;
    kdrt_scene *scene = nullptr;
    kdrt_build_report report;
    const kdrt_result r = kdrt_scene_build(geometries.data(), uint32_t(geometries.size()), nullptr, &scene, &report);
    if (r != KDRT_SUCCESS) return std::printf("scene: %s (geometry %u)\n", kdrt_result_string(r), report.invalid_geometry), 1;
    std::printf("scene: 3 level meshes, 3 shapes, %u instances (the player and %u agents)\n", kAgents + 1, kAgents);

    uint32_t player = kPlayer;
    kdrt_query camera = kdrt_default_query(), shadow = kdrt_default_query();
    camera.mask = kSeen, camera.filter = skip_geometry, camera.user = &player;
    shadow.mask = kCastsShadow;
    const float eye[3] = {0, 1.5f, 0}, sun[3] = {0.3f, 1, 0.2f}; // the eye is inside the player's box
    unsigned camera_rays = 0, filtered_player = 0, unfiltered_player = 0, orb_checks = 0, target_stays = 0, target_moves = 0;
    double commit_us = 0;
    const int frames = 8;
    for (int frame = 1; frame <= frames; ++frame) {
        // Move every agent. Until the commit, queries see the scene as it was.
        float old_x, old_z, new_x, new_z;
        agent_pose(kTarget - kFirstAgent, frame - 1, pose, &old_x, &old_z);
        agent_pose(kTarget - kFirstAgent, frame, pose, &new_x, &new_z);
        for (uint32_t a = 0; a < kAgents; ++a) {
            agent_pose(a, frame, pose);
            if (kdrt_scene_set_transform(scene, kFirstAgent + a, pose) != KDRT_SUCCESS) return 1;
        }
        const bool stayed = picks_target(scene, old_x, old_z) && !picks_target(scene, new_x, new_z);
        check(stayed, "the target moved before the commit", frame), target_stays += stayed;
        const auto start = std::chrono::steady_clock::now();
        if (kdrt_scene_commit(scene) != KDRT_SUCCESS) return std::printf("commit failed\n"), 1; // the top level only
        const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
        commit_us += us;
        const bool moved = picks_target(scene, new_x, new_z) && !picks_target(scene, old_x, old_z);
        check(moved, "the target is not where it moved to", frame), target_moves += moved;

        // A 32 x 16 grid of camera rays over 90 by 40 degrees, looking along +x, and a shadow ray
        // to the sun from every surface they hit.
        unsigned hits[kKinds] = {}, shadow_rays = 0, shadowed = 0;
        for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 32; ++x) {
                const float yaw = (x + 0.5f) / 32 * kPi / 2 - kPi / 4, pitch = 0.17f - (y + 0.5f) / 16 * 0.7f;
                const float level = std::cos(pitch); // the direction's length in the ground plane
                const kdrt_ray ray = {{eye[0], eye[1], eye[2]}, 0,
                                      {level * std::cos(yaw), std::sin(pitch), level * std::sin(yaw)}, INFINITY, 0};
                kdrt_hit hit;
                // Without the filter every ray hits the box it starts in; with it, none does.
                unfiltered_player += kdrt_scene_intersect(scene, &ray, nullptr, &hit) && hit.geometry == kPlayer;
                ++camera_rays;
                if (!kdrt_scene_intersect(scene, &ray, &camera, &hit)) { ++hits[kSky]; continue; }
                ++hits[kind_of(hit.geometry)], filtered_player += hit.geometry == kPlayer;
                kdrt_ray to_sun;
                kdrt_scene_spawn_ray(scene, &hit, sun, &to_sun); // off the surface, world space
                ++shadow_rays, shadowed += kdrt_scene_occluded(scene, &to_sun, &shadow);
            }
        // Orbs cast no shadow: straight up from the ground under one, a shadow ray is free,
        // while a ray of every mask bit meets the orb.
        for (uint32_t a = 1; a < kAgents; a += 3) {
            float x, z;
            agent_pose(a, frame, pose, &x, &z);
            const kdrt_ray up = {{x, 0.01f, z}, 0, {0, 1, 0}, INFINITY, 0};
            const bool ok = !kdrt_scene_occluded(scene, &up, &shadow) && kdrt_scene_occluded(scene, &up, nullptr);
            check(ok, "an orb blocks the sun, or no ray meets it", frame), orb_checks += ok;
        }
        std::printf("frame %d: %u agents moved, commit %.1f us; 512 rays:", frame, kAgents, us);
        for (int k = 0; k < kKinds; ++k) std::printf(" %s %u%s", kKindNames[k], hits[k], k + 1 < kKinds ? "," : ";");
        std::printf(" %u shadow rays, %.1f%% shadowed\n", shadow_rays, 100.0 * shadowed / (shadow_rays ? shadow_rays : 1));
    }

    // Objects come and go: a crate spawned between two rings, hidden, shown again and destroyed.
    // Each change shows from the next commit on, and an ID detached is free again.
    const uint32_t spawned = kFirstAgent + kAgents;
    float spot[12];
    place(spot, 0.4f, 0, 5.5f, 0.5f, 0);
    kdrt_geometry crate = kdrt_instance_geometry(spawned, trees[0], spot);
    crate.mask = kSeen | kCastsShadow | kPickable;
    const char *steps[4] = {"spawned", "hidden", "shown", "destroyed"};
    for (int step = 0; step < 4; ++step) {
        const kdrt_result changed = step == 0   ? kdrt_scene_attach(scene, &crate)
                                    : step == 3 ? kdrt_scene_detach(scene, spawned)
                                                : kdrt_scene_enable(scene, spawned, step == 2);
        const bool before = picks(scene, spawned, 5.5f, 0);
        check(changed == KDRT_SUCCESS && before == (step == 1 || step == 3), "a change showed before its commit", frames + 1 + step);
        if (kdrt_scene_commit(scene) != KDRT_SUCCESS) return std::printf("commit failed\n"), 1;
        const bool after = picks(scene, spawned, 5.5f, 0);
        check(after == (step == 0 || step == 2), "a change did not show after its commit", frames + 1 + step);
        std::printf("crate %u %s: %s\n", spawned, steps[step], after ? "picked" : "not there");
    }
    check(kdrt_scene_attach(scene, &crate) == KDRT_SUCCESS, "the destroyed crate's ID is not free", frames + 5);

    check(filtered_player == 0 && unfiltered_player == camera_rays, "the player's filter", frames);
    std::printf("player: %u of %u filtered rays hit it, %u of %u unfiltered ones did\n", filtered_player, camera_rays,
                unfiltered_player, camera_rays);
    std::printf("target: where it was before %u of %d commits, where it moved to after %u\n", target_stays, frames, target_moves);
    std::printf("orbs: %u of %d checks cast no shadow and meet an all-bits ray\n", orb_checks, frames * 12);
    std::printf("commit: %.1f us a frame on average, for %u instances\n", commit_us / frames, kAgents + 1);
    kdrt_scene_free(scene); // before the trees it borrows
    for (kdrt_tree *t : trees) kdrt_tree_free(t);
    std::printf(failures ? "%d checks FAILED\n" : "all checks passed\n", failures);
    return failures ? 1 : 0;
}
