/* gi_hvds.c - building the HVDS: gathering points, gathering rays, the
 * adaptive octree, keys and the photon/ray -> key maps (docs/pipeline.md). */
#define _POSIX_C_SOURCE 200809L
#include "gi_hvds.h"
#include "gi_mem.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_rng.h"

void gi_hvds_opts_default(gi_hvds_opts *o)
{
    memset(o, 0, sizeof *o);
    o->gather = GI_GATHER_REJECTION;
    o->gather_rays = 0; /* auto: GI_HVDS_RAY_BUDGET over the points, 256 to 1024 */
    o->r_min = 0.0f;
    o->r_max = 0.0f;
    o->dir_bins = 64;
    o->cell_photons = 16.0f;
    o->key_photons = 8;
    o->entry_keys = 1; /* measured: see gi-hvds(1), --entry-keys */
    o->occlusion_check = 1;
    o->leak_check = 1;
    o->cover_min_radius = 1;
    o->seed = 1;
}

/* ---- normal bins -------------------------------------------------------- */

static float g_bins[GI_HVDS_NORMAL_BINS][3];
static int g_bins_ready;

static void init_bins(void)
{
    if (__atomic_load_n(&g_bins_ready, __ATOMIC_ACQUIRE))
        return;
    float tmp[GI_HVDS_NORMAL_BINS][3];
    int k = 0;
    for (int x = -1; x <= 1; x++)
        for (int y = -1; y <= 1; y++)
            for (int z = -1; z <= 1; z++) {
                if (!x && !y && !z)
                    continue;
                float l = sqrtf((float)(x * x + y * y + z * z));
                tmp[k][0] = (float)x / l;
                tmp[k][1] = (float)y / l;
                tmp[k][2] = (float)z / l;
                k++;
            }
    memcpy(g_bins, tmp, sizeof tmp);
    __atomic_store_n(&g_bins_ready, 1, __ATOMIC_RELEASE);
}

int gi_hvds_normal_bin(const float n[3])
{
    init_bins();
    int best = 0;
    float bd = -2.0f;
    for (int i = 0; i < GI_HVDS_NORMAL_BINS; i++) {
        float d = n[0] * g_bins[i][0] + n[1] * g_bins[i][1] + n[2] * g_bins[i][2];
        if (d > bd) {
            bd = d;
            best = i;
        }
    }
    return best;
}

/* ---- octree ------------------------------------------------------------- */

typedef struct node {
    float min[3];
    float size;
    int32_t child;   /* first of 8 children, or -1 for a leaf */
    int32_t parent;
    uint8_t level;
} node;

typedef struct tree {
    node *n;
    size_t count, cap;
} tree;

static int tree_push(tree *t, const float mn[3], float size, int32_t parent, uint8_t level)
{
    if (t->count == t->cap) {
        size_t nc = t->cap ? 2 * t->cap : 1024;
        node *p = realloc(t->n, nc * sizeof *p);
        if (!p)
            return -1;
        t->n = p;
        t->cap = nc;
    }
    node *d = &t->n[t->count];
    memcpy(d->min, mn, sizeof d->min);
    d->size = size;
    d->child = -1;
    d->parent = parent;
    d->level = level;
    return (int)t->count++;
}

static int tree_split(tree *t, int32_t i)
{
    node nd = t->n[i];
    float h = 0.5f * nd.size;
    int32_t first = (int32_t)t->count;
    for (int c = 0; c < 8; c++) {
        float mn[3] = {nd.min[0] + ((c & 1) ? h : 0.0f), nd.min[1] + ((c & 2) ? h : 0.0f),
                       nd.min[2] + ((c & 4) ? h : 0.0f)};
        if (tree_push(t, mn, h, i, (uint8_t)(nd.level + 1)) < 0)
            return -1;
    }
    t->n[i].child = first;
    return 0;
}

static inline int child_of(const node *nd, const float p[3])
{
    float h = 0.5f * nd->size;
    return (p[0] >= nd->min[0] + h ? 1 : 0) | (p[1] >= nd->min[1] + h ? 2 : 0) |
           (p[2] >= nd->min[2] + h ? 4 : 0);
}

static int32_t find_leaf(const tree *t, const float p[3])
{
    int32_t i = 0;
    while (t->n[i].child >= 0)
        i = t->n[i].child + child_of(&t->n[i], p);
    return i;
}

/* ---- key hash: (node, normal bin) -> key index --------------------------- */

typedef struct khash {
    uint64_t *k;   /* node * 32 + bin + 1; 0 = empty */
    uint32_t *v;
    size_t cap;    /* power of two */
    size_t count;
} khash;

static int kh_init(khash *h, size_t expect)
{
    size_t cap = 1024;
    while (cap < 2 * expect)
        cap *= 2;
    h->k = calloc(cap, sizeof *h->k);
    h->v = malloc(cap * sizeof *h->v);
    h->cap = cap;
    h->count = 0;
    return h->k && h->v ? 0 : -1;
}

static void kh_free(khash *h)
{
    free(h->k);
    free(h->v);
}

static inline uint64_t kh_code(int32_t nodei, int bin) { return (uint64_t)nodei * 32u + (uint64_t)bin + 1u; }

static inline uint32_t kh_get(const khash *h, uint64_t code)
{
    size_t m = h->cap - 1, i = (size_t)gi_mix64(code) & m;
    while (h->k[i]) {
        if (h->k[i] == code)
            return h->v[i];
        i = (i + 1) & m;
    }
    return GI_HVDS_NO_KEY;
}

static int kh_grow(khash *h)
{
    khash n;
    if (kh_init(&n, h->cap))
        return -1;
    for (size_t i = 0; i < h->cap; i++)
        if (h->k[i]) {
            size_t m = n.cap - 1, j = (size_t)gi_mix64(h->k[i]) & m;
            while (n.k[j])
                j = (j + 1) & m;
            n.k[j] = h->k[i];
            n.v[j] = h->v[i];
            n.count++;
        }
    kh_free(h);
    *h = n;
    return 0;
}

/* Insert if absent (value v); returns 1 if inserted, 0 if present, -1 on OOM. */
static int kh_put(khash *h, uint64_t code, uint32_t v)
{
    if (2 * (h->count + 1) > h->cap && kh_grow(h))
        return -1;
    size_t m = h->cap - 1, i = (size_t)gi_mix64(code) & m;
    while (h->k[i]) {
        if (h->k[i] == code)
            return 0;
        i = (i + 1) & m;
    }
    h->k[i] = code;
    h->v[i] = v;
    h->count++;
    return 1;
}

static void kh_set(khash *h, uint64_t code, uint32_t v)
{
    size_t m = h->cap - 1, i = (size_t)gi_mix64(code) & m;
    while (h->k[i] && h->k[i] != code)
        i = (i + 1) & m;
    h->v[i] = v;
}

/* ---- surface sampling helpers ------------------------------------------- */

static double tri_area_d(const gi_scene *s, size_t t)
{
    const uint32_t *ix = s->indices + 3 * t;
    const float *a = s->positions + 3 * (size_t)ix[0], *b = s->positions + 3 * (size_t)ix[1],
                *c = s->positions + 3 * (size_t)ix[2];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double x = e1[1] * e2[2] - e1[2] * e2[1], y = e1[2] * e2[0] - e1[0] * e2[2],
           z = e1[0] * e2[1] - e1[1] * e2[0];
    return 0.5 * sqrt(x * x + y * y + z * z);
}

static float scene_diag(const gi_scene *s)
{
    float d[3] = {s->bbox_max[0] - s->bbox_min[0], s->bbox_max[1] - s->bbox_min[1],
                  s->bbox_max[2] - s->bbox_min[2]};
    return sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

/* Surface point and oriented normal at (tri, u, v, side). */
static void surf_point(const gi_scene *s, uint32_t t, float u, float v, int side, gi_vec3 *p, gi_vec3 *n)
{
    const uint32_t *ix = s->indices + 3 * (size_t)t;
    gi_vec3 a = gi_v3p(s->positions + 3 * (size_t)ix[0]), b = gi_v3p(s->positions + 3 * (size_t)ix[1]),
            c = gi_v3p(s->positions + 3 * (size_t)ix[2]);
    gi_vec3 e1 = gi_sub(b, a), e2 = gi_sub(c, a);
    *p = gi_add(a, gi_add(gi_scale(e1, u), gi_scale(e2, v)));
    gi_vec3 ng = gi_norm(gi_cross(e1, e2));
    *n = side ? gi_neg(ng) : ng;
}

/* Interpolated shading normal of triangle t at point p (in its plane), on the
 * side of the oriented geometric normal ng; ng itself when the triangle or
 * its vertex normals are degenerate. */
static gi_vec3 shading_normal_at(const gi_scene *s, uint32_t t, gi_vec3 p, gi_vec3 ng)
{
    const uint32_t *ix = s->indices + 3 * (size_t)t;
    gi_vec3 a = gi_v3p(s->positions + 3 * (size_t)ix[0]);
    gi_vec3 e1 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), a);
    gi_vec3 e2 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), a);
    gi_vec3 q = gi_sub(p, a);
    double d00 = gi_dot(e1, e1), d01 = gi_dot(e1, e2), d11 = gi_dot(e2, e2);
    double d20 = gi_dot(q, e1), d21 = gi_dot(q, e2), den = d00 * d11 - d01 * d01;
    if (!(den > 0.0) || !s->normals)
        return ng;
    float v = (float)((d11 * d20 - d01 * d21) / den), w = (float)((d00 * d21 - d01 * d20) / den);
    float u = 1.0f - v - w;
    gi_vec3 n = gi_add(gi_scale(gi_v3p(s->normals + 3 * (size_t)ix[0]), u),
                       gi_add(gi_scale(gi_v3p(s->normals + 3 * (size_t)ix[1]), v),
                              gi_scale(gi_v3p(s->normals + 3 * (size_t)ix[2]), w)));
    float len = gi_len(n);
    if (!(len > 1e-6f))
        return ng;
    n = gi_scale(n, 1.0f / len);
    if (gi_dot(n, ng) < 0.0f)
        n = gi_neg(n);
    return gi_dot(n, ng) > 0.05f ? n : ng;
}

/* Two lifted points see each other (no geometry between them). */
static int mutually_visible(const gi_rt *rt, gi_vec3 a, gi_vec3 na, gi_vec3 b, gi_vec3 nb, float lift)
{
    gi_vec3 pa = gi_madd(a, na, lift), pb = gi_madd(b, nb, lift);
    gi_vec3 d = gi_sub(pb, pa);
    float len = gi_len(d);
    if (!(len > 0.0f))
        return 1;
    d = gi_scale(d, 1.0f / len);
    return !gi_rt_occluded(rt, pa, d, 0.0f, len);
}

/* ---- the build ------------------------------------------------------------ */

/* A gathering ray's hit, 20 bytes: Sponza's 161 M rays are held until the
 * keys are assigned (at 32 bytes, with the normal and its bin stored, the
 * build peaked at 7.5 GB). The oriented normal and its bin are recomputed
 * from the triangle, bit for bit what trace_gray found. */
typedef struct ghit {
    float pos[3];
    float foot;  /* footprint width (m) */
    uint32_t ts; /* triangle << 1 | 1 where the ray found its back, GHIT_NONE: a miss or an absorbing back face */
} ghit;
#define GHIT_NONE UINT32_MAX

/* the hit's normal, oriented towards the ray's origin */
static inline gi_vec3 ghit_nrm(const gi_scene *s, const ghit *g)
{
    gi_vec3 n = gi_scene_tri_normal(s, g->ts >> 1);
    return g->ts & 1u ? gi_neg(n) : n;
}

static inline int ghit_bin(const gi_scene *s, const ghit *g)
{
    float n[3];
    gi_v3store(n, ghit_nrm(s, g));
    return gi_hvds_normal_bin(n);
}

typedef struct cand {
    float pos[3], nrm[3];
    uint32_t tri;
    float r;          /* min hit distance of the probe rays */
} cand;

static void cosine_dir(gi_vec3 n, float u1, float u2, gi_vec3 *d)
{
    *d = gi_sample_cosine(n, u1, u2);
}

