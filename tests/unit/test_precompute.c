/* test_precompute.c - gi-precompute's algorithm (gi_photon.c) on generated
 * scenes: degenerate triangles, single- and double-sided surfaces, grazing
 * self-intersection at scales from millimetres to kilometres, open scenes,
 * the entry areas (flux conservation, with and without region refinement),
 * determinism across thread counts, the bounce cap, Russian roulette against
 * its expected path length, and the reflectance factors. */
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

#include "gi_brdf.h"
#include "gi_gip.h"
#include "gi_gltf_write.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_photon.h"
#include "gi_rt.h"
#include "gi_scene.h"

static char g_dir[256];

static void assert_has_at(const char *msg, const char *sub, const char *file, int line)
{
    if (!strstr(msg, sub)) {
        print_error("%s:%d: message \"%s\" lacks \"%s\"\n", file, line, msg, sub);
        _fail(file, line);
    }
}
#define assert_has(msg, sub) assert_has_at((msg), (sub), __FILE__, __LINE__)

/* A loaded scene with its ray tracer. */
typedef struct world {
    gi_scene *s;
    gi_rt *rt;
} world;

static void world_make(world *w, gi_gltf_builder *b, const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s.gltf", g_dir, name);
    gi_status st = {0};
    int rc = gi_gltf_builder_write(b, path, &st);
    if (rc)
        print_error("%s\n", st.msg);
    assert_int_equal(rc, 0);
    gi_gltf_builder_free(b);
    assert_int_equal(gi_scene_load(path, &w->s, &st), 0);
    assert_int_equal(gi_rt_new(w->s, &w->rt, &st), 0);
}

static void world_free(world *w)
{
    gi_rt_free(w->rt);
    gi_scene_free(w->s);
}

static gi_gip *run(const world *w, const gi_gip_opts *o, int threads)
{
    gi_status st = {0};
    gi_gip *g = NULL;
    int rc = gi_photon_precompute(w->s, w->rt, o, threads, &g, &st);
    if (rc)
        print_error("precompute: %s\n", st.msg);
    assert_int_equal(rc, 0);
    assert_non_null(g);
    return g;
}

static gi_gip_opts opts(uint64_t photons)
{
    gi_gip_opts o;
    gi_gip_opts_default(&o);
    o.photons = photons;
    o.seed = getenv("GI_TEST_SEED") ? strtoull(getenv("GI_TEST_SEED"), NULL, 10) : 3;
    return o;
}

static double sum_dA(const gi_gip *g)
{
    gi_ksum k = {0, 0};
    for (uint32_t e = 0; e < g->num_entries; e++)
        gi_ksum_add(&k, g->entry_dA[e]);
    return gi_ksum_get(&k);
}

static double mean_len(const gi_gip *g) { return (double)g->num_photons / g->num_entries; }

/* A closed room [0,sx]x[0,sy]x[0,sz] * scale + offset, walls facing inwards. */
static gi_gltf_builder *room(const float albedo[3], float roughness, float metallic, float scale,
                             float offset, int double_sided, const float size[3])
{
    gi_gltf_builder *b = gi_gltf_builder_new();
    int m = gi_gltf_add_material(b, "wall", albedo, roughness, metallic, NULL, double_sided);
    float lo[3] = {offset, offset, offset};
    float hi[3] = {offset + size[0] * scale, offset + size[1] * scale, offset + size[2] * scale};
    gi_gltf_add_box(b, lo, hi, m, 1);
    return b;
}

/* ---- hard cases --------------------------------------------------------------- */

