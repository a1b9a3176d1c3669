/* main.c - gi-relight command line: renders the frames of a variant script
 * from a scene, its .gip and its .gih (docs/man/gi-relight.md). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gi_container.h"
#include "gi_exit.h"
#include "gi_brdf.h"
#include "gi_emit.h"
#include "gi_gbuffer.h"
#include "gi_gip.h"
#include "gi_hvds.h"
#include "gi_image.h"
#include "gi_log.h"
#include "gi_opt.h"
#include "gi_relight.h"
#include "gi_rt.h"
#include "gi_scene.h"
#include "gi_script.h"
#include "gi_shade.h"

static void help(void)
{
    printf("usage: gi-relight SCENE SCENE.gip SCENE.gih SCRIPT -o OUTDIR [options]\n"
           "Render every frame of a variant script with global illumination: direct light with\n"
           "exact shadows, indirect light from the precomputed photon paths through the HVDS.\n"
           "Writes OUTDIR/NAME.exr (linear cd/m^2 per RGB channel) for each frame.\n"
           "\n"
           "  -o, --output DIR        output directory (created if missing)\n"
           "  --frames A-B            render frames A..B only (0-based, inclusive; or one index or name)\n"
           "  --png                   also write a tone-mapped sRGB NAME.png\n"
           "  --exposure EV           PNG exposure: display = 1 - exp(-L * 2^EV) (default 0)\n"
           "  --timings FILE.csv      one row per frame: the stages of the paper's Table 1\n"
           "  --area-samples N        jittered samples per area light per pixel (default 16; also\n"
           "                          per pixel for the emissive surfaces, which light the scene;\n"
           "                          rectangles and meshes of <= 64 triangles: the shadow only)\n"
           "  --ss N                  N x N samples per pixel (default 1)\n"
           "  --aa N                  with --ss 1, N x N samples in pixels on geometric edges and\n"
           "                          (N+2) x (N+2) on hard shadow edges (odd N; 1 turns it off;\n"
           "                          default: 3 for 200k pixels or more, 7 below)\n"
           "  --coverage N            weigh an edge pixel's samples by the share of the pixel each\n"
           "                          sees, from N x N camera rays (light moves cost the same;\n"
           "                          default: aa + 4; 1 gives every sample an equal share)\n"
           "  --edge-refine, --no-edge-refine\n"
           "                          an edge pixel whose samples see a light's irradiance span more\n"
           "                          than 8x its mean over the image (sunlit against shade) gets 16\n"
           "                          more samples of it, found when first needed (default: on)\n"
           "  --refine-contrast X     that multiple of the mean (default 8; 1 refines ~2.5x as many\n"
           "                          pixels for little more accuracy)\n"
           "  --glossy-rays N         a metal's pixels reflect indirect light from N rays of its lobe\n"
           "                          (every other pixel of every other row, traced once per view and\n"
           "                          roughness, averaged over ~7 x 7 pixels of its surface; default\n"
           "                          36, 16 of them for a lobe narrower than that window: at\n"
           "                          640x480, roughness <= 0.15; 0: the gathering points' linear fit)\n"
           "  --glossy-stride N       of those, the pixels whose x and y are multiples of N gather\n"
           "                          (1-4, default 2; 1: every pixel, for final frames; the time\n"
           "                          of the gathers goes about as 1 / N^2); rough lobes\n"
           "                          (at 640x480, roughness >= 0.25) at 2N, over a wider window\n"
           "  --glossy-min-ks X       only lobes with ks >= X gather so (metals: ks ~ base colour);\n"
           "                          the others, dielectrics (ks 0.04) among them, take the linear\n"
           "                          fit (default 0.1; 0: every glossy lobe gathers)\n"
           "  --near-field R|auto     light that lit surfaces within R metres of a pixel throw onto it\n"
           "                          (first bounce, point, spot and sun lights) computed at the\n"
           "                          pixel, not interpolated between gathering points: brighter,\n"
           "                          truer concave creases beside lit faces (default auto: 0.65\n"
           "                          times the .gih's R+; 0 turns it off)\n"
           "  --near-stride N|auto    the pixels whose x and y are multiples of N trace the near\n"
           "                          field's rays, and each pixel takes the mean of the 3 x 3 of\n"
           "                          them around it on its surface (1-4; default auto: 2, and\n"
           "                          then every pixel beside one whose rays found something,\n"
           "                          with the mean over 3 x 3 pixels: 1 where there is a near\n"
           "                          field)\n"
           "  --lift-cap C            a gathering point's rays that --key-photons lifted to a coarser\n"
           "                          key read their later bounces there at most C times the mean of\n"
           "                          its other rays (default 1.5; 0: as the key holds them)\n");
    fputs("  --fresh-paths N|auto    at every light change, trace N photon paths from the lit\n"
           "                          entry points, chosen in proportion to their flux, and weigh\n"
           "                          them with the .gip's later bounces by effective sample size:\n"
           "                          less noise where the light is uneven (a lamp near a wall, a\n"
           "                          spot, a low sun), for 0.15-2 ms per 1000 paths on 2 cores;\n"
           "                          for final frames. auto: a pilot of 16384 paths, then as\n"
           "                          many as reach an effective sample size of 131072 with the\n"
           "                          .gip's (at most 4194304; Sponza: ~100 k under its arcade\n"
           "                          lamps, 0.6-1.6 M under its sun, 0.1-0.25 s) (default 0: off)\n"
          "  --fresh-view on|off     start the fresh paths ten times as often from the lit entry\n"
          "                          points on surfaces the last frame's gathering points see as\n"
          "                          from the others (weighted back: the same light on average);\n"
          "                          a sun on a building's roof and outer walls sends few paths\n"
          "                          in at its windows (default on; no effect on the first frame)\n",
          stdout);
    fputs("  --interp linear|mean    a pixel's indirect light from its gathering points: half their\n"
           "                          weighted mean, half a weighted linear fit (default), or the mean\n"
           "  --tex-filter on|off     average textures over each sample's pixel footprint (default on)\n"
           "  --only direct|indirect  render one part of the light: direct (compare with gi-compare\n"
           "                          render --max-bounces 0) or indirect (--min-bounces 1)\n"
           "  --gpoints               also write OUTDIR/NAME.gpoints: each gathering point's position,\n"
           "                          normal and indirect illuminance (a points file for\n"
           "                          gi-compare sensors --min-bounces 1)\n"
           "  -s, --seed S            random seed (default 1)\n"
           "  -j, --threads T         threads (default: all cores)\n"
           "  -q, --quiet / -v, --verbose / -V, --version / -h, --help\n"
           "\n"
           "exit status: 0 success, 2 usage, 3 bad input data (bad script, a .gip/.gih of another\n"
           "scene), 4 system failure\n", stdout);
}

enum { OPT_FRAMES = 256, OPT_PNG, OPT_EXPO, OPT_TIMINGS, OPT_AREA, OPT_SS, OPT_TEXF, OPT_AA, OPT_EREF, OPT_NOEREF, OPT_RCON, OPT_GPTS, OPT_ONLY, OPT_COV, OPT_GRAYS, OPT_GMINKS, OPT_GSTRIDE, OPT_INTERP, OPT_NEAR, OPT_NSTRIDE, OPT_LCAP, OPT_FRESH, OPT_FVIEW };

/* gi_shade's glossy gathers map a ray's hit to the key it reads */
static void gather_points(void *ctx, const uint32_t *idx, size_t n) { gi_relight_gather((gi_relight *)ctx, idx, n); }

