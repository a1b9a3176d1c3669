/* test_scene.c - the glTF loader (shim/gi_gltf_tiny.cpp) and gi_scene.c:
 * Khronos samples against the triangle counts of their MANIFEST, identical
 * geometry across .gltf/embedded/.glb variants, transforms, cameras, lights,
 * texture transforms and sampling, Sponza load time, and malformed files made
 * here that must give GI_EXIT_DATA (or GI_EXIT_SYSTEM) with the element named.
 *
 * Shared data: $GI_SHARED, else ../shared relative to the repo root (tests/run.sh
 * runs us from there); tests that need it skip when it is absent. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <ftw.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include <cmocka.h>

#include "gi_math.h"
#include "gi_scene.h"

/* ---- helpers ---------------------------------------------------------------- */

static char g_tmp[256];

static const char *shared_dir(void)
{
    const char *s = getenv("GI_SHARED");
    return s && *s ? s : "../shared";
}

/* Path under the shared data, or skip the test if the data is absent. */
static const char *sample(const char *rel)
{
    static char buf[8][1024];
    static int slot;
    char *p = buf[slot++ % 8];
    snprintf(p, 1024, "%s/%s", shared_dir(), rel);
    return p;
}

static void need_samples(void)
{
    struct stat sb;
    if (stat(sample("gltf-samples/MANIFEST.md"), &sb) != 0) {
        print_message("shared data not found at %s (set GI_SHARED); skipping\n", shared_dir());
        skip();
    }
}

static gi_scene *load_ok(const char *path)
{
    gi_scene *s = NULL;
    gi_status st = {0};
    int rc = gi_scene_load(path, &s, &st);
    if (rc != 0)
        fail_msg("loading %s failed (%d): %s", path, rc, st.msg);
    assert_non_null(s);
    return s;
}

static int has_warning(const gi_scene *s, const char *needle)
{
    for (size_t i = 0; i < s->num_warnings; i++)
        if (strstr(s->warnings[i], needle))
            return 1;
    return 0;
}

static char *write_file(const char *name, const void *data, size_t n)
{
    static char path[8][512];
    static int slot;
    char *p = path[slot++ % 8];
    snprintf(p, 512, "%s/%s", g_tmp, name);
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
    return p;
}

static char *write_text(const char *name, const char *text)
{
    return write_file(name, text, strlen(text));
}

/* JSON templates are written with ' for " to stay readable. */
static char *q(const char *s)
{
    char *r = strdup(s);
    assert_non_null(r);
    for (char *p = r; *p; p++)
        if (*p == '\'')
            *p = '"';
    return r;
}

static char *strf(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char *r = NULL;
    assert_true(vasprintf(&r, fmt, ap) >= 0);
    va_end(ap);
    return r;
}

/* Replace the first occurrence of `from` (which must exist) by `to`. */
static char *replace(const char *s, const char *from, const char *to)
{
    const char *p = strstr(s, from);
    if (!p)
        fail_msg("template lacks '%s'", from);
    size_t a = (size_t)(p - s), nf = strlen(from), nt = strlen(to), ns = strlen(s);
    char *r = malloc(ns - nf + nt + 1);
    assert_non_null(r);
    memcpy(r, s, a);
    memcpy(r + a, to, nt);
    memcpy(r + a + nt, p + nf, ns - a - nf + 1);
    return r;
}

static char *base64(const unsigned char *d, size_t n)
{
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char *r = malloc(4 * ((n + 2) / 3) + 1), *o = r;
    assert_non_null(r);
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)d[i] << 16 | (i + 1 < n ? (uint32_t)d[i + 1] << 8 : 0) |
                     (i + 2 < n ? d[i + 2] : 0);
        *o++ = tab[v >> 18 & 63];
        *o++ = tab[v >> 12 & 63];
        *o++ = i + 1 < n ? tab[v >> 6 & 63] : '=';
        *o++ = i + 2 < n ? tab[v & 63] : '=';
    }
    *o = 0;
    return r;
}

/* A growing binary buffer with 4-byte aligned sections. */
typedef struct blob {
    unsigned char d[4096];
    size_t n;
} blob;

static size_t blob_add(blob *b, const void *p, size_t n)
{
    size_t off = b->n;
    assert_true(off + n + 3 <= sizeof b->d);
    memcpy(b->d + off, p, n);
    b->n = (off + n + 3) & ~(size_t)3;
    return off;
}

static char *data_uri(const blob *b)
{
    char *enc = base64(b->d, b->n);
    char *r = strf("data:application/octet-stream;base64,%s", enc);
    free(enc);
    return r;
}

static int rm_cb(const char *p, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb;
    (void)flag;
    (void)ftw;
    return remove(p);
}