static void test_degenerate(void **state)
{
    (void)state;
    gi_gltf_builder *b = gi_gltf_builder_new();
    float c[3] = {0.5f, 0.5f, 0.5f};
    int m = gi_gltf_add_material(b, "m", c, 1.0f, 0.0f, NULL, 0);
    float q0[3] = {0, 0, 0}, q1[3] = {1, 0, 0}, q2[3] = {1, 0, -1}, q3[3] = {0, 0, -1};
    gi_gltf_add_quad(b, q0, q1, q2, q3, m);
    float z0[3] = {0, 0, 0}, z1[3] = {0.5f, 0, 0}, z2[3] = {1, 0, 0}; /* collinear: zero area */
    gi_gltf_add_triangle(b, z0, z1, z2, m);
    float s0[3] = {0, 0.5f, 0}, s1[3] = {1, 0.5f, 0}, s2[3] = {0.5f, 0.5f + 1e-8f, 0}; /* sliver */
    gi_gltf_add_triangle(b, s0, s1, s2, m);
    float t0[3] = {0, 1, 0}, t1[3] = {1e-3f, 1, 0}, t2[3] = {0, 1 + 1e-3f, 0}; /* small but fine */
    gi_gltf_add_triangle(b, t0, t1, t2, m);
    world w;
    world_make(&w, b, "degenerate");
    int skipped = 0;
    for (size_t t = 0; t < w.s->num_triangles; t++)
        skipped += gi_photon_skip_triangle(w.s, t);
    assert_int_equal(skipped, 2);
    gi_gip_opts o = opts(20000);
    gi_gip *g = run(&w, &o, 2);
    assert_int_equal(g->skipped_degenerate, 2);
    for (uint32_t e = 0; e < g->num_entries; e++)
        assert_false(gi_photon_skip_triangle(w.s, g->tri[g->path_start[e]]));
    /* uniform set: dA = A / N exactly, and they sum to the usable area */
    double area = 1.0 + 0.5e-6;
    for (uint32_t e = 0; e < g->num_entries; e++)
        assert_true(g->entry_dA[e] == g->entry_dA[0]);
    assert_true(fabs((double)g->entry_dA[0] * g->num_entries - area) < 1e-6 * area);
    assert_true(fabs(sum_dA(g) - area) < 1e-5 * area);
    gi_gip_free(g);
    world_free(&w);
}

static void test_empty_scene(void **state)
{
    (void)state;
    gi_gltf_builder *b = gi_gltf_builder_new();
    float c[3] = {0.5f, 0.5f, 0.5f};
    int m = gi_gltf_add_material(b, "m", c, 1.0f, 0.0f, NULL, 0);
    float z0[3] = {0, 0, 0}, z1[3] = {0.5f, 0, 0}, z2[3] = {1, 0, 0};
    gi_gltf_add_triangle(b, z0, z1, z2, m);
    world w;
    world_make(&w, b, "empty");
    gi_gip_opts o = opts(1000);
    gi_status st = {0};
    gi_gip *g = NULL;
    assert_int_equal(gi_photon_precompute(w.s, w.rt, &o, 1, &g, &st), GI_EXIT_DATA);
    assert_null(g);
    assert_has(st.msg, "no surface");
    world_free(&w);
}

static void test_sides(void **state)
{
    (void)state;
    for (int ds = 0; ds < 2; ds++) {
        gi_gltf_builder *b = gi_gltf_builder_new();
        float c[3] = {0.9f, 0.9f, 0.9f};
        int m = gi_gltf_add_material(b, "card", c, 1.0f, 0.0f, NULL, ds);
        float q0[3] = {0, 0, 0}, q1[3] = {2, 0, 0}, q2[3] = {2, 0, -3}, q3[3] = {0, 0, -3};
        gi_gltf_add_quad(b, q0, q1, q2, q3, m);
        world w;
        world_make(&w, b, ds ? "card2" : "card1");
        gi_gip_opts o = opts(10000);
        gi_gip *g = run(&w, &o, 2);
        uint32_t back = 0;
        for (uint32_t e = 0; e < g->num_entries; e++) {
            uint64_t v = g->path_start[e];
            back += g->side[v];
            /* one plane, nothing else: every path leaves it at once */
            assert_true(g->path_start[e + 1] == v + 1);
            float p[3], n[3];
            gi_gip_vertex(g, w.s, v, p, n);
            float d = n[0] * g->w_out[3 * v] + n[1] * g->w_out[3 * v + 1] + n[2] * g->w_out[3 * v + 2];
            assert_true(d > 0.0f); /* leaves on the entry's side */
            assert_true(fabsf(n[1] - (g->side[v] ? -1.0f : 1.0f)) < 1e-6f);
        }
        assert_true(g->escaped == g->num_entries);
        assert_true(g->num_photons == g->num_entries);
        if (ds) {
            assert_true(abs((int)back - (int)(g->num_entries - back)) <= 1);
            assert_true(fabs(sum_dA(g) - 12.0) < 1e-4);
        } else {
            assert_int_equal(back, 0);
            assert_true(fabs(sum_dA(g) - 6.0) < 1e-4);
        }
        gi_gip_free(g);
        world_free(&w);
    }
    /* single-sided walls seen from behind absorb: a box facing outwards */
    gi_gltf_builder *b = gi_gltf_builder_new();
    float c[3] = {0.9f, 0.9f, 0.9f};
    int m = gi_gltf_add_material(b, "in", c, 1.0f, 0.0f, NULL, 0);
    float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    gi_gltf_add_box(b, lo, hi, m, 1);
    float q0[3] = {-1, 2, -1}, q1[3] = {2, 2, -1}, q2[3] = {2, 2, 2}, q3[3] = {-1, 2, 2};
    gi_gltf_add_quad(b, q0, q1, q2, q3, m); /* a ceiling above the box, facing down */
    world w;
    world_make(&w, b, "absorb");
    gi_gip_opts o = opts(20000);
    gi_gip *g = run(&w, &o, 2);
    assert_true(g->absorbed > 0); /* paths from the ceiling hit the box's outside */
    gi_gip_free(g);
    world_free(&w);
}

