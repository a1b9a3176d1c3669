/* gi_gip.c - the .gip file: entry points and photon paths, written and read
 * through the gi container with every count and index validated (layout in
 * docs/formats.md, section ".gip (gi-precompute)"). */
#define _POSIX_C_SOURCE 200809L
#include "gi_gip.h"
#include "gi_mem.h"
#include "gi_rt.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_container.h"
#include "gi_crc32.h"
#include "gi_le.h"
#include "gi_math.h"

#ifndef GI_VERSION
#define GI_VERSION "dev"
#endif

/* Bytes per element of each section (formats.md). */
#define ENTR_HEADER 16u
#define ENTR_PER_ENTRY 18u /* dA f32 + base 3 x f32 + path length u16 */
#define REFL_PER_PHOTON 4u
#define DETL_PER_PHOTON 26u
#define STAT_SIZE 56u
/* Barycentrics may exceed the triangle by this much (float rounding of hits). */
#define BARY_SLACK 1e-5f

/* ---- small encodings ------------------------------------------------------- */

#define RGB9E5_BIAS 15
#define RGB9E5_MANT 9
#define RGB9E5_MAX 65408.0f /* (511 / 512) * 2^16 */

uint32_t gi_rgb9e5_pack(const float rgb[3])
{
    float c[3];
    for (int k = 0; k < 3; k++) {
        float v = rgb[k];
        c[k] = v > 0.0f ? (v < RGB9E5_MAX ? v : RGB9E5_MAX) : 0.0f; /* NaN and negatives: 0 */
    }
    float m = fmaxf(c[0], fmaxf(c[1], c[2]));
    if (!(m > 0.0f))
        return 0;
    int e2;
    frexpf(m, &e2); /* m = f 2^e2, f in [0.5, 1): floor(log2 m) = e2 - 1 */
    int fl = e2 - 1;
    if (fl < -RGB9E5_BIAS - 1)
        fl = -RGB9E5_BIAS - 1;
    int e = fl + 1 + RGB9E5_BIAS; /* 0..31 */
    float scale = ldexpf(1.0f, e - RGB9E5_BIAS - RGB9E5_MANT);
    if ((int)floorf(m / scale + 0.5f) == (1 << RGB9E5_MANT)) {
        e++;
        scale *= 2.0f;
    }
    uint32_t out = (uint32_t)e << 27;
    for (int k = 0; k < 3; k++) {
        uint32_t q = (uint32_t)floorf(c[k] / scale + 0.5f);
        if (q > 511u)
            q = 511u;
        out |= q << (9 * k);
    }
    return out;
}

void gi_rgb9e5_unpack(uint32_t v, float rgb[3])
{
    int e = (int)(v >> 27);
    float scale = ldexpf(1.0f, e - RGB9E5_BIAS - RGB9E5_MANT);
    for (int k = 0; k < 3; k++)
        rgb[k] = (float)((v >> (9 * k)) & 511u) * scale;
}

static inline float sgn_nz(float x) { return x >= 0.0f ? 1.0f : -1.0f; }

/* Octahedral projection of v onto the unit square [-1,1]^2. */
static void oct_fold(const float v[3], float *x, float *y)
{
    float l1 = fabsf(v[0]) + fabsf(v[1]) + fabsf(v[2]);
    if (!(l1 > 0.0f) || !isfinite(l1)) {
        *x = *y = 0.0f;
        return;
    }
    float px = v[0] / l1, py = v[1] / l1;
    if (v[2] < 0.0f) {
        float tx = (1.0f - fabsf(py)) * sgn_nz(px);
        float ty = (1.0f - fabsf(px)) * sgn_nz(py);
        px = tx;
        py = ty;
    }
    *x = gi_clampf(px, -1.0f, 1.0f);
    *y = gi_clampf(py, -1.0f, 1.0f);
}

void gi_gip_oct_decode(const int16_t e[2], float v[3])
{
    float x = fmaxf((float)e[0] / 32767.0f, -1.0f), y = fmaxf((float)e[1] / 32767.0f, -1.0f);
    float z = 1.0f - fabsf(x) - fabsf(y);
    if (z < 0.0f) {
        float tx = (1.0f - fabsf(y)) * sgn_nz(x);
        float ty = (1.0f - fabsf(x)) * sgn_nz(y);
        x = tx;
        y = ty;
    }
    float l = sqrtf(x * x + y * y + z * z);
    v[0] = x / l;
    v[1] = y / l;
    v[2] = z / l;
}

