/* gi_scene.c - the C side of a loaded scene: release, bounds/area/hash,
 * warnings, lookups, base-colour texture sampling and the JSON summary. The
 * glTF reading itself is in shim/gi_gltf_tiny.cpp. */
#include "gi_scene.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gi_math.h"

void gi_scene_free(gi_scene *s)
{
    if (!s)
        return;
    free(s->positions);
    free(s->normals);
    free(s->uv0);
    free(s->uv1);
    free(s->indices);
    free(s->tri_material);
    free(s->materials);
    for (size_t i = 0; i < s->num_textures; i++)
        free(s->textures[i].rgba);
    free(s->textures);
    free(s->lights);
    free(s->cameras);
    for (size_t i = 0; i < s->num_warnings; i++)
        free(s->warnings[i]);
    free(s->warnings);
    free(s);
}

void gi_scene_warn(gi_scene *s, const char *fmt, ...)
{
    if (!s)
        return;
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    char **w = realloc(s->warnings, (s->num_warnings + 1) * sizeof *w);
    if (!w)
        return; /* out of memory: a warning is the one thing we may lose */
    s->warnings = w;
    size_t n = strlen(buf) + 1;
    char *copy = malloc(n);
    if (!copy)
        return;
    memcpy(copy, buf, n);
    s->warnings[s->num_warnings++] = copy;
}

/* ---- geometry summaries ---------------------------------------------------- */

int gi_scene_triangle_degenerate(const gi_scene *s, size_t t)
{
    const uint32_t *ix = s->indices + 3 * t;
    const float *a = s->positions + 3 * (size_t)ix[0];
    const float *b = s->positions + 3 * (size_t)ix[1];
    const float *c = s->positions + 3 * (size_t)ix[2];
    double e1[3], e2[3], e3[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = (double)b[k] - a[k];
        e2[k] = (double)c[k] - a[k];
        e3[k] = (double)c[k] - b[k];
    }
    double cx = e1[1] * e2[2] - e1[2] * e2[1];
    double cy = e1[2] * e2[0] - e1[0] * e2[2];
    double cz = e1[0] * e2[1] - e1[1] * e2[0];
    double cross = sqrt(cx * cx + cy * cy + cz * cz);
    double l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    double l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    double l3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
    double lmax = fmax(l1, fmax(l2, l3));
    if (!isfinite(cross) || !isfinite(lmax))
        return 1;
    return !(cross > 1e-10 * lmax);
}

/* 64-bit FNV-1a over little-endian bytes: simple, stable across platforms. */
#define FNV_OFFSET 0xcbf29ce484222325ull
#define FNV_PRIME 0x100000001b3ull

static uint64_t fnv_u32(uint64_t h, uint32_t v)
{
    for (int i = 0; i < 4; i++) {
        h ^= (v >> (8 * i)) & 0xffu;
        h *= FNV_PRIME;
    }
    return h;
}

static uint64_t fnv_u64(uint64_t h, uint64_t v)
{
    h = fnv_u32(h, (uint32_t)v);
    return fnv_u32(h, (uint32_t)(v >> 32));
}

static uint64_t fnv_floats(uint64_t h, const float *p, size_t n)
{
    if (!p) {
        for (size_t i = 0; i < n; i++)
            h = fnv_u32(h, 0);
        return h;
    }
    for (size_t i = 0; i < n; i++) {
        uint32_t bits;
        memcpy(&bits, &p[i], 4);
        h = fnv_u32(h, bits);
    }
    return h;
}

uint64_t gi_scene_fingerprint(const gi_scene *s)
{
    uint64_t h = FNV_OFFSET;
    h = fnv_u64(h, (uint64_t)s->num_vertices);
    h = fnv_floats(h, s->positions, 3 * s->num_vertices);
    h = fnv_floats(h, s->uv0, 2 * s->num_vertices);
    h = fnv_floats(h, s->uv1, 2 * s->num_vertices);
    h = fnv_u64(h, (uint64_t)s->num_triangles);
    for (size_t i = 0; i < 3 * s->num_triangles; i++)
        h = fnv_u32(h, s->indices[i]);
    for (size_t i = 0; i < s->num_triangles; i++)
        h = fnv_u32(h, s->tri_material ? s->tri_material[i] : 0);
    return h;
}

