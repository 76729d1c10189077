/* The narrow accessor the test references read a least-squares plan through (grid_lsq_internal.h,
 * "for the test references"; tests/unit/grid_lsq_reference.c): each uncertainty the plan computes
 * written as a quadratic form vᵀΣv of the pinned inverse Σ, with the plan's own value beside it,
 * and one solve with the plan's factor. The references' refined solves live in the tests. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "grid_lsq_internal.h"

void sc_grid_lsq_probe_get(const sc_grid_lsq_plan *q, sc_grid_lsq_probe *p)
{
    p->n_red = q->n_red, p->ng = q->ng, p->ns = q->ns, p->nm = q->nm, p->neq = q->neq;
    p->pinned = q->pinned;
}

int sc_grid_lsq_probe_solve(const sc_grid_lsq_plan *q, double *b)
{
    return sc_spsym_solve(q->f, b, 1);
}

int sc_grid_lsq_probe_node(const sc_grid_lsq_plan *q, int k, double *v, double *plan)
{
    int n = q->n_red, ng = q->ng, i = 2 * k;
    double *U = malloc(sizeof(double) * 4 * (size_t)ng), scale[4];
    if (!U || !q->sgx) {
        free(U);
        return -1;
    }
    sc_lsq_gauge_basis(q, U, scale);
    memset(v, 0, sizeof(double) * (size_t)n);
    v[i] = 1;
    for (int t = 0; t < 4; ++t)
        for (int j = 0; j < ng; ++j)
            v[j] -= U[(size_t)t * ng + i] * U[(size_t)t * ng + j];
    *plan = q->sgx[k];
    free(U);
    return 0;
}

int sc_grid_lsq_probe_equation(const sc_grid_lsq_plan *q, long e, double *v, double *c,
                               double *w, double *plan)
{
    if (!q->eq_h)
        return -1;
    /* ã = ρ_e − the group's mean row */
    int a = q->eq_a[e], idx[ROW_MAX];
    double val[ROW_MAX], W = 0;
    memset(v, 0, sizeof(double) * (size_t)q->n_red);
    for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t)
        W += q->eq_w[q->grp_eq[t]];
    for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t) {
        long e2 = q->grp_eq[t];
        int len = sc_lsq_eq_row(q, e2, idx, val);
        for (int k = 0; k < len; ++k)
            v[idx[k]] -= q->eq_w[e2] * val[k] / W;
    }
    int len = sc_lsq_eq_row(q, e, idx, val);
    for (int k = 0; k < len; ++k)
        v[idx[k]] += val[k];
    *c = q->eq_w[e] / W, *w = q->eq_w[e], *plan = q->eq_h[e];
    return 0;
}

int sc_grid_lsq_probe_misalignment(const sc_grid_lsq_plan *q, int t, double *v, double *c,
                                   double *plan)
{
    double Minv_T[49], gam[7];
    if (!q->var_m)
        return -1;
    *plan = q->var_m[t];
    if (!q->misalignment_estimable || q->view_free[t / q->nb] || sc_lsq_gauge_matrix(q, Minv_T))
        return 1;
    int n = q->n_red;
    double *fm = calloc((size_t)q->nm, sizeof(double)), *ux = malloc(sizeof(double) * (size_t)n);
    double *zero = calloc((size_t)n, sizeof(double));
    double *uA = malloc(sizeof(double) * 2 * (size_t)q->nn);
    int rc = fm && ux && zero && uA ? 0 : -1;
    if (rc == 0) { /* uᵀΣu = rᵀΣr + Σ_a u_A[a]²/W_a with r = u_x − a_correction(u_A) */
        fm[t] = 1;
        sc_lsq_functional_vectors(q, Minv_T, NULL, fm, ux, uA, gam);
        memcpy(v, ux, sizeof(double) * (size_t)n);
        sc_lsq_a_correction(q, uA, v);
        *c = sc_lsq_functional_form(q, ux, uA, zero, 1);
    }
    free(fm), free(ux), free(zero), free(uA);
    return rc;
}