void gi_gip_oct_encode(const float v[3], int16_t e[2])
{
    float x, y;
    oct_fold(v, &x, &y);
    if (x == 0.0f && y == 0.0f && !(fabsf(v[2]) > 0.0f)) {
        e[0] = e[1] = 0; /* the zero vector (entry w_in) */
        return;
    }
    /* Of the four roundings around the exact point, keep the one that decodes
     * closest to v (Cigolle et al. 2014, "precise" encoding). The candidates
     * differ by ~1e-9 in their cosine, below float resolution, so they are
     * compared by the sine of the angle, in double. */
    double vx = v[0], vy = v[1], vz = v[2];
    double vl = sqrt(vx * vx + vy * vy + vz * vz);
    vx /= vl;
    vy /= vl;
    vz /= vl;
    float fx = floorf(x * 32767.0f), fy = floorf(y * 32767.0f);
    double best = INFINITY;
    e[0] = e[1] = 0;
    for (int i = 0; i < 4; i++) {
        float cx = gi_clampf(fx + (float)(i & 1), -32767.0f, 32767.0f);
        float cy = gi_clampf(fy + (float)(i >> 1), -32767.0f, 32767.0f);
        double px = cx / 32767.0, py = cy / 32767.0, pz = 1.0 - fabs(px) - fabs(py);
        if (pz < 0.0) {
            double tx = (1.0 - fabs(py)) * (px >= 0.0 ? 1.0 : -1.0);
            double ty = (1.0 - fabs(px)) * (py >= 0.0 ? 1.0 : -1.0);
            px = tx;
            py = ty;
        }
        double pl = sqrt(px * px + py * py + pz * pz);
        px /= pl;
        py /= pl;
        pz /= pl;
        double sx = py * vz - pz * vy, sy = pz * vx - px * vz, sz = px * vy - py * vx;
        double sin2 = sx * sx + sy * sy + sz * sz;
        if (px * vx + py * vy + pz * vz < 0.0)
            sin2 = 4.0 + sin2; /* the opposite hemisphere: never better */
        if (sin2 < best) {
            best = sin2;
            e[0] = (int16_t)cx;
            e[1] = (int16_t)cy;
        }
    }
}

/* ---- allocation ------------------------------------------------------------- */

void gi_gip_opts_default(gi_gip_opts *o)
{
    memset(o, 0, sizeof *o);
    o->photons = 1000000;
    o->max_bounces = -1;
    o->seed = 1;
    o->region_grid = 4;
    o->region_min_visible = 8192;
    o->region_max_skew = 1.0f;
}

gi_gip *gi_gip_new(uint32_t num_entries, uint64_t num_photons)
{
    if (num_photons > SIZE_MAX / 16 - 1)
        return NULL;
    gi_gip *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    gi_gip_opts_default(&g->opts);
    size_t n = num_entries, p = (size_t)num_photons;
    g->num_entries = num_entries;
    g->num_photons = num_photons;
    g->path_start = gi_calloc_large(n + 1, sizeof *g->path_start);
    g->entry_dA = gi_calloc_large(n + 1, sizeof *g->entry_dA);
    g->entry_base = gi_calloc_large(3 * n + 1, sizeof *g->entry_base);
    g->refl = gi_calloc_large(p + 1, sizeof *g->refl);
    g->tri = gi_calloc_large(p + 1, sizeof *g->tri);
    g->bary = gi_calloc_large(2 * p + 1, sizeof *g->bary);
    g->side = gi_calloc_large(p + 1, sizeof *g->side);
    g->w_in = gi_calloc_large(3 * p + 1, sizeof *g->w_in);
    g->w_out = gi_calloc_large(3 * p + 1, sizeof *g->w_out);
    g->pdf = gi_calloc_large(p + 1, sizeof *g->pdf);
    g->q = gi_calloc_large(p + 1, sizeof *g->q);
    if (!g->path_start || !g->entry_dA || !g->entry_base || !g->refl || !g->tri || !g->bary ||
        !g->side || !g->w_in || !g->w_out || !g->pdf || !g->q) {
        gi_gip_free(g);
        return NULL;
    }
    g->path_start[n] = num_photons;
    return g;
}

