/* gi_photon.c - entry points and light-independent photon paths (gi-precompute;
 * method in docs/pipeline.md, "Precompute"). */
#define _POSIX_C_SOURCE 200809L
#include "gi_photon.h"

#include <inttypes.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_rng.h"

/* Salts that keep the random streams of the stages apart. */
#define SALT_UNIFORM 0x756e69666f726d31ULL
#define SALT_PILOT 0x70696c6f74736574ULL
#define SALT_EVAL 0x6576616c67726964ULL
#define SALT_BATCH 0x6261746368726179ULL

#define PATH_CHUNK 1024 /* paths per parallel work item */
#define NO_BATCH (-1)

typedef struct entry {
    uint32_t tri;
    float u, v;
    uint8_t side;   /* 0 front (CCW normal), 1 back */
    int32_t batch;  /* refinement batch that placed it, NO_BATCH for the uniform set */
} entry;

/* One photon vertex while tracing (copied into the gi_gip arrays at the end). */
typedef struct pvert {
    float w_in[3], w_out[3];
    float u, v, pdf;
    uint32_t tri, refl;
    uint8_t side, q;
} pvert;

typedef struct vbuf {
    pvert *v;
    size_t n, cap;
    int failed;
} vbuf;

typedef struct pstats {
    uint64_t escaped, absorbed, roulette, capped;
} pstats;

typedef struct batch {
    gi_vec3 g;      /* grid point the rays leave from */
    uint32_t rays;  /* rays shot (hits or not): N_b of the mixture */
} batch;

typedef struct ctx {
    const gi_scene *s;
    const gi_rt *rt;
    const gi_gip_opts *o;
    int threads;
    float eps;
    uint8_t *fixed;     /* per material: sampled by its BSDF */
    uint8_t *skip;      /* per triangle: no entry points */
    uint64_t skipped;
    size_t nsided;      /* (triangle, side) pairs that get entry points */
    uint32_t *sided_tri;
    uint8_t *sided_side;
    double *cdf;        /* nsided + 1, area CDF normalised to [0, 1] */
    double area;        /* total area of the sided set, m^2 */
} ctx;

/* ---- triangles ---------------------------------------------------------------- */

static double tri_area_d(const gi_scene *s, size_t t, double *longest2)
{
    const uint32_t *ix = s->indices + 3 * t;
    const float *a = s->positions + 3 * (size_t)ix[0];
    const float *b = s->positions + 3 * (size_t)ix[1];
    const float *c = s->positions + 3 * (size_t)ix[2];
    double e1[3], e2[3], e3[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
        e3[k] = (double)c[k] - b[k];
    }
    double cx = e1[1] * e2[2] - e1[2] * e2[1];
    double cy = e1[2] * e2[0] - e1[0] * e2[2];
    double cz = e1[0] * e2[1] - e1[1] * e2[0];
    double l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    double l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    double l3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
    if (longest2)
        *longest2 = fmax(l1, fmax(l2, l3));
    return 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
}

static double scene_diag(const gi_scene *s)
{
    double d2 = 0.0;
    for (int k = 0; k < 3; k++) {
        double e = (double)s->bbox_max[k] - s->bbox_min[k];
        d2 += e * e;
    }
    return sqrt(d2);
}

static int skip_tri(const gi_scene *s, size_t t, double min_area)
{
    double l2;
    double a = tri_area_d(s, t, &l2);
    if (!isfinite(a) || !isfinite(l2))
        return 1;
    return !(a >= min_area) || !(a >= GI_PHOTON_SLIVER * l2) || !(a > 0.0);
}

int gi_photon_skip_triangle(const gi_scene *s, size_t t)
{
    double d = scene_diag(s) * GI_PHOTON_MIN_REL_SIZE;
    return skip_tri(s, t, d * d);
}

double gi_photon_skew(const double *counts, const double *hit, int nb)
{
    double hsum = 0.0, csum = 0.0;
    for (int b = 0; b < nb; b++) {
        if (!(hit[b] > 0.0))
            continue;
        hsum += hit[b];
        csum += counts[b];
    }
    if (!(hsum > 0.0))
        return 0.0;
    if (!(csum > 0.0))
        return INFINITY;
    double rho = csum / hsum, acc = 0.0; /* entries per unit of seen solid angle */
    for (int b = 0; b < nb; b++)
        if (hit[b] > 0.0)
            acc += hit[b] * rho / ((counts[b] + 0.5) / hit[b]);
    double vif = acc / hsum;
    return vif > 1.0 ? vif - 1.0 : 0.0;
}

