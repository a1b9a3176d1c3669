/* gi_texfilter.c - footprint-filtered base-colour textures (see gi_texfilter.h). */
#include "gi_texfilter.h"
#include "gi_mem.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define GI_TEXF_MAX_LEVELS 24
#define GI_TEXF_NMAX 8 /* lookups per footprint axis, at most */
#define GI_TEXF_CLAMP_ROWS 128 /* rows at level 0 for a footprint beyond a clamped edge */

typedef struct pyramid {
    int levels;
    gi_texture lv[GI_TEXF_MAX_LEVELS]; /* lv[0] shares the scene's texels */
    /* per level and row, with the texture constant over each texel (texel k
     * on [k, k+1)): F(x) = integral of the row from 0 to x, and G(x) = the
     * integral of F; pre[l][((y * (w + 1) + x) * 2 + {0: F, 1: G}) * 3 + c] at
     * integer x (double: G grows with w^2) */
    double *pre[GI_TEXF_MAX_LEVELS];
} pyramid;

struct gi_texfilter {
    const gi_scene *s;
    pyramid *p;   /* one per texture */
    uint8_t *bnd; /* per triangle: bit e (uv0) or 3 + e (uv1) when its edge e
                     (v_e to v_(e+1)%3) has no other triangle with the same
                     positions and texture coordinates: an edge of its UV
                     island (NULL: out of memory at build, none known) */
};

void gi_texfilter_free(gi_texfilter *f)
{
    if (!f)
        return;
    for (size_t t = 0; f->p && t < f->s->num_textures; t++)
        for (int l = 0; l < f->p[t].levels; l++) {
            if (l > 0)
                free(f->p[t].lv[l].rgba);
            free(f->p[t].pre[l]);
        }
    free(f->p);
    free(f->bnd);
    free(f);
}

/* ---- UV-island edges --------------------------------------------------------
 * A footprint's parallelogram lies in its triangle's plane and mapping; past an
 * edge that no triangle continues with the same texture coordinates (the rim
 * of a face, a seam of an atlas) the pixel sees something else, and the
 * texture there is whatever the atlas holds beyond the island. */
typedef struct edge_rec {
    uint64_t h;
    uint32_t tri;
    uint8_t e;
} edge_rec;

/* an edge's endpoints (position and texture coordinates), in a canonical order */
static void edge_key(const gi_scene *s, const float *uvs, uint32_t tri, int e, float k[10])
{
    const uint32_t *ix = s->indices + 3 * (size_t)tri;
    uint32_t a = ix[e], b = ix[(e + 1) % 3];
    float ka[5], kb[5];
    for (int c = 0; c < 3; c++) {
        ka[c] = s->positions[3 * (size_t)a + c];
        kb[c] = s->positions[3 * (size_t)b + c];
    }
    for (int c = 0; c < 2; c++) {
        ka[3 + c] = uvs[2 * (size_t)a + c];
        kb[3 + c] = uvs[2 * (size_t)b + c];
    }
    int swap = memcmp(ka, kb, sizeof ka) > 0;
    memcpy(k, swap ? kb : ka, sizeof ka);
    memcpy(k + 5, swap ? ka : kb, sizeof ka);
}

static uint64_t edge_hash(const float k[10])
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (int i = 0; i < 10; i++) {
        float v = k[i] == 0.0f ? 0.0f : k[i]; /* -0 and 0 alike */
        uint32_t u;
        memcpy(&u, &v, sizeof u);
        h = (h ^ u) * 0x100000001b3ull;
        h ^= h >> 29;
    }
    return h;
}

static int edge_cmp(const void *pa, const void *pb)
{
    const edge_rec *a = pa, *b = pb;
    return a->h < b->h ? -1 : a->h > b->h;
}

static void float_key_zero(float k[10])
{
    for (int i = 0; i < 10; i++)
        if (k[i] == 0.0f)
            k[i] = 0.0f;
}

/* f->bnd for both texture-coordinate sets; left NULL when out of memory (no
 * island edges known: footprints as before) */
