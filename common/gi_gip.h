/* gi_gip.h - the .gip file of gi-precompute: entry points and light-independent
 * photon paths (docs/pipeline.md for the method, docs/formats.md for bytes).
 *
 * Call order: gi-precompute fills a gi_gip and calls gi_gip_write; gi-hvds and
 * gi-relight call gi_gip_read (which checks the container, every count and
 * index, and that the file was made from `scene`), use the arrays, then
 * gi_gip_free. All arrays are owned by the gi_gip, opts.fixed included.
 * gi-precompute's algorithm is in gi_photon.h.
 *
 * Photon vertices are stored path after path; vertex path_start[p] is the
 * entry point of path p, and entry p is path p (one path per entry point).
 * Directions are unit vectors in world space. Errors: GI_EXIT_DATA for a bad
 * or foreign file (message names file, section, offset), GI_EXIT_SYSTEM for I/O. */
#ifndef GI_GIP_H
#define GI_GIP_H

#include <stddef.h>
#include <stdint.h>

#include "gi_scene.h"
#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_GIP_MAGIC "GIPHOTON"
#define GI_GIP_MAJOR 1
#define GI_GIP_MINOR 0
#define GI_GIP_MAX_PATH 65535  /* vertices per path (stored as u16) */

/* Options that change the result; recorded in META and read back. */
typedef struct gi_gip_opts {
    uint64_t photons;        /* target number of photon vertices (entry points included) */
    int max_bounces;         /* < 0: Russian roulette only; K: at most K vertices after the entry */
    uint64_t seed;
    int has_region;
    float region_min[3], region_max[3];
    size_t num_fixed;        /* materials sampled by their BRDF */
    char (*fixed)[GI_NAME_MAX];
    /* region refinement (paper 5.1), used only when has_region */
    int region_grid;              /* grid points along the region's longest axis (default 4) */
    uint32_t region_min_visible;  /* condition 1: entries a grid point must see (default 8192) */
    float region_max_skew;        /* condition 2: largest tolerated skew (default 1.0) */
} gi_gip_opts;

/* Defaults: 1,000,000 photons, Russian roulette only, seed 1, no region,
 * region grid 4, 8192 visible entries, skew 1.0, no fixed materials. */
void gi_gip_opts_default(gi_gip_opts *o);

typedef struct gi_gip {
    uint64_t scene_hash;     /* gi_scene.hash of the scene it was made from */
    gi_gip_opts opts;

    /* entry points (= paths) */
    uint32_t num_entries;
    uint32_t num_uniform;    /* entries [0, num_uniform) are the area-uniform base set */
    uint64_t num_photons;    /* photon vertices, entry points included */
    uint64_t *path_start;    /* num_entries + 1: vertex range of path p */
    float *entry_dA;         /* num_entries, m^2 */
    float *entry_base;       /* 3 * num_entries: base colour (texture applied) at the entry point */

    /* compact, per photon vertex, touched every frame */
    uint32_t *refl;          /* RGB9E5 reflectance factor R_k = f_s(w_in, w_out) cos(w_out) / (pdf q)
                                (vertex 0 of each path: unused, 0). Flux deposited at vertex k is
                                D_k = D_{k-1} R_k; D_0 comes from the lights at render time. */

    /* detail, per photon vertex: what recomputes R_k and places the photon */
    uint32_t *tri;           /* triangle index */
    float *bary;             /* 2 per vertex: (u, v), p = (1-u-v) p0 + u p1 + v p2 */
    uint8_t *side;           /* 0: front of the triangle (its CCW normal), 1: back */
    float *w_in;             /* 3 per vertex: direction towards the previous vertex (entry: 0,0,0) */
    float *w_out;            /* 3 per vertex: direction towards the next vertex */
    float *pdf;              /* solid-angle pdf with which w_out was sampled */
    uint8_t *q;              /* probability * 255 with which the path reached this vertex from the
                                previous one (Russian roulette at the previous vertex; 255 = 1,
                                always 255 at an entry point). R_k divides by this q. Every stored
                                vertex has a sampled w_out, also the last of its path. */

    /* statistics recorded by gi-precompute */
    uint64_t skipped_degenerate;   /* zero-area or sliver triangles left out */
    uint64_t escaped;              /* paths that left the scene */
    uint64_t absorbed;             /* paths that hit the back of a single-sided surface */
    uint64_t roulette;             /* paths ended by Russian roulette */
    uint64_t capped;               /* paths ended by --max-bounces */
    uint32_t region_batches;       /* refinement batches (grid points that failed a condition) */
    double pilot_mean;             /* mean vertices per path of the pilot run */

    uint64_t fingerprint;          /* gi_reader_fingerprint of the file read (0 if built in memory) */
} gi_gip;

/* A gi_gip with every array allocated (zeroed) for the given counts and
 * path_start[num_entries] = num_photons; opts defaulted. NULL if out of memory. */
gi_gip *gi_gip_new(uint32_t num_entries, uint64_t num_photons);

/* Write to path (temp file + rename). `scene_path` is recorded in META. */
int gi_gip_write(const gi_gip *g, const char *path, const gi_scene *scene, const char *scene_path,
                 gi_status *st);
/* Read and validate; refuses a file made from a different scene. */
int gi_gip_read(const char *path, const gi_scene *scene, gi_gip **out, gi_status *st);
/* Same from bytes in memory (copied); name is used in messages (fuzzing, tests). */
int gi_gip_read_memory(const void *data, size_t size, const char *name, const gi_scene *scene,
                       gi_gip **out, gi_status *st);
/* Payload bytes of the compact sections (ENTR + REFL, read every frame) and of
 * the detail section (DETL, read when a material changes) for g's counts. */
uint64_t gi_gip_compact_bytes(const gi_gip *g);
uint64_t gi_gip_detail_bytes(const gi_gip *g);
void gi_gip_free(gi_gip *g);

/* Position and oriented normal of vertex i, recomputed from tri/bary/side:
 * the interpolated shading normal, flipped onto the side the photon is on. */
void gi_gip_vertex(const gi_gip *g, const gi_scene *s, uint64_t i, float pos[3], float nrm[3]);
/* Reflectance factor R_i = f_s(w_in -> w_out) cos / (pdf q) of vertex i under
 * `materials` (indexed like s->materials; a variant's edited copy), from the
 * detail arrays: what a material change recomputes. w_in NULL: the stored
 * one (vertex 0 of a path has none and gives 0); otherwise the given unit
 * direction towards the light (R_0 at render time). */
void gi_gip_reflectance(const gi_gip *g, const gi_scene *s, const gi_material *materials,
                        uint64_t i, const float w_in[3], float rgb[3]);

/* Octahedral encoding of a unit direction as two snorm16 (the DETL layout);
 * the zero vector encodes to (0, 0). Decoding gives a unit vector; the angular
 * error of a round trip is below 1e-4 rad. */
void gi_gip_oct_encode(const float v[3], int16_t e[2]);
void gi_gip_oct_decode(const int16_t e[2], float v[3]);

/* RGB9E5 shared-exponent packing (range 0 .. 65408, 9-bit mantissas). */
uint32_t gi_rgb9e5_pack(const float rgb[3]);
void gi_rgb9e5_unpack(uint32_t v, float rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
