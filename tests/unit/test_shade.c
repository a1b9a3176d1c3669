/* test_shade.c - the interpolation of gathering points' irradiance at a
 * surface point (gi_shade_irradiance_at): both modes keep a constant field,
 * the half-linear-fit weights follow a sloped field where the weighted mean
 * flattens it, and their weights stay bounded on a field of noise. */
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

#include "gi_gltf_write.h"
#include "gi_hvds.h"
#include "gi_log.h"
#include "gi_photon.h"
#include "gi_rng.h"
#include "gi_rt.h"
#include "gi_scene.h"
#include "gi_shade.h"

static char g_dir[256];

typedef struct fixture {
    gi_scene *s;
    gi_rt *rt;
    gi_gip *gip;
    gi_hvds *h;
    gi_shade *sh;
} fixture;

/* An 8 x 8 m floor at y = 0 facing up, with gathering points every ~0.3 m. */
static void floor_fixture(fixture *f)
{
    char path[512];
    snprintf(path, sizeof path, "%s/floor.gltf", g_dir);
    gi_gltf_builder *b = gi_gltf_builder_new();
    float grey[3] = {0.5f, 0.5f, 0.5f};
    int m = gi_gltf_add_material(b, "grey", grey, 1.0f, 0.0f, NULL, 0);
    float p0[3] = {-4, 0, 4}, p1[3] = {4, 0, 4}, p2[3] = {4, 0, -4}, p3[3] = {-4, 0, -4};
    gi_gltf_add_quad(b, p0, p1, p2, p3, m);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, path, &st), 0);
    gi_gltf_builder_free(b);
    assert_int_equal(gi_scene_load(path, &f->s, &st), 0);
    assert_int_equal(gi_rt_new(f->s, &f->rt, &st), 0);
    gi_gip_opts go;
    gi_gip_opts_default(&go);
    go.photons = 20000;
    assert_int_equal(gi_photon_precompute(f->s, f->rt, &go, 2, &f->gip, &st), 0);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 16;
    ho.r_max = 0.3f;
    if (gi_hvds_build(f->s, f->rt, f->gip, 1234, &ho, 2, &f->h, &st))
        fail_msg("hvds build: %s", st.msg);
    assert_true(f->h->num_gpoints > 300);
    assert_int_equal(gi_shade_new(f->s, f->rt, f->h, &f->sh, &st), 0);
}

static void fixture_free(fixture *f)
{
    gi_shade_free(f->sh);
    gi_hvds_free(f->h);
    gi_gip_free(f->gip);
    gi_rt_free(f->rt);
    gi_scene_free(f->s);
}

/* rms over 400 points of the floor's inner 6 x 6 m of (interpolated - truth)
 * / truth, with truth(x, z) = a + bx x + bz z per point and gpe filled from it */
static double field_error(const fixture *f, float *gpe, double a, double bx, double bz, int linear)
{
    for (uint32_t i = 0; i < f->h->num_gpoints; i++) {
        const float *q = f->h->gpoints[i].pos;
        for (int c = 0; c < 3; c++)
            gpe[3 * i + c] = (float)(a + bx * q[0] + bz * q[2]);
    }
    gi_rng r;
    gi_rng_seed(&r, 77, 0, 0);
    const float n[3] = {0, 1, 0};
    double sum = 0.0;
    for (int i = 0; i < 400; i++) {
        float p[3] = {6.0f * gi_rng_float(&r) - 3.0f, 0.0f, 6.0f * gi_rng_float(&r) - 3.0f};
        float e[3];
        gi_shade_irradiance_at(f->sh, gpe, p, n, linear, e);
        double t = a + bx * p[0] + bz * p[2], d = (e[0] - t) / t;
        sum += d * d;
    }
    return sqrt(sum / 400.0);
}

static void test_interpolation_modes(void **state)
{
    (void)state;
    fixture f = {0};
    floor_fixture(&f);
    float *gpe = malloc(3 * (size_t)f.h->num_gpoints * sizeof *gpe);
    assert_non_null(gpe);
    /* a constant field: both modes keep it (their weights sum to one) */
    double c_mean = field_error(&f, gpe, 50.0, 0.0, 0.0, 0), c_lin = field_error(&f, gpe, 50.0, 0.0, 0.0, 1);
    /* a slope of 12% of the mean per metre, about 4% across a point's radius */
    double s_mean = field_error(&f, gpe, 50.0, 6.0, -3.0, 0), s_lin = field_error(&f, gpe, 50.0, 6.0, -3.0, 1);
    print_message("constant field: rms %.2g (mean), %.2g (linear); sloped field: %.4f (mean), %.4f (linear)\n",
                  c_mean, c_lin, s_mean, s_lin);
    assert_true(c_mean < 1e-5);
    assert_true(c_lin < 1e-5);
    assert_true(s_mean > 1e-3); /* the mean leaves an error the fit must remove */
    assert_true(s_lin < 0.8 * s_mean); /* half the weights are the fit's */
    /* a field of noise in [0, 100]: the fit's weights have an absolute sum of
     * at most 1.5, half of them the mean's, so no value leaves [-25, 125];
     * after the clamp, [0, 125] */
    gi_rng r;
    gi_rng_seed(&r, 5, 0, 0);
    for (uint32_t i = 0; i < 3 * f.h->num_gpoints; i++)
        gpe[i] = 100.0f * gi_rng_float(&r);
    const float n[3] = {0, 1, 0};
    float lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < 2000; i++) {
        float p[3] = {7.8f * gi_rng_float(&r) - 3.9f, 0.0f, 7.8f * gi_rng_float(&r) - 3.9f};
        float e[3];
        gi_shade_irradiance_at(f.sh, gpe, p, n, 1, e);
        for (int c = 0; c < 3; c++) {
            lo = fminf(lo, e[c]);
            hi = fmaxf(hi, e[c]);
        }
    }
    print_message("noise field in [0, 100]: the linear fit gave [%.2f, %.2f]\n", lo, hi);
    assert_true(lo >= 0.0f);
    assert_true(hi <= 125.0f + 1e-3f);
    assert_true(hi > 100.0f || lo < 1.0f || hi - lo > 50.0f); /* it did interpolate noise */
    free(gpe);
    fixture_free(&f);
}

static int setup(void **state)
{
    (void)state;
    gi_log_set_verbosity(-1);
    snprintf(g_dir, sizeof g_dir, "/tmp/gi_test_shade.XXXXXX");
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
        cmocka_unit_test(test_interpolation_modes),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
