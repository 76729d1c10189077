/* correct_apply.c — SPEC §4 runtime correction: bilinear grid G, clamped outside with a status
 * bit, linear profile offsets, measure / position modes, and the exact inverse by fixed-point
 * iteration (sc_corr_apply_inverse; SC_CORR_MEASURE_EXACT: SC_CORR_EXACT_ITERATIONS steps).
 *
 * Freestanding: no libm (floor by a cast after clamping to the non-negative table range, the
 * finiteness test by x - x == 0). Positions and the interpolation are doubles (mm: 1e-16
 * relative, far below a nanometre at +-1000 mm); the stored node values are the decoded values
 * rounded to float (micrometres, 24-bit mantissa: 6e-8 relative, 6 pm at 100 um), held as
 * doubles on the host (no conversion per call) or as floats with SC_CORR_COMPACT.
 * The table is only read, so any number of threads may call these functions on one table.
 *
 * Two implementations of one computation: portable scalar C, and on x86-64 (SSE2 is part of the
 * base ISA, so no -march flag is needed) the same operations in the same order on pairs of
 * doubles (x with y, two profiles at once) through GCC / Clang vector extensions (no header).
 * Both give the same results bit for bit; the scalar one is what runs on a microcontroller.
 */
#include <float.h>
#include <limits.h>
#include <stddef.h>
#include <stdint.h>

#include "selfcal/correct.h"

/* SC_CORR_SCALAR=1 builds the scalar twin on the host too: test_core_scalar runs the core's unit
 * tests on it (the twin is otherwise only built for microcontrollers). */
#if !SC_CORR_COMPACT && !SC_CORR_SCALAR && defined(__GNUC__) && !defined(__clang__) &&           \
    defined(__SSE2__)
#define SC_CORR_PAIRS 1
#else
#define SC_CORR_PAIRS 0
#endif

/* True if x, y and z are all finite: x - x is +0 for a finite x and NaN for NaN or +-infinity,
 * and a NaN survives the sums. One compare and one branch instead of six. */
static inline int all_finite(double x, double y, double z)
{
    return (x - x) + (y - y) + (z - z) == 0.0;
}

/* Cell index and fraction for the fractional node coordinate u: u clamped to [0, last] (min
 * then max: no data-dependent branch, and an infinite u clamps too), index floor(u) in
 * [0, last], fraction in [0, 1). At u = last the index is the last node's with fraction 0: the
 * node and profile arrays are padded after their last value (correct.h), so (1 - 0) a + 0 b is
 * exactly that node's value, as is the neighbouring cell's 0 a + 1 b. The index fits an int32
 * (last < 65535), so the conversion is a plain truncation. */
static inline int32_t cell(double u, double last, double *frac)
{
    u = u < last ? u : last;
    u = u > 0.0 ? u : 0.0;
    const int32_t k = (int32_t)u; /* u >= 0: the cast is floor */
    *frac = u - (double)k;
    return k;
}

/* The offset of profile p at position pos (micrometres), clamped to the profile's range (SPEC
 * §4: without a status bit; the out-of-range bit is about the grid). */
static inline double profile_um(const sc_corr_profile *p, const double pos[3])
{
    double f;
    const int32_t q = cell((pos[p->axis] - p->start_mm) * p->inv_step, p->last, &f);
    return (double)p->err_um[q] * (1.0 - f) + (double)p->err_um[q + 1] * f;
}

/* c[dir] += e, through selects that keep the three sums in registers. */
static inline void add_dir(unsigned dir, double e, double *c0, double *c1, double *c2)
{
    *c0 += dir == 0 ? e : 0.0;
    *c1 += dir == 1 ? e : 0.0;
    *c2 += dir == 2 ? e : 0.0;
}

#if SC_CORR_PAIRS
typedef double v2d __attribute__((vector_size(16)));
typedef double v2d_u8 __attribute__((vector_size(16), aligned(8))); /* 8-byte aligned access */
typedef int32_t v4i __attribute__((vector_size(16)));
typedef int64_t v2l __attribute__((vector_size(16)));

/* A pair from the table (16-byte aligned there: correct.h), and from the caller's arrays. */
static inline v2d load2(const void *p)
{
    return *(const v2d *)p;
}

static inline v2d load2u(const double *p)
{
    return *(const v2d_u8 *)p;
}

/* a & the 128-bit mask at m (in the table). */
static inline v2d and2(v2d a, const uint64_t *m)
{
    return __builtin_ia32_andpd(a, load2(m));
}

static inline v2d dup0(v2d a)
{
    return (v2d){a[0], a[0]};
}

static inline v2d dup1(v2d a)
{
    return (v2d){a[1], a[1]};
}

/* cell() on two coordinates at once (minpd / maxpd select exactly as the scalar ?: do): the
 * fractions in *frac, the two indices in the low and high halves of the result. */
static inline uint64_t cell2(v2d u, v2d last, v2d *frac)
{
    u = __builtin_ia32_minpd(u, last);            /* u < last ? u : last */
    u = __builtin_ia32_maxpd(u, (v2d){0.0, 0.0}); /* u > 0 ? u : 0 */
    const v4i k = __builtin_ia32_cvttpd2dq(u);    /* truncation: floor for u >= 0 */
    *frac = u - __builtin_ia32_cvtdq2pd(k);
    return (uint64_t)((v2l)k)[0];
}

/* All of x, y (the pair) and z finite (as all_finite). */
static inline int all_finite2(v2d xy, double z)
{
    const v2d d = (xy - xy) + (z - z);
    return __builtin_ia32_movmskpd(__builtin_ia32_cmpunordpd(d, d)) == 0;
}

