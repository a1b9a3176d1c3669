/* gi_hvds.h - the adaptive hierarchical volume (HVDS) of gi-hvds: octree,
 * keys (cell, normal bin, direction bin), the photon -> key map, gathering
 * points and their gathering rays as (key, count) pairs. Method in
 * docs/pipeline.md, bytes in docs/formats.md (.gih).
 *
 * Call order: gi_hvds_build (from a scene, its ray tracer and a .gip) or
 * gi_hvds_read (a .gih, checked against the scene and the .gip), then the
 * arrays, then gi_hvds_free. Keys are ordered so that every key's parent
 * comes after it: summing flux up the hierarchy is one pass in key order. */
#ifndef GI_HVDS_H
#define GI_HVDS_H

#include <stddef.h>
#include <stdint.h>

#include "gi_gip.h"
#include "gi_rt.h"
#include "gi_scene.h"
#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_HVDS_MAGIC "GIHVDS\0\0"
#define GI_HVDS_MAJOR 1
#define GI_HVDS_MINOR 2
#define GI_HVDS_NORMAL_BINS 26
#define GI_HVDS_NO_KEY 0xffffffffu
#define GI_HVDS_MAX_DEPTH 20
/* --gather-rays by default: this many rays over all gathering points, 256 to
 * 1024 per point; a ray's footprint is that of one of at most
 * GI_HVDS_FOOT_RAYS rays */
#define GI_HVDS_RAY_BUDGET (1u << 28)
#define GI_HVDS_FOOT_RAYS 256
/* gi_hvds_opts.hit_bytes by default: Sponza's 195 k points at 1024 rays
 * (4.0 GB) fit, at 2048 and 4096 rays they are traced again */
#define GI_HVDS_HIT_BYTES (4ull << 30)

enum { GI_GATHER_REJECTION = 0, GI_GATHER_KMEANS = 1 };

typedef struct gi_hvds_opts {
    int gather;              /* GI_GATHER_* */
    int gather_rays;         /* rays per gathering point (rounded to a square; 0: auto) */
    float r_min, r_max;      /* R- and R+ in metres (0: from the scene size) */
    int dir_bins;            /* direction bins on the sphere for glossy keys */
    float cell_photons;      /* the smallest cell holds about this many photons on average */
    int key_photons;         /* a gathering ray reads the nearest ancestor key holding at least
                                this many photons (0: its own key) */
    int entry_keys;          /* a ray lifted by key_photons reads its first bounce from a finer key
                                holding at least this many entry points (0: off, as .gih 1.1) */
    int occlusion_check;     /* 1: gathering rays descend past occluded coarse content (default) */
    int leak_check;          /* 1: split cells whose same-bin photons cannot see each other (default) */
    int cover_min_radius;    /* rejection: 1 (default) a kept point covers a candidate within the
                                smaller of their radii; 0: within its own (for comparisons) */
    uint64_t seed;
    uint64_t hit_bytes;      /* memory for the gathering rays' hits, held from their tracing to the keys
                                (0: GI_HVDS_HIT_BYTES); past it each point's rays are traced again
                                for its keys: the same .gih for one more pass of tracing */
} gi_hvds_opts;

void gi_hvds_opts_default(gi_hvds_opts *o);

typedef struct gi_gpoint {
    float pos[3];
    float nrm[3];            /* oriented normal: the side the point sees */
    float radius;            /* effective radius (Tabellion): weight falls to 0 beyond it */
    float r_harmonic;        /* harmonic mean distance of the gathering rays' hits (irradiance cache) */
    uint32_t tri;            /* triangle it lies on */
    uint32_t first_pair;     /* its (key, count) pairs: [first_pair, first_pair + num_pairs) */
    uint32_t num_pairs;
} gi_gpoint;

typedef struct gi_hvds {
    uint64_t scene_hash;
    uint64_t gip_fingerprint;
    gi_hvds_opts opts;

    /* octree (for statistics and debugging; relight needs only the keys) */
    uint32_t num_nodes;
    float root_min[3], root_size;
    uint32_t cells_per_level[GI_HVDS_MAX_DEPTH + 1];
    uint32_t depth;          /* deepest level in use */

    /* keys */
    uint32_t num_keys;
    uint32_t *key_parent;    /* parent key or GI_HVDS_NO_KEY */
    float *key_scale;        /* radiance per unit flux: 1 / (pi A) for diffuse keys (1/(m^2 sr)) */
    uint8_t *key_level;

    /* photon vertex -> finest key (GI_HVDS_NO_KEY: not stored) */
    uint64_t num_photons;
    uint32_t *photon_key;

    /* gathering points and rays */
    uint32_t num_gpoints;
    gi_gpoint *gpoints;
    uint32_t num_pairs;
    uint32_t *pair_key;
    uint16_t *pair_count;
    int8_t *pair_dir;        /* 3 per pair: mean unit direction of its rays x 127 (NULL: 1.0 file) */
    /* split rays (NULL without them: .gih 1.0 and 1.1, or entry_keys 0): rays that key_photons
     * lifted to a coarser key read their first bounce from a finer key, the entry points' mean
     * radiance there, and only the later bounces from the lifted key. Per gathering point i,
     * pairs [split_first[i], + split_n0[i]) are first-bounce (key, count) pairs and the
     * split_n1[i] after them later-bounce pairs. */
    uint32_t num_split;
    uint32_t *split_first, *split_n0, *split_n1;
    uint32_t *split_key;
    uint16_t *split_count;
    uint64_t num_rays;       /* gathering rays traced (= num_gpoints * gather_rays) */
    uint64_t rays_descended; /* rays moved to finer cells by the occlusion check */
    uint64_t rays_lifted;    /* rays moved to coarser keys by key_photons (build only, not stored) */
    uint64_t rays_kept_occ;  /* of rays_descended, those that found no key of their bin below and kept the
                                key they left, which held fewer than key_photons photons (build only) */
    uint64_t rays_retraced;  /* rays traced a second time, their hits over hit_bytes (build only) */
} gi_hvds;

int gi_hvds_build(const gi_scene *s, const gi_rt *rt, const gi_gip *gip, uint64_t gip_fingerprint,
                  const gi_hvds_opts *opts, int threads, gi_hvds **out, gi_status *st);
int gi_hvds_write(const gi_hvds *h, const char *path, const char *scene_path, const char *gip_path,
                  gi_status *st);
int gi_hvds_read(const char *path, const gi_scene *s, uint64_t gip_fingerprint, uint64_t num_photons,
                 gi_hvds **out, gi_status *st);
void gi_hvds_free(gi_hvds *h);

/* Normal bin (0..25) of a unit normal: nearest of the 26 directions of a cube's
 * faces, edges and corners. Opposite normals never share a bin. */
int gi_hvds_normal_bin(const float n[3]);

#ifdef __cplusplus
}
#endif
#endif
