/* fuzz_gih.c - libFuzzer harness for the .gih reader (gi_hvds_read): arbitrary
 * bytes must give either an HVDS whose every documented promise holds
 * (docs/formats.md, ".gih", "Reader checks") or GI_EXIT_DATA with a message
 * naming the file, never a crash, a leak or undefined behaviour.
 *
 * gi_hvds_read takes a path and a scene, so the harness builds a small scene
 * once (a closed single-sided room with a double-sided panel in it, written
 * by gi_gltf_builder and loaded back) and writes each input to one file in a
 * private temporary directory (in /dev/shm if it can; removed at exit). The
 * .gip it pretends to pair with is never made: its fingerprint is the
 * constant FUZZ_GIP_FINGERPRINT and its photon count FUZZ_PHOTONS, and the
 * seeds' photon vertices are placed by hand on the scene (gi_gip_new) before
 * gi_hvds_build traces the gathering rays. So the seeds depend on the scene
 * and the HVDS build, not on the photon tracer.
 *
 * Each input is tried twice: as given, and "repaired" (magic, major version,
 * file size, section count, every computable section CRC and the header CRC
 * set right from the container layout) so that mutations get past the
 * checksums to the HVDS checks behind them.
 *
 * Seeds: at start-up the harness builds two valid files (rejection and
 * k-means gathering), checks that they read back, and writes them as
 * rejection.seed and kmeans.seed into the first corpus directory given on
 * the command line when they are missing or differ there (so stale
 * checked-in seeds heal themselves in the scratch corpus). With
 * GI_FUZZ_GIH_SEEDS=DIR they are also written to DIR: that is how
 * tests/fuzz/corpus/fuzz_gih/ was made. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gi_container.h"
#include "gi_crc32.h"
#include "gi_gip.h"
#include "gi_gltf_write.h"
#include "gi_hvds.h"
#include "gi_le.h"
#include "gi_log.h"
#include "gi_rt.h"
#include "gi_scene.h"

#define FUZZ_GIP_FINGERPRINT 0x0123456789abcdefULL
#define FUZZ_PHOTONS 96u
#define FUZZ_MAX_REPAIR ((size_t)1 << 20)

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char g_dir[512];
static char g_path[600];
static gi_scene *g_scene;

static void fail(const char *what, const gi_status *st)
{
    fprintf(stderr, "fuzz_gih: %s%s%s\n", what, st ? ": " : "", st ? st->msg : "");
    abort();
}

static void cleanup(void)
{
    if (g_path[0])
        unlink(g_path);
    if (g_dir[0])
        rmdir(g_dir);
    gi_scene_free(g_scene);
    g_scene = NULL;
}

/* ---- the promises of an accepted file ---------------------------------------- */

static void check_hvds(const gi_hvds *h, const gi_scene *s)
{
    if (h->scene_hash != s->hash || h->gip_fingerprint != FUZZ_GIP_FINGERPRINT ||
        h->num_photons != FUZZ_PHOTONS || h->depth > GI_HVDS_MAX_DEPTH)
        abort();
    if (h->opts.gather != GI_GATHER_REJECTION && h->opts.gather != GI_GATHER_KMEANS)
        abort();
    unsigned sink = 0;
    const uint32_t K = h->num_keys;
    for (uint32_t i = 0; i < K; i++) {
        uint32_t p = h->key_parent[i];
        if (p != GI_HVDS_NO_KEY && (p <= i || p >= K))
            abort();
        if (!isfinite(h->key_scale[i]) || !(h->key_scale[i] >= 0.0f))
            abort();
        sink += h->key_level[i];
    }
    for (uint64_t i = 0; i < h->num_photons; i++)
        if (h->photon_key[i] != GI_HVDS_NO_KEY && h->photon_key[i] >= K)
            abort();
    for (uint32_t i = 0; i < h->num_pairs; i++) {
        if (h->pair_key[i] >= K)
            abort();
        sink += h->pair_count[i];
        if (h->pair_dir) /* GDIR (1.1): one direction per pair, all readable */
            sink += (unsigned)(h->pair_dir[3 * (size_t)i] + h->pair_dir[3 * (size_t)i + 1] + h->pair_dir[3 * (size_t)i + 2]);
    }
    for (uint32_t i = 0; i < h->num_gpoints; i++) {
        const gi_gpoint *g = &h->gpoints[i];
        for (int a = 0; a < 3; a++)
            if (!isfinite(g->pos[a]) || !isfinite(g->nrm[a]))
                abort();
        if (!isfinite(g->radius) || !(g->radius > 0.0f) || g->tri >= s->num_triangles)
            abort();
        if ((uint64_t)g->first_pair + g->num_pairs > h->num_pairs)
            abort();
        /* a consumer walks the point's pairs: they must be readable */
        for (uint32_t j = 0; j < g->num_pairs; j++)
            sink += h->pair_key[g->first_pair + j] == GI_HVDS_NO_KEY;
        sink += (unsigned)isnan(g->r_harmonic);
    }
    volatile unsigned keep = sink;
    (void)keep;
}

