/* stage_map.c — owns the stage error map file (SPEC §1 output, §5 rectangles): the one strict
 * reader and the one writer of `i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um` (rules in
 * selfcal/stage_map.h). Grid writes through it; lut build, export and plot read through it. */
#include "selfcal/stage_map.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/number.h"
#include "io_internal.h"

static const char *const columns[8] = {"i", "j", "x_mm", "y_mm", "gx_um", "gy_um", "ugx_um",
                                       "ugy_um"};

typedef struct map_row {
    long i, j, line;
    double v[6]; /* x, y, gx, gy, ugx, ugy (NaN when empty) */
} map_row;

typedef struct map_reader {
    sc_csv csv;
    int ncols;       /* fields per row (the header's) */
    int has_u;       /* the header has ugx_um,ugy_um */
    sc_io_rows rows; /* of map_row */
    long maxi, maxj;
    sc_stage_map *out; /* what build_map fills */
} map_reader;

/* The column header: the six SPEC columns, the two uncertainties as a pair, anything after. */
static sc_status read_column_header(void *ctx, sc_error *err)
{
    map_reader *r = ctx;
    const char *P = r->csv.path;
    int rc = sc_io_next_record(&r->csv, err);
    if (rc < 0)
        return err ? err->code : SC_E_INPUT;
    if (rc == 0)
        return sc_error_set(err, SC_E_INPUT, P, r->csv.line, "empty map file (no header line)");
    for (int k = 0; k < 6; ++k)
        if (k >= r->csv.nfields || strcmp(r->csv.field[k], columns[k]) != 0)
            return sc_error_set(err, SC_E_INPUT, P, r->csv.line,
                                "expected the map header i,j,x_mm,y_mm,gx_um,gy_um[,ugx_um,ugy_um]"
                                "; column %d is '%.40s'",
                                k + 1, k < r->csv.nfields ? r->csv.field[k] : "");
    int u6 = r->csv.nfields > 6 && !strcmp(r->csv.field[6], columns[6]);
    int u7 = r->csv.nfields > 7 && !strcmp(r->csv.field[7], columns[7]);
    if (u6 != u7)
        return sc_error_set(err, SC_E_INPUT, P, r->csv.line,
                            "expected the map header i,j,x_mm,y_mm,gx_um,gy_um[,ugx_um,ugy_um]; "
                            "the uncertainties come as the pair ugx_um,ugy_um");
    r->has_u = u6;
    r->ncols = r->csv.nfields;
    return SC_OK;
}

/* Parse the current row into row; ranges checked here so that the message names the line. */
static sc_status parse_fields(const map_reader *r, map_row *row, sc_error *err)
{
    const sc_csv *c = &r->csv;
    if (c->nfields != r->ncols)
        return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                            "expected %d fields (as the header), got %d", r->ncols, c->nfields);
    sc_status st;
    row->line = c->line;
    if ((st = sc_csv_long(c, 0, "i", &row->i, err)) != SC_OK ||
        (st = sc_csv_long(c, 1, "j", &row->j, err)) != SC_OK)
        return st;
    for (int k = 2; k < 8; ++k) {
        double *v = &row->v[k - 2];
        *v = NAN;
        if (k >= 6 && (!r->has_u || c->field[k][0] == '\0'))
            continue;
        if ((st = sc_csv_double(c, k, columns[k], v, err)) != SC_OK)
            return st;
        if (k < 4 && !(fabs(*v) <= SC_INPUT_MAX_ABS))
            return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                                "%s = %g mm is outside +-1 km", columns[k], *v);
        if (!(fabs(*v) <= SC_INPUT_MAX_ABS))
            return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                                "%s = %g um is not a plausible stage error (|value| <= 1 m)",
                                columns[k], *v);
        if (k >= 6 && *v < 0)
            return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                                "%s = %g um: an uncertainty is not negative", columns[k], *v);
    }
    if (row->i < 0 || row->j < 0 || row->i >= SC_STAGE_MAP_MAX_NODES ||
        row->j >= SC_STAGE_MAP_MAX_NODES)
        return sc_error_set(err, SC_E_INPUT, c->path, c->line,
                            "node (%ld,%ld) outside the supported grid (0 <= i, j < %d)", row->i,
                            row->j, SC_STAGE_MAP_MAX_NODES);
    return SC_OK;
}

