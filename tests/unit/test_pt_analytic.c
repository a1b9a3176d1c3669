/* test_pt_analytic.c - the reference path tracer against analytic truth:
 * inverse-square and cosine laws, area-source configuration factors, flux
 * conservation, closed rooms of high reflectance (no bounce cap), and the
 * furnace. Each Monte Carlo check allows max(4 standard errors, a small
 * floor) and is sized so that a 5% mistake falls outside it. */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gi_emit.h"
#include "gi_gltf_write.h"
#include "gi_light.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_pt.h"
#include "gi_brdf.h"
#include "gi_rt.h"
#include "gi_scene.h"

static char g_dir[256];

typedef struct world {
    gi_scene *s;
    gi_rt *rt;
    gi_pt *pt;
    gi_light lights[8];
    size_t nl;
} world;

/* Write the builder's scene, load it back and build a tracer for `lights`. */
static void world_make(world *w, gi_gltf_builder *b, const char *name, int threads)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s.gltf", g_dir, name);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, path, &st), 0);
    gi_gltf_builder_free(b);
    assert_int_equal(gi_scene_load(path, &w->s, &st), 0);
    assert_int_equal(gi_rt_new(w->s, &w->rt, &st), 0);
    gi_pt_opts o;
    gi_pt_opts_default(&o);
    o.progress = 0;
    o.threads = threads;
    o.seed = getenv("GI_TEST_SEED") ? strtoull(getenv("GI_TEST_SEED"), NULL, 10) : 7;
    assert_int_equal(gi_pt_new(w->rt, w->lights, w->nl, w->s->materials, w->s->num_materials, &o,
                               &w->pt, &st),
                     0);
}

static void world_free(world *w)
{
    gi_pt_free(w->pt);
    gi_rt_free(w->rt);
    gi_scene_free(w->s);
}

static gi_light point_light(float x, float y, float z, float cd)
{
    gi_light l;
    memset(&l, 0, sizeof l);
    strcpy(l.name, "p");
    l.type = GI_LIGHT_POINT;
    l.enabled = 1;
    l.color[0] = l.color[1] = l.color[2] = 1.0f;
    l.intensity = cd;
    l.position[0] = x;
    l.position[1] = y;
    l.position[2] = z;
    return l;
}

static gi_light area_light(const float c[3], const float u[3], const float v[3], float nits)
{
    gi_light l;
    memset(&l, 0, sizeof l);
    strcpy(l.name, "a");
    l.type = GI_LIGHT_AREA;
    l.enabled = 1;
    l.color[0] = l.color[1] = l.color[2] = 1.0f;
    l.intensity = nits;
    memcpy(l.position, c, sizeof l.position);
    memcpy(l.u, u, sizeof l.u);
    memcpy(l.v, v, sizeof l.v);
    return l;
}

/* Albedo of a dielectric roughness-1 material is 0.96 base + 0.04 (gi_brdf.h):
 * the base colour that gives reflectance rho. */
static float base_for_albedo(float rho) { return (rho - 0.04f) / 0.96f; }

static void big_plane(gi_gltf_builder *b, float half, int mat)
{
    float p0[3] = {-half, 0, -half}, p1[3] = {-half, 0, half}, p2[3] = {half, 0, half},
          p3[3] = {half, 0, -half};
    gi_gltf_add_quad(b, p0, p1, p2, p3, mat); /* normal +y: (p1-p0) x (p2-p0) */
}

/* ---- 1. inverse-square and cosine law ---------------------------------- */
static void test_point_inverse_square(void **state)
{
    (void)state;
    world w = {0};
    w.lights[w.nl++] = point_light(0.0f, 2.0f, 0.0f, 100.0f);
    gi_gltf_builder *b = gi_gltf_builder_new();
    float black[3] = {0.0f, 0.0f, 0.0f};
    int m = gi_gltf_add_material(b, "floor", black, 1.0f, 1.0f, NULL, 0);
    big_plane(b, 1000.0f, m);
    world_make(&w, b, "plane_point", 2);
    /* sensors on the black floor facing up, and tilted ones above it */
    float pts[][6] = {
        {0, 0, 0, 0, 1, 0},   {1, 0, 0, 0, 1, 0},   {2, 0, 0, 0, 1, 0},      {5, 0, 3, 0, 1, 0},
        {0.3f, 0, -7, 0, 1, 0}, {1, 0.5f, 0, -1, 1, 0}, {0, 1, 1, 0, 0.2f, -1},
    };
    size_t n = sizeof pts / sizeof pts[0];
    for (size_t i = 0; i < n; i++) { /* normalise normals as gi-compare sensors does */
        gi_vec3 nn = gi_norm(gi_v3p(pts[i] + 3));
        gi_v3store(pts[i] + 3, nn);
    }
    double lux[16], err[16];
    gi_status st = {0};
    assert_int_equal(gi_pt_sensors(w.pt, &pts[0][0], n, 16, lux, err, &st), 0);
    for (size_t i = 0; i < n; i++) {
        gi_vec3 d = gi_sub(gi_v3p(w.lights[0].position), gi_v3p(pts[i]));
        float d2 = gi_dot(d, d);
        float cosx = gi_dot(gi_norm(d), gi_v3p(pts[i] + 3));
        double expect = 100.0 * fmax(0.0, cosx) / d2;
        /* the sensor sees only the light and a black floor: exact */
        if (fabs(lux[i] - expect) > 1e-4 * expect + 1e-9)
            fail_msg("point %zu: E = %.6g lux, expected I cos/d^2 = %.6g", i, lux[i], expect);
    }
    world_free(&w);
}

