/* The least squares' shared low-level steps, below the plan, its execution and its
 * functionals (which all call them, so that none of those three calls back into another):
 * the progress report, one equation's row, the small dense solves and nullity test, the pinned
 * solve through the factor, a view's misalignment normal equations and fit, the free
 * misalignments' slots, the full system's description and the redundancy figures. */
#include "grid_lsq_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Tell the caller's progress function (if any) the phase and the work done so far. */
void sc_lsq_progress(const sc_grid_lsq_plan *q, const char *phase, double done)
{
    if (q->progress)
        q->progress(q->progress_ctx, phase, done, q->work_total, q->peak_est);
}

/* Numerical rank deficiency of a small dense symmetric PSD matrix (m x m, destroyed) by
 * Cholesky with diagonal pivoting; pivots below tol·(largest diagonal) end it. */
int sc_lsq_small_nullity(double *a, int m, double tol)
{
    double dmax = 0;
    for (int i = 0; i < m; ++i)
        if (a[i * m + i] > dmax)
            dmax = a[i * m + i];
    if (!(dmax > 0))
        return m;
    /* a view's misalignment fit (m <= 5) allocates nothing */
    int small[16], *piv = m <= 16 ? small : malloc(sizeof(int) * (size_t)m);
    if (!piv)
        return -1;
    for (int i = 0; i < m; ++i)
        piv[i] = i;
    int r = 0;
    for (; r < m; ++r) {
        int best = r;
        for (int i = r; i < m; ++i)
            if (a[piv[i] * m + piv[i]] > a[piv[best] * m + piv[best]])
                best = i;
        int t = piv[r];
        piv[r] = piv[best];
        piv[best] = t;
        int p = piv[r];
        double d = a[p * m + p];
        if (!(d > tol * dmax))
            break;
        for (int i = r + 1; i < m; ++i) {
            int pi = piv[i];
            double l = a[pi * m + p] / d;
            for (int j = r + 1; j < m; ++j) {
                int pj = piv[j];
                a[pi * m + pj] -= l * a[p * m + pj];
            }
        }
    }
    if (piv != small)
        free(piv);
    return m - r;
}

int sc_lsq_misalignment_nullity(const sc_lsq_full_desc *fd, int dense_max)
{
    int nm = fd->nm;
    if (nm > dense_max)
        return sc_lsq_full_misalignment_nullity_sparse(fd, LSQ_SMALL_TOL);
    double *mm = malloc(sizeof(double) * ((size_t)nm * nm + 1));
    int nu = -1;
    if (mm && sc_lsq_full_misalignment_block(fd, mm) == 0)
        nu = sc_lsq_small_nullity(mm, nm, LSQ_SMALL_TOL);
    free(mm);
    return nu;
}

/* Coefficients of w_e = s_e·J_e over x = (g, m): 3 (index, value) pairs, 4 with drift. */
int sc_lsq_eq_row(const sc_grid_lsq_plan *q, long e, int *idx, double *val)
{
    double s = q->eq_s[e];
    int base = q->ng + q->nb * q->eq_v[e];
    idx[0] = q->eq_g[e];
    val[0] = s;
    idx[1] = base + q->eq_c[e];
    val[1] = s;
    idx[2] = base + 2;
    val[2] = s * q->eq_pos[e];
    if (!q->drift)
        return 3;
    idx[3] = base + 3 + q->eq_c[e];
    val[3] = s * q->eq_dt[e];
    return 4;
}

/* The free (unpinned) misalignment unknowns: their original indices into at (ascending; may be
 * NULL), and into slot each misalignment's place among them, which is its whole column's in the
 * selected inverse (-1 pinned; may be NULL); their count. */
int sc_lsq_free_misalignments(const sc_grid_lsq_plan *q, int *at, int *slot)
{
    int k = 0;
    for (int t = 0; t < q->nm; ++t) {
        int free_t = !q->pinned[q->ng + t];
        if (slot)
            slot[t] = free_t ? k : -1;
        if (free_t && at)
            at[k] = q->ng + t;
        k += free_t;
    }
    return k;
}

