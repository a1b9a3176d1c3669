/* gi_relight.c - object-space relighting: lights -> entry points -> photons ->
 * HVDS keys -> gathering points. */
#define _POSIX_C_SOURCE 200809L
#include "gi_relight.h"
#include "gi_mem.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_light.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_photon.h"
#include "gi_rng.h"

/* four float lanes (GCC and Clang vector extension; SSE on x86-64) */
#define SPLIT_LATER 0x80000000u /* slot_src: the key's later vertices */
/* the fresh paths' importance of a lit entry that the view's gathering
 * points do not see (fresh_cdf_build) */
#ifndef GI_RELIGHT_FRESH_AWAY
#define GI_RELIGHT_FRESH_AWAY 0.1
#endif

typedef float v4f __attribute__((vector_size(16)));

/* Light seen by every entry point, cached per light so that a frame that
 * moves one light retraces only that light, and a material change retraces
 * nothing: irradiance E (lux, RGB, with visibility) and the mean incident
 * direction (exact for point, spot and directional lights). */
#define GI_RELIGHT_SLOTS GI_RELIGHT_MAX_LIGHTS
/* Slots whose irradiance buffers are allocated and touched when the relight
 * is made, within GI_RELIGHT_WARM_BYTES (at least 2): a new light state then
 * writes into memory already mapped. A first touch costs ~0.5-3.5 ms per MB
 * on this project's virtual machines, and a fresh 7 MB slot cost Sponza's
 * light moves ~8 ms each. A new state takes a slot never used before only
 * when every warm one is needed by its frame. */
#define GI_RELIGHT_WARM_MAX 8
#define GI_RELIGHT_WARM_BYTES ((size_t)64 << 20)
typedef struct light_slot {
    gi_light light;
    float *e;          /* 3 per entry */
    float *dir;        /* 3 per entry, only while some material is glossy (has_dir) */
    uint64_t last_use; /* frame counter, for eviction */
    int used;
    int has_dir;
} light_slot;

/* One photon of the key grid, stored in its bucket's run: a lookup reads
 * consecutive slots instead of an index and then three arrays at random
 * (position, normal, cell), which cost a cache miss each. */
struct kslot {
    float pos[3], nrm[3];
    uint64_t id;  /* its cell, packed (kpack): a bucket holds several cells */
    uint32_t key; /* the key a ray that finds it reads (its own or an ancestor with >= 8 photons) */
    uint32_t fine; /* its own (finest) key: where a fresh photon found beside it is summed */
};

/* A fresh photon (gi_relight_set_fresh_paths) while its key is looked up. */
struct fdep {
    float p[3], n[3], f[3];
    uint32_t key;
};
typedef struct fbuf {
    struct fdep *d;
    size_t n, cap;
    int failed;
} fbuf;

struct gi_relight {
    light_slot slots[GI_RELIGHT_SLOTS];
    uint64_t frame;
    double rays_seconds;
    const gi_scene *s;
    const gi_rt *rt;
    const gi_gip *gip;
    const gi_hvds *h;
    int threads;
    uint64_t seed;
    const gi_material *mats;
    float *refl;          /* 3 per photon vertex: R_k (vertex 0: unused) */
    float *entry_pos;     /* 3 per entry */
    float *entry_nrm;     /* 3 per entry */
    float *entry_texel;   /* 3 per entry: base-colour texture value (1 if untextured); base = factor * texel */
    float *entry_fd;      /* 3 per entry: dA cos_o / pdf * kd / pi for a purely diffuse entry; x < 0: glossy */
    float *flux;          /* 3 per photon vertex: outgoing flux */
    float *key_flux;      /* 3 per key */
    float *key_rad;       /* 4 per key: radiance pi/N * flux * scale (RGB, pad), read by the gather */
    uint64_t *key_start;  /* CSR: photons of each key (num_keys + 1); with split rays its
                             entry points first, up to key_mid */
    uint64_t *key_mid;    /* NULL without split rays */
    uint32_t *key_photon;
    float *key_flux0;     /* 3 per key, subtree: flux of the entry points alone (split rays) */
    double *key_da0;      /* per key, subtree: their area dA (m^2) */
    /* what split rays read, in a table of its own: per split-ray pair, its
     * slot; per slot, the key and which part (SPLIT_LATER: the later
     * vertices' radiance, else the entry points' mean radiance), and each
     * frame the radiance (4 floats, pi/N * L). Slots are numbered in the
     * order the gathering points first read them, so the gather reads the
     * table nearly in order: read by key, the split rays' entry-point keys,
     * fine and scattered, missed the cache (Sponza, --entry-keys 1, sun
     * moves, medians of 14 frames: the final gather took 14.0 ms a light
     * move read by key, 11.0 read by slot; 6.1 without split rays) */
    uint32_t *split_slot;
    uint32_t *slot_src;
    float *slot_rad;
    uint32_t num_slots;
    float *gp_e;          /* 3 per gathering point */
    /* lifted rays' later bounces at most lift_cap times the mean of the
     * point's other rays (gi_relight_set_lift_cap; 0: off), of gp_nreg
     * rays per point (its (key, count) pairs' rays; NULL without split rays) */
    float lift_cap;
    uint32_t *gp_nreg;
    uint32_t *gp_gen;     /* per gathering point: the light state (gen) gp_e and gp_t were gathered for */
    uint32_t gen;         /* bumped by every gi_relight_set_lights: the points are gathered when asked for */
    uint32_t *gather_list; /* scratch of gi_relight_gather: the stale points asked for */
    float *gp_t;          /* 9 per gathering point: tangential gradient of incident radiance (NULL: no GDIR) */
    /* fresh paths (gi_relight_set_fresh_paths): per light state, this many
     * paths traced from the lit diffuse entry points, chosen in proportion
     * to their flux, weighed with those entries' .gip later vertices */
    uint32_t fresh_paths;
    uint32_t fresh_target; /* gi_relight_set_fresh_auto: the effective sample size aimed at (0: fixed count) */
    uint32_t fresh_used;   /* paths traced for the current light state */
    double *fresh_acc;    /* 3 per key, zero between light states */
    double *fresh_cdf;    /* per entry + 1: the running sum of the diffuse entries' flux luminance */
    size_t fresh_deposits, fresh_lost;
    double fresh_t_keys;
    double fresh_alpha;   /* the weight of the .gip's later photons (of diffuse entries); 1 - it the fresh ones' */
    double fresh_ess[2];  /* effective sample sizes: the .gip's, the fresh paths' */
    /* the gathering points the last view read (gi_relight_gather's list),
     * for the fresh paths' importance (fresh_cdf_build) */
    uint32_t *view_pts;
    size_t view_n, view_cap;
    uint8_t *key_seen;    /* per key: read by one of those points' rays */
    double fresh_away;    /* the importance of a lit entry they do not see (1: none) */
    size_t fresh_seen;    /* lit entries seen by them, of the last cdf */
    double fresh_seen_share; /* their share of the lit entries' flux */
    int any_glossy;       /* some material has a glossy lobe: gp_t is computed */
    /* gi_relight_key_at: photons in a hash grid of cell kcell (CSR by bucket) */
    float kcell;
    uint32_t kmask;       /* buckets - 1 */
    uint32_t *kb_start;   /* kmask + 2 */
    struct kslot *kslot;  /* the photons, by bucket: what a lookup reads, side by side */
    gi_relight_times times;
};

static int alloc_all(gi_relight *r)
{
    uint64_t P = r->gip->num_photons, E = r->gip->num_entries, K = r->h->num_keys;
    r->refl = gi_calloc_large(3 * P + 3, sizeof *r->refl);
    r->flux = gi_calloc_large(3 * P + 3, sizeof *r->flux);
    r->entry_pos = gi_alloc_large((3 * E + 3) * sizeof *r->entry_pos);
    r->entry_nrm = gi_alloc_large((3 * E + 3) * sizeof *r->entry_nrm);
    r->entry_texel = gi_alloc_large((3 * E + 3) * sizeof *r->entry_texel);
    r->entry_fd = gi_alloc_large((3 * E + 3) * sizeof *r->entry_fd);
    r->key_flux = gi_calloc_large(3 * K + 3, sizeof *r->key_flux);
    r->key_rad = gi_calloc_large(4 * K + 4, sizeof *r->key_rad);
    r->key_start = gi_calloc_large(K + 2, sizeof *r->key_start);
    r->key_photon = gi_alloc_large((P + 1) * sizeof *r->key_photon);
    r->gp_e = gi_calloc_large(3 * (size_t)r->h->num_gpoints + 3, sizeof *r->gp_e);
    r->gp_gen = gi_calloc_large((size_t)r->h->num_gpoints + 1, sizeof *r->gp_gen);
    r->gather_list = gi_alloc_large(((size_t)r->h->num_gpoints + 1) * sizeof *r->gather_list);
    if (r->h->pair_dir && !(r->gp_t = gi_calloc_large(9 * (size_t)r->h->num_gpoints + 9, sizeof *r->gp_t)))
        return -1;
    return r->refl && r->flux && r->entry_pos && r->entry_nrm && r->entry_texel && r->entry_fd && r->key_flux && r->key_rad &&
                   r->key_start &&
                   r->key_photon && r->gp_e && r->gp_gen && r->gather_list
               ? 0
               : -1;
}

static gi_vec3 vertex_base(const gi_relight *r, const gi_material *m, uint64_t i);

/* Luminance of key k's flux less its entry points' (its later bounces). */
static double later_lum(const gi_relight *r, uint32_t k)
{
    static const double lum[3] = {0.2126, 0.7152, 0.0722};
    double l = 0.0;
    for (int c = 0; c < 3; c++)
        l += lum[c] * fmax((double)r->key_flux[3 * (size_t)k + c] - r->key_flux0[3 * (size_t)k + c], 0.0);
    return l;
}