/* Spot and directional lights obey the same laws with their own intensity. */
static void test_spot_directional(void **state)
{
    (void)state;
    world w = {0};
    gi_light sp = point_light(0.0f, 3.0f, 0.0f, 400.0f);
    sp.type = GI_LIGHT_SPOT;
    sp.direction[1] = -1.0f;
    sp.inner_cone = (float)(20.0 * GI_PI / 180.0);
    sp.outer_cone = (float)(30.0 * GI_PI / 180.0);
    w.lights[w.nl++] = sp;
    gi_gltf_builder *b = gi_gltf_builder_new();
    float black[3] = {0, 0, 0};
    int m = gi_gltf_add_material(b, "floor", black, 1.0f, 1.0f, NULL, 0);
    big_plane(b, 100.0f, m);
    world_make(&w, b, "plane_spot", 1);
    /* inside the inner cone (full), outside the outer cone (zero) */
    float pts[3][6] = {{0.5f, 0, 0, 0, 1, 0}, {3.0f, 0, 0, 0, 1, 0}, {0, 0, 0, 0, 1, 0}};
    double lux[3], err[3];
    gi_status st = {0};
    assert_int_equal(gi_pt_sensors(w.pt, &pts[0][0], 3, 4, lux, err, &st), 0);
    double d2 = 9.0 + 0.25;
    double e0 = 400.0 * (3.0 / sqrt(d2)) / d2;
    assert_true(fabs(lux[0] - e0) < 1e-4 * e0);
    assert_true(lux[1] == 0.0); /* atan(3/3) = 45 deg > 30 deg */
    assert_true(fabs(lux[2] - 400.0 / 9.0) < 1e-4 * 400.0 / 9.0);
    world_free(&w);

    world w2 = {0};
    gi_light sun;
    memset(&sun, 0, sizeof sun);
    sun.type = GI_LIGHT_DIRECTIONAL;
    sun.enabled = 1;
    sun.color[0] = sun.color[1] = sun.color[2] = 1.0f;
    sun.intensity = 10000.0f;
    gi_vec3 dir = gi_norm(gi_v3(0.3f, -1.0f, 0.2f));
    gi_v3store(sun.direction, dir);
    w2.lights[w2.nl++] = sun;
    b = gi_gltf_builder_new();
    m = gi_gltf_add_material(b, "floor", black, 1.0f, 1.0f, NULL, 0);
    big_plane(b, 100.0f, m);
    world_make(&w2, b, "plane_sun", 1);
    float p2[1][6] = {{1, 0, 1, 0, 1, 0}};
    assert_int_equal(gi_pt_sensors(w2.pt, &p2[0][0], 1, 4, lux, err, &st), 0);
    double es = 10000.0 * -dir.y;
    assert_true(fabs(lux[0] - es) < 1e-4 * es);
    world_free(&w2);
}

/* ---- 2. area source: E = L * (projected solid angle) -------------------- */
/* Lambert's formula for a polygon seen from x with normal n:
 * integral of cos over the solid angle = 1/2 sum_i theta_i n . unit(R_i x R_i+1). */
static double polygon_projected_solid_angle(const gi_vec3 *poly, int k, gi_vec3 x, gi_vec3 n)
{
    double sum = 0.0;
    for (int i = 0; i < k; i++) {
        gi_vec3 a = gi_sub(poly[i], x), c = gi_sub(poly[(i + 1) % k], x);
        double ax = a.x, ay = a.y, az = a.z, cx = c.x, cy = c.y, cz = c.z;
        double la = sqrt(ax * ax + ay * ay + az * az), lc = sqrt(cx * cx + cy * cy + cz * cz);
        double dot = (ax * cx + ay * cy + az * cz) / (la * lc);
        double th = acos(fmax(-1.0, fmin(1.0, dot)));
        double gx = ay * cz - az * cy, gy = az * cx - ax * cz, gz = ax * cy - ay * cx;
        double lg = sqrt(gx * gx + gy * gy + gz * gz);
        if (lg > 0)
            sum += th * (n.x * gx + n.y * gy + n.z * gz) / lg;
    }
    return 0.5 * fabs(sum);
}

static void test_area_configuration_factor(void **state)
{
    (void)state;
    world w = {0};
    float c[3] = {0, 1, 0}, u[3] = {0.5f, 0, 0}, v[3] = {0, 0, 0.25f};
    const float L = 1000.0f;
    w.lights[w.nl++] = area_light(c, u, v, L); /* u x v = -y: emits down */
    gi_gltf_builder *b = gi_gltf_builder_new();
    float black[3] = {0, 0, 0};
    int m = gi_gltf_add_material(b, "floor", black, 1.0f, 1.0f, NULL, 0);
    big_plane(b, 100.0f, m);
    world_make(&w, b, "plane_area", 2);
    float pts[][6] = {
        {0, 0, 0, 0, 1, 0},       {0.5f, 0, 0, 0, 1, 0},   {0.5f, 0, 0.25f, 0, 1, 0},
        {2, 0, 0, 0, 1, 0},       {0.45f, 0.9f, 0, 0, 1, 0}, /* close under the edge */
        {0, 0.5f, 0, 0.6f, 0.8f, 0},
    };
    size_t n = sizeof pts / sizeof pts[0];
    gi_vec3 poly[4] = {gi_v3(-0.5f, 1, -0.25f), gi_v3(0.5f, 1, -0.25f), gi_v3(0.5f, 1, 0.25f),
                       gi_v3(-0.5f, 1, 0.25f)};
    double lux[8], err[8];
    gi_status st = {0};
    assert_int_equal(gi_pt_sensors(w.pt, &pts[0][0], n, 65536, lux, err, &st), 0);
    for (size_t i = 0; i < n; i++) {
        double expect = L * polygon_projected_solid_angle(poly, 4, gi_v3p(pts[i]), gi_v3p(pts[i] + 3));
        double tol = fmax(4.0 * err[i], 0.003 * expect);
        print_message("area point %zu: E = %.5g +- %.2g lux, exact %.5g (%.2f%%)\n", i, lux[i], err[i],
                      expect, 100.0 * (lux[i] - expect) / expect);
        assert_true(tol < 0.02 * expect); /* precise enough to catch a 5% mistake */
        if (fabs(lux[i] - expect) > tol)
            fail_msg("area point %zu: E = %.6g +- %.3g, exact pi L F = %.6g", i, lux[i], err[i], expect);
    }
    world_free(&w);
}

