/* gi_light.h - light emission in photometric units, shared by the reference
 * path tracer, gi-precompute (entry-point energies) and gi-relight.
 *
 * Point and spot: intensity in candela (cd); the illuminance at distance d on a
 * surface at angle xi is E = I cos(xi) / d^2 (lux). Directional: illuminance in
 * lux on a surface facing the light. Area (rectangle): luminance in cd/m^2,
 * one-sided, emitting on the side of cross(u, v), Lambertian. Every value is
 * multiplied per channel by the light's colour. Spot falloff follows
 * KHR_lights_punctual: smooth between the inner and outer cone half angles.
 * Mesh (GI_LIGHT_MESH): the emissive triangles of gi_emit.h, sampled by power. */
#ifndef GI_LIGHT_H
#define GI_LIGHT_H

#include "gi_math.h"
#include "gi_rng.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One sample of incident light at a point x. The contribution to reflected
 * radiance is f_s * value * cos(theta_i), already divided by the pdf. */
typedef struct gi_light_sample {
    gi_vec3 wi;     /* unit direction from x towards the light */
    float dist;     /* distance to the sampled light point (INFINITY for directional) */
    gi_vec3 value;  /* radiance / pdf (solid angle); for delta lights the irradiance-like term */
    float pdf;      /* solid-angle pdf of the sample; 0 for delta lights */
    int delta;      /* 1 for point, spot and directional lights */
} gi_light_sample;

/* Sample light l as seen from x. Returns 0 when the light contributes nothing
 * (behind an area light, outside a spot cone, disabled). */
int gi_light_sample_at(const gi_light *l, gi_vec3 x, float u1, float u2, gi_light_sample *s);
/* Sample j of k x k stratified over light l as seen from x: (j % k + r1) / k,
 * (j / k + r2) / k with r1, r2 the next two numbers of rng (drawn even when
 * the light gives nothing there). Returns what gi_light_sample_at does. */
static inline int gi_light_sample_stratum(const gi_light *l, gi_vec3 x, int j, int k, gi_rng *rng,
                                          gi_light_sample *s)
{
    float u1 = ((float)(j % k) + gi_rng_float(rng)) / (float)k;
    float u2 = ((float)(j / k) + gi_rng_float(rng)) / (float)k;
    return gi_light_sample_at(l, x, u1, u2, s);
}
/* 1 for lights with extent (area, emissive mesh): sampled at several points,
 * soft shadows; 0 for point, spot and directional lights. */
static inline int gi_light_has_area(const gi_light *l) { return l->type == GI_LIGHT_AREA || l->type == GI_LIGHT_MESH; }
/* Light l with strength 1 and white colour in *unit, and what it was in
 * scale (colour times strength, per channel): every quantity gi computes
 * from one light is linear in these, so a light that is only dimmed or
 * tinted can be rendered once as *unit and scaled. Mesh lights (their
 * emitters carry the radiance) come back as they are, scale 1. */
void gi_light_unit(const gi_light *l, gi_light *unit, float scale[3]);
/* Rectangular area light l (GI_LIGHT_AREA): its projected solid angle seen
 * from x above the plane of normal n, unoccluded, from Lambert's formula for
 * a polygon clipped to that plane (0 behind the light or below the plane).
 * The irradiance at x is intensity * color * this. */
float gi_area_light_form(const gi_light *l, gi_vec3 x, gi_vec3 n);
/* Emissive meshes of at most this many triangles have an analytic irradiance. */
#define GI_LIGHT_ANALYTIC_TRIS 64
/* The unshadowed irradiance (lux per channel, colour and strength included)
 * that light l gives x above the plane of unit normal n, when it has a closed
 * form: a rectangle, or emissive triangles (at most GI_LIGHT_ANALYTIC_TRIS;
 * each seen from its emitting side). Returns 1 with *E set, else 0. */
int gi_light_analytic(const gi_light *l, gi_vec3 x, gi_vec3 n, gi_vec3 *E);
/* Spot cone attenuation in [0,1] for the cosine between the axis and the
 * direction from the light to the point. */
float gi_spot_falloff(const gi_light *l, float cos_angle);
/* Area light: normal (unit), area in m^2. */
gi_vec3 gi_area_light_normal(const gi_light *l);
float gi_area_light_area(const gi_light *l);
/* Ray against an area light rectangle: distance t in (tmin, tmax) or 0 if none.
 * Hits from either side are reported; *front says whether the ray sees the
 * emitting side. */
float gi_area_light_intersect(const gi_light *l, gi_vec3 o, gi_vec3 d, float tmin, float tmax,
                              int *front);
/* Solid-angle pdf of gi_light_sample_at for an area light when the sample
 * lands at distance t along direction d from x (for MIS). */
float gi_area_light_pdf(const gi_light *l, gi_vec3 d, float t);
/* Total flux in lumens-per-channel-like units (W-free photometric power),
 * used to choose among many lights: point 4 pi I, spot approx, directional
 * E times the scene's cross-section area (given), area pi L A. */
float gi_light_power(const gi_light *l, float scene_cross_section_m2);

#ifdef __cplusplus
}
#endif
#endif
