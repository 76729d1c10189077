/* The plan and the data that a `selfcal-grid v1` file describes (SPEC §1): their run-time sized
 * storage (a plan's views, a data set's per-view tables and arrays, a file's per-view lines) and
 * the geometry the file's header defines (which stage node a view's rot= and shift= put a mark
 * on, which marks its rows=/cols= select), with the checks of a plan.
 *
 * Why here, in io/: the reader checks every row against that geometry as it reads it (a mark off
 * the stage grid, a mark the view does not select, a row more than half a pitch from its nominal
 * place), so that each problem is reported at its own line and in file order. The containers and
 * the geometry are what the format means, not a method: keeping them with the format lets io/
 * depend on common/ alone, and every method in grid/ builds on them from above. (Passing the
 * reader callbacks into grid/ instead would have split the format's meaning over two folders
 * again.) */
#include "selfcal/grid.h"
#include "selfcal/grid_io.h"
#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS */

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- the plan's stage grid and where a view puts each mark ---- */

int sc_grid_stage_nx(const sc_grid_plan *p) { return p->stage_nx > 0 ? p->stage_nx : p->n; }

int sc_grid_stage_ny(const sc_grid_plan *p) { return p->stage_ny > 0 ? p->stage_ny : p->n; }

long sc_grid_stage_nodes(const sc_grid_plan *p)
{
    return (long)sc_grid_stage_nx(p) * sc_grid_stage_ny(p);
}

bool sc_grid_stage_is_plate(const sc_grid_plan *p)
{
    return sc_grid_stage_nx(p) == p->n && sc_grid_stage_ny(p) == p->n;
}

bool sc_grid_mark_node(const sc_grid_plan *p, int v, int i, int j, int *ni, int *nj)
{
    const sc_grid_view *w = &p->view[v];
    int c = (p->n - 1) / 2;
    int nx = sc_grid_stage_nx(p), ny = sc_grid_stage_ny(p);
    int u = j - c, q = i - c; /* plate-centred, in pitches: x = u, y = q */
    int ru, rq;
    switch (w->rot_deg) {
    case 0: ru = u; rq = q; break;
    case 90: ru = -q; rq = u; break;
    case 180: ru = -u; rq = -q; break;
    case 270: ru = q; rq = -u; break;
    default: return false;
    }
    int jn = (nx - 1) / 2 + ru + w->shift_x, in = (ny - 1) / 2 + rq + w->shift_y;
    if (jn < 0 || jn >= nx || in < 0 || in >= ny)
        return false;
    *ni = in;
    *nj = jn;
    return true;
}

bool sc_grid_view_measures(const sc_grid_plan *p, int v, int i, int j)
{
    int ni, nj;
    if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
        return false;
    const sc_grid_view *w = &p->view[v];
    if (w->restricted && !w->row_sel[i] && !w->col_sel[j])
        return false;
    return true;
}

void sc_grid_node_xy_mm(const sc_grid_plan *p, int i, int j, double *x_mm, double *y_mm)
{
    *x_mm = (j - (sc_grid_stage_nx(p) - 1) / 2.0) * p->pitch_mm;
    *y_mm = (i - (sc_grid_stage_ny(p) - 1) / 2.0) * p->pitch_mm;
}

bool sc_grid_mark_stage_xy_mm(const sc_grid_plan *p, int v, int i, int j, double *x_mm,
                              double *y_mm)
{
    int ni, nj;
    if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
        return false;
    sc_grid_node_xy_mm(p, ni, nj, x_mm, y_mm);
    return true;
}

bool sc_grid_sigma_valid(double u_um)
{
    return u_um >= SC_GRID_MIN_SIGMA_UM && u_um <= SC_INPUT_MAX_ABS;
}