/* ---- 2a. the relight's analytic irradiance of a rectangle ------------------ */
/* gi_area_light_form (Lambert's formula, clipped to the receiver's plane)
 * against a 512 x 512 stratified estimate with the light's own sampling, at
 * points under the light, beside it, close under an edge, far away, with
 * tilted normals whose plane cuts the rectangle, and behind it (0). */
static void test_area_form_analytic(void **state)
{
    (void)state;
    float c[3] = {0, 1, 0}, u[3] = {0.5f, 0, 0}, v[3] = {0, 0, 0.25f};
    gi_light l = area_light(c, u, v, 1.0f);
    const float pts[][6] = {
        {0, 0, 0, 0, 1, 0},          {2, 0, 0, 0, 1, 0},          {0.45f, 0.97f, 0, 0, 1, 0},
        {0, 0.9f, 0, 1, 0, 0},       {0.2f, 0.5f, 0.1f, -0.6f, 0.8f, 0}, {0, 0.5f, 0, 0.6f, 0.8f, 0},
        {30, -20, 10, 0, 1, 0},      {0.3f, 0.99f, 0.2f, 0, 0, 1}, {0, 1.5f, 0, 0, -1, 0},
    };
    const int K = 512;
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        gi_vec3 x = gi_v3p(pts[i]), n = gi_norm(gi_v3p(pts[i] + 3));
        double mc = 0.0;
        for (int j = 0; j < K * K; j++) {
            gi_light_sample ls;
            if (!gi_light_sample_at(&l, x, ((float)(j % K) + 0.5f) / K, ((float)(j / K) + 0.5f) / K, &ls))
                continue;
            double co = gi_dot(n, ls.wi);
            if (co > 0.0)
                mc += ls.value.x * co;
        }
        mc /= (double)K * K;
        double an = gi_area_light_form(&l, x, n);
        print_message("form point %zu: analytic %.6g, sampled %.6g\n", i, an, mc);
        if (fabs(an - mc) > 0.003 * mc + 1e-9)
            fail_msg("form point %zu: analytic %.6g, sampled %.6g", i, an, mc);
    }
}

/* ---- 2b. emissive glTF surfaces: the same rectangle as geometry ---------- */
/* The rectangle of test_area_configuration_factor as two emissive triangles
 * (single-sided, facing down). The mesh light that gi-relight builds from
 * them (gi_emit_light + gi_light_sample_at, stratified, no shadow rays needed
 * here) and the path tracer's own emitter sampling must both give pi L F;
 * the sampled pdf must equal gi_emit_pdf; the back side must get nothing. */
