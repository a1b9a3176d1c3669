/* test_container.c - unit tests of the gi container: LE helpers, CRC-32,
 * gi_hash64, gi_buf, writer/reader round trips, corruption, META, temp files. */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "gi_container.h"
#include "gi_crc32.h"
#include "gi_le.h"

static const char MAGIC[8] = {'G', 'I', 'P', 'H', 'O', 'T', 'O', 'N'};
static const char MAGIC_H[8] = {'G', 'I', 'H', 'V', 'D', 'S', 0, 0};
static char g_dir[256];

/* ---- helpers ------------------------------------------------------------- */

static void assert_has_at(const char *msg, const char *sub, const char *file, int line)
{
    if (!strstr(msg, sub)) {
        print_error("%s:%d: message \"%s\" lacks \"%s\"\n", file, line, msg, sub);
        _fail(file, line);
    }
}
#define assert_has(msg, sub) assert_has_at((msg), (sub), __FILE__, __LINE__)

static void path_in(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", g_dir, name);
}

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

/* Number of directory entries other than . and .. */
static int count_entries(const char *dir, const char *must_not_contain)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        if (must_not_contain && strstr(e->d_name, must_not_contain)) {
            print_error("unexpected file %s/%s\n", dir, e->d_name);
            fail();
        }
        n++;
    }
    closedir(d);
    return n;
}

static void remove_tree(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *e;
    char p[512];
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        struct stat sb;
        if (lstat(p, &sb) == 0 && S_ISDIR(sb.st_mode))
            remove_tree(p);
        else
            unlink(p);
    }
    closedir(d);
    rmdir(dir);
}

