/* gi_relight.h - the object-space half of a relight frame (paper §6, steps
 * 1-4 of docs/pipeline.md): entry-point flux from the frame's lights, photon
 * flux along the precomputed paths, accumulation into the HVDS keys and up the
 * hierarchy, and the indirect irradiance at every gathering point.
 *
 * Call order: gi_relight_new (borrows scene, ray tracer, .gip and .gih, which
 * must outlive it), gi_relight_set_materials (all materials the first time,
 * then only the changed ones), gi_relight_set_lights (every light change),
 * gi_relight_gpoint_irradiance, gi_relight_free. Deterministic for any thread
 * count: per-entry random numbers are seeded by (seed, entry, light). */
#ifndef GI_RELIGHT_H
#define GI_RELIGHT_H

#include <stddef.h>
#include <stdint.h>

#include "gi_gip.h"
#include "gi_hvds.h"
#include "gi_rt.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_relight gi_relight;

/* Lights that may be on in one frame (each has a cache of its light at every entry point). */
#define GI_RELIGHT_MAX_LIGHTS 32

typedef struct gi_relight_times {
    double entry;     /* entry-point flux from the lights (s) */
    double photons;   /* flux along the paths */
    double hvds;      /* accumulation into keys and up the hierarchy */
    double gather;    /* irradiance at gathering points (0: gi_relight_gather does it, on demand) */
    double materials; /* reflectance recomputation after a material change */
} gi_relight_times;

int gi_relight_new(const gi_scene *s, const gi_rt *rt, const gi_gip *gip, const gi_hvds *h, int threads,
                   uint64_t seed, gi_relight **out, gi_status *st);
void gi_relight_free(gi_relight *r);
/* Recompute reflectance factors of photons on materials whose flag is set
 * (changed == NULL: all). mats: one per scene material (a frame's copy). */
int gi_relight_set_materials(gi_relight *r, const gi_material *mats, const unsigned char *changed,
                             gi_status *st);
/* Lights of the frame (disabled ones are skipped); area lights get
 * `area_samples` jittered samples per entry point. Runs steps 1-3; step 4,
 * the gathering points, waits until they are asked for (gi_relight_gather). */
int gi_relight_set_lights(gi_relight *r, const gi_light *lights, size_t n, int area_samples,
                          gi_status *st);
/* Step 4 for the gathering points idx[0..n) (idx NULL: all of them) that were
 * not gathered since the last gi_relight_set_lights. */
void gi_relight_gather(gi_relight *r, const uint32_t *idx, size_t n);
/* Indirect irradiance (lux, RGB) at each gathering point: 3 floats per point
 * (gathers every point first). */
const float *gi_relight_gpoint_irradiance(gi_relight *r);
/* The part of gathering point i's indirect irradiance (lux, RGB, into out)
 * that its lifted rays read as later bounces from the coarser key that
 * --key-photons lifted them to (the .gih's split rays, GSPL; 0 without
 * them), after the lift cap below; and, into *later (NULL: not wanted),
 * the luminance of all its later bounces (light that left the photons after
 * the entry points, lifted or not; 0 without a split .gih). For checking the
 * points (gi-relight --gpoints), after gi_relight_gpoint_irradiance. */
void gi_relight_gpoint_lifted(const gi_relight *r, uint32_t i, float out[3], float *later);
/* Hold the later bounces that a point's lifted rays read to cap times the
 * mean of its other rays' (per ray; applied from the next gather; 0: off).
 * Default GI_RELIGHT_LIFT_CAP (lift_scale in gi_relight.c says why). */
#define GI_RELIGHT_LIFT_CAP 1.5f
void gi_relight_set_lift_cap(gi_relight *r, float cap);
/* Fresh paths: with n > 0, each gi_relight_set_lights traces n photon paths
 * from the diffuse entry points that the lights reach, chosen in proportion
 * to their flux, through the current materials, and sums them into the
 * keys, weighed against those entry points' precomputed later vertices by
 * effective sample size (the glossy entry points keep theirs). Needs the
 * photon grid (gi_relight_prepare_keys, which it calls). 0 (default): off.
 * Ends gi_relight_set_fresh_auto. */
