/* gi_gltf_write.h - build a small glTF 2.0 scene in memory and write it as one
 * self-contained .gltf file (JSON, binary buffer embedded as a base64 data URI).
 *
 * Used for generated test scenes and the Cornell-box example; it is not a
 * general exporter. Everything is in metres; lights in glTF's photometric units
 * (candela for point/spot, lux for directional), emission in nits (cd/m^2).
 *
 * Call order: gi_gltf_builder_new(), any number of gi_gltf_add_*() calls,
 * gi_gltf_builder_write() (may be called more than once; the same builder
 * state always gives the same bytes), gi_gltf_builder_free().
 *
 * Output layout: one mesh per material that has triangles (one primitive:
 * POSITION + NORMAL float VEC3, one vertex per triangle corner with the flat
 * face normal, u32 indices), each on its own root node named after the
 * material; then one node per light (KHR_lights_punctual) and per camera, whose
 * rotation quaternion maps the local -Z axis onto the light or view direction.
 *
 * Errors: the add functions return nothing (or -1 for add_material); a bad
 * argument (unknown material index, non-finite number, zero direction) or an
 * allocation failure is remembered in the builder and reported by
 * gi_gltf_builder_write as GI_EXIT_USAGE (bad argument) or GI_EXIT_SYSTEM
 * (memory, I/O). The file is written to "<path>.tmp.<pid>" beside the target,
 * flushed, synced and renamed; on failure the temporary file is removed and
 * the target is left untouched. */
#ifndef GI_GLTF_WRITE_H
#define GI_GLTF_WRITE_H

#include <stddef.h>

#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_gltf_builder gi_gltf_builder;

/* New empty builder; NULL only when out of memory. */
gi_gltf_builder *gi_gltf_builder_new(void);
/* Release a builder (NULL is fine). */
void gi_gltf_builder_free(gi_gltf_builder *b);

/* Add a pbrMetallicRoughness material (base_color linear RGB in [0,1]);
 * emission_nits is emitted radiance in cd/m^2 per channel or NULL for none,
 * written as emissiveFactor = emission / max component with
 * KHR_materials_emissive_strength = max component. Returns the material index,
 * or -1 on a bad argument or out of memory (remembered for the write). */
int gi_gltf_add_material(gi_gltf_builder *b, const char *name, const float base_color[3],
                         float roughness, float metallic, const float emission_nits[3],
                         int double_sided);
/* Add one triangle; counter-clockwise (p0, p1, p2) seen from the front; flat normal. */
void gi_gltf_add_triangle(gi_gltf_builder *b, const float p0[3], const float p1[3],
                          const float p2[3], int material);
/* Add a quad as the two triangles (p0, p1, p2) and (p0, p2, p3). */
void gi_gltf_add_quad(gi_gltf_builder *b, const float p0[3], const float p1[3],
                      const float p2[3], const float p3[3], int material);
/* Add an axis-aligned box (12 triangles) with normals outward (inward = 0) or
 * inward (inward = 1, e.g. a closed room seen from inside). */
void gi_gltf_add_box(gi_gltf_builder *b, const float lo[3], const float hi[3], int material,
                     int inward);
/* Point light at pos (metres), intensity in candela, linear RGB colour. */
void gi_gltf_add_point_light(gi_gltf_builder *b, const char *name, const float pos[3],
                             const float color[3], float intensity_cd);
/* Spot light at pos along dir (need not be unit), candela, cone half angles in
 * radians with 0 <= inner < outer <= pi/2. */
void gi_gltf_add_spot_light(gi_gltf_builder *b, const char *name, const float pos[3],
                            const float dir[3], const float color[3], float intensity_cd,
                            float inner_rad, float outer_rad);
/* Directional light travelling along dir (need not be unit); illuminance in lux. */
void gi_gltf_add_directional_light(gi_gltf_builder *b, const char *name, const float dir[3],
                                   const float color[3], float illuminance_lux);
/* Perspective camera at pos looking at target with the given up hint; vertical
 * field of view in radians; aspect = width/height, or <= 0 to leave it out.
 * znear is 0.01 m and zfar is infinite. If up is parallel to the view
 * direction another up is chosen. */
void gi_gltf_add_camera(gi_gltf_builder *b, const char *name, const float pos[3],
                        const float target[3], const float up[3], float yfov_rad, float aspect);

/* Number of triangles added so far (all materials). */
size_t gi_gltf_builder_triangles(const gi_gltf_builder *b);

/* Write the scene to path (see the top comment). Returns 0 or a GI_EXIT_* code. */
int gi_gltf_builder_write(gi_gltf_builder *b, const char *path, gi_status *st);

/* Helpers, exposed for tests and for other generators. */

/* Standard base64 (RFC 4648, '=' padding) of n bytes into out, which must hold
 * 4 * ((n + 2) / 3) + 1 bytes; NUL-terminates and returns the length. */
size_t gi_gltf_base64_encode(const unsigned char *in, size_t n, char *out);
/* Unit quaternion q = (x, y, z, w) of the shortest rotation taking -Z onto the
 * direction dir (need not be unit). dir = +Z gives a half turn about +Y.
 * Returns -1 (and the identity) if dir is zero or not finite, else 0. */
int gi_gltf_quat_from_dir(const float dir[3], float q[4]);
/* Unit quaternion q = (x, y, z, w) of the rotation taking -Z onto forward and
 * +Y onto the component of up orthogonal to forward (glTF camera convention).
 * If up is zero or parallel to forward, +Y, then +Z, is used as the hint.
 * Returns -1 (and the identity) if forward is zero or not finite, else 0. */
int gi_gltf_quat_look_at(const float forward[3], const float up[3], float q[4]);

#ifdef __cplusplus
}
#endif
#endif