static void test_emissive_configuration_factor(void **state)
{
    (void)state;
    world w = {0};
    const float L = 1000.0f;
    gi_gltf_builder *b = gi_gltf_builder_new();
    float black[3] = {0, 0, 0}, le[3] = {L, L, L};
    int m = gi_gltf_add_material(b, "floor", black, 1.0f, 1.0f, NULL, 0);
    int me = gi_gltf_add_material(b, "panel", black, 1.0f, 1.0f, le, 0);
    big_plane(b, 100.0f, m);
    float q0[3] = {-0.5f, 1, -0.25f}, q1[3] = {0.5f, 1, -0.25f}, q2[3] = {0.5f, 1, 0.25f}, q3[3] = {-0.5f, 1, 0.25f};
    gi_gltf_add_quad(b, q0, q1, q2, q3, me); /* counter-clockwise from below: faces -y */
    world_make(&w, b, "plane_emissive", 2);
    gi_status st = {0};
    gi_emit *e = NULL;
    assert_int_equal(gi_emit_build(w.s, w.s->materials, &e, &st), 0);
    assert_non_null(e);
    assert_int_equal(e->n, 2);
    assert_true(fabs(e->power - GI_PI * L * 0.5) < 1e-3 * GI_PI * L * 0.5);
    gi_light ml;
    gi_emit_light(e, 1, &ml);
    float pts[][6] = {
        {0, 0, 0, 0, 1, 0}, {0.5f, 0, 0, 0, 1, 0}, {2, 0, 0, 0, 1, 0}, {0.45f, 0.9f, 0, 0, 1, 0},
        {0, 0.5f, 0, 0.6f, 0.8f, 0},
    };
    size_t n = sizeof pts / sizeof pts[0];
    gi_vec3 poly[4] = {gi_v3p(q0), gi_v3p(q1), gi_v3p(q2), gi_v3p(q3)};
    double lux[8], err[8];
    assert_int_equal(gi_pt_sensors(w.pt, &pts[0][0], n, 65536, lux, err, &st), 0);
    for (size_t i = 0; i < n; i++) {
        gi_vec3 x = gi_v3p(pts[i]), nn = gi_v3p(pts[i] + 3);
        double expect = L * polygon_projected_solid_angle(poly, 4, x, nn);
        /* the mesh light, 256 x 256 stratified samples */
        const int k = 256;
        double sum = 0.0;
        for (int j = 0; j < k * k; j++) {
            float u1 = ((float)(j % k) + 0.5f) / (float)k, u2 = ((float)(j / k) + 0.5f) / (float)k;
            gi_light_sample ls;
            if (!gi_light_sample_at(&ml, x, u1, u2, &ls))
                continue;
            sum += (double)ls.value.y * fmax(0.0, (double)gi_dot(nn, ls.wi));
        }
        double mesh = sum / (double)(k * k);
        print_message("emissive point %zu: mesh light %.5g, path tracer %.5g +- %.2g, exact %.5g lux\n", i, mesh,
                      lux[i], err[i], expect);
        if (fabs(mesh - expect) > 0.003 * expect)
            fail_msg("emissive point %zu: mesh light E = %.6g, exact pi L F = %.6g", i, mesh, expect);
        /* the relight's closed form for a few emissive triangles */
        gi_vec3 ea;
        assert_int_equal(gi_light_analytic(&ml, x, gi_norm(nn), &ea), 1);
        if (fabs(ea.y - expect) > 1e-4 * expect)
            fail_msg("emissive point %zu: analytic E = %.6g, exact %.6g", i, ea.y, expect);
        double tol = fmax(4.0 * err[i], 0.003 * expect);
        assert_true(tol < 0.02 * expect);
        if (fabs(lux[i] - expect) > tol)
            fail_msg("emissive point %zu: path tracer E = %.6g +- %.3g, exact %.6g", i, lux[i], err[i], expect);
        /* the pdf of each sample is the one MIS asks for */
        for (size_t t = 0; t < e->n; t++) {
            gi_light_sample ls;
            gi_vec3 q, ng;
            if (!gi_emit_sample(e, t, x, 0.3f, 0.6f, &ls, &q, &ng))
                continue;
            float p2 = gi_emit_pdf(e, e->tri[t], ls.wi, ls.dist);
            assert_true(fabsf(p2 - ls.pdf) <= 1e-4f * ls.pdf);
        }
    }
    /* above the panel, looking down at its back: single-sided, nothing */
    gi_light_sample ls;
    assert_int_equal(gi_light_sample_at(&ml, gi_v3(0, 2, 0), 0.5f, 0.5f, &ls), 0);
    gi_vec3 eback;
    assert_int_equal(gi_light_analytic(&ml, gi_v3(0, 2, 0), gi_v3(0, -1, 0), &eback), 1);
    assert_true(eback.y == 0.0f);
    assert_true(gi_emit_pdf(e, w.s->num_triangles + 5, gi_v3(0, 1, 0), 1.0f) == 0.0f);
    gi_emit_free(e);
    /* double-sided, the same panel emits upwards too: from 1 m above it, by
     * symmetry, the exact value of 1 m below; the power counts both sides */
    gi_material *mats = malloc(w.s->num_materials * sizeof *mats);
    assert_non_null(mats);
    memcpy(mats, w.s->materials, w.s->num_materials * sizeof *mats);
    mats[me].double_sided = 1;
    assert_int_equal(gi_emit_build(w.s, mats, &e, &st), 0);
    assert_non_null(e);
    assert_true(fabs(e->power - GI_PI * L) < 1e-3 * GI_PI * L);
    gi_emit_light(e, 2, &ml);
    gi_vec3 up = gi_v3(0, 2, 0), down = gi_v3(0, -1, 0);
    double expect = L * polygon_projected_solid_angle(poly, 4, gi_v3(0, 0, 0), gi_v3(0, 1, 0)), sum = 0.0;
    const int k = 256;
    for (int j = 0; j < k * k; j++) {
        gi_light_sample s2;
        if (gi_light_sample_at(&ml, up, ((float)(j % k) + 0.5f) / (float)k, ((float)(j / k) + 0.5f) / (float)k, &s2))
            sum += (double)s2.value.y * fmax(0.0, (double)gi_dot(down, s2.wi));
    }
    print_message("double-sided panel from above: %.5g lux, exact %.5g\n", sum / (k * k), expect);
    assert_true(fabs(sum / (k * k) - expect) < 0.003 * expect);
    assert_int_equal(gi_light_analytic(&ml, up, down, &eback), 1);
    assert_true(fabs(eback.y - expect) < 1e-4 * expect);
    gi_emit_free(e);
    free(mats);
    world_free(&w);
}

/* ---- 3. flux conservation in a black box -------------------------------- */
/* Midpoint-rule sum of E * dA over the six inner faces of the cube [-1,1]^3. */
static double box_flux(world *w, int k, int spp, double *stderr_out)
{
    size_t n = 6 * (size_t)k * (size_t)k;
    float *pts = malloc(n * 6 * sizeof *pts);
    double *lux = malloc(n * sizeof *lux), *err = malloc(n * sizeof *err);
    size_t i = 0;
    for (int f = 0; f < 6; f++) {
        int ax = f / 2;
        float side = (f % 2) ? 1.0f : -1.0f;
        for (int a = 0; a < k; a++)
            for (int bb = 0; bb < k; bb++) {
                float p[3], nn[3] = {0, 0, 0};
                p[ax] = side;
                p[(ax + 1) % 3] = -1.0f + (2.0f * (float)a + 1.0f) / (float)k;
                p[(ax + 2) % 3] = -1.0f + (2.0f * (float)bb + 1.0f) / (float)k;
                nn[ax] = -side;
                memcpy(pts + 6 * i, p, sizeof p);
                memcpy(pts + 6 * i + 3, nn, sizeof nn);
                i++;
            }
    }
    gi_status st = {0};
    assert_int_equal(gi_pt_sensors(w->pt, pts, n, spp, lux, err, &st), 0);
    double dA = 4.0 / ((double)k * k), sum = 0.0, var = 0.0;
    for (i = 0; i < n; i++) {
        sum += lux[i] * dA;
        var += err[i] * err[i] * dA * dA;
    }
    free(pts);
    free(lux);
    free(err);
    *stderr_out = sqrt(var);
    return sum;
}

static void black_box(gi_gltf_builder *b, float rho)
{
    /* rho 0: metallic black, the only material with zero reflectance */
    float base = rho > 0 ? base_for_albedo(rho) : 0.0f;
    float col[3] = {base, base, base};
    int m = gi_gltf_add_material(b, "walls", col, 1.0f, rho > 0 ? 0.0f : 1.0f, NULL, 0);
    float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    gi_gltf_add_box(b, lo, hi, m, 1);
}

