/* grid_lsq_reference.h — test helper (tests/unit/grid_lsq_reference.c, compiled into the tests
 * that use it): reference values of a least-squares plan's uncertainties by refined solves,
 * independent of the selected inverse the plan uses. Not part of the library. */
#ifndef SELFCAL_TEST_GRID_LSQ_REFERENCE_H
#define SELFCAL_TEST_GRID_LSQ_REFERENCE_H

#include "selfcal/grid_lsq.h"

/* Reference values for accuracy tests, independent of the selected inverse: for nsample nodes
 * spread over the stage, the σ_x ratio by one solve refined against long-double residuals
 * (sx_ref) next to the plan's (sx_plan); for nsample equations spread over the list, the leverage
 * likewise (h_ref, h_plan). Slow (2 nsample refined solves): tests and benchmarks only.
 * Returns 0, -1 if memory ran out or the plan has no uncertainties. */
int sc_grid_lsq_reference(const sc_grid_lsq_plan *q, int nsample, int *node, double *sx_ref,
                          double *sx_plan, long *eq, double *h_ref, double *h_plan);

/* The same for the variance per unit σ of every misalignment unknown (q's nm of them; NaN
 * where the plan has none): var_ref by refined solves, var_plan the plan's. */
int sc_grid_lsq_reference_misalignments(const sc_grid_lsq_plan *q, double *var_ref,
                                        double *var_plan);

#endif
