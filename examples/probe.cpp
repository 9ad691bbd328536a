// kdrt's closest-point and overlap queries as an engine uses them: light probes placed on a grid
// and snapped to the nearest surface (kdrt_closest_point), and the triangles within a blast
// radius collected (kdrt_overlap_sphere) and highlighted in a small image. Needs only kdrt.h and
// the C++ standard library.
//
//   kdrt-probe-example [OUT.ppm]
//
// Prints what it found and checks it against a brute force over every triangle; with OUT.ppm it
// also writes the image (binary PPM): the mesh shaded, the triangles in the ball red, the
// snapped probes white.
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace {

// A closed torus around the y axis, major radius 1, minor 0.35: rings * sides * 2 triangles.
void make_torus(int rings, int sides, std::vector<float> &positions, std::vector<uint32_t> &indices) {
    const double pi = 3.14159265358979323846;
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < sides; ++j) {
            const double u = 2 * pi * i / rings, v = 2 * pi * j / sides, r = 1.0 + 0.35 * std::cos(v);
            positions.push_back(float(r * std::cos(u)));
            positions.push_back(float(0.35 * std::sin(v)));
            positions.push_back(float(r * std::sin(u)));
        }
    for (int i = 0; i < rings; ++i)
        for (int j = 0; j < sides; ++j) {
            const uint32_t a = uint32_t(i * sides + j), b = uint32_t(((i + 1) % rings) * sides + j);
            const uint32_t c = uint32_t(((i + 1) % rings) * sides + (j + 1) % sides), d = uint32_t(i * sides + (j + 1) % sides);
            indices.insert(indices.end(), {a, b, c, a, c, d});
        }
}

// The distance from p to the triangle (a, b, c) in double, for the brute-force check (Ericson,
// Real-Time Collision Detection 5.1.5).
double point_triangle(const double p[3], const double a[3], const double b[3], const double c[3]) {
    auto dot = [](const double *x, const double *y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
    double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    for (int k = 0; k < 3; ++k) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k], bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
    const double d1 = dot(ab, ap), d2 = dot(ac, ap), d3 = dot(ab, bp), d4 = dot(ac, bp), d5 = dot(ab, cp), d6 = dot(ac, cp);
    const double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    double s = 0, t = 0;  // q = a + s ab + t ac
    if (d1 <= 0 && d2 <= 0) s = 0, t = 0;
    else if (d3 >= 0 && d4 <= d3) s = 1, t = 0;
    else if (vc <= 0 && d1 >= 0 && d3 <= 0) s = d1 / (d1 - d3), t = 0;
    else if (d6 >= 0 && d5 <= d6) s = 0, t = 1;
    else if (vb <= 0 && d2 >= 0 && d6 <= 0) s = 0, t = d2 / (d2 - d6);
    else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) t = (d4 - d3) / ((d4 - d3) + (d5 - d6)), s = 1 - t;
    else s = vb / (va + vb + vc), t = vc / (va + vb + vc);
    for (int k = 0; k < 3; ++k) q[k] = a[k] + s * ab[k] + t * ac[k] - p[k];
    return std::sqrt(dot(q, q));
}

struct Mesh {
    std::vector<float> positions;
    std::vector<uint32_t> indices;
    void corners(uint32_t t, double c[3][3]) const {
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) c[k][a] = positions[3 * indices[3 * t + k] + a];
    }
    uint32_t triangles() const { return uint32_t(indices.size() / 3); }
};

// kdrt_overlap_sphere's callback: every triangle found goes into the engine's list.
int collect(void *user, const kdrt_overlap *found) {
    static_cast<std::vector<uint32_t> *>(user)->push_back(found->triangle);
    return 1;  // go on
}

}  // namespace

