/* io_internal.h — helpers shared by the readers and writers of io/ (not installed). */
#ifndef SELFCAL_IO_INTERNAL_H
#define SELFCAL_IO_INTERNAL_H

#include <stddef.h>

#include "../common/number_internal.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"

/* Next non-blank, non-comment ('#') line, split into fields: 1, 0 at end of file, -1 on error. */
int sc_io_next_record(sc_csv *r, sc_error *err);

/* A growing array of rows parsed from a file (elements of `size` bytes; zero it to start). */
typedef struct sc_io_rows {
    void *data;
    size_t n, cap, size;
} sc_io_rows;

/* Parse the current record of the reader behind ctx into row (a fresh element); may look at the
 * rows kept so far (rows->n of them). */
typedef sc_status (*sc_io_parse_row)(void *ctx, void *row, const sc_io_rows *rows, sc_error *err);

/* Read every remaining record of r (sc_io_next_record), growing rows by doubling and parsing each
 * with parse(ctx, ...): the record loop of the map readers. Stops at the first error. */
sc_status sc_io_read_rows(sc_csv *r, sc_io_rows *rows, sc_io_parse_row parse, void *ctx,
                          sc_error *err);

/* The steps of a map reader over the reader ctx: the column header, each row, then the result
 * built from the rows. */
typedef struct sc_io_table_steps {
    sc_status (*header)(void *ctx, sc_error *err);
    sc_io_parse_row row;
    sc_status (*build)(void *ctx, sc_error *err);
} sc_io_table_steps;

/* Open path into csv, run the steps (rows through sc_io_read_rows), then free rows->data and
 * close csv: the skeleton every map reader shares. */
sc_status sc_io_read_table(const char *path, sc_csv *csv, sc_io_rows *rows,
                           const sc_io_table_steps *steps, void *ctx, sc_error *err);

/* Append the shortest round-trip text (selfcal/number.h) of digits found before
 * (sc_number_find_shortest), then sep unless it is 0; returns the end. The caller's buffer holds
 * SC_NUMBER_BUF bytes per number. A row's numbers are all found first, then laid out
 * (number_internal.h says why). */
char *sc_io_put_shortest(char *p, const sc_number_shortest *d, char sep);

/* Append v as printf's "%.15g" writes it (sc_number_format_15g), then sep unless it is 0;
 * returns the end. The caller's buffer holds SC_NUMBER_BUF bytes per number. */
char *sc_io_put_15g(char *p, double v, char sep);

/* As sc_io_put_15g for a[k], but nothing (only sep) when a is NULL or a[k] is not finite: the
 * optional columns of the map and residual files. */
char *sc_io_put_15g_opt(char *p, const double *a, size_t k, char sep);

/* Append a whole number in decimal, then sep; returns the end. Like the number writers above, it
 * may write scratch bytes past the end (up to 18 bytes from p): keep SC_NUMBER_BUF of room. */
char *sc_io_put_long(char *p, long v, char sep);

/* Rows of text gathered in a block and written to an atomic file in big chunks (one fwrite per
 * row cost more than formatting it). Write rows at o->p, then call sc_io_out_row. */
#define SC_IO_BLOCK (256 * 1024)
#define SC_IO_ROW_MAX 1024 /* the room kept for one row */
typedef struct sc_io_out {
    sc_afile f; /* the caller's atomic file (sc_io_out_attach), which it ends */
    char *buf, *p;
    int nomem;  /* sc_io_out_rows ran out of memory: sc_io_out_drain says it */
    int write_errno; /* errno of the first failed write (0: none): the error's reason */
} sc_io_out;

/* The block for rows into f, an atomic file the caller opened and will end (with others: all
 * or none); sc_io_out_drain writes the rest and frees the block without ending f. */
sc_status sc_io_out_attach(sc_io_out *o, const sc_afile *f, sc_error *err);
sc_status sc_io_out_drain(sc_io_out *o, sc_error *err);

/* Write the block out (to f.fp) and start it again. */
void sc_io_out_flush(sc_io_out *o);

/* fwrite to the file, keeping the errno of the first failure for sc_io_out_drain's message. */
void sc_io_out_write(sc_io_out *o, const char *data, size_t len);

/* After a row: write the block out once less than SC_IO_ROW_MAX bytes are left in it. */
static inline void sc_io_out_row(sc_io_out *o)
{
    if (o->p - o->buf > SC_IO_BLOCK - SC_IO_ROW_MAX)
        sc_io_out_flush(o);
}

/* The CPUs this thread may run on (1 if that cannot be told): the readers and writers use a
 * second thread only where there is a second core. */
int sc_io_cpus_available(void);

/* Format row i of ctx at p (room for SC_IO_ROW_MAX bytes); returns the end of the row. */
typedef char *(*sc_io_format_row)(const void *ctx, long i, char *p);

/* From this many rows on, sc_io_out_rows formats on two threads where two cores are free. */
#define SC_IO_PARALLEL_ROWS 32768

/* Write rows 0..n-1 (format(ctx, i, ...)) in order after what o holds. Large files where a
 * second core is free: both threads take chunks of 2048 rows to format as they come free, and
 * this one writes every chunk in order (row_writer.c);
 * the text is the same either way. format must be safe to call from two threads at once. Out of
 * memory for the chunks: nothing written, o->nomem set (sc_io_out_drain says it). */
void sc_io_out_rows(sc_io_out *o, long n, sc_io_format_row format, const void *ctx);

/* sc_io_out_rows with the row count from which two threads format (for the tests). */
void sc_io_out_rows_tuned(sc_io_out *o, long n, sc_io_format_row format, const void *ctx,
                          long parallel_from);

/* Fit v = a + b·k to points (k, v) in any order (k whole numbers, each index at least once),
 * lines[m] the file line of point m, and judge its regularity. The reference line goes through
 * the first points of the smallest and the largest k, so that one bad point shows alone; where
 * points deviate from it, the line of the medians (each index's median, the median slope between
 * neighbouring indices) is the reference instead if fewer deviate from that (the bad point was
 * one of the two). *slope: the reference's slope (whether v increases); *bad: the deviating point
 * (beyond tol_frac of the slope) with the smallest line number, or -1, *dev its deviation; a, b:
 * the least-squares line over all points. -1 if out of memory, else 0. */
int sc_io_fit_line(const double *k, const double *v, const long *lines, size_t n, double tol_frac,
                   double *a, double *b, double *slope, double *dev, long *bad);

/* The first point of the smallest k (*lo) and of the largest (*hi); n >= 1. */
void sc_io_index_range(const double *k, size_t n, size_t *lo, size_t *hi);

#endif
