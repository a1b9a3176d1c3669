/* compare_report.c - `gi-compare report`: speed against error from a CSV of
 * runs: a Markdown report with equal-error speed ratios, and a log-log plot
 * drawn by gnuplot (PNG + SVG, with the data and script kept for re-plotting).
 *
 * Everything is written into a staging directory DIR/.report.tmp.<pid>, gnuplot
 * runs there, and each finished file is renamed into DIR; on failure the
 * staging directory is removed and DIR keeps its previous contents. */
#define _POSIX_C_SOURCE 200809L
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "compare.h"
#include "gi_exit.h"
#include "gi_log.h"
#include "gi_status.h"

/* Column names, in the order of report_row's fields. */
enum { COL_SCENE, COL_METHOD, COL_PARAMS, COL_SECONDS, COL_NRMSE, NCOLS };
static const char *const col_names[NCOLS] = {"scene", "method", "parameters", "seconds", "nrmse"};

/* Files written into DIR, in this order. */
static const char *const out_names[] = {"report.md", "report.gp", "error_vs_time.dat",
                                        "error_vs_time.png", "error_vs_time.svg"};
#define NOUT (sizeof out_names / sizeof out_names[0])

typedef struct report_opts {
    const char *csv_path;
    const char *out_dir;
} report_opts;

typedef struct report_row {
    char *scene, *method, *params;
    double seconds, nrmse;
    long line;     /* line of the CSV where the record starts */
    int scene_ix;  /* order of first appearance of the scene */
} report_row;

typedef struct report_runs {
    report_row *rows;
    size_t n, cap;
    char **scenes; /* distinct scene names, order of first appearance (borrowed from rows) */
    size_t nscenes;
} report_runs;

/* ---- command line -------------------------------------------------------- */

static void report_help(void)
{
    printf("usage: gi-compare report [options] -o DIR RUNS.csv\n"
           "\n"
           "Read RUNS.csv (header line naming the columns scene, method, parameters,\n"
           "seconds, nrmse in any order; RFC 4180 quoting) and write into DIR:\n"
           "  report.md            per scene: table of runs and equal-error speed ratios\n"
           "  error_vs_time.png    log-log plot of nrmse against time per frame\n"
           "  error_vs_time.svg    the same plot as SVG\n"
           "  report.gp, error_vs_time.dat   gnuplot script and data (re-plot: cd DIR;\n"
           "                       gnuplot report.gp)\n"
           "\n"
           "options:\n"
           "  -o, --output DIR   output directory (created if missing; required)\n"
           "  -q, --quiet        errors only\n"
           "  -v, --verbose      more messages\n"
           "  -h, --help         this help\n"
           "\n"
           "needs gnuplot on PATH. exit: 0 success, 2 usage, 3 malformed CSV (file:line),\n"
           "4 I/O error or gnuplot missing or failing\n");
}

static int report_usage(const char *fmt, ...) GI_PRINTF(1, 2);
static int report_usage(const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* main.c sets the log prefix to "gi-compare report" */
    fprintf(stderr, "%s: %s\ntry '%s --help'\n", gi_log_prog(), msg, gi_log_prog());
    return GI_EXIT_USAGE;
}

/* Returns -1 to go on, 0 after --help, or an exit code. */
static int report_parse(int argc, char **argv, report_opts *o)
{
    static const struct option longopts[] = {
        {"output", required_argument, NULL, 'o'},
        {"quiet", no_argument, NULL, 'q'},
        {"verbose", no_argument, NULL, 'v'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    int c, verbosity = gi_log_verbosity();
    memset(o, 0, sizeof *o);
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":o:qvh", longopts, NULL)) != -1) {
        switch (c) {
        case 'o':
            if (!optarg[0])
                return report_usage("--output: empty directory name");
            if (o->out_dir)
                return report_usage("--output given twice");
            o->out_dir = optarg;
            break;
        case 'q': verbosity = -1; break;
        case 'v': verbosity = verbosity < 0 ? 1 : verbosity + 1; break;
        case 'h': report_help(); return 0;
        case ':': return report_usage("option '%s' needs a value", argv[optind - 1]);
        default: return report_usage("unknown option '%s'", argv[optind - 1]);
        }
    }
    gi_log_set_verbosity(verbosity);
    if (argc - optind != 1)
        return report_usage("expected one RUNS.csv file, got %d arguments", argc - optind);
    if (!o->out_dir)
        return report_usage("missing -o DIR (output directory)");
    o->csv_path = argv[optind];
    return -1;
}

