/* lut_csv.c — fill a table from the files: the stage map (read by io/, selfcal/stage_map.h) and
 * the ey_um column of a SPEC §2 profile output, strict, with the file and line of every problem. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/correct.h"
#include "selfcal/csv.h"
#include "../core/lut_format.h"
#include "selfcal/lut.h"
#include "selfcal/stage_map.h"
#include "../io/io_internal.h"

/* Regularity tolerance: a node may sit this fraction of a pitch off the fitted regular grid
 * (covers the rounding of printed coordinates; a real irregularity is a sizeable fraction). */
#define SC_LUT_REGULAR_TOL 1e-3

static int find_column(const sc_csv *r, const char *name)
{
    for (int k = 0; k < r->nfields; ++k)
        if (strcmp(r->field[k], name) == 0)
            return k;
    return -1;
}

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

sc_status sc_lut_set_grid(sc_lut *lut, const sc_stage_map *m, const char *name, sc_error *err)
{
    if (m->nx > SC_LUT_MAX_NX || m->ny > SC_LUT_MAX_NY)
        return sc_error_set(err, SC_E_INPUT, name, 0,
                            "the map has %d x %d nodes; a table holds at most %d x %d", m->nx,
                            m->ny, SC_LUT_MAX_NX, SC_LUT_MAX_NY);
    if (!(m->px_mm >= SC_LUTF_MIN_PITCH_MM && m->py_mm >= SC_LUTF_MIN_PITCH_MM))
        return sc_error_set(err, SC_E_INPUT, name, 0, "pitch %g x %g mm is below the table's 1 nm",
                            m->px_mm, m->py_mm);
    size_t nn = (size_t)m->nx * (size_t)m->ny;
    memcpy(lut->gx_um, m->gx_um, nn * sizeof(double));
    memcpy(lut->gy_um, m->gy_um, nn * sizeof(double));
    lut->nx = m->nx;
    lut->ny = m->ny;
    lut->x0_mm = m->x0_mm;
    lut->y0_mm = m->y0_mm;
    lut->px_mm = m->px_mm;
    lut->py_mm = m->py_mm;
    return SC_OK;
}

sc_status sc_lut_read_map(const char *path, sc_lut *lut, sc_error *err)
{
    sc_stage_map m;
    sc_status st = sc_stage_map_read(path, &m, err);
    if (st == SC_OK)
        st = sc_lut_set_grid(lut, &m, path, err);
    sc_stage_map_free(&m);
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
    int rc = sc_io_next_record(&r, err);
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
    while ((rc = sc_io_next_record(&r, err)) > 0) {
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
    sc_io_fit_line(kk, xs, lines, (size_t)count, SC_LUT_REGULAR_TOL, &x0, &step, &dev, &worst);
    if (!(step > 0)) {
        st = sc_error_set(err, SC_E_INPUT, path, lines[count - 1],
                          "x_mm does not increase with n: %g here, %g at the first point (line %ld)",
                          xs[count - 1], xs[0], lines[0]);
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
