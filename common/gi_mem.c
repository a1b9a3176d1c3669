/* gi_mem.c - large buffers on transparent huge pages (see gi_mem.h). */
#define _DEFAULT_SOURCE /* madvise and MADV_HUGEPAGE under -std=c11 */
#include "gi_mem.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef __linux__
#include <sys/mman.h>
#endif

void *gi_alloc_large(size_t n)
{
    if (n < GI_MEM_LARGE)
        return malloc(n ? n : 1);
    /* whole huge pages, aligned, so that every 2 MiB of the buffer can be one */
    size_t sz = (n + GI_MEM_LARGE - 1) / GI_MEM_LARGE * GI_MEM_LARGE;
    void *p = aligned_alloc(GI_MEM_LARGE, sz);
    if (!p)
        return NULL;
#ifdef MADV_HUGEPAGE
    (void)madvise(p, sz, MADV_HUGEPAGE); /* advice only: without it the buffer still works */
#endif
    return p;
}

void *gi_calloc_large(size_t n, size_t sz)
{
    if (sz && n > SIZE_MAX / sz)
        return NULL;
    if (n * sz < GI_MEM_LARGE)
        return calloc(n ? n : 1, sz ? sz : 1);
    void *p = gi_alloc_large(n * sz);
    if (p)
        memset(p, 0, n * sz);
    return p;
}