static void island_edges(gi_texfilter *f)
{
    const gi_scene *s = f->s;
    size_t nt = s->num_triangles, ne = 3 * nt;
    if (!nt || !s->num_textures)
        return;
    uint8_t *bnd = calloc(nt, 1);
    edge_rec *r = gi_alloc_large(ne * sizeof *r);
    if (!bnd || !r) {
        free(bnd);
        free(r);
        return;
    }
    for (int set = 0; set < 2; set++) {
        const float *uvs = set ? s->uv1 : s->uv0;
        for (size_t t = 0; t < nt; t++)
            for (int e = 0; e < 3; e++) {
                float k[10];
                edge_key(s, uvs, (uint32_t)t, e, k);
                float_key_zero(k);
                r[3 * t + (size_t)e] = (edge_rec){edge_hash(k), (uint32_t)t, (uint8_t)e};
            }
        qsort(r, ne, sizeof *r, edge_cmp);
        for (size_t i = 0; i < ne;) {
            size_t j = i + 1;
            while (j < ne && r[j].h == r[i].h)
                j++;
            /* within a run of one hash: an edge whose key no other shares
             * (a long run, e.g. many copies of one edge, is taken as shared
             * rather than compared pair by pair) */
            for (size_t a = i; a < j && j - i <= 64; a++) {
                float ka[10];
                edge_key(s, uvs, r[a].tri, r[a].e, ka);
                float_key_zero(ka);
                int shared = 0;
                for (size_t b = i; b < j && !shared; b++) {
                    if (b == a)
                        continue;
                    float kb[10];
                    edge_key(s, uvs, r[b].tri, r[b].e, kb);
                    float_key_zero(kb);
                    shared = !memcmp(ka, kb, sizeof ka);
                }
                if (!shared)
                    bnd[r[a].tri] |= (uint8_t)(1u << (3 * set + r[a].e));
            }
            i = j;
        }
    }
    free(r);
    f->bnd = bnd;
}

/* Next level: ceil(w/2) x ceil(h/2), each texel the mean of its (up to) 2 x 2
 * parents; an odd last row or column is averaged with itself. */
static float *halve(const gi_texture *src, int w2, int h2)
{
    float *o = gi_alloc_large((size_t)w2 * (size_t)h2 * 4 * sizeof *o);
    if (!o)
        return NULL;
    const int w = src->width, h = src->height;
    for (int y = 0; y < h2; y++) {
        int y0 = 2 * y < h ? 2 * y : h - 1, y1 = 2 * y + 1 < h ? 2 * y + 1 : y0;
        for (int x = 0; x < w2; x++) {
            int x0 = 2 * x < w ? 2 * x : w - 1, x1 = 2 * x + 1 < w ? 2 * x + 1 : x0;
            const float *a = src->rgba + 4 * ((size_t)y0 * (size_t)w + (size_t)x0);
            const float *b = src->rgba + 4 * ((size_t)y0 * (size_t)w + (size_t)x1);
            const float *c = src->rgba + 4 * ((size_t)y1 * (size_t)w + (size_t)x0);
            const float *d = src->rgba + 4 * ((size_t)y1 * (size_t)w + (size_t)x1);
            float *q = o + 4 * ((size_t)y * (size_t)w2 + (size_t)x);
            for (int k = 0; k < 4; k++)
                q[k] = 0.25f * (a[k] + b[k] + c[k] + d[k]);
        }
    }
    return o;
}

int gi_texfilter_new(const gi_scene *s, gi_texfilter **out, gi_status *st)
{
    *out = NULL;
    gi_texfilter *f = calloc(1, sizeof *f);
    if (!f)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    f->s = s;
    f->p = calloc(s->num_textures ? s->num_textures : 1, sizeof *f->p);
    if (!f->p) {
        free(f);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    }
    for (size_t t = 0; t < s->num_textures; t++) {
        pyramid *p = &f->p[t];
        const gi_texture *tx = &s->textures[t];
        p->lv[0] = *tx;
        p->levels = 1;
        if (!tx->rgba || tx->width < 1 || tx->height < 1)
            continue;
        while (p->levels < GI_TEXF_MAX_LEVELS) {
            const gi_texture *prev = &p->lv[p->levels - 1];
            if (prev->width == 1 && prev->height == 1)
                break;
            gi_texture *nx = &p->lv[p->levels];
            *nx = *prev;
            nx->nearest = 0;
            nx->width = (prev->width + 1) / 2;
            nx->height = (prev->height + 1) / 2;
            nx->rgba = halve(prev, nx->width, nx->height);
            if (!nx->rgba) {
                gi_texfilter_free(f);
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the mip levels of texture %zu", t);
            }
            p->levels++;
        }
        for (int l = 0; l < p->levels; l++) {
            const gi_texture *lt = &p->lv[l];
            size_t w1 = (size_t)lt->width + 1;
            double *pre = gi_alloc_large(w1 * (size_t)lt->height * 6 * sizeof *pre);
            if (!pre) {
                gi_texfilter_free(f);
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the row sums of texture %zu", t);
            }
            for (int y = 0; y < lt->height; y++) {
                double *row = pre + (size_t)y * w1 * 6;
                const float *src = lt->rgba + (size_t)y * (size_t)lt->width * 4;
                for (int c = 0; c < 6; c++)
                    row[c] = 0.0;
                for (int x = 0; x < lt->width; x++)
                    for (int c = 0; c < 3; c++) {
                        double F0 = row[6 * x + c], G0 = row[6 * x + 3 + c], v = src[4 * x + c];
                        row[6 * (x + 1) + c] = F0 + v;
                        row[6 * (x + 1) + 3 + c] = G0 + F0 + 0.5 * v;
                    }
            }
            p->pre[l] = pre;
        }
    }
    island_edges(f);
    *out = f;
    return 0;
}

