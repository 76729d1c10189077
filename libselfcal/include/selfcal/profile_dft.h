/* selfcal/profile_dft.h — the two-set two-point straightness method by the discrete Fourier
 * transform (Ding et al. §2.2, after Elster): natural extension of y_k to a full period, the
 * zero-point compensation factor a12 (weighted mean, eq. 8), the combined coefficients (eq. 9),
 * inverse DFT, f relative to its least-squares line. Needs gcd(d1, d2) = 1 and N = p·d1·d2.
 *
 * Plan object in the manner of FFTW: create for (N, d1, d2, w1, w2) — the FFTW plans and every
 * spectral weight are made once — then solve many data sets. Derivation: docs/profile.md.
 * A plan owns its FFT buffers: one plan must not be used by two threads at once.
 */
#ifndef SELFCAL_PROFILE_DFT_H
#define SELFCAL_PROFILE_DFT_H

#include "selfcal/api.h"

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_profile_dft sc_profile_dft;

/* 1 if the DFT method can solve (n, d1, d2) (d1, d2 >= 2, d1 != d2, gcd = 1, n = p·d1·d2),
 * else 0 and the reason in err. */
SC_API int sc_profile_dft_usable(int n, int d1, int d2, sc_error *err);

/* Make the plan. w1, w2 > 0: weights of scans 1 and 2 (1/variance of y_k, 1/µm²); only their
 * ratio changes f. */
SC_API sc_status sc_profile_dft_create(int n, int d1, int d2, double w1, double w2,
                                       sc_profile_dft **out, sc_error *err);

/* Solve: y1 (n-d1 values), y2 (n-d2 values) in µm -> f (n values, µm, relative to its LS line). */
SC_API sc_status sc_profile_dft_solve(sc_profile_dft *p, const double *y1_um, const double *y2_um,
                                      double *f_um, sc_error *err);

/* Standard uncertainty of every f(n) (n values, µm) for white noise of variance 1/w_k on y_k,
 * computed exactly from the method's linear response in O(N log N) (docs/profile.md). */
SC_API sc_status sc_profile_dft_uncertainty(sc_profile_dft *p, double *uf_um, sc_error *err);

/* Free the plan (NULL is fine). */
SC_API void sc_profile_dft_destroy(sc_profile_dft *p);

#ifdef __cplusplus
}
#endif
#endif
