/* test_gltf_write.c - gi_gltf_write: base64, rotations, deterministic bytes,
 * buffer contents, errors without partial files, and a round trip through
 * gi_scene_load (the tinygltf loader). */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "gi_gltf_write.h"
#include "gi_scene.h"

static char g_dir[256];

static void path_in(char *buf, size_t cap, const char *name)
{
    snprintf(buf, cap, "%s/%s", g_dir, name);
}

static int count_entries(const char *dir, const char *substr)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") && strstr(e->d_name, substr))
            n++;
    closedir(d);
    return n;
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/gi_test_gltf_write.XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    DIR *d = opendir(g_dir);
    if (d) {
        struct dirent *e;
        char p[512];
        while ((e = readdir(d)) != NULL) {
            if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
                continue;
            snprintf(p, sizeof p, "%s/%s", g_dir, e->d_name);
            unlink(p);
        }
        closedir(d);
    }
    rmdir(g_dir);
    return 0;
}

static char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    assert_int_equal(fseek(f, 0, SEEK_END), 0);
    long n = ftell(f);
    assert_true(n >= 0);
    rewind(f);
    char *p = malloc((size_t)n + 1);
    assert_non_null(p);
    assert_int_equal(fread(p, 1, (size_t)n, f), (size_t)n);
    p[n] = '\0';
    fclose(f);
    if (len)
        *len = (size_t)n;
    return p;
}

/* Independent base64 decoder (returns decoded length, -1 on bad input). */
static long b64_decode(const char *in, size_t n, unsigned char *out)
{
    if (n % 4)
        return -1;
    long o = 0;
    for (size_t i = 0; i < n; i += 4) {
        int v[4], pad = 0;
        for (int k = 0; k < 4; k++) {
            char c = in[i + k];
            if (c >= 'A' && c <= 'Z')
                v[k] = c - 'A';
            else if (c >= 'a' && c <= 'z')
                v[k] = c - 'a' + 26;
            else if (c >= '0' && c <= '9')
                v[k] = c - '0' + 52;
            else if (c == '+')
                v[k] = 62;
            else if (c == '/')
                v[k] = 63;
            else if (c == '=' && i + 4 == n && k >= 2) {
                v[k] = 0;
                pad++;
            } else
                return -1;
        }
        uint32_t w = (uint32_t)v[0] << 18 | (uint32_t)v[1] << 12 | (uint32_t)v[2] << 6 | (uint32_t)v[3];
        out[o++] = (unsigned char)(w >> 16);
        if (pad < 2)
            out[o++] = (unsigned char)(w >> 8);
        if (pad < 1)
            out[o++] = (unsigned char)w;
    }
    return o;
}

/* Rotate v by unit quaternion q = (x, y, z, w): v' = v + 2 w (u x v) + 2 u x (u x v). */
static void qrot(const float q[4], const double v[3], double r[3])
{
    double u[3] = {q[0], q[1], q[2]}, w = q[3];
    double t[3] = {2 * (u[1] * v[2] - u[2] * v[1]), 2 * (u[2] * v[0] - u[0] * v[2]),
                   2 * (u[0] * v[1] - u[1] * v[0])};
    r[0] = v[0] + w * t[0] + (u[1] * t[2] - u[2] * t[1]);
    r[1] = v[1] + w * t[1] + (u[2] * t[0] - u[0] * t[2]);
    r[2] = v[2] + w * t[2] + (u[0] * t[1] - u[1] * t[0]);
}

static void unit3(const float *in, double out[3])
{
    double l = sqrt((double)in[0] * in[0] + (double)in[1] * in[1] + (double)in[2] * in[2]);
    for (int k = 0; k < 3; k++)
        out[k] = in[k] / l;
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double *a, const double *b, double *r)
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

/* ---- base64 ------------------------------------------------------------- */