static int trace_gray(const gi_scene *s, const gi_rt *rt, gi_vec3 o, gi_vec3 n, gi_vec3 d, float ray_sa,
                      ghit *h, float *dist)
{
    gi_vec3 org = gi_rt_offset(o, n, d);
    gi_hit hit;
    h->ts = GHIT_NONE;
    *dist = INFINITY;
    if (!gi_rt_intersect(rt, org, d, 0.0f, INFINITY, &hit))
        return 0;
    gi_surface sf;
    gi_rt_surface(rt, &hit, &sf);
    *dist = hit.t;
    const gi_material *m = &s->materials[sf.material];
    int front = gi_dot(sf.ng, d) < 0.0f;
    if (!front && !m->double_sided)
        return 1;
    gi_vec3 nn = front ? sf.ng : gi_neg(sf.ng);
    float cosh = fmaxf(fabsf(gi_dot(nn, d)), 0.05f);
    gi_v3store(h->pos, sf.p);
    h->foot = hit.t * sqrtf(ray_sa / cosh);
    h->ts = (uint32_t)sf.tri << 1 | (front ? 0u : 1u);
    return 1;
}

/* Point i's N gathering rays (k x k cosine strata about its shading normal
 * ns, jittered by the seed and i alone, so that step 8 can trace them again
 * and find the same hits) into out[0..N); with the harmonic mean's sum of
 * inverse distances and the nearest hit that sets the point's radius. */
static void trace_point(const gi_scene *s, const gi_rt *rt, const cand *cd, gi_vec3 ns, int N, int k, int nfoot,
                        uint64_t seed, size_t i, ghit *out, double *inv_sum, float *dmin)
{
    gi_vec3 n = gi_v3p(cd->nrm);
    gi_rng rng;
    gi_rng_seed(&rng, seed, i, 0x6a7);
    *inv_sum = 0.0;
    *dmin = INFINITY;
    for (int r = 0; r < N; r++) {
        float u1 = ((float)(r % k) + gi_rng_float(&rng)) / (float)k;
        float u2 = ((float)(r / k) + gi_rng_float(&rng)) / (float)k;
        gi_vec3 d;
        cosine_dir(ns, u1, u2, &d);
        float dist;
        ghit *gh = &out[r];
        if (gi_dot(d, n) <= 0.0f) {
            /* below the surface itself: no light (the path tracer ends such paths) */
            gh->ts = GHIT_NONE;
            continue;
        }
        float coso = fmaxf(gi_dot(d, ns), 0.05f);
        trace_gray(s, rt, gi_v3p(cd->pos), n, d, (float)GI_PI / ((float)nfoot * coso), gh, &dist);
        if (isfinite(dist)) {
            *inv_sum += 1.0 / fmax(dist, 1e-6);
            /* the radius (the splat's weights) is the nearest hit of the
             * rays in 16 of the k rows and 16 of the k columns of strata:
             * the same for any N >= 256. The nearest of all 1024 rays is
             * nearer, and the splat then spreads each point less (Sponza,
             * 1024 rays: arcade-moved 0.0986 -> 0.1011 against 0.0966 with
             * this radius) */
            if (((r % k) * 16) % k < 16 && ((r / k) * 16) % k < 16)
                *dmin = fminf(*dmin, dist);
        }
    }
}

/* Deterministic area-stratified candidates; both sides of double-sided triangles. */
static cand *make_candidates(const gi_scene *s, size_t count, uint64_t seed, size_t *out_n)
{
    size_t nt = s->num_triangles;
    double *cdf = malloc((2 * nt + 1) * sizeof *cdf);
    cand *c = malloc(count * sizeof *c);
    if (!cdf || !c) {
        free(cdf);
        free(c);
        return NULL;
    }
    double acc = 0.0;
    cdf[0] = 0.0;
    for (size_t t = 0; t < nt; t++) {
        double a = tri_area_d(s, t);
        const gi_material *m = &s->materials[s->tri_material[t]];
        if (!(a > 0.0))
            a = 0.0;
        acc += a;
        cdf[2 * t + 1] = acc;
        acc += m->double_sided ? a : 0.0;
        cdf[2 * t + 2] = acc;
    }
    if (!(acc > 0.0)) {
        free(cdf);
        free(c);
        *out_n = 0;
        return malloc(1);
    }
    gi_rng rng;
    gi_rng_seed(&rng, seed, 0x6a7e, 0);
    uint32_t scr1 = gi_rng_u32(&rng), scr2 = gi_rng_u32(&rng);
    double off = gi_rng_double(&rng);
    size_t n = 0;
    for (size_t i = 0; i < count; i++) {
        double u = ((double)i + off) / (double)count * acc;
        size_t lo = 0, hi = 2 * nt; /* cdf[lo] <= u < cdf[hi] */
        while (hi - lo > 1) {
            size_t mid = (lo + hi) / 2;
            if (cdf[mid] <= u)
                lo = mid;
            else
                hi = mid;
        }
        size_t t = lo / 2;
        int side = (int)(lo & 1);
        float r1 = gi_vdc((uint32_t)i, scr1), r2 = gi_sobol2((uint32_t)i, scr2);
        float sq = sqrtf(r1);
        float bu = r2 * sq, bv = 1.0f - sq; /* uniform on the triangle */
        gi_vec3 p, nn;
        surf_point(s, (uint32_t)t, bu, bv, side, &p, &nn);
        gi_v3store(c[n].pos, p);
        gi_v3store(c[n].nrm, nn);
        c[n].tri = (uint32_t)t;
        c[n].r = INFINITY;
        n++;
    }
    free(cdf);
    *out_n = n;
    return c;
}

/* Drop the candidates that no open space sees: every one of up to 8
 * stratified cosine rays from the candidate finds the back of a
 * single-sided surface (which absorbs). Such a face lies inside other
 * geometry (Sponza: a second layer of the vaults 1 cm behind the visible
 * one, facing the same way), so no light reaches it and no camera outside
 * sees it; left in, its points hold no light and, within a radius of the
 * visible surface with its normal, darkened the pixels that interpolate
 * them (hard-lights.script sun-wide: blotches of 3-10 cd/m2 on a vault
 * where the path tracer finds 25-30), and they covered the visible
 * surface's own candidates in the rejection. The first ray decides for
 * most: a front face or the sky keeps the candidate. Compacts c in place
 * (order kept); returns how many were dropped. */
/* 1 if every one of 8 stratified cosine rays from p (normal nn) finds the
 * back of a single-sided face: p lies inside other geometry (Sponza: a second
 * layer of the vaults 1.2 cm behind the visible one; floor under a column). */
static int enclosed_at(const gi_scene *s, const gi_rt *rt, gi_vec3 p, gi_vec3 nn, uint64_t seed, uint64_t i,
                       uint64_t salt)
{
    enum { NR = 8 };
    gi_rng rng;
    gi_rng_seed(&rng, seed, i, salt);
    int back = 0;
    for (int k = 0; k < NR && back == k; k++) {
        gi_vec3 d;
        cosine_dir(nn, ((float)(k & 3) + gi_rng_float(&rng)) * 0.25f, ((float)(k >> 2) + gi_rng_float(&rng)) * 0.5f,
                   &d);
        gi_hit h;
        if (!gi_rt_intersect(rt, gi_rt_offset(p, nn, d), d, 0.0f, INFINITY, &h))
            break; /* the sky */
        const uint32_t *ix = s->indices + 3 * (size_t)h.tri;
        gi_vec3 a = gi_v3p(s->positions + 3 * (size_t)ix[0]);
        gi_vec3 ng = gi_cross(gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), a),
                              gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), a));
        if (gi_dot(ng, d) > 0.0f && !s->materials[s->tri_material[h.tri]].double_sided)
            back++;
    }
    return back == NR;
}

static size_t drop_enclosed(const gi_scene *s, const gi_rt *rt, cand *c, size_t *nc, uint64_t seed, int threads)
{
    size_t n = *nc;
    uint8_t *drop = calloc(n + 1, 1);
    if (!drop)
        return 0; /* keep them all: the points are as before */
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads)
    for (size_t i = 0; i < n; i++) {
        gi_rt_thread_init();
        drop[i] = (uint8_t)enclosed_at(s, rt, gi_v3p(c[i].pos), gi_v3p(c[i].nrm), seed, i, 0xe2c105ed);
    }
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (!drop[i])
            c[m++] = c[i];
    free(drop);
    *nc = m;
    return n - m;
}

/* Spatial hash of accepted gathering points for the rejection test. */
typedef struct grid {
    float cell;
    size_t cap;
    int32_t *head;   /* cap buckets */
    int32_t *next;   /* per point */
} grid;

static size_t grid_bucket(const grid *g, int x, int y, int z)
{
    uint64_t h = gi_mix64(((uint64_t)(uint32_t)x * 73856093u) ^ ((uint64_t)(uint32_t)y * 19349663u) ^
                          ((uint64_t)(uint32_t)z * 83492791u));
    return (size_t)(h & (g->cap - 1));
}

static int select_rejection(const gi_rt *rt, cand *c, size_t nc, const gi_hvds_opts *o, float rmin,
                            float rmax, int threads, uint32_t **sel, size_t *nsel, float **reff)
{
    /* probe rays for R_i */
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads)
    for (size_t i = 0; i < nc; i++) {
        gi_rt_thread_init();
        gi_rng rng;
        gi_rng_seed(&rng, o->seed, i, 0x9b0be);
        float best = INFINITY;
        for (int k = 0; k < 16; k++) {
            gi_vec3 d;
            cosine_dir(gi_v3p(c[i].nrm), ((float)(k & 3) + gi_rng_float(&rng)) * 0.25f,
                       ((float)(k >> 2) + gi_rng_float(&rng)) * 0.25f, &d);
            gi_vec3 org = gi_rt_offset(gi_v3p(c[i].pos), gi_v3p(c[i].nrm), d);
            gi_hit h;
            if (gi_rt_intersect(rt, org, d, 0.0f, best, &h))
                best = h.t;
        }
        c[i].r = best;
    }
    grid g;
    g.cell = rmax;
    g.cap = 1;
    while (g.cap < 2 * nc + 16)
        g.cap *= 2;
    g.head = malloc(g.cap * sizeof *g.head);
    g.next = malloc((nc + 1) * sizeof *g.next);
    uint32_t *acc = malloc((nc + 1) * sizeof *acc);
    float *re = malloc((nc + 1) * sizeof *re);
    if (!g.head || !g.next || !acc || !re) {
        free(g.head);
        free(g.next);
        free(acc);
        free(re);
        return -1;
    }
    for (size_t i = 0; i < g.cap; i++)
        g.head[i] = -1;
    const float inv_na = 1.0f / sqrtf(1.0f - cosf((float)(10.0 * GI_PI / 180.0)));
    size_t na = 0;
    for (size_t i = 0; i < nc; i++) {
        gi_vec3 x = gi_v3p(c[i].pos), n = gi_v3p(c[i].nrm);
        int cx = (int)floorf(x.x / g.cell), cy = (int)floorf(x.y / g.cell), cz = (int)floorf(x.z / g.cell);
        int covered = 0;
        float r = fmaxf(fminf(0.5f * c[i].r, rmax), rmin);
        for (int dz = -1; dz <= 1 && !covered; dz++)
            for (int dy = -1; dy <= 1 && !covered; dy++)
                for (int dx = -1; dx <= 1 && !covered; dx++) {
                    for (int32_t j = g.head[grid_bucket(&g, cx + dx, cy + dy, cz + dz)]; j >= 0;
                         j = g.next[j]) {
                        const cand *a = &c[acc[j]];
                        /* within the smaller radius: a candidate nearer
                         * other surfaces than the point is (the foot of a
                         * wall above a floor) is covered only by a point
                         * within its own radius. With the point's radius
                         * alone the foot's pixels read points a radius up
                         * the wall, which see less of the floor: Sponza
                         * f3's sunlit column strips 15-40 cm above a sunlit
                         * ledge read 13-22 cd/m2 of indirect light where the
                         * path tracer finds 18-40 (docs/journal.md "Session 40") */
                        float rc = o->cover_min_radius ? fminf(re[j], r) : re[j];
                        float ep = gi_len(gi_sub(x, gi_v3p(a->pos))) / rc;
                        float en = sqrtf(fmaxf(0.0f, 1.0f - gi_dot(n, gi_v3p(a->nrm)))) * inv_na;
                        if (fmaxf(ep, en) < 1.0f) {
                            covered = 1;
                            break;
                        }
                    }
                }
        if (covered)
            continue;
        acc[na] = (uint32_t)i;
        re[na] = r;
        size_t b = grid_bucket(&g, cx, cy, cz);
        g.next[na] = g.head[b];
        g.head[b] = (int32_t)na;
        na++;
    }
    free(g.head);
    free(g.next);
    *sel = acc;
    *nsel = na;
    *reff = re;
    return 0;
}

