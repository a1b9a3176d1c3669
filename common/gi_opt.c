/* gi_opt.c - strict number parsing for command lines. */
#define _POSIX_C_SOURCE 200809L
#include "gi_opt.h"

#include <embree3/rtcore_config.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gi_log.h"
#include "gi_exit.h"

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

/* The output's directory must exist and be writable before any work starts. */
void gi_opt_check_output(const char *out)
{
    char dir[4096];
    const char *slash = strrchr(out, '/');
    if (!slash) {
        strcpy(dir, ".");
    } else if (slash == out) {
        strcpy(dir, "/");
    } else {
        size_t n = (size_t)(slash - out);
        if (n >= sizeof dir)
            gi_die(GI_EXIT_SYSTEM, "%s: path too long", out);
        memcpy(dir, out, n);
        dir[n] = '\0';
    }
    struct stat sb;
    if (stat(dir, &sb) != 0)
        gi_die(GI_EXIT_SYSTEM, "%s: cannot write into '%s': %s", out, dir, strerror(errno));
    if (!S_ISDIR(sb.st_mode))
        gi_die(GI_EXIT_SYSTEM, "%s: cannot write into '%s': Not a directory", out, dir);
    if (access(dir, W_OK | X_OK) != 0)
        gi_die(GI_EXIT_SYSTEM, "%s: cannot write into '%s': %s", out, dir, strerror(errno));
    if (stat(out, &sb) == 0 && S_ISDIR(sb.st_mode))
        gi_die(GI_EXIT_SYSTEM, "%s: Is a directory", out);
}

