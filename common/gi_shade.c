/* gi_shade.c - screen-space shading of relight frames. */
#define _POSIX_C_SOURCE 200809L
#include "gi_shade.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_light.h"
#include "gi_log.h"
#include "gi_math.h"
#include "gi_pt.h"
#include "gi_rng.h"

struct gi_shade {
    const gi_scene *s;
    const gi_rt *rt;
    const gi_hvds *h;
    /* uniform grid over the gathering points: cell = largest effective radius * reach */
    float gmin[3], cell;
    int gdim[3];
    uint32_t *gstart;   /* cells + 1 */
    uint32_t *gidx;
    float reach;        /* weights reach this many effective radii */
    /* G-buffer cache */
    gi_gpixel *px;
    int pw, ph, pss;
    gi_camera pcam;
    int valid;
};

void gi_shade_opts_default(gi_shade_opts *o)
{
    memset(o, 0, sizeof *o);
    o->area_samples = 16;
    o->ss = 1;
    o->direct = 1;
    o->indirect = 1;
    o->seed = 1;
}

int gi_shade_new(const gi_scene *s, const gi_rt *rt, const gi_hvds *h, gi_shade **out, gi_status *st)
{
    *out = NULL;
    gi_shade *sh = calloc(1, sizeof *sh);
    if (!sh)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    sh->s = s;
    sh->rt = rt;
    sh->h = h;
    sh->reach = 2.0f;
    float rmax = 0.0f;
    for (uint32_t i = 0; i < h->num_gpoints; i++)
        rmax = fmaxf(rmax, h->gpoints[i].radius);
    float ext = 0.0f;
    for (int a = 0; a < 3; a++)
        ext = fmaxf(ext, s->bbox_max[a] - s->bbox_min[a]);
    sh->cell = fmaxf(sh->reach * rmax, ext * 1e-3f + 1e-6f);
    size_t cells = 1;
    for (int a = 0; a < 3; a++) {
        sh->gmin[a] = s->bbox_min[a] - sh->cell;
        float span = s->bbox_max[a] - s->bbox_min[a] + 2.0f * sh->cell;
        sh->gdim[a] = (int)fminf(ceilf(span / sh->cell), 1024.0f);
        if (sh->gdim[a] < 1)
            sh->gdim[a] = 1;
        cells *= (size_t)sh->gdim[a];
    }
    /* keep the grid small: coarser cells if there would be too many */
    while (cells > 8u * 1024u * 1024u) {
        sh->cell *= 2.0f;
        cells = 1;
        for (int a = 0; a < 3; a++) {
            float span = s->bbox_max[a] - s->bbox_min[a] + 2.0f * sh->cell;
            sh->gdim[a] = (int)ceilf(span / sh->cell);
            cells *= (size_t)sh->gdim[a];
        }
    }
    sh->gstart = calloc(cells + 2, sizeof *sh->gstart);
    sh->gidx = malloc(((size_t)h->num_gpoints + 1) * sizeof *sh->gidx);
    if (!sh->gstart || !sh->gidx) {
        gi_shade_free(sh);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for the gathering-point grid");
    }
    uint32_t *cellof = malloc(((size_t)h->num_gpoints + 1) * sizeof *cellof);
    if (!cellof) {
        gi_shade_free(sh);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    }
    for (uint32_t i = 0; i < h->num_gpoints; i++) {
        int c[3];
        for (int a = 0; a < 3; a++) {
            c[a] = (int)floorf((h->gpoints[i].pos[a] - sh->gmin[a]) / sh->cell);
            c[a] = c[a] < 0 ? 0 : (c[a] >= sh->gdim[a] ? sh->gdim[a] - 1 : c[a]);
        }
        cellof[i] = (uint32_t)(((size_t)c[2] * (size_t)sh->gdim[1] + (size_t)c[1]) * (size_t)sh->gdim[0] + (size_t)c[0]);
        sh->gstart[cellof[i] + 1]++;
    }
    for (size_t c = 0; c < cells; c++)
        sh->gstart[c + 1] += sh->gstart[c];
    uint32_t *fill = malloc((cells + 1) * sizeof *fill);
    if (!fill) {
        free(cellof);
        gi_shade_free(sh);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    }
    memcpy(fill, sh->gstart, cells * sizeof *fill);
    for (uint32_t i = 0; i < h->num_gpoints; i++)
        sh->gidx[fill[cellof[i]]++] = i;
    free(fill);
    free(cellof);
    *out = sh;
    return 0;
}

void gi_shade_free(gi_shade *sh)
{
    if (!sh)
        return;
    free(sh->gstart);
    free(sh->gidx);
    free(sh->px);
    free(sh);
}

/* Irradiance-cache interpolation: w_i = 1 - E_i / reach with the Tabellion
 * error E_i = max(|x - x_i| / R_i, sqrt(1 - n.n_i) / sqrt(1 - cos 10deg));
 * if no point has weight, the nearest point on the same side within 4 cells. */
