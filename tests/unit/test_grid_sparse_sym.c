/* Unit tests of the symmetric sparse solver behind the least-squares grid estimator
 * (libselfcal/src/linalg/sparse_sym.h): solves and the selected inverse match dense computations
 * (with and without dense border columns, as the misalignments make), and the pivot-tolerance
 * rank decision counts the nullity of semidefinite matrices. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../libselfcal/src/linalg/sparse_sym.h"
#include "selfcal/rng.h"

/* B (m x n): ~per_row random entries per row among the first n - border columns, plus every
 * row touching the last `border` columns (dense columns). M = BᵀB (+ shift·I), dense. */
static double *random_gram(int m, int n, int per_row, int border, double shift, sc_rng *r)
{
    double *B = calloc((size_t)m * n, sizeof(double));
    for (int i = 0; i < m; ++i) {
        for (int t = 0; t < per_row; ++t)
            B[(size_t)i * n + (int)(sc_rng_uniform(r) * (n - border))] += sc_rng_normal(r);
        for (int c = 0; c < border; ++c)
            B[(size_t)i * n + n - border + c] = 0.1 * sc_rng_normal(r);
    }
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

/* Upper CSC of M (diagonal always stored). */
static void upper_csc(const double *M, int n, long **Ap, int **Ai, double **Ax)
{
    *Ap = calloc((size_t)n + 1, sizeof(long));
    *Ai = malloc(sizeof(int) * (size_t)n * n + 1);
    *Ax = malloc(sizeof(double) * (size_t)n * n + 1);
    long a = 0;
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i <= j; ++i) {
            double v = M[(size_t)i * n + j];
            if (v != 0 || i == j) {
                (*Ai)[a] = i;
                (*Ax)[a++] = v;
            }
        }
        (*Ap)[j + 1] = a;
    }
}

static void check_solve_selinv(int n, int m, int per_row, int border, unsigned seed)
{
    sc_rng r;
    sc_rng_seed(&r, seed);
    double *M = random_gram(m, n, per_row, border, 0.5, &r);
    long *Ap;
    int *Ai;
    double *Ax;
    upper_csc(M, n, &Ap, &Ai, &Ax);
    sc_spsym *f = NULL;
    assert_int_equal(sc_spsym_analyze(n, Ap, Ai, NULL, &f), 0);
    assert_int_equal(sc_spsym_factor(f, Ax, 1e-10), 0);
    assert_int_equal(sc_spsym_nullity(f), 0);
    assert_true(isnan(sc_spsym_inv(f, 0, 0))); /* not computed yet */
    assert_int_equal(sc_spsym_selinv(f, -1, NULL, 0), 0);
    /* column k of the inverse by a solve; compare its diagonal and the pattern entries */
    double *x = malloc(sizeof(double) * n), *y = malloc(sizeof(double) * n);
    double worst = 0;
    long checked = 0;
    for (int k = 0; k < n; ++k) {
        memset(x, 0, sizeof(double) * n);
        x[k] = 1;
        assert_int_equal(sc_spsym_solve(f, x, 1), 0);
        sc_spsym_matvec(f, x, y, 1);
        for (int i = 0; i < n; ++i)
            assert_true(fabs(y[i] - (i == k)) < 1e-9);
        worst = fmax(worst, fabs(sc_spsym_inv(f, k, k) - x[k]) / fabs(x[k]));
        for (int i = 0; i < n; ++i)
            if (M[(size_t)i * n + k] != 0) {
                double z = sc_spsym_inv(f, i, k);
                assert_false(isnan(z));
                assert_true(z == sc_spsym_inv(f, k, i));
                worst = fmax(worst, fabs(z - x[i]) / sqrt(fabs(x[k]) * fabs(sc_spsym_inv(f, i, i))));
                checked++;
            }
    }
    assert_true(checked >= n);
    assert_true(worst < 1e-10);
    /* a blocked solve of several right-hand sides gives what single solves give */
    int nb = n < 5 ? n : 5;
    double *X = calloc((size_t)n * nb, sizeof(double)), *Y = malloc(sizeof(double) * n * nb);
    for (int c = 0; c < nb; ++c)
        X[(size_t)c * n + c] = 1, X[(size_t)c * n + (n - 1 - c)] += 0.5;
    assert_int_equal(sc_spsym_solve(f, X, nb), 0);
    sc_spsym_matvec(f, X, Y, nb);
    for (int c = 0; c < nb; ++c) {
        memset(x, 0, sizeof(double) * n);
        x[c] = 1, x[n - 1 - c] += 0.5;
        for (int i = 0; i < n; ++i)
            assert_true(fabs(Y[(size_t)c * n + i] - x[i]) < 1e-9);
        assert_int_equal(sc_spsym_solve(f, x, 1), 0);
        for (int i = 0; i < n; ++i)
            assert_true(fabs(X[(size_t)c * n + i] - x[i]) <= 1e-10 * (1 + fabs(x[i])));
    }
    free(X), free(Y);
    sc_spsym_stats st;
    sc_spsym_get_stats(f, &st);
    assert_true(n == 1 || (st.nnz_factor > 0 && st.factor_flops > 0 && st.selinv_work > 0));
    assert_true(st.bytes > 0);
    assert_int_equal(st.n_null, 0);
    assert_true(st.min_kept_ratio > 0 && st.max_null_ratio == 0);
    assert_non_null(sc_spsym_ordering_name(st.ordering));
    free(x), free(y), free(Ap), free(Ai), free(Ax), free(M);
    sc_spsym_destroy(f);
}