static void test_base64_vectors(void **state)
{
    (void)state;
    /* RFC 4648 section 10. */
    static const char *const in[] = {"", "f", "fo", "foo", "foob", "fooba", "foobar"};
    static const char *const want[] = {"", "Zg==", "Zm8=", "Zm9v", "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy"};
    char out[64];
    for (int i = 0; i < 7; i++) {
        memset(out, 'X', sizeof out);
        size_t n = gi_gltf_base64_encode((const unsigned char *)in[i], strlen(in[i]), out);
        assert_int_equal(n, strlen(want[i]));
        assert_string_equal(out, want[i]);
    }
    /* High bytes exercise '+' and '/'. */
    const unsigned char hi[] = {0xfb, 0xff, 0xbf, 0xff, 0xfe};
    size_t n = gi_gltf_base64_encode(hi, sizeof hi, out);
    assert_int_equal(n, 8);
    assert_string_equal(out, "+/+///4=");
    /* Every byte value and every length mod 3 decodes back. */
    unsigned char all[256], back[256];
    for (int i = 0; i < 256; i++)
        all[i] = (unsigned char)(i * 37 + 11);
    char enc[4 * 86 + 1];
    for (size_t len = 250; len <= 256; len++) {
        size_t m = gi_gltf_base64_encode(all, len, enc);
        assert_int_equal(m, 4 * ((len + 2) / 3));
        assert_int_equal(strlen(enc), m);
        assert_int_equal(b64_decode(enc, m, back), (long)len);
        assert_memory_equal(all, back, len);
    }
}

/* ---- rotations ------------------------------------------------------------ */

static void test_quat_from_dir(void **state)
{
    (void)state;
    static const float dirs[][3] = {
        {0, 0, 1},     {0, 0, -1},     {0, 1, 0},      {0, -1, 0},      {1, 0, 0},
        {-1, 0, 0},    {1, 1, 1},      {-2, 0.5f, -3}, {0.3f, -4, 0.2f}, {1e-4f, 0, 1},
        {0, 1e-8f, 1}, {1e-7f, 0, -1}, {0, 0, 7},      {0, -5, 0},      {-1e-6f, -1e-6f, 1},
    };
    const double mz[3] = {0, 0, -1};
    for (size_t i = 0; i < sizeof dirs / sizeof dirs[0]; i++) {
        float q[4];
        assert_int_equal(gi_gltf_quat_from_dir(dirs[i], q), 0);
        double qn = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] +
                         (double)q[3] * q[3]);
        assert_true(fabs(qn - 1.0) < 1e-6);
        double d[3], r[3];
        unit3(dirs[i], d);
        qrot(q, mz, r);
        for (int k = 0; k < 3; k++) {
            if (fabs(r[k] - d[k]) > 2e-6)
                fail_msg("dir %zu (%g %g %g): -Z maps to (%g %g %g)", i, (double)dirs[i][0],
                         (double)dirs[i][1], (double)dirs[i][2], r[0], r[1], r[2]);
        }
    }
    float q[4];
    const float zero[3] = {0, 0, 0}, bad[3] = {NAN, 0, 1};
    assert_int_equal(gi_gltf_quat_from_dir(zero, q), -1);
    assert_true(q[3] == 1.0f && q[0] == 0.0f);
    assert_int_equal(gi_gltf_quat_from_dir(bad, q), -1);
}