/* Position and geometric normal on the entry's side. */
static void entry_geom(const gi_scene *s, const entry *e, gi_vec3 *p, gi_vec3 *n)
{
    const uint32_t *ix = s->indices + 3 * (size_t)e->tri;
    gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
    gi_vec3 p1 = gi_v3p(s->positions + 3 * (size_t)ix[1]);
    gi_vec3 p2 = gi_v3p(s->positions + 3 * (size_t)ix[2]);
    gi_vec3 e1 = gi_sub(p1, p0), e2 = gi_sub(p2, p0);
    *p = gi_add(p0, gi_add(gi_scale(e1, e->u), gi_scale(e2, e->v)));
    gi_vec3 ng = gi_norm(gi_cross(e1, e2));
    *n = e->side ? gi_neg(ng) : ng;
}

static void clamp_bary(float *u, float *v)
{
    *u = gi_clampf(*u, 0.0f, 1.0f);
    *v = gi_clampf(*v, 0.0f, 1.0f - *u);
}

/* ---- context ------------------------------------------------------------------ */

static void ctx_release(ctx *c)
{
    free(c->fixed);
    free(c->skip);
    free(c->sided_tri);
    free(c->sided_side);
    free(c->cdf);
}

static int ctx_init(ctx *c, const gi_scene *s, const gi_rt *rt, const gi_gip_opts *o, int threads,
                    gi_status *st)
{
    memset(c, 0, sizeof *c);
    c->s = s;
    c->rt = rt;
    c->o = o;
    c->threads = threads > 0 ? threads : omp_get_num_procs();
    c->eps = gi_rt_scene_eps(rt);
    c->fixed = calloc(s->num_materials + 1, 1);
    c->skip = calloc(s->num_triangles + 1, 1);
    c->sided_tri = malloc((2 * s->num_triangles + 1) * sizeof *c->sided_tri);
    c->sided_side = malloc(2 * s->num_triangles + 1);
    c->cdf = malloc((2 * s->num_triangles + 1) * sizeof *c->cdf);
    if (!c->fixed || !c->skip || !c->sided_tri || !c->sided_side || !c->cdf)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu triangles", s->num_triangles);
    for (size_t i = 0; i < o->num_fixed; i++) {
        int m = gi_scene_find_material(s, o->fixed[i]);
        if (m < 0) {
            char list[512];
            size_t n = 0;
            list[0] = '\0';
            for (size_t k = 0; k < s->num_materials && n + 4 < sizeof list; k++) {
                int w = snprintf(list + n, sizeof list - n, "%s'%s'", k ? ", " : "",
                                 s->materials[k].name);
                if (w < 0 || (size_t)w >= sizeof list - n) {
                    snprintf(list + n, sizeof list - n, ", ...");
                    break;
                }
                n += (size_t)w;
            }
            return gi_status_set(st, GI_EXIT_USAGE,
                                 "--fixed-material: no material '%s' in '%s' (it has %s)",
                                 o->fixed[i], s->path, list);
        }
        c->fixed[m] = 1;
    }
    double d = scene_diag(s) * GI_PHOTON_MIN_REL_SIZE;
    double min_area = d * d;
    double acc = 0.0;
    c->cdf[0] = 0.0;
    for (size_t t = 0; t < s->num_triangles; t++) {
        if (skip_tri(s, t, min_area)) {
            c->skip[t] = 1;
            c->skipped++;
            continue;
        }
        double a = tri_area_d(s, t, NULL);
        int sides = s->materials[s->tri_material[t]].double_sided ? 2 : 1;
        for (int sd = 0; sd < sides; sd++) {
            c->sided_tri[c->nsided] = (uint32_t)t;
            c->sided_side[c->nsided] = (uint8_t)sd;
            acc += a;
            c->cdf[++c->nsided] = acc;
        }
    }
    c->area = acc;
    if (c->nsided == 0 || !(acc > 0.0) || !isfinite(acc))
        return gi_status_set(st, GI_EXIT_DATA,
                             "%s: no surface to place entry points on (%zu triangles, %" PRIu64
                             " skipped as zero-area or sliver)",
                             s->path, s->num_triangles, c->skipped);
    for (size_t i = 1; i <= c->nsided; i++)
        c->cdf[i] /= acc;
    c->cdf[c->nsided] = 1.0;
    return 0;
}

/* ---- entry points ----------------------------------------------------------------- */

/* n area-uniform entries: the first coordinate of a shifted lattice i/n picks
 * the (triangle, side) through the area CDF, so every triangle gets its share
 * to within one point; a scrambled (0,2) sequence (van der Corput, Sobol)
 * places them in the triangle by the square-root mapping. */
