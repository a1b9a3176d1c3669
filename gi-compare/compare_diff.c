/* compare_diff.c - `gi-compare diff`: error statistics of an image against a
 * reference, key=value lines on stdout, optional false-colour error map. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare.h"
#include "gi_exit.h"
#include "gi_image.h"
#include "gi_log.h"
#include "gi_opt.h"
#include "gi_math.h"
#include "gi_status.h"

/* relmse denominator offset, in (image units)^2: mean of (a-b)^2 / (b^2 + 0.01). */
#define DIFF_RELMSE_EPS 0.01
/* Error map: epsilon of |La-Lb| / (|Lb| + eps) as a fraction of the mean
 * reference luminance, and the log10 range of the colour scale. */
#define DIFF_MAP_EPS_FRAC 0.01
#define DIFF_MAP_LOG_MIN (-3.0)
#define DIFF_MAP_LOG_MAX 0.0
/* Legend strip under the error map, and the narrowest map that fits it. */
#define DIFF_LEGEND_H 40
#define DIFF_LEGEND_MIN_W 160

typedef struct diff_opts {
    const char *a_path;
    const char *ref_path;
    const char *error_image; /* NULL: none */
    double tolerance;        /* < 0: no tolerance given */
} diff_opts;

static void diff_opts_default(diff_opts *o)
{
    memset(o, 0, sizeof *o);
    o->tolerance = -1.0;
}

static void diff_help(void)
{
    printf("usage: gi-compare diff [options] IMAGE REFERENCE\n"
           "\n"
           "Compare IMAGE against REFERENCE (any format OpenImageIO reads; RGB channels,\n"
           "or gray) and print key=value statistics on stdout: width height channels\n"
           "pixels rms nrmse relmse psnr max_abs max_abs_x max_abs_y mean_a mean_ref and\n"
           "per channel rms_r rms_g rms_b nrmse_r nrmse_g nrmse_b (rms_y, nrmse_y for gray).\n"
           "When REFERENCE is a gi-compare render of 2 spp or more, also ref_noise_nrmse (its\n"
           "own noise, estimated when it was rendered) and nrmse_excess = sqrt(max(0, nrmse^2\n"
           "- ref_noise_nrmse^2)): IMAGE's error against the noise-free image, were IMAGE's\n"
           "error independent of REFERENCE's noise (not so for a render of the same seed).\n"
           "--tolerance applies to nrmse.\n"
           "\n"
           "options:\n"
           "  -t, --tolerance T       exit 1 when nrmse > T (default: no limit, exit 0)\n"
           "  -e, --error-image FILE  write a PNG map of the per-pixel relative luminance\n"
           "                          error |a-b|/(|b|+eps), eps = 1%% of mean reference\n"
           "                          luminance, log colour scale 0.1%%..100%% with legend\n"
           "  -q, --quiet             errors only\n"
           "  -v, --verbose           more messages\n"
           "  -h, --help              this help\n"
           "\n"
           "exit: 0 within tolerance, 1 beyond it, 2 usage, 3 bad input (size or channel\n"
           "mismatch, NaN/Inf pixel, zero-mean reference), 4 unreadable file or I/O error\n");
}

static int diff_usage(const char *fmt, ...) GI_PRINTF(1, 2);
static int diff_usage(const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* main.c sets the log prefix to "gi-compare diff" */
    fprintf(stderr, "%s: %s\ntry '%s --help'\n", gi_log_prog(), msg, gi_log_prog());
    return GI_EXIT_USAGE;
}