static void test_flux_conservation(void **state)
{
    (void)state;
    /* point source off centre: sum E A = 4 pi I */
    world w = {0};
    const float I = 50.0f;
    w.lights[w.nl++] = point_light(0.2f, -0.3f, 0.1f, I);
    gi_gltf_builder *b = gi_gltf_builder_new();
    black_box(b, 0.0f);
    world_make(&w, b, "black_box_point", 2);
    double se;
    double phi = box_flux(&w, 48, 2, &se);
    double expect = 4.0 * GI_PI * I;
    print_message("point source: sum E A = %.6g lm, flux %.6g lm (%.3f%%)\n", phi, expect,
                  100.0 * (phi - expect) / expect);
    assert_true(fabs(phi - expect) < 0.005 * expect);
    world_free(&w);

    /* area source facing down from the centre: flux = pi L A */
    world w2 = {0};
    float c[3] = {0, 0.5f, 0}, u[3] = {0.3f, 0, 0}, v[3] = {0, 0, 0.2f};
    w2.lights[w2.nl++] = area_light(c, u, v, 100.0f);
    b = gi_gltf_builder_new();
    black_box(b, 0.0f);
    world_make(&w2, b, "black_box_area", 2);
    phi = box_flux(&w2, 24, 64, &se);
    expect = GI_PI * 100.0 * (4.0 * 0.3 * 0.2);
    print_message("area source: sum E A = %.6g +- %.2g lm, flux %.6g lm (%.3f%%)\n", phi, se, expect,
                  100.0 * (phi - expect) / expect);
    assert_true(se < 0.01 * expect);
    assert_true(fabs(phi - expect) < fmax(4.0 * se, 0.005 * expect));
    world_free(&w2);
}

/* ---- 4. closed room of uniform reflectance ------------------------------ */
static void room_check(float rho, int spp)
{
    world w = {0};
    const float I = 10.0f;
    w.lights[w.nl++] = point_light(0.1f, 0.2f, -0.15f, I);
    gi_gltf_builder *b = gi_gltf_builder_new();
    black_box(b, rho);
    char name[64];
    snprintf(name, sizeof name, "room_%02d", (int)(rho * 100.0f + 0.5f));
    world_make(&w, b, name, 2);
    double se;
    double phi_in = box_flux(&w, 16, spp, &se); /* sum E A over all surfaces */
    double S = 24.0, Phi = 4.0 * GI_PI * I;
    double mean = phi_in / S, expect = Phi / (S * (1.0 - rho)), se_mean = se / S;
    double capped = 0.0; /* what a 3-bounce cap would give, to show the test would catch it */
    for (int k = 0; k <= 3; k++)
        capped += pow(rho, k);
    capped *= Phi / S;
    print_message("room rho %.2f: mean E = %.5g +- %.2g lux, exact %.5g (%.2f%%); a 3-bounce cap gives %.5g\n",
                  rho, mean, se_mean, expect, 100.0 * (mean - expect) / expect, capped);
    assert_true(4.0 * se_mean < 0.02 * expect);
    assert_true(fabs(mean - expect) < fmax(4.0 * se_mean, 0.005 * expect));
    world_free(&w);
}

static void test_room_rho50(void **state) { (void)state; room_check(0.5f, 64); }
static void test_room_rho90(void **state) { (void)state; room_check(0.9f, 128); }

/* ---- 5. furnace: emitting enclosure, radiance Le / (1 - rho) ------------ */
static void furnace_check(float rho)
{
    world w = {0};
    gi_gltf_builder *b = gi_gltf_builder_new();
    float base = base_for_albedo(rho);
    float col[3] = {base, base, base}, le[3] = {2.0f, 2.0f, 2.0f};
    int m = gi_gltf_add_material(b, "glow", col, 1.0f, 0.0f, le, 0);
    float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    gi_gltf_add_box(b, lo, hi, m, 1);
    world_make(&w, b, rho > 0.7f ? "furnace80" : "furnace50", 2);
    gi_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.position[0] = 0.3f;
    cam.forward[0] = 1.0f;
    cam.up[1] = 1.0f;
    cam.yfov = 1.2f;
    int W = 24, H = 16, spp = 64;
    float *img = malloc((size_t)W * H * 3 * sizeof *img);
    gi_pt_render_result res;
    gi_status st = {0};
    assert_int_equal(gi_pt_render(w.pt, &cam, W, H, spp, 0.0, img, &res, &st), 0);
    double sum = 0.0, sum2 = 0.0;
    for (int i = 0; i < W * H; i++) {
        double y = gi_luminance(gi_v3p(img + 3 * i));
        sum += y;
        sum2 += y * y;
    }
    double n = (double)W * H, mean = sum / n;
    double se = sqrt(fmax(0.0, sum2 / n - mean * mean) / n);
    double expect = 2.0 / (1.0 - rho);
    print_message("furnace rho %.2f: mean L = %.5g +- %.2g nits, exact %.5g (%.2f%%), %d spp\n", rho,
                  mean, se, expect, 100.0 * (mean - expect) / expect, res.spp);
    assert_int_equal(res.spp, spp);
    assert_int_equal((int)res.dropped, 0);
    assert_true(4.0 * se < 0.02 * expect);
    assert_true(fabs(mean - expect) < fmax(4.0 * se, 0.005 * expect));
    free(img);
    world_free(&w);
}

static void test_furnace(void **state)
{
    (void)state;
    furnace_check(0.5f);
    furnace_check(0.8f);
}

/* Thread count does not change the result. */
/* The pinhole camera both the path tracer and the relight shoot through:
 * the centre ray is the view direction, the top and side edges are half the
 * vertical field of view and its horizontal counterpart away, and the
 * relight's per-view basis (gi_camera_frame_ray) gives exactly the rays of
 * gi_camera_ray, so both tools see the same pixels. */
