/* gi_texfilter.h - base-colour textures filtered over a pixel's footprint.
 *
 * A reference pixel is the box-filtered average of the radiance over the
 * pixel's square; a relight sample at the pixel centre that reads one bilinear
 * texel aliases wherever a pixel covers many texels (Sponza's walls at a
 * distance). gi_texfilter keeps a box-filtered mip pyramid of every texture and
 * averages the texture over the parallelogram that the pixel's footprint maps
 * to in texture space (from ray differentials on the triangle's plane): a grid
 * of bilinear lookups at the pyramid level where their spacing is one texel.
 * The result is the box filter of the reference, up to the lighting varying
 * inside the pixel. Built once per scene; read-only and thread-safe after. */
#ifndef GI_TEXFILTER_H
#define GI_TEXFILTER_H

#include "gi_math.h"
#include "gi_scene.h"
#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_texfilter gi_texfilter;

/* Pyramids of every texture of s (s must outlive the filter). */
int gi_texfilter_new(const gi_scene *s, gi_texfilter **out, gi_status *st);
void gi_texfilter_free(gi_texfilter *f);

/* Texture of material m (the factor left out: unit base colour) averaged over
 * the footprint of a camera ray on triangle tri. p: the hit point; dx, dy: the
 * directions (unit) of the rays through the neighbouring sample positions one
 * footprint step right and down, from the same eye. rgb = 1 when m has no
 * texture. Falls back to the point lookup when the footprint is degenerate. */
void gi_texfilter_texel(const gi_texfilter *f, const gi_material *m, uint32_t tri, gi_vec3 eye, gi_vec3 p,
                        gi_vec3 dx, gi_vec3 dy, float rgb[3]);

/* Average of texture t over the parallelogram uv + s a + t b, s, t in
 * [-1/2, 1/2] (texture coordinates, after the material's uv transform). */
void gi_texfilter_box(const gi_texfilter *f, int tex, const float uv[2], const float a[2], const float b[2],
                      float rgba[4]);

#ifdef __cplusplus
}
#endif
#endif
