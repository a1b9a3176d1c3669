/* gi_shade.c - screen-space shading of relight frames.
 *
 * When the camera (or size) changes, the G-buffer is rasterised and every
 * pixel sample gets a cached surface record and its irradiance-cache
 * interpolation weights (up to GI_SHADE_K gathering points). A frame whose
 * camera did not move only re-evaluates direct light and sums the cached
 * weights: the "splat" of a light or material change costs a few reads. */
#define _POSIX_C_SOURCE 200809L
#include "gi_shade.h"
#include "gi_mem.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_emit.h"
#include "gi_light.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_pt.h"
#include "gi_rng.h"
#include "gi_texfilter.h"

#define GI_SHADE_AA_MAX 7 /* largest --aa */
_Static_assert(GI_SHADE_AA_MAX * GI_SHADE_AA_MAX <= 64, "an edge pixel's samples are bits of a uint64_t");
/* The near field's default reach, in R+. 1.25 while a point gave up the
 * exact near field; since it gives up what its gather read (nf_prepare),
 * a shorter reach does better on Sponza: sun-b (4096 spp, three gi-hvds
 * seeds) 0.1006 / 0.1011 / 0.0996 -> 0.0946 / 0.0956 / 0.0950 at 0.65,
 * sun-moved 0.0862 / 0.0869 / 0.0864 -> 0.0866 / 0.0875 / 0.0869,
 * arcade-moved, sun-c and arcades-b within 0.0004 (seed 1 at 0.87 / 1.09 /
 * 1.96: sun-b 0.0953 / 0.0996 / 0.1060) */
#define GI_SHADE_NF_AUTO 0.65f
#define GI_SHADE_NF_LC 4      /* lights whose near-field terms are kept */
#define GI_SHADE_COV_MAX 31 /* largest coverage grid */
#define GI_SHADE_K 8 /* gathering points kept per pixel sample (largest weights) */
/* A gathering point off the sample's tangent plane by d (measured along the
 * mean of their normals, so that two points of one cylinder or sphere, whose
 * chord is square to that mean, are 0 apart) has error d / (PLANE x its
 * radius): a point on a parallel face a step below or above is out of reach
 * at 2 x PLANE x its radius. The irradiance-cache error alone (distance over
 * radius, normal angle) let a sample on the top of a column's plinth take
 * 74% of its weight from two points 5 cm below it, on the rail the plinth
 * overhangs, which read 0 and 0.03 lux (Sponza f3, pixel (230, 60), where the
 * path tracer finds 139 lux of indirect light). Sponza, 320 x 240, against
 * the references of docs/journal.md "Session 38": f1-f4 0.0847 0.0940 0.1111 0.0665
 * -> 0.0836 0.0913 0.1096 0.0675, u1-u5 0.0416 0.0579 0.1533 0.0443 0.0324
 * -> 0.0405 0.0579 0.1484 0.0442 0.0311; PLANE 0.15 did a little worse on
 * f1, f2 and f4 (0.0837 0.0920 0.0677), and a one-sided test (only points
 * behind the sample's plane) gained on f3 alone (0.1102). t140 is the
 * plinth; t130's crease lost by it (0.0256 -> 0.0322) */
#define GI_SHADE_PLANE 0.2f
#ifndef GI_SHADE_GLOSSY_WIN /* (a build with 0 averages nothing: converged gathers for comparisons) */
#define GI_SHADE_GLOSSY_WIN 3 /* glossy gathers averaged over (2 x this + 1)^2 pixels (one sample per pixel) */
#endif
#define GI_SHADE_STEP 4.0f /* a depth step of this many pixel footprints is an edge */
/* an edge pixel takes its edge samples for a light when the light's
 * irradiance over its 3x3 neighbourhood spans more than this fraction of
 * the light's mean over the image */
/* An edge pixel whose samples' irradiance from a light spans more than
 * this multiple of the light's mean gets GI_SHADE_XK^2 more samples for that
 * light (direct light only; their surfaces are found once per view). An
 * edge's error grows with its contrast, so the few pixels of the highest
 * contrast hold most of it: Sponza sun-b, direct light against 1024 spp,
 * 0.1168 without, 0.1084 at 1x, 0.1085 at 3x, 0.1091 at 8x; light moves
 * (sun-turn medians, interleaved) +10 ms at 1x, +3-4 ms at 8x. On by
 * default since 2026-12-02 (sun-b 0.1263 -> 0.1232, sun-moved 0.0988 ->
 * 0.0984; the Cornell box unchanged). */
#define GI_SHADE_EDGE_REFINE 8.0 /* gi_shade_opts.refine_contrast's default */
/* A pixel that is no edge, lit by a point or directional light, whose centre's
 * irradiance differs from its 4 neighbours' mean by more than this multiple of
 * the light's mean irradiance over the view is refined like a shadow edge
 * (light_pass). Sponza u3 (320 x 240, 2048 spp): 0.1630 -> 0.1589 nrmse at
 * 0.25-1, no further at 0.1; the other frames within 0.0004 (f4 0.0735 ->
 * 0.0731 at 0.5). */
#define GI_SHADE_CURVATURE 0.5
#define GI_SHADE_XK 4
#define GI_SHADE_XN (GI_SHADE_XK * GI_SHADE_XK)
/* vis: a pixel the shadow-edge rounds of the full pass refined */
#define VIS_SPREAD 4u
/* at most this many rounds of following slivers */
#ifndef GI_SHADE_SPREAD_ROUNDS
#define GI_SHADE_SPREAD_ROUNDS 4096
#endif
#ifndef GI_SHADE_EDGE_CONTRAST
#define GI_SHADE_EDGE_CONTRAST 0.02
#endif
#define GI_SHADE_SAA_MAX 0.18f /* largest added lobe variance (specular_aa) */
/* lights whose direct light is kept per pixel: as many as gi-relight lights
 * at once (GI_RELIGHT_MAX_LIGHTS), allocated as lights need them (17 bytes a
 * pixel each). With 8, a frame of 16 point lights recomputed the direct light
 * of 8 of them on every move of one (Sponza 640x480: ~700 ms a move) */
#define GI_SHADE_DCACHE 32
#define GI_SHADE_WARM_BYTES ((size_t)64 << 20) /* of them allocated up front (dcache_warm) */

typedef struct ssurf {
    float p[3], ng[3], ns[3], wo[3];
    float texel[3];     /* texture value at the point (1 when untextured): base = factor * texel */
    uint32_t material;
    float tsurf;        /* distance from the eye (INFINITY: background) */
    uint32_t tri;       /* the triangle seen (0-based; meaningful while valid) */
    uint8_t valid;      /* 1: a visible, shaded surface */
    uint8_t npairs;
    uint32_t gp[GI_SHADE_K];
    float w[GI_SHADE_K]; /* normalised weights */
    float nvar;          /* variance of the shading normal over the sample's footprint
                            (sum over both axes; 0: unknown), for specular anti-aliasing */
} ssurf;

/* What the splat reads of a sample, packed into one cache line: the ssurf
 * is 136 bytes and a light move reads every sample's weights, so the splat
 * was bound by memory. Weights are normalised, stored * 16384 (a linear fit's
 * weights can be negative, and reach 1.5 at most; linear_fit). A sample on a
 * glossy material is splatted from its ssurf (it needs ns and wo). */
typedef struct srec {
    uint32_t gp[GI_SHADE_K];
    int16_t w[GI_SHADE_K];
    float texel[3];
    uint32_t material; /* UINT32_MAX: no surface */
} srec;

/* Glossy lobe tables over (cos theta_o, Phong exponent): A, the lobe's
 * directional albedo int (n+2)/(2 pi) cos^n a cos theta_i dw over the upper
 * hemisphere, and B, the same integral of w . t with t the unit tangential
 * direction of the mirror direction, for radiance linear in direction. */
#define LOBE_NC 33 /* cos theta_o = i / 32 */
#define LOBE_NN 29 /* log2(n + 1) = j / 2 */

struct gi_shade {
    const gi_scene *s;
    const gi_rt *rt;
    const gi_hvds *h;
    gi_texfilter *tf;   /* mip pyramids for footprint-filtered textures */
    float reach;        /* weights reach this many effective radii */
    float lobe_a[LOBE_NN][LOBE_NC], lobe_b[LOBE_NN][LOBE_NC];
    /* influence grid: each gathering point is listed in every cell its
     * influence sphere (reach * radius) touches */
    float gmin[3], cell;
    int gdim[3];
    uint32_t *istart, *iidx;
    /* plain grid (point in its own cell) for the no-weight fallback */
    uint32_t *pstart, *pidx;
    /* per-sample cache, valid for pcam / pw x ph / pss */
    gi_gpixel *px;
    ssurf *sf;
    int pw, ph, pss, ptexf, paa, pcov;
    int lin, plin;        /* the view being prepared fits a plane (linear_fit); the cached view's did */
    /* edge antialiasing (ss == 1): pixel -> edge number (UINT32_MAX: none),
     * edge number -> pixel, and ne samples per edge pixel */
    uint32_t *eidx, *epix;
    ssurf *esf;
    /* splat records of sf (rec) and of esf (erec); esrc: per edge sample,
     * the sf index whose weights and texel it reused (UINT32_MAX: its own) */
    srec *rec, *erec;
    uint32_t *esrc;
    /* per esf sample of its own (esrc UINT32_MAX), whose near field it
     * takes: an sf index, ENF_GATHER or ENF_NONE (enf_view: the view it was
     * found for; nf_sources) */
    uint32_t *enfsrc;
    size_t cap_enfsrc;
    uint64_t enf_view;
    uint8_t *svalid;    /* per sf sample: its valid flag, for scans that need no more of it */
    /* per sf and per esf sample: its material (UINT32_MAX: not valid), for
     * the scans of every frame that need no more of it (a 144-byte ssurf
     * each read cost Sponza's light moves ~1 cache miss per sample) */
    uint32_t *smat, *esmat;
    ssurf **xsf;        /* per edge pixel: GI_SHADE_XN refinement samples, made when first needed (or NULL) */
    size_t nxsf;        /* entries of xsf */
    uint8_t *ehard;     /* per edge pixel: its samples see more than one material, texel or the background */
    float *ew;          /* per edge pixel, ne + 1 (the centre last): each sample's share of the pixel, from
                           pcov x pcov coverage rays (NULL: equal shares) */
    float *cind;        /* 3 per sf sample: its indirect light, scratch of the splat */
    /* glossy gathers of sf samples (opts glossy_rays), in slots (gslot): per
     * slot gr rays, each the key it reads and its cosine at the surface; gexp:
     * the Phong exponent they were drawn for (0: none yet); gpix: the sample
     * they were drawn at */
    uint32_t *gkey, *gpix;
    float *gcos, *gexp;
    uint16_t *gnr;      /* per slot: the rays drawn (glossy_nrays; the rest of its gr read no key) */
    float gsharp;       /* lobes of this exponent and up draw fewer rays (glossy_nrays; INFINITY: none) */
    size_t gdrawn, grays; /* gathers drawn and their rays, for -v (atomic adds) */
    /* per ray: the log of its cosine to the mirror direction, and its weight for the
     * exponent gtgt (per sample, 0: none yet): the rays drawn for gexp serve
     * nearby exponents by importance (glossy_reweight) */
    float *gca, *gw, *gtgt;
    float *gterm;       /* 3 per sf sample: its gathered glossy term, scratch of the splat */
    /* near field (see nf_prepare): the hits of each sf sample's short rays
     * (nf_xo[i] .. nf_xo[i + 1] in nf_xh) for view nf_view, those of each
     * gathering point (nf_po[i], nf_pn[i] of them in nf_ph; traced when a
     * view first reads the point, nf_pdone), all within nf_r0 */
    float nf_r0;
    uint64_t nf_view;
    struct nfhit *nf_xh, *nf_ph;
    uint32_t *nf_pk; /* each point hit's key (key_at), parallel to nf_ph; with key_flux0 */
    size_t nf_pkn;   /* hits [0, nf_pkn) have their key in nf_pk */
    uint32_t *nf_xo, *nf_po;
    uint8_t *nf_pn, *nf_pdone;
    size_t nf_nph, nf_cph;
    float *nf_ex;       /* 3 per sf sample: its near-field irradiance this frame */
    uint8_t *nf_do;     /* per sf sample: 1 when it traces (nf_stride) */
    int nf_stride;      /* the view's near_stride (0: adaptive; nf_prepare) */
    int nf_win;         /* its window's half-width */
    uint32_t *nf_hl, *nf_wl, *nf_co, *nf_cl; /* see nf_windows */
    uint8_t *nf_cc;
    size_t nf_nhl, nf_nwl;
    /* per light (at strength 1, white): each hit's term (nf_light), for the
     * samples' hits of view view and the first pdone of the points' */
    struct nflc {
        gi_light light;
        uint64_t view, last_use;
        size_t pdone, capx, capp;
        float *gx, *gp;
    } nflc[GI_SHADE_NF_LC];
    uint64_t nf_frame;
    float *nf_tmp;      /* scratch of the same size */
    size_t nf_cap;      /* the length nf_xo, nf_ex, nf_tmp and nf_do have room for */
    size_t nf_xh_cap;   /* nf_xh's room, in hits */
    float *nf_gpe;      /* 3 per gathering point: its irradiance less its near field */
    uint8_t *gdo;       /* per sf sample: 1 when gterm holds its term this frame */
    int gr;
    size_t cap_gkey, cap_gcos, cap_gexp; /* cap_gexp: slots; cap_gkey: samples (gterm, gdo) */
    /* capacities (elements) of the per-view arrays: a camera move reuses
     * them, since fresh pages cost a fault each (~30% of a camera move) */
    size_t cap_px, cap_sf, cap_eidx, cap_epix, cap_esf, cap_esrc, cap_ehard, cap_rec, cap_erec, cap_cind, cap_svalid, cap_ew;
    size_t cap_smat, cap_esmat;
    size_t nedge;
    int ne;
    /* the gathering points the view's records read, sorted (opts.gather) */
    uint32_t *vgp;
    size_t nvgp, cap_vgp;
    uint64_t *vbits;    /* scratch: one bit per gathering point */
    /* direct light per light, per pixel, for the current view (view_id):
     * a frame reuses it for every light unchanged since, and recomputes only
     * the pixels that see a changed material */
    uint64_t view_id;
    struct dcache {
        gi_light light;
        size_t index;       /* the light's index in the frame (its random stream) */
        uint64_t view_id;   /* 0: empty */
        uint64_t last_use;
        size_t np;          /* pixels the buffers hold */
        float *rgb;         /* 3 per pixel */
        uint8_t *vis;       /* per pixel (ss == 1 and not an area light): 0, 1 lit, 2 shadowed */
        float *ec;          /* per pixel (ss == 1): luminance of the light's irradiance at the centre sample */
    } dc[GI_SHADE_DCACHE];
    uint64_t frame_no;
    gi_material *pmats;     /* the materials the caches were computed with */
    size_t npmats;
    gi_camera pcam;
    gi_camera_frame cf; /* the basis of the view being prepared or shaded (gi_camera_frame_ray) */
    int valid;
    float jit[2 * 64];  /* sub-pixel position of each sample pass (ss <= 8) */
};

void gi_shade_opts_default(gi_shade_opts *o)
{
    memset(o, 0, sizeof *o);
    o->area_samples = 16;
    o->ss = 1;
    o->tex_filter = 1;
    o->aa = 0; /* automatic */
    o->direct = 1;
    o->indirect = 1;
    o->seed = 1;
    o->glossy_rays = 36;
    o->glossy_min_ks = GI_SHADE_GATHER_KS;
    o->glossy_stride = 2;
    o->near_field = -1.0f; /* automatic */
    o->near_stride = 0;    /* automatic */
    o->interp_linear = 1;
    o->edge_refine = 1;
    o->refine_contrast = GI_SHADE_EDGE_REFINE;
}

int gi_shade_gathers(const gi_material *m, const gi_shade_opts *o)
{
    if (o->glossy_rays <= 0)
        return 0;
    gi_bsdf b;
    gi_bsdf_init(&b, m, gi_v3p(m->base_color));
    return b.exponent > 0.0f && gi_maxc(b.ks) >= o->glossy_min_ks;
}

static inline int clampi(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }

static inline size_t cell_index(const gi_shade *sh, int x, int y, int z)
{
    return ((size_t)z * (size_t)sh->gdim[1] + (size_t)y) * (size_t)sh->gdim[0] + (size_t)x;
}

/* Stratified lobe sampling (24 x 24 per entry): cos a = u^(1 / (n + 1)) about
 * the mirror direction; weight f cos / pdf = (n + 2) / (n + 1) max(cos_i, 0). */
static void lobe_tables(gi_shade *sh)
{
    const int K = 24;
    for (int j = 0; j < LOBE_NN; j++) {
        double n = exp2(0.5 * j) - 1.0;
        for (int i = 0; i < LOBE_NC; i++) {
            double co = (double)i / (LOBE_NC - 1), so = sqrt(fmax(0.0, 1.0 - co * co));
            /* wo = (so, 0, co), mirror r = (-so, 0, co); tangent t = (-1, 0, 0) */
            double rx = -so, rz = co;
            /* about r: e1 = (rz, 0, -rx) (unit, orthogonal to r in the x-z plane) and y */
            double e1x = rz, e1z = -rx;
            double sa = 0.0, sb = 0.0;
            for (int p = 0; p < K; p++)
                for (int q = 0; q < K; q++) {
                    double u1 = (p + 0.5) / K, u2 = (q + 0.5) / K;
                    double ca = pow(u1, 1.0 / (n + 1.0)), sn = sqrt(fmax(0.0, 1.0 - ca * ca));
                    double phi = 2.0 * GI_PI * u2;
                    double wx = ca * rx + sn * cos(phi) * e1x, wz = ca * rz + sn * cos(phi) * e1z;
                    if (wz <= 0.0)
                        continue;
                    double wt = (n + 2.0) / (n + 1.0) * wz;
                    sa += wt;
                    sb += wt * -wx;
                }
            sh->lobe_a[j][i] = (float)(sa / (K * K));
            sh->lobe_b[j][i] = (float)(sb / (K * K));
        }
    }
}

static void lobe_lookup(const gi_shade *sh, float n, float co, float *a, float *b)
{
    float fj = gi_clampf(2.0f * log2f(n + 1.0f), 0.0f, (float)(LOBE_NN - 1));
    float fi = gi_clampf(co, 0.0f, 1.0f) * (float)(LOBE_NC - 1);
    int j0 = (int)fj, i0 = (int)fi;
    int j1 = j0 + 1 < LOBE_NN ? j0 + 1 : j0, i1 = i0 + 1 < LOBE_NC ? i0 + 1 : i0;
    float tj = fj - (float)j0, ti = fi - (float)i0;
    *a = (1 - tj) * ((1 - ti) * sh->lobe_a[j0][i0] + ti * sh->lobe_a[j0][i1]) +
         tj * ((1 - ti) * sh->lobe_a[j1][i0] + ti * sh->lobe_a[j1][i1]);
    *b = (1 - tj) * ((1 - ti) * sh->lobe_b[j0][i0] + ti * sh->lobe_b[j0][i1]) +
         tj * ((1 - ti) * sh->lobe_b[j1][i0] + ti * sh->lobe_b[j1][i1]);
}

int gi_shade_new(const gi_scene *s, const gi_rt *rt, const gi_hvds *h, gi_shade **out, gi_status *st)
{
    *out = NULL;
    gi_shade *sh = calloc(1, sizeof *sh);
    if (sh)
        sh->gsharp = INFINITY;
    if (!sh)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    sh->s = s;
    sh->rt = rt;
    sh->h = h;
    sh->reach = 2.0f;
    lobe_tables(sh);
    int rc = gi_texfilter_new(s, &sh->tf, st);
    if (rc) {
        free(sh);
        return rc;
    }
    uint32_t n = h->num_gpoints;
    /* cell: a few times the median influence radius, bounded to keep the grid small */
    float ext = 0.0f;
    for (int a = 0; a < 3; a++)
        ext = gi_fmaxf(ext, s->bbox_max[a] - s->bbox_min[a]);
    double rsum = 0.0;
    for (uint32_t i = 0; i < n; i++)
        rsum += h->gpoints[i].radius;
    float rmean = n ? (float)(rsum / n) : ext;
    sh->cell = gi_fmaxf(0.5f * sh->reach * rmean, ext * 1e-3f + 1e-6f);
    size_t cells;
    for (;;) {
        cells = 1;
        for (int a = 0; a < 3; a++) {
            sh->gmin[a] = s->bbox_min[a] - sh->cell;
            float span = s->bbox_max[a] - s->bbox_min[a] + 2.0f * sh->cell;
            sh->gdim[a] = (int)ceilf(span / sh->cell);
            if (sh->gdim[a] < 1)
                sh->gdim[a] = 1;
            cells *= (size_t)sh->gdim[a];
        }
        if (cells <= 4u * 1024u * 1024u)
            break;
        sh->cell *= 1.5f;
    }
    /* count entries of the influence grid */
    uint64_t total = 0;
    for (uint32_t i = 0; i < n; i++) {
        const gi_gpoint *g = &h->gpoints[i];
        float r = sh->reach * g->radius;
        uint64_t c = 1;
        for (int a = 0; a < 3; a++) {
            int lo = clampi((int)floorf((g->pos[a] - r - sh->gmin[a]) / sh->cell), 0, sh->gdim[a] - 1);
            int hi = clampi((int)floorf((g->pos[a] + r - sh->gmin[a]) / sh->cell), 0, sh->gdim[a] - 1);
            c *= (uint64_t)(hi - lo + 1);
        }
        total += c;
    }
    if (total > UINT32_MAX / 2) {
        gi_shade_free(sh);
        return gi_status_set(st, GI_EXIT_SYSTEM, "gathering-point grid too large (%llu entries)",
                             (unsigned long long)total);
    }
    sh->istart = gi_calloc_large(cells + 2, sizeof *sh->istart);
    sh->iidx = gi_alloc_large((total + 1) * sizeof *sh->iidx);
    sh->pstart = gi_calloc_large(cells + 2, sizeof *sh->pstart);
    sh->pidx = malloc(((size_t)n + 1) * sizeof *sh->pidx);
    if (!sh->istart || !sh->iidx || !sh->pstart || !sh->pidx) {
        gi_shade_free(sh);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the gathering-point grid");
    }
    for (int pass = 0; pass < 2; pass++) {
        for (uint32_t i = 0; i < n; i++) {
            const gi_gpoint *g = &h->gpoints[i];
            float r = sh->reach * g->radius;
            int lo[3], hi[3], c[3];
            for (int a = 0; a < 3; a++) {
                lo[a] = clampi((int)floorf((g->pos[a] - r - sh->gmin[a]) / sh->cell), 0, sh->gdim[a] - 1);
                hi[a] = clampi((int)floorf((g->pos[a] + r - sh->gmin[a]) / sh->cell), 0, sh->gdim[a] - 1);
                c[a] = clampi((int)floorf((g->pos[a] - sh->gmin[a]) / sh->cell), 0, sh->gdim[a] - 1);
            }
            size_t pc = cell_index(sh, c[0], c[1], c[2]);
            if (pass == 0)
                sh->pstart[pc + 1]++;
            else
                sh->pidx[sh->pstart[pc]++] = i;
            for (int z = lo[2]; z <= hi[2]; z++)
                for (int y = lo[1]; y <= hi[1]; y++)
                    for (int x = lo[0]; x <= hi[0]; x++) {
                        size_t ci = cell_index(sh, x, y, z);
                        if (pass == 0)
                            sh->istart[ci + 1]++;
                        else
                            sh->iidx[sh->istart[ci]++] = i;
                    }
        }
        if (pass == 0) {
            for (size_t ci = 0; ci < cells; ci++) {
                sh->istart[ci + 1] += sh->istart[ci];
                sh->pstart[ci + 1] += sh->pstart[ci];
            }
        } else {
            /* the fill advanced every start to the next cell's; shift back */
            for (size_t ci = cells; ci > 0; ci--) {
                sh->istart[ci] = sh->istart[ci - 1];
                sh->pstart[ci] = sh->pstart[ci - 1];
            }
            sh->istart[0] = 0;
            sh->pstart[0] = 0;
        }
    }
    size_t nonempty = 0;
    for (size_t ci = 0; ci < cells; ci++)
        nonempty += sh->istart[ci + 1] > sh->istart[ci];
    gi_verbose("interpolation grid: %d x %d x %d cells of %.3g m, %llu entries, %.1f points per occupied cell",
               sh->gdim[0], sh->gdim[1], sh->gdim[2], sh->cell, (unsigned long long)total,
               nonempty ? (double)total / (double)nonempty : 0.0);
    *out = sh;
    return 0;
}

static void free_xsf(gi_shade *sh)
{
    for (size_t e = 0; sh->xsf && e < sh->nxsf; e++)
        free(sh->xsf[e]);
    free(sh->xsf);
    sh->xsf = NULL;
    sh->nxsf = 0;
}

void gi_shade_free(gi_shade *sh)
{
    if (!sh)
        return;
    free(sh->istart);
    free(sh->iidx);
    free(sh->pstart);
    free(sh->pidx);
    free(sh->px);
    free(sh->sf);
    free(sh->esf);
    free(sh->epix);
    free(sh->eidx);
    free(sh->rec);
    free(sh->erec);
    free(sh->esrc);
    free(sh->enfsrc);
    free(sh->ehard);
    free(sh->ew);
    free(sh->svalid);
    free(sh->smat);
    free(sh->esmat);
    free(sh->gkey);
    free(sh->gpix);
    free(sh->nf_xh);
    free(sh->nf_ph);
    free(sh->nf_pk);
    free(sh->nf_xo);
    free(sh->nf_po);
    free(sh->nf_pn);
    free(sh->nf_pdone);
    free(sh->nf_ex);
    free(sh->nf_do);
    free(sh->nf_hl);
    free(sh->nf_wl);
    free(sh->nf_co);
    free(sh->nf_cc);
    free(sh->nf_cl);
    free(sh->nf_tmp);
    free(sh->nf_gpe);
    for (int i = 0; i < GI_SHADE_NF_LC; i++) {
        free(sh->nflc[i].gx);
        free(sh->nflc[i].gp);
    }
    free(sh->gcos);
    free(sh->gexp);
    free(sh->gnr);
    free(sh->gca);
    free(sh->gw);
    free(sh->gtgt);
    free(sh->gterm);
    free(sh->gdo);
    free(sh->cind);
    free(sh->vgp);
    free(sh->vbits);
    free_xsf(sh);
    for (int i = 0; i < GI_SHADE_DCACHE; i++) {
        free(sh->dc[i].rgb);
        free(sh->dc[i].vis);
        free(sh->dc[i].ec);
    }
    free(sh->pmats);
    gi_texfilter_free(sh->tf);
    free(sh);
}

/* Irradiance-cache weights at (p, n): w_i = 1 - E_i / reach with the
 * Tabellion error E_i = max(|x - x_i| / R_i, sqrt(1 - n.n_i) / sqrt(1 - cos 10deg)).
 * Keeps the K largest, normalised. No point with weight: the points on the
 * same side within 3 cells, with a wider reach (below). Returns the number
 * kept. */
/* Turn the normalised weights w of k gathering points into half their own
 * and half the weights of a weighted linear fit: the value at p of the plane
 * a + b.(x - p), in the tangent plane of n, fitted to the points' values
 * with weights w by least squares. A weighted mean flattens the indirect
 * light wherever it slopes (a column's foot beside a sunlit floor, a
 * soffit's curve): the fit follows the slope, and both sum to one. The
 * gradient b is damped by a ridge of GI_SHADE_FIT_RIDGE times the weighted
 * mean of the points' squared radii, doubled until the weights' absolute
 * sum is at most GI_SHADE_FIT_L1: noise grows with that sum, and a fit
 * without the bound extrapolated a few points' noise into spikes (Sponza
 * sun-moved 0.1034 -> 0.4179 with a ridge of 0.01). Measured against
 * 1024-spp references on Sponza (sun-moved / arcade-moved) and 2048-spp
 * ones on the Cornell box's more-variants (256 x 256, spot-down-wide, the
 * frame that changed most): the mean 0.0997 / 0.0971 and 0.0480; the fit
 * alone 0.0986 / 0.0964 and 0.0495 (it gives more weight to the nearest
 * points, and the box's points along its creases are too bright already);
 * the fit at 0.3 with the mean at 0.7 0.0991 / 0.0966 and 0.0484; half
 * each 0.0989 / 0.0964 and 0.0487. Ridges of 0.1 and 1 and bounds of 1.0
 * and 1.25 did no better on either. Weights may come out negative; the
 * splat clamps the irradiance at zero. */
#define GI_SHADE_FIT_RIDGE 0.3
#define GI_SHADE_FIT_L1 1.5
#define GI_SHADE_FIT_BLEND 0.5 /* the fit's share of the weights */
static void linear_fit(const gi_shade *sh, const float p[3], const float n[3], const uint32_t *idx, float *w, int k)
{
    gi_vec3 t, b;
    gi_basis(gi_v3p(n), &t, &b);
    double M[3][3] = {{0}}, u[GI_SHADE_K], v[GI_SHADE_K], r2 = 0.0;
    for (int q = 0; q < k; q++) {
        const gi_gpoint *g = &sh->h->gpoints[idx[q]];
        gi_vec3 d = gi_v3(g->pos[0] - p[0], g->pos[1] - p[1], g->pos[2] - p[2]);
        u[q] = gi_dot(d, t);
        v[q] = gi_dot(d, b);
        const double a[3] = {1.0, u[q], v[q]};
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                M[i][j] += w[q] * a[i] * a[j];
        r2 += w[q] * (double)g->radius * g->radius;
    }
    double lam = GI_SHADE_FIT_RIDGE * r2;
    for (int it = 0; it < 12 && lam > 0.0; it++, lam *= 2.0) {
        /* the first row of (M + diag(0, lam, lam))^-1, by cofactors */
        double A11 = M[1][1] + lam, A22 = M[2][2] + lam;
        double c0 = A11 * A22 - M[1][2] * M[2][1], c1 = M[1][2] * M[2][0] - M[1][0] * A22,
               c2 = M[1][0] * M[2][1] - A11 * M[2][0];
        double det = M[0][0] * c0 + M[0][1] * c1 + M[0][2] * c2;
        if (!(fabs(det) > 1e-300))
            continue;
        double cw[GI_SHADE_K], l1 = 0.0;
        for (int q = 0; q < k; q++) {
            cw[q] = w[q] * (c0 + c1 * u[q] + c2 * v[q]) / det;
            l1 += fabs(cw[q]);
        }
        if (l1 <= GI_SHADE_FIT_L1) {
            for (int q = 0; q < k; q++)
                w[q] = (float)(GI_SHADE_FIT_BLEND * cw[q] + (1.0 - GI_SHADE_FIT_BLEND) * w[q]);
            return;
        }
    }
    /* no ridge met the bound: the weighted mean stays */
}

