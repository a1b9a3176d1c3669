/* test_hvds.c - the HVDS against light leaking (two rooms sharing a 1 cm
 * wall), the occlusion error of coarse levels (paper §9, Fig. 12), the
 * accuracy of gathering-point irradiance against the path tracer, and
 * reproducible bytes for any thread count. */
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
#include "gi_math.h"
#include "gi_photon.h"
#include "gi_pt.h"
#include "gi_relight.h"
#include "gi_rt.h"
#include "gi_scene.h"

static char g_dir[256];

typedef struct pipe {
    gi_scene *s;
    gi_rt *rt;
    gi_gip *gip;
    gi_hvds *h;
    gi_relight *rl;
} pipe;

static void pipe_scene(pipe *p, gi_gltf_builder *b, const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s.gltf", g_dir, name);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, path, &st), 0);
    gi_gltf_builder_free(b);
    assert_int_equal(gi_scene_load(path, &p->s, &st), 0);
    assert_int_equal(gi_rt_new(p->s, &p->rt, &st), 0);
}

static void pipe_build(pipe *p, uint64_t photons, const gi_hvds_opts *ho, int threads)
{
    gi_status st = {0};
    gi_gip_opts go;
    gi_gip_opts_default(&go);
    go.photons = photons;
    if (!p->gip)
        assert_int_equal(gi_photon_precompute(p->s, p->rt, &go, 2, &p->gip, &st), 0);
    if (gi_hvds_build(p->s, p->rt, p->gip, 1234, ho, threads, &p->h, &st))
        fail_msg("hvds build: %s", st.msg);
}

static void pipe_light(pipe *p, const gi_light *l, size_t n)
{
    gi_status st = {0};
    gi_relight_free(p->rl);
    p->rl = NULL;
    assert_int_equal(gi_relight_new(p->s, p->rt, p->gip, p->h, 2, 1, &p->rl, &st), 0);
    assert_int_equal(gi_relight_set_materials(p->rl, p->s->materials, NULL, &st), 0);
    assert_int_equal(gi_relight_set_lights(p->rl, l, n, 4, &st), 0);
}

static void pipe_free_hvds(pipe *p)
{
    gi_relight_free(p->rl);
    p->rl = NULL;
    gi_hvds_free(p->h);
    p->h = NULL;
}

static void pipe_free(pipe *p)
{
    pipe_free_hvds(p);
    gi_gip_free(p->gip);
    gi_rt_free(p->rt);
    gi_scene_free(p->s);
}

static gi_light point(float x, float y, float z, float cd)
{
    gi_light l;
    memset(&l, 0, sizeof l);
    strcpy(l.name, "key");
    l.type = GI_LIGHT_POINT;
    l.enabled = 1;
    l.color[0] = l.color[1] = l.color[2] = 1.0f;
    l.intensity = cd;
    l.position[0] = x;
    l.position[1] = y;
    l.position[2] = z;
    return l;
}

/* Two rooms [0,1] and [1.01,2.01] along x sharing a 1 cm wall; one floor
 * quad runs under both (the hard case: the same plane on both sides). */
static gi_gltf_builder *two_rooms(void)
{
    gi_gltf_builder *b = gi_gltf_builder_new();
    float white[3] = {0.7f, 0.7f, 0.7f};
    int m = gi_gltf_add_material(b, "white", white, 1.0f, 0.0f, NULL, 0);
    float lo[3] = {0, 0, 0}, hi[3] = {2.01f, 1, 1};
    gi_gltf_add_box(b, lo, hi, m, 1);
    float wlo[3] = {1.0f, 0, 0}, whi[3] = {1.01f, 1, 1};
    gi_gltf_add_box(b, wlo, whi, m, 0);
    return b;
}

static void test_thin_wall_no_leak(void **state)
{
    (void)state;
    pipe p = {0};
    pipe_scene(&p, two_rooms(), "two_rooms");
    gi_light l = point(0.5f, 0.7f, 0.5f, 10.0f);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 64;
    pipe_build(&p, 200000, &ho, 2);
    pipe_light(&p, &l, 1);
    const float *e = gi_relight_gpoint_irradiance(p.rl);
    double lit = 0.0, dark = 0.0;
    uint32_t nlit = 0, ndark = 0;
    for (uint32_t i = 0; i < p.h->num_gpoints; i++) {
        const gi_gpoint *g = &p.h->gpoints[i];
        double y = gi_luminance(gi_v3p(e + 3 * i));
        if (g->pos[0] > 1.011f) {
            dark = fmax(dark, y);
            ndark++;
        } else if (g->pos[0] < 0.999f) {
            lit += y;
            nlit++;
        }
    }
    print_message("thin wall: %u points in the lit room (mean indirect %.4g lux), %u in the dark room "
                  "(max %.4g lux)\n", nlit, lit / nlit, ndark, dark);
    assert_true(nlit > 50 && ndark > 50);
    assert_true(lit / nlit > 0.1);
    assert_true(dark == 0.0);
    pipe_free_hvds(&p);

    /* the same HVDS without the leak and occlusion checks does leak: the test can fail */
    ho.leak_check = 0;
    ho.occlusion_check = 0;
    ho.cell_photons = 400.0f;
    pipe_build(&p, 0, &ho, 2);
    pipe_light(&p, &l, 1);
    e = gi_relight_gpoint_irradiance(p.rl);
    dark = 0.0;
    for (uint32_t i = 0; i < p.h->num_gpoints; i++)
        if (p.h->gpoints[i].pos[0] > 1.011f)
            dark = fmax(dark, gi_luminance(gi_v3p(e + 3 * i)));
    print_message("thin wall without the checks: max %.4g lux in the dark room\n", dark);
    assert_true(dark > 0.0);
    pipe_free(&p);
}

