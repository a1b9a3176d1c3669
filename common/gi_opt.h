/* gi_opt.h - strict parsing of command-line numbers and shared option helpers.
 * Each parser requires the whole string to be consumed and the value to be in
 * range; on failure it prints a usage error naming the option and exits 2. */
#ifndef GI_OPT_H
#define GI_OPT_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

long gi_opt_long(const char *opt, const char *s, long lo, long hi);
uint64_t gi_opt_u64(const char *opt, const char *s);
double gi_opt_double(const char *opt, const char *s, double lo, double hi);
/* Print "prog VERSION (commit C), Embree X, OpenImageIO Y" to stdout. */
void gi_opt_print_version(const char *prog);
/* Exit 4 with a message unless out's directory exists and is writable and
 * out is not a directory: checked before any long work. */
void gi_opt_check_output(const char *out);
/* Threads for -j: 0 means all cores. */
int gi_opt_threads(const char *s);

#ifdef __cplusplus
}
#endif
#endif
