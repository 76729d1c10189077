/* lut_csv.c — read the SPEC §1 stage error map and the SPEC §2 profile output for `lut build`
 * and the exporters: strict, with the file and line of every problem. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/correct.h"
#include "selfcal/csv.h"
#include "../core/lut_format.h"
#include "selfcal/lut.h"

/* Regularity tolerance: a node may sit this fraction of a pitch off the fitted regular grid
 * (covers the rounding of printed coordinates; a real irregularity is a sizeable fraction). */
#define SC_LUT_REGULAR_TOL 1e-3

/* Next non-blank, non-comment line split into fields: 1, 0 at end of file, -1 on error. */
static int next_record(sc_csv *r, sc_error *err)
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

static int find_column(const sc_csv *r, const char *name)
{
    for (int k = 0; k < r->nfields; ++k)
        if (strcmp(r->field[k], name) == 0)
            return k;
    return -1;
}

/* Fit v = a + b * k to points (k, v) given in any order, with lines[m] the file line of point m.
 * Regularity is judged against the line through the points with the smallest and largest k
 * (first of each), so that one bad point shows up alone; *bad = index of the deviating point with
 * the smallest line number (or -1). The returned a, b are the least-squares line over all points. */
/* Physical ranges (SC_INPUT_MAX_ABS), checked where the file is read so that the message names
 * the line: a position within 1 km (the table's own limit), an error within 1 m. */

static sc_status check_position(const char *path, long line, const char *name, double v,
                                sc_error *err)
{
    if (v >= -SC_INPUT_MAX_ABS && v <= SC_INPUT_MAX_ABS)
        return SC_OK;
    return sc_error_set(err, SC_E_INPUT, path, line, "%s = %g mm is outside +-1 km", name, v);
}

static sc_status check_error(const char *path, long line, const char *name, double v,
                             sc_error *err)
{
    if (v >= -SC_INPUT_MAX_ABS && v <= SC_INPUT_MAX_ABS)
        return SC_OK;
    return sc_error_set(err, SC_E_INPUT, path, line,
                        "%s = %g um is not a plausible stage error (|value| <= 1 m)", name, v);
}

static void fit_line(const double *k, const double *v, const long *lines, size_t n, double tol_frac,
                     double *a, double *b, double *dev, long *bad)
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
    double km = 0, vm = 0;
    for (size_t m = 0; m < n; ++m) {
        km += k[m];
        vm += v[m];
    }
    km /= (double)n;
    vm /= (double)n;
    double skk = 0, skv = 0;
    for (size_t m = 0; m < n; ++m) {
        skk += (k[m] - km) * (k[m] - km);
        skv += (k[m] - km) * (v[m] - vm);
    }
    *b = skk > 0 ? skv / skk : 0.0;
    *a = vm - *b * km;
}

static const char *const map_columns[6] = {"i", "j", "x_mm", "y_mm", "gx_um", "gy_um"};