static void test_solve_selinv(void **s)
{
    (void)s;
    check_solve_selinv(300, 400, 3, 0, 31);
    check_solve_selinv(400, 900, 4, 9, 32); /* dense border columns */
    check_solve_selinv(1, 1, 1, 0, 33);
}

/* Whole columns of the inverse from the selected inverse: for the border unknowns a hint orders
 * last (within the recurrences), and for unknowns anywhere else (by solves); both against
 * single solves. A grouped hint (pairs) gives the same solutions as CHOLMOD's own order. */
static void check_tracked_columns(int n, int border, int group, unsigned seed)
{
    sc_rng r;
    sc_rng_seed(&r, seed);
    double *M = random_gram(2 * n, n, 3, border, 0.5, &r);
    long *Ap;
    int *Ai;
    double *Ax;
    upper_csc(M, n, &Ap, &Ai, &Ax);
    int last[16], other[3] = {0, n / 2, n - border - 1};
    for (int t = 0; t < border; ++t)
        last[t] = n - 1 - t; /* in reverse: the caller's order is not the pivots' order */
    int n_grouped = (n - border) / group * group;
    sc_spsym_hint hint = {group, n_grouped, last, border};
    double *x = malloc(sizeof(double) * n), *x0 = malloc(sizeof(double) * n);
    double *col = malloc(sizeof(double) * n);
    for (int pass = 0; pass < 2; ++pass) {
        sc_spsym *f = NULL, *f0 = NULL;
        assert_int_equal(sc_spsym_analyze(n, Ap, Ai, &hint, &f), 0);
        assert_int_equal(sc_spsym_factor(f, Ax, 1e-10), 0);
        assert_int_equal(sc_spsym_analyze(n, Ap, Ai, NULL, &f0), 0);
        assert_int_equal(sc_spsym_factor(f0, Ax, 1e-10), 0);
        sc_spsym_stats st;
        sc_spsym_get_stats(f, &st);
        assert_int_equal(st.ordering, SC_SPSYM_ORDER_HINTED_AMD);
        assert_string_equal(sc_spsym_ordering_name(st.ordering),
                            "AMD, given unknowns last (CHOLMOD)");
        const int *cols = pass == 0 ? last : other;
        int nc = pass == 0 ? border : 3;
        assert_int_equal(sc_spsym_inv_column(f, 0, col), -1); /* not computed yet */
        assert_int_equal(sc_spsym_selinv(f, -1, cols, nc), 0);
        sc_spsym_get_stats(f, &st);
        assert_int_equal(st.tracked_by_solves, pass); /* the last pivots: in the recurrences */
        double worst = 0;
        for (int t = 0; t < nc; ++t) {
            memset(x, 0, sizeof(double) * n);
            x[cols[t]] = 1;
            memcpy(x0, x, sizeof(double) * n);
            assert_int_equal(sc_spsym_solve(f, x, 1), 0);
            assert_int_equal(sc_spsym_solve(f0, x0, 1), 0);
            assert_int_equal(sc_spsym_inv_column(f, t, col), 0);
            for (int i = 0; i < n; ++i) {
                double z = col[i], scale = fabs(x[cols[t]]);
                worst = fmax(worst, fabs(z - x[i]) / scale);
                worst = fmax(worst, fabs(x0[i] - x[i]) / scale);
            }
            /* on the pattern, the two parts of the selected inverse agree */
            assert_true(fabs(sc_spsym_inv(f, cols[t], cols[t]) - col[cols[t]]) <=
                        1e-12 * fabs(x[cols[t]]));
        }
        assert_true(worst < 1e-10);
        double row[16];
        for (int t = 0; t < nc; ++t) { /* whole columns against their rows, entry by entry */
            assert_int_equal(sc_spsym_inv_column(f, t, col), 0);
            for (int i = 0; i < n; ++i) {
                sc_spsym_inv_cols_at(f, i, row);
                assert_true(col[i] == row[t]);
            }
        }
        assert_int_equal(sc_spsym_inv_column(f, nc, col), -1);
        sc_spsym_drop_inverse(f);
        assert_int_equal(sc_spsym_inv_column(f, 0, col), -1);
        sc_spsym_inv_cols_at(f, 0, row);
        assert_true(isnan(row[0]));
        sc_spsym_destroy(f);
        sc_spsym_destroy(f0);
    }
    /* a reserved workspace serves solves of that many columns without being made anew */
    {
        sc_spsym *f = NULL;
        assert_int_equal(sc_spsym_analyze(n, Ap, Ai, &hint, &f), 0);
        assert_int_equal(sc_spsym_factor(f, Ax, 1e-10), 0);
        sc_spsym_stats st;
        assert_int_equal(sc_spsym_reserve_solve(f, 1), 0);
        memset(x, 0, sizeof(double) * n);
        x[0] = 1;
        assert_int_equal(sc_spsym_solve(f, x, 1), 0);
        sc_spsym_get_stats(f, &st);
        assert_int_equal(st.workspace_made, 0);
        double *X3 = calloc((size_t)n * 3, sizeof(double));
        assert_int_equal(sc_spsym_solve(f, X3, 3), 0); /* another shape: made anew */
        sc_spsym_get_stats(f, &st);
        assert_int_equal(st.workspace_made, 1);
        free(X3);
        sc_spsym_destroy(f);
    }
    /* a bad hint (an unknown twice) is refused */
    int twice[2] = {n - 1, n - 1};
    sc_spsym_hint bad = {1, 0, twice, 2};
    sc_spsym *f = NULL;
    assert_int_equal(sc_spsym_analyze(n, Ap, Ai, &bad, &f), -1);
    assert_null(f);
    free(x), free(x0), free(col), free(Ap), free(Ai), free(Ax), free(M);
}

