/* main.c - gi-compare: reference renders, sensors, image comparison, reports.
 * Command line only: dispatches to the subcommands in compare_*.c. */
#include <stdio.h>
#include <string.h>

#include "compare.h"
#include "gi_exit.h"
#include "gi_log.h"
#include "gi_opt.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: gi-compare COMMAND [ARGS]\n"
            "\n"
            "commands:\n"
            "  info SCENE                      print the loaded scene as JSON on stdout\n"
            "  render SCENE [SCRIPT] -o OUT.exr [--frame N|NAME] [--spp N] [--time S]\n"
            "                                  path-traced reference of a frame (cd/m^2)\n"
            "  sensors SCENE [SCRIPT] --points FILE [--frame N|NAME] [--spp N]\n"
            "                                  illuminance (lux) and its standard error at points\n"
            "  diff A.exr REF.exr [--tolerance T] [--error-image ERR.png]\n"
            "                                  error of A against REF as key=value lines\n"
            "  report RUNS.csv -o DIR          speed-against-error table and plot\n"
            "\n"
            "'gi-compare COMMAND --help' describes each command's options.\n"
            "exit status: 0 success, 1 difference beyond tolerance, 2 usage, 3 bad input data,\n"
            "4 system failure\n");
}

int main(int argc, char **argv)
{
    gi_log_init("gi-compare");
    if (argc < 2) {
        usage(stderr);
        return GI_EXIT_USAGE;
    }
    const char *cmd = argv[1];
    if (!strcmp(cmd, "-h") || !strcmp(cmd, "--help") || !strcmp(cmd, "help")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(cmd, "-V") || !strcmp(cmd, "--version")) {
        gi_opt_print_version("gi-compare");
        return 0;
    }
    static const struct {
        const char *name;
        int (*fn)(int, char **);
    } cmds[] = {
        {"info", compare_info_main},       {"render", compare_render_main},
        {"sensors", compare_sensors_main}, {"diff", compare_diff_main},
        {"report", compare_report_main},
    };
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
        if (!strcmp(cmd, cmds[i].name)) {
            static char prog[64];
            snprintf(prog, sizeof prog, "gi-compare %s", cmds[i].name);
            gi_log_init(prog);
            return cmds[i].fn(argc - 1, argv + 1);
        }
    }
    gi_usage_error("unknown command '%s'", cmd);
}