static void make_uniform(const ctx *c, uint32_t n, uint64_t salt, entry *out)
{
    uint64_t h = gi_mix64(c->o->seed ^ salt);
    double off = (double)(h >> 11) * (1.0 / 9007199254740992.0);
    uint32_t s1 = (uint32_t)gi_mix64(h + 1), s2 = (uint32_t)gi_mix64(h + 2);
    size_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        double x = ((double)i + off) / (double)n;
        while (k + 1 < c->nsided && c->cdf[k + 1] <= x)
            k++;
        float u2 = gi_vdc(i, s1), u3 = gi_sobol2(i, s2);
        float sq = sqrtf(u2);
        entry *e = &out[i];
        e->tri = c->sided_tri[k];
        e->side = c->sided_side[k];
        e->u = sq * (1.0f - u3);
        e->v = sq * u3;
        clamp_bary(&e->u, &e->v);
        e->batch = NO_BATCH;
    }
}

/* ---- photon paths ----------------------------------------------------------------- */

static int vbuf_push(vbuf *b, const pvert *v)
{
    if (b->failed)
        return -1;
    if (b->n == b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 4096;
        pvert *p = realloc(b->v, cap * sizeof *p);
        if (!p) {
            b->failed = 1;
            return -1;
        }
        b->v = p;
        b->cap = cap;
    }
    b->v[b->n++] = *v;
    return 0;
}

static inline gi_vec3 orient_ns(gi_vec3 ns, gi_vec3 ng) { return gi_dot(ns, ng) < 0.0f ? gi_neg(ns) : ns; }

/* Cosine-weighted direction around n with its solid-angle pdf; a sample at the
 * horizon (pdf 0 in float) is replaced by n itself so the pdf stays positive. */
static gi_vec3 sample_cos(gi_vec3 n, float u1, float u2, float *pdf)
{
    gi_vec3 w = gi_sample_cosine(n, u1, u2);
    float c = gi_dot(n, w);
    if (!(c > 1e-6f)) {
        w = n;
        c = 1.0f;
    }
    *pdf = c * GI_INV_PIf;
    return w;
}

/* Trace the path of entry e into b; base receives the entry's base colour.
 * Returns the number of vertices appended (>= 1), or 0 out of memory. */
static size_t trace_path(const ctx *c, const entry *e, gi_rng *rng, vbuf *b, float base[3],
                         pstats *ps)
{
    const gi_scene *s = c->s;
    const int K = c->o->max_bounces;
    size_t n0 = b->n;
    gi_hit h = {0.0f, e->tri, e->u, e->v};
    gi_surface sf;
    gi_rt_surface(c->rt, &h, &sf);
    const gi_material *m = &s->materials[sf.material];
    gi_scene_base_color(s, m, sf.uv0, sf.uv1, base);
    gi_vec3 ng = e->side ? gi_neg(sf.ng) : sf.ng;
    gi_vec3 ns = orient_ns(sf.ns, ng);

    /* vertex 0: light direction unknown, so cosine sampling whatever the material */
    pvert pv;
    memset(&pv, 0, sizeof pv);
    pv.tri = e->tri;
    pv.u = e->u;
    pv.v = e->v;
    pv.side = e->side;
    pv.q = 255;
    float u1 = gi_rng_float(rng), u2 = gi_rng_float(rng);
    gi_vec3 wo = sample_cos(ns, u1, u2, &pv.pdf);
    gi_v3store(pv.w_out, wo);
    if (vbuf_push(b, &pv))
        return 0;
    gi_vec3 p = sf.p;
    if (gi_dot(wo, ng) <= 0.0f) {
        ps->absorbed++; /* leaves below the geometric surface (shading normals) */
        return b->n - n0;
    }
    for (int k = 1;; k++) {
        gi_vec3 o = gi_rt_offset(p, ng, wo);
        if (!gi_rt_intersect(c->rt, o, wo, 0.0f, INFINITY, &h)) {
            ps->escaped++;
            break;
        }
        gi_rt_surface(c->rt, &h, &sf);
        gi_vec3 wi = gi_neg(wo);
        m = &s->materials[sf.material];
        int front = gi_dot(sf.ng, wi) > 0.0f;
        if (!front && !m->double_sided) {
            ps->absorbed++;
            break;
        }
        if ((K >= 0 && k > K) || k >= GI_GIP_MAX_PATH) {
            ps->capped++;
            break;
        }
        ng = front ? sf.ng : gi_neg(sf.ng);
        ns = orient_ns(sf.ns, ng);
        if (gi_dot(ns, wi) <= 0.0f)
            ns = ng;
        float bc[3];
        gi_scene_base_color(s, m, sf.uv0, sf.uv1, bc);
        gi_bsdf bsdf;
        gi_bsdf_init(&bsdf, m, gi_v3p(bc));
        float q = gi_clampf(gi_maxc(gi_bsdf_max_albedo(&bsdf)), GI_PHOTON_Q_MIN, GI_PHOTON_Q_MAX);
        uint8_t q8 = (uint8_t)lrintf(q * 255.0f);
        float qf = (float)q8 / 255.0f;
        if (gi_rng_float(rng) >= qf) {
            ps->roulette++;
            break;
        }
        gi_vec3 R;
        float pdf;
        u1 = gi_rng_float(rng);
        u2 = gi_rng_float(rng);
        if (c->fixed[sf.material]) {
            gi_vec3 wgt;
            if (!gi_bsdf_sample(&bsdf, ns, wi, u1, u2, gi_rng_float(rng), &wo, &wgt, &pdf)) {
                ps->absorbed++; /* the lobe sample fell below the surface: zero weight */
                break;
            }
            R = gi_scale(wgt, 1.0f / qf);
        } else {
            wo = sample_cos(ns, u1, u2, &pdf);
            gi_vec3 f = gi_bsdf_eval(&bsdf, ns, wi, wo);
            R = gi_scale(f, gi_dot(ns, wo) / (pdf * qf));
        }
        memset(&pv, 0, sizeof pv);
        pv.tri = h.tri;
        pv.u = h.u;
        pv.v = h.v;
        clamp_bary(&pv.u, &pv.v);
        pv.side = (uint8_t)!front;
        pv.q = q8;
        pv.pdf = pdf;
        gi_v3store(pv.w_in, wi);
        gi_v3store(pv.w_out, wo);
        float rgb[3] = {R.x, R.y, R.z};
        pv.refl = gi_rgb9e5_pack(rgb);
        if (vbuf_push(b, &pv))
            return 0;
        p = sf.p;
        if (gi_dot(wo, ng) <= 0.0f) {
            ps->absorbed++;
            break;
        }
    }
    return b->n - n0;
}

