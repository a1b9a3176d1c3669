/* gi_gbuffer.h - the screen-space G-buffer of gi-relight, rasterised with
 * OpenGL 4.5 core on OSMesa (llvmpipe, CPU).
 *
 * Each pixel gets the visible triangle and its barycentrics at the pixel
 * centre (or at given sub-pixel offsets); gi-relight then rebuilds position,
 * normals and texture coordinates with the same code as the path tracer, so
 * the two cannot disagree about the surface. Call order: gi_gbuffer_new (one
 * OSMesa context, geometry uploaded once), gi_gbuffer_render per view,
 * gi_gbuffer_free. Not thread-safe: one gi_gbuffer per thread. */
#ifndef GI_GBUFFER_H
#define GI_GBUFFER_H

#include <stdint.h>

#include "gi_scene.h"
#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_gbuffer gi_gbuffer;

/* One pixel: tri = triangle index + 1 (0: background), (u, v) barycentrics. */
typedef struct gi_gpixel {
    uint32_t tri;
    float u, v;
} gi_gpixel;

int gi_gbuffer_new(const gi_scene *s, gi_gbuffer **out, gi_status *st);
void gi_gbuffer_free(gi_gbuffer *g);
/* Rasterise the view of cam at w x h; (jx, jy) in [0,1) is the sample
 * position inside each pixel (0.5, 0.5: centre). Row 0 of px is the top. */
int gi_gbuffer_render(gi_gbuffer *g, const gi_camera *cam, int w, int h, float jx, float jy,
                      gi_gpixel *px, gi_status *st);
/* "Mesa x.y (renderer)" of the context, for --version and logs. */
const char *gi_gbuffer_renderer(const gi_gbuffer *g);

#ifdef __cplusplus
}
#endif
#endif