static void test_quat_look_at(void **state)
{
    (void)state;
    static const float fwd[][3] = {
        {0, 0, 1},  {0, 0, -1}, {0, 1, 0}, {0, -1, 0}, {1, 0, 0},      {-1, 0, 0},
        {1, 2, 3},  {-3, -1, 2}, {0, 1e-7f, 1}, {1e-7f, -1, 0}, {0.2f, -0.9f, 0.1f},
    };
    static const float ups[][3] = {{0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {0, 0, 0}};
    const double mz[3] = {0, 0, -1}, py[3] = {0, 1, 0}, px[3] = {1, 0, 0};
    for (size_t i = 0; i < sizeof fwd / sizeof fwd[0]; i++) {
        for (size_t j = 0; j < sizeof ups / sizeof ups[0]; j++) {
            float q[4];
            assert_int_equal(gi_gltf_quat_look_at(fwd[i], ups[j], q), 0);
            double f[3], rf[3], ru[3], rr[3], c[3];
            unit3(fwd[i], f);
            qrot(q, mz, rf);
            qrot(q, py, ru);
            qrot(q, px, rr);
            for (int k = 0; k < 3; k++)
                if (fabs(rf[k] - f[k]) > 2e-6)
                    fail_msg("forward %zu up %zu: -Z maps to (%g %g %g)", i, j, rf[0], rf[1], rf[2]);
            assert_true(fabs(dot3(ru, rf)) < 2e-6);
            assert_true(fabs(dot3(ru, ru) - 1.0) < 4e-6);
            /* Right-handed: image right = forward x up. */
            cross3(rf, ru, c);
            for (int k = 0; k < 3; k++)
                assert_true(fabs(c[k] - rr[k]) < 4e-6);
            /* Up lies in the plane of forward and the hint, on the hint's side,
             * unless the hint is zero or parallel to forward. */
            double h[3] = {ups[j][0], ups[j][1], ups[j][2]};
            double hl = sqrt(dot3(h, h));
            if (hl > 0) {
                double hc[3];
                cross3(f, h, hc);
                if (sqrt(dot3(hc, hc)) > 1e-3 * hl) {
                    double pu = dot3(ru, h) / hl;
                    double expect = sqrt(dot3(hc, hc)) / hl; /* |h - (h.f) f| / |h| */
                    if (fabs(pu - expect) > 1e-5)
                        fail_msg("forward %zu up %zu: up . hint %g, expected %g", i, j, pu, expect);
                }
            }
        }
    }
    /* Looking straight down with +Y as the hint still gives a valid frame. */
    const float down[3] = {0, -1, 0}, upy[3] = {0, 1, 0};
    float q[4];
    assert_int_equal(gi_gltf_quat_look_at(down, upy, q), 0);
    const float zero[3] = {0, 0, 0};
    assert_int_equal(gi_gltf_quat_look_at(zero, upy, q), -1);
}

/* ---- writing ------------------------------------------------------------ */

/* A small scene exercising every builder call; returns the builder. */
static gi_gltf_builder *small_scene(void)
{
    gi_gltf_builder *b = gi_gltf_builder_new();
    assert_non_null(b);
    const float white[3] = {0.8f, 0.7f, 0.6f}, black[3] = {0, 0, 0};
    const float emis[3] = {10.0f, 5.0f, 2.5f};
    int m0 = gi_gltf_add_material(b, "wall \"A\"\\", white, 0.5f, 0.25f, NULL, 0);
    int m1 = gi_gltf_add_material(b, "lamp", black, 1.0f, 0.0f, emis, 1);
    int m2 = gi_gltf_add_material(b, "room", white, 1.0f, 0.0f, NULL, 1);
    int m3 = gi_gltf_add_material(b, "unused", white, 1.0f, 0.0f, NULL, 1);
    assert_int_equal(m0, 0);
    assert_int_equal(m1, 1);
    assert_int_equal(m2, 2);
    assert_int_equal(m3, 3);
    const float a[3] = {0.1f, 0.2f, 0.3f}, bb[3] = {1.1f, 0.2f, 0.3f}, c[3] = {0.1f, 1.7f, 0.3f};
    gi_gltf_add_triangle(b, a, bb, c, m0);
    const float l0[3] = {-0.25f, 1.99f, -0.25f}, l1[3] = {0.25f, 1.99f, -0.25f};
    const float l2[3] = {0.25f, 1.99f, 0.25f}, l3[3] = {-0.25f, 1.99f, 0.25f};
    gi_gltf_add_quad(b, l0, l1, l2, l3, m1); /* (+x then +z from l0): faces down (-y) */
    const float lo[3] = {-1, 0, -1}, hi[3] = {1, 2, 1};
    gi_gltf_add_box(b, lo, hi, m2, 1);
    const float pp[3] = {0.5f, 1.5f, -0.5f}, pc[3] = {1.0f, 0.5f, 0.25f};
    gi_gltf_add_point_light(b, "bulb", pp, pc, 7.0f);
    const float sp[3] = {0, 1.8f, 0}, sd[3] = {0, -2, 0}, wc[3] = {1, 1, 1};
    gi_gltf_add_spot_light(b, "spot down", sp, sd, wc, 3.0f, 0.2f, 0.5f);
    const float sd2[3] = {0, 0, 1};
    gi_gltf_add_spot_light(b, "spot +z", sp, sd2, wc, 1.5f, 0.0f, 0.3f);
    const float dd[3] = {1, -1, 0.5f};
    gi_gltf_add_directional_light(b, "sun", dd, wc, 1000.0f);
    const float dd2[3] = {0, 0, -1};
    gi_gltf_add_directional_light(b, "sun -z", dd2, pc, 50.0f);
    const float cp[3] = {0.5f, 1.0f, -2.0f}, ct[3] = {0, 0.5f, 0}, cu[3] = {0, 1, 0};
    gi_gltf_add_camera(b, "cam", cp, ct, cu, 0.8f, 1.5f);
    const float dp[3] = {0, 1.9f, 0}, dt[3] = {0, 0, 0};
    gi_gltf_add_camera(b, "top", dp, dt, cu, 1.0f, 0.0f);
    assert_int_equal(gi_gltf_builder_triangles(b), 1 + 2 + 12);
    return b;
}

static void test_write_deterministic(void **state)
{
    (void)state;
    char p1[512], p2[512];
    path_in(p1, sizeof p1, "a.gltf");
    path_in(p2, sizeof p2, "b.gltf");
    gi_status st = {0};
    gi_gltf_builder *b = small_scene();
    assert_int_equal(gi_gltf_builder_write(b, p1, &st), 0);
    assert_int_equal(gi_gltf_builder_write(b, p2, &st), 0);
    gi_gltf_builder_free(b);
    /* A second builder with the same calls gives the same bytes too. */
    b = small_scene();
    assert_int_equal(gi_gltf_builder_write(b, p1, &st), 0); /* overwrite in place */
    gi_gltf_builder_free(b);
    size_t n1, n2;
    char *t1 = slurp(p1, &n1), *t2 = slurp(p2, &n2);
    assert_true(n1 > 1000);
    assert_int_equal(n1, n2);
    assert_memory_equal(t1, t2, n1);
    /* JSON escaping of the material name, extensions declared. */
    assert_non_null(strstr(t1, "\"name\":\"wall \\\"A\\\"\\\\\""));
    assert_non_null(strstr(t1, "\"KHR_lights_punctual\""));
    assert_non_null(strstr(t1, "\"KHR_materials_emissive_strength\""));
    assert_non_null(strstr(t1, "\"emissiveStrength\":10"));
    assert_non_null(strstr(t1, "\"emissiveFactor\":[1,0.5,0.25]"));
    free(t1);
    free(t2);
    assert_int_equal(count_entries(g_dir, ".tmp."), 0);
}

static void test_control_chars_escaped(void **state)
{
    (void)state;
    char p[512];
    path_in(p, sizeof p, "esc.gltf");
    gi_gltf_builder *b = gi_gltf_builder_new();
    const float w[3] = {1, 1, 1};
    gi_gltf_add_material(b, "a\nb\tc\x01" "d/\xc3\xa9", w, 1, 0, NULL, 1);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, p, &st), 0);
    gi_gltf_builder_free(b);
    char *t = slurp(p, NULL);
    assert_non_null(strstr(t, "\"a\\nb\\tc\\u0001d/\xc3\xa9\""));
    for (const char *c = t; *c; c++)
        assert_true((unsigned char)*c >= 0x20 || *c == '\n');
    free(t);
}

