/* io_common.c — owns what every reader and writer of io/ shares: the record loop, the row array
 * of the map readers, the atomic commit with its write-error check, the regular-spacing fit of positions in a file, and the fast
 * number output of the writers (selfcal/number.h), and how many cores a reader or writer may
 * spread over. */
#define _GNU_SOURCE /* sched_getaffinity */
#include <math.h>
#include <sched.h>
#include <stdlib.h>

#include "../common/line_fit.h"
#include "../common/number_internal.h"
#include "io_internal.h"
#include "selfcal/number.h"

int sc_io_next_record(sc_csv *r, sc_error *err)
{
    for (;;) {
        int rc = sc_csv_next_line(r, err);
        if (rc <= 0)
            return rc;
        if (r->text[0] == '#' || sc_csv_is_blank(r))
            continue;
        return sc_csv_split(r, err) < 0 ? -1 : 1;
    }
}

sc_status sc_io_read_rows(sc_csv *r, sc_io_rows *rows, sc_io_parse_row parse, void *ctx,
                          sc_error *err)
{
    int rc;
    while ((rc = sc_io_next_record(r, err)) > 0) {
        if (rows->n == rows->cap) {
            size_t cap = rows->cap ? 2 * rows->cap : 256;
            void *nr = realloc(rows->data, cap * rows->size);
            if (!nr)
                return sc_error_set(err, SC_E_NOMEM, r->path, r->line, "out of memory");
            rows->data = nr;
            rows->cap = cap;
        }
        sc_status st = parse(ctx, (char *)rows->data + rows->n * rows->size, rows, err);
        if (st != SC_OK)
            return st;
        ++rows->n;
    }
    return rc < 0 ? (err ? err->code : SC_E_INPUT) : SC_OK;
}

sc_status sc_io_read_table(const char *path, sc_csv *csv, sc_io_rows *rows,
                           const sc_io_table_steps *steps, void *ctx, sc_error *err)
{
    sc_status st = sc_csv_open(csv, path, err);
    if (st != SC_OK)
        return st;
    st = steps->header(ctx, err);
    if (st == SC_OK)
        st = sc_io_read_rows(csv, rows, steps->row, ctx, err);
    if (st == SC_OK)
        st = steps->build(ctx, err);
    free(rows->data);
    rows->data = NULL;
    sc_csv_close(csv);
    return st;
}

sc_status sc_io_finish(sc_afile *f, sc_error *err)
{
    if (ferror(f->fp)) {
        sc_afile_abort(f);
        return sc_error_set(err, SC_E_IO, f->path, 0, "write error");
    }
    return sc_afile_commit(f, err);
}

sc_status sc_io_out_open(sc_io_out *o, const char *path, sc_error *err)
{
    o->buf = o->p = NULL;
    o->nomem = 0;
    sc_status st = sc_afile_open(&o->f, path, err);
    if (st != SC_OK)
        return st;
    o->buf = o->p = malloc(SC_IO_BLOCK);
    if (!o->buf) {
        sc_afile_abort(&o->f);
        return sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    return SC_OK;
}

void sc_io_out_flush(sc_io_out *o)
{
    fwrite(o->buf, 1, (size_t)(o->p - o->buf), o->f.fp);
    o->p = o->buf;
}

sc_status sc_io_out_finish(sc_io_out *o, sc_error *err)
{
    if (!o->nomem)
        sc_io_out_flush(o);
    free(o->buf);
    o->buf = o->p = NULL;
    if (o->nomem) {
        sc_error_set(err, SC_E_NOMEM, o->f.path, 0, "out of memory");
        sc_afile_abort(&o->f);
        return SC_E_NOMEM;
    }
    return sc_io_finish(&o->f, err);
}

void sc_io_fit_line(const double *k, const double *v, const long *lines, size_t n,
                    double tol_frac, double *a, double *b, double *dev, long *bad)
{
    size_t lo = 0, hi = 0;
    for (size_t m = 1; m < n; ++m) {
        if (k[m] < k[lo])
            lo = m;
        if (k[m] > k[hi])
            hi = m;
    }
    double b0 = k[hi] > k[lo] ? (v[hi] - v[lo]) / (k[hi] - k[lo]) : 0.0;
    double tol = tol_frac * fabs(b0);
    *bad = -1;
    *dev = 0;
    for (size_t m = 0; m < n; ++m) {
        double d = fabs(v[m] - (v[lo] + b0 * (k[m] - k[lo])));
        if (d > tol && (*bad < 0 || lines[m] < lines[*bad])) {
            *bad = (long)m;
            *dev = d;
        }
    }
    sc_line_fit(k, v, n, a, b);
}

char *sc_io_put_shortest(char *p, const sc_number_shortest *d, char sep)
{
    p = sc_number_put_shortest(p, d);
    if (sep)
        *p++ = sep;
    return p;
}

char *sc_io_put_15g(char *p, double v, char sep)
{
    p += sc_number_format_15g(v, p);
    if (sep)
        *p++ = sep;
    return p;
}

char *sc_io_put_15g_opt(char *p, const double *a, size_t k, char sep)
{
    if (a && isfinite(a[k]))
        return sc_io_put_15g(p, a[k], sep);
    if (sep)
        *p++ = sep;
    return p;
}

char *sc_io_put_long(char *p, long v, char sep)
{
    unsigned long u = v < 0 ? 0UL - (unsigned long)v : (unsigned long)v;
    *p = '-';
    p = sc_number_put_u64(p + (v < 0), u);
    *p++ = sep;
    return p;
}

int sc_io_cpus_available(void)
{
    cpu_set_t set;
    return sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : 1;
}