/* The total correction at pos = (x, y, z) = (xy, z) in micrometres: (x, y) components in *cxy,
 * z in *cz; returns SC_CORR_ST_OUTSIDE if the position was outside the grid. */
static inline unsigned eval2(const sc_corr_table *t, const double pos[3], v2d xy, v2d *cxy,
                             double *cz)
{
    const v2d lo = load2(&t->x0_mm);
    const v2d out = __builtin_ia32_orpd(__builtin_ia32_cmpltpd(xy, load2(t->in_lo_mm)),
                                        __builtin_ia32_cmpltpd(load2(t->in_hi_mm), xy));
    const unsigned outside = (unsigned)__builtin_ia32_movmskpd(out);
    v2d f;
    const uint64_t ji = cell2((xy - lo) * load2(&t->inv_px), load2(&t->lastx), &f);
    const v2d w = 1.0 - f, wx = dup0(w), fx = dup0(f), wy = dup1(w), fy = dup1(f);
    const size_t nx = t->nx;
    const double *g0 = t->g_um[(ji >> 32) * nx + (uint32_t)ji], *g1 = g0 + 2 * nx;
    v2d c = (load2(g0) * wx + load2(g0 + 2) * fx) * wy + (load2(g1) * wx + load2(g1 + 2) * fx) * fy;
    /* Profiles two at a time (an odd count is padded with a slot that adds 0; correct.h); the
     * coordinate each one corrects is selected by bit masks, no branch. Adding 0 to the
     * coordinates a profile does not correct is what the scalar code does too (c + 0 = c: these
     * sums are never -0), and each sum is formed in profile order, so the results are those of
     * the scalar code. */
    v2d czz = {0.0, 0.0};
    const unsigned ns = t->p_slots;
    for (unsigned m = 0; m < ns; m += 2) {
        v2d fq;
        const uint64_t q = cell2(((v2d){pos[t->p_axis[m]], pos[t->p_axis[m + 1]]} -
                             load2(t->p_start_mm + m)) * load2(t->p_inv_step + m),
                            load2(t->p_last + m), &fq);
        const double *ea = t->profile[m].err_um + (uint32_t)q;
        const double *eb = t->profile[m + 1].err_um + (q >> 32);
        const v2d e = (v2d){ea[0], eb[0]} * (1.0 - fq) + (v2d){ea[1], eb[1]} * fq;
        const v2d e0 = dup0(e), e1 = dup1(e);
        c = (c + and2(e0, t->p_dir_mask[m])) + and2(e1, t->p_dir_mask[m + 1]);
        czz = (czz + and2(e0, t->p_dir_mask[m] + 2)) + and2(e1, t->p_dir_mask[m + 1] + 2);
    }
    *cxy = c;
    *cz = czz[0];
    return outside ? SC_CORR_ST_OUTSIDE : 0u;
}
#endif

/* The total correction at position (x, y, z) (grid G plus profile offsets), micrometres, per
 * coordinate; returns SC_CORR_ST_OUTSIDE if the position was outside the grid. */
static inline unsigned eval_um(const sc_corr_table *t, double x, double y, double z,
                               double c_um[3])
{
#if SC_CORR_PAIRS
    v2d cxy;
    const double pos[3] = {x, y, z};
    const unsigned st = eval2(t, pos, (v2d){x, y}, &cxy, &c_um[2]);
    c_um[0] = cxy[0];
    c_um[1] = cxy[1];
    return st;
#else
    const unsigned outside = (unsigned)(x < t->in_lo_mm[0]) | (unsigned)(x > t->in_hi_mm[0]) |
                             (unsigned)(y < t->in_lo_mm[1]) | (unsigned)(y > t->in_hi_mm[1]);
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
    double c2 = 0.0;
    const double pos[3] = {x, y, z};
    const unsigned np = t->n_profiles;
    for (unsigned m = 0; m < np; ++m)
        add_dir(t->profile[m].dir, profile_um(&t->profile[m], pos), &c0, &c1, &c2);
    c_um[0] = c0;
    c_um[1] = c1;
    c_um[2] = c2;
    return outside ? SC_CORR_ST_OUTSIDE : 0u;
#endif
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
    if (mode == SC_CORR_MEASURE_EXACT) /* a fixed number of steps: constant time */
        return sc_corr_apply_inverse(t, in_mm, out_mm, SC_CORR_EXACT_ITERATIONS);
    const double sign_mm = mode == SC_CORR_POSITION ? 1e-3 : -1e-3;
#if SC_CORR_PAIRS
    const v2d xy = load2u(in_mm);
    const double z = in_mm[2];
    if (!t || t->loaded != 1u || !all_finite2(xy, z))
        return pass_through(t, in_mm, out_mm);
    v2d cxy;
    double cz;
    const unsigned st = SC_CORR_ST_LOADED | eval2(t, in_mm, xy, &cxy, &cz);
    *(v2d_u8 *)out_mm = xy + sign_mm * cxy;
    out_mm[2] = z + sign_mm * cz;
    return st;
#else
    const double x = in_mm[0], y = in_mm[1], z = in_mm[2];
    if (!t || t->loaded != 1u || !all_finite(x, y, z))
        return pass_through(t, in_mm, out_mm);
    double c[3];
    const unsigned st = SC_CORR_ST_LOADED | eval_um(t, x, y, z, c);
    out_mm[0] = x + sign_mm * c[0];
    out_mm[1] = y + sign_mm * c[1];
    out_mm[2] = z + sign_mm * c[2];
    return st;
#endif
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
