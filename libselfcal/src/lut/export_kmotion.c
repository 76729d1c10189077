/* export_kmotion.c — the Dynomotion KMotionCNC geometric correction table (`--format kmotion`,
 * docs/exporters.md): the whole 2-D map, ideal + G at every node, in inches. */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"

/* KMotion's GeoCorrect (KMotionX GCodeInterpreter/Kinematics.cpp): the cell from floor() of the
 * offset position, clamped to the table, the fractions NOT clamped (outside it extrapolates the
 * edge cell), bilinear interpolation of the tabulated actuator positions. Inches. */
typedef struct kmo_ctx {
    int nrows, ncols;
    double sx, sy, ox, oy; /* spacing and offset, inches */
    double *ax, *ay;       /* [row * ncols + col]: adjusted (commanded) X, Y, inches as written */
} kmo_ctx;

static void kmo_geocorrect(const kmo_ctx *k, double x, double y, double *cx, double *cy)
{
    int col = (int)floor((x - k->ox) / k->sx), row = (int)floor((y - k->oy) / k->sy);
    if (col < 0)
        col = 0;
    if (col >= k->ncols - 1)
        col = k->ncols - 2;
    if (row < 0)
        row = 0;
    if (row >= k->nrows - 1)
        row = k->nrows - 2;
    const double fx = (x - (col * k->sx + k->ox)) / k->sx, fy = (y - (row * k->sy + k->oy)) / k->sy;
    const int bl = row * k->ncols + col, br = bl + 1, tl = bl + k->ncols, tr = tl + 1;
    const double xb = k->ax[bl] + (k->ax[br] - k->ax[bl]) * fx, xt = k->ax[tl] + (k->ax[tr] - k->ax[tl]) * fx;
    const double yb = k->ay[bl] + (k->ay[br] - k->ay[bl]) * fx, yt = k->ay[tl] + (k->ay[tr] - k->ay[tl]) * fx;
    *cx = xb + (xt - xb) * fy;
    *cy = yb + (yt - yb) * fy;
}

static double kmo_eval(const void *vctx, int comp, double x, double y)
{
    const kmo_ctx *k = vctx;
    double cx, cy;
    kmo_geocorrect(k, x / 25.4, y / 25.4, &cx, &cy);
    /* the correction KMotion applies, um: adjusted - ideal */
    return comp == 0 ? (cx * 25.4 - x) * 1e3 : (cy * 25.4 - y) * 1e3;
}

#define KMO_DECIMALS 9 /* inches: 1e-9 in = 0.0254 nm */

static sc_status export_kmotion(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                sc_export_report *rep, sc_error *err)
{
    if (o->interval_mm > 0 || o->use_line)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "kmotion: the table takes the map's own nodes (no interval, no line)");
    /* The map's nodes plus one ring of edge values: inside the map KMotion interpolates our
     * nodes; beyond it the ring holds the edge value and KMotion's extrapolation of the outer
     * cells is constant, which is our clamping. */
    kmo_ctx k;
    k.ncols = lut->nx + 2;
    k.nrows = lut->ny + 2;
    k.sx = lut->px_mm / 25.4;
    k.sy = lut->py_mm / 25.4;
    k.ox = (lut->x0_mm - lut->px_mm) / 25.4;
    k.oy = (lut->y0_mm - lut->py_mm) / 25.4;
    k.ax = malloc(sizeof *k.ax * (size_t)k.ncols * (size_t)k.nrows);
    k.ay = malloc(sizeof *k.ay * (size_t)k.ncols * (size_t)k.nrows);
    if (!k.ax || !k.ay) {
        free(k.ax);
        free(k.ay);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    const double sign = o->negate ? -1.0 : 1.0;
    rep->limit_um = o->limit_um;
    char line[160];
    sc_tb_printf(t, "%d,%d\n", k.nrows, k.ncols);
    sc_tb_printf(t, "%.*f,%.*f\n", KMO_DECIMALS, k.sx, KMO_DECIMALS, k.sy);
    sc_tb_printf(t, "%.*f,%.*f\n", KMO_DECIMALS, k.ox, KMO_DECIMALS, k.oy);
    for (int row = 0; row < k.nrows; ++row)
        for (int col = 0; col < k.ncols; ++col) {
            const double x = lut->x0_mm + (col - 1) * lut->px_mm, y = lut->y0_mm + (row - 1) * lut->py_mm;
            double gx, gy;
            sc_lut_grid_eval(lut, x, y, &gx, &gy); /* clamped: the ring has the edge values */
            gx *= sign;
            gy *= sign;
            if (rep->limit_um > 0) {
                long dummy = 0;
                gx = (double)sc_export_quantize(gx, 1e-6, rep->limit_um, &rep->clipped) * 1e-6;
                gy = (double)sc_export_quantize(gy, 1e-6, rep->limit_um, &dummy) * 1e-6;
                rep->clipped += dummy;
            }
            /* the ideal CAD point plus G: where KMotion must command to land on it; inches */
            snprintf(line, sizeof line, "%d,%d,%.*f,%.*f,0\n", row, col, KMO_DECIMALS,
                     (x + gx * 1e-3) / 25.4, KMO_DECIMALS, (y + gy * 1e-3) / 25.4);
            sc_tb_printf(t, "%s", line);
            /* what KMotion will read */
            const int kk = row * k.ncols + col;
            sscanf(strchr(strchr(line, ',') + 1, ',') + 1, "%lf,%lf", &k.ax[kk], &k.ay[kk]);
        }
    /* KMotion reads the spacing and offset as written too. */
    char hdr[128];
    snprintf(hdr, sizeof hdr, "%.*f %.*f %.*f %.*f", KMO_DECIMALS, k.sx, KMO_DECIMALS, k.sy,
             KMO_DECIMALS, k.ox, KMO_DECIMALS, k.oy);
    sscanf(hdr, "%lf %lf %lf %lf", &k.sx, &k.sy, &k.ox, &k.oy);
    int comps[2] = {0, 1};
    sc_export_residual(lut, comps, 2, sign, kmo_eval, &k, rep);
    rep->tables = 1;
    rep->points[0] = k.ncols;
    rep->points[1] = k.nrows;
    rep->interval_mm = lut->px_mm;
    rep->unit_um = 25.4e-6;
    free(k.ax);
    free(k.ay);
    return SC_OK;
}

const sc_export_backend sc_export_backend_kmotion = {SC_EXPORT_KMOTION, "kmotion", export_kmotion};