void gi_shade_irradiance_at(const gi_shade *sh, const float *gpe, const float p[3], const float n[3], float e[3])
{
    const gi_hvds *h = sh->h;
    const float inv_na = 1.0f / sqrtf(1.0f - cosf((float)(10.0 * GI_PI / 180.0)));
    int c[3];
    for (int a = 0; a < 3; a++)
        c[a] = (int)floorf((p[a] - sh->gmin[a]) / sh->cell);
    double acc[3] = {0, 0, 0}, wsum = 0.0;
    float best = INFINITY;
    int32_t besti = -1;
    for (int ring = 1; ring <= 4; ring++) {
        for (int dz = -ring; dz <= ring; dz++)
            for (int dy = -ring; dy <= ring; dy++)
                for (int dx = -ring; dx <= ring; dx++) {
                    if (ring > 1 && abs(dx) < ring && abs(dy) < ring && abs(dz) < ring)
                        continue; /* inner shells were done */
                    int x = c[0] + dx, y = c[1] + dy, z = c[2] + dz;
                    if (x < 0 || y < 0 || z < 0 || x >= sh->gdim[0] || y >= sh->gdim[1] || z >= sh->gdim[2])
                        continue;
                    size_t ci = ((size_t)z * (size_t)sh->gdim[1] + (size_t)y) * (size_t)sh->gdim[0] + (size_t)x;
                    for (uint32_t j = sh->gstart[ci]; j < sh->gstart[ci + 1]; j++) {
                        uint32_t i = sh->gidx[j];
                        const gi_gpoint *g = &h->gpoints[i];
                        float dn = n[0] * g->nrm[0] + n[1] * g->nrm[1] + n[2] * g->nrm[2];
                        if (dn <= 0.0f)
                            continue;
                        float d[3] = {p[0] - g->pos[0], p[1] - g->pos[1], p[2] - g->pos[2]};
                        float dist = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                        float ep = dist / g->radius;
                        float en = sqrtf(fmaxf(0.0f, 1.0f - dn)) * inv_na;
                        float err = fmaxf(ep, en);
                        if (ring == 1 && err < sh->reach) {
                            double w = 1.0 - err / sh->reach;
                            acc[0] += w * gpe[3 * i];
                            acc[1] += w * gpe[3 * i + 1];
                            acc[2] += w * gpe[3 * i + 2];
                            wsum += w;
                        }
                        float score = ep + en;
                        if (score < best) {
                            best = score;
                            besti = (int32_t)i;
                        }
                    }
                }
        if (wsum > 0.0 || besti >= 0)
            break;
    }
    if (wsum > 0.0) {
        for (int k = 0; k < 3; k++)
            e[k] = (float)(acc[k] / wsum);
    } else if (besti >= 0) {
        for (int k = 0; k < 3; k++)
            e[k] = gpe[3 * besti + k];
    } else {
        e[0] = e[1] = e[2] = 0.0f;
    }
}

static int same_camera(const gi_camera *a, const gi_camera *b)
{
    return !memcmp(a->position, b->position, sizeof a->position) && !memcmp(a->forward, b->forward, sizeof a->forward) &&
           !memcmp(a->up, b->up, sizeof a->up) && a->yfov == b->yfov && a->znear == b->znear && a->zfar == b->zfar;
}