/* Find `key` after `from` and parse the unsigned number after it. */
static size_t num_after(const char *from, const char *key)
{
    const char *s = strstr(from, key);
    assert_non_null(s);
    return (size_t)strtoull(s + strlen(key), NULL, 10);
}

static float getf(const unsigned char *p)
{
    uint32_t v = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &v, sizeof f);
    return f;
}

/* The embedded buffer, decoded: meshes in material order, each positions,
 * normals, indices (the layout the header documents). */
static void test_buffer_contents(void **state)
{
    (void)state;
    char p[512];
    path_in(p, sizeof p, "buf.gltf");
    gi_gltf_builder *b = gi_gltf_builder_new();
    const float w[3] = {0.5f, 0.5f, 0.5f};
    int out = gi_gltf_add_material(b, "out", w, 1, 0, NULL, 1);
    int in = gi_gltf_add_material(b, "in", w, 1, 0, NULL, 1);
    const float lo[3] = {-1.0f, 0.5f, 2.0f}, hi[3] = {3.0f, 1.0f, 2.25f};
    gi_gltf_add_box(b, lo, hi, out, 0);
    gi_gltf_add_box(b, lo, hi, in, 1);
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, p, &st), 0);
    gi_gltf_builder_free(b);
    char *t = slurp(p, NULL);
    /* Position accessor bounds are the box corners. */
    assert_non_null(strstr(t, "\"min\":[-1,0.5,2],\"max\":[3,1,2.25]"));
    const char *buffers = strstr(t, "\"buffers\":");
    assert_non_null(buffers);
    size_t len = num_after(buffers, "\"byteLength\":");
    const char *uri = strstr(buffers, "base64,");
    assert_non_null(uri);
    uri += 7;
    const char *end = strchr(uri, '"');
    assert_non_null(end);
    unsigned char *bin = malloc((size_t)(end - uri));
    assert_non_null(bin);
    assert_int_equal(b64_decode(uri, (size_t)(end - uri), bin), (long)len);
    assert_int_equal(len, 2 * 36 * (12 + 12 + 4));
    const double centre[3] = {1.0, 0.75, 2.125};
    for (int mesh = 0; mesh < 2; mesh++) {
        const unsigned char *pos = bin + mesh * 36 * 28, *nrm = pos + 36 * 12, *idx = nrm + 36 * 12;
        double area = 0.0;
        for (int tri = 0; tri < 12; tri++) {
            double v[3][3], c[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++) {
                uint32_t ix = (uint32_t)idx[(3 * tri + k) * 4] | (uint32_t)idx[(3 * tri + k) * 4 + 1] << 8;
                assert_true(ix < 36);
                for (int j = 0; j < 3; j++) {
                    v[k][j] = getf(pos + (ix * 3 + j) * 4);
                    c[j] += v[k][j] / 3;
                }
            }
            double e1[3], e2[3], n[3], d[3];
            for (int j = 0; j < 3; j++) {
                e1[j] = v[1][j] - v[0][j];
                e2[j] = v[2][j] - v[0][j];
                d[j] = c[j] - centre[j];
            }
            cross3(e1, e2, n);
            area += 0.5 * sqrt(dot3(n, n));
            /* outward box: winding normal away from the centre; inward: towards. */
            assert_true(mesh == 0 ? dot3(n, d) > 0 : dot3(n, d) < 0);
            for (int k = 0; k < 3; k++) {
                double sn[3];
                for (int j = 0; j < 3; j++)
                    sn[j] = getf(nrm + ((3 * tri + k) * 3 + j) * 4);
                assert_true(fabs(dot3(sn, sn) - 1.0) < 1e-6);
                assert_true(dot3(sn, n) / sqrt(dot3(n, n)) > 1.0 - 1e-6);
            }
        }
        double want = 2.0 * (4.0 * 0.5 + 4.0 * 0.25 + 0.5 * 0.25);
        assert_true(fabs(area - want) < 1e-5);
    }
    free(bin);
    free(t);
}

