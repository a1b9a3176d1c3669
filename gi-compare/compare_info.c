/* compare_info.c - `gi-compare info SCENE`: the loaded scene as JSON. */
#include <getopt.h>
#include <stdio.h>

#include "compare.h"
#include "gi_log.h"
#include "gi_scene.h"

int compare_info_main(int argc, char **argv)
{
    static const struct option longopts[] = {{"help", no_argument, 0, 'h'},
                                             {"quiet", no_argument, 0, 'q'},
                                             {0, 0, 0, 0}};
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "hq", longopts, NULL)) != -1) {
        switch (c) {
        case 'h':
            printf("usage: gi-compare info SCENE\n"
                   "Load a glTF 2.0 scene (.gltf or .glb) and print it as JSON on stdout:\n"
                   "triangles, materials, textures, lights (candela, lux, nits), cameras,\n"
                   "bounding box (m), surface area (m^2) and loader warnings.\n");
            return 0;
        case 'q':
            gi_log_set_verbosity(-1);
            break;
        default:
            gi_usage_error("bad option");
        }
    }
    if (argc - optind != 1)
        gi_usage_error("expected one SCENE argument, got %d", argc - optind);
    gi_status st = {0};
    gi_scene *s = NULL;
    if (gi_scene_load(argv[optind], &s, &st))
        gi_die_status(&st);
    gi_scene_print_json(s, stdout);
    int rc = fflush(stdout) ? GI_EXIT_SYSTEM : 0;
    gi_scene_free(s);
    if (rc)
        gi_error("writing stdout failed");
    return rc;
}
