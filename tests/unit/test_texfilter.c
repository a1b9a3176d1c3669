/* test_texfilter.c - footprint-filtered textures: pyramid levels keep the mean,
 * box averages match the analytic means of checkerboards, stripes and ramps,
 * the minor axis of a thin footprint is not blurred, and the footprint found
 * from camera rays on a quad is the one geometry predicts, and is cut at the
 * rim of the quad's UV island. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "gi_pt.h"
#include "gi_scene.h"
#include "gi_texfilter.h"

/* A scene with one texture of w x h texels, value(x, y) in every RGB channel,
 * and (with quad) one textured square in the plane z = 0 spanning x, y in
 * [-1, 1] with u = (x + 1) / 2, v = (1 - y) / 2. */
static gi_scene *make_scene(int w, int h, float (*value)(int x, int y), int wrap, int quad)
{
    gi_scene *s = calloc(1, sizeof *s);
    assert_non_null(s);
    s->num_textures = 1;
    s->textures = calloc(1, sizeof *s->textures);
    gi_texture *t = &s->textures[0];
    t->width = w;
    t->height = h;
    t->wrap_s = t->wrap_t = wrap;
    t->rgba = malloc((size_t)w * (size_t)h * 4 * sizeof(float));
    assert_non_null(t->rgba);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float *p = t->rgba + 4 * ((size_t)y * (size_t)w + (size_t)x);
            p[0] = p[1] = p[2] = value(x, y);
            p[3] = 1.0f;
        }
    s->num_materials = 1;
    s->materials = calloc(1, sizeof *s->materials);
    gi_material *m = &s->materials[0];
    m->base_color[0] = m->base_color[1] = m->base_color[2] = 1.0f;
    m->base_color_tex = 0;
    m->uv_xform[0] = m->uv_xform[4] = 1.0f;
    if (quad) {
        static const float pos[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
        static const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
        s->num_vertices = 4;
        s->positions = malloc(sizeof pos);
        memcpy(s->positions, pos, sizeof pos);
        s->normals = calloc(12, sizeof(float));
        s->uv0 = malloc(8 * sizeof(float));
        s->uv1 = malloc(8 * sizeof(float));
        for (int i = 0; i < 4; i++) {
            s->normals[3 * i + 2] = 1.0f;
            s->uv0[2 * i] = s->uv1[2 * i] = (pos[3 * i] + 1.0f) * 0.5f;
            s->uv0[2 * i + 1] = s->uv1[2 * i + 1] = (1.0f - pos[3 * i + 1]) * 0.5f;
        }
        s->num_triangles = 2;
        s->indices = malloc(sizeof idx);
        memcpy(s->indices, idx, sizeof idx);
        s->tri_material = calloc(2, sizeof(uint32_t));
    }
    gi_scene_finalize(s);
    return s;
}

static float v_const(int x, int y) { (void)x; (void)y; return 0.3f; }
static float v_checker(int x, int y) { return (float)((x + y) & 1); }
static float v_stripes_u(int x, int y) { (void)y; return (float)(x & 1); }
static float v_hash(int x, int y)
{
    uint32_t h = (uint32_t)x * 73856093u ^ (uint32_t)y * 19349663u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return (float)(h & 1023u) / 1023.0f;
}
static float v_ramp_u(int x, int y) { (void)y; return ((float)x + 0.5f) / 64.0f; }

static gi_texfilter *filter_of(const gi_scene *s)
{
    gi_texfilter *f = NULL;
    gi_status st = {0};
    assert_int_equal(gi_texfilter_new(s, &f, &st), 0);
    assert_non_null(f);
    return f;
}

/* A constant texture of odd size stays constant at every footprint size,
 * whatever level the footprint selects. */
