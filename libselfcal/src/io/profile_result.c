/* profile_result.c — owns the profile output file `n,x_mm,f_um,uf_um,ey_um` (SPEC §2): its one
 * strict reader (used by `plot profile` and, for the ey_um column, by `lut build`) and its writer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/number.h"
#include "selfcal/profile_file.h"
#include "selfcal/stage_map.h" /* SC_STAGE_MAP_MIN_PITCH_MM */
#include "io_internal.h"

#define PROFILE_REGULAR_TOL 1e-3 /* of the step */

/* The result file's columns, for its rows' formatter. */
typedef struct result_rows {
    double s_mm;
    const double *f_um, *uf_um, *ey_um;
    long n_ey;
} result_rows;

static char *result_row(const void *ctx, long i, char *p)
{
    const result_rows *t = ctx;
    /* a point the data cannot determine (SPEC §2a) leaves its fields empty */
    int has_f = isfinite(t->f_um[i]), has_uf = t->uf_um != NULL && isfinite(t->uf_um[i]);
    int has_ey = t->ey_um && i < t->n_ey && isfinite(t->ey_um[i]);
    sc_number_shortest d[4]; /* every number's digits first, then the text */
    sc_number_find_shortest((double)i * t->s_mm, &d[0]);
    sc_number_find_shortest(has_f ? t->f_um[i] : 0.0, &d[1]);
    sc_number_find_shortest(has_uf ? t->uf_um[i] : 0.0, &d[2]);
    sc_number_find_shortest(has_ey ? t->ey_um[i] : 0.0, &d[3]);
    p = sc_io_put_long(p, i, ',');
    p = sc_io_put_shortest(p, &d[0], ',');
    if (has_f)
        p = sc_io_put_shortest(p, &d[1], 0);
    *p++ = ',';
    if (has_uf)
        p = sc_io_put_shortest(p, &d[2], 0);
    *p++ = ',';
    if (has_ey)
        p = sc_io_put_shortest(p, &d[3], 0);
    *p++ = '\n';
    return p;
}

sc_status sc_profile_write_result_to(sc_afile *f, int n, double s_mm, const double *f_um,
                                     const double *uf_um, const double *ey_um, int n_ey,
                                     sc_error *err)
{
    sc_io_out o;
    sc_status st = sc_io_out_attach(&o, f, err);
    if (st != SC_OK)
        return st;
    fputs("n,x_mm,f_um,uf_um,ey_um\n", o.f.fp);
    result_rows t = {s_mm, f_um, uf_um, ey_um, n_ey};
    sc_io_out_rows(&o, n, result_row, &t);
    return sc_io_out_drain(&o, err);
}

sc_status sc_profile_write_result(const char *path, int n, double s_mm, const double *f_um,
                                  const double *uf_um, const double *ey_um, int n_ey,
                                  sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    st = sc_profile_write_result_to(&f, n, s_mm, f_um, uf_um, ey_um, n_ey, err);
    return sc_afile_finish(&f, st, err);
}

void sc_profile_result_free(sc_profile_result *r)
{
    if (!r)
        return;
    free(r->x_mm);
    free(r->f_um);
    free(r->uf_um);
    free(r->ey_um);
    memset(r, 0, sizeof *r);
}

static const char *const names[5] = {"n", "x_mm", "f_um", "uf_um", "ey_um"};

typedef struct result_reader {
    sc_csv csv;
    int col[5], ncol;
    size_t cap;
    long *lines;         /* file line of each row */
    long first_empty_ey; /* line of the first row with an empty ey_um (0: none yet) */
    sc_profile_result res;
} result_reader;