/* k-means over position and normal (Wang et al. 2009): seeds placed
 * adaptively (rejection with a doubled R+), then Lloyd iterations assigning
 * candidates to the nearest centre in the metric |dx|/R+ + |dn|/sin(alpha+). */
static int select_kmeans(const gi_rt *rt, cand *c, size_t nc, const gi_hvds_opts *o, float rmin,
                         float rmax, int threads, uint32_t **sel, size_t *nsel, float **reff)
{
    uint32_t *seeds;
    float *sre;
    size_t ns;
    if (select_rejection(rt, c, nc, o, rmin, 2.0f * rmax, threads, &seeds, &ns, &sre))
        return -1;
    float *cp = malloc(ns * 6 * sizeof *cp);
    uint32_t *assign = malloc(nc * sizeof *assign);
    if (!cp || !assign) {
        free(cp);
        free(assign);
        free(seeds);
        free(sre);
        return -1;
    }
    for (size_t k = 0; k < ns; k++) {
        memcpy(cp + 6 * k, c[seeds[k]].pos, 3 * sizeof(float));
        memcpy(cp + 6 * k + 3, c[seeds[k]].nrm, 3 * sizeof(float));
    }
    const float wn = 1.0f / sinf((float)(10.0 * GI_PI / 180.0));
    /* grid over centres for nearest searches */
    float cell = 2.0f * rmax;
    size_t cap = 1;
    while (cap < 2 * ns + 16)
        cap *= 2;
    int32_t *head = malloc(cap * sizeof *head), *next = malloc((ns + 1) * sizeof *next);
    double *sum = malloc(ns * 7 * sizeof *sum);
    if (!head || !next || !sum) {
        free(head);
        free(next);
        free(sum);
        free(cp);
        free(assign);
        free(seeds);
        free(sre);
        return -1;
    }
    grid g = {cell, cap, head, next};
    for (int it = 0; it < 6; it++) {
        for (size_t i = 0; i < cap; i++)
            head[i] = -1;
        for (size_t k = 0; k < ns; k++) {
            size_t b = grid_bucket(&g, (int)floorf(cp[6 * k] / cell), (int)floorf(cp[6 * k + 1] / cell),
                                   (int)floorf(cp[6 * k + 2] / cell));
            next[k] = head[b];
            head[b] = (int32_t)k;
        }
#pragma omp parallel for schedule(static) num_threads(threads)
        for (size_t i = 0; i < nc; i++) {
            gi_vec3 x = gi_v3p(c[i].pos), n = gi_v3p(c[i].nrm);
            int cx = (int)floorf(x.x / cell), cy = (int)floorf(x.y / cell), cz = (int)floorf(x.z / cell);
            float best = INFINITY;
            uint32_t bk = 0;
            for (int dz = -1; dz <= 1; dz++)
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++)
                        for (int32_t k = head[grid_bucket(&g, cx + dx, cy + dy, cz + dz)]; k >= 0; k = next[k]) {
                            float dp = gi_len(gi_sub(x, gi_v3p(cp + 6 * k))) / rmax;
                            float dn = gi_len(gi_sub(n, gi_v3p(cp + 6 * k + 3))) * wn;
                            float d = dp + dn;
                            if (d < best || (d == best && (uint32_t)k < bk)) {
                                best = d;
                                bk = (uint32_t)k;
                            }
                        }
            assign[i] = best < INFINITY ? bk : UINT32_MAX;
        }
        memset(sum, 0, ns * 7 * sizeof *sum);
        for (size_t i = 0; i < nc; i++) {
            if (assign[i] == UINT32_MAX)
                continue;
            double *sm = sum + 7 * assign[i];
            for (int k = 0; k < 3; k++) {
                sm[k] += c[i].pos[k];
                sm[3 + k] += c[i].nrm[k];
            }
            sm[6] += 1.0;
        }
        for (size_t k = 0; k < ns; k++) {
            double *sm = sum + 7 * k;
            if (sm[6] <= 0.0)
                continue;
            for (int j = 0; j < 3; j++)
                cp[6 * k + j] = (float)(sm[j] / sm[6]);
            gi_vec3 nn = gi_norm(gi_v3((float)sm[3], (float)sm[4], (float)sm[5]));
            gi_v3store(cp + 6 * k + 3, nn);
        }
    }
    /* each cluster is represented by its member closest to the centre (a real surface point) */
    float *bestd = malloc(ns * sizeof *bestd);
    uint32_t *rep = malloc(ns * sizeof *rep);
    if (!bestd || !rep) {
        free(bestd);
        free(rep);
        free(head);
        free(next);
        free(sum);
        free(cp);
        free(assign);
        free(seeds);
        free(sre);
        return -1;
    }
    for (size_t k = 0; k < ns; k++) {
        bestd[k] = INFINITY;
        rep[k] = UINT32_MAX;
    }
    for (size_t i = 0; i < nc; i++) {
        uint32_t k = assign[i];
        if (k == UINT32_MAX)
            continue;
        float d = gi_len(gi_sub(gi_v3p(c[i].pos), gi_v3p(cp + 6 * k))) / rmax +
                  gi_len(gi_sub(gi_v3p(c[i].nrm), gi_v3p(cp + 6 * k + 3))) * wn;
        if (d < bestd[k]) {
            bestd[k] = d;
            rep[k] = (uint32_t)i;
        }
    }
    size_t na = 0;
    for (size_t k = 0; k < ns; k++) {
        if (rep[k] == UINT32_MAX)
            continue;
        seeds[na] = rep[k];
        sre[na] = fmaxf(fminf(0.5f * c[rep[k]].r, rmax), rmin);
        na++;
    }
    free(bestd);
    free(rep);
    free(head);
    free(next);
    free(sum);
    free(cp);
    free(assign);
    *sel = seeds;
    *nsel = na;
    *reff = sre;
    return 0;
}

/* ---- polygon clipping for exact key areas ------------------------------- */

typedef struct poly {
    int n;
    double v[16][3];
} poly;

static void clip_plane(const poly *in, poly *out, int axis, double value, int keep_greater)
{
    out->n = 0;
    for (int i = 0; i < in->n; i++) {
        const double *a = in->v[i], *b = in->v[(i + 1) % in->n];
        double da = keep_greater ? a[axis] - value : value - a[axis];
        double db = keep_greater ? b[axis] - value : value - b[axis];
        if (da >= 0.0 && out->n < 16)
            memcpy(out->v[out->n++], a, sizeof out->v[0]);
        if ((da >= 0.0) != (db >= 0.0) && out->n < 16) {
            double t = da / (da - db);
            for (int k = 0; k < 3; k++)
                out->v[out->n][k] = a[k] + t * (b[k] - a[k]);
            out->n++;
        }
    }
}

static double poly_area(const poly *p)
{
    if (p->n < 3)
        return 0.0;
    double s[3] = {0, 0, 0};
    for (int i = 1; i + 1 < p->n; i++) {
        double e1[3], e2[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = p->v[i][k] - p->v[0][k];
            e2[k] = p->v[i + 1][k] - p->v[0][k];
        }
        s[0] += e1[1] * e2[2] - e1[2] * e2[1];
        s[1] += e1[2] * e2[0] - e1[0] * e2[2];
        s[2] += e1[0] * e2[1] - e1[1] * e2[0];
    }
    return 0.5 * sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
}

static void clip_to_box(const poly *in, poly *out, const node *nd)
{
    poly a, b;
    const poly *cur = in;
    poly *dst = &a;
    for (int axis = 0; axis < 3; axis++) {
        clip_plane(cur, dst, axis, nd->min[axis], 1);
        cur = dst;
        dst = dst == &a ? &b : &a;
        clip_plane(cur, dst, axis, (double)nd->min[axis] + nd->size, 0);
        cur = dst;
        dst = dst == &a ? &b : &a;
    }
    *out = *cur;
}

/* Add the polygon's area to every key (node, bin) it lies in, down the tree. */
static void area_walk(const tree *t, const khash *kh, int32_t ni, const poly *p, int bin, double *area)
{
    uint32_t k = kh_get(kh, kh_code(ni, bin));
    if (k == GI_HVDS_NO_KEY)
        return; /* no photons of this bin below: nothing reads this area */
    area[k] += poly_area(p);
    const node *nd = &t->n[ni];
    if (nd->child < 0)
        return;
    for (int c = 0; c < 8; c++) {
        poly q;
        clip_to_box(p, &q, &t->n[nd->child + c]);
        if (q.n >= 3)
            area_walk(t, kh, nd->child + c, &q, bin, area);
    }
}

/* ---- build ----------------------------------------------------------------- */

typedef struct keyrec {
    uint8_t level;
    int32_t node;
    int8_t bin;
} keyrec;

static int keyrec_cmp(const void *a, const void *b)
{
    const keyrec *x = a, *y = b;
    if (x->level != y->level)
        return x->level > y->level ? -1 : 1; /* deepest first: children before parents */
    if (x->node != y->node)
        return x->node < y->node ? -1 : 1;
    return (x->bin > y->bin) - (x->bin < y->bin);
}

static int u64_cmp(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* spread the low 10 bits of x to every third bit */
static uint32_t morton_spread(uint32_t x)
{
    x &= 0x3ffu;
    x = (x | (x << 16)) & 0x030000ffu;
    x = (x | (x << 8)) & 0x0300f00fu;
    x = (x | (x << 4)) & 0x030c30c3u;
    x = (x | (x << 2)) & 0x09249249u;
    return x;
}

/* The selected candidates sel[0..n) in Morton order of their positions (a
 * 1024^3 grid over their bounding box): the relight's final gather reads
 * the points in file order, each point's (key, count) pairs in a stream,
 * and neighbours in space read mostly the same keys, which then stay in
 * the cache (Sponza, sun moves, --entry-keys 1, medians of 14 frames on a
 * loaded machine: final gather 16.4 -> 13.8 ms; the points had come in
 * triangle order). Returns nonzero when out of memory. */
static int morton_sort(const cand *c, uint32_t *sel, size_t n)
{
    uint64_t *key = malloc((n + 1) * sizeof *key);
    if (!key)
        return 1;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fminf(lo[a], c[sel[i]].pos[a]);
            hi[a] = fmaxf(hi[a], c[sel[i]].pos[a]);
        }
    for (size_t i = 0; i < n; i++) {
        uint32_t q[3];
        for (int a = 0; a < 3; a++) {
            float ext = hi[a] - lo[a], f = ext > 0.0f ? (c[sel[i]].pos[a] - lo[a]) / ext : 0.0f;
            q[a] = (uint32_t)fminf(fmaxf(f * 1023.0f, 0.0f), 1023.0f);
        }
        uint64_t code = morton_spread(q[0]) | morton_spread(q[1]) << 1 | morton_spread(q[2]) << 2;
        key[i] = code << 32 | sel[i];
    }
    qsort(key, n, sizeof *key, u64_cmp);
    for (size_t i = 0; i < n; i++)
        sel[i] = (uint32_t)key[i];
    free(key);
    return 0;
}

/* (key, count) pairs of a sorted key list into out (2 words each); returns the pair count */
static uint32_t count_keys(const uint32_t *k, uint32_t n, uint32_t *out)
{
    uint32_t w = 0;
    for (uint32_t j = 0; j < n; j++) {
        if (!(w > 0 && out[2 * (w - 1)] == k[j])) {
            out[2 * w] = k[j];
            out[2 * w + 1] = 0;
            w++;
        }
        out[2 * (w - 1) + 1]++;
    }
    return w;
}

