/* export_beckhoff.c — the Beckhoff TwinCAT CNC / ISG plane compensation list (`--format beckhoff`,
 * docs/exporters.md): one slave axis, a 2-D table over the two master axes with one interval,
 * values and positions in 0.1 um integers; with o->cross_profile >= 0 the back-end writes the
 * cross compensation list of a straightness profile instead (export_cross.c). */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"

typedef struct beckhoff_ctx {
    long long start[2], interval; /* 0.1 um */
    int n[2];                     /* points along x (master 1) and y (master 2) */
    long long *code;              /* [j * n[0] + i], 0.1 um */
} beckhoff_ctx;

static double beckhoff_eval(const void *vctx, int comp, double x, double y)
{
    (void)comp;
    const beckhoff_ctx *c = vctx;
    double u = (x * 1e4 - (double)c->start[0]) / (double)c->interval;
    double v = (y * 1e4 - (double)c->start[1]) / (double)c->interval;
    u = fmin(fmax(u, 0.0), c->n[0] - 1.0);
    v = fmin(fmax(v, 0.0), c->n[1] - 1.0);
    int i = (int)u, j = (int)v;
    if (i > c->n[0] - 2)
        i = c->n[0] - 2;
    if (j > c->n[1] - 2)
        j = c->n[1] - 2;
    double fu = u - i, fv = v - j;
    const long long *r0 = c->code + (size_t)j * c->n[0], *r1 = r0 + c->n[0];
    double val = ((double)r0[i] * (1 - fu) + (double)r0[i + 1] * fu) * (1 - fv) +
                 ((double)r1[i] * (1 - fu) + (double)r1[i + 1] * fu) * fv;
    return 0.1 * val;
}

static long long gcd_ll(long long a, long long b)
{
    while (b) {
        long long t = a % b;
        a = b;
        b = t;
    }
    return a;
}

/* With unequal pitches, the largest interval (0.1 µm) that divides both, where the map's nodes
 * lie on the table's (whole 0.1 µm pitches and first node) and it needs at most 101 points per
 * master; 0 where there is none (equal pitches too: the default is then the pitch). */
static long long common_interval(const sc_lut *lut, const long long start[2], double x1, double y1)
{
    double a = lut->px_mm * 1e4, b = lut->py_mm * 1e4;
    long long ia = llround(a), ib = llround(b);
    if (ia == ib || ia < 1 || ib < 1 || fabs(a - (double)ia) > 1e-6 || fabs(b - (double)ib) > 1e-6 ||
        fabs(lut->x0_mm * 1e4 - (double)start[0]) > 1e-6 ||
        fabs(lut->y0_mm * 1e4 - (double)start[1]) > 1e-6)
        return 0;
    long long g = gcd_ll(ia, ib);
    for (int k = 0; k < 2; ++k) {
        double span = (k == 0 ? x1 : y1) * 1e4 - (double)start[k];
        if (sc_export_cover_points(0.0, span, (double)g) > SC_EXPORT_BECKHOFF_MAX_POINTS)
            return 0;
    }
    return g;
}

/* The plane table's grid: start positions and one interval (0.1 µm) for both masters, the
 * table starting at or before the map and covering it, at most 101 points along each. */
static sc_status beckhoff_grid(const sc_lut *lut, const sc_export_options *o, beckhoff_ctx *ctx,
                               sc_error *err)
{
    beckhoff_ctx c = *ctx;
    const double x1 = sc_export_node_x(lut, lut->nx - 1), y1 = sc_export_node_y(lut, lut->ny - 1);
    /* Positions in 0.1 um; the table starts at or before the map and covers it. */
    c.start[0] = (long long)floor(lut->x0_mm * 1e4 + 1e-6);
    c.start[1] = (long long)floor(lut->y0_mm * 1e4 + 1e-6);
    if (o->interval_mm > 0) {
        c.interval = llround(o->interval_mm * 1e4);
        if (c.interval < 1)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "beckhoff: interval %g mm is below 0.1 um", o->interval_mm);
    } else if ((c.interval = common_interval(lut, c.start, x1, y1)) > 0) {
        /* unequal pitches: the table's nodes take in every map node, so its bilinear
         * interpolation is the map's own (no resampling loss) */
    } else {
        c.interval = llround(fmin(lut->px_mm, lut->py_mm) * 1e4);
        if (c.interval < 1)
            c.interval = 1;
        /* One interval for both masters, at most 101 points each: widen if needed. */
        for (int a = 0; a < 2; ++a) {
            double span = (a == 0 ? x1 : y1) * 1e4 - (double)c.start[a];
            long long need = (long long)ceil(span / (SC_EXPORT_BECKHOFF_MAX_POINTS - 1) - 1e-9);
            if (need > c.interval)
                c.interval = need;
        }
    }
    for (int a = 0; a < 2; ++a) {
        double span = (a == 0 ? x1 : y1) * 1e4 - (double)c.start[a];
        c.n[a] = sc_export_cover_points(0.0, span, (double)c.interval);
        if (c.n[a] < 2)
            c.n[a] = 2;
        if (c.n[a] > SC_EXPORT_BECKHOFF_MAX_POINTS)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "beckhoff: interval %.4f mm needs %d points along %s; the table "
                                "holds %d (101 x 101 = max_points 10201)",
                                (double)c.interval * 1e-4, c.n[a], a == 0 ? "x" : "y",
                                SC_EXPORT_BECKHOFF_MAX_POINTS);
    }
    *ctx = c;
    return SC_OK;
}

