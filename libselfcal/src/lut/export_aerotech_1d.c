/* export_aerotech_1d.c — straightness profiles as an Aerotech Automation1 1-D axis calibration
 * file (`selfcal export --format aerotech-a1 --profile AXIS:DIR:P.csv`, written as OUT-1d beside
 * the map's 2-D file OUT; docs/exporters.md).
 *
 * Followed: Automation1 help, "Axis Calibration" (help.aerotech.com/automation1/Content/
 * Axis-Calibration.htm), its opening and the notes that open its section "1D Axis Calibration":
 * axis calibration corrects the position of an axis from the position of one (1-D) or two (2-D)
 * reference axes; a calibration file holds tables of ONE kind (so the 1-D tables get a file of
 * their own, the 2-D map stays in OUT); tables add up; linear interpolation between the table's
 * reference positions, "the nearest end point of the table" beyond them (selfcald's clamping of a
 * profile, SPEC §4); axis indices in files are one-based; "all calibration tables follow the sign
 * of the encoder"; corrections are bidirectional. A profile AXIS:DIR (the error of DIR along AXIS,
 * indicated - true) is one 1-D table: reference axis AXIS, output axis DIR.
 *
 * Written, one table per profile, equally spaced from the profile's first point (its own step, or
 * --profile-interval), values in um with 4 decimals:
 *   :START RefAxis OutputAxis SAMPLEDIST=.. POSUNIT=PRIMARY CORUNIT=PRIMARY/1000
 *   :START OFFSET=..
 *   one correction per line
 *   :END
 * OPEN (said in the file and in docs/exporters.md): the page we could read gives no 1-D file
 * syntax. The keyword line is the one public A3200/Automation1 calibration scripts write for a 1-D
 * table (`:START AXIS SAMPLEDIST= POSUNIT= CORUNIT=`, then `:START OFFSET=`), which corrects an
 * axis by its own position; naming the output axis after the reference axis follows the 2-D
 * line's order (reference axes, then output axes). The sign is taken as the amount added to the
 * command, +e (--negate: -e, as NEGCOR would), OFFSET as minus the first point's position (index
 * = (position + OFFSET) / SAMPLEDIST, as for 2-D), primary units as mm. The axis order of the
 * :START line is the open point: `aerotech_1d_output_first` (--a1-1d-order out,ref) swaps it. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "export_internal.h"

/* One profile's table while it is built. */
typedef struct a1_line {
    const sc_lut_profile *pr;
    double lo, hi, step; /* mm: the profile's first and last point, the table's spacing */
    int n;               /* entries */
    long long *code;     /* corrections, 1e-4 um */
} a1_line;

/* Automation1's 1-D rule: linear between the entries, the nearest end point beyond them. */
static double a1_line_eval(const a1_line *l, double s_mm)
{
    const double u = (s_mm - l->lo) / l->step;
    if (u <= 0)
        return (double)l->code[0] * SC_EXPORT_AEROTECH_UNIT_UM;
    if (u >= l->n - 1)
        return (double)l->code[l->n - 1] * SC_EXPORT_AEROTECH_UNIT_UM;
    int k = (int)u;
    if (k > l->n - 2)
        k = l->n - 2;
    const double f = u - k;
    return ((double)l->code[k] * (1 - f) + (double)l->code[k + 1] * f) *
           SC_EXPORT_AEROTECH_UNIT_UM;
}

/* Residual of table l against sign * the profile as selfcald applies it: the profile's points,
 * 16 between each two, and four steps beyond each end (where both hold their end values). */
static void a1_line_residual(const a1_line *l, int k, double sign, double *ss, long *n,
                             sc_export_report *rep)
{
    const sc_lut_profile *pr = l->pr;
    const int sub = 16, ns = sub * (pr->n - 1);
    for (int q = -4 * sub; q <= ns + 4 * sub; ++q) {
        const double s = l->lo + pr->step_mm * q / sub;
        const double r = a1_line_eval(l, s) -
                         sign * sc_export_interp1(pr->err_um, pr->n, pr->start_mm, pr->step_mm, s);
        *ss += r * r;
        ++*n;
        if (fabs(r) > rep->max_um) {
            rep->max_um = fabs(r);
            rep->max_at_mm[0] = s;
            rep->max_at_mm[1] = k;
        }
    }
}

/* The table of profile k: sized, filled with the quantized +-e at its points. */
static sc_status a1_line_build(const sc_lut *lut, const sc_export_options *o, int k, double sign,
                               a1_line *l, sc_export_report *rep, sc_error *err)
{
    sc_status st = sc_export_profile_meets_map(lut, k, "aerotech-a1", err);
    if (st != SC_OK)
        return st;
    l->pr = &lut->profile[k];
    l->lo = l->pr->start_mm;
    l->hi = l->pr->start_mm + l->pr->step_mm * (l->pr->n - 1);
    l->step = o->profile_interval_mm > 0 ? o->profile_interval_mm : l->pr->step_mm;
    l->n = sc_export_cover_points(l->lo, l->hi, l->step);
    if (l->n > SC_EXPORT_AEROTECH_1D_MAX_POINTS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "aerotech-a1: profile %d (%s -> %s) needs %d points at step %.6f mm; "
                            "selfcal writes at most %d per 1-D table: choose a larger "
                            "--profile-interval",
                            k, sc_lut_axis_name(l->pr->axis), sc_lut_axis_name(l->pr->dir), l->n,
                            l->step, SC_EXPORT_AEROTECH_1D_MAX_POINTS);
    l->code = malloc(sizeof *l->code * (size_t)l->n);
    if (!l->code)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (int i = 0; i < l->n; ++i) /* beyond hi (the last step's overhang): the end value */
        l->code[i] = sc_export_quantize(
            sign * sc_export_interp1(l->pr->err_um, l->pr->n, l->pr->start_mm, l->pr->step_mm,
                                     l->lo + i * l->step),
            SC_EXPORT_AEROTECH_UNIT_UM, o->limit_um, &rep->clipped);
    return SC_OK;
}