static int u32_cmp(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

#define NREP 4

/* n rounded to the nearest square k * k, k in 1..255 (pair counts are 16 bits). */
static int square_rays(int n, int *k)
{
    int r = (int)lrintf(sqrtf((float)(n > 0 ? n : 1)));
    r = r < 1 ? 1 : (r > 255 ? 255 : r);
    *k = r;
    return r * r;
}

int gi_hvds_build(const gi_scene *s, const gi_rt *rt, const gi_gip *gip, uint64_t gip_fingerprint,
                  const gi_hvds_opts *opts, int threads, gi_hvds **out, gi_status *st)
{
    *out = NULL;
    init_bins();
    if (threads <= 0)
        threads = omp_get_num_procs();
    gi_hvds_opts o = *opts;
    float diag = scene_diag(s);
    if (!(diag > 0.0f))
        return gi_status_set(st, GI_EXIT_DATA, "%s: the scene has no extent", s->path);
    /* diag / 181 (128 sqrt 2: twice as many points per area as diag / 128,
     * the default until 2026-12-02): Sponza against 1024-spp references,
     * sun-moved and arcade-moved nrmse 0.1076 / 0.1058 -> 0.1034 / 0.0983
     * (diag / 256 at 256 rays a point: 0.1033 / 0.0994), light moves ~8 ms
     * slower (final gather 7 -> 12 ms), gi-hvds 15 -> 39 s, .gih 74 -> 120
     * MB; GI_HVDS_RAY_BUDGET doubled with it keeps the Cornell box's 729
     * rays a point (docs/man/gi-hvds.md) */
    float rmax = o.r_max > 0.0f ? o.r_max : diag / 181.0f;
    float rmin = o.r_min > 0.0f ? o.r_min : rmax / 5.0f;
    if (rmin > rmax)
        return gi_status_set(st, GI_EXIT_USAGE, "--r-min %g is larger than --r-max %g", rmin, rmax);
    o.r_max = rmax;
    o.r_min = rmin;
    /* rays per point: given, or decided once the points are known */
    int k = 0, N = 0;
    if (o.gather_rays > 0)
        N = square_rays(o.gather_rays, &k);
    o.gather_rays = N;
    double t0 = gi_now();

    gi_hvds *h = calloc(1, sizeof *h);
    if (!h)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    h->scene_hash = s->hash;
    h->gip_fingerprint = gip_fingerprint;
    h->opts = o;
    int rc = 0;
    cand *c = NULL;
    uint32_t *sel = NULL;
    float *reff = NULL;
    ghit *hits = NULL, *rehits = NULL;
    float *ppos = NULL, *pnrm = NULL;
    int8_t *pbin = NULL;
    int32_t *pleaf = NULL;
    uint32_t *order = NULL, *lstart = NULL;
    uint8_t *checked = NULL, *flag = NULL;
    tree t = {0};
    khash kh = {0};
    keyrec *recs = NULL;
    uint32_t *reps = NULL;
    double *area = NULL;
    uint32_t **ptmp = NULL, **stmp = NULL;
    uint32_t *pcnt = NULL, *scnt0 = NULL, *scnt1 = NULL;
    uint64_t *ksub = NULL, *ksub0 = NULL;
    uint8_t *phid = NULL;

    /* 1. gathering points */
    double total = 0.0;
    for (size_t i = 0; i < s->num_triangles; i++) {
        double a = tri_area_d(s, i);
        if (a > 0.0)
            total += s->materials[s->tri_material[i]].double_sided ? 2.0 * a : a;
    }
    /* 64 candidates per pi R+^2, up to 1.6 M (until 2026-12-02: 16, up to
     * 400 k, which capped Sponza at 0.55 of its 16). Rejection can only keep
     * points where there are candidates, so the sparser set could not follow
     * a small R_i into creases and along mouldings. Sponza, 1024-spp refs,
     * three --seed of gi-hvds each: points 105 k -> 163 k; sun-b 0.1323 /
     * 0.1314 / 0.1349 -> 0.1263 / 0.1252 / 0.1267, arcades-b 0.0722 / 0.0726
     * / 0.0744 -> 0.0676 / 0.0686 / 0.0718, arcade-moved 0.0964 / 0.1001 /
     * 0.0945 -> 0.0887 / 0.0993 / 0.0917, sun-moved and sun-c within 0.002;
     * gi-hvds 24 -> 32 s, final gather ~13 -> ~16 ms. 4 M candidates gave no
     * more (sun-b 0.1260), nor did R- halved (0.1304). */
    double want = 64.0 * total / (GI_PI * (double)rmax * rmax);
    size_t ncand = (size_t)fmin(fmax(want, 2000.0), 1600000.0);
    size_t nc = 0, ng = 0;
    c = make_candidates(s, ncand, o.seed, &nc);
    if (!c) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu candidates", ncand);
        goto fail;
    }
    size_t nenc = nc ? drop_enclosed(s, rt, c, &nc, o.seed, threads) : 0;
    if (nenc)
        gi_verbose("candidates: %zu of %zu inside other geometry (every probe ray finds a back face) dropped",
                   nenc, nc + nenc);
    if (nc == 0) {
        rc = gi_status_set(st, GI_EXIT_DATA, "%s: the scene has no surface to place gathering points on",
                           s->path);
        goto fail;
    }
    if ((o.gather == GI_GATHER_KMEANS ? select_kmeans : select_rejection)(rt, c, nc, &o, rmin, rmax,
                                                                          threads, &sel, &ng, &reff)) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory selecting gathering points");
        goto fail;
    }
    if (morton_sort(c, sel, ng)) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory sorting %zu gathering points", ng);
        goto fail;
    }
    gi_verbose("gathering points: %zu of %zu candidates (%s, R+ %.4g m, R- %.4g m), %.2f s", ng, nc,
               o.gather == GI_GATHER_KMEANS ? "k-means" : "rejection", rmax, rmin, gi_now() - t0);
    if (!N) {
        /* auto: a fixed budget of rays over the scene's points. The relight's
         * gather costs one read per (point, key) pair, at most one per ray, so
         * the budget bounds its cost. 2^28 gives Sponza's 157k points 1024
         * (docs/man/gi-hvds.md: the more-variants sun-c 0.102 -> 0.090 against
         * 4096 spp, light moves' gather 4.5 -> 7-8 ms, the .gih 169 -> 362 MB) */
        double per = (double)GI_HVDS_RAY_BUDGET / (double)(ng ? ng : 1);
        N = square_rays((int)fmin(fmax(per, 256.0), 1024.0), &k);
        o.gather_rays = N;
        h->opts.gather_rays = N;
    }
    gi_verbose("gathering rays: %d per point", N);
    h->num_gpoints = (uint32_t)ng;
    h->gpoints = calloc(ng + 1, sizeof *h->gpoints);
    const uint64_t hit_budget = o.hit_bytes ? o.hit_bytes : GI_HVDS_HIT_BYTES;
    const int keep_hits = (uint64_t)ng * (uint64_t)N * sizeof *hits <= hit_budget;
    size_t chunk = keep_hits ? ng : (size_t)(hit_budget / ((uint64_t)N * sizeof *hits));
    if (chunk < 64)
        chunk = 64;
    if (chunk > ng)
        chunk = ng;
    if (!keep_hits)
        gi_verbose("gathering rays: %.1f GB of hits over %.1f GB: traced again when their keys are found",
                   (double)ng * N * sizeof *hits / 1e9, (double)hit_budget / 1e9);
    hits = malloc((chunk * (size_t)N + 1) * sizeof *hits);
    if (!h->gpoints || !hits) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu gathering points", ng);
        goto fail;
    }

    /* 2. photons: positions, oriented normals, normal bins */
    uint64_t P = gip->num_photons;
    h->num_photons = P;
    ppos = malloc((3 * P + 1) * sizeof *ppos);
    pnrm = malloc((3 * P + 1) * sizeof *pnrm);
    pbin = malloc((P + 1) * sizeof *pbin);
    pleaf = malloc((P + 1) * sizeof *pleaf);
    h->photon_key = malloc((P + 1) * sizeof *h->photon_key);
    if (!ppos || !pnrm || !pbin || !pleaf || !h->photon_key) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %llu photons", (unsigned long long)P);
        goto fail;
    }
