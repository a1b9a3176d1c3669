/* gi_log.h - messages for people (stderr only) and progress reports.
 *
 * Call gi_log_init(argv0-name) first in main. Verbosity: -1 quiet (errors only),
 * 0 default (warnings + summary), 1 and up verbose (stage progress, timings).
 * Every message is formatted fully and written with one write() so threads
 * do not interleave. stdout is never touched here. */
#ifndef GI_LOG_H
#define GI_LOG_H

#include <stddef.h>
#include <stdint.h>

#include "gi_status.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__)
#define GI_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define GI_PRINTF(a, b)
#endif

void gi_log_init(const char *prog);             /* sets the "gi-tool: " prefix */
const char *gi_log_prog(void);                  /* the prefix set by gi_log_init */
void gi_log_set_verbosity(int v);               /* -1 quiet, 0 default, >0 verbose */
int gi_log_verbosity(void);
void gi_error(const char *fmt, ...) GI_PRINTF(1, 2);   /* always printed */
void gi_warn(const char *fmt, ...) GI_PRINTF(1, 2);    /* verbosity >= 0 */
void gi_info(const char *fmt, ...) GI_PRINTF(1, 2);    /* verbosity >= 0: summaries */
void gi_verbose(const char *fmt, ...) GI_PRINTF(1, 2); /* verbosity >= 1 */
/* Print "prog: error: msg" and exit with code. */
_Noreturn void gi_die(int code, const char *fmt, ...) GI_PRINTF(2, 3);
/* Print st->msg as an error and exit with st->code (GI_EXIT_SYSTEM if unset). */
_Noreturn void gi_die_status(const gi_status *st);
/* Usage error: "prog: MSG" + "try 'prog --help'", exit 2. */
_Noreturn void gi_usage_error(const char *fmt, ...) GI_PRINTF(1, 2);

/* Programmer error: prints file:line and aborts. Never for file contents. */
#define GI_BUG(msg) gi_bug_at(__FILE__, __LINE__, (msg))
_Noreturn void gi_bug_at(const char *file, int line, const char *msg);

/* Monotonic wall clock in seconds. */
double gi_now(void);

/* Progress of a long loop. Thread-safe: gi_progress_add may be called from
 * any thread. On a TTY the line is redrawn; otherwise one line every ~10%.
 * Silent unless verbosity >= 0 and total is large enough to matter. */
typedef struct gi_progress {
    const char *what;
    uint64_t total;
    uint64_t done;       /* updated atomically */
    double t0;
    int last_decile;
    int tty;
    double last_draw;
} gi_progress;
void gi_progress_begin(gi_progress *p, const char *what, uint64_t total);
void gi_progress_add(gi_progress *p, uint64_t n);
void gi_progress_end(gi_progress *p);

#ifdef __cplusplus
}
#endif
#endif