int gi_relight_new(const gi_scene *s, const gi_rt *rt, const gi_gip *gip, const gi_hvds *h, int threads,
                   uint64_t seed, gi_relight **out, gi_status *st)
{
    *out = NULL;
    if (h->num_photons != gip->num_photons)
        return gi_status_set(st, GI_EXIT_DATA, "the .gih maps %llu photons but the .gip has %llu",
                             (unsigned long long)h->num_photons, (unsigned long long)gip->num_photons);
    gi_relight *r = calloc(1, sizeof *r);
    if (!r)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    r->s = s;
    r->rt = rt;
    r->gip = gip;
    r->h = h;
    r->threads = threads > 0 ? threads : omp_get_num_procs();
    r->seed = seed;
    r->lift_cap = GI_RELIGHT_LIFT_CAP;
    r->fresh_away = GI_RELIGHT_FRESH_AWAY;
    r->fresh_seen = SIZE_MAX;
    if (alloc_all(r)) {
        gi_relight_free(r);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %llu photons",
                             (unsigned long long)gip->num_photons);
    }
    size_t slot_bytes = (3 * (size_t)gip->num_entries + 3) * sizeof(float);
    int warm = (int)(GI_RELIGHT_WARM_BYTES / slot_bytes);
    warm = warm < 2 ? 2 : (warm > GI_RELIGHT_WARM_MAX ? GI_RELIGHT_WARM_MAX : warm);
    for (int k = 0; k < warm; k++) {
        if (!(r->slots[k].e = gi_alloc_large(slot_bytes))) {
            gi_relight_free(r);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %d light caches of %u entry points", warm,
                                 gip->num_entries);
        }
        memset(r->slots[k].e, 0, slot_bytes); /* touched now (calloc would leave fresh pages unmapped) */
    }
    for (uint32_t e = 0; e < gip->num_entries; e++) {
        uint64_t v0 = gip->path_start[e];
        gi_gip_vertex(gip, s, v0, r->entry_pos + 3 * (size_t)e, r->entry_nrm + 3 * (size_t)e);
        /* the texture alone, so a script's new base-colour factor applies at entry points too */
        gi_material unit = s->materials[s->tri_material[gip->tri[v0]]];
        unit.base_color[0] = unit.base_color[1] = unit.base_color[2] = 1.0f;
        gi_v3store(r->entry_texel + 3 * (size_t)e, vertex_base(r, &unit, v0));
    }
    /* CSR of photons by key, in photon order (deterministic sums) */
    uint64_t P = gip->num_photons;
    uint32_t K = h->num_keys;
    for (uint64_t p = 0; p < P; p++)
        if (h->photon_key[p] != GI_HVDS_NO_KEY)
            r->key_start[h->photon_key[p] + 1]++;
    for (uint32_t k = 0; k < K; k++)
        r->key_start[k + 1] += r->key_start[k];
    uint64_t *fill = malloc((K + 1) * sizeof *fill);
    if (!fill) {
        gi_relight_free(r);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    }
    memcpy(fill, r->key_start, (K + 1) * sizeof *fill);
    if (h->split_key) {
        /* split rays read a key's entry points apart from its later
         * vertices: the entry points go first in each key's list */
        r->key_mid = gi_alloc_large((K + 1) * sizeof *r->key_mid);
        r->key_flux0 = gi_calloc_large(3 * (size_t)K + 3, sizeof *r->key_flux0);
        r->key_da0 = gi_calloc_large((size_t)K + 1, sizeof *r->key_da0);
        r->split_slot = gi_alloc_large(((size_t)h->num_split + 1) * sizeof *r->split_slot);
        r->slot_src = gi_alloc_large(((size_t)h->num_split + 1) * sizeof *r->slot_src);
        uint32_t *slot_of = gi_alloc_large((2 * (size_t)K + 2) * sizeof *slot_of);
        if (!r->key_mid || !r->key_flux0 || !r->key_da0 || !r->split_slot || !r->slot_src || !slot_of) {
            free(slot_of);
            free(fill);
            gi_relight_free(r);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        }
        for (uint32_t e = 0; e < gip->num_entries; e++) {
            uint64_t v0 = gip->path_start[e];
            uint32_t k = h->photon_key[v0];
            if (k == GI_HVDS_NO_KEY)
                continue;
            r->key_photon[fill[k]++] = (uint32_t)v0;
            r->key_da0[k] += gip->entry_dA[e];
        }
        memcpy(r->key_mid, fill, (K + 1) * sizeof *fill);
        for (uint32_t e = 0; e < gip->num_entries; e++)
            for (uint64_t p = gip->path_start[e] + 1; p < gip->path_start[e + 1]; p++)
                if (h->photon_key[p] != GI_HVDS_NO_KEY)
                    r->key_photon[fill[h->photon_key[p]]++] = (uint32_t)p;
        for (uint32_t k = 0; k < K; k++)
            if (h->key_parent[k] != GI_HVDS_NO_KEY)
                r->key_da0[h->key_parent[k]] += r->key_da0[k];
        if (K >= SPLIT_LATER) {
            free(slot_of);
            free(fill);
            gi_relight_free(r);
            return gi_status_set(st, GI_EXIT_DATA, "%u keys: split rays need fewer than 2^31", K);
        }
        for (size_t k = 0; k < 2 * (size_t)K; k++)
            slot_of[k] = UINT32_MAX;
        uint32_t ns = 0;
        for (uint32_t i = 0; i < h->num_gpoints; i++) {
            uint32_t j0 = h->split_first[i], j1 = j0 + h->split_n0[i], j2 = j1 + h->split_n1[i];
            for (uint32_t j = j0; j < j2; j++) {
                uint32_t src = h->split_key[j] | (j < j1 ? 0u : SPLIT_LATER);
                size_t at = (size_t)h->split_key[j] * 2 + (j < j1 ? 0 : 1);
                if (slot_of[at] == UINT32_MAX) {
                    slot_of[at] = ns;
                    r->slot_src[ns++] = src;
                }
                r->split_slot[j] = slot_of[at];
            }
        }
        free(slot_of);
        r->num_slots = ns;
        gi_verbose("split rays: %u pairs read %u slots", h->num_split, ns);
        r->slot_rad = gi_calloc_large(4 * (size_t)ns + 4, sizeof *r->slot_rad);
        r->gp_nreg = malloc(((size_t)h->num_gpoints + 1) * sizeof *r->gp_nreg);
        if (!r->slot_rad || !r->gp_nreg) {
            free(fill);
            gi_relight_free(r);
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
        }
        for (uint32_t i = 0; i < h->num_gpoints; i++) {
            const gi_gpoint *g = &h->gpoints[i];
            uint32_t c = 0;
            for (uint32_t j = 0; j < g->num_pairs; j++)
                c += h->pair_count[g->first_pair + j];
            r->gp_nreg[i] = c;
        }
    } else {
        for (uint64_t p = 0; p < P; p++)
            if (h->photon_key[p] != GI_HVDS_NO_KEY)
                r->key_photon[fill[h->photon_key[p]]++] = (uint32_t)p;
    }
    free(fill);
    *out = r;
    return 0;
}

void gi_relight_free(gi_relight *r)
{
    if (!r)
        return;
    for (int i = 0; i < GI_RELIGHT_SLOTS; i++) {
        free(r->slots[i].e);
        free(r->slots[i].dir);
    }
    free(r->refl);
    free(r->flux);
    free(r->entry_pos);
    free(r->entry_nrm);
    free(r->entry_texel);
    free(r->entry_fd);
    free(r->key_flux);
    free(r->key_rad);
    free(r->key_start);
    free(r->key_mid);
    free(r->view_pts);
    free(r->key_seen);
    free(r->key_photon);
    free(r->key_flux0);
    free(r->key_da0);
    free(r->split_slot);
    free(r->slot_src);
    free(r->slot_rad);
    free(r->gp_nreg);
    free(r->gp_e);
    free(r->gp_t);
    free(r->gp_gen);
    free(r->gather_list);
    free(r->kb_start);
    free(r->kslot);
    free(r->fresh_acc);
    free(r->fresh_cdf);
    free(r);
}

/* Base colour at photon vertex i (texture applied). */
static gi_vec3 vertex_base(const gi_relight *r, const gi_material *m, uint64_t i)
{
    gi_surface sf;
    gi_scene_surface(r->s, r->gip->tri[i], r->gip->bary[2 * i], r->gip->bary[2 * i + 1], &sf);
    float rgb[3];
    gi_scene_base_color(r->s, m, sf.uv0, sf.uv1, rgb);
    return gi_v3p(rgb);
}

/* dA cos_o / (pdf q) * kd / pi of entry e under material m when m has no
 * glossy lobe (then the flux leaving e along its path is this times the sum
 * of the lights' irradiance E_l); fd[0] = -1 when it has one. */
static void entry_factor(const gi_relight *r, uint32_t e, const gi_material *m, float fd[3])
{
    const gi_gip *g = r->gip;
    uint64_t v0 = g->path_start[e];
    gi_bsdf b;
    gi_bsdf_init(&b, m, gi_mul(gi_v3p(m->base_color), gi_v3p(r->entry_texel + 3 * (size_t)e)));
    if (gi_maxc(b.ks) > 0.0f) {
        fd[0] = -1.0f;
        fd[1] = fd[2] = 0.0f;
        return;
    }
    gi_vec3 nn = gi_v3p(r->entry_nrm + 3 * (size_t)e), wo = gi_v3p(g->w_out + 3 * v0);
    float coso = gi_fmaxf(gi_dot(nn, wo), 0.0f);
    float denom = g->pdf[v0] * ((float)g->q[v0] / 255.0f);
    float k = denom > 0.0f && coso > 0.0f ? g->entry_dA[e] * coso / gi_fmaxf(denom, 1e-30f) * GI_INV_PIf : 0.0f;
    gi_v3store(fd, gi_scale(b.kd, k));
}