void gi_scene_finalize(gi_scene *s)
{
    if (!s)
        return;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    gi_ksum area = {0.0, 0.0};
    size_t degenerate = 0;
    for (size_t t = 0; t < s->num_triangles; t++) {
        const uint32_t *ix = s->indices + 3 * t;
        for (int j = 0; j < 3; j++) {
            const float *p = s->positions + 3 * (size_t)ix[j];
            for (int k = 0; k < 3; k++) {
                lo[k] = fminf(lo[k], p[k]);
                hi[k] = fmaxf(hi[k], p[k]);
            }
        }
        const float *a = s->positions + 3 * (size_t)ix[0];
        const float *b = s->positions + 3 * (size_t)ix[1];
        const float *c = s->positions + 3 * (size_t)ix[2];
        double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
        double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
        double cx = e1[1] * e2[2] - e1[2] * e2[1];
        double cy = e1[2] * e2[0] - e1[0] * e2[2];
        double cz = e1[0] * e2[1] - e1[1] * e2[0];
        double ar = 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
        if (isfinite(ar))
            gi_ksum_add(&area, ar);
        degenerate += (size_t)gi_scene_triangle_degenerate(s, t);
    }
    for (int k = 0; k < 3; k++) {
        s->bbox_min[k] = s->num_triangles ? lo[k] : 0.0f;
        s->bbox_max[k] = s->num_triangles ? hi[k] : 0.0f;
    }
    s->surface_area = gi_ksum_get(&area);
    s->num_degenerate = degenerate;
    s->hash = gi_scene_fingerprint(s);
}

/* ---- lookups --------------------------------------------------------------- */

int gi_scene_find_material(const gi_scene *s, const char *name)
{
    for (size_t i = 0; s && name && i < s->num_materials; i++)
        if (strcmp(s->materials[i].name, name) == 0)
            return (int)i;
    return -1;
}

int gi_scene_find_light(const gi_scene *s, const char *name)
{
    for (size_t i = 0; s && name && i < s->num_lights; i++)
        if (strcmp(s->lights[i].name, name) == 0)
            return (int)i;
    return -1;
}

/* ---- texture sampling ------------------------------------------------------ */

static inline int wrap_index(int i, int n, int mode)
{
    switch (mode) {
    case GI_WRAP_CLAMP:
        return i < 0 ? 0 : (i >= n ? n - 1 : i);
    case GI_WRAP_MIRROR: {
        int p = 2 * n;
        int m = i % p;
        if (m < 0)
            m += p;
        return m < n ? m : p - 1 - m;
    }
    default: {
        int m = i % n;
        return m < 0 ? m + n : m;
    }
    }
}

/* Continuous texel coordinate x (texel centres at k + 0.5 map to x = k) with
 * huge values folded into one wrap period first, so the int conversion below
 * cannot overflow. */
static inline float fold_coord(float x, int n, int mode)
{
    if (fabsf(x) < 1e8f)
        return x;
    if (!isfinite(x))
        return 0.0f;
    if (mode == GI_WRAP_CLAMP)
        return x < 0.0f ? -1.0f : (float)n;
    double period = mode == GI_WRAP_MIRROR ? 2.0 * n : (double)n;
    return (float)fmod((double)x, period);
}