static sc_status read_column_header(result_reader *rr, sc_error *err)
{
    sc_csv *r = &rr->csv;
    int rc = sc_io_next_record(r, err);
    if (rc < 0)
        return err ? err->code : SC_E_INPUT;
    for (int j = 0; j < 5; ++j)
        rr->col[j] = -1;
    for (int c = 0; rc > 0 && c < r->nfields; ++c)
        for (int j = 0; j < 5; ++j)
            if (!strcmp(r->field[c], names[j]) && rr->col[j] < 0)
                rr->col[j] = c;
    if (rr->col[0] < 0 || rr->col[1] < 0 || rr->col[2] < 0)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "expected a header naming the columns n, x_mm and f_um "
                            "(n,x_mm,f_um,uf_um,ey_um)");
    rr->ncol = r->nfields;
    rr->res.has_uf = rr->col[3] >= 0;
    rr->res.has_ey = rr->col[4] >= 0;
    rr->res.header_line = r->line;
    return SC_OK;
}

static sc_status grow(result_reader *rr, sc_error *err)
{
    size_t cap = rr->cap ? 2 * rr->cap : 1024;
    double **fld[4] = {&rr->res.x_mm, &rr->res.f_um, &rr->res.uf_um, &rr->res.ey_um};
    for (int j = 0; j < 4; ++j) {
        double *a = realloc(*fld[j], cap * sizeof(double));
        if (!a)
            return sc_error_set(err, SC_E_NOMEM, rr->csv.path, rr->csv.line, "out of memory");
        *fld[j] = a;
    }
    long *l = realloc(rr->lines, cap * sizeof *l);
    if (!l)
        return sc_error_set(err, SC_E_NOMEM, rr->csv.path, rr->csv.line, "out of memory");
    rr->lines = l;
    rr->cap = cap;
    return SC_OK;
}

/* One value of column j (1..4) of the current row: NaN where empty (uf, ey only). */
static sc_status row_value(result_reader *rr, int j, double *v, sc_error *err)
{
    const sc_csv *r = &rr->csv;
    int c = rr->col[j];
    *v = NAN;
    if (c < 0 || c >= r->nfields || r->field[c][0] == '\0') {
        if (j >= 3)
            return SC_OK;
        return sc_error_set(err, SC_E_INPUT, r->path, r->line, "%s is empty", names[j]);
    }
    sc_status st = sc_csv_double(r, c, names[j], v, err);
    if (st == SC_OK && !(fabs(*v) <= SC_INPUT_MAX_ABS))
        st = sc_error_set(err, SC_E_INPUT, r->path, r->line,
                          "%s = %g is beyond 1 m (or 1 km for x_mm)", names[j], *v);
    return st;
}

static sc_status read_row(result_reader *rr, sc_error *err)
{
    const sc_csv *r = &rr->csv;
    sc_profile_result *res = &rr->res;
    int last_optional = rr->col[3] == rr->ncol - 1 || rr->col[4] == rr->ncol - 1;
    if (r->nfields != rr->ncol && !(r->nfields == rr->ncol - 1 && last_optional))
        return sc_error_set(err, SC_E_INPUT, r->path, r->line, "expected %d fields, got %d",
                            rr->ncol, r->nfields);
    long idx;
    sc_status st = sc_csv_long(r, rr->col[0], "n", &idx, err);
    if (st != SC_OK)
        return st;
    if (idx != res->n)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line, "expected n = %d, got %ld", res->n,
                            idx);
    if ((size_t)res->n == rr->cap && (st = grow(rr, err)) != SC_OK)
        return st;
    double *dst[4] = {res->x_mm, res->f_um, res->uf_um, res->ey_um};
    for (int j = 1; j < 5; ++j)
        if ((st = row_value(rr, j, &dst[j - 1][res->n], err)) != SC_OK)
            return st;
    int has_ey = !isnan(res->ey_um[res->n]);
    if (has_ey && rr->first_empty_ey)
        return sc_error_set(err, SC_E_INPUT, r->path, rr->first_empty_ey,
                            "empty ey_um cell before further values (only trailing cells may be "
                            "empty)");
    if (!has_ey && !rr->first_empty_ey)
        rr->first_empty_ey = r->line;
    res->n_ey += has_ey;
    rr->lines[res->n++] = r->line;
    return SC_OK;
}