/* Reference indirect irradiance at points: total minus direct, path traced. */
static void reference_indirect(pipe *p, const gi_light *l, size_t nl, const float *pts, size_t n, int spp,
                               double *ind, double *se)
{
    gi_pt_opts o;
    gi_pt_opts_default(&o);
    o.progress = 0;
    o.seed = 99;
    gi_pt *pt = NULL;
    gi_status st = {0};
    assert_int_equal(gi_pt_new(p->rt, l, nl, p->s->materials, p->s->num_materials, &o, &pt, &st), 0);
    double *tot = malloc(n * sizeof *tot), *tse = malloc(n * sizeof *tse), *dir = malloc(n * sizeof *dir),
           *dse = malloc(n * sizeof *dse);
    assert_int_equal(gi_pt_sensors(pt, pts, n, spp, tot, tse, &st), 0);
    gi_pt_free(pt);
    o.max_bounces = 0;
    assert_int_equal(gi_pt_new(p->rt, l, nl, p->s->materials, p->s->num_materials, &o, &pt, &st), 0);
    assert_int_equal(gi_pt_sensors(pt, pts, n, 4, dir, dse, &st), 0);
    gi_pt_free(pt);
    for (size_t i = 0; i < n; i++) {
        ind[i] = tot[i] - dir[i];
        se[i] = sqrt(tse[i] * tse[i] + dse[i] * dse[i]);
    }
    free(tot);
    free(tse);
    free(dir);
    free(dse);
}

/* Relative rms error of the gathering points' indirect irradiance (luminance)
 * against the reference, over points selected by `sel` (NULL: all), at most 96. */
static double gpoint_error(pipe *p, const gi_light *l, size_t nl, int (*sel)(const gi_gpoint *), int spp,
                           size_t *count)
{
    const float *e = gi_relight_gpoint_irradiance(p->rl);
    size_t n = 0, cap = 96;
    float *pts = malloc(cap * 6 * sizeof *pts);
    uint32_t *idx = malloc(cap * sizeof *idx);
    uint32_t step = p->h->num_gpoints / 400 + 1;
    for (uint32_t i = 0; i < p->h->num_gpoints && n < cap; i += (sel ? 1 : step)) {
        const gi_gpoint *g = &p->h->gpoints[i];
        if (sel && !sel(g))
            continue;
        memcpy(pts + 6 * n, g->pos, 3 * sizeof(float));
        memcpy(pts + 6 * n + 3, g->nrm, 3 * sizeof(float));
        idx[n++] = i;
    }
    double *ref = malloc((n + 1) * sizeof *ref), *se = malloc((n + 1) * sizeof *se);
    reference_indirect(p, l, nl, pts, n, spp, ref, se);
    double num = 0.0, den = 0.0;
    for (size_t k = 0; k < n; k++) {
        double y = gi_luminance(gi_v3p(e + 3 * idx[k]));
        num += (y - ref[k]) * (y - ref[k]);
        den += ref[k] * ref[k];
    }
    free(pts);
    free(idx);
    free(ref);
    free(se);
    *count = n;
    return den > 0.0 ? sqrt(num / den) : 0.0;
}

/* A shelf over the floor: from the ceiling, a coarse cell holds the lit shelf
 * top and the shadowed floor under it (same normal), which it must not mix. */
static int above_shelf(const gi_gpoint *g)
{
    return g->pos[1] > 1.9f && g->nrm[1] < -0.9f;
}

/* A grey room [0, size]^3 seen from inside, with a shelf box [slo, shi] in it
 * (the material double-sided or not). */
static gi_gltf_builder *box_with_shelf(float size, const float slo[3], const float shi[3], float grey,
                                       int double_sided)
{
    gi_gltf_builder *b = gi_gltf_builder_new();
    float c[3] = {grey, grey, grey};
    int m = gi_gltf_add_material(b, "white", c, 1.0f, 0.0f, NULL, double_sided);
    float lo[3] = {0, 0, 0}, hi[3] = {size, size, size};
    gi_gltf_add_box(b, lo, hi, m, 1);
    gi_gltf_add_box(b, slo, shi, m, 0);
    return b;
}

static const uint8_t *g_held;
static const gi_gpoint *g_held_base;
static int held_point(const gi_gpoint *g) { return g_held[g - g_held_base]; }

/* The lift cap (gi_relight_set_lift_cap): at every gathering point the later
 * bounces its lifted rays read are, per ray, at most the cap times the mean
 * of its other rays' later bounces (recomputed here from the keys' fluxes);
 * some point is held (so the test sees the cap act); the irradiance drops
 * by what was held back and by nothing else; and the held points are nearer
 * the path tracer for it. The scene: a box lit from above with a
 * shelf 3 cm under its ceiling, whose narrow gap and sparse photons make
 * gi-hvds lift many rays to keys that also hold the lit walls. */
