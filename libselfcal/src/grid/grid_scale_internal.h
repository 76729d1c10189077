/* grid_scale_internal.h — private to the grid area: the pieces of SPEC §11 that
 * sc_grid_calibrate (grid_calibrate.c) and its Monte Carlo put together (grid_scale.c). */
#ifndef SELFCAL_GRID_SCALE_INTERNAL_H
#define SELFCAL_GRID_SCALE_INTERNAL_H

#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_scale.h"

/* The estimator of G on one mask: a least-squares plan, and with free view scales the
 * residuals R of each view's unit scale (b_v = 1e-3·Rot_v(p) µm per ppm), M = RᵀWR and its
 * pseudo-inverse; gb, mb: the plan's G (gx then gy) and plate magnification for each b_v. */
typedef struct sc_grid_est {
    sc_grid_lsq_plan *q;
    int nv, ns, mag, free, weighted, rank;
    long tot;      /* nv·N² */
    double *R;     /* nv columns of 2·tot (rx then ry) */
    double *M, *Mp; /* nv x nv */
    double *gb;    /* nv columns of 2·ns */
    double *mb;    /* nv */
    double *w;     /* 2·tot coordinate weights (0: unmeasured) */
} sc_grid_est;

/* The plate's magnification of a plate error map (ppm): 1e3·Σ(x·Ax + y·Ay)/Σ(x² + y²) over the
 * marks with a value (x, y plate-centred, mm). */
double sc_grid_plate_magnification_ppm(const sc_grid_plan *p, const double *ax, const double *ay);

/* 1 if the scale model applies to plan p: a plate scale, temperatures, or free view scales. */
int sc_grid_scale_model_applies(const sc_grid_plan *p, int view_scale_free);

/* d's measured values minus each view's plate scale s_ppm[v]·1e-3·Rot_v(p) (µm). */
void sc_grid_scale_subtract(sc_grid_data *d, const double *s_ppm);

/* c := a copy of d's plan and dx/dy (its own arrays); ux, uy, t_s borrowed from d. Free with
 * sc_grid_data_copy_free (never sc_grid_data_free). */
sc_status sc_grid_data_copy_values(const sc_grid_data *d, sc_grid_data *c, sc_error *err);
void sc_grid_data_copy_free(sc_grid_data *c);

/* Make the estimator for mask's measured marks (mag: the magnification gauge; free_scales:
 * each view's scale free). Free it with sc_grid_est_free, even on failure. */
sc_status sc_grid_est_make(const sc_grid_data *mask, const sc_grid_lsq_opts *opts, int mag,
                           int free_scales, sc_grid_est *e, sc_error *err);
void sc_grid_est_free(sc_grid_est *e);

/* The free view scales (ppm, nv) of d by e (which must have free_scales). */
sc_status sc_grid_est_free_scales(const sc_grid_est *e, const sc_grid_data *d, double *s,
                                  sc_error *err);

/* The budget: b's noise arrays must be allocated (NX·NY each); res->ugx_um/ugy_um come in as
 * the plan's noise part (SPEC gauge, without the free scales) and leave combined. noise_dof:
 * the degrees of freedom of σ_r (INFINITY when given or stated). */
sc_status sc_grid_budget_fill(const sc_grid_est *e, const sc_grid_plan *p, double noise_dof,
                              sc_grid_result *res, sc_grid_budget *b, sc_error *err);

/* The Monte Carlo trials on base (the data as measured, outliers removed) with the tables of
 * shared (free scales), on up to two threads (threads: 0 = both cores when there are two). */
sc_status sc_grid_mc_run(const sc_grid_data *base, const sc_grid_options *o,
                         const sc_grid_solution *s, const sc_grid_est *shared, long trials,
                         uint64_t seed, int threads, sc_grid_mc *mc, sc_error *err);

#endif
