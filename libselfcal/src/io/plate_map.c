/* plate_map.c — owns the plate error file `i,j,ax_um,ay_um` (SPEC §1, §5): its one strict reader
 * and its one writer (rules in selfcal/plate_map.h). `selfcal grid --artifact` and
 * `simulate grid` write through it. */
#include "selfcal/plate_map.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/number.h"
#include "io_internal.h"

static const char *const columns[4] = {"i", "j", "ax_um", "ay_um"};

typedef struct plate_row {
    long i, j, line;
    double ax, ay;
} plate_row;

typedef struct plate_reader {
    sc_csv csv;
    int ncols;
    sc_io_rows rows; /* of plate_row */
    sc_plate_map *out; /* what build_map fills */
} plate_reader;

static sc_status read_column_header(void *ctx, sc_error *err)
{
    plate_reader *r = ctx;
    int rc = sc_io_next_record(&r->csv, err);
    if (rc < 0)
        return err ? err->code : SC_E_INPUT;
    for (int k = 0; k < 4; ++k)
        if (rc == 0 || k >= r->csv.nfields || strcmp(r->csv.field[k], columns[k]) != 0)
            return sc_error_set(err, SC_E_INPUT, r->csv.path, r->csv.line,
                                "expected the plate error header i,j,ax_um,ay_um");
    r->ncols = r->csv.nfields;
    return SC_OK;
}

/* One value: NaN if empty. */
static sc_status value(const sc_csv *c, int k, double *v, sc_error *err)
{
    *v = NAN;
    if (c->field[k][0] == '\0')
        return SC_OK;
    sc_status st = sc_csv_double(c, k, columns[k], v, err);
    if (st == SC_OK && !(fabs(*v) <= SC_INPUT_MAX_ABS))
        st = sc_error_set(err, SC_E_INPUT, c->path, c->line,
                          "%s = %g um is not a plausible plate error (|value| <= 1 m)",
                          columns[k], *v);
    return st;
}

static sc_status parse_row(void *ctx, void *out, const sc_io_rows *rows, sc_error *err)
{
    (void)rows;
    const plate_reader *r = ctx;
    plate_row *row = out;
    const sc_csv *c = &r->csv;
    if (c->nfields != r->ncols)
        return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                            "expected %d fields (as the header), got %d", r->ncols, c->nfields);
    sc_status st;
    row->line = c->line;
    if ((st = sc_csv_long(c, 0, "i", &row->i, err)) != SC_OK ||
        (st = sc_csv_long(c, 1, "j", &row->j, err)) != SC_OK ||
        (st = value(c, 2, &row->ax, err)) != SC_OK || (st = value(c, 3, &row->ay, err)) != SC_OK)
        return st;
    if (isnan(row->ax) != isnan(row->ay))
        return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                            "ax_um and ay_um are both given or both empty");
    if (row->i < 0 || row->j < 0 || row->i >= SC_PLATE_MAP_MAX_N || row->j >= SC_PLATE_MAP_MAX_N)
        return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                            "mark (%ld,%ld) outside the supported plate (0 <= i, j < %d)", row->i,
                            row->j, SC_PLATE_MAP_MAX_N);
    return SC_OK;
}

/* n x n marks, each once, n odd. */
static sc_status build_map(void *ctx, sc_error *err)
{
    const plate_reader *r = ctx;
    sc_plate_map *m = r->out;
    const char *P = r->csv.path;
    const plate_row *rows = r->rows.data;
    size_t nrows = r->rows.n;
    int n = (int)lround(sqrt((double)nrows));
    if ((size_t)n * (size_t)n != nrows || n % 2 == 0 || n < 3)
        return sc_error_set(err, SC_E_INPUT, P, r->csv.line,
                            "%zu rows do not make an n x n plate with n odd and >= 3", nrows);
    size_t nn = nrows;
    long *line_of = calloc(nn, sizeof *line_of);
    m->ax_um = malloc(nn * sizeof(double));
    m->ay_um = malloc(nn * sizeof(double));
    if (!line_of || !m->ax_um || !m->ay_um) {
        free(line_of);
        return sc_error_set(err, SC_E_NOMEM, P, 0, "out of memory");
    }
    m->n = n;
    sc_status st = SC_OK;
    for (size_t q = 0; q < nrows && st == SC_OK; ++q) {
        const plate_row *row = &rows[q];
        size_t k = (size_t)row->i * (size_t)n + (size_t)row->j;
        if (row->i >= n || row->j >= n)
            st = sc_error_set(err, SC_E_INPUT, P, row->line,
                              "mark (%ld,%ld) is off the %d x %d plate", row->i, row->j, n, n);
        else if (line_of[k])
            st = sc_error_set(err, SC_E_INPUT, P, row->line, "mark (%ld,%ld) repeats line %ld",
                              row->i, row->j, line_of[k]);
        else {
            line_of[k] = row->line;
            m->ax_um[k] = row->ax;
            m->ay_um[k] = row->ay;
        }
    }
    free(line_of);
    return st;
}

static const sc_io_table_steps plate_steps = {read_column_header, parse_row, build_map};

sc_status sc_plate_map_read(const char *path, sc_plate_map *m, sc_error *err)
{
    memset(m, 0, sizeof *m);
    plate_reader r;
    memset(&r, 0, sizeof r);
    r.rows.size = sizeof(plate_row);
    r.out = m;
    sc_status st = sc_io_read_table(path, &r.csv, &r.rows, &plate_steps, &r, err);
    if (st != SC_OK)
        sc_plate_map_free(m);
    return st;
}

void sc_plate_map_free(sc_plate_map *m)
{
    free(m->ax_um);
    free(m->ay_um);
    memset(m, 0, sizeof *m);
}

void sc_plate_map_fprint(FILE *fp, const sc_plate_map *m)
{
    int n = m->n;
    fprintf(fp, "i,j,ax_um,ay_um\n");
    char line[4 * SC_NUMBER_BUF];
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            size_t k = (size_t)i * n + j;
            char *p = sc_io_put_long(line, i, ',');
            p = sc_io_put_long(p, j, ',');
            if (isfinite(m->ax_um[k]) && isfinite(m->ay_um[k])) {
                p = sc_io_put_15g(p, m->ax_um[k], ',');
                p = sc_io_put_15g(p, m->ay_um[k], '\n');
            } else {
                *p++ = ',';
                *p++ = '\n';
            }
            fwrite(line, 1, (size_t)(p - line), fp);
        }
}

sc_status sc_plate_map_write(const char *path, const sc_plate_map *m, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_plate_map_fprint(f.fp, m);
    return sc_afile_commit(&f, err); /* a write that failed: "write error: <reason>" */
}
