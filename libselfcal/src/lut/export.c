/* export.c — write a stage error map as a machine controller's compensation table and measure
 * what the controller will apply (docs/exporters.md):
 *   beckhoff     TwinCAT CNC / ISG plane compensation list: one slave axis, a 2-D table over the
 *                two master axes with one interval, values and positions in 0.1 um integers.
 *                (A straightness profile goes to a cross compensation list: export_cross.c.)
 *   siemens-cec  SINUMERIK 840D $AN_CEC tables: 1-D tables (input axis -> output axis) that add
 *                up; the map is split into its best additive form A(x) + B(y) (row and column
 *                means), the interaction part remains as residual. Values in mm.
 *   linuxcnc     joint compensation file (COMP_FILE_TYPE = 1: nominal, forward trim, reverse
 *                trim, mm), one joint: G of that axis as a function of that axis only (the mean
 *                over the other coordinate, or along one line).
 * Each exporter computes its table values, quantizes them to the format's unit, clips them to the
 * limit, then evaluates the controller's interpolation of exactly those values on a fine sampling
 * of the map (nodes and 4 x 4 sub-points per cell) against our bilinear map. */
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"
#include "selfcal/atomic_file.h"
#include "selfcal/export.h"

/* ---- common ---- */

void sc_export_options_init(sc_export_options *o, sc_export_format format)
{
    memset(o, 0, sizeof *o);
    o->format = format;
    o->axis = 0;
    o->beckhoff_x_axis_nr = 1;
    o->beckhoff_y_axis_nr = 2;
    o->siemens_x_name = "AX1";
    o->siemens_y_name = "AX2";
    o->siemens_first_table = 0;
    o->beckhoff_z_axis_nr = 3;
    o->cross_profile = -1;
}

int sc_export_format_from_name(const char *name)
{
    if (!strcmp(name, "beckhoff"))
        return SC_EXPORT_BECKHOFF;
    if (!strcmp(name, "siemens-cec"))
        return SC_EXPORT_SIEMENS_CEC;
    if (!strcmp(name, "linuxcnc"))
        return SC_EXPORT_LINUXCNC;
    if (!strcmp(name, "klipper"))
        return SC_EXPORT_KLIPPER;
    if (!strcmp(name, "marlin"))
        return SC_EXPORT_MARLIN;
    if (!strcmp(name, "reprap"))
        return SC_EXPORT_REPRAP;
    if (!strcmp(name, "kmotion"))
        return SC_EXPORT_KMOTION;
    if (!strcmp(name, "aerotech-a1"))
        return SC_EXPORT_AEROTECH_A1;
    if (!strcmp(name, "powerpmac"))
        return SC_EXPORT_POWERPMAC;
    return -1;
}

/* Component comp (0 = Gx, 1 = Gy) of the bilinear map at (x, y), um. */
static double map_g(const sc_lut *lut, int comp, double x, double y)
{
    return sc_export_map_g(lut, comp, x, y);
}

static double map_x(const sc_lut *lut, int j)
{
    return lut->x0_mm + j * lut->px_mm;
}

static double map_y(const sc_lut *lut, int i)
{
    return lut->y0_mm + i * lut->py_mm;
}

static const char *axis_upper(int axis)
{
    return axis == 0 ? "X" : "Y";
}

/* ---- Beckhoff / ISG plane compensation ---- */

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
    const double x1 = map_x(lut, lut->nx - 1), y1 = map_y(lut, lut->ny - 1);
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
    sc_tb_printf(t, "# Plane compensation of the %s axis, written by selfcal export\n", axis_upper(o->axis));
    sc_tb_printf(t, "# %s = %sG%s(X, Y) of the stage error map, in 0.1 um (G = indicated - true)\n",
              axis_upper(o->axis), sign < 0 ? "-" : "+", o->axis == 0 ? "x" : "y");
    sc_tb_printf(t, "# %s\n", sign < 0 ? "ISG's sign: the value is the error actual - setpoint, which the CNC "
                                     "takes off the setpoint"
                                   : "NEGATED: +G, the opposite of ISG's actual - setpoint");
    sc_tb_printf(t, "# residual (table - map): rms %.4f um, max %.4f um; clipped points: %ld\n",
              rep->rms_um, rep->max_um, rep->clipped);
    sc_tb_printf(t, "# ****************************************\n");
    sc_tb_printf(t, "kopf.achs_nr                            %d\n", slave_nr);
    sc_tb_printf(t, "kopf.log_achs_name                      %s\n", axis_upper(o->axis));
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
                sign * map_g(lut, o->axis, x, y), 0.1, rep->limit_um, &rep->clipped);
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