static void a1_line_write(sc_textbuf *t, const sc_export_options *o, int k, const a1_line *l,
                          double sign)
{
    const int nr[3] = {o->beckhoff_x_axis_nr, o->beckhoff_y_axis_nr, o->beckhoff_z_axis_nr};
    const int ref = nr[l->pr->axis], out = nr[l->pr->dir];
    const char *an = sc_lut_axis_name(l->pr->axis), *dn = sc_lut_axis_name(l->pr->dir);
    sc_tb_printf(t, "; table %d: corrections of axis %d (%s) from the position of axis %d (%s) = "
                    "%se, e = profile %d, the straightness error of %s along %s (indicated - "
                    "true), um\n",
                 k, out, dn, ref, an, sign > 0 ? "+" : "-", k, dn, an);
    sc_tb_printf(t, "; %s from %.6f mm every %.6f mm, %d points (OFFSET: minus the first "
                    "position); beyond them Automation1 holds the nearest end point\n",
                 an, l->lo, l->step, l->n);
    const int first = o->aerotech_1d_output_first ? out : ref;
    const int second = o->aerotech_1d_output_first ? ref : out;
    sc_tb_printf(t, ":START %d %d SAMPLEDIST=%.6f POSUNIT=PRIMARY CORUNIT=PRIMARY/1000\n", first,
                 second, l->step);
    sc_tb_printf(t, ":START OFFSET=%.6f\n", l->lo == 0 ? 0.0 : -l->lo);
    for (int i = 0; i < l->n; ++i) {
        const long long v = l->code[i];
        sc_tb_printf(t, "%s%lld.%04lld\n", v < 0 ? "-" : "", llabs(v) / 10000, llabs(v) % 10000);
    }
    sc_tb_printf(t, ":END\n");
}

sc_status sc_export_aerotech_1d(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                sc_export_report *rep, sc_error *err)
{
    if (lut->n_profiles < 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "aerotech-a1: a 1-D file needs a profile");
    a1_line l[SC_LUT_MAX_PROFILES] = {{0}};
    const double sign = o->negate ? -1.0 : 1.0;
    rep->limit_um = o->limit_um;
    rep->max_um = -1;
    sc_status st = SC_OK;
    double ss = 0;
    long n = 0;
    for (int k = 0; k < lut->n_profiles && st == SC_OK; ++k)
        st = a1_line_build(lut, o, k, sign, &l[k], rep, err);
    for (int k = 0; k < lut->n_profiles && st == SC_OK; ++k) {
        a1_line_residual(&l[k], k, sign, &ss, &n, rep);
        rep->points[k < 4 ? k : 3] += l[k].n;
    }
    if (st == SC_OK) {
        rep->tables = lut->n_profiles;
        rep->samples = n;
        rep->rms_um = sqrt(ss / (double)n);
        rep->interval_mm = l[0].step;
        rep->unit_um = SC_EXPORT_AEROTECH_UNIT_UM;
        sc_tb_printf(t, "; Automation1 1-D axis calibration file, written by selfcal export: %d "
                        "table(s), one per straightness profile\n",
                     lut->n_profiles);
        sc_tb_printf(t, "; %s\n", sign > 0 ? "assumed: a correction is added to the commanded "
                                             "position of its output axis (the table follows "
                                             "the encoder's sign)"
                                           : "NEGATED: -e, the opposite of the default");
        sc_tb_printf(t, "%s",
                     o->aerotech_1d_output_first
                         ? "; OPEN: the help page read gives no 1-D syntax; written ':START "
                           "OutputAxis RefAxis' (--a1-1d-order out,ref): check it in Studio's "
                           "calibration editor\n"
                         : "; OPEN: the help page read gives no 1-D syntax; ':START RefAxis "
                           "OutputAxis' follows public A3200/Automation1 scripts' 1-D line and "
                           "the 2-D line's order (--a1-1d-order out,ref swaps them): check it in "
                           "Studio's calibration editor\n");
        sc_tb_printf(t, "; residual (tables - profiles): rms %.5f um, max %.5f um; clipped "
                        "points: %ld\n",
                     rep->rms_um, rep->max_um, rep->clipped);
        for (int k = 0; k < lut->n_profiles; ++k)
            a1_line_write(t, o, k, &l[k], sign);
    }
    for (int k = 0; k < lut->n_profiles; ++k)
        free(l[k].code);
    return st;
}
