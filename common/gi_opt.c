/* gi_opt.c - strict number parsing for command lines. */
#include "gi_opt.h"

#include <embree3/rtcore_config.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "gi_log.h"

#ifndef GI_VERSION
#define GI_VERSION "dev"
#endif
#ifndef GI_COMMIT
#define GI_COMMIT "unknown"
#endif

long gi_opt_long(const char *opt, const char *s, long lo, long hi)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end != '\0')
        gi_usage_error("%s: expected an integer, got '%s'", opt, s);
    if (v < lo || v > hi)
        gi_usage_error("%s: %ld is out of range [%ld, %ld]", opt, v, lo, hi);
    return v;
}

uint64_t gi_opt_u64(const char *opt, const char *s)
{
    char *end;
    errno = 0;
    if (s[0] == '-')
        gi_usage_error("%s: expected a non-negative integer, got '%s'", opt, s);
    unsigned long long v = strtoull(s, &end, 10);
    if (errno || end == s || *end != '\0')
        gi_usage_error("%s: expected a non-negative integer, got '%s'", opt, s);
    return (uint64_t)v;
}

double gi_opt_double(const char *opt, const char *s, double lo, double hi)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end != '\0' || !isfinite(v))
        gi_usage_error("%s: expected a number, got '%s'", opt, s);
    if (v < lo || v > hi)
        gi_usage_error("%s: %g is out of range [%g, %g]", opt, v, lo, hi);
    return v;
}

int gi_opt_threads(const char *s) { return (int)gi_opt_long("-j/--threads", s, 0, 1024); }

void gi_opt_print_version(const char *prog)
{
    printf("%s %s (commit %s), Embree %d.%d.%d\n", prog, GI_VERSION, GI_COMMIT,
           RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH);
}