int gi_relight_set_materials(gi_relight *r, const gi_material *mats, const unsigned char *changed,
                             gi_status *st)
{
    double t0 = gi_now();
    r->mats = mats;
    r->any_glossy = 0;
    for (size_t m = 0; m < r->s->num_materials; m++) {
        gi_bsdf b;
        gi_bsdf_init(&b, &mats[m], gi_v3(1.0f, 1.0f, 1.0f));
        r->any_glossy |= gi_maxc(b.ks) > 0.0f;
    }
    const gi_gip *g = r->gip;
    const gi_scene *s = r->s;
    /* entry points of diffuse materials: the light-independent factor of their
     * outgoing flux, so that a light change costs one product per light */
#pragma omp parallel for schedule(dynamic, 1024) num_threads(r->threads)
    for (uint32_t e = 0; e < g->num_entries; e++) {
        uint64_t v0 = g->path_start[e];
        uint32_t mi = s->tri_material[g->tri[v0]];
        if (changed && !changed[mi])
            continue;
        entry_factor(r, e, &mats[mi], r->entry_fd + 3 * (size_t)e);
    }
    if (!changed && r->s->num_materials > 0 &&
        !memcmp(mats, s->materials, s->num_materials * sizeof *mats)) {
        /* the scene's own materials: the compact section already holds R_k */
        for (uint64_t i = 0; i < g->num_photons; i++)
            gi_rgb9e5_unpack(g->refl[i], r->refl + 3 * i);
        r->times.materials = gi_now() - t0;
        return 0;
    }
    /* a vertex on a material as the scene has it reads the .gip's R_k, as the
     * first frame of a run does: a material changed and changed back gives
     * the frame a fresh run gives (recomputed, R_k of a sharp glossy lobe
     * differ by up to 0.4%: the .gip's directions are rounded) */
    unsigned char *own = malloc(s->num_materials + 1);
    if (!own)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    for (size_t m = 0; m < s->num_materials; m++)
        own[m] = !memcmp(&mats[m], &s->materials[m], sizeof *mats);
#pragma omp parallel for schedule(dynamic, 256) num_threads(r->threads)
    for (uint32_t e = 0; e < g->num_entries; e++) {
        for (uint64_t i = g->path_start[e] + 1; i < g->path_start[e + 1]; i++) {
            uint32_t mi = s->tri_material[g->tri[i]];
            if (changed && !changed[mi])
                continue;
            if (own[mi]) {
                gi_rgb9e5_unpack(g->refl[i], r->refl + 3 * i);
                continue;
            }
            const gi_material *m = &mats[mi];
            float pos[3], nrm[3];
            gi_gip_vertex(g, s, i, pos, nrm);
            gi_bsdf b;
            gi_bsdf_init(&b, m, vertex_base(r, m, i));
            gi_vec3 n = gi_v3p(nrm), wi = gi_v3p(g->w_in + 3 * i), wo = gi_v3p(g->w_out + 3 * i);
            gi_vec3 f = gi_bsdf_eval(&b, n, wi, wo);
            float cosv = gi_fmaxf(gi_dot(n, wo), 0.0f);
            float q = (float)g->q[i] / 255.0f;
            float denom = g->pdf[i] * q;
            gi_vec3 R = denom > 0.0f ? gi_scale(f, cosv / denom) : gi_v3(0, 0, 0);
            gi_v3store(r->refl + 3 * i, R);
        }
    }
    free(own);
    r->times.materials = gi_now() - t0;
    return 0;
}

static int fresh_trace(gi_relight *r, fbuf *bufs, uint32_t M, int new_cdf, size_t *nlit, gi_status *st);
static double fresh_ess_of(const fbuf *fb, int threads);

