/* gi_light.c - sampling of point, spot, directional, rectangular area and
 * emissive-mesh lights. */
#include "gi_light.h"

#include "gi_emit.h"

#include <math.h>
#include <string.h>

float gi_spot_falloff(const gi_light *l, float cos_angle)
{
    float co = cosf(l->outer_cone), ci = cosf(l->inner_cone);
    float scale = 1.0f / gi_fmaxf(1e-4f, ci - co);
    float a = gi_clampf((cos_angle - co) * scale, 0.0f, 1.0f);
    return a * a;
}

gi_vec3 gi_area_light_normal(const gi_light *l)
{
    return gi_norm(gi_cross(gi_v3p(l->u), gi_v3p(l->v)));
}

float gi_area_light_area(const gi_light *l)
{
    return 4.0f * gi_len(gi_cross(gi_v3p(l->u), gi_v3p(l->v)));
}

int gi_light_sample_at(const gi_light *l, gi_vec3 x, float u1, float u2, gi_light_sample *s)
{
    if (!l->enabled)
        return 0;
    gi_vec3 col = gi_scale(gi_v3p(l->color), l->intensity);
    switch (l->type) {
    case GI_LIGHT_POINT:
    case GI_LIGHT_SPOT: {
        gi_vec3 d = gi_sub(gi_v3p(l->position), x);
        float d2 = gi_dot(d, d);
        if (!(d2 > 0.0f))
            return 0;
        float dist = sqrtf(d2);
        s->wi = gi_scale(d, 1.0f / dist);
        s->dist = dist;
        float att = 1.0f;
        if (l->type == GI_LIGHT_SPOT) {
            att = gi_spot_falloff(l, -gi_dot(s->wi, gi_v3p(l->direction)));
            if (att <= 0.0f)
                return 0;
        }
        s->value = gi_scale(col, att / d2);
        s->pdf = 0.0f;
        s->delta = 1;
        return 1;
    }
    case GI_LIGHT_DIRECTIONAL:
        s->wi = gi_neg(gi_norm(gi_v3p(l->direction)));
        s->dist = INFINITY;
        s->value = col;
        s->pdf = 0.0f;
        s->delta = 1;
        return 1;
    case GI_LIGHT_AREA: {
        gi_vec3 u = gi_v3p(l->u), v = gi_v3p(l->v);
        gi_vec3 p = gi_add(gi_v3p(l->position),
                           gi_add(gi_scale(u, 2.0f * u1 - 1.0f), gi_scale(v, 2.0f * u2 - 1.0f)));
        gi_vec3 d = gi_sub(p, x);
        float d2 = gi_dot(d, d);
        if (!(d2 > 0.0f))
            return 0;
        float dist = sqrtf(d2);
        s->wi = gi_scale(d, 1.0f / dist);
        float cosl = -gi_dot(s->wi, gi_area_light_normal(l));
        if (cosl <= 0.0f)
            return 0;
        float area = gi_area_light_area(l);
        s->pdf = d2 / (cosl * area);
        s->dist = dist;
        s->value = gi_scale(col, 1.0f / s->pdf);
        s->delta = 0;
        return 1;
    }
    case GI_LIGHT_MESH: {
        const gi_emit *e = l->mesh;
        if (!e || !e->n)
            return 0;
        /* u1 picks the triangle; what is left of it places the point, so a
         * stratified (u1, u2) stays stratified over the emitting area */
        size_t k = gi_emit_pick(e, u1);
        float w = e->cdf[k + 1] - e->cdf[k];
        float r1 = w > 0.0f ? gi_clampf((u1 - e->cdf[k]) / w, 0.0f, 0.99999994f) : 0.5f;
        gi_vec3 q, ng;
        if (!gi_emit_sample(e, k, x, r1, u2, s, &q, &ng))
            return 0;
        s->value = gi_mul(s->value, col);
        return 1;
    }
    default:
        return 0;
    }
}

/* Projected solid angle of the polygon q[0..m-1] (corners relative to the
 * receiver, m <= 4, convex) clipped to the half space above the plane of unit
 * normal nn: Lambert's formula, in double (far lights make neighbouring
 * directions nearly equal). */