static int group_setup(void **state)
{
    snprintf(g_dir, sizeof g_dir, "/tmp/gi_test_container.XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int group_teardown(void **state)
{
    remove_tree(g_dir);
    return 0;
}

/* Deterministic pseudo-random bytes. */
static void fill_lcg(unsigned char *p, size_t n, uint32_t seed)
{
    uint32_t x = seed * 2654435761u + 1;
    for (size_t i = 0; i < n; i++) {
        x = x * 1664525u + 1013904223u;
        p[i] = (unsigned char)(x >> 24);
    }
}

static float f32_bits(uint32_t u)
{
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static uint32_t bits_f32(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    return u;
}

static double f64_bits(uint64_t u)
{
    double f;
    memcpy(&f, &u, 8);
    return f;
}

static uint64_t bits_f64(double f)
{
    uint64_t u;
    memcpy(&u, &f, 8);
    return u;
}

static const uint32_t F32_PATTERNS[] = {
    0x7fc00000u, /* quiet NaN */
    0x7f800001u, /* signalling NaN, smallest payload */
    0x7fa5a5a5u, /* NaN with payload */
    0xffc00001u, /* negative NaN */
    0x7f800000u, /* +inf */
    0xff800000u, /* -inf */
    0x80000000u, /* -0 */
    0x00000001u, /* smallest subnormal */
    0x7f7fffffu, /* largest finite */
    0x3f800000u, /* 1 */
};
static const uint64_t F64_PATTERNS[] = {
    0x7ff8000000000000ull, 0x7ff0000000000001ull, 0x7ff5a5a5a5a5a5a5ull, 0xfff8000000000001ull,
    0x7ff0000000000000ull, 0xfff0000000000000ull, 0x8000000000000000ull, 0x0000000000000001ull,
    0x7fefffffffffffffull, 0x3ff0000000000000ull,
};

/* The small sample file: META, typed values, empty sections, an odd size. */
static void put_values(gi_buf *b)
{
    gi_buf_put_u8(b, 0xff);
    gi_buf_put_u16(b, 0xfffe);
    gi_buf_put_u32(b, 0xfffffffdu);
    gi_buf_put_u64(b, UINT64_MAX);
    gi_buf_put_u64(b, 0);
    gi_buf_put_i32(b, INT32_MIN);
    gi_buf_put_i64(b, -2);
    for (size_t i = 0; i < sizeof F32_PATTERNS / sizeof F32_PATTERNS[0]; i++)
        gi_buf_put_f32(b, f32_bits(F32_PATTERNS[i]));
    for (size_t i = 0; i < sizeof F64_PATTERNS / sizeof F64_PATTERNS[0]; i++)
        gi_buf_put_f64(b, f64_bits(F64_PATTERNS[i]));
}

static gi_writer *sample_writer(size_t big)
{
    gi_status st = {0};
    gi_writer *w = gi_writer_new(MAGIC, 1, 2);
    assert_non_null(w);
    gi_buf meta, vals;
    gi_buf_init(&meta);
    gi_buf_init(&vals);
    assert_int_equal(gi_meta_add(&meta, "tool", "gi-precompute", &st), 0);
    assert_int_equal(gi_meta_add(&meta, "version", "0.1.0", &st), 0);
    assert_int_equal(gi_meta_addf(&meta, "option.bins", &st, "%d", 128), 0);
    assert_int_equal(gi_meta_add_input(&meta, "scene", "scenes/box.gltf", 0x0123456789abcdefull,
                                       &st),
                     0);
    assert_int_equal(gi_writer_add_buf(w, "META", 0, &meta, &st), 0);
    assert_int_equal(meta.len, 0);
    put_values(&vals);
    assert_int_equal(gi_writer_add_buf(w, "VALS", 7, &vals, &st), 0);
    assert_int_equal(gi_writer_add(w, "EMPT", 0, NULL, 0, &st), 0);
    assert_int_equal(gi_writer_add(w, "ODD1", 0x80000000u, "hello, world!", 13, &st), 0);
    if (big) {
        unsigned char *p = malloc(big);
        assert_non_null(p);
        fill_lcg(p, big, 99);
        assert_int_equal(gi_writer_add(w, "BIG ", 0, p, big, &st), 0);
        free(p);
    }
    assert_int_equal(gi_writer_add(w, "EMP2", 0, NULL, 0, &st), 0);
    return w;
}

static unsigned char *sample_bytes(size_t big, size_t *n)
{
    char path[512];
    gi_status st = {0};
    path_in(path, sizeof path, "sample.gip");
    gi_writer *w = sample_writer(big);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);
    unsigned char *p = read_all(path, n);
    unlink(path);
    return p;
}

/* Build container bytes by hand from the docs/formats.md tables, independent
 * of the writer. Sections with data == NULL get a byte pattern. */
typedef struct craft_sec {
    const char *id;
    uint64_t offset;
    uint64_t size;
    const void *data;
    uint32_t reserved;
} craft_sec;

static size_t craft(unsigned char *out, size_t cap, const char magic[8], uint16_t major,
                    uint16_t minor, const craft_sec *s, uint32_t n, size_t file_len)
{
    memset(out, 0, cap);
    memcpy(out, magic, 8);
    gi_le_put_u16(out + 8, major);
    gi_le_put_u16(out + 10, minor);
    gi_le_put_u32(out + 12, n);
    size_t end = 32 + 32 * (size_t)n;
    uint32_t crcs[8] = {0};
    assert_true(n <= 8);
    /* Data first, then the table, so that a section deliberately placed over
     * the table cannot change the table. */
    for (uint32_t i = 0; i < n; i++) {
        unsigned char tmp[4096];
        const unsigned char *d = s[i].data;
        if (!d && s[i].size <= sizeof tmp) {
            for (size_t k = 0; k < s[i].size; k++)
                tmp[k] = (unsigned char)(k * 7 + i + 1);
            d = tmp;
        }
        if (s[i].offset <= cap && s[i].size <= cap - s[i].offset) {
            memcpy(out + s[i].offset, d, s[i].size);
            crcs[i] = gi_crc32(d, s[i].size);
            if (s[i].offset + s[i].size > end)
                end = s[i].offset + s[i].size;
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        unsigned char *e = out + 32 + 32 * i;
        memcpy(e, s[i].id, 4);
        gi_le_put_u32(e + 4, 0);
        gi_le_put_u64(e + 8, s[i].offset);
        gi_le_put_u64(e + 16, s[i].size);
        gi_le_put_u32(e + 24, crcs[i]);
        gi_le_put_u32(e + 28, s[i].reserved);
    }
    if (file_len == 0)
        file_len = end;
    assert_true(file_len <= cap);
    gi_le_put_u64(out + 16, file_len);
    uint32_t crc = gi_crc32(out, 28);
    crc = gi_crc32_update(crc, out + 32, 32 * (size_t)n);
    gi_le_put_u32(out + 28, crc);
    return file_len;
}

/* Recompute the header CRC after editing header or table bytes. */
static void fix_header_crc(unsigned char *d)
{
    uint32_t n = gi_le_get_u32(d + 12);
    uint32_t crc = gi_crc32_update(gi_crc32(d, 28), d + 32, 32 * (size_t)n);
    gi_le_put_u32(d + 28, crc);
}

static int open_mem(const void *p, size_t n, gi_reader **r, gi_status *st)
{
    gi_status_clear(st);
    return gi_reader_open_memory(p, n, "t.gip", MAGIC, 1, r, st);
}

/* ---- LE helpers ------------------------------------------------------------ */

static void test_le_integers(void **state)
{
    unsigned char b[24];
    /* Byte order is explicit, at an odd (unaligned) address. */
    gi_le_put_u32(b + 1, 0x01020304u);
    assert_int_equal(b[1], 0x04);
    assert_int_equal(b[2], 0x03);
    assert_int_equal(b[3], 0x02);
    assert_int_equal(b[4], 0x01);
    gi_le_put_u64(b + 3, 0x0102030405060708ull);
    for (int i = 0; i < 8; i++)
        assert_int_equal(b[3 + i], 8 - i);
    gi_le_put_u16(b + 5, 0xa1b2);
    assert_int_equal(b[5], 0xb2);
    assert_int_equal(b[6], 0xa1);

    const uint64_t u64s[] = {0, 1, 0x80, 0xff, 0x8000000000000000ull, UINT64_MAX,
                             0x7fffffffffffffffull, 0x00ff00ff00ff00ffull};
    for (size_t i = 0; i < sizeof u64s / sizeof u64s[0]; i++)
        for (int off = 0; off < 8; off++) {
            gi_le_put_u64(b + off, u64s[i]);
            assert_true(gi_le_get_u64(b + off) == u64s[i]);
            gi_le_put_u32(b + off, (uint32_t)u64s[i]);
            assert_true(gi_le_get_u32(b + off) == (uint32_t)u64s[i]);
            gi_le_put_u16(b + off, (uint16_t)u64s[i]);
            assert_true(gi_le_get_u16(b + off) == (uint16_t)u64s[i]);
            gi_le_put_u8(b + off, (uint8_t)u64s[i]);
            assert_true(gi_le_get_u8(b + off) == (uint8_t)u64s[i]);
        }
    const int32_t i32s[] = {0, -1, INT32_MIN, INT32_MAX, -123456};
    for (size_t i = 0; i < sizeof i32s / sizeof i32s[0]; i++) {
        gi_le_put_i32(b + 1, i32s[i]);
        assert_int_equal(gi_le_get_i32(b + 1), i32s[i]);
    }
    const int64_t i64s[] = {0, -1, INT64_MIN, INT64_MAX, -1234567890123ll};
    for (size_t i = 0; i < sizeof i64s / sizeof i64s[0]; i++) {
        gi_le_put_i64(b + 3, i64s[i]);
        assert_true(gi_le_get_i64(b + 3) == i64s[i]);
    }
    gi_le_put_i32(b, -2);
    assert_int_equal(b[0], 0xfe);
    assert_int_equal(b[3], 0xff);
}

static void test_le_floats_bit_exact(void **state)
{
    unsigned char b[16], e[8];
    for (size_t i = 0; i < sizeof F32_PATTERNS / sizeof F32_PATTERNS[0]; i++) {
        gi_le_put_f32(b + 1, f32_bits(F32_PATTERNS[i]));
        gi_le_put_u32(e, F32_PATTERNS[i]);
        assert_memory_equal(b + 1, e, 4);
        assert_int_equal(bits_f32(gi_le_get_f32(b + 1)), F32_PATTERNS[i]);
    }
    for (size_t i = 0; i < sizeof F64_PATTERNS / sizeof F64_PATTERNS[0]; i++) {
        gi_le_put_f64(b + 3, f64_bits(F64_PATTERNS[i]));
        gi_le_put_u64(e, F64_PATTERNS[i]);
        assert_memory_equal(b + 3, e, 8);
        assert_true(bits_f64(gi_le_get_f64(b + 3)) == F64_PATTERNS[i]);
    }
    /* IEEE-754 binary32 1.0 is 0x3f800000 in little-endian order. */
    gi_le_put_f32(b, 1.0f);
    assert_int_equal(b[0], 0x00);
    assert_int_equal(b[3], 0x3f);
    gi_le_put_f64(b, -2.0);
    assert_int_equal(b[7], 0xc0);
    assert_true(isinf(gi_le_get_f64(b + 0) * DBL_MAX));
}

/* ---- CRC-32 and hash --------------------------------------------------------- */

static void test_crc32_known(void **state)
{
    const char *s = "123456789";
    assert_int_equal(gi_crc32(s, 9), 0xCBF43926u);
    assert_int_equal(gi_crc32(s, 0), 0);
    for (size_t k = 0; k <= 9; k++)
        assert_int_equal(gi_crc32_update(gi_crc32(s, k), s + k, 9 - k), 0xCBF43926u);
}

static void test_file_crc32(void **state)
{
    char path[512];
    gi_status st = {0};
    size_t n = (3u << 20) + 17; /* several read chunks */
    unsigned char *p = malloc(n);
    assert_non_null(p);
    fill_lcg(p, n, 5);
    path_in(path, sizeof path, "crc.bin");
    write_bytes(path, p, n);
    uint32_t crc = 1;
    assert_int_equal(gi_file_crc32(path, &crc, &st), 0);
    assert_int_equal(crc, gi_crc32(p, n));
    unlink(path);
    free(p);
    assert_int_equal(gi_file_crc32(path, &crc, &st), GI_EXIT_SYSTEM);
    assert_has(st.msg, path);
    assert_has(st.msg, strerror(ENOENT));
}

static void test_hash64(void **state)
{
    unsigned char buf[301];
    fill_lcg(buf, sizeof buf, 11);
    uint64_t h = gi_hash64(buf, 300, 0);
    assert_true(h == gi_hash64(buf, 300, 0));
    assert_true(h != gi_hash64(buf, 300, 1));
    assert_true(h != gi_hash64(buf, 299, 0));
    /* Alignment does not change the value. */
    memmove(buf + 1, buf, 300);
    assert_true(h == gi_hash64(buf + 1, 300, 0));
    /* Every single-bit flip changes the hash, and by many bits on average. */
    double bits = 0;
    int flips = 0;
    for (size_t i = 0; i < 100; i++)
        for (int bit = 0; bit < 8; bit++) {
            buf[1 + i] ^= (unsigned char)(1u << bit);
            uint64_t g = gi_hash64(buf + 1, 100, 0);
            buf[1 + i] ^= (unsigned char)(1u << bit);
            uint64_t x = g ^ gi_hash64(buf + 1, 100, 0);
            assert_true(x != 0);
            bits += __builtin_popcountll(x);
            flips++;
        }
    assert_true(bits / flips > 28.0 && bits / flips < 36.0);
    /* All-zero inputs of different lengths differ (length is hashed). */
    unsigned char z[80] = {0};
    uint64_t seen[81];
    for (size_t n = 0; n <= 80; n++) {
        seen[n] = gi_hash64(z, n, 0);
        for (size_t m = 0; m < n; m++)
            assert_true(seen[m] != seen[n]);
    }
    /* Chaining is well defined. */
    assert_true(gi_hash64(buf, 50, gi_hash64(buf + 50, 50, 3)) !=
                gi_hash64(buf + 50, 50, gi_hash64(buf, 50, 3)));
    /* The algorithm is frozen: stored input hashes depend on it. If this
     * value changes, every .gip/.gih file on disk becomes stale. */
    assert_true(gi_hash64("123456789", 9, 0) == 0x91e5ae31c2f6dddaull);

    char hex[17];
    gi_hash64_hex(0x0123456789abcdefull, hex);
    assert_string_equal(hex, "0123456789abcdef");
    gi_hash64_hex(h, hex);
    assert_int_equal(strlen(hex), 16);
    assert_true(strtoull(hex, NULL, 16) == h);
}

/* ---- gi_buf ------------------------------------------------------------------ */

static void test_buf(void **state)
{
    gi_buf b;
    gi_buf_init(&b);
    for (uint32_t i = 0; i < 10000; i++)
        gi_buf_put_u32(&b, i * 3u);
    assert_true(gi_buf_ok(&b));
    assert_int_equal(b.len, 40000);
    for (uint32_t i = 0; i < 10000; i++)
        assert_int_equal(gi_le_get_u32(b.data + 4 * i), i * 3u);
    gi_buf_set_u32(&b, 8, 0xdeadbeefu);
    assert_int_equal(gi_le_get_u32(b.data + 8), 0xdeadbeefu);
    gi_buf_set_u64(&b, 40000 - 8, 0x1122334455667788ull);
    assert_true(gi_le_get_u64(b.data + 40000 - 8) == 0x1122334455667788ull);
    gi_buf_put_u8(&b, 1);
    gi_buf_align(&b, 16);
    assert_int_equal(b.len, 40016);
    for (size_t i = 40001; i < 40016; i++)
        assert_int_equal(b.data[i], 0);
    gi_buf_put_str(&b, "ab");
    gi_buf_put_zeros(&b, 3);
    gi_buf_put_bytes(&b, "xyz", 3);
    assert_memory_equal(b.data + 40016, "ab\0\0\0xyz", 8);
    gi_buf_release(&b);
    assert_null(b.data);
    assert_int_equal(b.len, 0);
    gi_buf_release(&b); /* releasing an empty buffer is fine */
}

/* ---- round trips -------------------------------------------------------------- */

static void test_roundtrip(void **state)
{
    char path[512];
    gi_status st = {0};
    path_in(path, sizeof path, "rt.gip");
    gi_writer *w = sample_writer(100000);
    gi_writer_set_flags(w, 0x5u);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);

    gi_reader *r = NULL;
    assert_int_equal(gi_reader_open(path, MAGIC, 1, &r, &st), 0);
    assert_non_null(r);
    assert_string_equal(gi_reader_name(r), path);
    assert_int_equal(gi_reader_major(r), 1);
    assert_int_equal(gi_reader_minor(r), 2);
    assert_int_equal(gi_reader_flags(r), 5);
    assert_int_equal(gi_reader_section_count(r), 6);
    const char *ids[] = {"META", "VALS", "EMPT", "ODD1", "BIG ", "EMP2"};
    uint64_t prev_end = 32 + 32 * 6;
    for (uint32_t i = 0; i < 6; i++) {
        gi_section_info info;
        assert_int_equal(gi_reader_section_info(r, i, &info), 0);
        assert_string_equal(info.id, ids[i]);
        assert_int_equal(info.offset % 16, 0);
        assert_true(info.offset >= prev_end && info.offset - prev_end < 16);
        prev_end = info.offset + info.size;
    }
    gi_section_info info;
    assert_int_equal(gi_reader_section_info(r, 6, &info), -1);
    assert_int_equal(gi_reader_section_info(r, 1, &info), 0);
    assert_int_equal(info.flags, 7);
    assert_int_equal(gi_reader_section_info(r, 3, &info), 0);
    assert_int_equal(info.flags, 0x80000000u);

    size_t n = 99;
    const unsigned char *p = gi_reader_section(r, "ODD1", &n);
    assert_non_null(p);
    assert_int_equal(n, 13);
    assert_memory_equal(p, "hello, world!", 13);
    p = gi_reader_section(r, "EMPT", &n);
    assert_non_null(p);
    assert_int_equal(n, 0);
    p = gi_reader_section(r, "EMP2", &n);
    assert_non_null(p);
    assert_int_equal(n, 0);
    p = gi_reader_section(r, "BIG ", &n);
    assert_int_equal(n, 100000);
    assert_int_equal(((uintptr_t)p) % 16, 0); /* arrays usable in place */
    unsigned char *expect = malloc(100000);
    fill_lcg(expect, 100000, 99);
    assert_memory_equal(p, expect, 100000);
    free(expect);
    n = 99;
    assert_null(gi_reader_section(r, "NONE", &n));
    assert_int_equal(n, 0);
    const void *q = NULL;
    assert_int_equal(gi_reader_require(r, "ODD1", &q, &n, &st), 0);
    assert_non_null(q);
    assert_int_equal(gi_reader_require(r, "PHOT", &q, &n, &st), GI_EXIT_DATA);
    assert_null(q);
    assert_has(st.msg, path);
    assert_has(st.msg, "section 'PHOT' missing");

    /* Typed values come back bit for bit through the cursor. */
    gi_cursor c;
    assert_int_equal(gi_reader_cursor(r, "VALS", &c, &st), 0);
    uint8_t u8;
    uint16_t u16;
    uint32_t u32;
    uint64_t u64;
    int32_t i32;
    int64_t i64;
    float f;
    double d;
    assert_int_equal(gi_cursor_u8(&c, &u8, &st), 0);
    assert_int_equal(u8, 0xff);
    assert_int_equal(gi_cursor_u16(&c, &u16, &st), 0);
    assert_int_equal(u16, 0xfffe);
    assert_int_equal(gi_cursor_u32(&c, &u32, &st), 0);
    assert_int_equal(u32, 0xfffffffdu);
    assert_int_equal(gi_cursor_u64(&c, &u64, &st), 0);
    assert_true(u64 == UINT64_MAX);
    assert_int_equal(gi_cursor_u64(&c, &u64, &st), 0);
    assert_true(u64 == 0);
    assert_int_equal(gi_cursor_i32(&c, &i32, &st), 0);
    assert_int_equal(i32, INT32_MIN);
    assert_int_equal(gi_cursor_i64(&c, &i64, &st), 0);
    assert_true(i64 == -2);
    for (size_t i = 0; i < sizeof F32_PATTERNS / sizeof F32_PATTERNS[0]; i++) {
        assert_int_equal(gi_cursor_f32(&c, &f, &st), 0);
        assert_int_equal(bits_f32(f), F32_PATTERNS[i]);
    }
    for (size_t i = 0; i < sizeof F64_PATTERNS / sizeof F64_PATTERNS[0]; i++) {
        assert_int_equal(gi_cursor_f64(&c, &d, &st), 0);
        assert_true(bits_f64(d) == F64_PATTERNS[i]);
    }
    assert_int_equal(gi_cursor_end(&c, &st), 0);
    assert_int_equal(gi_reader_cursor(r, "NOPE", &c, &st), GI_EXIT_DATA);
    assert_has(st.msg, "section 'NOPE' missing");
    gi_reader_free(r);
    gi_reader_free(NULL);
    unlink(path);
}

/* The writer's bytes equal a file assembled by hand from the spec tables. */
static void test_writer_matches_spec(void **state)
{
    gi_status st = {0};
    char path[512];
    path_in(path, sizeof path, "spec.gip");
    gi_writer *w = gi_writer_new(MAGIC, 1, 0);
    unsigned char a[20], b[33];
    for (int i = 0; i < 20; i++)
        a[i] = (unsigned char)(i * 7 + 1);
    for (int i = 0; i < 33; i++)
        b[i] = (unsigned char)(i * 7 + 3);
    assert_int_equal(gi_writer_add(w, "AAAA", 0, a, 20, &st), 0);
    assert_int_equal(gi_writer_add(w, "EMPT", 0, NULL, 0, &st), 0);
    assert_int_equal(gi_writer_add(w, "BBBB", 0, b, 33, &st), 0);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);
    size_t n;
    unsigned char *got = read_all(path, &n);
    /* table ends at 32 + 3*32 = 128; AAAA 128..148, EMPT at 160, BBBB 160..193 */
    craft_sec s[] = {{"AAAA", 128, 20, a, 0}, {"EMPT", 160, 0, NULL, 0}, {"BBBB", 160, 33, b, 0}};
    unsigned char want[512];
    size_t wn = craft(want, sizeof want, MAGIC, 1, 0, s, 3, 0);
    assert_int_equal(n, 193);
    assert_int_equal(wn, n);
    assert_memory_equal(got, want, n);
    free(got);

    /* No sections at all: just the 32-byte header. */
    w = gi_writer_new(MAGIC_H, 2, 1);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);
    got = read_all(path, &n);
    assert_int_equal(n, 32);
    wn = craft(want, sizeof want, MAGIC_H, 2, 1, NULL, 0, 0);
    assert_int_equal(wn, 32);
    assert_memory_equal(got, want, 32);
    gi_reader *r;
    assert_int_equal(gi_reader_open_memory(got, n, "h", MAGIC_H, 2, &r, &st), 0);
    assert_int_equal(gi_reader_section_count(r), 0);
    assert_null(gi_reader_meta(r, "tool"));
    gi_reader_free(r);
    free(got);
    unlink(path);
}