void gi_texture_sample(const gi_texture *t, float u, float v, float rgba[4])
{
    if (!t || !t->rgba || t->width < 1 || t->height < 1) {
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 1.0f;
        return;
    }
    const int w = t->width, h = t->height;
    if (t->nearest) {
        float x = fold_coord(u * (float)w, w, t->wrap_s);
        float y = fold_coord(v * (float)h, h, t->wrap_t);
        int ix = wrap_index((int)floorf(x), w, t->wrap_s);
        int iy = wrap_index((int)floorf(y), h, t->wrap_t);
        const float *p = t->rgba + 4 * ((size_t)iy * (size_t)w + (size_t)ix);
        rgba[0] = p[0];
        rgba[1] = p[1];
        rgba[2] = p[2];
        rgba[3] = p[3];
        return;
    }
    float x = fold_coord(u * (float)w - 0.5f, w, t->wrap_s);
    float y = fold_coord(v * (float)h - 0.5f, h, t->wrap_t);
    float fx0 = floorf(x), fy0 = floorf(y);
    float fx = x - fx0, fy = y - fy0;
    int x0 = (int)fx0, y0 = (int)fy0;
    int xa, xb, ya, yb;
    if (x0 >= 0 && x0 + 1 < w) { /* inside: no wrapping (the common case) */
        xa = x0;
        xb = x0 + 1;
    } else {
        xa = wrap_index(x0, w, t->wrap_s);
        xb = wrap_index(x0 + 1, w, t->wrap_s);
    }
    if (y0 >= 0 && y0 + 1 < h) {
        ya = y0;
        yb = y0 + 1;
    } else {
        ya = wrap_index(y0, h, t->wrap_t);
        yb = wrap_index(y0 + 1, h, t->wrap_t);
    }
    const float *p00 = t->rgba + 4 * ((size_t)ya * (size_t)w + (size_t)xa);
    const float *p10 = t->rgba + 4 * ((size_t)ya * (size_t)w + (size_t)xb);
    const float *p01 = t->rgba + 4 * ((size_t)yb * (size_t)w + (size_t)xa);
    const float *p11 = t->rgba + 4 * ((size_t)yb * (size_t)w + (size_t)xb);
    float w00 = (1.0f - fx) * (1.0f - fy), w10 = fx * (1.0f - fy);
    float w01 = (1.0f - fx) * fy, w11 = fx * fy;
    for (int c = 0; c < 4; c++)
        rgba[c] = w00 * p00[c] + w10 * p10[c] + w01 * p01[c] + w11 * p11[c];
}

void gi_scene_base_color(const gi_scene *s, const gi_material *m, const float uv0[2],
                         const float uv1[2], float rgb[3])
{
    rgb[0] = m->base_color[0];
    rgb[1] = m->base_color[1];
    rgb[2] = m->base_color[2];
    if (m->base_color_tex < 0 || (size_t)m->base_color_tex >= s->num_textures)
        return;
    const float *uv = (m->base_color_uv == 1 && uv1) ? uv1 : uv0;
    if (!uv)
        return;
    const float *x = m->uv_xform;
    float u = x[0] * uv[0] + x[1] * uv[1] + x[2];
    float v = x[3] * uv[0] + x[4] * uv[1] + x[5];
    float texel[4];
    gi_texture_sample(&s->textures[m->base_color_tex], u, v, texel);
    rgb[0] *= texel[0];
    rgb[1] *= texel[1];
    rgb[2] *= texel[2];
}

/* ---- JSON ------------------------------------------------------------------ */

/* Length of the valid UTF-8 sequence at p (1-4), or 0 if invalid. */
static size_t utf8_len(const unsigned char *p)
{
    unsigned c = p[0];
    if (c < 0x80)
        return 1;
    size_t n;
    unsigned min;
    if ((c & 0xe0) == 0xc0) {
        n = 2;
        min = 0x80;
        c &= 0x1f;
    } else if ((c & 0xf0) == 0xe0) {
        n = 3;
        min = 0x800;
        c &= 0x0f;
    } else if ((c & 0xf8) == 0xf0) {
        n = 4;
        min = 0x10000;
        c &= 0x07;
    } else {
        return 0;
    }
    for (size_t i = 1; i < n; i++) {
        if ((p[i] & 0xc0) != 0x80)
            return 0;
        c = (c << 6) | (p[i] & 0x3f);
    }
    if (c < min || c > 0x10ffff || (c >= 0xd800 && c <= 0xdfff))
        return 0;
    return n;
}

