/* libselfcal/src/core/correct_bounds.c — what a loaded table can command: the largest correction
 * of one coordinate and the steepest slope between neighbouring nodes or profile points.
 * Freestanding like the rest of the core (no libm). */
#include "selfcal/correct.h"

static double absd(double v)
{
    return v < 0 ? -v : v;
}

static void steeper(double *worst, double a, double b, double step_mm)
{
    double g = absd(b - a) / step_mm;
    if (g > *worst)
        *worst = g;
}

void sc_corr_bounds(const sc_corr_table *t, double *max_correction_um,
                    double *max_gradient_um_per_mm)
{
    double axis_um[3] = {0, 0, 0};
    double grad = 0;
    unsigned nx = t->nx, ny = t->ny;
    for (unsigned c = 0; c < 2; ++c)
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned j = 0; j < nx; ++j) {
                unsigned k = i * nx + j;
                double v = (double)t->g_um[k][c];
                if (absd(v) > axis_um[c])
                    axis_um[c] = absd(v);
                if (j + 1 < nx)
                    steeper(&grad, v, (double)t->g_um[k + 1][c], t->px_mm);
                if (i + 1 < ny)
                    steeper(&grad, v, (double)t->g_um[k + nx][c], t->py_mm);
            }
    for (unsigned p = 0; p < t->n_profiles; ++p) {
        const sc_corr_profile *pr = &t->profile[p];
        double m = 0;
        for (unsigned k = 0; k < pr->n; ++k) {
            double v = (double)pr->err_um[k];
            if (absd(v) > m)
                m = absd(v);
            if (k + 1 < pr->n)
                steeper(&grad, v, (double)pr->err_um[k + 1], pr->step_mm);
        }
        if (pr->dir < 3)
            axis_um[pr->dir] += m; /* profiles of one DIR add up */
    }
    double worst = axis_um[0];
    if (axis_um[1] > worst)
        worst = axis_um[1];
    if (axis_um[2] > worst)
        worst = axis_um[2];
    *max_correction_um = worst;
    *max_gradient_um_per_mm = grad;
}