static void test_deterministic(void **state)
{
    size_t n1, n2;
    unsigned char *a = sample_bytes(5000, &n1);
    unsigned char *b = sample_bytes(5000, &n2);
    assert_int_equal(n1, n2);
    assert_memory_equal(a, b, n1);
    /* A different payload gives different bytes (the comparison can fail). */
    unsigned char *c = sample_bytes(5001, &n2);
    assert_true(n1 != n2 || memcmp(a, c, n1) != 0);
    free(a);
    free(b);
    free(c);
}

static void test_minor_version_accepted(void **state)
{
    gi_status st = {0};
    craft_sec s[] = {{"DATA", 64, 5, "abcde", 0}};
    unsigned char d[256];
    size_t n = craft(d, sizeof d, MAGIC, 1, 9, s, 1, 0);
    gi_reader *r;
    assert_int_equal(open_mem(d, n, &r, &st), 0);
    assert_int_equal(gi_reader_minor(r), 9);
    gi_reader_free(r);
}

/* Non-canonical but valid layout: larger aligned gaps, unknown ids. */
static void test_unknown_sections_and_gaps(void **state)
{
    gi_status st = {0};
    craft_sec s[] = {{"XYZ1", 128, 3, "abc", 0}, {"META", 256, 7, "tool=x\n", 0},
                     {"zz_9", 512, 0, NULL, 0}};
    unsigned char d[1024];
    size_t n = craft(d, sizeof d, MAGIC, 1, 0, s, 3, 600);
    gi_reader *r;
    assert_int_equal(open_mem(d, n, &r, &st), 0);
    size_t sz;
    const unsigned char *p = gi_reader_section(r, "XYZ1", &sz);
    assert_int_equal(sz, 3);
    assert_memory_equal(p, "abc", 3);
    assert_string_equal(gi_reader_meta(r, "tool"), "x");
    gi_reader_free(r);
}