/* The scale lines of SPEC §11: finite, uncertainties >= 0, temperatures only with a CTE. */
static sc_status grid_scale_check(const sc_grid_plan *p, sc_error *err)
{
    const sc_grid_scale *sc = &p->scale;
    if (sc->has_plate_scale && (!(fabs(sc->plate_scale_ppm) <= SC_GRID_MAX_SCALE_PPM) ||
                                !(sc->u_plate_scale_ppm >= 0) ||
                                !(sc->u_plate_scale_ppm <= SC_GRID_MAX_SCALE_PPM)))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "plate_scale_ppm must be E, U with |E| <= %g and 0 <= U <= %g ppm",
                            SC_GRID_MAX_SCALE_PPM, SC_GRID_MAX_SCALE_PPM);
    if (sc->has_cte && (!(fabs(sc->cte_ppm_per_K) <= SC_GRID_MAX_CTE) ||
                        !(sc->u_cte_ppm_per_K >= 0) || !(sc->u_cte_ppm_per_K <= SC_GRID_MAX_CTE)))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "plate_cte_ppm_per_K must be A, U with |A| <= %g and 0 <= U <= %g "
                            "ppm/K",
                            SC_GRID_MAX_CTE, SC_GRID_MAX_CTE);
    if (sc->has_temps && !sc->has_cte)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "temp_C on the views needs '# plate_cte_ppm_per_K = A, U'");
    if (sc->has_temps && (!(sc->temp_u_K >= 0) || !(sc->temp_u_K <= SC_GRID_MAX_TEMP_U_K)))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "temp_u_K must be 0 to %g K",
                            SC_GRID_MAX_TEMP_U_K);
    for (int v = 0; sc->has_temps && v < p->n_views; ++v)
        if (!(p->view[v].temp_C >= SC_GRID_MIN_TEMP_C && p->view[v].temp_C <= SC_GRID_MAX_TEMP_C))
            return sc_error_set(err, SC_E_INPUT, NULL, 0, "view %d: temp_C must be %g to %g C",
                                v, SC_GRID_MIN_TEMP_C, SC_GRID_MAX_TEMP_C);
    return SC_OK;
}

/* The plan's sizes: N, the stage grid, the pitch and origin within the readers' limits (a plan
 * made in memory must write a file that reads back), the number of views. */
static sc_status plan_size_check(const sc_grid_plan *p, sc_error *err)
{
    if (p->n < 3 || p->n > SC_GRID_MAX_N || p->n % 2 == 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "N must be odd and in 3..%d (got %d)",
                            SC_GRID_MAX_N, p->n);
    if (p->stage_nx < 0 || p->stage_ny < 0 || (p->stage_nx > 0 && (p->stage_nx < 3 ||
        p->stage_nx % 2 == 0 || p->stage_nx > SC_GRID_MAX_STAGE)) || (p->stage_ny > 0 &&
        (p->stage_ny < 3 || p->stage_ny % 2 == 0 || p->stage_ny > SC_GRID_MAX_STAGE)))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "stage NX, NY must be odd and in 3..%d (got %d,%d)", SC_GRID_MAX_STAGE,
                            p->stage_nx, p->stage_ny);
    if (!(p->pitch_mm >= SC_GRID_MIN_PITCH_MM) || !(p->pitch_mm <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the pitch must be %g to %g mm, got %g", SC_GRID_MIN_PITCH_MM,
                            SC_INPUT_MAX_ABS, p->pitch_mm);
    if (!(fabs(p->origin_mm[0]) <= SC_INPUT_MAX_ABS) || !(fabs(p->origin_mm[1]) <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the origin must be within +-%g mm",
                            SC_INPUT_MAX_ABS);
    if (p->n_views < 1 || p->n_views > SC_GRID_VIEW_LIMIT || !p->view)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "number of views must be 1..%d",
                            SC_GRID_VIEW_LIMIT);
    return SC_OK;
}

