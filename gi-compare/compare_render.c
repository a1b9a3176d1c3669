/* compare_render.c - `gi-compare render` and `gi-compare sensors`: the
 * path-traced reference of a frame, and illuminance at points. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare.h"
#include "gi_image.h"
#include "gi_log.h"
#include "gi_opt.h"
#include "gi_pt.h"
#include "gi_rt.h"
#include "gi_scene.h"
#include "gi_script.h"

typedef struct job {
    const char *scene_path, *script_path, *frame_sel;
    gi_scene *scene;
    gi_script *script;
    gi_frame frame;
    gi_rt *rt;
    gi_pt *pt;
} job;

static void job_release(job *j)
{
    gi_pt_free(j->pt);
    gi_rt_free(j->rt);
    gi_frame_release(&j->frame);
    gi_script_free(j->script);
    gi_scene_free(j->scene);
}

/* Load scene and script, check the script against the scene, resolve the frame. */
static int job_load(job *j, gi_status *st)
{
    int rc = gi_scene_load(j->scene_path, &j->scene, st);
    if (rc)
        return rc;
    for (size_t i = 0; i < j->scene->num_warnings; i++)
        gi_warn("%s: %s", j->scene_path, j->scene->warnings[i]);
    if (!j->script_path) {
        if (j->frame_sel)
            return gi_status_set(st, GI_EXIT_USAGE, "--frame needs a SCRIPT");
        return gi_frame_from_scene(j->scene, &j->frame, st);
    }
    if ((rc = gi_script_parse_file(j->script_path, &j->script, st)))
        return rc;
    if ((rc = gi_script_check(j->script, j->scene, st)))
        return rc;
    int idx = 0;
    if (j->frame_sel) {
        idx = gi_script_find_frame(j->script, j->frame_sel);
        if (idx < 0)
            return gi_status_set(st, GI_EXIT_USAGE, "%s: no frame '%s' (the script has %zu frames)",
                                 j->script_path, j->frame_sel, gi_script_num_frames(j->script));
    }
    return gi_script_frame(j->script, j->scene, (size_t)idx, &j->frame, st);
}

static int job_tracer(job *j, const gi_pt_opts *po, gi_status *st)
{
    int rc = gi_rt_new(j->scene, &j->rt, st);
    if (rc)
        return rc;
    return gi_pt_new(j->rt, j->frame.lights, j->frame.num_lights, j->frame.materials,
                     j->frame.num_materials, po, &j->pt, st);
}

enum { OPT_SPP = 256, OPT_TIME, OPT_FRAME, OPT_SEED, OPT_MAXB, OPT_MINB, OPT_POINTS, OPT_SIZE };

static void render_help(void)
{
    printf("usage: gi-compare render SCENE [SCRIPT] -o OUT.exr [options]\n"
           "Path-trace the frame's camera, lights and materials (no SCRIPT: the glTF's own\n"
           "camera and lights). Output pixels are linear radiance in cd/m^2 per RGB channel.\n"
           "\n"
           "  -o, --output FILE      output EXR (float RGB; spp and time in its metadata)\n"
           "  --frame N|NAME         frame of the script (default: the first)\n"
           "  --spp N                samples per pixel (default 64)\n"
           "  --time SECONDS         stop after the pass that crosses this budget\n"
           "  --max-bounces K        cap the path length (default: none, Russian roulette)\n"
           "  --min-bounces K        leave out light that bounced fewer than K times before the\n"
           "                         visible surface (default 0; 1: indirect light only)\n"
           "  --size WxH             override the frame's resolution\n"
           "  -s, --seed S           random seed (default 1)\n"
           "  -j, --threads T        threads (default: all cores; the result does not depend on it)\n"
           "  -q, --quiet / -v, --verbose\n");
}