static void key_at(const void *ctx, size_t n, const float *p, const float *nrm, uint32_t *out)
{
    gi_relight_keys_at((const gi_relight *)ctx, n, p, nrm, out);
}

static int lights_equal(const gi_light *a, size_t na, const gi_light *b, size_t nb)
{
    if (na != nb)
        return 0;
    for (size_t i = 0; i < na; i++) {
        if (a[i].enabled != b[i].enabled)
            return 0;
        if (a[i].enabled && memcmp(&a[i], &b[i], sizeof a[i]))
            return 0;
    }
    return 1;
}

static int write_png(const char *path, const float *rgb, int w, int h, float ev, gi_status *st)
{
    gi_image im = {0};
    int rc = gi_image_init(&im, w, h, 3, st);
    if (rc)
        return rc;
    float k = exp2f(ev);
    for (size_t i = 0; i < 3 * (size_t)w * (size_t)h; i++)
        im.pixels[i] = 1.0f - expf(-fmaxf(rgb[i], 0.0f) * k);
    rc = gi_image_write_png_srgb(path, &im, 1.0f, st);
    gi_image_release(&im);
    return rc;
}

/* The gathering points of a frame as a gi-compare sensors points file: one
 * 'x y z nx ny nz' line each, the irradiance after a comment mark. Written
 * beside path and renamed, so path is complete or untouched. */
