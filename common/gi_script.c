/* gi_script.c - variant script parser, scene check and per-frame state resolution.
 *
 * The parser turns each line into one command and keeps the commands in order.
 * Script state (resolution, camera, per-name light slot, per-name material
 * override) depends only on the script, so it is summarised as small integer
 * arrays and snapshotted every few frames; gi_script_frame replays at most a
 * block of frames from the nearest snapshot and then resolves the state
 * against the scene. Grammar and semantics: docs/script.md. */
#define _POSIX_C_SOURCE 200809L
#include "gi_script.h"

#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DEG2RAD (3.14159265358979323846 / 180.0)
#define MAX_SCRIPT_BYTES ((size_t)1 << 30)
#define SNAPSHOT_BUDGET ((size_t)1 << 22) /* ints kept in snapshots at most (16 MiB) */

enum {
    CMD_RESOLUTION,  /* a = width, b = height */
    CMD_CAMERA,      /* a = index into cams */
    CMD_CAMERA_GLTF, /* a = scene camera index */
    CMD_LIGHT,       /* a = light name id, b = index into ldefs */
    CMD_LIGHT_OFF,   /* a = light name id */
    CMD_LIGHT_ON,    /* a = light name id */
    CMD_MATERIAL,    /* a = material name id, b = index into mrecs (accumulated) */
    CMD_FRAME        /* a = frame index */
};

typedef struct cmd {
    int kind;
    int line, col; /* of the token a scene check blames (name, camera index) */
    int a, b;
} cmd;

enum { M_BASECOLOR = 1, M_ROUGHNESS = 2, M_METALLIC = 4, M_EMISSION = 8 };

/* Material overrides accumulated over all earlier commands for one name. */
typedef struct mrec {
    unsigned mask; /* M_* */
    float base_color[3], roughness, metallic, emission[3];
} mrec;

/* Names to dense ids, with an open-addressing hash index. */
typedef struct names {
    char (*v)[GI_NAME_MAX];
    int *first; /* command that first named it */
    size_t n, cap;
    int *slot; /* -1 empty; power-of-two size */
    size_t nslot;
} names;

/* Script-only state of one light name. */
typedef struct lslot {
    int def;    /* index into ldefs, -1 if the script never defined it */
    int en;     /* -1 as defined or loaded, 0 switched off, 1 switched on */
    int en_cmd; /* command of the last on/off */
} lslot;

/* Script-only state at one frame. */
typedef struct sstate {
    int w, h;
    int cam_kind; /* 0 none, 1 script camera, 2 scene camera */
    int cam, cam_cmd;
    lslot *l; /* lights.n */
    int *m;   /* mats.n: index into mrecs or -1 */
} sstate;

struct gi_script {
    char *name;
    cmd *cmds;
    size_t ncmds, capcmds;
    gi_camera *cams;
    size_t ncams, capcams;
    gi_light *ldefs;
    size_t nldefs, capldefs;
    mrec *mrecs;
    size_t nmrecs, capmrecs;
    names lights, mats, frames; /* frames.first[i] = the frame's command */
    /* snapshots of sstate every `every` frames (snapshot j = state at frame j*every) */
    size_t every, nsnap;
    int *snap_hdr;   /* 5 ints per snapshot */
    lslot *snap_l;   /* lights.n per snapshot */
    int *snap_m;     /* mats.n per snapshot */
};

/* ---- small helpers ---------------------------------------------------------- */

/* Make room for `need` elements in the array whose pointer is at `pp` (any
 * object pointer type; read and written with memcpy, so no aliasing through
 * void **). Doubles the capacity; the old array is kept on failure. */
static int grow(void *pp, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    size_t c = *cap ? *cap : 16;
    while (c < need) {
        if (c > SIZE_MAX / 2 / elem)
            return -1;
        c *= 2;
    }
    void *old;
    memcpy(&old, pp, sizeof old);
    void *q = realloc(old, c * elem);
    if (!q)
        return -1;
    memcpy(pp, &q, sizeof q);
    *cap = c;
    return 0;
}

/* calloc that never returns NULL for n == 0 on success. */
static void *zalloc(size_t n, size_t elem) { return calloc(n ? n : 1, elem); }

static uint64_t hash_str(const char *s)
{
    uint64_t h = 1469598103934665603ull;
    for (; *s; s++) {
        h ^= (unsigned char)*s;
        h *= 1099511628211ull;
    }
    return h;
}

static int names_find(const names *t, const char *s)
{
    if (!t->nslot)
        return -1;
    size_t mask = t->nslot - 1;
    for (size_t k = (size_t)hash_str(s) & mask;; k = (k + 1) & mask) {
        int id = t->slot[k];
        if (id < 0)
            return -1;
        if (strcmp(t->v[id], s) == 0)
            return id;
    }
}

static int names_rehash(names *t, size_t nslot)
{
    int *slot = malloc(nslot * sizeof *slot);
    if (!slot)
        return -1;
    for (size_t k = 0; k < nslot; k++)
        slot[k] = -1;
    for (size_t id = 0; id < t->n; id++) {
        size_t k = (size_t)hash_str(t->v[id]) & (nslot - 1);
        while (slot[k] >= 0)
            k = (k + 1) & (nslot - 1);
        slot[k] = (int)id;
    }
    free(t->slot);
    t->slot = slot;
    t->nslot = nslot;
    return 0;
}

/* Add a name known to be absent; returns its id or -1 when out of memory. */
static int names_add(names *t, const char *s, int first)
{
    if (t->n >= (size_t)INT_MAX)
        return -1;
    if (t->n + 1 > t->cap) {
        size_t cap = t->cap;
        if (grow(&t->v, &cap, t->n + 1, sizeof *t->v))
            return -1;
        size_t cap2 = t->cap;
        if (grow(&t->first, &cap2, t->n + 1, sizeof *t->first))
            return -1;
        t->cap = cap < cap2 ? cap : cap2;
    }
    if ((t->n + 1) * 2 > t->nslot && names_rehash(t, t->nslot ? t->nslot * 2 : 64))
        return -1;
    snprintf(t->v[t->n], GI_NAME_MAX, "%s", s);
    t->first[t->n] = first;
    size_t k = (size_t)hash_str(s) & (t->nslot - 1);
    while (t->slot[k] >= 0)
        k = (k + 1) & (t->nslot - 1);
    t->slot[k] = (int)t->n;
    return (int)t->n++;
}

static void names_free(names *t)
{
    free(t->v);
    free(t->first);
    free(t->slot);
    memset(t, 0, sizeof *t);
}

/* Quote text for a message: at most 32 bytes, control bytes shown as '?'. */
static const char *quoted(const char *s, size_t len, char out[48])
{
    size_t n = len > 32 ? 32 : len, o = 0;
    out[o++] = '\'';
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)s[i];
        out[o++] = (c < 0x20 || c == 0x7f) ? '?' : (char)c;
    }
    if (n < len) {
        memcpy(out + o, "...", 3);
        o += 3;
    }
    out[o++] = '\'';
    out[o] = '\0';
    return out;
}