/* Mean vertices per path of a small deterministic pilot run, and the
 * relative standard error of that mean. */
static int pilot(const ctx *c, double *mean, double *rel_se, gi_status *st)
{
    const uint32_t n = GI_PHOTON_PILOT_PATHS;
    entry *E = malloc(n * sizeof *E);
    if (!E)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    make_uniform(c, n, SALT_PILOT, E);
    uint64_t total = 0, total2 = 0;
    int oom = 0;
#pragma omp parallel num_threads(c->threads) reduction(+ : total, total2, oom)
    {
        gi_rt_thread_init();
        vbuf b = {0};
        pstats ps = {0};
#pragma omp for schedule(dynamic, 64)
        for (uint32_t i = 0; i < n; i++) {
            gi_rng rng;
            gi_rng_seed(&rng, c->o->seed, i, 1);
            float base[3];
            b.n = 0;
            size_t k = trace_path(c, &E[i], &rng, &b, base, &ps);
            if (!k)
                oom = 1;
            total += k;
            total2 += (uint64_t)k * k;
        }
        free(b.v);
    }
    free(E);
    if (oom)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory in the pilot run");
    *mean = (double)total / n;
    double var = (double)total2 / n - *mean * *mean;
    *rel_se = var > 0.0 ? sqrt(var / n) / *mean : 0.0;
    return 0;
}

/* ---- region refinement (paper 5.1) --------------------------------------------------- */

static int dir_bin(gi_vec3 w)
{
    int zb = (int)((w.z + 1.0f) * 2.0f);
    zb = zb < 0 ? 0 : (zb > 3 ? 3 : zb);
    float phi = atan2f(w.y, w.x) + GI_PIf;
    int pb = (int)(phi * (8.0f / (2.0f * GI_PIf)));
    pb = pb < 0 ? 0 : (pb > 7 ? 7 : pb);
    return zb * 8 + pb;
}

