/* selfcal/profile_calibrate.h — a straightness measurement to a profile, end to end: the noise
 * (given, from the data's header, or estimated from the residuals), the scan weights, the method,
 * every point's uncertainty and the stage's e_y. What `selfcal profile` and the Python package's
 * calibrate_profile both call, so that they agree to the last bit.
 */
#ifndef SELFCAL_PROFILE_CALIBRATE_H
#define SELFCAL_PROFILE_CALIBRATE_H

#include <stdint.h>

#include "selfcal/api.h"
#include "selfcal/error.h"
#include "selfcal/profile.h"

#ifdef __cplusplus
extern "C" {
#endif

/* How to calibrate. Initialise with sc_profile_options_default. */
typedef struct sc_profile_options {
    sc_profile_method method;
    double sigma_disp_um;    /* each displacement sensor's noise (µm); NaN: the data's header line,
                                else unknown */
    double sigma_angle_urad; /* the angle sensor's noise (µrad); NaN: likewise */
    long mc_trials;          /* 0: analytic uncertainties; >= 2: that many Monte Carlo trials */
    uint64_t mc_seed;        /* seed of the Monte Carlo noise */
    sc_progress_fn progress; /* Monte Carlo progress (may be NULL) */
    void *progress_ctx;
    int residual_check;      /* 1 (default): with the noise given, also the residual ratio, which
                                for the DFT method costs an extra least-squares solve; 0: skip
                                that solve (wrss and residual_ratio NaN for DFT with given noise,
                                unless that noise is 0: then the residuals are always had, so
                                that a caller can tell noise-free data from a wrong 0) */
    /* Real rigs (SPEC §2a; least squares only). Any of these, or a gap in the data, takes the
     * rig solver (docs/profile-lsq.md §10) instead of the fast one. */
    int drift;               /* 0: none; 1: a drift a·τ common to both scans' y (τ = -1 at n = 0,
                                +1 at n = N-1); 2: a·τ + b·τ² */
    int reject_outliers;     /* 1: remove the worst flagged row, solve again, until none */
    int want_residuals;      /* 1: fill the solution's residual arrays (rig solver) */
} sc_profile_options;

/* Uncertainty budget entries of sc_profile_solution (what enters uf_um). */
enum { SC_PROFILE_U_NOISE = 0, SC_PROFILE_U_PROBE_GAIN, SC_PROFILE_U_ANGLE_SCALE,
       SC_PROFILE_U_SPACING, SC_PROFILE_U_N };

/* What came out. The arrays are the caller's, distinct, each of the data's N values (NULL: not
 * wanted); they are worked in, so after a failure their content is unspecified. */
typedef struct sc_profile_solution {
    double *f_um;            /* the profile relative to its least-squares line */
    double *uf_um;           /* its standard uncertainty (k = 1); NaN when no noise is known or
                                estimable (have_uf = 0) */
    double *ey_um;           /* the stage's straightness motion error from scan 1; NaN for
                                n >= N - d1 */
    int have_uf;             /* 1 if uf is given */
    int noise_known;         /* 1 if the noise was given (options or header), 0 if estimated */
    double sigma_disp_um;    /* the noise used when known (0 for a sensor not given), else NaN */
    double sigma_angle_urad;
    double sigma_y_um[2];    /* standard deviation of y1, y2 used for the uncertainties (NaN if none) */
    double wrss;             /* weighted residual sum of squares of the least-squares fit (NaN
                                for DFT with a nonzero noise given and residual_check 0) */
    int dof;                 /* its degrees of freedom, N - d1 - d2 */
    double residual_ratio;   /* sqrt(wrss/dof) when the noise is given and wrss known (1
                                expected), else NaN */
    /* χ² test of the stated noise (two-sided, 95 %): chi2_lo <= wrss/dof <= chi2_hi; NaN bounds
     * and chi2_pass 1 when not applicable. When it fails high, uf's noise part is scaled by
     * sqrt(wrss/dof) (u_scaled 1: the stated noise is too small for the residuals). */
    double chi2_lo, chi2_hi;
    int chi2_pass, u_scaled;
    /* Budget: each source's RMS and largest contribution to uf over the points (µm, k = 1):
     * noise, probe gain, angle scale, spacings; 0 for a source without U. */
    double budget_rms_um[SC_PROFILE_U_N], budget_max_um[SC_PROFILE_U_N];
    int rig;                 /* 1 if the rig solver ran (gaps, drift, residuals) */
    int n_undetermined;      /* points no row ties to the rest: f, uf NaN there */
    double drift_um[2];      /* the drift's a, b (µm; NaN when not fitted) */
    double drift_cost;       /* RMS of uf with the drift terms / without them (same rows;
                                NaN without drift) */
    /* Residuals (caller's arrays, n - d[k] values each, or NULL; with want_residuals): r = y
     * measured - fitted (µm), t standardized, outlier 0, 1 flagged, 2 flagged and removed; NaN
     * r and t for a row with no data or outside the determined points. */
    double *r_um[2], *t[2];
    unsigned char *outlier[2];
    double outlier_crit;     /* the critical |t| (data snooping, 5 % over the rows tested) */
    int n_flagged, n_removed;
} sc_profile_solution;

/* Least squares, analytic uncertainties, noise from the header or the residuals. */
SC_API void sc_profile_options_default(sc_profile_options *o);

/* Calibrate d by o into s (its arrays provided by the caller). The noise given in o wins over the
 * data's header lines; with neither, the noise is estimated from the least-squares residuals
 * (equal scan weights) and uf is left NaN when there is no redundancy (dof = 0). SC_E_INPUT
 * (file and line of d) when the method cannot solve (N, d1, d2). */
SC_API sc_status sc_profile_calibrate(const sc_profile_data *d, const sc_profile_options *o,
                                      sc_profile_solution *s, sc_error *err);

/* sc_profile_calibrate in two steps, plan and run (as FFTW's plan and execute), so that the first
 * can work while the rows are still being read (sc_profile_read_hooked). */
typedef struct sc_profile_calibration sc_profile_calibration;

/* The part of the calibration that needs only hdr's header fields (n, s_mm, d, the noise; its
 * arrays are not read): the noise and weights, the method's plan and, for least squares, the
 * banded factor with every point's unit uncertainty started on a second core. o is copied. Errors
 * as sc_profile_calibrate's; *out NULL on failure. */
SC_API sc_status sc_profile_calibration_create(const sc_profile_data *hdr,
                                               const sc_profile_options *o,
                                               sc_profile_calibration **out, sc_error *err);

/* Calibrate d into s with c: the same values as sc_profile_calibrate(d, o, s). d must have the
 * N, s_mm and spacings c was made for (SC_E_INPUT otherwise). c may run again. */
SC_API sc_status sc_profile_calibration_run(sc_profile_calibration *c, const sc_profile_data *d,
                                            sc_profile_solution *s, sc_error *err);

/* Free c and its plan (NULL: nothing). */
SC_API void sc_profile_calibration_destroy(sc_profile_calibration *c);

/* sc_profile_read(path, out), with *cal = sc_profile_calibration_create(header, o) made on a
 * thread of its own from the moment the header is read, while the rows are (at N = 10⁶ the plan
 * then costs little more than the reading). On failure nothing is left to free (*out zeroed,
 * *cal NULL) and err has the reading's error, else the plan's. */
SC_API sc_status sc_profile_read_and_plan(const char *path, const sc_profile_options *o,
                                          sc_profile_data *out, sc_profile_calibration **cal,
                                          sc_error *err);

#ifdef __cplusplus
}
#endif
#endif