/* ---- Siemens 840D CEC ---- */

typedef struct cec_table {
    int input, output;   /* 0 = x, 1 = y, 2 = z */
    int profile;         /* 1: a straightness profile's table (not part of the map's split) */
    int n;
    double min_mm, step_mm;
    long long *code_nm;  /* values in nm */
    double *value_um;    /* the same, um, for interpolation */
} cec_table;

typedef struct cec_ctx {
    int ntab;
    cec_table tab[4 + SC_LUT_MAX_PROFILES];
} cec_ctx;

static double cec_eval(const void *vctx, int comp, double x, double y)
{
    const cec_ctx *c = vctx;
    double sum = 0;
    for (int k = 0; k < c->ntab; ++k) {
        const cec_table *tb = &c->tab[k];
        if (tb->output != comp || tb->profile)
            continue;
        sum += sc_export_interp1(tb->value_um, tb->n, tb->min_mm, tb->step_mm, tb->input == 0 ? x : y);
    }
    return sum;
}

/* Mean of component comp over the other coordinate's nodes, at position s along `along`. */
static double mean_along(const sc_lut *lut, int comp, int along, double s)
{
    double sum = 0;
    int n = along == 0 ? lut->ny : lut->nx;
    for (int k = 0; k < n; ++k)
        sum += along == 0 ? map_g(lut, comp, s, map_y(lut, k)) : map_g(lut, comp, map_x(lut, k), s);
    return sum / n;
}

static double grand_mean(const sc_lut *lut, int comp)
{
    const double *g = comp == 0 ? lut->gx_um : lut->gy_um;
    double sum = 0;
    for (int k = 0; k < lut->nx * lut->ny; ++k)
        sum += g[k];
    return sum / (lut->nx * lut->ny);
}

static void free_cec(cec_ctx *c)
{
    for (int k = 0; k < c->ntab; ++k) {
        free(c->tab[k].code_nm);
        free(c->tab[k].value_um);
    }
}

/* Sizes table c->tab[c->ntab] for [lo, hi] at step (the 840D's or the 828D's point limit; `what`
 * names it in the message), allocates its values and counts it in c->ntab (freed by free_cec). */
static sc_status cec_new_table(cec_ctx *c, const sc_export_options *o, double lo, double hi,
                               double step, const char *what, sc_error *err)
{
    cec_table *tb = &c->tab[c->ntab];
    tb->step_mm = step;
    tb->n = sc_export_cover_points(lo, hi, step);
    tb->min_mm = lo;
    const int maxp = o->siemens_828d ? SC_EXPORT_SIEMENS_828D_POINTS : SC_EXPORT_SIEMENS_MAX_POINTS;
    if (tb->n > maxp)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "siemens-cec: %s needs %d points at step %.6f mm; a%s table holds %d: "
                            "choose a larger interval",
                            what, tb->n, step, o->siemens_828d ? "n 828D" : "",
                            maxp);
    tb->code_nm = malloc(sizeof *tb->code_nm * (size_t)tb->n);
    tb->value_um = malloc(sizeof *tb->value_um * (size_t)tb->n);
    ++c->ntab;
    if (!tb->code_nm || !tb->value_um)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    return SC_OK;
}

/* The map's components the export covers (x, y or both) and the table range an 828D has. */
static sc_status siemens_components(const sc_export_options *o, int *comps, int *ncomp,
                                    sc_error *err)
{
    *ncomp = 0;
    if (o->axis < 0) {
        comps[(*ncomp)++] = 0;
        comps[(*ncomp)++] = 1;
    } else if (o->axis <= 1)
        comps[(*ncomp)++] = o->axis;
    else
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "siemens-cec: axis must be x, y or both");
    if (o->siemens_first_table < 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "siemens-cec: table index must be >= 0");
    if (o->siemens_828d && o->siemens_first_table + 2 * *ncomp > SC_EXPORT_SIEMENS_828D_TABLES)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "siemens-cec: tables %d..%d do not exist on an 828D (8 tables, "
                            "0..7)",
                            o->siemens_first_table, o->siemens_first_table + 2 * *ncomp - 1);
    return SC_OK;
}