static double len3d(const double v[3]) { return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

static void cross3d(const double a[3], const double b[3], double r[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

static void store_unit(float out[3], const double v[3])
{
    double l = len3d(v);
    for (int k = 0; k < 3; k++)
        out[k] = (float)(v[k] / l);
}

/* ---- tokenizer and error reporting ---------------------------------------- */

typedef struct tok {
    const char *text; /* unescaped, NUL-terminated */
    const char *raw;  /* as written, for messages */
    size_t rawlen;
    int col;          /* 1-based byte column */
    int quoted;
} tok;

typedef struct parser {
    gi_script *s;
    gi_status *st;
    const char *name;
    int line;
    tok *t;
    size_t nt, capt;
    char *buf;
    size_t capbuf;
    int *mlast; /* per material id: last accumulated record, -1 none */
    size_t capmlast;
} parser;

static int perr(parser *p, int col, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static int perr(parser *p, int col, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return gi_status_set(p->st, GI_EXIT_DATA, "%s:%d:%d: %s", p->name, p->line, col, msg);
}

static int oom(gi_status *st) { return gi_status_set(st, GI_EXIT_SYSTEM, "out of memory"); }

/* Column of token i, or just after the last token when i is past the end. */
static int colat(const parser *p, size_t i)
{
    if (i < p->nt)
        return p->t[i].col;
    if (p->nt == 0)
        return 1;
    return p->t[p->nt - 1].col + (int)p->t[p->nt - 1].rawlen;
}

/* "'token'" or "end of line" for messages. */
static const char *got(const parser *p, size_t i, char out[48])
{
    if (i >= p->nt) {
        snprintf(out, 48, "end of line");
        return out;
    }
    return quoted(p->t[i].raw, p->t[i].rawlen, out);
}

static int is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/* Split one line [ls, le) into tokens. */
static int tokenize(parser *p, const char *ls, const char *le)
{
    size_t len = (size_t)(le - ls);
    if (grow(&p->buf, &p->capbuf, 2 * len + 1, 1))
        return oom(p->st);
    p->nt = 0;
    char *o = p->buf;
    const char *c = ls;
    while (c < le) {
        if (is_space(*c)) {
            c++;
            continue;
        }
        if (*c == '#')
            break;
        if (grow(&p->t, &p->capt, p->nt + 1, sizeof *p->t))
            return oom(p->st);
        tok *t = &p->t[p->nt];
        t->raw = c;
        t->col = (int)(c - ls) + 1;
        t->text = o;
        t->quoted = (*c == '"');
        if (t->quoted) {
            c++;
            while (c < le && *c != '"') {
                if (*c == '\\' && c + 1 < le && (c[1] == '"' || c[1] == '\\'))
                    c++;
                if (*c == '\0')
                    return perr(p, (int)(c - ls) + 1, "expected text, got a NUL byte");
                *o++ = *c++;
            }
            if (c >= le)
                return perr(p, t->col, "expected a closing '\"' before the end of the line");
            c++;
            if (c < le && !is_space(*c) && *c != '#') {
                char g[48];
                return perr(p, (int)(c - ls) + 1, "expected a space after the closing '\"', got %s",
                            quoted(c, 1, g));
            }
        } else {
            while (c < le && !is_space(*c) && *c != '#') {
                if (*c == '\0')
                    return perr(p, (int)(c - ls) + 1, "expected text, got a NUL byte");
                *o++ = *c++;
            }
        }
        *o++ = '\0';
        t->rawlen = (size_t)(c - t->raw);
        p->nt++;
    }
    return 0;
}

static int is_kw(const tok *t, const char *kw) { return !t->quoted && strcmp(t->text, kw) == 0; }

static int expect_eol(parser *p, size_t i)
{
    char g[48];
    if (i < p->nt)
        return perr(p, p->t[i].col, "expected end of line, got %s", got(p, i, g));
    return 0;
}

/* Numbers: strtod with full consumption, finite and representable as float.
 * Reads `count` numbers from tokens i.. after keyword `after`. */
static int numbers_at(parser *p, size_t i, const char *after, int count, double *out)
{
    char g[48];
    for (int k = 0; k < count; k++) {
        size_t j = i + (size_t)k;
        const char *what = count == 1 ? "a number" : "3 numbers";
        if (j >= p->nt)
            return perr(p, colat(p, j), "expected %s after '%s', got %s", what, after, got(p, j, g));
        const tok *t = &p->t[j];
        char *end = NULL;
        double v = 0.0;
        if (!t->quoted) {
            errno = 0;
            v = strtod(t->text, &end);
        }
        if (t->quoted || end == t->text || *end != '\0' || is_space(t->text[0]))
            return perr(p, t->col, "expected %s after '%s', got %s", what, after, got(p, j, g));
        if (!isfinite(v) || fabs(v) > FLT_MAX)
            return perr(p, t->col, "expected a finite number after '%s', got %s", after, got(p, j, g));
        out[k] = (double)(float)v; /* values are stored as float: check what is stored */
    }
    return 0;
}

/* Decimal integer in [lo, hi]; `what` names it ("a width"). */
static int int_at(parser *p, size_t i, const char *what, const char *after, long lo, long hi,
                  long *out)
{
    char g[48];
    int ok = 0;
    long v = 0;
    if (i < p->nt && !p->t[i].quoted) {
        const char *s = p->t[i].text;
        char *end = NULL;
        errno = 0;
        v = strtol(s, &end, 10);
        ok = end != s && *end == '\0' && errno == 0 && !is_space(s[0]) && v >= lo && v <= hi;
    }
    if (!ok)
        return perr(p, colat(p, i), "expected %s (an integer in %ld..%ld) after '%s', got %s", what,
                    lo, hi, after, got(p, i, g));
    *out = v;
    return 0;
}

/* A light, material or frame name: non-empty, at most GI_NAME_MAX-1 bytes. */
static int name_at(parser *p, size_t i, const char *what, const char *after)
{
    char g[48];
    if (i >= p->nt || p->t[i].text[0] == '\0')
        return perr(p, colat(p, i), "expected %s after '%s', got %s", what, after, got(p, i, g));
    if (strlen(p->t[i].text) >= GI_NAME_MAX)
        return perr(p, p->t[i].col, "expected %s of at most %d bytes, got %s", what, GI_NAME_MAX - 1,
                    got(p, i, g));
    return 0;
}

/* Value checks applied per number as it is read. */
enum { CK_ANY, CK_NONNEG, CK_UNIT01, CK_NONZERO3, CK_INNER, CK_OUTER, CK_FOV, CK_POSITIVE, CK_STRENGTH };

static int check_values(parser *p, size_t i, const char *kw, int n, int ck, const double *v)
{
    char g[48];
    for (int k = 0; k < n; k++) {
        const char *bad = NULL;
        double x = v[k];
        switch (ck) {
        case CK_NONNEG: bad = x < 0 ? ">= 0" : NULL; break;
        case CK_UNIT01: bad = (x < 0 || x > 1) ? "in 0..1" : NULL; break;
        case CK_INNER: bad = (x < 0 || x > 90) ? "in 0..90 degrees" : NULL; break;
        case CK_OUTER: bad = (x <= 0 || x > 90) ? "greater than 0 and at most 90 degrees" : NULL; break;
        case CK_FOV: bad = (x <= 0 || x >= 180) ? "between 0 and 180 degrees" : NULL; break;
        case CK_POSITIVE: bad = x <= 0 ? "> 0" : NULL; break;
        case CK_STRENGTH:
            bad = x < 0 ? ">= 0" : (x > GI_SCENE_MAX_STRENGTH ? "at most 1e15 (beyond the range of the images' floats)" : NULL);
            break;
        default: break;
        }
        if (bad)
            return perr(p, p->t[i + 1 + (size_t)k].col, "expected '%s' %s, got %s", kw, bad,
                        got(p, i + 1 + (size_t)k, g));
    }
    if (ck == CK_NONZERO3 && len3d(v) == 0.0)
        return perr(p, p->t[i + 1].col, "expected a nonzero vector after '%s', got %s %s %s", kw,
                    p->t[i + 1].text, p->t[i + 2].text, p->t[i + 3].text);
    return 0;
}

/* A keyword with its numbers, as read by read_props. */
typedef struct prop {
    const char *kw;
    int n;  /* 1 or 3 numbers */
    int ck; /* CK_* */
} prop;

typedef struct propvals {
    unsigned seen;
    double v[16][3];
    size_t at[16]; /* token index of the keyword */
} propvals;

/* Read "kw numbers kw numbers ..." from token i to the end of the line.
 * `allowed` masks props; `what`/`list` describe them for messages. */
static int read_props(parser *p, size_t i, const prop *props, int nprops, unsigned allowed,
                      const char *what, const char *list, propvals *pv)
{
    char g[48];
    memset(pv, 0, sizeof *pv);
    while (i < p->nt) {
        int k = -1;
        for (int j = 0; j < nprops; j++)
            if ((allowed >> j & 1u) && is_kw(&p->t[i], props[j].kw))
                k = j;
        if (k < 0)
            return perr(p, p->t[i].col, "expected %s (%s), got %s", what, list, got(p, i, g));
        if (pv->seen >> k & 1u)
            return perr(p, p->t[i].col, "expected '%s' only once, got it again", props[k].kw);
        int rc = numbers_at(p, i + 1, props[k].kw, props[k].n, pv->v[k]);
        if (!rc)
            rc = check_values(p, i, props[k].kw, props[k].n, props[k].ck, pv->v[k]);
        if (rc)
            return rc;
        pv->seen |= 1u << k;
        pv->at[k] = i;
        i += 1 + (size_t)props[k].n;
    }
    return 0;
}

static int add_cmd(parser *p, int kind, int col, int a, int b)
{
    gi_script *s = p->s;
    if (s->ncmds >= (size_t)INT_MAX || grow(&s->cmds, &s->capcmds, s->ncmds + 1, sizeof *s->cmds))
        return oom(p->st);
    cmd *c = &s->cmds[s->ncmds++];
    c->kind = kind;
    c->line = p->line;
    c->col = col;
    c->a = a;
    c->b = b;
    return 0;
}

/* ---- commands ----------------------------------------------------------------- */

static int parse_resolution(parser *p)
{
    long w, h;
    int rc = int_at(p, 1, "a width", "resolution", 1, GI_SCRIPT_MAX_RESOLUTION, &w);
    if (!rc)
        rc = int_at(p, 2, "a height", "resolution", 1, GI_SCRIPT_MAX_RESOLUTION, &h);
    if (!rc)
        rc = expect_eol(p, 3);
    if (!rc)
        rc = add_cmd(p, CMD_RESOLUTION, p->t[0].col, (int)w, (int)h);
    return rc;
}

enum { C_POSITION, C_TARGET, C_DIRECTION, C_UP, C_FOV, C_NEAR, C_FAR, C_N };
static const prop camera_props[C_N] = {
    {"position", 3, CK_ANY}, {"target", 3, CK_ANY}, {"direction", 3, CK_NONZERO3},
    {"up", 3, CK_NONZERO3},  {"fov", 1, CK_FOV},     {"near", 1, CK_POSITIVE},
    {"far", 1, CK_NONNEG},
};
#define CAMERA_LIST "position, target, direction, up, fov, near, far"

static int parse_camera(parser *p)
{
    gi_script *s = p->s;
    if (p->nt >= 2 && is_kw(&p->t[1], "gltf")) {
        long idx;
        int rc = int_at(p, 2, "a camera index", "gltf", 0, INT_MAX, &idx);
        if (!rc)
            rc = expect_eol(p, 3);
        if (!rc)
            rc = add_cmd(p, CMD_CAMERA_GLTF, p->t[2].col, (int)idx, 0);
        return rc;
    }
    char g[48];
    if (p->nt < 2)
        return perr(p, colat(p, 1), "expected 'gltf' or camera properties (" CAMERA_LIST "), got %s",
                    got(p, 1, g));
    propvals pv;
    int rc = read_props(p, 1, camera_props, C_N, (1u << C_N) - 1,
                        "'gltf' or a camera property", CAMERA_LIST, &pv);
    if (rc)
        return rc;
    if (!(pv.seen >> C_POSITION & 1u))
        return perr(p, p->t[0].col, "expected 'position' for the camera");
    int has_t = pv.seen >> C_TARGET & 1u, has_d = pv.seen >> C_DIRECTION & 1u;
    if (!has_t && !has_d)
        return perr(p, p->t[0].col, "expected 'target' or 'direction' for the camera");
    if (has_t && has_d) {
        size_t later = pv.at[C_TARGET] > pv.at[C_DIRECTION] ? pv.at[C_TARGET] : pv.at[C_DIRECTION];
        return perr(p, p->t[later].col, "expected either 'target' or 'direction', not both");
    }
    double fwd[3], up[3] = {0, 1, 0}, right[3], up2[3];
    for (int k = 0; k < 3; k++)
        fwd[k] = has_t ? pv.v[C_TARGET][k] - pv.v[C_POSITION][k] : pv.v[C_DIRECTION][k];
    if (len3d(fwd) == 0.0)
        return perr(p, p->t[pv.at[C_TARGET] + 1].col, "expected a 'target' different from 'position'");
    double lf = len3d(fwd);
    for (int k = 0; k < 3; k++)
        fwd[k] /= lf;
    if (pv.seen >> C_UP & 1u) {
        double lu = len3d(pv.v[C_UP]);
        for (int k = 0; k < 3; k++)
            up[k] = pv.v[C_UP][k] / lu;
    }
    cross3d(fwd, up, right);
    double lr = len3d(right);
    if (!(lr > 1e-6)) {
        size_t at = (pv.seen >> C_UP & 1u) ? pv.at[C_UP] + 1 : 0;
        return perr(p, p->t[at].col, "expected an 'up' vector not parallel to the view direction");
    }
    for (int k = 0; k < 3; k++)
        right[k] /= lr;
    cross3d(right, fwd, up2);
    double znear = (pv.seen >> C_NEAR & 1u) ? pv.v[C_NEAR][0] : 0.01;
    double zfar = (pv.seen >> C_FAR & 1u) ? pv.v[C_FAR][0] : 0.0;
    if (zfar != 0.0 && zfar <= znear) {
        char g2[48];
        return perr(p, p->t[pv.at[C_FAR] + 1].col,
                    "expected 'far' 0 (infinite) or greater than 'near' (%g), got %s", znear,
                    got(p, pv.at[C_FAR] + 1, g2));
    }
    if (grow(&s->cams, &s->capcams, s->ncams + 1, sizeof *s->cams))
        return oom(p->st);
    gi_camera *c = &s->cams[s->ncams];
    memset(c, 0, sizeof *c);
    for (int k = 0; k < 3; k++) {
        c->position[k] = (float)pv.v[C_POSITION][k];
        c->forward[k] = (float)fwd[k];
        c->up[k] = (float)up2[k];
    }
    c->yfov = (float)(((pv.seen >> C_FOV & 1u) ? pv.v[C_FOV][0] : 45.0) * DEG2RAD);
    c->aspect = 0.0f;
    c->znear = (float)znear;
    c->zfar = (float)zfar;
    rc = add_cmd(p, CMD_CAMERA, p->t[0].col, (int)s->ncams, 0);
    if (!rc)
        s->ncams++;
    return rc;
}

enum { L_POSITION, L_CENTER, L_DIRECTION, L_U, L_V, L_INTENSITY, L_ILLUMINANCE, L_LUMINANCE,
       L_COLOR, L_INNER, L_OUTER, L_RANGE, L_N };
static const prop light_props[L_N] = {
    {"position", 3, CK_ANY},      {"center", 3, CK_ANY},      {"direction", 3, CK_NONZERO3},
    {"u", 3, CK_NONZERO3},        {"v", 3, CK_NONZERO3},      {"intensity", 1, CK_STRENGTH},
    {"illuminance", 1, CK_STRENGTH}, {"luminance", 1, CK_STRENGTH}, {"color", 3, CK_STRENGTH},
    {"inner", 1, CK_INNER},       {"outer", 1, CK_OUTER},     {"range", 1, CK_NONNEG},
};
#define B(x) (1u << (x))
static const struct {
    const char *kw;
    unsigned allowed, required; /* required in the order they are reported */
    const char *list;
} light_types[4] = {
    [GI_LIGHT_POINT] = {"point", B(L_POSITION) | B(L_INTENSITY) | B(L_COLOR) | B(L_RANGE),
                        B(L_POSITION) | B(L_INTENSITY), "position, intensity, color, range"},
    [GI_LIGHT_SPOT] = {"spot",
                       B(L_POSITION) | B(L_DIRECTION) | B(L_INTENSITY) | B(L_COLOR) | B(L_INNER) |
                           B(L_OUTER) | B(L_RANGE),
                       B(L_POSITION) | B(L_DIRECTION) | B(L_INTENSITY) | B(L_OUTER),
                       "position, direction, intensity, inner, outer, color, range"},
    [GI_LIGHT_DIRECTIONAL] = {"directional", B(L_DIRECTION) | B(L_ILLUMINANCE) | B(L_COLOR),
                              B(L_DIRECTION) | B(L_ILLUMINANCE), "direction, illuminance, color"},
    [GI_LIGHT_AREA] = {"area", B(L_CENTER) | B(L_U) | B(L_V) | B(L_LUMINANCE) | B(L_COLOR),
                       B(L_CENTER) | B(L_U) | B(L_V) | B(L_LUMINANCE), "center, u, v, luminance, color"},
};

static int light_id(parser *p, const char *name)
{
    int id = names_find(&p->s->lights, name);
    if (id < 0)
        id = names_add(&p->s->lights, name, (int)p->s->ncmds);
    return id;
}

static int parse_light(parser *p)
{
    gi_script *s = p->s;
    char g[48];
    int rc = name_at(p, 1, "a light name", "light");
    if (rc)
        return rc;
    const char *name = p->t[1].text;
    if (p->nt >= 3 && (is_kw(&p->t[2], "off") || is_kw(&p->t[2], "on"))) {
        int kind = is_kw(&p->t[2], "off") ? CMD_LIGHT_OFF : CMD_LIGHT_ON;
        if ((rc = expect_eol(p, 3)))
            return rc;
        int id = light_id(p, name);
        if (id < 0)
            return oom(p->st);
        return add_cmd(p, kind, p->t[1].col, id, 0);
    }
    int type = -1;
    for (int k = 0; k < 4; k++)
        if (p->nt >= 3 && is_kw(&p->t[2], light_types[k].kw))
            type = k;
    if (type < 0)
        return perr(p, colat(p, 2),
                    "expected a light type (point, spot, directional, area) or 'on'/'off' after "
                    "'%s', got %s", name, got(p, 2, g));
    char what[64];
    snprintf(what, sizeof what, "a %s light property", light_types[type].kw);
    propvals pv;
    if ((rc = read_props(p, 3, light_props, L_N, light_types[type].allowed, what, light_types[type].list,
                         &pv)))
        return rc;
    static const int order[] = {L_POSITION, L_CENTER, L_DIRECTION, L_U, L_V, L_INTENSITY,
                                L_ILLUMINANCE, L_LUMINANCE, L_OUTER};
    for (size_t k = 0; k < sizeof order / sizeof order[0]; k++)
        if ((light_types[type].required & B(order[k])) && !(pv.seen & B(order[k])))
            return perr(p, p->t[2].col, "expected '%s' for %s light '%s'", light_props[order[k]].kw,
                        light_types[type].kw, name);
    gi_light L;
    memset(&L, 0, sizeof L);
    snprintf(L.name, sizeof L.name, "%s", name);
    L.type = type;
    L.enabled = 1;
    for (int k = 0; k < 3; k++)
        L.color[k] = (pv.seen & B(L_COLOR)) ? (float)pv.v[L_COLOR][k] : 1.0f;
    switch (type) {
    case GI_LIGHT_POINT:
    case GI_LIGHT_SPOT:
        L.intensity = (float)pv.v[L_INTENSITY][0];
        for (int k = 0; k < 3; k++)
            L.position[k] = (float)pv.v[L_POSITION][k];
        if (pv.seen & B(L_RANGE))
            L.range = (float)pv.v[L_RANGE][0];
        if (type == GI_LIGHT_SPOT) {
            store_unit(L.direction, pv.v[L_DIRECTION]);
            double inner = (pv.seen & B(L_INNER)) ? pv.v[L_INNER][0] : 0.0;
            double outer = pv.v[L_OUTER][0];
            if (inner > outer) {
                size_t at = pv.at[L_INNER] + 1;
                return perr(p, p->t[at].col, "expected 'inner' <= 'outer' (%g degrees), got %s",
                            outer, got(p, at, g));
            }
            L.inner_cone = (float)(inner * DEG2RAD);
            L.outer_cone = (float)(outer * DEG2RAD);
        }
        break;
    case GI_LIGHT_DIRECTIONAL:
        L.intensity = (float)pv.v[L_ILLUMINANCE][0];
        store_unit(L.direction, pv.v[L_DIRECTION]);
        break;
    default: { /* area */
        double n[3];
        cross3d(pv.v[L_U], pv.v[L_V], n);
        if (!(len3d(n) > 1e-6 * len3d(pv.v[L_U]) * len3d(pv.v[L_V])))
            return perr(p, p->t[pv.at[L_V] + 1].col, "expected 'v' not parallel to 'u', got %s %s %s",
                        p->t[pv.at[L_V] + 1].text, p->t[pv.at[L_V] + 2].text,
                        p->t[pv.at[L_V] + 3].text);
        L.intensity = (float)pv.v[L_LUMINANCE][0];
        for (int k = 0; k < 3; k++) {
            L.position[k] = (float)pv.v[L_CENTER][k];
            L.u[k] = (float)pv.v[L_U][k];
            L.v[k] = (float)pv.v[L_V][k];
        }
        store_unit(L.direction, n);
        break;
    }
    }
    if (grow(&s->ldefs, &s->capldefs, s->nldefs + 1, sizeof *s->ldefs))
        return oom(p->st);
    int id = light_id(p, name);
    if (id < 0)
        return oom(p->st);
    s->ldefs[s->nldefs] = L;
    if ((rc = add_cmd(p, CMD_LIGHT, p->t[1].col, id, (int)s->nldefs)))
        return rc;
    s->nldefs++;
    return 0;
}

enum { MP_BASECOLOR, MP_ROUGHNESS, MP_METALLIC, MP_EMISSION, MP_N };
static const prop material_props[MP_N] = {
    {"basecolor", 3, CK_UNIT01}, {"roughness", 1, CK_UNIT01},
    {"metallic", 1, CK_UNIT01},  {"emission", 3, CK_STRENGTH},
};
#define MATERIAL_LIST "basecolor, roughness, metallic, emission"

static int parse_material(parser *p)
{
    gi_script *s = p->s;
    char g[48];
    int rc = name_at(p, 1, "a material name", "material");
    if (rc)
        return rc;
    const char *name = p->t[1].text;
    if (p->nt < 3)
        return perr(p, colat(p, 2), "expected a material property (" MATERIAL_LIST ") after '%s', got %s",
                    name, got(p, 2, g));
    propvals pv;
    if ((rc = read_props(p, 2, material_props, MP_N, (1u << MP_N) - 1, "a material property",
                         MATERIAL_LIST, &pv)))
        return rc;
    int id = names_find(&s->mats, name);
    if (id < 0) {
        if ((id = names_add(&s->mats, name, (int)s->ncmds)) < 0)
            return oom(p->st);
        if (grow(&p->mlast, &p->capmlast, (size_t)id + 1, sizeof *p->mlast))
            return oom(p->st);
        p->mlast[id] = -1;
    }
    if (grow(&s->mrecs, &s->capmrecs, s->nmrecs + 1, sizeof *s->mrecs))
        return oom(p->st);
    mrec r;
    if (p->mlast[id] >= 0)
        r = s->mrecs[p->mlast[id]];
    else
        memset(&r, 0, sizeof r);
    for (int k = 0; k < 3; k++) {
        if (pv.seen & B(MP_BASECOLOR))
            r.base_color[k] = (float)pv.v[MP_BASECOLOR][k];
        if (pv.seen & B(MP_EMISSION))
            r.emission[k] = (float)pv.v[MP_EMISSION][k];
    }
    if (pv.seen & B(MP_ROUGHNESS))
        r.roughness = (float)pv.v[MP_ROUGHNESS][0];
    if (pv.seen & B(MP_METALLIC))
        r.metallic = (float)pv.v[MP_METALLIC][0];
    r.mask |= (pv.seen & B(MP_BASECOLOR) ? M_BASECOLOR : 0) | (pv.seen & B(MP_ROUGHNESS) ? M_ROUGHNESS : 0) |
              (pv.seen & B(MP_METALLIC) ? M_METALLIC : 0) | (pv.seen & B(MP_EMISSION) ? M_EMISSION : 0);
    if ((rc = add_cmd(p, CMD_MATERIAL, p->t[1].col, id, (int)s->nmrecs)))
        return rc;
    s->mrecs[s->nmrecs] = r;
    p->mlast[id] = (int)s->nmrecs++;
    return 0;
}

static int frame_name_ok(const char *n)
{
    if (!((n[0] >= 'A' && n[0] <= 'Z') || (n[0] >= 'a' && n[0] <= 'z') || (n[0] >= '0' && n[0] <= '9') ||
          n[0] == '_'))
        return 0;
    for (const char *c = n; *c; c++)
        if (!((*c >= 'A' && *c <= 'Z') || (*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') ||
              *c == '_' || *c == '-' || *c == '.'))
            return 0;
    return 1;
}

static int all_digits(const char *n)
{
    if (!*n)
        return 0;
    for (; *n; n++)
        if (*n < '0' || *n > '9')
            return 0;
    return 1;
}

static int parse_frame(parser *p)
{
    gi_script *s = p->s;
    char g[48];
    int rc = name_at(p, 1, "a frame name", "frame");
    if (rc)
        return rc;
    const char *name = p->t[1].text;
    if (!frame_name_ok(name))
        return perr(p, p->t[1].col,
                    "expected a frame name of letters, digits, '_', '-' and '.' starting with a "
                    "letter, digit or '_', got %s", got(p, 1, g));
    if (all_digits(name))
        return perr(p, p->t[1].col,
                    "expected a frame name that is not a number (it would read as a frame index), got %s",
                    got(p, 1, g));
    int prev = names_find(&s->frames, name);
    if (prev >= 0)
        return perr(p, p->t[1].col, "expected a unique frame name, got %s (already used on line %d)",
                    got(p, 1, g), s->cmds[s->frames.first[prev]].line);
    if ((rc = expect_eol(p, 2)))
        return rc;
    int idx = names_add(&s->frames, name, (int)s->ncmds);
    if (idx < 0)
        return oom(p->st);
    return add_cmd(p, CMD_FRAME, p->t[1].col, idx, 0);
}

/* ---- state replay and snapshots --------------------------------------------- */

static void state_init(const gi_script *s, sstate *S)
{
    S->w = GI_SCRIPT_DEFAULT_WIDTH;
    S->h = GI_SCRIPT_DEFAULT_HEIGHT;
    S->cam_kind = 0;
    S->cam = S->cam_cmd = -1;
    for (size_t k = 0; k < s->lights.n; k++) {
        S->l[k].def = -1;
        S->l[k].en = -1;
        S->l[k].en_cmd = -1;
    }
    for (size_t k = 0; k < s->mats.n; k++)
        S->m[k] = -1;
}

static void state_apply(const gi_script *s, sstate *S, size_t c)
{
    const cmd *m = &s->cmds[c];
    switch (m->kind) {
    case CMD_RESOLUTION: S->w = m->a; S->h = m->b; break;
    case CMD_CAMERA: S->cam_kind = 1; S->cam = m->a; S->cam_cmd = (int)c; break;
    case CMD_CAMERA_GLTF: S->cam_kind = 2; S->cam = m->a; S->cam_cmd = (int)c; break;
    case CMD_LIGHT: S->l[m->a].def = m->b; S->l[m->a].en = -1; break;
    case CMD_LIGHT_OFF: S->l[m->a].en = 0; S->l[m->a].en_cmd = (int)c; break;
    case CMD_LIGHT_ON: S->l[m->a].en = 1; S->l[m->a].en_cmd = (int)c; break;
    case CMD_MATERIAL: S->m[m->a] = m->b; break;
    default: break;
    }
}

static void snap_store(gi_script *s, const sstate *S, size_t j)
{
    int *h = s->snap_hdr + 5 * j;
    h[0] = S->w; h[1] = S->h; h[2] = S->cam_kind; h[3] = S->cam; h[4] = S->cam_cmd;
    if (s->lights.n)
        memcpy(s->snap_l + j * s->lights.n, S->l, s->lights.n * sizeof *S->l);
    if (s->mats.n)
        memcpy(s->snap_m + j * s->mats.n, S->m, s->mats.n * sizeof *S->m);
}

static void snap_load(const gi_script *s, sstate *S, size_t j)
{
    const int *h = s->snap_hdr + 5 * j;
    S->w = h[0]; S->h = h[1]; S->cam_kind = h[2]; S->cam = h[3]; S->cam_cmd = h[4];
    if (s->lights.n)
        memcpy(S->l, s->snap_l + j * s->lights.n, s->lights.n * sizeof *S->l);
    if (s->mats.n)
        memcpy(S->m, s->snap_m + j * s->mats.n, s->mats.n * sizeof *S->m);
}

static int state_alloc(const gi_script *s, sstate *S)
{
    S->l = zalloc(s->lights.n, sizeof *S->l);
    S->m = zalloc(s->mats.n, sizeof *S->m);
    return S->l && S->m ? 0 : -1;
}

static void state_free(sstate *S)
{
    free(S->l);
    free(S->m);
    S->l = NULL;
    S->m = NULL;
}

static int build_snapshots(gi_script *s, gi_status *st)
{
    size_t nf = s->frames.n;
    size_t per = 5 + 3 * s->lights.n + s->mats.n;
    size_t every = 16;
    while ((nf / every + 1) * per > SNAPSHOT_BUDGET && every < nf)
        every *= 2;
    s->every = every;
    s->nsnap = (nf + every - 1) / every;
    s->snap_hdr = zalloc(5 * s->nsnap, sizeof *s->snap_hdr);
    s->snap_l = zalloc(s->nsnap * s->lights.n, sizeof *s->snap_l);
    s->snap_m = zalloc(s->nsnap * s->mats.n, sizeof *s->snap_m);
    sstate S;
    if (!s->snap_hdr || !s->snap_l || !s->snap_m || state_alloc(s, &S)) {
        state_free(&S);
        return oom(st);
    }
    state_init(s, &S);
    size_t c = 0;
    for (size_t f = 0; f < nf; f++) {
        size_t end = (size_t)s->frames.first[f];
        for (; c <= end; c++)
            state_apply(s, &S, c);
        if (f % every == 0)
            snap_store(s, &S, f / every);
    }
    state_free(&S);
    return 0;
}

/* Apply commands from..(frame f's command) to S; returns the next command. */
static size_t state_goto(const gi_script *s, sstate *S, size_t f, size_t from)
{
    size_t end = (size_t)s->frames.first[f];
    for (size_t c = from; c <= end; c++)
        state_apply(s, S, c);
    return end + 1;
}

/* ---- parse entry points ----------------------------------------------------- */

int gi_script_parse_string(const char *text, size_t len, const char *name, gi_script **out,
                           gi_status *st)
{
    *out = NULL;
    if (!name)
        name = "<script>";
    if (len > MAX_SCRIPT_BYTES)
        return gi_status_set(st, GI_EXIT_DATA, "%s: larger than 1 GiB, not a script", name);
    gi_script *s = calloc(1, sizeof *s);
    if (!s || !(s->name = malloc(strlen(name) + 1))) {
        free(s);
        return oom(st);
    }
    memcpy(s->name, name, strlen(name) + 1);
    parser P;
    memset(&P, 0, sizeof P);
    P.s = s;
    P.st = st;
    P.name = s->name;
    int rc = 0;
    const char *c = text, *end = text + len;
    if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0)
        c += 3; /* UTF-8 byte order mark; columns count from after it */
    int pend_line = 0, pend_col = 0; /* first command after the last frame */
    int line = 0, eof_line = 1, eof_col = 1;
    while (c < end) {
        const char *le = memchr(c, '\n', (size_t)(end - c));
        if (!le)
            le = end;
        P.line = ++line;
        if ((rc = tokenize(&P, c, le)))
            goto fail;
        eof_line = le < end ? line + 1 : line;
        eof_col = le < end ? 1 : (int)(le - c) + 1;
        c = le < end ? le + 1 : end;
        if (P.nt == 0)
            continue;
        const tok *t0 = &P.t[0];
        if (is_kw(t0, "resolution"))
            rc = parse_resolution(&P);
        else if (is_kw(t0, "camera"))
            rc = parse_camera(&P);
        else if (is_kw(t0, "light"))
            rc = parse_light(&P);
        else if (is_kw(t0, "material"))
            rc = parse_material(&P);
        else if (is_kw(t0, "frame"))
            rc = parse_frame(&P);
        else {
            char g[48];
            rc = perr(&P, t0->col, "expected a command (resolution, camera, light, material, frame), got %s",
                      got(&P, 0, g));
        }
        if (rc)
            goto fail;
        if (is_kw(t0, "frame")) {
            pend_line = 0;
        } else if (!pend_line) {
            pend_line = P.line;
            pend_col = t0->col;
        }
    }
    if (s->frames.n == 0) {
        P.line = eof_line;
        rc = perr(&P, eof_col, "expected at least one 'frame' command, got end of file");
        goto fail;
    }
    if (pend_line) {
        P.line = pend_line;
        rc = perr(&P, pend_col, "expected a 'frame' command after this one: commands after the last "
                                "frame have no effect");
        goto fail;
    }
    if ((rc = build_snapshots(s, st)))
        goto fail;
    free(P.t);
    free(P.buf);
    free(P.mlast);
    *out = s;
    return 0;
fail:
    free(P.t);
    free(P.buf);
    free(P.mlast);
    gi_script_free(s);
    return rc;
}

int gi_script_parse_file(const char *path, gi_script **out, gi_status *st)
{
    *out = NULL;
    FILE *f = fopen(path, "rb");
    if (!f)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot open", path);
    char *buf = NULL;
    size_t n = 0, cap = 0;
    for (;;) {
        if (grow(&buf, &cap, n + 65536, 1)) {
            free(buf);
            fclose(f);
            return oom(st);
        }
        size_t r = fread(buf + n, 1, cap - n, f);
        n += r;
        if (r == 0)
            break;
        if (n > MAX_SCRIPT_BYTES)
            break;
    }
    if (ferror(f)) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot read", path);
        free(buf);
        fclose(f);
        return rc;
    }
    fclose(f);
    int rc = gi_script_parse_string(buf ? buf : "", n, path, out, st);
    free(buf);
    return rc;
}

void gi_script_free(gi_script *s)
{
    if (!s)
        return;
    free(s->name);
    free(s->cmds);
    free(s->cams);
    free(s->ldefs);
    free(s->mrecs);
    names_free(&s->lights);
    names_free(&s->mats);
    names_free(&s->frames);
    free(s->snap_hdr);
    free(s->snap_l);
    free(s->snap_m);
    free(s);
}

size_t gi_script_num_frames(const gi_script *s) { return s ? s->frames.n : 0; }

const char *gi_script_frame_name(const gi_script *s, size_t i)
{
    return s && i < s->frames.n ? s->frames.v[i] : NULL;
}

int gi_script_find_frame(const gi_script *s, const char *name_or_index)
{
    if (!s || !name_or_index)
        return -1;
    int id = names_find(&s->frames, name_or_index);
    if (id >= 0)
        return id;
    if (!all_digits(name_or_index) || strlen(name_or_index) > 10)
        return -1;
    unsigned long long v = strtoull(name_or_index, NULL, 10);
    return v < s->frames.n ? (int)v : -1;
}

/* ---- checks against a scene --------------------------------------------------- */

static const char *scene_label(const gi_scene *sc) { return sc->path[0] ? sc->path : "(unnamed)"; }

static int err_at(const gi_script *s, const cmd *c, gi_status *st, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
static int err_at(const gi_script *s, const cmd *c, gi_status *st, const char *fmt, ...)
{
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return gi_status_set(st, GI_EXIT_DATA, "%s:%d:%d: %s", s->name, c->line, c->col, msg);
}

static int err_camera(const gi_script *s, const cmd *c, const gi_scene *sc, gi_status *st)
{
    if (sc->num_cameras == 0)
        return err_at(s, c, st, "expected a camera index, got '%d': scene '%s' has no cameras", c->a,
                      scene_label(sc));
    return err_at(s, c, st, "expected a camera index in 0..%zu (scene '%s'), got '%d'",
                  sc->num_cameras - 1, scene_label(sc), c->a);
}

static int err_light(const gi_script *s, const cmd *c, const gi_scene *sc, gi_status *st)
{
    char g[48];
    const char *n = s->lights.v[c->a];
    return err_at(s, c, st, "expected a light of scene '%s' or one defined earlier in the script, got %s",
                  scene_label(sc), quoted(n, strlen(n), g));
}

static int err_material(const gi_script *s, const cmd *c, const gi_scene *sc, gi_status *st)
{
    char g[48];
    const char *n = s->mats.v[c->a];
    return err_at(s, c, st, "expected a material of scene '%s', got %s", scene_label(sc),
                  quoted(n, strlen(n), g));
}

/* Flags per name id: 1 if the scene has a light (material) of that name. */
static unsigned char *scene_light_ids(const gi_script *s, const gi_scene *sc, int *sid)
{
    unsigned char *in = zalloc(s->lights.n, 1);
    if (!in)
        return NULL;
    for (size_t j = 0; j < sc->num_lights; j++) {
        int id = names_find(&s->lights, sc->lights[j].name);
        if (sid)
            sid[j] = id;
        if (id >= 0)
            in[id] = 1;
    }
    return in;
}

int gi_script_check(const gi_script *s, const gi_scene *sc, gi_status *st)
{
    unsigned char *lin = scene_light_ids(s, sc, NULL);
    unsigned char *def = zalloc(s->lights.n, 1);
    unsigned char *min = zalloc(s->mats.n, 1);
    int rc = 0;
    if (!lin || !def || !min) {
        rc = oom(st);
        goto done;
    }
    for (size_t k = 0; k < sc->num_materials; k++) {
        int id = names_find(&s->mats, sc->materials[k].name);
        if (id >= 0)
            min[id] = 1;
    }
    for (size_t c = 0; c < s->ncmds && !rc; c++) {
        const cmd *m = &s->cmds[c];
        switch (m->kind) {
        case CMD_CAMERA_GLTF:
            if ((size_t)m->a >= sc->num_cameras)
                rc = err_camera(s, m, sc, st);
            break;
        case CMD_LIGHT: def[m->a] = 1; break;
        case CMD_LIGHT_OFF:
        case CMD_LIGHT_ON:
            if (!def[m->a] && !lin[m->a])
                rc = err_light(s, m, sc, st);
            break;
        case CMD_MATERIAL:
            if (!min[m->a])
                rc = err_material(s, m, sc, st);
            break;
        default: break;
        }
    }
done:
    free(lin);
    free(def);
    free(min);
    return rc;
}

/* ---- resolving frames ------------------------------------------------------------ */

void gi_frame_release(gi_frame *f)
{
    if (!f)
        return;
    free(f->lights);
    free(f->light_changed);
    free(f->materials);
    free(f->material_changed);
    memset(f, 0, sizeof *f);
}

/* Light array keys: scene slot j, or num_scene_lights + script light id. */
static int resolve(const gi_script *s, const gi_scene *sc, const sstate *S, size_t fi, gi_frame *f,
                   size_t **keys, gi_status *st)
{
    memset(f, 0, sizeof *f);
    *keys = NULL;
    snprintf(f->name, sizeof f->name, "%s", s->frames.v[fi]);
    f->index = fi;
    f->width = S->w;
    f->height = S->h;
    if (S->cam_kind == 1) {
        f->has_camera = 1;
        f->camera = s->cams[S->cam];
    } else if (S->cam_kind == 2) {
        if ((size_t)S->cam >= sc->num_cameras)
            return err_camera(s, &s->cmds[S->cam_cmd], sc, st);
        f->has_camera = 1;
        f->camera = sc->cameras[S->cam];
    }

    size_t nsl = sc->num_lights, nl = s->lights.n;
    int *sid = zalloc(nsl, sizeof *sid);
    unsigned char *used = zalloc(nl, 1);
    unsigned char *in = sid ? scene_light_ids(s, sc, sid) : NULL;
    int rc = 0;
    if (!sid || !used || !in) {
        rc = oom(st);
        goto done;
    }
    size_t extra = 0;
    for (size_t id = 0; id < nl; id++) {
        if (S->l[id].def >= 0 && !in[id])
            extra++;
        if (S->l[id].def < 0 && S->l[id].en >= 0 && !in[id]) {
            rc = err_light(s, &s->cmds[S->l[id].en_cmd], sc, st);
            goto done;
        }
    }
    f->num_lights = nsl + extra;
    f->lights = zalloc(f->num_lights, sizeof *f->lights);
    f->light_changed = zalloc(f->num_lights, 1);
    *keys = zalloc(f->num_lights, sizeof **keys);
    if (!f->lights || !f->light_changed || !*keys) {
        rc = oom(st);
        goto done;
    }
    for (size_t j = 0; j < nsl; j++) {
        int id = sid[j];
        gi_light *L = &f->lights[j];
        if (id >= 0 && S->l[id].def >= 0) {
            *L = s->ldefs[S->l[id].def];
            if (used[id])
                L->enabled = 0; /* a second scene light of the same name: replaced by the first */
            else
                L->enabled = S->l[id].en != 0;
            used[id] = 1;
        } else {
            *L = sc->lights[j];
            if (id >= 0 && S->l[id].en >= 0)
                L->enabled = S->l[id].en;
        }
        (*keys)[j] = j;
    }
    size_t o = nsl;
    for (size_t id = 0; id < nl; id++) {
        if (S->l[id].def >= 0 && !in[id]) {
            f->lights[o] = s->ldefs[S->l[id].def];
            f->lights[o].enabled = S->l[id].en != 0;
            (*keys)[o++] = nsl + id;
        }
    }

    f->num_materials = sc->num_materials;
    f->materials = zalloc(sc->num_materials, sizeof *f->materials);
    f->material_changed = zalloc(sc->num_materials, 1);
    unsigned char *matched = zalloc(s->mats.n, 1);
    if (!f->materials || !f->material_changed || !matched) {
        free(matched);
        rc = oom(st);
        goto done;
    }
    if (sc->num_materials)
        memcpy(f->materials, sc->materials, sc->num_materials * sizeof *f->materials);
    for (size_t k = 0; k < sc->num_materials; k++) {
        int id = names_find(&s->mats, sc->materials[k].name);
        if (id < 0)
            continue;
        matched[id] = 1;
        if (S->m[id] < 0)
            continue;
        const mrec *r = &s->mrecs[S->m[id]];
        gi_material *M = &f->materials[k];
        for (int c = 0; c < 3; c++) {
            if (r->mask & M_BASECOLOR)
                M->base_color[c] = r->base_color[c];
            if (r->mask & M_EMISSION)
                M->emission[c] = r->emission[c];
        }
        if (r->mask & M_ROUGHNESS)
            M->roughness = r->roughness;
        if (r->mask & M_METALLIC)
            M->metallic = r->metallic;
    }
    for (size_t id = 0; id < s->mats.n && !rc; id++)
        if (S->m[id] >= 0 && !matched[id])
            rc = err_material(s, &s->cmds[s->mats.first[id]], sc, st);
    free(matched);
done:
    free(sid);
    free(used);
    free(in);
    if (rc) {
        gi_frame_release(f);
        free(*keys);
        *keys = NULL;
    }
    return rc;
}

static int v3eq(const float *a, const float *b) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }

/* Same effect on the picture (fields a light type does not use are ignored). */
static int light_equal(const gi_light *a, const gi_light *b)
{
    if (!a->enabled && !b->enabled)
        return 1;
    if (a->enabled != b->enabled || a->type != b->type || a->intensity != b->intensity ||
        !v3eq(a->color, b->color))
        return 0;
    switch (a->type) {
    case GI_LIGHT_POINT: return v3eq(a->position, b->position);
    case GI_LIGHT_SPOT:
        return v3eq(a->position, b->position) && v3eq(a->direction, b->direction) &&
               a->inner_cone == b->inner_cone && a->outer_cone == b->outer_cone;
    case GI_LIGHT_DIRECTIONAL: return v3eq(a->direction, b->direction);
    default: return v3eq(a->position, b->position) && v3eq(a->u, b->u) && v3eq(a->v, b->v);
    }
}

static int camera_equal(const gi_camera *a, const gi_camera *b)
{
    return v3eq(a->position, b->position) && v3eq(a->forward, b->forward) && v3eq(a->up, b->up) &&
           a->yfov == b->yfov && a->aspect == b->aspect && a->znear == b->znear && a->zfar == b->zfar;
}

static int material_equal(const gi_material *a, const gi_material *b)
{
    return v3eq(a->base_color, b->base_color) && v3eq(a->emission, b->emission) &&
           a->roughness == b->roughness && a->metallic == b->metallic;
}

static void set_all_changed(gi_frame *f)
{
    f->changed = GI_CHANGED_ALL;
    if (f->num_lights)
        memset(f->light_changed, 1, f->num_lights);
    if (f->num_materials)
        memset(f->material_changed, 1, f->num_materials);
}

int gi_script_frame(const gi_script *s, const gi_scene *sc, size_t i, gi_frame *out, gi_status *st)
{
    memset(out, 0, sizeof *out);
    if (i >= s->frames.n)
        return gi_status_set(st, GI_EXIT_USAGE, "%s: frame %zu out of range (the script has %zu frames)",
                             s->name, i, s->frames.n);
    sstate S;
    gi_frame prev;
    size_t *keys = NULL, *pkeys = NULL;
    memset(&prev, 0, sizeof prev);
    int rc = 0;
    if (state_alloc(s, &S)) {
        rc = oom(st);
        goto done;
    }
    size_t first = i > 0 ? i - 1 : 0;
    size_t blk = first / s->every;
    snap_load(s, &S, blk);
    size_t next = (size_t)s->frames.first[blk * s->every] + 1;
    if (i > 0) {
        next = state_goto(s, &S, first, next);
        if ((rc = resolve(s, sc, &S, first, &prev, &pkeys, st)))
            goto done;
    }
    state_goto(s, &S, i, next);
    if ((rc = resolve(s, sc, &S, i, out, &keys, st)))
        goto done;
    if (i == 0) {
        set_all_changed(out);
        goto done;
    }
    unsigned ch = 0;
    if (out->width != prev.width || out->height != prev.height)
        ch |= GI_CHANGED_RESOLUTION;
    if (out->has_camera != prev.has_camera ||
        (out->has_camera && !camera_equal(&out->camera, &prev.camera)))
        ch |= GI_CHANGED_CAMERA;
    if (out->num_lights != prev.num_lights)
        ch |= GI_CHANGED_LIGHTS;
    for (size_t j = 0, k = 0; j < out->num_lights; j++) {
        while (k < prev.num_lights && pkeys[k] < keys[j])
            k++;
        int same = k < prev.num_lights && pkeys[k] == keys[j] && light_equal(&out->lights[j], &prev.lights[k]);
        out->light_changed[j] = (unsigned char)!same;
        if (!same)
            ch |= GI_CHANGED_LIGHTS;
    }
    for (size_t k = 0; k < out->num_materials; k++) {
        int same = material_equal(&out->materials[k], &prev.materials[k]);
        out->material_changed[k] = (unsigned char)!same;
        if (!same)
            ch |= GI_CHANGED_MATERIALS;
    }
    out->changed = ch;
done:
    state_free(&S);
    gi_frame_release(&prev);
    free(keys);
    free(pkeys);
    if (rc)
        gi_frame_release(out);
    return rc;
}

int gi_frame_from_scene(const gi_scene *sc, gi_frame *out, gi_status *st)
{
    memset(out, 0, sizeof *out);
    snprintf(out->name, sizeof out->name, "scene");
    out->width = GI_SCRIPT_DEFAULT_WIDTH;
    out->height = GI_SCRIPT_DEFAULT_HEIGHT;
    if (sc->num_cameras > 0) {
        out->has_camera = 1;
        out->camera = sc->cameras[0];
        float a = sc->cameras[0].aspect;
        if (a > 0 && isfinite(a)) {
            double h = floor(GI_SCRIPT_DEFAULT_WIDTH / (double)a + 0.5);
            out->height = h < 1 ? 1 : h > GI_SCRIPT_MAX_RESOLUTION ? GI_SCRIPT_MAX_RESOLUTION : (int)h;
        }
    }
    out->num_lights = sc->num_lights;
    out->lights = zalloc(sc->num_lights, sizeof *out->lights);
    out->light_changed = zalloc(sc->num_lights, 1);
    out->num_materials = sc->num_materials;
    out->materials = zalloc(sc->num_materials, sizeof *out->materials);
    out->material_changed = zalloc(sc->num_materials, 1);
    if (!out->lights || !out->light_changed || !out->materials || !out->material_changed) {
        gi_frame_release(out);
        return oom(st);
    }
    if (sc->num_lights)
        memcpy(out->lights, sc->lights, sc->num_lights * sizeof *out->lights);
    if (sc->num_materials)
        memcpy(out->materials, sc->materials, sc->num_materials * sizeof *out->materials);
    set_all_changed(out);
    return 0;
}
