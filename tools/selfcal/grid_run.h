/* grid_run.h — what `selfcal grid` shares with `report grid` and `verify`: the closed-form
 * methods' view checks. */
#ifndef SELFCAL_GRID_RUN_H
#define SELFCAL_GRID_RUN_H

#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"

/* The stage grid: NX x NY nodes (SPEC §5). */
#define GRID_STAGE_NX(p) sc_grid_stage_nx(p)
#define GRID_STAGE_NY(p) sc_grid_stage_ny(p)

/* Check that the views Ye's method (double_shift = 0) or the double shift (1) needs are declared
 * and completely measured in d (SC_E_INPUT naming the file and line otherwise). */
sc_status grid_check_exact_views(const char *path, const sc_grid_data *d,
                                 const sc_grid_file_info *info, int double_shift, sc_error *err);

#endif
