/* grid_lsq_internal.h — private to the grid area (and its benchmarks): the reduced, pinned normal
 * matrix a plan factors, so a benchmark can hand the very same matrix to another solver. */
#ifndef SELFCAL_GRID_LSQ_INTERNAL_H
#define SELFCAL_GRID_LSQ_INTERNAL_H

#include "selfcal/grid_lsq.h"

/* The matrix of q: n x n, upper triangle in compressed columns (borrowed from q). */
void sc_grid_lsq_matrix(const sc_grid_lsq_plan *q, int *n, const long **Ap, const int **Ai,
                        const double **Ax);

#endif
