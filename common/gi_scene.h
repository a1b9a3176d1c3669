/* gi_scene.h - a loaded scene: world-space triangles, materials, textures,
 * lights and cameras, in the project's units (metres, candela, lux, nits).
 *
 * Call order: gi_scene_load() (glTF 2.0 .gltf or .glb, via the tinygltf shim)
 * returns one owner; gi_scene_free() releases everything. The loader flattens
 * the node hierarchy: every triangle is in world space with its own three
 * vertices' attributes indexed through `indices`. Everything in the struct is
 * read-only for callers except where a function says otherwise (a variant
 * script may edit materials and lights of a copy, see gi_script.h).
 *
 * Errors: a malformed file gives GI_EXIT_DATA with a message naming the file
 * and the element ("meshes[2].primitives[0]: accessor 7 out of range"); an
 * unreadable file gives GI_EXIT_SYSTEM. Unsupported features are warnings,
 * collected in `warnings` with counts, never silently dropped. */
#ifndef GI_SCENE_H
#define GI_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_NAME_MAX 64

enum { GI_WRAP_REPEAT = 0, GI_WRAP_CLAMP = 1, GI_WRAP_MIRROR = 2 };

/* A decoded image, RGBA, texels stored linear float (sRGB-decoded when the
 * texture is used as base colour, which is the only use gi makes of textures). */
typedef struct gi_texture {
    char name[GI_NAME_MAX];
    int width, height;
    float *rgba;        /* width*height*4 floats, row 0 = top of the image (v = 0) */
    int wrap_s, wrap_t; /* GI_WRAP_* from the glTF sampler */
    int nearest;        /* 1 if the sampler's magFilter is NEAREST */
} gi_texture;

/* Material: Lambert + energy-conserving modified Phong lobe (see gi_brdf.h). */
typedef struct gi_material {
    char name[GI_NAME_MAX];
    float base_color[3];   /* linear RGB factor in [0,1] */
    int base_color_tex;    /* index into textures, or -1 */
    int base_color_uv;     /* 0 = TEXCOORD_0, 1 = TEXCOORD_1 */
    float uv_xform[6];     /* KHR_texture_transform as 2x3 row-major: u' = m0 u + m1 v + m2,
                              v' = m3 u + m4 v + m5 (identity when absent) */
    float roughness;       /* [0,1] */
    float metallic;        /* [0,1] */
    float emission[3];     /* emitted radiance, cd/m^2 (nits) per channel: glTF emissiveFactor
                              times KHR_materials_emissive_strength (default 1) */
    int double_sided;
} gi_material;

/* The largest light strength (cd, lux, nits), colour factor or emission the
 * loaders and scripts accept. The tools keep radiance in 32-bit floats: a
 * point light of 1e38 cd overflowed a Cornell-box frame to infinity in 189 of
 * its 256 pixels, 1e30 cd stayed finite; the brightest real sources are
 * ~1e10 cd, so 1e15 refuses nothing a design needs and leaves 1e23 of room
 * for inverse squares and sums. */
#define GI_SCENE_MAX_STRENGTH 1e15

enum { GI_LIGHT_POINT = 0, GI_LIGHT_SPOT = 1, GI_LIGHT_DIRECTIONAL = 2, GI_LIGHT_AREA = 3,
       /* emissive surfaces (gi_emit.h): made by gi-relight, never read from a file */
       GI_LIGHT_MESH = 4 };

typedef struct gi_light {
    char name[GI_NAME_MAX];
    int type;            /* GI_LIGHT_* */
    int enabled;         /* 0 when switched off by a script */
    float color[3];      /* linear RGB, multiplies intensity */
    float intensity;     /* point/spot: candela; directional: lux; area: nits (cd/m^2) */
    float position[3];   /* point, spot; area: centre */
    float direction[3];  /* spot: axis; directional: direction light travels (unit) */
    float inner_cone;    /* spot, radians, half angle where falloff starts */
    float outer_cone;    /* spot, radians, half angle where light ends */
    float range;         /* glTF range in metres, 0 = infinite (ignored by gi's physics) */
    float u[3], v[3];    /* area: half edge vectors; emits on the side of cross(u, v) */
    const struct gi_emit *mesh; /* GI_LIGHT_MESH: the emitters (borrowed) */
    uint64_t mesh_version;      /* GI_LIGHT_MESH: changes whenever the emitters do */
} gi_light;

