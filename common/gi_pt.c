/* gi_pt.c - unbiased path tracing with NEE and MIS (the project's ground truth). */
#define _POSIX_C_SOURCE 200809L
#include "gi_pt.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "gi_brdf.h"
#include "gi_emit.h"
#include "gi_light.h"
#include "gi_log.h"

/* Sampling all lights at every vertex is cheapest in variance for a few
 * lights; past this many, one light is chosen in proportion to its power. */
#define GI_PT_ALL_LIGHTS_MAX 8

struct gi_pt {
    const gi_rt *rt;
    const gi_scene *s;
    const gi_material *mats;
    size_t num_mats;
    gi_pt_opts opts;
    /* enabled lights */
    gi_light *lights;
    size_t nl;
    float *light_cdf;   /* nl + 1, by power, used when nl > GI_PT_ALL_LIGHTS_MAX */
    float *light_prob;  /* selection probability of each light */
    int sample_all;
    /* emissive triangles (NULL: none) */
    gi_emit *emit;
};

void gi_pt_opts_default(gi_pt_opts *o)
{
    memset(o, 0, sizeof *o);
    o->seed = 1;
    o->max_bounces = -1;
    o->min_bounces = 0;
    o->threads = 0;
    o->progress = 1;
}

static size_t upper_bound(const float *cdf, size_t n, float u)
{
    size_t lo = 0, hi = n; /* cdf[0] = 0, cdf[n] = 1; find i with cdf[i] <= u < cdf[i+1] */
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

int gi_pt_new(const gi_rt *rt, const gi_light *lights, size_t num_lights,
              const gi_material *materials, size_t num_materials, const gi_pt_opts *opts,
              gi_pt **out, gi_status *st)
{
    *out = NULL;
    const gi_scene *s = gi_rt_scene(rt);
    if (num_materials < s->num_materials)
        return gi_status_set(st, GI_EXIT_DATA, "frame has %zu materials, scene has %zu",
                             num_materials, s->num_materials);
    gi_pt *pt = calloc(1, sizeof *pt);
    if (!pt)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    pt->rt = rt;
    pt->s = s;
    pt->mats = materials;
    pt->num_mats = num_materials;
    if (opts)
        pt->opts = *opts;
    else
        gi_pt_opts_default(&pt->opts);

    pt->lights = calloc(num_lights + 1, sizeof *pt->lights);
    pt->light_cdf = calloc(num_lights + 2, sizeof *pt->light_cdf);
    pt->light_prob = calloc(num_lights + 1, sizeof *pt->light_prob);
    if (!pt->lights || !pt->light_cdf || !pt->light_prob) {
        gi_pt_free(pt);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    }
    float dx = s->bbox_max[0] - s->bbox_min[0], dy = s->bbox_max[1] - s->bbox_min[1],
          dz = s->bbox_max[2] - s->bbox_min[2];
    float cross = fmaxf(dx * dy, fmaxf(dy * dz, dx * dz));
    double total = 0.0;
    for (size_t i = 0; i < num_lights; i++) {
        if (!lights[i].enabled || lights[i].intensity <= 0.0f)
            continue;
        pt->lights[pt->nl] = lights[i];
        float p = gi_light_power(&lights[i], cross);
        pt->light_cdf[pt->nl + 1] = (float)(total += (p > 0.0f ? p : 0.0f));
        pt->nl++;
    }
    pt->sample_all = pt->nl <= GI_PT_ALL_LIGHTS_MAX || total <= 0.0;
    for (size_t i = 0; i < pt->nl; i++) {
        if (pt->sample_all) {
            pt->light_prob[i] = 1.0f;
        } else {
            pt->light_prob[i] = (float)((pt->light_cdf[i + 1] - pt->light_cdf[i]) / total);
        }
    }
    if (!pt->sample_all) {
        for (size_t i = 1; i <= pt->nl; i++)
            pt->light_cdf[i] = (float)(pt->light_cdf[i] / total);
        pt->light_cdf[pt->nl] = 1.0f;
    }

    /* emissive triangles, by power */
    int erc = gi_emit_build(s, materials, &pt->emit, st);
    if (erc) {
        gi_pt_free(pt);
        return erc;
    }
    *out = pt;
    return 0;
}

void gi_pt_free(gi_pt *pt)
{
    if (!pt)
        return;
    free(pt->lights);
    free(pt->light_cdf);
    free(pt->light_prob);
    gi_emit_free(pt->emit);
    free(pt);
}

static inline float power_heuristic(float a, float b)
{
    float a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

static inline int finite3(gi_vec3 v) { return isfinite(v.x) && isfinite(v.y) && isfinite(v.z); }

typedef struct vertex {
    gi_vec3 p, ng, ns, wo;
    gi_bsdf bsdf;
} vertex;

/* Direct light at vertex v by next-event estimation; beta is the path
 * throughput. Adds MIS-weighted contributions. */
static gi_vec3 direct_light(const gi_pt *pt, const vertex *v, gi_sampler *rng)
{
    gi_vec3 L = gi_v3(0.0f, 0.0f, 0.0f);
    size_t first = 0, last = pt->nl;
    if (pt->nl && !pt->sample_all) {
        first = upper_bound(pt->light_cdf, pt->nl, gi_sampler_1d(rng));
        last = first + 1;
    }
    for (size_t i = first; i < last; i++) {
        const gi_light *l = &pt->lights[i];
        gi_light_sample ls;
        float u1, u2;
        gi_sampler_2d(rng, &u1, &u2);
        if (!gi_light_sample_at(l, v->p, u1, u2, &ls))
            continue;
        float cosn = gi_dot(v->ns, ls.wi);
        if (cosn <= 0.0f || gi_dot(v->ng, ls.wi) <= 0.0f)
            continue;
        gi_vec3 f = gi_bsdf_eval(&v->bsdf, v->ns, v->wo, ls.wi);
        if (gi_maxc(f) <= 0.0f)
            continue;
        gi_vec3 o = gi_rt_offset(v->p, v->ng, ls.wi);
        float tmax = gi_rt_shadow_tmax(v->p, o, ls.dist);
        if (gi_rt_occluded(pt->rt, o, ls.wi, 0.0f, tmax))
            continue;
        float psel = pt->light_prob[i];
        float w = 1.0f;
        if (!ls.delta)
            w = power_heuristic(ls.pdf * psel, gi_bsdf_pdf(&v->bsdf, v->ns, v->wo, ls.wi));
        L = gi_add(L, gi_scale(gi_mul(f, ls.value), cosn * w / psel));
    }
    if (pt->emit) {
        const gi_emit *em = pt->emit;
        size_t k = gi_emit_pick(em, gi_sampler_1d(rng));
        float r1, r2;
        gi_sampler_2d(rng, &r1, &r2);
        gi_light_sample ls;
        gi_vec3 q, lng;
        if (gi_emit_sample(em, k, v->p, r1, r2, &ls, &q, &lng)) {
            gi_vec3 d = ls.wi;
            float cosn = gi_dot(v->ns, d);
            if (cosn > 0.0f && gi_dot(v->ng, d) > 0.0f) {
                gi_vec3 f = gi_bsdf_eval(&v->bsdf, v->ns, v->wo, d);
                if (gi_maxc(f) > 0.0f) {
                    /* short of the emitter by a relative margin and the
                     * origin's offset: an absolute offset at the emitter's
                     * end is below Embree's precision in t from a few metres
                     * away, and the emitter then shadows itself
                     * (test_emissive_configuration_factor) */
                    gi_vec3 o = gi_rt_offset(v->p, v->ng, d);
                    float tmax = gi_rt_shadow_tmax(v->p, o, ls.dist);
                    if (!gi_rt_occluded(pt->rt, o, d, 0.0f, tmax)) {
                        float w = power_heuristic(ls.pdf, gi_bsdf_pdf(&v->bsdf, v->ns, v->wo, d));
                        L = gi_add(L, gi_scale(gi_mul(f, ls.value), cosn * w));
                    }
                }
            }
        }
    }
    return L;
}

/* Continue a path from vertex v (already shaded for direct light) and return
 * the radiance it gathers by indirect transport, times beta0. */
static gi_vec3 trace_from(const gi_pt *pt, vertex v, gi_vec3 beta, int depth, gi_sampler *rng)
{
    gi_vec3 L = gi_v3(0.0f, 0.0f, 0.0f);
    const gi_scene *s = pt->s;
    /* depth counts scattering events: the direct light gathered at vertex
     * depth d has bounced d times, and so has emission hit by a BSDF sample
     * leaving vertex d (the MIS partner of that direct light). */
    for (;;) {
        gi_vec3 wi, w;
        float pdf;
        float b1, b2;
        gi_sampler_2d(rng, &b1, &b2);
        if (!gi_bsdf_sample(&v.bsdf, v.ns, v.wo, b1, b2, gi_sampler_1d(rng), &wi, &w, &pdf))
            break;
        if (gi_dot(wi, v.ng) <= 0.0f)
            break;
        beta = gi_mul(beta, w);
        depth++;
        /* Russian roulette after a few bounces, no hard cap */
        if (depth >= 3) {
            float q = fminf(0.95f, gi_maxc(beta));
            if (!(q > 0.0f) || gi_sampler_1d(rng) >= q)
                break;
            beta = gi_scale(beta, 1.0f / q);
        }
        gi_vec3 o = gi_rt_offset(v.p, v.ng, wi);
        gi_hit h;
        int hit = gi_rt_intersect(pt->rt, o, wi, 0.0f, INFINITY, &h);
        float thit = hit ? h.t : INFINITY;
        /* area lights are not geometry: every one the segment crosses adds its
         * emission (MIS with light sampling) and the path goes on */
        for (size_t i = 0; i < pt->nl; i++) {
            const gi_light *l = &pt->lights[i];
            if (l->type != GI_LIGHT_AREA)
                continue;
            int lfront;
            float t = gi_area_light_intersect(l, o, wi, 0.0f, thit, &lfront);
            if (t > 0.0f && lfront && depth - 1 >= pt->opts.min_bounces) {
                float lp = gi_area_light_pdf(l, wi, t) * pt->light_prob[i];
                float wgt = power_heuristic(pdf, lp);
                L = gi_add(L, gi_scale(gi_mul(beta, gi_v3p(l->color)), l->intensity * wgt));
            }
        }
        if (!hit)
            break;
        gi_surface sf;
        gi_rt_surface(pt->rt, &h, &sf);
        const gi_material *m = &pt->mats[sf.material];
        gi_vec3 wo = gi_neg(wi);
        int front = gi_dot(sf.ng, wo) > 0.0f;
        if (!front && !m->double_sided)
            break; /* back of a single-sided surface: absorbs */
        vertex nv;
        nv.p = sf.p;
        nv.ng = front ? sf.ng : gi_neg(sf.ng);
        nv.ns = gi_dot(sf.ns, nv.ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
        if (gi_dot(nv.ns, wo) <= 0.0f)
            nv.ns = nv.ng;
        nv.wo = wo;
        gi_vec3 le = gi_v3p(m->emission);
        if (gi_maxc(le) > 0.0f && depth - 1 >= pt->opts.min_bounces) {
            float ep = gi_emit_pdf(pt->emit, sf.tri, wi, h.t);
            float wgt = power_heuristic(pdf, ep);
            L = gi_add(L, gi_scale(gi_mul(beta, le), wgt));
        }
        if (pt->opts.max_bounces >= 0 && depth > pt->opts.max_bounces)
            break;
        float base[3];
        gi_scene_base_color(s, m, sf.uv0, sf.uv1, base);
        gi_bsdf_init(&nv.bsdf, m, gi_v3p(base));
        if (depth >= pt->opts.min_bounces)
            L = gi_add(L, gi_mul(beta, direct_light(pt, &nv, rng)));
        v = nv;
    }
    return L;
}

gi_vec3 gi_pt_radiance(const gi_pt *pt, gi_vec3 o, gi_vec3 d, gi_sampler *rng)
{
    gi_hit h;
    int hit = gi_rt_intersect(pt->rt, o, d, 0.0f, INFINITY, &h);
    float thit = hit ? h.t : INFINITY;
    gi_vec3 L = gi_v3(0.0f, 0.0f, 0.0f);
    /* directly visible area lights (all in front of the surface; they do not block) */
    for (size_t i = 0; i < pt->nl; i++) {
        const gi_light *l = &pt->lights[i];
        if (l->type != GI_LIGHT_AREA)
            continue;
        int lfront;
        float t = gi_area_light_intersect(l, o, d, 0.0f, thit, &lfront);
        if (t > 0.0f && lfront && pt->opts.min_bounces <= 0)
            L = gi_add(L, gi_scale(gi_v3p(l->color), l->intensity));
    }
    if (!hit)
        return L;
    gi_surface sf;
    gi_rt_surface(pt->rt, &h, &sf);
    const gi_material *m = &pt->mats[sf.material];
    gi_vec3 wo = gi_neg(d);
    int front = gi_dot(sf.ng, wo) > 0.0f;
    if (!front && !m->double_sided)
        return L;
    vertex v;
    v.p = sf.p;
    v.ng = front ? sf.ng : gi_neg(sf.ng);
    v.ns = gi_dot(sf.ns, v.ng) < 0.0f ? gi_neg(sf.ns) : sf.ns;
    if (gi_dot(v.ns, wo) <= 0.0f)
        v.ns = v.ng;
    v.wo = wo;
    if ((front || m->double_sided) && pt->opts.min_bounces <= 0)
        L = gi_add(L, gi_v3p(m->emission));
    float base[3];
    gi_scene_base_color(pt->s, m, sf.uv0, sf.uv1, base);
    gi_bsdf_init(&v.bsdf, m, gi_v3p(base));
    if (pt->opts.min_bounces <= 0)
        L = gi_add(L, direct_light(pt, &v, rng));
    L = gi_add(L, trace_from(pt, v, gi_v3(1.0f, 1.0f, 1.0f), 0, rng));
    return L;
}

gi_vec3 gi_pt_irradiance(const gi_pt *pt, gi_vec3 x, gi_vec3 n, gi_sampler *rng)
{
    /* E = pi * L_o of a white Lambertian sensor: L_o = integral (1/pi) L_i cos dw */
    vertex v;
    v.p = x;
    v.ng = v.ns = gi_norm(n);
    v.wo = v.ns;
    gi_bsdf_lambert(&v.bsdf, gi_v3(1.0f, 1.0f, 1.0f));
    gi_vec3 L = pt->opts.min_bounces <= 0 ? direct_light(pt, &v, rng) : gi_v3(0.0f, 0.0f, 0.0f);
    L = gi_add(L, trace_from(pt, v, gi_v3(1.0f, 1.0f, 1.0f), 0, rng));
    return gi_scale(L, GI_PIf);
}

void gi_camera_frame_init(gi_camera_frame *cf, const gi_camera *cam, int w, int h)
{
    cf->f = gi_norm(gi_v3p(cam->forward));
    gi_vec3 up = gi_norm(gi_v3p(cam->up));
    cf->r = gi_norm(gi_cross(cf->f, up));
    cf->up = gi_cross(cf->r, cf->f);
    cf->th = tanf(0.5f * cam->yfov);
    cf->aspect = (float)w / (float)h;
    cf->w = (float)w;
    cf->h = (float)h;
    cf->o = gi_v3p(cam->position);
}

void gi_camera_ray(const gi_camera *cam, int w, int h, float px, float py, gi_vec3 *o, gi_vec3 *d)
{
    gi_camera_frame cf;
    gi_camera_frame_init(&cf, cam, w, h);
    gi_camera_frame_ray(&cf, px, py, o, d);
}

int gi_pt_render(const gi_pt *pt, const gi_camera *cam, int w, int h, int spp,
                 double time_budget, float *rgb, gi_pt_render_result *res, gi_status *st)
{
    if (w <= 0 || h <= 0 || spp <= 0)
        return gi_status_set(st, GI_EXIT_USAGE, "bad image size %dx%d or spp %d", w, h, spp);
    size_t np = (size_t)w * (size_t)h;
    /* Two independent halves: even samples k take points k / 2 of the
     * scrambled sequence of seed S, odd ones those of another scrambling;
     * acc sums the first half, last the second */
    double *acc = calloc(np * 3, sizeof *acc), *last = calloc(np * 3, sizeof *last);
    if (!acc || !last) {
        free(acc);
        free(last);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for a %dx%d image", w, h);
    }
    int threads = pt->opts.threads > 0 ? pt->opts.threads : omp_get_num_procs();
    double t0 = gi_now();
    int done = 0;
    uint64_t dropped = 0, rays = 0;
    gi_progress prog;
    int pass_spp = 1;
    gi_progress_begin(&prog, "path tracing", (uint64_t)h * (uint64_t)spp);
    while (done < spp) {
        int n = pass_spp;
        if (n > spp - done)
            n = spp - done;
        int s0 = done;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads) reduction(+ : dropped, rays)
        for (int y = 0; y < h; y++) {
            gi_rt_thread_init();
            gi_rt_take_ray_count();
            for (int x = 0; x < w; x++) {
                size_t pix = (size_t)y * (size_t)w + (size_t)x;
                for (int k = s0; k < s0 + n; k++) {
                    gi_sampler rng;
                    gi_sampler_init(&rng, pt->opts.seed ^ (k & 1 ? 0x6a09e667f3bcc909ULL : 0), pix,
                                    (uint32_t)k >> 1);
                    gi_vec3 o, d;
                    float jx, jy;
                    gi_sampler_2d(&rng, &jx, &jy);
                    gi_camera_ray(cam, w, h, (float)x + jx, (float)y + jy, &o, &d);
                    gi_vec3 L = gi_pt_radiance(pt, o, d, &rng);
                    if (!finite3(L)) {
                        dropped++;
                        continue;
                    }
                    double *sum = (k & 1 ? last : acc) + 3 * pix;
                    sum[0] += L.x;
                    sum[1] += L.y;
                    sum[2] += L.z;
                }
            }
            rays += gi_rt_take_ray_count();
            if (pt->opts.progress)
                gi_progress_add(&prog, (uint64_t)n);
        }
        done += n;
        if (time_budget > 0.0 && gi_now() - t0 >= time_budget)
            break;
        pass_spp *= 2;
    }
    if (pt->opts.progress)
        gi_progress_end(&prog);
    /* The image's own noise, from its two halves (the even samples and the
     * odd, independently scrambled): their means differ by noise alone, with
     * E[(mA - mB)^2] = vA + vB, and the image, (nA mA + nB mB) / n, has
     * variance (nA^2 vA + nB^2 vB) / n^2 = E[(mA - mB)^2] nA nB / n^2 when
     * the variances go as 1 / n (vA nA = vB nB). Checked against renders of
     * another seed in t020; written as gi:noise_rms and gi:noise_nrmse */
    int na = (done + 1) / 2, nb = done / 2;
    gi_ksum sd2 = {0, 0}, sm = {0, 0};
    for (int y = 0; y < h; y++) {
        double rd2 = 0.0, rm = 0.0; /* a row's sums, then compensated across rows */
        for (size_t i = 3 * (size_t)y * (size_t)w; i < 3 * ((size_t)y + 1) * (size_t)w; i++) {
            double all = acc[i] + last[i];
            if (nb > 0) {
                double d = acc[i] / na - last[i] / nb;
                rd2 += d * d;
            }
            rm += all / done;
            rgb[i] = (float)(all / done);
        }
        gi_ksum_add(&sd2, rd2);
        gi_ksum_add(&sm, rm);
    }
    free(acc);
    free(last);
    if (res) {
        double mean = gi_ksum_get(&sm) / (3.0 * (double)np);
        res->noise_rms = nb > 0 ? sqrt(gi_ksum_get(&sd2) / (3.0 * (double)np) * (double)na * (double)nb) / done : -1.0;
        res->noise_nrmse = nb > 0 && mean > 0.0 ? res->noise_rms / mean : -1.0;
        res->spp = done;
        res->seconds = gi_now() - t0;
        res->dropped = dropped;
        res->rays = rays;
    }
    return 0;
}

int gi_pt_sensors(const gi_pt *pt, const float *points, size_t n, int spp, double *lux,
                  double *stderr_lux, gi_status *st)
{
    if (spp < 2)
        return gi_status_set(st, GI_EXIT_USAGE, "sensors need at least 2 samples, got %d", spp);
    int threads = pt->opts.threads > 0 ? pt->opts.threads : omp_get_num_procs();
    gi_progress prog;
    gi_progress_begin(&prog, "sensors", n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (size_t i = 0; i < n; i++) {
        gi_rt_thread_init();
        gi_vec3 x = gi_v3p(points + 6 * i), nn = gi_v3p(points + 6 * i + 3);
        double sum = 0.0, sum2 = 0.0;
        int taken = 0;
        for (int k = 0; k < spp; k++) {
            gi_sampler rng;
            gi_sampler_init(&rng, pt->opts.seed ^ 0x5e45025ULL, i, (uint32_t)k);
            gi_vec3 e = gi_pt_irradiance(pt, x, nn, &rng);
            if (!finite3(e))
                continue;
            double y = gi_luminance(e);
            sum += y;
            sum2 += y * y;
            taken++;
        }
        double mean = taken ? sum / taken : 0.0;
        double var = taken > 1 ? (sum2 - sum * mean) / (taken - 1) : 0.0;
        lux[i] = mean;
        stderr_lux[i] = var > 0.0 && taken > 0 ? sqrt(var / taken) : 0.0;
        if (pt->opts.progress)
            gi_progress_add(&prog, 1);
    }
    if (pt->opts.progress)
        gi_progress_end(&prog);
    return 0;
}