/* Read g_path; any result but a checked HVDS or GI_EXIT_DATA naming the file aborts. */
static void read_file(void)
{
    static gi_hvds sentinel;
    gi_status st = {0};
    gi_hvds *h = &sentinel; /* the reader must set it, also on failure */
    int rc = gi_hvds_read(g_path, g_scene, FUZZ_GIP_FINGERPRINT, FUZZ_PHOTONS, &h, &st);
    if (rc == 0) {
        if (!h || st.code != 0)
            abort();
        check_hvds(h, g_scene);
        gi_hvds_free(h);
        return;
    }
    if (h != NULL || rc != GI_EXIT_DATA || st.code != rc || strncmp(st.msg, g_path, strlen(g_path)) != 0)
        fail("bad failure", &st);
}

static int write_bytes(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return -1;
    size_t n = size ? fwrite(data, 1, size, f) : 0;
    int bad = n != size;
    bad |= fclose(f) != 0;
    return bad ? -1 : 0;
}

static void try_bytes(const void *data, size_t size)
{
    if (write_bytes(g_path, data, size) != 0) {
        perror(g_path);
        abort();
    }
    read_file();
}

/* ---- repair: make the container layer accept what it can ----------------- */

static void repair_container(unsigned char *d, size_t size)
{
    const size_t hdr = GI_CONTAINER_HEADER_SIZE, ent = GI_CONTAINER_ENTRY_SIZE;
    memcpy(d, GI_HVDS_MAGIC, 8);
    gi_le_put_u16(d + 8, GI_HVDS_MAJOR);
    gi_le_put_u64(d + 16, (uint64_t)size);
    size_t fits = (size - hdr) / ent;
    uint32_t count = gi_le_get_u32(d + 12);
    if (count > fits) {
        count = (uint32_t)fits;
        gi_le_put_u32(d + 12, count);
    }
    unsigned char *table = d + hdr;
    for (uint32_t i = 0; i < count; i++) {
        unsigned char *e = table + ent * i;
        uint64_t off = gi_le_get_u64(e + 8);
        uint64_t len = gi_le_get_u64(e + 16);
        if (off > size || len > size - off)
            continue; /* left for the reader to refuse */
        gi_le_put_u32(e + 24, gi_crc32(d + off, (size_t)len));
    }
    uint32_t crc = gi_crc32_update(gi_crc32(d, 28), table, ent * count);
    gi_le_put_u32(d + 28, crc);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    try_bytes(data, size);
    if (size < GI_CONTAINER_HEADER_SIZE || size > FUZZ_MAX_REPAIR)
        return 0;
    unsigned char *copy = malloc(size);
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    repair_container(copy, size);
    if (memcmp(copy, data, size) != 0)
        try_bytes(copy, size);
    free(copy);
    return 0;
}

/* ---- start-up: scene, seeds ----------------------------------------------- */