/* Visible-entry estimate and skew seen from grid point g (one thread). */
static void eval_point(const ctx *c, gi_vec3 g, const entry *E, size_t M, uint64_t key,
                       double *vis_est, double *skew)
{
    double cnt[GI_PHOTON_REGION_BINS] = {0}, hit[GI_PHOTON_REGION_BINS] = {0};
    gi_rng rng;
    gi_rng_seed(&rng, c->o->seed ^ SALT_EVAL, key, 2);
    for (int b = 0; b < GI_PHOTON_REGION_BINS; b++) {
        int zb = b / 8, pb = b % 8;
        for (int k = 0; k < GI_PHOTON_REGION_PROBES; k++) {
            float z = -1.0f + 0.5f * ((float)zb + gi_rng_float(&rng));
            float phi = 2.0f * GI_PIf * ((float)pb + gi_rng_float(&rng)) / 8.0f - GI_PIf;
            float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
            gi_vec3 d = gi_v3(r * cosf(phi), r * sinf(phi), z);
            gi_hit h;
            if (gi_rt_intersect(c->rt, g, d, c->eps, INFINITY, &h))
                hit[b] += 1.0 / GI_PHOTON_REGION_PROBES;
        }
    }
    size_t S = M < GI_PHOTON_REGION_SUBSET ? M : GI_PHOTON_REGION_SUBSET;
    size_t vis = 0;
    for (size_t j = 0; j < S; j++) {
        size_t idx = (size_t)(((double)j + gi_rng_double(&rng)) * (double)M / (double)S);
        if (idx >= M)
            idx = M - 1;
        gi_vec3 p, n;
        entry_geom(c->s, &E[idx], &p, &n);
        gi_vec3 v = gi_sub(g, p);
        float d = gi_len(v);
        if (!(d > c->eps))
            continue;
        gi_vec3 dir = gi_scale(v, 1.0f / d);
        if (gi_dot(n, dir) <= 0.0f)
            continue;
        gi_vec3 o = gi_rt_offset(p, n, dir);
        if (gi_rt_occluded(c->rt, o, dir, 0.0f, d - c->eps))
            continue;
        vis++;
        cnt[dir_bin(gi_neg(dir))] += 1.0;
    }
    *vis_est = S ? (double)vis * (double)M / (double)S : 0.0;
    *skew = gi_photon_skew(cnt, hit, GI_PHOTON_REGION_BINS);
    int any = 0;
    for (int b = 0; b < GI_PHOTON_REGION_BINS; b++)
        any |= hit[b] > 0.0;
    if (!any)
        *vis_est = -1.0; /* sees nothing: no batch can help */
}

/* Shoot a batch of `rays` uniform directions from g; each hit on a side that
 * gets entry points becomes an entry. Appends to *E (grown), returns 0 or -1. */
static int shoot_batch(const ctx *c, gi_vec3 g, uint32_t rays, int32_t bid, entry **E, size_t *M,
                       size_t *cap)
{
    entry *slot = malloc((size_t)rays * sizeof *slot + 1);
    uint8_t *ok = calloc((size_t)rays + 1, 1);
    if (!slot || !ok) {
        free(slot);
        free(ok);
        return -1;
    }
    uint64_t h = gi_mix64(c->o->seed ^ SALT_BATCH ^ gi_mix64((uint64_t)bid));
    uint32_t s1 = (uint32_t)h, s2 = (uint32_t)(h >> 32);
    const gi_scene *s = c->s;
#pragma omp parallel for schedule(static) num_threads(c->threads)
    for (uint32_t j = 0; j < rays; j++) {
        gi_rt_thread_init();
        float u1 = gi_vdc(j, s1), u2 = gi_sobol2(j, s2);
        float z = 1.0f - 2.0f * u1, r = sqrtf(fmaxf(0.0f, 1.0f - z * z)), phi = 2.0f * GI_PIf * u2;
        gi_vec3 d = gi_v3(r * cosf(phi), r * sinf(phi), z);
        gi_hit hh;
        if (!gi_rt_intersect(c->rt, g, d, c->eps, INFINITY, &hh))
            continue;
        if (c->skip[hh.tri])
            continue;
        const uint32_t *ix = s->indices + 3 * (size_t)hh.tri;
        gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
        gi_vec3 ng = gi_cross(gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), p0),
                              gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), p0));
        int front = gi_dot(ng, d) < 0.0f;
        if (!front && !s->materials[s->tri_material[hh.tri]].double_sided)
            continue;
        entry *e = &slot[j];
        e->tri = hh.tri;
        e->u = hh.u;
        e->v = hh.v;
        clamp_bary(&e->u, &e->v);
        e->side = (uint8_t)!front;
        e->batch = bid;
        ok[j] = 1;
    }
    int rc = 0;
    for (uint32_t j = 0; j < rays && !rc; j++) {
        if (!ok[j])
            continue;
        if (*M == *cap) {
            size_t nc = *cap ? 2 * *cap : 1024;
            entry *ne = realloc(*E, nc * sizeof *ne);
            if (!ne) {
                rc = -1;
                break;
            }
            *E = ne;
            *cap = nc;
        }
        (*E)[(*M)++] = slot[j];
    }
    free(slot);
    free(ok);
    return rc;
}

