/* number_internal.h — private: the number parser over a text that lies inside a larger readable
 * buffer (the CSV reader's block), so that its fast path may look ahead past the text's end; the
 * shortest formatter in two steps (digits, then text) for the writers' rows; the integer writer
 * of their index columns. */
#ifndef SELFCAL_NUMBER_INTERNAL_H
#define SELFCAL_NUMBER_INTERNAL_H

#include <stdint.h>

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* sc_number_parse_prefix on [s, end), allowed to read (never to take) bytes up to readable
 * (readable >= end, all of [s, readable) initialized memory). */
sc_status sc_number_parse_prefix_within(const char *s, const char *end, const char *readable,
                                        const char **stop, double *out);

/* A double's shortest round-trip digits (m·10^e; m = 0 for 0, NaN and the infinities), found
 * apart from their layout: a writer of several numbers a row finds all their digits first and
 * then lays them out, and the processor overlaps the searches, which it cannot do across a
 * layout that waits for the previous one's length (docs/profile.md: a row of three numbers,
 * 24 ns a number instead of 28.5). sc_number_format(v) is find, then put. */
typedef struct sc_number_shortest {
    double v;
    uint64_t m;
    int e;
} sc_number_shortest;

void sc_number_find_shortest(double v, sc_number_shortest *d);

/* Lay out d as sc_number_format does (with its NUL; scratch bytes up to SC_NUMBER_BUF from p);
 * returns the end (the NUL's place). */
char *sc_number_put_shortest(char *p, const sc_number_shortest *d);

/* Write u's decimal digits at p (no NUL); returns the end. May write scratch bytes past the end,
 * never beyond p + 17 (SC_NUMBER_BUF from p is room enough). */
char *sc_number_put_u64(char *p, uint64_t u);

#ifdef __cplusplus
}
#endif
#endif