static int write_gpoints(const char *path, const gi_relight *rl, const gi_hvds *h, const float *e, const char *frame,
                         gi_status *st)
{
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f)
        return gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot create", tmp);
    fprintf(f, "# gi-relight gathering points of frame '%s': %u points\n"
               "# x y z (m)  nx ny nz  # E_lux (luminance of the indirect illuminance)  E_r E_g E_b  radius_m  index"
               "  lifted_lux (of E_lux, read as later bounces from lifted keys)  later_lux (of E_lux, all later bounces)\n",
            frame, h->num_gpoints);
    for (uint32_t i = 0; i < h->num_gpoints; i++) {
        const gi_gpoint *g = &h->gpoints[i];
        const float *x = e + 3 * (size_t)i;
        float lf[3], later;
        gi_relight_gpoint_lifted(rl, i, lf, &later);
        fprintf(f, "%.7g %.7g %.7g %.6f %.6f %.6f # %.6g %.6g %.6g %.6g %.4g %u %.6g %.6g\n", g->pos[0], g->pos[1], g->pos[2],
                g->nrm[0], g->nrm[1], g->nrm[2], gi_luminance(gi_v3p(x)), x[0], x[1], x[2], g->radius, i,
                gi_luminance(gi_v3p(lf)), later);
    }
    int bad = ferror(f);
    if (fclose(f) || bad) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: write failed", tmp);
        remove(tmp);
        return rc;
    }
    if (rename(tmp, path)) {
        int rc = gi_status_errno(st, GI_EXIT_SYSTEM, "%s: cannot rename to %s", tmp, path);
        remove(tmp);
        return rc;
    }
    return 0;
}

