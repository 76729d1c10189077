/* Shared by the grid tests that simulate a plan: the truth arrays sc_grid_sim_run fills, laid out
 * in one buffer, and the work it needs behind them. */
#ifndef TEST_GRID_SIM_UTIL_H
#define TEST_GRID_SIM_UTIL_H

#include <stdlib.h>

#include "selfcal/grid_sim.h"

/* One buffer for plan p's simulation: G at the stage's nodes, A at the plate's marks, each
 * view's misalignment (t's arrays point into it), then sc_grid_sim_work_doubles_plan(p) doubles
 * of work (*work). The caller frees the buffer; NULL if out of memory. */
static double *tu_sim_buffer(const sc_grid_plan *p, sc_grid_sim_truth *t, double **work)
{
    const size_t ns = (size_t)sc_grid_stage_nodes(p), nn = (size_t)p->n * (size_t)p->n;
    const size_t nv = (size_t)p->n_views;
    double *buf = malloc(sizeof(double) *
                         (2 * ns + 2 * nn + 3 * nv + sc_grid_sim_work_doubles_plan(p)));
    *work = NULL;
    if (!buf)
        return NULL;
    *t = (sc_grid_sim_truth){.gx_um = buf, .gy_um = buf + ns, .ax_um = buf + 2 * ns,
                             .ay_um = buf + 2 * ns + nn, .tx_um = buf + 2 * ns + 2 * nn,
                             .ty_um = buf + 2 * ns + 2 * nn + nv,
                             .theta_urad = buf + 2 * ns + 2 * nn + 2 * nv};
    *work = buf + 2 * ns + 2 * nn + 3 * nv;
    return buf;
}

#endif
