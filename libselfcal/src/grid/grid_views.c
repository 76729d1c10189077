/* Run-time sized per-view storage of a result: its per-view arrays in one block (no cap on the
 * number of views; grid.h). A plan's views and a data set's tables are io/grid_plan.c's. */
#include "selfcal/grid.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

sc_status sc_grid_result_views(sc_grid_result *res, int n_views, sc_error *err)
{
    sc_grid_result_free_views(res);
    size_t nv = n_views > 0 ? (size_t)n_views : 1;
    double *b = malloc(SC_GRID_RESULT_VIEW_ARRAYS * nv * sizeof *b);
    if (!b)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (results of %d views)",
                            n_views);
    for (size_t k = 0; k < SC_GRID_RESULT_VIEW_ARRAYS * nv; ++k)
        b[k] = NAN;
    double **a[SC_GRID_RESULT_VIEW_ARRAYS] = {
        &res->tx_um,   &res->ty_um,    &res->theta_urad,  &res->utx_um,        &res->uty_um,
        &res->utheta_urad, &res->vx_um_s, &res->vy_um_s, &res->uvx_um_s,     &res->uvy_um_s,
        &res->view_sigma_um, &res->view_noise_factor, &res->view_sigma_u_um};
    for (int t = 0; t < SC_GRID_RESULT_VIEW_ARRAYS; ++t)
        *a[t] = b + (size_t)t * nv;
    res->view_block = b;
    return SC_OK;
}

void sc_grid_result_free_views(sc_grid_result *res)
{
    if (!res->view_block)
        return;
    free(res->view_block);
    res->view_block = NULL;
    res->tx_um = res->ty_um = res->theta_urad = res->utx_um = res->uty_um = res->utheta_urad = NULL;
    res->vx_um_s = res->vy_um_s = res->uvx_um_s = res->uvy_um_s = NULL;
    res->view_sigma_um = res->view_noise_factor = res->view_sigma_u_um = NULL;
}