/* ---- CSV (RFC 4180) ------------------------------------------------------ */

typedef struct csv_parser {
    const char *path, *buf;
    size_t len, pos;
    long line; /* current line, 1-based */
} csv_parser;

typedef struct csv_record {
    char **f;
    size_t n, cap;
    long line; /* line where the record starts */
} csv_record;

static void csv_record_clear(csv_record *r)
{
    for (size_t i = 0; i < r->n; i++)
        free(r->f[i]);
    r->n = 0;
}

static void csv_record_free(csv_record *r)
{
    csv_record_clear(r);
    free(r->f);
    memset(r, 0, sizeof *r);
}

typedef struct strbuf {
    char *s;
    size_t n, cap;
} strbuf;

static int sb_put(strbuf *b, char c)
{
    if (b->n + 1 >= b->cap) {
        size_t cap = b->cap ? 2 * b->cap : 32;
        char *s = realloc(b->s, cap);
        if (!s)
            return -1;
        b->s = s;
        b->cap = cap;
    }
    b->s[b->n++] = c;
    b->s[b->n] = '\0';
    return 0;
}

/* Read one field; *eor is set at end of record (newline or end of file). */
static int csv_field(csv_parser *p, strbuf *b, int *eor, gi_status *st)
{
    if (!b->s && sb_put(b, '\0'))
        goto oom;
    b->n = 0;
    b->s[0] = '\0';
    *eor = 0;
    if (p->pos < p->len && p->buf[p->pos] == '"') {
        long open_line = p->line;
        p->pos++;
        for (;;) {
            if (p->pos >= p->len)
                return gi_status_set(st, GI_EXIT_DATA,
                                     "%s:%ld: unterminated quoted field (opened on line %ld)",
                                     p->path, p->line, open_line);
            char c = p->buf[p->pos];
            if (c == '\0')
                return gi_status_set(st, GI_EXIT_DATA, "%s:%ld: NUL byte in a text file", p->path,
                                     p->line);
            if (c == '"') {
                if (p->pos + 1 < p->len && p->buf[p->pos + 1] == '"') {
                    if (sb_put(b, '"'))
                        goto oom;
                    p->pos += 2;
                    continue;
                }
                p->pos++;
                break;
            }
            if (c == '\n')
                p->line++;
            if (sb_put(b, c))
                goto oom;
            p->pos++;
        }
        if (p->pos >= p->len) {
            *eor = 1;
            return 0;
        }
        char c = p->buf[p->pos];
        if (c == ',') {
            p->pos++;
        } else if (c == '\n') {
            p->pos++;
            p->line++;
            *eor = 1;
        } else if (c == '\r' && p->pos + 1 < p->len && p->buf[p->pos + 1] == '\n') {
            p->pos += 2;
            p->line++;
            *eor = 1;
        } else {
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s:%ld: expected ',' or end of line after a closing quote, "
                                 "found '%c'",
                                 p->path, p->line, isprint((unsigned char)c) ? c : '?');
        }
        return 0;
    }
    for (;;) {
        if (p->pos >= p->len) {
            *eor = 1;
            return 0;
        }
        char c = p->buf[p->pos];
        if (c == ',') {
            p->pos++;
            return 0;
        }
        if (c == '\n' || (c == '\r' && p->pos + 1 < p->len && p->buf[p->pos + 1] == '\n')) {
            p->pos += c == '\n' ? 1 : 2;
            p->line++;
            *eor = 1;
            return 0;
        }
        if (c == '"')
            return gi_status_set(st, GI_EXIT_DATA,
                                 "%s:%ld: quote inside an unquoted field (quote the whole field "
                                 "and double inner quotes)",
                                 p->path, p->line);
        if (c == '\0')
            return gi_status_set(st, GI_EXIT_DATA, "%s:%ld: NUL byte in a text file", p->path,
                                 p->line);
        if (sb_put(b, c))
            goto oom;
        p->pos++;
    }
oom:
    return gi_status_set(st, GI_EXIT_SYSTEM, "%s:%ld: out of memory", p->path, p->line);
}