static void test_errors_leave_no_file(void **state)
{
    (void)state;
    char p[512];
    gi_status st = {0};
    const float w[3] = {1, 1, 1}, a[3] = {0, 0, 0}, b1[3] = {1, 0, 0}, c[3] = {0, 1, 0};

    /* Unknown material index: a usage error, nothing written. */
    path_in(p, sizeof p, "bad-material.gltf");
    gi_gltf_builder *b = gi_gltf_builder_new();
    gi_gltf_add_material(b, "m", w, 1, 0, NULL, 1);
    gi_gltf_add_triangle(b, a, b1, c, 5);
    assert_int_equal(gi_gltf_builder_write(b, p, &st), GI_EXIT_USAGE);
    assert_non_null(strstr(st.msg, "material index 5"));
    assert_non_null(strstr(st.msg, p));
    gi_gltf_builder_free(b);
    assert_int_equal(count_entries(g_dir, "bad-material"), 0);

    /* Non-finite vertex and bad cone angles are refused. */
    b = gi_gltf_builder_new();
    int m = gi_gltf_add_material(b, "m", w, 1, 0, NULL, 1);
    const float nan3[3] = {0, NAN, 0};
    gi_gltf_add_triangle(b, a, nan3, c, m);
    st.code = 0;
    assert_int_equal(gi_gltf_builder_write(b, p, &st), GI_EXIT_USAGE);
    gi_gltf_builder_free(b);
    b = gi_gltf_builder_new();
    const float down[3] = {0, -1, 0};
    gi_gltf_add_spot_light(b, "s", a, down, w, 1.0f, 0.6f, 0.5f);
    assert_int_equal(gi_gltf_builder_write(b, p, &st), GI_EXIT_USAGE);
    assert_non_null(strstr(st.msg, "'s'"));
    gi_gltf_builder_free(b);
    b = gi_gltf_builder_new();
    const float over[3] = {1.5f, 0, 0};
    assert_int_equal(gi_gltf_add_material(b, "hot", over, 1, 0, NULL, 1), -1);
    assert_int_equal(gi_gltf_builder_write(b, p, &st), GI_EXIT_USAGE);
    gi_gltf_builder_free(b);
    assert_int_equal(count_entries(g_dir, "bad-material"), 0);

    /* Directory that does not exist: system error, no temp file anywhere. */
    snprintf(p, sizeof p, "%s/no-such-dir/x.gltf", g_dir);
    b = gi_gltf_builder_new();
    gi_gltf_add_material(b, "m", w, 1, 0, NULL, 1);
    gi_gltf_add_triangle(b, a, b1, c, 0);
    assert_int_equal(gi_gltf_builder_write(b, p, &st), GI_EXIT_SYSTEM);
    assert_non_null(strstr(st.msg, "no-such-dir"));
    gi_gltf_builder_free(b);
    assert_int_equal(count_entries(g_dir, ".tmp."), 0);

    /* Target is a directory: rename fails, the temp file is removed. */
    path_in(p, sizeof p, "adir");
    assert_int_equal(mkdir(p, 0755), 0);
    b = gi_gltf_builder_new();
    gi_gltf_add_material(b, "m", w, 1, 0, NULL, 1);
    gi_gltf_add_triangle(b, a, b1, c, 0);
    assert_int_equal(gi_gltf_builder_write(b, p, &st), GI_EXIT_SYSTEM);
    gi_gltf_builder_free(b);
    assert_int_equal(count_entries(g_dir, ".tmp."), 0);
    assert_int_equal(rmdir(p), 0);
}

