/* gi_mem.h - large buffers that are cheap to touch for the first time.
 *
 * On this project's machines (virtual, 4 KiB pages) a first touch costs about
 * 10 us per page: a 15 MB buffer filled once costs ~40 ms of faults, more than
 * the work done in it. gi_alloc_large asks for transparent huge pages on
 * buffers of GI_MEM_LARGE bytes or more (one fault per 2 MiB); where the kernel
 * declines, it is an ordinary allocation. Release with free(). */
#ifndef GI_MEM_H
#define GI_MEM_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define GI_MEM_LARGE ((size_t)2 << 20)

/* n bytes (contents undefined), or NULL when out of memory */
void *gi_alloc_large(size_t n);
/* n elements of sz bytes, zeroed (calloc's contract), or NULL */
void *gi_calloc_large(size_t n, size_t sz);

#ifdef __cplusplus
}
#endif
#endif