static int full_row_cb(const void *ctx, long e, int *idx, double *val)
{
    return sc_lsq_eq_row(ctx, e, idx, val);
}

void sc_lsq_full_desc_of(const sc_grid_lsq_plan *q, sc_lsq_full_desc *d)
{
    d->n_red = q->n_red, d->ng = q->ng, d->nm = q->nm, d->nb = q->nb;
    d->neq = q->neq, d->n_groups = 2 * q->nn;
    d->grp_ptr = q->grp_ptr, d->grp_eq = q->grp_eq;
    d->w = q->eq_w, d->pinned = q->pinned;
    d->row = full_row_cb, d->ctx = q, d->row_max = ROW_MAX;
}

/* X (n_red x ncol, column after column) := pinned-system solves of its columns (original index
 * space), with `refine` steps of iterative refinement against the assembled matrix; B and R:
 * workspace of n_red·ncol each (unused, may be NULL, without refinement). Returns 0, -1 if the
 * solver ran out of memory. */
int sc_lsq_pinned_solve(const sc_grid_lsq_plan *q, double *X, int ncol, int refine, double *B,
                        double *R)
{
    size_t n = (size_t)q->n_red, tot = n * (size_t)ncol;
    for (size_t k = 0; k < tot; ++k)
        X[k] = q->pinned[k % n] ? 0.0 : X[k];
    if (q->full) { /* a solve of the full matrix with zeros on A: the reduced system's */
        if (sc_lsq_full_solve(q->full, q->f, X, ncol, refine) != 0)
            return -1;
        for (size_t k = 0; k < tot; ++k)
            if (q->pinned[k % n])
                X[k] = 0.0;
        return 0;
    }
    if (refine > 0)
        memcpy(B, X, sizeof(double) * tot);
    if (sc_spsym_solve(q->f, X, ncol) != 0)
        return -1;
    for (int it = 0; it < refine; ++it) {
        sc_spsym_matvec(q->f, X, R, ncol);
        for (size_t k = 0; k < tot; ++k)
            R[k] = B[k] - R[k];
        if (sc_spsym_solve(q->f, R, ncol) != 0)
            return -1;
        for (size_t k = 0; k < tot; ++k)
            X[k] += R[k];
    }
    for (size_t k = 0; k < tot; ++k)
        if (q->pinned[k % n])
            X[k] = 0.0;
    return 0;
}

/* X (n_red x ncol) := 0 at the pinned unknowns. */
void sc_lsq_zero_pinned(const sc_grid_lsq_plan *q, double *X, int ncol)
{
    for (int i = 0; i < q->n_red; ++i)
        if (q->pinned[i])
            for (int c = 0; c < ncol; ++c)
                X[(size_t)c * q->n_red + i] = 0.0;
}

/* Equation e's part (its row idx, val, len: eq_row's) of its view's block of the misalignment
 * normal matrix, G and A held (nrm: nb x nb per view). */
void sc_lsq_view_normal_add(const sc_grid_lsq_plan *q, long e, const int *idx, const double *val,
                            int len, double *nrm)
{
    int nb = q->nb, v = q->eq_v[e], base = q->ng + nb * v;
    double *b = nrm + (size_t)v * nb * nb;
    for (int i = 1; i < len; ++i)
        for (int j = 1; j < len; ++j)
            b[(idx[i] - base) * nb + idx[j] - base] += q->eq_w[e] * val[i] * val[j];
}

/* The redundancy figures of q->info from the leverages. */
void sc_lsq_redundancy_info(sc_grid_lsq_plan *q)
{
    long testable = 0;
    double rmin = INFINITY, rsum = 0;
    for (long e = 0; e < q->neq; ++e) {
        double r = 1.0 - q->eq_h[e];
        if (r > 1e-9) { /* as the residuals' test: t is NaN beyond */
            testable++, rsum += r;
            rmin = fmin(rmin, r);
        }
    }
    q->info.n_testable = testable;
    q->info.n_untestable = q->neq - testable;
    q->info.redundancy_min = testable ? rmin : NAN;
    q->info.redundancy_mean = testable ? rsum / (double)testable : NAN;
    double crit = sc_grid_outlier_critical(SC_GRID_OUTLIER_ALPHA, testable, 0);
    q->info.mdb_ratio_max = sc_grid_mdb_ratio(crit, 0.8, q->info.redundancy_min);
    q->info.mdb_ratio_mean_r = sc_grid_mdb_ratio(crit, 0.8, q->info.redundancy_mean);
}