static void test_lift_cap(void **state)
{
    (void)state;
    pipe p = {0};
    const float slo[3] = {0.0f, 0.95f, 0.0f}, shi[3] = {0.6f, 0.97f, 1.0f};
    pipe_scene(&p, box_with_shelf(1.0f, slo, shi, 0.73f, 1), "lift_cap");
    gi_light l = point(0.8f, 0.6f, 0.5f, 2.0f);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 256;
    ho.r_max = 0.05f;
    ho.r_min = 0.01f;
    pipe_build(&p, 40000, &ho, 2);
    const gi_hvds *h = p.h;
    assert_non_null(h->split_first); /* split rays: the default --entry-keys */
    const uint32_t n = h->num_gpoints;
    pipe_light(&p, &l, 1);
    gi_relight_set_lift_cap(p.rl, 0.0f);
    float *e0 = malloc(3 * (size_t)n * sizeof *e0), *lf0 = malloc(3 * (size_t)n * sizeof *lf0);
    assert_non_null(e0);
    assert_non_null(lf0);
    memcpy(e0, gi_relight_gpoint_irradiance(p.rl), 3 * (size_t)n * sizeof *e0);
    for (uint32_t i = 0; i < n; i++)
        gi_relight_gpoint_lifted(p.rl, i, lf0 + 3 * (size_t)i, NULL);
    gi_status st = {0};
    gi_relight_set_lift_cap(p.rl, 1.5f);
    assert_int_equal(gi_relight_set_lights(p.rl, &l, 1, 4, &st), 0);
    const float *e1 = gi_relight_gpoint_irradiance(p.rl);
    const float *kf = gi_relight_key_flux(p.rl), *kf0 = gi_relight_key_flux0(p.rl);
    assert_non_null(kf0);
    const double w = GI_PI / (double)(h->num_rays / h->num_gpoints);
    size_t held = 0, lifted_pts = 0;
    uint8_t *flag = calloc(n + 1, 1);
    assert_non_null(flag);
    for (uint32_t i = 0; i < n; i++) {
        const gi_gpoint *g = &h->gpoints[i];
        double later = 0.0;
        uint32_t nreg = 0, nl = 0;
        for (uint32_t j = g->first_pair; j < g->first_pair + g->num_pairs; j++) {
            uint32_t k = h->pair_key[j];
            double lk = 0.0;
            for (int c = 0; c < 3; c++)
                lk += (c == 0 ? 0.2126 : c == 1 ? 0.7152 : 0.0722) * fmax((double)kf[3 * (size_t)k + c] - kf0[3 * (size_t)k + c], 0.0);
            later += lk * h->key_scale[k] * w * h->pair_count[j];
            nreg += h->pair_count[j];
        }
        uint32_t j1 = h->split_first[i] + h->split_n0[i];
        for (uint32_t j = j1; j < j1 + h->split_n1[i]; j++)
            nl += h->split_count[j];
        float lf[3];
        gi_relight_gpoint_lifted(p.rl, i, lf, NULL);
        double l1 = gi_luminance(gi_v3p(lf)), raw = gi_luminance(gi_v3p(lf0 + 3 * (size_t)i));
        lifted_pts += nl > 0;
        if (nreg >= 64 && nl) {
            double bound = 1.5 * later / nreg * nl;
            assert_true(l1 <= bound * (1.0 + 1e-3) + 1e-9);
            flag[i] = raw > bound * 1.001;
            held += flag[i];
        } else {
            assert_true(fabs(l1 - raw) <= 1e-4 * raw + 1e-9); /* too few other rays: left alone */
        }
        for (int c = 0; c < 3; c++) /* it loses what was held back, and nothing else */
            assert_true(fabs((e0[3 * (size_t)i + c] - e1[3 * (size_t)i + c]) - (lf0[3 * (size_t)i + c] - lf[c])) <=
                        1e-3 * e0[3 * (size_t)i + c] + 1e-6);
    }
    /* the held points against the path tracer, with the cap and without */
    size_t m0, m1;
    g_held = flag;
    g_held_base = h->gpoints;
    double err1 = gpoint_error(&p, &l, 1, held_point, 1024, &m1);
    gi_relight_set_lift_cap(p.rl, 0.0f);
    assert_int_equal(gi_relight_set_lights(p.rl, &l, 1, 4, &st), 0);
    double err0 = gpoint_error(&p, &l, 1, held_point, 1024, &m0);
    print_message("lift cap: %u points, %zu with lifted rays, %zu held; at %zu of those, error against 1024 spp "
                  "%.2f%% without the cap, %.2f%% with it (relative rms)\n", n, lifted_pts, held, m1, 100 * err0,
                  100 * err1);
    assert_true(held > 0);
    assert_int_equal(m0, m1);
    assert_true(err1 < err0);
    free(flag);
    free(e0);
    free(lf0);
    pipe_free(&p);
}

/* Step 4 on demand: after a light move, the points asked for hold the new
 * light's irradiance, exactly as a full gather gives it, and only they do
 * until the rest are asked for. */
