/* Run-time sized per-view storage: a plan's views, a data set's per-view tables and a result's
 * per-view arrays (no cap on the number of views; grid.h, grid_io.h). */
#include "selfcal/grid.h"
#include "selfcal/grid_io.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

sc_status sc_grid_plan_views(sc_grid_plan *p, int n_views, sc_error *err)
{
    if (n_views < 1 || n_views > SC_GRID_VIEW_LIMIT)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "number of views must be 1..%d (got %d)",
                            SC_GRID_VIEW_LIMIT, n_views);
    int had = p->view ? p->n_views : 0;
    if (had < 0)
        had = 0;
    sc_grid_view *w = realloc(p->view, (size_t)n_views * sizeof *w);
    if (!w)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (a plan of %d views)",
                            n_views);
    if (n_views > had)
        memset(w + had, 0, (size_t)(n_views - had) * sizeof *w);
    p->view = w;
    p->n_views = n_views;
    return SC_OK;
}

sc_status sc_grid_plan_copy(sc_grid_plan *dst, const sc_grid_plan *src, sc_error *err)
{
    if (dst == src)
        return SC_OK;
    sc_grid_view *w = NULL;
    if (src->n_views > 0 && src->view) {
        w = malloc((size_t)src->n_views * sizeof *w);
        if (!w)
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (a plan of %d views)",
                                src->n_views);
        memcpy(w, src->view, (size_t)src->n_views * sizeof *w);
    }
    free(dst->view);
    *dst = *src;
    dst->view = w;
    if (!w)
        dst->n_views = 0;
    return SC_OK;
}

void sc_grid_plan_free(sc_grid_plan *p)
{
    free(p->view);
    p->view = NULL;
    p->n_views = 0;
}

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

sc_status sc_grid_data_views(sc_grid_data *d, sc_error *err)
{
    int nv = d->plan.n_views;
    if (d->dx_um)
        return SC_OK;
    double **t = calloc(5 * (size_t)(nv > 0 ? nv : 1), sizeof *t);
    if (!t)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data of %d views)",
                            nv);
    size_t s = (size_t)(nv > 0 ? nv : 1);
    d->dx_um = t, d->dy_um = t + s, d->ux_um = t + 2 * s, d->uy_um = t + 3 * s;
    d->t_s = t + 4 * s;
    return SC_OK;
}