/* The tangent-plane term of a point's error (GI_SHADE_PLANE); d = p - g->pos,
 * n . g->nrm > 0. */
static inline float plane_err(const float n[3], const gi_gpoint *g, const float d[3])
{
    float m[3] = {n[0] + g->nrm[0], n[1] + g->nrm[1], n[2] + g->nrm[2]};
    float dm = d[0] * m[0] + d[1] * m[1] + d[2] * m[2];
    return fabsf(dm) / (sqrtf(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) * GI_SHADE_PLANE * g->radius);
}

static int interp_weights(const gi_shade *sh, const float p[3], const float n[3], int lin, uint32_t *idx,
                          float *wout)
{
    const gi_hvds *h = sh->h;
    const float inv_na = 1.0f / sqrtf(1.0f - cosf((float)(10.0 * GI_PI / 180.0)));
    int c[3];
    for (int a = 0; a < 3; a++)
        c[a] = (int)floorf((p[a] - sh->gmin[a]) / sh->cell);
    int k = 0;
    double wsum = 0.0;
    if (c[0] >= 0 && c[1] >= 0 && c[2] >= 0 && c[0] < sh->gdim[0] && c[1] < sh->gdim[1] && c[2] < sh->gdim[2]) {
        size_t ci = cell_index(sh, c[0], c[1], c[2]);
        for (uint32_t j = sh->istart[ci]; j < sh->istart[ci + 1]; j++) {
            uint32_t i = sh->iidx[j];
            const gi_gpoint *g = &h->gpoints[i];
            float dn = n[0] * g->nrm[0] + n[1] * g->nrm[1] + n[2] * g->nrm[2];
            if (dn <= 0.0f)
                continue;
            float en = sqrtf(gi_fmaxf(0.0f, 1.0f - dn)) * inv_na;
            if (en >= sh->reach)
                continue;
            float d[3] = {p[0] - g->pos[0], p[1] - g->pos[1], p[2] - g->pos[2]};
            float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            float rr = sh->reach * g->radius;
            if (d2 >= rr * rr)
                continue;
            float err = gi_fmaxf(gi_fmaxf(sqrtf(d2) / g->radius, en), plane_err(n, g, d));
            float w = 1.0f - err / sh->reach;
            if (w <= 0.0f)
                continue;
            if (k < GI_SHADE_K) {
                idx[k] = i;
                wout[k] = w;
                k++;
            } else {
                int m = 0;
                for (int q = 1; q < GI_SHADE_K; q++)
                    if (wout[q] < wout[m])
                        m = q;
                if (w > wout[m]) {
                    idx[m] = i;
                    wout[m] = w;
                }
            }
        }
    }
    if (k == 0) {
        /* no point within reach: the K points on the same side within 3
         * cells of least error E_i, weighted as above with the reach
         * widened to 1.5 times the least error. The single nearest point,
         * as before, left blocks and steps (4.9% of Sponza's pixels held a
         * quarter of its indirect light's squared error); the widened reach
         * moves with the pixel, so the weights stay continuous. Sponza
         * against 1024-spp references, sun-moved and arcade-moved: nearest
         * 0.1124, 0.1097; 1.25x 0.1123, 0.1081; 1.5x 0.1121, 0.1074; 2x
         * 0.1122, 0.1074 (with gathering points at diag/256 and --aa 5: 2x
         * 0.1002, 0.0975, 1.5x 0.0999, 0.0967, nearest 0.0996, 0.0962) */
        float err[GI_SHADE_K];
        for (int dz = -3; dz <= 3; dz++)
            for (int dy = -3; dy <= 3; dy++)
                for (int dx = -3; dx <= 3; dx++) {
                    int x = c[0] + dx, y = c[1] + dy, z = c[2] + dz;
                    if (x < 0 || y < 0 || z < 0 || x >= sh->gdim[0] || y >= sh->gdim[1] || z >= sh->gdim[2])
                        continue;
                    size_t ci = cell_index(sh, x, y, z);
                    for (uint32_t j = sh->pstart[ci]; j < sh->pstart[ci + 1]; j++) {
                        uint32_t i = sh->pidx[j];
                        const gi_gpoint *g = &h->gpoints[i];
                        float dn = n[0] * g->nrm[0] + n[1] * g->nrm[1] + n[2] * g->nrm[2];
                        if (dn <= 0.0f)
                            continue;
                        float d[3] = {p[0] - g->pos[0], p[1] - g->pos[1], p[2] - g->pos[2]};
                        float e = gi_fmaxf(sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / g->radius,
                                        sqrtf(gi_fmaxf(0.0f, 1.0f - dn)) * inv_na);
                        e = gi_fmaxf(e, plane_err(n, g, d));
                        if (k < GI_SHADE_K) {
                            idx[k] = i;
                            err[k++] = e;
                        } else {
                            int m = 0;
                            for (int q = 1; q < GI_SHADE_K; q++)
                                if (err[q] > err[m])
                                    m = q;
                            if (e < err[m]) {
                                idx[m] = i;
                                err[m] = e;
                            }
                        }
                    }
                }
        if (k == 0)
            return 0;
        float emin = err[0];
        for (int q = 1; q < k; q++)
            emin = gi_fminf(emin, err[q]);
        float r2 = 1.5f * emin + 1e-6f;
        int kk = 0;
        for (int q = 0; q < k; q++)
            if (err[q] < r2) {
                idx[kk] = idx[q];
                wout[kk++] = 1.0f - err[q] / r2;
            }
        k = kk;
    }
    for (int q = 0; q < k; q++)
        wsum += wout[q];
    for (int q = 0; q < k; q++)
        wout[q] = (float)(wout[q] / wsum);
    if (lin && k >= 3)
        linear_fit(sh, p, n, idx, wout, k);
    return k;
}

void gi_shade_irradiance_at(const gi_shade *sh, const float *gpe, const float p[3], const float n[3], int linear,
                            float e[3])
{
    uint32_t idx[GI_SHADE_K];
    float w[GI_SHADE_K];
    int k = interp_weights(sh, p, n, linear, idx, w);
    e[0] = e[1] = e[2] = 0.0f;
    for (int q = 0; q < k; q++)
        for (int c = 0; c < 3; c++)
            e[c] += w[q] * gpe[3 * idx[q] + c];
    for (int c = 0; c < 3; c++)
        e[c] = gi_fmaxf(e[c], 0.0f); /* as the splat: a fit's weights can be negative */
}

static int same_camera(const gi_camera *a, const gi_camera *b)
{
    return !memcmp(a->position, b->position, sizeof a->position) && !memcmp(a->forward, b->forward, sizeof a->forward) &&
           !memcmp(a->up, b->up, sizeof a->up) && a->yfov == b->yfov && a->znear == b->znear && a->zfar == b->zfar;
}

/* Variance of the shading normal over a sample's footprint (sum over both
 * axes), for specular_aa: the interpolated vertex normal's change between
 * the sample point p and where the rays dx, dy through the neighbouring
 * sample positions meet the triangle's plane, taken as linear across the
 * footprint (a box: variance 1/12 of the change squared). 0 on a flat-shaded
 * triangle; a crease between triangles is the edge samples' business. */
static float footprint_nvar(const gi_scene *s, uint32_t tri, gi_vec3 eye, gi_vec3 p, gi_vec3 dx, gi_vec3 dy)
{
    const uint32_t *ix = s->indices + 3 * (size_t)tri;
    gi_vec3 n0 = gi_v3p(s->normals + 3 * (size_t)ix[0]), n1 = gi_v3p(s->normals + 3 * (size_t)ix[1]),
            n2 = gi_v3p(s->normals + 3 * (size_t)ix[2]);
    gi_vec3 dn1 = gi_sub(n1, n0), dn2 = gi_sub(n2, n0);
    if (gi_dot(dn1, dn1) + gi_dot(dn2, dn2) < 1e-12f)
        return 0.0f;
    gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
    gi_vec3 e1 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), p0);
    gi_vec3 e2 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), p0);
    float d00 = gi_dot(e1, e1), d01 = gi_dot(e1, e2), d11 = gi_dot(e2, e2), den = d00 * d11 - d01 * d01;
    gi_vec3 ng = gi_cross(e1, e2);
    if (!(den > 0.0f))
        return 0.0f;
    /* the interpolated normal at p, unnormalised, and its length */
    gi_vec3 dp = gi_sub(p, p0);
    float b1 = (d11 * gi_dot(dp, e1) - d01 * gi_dot(dp, e2)) / den;
    float b2 = (d00 * gi_dot(dp, e2) - d01 * gi_dot(dp, e1)) / den;
    gi_vec3 N = gi_add(n0, gi_add(gi_scale(dn1, b1), gi_scale(dn2, b2)));
    float len = gi_len(N);
    if (!(len > 1e-12f))
        return 0.0f;
    gi_vec3 nn = gi_scale(N, 1.0f / len);
    float pn = gi_dot(gi_sub(p, eye), ng), v = 0.0f;
    gi_vec3 dirs[2] = {dx, dy};
    for (int k = 0; k < 2; k++) {
        float dn = gi_dot(dirs[k], ng), t = pn / dn;
        if (!(fabsf(dn) > 1e-12f) || !(t > 0.0f) || !isfinite(t))
            continue;
        gi_vec3 q = gi_sub(gi_add(eye, gi_scale(dirs[k], t)), p);
        float c1 = (d11 * gi_dot(q, e1) - d01 * gi_dot(q, e2)) / den;
        float c2 = (d00 * gi_dot(q, e2) - d01 * gi_dot(q, e1)) / den;
        gi_vec3 dN = gi_add(gi_scale(dn1, c1), gi_scale(dn2, c2));
        /* change of the normalised normal: the part of dN across it, / |N| */
        gi_vec3 dt = gi_scale(gi_sub(dN, gi_scale(nn, gi_dot(dN, nn))), 1.0f / len);
        v += gi_dot(dt, dt);
    }
    return v / 12.0f;
}

/* Fill the cached record of a sample at pixel position (fx, fy) that sees
 * triangle tri (0-based) at barycentrics (u, v); step: the sample's footprint
 * in pixels (for the texture filter). texf: 1 the texel filtered over the
 * footprint, 0 the texture at the point, -1 no texel (1: the caller's), -2
 * no texel and no normal spread either (the surface only). */
static void fill_sample(const gi_shade *sh, const gi_camera *cam, int w, int h, uint32_t tri, float u, float v,
                        float fx, float fy, float step, int texf, int weights, ssurf *o)
{
    const gi_scene *s = sh->s;
    gi_vec3 eye = gi_v3p(cam->position);
    o->valid = 0;
    o->npairs = 0;
    o->tsurf = INFINITY;
    o->nvar = 0.0f;
    gi_hit hit = {0.0f, tri, u, v};
    gi_surface sf;
    gi_rt_surface(sh->rt, &hit, &sf);
    const gi_material *m = &s->materials[sf.material];
    o->tsurf = gi_len(gi_sub(sf.p, eye));
    gi_vec3 wo = gi_norm(gi_sub(eye, sf.p));
    int front = gi_dot(sf.ng, wo) > 0.0f;
    o->material = sf.material;
    o->tri = tri;
    /* sidedness is a property of the scene's material; scripts change colours, not sides */
    if (!front && !m->double_sided)
        return;
    gi_vec3 ng = front ? sf.ng : gi_neg(sf.ng);
    gi_vec3 nsn = gi_dot(sf.ns, ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
    if (gi_dot(nsn, wo) <= 0.0f)
        nsn = ng;
    gi_v3store(o->p, sf.p);
    gi_v3store(o->ng, ng);
    gi_v3store(o->ns, nsn);
    gi_v3store(o->wo, wo);
    /* texel = base colour with a unit factor, averaged over the sample's
     * footprint like the reference's box-filtered pixel; the spread of the
     * shading normal over the same footprint */
    gi_vec3 ro, dx, dy;
    int tex = texf > 0 && m->base_color_tex >= 0;
    /* (for every sample, glossy or not: computed only while some material
     * was glossy, a first glossy material re-rasterised the view, Sponza
     * 640x480 ~420 ms; always, a camera move costs ~5-10 ms more) */
    int nvar = texf > -2;
    if (tex || nvar) {
        gi_camera_frame_ray(&sh->cf, fx + step, fy, &ro, &dx);
        gi_camera_frame_ray(&sh->cf, fx, fy + step, &ro, &dy);
    }
    if (nvar)
        o->nvar = footprint_nvar(s, sf.tri, eye, sf.p, dx, dy);
    if (texf < 0) {
        o->texel[0] = o->texel[1] = o->texel[2] = 1.0f; /* the caller's business */
    } else if (tex) {
        gi_texfilter_texel(sh->tf, m, sf.tri, eye, sf.p, dx, dy, o->texel);
    } else {
        gi_material unit = *m;
        unit.base_color[0] = unit.base_color[1] = unit.base_color[2] = 1.0f;
        gi_scene_base_color(s, &unit, sf.uv0, sf.uv1, o->texel);
    }
    if (weights)
        o->npairs = (uint8_t)interp_weights(sh, o->p, o->ns, sh->lin, o->gp, o->w);
    o->valid = 1;
}

/* 1 if the samples of two neighbouring pixels see different surfaces: one
 * sees nothing, other materials, a crease (shading normals > ~18 deg apart)
 * or a depth step (b off a's plane by more than 4 pixel footprints, or by
 * half of one between triangles whose texels differ by over 20%, or by less
 * where the texture mapping jumps between them). */
static int discontinuity_tx(const gi_scene *s, const ssurf *a, const ssurf *b, float pix_angle, int *texel);
static int discontinuity(const gi_shade *sh, const ssurf *a, const ssurf *b, float pix_angle)
{
    return discontinuity_tx(sh->s, a, b, pix_angle, NULL);
}

/* Texture coordinates (of material m's base-colour set) that triangle tri's
 * mapping gives point p, taken into the triangle's plane; 0 for a degenerate
 * triangle. */
static int tri_uv_at(const gi_scene *s, const gi_material *m, uint32_t tri, const float p[3], double uv[2])
{
    const uint32_t *ix = s->indices + 3 * (size_t)tri;
    const float *q0 = s->positions + 3 * (size_t)ix[0], *q1 = s->positions + 3 * (size_t)ix[1],
                *q2 = s->positions + 3 * (size_t)ix[2];
    double e1[3], e2[3], v[3];
    for (int c = 0; c < 3; c++) {
        e1[c] = (double)q1[c] - q0[c];
        e2[c] = (double)q2[c] - q0[c];
        v[c] = (double)p[c] - q0[c];
    }
    double d00 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], d01 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
    double d11 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    double d20 = v[0] * e1[0] + v[1] * e1[1] + v[2] * e1[2], d21 = v[0] * e2[0] + v[1] * e2[1] + v[2] * e2[2];
    double den = d00 * d11 - d01 * d01;
    if (!(den > 0.0))
        return 0;
    double b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den;
    const float *uvs = m->base_color_uv == 1 ? s->uv1 : s->uv0;
    const float *t0 = uvs + 2 * (size_t)ix[0], *t1 = uvs + 2 * (size_t)ix[1], *t2 = uvs + 2 * (size_t)ix[2];
    for (int c = 0; c < 2; c++)
        uv[c] = t0[c] + b1 * ((double)t1[c] - t0[c]) + b2 * ((double)t2[c] - t0[c]);
    return 1;
}

/* 1 if the texture mapping jumps between the samples a and b (different
 * triangles of one textured material): at b, a's triangle's mapping carried
 * across its plane and b's own disagree by more than 2 texels plus half the
 * distance (in texels) between a and b. A tile or decal mapped to another
 * part of the texture than what surrounds it, where the footprint filter of
 * a sample on one side cannot know the other. Texture repeats are not
 * jumps. */
static int uv_seam(const gi_scene *s, const ssurf *a, const ssurf *b)
{
    const gi_material *m = &s->materials[a->material];
    if (m->base_color_tex < 0 || (size_t)m->base_color_tex >= s->num_textures)
        return 0;
    const gi_texture *t = &s->textures[m->base_color_tex];
    double ua[2], ub[2], ua0[2];
    if (!tri_uv_at(s, m, a->tri, b->p, ua) || !tri_uv_at(s, m, b->tri, b->p, ub) ||
        !tri_uv_at(s, m, a->tri, a->p, ua0))
        return 0;
    const float *x = m->uv_xform;
    double du[2] = {ub[0] - ua[0], ub[1] - ua[1]}, de[2] = {ua[0] - ua0[0], ua[1] - ua0[1]};
    double jt[2] = {x[0] * du[0] + x[1] * du[1], x[3] * du[0] + x[4] * du[1]};
    double et[2] = {x[0] * de[0] + x[1] * de[1], x[3] * de[0] + x[4] * de[1]};
    if (t->wrap_s != GI_WRAP_CLAMP)
        jt[0] -= nearbyint(jt[0] / (t->wrap_s == GI_WRAP_MIRROR ? 2.0 : 1.0)) * (t->wrap_s == GI_WRAP_MIRROR ? 2.0 : 1.0);
    if (t->wrap_t != GI_WRAP_CLAMP)
        jt[1] -= nearbyint(jt[1] / (t->wrap_t == GI_WRAP_MIRROR ? 2.0 : 1.0)) * (t->wrap_t == GI_WRAP_MIRROR ? 2.0 : 1.0);
    double jump = hypot(jt[0] * t->width, jt[1] * t->height), ext = hypot(et[0] * t->width, et[1] * t->height);
    return jump > 2.0 + 0.5 * ext;
}

/* discontinuity, except that with texel != NULL a pair whose answer depends
 * on a's texel sets *texel = 1 and gives 0 (a's texel not looked up yet) */
static int discontinuity_tx(const gi_scene *s, const ssurf *a, const ssurf *b, float pix_angle, int *texel)
{
    if (a->valid != b->valid)
        return 1;
    if (!a->valid)
        return 0;
    if (a->material != b->material)
        return 2;
    if (a->ns[0] * b->ns[0] + a->ns[1] * b->ns[1] + a->ns[2] * b->ns[2] < 0.95f)
        return 3;
    float d[3] = {b->p[0] - a->p[0], b->p[1] - a->p[1], b->p[2] - a->p[2]};
    float off = fabsf(d[0] * a->ng[0] + d[1] * a->ng[1] + d[2] * a->ng[2]);
    float fp = pix_angle * gi_fminf(a->tsurf, b->tsurf);
    if (off > GI_SHADE_STEP * fp)
        return 4;
    /* a smaller step between triangles whose textures differ there (a
     * raised tile mapped to another part of its texture; within one
     * triangle the texture filter takes care of texture edges). glTF
     * VertexColorTest at 160x120 against 256 spp: nrmse 0.203 / 0.249 ->
     * 0.037 / 0.046; Sponza: 581 -> 870 such pixels, sun-b, sun-moved,
     * arcade-moved 0.1212, 0.0980, 0.0870 -> 0.1204, 0.0976, 0.0863.
     * Or no step at all where the mapping jumps (uv_seam): the same tiles
     * at 96x72 stand 0.49 footprints off the panel: t120 0.234 / 0.384 ->
     * 0.081 / 0.094; Sponza 870 -> 1323 such pixels, sun-moved and
     * arcade-moved unchanged (0.0851 / 0.0966) */
    if (a->tri != b->tri) {
        if (texel) {
            if (off > 0.5f * fp || (s && uv_seam(s, a, b)))
                *texel = 1;
            return 0;
        }
        float ta = gi_luminance(gi_v3p(a->texel)), tb = gi_luminance(gi_v3p(b->texel));
        if (fabsf(ta - tb) > 0.2f * gi_fmaxf(ta, tb) && (off > 0.5f * fp || (s && uv_seam(s, a, b))))
            return 4;
    }
    return 0;
}

static int discontinuous(const gi_shade *sh, const ssurf *a, const ssurf *b, float pix_angle)
{
    return discontinuity(sh, a, b, pix_angle) != 0;
}

static void pack_rec(const ssurf *sf, srec *r)
{
    memset(r, 0, sizeof *r);
    r->material = sf->valid ? sf->material : UINT32_MAX;
    if (!sf->valid)
        return;
    memcpy(r->texel, sf->texel, sizeof r->texel);
    for (int q = 0; q < sf->npairs; q++) {
        r->gp[q] = sf->gp[q];
        r->w[q] = (int16_t)lrintf(gi_clampf(sf->w[q], -1.99f, 1.99f) * 16384.0f);
    }
    /* the unused slots (weight 0) repeat the first point, which the view's
     * gathers and near field fill: point 0 may be one they never wrote, and
     * 0 x NaN is NaN (a checkerboard floor lost the indirect light of half its
     * pixels, t090, whenever the near field's array held a NaN there) */
    for (int q = sf->npairs; q < GI_SHADE_K; q++)
        r->gp[q] = sf->npairs ? sf->gp[0] : 0;
}

/* Rasterise and fill the per-sample cache; with ss == 1 and aa >= 3, find the
 * pixels on geometric edges and give each aa*aa - 1 more samples (Embree
 * camera rays, stratified over the pixel around the centre sample). */
/* *p holds at least n elements of size sz afterwards (contents undefined),
 * or NULL when out of memory */
static void reserve(void *pp, size_t *cap, size_t n, size_t sz)
{
    void **p = (void **)pp;
    if (*p && n <= *cap)
        return;
    free(*p);
    *p = gi_alloc_large((n ? n : 1) * sz);
    *cap = *p ? n : 0;
}
#define RESERVE(field, n) reserve(&sh->field, &sh->cap_##field, (n), sizeof *sh->field)
/* for arrays whose length changes with the view (edge pixels, the points it
 * reads): a quarter more than asked, so that the next views seldom need new
 * memory (Sponza's first camera move took 22 k page faults, ~140 ms more
 * than the next, making its edge samples' arrays 1% larger) */
#define RESERVE_VIEW(field, n) reserve_view(&sh->field, &sh->cap_##field, (n), sizeof *sh->field)
static void reserve_view(void *pp, size_t *cap, size_t n, size_t sz)
{
    void **p = (void **)pp;
    if (*p && n <= *cap)
        return;
    reserve(pp, cap, n + n / 4, sz);
}

/* The positions of the aa * aa - 1 edge samples of pixel (x, y) (stratified
 * and jittered, the centre cell left to the G-buffer's sample). */
static void edge_positions(int aa, int x, int y, size_t pix, float *fx, float *fy)
{
    gi_rng r;
    gi_rng_seed(&r, 0xed9e, pix, 0);
    float estep = 1.0f / (float)aa;
    for (int j = 0, c = 0; c < aa * aa; c++) {
        if (c == aa * aa / 2)
            continue;
        fx[j] = (float)x + ((float)(c % aa) + gi_rng_float(&r)) * estep;
        fy[j] = (float)y + ((float)(c / aa) + gi_rng_float(&r)) * estep;
        j++;
    }
}

/* Index (0..ne, ne: the centre) of the sample of edge pixel e nearest to
 * (fx, fy) on the surface of o (or seeing nothing, like o); -1 when none. */
static int nearest_same_surface(const gi_shade *sh, size_t e, const ssurf *o, float fx, float fy, const float *sfx,
                                const float *sfy, int w, float pix_angle)
{
    const int ne = sh->ne;
    size_t pix = sh->epix[e];
    int best = -1;
    float bd = INFINITY;
    for (int j = 0; j <= ne; j++) {
        const ssurf *c = j < ne ? &sh->esf[e * (size_t)ne + (size_t)j] : &sh->sf[pix];
        if (discontinuous(sh, o, c, pix_angle))
            continue;
        float cx = j < ne ? sfx[j] : (float)(pix % (size_t)w) + 0.5f, cy = j < ne ? sfy[j] : (float)(pix / (size_t)w) + 0.5f;
        float d = (fx - cx) * (fx - cx) + (fy - cy) * (fy - cy);
        if (d < bd) {
            bd = d;
            best = j;
        }
    }
    return best;
}

/* Each sample's share of edge pixel e (sh->ew): cov x cov camera rays
 * stratified over the pixel, each given to the nearest of the pixel's ne + 1
 * samples that sees the same surface (the same triangle, else no
 * discontinuity), else to the nearest sample. With equal shares the pixel's
 * coverage is known to 1 / (ne + 1); the rays need no shading, so a light
 * move costs the same. A surface that rays find and no sample sees (a sliver
 * between the samples: a bevel or a face seen edge-on) replaces a sample
 * whose surface another sample also sees, with texel and weights of its own
 * (sh->esf, esrc, ehard change); Sponza's sunlit bevels were lost before,
 * sun-moved 0.1121 -> 0.1100 nrmse, arcade-moved 0.1074 -> 0.1068. texf:
 * as fill_sample's, for such a sample. sfx, sfy: the ne edge samples'
 * positions. */