static void test_gather_on_demand(void **state)
{
    (void)state;
    pipe p = {0};
    pipe_scene(&p, two_rooms(), "two_rooms_lazy");
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 64;
    pipe_build(&p, 100000, &ho, 2);
    gi_light a = point(0.5f, 0.7f, 0.5f, 10.0f), b = point(1.5f, 0.5f, 0.3f, 20.0f);
    const uint32_t n = p.h->num_gpoints;
    float *full_b = malloc(3 * (size_t)n * sizeof *full_b), *ea = malloc(3 * (size_t)n * sizeof *ea);
    uint32_t *idx = malloc(((size_t)n / 3 + 1) * sizeof *idx);
    assert_non_null(full_b);
    assert_non_null(ea);
    assert_non_null(idx);
    pipe_light(&p, &b, 1);
    memcpy(full_b, gi_relight_gpoint_irradiance(p.rl), 3 * (size_t)n * sizeof *full_b);
    pipe_light(&p, &a, 1);
    memcpy(ea, gi_relight_gpoint_irradiance(p.rl), 3 * (size_t)n * sizeof *ea);
    gi_status st = {0};
    assert_int_equal(gi_relight_set_lights(p.rl, &b, 1, 4, &st), 0);
    size_t k = 0;
    for (uint32_t i = 0; i < n; i += 3)
        idx[k++] = i;
    gi_relight_gather(p.rl, idx, k);
    gi_relight_gather(p.rl, idx, k); /* asked twice: gathered once, the same values */
    const float *e = gi_relight_gpoint_irradiance_lazy(p.rl);
    size_t differ_a = 0, differ_b = 0, stale = 0;
    for (uint32_t i = 0; i < n; i++) {
        int asked = i % 3 == 0;
        int eq_b = !memcmp(e + 3 * (size_t)i, full_b + 3 * (size_t)i, 3 * sizeof *e);
        int eq_a = !memcmp(e + 3 * (size_t)i, ea + 3 * (size_t)i, 3 * sizeof *e);
        if (asked && !eq_b)
            differ_b++;
        if (!asked && !eq_a)
            differ_a++;
        if (!asked && !eq_b)
            stale++;
    }
    print_message("gather on demand: %u points, %zu asked for; %zu of the rest still hold the old light's\n", n, k,
                  stale);
    assert_int_equal(differ_b, 0);
    assert_int_equal(differ_a, 0);
    assert_true(stale > 0); /* the lights differ, so the test sees a point left alone */
    e = gi_relight_gpoint_irradiance(p.rl); /* all of them now */
    assert_memory_equal(e, full_b, 3 * (size_t)n * sizeof *e);
    free(full_b);
    free(ea);
    free(idx);
    pipe_free(&p);
}

/* gi_relight_keys_at: the key a glossy ray reads is that of the nearest photon
 * within the grid's reach whose normal is within 45 degrees (or an ancestor
 * of its key), found by brute force; batches give what single lookups give. */
static void test_keys_at_nearest(void **state)
{
    (void)state;
    pipe p = {0};
    pipe_scene(&p, two_rooms(), "two_rooms_keys");
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 16;
    pipe_build(&p, 20000, &ho, 2);
    gi_light a = point(0.5f, 0.7f, 0.5f, 10.0f);
    pipe_light(&p, &a, 1);
    gi_status st = {0};
    assert_int_equal(gi_relight_prepare_keys(p.rl, &st), 0);
    const float c = gi_relight_key_cell(p.rl);
    assert_true(c > 0.0f);
    const uint64_t P = p.gip->num_photons;
    float *pp = malloc(3 * P * sizeof *pp), *pn = malloc(3 * P * sizeof *pn);
    assert_non_null(pp);
    assert_non_null(pn);
    for (uint64_t i = 0; i < P; i++)
        gi_gip_vertex(p.gip, p.s, i, pp + 3 * i, pn + 3 * i);
    enum { NQ = 500 };
    float q[3 * NQ], qn[3 * NQ];
    uint32_t got[NQ];
    uint64_t rs = 0x9e3779b97f4a7c15ull;
    for (int i = 0; i < NQ; i++) {
        /* near a photon (within a cell, so that some searches cross cells),
         * with its normal tilted; every 7th far from the geometry */
        rs = rs * 6364136223846793005ull + 1442695040888963407ull;
        uint64_t k = (rs >> 33) % P;
        for (int a2 = 0; a2 < 3; a2++) {
            rs = rs * 6364136223846793005ull + 1442695040888963407ull;
            float u = (float)((rs >> 40) & 0xFFFF) / 65535.0f - 0.5f;
            q[3 * i + a2] = pp[3 * k + a2] + u * c * (i % 7 ? 1.0f : 40.0f);
            qn[3 * i + a2] = pn[3 * k + a2] + 0.3f * u;
        }
        float l = sqrtf(qn[3 * i] * qn[3 * i] + qn[3 * i + 1] * qn[3 * i + 1] + qn[3 * i + 2] * qn[3 * i + 2]);
        for (int a2 = 0; a2 < 3; a2++)
            qn[3 * i + a2] /= l;
    }
    gi_relight_keys_at(p.rl, NQ, q, qn, got);
    int found = 0, none = 0;
    for (int i = 0; i < NQ; i++) {
        assert_int_equal(gi_relight_key_at(p.rl, q + 3 * i, qn + 3 * i), got[i]);
        uint64_t best = UINT64_MAX;
        float bd = c * c;
        for (uint64_t j = 0; j < P; j++) {
            const float *x = pp + 3 * j, *n = pn + 3 * j;
            if (n[0] * qn[3 * i] + n[1] * qn[3 * i + 1] + n[2] * qn[3 * i + 2] < 0.7071f)
                continue;
            float d = (x[0] - q[3 * i]) * (x[0] - q[3 * i]) + (x[1] - q[3 * i + 1]) * (x[1] - q[3 * i + 1]) +
                      (x[2] - q[3 * i + 2]) * (x[2] - q[3 * i + 2]);
            if (d < bd) {
                bd = d;
                best = j;
            }
        }
        if (best == UINT64_MAX || p.h->photon_key[best] == GI_HVDS_NO_KEY) {
            assert_int_equal(got[i], GI_HVDS_NO_KEY);
            none++;
            continue;
        }
        uint32_t k = p.h->photon_key[best];
        while (k != got[i] && p.h->key_parent[k] != GI_HVDS_NO_KEY)
            k = p.h->key_parent[k];
        if (k != got[i])
            fail_msg("query %d: key %u is not the nearest photon's (%llu, key %u) nor an ancestor of it", i, got[i],
                     (unsigned long long)best, p.h->photon_key[best]);
        found++;
    }
    print_message("keys_at: %d of %d queries found their nearest photon's key, %d none\n", found, NQ, none);
    assert_true(found > NQ / 2);
    assert_true(none > 0);
    free(pp);
    free(pn);
    pipe_free(&p);
}

