/* export_cross.c — a straightness profile as a Beckhoff TwinCAT CNC / ISG cross compensation list
 * (kw.crosscomp.*; docs/exporters.md). A profile AXIS:DIR is the error of coordinate DIR as a
 * function of AXIS (SPEC §4), so the slave axis (the one corrected, whose list it is) is DIR and
 * the master axis (whose command position is the table's input) is AXIS. Interpolation points
 * ("setpoints", ascending, not necessarily equidistant) and values in 0.1 um integers, linear
 * between the points; ISG's sign (actual - setpoint) is -e.
 *
 * ISG does not document what the compensation does beyond the first and last point. With the
 * master axis' travel the table gets points at the travel ends carrying the profile's end values
 * (selfcald's clamping), so the controller never leaves the table; without it the table spans the
 * profile and the report says so (span_mm, travel_points = 0). The residual evaluates the
 * controller's interpolation of the written integers against the profile as selfcald applies it
 * (linear, clamped), at the profile's points, 16 points between each two, the table's points and
 * within the travel beyond the profile. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"

/* The controller's value at master position s (0.1 um codes in, um out): linear between the
 * written points, the end values beyond them (within the travel, where the table ends at the
 * travel, that is exact; beyond the profile without a travel it is our assumption, unchecked). */
static double cross_eval(const long long *set, const long long *val, int m, double s_mm)
{
    const double q = s_mm * 1e4;
    if (q <= (double)set[0])
        return 0.1 * (double)val[0];
    if (q >= (double)set[m - 1])
        return 0.1 * (double)val[m - 1];
    int lo = 0, hi = m - 1; /* set[lo] <= q < set[hi] */
    while (hi - lo > 1) {
        const int mid = (lo + hi) / 2;
        if ((double)set[mid] <= q)
            lo = mid;
        else
            hi = mid;
    }
    const double f = (q - (double)set[lo]) / (double)(set[hi] - set[lo]);
    return 0.1 * ((double)val[lo] * (1 - f) + (double)val[hi] * f);
}

static const char *upper(int axis)
{
    return axis == 0 ? "X" : axis == 1 ? "Y" : "Z";
}

/* One residual sample: controller - sign * profile at s. */
static void sample(const sc_lut_profile *pr, double sign, const long long *set,
                   const long long *val, int m, double s_mm, double *ss, long *n,
                   sc_export_report *rep)
{
    const double r = cross_eval(set, val, m, s_mm) -
                     sign * sc_export_interp1(pr->err_um, pr->n, pr->start_mm, pr->step_mm, s_mm);
    *ss += r * r;
    ++*n;
    if (fabs(r) > rep->max_um) {
        rep->max_um = fabs(r);
        rep->max_at_mm[0] = s_mm;
        rep->max_at_mm[1] = 0.0;
    }
}

/* One profile's cross compensation list while it is built. */
typedef struct {
    const sc_lut_profile *pr;
    int k;              /* its index in the table */
    double lo, hi;      /* its first and last point, mm */
    double step;        /* the list's step, mm */
    double sign;        /* -1: ISG's actual - setpoint; +1 with --negate */
    const char *an, *dn; /* its axis and direction, lower case */
    long long *set, *val; /* setpoints and corrections, 0.1 µm */
    int m;              /* their count */
} cross_list;

/* --travel MIN,MAX must be an interval within 1 km that holds the profile. */
static sc_status cross_check_travel(const sc_export_options *o, const cross_list *c,
                                    sc_error *err)
{
    if (!o->use_travel)
        return SC_OK;
    if (!(isfinite(o->travel_mm[0]) && isfinite(o->travel_mm[1]) &&
          o->travel_mm[0] < o->travel_mm[1] && fabs(o->travel_mm[0]) <= 1e6 &&
          fabs(o->travel_mm[1]) <= 1e6))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "beckhoff: travel %g..%g mm: MIN < MAX within 1 km, please",
                            o->travel_mm[0], o->travel_mm[1]);
    /* 1e-4 mm: the profile's ends are whole 0.1 um setpoints at most 0.05 um away. */
    if (o->travel_mm[0] > c->lo + 1e-4 || o->travel_mm[1] < c->hi - 1e-4)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "beckhoff: travel %g..%g mm does not contain profile %d (%s -> %s), "
                            "%s = %g..%g mm",
                            o->travel_mm[0], o->travel_mm[1], c->k, c->an, c->dn, c->an, c->lo,
                            c->hi);
    return SC_OK;
}