int compare_render_main(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"help", no_argument, 0, 'h'},          {"output", required_argument, 0, 'o'},
        {"spp", required_argument, 0, OPT_SPP}, {"time", required_argument, 0, OPT_TIME},
        {"frame", required_argument, 0, OPT_FRAME}, {"seed", required_argument, 0, 's'},
        {"threads", required_argument, 0, 'j'}, {"max-bounces", required_argument, 0, OPT_MAXB},
        {"min-bounces", required_argument, 0, OPT_MINB}, {"size", required_argument, 0, OPT_SIZE}, {"quiet", no_argument, 0, 'q'},
        {"verbose", no_argument, 0, 'v'},       {0, 0, 0, 0}};
    job j;
    memset(&j, 0, sizeof j);
    gi_pt_opts po;
    gi_pt_opts_default(&po);
    const char *out = NULL;
    int spp = 64, sw = 0, sh = 0;
    double budget = 0.0;
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "ho:s:j:qv", longopts, NULL)) != -1) {
        switch (c) {
        case 'h': render_help(); return 0;
        case 'o': out = optarg; break;
        case OPT_SPP: spp = (int)gi_opt_long("--spp", optarg, 1, 1 << 24); break;
        case OPT_TIME: budget = gi_opt_double("--time", optarg, 1e-3, 1e9); break;
        case OPT_FRAME: j.frame_sel = optarg; break;
        case 's': po.seed = gi_opt_u64("--seed", optarg); break;
        case 'j': po.threads = gi_opt_threads(optarg); break;
        case OPT_MAXB: po.max_bounces = (int)gi_opt_long("--max-bounces", optarg, 0, 1 << 20); break;
        case OPT_MINB: po.min_bounces = (int)gi_opt_long("--min-bounces", optarg, 0, 1 << 20); break;
        case OPT_SIZE:
            if (sscanf(optarg, "%dx%d", &sw, &sh) != 2 || sw < 1 || sh < 1 || sw > 16384 || sh > 16384)
                gi_usage_error("--size: expected WxH such as 640x480, got '%s'", optarg);
            break;
        case 'q': gi_log_set_verbosity(-1); break;
        case 'v': gi_log_set_verbosity(gi_log_verbosity() + 1); break;
        default: gi_usage_error("bad option");
        }
    }
    if (po.max_bounces >= 0 && po.min_bounces > po.max_bounces)
        gi_usage_error("--min-bounces %d is above --max-bounces %d: no light would be left", po.min_bounces,
                       po.max_bounces);
    int npos = argc - optind;
    if (npos < 1 || npos > 2)
        gi_usage_error("expected SCENE [SCRIPT], got %d arguments", npos);
    if (!out)
        gi_usage_error("missing -o OUT.exr");
    gi_opt_check_output(out); /* before the render, which can take hours */
    j.scene_path = argv[optind];
    j.script_path = npos == 2 ? argv[optind + 1] : NULL;
    po.progress = gi_log_verbosity() >= 0;

    gi_status st = {0};
    int rc = job_load(&j, &st);
    if (!rc && !j.frame.has_camera)
        rc = gi_status_set(&st, GI_EXIT_DATA,
                           "%s: frame '%s' has no camera (give one with 'camera' in the script)",
                           j.script_path ? j.script_path : j.scene_path, j.frame.name);
    if (!rc)
        rc = job_tracer(&j, &po, &st);
    if (rc) {
        job_release(&j);
        gi_die_status(&st);
    }
    int w = sw ? sw : j.frame.width, h = sh ? sh : j.frame.height;
    gi_image img = {0};
    if ((rc = gi_image_init(&img, w, h, 3, &st))) {
        job_release(&j);
        gi_die_status(&st);
    }
    gi_pt_render_result res;
    rc = gi_pt_render(j.pt, &j.frame.camera, w, h, spp, budget, img.pixels, &res, &st);
    if (!rc) {
        char sppbuf[32], secbuf[32], seedbuf[32], hashbuf[32], bouncebuf[32], minbbuf[32], nbuf[32], nrbuf[32];
        snprintf(sppbuf, sizeof sppbuf, "%d", res.spp);
        snprintf(secbuf, sizeof secbuf, "%.3f", res.seconds);
        snprintf(seedbuf, sizeof seedbuf, "%llu", (unsigned long long)po.seed);
        snprintf(hashbuf, sizeof hashbuf, "%016llx", (unsigned long long)j.scene->hash);
        snprintf(bouncebuf, sizeof bouncebuf, "%d", po.max_bounces);
        snprintf(minbbuf, sizeof minbbuf, "%d", po.min_bounces);
        snprintf(nbuf, sizeof nbuf, "%.6g", res.noise_rms);
        snprintf(nrbuf, sizeof nrbuf, "%.6g", res.noise_nrmse);
        gi_image_meta meta[] = {
            {"tool", "gi-compare render"}, {"spp", sppbuf},          {"seconds", secbuf},
            {"seed", seedbuf},             {"scene_hash", hashbuf},  {"frame", j.frame.name},
            {"max_bounces", bouncebuf},    {"min_bounces", minbbuf}, {"units", "cd/m^2"},
            {"noise_rms", nbuf},           {"noise_nrmse", nrbuf},
        };
        /* (the noise last: left out below 2 spp, where there is no estimate) */
        size_t nmeta = sizeof meta / sizeof meta[0] - (res.noise_nrmse >= 0.0 ? 0 : 2);
        rc = gi_image_write_exr(out, &img, meta, nmeta, &st);
    }
    if (!rc) {
        if (res.dropped)
            gi_warn("%llu non-finite samples were discarded", (unsigned long long)res.dropped);
        gi_info("rendered frame '%s' %dx%d, %d spp in %.2f s (%.2f Mrays/s, %.3f us per sample) -> %s",
                j.frame.name, w, h, res.spp, res.seconds, res.rays / res.seconds * 1e-6,
                res.seconds * 1e6 / ((double)w * h * res.spp), out);
        if (res.noise_nrmse >= 0.0)
            gi_info("its own noise, estimated from its two halves: nrmse %.4f (an image compared with it "
                    "cannot measure below this)",
                    res.noise_nrmse);
    }
    gi_image_release(&img);
    job_release(&j);
    if (rc)
        gi_die_status(&st);
    return 0;
}