/* Indirect irradiance (luminance) at n wall samples (pos, normal) as the
 * relight interpolates it from the points on the back wall z = 1: weights
 * 1 - max(d / R, normal error) / 2, gi_shade's reach of 2 radii. */
static void wall_interp(const pipe *p, const float *pts, size_t n, double *out)
{
    const float *e = gi_relight_gpoint_irradiance(p->rl);
    const float inv_na = 1.0f / sqrtf(1.0f - cosf((float)(10.0 * GI_PI / 180.0)));
    for (size_t k = 0; k < n; k++) {
        const float *x = pts + 6 * k;
        double ws = 0.0, we = 0.0;
        for (uint32_t i = 0; i < p->h->num_gpoints; i++) {
            const gi_gpoint *g = &p->h->gpoints[i];
            float dn = g->nrm[0] * x[3] + g->nrm[1] * x[4] + g->nrm[2] * x[5];
            if (dn <= 0.0f)
                continue;
            double en = sqrt(fmax(0.0, 1.0 - dn)) * inv_na;
            double d = gi_len(gi_sub(gi_v3p(g->pos), gi_v3p(x)));
            double w = 1.0 - fmax(d / g->radius, en) / 2.0;
            if (w > 0.0) {
                ws += w;
                we += w * gi_luminance(gi_v3p(e + 3 * i));
            }
        }
        assert_true(ws > 0.0);
        out[k] = we / ws;
    }
}

/* Gathering points at the foot of a wall, where a lit floor's light falls off
 * with height: gi-hvds's rejection keeps a candidate unless a kept point lies
 * within the smaller of their two radii. A kept point's radius alone let
 * points a radius up the wall, which see less of the floor, cover its foot,
 * and samples there read too little (Sponza f3: sunlit column strips 15-40 cm
 * above a sunlit ledge read 13-22 cd/m2 of indirect light where the path
 * tracer finds 18-40). The interpolated indirect irradiance 1-8 cm above the
 * floor against the path tracer, with either rule on the same photons. */
static void test_wall_foot_points(void **state)
{
    (void)state;
    pipe p = {0};
    gi_gltf_builder *b = gi_gltf_builder_new();
    float grey[3] = {0.7f, 0.7f, 0.7f};
    int m = gi_gltf_add_material(b, "white", grey, 1.0f, 0.0f, NULL, 0);
    float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    gi_gltf_add_box(b, lo, hi, m, 1);
    pipe_scene(&p, b, "wall_foot");
    /* a lamp low over the floor in front of the back wall */
    gi_light l = point(0.5f, 0.25f, 0.75f, 1.0f);
    enum { NX = 12, NY = 8, N = NX * NY };
    float pts[6 * N];
    for (int iy = 0; iy < NY; iy++)
        for (int ix = 0; ix < NX; ix++) {
            float *x = pts + 6 * (iy * NX + ix);
            x[0] = 0.3f + 0.4f * ((float)ix + 0.5f) / NX;
            x[1] = 0.01f + 0.01f * (float)iy;
            x[2] = 0.999f;
            x[3] = x[4] = 0.0f;
            x[5] = -1.0f;
        }
    double ref[N], se[N], got[2][N];
    reference_indirect(&p, &l, 1, pts, N, 2048, ref, se);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 1024;
    ho.r_max = 0.2f;
    ho.r_min = 0.005f;
    uint32_t np[2];
    double err[2], bias[2];
    for (int v = 0; v < 2; v++) {
        ho.cover_min_radius = 1 - v;
        pipe_build(&p, v ? 0 : 400000, &ho, 2);
        pipe_light(&p, &l, 1);
        np[v] = p.h->num_gpoints;
        wall_interp(&p, pts, N, got[v]);
        double num = 0.0, den = 0.0, sg = 0.0, sr = 0.0;
        for (int k = 0; k < N; k++) {
            num += (got[v][k] - ref[k]) * (got[v][k] - ref[k]);
            den += ref[k] * ref[k];
            sg += got[v][k];
            sr += ref[k];
        }
        err[v] = sqrt(num / den);
        bias[v] = sg / sr - 1.0;
        pipe_free_hvds(&p);
    }
    double sem = 0.0, sr = 0.0;
    for (int k = 0; k < N; k++) {
        sem += se[k] * se[k];
        sr += ref[k] * ref[k];
    }
    print_message("wall foot, 1-8 cm up: interpolated indirect light against the path tracer (its noise %.3f): "
                  "relative rms %.3f, mean %+.3f with the smaller radius (%u points); %.3f, %+.3f with the kept "
                  "point's (%u points)\n", sqrt(sem / sr), err[0], bias[0], np[0], err[1], bias[1], np[1]);
    assert_true(err[0] < err[1]);
    assert_true(fabs(bias[0]) < fabs(bias[1]));
    pipe_free(&p);
}