/* Decide the refinement batches from the region's grid against the entries
 * E[0, M) (the uniform set), appending the batch entries to E. */
static int refine(const ctx *c, size_t n_target, entry **E, size_t *M, size_t *cap, batch **out_b,
                  uint32_t *out_nb, gi_status *st)
{
    const gi_gip_opts *o = c->o;
    float ext[3], L = 0.0f;
    for (int k = 0; k < 3; k++) {
        ext[k] = o->region_max[k] - o->region_min[k];
        L = fmaxf(L, ext[k]);
    }
    int n[3];
    for (int k = 0; k < 3; k++) {
        long v = L > 0.0f ? lrintf((float)o->region_grid * ext[k] / L) : 1;
        n[k] = v < 1 ? 1 : (int)v;
    }
    size_t ng = (size_t)n[0] * n[1] * n[2];
    gi_vec3 *gp = malloc(ng * sizeof *gp);
    double *vis = malloc(ng * sizeof *vis), *skew = malloc(ng * sizeof *skew);
    size_t max_batches = (size_t)GI_PHOTON_REGION_ROUNDS * ng;
    batch *B = malloc((max_batches + 1) * sizeof *B);
    if (!gp || !vis || !skew || !B) {
        free(gp);
        free(vis);
        free(skew);
        free(B);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the region grid");
    }
    size_t i = 0;
    for (int z = 0; z < n[2]; z++)
        for (int y = 0; y < n[1]; y++)
            for (int x = 0; x < n[0]; x++)
                gp[i++] = gi_v3(o->region_min[0] + ext[0] * ((float)x + 0.5f) / (float)n[0],
                                o->region_min[1] + ext[1] * ((float)y + 0.5f) / (float)n[1],
                                o->region_min[2] + ext[2] * ((float)z + 0.5f) / (float)n[2]);
    gi_verbose("region: grid %dx%dx%d, condition 1: at least %" PRIu32
               " visible entry points, condition 2: skew at most %g",
               n[0], n[1], n[2], o->region_min_visible, (double)o->region_max_skew);
    uint32_t nb = 0;
    double budget = GI_PHOTON_REGION_SHARE * (double)n_target; /* rays, all batches */
    int rc = 0;
    for (int round = 0; round < GI_PHOTON_REGION_ROUNDS && budget >= 1.0; round++) {
        const entry *Ec = *E;
        size_t Mc = *M;
#pragma omp parallel for schedule(dynamic, 1) num_threads(c->threads)
        for (size_t k = 0; k < ng; k++) {
            gi_rt_thread_init();
            eval_point(c, gp[k], Ec, Mc, (uint64_t)round * 1000003u + k, &vis[k], &skew[k]);
        }
        size_t fails = 0;
        for (size_t k = 0; k < ng; k++) {
            int f = vis[k] >= 0.0 && (vis[k] < (double)o->region_min_visible ||
                                      skew[k] > (double)o->region_max_skew);
            gi_verbose("region: round %d, grid point (%.4g, %.4g, %.4g): %.0f visible entry points, "
                       "skew %.3g%s",
                       round + 1, (double)gp[k].x, (double)gp[k].y, (double)gp[k].z,
                       vis[k] < 0.0 ? 0.0 : vis[k], skew[k], f ? ": refine" : "");
            fails += (size_t)f;
            if (!f)
                vis[k] = -2.0; /* marks "passes" for the loop below */
        }
        if (!fails)
            break;
        double rays = 2.0 * (double)(o->region_min_visible ? o->region_min_visible : 1);
        if (rays * (double)fails > budget)
            rays = floor(budget / (double)fails);
        if (rays < 1.0)
            break;
        for (size_t k = 0; k < ng; k++) {
            if (vis[k] == -2.0 || vis[k] < 0.0)
                continue;
            B[nb].g = gp[k];
            B[nb].rays = (uint32_t)rays;
            if (shoot_batch(c, gp[k], (uint32_t)rays, (int32_t)nb, E, M, cap)) {
                rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for refinement entries");
                break;
            }
            nb++;
            budget -= rays;
        }
        if (rc)
            break;
    }
    free(gp);
    free(vis);
    free(skew);
    if (rc) {
        free(B);
        return rc;
    }
    *out_b = B;
    *out_nb = nb;
    return 0;
}