int gi_relight_set_lights(gi_relight *r, const gi_light *lights, size_t n, int area_samples, gi_status *st)
{
    if (!r->mats)
        return gi_status_set(st, GI_EXIT_USAGE, "gi_relight_set_materials must come first");
    const gi_gip *g = r->gip;
    const gi_scene *s = r->s;
    const gi_hvds *h = r->h;
    if (area_samples < 1)
        area_samples = 1;
    int ks = (int)ceilf(sqrtf((float)area_samples));
    double t0 = gi_now();
    /* 1a. light arriving at every entry point, per light, from the cache or traced */
    r->frame++;
    int slot_of[GI_RELIGHT_SLOTS];
    size_t lid[GI_RELIGHT_SLOTS];
    int nused = 0;
    int cacheable = 1;
    const int need_dir = r->any_glossy; /* glossy entries weigh each light by its direction */
    {
        size_t ne = 0;
        for (size_t l = 0; l < n; l++)
            ne += lights[l].enabled ? 1 : 0;
        cacheable = ne <= GI_RELIGHT_SLOTS;
    }
    /* each light traced at strength 1 and white (gi_light_unit) and scaled
     * in 1b: a light only dimmed or tinted is not traced again */
    float lsc[GI_RELIGHT_SLOTS][3];
    for (size_t l = 0; l < n && cacheable; l++) {
        if (!lights[l].enabled)
            continue;
        gi_light unit;
        gi_light_unit(&lights[l], &unit, lsc[nused]);
        int found = -1;
        for (int k = 0; k < GI_RELIGHT_SLOTS && found < 0; k++)
            if (r->slots[k].used && !memcmp(&r->slots[k].light, &unit, sizeof unit))
                found = k;
        /* a light without area arrives at an entry point from one
         * direction, which 1b takes from the light itself: only an area
         * light's directions (the mean over its samples) are stored */
        const int sdir = need_dir && gi_light_has_area(&unit);
        if (found >= 0 && sdir && !r->slots[found].has_dir) {
            /* cached while every material was diffuse: trace it again for
             * the directions. (A sun's or a lamp's were traced so too, and
             * stored: Sponza, a sun and a lamp, the floor made metal, entry
             * points 56 ms on that frame, ~35 ms of it the rays.) */
            light_slot *sl = &r->slots[found];
            if (!sl->dir && !(sl->dir = gi_alloc_large((3 * (size_t)g->num_entries + 3) * sizeof *sl->dir)))
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory caching light '%s'", lights[l].name);
            sl->used = 2;
        }
        if (found < 0) {
            /* a slot with buffers not needed by this frame (never used
             * first, then the least recently used), else a new one */
            uint64_t oldest = UINT64_MAX;
            for (int k = 0; k < GI_RELIGHT_SLOTS; k++) {
                if (!r->slots[k].e || r->slots[k].last_use == r->frame)
                    continue;
                uint64_t age = r->slots[k].used ? r->slots[k].last_use : 0;
                if (found < 0 || age < oldest) {
                    oldest = age;
                    found = k;
                }
            }
            for (int k = 0; k < GI_RELIGHT_SLOTS && found < 0; k++)
                if (!r->slots[k].e)
                    found = k;
            light_slot *sl = &r->slots[found];
            /* the directions only while some material is glossy: a diffuse
             * entry needs none, and a new buffer costs its first touch (on
             * virtual machines ~1 ms per MB, as much as the rays) */
            if (!sl->e)
                sl->e = gi_alloc_large((3 * (size_t)g->num_entries + 3) * sizeof *sl->e);
            if (sdir && !sl->dir)
                sl->dir = gi_alloc_large((3 * (size_t)g->num_entries + 3) * sizeof *sl->dir);
            if (!sl->e || (sdir && !sl->dir))
                return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory caching light '%s'", lights[l].name);
            sl->light = unit;
            sl->used = 2; /* 2: to be traced */
        }
        r->slots[found].last_use = r->frame;
        slot_of[nused] = found;
        lid[nused] = l;
        nused++;
    }
    if (!cacheable)
        return gi_status_set(st, GI_EXIT_USAGE, "more than %d lights are on; gi-relight handles at most %d at once",
                             GI_RELIGHT_SLOTS, GI_RELIGHT_SLOTS);
    for (int u = 0; u < nused; u++) {
        light_slot *sl = &r->slots[slot_of[u]];
        if (sl->used != 2)
            continue;
        const gi_light *L = &sl->light;
        const int area = gi_light_has_area(L), ns = area ? ks * ks : 1;
        size_t l = lid[u];
        /* entry points come in surface order, so neighbours in the list are
         * near each other: their shadow rays go to Embree as packets */
        enum { CHUNK = 256 };
        uint32_t nchunks = (g->num_entries + CHUNK - 1) / CHUNK;
        size_t cap = (size_t)CHUNK * (size_t)ns;
        int fail = 0;
#pragma omp parallel num_threads(r->threads)
        {
            gi_rt_thread_init();
            gi_vec3 *ro = malloc(cap * sizeof *ro), *rd = malloc(cap * sizeof *rd), *rv = malloc(cap * sizeof *rv);
            float *rt = malloc(cap * sizeof *rt);
            uint32_t *re = malloc(cap * sizeof *re);
            uint8_t *occ = malloc(cap);
            gi_vec3 *acc = malloc(CHUNK * sizeof *acc), *dacc = malloc(CHUNK * sizeof *dacc);
            int ok = ro && rd && rv && rt && re && occ && acc && dacc;
            if (!ok) {
#pragma omp atomic write
                fail = 1;
            }
#pragma omp for schedule(dynamic, 2)
            for (uint32_t ch = 0; ch < nchunks; ch++) {
                if (!ok)
                    continue;
                uint32_t e0 = ch * CHUNK, e1 = e0 + CHUNK < g->num_entries ? e0 + CHUNK : g->num_entries;
                int nr = 0;
                for (uint32_t e = e0; e < e1; e++) {
                    gi_vec3 x = gi_v3p(r->entry_pos + 3 * (size_t)e), nn = gi_v3p(r->entry_nrm + 3 * (size_t)e);
                    acc[e - e0] = dacc[e - e0] = gi_v3(0, 0, 0);
                    gi_rng rng = {0, 0}; /* seeded below when the light has area */
                    /* sampled, also where the pixels take a closed form
                     * (gi_light_analytic): an entry point's light is summed
                     * into keys with its neighbours', which averages the
                     * noise away, and the form costs as much as the rays
                     * (Cornell panel frames: the same nrmse within 0.0005,
                     * 40 ms more per light move) */
                    if (area) /* (a light without area takes no random numbers) */
                        gi_rng_seed(&rng, r->seed, e, l);
                    for (int j = 0; j < ns; j++) {
                        gi_light_sample ls;
                        if (!(area ? gi_light_sample_stratum(L, x, j, ks, &rng, &ls)
                                   : gi_light_sample_at(L, x, 0.5f, 0.5f, &ls)))
                            continue;
                        float cosi = gi_dot(nn, ls.wi);
                        if (cosi <= 0.0f)
                            continue;
                        ro[nr] = gi_rt_offset(x, nn, ls.wi);
                        rd[nr] = ls.wi;
                        rt[nr] = gi_rt_shadow_tmax(x, ro[nr], ls.dist);
                        rv[nr] = gi_scale(ls.value, cosi);
                        re[nr] = e - e0;
                        nr++;
                    }
                }
                gi_rt_occluded_n(r->rt, nr, ro, rd, rt, occ);
                for (int q = 0; q < nr; q++) {
                    if (occ[q])
                        continue;
                    acc[re[q]] = gi_add(acc[re[q]], rv[q]);
                    dacc[re[q]] = gi_madd(dacc[re[q]], rd[q], gi_luminance(rv[q]) + 1e-30f);
                }
                for (uint32_t e = e0; e < e1; e++) {
                    gi_v3store(sl->e + 3 * (size_t)e, gi_scale(acc[e - e0], 1.0f / (float)ns));
                    if (need_dir && area)
                        gi_v3store(sl->dir + 3 * (size_t)e, gi_norm(dacc[e - e0]));
                }
            }
            free(ro);
            free(rd);
            free(rv);
            free(rt);
            free(re);
            free(occ);
            free(acc);
            free(dacc);
        }
        if (fail)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory tracing light '%s'", L->name);
        sl->used = 1;
        sl->has_dir = need_dir && gi_light_has_area(&sl->light);
    }
    double t0b = gi_now();
    /* 1b. flux leaving each entry point along its path: Phi_0 = dA sum_l f(w_l, w_out) E_l cos_o / pdf */
#pragma omp parallel for schedule(dynamic, 1024) num_threads(r->threads)
    for (uint32_t e = 0; e < g->num_entries; e++) {
        uint64_t v0 = g->path_start[e];
        const float *fd = r->entry_fd + 3 * (size_t)e;
        if (fd[0] >= 0.0f) {
            /* diffuse: the same value as the general case below, one product per light */
            gi_vec3 esum = gi_v3(0, 0, 0);
            for (int u = 0; u < nused; u++)
                esum = gi_add(esum, gi_mul(gi_v3p(r->slots[slot_of[u]].e + 3 * (size_t)e), gi_v3p(lsc[u])));
            gi_v3store(r->flux + 3 * v0, gi_mul(gi_v3p(fd), esum));
            continue;
        }
        gi_vec3 nn = gi_v3p(r->entry_nrm + 3 * (size_t)e);
        const gi_material *m = &r->mats[s->tri_material[g->tri[v0]]];
        gi_bsdf b;
        gi_bsdf_init(&b, m, gi_mul(gi_v3p(m->base_color), gi_v3p(r->entry_texel + 3 * (size_t)e)));
        gi_vec3 wo = gi_v3p(g->w_out + 3 * v0);
        float coso = gi_fmaxf(gi_dot(nn, wo), 0.0f);
        float denom = g->pdf[v0] * ((float)g->q[v0] / 255.0f);
        gi_vec3 sum = gi_v3(0, 0, 0);
        if (denom > 0.0f && coso > 0.0f) {
            for (int u = 0; u < nused; u++) {
                const light_slot *sl = &r->slots[slot_of[u]];
                gi_vec3 ev = gi_mul(gi_v3p(sl->e + 3 * (size_t)e), gi_v3p(lsc[u]));
                if (gi_maxc(ev) <= 0.0f)
                    continue;
                gi_vec3 wi;
                if (gi_light_has_area(&sl->light)) {
                    wi = gi_v3p(sl->dir + 3 * (size_t)e);
                } else {
                    gi_light_sample ls;
                    if (!gi_light_sample_at(&sl->light, gi_v3p(r->entry_pos + 3 * (size_t)e), 0.5f, 0.5f, &ls))
                        continue;
                    wi = ls.wi;
                }
                gi_vec3 f = gi_bsdf_eval(&b, nn, wi, wo);
                sum = gi_add(sum, gi_mul(f, ev));
            }
        }
        gi_v3store(r->flux + 3 * v0, gi_scale(sum, g->entry_dA[e] * coso / gi_fmaxf(denom, 1e-30f)));
    }
    r->rays_seconds = t0b - t0;
    double t1 = gi_now();
    /* 2. along the paths */
    const int fresh = r->fresh_paths > 0 || r->fresh_target > 0;
    if (fresh) {
        if (gi_relight_prepare_keys(r, st))
            return st->code;
        if (!r->fresh_acc && !(r->fresh_acc = gi_calloc_large(3 * (size_t)h->num_keys + 3, sizeof *r->fresh_acc)))
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for fresh paths");
    }
    /* with fresh paths, the luminance of the diffuse entry points' later
     * photons and of its square, per chunk of entries in a fixed order
     * (the same sums whatever the thread count) */
    enum { ECH = 4096 };
    const uint32_t nech = (g->num_entries + ECH - 1) / ECH;
    double *esum = fresh ? calloc(2 * (size_t)nech + 2, sizeof *esum) : NULL;
    if (fresh && !esum)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for fresh paths");
    double t1b = gi_now();
#pragma omp parallel for schedule(dynamic, 1) num_threads(r->threads)
    for (uint32_t ch = 0; ch < nech; ch++) {
        uint32_t e1 = (ch + 1) * ECH < g->num_entries ? (ch + 1) * ECH : g->num_entries;
        double s1 = 0.0, s2 = 0.0;
        for (uint32_t e = ch * ECH; e < e1; e++) {
            const int diffuse = r->entry_fd[3 * (size_t)e] >= 0.0f;
            for (uint64_t i = g->path_start[e] + 1; i < g->path_start[e + 1]; i++) {
                for (int c = 0; c < 3; c++)
                    r->flux[3 * i + c] = r->flux[3 * (i - 1) + c] * r->refl[3 * i + c];
                if (esum && diffuse) {
                    double l = 0.2126 * r->flux[3 * i] + 0.7152 * r->flux[3 * i + 1] + 0.0722 * r->flux[3 * i + 2];
                    s1 += l;
                    s2 += l * l;
                }
            }
        }
        if (esum) {
            esum[2 * ch] = s1;
            esum[2 * ch + 1] = s2;
        }
    }
    fbuf *fb = NULL;
    size_t fresh_lit = 0;
    r->fresh_deposits = r->fresh_lost = 0;
    r->fresh_used = 0;
    r->fresh_alpha = 1.0;
    r->fresh_ess[0] = r->fresh_ess[1] = 0.0;
    if (fresh) {
        double p1 = 0.0, p2 = 0.0;
        for (uint32_t ch = 0; ch < nech; ch++) {
            p1 += esum[2 * ch];
            p2 += esum[2 * ch + 1];
        }
        free(esum);
        if (!(fb = calloc((size_t)r->threads, sizeof *fb)))
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for fresh paths");
        /* a fixed count, or (gi_relight_set_fresh_auto) a pilot whose
         * effective sample size per path says how many paths bring the
         * two estimates together to the target: then that many, traced
         * anew (systematic sampling spreads any count over all the lit
         * entries, so the pilot's paths are not the first ones of more) */
        const double essp = p2 > 0.0 ? p1 * p1 / p2 : 0.0;
        uint32_t M = r->fresh_target ? GI_RELIGHT_FRESH_PILOT : r->fresh_paths;
        int frc = fresh_trace(r, fb, M, 1, &fresh_lit, st);
        double essf = frc ? 0.0 : fresh_ess_of(fb, r->threads);
        if (!frc && r->fresh_target && essp + essf < (double)r->fresh_target && essf > 0.0) {
            double need = ((double)r->fresh_target - essp) / (essf / (double)M);
            uint32_t m = need >= (double)GI_RELIGHT_FRESH_MAX ? GI_RELIGHT_FRESH_MAX : (uint32_t)ceil(need);
            if (m > M) {
                for (int t = 0; t < r->threads; t++)
                    fb[t].n = 0;
                M = m;
                frc = fresh_trace(r, fb, M, 0, &fresh_lit, st);
                essf = frc ? 0.0 : fresh_ess_of(fb, r->threads);
            }
        }
        if (frc) {
            for (int t = 0; t < r->threads; t++)
                free(fb[t].d);
            free(fb);
            return frc;
        }
        r->fresh_used = fresh_lit ? M : 0; /* none is traced where no entry is lit */
        /* two estimates of the same later bounces, weighed by their
         * effective sample sizes (sum w)^2 / sum w^2, inversely to their
         * variance: the .gip's photons of diffuse entries (few carry light,
         * and their flux can span orders of magnitude, as beside a lamp
         * close to a wall) and the fresh ones (about equal flux each) */
        r->fresh_ess[0] = essp;
        r->fresh_ess[1] = essf;
        r->fresh_alpha = essp + essf > 0.0 ? essp / (essp + essf) : 1.0;
        const float alpha = (float)r->fresh_alpha, beta = (float)(1.0 - r->fresh_alpha);
        if (alpha < 1.0f) {
#pragma omp parallel for schedule(dynamic, 1024) num_threads(r->threads)
            for (uint32_t e = 0; e < g->num_entries; e++) {
                if (r->entry_fd[3 * (size_t)e] < 0.0f)
                    continue;
                for (uint64_t i = g->path_start[e] + 1; i < g->path_start[e + 1]; i++)
                    for (int c = 0; c < 3; c++)
                        r->flux[3 * i + c] *= alpha;
            }
        }
        /* summed in path order (thread t's buffer holds a contiguous range) */
        for (int t = 0; t < r->threads; t++)
            for (size_t i = 0; i < fb[t].n; i++) {
                const struct fdep *d = &fb[t].d[i];
                if (d->key == GI_HVDS_NO_KEY) {
                    r->fresh_lost++;
                    continue;
                }
                r->fresh_deposits++;
                for (int c = 0; c < 3; c++)
                    r->fresh_acc[3 * (size_t)d->key + c] += (double)(beta * d->f[c]);
            }
    }
    double t2 = gi_now();
    /* 3. keys: sum of their photons, then up the hierarchy (parents after children) */
    uint32_t K = h->num_keys;
#pragma omp parallel for schedule(dynamic, 1024) num_threads(r->threads)
    for (uint32_t k = 0; k < K; k++) {
        /* with split rays the entry points (first in the list) are also
         * summed on their own */
        uint64_t mid = r->key_mid ? r->key_mid[k] : r->key_start[k];
        double a[3] = {0, 0, 0};
        for (uint64_t j = r->key_start[k]; j < mid; j++) {
            const float *f = r->flux + 3 * (size_t)r->key_photon[j];
            a[0] += f[0];
            a[1] += f[1];
            a[2] += f[2];
        }
        if (r->key_mid)
            for (int c = 0; c < 3; c++)
                r->key_flux0[3 * (size_t)k + c] = (float)a[c];
        for (uint64_t j = mid; j < r->key_start[k + 1]; j++) {
            const float *f = r->flux + 3 * (size_t)r->key_photon[j];
            a[0] += f[0];
            a[1] += f[1];
            a[2] += f[2];
        }
        if (fresh)
            for (int c = 0; c < 3; c++)
                a[c] += r->fresh_acc[3 * (size_t)k + c];
        r->key_flux[3 * k] = (float)a[0];
        r->key_flux[3 * k + 1] = (float)a[1];
        r->key_flux[3 * k + 2] = (float)a[2];
    }
    if (fb) {
        for (int t = 0; t < r->threads; t++) {
            for (size_t i = 0; i < fb[t].n; i++)
                if (fb[t].d[i].key != GI_HVDS_NO_KEY)
                    for (int c = 0; c < 3; c++)
                        r->fresh_acc[3 * (size_t)fb[t].d[i].key + c] = 0.0;
            free(fb[t].d);
        }
        free(fb);
    }
    for (uint32_t k = 0; k < K; k++) {
        uint32_t p = h->key_parent[k];
        if (p == GI_HVDS_NO_KEY)
            continue;
        for (int c = 0; c < 3; c++)
            r->key_flux[3 * (size_t)p + c] += r->key_flux[3 * (size_t)k + c];
        if (r->key_mid)
            for (int c = 0; c < 3; c++)
                r->key_flux0[3 * (size_t)p + c] += r->key_flux0[3 * (size_t)k + c];
    }
    /* the per-key factor of step 4 (gi_relight_gather), taken once here so
     * its pair loop reads one 16-byte record per ray */
    float w = (float)GI_PI / (float)(h->num_rays && h->num_gpoints ? h->num_rays / h->num_gpoints : 1);
#pragma omp parallel for schedule(static) num_threads(r->threads)
    for (uint32_t k = 0; k < K; k++) {
        for (int c = 0; c < 3; c++)
            r->key_rad[4 * (size_t)k + c] = (float)((double)r->key_flux[3 * (size_t)k + c] * h->key_scale[k] * w);
        if (r->key_mid) /* the pad: the luminance of its later bounces alone (lift_scale) */
            r->key_rad[4 * (size_t)k + 3] = (float)(later_lum(r, k) * h->key_scale[k] * w);
    }
    /* split rays: the entry points' mean radiance, sum dA kd E / (pi sum dA),
     * and the later vertices' radiance on their own */
#pragma omp parallel for schedule(static) num_threads(r->threads)
    for (uint32_t q = 0; q < r->num_slots; q++) {
        uint32_t k = r->slot_src[q] & ~SPLIT_LATER;
        for (int c = 0; c < 3; c++) {
            double f0 = r->key_flux0[3 * (size_t)k + c], v;
            if (r->slot_src[q] & SPLIT_LATER)
                v = fmax((double)r->key_flux[3 * (size_t)k + c] - f0, 0.0) * h->key_scale[k] * w;
            else
                v = r->key_da0[k] > 0.0 ? f0 * (double)w / (GI_PI * r->key_da0[k]) : 0.0;
            r->slot_rad[4 * (size_t)q + c] = (float)v;
        }
    }
    /* 4. the gathering points: when asked for (gi_relight_gather), only
     * those a view reads */
    r->gen++;
    double t4 = gi_now();
    /* -v (counted after the timings): how many photons after the entry
     * points carry light. The paths do not know the lights, so only those
     * from lit entry points do, and the later bounces' noise goes with
     * their count (under the low sun of untuned.script's u6 on Sponza:
     * 2.2%, docs/journal.md "Session 42") */
    size_t n_later = 0, n_lit = 0;
    if (gi_log_verbosity() >= 1) {
#pragma omp parallel for schedule(dynamic, 1024) num_threads(r->threads) reduction(+ : n_later, n_lit)
        for (uint32_t e = 0; e < g->num_entries; e++)
            for (uint64_t i = g->path_start[e] + 1; i < g->path_start[e + 1]; i++) {
                n_later++;
                n_lit += r->flux[3 * i] > 0.0f || r->flux[3 * i + 1] > 0.0f || r->flux[3 * i + 2] > 0.0f;
            }
    }
    gi_verbose("photon energies: entry-point rays %.1f ms, entry flux %.1f ms, along the paths %.1f ms; keys %.1f ms; "
               "%zu of %zu photons after the entry points carry light (%.1f%%)",
               1e3 * (t0b - t0), 1e3 * (t1 - t0b), 1e3 * (t2 - t1), 1e3 * (t4 - t2), n_lit, n_later,
               n_later ? 100.0 * (double)n_lit / (double)n_later : 0.0);
    if (fresh)
        gi_verbose("fresh paths: %u from %zu lit diffuse entry points, %zu photons summed into keys (%zu found no "
                   "key), %.1f ms",
                   r->fresh_used, fresh_lit, r->fresh_deposits, r->fresh_lost, 1e3 * (t2 - t1b));
    if (fresh && r->fresh_seen != SIZE_MAX)
        gi_verbose("fresh paths: %zu of the lit entry points (%.1f%% of their flux) on surfaces the last view's "
                   "gathering points see; the others start paths at %g times their flux's rate",
                   r->fresh_seen, 100.0 * r->fresh_seen_share, r->fresh_away);
    if (fresh)
        gi_verbose("fresh paths: traced by %.1f ms; effective sample sizes %.0f (.gip) and %.0f (fresh): weights "
                   "%.3f and %.3f",
                   1e3 * (r->fresh_t_keys - t1b), r->fresh_ess[0], r->fresh_ess[1], r->fresh_alpha,
                   1.0 - r->fresh_alpha);
    r->times.entry = t1 - t0;
    r->times.photons = t2 - t1;
    r->times.hvds = t4 - t2;
    r->times.gather = 0.0;
    return 0;
}

