/* profile_lsq_dense.h — dense O(N³) reference for the two-set two-point least squares (tests and
 * benchmarks only; LAPACKE). Independent of the fast banded solver in libselfcal. */
#ifndef SELFCAL_TEST_PROFILE_LSQ_DENSE_H
#define SELFCAL_TEST_PROFILE_LSQ_DENSE_H

/* Solve the weighted least-squares problem y_k(j) = f(j+d_k) - f(j) + c_k (k = 1, 2) with the
 * gauge Σf = 0, Σ n·f = 0 by the dense bordered (KKT) system [AᵀWA Qᵀ; Q 0] (LAPACK dsytrf/dsytrs);
 * uf (may be NULL): sqrt of the diagonal of the covariance, the top-left block of the inverse of
 * the KKT matrix (dsytri). f: n values, c: 2 values (may be NULL). Returns 0 on success. */
int sc_profile_lsq_dense_solve(int n, int d1, int d2, double w1, double w2, const double *y1,
                               const double *y2, double *f, double *c, double *uf);

/* Numerical rank of the unweighted design matrix (2N-d1-d2 rows, N+2 columns: f, c1, c2) by SVD;
 * the problem is solvable exactly when it is N (the 2-dimensional gauge: constant and line). */
int sc_profile_lsq_dense_rank(int n, int d1, int d2);

#endif
