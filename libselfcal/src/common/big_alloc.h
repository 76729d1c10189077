/* big_alloc.h — private: the library's large work arrays (the grid solver's matrix, selected
 * inverse and columns: megabytes, written once), allocated as usual and, from 2 MiB up, hinted
 * to Linux for transparent huge pages (madvise MADV_HUGEPAGE on the block's 2 MiB-aligned
 * inside, before its first touch; blocks not asked zeroed start on a 2 MiB boundary): one page
 * fault per 2 MiB instead of per 4 KiB where the system gives huge pages on request; a plain
 * allocation elsewhere. A hint on the block itself: no
 * process-wide setting changes. Freed with free(). The command line compiles the same file for
 * the allocator it gives SuiteSparse (tools/selfcal/main.c). */
#ifndef SELFCAL_BIG_ALLOC_H
#define SELFCAL_BIG_ALLOC_H

#include <stddef.h>

/* malloc(count * size) (2 MiB-aligned from 2 MiB), or calloc when zeroed; NULL if it overflows
 * or memory ran out. */
void *sc_big_alloc(size_t count, size_t size, int zeroed);

/* realloc(p, size) with the same hint on the result. */
void *sc_big_realloc(void *p, size_t size);

#endif
