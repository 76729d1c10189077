/* Unit tests of the sparse LDLᵀ module behind the least-squares grid estimator: orderings are
 * permutations, solves and the Takahashi selected inverse match dense computations, and the
 * pivot-tolerance rank decision counts the nullity of semidefinite matrices. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../libselfcal/src/grid/sparse_ldl.h"
#include "selfcal/rng.h"

/* A random sparse matrix B (m x n, ~3 entries per row) and M = BᵀB (+ shift·I), dense. */
static double *random_gram(int m, int n, double shift, sc_rng *r)
{
    double *B = calloc((size_t)m * n, sizeof(double));
    for (int i = 0; i < m; ++i)
        for (int t = 0; t < 3; ++t)
            B[(size_t)i * n + (int)(sc_rng_uniform(r) * n)] += sc_rng_normal(r);
    double *M = calloc((size_t)n * n, sizeof(double));
    for (int i = 0; i < m; ++i)
        for (int a = 0; a < n; ++a)
            if (B[(size_t)i * n + a] != 0)
                for (int b = 0; b < n; ++b)
                    M[(size_t)a * n + b] += B[(size_t)i * n + a] * B[(size_t)i * n + b];
    for (int a = 0; a < n; ++a)
        M[(size_t)a * n + a] += shift;
    free(B);
    return M;
}

/* Graph (CSR, no diagonal) of a dense symmetric matrix's nonzeros. */
static void graph_of(const double *M, int n, long **ptr, int **idx)
{
    *ptr = calloc((size_t)n + 1, sizeof(long));
    *idx = malloc(sizeof(int) * (size_t)n * n + 1);
    long a = 0;
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j)
            if (j != i && M[(size_t)i * n + j] != 0)
                (*idx)[a++] = j;
        (*ptr)[i + 1] = a;
    }
}

/* Upper CSC of P M Pᵀ. */
static void permuted_upper(const double *M, int n, const int *perm, long **Ap, int **Ai,
                           double **Ax)
{
    *Ap = calloc((size_t)n + 1, sizeof(long));
    *Ai = malloc(sizeof(int) * (size_t)n * n + 1);
    *Ax = malloc(sizeof(double) * (size_t)n * n + 1);
    long a = 0;
    for (int k = 0; k < n; ++k) {
        for (int i = 0; i <= k; ++i) {
            double v = M[(size_t)perm[i] * n + perm[k]];
            if (v != 0 || i == k) {
                (*Ai)[a] = i;
                (*Ax)[a++] = v;
            }
        }
        (*Ap)[k + 1] = a;
    }
}

static void check_perm(const int *perm, int n)
{
    char *seen = calloc(n, 1);
    for (int k = 0; k < n; ++k) {
        assert_true(perm[k] >= 0 && perm[k] < n);
        assert_false(seen[perm[k]]);
        seen[perm[k]] = 1;
    }
    free(seen);
}

static void test_orders_solve_selinv(void **s)
{
    (void)s;
    sc_rng r;
    sc_rng_seed(&r, 31);
    const int n = 300;
    double *M = random_gram(400, n, 0.5, &r);
    long *ptr;
    int *idx;
    graph_of(M, n, &ptr, &idx);
    int *perm = malloc(sizeof(int) * n);
    for (int o = 0; o < 4; ++o) {
        int rc = o == 0   ? sc_nd_order(n, ptr, idx, perm, 16, 0)
                 : o == 1 ? sc_amd_order(n, ptr, idx, perm)
                 : o == 2 ? sc_nd_order(n, ptr, idx, perm, 64, 1)
                          : 0; /* o == 3: the identity order */
        if (o == 3)
            for (int k = 0; k < n; ++k)
                perm[k] = k;
        assert_int_equal(rc, 0);
        check_perm(perm, n);
        assert_true(sc_order_flops(n, ptr, idx, perm) > 0);
        long *Ap;
        int *Ai;
        double *Ax;
        permuted_upper(M, n, perm, &Ap, &Ai, &Ax);
        sc_ldl f;
        assert_int_equal(sc_ldl_factor(&f, n, Ap, Ai, Ax, 1e-10), 0);
        assert_int_equal(f.n_null, 0);
        assert_int_equal(sc_ldl_selinv(&f), 0);
        /* column k of the inverse by a solve; compare its diagonal and pattern entries */
        double *x = malloc(sizeof(double) * n), *y = malloc(sizeof(double) * n);
        double worst = 0;
        for (int k = 0; k < n; ++k) {
            memset(x, 0, sizeof(double) * n);
            x[k] = 1;
            sc_ldl_solve(&f, x);
            /* residual of the solve */
            sc_ldl_matvec(&f, x, y);
            for (int i = 0; i < n; ++i)
                assert_true(fabs(y[i] - (i == k)) < 1e-9);
            worst = fmax(worst, fabs(f.Zd[k] - x[k]) / fabs(x[k]));
            for (long p = f.Lp[k]; p < f.Lp[k + 1]; ++p)
                worst = fmax(worst, fabs(f.Zx[p] - x[f.Li[p]]) / fabs(x[k]));
        }
        assert_true(worst < 1e-10);
        free(x), free(y), free(Ap), free(Ai), free(Ax);
        sc_ldl_free(&f);
    }
    free(perm), free(ptr), free(idx), free(M);
}

