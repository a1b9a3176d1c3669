/* gi_photon.h - gi-precompute's algorithm as a library: entry points (area-
 * uniform base set plus adaptive refinement inside a region, paper 5.1) and
 * light-independent photon paths traced with Embree (docs/pipeline.md).
 *
 * Call order: load a gi_scene, build its gi_rt, fill a gi_gip_opts
 * (gi_gip_opts_default, then the options), call gi_photon_precompute, write
 * the result with gi_gip_write, gi_gip_free it. The result depends only on the
 * scene, the options and the seed, never on the thread count: every path and
 * every refinement ray is seeded by its own index.
 *
 * Progress goes to stderr through gi_log (gi_progress; stages with -v).
 * Errors: GI_EXIT_USAGE for options that do not fit the scene (an unknown
 * --fixed-material name, too many photons), GI_EXIT_DATA for a scene with no
 * usable surface, GI_EXIT_SYSTEM for memory. */
#ifndef GI_PHOTON_H
#define GI_PHOTON_H

#include <stddef.h>

#include "gi_gip.h"
#include "gi_rt.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Paths of the pilot run that estimates the mean path length L; the entry
 * count is photons / L raised by GI_PHOTON_PILOT_AIM relative standard
 * errors of L, so the photon count reaches --photons in nearly every run. */
#define GI_PHOTON_PILOT_PATHS 8192
#define GI_PHOTON_PILOT_AIM 2.0
/* Triangles below these are skipped (no entry points) and counted:
 * area < (scene bounding-box diagonal * GI_PHOTON_MIN_REL_SIZE)^2, or a sliver
 * with area < GI_PHOTON_SLIVER * (longest edge)^2. */
#define GI_PHOTON_MIN_REL_SIZE 1e-7
#define GI_PHOTON_SLIVER 1e-7
/* Russian roulette: continuation probability = clamp(max albedo, MIN, MAX),
 * stored as round(255 q). */
#define GI_PHOTON_Q_MIN 0.1f
#define GI_PHOTON_Q_MAX 0.95f
/* Region refinement: entries tested per grid point for visibility, probe rays
 * per grid point for the solid angle each direction bin sees, rounds of
 * refinement, and the share of all entry points refinement may take. */
#define GI_PHOTON_REGION_SUBSET 16384
#define GI_PHOTON_REGION_BINS 32
#define GI_PHOTON_REGION_PROBES 16
#define GI_PHOTON_REGION_ROUNDS 2
#define GI_PHOTON_REGION_SHARE 0.5

/* Trace the photon paths of scene s (ray tracer rt built from s) with the
 * given options and threads (<= 0: all cores). *out is a new gi_gip owned by
 * the caller (its opts.fixed is a copy). */
int gi_photon_precompute(const gi_scene *s, const gi_rt *rt, const gi_gip_opts *opts, int threads,
                         gi_gip **out, gi_status *st);

/* 1 if triangle t gets no entry points (zero area or sliver, see above). */
int gi_photon_skip_triangle(const gi_scene *s, size_t t);

/* Skew of a grid point's view of the entry points (condition 2 of paper 5.1):
 * counts[b] visible entries and hit[b] in [0, 1] the share of directions that
 * see a surface, over nb equal-solid-angle bins. A light at the grid point
 * emits evenly in angle, so what matters is how the entries' density per
 * solid angle, rho_b = counts[b] / hit[b], spreads: the skew is the variance
 * inflation of that density against an even one, minus 1:
 *   skew = (sum_b hit_b * mean_rho / rho_b) / (sum_b hit_b) - 1
 * (mean_rho = sum counts / sum hit, counts + 0.5 so an empty bin is finite).
 * 0 for an even view, 1 for twice the variance, large when some directions
 * see almost no entries; 0 when nothing is seen, INFINITY when surfaces are
 * seen but no entry is. Exposed for tests. */
double gi_photon_skew(const double *counts, const double *hit, int nb);

#ifdef __cplusplus
}
#endif
#endif
