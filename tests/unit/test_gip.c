/* test_gip.c - the .gip file: bit-exact write/read round trip (directions up to
 * the documented octahedral quantisation), RGB9E5 and octahedral encodings,
 * truncation at every section boundary, foreign scenes and files, and every
 * content check of the reader on files whose CRCs are valid. */
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

#include "gi_container.h"
#include "gi_gip.h"
#include "gi_gltf_write.h"
#include "gi_le.h"
#include "gi_math.h"
#include "gi_rng.h"
#include "gi_scene.h"

static char g_dir[256];
static gi_scene *g_scene, *g_other;

/* ---- helpers --------------------------------------------------------------- */

static void assert_has_at(const char *msg, const char *sub, const char *file, int line)
{
    if (!strstr(msg, sub)) {
        print_error("%s:%d: message \"%s\" lacks \"%s\"\n", file, line, msg, sub);
        _fail(file, line);
    }
}
#define assert_has(msg, sub) assert_has_at((msg), (sub), __FILE__, __LINE__)

static void path_in(char *out, size_t n, const char *name) { snprintf(out, n, "%s/%s", g_dir, name); }

static unsigned char *read_all(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *p = malloc(len > 0 ? (size_t)len : 1);
    assert_non_null(p);
    assert_int_equal(fread(p, 1, (size_t)len, f), (size_t)len);
    fclose(f);
    *n = (size_t)len;
    return p;
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(p, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static gi_scene *make_scene(const char *name, float size)
{
    gi_gltf_builder *b = gi_gltf_builder_new();
    assert_non_null(b);
    float white[3] = {0.8f, 0.8f, 0.8f}, red[3] = {0.7f, 0.1f, 0.1f};
    int m0 = gi_gltf_add_material(b, "white", white, 1.0f, 0.0f, NULL, 0);
    int m1 = gi_gltf_add_material(b, "red card", red, 0.5f, 0.0f, NULL, 1);
    float lo[3] = {0, 0, 0}, hi[3] = {size, size, size};
    gi_gltf_add_box(b, lo, hi, m0, 1);
    float p0[3] = {0.2f, 0.5f, 0.2f}, p1[3] = {0.8f, 0.5f, 0.2f}, p2[3] = {0.8f, 0.5f, 0.8f},
          p3[3] = {0.2f, 0.5f, 0.8f};
    gi_gltf_add_quad(b, p0, p1, p2, p3, m1);
    char path[512];
    path_in(path, sizeof path, name);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, path, &st), 0);
    gi_gltf_builder_free(b);
    gi_scene *s = NULL;
    assert_int_equal(gi_scene_load(path, &s, &st), 0);
    return s;
}

static void rand_dir(gi_rng *r, float d[3])
{
    float z = 1.0f - 2.0f * gi_rng_float(r), phi = 2.0f * GI_PIf * gi_rng_float(r);
    float s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    d[0] = s * cosf(phi);
    d[1] = s * sinf(phi);
    d[2] = z;
}

