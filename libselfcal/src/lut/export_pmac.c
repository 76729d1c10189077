/* export_pmac.c — the stage error map as Power PMAC compensation tables (`selfcal export --format
 * powerpmac`, docs/exporters.md): a script of CompTable[m] setup elements and data, two 2-D
 * tables (m = T: the x motor's correction, m = T + 1: the y motor's), both over the x and y
 * motors' positions.
 *
 * Source: Power PMAC Software Reference Manual (Delta Tau / Omron, 050-PRPMAC-0S0), the
 * CompTable[m] data structure: Source[i] (the motor whose position is dimension i's input),
 * Nx[i] (the zones along dimension i), X0[i] (the first entry's position), Dx[i] (the table's span
 * along dimension i), Target[k] (the address the output goes to: Motor[n].CompPos.a), Sf[k] (the
 * scale of that output), Ctrl, Data[] (the entries). The element names and the use of Dx as the
 * span (not the step) agree with a public Power PMAC command builder (Nx = entries, Dx = to -
 * from); the stored copy of the manual we could read stops at its title pages. Turbo PMAC's
 * Software Reference (DEFINE COMP) documents that a table ROLLS OVER outside its span.
 *
 * Open points, said in the file and in docs/exporters.md: the sign (taken as: CompPos is added to
 * the motor's commanded position, so the value is +G; --negate writes -G); the entries (taken as
 * (Nx[0] + 1) x (Nx[1] + 1) values, dimension 0 fastest); Ctrl (written 3, taken as "no rollover
 * in dimensions 0 and 1": the end entries beyond the table, which is selfcald's clamping; a
 * controller that rolls over instead applies the far edge's value beyond the table); the units
 * (motor units: mm unless --steps-per-mm gives motor units per mm). The residual assumes the
 * documented bilinear interpolation inside and the held end values beyond. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "export_internal.h"

#define PMAC_DECIMALS_SCALE 1e9 /* entries written with 9 decimals of motor units */

typedef struct pmac_ctx {
    int n[2];              /* entries along x (dimension 0) and y (dimension 1) */
    double x0[2], step[2]; /* mm */
    double upm[2];         /* motor units per mm of x and y */
    long long *code[2];    /* [j * n[0] + i]: x's and y's corrections, 1e-9 motor units */
} pmac_ctx;

static double pmac_eval(const void *vctx, int comp, double x, double y)
{
    const pmac_ctx *c = vctx;
    double u = fmin(fmax((x - c->x0[0]) / c->step[0], 0.0), c->n[0] - 1.0);
    double v = fmin(fmax((y - c->x0[1]) / c->step[1], 0.0), c->n[1] - 1.0);
    int i = (int)u, j = (int)v;
    if (i > c->n[0] - 2)
        i = c->n[0] - 2;
    if (j > c->n[1] - 2)
        j = c->n[1] - 2;
    const double fu = u - i, fv = v - j;
    const long long *r0 = c->code[comp] + (size_t)j * c->n[0], *r1 = r0 + c->n[0];
    const double a = (double)r0[i] * (1 - fu) + (double)r0[i + 1] * fu;
    const double b = (double)r1[i] * (1 - fu) + (double)r1[i + 1] * fu;
    /* motor units of the target motor -> um */
    return (a * (1 - fv) + b * fv) / PMAC_DECIMALS_SCALE / c->upm[comp] * 1e3;
}

static void pmac_value(char *buf, size_t cap, long long v)
{
    snprintf(buf, cap, "%s%lld.%09lld", v < 0 ? "-" : "", llabs(v) / 1000000000LL,
             llabs(v) % 1000000000LL);
}