static void coverage_shares(gi_shade *sh, const gi_camera *cam, int w, int h, size_t e, int cov_all, int texf,
                            const float *sfx, const float *sfy, float pix_angle)
{
    const int ne = sh->ne > 0 ? sh->ne : 0, ns = ne + 1;
    size_t pix = sh->epix[e];
    int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w);
    const ssurf *smp[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    float spx[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX], spy[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    int cnt[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    for (int j = 0; j < ne; j++) {
        smp[j] = &sh->esf[e * (size_t)ne + (size_t)j];
        spx[j] = sfx[j];
        spy[j] = sfy[j];
        cnt[j] = 0;
    }
    smp[ne] = &sh->sf[pix];
    spx[ne] = (float)x + 0.5f;
    spy[ne] = (float)y + 0.5f;
    cnt[ne] = 0;
    float *ew = sh->ew + e * (size_t)ns;
    /* every sample on the centre's surface: the shares stay equal (the
     * pixel is an edge pixel for its neighbours' sake) unless a ray finds a
     * sliver between the samples (below). Every ray is traced then, on a
     * grid two rays coarser: Sponza, sun-moved and arcade-moved against
     * 1024 spp, none 0.1093 / 0.1068 nrmse, 3 x 3 0.1083 / 0.1066, 4 x 4
     * 0.1079 / 0.1060, 5 x 5 0.1076 / 0.1058, 7 x 7 0.1073 / 0.1056; camera
     * moves ~40, ~65 and ~115 ms slower for 4 x 4, 5 x 5 and 7 x 7 */
    int one = 1;
    for (int j = 0; j < ne && one; j++)
        one = !discontinuous(sh, smp[j], smp[ne], pix_angle);
    const int cov = one ? cov_all - 2 : cov_all;
    if (cov < 1) {
        for (int j = 0; j < ns; j++)
            ew[j] = 1.0f / (float)ns;
        return;
    }
    const int nr = cov * cov;
    /* which samples see the same surface */
    uint8_t same[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX][GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    for (int a = 0; a < ns; a++)
        for (int b = a; b < ns; b++)
            same[a][b] = same[b][a] = (uint8_t)!discontinuous(sh, smp[a], smp[b], pix_angle);
    /* as bits: samemask[a] bit b = same[a][b]; and each sample's triangle
     * (UINT32_MAX: sees nothing), read by every ray below */
    uint64_t samemask[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    uint32_t stri[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    for (int a = 0; a < ns; a++) {
        samemask[a] = 0;
        for (int b = 0; b < ns; b++)
            samemask[a] |= (uint64_t)same[a][b] << b;
        stri[a] = smp[a]->valid ? smp[a]->tri : UINT32_MAX;
    }
    const float spacing = 1.0f / sqrtf((float)ns); /* between neighbouring samples, about */
    /* a surface that few samples see (a strip along a side of the pixel, a
     * corner) has rays farther from them than the test below looks: the
     * pixel's rays are all traced. glTF Box seen 10 cm above its top face
     * at 160x120: a corner pixel's top face took 5 of 121 rays where its
     * coverage is 9.4%; the frame 0.112 -> 0.089 nrmse against 1024 spp
     * (every ray traced: 0.088); Sponza sun-moved / arcade-moved 0.0850 /
     * 0.0966 -> 0.0848 / 0.0961 */
    int minor = 0;
    if (!one) {
        const int few = ns / 12 > 1 ? ns / 12 : 1;
        for (int a = 0; a < ns && !minor; a++) {
            int g = 0;
            for (int b = 0; b < ns; b++)
                g += same[a][b];
            minor = g <= few;
        }
    }
    gi_rng r;
    gi_rng_seed(&r, 0xc0e7, pix, 0);
    enum { CH = 64 };
    float fx[CH], fy[CH];
    gi_vec3 ro[CH], rd[CH];
    gi_hit hit[CH];
    uint8_t found[CH];
    /* orphans: rays that find a surface none of the samples sees (a sliver
     * thinner than the samples' spacing), grouped by surface; og_cnt[g][j]:
     * how many of group g's rays went to sample j meanwhile */
    enum { OG = 2 };
    int nog = 0, og_n[OG];
    ssurf og_sf[OG];
    gi_hit og_hit[OG];
    uint8_t og_found[OG];
    float og_x[OG], og_y[OG];
    int og_cnt[OG][GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    int n = 0;
    for (int c = 0; c <= nr; c++) {
        if (c < nr) {
            float qx = (float)x + ((float)(c % cov) + gi_rng_float(&r)) / (float)cov;
            float qy = (float)y + ((float)(c / cov) + gi_rng_float(&r)) / (float)cov;
            /* a ray whose nearest samples, out to one spacing beyond the
             * nearest, all see one surface would find it: counted untraced.
             * Sponza: 26% of the rays, camera moves ~45 ms faster (G-buffer
             * medians 454 -> 410 ms), nrmse +0.0002 and +0.0004; half a
             * spacing: 40 ms more saved for +0.0009 and +0.0017 */
            if (!one && !minor) {
                /* (with every sample on one surface every ray is traced,
                 * so the test is not made: Sponza's 12-frame camera script,
                 * edge samples 308 -> 300 ms, medians; frames identical) */
                float d2[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
                /* the distances first, in a loop of their own (vectorised), then
                 * the nearest and the test, without branches on the data */
                for (int j = 0; j < ns; j++)
                    d2[j] = (qx - spx[j]) * (qx - spx[j]) + (qy - spy[j]) * (qy - spy[j]);
                int n1 = 0;
                for (int j = 1; j < ns; j++)
                    n1 = d2[j] < d2[n1] ? j : n1;
                float lim = sqrtf(d2[n1]) + spacing, lim2 = lim * lim;
                uint64_t nearby = 0; /* bits: the samples out to lim */
                for (int j = 0; j < ns; j++)
                    nearby |= (uint64_t)(d2[j] <= lim2) << j;
                if (!(nearby & ~samemask[n1])) {
                    cnt[n1]++;
                    continue;
                }
            }
            fx[n] = qx;
            fy[n] = qy;
            gi_camera_frame_ray(&sh->cf, qx, qy, &ro[n], &rd[n]);
            n++;
        }
        if (n == 0 || (n < CH && c < nr))
            continue;
        gi_rt_intersect_n(sh->rt, n, ro, rd, 0.0f, hit, found);
        for (int i = 0; i < n; i++) {
            int best = -1;
            float bd = INFINITY;
            if (found[i])
                for (int j = 0; j < ns; j++)
                    if (stri[j] == hit[i].tri) {
                        float d = (fx[i] - spx[j]) * (fx[i] - spx[j]) + (fy[i] - spy[j]) * (fy[i] - spy[j]);
                        if (d < bd) {
                            bd = d;
                            best = j;
                        }
                    }
            int orphan = -1;
            if (best < 0) {
                ssurf t;
                t.valid = 0;
                if (found[i])
                    fill_sample(sh, cam, w, h, hit[i].tri, hit[i].u, hit[i].v, fx[i], fy[i], 1.0f / (float)cov, -2, 0,
                                &t);
                for (int pass = 0; pass < 2 && best < 0; pass++) {
                    for (int j = 0; j < ns; j++) {
                        if (!pass && discontinuous(sh, &t, smp[j], pix_angle))
                            continue;
                        float d = (fx[i] - spx[j]) * (fx[i] - spx[j]) + (fy[i] - spy[j]) * (fy[i] - spy[j]);
                        if (d < bd) {
                            bd = d;
                            best = j;
                        }
                    }
                    if (!pass && best < 0) {
                        for (int g = 0; g < nog && orphan < 0; g++)
                            if (!discontinuous(sh, &t, &og_sf[g], pix_angle))
                                orphan = g;
                        if (orphan < 0 && nog < OG) {
                            orphan = nog++;
                            og_sf[orphan] = t;
                            og_hit[orphan] = hit[i];
                            og_found[orphan] = found[i];
                            og_x[orphan] = fx[i];
                            og_y[orphan] = fy[i];
                            og_n[orphan] = 0;
                            memset(og_cnt[orphan], 0, sizeof og_cnt[orphan]);
                        }
                    }
                }
            }
            cnt[best]++;
            if (orphan >= 0) {
                og_n[orphan]++;
                og_cnt[orphan][best]++;
            }
        }
        n = 0;
    }
    /* an orphan surface takes the place of an edge sample whose surface
     * another sample also sees: that one takes over its rays, the orphan's
     * rays come back from where they went, and the new sample is made like
     * the rest (texel over its footprint, weights), so a light move shades
     * as many samples as before */
    uint8_t taken[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX] = {0};
    for (int pick = 0; pick < nog; pick++) {
        int g = 0;
        for (int q = 1; q < nog; q++)
            if (og_n[q] > og_n[g])
                g = q;
        if (og_n[g] <= 0)
            break;
        int victim = -1, partner = -1;
        float vd = INFINITY;
        for (int j = 0; j < ne; j++) {
            if (taken[j])
                continue;
            for (int k = 0; k < ns; k++) {
                if (k == j || taken[k] || !same[j][k])
                    continue;
                /* the least-counted sample, then its nearest partner */
                float dx = spx[j] - spx[k], dy = spy[j] - spy[k], d = (float)cnt[j] * 64.0f + dx * dx + dy * dy;
                if (d < vd) {
                    vd = d;
                    victim = j;
                    partner = k;
                }
            }
        }
        if (victim < 0)
            break;
        for (int j = 0; j < ns; j++)
            cnt[j] -= og_cnt[g][j];
        cnt[partner] += cnt[victim];
        for (int q = 0; q < nog; q++) {
            og_cnt[q][partner] += og_cnt[q][victim];
            og_cnt[q][victim] = 0;
        }
        cnt[victim] = og_n[g];
        og_n[g] = 0;
        taken[victim] = 1;
        size_t vi = e * (size_t)ne + (size_t)victim;
        ssurf *o = &sh->esf[vi];
        if (og_found[g] && og_sf[g].valid) {
            fill_sample(sh, cam, w, h, og_hit[g].tri, og_hit[g].u, og_hit[g].v, og_x[g], og_y[g],
                        1.0f / sqrtf((float)ns), texf, 1, o);
        } else {
            *o = og_sf[g];
            o->valid = 0;
            o->npairs = 0;
        }
        sh->esrc[vi] = UINT32_MAX;
        sh->ehard[e] = 1;
        spx[victim] = og_x[g];
        spy[victim] = og_y[g];
        for (int k = 0; k < ns; k++)
            same[victim][k] = same[k][victim] = (uint8_t)(k == victim || !discontinuous(sh, o, smp[k], pix_angle));
    }
    int subst = 0;
    for (int j = 0; j < ne; j++)
        subst |= taken[j];
    for (int j = 0; j < ns; j++)
        ew[j] = one && !subst ? 1.0f / (float)ns : (float)cnt[j] / (float)nr;
}

/* The ne edge samples of edge pixel e from their camera rays' hits (shit,
 * sfound; positions sfx, sfy): surface, texel and weights (or a
 * neighbour's, on the same surface), whether the pixel's coverage matters
 * (sh->ehard), and with cov > 0 the samples' shares (coverage_shares). */
static void edge_pixel(gi_shade *sh, const gi_camera *cam, int w, int h, size_t e, int texf, int cov, float estep,
                       float pix_angle, const float *sfx, const float *sfy, const gi_hit *shit,
                       const uint8_t *sfound)
{
    const gi_scene *s = sh->s;
    const int ne = sh->ne;
    size_t pix = sh->epix[e];
    int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w);
    for (int j = 0; j < ne;) {
        float fx = sfx[j], fy = sfy[j];
        gi_hit hit = shit[j];
        sh->esrc[e * (size_t)ne + (size_t)j] = UINT32_MAX;
        ssurf *o = &sh->esf[e * (size_t)ne + (size_t)j];
        o->valid = 0;
        o->npairs = 0;
        o->tsurf = INFINITY;
        if (!sfound[j++])
            continue;
        fill_sample(sh, cam, w, h, hit.tri, hit.u, hit.v, fx, fy, estep, -1, 0, o);
        if (!o->valid)
            continue;
        /* the texel (filtered over its pixel) and interpolation weights
         * of the centre's or a neighbour's sample on the same surface;
         * computed afresh only on a surface none of them sees */
        const size_t ci[5] = {pix, pix - 1, pix + 1, pix - (size_t)w, pix + (size_t)w};
        const ssurf *cand[5] = {&sh->sf[pix], x > 0 ? &sh->sf[pix - 1] : NULL,
                                x + 1 < w ? &sh->sf[pix + 1] : NULL, y > 0 ? &sh->sf[pix - w] : NULL,
                                y + 1 < h ? &sh->sf[pix + w] : NULL};
        int reused = 0, wreused = 0;
        for (int q = 0; q < 5 && !reused && !wreused; q++)
            if (cand[q] && cand[q]->valid && !discontinuous(sh, o, cand[q], pix_angle)) {
                o->npairs = cand[q]->npairs;
                memcpy(o->gp, cand[q]->gp, sizeof o->gp);
                memcpy(o->w, cand[q]->w, sizeof o->w);
                /* a neighbour's texel is its own footprint's
                 * average, which on a textured face seen at a
                 * grazing angle lies many texels away: such a
                 * sample filters its own (glTF BoxTextured's top
                 * face from 6 degrees above, 160x120 against 256
                 * spp: nrmse 0.0699 -> 0.0459; Sponza sun-b,
                 * sun-moved, arcade-moved 0.1232, 0.0984, 0.0884
                 * -> 0.1212, 0.0980, 0.0870) */
                if (texf && s->materials[o->material].base_color_tex >= 0) {
                    /* the centre's texel is its whole pixel's average
                     * too: where the light varies across the pixel
                     * with the texture (Sponza's mouldings, whose
                     * textures darken their grooves), an edge pixel
                     * summed its samples' light times that average,
                     * not each sample's light times its own texels.
                     * Every such sample filters its own 1 / aa of the
                     * pixel; the splat scales the centre's indirect
                     * light by the texels' ratio (Sponza, 320 x 240
                     * against 1024-2048 spp: f3's direct light 0.109 ->
                     * 0.080 nrmse, the frame 0.123 -> 0.111; u3 0.159
                     * -> 0.153; f1 0.088 -> 0.085) */
                    if (q == 0 && o->material == cand[0]->material)
                        sh->esrc[e * (size_t)ne + (size_t)(j - 1)] = (uint32_t)pix;
                    wreused = 1;
                    break;
                }
                memcpy(o->texel, cand[q]->texel, sizeof o->texel);
                /* same material, weights and texel: the splat takes
                 * that sample's indirect light (wo and ns differ by
                 * less than a pixel, which only a glossy lobe sees) */
                if (o->material == cand[q]->material)
                    sh->esrc[e * (size_t)ne + (size_t)(j - 1)] = (uint32_t)ci[q];
                reused = 1;
            }
        if (!reused && texf && s->materials[o->material].base_color_tex >= 0) {
            gi_vec3 r0, dx, dy;
            gi_camera_frame_ray(&sh->cf, fx + estep, fy, &r0, &dx);
            gi_camera_frame_ray(&sh->cf, fx, fy + estep, &r0, &dy);
            gi_texfilter_texel(sh->tf, &s->materials[o->material], hit.tri, gi_v3p(cam->position),
                               gi_v3p(o->p), dx, dy, o->texel);
        } else if (!reused) {
            /* the texture's value at the point (camera_sample left it) */
            gi_surface hs;
            gi_rt_surface(sh->rt, &hit, &hs);
            gi_material unit = s->materials[o->material];
            unit.base_color[0] = unit.base_color[1] = unit.base_color[2] = 1.0f;
            gi_scene_base_color(s, &unit, hs.uv0, hs.uv1, o->texel);
        }
        if (!reused && !wreused)
            o->npairs = (uint8_t)interp_weights(sh, o->p, o->ns, sh->lin, o->gp, o->w);
    }
    /* hard (1): the pixel's coverage matters whatever the light: its
     * samples see the background, another material or texel. 2: they
     * straddle a crease (a lit bevel between shaded faces: the
     * centres around it, all on the faces, cannot tell that it
     * differs), which matters for a light that lights the two sides
     * differently (light_pass) */
    const ssurf *c0 = &sh->sf[pix];
    float t0 = gi_luminance(gi_v3p(c0->texel));
    for (int j = 0; j < ne && sh->ehard[e] != 1; j++) {
        const ssurf *o = &sh->esf[e * (size_t)ne + (size_t)j];
        if (o->valid != c0->valid ||
            (o->valid && (o->material != c0->material ||
                          fabsf(gi_luminance(gi_v3p(o->texel)) - t0) > 0.2f * t0)))
            sh->ehard[e] = 1;
        else if (o->valid && discontinuity(sh, c0, o, pix_angle) == 3)
            sh->ehard[e] = 2;
    }
    if (cov > 0)
        coverage_shares(sh, cam, w, h, e, cov, texf, sfx, sfy, pix_angle);
}

static int prepare_view(gi_shade *sh, gi_gbuffer *gb, const gi_camera *cam, int w, int h, int ss, int texf,
                        int aa, int cov, int threads, gi_status *st)
{
    size_t np = (size_t)w * (size_t)h, ns = np * (size_t)(ss * ss);
    free_xsf(sh);
    sh->nedge = 0;
    sh->ne = 0;
    sh->valid = 0;
    gi_camera_frame_init(&sh->cf, cam, w, h);
    RESERVE(px, ns);
    RESERVE(sf, ns);
    if (!sh->px || !sh->sf)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for a %dx%d G-buffer with %dx%d samples", w, h, ss, ss);
    /* one jittered position per stratum (the same for every pixel of a pass):
     * with ss > 1 the pixel average is an unbiased box filter like the reference's */
    double tv0 = gi_now();
    gi_rng rng;
    gi_rng_seed(&rng, 0x5eed, (uint64_t)ss, 0);
    for (int k = 0; k < ss * ss; k++) {
        float r1 = ss > 1 ? gi_rng_float(&rng) : 0.5f, r2 = ss > 1 ? gi_rng_float(&rng) : 0.5f;
        float jx = ((float)(k % ss) + r1) / (float)ss, jy = ((float)(k / ss) + r2) / (float)ss;
        sh->jit[2 * k] = jx;
        sh->jit[2 * k + 1] = jy;
        int rc = gi_gbuffer_render(gb, cam, w, h, jx, jy, sh->px + (size_t)k * np, st);
        if (rc)
            return rc;
    }
    const gi_scene *s = sh->s;
    float step = 1.0f / (float)ss;
    double tv1 = gi_now();
    /* in tiles of TILE_W x TILE_H pixels: neighbours above and below read
     * the same texture rows while they are still in cache (in scanline
     * order the filter waited on memory for half its time) */
    enum { TILE_W = 16, TILE_H = 16 };
    const size_t tx = ((size_t)w + TILE_W - 1) / TILE_W, ty = ((size_t)h + TILE_H - 1) / TILE_H;
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads)
    for (size_t t = 0; t < tx * ty * (size_t)(ss * ss); t++) {
        gi_rt_thread_init();
        size_t k = t / (tx * ty), tt = t % (tx * ty);
        int x0 = (int)(tt % tx) * TILE_W, y0 = (int)(tt / tx) * TILE_H;
        int x1 = x0 + TILE_W < w ? x0 + TILE_W : w, y1 = y0 + TILE_H < h ? y0 + TILE_H : h;
        for (int y = y0; y < y1; y++)
            for (int x = x0; x < x1; x++) {
                size_t pix = (size_t)y * (size_t)w + (size_t)x, i = k * np + pix;
                const gi_gpixel *g = &sh->px[i];
                ssurf *o = &sh->sf[i];
                o->valid = 0;
                o->npairs = 0;
                o->tsurf = INFINITY;
                if (!g->tri || g->tri > s->num_triangles)
                    continue;
                float fx = (float)x + sh->jit[2 * k], fy = (float)y + sh->jit[2 * k + 1];
                fill_sample(sh, cam, w, h, g->tri - 1, g->u, g->v, fx, fy, step, texf, 1, o);
                if (!o->valid) {
                    /* the back of a single-sided triangle (which absorbs):
                     * where it lies in the plane of a front face, GL and
                     * Embree may break the tie differently, so the sample
                     * takes what the path tracer's camera ray finds (glTF
                     * VertexColorTest, tiles on a panel, 160x120 against
                     * 256 spp: the pixels along its tiles' edges) */
                    gi_vec3 ro, rd;
                    gi_hit eh;
                    gi_camera_frame_ray(&sh->cf, fx, fy, &ro, &rd);
                    if (gi_rt_intersect(sh->rt, ro, rd, 0.0f, INFINITY, &eh) && eh.tri != g->tri - 1)
                        fill_sample(sh, cam, w, h, eh.tri, eh.u, eh.v, fx, fy, step, texf, 1, o);
                }
            }
    }
    double tv2 = gi_now();
    if (!(ss == 1 && aa >= 3 && cov > 0)) {
        free(sh->ew); /* NULL: equal shares */
        sh->ew = NULL;
        sh->cap_ew = 0;
    }
    if (!(ss == 1 && aa >= 3)) {
        free(sh->eidx); /* NULL: this view has no edge samples */
        sh->eidx = NULL;
        sh->cap_eidx = 0;
    }
    if (ss == 1 && aa >= 3) {
        RESERVE(eidx, np);
        if (!sh->eidx)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for edge samples");
        float pix_angle = 2.0f * tanf(0.5f * cam->yfov) / (float)h;
        /* each pixel's reason (0: none) in parallel, then the indices in order */
#pragma omp parallel for schedule(static) num_threads(threads)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t pix = (size_t)y * (size_t)w + (size_t)x;
                const ssurf *a = &sh->sf[pix];
                int r = 0;
                if (x > 0)
                    r = discontinuity(sh, a, a - 1, pix_angle);
                if (!r && x + 1 < w)
                    r = discontinuity(sh, a, a + 1, pix_angle);
                if (!r && y > 0)
                    r = discontinuity(sh, a, a - w, pix_angle);
                if (!r && y + 1 < h)
                    r = discontinuity(sh, a, a + w, pix_angle);
                sh->eidx[pix] = (uint32_t)r;
            }
        size_t nedge = 0, why[5] = {0, 0, 0, 0, 0};
        for (size_t pix = 0; pix < np; pix++) {
            uint32_t r = sh->eidx[pix];
            why[r]++;
            sh->eidx[pix] = r ? (uint32_t)nedge++ : UINT32_MAX;
        }
        gi_verbose("edge pixels: %zu by coverage, %zu by material, %zu by crease, %zu by depth step", why[1],
                   why[2], why[3], why[4]);
        int ne = aa * aa - 1;
        RESERVE_VIEW(epix, nedge + 1);
        RESERVE_VIEW(esf, nedge * (size_t)ne + 1);
        RESERVE_VIEW(esrc, nedge * (size_t)ne + 1);
        RESERVE_VIEW(ehard, nedge + 1);
        if (cov > 0) {
            RESERVE_VIEW(ew, nedge * (size_t)(ne + 1) + 1);
            if (!sh->ew)
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu edge pixels", nedge);
        }
        if (sh->ehard)
            memset(sh->ehard, 0, nedge + 1);
        sh->xsf = gi_calloc_large(nedge + 1, sizeof *sh->xsf);
        sh->nxsf = sh->xsf ? nedge : 0;
        if (!sh->epix || !sh->esf || !sh->esrc || !sh->ehard || !sh->xsf)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu edge pixels", nedge);
        for (size_t pix = 0; pix < np; pix++)
            if (sh->eidx[pix] != UINT32_MAX)
                sh->epix[sh->eidx[pix]] = (uint32_t)pix;
        sh->nedge = nedge;
        sh->ne = ne;
        float estep = 1.0f / (float)aa;
        /* two pixels at a time: their 2 ne camera rays (16 at --aa 3) fill
         * whole packets, where one pixel's 8 left half of each empty */
#pragma omp parallel for schedule(dynamic, 32) num_threads(threads)
        for (size_t e2 = 0; e2 < (nedge + 1) / 2; e2++) {
            gi_rt_thread_init();
            enum { NA = GI_SHADE_AA_MAX * GI_SHADE_AA_MAX };
            float sfx[2][NA], sfy[2][NA];
            gi_vec3 sro[2 * NA], srd[2 * NA];
            gi_hit shit[2 * NA];
            uint8_t sfound[2 * NA];
            size_t e0 = 2 * e2, e1 = e0 + 2 < nedge ? e0 + 2 : nedge;
            int nr = 0;
            for (size_t e = e0; e < e1; e++) {
                size_t pix = sh->epix[e];
                int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w), q = (int)(e - e0);
                edge_positions(aa, x, y, pix, sfx[q], sfy[q]);
                for (int j = 0; j < ne; j++, nr++)
                    gi_camera_frame_ray(&sh->cf, sfx[q][j], sfy[q][j], &sro[nr], &srd[nr]);
            }
            gi_rt_intersect_n(sh->rt, nr, sro, srd, 0.0f, shit, sfound);
            for (size_t e = e0; e < e1; e++) {
                int q = (int)(e - e0);
                edge_pixel(sh, cam, w, h, e, texf, cov, estep, pix_angle, sfx[q], sfy[q], shit + (size_t)q * (size_t)ne,
                           sfound + (size_t)q * (size_t)ne);
            }
        }
        gi_verbose("edge antialiasing: %zu of %zu pixels (%.1f%%) get %d more samples", nedge, np,
                   100.0 * (double)nedge / (double)np, ne);
    }
    RESERVE(rec, ns + 1);
    RESERVE_VIEW(erec, sh->nedge * (size_t)sh->ne + 1);
    RESERVE(cind, 3 * ns + 1);
    RESERVE(svalid, ns + 1);
    RESERVE(smat, ns + 1);
    RESERVE_VIEW(esmat, sh->nedge * (size_t)sh->ne + 1);
    if (!sh->rec || !sh->erec || !sh->cind || !sh->svalid || !sh->smat || !sh->esmat)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu splat records", ns);
#pragma omp parallel for schedule(static) num_threads(threads)
    for (size_t i = 0; i < ns; i++) {
        pack_rec(&sh->sf[i], &sh->rec[i]);
        sh->svalid[i] = sh->sf[i].valid;
        sh->smat[i] = sh->sf[i].valid ? sh->sf[i].material : UINT32_MAX;
    }
#pragma omp parallel for schedule(static) num_threads(threads)
    for (size_t i = 0; i < sh->nedge * (size_t)sh->ne; i++) {
        pack_rec(&sh->esf[i], &sh->erec[i]);
        sh->esmat[i] = sh->esf[i].valid ? sh->esf[i].material : UINT32_MAX;
    }
    /* the gathering points the records read */
    {
        size_t nb = ((size_t)sh->h->num_gpoints + 63) / 64, ne = sh->nedge * (size_t)sh->ne;
        if (!sh->vbits && !(sh->vbits = calloc(nb + 1, sizeof *sh->vbits)))
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        memset(sh->vbits, 0, (nb + 1) * sizeof *sh->vbits);
        int vfail = 0;
        /* each thread marks its share of the samples in a set of its own */
#pragma omp parallel num_threads(threads)
        {
            uint64_t *vb = calloc(nb + 1, sizeof *vb);
            if (!vb) {
#pragma omp atomic write
                vfail = 1;
            }
#pragma omp for schedule(static)
            for (size_t i = 0; i < ns + ne; i++) {
                const ssurf *o = i < ns ? &sh->sf[i] : &sh->esf[i - ns];
                for (int q = 0; vb && o->valid && q < o->npairs; q++)
                    vb[o->gp[q] >> 6] |= 1ull << (o->gp[q] & 63);
            }
            if (vb) {
#pragma omp critical(gi_shade_vbits)
                for (size_t b = 0; b < nb; b++)
                    sh->vbits[b] |= vb[b];
            }
            free(vb);
        }
        if (vfail)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        size_t n = 0;
        for (size_t b = 0; b < nb; b++)
            n += (size_t)__builtin_popcountll(sh->vbits[b]);
        RESERVE_VIEW(vgp, n + 1);
        if (!sh->vgp)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        n = 0;
        for (size_t b = 0; b < nb; b++)
            for (uint64_t m = sh->vbits[b]; m; m &= m - 1)
                sh->vgp[n++] = (uint32_t)(b * 64 + (size_t)__builtin_ctzll(m));
        sh->nvgp = n;
    }
    gi_verbose("view: rasterise %.1f ms, %zu surfaces and weights %.1f ms, edge samples %.1f ms; it reads %zu of %u "
               "gathering points",
               1e3 * (tv1 - tv0), ns, 1e3 * (tv2 - tv1), 1e3 * (gi_now() - tv2), sh->nvgp, sh->h->num_gpoints);
    sh->pw = w;
    sh->ph = h;
    sh->pss = ss;
    sh->ptexf = texf;
    sh->paa = aa;
    sh->pcov = cov;
    sh->plin = sh->lin;
    sh->pcam = *cam;
    sh->valid = 1;
    sh->view_id++; /* every cached direct light is stale */
    if (sh->gexp)
        memset(sh->gexp, 0, sh->cap_gexp * sizeof *sh->gexp); /* the glossy gathers too */
    if (sh->gtgt)
        memset(sh->gtgt, 0, sh->cap_gexp * sizeof *sh->gtgt);
    return 0;
}

/* Visibility of an area light's sliver in a pixel that the 4 x 4 grid of
 * visible_area_lights missed: camera rays through the part of the projected
 * rectangle inside the pixel (poly, n vertices in pixel units: its centroid
 * and the points halfway from it to each vertex). Before, such a pixel took
 * the sliver unblocked: Sponza, a 1.2 x 0.8 m panel under an arcade's vault
 * seen edge-on from 17 m, hidden behind stone in the path tracer's image,
 * lit a row of pixels up to 289 cd/m2 (320 x 240, nrmse 2.0). */
static void sliver_visibility(const gi_shade *sh, const gi_light *lt, float poly[][2], int n, int *hits,
                              int *seen)
{
    if (n < 3)
        return;
    float cx = 0.0f, cy = 0.0f;
    for (int i = 0; i < n; i++) {
        cx += poly[i][0];
        cy += poly[i][1];
    }
    cx /= (float)n;
    cy /= (float)n;
    for (int i = -1; i < n; i++) {
        float px = i < 0 ? cx : 0.5f * (cx + poly[i][0]), py = i < 0 ? cy : 0.5f * (cy + poly[i][1]);
        gi_vec3 ro, rd;
        gi_camera_frame_ray(&sh->cf, px, py, &ro, &rd);
        int front;
        float t = gi_area_light_intersect(lt, ro, rd, 0.0f, INFINITY, &front);
        if (t > 0.0f && front) {
            (*seen)++;
            *hits += !gi_rt_occluded(sh->rt, ro, rd, 0.0f, t * (1.0f - 1e-5f));
        }
    }
}

/* Area lights seen directly by the camera, antialiased like the reference:
 * the exact share of each pixel covered by the projected rectangle, times the
 * share of 4 x 4 camera rays through the light that no geometry blocks
 * (Embree). Only pixels in the light's projected bounding box. Adds into rgb. */
static void visible_area_lights(const gi_shade *sh, const gi_camera *cam, int w, int h, const gi_light *lights,
                                size_t num_lights, float *rgb, int threads)
{
    gi_vec3 f = gi_norm(gi_v3p(cam->forward)), up = gi_norm(gi_v3p(cam->up));
    gi_vec3 r = gi_norm(gi_cross(f, up));
    up = gi_cross(r, f);
    float th = tanf(0.5f * cam->yfov), aspect = (float)w / (float)h;
    gi_vec3 eye = gi_v3p(cam->position);
    for (size_t l = 0; l < num_lights; l++) {
        const gi_light *lt = &lights[l];
        if (!lt->enabled || lt->type != GI_LIGHT_AREA)
            continue;
        gi_vec3 c = gi_v3p(lt->position), u = gi_v3p(lt->u), v = gi_v3p(lt->v);
        int x0 = 0, y0 = 0, x1 = w - 1, y1 = h - 1, all_front = 1;
        float bx0 = INFINITY, by0 = INFINITY, bx1 = -INFINITY, by1 = -INFINITY;
        for (int k = 0; k < 4; k++) {
            gi_vec3 q = gi_add(c, gi_add(gi_scale(u, (k & 1) ? 1.0f : -1.0f), gi_scale(v, (k & 2) ? 1.0f : -1.0f)));
            gi_vec3 d = gi_sub(q, eye);
            float z = gi_dot(d, f);
            if (z <= 1e-6f) {
                all_front = 0;
                break;
            }
            float px = (gi_dot(d, r) / (z * th * aspect) + 1.0f) * 0.5f * (float)w;
            float py = (1.0f - gi_dot(d, up) / (z * th)) * 0.5f * (float)h;
            bx0 = gi_fminf(bx0, px);
            bx1 = gi_fmaxf(bx1, px);
            by0 = gi_fminf(by0, py);
            by1 = gi_fmaxf(by1, py);
        }
        if (all_front) {
            if (bx1 < 0.0f || by1 < 0.0f || bx0 >= (float)w || by0 >= (float)h)
                continue;
            x0 = clampi((int)floorf(bx0) - 1, 0, w - 1);
            x1 = clampi((int)floorf(bx1) + 1, 0, w - 1);
            y0 = clampi((int)floorf(by0) - 1, 0, h - 1);
            y1 = clampi((int)floorf(by1) + 1, 0, h - 1);
        }
        gi_vec3 le = gi_scale(gi_v3p(lt->color), lt->intensity);
        /* projected corners, in pixel units, in order around the rectangle */
        float poly[4][2];
        if (all_front) {
            static const int ord[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
            for (int k = 0; k < 4; k++) {
                gi_vec3 q = gi_add(c, gi_add(gi_scale(u, (float)ord[k][0]), gi_scale(v, (float)ord[k][1])));
                gi_vec3 d = gi_sub(q, eye);
                float z = gi_dot(d, f);
                poly[k][0] = (gi_dot(d, r) / (z * th * aspect) + 1.0f) * 0.5f * (float)w;
                poly[k][1] = (1.0f - gi_dot(d, up) / (z * th)) * 0.5f * (float)h;
            }
        }
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
        for (int y = y0; y <= y1; y++) {
            gi_rt_thread_init();
            for (int x = x0; x <= x1; x++) {
                int hits = 0, seen = 0;
                for (int k = 0; k < 16; k++) {
                    gi_vec3 ro, rd;
                    gi_camera_frame_ray(&sh->cf, (float)x + ((float)(k & 3) + 0.5f) / 4.0f,
                                  (float)y + ((float)(k >> 2) + 0.5f) / 4.0f, &ro, &rd);
                    int front;
                    float t = gi_area_light_intersect(lt, ro, rd, 0.0f, INFINITY, &front);
                    if (t > 0.0f && front) {
                        seen++;
                        hits += !gi_rt_occluded(sh->rt, ro, rd, 0.0f, t * (1.0f - 1e-5f));
                    }
                }
                float cover;
                if (all_front) {
                    /* exact share of the pixel square inside the projected rectangle */
                    float a[12][2], b[12][2];
                    int na = 4;
                    memcpy(a, poly, sizeof poly);
                    const float lim[4] = {(float)x, (float)(x + 1), (float)y, (float)(y + 1)};
                    for (int e = 0; e < 4; e++) {
                        int ax = e / 2, keep_ge = !(e & 1), nb = 0;
                        for (int i = 0; i < na; i++) {
                            const float *p0 = a[i], *p1 = a[(i + 1) % na];
                            float d0 = keep_ge ? p0[ax] - lim[e] : lim[e] - p0[ax];
                            float d1 = keep_ge ? p1[ax] - lim[e] : lim[e] - p1[ax];
                            if (d0 >= 0.0f && nb < 12) {
                                b[nb][0] = p0[0];
                                b[nb][1] = p0[1];
                                nb++;
                            }
                            if ((d0 >= 0.0f) != (d1 >= 0.0f) && nb < 12) {
                                float t = d0 / (d0 - d1);
                                b[nb][0] = p0[0] + t * (p1[0] - p0[0]);
                                b[nb][1] = p0[1] + t * (p1[1] - p0[1]);
                                nb++;
                            }
                        }
                        memcpy(a, b, sizeof b);
                        na = nb;
                    }
                    float area2 = 0.0f;
                    for (int i = 0; i < na; i++)
                        area2 += a[i][0] * a[(i + 1) % na][1] - a[(i + 1) % na][0] * a[i][1];
                    cover = 0.5f * fabsf(area2);
                    if (cover > 0.0f) {
                        /* facing: the emitting side towards the eye */
                        if (gi_dot(gi_sub(eye, c), gi_cross(u, v)) <= 0.0f)
                            cover = 0.0f;
                        else {
                            if (!seen)
                                sliver_visibility(sh, lt, a, na, &hits, &seen);
                            /* a sliver that no ray could find: counted hidden
                             * (it covers less than a part in 1e3 of the pixel) */
                            cover = seen ? cover * (float)hits / (float)seen : 0.0f;
                        }
                    }
                } else {
                    cover = (float)hits / 16.0f;
                }
                if (cover > 0.0f) {
                    float *o = rgb + 3 * ((size_t)y * (size_t)w + (size_t)x);
                    o[0] += le.x * cover;
                    o[1] += le.y * cover;
                    o[2] += le.z * cover;
                }
            }
        }
    }
}

/* Specular anti-aliasing: a glossy lobe evaluated at one point of a pixel
 * stands for the pixel's average over the normals it covers. The lobe
 * cos^n is about a Gaussian of variance 1/n per axis around the mirror
 * direction, which turns twice as fast as the normal: over a footprint whose
 * normal varies with total variance nvar (both axes, nvar / 2 each;
 * footprint_nvar), the average is the lobe widened to 1/n + 2 nvar per axis
 * (as Kaplanyan et al. 2016 do for microfacet lobes). The widening is capped
 * at 0.18 (Tokuyoshi and Kaplanyan 2019) for footprints that span a strongly
 * curved patch. The reference path tracer averages its samples over the
 * pixel instead. Without this a sharp highlight smaller than a pixel is
 * missed by the pixel's one sample or hit at its peak: on a metal sphere at
 * 64 x 48 (t115) nrmse 5.4 and 6.9 against 1024 spp, with it 2.7 and 2.4; a
 * glossy Suzanne (glTF sample IridescenceSuzanne, 96 x 72) 26.9 -> 2.7. */
static inline void specular_aa(gi_bsdf *b, float nvar)
{
    if (!(nvar > 0.0f) || !(b->exponent > 0.0f) || gi_maxc(b->ks) <= 0.0f)
        return;
    b->exponent = 1.0f / (1.0f / b->exponent + gi_fminf(2.0f * nvar, GI_SHADE_SAA_MAX));
}

/* Shadow rays of one thread, traced in coherent packets: each ray carries the
 * unshadowed contribution it adds to acc[idx] when nothing blocks it. */
enum { SB_CAP = 2048 };
typedef struct sbatch {
    const gi_rt *rt;
    int n;
    gi_vec3 o[SB_CAP], d[SB_CAP], c[SB_CAP];
    float t[SB_CAP], ce[SB_CAP], wd[SB_CAP];
    float *eacc;        /* NULL, or per slot: sum of the irradiance luminance of the rays that found the light */
    uint32_t idx[SB_CAP];
    uint8_t occ[SB_CAP];
    gi_vec3 *acc;
    uint16_t *nlit;     /* NULL, or per slot: rays that found the light */
} sbatch;

static void sb_flush(sbatch *b)
{
    if (!b->n)
        return;
    gi_rt_occluded_n(b->rt, b->n, b->o, b->d, b->t, b->occ);
    for (int q = 0; q < b->n; q++)
        if (!b->occ[q]) {
            b->acc[b->idx[q]] = gi_add(b->acc[b->idx[q]], b->c[q]);
            if (b->eacc)
                b->eacc[b->idx[q]] += b->ce[q];
            if (b->nlit)
                b->nlit[b->idx[q]]++;
        }
    b->n = 0;
}

/* Queue the shadow rays of light lt (index l) at sample sf; the sample's
 * random numbers come from (seed, id, l), so the image does not depend on the
 * thread count or the batching. Contributions are not yet divided by the
 * number of light samples. */
/* The BSDF half of a mesh light's MIS estimate at p: nb = kb x kb
 * stratified BSDF samples traced to the first surface; one that finds the
 * emitting side of an emissive triangle adds its radiance with the power
 * heuristic against nsmp light samples, scaled to stand for nsmp samples
 * (the caller divides by them). Adds straight into acc[slot]. Returns how
 * many found an emitter. With kb = ka / 2 (4 rays for 16 light samples, 16
 * for the 64 of a penumbra): Sponza's round doors made emissive, 240 x 180
 * against 512 spp (noise 0.053), nrmse 0.370 -> 0.115 (isolated door
 * pixels up to 79 cd/m2 where the path tracer finds 42), the direct stage
 * 3.2 -> 4.4 s; kb = ka / 4: 0.134, 3.7 s. The closed emissive box of t101:
 * direct part 0.096 -> 0.024. */
enum { SB_MIS_MAX = 8 }; /* kb at most: 64 BSDF rays */
static int sb_mesh_bsdf(sbatch *b, const gi_bsdf *bs, const gi_light *lt, gi_vec3 p, gi_vec3 ng, gi_vec3 nsn,
                        gi_vec3 wo, int nsmp, int nb, uint64_t seed, uint64_t id, uint64_t l, uint32_t slot)
{
    const gi_emit *e = lt->mesh;
    int kb = 1;
    while ((kb + 1) * (kb + 1) <= nb)
        kb++;
    gi_vec3 ro[SB_MIS_MAX * SB_MIS_MAX], rd[SB_MIS_MAX * SB_MIS_MAX], w[SB_MIS_MAX * SB_MIS_MAX];
    float pdf[SB_MIS_MAX * SB_MIS_MAX];
    gi_hit hit[SB_MIS_MAX * SB_MIS_MAX];
    uint8_t found[SB_MIS_MAX * SB_MIS_MAX];
    gi_rng rng;
    gi_rng_seed(&rng, seed ^ 0x6d15b5dfull, id, l);
    int n = 0;
    for (int j = 0; j < kb * kb; j++) {
        float u1 = ((float)(j % kb) + gi_rng_float(&rng)) / (float)kb;
        float u2 = ((float)(j / kb) + gi_rng_float(&rng)) / (float)kb;
        float u3 = gi_rng_float(&rng);
        gi_vec3 wi;
        if (!gi_bsdf_sample(bs, nsn, wo, u1, u2, u3, &wi, &w[n], &pdf[n]) || gi_dot(wi, ng) <= 0.0f ||
            !(pdf[n] > 0.0f) || gi_maxc(w[n]) <= 0.0f)
            continue;
        ro[n] = gi_rt_offset(p, ng, wi);
        rd[n] = wi;
        n++;
    }
    if (!n)
        return 0;
    gi_rt_intersect_n(b->rt, n, ro, rd, 0.0f, hit, found);
    gi_vec3 col = gi_scale(gi_v3p(lt->color), lt->intensity), sum = gi_v3(0, 0, 0);
    int nhit = 0;
    for (int q = 0; q < n; q++) {
        if (!found[q] || hit[q].tri >= e->num_triangles)
            continue;
        int32_t k = e->index_of_tri[hit[q].tri];
        if (k < 0)
            continue;
        gi_vec3 en = gi_v3p(e->geo + 12 * (size_t)k + 9);
        if (gi_dot(en, rd[q]) >= 0.0f && !e->two_sided[k])
            continue; /* its back: emits nothing this way */
        float pl = (float)nsmp * gi_emit_pdf(e, hit[q].tri, rd[q], hit[q].t), pb = (float)kb * (float)kb * pdf[q];
        float wgt = pb * pb / (pb * pb + pl * pl);
        sum = gi_madd(sum, gi_mul(w[q], gi_mul(gi_v3p(e->le + 3 * (size_t)k), col)), wgt);
        nhit++;
    }
    if (nhit)
        b->acc[slot] = gi_madd(b->acc[slot], sum, (float)nsmp / (float)(kb * kb));
    return nhit;
}

static int sb_light(sbatch *b, const ssurf *sf, const gi_material *mats, const gi_light *lt, uint64_t l, int ka,
                    uint64_t seed, uint64_t id, uint32_t slot)
{
    int queued = 0;
    const gi_material *m = &mats[sf->material];
    gi_vec3 p = gi_v3p(sf->p), ng = gi_v3p(sf->ng), nsn = gi_v3p(sf->ns), wo = gi_v3p(sf->wo);
    gi_bsdf bs;
    gi_bsdf_init(&bs, m, gi_mul(gi_v3p(m->base_color), gi_v3p(sf->texel)));
    specular_aa(&bs, sf->nvar);
    int nsmp = gi_light_has_area(lt) ? ka * ka : 1;
    gi_rng rng = {0, 0}; /* seeded below when the light has area */
    /* a rectangle's (or a few emissive triangles') diffuse light is exact
     * unshadowed (Lambert's formula), times the share of the samples' weight
     * that finds the light (a ratio estimator): no noise where the whole
     * light is seen, close to a large panel where sampled irradiance is
     * noisiest. Cornell box, a 0.4 x 0.4 m
     * ceiling panel, 256 x 256 against 2048 spp: nrmse 0.0474 -> 0.0128, with
     * a glossy floor 0.0475 -> 0.0128 (t082) */
    gi_vec3 ediff = gi_v3(0, 0, 0), ean;
    int analytic = nsmp <= SB_CAP && gi_maxc(bs.kd) > 0.0f && gi_light_analytic(lt, p, nsn, &ean) &&
                   gi_maxc(ean) > 0.0f;
    if (analytic) {
        /* this sample's rays in one batch, so that their diffuse parts can
         * be divided by the weight of all samples once it is known */
        ediff = gi_scale(gi_mul(bs.kd, ean), GI_INV_PIf * (float)nsmp);
        if (b->n + nsmp > SB_CAP)
            sb_flush(b);
    }
    /* a mesh light (emissive triangles) sampled by power spikes where a
     * point lies close to an emitter, e.g. along a concave crease of an
     * emissive surface, lit by the faces across it: nb BSDF samples more,
     * with the power heuristic (sb_mesh_bsdf) */
    const int mis = lt->type == GI_LIGHT_MESH && !analytic && lt->mesh;
    const int kbs = ka >= 2 ? (ka / 2 < SB_MIS_MAX ? ka / 2 : SB_MIS_MAX) : 1, nb = mis ? kbs * kbs : 0;
    const int q0 = b->n;
    double wsum = 0.0;
    /* a light without area takes no random numbers: its stream is not
     * seeded (3% of a Sponza light move's time went to seeding it) */
    const int has_area = gi_light_has_area(lt);
    if (has_area)
        gi_rng_seed(&rng, seed, id, l);
    for (int j = 0; j < nsmp; j++) {
        gi_light_sample ls;
        if (!(has_area ? gi_light_sample_stratum(lt, p, j, ka, &rng, &ls) : gi_light_sample_at(lt, p, 0.5f, 0.5f, &ls)))
            continue;
        float cosi = gi_dot(nsn, ls.wi);
        if (cosi <= 0.0f)
            continue;
        float wq = gi_luminance(ls.value) * cosi;
        wsum += wq;
        if (gi_dot(ng, ls.wi) <= 0.0f)
            continue;
        gi_vec3 f = gi_bsdf_eval(&bs, nsn, wo, ls.wi);
        /* a lobe that reflects none of this light (a metal's lobe facing
         * away) needs no ray, unless the light's irradiance is asked for
         * (eacc): the edge pixels' decisions (light_pass) read it and must
         * not depend on the material, or a frame after a material change
         * differed from the same frame rendered fresh (Sponza, a floor made
         * metal: the direct part 0.056 nrmse apart, at edges on the walls) */
        if (gi_maxc(f) <= 0.0f && !b->eacc)
            continue;
        if (mis) {
            /* MIS with the BSDF samples below, as the path tracer weighs them */
            float pl = (float)nsmp * ls.pdf, pb = (float)nb * gi_bsdf_pdf(&bs, nsn, wo, ls.wi);
            f = gi_scale(f, pl * pl / (pl * pl + pb * pb));
        }
        if (b->n == SB_CAP)
            sb_flush(b);
        int q = b->n++;
        b->o[q] = gi_rt_offset(p, ng, ls.wi);
        b->d[q] = ls.wi;
        b->t[q] = gi_rt_shadow_tmax(p, b->o[q], ls.dist);
        /* analytic: the sampled glossy lobe now, the diffuse part's weight
         * kept for below */
        b->c[q] = gi_scale(gi_mul(analytic ? gi_sub(f, gi_scale(bs.kd, GI_INV_PIf)) : f, ls.value), cosi);
        b->wd[q] = wq;
        b->ce[q] = wq;
        b->idx[q] = slot;
        queued++;
    }
    if (analytic && wsum > 0.0) {
        float inv = (float)(1.0 / wsum);
        for (int q = q0; q < b->n; q++)
            b->c[q] = gi_madd(b->c[q], ediff, b->wd[q] * inv);
    }
    if (mis)
        (void)sb_mesh_bsdf(b, &bs, lt, p, ng, nsn, wo, nsmp, nb, seed, id, l, slot);
    return queued;
}

/* Direct light of light lt (index l) at n samples (sample i at samp[i],
 * random id ids[i]) into out[i], divided by the light's sample count. acc:
 * n scratch vectors. vis (NULL for area lights): vis[i] = 0 when sample i
 * sent the light no shadow ray, 1 when lit, 2 when shadowed. */
static void light_samples(sbatch *b, const ssurf *const *samp, const uint64_t *ids, size_t n, const gi_light *lt,
                          size_t l, const gi_material *mats, int ka, uint64_t seed, gi_vec3 *acc, gi_vec3 *out,
                          uint8_t *vis, uint16_t *cnt, float *eout)
{
    int area = gi_light_has_area(lt);
    b->acc = acc;
    b->nlit = area ? cnt : NULL;
    b->eacc = eout;
    for (size_t e = 0; e < n; e++) {
        acc[e] = gi_v3(0, 0, 0);
        if (eout)
            eout[e] = 0.0f;
        if (b->nlit)
            cnt[e] = 0;
        int q = samp[e] ? sb_light(b, samp[e], mats, lt, l, ka, seed, ids[e], (uint32_t)e) : 0;
        if (vis)
            vis[e] = (uint8_t)(q ? 2 : 0); /* 2 until the flush finds it lit */
    }
    sb_flush(b);
    float inv = 1.0f / (float)(area ? ka * ka : 1);
    if (area && cnt) {
        /* penumbrae: where some of the ka x ka rays found the light and some
         * did not, (2 ka)^2 more rays from a second stream; the estimate is
         * the mean of all 5 ka^2 */
        int kb = ka < 32 ? 2 * ka : 64;
        b->nlit = NULL; /* the counts are final: the flushes below must not touch them */
        for (size_t e = 0; e < n; e++) {
            if (!samp[e] || cnt[e] == 0 || cnt[e] >= (uint16_t)(ka * ka))
                continue;
            sb_light(b, samp[e], mats, lt, (uint64_t)l | (1ull << 32), kb, seed, ids[e], (uint32_t)e);
            cnt[e] = UINT16_MAX; /* refined */
        }
        sb_flush(b);
        b->eacc = NULL;
        for (size_t e = 0; e < n; e++) {
            float sc = cnt[e] == UINT16_MAX ? 1.0f / (float)(ka * ka + kb * kb) : inv;
            out[e] = gi_scale(acc[e], sc);
            if (eout)
                eout[e] *= sc;
        }
        return;
    }
    b->eacc = NULL;
    for (size_t e = 0; e < n; e++) {
        out[e] = gi_scale(acc[e], inv);
        /* lit: a ray found the light (its irradiance, where asked for: a
         * lobe that reflects none of it still sends the ray, sb_light) */
        if (vis && vis[e] && (eout ? eout[e] > 0.0f : gi_maxc(acc[e]) > 0.0f))
            vis[e] = 1;
        if (eout)
            eout[e] *= inv;
    }
}

/* Indirect light of one pixel sample: the diffuse lobe takes the interpolated
 * irradiance, kd E / pi; the glossy lobe takes ks (A E / pi + B b_t . t), the
 * lobe integrated against incident radiance linear in direction
 * (lobe_tables), b_t from the gathering points' gradients (gpt, NULL: 0). */
static inline gi_vec3 indirect_sample(const gi_shade *sh, const ssurf *sf, const gi_material *mats, const float *gpe,
                                      const float *gpt, const gi_vec3 *gg, const float *enb)
{
    const gi_material *m = &mats[sf->material];
    float e[3] = {0, 0, 0}, tg[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    gi_bsdf b;
    gi_bsdf_init(&b, m, gi_mul(gi_v3p(m->base_color), gi_v3p(sf->texel)));
    int glossy = gi_maxc(b.ks) > 0.0f;
    for (int q = 0; q < sf->npairs; q++) {
        const float *g = gpe + 3 * (size_t)sf->gp[q];
        e[0] += sf->w[q] * g[0];
        e[1] += sf->w[q] * g[1];
        e[2] += sf->w[q] * g[2];
        if (glossy && gpt) {
            const float *t = gpt + 9 * (size_t)sf->gp[q];
            for (int c = 0; c < 9; c++)
                tg[c] += sf->w[q] * t[c];
        }
    }
    if (enb) { /* the sample's near field (nf_prepare), added to the rest */
        e[0] = gi_fmaxf(e[0], 0.0f) + enb[0];
        e[1] = gi_fmaxf(e[1], 0.0f) + enb[1];
        e[2] = gi_fmaxf(e[2], 0.0f) + enb[2];
    }
    gi_vec3 E = gi_scale(gi_v3(gi_fmaxf(e[0], 0.0f), gi_fmaxf(e[1], 0.0f), gi_fmaxf(e[2], 0.0f)), GI_INV_PIf);
    gi_vec3 out = gi_mul(b.kd, E);
    if (glossy && gg) {
        out = gi_add(out, gi_mul(b.ks, *gg)); /* the gathered lobe */
    } else if (glossy) {
        gi_vec3 n = gi_v3p(sf->ns), wo = gi_v3p(sf->wo);
        float co = gi_dot(n, wo);
        float A, B;
        lobe_lookup(sh, b.exponent, co, &A, &B);
        gi_vec3 r = gi_reflect(wo, n);
        gi_vec3 rt = gi_sub(r, gi_scale(n, gi_dot(r, n)));
        float lt = gi_len(rt);
        gi_vec3 gl = gi_scale(E, A);
        if (gpt && lt > 1e-6f) {
            rt = gi_scale(rt, 1.0f / lt);
            gl.x += B * (tg[0] * rt.x + tg[1] * rt.y + tg[2] * rt.z);
            gl.y += B * (tg[3] * rt.x + tg[4] * rt.y + tg[5] * rt.z);
            gl.z += B * (tg[6] * rt.x + tg[7] * rt.y + tg[8] * rt.z);
        }
        gl = gi_v3(gi_fmaxf(gl.x, 0.0f), gi_fmaxf(gl.y, 0.0f), gi_fmaxf(gl.z, 0.0f));
        out = gi_add(out, gi_mul(b.ks, gl));
    }
    return out;
}

/* Glossy gathers are drawn from a mixture of GI_SHADE_GLOSSY_C Phong lobes
 * about the mirror direction, of exponents m / 3, m and 3 m (an equal share
 * of the rays each), and weighted for the material's exponent n by
 * f_n / p_mix: p_mix = sum_c (m_c + 1) cos^m_c(a) / (2 pi C), the balance
 * heuristic over the components. One draw then serves exponents from
 * GI_SHADE_GLOSSY_LO to GI_SHADE_GLOSSY_HI times m, where the weights keep
 * at least ~40% of the rays' worth ((int f)^2 / int f^2 / p; 88% at n = m),
 * so a metal's roughness moved by up to ~1.6x either way (0.4 -> 0.25 or
 * 0.65) reweights the rays rather than tracing new ones. One lobe drawn at
 * n / 1.4 served 0.46 to 2.1 times n (roughness 0.3: 0.26 to 0.35), and a
 * larger change traced ~1.1 M rays again. Sponza, 640 x 480, a metal floor
 * at roughness 0.4, then 0.3, 0.33, 0.5, 0.6, 0.2, 0.25, against gathers
 * of 256 rays at every pixel (nrmse of the frame; splat ms, one run): one
 * lobe 0.0126, 0.0223, 0.0188, 0.0119, 0.0119, 0.0195, 0.0210 (440, 44,
 * 488, 485, 312, 334 ms after the first); the mixture 0.0131, 0.0233,
 * 0.0195, 0.0145, 0.0126, 0.0217, 0.0275 (29, 33, 34, 366, 293, 33 ms: only
 * 0.6 and 0.2 draw again). Spread 4 instead of 3: 0.0137 ... 0.0310. */
#define GI_SHADE_GLOSSY_C 3
#ifndef GI_SHADE_GLOSSY_SPREAD
#define GI_SHADE_GLOSSY_SPREAD 3.0f
#endif
#define GI_SHADE_GLOSSY_LO 0.25f
#define GI_SHADE_GLOSSY_HI 6.0f

/* the mixture's density in cos a, times 2 pi (see above); nc components */
static double glossy_pmix(double m, double lca, int nc)
{
    /* from the cosine's log (lca): exp where pow took ~7% of a first metal
     * frame (three a ray) */
    if (nc == 1)
        return (m + 1.0) * exp(m * lca);
    double sum = 0.0, mc = m;
    for (int c = 0; c < nc / 2; c++)
        mc /= (double)GI_SHADE_GLOSSY_SPREAD;
    for (int c = 0; c < nc; c++, mc *= (double)GI_SHADE_GLOSSY_SPREAD)
        sum += (mc + 1.0) * exp(mc * lca);
    return sum / (double)nc;
}

/* The glossy gather of sample sf (index i): sh->gr rays from the mixture
 * of lobes about exponent ex (above), each traced to the surface it hits
 * and mapped to a key by o->key_at; rays below the surface or into nothing
 * read no key. Ray j belongs to component j % C: its cosine's power
 * stratified over the component's rays, its azimuth a golden-ratio sequence
 * rotated at random (per sample and component). */
static int glossy_nrays(const gi_shade *sh, float n);
static void glossy_gather(gi_shade *sh, const ssurf *sf, size_t i, size_t gq, float ex, const gi_shade_opts *o)
{
    const int gr = glossy_nrays(sh, ex), nc = gr >= GI_SHADE_GLOSSY_C ? GI_SHADE_GLOSSY_C : 1;
    uint32_t *gk = sh->gkey + gq * (size_t)sh->gr;
    float *gc = sh->gcos + gq * (size_t)sh->gr, *gca = sh->gca + gq * (size_t)sh->gr;
    for (int j = gr; j < sh->gr; j++) {
        gk[j] = GI_HVDS_NO_KEY;
        gc[j] = 0.0f;
        gca[j] = 0.0f;
    }
    gi_vec3 n = gi_v3p(sf->ns), ng = gi_v3p(sf->ng), wo = gi_v3p(sf->wo), p = gi_v3p(sf->p);
    gi_vec3 r = gi_reflect(wo, n), t, bt;
    gi_basis(r, &t, &bt);
    gi_rng rng;
    gi_rng_seed(&rng, o->seed ^ 0x6c055eedull, (uint64_t)i, 0);
    float rot[GI_SHADE_GLOSSY_C], mcs[GI_SHADE_GLOSSY_C];
    for (int c = 0; c < nc; c++) {
        rot[c] = gi_rng_float(&rng);
        mcs[c] = ex * powf(GI_SHADE_GLOSSY_SPREAD, (float)(c - nc / 2));
    }
    gi_vec3 ro[16], rd[16];
    gi_hit hit[16];
    uint8_t found[16];
    int slot[16], nq = 0;
    for (int j = 0; j < gr; j++) {
        gk[j] = GI_HVDS_NO_KEY;
        gc[j] = 0.0f;
        const int c = j % nc, tj = j / nc, nj = (gr - c + nc - 1) / nc; /* its index and count in the component */
        const float mc = mcs[c];
        float u1 = ((float)tj + gi_rng_float(&rng)) / (float)nj;
        float u2 = (float)tj * 0.618034f + rot[c];
        u2 -= floorf(u2);
        float ca = powf(u1, 1.0f / (mc + 1.0f)), sa = sqrtf(gi_fmaxf(0.0f, 1.0f - ca * ca));
        float phi = 2.0f * GI_PIf * u2;
        const double lca = log((double)ca); /* -inf at ca = 0: weights 0 */
        gca[j] = (float)lca;
        gi_vec3 d = gi_norm(gi_to_world(gi_v3(sa * cosf(phi), sa * sinf(phi), ca), t, bt, r));
        float cosi = gi_dot(n, d);
        if (cosi > 0.0f && gi_dot(ng, d) > 0.0f) {
            /* the cosine over the mixture's density: glossy_reweight
             * multiplies in the lobe */
            double pm = glossy_pmix(ex, lca, nc);
            gc[j] = pm > 0.0 ? (float)((double)cosi / pm) : 0.0f;
            if (gc[j] > 0.0f) {
                ro[nq] = gi_rt_offset(p, ng, d);
                rd[nq] = d;
                slot[nq++] = j;
            }
        }
        if (nq == 16 || (j == gr - 1 && nq > 0)) {
            gi_rt_intersect_n(sh->rt, nq, ro, rd, 0.0f, hit, found);
            float hp[16 * 3], hh[16 * 3];
            int hs_slot[16], nh = 0;
            for (int q = 0; q < nq; q++) {
                if (!found[q])
                    continue;
                gi_surface hs;
                gi_rt_surface(sh->rt, &hit[q], &hs);
                /* the side the ray arrives on */
                gi_vec3 hn = gi_dot(hs.ng, rd[q]) < 0.0f ? hs.ng : gi_neg(hs.ng);
                gi_vec3 hsn = gi_dot(hs.ns, hn) < 0.0f ? gi_neg(hs.ns) : hs.ns;
                gi_v3store(hp + 3 * nh, hs.p);
                gi_v3store(hh + 3 * nh, hsn);
                hs_slot[nh++] = slot[q];
            }
            /* the keys of the packet's hits, looked up together */
            uint32_t keys[16];
            o->key_at(o->key_ctx, (size_t)nh, hp, hh, keys);
            for (int q = 0; q < nh; q++)
                gk[hs_slot[q]] = keys[q];
            nq = 0;
        }
    }
    sh->gexp[gq] = ex;
    sh->gnr[gq] = (uint16_t)gr;
    __atomic_add_fetch(&sh->gdrawn, 1, __ATOMIC_RELAXED);
    __atomic_add_fetch(&sh->grays, (size_t)gr, __ATOMIC_RELAXED);
    sh->gtgt[gq] = 0.0f; /* its weights are to be made */
    sh->gpix[gq] = (uint32_t)i;
}

/* A lobe of exponent n that spans 1 / sqrt(n + 2) radians, about, blurs
 * more than a window twice as wide (2 x 2 gs - 1 pixels each way) when that
 * half-width's angle seen from the camera is less than this times that: such a
 * lobe gathers on a grid twice as coarse, over that window (see the
 * splat). With --glossy-stride 2 at 640 x 480 and a vertical field of 60
 * degrees, exponents up to 562 (roughness 0.245 and up; 0.3: 245, 0.4:
 * 76); at 320 x 240 up to 139 (0.35), at 64 x 48 up to 3.6. Sponza, 640 x 480, a sun and a
 * lamp, the floor made metal, its first frame against 256-ray gathers at
 * every pixel (nrmse of the frame; grid 2 over 7 x 7 -> grid 4 over 15 x 15,
 * its fine pixels gathering where the coarse are few, GI_SHADE_GLOSSY_FEW):
 * roughness 0.25 0.0315 -> 0.0324, 0.4 0.0199 -> 0.0201, 0.6 0.0189 ->
 * 0.0187, the gathers ~290 -> ~95 ms; a sharper lobe loses (0.15: 0.0107 ->
 * 0.0193 on the coarse grid alone). Its columns and walls made metal
 * instead (roughness 0.3, 0.5): 0.0680, 0.0192 -> 0.0662, 0.0219, 43% of
 * the gathers (10.4 k of 24.0 k); the window blurs the faces' changes
 * there, where a coarse grid alone (7.8 k) read 0.0241 at 0.5. */
#define GI_SHADE_GLOSSY_WIDE 0.4f
/* where fewer of the coarse grid's gathers than this lie on a pixel's
 * surface within its window, the finer grid's pixel gathers too (the
 * columns above at 0.5: 4 0.0237, 8 0.0219, 12 0.0218 for 7.7 k, 10.4 k,
 * 15.4 k gathers) */
#ifndef GI_SHADE_GLOSSY_FEW
#define GI_SHADE_GLOSSY_FEW 8
#endif
/* The weight, along one axis, of a glossy gather d pixels from the pixel
 * that averages the gathers within its window (R: the window's half-width,
 * G: the spacing of its material's grid): 1 out to R + 1/2 - G/2, then
 * down to 0 at R + 1/2 + G/2, the window's box smoothed by one grid
 * spacing. Over a grid of spacing G the weights then sum to the same for
 * every pixel, and a pixel one step further takes in a gather by degrees.
 * With a plain box the gathers came in and went out all at once, every
 * G-th pixel: a metal's reflection was a mosaic of G x G blocks. G = 1 is
 * the box. */
static inline float glossy_wt(int d, int R, int G)
{
    float a = (float)(d < 0 ? -d : d);
    float v = ((float)R + 0.5f - a) / (float)G + 0.5f;
    return v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v;
}
/* The slot of the grid pixel at (fx, fy) of the grid (gw a row): those at
 * even fx and fy first, (gw + 1) / 2 a row, ncoarse of them; then every
 * grid pixel at fy gw + fx after them (the even ones' places unused) */
static inline size_t grid_slot(size_t fx, size_t fy, size_t gw, size_t ncoarse)
{
    return !((fx | fy) & 1) ? (fy / 2) * ((gw + 1) / 2) + fx / 2 : ncoarse + fy * gw + fx;
}

/* Slots for cap gathers, those below cap_gexp kept; the new ones empty.
 * 0: out of memory (the arrays as they were) */
static int glossy_slots(gi_shade *sh, size_t cap)
{
    const size_t old = sh->cap_gexp, gr = (size_t)sh->gr;
    if (cap <= old)
        return 1;
    int ok = 1;
#define GROW(f, n)                                      \
    do {                                                \
        void *t_ = realloc(sh->f, (n) * sizeof *sh->f); \
        if (t_)                                         \
            sh->f = t_;                                 \
        else                                            \
            ok = 0;                                     \
    } while (0)
    GROW(gkey, cap * gr);
    GROW(gcos, cap * gr);
    GROW(gca, cap * gr);
    GROW(gw, cap * gr);
    GROW(gexp, cap);
    GROW(gnr, cap);
    GROW(gtgt, cap);
    GROW(gpix, cap);
#undef GROW
    if (!ok)
        return 0;
    for (size_t q = old; q < cap; q++) {
        sh->gexp[q] = 0.0f;
        sh->gnr[q] = 0;
        sh->gtgt[q] = 0.0f;
        sh->gpix[q] = UINT32_MAX;
    }
    sh->cap_gexp = cap;
    return 1;
}

/* The rays of a gather drawn for exponent n: all of --glossy-rays, or 4/9
 * of them (16 of 36) for a lobe narrower than the window its gathers are
 * averaged over (sh->gsharp: a width of ~1 / sqrt(n + 2) radians against
 * the window's 2 GI_SHADE_GLOSSY_WIN + 1 pixels seen from the camera; at
 * 640 x 480 with a vertical field of 60 degrees, exponents from 3540,
 * roughness 0.153 and less). There the
 * window's gathers each see a part of what the pixels reflect, and the
 * keys they read change little within a lobe. Sponza, 640 x 480, the floor
 * made metal, its first frame against 256-ray gathers at every pixel
 * (nrmse; the frame's ms, one run each), 36 -> 16 rays: roughness 0.08
 * 0.0094 -> 0.0103 (304 -> 183), 0.12 0.0092 -> 0.0102 (318 -> 184), 0.15
 * 0.0107 -> 0.0136 (355 -> 221); beyond the line 0.2 would lose 0.0244 ->
 * 0.0298 and 0.24 0.0313 -> 0.0411. */
static int glossy_nrays(const gi_shade *sh, float n)
{
    if (sh->gr < GI_SHADE_GLOSSY_C || !(n >= sh->gsharp))
        return sh->gr;
    int nr = (4 * sh->gr + 8) / 9;
    return nr > GI_SHADE_GLOSSY_C ? nr : GI_SHADE_GLOSSY_C;
}

/* with fewer rays than components, one lobe drawn at n / 1.4, serving
 * 0.65 to 3 times that (the weights' worth >= ~55%) */
#define GI_SHADE_GLOSSY_DRAW1 1.4f
static int glossy_reusable(const gi_shade *sh, float m, int nr, float n)
{
    const float lo = sh->gr >= GI_SHADE_GLOSSY_C ? GI_SHADE_GLOSSY_LO : 0.65f;
    const float hi = sh->gr >= GI_SHADE_GLOSSY_C ? GI_SHADE_GLOSSY_HI : 3.0f;
    return m > 0.0f && n >= lo * m && n <= hi * m && nr >= glossy_nrays(sh, n);
}

/* The weights of slot q's rays for exponent n (glossy_reusable):
 * cos_i f_n / p_mix, with f_n = (n + 2) cos^n(a) / (2 pi). */
static void glossy_reweight(gi_shade *sh, size_t q, float n)
{
    const size_t gr = (size_t)sh->gr;
    const float *gc = sh->gcos + q * gr, *gca = sh->gca + q * gr;
    float *gw = sh->gw + q * gr;
    double sc = (double)n + 2.0;
    for (int r = 0; r < sh->gnr[q]; r++)
        gw[r] = gc[r] > 0.0f ? (float)((double)gc[r] * sc * exp((double)n * (double)gca[r])) : 0.0f;
    sh->gtgt[q] = n;
}

/* Sample i's gather (in slot q) and weights ready for exponent n: drawn
 * again only when the slot holds no rays of i's that can serve n */
static void glossy_ready(gi_shade *sh, const ssurf *sf, size_t i, size_t q, float n, const gi_shade_opts *o)
{
    if (sh->gpix[q] != (uint32_t)i || !glossy_reusable(sh, sh->gexp[q], sh->gnr[q], n))
        glossy_gather(sh, sf, i, q, sh->gr >= GI_SHADE_GLOSSY_C ? n : n / GI_SHADE_GLOSSY_DRAW1, o);
    if (sh->gtgt[q] != n)
        glossy_reweight(sh, q, n);
}

/* The lobe's reflection of the radiance the gather in slot q reads, per
 * unit ks: the mean of L times the rays' weights (glossy_reweight). */
static gi_vec3 glossy_term(const gi_shade *sh, size_t q, const float *kflux)
{
    const uint32_t *gk = sh->gkey + q * (size_t)sh->gr;
    const float *gc = sh->gw + q * (size_t)sh->gr;
    const int nr = sh->gnr[q];
    double a[3] = {0, 0, 0};
    for (int r = 0; r < nr; r++) {
        uint32_t k = gk[r];
        if (k == GI_HVDS_NO_KEY)
            continue;
        double c = (double)gc[r] * sh->h->key_scale[k];
        a[0] += c * kflux[3 * (size_t)k];
        a[1] += c * kflux[3 * (size_t)k + 1];
        a[2] += c * kflux[3 * (size_t)k + 2];
    }
    double sc = nr > 0 ? 1.0 / (double)nr : 0.0;
    return gi_v3((float)(a[0] * sc), (float)(a[1] * sc), (float)(a[2] * sc));
}

/* One sample's indirect light: from its packed record when its material
 * is diffuse (the common case), else from its ssurf. */
static inline gi_vec3 splat_rec(const gi_shade *sh, const srec *r, const ssurf *sf, const uint8_t *glossy,
                                const gi_material *mats, const float *gpe, const float *gpt)
{
    if (r->material == UINT32_MAX)
        return gi_v3(0, 0, 0);
    if (glossy[r->material])
        return indirect_sample(sh, sf, mats, gpe, gpt, NULL, NULL);
    const gi_material *m = &mats[r->material];
    float e[3] = {0, 0, 0};
    int32_t wsum = 0;
    for (int q = 0; q < GI_SHADE_K; q++) {
        const float *g = gpe + 3 * (size_t)r->gp[q];
        float wq = (float)r->w[q];
        wsum += r->w[q];
        e[0] += wq * g[0];
        e[1] += wq * g[1];
        e[2] += wq * g[2];
    }
    if (wsum <= 0)
        return gi_v3(0, 0, 0);
    gi_bsdf b;
    gi_bsdf_init(&b, m, gi_mul(gi_v3p(m->base_color), gi_v3p(r->texel)));
    gi_vec3 E = gi_v3(gi_fmaxf(e[0], 0.0f), gi_fmaxf(e[1], 0.0f), gi_fmaxf(e[2], 0.0f));
    return gi_mul(b.kd, gi_scale(E, GI_INV_PIf / (float)wsum));
}

/* *out = v, the indirect light of a diffuse sample whose texel is ts, for
 * one on the same surface and material whose texel is tq (edge_pixel): a
 * diffuse sample's light, near field included, is linear in its texel.
 * Returns 0 when a channel of ts is 0 where tq's is not. */
static inline int texel_scaled(gi_vec3 v, const float tq[3], const float ts[3], gi_vec3 *out)
{
    float f[3];
    for (int c = 0; c < 3; c++) {
        if (tq[c] == ts[c])
            f[c] = 1.0f;
        else if (ts[c] > 0.0f)
            f[c] = tq[c] / ts[c];
        else
            return 0;
    }
    *out = gi_v3(v.x * f[0], v.y * f[1], v.z * f[2]);
    return 1;
}

/* Light lt at aa*aa - 1 more points of pixel (x, y)'s plane (stratified
 * around the centre sample, as for geometric edges): replaces the centre
 * sample's share of the light by the average over all aa*aa points. acc:
 * NE + 1 scratch vectors. */
/* 1 if pixel pix's centre sample faces light lt (a point, spot or
 * directional light): where it sent the light no ray, the light's cone left
 * it dark. */
static int cone_dark(const gi_shade *sh, const gi_light *lt, size_t pix)
{
    const ssurf *c = &sh->sf[pix];
    if (!sh->svalid[pix] || lt->type != GI_LIGHT_SPOT)
        return 0;
    gi_vec3 wi = gi_norm(gi_sub(gi_v3p(lt->position), gi_v3p(c->p)));
    return gi_dot(gi_v3p(c->ng), wi) > 0.0f && gi_dot(gi_v3p(c->ns), wi) > 0.0f;
}

/* Whether a pixel of centre visibility v0 (cone_dark: c0) and its neighbour
 * q of visibility vq see a shadow's edge between them (lit and shadowed), a
 * terminator (lit and facing away from the light), or a spot cone's (one
 * inside the cone, lit or shadowed, the other facing the spot outside it). */
static inline int vis_edge(unsigned v0, int c0, unsigned vq, const gi_shade *sh, const gi_light *lt, size_t q)
{
    if ((v0 == 1u && vq == 2u) || (v0 == 2u && vq == 1u))
        return 1;
    /* lit beside a surface that sent no ray: it faces away (a terminator)
     * or lies outside a spot's cone */
    if ((v0 == 1u && vq == 0u) || (v0 == 0u && vq == 1u))
        return sh->svalid[q];
    if (v0 && vq == 0u)
        return cone_dark(sh, lt, q);
    return v0 == 0u && c0 && vq;
}

/* The 8 neighbours of a pixel, in the order of shadow_edge_pixel's border
 * bits: left, right, above, below, then the corners above left, above right,
 * below left, below right. */
static const int nb8[8][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}, {-1, -1}, {1, -1}, {-1, 1}, {1, 1}};

/* Bits of the neighbours (nb8) that border the cell (cx, cy) of an aa x aa grid. */
static unsigned border_bits(int cx, int cy, int aa)
{
    unsigned m = 0;
    int l = cx == 0, r = cx == aa - 1, u = cy == 0, d = cy == aa - 1;
    m |= (unsigned)l << 0 | (unsigned)r << 1 | (unsigned)u << 2 | (unsigned)d << 3;
    m |= (unsigned)(u && l) << 4 | (unsigned)(u && r) << 5 | (unsigned)(d && l) << 6 | (unsigned)(d && r) << 7;
    return m;
}

/* *lit and *dark (may be NULL): bit k (nb8) set when a sample in the cells
 * along the border with neighbour k found the light, or sent a ray that was
 * blocked. */
static void shadow_edge_pixel(const gi_shade *sh, sbatch *b, const gi_camera *cam, int w, int h, int x, int y,
                              const gi_light *lt, size_t l, const gi_material *mats, const gi_shade_opts *o,
                              gi_vec3 *acc, float *out, unsigned *lit, unsigned *dark)
{
    /* two more points per side than the geometric edges (5 x 5 at --aa 3): a
     * hard shadow's edge crosses the pixel at full contrast, where 3 x 3
     * points leave steps of 1/9. Sponza, 640x480: sun 0.0707 -> 0.0692,
     * sun-moved 0.1435 -> 0.1404 nrmse for 2-6 ms per light; 7 x 7 gained
     * 0.0006 more for another 5-8 ms. */
    const int aa = sh->paa + 2, NE = aa * aa - 1;
    size_t pix = (size_t)y * (size_t)w + (size_t)x;
    const ssurf *c = &sh->sf[pix];
    gi_vec3 p = gi_v3p(c->p), ng = gi_v3p(c->ng), eye = gi_v3p(cam->position);
    float pn = gi_dot(gi_sub(p, eye), ng);
    ssurf sub = *c;
    sub.nvar = c->nvar / (float)(aa * aa);
    gi_rng r;
    gi_rng_seed(&r, 0xed9e, pix, 0);
    b->acc = acc;
    enum { NC = (GI_SHADE_AA_MAX + 2) * (GI_SHADE_AA_MAX + 2) };
    uint8_t sent[NC], found[NC];
    gi_vec3 cro[NC], crd[NC];
    gi_hit chit[NC];
    float cfx[NC], cfy[NC];
    for (int j = 0, cell = 0; cell < aa * aa; cell++) {
        if (cell == aa * aa / 2)
            continue;
        float fx = (float)x + ((float)(cell % aa) + gi_rng_float(&r)) / (float)aa;
        float fy = (float)y + ((float)(cell / aa) + gi_rng_float(&r)) / (float)aa;
        gi_camera_frame_ray(&sh->cf, fx, fy, &cro[j], &crd[j]);
        cfx[j] = fx;
        cfy[j] = fy;
        j++;
    }
    /* The points are where the camera rays meet the surface, found by
     * Embree (a ray that finds a surface off the centre's plane shades that
     * surface; the plane stands in only where a ray finds nothing, or a
     * surface that cannot be shaded). On a curved face the plane leaves the surface within the
     * pixel, and on a concave one (Sponza's arches, seen from below) its
     * points lie behind the surface, which blocks their shadow rays: lit
     * pixels beside a shadow's edge lost ~40% of their sunlight (Sponza
     * sun-b, 320 x 240: 62 cd/m2 where the path tracer and 4 x 4 samples of
     * the real surface find 108; the frame's direct part 0.0701 -> 0.0636
     * nrmse against 512 spp, the frame 0.1199 -> 0.1159). */
    const float fp = 2.0f * tanf(0.5f * cam->yfov) / (float)h * c->tsurf;
    /* Where the centre's 4 neighbours lie on its plane, so does the pixel
     * (within their diamond): the plane's points are the surface's, and no
     * ray is needed (Sponza: most shadow edges fall on floors and walls;
     * tracing the rays at every such pixel cost light moves 5-12 ms) */
    int flat = 1;
    const int nbx[4] = {-1, 1, 0, 0}, nby[4] = {0, 0, -1, 1};
    for (int k = 0; k < 4 && flat; k++) {
        int xx = x + nbx[k], yy = y + nby[k];
        if (xx < 0 || yy < 0 || xx >= w || yy >= h)
            continue;
        const ssurf *q = &sh->sf[(size_t)yy * (size_t)w + (size_t)xx];
        if (!q->valid || q->tri == c->tri)
            continue;
        float dn = q->ng[0] * c->ng[0] + q->ng[1] * c->ng[1] + q->ng[2] * c->ng[2];
        float off = fabsf((q->p[0] - c->p[0]) * c->ng[0] + (q->p[1] - c->p[1]) * c->ng[1] +
                          (q->p[2] - c->p[2]) * c->ng[2]);
        flat = dn >= 0.99999f && off <= 1e-3f * fp;
    }
    if (flat)
        memset(found, 0, (size_t)NE);
    else
        gi_rt_intersect_n(sh->rt, NE, cro, crd, 0.0f, chit, found);
    for (int j = 0; j < NE; j++) {
        acc[j] = gi_v3(0, 0, 0);
        gi_vec3 ro = cro[j], rd = crd[j];
        int on = 0;
        if (found[j]) {
            gi_surface hs;
            gi_rt_surface(sh->rt, &chit[j], &hs);
            gi_vec3 hn = gi_dot(hs.ng, rd) > 0.0f ? gi_neg(hs.ng) : hs.ng;
            if (gi_dot(hn, ng) >= 0.95f && fabsf(gi_dot(gi_sub(hs.p, p), ng)) <= GI_SHADE_STEP * fp) {
                gi_v3store(sub.p, hs.p);
                gi_v3store(sub.ng, hn);
                /* with the surface's own shading normal there (oriented as
                 * in fill_sample) */
                gi_vec3 hsn = gi_dot(hs.ns, hn) < 0.0f ? gi_neg(hs.ns) : hs.ns;
                gi_v3store(sub.ns, gi_dot(hsn, rd) < 0.0f ? hsn : hn);
                on = 1;
            } else {
                /* The ray sees another surface: a face thinner than a pixel
                 * that no centre sample saw, so the pixel is no edge pixel
                 * (a ledge's top between the wall above and the ledge's
                 * front). The centre's plane stood in for it and took the
                 * light at the wall's angle: a sunlit top read as dark as
                 * the wall (mkledge.py under a high sun, direct light 0.108
                 * -> 0.077 nrmse against 512 spp; Sponza seen from the
                 * upper gallery, 320 x 240, a moulding's pixel 134 cd/m2
                 * where the path tracer finds 244). It is shaded as itself,
                 * its texel at the point (a footprint of 1 / aa pixel). */
                ssurf other;
                fill_sample(sh, cam, w, h, chit[j].tri, chit[j].u, chit[j].v, cfx[j], cfy[j], 1.0f / (float)aa,
                            sh->ptexf > 0 ? 0 : sh->ptexf, 0, &other);
                if (other.valid) {
                    sent[j] = (uint8_t)(sb_light(b, &other, mats, lt, l, 1, o->seed, pix * 64u + 1u + (uint64_t)j,
                                                 (uint32_t)j) > 0);
                    continue;
                }
            }
        }
        float dn = gi_dot(rd, ng), t = pn / dn;
        if (!on && dn < 0.0f && t > 0.0f && isfinite(t)) {
            /* put back on the plane: o + t d carries the rounding of the
             * camera's distance, which gi_rt_offset's few ulps of the
             * point's own coordinates do not cover. A wall at x = 0 seen
             * from 450 m (the Cornell box scaled by 1000): points 3e-5 m
             * behind it, whose shadow rays it blocked (shadow-edge pixels
             * at half their light) */
            gi_vec3 q = gi_add(ro, gi_scale(rd, t));
            q = gi_sub(q, gi_scale(ng, gi_dot(gi_sub(q, p), ng)));
            gi_v3store(sub.p, q);
            gi_v3store(sub.ng, ng);
            memcpy(sub.ns, c->ns, sizeof sub.ns);
            on = 1;
        }
        if (on) {
            gi_v3store(sub.wo, gi_neg(rd));
            sent[j] = (uint8_t)(sb_light(b, &sub, mats, lt, l, 1, o->seed, pix * 64u + 1u + (uint64_t)j,
                                         (uint32_t)j) > 0);
        } else {
            /* the plane is not seen there: keep the centre sample's value */
            sent[j] = (uint8_t)(sb_light(b, c, mats, lt, l, 1, o->seed, pix * 64u, (uint32_t)j) > 0);
        }
    }
    acc[NE] = gi_v3(0, 0, 0);
    sb_light(b, c, mats, lt, l, 1, o->seed, pix * 64u, (uint32_t)NE);
    sb_flush(b);
    if (lit && dark) {
        *lit = *dark = 0;
        for (int j = 0, cell = 0; cell < aa * aa; cell++) {
            if (cell == aa * aa / 2)
                continue;
            if (sent[j]) {
                unsigned m = border_bits(cell % aa, cell / aa, aa);
                if (gi_maxc(acc[j]) > 0.0f)
                    *lit |= m;
                else
                    *dark |= m;
            }
            j++;
        }
    }
    /* the pixel holds the centre's contribution (acc[NE], exact re-trace of
     * the same ray); swap it for the mean of all aa*aa */
    gi_vec3 sum = gi_v3(0, 0, 0);
    for (int j = 0; j <= NE; j++)
        sum = gi_add(sum, acc[j]);
    gi_vec3 delta = gi_sub(gi_scale(sum, 1.0f / (float)(NE + 1)), acc[NE]);
    out[0] += delta.x;
    out[1] += delta.y;
    out[2] += delta.z;
}

/* Direct light of one light into C (3 floats per pixel): the mean of each
 * pixel's samples (edge pixels: with their extra samples), then the shadow
 * edges refined. mask (NULL: every pixel): only pixels with mask[pix]. vis:
 * per pixel (ss == 1, not an area light; else NULL), kept for later masked
 * passes. Returns 0, or 1 when out of memory. */
/* The refinement samples of edge pixel e: GI_SHADE_XN Embree camera rays
 * jittered over a GI_SHADE_XK^2 grid of the pixel, each with its texel taken
 * from the pixel's own samples on the same surface, else the texture's value
 * at the point.
 * NULL when out of memory (the pixel then keeps its aa x aa estimate). */
/* o->texel: the texture's value (unit base-colour factor) at the point hit
 * found, as fill_sample's texf 0 gives it */
static void point_texel(const gi_shade *sh, const gi_hit *hit, ssurf *o)
{
    gi_surface hs;
    gi_rt_surface(sh->rt, hit, &hs);
    gi_material unit = sh->s->materials[o->material];
    unit.base_color[0] = unit.base_color[1] = unit.base_color[2] = 1.0f;
    gi_scene_base_color(sh->s, &unit, hs.uv0, hs.uv1, o->texel);
}

static ssurf *extra_samples(gi_shade *sh, const gi_camera *cam, int w, int h, size_t e)
{
    if (sh->xsf[e])
        return sh->xsf[e];
    /* the samples, then (with coverage shares) each one's group: the index
     * of the pixel's nearest sample on its surface (255: none) */
    ssurf *x = malloc(GI_SHADE_XN * sizeof *x + GI_SHADE_XN);
    if (!x)
        return NULL;
    uint8_t *grp = (uint8_t *)(x + GI_SHADE_XN);
    size_t pix = sh->epix[e];
    int px = (int)(pix % (size_t)w), py = (int)(pix / (size_t)w);
    float pix_angle = 2.0f * tanf(0.5f * cam->yfov) / (float)h, step = 1.0f / (float)GI_SHADE_XK;
    gi_rng r;
    gi_rng_seed(&r, 0x3e6e, pix, 0);
    float sfx[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX], sfy[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
    if (sh->ew)
        edge_positions(sh->paa, px, py, pix, sfx, sfy);
    /* the camera rays first, traced together (one coherent packet: a light
     * move that refines ~1,200 new Sponza pixels spent ~25 ms of CPU on
     * them one by one) */
    float xfx[GI_SHADE_XN], xfy[GI_SHADE_XN];
    gi_vec3 xro[GI_SHADE_XN], xrd[GI_SHADE_XN];
    gi_hit xhit[GI_SHADE_XN];
    uint8_t xfound[GI_SHADE_XN];
    for (int j = 0; j < GI_SHADE_XN; j++) {
        xfx[j] = (float)px + ((float)(j % GI_SHADE_XK) + gi_rng_float(&r)) * step;
        xfy[j] = (float)py + ((float)(j / GI_SHADE_XK) + gi_rng_float(&r)) * step;
        gi_camera_frame_ray(&sh->cf, xfx[j], xfy[j], &xro[j], &xrd[j]);
    }
    gi_rt_intersect_n(sh->rt, GI_SHADE_XN, xro, xrd, 0.0f, xhit, xfound);
    for (int j = 0; j < GI_SHADE_XN; j++) {
        ssurf *o = &x[j];
        float fx = xfx[j], fy = xfy[j];
        o->valid = 0;
        o->npairs = 0;
        o->tsurf = INFINITY;
        if (xfound[j]) /* the texel below */
            fill_sample(sh, cam, w, h, xhit[j].tri, xhit[j].u, xhit[j].v, fx, fy, step, -1, 0, o);
        int ok = o->valid;
        /* the texture's value at the point, looked up only where the tests
         * below consult it (a step between triangles) or no sample lends
         * one: most samples take the centre's or an edge sample's (its
         * memory latency was most of a new refinement's ~20 us of CPU) */
        int need = 0, have = 0;
        for (int q = 0; ok && q <= sh->ne; q++) {
            const ssurf *c = q < sh->ne ? &sh->esf[e * (size_t)sh->ne + (size_t)q] : &sh->sf[pix];
            (void)discontinuity_tx(sh->s, o, c, pix_angle, &need);
        }
        if (need) {
            point_texel(sh, &xhit[j], o);
            have = 1;
        }
        if (sh->ew) {
            int g = nearest_same_surface(sh, e, o, fx, fy, sfx, sfy, w, pix_angle);
            grp[j] = (uint8_t)(g < 0 ? 255 : g);
        }
        if (!ok)
            continue;
        int reused = 0;
        const ssurf *c0 = &sh->sf[pix];
        if (sh->ew && grp[j] < sh->ne) {
            const ssurf *c = &sh->esf[e * (size_t)sh->ne + (size_t)grp[j]];
            if (c->valid && !discontinuous(sh, o, c, pix_angle)) {
                memcpy(o->texel, c->texel, sizeof o->texel);
                reused = 1;
            }
        }
        if (!reused && c0->valid && !discontinuous(sh, o, c0, pix_angle)) {
            memcpy(o->texel, c0->texel, sizeof o->texel);
            reused = 1;
        }
        for (int q = 0; q < sh->ne && !reused; q++) {
            const ssurf *c = &sh->esf[e * (size_t)sh->ne + (size_t)q];
            if (c->valid && !discontinuous(sh, o, c, pix_angle)) {
                memcpy(o->texel, c->texel, sizeof o->texel);
                reused = 1;
            }
        }
        /* else the texture at the point: sixteen such samples average the
         * texture over the pixel's part */
        if (!reused && !have)
            point_texel(sh, &xhit[j], o);
    }
    sh->xsf[e] = x;
    return x;
}

static int light_pass(gi_shade *sh, const gi_camera *cam, int w, int h, const gi_light *lt, size_t l,
                      const gi_material *mats, const gi_shade_opts *o, int ka, const uint8_t *mask, float *C,
                      uint8_t *vis, float *ec, int threads)
{
    const size_t np = (size_t)w * (size_t)h;
    const int S = sh->pss * sh->pss, NE = sh->ne;
    if (S != 1 || !NE)
        ec = NULL;
    float tau = INFINITY; /* edge pixels with less contrast than this keep their centre sample */
    double tp[3], tp0 = gi_now();
    size_t nskip = 0, nref = 0, nnew = 0;
    float tau_ref = INFINITY; /* edge pixels with more contrast than this get refinement samples */
    size_t rowlen = (size_t)w * (size_t)S * 4; /* a band of rows (below) */
    size_t chunk = 64 * (size_t)(NE > GI_SHADE_XN ? NE : GI_SHADE_XN);
    size_t cap = (rowlen > chunk ? rowlen : chunk) + (size_t)NE + 1;
    int fail = 0;
    /* shadow edges followed in rounds (see below): a full pass only */
    uint8_t *spread = NULL;
    uint32_t *slist = NULL;
    size_t nspread = 0, nspread_all = 0, ncurv = 0;
    if (vis && !mask) {
        spread = calloc(np, 1);
        slist = malloc(np * sizeof *slist);
        if (!spread || !slist) {
            free(spread);
            free(slist);
            spread = NULL; /* without the rounds, as before */
            slist = NULL;
        }
    }
#pragma omp parallel num_threads(threads)
    {
        gi_rt_thread_init();
        sbatch *b = malloc(sizeof *b);
        gi_vec3 *acc = malloc(cap * sizeof *acc), *L = malloc(cap * sizeof *L), *L2 = malloc(cap * sizeof *L2);
        const ssurf **samp = malloc(cap * sizeof *samp);
        uint64_t *ids = malloc(cap * sizeof *ids);
        uint8_t *v = malloc(cap);
        uint16_t *cnt = malloc(cap * sizeof *cnt);
        float *ev = malloc(cap * sizeof *ev);
        int ok = b && acc && L && L2 && samp && ids && v && cnt && ev;
        if (!ok) {
#pragma omp atomic write
            fail = 1;
        } else {
            b->rt = sh->rt;
            b->n = 0;
            b->nlit = NULL;
            b->eacc = NULL;
        }
        /* bands of RB rows, their pixels in RB x RB tiles: a packet's 16
         * shadow rays leave a compact patch of the view, not a 16-pixel
         * strip (each pixel's S samples stay together and in order, so the
         * sums are the same) */
        const int RB = S == 1 ? 4 : 1;
#pragma omp for schedule(dynamic, 1)
        for (int y0 = 0; y0 < h; y0 += RB) {
            if (!ok)
                continue; /* every thread must reach the loop; the pass fails below */
            const int y1 = y0 + RB < h ? y0 + RB : h;
            size_t n = 0;
            for (int x0 = 0; x0 < w; x0 += RB)
                for (int y = y0; y < y1; y++)
                    for (int x = x0; x < x0 + RB && x < w; x++) {
                        size_t pix = (size_t)y * (size_t)w + (size_t)x;
                        for (int k = 0; k < S; k++, n++) {
                            const ssurf *sf = &sh->sf[(size_t)k * np + pix];
                            samp[n] = (!mask || mask[pix]) && sh->svalid[(size_t)k * np + pix] ? sf : NULL;
                            ids[n] = pix * 64u + (uint64_t)k;
                        }
                    }
            light_samples(b, samp, ids, n, lt, l, mats, ka, o->seed, acc, L, vis ? v : NULL, cnt, ec ? ev : NULL);
            for (size_t e = 0; e < n; e += (size_t)S) {
                size_t pix = (size_t)(ids[e] >> 6);
                if (mask && !mask[pix])
                    continue;
                if (ec)
                    ec[pix] = ev[e];
                gi_vec3 sum = gi_v3(0, 0, 0);
                for (int k = 0; k < S; k++)
                    sum = gi_add(sum, L[e + (size_t)k]);
                gi_v3store(C + 3 * pix, gi_scale(sum, 1.0f / (float)S));
                if (vis) /* a masked pass keeps the full pass's flag (below) */
                    vis[pix] = mask ? (uint8_t)(v[e] | (vis[pix] & VIS_SPREAD)) : v[e];
            }
        }
#pragma omp single
        tp[0] = gi_now();
        /* Edge pixels whose 5x5 neighbourhood of centre samples receives
         * nearly the same irradiance from this light, and whose own samples
         * all see one material and texel, keep their centre sample: the
         * pixel's coverage does not matter for this light there. The
         * threshold is a fraction of the light's mean irradiance over the
         * visible samples; it and the decisions use only the light and the
         * geometry, so a material change recomputes the same pixels.
         * Measured on Sponza (640x480): 40-60% of the edge pixels skip, 3-5 ms
         * per light; what it misses is sunlit slivers thinner than the
         * pixel spacing between shadowed centres (a 3x3 neighbourhood: +0.002
         * nrmse on sun-moved, 5x5: +0.0008, the other frames unchanged). */
        if (ec) {
#pragma omp single
            {
                double sum = 0.0;
                size_t nv = 0;
                for (size_t pix = 0; pix < np; pix++)
                    if (sh->svalid[pix]) {
                        sum += ec[pix];
                        nv++;
                    }
                if (nv && sum > 0.0) {
                    tau = (float)(GI_SHADE_EDGE_CONTRAST * sum / (double)nv);
                    /* area lights: their own jittered samples already
                     * average over the pixel's samples, and their estimate's
                     * noise would read as contrast */
                    if (o->edge_refine && !gi_light_has_area(lt))
                        tau_ref = (float)(o->refine_contrast * sum / (double)nv);
                }
            }
        }
        /* edge pixels: the centre sample (in C now) and NE more, averaged.
         * A rectangular light's rays only decide its shadow (the diffuse
         * part is Lambert's formula): each of the NE samples takes (ka / 2)^2
         * of them, so a pixel still traces several times the centre's ka^2
         * (Sponza, a 2 x 2 m panel at 320 x 240: direct 525 -> 211 ms, nrmse
         * 0.01968 -> 0.01973 against 1024 spp). A mesh light keeps ka^2:
         * with fewer, Sponza's glowing doors went 0.093 -> 0.109. */
        const int kae = lt->type == GI_LIGHT_AREA && NE >= 8 && ka >= 4 ? ka / 2 : ka;
        size_t nchunks = (sh->nedge + 63) / 64;
#pragma omp for schedule(dynamic, 1)
        for (size_t c = 0; c < nchunks; c++) {
            if (!ok)
                continue;
            size_t e0 = c * 64, e1 = e0 + 64 < sh->nedge ? e0 + 64 : sh->nedge;
            size_t n = (e1 - e0) * (size_t)NE;
            uint8_t skip[64];
            gi_vec3 cen[64]; /* the centre samples' light, for the refinement */
            size_t ns = 0;
            for (size_t e = e0; e < e1; e++) {
                skip[e - e0] = 0;
                if (!ec || sh->ehard[e] == 1)
                    continue;
                size_t pix = sh->epix[e];
                if (sh->ehard[e] == 2) {
                    /* across a crease: the light's unshadowed irradiance on
                     * the samples' normals against the centre's (Sponza
                     * sun-moved 0.1100 -> 0.1093 nrmse; most crease pixels
                     * see the two sides lit alike and still skip) */
                    const ssurf *c0 = &sh->sf[pix];
                    gi_rng lr;
                    gi_rng_seed(&lr, 0xc7ea, pix, l);
                    gi_light_sample ls;
                    if (!c0->valid || !gi_light_sample_stratum(lt, gi_v3p(c0->p), 0, 1, &lr, &ls))
                        continue;
                    float lv = gi_luminance(ls.value), e0v = lv * gi_fmaxf(gi_dot(gi_v3p(c0->ns), ls.wi), 0.0f);
                    int differs = 0;
                    for (int j = 0; j < NE && !differs; j++) {
                        const ssurf *q = &sh->esf[e * (size_t)NE + (size_t)j];
                        if (q->valid)
                            differs = fabsf(lv * gi_fmaxf(gi_dot(gi_v3p(q->ns), ls.wi), 0.0f) - e0v) > tau;
                    }
                    if (differs)
                        continue;
                }
                int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w);
                float lo = INFINITY, hi = -INFINITY;
                for (int dy = -2; dy <= 2; dy++)
                    for (int dx = -2; dx <= 2; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                            continue;
                        size_t q = (size_t)yy * (size_t)w + (size_t)xx;
                        if (!sh->svalid[q])
                            continue;
                        lo = gi_fminf(lo, ec[q]);
                        hi = gi_fmaxf(hi, ec[q]);
                    }
                skip[e - e0] = hi - lo <= tau;
                ns += skip[e - e0];
            }
            if (ns) {
#pragma omp atomic
                nskip += ns;
            }
            for (size_t i = 0; i < n; i++) {
                size_t e = e0 + i / (size_t)NE, j = i % (size_t)NE;
                size_t q = e * (size_t)NE + j;
                samp[i] = !skip[e - e0] && (!mask || mask[sh->epix[e]]) && sh->esmat[q] != UINT32_MAX ? &sh->esf[q]
                                                                                                       : NULL;
                ids[i] = (uint64_t)sh->epix[e] * 64u + 1u + (uint64_t)j;
            }
            light_samples(b, samp, ids, n, lt, l, mats, kae, o->seed, acc, L, NULL, cnt, ec ? ev : NULL);
            /* pixels whose samples still see a strong contrast of this
             * light's irradiance (a sunlit edge against shade) get
             * GI_SHADE_XN more samples of it */
            uint8_t refine[64];
            size_t nr = 0;
            for (size_t e = e0; e < e1; e++) {
                refine[e - e0] = 0;
                if (!ec || skip[e - e0] || (mask && !mask[sh->epix[e]]))
                    continue;
                float lo = ec[sh->epix[e]], hi = lo;
                for (int j = 0; j < NE; j++) {
                    float v0 = sh->esmat[e * (size_t)NE + (size_t)j] != UINT32_MAX ? ev[(e - e0) * (size_t)NE + (size_t)j]
                                                                                   : 0.0f;
                    lo = gi_fminf(lo, v0);
                    hi = gi_fmaxf(hi, v0);
                }
                refine[e - e0] = hi - lo > tau_ref;
            }
            for (size_t e = e0; e < e1; e++) {
                if ((mask && !mask[sh->epix[e]]) || skip[e - e0])
                    continue;
                float *px = C + 3 * (size_t)sh->epix[e];
                cen[e - e0] = gi_v3p(px);
                if (sh->ew) {
                    const float *ew = sh->ew + e * (size_t)(NE + 1);
                    gi_vec3 sum = gi_scale(gi_v3p(px), ew[NE]);
                    for (int j = 0; j < NE; j++)
                        sum = gi_madd(sum, L[(e - e0) * (size_t)NE + (size_t)j], ew[j]);
                    gi_v3store(px, sum);
                    continue;
                }
                gi_vec3 sum = gi_v3p(px);
                for (int j = 0; j < NE; j++)
                    sum = gi_add(sum, L[(e - e0) * (size_t)NE + (size_t)j]);
                gi_v3store(px, gi_scale(sum, 1.0f / (float)(NE + 1)));
            }
            size_t n2 = 0;
            for (size_t e = e0; e < e1; e++) {
                if (!refine[e - e0])
                    continue;
                if (!sh->xsf[e]) {
#pragma omp atomic
                    nnew++;
                }
                const ssurf *x = extra_samples(sh, cam, w, h, e);
                if (!x) {
                    refine[e - e0] = 0;
                    continue;
                }
                for (int j = 0; j < GI_SHADE_XN; j++) {
                    samp[n2] = x[j].valid ? &x[j] : NULL;
                    ids[n2++] = (uint64_t)sh->epix[e] * 64u + (uint64_t)j;
                }
                nr++;
            }
            if (nr) {
#pragma omp atomic
                nref += nr;
            }
            if (n2) {
                if (sh->ew) /* the edge samples' light, for the refinement's groups */
                    memcpy(L2, L, n * sizeof *L2);
                light_samples(b, samp, ids, n2, lt, (uint64_t)l | (2ull << 32), mats, ka, o->seed, acc, L, NULL, cnt,
                              NULL);
                size_t k2 = 0;
                for (size_t e = e0; e < e1; e++) {
                    if (!refine[e - e0])
                        continue;
                    float *px = C + 3 * (size_t)sh->epix[e];
                    if (sh->ew) {
                        /* each sample's share of the pixel stays its
                         * coverage; its light becomes the mean of it and
                         * the refinement samples nearest to it on its surface */
                        const float *ew = sh->ew + e * (size_t)(NE + 1);
                        const uint8_t *grp = (const uint8_t *)(sh->xsf[e] + GI_SHADE_XN);
                        gi_vec3 gs[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
                        int gc[GI_SHADE_AA_MAX * GI_SHADE_AA_MAX];
                        for (int j = 0; j < NE; j++) {
                            gs[j] = L2[(e - e0) * (size_t)NE + (size_t)j];
                            gc[j] = 1;
                        }
                        gs[NE] = cen[e - e0];
                        gc[NE] = 1;
                        for (int j = 0; j < GI_SHADE_XN; j++, k2++)
                            if (grp[j] <= NE) {
                                gs[grp[j]] = gi_add(gs[grp[j]], L[k2]);
                                gc[grp[j]]++;
                            }
                        gi_vec3 sum = gi_v3(0, 0, 0);
                        for (int j = 0; j <= NE; j++)
                            sum = gi_madd(sum, gs[j], ew[j] / (float)gc[j]);
                        gi_v3store(px, sum);
                        continue;
                    }
                    gi_vec3 sum = gi_scale(gi_v3p(px), (float)(NE + 1));
                    for (int j = 0; j < GI_SHADE_XN; j++)
                        sum = gi_add(sum, L[k2++]);
                    gi_v3store(px, gi_scale(sum, 1.0f / (float)(NE + 1 + GI_SHADE_XN)));
                }
            }
        }
#pragma omp single
        tp[1] = gi_now();
        /* shadow edges: a pixel (not on a geometric edge) lit while a
         * neighbour is shadowed, or the reverse, gets the light at NE more
         * points of its plane. Then, in rounds, so does a shadowed
         * neighbour of such a pixel whose samples along their common border
         * found the light: a sunlit sliver thinner than a pixel that runs
         * between shadowed centres is followed pixel by pixel. Before, a
         * pixel whose centre and four neighbours' centres all missed the
         * sliver kept its centre's value: Sponza, a sunlit strip across the
         * floor seen at 180 x 240 with a 100-degree field of view, pixels of
         * 55 cd/m2 in the path tracer's image at 0. Not the reverse (a thin
         * shadow between lit centres): the plane's points can lie a fraction
         * of a millimetre behind a neighbouring triangle raised by as much
         * (Sponza's floor slabs), whose shadow rays then find it, and lit
         * pixels next to a shadow edge went dark (sun-moved: rows at 35 where
         * the path tracer finds 43). A masked pass (a material change)
         * refines the pixels its full pass did, flagged VIS_SPREAD in vis. */
        if (vis) {
            const float tau_curv = (float)(GI_SHADE_CURVATURE / GI_SHADE_EDGE_CONTRAST) * tau;
            uint32_t *loc = NULL;
            size_t nloc = 0, cloc = 0;
#define SPREAD_FROM(px_, py_, lit_, dark_)                                                                         \
    do {                                                                                                          \
        for (int k_ = 0; spread && k_ < 8; k_++) {                                                                \
            int nx_ = (px_) + nb8[k_][0], ny_ = (py_) + nb8[k_][1];                                              \
            if (nx_ < 0 || ny_ < 0 || nx_ >= w || ny_ >= h)                                                       \
                continue;                                                                                         \
            size_t q_ = (size_t)ny_ * (size_t)w + (size_t)nx_;                                                    \
            unsigned vq_ = vis[q_] & 3u;                                                                          \
            if (vq_ != 2 || sh->eidx[q_] != UINT32_MAX || !sh->svalid[q_] || !(((lit_) >> k_) & 1u) ||            \
                spread[q_] ||                                                                                     \
                __atomic_exchange_n(&spread[q_], (uint8_t)1, __ATOMIC_RELAXED))                                   \
                continue;                                                                                         \
            if (nloc == cloc) {                                                                                   \
                size_t nc_ = cloc ? 2 * cloc : 256;                                                               \
                uint32_t *t_ = realloc(loc, nc_ * sizeof *t_);                                                    \
                if (!t_)                                                                                          \
                    continue; /* dropped: neither this pass nor a masked one refines it */                       \
                loc = t_;                                                                                         \
                cloc = nc_;                                                                                       \
            }                                                                                                     \
            loc[nloc++] = (uint32_t)q_;                                                                           \
        }                                                                                                         \
    } while (0)
#pragma omp for schedule(dynamic, 4)
            for (int y = 0; y < h; y++) {
                if (!ok)
                    continue;
                for (int x = 0; x < w; x++) {
                    size_t pix = (size_t)y * (size_t)w + (size_t)x;
                    if ((mask && !mask[pix]) || sh->eidx[pix] != UINT32_MAX || !sh->svalid[pix])
                        continue;
                    /* lit beside shadowed; or inside a spot's cone beside a
                     * pixel that faces the spot and sent it no ray (outside
                     * the cone): a hard-edged spot's circle, one sample per
                     * pixel, was
                     * jagged (Sponza, inner = outer = 20 degrees, 160 x 120
                     * against 256 spp: nrmse 1.36, 97% of its square in the
                     * circle's pixels). And lit beside a pixel that faces
                     * away from the light (a terminator, spots' too: t137's
                     * columns under a spot 0.133 -> 0.118), or the reverse:
                     * a column's sunlit flank turning into its own shade
                     * within one pixel, which no crease marks (neighbouring
                     * centres' normals close), kept its centre's light
                     * (Sponza u3, a column of pixels at 73 cd/m2 where the
                     * path tracer finds 49: the frame 0.1687 -> 0.1630
                     * nrmse; u4, a lamp's, 0.0539 -> 0.0446; t137's
                     * columns, direct light 0.104 -> 0.092).
                     * Tried before the camera rays found the real surface:
                     * the plane's points on a curved face found false
                     * shadows then (arcade-moved +0.0003). */
                    const unsigned v0 = vis[pix] & 3u;
                    const int c0 = v0 == 0u && cone_dark(sh, lt, pix);
#define VIS_EDGE(q_) vis_edge(v0, c0, vis[q_] & 3u, sh, lt, (q_))
                    int differs = (x > 0 && VIS_EDGE(pix - 1)) || (x + 1 < w && VIS_EDGE(pix + 1)) ||
                                  (y > 0 && VIS_EDGE(pix - w)) || (y + 1 < h && VIS_EDGE(pix + w));
#undef VIS_EDGE
                    /* a lit centre whose irradiance stands out from its
                     * 4 neighbours' mean by over GI_SHADE_CURVATURE of the
                     * light's mean over the view: the light varies across
                     * the pixel too much for its centre to stand for it (a
                     * carved relief, a lamp close above a floor). No edge
                     * marks these; they get the same 24 more points. */
                    if (!differs && ec && v0 == 1u && isfinite(tau)) {
                        float sum = 0.0f;
                        int nn = 0;
                        for (int k = 0; k < 4; k++) {
                            int xx = x + nb8[k][0], yy = y + nb8[k][1];
                            if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                                continue;
                            size_t q = (size_t)yy * (size_t)w + (size_t)xx;
                            if (sh->svalid[q]) {
                                sum += ec[q];
                                nn++;
                            }
                        }
                        differs = nn >= 2 && fabsf(ec[pix] - sum / (float)nn) > tau_curv;
                        if (differs) {
#pragma omp atomic
                            ncurv++;
                        }
                    }
                    if (mask && (vis[pix] & VIS_SPREAD))
                        differs = 1;
                    if (!differs || (spread && __atomic_exchange_n(&spread[pix], (uint8_t)1, __ATOMIC_RELAXED)))
                        continue;
                    unsigned lit = 0, dark = 0;
                    shadow_edge_pixel(sh, b, cam, w, h, x, y, lt, l, mats, o, acc, C + 3 * pix, &lit, &dark);
                    SPREAD_FROM(x, y, lit, dark);
                }
            }
            /* the rounds (a full pass only: spread is NULL otherwise) */
            for (int round = 0; spread && round < GI_SHADE_SPREAD_ROUNDS; round++) {
#pragma omp single
                nspread = 0;
#pragma omp critical
                {
                    if (nloc)
                        memcpy(slist + nspread, loc, nloc * sizeof *loc);
                    nspread += nloc;
                }
                nloc = 0;
#pragma omp barrier
                const size_t nnow = nspread;
                if (!nnow)
                    break;
#pragma omp single
                nspread_all += nnow;
#pragma omp for schedule(dynamic, 8)
                for (size_t i = 0; i < nnow; i++) {
                    if (!ok)
                        continue;
                    size_t pix = slist[i];
                    int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w);
                    unsigned lit = 0, dark = 0;
                    shadow_edge_pixel(sh, b, cam, w, h, x, y, lt, l, mats, o, acc, C + 3 * pix, &lit, &dark);
                    vis[pix] |= VIS_SPREAD;
                    SPREAD_FROM(x, y, lit, dark);
                }
            }
#undef SPREAD_FROM
            free(loc);
        }
        free(b);
        free(acc);
        free(L);
        free(L2);
        free(samp);
        free(ids);
        free(v);
        free(cnt);
        free(ev);
    }
    free(spread);
    free(slist);
    tp[2] = gi_now();
    gi_verbose("light %zu: rows %.1f ms, edge pixels %.1f ms, shadow edges %.1f ms (%zu pixels followed slivers, %zu "
               "pixels of uneven light)",
               l, 1e3 * (tp[0] - tp0), 1e3 * (tp[1] - tp[0]), 1e3 * (tp[2] - tp[1]), nspread_all, ncurv);
    if (ec)
        gi_verbose("light %zu: %zu of %zu edge pixels kept their centre sample (contrast below %.3g), %zu refined "
                   "(above %.3g; %zu of them found their %d samples now)",
                   l, nskip, sh->nedge, tau, nref, tau_ref, nnew, GI_SHADE_XN);
    return fail;
}

/* Allocate and touch the buffers of up to GI_SHADE_DCACHE direct-light
 * slots for np pixels, within GI_SHADE_WARM_BYTES (at least 2), once per
 * image size: a light move then writes into memory already mapped (a first
 * touch costs ~0.5-3.5 ms per MB on this project's virtual machines; a fresh
 * slot cost Sponza's light moves ~10 ms). Returns nonzero when out of memory. */
static int dcache_warm(gi_shade *sh, size_t np)
{
    size_t per = np * (3 * sizeof(float) + 1 + sizeof(float));
    int have = 0;
    for (int i = 0; i < GI_SHADE_DCACHE; i++)
        have += sh->dc[i].rgb && sh->dc[i].np == np;
    if (have)
        return 0;
    size_t warm = GI_SHADE_WARM_BYTES / (per ? per : 1);
    warm = warm < 2 ? 2 : (warm > GI_SHADE_DCACHE ? GI_SHADE_DCACHE : warm);
    for (size_t i = 0; i < warm; i++) {
        struct dcache *d = &sh->dc[i];
        free(d->rgb);
        free(d->vis);
        free(d->ec);
        memset(d, 0, sizeof *d);
        d->rgb = gi_alloc_large(np * 3 * sizeof *d->rgb);
        d->vis = gi_alloc_large(np);
        d->ec = gi_alloc_large(np * sizeof *d->ec);
        if (!d->rgb || !d->vis || !d->ec)
            return 1;
        /* written, not calloc'ed: calloc leaves fresh pages untouched */
        memset(d->rgb, 0, np * 3 * sizeof *d->rgb);
        memset(d->vis, 0, np);
        memset(d->ec, 0, np * sizeof *d->ec);
        d->np = np;
    }
    return 0;
}

/* 1 if pixel sample o2 lies on the surface of glossy sample sf for the
 * average of gathered terms: same material, normals within ~11 degrees, no
 * discontinuity (pa: a pixel's angle) */
static int glossy_neighbour(const ssurf *sf, const ssurf *o2, float pa)
{
    return o2->valid && o2->material == sf->material &&
           sf->ns[0] * o2->ns[0] + sf->ns[1] * o2->ns[1] + sf->ns[2] * o2->ns[2] >= 0.98f &&
           !discontinuity_tx(NULL, sf, o2, pa, NULL);
}

/* ---- near field ------------------------------------------------------------
 * The gathering points hold the indirect irradiance E at points R- to R+
 * apart, and the splat interpolates between them. Along a concave crease
 * beside a lit face E peaks within a few centimetres, between the points:
 * Sponza, sun-moved (640x480), the wall 1.6 cm above a sunlit ledge receives
 * 332 lux of indirect light (16384-spp sensors), 4.84 cm above 249, 7 cm 165,
 * 20 cm 58, where the nearest points (17-20 cm away) hold 27-57 and match the
 * path tracer; the pixels there were 3-12x too dark, and the 1% of pixels
 * with the largest indirect error held 60% of its square, 89% of them too
 * dark. So E is split: E = E_nb + E_rest, E_nb the first bounce of direct
 * light off diffuse surfaces within r0 (nf_r0), estimated the same way at
 * samples and points (NF_KX, NF_KP cosine-distributed rays up to r0, each
 * hit's diffuse radiance kd / pi E_direct with a shadow ray per point, spot
 * or directional light); the splat interpolates E_rest = E - E_nb between
 * the points and adds each sample's own E_nb (averaged over the samples of
 * its surface nearby, nf_stride). The hits are geometry (traced once
 * per view, and once per point); a frame only shades them, with each light's
 * terms kept while it stays (struct nflc). */
#define NF_KX 16 /* rays per traced sample (a square: whole strata) */
#define NF_KP 36 /* rays per gathering point (a square: whole strata) */
/* Which samples trace (gi_shade_opts.near_stride): with a stride S, those
 * whose x and y are multiples of S, and those without such a sample of
 * their surface within S pixels; a sample's near field is the mean of those
 * traced within (2 S + 1)^2 pixels on its surface and within r0 / 2
 * (nf_neighbour): 9 of them, 144 rays, where the surface goes on. The
 * default (0) traces at stride 2 first and then every other sample that has
 * one of those with a hit within 2 pixels on its surface (nf_do 2), and
 * takes the mean over 3 x 3: stride 1 where there is a near field, 2
 * elsewhere.
 *
 * A mean over 5 x 5 at stride 2 smears the peak beside a crease over +-2
 * pixels (up to r0 / 2), too far where pixels are wide. Sponza against
 * 1024-4096 spp, 320 x 240: f3 (the upper gallery over sunlit ledges)
 * 0.1021 at stride 2, 0.0960 at stride 1, 0.0968 by default, the nine other
 * views of docs/journal.md "Four more views" and untuned.script within -0.0013 /
 * +0.0003 of stride 2; 640 x 480: sun-moved 0.0776 / 0.0762 / 0.0762,
 * camera-walk.script's camera moves ~580 / ~720 / ~650 ms (the default
 * traces ~30 k more samples a view, each with something within r0: ~55 ms),
 * light moves the same. */
#define NF_STRIDE_MAX 4
typedef struct nfhit {
    float p[3], n[3], tex[3]; /* point, shading normal facing the ray, base-colour texel (unit factor) */
    uint32_t mat;
} nfhit;

/* The hits within r0 of K cosine-distributed rays about n from p, whose
 * surface's geometric normal (facing n) is ng, into out; their count. */
static int nf_trace(const gi_shade *sh, gi_vec3 p, gi_vec3 n, gi_vec3 ng, int K, uint64_t id, float r0,
                    nfhit *out)
{
    enum { KM = 36 };
    int k = (int)ceilf(sqrtf((float)K)), m = 0, nh = 0;
    /* every ray leaves from ro (gi_rt_offset moves p along ng for any
     * direction above ng) and ends within r0 above ro's plane: with no
     * triangle there, none can hit. Most samples have none within r0
     * (Sponza, camera-walk.script: 86-88% of those traced found nothing);
     * the point query costs less than their rays, and the answer is the
     * same */
    gi_vec3 ro0 = gi_rt_offset(p, ng, ng);
    float h0 = gi_dot(gi_sub(ro0, p), ng);
    if (!gi_rt_near_above(sh->rt, ro0, ng, r0 * (1.0f + 1e-3f), -0.5f * gi_fmaxf(h0, 0.0f)))
        return 0;
    gi_rng rng;
    gi_rng_seed(&rng, 0x4ea7f1e1dull, id, 0);
    gi_vec3 ro[KM], rd[KM];
    float tmax[KM];
    gi_hit hit[KM];
    uint8_t found[KM];
    for (int j = 0; j < K && j < KM; j++) {
        float u1 = ((float)(j % k) + gi_rng_float(&rng)) / (float)k;
        float u2 = ((float)(j / k % k) + gi_rng_float(&rng)) / (float)k;
        gi_vec3 d = gi_sample_cosine(n, u1, u2);
        if (gi_dot(d, ng) <= 0.0f)
            continue; /* under the surface: it would find the surface's own neighbours */
        rd[m] = d;
        ro[m] = gi_rt_offset(p, ng, d);
        tmax[m++] = r0;
    }
    if (!m)
        return 0;
    gi_rt_intersect_n_upto(sh->rt, m, ro, rd, tmax, hit, found);
    for (int j = 0; j < m; j++) {
        if (!found[j])
            continue;
        gi_surface hs;
        gi_rt_surface(sh->rt, &hit[j], &hs);
        const gi_material *mt = &sh->s->materials[hs.material];
        int front = gi_dot(hs.ng, rd[j]) < 0.0f;
        if (!front && !mt->double_sided)
            continue; /* a back face absorbs */
        gi_vec3 hn = front ? hs.ng : gi_neg(hs.ng);
        gi_vec3 hsn = gi_dot(hs.ns, hn) < 0.0f ? gi_neg(hs.ns) : hs.ns;
        nfhit *o = &out[nh++];
        gi_v3store(o->p, hs.p);
        gi_v3store(o->n, hsn);
        gi_material unit = *mt;
        unit.base_color[0] = unit.base_color[1] = unit.base_color[2] = 1.0f;
        gi_scene_base_color(sh->s, &unit, hs.uv0, hs.uv1, o->tex);
        o->mat = hs.material;
    }
    return nh;
}

/* Per light (at strength 1 and white, gi_light_unit) and hit: its direct
 * irradiance / pi, E cos / pi with the shadow ray's verdict, for hits
 * [0, n) into g. */
static void nf_light(const gi_shade *sh, const nfhit *hits, size_t n, const gi_light *unit, float *g, int threads)
{
    enum { B = 64 };
#pragma omp parallel for schedule(dynamic, 16) num_threads(threads)
    for (size_t c = 0; c < (n + B - 1) / B; c++) {
        gi_rt_thread_init();
        gi_vec3 ro[B], rd[B];
        float tm[B], v[B];
        uint8_t occ[B];
        size_t slot[B], i0 = c * B, i1 = i0 + B < n ? i0 + B : n;
        int q = 0;
        for (size_t i = i0; i < i1; i++) {
            const nfhit *hh = &hits[i];
            gi_vec3 p = gi_v3p(hh->p), nn = gi_v3p(hh->n);
            gi_light_sample ls;
            g[i] = 0.0f;
            if (!gi_light_sample_at(unit, p, 0.5f, 0.5f, &ls))
                continue;
            float co = gi_dot(nn, ls.wi);
            if (co <= 0.0f || !(ls.value.x > 0.0f))
                continue;
            ro[q] = gi_rt_offset(p, nn, ls.wi);
            rd[q] = ls.wi;
            tm[q] = gi_rt_shadow_tmax(p, ro[q], ls.dist);
            v[q] = ls.value.x * co * GI_INV_PIf;
            slot[q++] = i;
        }
        if (!q)
            continue;
        gi_rt_occluded_n(sh->rt, q, ro, rd, tm, occ);
        for (int k = 0; k < q; k++)
            g[slot[k]] = occ[k] ? 0.0f : v[k];
    }
}

/* The lights of this frame the near field takes, with their caches. */
typedef struct nfuse {
    const float *gx, *gp; /* the cache's per-hit terms (samples' hits, points' hits) */
    float sc[3];          /* the light's strength and colour */
} nfuse;

/* E_nb of a sample or point with n hits (the first at index h0 of hits, of
 * the lights' terms gx / gp as pts) of K rays: pi / K times their radiance. */
static gi_vec3 nf_irradiance(const nfhit *hits, size_t h0, int n, int K, const nfuse *use, int nu, int pts,
                             const gi_material *mats)
{
    gi_vec3 sum = gi_v3(0, 0, 0);
    for (int j = 0; j < n; j++) {
        size_t i = h0 + (size_t)j;
        gi_vec3 e = gi_v3(0, 0, 0);
        for (int u = 0; u < nu; u++) {
            float t = (pts ? use[u].gp : use[u].gx)[i];
            e = gi_madd(e, gi_v3(use[u].sc[0], use[u].sc[1], use[u].sc[2]), t);
        }
        if (gi_maxc(e) <= 0.0f)
            continue;
        const nfhit *hh = &hits[i];
        gi_bsdf b;
        gi_bsdf_init(&b, &mats[hh->mat], gi_mul(gi_v3p(mats[hh->mat].base_color), gi_v3p(hh->tex)));
        sum = gi_add(sum, gi_mul(b.kd, e));
    }
    return gi_scale(sum, GI_PIf / (float)K);
}

static int nf_any_light(const gi_light *lights, size_t nl)
{
    for (size_t l = 0; l < nl; l++)
        if (lights[l].enabled && !gi_light_has_area(&lights[l]))
            return 1;
    return 0;
}

static int glossy_neighbour(const ssurf *sf, const ssurf *o2, float pa);

/* 1 if sample o2 may stand for sf in the near field: the same surface
 * (glossy_neighbour) and within r0 / 2 of it, so that a window of pixels
 * wider than the near field (the Cornell box at 64 x 64: 8.6 mm pixels,
 * r0 6.6 mm) does not spread a crease's peak */
static int nf_neighbour(const ssurf *sf, const ssurf *o2, float pa, float r0)
{
    float d[3] = {o2->p[0] - sf->p[0], o2->p[1] - sf->p[1], o2->p[2] - sf->p[2]};
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= 0.25f * r0 * r0 && glossy_neighbour(sf, o2, pa);
}

/* Per view: the traced samples with hits (nf_hl) and, for each sample whose
 * window (nf_stride) holds one on its surface, the traced samples there
 * (nf_wl[q]: the sample, nf_cl[nf_co[q] ..]: those with hits, nf_cc[q]: all
 * of them); every other sample's near field is 0. 0 or -1 (out of memory). */
static int nf_windows(gi_shade *sh, size_t ns, int threads)
{
    const int w = sh->pw, h = sh->ph, win = sh->nf_win;
    const size_t np = (size_t)w * (size_t)h;
    const float pa = 2.0f * tanf(0.5f * sh->pcam.yfov) / (float)h;
    free(sh->nf_hl);
    free(sh->nf_wl);
    free(sh->nf_co);
    free(sh->nf_cc);
    free(sh->nf_cl);
    sh->nf_hl = malloc((ns + 1) * sizeof *sh->nf_hl);
    sh->nf_wl = malloc((ns + 1) * sizeof *sh->nf_wl);
    sh->nf_co = malloc((ns + 2) * sizeof *sh->nf_co);
    sh->nf_cc = malloc(ns + 1);
    uint8_t *nh = calloc(ns + 1, 1);
    if (!sh->nf_hl || !sh->nf_wl || !sh->nf_co || !sh->nf_cc || !nh) {
        free(nh);
        sh->nf_cl = NULL;
        return -1;
    }
    size_t nhl = 0;
    for (size_t i = 0; i < ns; i++)
        if (sh->nf_xo[i + 1] > sh->nf_xo[i])
            sh->nf_hl[nhl++] = (uint32_t)i;
    sh->nf_nhl = nhl;
    memset(sh->nf_ex, 0, ns * 3 * sizeof *sh->nf_ex);
    /* per sample, how many traced samples with hits its window holds */
#pragma omp parallel for schedule(static) num_threads(threads)
    for (size_t i = 0; i < ns; i++) {
        const ssurf *sf = &sh->sf[i];
        if (!sf->valid)
            continue;
        size_t k = i / np, pix = i % np;
        int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w), hit = 0;
        for (int dy = -win; dy <= win; dy++)
            for (int dx = -win; dx <= win; dx++) {
                int xx = x + dx, yy = y + dy;
                if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                    continue;
                size_t j = k * np + (size_t)yy * (size_t)w + (size_t)xx;
                if (sh->nf_do[j] && sh->nf_xo[j + 1] > sh->nf_xo[j] && (!(dx || dy) || nf_neighbour(sf, &sh->sf[j], pa, sh->nf_r0)))
                    hit++;
            }
        nh[i] = (uint8_t)hit;
    }
    /* the listed samples and their offsets */
    size_t nw = 0, nc = 0;
    for (size_t i = 0; i < ns; i++)
        if (nh[i]) {
            sh->nf_wl[nw] = (uint32_t)i;
            sh->nf_co[nw++] = (uint32_t)nc;
            nc += nh[i];
        }
    sh->nf_co[nw] = (uint32_t)nc;
    sh->nf_nwl = nw;
    sh->nf_cl = malloc((nc + 1) * sizeof *sh->nf_cl);
    if (!sh->nf_cl) {
        free(nh);
        return -1;
    }
    /* the lists, by listed sample (its offset known) */
#pragma omp parallel for schedule(static) num_threads(threads)
    for (size_t q = 0; q < sh->nf_nwl; q++) {
        size_t i = sh->nf_wl[q];
        const ssurf *sf = &sh->sf[i];
        size_t k = i / np, pix = i % np;
        int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w), all = 0;
        uint32_t c = sh->nf_co[q];
        for (int dy = -win; dy <= win; dy++)
            for (int dx = -win; dx <= win; dx++) {
                int xx = x + dx, yy = y + dy;
                if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                    continue;
                size_t j = k * np + (size_t)yy * (size_t)w + (size_t)xx;
                if (!sh->nf_do[j] || ((dx || dy) && !nf_neighbour(sf, &sh->sf[j], pa, sh->nf_r0)))
                    continue;
                all++;
                if (sh->nf_xo[j + 1] > sh->nf_xo[j])
                    sh->nf_cl[c++] = (uint32_t)j;
            }
        sh->nf_cc[q] = (uint8_t)all;
    }
    free(nh);
    return 0;
}

/* The near field of this frame (see above): sh->nf_ex for the ns samples
 * and the gathering points' irradiance less theirs; returns that array, or
 * gpe itself when the near field is off or has nothing to do, or NULL when
 * out of memory. */
static const float *nf_prepare(gi_shade *sh, const float *gpe, size_t ns, float r0, const gi_light *lights, size_t nl,
                               const gi_material *mats, int threads, const gi_shade_opts *o)
{
    if (!(r0 > 0.0f) || !gpe || !nf_any_light(lights, nl))
        return gpe;
    const size_t npt = sh->h->num_gpoints;
    if (sh->nf_r0 != r0) { /* (a new r0: every hit is stale) */
        free(sh->nf_pdone);
        sh->nf_pdone = NULL;
        sh->nf_nph = 0;
        sh->nf_pkn = 0;
        sh->nf_view = 0;
        sh->nf_r0 = r0;
        for (int i = 0; i < GI_SHADE_NF_LC; i++)
            sh->nflc[i].view = sh->nflc[i].pdone = 0;
    }
    if (!sh->nf_pdone) {
        sh->nf_pdone = calloc(npt + 1, 1);
        free(sh->nf_po);
        free(sh->nf_pn);
        free(sh->nf_gpe);
        sh->nf_po = malloc((npt + 1) * sizeof *sh->nf_po);
        sh->nf_pn = calloc(npt + 1, 1);
        /* zeroed: only the points a view reads are written, and an
         * uninitialised value read with weight 0 can still be a NaN */
        sh->nf_gpe = calloc((npt + 1) * 3, sizeof *sh->nf_gpe);
        if (!sh->nf_pdone || !sh->nf_po || !sh->nf_pn || !sh->nf_gpe) {
            free(sh->nf_pdone);
            sh->nf_pdone = NULL;
            return NULL;
        }
    }
    enum { CH = 512 };
    /* the hits of the points this view reads that have none yet */
    {
        double tp0 = gi_now();
        size_t nnew = 0;
        for (size_t q = 0; q < sh->nvgp; q++)
            nnew += !sh->nf_pdone[sh->vgp[q]];
        if (nnew) {
            if (sh->nf_nph + nnew * NF_KP > sh->nf_cph) {
                size_t cap = (sh->nf_nph + nnew * NF_KP) * 3 / 2 + 1024;
                nfhit *p = realloc(sh->nf_ph, cap * sizeof *p);
                if (!p)
                    return NULL;
                sh->nf_ph = p;
                uint32_t *pk = realloc(sh->nf_pk, cap * sizeof *pk);
                if (!pk)
                    return NULL;
                sh->nf_pk = pk;
                sh->nf_cph = cap;
            }
            uint32_t *todo = malloc(nnew * sizeof *todo);
            if (!todo)
                return NULL;
            size_t t = 0;
            for (size_t q = 0; q < sh->nvgp; q++)
                if (!sh->nf_pdone[sh->vgp[q]])
                    todo[t++] = sh->vgp[q];
            /* each new point's NF_KP slots after the pool's end, packed after */
            nfhit *base = sh->nf_ph + sh->nf_nph;
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
            for (size_t q = 0; q < nnew; q++) {
                gi_rt_thread_init();
                const gi_gpoint *g = &sh->h->gpoints[todo[q]];
                gi_vec3 n = gi_v3p(g->nrm), ng = n;
                if (g->tri < sh->s->num_triangles) {
                    /* its triangle's own normal: along smooth-shaded
                     * curves (Sponza's vaults) the interpolated normal leans
                     * up to 60 degrees away, and rays under the facet found
                     * its neighbours (Sponza arcade-moved 0.0993 -> 0.1041
                     * nrmse with the point's normal, 0.0979 with this) */
                    gi_surface ts;
                    gi_scene_surface(sh->s, g->tri, 1.0f / 3.0f, 1.0f / 3.0f, &ts);
                    ng = gi_dot(ts.ng, n) < 0.0f ? gi_neg(ts.ng) : ts.ng;
                }
                sh->nf_pn[todo[q]] = (uint8_t)nf_trace(sh, gi_v3p(g->pos), n, ng, NF_KP,
                                                       (uint64_t)todo[q] | (1ull << 40), r0, base + q * NF_KP);
            }
            size_t w = sh->nf_nph;
            for (size_t q = 0; q < nnew; q++) {
                uint32_t i = todo[q];
                memmove(sh->nf_ph + w, base + q * NF_KP, sh->nf_pn[i] * sizeof *sh->nf_ph);
                sh->nf_po[i] = (uint32_t)w;
                w += sh->nf_pn[i];
                sh->nf_pdone[i] = 1;
            }
            if (o->key_at && o->key_flux0) {
                size_t h0 = sh->nf_pkn, nh = w - h0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
                for (size_t c0 = 0; c0 < nh; c0 += 256) {
                    float pp[3 * 256], nn[3 * 256];
                    size_t m = nh - c0 < 256 ? nh - c0 : 256;
                    for (size_t j = 0; j < m; j++) {
                        memcpy(pp + 3 * j, sh->nf_ph[h0 + c0 + j].p, 3 * sizeof(float));
                        memcpy(nn + 3 * j, sh->nf_ph[h0 + c0 + j].n, 3 * sizeof(float));
                    }
                    o->key_at(o->key_ctx, m, pp, nn, sh->nf_pk + h0 + c0);
                }
                sh->nf_pkn = w;
            }
            sh->nf_nph = w;
            free(todo);
            gi_verbose("near field: %zu new points traced, %.1f ms", nnew, 1e3 * (gi_now() - tp0));
        }
    }
    /* the samples' hits, once per view: chunks traced in parallel, then packed */
    const int mode = o->near_stride < 0 ? 0 : o->near_stride > NF_STRIDE_MAX ? NF_STRIDE_MAX : o->near_stride;
    const int stride = mode ? mode : 2, fill = !mode;
    if (mode != sh->nf_stride || !sh->nf_win) {
        sh->nf_stride = mode;
        sh->nf_win = mode ? mode : 1;
        sh->nf_view = 0;
    }
    if (sh->nf_view != sh->view_id) {
        double tv0 = gi_now();
        size_t nch = (ns + CH - 1) / CH;
        nfhit **cb = calloc(nch + 1, sizeof *cb);
        uint32_t *cn = calloc(ns + 1, sizeof *cn);
        if (!sh->nf_xo || sh->nf_cap < ns + 1) { /* kept from view to view: new memory costs its page faults */
            free(sh->nf_xo);
            free(sh->nf_ex);
            free(sh->nf_tmp);
            free(sh->nf_do);
            sh->nf_xo = malloc((ns + 1) * sizeof *sh->nf_xo);
            sh->nf_ex = malloc((ns + 1) * 3 * sizeof *sh->nf_ex);
            sh->nf_tmp = malloc((ns + 1) * 3 * sizeof *sh->nf_tmp);
            sh->nf_do = malloc(ns + 1);
            sh->nf_cap = ns + 1;
        }
        int fail = !cb || !cn || !sh->nf_xo || !sh->nf_ex || !sh->nf_tmp || !sh->nf_do;
        if (!fail) {
            /* which samples trace: every stride-th of every stride-th
             * row, and any other without one of them on its surface nearby */
            const int w = sh->pw, h = sh->ph;
            const size_t np = (size_t)w * (size_t)h;
            const float pa = 2.0f * tanf(0.5f * sh->pcam.yfov) / (float)h;
#pragma omp parallel for schedule(static) num_threads(threads)
            for (size_t i = 0; i < ns; i++) {
                const ssurf *sf = &sh->sf[i];
                size_t k = i / np, pix = i % np;
                int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w), on = 0;
                if (!sf->valid) {
                    sh->nf_do[i] = 0;
                    continue;
                }
                if (x % stride == 0 && y % stride == 0) {
                    sh->nf_do[i] = 1;
                    continue;
                }
                for (int dy = -stride; dy <= stride && !on; dy++)
                    for (int dx = -stride; dx <= stride && !on; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h || xx % stride || yy % stride)
                            continue;
                        on = nf_neighbour(sf, &sh->sf[k * np + (size_t)yy * (size_t)w + (size_t)xx], pa, r0);
                    }
                sh->nf_do[i] = (uint8_t)!on;
            }
        }
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
        for (size_t c = 0; c < nch; c++) {
            if (fail)
                continue;
            gi_rt_thread_init();
            size_t i0 = c * CH, i1 = i0 + CH < ns ? i0 + CH : ns;
            nfhit *buf = malloc((i1 - i0) * NF_KX * sizeof *buf);
            if (!buf) {
#pragma omp atomic write
                fail = 1;
                continue;
            }
            size_t n = 0;
            for (size_t i = i0; i < i1; i++) {
                const ssurf *sf = &sh->sf[i];
                int k = sh->nf_do[i] ? nf_trace(sh, gi_v3p(sf->p), gi_v3p(sf->ns), gi_v3p(sf->ng), NF_KX, i, r0, buf + n)
                                     : 0;
                cn[i] = (uint32_t)k;
                n += (size_t)k;
            }
            cb[c] = buf;
        }
        /* adaptive: every other sample with a traced one of its surface
         * within the stride that found something traces too (nf_do 2) */
        nfhit **cb2 = fill ? calloc(nch + 1, sizeof *cb2) : NULL;
        uint8_t *mk = fill ? calloc(ns + 1, 1) : NULL; /* (marked apart: the loop reads nf_do's neighbours) */
        fail |= fill && (!cb2 || !mk);
        if (fill && !fail) {
            const int w = sh->pw, h = sh->ph;
            const size_t np = (size_t)w * (size_t)h;
            const float pa = 2.0f * tanf(0.5f * sh->pcam.yfov) / (float)h;
#pragma omp parallel for schedule(static) num_threads(threads)
            for (size_t i = 0; i < ns; i++) {
                const ssurf *sf = &sh->sf[i];
                if (!sf->valid || sh->nf_do[i])
                    continue;
                size_t k = i / np, pix = i % np;
                int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w), on = 0;
                for (int dy = -stride; dy <= stride && !on; dy++)
                    for (int dx = -stride; dx <= stride && !on; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h)
                            continue;
                        size_t j = k * np + (size_t)yy * (size_t)w + (size_t)xx;
                        on = sh->nf_do[j] == 1 && cn[j] && nf_neighbour(sf, &sh->sf[j], pa, r0);
                    }
                mk[i] = (uint8_t)on;
            }
            for (size_t i = 0; i < ns; i++)
                if (mk[i])
                    sh->nf_do[i] = 2;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
            for (size_t c = 0; c < nch; c++) {
                if (fail)
                    continue;
                gi_rt_thread_init();
                size_t i0 = c * CH, i1 = i0 + CH < ns ? i0 + CH : ns, m = 0;
                for (size_t i = i0; i < i1; i++)
                    m += sh->nf_do[i] == 2;
                if (!m)
                    continue;
                nfhit *buf = malloc(m * NF_KX * sizeof *buf);
                if (!buf) {
#pragma omp atomic write
                    fail = 1;
                    continue;
                }
                size_t n = 0;
                for (size_t i = i0; i < i1; i++) {
                    if (sh->nf_do[i] != 2)
                        continue;
                    const ssurf *sf = &sh->sf[i];
                    int kh = nf_trace(sh, gi_v3p(sf->p), gi_v3p(sf->ns), gi_v3p(sf->ng), NF_KX, i, r0, buf + n);
                    cn[i] = (uint32_t)kh;
                    n += (size_t)kh;
                }
                cb2[c] = buf;
            }
        }
        size_t tot = 0;
        for (size_t i = 0; !fail && i < ns; i++) {
            sh->nf_xo[i] = (uint32_t)tot;
            tot += cn[i];
        }
        if (!fail) {
            sh->nf_xo[ns] = (uint32_t)tot;
            if (!sh->nf_xh || sh->nf_xh_cap < tot + 1) {
                free(sh->nf_xh);
                sh->nf_xh_cap = tot + 1 + (tot + 1) / 4;
                sh->nf_xh = malloc(sh->nf_xh_cap * sizeof *sh->nf_xh);
            }
            fail = !sh->nf_xh;
        }
        for (size_t c = 0; c < nch && cb; c++) {
            if (!fail && cb[c]) {
                size_t i0 = c * CH, i1 = i0 + CH < ns ? i0 + CH : ns;
                if (cb2 && cb2[c]) { /* the two passes' hits, in the samples' order */
                    const nfhit *p1 = cb[c], *p2 = cb2[c];
                    for (size_t i = i0; i < i1; i++) {
                        const nfhit **src = sh->nf_do[i] == 2 ? &p2 : &p1;
                        memcpy(sh->nf_xh + sh->nf_xo[i], *src, cn[i] * sizeof *sh->nf_xh);
                        *src += cn[i];
                    }
                } else {
                    memcpy(sh->nf_xh + sh->nf_xo[i0], cb[c], (sh->nf_xo[i1] - sh->nf_xo[i0]) * sizeof *sh->nf_xh);
                }
            }
            free(cb[c]);
            if (cb2)
                free(cb2[c]);
        }
        free(cb);
        free(cb2);
        free(mk);
        free(cn);
        if (fail) {
            free(sh->nf_xo);
            sh->nf_xo = NULL;
            sh->nf_cap = 0;
            return NULL;
        }
        sh->nf_view = sh->view_id;
        size_t ntr = 0, nzero = 0, nfill = 0;
        for (size_t i = 0; i < ns; i++) {
            ntr += sh->nf_do[i] != 0;
            nfill += sh->nf_do[i] == 2;
            nzero += sh->nf_do[i] && sh->nf_xo[i + 1] == sh->nf_xo[i];
        }
        double tv1 = gi_now();
        if (nf_windows(sh, ns, threads))
            return NULL;
        gi_verbose("near field: %zu of %zu rays of %zu samples (%zu of them beside a hit) end within %.3g m "
                   "(%.1f ms; %zu samples find nothing), windows %.1f ms",
                   tot, ntr * NF_KX, ntr, nfill, r0, 1e3 * (tv1 - tv0), nzero, 1e3 * (gi_now() - tv1));
    }
    /* each light's terms where its cache lacks them */
    double tn0 = gi_now();
    nfuse use[GI_SHADE_NF_LC];
    int nu = 0;
    sh->nf_frame++;
    for (size_t l = 0; l < nl; l++) {
        if (!lights[l].enabled || gi_light_has_area(&lights[l]))
            continue;
        gi_light unit;
        float lsc[3];
        gi_light_unit(&lights[l], &unit, lsc);
        struct nflc *c = NULL;
        for (int i = 0; i < GI_SHADE_NF_LC && !c; i++)
            if ((sh->nflc[i].view || sh->nflc[i].pdone) && !memcmp(&sh->nflc[i].light, &unit, sizeof unit))
                c = &sh->nflc[i];
        if (!c) {
            /* the least recently used slot not taken this frame */
            for (int i = 0; i < GI_SHADE_NF_LC; i++)
                if (sh->nflc[i].last_use != sh->nf_frame && (!c || sh->nflc[i].last_use < c->last_use))
                    c = &sh->nflc[i];
            if (!c)
                break; /* more lights than slots: the rest stay interpolated */
            c->light = unit;
            c->view = 0;
            c->pdone = 0;
        }
        c->last_use = sh->nf_frame;
        size_t nx = sh->nf_xo[ns];
        if (c->capx < nx + 1 || c->capp < sh->nf_nph + 1) {
            size_t cx = nx + 1 > c->capx ? nx + 1 : c->capx, cp = sh->nf_nph + 1 > c->capp ? sh->nf_cph + 1 : c->capp;
            float *gx = cx != c->capx ? realloc(c->gx, cx * sizeof *gx) : c->gx;
            if (gx)
                c->gx = gx, c->capx = cx;
            float *gp = cp != c->capp ? realloc(c->gp, cp * sizeof *gp) : c->gp;
            if (gp)
                c->gp = gp, c->capp = cp;
            if (!gx || !gp)
                return NULL;
        }
        if (c->view != sh->view_id) {
            nf_light(sh, sh->nf_xh, nx, &unit, c->gx, threads);
            c->view = sh->view_id;
        }
        if (c->pdone < sh->nf_nph) {
            nf_light(sh, sh->nf_ph + c->pdone, sh->nf_nph - c->pdone, &unit, c->gp + c->pdone, threads);
            c->pdone = sh->nf_nph;
        }
        use[nu].gx = c->gx;
        use[nu].gp = c->gp;
        memcpy(use[nu].sc, lsc, sizeof lsc);
        nu++;
    }
    double tn1 = gi_now();
    /* the points' and the samples' near field this frame */
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
    for (size_t q = 0; q < sh->nvgp; q++) {
        uint32_t i = sh->vgp[q];
        gi_vec3 e = nf_irradiance(sh->nf_ph, sh->nf_po[i], sh->nf_pn[i], NF_KP, use, nu, 1, mats);
        if (o->key_at && o->key_flux0 && sh->nf_pk && (size_t)sh->nf_po[i] + sh->nf_pn[i] <= sh->nf_pkn) {
            /* what the point's own gather read of that first bounce: the
             * keys at its near hits, their entry points' flux over their
             * area. The pixels add the near field back exactly, so the
             * far light must lose what the gather counted, not the exact
             * value: a point beside a sunlit ledge reads the ledge's
             * light through a key that spreads it over the ledge's
             * surroundings, and taking the exact, larger value out left
             * it too little far light (Sponza, a column's foot beside the
             * sunlit floor: 0.27-0.82 of the path tracer's indirect
             * light at the points within 12 cm of the floor, and the
             * pixels ~19% dark). Three gi-hvds seeds, against 512 spp
             * (4096 for sun-b and sun-c): sun-moved 0.0874 / 0.0880 /
             * 0.0877 -> 0.0862 / 0.0869 / 0.0864, arcade-moved 0.0998 /
             * 0.1010 / 0.1017 -> 0.0987 / 0.1004 / 0.0992, sun-b 0.1054 /
             * 0.1072 / 0.1045 -> 0.1006 / 0.1011 / 0.0996, sun-c and
             * arcades-b within +0.0002 / -0.0007. Subtracting the keys'
             * whole radiance there instead (their later bounces too,
             * which the pixels' exact first bounce does not give back)
             * had cost arcades-b 0.0857 -> 0.0928. */
            double a[3] = {0, 0, 0};
            for (uint32_t j = sh->nf_po[i]; j < sh->nf_po[i] + sh->nf_pn[i]; j++) {
                uint32_t k = sh->nf_pk[j];
                if (k == GI_HVDS_NO_KEY)
                    continue;
                for (int c = 0; c < 3; c++)
                    a[c] += (double)o->key_flux0[3 * (size_t)k + c] * sh->h->key_scale[k];
            }
            e = gi_scale(gi_v3((float)a[0], (float)a[1], (float)a[2]), GI_PIf / (float)NF_KP);
        }
        /* what is left is far light, never below 0: the point's 36 near
         * rays estimate what its ~1000 gathering rays read of the near
         * keys, and where one of them finds a bright key the estimate can
         * exceed the whole gather (0.3-0.8% of the visible points on
         * Sponza's frames; one at -65 lux beside 50 pulled a sample on
         * its ledge to 0 where the path tracer has 41 cd/m2). Clamped:
         * sun-moved 0.0847 -> 0.0842, sun-b 0.0973 -> 0.0969, the upper
         * gallery of session 27's unseen frames 0.1911 -> 0.1899; no frame
         * of the set worse (docs/journal.md, "Six frames nobody tuned on") */
        sh->nf_gpe[3 * (size_t)i] = gi_fmaxf(gpe[3 * (size_t)i] - e.x, 0.0f);
        sh->nf_gpe[3 * (size_t)i + 1] = gi_fmaxf(gpe[3 * (size_t)i + 1] - e.y, 0.0f);
        sh->nf_gpe[3 * (size_t)i + 2] = gi_fmaxf(gpe[3 * (size_t)i + 2] - e.z, 0.0f);
    }
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
    for (size_t q = 0; q < sh->nf_nhl; q++) {
        uint32_t i = sh->nf_hl[q], a = sh->nf_xo[i], b = sh->nf_xo[i + 1];
        gi_v3store(sh->nf_tmp + 3 * (size_t)i, nf_irradiance(sh->nf_xh, a, (int)(b - a), NF_KX, use, nu, 0, mats));
    }
