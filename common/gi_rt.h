/* gi_rt.h - ray tracing against a gi_scene with Embree 3, shared by all tools.
 *
 * gi_rt_new builds one Embree device and scene (robust, high quality BVH)
 * with a triangle's Embree primID equal to its gi_scene triangle index.
 * The gi_scene must outlive the gi_rt. Each thread that traces calls
 * gi_rt_thread_init() once (sets FTZ/DAZ as Embree asks). Queries are
 * thread-safe. Errors from Embree are recorded and turned into GI_EXIT_SYSTEM. */
#ifndef GI_RT_H
#define GI_RT_H

#include <stdint.h>
#include <string.h>

#include "gi_math.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_rt gi_rt;

typedef struct gi_hit {
    float t;        /* distance along the (unit) ray direction */
    uint32_t tri;   /* triangle index in the gi_scene */
    float u, v;     /* barycentrics: p = (1-u-v) p0 + u p1 + v p2 */
} gi_hit;

/* Surface data at a hit, computed from barycentrics for accuracy. */
typedef struct gi_surface {
    gi_vec3 p;       /* position */
    gi_vec3 ng;      /* unit geometric normal, on the triangle's front side (CCW) */
    gi_vec3 ns;      /* unit interpolated shading normal */
    float uv0[2], uv1[2];
    uint32_t tri, material;
} gi_surface;

int gi_rt_new(const gi_scene *s, gi_rt **out, gi_status *st);
void gi_rt_free(gi_rt *rt);
void gi_rt_thread_init(void);

/* Closest hit along o + t d, t in (tmin, tmax); returns 1 on a hit. d unit. */
int gi_rt_intersect(const gi_rt *rt, gi_vec3 o, gi_vec3 d, float tmin, float tmax, gi_hit *hit);
/* n coherent rays (say, the samples of one pixel) from tmin to infinity, in
 * packets of 16; found[i] = 1 and hit[i] set when ray i hits. */
void gi_rt_intersect_n(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, float tmin, gi_hit *hit,
                       uint8_t *found);
/* gi_rt_intersect_n with each ray ending at tmax[i] (hits beyond are not found). */
void gi_rt_intersect_n_upto(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, const float *tmax, gi_hit *hit,
                            uint8_t *found);
/* 1 if anything blocks o + t d for t in (tmin, tmax). */
int gi_rt_occluded(const gi_rt *rt, gi_vec3 o, gi_vec3 d, float tmin, float tmax);
/* n shadow rays o[i] + t d[i], t in (0, tmax[i]), traced as coherent packets
 * of 16 (neighbouring pixels towards one light); occluded[i] = 1 if blocked. */
void gi_rt_occluded_n(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, const float *tmax,
                      uint8_t *occluded);
/* 0 when no triangle has a point q with |q - o| <= r and n . (q - o) > hmin
 * (n unit): then no ray from o into that half-space (n . d > 0) ending
 * within r can hit anything; 1 otherwise, or when unsure (more than ~100
 * triangles within reach, as on a finely tessellated plane). An Embree
 * point query, stopped at the first such triangle. */
int gi_rt_near_above(const gi_rt *rt, gi_vec3 o, gi_vec3 n, float r, float hmin);
/* Fill the surface record of a hit. */
void gi_rt_surface(const gi_rt *rt, const gi_hit *hit, gi_surface *sf);
/* The same for triangle tri at barycentrics (u, v) of scene s (no ray tracer needed). */
void gi_scene_surface(const gi_scene *s, uint32_t tri, float u, float v, gi_surface *sf);
/* Triangle tri's unit geometric normal, bit for bit gi_scene_surface's ng. */
gi_vec3 gi_scene_tri_normal(const gi_scene *s, uint32_t tri);
/* Move p off its surface along ng (towards the side dir points to) by a few
 * ulps scaled with |p|, a fixed 1/65536 m within 1/32 m of a coordinate's zero
 * (Waechter and Binder 2019, reimplemented). The Cornell box scaled by 0.01 to
 * 10,000 (5.5 mm to 5.5 km wide) relights within 0.024 nrmse of the box at
 * scale 1 (t142 tests 1,000 and 10,000); at 0.001 (0.55 mm) that fixed step is
 * 3% of the room and the frames are 0.07-0.43 off. p must be on its surface
 * to a few of its own ulps: a point found as o + t d from a far origin is not
 * (shadow_edge_pixel puts it back on its plane). */
static inline gi_vec3 gi_rt_offset(gi_vec3 p, gi_vec3 ng, gi_vec3 dir)
{
    /* integer ulps where |p| is large, a fixed tiny step near 0; inline:
     * every shadow ray of a light move takes one (a call cost ~1.5% of
     * Sponza's light moves) */
    const float origin = 1.0f / 32.0f, float_scale = 1.0f / 65536.0f, int_scale = 256.0f;
    gi_vec3 n = gi_dot(ng, dir) < 0.0f ? gi_neg(ng) : ng;
    float pc[3] = {p.x, p.y, p.z}, nc[3] = {n.x, n.y, n.z}, r[3];
    for (int k = 0; k < 3; k++) {
        int32_t of = (int32_t)(int_scale * nc[k]);
        int32_t bits;
        memcpy(&bits, &pc[k], 4);
        bits += pc[k] < 0.0f ? -of : of;
        float pi;
        memcpy(&pi, &bits, 4);
        r[k] = fabsf(pc[k]) < origin ? pc[k] + float_scale * nc[k] : pi;
    }
    return gi_v3(r[0], r[1], r[2]);
}
/* Extent of a shadow ray from o (x moved off its surface by gi_rt_offset)
 * towards a light point at distance dist from x: short of the point by
 * 1e-3 dist plus the offset |o - x|, so a light's own surface (an emissive
 * triangle) never shadows it: at a grazing angle (cos 0.1) a 1e-4 margin
 * left Embree's error in t to decide, and the path tracer lost 4-17% of an
 * emitter's light (test_emissive_configuration_factor). Occluders within
 * 0.1% of the distance from the light are not seen. INFINITY stays INFINITY. */
static inline float gi_rt_shadow_tmax(gi_vec3 x, gi_vec3 o, float dist)
{
    if (!isfinite(dist))
        return INFINITY;
    return gi_fmaxf(0.0f, dist * (1.0f - 1e-3f) - gi_len(gi_sub(o, x)));
}
/* A distance below which two points count as the same, scaled with the scene. */
float gi_rt_scene_eps(const gi_rt *rt);
const gi_scene *gi_rt_scene(const gi_rt *rt);
/* Rays traced by the calling thread since its previous call (then reset). */
uint64_t gi_rt_take_ray_count(void);

#ifdef __cplusplus
}
#endif
#endif