static double polygon_form(double q[][3], int m, const double nn[3])
{
    double p[8][3];
    int k = 0;
    for (int i = 0; i < m; i++) {
        const double *a = q[i], *b = q[(i + 1) % m];
        double da = a[0] * nn[0] + a[1] * nn[1] + a[2] * nn[2];
        double db = b[0] * nn[0] + b[1] * nn[1] + b[2] * nn[2];
        if (da >= 0.0)
            memcpy(p[k++], a, sizeof p[0]);
        if ((da >= 0.0) != (db >= 0.0)) {
            double t = da / (da - db);
            for (int c = 0; c < 3; c++)
                p[k][c] = a[c] + t * (b[c] - a[c]);
            k++;
        }
    }
    if (k < 3)
        return 0.0;
    for (int i = 0; i < k; i++) {
        double len = sqrt(p[i][0] * p[i][0] + p[i][1] * p[i][1] + p[i][2] * p[i][2]);
        if (!(len > 0.0))
            return 0.0; /* the receiver on the light */
        for (int c = 0; c < 3; c++)
            p[i][c] /= len;
    }
    /* each edge: the angle it subtends times the normal's component along
     * the normal of the plane through it and the receiver */
    double sum = 0.0;
    for (int i = 0; i < k; i++) {
        const double *a = p[i], *b = p[(i + 1) % k];
        double cr[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        double sn = sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
        if (!(sn > 0.0))
            continue;
        double ang = atan2(sn, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
        sum += ang * (cr[0] * nn[0] + cr[1] * nn[1] + cr[2] * nn[2]) / sn;
    }
    return 0.5 * fabs(sum);
}

float gi_area_light_form(const gi_light *l, gi_vec3 x, gi_vec3 n)
{
    if (l->type != GI_LIGHT_AREA)
        return 0.0f;
    gi_vec3 c = gi_v3p(l->position), u = gi_v3p(l->u), v = gi_v3p(l->v);
    if (gi_dot(gi_sub(x, c), gi_area_light_normal(l)) <= 0.0f)
        return 0.0f;
    double q[4][3], nn[3] = {n.x, n.y, n.z};
    const float su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
    for (int i = 0; i < 4; i++) {
        q[i][0] = (double)c.x - x.x + su[i] * (double)u.x + sv[i] * (double)v.x;
        q[i][1] = (double)c.y - x.y + su[i] * (double)u.y + sv[i] * (double)v.y;
        q[i][2] = (double)c.z - x.z + su[i] * (double)u.z + sv[i] * (double)v.z;
    }
    return (float)polygon_form(q, 4, nn);
}

int gi_light_analytic(const gi_light *l, gi_vec3 x, gi_vec3 n, gi_vec3 *E)
{
    *E = gi_v3(0.0f, 0.0f, 0.0f);
    if (!l->enabled)
        return 0;
    gi_vec3 col = gi_scale(gi_v3p(l->color), l->intensity);
    if (l->type == GI_LIGHT_AREA) {
        *E = gi_scale(col, gi_area_light_form(l, x, n));
        return 1;
    }
    const gi_emit *e = l->mesh;
    if (l->type != GI_LIGHT_MESH || !e || e->n == 0 || e->n > GI_LIGHT_ANALYTIC_TRIS)
        return 0;
    double nn[3] = {n.x, n.y, n.z}, acc[3] = {0, 0, 0};
    for (size_t k = 0; k < e->n; k++) {
        const float *g = e->geo + 12 * k;
        double q[3][3];
        for (int c = 0; c < 3; c++) {
            q[0][c] = (double)g[c] - (&x.x)[c];
            q[1][c] = q[0][c] + g[3 + c];
            q[2][c] = q[0][c] + g[6 + c];
        }
        /* the emitting side faces x: its normal points towards x */
        double side = -(q[0][0] * g[9] + q[0][1] * g[10] + q[0][2] * g[11]);
        if (!(side > 0.0) && !(side < 0.0 && e->two_sided[k]))
            continue;
        double f = polygon_form(q, 3, nn);
        for (int c = 0; c < 3; c++)
            acc[c] += f * e->le[3 * k + c];
    }
    *E = gi_mul(col, gi_v3((float)acc[0], (float)acc[1], (float)acc[2]));
    return 1;
}

void gi_light_unit(const gi_light *l, gi_light *unit, float scale[3])
{
    *unit = *l;
    if (l->type == GI_LIGHT_MESH) {
        scale[0] = scale[1] = scale[2] = 1.0f;
        return;
    }
    for (int c = 0; c < 3; c++) {
        scale[c] = l->color[c] * l->intensity;
        unit->color[c] = 1.0f;
    }
    unit->intensity = 1.0f;
}


float gi_area_light_intersect(const gi_light *l, gi_vec3 o, gi_vec3 d, float tmin, float tmax,
                              int *front)
{
    gi_vec3 u = gi_v3p(l->u), v = gi_v3p(l->v);
    gi_vec3 n = gi_cross(u, v);
    float dn = gi_dot(d, n);
    if (dn == 0.0f)
        return 0.0f;
    gi_vec3 c = gi_v3p(l->position);
    float t = gi_dot(gi_sub(c, o), n) / dn;
    if (!(t > tmin && t < tmax))
        return 0.0f;
    gi_vec3 q = gi_sub(gi_madd(o, d, t), c);
    float uu = gi_dot(u, u), vv = gi_dot(v, v);
    float a = gi_dot(q, u) / uu, b = gi_dot(q, v) / vv;
    if (fabsf(a) > 1.0f || fabsf(b) > 1.0f)
        return 0.0f;
    *front = dn < 0.0f;
    return t;
}

float gi_area_light_pdf(const gi_light *l, gi_vec3 d, float t)
{
    float cosl = -gi_dot(d, gi_area_light_normal(l));
    if (cosl <= 0.0f)
        return 0.0f;
    return t * t / (cosl * gi_area_light_area(l));
}

float gi_light_power(const gi_light *l, float scene_cross_section_m2)
{
    if (!l->enabled)
        return 0.0f;
    float lum = gi_luminance(gi_v3p(l->color)) * l->intensity;
    switch (l->type) {
    case GI_LIGHT_POINT:
        return 4.0f * GI_PIf * lum;
    case GI_LIGHT_SPOT: {
        /* solid angle of the cone between inner and outer, halfway */
        float c = cosf(0.5f * (l->inner_cone + l->outer_cone));
        return 2.0f * GI_PIf * (1.0f - c) * lum;
    }
    case GI_LIGHT_DIRECTIONAL:
        return lum * scene_cross_section_m2;
    case GI_LIGHT_AREA:
        return GI_PIf * lum * gi_area_light_area(l);
    case GI_LIGHT_MESH:
        return l->mesh ? (float)l->mesh->power * lum : 0.0f;
    default:
        return 0.0f;
    }
}