int main(int argc, char **argv)
{
    gi_log_init("gi-relight");
    static const struct option longopts[] = {
        {"help", no_argument, 0, 'h'},           {"version", no_argument, 0, 'V'},
        {"output", required_argument, 0, 'o'},   {"frames", required_argument, 0, OPT_FRAMES},
        {"png", no_argument, 0, OPT_PNG},        {"exposure", required_argument, 0, OPT_EXPO},
        {"timings", required_argument, 0, OPT_TIMINGS}, {"area-samples", required_argument, 0, OPT_AREA},
        {"ss", required_argument, 0, OPT_SS},    {"tex-filter", required_argument, 0, OPT_TEXF},
        {"aa", required_argument, 0, OPT_AA}, {"coverage", required_argument, 0, OPT_COV},    {"edge-refine", no_argument, 0, OPT_EREF}, {"no-edge-refine", no_argument, 0, OPT_NOEREF}, {"refine-contrast", required_argument, 0, OPT_RCON},
        {"glossy-rays", required_argument, 0, OPT_GRAYS}, {"glossy-min-ks", required_argument, 0, OPT_GMINKS}, {"glossy-stride", required_argument, 0, OPT_GSTRIDE}, {"interp", required_argument, 0, OPT_INTERP},
        {"near-field", required_argument, 0, OPT_NEAR},
        {"near-stride", required_argument, 0, OPT_NSTRIDE}, {"lift-cap", required_argument, 0, OPT_LCAP},
        {"fresh-paths", required_argument, 0, OPT_FRESH},
        {"fresh-view", required_argument, 0, OPT_FVIEW},
        {"gpoints", no_argument, 0, OPT_GPTS},   {"only", required_argument, 0, OPT_ONLY},
        {"seed", required_argument, 0, 's'},
        {"threads", required_argument, 0, 'j'},  {"quiet", no_argument, 0, 'q'},
        {"verbose", no_argument, 0, 'v'},        {0, 0, 0, 0}};
    const char *outdir = NULL, *frames = NULL, *timings = NULL;
    int png = 0, gpts = 0, threads = 0, c;
    float ev = 0.0f, lift_cap = GI_RELIGHT_LIFT_CAP;
    long fresh_paths = 0;
    int fresh_view = 1;
    gi_shade_opts so;
    gi_shade_opts_default(&so);
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":hVo:s:j:qv", longopts, NULL)) != -1) {
        switch (c) {
        case 'h': help(); return 0;
        case 'V': gi_opt_print_version("gi-relight"); return 0;
        case 'o': outdir = optarg; break;
        case OPT_FRAMES: frames = optarg; break;
        case OPT_PNG: png = 1; break;
        case OPT_EXPO: ev = (float)gi_opt_double("--exposure", optarg, -60, 60); break;
        case OPT_TIMINGS: timings = optarg; break;
        case OPT_AREA: so.area_samples = (int)gi_opt_long("--area-samples", optarg, 1, 4096); break;
        case OPT_SS: so.ss = (int)gi_opt_long("--ss", optarg, 1, 8); break;
        case OPT_AA:
            so.aa = (int)gi_opt_long("--aa", optarg, 1, 7);
            if (!(so.aa & 1))
                gi_usage_error("--aa: expected an odd number (1, 3, 5 or 7), got %d", so.aa);
            break;
        case OPT_EREF: so.edge_refine = 1; break;
        case OPT_NOEREF: so.edge_refine = 0; break;
        case OPT_RCON: so.refine_contrast = (float)gi_opt_double("--refine-contrast", optarg, 0.01, 1e6); break;
        case OPT_COV: so.coverage = (int)gi_opt_long("--coverage", optarg, 1, 31); break;
        case OPT_GRAYS: so.glossy_rays = (int)gi_opt_long("--glossy-rays", optarg, 0, 1024); break;
        case OPT_GMINKS: so.glossy_min_ks = (float)gi_opt_double("--glossy-min-ks", optarg, 0.0, 1.0); break;
        case OPT_GSTRIDE: so.glossy_stride = (int)gi_opt_long("--glossy-stride", optarg, 1, 4); break;
        case OPT_FRESH:
            fresh_paths = !strcmp(optarg, "auto") ? -1 : gi_opt_long("--fresh-paths", optarg, 0, 1L << 26);
            break;
        case OPT_LCAP:
            lift_cap = (float)gi_opt_double("--lift-cap", optarg, 0.0, 1e6);
            break;
        case OPT_NEAR:
            so.near_field = !strcmp(optarg, "auto") ? -1.0f : (float)gi_opt_double("--near-field", optarg, 0.0, 1e6);
            break;
        case OPT_NSTRIDE:
            so.near_stride = !strcmp(optarg, "auto") ? 0 : (int)gi_opt_long("--near-stride", optarg, 1, 4);
            break;
        case OPT_GPTS: gpts = 1; break;
        case OPT_ONLY:
            if (!strcmp(optarg, "direct"))
                so.indirect = 0;
            else if (!strcmp(optarg, "indirect"))
                so.direct = 0;
            else
                gi_usage_error("--only: expected direct or indirect, got '%s'", optarg);
            break;
        case OPT_INTERP:
            if (!strcmp(optarg, "linear"))
                so.interp_linear = 1;
            else if (!strcmp(optarg, "mean"))
                so.interp_linear = 0;
            else
                gi_usage_error("--interp: expected linear or mean, got '%s'", optarg);
            break;
        case OPT_FVIEW:
            if (!strcmp(optarg, "on"))
                fresh_view = 1;
            else if (!strcmp(optarg, "off"))
                fresh_view = 0;
            else
                gi_usage_error("--fresh-view: expected on or off, got '%s'", optarg);
            break;
        case OPT_TEXF:
            if (!strcmp(optarg, "on"))
                so.tex_filter = 1;
            else if (!strcmp(optarg, "off"))
                so.tex_filter = 0;
            else
                gi_usage_error("--tex-filter: expected on or off, got '%s'", optarg);
            break;
        case 's': so.seed = gi_opt_u64("--seed", optarg); break;
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
    if (argc - optind != 4)
        gi_usage_error("expected SCENE SCENE.gip SCENE.gih SCRIPT, got %d arguments", argc - optind);
    if (!outdir)
        gi_usage_error("missing -o OUTDIR");
    so.threads = threads;
    so.gather = gather_points;
    {
        const char *nc = getenv("GI_RELIGHT_NO_CACHE");
        so.no_cache = nc && !strcmp(nc, "1");
    }
    const char *scene_path = argv[optind], *gip_path = argv[optind + 1], *gih_path = argv[optind + 2],
               *script_path = argv[optind + 3];
    gi_container_install_signal_cleanup();

    double t0 = gi_now();
    gi_status st = {0};
    gi_scene *s = NULL;
    gi_script *sc = NULL;
    gi_gip *gip = NULL;
    gi_hvds *h = NULL;
    gi_rt *rt = NULL;
    gi_relight *rl = NULL;
    gi_gbuffer *gb = NULL;
    gi_shade *sh = NULL;
    FILE *tf = NULL;
    float *rgb = NULL;
    gi_frame fr = {0};
    gi_material *applied_mats = NULL;
    gi_light *applied_lights = NULL;
    size_t applied_nl = 0;
    gi_emit *emit = NULL;          /* emissive triangles of the applied materials */
    float *emit_le = NULL;         /* 3 per material: the emissions emit was built from */
    uint64_t emit_version = 0;
    gi_light *flights = NULL;      /* the frame's lights, then the mesh light if anything emits */
    size_t first = 0, last = 0;
    int rc = gi_scene_load(scene_path, &s, &st);
    if (!rc)
        rc = gi_script_parse_file(script_path, &sc, &st);
    if (!rc)
        rc = gi_script_check(sc, s, &st);
    if (!rc) {
        size_t nf = gi_script_num_frames(sc);
        last = nf - 1;
        if (frames) {
            const char *dash = strchr(frames, '-');
            int named = gi_script_find_frame(sc, frames);
            if (named >= 0) {
                first = last = (size_t)named;
            } else if (dash && dash != frames) {
                char a[64];
                size_t la = (size_t)(dash - frames);
                if (la >= sizeof a)
                    gi_usage_error("--frames: bad range '%s'", frames);
                memcpy(a, frames, la);
                a[la] = '\0';
                first = (size_t)gi_opt_long("--frames", a, 0, (long)nf - 1);
                last = (size_t)gi_opt_long("--frames", dash + 1, (long)first, (long)nf - 1);
            } else {
                int fi = gi_script_find_frame(sc, frames);
                if (fi < 0)
                    gi_usage_error("--frames: no frame '%s' in %s (%zu frames)", frames, script_path, nf);
                first = last = (size_t)fi;
            }
        }
        /* every frame to render must resolve and have a camera: refuse before any work */
        for (size_t i = first; i <= last && !rc; i++) {
            rc = gi_script_frame(sc, s, i, &fr, &st);
            if (!rc && !fr.has_camera)
                rc = gi_status_set(&st, GI_EXIT_DATA, "%s: frame '%s' has no camera", script_path, fr.name);
            if (!rc) {
                size_t on = 0;
                for (size_t l = 0; l < fr.num_lights; l++)
                    on += fr.lights[l].enabled ? 1 : 0;
                for (size_t m = 0; m < s->num_materials; m++)
                    if (gi_maxc(gi_v3p(fr.materials[m].emission)) > 0.0f) {
                        on++; /* the emissive surfaces, one mesh light */
                        break;
                    }
                if (on > GI_RELIGHT_MAX_LIGHTS)
                    rc = gi_status_set(&st, GI_EXIT_DATA, "%s: frame '%s' has %zu lights on; gi-relight handles "
                                       "at most %d at once", script_path, fr.name, on, GI_RELIGHT_MAX_LIGHTS);
            }
            gi_frame_release(&fr);
        }
    }
    if (!rc)
        rc = gi_gip_read(gip_path, s, &gip, &st);
    uint64_t fp = gip ? gip->fingerprint : 0;
    if (!rc)
        rc = gi_hvds_read(gih_path, s, fp, gip->num_photons, &h, &st);
    if (!rc && mkdir(outdir, 0777) && errno != EEXIST)
        rc = gi_status_errno(&st, GI_EXIT_SYSTEM, "%s: cannot create the output directory", outdir);
    struct stat ost;
    if (!rc && stat(outdir, &ost))
        rc = gi_status_errno(&st, GI_EXIT_SYSTEM, "%s: cannot read the output directory", outdir);
    else if (!rc && !S_ISDIR(ost.st_mode))
        rc = gi_status_set(&st, GI_EXIT_USAGE, "%s: expected an output directory, got a file", outdir);
    if (!rc)
        rc = gi_rt_new(s, &rt, &st);
    if (!rc)
        rc = gi_relight_new(s, rt, gip, h, threads, so.seed, &rl, &st);
    if (!rc)
        gi_relight_set_lift_cap(rl, lift_cap);
    if (!rc)
        gi_relight_set_fresh_importance(rl, fresh_view);
    if (!rc && fresh_paths < 0)
        gi_relight_set_fresh_auto(rl, GI_RELIGHT_FRESH_AUTO);
    else if (!rc)
        gi_relight_set_fresh_paths(rl, (uint32_t)fresh_paths);
    so.gather_ctx = rl;
    if (!rc)
        rc = gi_gbuffer_new(s, &gb, &st);
    if (!rc)
        rc = gi_shade_new(s, rt, h, &sh, &st);
    if (!rc && timings) {
        tf = fopen(timings, "w");
        if (!tf)
            rc = gi_status_errno(&st, GI_EXIT_SYSTEM, "%s: cannot open", timings);
        else
            fprintf(tf, "frame,name,changed,width,height,t_direct_ms,t_photon_energies_ms,t_hvds_ms,"
                        "t_final_gather_ms,t_splat_ms,t_materials_ms,t_gbuffer_ms,t_total_ms\n");
    }
    gi_verbose("loaded in %.2f s: %zu triangles, %llu photons, %u keys, %u gathering points", gi_now() - t0,
               s ? s->num_triangles : 0, gip ? (unsigned long long)gip->num_photons : 0ULL, h ? h->num_keys : 0,
               h ? h->num_gpoints : 0);
    gi_camera last_cam;
    memset(&last_cam, 0, sizeof last_cam);
    int have_last = 0;
    for (size_t i = first; i <= last && !rc; i++) {
        struct rusage ru0;
        getrusage(RUSAGE_SELF, &ru0);
        double f0 = gi_now();
        if ((rc = gi_script_frame(sc, s, i, &fr, &st)))
            break;
        unsigned changed = 0;
        unsigned char *mchg = calloc(s->num_materials + 1, 1);
        if (!mchg) {
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory");
            break;
        }
        int any_mat = 0;
        if (!applied_mats) {
            applied_mats = malloc(s->num_materials * sizeof *applied_mats);
            if (!applied_mats) {
                free(mchg);
                rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory");
                break;
            }
            /* the relight keeps a pointer to the materials: give it our copy, not the frame's */
            memcpy(applied_mats, fr.materials, s->num_materials * sizeof *applied_mats);
            rc = gi_relight_set_materials(rl, applied_mats, NULL, &st);
            any_mat = 1;
            changed |= GI_CHANGED_MATERIALS;
        } else {
            for (size_t m = 0; m < s->num_materials; m++)
                if (memcmp(&applied_mats[m], &fr.materials[m], sizeof fr.materials[m])) {
                    mchg[m] = 1;
                    any_mat = 1;
                }
            if (any_mat) {
                memcpy(applied_mats, fr.materials, s->num_materials * sizeof *applied_mats);
                rc = gi_relight_set_materials(rl, applied_mats, mchg, &st);
                changed |= GI_CHANGED_MATERIALS;
            }
        }
        free(mchg);
        if (rc)
            break;
        memcpy(applied_mats, fr.materials, s->num_materials * sizeof *applied_mats);
        double tmat = any_mat ? gi_relight_times_last(rl)->materials : 0.0;
        /* emissive surfaces light the scene as one mesh light, rebuilt when an emission changes */
        int echg = !emit_le;
        if (!emit_le && !(emit_le = calloc(3 * s->num_materials + 3, sizeof *emit_le))) {
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory");
            break;
        }
        for (size_t m = 0; m < s->num_materials; m++)
            if (memcmp(emit_le + 3 * m, fr.materials[m].emission, 3 * sizeof *emit_le)) {
                memcpy(emit_le + 3 * m, fr.materials[m].emission, 3 * sizeof *emit_le);
                echg = 1;
            }
        if (echg) {
            gi_emit_free(emit);
            emit = NULL;
            if ((rc = gi_emit_build(s, applied_mats, &emit, &st)))
                break;
            emit_version++;
            if (emit)
                gi_verbose("%zu emissive triangles light the scene (%.1f lm)", emit->n, emit->power);
        }
        free(flights);
        size_t nfl = fr.num_lights + (emit ? 1 : 0);
        if (!(flights = malloc((nfl + 1) * sizeof *flights))) {
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory");
            break;
        }
        if (fr.num_lights)
            memcpy(flights, fr.lights, fr.num_lights * sizeof *flights);
        if (emit)
            gi_emit_light(emit, emit_version, &flights[fr.num_lights]);
        int lchg = !applied_lights || !lights_equal(applied_lights, applied_nl, flights, nfl);
        if (lchg)
            changed |= GI_CHANGED_LIGHTS;
        gi_relight_times rt_t = {0};
        if (lchg || any_mat) {
            if ((rc = gi_relight_set_lights(rl, flights, nfl, 4, &st)))
                break;
            rt_t = *gi_relight_times_last(rl);
            free(applied_lights);
            applied_lights = malloc((nfl + 1) * sizeof *applied_lights);
            if (!applied_lights) {
                rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory");
                break;
            }
            memcpy(applied_lights, flights, nfl * sizeof *applied_lights);
            applied_nl = nfl;
        }
        if (!have_last || memcmp(&last_cam, &fr.camera, sizeof last_cam))
            changed |= GI_CHANGED_CAMERA;
        last_cam = fr.camera;
        have_last = 1;
        free(rgb);
        rgb = malloc((size_t)fr.width * (size_t)fr.height * 3 * sizeof *rgb);
        if (!rgb) {
            rc = gi_status_set(&st, GI_EXIT_SYSTEM, "out of memory for a %dx%d frame", fr.width, fr.height);
            break;
        }
        /* the photon grid, once: for glossy reflection gathered at the
         * pixels, and for the near field (the keys its points' near rays
         * find, gi_shade_opts.key_flux0) */
        int any_gather = 0;
        for (size_t m = 0; m < fr.num_materials; m++)
            any_gather |= gi_shade_gathers(&fr.materials[m], &so);
        int near = so.near_field != 0.0f && so.indirect && gi_relight_key_flux0(rl);
        if ((any_gather || near) && !so.key_at) {
            double tk = gi_now();
            if ((rc = gi_relight_prepare_keys(rl, &st)))
                break;
            gi_verbose("photon grid (glossy gathers, near field): %.1f ms", 1e3 * (gi_now() - tk));
            so.key_at = key_at;
            so.key_ctx = rl;
            so.key_flux = gi_relight_key_flux(rl);
            so.key_flux0 = gi_relight_key_flux0(rl);
        }
        gi_shade_times stt;
        if ((rc = gi_shade_frame(sh, gb, &fr.camera, fr.width, fr.height, flights, nfl, fr.materials,
                                 gi_relight_gpoint_irradiance_lazy(rl), gi_relight_gpoint_gradient_lazy(rl), &so, rgb,
                                 &stt,
                                 &st)))
            break;
        double f1 = gi_now();
        struct rusage ru1;
        getrusage(RUSAGE_SELF, &ru1);
        gi_verbose("frame %zu: %ld page faults", i, ru1.ru_minflt - ru0.ru_minflt);
        char path[4096];
        gi_image im = {fr.width, fr.height, 3, rgb};
        char secs[32];
        snprintf(secs, sizeof secs, "%.6f", f1 - f0);
        gi_image_meta meta[] = {{"tool", "gi-relight"}, {"frame", fr.name}, {"seconds", secs}, {"units", "cd/m^2"}};
        snprintf(path, sizeof path, "%s/%s.exr", outdir, fr.name);
        if ((rc = gi_image_write_exr(path, &im, meta, 4, &st)))
            break;
        if (gpts) {
            snprintf(path, sizeof path, "%s/%s.gpoints", outdir, fr.name);
            if ((rc = write_gpoints(path, rl, h, gi_relight_gpoint_irradiance(rl), fr.name, &st)))
                break;
        }
        if (png) {
            snprintf(path, sizeof path, "%s/%s.png", outdir, fr.name);
            if ((rc = write_png(path, rgb, fr.width, fr.height, ev, &st)))
                break;
        }
        char chg[64];
        snprintf(chg, sizeof chg, "%s%s%s%s", (changed & GI_CHANGED_LIGHTS) ? "lights " : "",
                 (changed & GI_CHANGED_MATERIALS) ? "materials " : "", (changed & GI_CHANGED_CAMERA) ? "camera " : "",
                 changed ? "" : "nothing");
        size_t cl = strlen(chg);
        if (cl && chg[cl - 1] == ' ')
            chg[cl - 1] = '\0';
        double total = f1 - f0;
        if (tf)
            fprintf(tf, "%zu,%s,%s,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", i, fr.name, chg, fr.width,
                    fr.height, 1e3 * stt.direct, 1e3 * (rt_t.entry + rt_t.photons), 1e3 * rt_t.hvds,
                    1e3 * (rt_t.gather + stt.gather), 1e3 * stt.splat, 1e3 * tmat, 1e3 * stt.gbuffer, 1e3 * total);
        gi_info("frame %zu '%s' (%s): %.1f ms (direct %.1f, photons %.1f, hvds %.1f, gather %.1f, splat %.1f, "
                "materials %.1f, G-buffer %.1f)",
                i, fr.name, chg, 1e3 * total, 1e3 * stt.direct, 1e3 * (rt_t.entry + rt_t.photons), 1e3 * rt_t.hvds,
                1e3 * (rt_t.gather + stt.gather), 1e3 * stt.splat, 1e3 * tmat, 1e3 * stt.gbuffer);
        gi_frame_release(&fr);
    }
    gi_frame_release(&fr);
    if (tf && fclose(tf) && !rc)
        rc = gi_status_errno(&st, GI_EXIT_SYSTEM, "%s: write failed", timings);
    free(rgb);
    free(applied_mats);
    free(applied_lights);
    free(flights);
    free(emit_le);
    gi_emit_free(emit);
    gi_shade_free(sh);
    gi_gbuffer_free(gb);
    gi_relight_free(rl);
    gi_rt_free(rt);
    gi_hvds_free(h);
    gi_gip_free(gip);
    gi_script_free(sc);
    gi_scene_free(s);
    if (rc)
        gi_die_status(&st);
    return 0;
}
