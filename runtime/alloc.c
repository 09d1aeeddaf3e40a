/* alloc.c - the allocator of libfrep (runtime/alloc.h) and its hook.
 *
 * The hook is the library's only process-wide state: it is installed before any other
 * call (frep.h says so) and only read afterwards, so threads never race on it.
 */
#include "config.h"

#include "alloc.h"
#include "frep.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

static frep_alloc_fn hook_fn;   /* NULL: the C library */
static void *hook_user;

void frep_set_allocator(frep_alloc_fn fn, void *user)
{
    hook_fn = fn;
    hook_user = fn ? user : NULL;
}

void *frep_malloc(size_t n)
{
    if (n == 0) n = 1;
    return hook_fn ? hook_fn(hook_user, NULL, n) : malloc(n);
}

void *frep_calloc(size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    if (!hook_fn) return calloc(count ? count : 1, size ? size : 1);
    size_t n = count * size;
    if (n == 0) n = 1;
    void *p = hook_fn(hook_user, NULL, n);
    if (p) memset(p, 0, n);
    return p;
}

void *frep_realloc(void *p, size_t n)
{
    if (n == 0) n = 1;
    return hook_fn ? hook_fn(hook_user, p, n) : realloc(p, n);
}

void *frep_reallocarray(void *p, size_t count, size_t size)
{
    if (size && count > SIZE_MAX / size) return NULL;
    return frep_realloc(p, count * size);
}

void frep_free(void *p)
{
    if (!p) return;
    if (hook_fn) hook_fn(hook_user, p, 0);
    else free(p);
}

void frep_prefault(void *p, size_t n)
{
#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
    long page = sysconf(_SC_PAGESIZE);
    if (page <= 0 || n < FREP_PREFAULT_MIN_BYTES) return;
    uintptr_t lo = ((uintptr_t)p + (uintptr_t)page - 1) & ~((uintptr_t)page - 1);
    uintptr_t hi = ((uintptr_t)p + n) & ~((uintptr_t)page - 1);
#ifdef MADV_HUGEPAGE
    uintptr_t huge = (uintptr_t)FREP_HUGE_PAGE_BYTES;
    uintptr_t hlo = ((uintptr_t)p + huge - 1) & ~(huge - 1);
    uintptr_t hhi = ((uintptr_t)p + n) & ~(huge - 1);
    if (hhi > hlo) (void)madvise((void *)hlo, hhi - hlo, MADV_HUGEPAGE);
#endif
    if (hi > lo) (void)madvise((void *)lo, hi - lo, MADV_POPULATE_WRITE);
#else
    (void)p;
    (void)n;
#endif
}

char *frep_strndup(const char *s, size_t n)
{
    size_t len = 0;
    while (len < n && s[len]) len++;
    char *d = frep_malloc(len + 1);
    if (!d) return NULL;
    memcpy(d, s, len);
    d[len] = '\0';
    return d;
}

char *frep_strdup(const char *s) { return frep_strndup(s, SIZE_MAX); }

/* The block starts with room for the pointer frep_malloc returned, stored just before
 * the aligned address. */
void *frep_aligned_alloc(size_t align, size_t n)
{
    if (align < sizeof(void *)) align = sizeof(void *);
    if (align > 4096 || (align & (align - 1)) || n > SIZE_MAX - align - sizeof(void *))
        return NULL;
    unsigned char *raw = frep_malloc(n + align + sizeof(void *));
    if (!raw) return NULL;
    uintptr_t a = ((uintptr_t)(raw + sizeof(void *)) + align - 1) & ~(uintptr_t)(align - 1);
    ((void **)a)[-1] = raw;
    return (void *)a;
}

void frep_aligned_free(void *p)
{
    if (p) frep_free(((void **)p)[-1]);
}