/* A synthetic but valid gi_gip for g_scene: random path lengths and values. */
static gi_gip *make_gip(uint32_t n, uint64_t seed)
{
    gi_rng r;
    gi_rng_seed(&r, seed, 0, 0);
    uint32_t *len = malloc(n * sizeof *len);
    uint64_t P = 0;
    for (uint32_t i = 0; i < n; i++) {
        len[i] = 1 + gi_rng_u32(&r) % 6;
        P += len[i];
    }
    gi_gip *g = gi_gip_new(n, P);
    assert_non_null(g);
    g->scene_hash = g_scene->hash;
    g->num_uniform = n - n / 4;
    g->opts.photons = P;
    g->opts.max_bounces = 5;
    g->opts.seed = 0xfedcba9876543210ULL;
    g->opts.has_region = 1;
    float rmin[3] = {0.1f, 0.95f, -0.3f}, rmax[3] = {0.9f, 0.99f, 1.0f / 3.0f};
    memcpy(g->opts.region_min, rmin, sizeof rmin);
    memcpy(g->opts.region_max, rmax, sizeof rmax);
    g->opts.region_grid = 5;
    g->opts.region_min_visible = 1234;
    g->opts.region_max_skew = 0.7f;
    g->opts.num_fixed = 2;
    g->opts.fixed = calloc(2, sizeof *g->opts.fixed);
    strcpy(g->opts.fixed[0], "white");
    strcpy(g->opts.fixed[1], "red card");
    g->skipped_degenerate = 3;
    g->escaped = 17;
    g->absorbed = 5;
    g->roulette = 99;
    g->capped = 2;
    g->region_batches = 4;
    g->pilot_mean = 2.718281828;
    uint64_t v = 0;
    for (uint32_t i = 0; i < n; i++) {
        g->path_start[i] = v;
        g->entry_dA[i] = 1e-4f * (0.5f + gi_rng_float(&r));
        for (int k = 0; k < 3; k++)
            g->entry_base[3 * i + k] = gi_rng_float(&r);
        for (uint32_t k = 0; k < len[i]; k++, v++) {
            g->tri[v] = gi_rng_u32(&r) % (uint32_t)g_scene->num_triangles;
            float a = gi_rng_float(&r), b = gi_rng_float(&r);
            if (a + b > 1.0f) {
                a = 1.0f - a;
                b = 1.0f - b;
            }
            g->bary[2 * v] = a;
            g->bary[2 * v + 1] = b;
            g->side[v] = (uint8_t)(gi_rng_u32(&r) & 1);
            g->pdf[v] = 0.01f + gi_rng_float(&r);
            rand_dir(&r, g->w_out + 3 * v);
            if (k == 0) {
                g->q[v] = 255;
                g->refl[v] = 0; /* w_in stays (0,0,0) */
            } else {
                g->q[v] = (uint8_t)(1 + gi_rng_u32(&r) % 255);
                float rgb[3] = {gi_rng_float(&r) * 3.0f, gi_rng_float(&r), gi_rng_float(&r) * 0.1f};
                g->refl[v] = gi_rgb9e5_pack(rgb);
                rand_dir(&r, g->w_in + 3 * v);
            }
        }
    }
    g->path_start[n] = v;
    free(len);
    return g;
}

static double angle(const float *a, const float *b)
{
    double d = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
    double cx = (double)a[1] * b[2] - (double)a[2] * b[1];
    double cy = (double)a[2] * b[0] - (double)a[0] * b[2];
    double cz = (double)a[0] * b[1] - (double)a[1] * b[0];
    return atan2(sqrt(cx * cx + cy * cy + cz * cz), d);
}

/* ---- setup ----------------------------------------------------------------- */

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/gi-test-gip-XXXXXX");
    if (!mkdtemp(g_dir))
        return -1;
    g_scene = make_scene("a.gltf", 1.0f);
    g_other = make_scene("b.gltf", 1.5f);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    gi_scene_free(g_scene);
    gi_scene_free(g_other);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* ---- encodings ---------------------------------------------------------------- */