void gi_relight_set_fresh_paths(gi_relight *r, uint32_t n);
/* Fresh paths, as many as it takes: with target > 0, each
 * gi_relight_set_lights traces a pilot of GI_RELIGHT_FRESH_PILOT paths; if
 * the .gip's later photons and the pilot's together fall short of an
 * effective sample size of target, it traces as many paths as the pilot's
 * yield per path says reach it (at most GI_RELIGHT_FRESH_MAX), in place of
 * the pilot. Under a low sun most paths leave the scene and the .gip's
 * later photons are few (Sponza u6: 5,305), so that is ~10^6 paths there
 * and the pilot alone beside a lamp. 0: off. Ends gi_relight_set_fresh_paths. */
void gi_relight_set_fresh_auto(gi_relight *r, uint32_t target);
/* Fresh paths' importance (on by default): after a frame, the lit entry
 * points on surfaces its gathering points see (a key of theirs, or an
 * ancestor, read by the points' rays) start paths in proportion to their
 * flux, the others at GI_RELIGHT_FRESH_AWAY times that rate, each path
 * weighed by 1 / its probability: unbiased, and under a sun most of the
 * flux that falls on a building's roof and outer walls sends its paths
 * elsewhere. Off: every lit entry in proportion to its flux. */
void gi_relight_set_fresh_importance(gi_relight *r, int on);
#define GI_RELIGHT_FRESH_AUTO 131072u
#define GI_RELIGHT_FRESH_PILOT 16384u
#define GI_RELIGHT_FRESH_MAX 4194304u
/* The paths traced for the last light state (0: none). */
uint32_t gi_relight_fresh_used(const gi_relight *r);
/* Of the last gi_relight_set_lights with fresh paths: the effective sample
 * sizes (sum w)^2 / sum w^2 of the luminance of the .gip's later photons
 * of diffuse entries (ess[0]) and of the fresh photons (ess[1]), the weight
 * alpha = ess[0] / (ess[0] + ess[1]) of the former (1 - alpha the latter's),
 * and how many fresh photons were summed into keys. */
void gi_relight_fresh_stats(const gi_relight *r, double ess[2], double *alpha, size_t *photons);
/* Per gathering point, 9 floats: for each of R, G, B the tangential part b_t
 * (cd/m^2 per unit direction) of a linear fit L(w) = E / pi + b_t . w of the
 * incident radiance, from the mean ray direction of each (key, count) pair
 * (gathers every point first).
 * gi_shade uses it for low-frequency glossy reflection. NULL when the .gih has
 * no GDIR section (format 1.0) or no material of the last
 * gi_relight_set_materials has a glossy lobe (then it is not computed). */
const float *gi_relight_gpoint_gradient(gi_relight *r);
/* The same arrays, where only the points gathered since the last
 * gi_relight_set_lights hold this light's values (gi_shade_opts.gather). */
const float *gi_relight_gpoint_irradiance_lazy(const gi_relight *r);
const float *gi_relight_gpoint_gradient_lazy(const gi_relight *r);
/* Flux (RGB) accumulated in each key (after set_lights). */
const float *gi_relight_key_flux(const gi_relight *r);
const float *gi_relight_key_flux0(const gi_relight *r); /* the entry points' share of key_flux (split rays), or NULL */
/* Ready gi_relight_key_at: a hash grid over the photon vertices (built once,
 * ~100 ms per million photons). Not thread-safe; 0 or a GI_EXIT_* code. */
int gi_relight_prepare_keys(gi_relight *r, gi_status *st);
/* The key whose radiance, key_flux * key_scale (cd/m^2), a ray hitting the
 * surface at p (unit normal n, facing the ray) reads: that of the nearest
 * photon vertex within one grid cell whose normal is within 45 degrees, lifted
 * to the nearest ancestor holding at least 8 photons, as gi-hvds does for
 * gathering rays. GI_HVDS_NO_KEY when none. Thread-safe after
 * gi_relight_prepare_keys. */
uint32_t gi_relight_key_at(const gi_relight *r, const float p[3], const float n[3]);
/* gi_relight_key_at for n points at once (p, nrm: 3 floats each), faster:
 * the lookups' memory is fetched for several at a time. */
void gi_relight_keys_at(const gi_relight *r, size_t n, const float *p, const float *nrm, uint32_t *out);
/* The side of the key grid's cells (m): the search's reach. 0 before
 * gi_relight_prepare_keys. */
float gi_relight_key_cell(const gi_relight *r);
const gi_relight_times *gi_relight_times_last(const gi_relight *r);

#ifdef __cplusplus
}
#endif
#endif
