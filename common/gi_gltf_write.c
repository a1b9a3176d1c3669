/* gi_gltf_write.c - a small deterministic glTF 2.0 writer (JSON + embedded base64 buffer). */
#define _POSIX_C_SOURCE 200809L

#include "gi_gltf_write.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define GW_PI 3.14159265358979323846

enum { GW_POINT = 0, GW_SPOT = 1, GW_DIRECTIONAL = 2 };

/* Floats per stored triangle: 3 corners x 3 coordinates + the flat normal. */
#define GW_TRI_FLOATS 12

typedef struct gw_mat {
    char *name;
    float base[3];
    float rough, metal;
    float emis[3];
    int has_emis;
    int double_sided;
    float *tri;          /* GW_TRI_FLOATS per triangle */
    size_t ntri, cap;
} gw_mat;

typedef struct gw_light {
    char *name;
    int type;
    float pos[3];
    float q[4];          /* node rotation, x y z w */
    float color[3];
    float intensity;
    float inner, outer;
} gw_light;

typedef struct gw_cam {
    char *name;
    float pos[3];
    float q[4];
    float yfov, aspect;
} gw_cam;

struct gi_gltf_builder {
    gw_mat *mats;
    size_t nmat, capmat;
    gw_light *lights;
    size_t nlight, caplight;
    gw_cam *cams;
    size_t ncam, capcam;
    int err_code;        /* first recorded error, 0 if none */
    char err[512];
};

/* ---- errors recorded by the add functions ------------------------------ */

static void gw_fail(gi_gltf_builder *b, int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static void gw_fail(gi_gltf_builder *b, int code, const char *fmt, ...)
{
    if (b->err_code)
        return;  /* keep the first error: later ones are often consequences */
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(b->err, sizeof b->err, fmt, ap);
    va_end(ap);
    b->err_code = code;
}

static int gw_finite3(const float *v)
{
    return v && isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static int gw_grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    size_t nc = *cap ? *cap : 8;
    while (nc < need) {
        if (nc > SIZE_MAX / 2 / elem)
            return -1;
        nc *= 2;
    }
    void *q = realloc(*p, nc * elem);
    if (!q)
        return -1;
    *p = q;
    *cap = nc;
    return 0;
}

static char *gw_strdup(const char *s)
{
    if (!s)
        return NULL;
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

/* ---- builder ------------------------------------------------------------ */

gi_gltf_builder *gi_gltf_builder_new(void)
{
    return calloc(1, sizeof(gi_gltf_builder));
}

void gi_gltf_builder_free(gi_gltf_builder *b)
{
    if (!b)
        return;
    for (size_t i = 0; i < b->nmat; i++) {
        free(b->mats[i].name);
        free(b->mats[i].tri);
    }
    for (size_t i = 0; i < b->nlight; i++)
        free(b->lights[i].name);
    for (size_t i = 0; i < b->ncam; i++)
        free(b->cams[i].name);
    free(b->mats);
    free(b->lights);
    free(b->cams);
    free(b);
}

size_t gi_gltf_builder_triangles(const gi_gltf_builder *b)
{
    size_t n = 0;
    for (size_t i = 0; b && i < b->nmat; i++)
        n += b->mats[i].ntri;
    return n;
}

int gi_gltf_add_material(gi_gltf_builder *b, const char *name, const float base_color[3],
                         float roughness, float metallic, const float emission_nits[3],
                         int double_sided)
{
    if (!b)
        return -1;
    const char *nm = name ? name : "(unnamed)";
    if (!gw_finite3(base_color) || !isfinite(roughness) || !isfinite(metallic) ||
        (emission_nits && !gw_finite3(emission_nits))) {
        gw_fail(b, GI_EXIT_USAGE, "material '%s': missing or non-finite value", nm);
        return -1;
    }
    for (int k = 0; k < 3; k++) {
        if (base_color[k] < 0.0f || base_color[k] > 1.0f) {
            gw_fail(b, GI_EXIT_USAGE, "material '%s': base colour %g outside [0,1]", nm,
                    (double)base_color[k]);
            return -1;
        }
        if (emission_nits && emission_nits[k] < 0.0f) {
            gw_fail(b, GI_EXIT_USAGE, "material '%s': negative emission %g", nm,
                    (double)emission_nits[k]);
            return -1;
        }
    }
    if (roughness < 0.0f || roughness > 1.0f || metallic < 0.0f || metallic > 1.0f) {
        gw_fail(b, GI_EXIT_USAGE, "material '%s': roughness %g or metallic %g outside [0,1]", nm,
                (double)roughness, (double)metallic);
        return -1;
    }
    if (b->nmat >= INT32_MAX ||
        gw_grow((void **)&b->mats, &b->capmat, b->nmat + 1, sizeof *b->mats)) {
        gw_fail(b, GI_EXIT_SYSTEM, "material '%s': out of memory", nm);
        return -1;
    }
    gw_mat *m = &b->mats[b->nmat];
    memset(m, 0, sizeof *m);
    if (name && !(m->name = gw_strdup(name))) {
        gw_fail(b, GI_EXIT_SYSTEM, "material '%s': out of memory", nm);
        return -1;
    }
    memcpy(m->base, base_color, sizeof m->base);
    m->rough = roughness;
    m->metal = metallic;
    if (emission_nits && (emission_nits[0] > 0.0f || emission_nits[1] > 0.0f ||
                          emission_nits[2] > 0.0f)) {
        memcpy(m->emis, emission_nits, sizeof m->emis);
        m->has_emis = 1;
    }
    m->double_sided = double_sided != 0;
    return (int)b->nmat++;
}

void gi_gltf_add_triangle(gi_gltf_builder *b, const float p0[3], const float p1[3],
                          const float p2[3], int material)
{
    if (!b)
        return;
    if (material < 0 || (size_t)material >= b->nmat) {
        gw_fail(b, GI_EXIT_USAGE, "triangle: material index %d out of range (%zu materials)",
                material, b->nmat);
        return;
    }
    if (!gw_finite3(p0) || !gw_finite3(p1) || !gw_finite3(p2)) {
        gw_fail(b, GI_EXIT_USAGE, "triangle: missing or non-finite vertex");
        return;
    }
    gw_mat *m = &b->mats[material];
    /* Every corner becomes one u32-indexed vertex. */
    if (m->ntri >= UINT32_MAX / 3 ||
        gw_grow((void **)&m->tri, &m->cap, m->ntri + 1, GW_TRI_FLOATS * sizeof(float))) {
        gw_fail(b, GI_EXIT_SYSTEM, "triangle: out of memory or too many triangles");
        return;
    }
    float *t = m->tri + m->ntri * GW_TRI_FLOATS;
    for (int k = 0; k < 3; k++) {
        t[k] = p0[k];
        t[3 + k] = p1[k];
        t[6 + k] = p2[k];
    }
    /* Flat normal of the counter-clockwise winding, in double so thin
     * triangles keep a correct direction. A degenerate triangle gets +Z. */
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)p1[k] - p0[k];
        e2[k] = (double)p2[k] - p0[k];
    }
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                   e1[0] * e2[1] - e1[1] * e2[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len > 0.0 && isfinite(len)) {
        for (int k = 0; k < 3; k++)
            t[9 + k] = (float)(n[k] / len);
    } else {
        t[9] = 0.0f;
        t[10] = 0.0f;
        t[11] = 1.0f;
    }
    m->ntri++;
}