/* The two tables of one map component: additive split A(x) = mean over y (input x), B(y) =
 * mean over x minus the grand mean (input y); A(x_j) + B(y_i) is the least-squares additive
 * fit. */
static sc_status siemens_map_tables(const sc_lut *lut, const sc_export_options *o, int comp,
                                    double sign, cec_ctx *c, sc_export_report *rep, sc_error *err)
{
    const double gm = grand_mean(lut, comp);
    for (int in = 0; in < 2; ++in) {
        cec_table *tb = &c->tab[c->ntab];
        tb->input = in;
        tb->output = comp;
        const double lo = in == 0 ? lut->x0_mm : lut->y0_mm;
        const double hi = in == 0 ? map_x(lut, lut->nx - 1) : map_y(lut, lut->ny - 1);
        const double step = o->interval_mm > 0 ? o->interval_mm
                                               : (in == 0 ? lut->px_mm : lut->py_mm);
        sc_status st = cec_new_table(c, o, lo, hi, step, in == 0 ? "the x table" : "the y table",
                                     err);
        if (st != SC_OK)
            return st;
        for (int k = 0; k < tb->n; ++k) {
            double s = lo + k * tb->step_mm;
            double v = mean_along(lut, comp, in, s) - (in == 1 ? gm : 0.0);
            tb->code_nm[k] = sc_export_quantize(sign * v, 1e-3, rep->limit_um, &rep->clipped);
            tb->value_um[k] = 1e-3 * (double)tb->code_nm[k];
        }
    }
    return SC_OK;
}

/* A straightness profile's table: input AXIS -> output DIR, the profile's own points (or the
 * interval), values of its linear interpolation clamped to its range; its residual (the
 * table's interpolation against the profile's, dense along the axis and beyond both ends, where
 * both clamp) into rep->profile_max_um. */
static sc_status siemens_profile_table(const sc_lut *lut, const sc_export_options *o, int pk,
                                       double sign, cec_ctx *c, sc_export_report *rep,
                                       sc_error *err)
{
    const sc_lut_profile *pr = &lut->profile[pk];
    sc_status st = sc_export_profile_meets_map(lut, pk, "siemens-cec", err);
    if (st != SC_OK)
        return st;
    cec_table *tb = &c->tab[c->ntab];
    tb->input = pr->axis;
    tb->output = pr->dir;
    tb->profile = 1;
    const double lo = pr->start_mm, hi = pr->start_mm + pr->step_mm * (pr->n - 1);
    char what[64];
    snprintf(what, sizeof what, "profile %d (%s -> %s)", pk, sc_lut_axis_name(pr->axis),
             sc_lut_axis_name(pr->dir));
    const double pstep = o->profile_interval_mm > 0 ? o->profile_interval_mm
                         : o->interval_mm > 0       ? o->interval_mm
                                                    : pr->step_mm;
    st = cec_new_table(c, o, lo, hi, pstep, what, err);
    if (st != SC_OK)
        return st;
    for (int k = 0; k < tb->n; ++k) {
        double v = sc_export_interp1(pr->err_um, pr->n, pr->start_mm, pr->step_mm,
                                     lo + k * tb->step_mm);
        tb->code_nm[k] = sc_export_quantize(sign * v, 1e-3, rep->limit_um, &rep->clipped);
        tb->value_um[k] = 1e-3 * (double)tb->code_nm[k];
    }
    const int ns = 16 * (pr->n - 1);
    for (int q = -8; q <= ns + 8; ++q) {
        double s_mm = lo + (hi - lo) * q / ns;
        double r = sc_export_interp1(tb->value_um, tb->n, tb->min_mm, tb->step_mm, s_mm) -
                   sign * sc_export_interp1(pr->err_um, pr->n, pr->start_mm, pr->step_mm, s_mm);
        if (fabs(r) > rep->profile_max_um)
            rep->profile_max_um = fabs(r);
    }
    return SC_OK;
}