void gi_gip_free(gi_gip *g)
{
    if (!g)
        return;
    free(g->opts.fixed);
    free(g->path_start);
    free(g->entry_dA);
    free(g->entry_base);
    free(g->refl);
    free(g->tri);
    free(g->bary);
    free(g->side);
    free(g->w_in);
    free(g->w_out);
    free(g->pdf);
    free(g->q);
    free(g);
}

uint64_t gi_gip_compact_bytes(const gi_gip *g)
{
    return ENTR_HEADER + (uint64_t)ENTR_PER_ENTRY * g->num_entries +
           (uint64_t)REFL_PER_PHOTON * g->num_photons;
}

uint64_t gi_gip_detail_bytes(const gi_gip *g) { return (uint64_t)DETL_PER_PHOTON * g->num_photons; }

/* ---- geometry of a stored vertex --------------------------------------------- */

/* The surface at a stored vertex comes from gi_scene_surface (gi_rt.h), the
 * same reconstruction the ray tracer uses at its hits. */

void gi_gip_vertex(const gi_gip *g, const gi_scene *s, uint64_t i, float pos[3], float nrm[3])
{
    gi_surface sf;
    gi_scene_surface(s, g->tri[i], g->bary[2 * i], g->bary[2 * i + 1], &sf);
    gi_vec3 ng = g->side[i] ? gi_neg(sf.ng) : sf.ng;
    gi_vec3 ns = gi_dot(sf.ns, ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
    gi_v3store(pos, sf.p);
    gi_v3store(nrm, ns);
}

void gi_gip_reflectance(const gi_gip *g, const gi_scene *s, const gi_material *materials,
                        uint64_t i, const float w_in[3], float rgb[3])
{
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    gi_vec3 wi = gi_v3p(w_in ? w_in : g->w_in + 3 * i);
    gi_vec3 wo = gi_v3p(g->w_out + 3 * i);
    if (!(gi_dot(wi, wi) > 0.0f) || !(g->pdf[i] > 0.0f) || g->q[i] == 0)
        return;
    uint32_t t = g->tri[i];
    gi_surface sf;
    gi_scene_surface(s, t, g->bary[2 * i], g->bary[2 * i + 1], &sf);
    gi_vec3 ng = g->side[i] ? gi_neg(sf.ng) : sf.ng;
    gi_vec3 ns = gi_dot(sf.ns, ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
    if (gi_dot(ns, wi) <= 0.0f)
        ns = ng; /* the same fallback as the tracer (gi_photon.c, gi_pt.c) */
    const gi_material *m = &materials[s->tri_material[t]];
    float base[3];
    gi_scene_base_color(s, m, sf.uv0, sf.uv1, base);
    gi_bsdf b;
    gi_bsdf_init(&b, m, gi_v3p(base));
    gi_vec3 f = gi_bsdf_eval(&b, ns, wi, wo);
    float c = gi_dot(ns, wo);
    if (!(c > 0.0f))
        return;
    float k = c / (g->pdf[i] * ((float)g->q[i] / 255.0f));
    gi_v3store(rgb, gi_scale(f, k));
}

/* ---- writer ----------------------------------------------------------------- */

static int add_meta(const gi_gip *g, gi_buf *meta, const gi_scene *scene, const char *scene_path,
                    gi_status *st)
{
    const gi_gip_opts *o = &g->opts;
    int rc;
    if ((rc = gi_meta_add(meta, "tool", "gi-precompute", st)) ||
        (rc = gi_meta_add(meta, "version", GI_VERSION, st)) ||
        (rc = gi_meta_addf(meta, "option.photons", st, "%" PRIu64, o->photons)))
        return rc;
    if (o->max_bounces < 0)
        rc = gi_meta_add(meta, "option.max-bounces", "none", st);
    else
        rc = gi_meta_addf(meta, "option.max-bounces", st, "%d", o->max_bounces);
    if (rc || (rc = gi_meta_addf(meta, "option.seed", st, "%" PRIu64, o->seed)))
        return rc;
    if (o->has_region) {
        /* %.9g gives back the same float when parsed. */
        if ((rc = gi_meta_addf(meta, "option.region", st, "%.9g %.9g %.9g %.9g %.9g %.9g",
                               (double)o->region_min[0], (double)o->region_min[1],
                               (double)o->region_min[2], (double)o->region_max[0],
                               (double)o->region_max[1], (double)o->region_max[2])) ||
            (rc = gi_meta_addf(meta, "option.region-grid", st, "%d", o->region_grid)) ||
            (rc = gi_meta_addf(meta, "option.region-min-visible", st, "%" PRIu32,
                               o->region_min_visible)) ||
            (rc = gi_meta_addf(meta, "option.region-max-skew", st, "%.9g",
                               (double)o->region_max_skew)))
            return rc;
    } else if ((rc = gi_meta_add(meta, "option.region", "none", st))) {
        return rc;
    }
    if ((rc = gi_meta_addf(meta, "option.fixed-material.count", st, "%zu", o->num_fixed)))
        return rc;
    for (size_t i = 0; i < o->num_fixed; i++) {
        char key[64];
        snprintf(key, sizeof key, "option.fixed-material.%zu", i);
        if ((rc = gi_meta_add(meta, key, o->fixed[i], st)))
            return rc;
    }
    return gi_meta_add_input(meta, "scene", scene_path, scene->hash, st);
}

int gi_gip_write(const gi_gip *g, const char *path, const gi_scene *scene, const char *scene_path,
                 gi_status *st)
{
    if (g->scene_hash != scene->hash)
        return gi_status_set(st, GI_EXIT_USAGE,
                             "%s: the photon paths were made from another scene than '%s'", path,
                             scene_path);
    const uint64_t N = g->num_entries, P = g->num_photons;
    gi_buf meta, entr, refl, detl, stat;
    gi_buf_init(&meta);
    gi_buf_init(&entr);
    gi_buf_init(&refl);
    gi_buf_init(&detl);
    gi_buf_init(&stat);
    gi_writer *w = NULL;
    int rc = add_meta(g, &meta, scene, scene_path, st);
    if (rc)
        goto done;
    if (N > SIZE_MAX / 32 || P > SIZE_MAX / 32) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s: too many photons for memory", path);
        goto done;
    }

    for (uint64_t i = 0; i < N; i++) {
        uint64_t len = g->path_start[i + 1] - g->path_start[i];
        if (g->path_start[i + 1] <= g->path_start[i] || len > GI_GIP_MAX_PATH) {
            rc = gi_status_set(st, GI_EXIT_USAGE,
                               "%s: path %" PRIu64 " has %" PRId64 " vertices, not 1 to %d", path,
                               i, (int64_t)len, GI_GIP_MAX_PATH);
            goto done;
        }
    }
    if (N == 0 || g->path_start[0] != 0 || g->path_start[N] != P) {
        rc = gi_status_set(st, GI_EXIT_USAGE, "%s: paths do not cover the %" PRIu64 " photons", path, P);
        goto done;
    }
    gi_buf_reserve(&entr, (size_t)(ENTR_HEADER + ENTR_PER_ENTRY * N));
    gi_buf_put_u32(&entr, g->num_entries);
    gi_buf_put_u32(&entr, g->num_uniform);
    gi_buf_put_u64(&entr, P);
    for (uint64_t i = 0; i < N; i++)
        gi_buf_put_f32(&entr, g->entry_dA[i]);
    for (uint64_t i = 0; i < 3 * N; i++)
        gi_buf_put_f32(&entr, g->entry_base[i]);
    for (uint64_t i = 0; i < N; i++)
        gi_buf_put_u16(&entr, (uint16_t)(g->path_start[i + 1] - g->path_start[i]));

    gi_buf_reserve(&refl, (size_t)(REFL_PER_PHOTON * P));
    for (uint64_t i = 0; i < P; i++)
        gi_buf_put_u32(&refl, g->refl[i]);

    gi_buf_reserve(&detl, (size_t)(DETL_PER_PHOTON * P));
    for (uint64_t i = 0; i < P; i++)
        gi_buf_put_u32(&detl, g->tri[i]);
    for (uint64_t i = 0; i < 2 * P; i++)
        gi_buf_put_f32(&detl, g->bary[i]);
    for (uint64_t i = 0; i < P; i++)
        gi_buf_put_f32(&detl, g->pdf[i]);
    for (int which = 0; which < 2; which++) {
        const float *d = which ? g->w_out : g->w_in;
        for (uint64_t i = 0; i < P; i++) {
            int16_t e[2];
            gi_gip_oct_encode(d + 3 * i, e);
            gi_buf_put_u16(&detl, (uint16_t)e[0]);
            gi_buf_put_u16(&detl, (uint16_t)e[1]);
        }
    }
    gi_buf_put_bytes(&detl, g->side, (size_t)P);
    gi_buf_put_bytes(&detl, g->q, (size_t)P);

    gi_buf_put_u64(&stat, g->skipped_degenerate);
    gi_buf_put_u64(&stat, g->escaped);
    gi_buf_put_u64(&stat, g->absorbed);
    gi_buf_put_u64(&stat, g->roulette);
    gi_buf_put_u64(&stat, g->capped);
    gi_buf_put_u32(&stat, g->region_batches);
    gi_buf_put_u32(&stat, 0);
    gi_buf_put_f64(&stat, g->pilot_mean);

    w = gi_writer_new(GI_GIP_MAGIC, GI_GIP_MAJOR, GI_GIP_MINOR);
    if (!w) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
        goto done;
    }
    if ((rc = gi_writer_add_buf(w, "META", 0, &meta, st)) ||
        (rc = gi_writer_add_buf(w, "ENTR", 0, &entr, st)) ||
        (rc = gi_writer_add_buf(w, "REFL", 0, &refl, st)) ||
        (rc = gi_writer_add_buf(w, "DETL", 0, &detl, st)) ||
        (rc = gi_writer_add_buf(w, "STAT", 0, &stat, st)))
        goto done;
    rc = gi_writer_write(w, path, st);
done:
    gi_writer_free(w);
    gi_buf_release(&meta);
    gi_buf_release(&entr);
    gi_buf_release(&refl);
    gi_buf_release(&detl);
    gi_buf_release(&stat);
    return rc;
}

