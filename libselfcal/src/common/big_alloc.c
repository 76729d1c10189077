/* big_alloc.c — the large work arrays' allocation with a huge-page hint (big_alloc.h). Compiled
 * into the library and into the command line, whose allocator for SuiteSparse uses it too. */
#include "big_alloc.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

#define BIG_FROM ((size_t)2 << 20)
#define HUGE_PAGE ((uintptr_t)2 << 20)

/* The hint on the 2 MiB-aligned inside of a block of n bytes at p (none below BIG_FROM). */
static void advise_huge(void *p, size_t n)
{
#ifdef MADV_HUGEPAGE
    if (!p || n < BIG_FROM)
        return;
    uintptr_t a = ((uintptr_t)p + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
    uintptr_t b = ((uintptr_t)p + n) & ~(HUGE_PAGE - 1);
    if (b > a)
        madvise((void *)a, b - a, MADV_HUGEPAGE); /* a hint: refused or not, nothing changes */
#else
    (void)p, (void)n;
#endif
}

void *sc_big_alloc(size_t count, size_t size, int zeroed)
{
    if (size && count > SIZE_MAX / size)
        return NULL;
    size_t n = count * size;
    void *p = NULL;
    if (!zeroed && n >= BIG_FROM) {
        /* from a 2 MiB boundary, so that the hint covers the block from its first byte: 1 000
         * fewer faults at N = 101 (the grid command), the same peak. Zeroed blocks stay calloc's:
         * fresh mappings need no clearing pass, which aligned memory would */
        if (posix_memalign(&p, (size_t)HUGE_PAGE, n) != 0)
            return NULL;
    } else {
        p = zeroed ? calloc(count ? count : 1, size ? size : 1) : malloc(n ? n : 1);
    }
    advise_huge(p, n);
    return p;
}

void *sc_big_realloc(void *p, size_t size)
{
    void *q = realloc(p, size);
    advise_huge(q, size);
    return q;
}
