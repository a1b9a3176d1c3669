/* gi_shade.h - the screen-space half of a relight frame: surfaces from the
 * OSMesa G-buffer, direct light with exact (Embree) shadows, area lights by
 * stratified jittered samples (Fournier-Peroche style), and indirect light
 * interpolated per pixel from the gathering points' irradiance with
 * irradiance-cache weights, times the surface's reflectance.
 *
 * Call order: gi_shade_new (builds a spatial grid of the gathering points),
 * gi_shade_frame per frame, gi_shade_free. The G-buffer is rasterised again
 * only when the camera or size changes. Output: linear cd/m^2, RGB, row 0 at
 * the top. Same BRDF and light code as the reference path tracer. */
#ifndef GI_SHADE_H
#define GI_SHADE_H

#include <stddef.h>
#include <stdint.h>

#include "gi_gbuffer.h"
#include "gi_hvds.h"
#include "gi_rt.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_shade gi_shade;

typedef struct gi_shade_opts {
    int area_samples;   /* jittered samples per area light per pixel sample (default 16) */
    int ss;             /* ss x ss G-buffer samples per pixel (default 1: pixel centre) */
    int tex_filter;     /* 1 (default): textures averaged over each sample's footprint
                           (gi_texfilter); 0: one bilinear lookup at the sample */
    int aa;             /* with ss == 1: pixels on geometric edges (silhouettes, creases,
                           material borders) and hard shadow edges get aa x aa samples
                           (odd; 1: off; 0, the default: 3 from 200k pixels up, 7
                           below) */
    int edge_refine;    /* 1 (default): edge pixels whose samples see a strong contrast of
                           a point, spot or directional light's irradiance (more than 8x
                           its mean over the image) get 16 more samples of it; 0: off */
    float refine_contrast; /* that multiple (default 8) */
    int coverage;       /* with aa >= 3: each edge pixel's samples weighted by their share
                           of coverage x coverage camera rays (0, the default: aa + 4;
                           1: equal shares) */
    int interp_linear;  /* 1 (default): a pixel sample's indirect light is half the weighted
                           mean of its gathering points' irradiance and half their weighted
                           linear fit (gi_shade.c, linear_fit); 0: the mean alone (the
                           irradiance cache's) */
    /* near field: the first bounce of direct light off surfaces within
     * near_field metres of a pixel sample, computed at the sample (short
     * rays, traced once per view, and a shadow ray per hit and light per
     * frame) instead of interpolated between gathering points, which cannot
     * follow its peak along a concave crease beside a lit face (gi_shade.c,
     * near-field). < 0 (default): 1.25 times the .gih's R+; 0: off. Point,
     * spot and directional lights; area and emissive lights stay
     * interpolated. */
    float near_field;
    /* the near field's samples: those whose x and y are multiples of this
     * trace their rays, and each sample takes the mean of the 3 x 3 traced
     * around it on its surface (1-4; 0, the default: 2, and then every
     * other sample beside one that found something, with the mean over
     * 3 x 3 pixels) */
    int near_stride;
    int direct;         /* include direct light (default 1) */
    int indirect;       /* include interpolated indirect light (default 1) */
    uint64_t seed;
    int threads;
    /* glossy reflection of indirect light by gathering at the pixel: each
     * visible glossy sample traces glossy_rays rays from its lobe once per
     * view and reads the radiance of the keys they hit every frame,
     * key_flux[k] * key_scale[k]. key_at (NULL: the gathering points' linear
     * fit instead) maps n hits (p, nrm: 3 floats each) to their keys; key_ctx
     * is its first argument. */
    int glossy_rays;    /* default 36; 0: off */
    /* only lobes whose ks (max over RGB, at the material's base colour
     * factor) is at least this gather; the rest take the linear fit
     * (default GI_SHADE_GATHER_KS) */
    float glossy_min_ks;
    /* with one sample per pixel, the pixels whose x and y are multiples of
     * this gather (default 2; 1: every pixel), the rest averaging the
     * gathers within 7 x 7 pixels on their surface (values < 1: 2); with 2
     * or more, lobes wider than a window twice as wide (at 640 x 480,
     * roughness 0.25 and up) at multiples of twice it, over (4 x it - 1)^2
     * pixels (gi_shade.c, GI_SHADE_GLOSSY_WIDE) */
    int glossy_stride;
    void (*key_at)(const void *ctx, size_t n, const float *p, const float *nrm, uint32_t *out);
    const void *key_ctx;
    const float *key_flux;
    /* NULL, or the entry points' share of key_flux (gi_relight_key_flux0):
     * with key_at, a gathering point's near field is taken out of its
     * irradiance as its gather read it from the keys (the first bounce off
     * the surfaces its near rays find), not as computed exactly */
    const float *key_flux0;
    /* NULL, or called before the indirect light with the gathering points
     * the view reads (sorted, each once), so that only those need values
     * (gi_relight_gather); gather_ctx is its first argument */
    void (*gather)(void *ctx, const uint32_t *idx, size_t n);
    void *gather_ctx;
    int no_cache;       /* 1: recompute every light's direct light every frame (tests
                           compare it with the cached path; gi-relight sets it when
                           GI_RELIGHT_NO_CACHE=1) */
} gi_shade_opts;

typedef struct gi_shade_times {
    double gbuffer;     /* rasterisation + read-back (0 when reused) */
    double direct;      /* direct light */
    double gather;      /* opts.gather, for the points the view reads */
    double splat;       /* indirect interpolation ("splatting") and composition */
} gi_shade_times;

void gi_shade_opts_default(gi_shade_opts *o);
/* 1 if material m's glossy lobe gathers at the pixels under options o: a
 * dielectric's lobe (ks = 0.04) reflects too little for the rays to pay.
 * Sponza, the floor glossy under a sun and a lamp, 320 x 240: the linear fit
 * instead of 144-ray gathers differs by nrmse 0.002 for a dielectric of
 * roughness 0.1, 0.2 or 0.5, by 0.006 at metallic 0.25 (ks ~ 0.2), 0.016 at
 * 0.5 and 0.10 at 1; 36 rays cost ~1 s per roughness change at 640 x 480. */
#define GI_SHADE_GATHER_KS 0.1f
int gi_shade_gathers(const gi_material *m, const gi_shade_opts *o);
int gi_shade_new(const gi_scene *s, const gi_rt *rt, const gi_hvds *h, gi_shade **out, gi_status *st);
void gi_shade_free(gi_shade *sh);
/* Render one frame into rgb (3 floats per pixel). gp_irradiance: 3 floats per
 * gathering point (gi_relight_gpoint_irradiance); gp_gradient: 9 per point
 * (gi_relight_gpoint_gradient) or NULL, for low-frequency glossy reflection. */
int gi_shade_frame(gi_shade *sh, gi_gbuffer *gb, const gi_camera *cam, int w, int h,
                   const gi_light *lights, size_t num_lights, const gi_material *mats,
                   const float *gp_irradiance, const float *gp_gradient, const gi_shade_opts *o, float *rgb,
                   gi_shade_times *times, gi_status *st);
/* Interpolated indirect irradiance (lux, RGB) at surface point p with
 * oriented normal n, as a pixel sample there gets it: linear 1, half the
 * weighted mean and half the weighted linear fit (gi_shade_opts.interp_linear's
 * default), 0 the mean alone; clamped at 0; 0 if no gathering point is near.
 * For tests and tools. */
void gi_shade_irradiance_at(const gi_shade *sh, const float *gp_irradiance, const float p[3],
                            const float n[3], int linear, float e[3]);

#ifdef __cplusplus
}
#endif
#endif