static void test_constant_odd_size(void **state)
{
    (void)state;
    gi_scene *s = make_scene(37, 5, v_const, GI_WRAP_REPEAT, 0);
    gi_texfilter *f = filter_of(s);
    const float uv[2] = {0.31f, 0.77f};
    for (float len = 0.0f; len < 40.0f; len = len * 2.0f + 0.01f) {
        float a[2] = {len, 0.1f * len}, b[2] = {-0.2f * len, 0.5f * len}, rgba[4];
        gi_texfilter_box(f, 0, uv, a, b, rgba);
        for (int c = 0; c < 3; c++)
            assert_float_equal(rgba[c], 0.3f, 1e-5f);
    }
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* One-texel checks: a zero footprint at a texel centre reads that texel; a
 * footprint of 16 x 16 texels (and 200 x 200, through the pyramid) averages
 * to one half. */
static void test_checker_means(void **state)
{
    (void)state;
    gi_scene *s = make_scene(256, 256, v_checker, GI_WRAP_REPEAT, 0);
    gi_texfilter *f = filter_of(s);
    float rgba[4];
    const float zero[2] = {0, 0};
    float uv[2] = {(10.0f + 0.5f) / 256.0f, (3.0f + 0.5f) / 256.0f}; /* texel (10, 3): 1 */
    gi_texfilter_box(f, 0, uv, zero, zero, rgba);
    assert_float_equal(rgba[0], 1.0f, 1e-5f);
    const float sizes[3] = {16.0f, 200.0f, 1000.0f};
    for (int i = 0; i < 3; i++) {
        float a[2] = {sizes[i] / 256.0f, 0}, b[2] = {0, sizes[i] / 256.0f};
        gi_texfilter_box(f, 0, uv, a, b, rgba);
        assert_float_equal(rgba[0], 0.5f, 0.02f);
    }
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* An unbounded footprint (a ray grazing the plane) gives the texture's mean,
 * finite, for either axis. */
static void test_infinite_footprint(void **state)
{
    (void)state;
    gi_scene *s = make_scene(64, 32, v_checker, GI_WRAP_REPEAT, 0);
    gi_texfilter *f = filter_of(s);
    const float uv[2] = {0.3f, 0.6f};
    const float fin[2] = {0.01f, 0.02f};
    const float inf_a[2] = {INFINITY, 0.0f}, inf_b[2] = {0.0f, -INFINITY};
    float rgba[4];
    gi_texfilter_box(f, 0, uv, inf_a, fin, rgba);
    assert_float_equal(rgba[0], 0.5f, 1e-5f);
    gi_texfilter_box(f, 0, uv, fin, inf_b, rgba);
    assert_float_equal(rgba[0], 0.5f, 1e-5f);
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* Stripes along u: a footprint 8 texels long across the stripes averages
 * them; one 8 texels long along them (and none across) keeps the stripe's
 * value: the minor axis is not blurred. */
static void test_anisotropic(void **state)
{
    (void)state;
    gi_scene *s = make_scene(64, 64, v_stripes_u, GI_WRAP_REPEAT, 0);
    gi_texfilter *f = filter_of(s);
    float rgba[4];
    float uv[2] = {(21.0f + 0.5f) / 64.0f, 0.5f}; /* column 21: 1 */
    const float zero[2] = {0, 0};
    float across[2] = {8.0f / 64.0f, 0.0f}, along[2] = {0.0f, 8.0f / 64.0f};
    gi_texfilter_box(f, 0, uv, across, zero, rgba);
    assert_float_equal(rgba[0], 0.5f, 0.02f);
    gi_texfilter_box(f, 0, uv, zero, along, rgba);
    assert_float_equal(rgba[0], 1.0f, 1e-5f);
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* A linear ramp keeps its value at the centre of any symmetric footprint
 * away from the border, at level 0 and through the pyramid. */
static void test_ramp_centre(void **state)
{
    (void)state;
    gi_scene *s = make_scene(64, 64, v_ramp_u, GI_WRAP_CLAMP, 0);
    gi_texfilter *f = filter_of(s);
    const float uv[2] = {0.5f, 0.5f};
    const float lens[4] = {1.0f, 5.0f, 20.0f, 40.0f};
    for (int i = 0; i < 4; i++) {
        float a[2] = {lens[i] / 64.0f, 0.0f}, b[2] = {0.0f, lens[i] / 64.0f}, rgba[4];
        gi_texfilter_box(f, 0, uv, a, b, rgba);
        assert_float_equal(rgba[0], 0.5f, 0.01f);
    }
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* Any parallelogram, rotated, sheared, partly outside the texture, in each
 * wrap mode, against a brute-force average under a 400 x 400 grid of points:
 * of a texel or more (area >= 1) the filter is exact for the texture taken
 * constant over each texel while it spans at most 8 rows (beyond, a coarser
 * level: within 0.06); below, its grid of bilinear lookups is within 0.05 of
 * the bilinear texture's mean (a random texture, the worst case). */
static void test_parallelogram_exact(void **state)
{
    (void)state;
    const int modes[3] = {GI_WRAP_REPEAT, GI_WRAP_CLAMP, GI_WRAP_MIRROR};
    int n_exact = 0, n_grid = 0;
    for (int mi = 0; mi < 3; mi++) {
        gi_scene *s = make_scene(16, 12, v_hash, modes[mi], 0);
        gi_texfilter *f = filter_of(s);
        const gi_texture *t = &s->textures[0];
        uint32_t seed = 12345u + (uint32_t)mi;
        for (int trial = 0; trial < 60; trial++) {
            float r[6];
            for (int k = 0; k < 6; k++) {
                seed = seed * 1664525u + 1013904223u;
                r[k] = (float)(seed >> 8) / 16777216.0f;
            }
            float uv[2] = {-0.5f + 2.0f * r[0], -0.5f + 2.0f * r[1]};
            float ang = 6.2831853f * r[2], la = 0.2f + 6.0f * r[3] * r[3], lb = 0.2f + 6.0f * r[4] * r[4];
            float skew = 0.3f + 1.2f * r[5];
            float a[2] = {la * cosf(ang) / 16.0f, la * sinf(ang) / 12.0f};
            float b[2] = {lb * cosf(ang + skew) / 16.0f, lb * sinf(ang + skew) / 12.0f};
            float area = la * lb * fabsf(sinf(skew));
            float got[4];
            gi_texfilter_box(f, 0, uv, a, b, got);
            gi_texture tn = *t;
            tn.nearest = area >= 1.0f;
            double ref = 0.0;
            const int N = 400;
            for (int j = 0; j < N; j++)
                for (int i = 0; i < N; i++) {
                    float ss = ((float)i + 0.5f) / (float)N - 0.5f, tt = ((float)j + 0.5f) / (float)N - 0.5f;
                    float q[4];
                    gi_texture_sample(&tn, uv[0] + ss * a[0] + tt * b[0], uv[1] + ss * a[1] + tt * b[1], q);
                    ref += q[0];
                }
            ref /= (double)N * N;
            float hy = 0.5f * (fabsf(a[1]) + fabsf(b[1])) * 12.0f, cy = uv[1] * 12.0f;
            int rows = (int)(floorf(cy + hy) - floorf(cy - hy)) + 1;
            if (area >= 1.0f && rows <= 8) {
                assert_float_equal(got[0], (float)ref, 0.002f);
                n_exact++;
            } else if (area >= 1.0f) {
                /* more rows: a coarser level, blurred by its 2 x 2 boxes */
                assert_float_equal(got[0], (float)ref, 0.06f);
            } else {
                assert_float_equal(got[0], (float)ref, 0.05f);
                n_grid++;
            }
        }
        gi_texfilter_free(f);
        gi_scene_free(s);
    }
    assert_true(n_exact > 60 && n_grid > 20); /* both paths were exercised */
}

/* A texture with a one-texel dark frame, clamped: footprints of 10 to 40
 * texels reaching beyond the edge see the frame's texels continue there. A
 * coarser level would average the frame with the texels inside it (0.6
 * where the clamp gives 0.2); the filter takes such footprints at level 0
 * and is exact (the texture taken constant per texel). */
static float v_frame(int x, int y) { return (x == 0 || y == 0 || x == 63 || y == 47) ? 0.2f : 1.0f; }

static void test_clamp_beyond_edge(void **state)
{
    (void)state;
    gi_scene *s = make_scene(64, 48, v_frame, GI_WRAP_CLAMP, 0);
    gi_texfilter *f = filter_of(s);
    gi_texture tn = s->textures[0];
    tn.nearest = 1;
    const float centres[5][2] = {{1.2f, 0.5f}, {-0.25f, 0.4f}, {0.5f, 1.3f}, {0.45f, -0.2f}, {1.05f, 1.1f}};
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) {
            float la = 10.0f + 15.0f * (float)k;
            float a[2] = {la / 64.0f, 0.3f * la / 48.0f}, b[2] = {-0.2f * la / 64.0f, la / 48.0f}, got[4];
            gi_texfilter_box(f, 0, centres[i], a, b, got);
            double ref = 0.0;
            const int N = 400;
            for (int j = 0; j < N; j++)
                for (int q = 0; q < N; q++) {
                    float ss = ((float)q + 0.5f) / (float)N - 0.5f, tt = ((float)j + 0.5f) / (float)N - 0.5f, v[4];
                    gi_texture_sample(&tn, centres[i][0] + ss * a[0] + tt * b[0],
                                      centres[i][1] + ss * a[1] + tt * b[1], v);
                    ref += v[0];
                }
            ref /= (double)N * N;
            assert_float_equal(got[0], (float)ref, 0.003f);
        }
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* A camera at (x, y, D) looking down -z at the quad of make_scene, 100 x 100
 * pixels of pixel_m metres at the quad (fov 0.5 rad): the ray through (c, c)
 * and its neighbours one pixel right and down (directions dx, dy), its origin
 * o and hit p; returns the quad's triangle at p (its diagonal runs from (-1,
 * -1) to (1, 1)). */
static uint32_t head_on(float x, float y, float pixel_m, float c, gi_vec3 *o, gi_vec3 *p, gi_vec3 *dx, gi_vec3 *dy)
{
    const int w = 100, h = 100;
    const float fov = 0.5f, D = pixel_m * (float)h / (2.0f * tanf(0.5f * fov));
    gi_camera cam = {.position = {x, y, D}, .forward = {0, 0, -1}, .up = {0, 1, 0}, .yfov = fov};
    gi_vec3 d;
    gi_camera_ray(&cam, w, h, c, c, o, &d);
    gi_camera_ray(&cam, w, h, c + 1.0f, c, o, dx);
    gi_camera_ray(&cam, w, h, c, c + 1.0f, o, dy);
    *p = gi_add(*o, gi_scale(d, -o->z / d.z));
    return (p->y - p->x <= 0.0f) ? 0 : 1;
}

/* The footprint from camera rays: a quad 2 m wide with a 512-texel checker,
 * seen head-on from distance D through a pixel that spans D * 2 tan(fov/2) / h
 * metres. Close (a quarter texel per pixel) the texel is (nearly) the point
 * lookup; far (8 texels per pixel) it is the checker's mean. */
static void test_texel_from_camera(void **state)
{
    (void)state;
    gi_scene *s = make_scene(512, 512, v_checker, GI_WRAP_REPEAT, 1);
    gi_texfilter *f = filter_of(s);
    const float texel_m = 2.0f / 512.0f;
    const float per_pixel[2] = {0.25f, 8.0f};
    for (int i = 0; i < 2; i++) {
        gi_vec3 o, p, dx, dy;
        uint32_t tri = head_on(0.0013f, 0.0021f, per_pixel[i] * texel_m, 50.5f, &o, &p, &dx, &dy);
        float rgb[3], point[4];
        gi_texfilter_texel(f, &s->materials[0], tri, o, p, dx, dy, rgb);
        gi_texture_sample(&s->textures[0], (p.x + 1.0f) * 0.5f, (1.0f - p.y) * 0.5f, point);
        if (i == 0)
            assert_float_equal(rgb[0], point[0], 0.3f);
        else
            assert_float_equal(rgb[0], 0.5f, 0.03f);
    }
    gi_texfilter_free(f);
    gi_scene_free(s);
}

/* A footprint that crosses the rim of its face's UV island is cut there: the
 * quad's left edge (x = -1, u = 0) has no neighbour, and a pixel of 8 texels
 * centred 0.64 texel inside it averages the ramp over u in [0, 4.64 texels],
 * not over the texture's far end that a repeat wraps in (~0.43). Its
 * diagonal is shared: a footprint across it is not cut. */
static void test_cut_at_island_rim(void **state)
{
    (void)state;
    gi_scene *s = make_scene(64, 64, v_ramp_u, GI_WRAP_REPEAT, 1);
    gi_texfilter *f = filter_of(s);
    const float at[2][2] = {{-0.98f, 0.1f}, {0.02f, 0.0f}}; /* by the rim; on the diagonal */
    for (int i = 0; i < 2; i++) {
        gi_vec3 o, p, dx, dy;
        uint32_t tri = head_on(at[i][0], at[i][1], 8.0f * 2.0f / 64.0f, 50.0f, &o, &p, &dx, &dy);
        float rgb[3];
        gi_texfilter_texel(f, &s->materials[0], tri, o, p, dx, dy, rgb);
        float u = (p.x + 1.0f) * 0.5f * 64.0f; /* in texels */
        if (i == 0) {
            /* the texel-constant ramp's mean over [0, u + 4] */
            float hi = u + 4.0f, sum = 0.0f;
            for (int k = 0; (float)k < hi; k++)
                sum += ((float)k + 0.5f) / 64.0f * fminf(1.0f, hi - (float)k);
            assert_float_equal(rgb[0], sum / hi, 0.005f);
        } else {
            assert_float_equal(rgb[0], u / 64.0f, 0.01f); /* uncut: the mean at the centre */
        }
    }
    gi_texfilter_free(f);
    gi_scene_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_constant_odd_size),
        cmocka_unit_test(test_checker_means),
        cmocka_unit_test(test_anisotropic),
        cmocka_unit_test(test_ramp_centre),
        cmocka_unit_test(test_parallelogram_exact),
        cmocka_unit_test(test_clamp_beyond_edge),
        cmocka_unit_test(test_texel_from_camera),
        cmocka_unit_test(test_infinite_footprint),
        cmocka_unit_test(test_cut_at_island_rim),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