static void test_rgb9e5(void **state)
{
    (void)state;
    float out[3];
    float zero[3] = {0, 0, 0};
    assert_int_equal(gi_rgb9e5_pack(zero), 0);
    gi_rgb9e5_unpack(0, out);
    assert_true(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f);

    /* values with at most 9 significant bits in the shared range are exact */
    float exact[][3] = {{1.0f, 0.5f, 0.25f}, {65408.0f, 0.0f, 128.0f}, {3.0f, 1.5f, 0.0f},
                        {0.0009765625f, 0.0f, 0.0f}};
    for (size_t i = 0; i < sizeof exact / sizeof exact[0]; i++) {
        gi_rgb9e5_unpack(gi_rgb9e5_pack(exact[i]), out);
        for (int k = 0; k < 3; k++)
            assert_true(out[k] == exact[i][k]);
    }

    /* range: clamped above 65408, non-finite and negative handled */
    float big[3] = {1e9f, INFINITY, -5.0f};
    gi_rgb9e5_unpack(gi_rgb9e5_pack(big), out);
    assert_true(out[0] == 65408.0f && out[1] == 65408.0f && out[2] == 0.0f);
    float bad[3] = {NAN, 2.0f, -INFINITY};
    gi_rgb9e5_unpack(gi_rgb9e5_pack(bad), out);
    assert_true(out[0] == 0.0f && out[1] == 2.0f && out[2] == 0.0f);
    /* tiny values: below the smallest step 2^-24 they vanish, above they survive */
    float tiny[3] = {1e-9f, 1e-7f, 0.0f};
    gi_rgb9e5_unpack(gi_rgb9e5_pack(tiny), out);
    assert_true(out[0] == 0.0f);
    assert_true(fabsf(out[1] - 1e-7f) <= 0.5f * ldexpf(1.0f, -24));

    /* accuracy: every channel within half a step of the shared exponent,
     * i.e. at most max(rgb) * 2^-9, or half the smallest step 2^-24 */
    gi_rng r;
    gi_rng_seed(&r, 5, 0, 0);
    double worst = 0.0;
    for (int i = 0; i < 200000; i++) {
        float m = powf(10.0f, -5.0f + 9.5f * gi_rng_float(&r));
        float in[3] = {m, m * gi_rng_float(&r), m * gi_rng_float(&r) * gi_rng_float(&r)};
        int rot = (int)(gi_rng_u32(&r) % 3);
        float v[3] = {in[rot], in[(rot + 1) % 3], in[(rot + 2) % 3]};
        if (m > 65408.0f)
            continue;
        gi_rgb9e5_unpack(gi_rgb9e5_pack(v), out);
        for (int k = 0; k < 3; k++) {
            double err = fabs((double)out[k] - v[k]);
            double bound = fmax((double)m / 512.0, ldexp(1.0, -25));
            if (err / bound > worst)
                worst = err / bound;
            assert_true(err <= bound * (1.0 + 1e-6));
        }
    }
    assert_true(worst > 0.5); /* the bound is tight: the check is not vacuous */
}

static void test_octahedral(void **state)
{
    (void)state;
    gi_rng r;
    gi_rng_seed(&r, 11, 0, 0);
    double worst = 0.0;
    for (int i = 0; i < 200000; i++) {
        float d[3], o[3];
        int16_t e[2];
        rand_dir(&r, d);
        if (i < 6) { /* the axes, folds included */
            d[0] = d[1] = d[2] = 0.0f;
            d[i / 2] = (i & 1) ? -1.0f : 1.0f;
        }
        gi_gip_oct_encode(d, e);
        gi_gip_oct_decode(e, o);
        assert_true(fabsf(o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - 1.0f) < 1e-6f);
        double a = angle(d, o);
        if (a > worst)
            worst = a;
        assert_true(a < 1e-4);
    }
    assert_true(worst > 1e-5); /* the measurement resolves the quantisation */
    float z[3] = {0, 0, 0};
    int16_t e[2] = {7, 7};
    gi_gip_oct_encode(z, e);
    assert_int_equal(e[0], 0);
    assert_int_equal(e[1], 0);
    /* every code decodes to a unit vector, the extremes included */
    int16_t ex[2] = {-32768, 32767};
    float o[3];
    gi_gip_oct_decode(ex, o);
    assert_true(isfinite(o[0]) && fabsf(o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - 1.0f) < 1e-6f);
}

/* ---- round trip ----------------------------------------------------------------- */