static inline uint32_t kbucket(const gi_relight *r, int64_t x, int64_t y, int64_t z)
{
    uint64_t h = (uint64_t)x * 73856093u ^ (uint64_t)y * 19349663u ^ (uint64_t)z * 83492791u;
    return (uint32_t)(h ^ (h >> 29)) & r->kmask;
}

static inline int64_t kcoord(const gi_relight *r, float v) { return (int64_t)floorf(v / r->kcell); }

static inline uint64_t kpack(int64_t x, int64_t y, int64_t z)
{
    return ((uint64_t)x & 0x1FFFFF) << 42 | ((uint64_t)y & 0x1FFFFF) << 21 | ((uint64_t)z & 0x1FFFFF);
}

int gi_relight_prepare_keys(gi_relight *r, gi_status *st)
{
    if (r->kb_start)
        return 0;
    const gi_gip *g = r->gip;
    const gi_hvds *h = r->h;
    uint64_t P = g->num_photons;
    uint32_t K = h->num_keys;
    if (P == 0 || P >= UINT32_MAX)
        return gi_status_set(st, GI_EXIT_DATA, "no photons to look keys up in");
    /* cells holding ~8 photons of a surface: side sqrt(8 A / P) */
    double area = 0.0;
    for (size_t t = 0; t < r->s->num_triangles; t++) {
        const float *v0 = r->s->positions + 3 * (size_t)r->s->indices[3 * t];
        const float *v1 = r->s->positions + 3 * (size_t)r->s->indices[3 * t + 1];
        const float *v2 = r->s->positions + 3 * (size_t)r->s->indices[3 * t + 2];
        gi_vec3 c = gi_cross(gi_sub(gi_v3p(v1), gi_v3p(v0)), gi_sub(gi_v3p(v2), gi_v3p(v0)));
        area += 0.5 * (double)gi_len(c);
    }
    r->kcell = (float)fmax(sqrt(8.0 * area / (double)P), 1e-6);
    uint32_t nb = 1;
    while (nb < P && nb < (1u << 30))
        nb <<= 1;
    r->kmask = nb - 1;
    r->kb_start = calloc((size_t)nb + 2, sizeof *r->kb_start);
    r->kslot = gi_alloc_large(P * sizeof *r->kslot);
    uint32_t *klift = malloc(((size_t)K + 1) * sizeof *klift);
    uint64_t *cnt = calloc((size_t)K + 1, sizeof *cnt);
    uint32_t *bk = gi_alloc_large(P * sizeof *bk);
    uint32_t *fill = malloc(((size_t)nb + 1) * sizeof *fill);
    if (!r->kb_start || !r->kslot || !klift || !cnt || !bk || !fill) {
        free(klift);
        free(cnt);
        free(bk);
        free(fill);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the photon grid");
    }
    /* photons under each key (parents after children, as in set_lights),
     * then the key each one lifts to */
    for (uint64_t p = 0; p < P; p++)
        if (h->photon_key[p] != GI_HVDS_NO_KEY)
            cnt[h->photon_key[p]]++;
    for (uint32_t k = 0; k < K; k++)
        if (h->key_parent[k] != GI_HVDS_NO_KEY)
            cnt[h->key_parent[k]] += cnt[k];
    for (uint32_t k = 0; k < K; k++) {
        uint32_t q = k;
        while (cnt[q] < 8 && h->key_parent[q] != GI_HVDS_NO_KEY && h->key_scale[h->key_parent[q]] > 0.0f)
            q = h->key_parent[q];
        klift[k] = q;
    }
    free(cnt);
    /* each photon's bucket (in parallel), its place in the bucket runs
     * (one pass in photon order, so that each bucket holds its photons in
     * the order of their indices and ties between equally near photons
     * break the same way), then the slots filled in parallel: the grid of
     * Sponza's 1.0 M photons 189 -> 138 ms, most of the rest the first
     * touch of its 40 MB */
    double tg0 = gi_now();
#pragma omp parallel for schedule(static) num_threads(r->threads)
    for (uint64_t p = 0; p < P; p++) {
        float x[3], n[3];
        gi_gip_vertex(g, r->s, p, x, n);
        bk[p] = kbucket(r, kcoord(r, x[0]), kcoord(r, x[1]), kcoord(r, x[2]));
    }
    double tg1 = gi_now();
    for (uint64_t p = 0; p < P; p++)
        r->kb_start[bk[p] + 1]++;
    for (uint32_t b = 0; b < nb; b++)
        r->kb_start[b + 1] += r->kb_start[b];
    memcpy(fill, r->kb_start, ((size_t)nb + 1) * sizeof *fill);
    for (uint64_t p = 0; p < P; p++)
        bk[p] = fill[bk[p]]++; /* now the photon's slot */
    double tg2 = gi_now();
#pragma omp parallel for schedule(static) num_threads(r->threads)
    for (uint64_t p = 0; p < P; p++) {
        struct kslot *ks = &r->kslot[bk[p]];
        gi_gip_vertex(g, r->s, p, ks->pos, ks->nrm);
        ks->id = kpack(kcoord(r, ks->pos[0]), kcoord(r, ks->pos[1]), kcoord(r, ks->pos[2]));
        uint32_t k = h->photon_key[p];
        ks->key = k == GI_HVDS_NO_KEY ? k : klift[k];
        ks->fine = k;
    }
    gi_verbose("photon grid: buckets %.1f ms, places %.1f ms, slots %.1f ms", 1e3 * (tg1 - tg0), 1e3 * (tg2 - tg1), 1e3 * (gi_now() - tg2));
    free(fill);
    free(bk);
    free(klift);
    return 0;
}

