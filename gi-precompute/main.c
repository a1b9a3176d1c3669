/* main.c - gi-precompute command line: entry points and light-independent
 * photon paths of a scene, written as a .gip (docs/man/gi-precompute.md). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gi_container.h"
#include "gi_exit.h"
#include "gi_gip.h"
#include "gi_log.h"
#include "gi_opt.h"
#include "gi_photon.h"
#include "gi_rt.h"
#include "gi_scene.h"

typedef struct precompute_opts {
    const char *scene;
    const char *output;
    int threads;
    int verbosity;
    int region_opts_given; /* a --region-* option was given */
    gi_gip_opts gip;
} precompute_opts;

enum {
    OPT_PHOTONS = 256,
    OPT_MAXB,
    OPT_FIXED,
    OPT_REGION,
    OPT_RGRID,
    OPT_RVIS,
    OPT_RSKEW,
};

static void usage(void)
{
    printf("usage: gi-precompute SCENE -o OUT.gip [options]\n"
           "Place entry points on the surfaces of SCENE (glTF 2.0) and trace light-independent\n"
           "photon paths from them; gi-hvds and gi-relight read the result.\n"
           "\n"
           "output:\n"
           "  -o, --output FILE        the .gip to write (required)\n"
           "photon paths:\n"
           "  --photons N              photon vertices wanted, entry points included\n"
           "                           (default 1000000)\n"
           "  --max-bounces K          at most K vertices after the entry point (default: no cap,\n"
           "                           Russian roulette only; 3 reproduces the paper)\n"
           "  --fixed-material NAME    sample this material by its BRDF instead of the cosine\n"
           "                           (repeatable; for materials no variant will change)\n"
           "entry-point refinement (paper 5.1):\n"
           "  --region XMIN YMIN ZMIN XMAX YMAX ZMAX\n"
           "                           box where lights will be placed, metres (also one argument\n"
           "                           with commas: --region=0,2,0,5,2.5,5); default: none\n"
           "  --region-grid N          grid points along the region's longest axis (default 4)\n"
           "  --region-min-visible N   condition 1: entry points each grid point must see\n"
           "                           (default 8192)\n"
           "  --region-max-skew X      condition 2: largest skew of their directions (default 1)\n"
           "run:\n"
           "  -s, --seed S             random seed (default 1)\n"
           "  -j, --threads T          threads (default 0: all cores; the output does not depend\n"
           "                           on it)\n"
           "  -q, --quiet              errors only\n"
           "  -v, --verbose            stage progress and timings (repeatable)\n"
           "  -h, --help               this text\n"
           "  -V, --version            version, commit and Embree version\n"
           "\n"
           "exit status: 0 success, 2 usage (also an unknown --fixed-material), 3 bad input data,\n"
           "4 system failure\n");
}

/* Six numbers of --region: one argument with commas or spaces, or the option
 * argument and the five arguments after it (advancing optind). */
static void parse_region(int argc, char **argv, gi_gip_opts *g)
{
    const char *parts[6];
    char buf[1024];
    int n = 0;
    if (strpbrk(optarg, ", \t")) {
        if (strlen(optarg) >= sizeof buf)
            gi_usage_error("--region: argument too long");
        strcpy(buf, optarg);
        for (char *tok = strtok(buf, ", \t"); tok; tok = strtok(NULL, ", \t")) {
            if (n == 6)
                gi_usage_error("--region: expected 6 numbers, got more in '%s'", optarg);
            parts[n++] = tok;
        }
    } else {
        parts[n++] = optarg;
        while (n < 6 && optind < argc)
            parts[n++] = argv[optind++];
    }
    if (n != 6)
        gi_usage_error("--region: expected 6 numbers XMIN YMIN ZMIN XMAX YMAX ZMAX, got %d", n);
    float v[6];
    for (int i = 0; i < 6; i++)
        v[i] = (float)gi_opt_double("--region", parts[i], -1e30, 1e30);
    for (int k = 0; k < 3; k++)
        if (v[k] > v[k + 3])
            gi_usage_error("--region: minimum %g is above maximum %g on axis %c", (double)v[k],
                           (double)v[k + 3], "xyz"[k]);
    g->has_region = 1;
    memcpy(g->region_min, v, sizeof g->region_min);
    memcpy(g->region_max, v + 3, sizeof g->region_max);
}