/* Next record into r. Returns 0 with r->n > 0, 0 with r->n == 0 at end of file,
 * or an error code. Unquoted fields are trimmed of spaces and tabs. */
static int csv_record_next(csv_parser *p, csv_record *r, gi_status *st)
{
    csv_record_clear(r);
    if (p->pos >= p->len)
        return 0;
    r->line = p->line;
    strbuf b = {NULL, 0, 0};
    int eor = 0, rc = 0;
    while (!eor) {
        int quoted = p->pos < p->len && p->buf[p->pos] == '"';
        if ((rc = csv_field(p, &b, &eor, st)) != 0)
            break;
        char *s = b.s, *e = b.s + b.n;
        if (!quoted) {
            while (s < e && (*s == ' ' || *s == '\t'))
                s++;
            while (e > s && (e[-1] == ' ' || e[-1] == '\t'))
                e--;
        }
        if (r->n == r->cap) {
            size_t cap = r->cap ? 2 * r->cap : 8;
            char **f = realloc(r->f, cap * sizeof *f);
            if (!f) {
                rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s:%ld: out of memory", p->path, p->line);
                break;
            }
            r->f = f;
            r->cap = cap;
        }
        size_t len = (size_t)(e - s);
        char *copy = malloc(len + 1);
        if (!copy) {
            rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s:%ld: out of memory", p->path, p->line);
            break;
        }
        memcpy(copy, s, len);
        copy[len] = '\0';
        r->f[r->n++] = copy;
    }
    free(b.s);
    return rc;
}

static int record_is_blank(const csv_record *r) { return r->n == 1 && r->f[0][0] == '\0'; }

static int read_file(const char *path, char **buf, size_t *len, gi_status *st)
{
    *buf = NULL;
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot open", path);
    size_t cap = 1 << 16, n = 0;
    char *b = malloc(cap);
    if (!b) {
        fclose(f);
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
    }
    for (;;) {
        if (n == cap) {
            char *nb = cap > ((size_t)1 << 40) ? NULL : realloc(b, cap * 2);
            if (!nb) {
                free(b);
                fclose(f);
                return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
            }
            b = nb;
            cap *= 2;
        }
        size_t got = fread(b + n, 1, cap - n, f);
        n += got;
        if (got == 0)
            break;
    }
    if (ferror(f)) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: read error", path);
        free(b);
        fclose(f);
        return rc;
    }
    fclose(f);
    *buf = b;
    *len = n;
    return 0;
}

/* A finite number > 0, the whole field. */
static int parse_positive(const char *s, double *out)
{
    char *end;
    if (!*s)
        return -1;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end != '\0' || errno == ERANGE || !isfinite(v) || !(v > 0.0))
        return -1;
    *out = v;
    return 0;
}

static void runs_free(report_runs *R)
{
    for (size_t i = 0; i < R->n; i++) {
        free(R->rows[i].scene);
        free(R->rows[i].method);
        free(R->rows[i].params);
    }
    free(R->rows);
    free(R->scenes);
    memset(R, 0, sizeof *R);
}

/* Keep the row's three strings (ownership moves out of the record). */
static int runs_add(report_runs *R, csv_record *r, const int col[NCOLS], double secs, double err,
                    const char *path, gi_status *st)
{
    if (R->n == R->cap) {
        size_t cap = R->cap ? 2 * R->cap : 64;
        report_row *rows = realloc(R->rows, cap * sizeof *rows);
        if (!rows)
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
        R->rows = rows;
        R->cap = cap;
    }
    report_row *row = &R->rows[R->n];
    row->scene = r->f[col[COL_SCENE]];
    row->method = r->f[col[COL_METHOD]];
    row->params = r->f[col[COL_PARAMS]];
    r->f[col[COL_SCENE]] = r->f[col[COL_METHOD]] = r->f[col[COL_PARAMS]] = NULL;
    row->seconds = secs;
    row->nrmse = err;
    row->line = r->line;
    row->scene_ix = -1;
    R->n++;
    return 0;
}

