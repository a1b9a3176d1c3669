/* compare.h - the subcommands of gi-compare. Each takes the arguments after
 * the subcommand name (argv[0] is the subcommand), parses its own options with
 * getopt_long, and returns the process exit code (GI_EXIT_*). */
#ifndef GI_COMPARE_H
#define GI_COMPARE_H

int compare_info_main(int argc, char **argv);    /* compare_info.c */
int compare_render_main(int argc, char **argv);  /* compare_render.c */
int compare_sensors_main(int argc, char **argv); /* compare_render.c */
int compare_diff_main(int argc, char **argv);    /* compare_diff.c */
int compare_report_main(int argc, char **argv);  /* compare_report.c */

#endif