#pragma omp parallel for schedule(static) num_threads(threads)
    for (size_t q = 0; q < sh->nf_nwl; q++) {
        uint32_t i = sh->nf_wl[q];
        gi_vec3 e = gi_v3(0, 0, 0);
        for (uint32_t c = sh->nf_co[q]; c < sh->nf_co[q + 1]; c++)
            e = gi_add(e, gi_v3p(sh->nf_tmp + 3 * (size_t)sh->nf_cl[c]));
        gi_v3store(sh->nf_ex + 3 * (size_t)i, gi_scale(e, 1.0f / (float)sh->nf_cc[q]));
    }
    gi_verbose("near field: shadow rays %.1f ms, shading %.1f ms (%zu hits at %zu points, %zu at samples)",
               1e3 * (tn1 - tn0), 1e3 * (gi_now() - tn1), sh->nf_nph, sh->nvgp, (size_t)sh->nf_xo[ns]);
    return sh->nf_gpe;
}

/* Whose near field each edge sample of its own takes (sh->enfsrc, once per
 * view). The pixels' near field is evaluated at the centre samples; the
 * points' irradiance that the splat interpolates has the points' own near
 * field taken out (nf_prepare). An edge sample on the centre's surface takes
 * the centre's; one on another surface (a ledge's top in a pixel whose centre
 * sees its front) that of the nearest centre sample of the 3 x 3 pixels on
 * its surface; with none there, the points' whole irradiance, near field and
 * all, as without the near field. Before, such a sample took the points'
 * irradiance less their near field and nothing back: Sponza's sunlit
 * ledges seen edge-on were ~25 cd/m2 too dark in their indirect light. The
 * decisions are geometry: a light move reads them. 0, or 1 when out of
 * memory. */
