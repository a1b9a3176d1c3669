/* gi_status.h - error reporting for library code.
 *
 * Library functions never exit: they return 0 on success or a GI_EXIT_* code,
 * and fill a caller-owned gi_status with the code and a one-line message that
 * already names the place (file, line:column, offset, section). Only main()
 * turns a status into a message on stderr and an exit code (gi_log.h).
 * A zeroed gi_status means "no error". */
#ifndef GI_STATUS_H
#define GI_STATUS_H

#include "gi_exit.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GI_STATUS_MSG_MAX 1024

typedef struct gi_status {
    int code;                     /* 0, or one of GI_EXIT_* */
    char msg[GI_STATUS_MSG_MAX];  /* "file: place: what", lowercase, no final period */
} gi_status;

/* Record an error; returns code so callers can `return gi_status_set(...)`. */
int gi_status_set(gi_status *st, int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* Like gi_status_set, appending ": strerror(errno)". */
int gi_status_errno(gi_status *st, int code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* Reset to "no error". */
void gi_status_clear(gi_status *st);

#ifdef __cplusplus
}
#endif
#endif
