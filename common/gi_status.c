/* gi_status.c - error records returned by library code. */
#include "gi_status.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

int gi_status_set(gi_status *st, int code, const char *fmt, ...)
{
    if (!st)
        return code;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(st->msg, sizeof st->msg, fmt, ap);
    va_end(ap);
    st->code = code;
    return code;
}

int gi_status_errno(gi_status *st, int code, const char *fmt, ...)
{
    int err = errno;
    if (!st)
        return code;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(st->msg, sizeof st->msg, fmt, ap);
    va_end(ap);
    size_t n = strlen(st->msg);
    snprintf(st->msg + n, sizeof st->msg - n, ": %s", strerror(err));
    st->code = code;
    return code;
}

void gi_status_clear(gi_status *st)
{
    if (st) {
        st->code = 0;
        st->msg[0] = '\0';
    }
}