/* F and G (see pyramid) of the row whose sums start at pr, at x in [0, w]:
 * inside the texture every wrap mode agrees, and this is all the lookups of a
 * footprint that lies in one period (see parallelogram_mean). A cut's x may
 * round a few ulps past [0, w]: the edge texel is extrapolated there. */
static inline void row_FG_in(const double *pr, int w, double x, double F[3], double G[3])
{
    int i = x > 0.0 ? (int)x : 0;
    if (i > w - 1)
        i = w - 1;
    double fr = x - (double)i;
    /* the texel's value is F's step over it: the texels themselves are
     * another array, and reading them cost another cache miss per lookup */
    const double *p = pr + 6 * (size_t)i;
    for (int c = 0; c < 3; c++) {
        double Fl = p[c], v = p[6 + c] - Fl;
        F[c] = Fl + fr * v;
        G[c] = p[3 + c] + Fl * fr + 0.5 * fr * fr * v;
    }
}

/* F and G of the row with sums pr and texels tx at any x, extended beyond
 * [0, w) by the s wrap mode. */
static void row_FG(const gi_texture *t, const double *pr, const float *tx, double x, double F[3], double G[3])
{
    const int w = t->width;
    if (t->wrap_s == GI_WRAP_CLAMP && (x <= 0.0 || x >= (double)w)) {
        /* constant edge texels continue outside */
        if (x <= 0.0) {
            for (int c = 0; c < 3; c++) {
                F[c] = x * tx[c];
                G[c] = 0.5 * x * x * tx[c];
            }
        } else {
            double d = x - (double)w;
            for (int c = 0; c < 3; c++) {
                double v = tx[4 * (w - 1) + c];
                F[c] = pr[6 * w + c] + d * v;
                G[c] = pr[6 * w + 3 + c] + pr[6 * w + c] * d + 0.5 * d * d * v;
            }
        }
        return;
    }
    /* periodic: F(x + P) = F(x) + TP, G(x + P) = G(x) + GP + x TP, so
     * G(m P + xf) = G(xf) + m GP + TP (m xf + P m (m - 1) / 2) */
    int mirror = t->wrap_s == GI_WRAP_MIRROR;
    double P = mirror ? 2.0 * w : (double)w;
    double m = 0.0, xf = x;
    if (t->wrap_s != GI_WRAP_CLAMP && !(x >= 0.0 && x < P)) { /* in the first period: no division */
        m = floor(x / P);
        xf = x - m * P;
    }
    int flip = mirror && xf >= (double)w; /* second half of a mirror period */
    double xi = flip ? 2.0 * w - xf : xf;
    if (!mirror && m == 0.0) {
        /* the common case, in the first period: the row's totals at its end
         * (another cache line) are not needed */
        row_FG_in(pr, w, xi, F, G);
        return;
    }
    /* (NaN x: i = 0, and F and G are NaN) */
    int i = xi > 0.0 ? (int)xi : 0;
    if (i > w - 1)
        i = w - 1;
    double fr = xi - (double)i;
    for (int c = 0; c < 3; c++) {
        double T = pr[6 * w + c], Gw = pr[6 * w + 3 + c], v = pr[6 * (i + 1) + c] - pr[6 * i + c];
        double Fi = pr[6 * i + c] + fr * v;
        double Gi = pr[6 * i + 3 + c] + pr[6 * i + c] * fr + 0.5 * fr * fr * v;
        double Fp = Fi, Gp = Gi, TP = T, GP = Gw;
        if (mirror) {
            /* on [w, 2w): F = 2T - F_in(2w - x), G = 2T (x - w) + G_in(2w - x) */
            if (flip) {
                Fp = 2.0 * T - Fi;
                Gp = 2.0 * T * (xf - (double)w) + Gi;
            }
            TP = 2.0 * T;
            GP = 2.0 * T * (double)w;
        }
        F[c] = Fp + m * TP;
        G[c] = Gp + m * GP + TP * (m * xf + P * m * (m - 1.0) * 0.5);
    }
}

/* Wrap row yr (an integer) by the texture's t mode. */
static int wrap_row(double yr, int h, int mode)
{
    if (yr >= 0.0 && yr < (double)h)
        return (int)yr; /* inside: the common case, no division */
    if (mode == GI_WRAP_CLAMP)
        return yr < 0.0 ? 0 : h - 1;
    double p = mode == GI_WRAP_MIRROR ? 2.0 * h : (double)h;
    double m = fmod(yr, p); /* exact, and no int overflow for a far-away row */
    if (m < 0.0)
        m += p;
    int r = (int)m;
    return r < h ? r : 2 * h - 1 - r;
}

