/* selfcal/profile_lsq.h — the two-set two-point straightness method by least squares (Ding §2.3),
 * solved in O(N·d2²) time and O(N·d2) memory (banded normal matrix plus a few border rows), with
 * every point's standard uncertainty at the same order of cost.
 *
 * Data: y_k(n) = f(n + d_k) - f(n) + c_k for n = 0..N-d_k-1, k = 1, 2, in µm. Unknowns: f(0..N-1)
 * relative to its least-squares line, c1, c2. Scan k is weighted by w_k (1/variance of y_k).
 * Plan object in the manner of FFTW: create for (N, d1, d2, w1, w2), solve many data sets.
 */
#ifndef SELFCAL_PROFILE_LSQ_H
#define SELFCAL_PROFILE_LSQ_H

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_profile_lsq sc_profile_lsq;

/* 1 if (n, d1, d2) can be solved by least squares, else 0 and a reason in err. */
int sc_profile_lsq_solvable(int n, int d1, int d2, sc_error *err);

/* Factor the problem. w1, w2 > 0: weights of scans 1 and 2 (1/µm²); only their ratio changes f. */
sc_status sc_profile_lsq_create(int n, int d1, int d2, double w1, double w2, sc_profile_lsq **out,
                                sc_error *err);

/* Solve: y1 (n-d1 values), y2 (n-d2 values) in µm -> f (n values, µm, relative to its LS line),
 * c (2 values, µm; may be NULL), weighted residual sum of squares (may be NULL). */
sc_status sc_profile_lsq_solve(const sc_profile_lsq *p, const double *y1_um, const double *y2_um,
                               double *f_um, double *c_um, double *wrss, sc_error *err);

/* Standard uncertainty of every f(n) (n values, µm) given the weights the plan was made with
 * (weights = 1/σ² of y_k in 1/µm²), i.e. sqrt of the diagonal of the estimator covariance. */
sc_status sc_profile_lsq_uncertainty(const sc_profile_lsq *p, double *uf_um, sc_error *err);

/* Free the plan (NULL is fine). */
void sc_profile_lsq_destroy(sc_profile_lsq *p);

#ifdef __cplusplus
}
#endif
#endif