/* The nearest photon of cell (x, y, z) to p within *best (squared), normal
 * within 45 degrees of n; *bp its slot. */
static inline void kscan(const gi_relight *r, int64_t x, int64_t y, int64_t z, const float p[3], const float n[3],
                         float *best, uint32_t *bp)
{
    uint32_t b = kbucket(r, x, y, z);
    uint64_t id = kpack(x, y, z);
    /* without branches on the data: whether a photon is in the cell, faces
     * the right way and is nearer are coin tosses a branch mispredicts */
    float bd = *best;
    uint32_t bj = *bp;
    for (uint32_t j = r->kb_start[b]; j < r->kb_start[b + 1]; j++) {
        const struct kslot *ks = &r->kslot[j];
        const float *a = ks->pos, *an = ks->nrm;
        float dn = an[0] * n[0] + an[1] * n[1] + an[2] * n[2];
        float d0 = a[0] - p[0], d1 = a[1] - p[1], d2 = a[2] - p[2];
        float d = d0 * d0 + d1 * d1 + d2 * d2;
        /* another cell in the bucket, or a normal more than 45 degrees off: skipped */
        int take = (ks->id == id) & !(dn < 0.7071f) & (d < bd);
        bd = take ? d : bd;
        bj = take ? j : bj;
    }
    *best = bd;
    *bp = bj;
}

/* The cells around cell c that can hold a photon nearer to p than best
 * (squared): the distance from p to each one's box against it. Returns how
 * many, in the order dz, dy, dx (the order decides ties). Only the offsets
 * whose face is nearer than the bound are tried on each axis: a cell beyond
 * a farther face is at least that far (usually one to three cells remain of
 * the 26; the loop over all of them was a fifth of a glossy gather's key
 * lookups). */
static int knear_cells(const gi_relight *r, const int64_t c[3], const float p[3], float best, int64_t (*out)[3],
                       float *gout)
{
    const float cs = r->kcell;
    int off[3][3], no[3];
    float e2[3][3];
    for (int a = 0; a < 3; a++) {
        float base = (float)c[a] * cs;
        float lo = p[a] - base;      /* to the cell's lower face */
        float hi = base + cs - p[a]; /* to its upper face */
        int k = 0;
        if (lo * lo < best) {
            off[a][k] = -1;
            e2[a][k++] = lo * lo;
        }
        off[a][k] = 0;
        e2[a][k++] = 0.0f;
        if (hi * hi < best) {
            off[a][k] = 1;
            e2[a][k++] = hi * hi;
        }
        no[a] = k;
    }
    int m = 0;
    for (int iz = 0; iz < no[2]; iz++)
        for (int iy = 0; iy < no[1]; iy++)
            for (int ix = 0; ix < no[0]; ix++) {
                int dx = off[0][ix], dy = off[1][iy], dz = off[2][iz];
                if (!dx && !dy && !dz)
                    continue;
                /* the same sum, in the same order, as over all 26 */
                float g = 0.0f;
                g += e2[0][ix];
                g += e2[1][iy];
                g += e2[2][iz];
                if (g >= best)
                    continue;
                out[m][0] = c[0] + dx;
                out[m][1] = c[1] + dy;
                out[m][2] = c[2] + dz;
                gout[m++] = g;
            }
    return m;
}

/* Lookups in batches whose memory is asked for ahead: a lookup's time was
 * mostly waiting for its bucket's start and then its slots, one cache miss
 * after another (44% of a glossy material change's profile on Sponza). The
 * buckets of a batch's home cells are fetched together, then their slots,
 * then the same for the neighbours that remain candidates; each query scans
 * its cells in the order of the one-at-a-time search, with the same bound,
 * so the answers are the same. */
enum { KBATCH = 16 };

static void keys_at_batch(const gi_relight *r, int n, const float *p, const float *nrm, uint32_t *out, int fine)
{
    int64_t c[KBATCH][3];
    uint32_t b[KBATCH], bp[KBATCH];
    float best[KBATCH];
    for (int i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++)
            c[i][a] = kcoord(r, p[3 * i + a]);
        b[i] = kbucket(r, c[i][0], c[i][1], c[i][2]);
        __builtin_prefetch(&r->kb_start[b[i]]);
    }
    for (int i = 0; i < n; i++)
        __builtin_prefetch(&r->kslot[r->kb_start[b[i]]]);
    for (int i = 0; i < n; i++) {
        best[i] = r->kcell * r->kcell;
        bp[i] = UINT32_MAX;
        kscan(r, c[i][0], c[i][1], c[i][2], p + 3 * i, nrm + 3 * i, &best[i], &bp[i]);
    }
    int64_t nb[KBATCH][26][3];
    float ng[KBATCH][26];
    int nn[KBATCH];
    for (int i = 0; i < n; i++) {
        nn[i] = knear_cells(r, c[i], p + 3 * i, best[i], nb[i], ng[i]);
        for (int j = 0; j < nn[i]; j++)
            __builtin_prefetch(&r->kb_start[kbucket(r, nb[i][j][0], nb[i][j][1], nb[i][j][2])]);
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < nn[i]; j++)
            __builtin_prefetch(&r->kslot[r->kb_start[kbucket(r, nb[i][j][0], nb[i][j][1], nb[i][j][2])]]);
    for (int i = 0; i < n; i++) {
        /* the bound tightens as cells are scanned, as in the plain search:
         * a cell it now excludes holds nothing nearer */
        for (int j = 0; j < nn[i]; j++)
            if (ng[i][j] < best[i])
                kscan(r, nb[i][j][0], nb[i][j][1], nb[i][j][2], p + 3 * i, nrm + 3 * i, &best[i], &bp[i]);
        out[i] = bp[i] == UINT32_MAX ? GI_HVDS_NO_KEY : fine ? r->kslot[bp[i]].fine : r->kslot[bp[i]].key;
    }
}

void gi_relight_set_fresh_paths(gi_relight *r, uint32_t n)
{
    r->fresh_paths = n;
    r->fresh_target = 0;
}
void gi_relight_set_fresh_importance(gi_relight *r, int on) { r->fresh_away = on ? GI_RELIGHT_FRESH_AWAY : 1.0; }
void gi_relight_set_fresh_auto(gi_relight *r, uint32_t target)
{
    r->fresh_target = target;
    r->fresh_paths = 0;
}
uint32_t gi_relight_fresh_used(const gi_relight *r) { return r->fresh_used; }

void gi_relight_fresh_stats(const gi_relight *r, double ess[2], double *alpha, size_t *photons)
{
    ess[0] = r->fresh_ess[0];
    ess[1] = r->fresh_ess[1];
    *alpha = r->fresh_alpha;
    *photons = r->fresh_deposits;
}

static int fbuf_push(fbuf *b, gi_vec3 p, gi_vec3 n, gi_vec3 f)
{
    if (b->n == b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 4096;
        struct fdep *d = realloc(b->d, cap * sizeof *d);
        if (!d) {
            b->failed = 1;
            return -1;
        }
        b->d = d;
        b->cap = cap;
    }
    struct fdep *x = &b->d[b->n++];
    gi_v3store(x->p, p);
    gi_v3store(x->n, n);
    gi_v3store(x->f, f);
    x->key = GI_HVDS_NO_KEY;
    return 0;
}

/* Step 2b, fresh paths: r->fresh_paths paths from the diffuse entry points,
 * each chosen with probability in proportion to the luminance of its flux
 * (systematic sampling: an entry point with k times the mean flux per path
 * starts about k of them), so that every path carries the same luminance.
 * They leave in a cosine-distributed direction, are traced through the
 * scene's current materials (BSDF sampling, the precompute's Russian
 * roulette) and every vertex's outgoing flux is summed into the finest key
 * of the nearest precomputed photon. The paths of the .gip know nothing of
 * the lights: under a low sun 2.2% of them carry light (docs/journal.md, "Session
 * 42"), and the later bounces come from few photons of very unequal flux.
 * Thread t traces a contiguous range of paths in order (static schedule),
 * so the buffers read in thread order list the photons in path order
 * whatever the thread count. Path j takes the same random numbers in every
 * light state, so that a light moved a little moves the photons little. */
static double fresh_ess_of(const fbuf *fb, int threads)
{
    double f1 = 0.0, f2 = 0.0;
    for (int t = 0; t < threads; t++)
        for (size_t i = 0; i < fb[t].n; i++) {
            const struct fdep *d = &fb[t].d[i];
            if (d->key == GI_HVDS_NO_KEY)
                continue;
            double l = 0.2126 * d->f[0] + 0.7152 * d->f[1] + 0.0722 * d->f[2];
            f1 += l;
            f2 += l * l;
        }
    return f2 > 0.0 ? f1 * f1 / f2 : 0.0;
}