/* One row (sc_io_parse_row): its fields, then the node span so far. */
static sc_status parse_row(void *ctx, void *out, const sc_io_rows *rows, sc_error *err)
{
    map_reader *r = ctx;
    map_row *row = out;
    sc_status st = parse_fields(r, row, err);
    if (st != SC_OK)
        return st;
    r->maxi = row->i > r->maxi ? row->i : r->maxi;
    r->maxj = row->j > r->maxj ? row->j : r->maxj;
    /* Memory bounded by what is valid: distinct nodes within 0..maxi x 0..maxj number at
     * most (maxi+1)(maxj+1), so more rows than that means a repeated node; stop here
     * instead of keeping every row of an arbitrarily long file. */
    if ((unsigned long long)rows->n + 1 >
        (unsigned long long)(r->maxi + 1) * (unsigned long long)(r->maxj + 1))
        return sc_error_set(err, SC_E_INPUT, r->csv.path, r->csv.line,
                            "a node repeats: more rows than the %ld x %ld nodes they span "
                            "(node (%ld,%ld) or an earlier one)", r->maxj + 1, r->maxi + 1,
                            row->i, row->j);
    return SC_OK;
}

static sc_status alloc_map(sc_stage_map *m, const char *path, sc_error *err)
{
    size_t nn = (size_t)m->nx * (size_t)m->ny;
    double **arr[4] = {&m->gx_um, &m->gy_um, &m->ugx_um, &m->ugy_um};
    for (int a = 0; a < 4; ++a) {
        *arr[a] = malloc(nn * sizeof(double));
        if (!*arr[a])
            return sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    return SC_OK;
}

/* Put the rows on the nx x ny grid: each node once, none missing. line_of is nx*ny, zeroed. */
static sc_status place_rows(const map_reader *r, sc_stage_map *m, long *line_of, sc_error *err)
{
    const char *P = r->csv.path;
    const map_row *rows = r->rows.data;
    for (size_t q = 0; q < r->rows.n; ++q) {
        const map_row *row = &rows[q];
        size_t k = (size_t)row->i * (size_t)m->nx + (size_t)row->j;
        if (line_of[k])
            return sc_error_set(err, SC_E_INPUT, P, row->line,
                                "node (%ld,%ld) repeats line %ld", row->i, row->j, line_of[k]);
        line_of[k] = row->line;
        m->gx_um[k] = row->v[2];
        m->gy_um[k] = row->v[3];
        m->ugx_um[k] = row->v[4];
        m->ugy_um[k] = row->v[5];
    }
    for (int i = 0; i < m->ny; ++i)
        for (int j = 0; j < m->nx; ++j)
            if (!line_of[(size_t)i * m->nx + j])
                return sc_error_set(err, SC_E_INPUT, P, r->csv.line,
                                    "incomplete grid: node (%d,%d) of %d x %d is missing", i, j,
                                    m->ny, m->nx);
    return SC_OK;
}

/* Regularity of one axis (axis 0: x_mm against j, 1: y_mm against i); sets origin and pitch. */
static sc_status fit_axis(const map_reader *r, int axis, double *kk, double *vv, long *lines,
                          double *origin, double *pitch, sc_error *err)
{
    const char *P = r->csv.path, *name = axis ? "y_mm" : "x_mm", *idx = axis ? "i" : "j";
    const map_row *rows = r->rows.data;
    size_t nrows = r->rows.n;
    for (size_t q = 0; q < nrows; ++q) {
        kk[q] = (double)(axis ? rows[q].i : rows[q].j);
        vv[q] = rows[q].v[axis];
        lines[q] = rows[q].line;
    }
    double dev, slope;
    long worst;
    if (sc_io_fit_line(kk, vv, lines, nrows, SC_STAGE_MAP_REGULAR_TOL, origin, pitch, &slope, &dev,
                       &worst) != 0)
        return sc_error_set(err, SC_E_NOMEM, P, 0, "out of memory");
    /* whole-file properties, named at a row: the first row of the largest index, compared with
     * the first row of the smallest */
    size_t qmin, qmax;
    sc_io_index_range(kk, nrows, &qmin, &qmax);
    if (!(slope > 0))
        return sc_error_set(err, SC_E_INPUT, P, lines[qmax],
                            "%s does not increase with %s: %s = %g at %s = %g, %g at %s = %g "
                            "(line %ld)", name, idx, name, vv[qmax], idx, kk[qmax], vv[qmin],
                            idx, kk[qmin], lines[qmin]);
    if (worst >= 0)
        return sc_error_set(err, SC_E_INPUT, P, lines[worst],
                            "irregular grid: %s is %.3g mm off the regular grid (pitch %.6f mm)",
                            name, dev, slope);
    if (!(*pitch >= SC_STAGE_MAP_MIN_PITCH_MM))
        return sc_error_set(err, SC_E_INPUT, P, lines[qmax], "%c pitch %g mm is below 1 nm",
                            name[0], *pitch);
    return SC_OK;
}

/* From the rows read: dimensions, values, regular geometry. */
static sc_status build_map(void *ctx, sc_error *err)
{
    const map_reader *r = ctx;
    sc_stage_map *m = r->out;
    const char *P = r->csv.path;
    if (r->maxi < 1 || r->maxj < 1)
        return sc_error_set(err, SC_E_INPUT, P, r->csv.line,
                            "the map needs at least 2 x 2 nodes; it has %ld x %ld",
                            r->maxi < 0 ? 0 : r->maxi + 1, r->maxj < 0 ? 0 : r->maxj + 1);
    m->nx = (int)r->maxj + 1;
    m->ny = (int)r->maxi + 1;
    size_t nn = (size_t)m->nx * (size_t)m->ny, n = r->rows.n > nn ? r->rows.n : nn;
    long *line_of = calloc(nn, sizeof *line_of), *lines = malloc(n * sizeof *lines);
    double *kk = malloc(n * sizeof *kk), *vv = malloc(n * sizeof *vv);
    sc_status st = SC_OK;
    if (!line_of || !lines || !kk || !vv)
        st = sc_error_set(err, SC_E_NOMEM, P, 0, "out of memory");
    if (st == SC_OK)
        st = alloc_map(m, P, err);
    if (st == SC_OK)
        st = place_rows(r, m, line_of, err);
    if (st == SC_OK)
        st = fit_axis(r, 0, kk, vv, lines, &m->x0_mm, &m->px_mm, err);
    if (st == SC_OK)
        st = fit_axis(r, 1, kk, vv, lines, &m->y0_mm, &m->py_mm, err);
    free(line_of);
    free(lines);
    free(kk);
    free(vv);
    return st;
}

static const sc_io_table_steps map_steps = {read_column_header, parse_row, build_map};

sc_status sc_stage_map_read(const char *path, sc_stage_map *m, sc_error *err)
{
    memset(m, 0, sizeof *m);
    map_reader r;
    memset(&r, 0, sizeof r);
    r.rows.size = sizeof(map_row);
    r.maxi = r.maxj = -1;
    r.out = m;
    sc_status st = sc_io_read_table(path, &r.csv, &r.rows, &map_steps, &r, err);
    if (st != SC_OK)
        sc_stage_map_free(m);
    return st;
}

void sc_stage_map_free(sc_stage_map *m)
{
    free(m->gx_um);
    free(m->gy_um);
    free(m->ugx_um);
    free(m->ugy_um);
    memset(m, 0, sizeof *m);
}

bool sc_stage_map_has_u(const sc_stage_map *m)
{
    size_t nn = (size_t)m->nx * (size_t)m->ny;
    for (size_t k = 0; m->ugx_um && m->ugy_um && k < nn; ++k)
        if (isfinite(m->ugx_um[k]) || isfinite(m->ugy_um[k]))
            return true;
    return false;
}

double sc_stage_map_x_mm(const sc_stage_map *m, int j)
{
    return m->x0_mm + j * m->px_mm;
}

double sc_stage_map_y_mm(const sc_stage_map *m, int i)
{
    return m->y0_mm + i * m->py_mm;
}

void sc_stage_map_fprint(FILE *fp, const sc_stage_map *m)
{
    fprintf(fp, "i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n");
    char line[8 * SC_NUMBER_BUF];
    for (int i = 0; i < m->ny; ++i)
        for (int j = 0; j < m->nx; ++j) {
            size_t k = (size_t)i * m->nx + j;
            char *p = sc_io_put_long(line, i, ',');
            p = sc_io_put_long(p, j, ',');
            p = sc_io_put_15g(p, sc_stage_map_x_mm(m, j), ',');
            p = sc_io_put_15g(p, sc_stage_map_y_mm(m, i), ',');
            p = sc_io_put_15g(p, m->gx_um[k], ',');
            p = sc_io_put_15g(p, m->gy_um[k], ',');
            p = sc_io_put_15g_opt(p, m->ugx_um, k, ',');
            p = sc_io_put_15g_opt(p, m->ugy_um, k, '\n');
            fwrite(line, 1, (size_t)(p - line), fp);
        }
}

sc_status sc_stage_map_write(const char *path, const sc_stage_map *m, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_stage_map_fprint(f.fp, m);
    return sc_afile_commit(&f, err); /* a write that failed: "write error: <reason>" */
}
