/* export_siemens.c — SINUMERIK 840D / 828D $AN_CEC tables (`--format siemens-cec`,
 * docs/exporters.md): 1-D tables (input axis -> output axis) that add up; the map is split into
 * its best additive form A(x) + B(y) (row and column means), the interaction part remains as
 * residual; each straightness profile is one more table. Values in mm. */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"

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
    const double gm = sc_export_grand_mean(lut, comp);
    for (int in = 0; in < 2; ++in) {
        cec_table *tb = &c->tab[c->ntab];
        tb->input = in;
        tb->output = comp;
        const double lo = in == 0 ? lut->x0_mm : lut->y0_mm;
        const double hi = in == 0 ? sc_export_node_x(lut, lut->nx - 1) : sc_export_node_y(lut, lut->ny - 1);
        const double step = o->interval_mm > 0 ? o->interval_mm
                                               : (in == 0 ? lut->px_mm : lut->py_mm);
        sc_status st = cec_new_table(c, o, lo, hi, step, in == 0 ? "the x table" : "the y table",
                                     err);
        if (st != SC_OK)
            return st;
        for (int k = 0; k < tb->n; ++k) {
            double s = lo + k * tb->step_mm;
            double v = sc_export_mean_along(lut, comp, in, s) - (in == 1 ? gm : 0.0);
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

const sc_export_backend sc_export_backend_siemens = {SC_EXPORT_SIEMENS_CEC, "siemens-cec",
                                                     export_siemens};