/* The extremes over its range of the sum of the tables with output `out` and input `in`
 * (piecewise linear, clamped: the extremes lie at their points); 0 if there are none. */
static int cec_input_extremes(const cec_ctx *c, int out, int in, double *lo, double *hi)
{
    int any = 0;
    *lo = INFINITY, *hi = -INFINITY;
    for (int k = 0; k < c->ntab; ++k) {
        const cec_table *at = &c->tab[k];
        if (at->output != out || at->input != in)
            continue;
        any = 1;
        for (int p = 0; p < at->n; ++p) {
            double s_mm = at->min_mm + p * at->step_mm, sum = 0;
            for (int q = 0; q < c->ntab; ++q) {
                const cec_table *tb = &c->tab[q];
                if (tb->output == out && tb->input == in)
                    sum += sc_export_interp1(tb->value_um, tb->n, tb->min_mm, tb->step_mm, s_mm);
            }
            *lo = fmin(*lo, sum), *hi = fmax(*hi, sum);
        }
    }
    return any;
}

/* MD32720 $MA_CEC_MAX_SUM limits the total of the tables acting on an axis, not each entry: the
 * tables' sum at the worst point of the travel (each input axis at its own extreme: the inputs
 * move independently) must stay within the limit, else the controller would cut it. */
static sc_status cec_check_sum(const cec_ctx *c, const sc_export_options *o, double limit_um,
                               sc_error *err)
{
    const char *name[3] = {o->siemens_x_name, o->siemens_y_name,
                           o->siemens_z_name ? o->siemens_z_name : "AX3"};
    for (int out = 0; out < 3; ++out) {
        double lo = 0, hi = 0, a, b;
        for (int in = 0; in < 3; ++in)
            if (cec_input_extremes(c, out, in, &a, &b))
                lo += a, hi += b;
        double worst = fmax(hi, -lo);
        if (worst > limit_um + 1e-6)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "siemens-cec: the %s tables of axis %s add up to %.3f um at the "
                                "worst point of the travel, beyond the %.3f um that MD32720 "
                                "$MA_CEC_MAX_SUM allows (--limit-um): the controller would cut "
                                "the sum; raise MD32720 and give --limit-um to match",
                                out == 0 ? "X" : out == 1 ? "Y" : "Z", name[out], worst, limit_um);
    }
    return SC_OK;
}

/* The comment block at the head of the CEC file. */
static void siemens_write_header(sc_textbuf *t, const sc_export_options *o, const cec_ctx *c,
                                 const int *comps, int ncomp, double sign,
                                 const sc_export_report *rep)
{
    sc_tb_printf(t, "%%_N_NC_CEC_INI\n");
    sc_tb_printf(t, "CHANDATA(1)\n");
    sc_tb_printf(t, "; cross error compensation written by selfcal export: %d table(s), values in mm\n",
              c->ntab);
    /* K3: CEC positions and values are read in the current measuring system */
    sc_tb_printf(t, "; positions and values in mm, for a metric basic system (MD10240 = 1); an inch "
                    "machine needs them / 25.4\n");
    sc_tb_printf(t, "; map = A(x) + B(y) + residual; tables hold %sA and %sB of %s (G = indicated - true)\n",
              sign < 0 ? "-" : "+", sign < 0 ? "-" : "+", ncomp == 2 ? "Gx and Gy" : (comps[0] == 0 ? "Gx" : "Gy"));
    sc_tb_printf(t, "; %s\n", sign < 0 ? "Siemens' sign (K3): a positive value moves the axis negative, so -G moves it by +G"
                                   : "NEGATED: +G, the opposite of Siemens' sign");
    sc_tb_printf(t, "; residual (tables - map): rms %.4f um, max %.4f um; clipped points: %ld\n",
              rep->rms_um, rep->max_um, rep->clipped);
    if (o->siemens_828d)
        sc_tb_printf(t, "; SINUMERIK 828D: 8 tables x 200 points, fixed; MD32710 $MA_CEC_ENABLE = 1 (output axes) and\n");
    else
        sc_tb_printf(t, "; needs MD18342 $MN_MM_CEC_MAX_POINTS[t] >= points, MD32710 $MA_CEC_ENABLE = 1 (output axes) and\n");
    sc_tb_printf(t, "; SD41300 $SN_CEC_TABLE_ENABLE[t] = 1 for each table t below\n");
}

