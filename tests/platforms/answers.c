/* The same answers on every platform, bit for bit: a stored file of rays and their expected
   answers (tests/platforms/answers.txt), checked on each target CI builds (x86-64 with every
   kernel, aarch64, i386 with SSE2, mingw under wine, wasm under node).

     answers FILE            check every answer in FILE with every kernel this build has, under
                             both builders and both intersectors; then load the saved trees
                             beside FILE (answers.kdrt) and check them as well (below); exit 1
                             on any difference
     answers --write FILE    write FILE from this build's scalar kernel, and answers.kdrt beside
                             it from the trees that answered (only after a change that is meant
                             to change answers or the saved format, and say why in the commit)

   The mesh is made here from integers scaled by powers of two (no libm: the C libraries of the
   targets round sin and cos differently), so every target has the same floats. The rays are in
   the file. An answer line holds, as hexadecimal bits, what each query returns for its ray:
   the nearest hit (triangle, t, u, v), whether the ray is occluded, the 3 nearest hits, the hit's
   surface point and normal, the reflected ray kdrt_spawn_ray() makes and its nearest hit, the
   refracted direction and the Fresnel reflectance, and the nearest hit in a scene of the mesh
   and two instances of it; then, with the fast intersector, the nearest hit and occlusion on
   a median tree and on an SAH tree (its answers may depend on the tree: a ray through an edge
   can meet both triangles of it, or neither, and which is tested depends on the cells; the
   watertight test's cannot). The batch calls must give the single calls' answers. Start cells are left out: they name nodes,
   and trees may differ where libc's qsort orders ties differently; no answer depends on them.

   Saved trees, made on x86-64 and loaded everywhere: answers.kdrt holds, back to back as
   kdrt_tree_save() and kdrt_scene_save_meshes() wrote them when FILE was written, the watertight
   SAH tree, the fast median and fast SAH trees and the scene's mesh tree that gave FILE's
   answers. Each target loads them with kdrt_tree_load() and kdrt_scene_load() against the mesh
   made here, copied and in place (64-byte aligned), with every kernel it has; the loaded trees
   and the scene over them must give every answer of FILE (the fast trees' answers too, which are
   the saved trees' own), and each must save again to its bytes in answers.kdrt. A file that does
   not load (damaged, another format version, a mesh whose floats differ here) fails the check.
   Strict C99, the header only. */
#define KDRT_IMPLEMENTATION
#include "kdrt.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GRID 16                     /* quads a side of the height field */
#define GRID_VERTICES ((GRID + 1) * (GRID + 1))
#define EXTRA_TRIANGLES 24          /* tilted triangles crossing the field */
#define VERTEX_COUNT (GRID_VERTICES + 3 * EXTRA_TRIANGLES)
#define TRIANGLE_COUNT (2 * GRID * GRID + EXTRA_TRIANGLES)
#define RAY_COUNT 640
#define RAY_WORDS 8                 /* org, tmin, dir, tmax */
#define WATERTIGHT_WORDS 40
#define FAST_WORDS 10            /* 5 a builder */
#define ANSWER_WORDS (WATERTIGHT_WORDS + FAST_WORDS)
#define MAX_REPORTED 8              /* differences printed a configuration */