/* Points file: one "x y z nx ny nz" per line; '#' comments and blank lines allowed. */
static int read_points(const char *path, float **pts, size_t *n, gi_status *st)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot open", path);
    size_t cap = 64, cnt = 0;
    float *p = malloc(cap * 6 * sizeof *p);
    char line[4096];
    int lineno = 0, rc = 0;
    while (p && fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        size_t ll = strlen(line);
        while (ll > 0 && (line[ll - 1] == '\n' || line[ll - 1] == '\r' || line[ll - 1] == ' ' ||
                          line[ll - 1] == '\t'))
            line[--ll] = '\0';
        char *s = line;
        while (*s == ' ' || *s == '\t' || *s == '\r' || *s == '\n')
            s++;
        if (!*s)
            continue;
        if (cnt == cap) {
            cap *= 2;
            float *q = realloc(p, cap * 6 * sizeof *p);
            if (!q) {
                free(p);
                p = NULL;
                break;
            }
            p = q;
        }
        for (int k = 0; k < 6; k++) {
            char *end;
            while (*s == ' ' || *s == '\t')
                s++;
            errno = 0;
            double v = strtod(s, &end);
            if (end == s || errno || !isfinite(v)) {
                rc = gi_status_set(st, GI_EXIT_DATA, "%s:%d:%d: expected 6 numbers (x y z nx ny nz), "
                                   "number %d is missing or bad", path, lineno, (int)(s - line) + 1, k + 1);
                goto done;
            }
            p[6 * cnt + k] = (float)v;
            s = end;
        }
        while (*s == ' ' || *s == '\t' || *s == '\r' || *s == '\n')
            s++;
        if (*s) {
            rc = gi_status_set(st, GI_EXIT_DATA, "%s:%d:%d: unexpected '%.20s' after 6 numbers", path,
                               lineno, (int)(s - line) + 1, s);
            goto done;
        }
        float nl = sqrtf(p[6 * cnt + 3] * p[6 * cnt + 3] + p[6 * cnt + 4] * p[6 * cnt + 4] +
                         p[6 * cnt + 5] * p[6 * cnt + 5]);
        if (!(nl > 0.0f)) {
            rc = gi_status_set(st, GI_EXIT_DATA, "%s:%d: the normal is the zero vector", path, lineno);
            goto done;
        }
        for (int k = 3; k < 6; k++)
            p[6 * cnt + k] /= nl;
        cnt++;
    }
    if (!p)
        rc = gi_status_set(st, GI_EXIT_SYSTEM, "%s: out of memory", path);
    else if (ferror(f))
        rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: read error", path);
    else if (cnt == 0)
        rc = gi_status_set(st, GI_EXIT_DATA, "%s: no points (expected lines of x y z nx ny nz)", path);
done:
    fclose(f);
    if (rc) {
        free(p);
        return rc;
    }
    *pts = p;
    *n = cnt;
    return 0;
}