/* One table's values and machine data. */
static void siemens_write_table(sc_textbuf *t, const sc_export_options *o, const cec_table *tb,
                                int ti)
{
    const char *name[3] = {o->siemens_x_name, o->siemens_y_name,
                           o->siemens_z_name ? o->siemens_z_name : "AX3"};
    sc_tb_printf(t, "; table %d: %s%s error of %s as a function of %s, %d points\n", ti,
              tb->profile ? "straightness profile: " : "", tb->output == 0 ? "X" : tb->output == 1 ? "Y" : "Z",
              name[tb->output], name[tb->input], tb->n);
    for (int p = 0; p < tb->n; ++p) {
        long long v = tb->code_nm[p];
        sc_tb_printf(t, "$AN_CEC[%d,%d]=%s%lld.%06lld\n", ti, p, v < 0 ? "-" : "", llabs(v) / 1000000,
                  llabs(v) % 1000000);
    }
    sc_tb_printf(t, "$AN_CEC_INPUT_AXIS[%d]=(%s)\n", ti, name[tb->input]);
    sc_tb_printf(t, "$AN_CEC_OUTPUT_AXIS[%d]=(%s)\n", ti, name[tb->output]);
    sc_tb_printf(t, "$AN_CEC_STEP[%d]=%.6f\n", ti, tb->step_mm);
    sc_tb_printf(t, "$AN_CEC_MIN[%d]=%.6f\n", ti, tb->min_mm);
    sc_tb_printf(t, "$AN_CEC_MAX[%d]=%.6f\n", ti, tb->min_mm + (tb->n - 1) * tb->step_mm);
    sc_tb_printf(t, "$AN_CEC_DIRECTION[%d]=0\n", ti);
    sc_tb_printf(t, "$AN_CEC_MULT_BY_TABLE[%d]=0\n", ti);
    sc_tb_printf(t, "$AN_CEC_IS_MODULO[%d]=0\n", ti);
}

static sc_status export_siemens(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                sc_export_report *rep, sc_error *err)
{
    int comps[2], ncomp;
    sc_status st = siemens_components(o, comps, &ncomp, err);
    if (st != SC_OK)
        return st;
    /* Siemens' own words for sag compensation (Function Manual Extended Functions, K3, "Sag
     * compensation and angularity error compensation"): the table holds a compensation value per
     * input position, sent to the position control loop as an additional setpoint, and a positive
     * value moves the machine axis in the negative direction. The axis must move by +G (to
     * t + G when asked for t), so the value is -G by default (docs/exporters.md). */
    const double sign = o->negate ? 1.0 : -1.0;
    rep->limit_um = o->limit_um > 0 ? o->limit_um : 1000.0; /* MD32720 CEC_MAX_SUM default 1 mm */
    cec_ctx c;
    memset(&c, 0, sizeof c);
    for (int ci = 0; ci < ncomp && st == SC_OK; ++ci)
        st = siemens_map_tables(lut, o, comps[ci], sign, &c, rep, err);
    for (int pk = 0; pk < lut->n_profiles && st == SC_OK; ++pk)
        st = siemens_profile_table(lut, o, pk, sign, &c, rep, err);
    if (st == SC_OK)
        st = cec_check_sum(&c, o, rep->limit_um, err);
    if (st == SC_OK && o->siemens_828d &&
        o->siemens_first_table + c.ntab > SC_EXPORT_SIEMENS_828D_TABLES)
        st = sc_error_set(err, SC_E_INPUT, NULL, 0,
                          "siemens-cec: %d tables from table %d do not fit an 828D (8 tables, "
                          "0..7)",
                          c.ntab, o->siemens_first_table);
    if (st != SC_OK) {
        free_cec(&c);
        return st;
    }
    sc_export_residual(lut, comps, ncomp, sign, cec_eval, &c, rep);
    rep->tables = c.ntab;
    for (int k = 0; k < c.ntab && k < 4; ++k)
        rep->points[k] = c.tab[k].n;
    rep->interval_mm = c.tab[0].step_mm;
    rep->unit_um = 1e-3;
    siemens_write_header(t, o, &c, comps, ncomp, sign, rep);
    for (int k = 0; k < c.ntab; ++k)
        siemens_write_table(t, o, &c.tab[k], o->siemens_first_table + k);
    sc_tb_printf(t, "M17\n");
    free_cec(&c);
    return SC_OK;
}