static void add_fixed(gi_gip_opts *g, const char *name)
{
    if (strlen(name) == 0 || strlen(name) >= GI_NAME_MAX)
        gi_usage_error("--fixed-material: name '%s' is empty or longer than %d bytes", name,
                       GI_NAME_MAX - 1);
    for (size_t i = 0; i < g->num_fixed; i++)
        if (strcmp(g->fixed[i], name) == 0)
            gi_usage_error("--fixed-material '%s' given twice", name);
    char(*nf)[GI_NAME_MAX] = realloc(g->fixed, (g->num_fixed + 1) * sizeof *g->fixed);
    if (!nf)
        gi_die(GI_EXIT_SYSTEM, "out of memory");
    g->fixed = nf;
    strcpy(g->fixed[g->num_fixed++], name);
}

static void parse_args(int argc, char **argv, precompute_opts *o)
{
    static const struct option longopts[] = {
        {"output", required_argument, 0, 'o'},
        {"photons", required_argument, 0, OPT_PHOTONS},
        {"max-bounces", required_argument, 0, OPT_MAXB},
        {"fixed-material", required_argument, 0, OPT_FIXED},
        {"region", required_argument, 0, OPT_REGION},
        {"region-grid", required_argument, 0, OPT_RGRID},
        {"region-min-visible", required_argument, 0, OPT_RVIS},
        {"region-max-skew", required_argument, 0, OPT_RSKEW},
        {"seed", required_argument, 0, 's'},
        {"threads", required_argument, 0, 'j'},
        {"quiet", no_argument, 0, 'q'},
        {"verbose", no_argument, 0, 'v'},
        {"help", no_argument, 0, 'h'},
        {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0}};
    memset(o, 0, sizeof *o);
    gi_gip_opts_default(&o->gip);
    int quiet = 0, verbose = 0, c;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":o:s:j:qvhV", longopts, NULL)) != -1) {
        switch (c) {
        case 'o': o->output = optarg; break;
        case OPT_PHOTONS:
            o->gip.photons = gi_opt_u64("--photons", optarg);
            if (o->gip.photons < 1 || o->gip.photons > (uint64_t)1e12)
                gi_usage_error("--photons: %s is out of range [1, 1e12]", optarg);
            break;
        case OPT_MAXB: o->gip.max_bounces = (int)gi_opt_long("--max-bounces", optarg, 0, GI_GIP_MAX_PATH - 1); break;
        case OPT_FIXED: add_fixed(&o->gip, optarg); break;
        case OPT_REGION: parse_region(argc, argv, &o->gip); break;
        case OPT_RGRID:
            o->gip.region_grid = (int)gi_opt_long("--region-grid", optarg, 1, 64);
            o->region_opts_given = 1;
            break;
        case OPT_RVIS:
            o->gip.region_min_visible =
                (uint32_t)gi_opt_long("--region-min-visible", optarg, 0, 1L << 30);
            o->region_opts_given = 1;
            break;
        case OPT_RSKEW:
            o->gip.region_max_skew = (float)gi_opt_double("--region-max-skew", optarg, 0.0, 1e6);
            o->region_opts_given = 1;
            break;
        case 's': o->gip.seed = gi_opt_u64("--seed", optarg); break;
        case 'j': o->threads = gi_opt_threads(optarg); break;
        case 'q': quiet = 1; break;
        case 'v': verbose++; break;
        case 'h': usage(); exit(0);
        case 'V': gi_opt_print_version("gi-precompute"); exit(0);
        case ':': gi_usage_error("option '%s' needs an argument", argv[optind - 1]);
        default:
            if (optopt && optopt < 256)
                gi_usage_error("unknown option '-%c'", optopt);
            gi_usage_error("unknown option '%s'", argv[optind - 1]);
        }
    }
    if (quiet && verbose)
        gi_usage_error("-q and -v contradict each other");
    o->verbosity = quiet ? -1 : verbose;
    if (optind >= argc)
        gi_usage_error("missing SCENE");
    if (argc - optind > 1)
        gi_usage_error("one SCENE expected, got '%s' too", argv[optind + 1]);
    o->scene = argv[optind];
    if (!o->output)
        gi_usage_error("missing -o/--output");
    if (o->region_opts_given && !o->gip.has_region)
        gi_usage_error("--region-grid, --region-min-visible and --region-max-skew need --region");
    if (strcmp(o->output, o->scene) == 0)
        gi_usage_error("-o '%s' would overwrite the scene", o->output);
}

