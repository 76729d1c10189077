/* selfcal/grid_exact.h — the exact (closed-form) grid self-calibration methods:
 *   Ye et al. (1997): views {rot 0}, {rot 90}, {shift +1,0};
 *   Petrò (2019) double shift: {rot 0}, {rot 90}, {shift +2,0}, {shift -3,0: row c, columns c, c+1}.
 * Plan objects in the manner of FFTW: create once for a size N (allocates the FFTW plans and the
 * workspace), execute on any number of data sets without allocating, destroy. Creation and
 * destruction call FFTW's planner under the library's own lock, so threads may make and destroy
 * plans at once; a plan holds its workspace: not thread-safe on one plan (one plan per thread).
 * Derivation and figures: docs/grid-exact.md.
 */
#ifndef SELFCAL_GRID_EXACT_H
#define SELFCAL_GRID_EXACT_H

#include <stdbool.h>
#include "selfcal/api.h"

#include "selfcal/grid.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sc_grid_exact_method {
    SC_GRID_YE = 0,
    SC_GRID_DOUBLE_SHIFT = 1
} sc_grid_exact_method;

typedef struct sc_grid_exact_plan sc_grid_exact_plan;

/* A view a closed-form method needs, by its role (0: rot 0; 1: rot 90; 2: the +shift view;
 * 3: double shift's -3 view). partial: only plate row c and columns c, c+1 are used. */
typedef struct sc_grid_view_need {
    int rot_deg, shift_x, shift_y;
    int partial;
} sc_grid_view_need;

/* The method's knowledge of its plan, stated once: fills need[0..] with the views method m
 * needs, in role order, and returns their count (3 for Ye, 4 for double shift). The plan
 * builders (sc_grid_plan_ye, sc_grid_plan_double_shift), the solver and the CLI all ask here. */
SC_API int sc_grid_exact_needs(sc_grid_exact_method m, sc_grid_view_need need[4]);

/* The smallest plate size N the method works for (3 for Ye, 9 for double shift). */
SC_API int sc_grid_exact_min_n(sc_grid_exact_method m);

/* True if method m uses mark (i, j) of the view in role r, for an n x n plate. */
SC_API bool sc_grid_exact_uses_mark(sc_grid_exact_method m, int n, int r, int i, int j);

/* Make a plan for method m and plate size n (Ye: n odd >= 3; double shift: n odd >= 9). */
SC_API sc_status sc_grid_exact_plan_create(sc_grid_exact_method m, int n, sc_grid_exact_plan **out,
                                           sc_error *err);

/* Separate G and A from d (its views are found by rot/shift; a missing or incomplete needed view
 * is SC_E_INPUT). Fills res (G, A, O, R, misalignments, residual RMS; uncertainties NaN). */
SC_API sc_status sc_grid_exact_execute(sc_grid_exact_plan *p, const sc_grid_data *d,
                                       sc_grid_result *res, sc_error *err);

/* Free the plan (NULL is fine). */
SC_API void sc_grid_exact_plan_destroy(sc_grid_exact_plan *p);

#ifdef __cplusplus
}
#endif
#endif
