/* selfcal/csv.h — a strict line reader for selfcal's CSV formats.
 *
 * Reads one line at a time, counts lines (1-based) for error messages, strips CR/LF, refuses NUL
 * bytes and over-long lines, splits at commas and parses numbers strictly (no trailing junk,
 * no NaN or infinity). Comment/header lines start with '#'.
 */
#ifndef SELFCAL_CSV_H
#define SELFCAL_CSV_H

#include <stdbool.h>
#include "selfcal/api.h"

#include <stdio.h>

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_CSV_MAX_FIELDS 64

/* Plausibility bound of any number read from an input file, in the file's own unit: 1e6 µm is
 * 1 m of error, 1e6 mm is 1 km of travel, 1e6 µrad is 1 rad. Beyond it nothing is a measurement
 * of a stage, and encodings, exporters and solvers could overflow: readers refuse such values
 * as bad input at their line. */
#define SC_INPUT_MAX_ABS 1.0e6
#define SC_CSV_MAX_LINE 65536
/* More comment ('#') or blank lines in a row than this is refused (an endless input of them, a
 * pipe from `yes '#'`, would otherwise be read forever): no measurement file has a million. */
#define SC_CSV_MAX_SKIP_RUN 1000000L
/* The reader's words for a NUL byte and for such a run (the run's with SC_CSV_MAX_SKIP_RUN as
 * its %ld), for the readers of the same text outside it (the DABAM reader, the CLI's copy of a
 * pipe), so that every one says it alike. */
#define SC_CSV_NUL_MSG "NUL byte in a text file (UTF-16? save it as UTF-8)"
#define SC_CSV_SKIP_RUN_MSG \
    "more than %ld comment or blank lines in a row: not a data file (an endless input?)"

typedef struct sc_csv {
    FILE *fp;
    int owns_fp;
    char path[256];
    long line;                       /* number of the current line, 1-based */
    char *text;                      /* the current line, without its line end (in buf) */
    size_t len;                      /* its length in bytes */
    int nfields;                     /* after sc_csv_split */
    char *field[SC_CSV_MAX_FIELDS];  /* point into text (split modifies it) */
    char *buf;                       /* read-ahead block of the file (the reader's own) */
    size_t buf_len, buf_pos;
    long long buf_off;               /* offset in the file of buf[0] */
    int eof;
    long skip_run;                   /* comment or blank lines just read in a row (a reader
                                        that takes a '#' line as data sets it to 0) */
} sc_csv;

/* The status of a failed open with errno errnum: a path that names nothing (or a directory) is
 * bad input (SC_E_INPUT); a refusal by the system (permission, I/O, no descriptors) is SC_E_IO. */
SC_API sc_status sc_open_failure_status(int errnum);

/* Open an input file for reading (binary); NULL with err set on failure. A missing file or a
 * directory is bad input (SC_E_INPUT: the user named the wrong thing); a file the system will not
 * let us read is SC_E_IO (sc_open_failure_status). */
SC_API FILE *sc_open_input(const char *path, sc_error *err);

/* Open path for reading ("-" reads stdin). */
SC_API sc_status sc_csv_open(sc_csv *r, const char *path, sc_error *err);

/* Close the file and free the read-ahead block; safe to call twice. */
SC_API void sc_csv_close(sc_csv *r);

/* Read the next line: r->text (NUL-terminated, valid until the next call) and r->len; 1 = a line,
 * 0 = end of file, -1 = error (err says which). */
SC_API int sc_csv_next_line(sc_csv *r, sc_error *err);

/* Is the current line empty or only white space? */
SC_API bool sc_csv_is_blank(const sc_csv *r);

/* Split the current line at commas, trimming blanks around fields; returns the field count or -1. */
SC_API int sc_csv_split(sc_csv *r, sc_error *err);

/* The fast path of a reader's data rows: is the current line exactly the fields that types lists
 * ('L' a whole number into longs[], 'D' a number into doubles[], in order), separated by single
 * commas with no blanks, each valid as sc_csv_long / sc_csv_double take it? True with the values
 * stored; false and the reader takes its general path (sc_csv_split, ...), which says what is
 * wrong. */
SC_API bool sc_csv_is_plain_row(const sc_csv *r, const char *types, long *longs, double *doubles);

/* Parse field k as a finite double; name is used in the error message. */
SC_API sc_status sc_csv_double(const sc_csv *r, int k, const char *name, double *out,
                               sc_error *err);

/* Parse field k as a whole number (decimal, optional sign). */
SC_API sc_status sc_csv_long(const sc_csv *r, int k, const char *name, long *out, sc_error *err);

/* Trim white space at both ends of s in place; returns the first non-blank character. */
SC_API char *sc_str_trim(char *s);

/* Parse s strictly as a finite double / a long: SC_OK and *out set, or SC_E_INPUT (no message:
 * the caller knows the field and the line; sc_csv_double/_long below say them). */
SC_API sc_status sc_parse_double(const char *s, double *out);
SC_API sc_status sc_parse_long(const char *s, long *out);

/* For a header line "# key = value", copy the trimmed key and point *value at the trimmed value
 * (the value is the rest of the line with trailing blanks removed in place). True if it has that form. */
SC_API bool sc_header_kv(char *line, char *key, size_t keylen, char **value);

#ifdef __cplusplus
}
#endif
#endif