/* A closed 1 m room seen from inside (single-sided) with a double-sided
 * 0.5 m panel standing in it: both kinds of key, some occlusion. */
static gi_scene *make_scene(const char *dir)
{
    char path[700];
    snprintf(path, sizeof path, "%s/room.gltf", dir);
    gi_gltf_builder *b = gi_gltf_builder_new();
    if (!b)
        fail("out of memory", NULL);
    float white[3] = {0.7f, 0.7f, 0.7f}, red[3] = {0.6f, 0.1f, 0.1f};
    int wall = gi_gltf_add_material(b, "wall", white, 1.0f, 0.0f, NULL, 0);
    int panel = gi_gltf_add_material(b, "panel", red, 1.0f, 0.0f, NULL, 1);
    float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    gi_gltf_add_box(b, lo, hi, wall, 1);
    float p0[3] = {0.25f, 0.1f, 0.5f}, p1[3] = {0.75f, 0.1f, 0.5f};
    float p2[3] = {0.75f, 0.6f, 0.5f}, p3[3] = {0.25f, 0.6f, 0.5f};
    gi_gltf_add_quad(b, p0, p1, p2, p3, panel);
    gi_status st = {0};
    gi_scene *s = NULL;
    if (gi_gltf_builder_write(b, path, &st) != 0)
        fail("writing the scene", &st);
    gi_gltf_builder_free(b);
    if (gi_scene_load(path, &s, &st) != 0)
        fail("loading the scene", &st);
    unlink(path);
    return s;
}

/* FUZZ_PHOTONS photon vertices spread over the surfaces by a fixed sequence,
 * on the lit side of single-sided triangles and either side of double-sided
 * ones; 8 paths of 12 vertices. Only what gi_hvds_build reads is filled. */
static gi_gip *make_gip(const gi_scene *s)
{
    const uint32_t paths = 8;
    gi_gip *g = gi_gip_new(paths, FUZZ_PHOTONS);
    if (!g)
        fail("out of memory", NULL);
    for (uint32_t p = 0; p <= paths; p++)
        g->path_start[p] = (uint64_t)p * FUZZ_PHOTONS / paths;
    uint32_t x = 12345u;
    for (uint64_t i = 0; i < FUZZ_PHOTONS; i++) {
        x = x * 1664525u + 1013904223u;
        uint32_t t = (x >> 8) % (uint32_t)s->num_triangles;
        x = x * 1664525u + 1013904223u;
        float u = (float)(x >> 16) / 65536.0f;
        x = x * 1664525u + 1013904223u;
        float v = (float)(x >> 16) / 65536.0f;
        if (u + v > 1.0f) {
            u = 1.0f - u;
            v = 1.0f - v;
        }
        g->tri[i] = t;
        g->bary[2 * i] = u;
        g->bary[2 * i + 1] = v;
        g->side[i] = (uint8_t)(s->materials[s->tri_material[t]].double_sided ? (x >> 31) : 0);
        g->q[i] = 255;
    }
    return g;
}

typedef struct seed_file {
    const char *name;
    unsigned char *data;
    size_t size;
} seed_file;

static seed_file g_seeds[2] = {{"rejection.seed", NULL, 0}, {"kmeans.seed", NULL, 0}};

static int slurp(const char *path, unsigned char **data, size_t *size)
{
    *data = NULL;
    *size = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    size_t cap = 0, n = 0;
    unsigned char *buf = NULL;
    for (;;) {
        if (n == cap) {
            size_t ncap = cap ? 2 * cap : 4096;
            unsigned char *nb = realloc(buf, ncap);
            if (!nb) {
                free(buf);
                fclose(f);
                return -1;
            }
            buf = nb;
            cap = ncap;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0)
            break;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(buf);
        return -1;
    }
    *data = buf;
    *size = n;
    return 0;
}