void gi_gltf_add_quad(gi_gltf_builder *b, const float p0[3], const float p1[3],
                      const float p2[3], const float p3[3], int material)
{
    gi_gltf_add_triangle(b, p0, p1, p2, material);
    gi_gltf_add_triangle(b, p0, p2, p3, material);
}

void gi_gltf_add_box(gi_gltf_builder *b, const float lo[3], const float hi[3], int material,
                     int inward)
{
    if (!b)
        return;
    if (!gw_finite3(lo) || !gw_finite3(hi)) {
        gw_fail(b, GI_EXIT_USAGE, "box: missing or non-finite corner");
        return;
    }
    /* Corner i has x from bit 0, y from bit 1, z from bit 2 (0 = lo, 1 = hi). */
    float c[8][3];
    for (int i = 0; i < 8; i++) {
        c[i][0] = (i & 1) ? hi[0] : lo[0];
        c[i][1] = (i & 2) ? hi[1] : lo[1];
        c[i][2] = (i & 4) ? hi[2] : lo[2];
    }
    /* Faces listed counter-clockwise seen from outside (for lo < hi). */
    static const int face[6][4] = {
        {0, 4, 6, 2}, /* -x */
        {1, 3, 7, 5}, /* +x */
        {0, 1, 5, 4}, /* -y */
        {2, 6, 7, 3}, /* +y */
        {0, 2, 3, 1}, /* -z */
        {4, 5, 7, 6}, /* +z */
    };
    for (int f = 0; f < 6; f++) {
        const int *v = face[f];
        if (inward)
            gi_gltf_add_quad(b, c[v[0]], c[v[3]], c[v[2]], c[v[1]], material);
        else
            gi_gltf_add_quad(b, c[v[0]], c[v[1]], c[v[2]], c[v[3]], material);
    }
}

