/* selfcal/profile.h — straightness profiles by the two-set two-point method (Ding et al., SPEC §2):
 * the measurement data set, its strict reader and writer, the combined differences y_k, the
 * stage's straightness motion error e_y, the output file, and Monte Carlo uncertainty.
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

#ifdef __cplusplus
extern "C" {
#endif

/* One measurement: two scans of the same profile with sensor spacings d[0]·s and d[1]·s. */
typedef struct sc_profile_data {
    int n;                 /* N: points on the profile, n = 0..N-1 */
    double s_mm;           /* sampling interval s (mm) */
    int d[2];              /* d1, d2: sensor spacings in samples */
    double *m1_um[2];      /* scan k: displacement sensor 1, N-d[k] values (µm) */
    double *m2_um[2];      /* scan k: displacement sensor 2, N-d[k] values (µm) */
    double *m3_urad[2];    /* scan k: angle sensor, N-d[k] values (µrad) */
    int has_sigma_disp;    /* 1 if sigma_disp_um is known (header line) */
    int has_sigma_angle;   /* 1 if sigma_angle_urad is known (header line) */
    double sigma_disp_um;  /* standard deviation of each displacement sensor (µm) */
    double sigma_angle_urad; /* standard deviation of the angle sensor (µrad) */
    long line_n;           /* line numbers of the "# N =" and "# scan k:" header lines in the */
    long line_scan[2];     /* file read (0 when not read from a file), for error messages */
    char path[256];        /* the file it was read from ("" if none) */
} sc_profile_data;

/* The reconstruction method. */
typedef enum sc_profile_method { SC_PROFILE_DFT = 0, SC_PROFILE_LSQ = 1 } sc_profile_method;

/* Allocate the per-scan arrays of d for (n, s_mm, d1, d2) (zero-filled; no sigmas). */
SC_API sc_status sc_profile_data_init(sc_profile_data *d, int n, double s_mm, int d1, int d2,
                                      sc_error *err);

/* Free the arrays of d (d itself is the caller's); safe on a zeroed or freed struct. */
SC_API void sc_profile_data_free(sc_profile_data *d);

/* Read a `selfcal-profile v1` file strictly (SPEC §2): missing scan, gaps or duplicates in n,
 * n out of range, N too small for the spacings, non-numeric fields -> SC_E_INPUT with file:line.
 * Method-specific conditions are checked by sc_profile_check_method. */
SC_API sc_status sc_profile_read(const char *path, sc_profile_data *out, sc_error *err);

/* Check that method can solve (N, d1, d2) of d; the error names the file and header line. */
SC_API sc_status sc_profile_check_method(const sc_profile_data *d, sc_profile_method method,
                                         sc_error *err);

/* Write d as a `selfcal-profile v1` file atomically (each number with the fewest digits that read
 * back exactly, selfcal/number.h; the sigma lines only when known). */
SC_API sc_status sc_profile_write(const char *path, const sc_profile_data *d, sc_error *err);

/* The combined difference y_k = m2 - m1 - D_k·m3·1e-3 of scan k (k = 0 or 1), N-d[k] values (µm). */
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

/* Write the output file `n,x_mm,f_um,uf_um,ey_um` atomically: f, uf (may be NULL: empty column)
 * have n values, ey has n_ey values (empty where index >= n_ey). */
SC_API sc_status sc_profile_write_result(const char *path, int n, double s_mm, const double *f_um,
                                         const double *uf_um, const double *ey_um, int n_ey,
                                         sc_error *err);

/* A profile result or truth file read back (columns found by name; missing/empty -> NaN). */
typedef struct sc_profile_result {
    int n;
    double *x_mm, *f_um, *uf_um, *ey_um; /* n values each */
} sc_profile_result;

/* Read a file with a header line naming at least n,x_mm,f_um (uf_um and ey_um optional). */
SC_API sc_status sc_profile_read_result(const char *path, sc_profile_result *out, sc_error *err);

/* Free the arrays of r. */
SC_API void sc_profile_result_free(sc_profile_result *r);

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