static void test_camera_rays(void **state)
{
    (void)state;
    gi_camera cam;
    memset(&cam, 0, sizeof cam);
    gi_vec3 f = gi_norm(gi_v3(0.3f, -0.2f, 0.9f)), up0 = gi_v3(0.1f, 1.0f, 0.05f);
    gi_vec3 r = gi_norm(gi_cross(f, up0)), up = gi_cross(r, f);
    gi_v3store(cam.forward, f);
    gi_v3store(cam.up, up);
    cam.position[0] = 1.5f;
    cam.position[1] = -2.0f;
    cam.position[2] = 0.25f;
    cam.yfov = 0.9f;
    const int w = 320, h = 200;
    gi_vec3 o, d;
    gi_camera_ray(&cam, w, h, 160.0f, 100.0f, &o, &d);
    assert_true(gi_len(gi_sub(d, f)) < 1e-6f);
    assert_true(o.x == 1.5f && o.y == -2.0f && o.z == 0.25f);
    gi_camera_ray(&cam, w, h, 160.0f, 0.0f, &o, &d); /* top edge: up by yfov / 2 */
    assert_true(fabsf(acosf(gi_dot(d, f)) - 0.45f) < 1e-5f);
    assert_true(gi_dot(d, up) > 0.0f);
    gi_camera_ray(&cam, w, h, 0.0f, 100.0f, &o, &d); /* left edge */
    float hx = atanf(tanf(0.45f) * (float)w / (float)h);
    assert_true(fabsf(acosf(fminf(1.0f, gi_dot(d, f))) - hx) < 1e-5f);
    assert_true(gi_dot(d, r) < 0.0f);
    gi_camera_frame cf;
    gi_camera_frame_init(&cf, &cam, w, h);
    uint64_t x = 12345;
    for (int i = 0; i < 1000; i++) {
        x = x * 6364136223846793005ull + 1442695040888963407ull;
        float px = (float)(x >> 40) / (float)(1u << 24) * (float)w;
        float py = (float)((x >> 16) & 0xffffff) / (float)(1u << 24) * (float)h;
        gi_vec3 o1, d1, o2, d2;
        gi_camera_ray(&cam, w, h, px, py, &o1, &d1);
        gi_camera_frame_ray(&cf, px, py, &o2, &d2);
        assert_memory_equal(&d1, &d2, sizeof d1);
        assert_memory_equal(&o1, &o2, sizeof o1);
        assert_true(fabsf(gi_len(d1) - 1.0f) < 1e-6f);
    }
}

/* ---- near-geometry query: what the near field's rays could hit --------- */
static void test_near_above(void **state)
{
    (void)state;
    world w = {0};
    w.lights[w.nl++] = point_light(0.0f, 2.0f, 0.0f, 1.0f);
    gi_gltf_builder *b = gi_gltf_builder_new();
    float grey[3] = {0.5f, 0.5f, 0.5f};
    int m = gi_gltf_add_material(b, "grey", grey, 1.0f, 0.0f, NULL, 0);
    big_plane(b, 2.0f, m); /* the floor, y = 0 */
    /* a wall x = 1, from the floor up to y = 1, z in [-1, 1] */
    float a0[3] = {1, 0, -1}, a1[3] = {1, 1, -1}, a2[3] = {1, 1, 1}, a3[3] = {1, 0, 1};
    gi_gltf_add_quad(b, a0, a1, a2, a3, m);
    /* a small slanted triangle hanging at y ~ 0.5 over (-1, -1) */
    float t0[3] = {-1.1f, 0.45f, -1.0f}, t1[3] = {-0.9f, 0.55f, -1.0f}, t2[3] = {-1.0f, 0.5f, -0.8f};
    gi_gltf_add_triangle(b, t0, t1, t2, m);
    world_make(&w, b, "near", 1);
    const gi_vec3 up = gi_v3(0, 1, 0), down = gi_v3(0, -1, 0);
    /* 1 mm above the floor, the floor itself 1 mm below the half-space: only
     * the wall, 0.5 m away, counts */
    gi_vec3 o = gi_v3(0.5f, 1e-3f, 0.0f);
    assert_int_equal(gi_rt_near_above(w.rt, o, up, 0.49f, -5e-4f), 0);
    assert_int_equal(gi_rt_near_above(w.rt, o, up, 0.51f, -5e-4f), 1);
    /* the floor counts once the half-space takes it in */
    assert_int_equal(gi_rt_near_above(w.rt, o, up, 0.1f, -2e-3f), 1);
    /* beyond the wall's top: the nearest point is its edge (1, 1, 0) */
    o = gi_v3(0.5f, 1.3f, 0.0f);
    float dtop = sqrtf(0.25f + 0.09f);
    assert_int_equal(gi_rt_near_above(w.rt, o, down, dtop - 1e-3f, 0.0f), 0);
    assert_int_equal(gi_rt_near_above(w.rt, o, down, dtop + 1e-3f, 0.0f), 1);
    /* facing up there, the wall lies below: nothing, however far */
    assert_int_equal(gi_rt_near_above(w.rt, o, up, 5.0f, 0.0f), 0);
    /* facing the floor from 0.3 m above it, away from the wall */
    o = gi_v3(-0.5f, 0.3f, 0.5f);
    assert_int_equal(gi_rt_near_above(w.rt, o, down, 0.29f, 0.0f), 0);
    assert_int_equal(gi_rt_near_above(w.rt, o, down, 0.31f, 0.0f), 1);
    /* the small triangle: 0.2 m under a point above its centre (its plane
     * tilts, so the distance is less than 0.2 but more than 0.19) */
    o = gi_v3(-1.0f, 0.7f, -0.9f);
    assert_int_equal(gi_rt_near_above(w.rt, o, down, 0.18f, 0.0f), 0);
    assert_int_equal(gi_rt_near_above(w.rt, o, down, 0.2f, 0.0f), 1);
    /* never a miss where rays find something: random points above the
     * floor, random normals, 64 rays each within r into the half-space */
    gi_rng rng;
    gi_rng_seed(&rng, 99, 0, 0);
    int zeros = 0, ones = 0;
    for (int i = 0; i < 3000; i++) {
        gi_vec3 p = gi_v3(-1.5f + 3.0f * gi_rng_float(&rng), 1e-3f + 1.2f * gi_rng_float(&rng),
                          -1.5f + 3.0f * gi_rng_float(&rng));
        gi_vec3 n = gi_sample_cosine(gi_v3(0, 1, 0), gi_rng_float(&rng), gi_rng_float(&rng));
        if (gi_rng_float(&rng) < 0.5f)
            n = gi_neg(n);
        float r = 0.05f + 0.5f * gi_rng_float(&rng);
        int near = gi_rt_near_above(w.rt, p, n, r, 0.0f);
        zeros += !near;
        ones += near;
        for (int k = 0; k < 64 && !near; k++) {
            gi_vec3 d = gi_sample_cosine(n, gi_rng_float(&rng), gi_rng_float(&rng));
            gi_hit hit;
            if (gi_dot(d, n) > 0.0f && gi_rt_intersect(w.rt, p, d, 0.0f, r, &hit))
                fail_msg("ray %d from (%g %g %g) hit at t=%g, query said nothing within %g", k, p.x, p.y,
                         p.z, hit.t, r);
        }
    }
    assert_true(zeros > 300 && ones > 300); /* both answers occur */
    world_free(&w);
}

