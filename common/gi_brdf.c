/* gi_brdf.c - Lambert + modified Phong, evaluation and importance sampling. */
#include "gi_brdf.h"

float gi_brdf_exponent(float roughness)
{
    float r = gi_clampf(roughness, 0.0f, 1.0f);
    float alpha = r * r;
    float a2 = alpha * alpha;
    if (a2 <= 2.0f / (GI_BRDF_MAX_EXPONENT + 2.0f))
        return GI_BRDF_MAX_EXPONENT;
    float n = 2.0f / a2 - 2.0f;
    return n < 0.0f ? 0.0f : n;
}

static void set_lobe_prob(gi_bsdf *b)
{
    float d = gi_luminance(b->kd), s = gi_luminance(b->ks);
    b->p_spec = (d + s) > 0.0f ? s / (d + s) : 0.0f;
}

void gi_bsdf_init(gi_bsdf *b, const gi_material *m, gi_vec3 base)
{
    float metal = gi_clampf(m->metallic, 0.0f, 1.0f);
    base = gi_v3(gi_clampf(base.x, 0.0f, 1.0f), gi_clampf(base.y, 0.0f, 1.0f),
                 gi_clampf(base.z, 0.0f, 1.0f));
    b->kd = gi_scale(base, (1.0f - metal) * (1.0f - GI_BRDF_F0));
    float f0 = GI_BRDF_F0 * (1.0f - metal);
    b->ks = gi_add(gi_scale(base, metal), gi_v3(f0, f0, f0));
    b->exponent = gi_brdf_exponent(m->roughness);
    if (b->exponent < 1.0f) {
        /* A lobe this wide is diffuse: (n+2)/(2 pi) cos^n tends to 1/pi as n -> 0.
         * Folding it into kd keeps the model exactly energy-conserving there. */
        b->kd = gi_add(b->kd, b->ks);
        b->ks = gi_v3(0.0f, 0.0f, 0.0f);
        b->exponent = 0.0f;
    }
    set_lobe_prob(b);
}

void gi_bsdf_lambert(gi_bsdf *b, gi_vec3 rho)
{
    b->kd = rho;
    b->ks = gi_v3(0.0f, 0.0f, 0.0f);
    b->exponent = 0.0f;
    b->p_spec = 0.0f;
}

/* Normalised Phong lobe value (n+2)/(2pi) cos^n a, and its sampling density (n+1)/(2pi) cos^n a. */
static inline float phong_cos(gi_vec3 n, gi_vec3 wo, gi_vec3 wi)
{
    gi_vec3 r = gi_reflect(wo, n);
    float c = gi_dot(r, wi);
    return c > 0.0f ? c : 0.0f;
}

gi_vec3 gi_bsdf_eval(const gi_bsdf *b, gi_vec3 n, gi_vec3 wo, gi_vec3 wi)
{
    if (gi_dot(n, wo) <= 0.0f || gi_dot(n, wi) <= 0.0f)
        return gi_v3(0.0f, 0.0f, 0.0f);
    gi_vec3 f = gi_scale(b->kd, GI_INV_PIf);
    if (b->p_spec > 0.0f) {
        float c = phong_cos(n, wo, wi);
        if (c > 0.0f) {
            float lobe = (b->exponent + 2.0f) * (0.5f * GI_INV_PIf) * powf(c, b->exponent);
            f = gi_madd(f, b->ks, lobe);
        }
    }
    return f;
}

float gi_bsdf_pdf(const gi_bsdf *b, gi_vec3 n, gi_vec3 wo, gi_vec3 wi)
{
    float cosi = gi_dot(n, wi);
    if (gi_dot(n, wo) <= 0.0f || cosi <= 0.0f)
        return 0.0f;
    float pd = cosi * GI_INV_PIf;
    float ps = 0.0f;
    if (b->p_spec > 0.0f) {
        float c = phong_cos(n, wo, wi);
        if (c > 0.0f)
            ps = (b->exponent + 1.0f) * (0.5f * GI_INV_PIf) * powf(c, b->exponent);
    }
    return (1.0f - b->p_spec) * pd + b->p_spec * ps;
}

gi_vec3 gi_sample_cosine(gi_vec3 n, float u1, float u2)
{
    float r = sqrtf(u1), phi = 2.0f * GI_PIf * u2;
    float z = sqrtf(gi_fmaxf(0.0f, 1.0f - u1));
    gi_vec3 t, bt;
    gi_basis(n, &t, &bt);
    return gi_norm(gi_to_world(gi_v3(r * cosf(phi), r * sinf(phi), z), t, bt, n));
}

int gi_bsdf_sample(const gi_bsdf *b, gi_vec3 n, gi_vec3 wo, float u1, float u2, float u3,
                   gi_vec3 *wi, gi_vec3 *weight, float *pdf)
{
    if (gi_dot(n, wo) <= 0.0f)
        return 0;
    gi_vec3 d;
    if (u3 < b->p_spec) {
        /* cos a = u1^(1/(n+1)) around the mirror direction */
        gi_vec3 r = gi_reflect(wo, n);
        float ca = powf(u1, 1.0f / (b->exponent + 1.0f));
        float sa = sqrtf(gi_fmaxf(0.0f, 1.0f - ca * ca)), phi = 2.0f * GI_PIf * u2;
        gi_vec3 t, bt;
        gi_basis(r, &t, &bt);
        d = gi_norm(gi_to_world(gi_v3(sa * cosf(phi), sa * sinf(phi), ca), t, bt, r));
    } else {
        d = gi_sample_cosine(n, u1, u2);
    }
    float cosi = gi_dot(n, d);
    if (cosi <= 0.0f)
        return 0;
    float p = gi_bsdf_pdf(b, n, wo, d);
    if (!(p > 0.0f))
        return 0;
    gi_vec3 f = gi_bsdf_eval(b, n, wo, d);
    *wi = d;
    *pdf = p;
    *weight = gi_scale(f, cosi / p);
    return 1;
}

gi_vec3 gi_bsdf_max_albedo(const gi_bsdf *b) { return gi_add(b->kd, b->ks); }