#pragma omp parallel for schedule(static) num_threads(threads)
    for (uint64_t p = 0; p < P; p++) {
        gi_gip_vertex(gip, s, p, ppos + 3 * p, pnrm + 3 * p);
        /* bin by the geometric normal on the photon's side, as key areas and
         * gathering-ray hits are: shading normals would strand flux in keys
         * whose clipped area is zero */
        gi_vec3 gp, gn;
        surf_point(s, gip->tri[p], 0.3f, 0.3f, gip->side[p], &gp, &gn);
        gi_v3store(pnrm + 3 * p, gn);
        pbin[p] = (int8_t)gi_hvds_normal_bin(pnrm + 3 * p);
    }
    /* entry points inside other geometry (enclosed_at: the floor under a
     * column, the hidden layer of a vault): no light reaches them and no
     * gathering ray sees them. They take no key, and their share of each
     * key's entry area is taken out of the key's area (step 7): a key's
     * radiance is its flux over the area that can hold it. Before, they
     * diluted their keys: on Sponza under the sun the gathering points held
     * 0.91 of the path tracer's indirect illuminance (the sum over 400 random
     * points), under the arcade lights 0.995; a test court with columns
     * standing on its floor 0.987, the same with the floor cut out under them
     * 1.001. */
    phid = calloc(P + 1, 1);
    if (!phid)
        goto oom;
    size_t nhid = 0;
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads) reduction(+ : nhid)
    for (uint32_t e = 0; e < gip->num_entries; e++) {
        gi_rt_thread_init();
        uint64_t v0 = gip->path_start[e];
        if (enclosed_at(s, rt, gi_v3p(ppos + 3 * v0), gi_v3p(pnrm + 3 * v0), o.seed, e, 0x41dde7u)) {
            phid[v0] = 1;
            nhid++;
        }
    }
    if (nhid)
        gi_verbose("entry points: %zu of %u inside other geometry (every probe ray finds a back face): no key",
                   nhid, gip->num_entries);

    /* 3. octree: the root cube (refined by the gathering rays' footprints in step 4) */
    {
        float ext = 0.0f, mn[3];
        for (int a = 0; a < 3; a++)
            ext = fmaxf(ext, s->bbox_max[a] - s->bbox_min[a]);
        ext *= 1.001f;
        ext += 1e-6f;
        for (int a = 0; a < 3; a++)
            mn[a] = 0.5f * (s->bbox_min[a] + s->bbox_max[a]) - 0.5f * ext;
        if (tree_push(&t, mn, ext, -1, 0) < 0)
            goto oom;
        memcpy(h->root_min, mn, sizeof mn);
        h->root_size = ext;
    }
    float min_size = P ? (float)sqrt((double)o.cell_photons * total / (double)P) : h->root_size;

    /* 4. gathering rays, and the octree refined by their footprints. A
     * ray's footprint, which picks the octree level it reads, is that of one
     * of at most GI_HVDS_FOOT_RAYS rays: more rays lower the gather's noise
     * without splitting the octree into keys of fewer photons (Cornell box,
     * 1024 rays: the same errors within 0.0005 as with their own footprints,
     * and half the relight's gather time). The hits are held for step 8
     * while they fit in hit_bytes; beyond that they are traced in chunks
     * here, and each point's again in step 8 (the same rays, so the same
     * .gih): Sponza at 4096 rays a point held 16 GB of them. */
    const int nfoot = N < GI_HVDS_FOOT_RAYS ? N : GI_HVDS_FOOT_RAYS;
    {
        gi_progress prog;
        gi_progress_begin(&prog, "gathering rays", ng);
        for (size_t c0 = 0; c0 < ng; c0 += chunk) {
            size_t c1 = c0 + chunk < ng ? c0 + chunk : ng;
            ghit *ch = keep_hits ? hits + c0 * (size_t)N : hits;
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads)
            for (size_t i = c0; i < c1; i++) {
                gi_rt_thread_init();
                const cand *cd = &c[sel[i]];
                gi_gpoint *gp = &h->gpoints[i];
                gi_vec3 n = gi_v3p(cd->nrm);
                /* the irradiance is gathered about the shading normal, as the
                 * path tracer and the relight's pixels shade: on tessellated
                 * curved surfaces the triangles' own normals would facet it */
                gi_vec3 ns = shading_normal_at(s, cd->tri, gi_v3p(cd->pos), n);
                memcpy(gp->pos, cd->pos, sizeof gp->pos);
                gi_v3store(gp->nrm, ns);
                gp->tri = cd->tri;
                double inv_sum;
                float dmin;
                trace_point(s, rt, cd, ns, N, k, nfoot, o.seed, i, ch + (i - c0) * (size_t)N, &inv_sum, &dmin);
                gp->r_harmonic = inv_sum > 0.0 ? (float)(N / inv_sum) : INFINITY;
                gp->radius = fmaxf(fminf(0.5f * dmin, rmax), rmin);
                gi_progress_add(&prog, 1);
            }
            for (size_t j = 0; j < (c1 - c0) * (size_t)N; j++) {
                const ghit *gh = &ch[j];
                if (gh->ts == GHIT_NONE)
                    continue;
                float target = fmaxf(gh->foot, min_size);
                int32_t ni = 0;
                while (t.n[ni].level < GI_HVDS_MAX_DEPTH && t.n[ni].size > 2.0f * target) {
                    if (t.n[ni].child < 0 && tree_split(&t, ni))
                        goto oom;
                    ni = t.n[ni].child + child_of(&t.n[ni], gh->pos);
                }
            }
        }
        gi_progress_end(&prog);
    }
    h->num_rays = (uint64_t)ng * (uint64_t)N;

    size_t nodes_after_footprints = t.count;

    /* 5. leak refinement: split leaves whose photons of one normal bin cannot all see each other */
    float leak_min = h->root_size / (float)(1 << GI_HVDS_MAX_DEPTH);
    for (int round = 0; round < (o.leak_check ? GI_HVDS_MAX_DEPTH : 0); round++) {
#pragma omp parallel for schedule(static) num_threads(threads)
        for (uint64_t p = 0; p < P; p++)
            pleaf[p] = find_leaf(&t, ppos + 3 * p);
        /* counting sort of photons by leaf */
        free(order);
        free(lstart);
        order = malloc((P + 1) * sizeof *order);
        lstart = calloc(t.count + 2, sizeof *lstart);
        if (!order || !lstart)
            goto oom;
        for (uint64_t p = 0; p < P; p++)
            lstart[pleaf[p] + 1]++;
        for (size_t i = 0; i < t.count; i++)
            lstart[i + 1] += lstart[i];
        {
            uint32_t *fill = malloc((t.count + 1) * sizeof *fill);
            if (!fill)
                goto oom;
            memcpy(fill, lstart, t.count * sizeof *fill);
            for (uint64_t p = 0; p < P; p++)
                order[fill[pleaf[p]]++] = (uint32_t)p;
            free(fill);
        }
        if (!checked) {
            checked = calloc(t.count + 1, 1); /* later rounds extend it as nodes are added */
            if (!checked)
                goto oom;
        }
        free(flag);
        flag = calloc(t.count + 1, 1);
        if (!flag)
            goto oom;
        size_t nchk = t.count;
        int any = 0;
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads) reduction(| : any)
        for (size_t li = 0; li < nchk; li++) {
            if (t.n[li].child >= 0 || checked[li])
                continue;
            uint32_t b0 = lstart[li], b1 = lstart[li + 1];
            if (b1 - b0 < 2 || t.n[li].level >= GI_HVDS_MAX_DEPTH || t.n[li].size <= leak_min)
                continue;
            gi_rt_thread_init();
            uint32_t cnt[GI_HVDS_NORMAL_BINS] = {0};
            for (uint32_t j = b0; j < b1; j++)
                if (!phid[order[j]])
                    cnt[pbin[order[j]]]++;
            uint32_t pick[GI_HVDS_NORMAL_BINS][6];
            uint32_t seen[GI_HVDS_NORMAL_BINS] = {0}, npk[GI_HVDS_NORMAL_BINS] = {0};
            for (uint32_t j = b0; j < b1; j++) {
                uint32_t p = order[j];
                if (phid[p])
                    continue;
                int b = pbin[p];
                uint32_t m = cnt[b] < 6 ? cnt[b] : 6;
                /* take the photons at ranks floor(q * cnt / m), q = 0..m-1 */
                if (npk[b] < m && seen[b] == (uint32_t)((uint64_t)npk[b] * cnt[b] / m))
                    pick[b][npk[b]++] = p;
                seen[b]++;
            }
            float lift = 1e-3f * t.n[li].size;
            int blocked = 0;
            for (int b = 0; b < GI_HVDS_NORMAL_BINS && !blocked; b++)
                for (uint32_t x = 0; x < npk[b] && !blocked; x++)
                    for (uint32_t y = x + 1; y < npk[b] && !blocked; y++) {
                        uint32_t pa = pick[b][x], pb = pick[b][y];
                        if (!mutually_visible(rt, gi_v3p(ppos + 3 * pa), gi_v3p(pnrm + 3 * pa),
                                              gi_v3p(ppos + 3 * pb), gi_v3p(pnrm + 3 * pb), lift))
                            blocked = 1;
                    }
            if (blocked) {
                flag[li] = 1;
                any = 1;
            }
        }
        for (size_t li = 0; li < nchk; li++)
            if (t.n[li].child < 0)
                checked[li] = 1;
        if (!any)
            break;
        for (size_t li = 0; li < nchk; li++)
            if (flag[li] && tree_split(&t, (int32_t)li))
                goto oom;
        uint8_t *nc2 = realloc(checked, t.count + 1);
        if (!nc2)
            goto oom;
        memset(nc2 + nchk, 0, t.count + 1 - nchk);
        checked = nc2;
    }
