/* selfcal/profile_sim.h — simulated two-scan straightness measurements (SPEC §2 model) and the
 * profiles to measure: random smooth ones (seeded) or real mirror profiles from DABAM files. */
#ifndef SELFCAL_PROFILE_SIM_H
#define SELFCAL_PROFILE_SIM_H

#include "selfcal/api.h"

#include <stddef.h>
#include <stdint.h>

#include "selfcal/error.h"
#include "selfcal/profile.h"
#include "selfcal/rng.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What the simulated instrument does besides measuring f. */
typedef struct sc_profile_sim {
    int n;                   /* N points */
    double s_mm;             /* sampling interval (mm) */
    int d1, d2;              /* sensor spacings of scans 1 and 2 (samples) */
    double sigma_disp_um;    /* white noise of each displacement sensor (µm) */
    double sigma_angle_urad; /* white noise of the angle sensor (µrad) */
    double ey_amp_um;        /* RMS of the stage's straightness motion error e_y (µm) */
    double ep_amp_urad;      /* RMS of the stage's pitch error e_p (µrad) */
    double u1_um, u2_um;     /* zero-point errors of the displacement sensors (µm) */
    double u3_urad;          /* zero-point error of the angle sensor (µrad) */
    double b0_um;            /* offset of the stage's reference line (µm) */
    int write_sigma;         /* 1: put the sigma header lines in the data file */
    uint64_t seed;           /* noise and stage errors */
} sc_profile_sim;

/* Defaults: N = 330, s = 1 mm, d = 10/11, 10 nm / 1 µrad noise, 0.5 µm e_y, 2 µrad e_p,
 * zero points 1.5/-0.7 µm, 3 µrad, b0 = 20 µm, sigma lines written, seed 1. */
SC_API void sc_profile_sim_defaults(sc_profile_sim *p);

/* A random smooth profile of n points with RMS amp_um about its least-squares line: a sum of
 * `harmonics` sine waves with random phases and amplitudes falling as 1/j^1.5. */
SC_API void sc_profile_random_smooth(int n, double amp_um, int harmonics, sc_rng *rng,
                                     double *f_um);

/* The random smooth profile `selfcal simulate profile` measures for instrument p: seeded from
 * p->seed (mixed, so that f and the instrument's own noise are independent), RMS amp_um. */
SC_API void sc_profile_sim_random_truth(const sc_profile_sim *p, double amp_um, int harmonics,
                                 double *f_um);

/* A DABAM mirror profile (dat_path; its metadata is the .txt next to it): heights (a slope
 * profile is integrated by the cumulative trapezoid rule) in µm, resampled linearly onto n points
 * at s_mm — at true scale centred on the mirror if (n-1)·s fits in its length, else stretched over
 * it — relative to the least-squares line. info (may be NULL) gets a one-line description. */
SC_API sc_status sc_profile_load_dabam(const char *dat_path, int n, double s_mm, double *f_um,
                                       char *info, size_t infolen, sc_error *err);

/* Simulate the measurement of f (n values, µm) by the instrument p: fills out (freed by the
 * caller with sc_profile_data_free) and ey_um (n values: the stage's e_y at every stage
 * position, µm, as simulated, before any line removal). */
SC_API sc_status sc_profile_simulate(const sc_profile_sim *p, const double *f_um,
                                     sc_profile_data *out, double *ey_um, sc_error *err);

#ifdef __cplusplus
}
#endif
#endif
