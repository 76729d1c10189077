/* selfcal/profile_dft.h — the two-set two-point straightness method by the discrete Fourier
 * transform (Ding et al. §2.2, after Elster): natural extension of y_k to a full period, the
 * zero-point compensation factor a12 (weighted mean, eq. 8), the combined coefficients (eq. 9),
 * inverse DFT, f relative to its least-squares line. Needs gcd(d1, d2) = 1 and N = p·d1·d2.
 *
 * Plan object in the manner of FFTW: sc_profile_dft_plan_create for (N, d1, d2, w1, w2) makes the
 * FFTW plans and every spectral weight once; sc_profile_dft_execute then solves any number of data
 * sets without allocating. Derivation: docs/profile.md.
 * The plan holds its FFT buffers: not thread-safe on one plan (one plan per thread); creating and
 * destroying plans in several threads at once is safe (FFTW's planner runs under a library lock).
 */
#ifndef SELFCAL_PROFILE_DFT_H
#define SELFCAL_PROFILE_DFT_H

#include <stdbool.h>
#include <stddef.h>

#include "selfcal/api.h"

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_profile_dft_plan sc_profile_dft_plan;

/* Can the DFT method solve (n, d1, d2)? (d1, d2 >= 1, d1 != d2, gcd = 1, n = p·d1·d2 and
 * n >= 2·max(d1, d2).) If not, false and the reason in err (SC_E_INPUT). */
SC_API bool sc_profile_dft_is_usable(int n, int d1, int d2, sc_error *err);

/* Make the plan (all allocation and FFTW planning). w1, w2 > 0: weights of scans 1 and 2
 * (1/variance of y_k, 1/µm²); only their ratio changes f. */
SC_API sc_status sc_profile_dft_plan_create(int n, int d1, int d2, double w1, double w2,
                                            sc_profile_dft_plan **out, sc_error *err);

/* Solve: y1 (n-d1 values), y2 (n-d2 values) in µm -> f (n values, µm, relative to its LS line).
 * Allocates nothing; uses the plan's FFT buffers (not thread-safe on one plan). */
SC_API sc_status sc_profile_dft_execute(sc_profile_dft_plan *p, const double *y1_um,
                                        const double *y2_um, double *f_um, sc_error *err);

/* Doubles of workspace sc_profile_dft_uncertainty needs (about 16·N). */
SC_API size_t sc_profile_dft_work_size(const sc_profile_dft_plan *p);

/* Standard uncertainty of every f(n) (n values, µm) for white noise of variance 1/w_k on y_k,
 * computed exactly from the method's linear response in O(N log N) (docs/profile.md).
 * work: sc_profile_dft_work_size(p) doubles (then nothing is allocated), or NULL to have the call
 * allocate them (SC_E_NOMEM possible). Not thread-safe on one plan. */
SC_API sc_status sc_profile_dft_uncertainty(sc_profile_dft_plan *p, double *uf_um, double *work,
                                            sc_error *err);

/* Free the plan (NULL is fine). */
SC_API void sc_profile_dft_plan_destroy(sc_profile_dft_plan *p);

#ifdef __cplusplus
}
#endif
#endif