static void test_roundtrip(void **state)
{
    (void)state;
    gi_gip *g = make_gip(3000, 1);
    char p1[512], p2[512];
    path_in(p1, sizeof p1, "rt1.gip");
    path_in(p2, sizeof p2, "rt2.gip");
    gi_status st = {0};
    assert_int_equal(gi_gip_write(g, p1, g_scene, "scenes/a.gltf", &st), 0);
    gi_gip *h = NULL;
    int rc = gi_gip_read(p1, g_scene, &h, &st);
    if (rc)
        print_error("%s\n", st.msg);
    assert_int_equal(rc, 0);
    assert_non_null(h);
    uint64_t P = g->num_photons, N = g->num_entries;
    assert_int_equal(h->num_entries, N);
    assert_int_equal(h->num_uniform, g->num_uniform);
    assert_int_equal(h->num_photons, P);
    assert_true(h->scene_hash == g_scene->hash);
    assert_true(h->fingerprint != 0);
    assert_memory_equal(h->path_start, g->path_start, (N + 1) * sizeof *h->path_start);
    assert_memory_equal(h->entry_dA, g->entry_dA, N * sizeof *h->entry_dA);
    assert_memory_equal(h->entry_base, g->entry_base, 3 * N * sizeof *h->entry_base);
    assert_memory_equal(h->refl, g->refl, P * sizeof *h->refl);
    assert_memory_equal(h->tri, g->tri, P * sizeof *h->tri);
    assert_memory_equal(h->bary, g->bary, 2 * P * sizeof *h->bary);
    assert_memory_equal(h->side, g->side, P);
    assert_memory_equal(h->pdf, g->pdf, P * sizeof *h->pdf);
    assert_memory_equal(h->q, g->q, P);
    double worst = 0.0;
    for (uint64_t i = 0; i < P; i++) {
        double a = angle(h->w_out + 3 * i, g->w_out + 3 * i);
        worst = fmax(worst, a);
        assert_true(a < 1e-4);
    }
    for (uint32_t p = 0; p < N; p++) {
        uint64_t v = g->path_start[p];
        assert_true(h->w_in[3 * v] == 0.0f && h->w_in[3 * v + 1] == 0.0f && h->w_in[3 * v + 2] == 0.0f);
        for (v++; v < g->path_start[p + 1]; v++)
            assert_true(angle(h->w_in + 3 * v, g->w_in + 3 * v) < 1e-4);
    }
    assert_true(worst > 0.0); /* quantisation happened: the comparison is real */
    /* options and statistics */
    assert_true(h->opts.photons == g->opts.photons);
    assert_int_equal(h->opts.max_bounces, 5);
    assert_true(h->opts.seed == g->opts.seed);
    assert_int_equal(h->opts.has_region, 1);
    assert_memory_equal(h->opts.region_min, g->opts.region_min, sizeof h->opts.region_min);
    assert_memory_equal(h->opts.region_max, g->opts.region_max, sizeof h->opts.region_max);
    assert_int_equal(h->opts.region_grid, 5);
    assert_int_equal(h->opts.region_min_visible, 1234);
    assert_true(h->opts.region_max_skew == 0.7f);
    assert_int_equal(h->opts.num_fixed, 2);
    assert_string_equal(h->opts.fixed[0], "white");
    assert_string_equal(h->opts.fixed[1], "red card");
    assert_true(h->skipped_degenerate == 3 && h->escaped == 17 && h->absorbed == 5 &&
                h->roulette == 99 && h->capped == 2 && h->region_batches == 4);
    assert_true(h->pilot_mean == 2.718281828);

    /* writing what was read gives the same bytes: the quantisation is stable */
    h->scene_hash = g_scene->hash;
    assert_int_equal(gi_gip_write(h, p2, g_scene, "scenes/a.gltf", &st), 0);
    size_t n1, n2;
    unsigned char *b1 = read_all(p1, &n1), *b2 = read_all(p2, &n2);
    assert_int_equal(n1, n2);
    assert_memory_equal(b1, b2, n1);
    /* and the same from memory */
    gi_gip *m = NULL;
    assert_int_equal(gi_gip_read_memory(b1, n1, "mem.gip", g_scene, &m, &st), 0);
    assert_memory_equal(m->refl, g->refl, P * sizeof *m->refl);
    gi_gip_free(m);
    free(b1);
    free(b2);

    /* no region, Russian roulette only, no fixed materials */
    gi_gip *g2 = make_gip(10, 2);
    g2->opts.has_region = 0;
    g2->opts.max_bounces = -1;
    free(g2->opts.fixed);
    g2->opts.fixed = NULL;
    g2->opts.num_fixed = 0;
    assert_int_equal(gi_gip_write(g2, p2, g_scene, "a.gltf", &st), 0);
    gi_gip *h2 = NULL;
    assert_int_equal(gi_gip_read(p2, g_scene, &h2, &st), 0);
    assert_int_equal(h2->opts.has_region, 0);
    assert_int_equal(h2->opts.max_bounces, -1);
    assert_int_equal(h2->opts.num_fixed, 0);
    assert_null(h2->opts.fixed);
    /* sizes reported match the file's sections */
    gi_reader *r = NULL;
    assert_int_equal(gi_reader_open(p1, GI_GIP_MAGIC, GI_GIP_MAJOR, &r, &st), 0);
    size_t se, sr, sd;
    assert_non_null(gi_reader_section(r, "ENTR", &se));
    assert_non_null(gi_reader_section(r, "REFL", &sr));
    assert_non_null(gi_reader_section(r, "DETL", &sd));
    assert_true(gi_gip_compact_bytes(g) == se + sr);
    assert_true(gi_gip_detail_bytes(g) == sd);
    assert_string_equal(gi_reader_meta(r, "tool"), "gi-precompute");
    assert_string_equal(gi_reader_meta(r, "input.scene"), "scenes/a.gltf");
    gi_reader_free(r);
    gi_gip_free(h2);
    gi_gip_free(g2);
    gi_gip_free(h);
    gi_gip_free(g);
}