/* An empty builder still writes valid glTF (no empty arrays). */
static void test_empty_scene(void **state)
{
    (void)state;
    char p[512];
    path_in(p, sizeof p, "empty.gltf");
    gi_gltf_builder *b = gi_gltf_builder_new();
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, p, &st), 0);
    gi_gltf_builder_free(b);
    char *t = slurp(p, NULL);
    assert_non_null(strstr(t, "\"version\":\"2.0\""));
    assert_null(strstr(t, "[]"));
    assert_null(strstr(t, "\"buffers\""));
    free(t);
    gi_gltf_builder_free(NULL);
}

/* ---- round trip through the loader ---------------------------------------- */
#ifndef GI_TEST_NO_LOADER

static const gi_light *find_light(const gi_scene *s, const char *name)
{
    for (size_t i = 0; i < s->num_lights; i++)
        if (!strcmp(s->lights[i].name, name))
            return &s->lights[i];
    fail_msg("light '%s' not loaded", name);
    return NULL;
}

static void near3(const float *got, double x, double y, double z, double tol, const char *what)
{
    if (fabs(got[0] - x) > tol || fabs(got[1] - y) > tol || fabs(got[2] - z) > tol)
        fail_msg("%s: got (%.9g %.9g %.9g), want (%.9g %.9g %.9g)", what, (double)got[0],
                 (double)got[1], (double)got[2], x, y, z);
}