#define ENF_NONE UINT32_MAX
#define ENF_GATHER (UINT32_MAX - 1)
static int nf_sources(gi_shade *sh, int w, int h, float pa, int threads)
{
    if (sh->enf_view == sh->view_id && sh->enfsrc)
        return 0;
    const int ne = sh->ne;
    RESERVE_VIEW(enfsrc, sh->nedge * (size_t)ne + 1);
    if (!sh->enfsrc)
        return 1;
    size_t nown = 0, nnb = 0, nall = 0;
#pragma omp parallel for schedule(dynamic, 256) num_threads(threads) reduction(+ : nown, nnb, nall)
    for (size_t e = 0; e < sh->nedge; e++) {
        size_t pix = sh->epix[e];
        int px = (int)(pix % (size_t)w), py = (int)(pix / (size_t)w);
        for (int j = 0; j < ne; j++) {
            size_t q = e * (size_t)ne + (size_t)j;
            const ssurf *es = &sh->esf[q];
            uint32_t best = ENF_NONE;
            if (sh->esrc[q] != UINT32_MAX || sh->erec[q].material == UINT32_MAX) {
                sh->enfsrc[q] = ENF_NONE;
                continue;
            }
            if (glossy_neighbour(es, &sh->sf[pix], pa)) {
                sh->enfsrc[q] = (uint32_t)pix;
                nown++;
                continue;
            }
            float bd = INFINITY;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = px + dx, yy = py + dy;
                    if ((!dx && !dy) || xx < 0 || yy < 0 || xx >= w || yy >= h)
                        continue;
                    size_t c = (size_t)yy * (size_t)w + (size_t)xx;
                    if (!glossy_neighbour(es, &sh->sf[c], pa))
                        continue;
                    float d0 = es->p[0] - sh->sf[c].p[0], d1 = es->p[1] - sh->sf[c].p[1],
                          d2 = es->p[2] - sh->sf[c].p[2], dd = d0 * d0 + d1 * d1 + d2 * d2;
                    if (dd < bd) {
                        bd = dd;
                        best = (uint32_t)c;
                    }
                }
            sh->enfsrc[q] = best != ENF_NONE ? best : ENF_GATHER;
            nnb += best != ENF_NONE;
            nall += best == ENF_NONE;
        }
    }
    sh->enf_view = sh->view_id;
    gi_verbose("near field: edge samples of their own: %zu on their centre's surface, %zu take a neighbour's, "
               "%zu the points' whole irradiance",
               nown, nnb, nall);
    return 0;
}