static void test_coarse_level_occlusion(void **state)
{
    (void)state;
    pipe p = {0};
    const float slo[3] = {0.05f, 0.2f, 0.05f}, shi[3] = {1.95f, 0.22f, 1.95f};
    pipe_scene(&p, box_with_shelf(2.0f, slo, shi, 0.75f, 0), "shelf");
    gi_light l = point(1.0f, 1.0f, 1.0f, 20.0f);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 64;
    ho.cell_photons = 64.0f;
    ho.r_max = 0.1f;
    pipe_build(&p, 400000, &ho, 2);
    pipe_light(&p, &l, 1);
    size_t n1, n2;
    double err_on = gpoint_error(&p, &l, 1, above_shelf, 2048, &n1);
    uint64_t desc = p.h->rays_descended;
    pipe_free_hvds(&p);
    ho.occlusion_check = 0;
    pipe_build(&p, 0, &ho, 2);
    pipe_light(&p, &l, 1);
    double err_off = gpoint_error(&p, &l, 1, above_shelf, 2048, &n2);
    print_message("shelf: %llu rays descended; indirect error above the shelf %.2f%% with the occlusion "
                  "check, %.2f%% without (%zu points)\n", (unsigned long long)desc, 100 * err_on, 100 * err_off, n1);
    assert_true(n1 >= 8);
    assert_true(desc > 0);
    assert_true(err_on < err_off);
    pipe_free(&p);
}

static int same_bytes(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    assert_non_null(fa);
    assert_non_null(fb);
    int same = 1, ca, cb;
    do {
        ca = fgetc(fa);
        cb = fgetc(fb);
        same &= ca == cb;
    } while (ca != EOF && cb != EOF);
    fclose(fa);
    fclose(fb);
    return same;
}

static void test_cornell_like_accuracy_and_bytes(void **state)
{
    (void)state;
    pipe p = {0};
    gi_gltf_builder *b = gi_gltf_builder_new();
    float white[3] = {0.73f, 0.73f, 0.73f}, red[3] = {0.63f, 0.065f, 0.05f}, green[3] = {0.14f, 0.45f, 0.09f};
    int mw = gi_gltf_add_material(b, "white", white, 1.0f, 0.0f, NULL, 1);
    int mr = gi_gltf_add_material(b, "red", red, 1.0f, 0.0f, NULL, 1);
    int mg = gi_gltf_add_material(b, "green", green, 1.0f, 0.0f, NULL, 1);
    float A[3] = {0, 0, 0}, B[3] = {1, 0, 0}, C[3] = {1, 0, 1}, D[3] = {0, 0, 1};
    float E[3] = {0, 1, 0}, F[3] = {1, 1, 0}, G[3] = {1, 1, 1}, H[3] = {0, 1, 1};
    gi_gltf_add_quad(b, A, D, C, B, mw); /* floor */
    gi_gltf_add_quad(b, E, F, G, H, mw); /* ceiling */
    gi_gltf_add_quad(b, D, H, G, C, mw); /* back */
    gi_gltf_add_quad(b, A, E, H, D, mr); /* left */
    gi_gltf_add_quad(b, B, C, G, F, mg); /* right */
    float blo[3] = {0.2f, 0, 0.5f}, bhi[3] = {0.45f, 0.5f, 0.75f};
    gi_gltf_add_box(b, blo, bhi, mw, 0);
    pipe_scene(&p, b, "cornell_like");
    gi_light l = point(0.5f, 0.9f, 0.5f, 2.0f);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 144;
    ho.entry_keys = 2; /* split rays, to check GSPL below */
    pipe_build(&p, 300000, &ho, 1);
    assert_true(p.h->rays_retraced == 0); /* its hits fit the default budget */
    char p1[512], p2[512];
    snprintf(p1, sizeof p1, "%s/a.gih", g_dir);
    snprintf(p2, sizeof p2, "%s/b.gih", g_dir);
    gi_status st = {0};
    assert_int_equal(gi_hvds_write(p.h, p1, "scene", "gip", &st), 0);
    pipe_light(&p, &l, 1);
    size_t n;
    double err = gpoint_error(&p, &l, 1, NULL, 1024, &n);
    print_message("box: %u gathering points, %u keys, depth %u; indirect irradiance error at %zu points: "
                  "%.2f%% (relative rms)\n", p.h->num_gpoints, p.h->num_keys, p.h->depth, n, 100 * err);
    assert_true(err < 0.15);
    /* two threads: identical bytes */
    pipe_free_hvds(&p);
    pipe_build(&p, 0, &ho, 2);
    assert_int_equal(gi_hvds_write(p.h, p2, "scene", "gip", &st), 0);
    assert_true(same_bytes(p1, p2));
    /* the hits over a small budget, traced in chunks of 364 points and again
     * for the keys (gi_hvds_opts.hit_bytes): identical bytes */
    pipe_free_hvds(&p);
    gi_hvds_opts hc = ho;
    hc.hit_bytes = 1u << 20;
    pipe_build(&p, 0, &hc, 2);
    assert_true(p.h->rays_retraced == p.h->num_rays);
    assert_int_equal(gi_hvds_write(p.h, p2, "scene", "gip", &st), 0);
    assert_true(same_bytes(p1, p2));
    pipe_free_hvds(&p);
    pipe_build(&p, 0, &ho, 2);
    /* reading back: accepted with the right .gip fingerprint, refused with another */
    gi_hvds *h2 = NULL;
    assert_int_equal(gi_hvds_read(p1, p.s, 1234, p.gip->num_photons, &h2, &st), 0);
    assert_int_equal(h2->num_keys, p.h->num_keys);
    assert_int_equal(h2->num_pairs, p.h->num_pairs);
    /* GDIR: the pairs' mean ray directions survive the file, lie in their
     * point's hemisphere and are no longer than a unit vector */
    assert_non_null(p.h->pair_dir);
    assert_non_null(h2->pair_dir);
    assert_memory_equal(h2->pair_dir, p.h->pair_dir, 3 * (size_t)p.h->num_pairs);
    for (uint32_t i = 0; i < h2->num_gpoints; i++) {
        const gi_gpoint *g = &h2->gpoints[i];
        for (uint32_t j = g->first_pair; j < g->first_pair + g->num_pairs; j++) {
            const int8_t *d = h2->pair_dir + 3 * (size_t)j;
            float x = d[0] / 127.0f, y = d[1] / 127.0f, z = d[2] / 127.0f;
            assert_true(x * x + y * y + z * z <= 1.03f);
            assert_true(x * g->nrm[0] + y * g->nrm[1] + z * g->nrm[2] > -0.05f);
        }
    }
    /* GSPL: the split rays survive the file; each split ray is in both of
     * its point's lists once (first bounce, later bounces), and with the
     * other pairs no point has more rays than it traced */
    assert_non_null(p.h->split_key);
    assert_non_null(h2->split_key);
    assert_true(h2->num_split > 0);
    assert_int_equal(h2->num_split, p.h->num_split);
    assert_memory_equal(h2->split_key, p.h->split_key, h2->num_split * sizeof *h2->split_key);
    assert_memory_equal(h2->split_count, p.h->split_count, h2->num_split * sizeof *h2->split_count);
    for (uint32_t i = 0; i < h2->num_gpoints; i++) {
        const gi_gpoint *g = &h2->gpoints[i];
        uint64_t n0 = 0, n1 = 0, nm = 0;
        uint32_t j0 = h2->split_first[i], j1 = j0 + h2->split_n0[i], j2 = j1 + h2->split_n1[i];
        for (uint32_t j = j0; j < j1; j++)
            n0 += h2->split_count[j];
        for (uint32_t j = j1; j < j2; j++)
            n1 += h2->split_count[j];
        for (uint32_t j = g->first_pair; j < g->first_pair + g->num_pairs; j++)
            nm += h2->pair_count[j];
        assert_true(n0 == n1);
        assert_true(nm + n0 <= (uint64_t)(h2->num_rays / h2->num_gpoints));
    }
    gi_hvds_free(h2);
    assert_int_equal(gi_hvds_read(p1, p.s, 4321, p.gip->num_photons, &h2, &st), GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "gip"));
    pipe_free(&p);
}

