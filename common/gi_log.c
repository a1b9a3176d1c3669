/* gi_log.c - messages and progress on stderr. */
#define _POSIX_C_SOURCE 200809L
#include "gi_log.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static const char *g_prog = "gi";
static int g_verbosity = 0;

void gi_log_init(const char *prog) { g_prog = prog; }
const char *gi_log_prog(void) { return g_prog; }
void gi_log_set_verbosity(int v) { g_verbosity = v; }
int gi_log_verbosity(void) { return g_verbosity; }

/* Format "prog: kind: msg\n" into one buffer and write it at once. */
static void emit(const char *kind, const char *fmt, va_list ap)
{
    char buf[4096];
    int n;
    if (kind)
        n = snprintf(buf, sizeof buf, "%s: %s: ", g_prog, kind);
    else
        n = snprintf(buf, sizeof buf, "%s: ", g_prog);
    if (n < 0)
        return;
    if ((size_t)n < sizeof buf) {
        int m = vsnprintf(buf + n, sizeof buf - (size_t)n, fmt, ap);
        if (m > 0)
            n += m;
    }
    if ((size_t)n >= sizeof buf - 1)
        n = (int)sizeof buf - 2;
    buf[n++] = '\n';
    ssize_t w = write(STDERR_FILENO, buf, (size_t)n);
    (void)w;
}

void gi_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    emit("error", fmt, ap);
    va_end(ap);
}

void gi_warn(const char *fmt, ...)
{
    if (g_verbosity < 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    emit("warning", fmt, ap);
    va_end(ap);
}

void gi_info(const char *fmt, ...)
{
    if (g_verbosity < 0)
        return;
    va_list ap;
    va_start(ap, fmt);
    emit(NULL, fmt, ap);
    va_end(ap);
}

void gi_verbose(const char *fmt, ...)
{
    if (g_verbosity < 1)
        return;
    va_list ap;
    va_start(ap, fmt);
    emit(NULL, fmt, ap);
    va_end(ap);
}

void gi_die(int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    emit("error", fmt, ap);
    va_end(ap);
    exit(code);
}

void gi_die_status(const gi_status *st)
{
    int code = st && st->code ? st->code : GI_EXIT_SYSTEM;
    gi_die(code, "%s", st && st->msg[0] ? st->msg : "unknown failure");
}

void gi_usage_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    emit(NULL, fmt, ap);
    va_end(ap);
    char buf[256];
    int n = snprintf(buf, sizeof buf, "try '%s --help'\n", g_prog);
    if (n > 0) {
        ssize_t w = write(STDERR_FILENO, buf, (size_t)n);
        (void)w;
    }
    exit(GI_EXIT_USAGE);
}

void gi_bug_at(const char *file, int line, const char *msg)
{
    fprintf(stderr, "%s: internal error at %s:%d: %s\n", g_prog, file, line, msg);
    abort();
}

double gi_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void gi_progress_begin(gi_progress *p, const char *what, uint64_t total)
{
    memset(p, 0, sizeof *p);
    p->what = what;
    p->total = total ? total : 1;
    p->t0 = gi_now();
    p->tty = isatty(STDERR_FILENO);
    p->last_decile = 0;
}

static void draw(gi_progress *p, uint64_t done, int final)
{
    double el = gi_now() - p->t0;
    double frac = (double)done / (double)p->total;
    double eta = frac > 0 ? el * (1.0 - frac) / frac : 0.0;
    char buf[256];
    int n;
    if (final)
        n = snprintf(buf, sizeof buf, "%s%s: %s: 100%% in %.2f s\n", p->tty ? "\r" : "", g_prog,
                     p->what, el);
    else
        n = snprintf(buf, sizeof buf, "%s%s: %s: %3.0f%%, %.1f s elapsed, eta %.1f s%s",
                     p->tty ? "\r" : "", g_prog, p->what, 100.0 * frac, el, eta,
                     p->tty ? "   " : "\n");
    if (n > 0) {
        if ((size_t)n >= sizeof buf)
            n = (int)sizeof buf - 1;
        ssize_t w = write(STDERR_FILENO, buf, (size_t)n);
        (void)w;
    }
}

void gi_progress_add(gi_progress *p, uint64_t n)
{
    uint64_t done = __atomic_add_fetch(&p->done, n, __ATOMIC_RELAXED);
    if (g_verbosity < 0)
        return;
    double now = gi_now();
    if (now - p->t0 < 1.0)
        return; /* short jobs stay quiet */
    int decile = (int)(10.0 * (double)done / (double)p->total);
    int prev = __atomic_load_n(&p->last_decile, __ATOMIC_RELAXED);
    if (p->tty) {
        double last = p->last_draw;
        if (now - last < 0.25)
            return;
        p->last_draw = now;
        draw(p, done, 0);
    } else if (decile > prev &&
               __atomic_compare_exchange_n(&p->last_decile, &prev, decile, 0, __ATOMIC_RELAXED,
                                           __ATOMIC_RELAXED)) {
        draw(p, done, 0);
    }
}

void gi_progress_end(gi_progress *p)
{
    if (g_verbosity < 0)
        return;
    if (gi_now() - p->t0 >= 1.0 || g_verbosity > 0)
        draw(p, p->total, 1);
}