static int runs_read(const char *path, report_runs *R, gi_status *st)
{
    char *buf;
    size_t len;
    int rc = read_file(path, &buf, &len, st);
    if (rc)
        return rc;
    csv_parser p = {path, buf, len, 0, 1};
    if (len >= 3 && !memcmp(buf, "\xEF\xBB\xBF", 3))
        p.pos = 3; /* UTF-8 byte order mark */
    csv_record r = {NULL, 0, 0, 0};
    int col[NCOLS];
    size_t ncols = 0;

    /* header: the first non-blank record */
    do {
        if ((rc = csv_record_next(&p, &r, st)) != 0)
            goto out;
    } while (r.n > 0 && record_is_blank(&r));
    if (r.n == 0) {
        rc = gi_status_set(st, GI_EXIT_DATA, "%s: empty file: expected a header line '%s,%s,%s,%s,%s'",
                           path, col_names[0], col_names[1], col_names[2], col_names[3],
                           col_names[4]);
        goto out;
    }
    for (int k = 0; k < NCOLS; k++)
        col[k] = -1;
    for (size_t i = 0; i < r.n; i++)
        for (int k = 0; k < NCOLS; k++) {
            const char *a = r.f[i], *b = col_names[k];
            while (*a && *b && tolower((unsigned char)*a) == *b) {
                a++;
                b++;
            }
            if (*a || *b)
                continue;
            if (col[k] >= 0) {
                rc = gi_status_set(st, GI_EXIT_DATA, "%s:%ld: header: column '%s' appears twice",
                                   path, r.line, col_names[k]);
                goto out;
            }
            col[k] = (int)i;
        }
    for (int k = 0; k < NCOLS; k++)
        if (col[k] < 0) {
            rc = gi_status_set(st, GI_EXIT_DATA,
                               "%s:%ld: header: expected columns %s,%s,%s,%s,%s; '%s' is missing",
                               path, r.line, col_names[0], col_names[1], col_names[2],
                               col_names[3], col_names[4], col_names[k]);
            goto out;
        }
    ncols = r.n;

    for (;;) {
        if ((rc = csv_record_next(&p, &r, st)) != 0)
            goto out;
        if (r.n == 0)
            break;
        if (record_is_blank(&r))
            continue;
        if (r.n != ncols) {
            rc = gi_status_set(st, GI_EXIT_DATA,
                               "%s:%ld: expected %zu fields as in the header, got %zu (quote "
                               "fields that contain commas)",
                               path, r.line, ncols, r.n);
            goto out;
        }
        for (int k = COL_SCENE; k <= COL_METHOD; k++)
            if (!r.f[col[k]][0]) {
                rc = gi_status_set(st, GI_EXIT_DATA, "%s:%ld: field %d (%s): expected a name, got "
                                   "an empty field", path, r.line, col[k] + 1, col_names[k]);
                goto out;
            }
        double v[2];
        for (int k = COL_SECONDS; k <= COL_NRMSE; k++)
            if (parse_positive(r.f[col[k]], &v[k - COL_SECONDS]) != 0) {
                rc = gi_status_set(st, GI_EXIT_DATA,
                                   "%s:%ld: field %d (%s): expected a positive finite number, got "
                                   "'%.40s'", path, r.line, col[k] + 1, col_names[k],
                                   r.f[col[k]]);
                goto out;
            }
        if ((rc = runs_add(R, &r, col, v[0], v[1], path, st)) != 0)
            goto out;
    }
    if (R->n == 0) {
        rc = gi_status_set(st, GI_EXIT_DATA, "%s: no data rows after the header", path);
        goto out;
    }

    /* distinct scenes in order of first appearance */
    R->scenes = malloc(R->n * sizeof *R->scenes);
    if (!R->scenes) {
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
        goto out;
    }
    for (size_t i = 0; i < R->n; i++) {
        size_t s = 0;
        while (s < R->nscenes && strcmp(R->scenes[s], R->rows[i].scene))
            s++;
        if (s == R->nscenes)
            R->scenes[R->nscenes++] = R->rows[i].scene;
        R->rows[i].scene_ix = (int)s;
    }
out:
    csv_record_free(&r);
    free(buf);
    return rc;
}

static int row_cmp(const void *pa, const void *pb)
{
    const report_row *a = pa, *b = pb;
    if (a->scene_ix != b->scene_ix)
        return a->scene_ix < b->scene_ix ? -1 : 1;
    int c = strcmp(a->method, b->method);
    if (c)
        return c;
    if (a->seconds != b->seconds)
        return a->seconds < b->seconds ? -1 : 1;
    return a->line < b->line ? -1 : (a->line > b->line);
}