#pragma omp parallel for schedule(static) num_threads(threads)
    for (uint64_t p = 0; p < P; p++)
        pleaf[p] = find_leaf(&t, ppos + 3 * p);
    gi_verbose("octree: %zu nodes after footprints, %zu after leak refinement (min cell %.4g m), %.2f s",
               nodes_after_footprints, t.count, min_size, gi_now() - t0);

    /* 6. keys: every (leaf, bin) holding photons and all its ancestors */
    if (kh_init(&kh, P / 4 + 1024))
        goto oom;
    size_t nrec = 0, caprec = 1024;
    recs = malloc(caprec * sizeof *recs);
    if (!recs)
        goto oom;
    for (uint64_t p = 0; p < P; p++) {
        for (int32_t ni = phid[p] ? -1 : pleaf[p]; ni >= 0; ni = t.n[ni].parent) {
            int ins = kh_put(&kh, kh_code(ni, pbin[p]), 0);
            if (ins < 0)
                goto oom;
            if (ins == 0)
                break; /* present, and so are its ancestors */
            if (nrec == caprec) {
                caprec *= 2;
                keyrec *nr = realloc(recs, caprec * sizeof *recs);
                if (!nr)
                    goto oom;
                recs = nr;
            }
            recs[nrec].level = t.n[ni].level;
            recs[nrec].node = ni;
            recs[nrec].bin = pbin[p];
            nrec++;
        }
    }
    qsort(recs, nrec, sizeof *recs, keyrec_cmp);
    for (size_t i = 0; i < nrec; i++)
        kh_set(&kh, kh_code(recs[i].node, recs[i].bin), (uint32_t)i);
    h->num_keys = (uint32_t)nrec;
    h->key_parent = malloc((nrec + 1) * sizeof *h->key_parent);
    h->key_scale = calloc(nrec + 1, sizeof *h->key_scale);
    h->key_level = malloc(nrec + 1);
    reps = malloc((nrec + 1) * NREP * sizeof *reps);
    area = calloc(nrec + 1, sizeof *area);
    if (!h->key_parent || !h->key_scale || !h->key_level || !reps || !area)
        goto oom;
    for (size_t i = 0; i < nrec; i++) {
        int32_t pn = t.n[recs[i].node].parent;
        h->key_parent[i] = pn >= 0 ? kh_get(&kh, kh_code(pn, recs[i].bin)) : GI_HVDS_NO_KEY;
        h->key_level[i] = recs[i].level;
        for (int r = 0; r < NREP; r++)
            reps[i * NREP + r] = UINT32_MAX;
    }
    for (uint64_t p = 0; p < P; p++)
        h->photon_key[p] = phid[p] ? GI_HVDS_NO_KEY : kh_get(&kh, kh_code(pleaf[p], pbin[p]));
    /* representatives: leaf keys from their photons (spread by rank), parents from children */
    {
        uint32_t *kcnt = calloc(nrec + 1, sizeof *kcnt), *kseen = calloc(nrec + 1, sizeof *kseen);
        uint8_t *kn = calloc(nrec + 1, 1);
        if (!kcnt || !kseen || !kn) {
            free(kcnt);
            free(kseen);
            free(kn);
            goto oom;
        }
        for (uint64_t p = 0; p < P; p++)
            if (h->photon_key[p] != GI_HVDS_NO_KEY)
                kcnt[h->photon_key[p]]++;
        for (uint64_t p = 0; p < P; p++) {
            uint32_t kk = h->photon_key[p];
            if (kk == GI_HVDS_NO_KEY)
                continue;
            uint32_t m = kcnt[kk] < NREP ? kcnt[kk] : NREP;
            if (kn[kk] < m && kseen[kk] == (uint32_t)((uint64_t)kn[kk] * kcnt[kk] / m))
                reps[kk * NREP + kn[kk]++] = (uint32_t)p;
            kseen[kk]++;
        }
        for (int pass = 0; pass < NREP; pass++)
            for (size_t i = 0; i < nrec; i++) {
                uint32_t pk = h->key_parent[i];
                if (pk == GI_HVDS_NO_KEY || pass >= kn[i] || kn[pk] >= NREP)
                    continue;
                /* a parent collects its children's representatives in rounds */
                uint32_t r = reps[i * NREP + pass];
                int dup = 0;
                for (int q = 0; q < kn[pk]; q++)
                    dup |= reps[pk * NREP + q] == r;
                if (!dup)
                    reps[pk * NREP + kn[pk]++] = r;
            }
        free(kcnt);
        free(kseen);
        free(kn);
    }

    /* 7. exact surface area of every key, by clipping triangles to cells */
    for (size_t tri = 0; tri < s->num_triangles; tri++) {
        double a = tri_area_d(s, tri);
        if (!(a > 0.0))
            continue;
        const gi_material *m = &s->materials[s->tri_material[tri]];
        const uint32_t *ix = s->indices + 3 * tri;
        poly pg;
        pg.n = 3;
        for (int v = 0; v < 3; v++)
            for (int q = 0; q < 3; q++)
                pg.v[v][q] = s->positions[3 * (size_t)ix[v] + q];
        gi_vec3 p0, ng0;
        surf_point(s, (uint32_t)tri, 0.3f, 0.3f, 0, &p0, &ng0);
        for (int side = 0; side < (m->double_sided ? 2 : 1); side++) {
            float nn[3] = {side ? -ng0.x : ng0.x, side ? -ng0.y : ng0.y, side ? -ng0.z : ng0.z};
            area_walk(&t, &kh, 0, &pg, gi_hvds_normal_bin(nn), area);
        }
    }
    if (nhid) {
        /* the entry area of each key's subtree, all and outside other
         * geometry; a hidden entry counts in the deepest key above its leaf */
        double *eall = calloc(nrec + 1, sizeof *eall), *evis = calloc(nrec + 1, sizeof *evis);
        if (!eall || !evis) {
            free(eall);
            free(evis);
            goto oom;
        }
        for (uint32_t e = 0; e < gip->num_entries; e++) {
            uint64_t v0 = gip->path_start[e];
            uint32_t ke = GI_HVDS_NO_KEY;
            for (int32_t ni = pleaf[v0]; ni >= 0 && ke == GI_HVDS_NO_KEY; ni = t.n[ni].parent)
                ke = kh_get(&kh, kh_code(ni, pbin[v0]));
            if (ke == GI_HVDS_NO_KEY)
                continue;
            eall[ke] += gip->entry_dA[e];
            if (!phid[v0])
                evis[ke] += gip->entry_dA[e];
        }
        for (size_t i = 0; i < nrec; i++) {
            uint32_t pk = h->key_parent[i];
            if (pk != GI_HVDS_NO_KEY) {
                eall[pk] += eall[i];
                evis[pk] += evis[i];
            }
            /* a key whose entries are all hidden keeps its area: its
             * photons came along paths, and its entries tell nothing */
            if (eall[i] > 0.0 && evis[i] > 0.0 && evis[i] < eall[i])
                area[i] *= evis[i] / eall[i];
        }
        free(eall);
        free(evis);
    }
    for (size_t i = 0; i < nrec; i++)
        h->key_scale[i] = area[i] > 0.0 ? (float)(1.0 / (GI_PI * area[i])) : 0.0f;

    /* photons under every key (its own and its descendants'), for --key-photons */
    ksub = calloc(nrec + 1, sizeof *ksub);
    if (!ksub)
        goto oom;
    for (uint64_t p = 0; p < P; p++)
        if (h->photon_key[p] != GI_HVDS_NO_KEY)
            ksub[h->photon_key[p]]++;
    for (size_t i = 0; i < nrec; i++)
        if (h->key_parent[i] != GI_HVDS_NO_KEY)
            ksub[h->key_parent[i]] += ksub[i];
    /* entry points (first vertices) under every key, for --entry-keys */
    const uint64_t kmin0 = (uint64_t)(o.entry_keys > 0 ? o.entry_keys : 0);
    if (kmin0) {
        ksub0 = calloc(nrec + 1, sizeof *ksub0);
        if (!ksub0)
            goto oom;
        for (uint32_t e = 0; e < gip->num_entries; e++) {
            uint32_t ke = h->photon_key[gip->path_start[e]];
            if (ke != GI_HVDS_NO_KEY)
                ksub0[ke]++;
        }
        for (size_t i = 0; i < nrec; i++)
            if (h->key_parent[i] != GI_HVDS_NO_KEY)
                ksub0[h->key_parent[i]] += ksub0[i];
    }

    /* 8. gathering rays -> keys: footprint level, then down while occluded,
     * then up while the key holds fewer than key_photons photons. One photon
     * in a sliver of a cell otherwise gives a radiance spike that every ray
     * into it repeats (Sponza: a gathering point in a crevice at 8983 lux
     * against 48 measured). The coarser key is taken even where the occlusion
     * check had descended: measured on Sponza, keeping the check there left
     * those spikes and gained nothing (sun-moved nrmse 0.149 either way,
     * 0.144 without it). */
    pcnt = calloc(ng + 1, sizeof *pcnt);
    ptmp = calloc(ng + 1, sizeof *ptmp);
    if (kmin0) {
        scnt0 = calloc(ng + 1, sizeof *scnt0);
        scnt1 = calloc(ng + 1, sizeof *scnt1);
        stmp = calloc(ng + 1, sizeof *stmp);
    }
    if (!keep_hits && !(rehits = malloc(((size_t)threads * (size_t)N + 1) * sizeof *rehits)))
        goto oom;
    if (!pcnt || !ptmp || (kmin0 && (!scnt0 || !scnt1 || !stmp)))
        goto oom;
    uint64_t descended = 0, lifted = 0, kept_occ = 0;
    const uint64_t kmin = (uint64_t)(o.key_photons > 0 ? o.key_photons : 0);
    int oom_flag = 0;
    gi_progress kprog; /* minutes on Sponza at 4096 rays, traced again */
    gi_progress_begin(&kprog, "gathering rays' keys", ng);
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads) reduction(+ : descended, lifted, kept_occ) reduction(| : oom_flag)
    for (size_t i = 0; i < ng; i++) {
        gi_rt_thread_init();
        uint64_t *keys = malloc((size_t)N * sizeof *keys); /* key << 32 | ray */
        uint32_t *skeys = kmin0 ? malloc((2 * (size_t)N + 2) * sizeof *skeys) : NULL; /* split rays: first, later */
        if (!keys || (kmin0 && !skeys)) {
            free(keys);
            free(skeys);
            oom_flag = 1;
            continue;
        }
        /* the point's hits: held since step 4, or traced again */
        ghit *ph = hits + i * (size_t)N;
        if (!keep_hits) {
            double inv_sum;
            float dmin;
            ph = rehits + (size_t)omp_get_thread_num() * (size_t)N;
            trace_point(s, rt, &c[sel[i]], gi_v3p(h->gpoints[i].nrm), N, k, nfoot, o.seed, i, ph, &inv_sum, &dmin);
        }
        uint32_t nk = 0, ns = 0;
        for (int r = 0; r < N; r++) {
            const ghit *gh = &ph[r];
            if (gh->ts == GHIT_NONE)
                continue;
            const int bin = ghit_bin(s, gh);
            /* down to the footprint level, remembering the deepest cell on the
             * way that has a key of the hit's normal bin: where the footprint
             * cell has none (a face smaller than the entry-point spacing, such
             * as a column base's top), that key stands in for it rather than
             * darkness. Sponza, sun-moved: 17% of the rays that found no key
             * find one so; the sunlit gathering points seen by the camera go
             * from 0.82 to 0.84 of the path tracer's indirect illuminance in
             * sum, rms 0.40 -> 0.35; images 0.1199 -> 0.1190 (sun-moved),
             * 0.1190 -> 0.1187 (arcade-moved) */
            int32_t ni = 0, ni_up = -1;
            uint32_t key_up = GI_HVDS_NO_KEY;
            for (;;) {
                uint32_t kk = kh_get(&kh, kh_code(ni, bin));
                if (kk != GI_HVDS_NO_KEY) {
                    key_up = kk;
                    ni_up = ni;
                }
                if (!(t.n[ni].child >= 0 && 0.5f * t.n[ni].size >= gh->foot))
                    break;
                ni = t.n[ni].child + child_of(&t.n[ni], gh->pos);
            }
            uint32_t key = kh_get(&kh, kh_code(ni, bin));
            if (key == GI_HVDS_NO_KEY && key_up != GI_HVDS_NO_KEY) {
                key = key_up;
                ni = ni_up;
            }
            int moved = 0;
            uint32_t key_occ = GI_HVDS_NO_KEY; /* the last key the check left */
            while (o.occlusion_check && key != GI_HVDS_NO_KEY && t.n[ni].child >= 0) {
                int ok = 1;
                float lift = 1e-3f * t.n[ni].size;
                for (int q = 0; q < NREP && ok; q++) {
                    uint32_t rp = reps[key * NREP + q];
                    if (rp == UINT32_MAX)
                        break;
                    ok = mutually_visible(rt, gi_v3p(gh->pos), ghit_nrm(s, gh), gi_v3p(ppos + 3 * rp),
                                          gi_v3p(pnrm + 3 * rp), lift);
                }
                if (ok)
                    break;
                key_occ = key;
                ni = t.n[ni].child + child_of(&t.n[ni], gh->pos);
                key = kh_get(&kh, kh_code(ni, bin));
                moved = 1;
            }
            descended += (uint64_t)moved;
            /* The check can land in a cell that holds no photon of the
             * hit's bin, and the ray then read no light. When the key it
             * left holds fewer than key_photons photons, that empty cell
             * says nothing (a sunlit floor of ~1000 photons/m^2 leaves most
             * 3 cm cells empty), and the ray keeps that key (lifted below
             * like any other). Sponza, 2.2% of all rays end keyless so, 81%
             * of them keep a key now; the gathering points beside a sunlit
             * strip read ~0.1 of the path tracer's light before (a column's
             * foot 5 cm above the upper gallery's floor: 42 lux against
             * 542). Against the references of docs/journal.md "Six frames nobody
             * tuned on", "Four more views" and the Sponza targets: every
             * sun frame better (u1-u3, u5, u6 0.0394 0.0518 0.1898 0.0328
             * 0.1794 -> 0.0383 0.0510 0.1808 0.0321 0.1767, sun-moved 0.0838
             * -> 0.0816, f1-f3 0.0918 0.0947 0.1462 -> 0.0896 0.0940 0.1395,
             * sun-b, sun-c, sun-wide 0.0964 0.1174 0.1254 -> 0.0939 0.1139
             * 0.1241), the lamp-only frames from -0.0013 to +0.0007
             * (arcades-b 0.0663 -> 0.0650, u4 0.0522 -> 0.0521, f4 0.0735
             * -> 0.0737, arcade-moved 0.0959 -> 0.0966); the Cornell box
             * unchanged. Keeping it whatever the key's count (measured
             * before) cost the lamp frames more (arcade-moved 0.0977) for
             * the same sun frames. Thin fins on a sunlit floor (t135) are a
             * case it does not mend: the floor's keys on both sides of a
             * fin leak, before and after (its shaded sides 1.47 -> 1.50 of
             * the path tracer, sunlit sides 0.78 -> 0.79, all points 0.990
             * -> 0.996, at 30 k photons). */
            if (moved && key == GI_HVDS_NO_KEY && ksub[key_occ] < kmin) {
                key = key_occ;
                kept_occ++;
            }
            uint32_t key_fp = key;
            while (key != GI_HVDS_NO_KEY && ksub[key] < kmin) {
                uint32_t pk = h->key_parent[key];
                if (pk == GI_HVDS_NO_KEY || !(h->key_scale[pk] > 0.0f))
                    break;
                key = pk;
                lifted++;
            }
            if (kmin0 && key != key_fp) {
                /* lifted: the coarser key averages surface the hit may not
                 * share (a sunlit strip's key read from its shaded foot). The
                 * first bounce, the entry points' exactly computed light,
                 * needs no photon count: it is read from the finest key that
                 * holds kmin0 entry points, when that is finer */
                uint32_t k0 = key_fp;
                while (ksub0[k0] < kmin0 && h->key_parent[k0] != GI_HVDS_NO_KEY && k0 != key)
                    k0 = h->key_parent[k0];
                if (k0 != key && ksub0[k0] >= kmin0) {
                    skeys[ns] = k0;
                    skeys[N + ns] = key;
                    ns++;
                    continue;
                }
            }
            if (key != GI_HVDS_NO_KEY)
                keys[nk++] = (uint64_t)key << 32 | (uint32_t)r;
        }
        if (kmin0) {
            uint32_t *sp = malloc((4 * (size_t)ns + 4) * sizeof *sp);
            if (!sp) {
                free(keys);
                free(skeys);
                oom_flag = 1;
                continue;
            }
            qsort(skeys, ns, sizeof *skeys, u32_cmp);
            qsort(skeys + N, ns, sizeof *skeys, u32_cmp);
            scnt0[i] = count_keys(skeys, ns, sp);
            scnt1[i] = count_keys(skeys + N, ns, sp + 2 * scnt0[i]);
            stmp[i] = sp;
            free(skeys);
        }
        qsort(keys, nk, sizeof *keys, u64_cmp);
        /* compact into (key, count, mean direction x, y, z) records of 5 words */
        uint32_t *pr = malloc((5 * (size_t)nk + 5) * sizeof *pr);
        float *sum = malloc((3 * (size_t)nk + 3) * sizeof *sum);
        if (!pr || !sum) {
            free(keys);
            free(pr);
            free(sum);
            oom_flag = 1;
            continue;
        }
        const float *gpos = h->gpoints[i].pos;
        uint32_t w = 0;
        for (uint32_t j = 0; j < nk; j++) {
            uint32_t key = (uint32_t)(keys[j] >> 32);
            const ghit *gh = &ph[(uint32_t)keys[j]];
            gi_vec3 d = gi_norm(gi_sub(gi_v3p(gh->pos), gi_v3p(gpos)));
            if (!(w > 0 && pr[5 * (w - 1)] == key)) {
                pr[5 * w] = key;
                pr[5 * w + 1] = 0;
                sum[3 * w] = sum[3 * w + 1] = sum[3 * w + 2] = 0.0f;
                w++;
            }
            pr[5 * (w - 1) + 1]++;
            sum[3 * (w - 1)] += d.x;
            sum[3 * (w - 1) + 1] += d.y;
            sum[3 * (w - 1) + 2] += d.z;
        }
        for (uint32_t j = 0; j < w; j++)
            for (int a = 0; a < 3; a++) {
                float m = sum[3 * j + a] / (float)pr[5 * j + 1];
                memcpy(&pr[5 * j + 2 + a], &m, sizeof m);
            }
        free(sum);
        free(keys);
        ptmp[i] = pr;
        pcnt[i] = w;
        gi_progress_add(&kprog, 1);
    }
    gi_progress_end(&kprog);
    if (oom_flag)
        goto oom;
    h->rays_descended = descended;
    h->rays_lifted = lifted;
    h->rays_kept_occ = kept_occ;
    h->rays_retraced = keep_hits ? 0 : (uint64_t)ng * (uint64_t)N;
    {
        uint64_t np = 0;
        for (size_t i = 0; i < ng; i++)
            np += pcnt[i];
        if (np > UINT32_MAX) {
            rc = gi_status_set(st, GI_EXIT_USAGE, "too many gathering-ray pairs (%llu)", (unsigned long long)np);
            goto fail;
        }
        h->num_pairs = (uint32_t)np;
        h->pair_key = malloc((np + 1) * sizeof *h->pair_key);
        h->pair_count = malloc((np + 1) * sizeof *h->pair_count);
        h->pair_dir = malloc(3 * (np + 1));
        if (!h->pair_key || !h->pair_count || !h->pair_dir)
            goto oom;
        uint32_t at = 0;
        for (size_t i = 0; i < ng; i++) {
            h->gpoints[i].first_pair = at;
            h->gpoints[i].num_pairs = pcnt[i];
            for (uint32_t j = 0; j < pcnt[i]; j++) {
                h->pair_key[at] = ptmp[i][5 * j];
                h->pair_count[at] = (uint16_t)ptmp[i][5 * j + 1];
                for (int a = 0; a < 3; a++) {
                    float m;
                    memcpy(&m, &ptmp[i][5 * j + 2 + a], sizeof m);
                    h->pair_dir[3 * (size_t)at + a] = (int8_t)lrintf(127.0f * gi_clampf(m, -1.0f, 1.0f));
                }
                at++;
            }
        }
    }
    if (kmin0) {
        uint64_t np = 0;
        for (size_t i = 0; i < ng; i++)
            np += (uint64_t)scnt0[i] + scnt1[i];
        if (np > UINT32_MAX) {
            rc = gi_status_set(st, GI_EXIT_USAGE, "too many split-ray pairs (%llu)", (unsigned long long)np);
            goto fail;
        }
        h->num_split = (uint32_t)np;
        h->split_first = malloc((ng + 1) * sizeof *h->split_first);
        h->split_n0 = malloc((ng + 1) * sizeof *h->split_n0);
        h->split_n1 = malloc((ng + 1) * sizeof *h->split_n1);
        h->split_key = malloc((np + 1) * sizeof *h->split_key);
        h->split_count = malloc((np + 1) * sizeof *h->split_count);
        if (!h->split_first || !h->split_n0 || !h->split_n1 || !h->split_key || !h->split_count)
            goto oom;
        uint32_t at = 0;
        for (size_t i = 0; i < ng; i++) {
            h->split_first[i] = at;
            h->split_n0[i] = scnt0[i];
            h->split_n1[i] = scnt1[i];
            for (uint32_t j = 0; j < scnt0[i] + scnt1[i]; j++) {
                h->split_key[at] = stmp[i][2 * j];
                h->split_count[at] = (uint16_t)stmp[i][2 * j + 1];
                at++;
            }
        }
    }

    /* statistics */
    h->num_nodes = (uint32_t)t.count;
    for (size_t i = 0; i < t.count; i++) {
        if (t.n[i].child < 0) {
            h->cells_per_level[t.n[i].level]++;
            if (t.n[i].level > h->depth)
                h->depth = t.n[i].level;
        }
    }
    goto done;