/* ---- reader ------------------------------------------------------------------ */

static int meta_need(const gi_reader *r, const char *key, const char **v, gi_status *st)
{
    *v = gi_reader_meta(r, key);
    if (!*v)
        return gi_status_set(st, GI_EXIT_DATA, "%s: section 'META': no '%s' recorded",
                             gi_reader_name(r), key);
    return 0;
}

static int meta_bad(const gi_reader *r, const char *key, const char *v, gi_status *st)
{
    return gi_status_set(st, GI_EXIT_DATA, "%s: section 'META': %s: bad value '%.64s'",
                         gi_reader_name(r), key, v);
}

static int meta_u64(const gi_reader *r, const char *key, uint64_t lo, uint64_t hi, uint64_t *out,
                    gi_status *st)
{
    const char *v;
    int rc = meta_need(r, key, &v, st);
    if (rc)
        return rc;
    char *end;
    errno = 0;
    unsigned long long x = strtoull(v, &end, 10);
    if (errno || end == v || *end || v[0] == '-' || v[0] == '+' || v[0] == ' ' || x < lo || x > hi)
        return meta_bad(r, key, v, st);
    *out = (uint64_t)x;
    return 0;
}

/* n floats separated by single spaces, each finite. */
static int meta_floats(const gi_reader *r, const char *key, float *out, int n, gi_status *st)
{
    const char *v;
    int rc = meta_need(r, key, &v, st);
    if (rc)
        return rc;
    const char *p = v;
    for (int i = 0; i < n; i++) {
        if (i > 0) {
            if (*p != ' ')
                return meta_bad(r, key, v, st);
            p++;
        }
        if (*p == ' ' || *p == '\0')
            return meta_bad(r, key, v, st);
        char *end;
        errno = 0;
        float x = strtof(p, &end);
        if (errno || end == p || !isfinite(x))
            return meta_bad(r, key, v, st);
        out[i] = x;
        p = end;
    }
    if (*p)
        return meta_bad(r, key, v, st);
    return 0;
}