static void pmac_table(sc_textbuf *t, const sc_export_options *o, const pmac_ctx *c, int comp,
                       double sign)
{
    const int m = o->siemens_first_table + comp;
    const int mot[2] = {o->beckhoff_x_axis_nr, o->beckhoff_y_axis_nr};
    sc_tb_printf(t, "// CompTable[%d]: %sG%s of motor %d (%s) over motors %d (x) and %d (y)\n", m,
                 sign > 0 ? "+" : "-", comp == 0 ? "x" : "y", mot[comp], comp == 0 ? "x" : "y",
                 mot[0], mot[1]);
    for (int d = 0; d < 2; ++d)
        sc_tb_printf(t, "CompTable[%d].Source[%d]=%d\n", m, d, mot[d]);
    for (int d = 0; d < 2; ++d)
        sc_tb_printf(t, "CompTable[%d].Nx[%d]=%d\n", m, d, c->n[d] - 1);
    sc_tb_printf(t, "CompTable[%d].Nx[2]=0\n", m);
    for (int d = 0; d < 2; ++d)
        sc_tb_printf(t, "CompTable[%d].X0[%d]=%.9f\n", m, d, c->x0[d] * c->upm[d]);
    for (int d = 0; d < 2; ++d)
        sc_tb_printf(t, "CompTable[%d].Dx[%d]=%.9f\n", m, d,
                     (c->n[d] - 1) * c->step[d] * c->upm[d]);
    sc_tb_printf(t, "CompTable[%d].Target[0]=Motor[%d].CompPos.a\n", m, mot[comp]);
    sc_tb_printf(t, "CompTable[%d].Sf[0]=1\n", m);
    sc_tb_printf(t, "CompTable[%d].Ctrl=3\n", m);
    char v[48];
    for (int j = 0; j < c->n[1]; ++j) {
        sc_tb_printf(t, "CompTable[%d].Data[%d]=", m, j * c->n[0]);
        for (int i = 0; i < c->n[0]; ++i) {
            pmac_value(v, sizeof v, c->code[comp][(size_t)j * c->n[0] + i]);
            sc_tb_printf(t, "%s%s", i ? "," : "", v);
        }
        sc_tb_printf(t, "\n");
    }
}

static sc_status export_powerpmac(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                sc_export_report *rep, sc_error *err)
{
    if (o->interval_mm > 0 || o->use_line)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "powerpmac: the tables take the map's own nodes (no interval, no "
                            "line)");
    if (o->siemens_first_table < 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "powerpmac: table index %d is below 0",
                            o->siemens_first_table);
    pmac_ctx c;
    c.n[0] = lut->nx;
    c.n[1] = lut->ny;
    c.x0[0] = lut->x0_mm;
    c.x0[1] = lut->y0_mm;
    c.step[0] = lut->px_mm;
    c.step[1] = lut->py_mm;
    for (int d = 0; d < 2; ++d) {
        const double s = o->steps_per_mm[d];
        if (!(s >= 0) || !(s <= 1e9))
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "powerpmac: motor units per mm must be in 0..1e9, not %g", s);
        c.upm[d] = s > 0 ? s : 1.0;
    }
    const size_t nn = (size_t)c.n[0] * (size_t)c.n[1];
    c.code[0] = malloc(sizeof *c.code[0] * nn);
    c.code[1] = malloc(sizeof *c.code[1] * nn);
    if (!c.code[0] || !c.code[1]) {
        free(c.code[0]);
        free(c.code[1]);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    const double sign = o->negate ? -1.0 : 1.0;
    rep->limit_um = o->limit_um;
    for (int comp = 0; comp < 2; ++comp) {
        const double *g = comp == 0 ? lut->gx_um : lut->gy_um;
        /* quantized in 1e-9 motor units of the target motor (unit in um: 1e-6 / upm) */
        const double unit_um = 1e3 / PMAC_DECIMALS_SCALE / c.upm[comp];
        for (size_t k = 0; k < nn; ++k)
            c.code[comp][k] = sc_export_quantize(sign * g[k], unit_um, o->limit_um, &rep->clipped);
    }
    const int comps[2] = {0, 1};
    sc_export_residual(lut, comps, 2, sign, pmac_eval, &c, rep);
    rep->tables = 2;
    rep->points[0] = c.n[0];
    rep->points[1] = c.n[1];
    rep->interval_mm = c.step[0];
    rep->unit_um = 1e3 / PMAC_DECIMALS_SCALE / fmax(c.upm[0], c.upm[1]);

    sc_tb_printf(t, "// Power PMAC compensation tables, written by selfcal export\n");
    sc_tb_printf(t, "// values: %sG of the stage error map (G = indicated - true) in motor units "
                    "(%.9g per mm of x, %.9g of y)\n", sign > 0 ? "+" : "-", c.upm[0], c.upm[1]);
    sc_tb_printf(t, "// %s\n", sign > 0 ? "assumed: Motor[n].CompPos is added to the motor's "
                                         "commanded position"
                                       : "NEGATED: -G, the opposite of the default");
    sc_tb_printf(t, "// assumed: Ctrl=3 holds the end entries beyond the table in both dimensions "
                    "(no rollover), (Nx[0]+1) x (Nx[1]+1) entries, dimension 0 (x) fastest\n");
    sc_tb_printf(t, "// residual (tables - map): rms %.6f um, max %.6f um; clipped points: %ld\n",
                 rep->rms_um, rep->max_um, rep->clipped);
    for (int comp = 0; comp < 2; ++comp)
        pmac_table(t, o, &c, comp, sign);
    free(c.code[0]);
    free(c.code[1]);
    return SC_OK;
}

const sc_export_backend sc_export_backend_powerpmac = {SC_EXPORT_POWERPMAC, "powerpmac", export_powerpmac};