/* ---- rotations ------------------------------------------------------------ */

static void gw_quat_identity(float q[4])
{
    q[0] = q[1] = q[2] = 0.0f;
    q[3] = 1.0f;
}

int gi_gltf_quat_from_dir(const float dir[3], float q[4])
{
    gw_quat_identity(q);
    if (!gw_finite3(dir))
        return -1;
    double d[3] = {dir[0], dir[1], dir[2]};
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 0.0) || !isfinite(len))
        return -1;
    for (int k = 0; k < 3; k++)
        d[k] /= len;
    /* Shortest arc from a = (0,0,-1) to d: (a x d, 1 + a.d) normalised, i.e.
     * (d.y, -d.x, 0, 1 - d.z). 1 - d.z cancels when d is near +Z, so use the
     * equal (d.x^2 + d.y^2) / (1 + d.z) there. */
    double w = d[2] > 0.0 ? (d[0] * d[0] + d[1] * d[1]) / (1.0 + d[2]) : 1.0 - d[2];
    double x = d[1], y = -d[0];
    double n = sqrt(x * x + y * y + w * w);
    if (!(n > 1e-300)) {
        /* d = +Z exactly: any half turn about an axis in the XY plane; take +Y. */
        q[0] = 0.0f;
        q[1] = 1.0f;
        q[2] = 0.0f;
        q[3] = 0.0f;
        return 0;
    }
    q[0] = (float)(x / n);
    q[1] = (float)(y / n);
    q[2] = 0.0f;
    q[3] = (float)(w / n);
    return 0;
}

static int gw_unit(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(l > 0.0) || !isfinite(l))
        return -1;
    v[0] /= l;
    v[1] /= l;
    v[2] /= l;
    return 0;
}

