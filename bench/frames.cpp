#include "frames.hpp"
#include "scenes.hpp"  // unit_sized, median
#include "common/random.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace kb {

namespace {

constexpr double kPitch = 1.5;        // the field's grid: unit-sized meshes, scaled up to 1.2
constexpr double kFramesPerSecond = 30;

// Appends to `mesh` a grid of quads (2 triangles each) over the rectangle from corner c along
// edges a and b, `cells` a side.
void add_grid(common::Mesh &mesh, const double c[3], const double a[3], const double b[3], uint32_t cells) {
    const uint32_t base = mesh.vertex_count();
    for (uint32_t j = 0; j <= cells; ++j)
        for (uint32_t i = 0; i <= cells; ++i)
            for (int k = 0; k < 3; ++k)
                mesh.positions.push_back(float(c[k] + a[k] * double(i) / cells + b[k] * double(j) / cells));
    for (uint32_t j = 0; j < cells; ++j)
        for (uint32_t i = 0; i < cells; ++i) {
            const uint32_t v = base + j * (cells + 1) + i, w = v + cells + 1;
            mesh.indices.insert(mesh.indices.end(), {v, v + 1, w + 1, v, w + 1, w});
        }
}

// mesh (unit_sized) scaled by s and moved to `at`, in world space.
common::Mesh placed(const common::Mesh &mesh, double s, const double at[3]) {
    common::Mesh out = unit_sized(mesh);
    for (size_t i = 0; i < out.positions.size(); ++i) out.positions[i] = float(s * out.positions[i] + at[i % 3]);
    return out;
}

void normalise(double v[3]) {
    const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; ++k) v[k] /= n;
}

}  // namespace

FramesWorld frames_world(const std::vector<common::Mesh> &prototypes, const std::vector<common::Mesh> &statues,
                         const common::Mesh &deforming, uint32_t count, uint32_t seed) {
    FramesWorld w;
    w.prototypes = prototypes;
    common::Rng rng(seed);
    const uint32_t columns = std::max(1u, uint32_t(std::ceil(std::sqrt(double(count)) - 1e-9)));
    const uint32_t rows = (count + columns - 1) / columns;
    const double half = w.half = std::max(2.0, 0.5 * kPitch * std::max(columns, rows));
    for (uint32_t i = 0; i < count && !prototypes.empty(); ++i) {
        FramesWorld::Mover m;
        m.prototype = uint32_t(i % prototypes.size());
        // A uniformly random rotation (Shoemake's unit quaternion from three uniforms), as the field's.
        const double u1 = rng.uniform(), u2 = 2 * M_PI * rng.uniform(), u3 = 2 * M_PI * rng.uniform();
        const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
        const double x = a * std::sin(u2), y = a * std::cos(u2), z = b * std::sin(u3), q = b * std::cos(u3);
        const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * q),     2 * (x * z + y * q),
                             2 * (x * y + z * q),     1 - 2 * (x * x + z * z), 2 * (y * z - x * q),
                             2 * (x * z - y * q),     2 * (y * z + x * q),     1 - 2 * (x * x + y * y)};
        std::copy(r, r + 9, m.turn);
        m.scale = rng.range(0.8, 1.2);
        m.base[0] = kPitch * (double(i % columns) - 0.5 * (columns - 1));
        m.base[1] = 0.6 * m.scale + 0.1;  // above the floor, bobbing by 0.1
        m.base[2] = kPitch * (double(i / columns) - 0.5 * (rows - 1));
        m.phase = 2 * M_PI * rng.uniform();
        m.speed = rng.range(0.5, 1.5) * (rng.uniform() < 0.5 ? -1 : 1);
        w.movers.push_back(m);
    }

    // Behind the field: the statues and the deforming mesh in a row (the deforming one in the
    // middle), a wall behind them, and a floor under it all.
    const double size = 0.9 * half, row_z = -half - 1 - 0.5 * size;
    const uint32_t slots = uint32_t(statues.size()) + 1, middle = slots / 2;
    const double wall_z = row_z - 0.8 * size - 1;
    const double width = std::max(1.5 * half, 0.6 * size * slots) + 2;
    common::Mesh floor, wall;
    floor.name = "floor", wall.name = "wall";
    {
        const double c[3] = {-width, 0, wall_z}, a[3] = {2 * width, 0, 0}, b[3] = {0, 0, half + 2 - wall_z};
        add_grid(floor, c, b, a, 16);  // wound to face up
        const double cw[3] = {-width, 0, wall_z}, aw[3] = {2 * width, 0, 0}, bw[3] = {0, 2 * size + 2, 0};
        add_grid(wall, cw, aw, bw, 4);
    }
    w.level.push_back(std::move(floor));
    w.level.push_back(std::move(wall));
    for (uint32_t s = 0, slot = 0; s < statues.size(); ++s, ++slot) {
        if (slot == middle) ++slot;
        const double at[3] = {1.2 * size * (double(slot) - 0.5 * (slots - 1)), 0.5 * size + 0.05, row_z};
        w.level.push_back(placed(statues[s], size, at));
    }
    w.deforming = unit_sized(deforming);
    const double at[3] = {1.2 * size * (double(middle) - 0.5 * (slots - 1)), 0.5 * size + 0.05, row_z};
    const float t[12] = {float(size), 0, 0, float(at[0]), 0, float(size), 0, float(at[1]), 0, 0, float(size), float(at[2])};
    std::copy(t, t + 12, w.deforming_transform);

    // The camera above the field's front edge, looking down over it to the statues; the light above.
    const double eye[3] = {0, 0.6 * half + 2, 1.2 * half + 3}, target[3] = {0, 0.15 * half, -0.7 * half};
    double f[3] = {target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
    normalise(f);
    double r[3] = {-f[2], 0, f[0]};  // f x (0, 1, 0)
    normalise(r);
    const double u[3] = {r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
    const double tan_half = 0.9;  // a wide view, as games have
    for (int k = 0; k < 3; ++k) {
        w.eye[k] = float(eye[k]);
        w.forward[k] = float(f[k]);
        w.right[k] = float(tan_half * r[k]);
        w.up[k] = float(tan_half * u[k]);
    }
    const double light[3] = {0.5 * half, 2 * half + 3, 0.5 * half};
    for (int k = 0; k < 3; ++k) w.light[k] = float(light[k]);

    uint32_t next = 0;
    for (const FramesWorld::Mover &m : w.movers) w.first.push_back(next), next += prototypes[m.prototype].triangle_count();
    for (const common::Mesh &mesh : w.level) w.first.push_back(next), next += mesh.triangle_count();
    w.first.push_back(next);
    return w;
}

void mover_transform(const FramesWorld &world, uint32_t i, unsigned frame, float out[12]) {
    const FramesWorld::Mover &m = world.movers[i];
    const double seconds = frame / kFramesPerSecond;
    const double angle = m.phase + m.speed * M_PI * seconds;  // half a turn a second at speed 1
    const double c = std::cos(angle), s = std::sin(angle);
    // Turned about the vertical by the angle, after its own rotation, and scaled.
    const double spin[9] = {c, 0, s, 0, 1, 0, -s, 0, c};
    const double at[3] = {m.base[0] + 0.25 * c, m.base[1] + 0.1 * std::sin(2 * angle), m.base[2] + 0.25 * s};
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) {
            double v = 0;
            for (int k = 0; k < 3; ++k) v += spin[3 * row + k] * m.turn[3 * k + col];
            out[4 * row + col] = float(m.scale * v);
        }
        out[4 * row + 3] = float(at[row]);
    }
}