/* ---- equal-error interpolation ---------------------------------------------- */

/* Time at which a method's curve (points sorted by seconds) reaches error e,
 * interpolating log(time) against log(error) between consecutive points; the
 * earliest crossing wins. Returns 0 and sets *t, or -1 if e is outside every
 * segment. */
static int time_at_error(const report_row *pts, size_t n, double e, double *t)
{
    double le = log(e);
    for (size_t i = 0; i < n; i++) {
        if (pts[i].nrmse == e) {
            *t = pts[i].seconds;
            return 0;
        }
        if (i + 1 == n)
            break;
        double e0 = pts[i].nrmse, e1 = pts[i + 1].nrmse;
        if ((e0 < e && e < e1) || (e1 < e && e < e0)) {
            double f = (le - log(e0)) / (log(e1) - log(e0));
            double lt = log(pts[i].seconds) + f * (log(pts[i + 1].seconds) - log(pts[i].seconds));
            *t = exp(lt);
            return 0;
        }
    }
    return -1;
}

/* ---- output files ---------------------------------------------------------- */

static char *path_join(const char *dir, const char *name)
{
    size_t a = strlen(dir), b = strlen(name);
    char *p = malloc(a + b + 2);
    if (!p)
        return NULL;
    memcpy(p, dir, a);
    p[a] = '/';
    memcpy(p + a + 1, name, b + 1);
    return p;
}

/* Markdown table cell: '|' escaped, line breaks as spaces. */
static void md_cell(FILE *f, const char *s)
{
    for (; *s; s++) {
        if (*s == '|')
            fputs("\\|", f);
        else if (*s == '\n' || *s == '\r')
            fputc(' ', f);
        else
            fputc(*s, f);
    }
}

/* gnuplot single-quoted string body: ' doubled, line breaks as spaces. */
static void gp_str(FILE *f, const char *s)
{
    for (; *s; s++) {
        if (*s == '\'')
            fputs("''", f);
        else if (*s == '\n' || *s == '\r')
            fputc(' ', f);
        else
            fputc(*s, f);
    }
}

static void fmt_ratio(char *buf, size_t cap, double r)
{
    if (r >= 10.0)
        snprintf(buf, cap, "%.0f", r);
    else
        snprintf(buf, cap, "%.2g", r);
}

/* Close a file we wrote, checking every step (buffered errors, fsync). */
static int close_checked(FILE *f, const char *path, gi_status *st)
{
    int bad = ferror(f) || fflush(f) != 0;
    if (!bad && fsync(fileno(f)) != 0)
        bad = 1;
    if (fclose(f) != 0)
        bad = 1;
    return bad ? gi_status_errno(st, GI_EXIT_SYSTEM, "%s: write failed", path) : 0;
}

/* Range [b, e) of rows with the same scene starting at b. */
static size_t scene_end(const report_runs *R, size_t b)
{
    size_t e = b;
    while (e < R->n && R->rows[e].scene_ix == R->rows[b].scene_ix)
        e++;
    return e;
}

static size_t method_end(const report_runs *R, size_t b, size_t lim)
{
    size_t e = b;
    while (e < lim && !strcmp(R->rows[e].method, R->rows[b].method))
        e++;
    return e;
}