static int read_opts(const gi_reader *r, gi_gip_opts *o, gi_status *st)
{
    gi_gip_opts_default(o);
    uint64_t x;
    const char *v;
    int rc;
    if ((rc = meta_u64(r, "option.photons", 1, UINT64_MAX, &o->photons, st)) ||
        (rc = meta_need(r, "option.max-bounces", &v, st)))
        return rc;
    if (strcmp(v, "none") == 0) {
        o->max_bounces = -1;
    } else {
        if ((rc = meta_u64(r, "option.max-bounces", 0, GI_GIP_MAX_PATH - 1, &x, st)))
            return rc;
        o->max_bounces = (int)x;
    }
    if ((rc = meta_u64(r, "option.seed", 0, UINT64_MAX, &o->seed, st)) ||
        (rc = meta_need(r, "option.region", &v, st)))
        return rc;
    if (strcmp(v, "none") != 0) {
        float b[6];
        if ((rc = meta_floats(r, "option.region", b, 6, st)))
            return rc;
        if (b[0] > b[3] || b[1] > b[4] || b[2] > b[5])
            return meta_bad(r, "option.region", v, st);
        o->has_region = 1;
        memcpy(o->region_min, b, sizeof o->region_min);
        memcpy(o->region_max, b + 3, sizeof o->region_max);
        if ((rc = meta_u64(r, "option.region-grid", 1, 64, &x, st)))
            return rc;
        o->region_grid = (int)x;
        if ((rc = meta_u64(r, "option.region-min-visible", 0, UINT32_MAX, &x, st)))
            return rc;
        o->region_min_visible = (uint32_t)x;
        if ((rc = meta_floats(r, "option.region-max-skew", &o->region_max_skew, 1, st)))
            return rc;
        if (!(o->region_max_skew >= 0.0f))
            return meta_bad(r, "option.region-max-skew", gi_reader_meta(r, "option.region-max-skew"),
                            st);
    }
    if ((rc = meta_u64(r, "option.fixed-material.count", 0, 1 << 16, &x, st)))
        return rc;
    if (x > 0) {
        o->fixed = calloc((size_t)x, sizeof *o->fixed);
        if (!o->fixed)
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", gi_reader_name(r));
        o->num_fixed = (size_t)x;
        for (size_t i = 0; i < o->num_fixed; i++) {
            char key[64];
            snprintf(key, sizeof key, "option.fixed-material.%zu", i);
            if ((rc = meta_need(r, key, &v, st)))
                return rc;
            if (strlen(v) >= GI_NAME_MAX)
                return meta_bad(r, key, v, st);
            strcpy(o->fixed[i], v);
        }
    }
    return 0;
}