/* A flat floor of many triangles, at a scale and far from the origin: a path
 * leaving a plane can never hit it again, whatever the angle. */
static void test_grazing_scales(void **state)
{
    (void)state;
    const float scales[] = {1e-3f, 1.0f, 1e3f};
    const float offsets[] = {0.0f, 5.0f};
    for (int si = 0; si < 3; si++) {
        for (int oi = 0; oi < 2; oi++) {
            /* 0, or 50 floor sizes from the origin: 5 cm, 50 m, 50 km */
            float sc = scales[si], off = offsets[oi] * sc * 10.0f;
            gi_gltf_builder *b = gi_gltf_builder_new();
            float c[3] = {0.9f, 0.9f, 0.9f};
            int m = gi_gltf_add_material(b, "floor", c, 1.0f, 0.0f, NULL, 0);
            const int G = 16;
            for (int i = 0; i < G; i++)
                for (int j = 0; j < G; j++) {
                    float x0 = off + sc * (float)i / G, x1 = off + sc * (float)(i + 1) / G;
                    float z0 = off + sc * (float)j / G, z1 = off + sc * (float)(j + 1) / G;
                    float p0[3] = {x0, off, z1}, p1[3] = {x1, off, z1}, p2[3] = {x1, off, z0},
                          p3[3] = {x0, off, z0};
                    gi_gltf_add_quad(b, p0, p1, p2, p3, m);
                }
            world w;
            char name[64];
            snprintf(name, sizeof name, "floor%d%d", si, oi);
            world_make(&w, b, name);
            gi_gip_opts o = opts(40000);
            gi_gip *g = run(&w, &o, 2);
            if (g->num_photons != g->num_entries)
                print_error("scale %g offset %g: %llu photons for %u paths\n", (double)sc,
                            (double)off, (unsigned long long)g->num_photons, g->num_entries);
            assert_true(g->num_photons == g->num_entries);
            assert_true(g->escaped == g->num_entries);
            /* the grazing tail was exercised */
            int grazing = 0;
            for (uint32_t e = 0; e < g->num_entries; e++)
                grazing += g->w_out[3 * (size_t)e + 1] < 0.01f;
            assert_true(grazing > 0);
            gi_gip_free(g);
            world_free(&w);
        }
    }
}

/* Closed rooms from millimetres to kilometres: nothing leaks, and the same
 * seed gives the same statistics. */
static void test_room_scales(void **state)
{
    (void)state;
    const float size[3] = {1.0f, 0.7f, 1.3f};
    const float albedo[3] = {0.6f, 0.6f, 0.6f};
    double means[3];
    const float scales[] = {1e-3f, 1.0f, 1e3f};
    for (int si = 0; si < 3; si++) {
        world w;
        char name[64];
        snprintf(name, sizeof name, "room%d", si);
        world_make(&w, room(albedo, 1.0f, 0.0f, scales[si], si == 2 ? 2000.0f : 0.0f, 0, size), name);
        gi_gip_opts o = opts(50000);
        gi_gip *g = run(&w, &o, 2);
        if (g->escaped || g->absorbed)
            print_error("scale %g: %llu escaped, %llu absorbed\n", (double)scales[si],
                        (unsigned long long)g->escaped, (unsigned long long)g->absorbed);
        assert_true(g->escaped == 0);
        assert_true(g->absorbed == 0);
        means[si] = mean_len(g);
        /* consecutive vertices never lie on the same wall: no self-hits */
        for (uint32_t e = 0; e < g->num_entries; e++)
            for (uint64_t v = g->path_start[e] + 1; v < g->path_start[e + 1]; v++) {
                float p0[3], n0[3], p1[3], n1[3];
                gi_gip_vertex(g, w.s, v - 1, p0, n0);
                gi_gip_vertex(g, w.s, v, p1, n1);
                assert_true(n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2] < 0.5f);
            }
        gi_gip_free(g);
        world_free(&w);
    }
    assert_true(fabs(means[0] - means[1]) < 0.03 * means[1]);
    assert_true(fabs(means[2] - means[1]) < 0.03 * means[1]);
}