/* x_mm regular and increasing (SC_E_INPUT at the first line off the regular spacing). */
static sc_status check_regular(const result_reader *rr, sc_error *err)
{
    const sc_profile_result *res = &rr->res;
    if (res->n < 2)
        return SC_OK;
    double *k = malloc((size_t)res->n * sizeof *k);
    if (!k)
        return sc_error_set(err, SC_E_NOMEM, rr->csv.path, 0, "out of memory");
    for (int i = 0; i < res->n; ++i)
        k[i] = i;
    double a, b, slope, dev;
    long bad;
    int rc = sc_io_fit_line(k, res->x_mm, rr->lines, (size_t)res->n, PROFILE_REGULAR_TOL, &a, &b,
                            &slope, &dev, &bad);
    free(k);
    if (rc != 0)
        return sc_error_set(err, SC_E_NOMEM, rr->csv.path, 0, "out of memory");
    if (!(slope > 0))
        return sc_error_set(err, SC_E_INPUT, rr->csv.path, rr->lines[res->n - 1],
                            "x_mm does not increase with n: %g here, %g at the first point "
                            "(line %ld)",
                            res->x_mm[res->n - 1], res->x_mm[0], rr->lines[0]);
    if (bad >= 0)
        return sc_error_set(err, SC_E_INPUT, rr->csv.path, rr->lines[bad],
                            "irregular profile: x_mm is %.3g mm off the regular spacing %.6f mm",
                            dev, slope);
    if (!(b >= SC_STAGE_MAP_MIN_PITCH_MM)) /* as a map's pitch: what a table can place */
        return sc_error_set(err, SC_E_INPUT, rr->csv.path, rr->lines[1],
                            "x_mm spacing %g mm is below 1 nm", b);
    return SC_OK;
}

sc_status sc_profile_read_result(const char *path, sc_profile_result *out, sc_error *err)
{
    memset(out, 0, sizeof *out);
    result_reader rr;
    memset(&rr, 0, sizeof rr);
    sc_status st = sc_csv_open(&rr.csv, path, err);
    if (st != SC_OK)
        return st;
    st = read_column_header(&rr, err);
    int rc = 0;
    while (st == SC_OK && (rc = sc_io_next_record(&rr.csv, err)) == 1)
        st = read_row(&rr, err);
    if (st == SC_OK && rc < 0)
        st = err ? err->code : SC_E_INPUT;
    if (st == SC_OK && rr.res.n == 0)
        st = sc_error_set(err, SC_E_INPUT, rr.csv.path, rr.csv.line, "no data rows");
    if (st == SC_OK)
        st = check_regular(&rr, err);
    rr.res.last_line = rr.csv.line;
    free(rr.lines);
    sc_csv_close(&rr.csv);
    if (st != SC_OK) {
        sc_profile_result_free(&rr.res);
        return st;
    }
    *out = rr.res;
    return SC_OK;
}

/* The residual file's columns, for its rows' formatter. */
typedef struct residual_rows {
    int m0;
    const double *r_um[2], *t[2];
    const unsigned char *outlier[2];
} residual_rows;

static char *residual_row(const void *ctx, long i, char *p)
{
    const residual_rows *t = ctx;
    int k = i >= t->m0;
    long j = k ? i - t->m0 : i;
    p = sc_io_put_long(p, k + 1, ',');
    p = sc_io_put_long(p, j, ',');
    p = sc_io_put_15g_opt(p, t->r_um[k], (size_t)j, ',');
    p = sc_io_put_15g_opt(p, t->t[k], (size_t)j, ',');
    return sc_io_put_long(p, t->outlier[k][j] != 0, '\n');
}

sc_status sc_profile_write_residuals_to(sc_afile *f, int n, const int d[2],
                                        const double *const r_um[2], const double *const t[2],
                                        const unsigned char *const outlier[2], sc_error *err)
{
    sc_io_out o;
    sc_status st = sc_io_out_attach(&o, f, err);
    if (st != SC_OK)
        return st;
    fputs("scan,n,r_um,t,outlier\n", o.f.fp);
    residual_rows rr = {n - d[0], {r_um[0], r_um[1]}, {t[0], t[1]}, {outlier[0], outlier[1]}};
    sc_io_out_rows(&o, 2L * n - d[0] - d[1], residual_row, &rr);
    return sc_io_out_drain(&o, err);
}