int main(int argc, char **argv) {
    Mesh mesh;
    make_torus(96, 48, mesh.positions, mesh.indices);
    const kdrt_triangles view = {mesh.positions.data(), 0, uint32_t(mesh.positions.size() / 3), mesh.indices.data(),
                                 mesh.triangles()};
    kdrt_tree *tree = nullptr;
    kdrt_result r = kdrt_tree_build(&view, nullptr, &tree, nullptr);
    if (r != KDRT_SUCCESS) {
        std::fprintf(stderr, "kdrt_tree_build: %s\n", kdrt_result_string(r));
        return 1;
    }
    int failures = 0;

    // Probes: a 6 x 3 x 6 grid over the torus's box, each moved to the nearest point of the
    // surface, as an engine places light probes an artist scattered roughly. Those more than
    // 0.5 from any surface are dropped (max_distance): they answer KDRT_INVALID_ID.
    std::vector<float> snapped;
    int probes = 0, dropped = 0;
    double worst = 0;
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 6; ++k) {
                const float p[3] = {-1.5f + 0.6f * float(i), -0.5f + 0.5f * float(j), -1.5f + 0.6f * float(k)};
                kdrt_closest c;
                r = kdrt_closest_point(tree, p, 0.5f, &c);
                ++probes;
                if (r != KDRT_SUCCESS) {
                    std::printf("probe %d: %s\n", probes, kdrt_result_string(r));
                    ++failures;
                    continue;
                }
                // The brute force: the nearest triangle's distance, every triangle in double.
                const double q[3] = {p[0], p[1], p[2]};
                double nearest = INFINITY;
                for (uint32_t t = 0; t < mesh.triangles(); ++t) {
                    double corner[3][3];
                    mesh.corners(t, corner);
                    nearest = std::min(nearest, point_triangle(q, corner[0], corner[1], corner[2]));
                }
                if (c.triangle == KDRT_INVALID_ID) {
                    ++dropped;
                    if (nearest <= 0.5) std::printf("probe %d: dropped, but a triangle is %g away\n", probes, nearest), ++failures;
                    continue;
                }
                worst = std::max(worst, std::fabs(c.distance - nearest));
                // The snapped point lies on the triangle kdrt names: its own distance to it is ~0.
                double corner[3][3];
                mesh.corners(c.triangle, corner);
                const double s[3] = {c.point[0], c.point[1], c.point[2]};
                if (std::fabs(c.distance - nearest) > 1e-6 || point_triangle(s, corner[0], corner[1], corner[2]) > 1e-6) {
                    std::printf("probe %d: kdrt %g, brute force %g\n", probes, double(c.distance), nearest);
                    ++failures;
                }
                snapped.insert(snapped.end(), c.point, c.point + 3);
            }
    std::printf("probes: %d placed, %zu snapped to the surface, %d dropped (nothing within 0.5); "
                "largest difference from the brute force %.2g\n",
                probes, snapped.size() / 3, dropped, worst);

    // A blast at the highest snapped probe (the first of them): the triangles within 0.4 of it,
    // collected by the callback.
    size_t top = 0;
    for (size_t i = 3; i < snapped.size(); i += 3)
        if (snapped[i + 1] > snapped[top + 1]) top = i;
    const float centre[3] = {snapped[top], snapped[top + 1], snapped[top + 2]};
    const float radius = 0.4f;
    std::vector<uint32_t> hit;
    uint64_t count = 0;
    r = kdrt_overlap_sphere(tree, centre, radius, collect, &hit, &count);
    std::sort(hit.begin(), hit.end());
    // The brute force: every triangle within the radius, with a margin for rounding either way.
    const double c[3] = {centre[0], centre[1], centre[2]};
    size_t missed = 0, extra = 0, inside = 0;
    for (uint32_t t = 0; t < mesh.triangles(); ++t) {
        double corner[3][3];
        mesh.corners(t, corner);
        const double d = point_triangle(c, corner[0], corner[1], corner[2]);
        const bool found = std::binary_search(hit.begin(), hit.end(), t);
        inside += d <= radius;
        missed += d < radius - 1e-6 && !found;
        extra += d > radius + 1e-6 && found;
    }
    const bool unique = std::adjacent_find(hit.begin(), hit.end()) == hit.end();
    std::printf("blast: %llu of %u triangles within %.1f of (%.3f, %.3f, %.3f) (brute force: %zu); %zu missed, "
                "%zu extra, %s\n",
                (unsigned long long)count, mesh.triangles(), double(radius), double(centre[0]), double(centre[1]),
                double(centre[2]), inside, missed, extra, unique ? "each once" : "some twice");
    if (r != KDRT_SUCCESS || count != hit.size() || missed || extra || !unique || count == 0) ++failures;

    // The image: a pinhole camera above and in front, the ball's triangles red, the probes white.
    if (argc > 1) {
        const int w = 320, h = 240;
        std::vector<unsigned char> rgb(size_t(w) * h * 3);
        std::vector<char> in_ball(mesh.triangles(), 0);
        for (uint32_t t : hit) in_ball[t] = 1;
        const float eye[3] = {0.f, 2.2f, 2.6f};
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                // Looking at the origin: forward (0, -0.65, -0.76), right (1, 0, 0), up (0, 0.76, -0.65).
                const float sx = (2.f * (float(x) + 0.5f) / float(w) - 1.f) * 0.75f * float(w) / float(h);
                const float sy = (1.f - 2.f * (float(y) + 0.5f) / float(h)) * 0.75f;
                kdrt_ray ray = {};
                ray.org[0] = eye[0], ray.org[1] = eye[1], ray.org[2] = eye[2];
                ray.dir[0] = sx, ray.dir[1] = -0.65f + 0.76f * sy, ray.dir[2] = -0.76f - 0.65f * sy;
                ray.tmin = 0.f, ray.tmax = INFINITY;
                kdrt_hit hitinfo;
                unsigned char *px = &rgb[3 * (size_t(y) * w + x)];
                px[0] = 30, px[1] = 30, px[2] = 40;
                if (!kdrt_intersect(tree, &ray, &hitinfo)) continue;
                double corner[3][3], e0[3], e1[3], n[3];
                mesh.corners(hitinfo.triangle, corner);
                for (int a = 0; a < 3; ++a) e0[a] = corner[1][a] - corner[0][a], e1[a] = corner[2][a] - corner[0][a];
                n[0] = e0[1] * e1[2] - e0[2] * e1[1], n[1] = e0[2] * e1[0] - e0[0] * e1[2], n[2] = e0[0] * e1[1] - e0[1] * e1[0];
                const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                const double dl = len > 0 ? std::fabs(n[0] * 0.3 + n[1] * 0.9 + n[2] * 0.3) / (len * 0.995) : 0;
                const double shade = 0.2 + 0.8 * std::min(1.0, dl);
                const bool red = in_ball[hitinfo.triangle];
                px[0] = (unsigned char)(255 * shade), px[1] = (unsigned char)(255 * shade * (red ? 0.2 : 0.8));
                px[2] = (unsigned char)(255 * shade * (red ? 0.2 : 0.7));
            }
        // The probes: a white dot where each snapped point lands in the image.
        for (size_t i = 0; i < snapped.size(); i += 3) {
            const double d[3] = {snapped[i] - eye[0], snapped[i + 1] - eye[1], snapped[i + 2] - eye[2]};
            const double f = d[0] * 0.0 + d[1] * -0.65 + d[2] * -0.76, u = d[0], v = d[1] * 0.76 + d[2] * -0.65;
            if (f <= 0) continue;
            const int x = int((u / f / (0.75 * w / h) + 1) * 0.5 * w), y = int((1 - v / f / 0.75) * 0.5 * h);
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h)
                        std::fill_n(&rgb[3 * (size_t(y + dy) * w + x + dx)], 3, (unsigned char)255);
        }
        std::FILE *out = std::fopen(argv[1], "wb");
        const bool ok = out && std::fprintf(out, "P6\n%d %d\n255\n", w, h) > 0 &&
                        std::fwrite(rgb.data(), 1, rgb.size(), out) == rgb.size();
        if (!out || std::fclose(out) != 0 || !ok) {
            std::fprintf(stderr, "cannot write %s\n", argv[1]);
            ++failures;
        } else {
            std::printf("image: %s, %dx%d\n", argv[1], w, h);
        }
    }
    kdrt_tree_free(tree);
    if (failures) {
        std::printf("%d check(s) failed\n", failures);
        return 1;
    }
    std::printf("all checks passed\n");
    return 0;
}
