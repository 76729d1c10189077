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

/* True if x, y and z are all finite: x - x is +0 for a finite x and NaN for NaN or +-infinity,
 * and a NaN survives the sums. One compare and one branch instead of six. */
static inline int all_finite(double x, double y, double z)
{
    return (x - x) + (y - y) + (z - z) == 0.0;
}

/* Cell index and fraction for the fractional node coordinate u: u clamped to [0, last] (min
 * then max: compilers emit selects, no data-dependent branch; an infinite u clamps too), index
 * floor(u) in [0, last], fraction in [0, 1). At u = last the index is the last node's with
 * fraction 0: the node and profile arrays are padded after their last value (correct.h), so
 * (1 - 0) a + 0 b is exactly that node's value, as is the neighbouring cell's 0 a + 1 b. The index
 * fits an int32 (last < 65535), so the conversion is a plain truncation. */
static inline int32_t cell(double u, double last, double *frac)
{
    u = u < last ? u : last;
    u = u > 0.0 ? u : 0.0;
    const int32_t k = (int32_t)u; /* u >= 0: the cast is floor */
    *frac = u - (double)k;
    return k;
}

/* The total correction at position (x, y, z) (grid G plus profile offsets), micrometres, per
 * coordinate; returns SC_CORR_ST_OUTSIDE if the position was outside the grid. */
static inline unsigned eval_um(const sc_corr_table *t, double x, double y, double z,
                               double c_um[3])
{
    const unsigned outside = (unsigned)(x < t->x0_mm) | (unsigned)(x > t->x1_mm) |
                             (unsigned)(y < t->y0_mm) | (unsigned)(y > t->y1_mm);
    /* Clamping the node coordinate to [0, last] is clamping the position to the grid's edges. */
    double fx, fy;
    const int32_t j = cell((x - t->x0_mm) * t->inv_px, t->lastx, &fx);
    const int32_t i = cell((y - t->y0_mm) * t->inv_py, t->lasty, &fy);
    /* (1-f)a + f b: exactly a at f = 0 and exactly b at f = 1, so the value at a node is the
     * node's value whichever of its cells the rounding picks (continuity across cell edges). */
    const double wx = 1.0 - fx, wy = 1.0 - fy;
    const int32_t k = i * (int32_t)t->nx + j, kn = k + (int32_t)t->nx;
    const sc_corr_value *g00 = t->g_um[k], *g01 = t->g_um[k + 1], *g10 = t->g_um[kn],
                        *g11 = t->g_um[kn + 1];
    double c0 = ((double)g00[0] * wx + (double)g01[0] * fx) * wy +
                ((double)g10[0] * wx + (double)g11[0] * fx) * fy;
    double c1 = ((double)g00[1] * wx + (double)g01[1] * fx) * wy +
                ((double)g10[1] * wx + (double)g11[1] * fx) * fy;
    /* Profiles: clamped to their range without a status bit (SPEC §4: the out-of-range bit is
     * about the grid). The offset goes to coordinate dir through selects, which keep the sums in
     * registers. */
    double c2 = 0.0;
    const double pos[3] = {x, y, z};
    const unsigned np = t->n_profiles;
    for (unsigned m = 0; m < np; ++m) {
        const sc_corr_profile *p = &t->profile[m];
        double f;
        const int32_t q = cell((pos[p->axis] - p->start_mm) * p->inv_step, p->last, &f);
        const double e = (double)p->err_um[q] * (1.0 - f) + (double)p->err_um[q + 1] * f;
        const unsigned d = p->dir;
        c0 += d == 0 ? e : 0.0;
        c1 += d == 1 ? e : 0.0;
        c2 += d == 2 ? e : 0.0;
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
    if (!all_finite(in[0], in[1], in[2]))
        st |= SC_CORR_ST_INVALID;
    return st;
}

unsigned sc_corr_apply(const sc_corr_table *t, sc_corr_mode mode, const double in_mm[3],
                       double out_mm[3])
{
    const double x = in_mm[0], y = in_mm[1], z = in_mm[2];
    if (!t || t->loaded != 1u || !all_finite(x, y, z))
        return pass_through(t, in_mm, out_mm);
    double c[3];
    unsigned st = SC_CORR_ST_LOADED | eval_um(t, x, y, z, c);
    const double sign_mm = mode == SC_CORR_POSITION ? 1e-3 : -1e-3;
    out_mm[0] = x + sign_mm * c[0];
    out_mm[1] = y + sign_mm * c[1];
    out_mm[2] = z + sign_mm * c[2];
    return st;
}

unsigned sc_corr_apply_inverse(const sc_corr_table *t, const double in_mm[3], double out_mm[3],
                               int iterations)
{
    if (!t || t->loaded != 1u || !all_finite(in_mm[0], in_mm[1], in_mm[2]))
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
        st |= eval_um(t, q[0], q[1], q[2], c);
        q[0] = in_mm[0] - 1e-3 * c[0];
        q[1] = in_mm[1] - 1e-3 * c[1];
        q[2] = in_mm[2] - 1e-3 * c[2];
    }
    out_mm[0] = q[0];
    out_mm[1] = q[1];
    out_mm[2] = q[2];
    return st;
}