/* Returns -1 on success (keep going), 0 for --help, or an exit code. */
static int diff_parse(int argc, char **argv, diff_opts *o)
{
    static const struct option longopts[] = {
        {"tolerance", required_argument, NULL, 't'},
        {"error-image", required_argument, NULL, 'e'},
        {"quiet", no_argument, NULL, 'q'},
        {"verbose", no_argument, NULL, 'v'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    int c, verbosity = gi_log_verbosity();
    optind = 1;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":t:e:qvh", longopts, NULL)) != -1) {
        switch (c) {
        case 't': {
            char *end;
            errno = 0;
            double t = strtod(optarg, &end);
            if (end == optarg || *end != '\0' || errno == ERANGE || !isfinite(t) || t < 0.0)
                return diff_usage("--tolerance: expected a number >= 0, got '%s'", optarg);
            o->tolerance = t;
            break;
        }
        case 'e':
            if (!optarg[0])
                return diff_usage("--error-image: empty file name");
            o->error_image = optarg;
            break;
        case 'q': verbosity = -1; break;
        case 'v': verbosity = verbosity < 0 ? 1 : verbosity + 1; break;
        case 'h': diff_help(); return 0;
        case ':': return diff_usage("option '%s' needs a value", argv[optind - 1]);
        default: return diff_usage("unknown option '%s'", argv[optind - 1]);
        }
    }
    gi_log_set_verbosity(verbosity);
    if (argc - optind != 2)
        return diff_usage("expected two images, IMAGE and REFERENCE (got %s)",
                          argc - optind < 2 ? "fewer" : "more");
    o->a_path = argv[optind];
    o->ref_path = argv[optind + 1];
    if (o->error_image && (!strcmp(o->error_image, o->a_path) ||
                           !strcmp(o->error_image, o->ref_path)))
        return diff_usage("--error-image '%s' would overwrite an input", o->error_image);
    if (o->error_image)
        gi_opt_check_output(o->error_image);
    return -1;
}

/* Colour channels compared: RGB for 3+ channels, gray for 1-2. */
static int colour_channels(const gi_image *im) { return im->channels >= 3 ? 3 : 1; }

static const char *channel_name(int nc, int c)
{
    static const char *rgb[3] = {"r", "g", "b"};
    return nc == 1 ? "y" : rgb[c];
}

/* First non-finite value among the compared channels, row-major order. */
static int check_finite(const gi_image *im, int nc, const char *path, gi_status *st)
{
    static const char *upper[3] = {"R", "G", "B"};
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++) {
            const float *p = im->pixels + ((size_t)y * (size_t)im->width + (size_t)x) *
                                              (size_t)im->channels;
            for (int c = 0; c < nc; c++)
                if (!isfinite(p[c]))
                    return gi_status_set(st, GI_EXIT_DATA,
                                         "%s: pixel (%d, %d) channel %s is %s (x from left, y "
                                         "from top)",
                                         path, x, y, nc == 1 ? "Y" : upper[c],
                                         isnan(p[c]) ? "nan" : (p[c] > 0 ? "+inf" : "-inf"));
        }
    return 0;
}

/* ---- error map --------------------------------------------------------- */

/* Viridis colour map sampled at 9 evenly spaced points (sRGB bytes). */
static const unsigned char viridis9[9][3] = {
    {68, 1, 84},   {71, 44, 122},  {59, 82, 139},  {44, 113, 142}, {33, 145, 140},
    {39, 173, 129}, {92, 200, 99}, {170, 220, 50}, {253, 231, 37},
};

static void colour_map(double t, float out[3])
{
    if (!(t > 0.0))
        t = 0.0;
    if (t > 1.0)
        t = 1.0;
    double f = t * 8.0;
    int i = (int)f;
    if (i > 7)
        i = 7;
    double u = f - (double)i;
    for (int c = 0; c < 3; c++)
        out[c] = (float)(((1.0 - u) * viridis9[i][c] + u * viridis9[i + 1][c]) / 255.0);
}

/* A 5x7 bitmap font with just what the legend needs. */
typedef struct glyph {
    char ch;
    const char *rows[7];
} glyph;

static const glyph font5x7[] = {
    {'0', {" ### ", "#   #", "#  ##", "# # #", "##  #", "#   #", " ### "}},
    {'1', {"  #  ", " ##  ", "  #  ", "  #  ", "  #  ", "  #  ", " ### "}},
    {'2', {" ### ", "#   #", "    #", "   # ", "  #  ", " #   ", "#####"}},
    {'3', {"#####", "   # ", "  #  ", "   # ", "    #", "#   #", " ### "}},
    {'4', {"   # ", "  ## ", " # # ", "#  # ", "#####", "   # ", "   # "}},
    {'5', {"#####", "#    ", "#### ", "    #", "    #", "#   #", " ### "}},
    {'6', {"  ## ", " #   ", "#    ", "#### ", "#   #", "#   #", " ### "}},
    {'7', {"#####", "    #", "   # ", "  #  ", " #   ", " #   ", " #   "}},
    {'8', {" ### ", "#   #", "#   #", " ### ", "#   #", "#   #", " ### "}},
    {'9', {" ### ", "#   #", "#   #", " ####", "    #", "   # ", " ##  "}},
    {'.', {"     ", "     ", "     ", "     ", "     ", " ##  ", " ##  "}},
    {'e', {"     ", "     ", " ### ", "#   #", "#####", "#    ", " ### "}},
    {'-', {"     ", "     ", "     ", "#####", "     ", "     ", "     "}},
    {'%', {"##   ", "##  #", "   # ", "  #  ", " #   ", "#  ##", "   ##"}},
};

