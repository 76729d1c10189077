/* selfcal/profile.h — straightness profiles by the two-set two-point method (Ding et al., SPEC §2):
 * the combined differences y_k, the stage's straightness motion error e_y, residuals and Monte
 * Carlo uncertainty. The data set and the result, with their files, are io/'s:
 * selfcal/profile_file.h.
 *
 * Model: scan k (k = 1, 2) samples n = 0..N-d_k-1 with sensor spacing D_k = d_k·s (mm);
 * y_k(n) = m2 - m1 - D_k·m3 = f(n + d_k) - f(n) + c_k, where D_k[mm]·m3[µrad] is in nm (×1e-3 µm).
 * The methods themselves: selfcal/profile_dft.h (Fourier), selfcal/profile_lsq.h (least squares).
 */
#ifndef SELFCAL_PROFILE_H
#define SELFCAL_PROFILE_H

#include "selfcal/api.h"

#include <stdint.h>

#include "selfcal/error.h"
#include "selfcal/profile_file.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The reconstruction method. */
typedef enum sc_profile_method { SC_PROFILE_DFT = 0, SC_PROFILE_LSQ = 1 } sc_profile_method;

/* Check that method can solve (N, d1, d2) of d; the error names the file and header line. */
SC_API sc_status sc_profile_check_method(const sc_profile_data *d, sc_profile_method method,
                                         sc_error *err);

/* The combined difference y_k = m2/K - m1 - D_k·(m3/K_angle)·1e-3 of scan k (k = 0 or 1), N-d[k]
 * values (µm); K, K_angle: the data's probe_gain and angle_scale (1 when not given); NaN where
 * the data have a gap. */
SC_API void sc_profile_combine(const sc_profile_data *d, int k, double *y_um);

/* Variance of y_k (µm²) for displacement noise sigma_disp_um and angle noise sigma_angle_urad:
 * 2·σ_disp² + (D_k·σ_angle·1e-3)², D_k = d·s_mm. */
SC_API double sc_profile_y_variance(int d, double s_mm, double sigma_disp_um,
                                    double sigma_angle_urad);

/* Replace v[0..n-1] (samples at equal spacing) by its residual from its least-squares line. */
SC_API void sc_profile_remove_line(int n, double *v);

/* The stage's straightness motion error from scan 1: e_y = m1 - f relative to its least-squares
 * line over n = 0..N-d1-1 (N-d1 values, µm); f_um: the reconstructed profile (N values, µm). */
SC_API void sc_profile_stage_error(const sc_profile_data *d, const double *f_um, double *ey_um);

/* Residual noise estimate: for profile f (N values) and the data y1, y2, fit c1, c2 and return
 * the weighted residual sum of squares; *dof gets the degrees of freedom 2N - d1 - d2 - N. */
SC_API double sc_profile_residual_ss(int n, int d1, int d2, const double *y1_um,
                                     const double *y2_um, const double *f_um, double w1, double w2,
                                     int *dof);

/* A linear estimator of f from (y1, y2): writes f (N values, µm). */
typedef sc_status (*sc_profile_solver_fn)(void *ctx, const double *y1_um, const double *y2_um,
                                          double *f_um, sc_error *err);

/* Progress report: done of total trials finished. */
typedef void (*sc_progress_fn)(void *ctx, long done, long total);

/* Monte Carlo standard uncertainty of every f(n) (N values, µm): `trials` repetitions of white
 * noise of standard deviation sigma_y1_um / sigma_y2_um on y1 / y2 (seeded), through solve.
 * Exact for a linear estimator, whose error does not depend on f or c. progress may be NULL. */
SC_API sc_status sc_profile_mc_uncertainty(int n, int d1, int d2, double sigma_y1_um,
                                           double sigma_y2_um, sc_profile_solver_fn solve,
                                           void *ctx, long trials, uint64_t seed,
                                           sc_progress_fn progress, void *pctx, double *uf_um,
                                           sc_error *err);

#ifdef __cplusplus
}
#endif
#endif