oom:
    rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory building the HVDS");
fail:
    gi_hvds_free(h);
    h = NULL;
done:
    if (ptmp)
        for (size_t i = 0; i < ng; i++)
            free(ptmp[i]);
    free(ptmp);
    free(pcnt);
    if (stmp)
        for (size_t i = 0; i < ng; i++)
            free(stmp[i]);
    free(stmp);
    free(scnt0);
    free(scnt1);
    free(ksub);
    free(ksub0);
    free(area);
    free(reps);
    free(recs);
    kh_free(&kh);
    free(t.n);
    free(flag);
    free(checked);
    free(order);
    free(lstart);
    free(pleaf);
    free(pbin);
    free(phid);
    free(pnrm);
    free(ppos);
    free(hits);
    free(rehits);
    free(reff);
    free(sel);
    free(c);
    *out = h;
    return rc;
}

void gi_hvds_free(gi_hvds *h)
{
    if (!h)
        return;
    free(h->key_parent);
    free(h->key_scale);
    free(h->key_level);
    free(h->photon_key);
    free(h->gpoints);
    free(h->pair_key);
    free(h->pair_count);
    free(h->pair_dir);
    free(h->split_first);
    free(h->split_n0);
    free(h->split_n1);
    free(h->split_key);
    free(h->split_count);
    free(h);
}

/* ---- .gih file ------------------------------------------------------------- */

#include "gi_container.h"
#include "gi_crc32.h"

#ifndef GI_VERSION
#define GI_VERSION "dev"
#endif

int gi_hvds_write(const gi_hvds *h, const char *path, const char *scene_path, const char *gip_path,
                  gi_status *st)
{
    gi_buf meta, octr, keys, pkey, gpts, gray;
    gi_buf_init(&meta);
    gi_buf_init(&octr);
    gi_buf_init(&keys);
    gi_buf_init(&pkey);
    gi_buf_init(&gpts);
    gi_buf_init(&gray);
    gi_buf gdir, gspl;
    gi_buf_init(&gdir);
    gi_buf_init(&gspl);
    int rc = 0;
    const gi_hvds_opts *o = &h->opts;
    if ((rc = gi_meta_add(&meta, "tool", "gi-hvds", st)) || (rc = gi_meta_add(&meta, "version", GI_VERSION, st)) ||
        (rc = gi_meta_add(&meta, "option.gather", o->gather == GI_GATHER_KMEANS ? "kmeans" : "rejection", st)) ||
        (rc = gi_meta_addf(&meta, "option.gather-rays", st, "%d", o->gather_rays)) ||
        (rc = gi_meta_addf(&meta, "option.r-min", st, "%.9g", o->r_min)) ||
        (rc = gi_meta_addf(&meta, "option.r-max", st, "%.9g", o->r_max)) ||
        (rc = gi_meta_addf(&meta, "option.dir-bins", st, "%d", o->dir_bins)) ||
        (rc = gi_meta_addf(&meta, "option.cell-photons", st, "%.9g", o->cell_photons)) ||
        (rc = gi_meta_addf(&meta, "option.key-photons", st, "%d", o->key_photons)) ||
        (rc = gi_meta_addf(&meta, "option.entry-keys", st, "%d", h->split_key ? o->entry_keys : 0)) ||
        (rc = gi_meta_addf(&meta, "option.occlusion-check", st, "%d", o->occlusion_check)) ||
        (rc = gi_meta_addf(&meta, "option.leak-check", st, "%d", o->leak_check)) ||
        (rc = gi_meta_addf(&meta, "option.seed", st, "%llu", (unsigned long long)o->seed)) ||
        (rc = gi_meta_add_input(&meta, "scene", scene_path, h->scene_hash, st)) ||
        (rc = gi_meta_add_input(&meta, "gip", gip_path, h->gip_fingerprint, st)))
        goto out;

    for (int a = 0; a < 3; a++)
        gi_buf_put_f32(&octr, h->root_min[a]);
    gi_buf_put_f32(&octr, h->root_size);
    gi_buf_put_u32(&octr, h->num_nodes);
    gi_buf_put_u32(&octr, h->depth);
    for (int l = 0; l <= GI_HVDS_MAX_DEPTH; l++)
        gi_buf_put_u32(&octr, h->cells_per_level[l]);

    gi_buf_put_u32(&keys, h->num_keys);
    for (uint32_t i = 0; i < h->num_keys; i++)
        gi_buf_put_u32(&keys, h->key_parent[i]);
    for (uint32_t i = 0; i < h->num_keys; i++)
        gi_buf_put_f32(&keys, h->key_scale[i]);
    for (uint32_t i = 0; i < h->num_keys; i++)
        gi_buf_put_u8(&keys, h->key_level[i]);

    gi_buf_put_u64(&pkey, h->num_photons);
    for (uint64_t i = 0; i < h->num_photons; i++)
        gi_buf_put_u32(&pkey, h->photon_key[i]);

    gi_buf_put_u32(&gpts, h->num_gpoints);
    for (uint32_t i = 0; i < h->num_gpoints; i++) {
        const gi_gpoint *g = &h->gpoints[i];
        for (int a = 0; a < 3; a++)
            gi_buf_put_f32(&gpts, g->pos[a]);
        for (int a = 0; a < 3; a++)
            gi_buf_put_f32(&gpts, g->nrm[a]);
        gi_buf_put_f32(&gpts, g->radius);
        gi_buf_put_f32(&gpts, g->r_harmonic);
        gi_buf_put_u32(&gpts, g->tri);
        gi_buf_put_u32(&gpts, g->first_pair);
        gi_buf_put_u32(&gpts, g->num_pairs);
    }

    gi_buf_put_u32(&gray, h->num_pairs);
    gi_buf_put_u64(&gray, h->num_rays);
    gi_buf_put_u64(&gray, h->rays_descended);
    for (uint32_t i = 0; i < h->num_pairs; i++)
        gi_buf_put_u32(&gray, h->pair_key[i]);
    for (uint32_t i = 0; i < h->num_pairs; i++)
        gi_buf_put_u16(&gray, h->pair_count[i]);
    if (h->pair_dir) {
        gi_buf_put_u32(&gdir, h->num_pairs);
        gi_buf_put_bytes(&gdir, h->pair_dir, 3 * (size_t)h->num_pairs);
    }
    if (h->split_key) {
        gi_buf_put_u32(&gspl, h->num_gpoints);
        gi_buf_put_u32(&gspl, h->num_split);
        for (uint32_t i = 0; i < h->num_gpoints; i++) {
            gi_buf_put_u32(&gspl, h->split_first[i]);
            gi_buf_put_u32(&gspl, h->split_n0[i]);
            gi_buf_put_u32(&gspl, h->split_n1[i]);
        }
        for (uint32_t i = 0; i < h->num_split; i++)
            gi_buf_put_u32(&gspl, h->split_key[i]);
        for (uint32_t i = 0; i < h->num_split; i++)
            gi_buf_put_u16(&gspl, h->split_count[i]);
    }

    gi_writer *w = gi_writer_new(GI_HVDS_MAGIC, GI_HVDS_MAJOR, GI_HVDS_MINOR);
    if (!w) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        goto out;
    }
    if (!(rc = gi_writer_add_buf(w, "META", 0, &meta, st)) && !(rc = gi_writer_add_buf(w, "OCTR", 0, &octr, st)) &&
        !(rc = gi_writer_add_buf(w, "KEYS", 0, &keys, st)) && !(rc = gi_writer_add_buf(w, "PKEY", 0, &pkey, st)) &&
        !(rc = gi_writer_add_buf(w, "GPTS", 0, &gpts, st)) && !(rc = gi_writer_add_buf(w, "GRAY", 0, &gray, st)) &&
        !(rc = h->pair_dir ? gi_writer_add_buf(w, "GDIR", 0, &gdir, st) : 0) &&
        !(rc = h->split_key ? gi_writer_add_buf(w, "GSPL", 0, &gspl, st) : 0))
        rc = gi_writer_write(w, path, st);
    gi_writer_free(w);
out:
    gi_buf_release(&meta);
    gi_buf_release(&octr);
    gi_buf_release(&keys);
    gi_buf_release(&pkey);
    gi_buf_release(&gpts);
    gi_buf_release(&gray);
    gi_buf_release(&gdir);
    gi_buf_release(&gspl);
    return rc;
}

/* n (key, count) pairs as GRAY and GSPL store them: n u32 keys, each < num_keys, then n u16
 * counts; what names a pair in the error ("gathering pair 3 names key 9 of 8") */
static int read_pairs(gi_cursor *c, uint32_t n, uint32_t num_keys, uint32_t *key, uint16_t *count, const char *what,
                      gi_status *st)
{
    int rc;
    for (uint32_t i = 0; i < n; i++) {
        if ((rc = gi_cursor_u32(c, &key[i], st)))
            return rc;
        if (key[i] >= num_keys)
            return gi_cursor_fail(c, st, "%s %u names key %u of %u", what, i, key[i], num_keys);
    }
    for (uint32_t i = 0; i < n; i++)
        if ((rc = gi_cursor_u16(c, &count[i], st)))
            return rc;
    return gi_cursor_end(c, st);
}