/* ---- corruption ---------------------------------------------------------------- */

static void test_truncation_every_offset(void **state)
{
    gi_status st = {0};
    size_t n;
    unsigned char *full = sample_bytes(0, &n);
    gi_reader *r = NULL;
    assert_int_equal(open_mem(full, n, &r, &st), 0);
    gi_reader_free(r);
    for (size_t len = 0; len < n; len++) {
        r = (gi_reader *)1;
        int rc = open_mem(full, len, &r, &st);
        if (rc != GI_EXIT_DATA)
            print_error("length %zu: rc %d (%s)\n", len, rc, st.msg);
        assert_int_equal(rc, GI_EXIT_DATA);
        assert_null(r);
        assert_true(strncmp(st.msg, "t.gip: ", 7) == 0);
        if (len >= 32)
            assert_has(st.msg, "truncated");
    }
    /* One byte too many is refused too. */
    unsigned char *more = malloc(n + 1);
    memcpy(more, full, n);
    more[n] = 0;
    assert_int_equal(open_mem(more, n + 1, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "trailing data");
    free(more);
    free(full);
}

/* Files on disk cut at every section boundary (start and end of each). */
static void test_truncation_at_boundaries(void **state)
{
    char path[512];
    gi_status st = {0};
    path_in(path, sizeof path, "trunc.gip");
    gi_writer *w = sample_writer(70000);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);
    gi_reader *r;
    assert_int_equal(gi_reader_open(path, MAGIC, 1, &r, &st), 0);
    uint32_t ns = gi_reader_section_count(r);
    uint64_t cuts[64];
    size_t ncut = 0;
    cuts[ncut++] = 0;
    cuts[ncut++] = 8;
    cuts[ncut++] = 31;
    cuts[ncut++] = 32;
    for (uint32_t i = 0; i < ns; i++) {
        gi_section_info info;
        gi_reader_section_info(r, i, &info);
        cuts[ncut++] = 32 + 32 * (uint64_t)i;
        cuts[ncut++] = info.offset;
        cuts[ncut++] = info.offset + info.size / 2;
        cuts[ncut++] = info.offset + info.size;
        if (info.offset > 0)
            cuts[ncut++] = info.offset - 1;
    }
    gi_reader_free(r);
    size_t n;
    unsigned char *full = read_all(path, &n);
    for (size_t k = 0; k < ncut; k++) {
        if (cuts[k] >= n)
            continue;
        write_bytes(path, full, (size_t)cuts[k]);
        r = (gi_reader *)1;
        int rc = gi_reader_open(path, MAGIC, 1, &r, &st);
        if (rc != GI_EXIT_DATA)
            print_error("cut at %llu: rc %d (%s)\n", (unsigned long long)cuts[k], rc, st.msg);
        assert_int_equal(rc, GI_EXIT_DATA);
        assert_null(r);
        assert_has(st.msg, path);
    }
    free(full);
    unlink(path);
}