/* dA_e = 1 / (N_u / A + sum_b N_b p_b(x_e)): the balance heuristic over the
 * uniform set and the batches, p_b the area density of batch b (uniform
 * directions from its grid point: cos / (4 pi d^2), times visibility). */
static void entry_areas(const ctx *c, const entry *E, size_t M, uint32_t nu, const batch *B,
                        uint32_t nb, float *dA)
{
    const double uni = (double)nu / c->area;
    const float dA_uniform = (float)(c->area / (double)nu);
    gi_progress prog;
    gi_progress_begin(&prog, "entry areas", M);
#pragma omp parallel for schedule(dynamic, 256) num_threads(c->threads)
    for (size_t e = 0; e < M; e++) {
        gi_rt_thread_init();
        gi_vec3 p, n;
        entry_geom(c->s, &E[e], &p, &n);
        double extra = 0.0;
        for (uint32_t b = 0; b < nb; b++) {
            gi_vec3 v = gi_sub(B[b].g, p);
            float d = gi_len(v);
            if (!(d > c->eps))
                continue;
            gi_vec3 dir = gi_scale(v, 1.0f / d);
            float cosx = gi_dot(n, dir);
            if (cosx <= 0.0f)
                continue;
            if (E[e].batch != (int32_t)b) {
                gi_vec3 o = gi_rt_offset(p, n, dir);
                if (gi_rt_occluded(c->rt, o, dir, 0.0f, d - c->eps))
                    continue;
            }
            extra += (double)B[b].rays * (double)cosx / (4.0 * GI_PI * (double)d * (double)d);
        }
        dA[e] = extra > 0.0 ? (float)(1.0 / (uni + extra)) : dA_uniform;
        if ((e & 4095) == 0)
            gi_progress_add(&prog, e + 4096 <= M ? 4096 : M - e);
    }
    gi_progress_end(&prog);
}

/* ---- the whole precomputation ------------------------------------------------------- */