static void test_open_scene(void **state)
{
    (void)state;
    /* two parallel cards facing each other: some paths bounce, the rest escape */
    gi_gltf_builder *b = gi_gltf_builder_new();
    float c[3] = {0.8f, 0.8f, 0.8f};
    int m = gi_gltf_add_material(b, "card", c, 1.0f, 0.0f, NULL, 0);
    float a0[3] = {0, 0, 0}, a1[3] = {1, 0, 0}, a2[3] = {1, 0, -1}, a3[3] = {0, 0, -1};
    gi_gltf_add_quad(b, a0, a1, a2, a3, m);
    float b0[3] = {0, 1, 0}, b1[3] = {0, 1, -1}, b2[3] = {1, 1, -1}, b3[3] = {1, 1, 0};
    gi_gltf_add_quad(b, b0, b1, b2, b3, m);
    world w;
    world_make(&w, b, "open");
    gi_gip_opts o = opts(20000);
    gi_gip *g = run(&w, &o, 2);
    /* every path ends by escaping or by roulette (nothing absorbs here) */
    assert_true(g->escaped + g->roulette == g->num_entries);
    assert_true(g->escaped > g->num_entries / 2);
    assert_true(g->num_photons > g->num_entries);
    gi_gip_free(g);
    world_free(&w);
}

/* ---- entry areas ----------------------------------------------------------------- */

/* Sum of dA over entries whose position satisfies axis k near value c. */
static double sum_dA_plane(const gi_gip *g, const gi_scene *s, int k, float c, float tol,
                           uint32_t *count)
{
    gi_ksum sum = {0, 0};
    *count = 0;
    for (uint32_t e = 0; e < g->num_entries; e++) {
        float p[3], n[3];
        gi_gip_vertex(g, s, g->path_start[e], p, n);
        if (fabsf(p[k] - c) < tol) {
            gi_ksum_add(&sum, g->entry_dA[e]);
            (*count)++;
        }
    }
    return gi_ksum_get(&sum);
}

/* A 4 x 3 x 5 m room with a table (double-sided slab) and a region just
 * under the ceiling: the refinement adds entries, and the dA-weighted sums
 * still estimate each surface's area, including the floor the table hides
 * from the grid points (visibility in the batch densities). */
static void test_region(void **state)
{
    (void)state;
    const float albedo[3] = {0.5f, 0.5f, 0.5f};
    gi_gltf_builder *b = gi_gltf_builder_new();
    int m = gi_gltf_add_material(b, "wall", albedo, 1.0f, 0.0f, NULL, 0);
    int mt = gi_gltf_add_material(b, "table", albedo, 1.0f, 0.0f, NULL, 1);
    float lo[3] = {0, 0, 0}, hi[3] = {4, 3, 5};
    gi_gltf_add_box(b, lo, hi, m, 1);
    float t0[3] = {1, 1.5f, 1}, t1[3] = {1, 1.5f, 4}, t2[3] = {3, 1.5f, 4}, t3[3] = {3, 1.5f, 1};
    gi_gltf_add_quad(b, t0, t1, t2, t3, mt);
    world w;
    world_make(&w, b, "regionroom");
    gi_gip_opts o = opts(60000);
    o.has_region = 1;
    float rmin[3] = {0.5f, 2.85f, 0.5f}, rmax[3] = {3.5f, 2.9f, 4.5f};
    memcpy(o.region_min, rmin, sizeof rmin);
    memcpy(o.region_max, rmax, sizeof rmax);
    o.region_min_visible = 2000;
    gi_gip *g = run(&w, &o, 2);
    assert_true(g->region_batches > 0);
    assert_true(g->num_entries > g->num_uniform);
    /* the photon budget is kept: refinement entries come out of the uniform set */
    assert_true(fabs((double)g->num_photons - 60000.0) < 0.1 * 60000.0);
    for (uint32_t e = 0; e < g->num_entries; e++)
        assert_true(g->entry_dA[e] > 0.0f && isfinite(g->entry_dA[e]));
    /* flux conservation: dA-weighted sums are unbiased area estimates */
    double total = 2.0 * (4.0 * 3.0 + 3.0 * 5.0 + 4.0 * 5.0) + 2.0 * 6.0;
    double sum = sum_dA(g);
    uint32_t nc, nf, nt;
    double ceil = sum_dA_plane(g, w.s, 1, 3.0f, 1e-4f, &nc);
    double floor_ = sum_dA_plane(g, w.s, 1, 0.0f, 1e-4f, &nf);
    double table = sum_dA_plane(g, w.s, 1, 1.5f, 1e-4f, &nt);
    gi_verbose("region: %u entries (%u uniform), sum dA %.4f of %.4f; ceiling %.4f (%u entries), "
               "floor %.4f (%u), table %.4f (%u)",
               g->num_entries, g->num_uniform, sum, total, ceil, nc, floor_, nf, table, nt);
    assert_true(fabs(sum - total) < 0.005 * total);
    assert_true(fabs(ceil - 20.0) < 0.015 * 20.0);
    assert_true(fabs(floor_ - 20.0) < 0.015 * 20.0);
    assert_true(fabs(table - 12.0) < 0.02 * 12.0);
    /* the ceiling, right above the region, got denser than the floor */
    assert_true(nc > nf);
    /* the uniform part alone keeps dA <= A / N_u */
    double du = total / g->num_uniform;
    for (uint32_t e = 0; e < g->num_entries; e++)
        assert_true(g->entry_dA[e] <= (float)du * 1.0001f);
    gi_gip_free(g);
    world_free(&w);
}

