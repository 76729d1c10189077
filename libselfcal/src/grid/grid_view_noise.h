/* grid_view_noise.h — private to the grid area: each view's noise in a least-squares grid
 * calibration (grid_view_noise.c), as the calibration pipeline (grid_calibrate.c) calls it. */
#ifndef SELFCAL_GRID_VIEW_NOISE_H
#define SELFCAL_GRID_VIEW_NOISE_H

#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_lsq.h"

/* The uncertainties the data came with (restored on return), and the factors applied on them. */
typedef struct view_noise {
    double *sigma_um;                   /* each view's sigma_um as read (0: none) */
    double *u;                          /* the rows' ux then uy as read, per view (NULL: none) */
    double *f;                          /* the factors now in d (per view; with sigma_um one
                                           block of 2 n_views) */
    int active;                         /* 1: saved, to be restored */
} view_noise;

/* Save d's uncertainties into vn if the noise per view is to be estimated (else nothing). */
sc_status sc_grid_view_noise_save(const sc_grid_data *d, int estimate, view_noise *vn,
                                  sc_error *err);

/* d's uncertainties as read and vn's factors back to 1 (vn kept). */
void sc_grid_view_noise_as_read(sc_grid_data *d, view_noise *vn);

/* d's uncertainties as read; vn released. */
void sc_grid_view_noise_restore(sc_grid_data *d, view_noise *vn);

/* Förstner's variance components: re-weight the views by their estimated noise and solve again
 * until it settles (*qp and s->res then the fit with those weights; the weights as read kept,
 * with a warning, when it cannot settle); src names the data in warnings. */
sc_status sc_grid_estimate_view_noise(sc_grid_data *d, const sc_grid_file_info *info,
                                      const sc_grid_options *o, view_noise *vn,
                                      sc_grid_solution *s, sc_grid_lsq_plan **qp, const char *src,
                                      sc_error *err);

#endif
