/* alloc.h - the one allocator of libfrep: every allocation of the library goes through
 * these functions, and so through the hook of frep_set_allocator() (frep.h) when one
 * is installed. Tests install a failing hook to run every cleanup path
 * (tests/faults.h); the default is the C library's malloc/realloc/free.
 *
 * Sizes of 0 are rounded up to 1, so a NULL result always means "out of memory".
 */
#ifndef FREP_ALLOC_H
#define FREP_ALLOC_H

#include <stddef.h>

void *frep_malloc(size_t n);
void *frep_calloc(size_t count, size_t size);   /* NULL also when count * size overflows */
void *frep_realloc(void *p, size_t n);
void *frep_reallocarray(void *p, size_t count, size_t size);
/* frep_free(p) is declared in frep.h: allocations the library hands to its caller are
 * released with it. */
void frep_free(void *p);
char *frep_strdup(const char *s);
char *frep_strndup(const char *s, size_t n);
/* Fault in the whole pages of [p, p + n) of a fresh allocation that is about to be
 * written whole, in one system call instead of one page fault a page (Linux's
 * MADV_POPULATE_WRITE; a hint: nothing happens where it is missing or fails).  Below
 * FREP_PREFAULT_MIN_BYTES nothing: a few faults cost less than the call.  The
 * FREP_HUGE_PAGE_BYTES-aligned interior of the range is first offered huge pages
 * (MADV_HUGEPAGE, for kernels whose transparent huge pages are "madvise"): one TLB
 * entry then covers 2 MiB, which cut the time the mesher spends copying its blocks'
 * pools into the mesh by ~40% (the gyroid at -g 128: 37.1 -> 22.8 ms on one thread,
 * doc/benchmarks.md). */
#define FREP_PREFAULT_MIN_BYTES ((size_t)1 << 14)
#define FREP_HUGE_PAGE_BYTES ((size_t)1 << 21)
void frep_prefault(void *p, size_t n);
/* Memory aligned to `align` (a power of two, at most 4096); release with
 * frep_aligned_free, never with frep_free. */
void *frep_aligned_alloc(size_t align, size_t n);
void frep_aligned_free(void *p);

#endif
