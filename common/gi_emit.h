/* gi_emit.h - emissive triangles as one light: the table the reference path
 * tracer samples for next-event estimation, and the "mesh" light
 * (GI_LIGHT_MESH) that gi-relight adds to a frame whose materials emit, so
 * that the relight and the reference sample emission with the same code.
 *
 * A triangle emits the radiance (cd/m^2, RGB) of its material's emission on
 * the side of its geometric normal cross(p1 - p0, p2 - p0), on both sides when
 * the material is double-sided. Triangles are chosen in proportion to area
 * times luminance, points uniformly on the chosen triangle. */
#ifndef GI_EMIT_H
#define GI_EMIT_H

#include <stddef.h>
#include <stdint.h>

#include "gi_light.h"
#include "gi_scene.h"
#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_emit {
    size_t n;                /* emissive triangles */
    uint32_t *tri;           /* scene triangle of each */
    float *cdf;              /* n + 1 selection CDF: cdf[0] = 0, cdf[n] = 1 */
    float *geo;              /* 12 per emitter: p0, p1 - p0, p2 - p0, unit geometric normal */
    float *area;             /* m^2 per emitter */
    float *le;               /* 3 per emitter: emitted radiance, cd/m^2 */
    unsigned char *two_sided;
    int32_t *index_of_tri;   /* per scene triangle: emitter index or -1 */
    size_t num_triangles;
    double power;            /* luminous flux, lm: pi L A summed over emitting sides */
} gi_emit;

/* Emitters of scene s under materials mats (num_materials >= the scene's).
 * *out is NULL when nothing emits. Returns 0 or a GI_EXIT_* code. */
int gi_emit_build(const gi_scene *s, const gi_material *mats, gi_emit **out, gi_status *st);
void gi_emit_free(gi_emit *e);

/* Emitter index chosen by u in [0, 1). */
size_t gi_emit_pick(const gi_emit *e, float u);
/* Sample a point on emitter k with (r1, r2) in [0,1)^2 as seen from x:
 * direction, distance, pdf in solid angle (selection included) and value =
 * radiance / pdf. Returns 0 when x sees the triangle's non-emitting side or
 * the sample is degenerate. *q receives the point, *ng the emitter's normal. */
int gi_emit_sample(const gi_emit *e, size_t k, gi_vec3 x, float r1, float r2, gi_light_sample *s, gi_vec3 *q,
                   gi_vec3 *ng);
/* Solid-angle pdf of gi_emit_pick + gi_emit_sample for the point of scene
 * triangle tri at distance dist along unit direction d (0 if not emissive). */
float gi_emit_pdf(const gi_emit *e, uint32_t tri, gi_vec3 d, float dist);

/* The mesh light over e: type GI_LIGHT_MESH, colour 1, intensity 1, name
 * "emissive-surfaces", mesh_version = version (give a new one whenever e is
 * rebuilt, so caches keyed by the light's bytes see the change). It borrows
 * e, which must outlive it. */
void gi_emit_light(const gi_emit *e, uint64_t version, gi_light *l);

#ifdef __cplusplus
}
#endif
#endif