int gi_photon_precompute(const gi_scene *s, const gi_rt *rt, const gi_gip_opts *opts, int threads,
                         gi_gip **out, gi_status *st)
{
    *out = NULL;
    if (opts->photons == 0)
        return gi_status_set(st, GI_EXIT_USAGE, "--photons must be at least 1");
    ctx c;
    int rc = ctx_init(&c, s, rt, opts, threads, st);
    if (rc) {
        ctx_release(&c);
        return rc;
    }
    double t0 = gi_now();
    entry *E = NULL;
    batch *B = NULL;
    uint32_t nb = 0;
    float *dA = NULL, *base = NULL;
    uint32_t *plen = NULL;
    vbuf *bufs = NULL;
    pstats *pst = NULL;
    size_t nchunks = 0;
    gi_gip *g = NULL;

    double mean = 0.0, rel_se = 0.0;
    if ((rc = pilot(&c, &mean, &rel_se, st)))
        goto done;
    /* aim GI_PHOTON_PILOT_AIM standard errors above the estimate, so that
     * --photons is reached nearly always and overshot by ~1% */
    double want = (double)opts->photons / mean * (1.0 + GI_PHOTON_PILOT_AIM * rel_se);
    if (want > (double)(UINT32_MAX / 2)) {
        rc = gi_status_set(st, GI_EXIT_USAGE,
                           "--photons %" PRIu64 " needs %.0f entry points, more than %u",
                           opts->photons, want, UINT32_MAX / 2);
        goto done;
    }
    size_t ne = (size_t)ceil(want);
    if (ne < 1)
        ne = 1;
    gi_verbose("pilot: %d paths, mean path length %.3f vertices (+-%.2f%%) -> %zu entry points "
               "(%.2f s)",
               GI_PHOTON_PILOT_PATHS, mean, 100.0 * rel_se, ne, gi_now() - t0);

    /* entry points: the uniform set, then the region's batches */
    size_t M = ne, cap = ne + 1;
    E = malloc(cap * sizeof *E);
    if (!E) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu entry points", ne);
        goto done;
    }
    make_uniform(&c, (uint32_t)ne, SALT_UNIFORM, E);
    uint32_t nu = (uint32_t)ne;
    if (opts->has_region) {
        double tr = gi_now();
        if ((rc = refine(&c, ne, &E, &M, &cap, &B, &nb, st)))
            goto done;
        size_t added = M - ne;
        if (added > 0) {
            /* the refinement's entries come out of the uniform set's share */
            size_t keep = ne > added ? ne - added : 0;
            if (keep < (ne + 1) / 2)
                keep = (ne + 1) / 2;
            nu = (uint32_t)keep;
            memmove(E + nu, E + ne, added * sizeof *E);
            make_uniform(&c, nu, SALT_UNIFORM, E);
            M = nu + added;
        }
        gi_verbose("region: %" PRIu32 " batches, %zu entry points added, uniform set %" PRIu32
                   " (%.2f s)",
                   nb, added, nu, gi_now() - tr);
    }

    dA = malloc(M * sizeof *dA);
    base = malloc(3 * M * sizeof *base);
    plen = malloc(M * sizeof *plen);
    nchunks = (M + PATH_CHUNK - 1) / PATH_CHUNK;
    bufs = calloc(nchunks, sizeof *bufs);
    pst = calloc(nchunks, sizeof *pst);
    if (!dA || !base || !plen || !bufs || !pst) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu entry points", M);
        goto done;
    }
    if (nb > 0) {
        entry_areas(&c, E, M, nu, B, nb, dA);
    } else {
        float a = (float)(c.area / (double)nu);
        for (size_t e = 0; e < M; e++)
            dA[e] = a;
    }

    /* photon paths, chunk by chunk in parallel, concatenated in path order */
    {
        double tp = gi_now();
        gi_progress prog;
        gi_progress_begin(&prog, "photon paths", M);
        int oom = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(c.threads) reduction(+ : oom)
        for (size_t ch = 0; ch < nchunks; ch++) {
            gi_rt_thread_init();
            size_t lo = ch * PATH_CHUNK, hi = lo + PATH_CHUNK < M ? lo + PATH_CHUNK : M;
            for (size_t p = lo; p < hi; p++) {
                gi_rng rng;
                gi_rng_seed(&rng, opts->seed, p, 0);
                size_t k = trace_path(&c, &E[p], &rng, &bufs[ch], base + 3 * p, &pst[ch]);
                if (!k) {
                    oom = 1;
                    break;
                }
                plen[p] = (uint32_t)k;
            }
            gi_progress_add(&prog, hi - lo);
        }
        gi_progress_end(&prog);
        if (oom) {
            rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the photon paths");
            goto done;
        }
        gi_verbose("paths: %zu traced (%.2f s)", M, gi_now() - tp);
    }

    uint64_t P = 0;
    for (size_t ch = 0; ch < nchunks; ch++)
        P += bufs[ch].n;
    g = gi_gip_new((uint32_t)M, P);
    if (!g) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %" PRIu64 " photons", P);
        goto done;
    }
    g->scene_hash = s->hash;
    g->opts = *opts;
    g->opts.fixed = NULL;
    if (opts->num_fixed) {
        g->opts.fixed = malloc(opts->num_fixed * sizeof *g->opts.fixed);
        if (!g->opts.fixed) {
            rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
            goto done;
        }
        memcpy(g->opts.fixed, opts->fixed, opts->num_fixed * sizeof *g->opts.fixed);
    }
    g->num_uniform = nu;
    g->skipped_degenerate = c.skipped;
    g->region_batches = nb;
    g->pilot_mean = mean;
    {
        uint64_t v = 0;
        for (size_t p = 0; p < M; p++) {
            g->path_start[p] = v;
            v += plen[p];
        }
        g->path_start[M] = v;
        memcpy(g->entry_dA, dA, M * sizeof *dA);
        memcpy(g->entry_base, base, 3 * M * sizeof *base);
        uint64_t i = 0;
        for (size_t ch = 0; ch < nchunks; ch++) {
            g->escaped += pst[ch].escaped;
            g->absorbed += pst[ch].absorbed;
            g->roulette += pst[ch].roulette;
            g->capped += pst[ch].capped;
            for (size_t k = 0; k < bufs[ch].n; k++, i++) {
                const pvert *pv = &bufs[ch].v[k];
                g->tri[i] = pv->tri;
                g->bary[2 * i] = pv->u;
                g->bary[2 * i + 1] = pv->v;
                g->side[i] = pv->side;
                g->q[i] = pv->q;
                g->pdf[i] = pv->pdf;
                g->refl[i] = pv->refl;
                memcpy(g->w_in + 3 * i, pv->w_in, sizeof pv->w_in);
                memcpy(g->w_out + 3 * i, pv->w_out, sizeof pv->w_out);
            }
        }
    }
    *out = g;
    g = NULL;
done:
    gi_gip_free(g);
    for (size_t ch = 0; bufs && ch < nchunks; ch++)
        free(bufs[ch].v);
    free(bufs);
    free(pst);
    free(plen);
    free(base);
    free(dA);
    free(B);
    free(E);
    ctx_release(&c);
    return rc;
}