/* A sample's diffuse reflection of near-field irradiance e. */
static gi_vec3 nf_radiance(const gi_material *mats, uint32_t mat, const float texel[3], const float *e)
{
    const gi_material *m = &mats[mat];
    gi_bsdf b;
    gi_bsdf_init(&b, m, gi_mul(gi_v3p(m->base_color), gi_v3p(texel)));
    return gi_mul(b.kd, gi_scale(gi_v3p(e), GI_INV_PIf));
}

int gi_shade_frame(gi_shade *sh, gi_gbuffer *gb, const gi_camera *cam, int w, int h,
                   const gi_light *lights, size_t num_lights, const gi_material *mats,
                   const float *gpe, const float *gpt, const gi_shade_opts *o, float *rgb, gi_shade_times *times,
                   gi_status *st)
{
    int ss = o->ss < 1 ? 1 : o->ss;
    size_t np = (size_t)w * (size_t)h;
    /* automatic: the share of pixels on edges grows as the image shrinks
     * (perimeter against area), so small images take more samples per edge
     * pixel for the same whole-image error. Cornell box at 64x64: 3 -> 0.064,
     * 5 -> 0.037, 7 -> 0.032 nrmse (camera-moved frame against 4096 spp).
     * 7 (with --coverage 11) from 20k pixels too since 2026-12-07, when 5
     * had been the default there: Sponza at 320x240 against 1024-4096 spp,
     * f1-f4 0.0826 0.0907 0.1091 0.0648 -> 0.0785 0.0892 0.1024 0.0635, u1-u6
     * 0.0409 0.0578 0.1480 0.0415 0.0311 0.1816 -> 0.0400 0.0563 0.1403
     * 0.0408 0.0307 0.1815; frames ~1.5x as long (f.script 2.15 -> 3.17 s,
     * the G-buffer ~1.8x), about what a 640x480 view spends on its edges at
     * 3. The Cornell box's more-variants (256x256) at most 0.0012 better. */
    int aa = o->aa == 0 ? (np >= 200000 ? 3 : 7) : (o->aa >= 3 ? (o->aa | 1) : 1);
    if (aa > GI_SHADE_AA_MAX)
        aa = GI_SHADE_AA_MAX;
    int threads = o->threads > 0 ? o->threads : omp_get_num_procs();
    double t0 = gi_now();
    int texf = o->tex_filter != 0;
    /* automatic: aa + 4 rays a side. Sponza 640x480 (--aa 3): nrmse
     * 0.1190 -> 0.1124 (sun-moved), 0.1187 -> 0.1097 (arcade-moved); the
     * Cornell box 0.0570 -> 0.0531 (camera-moved); light moves cost the
     * same, camera moves ~115 ms more on Sponza (G-buffer medians
     * 292 -> 407 ms on a 20-frame camera script) */
    int cov = o->coverage == 0 ? aa + 4 : (o->coverage >= 2 ? o->coverage : 0);
    if (!(ss == 1 && aa >= 3))
        cov = 0;
    if (cov > GI_SHADE_COV_MAX)
        cov = GI_SHADE_COV_MAX;
    if (!sh->valid || sh->pw != w || sh->ph != h || sh->pss != ss || sh->ptexf != texf || sh->paa != aa ||
        sh->pcov != cov || !same_camera(&sh->pcam, cam) ||
        sh->plin != (o->interp_linear != 0)) {
        sh->lin = o->interp_linear != 0;
        int rc = prepare_view(sh, gb, cam, w, h, ss, texf, aa, cov, threads, st);
        if (rc)
            return rc;
    }
    gi_camera_frame_init(&sh->cf, cam, w, h);
    double t1 = gi_now();
    int ka = (int)ceilf(sqrtf((float)(o->area_samples > 0 ? o->area_samples : 1)));
    int has_area = 0;
    for (size_t l = 0; l < num_lights; l++)
        has_area |= lights[l].enabled && lights[l].type == GI_LIGHT_AREA; /* drawn: mesh lights are geometry */
    const int S = ss * ss;
    const int NE = sh->ne;
    /* materials changed since the cached direct light was computed: the
     * pixels with a sample on one of them are recomputed */
    const size_t nm = sh->s->num_materials;
    uint8_t *mchanged = calloc(nm ? nm : 1, 1), *mask = NULL;
    if (!mchanged)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    int any_changed = 0;
    for (size_t m = 0; m < nm; m++) {
        mchanged[m] = !sh->pmats || sh->npmats != nm || memcmp(&sh->pmats[m], &mats[m], sizeof mats[m]) != 0;
        any_changed |= mchanged[m];
    }
    if (any_changed) {
        mask = calloc(np, 1);
        if (!mask) {
            free(mchanged);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        }
        for (size_t pix = 0; pix < np; pix++) {
            for (int k = 0; k < S && !mask[pix]; k++) {
                uint32_t mt = sh->smat[(size_t)k * np + pix];
                mask[pix] = mt != UINT32_MAX && mchanged[mt];
            }
            uint32_t e = sh->eidx ? sh->eidx[pix] : UINT32_MAX;
            for (int j = 0; e != UINT32_MAX && j < NE && !mask[pix]; j++) {
                uint32_t mt = sh->esmat[(size_t)e * (size_t)NE + (size_t)j];
                mask[pix] = mt != UINT32_MAX && mchanged[mt];
            }
        }
        free(sh->pmats);
        sh->pmats = malloc((nm ? nm : 1) * sizeof *sh->pmats);
        if (sh->pmats)
            memcpy(sh->pmats, mats, nm * sizeof *mats);
        sh->npmats = sh->pmats ? nm : 0;
    }
    free(mchanged);
    /* pass 1: emission (light that reaches the camera without a bounce:
     * part of the direct light), then each light's direct light from its
     * cache or computed (shadow rays as packets) */
    int emits = 0; /* some material emits: else pass 1 starts from black */
    for (size_t m = 0; m < nm && o->direct; m++)
        emits |= gi_maxc(gi_v3p(mats[m].emission)) > 0.0f;
#pragma omp parallel for schedule(static) num_threads(threads)
    for (size_t pix = 0; pix < np; pix++) {
        if (!emits) {
            rgb[3 * pix] = rgb[3 * pix + 1] = rgb[3 * pix + 2] = 0.0f;
            continue;
        }
        gi_vec3 sum = gi_v3(0, 0, 0);
        int count = S;
        for (int k = 0; k < S && o->direct; k++) {
            uint32_t mt = sh->smat[(size_t)k * np + pix];
            if (mt != UINT32_MAX)
                sum = gi_add(sum, gi_v3p(mats[mt].emission));
        }
        uint32_t e = sh->eidx ? sh->eidx[pix] : UINT32_MAX;
        if (e != UINT32_MAX && sh->ew) {
            const float *ew = sh->ew + (size_t)e * (size_t)(NE + 1);
            sum = gi_scale(sum, ew[NE]);
            for (int j = 0; j < NE && o->direct; j++) {
                uint32_t mt = sh->esmat[(size_t)e * (size_t)NE + (size_t)j];
                if (mt != UINT32_MAX)
                    sum = gi_madd(sum, gi_v3p(mats[mt].emission), ew[j]);
            }
            count = 1;
        } else if (e != UINT32_MAX) {
            for (int j = 0; j < NE && o->direct; j++) {
                uint32_t mt = sh->esmat[(size_t)e * (size_t)NE + (size_t)j];
                if (mt != UINT32_MAX)
                    sum = gi_add(sum, gi_v3p(mats[mt].emission));
            }
            count += NE;
        }
        gi_v3store(rgb + 3 * pix, gi_scale(sum, 1.0f / (float)count));
    }
    sh->frame_no++;
    int fail = 0;
    for (size_t l = 0; o->direct && l < num_lights && !fail; l++) {
        if (!lights[l].enabled)
            continue;
        /* computed for the light at strength 1 and white, then scaled: a
         * light only dimmed or tinted keeps its cached pixels (Sponza, the
         * sun dimmed: direct light ~50 -> ~1 ms) */
        gi_light unit;
        float lsc[3];
        gi_light_unit(&lights[l], &unit, lsc);
        const gi_light *lt = &unit;
        struct dcache *d = NULL;
        for (int i = 0; i < GI_SHADE_DCACHE && !d && !o->no_cache; i++)
            if (sh->dc[i].view_id == sh->view_id && sh->dc[i].index == l &&
                !memcmp(&sh->dc[i].light, lt, sizeof *lt))
                d = &sh->dc[i];
        const uint8_t *m = mask;
        if (!d) {
            /* the least recently used slot whose buffers fit (an empty one
             * first), not needed by this frame; else the least recently used */
            if (dcache_warm(sh, np)) {
                fail = 1;
                break;
            }
            for (int i = 0; i < GI_SHADE_DCACHE; i++) {
                struct dcache *c = &sh->dc[i];
                if (c->rgb && c->np == np && c->last_use != sh->frame_no &&
                    (!d || (c->view_id ? c->last_use : 0) < (d->view_id ? d->last_use : 0)))
                    d = c;
            }
            if (!d) {
                d = &sh->dc[0];
                for (int i = 1; i < GI_SHADE_DCACHE; i++)
                    if (sh->dc[i].last_use < d->last_use)
                        d = &sh->dc[i];
            }
            if (!d->rgb || d->np != np) {
                free(d->rgb);
                free(d->vis);
                free(d->ec);
                d->rgb = gi_alloc_large(np * 3 * sizeof *d->rgb);
                d->vis = gi_alloc_large(np);
                d->ec = gi_alloc_large(np * sizeof *d->ec);
                d->np = np;
            }
            if (!d->rgb || !d->vis || !d->ec) {
                fail = 1;
                break;
            }
            d->light = *lt;
            d->index = l;
            d->view_id = 0;
            m = NULL; /* every pixel */
        } else if (!any_changed) {
            m = NULL;
        }
        if (!(d->view_id == sh->view_id && !any_changed)) {
            int use_vis = S == 1 && NE > 0 && !gi_light_has_area(lt);
            if (light_pass(sh, cam, w, h, lt, l, mats, o, ka, m, d->rgb, use_vis ? d->vis : NULL, d->ec, threads)) {
                d->view_id = 0;
                fail = 1;
                break;
            }
            d->view_id = sh->view_id;
        }
        d->last_use = sh->frame_no;
        const float *src = d->rgb;
#pragma omp parallel for schedule(static) num_threads(threads)
        for (size_t i = 0; i < np; i++)
            for (int c = 0; c < 3; c++)
                rgb[3 * i + (size_t)c] += src[3 * i + (size_t)c] * lsc[c];
    }
    free(mask);
    if (fail)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for direct light");
    if (has_area && o->direct) /* light seen without a bounce: part of the direct light */
        visible_area_lights(sh, cam, w, h, lights, num_lights, rgb, threads);
    double t2 = gi_now();
    if (o->indirect && gpe && o->gather)
        o->gather(o->gather_ctx, sh->vgp, sh->nvgp);
    double t2g = gi_now();
    /* pass 2: indirect light from the cached interpolation weights: each
     * sf sample from its packed record, then each pixel's average, where an
     * edge sample that reused a neighbour's weights takes its value */
    if (o->indirect && gpe) {
        const size_t ns = np * (size_t)S;
        uint8_t *glossy = malloc(nm ? nm : 1);
        if (!glossy)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        /* 1: a glossy lobe (ks > 0 for some base colour, whatever the
         * texel); 2: one that gathers (gi_shade_gathers) */
        int any_gather = 0;
        for (size_t m = 0; m < nm; m++) {
            gi_bsdf b;
            gi_bsdf_init(&b, &mats[m], gi_v3p(mats[m].base_color));
            glossy[m] = b.exponent > 0.0f ? (uint8_t)(1 + gi_shade_gathers(&mats[m], o)) : 0;
            any_gather |= glossy[m] == 2;
        }
        int gather = any_gather && o->key_at && o->key_flux;
        /* glossy samples: their gathers (traced once per view and exponent),
         * then the gathered term of each, in gterm. With one sample per
         * pixel only the pixels on a grid gather (gdo 1), and the others (2)
         * take the terms of the gathers within a window around, on their
         * surface, unless there is none: those gather too (3). The grid is
         * every other pixel of every other row (--glossy-stride), the window
         * 7 x 7 pixels (~16 gathers, ~550 rays): Sponza, a metal floor under
         * a sun and a lamp, 640 x 480, the splat of a roughness change
         * 0.94-1.09 s -> 0.29-0.30 s against gathers at every pixel over
         * 5 x 5; against 144-ray gathers at every pixel (320 x 240), nrmse
         * 0.012 -> 0.017 (metallic 1, roughness 0.3) and 0.011 -> 0.014
         * (0.15). A lobe that blurs more than a window twice as wide
         * (GI_SHADE_GLOSSY_WIDE: at 640 x 480, roughness 0.25 and up) gathers
         * on a grid twice as coarse, over 15 x 15 pixels (~16 gathers
         * again): a quarter of the rays. With
         * several samples a pixel (--ss) every sample gathers; the window
         * averages the samples of one jitter. */
        const int S1 = S == 1;
        const size_t gs = o->glossy_stride >= 1 ? (size_t)o->glossy_stride : 2;
        const float pa = 2.0f * tanf(0.5f * cam->yfov) / (float)h;
        /* per material: its lobe's exponent at the base colour, its grid's
         * spacing and its window's half-width */
        const size_t nm1 = nm ? nm : 1;
        float *mexp = malloc(nm1 * (sizeof *mexp + 2));
        if (!mexp) {
            free(glossy);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        }
        uint8_t *mgs = (uint8_t *)(mexp + nm1), *mwin = mgs + nm1;
        for (size_t m = 0; m < nm; m++) {
            gi_bsdf b;
            gi_bsdf_init(&b, &mats[m], gi_v3p(mats[m].base_color));
            mexp[m] = b.exponent;
            size_t g = gs;
            /* (--glossy-stride 1 stays every pixel, for final frames) */
            if (S1 && gs >= 2 && glossy[m] == 2 && b.exponent > 0.0f &&
                (float)(4 * gs - 1) * pa * sqrtf(b.exponent + 2.0f) <= GI_SHADE_GLOSSY_WIDE)
                g = 2 * gs;
            g = g < 16 ? g : 16;
            mgs[m] = (uint8_t)(S1 ? g : 1);
            mwin[m] = (uint8_t)(S1 && g > gs ? 2 * (int)g - 1 : GI_SHADE_GLOSSY_WIN);
        }
        /* lobes narrower than the fine grid's window draw fewer rays (glossy_nrays) */
        {
            float wa = (float)(2 * GI_SHADE_GLOSSY_WIN + 1) * pa;
            sh->gsharp = S1 && gs >= 2 && GI_SHADE_GLOSSY_WIN >= 1 && wa > 0.0f ? 1.0f / (wa * wa) - 2.0f : INFINITY;
        }
        /* the slots: one per grid pixel (at the finest spacing, gs), then
         * the lone gathers of the frame; with --ss one per sample */
        /* the grid's pixels at even (x / gs, y / gs) first, the coarse
         * grid's, side by side: a frame whose gathers are all coarse
         * touches a quarter of the slots' memory, not half of it (fresh
         * pages cost a fault each: Sponza's first metal frame 2887 -> 2357
         * faults) */
        const size_t gsw = S1 ? ((size_t)w + gs - 1) / gs : 0, gsh = S1 ? ((size_t)h + gs - 1) / gs : 0;
        const size_t ncoarse = ((gsw + 1) / 2) * ((gsh + 1) / 2);
        const size_t ngrid = S1 ? ncoarse + gsw * gsh : ns;
        if (gather && sh->gr != o->glossy_rays) {
            sh->gr = o->glossy_rays;
            sh->cap_gexp = 0; /* other sizes: reallocate */
        }
        if (gather && sh->cap_gkey < ns) {
            free(sh->gterm);
            free(sh->gdo);
            sh->gterm = malloc(3 * ns * sizeof *sh->gterm);
            sh->gdo = calloc(ns, 1);
            sh->cap_gkey = sh->gterm && sh->gdo ? ns : 0;
        }
        if (gather && sh->cap_gexp < ngrid && !glossy_slots(sh, ngrid + ngrid / 16 + 64)) {
            free(mexp);
            free(glossy);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for glossy gathers");
        }
        if (gather && !sh->cap_gkey) {
            free(mexp);
            free(glossy);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for glossy gathers");
        }
        uint8_t *gself = NULL;
        if (gather && S1 && !(gself = calloc(ns, 1))) {
            free(mexp);
            free(glossy);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for glossy gathers");
        }
        sh->gdrawn = sh->grays = 0;
        double ts0 = gi_now();
        size_t nlone = 0;
        uint32_t *lone = NULL; /* the lone gathers' samples, in order */
        if (gather) {
#pragma omp parallel num_threads(threads)
            {
                gi_rt_thread_init();
#pragma omp for schedule(dynamic, 256)
                for (size_t i = 0; i < ns; i++) {
                    const ssurf *sf = &sh->sf[i];
                    sh->gdo[i] = 0;
                    if (sh->rec[i].material == UINT32_MAX || glossy[sh->rec[i].material] != 2 || !sf->valid)
                        continue;
                    const float ex = mexp[sf->material];
                    if (!(ex > 0.0f))
                        continue;
                    const size_t g = mgs[sf->material], x = i % (size_t)w, y = i / (size_t)w;
                    if (S1 && (x % g || y % g)) {
                        sh->gdo[i] = 2;
                        continue;
                    }
                    const size_t q = S1 ? grid_slot(x / gs, y / gs, gsw, ncoarse) : i;
                    glossy_ready(sh, sf, i, q, ex, o);
                    gi_v3store(sh->gterm + 3 * i, glossy_term(sh, q, o->key_flux));
                    sh->gdo[i] = 1;
                }
                /* a coarse grid's pixels on the fine grid gather too where
                 * few of the coarse gathers around lie on their surface (a
                 * column, curved within the window): GI_SHADE_GLOSSY_FEW */
#pragma omp for schedule(dynamic, 256)
                for (size_t i = 0; i < ns; i++) {
                    if (!S1 || sh->gdo[i] != 2)
                        continue;
                    const ssurf *sf = &sh->sf[i];
                    const size_t g = mgs[sf->material], x = i % (size_t)w, y = i / (size_t)w;
                    if (g == gs || x % gs || y % gs)
                        continue;
                    const int R = mwin[sf->material], gg = (int)g;
                    int x0 = (int)x - R > 0 ? (int)x - R : 0, x1 = (int)x + R < w - 1 ? (int)x + R : w - 1;
                    int y0 = (int)y - R > 0 ? (int)y - R : 0, y1 = (int)y + R < h - 1 ? (int)y + R : h - 1;
                    int cnt = 0;
                    for (int yy = (y0 + gg - 1) / gg * gg; yy <= y1 && cnt < GI_SHADE_GLOSSY_FEW; yy += gg)
                        for (int xx = (x0 + gg - 1) / gg * gg; xx <= x1 && cnt < GI_SHADE_GLOSSY_FEW; xx += gg) {
                            size_t j = (size_t)yy * (size_t)w + (size_t)xx;
                            cnt += sh->gdo[j] == 1 && glossy_neighbour(sf, &sh->sf[j], pa);
                        }
                    if (cnt >= GI_SHADE_GLOSSY_FEW)
                        continue;
                    const size_t q = grid_slot(x / gs, y / gs, gsw, ncoarse);
                    glossy_ready(sh, sf, i, q, mexp[sf->material], o);
                    gi_v3store(sh->gterm + 3 * i, glossy_term(sh, q, o->key_flux));
                    sh->gdo[i] = 4; /* (read as 1 from the next loop on) */
                }
#pragma omp for schedule(static)
                for (size_t i = 0; i < ns; i++)
                    if (sh->gdo[i] == 4)
                        sh->gdo[i] = 1;
                /* the pixels left without a gathered neighbour */
#pragma omp for schedule(dynamic, 256)
                for (size_t i = 0; i < ns; i++) {
                    if (!S1 || sh->gdo[i] != 2)
                        continue;
                    const ssurf *sf = &sh->sf[i];
                    const int R = mwin[sf->material], gg = (int)gs;
                    int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w), found = 0;
                    int x0 = x - R > 0 ? x - R : 0, x1 = x + R < w - 1 ? x + R : w - 1;
                    int y0 = y - R > 0 ? y - R : 0, y1 = y + R < h - 1 ? y + R : h - 1;
                    for (int yy = (y0 + gg - 1) / gg * gg; yy <= y1 && !found; yy += gg)
                        for (int xx = (x0 + gg - 1) / gg * gg; xx <= x1 && !found; xx += gg) {
                            size_t j = (size_t)yy * (size_t)w + (size_t)xx;
                            found = sh->gdo[j] == 1 && glossy_neighbour(sf, &sh->sf[j], pa);
                        }
                    gself[i] = (uint8_t)!found;
                }
            }
            /* their slots in order, so that a later frame finds its gathers */
            for (size_t i = 0; gself && i < ns; i++)
                nlone += gself[i];
            if (nlone && !(lone = malloc(nlone * sizeof *lone))) {
                free(gself);
                free(mexp);
                    free(glossy);
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for glossy gathers");
            }
            for (size_t i = 0, k = 0; nlone && i < ns; i++)
                if (gself[i])
                    lone[k++] = (uint32_t)i;
            if (nlone && ngrid + nlone > sh->cap_gexp && !glossy_slots(sh, ngrid + 2 * nlone + 64)) {
                free(lone);
                free(gself);
                free(mexp);
                    free(glossy);
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for glossy gathers");
            }
#pragma omp parallel num_threads(threads)
            {
                gi_rt_thread_init();
#pragma omp for schedule(dynamic, 16)
                for (size_t k = 0; k < nlone; k++) {
                    size_t i = lone[k];
                    const ssurf *sf = &sh->sf[i];
                    glossy_ready(sh, sf, i, ngrid + k, mexp[sf->material], o);
                    gi_v3store(sh->gterm + 3 * i, glossy_term(sh, ngrid + k, o->key_flux));
                }
            }
        }
        /* each sample's indirect light; a glossy sample averages the terms
         * gathered within (2R + 1)^2 pixels on its surface (same material,
         * normals within ~11 degrees, on its plane): many times the rays
         * where the reflection changes slowly, as it does across a glossy
         * lobe */
        /* the near field: each sample's own, the points' irradiance less theirs */
        double ts1 = gi_now();
        const float r0 = o->near_field < 0.0f ? GI_SHADE_NF_AUTO * sh->h->opts.r_max : o->near_field;
        const float *gpe_all = gpe;
        gpe = nf_prepare(sh, gpe, ns, r0, lights, num_lights, mats, threads, o);
        if (!gpe) {
            free(lone);
            free(gself);
            free(mexp);
            free(glossy);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the near field");
        }
        const float *nfe = gpe != gpe_all ? sh->nf_ex : NULL;
        double ts2 = gi_now();
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads)
        for (size_t i = 0; i < ns; i++) {
            gi_vec3 v;
            const ssurf *sf = &sh->sf[i];
            if (gather && sh->gdo[i]) {
                gi_vec3 g = gi_v3(0, 0, 0);
                float wsum = 0.0f;
                /* with several samples a pixel (--ss) every sample
                 * gathers, and the window runs over the samples of the same
                 * jitter (k) in the pixels around (it read x = y = 0 then:
                 * every sample took sample 0's term, and a metal floor at
                 * --ss 2 reflected nothing) */
                const size_t k = i / np, pix = i % np;
                /* the gathers on the grid, then the lone ones, each
                 * weighed by glossy_wt: the window's edges ramp over one
                 * grid spacing (a box's steps made blocks) */
                const int R = mwin[sf->material], gg = S1 ? (int)gs : 1;
                const int G = S1 ? (int)mgs[sf->material] : 1, RR = R + G / 2;
                int x = (int)(pix % (size_t)w), y = (int)(pix / (size_t)w);
                int x0 = x - RR > 0 ? x - RR : 0, x1 = x + RR < w - 1 ? x + RR : w - 1;
                int y0 = y - RR > 0 ? y - RR : 0, y1 = y + RR < h - 1 ? y + RR : h - 1;
                for (int yy = (y0 + gg - 1) / gg * gg; yy <= y1; yy += gg) {
                    const float wy = glossy_wt(yy - y, R, G);
                    for (int xx = (x0 + gg - 1) / gg * gg; xx <= x1; xx += gg) {
                        size_t j = k * np + (size_t)yy * (size_t)w + (size_t)xx;
                        float wt = wy * glossy_wt(xx - x, R, G);
                        if (!(wt > 0.0f) || sh->gdo[j] != 1 || (j != i && !glossy_neighbour(sf, &sh->sf[j], pa)))
                            continue;
                        g = gi_madd(g, gi_v3p(sh->gterm + 3 * j), wt);
                        wsum += wt;
                    }
                }
                for (int yy = y0; nlone && yy <= y1; yy++) {
                    /* (only with one sample a pixel, k = 0) */
                    uint32_t a = (uint32_t)((size_t)yy * (size_t)w + (size_t)x0);
                    size_t lo = 0, hi = nlone;
                    while (lo < hi) {
                        size_t md = lo + (hi - lo) / 2;
                        if (lone[md] < a)
                            lo = md + 1;
                        else
                            hi = md;
                    }
                    const float wy = glossy_wt(yy - y, R, G);
                    for (; lo < nlone && lone[lo] <= (uint32_t)((size_t)yy * (size_t)w + (size_t)x1); lo++) {
                        size_t j = lone[lo];
                        float wt = wy * glossy_wt((int)(j % (size_t)w) - x, R, G);
                        if (!(wt > 0.0f) || (j != i && !glossy_neighbour(sf, &sh->sf[j], pa)))
                            continue;
                        g = gi_madd(g, gi_v3p(sh->gterm + 3 * j), wt);
                        wsum += wt;
                    }
                }
                g = gi_scale(g, wsum > 0.0f ? 1.0f / wsum : 0.0f);
                v = indirect_sample(sh, sf, mats, gpe, gpt, &g, nfe ? nfe + 3 * i : NULL);
            } else if (nfe && sh->rec[i].material != UINT32_MAX && glossy[sh->rec[i].material]) {
                v = indirect_sample(sh, sf, mats, gpe, gpt, NULL, nfe + 3 * i);
            } else {
                v = splat_rec(sh, &sh->rec[i], sf, glossy, mats, gpe, gpt);
                if (nfe && sh->rec[i].material != UINT32_MAX && gi_maxc(gi_v3p(nfe + 3 * i)) > 0.0f)
                    v = gi_add(v, nf_radiance(mats, sh->rec[i].material, sh->rec[i].texel, nfe + 3 * i));
            }
            gi_v3store(sh->cind + 3 * i, v);
        }
        if (nfe && sh->eidx && sh->nedge && nf_sources(sh, w, h, pa, threads)) {
            free(lone);
            free(gself);
            free(mexp);
            free(glossy);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the near field");
        }
