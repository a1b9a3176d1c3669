/* test_image.c - gi_image: EXR/PNG round trips, metadata, errors, no temp files left. */
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

#include "gi_image.h"

static char g_dir[256];

static void path_in(char *buf, size_t cap, const char *name)
{
    snprintf(buf, cap, "%s/%s", g_dir, name);
}

/* Number of entries in dir whose name contains ".tmp.". */
static int count_temps(const char *dir)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strstr(e->d_name, ".tmp."))
            n++;
    closedir(d);
    return n;
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/gi_test_image.XXXXXX");
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
            if (unlink(p) != 0)
                rmdir(p);
        }
        closedir(d);
    }
    return rmdir(g_dir);
}

static void test_init_release(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image z;
    memset(&z, 0, sizeof z);
    gi_image_release(&z); /* zeroed struct is fine */
    gi_image_release(NULL);
    gi_image im;
    assert_int_equal(gi_image_init(&im, 3, 2, 3, &st), 0);
    assert_int_equal(im.width, 3);
    assert_int_equal(im.height, 2);
    assert_int_equal(im.channels, 3);
    for (int i = 0; i < 18; i++)
        assert_true(im.pixels[i] == 0.0f);
    gi_image_release(&im);
    assert_null(im.pixels);
    assert_int_equal(gi_image_init(&im, 0, 2, 3, &st), GI_EXIT_DATA);
    assert_int_equal(gi_image_init(&im, 2, 2, 5, &st), GI_EXIT_DATA);
    assert_null(im.pixels);
}

/* Values EXR half would not keep: many mantissa bits, large, tiny, negative. */
static float tricky(int i)
{
    switch (i % 7) {
    case 0: return 0.1f * (float)i;
    case 1: return 1.0f / 3.0f + (float)i;
    case 2: return -12345.678f;
    case 3: return 1.0e-30f;
    case 4: return 3.0e20f;
    case 5: return (float)i * 1.000001f;
    default: return 0.0f;
    }
}

static void roundtrip_exr(int w, int h, int nc)
{
    gi_status st = {0};
    gi_image im = {0}, back = {0};
    assert_int_equal(gi_image_init(&im, w, h, nc, &st), 0);
    size_t n = (size_t)w * (size_t)h * (size_t)nc;
    for (size_t i = 0; i < n; i++)
        im.pixels[i] = tricky((int)i);
    char p[512];
    snprintf(p, sizeof p, "%s/rt%d.exr", g_dir, nc);
    int rc = gi_image_write_exr(p, &im, NULL, 0, &st);
    if (rc)
        fail_msg("write: %s", st.msg);
    rc = gi_image_read(p, &back, &st);
    if (rc)
        fail_msg("read: %s", st.msg);
    assert_int_equal(back.width, w);
    assert_int_equal(back.height, h);
    assert_int_equal(back.channels, nc);
    assert_memory_equal(back.pixels, im.pixels, n * sizeof(float));
    gi_image_release(&im);
    gi_image_release(&back);
    assert_int_equal(count_temps(g_dir), 0);
}

static void test_exr_roundtrip_rgb(void **state) { (void)state; roundtrip_exr(37, 23, 3); }
static void test_exr_roundtrip_gray(void **state) { (void)state; roundtrip_exr(5, 9, 1); }
static void test_exr_roundtrip_rgba(void **state) { (void)state; roundtrip_exr(16, 4, 4); }

static void test_exr_overwrite(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image a = {0}, back = {0};
    char p[512];
    path_in(p, sizeof p, "over.exr");
    assert_int_equal(gi_image_init(&a, 2, 2, 3, &st), 0);
    a.pixels[0] = 1.0f;
    assert_int_equal(gi_image_write_exr(p, &a, NULL, 0, &st), 0);
    a.pixels[0] = 2.0f;
    assert_int_equal(gi_image_write_exr(p, &a, NULL, 0, &st), 0);
    assert_int_equal(gi_image_read(p, &back, &st), 0);
    assert_true(back.pixels[0] == 2.0f);
    gi_image_release(&a);
    gi_image_release(&back);
}

