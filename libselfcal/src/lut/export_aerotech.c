/* export_aerotech.c — the stage error map as an Aerotech Automation1 2-D axis calibration file
 * (`selfcal export --format aerotech-a1`, docs/exporters.md).
 *
 * Followed: Automation1 help, "Axis Calibration" (help.aerotech.com/automation1/Content/
 * Axis-Calibration.htm), the part we could read (its opening): a calibration file holds tables
 * of one kind, UTF-8; a 2-D table corrects two output axes from the positions of two reference
 * axes; tables add up; between reference positions linear interpolation, and "if the position of
 * the reference axis is not within the values in the table ... the nearest end point of the table
 * is used" (that is selfcald's clamping); axis indices in files are one-based; "all calibration
 * tables follow the sign of the encoder" (ReverseMotionDirection has no effect on them); all
 * corrections are bidirectional.
 *
 * Written: one table, the map's own nodes (so the controller's bilinear interpolation is the
 * map's), rows along y (the row axis), columns along x, each row NumCols pairs (correction of
 * output axis 1 = x, output axis 2 = y):
 *   :START2D RowAxis ColumnAxis OutputAxis1 OutputAxis2 SampleDistRow SampleDistCol NumCols
 *   :START2D POSUNIT=PRIMARY CORUNIT=PRIMARY/1000 OFFSETROW=.. OFFSETCOL=..
 *   ... rows ...
 *   :END
 * The stored copy of the help page we could read stops after its opening sections; the keyword
 * layout above, CORUNIT=PRIMARY/1000, NEGCOR and the OFFSET convention are those of public
 * calibration scripts written for A3200 and Automation1 controllers (one of them Aerotech's own
 * factory tool for 1-D files, whose corrections are the negated measured error, commanded -
 * measured). Open points, said in the file and in docs/exporters.md: the sign (taken as what is
 * added to the commanded position, +G; --negate writes -G, as NEGCOR would), the axis binding
 * (--axis-numbers NX,NY give the one-based indices of x and y), the units (primary units taken
 * as mm, corrections PRIMARY/1000 = um) and OFFSETROW/OFFSETCOL, written as the NEGATIVE of the
 * first row's and column's positions (those scripts' convention: table index = (position +
 * OFFSET) / SampleDist); --offset moves the map into machine coordinates. Straightness
 * profiles go to a 1-D file of their own (a calibration file holds tables of one kind):
 * export_aerotech_1d.c. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "export_internal.h"

typedef struct a1_ctx {
    int ncols, nrows;
    double x0, y0, dx, dy;  /* mm: the first column's and row's positions and the steps */
    long long *code;        /* [row * ncols + col][2]: corrections of x and y, 1e-4 um */
} a1_ctx;

/* Automation1's rule for a 2-D table: bilinear between the reference positions, the nearest end
 * point of the table beyond them (each reference axis clamped to the table). */
static double a1_eval(const void *vctx, int comp, double x, double y)
{
    const a1_ctx *c = vctx;
    double u = fmin(fmax((x - c->x0) / c->dx, 0.0), c->ncols - 1.0);
    double v = fmin(fmax((y - c->y0) / c->dy, 0.0), c->nrows - 1.0);
    int i = (int)u, j = (int)v;
    if (i > c->ncols - 2)
        i = c->ncols - 2;
    if (j > c->nrows - 2)
        j = c->nrows - 2;
    const double fu = u - i, fv = v - j;
    const long long *r0 = c->code + 2 * ((size_t)j * c->ncols), *r1 = r0 + 2 * c->ncols;
    const double a = (double)r0[2 * i + comp] * (1 - fu) + (double)r0[2 * (i + 1) + comp] * fu;
    const double b = (double)r1[2 * i + comp] * (1 - fu) + (double)r1[2 * (i + 1) + comp] * fu;
    return (a * (1 - fv) + b * fv) * SC_EXPORT_AEROTECH_UNIT_UM;
}

/* A code of 1e-4 um as its decimal text, exactly. */
static void a1_value(char *buf, size_t cap, long long v)
{
    snprintf(buf, cap, "%s%lld.%04lld", v < 0 ? "-" : "", llabs(v) / 10000, llabs(v) % 10000);
}