static void test_round_trip(void **state)
{
    (void)state;
    char p[512];
    path_in(p, sizeof p, "rt.gltf");
    gi_gltf_builder *b = small_scene();
    gi_status st = {0};
    assert_int_equal(gi_gltf_builder_write(b, p, &st), 0);
    gi_gltf_builder_free(b);

    gi_scene *s = NULL;
    int rc = gi_scene_load(p, &s, &st);
    if (rc)
        fail_msg("gi_scene_load: %s", st.msg);
    assert_non_null(s);
    for (size_t i = 0; i < s->num_warnings; i++)
        print_message("loader warning: %s\n", s->warnings[i]);
    assert_int_equal(s->num_warnings, 0); /* the writer uses only supported features */
    assert_int_equal(s->num_triangles, 15);

    /* Materials: by name, values exact (the writer prints %.9g). */
    int mw = gi_scene_find_material(s, "wall \"A\"\\");
    int ml = gi_scene_find_material(s, "lamp");
    int mr = gi_scene_find_material(s, "room");
    assert_true(mw >= 0 && ml >= 0 && mr >= 0);
    const gi_material *w = &s->materials[mw], *l = &s->materials[ml];
    near3(w->base_color, 0.8f, 0.7f, 0.6f, 0.0, "wall base colour");
    assert_true(w->roughness == 0.5f && w->metallic == 0.25f);
    assert_int_equal(w->double_sided, 0);
    near3(w->emission, 0, 0, 0, 0.0, "wall emission");
    near3(l->emission, 10, 5, 2.5, 1e-5, "lamp emission (nits)");
    assert_int_equal(l->double_sided, 1);
    assert_true(s->materials[mr].roughness == 1.0f);

    /* Triangles: count per material, winding normals, stored normals agree. */
    int count[3] = {0, 0, 0};
    int seen_tri = 0;
    for (size_t t = 0; t < s->num_triangles; t++) {
        uint32_t mat = s->tri_material[t];
        assert_true(mat < s->num_materials);
        const uint32_t *ix = &s->indices[3 * t];
        double v[3][3];
        for (int k = 0; k < 3; k++) {
            assert_true(ix[k] < s->num_vertices);
            for (int j = 0; j < 3; j++)
                v[k][j] = s->positions[3 * ix[k] + j];
        }
        double e1[3], e2[3], n[3], c[3];
        for (int j = 0; j < 3; j++) {
            e1[j] = v[1][j] - v[0][j];
            e2[j] = v[2][j] - v[0][j];
            c[j] = (v[0][j] + v[1][j] + v[2][j]) / 3.0;
        }
        cross3(e1, e2, n);
        double nl = sqrt(dot3(n, n));
        assert_true(nl > 0);
        for (int k = 0; k < 3; k++) {
            const float *sn = &s->normals[3 * ix[k]];
            double snd[3] = {sn[0], sn[1], sn[2]};
            assert_true(dot3(snd, n) / nl > 1.0 - 1e-5);
        }
        if ((int)mat == mw) {
            count[0]++;
            /* The single triangle, exact positions, counter-clockwise seen from +z. */
            const double want[3][3] = {{0.1f, 0.2f, 0.3f}, {1.1f, 0.2f, 0.3f}, {0.1f, 1.7f, 0.3f}};
            for (int r = 0; r < 3; r++) /* any rotation of the corner order */
                if (!memcmp(v[0], want[r], sizeof v[0]) && !memcmp(v[1], want[(r + 1) % 3], sizeof v[0]) &&
                    !memcmp(v[2], want[(r + 2) % 3], sizeof v[0]))
                    seen_tri = 1;
            assert_true(n[2] > 0);
        } else if ((int)mat == ml) {
            count[1]++;
            assert_true(n[1] < 0); /* the lamp quad faces down */
            assert_true(fabs(c[1] - 1.99f) < 1e-6);
        } else if ((int)mat == mr) {
            count[2]++;
            /* inward box around (0, 1, 0): normals point to the centre. */
            double d[3] = {-c[0], 1.0 - c[1], -c[2]};
            assert_true(dot3(n, d) > 0);
        } else {
            fail_msg("triangle %zu has unexpected material %u", t, mat);
        }
    }
    assert_true(seen_tri);
    assert_int_equal(count[0], 1);
    assert_int_equal(count[1], 2);
    assert_int_equal(count[2], 12);
    near3(s->bbox_min, -1, 0, -1, 0.0, "bbox min");
    near3(s->bbox_max, 1.1f, 2, 1, 0.0, "bbox max"); /* the single triangle reaches x = 1.1 */

    /* Lights. */
    assert_int_equal(s->num_lights, 5);
    const gi_light *bulb = find_light(s, "bulb");
    assert_int_equal(bulb->type, GI_LIGHT_POINT);
    near3(bulb->position, 0.5f, 1.5f, -0.5f, 0.0, "bulb position");
    near3(bulb->color, 1.0, 0.5, 0.25, 0.0, "bulb colour");
    assert_true(bulb->intensity == 7.0f);
    const gi_light *sdown = find_light(s, "spot down");
    assert_int_equal(sdown->type, GI_LIGHT_SPOT);
    near3(sdown->position, 0, 1.8f, 0, 0.0, "spot position");
    near3(sdown->direction, 0, -1, 0, 1e-6, "spot direction");
    assert_true(sdown->intensity == 3.0f);
    assert_true(fabsf(sdown->inner_cone - 0.2f) < 1e-7f && fabsf(sdown->outer_cone - 0.5f) < 1e-7f);
    const gi_light *spz = find_light(s, "spot +z");
    near3(spz->direction, 0, 0, 1, 1e-6, "spot +z direction");
    assert_true(spz->inner_cone == 0.0f && fabsf(spz->outer_cone - 0.3f) < 1e-7f);
    const gi_light *sun = find_light(s, "sun");
    assert_int_equal(sun->type, GI_LIGHT_DIRECTIONAL);
    near3(sun->direction, 1 / 1.5, -1 / 1.5, 0.5 / 1.5, 1e-6, "sun direction");
    assert_true(sun->intensity == 1000.0f);
    const gi_light *sunz = find_light(s, "sun -z");
    near3(sunz->direction, 0, 0, -1, 1e-6, "sun -z direction");
    near3(sunz->color, 1.0, 0.5, 0.25, 0.0, "sun -z colour");

    /* Cameras. */
    assert_int_equal(s->num_cameras, 2);
    const gi_camera *cam = &s->cameras[0], *top = &s->cameras[1];
    assert_string_equal(cam->name, "cam");
    near3(cam->position, 0.5f, 1.0f, -2.0f, 1e-7, "camera position");
    double f[3] = {-0.5, -0.5, 2.0};
    double fl = sqrt(dot3(f, f));
    near3(cam->forward, f[0] / fl, f[1] / fl, f[2] / fl, 1e-6, "camera forward");
    double up[3] = {cam->up[0], cam->up[1], cam->up[2]}, fw[3] = {cam->forward[0], cam->forward[1], cam->forward[2]};
    assert_true(fabs(dot3(up, fw)) < 1e-6);
    assert_true(up[1] > 0.9);  /* +Y hint: the up vector is nearly +Y */
    assert_true(fabs(up[0] * f[2] - up[2] * f[0]) < 1e-5);  /* in the plane of f and +Y */
    assert_true(fabsf(cam->yfov - 0.8f) < 1e-7f);
    assert_true(fabsf(cam->aspect - 1.5f) < 1e-7f);
    assert_string_equal(top->name, "top");
    near3(top->forward, 0, -1, 0, 1e-6, "top camera forward");
    assert_true(top->aspect == 0.0f);
    gi_scene_free(s);
}
#endif

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_base64_vectors),
        cmocka_unit_test(test_quat_from_dir),
        cmocka_unit_test(test_quat_look_at),
        cmocka_unit_test(test_write_deterministic),
        cmocka_unit_test(test_control_chars_escaped),
        cmocka_unit_test(test_buffer_contents),
        cmocka_unit_test(test_errors_leave_no_file),
        cmocka_unit_test(test_empty_scene),
#ifndef GI_TEST_NO_LOADER
        cmocka_unit_test(test_round_trip),
#endif
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