/* The parallelogram s a + t b, |s|, |t| <= 1/2, as two chains of edges from
 * its bottom vertex to its top one, for the x extent at a height y. */
typedef struct pgram {
    double a[2], b[2], inv[2]; /* for x_extent: the edges, 1 / a_y and 1 / b_y */
    double hy;                 /* the vertices' y: -hy, vy[1], vy[2], hy */
    double vy[4];              /* sorted */
    double tol;                /* a y closer than this to a vertex's takes x_extent */
    int chains;                /* 0 with a (nearly) horizontal edge: x_extent only */
    double bx;                 /* the bottom vertex's x */
    double lx, ly, rx, ry;     /* the middle vertex of the left chain and of the right one */
    double s1, s2;             /* dx/dy along the left chain's lower and upper edge (the right chain's upper
                                  and lower: opposite edges are parallel) */
} pgram;

static void pgram_init(pgram *g, const double a[2], const double b[2])
{
    g->a[0] = a[0];
    g->a[1] = a[1];
    g->b[0] = b[0];
    g->b[1] = b[1];
    /* 1 / a_y and 1 / b_y for x_extent: a division there per edge and cut was
     * most of the filter's time */
    g->inv[0] = fabs(a[1]) < 1e-12 ? 0.0 : 1.0 / a[1];
    g->inv[1] = fabs(b[1]) < 1e-12 ? 0.0 : 1.0 / b[1];
    /* the edges pointing up */
    double ua[2] = {a[1] < 0.0 ? -a[0] : a[0], fabs(a[1])}, ub[2] = {b[1] < 0.0 ? -b[0] : b[0], fabs(b[1])};
    g->hy = 0.5 * (ua[1] + ub[1]);
    double m = 0.5 * fabs(ua[1] - ub[1]);
    g->vy[0] = -g->hy;
    g->vy[1] = -m;
    g->vy[2] = m;
    g->vy[3] = g->hy;
    /* x_extent takes an edge up to 1e-9 of its length past its ends, and
     * rounds: near a vertex the two may differ, anywhere else both cut the
     * same two edges */
    g->tol = 4e-9 * (ua[1] + ub[1]);
    g->chains = ua[1] >= 1e-12 && ub[1] >= 1e-12;
    /* from the bottom vertex -(ua + ub) / 2 the left chain goes up the edge
     * that turns counterclockwise from the other */
    int ub_left = ua[0] * ub[1] - ua[1] * ub[0] > 0.0;
    const double *dl = ub_left ? ub : ua, *dr = ub_left ? ua : ub;
    g->bx = -0.5 * (ua[0] + ub[0]);
    g->lx = 0.5 * (dl[0] - dr[0]);
    g->ly = 0.5 * (dl[1] - dr[1]);
    g->rx = -g->lx;
    g->ry = -g->ly;
    g->s1 = dl[1] > 0.0 ? dl[0] / dl[1] : 0.0;
    g->s2 = dr[1] > 0.0 ? dr[0] / dr[1] : 0.0;
}

/* x extent {min, max} of {s a + t b : s a_y + t b_y = ym, |s|, |t| <= 1/2};
 * {+inf, -inf} when the line misses the parallelogram. */
static void x_extent(const pgram *g, double ym, double out[2])
{
    double lo = INFINITY, hi = -INFINITY;
    for (int e = 0; e < 4; e++) {
        double fixed = (e & 1) ? 0.5 : -0.5;
        const double *pf = e < 2 ? g->a : g->b, *po = e < 2 ? g->b : g->a; /* pf's parameter is fixed */
        if (fabs(po[1]) < 1e-12)
            continue;
        double other = (ym - fixed * pf[1]) * g->inv[e < 2 ? 1 : 0];
        if (other < -0.5 - 1e-9 || other > 0.5 + 1e-9)
            continue;
        double xv = fixed * pf[0] + other * po[0];
        /* (not fmin and fmax: library calls at -O2, 4% of the filter) */
        lo = xv < lo ? xv : lo;
        hi = xv > hi ? xv : hi;
    }
    out[0] = lo;
    out[1] = hi;
}

/* The x extent at height yy (relative to the centre) where a row's piece
 * starts (first) or ends. Returns 0 when it had to nudge yy (then the extent
 * depends on first). */
