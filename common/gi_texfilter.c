/* gi_texfilter.c - footprint-filtered base-colour textures (see gi_texfilter.h). */
#include "gi_texfilter.h"
#include "gi_mem.h"

#include <math.h>
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
    pyramid *p; /* one per texture */
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
    free(f);
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
    *out = f;
    return 0;
}

/* F and G (see pyramid) of row `row` at x, extended beyond [0, w) by the
 * s wrap mode. */
static void row_FG(const gi_texture *t, const double *pre, int row, double x, double F[3], double G[3])
{
    const int w = t->width;
    const double *pr = pre + (size_t)row * (size_t)(w + 1) * 6;
    const float *tx = t->rgba + (size_t)row * (size_t)w * 4;
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
    int i = (int)xi;
    if (i >= w)
        i = w - 1;
    if (i < 0)
        i = 0;
    double fr = xi - (double)i;
    /* the texel's value is F's step over it: the texels themselves are
     * another array, and reading them cost another cache miss per lookup */
    if (!mirror && m == 0.0) {
        /* the common case, in the first period: the row's totals at its end
         * (another cache line) are not needed */
        for (int c = 0; c < 3; c++) {
            double Fl = pr[6 * i + c], v = pr[6 * (i + 1) + c] - Fl;
            F[c] = Fl + fr * v;
            G[c] = pr[6 * i + 3 + c] + Fl * fr + 0.5 * fr * fr * v;
        }
        return;
    }
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

/* Wrap a row index by the texture's t mode. */
static int wrap_row(int y, int h, int mode)
{
    if (mode == GI_WRAP_CLAMP)
        return y < 0 ? 0 : (y >= h ? h - 1 : y);
    if (mode == GI_WRAP_MIRROR) {
        int p = 2 * h, m = y % p;
        if (m < 0)
            m += p;
        return m < h ? m : p - 1 - m;
    }
    int m = y % h;
    return m < 0 ? m + h : m;
}

/* x extent {min, max} of {s a + t b : s a_y + t b_y = ym, |s|, |t| <= 1/2};
 * {+inf, -inf} when the line misses the parallelogram. */
static void x_extent(const double a[2], const double b[2], const double inv[2], double ym, double out[2])
{
    out[0] = INFINITY;
    out[1] = -INFINITY;
    for (int e = 0; e < 4; e++) {
        double fixed = (e & 1) ? 0.5 : -0.5;
        const double *pf = e < 2 ? a : b, *po = e < 2 ? b : a; /* pf's parameter is fixed */
        if (fabs(po[1]) < 1e-12)
            continue;
        double other = (ym - fixed * pf[1]) * inv[e < 2 ? 1 : 0];
        if (other < -0.5 - 1e-9 || other > 0.5 + 1e-9)
            continue;
        double xv = fixed * pf[0] + other * po[0];
        out[0] = fmin(out[0], xv);
        out[1] = fmax(out[1], xv);
    }
}

/* Exact average of a (piecewise constant) level over the parallelogram
 * c + s a + t b, s, t in [-1/2, 1/2], in texel units: row by row, cut at the
 * parallelogram's vertices, so that on each piece both ends of the row's
 * x extent move linearly and edge_integral is exact. Returns 0 when the
 * parallelogram spans more than maxrows rows. */
static int parallelogram_mean(const gi_texture *t, const double *pre, const double c[2], const double a[2],
                              const double b[2], int maxrows, float rgba[4])
{
    double hy = 0.5 * (fabs(a[1]) + fabs(b[1]));
    double y0 = c[1] - hy, y1 = c[1] + hy;
    if (floor(y1) - floor(y0) + 1.0 > (double)maxrows)
        return 0;
    double area = fabs(a[0] * b[1] - a[1] * b[0]);
    if (!(area > 0.0))
        return 0;
    double vy[4] = {c[1] + 0.5 * (a[1] + b[1]), c[1] + 0.5 * (a[1] - b[1]), c[1] - 0.5 * (a[1] - b[1]),
                    c[1] - 0.5 * (a[1] + b[1])};
    for (int i = 1; i < 4; i++) /* sort */
        for (int j = i; j > 0 && vy[j] < vy[j - 1]; j--) {
            double tmp = vy[j];
            vy[j] = vy[j - 1];
            vy[j - 1] = tmp;
        }
    double acc[3] = {0, 0, 0};
    /* 1 / a_y and 1 / b_y for x_extent: a division there per edge and cut was
     * most of the filter's time */
    const double inv[2] = {fabs(a[1]) < 1e-12 ? 0.0 : 1.0 / a[1], fabs(b[1]) < 1e-12 ? 0.0 : 1.0 / b[1]};
    for (double yr = floor(y0); yr < y1; yr += 1.0) {
        int row = wrap_row((int)yr, t->height, t->wrap_t);
        double cuts[6];
        int nc = 0;
        cuts[nc++] = fmax(yr, y0);
        for (int i = 0; i < 4; i++)
            if (vy[i] > cuts[0] && vy[i] < fmin(yr + 1.0, y1))
                cuts[nc++] = vy[i];
        cuts[nc++] = fmin(yr + 1.0, y1);
        /* the extent's ends at every cut (continuous in y: the parallelogram
         * is convex), with F and G there, shared by the pieces on both sides */
        double xe[6][2], F[6][2][3], G[6][2][3];
        for (int j = 0; j < nc; j++) {
            double yy = cuts[j] - c[1];
            x_extent(a, b, inv, yy, xe[j]);
            if (!(xe[j][1] >= xe[j][0])) {
                /* at the parallelogram's top or bottom vertex rounding may
                 * miss it: nudge inside */
                x_extent(a, b, inv, yy + (j == 0 ? 1e-9 : -1e-9) * (1.0 + fabs(hy)), xe[j]);
                if (!(xe[j][1] >= xe[j][0]))
                    xe[j][0] = xe[j][1] = 0.5 * (xe[j][0] + xe[j][1]);
                if (!isfinite(xe[j][0]))
                    xe[j][0] = xe[j][1] = 0.0;
            }
            for (int side = 0; side < 2; side++)
                row_FG(t, pre, row, c[0] + xe[j][side], F[j][side], G[j][side]);
        }
        for (int j = 0; j + 1 < nc; j++) {
            double h = cuts[j + 1] - cuts[j];
            if (h <= 0.0)
                continue;
            for (int side = 0; side < 2; side++) {
                /* integral over the piece of F at the end moving linearly from
                 * x0 to x1: (G(x1) - G(x0)) / slope; trapezoid when it barely moves */
                double x0 = xe[j][side], x1 = xe[j + 1][side], sg = side ? 1.0 : -1.0;
                if (fabs(x1 - x0) < 1e-6 * (1.0 + fabs(x0 + c[0]))) {
                    for (int k = 0; k < 3; k++)
                        acc[k] += sg * 0.5 * (F[j][side][k] + F[j + 1][side][k]) * h;
                } else {
                    double q = h / (x1 - x0);
                    for (int k = 0; k < 3; k++)
                        acc[k] += sg * (G[j + 1][side][k] - G[j][side][k]) * q;
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
    /* lengths of the footprint's edges in level-0 texels */
    float la = hypotf(a[0] * (float)t0->width, a[1] * (float)t0->height);
    float lb = hypotf(b[0] * (float)t0->width, b[1] * (float)t0->height);
    if (!(la == la) || !(lb == lb)) /* NaN: no footprint */
        la = lb = 0.0f;
    float lmax = fmaxf(la, lb);
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