#pragma omp parallel for schedule(dynamic, 1024) num_threads(threads)
        for (size_t pix = 0; pix < np; pix++) {
            gi_vec3 sum = gi_v3(0, 0, 0);
            int count = S;
            for (int k = 0; k < S; k++)
                sum = gi_add(sum, gi_v3p(sh->cind + 3 * ((size_t)k * np + pix)));
            uint32_t e = sh->eidx ? sh->eidx[pix] : UINT32_MAX;
            if (e != UINT32_MAX) {
                const float *ew = sh->ew ? sh->ew + (size_t)e * (size_t)(NE + 1) : NULL;
                if (ew)
                    sum = gi_scale(sum, ew[NE]);
                for (int j = 0; j < NE; j++) {
                    size_t q = (size_t)e * (size_t)NE + (size_t)j;
                    uint32_t src = sh->esrc[q];
                    /* an edge sample of its own takes the near field
                     * nf_sources found it, or with none the points' whole
                     * irradiance */
                    const uint32_t nfs = src == UINT32_MAX && nfe ? sh->enfsrc[q] : ENF_NONE;
                    gi_vec3 v = src != UINT32_MAX ? gi_v3p(sh->cind + 3 * (size_t)src) : gi_v3(0, 0, 0);
                    /* (a glossy sample keeps its centre's light: its
                     * lobe's gather is the centre's) */
                    if (src == UINT32_MAX || (!glossy[sh->erec[q].material] &&
                                              !texel_scaled(v, sh->erec[q].texel, sh->rec[src].texel, &v)))
                        v = splat_rec(sh, &sh->erec[q], &sh->esf[q], glossy, mats,
                                      nfs == ENF_GATHER || src != UINT32_MAX ? gpe_all : gpe, gpt);
                    if (nfs < ENF_GATHER && gi_maxc(gi_v3p(nfe + 3 * (size_t)nfs)) > 0.0f)
                        v = gi_add(v, nf_radiance(mats, sh->erec[q].material, sh->erec[q].texel,
                                                  nfe + 3 * (size_t)nfs));
                    sum = ew ? gi_madd(sum, v, ew[j]) : gi_add(sum, v);
                }
                count = ew ? 1 : count + NE;
            }
            float *out = rgb + 3 * pix;
            float sc = 1.0f / (float)count;
            out[0] += sum.x * sc;
            out[1] += sum.y * sc;
            out[2] += sum.z * sc;
        }
        if (gather)
        {
            size_t n1 = 0, n2 = 0, n3 = 0;
            for (size_t i = 0; i < np * (size_t)S; i++) {
                n1 += sh->gdo[i] == 1;
                n2 += sh->gdo[i] == 2;
                n3 += gself && gself[i];
            }
            gi_verbose("splat: glossy gathers %.1f ms (%zu on the grid, %zu of %zu others alone), %zu drawn of %zu rays, "
                       "near field %.1f ms, samples and pixels %.1f ms",
                       1e3 * (ts1 - ts0), n1, n3, n2, sh->gdrawn, sh->grays, 1e3 * (ts2 - ts1),
                       1e3 * (gi_now() - ts2));
        }
        free(lone);
        free(gself);
        free(mexp);
        free(glossy);
    }
    double t3 = gi_now();
    if (times) {
        times->gbuffer = t1 - t0;
        times->direct = t2 - t1;
        times->gather = t2g - t2;
        times->splat = t3 - t2g;
    }
    return 0;
}