int main(int argc, char **argv)
{
    gi_log_init("gi-precompute");
    precompute_opts o;
    parse_args(argc, argv, &o);
    gi_log_set_verbosity(o.verbosity);
    gi_container_install_signal_cleanup();
    gi_opt_check_output(o.output);

    double t0 = gi_now();
    gi_status st = {0};
    gi_scene *s = NULL;
    gi_rt *rt = NULL;
    gi_gip *g = NULL;
    if (gi_scene_load(o.scene, &s, &st))
        gi_die_status(&st);
    for (size_t i = 0; i < s->num_warnings; i++)
        gi_warn("%s: %s", o.scene, s->warnings[i]);
    if (o.gip.has_region) {
        int outside = 0;
        for (int k = 0; k < 3; k++)
            outside |= o.gip.region_max[k] < s->bbox_min[k] || o.gip.region_min[k] > s->bbox_max[k];
        if (outside)
            gi_warn("--region lies outside the scene's bounding box");
    }
    gi_verbose("%s: %zu triangles, %zu materials, %.4g m^2, loaded in %.2f s", o.scene,
               s->num_triangles, s->num_materials, s->surface_area, gi_now() - t0);
    if (gi_rt_new(s, &rt, &st))
        gi_die_status(&st);
    double t1 = gi_now();
    if (gi_photon_precompute(s, rt, &o.gip, o.threads, &g, &st))
        gi_die_status(&st);
    double t2 = gi_now();
    if (gi_gip_write(g, o.output, s, o.scene, &st))
        gi_die_status(&st);
    double t3 = gi_now();

    struct stat sb;
    double mb = stat(o.output, &sb) == 0 ? (double)sb.st_size / 1e6 : 0.0;
    double P = (double)g->num_photons, N = (double)g->num_entries;
    double tp = t2 - t1 > 0.0 ? t2 - t1 : 1e-9;
    gi_info("%s: %" PRIu32 " entry points (%" PRIu32 " uniform, %" PRIu32 " from %" PRIu32
            " region batches), %" PRIu64 " photons, mean path length %.3f, %.1f%% of paths "
            "escaped, %" PRIu64 " triangles skipped; precompute %.2f s (%.0f photons/s), "
            "total %.2f s; %.1f MB: compact %.2f B/photon, detail %.2f B/photon",
            o.output, g->num_entries, g->num_uniform, g->num_entries - g->num_uniform,
            g->region_batches, g->num_photons, P / N, 100.0 * (double)g->escaped / N,
            g->skipped_degenerate, t2 - t1, P / tp, t3 - t0, mb,
            (double)gi_gip_compact_bytes(g) / P, (double)gi_gip_detail_bytes(g) / P);
    gi_verbose("%s: written in %.2f s; paths: %" PRIu64 " escaped, %" PRIu64 " absorbed, %" PRIu64
               " ended by roulette, %" PRIu64 " capped",
               o.output, t3 - t2, g->escaped, g->absorbed, g->roulette, g->capped);
    gi_gip_free(g);
    gi_rt_free(rt);
    gi_scene_free(s);
    free(o.gip.fixed);
    return 0;
}
