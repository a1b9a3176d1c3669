/* gi_brdf.h - the one material model of gi, shared by gi-precompute,
 * gi-relight and the reference path tracer so they cannot drift.
 *
 * f_s(wo, wi) = kd / pi  +  ks * (n + 2) / (2 pi) * max(0, cos a)^n
 * where a is the angle between wi and the mirror direction of wo about the
 * normal: Lambert plus an energy-conserving modified Phong lobe (Lafortune and
 * Willems 1994). glTF pbrMetallicRoughness maps to it as
 *   kd = base * (1 - metallic) * (1 - F0),  ks = base * metallic + F0 * (1 - metallic),
 *   F0 = 0.04 (dielectric reflectance at normal incidence),
 *   n  = 2 / alpha^2 - 2 with alpha = roughness^2 (Walter et al. 2007 mapping),
 *        clamped to [0, GI_BRDF_MAX_EXPONENT].
 * kd + ks <= 1 per channel, so no material creates energy. A lobe with n < 1
 * (roughness above about 0.97) is folded into kd: at roughness 1 a dielectric
 * is Lambertian with albedo 0.96 base + 0.04. Truly black is metallic 1 with
 * base 0 (a black dielectric still reflects F0 = 4%).
 * Directions are unit vectors pointing away from the surface; n is the shading
 * normal on the side the light arrives from (callers flip it). */
#ifndef GI_BRDF_H
#define GI_BRDF_H

#include "gi_math.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_BRDF_F0 0.04f
#define GI_BRDF_MAX_EXPONENT 10000.0f

typedef struct gi_bsdf {
    gi_vec3 kd;      /* diffuse reflectance */
    gi_vec3 ks;      /* glossy reflectance */
    float exponent;  /* Phong exponent n */
    float p_spec;    /* probability of sampling the glossy lobe */
} gi_bsdf;

/* Phong exponent for a glTF roughness in [0, 1]. */
float gi_brdf_exponent(float roughness);
/* Build the BSDF of a material whose (textured) base colour is base. */
void gi_bsdf_init(gi_bsdf *b, const gi_material *m, gi_vec3 base);
/* Lambertian BSDF of reflectance rho (sensors, tests). */
void gi_bsdf_lambert(gi_bsdf *b, gi_vec3 rho);
/* f_s(wo -> wi) in 1/sr; zero when wo or wi is below the surface. */
gi_vec3 gi_bsdf_eval(const gi_bsdf *b, gi_vec3 n, gi_vec3 wo, gi_vec3 wi);
/* Solid-angle density with which gi_bsdf_sample picks wi. */
float gi_bsdf_pdf(const gi_bsdf *b, gi_vec3 n, gi_vec3 wo, gi_vec3 wi);
/* Sample wi from three uniforms; returns 0 if the sample is below the surface.
 * *weight = f_s cos / pdf, *pdf the solid-angle density. */
int gi_bsdf_sample(const gi_bsdf *b, gi_vec3 n, gi_vec3 wo, float u1, float u2, float u3,
                   gi_vec3 *wi, gi_vec3 *weight, float *pdf);
/* Directional albedo estimate's upper bound: kd + ks per channel. */
gi_vec3 gi_bsdf_max_albedo(const gi_bsdf *b);
/* Cosine-weighted direction around n; pdf = cos / pi. */
gi_vec3 gi_sample_cosine(gi_vec3 n, float u1, float u2);
/* Mirror of w about n. */
static inline gi_vec3 gi_reflect(gi_vec3 w, gi_vec3 n) { return gi_sub(gi_scale(n, 2.0f * gi_dot(w, n)), w); }

#ifdef __cplusplus
}
#endif
#endif