int gi_hvds_read(const char *path, const gi_scene *s, uint64_t gip_fingerprint, uint64_t num_photons,
                 gi_hvds **out, gi_status *st)
{
    *out = NULL;
    gi_reader *r = NULL;
    int rc = gi_reader_open(path, GI_HVDS_MAGIC, GI_HVDS_MAJOR, &r, st);
    if (rc)
        return rc;
    char hex[17];
    gi_hash64_hex(s->hash, hex);
    if ((rc = gi_container_check_input(r, "input.scene.hash", hex, st))) {
        gi_reader_free(r);
        return rc;
    }
    gi_hash64_hex(gip_fingerprint, hex);
    if ((rc = gi_container_check_input(r, "input.gip.hash", hex, st))) {
        gi_reader_free(r);
        return rc;
    }
    gi_hvds *h = calloc(1, sizeof *h);
    if (!h) {
        gi_reader_free(r);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    }
    h->scene_hash = s->hash;
    h->gip_fingerprint = gip_fingerprint;
    gi_hvds_opts_default(&h->opts);
    const char *v;
    if ((v = gi_reader_meta(r, "option.gather-rays")))
        h->opts.gather_rays = atoi(v);
    h->opts.key_photons = 0; /* files from before the option */
    if ((v = gi_reader_meta(r, "option.key-photons")))
        h->opts.key_photons = atoi(v);
    h->opts.entry_keys = 0; /* files without split rays */
    if ((v = gi_reader_meta(r, "option.entry-keys")))
        h->opts.entry_keys = atoi(v);
    if ((v = gi_reader_meta(r, "option.r-min")))
        h->opts.r_min = strtof(v, NULL);
    if ((v = gi_reader_meta(r, "option.r-max")))
        h->opts.r_max = strtof(v, NULL);
    if ((v = gi_reader_meta(r, "option.gather")))
        h->opts.gather = !strcmp(v, "kmeans") ? GI_GATHER_KMEANS : GI_GATHER_REJECTION;

    gi_cursor c;
    uint32_t u32;
    uint64_t u64;
    /* OCTR */
    if ((rc = gi_reader_cursor(r, "OCTR", &c, st)))
        goto fail;
    for (int a = 0; a < 3 && !rc; a++)
        rc = gi_cursor_f32(&c, &h->root_min[a], st);
    if (rc || (rc = gi_cursor_f32(&c, &h->root_size, st)) || (rc = gi_cursor_u32(&c, &h->num_nodes, st)) ||
        (rc = gi_cursor_u32(&c, &h->depth, st)))
        goto fail;
    for (int l = 0; l <= GI_HVDS_MAX_DEPTH && !rc; l++)
        rc = gi_cursor_u32(&c, &h->cells_per_level[l], st);
    if (rc || (rc = gi_cursor_end(&c, st)))
        goto fail;
    if (h->depth > GI_HVDS_MAX_DEPTH) {
        rc = gi_cursor_fail(&c, st, "octree depth %u exceeds %d", h->depth, GI_HVDS_MAX_DEPTH);
        goto fail;
    }
    /* KEYS */
    if ((rc = gi_reader_cursor(r, "KEYS", &c, st)) || (rc = gi_cursor_u32(&c, &u32, st)) ||
        (rc = gi_cursor_check_count(&c, u32, 9, "keys", st)))
        goto fail;
    h->num_keys = u32;
    h->key_parent = gi_alloc_large(((size_t)u32 + 1) * sizeof *h->key_parent);
    h->key_scale = gi_alloc_large(((size_t)u32 + 1) * sizeof *h->key_scale);
    h->key_level = gi_alloc_large((size_t)u32 + 1);
    if (!h->key_parent || !h->key_scale || !h->key_level)
        goto oom;
    for (uint32_t i = 0; i < h->num_keys; i++) {
        if ((rc = gi_cursor_u32(&c, &h->key_parent[i], st)))
            goto fail;
        if (h->key_parent[i] != GI_HVDS_NO_KEY && (h->key_parent[i] <= i || h->key_parent[i] >= h->num_keys)) {
            rc = gi_cursor_fail(&c, st, "key %u has parent %u (must be a later key below %u)", i,
                                h->key_parent[i], h->num_keys);
            goto fail;
        }
    }
    for (uint32_t i = 0; i < h->num_keys; i++) {
        if ((rc = gi_cursor_f32(&c, &h->key_scale[i], st)))
            goto fail;
        if (!(h->key_scale[i] >= 0.0f) || !isfinite(h->key_scale[i])) {
            rc = gi_cursor_fail(&c, st, "key %u has a bad scale %g", i, h->key_scale[i]);
            goto fail;
        }
    }
    for (uint32_t i = 0; i < h->num_keys && !rc; i++)
        rc = gi_cursor_u8(&c, &h->key_level[i], st);
    if (rc || (rc = gi_cursor_end(&c, st)))
        goto fail;
    /* PKEY */
    if ((rc = gi_reader_cursor(r, "PKEY", &c, st)) || (rc = gi_cursor_u64(&c, &u64, st)) ||
        (rc = gi_cursor_check_count(&c, u64, 4, "photon keys", st)))
        goto fail;
    if (u64 != num_photons) {
        rc = gi_cursor_fail(&c, st, "maps %llu photons but the .gip has %llu", (unsigned long long)u64,
                            (unsigned long long)num_photons);
        goto fail;
    }
    h->num_photons = u64;
    h->photon_key = gi_alloc_large((u64 + 1) * sizeof *h->photon_key);
    if (!h->photon_key)
        goto oom;
    for (uint64_t i = 0; i < u64; i++) {
        if ((rc = gi_cursor_u32(&c, &h->photon_key[i], st)))
            goto fail;
        if (h->photon_key[i] != GI_HVDS_NO_KEY && h->photon_key[i] >= h->num_keys) {
            rc = gi_cursor_fail(&c, st, "photon %llu maps to key %u of %u", (unsigned long long)i,
                                h->photon_key[i], h->num_keys);
            goto fail;
        }
    }
    if ((rc = gi_cursor_end(&c, st)))
        goto fail;
    /* GRAY (read before GPTS so point ranges can be checked) */
    gi_cursor cg;
    if ((rc = gi_reader_cursor(r, "GRAY", &cg, st)) || (rc = gi_cursor_u32(&cg, &u32, st)) ||
        (rc = gi_cursor_u64(&cg, &h->num_rays, st)) || (rc = gi_cursor_u64(&cg, &h->rays_descended, st)) ||
        (rc = gi_cursor_check_count(&cg, u32, 6, "gathering pairs", st)))
        goto fail;
    h->num_pairs = u32;
    h->pair_key = gi_alloc_large(((size_t)u32 + 1) * sizeof *h->pair_key);
    h->pair_count = gi_alloc_large(((size_t)u32 + 1) * sizeof *h->pair_count);
    if (!h->pair_key || !h->pair_count)
        goto oom;
    if ((rc = read_pairs(&cg, u32, h->num_keys, h->pair_key, h->pair_count, "gathering pair", st)))
        goto fail;
    /* GDIR (optional, 1.1): mean direction of each pair's rays */
    if (gi_reader_section(r, "GDIR", NULL)) {
        gi_cursor cd;
        const void *bytes = NULL;
        if ((rc = gi_reader_cursor(r, "GDIR", &cd, st)) || (rc = gi_cursor_u32(&cd, &u32, st)))
            goto fail;
        if (u32 != h->num_pairs) {
            rc = gi_cursor_fail(&cd, st, "%u pair directions for %u gathering pairs", u32, h->num_pairs);
            goto fail;
        }
        if ((rc = gi_cursor_bytes(&cd, &bytes, 3 * (size_t)u32, st)) || (rc = gi_cursor_end(&cd, st)))
            goto fail;
        h->pair_dir = gi_alloc_large(3 * (size_t)u32 + 3);
        if (!h->pair_dir)
            goto oom;
        memcpy(h->pair_dir, bytes, 3 * (size_t)u32);
    }
    /* GPTS */
    if ((rc = gi_reader_cursor(r, "GPTS", &c, st)) || (rc = gi_cursor_u32(&c, &u32, st)) ||
        (rc = gi_cursor_check_count(&c, u32, 44, "gathering points", st)))
        goto fail;
    h->num_gpoints = u32;
    h->gpoints = gi_calloc_large((size_t)u32 + 1, sizeof *h->gpoints);
    if (!h->gpoints)
        goto oom;
    for (uint32_t i = 0; i < u32; i++) {
        gi_gpoint *g = &h->gpoints[i];
        for (int a = 0; a < 3 && !rc; a++)
            rc = gi_cursor_f32(&c, &g->pos[a], st);
        for (int a = 0; a < 3 && !rc; a++)
            rc = gi_cursor_f32(&c, &g->nrm[a], st);
        if (rc || (rc = gi_cursor_f32(&c, &g->radius, st)) || (rc = gi_cursor_f32(&c, &g->r_harmonic, st)) ||
            (rc = gi_cursor_u32(&c, &g->tri, st)) || (rc = gi_cursor_u32(&c, &g->first_pair, st)) ||
            (rc = gi_cursor_u32(&c, &g->num_pairs, st)))
            goto fail;
        int finite = isfinite(g->pos[0]) && isfinite(g->pos[1]) && isfinite(g->pos[2]) && isfinite(g->nrm[0]) &&
                     isfinite(g->nrm[1]) && isfinite(g->nrm[2]) && g->radius > 0.0f && isfinite(g->radius);
        if (!finite || g->tri >= s->num_triangles || g->first_pair > h->num_pairs ||
            g->num_pairs > h->num_pairs - g->first_pair) {
            rc = gi_cursor_fail(&c, st, "gathering point %u is invalid (position, radius, triangle or pair range)", i);
            goto fail;
        }
    }
    if ((rc = gi_cursor_end(&c, st)))
        goto fail;
    /* GSPL (optional, 1.2): split rays */
    if (gi_reader_section(r, "GSPL", NULL)) {
        gi_cursor cs;
        uint32_t ngp = 0;
        if ((rc = gi_reader_cursor(r, "GSPL", &cs, st)) || (rc = gi_cursor_u32(&cs, &ngp, st)) ||
            (rc = gi_cursor_u32(&cs, &u32, st)))
            goto fail;
        if (ngp != h->num_gpoints) {
            rc = gi_cursor_fail(&cs, st, "split rays for %u gathering points, the file has %u", ngp, h->num_gpoints);
            goto fail;
        }
        if ((rc = gi_cursor_check_count(&cs, u32, 6, "split-ray pairs", st)))
            goto fail;
        h->num_split = u32;
        h->split_first = gi_alloc_large(((size_t)ngp + 1) * sizeof *h->split_first);
        h->split_n0 = gi_alloc_large(((size_t)ngp + 1) * sizeof *h->split_n0);
        h->split_n1 = gi_alloc_large(((size_t)ngp + 1) * sizeof *h->split_n1);
        h->split_key = gi_alloc_large(((size_t)u32 + 1) * sizeof *h->split_key);
        h->split_count = gi_alloc_large(((size_t)u32 + 1) * sizeof *h->split_count);
        if (!h->split_first || !h->split_n0 || !h->split_n1 || !h->split_key || !h->split_count)
            goto oom;
        for (uint32_t i = 0; i < ngp; i++) {
            if ((rc = gi_cursor_u32(&cs, &h->split_first[i], st)) || (rc = gi_cursor_u32(&cs, &h->split_n0[i], st)) ||
                (rc = gi_cursor_u32(&cs, &h->split_n1[i], st)))
                goto fail;
            uint64_t end = (uint64_t)h->split_first[i] + h->split_n0[i] + h->split_n1[i];
            if (end > u32) {
                rc = gi_cursor_fail(&cs, st, "gathering point %u: split-ray pairs end at %llu, beyond the %u pairs", i,
                                    (unsigned long long)end, u32);
                goto fail;
            }
        }
        if ((rc = read_pairs(&cs, u32, h->num_keys, h->split_key, h->split_count, "split-ray pair", st)))
            goto fail;
    }
    gi_reader_free(r);
    *out = h;
    return 0;
oom:
    rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
fail:
    gi_reader_free(r);
    gi_hvds_free(h);
    return rc;
}