/* A JSON string: quotes, backslashes and control characters escaped, valid
 * UTF-8 kept as is, invalid bytes replaced by U+FFFD. */
static void json_str(FILE *f, const char *str)
{
    if (!str) {
        fputs("null", f);
        return;
    }
    const unsigned char *p = (const unsigned char *)str;
    fputc('"', f);
    while (*p) {
        unsigned c = *p;
        if (c == '"' || c == '\\') {
            fputc('\\', f);
            fputc((int)c, f);
            p++;
        } else if (c < 0x20 || c == 0x7f) {
            switch (c) {
            case '\n': fputs("\\n", f); break;
            case '\r': fputs("\\r", f); break;
            case '\t': fputs("\\t", f); break;
            case '\b': fputs("\\b", f); break;
            case '\f': fputs("\\f", f); break;
            default: fprintf(f, "\\u%04x", c); break;
            }
            p++;
        } else if (c < 0x80) {
            fputc((int)c, f);
            p++;
        } else {
            size_t n = utf8_len(p);
            if (n == 0) {
                fputs("\\ufffd", f);
                p++;
            } else {
                fwrite(p, 1, n, f);
                p += n;
            }
        }
    }
    fputc('"', f);
}

static void json_num(FILE *f, double x)
{
    if (isfinite(x))
        fprintf(f, "%.9g", x);
    else
        fputs("null", f);
}

static void json_vec(FILE *f, const float *v, int n)
{
    fputc('[', f);
    for (int i = 0; i < n; i++) {
        if (i)
            fputs(", ", f);
        json_num(f, v[i]);
    }
    fputc(']', f);
}

static const char *light_type_name(int type)
{
    switch (type) {
    case GI_LIGHT_POINT: return "point";
    case GI_LIGHT_SPOT: return "spot";
    case GI_LIGHT_DIRECTIONAL: return "directional";
    case GI_LIGHT_AREA: return "area";
    case GI_LIGHT_MESH: return "mesh";
    default: return "unknown";
    }
}