static const glyph *find_glyph(char ch)
{
    for (size_t i = 0; i < sizeof font5x7 / sizeof font5x7[0]; i++)
        if (font5x7[i].ch == ch)
            return &font5x7[i];
    return NULL; /* drawn as a blank */
}

static void put_px(gi_image *im, int x, int y, const float rgb[3])
{
    if (x < 0 || y < 0 || x >= im->width || y >= im->height)
        return;
    float *p = im->pixels + ((size_t)y * (size_t)im->width + (size_t)x) * 3;
    p[0] = rgb[0];
    p[1] = rgb[1];
    p[2] = rgb[2];
}

static int text_width(const char *s, int scale) { return (int)strlen(s) * 6 * scale - scale; }

static void draw_text(gi_image *im, int x0, int y0, const char *s, int scale, const float rgb[3])
{
    for (; *s; s++, x0 += 6 * scale) {
        const glyph *g = find_glyph(*s);
        if (!g)
            continue;
        for (int r = 0; r < 7; r++)
            for (int c = 0; c < 5; c++)
                if (g->rows[r][c] == '#')
                    for (int dy = 0; dy < scale; dy++)
                        for (int dx = 0; dx < scale; dx++)
                            put_px(im, x0 + c * scale + dx, y0 + r * scale + dy, rgb);
    }
}

static double luminance_at(const gi_image *im, size_t i, int nc)
{
    const float *p = im->pixels + i * (size_t)im->channels;
    if (nc == 1)
        return p[0];
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

/* Build and write the error map: the image area, then a legend strip. */
static int write_error_map(const char *path, const gi_image *a, const gi_image *b, int nc,
                           gi_status *st)
{
    int w = a->width, h = a->height;
    size_t npix = (size_t)w * (size_t)h;
    gi_ksum lsum = {0, 0};
    for (size_t i = 0; i < npix; i++)
        gi_ksum_add(&lsum, luminance_at(b, i, nc));
    double eps = DIFF_MAP_EPS_FRAC * gi_ksum_get(&lsum) / (double)npix;
    if (!(eps > 1e-12))
        eps = 1e-12;

    int ow = w > DIFF_LEGEND_MIN_W ? w : DIFF_LEGEND_MIN_W;
    if (h > 1 << 28)
        return gi_status_set(st, GI_EXIT_DATA, "%s: image too tall for an error map", path);
    gi_image m = {0, 0, 0, NULL};
    int rc = gi_image_init(&m, ow, h + DIFF_LEGEND_H, 3, st);
    if (rc)
        return rc;
    const float bg[3] = {0.1f, 0.1f, 0.1f}, fg[3] = {0.92f, 0.92f, 0.92f};
    for (int y = 0; y < m.height; y++)
        for (int x = 0; x < m.width; x++)
            put_px(&m, x, y, bg);
    const double span = DIFF_MAP_LOG_MAX - DIFF_MAP_LOG_MIN;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            double la = luminance_at(a, i, nc), lb = luminance_at(b, i, nc);
            double e = fabs(la - lb) / (fabs(lb) + eps);
            double t = e > 0.0 ? (log10(e) - DIFF_MAP_LOG_MIN) / span : 0.0;
            float rgb[3];
            colour_map(t, rgb);
            put_px(&m, x, y, rgb);
        }

    /* legend: colour bar, ticks at each decade, labels in percent */
    static const char *labels[] = {"0.1%", "1%", "10%", "100%"};
    int nticks = (int)(sizeof labels / sizeof labels[0]);
    int scale = ow >= 480 ? 2 : 1;
    /* inclusive ends of the bar, inset so the end labels are centred on their ticks */
    int x0 = text_width(labels[0], scale) / 2 + 3;
    int x1 = ow - 4 - text_width(labels[nticks - 1], scale) / 2;
    int bar_y = h + 6, bar_h = 10;
    for (int x = x0; x <= x1; x++) {
        float rgb[3];
        colour_map((double)(x - x0) / (double)(x1 - x0), rgb);
        for (int y = bar_y; y < bar_y + bar_h; y++)
            put_px(&m, x, y, rgb);
    }
    for (int k = 0; k < nticks; k++) {
        int tx = x0 + (int)lround((double)k / (double)(nticks - 1) * (double)(x1 - x0));
        for (int y = bar_y + bar_h; y < bar_y + bar_h + 3; y++)
            put_px(&m, tx, y, fg);
        int tw = text_width(labels[k], scale);
        int lx = tx - tw / 2;
        if (lx < 1)
            lx = 1;
        if (lx + tw > ow - 1)
            lx = ow - 1 - tw;
        draw_text(&m, lx, bar_y + bar_h + 5, labels[k], scale, fg);
    }
    rc = gi_image_write_png(path, &m, st);
    gi_image_release(&m);
    return rc;
}