static void write_ratios(FILE *f, const report_runs *R, size_t sb, size_t se)
{
    size_t nmethods = 0;
    for (size_t m = sb; m < se; m = method_end(R, m, se))
        nmethods++;
    fprintf(f, "\n### Speed at equal error\n\n");
    if (nmethods < 2) {
        fprintf(f, "Only one method for this scene: nothing to compare.\n");
        return;
    }
    fprintf(f, "Time each method needs to reach the other's errors, interpolating log(time) "
               "against log(nrmse) along its curve.\n\n");
    for (size_t xb = sb; xb < se; xb = method_end(R, xb, se)) {
        size_t xe = method_end(R, xb, se);
        for (size_t yb = sb; yb < se; yb = method_end(R, yb, se)) {
            if (yb == xb)
                continue;
            size_t ye = method_end(R, yb, se);
            const char *x = R->rows[xb].method, *y = R->rows[yb].method;
            double lo = INFINITY, hi = 0;
            for (size_t j = yb; j < ye; j++) {
                lo = fmin(lo, R->rows[j].nrmse);
                hi = fmax(hi, R->rows[j].nrmse);
            }
            for (size_t i = xb; i < xe; i++) {
                const report_row *p = &R->rows[i];
                double ty;
                fprintf(f, "- %s reaches nrmse %.3g in %.3g s; ", x, p->nrmse, p->seconds);
                if (time_at_error(R->rows + yb, ye - yb, p->nrmse, &ty) == 0) {
                    /* ratio of the other's time to this one's; below 1 say it inverted */
                    char rb[32];
                    double ratio = ty / p->seconds;
                    fmt_ratio(rb, sizeof rb, ratio >= 1.0 ? ratio : 1.0 / ratio);
                    fprintf(f, "%s needs %.3g s at that error (\xE2\x89\x88%s\xC3\x97%s)\n", y,
                            ty, rb, ratio >= 1.0 ? "" : " less time");
                } else {
                    fprintf(f, "%s: not reached (its nrmse spans %.3g to %.3g)\n", y, lo, hi);
                }
            }
        }
    }
}

static int write_markdown(const char *path, const report_opts *o, const report_runs *R,
                          gi_status *st)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create", path);
    fprintf(f, "# Speed against error\n\n");
    fprintf(f, "From `%s`: %zu run%s, %zu scene%s. Error is nrmse against the reference "
               "(rms / mean of the reference); time is seconds per frame.\n\n",
            o->csv_path, R->n, R->n == 1 ? "" : "s", R->nscenes, R->nscenes == 1 ? "" : "s");
    fprintf(f, "![nrmse against time per frame, log-log](error_vs_time.png)\n\n");
    fprintf(f, "Also `error_vs_time.svg`; to re-plot, run `gnuplot report.gp` in this "
               "directory (data in `error_vs_time.dat`).\n");
    for (size_t sb = 0; sb < R->n;) {
        size_t se = scene_end(R, sb);
        fprintf(f, "\n## Scene: ");
        md_cell(f, R->rows[sb].scene);
        fprintf(f, "\n\n| method | parameters | seconds | nrmse |\n|---|---|---:|---:|\n");
        for (size_t i = sb; i < se; i++) {
            const report_row *r = &R->rows[i];
            fputs("| ", f);
            md_cell(f, r->method);
            fputs(" | ", f);
            md_cell(f, r->params);
            fprintf(f, " | %.6g | %.6g |\n", r->seconds, r->nrmse);
        }
        write_ratios(f, R, sb, se);
        sb = se;
    }
    return close_checked(f, path, st);
}

static int write_plot_files(const char *dat_path, const char *gp_path, const report_opts *o,
                            const report_runs *R, gi_status *st)
{
    FILE *d = fopen(dat_path, "w");
    if (!d)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create", dat_path);
    fprintf(d, "# error_vs_time.dat - written by gi-compare report from %s\n", o->csv_path);
    fprintf(d, "# one block (gnuplot index) per scene and method; columns: seconds nrmse\n");
    size_t nblocks = 0;
    for (size_t mb = 0; mb < R->n;) {
        size_t me = method_end(R, mb, scene_end(R, mb));
        fprintf(d, "%s# index %zu: scene '", nblocks ? "\n\n" : "", nblocks);
        gp_str(d, R->rows[mb].scene);
        fputs("', method '", d);
        gp_str(d, R->rows[mb].method);
        fputs("'\n", d);
        for (size_t i = mb; i < me; i++)
            fprintf(d, "%.9g %.9g\n", R->rows[i].seconds, R->rows[i].nrmse);
        nblocks++;
        mb = me;
    }
    int rc = close_checked(d, dat_path, st);
    if (rc)
        return rc;

    FILE *g = fopen(gp_path, "w");
    if (!g)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create", gp_path);
    fprintf(g,
            "# report.gp - written by gi-compare report from %s\n"
            "# re-plot in this directory: gnuplot report.gp\n"
            "set logscale xy\n"
            "set xlabel 'time per frame (s)'\n"
            "set ylabel 'nrmse vs reference'\n"
            "set grid xtics ytics lc rgb '#b0b0b0'\n"
            "set key outside below\n"
            "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) {\n"
            "  set terminal pngcairo size 960,600 noenhanced\n"
            "} else {\n"
            "  set terminal png size 960,600 noenhanced\n"
            "}\n"
            "set output 'error_vs_time.png'\n"
            "plot \\\n",
            o->csv_path);
    size_t k = 0;
    for (size_t mb = 0; mb < R->n; k++) {
        size_t me = method_end(R, mb, scene_end(R, mb));
        fprintf(g, "  'error_vs_time.dat' index %zu using 1:2 with linespoints lw 1.5 pt %zu ps 1.3 title '",
                k, 1 + k % 13);
        if (R->nscenes > 1) {
            gp_str(g, R->rows[mb].scene);
            fputs(": ", g);
        }
        gp_str(g, R->rows[mb].method);
        fprintf(g, "'%s\n", k + 1 < nblocks ? ", \\" : "");
        mb = me;
    }
    fprintf(g, "set terminal svg size 960,600 noenhanced\n"
               "set output 'error_vs_time.svg'\n"
               "replot\n"
               "unset output\n");
    return close_checked(g, gp_path, st);
}