void gi_scene_print_json(const gi_scene *s, void *file)
{
    FILE *f = file;
    const double deg = 180.0 / GI_PI;
    fputs("{\n  \"file\": ", f);
    json_str(f, s->path);
    fprintf(f, ",\n  \"hash\": \"%016llx\",\n", (unsigned long long)s->hash);
    fprintf(f, "  \"triangles\": %zu,\n  \"vertices\": %zu,\n  \"degenerate_triangles\": %zu,\n",
            s->num_triangles, s->num_vertices, s->num_degenerate);

    fputs("  \"materials\": [", f);
    for (size_t i = 0; i < s->num_materials; i++) {
        const gi_material *m = &s->materials[i];
        fputs(i ? ",\n    {" : "\n    {", f);
        fputs("\"name\": ", f);
        json_str(f, m->name);
        fputs(", \"base_color\": ", f);
        json_vec(f, m->base_color, 3);
        fputs(", \"base_color_texture\": ", f);
        if (m->base_color_tex >= 0 && (size_t)m->base_color_tex < s->num_textures)
            json_str(f, s->textures[m->base_color_tex].name);
        else
            fputs("null", f);
        fputs(", \"roughness\": ", f);
        json_num(f, m->roughness);
        fputs(", \"metallic\": ", f);
        json_num(f, m->metallic);
        fputs(", \"emission\": ", f);
        json_vec(f, m->emission, 3);
        fprintf(f, ", \"double_sided\": %s}", m->double_sided ? "true" : "false");
    }
    fputs(s->num_materials ? "\n  ],\n" : "],\n", f);

    fputs("  \"textures\": [", f);
    for (size_t i = 0; i < s->num_textures; i++) {
        const gi_texture *t = &s->textures[i];
        fputs(i ? ",\n    {" : "\n    {", f);
        fputs("\"name\": ", f);
        json_str(f, t->name);
        fprintf(f, ", \"width\": %d, \"height\": %d}", t->width, t->height);
    }
    fputs(s->num_textures ? "\n  ],\n" : "],\n", f);

    fputs("  \"lights\": [", f);
    for (size_t i = 0; i < s->num_lights; i++) {
        const gi_light *l = &s->lights[i];
        fputs(i ? ",\n    {" : "\n    {", f);
        fputs("\"name\": ", f);
        json_str(f, l->name);
        fputs(", \"type\": ", f);
        json_str(f, light_type_name(l->type));
        const char *key = l->type == GI_LIGHT_DIRECTIONAL ? "illuminance_lux"
                          : l->type == GI_LIGHT_AREA      ? "luminance_nits"
                                                          : "intensity_cd";
        fprintf(f, ", \"%s\": ", key);
        json_num(f, l->intensity);
        fputs(", \"color\": ", f);
        json_vec(f, l->color, 3);
        fputs(", \"position\": ", f);
        if (l->type == GI_LIGHT_DIRECTIONAL)
            fputs("null", f);
        else
            json_vec(f, l->position, 3);
        fputs(", \"direction\": ", f);
        if (l->type == GI_LIGHT_POINT)
            fputs("null", f);
        else
            json_vec(f, l->direction, 3);
        fputs(", \"inner_cone_deg\": ", f);
        if (l->type == GI_LIGHT_SPOT)
            json_num(f, l->inner_cone * deg);
        else
            fputs("null", f);
        fputs(", \"outer_cone_deg\": ", f);
        if (l->type == GI_LIGHT_SPOT)
            json_num(f, l->outer_cone * deg);
        else
            fputs("null", f);
        fputc('}', f);
    }
    fputs(s->num_lights ? "\n  ],\n" : "],\n", f);

    fputs("  \"cameras\": [", f);
    for (size_t i = 0; i < s->num_cameras; i++) {
        const gi_camera *c = &s->cameras[i];
        fputs(i ? ",\n    {" : "\n    {", f);
        fputs("\"name\": ", f);
        json_str(f, c->name);
        fputs(", \"position\": ", f);
        json_vec(f, c->position, 3);
        fputs(", \"forward\": ", f);
        json_vec(f, c->forward, 3);
        fputs(", \"up\": ", f);
        json_vec(f, c->up, 3);
        fputs(", \"yfov_deg\": ", f);
        json_num(f, c->yfov * deg);
        fputs(", \"aspect\": ", f);
        if (c->aspect > 0.0f)
            json_num(f, c->aspect);
        else
            fputs("null", f);
        fputs(", \"znear\": ", f);
        json_num(f, c->znear);
        fputs(", \"zfar\": ", f);
        if (c->zfar > 0.0f)
            json_num(f, c->zfar);
        else
            fputs("null", f);
        fputc('}', f);
    }
    fputs(s->num_cameras ? "\n  ],\n" : "],\n", f);

    fputs("  \"bbox\": {\"min\": ", f);
    json_vec(f, s->bbox_min, 3);
    fputs(", \"max\": ", f);
    json_vec(f, s->bbox_max, 3);
    fputs("},\n  \"surface_area_m2\": ", f);
    json_num(f, s->surface_area);
    fputs(",\n  \"warnings\": [", f);
    for (size_t i = 0; i < s->num_warnings; i++) {
        fputs(i ? ",\n    " : "\n    ", f);
        json_str(f, s->warnings[i]);
    }
    fputs(s->num_warnings ? "\n  ]\n}\n" : "]\n}\n", f);
}