/* Luminance of the later bounces' flux over the whole scene: the keys
 * without a parent, less their entry points' share. */
static double later_flux_total(const pipe *p)
{
    const float *kf = gi_relight_key_flux(p->rl), *kf0 = gi_relight_key_flux0(p->rl);
    double t = 0.0;
    for (uint32_t k = 0; k < p->h->num_keys; k++)
        if (p->h->key_parent[k] == GI_HVDS_NO_KEY)
            for (int c = 0; c < 3; c++)
                t += (c == 0 ? 0.2126 : c == 1 ? 0.7152 : 0.0722) * (kf[3 * (size_t)k + c] - kf0[3 * (size_t)k + c]);
    return t;
}

/* Fresh paths (gi_relight_set_fresh_paths) beside a lamp 4 cm from a wall,
 * where the .gip's later photons carry flux that spans orders of magnitude:
 * the fresh photons, about equal in flux, have the larger effective sample
 * size and take the larger weight; the later bounces keep their total flux
 * (two unbiased estimates of it, within 3%); the gathering points'
 * indirect irradiance stays within 12% of the path tracer (relative rms
 * at 96 points; the path tracer's own noise at 1024 spp is ~8% there, so
 * this guards against a bias, not a gain: docs/journal.md, "Session 43"); and one
 * thread gives the bytes two give. */