static int cut_extent(const pgram *g, double yy, int first, double xe[2])
{
    if (g->chains && yy - g->vy[0] > g->tol && g->vy[3] - yy > g->tol && fabs(yy - g->vy[1]) > g->tol &&
        fabs(yy - g->vy[2]) > g->tol) {
        /* away from the vertices (the cuts at row boundaries, most of them):
         * one edge of each chain, no tests */
        xe[0] = yy < g->ly ? g->bx + (yy + g->hy) * g->s1 : g->lx + (yy - g->ly) * g->s2;
        xe[1] = yy < g->ry ? g->bx + (yy + g->hy) * g->s2 : g->rx + (yy - g->ry) * g->s1;
        return 1;
    }
    x_extent(g, yy, xe);
    if (xe[1] >= xe[0])
        return 1;
    /* at the parallelogram's top or bottom vertex rounding may miss it:
     * nudge inside */
    x_extent(g, yy + (first ? 1e-9 : -1e-9) * (1.0 + fabs(g->hy)), xe);
    if (!(xe[1] >= xe[0]))
        xe[0] = xe[1] = 0.5 * (xe[0] + xe[1]);
    if (!isfinite(xe[0]))
        xe[0] = xe[1] = 0.0;
    return 0;
}

/* A row's cuts (at most its two ends and the two middle vertices): y
 * (absolute) and the extent's ends there (relative to the centre). */
typedef struct rowcuts {
    int nc;
    const double *pr; /* the row's F and G */
    const float *tx;  /* its texels */
    double y[4], xe[4][2];
} rowcuts;

#define GI_TEXF_CHUNK 8 /* rows whose cuts are found (and lookups prefetched) before the first lookup */

/* Exact average of a (piecewise constant) level over the parallelogram
 * c + s a + t b, s, t in [-1/2, 1/2], in texel units: row by row, cut at the
 * parallelogram's vertices, so that on each piece both ends of the row's
 * x extent move linearly and the integral of F along an end is exact.
 * Returns 0 when the parallelogram spans more than maxrows rows. */