static int setup_tmp(void **state)
{
    (void)state;
    snprintf(g_tmp, sizeof g_tmp, "%s/gi_test_scene.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    return mkdtemp(g_tmp) ? 0 : -1;
}

static int teardown_tmp(void **state)
{
    (void)state;
    nftw(g_tmp, rm_cb, 8, FTW_DEPTH | FTW_PHYS);
    return 0;
}

/* ---- the Khronos samples ------------------------------------------------------ */

/* Triangle counts from shared/gltf-samples/MANIFEST.md (counted per TRIANGLES,
 * STRIP and FAN primitive). Where a mesh is drawn by several nodes the loader
 * instantiates it, so `loaded` adds those instances, derived by hand from the
 * node lists: SimpleMeshes draws its 1 triangle twice; TextureTransformTest's
 * 9 primitives (18 triangles) include mesh 6 drawn by 3 nodes and mesh 7 by 2,
 * giving 18 + 2*2 + 1*2 = 24. AssetGenerator modes: 00-03 and 07-10 are
 * points/lines (0), the others TRIANGLES/STRIP/FAN with 2 triangles each. */
static const struct {
    const char *path;
    size_t manifest, loaded;
} k_samples[] = {
    {"Box/glTF/Box.gltf", 12, 12},
    {"Box/glTF-Embedded/Box.gltf", 12, 12},
    {"Box/glTF-Binary/Box.glb", 12, 12},
    {"BoxInterleaved/glTF/BoxInterleaved.gltf", 12, 12},
    {"BoxInterleaved/glTF-Embedded/BoxInterleaved.gltf", 12, 12},
    {"BoxInterleaved/glTF-Binary/BoxInterleaved.glb", 12, 12},
    {"BoxTextured/glTF/BoxTextured.gltf", 12, 12},
    {"BoxTextured/glTF-Embedded/BoxTextured.gltf", 12, 12},
    {"BoxTextured/glTF-Binary/BoxTextured.glb", 12, 12},
    {"BoxVertexColors/glTF/BoxVertexColors.gltf", 12, 12},
    {"BoxVertexColors/glTF-Embedded/BoxVertexColors.gltf", 12, 12},
    {"BoxVertexColors/glTF-Binary/BoxVertexColors.glb", 12, 12},
    {"VertexColorTest/glTF/VertexColorTest.gltf", 36, 36},
    {"VertexColorTest/glTF-Embedded/VertexColorTest.gltf", 36, 36},
    {"VertexColorTest/glTF-Binary/VertexColorTest.glb", 36, 36},
    {"Triangle/glTF/Triangle.gltf", 1, 1},
    {"Triangle/glTF-Embedded/Triangle.gltf", 1, 1},
    {"TriangleWithoutIndices/glTF/TriangleWithoutIndices.gltf", 1, 1},
    {"TriangleWithoutIndices/glTF-Embedded/TriangleWithoutIndices.gltf", 1, 1},
    {"SimpleMeshes/glTF/SimpleMeshes.gltf", 1, 2},
    {"SimpleMeshes/glTF-Embedded/SimpleMeshes.gltf", 1, 2},
    {"SimpleSparseAccessor/glTF/SimpleSparseAccessor.gltf", 12, 12},
    {"SimpleSparseAccessor/glTF-Embedded/SimpleSparseAccessor.gltf", 12, 12},
    {"Cameras/glTF/Cameras.gltf", 2, 2},
    {"Cameras/glTF-Embedded/Cameras.gltf", 2, 2},
    {"OrientationTest/glTF/OrientationTest.gltf", 524, 524},
    {"OrientationTest/glTF-Embedded/OrientationTest.gltf", 524, 524},
    {"OrientationTest/glTF-Binary/OrientationTest.glb", 524, 524},
    {"MultiUVTest/glTF/MultiUVTest.gltf", 12, 12},
    {"MultiUVTest/glTF-Embedded/MultiUVTest.gltf", 12, 12},
    {"MultiUVTest/glTF-Binary/MultiUVTest.glb", 12, 12},
    {"TextureSettingsTest/glTF/TextureSettingsTest.gltf", 72, 72},
    {"TextureSettingsTest/glTF-Embedded/TextureSettingsTest.gltf", 72, 72},
    {"TextureSettingsTest/glTF-Binary/TextureSettingsTest.glb", 72, 72},
    {"TextureTransformTest/glTF/TextureTransformTest.gltf", 18, 24},
    {"LightsPunctualLamp/glTF/LightsPunctualLamp.gltf", 6000, 6000},
    {"IridescenceSuzanne/glTF/IridescenceSuzanne.gltf", 11808, 11808},
    {"Suzanne/glTF/Suzanne.gltf", 3936, 3936},
    {"Box With Spaces/glTF/Box With Spaces.gltf", 12, 12},
    {"Unicode\xe2\x9d\xa4\xe2\x99\xbbTest/glTF/Unicode\xe2\x9d\xa4\xe2\x99\xbbTest.gltf", 2, 2},
    {"Unicode\xe2\x9d\xa4\xe2\x99\xbbTest/glTF-Binary/Unicode\xe2\x9d\xa4\xe2\x99\xbbTest.glb", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_00.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_01.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_02.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_03.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_04.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_05.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_06.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_07.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_08.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_09.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_10.gltf", 0, 0},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_11.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_12.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_13.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_14.gltf", 2, 2},
    {"AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_15.gltf", 2, 2},
};
#define NUM_SAMPLES (sizeof k_samples / sizeof k_samples[0])

static int g_found, g_unlisted;

static int find_cb(const char *p, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb;
    (void)ftw;
    if (flag != FTW_F)
        return 0;
    size_t n = strlen(p);
    if (!((n > 5 && strcmp(p + n - 5, ".gltf") == 0) || (n > 4 && strcmp(p + n - 4, ".glb") == 0)))
        return 0;
    g_found++;
    const char *rel = strstr(p, "gltf-samples/") + strlen("gltf-samples/");
    for (size_t i = 0; i < NUM_SAMPLES; i++)
        if (strcmp(k_samples[i].path, rel) == 0)
            return 0;
    print_message("sample not in the test's table: %s\n", rel);
    g_unlisted++;
    return 0;
}

static void test_samples_load_with_manifest_counts(void **state)
{
    (void)state;
    need_samples();
    /* every .gltf/.glb on disk must be in the table (so none is left untested) */
    g_found = g_unlisted = 0;
    assert_int_equal(nftw(sample("gltf-samples"), find_cb, 16, FTW_PHYS), 0);
    assert_int_equal(g_unlisted, 0);
    assert_int_equal((size_t)g_found, NUM_SAMPLES);
    for (size_t i = 0; i < NUM_SAMPLES; i++) {
        char rel[512];
        snprintf(rel, sizeof rel, "gltf-samples/%s", k_samples[i].path);
        gi_scene *s = load_ok(sample(rel));
        if (s->num_triangles != k_samples[i].loaded)
            fail_msg("%s: %zu triangles, expected %zu (manifest %zu)", k_samples[i].path,
                     s->num_triangles, k_samples[i].loaded, k_samples[i].manifest);
        assert_true(s->num_materials >= 1);
        for (size_t t = 0; t < s->num_triangles; t++) {
            assert_true(s->tri_material[t] < s->num_materials);
            for (int k = 0; k < 3; k++)
                assert_true(s->indices[3 * t + k] < s->num_vertices);
        }
        for (size_t v = 0; v < s->num_vertices; v++) {
            const float *n = s->normals + 3 * v;
            assert_float_equal(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-4);
        }
        assert_int_equal(s->hash, gi_scene_fingerprint(s));
        gi_scene_free(s);
    }
}

static void assert_same_geometry(const char *a, const char *b)
{
    gi_scene *x = load_ok(sample(a)), *y = load_ok(sample(b));
    assert_int_equal(x->num_vertices, y->num_vertices);
    assert_int_equal(x->num_triangles, y->num_triangles);
    assert_true(x->num_triangles > 0);
    size_t nv = x->num_vertices, nt = x->num_triangles;
    assert_memory_equal(x->positions, y->positions, 3 * nv * sizeof(float));
    assert_memory_equal(x->normals, y->normals, 3 * nv * sizeof(float));
    assert_memory_equal(x->uv0, y->uv0, 2 * nv * sizeof(float));
    assert_memory_equal(x->uv1, y->uv1, 2 * nv * sizeof(float));
    assert_memory_equal(x->indices, y->indices, 3 * nt * sizeof(uint32_t));
    assert_memory_equal(x->tri_material, y->tri_material, nt * sizeof(uint32_t));
    assert_int_equal(x->hash, y->hash);
    assert_int_equal(x->num_materials, y->num_materials);
    assert_int_equal(x->num_textures, y->num_textures);
    gi_scene_free(x);
    gi_scene_free(y);
}

static void test_variants_identical(void **state)
{
    (void)state;
    need_samples();
    static const char *models[] = {"Box", "BoxInterleaved", "BoxTextured", "BoxVertexColors",
                                   "VertexColorTest", "OrientationTest", "MultiUVTest",
                                   "TextureSettingsTest"};
    char a[512], b[512], c[512];
    for (size_t i = 0; i < sizeof models / sizeof models[0]; i++) {
        snprintf(a, sizeof a, "gltf-samples/%s/glTF/%s.gltf", models[i], models[i]);
        snprintf(b, sizeof b, "gltf-samples/%s/glTF-Embedded/%s.gltf", models[i], models[i]);
        snprintf(c, sizeof c, "gltf-samples/%s/glTF-Binary/%s.glb", models[i], models[i]);
        assert_same_geometry(a, b);
        assert_same_geometry(a, c);
    }
    static const char *two[] = {"Triangle", "TriangleWithoutIndices", "SimpleMeshes",
                                "SimpleSparseAccessor", "Cameras"};
    for (size_t i = 0; i < sizeof two / sizeof two[0]; i++) {
        snprintf(a, sizeof a, "gltf-samples/%s/glTF/%s.gltf", two[i], two[i]);
        snprintf(b, sizeof b, "gltf-samples/%s/glTF-Embedded/%s.gltf", two[i], two[i]);
        assert_same_geometry(a, b);
    }
    assert_same_geometry("gltf-samples/Unicode\xe2\x9d\xa4\xe2\x99\xbbTest/glTF/Unicode\xe2\x9d\xa4\xe2\x99\xbbTest.gltf",
                         "gltf-samples/Unicode\xe2\x9d\xa4\xe2\x99\xbbTest/glTF-Binary/Unicode\xe2\x9d\xa4\xe2\x99\xbbTest.glb");
}

static void assert_vec3(const float *v, double x, double y, double z, double eps)
{
    assert_float_equal(v[0], x, eps);
    assert_float_equal(v[1], y, eps);
    assert_float_equal(v[2], z, eps);
}

static void test_simple_meshes_instanced(void **state)
{
    (void)state;
    need_samples();
    gi_scene *s = load_ok(sample("gltf-samples/SimpleMeshes/glTF/SimpleMeshes.gltf"));
    assert_int_equal(s->num_triangles, 2);
    /* the triangle (0,0,0) (1,0,0) (0,1,0) on node 0, and on node 1 moved by +1 in x */
    const uint32_t *t0 = s->indices, *t1 = s->indices + 3;
    assert_vec3(s->positions + 3 * t0[0], 0, 0, 0, 1e-6);
    assert_vec3(s->positions + 3 * t0[1], 1, 0, 0, 1e-6);
    assert_vec3(s->positions + 3 * t0[2], 0, 1, 0, 1e-6);
    assert_vec3(s->positions + 3 * t1[0], 1, 0, 0, 1e-6);
    assert_vec3(s->positions + 3 * t1[1], 2, 0, 0, 1e-6);
    assert_vec3(s->positions + 3 * t1[2], 1, 1, 0, 1e-6);
    /* no NORMAL in the file: flat normals, +z for this counter-clockwise triangle */
    assert_vec3(s->normals + 3 * t1[0], 0, 0, 1, 1e-6);
    assert_float_equal(s->surface_area, 1.0, 1e-9);
    assert_float_equal(s->bbox_max[0], 2.0, 1e-6);
    gi_scene_free(s);
}

static void test_cameras(void **state)
{
    (void)state;
    need_samples();
    gi_scene *s = load_ok(sample("gltf-samples/Cameras/glTF/Cameras.gltf"));
    assert_int_equal(s->num_cameras, 1);
    const gi_camera *c = &s->cameras[0];
    assert_vec3(c->position, 0.5, 0.5, 3.0, 1e-6);
    assert_vec3(c->forward, 0, 0, -1, 1e-6);
    assert_vec3(c->up, 0, 1, 0, 1e-6);
    assert_float_equal(c->yfov, 0.7, 1e-6);
    assert_float_equal(c->aspect, 1.0, 1e-6);
    assert_float_equal(c->znear, 0.01, 1e-7);
    assert_float_equal(c->zfar, 100.0, 1e-4);
    assert_true(has_warning(s, "orthographic"));
    /* the mesh node is rotated -45 degrees about x: the unit square's far edge
     * (y = 1) goes to y = z = -sqrt(1/2) (quaternion [-0.383, 0, 0, 0.92375]) */
    assert_float_equal(s->bbox_max[1], 0.7066, 1e-3);
    assert_float_equal(s->bbox_min[2], -0.7076, 1e-3);
    gi_scene_free(s);
}

static void test_lights_punctual_lamp(void **state)
{
    (void)state;
    need_samples();
    gi_scene *s = load_ok(sample("gltf-samples/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf"));
    assert_int_equal(s->num_lights, 5);
    for (size_t i = 0; i < s->num_lights; i++) {
        assert_int_equal(s->lights[i].type, GI_LIGHT_POINT);
        assert_int_equal(s->lights[i].enabled, 1);
        assert_true(s->lights[i].intensity > 0.0f);
        for (size_t j = 0; j < i; j++)
            assert_string_not_equal(s->lights[i].name, s->lights[j].name);
        assert_int_equal(gi_scene_find_light(s, s->lights[i].name), (int)i);
    }
    int p = gi_scene_find_light(s, "Point");
    assert_true(p >= 0);
    assert_float_equal(s->lights[p].intensity, 15.0, 1e-5);
    assert_true(has_warning(s, "KHR_materials_transmission"));
    assert_true(has_warning(s, "normalTexture"));
    assert_true(s->num_textures >= 1);
    gi_scene_free(s);
}

static void test_iridescence_directional(void **state)
{
    (void)state;
    need_samples();
    gi_scene *s = load_ok(sample("gltf-samples/IridescenceSuzanne/glTF/IridescenceSuzanne.gltf"));
    assert_int_equal(s->num_lights, 1);
    const gi_light *l = &s->lights[0];
    assert_int_equal(l->type, GI_LIGHT_DIRECTIONAL);
    assert_float_equal(l->intensity, 2.0, 1e-6); /* lux */
    /* the light node only translates, so the light travels along -z */
    assert_vec3(l->direction, 0, 0, -1, 1e-6);
    /* three materials all named "Material" become unique */
    assert_int_equal(s->num_materials, 3);
    assert_true(gi_scene_find_material(s, "Material") >= 0);
    assert_true(gi_scene_find_material(s, "Material_2") >= 0);
    assert_true(gi_scene_find_material(s, "Material_3") >= 0);
    assert_true(has_warning(s, "KHR_materials_iridescence"));
    gi_scene_free(s);
}

static void test_texture_transform(void **state)
{
    (void)state;
    need_samples();
    gi_scene *s = load_ok(sample("gltf-samples/TextureTransformTest/glTF/TextureTransformTest.gltf"));
    /* values from the file's KHR_texture_transform; matrix = T * R(rot) * S */
    int m = gi_scene_find_material(s, "Offset U");
    assert_true(m >= 0);
    const float *x = s->materials[m].uv_xform;
    assert_float_equal(x[0], 1, 1e-6);
    assert_float_equal(x[2], 0.5, 1e-6);
    assert_float_equal(x[4], 1, 1e-6);
    assert_float_equal(x[5], 0, 1e-6);
    m = gi_scene_find_material(s, "Rotation");
    assert_true(m >= 0);
    x = s->materials[m].uv_xform;
    double r = 0.39269908169872414;
    assert_float_equal(x[0], cos(r), 1e-6);
    assert_float_equal(x[1], sin(r), 1e-6);
    assert_float_equal(x[3], -sin(r), 1e-6);
    assert_float_equal(x[4], cos(r), 1e-6);
    m = gi_scene_find_material(s, "All");
    assert_true(m >= 0);
    x = s->materials[m].uv_xform;
    assert_float_equal(x[0], cos(0.3) * 1.5, 1e-6);
    assert_float_equal(x[1], sin(0.3) * 1.5, 1e-6);
    assert_float_equal(x[2], -0.2, 1e-6);
    assert_float_equal(x[5], -0.1, 1e-6);
    /* the texture's sampler clamps to edge */
    assert_true(s->materials[m].base_color_tex >= 0);
    const gi_texture *t = &s->textures[s->materials[m].base_color_tex];
    assert_int_equal(t->wrap_s, GI_WRAP_CLAMP);
    assert_int_equal(t->wrap_t, GI_WRAP_CLAMP);
    /* base colour applies the transform: compare with a direct texture lookup */
    float uv[2] = {0.3f, 0.6f}, rgb[3], tex[4];
    gi_scene_base_color(s, &s->materials[m], uv, uv, rgb);
    gi_texture_sample(t, x[0] * uv[0] + x[1] * uv[1] + x[2], x[3] * uv[0] + x[4] * uv[1] + x[5], tex);
    for (int k = 0; k < 3; k++)
        assert_float_equal(rgb[k], s->materials[m].base_color[k] * tex[k], 1e-6);
    m = gi_scene_find_material(s, "Correct");
    assert_true(m >= 0);
    assert_float_equal(s->materials[m].uv_xform[0], 1, 0);
    assert_float_equal(s->materials[m].uv_xform[2], 0, 0);
    gi_scene_free(s);
}

static void test_primitive_modes(void **state)
{
    (void)state;
    need_samples();
    static const char *warned[] = {"POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"};
    for (int i = 0; i < 16; i++) {
        char rel[256];
        snprintf(rel, sizeof rel, "gltf-samples/AssetGenerator_Mesh_PrimitiveMode/Mesh_PrimitiveMode_%02d.gltf", i);
        gi_scene *s = load_ok(sample(rel));
        int lines = (i <= 3) || (i >= 7 && i <= 10);
        if (lines) {
            assert_int_equal(s->num_triangles, 0);
            const char *mode = warned[i <= 3 ? i : i - 7];
            char want[64];
            snprintf(want, sizeof want, "mode %s (1)", mode);
            if (!has_warning(s, want))
                fail_msg("%s: no warning naming %s", rel, want);
        } else {
            assert_int_equal(s->num_triangles, 2);
            assert_int_equal(s->num_degenerate, 0);
            /* STRIP and FAN keep a consistent winding: both triangles face the same way */
            float n[2][3];
            for (int t = 0; t < 2; t++) {
                const float *a = s->positions + 3 * s->indices[3 * t];
                const float *b = s->positions + 3 * s->indices[3 * t + 1];
                const float *c = s->positions + 3 * s->indices[3 * t + 2];
                float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
                float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
                n[t][0] = e1[1] * e2[2] - e1[2] * e2[1];
                n[t][1] = e1[2] * e2[0] - e1[0] * e2[2];
                n[t][2] = e1[0] * e2[1] - e1[1] * e2[0];
            }
            assert_true(n[0][0] * n[1][0] + n[0][1] * n[1][1] + n[0][2] * n[1][2] > 0.0f);
            assert_false(has_warning(s, "non-triangle"));
        }
        gi_scene_free(s);
    }
}

static void test_sponza_load_time(void **state)
{
    (void)state;
    const char *p = sample("scenes/sponza/sponza.gltf");
    struct stat sb;
    if (stat(p, &sb) != 0) {
        print_message("%s not found; skipping\n", p);
        skip();
    }
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    gi_scene *s = load_ok(p);
    clock_gettime(CLOCK_MONOTONIC, &b);
    double dt = (double)(b.tv_sec - a.tv_sec) + 1e-9 * (double)(b.tv_nsec - a.tv_nsec);
    print_message("sponza.gltf loaded in %.3f s (target < 1 s): %zu triangles, %zu textures\n", dt,
                  s->num_triangles, s->num_textures);
    assert_int_equal(s->num_triangles, 69063);
    assert_int_equal(s->num_vertices, 64639);
    assert_int_equal(s->num_textures, 11);
    assert_int_equal(s->num_materials, 20);
    assert_true(dt < 3.0);
    /* provenance: world bbox [-17.40,-0.91,-7.80]..[17.42,15.65,7.80] */
    assert_vec3(s->bbox_min, -17.40, -0.91, -7.80, 0.01);
    assert_vec3(s->bbox_max, 17.42, 15.65, 7.80, 0.01);
    for (size_t i = 0; i < s->num_textures; i++) {
        const gi_texture *t = &s->textures[i];
        assert_true(t->width > 0 && t->height > 0);
        for (size_t k = 0; k < (size_t)t->width * t->height * 4; k++)
            assert_true(t->rgba[k] >= 0.0f && t->rgba[k] <= 1.0f);
    }
    gi_scene_free(s);
}

/* ---- texture sampling ------------------------------------------------------- */

static void test_texture_sample_wrap(void **state)
{
    (void)state;
    /* 4x1 texture, red channel 0, 1, 2, 3 (texel centres at u = 0.125 + k/4) */
    float texels[16] = {0};
    for (int k = 0; k < 4; k++) {
        texels[4 * k] = (float)k;
        texels[4 * k + 3] = 1.0f;
    }
    gi_texture t = {.width = 4, .height = 1, .rgba = texels};
    float c[4];
    /* at texel centres the lookup is exact */
    for (int k = 0; k < 4; k++) {
        gi_texture_sample(&t, 0.125f + 0.25f * k, 0.5f, c);
        assert_float_equal(c[0], k, 1e-6);
        assert_float_equal(c[3], 1.0, 1e-6);
    }
    /* bilinear midpoint between texels 1 and 2 */
    gi_texture_sample(&t, 0.5f, 0.5f, c);
    assert_float_equal(c[0], 1.5, 1e-6);
    /* REPEAT: u = 1.375 is texel 1; at u = 0 the edge blends texels 3 and 0 */
    t.wrap_s = GI_WRAP_REPEAT;
    gi_texture_sample(&t, 1.375f, 0.5f, c);
    assert_float_equal(c[0], 1.0, 1e-5);
    gi_texture_sample(&t, -0.625f, 0.5f, c);
    assert_float_equal(c[0], 1.0, 1e-5);
    gi_texture_sample(&t, 0.0f, 0.5f, c);
    assert_float_equal(c[0], 1.5, 1e-6);
    /* CLAMP: beyond the edges the border texels */
    t.wrap_s = GI_WRAP_CLAMP;
    gi_texture_sample(&t, -3.0f, 0.5f, c);
    assert_float_equal(c[0], 0.0, 1e-6);
    gi_texture_sample(&t, 7.0f, 0.5f, c);
    assert_float_equal(c[0], 3.0, 1e-6);
    gi_texture_sample(&t, 0.0f, 0.5f, c);
    assert_float_equal(c[0], 0.0, 1e-6);
    /* MIRROR: [1, 2) runs backwards, so u = 1.125 is texel 3 and u = 1.875 texel 0 */
    t.wrap_s = GI_WRAP_MIRROR;
    gi_texture_sample(&t, 1.125f, 0.5f, c);
    assert_float_equal(c[0], 3.0, 1e-5);
    gi_texture_sample(&t, 1.875f, 0.5f, c);
    assert_float_equal(c[0], 0.0, 1e-5);
    gi_texture_sample(&t, -0.125f, 0.5f, c);
    assert_float_equal(c[0], 0.0, 1e-5);
    gi_texture_sample(&t, 1.0f, 0.5f, c); /* the mirror edge repeats texel 3 */
    assert_float_equal(c[0], 3.0, 1e-5);
    /* NEAREST */
    t.wrap_s = GI_WRAP_REPEAT;
    t.nearest = 1;
    gi_texture_sample(&t, 0.49f, 0.5f, c);
    assert_float_equal(c[0], 1.0, 0);
    gi_texture_sample(&t, 0.51f, 0.5f, c);
    assert_float_equal(c[0], 2.0, 0);
    gi_texture_sample(&t, -0.01f, 0.5f, c);
    assert_float_equal(c[0], 3.0, 0);
    /* huge and non-finite coordinates stay in range and never crash */
    t.nearest = 0;
    const float odd[] = {1e12f, -1e12f, INFINITY, -INFINITY, NAN, 3.0e9f};
    for (int w = 0; w < 3; w++) {
        t.wrap_s = t.wrap_t = w;
        for (size_t i = 0; i < sizeof odd / sizeof odd[0]; i++) {
            gi_texture_sample(&t, odd[i], odd[i], c);
            assert_true(c[0] >= 0.0f && c[0] <= 3.0f);
        }
    }
}

static void test_texture_sample_2d(void **state)
{
    (void)state;
    /* 2x2: value = 10 * row + col in red; bilinear centre = mean, v = 0 is row 0 */
    float texels[16] = {0};
    for (int r = 0; r < 2; r++)
        for (int col = 0; col < 2; col++)
            texels[4 * (2 * r + col)] = (float)(10 * r + col);
    gi_texture t = {.width = 2, .height = 2, .rgba = texels, .wrap_s = GI_WRAP_CLAMP, .wrap_t = GI_WRAP_CLAMP};
    float c[4];
    gi_texture_sample(&t, 0.5f, 0.5f, c);
    assert_float_equal(c[0], 5.5, 1e-6);
    gi_texture_sample(&t, 0.75f, 0.25f, c);
    assert_float_equal(c[0], 1.0, 1e-6);
    gi_texture_sample(&t, 0.25f, 0.75f, c);
    assert_float_equal(c[0], 10.0, 1e-6);
    gi_texture_sample(&t, 0.5f, 0.25f, c);
    assert_float_equal(c[0], 0.5, 1e-6);
}

/* A PNG (RGBA 8-bit) in memory: zlib-compressed rows with filter 0. */
static unsigned char *make_png(int w, int h, const unsigned char *rgba, size_t *out_n)
{
    size_t raw_n = (size_t)h * (1 + 4 * (size_t)w);
    unsigned char *raw = malloc(raw_n);
    assert_non_null(raw);
    for (int y = 0; y < h; y++) {
        raw[y * (1 + 4 * w)] = 0;
        memcpy(raw + y * (1 + 4 * w) + 1, rgba + 4 * w * y, 4 * (size_t)w);
    }
    uLongf zn = compressBound(raw_n);
    unsigned char *z = malloc(zn);
    assert_non_null(z);
    assert_int_equal(compress(z, &zn, raw, raw_n), Z_OK);
    size_t n = 8 + (12 + 13) + (12 + zn) + 12;
    unsigned char *png = malloc(n), *p = png;
    assert_non_null(png);
    memcpy(p, "\x89PNG\r\n\x1a\n", 8);
    p += 8;
    const struct {
        const char *type;
        const unsigned char *d;
        size_t n;
    } chunks[3] = {{"IHDR", NULL, 13}, {"IDAT", z, zn}, {"IEND", NULL, 0}};
    unsigned char ihdr[13] = {0, 0, 0, (unsigned char)w, 0, 0, 0, (unsigned char)h, 8, 6, 0, 0, 0};
    for (int c = 0; c < 3; c++) {
        const unsigned char *d = c == 0 ? ihdr : chunks[c].d;
        size_t len = chunks[c].n;
        p[0] = (unsigned char)(len >> 24);
        p[1] = (unsigned char)(len >> 16);
        p[2] = (unsigned char)(len >> 8);
        p[3] = (unsigned char)len;
        memcpy(p + 4, chunks[c].type, 4);
        if (len)
            memcpy(p + 8, d, len);
        uLong crc = crc32(0, p + 4, (uInt)(4 + len));
        p[8 + len] = (unsigned char)(crc >> 24);
        p[9 + len] = (unsigned char)(crc >> 16);
        p[10 + len] = (unsigned char)(crc >> 8);
        p[11 + len] = (unsigned char)crc;
        p += 12 + len;
    }
    free(raw);
    free(z);
    *out_n = (size_t)(p - png);
    return png;
}

static double srgb_ref(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

/* Two triangles of a unit quad with uv, normals, TEXCOORD_1 as normalized
 * u8, and a 2x2 PNG base colour texture with a nearest/clamp/mirror sampler. */
static char *textured_quad(int corrupt_png)
{
    blob b = {0};
    float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    float nrm[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
    float uv[8] = {0, 1, 1, 1, 1, 0, 0, 0};
    unsigned char uv1[8] = {0, 255, 255, 255, 255, 0, 0, 0};
    uint16_t ind[6] = {0, 1, 2, 0, 2, 3};
    size_t op = blob_add(&b, pos, sizeof pos), on = blob_add(&b, nrm, sizeof nrm);
    size_t ou = blob_add(&b, uv, sizeof uv), ou1 = blob_add(&b, uv1, sizeof uv1);
    size_t oi = blob_add(&b, ind, sizeof ind);
    /* texels: (128,0,255,64) (255,255,255,255) / (0,0,0,0) (64,128,192,255) */
    unsigned char px[16] = {128, 0, 255, 64, 255, 255, 255, 255, 0, 0, 0, 0, 64, 128, 192, 255};
    size_t png_n;
    unsigned char *png = make_png(2, 2, px, &png_n);
    if (corrupt_png) { /* the IDAT chunk (at byte 33) claims 2 GB */
        png[33] = 0x7f;
        png[34] = 0xff;
    }
    char *png64 = base64(png, png_n);
    char *uri = data_uri(&b);
    char *tmpl = q("{'asset':{'version':'2.0'},'scene':0,'scenes':[{'nodes':[0]}],"
                   "'nodes':[{'mesh':0}],"
                   "'meshes':[{'primitives':[{'attributes':{'POSITION':0,'NORMAL':1,'TEXCOORD_0':2,"
                   "'TEXCOORD_1':3},'indices':4,'material':0}]}],"
                   "'materials':[{'name':'tex','pbrMetallicRoughness':{'baseColorFactor':[0.5,1,1,1],"
                   "'baseColorTexture':{'index':0,'texCoord':1}}}],"
                   "'textures':[{'source':0,'sampler':0,'name':'checker'}],"
                   "'samplers':[{'wrapS':33071,'wrapT':33648,'magFilter':9728}],"
                   "'images':[{'uri':'data:image/png;base64,%s'}],"
                   "'accessors':[{'bufferView':0,'componentType':5126,'count':4,'type':'VEC3'},"
                   "{'bufferView':1,'componentType':5126,'count':4,'type':'VEC3'},"
                   "{'bufferView':2,'componentType':5126,'count':4,'type':'VEC2'},"
                   "{'bufferView':3,'componentType':5121,'normalized':true,'count':4,'type':'VEC2'},"
                   "{'bufferView':4,'componentType':5123,'count':6,'type':'SCALAR'}],"
                   "'bufferViews':[{'buffer':0,'byteOffset':%zu,'byteLength':48},"
                   "{'buffer':0,'byteOffset':%zu,'byteLength':48},"
                   "{'buffer':0,'byteOffset':%zu,'byteLength':32},"
                   "{'buffer':0,'byteOffset':%zu,'byteLength':8},"
                   "{'buffer':0,'byteOffset':%zu,'byteLength':12}],"
                   "'buffers':[{'byteLength':%zu,'uri':'%s'}]}");
    char *json = strf(tmpl, png64, op, on, ou, ou1, oi, b.n, uri);
    free(tmpl);
    free(uri);
    free(png64);
    free(png);
    return json;
}

static void test_texture_decode_srgb(void **state)
{
    (void)state;
    char *json = textured_quad(0);
    gi_scene *s = load_ok(write_text("quad.gltf", json));
    free(json);
    assert_int_equal(s->num_triangles, 2);
    assert_int_equal(s->num_textures, 1);
    const gi_texture *t = &s->textures[0];
    assert_string_equal(t->name, "checker");
    assert_int_equal(t->width, 2);
    assert_int_equal(t->height, 2);
    assert_int_equal(t->wrap_s, GI_WRAP_CLAMP);
    assert_int_equal(t->wrap_t, GI_WRAP_MIRROR);
    assert_int_equal(t->nearest, 1);
    /* sRGB decode of 128 (0.5 * 255 rounded) and of 64, 192; alpha stays linear */
    assert_float_equal(t->rgba[0], srgb_ref(128 / 255.0), 1e-6);
    assert_float_equal(t->rgba[0], 0.2158605, 1e-6);
    assert_float_equal(t->rgba[2], 1.0, 1e-7);
    assert_float_equal(t->rgba[3], 64 / 255.0, 1e-7);
    assert_float_equal(t->rgba[12], srgb_ref(64 / 255.0), 1e-6);
    assert_float_equal(t->rgba[14], srgb_ref(192 / 255.0), 1e-6);
    const gi_material *m = &s->materials[0];
    assert_int_equal(m->base_color_tex, 0);
    assert_int_equal(m->base_color_uv, 1);
    /* TEXCOORD_1 was normalized u8: 255 -> 1.0 */
    int v1 = -1;
    for (size_t v = 0; v < s->num_vertices; v++)
        if (s->positions[3 * v] == 1.0f && s->positions[3 * v + 1] == 0.0f)
            v1 = (int)v;
    assert_true(v1 >= 0);
    assert_float_equal(s->uv1[2 * v1], 1.0, 0);
    assert_float_equal(s->uv1[2 * v1 + 1], 1.0, 0);
    /* base colour: factor (0.5, 1, 1) times the nearest texel; uv1 used, uv0 ignored */
    float uv0[2] = {0.9f, 0.9f}, uv1[2] = {0.25f, 0.25f}, rgb[3];
    gi_scene_base_color(s, m, uv0, uv1, rgb);
    assert_float_equal(rgb[0], 0.5 * srgb_ref(128 / 255.0), 1e-6);
    assert_float_equal(rgb[1], 0.0, 1e-7);
    assert_float_equal(rgb[2], 1.0, 1e-6);
    uv1[0] = 0.75f;
    uv1[1] = 0.75f;
    gi_scene_base_color(s, m, uv0, uv1, rgb);
    assert_float_equal(rgb[1], srgb_ref(128 / 255.0), 1e-6);
    /* CLAMP in u: u = 3.0 stays at the right column */
    uv1[0] = 3.0f;
    uv1[1] = 0.25f;
    gi_scene_base_color(s, m, uv0, uv1, rgb);
    assert_float_equal(rgb[0], 0.5, 1e-6);
    gi_scene_free(s);

    /* a corrupt PNG is dropped with a warning; the material keeps its factor */
    json = textured_quad(1);
    s = load_ok(write_text("quad_bad_png.gltf", json));
    free(json);
    assert_int_equal(s->num_textures, 0);
    assert_int_equal(s->materials[0].base_color_tex, -1);
    assert_true(has_warning(s, "images[0] (embedded): corrupt PNG"));
    gi_scene_base_color(s, &s->materials[0], uv0, uv1, rgb);
    assert_float_equal(rgb[0], 0.5, 0);
    gi_scene_free(s);
}

/* ---- small generated scenes ---------------------------------------------------- */

/* Template of a valid one-triangle file; the malformed variants are made by
 * replacing one piece. Buffer: positions 0..36, u16 indices 36..42, a sparse
 * u16 index at 44, a sparse VEC3 value at 48..60. */
static char *tiny_buffer_uri(uint16_t i2, uint16_t sparse_index)
{
    blob b = {0};
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint16_t ind[3] = {0, 1, i2};
    float val[3] = {0.5f, 0.5f, 0.5f};
    blob_add(&b, pos, sizeof pos);
    blob_add(&b, ind, sizeof ind);
    blob_add(&b, &sparse_index, 2);
    blob_add(&b, val, sizeof val);
    assert_int_equal(b.n, 60);
    return data_uri(&b);
}

static const char *k_tiny =
    "{'asset':{'version':'2.0'},'scene':0,'scenes':[{'nodes':[0]}],"
    "'nodes':[{'name':'root','mesh':0}],"
    "'meshes':[{'primitives':[{'attributes':{'POSITION':0},'indices':1,'material':0}]}],"
    "'materials':[{'name':'mat'}],"
    "'accessors':[{'bufferView':0,'componentType':5126,'count':3,'type':'VEC3'},"
    "{'bufferView':1,'componentType':5123,'count':3,'type':'SCALAR'}],"
    "'bufferViews':[{'buffer':0,'byteOffset':0,'byteLength':36},"
    "{'buffer':0,'byteOffset':36,'byteLength':6},"
    "{'buffer':0,'byteOffset':44,'byteLength':2},"
    "{'buffer':0,'byteOffset':48,'byteLength':12}],"
    "'buffers':[{'byteLength':60,'uri':'URI'}]}";

static char *tiny_json(uint16_t i2, uint16_t sparse_index)
{
    char *t = q(k_tiny), *uri = tiny_buffer_uri(i2, sparse_index);
    char *r = replace(t, "URI", uri);
    free(t);
    free(uri);
    return r;
}

/* Load `json` written as `name`; expect `code` and every needle in the message. */
static void expect_fail(const char *name, const char *json, int code, const char *needle)
{
    char *path = write_text(name, json);
    gi_scene *s = (gi_scene *)1;
    gi_status st = {0};
    int rc = gi_scene_load(path, &s, &st);
    if (rc != code || !strstr(st.msg, needle) || strncmp(st.msg, path, strlen(path)) != 0)
        fail_msg("%s: got %d '%s', wanted %d with '%s'", name, rc, st.msg, code, needle);
    assert_int_equal(st.code, code);
    assert_null(s);
}

static void expect_fail_variant(const char *name, const char *from, const char *to, const char *needle)
{
    char *base = tiny_json(2, 1);
    char *f = q(from), *t = q(to);
    char *json = replace(base, f, t);
    expect_fail(name, json, GI_EXIT_DATA, needle);
    free(json);
    free(f);
    free(t);
    free(base);
}

static void test_tiny_valid_and_sparse(void **state)
{
    (void)state;
    char *json = tiny_json(2, 1);
    gi_scene *s = load_ok(write_text("tiny.gltf", json));
    assert_int_equal(s->num_triangles, 1);
    assert_int_equal(s->num_warnings, 0);
    assert_string_equal(s->materials[0].name, "mat");
    gi_scene_free(s);
    /* sparse substitution: vertex 1 becomes (0.5, 0.5, 0.5) */
    char *f = q("'type':'VEC3'}"), *t = q("'type':'VEC3','sparse':{'count':1,'indices':"
                                          "{'bufferView':2,'componentType':5123},'values':{'bufferView':3}}}");
    char *sp = replace(json, f, t);
    s = load_ok(write_text("sparse.gltf", sp));
    assert_vec3(s->positions + 3 * s->indices[1], 0.5, 0.5, 0.5, 0);
    assert_vec3(s->positions + 3 * s->indices[2], 0, 1, 0, 0);
    gi_scene_free(s);
    /* ... and its index out of range */
    char *bad = tiny_json(2, 5);
    char *bsp = replace(bad, f, t);
    expect_fail("sparse_oob.gltf", bsp, GI_EXIT_DATA, "accessors[0].sparse.indices: index 5");
    free(bsp);
    free(bad);
    free(sp);
    free(f);
    free(t);
    free(json);
}

static void test_malformed_files(void **state)
{
    (void)state;
    expect_fail_variant("acc_oob.gltf", "'POSITION':0", "'POSITION':9",
                        "meshes[0].primitives[0].attributes.POSITION: accessor 9 does not exist (file has 2)");
    expect_fail_variant("ind_oob.gltf", "'indices':1", "'indices':9", "indices");
    expect_fail_variant("bv_beyond_buffer.gltf", "'byteOffset':36,'byteLength':6",
                        "'byteOffset':36,'byteLength':600", "bufferViews[1]: byteOffset 36 + byteLength 600");
    expect_fail_variant("acc_beyond_bv.gltf", "'count':3,'type':'VEC3'", "'count':4,'type':'VEC3'",
                        "accessors[0]: byteOffset 0 + 4 elements");
    expect_fail_variant("cycle.gltf", "'nodes':[{'name':'root','mesh':0}]",
                        "'nodes':[{'name':'root','mesh':0,'children':[1]},{'children':[0]}]", "cycle");
    expect_fail_variant("self_child.gltf", "'name':'root',", "'name':'root','children':[0],", "cycle");
    expect_fail_variant("child_oob.gltf", "'name':'root',", "'name':'root','children':[7],",
                        "nodes[0].children[0]: node 7 does not exist (file has 1)");
    expect_fail_variant("two_parents.gltf", "'nodes':[{'name':'root','mesh':0}]",
                        "'nodes':[{'name':'root','mesh':0,'children':[2]},{'children':[2]},{}]",
                        "nodes[1].children[0]: node 2 is already a child of node 0");
    expect_fail_variant("mat_oob.gltf", "'material':0", "'material':3",
                        "meshes[0].primitives[0].material: material 3 does not exist (file has 1)");
    expect_fail_variant("stride.gltf", "'byteOffset':0,'byteLength':36", "'byteOffset':0,'byteLength':36,'byteStride':8",
                        "byteStride 8 is smaller than the element size 12");
    expect_fail_variant("count0.gltf", "'count':3,'type':'VEC3'", "'count':0,'type':'VEC3'", "accessors[0]: count 0");
    expect_fail_variant("scene_node_oob.gltf", "'scenes':[{'nodes':[0]}]", "'scenes':[{'nodes':[4]}]",
                        "scenes[0].nodes[0]: node 4 does not exist");
    expect_fail_variant("default_scene_oob.gltf", "'scene':0", "'scene':3", "scene: scene 3 does not exist");
    expect_fail_variant("mesh_oob.gltf", "'mesh':0", "'mesh':2", "nodes[0].mesh: mesh 2 does not exist");
    expect_fail_variant("camera_oob.gltf", "'mesh':0", "'mesh':0,'camera':1", "nodes[0].camera: camera 1 does not exist");
    expect_fail_variant("light_oob.gltf", "'mesh':0", "'mesh':0,'extensions':{'KHR_lights_punctual':{'light':2}}",
                        "KHR_lights_punctual.light: light 2 does not exist (file has 0)");
    expect_fail_variant("tex_oob.gltf", "'name':'mat'", "'name':'mat','pbrMetallicRoughness':{'baseColorTexture':{'index':4}}",
                        "materials[0].pbrMetallicRoughness.baseColorTexture: texture 4 does not exist");
    expect_fail_variant("image_oob.gltf", "'materials'", "'textures':[{'source':3}],'materials'",
                        "textures[0].source: image 3 does not exist (file has 0)");
    expect_fail_variant("sampler_oob.gltf", "'materials'", "'textures':[{'sampler':1}],'materials'",
                        "textures[0].sampler: sampler 1 does not exist");
    expect_fail_variant("buffer_oob.gltf", "{'buffer':0,'byteOffset':44", "{'buffer':3,'byteOffset':44",
                        "bufferViews[2].buffer: buffer 3 does not exist (file has 1)");
    expect_fail_variant("pos_type.gltf", "'componentType':5126,'count':3,'type':'VEC3'",
                        "'componentType':5126,'count':3,'type':'VEC2'",
                        "attributes.POSITION: accessor 0 has type VEC2, expected VEC3");
    expect_fail_variant("idx_type.gltf", "'componentType':5123,'count':3,'type':'SCALAR'",
                        "'componentType':5122,'count':3,'type':'SCALAR'", "has component type SHORT, expected UNSIGNED_BYTE");
    expect_fail_variant("bad_mode.gltf", "'material':0", "'material':0,'mode':9", "invalid mode 9");
    expect_fail_variant("bad_spot.gltf", "'materials'",
                        "'extensions':{'KHR_lights_punctual':{'lights':[{'type':'spot','spot':"
                        "{'innerConeAngle':1.0,'outerConeAngle':0.5}}]}},'materials'",
                        "lights[0]: spot cone angles");
    /* strengths beyond what the images' floats hold, and a negative colour */
    expect_fail_variant("bright_light.gltf", "'materials'",
                        "'extensions':{'KHR_lights_punctual':{'lights':[{'type':'point','intensity':1e38}]}},'materials'",
                        "lights[0]: intensity 1e+38 must be a finite number in 0..1e+15");
    expect_fail_variant("neg_colour.gltf", "'materials'",
                        "'extensions':{'KHR_lights_punctual':{'lights':[{'type':'point','intensity':1,"
                        "'color':[1,-0.5,1]}]}},'materials'",
                        "lights[0]: color -0.5 must be in 0..1e+15");
    expect_fail_variant("bright_emission.gltf", "'materials':[{'name':'mat'}]",
                        "'materials':[{'name':'mat','emissiveFactor':[1,1,0.5],"
                        "'extensions':{'KHR_materials_emissive_strength':{'emissiveStrength':1e16}}}]",
                        "emission 1e+16 (emissiveFactor times emissiveStrength) must be in 0..1e+15");
    expect_fail_variant("required_ext.gltf", "'materials'", "'extensionsUsed':['KHR_draco_mesh_compression'],"
                        "'extensionsRequired':['KHR_draco_mesh_compression'],'materials'",
                        "KHR_draco_mesh_compression");

    /* index value beyond the vertex count */
    char *j = tiny_json(7, 1);
    expect_fail("idx_value.gltf", j, GI_EXIT_DATA,
                "meshes[0].primitives[0].indices: index value 7 at position 2 is not below the vertex count 3");
    /* bad JSON: cut in the middle */
    j[strlen(j) / 2] = 0;
    expect_fail("bad.gltf", j, GI_EXIT_DATA, "bad.gltf: ");
    free(j);
    /* missing .bin: a system error naming the file */
    char *t = q(k_tiny);
    j = replace(t, "URI", "missing.bin");
    expect_fail("missing_bin.gltf", j, GI_EXIT_SYSTEM, "missing.bin");
    char *p = write_text("missing_bin2.gltf", j);
    gi_scene *s = NULL;
    gi_status st = {0};
    assert_int_equal(gi_scene_load(p, &s, &st), GI_EXIT_SYSTEM);
    assert_non_null(strstr(st.msg, strerror(ENOENT)));
    free(j);
    free(t);
    /* missing top-level file */
    snprintf(st.msg, sizeof st.msg, "x");
    char nofile[600];
    snprintf(nofile, sizeof nofile, "%s/no-such-file.gltf", g_tmp);
    assert_int_equal(gi_scene_load(nofile, &s, &st), GI_EXIT_SYSTEM);
    assert_null(s);
    assert_non_null(strstr(st.msg, "no-such-file.gltf"));
    assert_non_null(strstr(st.msg, strerror(ENOENT)));
    /* a directory */
    assert_int_equal(gi_scene_load(g_tmp, &s, &st), GI_EXIT_SYSTEM);
    /* empty file */
    expect_fail("empty.gltf", "", GI_EXIT_DATA, "empty.gltf");
}

/* A .glb made from the tiny scene: valid, then truncated at many lengths. */
static void test_glb_truncated(void **state)
{
    (void)state;
    blob b = {0};
    float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint16_t ind[4] = {0, 1, 2, 0};
    blob_add(&b, pos, sizeof pos);
    blob_add(&b, ind, sizeof ind);
    char *js = q("{'asset':{'version':'2.0'},'scene':0,'scenes':[{'nodes':[0]}],'nodes':[{'mesh':0}],"
                 "'meshes':[{'primitives':[{'attributes':{'POSITION':0},'indices':1}]}],"
                 "'accessors':[{'bufferView':0,'componentType':5126,'count':3,'type':'VEC3'},"
                 "{'bufferView':1,'componentType':5123,'count':3,'type':'SCALAR'}],"
                 "'bufferViews':[{'buffer':0,'byteOffset':0,'byteLength':36},{'buffer':0,'byteOffset':36,'byteLength':6}],"
                 "'buffers':[{'byteLength':44}]}   ");
    size_t jn = strlen(js);
    while (jn % 4)
        js[--jn] = 0; /* the JSON chunk ends on a 4-byte boundary (trailing spaces) */
    size_t total = 12 + 8 + jn + 8 + b.n;
    unsigned char *glb = malloc(total);
    assert_non_null(glb);
    uint32_t hdr[5] = {0x46546c67u, 2, (uint32_t)total, (uint32_t)jn, 0x4e4f534au};
    memcpy(glb, hdr, 20);
    memcpy(glb + 20, js, jn);
    uint32_t bin[2] = {(uint32_t)b.n, 0x004e4942u};
    memcpy(glb + 20 + jn, bin, 8);
    memcpy(glb + 28 + jn, b.d, b.n);
    gi_scene *s = load_ok(write_file("tiny.glb", glb, total));
    assert_int_equal(s->num_triangles, 1);
    /* no material in the file: one default material, white 0.8, roughness 1 */
    assert_int_equal(s->num_materials, 1);
    assert_float_equal(s->materials[0].base_color[0], 0.8, 1e-7);
    assert_float_equal(s->materials[0].roughness, 1.0, 0);
    gi_scene_free(s);
    for (size_t cut = 0; cut < total; cut += (cut < 40 ? 1 : 7)) {
        gi_status st = {0};
        s = NULL;
        int rc = gi_scene_load_memory(glb, cut, "cut.glb", NULL, &s, &st);
        if (rc != GI_EXIT_DATA)
            fail_msg("glb cut at %zu of %zu: rc %d (%s)", cut, total, rc, st.msg);
        assert_null(s);
        assert_non_null(strstr(st.msg, "cut.glb: "));
    }
    free(glb);
    free(js);
}

/* Random byte mutations of valid files: any outcome but a crash (0, 3 or 4). */
static void test_mutations_never_crash(void **state)
{
    (void)state;
    char *json = tiny_json(2, 1);
    size_t n = strlen(json);
    char *buf = malloc(n + 1);
    assert_non_null(buf);
    uint64_t x = 0x9e3779b97f4a7c15ull;
    int ok = 0;
    for (int iter = 0; iter < 3000; iter++) {
        memcpy(buf, json, n + 1);
        int flips = 1 + iter % 4;
        for (int k = 0; k < flips; k++) {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            static const char alphabet[] = "0123456789-9e+.[]{},:'\"xtrue";
            buf[x % n] = alphabet[(x >> 32) % (sizeof alphabet - 1)];
        }
        gi_scene *s = NULL;
        gi_status st = {0};
        int rc = gi_scene_load_memory(buf, n, "mut.gltf", NULL, &s, &st);
        assert_true(rc == 0 || rc == GI_EXIT_DATA || rc == GI_EXIT_SYSTEM);
        assert_true((rc == 0) == (s != NULL));
        if (rc)
            assert_true(strncmp(st.msg, "mut.gltf: ", 10) == 0);
        ok += rc == 0;
        gi_scene_free(s);
    }
    print_message("mutations: %d of 3000 still loaded\n", ok);
    free(buf);
    free(json);
}

static void test_strip_fan_winding_mirror(void **state)
{
    (void)state;
    /* a quad as TRIANGLE_STRIP (0,1,3,2 order) with +z normals, drawn by a
     * plain node and by a node mirrored in x (negative determinant) */
    blob b = {0};
    float pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    float nrm[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
    size_t op = blob_add(&b, pos, sizeof pos), on = blob_add(&b, nrm, sizeof nrm);
    char *uri = data_uri(&b);
    char *tmpl = q("{'asset':{'version':'2.0'},'scenes':[{'nodes':[0,1,2]}],"
                   "'nodes':[{'mesh':0},{'mesh':0,'scale':[-1,1,1]},{'mesh':1,'matrix':[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1]}],"
                   "'meshes':[{'primitives':[{'attributes':{'POSITION':0,'NORMAL':1},'mode':5}]},"
                   "{'primitives':[{'attributes':{'POSITION':0},'mode':6}]}],"
                   "'accessors':[{'bufferView':0,'componentType':5126,'count':4,'type':'VEC3'},"
                   "{'bufferView':1,'componentType':5126,'count':4,'type':'VEC3'}],"
                   "'bufferViews':[{'buffer':0,'byteOffset':%zu,'byteLength':48},{'buffer':0,'byteOffset':%zu,'byteLength':48}],"
                   "'buffers':[{'byteLength':%zu,'uri':'%s'}]}");
    char *json = strf(tmpl, op, on, b.n, uri);
    gi_scene *s = load_ok(write_text("strip.gltf", json));
    /* 2 (strip) + 2 (mirrored strip) + 2 (fan) triangles */
    assert_int_equal(s->num_triangles, 6);
    for (size_t t = 0; t < 4; t++) {
        const uint32_t *ix = s->indices + 3 * t;
        const float *a = s->positions + 3 * ix[0], *bb = s->positions + 3 * ix[1], *c = s->positions + 3 * ix[2];
        float e1[3] = {bb[0] - a[0], bb[1] - a[1], bb[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float gz = e1[0] * e2[1] - e1[1] * e2[0];
        /* geometric normal agrees with the stored (+z) normal, mirrored or not */
        assert_true(gz > 0.0f);
        assert_vec3(s->normals + 3 * ix[0], 0, 0, 1, 1e-6);
    }
    /* the mirrored instance lies at x <= 0 */
    assert_float_equal(s->bbox_min[0], -1.0, 0);
    /* the fan has no normals: flat, its vertices moved to z = 5 by the matrix */
    for (size_t t = 4; t < 6; t++)
        for (int k = 0; k < 3; k++) {
            assert_float_equal(s->positions[3 * s->indices[3 * t + k] + 2], 5.0, 0);
            assert_float_equal(fabsf(s->normals[3 * s->indices[3 * t + k] + 2]), 1.0, 1e-6);
        }
    assert_int_equal(s->num_materials, 1);
    assert_string_equal(s->materials[0].name, "default");
    gi_scene_free(s);
    free(json);
    free(tmpl);
    free(uri);
}

/* printf's spellings of non-finite numbers as JSON values */
static int has_bad_number(const char *json)
{
    static const char *bad[] = {" nan", "[nan", " -nan", "[-nan", " inf", "[inf", " -inf", "[-inf"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        if (strstr(json, bad[i]))
            return 1;
    return 0;
}

static void test_names_lights_materials(void **state)
{
    (void)state;
    blob b = {0};
    /* two triangles, the second degenerate (collinear), plus a zero normal */
    float pos[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0, 3, 0, 0};
    float nrm[15] = {0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 1};
    uint16_t ind[6] = {0, 1, 2, 0, 3, 4};
    size_t op = blob_add(&b, pos, sizeof pos), on = blob_add(&b, nrm, sizeof nrm), oi = blob_add(&b, ind, sizeof ind);
    char *uri = data_uri(&b);
    char *tmpl = q("{'asset':{'version':'2.0'},'scene':0,'scenes':[{'nodes':[0,1,2,3]}],"
                   "'extensionsUsed':['KHR_lights_punctual','KHR_materials_emissive_strength','KHR_materials_transmission'],"
                   "'extensions':{'KHR_lights_punctual':{'lights':["
                   "{'type':'spot','name':'lamp','intensity':100,'spot':{}},"
                   "{'type':'point','name':'lamp','intensity':5,'color':[1,0.5,0.25]},"
                   "{'type':'directional'}]}},"
                   "'nodes':[{'mesh':0},"
                   "{'translation':[1,2,3],'rotation':[0.70710678,0,0,0.70710678],'extensions':{'KHR_lights_punctual':{'light':0}}},"
                   "{'translation':[0,4,0],'extensions':{'KHR_lights_punctual':{'light':1}}},"
                   "{'children':[4]},{'extensions':{'KHR_lights_punctual':{'light':2}}}],"
                   "'meshes':[{'primitives':[{'attributes':{'POSITION':0,'NORMAL':1},'indices':2,'material':1},"
                   "{'attributes':{'POSITION':0,'NORMAL':1},'indices':2,'material':2},"
                   "{'attributes':{'POSITION':0,'NORMAL':1},'indices':2}]}],"
                   "'materials':[{'name':'glow','emissiveFactor':[1,0.5,0],'extensions':{'KHR_materials_emissive_strength':{'emissiveStrength':40}}},"
                   "{'name':'glow','doubleSided':true,'pbrMetallicRoughness':{'baseColorFactor':[0.2,0.4,0.6,1],'roughnessFactor':0.3,'metallicFactor':0.1}},"
                   "{'name':'a\\u0022b\\\\c\\nd\xe2\x98\x83'},{}],"
                   "'accessors':[{'bufferView':0,'componentType':5126,'count':5,'type':'VEC3'},"
                   "{'bufferView':1,'componentType':5126,'count':5,'type':'VEC3'},"
                   "{'bufferView':2,'componentType':5123,'count':6,'type':'SCALAR'}],"
                   "'bufferViews':[{'buffer':0,'byteOffset':%zu,'byteLength':60},{'buffer':0,'byteOffset':%zu,'byteLength':60},"
                   "{'buffer':0,'byteOffset':%zu,'byteLength':12}],"
                   "'buffers':[{'byteLength':%zu,'uri':'%s'}]}");
    char *json = strf(tmpl, op, on, oi, b.n, uri);
    gi_scene *s = load_ok(write_text("names.gltf", json));
    /* 3 primitives x 2 triangles, one of each pair degenerate and kept */
    assert_int_equal(s->num_triangles, 6);
    assert_int_equal(s->num_degenerate, 3);
    assert_true(has_warning(s, "3 degenerate"));
    assert_true(has_warning(s, "KHR_materials_transmission"));
    assert_false(has_warning(s, "KHR_materials_emissive_strength"));
    assert_true(has_warning(s, "zero-length"));
    /* the zero normal (vertex 2) was replaced by the face normal */
    assert_vec3(s->normals + 3 * s->indices[2], 0, 0, 1, 1e-6);
    /* materials: duplicates suffixed, unnamed numbered, default appended */
    assert_int_equal(s->num_materials, 5);
    assert_string_equal(s->materials[0].name, "glow");
    assert_string_equal(s->materials[1].name, "glow_2");
    assert_string_equal(s->materials[2].name, "a\"b\\c\nd\xe2\x98\x83");
    assert_string_equal(s->materials[3].name, "material3");
    assert_string_equal(s->materials[4].name, "default");
    assert_int_equal(s->tri_material[0], 1);
    assert_int_equal(s->tri_material[2], 2);
    assert_int_equal(s->tri_material[4], 4);
    assert_vec3(s->materials[0].emission, 40, 20, 0, 1e-5);
    assert_vec3(s->materials[1].base_color, 0.2, 0.4, 0.6, 1e-7);
    assert_float_equal(s->materials[1].roughness, 0.3, 1e-7);
    assert_float_equal(s->materials[1].metallic, 0.1, 1e-7);
    assert_int_equal(s->materials[1].double_sided, 1);
    assert_int_equal(s->materials[0].double_sided, 0);
    /* lights: names unique, spot defaults, world transforms */
    assert_int_equal(s->num_lights, 3);
    const gi_light *sp = &s->lights[0], *pt = &s->lights[1], *dl = &s->lights[2];
    assert_string_equal(sp->name, "lamp");
    assert_string_equal(pt->name, "lamp_2");
    assert_string_equal(dl->name, "light2");
    assert_int_equal(sp->type, GI_LIGHT_SPOT);
    assert_float_equal(sp->inner_cone, 0.0, 0);
    assert_float_equal(sp->outer_cone, GI_PI / 4, 1e-6);
    assert_float_equal(sp->intensity, 100, 0);
    assert_vec3(sp->position, 1, 2, 3, 1e-6);
    /* rotation +90 degrees about x takes -z to +y */
    assert_vec3(sp->direction, 0, 1, 0, 1e-6);
    assert_vec3(pt->position, 0, 4, 0, 0);
    assert_vec3(pt->color, 1, 0.5, 0.25, 0);
    assert_int_equal(dl->type, GI_LIGHT_DIRECTIONAL);
    assert_vec3(dl->direction, 0, 0, -1, 0);
    assert_vec3(dl->color, 1, 1, 1, 0);

    /* JSON: escaped names, no nan/inf, 16-hex hash */
    char *out = NULL;
    size_t outn = 0;
    FILE *f = open_memstream(&out, &outn);
    assert_non_null(f);
    gi_scene_print_json(s, f);
    assert_int_equal(fclose(f), 0);
    assert_non_null(strstr(out, "\"name\": \"a\\\"b\\\\c\\nd\xe2\x98\x83\""));
    char want[64];
    snprintf(want, sizeof want, "\"hash\": \"%016llx\"", (unsigned long long)s->hash);
    assert_non_null(strstr(out, want));
    assert_non_null(strstr(out, "\"triangles\": 6"));
    assert_non_null(strstr(out, "\"degenerate_triangles\": 3"));
    assert_non_null(strstr(out, "\"intensity_cd\": 100"));
    assert_non_null(strstr(out, "\"illuminance_lux\": 1"));
    assert_non_null(strstr(out, "\"outer_cone_deg\": 45"));
    assert_non_null(strstr(out, "\"emission\": [40, 20, 0]"));
    assert_false(has_bad_number(out));
    free(out);
    /* a non-finite value prints as null */
    s->surface_area = NAN;
    out = NULL;
    f = open_memstream(&out, &outn);
    gi_scene_print_json(s, f);
    fclose(f);
    assert_non_null(strstr(out, "\"surface_area_m2\": null"));
    assert_false(has_bad_number(out));
    free(out);
    gi_scene_free(s);
    free(json);
    free(tmpl);
    free(uri);
}

static void test_fingerprint(void **state)
{
    (void)state;
    char *json = tiny_json(2, 1);
    gi_scene *a = load_ok(write_text("fp.gltf", json));
    gi_scene *b = NULL;
    gi_status st = {0};
    assert_int_equal(gi_scene_load_memory(json, strlen(json), "mem.gltf", NULL, &b, &st), 0);
    assert_int_equal(a->hash, b->hash);
    assert_string_equal(b->path, "mem.gltf");
    uint64_t h = a->hash;
    a->positions[4] = 0.25f;
    assert_true(gi_scene_fingerprint(a) != h);
    a->positions[4] = 0.0f;
    assert_int_equal(gi_scene_fingerprint(a), h);
    a->uv0[1] = 0.5f;
    assert_true(gi_scene_fingerprint(a) != h);
    a->uv0[1] = 0.0f;
    a->uv1[0] = 0.5f;
    assert_true(gi_scene_fingerprint(a) != h);
    a->uv1[0] = 0.0f;
    a->tri_material[0] = 1;
    assert_true(gi_scene_fingerprint(a) != h);
    a->tri_material[0] = 0;
    uint32_t t = a->indices[1];
    a->indices[1] = a->indices[2];
    a->indices[2] = t;
    assert_true(gi_scene_fingerprint(a) != h);
    a->indices[2] = a->indices[1];
    a->indices[1] = t;
    /* material parameters are not part of it (scripts change them) */
    a->materials[0].base_color[0] = 0.1f;
    assert_int_equal(gi_scene_fingerprint(a), h);
    /* finalize recomputes bbox, area and hash */
    a->positions[3] = 2.0f;
    gi_scene_finalize(a);
    assert_float_equal(a->bbox_max[0], 2.0, 0);
    assert_float_equal(a->surface_area, 1.0, 1e-9);
    assert_true(a->hash != h);
    gi_scene_free(a);
    gi_scene_free(b);
    free(json);
    gi_scene_free(NULL);
}

static void test_load_memory_matches_file(void **state)
{
    (void)state;
    need_samples();
    const char *p = sample("gltf-samples/Box/glTF-Binary/Box.glb");
    FILE *f = fopen(p, "rb");
    assert_non_null(f);
    unsigned char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_true(n > 0 && n < sizeof buf);
    gi_scene *a = load_ok(p), *b = NULL;
    gi_status st = {0};
    assert_int_equal(gi_scene_load_memory(buf, n, "Box.glb", NULL, &b, &st), 0);
    assert_int_equal(a->hash, b->hash);
    gi_scene_free(a);
    gi_scene_free(b);
    /* an external .bin is refused when there is no base directory */
    p = sample("gltf-samples/Box/glTF/Box.gltf");
    f = fopen(p, "rb");
    assert_non_null(f);
    n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_int_equal(gi_scene_load_memory(buf, n, "Box.gltf", NULL, &b, &st), GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "external file"));
    /* ... and resolved against base_dir when given */
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/gltf-samples/Box/glTF", shared_dir());
    assert_int_equal(gi_scene_load_memory(buf, n, "Box.gltf", dir, &b, &st), 0);
    assert_int_equal(b->num_triangles, 12);
    gi_scene_free(b);
}

static void test_load_limit(void **state)
{
    (void)state;
    char *json = tiny_json(2, 1);
    gi_scene *s = NULL;
    gi_status st = {0};
    gi_scene_set_load_limit(2);
    int rc = gi_scene_load_memory(json, strlen(json), "lim.gltf", NULL, &s, &st);
    gi_scene_set_load_limit(0);
    assert_int_equal(rc, GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "limit"));
    assert_int_equal(gi_scene_load_memory(json, strlen(json), "lim.gltf", NULL, &s, &st), 0);
    gi_scene_free(s);
    free(json);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_samples_load_with_manifest_counts),
        cmocka_unit_test(test_variants_identical),
        cmocka_unit_test(test_simple_meshes_instanced),
        cmocka_unit_test(test_cameras),
        cmocka_unit_test(test_lights_punctual_lamp),
        cmocka_unit_test(test_iridescence_directional),
        cmocka_unit_test(test_texture_transform),
        cmocka_unit_test(test_primitive_modes),
        cmocka_unit_test(test_sponza_load_time),
        cmocka_unit_test(test_texture_sample_wrap),
        cmocka_unit_test(test_texture_sample_2d),
        cmocka_unit_test(test_texture_decode_srgb),
        cmocka_unit_test(test_tiny_valid_and_sparse),
        cmocka_unit_test(test_malformed_files),
        cmocka_unit_test(test_glb_truncated),
        cmocka_unit_test(test_mutations_never_crash),
        cmocka_unit_test(test_strip_fan_winding_mirror),
        cmocka_unit_test(test_names_lights_materials),
        cmocka_unit_test(test_fingerprint),
        cmocka_unit_test(test_load_memory_matches_file),
        cmocka_unit_test(test_load_limit),
    };
    return cmocka_run_group_tests(tests, setup_tmp, teardown_tmp);
}
