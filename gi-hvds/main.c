/* main.c - gi-hvds command line: gathering points, gathering rays and the
 * adaptive HVDS from a scene and its .gip (docs/man/gi-hvds.md). */
#define _POSIX_C_SOURCE 200809L
#include <getopt.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "gi_container.h"
#include "gi_exit.h"
#include "gi_gip.h"
#include "gi_hvds.h"
#include "gi_log.h"
#include "gi_opt.h"
#include "gi_rt.h"
#include "gi_scene.h"

static void help(void)
{
    gi_hvds_opts d;
    gi_hvds_opts_default(&d);
    printf("usage: gi-hvds SCENE SCENE.gip -o SCENE.gih [options]\n"
           "Build the adaptive hierarchical volume (HVDS) of a scene: view-independent gathering\n"
           "points, their gathering rays, the octree and the photon/ray -> (cell, bin) maps.\n"
           "\n"
           "  -o, --output FILE        the .gih to write (required)\n"
           "  --gather rejection|kmeans  gathering-point selection (default rejection: Tabellion metric)\n"
           "  --gather-rays N|auto     rays per gathering point, rounded to a square (default auto:\n"
           "                           2^28 over the points, 256 to 1024)\n"
           "  --r-min R, --r-max R     min/max spacing of gathering points in metres\n"
           "                           (default R+ = scene diagonal / 181, R- = R+ / 5)\n"
           "  --dir-bins N             direction bins for glossy keys (default %d; recorded only:\n"
           "                           every key is diffuse in this version, see gi-hvds(1))\n"
           "  --cell-photons N         the smallest cell holds about N photons (default %g)\n"
           "  --key-photons N          a gathering ray reads the nearest coarser key holding at least\n"
           "                           N photons when its own holds fewer (default %d; 0: off)\n"
           "  --entry-keys N           such a ray reads its first bounce (the entry points' light) from\n"
           "                           the finest key holding N entry points (default %d; 0: off)\n"
           "  --no-occlusion-check     experiments: keep gathering rays at their footprint level even\n"
           "                           when that cell holds surfaces hidden from the hit (paper §9)\n"
           "  --no-leak-check          experiments: do not split cells across thin walls\n"
           "  -s, --seed S             random seed (default %llu)\n"
           "  -j, --threads T          threads (default: all cores; output is identical for any T)\n"
           "  -q, --quiet / -v, --verbose / -V, --version / -h, --help\n"
           "\n"
           "exit status: 0 success, 2 usage, 3 bad input data (including a .gip of another\n"
           "scene), 4 system failure\n",
           d.dir_bins, d.cell_photons, d.key_photons, d.entry_keys, (unsigned long long)d.seed);
}

enum { OPT_GATHER = 256, OPT_RAYS, OPT_RMIN, OPT_RMAX, OPT_DIRB, OPT_CELLP, OPT_KEYP, OPT_ENTK, OPT_NOOCC, OPT_NOLEAK };