/* The running sum of the diffuse entries' flux luminance (r->fresh_cdf);
 * *nlit: how many are lit. */
/* The keys that the last view's gathering points read (their pairs' keys
 * and their split rays' keys) into r->key_seen; 0 when there is no view yet
 * or no memory for the marks. */
static int mark_seen_keys(gi_relight *r)
{
    const gi_hvds *h = r->h;
    if (!r->view_n || !h->photon_key)
        return 0;
    if (!r->key_seen && !(r->key_seen = malloc((size_t)h->num_keys + 1)))
        return 0;
    memset(r->key_seen, 0, (size_t)h->num_keys + 1);
    for (size_t q = 0; q < r->view_n; q++) {
        uint32_t i = r->view_pts[q];
        if (i >= h->num_gpoints)
            continue;
        const gi_gpoint *gp = &h->gpoints[i];
        for (uint32_t j = 0; j < gp->num_pairs; j++)
            r->key_seen[h->pair_key[gp->first_pair + j]] = 1;
        if (r->key_mid)
            for (uint32_t j = h->split_first[i]; j < h->split_first[i] + h->split_n0[i] + h->split_n1[i]; j++)
                r->key_seen[r->slot_src[r->split_slot[j]] & ~SPLIT_LATER] = 1;
    }
    return 1;
}

/* 1 if entry e's key or one of its ancestors is marked in r->key_seen */
static int entry_seen(const gi_relight *r, uint32_t e)
{
    const gi_hvds *h = r->h;
    uint32_t k = h->photon_key[r->gip->path_start[e]];
    for (int d = 0; k != GI_HVDS_NO_KEY && d < 64; d++, k = h->key_parent[k])
        if (r->key_seen[k])
            return 1;
    return 0;
}

/* The running sum of the lit diffuse entries' flux luminance times their
 * importance: 1 for an entry on a surface that the last view's gathering
 * points see (its key or an ancestor read by their rays), GI_RELIGHT_FRESH_AWAY
 * for the others, whose paths only reach the view after another bounce (or
 * never: an office's roof and outer walls under a sun, "Session 48"). A path
 * from an entry chosen with probability p carries flux / (M p), so the sum
 * stays unbiased; only where the paths start changes. No view yet (the first
 * frame): every entry 1. */
static void fresh_cdf_build(gi_relight *r, size_t *nlit)
{
    const gi_gip *g = r->gip;
    const uint32_t NE = g->num_entries;
    double *cdf = r->fresh_cdf;
    cdf[0] = 0.0;
    size_t lit = 0, seen = 0;
    double lsum = 0.0, lseen = 0.0;
    const int imp = r->fresh_away < 1.0 && mark_seen_keys(r);
    const double away = r->fresh_away;
#pragma omp parallel for schedule(static) num_threads(r->threads) reduction(+ : lit, seen, lsum, lseen)
    for (uint32_t e = 0; e < NE; e++) {
        double l = 0.0;
        if (r->entry_fd[3 * (size_t)e] >= 0.0f) {
            const float *f = r->flux + 3 * g->path_start[e];
            l = 0.2126 * f[0] + 0.7152 * f[1] + 0.0722 * f[2];
            l = l > 0.0 ? l : 0.0;
        }
        lit += l > 0.0;
        lsum += l;
        if (imp && l > 0.0) {
            if (entry_seen(r, e)) {
                seen++;
                lseen += l;
            } else {
                l *= away;
            }
        }
        cdf[e + 1] = l;
    }
    r->fresh_seen = imp ? seen : SIZE_MAX;
    r->fresh_seen_share = imp && lsum > 0.0 ? lseen / lsum : 0.0;
    for (uint32_t e = 0; e < NE; e++)
        cdf[e + 1] += cdf[e];
    *nlit = lit;
}