static void make_seeds(const gi_scene *s)
{
    gi_status st = {0};
    gi_rt *rt = NULL;
    if (gi_rt_new(s, &rt, &st) != 0)
        fail("building the ray tracer", &st);
    gi_gip *gip = make_gip(s);
    for (int k = 0; k < 2; k++) {
        gi_hvds_opts o;
        gi_hvds_opts_default(&o);
        o.gather = k == 0 ? GI_GATHER_REJECTION : GI_GATHER_KMEANS;
        o.gather_rays = 4;
        o.r_max = 1.0f;
        o.r_min = 0.6f;
        o.cell_photons = 4.0f;
        o.seed = 7;
        if (k == 1) { /* a different tree and more pairs per point */
            o.gather_rays = 9;
            o.cell_photons = 2.0f;
            o.leak_check = 0;
            o.occlusion_check = 0;
        }
        gi_hvds *h = NULL;
        if (gi_hvds_build(s, rt, gip, FUZZ_GIP_FINGERPRINT, &o, 1, &h, &st) != 0)
            fail("building the seed HVDS", &st);
        if (gi_hvds_write(h, g_path, "room.gltf", "room.gip", &st) != 0)
            fail("writing the seed", &st);
        gi_hvds_free(h);
        if (slurp(g_path, &g_seeds[k].data, &g_seeds[k].size) != 0) {
            perror(g_path);
            abort();
        }
        /* the seed itself must be accepted: otherwise the harness is stale */
        gi_hvds *back = NULL;
        if (gi_hvds_read(g_path, s, FUZZ_GIP_FINGERPRINT, FUZZ_PHOTONS, &back, &st) != 0)
            fail("reading the seed back", &st);
        check_hvds(back, s);
        gi_hvds_free(back);
    }
    gi_gip_free(gip);
    gi_rt_free(rt);
}

/* Write each seed into dir as NAME unless an identical file is there. */
static void put_seeds(const char *dir)
{
    for (int k = 0; k < 2; k++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", dir, g_seeds[k].name);
        unsigned char *old = NULL;
        size_t n = 0;
        int same = slurp(path, &old, &n) == 0 && n == g_seeds[k].size && memcmp(old, g_seeds[k].data, n) == 0;
        free(old);
        if (same)
            continue;
        if (write_bytes(path, g_seeds[k].data, g_seeds[k].size) != 0)
            fprintf(stderr, "fuzz_gih: cannot write %s\n", path);
        else
            fprintf(stderr, "fuzz_gih: wrote %s (%zu bytes)\n", path, g_seeds[k].size);
    }
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    gi_log_set_verbosity(-1);
    /* Every input is written twice: in memory (/dev/shm) that is some 20 times
     * faster than on a disk file system, whose truncations cost milliseconds. */
    const char *tmp = getenv("TMPDIR");
    const char *dirs[3] = {"/dev/shm", tmp && tmp[0] && strlen(tmp) < 400 ? tmp : "/tmp", "/tmp"};
    int made = 0;
    for (int i = 0; i < 3 && !made; i++) {
        snprintf(g_dir, sizeof g_dir, "%s/gi_fuzz_gih.XXXXXX", dirs[i]);
        made = mkdtemp(g_dir) != NULL;
    }
    if (!made) {
        perror(g_dir);
        abort();
    }
    snprintf(g_path, sizeof g_path, "%s/input.gih", g_dir);
    atexit(cleanup);
    g_scene = make_scene(g_dir);
    make_seeds(g_scene);
    const char *out = getenv("GI_FUZZ_GIH_SEEDS");
    if (out && out[0])
        put_seeds(out);
    /* the first corpus directory, if any: libFuzzer reads it after this */
    for (int i = 1; i < *argc; i++) {
        const char *a = (*argv)[i];
        struct stat sb;
        if (a[0] == '-')
            continue;
        if (stat(a, &sb) == 0 && S_ISDIR(sb.st_mode))
            put_seeds(a);
        break;
    }
    for (int k = 0; k < 2; k++) {
        free(g_seeds[k].data);
        g_seeds[k].data = NULL;
    }
    return 0;
}