/* ---- Dynomotion KMotionCNC geometric correction table ---- */

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

/* ---- LinuxCNC joint compensation ---- */

typedef struct lcnc_ctx {
    int axis, n;
    double start_mm, step_mm;
    double *value_um;
} lcnc_ctx;

static double lcnc_eval(const void *vctx, int comp, double x, double y)
{
    (void)comp;
    const lcnc_ctx *c = vctx;
    return sc_export_interp1(c->value_um, c->n, c->start_mm, c->step_mm, c->axis == 0 ? x : y);
}

static sc_status export_linuxcnc(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                 sc_export_report *rep, sc_error *err)
{
    if (o->axis != 0 && o->axis != 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "linuxcnc: one joint at a time: choose the axis, x or y");
    if (o->use_line) { /* the line must cross the map: beyond it the map would be clamped */
        double a = o->axis == 0 ? lut->y0_mm : lut->x0_mm;
        double b = o->axis == 0 ? map_y(lut, lut->ny - 1) : map_x(lut, lut->nx - 1);
        double tol = 1e-9 * (fabs(a) + fabs(b) + 1);
        if (!(o->line_mm >= a - tol && o->line_mm <= b + tol))
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "linuxcnc: --at %g mm is outside the map (%c from %g to %g mm)",
                                o->line_mm, o->axis == 0 ? 'y' : 'x', a, b);
    }
    lcnc_ctx c;
    c.axis = o->axis;
    const double lo = o->axis == 0 ? lut->x0_mm : lut->y0_mm;
    const double hi = o->axis == 0 ? map_x(lut, lut->nx - 1) : map_y(lut, lut->ny - 1);
    c.step_mm = o->interval_mm > 0 ? o->interval_mm : (o->axis == 0 ? lut->px_mm : lut->py_mm);
    c.n = sc_export_cover_points(lo, hi, c.step_mm);
    c.start_mm = lo;
    if (c.n > SC_EXPORT_LINUXCNC_MAX_POINTS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "linuxcnc: step %.6f mm needs %d entries; a joint holds %d",
                            c.step_mm, c.n, SC_EXPORT_LINUXCNC_MAX_POINTS);
    c.value_um = malloc(sizeof *c.value_um * (size_t)c.n);
    long long *code = malloc(sizeof *code * (size_t)c.n);
    if (!c.value_um || !code) {
        free(c.value_um);
        free(code);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    const double sign = o->negate ? -1.0 : 1.0;
    rep->limit_um = o->limit_um; /* the format itself has no value limit */
    for (int k = 0; k < c.n; ++k) {
        double s = lo + k * c.step_mm, v;
        if (o->use_line)
            v = o->axis == 0 ? map_g(lut, 0, s, o->line_mm) : map_g(lut, 1, o->line_mm, s);
        else
            v = mean_along(lut, o->axis, o->axis, s);
        code[k] = sc_export_quantize(sign * v, 1e-3, rep->limit_um, &rep->clipped);
        c.value_um[k] = 1e-3 * (double)code[k];
    }
    int comps[1] = {o->axis};
    sc_export_residual(lut, comps, 1, sign, lcnc_eval, &c, rep);
    rep->tables = 1;
    rep->points[0] = c.n;
    rep->interval_mm = c.step_mm;
    rep->unit_um = 1e-3;
    /* "nominal forward-trim reverse-trim" lines, ascending, then ONE comment line: LinuxCNC's
     * loader reads triplets until the first line that is not one, so a trailing comment is
     * ignored while a leading one would make it load nothing, silently. Beyond the table
     * LinuxCNC holds the end trims: its table starts with a sentinel at -DBL_MAX that takes the
     * first trim with no slope when the first entry is loaded (motion/command.c,
     * SET_JOINT_COMP), and the last entry keeps no slope to the sentinel at +DBL_MAX; that is
     * selfcald's clamping, so no entry beyond the map is needed. */
    for (int k = 0; k < c.n; ++k) {
        long long v = code[k];
        char trim[48];
        snprintf(trim, sizeof trim, "%s%lld.%06lld", v < 0 ? "-" : "", llabs(v) / 1000000,
                 llabs(v) % 1000000);
        sc_tb_printf(t, "%.6f %s %s\n", lo + k * c.step_mm, trim, trim);
    }
    sc_tb_printf(t, "# selfcal export: %s trims (%sG%s, mm; a machine in inches needs them / 25.4) - "
                 "needs COMP_FILE_TYPE = 1 in [JOINT_n]: LinuxCNC's default 0 reads them as "
                 "positions\n",
              axis_upper(o->axis), sign < 0 ? "-" : "+", o->axis == 0 ? "x" : "y");
    free(code);
    free(c.value_um);
    return SC_OK;
}