/* Solve a small dense symmetric system m x m (row-major, destroyed) in place of rhs by Gaussian
 * elimination with partial pivoting; a null pivot gives a NaN solution. */
void sc_lsq_small_solve(double *a, double *rhs, int m)
{
    for (int c = 0; c < m; ++c) {
        int best = c;
        for (int r = c + 1; r < m; ++r)
            if (fabs(a[r * m + c]) > fabs(a[best * m + c]))
                best = r;
        if (best != c) {
            for (int k = 0; k < m; ++k) {
                double t = a[c * m + k];
                a[c * m + k] = a[best * m + k];
                a[best * m + k] = t;
            }
            double t = rhs[c];
            rhs[c] = rhs[best];
            rhs[best] = t;
        }
        double piv = a[c * m + c], scale = 0;
        for (int k = 0; k < m; ++k)
            scale = fmax(scale, fabs(a[k * m + k]));
        if (!(fabs(piv) > 1e-13 * scale)) {
            for (int k = 0; k < m; ++k)
                rhs[k] = NAN;
            return;
        }
        for (int r = c + 1; r < m; ++r) {
            double l = a[r * m + c] / piv;
            for (int k = c; k < m; ++k)
                a[r * m + k] -= l * a[c * m + k];
            rhs[r] -= l * rhs[c];
        }
    }
    for (int c = m - 1; c >= 0; --c) {
        double t = rhs[c];
        for (int k = c + 1; k < m; ++k)
            t -= a[c * m + k] * rhs[k];
        rhs[c] = t / a[c * m + c];
    }
}

/* One view's misalignment fit from its normal equations nrm (nb x nb, row-major) and rh: the
 * columns taken in order (tx, ty, φ, vx, vy), each kept when the system stays regular with it
 * (Cholesky with diagonal pivoting, LSQ_SMALL_TOL), the kept ones solved, the others 0 — a
 * particular least-squares solution, so the residuals are right whatever the view determines
 * (a single mark: tx, ty fit it exactly, φ stays 0). m: nb values (NaN for a view without
 * equations); returns how many columns were kept (nb: the misalignments are determined). */
int sc_lsq_fit_view(const double *nrm, const double *rh, int nb, double *m)
{
    int keep[SC_GRID_LSQ_MAX_NB], nk = 0;
    for (int c = 0; c < nb; ++c)
        m[c] = 0;
    for (int c = 0; c < nb; ++c) {
        double sub[SC_GRID_LSQ_MAX_NB * SC_GRID_LSQ_MAX_NB];
        keep[nk] = c;
        for (int i = 0; i <= nk; ++i)
            for (int j = 0; j <= nk; ++j)
                sub[i * (nk + 1) + j] = nrm[keep[i] * nb + keep[j]];
        if (sc_lsq_small_nullity(sub, nk + 1, LSQ_SMALL_TOL) == 0)
            ++nk;
    }
    if (nk == 0) {
        for (int c = 0; c < nb; ++c)
            m[c] = NAN;
        return 0;
    }
    double sub[SC_GRID_LSQ_MAX_NB * SC_GRID_LSQ_MAX_NB], r[SC_GRID_LSQ_MAX_NB];
    for (int i = 0; i < nk; ++i) {
        r[i] = rh[keep[i]];
        for (int j = 0; j < nk; ++j)
            sub[i * nk + j] = nrm[keep[i] * nb + keep[j]];
    }
    sc_lsq_small_solve(sub, r, nk);
    for (int i = 0; i < nk; ++i)
        m[keep[i]] = r[i];
    return nk;
}