/* A finely tessellated plane puts hundreds of triangles within reach, all
 * below the half-space: the query gives up ("unsure", 1) rather than look
 * at them all; the same plane as one quad answers 0. */
static void test_near_above_dense(void **state)
{
    (void)state;
    for (int dense = 0; dense < 2; dense++) {
        world w = {0};
        w.lights[w.nl++] = point_light(0.0f, 2.0f, 0.0f, 1.0f);
        gi_gltf_builder *b = gi_gltf_builder_new();
        float grey[3] = {0.5f, 0.5f, 0.5f};
        int m = gi_gltf_add_material(b, "grey", grey, 1.0f, 0.0f, NULL, 0);
        if (dense) {
            const int k = 40; /* 40 x 40 quads of 1 cm */
            for (int i = 0; i < k; i++)
                for (int j = 0; j < k; j++) {
                    float x0 = -0.2f + 0.01f * (float)i, z0 = -0.2f + 0.01f * (float)j;
                    float p0[3] = {x0, 0, z0}, p1[3] = {x0, 0, z0 + 0.01f}, p2[3] = {x0 + 0.01f, 0, z0 + 0.01f},
                          p3[3] = {x0 + 0.01f, 0, z0};
                    gi_gltf_add_quad(b, p0, p1, p2, p3, m);
                }
        } else {
            big_plane(b, 0.2f, m);
        }
        world_make(&w, b, dense ? "near_dense" : "near_coarse", 1);
        gi_vec3 o = gi_v3(0.003f, 1e-3f, 0.004f);
        assert_int_equal(gi_rt_near_above(w.rt, o, gi_v3(0, 1, 0), 0.1f, -5e-4f), dense);
        /* within reach of a few triangles only: decided either way */
        assert_int_equal(gi_rt_near_above(w.rt, o, gi_v3(0, 1, 0), 0.004f, -5e-4f), 0);
        world_free(&w);
    }
}

/* ---- closed meshes: no ray slips between triangles ----------------------
 * An icosphere (1280 triangles, every edge shared) around the origin: rays
 * from inside aimed exactly at its vertices, along its edges and at random
 * must all hit it, as intersection, as packets and as shadow rays to a point
 * outside. A ray through a shared edge or vertex that misses every triangle
 * there would let light leak (Embree without its robust mode: the scene
 * flag in gi_rt.c). */
static void ico_tri(gi_gltf_builder *b, const float *a, const float *c, const float *d, int depth, int m)
{
    if (depth == 0) {
        gi_gltf_add_triangle(b, a, c, d, m);
        return;
    }
    float ac[3], cd[3], da[3];
    for (int k = 0; k < 3; k++) {
        ac[k] = 0.5f * (a[k] + c[k]);
        cd[k] = 0.5f * (c[k] + d[k]);
        da[k] = 0.5f * (d[k] + a[k]);
    }
    float *mid[3] = {ac, cd, da};
    for (int i = 0; i < 3; i++) { /* onto the unit sphere: shared midpoints get the same floats */
        float l = sqrtf(mid[i][0] * mid[i][0] + mid[i][1] * mid[i][1] + mid[i][2] * mid[i][2]);
        for (int k = 0; k < 3; k++)
            mid[i][k] /= l;
    }
    ico_tri(b, a, ac, da, depth - 1, m);
    ico_tri(b, ac, c, cd, depth - 1, m);
    ico_tri(b, da, cd, d, depth - 1, m);
    ico_tri(b, ac, cd, da, depth - 1, m);
}