void deformed_positions(const FramesWorld &world, unsigned frame, std::vector<float> &out) {
    const std::vector<float> &rest = world.deforming.positions;
    out.resize(rest.size() + 4);
    const double seconds = frame / kFramesPerSecond, amplitude = 0.02;
    for (size_t v = 0; v + 2 < rest.size(); v += 3) {
        const double x = rest[v], y = rest[v + 1], z = rest[v + 2];
        const double wave = 2 * M_PI * (2 * y - seconds);  // a wave a second travelling up the mesh
        out[v] = float(x + amplitude * std::sin(wave + 3 * z));
        out[v + 1] = float(y + 0.5 * amplitude * std::sin(wave));
        out[v + 2] = float(z + amplitude * std::cos(wave + 3 * x));
    }
    std::fill(out.end() - 4, out.end(), 0.0f);
}

std::vector<kdrt_ray> frames_camera_rays(const FramesWorld &world, unsigned width, unsigned height) {
    std::vector<kdrt_ray> rays;
    rays.reserve(size_t(width) * height);
    const double aspect = double(width) / height;
    for (unsigned y = 0; y < height; ++y)
        for (unsigned x = 0; x < width; ++x) {
            const double sx = (2.0 * (x + 0.5) / width - 1.0) * aspect, sy = 1.0 - 2.0 * (y + 0.5) / height;
            kdrt_ray r{};
            for (int k = 0; k < 3; ++k) {
                r.org[k] = world.eye[k];
                r.dir[k] = float(world.forward[k] + sx * world.right[k] + sy * world.up[k]);
            }
            r.tmin = 0, r.tmax = INFINITY;
            rays.push_back(r);
        }
    return rays;
}

std::string frames_csv_header() {
    return "Phase;Instances;Threads;Variant;KdrtMs;EmbreeMs;Ratio;KdrtMaxMs;EmbreeMaxMs;Frames;Count;Mismatches;"
           "ComparedRays;EmbreeQuality";
}

std::string frames_csv_row(const FramesRow &row) {
    const double kdrt = median(row.kdrt_ms), kdrt_max = row.kdrt_ms.empty() ? 0 : *std::max_element(row.kdrt_ms.begin(), row.kdrt_ms.end());
    char buf[512];
    int n = std::snprintf(buf, sizeof buf, "%s;%u;%u;%s;%.3f;", row.phase.c_str(), row.instances, row.threads,
                          row.variant.c_str(), kdrt);
    std::string line(buf, size_t(n));
    if (row.embree) {
        const double embree = median(row.embree_ms);
        const double embree_max = row.embree_ms.empty() ? 0 : *std::max_element(row.embree_ms.begin(), row.embree_ms.end());
        n = std::snprintf(buf, sizeof buf, "%.3f;%.3f;%.3f;%.3f;", embree, kdrt > 0 ? embree / kdrt : 0.0, kdrt_max,
                          embree_max);
    } else {
        n = std::snprintf(buf, sizeof buf, ";;%.3f;;", kdrt_max);
    }
    line.append(buf, size_t(n));
    n = std::snprintf(buf, sizeof buf, "%zu;%llu;", row.kdrt_ms.size(), (unsigned long long)row.count);
    line.append(buf, size_t(n));
    if (row.compared) {
        n = std::snprintf(buf, sizeof buf, "%llu;%llu;", (unsigned long long)row.mismatches,
                          (unsigned long long)row.compared_rays);
        line.append(buf, size_t(n));
    } else {
        line += ";;";
    }
    if (row.embree) line += row.embree_quality;
    return line;
}

}  // namespace kb
