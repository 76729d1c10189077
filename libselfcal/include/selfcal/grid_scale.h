/* selfcal/grid_scale.h — the plate's scale and temperature (SPEC §11) in a least-squares grid
 * calibration: the data brought to the 20 °C plate, the stage's magnification tied to the plate's
 * certified scale, free per-view scales, the uncertainty budget of G (GUM, JCGM 100) and its
 * Monte Carlo check (JCGM 101). docs/grid.md, "Scale, temperature and the uncertainty budget".
 *
 * Model (µm; x, y in mm): the plate of view v is the 20 °C plate scaled by
 *     s_v = E + A·(T_v − 20) ppm,
 * so its marks sit s_v·1e-3·Rot_v(p) µm from where an unscaled plate puts them (p: the mark's
 * plate-centred nominal position). sc_grid_calibrate subtracts that, solves, and with E given
 * moves the plate's magnification (which the certificate fixes at E) to the stage:
 *     M = 1e3·Σ(x·Ax + y·Ay)/Σ(x² + y²)   (over the measured marks, of the solution's A),
 *     G += M·1e-3·(x, y),   A −= M·1e-3·(x, y),
 * i.e. the gauge of G keeps no translation and no rotation, and A has no magnification.
 */
#ifndef SELFCAL_GRID_SCALE_H
#define SELFCAL_GRID_SCALE_H

#include <stdint.h>

#include "selfcal/api.h"
#include "selfcal/grid.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One source of the budget, at the node and component where the combined u is largest. */
typedef struct sc_grid_budget_row {
    const char *source;  /* static name: "measurement noise", "plate scale E", ... */
    const char *unit;    /* the unit of u: "um", "ppm", "ppm/K", "K" */
    double u;            /* the source's standard uncertainty (NaN: stated per measurement) */
    double c;            /* its sensitivity there, µm per unit of u (for the temperatures the
                            root sum of squares over the views: each view's own) */
    double contrib_um;   /* its contribution |c|·u, µm */
    double dof;          /* degrees of freedom (INFINITY: taken as exact) */
} sc_grid_budget_row;

#define SC_GRID_BUDGET_ROWS 5

/* The scale model's results and the budget. Arrays are allocated by sc_grid_calibrate and freed
 * by sc_grid_solution_free. */
typedef struct sc_grid_budget {
    int applies;                 /* 1: the model of SPEC §11 was used (a scale line, temp_C, or
                                    free view scales); 0: nothing below is set */
    int magnification;           /* 1: plate_scale_ppm given: G includes M */
    double magnification_ppm;    /* M (NaN without plate_scale_ppm) */
    double u_magnification_ppm;  /* its combined standard uncertainty */
    double u_magnification_noise_ppm; /* the noise's part of it */
    int view_scale_free;         /* 1: each view's relative scale was estimated */
    int n_views;
    double *view_scale_ppm;      /* per view: the scale used, s_v (+ the free part), ppm */
    double *view_scale_free_ppm; /* the free relative scales (mean 0; NaN when not free) */
    double *u_view_scale_free_ppm; /* their standard uncertainties */
    double view_scale_chi2;      /* sᵀCov(s)⁺s of the free scales, and its 95 % critical value */
    double view_scale_chi2_crit;
    int view_scale_significant;  /* 1: the free scales are significant (χ² test at 95 %) */
    double *ugx_noise_um, *ugy_noise_um; /* per stage node: the noise's part of u(G), k = 1 */
    int n_rows;
    sc_grid_budget_row row[SC_GRID_BUDGET_ROWS];
    long worst_node;             /* node (i*NX + j) and component (0: x, 1: y) of the largest */
    int worst_comp;              /* combined u */
    double u_c_um;               /* the combined standard uncertainty there */
    double nu_eff;               /* its effective degrees of freedom (Welch–Satterthwaite) */
    double k;                    /* the coverage factor */
    int k_welch;                 /* 1: k = t_0.975(nu_eff) (σ_r estimated from few degrees of
                                    freedom: nu_eff < 30); 0: k = 2 */
    double U_um;                 /* the expanded uncertainty k·u_c */
} sc_grid_budget;

/* The Monte Carlo check of a calibration (JCGM 101): per node the standard deviation of G over
 * the trials, its ratio to the budget's u, and the 95 % probabilistically symmetric coverage
 * interval. Arrays NX·NY, freed by sc_grid_mc_free. */
typedef struct sc_grid_mc {
    long trials;
    uint64_t seed;
    int threads;                 /* threads used */
    double seconds;              /* wall time of the trials */
    double *ugx_um, *ugy_um;     /* the trials' standard deviation of gx, gy */
    double *ratio_x, *ratio_y;   /* ugx_um / the budget's ugx_um, likewise y */
    double *gx_lo_um, *gx_hi_um, *gy_lo_um, *gy_hi_um; /* 2.5 % and 97.5 % quantiles */
    double ratio_min, ratio_max, ratio_mean; /* over every node and component */
    double magnification_sd_ppm; /* the trials' standard deviation of M (NaN without E) */
} sc_grid_mc;

/* Student's t quantile: t with P(T <= t) = p for dof degrees of freedom (dof > 0, may be
 * fractional; INFINITY: the normal's). NaN for bad arguments. */
SC_API double sc_student_t_quantile(double p, double dof);

/* Free what a Monte Carlo result holds (safe on a zeroed or freed one). */
SC_API void sc_grid_mc_free(sc_grid_mc *mc);

#ifdef __cplusplus
}
#endif
#endif