static void test_closed_mesh_no_escape(void **state)
{
    (void)state;
    world w = {0};
    w.lights[w.nl++] = point_light(0.0f, 5.0f, 0.0f, 1.0f);
    gi_gltf_builder *b = gi_gltf_builder_new();
    float grey[3] = {0.5f, 0.5f, 0.5f};
    int m = gi_gltf_add_material(b, "grey", grey, 1.0f, 0.0f, NULL, 0);
    const float t = 1.6180339887f, n0 = sqrtf(1.0f + t * t);
    float v[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                      {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (int i = 0; i < 12; i++)
        for (int k = 0; k < 3; k++)
            v[i][k] /= n0;
    static const int f[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                 {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int i = 0; i < 20; i++)
        ico_tri(b, v[f[i][0]], v[f[i][1]], v[f[i][2]], 3, m);
    world_make(&w, b, "ico", 1);
    assert_int_equal((int)w.s->num_triangles, 1280);
    gi_rng rng;
    gi_rng_seed(&rng, 5, 0, 0);
    enum { N = 16 };
    int rays = 0, missed = 0, unoccluded = 0, bykind[3] = {0, 0, 0};
    gi_vec3 ro[N], rd[N];
    float tmax[N];
    int q = 0;
    for (size_t tri = 0; tri < w.s->num_triangles; tri++) {
        const uint32_t *ix = w.s->indices + 3 * tri;
        gi_vec3 p[3];
        for (int i = 0; i < 3; i++)
            p[i] = gi_v3p(w.s->positions + 3 * (size_t)ix[i]);
        /* each vertex, points along each edge (the midpoint exactly), and a
         * random point inside, from origins near the centre */
        gi_vec3 aim[3 + 3 * 5 + 1];
        int na = 0;
        for (int i = 0; i < 3; i++) {
            aim[na++] = p[i];
            for (int j = 0; j < 5; j++) {
                float s2 = j == 0 ? 0.5f : gi_rng_float(&rng);
                aim[na++] = gi_add(p[i], gi_scale(gi_sub(p[(i + 1) % 3], p[i]), s2));
            }
        }
        float u = gi_rng_float(&rng), vv = gi_rng_float(&rng);
        if (u + vv > 1.0f)
            u = 1.0f - u, vv = 1.0f - vv;
        aim[na++] = gi_add(p[0], gi_add(gi_scale(gi_sub(p[1], p[0]), u), gi_scale(gi_sub(p[2], p[0]), vv)));
        for (int a = 0; a < na; a++) {
            gi_vec3 o = a % 2 ? gi_v3(0, 0, 0)
                              : gi_v3(0.3f * (gi_rng_float(&rng) - 0.5f), 0.3f * (gi_rng_float(&rng) - 0.5f),
                                      0.3f * (gi_rng_float(&rng) - 0.5f));
            gi_vec3 d = gi_norm(gi_sub(aim[a], o));
            gi_hit hit;
            rays++;
            int kind = a == na - 1 ? 2 : a % 6 == 0 ? 0 : 1; /* vertex, edge, inside */
            int mi = !gi_rt_intersect(w.rt, o, d, 0.0f, INFINITY, &hit);
            int un = !gi_rt_occluded(w.rt, o, d, 0.0f, 3.0f);
            missed += mi;
            unoccluded += un;
            bykind[kind] += mi + un;
            ro[q] = o;
            rd[q] = d;
            tmax[q++] = 3.0f;
            if (q == N) {
                gi_hit hh[N];
                uint8_t found[N], occ[N];
                gi_rt_intersect_n_upto(w.rt, q, ro, rd, tmax, hh, found);
                gi_rt_occluded_n(w.rt, q, ro, rd, tmax, occ);
                for (int k = 0; k < q; k++) {
                    missed += !found[k];
                    unoccluded += !occ[k];
                }
                q = 0;
            }
        }
    }
    assert_true(rays > 20000);
    /* Each ray went single and in a packet, as intersection and as shadow
     * ray: 4 rays traces. Embree's robust mode is not perfectly watertight
     * either (2026-12-06: 2 intersections missed and 2 shadow rays passed of
     * 2 x 24320 each, the single rays' at vertices); without it 2656 missed
     * and 3189 passed (926 of the single rays' at vertices, 1730 on edges) */
    gi_info("closed mesh: %d of %d intersections missed, %d of %d shadow rays passed (single rays: at vertices %d, "
            "on edges %d, inside %d)",
            missed, 2 * rays, unoccluded, 2 * rays, bykind[0], bykind[1], bykind[2]);
    if (missed + unoccluded > 4 * rays / 1000)
        fail_msg("%d of %d intersections with a closed mesh, aimed at its vertices and edges, missed it; %d of %d "
                 "shadow rays passed (more than 1 in 1000: is the Embree scene robust?)",
                 missed, 2 * rays, unoccluded, 2 * rays);
    world_free(&w);
}

static void test_thread_independence(void **state)
{
    (void)state;
    float *img[2];
    for (int t = 0; t < 2; t++) {
        world w = {0};
        w.lights[w.nl++] = point_light(0.1f, 0.5f, 0.0f, 5.0f);
        gi_gltf_builder *b = gi_gltf_builder_new();
        black_box(b, 0.6f);
        world_make(&w, b, t ? "thr2" : "thr1", t + 1);
        gi_camera cam;
        memset(&cam, 0, sizeof cam);
        cam.forward[2] = 1.0f;
        cam.up[1] = 1.0f;
        cam.yfov = 1.0f;
        img[t] = malloc(16 * 12 * 3 * sizeof(float));
        gi_status st = {0};
        gi_pt_render_result res;
        assert_int_equal(gi_pt_render(w.pt, &cam, 16, 12, 8, 0.0, img[t], &res, &st), 0);
        world_free(&w);
    }
    assert_memory_equal(img[0], img[1], 16 * 12 * 3 * sizeof(float));
    free(img[0]);
    free(img[1]);
}

static int setup(void **state)
{
    (void)state;
    gi_log_set_verbosity(-1);
    snprintf(g_dir, sizeof g_dir, "/tmp/gi_test_pt.XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_point_inverse_square),
        cmocka_unit_test(test_spot_directional),
        cmocka_unit_test(test_area_configuration_factor),
        cmocka_unit_test(test_area_form_analytic),
        cmocka_unit_test(test_emissive_configuration_factor),
        cmocka_unit_test(test_flux_conservation),
        cmocka_unit_test(test_room_rho50),
        cmocka_unit_test(test_room_rho90),
        cmocka_unit_test(test_furnace),
        cmocka_unit_test(test_camera_rays),
        cmocka_unit_test(test_near_above),
        cmocka_unit_test(test_near_above_dense),
        cmocka_unit_test(test_closed_mesh_no_escape),
        cmocka_unit_test(test_thread_independence),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