/* ---- statistics ---------------------------------------------------------- */

typedef struct diff_stats {
    double sq[3], rel, sum_a[3], sum_b[3], max_abs, peak;
    int max_x, max_y;
} diff_stats;

static void accumulate(const gi_image *a, const gi_image *b, int nc, diff_stats *s)
{
    gi_ksum sq[3] = {{0, 0}}, sa[3] = {{0, 0}}, sb[3] = {{0, 0}}, rel = {0, 0};
    double max_abs = 0.0, peak = -INFINITY;
    int mx = 0, my = 0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            size_t i = (size_t)y * (size_t)a->width + (size_t)x;
            const float *pa = a->pixels + i * (size_t)a->channels;
            const float *pb = b->pixels + i * (size_t)b->channels;
            for (int c = 0; c < nc; c++) {
                double va = pa[c], vb = pb[c], d = va - vb;
                gi_ksum_add(&sq[c], d * d);
                gi_ksum_add(&sa[c], va);
                gi_ksum_add(&sb[c], vb);
                gi_ksum_add(&rel, d * d / (vb * vb + DIFF_RELMSE_EPS));
                if (fabs(d) > max_abs) {
                    max_abs = fabs(d);
                    mx = x;
                    my = y;
                }
                if (vb > peak)
                    peak = vb;
            }
        }
    for (int c = 0; c < nc; c++) {
        s->sq[c] = gi_ksum_get(&sq[c]);
        s->sum_a[c] = gi_ksum_get(&sa[c]);
        s->sum_b[c] = gi_ksum_get(&sb[c]);
    }
    s->rel = gi_ksum_get(&rel);
    s->max_abs = max_abs;
    s->peak = peak;
    s->max_x = mx;
    s->max_y = my;
}

/* rms / mean, with 0 for an exact match and +inf for a non-positive mean. */
static double normalised(double rms, double mean)
{
    if (rms == 0.0)
        return 0.0;
    return mean > 0.0 ? rms / mean : INFINITY;
}