static void test_vertex(void **state)
{
    (void)state;
    gi_gip *g = make_gip(200, 3);
    for (uint64_t i = 0; i < g->num_photons; i++) {
        float p[3], n[3];
        gi_gip_vertex(g, g_scene, i, p, n);
        const uint32_t *ix = g_scene->indices + 3 * (size_t)g->tri[i];
        float u = g->bary[2 * i], v = g->bary[2 * i + 1];
        for (int k = 0; k < 3; k++) {
            float want = (1 - u - v) * g_scene->positions[3 * ix[0] + k] +
                         u * g_scene->positions[3 * ix[1] + k] + v * g_scene->positions[3 * ix[2] + k];
            assert_true(fabsf(p[k] - want) < 1e-5f);
        }
        /* the flat normal of the triangle, on the photon's side */
        gi_vec3 p0 = gi_v3p(g_scene->positions + 3 * ix[0]);
        gi_vec3 ng = gi_norm(gi_cross(gi_sub(gi_v3p(g_scene->positions + 3 * ix[1]), p0),
                                      gi_sub(gi_v3p(g_scene->positions + 3 * ix[2]), p0)));
        float d = gi_dot(ng, gi_v3p(n));
        assert_true(g->side[i] ? d < -0.999f : d > 0.999f);
    }
    gi_gip_free(g);
}

/* ---- refusals --------------------------------------------------------------------- */

static void expect_refused(const char *path, int code, const char *sub)
{
    gi_status st = {0};
    gi_gip *g = (gi_gip *)1;
    int rc = gi_gip_read(path, g_scene, &g, &st);
    if (rc != code)
        print_error("%s: rc %d (wanted %d): %s\n", path, rc, code, st.msg);
    assert_int_equal(rc, code);
    if (code == 0) {
        assert_non_null(g);
        gi_gip_free(g);
        return;
    }
    assert_null(g);
    if (sub)
        assert_has(st.msg, sub);
}

static void test_truncation(void **state)
{
    (void)state;
    gi_gip *g = make_gip(50, 4);
    char p[512], t[512];
    path_in(p, sizeof p, "full.gip");
    path_in(t, sizeof t, "cut.gip");
    gi_status st = {0};
    assert_int_equal(gi_gip_write(g, p, g_scene, "a.gltf", &st), 0);
    size_t n;
    unsigned char *b = read_all(p, &n);
    gi_reader *r = NULL;
    assert_int_equal(gi_reader_open(p, GI_GIP_MAGIC, GI_GIP_MAJOR, &r, &st), 0);
    uint32_t ns = gi_reader_section_count(r);
    assert_int_equal(ns, 5);
    size_t cuts[64];
    int nc = 0;
    cuts[nc++] = 0;
    cuts[nc++] = 8;
    cuts[nc++] = 31;
    cuts[nc++] = 32;
    for (uint32_t i = 0; i < ns; i++) {
        gi_section_info si;
        assert_int_equal(gi_reader_section_info(r, i, &si), 0);
        cuts[nc++] = 32 + 32 * (size_t)i + 31; /* inside the table entry */
        cuts[nc++] = (size_t)si.offset - 1;
        cuts[nc++] = (size_t)si.offset;
        cuts[nc++] = (size_t)(si.offset + si.size / 2);
        cuts[nc++] = (size_t)(si.offset + si.size) - 1;
        if (si.offset + si.size < n)
            cuts[nc++] = (size_t)(si.offset + si.size);
    }
    gi_reader_free(r);
    for (int i = 0; i < nc; i++) {
        assert_true(cuts[i] < n);
        write_bytes(t, b, cuts[i]);
        expect_refused(t, GI_EXIT_DATA, cuts[i] == 0 ? "empty" : NULL);
        gi_gip *m = NULL;
        assert_int_equal(gi_gip_read_memory(b, cuts[i], "cut", g_scene, &m, &st), GI_EXIT_DATA);
        assert_null(m);
    }
    /* a byte more is refused too */
    unsigned char *b2 = malloc(n + 1);
    memcpy(b2, b, n);
    b2[n] = 0;
    write_bytes(t, b2, n + 1);
    expect_refused(t, GI_EXIT_DATA, "trailing");
    free(b2);
    /* flipped bytes anywhere are caught */
    for (size_t i = 0; i < n; i += n / 97 + 1) {
        b[i] ^= 0x10;
        gi_gip *m = NULL;
        assert_int_equal(gi_gip_read_memory(b, n, "flip", g_scene, &m, &st), GI_EXIT_DATA);
        b[i] ^= 0x10;
    }
    free(b);
    gi_gip_free(g);
}