static int parallelogram_mean(const gi_texture *t, const double *pre, const double c[2], const double a[2],
                              const double b[2], int maxrows, float rgba[4])
{
    double hy = 0.5 * (fabs(a[1]) + fabs(b[1]));
    double y0 = c[1] - hy, y1 = c[1] + hy;
    double rows = floor(y1) - floor(y0) + 1.0;
    if (rows > (double)maxrows)
        return 0;
    double area = fabs(a[0] * b[1] - a[1] * b[0]);
    if (!(area > 0.0))
        return 0;
    /* (rows bounds the loop where yr + 1 == yr, at |y| > 2^53; NaN: none) */
    const int nrows = rows >= 1.0 ? (int)rows : 0;
    const int w = t->width, h = t->height;
    pgram g;
    pgram_init(&g, a, b);
    /* the middle vertices' y, the only ones that can fall inside a row (the
     * same sums as the vertices c + (+-a +- b) / 2) */
    const double vm[2] = {c[1] + g.vy[1], c[1] + g.vy[2]};
    /* A footprint inside [0, w] of one period takes row_FG_in for every
     * lookup, with the centre shifted by whole periods of a repeat or mirror
     * wrap: the mean is the same. On Sponza 98% of footprints are (56% in
     * the first period, 43% in another: its walls tile their textures). The
     * shift also keeps the sums small: far from the first period row_FG's
     * m GP + TP (...) terms cost up to 2e-4 in relative error (uv ~ 50 on a
     * 2048-texel row, measured against the same code in long double). */
    double hx = 0.5 * (fabs(a[0]) + fabs(b[0])), cx = c[0];
    int inside;
    if (t->wrap_s == GI_WRAP_CLAMP) {
        inside = cx - hx >= 0.0 && cx + hx <= (double)w;
    } else {
        double P = t->wrap_s == GI_WRAP_MIRROR ? 2.0 * w : (double)w;
        double sh = cx - hx >= 0.0 && cx - hx < P ? 0.0 : P * floor((cx - hx) / P);
        inside = cx - sh + hx <= (double)w; /* (false for a NaN centre) */
        if (inside)
            cx -= sh;
    }
    double acc[3] = {0, 0, 0};
    rowcuts rc[GI_TEXF_CHUNK];
    double yr = floor(y0);
    int done = 0;
    /* the extent at the last row's end, shared with the next row's start */
    double xe_end[2] = {0, 0};
    int end_ok = 0;
    while (done < nrows && yr < y1) {
        /* pass 1: the cuts and their extents (arithmetic only), and every
         * lookup's cache lines asked for. Each row is other cache lines, and
         * they miss: the filter's time was mostly waiting for them one by
         * one. Asked for together the misses overlap. On Sponza's footprints
         * (gi-relight camera moves, replayed one thread): 1.06 us per
         * footprint before, 0.67 with the arithmetic below alone, 0.40 with
         * the prefetches (shuffled, so that no lines are left from the
         * previous footprint: 2.2 us, 1.6, 0.7). */
        int nr = 0;
        for (; nr < GI_TEXF_CHUNK && done < nrows && yr < y1; nr++, done++, yr += 1.0) {
            rowcuts *r = &rc[nr];
            int row = wrap_row(yr, h, t->wrap_t);
            r->pr = pre + (size_t)row * (size_t)(w + 1) * 6;
            r->tx = t->rgba + (size_t)row * (size_t)w * 4;
            double ys = yr > y0 ? yr : y0, ye = yr + 1.0 < y1 ? yr + 1.0 : y1; /* (fmax, fmin: calls) */
            int n = 0;
            r->y[n++] = ys;
            for (int i = 0; i < 2; i++)
                if (vm[i] > ys && vm[i] < ye && !(n > 1 && vm[i] == r->y[n - 1]))
                    r->y[n++] = vm[i];
            r->y[n++] = ye;
            r->nc = n;
            for (int j = 0; j < n; j++) {
                if (j == 0 && end_ok && ys == yr) {
                    r->xe[0][0] = xe_end[0]; /* the previous row's end */
                    r->xe[0][1] = xe_end[1];
                } else {
                    int ok = cut_extent(&g, r->y[j] - c[1], j == 0, r->xe[j]);
                    if (j == n - 1) {
                        end_ok = ok;
                        xe_end[0] = r->xe[j][0];
                        xe_end[1] = r->xe[j][1];
                    }
                }
            }
#if defined(__GNUC__)
            if (inside)
                for (int j = 0; j < n; j++)
                    for (int side = 0; side < 2; side++) {
                        double x = cx + r->xe[j][side];
                        int i = x > 0.0 ? (int)x : 0;
                        i = i > w - 1 ? w - 1 : i;
                        /* F_i, G_i, F_i+1: 72 bytes, on two lines (one
                         * prefetch per lookup: 0.40 us; once per row end
                         * over the lookups' range of x: 0.45) */
                        __builtin_prefetch(r->pr + 6 * (size_t)i);
                        __builtin_prefetch(r->pr + 6 * (size_t)i + 8);
                    }
#endif
        }
        /* pass 2: the lookups, and the integrals over each piece */
        for (int k = 0; k < nr; k++) {
            const rowcuts *r = &rc[k];
            double F[2][2][3], G[2][2][3]; /* at the piece's lower and upper cut, per end */
            for (int j = 0; j < r->nc; j++) {
                int cur = j & 1;
                for (int side = 0; side < 2; side++) {
                    if (inside)
                        row_FG_in(r->pr, w, cx + r->xe[j][side], F[cur][side], G[cur][side]);
                    else
                        row_FG(t, r->pr, r->tx, c[0] + r->xe[j][side], F[cur][side], G[cur][side]);
                }
                if (j == 0)
                    continue;
                int prv = cur ^ 1;
                double hh = r->y[j] - r->y[j - 1];
                if (hh <= 0.0)
                    continue;
                for (int side = 0; side < 2; side++) {
                    /* integral over the piece of F at the end moving linearly
                     * from x0 to x1: (G(x1) - G(x0)) / slope; trapezoid when
                     * it barely moves (the test on the unshifted x) */
                    double x0 = r->xe[j - 1][side], x1 = r->xe[j][side], sg = side ? 1.0 : -1.0;
                    if (fabs(x1 - x0) < 1e-6 * (1.0 + fabs(x0 + c[0]))) {
                        for (int q = 0; q < 3; q++)
                            acc[q] += sg * 0.5 * (F[prv][side][q] + F[cur][side][q]) * hh;
                    } else {
                        double qq = hh / (x1 - x0);
                        for (int q = 0; q < 3; q++)
                            acc[q] += sg * (G[cur][side][q] - G[prv][side][q]) * qq;
                    }
                }
            }
        }
    }
    for (int k = 0; k < 3; k++)
        rgba[k] = (float)(acc[k] / area);
    rgba[3] = 1.0f;
    return 1;
}

