/* export_linuxcnc.c — the LinuxCNC joint compensation file (`--format linuxcnc`,
 * docs/exporters.md; COMP_FILE_TYPE = 1: nominal, forward trim, reverse trim, mm), one joint: G of
 * that axis as a function of that axis only (the mean over the other coordinate, or along one
 * line). */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"

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
        double b = o->axis == 0 ? sc_export_node_y(lut, lut->ny - 1) : sc_export_node_x(lut, lut->nx - 1);
        double tol = 1e-9 * (fabs(a) + fabs(b) + 1);
        if (!(o->line_mm >= a - tol && o->line_mm <= b + tol))
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "linuxcnc: --at %g mm is outside the map (%c from %g to %g mm)",
                                o->line_mm, o->axis == 0 ? 'y' : 'x', a, b);
    }
    lcnc_ctx c;
    c.axis = o->axis;
    const double lo = o->axis == 0 ? lut->x0_mm : lut->y0_mm;
    const double hi = o->axis == 0 ? sc_export_node_x(lut, lut->nx - 1) : sc_export_node_y(lut, lut->ny - 1);
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
            v = o->axis == 0 ? sc_export_map_g(lut, 0, s, o->line_mm) : sc_export_map_g(lut, 1, o->line_mm, s);
        else
            v = sc_export_mean_along(lut, o->axis, o->axis, s);
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
              sc_export_axis_upper(o->axis), sign < 0 ? "-" : "+", o->axis == 0 ? "x" : "y");
    free(code);
    free(c.value_um);
    return SC_OK;
}

const sc_export_backend sc_export_backend_linuxcnc = {SC_EXPORT_LINUXCNC, "linuxcnc",
                                                      export_linuxcnc};