static void test_foreign(void **state)
{
    (void)state;
    gi_gip *g = make_gip(20, 5);
    char p[512], t[512];
    path_in(p, sizeof p, "foreign.gip");
    gi_status st = {0};
    assert_int_equal(gi_gip_write(g, p, g_scene, "a.gltf", &st), 0);
    /* made from another scene */
    gi_gip *h = (gi_gip *)1;
    assert_int_equal(gi_gip_read(p, g_other, &h, &st), GI_EXIT_DATA);
    assert_null(h);
    assert_has(st.msg, "made from scene hash");
    assert_has(st.msg, "re-run gi-precompute");
    /* the writer refuses paths of another scene */
    assert_int_equal(gi_gip_write(g, p, g_other, "b.gltf", &st), GI_EXIT_USAGE);
    /* another file type */
    path_in(t, sizeof t, "x.gih");
    gi_writer *w = gi_writer_new("GIHVDS\0\0", 1, 0);
    assert_int_equal(gi_writer_write(w, t, &st), 0);
    gi_writer_free(w);
    expect_refused(t, GI_EXIT_DATA, "is a .gih file");
    path_in(t, sizeof t, "x.txt");
    write_bytes(t, "hello world, this is not a gip file", 35);
    expect_refused(t, GI_EXIT_DATA, "not a .gip file");
    /* a newer major version */
    path_in(t, sizeof t, "v2.gip");
    w = gi_writer_new(GI_GIP_MAGIC, GI_GIP_MAJOR + 1, 0);
    assert_int_equal(gi_writer_write(w, t, &st), 0);
    gi_writer_free(w);
    expect_refused(t, GI_EXIT_DATA, "format 2.0");
    /* missing file: a system error */
    path_in(t, sizeof t, "none.gip");
    expect_refused(t, GI_EXIT_SYSTEM, "No such file");
    gi_gip_free(g);
}

/* Rewrite src into dst with section `id` replaced by data (or dropped if
 * data is NULL); the container's CRCs are valid, so only content checks can
 * refuse the result. */
static void rebuild(const char *src, const char *dst, const char *id, const void *data, size_t size)
{
    gi_status st = {0};
    gi_reader *r = NULL;
    assert_int_equal(gi_reader_open(src, GI_GIP_MAGIC, GI_GIP_MAJOR, &r, &st), 0);
    gi_writer *w = gi_writer_new(GI_GIP_MAGIC, GI_GIP_MAJOR, GI_GIP_MINOR);
    for (uint32_t i = 0; i < gi_reader_section_count(r); i++) {
        gi_section_info si;
        gi_reader_section_info(r, i, &si);
        if (memcmp(si.id, id, 4) == 0) {
            if (data)
                assert_int_equal(gi_writer_add(w, si.id, 0, data, size, &st), 0);
            continue;
        }
        size_t n;
        const void *p = gi_reader_section(r, si.id, &n);
        assert_int_equal(gi_writer_add(w, si.id, 0, p, n, &st), 0);
    }
    assert_int_equal(gi_writer_write(w, dst, &st), 0);
    gi_writer_free(w);
    gi_reader_free(r);
}