/* View v: its stated noise, its rotation, and at least one mark it measures on the stage grid. */
static sc_status view_check(const sc_grid_plan *p, int v, sc_error *err)
{
    const sc_grid_view *w = &p->view[v];
    if (!(w->sigma_um == 0 || sc_grid_sigma_valid(w->sigma_um))) /* 0: not stated */
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "view %d: sigma_um must be %g to %g um (0: not stated), got %g", v,
                            SC_GRID_MIN_SIGMA_UM, SC_INPUT_MAX_ABS, w->sigma_um);
    if (w->rot_deg != 0 && w->rot_deg != 90 && w->rot_deg != 180 && w->rot_deg != 270)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "view %d: rot must be 0, 90, 180 or 270 (got %d)", v, w->rot_deg);
    int any = 0;
    for (int i = 0; i < p->n && !any; ++i)
        for (int j = 0; j < p->n && !any; ++j)
            any = sc_grid_view_measures(p, v, i, j);
    if (!any)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "view %d (rot %d, shift %d,%d) lands no measured mark on the "
                            "stage grid",
                            v, w->rot_deg, w->shift_x, w->shift_y);
    return SC_OK;
}

sc_status sc_grid_plan_check(const sc_grid_plan *p, sc_error *err)
{
    sc_status st = plan_size_check(p, err);
    for (int v = 0; st == SC_OK && v < p->n_views; ++v)
        st = view_check(p, v, err);
    return st == SC_OK ? grid_scale_check(p, err) : st;
}

/* ---- run-time sized storage: a plan's views, a data set's tables, a file's lines ---- */

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

/* Free d's arrays and per-view tables, not its plan. */
static void data_free_arrays(sc_grid_data *d)
{
    if (d->dx_um)
        for (int v = 0; v < d->plan.n_views; ++v) {
            free(d->dx_um[v]);
            free(d->dy_um[v]);
            free(d->ux_um[v]);
            free(d->uy_um[v]);
            free(d->t_s[v]);
        }
    free(d->dx_um); /* the one block of the five tables */
    d->dx_um = d->dy_um = d->ux_um = d->uy_um = d->t_s = NULL;
}

sc_status sc_grid_data_alloc(sc_grid_data *d, sc_error *err)
{
    size_t nn = (size_t)d->plan.n * (size_t)d->plan.n;
    d->dx_um = NULL; /* whatever it held is not d's (a fresh d) */
    sc_status st = sc_grid_data_views(d, err);
    if (st != SC_OK)
        return st;
    for (int v = 0; v < d->plan.n_views; ++v) {
        d->dx_um[v] = malloc(nn * sizeof(double));
        d->dy_um[v] = malloc(nn * sizeof(double));
        if (!d->dx_um[v] || !d->dy_um[v]) {
            data_free_arrays(d);
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data, N = %d)",
                                d->plan.n);
        }
        for (size_t k = 0; k < nn; ++k)
            d->dx_um[v][k] = d->dy_um[v][k] = NAN;
    }
    return SC_OK;
}

sc_status sc_grid_data_alloc_extra(sc_grid_data *d, int weights, int times, sc_error *err)
{
    size_t nn = (size_t)d->plan.n * (size_t)d->plan.n;
    sc_status st = sc_grid_data_views(d, err);
    if (st != SC_OK)
        return st;
    for (int v = 0; v < d->plan.n_views; ++v) {
        double **a[3] = {&d->ux_um[v], &d->uy_um[v], &d->t_s[v]};
        for (int t = 0; t < 3; ++t) {
            if ((t < 2 && !weights) || (t == 2 && !times) || *a[t])
                continue;
            *a[t] = malloc(nn * sizeof(double));
            if (!*a[t])
                return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data)");
            for (size_t k = 0; k < nn; ++k)
                (*a[t])[k] = NAN;
        }
    }
    return SC_OK;
}

void sc_grid_data_free(sc_grid_data *d)
{
    data_free_arrays(d);
    sc_grid_plan_free(&d->plan);
}

void sc_grid_file_info_free(sc_grid_file_info *info)
{
    if (!info)
        return;
    free(info->view_line), free(info->view_id), free(info->view_rows);
    info->view_line = NULL, info->view_id = NULL, info->view_rows = NULL;
}