static void gw_cross(const double a[3], const double b[3], double r[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

int gi_gltf_quat_look_at(const float forward[3], const float up[3], float q[4])
{
    gw_quat_identity(q);
    if (!gw_finite3(forward))
        return -1;
    double f[3] = {forward[0], forward[1], forward[2]};
    if (gw_unit(f))
        return -1;
    /* right = f x up; try the caller's hint, then +Y, then +Z. */
    double hints[3][3] = {{0, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    if (gw_finite3(up)) {
        hints[0][0] = up[0];
        hints[0][1] = up[1];
        hints[0][2] = up[2];
    }
    double r[3] = {0, 0, 0};
    int ok = 0;
    for (int h = 0; h < 3 && !ok; h++) {
        double u[3] = {hints[h][0], hints[h][1], hints[h][2]};
        if (gw_unit(u))
            continue;
        gw_cross(f, u, r);
        /* |f x u| = sin(angle): refuse nearly parallel hints. */
        double s = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        ok = s > 1e-6 && gw_unit(r) == 0;
    }
    if (!ok)
        return -1;  /* cannot happen for a unit f: +Y and +Z are not both parallel to it */
    double u[3];
    gw_cross(r, f, u);
    /* Rotation matrix columns: local X -> r, local Y -> u, local Z -> -f. */
    double m[3][3] = {{r[0], u[0], -f[0]}, {r[1], u[1], -f[1]}, {r[2], u[2], -f[2]}};
    double tr = m[0][0] + m[1][1] + m[2][2];
    double x, y, z, w;
    if (tr > 0.0) {
        double s = sqrt(tr + 1.0) * 2.0;
        w = 0.25 * s;
        x = (m[2][1] - m[1][2]) / s;
        y = (m[0][2] - m[2][0]) / s;
        z = (m[1][0] - m[0][1]) / s;
    } else if (m[0][0] > m[1][1] && m[0][0] > m[2][2]) {
        double s = sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2.0;
        w = (m[2][1] - m[1][2]) / s;
        x = 0.25 * s;
        y = (m[0][1] + m[1][0]) / s;
        z = (m[0][2] + m[2][0]) / s;
    } else if (m[1][1] > m[2][2]) {
        double s = sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2.0;
        w = (m[0][2] - m[2][0]) / s;
        x = (m[0][1] + m[1][0]) / s;
        y = 0.25 * s;
        z = (m[1][2] + m[2][1]) / s;
    } else {
        double s = sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2.0;
        w = (m[1][0] - m[0][1]) / s;
        x = (m[0][2] + m[2][0]) / s;
        y = (m[1][2] + m[2][1]) / s;
        z = 0.25 * s;
    }
    if (w < 0.0) {  /* one canonical sign, so equal rotations print equally */
        x = -x;
        y = -y;
        z = -z;
        w = -w;
    }
    double n = sqrt(x * x + y * y + z * z + w * w);
    q[0] = (float)(x / n);
    q[1] = (float)(y / n);
    q[2] = (float)(z / n);
    q[3] = (float)(w / n);
    return 0;
}

/* ---- lights and cameras -------------------------------------------------- */

static gw_light *gw_new_light(gi_gltf_builder *b, const char *name, const float color[3],
                              float intensity, const char *what)
{
    const char *nm = name ? name : "(unnamed)";
    if (!gw_finite3(color) || !isfinite(intensity) || intensity < 0.0f || color[0] < 0.0f ||
        color[1] < 0.0f || color[2] < 0.0f) {
        gw_fail(b, GI_EXIT_USAGE, "%s light '%s': missing, negative or non-finite colour or intensity",
                what, nm);
        return NULL;
    }
    if (gw_grow((void **)&b->lights, &b->caplight, b->nlight + 1, sizeof *b->lights)) {
        gw_fail(b, GI_EXIT_SYSTEM, "%s light '%s': out of memory", what, nm);
        return NULL;
    }
    gw_light *l = &b->lights[b->nlight];
    memset(l, 0, sizeof *l);
    if (name && !(l->name = gw_strdup(name))) {
        gw_fail(b, GI_EXIT_SYSTEM, "%s light '%s': out of memory", what, nm);
        return NULL;
    }
    memcpy(l->color, color, sizeof l->color);
    l->intensity = intensity;
    gw_quat_identity(l->q);
    b->nlight++;
    return l;
}

void gi_gltf_add_point_light(gi_gltf_builder *b, const char *name, const float pos[3],
                             const float color[3], float intensity_cd)
{
    if (!b)
        return;
    if (!gw_finite3(pos)) {
        gw_fail(b, GI_EXIT_USAGE, "point light '%s': missing or non-finite position",
                name ? name : "(unnamed)");
        return;
    }
    gw_light *l = gw_new_light(b, name, color, intensity_cd, "point");
    if (!l)
        return;
    l->type = GW_POINT;
    memcpy(l->pos, pos, sizeof l->pos);
}

void gi_gltf_add_spot_light(gi_gltf_builder *b, const char *name, const float pos[3],
                            const float dir[3], const float color[3], float intensity_cd,
                            float inner_rad, float outer_rad)
{
    if (!b)
        return;
    const char *nm = name ? name : "(unnamed)";
    float q[4];
    if (!gw_finite3(pos) || gi_gltf_quat_from_dir(dir, q)) {
        gw_fail(b, GI_EXIT_USAGE, "spot light '%s': missing or non-finite position, or zero direction",
                nm);
        return;
    }
    if (!(inner_rad >= 0.0f && inner_rad < outer_rad && outer_rad <= (float)(GW_PI / 2))) {
        gw_fail(b, GI_EXIT_USAGE, "spot light '%s': cone angles %g, %g not 0 <= inner < outer <= pi/2",
                nm, (double)inner_rad, (double)outer_rad);
        return;
    }
    gw_light *l = gw_new_light(b, name, color, intensity_cd, "spot");
    if (!l)
        return;
    l->type = GW_SPOT;
    memcpy(l->pos, pos, sizeof l->pos);
    memcpy(l->q, q, sizeof l->q);
    l->inner = inner_rad;
    l->outer = outer_rad;
}

void gi_gltf_add_directional_light(gi_gltf_builder *b, const char *name, const float dir[3],
                                   const float color[3], float illuminance_lux)
{
    if (!b)
        return;
    float q[4];
    if (gi_gltf_quat_from_dir(dir, q)) {
        gw_fail(b, GI_EXIT_USAGE, "directional light '%s': zero or non-finite direction",
                name ? name : "(unnamed)");
        return;
    }
    gw_light *l = gw_new_light(b, name, color, illuminance_lux, "directional");
    if (!l)
        return;
    l->type = GW_DIRECTIONAL;
    memcpy(l->q, q, sizeof l->q);
}

void gi_gltf_add_camera(gi_gltf_builder *b, const char *name, const float pos[3],
                        const float target[3], const float up[3], float yfov_rad, float aspect)
{
    if (!b)
        return;
    const char *nm = name ? name : "(unnamed)";
    if (!gw_finite3(pos) || !gw_finite3(target) || !isfinite(aspect) ||
        !(yfov_rad > 0.0f && yfov_rad < (float)GW_PI)) {
        gw_fail(b, GI_EXIT_USAGE, "camera '%s': missing or non-finite value, or yfov outside (0, pi)",
                nm);
        return;
    }
    float fwd[3] = {target[0] - pos[0], target[1] - pos[1], target[2] - pos[2]};
    float q[4];
    if (gi_gltf_quat_look_at(fwd, up, q)) {
        gw_fail(b, GI_EXIT_USAGE, "camera '%s': target equals position", nm);
        return;
    }
    if (gw_grow((void **)&b->cams, &b->capcam, b->ncam + 1, sizeof *b->cams)) {
        gw_fail(b, GI_EXIT_SYSTEM, "camera '%s': out of memory", nm);
        return;
    }
    gw_cam *c = &b->cams[b->ncam];
    memset(c, 0, sizeof *c);
    if (name && !(c->name = gw_strdup(name))) {
        gw_fail(b, GI_EXIT_SYSTEM, "camera '%s': out of memory", nm);
        return;
    }
    memcpy(c->pos, pos, sizeof c->pos);
    memcpy(c->q, q, sizeof c->q);
    c->yfov = yfov_rad;
    c->aspect = aspect > 0.0f ? aspect : 0.0f;
    b->ncam++;
}

/* ---- text output -------------------------------------------------------- */

typedef struct gw_buf {
    char *p;
    size_t n, cap;
    int oom;
} gw_buf;

static int gw_reserve(gw_buf *o, size_t extra)
{
    if (o->oom)
        return -1;
    if (extra > SIZE_MAX - o->n - 1 ||
        gw_grow((void **)&o->p, &o->cap, o->n + extra + 1, 1)) {
        o->oom = 1;
        return -1;
    }
    return 0;
}

static void gw_put(gw_buf *o, const char *s)
{
    size_t n = strlen(s);
    if (gw_reserve(o, n))
        return;
    memcpy(o->p + o->n, s, n + 1);
    o->n += n;
}

static void gw_printf(gw_buf *o, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void gw_printf(gw_buf *o, const char *fmt, ...)
{
    char tmp[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= sizeof tmp) {
        o->oom = 1;  /* only short numeric fragments go through here */
        return;
    }
    gw_put(o, tmp);
}

/* %.9g is enough digits for any float to read back bit-exactly. */
static void gw_num(gw_buf *o, float v)
{
    if (v == 0.0f)
        v = 0.0f;  /* print -0 as 0 */
    gw_printf(o, "%.9g", (double)v);
}

static void gw_vec(gw_buf *o, const float *v, int n)
{
    gw_put(o, "[");
    for (int i = 0; i < n; i++) {
        if (i)
            gw_put(o, ",");
        gw_num(o, v[i]);
    }
    gw_put(o, "]");
}

/* JSON string: quotes, backslash and control characters escaped; other bytes
 * (UTF-8 included) copied as they are. */
static void gw_str(gw_buf *o, const char *s)
{
    gw_put(o, "\"");
    for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
        char e[8];
        switch (*c) {
        case '"': gw_put(o, "\\\""); break;
        case '\\': gw_put(o, "\\\\"); break;
        case '\n': gw_put(o, "\\n"); break;
        case '\r': gw_put(o, "\\r"); break;
        case '\t': gw_put(o, "\\t"); break;
        case '\b': gw_put(o, "\\b"); break;
        case '\f': gw_put(o, "\\f"); break;
        default:
            if (*c < 0x20) {
                snprintf(e, sizeof e, "\\u%04x", *c);
            } else {
                e[0] = (char)*c;
                e[1] = '\0';
            }
            gw_put(o, e);
        }
    }
    gw_put(o, "\"");
}

static void gw_name(gw_buf *o, const char *name)
{
    if (name) {
        gw_put(o, "\"name\":");
        gw_str(o, name);
        gw_put(o, ",");
    }
}

size_t gi_gltf_base64_encode(const unsigned char *in, size_t n, char *out)
{
    static const char tab[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t o = 0, i = 0;
    for (; i + 3 <= n; i += 3) {
        uint32_t v = (uint32_t)in[i] << 16 | (uint32_t)in[i + 1] << 8 | in[i + 2];
        out[o++] = tab[v >> 18];
        out[o++] = tab[(v >> 12) & 63];
        out[o++] = tab[(v >> 6) & 63];
        out[o++] = tab[v & 63];
    }
    if (n - i == 1) {
        uint32_t v = (uint32_t)in[i] << 16;
        out[o++] = tab[v >> 18];
        out[o++] = tab[(v >> 12) & 63];
        out[o++] = '=';
        out[o++] = '=';
    } else if (n - i == 2) {
        uint32_t v = (uint32_t)in[i] << 16 | (uint32_t)in[i + 1] << 8;
        out[o++] = tab[v >> 18];
        out[o++] = tab[(v >> 12) & 63];
        out[o++] = tab[(v >> 6) & 63];
        out[o++] = '=';
    }
    out[o] = '\0';
    return o;
}

static void gw_le32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)(v & 0xff);
    p[1] = (unsigned char)((v >> 8) & 0xff);
    p[2] = (unsigned char)((v >> 16) & 0xff);
    p[3] = (unsigned char)(v >> 24);
}

static void gw_lef(unsigned char *p, float f)
{
    uint32_t v;
    memcpy(&v, &f, sizeof v);
    gw_le32(p, v);
}

/* Build the whole document in o. Returns 0, or GI_EXIT_SYSTEM when out of memory. */
static int gw_document(const gi_gltf_builder *b, gw_buf *o)
{
    /* Binary buffer: per mesh, positions, normals, indices (all 4-byte aligned). */
    size_t nmesh = 0, bytes = 0;
    for (size_t i = 0; i < b->nmat; i++) {
        size_t nt = b->mats[i].ntri;
        if (!nt)
            continue;
        nmesh++;
        size_t per = 3 * (12 + 12 + 4);  /* per triangle: 3 vertices, pos + nrm + index */
        if (nt > (SIZE_MAX - bytes) / per / 2)
            return GI_EXIT_SYSTEM;
        bytes += nt * per;
    }
    if (bytes > UINT32_MAX)  /* byteLength fields and base64 size stay sane */
        return GI_EXIT_SYSTEM;
    unsigned char *bin = NULL;
    if (bytes) {
        bin = malloc(bytes);
        if (!bin)
            return GI_EXIT_SYSTEM;
        size_t off = 0;
        for (size_t i = 0; i < b->nmat; i++) {
            const gw_mat *m = &b->mats[i];
            if (!m->ntri)
                continue;
            size_t nv = 3 * m->ntri;
            for (size_t t = 0; t < m->ntri; t++)
                for (int c = 0; c < 3; c++)
                    for (int k = 0; k < 3; k++)
                        gw_lef(bin + off + ((3 * t + c) * 3 + k) * 4,
                               m->tri[t * GW_TRI_FLOATS + 3 * c + k]);
            off += nv * 12;
            for (size_t t = 0; t < m->ntri; t++)
                for (int c = 0; c < 3; c++)
                    for (int k = 0; k < 3; k++)
                        gw_lef(bin + off + ((3 * t + c) * 3 + k) * 4,
                               m->tri[t * GW_TRI_FLOATS + 9 + k]);
            off += nv * 12;
            for (size_t v = 0; v < nv; v++)
                gw_le32(bin + off + v * 4, (uint32_t)v);
            off += nv * 4;
        }
    }

    int any_emis = 0;
    for (size_t i = 0; i < b->nmat; i++)
        any_emis |= b->mats[i].has_emis;

    gw_put(o, "{\n\"asset\":{\"version\":\"2.0\",\"generator\":\"gi gi_gltf_write\"},\n");
    if (b->nlight || any_emis) {
        gw_put(o, "\"extensionsUsed\":[");
        if (b->nlight)
            gw_put(o, any_emis ? "\"KHR_lights_punctual\"," : "\"KHR_lights_punctual\"");
        if (any_emis)
            gw_put(o, "\"KHR_materials_emissive_strength\"");
        gw_put(o, "],\n");
    }
    if (b->nlight) {
        gw_put(o, "\"extensions\":{\"KHR_lights_punctual\":{\"lights\":[\n");
        for (size_t i = 0; i < b->nlight; i++) {
            const gw_light *l = &b->lights[i];
            static const char *const type[] = {"point", "spot", "directional"};
            gw_put(o, "{");
            gw_name(o, l->name);
            gw_printf(o, "\"type\":\"%s\",\"color\":", type[l->type]);
            gw_vec(o, l->color, 3);
            gw_put(o, ",\"intensity\":");
            gw_num(o, l->intensity);
            if (l->type == GW_SPOT) {
                gw_put(o, ",\"spot\":{\"innerConeAngle\":");
                gw_num(o, l->inner);
                gw_put(o, ",\"outerConeAngle\":");
                gw_num(o, l->outer);
                gw_put(o, "}");
            }
            gw_put(o, i + 1 < b->nlight ? "},\n" : "}\n");
        }
        gw_put(o, "]}},\n");
    }

    size_t nnode = nmesh + b->nlight + b->ncam;
    /* glTF forbids empty arrays: a scene without nodes has no "nodes" key. */
    gw_put(o, "\"scene\":0,\n\"scenes\":[{");
    if (nnode) {
        gw_put(o, "\"nodes\":[");
        for (size_t i = 0; i < nnode; i++)
            gw_printf(o, i ? ",%zu" : "%zu", i);
        gw_put(o, "]");
    }
    gw_put(o, "}]");

    /* Nodes: meshes first, then lights, then cameras. */
    if (nnode) {
        gw_put(o, ",\n\"nodes\":[\n");
        size_t k = 0, mesh = 0;
        for (size_t i = 0; i < b->nmat; i++) {
            if (!b->mats[i].ntri)
                continue;
            gw_put(o, "{");
            gw_name(o, b->mats[i].name);
            gw_printf(o, "\"mesh\":%zu", mesh++);
            gw_put(o, ++k < nnode ? "},\n" : "}\n");
        }
        for (size_t i = 0; i < b->nlight; i++) {
            const gw_light *l = &b->lights[i];
            gw_put(o, "{");
            gw_name(o, l->name);
            if (l->type != GW_DIRECTIONAL) {
                gw_put(o, "\"translation\":");
                gw_vec(o, l->pos, 3);
                gw_put(o, ",");
            }
            if (l->type != GW_POINT) {
                gw_put(o, "\"rotation\":");
                gw_vec(o, l->q, 4);
                gw_put(o, ",");
            }
            gw_printf(o, "\"extensions\":{\"KHR_lights_punctual\":{\"light\":%zu}}", i);
            gw_put(o, ++k < nnode ? "},\n" : "}\n");
        }
        for (size_t i = 0; i < b->ncam; i++) {
            const gw_cam *c = &b->cams[i];
            gw_put(o, "{");
            gw_name(o, c->name);
            gw_put(o, "\"translation\":");
            gw_vec(o, c->pos, 3);
            gw_put(o, ",\"rotation\":");
            gw_vec(o, c->q, 4);
            gw_printf(o, ",\"camera\":%zu", i);
            gw_put(o, ++k < nnode ? "},\n" : "}\n");
        }
        gw_put(o, "]");
    }

    if (nmesh) {
        gw_put(o, ",\n\"meshes\":[\n");
        size_t mesh = 0;
        for (size_t i = 0; i < b->nmat; i++) {
            if (!b->mats[i].ntri)
                continue;
            size_t a = 3 * mesh;  /* accessors: position, normal, indices */
            gw_put(o, "{");
            gw_name(o, b->mats[i].name);
            gw_printf(o, "\"primitives\":[{\"attributes\":{\"POSITION\":%zu,\"NORMAL\":%zu},"
                         "\"indices\":%zu,\"material\":%zu,\"mode\":4}]",
                      a, a + 1, a + 2, i);
            gw_put(o, ++mesh < nmesh ? "},\n" : "}\n");
        }
        gw_put(o, "]");
    }

    if (b->nmat) {
        gw_put(o, ",\n\"materials\":[\n");
        for (size_t i = 0; i < b->nmat; i++) {
            const gw_mat *m = &b->mats[i];
            float bc[4] = {m->base[0], m->base[1], m->base[2], 1.0f};
            gw_put(o, "{");
            gw_name(o, m->name);
            gw_put(o, "\"pbrMetallicRoughness\":{\"baseColorFactor\":");
            gw_vec(o, bc, 4);
            gw_put(o, ",\"metallicFactor\":");
            gw_num(o, m->metal);
            gw_put(o, ",\"roughnessFactor\":");
            gw_num(o, m->rough);
            gw_put(o, "}");
            if (m->has_emis) {
                float mx = fmaxf(m->emis[0], fmaxf(m->emis[1], m->emis[2]));
                float ef[3] = {m->emis[0] / mx, m->emis[1] / mx, m->emis[2] / mx};
                gw_put(o, ",\"emissiveFactor\":");
                gw_vec(o, ef, 3);
                gw_put(o, ",\"extensions\":{\"KHR_materials_emissive_strength\":"
                          "{\"emissiveStrength\":");
                gw_num(o, mx);
                gw_put(o, "}}");
            }
            gw_put(o, m->double_sided ? ",\"doubleSided\":true" : ",\"doubleSided\":false");
            gw_put(o, i + 1 < b->nmat ? "},\n" : "}\n");
        }
        gw_put(o, "]");
    }

    if (b->ncam) {
        gw_put(o, ",\n\"cameras\":[\n");
        for (size_t i = 0; i < b->ncam; i++) {
            const gw_cam *c = &b->cams[i];
            gw_put(o, "{");
            gw_name(o, c->name);
            gw_put(o, "\"type\":\"perspective\",\"perspective\":{");
            if (c->aspect > 0.0f) {
                gw_put(o, "\"aspectRatio\":");
                gw_num(o, c->aspect);
                gw_put(o, ",");
            }
            gw_put(o, "\"yfov\":");
            gw_num(o, c->yfov);
            gw_put(o, ",\"znear\":");
            gw_num(o, 0.01f);
            gw_put(o, "}");
            gw_put(o, i + 1 < b->ncam ? "},\n" : "}\n");
        }
        gw_put(o, "]");
    }

    if (nmesh) {
        gw_put(o, ",\n\"accessors\":[\n");
        size_t mesh = 0;
        for (size_t i = 0; i < b->nmat; i++) {
            const gw_mat *m = &b->mats[i];
            if (!m->ntri)
                continue;
            size_t nv = 3 * m->ntri;
            float lo[3], hi[3];
            for (int k = 0; k < 3; k++)
                lo[k] = hi[k] = m->tri[k];
            for (size_t t = 0; t < m->ntri; t++)
                for (int c = 0; c < 3; c++)
                    for (int k = 0; k < 3; k++) {
                        float v = m->tri[t * GW_TRI_FLOATS + 3 * c + k];
                        lo[k] = fminf(lo[k], v);
                        hi[k] = fmaxf(hi[k], v);
                    }
            size_t bv = 3 * mesh;
            gw_printf(o, "{\"bufferView\":%zu,\"componentType\":5126,\"count\":%zu,"
                         "\"type\":\"VEC3\",\"min\":", bv, nv);
            gw_vec(o, lo, 3);
            gw_put(o, ",\"max\":");
            gw_vec(o, hi, 3);
            gw_put(o, "},\n");
            gw_printf(o, "{\"bufferView\":%zu,\"componentType\":5126,\"count\":%zu,"
                         "\"type\":\"VEC3\"},\n", bv + 1, nv);
            gw_printf(o, "{\"bufferView\":%zu,\"componentType\":5125,\"count\":%zu,"
                         "\"type\":\"SCALAR\"}", bv + 2, nv);
            gw_put(o, ++mesh < nmesh ? ",\n" : "\n");
        }
        gw_put(o, "]");

        gw_put(o, ",\n\"bufferViews\":[\n");
        size_t off = 0;
        mesh = 0;
        for (size_t i = 0; i < b->nmat; i++) {
            const gw_mat *m = &b->mats[i];
            if (!m->ntri)
                continue;
            size_t nv = 3 * m->ntri;
            gw_printf(o, "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34962},\n",
                      off, nv * 12);
            off += nv * 12;
            gw_printf(o, "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34962},\n",
                      off, nv * 12);
            off += nv * 12;
            gw_printf(o, "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34963}",
                      off, nv * 4);
            off += nv * 4;
            gw_put(o, ++mesh < nmesh ? ",\n" : "\n");
        }
        gw_put(o, "]");

        gw_printf(o, ",\n\"buffers\":[{\"byteLength\":%zu,\"uri\":\"", bytes);
        gw_put(o, "data:application/octet-stream;base64,");
        size_t enc = 4 * ((bytes + 2) / 3);
        if (gw_reserve(o, enc) == 0)
            o->n += gi_gltf_base64_encode(bin, bytes, o->p + o->n);
        gw_put(o, "\"}]");
    }
    gw_put(o, "\n}\n");
    free(bin);
    return o->oom ? GI_EXIT_SYSTEM : 0;
}

/* ---- file output ---------------------------------------------------------- */

int gi_gltf_builder_write(gi_gltf_builder *b, const char *path, gi_status *st)
{
    if (!b || !path || !*path)
        return gi_status_set(st, GI_EXIT_USAGE, "gltf write: no builder or no output path");
    if (b->err_code)
        return gi_status_set(st, b->err_code, "%s: %s", path, b->err);

    gw_buf o = {0};
    if (gw_document(b, &o)) {
        free(o.p);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory building the document", path);
    }

    size_t tlen = strlen(path) + 32;
    char *tmp = malloc(tlen);
    if (!tmp) {
        free(o.p);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
    }
    snprintf(tmp, tlen, "%s.tmp.%ld", path, (long)getpid());

    int rc = 0;
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create temporary file '%s'", path, tmp);
        free(tmp);
        free(o.p);
        return rc;
    }
    if (fwrite(o.p, 1, o.n, f) != o.n)
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot write", tmp);
    else if (fflush(f) != 0)
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot write", tmp);
    else if (fsync(fileno(f)) != 0 && errno != EINVAL)  /* EINVAL: file system without fsync */
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot sync", tmp);
    if (fclose(f) != 0 && rc == 0)
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot close", tmp);
    if (rc == 0 && rename(tmp, path) != 0)
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot rename '%s' to it", path, tmp);
    if (rc != 0)
        unlink(tmp);
    free(tmp);
    free(o.p);
    return rc;
}