/* Every byte is covered: header and table by the header CRC, data by the
 * section CRCs, padding by the zero check. */
static void test_flip_every_byte(void **state)
{
    gi_status st = {0};
    size_t n;
    unsigned char *d = sample_bytes(0, &n);
    const unsigned char masks[] = {0x01, 0x80, 0xff};
    size_t checksum = 0, padding = 0;
    for (size_t pos = 0; pos < n; pos++)
        for (size_t m = 0; m < sizeof masks; m++) {
            d[pos] ^= masks[m];
            gi_reader *r = (gi_reader *)1;
            int rc = open_mem(d, n, &r, &st);
            d[pos] ^= masks[m];
            if (rc != GI_EXIT_DATA)
                print_error("flip 0x%02x at %zu: rc %d\n", masks[m], pos, rc);
            assert_int_equal(rc, GI_EXIT_DATA);
            assert_null(r);
            checksum += strstr(st.msg, "checksum mismatch") != NULL;
            padding += strstr(st.msg, "padding byte") != NULL;
        }
    /* Both kinds of detection were exercised. */
    assert_true(checksum > n);
    assert_true(padding > 0);
    free(d);
}

static void test_wrong_magic(void **state)
{
    gi_status st = {0};
    gi_reader *r;
    craft_sec s[] = {{"DATA", 64, 5, "abcde", 0}};
    unsigned char d[256];
    size_t n = craft(d, sizeof d, MAGIC_H, 1, 0, s, 1, 0);
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_string_equal(st.msg,
                        "t.gip: is a .gih file (gi-hvds), expected a .gip file (gi-precompute)");
    assert_int_equal(open_mem("{\n  \"asset\": {}}\n", 17, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "is a JSON text file (.gltf?), expected a .gip file");
    assert_int_equal(open_mem("\x89PNG\r\n\x1a\n0000000000000000000000000000", 36, &r, &st),
                     GI_EXIT_DATA);
    assert_has(st.msg, "is a PNG image");
    assert_int_equal(open_mem("hello world, this is not a container", 36, &r, &st),
                     GI_EXIT_DATA);
    assert_has(st.msg, "not a .gip file (gi-precompute): starts with 'hello wo'");
    assert_int_equal(open_mem("", 0, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "empty file");
    assert_int_equal(open_mem("GIPHO", 5, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "truncated: 5 bytes");
    /* An unknown expected magic is quoted with escapes. */
    const char odd[8] = {'X', 'Y', 0, 1, 'Z', 'Z', 'Z', 'Z'};
    assert_int_equal(gi_reader_open_memory(d, n, "f", odd, 1, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "expected a gi file with magic 'XY\\x00\\x01ZZZZ'");
}

static void test_unknown_major(void **state)
{
    gi_status st = {0};
    gi_reader *r;
    craft_sec s[] = {{"DATA", 64, 5, "abcde", 0}};
    unsigned char d[256];
    size_t n = craft(d, sizeof d, MAGIC, 3, 0, s, 1, 0);
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "t.gip: file was written by format 3.0; this gi reads 1.x");
    assert_has(st.msg, "newer");
    n = craft(d, sizeof d, MAGIC, 0, 7, s, 1, 0);
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "format 0.7; this gi reads 1.x");
}

/* Files with valid CRCs whose layout breaks a rule. */
static void test_bad_layouts(void **state)
{
    gi_status st = {0};
    gi_reader *r;
    unsigned char d[2048];
    size_t n;
    struct {
        craft_sec s[3];
        uint32_t ns;
        size_t len;
        const char *msg;
    } cases[] = {
        {{{"AAAA", 72, 4, NULL, 0}}, 1, 0, "offset 40 (section 'AAAA'): data offset 72 is not a multiple of 16"},
        {{{"AAAA", 48, 4, NULL, 0}}, 1, 0, "data offset 48 overlaps the section table, which ends at 64"},
        {{{"AAAA", 96, 40, NULL, 0}, {"BBBB", 128, 4, NULL, 0}}, 2, 0,
         "offset 72 (section 'BBBB'): data offset 128 overlaps the previous section, which ends at 136"},
        {{{"AAAA", 96, 4, NULL, 0}, {"BBBB", 112, UINT64_MAX - 40, NULL, 0}}, 2, 128,
         "offset 80 (section 'BBBB'): 18446744073709551575 bytes at offset 112 run past the end"},
        {{{"AAAA", 96, 4, NULL, 0}, {"BBBB", UINT64_MAX - 15, 16, NULL, 0}}, 2, 128,
         "run past the end of the file (128 bytes)"},
        {{{"AAAA", 96, 4, NULL, 0}, {"AAAA", 112, 4, NULL, 0}}, 2, 0,
         "offset 64 (section 'AAAA'): duplicate section id (first at offset 32)"},
        {{{"AAAA", 64, 4, NULL, 1}}, 1, 0, "offset 60 (section 'AAAA'): reserved field is not zero"},
        {{{"A\nAA", 64, 4, NULL, 0}}, 1, 0, "offset 32: section id 'A\\x0aAA' is not 4 printable"},
        {{{"META", 64, 6, "tool=x", 0}}, 1, 0, "(section 'META'): line 1: no newline"},
        {{{"META", 64, 12, "tool=x\nnoeq\n", 0}}, 1, 0, "offset 71 (section 'META'): line 2: missing '='"},
        {{{"META", 64, 10, "a=1\nb c=2\n", 0}}, 1, 0, "line 2: key is not 1-127 characters"},
        {{{"META", 64, 9, "a=1\n=bad\n", 0}}, 1, 0, "line 2: key is not"},
        {{{"META", 64, 11, "k=1\nz=\0\nk=2", 0}}, 1, 0, "line 2: NUL byte"},
        {{{"META", 64, 15, "k=1\nz=ok\nk=2=3\n", 0}}, 1, 0, "offset 73 (section 'META'): key 'k' appears twice"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        n = craft(d, sizeof d, MAGIC, 1, 0, cases[i].s, cases[i].ns, cases[i].len);
        r = (gi_reader *)1;
        int rc = open_mem(d, n, &r, &st);
        if (rc != GI_EXIT_DATA || !strstr(st.msg, cases[i].msg))
            print_error("case %zu: rc %d: %s\n", i, rc, st.msg);
        assert_int_equal(rc, GI_EXIT_DATA);
        assert_null(r);
        assert_has(st.msg, cases[i].msg);
    }

    /* Nonzero padding between sections, and after the last one. */
    craft_sec s[] = {{"AAAA", 96, 4, NULL, 0}, {"BBBB", 112, 4, NULL, 0}};
    n = craft(d, sizeof d, MAGIC, 1, 0, s, 2, 128);
    assert_int_equal(open_mem(d, n, &r, &st), 0);
    gi_reader_free(r);
    d[102] = 0x5a;
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "offset 102 (before section 'BBBB'): padding byte 0x5a is not zero");
    d[102] = 0;
    d[127] = 1;
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "offset 127 (after the last section): padding byte 0x01 is not zero");
    d[127] = 0;

    /* A section count that cannot fit, with a matching CRC. */
    gi_le_put_u32(d + 12, 0xffffffffu);
    gi_le_put_u32(d + 28, gi_crc32(d, 28)); /* table cannot be read anyway */
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "offset 12: section count 4294967295 does not fit in a 128-byte file");
    gi_le_put_u32(d + 12, 2);
    fix_header_crc(d);
    assert_int_equal(open_mem(d, n, &r, &st), 0);
    gi_reader_free(r);

    /* Section data changed: its CRC names the section and its offset. */
    d[113] ^= 0x10;
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "t.gip: offset 112 (section 'BBBB'): checksum mismatch");
    d[113] ^= 0x10;
    /* Header changed without fixing its CRC. */
    d[24] = 1;
    assert_int_equal(open_mem(d, n, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "t.gip: offset 28: header checksum mismatch");
}

