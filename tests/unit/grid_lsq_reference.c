/* Reference values for the accuracy tests of the least-squares grid estimator
 * (grid_lsq_reference.h): column solves refined against residuals in long double until they stop
 * changing, independent of the selected inverse. A test helper, moved out of the library: it
 * reads the plan through the estimator's internal header (grid_lsq_internal.h). */
#include "grid_lsq_reference.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../libselfcal/src/grid/grid_lsq_internal.h"


/* y = S x (the pinned matrix), in long double. */
static void matvec_long(const sc_grid_lsq_plan *q, const long double *x, long double *y)
{
    for (int i = 0; i < q->n_red; ++i)
        y[i] = 0;
    for (int j = 0; j < q->n_red; ++j)
        for (long p = q->Ap[j]; p < q->Ap[j + 1]; ++p) {
            int i = q->Ai[p];
            y[i] += (long double)q->Ax[p] * x[j];
            if (i != j)
                y[j] += (long double)q->Ax[p] * x[i];
        }
}

/* vᵀ Σ v (Σ the pinned inverse, 0 on pins) by a refined solve; -1 if memory ran out. */
static double exact_quad(const sc_grid_lsq_plan *q, const double *v, double *b, long double *x,
                         long double *r)
{
    int n = q->n_red;
    for (int i = 0; i < n; ++i)
        b[i] = q->pinned[i] ? 0.0 : v[i];
    for (int i = 0; i < n; ++i)
        x[i] = 0;
    for (int it = 0; it < 6; ++it) {
        matvec_long(q, x, r);
        for (int i = 0; i < n; ++i)
            b[i] = q->pinned[i] ? 0.0 : (double)((long double)v[i] - r[i]);
        if (sc_spsym_solve(q->f, b, 1) != 0)
            return -1;
        for (int i = 0; i < n; ++i)
            x[i] += q->pinned[i] ? 0.0L : (long double)b[i];
    }
    long double s = 0;
    for (int i = 0; i < n; ++i)
        s += q->pinned[i] ? 0.0L : (long double)v[i] * x[i];
    return (double)s;
}

/* Var/σ0² of every misalignment unknown by refined solves into var (NaN where the plan has
 * none): uᵀΣu = rᵀΣr + Σ_a u_A[a]²/W_a with r = u_x − sc_lsq_a_correction(u_A). */
static int reference_misalignments(const sc_grid_lsq_plan *q, double *var, double *b,
                                   long double *x, long double *r)
{
    double Minv_T[49], gam[7];
    int n = q->n_red;
    for (int t = 0; t < q->nm; ++t)
        var[t] = NAN;
    if (!q->misalignment_estimable || sc_lsq_gauge_matrix(q, Minv_T) != 0)
        return 0;
    double *fm = calloc((size_t)q->nm, sizeof(double)), *ux = malloc(sizeof(double) * (size_t)n);
    double *rv = malloc(sizeof(double) * (size_t)n), *zero = calloc((size_t)n, sizeof(double));
    double *uA = malloc(sizeof(double) * 2 * (size_t)q->nn);
    int rc = fm && ux && rv && zero && uA ? 0 : -1;
    for (int t = 0; rc == 0 && t < q->nm; ++t) {
        memset(fm, 0, sizeof(double) * (size_t)q->nm);
        fm[t] = 1;
        sc_lsq_functional_vectors(q, Minv_T, NULL, fm, ux, uA, gam);
        memcpy(rv, ux, sizeof(double) * (size_t)n);
        sc_lsq_a_correction(q, uA, rv);
        double quad = exact_quad(q, rv, b, x, r);
        if (quad < 0)
            rc = -1;
        var[t] = quad + sc_lsq_functional_form(q, ux, uA, zero, 1);
    }
    free(fm), free(ux), free(rv), free(zero), free(uA);
    return rc;
}

int sc_grid_lsq_reference_misalignments(const sc_grid_lsq_plan *q, double *var_ref,
                                        double *var_plan)
{
    int n = q->n_red;
    double *b = malloc(sizeof(double) * (size_t)n);
    long double *x = malloc(sizeof(long double) * (size_t)n);
    long double *r = malloc(sizeof(long double) * (size_t)n);
    int rc = b && x && r && q->var_m ? reference_misalignments(q, var_ref, b, x, r) : -1;
    for (int t = 0; rc == 0 && t < q->nm; ++t) {
        var_plan[t] = q->var_m[t];
        if (q->view_free[t / q->nb])
            var_ref[t] = NAN;
    }
    free(b), free(x), free(r);
    return rc;
}

int sc_grid_lsq_reference(const sc_grid_lsq_plan *q, int nsample, int *node, double *sx_ref,
                          double *sx_plan, long *eq, double *h_ref, double *h_plan)
{
    int n = q->n_red, ng = q->ng;
    double *v = calloc((size_t)n, sizeof(double)), *b = malloc(sizeof(double) * (size_t)n);
    double *U = malloc(sizeof(double) * 4 * (size_t)ng), scale[4];
    long double *x = malloc(sizeof(long double) * (size_t)n);
    long double *r = malloc(sizeof(long double) * (size_t)n);
    int rc = -1;
    if (!v || !b || !U || !x || !r || !q->sgx || !q->eq_h)
        goto out;
    sc_lsq_gauge_basis(q, U, scale);
    for (int s = 0; s < nsample; ++s) {
        /* σ_x of a node: (P⊥e)ᵀ Σ (P⊥e) */
        int k = (int)((long)s * q->ns / nsample), i = 2 * k;
        memset(v, 0, sizeof(double) * (size_t)n);
        v[i] = 1;
        for (int t = 0; t < 4; ++t)
            for (int j = 0; j < ng; ++j)
                v[j] -= U[(size_t)t * ng + i] * U[(size_t)t * ng + j];
        double var = exact_quad(q, v, b, x, r);
        node[s] = k;
        sx_ref[s] = sqrt(var > 0 ? var : 0);
        sx_plan[s] = q->sgx[k];
        /* the leverage of an equation: w_e/W_a + w_e ãᵀΣã, ã = ρ_e − the group's mean row */
        long e = (long)((double)s * q->neq / nsample);
        int a = q->eq_a[e], idx[ROW_MAX];
        double val[ROW_MAX], W = 0;
        memset(v, 0, sizeof(double) * (size_t)n);
        for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t)
            W += q->eq_w[q->grp_eq[t]];
        for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t) {
            long e2 = q->grp_eq[t];
            int len = sc_lsq_eq_row(q, e2, idx, val);
            for (int c = 0; c < len; ++c)
                v[idx[c]] -= q->eq_w[e2] * val[c] / W;
        }
        int len = sc_lsq_eq_row(q, e, idx, val);
        for (int c = 0; c < len; ++c)
            v[idx[c]] += val[c];
        eq[s] = e;
        h_ref[s] = q->eq_w[e] / W + q->eq_w[e] * exact_quad(q, v, b, x, r);
        h_plan[s] = q->eq_h[e];
    }
    rc = 0;
out:
    free(v), free(b), free(U), free(x), free(r);
    return rc;
}
