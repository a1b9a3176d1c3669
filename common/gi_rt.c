/* gi_rt.c - the Embree 3 scene and ray queries. */
#define _POSIX_C_SOURCE 200809L
#include "gi_rt.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <pmmintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <xmmintrin.h>

struct gi_rt {
    RTCDevice device;
    RTCScene scene;
    const gi_scene *s;
    float eps;
    int error;
    char error_msg[256];
};

static void on_error(void *user, enum RTCError code, const char *str)
{
    gi_rt *rt = user;
    if (rt && !rt->error) {
        rt->error = (int)code;
        snprintf(rt->error_msg, sizeof rt->error_msg, "embree error %d: %s", (int)code,
                 str ? str : "");
    }
}

/* Rays traced by the calling thread since its last gi_rt_take_ray_count. */
static _Thread_local uint64_t tl_rays;

uint64_t gi_rt_take_ray_count(void)
{
    uint64_t n = tl_rays;
    tl_rays = 0;
    return n;
}

void gi_rt_thread_init(void)
{
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

int gi_rt_new(const gi_scene *s, gi_rt **out, gi_status *st)
{
    *out = NULL;
    gi_rt *rt = calloc(1, sizeof *rt);
    if (!rt)
        return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory building the ray-tracing scene");
    rt->s = s;
    gi_rt_thread_init();
    rt->device = rtcNewDevice("verbose=0");
    if (!rt->device) {
        free(rt);
        return gi_status_set(st, GI_EXIT_SYSTEM, "cannot create the Embree device (error %d)",
                             (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(rt->device, on_error, rt);
    rt->scene = rtcNewScene(rt->device);
    /* robust: rays aimed at a closed mesh's shared edges and vertices
     * (test_closed_mesh_no_escape) missed it 4 times in 97 k with it and
     * 5845 times without; without it Sponza's camera moves were 12% faster
     * and its light moves 5% (2026-12-06), but a ray through an edge is a
     * light leak */
    rtcSetSceneFlags(rt->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(rt->scene, RTC_BUILD_QUALITY_HIGH);
    if (s->num_triangles > 0) {
        RTCGeometry g = rtcNewGeometry(rt->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        /* Embree-owned buffers carry the padding Embree needs past the last vertex. */
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                            3 * sizeof(float), s->num_vertices);
        unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                               3 * sizeof(unsigned), s->num_triangles);
        if (!vb || !ib) {
            rtcReleaseGeometry(g);
            gi_rt_free(rt);
            return gi_status_set(st, GI_EXIT_SYSTEM, "cannot allocate Embree buffers for %zu triangles",
                                 s->num_triangles);
        }
        memcpy(vb, s->positions, 3 * sizeof(float) * s->num_vertices);
        memcpy(ib, s->indices, 3 * sizeof(unsigned) * s->num_triangles);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(rt->scene, g, 0);
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(rt->scene);
    if (rt->error || rtcGetDeviceError(rt->device) != RTC_ERROR_NONE) {
        gi_status_set(st, GI_EXIT_SYSTEM, "building the Embree scene: %s",
                      rt->error_msg[0] ? rt->error_msg : "unknown error");
        gi_rt_free(rt);
        return GI_EXIT_SYSTEM;
    }
    float ext = 0.0f;
    for (int k = 0; k < 3; k++) {
        ext = gi_fmaxf(ext, fabsf(s->bbox_min[k]));
        ext = gi_fmaxf(ext, fabsf(s->bbox_max[k]));
    }
    rt->eps = gi_fmaxf(ext, 1e-6f) * 1e-5f;
    *out = rt;
    return 0;
}

void gi_rt_free(gi_rt *rt)
{
    if (!rt)
        return;
    if (rt->scene)
        rtcReleaseScene(rt->scene);
    if (rt->device)
        rtcReleaseDevice(rt->device);
    free(rt);
}

const gi_scene *gi_rt_scene(const gi_rt *rt) { return rt->s; }
float gi_rt_scene_eps(const gi_rt *rt) { return rt->eps; }

int gi_rt_intersect(const gi_rt *rt, gi_vec3 o, gi_vec3 d, float tmin, float tmax, gi_hit *hit)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    rh.ray.org_x = o.x;
    rh.ray.org_y = o.y;
    rh.ray.org_z = o.z;
    rh.ray.dir_x = d.x;
    rh.ray.dir_y = d.y;
    rh.ray.dir_z = d.z;
    rh.ray.tnear = tmin;
    rh.ray.tfar = tmax;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    tl_rays++;
    rtcIntersect1(rt->scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
        return 0;
    hit->t = rh.ray.tfar;
    hit->tri = rh.hit.primID;
    hit->u = rh.hit.u;
    hit->v = rh.hit.v;
    return 1;
}

/* Lanes [0, 16) of a packet from rays base.. of o, d (lanes past the m rays
 * left: invalid, copies of the first), from tnear to tfar (tmax[k], or
 * INFINITY when tmax is NULL). */
static void packet16(struct RTCRay16 *r, int *valid, int base, int m, const gi_vec3 *o, const gi_vec3 *d,
                     float tnear, const float *tmax)
{
    for (int i = 0; i < 16; i++) {
        int k = base + (i < m ? i : 0);
        valid[i] = i < m ? -1 : 0;
        r->org_x[i] = o[k].x;
        r->org_y[i] = o[k].y;
        r->org_z[i] = o[k].z;
        r->dir_x[i] = d[k].x;
        r->dir_y[i] = d[k].y;
        r->dir_z[i] = d[k].z;
        r->tnear[i] = tnear;
        r->tfar[i] = tmax ? tmax[k] : INFINITY;
        r->time[i] = 0.0f;
        r->mask[i] = 0xffffffffu;
        r->id[i] = (unsigned)i;
        r->flags[i] = 0;
    }
}

static void intersect_n(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, float tmin, const float *tmax,
                        gi_hit *hit, uint8_t *found);

void gi_rt_intersect_n(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, float tmin, gi_hit *hit,
                       uint8_t *found)
{
    intersect_n(rt, n, o, d, tmin, NULL, hit, found);
}

void gi_rt_intersect_n_upto(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, const float *tmax, gi_hit *hit,
                            uint8_t *found)
{
    intersect_n(rt, n, o, d, 0.0f, tmax, hit, found);
}

static void intersect_n(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, float tmin, const float *tmax,
                        gi_hit *hit, uint8_t *found)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    /* not RTC_INTERSECT_CONTEXT_FLAG_COHERENT: with it Embree 3.13 found
     * other (wrong) hits for some camera rays of a Sponza pixel (7 pixels of
     * a frame lit where single rays and the path tracer see shade); shadow
     * rays give the same answers either way */
    for (int base = 0; base < n; base += 16) {
        int m = n - base < 16 ? n - base : 16;
        RTC_ALIGN(64) int valid[16];
        RTC_ALIGN(64) struct RTCRayHit16 r;
        packet16(&r.ray, valid, base, m, o, d, tmin, tmax);
        for (int i = 0; i < 16; i++) {
            r.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
            r.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
        }
        tl_rays += (uint64_t)m;
        rtcIntersect16(valid, rt->scene, &ctx, &r);
        for (int i = 0; i < m; i++) {
            found[base + i] = r.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
            if (found[base + i]) {
                hit[base + i].t = r.ray.tfar[i];
                hit[base + i].tri = r.hit.primID[i];
                hit[base + i].u = r.hit.u[i];
                hit[base + i].v = r.hit.v[i];
            }
        }
    }
}

/* ---- near-geometry query (gi_rt_near_above) ---- */
typedef struct nearq {
    const gi_scene *s;
    double o[3], n[3], r2, hmin;
    int found, visits;
} nearq;

/* triangles a query looks at before it gives up (answers "unsure"): a
 * finely tessellated plane can put thousands within reach, which would
 * cost more than the rays the query is meant to save */
#define GI_RT_NEAR_VISITS 96

/* squared distance from the origin to segment a-b */
static double seg_dist2(const double *a, const double *b)
{
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    double t = l2 > 0.0 ? -(a[0] * ab[0] + a[1] * ab[1] + a[2] * ab[2]) / l2 : 0.0;
    t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
    double c[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
    return c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
}

/* Does triangle tri reach the part of the ball above the plane? The
 * triangle (relative to o) is clipped to n . q >= hmin, then the distance
 * from o to the clipped polygon (convex, planar, <= 4 corners) is compared
 * with r: o's projection on its plane when inside, else the nearest edge. */
static int near_tri(const nearq *q, uint32_t tri)
{
    const gi_scene *s = q->s;
    double v[3][3], h[3];
    for (int i = 0; i < 3; i++) {
        const float *p = s->positions + 3 * (size_t)s->indices[3 * (size_t)tri + (size_t)i];
        for (int k = 0; k < 3; k++)
            v[i][k] = (double)p[k] - q->o[k];
        h[i] = v[i][0] * q->n[0] + v[i][1] * q->n[1] + v[i][2] * q->n[2] - q->hmin;
    }
    double poly[4][3];
    int m = 0;
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3;
        if (h[i] >= 0.0)
            memcpy(poly[m++], v[i], sizeof poly[0]);
        if ((h[i] >= 0.0) != (h[j] >= 0.0)) {
            double t = h[i] / (h[i] - h[j]);
            for (int k = 0; k < 3; k++)
                poly[m][k] = v[i][k] + t * (v[j][k] - v[i][k]);
            m++;
        }
    }
    if (m == 0)
        return 0;
    double best = INFINITY;
    for (int i = 0; i < m; i++) {
        double d = seg_dist2(poly[i], poly[(i + 1) % m]);
        best = d < best ? d : best;
    }
    if (best <= q->r2)
        return 1;
    /* o's projection inside the polygon: the distance is the plane's */
    double e1[3], e2[3], pn[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = v[1][k] - v[0][k];
        e2[k] = v[2][k] - v[0][k];
    }
    pn[0] = e1[1] * e2[2] - e1[2] * e2[1];
    pn[1] = e1[2] * e2[0] - e1[0] * e2[2];
    pn[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double pl2 = pn[0] * pn[0] + pn[1] * pn[1] + pn[2] * pn[2];
    if (!(pl2 > 0.0))
        return 0; /* degenerate: its edges said it */
    double pd = pn[0] * v[0][0] + pn[1] * v[0][1] + pn[2] * v[0][2];
    if (pd * pd / pl2 > q->r2)
        return 0;
    double c[3] = {pn[0] * pd / pl2, pn[1] * pd / pl2, pn[2] * pd / pl2};
    int pos = 0, neg = 0;
    for (int i = 0; i < m; i++) {
        const double *a = poly[i], *b = poly[(i + 1) % m];
        double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double x = pn[0] * (ab[1] * ac[2] - ab[2] * ac[1]) + pn[1] * (ab[2] * ac[0] - ab[0] * ac[2]) +
                   pn[2] * (ab[0] * ac[1] - ab[1] * ac[0]);
        pos |= x >= 0.0;
        neg |= x <= 0.0;
    }
    return !(pos && neg);
}

static bool near_cb(struct RTCPointQueryFunctionArguments *a)
{
    nearq *q = a->userPtr;
    if (q->found)
        return false;
    if (++q->visits > GI_RT_NEAR_VISITS || near_tri(q, a->primID)) {
        q->found = 1;
        a->query->radius = 0.0f; /* nothing more to look at */
        return true;
    }
    return false;
}

int gi_rt_near_above(const gi_rt *rt, gi_vec3 o, gi_vec3 n, float r, float hmin)
{
    if (!rt->s || rt->s->num_triangles == 0)
        return 0;
    nearq q = {.s = rt->s,
               .o = {o.x, o.y, o.z},
               .n = {n.x, n.y, n.z},
               .r2 = (double)r * (double)r,
               .hmin = hmin,
               .found = 0,
               .visits = 0};
    struct RTCPointQuery pq = {.x = o.x, .y = o.y, .z = o.z, .time = 0.0f, .radius = r};
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(rt->scene, &pq, &ctx, near_cb, &q);
    return q.found;
}

int gi_rt_occluded(const gi_rt *rt, gi_vec3 o, gi_vec3 d, float tmin, float tmax)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    r.org_x = o.x;
    r.org_y = o.y;
    r.org_z = o.z;
    r.dir_x = d.x;
    r.dir_y = d.y;
    r.dir_z = d.z;
    r.tnear = tmin;
    r.tfar = tmax;
    r.time = 0.0f;
    r.mask = 0xffffffffu;
    r.id = 0;
    r.flags = 0;
    tl_rays++;
    rtcOccluded1(rt->scene, &ctx, &r);
    return r.tfar < 0.0f;
}

void gi_rt_occluded_n(const gi_rt *rt, int n, const gi_vec3 *o, const gi_vec3 *d, const float *tmax,
                      uint8_t *occluded)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (int base = 0; base < n; base += 16) {
        int m = n - base < 16 ? n - base : 16;
        RTC_ALIGN(64) int valid[16];
        RTC_ALIGN(64) struct RTCRay16 r;
        packet16(&r, valid, base, m, o, d, 0.0f, tmax);
        tl_rays += (uint64_t)m;
        rtcOccluded16(valid, rt->scene, &ctx, &r);
        for (int i = 0; i < m; i++)
            occluded[base + i] = r.tfar[i] < 0.0f;
    }
}

gi_vec3 gi_scene_tri_normal(const gi_scene *s, uint32_t tri)
{
    const uint32_t *ix = s->indices + 3 * (size_t)tri;
    gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
    gi_vec3 e1 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[1]), p0);
    gi_vec3 e2 = gi_sub(gi_v3p(s->positions + 3 * (size_t)ix[2]), p0);
    return gi_norm(gi_cross(e1, e2));
}

void gi_scene_surface(const gi_scene *s, uint32_t tri, float u, float v, gi_surface *sf)
{
    const uint32_t *ix = s->indices + 3 * (size_t)tri;
    gi_vec3 p0 = gi_v3p(s->positions + 3 * (size_t)ix[0]);
    gi_vec3 p1 = gi_v3p(s->positions + 3 * (size_t)ix[1]);
    gi_vec3 p2 = gi_v3p(s->positions + 3 * (size_t)ix[2]);
    float w = 1.0f - u - v;
    gi_vec3 e1 = gi_sub(p1, p0), e2 = gi_sub(p2, p0);
    sf->p = gi_add(p0, gi_add(gi_scale(e1, u), gi_scale(e2, v)));
    sf->ng = gi_norm(gi_cross(e1, e2)); /* (gi_scene_tri_normal: the same sums) */
    gi_vec3 n0 = gi_v3p(s->normals + 3 * (size_t)ix[0]);
    gi_vec3 n1 = gi_v3p(s->normals + 3 * (size_t)ix[1]);
    gi_vec3 n2 = gi_v3p(s->normals + 3 * (size_t)ix[2]);
    gi_vec3 ns = gi_add(gi_scale(n0, w), gi_add(gi_scale(n1, u), gi_scale(n2, v)));
    float l = gi_len(ns);
    sf->ns = l > 1e-12f ? gi_scale(ns, 1.0f / l) : sf->ng;
    for (int k = 0; k < 2; k++) {
        sf->uv0[k] = w * s->uv0[2 * ix[0] + k] + u * s->uv0[2 * ix[1] + k] + v * s->uv0[2 * ix[2] + k];
        sf->uv1[k] = w * s->uv1[2 * ix[0] + k] + u * s->uv1[2 * ix[1] + k] + v * s->uv1[2 * ix[2] + k];
    }
    sf->tri = tri;
    sf->material = s->tri_material[tri];
}

void gi_rt_surface(const gi_rt *rt, const gi_hit *hit, gi_surface *sf)
{
    gi_scene_surface(rt->s, hit->tri, hit->u, hit->v, sf);
}