static uint32_t bits_of(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static float float_of(uint32_t u)
{
    float x;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* A 32-bit integer hash (lowbias32): the same numbers everywhere. */
static uint32_t hash(uint32_t x)
{
    x ^= x >> 16, x *= 0x7feb352du, x ^= x >> 15, x *= 0x846ca68bu, x ^= x >> 16;
    return x;
}

/* A float in [-1, 1) with 16 bits: exact on every target (an integer over a power of two). */
static float unit(uint32_t seed) { return (float)((int32_t)(hash(seed) >> 16) - 32768) / 32768.0f; }

/* The height field over [-1, 1]^2 (shared edges and vertices everywhere) and tilted triangles
   crossing it, so rays meet edges, vertices, overlaps and ties. */
static void make_mesh(float *v, uint32_t *idx)
{
    uint32_t i, j, k = 0, t = 0;
    for (j = 0; j <= GRID; ++j)
        for (i = 0; i <= GRID; ++i, ++k) {
            v[3 * k + 0] = (float)((int)i - GRID / 2) / (float)(GRID / 2);
            v[3 * k + 1] = (float)((int)j - GRID / 2) / (float)(GRID / 2);
            v[3 * k + 2] = unit(k) / 8.0f;
        }
    for (j = 0; j < GRID; ++j)
        for (i = 0; i < GRID; ++i) {
            const uint32_t a = j * (GRID + 1) + i, b = a + 1, c = a + GRID + 1, d = c + 1;
            idx[t++] = a, idx[t++] = b, idx[t++] = d; /* counter-clockwise from above */
            idx[t++] = a, idx[t++] = d, idx[t++] = c;
        }
    for (i = 0; i < EXTRA_TRIANGLES; ++i)
        for (j = 0; j < 3; ++j, ++k) {
            v[3 * k + 0] = unit(1000 + 9 * i + 3 * j) * 1.25f;
            v[3 * k + 1] = unit(1001 + 9 * i + 3 * j) * 1.25f;
            v[3 * k + 2] = unit(1002 + 9 * i + 3 * j) / 2.0f;
            idx[t++] = k;
        }
}

/* The rays of a new file: from above at random points, aimed at the field's vertices and edge
   midpoints exactly, grazing the field, along the axes (zero and negative zero components), from
   far away, cut short by tmin and tmax, and a few degenerate ones (zero and NaN directions). */
static void make_ray(uint32_t n, const float *v, kdrt_ray *ray)
{
    const uint32_t s = 7919u * n, kind = n % 8u;
    float target[3];
    int a;
    memset(ray, 0, sizeof *ray);
    ray->tmin = 0.0f, ray->tmax = INFINITY;
    ray->org[0] = unit(s), ray->org[1] = unit(s + 1), ray->org[2] = 2.0f + unit(s + 2);
    target[0] = unit(s + 3) * 1.1f, target[1] = unit(s + 4) * 1.1f, target[2] = 0.0f;
    if (kind == 1 || kind == 2) { /* a vertex, or the midpoint of an edge (diagonals included) */
        const uint32_t q = hash(s + 5) % GRID_VERTICES, r = q + (kind == 2 ? 1 + hash(s + 6) % 2 : 0);
        const uint32_t w = r < GRID_VERTICES ? r : q;
        uint32_t c;
        for (c = 0; c < 3; ++c) target[c] = (v[3 * q + c] + v[3 * w + c]) * 0.5f;
    } else if (kind == 3) { /* grazing: nearly in the field's plane */
        ray->org[0] = -2.0f, ray->org[2] = unit(s + 7) / 8.0f;
        target[0] = 2.0f, target[1] = ray->org[1] + unit(s + 8) / 4.0f, target[2] = unit(s + 9) / 8.0f;
    } else if (kind == 4) { /* along an axis */
        ray->org[2] = unit(s + 10) > 0.0f ? 3.0f : -3.0f;
        for (a = 0; a < 2; ++a) target[a] = ray->org[a];
        target[2] = -ray->org[2];
    } else if (kind == 5) { /* far away */
        for (a = 0; a < 3; ++a) ray->org[a] = unit(s + 11 + (uint32_t)a) * 1048576.0f;
        ray->org[2] = ray->org[2] < 0.0f ? ray->org[2] - 65536.0f : ray->org[2] + 65536.0f;
    } else if (kind == 6) { /* a segment: tmin and tmax cut the ray */
        ray->tmin = 0.5f + unit(s + 14) / 4.0f, ray->tmax = 1.0f + unit(s + 15) / 8.0f;
    }
    for (a = 0; a < 3; ++a) ray->dir[a] = target[a] - ray->org[a];
    if (kind == 4) ray->dir[0] = (n & 16u) ? -0.0f : 0.0f, ray->dir[1] = 0.0f;
    if (n % 97u == 0u) ray->dir[0] = ray->dir[1] = ray->dir[2] = 0.0f;
    if (n % 101u == 0u) ray->dir[1] = float_of(0x7fc00000u); /* NaN */
}

/* The transforms of the scene's two instances: a rotation by the 3-4-5 triangle's angle with a
   scale and a shift, and a mirror with a shear, both lifted over the field. */
static const float instance_transforms[2][12] = {
    {0.6f, -0.8f, 0.0f, 0.25f, 0.8f, 0.6f, 0.0f, -0.125f, 0.0f, 0.0f, 1.5f, 0.75f},
    {-1.0f, 0.25f, 0.0f, 0.5f, 0.0f, 1.0f, 0.0f, 0.375f, 0.125f, 0.0f, 0.5f, 1.25f},
};

typedef struct answerer {
    kdrt_tree *watertight, *fast[2], *instanced; /* fast: median, SAH */
    kdrt_scene *scene;
} answerer;

static void answerer_free(answerer *q)
{
    kdrt_scene_free(q->scene);
    kdrt_tree_free(q->watertight), kdrt_tree_free(q->instanced);
    kdrt_tree_free(q->fast[0]), kdrt_tree_free(q->fast[1]);
    memset(q, 0, sizeof *q);
}

static int answerer_build(answerer *q, const kdrt_triangles *mesh, kdrt_builder builder,
                          uint32_t kernel_flags)
{
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_geometry g[3];
    int i, ok = 1;
    memset(q, 0, sizeof *q);
    o.builder = builder, o.flags = kernel_flags;
    ok &= kdrt_tree_build(mesh, &o, &q->watertight, NULL) == KDRT_SUCCESS;
    ok &= kdrt_tree_build(mesh, &o, &q->instanced, NULL) == KDRT_SUCCESS;
    o.intersector = KDRT_INTERSECTOR_FAST;
    for (i = 0; i < 2; ++i) {
        o.builder = i ? KDRT_BUILDER_SAH : KDRT_BUILDER_MEDIAN;
        ok &= kdrt_tree_build(mesh, &o, &q->fast[i], NULL) == KDRT_SUCCESS;
    }
    o.builder = builder;
    if (ok) {
        g[0] = kdrt_mesh_geometry(7, mesh);
        for (i = 0; i < 2; ++i) g[1 + i] = kdrt_instance_geometry(20u + (uint32_t)i, q->instanced, instance_transforms[i]);
        o.intersector = KDRT_INTERSECTOR_WATERTIGHT;
        ok &= kdrt_scene_build(g, 3, &o, &q->scene, NULL) == KDRT_SUCCESS;
    }
    if (!ok) answerer_free(q);
    return ok;
}

static void put_hit(uint32_t **w, const kdrt_hit *h)
{
    *(*w)++ = h->triangle, *(*w)++ = bits_of(h->t), *(*w)++ = bits_of(h->u), *(*w)++ = bits_of(h->v);
}

static void put_floats(uint32_t **w, const float *x, int n)
{
    int i;
    for (i = 0; i < n; ++i) *(*w)++ = bits_of(x[i]);
}

/* Every answer of one ray, in the order of the file's columns. */
static void answer(const answerer *q, const kdrt_ray *ray, uint32_t out[ANSWER_WORDS])
{
    uint32_t *w = out, i, found;
    kdrt_hit hit, near3[3], scene_hit;
    kdrt_ray bounce;
    float point[3] = {0, 0, 0}, normal[3] = {0, 0, 0}, reflected[3], refracted[3] = {0, 0, 0};
    float fresnel = 0.0f;
    int hit_any = kdrt_intersect(q->watertight, ray, &hit), surface = 0, refracts = 0;
    put_hit(&w, &hit);
    *w++ = (uint32_t)kdrt_occluded(q->watertight, ray);
    found = kdrt_intersect_k(q->watertight, ray, NULL, near3, 3);
    *w++ = found;
    for (i = 0; i < 3; ++i) {
        *w++ = i < found ? near3[i].triangle : KDRT_INVALID_ID;
        *w++ = i < found ? bits_of(near3[i].t) : 0u;
    }
    if (hit_any) surface = kdrt_hit_surface(q->watertight, &hit, point, normal);
    *w++ = (uint32_t)surface;
    put_floats(&w, point, 3), put_floats(&w, normal, 3);
    memset(&bounce, 0, sizeof bounce);
    if (surface) {
        kdrt_reflect(ray->dir, normal, reflected);
        kdrt_spawn_ray(q->watertight, &hit, reflected, &bounce);
        refracts = kdrt_refract(ray->dir, normal, 1.0f / 1.5f, refracted);
        /* Products of floats are exact in double, so no compiler's contraction changes this. */
        const double cos_i = -((double)ray->dir[0] * normal[0] + (double)ray->dir[1] * normal[1] +
                               (double)ray->dir[2] * normal[2]);
        fresnel = kdrt_fresnel_dielectric((float)cos_i, 1.5f);
    }
    put_floats(&w, bounce.org, 3), put_floats(&w, bounce.dir, 3);
    kdrt_intersect(q->watertight, &bounce, &hit);
    put_hit(&w, &hit);
    *w++ = (uint32_t)refracts;
    put_floats(&w, refracted, 3), put_floats(&w, &fresnel, 1);
    kdrt_scene_intersect(q->scene, ray, NULL, &scene_hit);
    put_hit(&w, &scene_hit);
    *w++ = scene_hit.geometry, *w++ = scene_hit.instance;
    for (i = 0; i < 2; ++i) { /* the fast intersector, on a median tree and an SAH tree */
        kdrt_intersect(q->fast[i], ray, &hit);
        put_hit(&w, &hit);
        *w++ = (uint32_t)kdrt_occluded(q->fast[i], ray);
    }
}

static const char *const column_names[ANSWER_WORDS] = {
    "triangle", "t", "u", "v", "occluded", "k count", "k0 triangle", "k0 t", "k1 triangle",
    "k1 t", "k2 triangle", "k2 t", "surface", "point x", "point y", "point z", "normal x",
    "normal y", "normal z", "bounce org x", "bounce org y", "bounce org z", "bounce dir x",
    "bounce dir y", "bounce dir z", "bounce triangle", "bounce t", "bounce u", "bounce v",
    "refracts", "refracted x", "refracted y", "refracted z", "fresnel", "scene triangle",
    "scene t", "scene u", "scene v", "scene geometry", "scene instance", "fast median triangle", "fast median t",
    "fast median u", "fast median v", "fast median occluded", "fast sah triangle", "fast sah t",
    "fast sah u", "fast sah v", "fast sah occluded"};
typedef char column_names_match[sizeof column_names / sizeof *column_names == ANSWER_WORDS ? 1 : -1];

/* The batch calls must answer as the single calls do: checked here, not stored. */
static uint32_t batch_differences(const answerer *q, const kdrt_ray *rays,
                                  uint32_t (*answers)[ANSWER_WORDS], uint32_t count)
{
    kdrt_hit *hits = (kdrt_hit *)malloc(count * sizeof *hits);
    uint8_t *occluded = (uint8_t *)malloc(count);
    uint32_t i, bad = 0;
    if (!hits || !occluded) {
        free(hits), free(occluded);
        return count;
    }
    kdrt_intersect_batch(q->watertight, rays, count, NULL, hits);
    kdrt_occluded_batch(q->watertight, rays, count, NULL, occluded);
    for (i = 0; i < count; ++i)
        bad += hits[i].triangle != answers[i][0] || bits_of(hits[i].t) != answers[i][1] ||
               bits_of(hits[i].u) != answers[i][2] || bits_of(hits[i].v) != answers[i][3] ||
               occluded[i] != answers[i][4];
    free(hits), free(occluded);
    return bad;
}

/* The saved trees, in answers.kdrt's order: the answerer's three trees and its scene's. */
#define SAVED_TREES 4
static const char *const saved_names[SAVED_TREES] = {"watertight sah tree", "fast median tree",
                                                     "fast sah tree", "scene's mesh tree"};

typedef struct buffer {
    unsigned char *data;
    size_t size, capacity;
} buffer;

static int buffer_write(void *user, const void *bytes, size_t size)
{
    buffer *out = (buffer *)user;
    if (size > out->capacity - out->size) return 0;
    memcpy(out->data + out->size, bytes, size);
    out->size += size;
    return 1;
}

/* Saved tree which of q (saved_names' order) into out, malloc'd; 0 on failure. */
static int save_one(const answerer *q, int which, buffer *out)
{
    const kdrt_tree *tree = which == 0 ? q->watertight : which < 3 ? q->fast[which - 1] : NULL;
    const size_t size = tree ? kdrt_tree_saved_size(tree) : kdrt_scene_saved_size(q->scene);
    kdrt_result r;
    out->size = 0, out->capacity = size;
    out->data = (unsigned char *)malloc(size ? size : 1u);
    if (!out->data) return 0;
    r = tree ? kdrt_tree_save(tree, buffer_write, out) : kdrt_scene_save_meshes(q->scene, buffer_write, out);
    if (r != KDRT_SUCCESS || out->size != size) {
        fprintf(stderr, "answers: saving the %s failed: %s\n", saved_names[which], kdrt_result_string(r));
        free(out->data), out->data = NULL;
        return 0;
    }
    return 1;
}

/* path with its file name (after the last slash or backslash) replaced by name, malloc'd. */
static char *beside(const char *path, const char *name)
{
    size_t dir = strlen(path);
    char *out;
    while (dir > 0 && path[dir - 1] != '/' && path[dir - 1] != '\\') --dir;
    out = (char *)malloc(dir + strlen(name) + 1);
    if (out) memcpy(out, path, dir), strcpy(out + dir, name);
    return out;
}

/* The whole file at path, malloc'd; 0 when it cannot be read. */
static int read_all(const char *path, buffer *out)
{
    FILE *f = fopen(path, "rb");
    size_t got = 0;
    memset(out, 0, sizeof *out);
    if (!f) return 0;
    do {
        if (out->size == out->capacity) {
            unsigned char *grown = (unsigned char *)realloc(out->data, out->capacity + 65536u);
            if (!grown) break;
            out->data = grown, out->capacity += 65536u;
        }
        got = fread(out->data + out->size, 1, out->capacity - out->size, f);
        out->size += got;
    } while (got > 0);
    if (ferror(f) || !feof(f)) {
        fclose(f), free(out->data);
        memset(out, 0, sizeof *out);
        return 0;
    }
    fclose(f);
    return 1;
}

/* Splits answers.kdrt into its SAVED_TREES saved trees by the file size each header records
   (bytes 24 to 31, little-endian); 0, with a message, unless they fill it exactly. */
static int split_saved(const char *path, const buffer *file, buffer saved[SAVED_TREES])
{
    size_t at = 0;
    int i, b;
    for (i = 0; i < SAVED_TREES; ++i) {
        uint64_t size = 0;
        if (file->size - at < 32u) {
            fprintf(stderr, "answers: %s ends before its %s (%lu bytes)\n", path, saved_names[i],
                    (unsigned long)file->size);
            return 0;
        }
        for (b = 7; b >= 0; --b) size = size << 8 | file->data[at + 24u + (unsigned)b];
        if (size > file->size - at) {
            fprintf(stderr, "answers: %s: its %s records %lu bytes, more than the file has left\n", path,
                    saved_names[i], (unsigned long)size);
            return 0;
        }
        saved[i].data = file->data + at, saved[i].size = saved[i].capacity = (size_t)size;
        at += (size_t)size;
    }
    if (at != file->size) {
        fprintf(stderr, "answers: %s holds %lu bytes after its %d saved trees\n", path,
                (unsigned long)(file->size - at), SAVED_TREES);
        return 0;
    }
    return 1;
}

/* The answerer of the saved trees: each loaded (the instanced tree is the watertight tree
   loaded again, as it was built alike) with these flags, and the scene with its mesh tree
   loaded. 0, with a message naming the tree, when a load fails. */
static int answerer_load(answerer *q, const kdrt_triangles *mesh, const buffer saved[SAVED_TREES],
                         uint32_t flags, const char *path)
{
    kdrt_build_options o = kdrt_default_build_options();
    kdrt_tree **trees[4];
    kdrt_geometry g[3];
    kdrt_result r = KDRT_SUCCESS;
    int i, which = 0;
    memset(q, 0, sizeof *q);
    o.flags = flags;
    trees[0] = &q->watertight, trees[1] = &q->fast[0], trees[2] = &q->fast[1], trees[3] = &q->instanced;
    for (i = 0; i < 4 && r == KDRT_SUCCESS; ++i) {
        which = i < 3 ? i : 0;
        r = kdrt_tree_load(saved[which].data, saved[which].size, mesh, &o, trees[i], NULL);
    }
    if (r == KDRT_SUCCESS) {
        which = 3;
        g[0] = kdrt_mesh_geometry(7, mesh);
        for (i = 0; i < 2; ++i) g[1 + i] = kdrt_instance_geometry(20u + (uint32_t)i, q->instanced, instance_transforms[i]);
        r = kdrt_scene_load(g, 3, saved[3].data, saved[3].size, &o, &q->scene, NULL);
    }
    if (r != KDRT_SUCCESS) {
        fprintf(stderr, "answers: %s: the %s does not load: %s\n", path, saved_names[which], kdrt_result_string(r));
        answerer_free(q);
        return 0;
    }
    return 1;
}

/* How many of q's trees save to bytes other than saved's (a failed save counts). */
static int saved_differences(const answerer *q, const buffer saved[SAVED_TREES])
{
    int i, bad = 0;
    for (i = 0; i < SAVED_TREES; ++i) {
        buffer again;
        if (!save_one(q, i, &again)) {
            ++bad;
            continue;
        }
        if (again.size != saved[i].size || memcmp(again.data, saved[i].data, again.size) != 0) {
            fprintf(stderr, "answers: the loaded %s saves to other bytes than the file's "
                            "(%lu bytes, the file's %lu)\n",
                    saved_names[i], (unsigned long)again.size, (unsigned long)saved[i].size);
            ++bad;
        }
        free(again.data);
    }
    return bad;
}

/* Every answer of q against expected, differences printed (MAX_REPORTED of them); returns the
   rays that differ, and the batch answers that differ in *batch_bad. */
static uint32_t differences(const answerer *q, const kdrt_ray *rays, uint32_t (*expected)[ANSWER_WORDS],
                            uint32_t count, uint32_t *batch_bad)
{
    uint32_t n, i, bad = 0, reported = 0;
    for (n = 0; n < count; ++n) {
        uint32_t got[ANSWER_WORDS];
        int differs = 0;
        answer(q, &rays[n], got);
        for (i = 0; i < ANSWER_WORDS; ++i) {
            if (got[i] == expected[n][i]) continue;
            differs = 1;
            if (reported++ < MAX_REPORTED)
                fprintf(stderr, "answers: ray %u, %s: got %08x, the file has %08x\n", n,
                        column_names[i], got[i], expected[n][i]);
        }
        bad += (uint32_t)differs;
    }
    *batch_bad = batch_differences(q, rays, expected, count);
    return bad;
}

/* One line: 8 words of ray, '|', ANSWER_WORDS words of answers. */
static int parse_line(const char *line, uint32_t ray_words[RAY_WORDS], uint32_t answers[ANSWER_WORDS])
{
    const char *p = line;
    char *end;
    int i;
    for (i = 0; i < RAY_WORDS + ANSWER_WORDS; ++i) {
        unsigned long x;
        while (*p == ' ' || (i == RAY_WORDS && *p == '|')) ++p;
        x = strtoul(p, &end, 16);
        if (end == p || end - p > 8) return 0;
        if (i < RAY_WORDS) ray_words[i] = (uint32_t)x;
        else answers[i - RAY_WORDS] = (uint32_t)x;
        p = end;
    }
    while (*p == ' ' || *p == '\r' || *p == '\n') ++p;
    return *p == '\0';
}

static void ray_of_words(const uint32_t w[RAY_WORDS], kdrt_ray *ray)
{
    int a;
    memset(ray, 0, sizeof *ray);
    for (a = 0; a < 3; ++a) ray->org[a] = float_of(w[a]), ray->dir[a] = float_of(w[4 + a]);
    ray->tmin = float_of(w[3]), ray->tmax = float_of(w[7]);
}

/* answers.kdrt beside path: q's saved trees, back to back. */
static int write_saved(const char *path, const answerer *q)
{
    char *saved_path = beside(path, "answers.kdrt");
    FILE *f = saved_path ? fopen(saved_path, "wb") : NULL;
    size_t total = 0;
    int i, ok = f != NULL;
    for (i = 0; i < SAVED_TREES && ok; ++i) {
        buffer b;
        ok = save_one(q, i, &b);
        if (ok) ok = fwrite(b.data, 1, b.size, f) == b.size, total += b.size, free(b.data);
    }
    if (f && fclose(f) != 0) ok = 0;
    if (ok)
        printf("answers: wrote %d saved trees (%lu bytes) to %s\n", SAVED_TREES, (unsigned long)total,
               saved_path);
    else fprintf(stderr, "answers: cannot write %s\n", saved_path ? saved_path : "answers.kdrt");
    free(saved_path);
    return ok;
}

static int write_file(const char *path, const kdrt_triangles *mesh, const float *v)
{
    answerer q;
    FILE *f;
    uint32_t n, i, a[ANSWER_WORDS];
    int saved;
    if (!answerer_build(&q, mesh, KDRT_BUILDER_SAH, KDRT_BUILD_SCALAR_KERNEL)) {
        fprintf(stderr, "answers: the build failed\n");
        return 1;
    }
    f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "answers: cannot write %s\n", path);
        answerer_free(&q);
        return 1;
    }
    fprintf(f, "# kdrt answers 1: %d rays (org, tmin, dir, tmax) | answers (tests/platforms/answers.c), as float bits\n", RAY_COUNT);
    for (n = 0; n < RAY_COUNT; ++n) {
        kdrt_ray ray;
        make_ray(n, v, &ray);
        answer(&q, &ray, a);
        fprintf(f, "%08x %08x %08x %08x %08x %08x %08x %08x |", bits_of(ray.org[0]),
                bits_of(ray.org[1]), bits_of(ray.org[2]), bits_of(ray.tmin), bits_of(ray.dir[0]),
                bits_of(ray.dir[1]), bits_of(ray.dir[2]), bits_of(ray.tmax));
        for (i = 0; i < ANSWER_WORDS; ++i) fprintf(f, " %x", a[i]);
        fprintf(f, "\n");
    }
    if (fclose(f) != 0) {
        fprintf(stderr, "answers: cannot write %s\n", path);
        answerer_free(&q);
        return 1;
    }
    printf("answers: wrote %d rays to %s\n", RAY_COUNT, path);
    saved = write_saved(path, &q);
    answerer_free(&q);
    return saved ? 0 : 1;
}