int main(int argc, char **argv)
{
    gi_log_init("gi-hvds");
    static const struct option longopts[] = {
        {"help", no_argument, 0, 'h'},          {"version", no_argument, 0, 'V'},
        {"output", required_argument, 0, 'o'},  {"gather", required_argument, 0, OPT_GATHER},
        {"gather-rays", required_argument, 0, OPT_RAYS}, {"r-min", required_argument, 0, OPT_RMIN},
        {"r-max", required_argument, 0, OPT_RMAX}, {"dir-bins", required_argument, 0, OPT_DIRB},
        {"cell-photons", required_argument, 0, OPT_CELLP}, {"key-photons", required_argument, 0, OPT_KEYP},
        {"entry-keys", required_argument, 0, OPT_ENTK},
        {"seed", required_argument, 0, 's'},
        {"threads", required_argument, 0, 'j'}, {"quiet", no_argument, 0, 'q'},
        {"verbose", no_argument, 0, 'v'},       {"no-occlusion-check", no_argument, 0, OPT_NOOCC},
        {"no-leak-check", no_argument, 0, OPT_NOLEAK}, {0, 0, 0, 0}};
    gi_hvds_opts o;
    gi_hvds_opts_default(&o);
    const char *out = NULL;
    int threads = 0, c;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":hVo:s:j:qv", longopts, NULL)) != -1) {
        switch (c) {
        case 'h': help(); return 0;
        case 'V': gi_opt_print_version("gi-hvds"); return 0;
        case 'o': out = optarg; break;
        case OPT_GATHER:
            if (!strcmp(optarg, "rejection"))
                o.gather = GI_GATHER_REJECTION;
            else if (!strcmp(optarg, "kmeans"))
                o.gather = GI_GATHER_KMEANS;
            else
                gi_usage_error("--gather: expected 'rejection' or 'kmeans', got '%s'", optarg);
            break;
        case OPT_RAYS:
            o.gather_rays = strcmp(optarg, "auto") ? (int)gi_opt_long("--gather-rays", optarg, 1, 65535) : 0;
            break;
        case OPT_RMIN: o.r_min = (float)gi_opt_double("--r-min", optarg, 1e-9, 1e9); break;
        case OPT_RMAX: o.r_max = (float)gi_opt_double("--r-max", optarg, 1e-9, 1e9); break;
        case OPT_DIRB: o.dir_bins = (int)gi_opt_long("--dir-bins", optarg, 1, 4096); break;
        case OPT_CELLP: o.cell_photons = (float)gi_opt_double("--cell-photons", optarg, 0.01, 1e9); break;
        case OPT_KEYP: o.key_photons = (int)gi_opt_long("--key-photons", optarg, 0, 1000000); break;
        case OPT_ENTK: o.entry_keys = (int)gi_opt_long("--entry-keys", optarg, 0, 1000000); break;
        case OPT_NOOCC: o.occlusion_check = 0; break;
        case OPT_NOLEAK: o.leak_check = 0; break;
        case 's': o.seed = gi_opt_u64("--seed", optarg); break;
        case 'j': threads = gi_opt_threads(optarg); break;
        case 'q': gi_log_set_verbosity(-1); break;
        case 'v': gi_log_set_verbosity(gi_log_verbosity() + 1); break;
        case ':': gi_usage_error("option '%s' needs an argument", argv[optind - 1]);
        default:
            if (optopt && optopt < 256)
                gi_usage_error("unknown option '-%c'", optopt);
            gi_usage_error("unknown option '%s'", argv[optind - 1]);
        }
    }
    if (argc - optind != 2)
        gi_usage_error("expected SCENE and SCENE.gip, got %d arguments", argc - optind);
    if (!out)
        gi_usage_error("missing -o SCENE.gih");
    if (o.r_min > 0.0f && o.r_max > 0.0f && o.r_min > o.r_max)
        gi_usage_error("--r-min %g is larger than --r-max %g", o.r_min, o.r_max);
    const char *scene_path = argv[optind], *gip_path = argv[optind + 1];
    gi_opt_check_output(out);
    gi_container_install_signal_cleanup();

    double t0 = gi_now();
    gi_status st = {0};
    gi_scene *s = NULL;
    gi_rt *rt = NULL;
    gi_gip *gip = NULL;
    gi_hvds *h = NULL;
    int rc = gi_scene_load(scene_path, &s, &st);
    if (!rc)
        rc = gi_gip_read(gip_path, s, &gip, &st);
    uint64_t fp = gip ? gip->fingerprint : 0;
    if (!rc)
        rc = gi_rt_new(s, &rt, &st);
    double t_load = gi_now();
    if (!rc)
        rc = gi_hvds_build(s, rt, gip, fp, &o, threads, &h, &st);
    double t_build = gi_now();
    if (!rc)
        rc = gi_hvds_write(h, out, scene_path, gip_path, &st);
    if (!rc) {
        struct stat sb;
        long long size = stat(out, &sb) == 0 ? (long long)sb.st_size : -1;
        char levels[512];
        size_t n = 0;
        levels[0] = '\0';
        for (uint32_t l = 0; l <= h->depth && n < sizeof levels - 32; l++)
            if (h->cells_per_level[l])
                n += (size_t)snprintf(levels + n, sizeof levels - n, "%s%u:%u", n ? " " : "", l,
                                      h->cells_per_level[l]);
        char split[64] = "";
        if (h->split_key)
            snprintf(split, sizeof split, " and %u split-ray pairs", h->num_split);
        gi_info("%u gathering points (%s), %llu gathering rays -> %u (key, count) pairs%s, %llu moved to finer "
                "cells by the occlusion check (%llu of them back, finding no photon there), %llu to coarser keys "
                "for --key-photons %d",
                h->num_gpoints, h->opts.gather == GI_GATHER_KMEANS ? "k-means" : "rejection",
                (unsigned long long)h->num_rays, h->num_pairs, split, (unsigned long long)h->rays_descended,
                (unsigned long long)h->rays_kept_occ, (unsigned long long)h->rays_lifted, h->opts.key_photons);
        gi_info("octree: %u nodes, depth %u, leaves per level %s; %u keys", h->num_nodes, h->depth, levels,
                h->num_keys);
        gi_info("%s: %lld bytes; per photon %.2f bytes (key) + %.2f (.gip compact, read every frame); per gathering ray "
                "%.2f bytes; load %.2f s, build %.2f s, total %.2f s",
                out, size, 4.0, (double)gi_gip_compact_bytes(gip) / (double)(gip->num_photons ? gip->num_photons : 1), h->num_rays ? (h->pair_dir ? 9.0 : 6.0) * h->num_pairs / (double)h->num_rays : 0.0,
                t_load - t0, t_build - t_load, gi_now() - t0);
    }
    gi_hvds_free(h);
    gi_rt_free(rt);
    gi_gip_free(gip);
    gi_scene_free(s);
    if (rc)
        gi_die_status(&st);
    return 0;
}