int compare_diff_main(int argc, char **argv)
{
    diff_opts o;
    diff_opts_default(&o);
    int rc = diff_parse(argc, argv, &o);
    if (rc >= 0)
        return rc;

    gi_status st = {0};
    gi_image a = {0, 0, 0, NULL}, b = {0, 0, 0, NULL};
    double t0 = gi_now();
    if ((rc = gi_image_read(o.a_path, &a, &st)) != 0 ||
        (rc = gi_image_read(o.ref_path, &b, &st)) != 0) {
        gi_error("%s", st.msg);
        goto out;
    }
    gi_verbose("read %s and %s in %.2f s", o.a_path, o.ref_path, gi_now() - t0);
    int nc = colour_channels(&a);
    if (nc != colour_channels(&b)) {
        gi_error("%s has %d channel%s but %s has %d: cannot compare %s with %s", o.a_path,
                 a.channels, a.channels == 1 ? "" : "s", o.ref_path, b.channels,
                 nc == 3 ? "colour" : "gray", nc == 3 ? "gray" : "colour");
        rc = GI_EXIT_DATA;
        goto out;
    }
    if (a.width != b.width || a.height != b.height) {
        gi_error("%s is %dx%d but %s is %dx%d", o.a_path, a.width, a.height, o.ref_path, b.width,
                 b.height);
        rc = GI_EXIT_DATA;
        goto out;
    }
    if ((rc = check_finite(&a, nc, o.a_path, &st)) != 0 ||
        (rc = check_finite(&b, nc, o.ref_path, &st)) != 0) {
        gi_error("%s", st.msg);
        goto out;
    }

    diff_stats s;
    memset(&s, 0, sizeof s);
    accumulate(&a, &b, nc, &s);
    double npix = (double)a.width * (double)a.height, nval = npix * nc;
    double sq = 0, suma = 0, sumb = 0;
    for (int c = 0; c < nc; c++) {
        sq += s.sq[c];
        suma += s.sum_a[c];
        sumb += s.sum_b[c];
    }
    double mse = sq / nval, rms = sqrt(mse), mean_a = suma / nval, mean_ref = sumb / nval;
    if (rms > 0.0 && !(mean_ref > 0.0)) {
        gi_error("%s: mean reference value is %g: nrmse (rms / mean) is undefined", o.ref_path,
                 mean_ref);
        rc = GI_EXIT_DATA;
        goto out;
    }
    double nrmse = normalised(rms, mean_ref);
    double psnr = mse == 0.0 ? INFINITY
                  : s.peak > 0.0 ? 10.0 * log10(s.peak * s.peak / mse)
                                 : -INFINITY;

    if (o.error_image) {
        if ((rc = write_error_map(o.error_image, &a, &b, nc, &st)) != 0) {
            gi_error("%s", st.msg);
            goto out;
        }
        gi_verbose("wrote %s", o.error_image);
    }

    printf("width=%d\nheight=%d\nchannels=%d\npixels=%.0f\n", a.width, a.height, nc, npix);
    printf("rms=%.9g\nnrmse=%.9g\nrelmse=%.9g\npsnr=%.9g\n", rms, nrmse, s.rel / nval, psnr);
    printf("max_abs=%.9g\nmax_abs_x=%d\nmax_abs_y=%d\n", s.max_abs, s.max_x, s.max_y);
    printf("mean_a=%.9g\nmean_ref=%.9g\n", mean_a, mean_ref);
    for (int c = 0; c < nc; c++)
        printf("rms_%s=%.9g\n", channel_name(nc, c), sqrt(s.sq[c] / npix));
    for (int c = 0; c < nc; c++)
        printf("nrmse_%s=%.9g\n", channel_name(nc, c),
               normalised(sqrt(s.sq[c] / npix), s.sum_b[c] / npix));
    {
        /* the reference's own noise, when gi-compare render estimated it */
        char nb[64];
        gi_status mst = {0};
        char *end = NULL;
        double rn = -1.0;
        if (gi_image_read_meta(o.ref_path, "noise_nrmse", nb, sizeof nb, &mst) == 0)
            rn = strtod(nb, &end);
        if (rn >= 0.0 && end && end != nb && *end == '\0' && isfinite(rn)) {
            double ex2 = nrmse * nrmse - rn * rn;
            printf("ref_noise_nrmse=%.9g\nnrmse_excess=%.9g\n", rn, ex2 > 0.0 ? sqrt(ex2) : 0.0);
        } else {
            gi_verbose("no reference noise: %s", mst.code ? mst.msg : "gi:noise_nrmse is not a number >= 0");
        }
    }
    if (fflush(stdout) != 0 || ferror(stdout)) {
        gi_error("stdout: write failed");
        rc = GI_EXIT_SYSTEM;
        goto out;
    }
    rc = GI_EXIT_OK;
    if (o.tolerance >= 0.0 && nrmse > o.tolerance) {
        gi_info("%s: nrmse %.6g exceeds tolerance %.6g", o.a_path, nrmse, o.tolerance);
        rc = GI_EXIT_DIFFER;
    }
out:
    gi_image_release(&a);
    gi_image_release(&b);
    return rc;
}