int gi_shade_frame(gi_shade *sh, gi_gbuffer *gb, const gi_camera *cam, int w, int h,
                   const gi_light *lights, size_t num_lights, const gi_material *mats,
                   const float *gpe, const gi_shade_opts *o, float *rgb, gi_shade_times *times,
                   gi_status *st)
{
    int ss = o->ss < 1 ? 1 : o->ss;
    size_t np = (size_t)w * (size_t)h;
    double t0 = gi_now();
    if (!sh->valid || sh->pw != w || sh->ph != h || sh->pss != ss || !same_camera(&sh->pcam, cam)) {
        free(sh->px);
        sh->px = malloc(np * (size_t)(ss * ss) * sizeof *sh->px);
        if (!sh->px) {
            sh->valid = 0;
            return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for a %dx%d G-buffer", w, h);
        }
        for (int k = 0; k < ss * ss; k++) {
            float jx = ((float)(k % ss) + 0.5f) / (float)ss, jy = ((float)(k / ss) + 0.5f) / (float)ss;
            int rc = gi_gbuffer_render(gb, cam, w, h, jx, jy, sh->px + (size_t)k * np, st);
            if (rc) {
                sh->valid = 0;
                return rc;
            }
        }
        sh->pw = w;
        sh->ph = h;
        sh->pss = ss;
        sh->pcam = *cam;
        sh->valid = 1;
    }
    double t1 = gi_now();
    int threads = o->threads > 0 ? o->threads : omp_get_num_procs();
    int ka = (int)ceilf(sqrtf((float)(o->area_samples > 0 ? o->area_samples : 1)));
    gi_vec3 eye = gi_v3p(cam->position);
    const gi_scene *s = sh->s;
    double tdirect = 0.0;
    int has_area = 0;
    for (size_t l = 0; l < num_lights; l++)
        has_area |= lights[l].enabled && lights[l].type == GI_LIGHT_AREA;
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads) reduction(+ : tdirect)
    for (int y = 0; y < h; y++) {
        gi_rt_thread_init();
        for (int x = 0; x < w; x++) {
            size_t pix = (size_t)y * (size_t)w + (size_t)x;
            gi_vec3 sum = gi_v3(0, 0, 0);
            for (int k = 0; k < ss * ss; k++) {
                const gi_gpixel *g = &sh->px[(size_t)k * np + pix];
                int has_surface = g->tri && g->tri <= s->num_triangles;
                gi_surface sf;
                float tsurf = INFINITY;
                if (has_surface) {
                    gi_hit hit = {0.0f, g->tri - 1, g->u, g->v};
                    gi_rt_surface(sh->rt, &hit, &sf);
                    tsurf = gi_len(gi_sub(sf.p, eye));
                }
                if (has_area) {
                    /* area lights the camera sees directly (they do not hide what is behind) */
                    float jx = ((float)(k % ss) + 0.5f) / (float)ss, jy = ((float)(k / ss) + 0.5f) / (float)ss;
                    gi_vec3 ro, rd;
                    gi_camera_ray(cam, w, h, (float)x + jx, (float)y + jy, &ro, &rd);
                    for (size_t l = 0; l < num_lights; l++) {
                        const gi_light *lt = &lights[l];
                        int lf;
                        if (!lt->enabled || lt->type != GI_LIGHT_AREA)
                            continue;
                        float tl = gi_area_light_intersect(lt, ro, rd, 0.0f, tsurf * 0.9999f, &lf);
                        if (tl > 0.0f && lf)
                            sum = gi_add(sum, gi_scale(gi_v3p(lt->color), lt->intensity));
                    }
                }
                if (!has_surface)
                    continue;
                const gi_material *m = &mats[sf.material];
                gi_vec3 wo = gi_norm(gi_sub(eye, sf.p));
                int front = gi_dot(sf.ng, wo) > 0.0f;
                if (!front && !m->double_sided)
                    continue; /* back of a single-sided surface: black, as in the reference */
                gi_vec3 ng = front ? sf.ng : gi_neg(sf.ng);
                gi_vec3 ns = gi_dot(sf.ns, ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
                if (gi_dot(ns, wo) <= 0.0f)
                    ns = ng;
                gi_vec3 L = gi_v3p(m->emission);
                float base[3];
                gi_scene_base_color(s, m, sf.uv0, sf.uv1, base);
                gi_bsdf b;
                gi_bsdf_init(&b, m, gi_v3p(base));
                double td0 = gi_now();
                if (o->direct) {
                    for (size_t l = 0; l < num_lights; l++) {
                        const gi_light *lt = &lights[l];
                        if (!lt->enabled)
                            continue;
                        int ns_ = lt->type == GI_LIGHT_AREA ? ka * ka : 1;
                        gi_rng rng;
                        gi_rng_seed(&rng, o->seed, pix * 64u + (uint64_t)k, l);
                        gi_vec3 acc = gi_v3(0, 0, 0);
                        for (int j = 0; j < ns_; j++) {
                            float u1 = ((float)(j % ka) + gi_rng_float(&rng)) / (float)ka;
                            float u2 = ((float)(j / ka) + gi_rng_float(&rng)) / (float)ka;
                            gi_light_sample ls;
                            if (!gi_light_sample_at(lt, sf.p, u1, u2, &ls))
                                continue;
                            float cosi = gi_dot(ns, ls.wi);
                            if (cosi <= 0.0f || gi_dot(ng, ls.wi) <= 0.0f)
                                continue;
                            gi_vec3 org = gi_rt_offset(sf.p, ng, ls.wi);
                            float tmax = isfinite(ls.dist) ? ls.dist * (1.0f - 1e-4f) : INFINITY;
                            if (gi_rt_occluded(sh->rt, org, ls.wi, 0.0f, tmax))
                                continue;
                            gi_vec3 f = gi_bsdf_eval(&b, ns, wo, ls.wi);
                            acc = gi_add(acc, gi_scale(gi_mul(f, ls.value), cosi));
                        }
                        L = gi_add(L, gi_scale(acc, 1.0f / (float)ns_));
                    }
                }
                double td1 = gi_now();
                tdirect += td1 - td0;
                if (o->indirect && gpe) {
                    float e[3], pp[3], nn[3];
                    gi_v3store(pp, sf.p);
                    gi_v3store(nn, ng);
                    gi_shade_irradiance_at(sh, gpe, pp, nn, e);
                    /* low-frequency approximation: the whole BRDF sees the indirect light as diffuse */
                    gi_vec3 alb = gi_bsdf_max_albedo(&b);
                    L = gi_add(L, gi_scale(gi_mul(alb, gi_v3p(e)), GI_INV_PIf));
                }
                sum = gi_add(sum, L);
            }
            gi_v3store(rgb + 3 * pix, gi_scale(sum, 1.0f / (float)(ss * ss)));
        }
    }
    double t2 = gi_now();
    if (times) {
        times->gbuffer = t1 - t0;
        double wall = t2 - t1;
        double dshare = tdirect / (double)threads;
        if (dshare > wall)
            dshare = wall;
        times->direct = dshare;
        times->splat = wall - dshare;
    }
    return 0;
}
