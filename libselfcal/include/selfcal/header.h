/* selfcal/header.h — a declarative parser for the `# key = value` header lines of selfcal's
 * text formats.
 *
 * A reader describes its keys once, in a table: the key, the type of its value, where in the
 * reader's own struct the value goes (offsetof), whether it is required, and its range. It then
 * feeds every header line to sc_header_line() and calls sc_header_finish() at the end of the
 * header. The parser reports, as SC_E_INPUT with FILE:LINE, a value that does not parse, a value
 * out of range, a key given twice (naming the first line) and a required key that is missing.
 * Lines that are not `key = value`, and keys not in the table, are left to the caller (format
 * extensions, or lines such as `# view 0: rot=0`).
 *
 * Example:
 *     static const sc_header_key keys[] = {
 *         {"N", SC_HEADER_LONG, offsetof(my_hdr, n), 1, 3, 1e8, 0},
 *         {"s_mm", SC_HEADER_DOUBLE, offsetof(my_hdr, s_mm), 1, 0, 1e6, SC_HEADER_MIN_EXCLUSIVE},
 *     };
 */
#ifndef SELFCAL_HEADER_H
#define SELFCAL_HEADER_H

#include <stddef.h>

#include <stdbool.h>

#include "selfcal/api.h"
#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_HEADER_MAX_KEYS 32

typedef enum sc_header_type {
    SC_HEADER_LONG,        /* a whole number, stored as long */
    SC_HEADER_DOUBLE,      /* a finite number, stored as double */
    SC_HEADER_DOUBLE_PAIR, /* "a,b": two finite numbers, stored as double[2] (range: each) */
    SC_HEADER_LONG_PAIR    /* "a,b": two whole numbers, stored as long[2] (range: each) */
} sc_header_type;

/* Flags of a key. */
#define SC_HEADER_MIN_EXCLUSIVE 1 /* the value must be > min (not >= min) */

typedef struct sc_header_key {
    const char *key;     /* as written before '=' (case-sensitive) */
    sc_header_type type;
    size_t offset;       /* offsetof the destination in the caller's struct */
    int required;        /* 1: sc_header_finish reports the key if it never appeared */
    double min, max;     /* inclusive range of each number (see flags) */
    int flags;
} sc_header_key;

typedef struct sc_header {
    const sc_header_key *keys;
    int n_keys;
    void *dst;                      /* the caller's struct the offsets refer to */
    long line[SC_HEADER_MAX_KEYS];  /* line where each key was given, 0 if not (yet) */
} sc_header;

/* Start parsing into dst with the key table keys[0..n_keys-1] (n_keys <= SC_HEADER_MAX_KEYS).
 * Values of keys that never appear are left as they are in dst (set defaults before). */
SC_API void sc_header_init(sc_header *h, const sc_header_key *keys, int n_keys, void *dst);

/* Feed one line of text (as read, starting with '#') at line `line` of file `path`.
 * *used = true if the line was `# key = value` with a key of the table (value stored), else false and
 * the line is untouched. SC_E_INPUT with FILE:LINE for a bad value, a value out of range or a
 * repeated key. used may be NULL. */
SC_API sc_status sc_header_line(sc_header *h, const char *path, long line, const char *text,
                                bool *used, sc_error *err);

/* End of the header: SC_E_INPUT naming the first required key that was not given, reported at
 * `line` (e.g. the line where the header ended). */
SC_API sc_status sc_header_finish(const sc_header *h, const char *path, long line, sc_error *err);

/* The line where key was given (0 if it was not, or is not in the table). */
SC_API long sc_header_line_of(const sc_header *h, const char *key);

#ifdef __cplusplus
}
#endif
#endif
