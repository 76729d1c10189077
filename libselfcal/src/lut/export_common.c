/* export_common.c — what every exporter back-end shares (export_internal.h): the text buffer,
 * quantization and clipping, 1-D clamped interpolation, table sizing, the map's value at a
 * point, and the residual of a controller's interpolation against the map. */
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "export_internal.h"

/* ---- a growing text buffer ---- */

void sc_tb_printf(sc_textbuf *t, const char *fmt, ...)
{
    if (t->failed)
        return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(t->s ? t->s + t->len : NULL, t->s ? t->cap - t->len : 0, fmt, ap);
        va_end(ap);
        if (n < 0) {
            t->failed = 1;
            return;
        }
        if (t->s && t->len + (size_t)n < t->cap) {
            t->len += (size_t)n;
            return;
        }
        size_t ncap = t->cap ? t->cap * 2 : 65536;
        while (ncap < t->len + (size_t)n + 1)
            ncap *= 2;
        char *p = realloc(t->s, ncap);
        if (!p) {
            t->failed = 1;
            return;
        }
        t->s = p;
        t->cap = ncap;
    }
}

/* ---- the map and its tables ---- */

double sc_export_map_g(const sc_lut *lut, int comp, double x, double y)
{
    double gx, gy;
    sc_lut_grid_eval(lut, x, y, &gx, &gy);
    return comp == 0 ? gx : gy;
}

long long sc_export_quantize(double v_um, double unit_um, double limit_um, long *clipped)
{
    if (limit_um > 0 && fabs(v_um) > limit_um) {
        v_um = v_um > 0 ? limit_um : -limit_um;
        ++*clipped;
    }
    return llround(v_um / unit_um);
}

double sc_export_interp1(const double *v, int n, double start, double step, double s)
{
    double u = (s - start) / step;
    if (u <= 0)
        return v[0];
    if (u >= n - 1)
        return v[n - 1];
    int k = (int)u;
    if (k > n - 2)
        k = n - 2;
    double f = u - k;
    return v[k] * (1 - f) + v[k + 1] * f;
}

sc_status sc_export_profile_meets_map(const sc_lut *lut, int k, const char *fmt, sc_error *err)
{
    const sc_lut_profile *p = &lut->profile[k];
    if (p->axis > 1)
        return SC_OK; /* the map has no extent along z */
    const double lo = p->axis == 0 ? lut->x0_mm : lut->y0_mm;
    const double hi = lo + (p->axis == 0 ? (lut->nx - 1) * lut->px_mm : (lut->ny - 1) * lut->py_mm);
    const double a = p->start_mm, b = p->start_mm + (p->n - 1) * p->step_mm;
    if (b < lo || a > hi)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "%s: profile %d (%s -> %s) covers %s = %g..%g mm, the map %g..%g mm: "
                            "they do not overlap (place it with AXIS:DIR:P.csv@OFFSET_MM)",
                            fmt, k, sc_lut_axis_name(p->axis), sc_lut_axis_name(p->dir),
                            sc_lut_axis_name(p->axis), a, b, lo, hi);
    return SC_OK;
}

void sc_export_residual(const sc_lut *lut, const int *comps, int ncomp, double sign,
                        sc_export_ctrl_fn f, const void *ctx, sc_export_report *rep)
{
    const int sub = 4;
    double ss = 0, mx = -1;
    long n = 0;
    for (int a = 0; a <= sub * (lut->ny - 1); ++a)
        for (int b = 0; b <= sub * (lut->nx - 1); ++b) {
            double x = lut->x0_mm + lut->px_mm * b / sub, y = lut->y0_mm + lut->py_mm * a / sub;
            for (int c = 0; c < ncomp; ++c) {
                double r = f(ctx, comps[c], x, y) - sign * sc_export_map_g(lut, comps[c], x, y);
                ss += r * r;
                ++n;
                if (fabs(r) > mx) {
                    mx = fabs(r);
                    rep->max_at_mm[0] = x;
                    rep->max_at_mm[1] = y;
                }
            }
        }
    rep->samples = n;
    rep->rms_um = sqrt(ss / (double)n);
    rep->max_um = mx;
}

int sc_export_cover_points(double lo, double hi, double step)
{
    double q = ceil((hi - lo) / step - 1e-9);
    return q < (double)INT_MAX - 1.0 ? 1 + (int)q : INT_MAX;
}

/* Mean of component comp over the other coordinate's nodes, at position s along `along`. */
double sc_export_mean_along(const sc_lut *lut, int comp, int along, double s)
{
    double sum = 0;
    int n = along == 0 ? lut->ny : lut->nx;
    for (int k = 0; k < n; ++k)
        sum += along == 0 ? sc_export_map_g(lut, comp, s, sc_export_node_y(lut, k)) : sc_export_map_g(lut, comp, sc_export_node_x(lut, k), s);
    return sum / n;
}

double sc_export_grand_mean(const sc_lut *lut, int comp)
{
    const double *g = comp == 0 ? lut->gx_um : lut->gy_um;
    double sum = 0;
    for (int k = 0; k < lut->nx * lut->ny; ++k)
        sum += g[k];
    return sum / (lut->nx * lut->ny);
}