static int fresh_trace(gi_relight *r, fbuf *bufs, uint32_t M, int new_cdf, size_t *nlit, gi_status *st)
{
    const gi_gip *g = r->gip;
    const gi_scene *s = r->s;
    const uint32_t NE = g->num_entries;
    if (!r->fresh_cdf && !(r->fresh_cdf = gi_alloc_large(((size_t)NE + 1) * sizeof *r->fresh_cdf)))
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for fresh paths");
    const double *cdf = r->fresh_cdf;
    if (new_cdf)
        fresh_cdf_build(r, nlit);
    const double S = cdf[NE];
    if (!(S > 0.0) || !M) {
        r->fresh_t_keys = gi_now(); /* nothing lit: no path, no key */
        return 0;
    }
    gi_rng r0;
    gi_rng_seed(&r0, r->seed, 0x66726573ULL, 0);
    const double xi = gi_rng_double(&r0);
#pragma omp parallel num_threads(r->threads)
    {
        gi_rt_thread_init();
        fbuf *b = &bufs[omp_get_thread_num()];
        uint32_t lo = UINT32_MAX; /* the entry of the thread's last path */
#pragma omp for schedule(static)
        for (uint32_t j = 0; j < M; j++) {
            if (b->failed)
                continue;
            double u = ((double)j + xi) / (double)M * S;
            /* the last entry e with cdf[e] <= u: a binary search for the
             * thread's first path, then forward, as u grows with j (the
             * search had been 70% of this loop's own time) */
            if (lo == UINT32_MAX) {
                uint32_t hi = NE;
                lo = 0;
                while (hi - lo > 1) {
                    uint32_t mid = lo + (hi - lo) / 2;
                    if (cdf[mid] <= u)
                        lo = mid;
                    else
                        hi = mid;
                }
            } else
                while (lo + 1 < NE && cdf[lo + 1] <= u)
                    lo++;
            const uint32_t e = lo;
            const uint64_t v0 = g->path_start[e];
            const double le = cdf[e + 1] - cdf[e];
            if (!(le > 0.0))
                continue;
            gi_vec3 phi = gi_scale(gi_v3p(r->flux + 3 * v0), (float)(S / ((double)M * le)));
            gi_surface sf;
            gi_scene_surface(s, g->tri[v0], g->bary[2 * v0], g->bary[2 * v0 + 1], &sf);
            gi_vec3 ng = g->side[v0] ? gi_neg(sf.ng) : sf.ng;
            gi_vec3 ns = gi_dot(sf.ns, ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
            gi_rng rng;
            gi_rng_seed(&rng, r->seed, j, 0x46524553ULL);
            float u1 = gi_rng_float(&rng), u2 = gi_rng_float(&rng);
            gi_vec3 wo = gi_sample_cosine(ns, u1, u2);
            if (gi_dot(wo, ng) <= 0.0f)
                continue;
            gi_vec3 p = sf.p;
            for (int k = 1; k < 64; k++) {
                gi_hit hit;
                if (!gi_rt_intersect(r->rt, gi_rt_offset(p, ng, wo), wo, 0.0f, INFINITY, &hit))
                    break;
                gi_rt_surface(r->rt, &hit, &sf);
                gi_vec3 wi = gi_neg(wo);
                const gi_material *m = &r->mats[sf.material];
                int front = gi_dot(sf.ng, wi) > 0.0f;
                if (!front && !m->double_sided)
                    break;
                ng = front ? sf.ng : gi_neg(sf.ng);
                ns = gi_dot(sf.ns, ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
                gi_vec3 nk = ns; /* the normal a photon here is binned by (gi_gip_vertex) */
                if (gi_dot(ns, wi) <= 0.0f)
                    ns = ng;
                float bc[3];
                gi_scene_base_color(s, m, sf.uv0, sf.uv1, bc);
                gi_bsdf bsdf;
                gi_bsdf_init(&bsdf, m, gi_v3p(bc));
                float q = gi_clampf(gi_maxc(gi_bsdf_max_albedo(&bsdf)), GI_PHOTON_Q_MIN, GI_PHOTON_Q_MAX);
                if (gi_rng_float(&rng) >= q)
                    break;
                gi_vec3 wgt;
                float pdf;
                u1 = gi_rng_float(&rng);
                u2 = gi_rng_float(&rng);
                if (!gi_bsdf_sample(&bsdf, ns, wi, u1, u2, gi_rng_float(&rng), &wo, &wgt, &pdf))
                    break;
                phi = gi_mul(phi, gi_scale(wgt, 1.0f / q));
                if (fbuf_push(b, sf.p, nk, phi))
                    break;
                p = sf.p;
                if (gi_dot(wo, ng) <= 0.0f)
                    break;
            }
        }
        /* the keys, in batches (gi_relight_keys_at) */
#pragma omp barrier
#pragma omp master
        r->fresh_t_keys = gi_now();
        for (size_t i = 0; i < b->n && !b->failed; i += KBATCH) {
            int nb = b->n - i < KBATCH ? (int)(b->n - i) : KBATCH;
            float pp[3 * KBATCH], nn[3 * KBATCH];
            uint32_t kk[KBATCH];
            for (int q = 0; q < nb; q++) {
                memcpy(pp + 3 * q, b->d[i + (size_t)q].p, sizeof b->d[0].p);
                memcpy(nn + 3 * q, b->d[i + (size_t)q].n, sizeof b->d[0].n);
            }
            keys_at_batch(r, nb, pp, nn, kk, 1);
            for (int q = 0; q < nb; q++)
                b->d[i + (size_t)q].key = kk[q];
        }
    }
    for (int t = 0; t < r->threads; t++)
        if (bufs[t].failed)
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for fresh paths");
    return 0;
}

void gi_relight_keys_at(const gi_relight *r, size_t n, const float *p, const float *nrm, uint32_t *out)
{
    if (!r->kb_start) {
        for (size_t i = 0; i < n; i++)
            out[i] = GI_HVDS_NO_KEY;
        return;
    }
    for (size_t i = 0; i < n; i += KBATCH)
        keys_at_batch(r, n - i < KBATCH ? (int)(n - i) : KBATCH, p + 3 * i, nrm + 3 * i, out + i, 0);
}

float gi_relight_key_cell(const gi_relight *r) { return r->kb_start ? r->kcell : 0.0f; }

uint32_t gi_relight_key_at(const gi_relight *r, const float p[3], const float n[3])
{
    uint32_t k;
    gi_relight_keys_at(r, 1, p, n, &k);
    return k;
}

/* Step 4 for the gathering points idx[0..n) (idx NULL: all) not yet gathered
 * since the last gi_relight_set_lights: E = sum over rays of L(key) * pi / N,
 * L = flux * scale, from the per-key factor of set_lights, so the pair loop
 * reads one 16-byte record per ray. A view reads a small share of the points
 * (Sponza, 640x480: ~X of 162,880), so a light move gathers only those and a
 * camera move the ones it newly sees. */
/* Point i's split rays: their first bounces added to a, their later bounces
 * (read from the lifted keys) into l1. */
static void split_sums(const gi_relight *r, uint32_t i, double a[3], float l1[3])
{
    const gi_hvds *h = r->h;
    uint32_t j0 = h->split_first[i], j1 = j0 + h->split_n0[i], j2 = j1 + h->split_n1[i];
    const uint32_t *sl = r->split_slot;
    const uint16_t *sc = h->split_count;
    v4f s0 = {0, 0, 0, 0}, s1 = {0, 0, 0, 0};
    for (uint32_t j = j0; j < j1; j++) {
        v4f l0;
        memcpy(&l0, r->slot_rad + 4 * (size_t)sl[j], sizeof l0);
        s0 += l0 * (float)sc[j];
    }
    for (uint32_t j = j1; j < j2; j++) {
        v4f l0;
        memcpy(&l0, r->slot_rad + 4 * (size_t)sl[j], sizeof l0);
        s1 += l0 * (float)sc[j];
    }
    for (int c = 0; c < 3; c++) {
        a[c] += s0[c];
        l1[c] = s1[c];
    }
}

/* The factor on point i's lifted later bounces l1 (RGB), given the
 * luminance `later` of its pairs' later bounces. A ray lifted by
 * --key-photons reads its later bounces from a coarser key, which may
 * average surfaces far brighter than the one it hit: Sponza's gathering
 * points in tight corners (radius at --r-min) read 268-477 of their 1024
 * rays from one 0.3-1.1 m key and came to 3-12x the path tracer's indirect
 * illuminance (u6: 62.9 lux against 8.0, 57.3 of it lifted; u3 with another
 * seed: 151 against 12.9), each a bright blotch in a dim frame. Those rays'
 * later bounces are held to lift_cap times the mean of the point's other
 * rays (at least 64 of them), per ray. docs/journal.md, "Session 39": u3 0.1487 ->
 * 0.1480, u6 0.1862 -> 0.1816, f4 0.0671 -> 0.0648, u3 with gi-hvds and
 * gi-precompute seed 2 0.2401 -> 0.1632; over 6000 of u6's points against
 * 1024-spp sensors, those with half their light lifted read 1.3-1.5x in sum
 * before. */
static float lift_scale(const gi_relight *r, uint32_t i, float later, const float l1[3])
{
    if (!(r->lift_cap > 0.0f) || !r->gp_nreg)
        return 1.0f;
    const gi_hvds *h = r->h;
    uint32_t nl = 0, nreg = r->gp_nreg[i];
    for (uint32_t j = h->split_first[i] + h->split_n0[i]; j < h->split_first[i] + h->split_n0[i] + h->split_n1[i]; j++)
        nl += h->split_count[j];
    if (!nl || nreg < 64)
        return 1.0f;
    float ll = 0.2126f * l1[0] + 0.7152f * l1[1] + 0.0722f * l1[2];
    float lim = r->lift_cap * gi_fmaxf(later, 0.0f) / (float)nreg * (float)nl;
    return ll > lim ? lim / ll : 1.0f;
}

void gi_relight_set_lift_cap(gi_relight *r, float cap) { r->lift_cap = cap > 0.0f ? cap : 0.0f; }

void gi_relight_gather(gi_relight *r, const uint32_t *idx, size_t n)
{
    const gi_hvds *h = r->h;
    if (idx && n) { /* the view's points, for the next light state's fresh paths */
        if (r->view_cap < n) {
            uint32_t *v = realloc(r->view_pts, n * sizeof *v);
            if (v) {
                r->view_pts = v;
                r->view_cap = n;
            }
        }
        r->view_n = r->view_cap >= n ? n : 0; /* (out of memory: no importance) */
        if (r->view_n)
            memcpy(r->view_pts, idx, n * sizeof *idx);
    }
    if (!idx)
        n = h->num_gpoints;
    size_t ns = 0;
    for (size_t q = 0; q < n; q++) {
        uint32_t i = idx ? idx[q] : (uint32_t)q;
        if (i < h->num_gpoints && r->gp_gen[i] != r->gen) {
            r->gp_gen[i] = r->gen; /* listed once, however often asked for */
            r->gather_list[ns++] = i;
        }
    }
    if (!ns)
        return;
#pragma omp parallel for schedule(dynamic, 256) num_threads(r->threads)
    for (size_t q = 0; q < ns; q++) {
        const uint32_t i = r->gather_list[q];
        const gi_gpoint *gp = &h->gpoints[i];
        double a[3] = {0, 0, 0};
        float later = 0.0f; /* the pairs' later bounces, luminance (key_rad's pad) */
        {
            /* four floats a key (RGB and a pad), summed in float lanes: a
             * point has at most 1024 pairs, so float keeps ~1e-5 of the sum;
             * two accumulators halve the dependency chain */
            v4f s0 = {0, 0, 0, 0}, s1 = {0, 0, 0, 0};
            const uint32_t *pk = h->pair_key + gp->first_pair;
            const uint16_t *pc = h->pair_count + gp->first_pair;
            uint32_t npair = gp->num_pairs, j = 0;
            for (; j + 1 < npair; j += 2) {
                v4f l0, l1;
                memcpy(&l0, r->key_rad + 4 * (size_t)pk[j], sizeof l0);
                memcpy(&l1, r->key_rad + 4 * (size_t)pk[j + 1], sizeof l1);
                s0 += l0 * (float)pc[j];
                s1 += l1 * (float)pc[j + 1];
            }
            if (j < npair) {
                v4f l0;
                memcpy(&l0, r->key_rad + 4 * (size_t)pk[j], sizeof l0);
                s0 += l0 * (float)pc[j];
            }
            s0 += s1;
            a[0] = s0[0];
            a[1] = s0[1];
            a[2] = s0[2];
            later = s0[3];
        }
        if (r->key_mid) {
            float l1[3];
            split_sums(r, i, a, l1);
            float f = lift_scale(r, i, later, l1);
            for (int c = 0; c < 3; c++)
                a[c] += f * l1[c];
        }
        r->gp_e[3 * i] = (float)a[0];
        r->gp_e[3 * i + 1] = (float)a[1];
        r->gp_e[3 * i + 2] = (float)a[2];
        if (r->gp_t && r->any_glossy) {
            /* the cosine-weighted first moment M1 = (1/N) sum L w of the
             * incident radiance; for L(w) = a + b.w its part tangential to the
             * point's normal is b_t / 4, so T = 4 (M1 - (M1.n) n). Split rays
             * (GSPL) have no directions and are left out of it. In float
             * lanes like the sum above, from the same per-key radiance
             * (key_rad = L pi / N): in double from the fluxes it was half of
             * a light move's final gather once a material was glossy */
            v4f m0 = {0, 0, 0, 0}, m1 = {0, 0, 0, 0}, m2 = {0, 0, 0, 0};
            const uint32_t *pk = h->pair_key + gp->first_pair;
            const uint16_t *pc = h->pair_count + gp->first_pair;
            const int8_t *d = h->pair_dir + 3 * (size_t)gp->first_pair;
            for (uint32_t j = 0; j < gp->num_pairs; j++) {
                v4f l;
                memcpy(&l, r->key_rad + 4 * (size_t)pk[j], sizeof l);
                l *= (float)pc[j];
                m0 += l * (float)d[3 * j];
                m1 += l * (float)d[3 * j + 1];
                m2 += l * (float)d[3 * j + 2];
            }
            /* key_rad's pi / N and the directions' 127 out, the 4 in */
            const double inv = 4.0 / (127.0 * GI_PI);
            for (int c = 0; c < 3; c++) {
                double mc[3] = {m0[c], m1[c], m2[c]};
                double dn = mc[0] * gp->nrm[0] + mc[1] * gp->nrm[1] + mc[2] * gp->nrm[2];
                for (int x = 0; x < 3; x++)
                    r->gp_t[9 * (size_t)i + 3 * c + x] = (float)((mc[x] - dn * gp->nrm[x]) * inv);
            }
        }
    }
}

const float *gi_relight_gpoint_irradiance(gi_relight *r)
{
    gi_relight_gather(r, NULL, 0);
    return r->gp_e;
}
const float *gi_relight_gpoint_gradient(gi_relight *r)
{
    gi_relight_gather(r, NULL, 0);
    return r->any_glossy ? r->gp_t : NULL;
}
void gi_relight_gpoint_lifted(const gi_relight *r, uint32_t i, float out[3], float *later_out)
{
    const gi_hvds *h = r->h;
    out[0] = out[1] = out[2] = 0.0f;
    if (later_out)
        *later_out = 0.0f;
    if (!r->key_mid || i >= h->num_gpoints)
        return;
    const gi_gpoint *gp = &h->gpoints[i];
    double later = 0.0, a[3] = {0, 0, 0};
    for (uint32_t j = 0; j < gp->num_pairs; j++)
        later += (double)r->key_rad[4 * (size_t)h->pair_key[gp->first_pair + j] + 3] * h->pair_count[gp->first_pair + j];
    float l1[3];
    split_sums(r, i, a, l1);
    float f = lift_scale(r, i, (float)later, l1);
    for (int c = 0; c < 3; c++)
        out[c] = f * l1[c];
    if (later_out)
        *later_out = (float)later + gi_luminance(gi_v3p(out));
}
const float *gi_relight_gpoint_irradiance_lazy(const gi_relight *r) { return r->gp_e; }
const float *gi_relight_gpoint_gradient_lazy(const gi_relight *r) { return r->any_glossy ? r->gp_t : NULL; }
const float *gi_relight_key_flux(const gi_relight *r) { return r->key_flux; }
const float *gi_relight_key_flux0(const gi_relight *r) { return r->key_flux0; }
const gi_relight_times *gi_relight_times_last(const gi_relight *r) { return &r->times; }
