/* gi_math.h - small inline vector helpers (float3 as float[3]) and constants.
 * Header only. Units are whatever the caller's are (metres in world space). */
#ifndef GI_MATH_H
#define GI_MATH_H

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

#define GI_PI 3.14159265358979323846
#define GI_PIf 3.14159265358979323846f
#define GI_INV_PIf 0.31830988618379067154f

typedef struct gi_vec3 { float x, y, z; } gi_vec3;

static inline gi_vec3 gi_v3(float x, float y, float z) { gi_vec3 r = {x, y, z}; return r; }
static inline gi_vec3 gi_v3p(const float *p) { gi_vec3 r = {p[0], p[1], p[2]}; return r; }
static inline void gi_v3store(float *p, gi_vec3 a) { p[0] = a.x; p[1] = a.y; p[2] = a.z; }
static inline gi_vec3 gi_add(gi_vec3 a, gi_vec3 b) { return gi_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline gi_vec3 gi_sub(gi_vec3 a, gi_vec3 b) { return gi_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline gi_vec3 gi_mul(gi_vec3 a, gi_vec3 b) { return gi_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline gi_vec3 gi_scale(gi_vec3 a, float s) { return gi_v3(a.x * s, a.y * s, a.z * s); }
static inline gi_vec3 gi_madd(gi_vec3 a, gi_vec3 b, float s) { return gi_v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline float gi_dot(gi_vec3 a, gi_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline gi_vec3 gi_cross(gi_vec3 a, gi_vec3 b)
{
    return gi_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float gi_len(gi_vec3 a) { return sqrtf(gi_dot(a, a)); }
static inline gi_vec3 gi_norm(gi_vec3 a)
{
    float l = gi_len(a);
    return l > 0.0f ? gi_scale(a, 1.0f / l) : gi_v3(0.0f, 0.0f, 1.0f);
}
static inline gi_vec3 gi_neg(gi_vec3 a) { return gi_v3(-a.x, -a.y, -a.z); }
/* fmaxf and fminf as inline code: without -ffinite-math-only the compiler
 * calls libm for them (1.9% of a Sponza light move's profile). The same
 * results as glibc's, signed zeros and NaN included: the first operand
 * when they compare equal, the other one when one is NaN. */
static inline float gi_fmaxf(float a, float b) { return a >= b || b != b ? a : b; }
static inline float gi_fminf(float a, float b) { return a <= b || b != b ? a : b; }
static inline float gi_maxc(gi_vec3 a) { return gi_fmaxf(a.x, gi_fmaxf(a.y, a.z)); }
static inline float gi_luminance(gi_vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
static inline float gi_clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* Orthonormal basis around unit n (Duff et al. 2017, branchless). */
static inline void gi_basis(gi_vec3 n, gi_vec3 *t, gi_vec3 *b)
{
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float bb = n.x * n.y * a;
    *t = gi_v3(1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    *b = gi_v3(bb, sign + n.y * n.y * a, -n.y);
}
static inline gi_vec3 gi_to_world(gi_vec3 l, gi_vec3 t, gi_vec3 b, gi_vec3 n)
{
    return gi_v3(t.x * l.x + b.x * l.y + n.x * l.z, t.y * l.x + b.y * l.y + n.y * l.z,
                 t.z * l.x + b.z * l.y + n.z * l.z);
}

/* Kahan-Babuska (Neumaier) compensated sum: use for sums over millions of terms. */
typedef struct gi_ksum { double s, c; } gi_ksum;
static inline void gi_ksum_add(gi_ksum *k, double x)
{
    double t = k->s + x;
    if (fabs(k->s) >= fabs(x))
        k->c += (k->s - t) + x;
    else
        k->c += (x - t) + k->s;
    k->s = t;
}
static inline double gi_ksum_get(const gi_ksum *k) { return k->s + k->c; }

#ifdef __cplusplus
}
#endif
#endif