/* Copy of section id of file src (caller frees). */
static unsigned char *section_copy(const char *src, const char *id, size_t *n)
{
    gi_status st = {0};
    gi_reader *r = NULL;
    assert_int_equal(gi_reader_open(src, GI_GIP_MAGIC, GI_GIP_MAJOR, &r, &st), 0);
    const void *p = gi_reader_section(r, id, n);
    assert_non_null(p);
    unsigned char *c = malloc(*n + 16);
    memcpy(c, p, *n);
    gi_reader_free(r);
    return c;
}

typedef struct patch {
    const char *id;
    size_t off;     /* byte offset in the section; see the layout in docs/formats.md */
    int width;      /* 1, 2, 4 */
    uint32_t value; /* as an integer (floats by bits) */
    const char *msg;
} patch;

static uint32_t fbits(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    return u;
}

static void test_content_checks(void **state)
{
    (void)state;
    gi_gip *g = make_gip(8, 6);
    const size_t N = g->num_entries, P = (size_t)g->num_photons;
    char p[512], t[512];
    path_in(p, sizeof p, "good.gip");
    path_in(t, sizeof t, "bad.gip");
    gi_status st = {0};
    assert_int_equal(gi_gip_write(g, p, g_scene, "a.gltf", &st), 0);
    expect_refused(p, 0, NULL); /* the unpatched file is fine */
    /* ENTR: 16-byte header, dA[N], base[3N], length u16[N]; DETL: tri[P],
     * bary[2P], pdf[P], w_in[2P] i16, w_out[2P] i16, side[P], q[P] */
    size_t e_da = 16, e_base = 16 + 4 * N, e_len = 16 + 16 * N;
    size_t v1 = (size_t)g->path_start[1]; /* entry of path 1 */
    size_t longp = 0; /* a path of 2 or more vertices */
    while (g->path_start[longp + 1] - g->path_start[longp] < 2)
        longp++;
    assert_true(longp < N);
    uint16_t len0 = (uint16_t)(g->path_start[1] - g->path_start[0]);
    uint16_t lenl = (uint16_t)(g->path_start[longp + 1] - g->path_start[longp]);
    const patch patches[] = {
        {"ENTR", 0, 4, 0, "no entry points"},
        {"ENTR", 4, 4, (uint32_t)N + 1, "uniform entries"},
        {"ENTR", 8, 4, (uint32_t)N - 1, "photons for"},
        {"ENTR", 8, 4, (uint32_t)P + 1, "expected"},
        {"ENTR", e_da + 4, 4, fbits(-1.0f), "differential area"},
        {"ENTR", e_da + 8, 4, fbits(0.0f), "differential area"},
        {"ENTR", e_da, 4, fbits(NAN), "differential area"},
        {"ENTR", e_da, 4, fbits(INFINITY), "differential area"},
        {"ENTR", e_base + 4, 4, fbits(NAN), "base colour"},
        {"ENTR", e_base, 4, fbits(-0.5f), "base colour"},
        {"ENTR", e_len, 2, 0, "has no vertex"},
        {"ENTR", e_len, 2, (uint32_t)len0 + 1, "runs past"},
        {"ENTR", e_len + 2 * longp, 2, (uint32_t)lenl - 1, "vertices, the header says"},
        {"ENTR", e_len + 2, 2, 65535, "runs past"},
        {"DETL", 4, 4, (uint32_t)g_scene->num_triangles, "does not exist"},
        {"DETL", 0, 4, 0xffffffffu, "does not exist"},
        {"DETL", 4 * P + 8 * 2, 4, fbits(-0.1f), "barycentrics"},
        {"DETL", 4 * P + 8 * 2 + 4, 4, fbits(1.5f), "barycentrics"},
        {"DETL", 4 * P, 4, fbits(NAN), "barycentrics"},
        {"DETL", 12 * P + 4 * 3, 4, fbits(0.0f), "pdf"},
        {"DETL", 12 * P, 4, fbits(INFINITY), "pdf"},
        {"DETL", 24 * P + 1, 1, 2, "side"},
        {"DETL", 25 * P + 2, 1, 0, "continuation probability"},
        {"DETL", 16 * P + 4 * v1, 2, 100, "incoming direction"},
        {"REFL", 4 * v1, 4, 0x12345u, "entry point has a reflectance"},
        {"STAT", 44, 4, 1, "reserved"},
        {"STAT", 48, 4, fbits(NAN), "pilot"},
    };
    for (size_t i = 0; i < sizeof patches / sizeof patches[0]; i++) {
        const patch *q = &patches[i];
        size_t n;
        unsigned char *sec = section_copy(p, q->id, &n);
        assert_true(q->off + (size_t)q->width <= n);
        if (q->width == 1)
            sec[q->off] = (unsigned char)q->value;
        else if (q->width == 2)
            gi_le_put_u16(sec + q->off, (uint16_t)q->value);
        else if (strcmp(q->id, "STAT") == 0 && q->off == 48)
            gi_le_put_f64(sec + q->off, NAN);
        else
            gi_le_put_u32(sec + q->off, q->value);
        rebuild(p, t, q->id, sec, n);
        free(sec);
        expect_refused(t, GI_EXIT_DATA, q->msg);
    }
    /* sections of the wrong size */
    const char *ids[] = {"ENTR", "REFL", "DETL", "STAT"};
    for (int i = 0; i < 4; i++) {
        size_t n;
        unsigned char *sec = section_copy(p, ids[i], &n);
        rebuild(p, t, ids[i], sec, n - 1);
        expect_refused(t, GI_EXIT_DATA, ids[i]);
        memset(sec + n, 0, 4);
        rebuild(p, t, ids[i], sec, n + 4);
        expect_refused(t, GI_EXIT_DATA, ids[i]);
        rebuild(p, t, ids[i], NULL, 0);
        expect_refused(t, GI_EXIT_DATA, "missing");
        free(sec);
    }
    /* META: missing keys and bad values */
    size_t mn;
    unsigned char *meta = section_copy(p, "META", &mn);
    meta[mn] = '\0';
    const char *edits[][3] = {
        {"option.photons=", "option.photons=abc\n", "option.photons"},
        {"option.photons=", "option.photons=0\n", "option.photons"},
        {"option.max-bounces=", "option.max-bounces=-3\n", "option.max-bounces"},
        {"option.seed=", "option.seed=1x\n", "option.seed"},
        {"option.region=", "option.region=1 2 3 4 5\n", "option.region"},
        {"option.region=", "option.region=1 2 3 0 5 6\n", "option.region"},
        {"option.region-grid=", "option.region-grid=0\n", "option.region-grid"},
        {"option.fixed-material.count=", "option.fixed-material.count=3\n", "option.fixed-material.2"},
        {"option.fixed-material.0=", "", "option.fixed-material.0"},
        {"input.scene.hash=", "", "input.scene.hash"},
        {"option.seed=", "", "option.seed"},
    };
    for (size_t i = 0; i < sizeof edits / sizeof edits[0]; i++) {
        const char *at = strstr((char *)meta, edits[i][0]);
        assert_non_null(at);
        const char *eol = strchr(at, '\n') + 1;
        char buf[4096];
        size_t k = (size_t)(at - (char *)meta);
        memcpy(buf, meta, k);
        strcpy(buf + k, edits[i][1]);
        strcat(buf, eol);
        rebuild(p, t, "META", buf, strlen(buf));
        expect_refused(t, GI_EXIT_DATA, edits[i][2]);
    }
    free(meta);
    gi_gip_free(g);
}

static void test_writer_checks(void **state)
{
    (void)state;
    gi_gip *g = make_gip(5, 7);
    char p[512];
    path_in(p, sizeof p, "w.gip");
    gi_status st = {0};
    g->path_start[2] = g->path_start[1]; /* an empty path */
    assert_int_equal(gi_gip_write(g, p, g_scene, "a.gltf", &st), GI_EXIT_USAGE);
    assert_has(st.msg, "path 1");
    assert_int_equal(access(p, F_OK), -1); /* nothing written */
    gi_gip_free(g);
    /* a META value with a newline cannot be recorded */
    g = make_gip(5, 7);
    assert_int_equal(gi_gip_write(g, p, g_scene, "bad\nname.gltf", &st), GI_EXIT_USAGE);
    assert_int_equal(access(p, F_OK), -1);
    gi_gip_free(g);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rgb9e5),
        cmocka_unit_test(test_octahedral),
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_vertex),
        cmocka_unit_test(test_truncation),
        cmocka_unit_test(test_foreign),
        cmocka_unit_test(test_content_checks),
        cmocka_unit_test(test_writer_checks),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
