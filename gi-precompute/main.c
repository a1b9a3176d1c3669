/* main.c - gi-precompute command line. PLACEHOLDER: the tool's real work lands with its
 * issue; until then it loads and validates the scene and says what it would do. */
#include <getopt.h>
#include <stdio.h>

#include "gi_exit.h"
#include "gi_log.h"
#include "gi_opt.h"
#include "gi_scene.h"

int main(int argc, char **argv)
{
    gi_log_init("gi-precompute");
    static const struct option longopts[] = {{"help", no_argument, 0, 'h'},
                                             {"version", no_argument, 0, 'V'},
                                             {0, 0, 0, 0}};
    int c;
    while ((c = getopt_long(argc, argv, "hV", longopts, NULL)) != -1) {
        switch (c) {
        case 'h':
            printf("usage: gi-precompute SCENE ...\n"
                   "PLACEHOLDER: this tool is not implemented yet; it only loads and checks SCENE.\n");
            return 0;
        case 'V':
            gi_opt_print_version("gi-precompute");
            return 0;
        default:
            gi_usage_error("bad option");
        }
    }
    if (optind >= argc)
        gi_usage_error("missing SCENE");
    gi_status st = {0};
    gi_scene *s = NULL;
    if (gi_scene_load(argv[optind], &s, &st))
        gi_die_status(&st);
    gi_error("not implemented yet (placeholder); scene '%s' loaded: %zu triangles", argv[optind],
             s->num_triangles);
    gi_scene_free(s);
    return GI_EXIT_SYSTEM;
}