/* ---- gnuplot ------------------------------------------------------------------ */

/* Find an executable named `name` on PATH; returns a malloc'd path or NULL. */
static char *find_on_path(const char *name)
{
    const char *path = getenv("PATH");
    if (!path || !*path)
        path = "/usr/bin:/bin";
    for (const char *p = path;;) {
        const char *colon = strchr(p, ':');
        size_t len = colon ? (size_t)(colon - p) : strlen(p);
        char *dir = malloc(len + 2);
        if (!dir)
            return NULL;
        if (len == 0) {
            strcpy(dir, ".");
        } else {
            memcpy(dir, p, len);
            dir[len] = '\0';
        }
        char *cand = path_join(dir, name);
        free(dir);
        struct stat sb;
        if (cand && stat(cand, &sb) == 0 && S_ISREG(sb.st_mode) && access(cand, X_OK) == 0)
            return cand;
        free(cand);
        if (!colon)
            return NULL;
        p = colon + 1;
    }
}

/* Run `gnuplot report.gp` in dir with output to dir/gnuplot.log. */
static int run_gnuplot(const char *gnuplot, const char *dir, gi_status *st)
{
    pid_t pid = fork();
    if (pid < 0)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "gnuplot: cannot fork");
    if (pid == 0) {
        if (chdir(dir) != 0)
            _exit(126);
        int fd = open("gnuplot.log", O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int nul = open("/dev/null", O_RDONLY);
        if (fd < 0 || nul < 0 || dup2(nul, 0) < 0 || dup2(fd, 1) < 0 || dup2(fd, 2) < 0)
            _exit(126);
        char *const args[] = {(char *)"gnuplot", (char *)"report.gp", NULL};
        execv(gnuplot, args);
        _exit(127);
    }
    int status;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            return gi_status_errno(st, GI_EXIT_SYSTEM, "gnuplot: waitpid");
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0)
        return 0;
    /* first line of gnuplot's messages, to say why */
    char line[300] = "";
    char *log_path = path_join(dir, "gnuplot.log");
    FILE *f = log_path ? fopen(log_path, "r") : NULL;
    if (f) {
        while (fgets(line, sizeof line, f))
            if (strspn(line, " \t\r\n^") != strlen(line))
                break;
        line[strcspn(line, "\r\n")] = '\0';
        fclose(f);
    }
    free(log_path);
    if (WIFEXITED(status))
        return gi_status_set(st, GI_EXIT_SYSTEM, "%s failed (exit %d)%s%s", gnuplot,
                             WEXITSTATUS(status), line[0] ? ": " : "", line);
    return gi_status_set(st, GI_EXIT_SYSTEM, "%s killed by signal %d", gnuplot,
                         WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

static int nonempty_file(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0;
}

/* fsync a file written by another process. */
static int sync_file(const char *path, gi_status *st)
{
    int fd = open(path, O_RDONLY);
    if (fd < 0)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot open", path);
    int bad = fsync(fd) != 0;
    if (close(fd) != 0)
        bad = 1;
    return bad ? gi_status_errno(st, GI_EXIT_SYSTEM, "%s: fsync", path) : 0;
}

static void remove_stage(const char *stage)
{
    for (size_t i = 0; i < NOUT; i++) {
        char *p = path_join(stage, out_names[i]);
        if (p)
            unlink(p);
        free(p);
    }
    char *p = path_join(stage, "gnuplot.log");
    if (p)
        unlink(p);
    free(p);
    rmdir(stage);
}

static int ensure_dir(const char *dir, gi_status *st)
{
    struct stat sb;
    if (stat(dir, &sb) == 0) {
        if (!S_ISDIR(sb.st_mode))
            return gi_status_set(st, GI_EXIT_SYSTEM, "%s: exists and is not a directory", dir);
        return 0;
    }
    if (errno != ENOENT)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot stat", dir);
    if (mkdir(dir, 0777) != 0 && errno != EEXIST)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create directory", dir);
    return 0;
}

int compare_report_main(int argc, char **argv)
{
    report_opts o;
    int rc = report_parse(argc, argv, &o);
    if (rc >= 0)
        return rc;

    gi_status st = {0};
    report_runs R;
    memset(&R, 0, sizeof R);
    char *gnuplot = NULL, *stage = NULL;
    char *paths[NOUT] = {NULL};

    gnuplot = find_on_path("gnuplot");
    if (!gnuplot) {
        gi_error("gnuplot not found on PATH: it draws error_vs_time.png (Debian: apt-get install "
                 "gnuplot-nox)");
        rc = GI_EXIT_SYSTEM;
        goto out;
    }
    if ((rc = runs_read(o.csv_path, &R, &st)) != 0)
        goto fail;
    qsort(R.rows, R.n, sizeof *R.rows, row_cmp);
    gi_verbose("%s: %zu runs in %zu scenes", o.csv_path, R.n, R.nscenes);

    if ((rc = ensure_dir(o.out_dir, &st)) != 0)
        goto fail;
    char name[64];
    snprintf(name, sizeof name, ".report.tmp.%ld", (long)getpid());
    stage = path_join(o.out_dir, name);
    for (size_t i = 0; stage && i < NOUT; i++)
        paths[i] = path_join(stage, out_names[i]);
    for (size_t i = 0; i < NOUT; i++)
        if (!stage || !paths[i]) {
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "%s: out of memory", o.out_dir);
            goto fail;
        }
    if (mkdir(stage, 0777) != 0) {
        rc = gi_status_errno(&st, GI_EXIT_SYSTEM, "%s: cannot create staging directory", stage);
        free(stage);
        stage = NULL; /* not ours to remove */
        goto fail;
    }
    if ((rc = write_markdown(paths[0], &o, &R, &st)) != 0 ||
        (rc = write_plot_files(paths[2], paths[1], &o, &R, &st)) != 0)
        goto fail;
    double t0 = gi_now();
    if ((rc = run_gnuplot(gnuplot, stage, &st)) != 0)
        goto fail;
    gi_verbose("gnuplot: %.2f s", gi_now() - t0);
    for (size_t i = 3; i < NOUT; i++) {
        if (!nonempty_file(paths[i])) {
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "%s: gnuplot did not write %s", gnuplot,
                               out_names[i]);
            goto fail;
        }
        if ((rc = sync_file(paths[i], &st)) != 0)
            goto fail;
    }
    for (size_t i = 0; i < NOUT; i++) {
        char *dst = path_join(o.out_dir, out_names[i]);
        if (!dst || rename(paths[i], dst) != 0) {
            rc = dst ? gi_status_errno(&st, GI_EXIT_SYSTEM, "%s: cannot rename into place", dst)
                     : gi_status_set(&st, GI_EXIT_SYSTEM, "%s: out of memory", o.out_dir);
            free(dst);
            goto fail;
        }
        free(dst);
    }
    remove_stage(stage);
    gi_info("wrote %s/report.md and error_vs_time.png (%zu run%s, %zu scene%s)", o.out_dir, R.n,
            R.n == 1 ? "" : "s", R.nscenes, R.nscenes == 1 ? "" : "s");
    rc = GI_EXIT_OK;
    goto out;
fail:
    gi_error("%s", st.msg);
    if (stage)
        remove_stage(stage);
out:
    for (size_t i = 0; i < NOUT; i++)
        free(paths[i]);
    free(stage);
    free(gnuplot);
    runs_free(&R);
    return rc;
}