/* ---- reader entry points ---------------------------------------------------- */

static void test_open_errors(void **state)
{
    char path[512];
    gi_status st = {0};
    gi_reader *r = (gi_reader *)1;
    path_in(path, sizeof path, "does-not-exist.gip");
    assert_int_equal(gi_reader_open(path, MAGIC, 1, &r, &st), GI_EXIT_SYSTEM);
    assert_null(r);
    assert_has(st.msg, path);
    assert_has(st.msg, strerror(ENOENT));
    assert_int_equal(gi_reader_open(g_dir, MAGIC, 1, &r, &st), GI_EXIT_SYSTEM);
    assert_has(st.msg, strerror(EISDIR));
    path_in(path, sizeof path, "empty.gip");
    write_bytes(path, "", 0);
    assert_int_equal(gi_reader_open(path, MAGIC, 1, &r, &st), GI_EXIT_DATA);
    assert_has(st.msg, "empty file");
    unlink(path);
}

/* A pipe cannot be mapped: the reader reads it into memory instead. */
static void test_open_fifo(void **state)
{
    char path[512];
    gi_status st = {0};
    size_t n;
    unsigned char *d = sample_bytes(200000, &n);
    path_in(path, sizeof path, "fifo");
    assert_int_equal(mkfifo(path, 0600), 0);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        FILE *f = fopen(path, "wb");
        size_t k = f ? fwrite(d, 1, n, f) : 0;
        _exit(f && k == n && fclose(f) == 0 ? 0 : 1);
    }
    gi_reader *r;
    int rc = gi_reader_open(path, MAGIC, 1, &r, &st);
    int status;
    waitpid(pid, &status, 0);
    assert_int_equal(rc, 0);
    assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    size_t sz;
    assert_non_null(gi_reader_section(r, "BIG ", &sz));
    assert_int_equal(sz, 200000);
    assert_string_equal(gi_reader_meta(r, "tool"), "gi-precompute");
    gi_reader_free(r);
    unlink(path);
    free(d);
}

static void test_cursor_bounds(void **state)
{
    gi_status st = {0};
    unsigned char d[256];
    craft_sec s[] = {{"ZERO", 96, 0, NULL, 0}, {"TENB", 96, 10, NULL, 0}};
    size_t n = craft(d, sizeof d, MAGIC, 1, 0, s, 2, 0);
    gi_reader *r;
    assert_int_equal(open_mem(d, n, &r, &st), 0);
    gi_cursor c;
    assert_int_equal(gi_reader_cursor(r, "TENB", &c, &st), 0);
    uint64_t u64;
    uint32_t u32 = 77;
    uint16_t u16;
    assert_int_equal(gi_cursor_u64(&c, &u64, &st), 0);
    assert_true(u64 == gi_le_get_u64(d + 96));
    assert_int_equal(gi_cursor_remaining(&c), 2);
    assert_int_equal(gi_cursor_u32(&c, &u32, &st), GI_EXIT_DATA);
    assert_int_equal(u32, 0);
    assert_string_equal(st.msg, "t.gip: offset 104 (section 'TENB'): truncated: need 4 bytes, 2 left");
    assert_int_equal(gi_cursor_remaining(&c), 2); /* did not move */
    assert_int_equal(gi_cursor_end(&c, &st), GI_EXIT_DATA);
    assert_has(st.msg, "offset 104 (section 'TENB'): 2 unparsed bytes");
    assert_int_equal(gi_cursor_check_count(&c, 1, 2, "count", &st), 0);
    assert_int_equal(gi_cursor_check_count(&c, 2, 2, "count", &st), GI_EXIT_DATA);
    assert_int_equal(gi_cursor_check_count(&c, UINT64_MAX, 24, "photon count", &st),
                     GI_EXIT_DATA);
    assert_has(st.msg, "photon count 18446744073709551615 x 24 bytes exceeds the 2 bytes left");
    assert_int_equal(gi_cursor_check_count(&c, (UINT64_MAX / 3) + 1, 3, "n", &st), GI_EXIT_DATA);
    assert_int_equal(gi_cursor_u16(&c, &u16, &st), 0);
    assert_int_equal(u16, gi_le_get_u16(d + 104));
    assert_int_equal(gi_cursor_end(&c, &st), 0);
    const void *p = (const void *)1;
    assert_int_equal(gi_cursor_bytes(&c, &p, 1, &st), GI_EXIT_DATA);
    assert_null(p);
    assert_int_equal(gi_cursor_bytes(&c, &p, 0, &st), 0);
    assert_int_equal(gi_cursor_skip(&c, SIZE_MAX, &st), GI_EXIT_DATA);
    assert_int_equal(gi_cursor_fail(&c, &st, "bad value %d", 5), GI_EXIT_DATA);
    assert_string_equal(st.msg, "t.gip: offset 106 (section 'TENB'): bad value 5");

    assert_int_equal(gi_reader_cursor(r, "ZERO", &c, &st), 0);
    uint8_t u8 = 9;
    assert_int_equal(gi_cursor_u8(&c, &u8, &st), GI_EXIT_DATA);
    assert_int_equal(u8, 0);
    assert_has(st.msg, "offset 96 (section 'ZERO'): truncated: need 1 byte, 0 left");
    assert_int_equal(gi_cursor_end(&c, &st), 0);
    gi_reader_free(r);
}

