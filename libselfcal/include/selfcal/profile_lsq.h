/* selfcal/profile_lsq.h — the two-set two-point straightness method by least squares (Ding §2.3),
 * solved in O(N·d2²) time and O(N·d2) memory (banded normal matrix plus a few border rows), with
 * every point's standard uncertainty at the same order of cost.
 *
 * Data: y_k(n) = f(n + d_k) - f(n) + c_k for n = 0..N-d_k-1, k = 1, 2, in µm. Unknowns: f(0..N-1)
 * relative to its least-squares line, c1, c2. Scan k is weighted by w_k (1/variance of y_k).
 * Plan object in the manner of FFTW: sc_profile_lsq_plan_create for (N, d1, d2, w1, w2) factors
 * once; sc_profile_lsq_execute then solves any number of data sets without allocating. Execute
 * and uncertainty take a const plan: concurrent calls on one plan are fine.
 */
#ifndef SELFCAL_PROFILE_LSQ_H
#define SELFCAL_PROFILE_LSQ_H

#include <stdbool.h>
#include <stddef.h>

#include "selfcal/api.h"

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_profile_lsq_plan sc_profile_lsq_plan;

/* Can (n, d1, d2) be solved by least squares? If not, false and the reason in err (SC_E_INPUT).
 * Exact condition (docs/profile-lsq.md): d1, d2 >= 1, gcd(d1, d2) = 1 and N >= d1 + d2 (at
 * N = d1 + d2 the fit is exactly determined: no redundancy, wrss = 0). d = 1 is allowed. */
SC_API bool sc_profile_lsq_is_solvable(int n, int d1, int d2, sc_error *err);

/* Factor the problem in O(N·d²) time, O(N·d) memory (d = max(d1, d2); 8·N·(d+1) bytes for the
 * factor). w1, w2 > 0: weights of scans 1 and 2 (1/µm²); only their ratio changes f.
 * Tuning (threads, huge pages) is not part of the API: environment variables
 * SELFCAL_PROFILE_LSQ_ONE_THREAD=1 (no helper thread) and SELFCAL_PROFILE_LSQ_HUGE_PAGES=1
 * (factor in transparent huge pages), read at create; docs/profile-lsq.md. Results are identical. */
SC_API sc_status sc_profile_lsq_plan_create(int n, int d1, int d2, double w1, double w2,
                                            sc_profile_lsq_plan **out, sc_error *err);

/* Degrees of freedom of the fit, N - d1 - d2 (observations minus determined unknowns): divide the
 * weighted residual sum of squares by it to estimate the noise scale (0: no estimate possible). */
SC_API int sc_profile_lsq_dof(const sc_profile_lsq_plan *p);

/* Does the plan run the AVX2/FMA kernels (false: the portable ones)? */
SC_API bool sc_profile_lsq_uses_simd(const sc_profile_lsq_plan *p);

/* Solve: y1 (n-d1 values), y2 (n-d2 values) in µm -> f (n values, µm, relative to its LS line),
 * c (2 values, µm, the offsets c1, c2 that go with that f; may be NULL), weighted residual sum of
 * squares Σ w_k·r² (may be NULL). O(N·d), allocates nothing; the plan is not modified
 * (concurrent calls are fine).
 * A non-finite y -> SC_E_INPUT. */
SC_API sc_status sc_profile_lsq_execute(const sc_profile_lsq_plan *p, const double *y1_um,
                                        const double *y2_um, double *f_um, double *c_um, double *wrss,
                                        sc_error *err);

/* Doubles of workspace sc_profile_lsq_uncertainty needs (O(d²)). */
SC_API size_t sc_profile_lsq_work_size(const sc_profile_lsq_plan *p);

/* Standard uncertainty of every f(n) (n values, µm) given the weights the plan was made with
 * (weights = 1/σ² of y_k in 1/µm²), i.e. sqrt of the diagonal of the estimator covariance in the
 * least-squares-line gauge; O(N·d²) time (selected inversion). work: sc_profile_lsq_work_size(p)
 * doubles (then nothing is allocated), or NULL to have the call allocate them (SC_E_NOMEM
 * possible). Multiply by sqrt(wrss/dof) for the noise estimated from the residuals. */
SC_API sc_status sc_profile_lsq_uncertainty(const sc_profile_lsq_plan *p, double *uf_um,
                                            double *work, sc_error *err);

/* Free the plan (NULL is fine). */
SC_API void sc_profile_lsq_plan_destroy(sc_profile_lsq_plan *p);

#ifdef __cplusplus
}
#endif
#endif