sc_status sc_export_write(const sc_lut *lut, const sc_export_options *o, const char *path,
                          sc_export_report *rep, sc_error *err)
{
    memset(rep, 0, sizeof *rep);
    if (lut->nx < 2 || lut->ny < 2)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the map needs at least 2 x 2 nodes");
    if (!(o->interval_mm >= 0) || !isfinite(o->interval_mm) || !(o->limit_um >= 0) ||
        !isfinite(o->limit_um))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the interval and the value limit must be finite and >= 0");
    if (o->interval_mm > 1e6)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "interval %g mm is beyond 1 km",
                            o->interval_mm);
    if (o->cross_profile >= 0 && (o->format != SC_EXPORT_BECKHOFF || o->cross_profile >= lut->n_profiles))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "a cross compensation list needs --format beckhoff and profile %d of %d",
                            o->cross_profile, lut->n_profiles);
    if (!(o->profile_interval_mm >= 0) || !(o->profile_interval_mm <= 1e6) ||
        (o->profile_interval_mm > 0 && o->profile_interval_mm < 1e-4))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "profile interval %g mm: 0.1 um .. 1 km, please", o->profile_interval_mm);
    if (o->interval_mm > 0 && o->interval_mm < 1e-4)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "interval %g mm is below the 0.1 um resolution of the tables",
                            o->interval_mm);
    sc_textbuf t = {0};
    sc_status st;
    switch (o->format) {
    case SC_EXPORT_BECKHOFF:
        st = o->cross_profile >= 0 ? sc_export_beckhoff_cross(lut, o, &t, rep, err)
                                   : export_beckhoff(lut, o, &t, rep, err);
        break;
    case SC_EXPORT_SIEMENS_CEC:
        st = export_siemens(lut, o, &t, rep, err);
        break;
    case SC_EXPORT_LINUXCNC:
        st = export_linuxcnc(lut, o, &t, rep, err);
        break;
    case SC_EXPORT_KMOTION:
        st = export_kmotion(lut, o, &t, rep, err);
        break;
    case SC_EXPORT_AEROTECH_A1:
        st = sc_export_aerotech(lut, o, &t, rep, err);
        break;
    case SC_EXPORT_POWERPMAC:
        st = sc_export_powerpmac(lut, o, &t, rep, err);
        break;
    case SC_EXPORT_KLIPPER:
    case SC_EXPORT_MARLIN:
    case SC_EXPORT_REPRAP:
        t.cap = 8192;
        t.s = malloc(t.cap);
        st = t.s ? sc_export_firmware(lut, o, t.s, t.cap, &t.len, rep, err)
                 : sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        break;
    default:
        st = sc_error_set(err, SC_E_INPUT, NULL, 0, "unknown export format %d", (int)o->format);
    }
    if (st == SC_OK && t.failed)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory while formatting");
    if (st == SC_OK && path)
        st = sc_write_file_atomic(path, t.s, t.len, err);
    free(t.s);
    return st;
}
