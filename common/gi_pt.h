/* gi_pt.h - the reference: an unbiased Monte Carlo path tracer on Embree.
 *
 * Next-event estimation on every light type, multiple importance sampling
 * (power heuristic) for area lights and emissive triangles, Russian roulette
 * without a bounce cap (max_bounces < 0), the shared BRDF (gi_brdf.h) and
 * light code (gi_light.h), base-colour textures. Random numbers are seeded by
 * (seed, pixel or point, sample index), so results do not depend on threads.
 *
 * Call order: gi_pt_new (per frame state: lights and materials of the frame),
 * then gi_pt_render or gi_pt_sensors any number of times, then gi_pt_free.
 * Surfaces: a single-sided triangle seen from behind absorbs (black, opaque);
 * emission leaves the front side only unless the material is double sided.
 * Script area lights are not geometry: they do not block light. */
#ifndef GI_PT_H
#define GI_PT_H

#include <stddef.h>
#include <stdint.h>

#include "gi_rng.h"
#include "gi_rt.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_pt_opts {
    uint64_t seed;
    int max_bounces;     /* < 0: unlimited (Russian roulette only); 0: direct light only */
    int min_bounces;     /* leave out light that bounced fewer times (0: keep all; 1: indirect
                            light only, what gi-relight's gathering points estimate) */
    int threads;         /* 0: all cores */
    int progress;        /* report progress on stderr */
} gi_pt_opts;

void gi_pt_opts_default(gi_pt_opts *o);

typedef struct gi_pt gi_pt;

/* lights/materials are borrowed and must outlive the gi_pt (materials: one per
 * scene material, e.g. a gi_frame's overridden copy). */
int gi_pt_new(const gi_rt *rt, const gi_light *lights, size_t num_lights,
              const gi_material *materials, size_t num_materials, const gi_pt_opts *opts,
              gi_pt **out, gi_status *st);
void gi_pt_free(gi_pt *pt);

/* Radiance (cd/m^2, RGB) arriving at o from direction -d, one sample. */
gi_vec3 gi_pt_radiance(const gi_pt *pt, gi_vec3 o, gi_vec3 d, gi_sampler *rng);
/* One-sample estimate of the illuminance (lux, RGB) on a small sensor at x
 * facing n (hemisphere above n, direct and indirect). */
gi_vec3 gi_pt_irradiance(const gi_pt *pt, gi_vec3 x, gi_vec3 n, gi_sampler *rng);

typedef struct gi_pt_render_result {
    int spp;             /* samples per pixel actually taken */
    double seconds;      /* wall time */
    uint64_t rays;       /* rays traced (closest-hit and shadow) */
    uint64_t dropped;    /* non-finite samples discarded (should be 0) */
    /* the image's own noise, estimated from its first samples against its
     * last pass (the second half at 2^k spp): rms over pixels and channels
     * (cd/m^2), and that over the image's mean; -1 below 2 spp */
    double noise_rms, noise_nrmse;
} gi_pt_render_result;

/* Render w x h pixels (row 0 at the top) into rgb (3 floats per pixel) with up
 * to spp samples; time_budget > 0 stops after the pass that crosses it
 * (passes double in size, so the result depends only on the spp reached). */
int gi_pt_render(const gi_pt *pt, const gi_camera *cam, int w, int h, int spp,
                 double time_budget, float *rgb, gi_pt_render_result *res, gi_status *st);

/* Illuminance at n points (6 floats each: x y z nx ny nz): mean lux (luminance
 * of the RGB estimate) and its standard error, over spp samples each. */
int gi_pt_sensors(const gi_pt *pt, const float *points, size_t n, int spp, double *lux,
                  double *stderr_lux, gi_status *st);

/* Camera ray through pixel position (px, py) in [0,w) x [0,h). */
void gi_camera_ray(const gi_camera *cam, int w, int h, float px, float py, gi_vec3 *o, gi_vec3 *d);

/* The same rays with the camera's basis computed once: gi_camera_frame_ray
 * gives exactly gi_camera_ray's result (the same operations in the same
 * order), without its three square roots and tangent per ray. */
typedef struct gi_camera_frame {
    gi_vec3 o, f, r, up;
    float th, aspect, w, h;
} gi_camera_frame;
void gi_camera_frame_init(gi_camera_frame *cf, const gi_camera *cam, int w, int h);
static inline void gi_camera_frame_ray(const gi_camera_frame *cf, float px, float py, gi_vec3 *o, gi_vec3 *d)
{
    float sx = (2.0f * px / cf->w - 1.0f) * cf->th * cf->aspect;
    float sy = (1.0f - 2.0f * py / cf->h) * cf->th;
    *o = cf->o;
    *d = gi_norm(gi_add(cf->f, gi_add(gi_scale(cf->r, sx), gi_scale(cf->up, sy))));
}

#ifdef __cplusplus
}
#endif
#endif