/* ---- META ---------------------------------------------------------------------- */

static void test_meta_build_and_lookup(void **state)
{
    gi_status st = {0};
    gi_buf m;
    gi_buf_init(&m);
    assert_int_equal(gi_meta_add(&m, "tool", "gi-hvds", &st), 0);
    assert_int_equal(gi_meta_add(&m, "option.expr", "a=b", &st), 0);
    assert_int_equal(gi_meta_add(&m, "option.empty", "", &st), 0);
    assert_int_equal(gi_meta_add(&m, "tool", "again", &st), GI_EXIT_USAGE);
    assert_has(st.msg, "key 'tool' given twice");
    assert_int_equal(gi_meta_add(&m, "input.x", "a\nb", &st), GI_EXIT_USAGE);
    assert_has(st.msg, "newline");
    assert_int_equal(gi_meta_add(&m, "bad key", "v", &st), GI_EXIT_USAGE);
    assert_int_equal(gi_meta_add(&m, "", "v", &st), GI_EXIT_USAGE);
    char longkey[200];
    memset(longkey, 'k', sizeof longkey - 1);
    longkey[sizeof longkey - 1] = '\0';
    assert_int_equal(gi_meta_add(&m, longkey, "v", &st), GI_EXIT_USAGE);
    assert_int_equal(gi_meta_addf(&m, "option.scale", &st, "%.3f", 0.5), 0);
    assert_int_equal(gi_meta_add_input(&m, "gip", "out/scene.gip", 0xfedcba9876543210ull, &st),
                     0);
    const char *text = "tool=gi-hvds\noption.expr=a=b\noption.empty=\noption.scale=0.500\n"
                       "input.gip=out/scene.gip\ninput.gip.hash=fedcba9876543210\n";
    assert_int_equal(m.len, strlen(text));
    assert_memory_equal(m.data, text, m.len);

    gi_writer *w = gi_writer_new(MAGIC_H, 1, 0);
    assert_int_equal(gi_writer_add_buf(w, "META", 0, &m, &st), 0);
    char path[512];
    path_in(path, sizeof path, "meta.gih");
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);
    gi_reader *r;
    assert_int_equal(gi_reader_open(path, MAGIC_H, 1, &r, &st), 0);
    assert_string_equal(gi_reader_meta(r, "tool"), "gi-hvds");
    assert_string_equal(gi_reader_meta(r, "option.expr"), "a=b");
    assert_string_equal(gi_reader_meta(r, "option.empty"), "");
    assert_string_equal(gi_reader_meta(r, "option.scale"), "0.500");
    assert_string_equal(gi_reader_meta(r, "input.gip"), "out/scene.gip");
    assert_string_equal(gi_reader_meta(r, "input.gip.hash"), "fedcba9876543210");
    assert_null(gi_reader_meta(r, "input"));
    assert_null(gi_reader_meta(r, "option.exp"));
    gi_reader_free(r);
    unlink(path);
}

static void test_check_input(void **state)
{
    gi_status st = {0};
    char path[512];
    path_in(path, sizeof path, "scene.gip");
    gi_writer *w = sample_writer(0);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    gi_writer_free(w);
    gi_reader *r;
    assert_int_equal(gi_reader_open(path, MAGIC, 1, &r, &st), 0);
    gi_status_clear(&st);
    assert_int_equal(gi_container_check_input(r, "input.scene.hash", "0123456789abcdef", &st), 0);
    assert_int_equal(st.code, 0);
    char want[1024];
    snprintf(want, sizeof want,
             "%s: section 'META': made from scene hash 0123456789abcdef, but the scene given "
             "has 4567456745674567 (re-run gi-precompute)",
             path);
    assert_int_equal(gi_container_check_input(r, "input.scene.hash", "4567456745674567", &st),
                     GI_EXIT_DATA);
    assert_string_equal(st.msg, want);
    assert_int_equal(gi_container_check_input(r, "input.scene", "other.gltf", &st),
                     GI_EXIT_DATA);
    assert_has(st.msg, "made from scene 'scenes/box.gltf', but the scene given is 'other.gltf'");
    assert_int_equal(gi_container_check_input(r, "option.bins", "64", &st), GI_EXIT_DATA);
    assert_has(st.msg, "made with option.bins=128, but option.bins=64 is needed");
    assert_int_equal(gi_container_check_input(r, "input.lights.hash", "00", &st), GI_EXIT_DATA);
    assert_has(st.msg, "section 'META': no 'input.lights.hash' recorded (re-run gi-precompute)");

    /* Fingerprints: equal for equal content, different otherwise. */
    gi_reader *r2;
    size_t n;
    unsigned char *same = read_all(path, &n);
    assert_int_equal(open_mem(same, n, &r2, &st), 0);
    assert_true(gi_reader_fingerprint(r) == gi_reader_fingerprint(r2));
    gi_reader_free(r2);
    free(same);
    unsigned char *other = sample_bytes(16, &n);
    assert_int_equal(open_mem(other, n, &r2, &st), 0);
    assert_true(gi_reader_fingerprint(r) != gi_reader_fingerprint(r2));
    gi_reader_free(r2);
    free(other);
    gi_reader_free(r);

    /* A file without META cannot vouch for its inputs. */
    craft_sec s[] = {{"DATA", 64, 5, "abcde", 0}};
    unsigned char d[256];
    n = craft(d, sizeof d, MAGIC, 1, 0, s, 1, 0);
    assert_int_equal(open_mem(d, n, &r, &st), 0);
    assert_int_equal(gi_container_check_input(r, "input.scene.hash", "00", &st), GI_EXIT_DATA);
    assert_has(st.msg, "t.gip: section 'META' missing");
    gi_reader_free(r);
    unlink(path);
}

