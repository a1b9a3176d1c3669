/* gi_emit.c - emissive triangles: build, sample, pdf (see gi_emit.h). */
#include "gi_emit.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void gi_emit_free(gi_emit *e)
{
    if (!e)
        return;
    free(e->tri);
    free(e->cdf);
    free(e->geo);
    free(e->area);
    free(e->le);
    free(e->two_sided);
    free(e->index_of_tri);
    free(e);
}

int gi_emit_build(const gi_scene *s, const gi_material *mats, gi_emit **out, gi_status *st)
{
    *out = NULL;
    size_t n = 0;
    for (size_t t = 0; t < s->num_triangles; t++)
        if (gi_maxc(gi_v3p(mats[s->tri_material[t]].emission)) > 0.0f)
            n++;
    if (!n)
        return 0;
    gi_emit *e = calloc(1, sizeof *e);
    if (!e)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory");
    e->num_triangles = s->num_triangles;
    e->tri = malloc(n * sizeof *e->tri);
    e->cdf = malloc((n + 1) * sizeof *e->cdf);
    e->geo = malloc(12 * n * sizeof *e->geo);
    e->area = malloc(n * sizeof *e->area);
    e->le = malloc(3 * n * sizeof *e->le);
    e->two_sided = malloc(n);
    e->index_of_tri = malloc((s->num_triangles + 1) * sizeof *e->index_of_tri);
    if (!e->tri || !e->cdf || !e->geo || !e->area || !e->le || !e->two_sided || !e->index_of_tri) {
        gi_emit_free(e);
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory for %zu emissive triangles", n);
    }
    double acc = 0.0, power = 0.0;
    e->cdf[0] = 0.0f;
    for (size_t t = 0; t < s->num_triangles; t++) {
        e->index_of_tri[t] = -1;
        const gi_material *m = &mats[s->tri_material[t]];
        gi_vec3 le = gi_v3p(m->emission);
        if (gi_maxc(le) <= 0.0f)
            continue;
        const uint32_t *ix = s->indices + 3 * t;
        gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
        gi_vec3 e1 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), p0);
        gi_vec3 e2 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), p0);
        gi_vec3 c = gi_cross(e1, e2);
        float a = 0.5f * gi_len(c);
        if (!(a > 0.0f) || !isfinite(a))
            continue;
        size_t k = e->n++;
        e->index_of_tri[t] = (int32_t)k;
        e->tri[k] = (uint32_t)t;
        float *g = e->geo + 12 * k;
        gi_v3store(g, p0);
        gi_v3store(g + 3, e1);
        gi_v3store(g + 6, e2);
        gi_v3store(g + 9, gi_scale(c, 0.5f / a));
        e->area[k] = a;
        gi_v3store(e->le + 3 * k, le);
        e->two_sided[k] = (unsigned char)(m->double_sided != 0);
        float lum = gi_luminance(le);
        acc += (double)a * (double)gi_fmaxf(lum, 1e-6f);
        power += GI_PI * (double)a * (double)gi_fmaxf(lum, 0.0f) * (e->two_sided[k] ? 2.0 : 1.0);
        e->cdf[e->n] = (float)acc;
    }
    if (!e->n) {
        gi_emit_free(e);
        return 0;
    }
    for (size_t i = 1; i < e->n; i++)
        e->cdf[i] = (float)(e->cdf[i] / acc);
    e->cdf[e->n] = 1.0f;
    e->power = power;
    *out = e;
    return 0;
}

size_t gi_emit_pick(const gi_emit *e, float u)
{
    size_t lo = 0, hi = e->n; /* cdf[lo] <= u < cdf[hi] */
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (e->cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

int gi_emit_sample(const gi_emit *e, size_t k, gi_vec3 x, float r1, float r2, gi_light_sample *s, gi_vec3 *q,
                   gi_vec3 *ng)
{
    const float *g = e->geo + 12 * k;
    /* barycentrics (1 - sqrt r1, r2 sqrt r1, (1 - r2) sqrt r1): uniform in area */
    float sq = sqrtf(r1);
    float w1 = r2 * sq, w2 = sq - w1;
    gi_vec3 p0 = gi_v3p(g), e1 = gi_v3p(g + 3), e2 = gi_v3p(g + 6), n = gi_v3p(g + 9);
    gi_vec3 p = gi_add(p0, gi_add(gi_scale(e1, w1), gi_scale(e2, w2)));
    *q = p;
    *ng = n;
    gi_vec3 d = gi_sub(p, x);
    float d2 = gi_dot(d, d);
    if (!(d2 > 0.0f))
        return 0;
    float dist = sqrtf(d2);
    gi_vec3 wi = gi_scale(d, 1.0f / dist);
    float cosl = -gi_dot(wi, n);
    if (!(cosl > 0.0f) && !e->two_sided[k])
        return 0;
    cosl = fabsf(cosl);
    if (!(cosl > 0.0f))
        return 0;
    float psel = e->cdf[k + 1] - e->cdf[k];
    float pdf = psel * d2 / (cosl * e->area[k]);
    if (!(pdf > 0.0f) || !isfinite(pdf))
        return 0;
    s->wi = wi;
    s->dist = dist;
    s->pdf = pdf;
    s->value = gi_scale(gi_v3p(e->le + 3 * k), 1.0f / pdf);
    s->delta = 0;
    return 1;
}

float gi_emit_pdf(const gi_emit *e, uint32_t tri, gi_vec3 d, float dist)
{
    if (!e || tri >= e->num_triangles)
        return 0.0f;
    int32_t k = e->index_of_tri[tri];
    if (k < 0)
        return 0.0f;
    float psel = e->cdf[k + 1] - e->cdf[k];
    float cosl = fabsf(gi_dot(gi_v3p(e->geo + 12 * (size_t)k + 9), d));
    if (!(cosl > 0.0f))
        return 0.0f;
    return psel * dist * dist / (cosl * e->area[k]);
}

void gi_emit_light(const gi_emit *e, uint64_t version, gi_light *l)
{
    memset(l, 0, sizeof *l);
    snprintf(l->name, sizeof l->name, "%s", "emissive-surfaces");
    l->type = GI_LIGHT_MESH;
    l->enabled = e != NULL;
    l->color[0] = l->color[1] = l->color[2] = 1.0f;
    l->intensity = 1.0f;
    l->mesh = e;
    l->mesh_version = version;
}