static void test_meta_roundtrip(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0};
    assert_int_equal(gi_image_init(&im, 4, 4, 3, &st), 0);
    const char *cmd = "gi-relight -o out.exr --seed 7 scene.gltf \"quoted, with commas\"";
    gi_image_meta meta[] = {{"tool", "gi-relight 0.1.0"}, {"cmdline", cmd}, {"empty", ""}};
    char p[512];
    path_in(p, sizeof p, "meta.exr");
    /* an empty value would be dropped by the EXR writer: refused, nothing written */
    assert_int_equal(gi_image_write_exr(p, &im, meta, 3, &st), GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "gi:empty"));
    assert_int_equal(access(p, F_OK), -1);
    assert_int_equal(count_temps(g_dir), 0);
    int rc = gi_image_write_exr(p, &im, meta, 2, &st);
    if (rc)
        fail_msg("write: %s", st.msg);
    char v[256];
    assert_int_equal(gi_image_read_meta(p, "tool", v, sizeof v, &st), 0);
    assert_string_equal(v, "gi-relight 0.1.0");
    assert_int_equal(gi_image_read_meta(p, "cmdline", v, sizeof v, &st), 0);
    assert_string_equal(v, cmd);
    /* absent key */
    assert_int_equal(gi_image_read_meta(p, "nonesuch", v, sizeof v, &st), GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "gi:nonesuch"));
    assert_non_null(strstr(st.msg, "meta.exr"));
    /* too small a buffer is refused, not truncated silently */
    char small[8];
    assert_int_equal(gi_image_read_meta(p, "tool", small, sizeof small, &st), GI_EXIT_DATA);
    gi_image_release(&im);
}

/* Read a PNG back and return its bytes at pixel i, channel c (0..255). */
static int png_byte(const gi_image *im, int i, int c)
{
    return (int)lrintf(im->pixels[i * im->channels + c] * 255.0f);
}

static void test_png_srgb_values(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0}, back = {0};
    assert_int_equal(gi_image_init(&im, 6, 1, 3, &st), 0);
    const float in[6] = {0.0f, 0.5f, 1.0f, 0.25f, 7.0f, -1.0f};
    for (int i = 0; i < 6; i++)
        for (int c = 0; c < 3; c++)
            im.pixels[i * 3 + c] = in[i];
    im.pixels[3 * 3 + 1] = 0.001f; /* linear segment: 12.92 * 0.002 * 255 = 6.59 -> 7 */
    char p[512];
    path_in(p, sizeof p, "srgb.png");
    /* exposure 2: 0.5 -> 1, 0.25 -> 0.5 */
    int rc = gi_image_write_png_srgb(p, &im, 2.0f, &st);
    if (rc)
        fail_msg("write: %s", st.msg);
    assert_int_equal(gi_image_read(p, &back, &st), 0);
    assert_int_equal(back.channels, 3);
    assert_int_equal(back.width, 6);
    assert_int_equal(png_byte(&back, 0, 0), 0);
    assert_int_equal(png_byte(&back, 1, 0), 255);
    assert_int_equal(png_byte(&back, 3, 0), 188);
    assert_int_equal(png_byte(&back, 3, 1), 7);
    assert_int_equal(png_byte(&back, 4, 2), 255); /* clamped */
    assert_int_equal(png_byte(&back, 5, 2), 0);   /* clamped */
    gi_image_release(&back);
    /* exposure 1: the canonical 0 -> 0, 0.5 -> 188, 1 -> 255 */
    assert_int_equal(gi_image_write_png_srgb(p, &im, 1.0f, &st), 0);
    assert_int_equal(gi_image_read(p, &back, &st), 0);
    assert_int_equal(png_byte(&back, 0, 1), 0);
    assert_int_equal(png_byte(&back, 1, 1), 188);
    assert_int_equal(png_byte(&back, 2, 1), 255);
    assert_true(fabsf(gi_image_srgb_encode(0.5f) - 0.735357f) < 1e-5f);
    gi_image_release(&back);
    gi_image_release(&im);
}

static void test_png_gray_to_rgb(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0}, back = {0};
    assert_int_equal(gi_image_init(&im, 2, 1, 1, &st), 0);
    im.pixels[0] = 0.5f;
    im.pixels[1] = NAN;
    char p[512];
    path_in(p, sizeof p, "gray.png");
    assert_int_equal(gi_image_write_png_srgb(p, &im, 1.0f, &st), 0);
    assert_int_equal(gi_image_read(p, &back, &st), 0);
    assert_int_equal(back.channels, 3);
    assert_int_equal(png_byte(&back, 0, 2), 188);
    assert_int_equal(png_byte(&back, 1, 0), 0);
    gi_image_release(&back);
    gi_image_release(&im);
}

static void test_png_linear_quantise(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0}, back = {0};
    assert_int_equal(gi_image_init(&im, 2, 2, 4, &st), 0);
    const float v[16] = {0.5f, 0.0f, 1.0f, 1.0f, 2.0f / 255.0f, -3.0f, 9.0f, 0.25f,
                         0.1f, 0.2f,  0.3f, 1.0f, 0.998f,        0.002f, 0.5f, 0.0f};
    memcpy(im.pixels, v, sizeof v);
    char p[512];
    path_in(p, sizeof p, "lin.png");
    assert_int_equal(gi_image_write_png(p, &im, &st), 0);
    assert_int_equal(gi_image_read(p, &back, &st), 0);
    assert_int_equal(back.channels, 4);
    assert_int_equal(back.width, 2);
    assert_int_equal(back.height, 2);
    for (int i = 0; i < 16; i++) {
        float c = v[i] < 0 ? 0 : (v[i] > 1 ? 1 : v[i]);
        int want = (int)floorf(c * 255.0f + 0.5f);
        assert_int_equal(png_byte(&back, i / 4, i % 4), want);
    }
    assert_int_equal(png_byte(&back, 0, 0), 128);
    gi_image_release(&back);
    gi_image_release(&im);
}