void gi_texfilter_box(const gi_texfilter *f, int tex, const float uv[2], const float a[2], const float b[2],
                      float rgba[4])
{
    const pyramid *p = &f->p[tex];
    const gi_texture *t0 = &p->lv[0];
    if (!t0->rgba || t0->width < 1 || t0->height < 1) {
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 1.0f;
        return;
    }
    if (isinf(a[0]) || isinf(a[1]) || isinf(b[0]) || isinf(b[1])) {
        /* an unbounded footprint (a neighbouring ray along the plane): the
         * whole texture's mean, the last level's one texel (the grid below
         * would cast an infinite count to int) */
        const gi_texture *tl = &p->lv[p->levels - 1];
        for (int k = 0; k < 4; k++)
            rgba[k] = tl->rgba[k];
        return;
    }
    /* lengths of the footprint's edges in level-0 texels */
    float la = hypotf(a[0] * (float)t0->width, a[1] * (float)t0->height);
    float lb = hypotf(b[0] * (float)t0->width, b[1] * (float)t0->height);
    if (!(la == la) || !(lb == lb)) /* NaN: no footprint */
        la = lb = 0.0f;
    float lmax = gi_fmaxf(la, lb);
    float area0 = fabsf(a[0] * b[1] - a[1] * b[0]) * (float)t0->width * (float)t0->height;
    if (area0 >= 1.0f) {
        /* a footprint of a texel or more: the exact box average from row
         * sums, at the finest level where it spans at most 8 rows (the
         * texture taken constant over each texel: against the bilinear
         * reconstruction the difference is a blur of a texel). Measured on
         * Sponza (sun frame, 640x480): coarser levels, or bilinear lookups
         * at a level chosen by the footprint, blur enough to cost 0.01-0.03
         * in nrmse. */
        /* beyond a clamped edge the level-0 edge texels continue; a coarser
         * level's edge texel averages them with the texels inside (a thin
         * dark border: 0.87 where the clamp gives 0.75), so a footprint that
         * leaves the texture on a clamped axis is taken at level 0, up to
         * GI_TEXF_CLAMP_ROWS rows (such footprints are rare) */
        float hu = 0.5f * (fabsf(a[0]) + fabsf(b[0])), hv = 0.5f * (fabsf(a[1]) + fabsf(b[1]));
        int out = (t0->wrap_s == GI_WRAP_CLAMP && (uv[0] - hu < 0.0f || uv[0] + hu > 1.0f)) ||
                  (t0->wrap_t == GI_WRAP_CLAMP && (uv[1] - hv < 0.0f || uv[1] + hv > 1.0f));
        if (out) {
            double c2[2] = {(double)uv[0] * t0->width, (double)uv[1] * t0->height};
            double a2[2] = {(double)a[0] * t0->width, (double)a[1] * t0->height};
            double b2[2] = {(double)b[0] * t0->width, (double)b[1] * t0->height};
            if (parallelogram_mean(t0, p->pre[0], c2, a2, b2, GI_TEXF_CLAMP_ROWS, rgba))
                return;
        }
        for (int l = 0; l < p->levels; l++) {
            const gi_texture *tl = &p->lv[l];
            double c2[2] = {(double)uv[0] * tl->width, (double)uv[1] * tl->height};
            double a2[2] = {(double)a[0] * tl->width, (double)a[1] * tl->height};
            double b2[2] = {(double)b[0] * tl->width, (double)b[1] * tl->height};
            if (parallelogram_mean(tl, p->pre[l], c2, a2, b2, 8, rgba))
                return;
        }
    }
    int level = 0;
    if (lmax > (float)GI_TEXF_NMAX) {
        float lv = ceilf(log2f(lmax / (float)GI_TEXF_NMAX));
        level = lv >= (float)(p->levels - 1) ? p->levels - 1 : (int)lv;
    }
    float scale = ldexpf(1.0f, -level); /* level texels per level-0 texel (about) */
    /* under a texel of area: a grid of bilinear lookups a texel apart */
    int na = (int)ceilf(la * scale - 1e-3f), nb = (int)ceilf(lb * scale - 1e-3f);
    na = na < 1 ? 1 : (na > GI_TEXF_NMAX ? GI_TEXF_NMAX : na);
    nb = nb < 1 ? 1 : (nb > GI_TEXF_NMAX ? GI_TEXF_NMAX : nb);
    const gi_texture *t = &p->lv[level];
    double acc[4] = {0, 0, 0, 0};
    for (int j = 0; j < nb; j++) {
        float sb = ((float)j + 0.5f) / (float)nb - 0.5f;
        for (int i = 0; i < na; i++) {
            float sa = ((float)i + 0.5f) / (float)na - 0.5f;
            float q[4];
            gi_texture_sample(t, uv[0] + sa * a[0] + sb * b[0], uv[1] + sa * a[1] + sb * b[1], q);
            for (int k = 0; k < 4; k++)
                acc[k] += q[k];
        }
    }
    double inv = 1.0 / (double)(na * nb);
    for (int k = 0; k < 4; k++)
        rgba[k] = (float)(acc[k] * inv);
}

void gi_texfilter_texel(const gi_texfilter *f, const gi_material *m, uint32_t tri, gi_vec3 eye, gi_vec3 p,
                        gi_vec3 dx, gi_vec3 dy, float rgb[3])
{
    const gi_scene *s = f->s;
    rgb[0] = rgb[1] = rgb[2] = 1.0f;
    if (m->base_color_tex < 0 || (size_t)m->base_color_tex >= s->num_textures || tri >= s->num_triangles)
        return;
    const uint32_t *ix = s->indices + 3 * (size_t)tri;
    gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
    gi_vec3 e1 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), p0);
    gi_vec3 e2 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), p0);
    const float *uvs = m->base_color_uv == 1 ? s->uv1 : s->uv0;
    const float *t0 = uvs + 2 * (size_t)ix[0], *t1 = uvs + 2 * (size_t)ix[1], *t2 = uvs + 2 * (size_t)ix[2];
    double d00 = gi_dot(e1, e1), d01 = gi_dot(e1, e2), d11 = gi_dot(e2, e2);
    double den = d00 * d11 - d01 * d01;
    gi_vec3 n = gi_cross(e1, e2);
    /* barycentric coordinates (b1, b2) of a point offset v from p0, in the plane */