typedef struct gi_camera {
    char name[GI_NAME_MAX];
    float position[3];
    float forward[3];    /* unit view direction */
    float up[3];         /* unit, orthogonal to forward */
    float yfov;          /* vertical field of view, radians */
    float aspect;        /* width/height from the file, 0 if unspecified */
    float znear, zfar;   /* zfar 0 = infinite */
} gi_camera;

typedef struct gi_scene {
    char path[1024];          /* file it was loaded from */
    uint64_t hash;            /* fingerprint of geometry and materials (gi_scene_fingerprint) */

    size_t num_vertices;
    float *positions;         /* 3 * num_vertices, world space, metres */
    float *normals;           /* 3 * num_vertices, world space, unit (generated if absent) */
    float *uv0;               /* 2 * num_vertices (zeros if absent) */
    float *uv1;               /* 2 * num_vertices (copy of uv0 if absent) */

    size_t num_triangles;
    uint32_t *indices;        /* 3 * num_triangles into the vertex arrays */
    uint32_t *tri_material;   /* num_triangles, index into materials */

    size_t num_materials;
    gi_material *materials;   /* at least one: a default white Lambert if the file has none */
    size_t num_textures;
    gi_texture *textures;
    size_t num_lights;
    gi_light *lights;
    size_t num_cameras;
    gi_camera *cameras;

    float bbox_min[3], bbox_max[3];
    double surface_area;      /* sum of triangle areas, m^2 */
    size_t num_degenerate;    /* triangles with (near) zero area, kept in the arrays
                                 (gi_scene_triangle_degenerate); set by gi_scene_finalize */

    size_t num_warnings;
    char **warnings;          /* human-readable, each with a count where it applies */
} gi_scene;

/* Load a .gltf or .glb file. On success *out owns everything. */
int gi_scene_load(const char *path, gi_scene **out, gi_status *st);
/* Load from memory (.glb if it starts with "glTF", else .gltf JSON). `name` is
 * used in messages and as s->path; external URIs resolve against base_dir, and
 * are refused (GI_EXIT_DATA) when base_dir is NULL. */
int gi_scene_load_memory(const void *data, size_t size, const char *name,
                         const char *base_dir, gi_scene **out, gi_status *st);
/* Safety cap for the loader (process-wide): maximum vertices, triangles and
 * texels per texture a load may create; beyond it GI_EXIT_DATA. 0 restores the
 * default (2^28). Fuzz harnesses lower it. Not thread-safe against loads. */
void gi_scene_set_load_limit(size_t max_elements);
/* Release a scene (NULL is fine). Every pointer in the struct is owned and
 * released with free(); a scene built by hand must use malloc/calloc too. */
void gi_scene_free(gi_scene *s);

/* Recompute bbox, surface_area and hash after the arrays were filled. */
void gi_scene_finalize(gi_scene *s);
/* 64-bit fingerprint of positions, indices, uvs and per-triangle materials
 * (not material parameters, which scripts may change). Stable across runs. */
uint64_t gi_scene_fingerprint(const gi_scene *s);
/* Append a warning (printf style) to s->warnings. */
void gi_scene_warn(gi_scene *s, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* 1 if triangle t has (near) zero area: |e1 x e2| <= 1e-10 * (longest edge)^2,
 * or a non-finite vertex. Such triangles are kept in the scene but counted. */
int gi_scene_triangle_degenerate(const gi_scene *s, size_t t);
/* Find by name; -1 if absent. */
int gi_scene_find_material(const gi_scene *s, const char *name);
int gi_scene_find_light(const gi_scene *s, const char *name);

/* Base colour (linear RGB) of material m at texture coordinates uv0/uv1:
 * factor times the bilinearly filtered, sRGB-decoded texture with the
 * sampler's wrap modes and the material's uv transform. */
void gi_scene_base_color(const gi_scene *s, const gi_material *m, const float uv0[2],
                         const float uv1[2], float rgb[3]);
/* Bilinear lookup of a texture at (u, v) with its wrap modes; rgba out. */
void gi_texture_sample(const gi_texture *t, float u, float v, float rgba[4]);

/* Print the scene as JSON (gi-compare info) to f. */
void gi_scene_print_json(const gi_scene *s, void *file /* FILE* */);

#ifdef __cplusplus
}
#endif
#endif