static void test_tracked_columns(void **s)
{
    (void)s;
    check_tracked_columns(300, 9, 1, 41);
    check_tracked_columns(400, 12, 2, 42);
    check_tracked_columns(60, 1, 2, 43);
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
    for (int c = 0; c < 5; ++c)
        for (int i = 0; i < m; ++i)
            B[(size_t)i * n + n - 5 + c] = B[(size_t)i * n + 3 * c] - 2 * B[(size_t)i * n + 7 * c + 1];
    double *M = calloc((size_t)n * n, sizeof(double));
    for (int i = 0; i < m; ++i)
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b)
                M[(size_t)a * n + b] += B[(size_t)i * n + a] * B[(size_t)i * n + b];
    long *Ap;
    int *Ai;
    double *Ax;
    upper_csc(M, n, &Ap, &Ai, &Ax);
    sc_spsym *f = NULL;
    assert_int_equal(sc_spsym_analyze(n, Ap, Ai, NULL, &f), 0);
    assert_int_equal(sc_spsym_factor(f, Ax, 1e-10), 0);
    assert_int_equal(sc_spsym_nullity(f), 5);
    sc_spsym_stats st;
    sc_spsym_get_stats(f, &st);
    assert_true(st.max_null_ratio < 1e-13);
    assert_true(st.min_kept_ratio > 1e-6);
    /* a consistent right-hand side b = M x0 is solved (residual small) */
    double *x0 = malloc(sizeof(double) * n), *b = malloc(sizeof(double) * n);
    double *y = malloc(sizeof(double) * n), *mb = malloc(sizeof(double) * n);
    for (int i = 0; i < n; ++i)
        x0[i] = sc_rng_normal(&r);
    sc_spsym_matvec(f, x0, b, 1);
    memcpy(y, b, sizeof(double) * n);
    assert_int_equal(sc_spsym_solve(f, y, 1), 0);
    sc_spsym_matvec(f, y, mb, 1);
    for (int i = 0; i < n; ++i)
        assert_true(fabs(mb[i] - b[i]) < 1e-8 * (1 + fabs(b[i])));
    /* refactoring with a tolerance above the kept pivots declares more null pivots */
    assert_int_equal(sc_spsym_factor(f, Ax, 0.99), 0);
    assert_true(sc_spsym_nullity(f) > 5);
    /* and back: the same analysis serves a new factorization */
    assert_int_equal(sc_spsym_factor(f, Ax, 1e-10), 0);
    assert_int_equal(sc_spsym_nullity(f), 5);
    sc_spsym_destroy(f);
    free(x0), free(b), free(y), free(mb), free(Ap), free(Ai), free(Ax), free(M), free(B);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_solve_selinv),
        cmocka_unit_test(test_rank_decision),
        cmocka_unit_test(test_tracked_columns),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