int main(int argc, char **argv)
{
    static float vertices[3 * VERTEX_COUNT];
    static uint32_t indices[3 * TRIANGLE_COUNT];
    static kdrt_ray rays[RAY_COUNT];
    static uint32_t expected[RAY_COUNT][ANSWER_WORDS];
    static const uint32_t kernel_flags[3] = {0u, KDRT_BUILD_AVX2_KERNEL, KDRT_BUILD_SCALAR_KERNEL};
    static const kdrt_builder builders[2] = {KDRT_BUILDER_MEDIAN, KDRT_BUILDER_SAH};
    kdrt_triangles mesh;
    kdrt_kernel seen[3];
    char line[1024];
    uint32_t count = 0, passed = 0, failed = 0;
    int k, b, seen_count = 0, in_place;
    FILE *f;
    char *saved_path;
    buffer saved_file, saved[SAVED_TREES];

    make_mesh(vertices, indices);
    memset(&mesh, 0, sizeof mesh);
    mesh.positions = vertices, mesh.vertex_count = VERTEX_COUNT;
    mesh.indices = indices, mesh.triangle_count = TRIANGLE_COUNT;
    if (argc == 3 && strcmp(argv[1], "--write") == 0) return write_file(argv[2], &mesh, vertices);
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: answers FILE | answers --write FILE  (the saved trees: answers.kdrt beside FILE)\n");
        return 2;
    }

    f = fopen(argv[1], "r");
    if (!f) {
        fprintf(stderr, "answers: cannot read %s\n", argv[1]);
        return 1;
    }
    while (fgets(line, sizeof line, f)) {
        uint32_t w[RAY_WORDS];
        if (line[0] == '#') continue;
        if (count == RAY_COUNT || !parse_line(line, w, expected[count])) {
            fprintf(stderr, "answers: %s: line %u is not a ray and its answers\n", argv[1], count + 2u);
            fclose(f);
            return 1;
        }
        ray_of_words(w, &rays[count++]);
    }
    fclose(f);
    if (count != RAY_COUNT) {
        fprintf(stderr, "answers: %s holds %u rays, not %d\n", argv[1], count, RAY_COUNT);
        return 1;
    }

    /* Every kernel this build has, once each: the flags that pick a kernel already running are
       left out. */
    for (k = 0; k < 3; ++k)
        for (b = 0; b < 2; ++b) {
            answerer q;
            kdrt_tree_stats stats;
            uint32_t n, bad;
            int s, repeated = 0;
            if (!answerer_build(&q, &mesh, builders[b], kernel_flags[k])) {
                fprintf(stderr, "answers: the build failed\n");
                return 1;
            }
            kdrt_tree_get_stats(q.watertight, &stats);
            for (s = 0; s < seen_count; ++s) repeated |= b == 0 && seen[s] == stats.kernel;
            if (repeated) {
                answerer_free(&q);
                break;
            }
            if (b == 0) seen[seen_count++] = stats.kernel;
            bad = differences(&q, rays, expected, count, &n);
            printf("answers: kernel %s, builder %s: %u rays, %u differ from the file, %u batch answers differ\n",
                   kdrt_kernel_string(stats.kernel), b ? "sah" : "median", count, bad, n);
            if (bad || n) ++failed;
            else ++passed;
            answerer_free(&q);
        }

    /* The trees saved on x86-64 (answers.kdrt), loaded copied and in place with every kernel
       this build has (seen above): the same answers, and saved again, the same bytes. */
    saved_path = beside(argv[1], "answers.kdrt");
    if (!saved_path || !read_all(saved_path, &saved_file)) {
        fprintf(stderr, "answers: cannot read the saved trees, %s\n",
                saved_path ? saved_path : "answers.kdrt");
        return 1;
    }
    if (!split_saved(saved_path, &saved_file, saved)) return 1;
    for (in_place = 0; in_place < 2; ++in_place) {
        buffer aligned[SAVED_TREES];
        unsigned char *copies = NULL;
        kdrt_kernel done[3];
        int done_count = 0;
        if (in_place) { /* each tree at a 64-byte boundary, as KDRT_LOAD_IN_PLACE uses it */
            size_t at = 0;
            int i;
            copies = (unsigned char *)malloc(saved_file.size + 64u * SAVED_TREES);
            if (!copies) {
                fprintf(stderr, "answers: out of memory\n");
                return 1;
            }
            for (i = 0; i < SAVED_TREES; ++i) {
                at += (64u - (size_t)((uintptr_t)(copies + at) % 64u)) % 64u;
                aligned[i] = saved[i], aligned[i].data = copies + at;
                memcpy(aligned[i].data, saved[i].data, saved[i].size);
                at += saved[i].size;
            }
        } else {
            memcpy(aligned, saved, sizeof aligned);
        }
        for (k = 0; k < 3; ++k) {
            answerer q;
            kdrt_tree_stats stats;
            uint32_t batch_bad, bad;
            int s, repeated = 0, other_bytes, owns_wrong;
            const uint32_t flags = kernel_flags[k] | (in_place ? (uint32_t)KDRT_LOAD_IN_PLACE : 0u);
            if (!answerer_load(&q, &mesh, aligned, flags, saved_path)) {
                free(copies), free(saved_file.data), free(saved_path);
                return 1;
            }
            kdrt_tree_get_stats(q.watertight, &stats);
            for (s = 0; s < done_count; ++s) repeated |= done[s] == stats.kernel;
            if (repeated) {
                answerer_free(&q);
                continue;
            }
            done[done_count++] = stats.kernel;
            /* In place, the tree owns its struct alone (every target here is little-endian);
               copied, about the file's size (less its header on 32-bit targets). */
            owns_wrong = in_place != (stats.bytes < aligned[0].size / 2u);
            if (owns_wrong)
                fprintf(stderr, "answers: the watertight sah tree loaded %s owns %lu bytes, its file %lu\n",
                        in_place ? "in place" : "copied", (unsigned long)stats.bytes,
                        (unsigned long)aligned[0].size);
            bad = differences(&q, rays, expected, count, &batch_bad);
            other_bytes = saved_differences(&q, aligned);
            printf("answers: saved trees %s, kernel %s: %u rays, %u differ from the file, "
                   "%u batch answers differ, %d of %d trees save to other bytes\n",
                   in_place ? "in place" : "copied", kdrt_kernel_string(stats.kernel), count, bad,
                   batch_bad, other_bytes, SAVED_TREES);
            if (bad || batch_bad || other_bytes || owns_wrong) ++failed;
            else ++passed;
            answerer_free(&q);
        }
        if (done_count != seen_count) {
            fprintf(stderr, "answers: the saved trees %s ran %d kernels, the built trees %d\n",
                    in_place ? "loaded in place" : "copied", done_count, seen_count);
            ++failed;
        }
        free(copies);
    }
    free(saved_file.data), free(saved_path);
    printf("%u passed, %u failed\n", passed, failed);
    return failed ? 1 : 0;
}