#define BARY(v, b1, b2)                                                                                             \
    do {                                                                                                            \
        double d20_ = gi_dot((v), e1), d21_ = gi_dot((v), e2);                                                      \
        (b1) = (d11 * d20_ - d01 * d21_) / den;                                                                     \
        (b2) = (d00 * d21_ - d01 * d20_) / den;                                                                     \
    } while (0)
    float uv[2], a[2] = {0, 0}, b[2] = {0, 0};
    if (!(den > 0.0)) {
        uv[0] = t0[0]; /* degenerate triangle: its first vertex, no footprint */
        uv[1] = t0[1];
    } else {
        double b1, b2;
        BARY(gi_sub(p, p0), b1, b2);
        for (int c = 0; c < 2; c++)
            uv[c] = (float)(t0[c] + b1 * (t1[c] - t0[c]) + b2 * (t2[c] - t0[c]));
        /* footprint: where the neighbouring rays meet the triangle's plane */
        gi_vec3 dirs[2] = {dx, dy};
        float *out[2] = {a, b};
        float pn = gi_dot(gi_sub(p, eye), n);
        for (int k = 0; k < 2; k++) {
            float dn = gi_dot(dirs[k], n);
            float tq = pn / dn;
            if (!(fabsf(dn) > 1e-12f) || !(tq > 0.0f) || !isfinite(tq))
                continue; /* the neighbour ray misses the plane: no footprint that way */
            gi_vec3 q = gi_add(eye, gi_scale(dirs[k], tq));
            double c1, c2;
            BARY(gi_sub(q, p), c1, c2);
            for (int c = 0; c < 2; c++)
                out[k][c] = (float)(c1 * (t1[c] - t0[c]) + c2 * (t2[c] - t0[c]));
        }
        /* cut at each edge of the triangle's UV island that it crosses:
         * seen at a grazing angle, a sample's footprint on the plane runs far
         * past the face it lies on, where the pixel sees something else. The
         * part inside stays a parallelogram: its extent across the edge runs
         * from the edge to where it ran, its centre moved in between. */
        unsigned be = f->bnd ? (f->bnd[tri] >> (m->base_color_uv == 1 ? 3 : 0)) & 7u : 0u;
        const float *tv[3] = {t0, t1, t2};
        for (int e = 0; e < 3 && be; e++) {
            if (!((be >> e) & 1u))
                continue;
            const float *ti = tv[e], *tj = tv[(e + 1) % 3], *tk = tv[(e + 2) % 3];
            double ex = (double)tj[0] - ti[0], ey = (double)tj[1] - ti[1], len = hypot(ex, ey);
            if (!(len > 0.0))
                continue;
            double nx = -ey / len, ny = ex / len; /* unit normal, turned inwards below */
            if (nx * ((double)tk[0] - ti[0]) + ny * ((double)tk[1] - ti[1]) < 0.0) {
                nx = -nx;
                ny = -ny;
            }
            double dc = nx * ((double)uv[0] - ti[0]) + ny * ((double)uv[1] - ti[1]);
            double an = nx * a[0] + ny * a[1], bn = nx * b[0] + ny * b[1], hh = 0.5 * (fabs(an) + fabs(bn));
            if (!(hh > dc) || !(dc > -hh))
                continue; /* inside, or (numerically) wholly outside: left as it is */
            double sq = (hh + dc) / (2.0 * hh), shift = 0.5 * (hh - dc);
            a[0] = (float)(a[0] - (1.0 - sq) * an * nx);
            a[1] = (float)(a[1] - (1.0 - sq) * an * ny);
            b[0] = (float)(b[0] - (1.0 - sq) * bn * nx);
            b[1] = (float)(b[1] - (1.0 - sq) * bn * ny);
            uv[0] = (float)(uv[0] + shift * nx);
            uv[1] = (float)(uv[1] + shift * ny);
        }
    }
#undef BARY
    const float *x = m->uv_xform;
    float tuv[2] = {x[0] * uv[0] + x[1] * uv[1] + x[2], x[3] * uv[0] + x[4] * uv[1] + x[5]};
    float ta[2] = {x[0] * a[0] + x[1] * a[1], x[3] * a[0] + x[4] * a[1]};
    float tb[2] = {x[0] * b[0] + x[1] * b[1], x[3] * b[0] + x[4] * b[1]};
    float rgba[4];
    gi_texfilter_box(f, m->base_color_tex, tuv, ta, tb, rgba);
    rgb[0] = rgba[0];
    rgb[1] = rgba[1];
    rgb[2] = rgba[2];
}