static void test_fresh_paths(void **state)
{
    (void)state;
    pipe p = {0};
    gi_gltf_builder *b = gi_gltf_builder_new();
    float white[3] = {0.73f, 0.73f, 0.73f}, red[3] = {0.63f, 0.065f, 0.05f};
    int mw = gi_gltf_add_material(b, "white", white, 1.0f, 0.0f, NULL, 1);
    int mr = gi_gltf_add_material(b, "red", red, 1.0f, 0.0f, NULL, 1);
    float A[3] = {0, 0, 0}, B[3] = {1, 0, 0}, C[3] = {1, 0, 1}, D[3] = {0, 0, 1};
    float E[3] = {0, 1, 0}, F[3] = {1, 1, 0}, G[3] = {1, 1, 1}, H[3] = {0, 1, 1};
    gi_gltf_add_quad(b, A, D, C, B, mw); /* floor */
    gi_gltf_add_quad(b, E, F, G, H, mw); /* ceiling */
    gi_gltf_add_quad(b, D, H, G, C, mw); /* back */
    gi_gltf_add_quad(b, A, E, H, D, mr); /* left, the lamp beside it */
    gi_gltf_add_quad(b, B, C, G, F, mw); /* right */
    pipe_scene(&p, b, "fresh_paths");
    gi_light l = point(0.04f, 0.5f, 0.5f, 0.5f);
    gi_hvds_opts ho;
    gi_hvds_opts_default(&ho);
    ho.gather_rays = 144;
    pipe_build(&p, 100000, &ho, 2);
    const uint32_t n = p.h->num_gpoints;
    pipe_light(&p, &l, 1);
    size_t n0, n1;
    double err0 = gpoint_error(&p, &l, 1, NULL, 1024, &n0), flux0 = later_flux_total(&p);
    gi_status st = {0};
    gi_relight_set_fresh_paths(p.rl, 20000);
    assert_int_equal(gi_relight_set_lights(p.rl, &l, 1, 4, &st), 0);
    double err1 = gpoint_error(&p, &l, 1, NULL, 1024, &n1), flux1 = later_flux_total(&p);
    float *e2 = malloc(3 * (size_t)n * sizeof *e2);
    assert_non_null(e2);
    memcpy(e2, gi_relight_gpoint_irradiance(p.rl), 3 * (size_t)n * sizeof *e2);
    gi_relight *r1 = NULL;
    assert_int_equal(gi_relight_new(p.s, p.rt, p.gip, p.h, 1, 1, &r1, &st), 0);
    gi_relight_set_fresh_paths(r1, 20000);
    assert_int_equal(gi_relight_set_materials(r1, p.s->materials, NULL, &st), 0);
    assert_int_equal(gi_relight_set_lights(r1, &l, 1, 4, &st), 0);
    const float *e1 = gi_relight_gpoint_irradiance(r1);
    double ess[2], alpha;
    size_t nf;
    gi_relight_fresh_stats(p.rl, ess, &alpha, &nf);
    print_message("fresh paths: effective sample sizes %.0f (.gip) and %.0f (20000 fresh paths, %zu photons), "
                  "weights %.3f and %.3f; indirect error at %zu points %.2f%% without, %.2f%% with; later flux "
                  "%.5g and %.5g\n", ess[0], ess[1], nf, alpha, 1.0 - alpha, n0, 100 * err0, 100 * err1, flux0,
                  flux1);
    assert_int_equal(n0, n1);
    assert_true(nf > 20000);
    assert_true(ess[1] > 2.0 * ess[0]);
    assert_true(alpha > 0.0 && alpha < 0.5);
    assert_true(err0 < 0.12);
    assert_true(err1 < 0.12);
    assert_true(fabs(flux1 - flux0) < 0.03 * flux0);
    assert_memory_equal(e1, e2, 3 * (size_t)n * sizeof *e1);
    /* auto: the pilot alone where it reaches the target with the .gip's,
     * else as many paths as its yield says reach it */
    gi_relight_set_fresh_auto(p.rl, 10000);
    assert_int_equal(gi_relight_set_lights(p.rl, &l, 1, 4, &st), 0);
    gi_relight_fresh_stats(p.rl, ess, &alpha, &nf);
    uint32_t used_lo = gi_relight_fresh_used(p.rl);
    double ess_lo = ess[0] + ess[1];
    gi_relight_set_fresh_auto(p.rl, 60000);
    assert_int_equal(gi_relight_set_lights(p.rl, &l, 1, 4, &st), 0);
    gi_relight_fresh_stats(p.rl, ess, &alpha, &nf);
    uint32_t used_hi = gi_relight_fresh_used(p.rl);
    double flux2 = later_flux_total(&p);
    print_message("fresh paths, auto: target 10000: %u paths, effective sample size %.0f; target 60000: %u paths, "
                  "%.0f (%.0f + %.0f); later flux %.5g\n", used_lo, ess_lo, used_hi, ess[0] + ess[1], ess[0], ess[1],
                  flux2);
    assert_int_equal(used_lo, GI_RELIGHT_FRESH_PILOT);
    assert_true(ess_lo >= 10000.0);
    assert_true(used_hi > GI_RELIGHT_FRESH_PILOT && used_hi < GI_RELIGHT_FRESH_MAX);
    assert_true(ess[0] + ess[1] > 0.85 * 60000.0 && ess[0] + ess[1] < 1.3 * 60000.0);
    assert_true(fabs(flux2 - flux0) < 0.03 * flux0);
    gi_relight_set_fresh_paths(p.rl, 0); /* a count ends auto */
    assert_int_equal(gi_relight_set_lights(p.rl, &l, 1, 4, &st), 0);
    assert_int_equal(gi_relight_fresh_used(p.rl), 0);
    gi_relight_free(r1);
    free(e2);
    pipe_free(&p);
}

static int setup(void **state)
{
    (void)state;
    gi_log_set_verbosity(-1);
    snprintf(g_dir, sizeof g_dir, "/tmp/gi_test_hvds.XXXXXX");
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
        cmocka_unit_test(test_thin_wall_no_leak),
        cmocka_unit_test(test_gather_on_demand),
        cmocka_unit_test(test_lift_cap),
        cmocka_unit_test(test_wall_foot_points),
        cmocka_unit_test(test_keys_at_nearest),
        cmocka_unit_test(test_coarse_level_occlusion),
        cmocka_unit_test(test_cornell_like_accuracy_and_bytes),
        cmocka_unit_test(test_fresh_paths),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