int compare_sensors_main(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"help", no_argument, 0, 'h'},           {"points", required_argument, 0, OPT_POINTS},
        {"spp", required_argument, 0, OPT_SPP},  {"frame", required_argument, 0, OPT_FRAME},
        {"seed", required_argument, 0, 's'},     {"threads", required_argument, 0, 'j'},
        {"max-bounces", required_argument, 0, OPT_MAXB}, {"min-bounces", required_argument, 0, OPT_MINB},
        {"quiet", no_argument, 0, 'q'},
        {"verbose", no_argument, 0, 'v'},        {0, 0, 0, 0}};
    job j;
    memset(&j, 0, sizeof j);
    gi_pt_opts po;
    gi_pt_opts_default(&po);
    const char *points = NULL;
    int spp = 1024;
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "hs:j:qv", longopts, NULL)) != -1) {
        switch (c) {
        case 'h':
            printf("usage: gi-compare sensors SCENE [SCRIPT] --points FILE [options]\n"
                   "Illuminance in lux (direct + indirect, hemisphere above the normal) at points.\n"
                   "FILE has one 'x y z nx ny nz' per line (metres). Prints one line per point:\n"
                   "'E_lux stderr_lux' (luminance of the RGB illuminance; its standard error).\n"
                   "\n"
                   "  --points FILE          the points (required)\n"
                   "  --frame N|NAME         frame of the script (default: the first)\n"
                   "  --spp N                samples per point (default 1024)\n"
                   "  --max-bounces K        cap the path length (default: none)\n"
                   "  --min-bounces K        leave out light that bounced fewer than K times (default 0;\n"
                   "                         1: the indirect illuminance gi-relight's gathering points hold)\n"
                   "  -s, --seed S / -j, --threads T / -q / -v\n");
            return 0;
        case OPT_POINTS: points = optarg; break;
        case OPT_SPP: spp = (int)gi_opt_long("--spp", optarg, 2, 1 << 28); break;
        case OPT_FRAME: j.frame_sel = optarg; break;
        case 's': po.seed = gi_opt_u64("--seed", optarg); break;
        case 'j': po.threads = gi_opt_threads(optarg); break;
        case OPT_MAXB: po.max_bounces = (int)gi_opt_long("--max-bounces", optarg, 0, 1 << 20); break;
        case OPT_MINB: po.min_bounces = (int)gi_opt_long("--min-bounces", optarg, 0, 1 << 20); break;
        case 'q': gi_log_set_verbosity(-1); break;
        case 'v': gi_log_set_verbosity(gi_log_verbosity() + 1); break;
        default: gi_usage_error("bad option");
        }
    }
    if (po.max_bounces >= 0 && po.min_bounces > po.max_bounces)
        gi_usage_error("--min-bounces %d is above --max-bounces %d: no light would be left", po.min_bounces,
                       po.max_bounces);
    int npos = argc - optind;
    if (npos < 1 || npos > 2)
        gi_usage_error("expected SCENE [SCRIPT], got %d arguments", npos);
    if (!points)
        gi_usage_error("missing --points FILE");
    j.scene_path = argv[optind];
    j.script_path = npos == 2 ? argv[optind + 1] : NULL;
    po.progress = gi_log_verbosity() >= 0;
    gi_status st = {0};
    float *pts = NULL;
    size_t n = 0;
    int rc = read_points(points, &pts, &n, &st);
    if (!rc)
        rc = job_load(&j, &st);
    if (!rc)
        rc = job_tracer(&j, &po, &st);
    double *lux = NULL, *err = NULL;
    if (!rc) {
        lux = calloc(n, sizeof *lux);
        err = calloc(n, sizeof *err);
        if (!lux || !err)
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory");
    }
    if (!rc)
        rc = gi_pt_sensors(j.pt, pts, n, spp, lux, err, &st);
    if (!rc) {
        for (size_t i = 0; i < n; i++)
            printf("%.9g %.9g\n", lux[i], err[i]);
        if (fflush(stdout))
            rc = gi_status_errno(&st, GI_EXIT_SYSTEM, "writing stdout");
    }
    free(pts);
    free(lux);
    free(err);
    job_release(&j);
    if (rc)
        gi_die_status(&st);
    return 0;
}