static sc_status export_aerotech(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                               sc_export_report *rep, sc_error *err)
{
    if (o->cross_profile >= 0) /* the profiles' 1-D file */
        return sc_export_aerotech_1d(lut, o, t, rep, err);
    if (o->interval_mm > 0 || o->use_line)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "aerotech-a1: the table takes the map's own nodes (no interval, no "
                            "line)");
    a1_ctx c;
    c.ncols = lut->nx;
    c.nrows = lut->ny;
    c.x0 = lut->x0_mm;
    c.y0 = lut->y0_mm;
    c.dx = lut->px_mm;
    c.dy = lut->py_mm;
    c.code = malloc(sizeof *c.code * 2 * (size_t)c.ncols * (size_t)c.nrows);
    if (!c.code)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    const double sign = o->negate ? -1.0 : 1.0;
    rep->limit_um = o->limit_um;
    for (int r = 0; r < c.nrows; ++r)
        for (int k = 0; k < c.ncols; ++k)
            for (int comp = 0; comp < 2; ++comp) {
                const double *g = comp == 0 ? lut->gx_um : lut->gy_um;
                c.code[2 * ((size_t)r * c.ncols + k) + comp] = sc_export_quantize(
                    sign * g[r * lut->nx + k], SC_EXPORT_AEROTECH_UNIT_UM, o->limit_um,
                    &rep->clipped);
            }
    const int comps[2] = {0, 1};
    sc_export_residual(lut, comps, 2, sign, a1_eval, &c, rep);
    rep->tables = 1;
    rep->points[0] = c.ncols;
    rep->points[1] = c.nrows;
    rep->interval_mm = c.dx;
    rep->unit_um = SC_EXPORT_AEROTECH_UNIT_UM;

    const int ax = o->beckhoff_x_axis_nr, ay = o->beckhoff_y_axis_nr;
    sc_tb_printf(t, "; Automation1 2-D axis calibration table, written by selfcal export\n");
    sc_tb_printf(t, "; corrections of axis %d (x) and axis %d (y) = %sG of the stage error map "
                    "(G = indicated - true), um\n", ax, ay, sign > 0 ? "+" : "-");
    sc_tb_printf(t, "; %s\n", sign > 0 ? "assumed: a correction is added to the commanded "
                                         "position (the table follows the encoder's sign)"
                                       : "NEGATED: -G, the opposite of the default");
    sc_tb_printf(t, "; rows: y (axis %d) from %.6f mm step %.6f mm; columns: x (axis %d) from "
                    "%.6f mm step %.6f mm (OFFSETROW/OFFSETCOL: minus those first positions); "
                    "beyond the table Automation1 holds its nearest end point\n",
                 ay, c.y0, c.dy, ax, c.x0, c.dx);
    sc_tb_printf(t, "; residual (table - map): rms %.5f um, max %.5f um; clipped points: %ld\n",
                 rep->rms_um, rep->max_um, rep->clipped);
    sc_tb_printf(t, ":START2D %d %d %d %d %.6f %.6f %d\n", ay, ax, ax, ay, c.dy, c.dx, c.ncols);
    /* OFFSET = -(the first row's / column's position): index = (position + OFFSET) / step */
    sc_tb_printf(t, ":START2D POSUNIT=PRIMARY CORUNIT=PRIMARY/1000 OFFSETROW=%.6f OFFSETCOL=%.6f\n",
                 c.y0 == 0 ? 0.0 : -c.y0, c.x0 == 0 ? 0.0 : -c.x0);
    char a[40], b[40];
    for (int r = 0; r < c.nrows; ++r) {
        for (int k = 0; k < c.ncols; ++k) {
            const long long *v = c.code + 2 * ((size_t)r * c.ncols + k);
            a1_value(a, sizeof a, v[0]);
            a1_value(b, sizeof b, v[1]);
            sc_tb_printf(t, "%s%s %s", k ? "  " : "", a, b);
        }
        sc_tb_printf(t, "\n");
    }
    sc_tb_printf(t, ":END\n");
    free(c.code);
    return SC_OK;
}

const sc_export_backend sc_export_backend_aerotech = {SC_EXPORT_AEROTECH_A1, "aerotech-a1", export_aerotech};