sc_status sc_lut_read_map(const char *path, sc_lut *lut, sc_error *err)
{
    const size_t cap = (size_t)SC_LUT_MAX_NX * SC_LUT_MAX_NY;
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    /* Per slot (i * MAX_NX + j): the line it came from (0 = not seen) and its x, y. */
    long *line_of = calloc(cap, sizeof *line_of);
    double *xs = malloc(cap * sizeof *xs), *ys = malloc(cap * sizeof *ys);
    double *kk = malloc(cap * sizeof *kk), *vv = malloc(cap * sizeof *vv);
    long *lines = malloc(cap * sizeof *lines);
    if (!line_of || !xs || !ys || !kk || !vv || !lines) {
        st = sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
        goto done;
    }
    int rc = next_record(&r, err);
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto done;
    }
    if (rc == 0) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line, "empty map file (no header line)");
        goto done;
    }
    for (int k = 0; k < 6; ++k)
        if (k >= r.nfields || strcmp(r.field[k], map_columns[k]) != 0) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "expected the map header i,j,x_mm,y_mm,gx_um,gy_um,...; column %d is "
                              "'%.40s'",
                              k + 1, k < r.nfields ? r.field[k] : "");
            goto done;
        }
    const int ncols = r.nfields;
    int maxi = -1, maxj = -1;
    size_t nrows = 0;
    while ((rc = next_record(&r, err)) > 0) {
        if (r.nfields != ncols) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "%d fields, the header has %d",
                              r.nfields, ncols);
            goto done;
        }
        long i, j;
        double x, y, gx, gy;
        if ((st = sc_csv_long(&r, 0, "i", &i, err)) != SC_OK ||
            (st = sc_csv_long(&r, 1, "j", &j, err)) != SC_OK ||
            (st = sc_csv_double(&r, 2, "x_mm", &x, err)) != SC_OK ||
            (st = sc_csv_double(&r, 3, "y_mm", &y, err)) != SC_OK ||
            (st = sc_csv_double(&r, 4, "gx_um", &gx, err)) != SC_OK ||
            (st = sc_csv_double(&r, 5, "gy_um", &gy, err)) != SC_OK)
            goto done;
        if ((st = check_position(path, r.line, "x_mm", x, err)) != SC_OK ||
            (st = check_position(path, r.line, "y_mm", y, err)) != SC_OK ||
            (st = check_error(path, r.line, "gx_um", gx, err)) != SC_OK ||
            (st = check_error(path, r.line, "gy_um", gy, err)) != SC_OK)
            goto done;
        if (i < 0 || j < 0 || i >= SC_LUT_MAX_NY || j >= SC_LUT_MAX_NX) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "node (%ld,%ld) outside the supported grid (i < %d, j < %d)", i, j,
                              SC_LUT_MAX_NY, SC_LUT_MAX_NX);
            goto done;
        }
        size_t slot = (size_t)i * SC_LUT_MAX_NX + (size_t)j;
        if (line_of[slot]) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "node (%ld,%ld) repeats line %ld", i,
                              j, line_of[slot]);
            goto done;
        }
        line_of[slot] = r.line;
        xs[slot] = x;
        ys[slot] = y;
        lut->gx_um[slot] = gx; /* compacted below */
        lut->gy_um[slot] = gy;
        if (i > maxi)
            maxi = (int)i;
        if (j > maxj)
            maxj = (int)j;
        ++nrows;
    }
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto done;
    }
    const int nx = maxj + 1, ny = maxi + 1;
    if (nx < 2 || ny < 2) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line,
                          "the map needs at least 2 x 2 nodes; it has %d x %d", nx < 0 ? 0 : nx,
                          ny < 0 ? 0 : ny);
        goto done;
    }
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j)
            if (!line_of[(size_t)i * SC_LUT_MAX_NX + j]) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                  "incomplete grid: node (%d,%d) of %d x %d is missing", i, j, ny,
                                  nx);
                goto done;
            }
    /* Regularity: x depends on j only, y on i only, both linearly. */
    size_t n = 0;
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j, ++n) {
            size_t slot = (size_t)i * SC_LUT_MAX_NX + j;
            kk[n] = j;
            vv[n] = xs[slot];
            lines[n] = line_of[slot];
        }
    double x0, px, y0, py, dev;
    long worst;
    fit_line(kk, vv, lines, n, SC_LUT_REGULAR_TOL, &x0, &px, &dev, &worst);
    if (!(px > 0)) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "x_mm does not increase with j (pitch %g mm)", px);
        goto done;
    }
    if (!(px >= SC_LUTF_MIN_PITCH_MM)) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "x pitch %g mm is below the table's 1 nm", px);
        goto done;
    }
    if (worst >= 0) {
        st = sc_error_set(err, SC_E_INPUT, path, lines[worst],
                          "irregular grid: x_mm is %.3g mm off the regular grid (pitch %.6f mm)",
                          dev, px);
        goto done;
    }
    n = 0;
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j, ++n) {
            size_t slot = (size_t)i * SC_LUT_MAX_NX + j;
            kk[n] = i;
            vv[n] = ys[slot];
        }
    fit_line(kk, vv, lines, n, SC_LUT_REGULAR_TOL, &y0, &py, &dev, &worst);
    if (!(py > 0)) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "y_mm does not increase with i (pitch %g mm)", py);
        goto done;
    }
    if (!(py >= SC_LUTF_MIN_PITCH_MM)) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "y pitch %g mm is below the table's 1 nm", py);
        goto done;
    }
    if (worst >= 0) {
        st = sc_error_set(err, SC_E_INPUT, path, lines[worst],
                          "irregular grid: y_mm is %.3g mm off the regular grid (pitch %.6f mm)",
                          dev, py);
        goto done;
    }
    /* Compact from stride SC_LUT_MAX_NX to stride nx (in place: destinations never pass sources). */
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j) {
            lut->gx_um[(size_t)i * nx + j] = lut->gx_um[(size_t)i * SC_LUT_MAX_NX + j];
            lut->gy_um[(size_t)i * nx + j] = lut->gy_um[(size_t)i * SC_LUT_MAX_NX + j];
        }
    (void)nrows;
    lut->nx = nx;
    lut->ny = ny;
    lut->x0_mm = x0;
    lut->y0_mm = y0;
    lut->px_mm = px;
    lut->py_mm = py;
    st = SC_OK;
