/* correct_apply.c — SPEC §4 runtime correction: bilinear grid G, clamped outside with a status
 * bit, linear profile offsets, measure / position modes, and the exact inverse by fixed-point
 * iteration.
 *
 * Freestanding: no libm (floor by a cast after clamping to the non-negative table range, the
 * finiteness test by comparison with DBL_MAX). Positions and the interpolation are doubles (mm:
 * 1e-16 relative, far below a nanometre at +-1000 mm); the stored node values are floats
 * (micrometres, 24-bit mantissa: 6e-8 relative, 6 pm at 100 um).
 * The table is only read, so any number of threads may call these functions on one table.
 */
#include <float.h>
#include <limits.h>
#include <stddef.h>
#include <stdint.h>

#include "selfcal/correct.h"

/* True for a finite double; false for NaN and +-infinity. */
static inline int is_finite(double x)
{
    return x >= -DBL_MAX && x <= DBL_MAX;
}

/* x limited to [lo, hi] (inputs are finite here). Written as selects so that compilers use
 * min/max instructions or conditional moves: no data-dependent branches. */
static inline double clampd(double x, double lo, double hi)
{
    x = x < lo ? lo : x;
    return x > hi ? hi : x;
}

/* Cell index and fraction for the fractional node coordinate u (already in [0, last] up to
 * rounding; clamped again): index in [0, n-2], fraction in [0, 1]. */
static inline unsigned cell(double u, double last, unsigned n, double *frac)
{
    u = clampd(u, 0.0, last);
    unsigned k = (unsigned)u; /* u >= 0: the cast is floor */
    k = k > n - 2u ? n - 2u : k;
    *frac = u - (double)k;
    return k;
}

/* The total correction at position in (grid G plus profile offsets), micrometres, per
 * coordinate; returns SC_CORR_ST_OUTSIDE if the position was outside the grid. */
static inline unsigned eval_um(const sc_corr_table *t, const double in[3], double c_um[3])
{
    const unsigned outside = (unsigned)(in[0] < t->x0_mm) | (unsigned)(in[0] > t->x1_mm) |
                             (unsigned)(in[1] < t->y0_mm) | (unsigned)(in[1] > t->y1_mm);
    /* Clamping the node coordinate to [0, last] is clamping the position to the grid's edges. */
    double fx, fy;
    const unsigned j = cell((in[0] - t->x0_mm) * t->inv_px, t->lastx, t->nx, &fx);
    const unsigned i = cell((in[1] - t->y0_mm) * t->inv_py, t->lasty, t->ny, &fy);
    /* (1-f)a + f b: exactly a at f = 0 and exactly b at f = 1, so the value at a node is the
     * node's value whichever of its cells the rounding picks (continuity across cell edges). */
    const double wx = 1.0 - fx, wy = 1.0 - fy;
    const size_t k = (size_t)i * t->nx + j, kn = k + t->nx;
    const float *g00 = t->g_um[k], *g01 = t->g_um[k + 1], *g10 = t->g_um[kn], *g11 = t->g_um[kn + 1];
    double c0 = ((double)g00[0] * wx + (double)g01[0] * fx) * wy +
                ((double)g10[0] * wx + (double)g11[0] * fx) * fy;
    double c1 = ((double)g00[1] * wx + (double)g01[1] * fx) * wy +
                ((double)g10[1] * wx + (double)g11[1] * fx) * fy;
    /* Profiles: clamped to their range without a status bit (SPEC §4: the out-of-range bit is
     * about the grid). The offset goes to coordinate dir through a 0/1 mask, which keeps the
     * sums in registers. */
    double c2 = 0.0;
    for (unsigned m = 0; m < t->n_profiles; ++m) {
        const sc_corr_profile *p = &t->profile[m];
        double f;
        const unsigned q = cell((in[p->axis] - p->start_mm) * p->inv_step, p->last, p->n, &f);
        const double e = (double)p->err_um[q] * (1.0 - f) + (double)p->err_um[q + 1] * f;
        c0 += e * p->dir_mask[0];
        c1 += e * p->dir_mask[1];
        c2 += e * p->dir_mask[2];
    }
    c_um[0] = c0;
    c_um[1] = c1;
    c_um[2] = c2;
    return outside ? SC_CORR_ST_OUTSIDE : 0u;
}

static unsigned pass_through(const sc_corr_table *t, const double in[3], double out[3])
{
    out[0] = in[0];
    out[1] = in[1];
    out[2] = in[2];
    unsigned st = (t && t->loaded == 1u) ? SC_CORR_ST_LOADED : 0u;
    if (!is_finite(in[0]) || !is_finite(in[1]) || !is_finite(in[2]))
        st |= SC_CORR_ST_INVALID;
    return st;
}

unsigned sc_corr_apply(const sc_corr_table *t, sc_corr_mode mode, const double in_mm[3],
                       double out_mm[3])
{
    if (!t || t->loaded != 1u || !is_finite(in_mm[0]) || !is_finite(in_mm[1]) ||
        !is_finite(in_mm[2]))
        return pass_through(t, in_mm, out_mm);
    double c[3];
    unsigned st = SC_CORR_ST_LOADED | eval_um(t, in_mm, c);
    const double sign_mm = mode == SC_CORR_POSITION ? 1e-3 : -1e-3;
    out_mm[0] = in_mm[0] + sign_mm * c[0];
    out_mm[1] = in_mm[1] + sign_mm * c[1];
    out_mm[2] = in_mm[2] + sign_mm * c[2];
    return st;
}

unsigned sc_corr_apply_inverse(const sc_corr_table *t, const double in_mm[3], double out_mm[3],
                               int iterations)
{
    if (!t || t->loaded != 1u || !is_finite(in_mm[0]) || !is_finite(in_mm[1]) ||
        !is_finite(in_mm[2]))
        return pass_through(t, in_mm, out_mm);
    /* A fixed, bounded iteration count keeps the call constant-time. */
    if (iterations < 1)
        iterations = 1;
    if (iterations > 16)
        iterations = 16;
    /* q <- p - C(q), starting from q = p (the first step is measure mode). The map contracts when
     * the correction's slope is below 1, true for any real stage (slopes are ~1e-5). */
    double q[3] = {in_mm[0], in_mm[1], in_mm[2]}, c[3];
    unsigned st = SC_CORR_ST_LOADED;
    for (int it = 0; it < iterations; ++it) {
        st |= eval_um(t, q, c);
        q[0] = in_mm[0] - 1e-3 * c[0];
        q[1] = in_mm[1] - 1e-3 * c[1];
        q[2] = in_mm[2] - 1e-3 * c[2];
    }
    out_mm[0] = q[0];
    out_mm[1] = q[1];
    out_mm[2] = q[2];
    return st;
}