static sc_status cross_too_many(const cross_list *c, int points, int extra, sc_error *err)
{
    const int maxp = SC_EXPORT_BECKHOFF_CROSS_MAX_POINTS;
    return sc_error_set(err, SC_E_INPUT, NULL, 0,
                        "beckhoff: profile %d (%s -> %s) needs %d points at step %.4f mm; ISG's "
                        "cross compensation holds %d (kw.crosscomp.max_points): choose "
                        "--profile-interval %.4f or more",
                        c->k, c->an, c->dn, points, c->step, maxp,
                        ceil((c->hi - c->lo) / (maxp - 1 - extra) * 1e4) * 1e-4);
}

/* The setpoints: the profile's points, or the interval's from lo with hi as the last point,
 * and with --travel the travel's ends; they must ascend and fit ISG's list. */
static sc_status cross_setpoints(const sc_export_options *o, int inner, cross_list *c,
                                 sc_export_report *rep, sc_error *err)
{
    long long *set = c->set;
    int m = 0;
    if (o->use_travel && llround(o->travel_mm[0] * 1e4) < llround(c->lo * 1e4))
        set[m++] = llround(o->travel_mm[0] * 1e4);
    for (int i = 0; i < inner; ++i) {
        const long long v = llround((i == inner - 1 ? c->hi : c->lo + i * c->step) * 1e4);
        if (i == inner - 1 && m > 0 && v <= set[m - 1] && i > 0)
            --m; /* hi within 0.1 um of the previous point: hi replaces it */
        set[m++] = v;
    }
    if (o->use_travel && llround(o->travel_mm[1] * 1e4) > set[m - 1])
        set[m++] = llround(o->travel_mm[1] * 1e4);
    c->m = m;
    rep->travel_points = 0;
    if (o->use_travel) {
        rep->travel_points += set[0] < llround(c->lo * 1e4);
        rep->travel_points += set[m - 1] > llround(c->hi * 1e4);
    }
    for (int i = 1; i < m; ++i)
        if (set[i] <= set[i - 1]) /* ISG: error 70245 */
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "beckhoff: profile %d's points are closer than 0.1 um (step %g "
                                "mm): setpoints must ascend",
                                c->k, c->step);
    if (m > SC_EXPORT_BECKHOFF_CROSS_MAX_POINTS)
        return cross_too_many(c, m, o->use_travel ? 2 : 0, err);
    return SC_OK;
}

/* Residual: the profile's points and 16 between each two, the table's points, and the travel
 * beyond the profile (16 samples on each side). */
static void cross_residual(const sc_export_options *o, const cross_list *c,
                           sc_export_report *rep)
{
    const sc_lut_profile *pr = c->pr;
    double ss = 0;
    long n = 0;
    rep->max_um = -1;
    const int sub = 16;
    for (int i = 0; i <= sub * (pr->n - 1); ++i)
        sample(pr, c->sign, c->set, c->val, c->m, c->lo + pr->step_mm * i / sub, &ss, &n, rep);
    for (int i = 0; i < c->m; ++i)
        sample(pr, c->sign, c->set, c->val, c->m, (double)c->set[i] * 1e-4, &ss, &n, rep);
    if (o->use_travel)
        for (int i = 0; i < sub; ++i) {
            const double f = (double)i / sub;
            sample(pr, c->sign, c->set, c->val, c->m,
                   o->travel_mm[0] + f * (c->lo - o->travel_mm[0]), &ss, &n, rep);
            sample(pr, c->sign, c->set, c->val, c->m,
                   o->travel_mm[1] - f * (o->travel_mm[1] - c->hi), &ss, &n, rep);
        }
    rep->samples = n;
    rep->rms_um = sqrt(ss / (double)n);
}

