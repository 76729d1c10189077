/* io_common.c — owns what every reader and writer of io/ shares: the record loop, the row array
 * of the map readers, the atomic commit with its write-error check, the regular-spacing fit of positions in a file, and the fast
 * number output of the writers (selfcal/number.h), and how many cores a reader or writer may
 * spread over. */
#define _GNU_SOURCE /* sched_getaffinity */
#include <errno.h>
#include <math.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>

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

void sc_io_out_write(sc_io_out *o, const char *data, size_t len)
{
    errno = 0;
    if (fwrite(data, 1, len, o->f.fp) != len && !o->write_errno)
        o->write_errno = errno ? errno : EIO;
}

void sc_io_out_flush(sc_io_out *o)
{
    sc_io_out_write(o, o->buf, (size_t)(o->p - o->buf));
    o->p = o->buf;
}

sc_status sc_io_out_attach(sc_io_out *o, const sc_afile *f, sc_error *err)
{
    o->f = *f; /* the same FILE and paths: the caller's entry ends it */
    o->nomem = 0;
    o->write_errno = 0;
    o->buf = o->p = malloc(SC_IO_BLOCK);
    if (!o->buf)
        return sc_error_set(err, SC_E_NOMEM, f->path, 0, "out of memory");
    return SC_OK;
}

sc_status sc_io_out_drain(sc_io_out *o, sc_error *err)
{
    if (!o->nomem)
        sc_io_out_flush(o);
    free(o->buf);
    o->buf = o->p = NULL;
    if (o->nomem)
        return sc_error_set(err, SC_E_NOMEM, o->f.path, 0, "out of memory");
    if (o->write_errno)
        return sc_error_set(err, SC_E_IO, o->f.path, 0, "write error: %s",
                            strerror(o->write_errno));
    return SC_OK;
}

/* The deviating points of v against a + b·k (beyond tol): how many; *bad the one of smallest
 * line number (-1 if none), *dev its deviation. */
static size_t deviating(const double *k, const double *v, const long *lines, size_t n, double a,
                        double b, double tol, long *bad, double *dev)
{
    size_t count = 0;
    *bad = -1;
    *dev = 0;
    for (size_t m = 0; m < n; ++m) {
        double d = fabs(v[m] - (a + b * k[m]));
        if (!(d <= tol)) {
            count++;
            if (*bad < 0 || lines[m] < lines[*bad]) {
                *bad = (long)m;
                *dev = d;
            }
        }
    }
    return count;
}

/* The median of x[0..n-1] (n >= 1; x is reordered): Hoare's selection, twice for even n. */
static double select_kth(double *x, size_t n, size_t kth)
{
    size_t lo = 0, hi = n - 1;
    while (lo < hi) {
        double pivot = x[lo + (hi - lo) / 2];
        size_t i = lo, j = hi;
        while (i <= j) {
            while (x[i] < pivot)
                i++;
            while (x[j] > pivot)
                j--;
            if (i <= j) {
                double t = x[i];
                x[i] = x[j];
                x[j] = t;
                i++;
                if (j == 0)
                    break;
                j--;
            }
        }
        if (kth <= j)
            hi = j;
        else if (kth >= i)
            lo = i;
        else
            break;
    }
    return x[kth];
}

static double median(double *x, size_t n)
{
    double hi = select_kth(x, n, n / 2);
    if (n % 2)
        return hi;
    double lo = x[0]; /* the largest of the lower half, which selection left below n/2 */
    for (size_t m = 1; m < n / 2; ++m)
        lo = x[m] > lo ? x[m] : lo;
    return 0.5 * (lo + hi);
}

/* The robust reference line: the median of each index's values, the median of the slopes
 * between neighbouring indices, the median of the intercepts. k are whole numbers from kmin to
 * kmax (kmax - kmin < n). -1 if out of memory. */
static int robust_line(const double *k, const double *v, size_t n, double kmin, double kmax,
                       double *a, double *b)
{
    size_t groups = (size_t)(kmax - kmin) + 1;
    size_t *start = calloc(groups + 1, sizeof *start), *fill = malloc(groups * sizeof *fill);
    double *byk = malloc(n * sizeof *byk), *med = malloc(groups * sizeof *med);
    double *work = malloc(groups * sizeof *work);
    int ok = start && fill && byk && med && work;
    if (ok) {
        for (size_t m = 0; m < n; ++m)
            start[(size_t)(k[m] - kmin) + 1]++;
        for (size_t g = 0; g < groups; ++g)
            start[g + 1] += start[g], fill[g] = start[g];
        for (size_t m = 0; m < n; ++m)
            byk[fill[(size_t)(k[m] - kmin)]++] = v[m];
        size_t used = 0, slopes = 0;
        for (size_t g = 0; g < groups; ++g)
            if (start[g + 1] > start[g])
                med[g] = median(byk + start[g], start[g + 1] - start[g]);
        for (size_t g = 0, prev = 0; g < groups; ++g) {
            if (start[g + 1] == start[g])
                continue;
            if (used++)
                work[slopes++] = (med[g] - med[prev]) / (double)(g - prev);
            prev = g;
        }
        *b = slopes ? median(work, slopes) : 0.0;
        used = 0;
        for (size_t g = 0; g < groups; ++g)
            if (start[g + 1] > start[g])
                work[used++] = med[g] - *b * (kmin + (double)g);
        *a = median(work, used);
    }
    free(start), free(fill), free(byk), free(med), free(work);
    return ok ? 0 : -1;
}

void sc_io_index_range(const double *k, size_t n, size_t *lo, size_t *hi)
{
    *lo = *hi = 0;
    for (size_t m = 1; m < n; ++m) {
        if (k[m] < k[*lo])
            *lo = m;
        if (k[m] > k[*hi])
            *hi = m;
    }
}

int sc_io_fit_line(const double *k, const double *v, const long *lines, size_t n,
                   double tol_frac, double *a, double *b, double *slope, double *dev, long *bad)
{
    size_t lo, hi;
    sc_io_index_range(k, n, &lo, &hi);
    double b0 = k[hi] > k[lo] ? (v[hi] - v[lo]) / (k[hi] - k[lo]) : 0.0;
    double a0 = v[lo] - b0 * k[lo];
    size_t off = deviating(k, v, lines, n, a0, b0, tol_frac * fabs(b0), bad, dev);
    *slope = b0;
    if (off > 0 && k[hi] - k[lo] < (double)n) {
        /* the first point of the smallest or the largest index may be the bad one: then against
         * the medians' line, if fewer points deviate from it */
        double a1, b1, dev1;
        long bad1;
        if (robust_line(k, v, n, k[lo], k[hi], &a1, &b1) != 0)
            return -1;
        if (deviating(k, v, lines, n, a1, b1, tol_frac * fabs(b1), &bad1, &dev1) < off)
            *slope = b1, *bad = bad1, *dev = dev1;
    }
    sc_line_fit(k, v, n, a, b);
    return 0;
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