/* Report a bad element at byte `at` of the cursor's section. */
static int fail_at(gi_cursor *c, size_t at, gi_status *st, const char *what, uint64_t index,
                   const char *detail)
{
    c->pos = at;
    return gi_cursor_fail(c, st, "%s %" PRIu64 ": %s", what, index, detail);
}

static int parse(const gi_reader *r, const gi_scene *scene, gi_gip **out, gi_status *st)
{
    const char *nm = gi_reader_name(r);
    char hex[17];
    gi_hash64_hex(scene->hash, hex);
    int rc = gi_container_check_input(r, "input.scene.hash", hex, st);
    if (rc)
        return rc;
    gi_gip_opts opts;
    if ((rc = read_opts(r, &opts, st))) {
        free(opts.fixed);
        return rc;
    }

    /* sizes first: every count is checked against the bytes present before
     * anything is allocated for it */
    gi_cursor ce, cr, cd, cs;
    uint32_t N = 0, U = 0;
    uint64_t P = 0;
    if ((rc = gi_reader_cursor(r, "ENTR", &ce, st)) || (rc = gi_reader_cursor(r, "REFL", &cr, st)) ||
        (rc = gi_reader_cursor(r, "DETL", &cd, st)) || (rc = gi_reader_cursor(r, "STAT", &cs, st)) ||
        (rc = gi_cursor_u32(&ce, &N, st)) || (rc = gi_cursor_u32(&ce, &U, st)) ||
        (rc = gi_cursor_u64(&ce, &P, st))) {
        free(opts.fixed);
        return rc;
    }
    rc = 0;
    if (N == 0)
        rc = gi_cursor_fail(&ce, st, "no entry points");
    else if (U > N)
        rc = gi_cursor_fail(&ce, st, "%" PRIu32 " uniform entries of only %" PRIu32, U, N);
    else if (P < N)
        rc = gi_cursor_fail(&ce, st, "%" PRIu64 " photons for %" PRIu32 " paths", P, N);
    else if (gi_cursor_remaining(&ce) != (uint64_t)ENTR_PER_ENTRY * N)
        rc = gi_cursor_fail(&ce, st, "%zu bytes for %" PRIu32 " entries, expected %" PRIu64,
                            gi_cursor_remaining(&ce), N, (uint64_t)ENTR_PER_ENTRY * N);
    else if (P > cr.size / REFL_PER_PHOTON || cr.size != REFL_PER_PHOTON * P)
        rc = gi_cursor_fail(&cr, st, "%zu bytes, expected %" PRIu64 " photons x %u", cr.size, P,
                            REFL_PER_PHOTON);
    else if (cd.size != DETL_PER_PHOTON * P)
        rc = gi_cursor_fail(&cd, st, "%zu bytes, expected %" PRIu64 " photons x %u", cd.size, P,
                            DETL_PER_PHOTON);
    else if (cs.size != STAT_SIZE)
        rc = gi_cursor_fail(&cs, st, "%zu bytes, expected %u", cs.size, STAT_SIZE);
    if (rc) {
        free(opts.fixed);
        return rc;
    }

    gi_gip *g = gi_gip_new(N, P);
    if (!g) {
        free(opts.fixed);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory for %" PRIu64 " photons", nm, P);
    }
    g->opts = opts;
    g->scene_hash = scene->hash;
    g->num_uniform = U;
    g->fingerprint = gi_reader_fingerprint(r);

    /* ENTR */
    const unsigned char *b = ce.base;
    size_t o_da = ENTR_HEADER, o_base = o_da + 4 * (size_t)N, o_len = o_base + 12 * (size_t)N;
    uint64_t acc = 0;
    for (size_t i = 0; i < N; i++) {
        uint16_t len = gi_le_get_u16(b + o_len + 2 * i);
        g->path_start[i] = acc;
        if (len == 0) {
            rc = fail_at(&ce, o_len + 2 * i, st, "path", i, "has no vertex");
            goto fail;
        }
        acc += len;
        if (acc > P) {
            rc = fail_at(&ce, o_len + 2 * i, st, "path", i, "runs past the photon count");
            goto fail;
        }
    }
    if (acc != P) {
        char d[96];
        snprintf(d, sizeof d, "paths hold %" PRIu64 " vertices, the header says %" PRIu64, acc, P);
        rc = fail_at(&ce, o_len, st, "path", 0, d);
        goto fail;
    }
    g->path_start[N] = P;
    for (size_t i = 0; i < N; i++) {
        float a = gi_le_get_f32(b + o_da + 4 * i);
        if (!(a > 0.0f) || !isfinite(a)) {
            rc = fail_at(&ce, o_da + 4 * i, st, "entry", i, "differential area is not finite and positive");
            goto fail;
        }
        g->entry_dA[i] = a;
    }
    for (size_t i = 0; i < 3 * (size_t)N; i++) {
        float c = gi_le_get_f32(b + o_base + 4 * i);
        if (!(c >= 0.0f) || !isfinite(c)) {
            rc = fail_at(&ce, o_base + 4 * i, st, "entry", i / 3, "base colour is not finite and non-negative");
            goto fail;
        }
        g->entry_base[i] = c;
    }

    /* REFL */
    for (size_t i = 0; i < P; i++)
        g->refl[i] = gi_le_get_u32(cr.base + 4 * i);

    /* DETL */
    b = cd.base;
    size_t o_tri = 0, o_bary = 4 * (size_t)P, o_pdf = 12 * (size_t)P, o_win = 16 * (size_t)P,
           o_wout = 20 * (size_t)P, o_side = 24 * (size_t)P, o_q = 25 * (size_t)P;
    for (size_t i = 0; i < P; i++) {
        uint32_t t = gi_le_get_u32(b + o_tri + 4 * i);
        if (t >= scene->num_triangles) {
            char d[96];
            snprintf(d, sizeof d, "triangle %" PRIu32 " does not exist (the scene has %zu)", t,
                     scene->num_triangles);
            rc = fail_at(&cd, o_tri + 4 * i, st, "photon", i, d);
            goto fail;
        }
        g->tri[i] = t;
        float u = gi_le_get_f32(b + o_bary + 8 * i), v = gi_le_get_f32(b + o_bary + 8 * i + 4);
        if (!(u >= 0.0f) || !(v >= 0.0f) || !(u + v <= 1.0f + BARY_SLACK)) {
            rc = fail_at(&cd, o_bary + 8 * i, st, "photon", i, "barycentrics outside the triangle");
            goto fail;
        }
        g->bary[2 * i] = u;
        g->bary[2 * i + 1] = v;
        float pdf = gi_le_get_f32(b + o_pdf + 4 * i);
        if (!(pdf > 0.0f) || !isfinite(pdf)) {
            rc = fail_at(&cd, o_pdf + 4 * i, st, "photon", i, "pdf is not finite and positive");
            goto fail;
        }
        g->pdf[i] = pdf;
        for (int which = 0; which < 2; which++) {
            size_t at = (which ? o_wout : o_win) + 4 * i;
            int16_t e[2];
            uint16_t e0 = gi_le_get_u16(b + at), e1 = gi_le_get_u16(b + at + 2);
            memcpy(&e[0], &e0, 2);
            memcpy(&e[1], &e1, 2);
            gi_gip_oct_decode(e, (which ? g->w_out : g->w_in) + 3 * i);
        }
        uint8_t sd = b[o_side + i], q = b[o_q + i];
        if (sd > 1) {
            rc = fail_at(&cd, o_side + i, st, "photon", i, "side is neither 0 (front) nor 1 (back)");
            goto fail;
        }
        if (q == 0) {
            rc = fail_at(&cd, o_q + i, st, "photon", i, "continuation probability is 0");
            goto fail;
        }
        g->side[i] = sd;
        g->q[i] = q;
    }

    /* STAT */
    {
        uint32_t res = 0;
        gi_cursor_u64(&cs, &g->skipped_degenerate, st);
        gi_cursor_u64(&cs, &g->escaped, st);
        gi_cursor_u64(&cs, &g->absorbed, st);
        gi_cursor_u64(&cs, &g->roulette, st);
        gi_cursor_u64(&cs, &g->capped, st);
        gi_cursor_u32(&cs, &g->region_batches, st);
        gi_cursor_u32(&cs, &res, st);
        gi_cursor_f64(&cs, &g->pilot_mean, st);
        if (res != 0) {
            cs.pos = 44;
            rc = gi_cursor_fail(&cs, st, "reserved field is not zero");
            goto fail;
        }
        if (!isfinite(g->pilot_mean) || g->pilot_mean < 0.0) {
            cs.pos = 48;
            rc = gi_cursor_fail(&cs, st, "pilot mean path length is not finite and non-negative");
            goto fail;
        }
    }

    /* cross-checks: entry vertices carry no stored reflectance or incoming direction */
    for (size_t p = 0; p < N; p++) {
        uint64_t v = g->path_start[p];
        if (g->refl[v] != 0) {
            rc = fail_at(&cr, 4 * (size_t)v, st, "photon", v,
                         "entry point has a reflectance (it is computed at render time)");
            goto fail;
        }
        if (gi_le_get_u32(cd.base + o_win + 4 * (size_t)v) != 0) {
            rc = fail_at(&cd, o_win + 4 * (size_t)v, st, "photon", v,
                         "entry point has an incoming direction");
            goto fail;
        }
        g->w_in[3 * v] = g->w_in[3 * v + 1] = g->w_in[3 * v + 2] = 0.0f;
    }
    *out = g;
    return 0;
fail:
    gi_gip_free(g);
    return rc;
}

int gi_gip_read(const char *path, const gi_scene *scene, gi_gip **out, gi_status *st)
{
    *out = NULL;
    gi_reader *r = NULL;
    int rc = gi_reader_open(path, GI_GIP_MAGIC, GI_GIP_MAJOR, &r, st);
    if (rc)
        return rc;
    rc = parse(r, scene, out, st);
    gi_reader_free(r);
    return rc;
}

int gi_gip_read_memory(const void *data, size_t size, const char *name, const gi_scene *scene,
                       gi_gip **out, gi_status *st)
{
    *out = NULL;
    gi_reader *r = NULL;
    int rc = gi_reader_open_memory(data, size, name, GI_GIP_MAGIC, GI_GIP_MAJOR, &r, st);
    if (rc)
        return rc;
    rc = parse(r, scene, out, st);
    gi_reader_free(r);
    return rc;
}