static void test_skew(void **state)
{
    (void)state;
    double c[8], h[8];
    for (int i = 0; i < 8; i++) {
        c[i] = 1000.0;
        h[i] = 1.0;
    }
    assert_true(gi_photon_skew(c, h, 8) < 0.01);
    /* half coverage with half the entries is just as even */
    c[3] = 500.0;
    h[3] = 0.5;
    assert_true(gi_photon_skew(c, h, 8) < 0.01);
    /* bins that see nothing do not count */
    c[5] = 0.0;
    h[5] = 0.0;
    assert_true(gi_photon_skew(c, h, 8) < 0.01);
    /* a bin seeing surfaces but no entry: skewed */
    c[6] = 0.0;
    assert_true(gi_photon_skew(c, h, 8) > 10.0);
    /* strong imbalance */
    c[6] = 1000.0;
    c[0] = 20000.0;
    double sk = gi_photon_skew(c, h, 8);
    assert_true(sk > 1.5 && sk < 2.5);
    /* Poisson noise alone is not skew */
    double cn[8] = {9, 11, 10, 13, 7, 10, 12, 8}, hn[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    assert_true(gi_photon_skew(cn, hn, 8) < 0.05);
    double z[8] = {0}, hz[8] = {0};
    assert_true(gi_photon_skew(z, hz, 8) == 0.0);
    assert_true(isinf(gi_photon_skew(z, hn, 8)));
}

/* ---- determinism and the path-length controls ----------------------------------------- */

static void test_threads(void **state)
{
    (void)state;
    const float size[3] = {3.0f, 2.5f, 3.0f};
    const float albedo[3] = {0.7f, 0.6f, 0.5f};
    world w;
    world_make(&w, room(albedo, 0.6f, 0.2f, 1.0f, 0.0f, 1, size), "threads");
    gi_gip_opts o = opts(30000);
    o.has_region = 1;
    float rmin[3] = {0.5f, 2.0f, 0.5f}, rmax[3] = {2.5f, 2.4f, 2.5f};
    memcpy(o.region_min, rmin, sizeof rmin);
    memcpy(o.region_max, rmax, sizeof rmax);
    o.region_min_visible = 1000;
    o.region_grid = 3;
    char p[3][512];
    for (int t = 0; t < 3; t++) {
        gi_gip *g = run(&w, &o, t == 2 ? 3 : t + 1);
        if (t == 0)
            assert_true(g->region_batches > 0);
        snprintf(p[t], sizeof p[t], "%s/threads%d.gip", g_dir, t);
        gi_status st = {0};
        assert_int_equal(gi_gip_write(g, p[t], w.s, "threads.gltf", &st), 0);
        gi_gip_free(g);
    }
    for (int t = 1; t < 3; t++) {
        FILE *a = fopen(p[0], "rb"), *b = fopen(p[t], "rb");
        assert_non_null(a);
        assert_non_null(b);
        int ca, cb;
        long n = 0;
        do {
            ca = fgetc(a);
            cb = fgetc(b);
            n++;
        } while (ca == cb && ca != EOF);
        if (ca != cb)
            print_error("files differ at byte %ld\n", n - 1);
        assert_int_equal(ca, cb);
        fclose(a);
        fclose(b);
    }
    world_free(&w);
}

static void test_max_bounces(void **state)
{
    (void)state;
    const float size[3] = {1.0f, 1.0f, 1.0f};
    const float albedo[3] = {0.95f, 0.95f, 0.95f};
    world w;
    world_make(&w, room(albedo, 1.0f, 0.0f, 1.0f, 0.0f, 0, size), "bright");
    gi_gip_opts o = opts(40000);
    gi_gip *g = run(&w, &o, 2);
    uint64_t longest = 0;
    for (uint32_t e = 0; e < g->num_entries; e++)
        if (g->path_start[e + 1] - g->path_start[e] > longest)
            longest = g->path_start[e + 1] - g->path_start[e];
    assert_true(longest > 4); /* no cut by default */
    assert_true(g->capped == 0);
    double m0 = mean_len(g);
    gi_gip_free(g);

    o.max_bounces = 3;
    g = run(&w, &o, 2);
    int four = 0;
    for (uint32_t e = 0; e < g->num_entries; e++) {
        uint64_t len = g->path_start[e + 1] - g->path_start[e];
        assert_true(len >= 1 && len <= 4);
        four += len == 4;
    }
    assert_true(four > 0);
    assert_true(g->capped > 0);
    /* the photon target holds either way: shorter paths, more of them */
    assert_true(mean_len(g) < m0);
    assert_true(fabs((double)g->num_photons - 40000.0) < 0.1 * 40000.0);
    gi_gip_free(g);
    world_free(&w);
}

/* In a closed room of one Lambertian material, a path continues at each
 * bounce with probability q, so its mean length is 1 / (1 - q). */
static void test_albedo(void **state)
{
    (void)state;
    const float size[3] = {2.0f, 1.5f, 1.0f};
    const float albedos[] = {0.2f, 0.5f, 0.8f};
    double prev = 0.0;
    for (int i = 0; i < 3; i++) {
        float a[3] = {albedos[i], albedos[i] * 0.5f, albedos[i] * 0.25f};
        world w;
        char name[32];
        snprintf(name, sizeof name, "albedo%d", i);
        world_make(&w, room(a, 1.0f, 0.0f, 1.0f, 0.0f, 0, size), name);
        gi_gip_opts o = opts(60000);
        gi_gip *g = run(&w, &o, 2);
        gi_bsdf b;
        gi_bsdf_init(&b, &w.s->materials[0], gi_v3p(a));
        float q = gi_clampf(gi_maxc(gi_bsdf_max_albedo(&b)), 0.1f, 0.95f);
        double qf = (double)lrintf(q * 255.0f) / 255.0;
        double want = 1.0 / (1.0 - qf), got = mean_len(g);
        double se = sqrt(qf) / (1.0 - qf) / sqrt((double)g->num_entries); /* geometric law */
        if (fabs(got - want) > 4.0 * se + 1e-3)
            print_error("albedo %g: mean length %g, expected %g (se %g)\n", (double)albedos[i], got,
                        want, se);
        assert_true(fabs(got - want) <= 4.0 * se + 1e-3);
        assert_true(got > prev);
        prev = got;
        /* the pilot's estimate gave the photon target */
        assert_true(fabs(g->pilot_mean - want) < 0.15 * want);
        assert_true(fabs((double)g->num_photons - 60000.0) < 0.1 * 60000.0);
        assert_true(g->roulette == g->num_entries);
        gi_gip_free(g);
        world_free(&w);
    }
}

/* R_k = f cos / (pdf q) = kd / q for a Lambertian surface under cosine sampling. */
static void test_lambert_reflectance(void **state)
{
    (void)state;
    const float size[3] = {2.0f, 1.0f, 1.5f};
    const float a[3] = {0.7f, 0.4f, 0.15f};
    world w;
    world_make(&w, room(a, 1.0f, 0.0f, 1.0f, 0.0f, 0, size), "lambert");
    gi_gip_opts o = opts(20000);
    gi_gip *g = run(&w, &o, 2);
    gi_bsdf b;
    gi_bsdf_init(&b, &w.s->materials[0], gi_v3p(a));
    assert_true(b.ks.x == 0.0f); /* roughness 1 folds the lobe into kd: Lambertian */
    uint64_t checked = 0;
    for (uint32_t e = 0; e < g->num_entries; e++) {
        uint64_t v0 = g->path_start[e];
        assert_int_equal(g->refl[v0], 0);
        assert_int_equal(g->q[v0], 255);
        /* entry base colour is the material's */
        assert_true(fabsf(g->entry_base[3 * e] - a[0]) < 1e-6f);
        for (uint64_t v = v0 + 1; v < g->path_start[e + 1]; v++) {
            float r[3], rr[3];
            gi_rgb9e5_unpack(g->refl[v], r);
            float qf = (float)g->q[v] / 255.0f;
            float kd[3] = {b.kd.x, b.kd.y, b.kd.z};
            for (int k = 0; k < 3; k++)
                assert_true(fabsf(r[k] - kd[k] / qf) <= (kd[0] / qf) / 256.0f);
            /* recomputing from the detail arrays gives the same */
            gi_gip_reflectance(g, w.s, w.s->materials, v, NULL, rr);
            for (int k = 0; k < 3; k++)
                assert_true(fabsf(rr[k] - kd[k] / qf) <= 1e-4f * kd[k] / qf);
            /* pdf is the cosine density around the (flat) normal */
            float p[3], n[3];
            gi_gip_vertex(g, w.s, v, p, n);
            const float *wo = g->w_out + 3 * v, *wi = g->w_in + 3 * v;
            float c = n[0] * wo[0] + n[1] * wo[1] + n[2] * wo[2];
            assert_true(fabsf(g->pdf[v] - c / GI_PIf) < 1e-5f);
            assert_true(n[0] * wi[0] + n[1] * wi[1] + n[2] * wi[2] > 0.0f);
            checked++;
        }
    }
    assert_true(checked > 1000);
    /* a changed material gives the new albedo / q from the same paths */
    gi_material m2 = w.s->materials[0];
    m2.base_color[0] = 0.1f;
    m2.base_color[1] = 0.2f;
    m2.base_color[2] = 0.3f;
    uint64_t v = 0;
    for (uint32_t e = 0; e < g->num_entries && v == 0; e++)
        if (g->path_start[e + 1] - g->path_start[e] > 1)
            v = g->path_start[e] + 1;
    assert_true(v > 0);
    float rr[3];
    gi_gip_reflectance(g, w.s, &m2, v, NULL, rr);
    gi_bsdf b2;
    gi_bsdf_init(&b2, &m2, gi_v3p(m2.base_color));
    float qf = (float)g->q[v] / 255.0f;
    assert_true(fabsf(rr[2] - b2.kd.z / qf) < 1e-4f);
    /* R_0 with a light direction: kd / q0 with q0 = 1 */
    float wl[3];
    float p[3], n[3];
    gi_gip_vertex(g, w.s, 0, p, n);
    memcpy(wl, n, sizeof wl);
    gi_gip_reflectance(g, w.s, w.s->materials, 0, wl, rr);
    assert_true(fabsf(rr[0] - b.kd.x) < 1e-4f);
    gi_gip_reflectance(g, w.s, w.s->materials, 0, NULL, rr);
    assert_true(rr[0] == 0.0f && rr[1] == 0.0f && rr[2] == 0.0f);
    gi_gip_free(g);
    world_free(&w);
}

/* A glossy material declared fixed is sampled by its BSDF: its stored pdf is
 * the BSDF's, and R recomputed from the detail matches the stored one. */
static void test_fixed_material(void **state)
{
    (void)state;
    gi_gltf_builder *b = gi_gltf_builder_new();
    float white[3] = {0.8f, 0.8f, 0.8f}, metal[3] = {0.9f, 0.7f, 0.5f};
    int mw = gi_gltf_add_material(b, "walls", white, 1.0f, 0.0f, NULL, 0);
    int mg = gi_gltf_add_material(b, "glossy floor", metal, 0.3f, 1.0f, NULL, 0);
    float lo[3] = {0, 0, 0}, hi[3] = {2, 2, 2};
    gi_gltf_add_box(b, lo, hi, mw, 1);
    float q0[3] = {0.01f, 0.01f, 1.99f}, q1[3] = {1.99f, 0.01f, 1.99f}, q2[3] = {1.99f, 0.01f, 0.01f},
          q3[3] = {0.01f, 0.01f, 0.01f};
    gi_gltf_add_quad(b, q0, q1, q2, q3, mg);
    world w;
    world_make(&w, b, "fixed");
    int gm = gi_scene_find_material(w.s, "glossy floor");
    assert_true(gm >= 0);
    for (int fixed = 0; fixed < 2; fixed++) {
        gi_gip_opts o = opts(30000);
        char(*names)[GI_NAME_MAX] = calloc(1, sizeof *names);
        strcpy(names[0], "glossy floor");
        if (fixed) {
            o.fixed = names;
            o.num_fixed = 1;
        }
        gi_gip *g = run(&w, &o, 2);
        if (fixed) {
            assert_int_equal(g->opts.num_fixed, 1);
            assert_string_equal(g->opts.fixed[0], "glossy floor");
        }
        gi_bsdf bs;
        gi_bsdf_init(&bs, &w.s->materials[gm], gi_v3p(metal));
        int on = 0, is_bsdf_pdf = 0;
        double worst = 0.0;
        for (uint32_t e = 0; e < g->num_entries; e++)
            for (uint64_t v = g->path_start[e] + 1; v < g->path_start[e + 1]; v++) {
                if (w.s->tri_material[g->tri[v]] != (uint32_t)gm)
                    continue;
                on++;
                float p[3], n[3], r[3], rr[3];
                gi_gip_vertex(g, w.s, v, p, n);
                gi_vec3 nn = gi_v3p(n), wi = gi_v3p(g->w_in + 3 * v), wo = gi_v3p(g->w_out + 3 * v);
                float bp = gi_bsdf_pdf(&bs, nn, wi, wo), cp = gi_dot(nn, wo) / GI_PIf;
                is_bsdf_pdf += fabsf(g->pdf[v] - bp) < 1e-3f * bp + 1e-6f &&
                               fabsf(g->pdf[v] - cp) > 1e-2f * cp;
                gi_rgb9e5_unpack(g->refl[v], r);
                gi_gip_reflectance(g, w.s, w.s->materials, v, NULL, rr);
                for (int k = 0; k < 3; k++) {
                    double rel = fabs((double)rr[k] - r[k]) / fmax(r[0], 1e-3);
                    worst = fmax(worst, rel);
                }
            }
        assert_true(on > 500);
        if (worst > 0.02)
            print_error("fixed %d: recomputed R differs by %g\n", fixed, worst);
        assert_true(worst < 0.02);
        if (fixed)
            assert_true(is_bsdf_pdf > on * 9 / 10);
        else
            assert_true(is_bsdf_pdf < on / 10);
        gi_gip_free(g);
        free(names);
    }
    /* an unknown name is a usage error that lists the scene's materials */
    gi_gip_opts o = opts(1000);
    char(*bad)[GI_NAME_MAX] = calloc(1, sizeof *bad);
    strcpy(bad[0], "marble");
    o.fixed = bad;
    o.num_fixed = 1;
    gi_status st = {0};
    gi_gip *g = NULL;
    assert_int_equal(gi_photon_precompute(w.s, w.rt, &o, 1, &g, &st), GI_EXIT_USAGE);
    assert_null(g);
    assert_has(st.msg, "'marble'");
    assert_has(st.msg, "'glossy floor'");
    free(bad);
    world_free(&w);
}

static void test_photon_target(void **state)
{
    (void)state;
    const float size[3] = {1.0f, 2.0f, 3.0f};
    const float albedo[3] = {0.6f, 0.6f, 0.6f};
    world w;
    world_make(&w, room(albedo, 1.0f, 0.0f, 1.0f, 0.0f, 1, size), "target");
    const uint64_t targets[] = {1, 500, 25000};
    for (int i = 0; i < 3; i++) {
        gi_gip_opts o = opts(targets[i]);
        gi_gip *g = run(&w, &o, 2);
        assert_true(g->num_entries >= 1);
        if (targets[i] >= 500)
            assert_true(fabs((double)g->num_photons - (double)targets[i]) < 0.15 * (double)targets[i]);
        /* double-sided walls: half the entries outside, escaping at once */
        assert_true(fabs(sum_dA(g) - 2.0 * 22.0) < 1e-4 * 44.0);
        gi_gip_free(g);
    }
    gi_gip_opts o = opts(0);
    gi_status st = {0};
    gi_gip *g = NULL;
    assert_int_equal(gi_photon_precompute(w.s, w.rt, &o, 1, &g, &st), GI_EXIT_USAGE);
    world_free(&w);
}

static int setup(void **state)
{
    (void)state;
    gi_log_set_verbosity(getenv("GI_TEST_VERBOSE") ? 1 : -1);
    snprintf(g_dir, sizeof g_dir, "/tmp/gi-test-precompute-XXXXXX");
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
        cmocka_unit_test(test_degenerate),
        cmocka_unit_test(test_empty_scene),
        cmocka_unit_test(test_sides),
        cmocka_unit_test(test_grazing_scales),
        cmocka_unit_test(test_room_scales),
        cmocka_unit_test(test_open_scene),
        cmocka_unit_test(test_region),
        cmocka_unit_test(test_skew),
        cmocka_unit_test(test_threads),
        cmocka_unit_test(test_max_bounces),
        cmocka_unit_test(test_albedo),
        cmocka_unit_test(test_lambert_reflectance),
        cmocka_unit_test(test_fixed_material),
        cmocka_unit_test(test_photon_target),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