static void test_read_missing(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0};
    char p[512];
    path_in(p, sizeof p, "does-not-exist.exr");
    assert_int_equal(gi_image_read(p, &im, &st), GI_EXIT_SYSTEM);
    assert_non_null(strstr(st.msg, "does-not-exist.exr"));
    assert_non_null(strstr(st.msg, "No such file"));
    assert_null(im.pixels);
    char v[16];
    assert_int_equal(gi_image_read_meta(p, "tool", v, sizeof v, &st), GI_EXIT_SYSTEM);
    /* a directory */
    assert_int_equal(gi_image_read(g_dir, &im, &st), GI_EXIT_SYSTEM);
}

static void test_read_garbage(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0};
    char p[512];
    path_in(p, sizeof p, "garbage.exr");
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    fputs("this is not an image, just text\n", f);
    fclose(f);
    assert_int_equal(gi_image_read(p, &im, &st), GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "garbage.exr"));
    assert_null(im.pixels);

    /* a truncated EXR */
    gi_image a = {0};
    assert_int_equal(gi_image_init(&a, 64, 64, 3, &st), 0);
    for (int i = 0; i < 64 * 64 * 3; i++)
        a.pixels[i] = (float)i;
    char q[512];
    path_in(q, sizeof q, "trunc.exr");
    assert_int_equal(gi_image_write_exr(q, &a, NULL, 0, &st), 0);
    struct stat sb;
    assert_int_equal(stat(q, &sb), 0);
    assert_int_equal(truncate(q, sb.st_size / 2), 0);
    int rc = gi_image_read(q, &im, &st);
    assert_int_equal(rc, GI_EXIT_DATA);
    assert_non_null(strstr(st.msg, "trunc.exr"));
    assert_null(im.pixels);
    gi_image_release(&a);
}

static void test_write_missing_dir(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image im = {0};
    assert_int_equal(gi_image_init(&im, 2, 2, 3, &st), 0);
    char p[512];
    path_in(p, sizeof p, "no-such-dir/out.exr");
    assert_int_equal(gi_image_write_exr(p, &im, NULL, 0, &st), GI_EXIT_SYSTEM);
    assert_non_null(strstr(st.msg, "no-such-dir/out.exr"));
    path_in(p, sizeof p, "no-such-dir/out.png");
    assert_int_equal(gi_image_write_png(p, &im, &st), GI_EXIT_SYSTEM);
    assert_int_equal(count_temps(g_dir), 0);

    /* rename fails (target is a non-empty directory): the temp file must go */
    char d[512], inner[600];
    path_in(d, sizeof d, "target.exr");
    assert_int_equal(mkdir(d, 0755), 0);
    snprintf(inner, sizeof inner, "%s/keep", d);
    FILE *f = fopen(inner, "w");
    assert_non_null(f);
    fclose(f);
    assert_int_equal(gi_image_write_exr(d, &im, NULL, 0, &st), GI_EXIT_SYSTEM);
    assert_non_null(strstr(st.msg, "target.exr"));
    assert_int_equal(count_temps(g_dir), 0);
    path_in(d, sizeof d, "target.exr");
    assert_int_equal(gi_image_write_png_srgb(d, &im, 1.0f, &st), GI_EXIT_SYSTEM);
    assert_int_equal(count_temps(g_dir), 0);
    unlink(inner);
    gi_image_release(&im);
}

static void test_write_invalid(void **state)
{
    (void)state;
    gi_status st = {0};
    gi_image z;
    memset(&z, 0, sizeof z);
    char p[512];
    path_in(p, sizeof p, "invalid.exr");
    assert_int_not_equal(gi_image_write_exr(p, &z, NULL, 0, &st), 0);
    assert_int_not_equal(gi_image_write_png(p, &z, &st), 0);
    assert_int_equal(access(p, F_OK), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_release),
        cmocka_unit_test(test_exr_roundtrip_rgb),
        cmocka_unit_test(test_exr_roundtrip_gray),
        cmocka_unit_test(test_exr_roundtrip_rgba),
        cmocka_unit_test(test_exr_overwrite),
        cmocka_unit_test(test_meta_roundtrip),
        cmocka_unit_test(test_png_srgb_values),
        cmocka_unit_test(test_png_gray_to_rgb),
        cmocka_unit_test(test_png_linear_quantise),
        cmocka_unit_test(test_read_missing),
        cmocka_unit_test(test_read_garbage),
        cmocka_unit_test(test_write_missing_dir),
        cmocka_unit_test(test_write_invalid),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
