/* Scalar sparse LDLᵀ with pivot-tolerance rank decisions and the Takahashi selected inverse: the
 * rank-revealing path of sparse_sym.c for numerically singular matrices, which CHOLMOD's
 * Cholesky cannot factor (plans that do not identify G). See sparse_ldl.h, docs/grid-lsq.md. */
#include "sparse_ldl.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- factorization */

void sc_ldl_free(sc_ldl *f)
{
    if (!f)
        return;
    free(f->parent), free(f->Lp), free(f->Li), free(f->Lx), free(f->D), free(f->Zx), free(f->Zd);
    memset(f, 0, sizeof *f);
}

/* Symbolic: elimination tree and column counts (lnz), f->Lp and the flop count. */
static void ldl_symbolic(sc_ldl *f, int *flag, long *lnz)
{
    int n = f->n;
    for (int k = 0; k < n; ++k) {
        f->parent[k] = -1;
        flag[k] = k;
        lnz[k] = 0;
        for (long p = f->Ap[k]; p < f->Ap[k + 1]; ++p) {
            int i = f->Ai[p];
            if (i >= k)
                continue;
            for (; flag[i] != k; i = f->parent[i]) {
                if (f->parent[i] == -1)
                    f->parent[i] = k;
                lnz[i]++;
                flag[i] = k;
            }
        }
    }
    f->Lp[0] = 0;
    for (int k = 0; k < n; ++k) {
        f->Lp[k + 1] = f->Lp[k] + lnz[k];
        f->flops += (double)lnz[k] * (double)lnz[k];
    }
}

/* Row k of L (a sparse triangular solve on the reach of the elimination tree) and the pivot
 * d_k; returns d_k, akk: A_kk. */
static double ldl_row(sc_ldl *f, int k, int *flag, long *lnz, int *pattern, double *y, double *akk)
{
    int n = f->n, top = n;
    *akk = 0;
    y[k] = 0;
    flag[k] = k;
    lnz[k] = 0;
    for (long p = f->Ap[k]; p < f->Ap[k + 1]; ++p) {
        int i = f->Ai[p];
        if (i > k)
            continue;
        y[i] += f->Ax[p];
        if (i == k)
            *akk += f->Ax[p];
        int len = 0;
        for (; flag[i] != k; i = f->parent[i]) {
            pattern[len++] = i;
            flag[i] = k;
        }
        while (len > 0)
            pattern[--top] = pattern[--len];
    }
    double dk = y[k];
    y[k] = 0;
    for (; top < n; ++top) {
        int i = pattern[top];
        double yi = y[i];
        y[i] = 0;
        long p2 = f->Lp[i] + lnz[i], p;
        for (p = f->Lp[i]; p < p2; ++p)
            y[f->Li[p]] -= f->Lx[p] * yi;
        double lki = f->D[i] != 0 ? yi / f->D[i] : 0.0;
        dk -= lki * yi;
        f->Li[p] = k;
        f->Lx[p] = lki;
        lnz[i]++;
    }
    return dk;
}

int sc_ldl_factor(sc_ldl *f, int n, const long *Ap, const int *Ai, const double *Ax, double tol)
{
    memset(f, 0, sizeof *f);
    f->n = n;
    f->Ap = Ap;
    f->Ai = Ai;
    f->Ax = Ax;
    f->parent = malloc(sizeof(int) * (size_t)(n + 1));
    f->Lp = malloc(sizeof(long) * (size_t)(n + 1));
    f->D = malloc(sizeof(double) * (size_t)(n + 1));
    int *flag = malloc(sizeof(int) * (size_t)(n + 1));
    long *lnz = malloc(sizeof(long) * (size_t)(n + 1));
    int *pattern = malloc(sizeof(int) * (size_t)(n + 1));
    double *y = calloc((size_t)n + 1, sizeof(double));
    if (!f->parent || !f->Lp || !f->D || !flag || !lnz || !pattern || !y)
        goto nomem;
    ldl_symbolic(f, flag, lnz);
    long nz = f->Lp[n];
    f->Li = malloc(sizeof(int) * (size_t)(nz + 1));
    f->Lx = malloc(sizeof(double) * (size_t)(nz + 1));
    if (!f->Li || !f->Lx)
        goto nomem;
    f->bytes = (size_t)nz * (sizeof(int) + sizeof(double)) +
               (size_t)(n + 1) * (sizeof(int) + sizeof(long) + sizeof(double));
    /* numeric, up-looking, with the rank decisions */
    f->min_kept_ratio = INFINITY;
    f->max_null_ratio = 0;
    for (int k = 0; k < n; ++k) {
        double akk, dk = ldl_row(f, k, flag, lnz, pattern, y, &akk);
        double ratio = akk > 0 ? dk / akk : 0.0;
        if (!(akk > 0) || !(ratio > tol)) {
            f->D[k] = 0;
            f->n_null++;
            if (ratio > f->max_null_ratio)
                f->max_null_ratio = ratio;
        } else {
            f->D[k] = dk;
            if (ratio < f->min_kept_ratio)
                f->min_kept_ratio = ratio;
        }
    }
    free(flag), free(lnz), free(pattern), free(y);
    return 0;
nomem:
    free(flag), free(lnz), free(pattern), free(y);
    sc_ldl_free(f);
    return -1;
}