/* Semidefinite: M = BᵀB with B of rank n - 5 (5 columns are combinations of others). */
static void test_rank_decision(void **s)
{
    (void)s;
    sc_rng r;
    sc_rng_seed(&r, 7);
    const int n = 120, m = 400;
    double *B = calloc((size_t)m * n, sizeof(double));
    for (int i = 0; i < m; ++i)
        for (int t = 0; t < 4; ++t)
            B[(size_t)i * n + (int)(sc_rng_uniform(&r) * (n - 5))] += sc_rng_normal(&r);
    /* the last 5 columns: each a combination of two earlier ones */
    for (int c = 0; c < 5; ++c)
        for (int i = 0; i < m; ++i)
            B[(size_t)i * n + n - 5 + c] = B[(size_t)i * n + 3 * c] - 2 * B[(size_t)i * n + 7 * c + 1];
    double *M = calloc((size_t)n * n, sizeof(double));
    for (int i = 0; i < m; ++i)
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b)
                M[(size_t)a * n + b] += B[(size_t)i * n + a] * B[(size_t)i * n + b];
    long *ptr;
    int *idx;
    graph_of(M, n, &ptr, &idx);
    int *perm = malloc(sizeof(int) * n);
    assert_int_equal(sc_amd_order(n, ptr, idx, perm), 0);
    long *Ap;
    int *Ai;
    double *Ax;
    permuted_upper(M, n, perm, &Ap, &Ai, &Ax);
    sc_ldl f;
    assert_int_equal(sc_ldl_factor(&f, n, Ap, Ai, Ax, 1e-10), 0);
    assert_int_equal(f.n_null, 5);
    assert_true(f.max_null_ratio < 1e-13);
    assert_true(f.min_kept_ratio > 1e-6);
    /* a consistent right-hand side b = M x0 is solved (residual small) */
    double *x0 = malloc(sizeof(double) * n), *b = malloc(sizeof(double) * n);
    double *y = malloc(sizeof(double) * n);
    for (int i = 0; i < n; ++i)
        x0[i] = sc_rng_normal(&r);
    sc_ldl_matvec(&f, x0, b);
    memcpy(y, b, sizeof(double) * n);
    sc_ldl_solve(&f, y);
    double *mb = malloc(sizeof(double) * n);
    sc_ldl_matvec(&f, y, mb);
    for (int i = 0; i < n; ++i)
        assert_true(fabs(mb[i] - b[i]) < 1e-8 * (1 + fabs(b[i])));
    sc_ldl_free(&f);
    /* a tolerance above the kept pivots declares more null pivots: the decision is the tolerance's */
    assert_int_equal(sc_ldl_factor(&f, n, Ap, Ai, Ax, 0.99), 0);
    assert_true(f.n_null > 5);
    sc_ldl_free(&f);
    free(x0), free(b), free(y), free(mb), free(Ap), free(Ai), free(Ax), free(perm), free(ptr);
    free(idx), free(M), free(B);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_orders_solve_selinv),
        cmocka_unit_test(test_rank_decision),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