/* The cross compensation file (kw.crosscomp). */
static void cross_write(sc_textbuf *t, const sc_export_options *o, const cross_list *c,
                        const sc_export_report *rep)
{
    const sc_lut_profile *pr = c->pr;
    const double sign = c->sign, lo = c->lo, hi = c->hi;
    const char *an = c->an, *dn = c->dn;
    const long long *set = c->set, *val = c->val;
    const int k = c->k, m = c->m;
    const int nr[3] = {o->beckhoff_x_axis_nr, o->beckhoff_y_axis_nr, o->beckhoff_z_axis_nr};
    const char *S = upper(pr->dir), *M = upper(pr->axis);
    sc_tb_printf(t, "# ****************************************\n");
    sc_tb_printf(t, "# Cross compensation of the %s axis by the %s axis, written by selfcal export\n",
                 S, M);
    sc_tb_printf(t, "# %s = %se(%s): the straightness error of %s along %s (profile %d, indicated - "
                    "true), 0.1 um\n",
                 S, sign < 0 ? "-" : "+", M, dn, an, k);
    sc_tb_printf(t, "# %s\n", sign < 0 ? "ISG's sign: the value is the error actual - setpoint, which "
                                         "the CNC takes off the setpoint"
                                       : "NEGATED: +e, the opposite of ISG's actual - setpoint");
    sc_tb_printf(t, "# %s from %.4f to %.4f mm; the profile %.4f..%.4f mm%s\n", M, rep->span_mm[0],
                 rep->span_mm[1], lo, hi,
                 rep->travel_points ? ", its end values held to the travel's ends" : "");
    if (!o->use_travel)
        sc_tb_printf(t, "# beyond the first and last point: not documented by ISG (no --travel given)\n");
    sc_tb_printf(t, "# residual (table - profile): rms %.4f um, max %.4f um; clipped points: %ld\n",
                 rep->rms_um, rep->max_um, rep->clipped);
    sc_tb_printf(t, "# activate with lr_param.crosscomp 1 (P-AXIS-00047) in the %s axis' machine data\n",
                 S);
    sc_tb_printf(t, "# ****************************************\n");
    sc_tb_printf(t, "kopf.achs_nr                          %d\n", nr[pr->dir]);
    sc_tb_printf(t, "kopf.log_achs_name                    %s\n", S);
    sc_tb_printf(t, "kw.crosscomp.unit                     1   /* 0.1 um */\n");
    sc_tb_printf(t, "kw.crosscomp.last_index               %d\n", m - 1);
    sc_tb_printf(t, "kw.crosscomp.master_ax_nr             %d   /* %s */\n", nr[pr->axis], M);
    sc_tb_printf(t, "kw.crosscomp.n_cycles                 10\n");
    for (int i = 0; i < m; ++i) {
        sc_tb_printf(t, "kw.crosscomp.table[%d].setpoint %lld\n", i, set[i]);
        sc_tb_printf(t, "kw.crosscomp.table[%d].correction %lld\n", i, val[i]);
    }
    sc_tb_printf(t, "End\n");
}

sc_status sc_export_beckhoff_cross(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                   sc_export_report *rep, sc_error *err)
{
    cross_list c = {0};
    c.k = o->cross_profile;
    c.pr = &lut->profile[c.k];
    sc_status st = sc_export_profile_meets_map(lut, c.k, "beckhoff", err);
    if (st != SC_OK)
        return st;
    c.lo = c.pr->start_mm;
    c.hi = c.pr->start_mm + c.pr->step_mm * (c.pr->n - 1);
    c.an = sc_lut_axis_name(c.pr->axis);
    c.dn = sc_lut_axis_name(c.pr->dir);
    st = cross_check_travel(o, &c, err);
    if (st != SC_OK)
        return st;
    c.step = o->profile_interval_mm > 0 ? o->profile_interval_mm : c.pr->step_mm;
    const double q = ceil((c.hi - c.lo) / c.step - 1e-9);
    const int inner = q < 1e7 ? 1 + (int)q : 10000000;
    const int extra = o->use_travel ? 2 : 0;
    /* a first bound before allocating; the exact check follows the setpoints */
    if (inner + extra > SC_EXPORT_BECKHOFF_CROSS_MAX_POINTS + 2)
        return cross_too_many(&c, inner + extra, extra, err);
    c.set = malloc(sizeof *c.set * (size_t)(inner + 2));
    c.val = malloc(sizeof *c.val * (size_t)(inner + 2));
    if (!c.set || !c.val)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    else
        st = cross_setpoints(o, inner, &c, rep, err);
    if (st == SC_OK) {
        /* ISG's value is actual - setpoint = true - indicated = -e; the profile at each
         * setpoint as written (clamped: the travel points carry the end values). */
        c.sign = o->negate ? 1.0 : -1.0;
        rep->limit_um = o->limit_um > 0 ? o->limit_um : 214748364.7; /* SGN32 in 0.1 um */
        for (int i = 0; i < c.m; ++i)
            c.val[i] = sc_export_quantize(
                c.sign * sc_export_interp1(c.pr->err_um, c.pr->n, c.pr->start_mm, c.pr->step_mm,
                                           (double)c.set[i] * 1e-4),
                0.1, rep->limit_um, &rep->clipped);
        cross_residual(o, &c, rep);
        rep->tables = 1;
        rep->points[0] = c.m;
        rep->interval_mm = c.step;
        rep->unit_um = 0.1;
        rep->span_mm[0] = (double)c.set[0] * 1e-4;
        rep->span_mm[1] = (double)c.set[c.m - 1] * 1e-4;
        cross_write(t, o, &c, rep);
    }
    free(c.set);
    free(c.val);
    return st;
}