done:
    sc_csv_close(&r);
    free(line_of);
    free(xs);
    free(ys);
    free(kk);
    free(vv);
    free(lines);
    return st;
}

sc_status sc_lut_read_profile(const char *path, int axis, int dir, sc_lut_profile *p,
                              sc_error *err)
{
    if (axis < 0 || axis > 2 || dir < 0 || dir > 2)
        return sc_error_set(err, SC_E_INPUT, path, 0, "profile axis/dir must be x, y or z");
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    double kk[SC_LUT_MAX_PROFILE_POINTS], xs[SC_LUT_MAX_PROFILE_POINTS];
    long lines[SC_LUT_MAX_PROFILE_POINTS];
    int rc = next_record(&r, err);
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto done;
    }
    if (rc == 0) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line, "empty profile file (no header line)");
        goto done;
    }
    const int cn = find_column(&r, "n"), cx = find_column(&r, "x_mm"), ce = find_column(&r, "ey_um");
    if (cn != 0 || cx < 0 || ce < 0) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line,
                          "expected the profile header n,x_mm,f_um,uf_um,ey_um");
        goto done;
    }
    const int ncols = r.nfields;
    long expect = 0, first_empty = 0;
    int count = 0;
    while ((rc = next_record(&r, err)) > 0) {
        /* The last column may be missing entirely where it is empty. */
        if (r.nfields != ncols && !(r.nfields == ncols - 1 && ce == ncols - 1)) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "%d fields, the header has %d",
                              r.nfields, ncols);
            goto done;
        }
        long n;
        double x, e;
        if ((st = sc_csv_long(&r, cn, "n", &n, err)) != SC_OK ||
            (st = sc_csv_double(&r, cx, "x_mm", &x, err)) != SC_OK)
            goto done;
        if (n != expect) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "n = %ld where %ld was expected", n,
                              expect);
            goto done;
        }
        ++expect;
        int empty = ce >= r.nfields || r.field[ce][0] == '\0';
        if (empty) {
            if (!first_empty)
                first_empty = r.line;
            continue;
        }
        if (first_empty) {
            st = sc_error_set(err, SC_E_INPUT, path, first_empty,
                              "empty ey_um cell before further values (only trailing cells may be empty)");
            goto done;
        }
        if ((st = sc_csv_double(&r, ce, "ey_um", &e, err)) != SC_OK ||
            (st = check_position(path, r.line, "x_mm", x, err)) != SC_OK ||
            (st = check_error(path, r.line, "ey_um", e, err)) != SC_OK)
            goto done;
        if (count >= SC_LUT_MAX_PROFILE_POINTS) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "more than %d profile points",
                              SC_LUT_MAX_PROFILE_POINTS);
            goto done;
        }
        kk[count] = count;
        xs[count] = x;
        lines[count] = r.line;
        p->err_um[count] = e;
        ++count;
    }
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto done;
    }
    if (count < 2) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line,
                          "the profile has %d ey_um values; at least 2 are needed", count);
        goto done;
    }
    double x0, step, dev;
    long worst;
    fit_line(kk, xs, lines, (size_t)count, SC_LUT_REGULAR_TOL, &x0, &step, &dev, &worst);
    if (!(step > 0)) {
        st = sc_error_set(err, SC_E_INPUT, path, 0, "x_mm does not increase with n");
        goto done;
    }
    if (worst >= 0) {
        st = sc_error_set(err, SC_E_INPUT, path, lines[worst],
                          "irregular profile: x_mm is %.3g mm off the regular spacing %.6f mm", dev,
                          step);
        goto done;
    }
    p->axis = axis;
    p->dir = dir;
    p->n = count;
    p->start_mm = x0;
    p->step_mm = step;
    p->encoding = 0;
    p->scale_pm = 0;
    st = SC_OK;
done:
    sc_csv_close(&r);
    return st;
}