/* ---- writer failures and temp files --------------------------------------------- */

static void test_write_success_leaves_only_target(void **state)
{
    char dir[512], path[600];
    gi_status st = {0};
    path_in(dir, sizeof dir, "ok");
    assert_int_equal(mkdir(dir, 0700), 0);
    snprintf(path, sizeof path, "%s/out.gip", dir);
    gi_writer *w = sample_writer(1000);
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    assert_int_equal(count_entries(dir, ".tmp."), 1);
    /* Overwriting an existing file works the same way. */
    assert_int_equal(gi_writer_write(w, path, &st), 0);
    assert_int_equal(count_entries(dir, ".tmp."), 1);
    gi_writer_free(w);
    gi_reader *r;
    assert_int_equal(gi_reader_open(path, MAGIC, 1, &r, &st), 0);
    gi_reader_free(r);
}

static void test_write_fail_no_directory(void **state)
{
    char path[512];
    gi_status st = {0};
    int before = count_entries(g_dir, NULL);
    path_in(path, sizeof path, "no-such-dir/out.gip");
    gi_writer *w = sample_writer(0);
    assert_int_equal(gi_writer_write(w, path, &st), GI_EXIT_SYSTEM);
    gi_writer_free(w);
    assert_has(st.msg, "no-such-dir/out.gip.tmp.");
    assert_has(st.msg, strerror(ENOENT));
    assert_int_equal(count_entries(g_dir, ".tmp."), before);
}

/* rename fails (the target is a directory): the temp file is removed. */
static void test_write_fail_rename(void **state)
{
    char dir[512], path[600];
    gi_status st = {0};
    path_in(dir, sizeof dir, "rn");
    assert_int_equal(mkdir(dir, 0700), 0);
    snprintf(path, sizeof path, "%s/target", dir);
    assert_int_equal(mkdir(path, 0700), 0);
    gi_writer *w = sample_writer(0);
    assert_int_equal(gi_writer_write(w, path, &st), GI_EXIT_SYSTEM);
    gi_writer_free(w);
    assert_has(st.msg, "cannot rename");
    assert_int_equal(count_entries(dir, ".tmp."), 1);
}

/* A write error part-way (file size limit): temp removed, old file intact. */
static void test_write_fail_midway(void **state)
{
    char dir[512], path[600];
    gi_status st = {0};
    path_in(dir, sizeof dir, "mid");
    assert_int_equal(mkdir(dir, 0700), 0);
    snprintf(path, sizeof path, "%s/out.gip", dir);
    write_bytes(path, "old contents", 12);

    gi_writer *w = sample_writer(1 << 20);
    struct rlimit old, lim;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
    void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
    lim = old;
    lim.rlim_cur = 65536;
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
    int rc = gi_writer_write(w, path, &st);
    setrlimit(RLIMIT_FSIZE, &old);
    signal(SIGXFSZ, prev);
    gi_writer_free(w);
    assert_int_equal(rc, GI_EXIT_SYSTEM);
    assert_has(st.msg, ".tmp.");
    assert_has(st.msg, strerror(EFBIG));
    assert_int_equal(count_entries(dir, ".tmp."), 1);
    size_t n;
    unsigned char *p = read_all(path, &n);
    assert_int_equal(n, 12);
    assert_memory_equal(p, "old contents", 12);
    free(p);
}

static void test_signal_cleanup(void **state)
{
    char path[512], keep[512];
    path_in(path, sizeof path, "pending.gip.tmp.1");
    path_in(keep, sizeof keep, "finished.gip.tmp.1");
    write_bytes(path, "x", 1);
    write_bytes(keep, "y", 1);
    char tmp[64];
    assert_int_equal(gi_container_temp_path("a/b.gip", tmp, sizeof tmp), 0);
    char want[64];
    snprintf(want, sizeof want, "a/b.gip.tmp.%ld", (long)getpid());
    assert_string_equal(tmp, want);
    assert_int_equal(gi_container_temp_path("a/b.gip", tmp, 8), -1);

    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        gi_container_install_signal_cleanup();
        gi_container_install_signal_cleanup(); /* idempotent */
        int h1 = gi_container_temp_register(keep);
        int h2 = gi_container_temp_register(path);
        gi_container_temp_unregister(h1);
        if (h1 < 0 || h2 < 0)
            _exit(3);
        raise(SIGTERM);
        _exit(4); /* not reached */
    }
    int status;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFSIGNALED(status));
    assert_int_equal(WTERMSIG(status), SIGTERM);
    assert_int_equal(access(path, F_OK), -1);
    assert_int_equal(errno, ENOENT);
    assert_int_equal(access(keep, F_OK), 0);

    /* An ignored signal stays ignored (nohup): nothing is removed. */
    write_bytes(path, "x", 1);
    pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        signal(SIGHUP, SIG_IGN);
        gi_container_install_signal_cleanup();
        gi_container_temp_register(path);
        raise(SIGHUP);
        _exit(7);
    }
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 7);
    assert_int_equal(access(path, F_OK), 0);
    unlink(path);
    unlink(keep);

    /* The registry has a fixed number of slots and reuses freed ones. */
    int h[9];
    int got = 0;
    for (int i = 0; i < 9; i++) {
        h[i] = gi_container_temp_register("/nonexistent/x");
        got += h[i] >= 0;
    }
    assert_int_equal(got, 8);
    assert_int_equal(h[8], -1);
    gi_container_temp_unregister(h[3]);
    assert_int_equal(gi_container_temp_register("/nonexistent/y"), h[3]);
    for (int i = 0; i < 8; i++)
        gi_container_temp_unregister(h[i]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_le_integers),
        cmocka_unit_test(test_le_floats_bit_exact),
        cmocka_unit_test(test_crc32_known),
        cmocka_unit_test(test_file_crc32),
        cmocka_unit_test(test_hash64),
        cmocka_unit_test(test_buf),
        cmocka_unit_test(test_roundtrip),
        cmocka_unit_test(test_writer_matches_spec),
        cmocka_unit_test(test_deterministic),
        cmocka_unit_test(test_minor_version_accepted),
        cmocka_unit_test(test_unknown_sections_and_gaps),
        cmocka_unit_test(test_truncation_every_offset),
        cmocka_unit_test(test_truncation_at_boundaries),
        cmocka_unit_test(test_flip_every_byte),
        cmocka_unit_test(test_wrong_magic),
        cmocka_unit_test(test_unknown_major),
        cmocka_unit_test(test_bad_layouts),
        cmocka_unit_test(test_open_errors),
        cmocka_unit_test(test_open_fifo),
        cmocka_unit_test(test_cursor_bounds),
        cmocka_unit_test(test_meta_build_and_lookup),
        cmocka_unit_test(test_check_input),
        cmocka_unit_test(test_write_success_leaves_only_target),
        cmocka_unit_test(test_write_fail_no_directory),
        cmocka_unit_test(test_write_fail_rename),
        cmocka_unit_test(test_write_fail_midway),
        cmocka_unit_test(test_signal_cleanup),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
