/* grid_calibrate_common.h — private to the grid area: the small helpers the calibration pipeline
 * (grid_calibrate.c) and its estimation of each view's noise (grid_view_noise.c) both use. They
 * live below both (grid_calibrate_common.c), so the two files depend on them and not on each other. */
#ifndef SELFCAL_GRID_CALIBRATE_COMMON_H
#define SELFCAL_GRID_CALIBRATE_COMMON_H

#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_lsq.h"

/* Residuals (µm) below this are at the rounding level: noise-free data. */
#define NOISE_FLOOR_UM 1e-9

/* o's warning function (if any) with the formatted message. */
void sc_grid_warnf(const sc_grid_options *o, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* The id of view v as the file names it (its index when the file gives none). */
int sc_grid_view_id(const sc_grid_file_info *info, int v);

/* The least squares' model options from the calibration's. */
sc_grid_lsq_opts sc_grid_lsq_opts_of(const sc_grid_options *o);

#endif