/* The plane compensation file (kw.crosscomp2), values c.code. */
static void beckhoff_write(sc_textbuf *t, const sc_export_options *o, const beckhoff_ctx *cp,
                           double sign, const sc_export_report *rep)
{
    const beckhoff_ctx c = *cp;
    const int slave_nr = o->axis == 0 ? o->beckhoff_x_axis_nr : o->beckhoff_y_axis_nr;
    sc_tb_printf(t, "# ****************************************\n");
    sc_tb_printf(t, "# Plane compensation of the %s axis, written by selfcal export\n", sc_export_axis_upper(o->axis));
    sc_tb_printf(t, "# %s = %sG%s(X, Y) of the stage error map, in 0.1 um (G = indicated - true)\n",
              sc_export_axis_upper(o->axis), sign < 0 ? "-" : "+", o->axis == 0 ? "x" : "y");
    sc_tb_printf(t, "# %s\n", sign < 0 ? "ISG's sign: the value is the error actual - setpoint, which the CNC "
                                     "takes off the setpoint"
                                   : "NEGATED: +G, the opposite of ISG's actual - setpoint");
    sc_tb_printf(t, "# residual (table - map): rms %.4f um, max %.4f um; clipped points: %ld\n",
              rep->rms_um, rep->max_um, rep->clipped);
    sc_tb_printf(t, "# ****************************************\n");
    sc_tb_printf(t, "kopf.achs_nr                            %d\n", slave_nr);
    sc_tb_printf(t, "kopf.log_achs_name                      %s\n", sc_export_axis_upper(o->axis));
    sc_tb_printf(t, "kw.crosscomp2.unit                      1   /* 0.1 um */\n");
    sc_tb_printf(t, "kw.crosscomp2.interval                  %lld   /* %.4f mm */\n", c.interval,
              (double)c.interval * 1e-4);
    sc_tb_printf(t, "kw.crosscomp2.last_index_master1        %d\n", c.n[0] - 1);
    sc_tb_printf(t, "kw.crosscomp2.last_index_master2        %d\n", c.n[1] - 1);
    sc_tb_printf(t, "kw.crosscomp2.start_position_master1    %lld   /* %.4f mm */\n", c.start[0],
              (double)c.start[0] * 1e-4);
    sc_tb_printf(t, "kw.crosscomp2.start_position_master2    %lld   /* %.4f mm */\n", c.start[1],
              (double)c.start[1] * 1e-4);
    sc_tb_printf(t, "kw.crosscomp2.n_cycles                  10\n");
    sc_tb_printf(t, "kw.crosscomp2.master1_ax_nr             %d\n", o->beckhoff_x_axis_nr);
    sc_tb_printf(t, "kw.crosscomp2.master2_ax_nr             %d\n", o->beckhoff_y_axis_nr);
    /* table[j][i]: "the first index j refers to the second master axis" (ISG, P-COMP-00016), so
     * j runs along y (master 2) and i along x (master 1). The inline "/ * .. * /" comments above
     * follow a value after a space, which ISG's list reader takes ("Comments in the ASCII
     * file"; its own plane compensation example writes "interval 100000 / * 10 mm * /"). */
    for (int j = 0; j < c.n[1]; ++j)
        for (int i = 0; i < c.n[0]; ++i)
            sc_tb_printf(t, "kw.crosscomp2.table[%3d][%3d].correction %lld\n", j, i,
                      c.code[(size_t)j * c.n[0] + i]);
    sc_tb_printf(t, "End\n");
}

static sc_status export_beckhoff(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                 sc_export_report *rep, sc_error *err)
{
    if (o->axis != 0 && o->axis != 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "beckhoff: choose the compensated (slave) axis, x or y");
    beckhoff_ctx c;
    memset(&c, 0, sizeof c);
    sc_status st = beckhoff_grid(lut, o, &c, err);
    if (st != SC_OK)
        return st;
    c.code = malloc(sizeof *c.code * (size_t)c.n[0] * (size_t)c.n[1]);
    if (!c.code)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    /* ISG's compensation values are measured errors, actual - setpoint (their leadscrew example:
     * setpoint 19866.7 um, actual 19856.5 um, value -102 x 0.1 um), which the CNC takes off the
     * setpoint: -G by default (docs/exporters.md). */
    const double sign = o->negate ? 1.0 : -1.0;
    rep->limit_um = o->limit_um > 0 ? o->limit_um : 214748364.7; /* SGN32 in 0.1 um */
    for (int j = 0; j < c.n[1]; ++j)
        for (int i = 0; i < c.n[0]; ++i) {
            double x = (double)(c.start[0] + i * c.interval) * 1e-4;
            double y = (double)(c.start[1] + j * c.interval) * 1e-4;
            c.code[(size_t)j * c.n[0] + i] = sc_export_quantize(
                sign * sc_export_map_g(lut, o->axis, x, y), 0.1, rep->limit_um, &rep->clipped);
        }
    int comps[1] = {o->axis};
    sc_export_residual(lut, comps, 1, sign, beckhoff_eval, &c, rep);
    rep->tables = 1;
    rep->points[0] = c.n[0];
    rep->points[1] = c.n[1];
    rep->interval_mm = (double)c.interval * 1e-4;
    rep->unit_um = 0.1;
    beckhoff_write(t, o, &c, sign, rep);
    free(c.code);
    return SC_OK;
}

static sc_status beckhoff_write_any(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                    sc_export_report *rep, sc_error *err)
{
    return o->cross_profile >= 0 ? sc_export_beckhoff_cross(lut, o, t, rep, err)
                                 : export_beckhoff(lut, o, t, rep, err);
}

const sc_export_backend sc_export_backend_beckhoff = {SC_EXPORT_BECKHOFF, "beckhoff",
                                                      beckhoff_write_any};