void sc_ldl_solve(const sc_ldl *f, double *x)
{
    int n = f->n;
    for (int j = 0; j < n; ++j) {
        double xj = x[j];
        if (xj != 0)
            for (long p = f->Lp[j]; p < f->Lp[j + 1]; ++p)
                x[f->Li[p]] -= f->Lx[p] * xj;
    }
    for (int j = 0; j < n; ++j)
        x[j] = f->D[j] != 0 ? x[j] / f->D[j] : 0.0;
    for (int j = n - 1; j >= 0; --j) {
        double s = x[j];
        for (long p = f->Lp[j]; p < f->Lp[j + 1]; ++p)
            s -= f->Lx[p] * x[f->Li[p]];
        x[j] = f->D[j] != 0 ? s : 0.0;
    }
}

void sc_ldl_matvec(const sc_ldl *f, const double *x, double *y)
{
    int n = f->n;
    for (int j = 0; j < n; ++j)
        y[j] = 0;
    for (int j = 0; j < n; ++j)
        for (long p = f->Ap[j]; p < f->Ap[j + 1]; ++p) {
            int i = f->Ai[p];
            if (i > j)
                continue;
            y[i] += f->Ax[p] * x[j];
            if (i != j)
                y[j] += f->Ax[p] * x[i];
        }
}

/* Takahashi: Z = D⁻¹L⁻¹ + (I - Lᵀ)Z gives, column by column from the last,
 * Z_ij = -Σ_{k∈S_j} Z_ik L_kj (i ∈ S_j) and Z_jj = 1/d_j - Σ_{k∈S_j} L_kj Z_kj, with S_j the
 * pattern of column j of L. S_j ∪ {j} is a clique of the filled graph and, for i ∈ S_j, every
 * k ∈ S_j with k > i lies in S_i, so all Z_ik needed are on L's pattern. */
int sc_ldl_selinv(sc_ldl *f)
{
    int n = f->n;
    long nz = f->Lp[n];
    free(f->Zx), free(f->Zd);
    f->Zx = malloc(sizeof(double) * (size_t)(nz + 1));
    f->Zd = malloc(sizeof(double) * (size_t)(n + 1));
    double *acc = calloc((size_t)n + 1, sizeof(double));
    double *wl = calloc((size_t)n + 1, sizeof(double));
    if (!f->Zx || !f->Zd || !acc || !wl) {
        free(acc), free(wl);
        free(f->Zx), free(f->Zd);
        f->Zx = f->Zd = NULL;
        return -1;
    }
    f->bytes += (size_t)nz * sizeof(double) + (size_t)(n + 1) * sizeof(double);
    /* wl holds column j of L scattered (zero elsewhere), so the inner loop needs no test:
     * acc[r] for rows r outside S_j collects garbage that is never read (acc[i], i ∈ S_j, is
     * cleared first). */
    for (int j = n - 1; j >= 0; --j) {
        long p0 = f->Lp[j], p1 = f->Lp[j + 1];
        double dinv = f->D[j] != 0 ? 1.0 / f->D[j] : 0.0;
        for (long p = p0; p < p1; ++p) {
            int k = f->Li[p];
            wl[k] = f->Lx[p];
            acc[k] = 0;
        }
        for (long p = p0; p < p1; ++p) {
            int k = f->Li[p];
            double lkj = f->Lx[p], sk = f->Zd[k] * lkj;
            long q0 = f->Lp[k], q1 = f->Lp[k + 1];
            const int *ri = f->Li;
            const double *zx = f->Zx;
            f->selinv_work += (double)(q1 - q0);
            for (long q = q0; q < q1; ++q) {
                int r = ri[q];
                double z = zx[q]; /* Z_rk, r > k */
                acc[r] += z * lkj;
                sk += z * wl[r];
            }
            acc[k] += sk;
        }
        double zjj = dinv;
        for (long p = p0; p < p1; ++p) {
            int i = f->Li[p];
            f->Zx[p] = -acc[i];
            zjj += f->Lx[p] * acc[i];
            wl[i] = 0;
        }
        f->Zd[j] = f->D[j] != 0 ? zjj : 0.0;
        if (f->D[j] == 0)
            for (long p = p0; p < p1; ++p)
                f->Zx[p] = 0;
    }
    free(acc), free(wl);
    return 0;
}
