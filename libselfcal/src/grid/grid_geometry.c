/* Geometry of views, the noise-free forward model and the gauge of SPEC §1. */
#include "selfcal/grid.h"
#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS */

#include <math.h>

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

void sc_grid_mark_xy_mm(const sc_grid_plan *p, int i, int j, double *x_mm, double *y_mm)
{
    double c = (p->n - 1) / 2.0;
    *x_mm = (j - c) * p->pitch_mm;
    *y_mm = (i - c) * p->pitch_mm;
}

double sc_grid_data_u_um(const sc_grid_data *d, int v, long k, int c)
{
    const double *u = !d->ux_um ? NULL : c ? d->uy_um[v] : d->ux_um[v];
    if (u && isfinite(u[k]))
        return u[k];
    return d->plan.view[v].sigma_um > 0 ? d->plan.view[v].sigma_um : NAN;
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

void sc_grid_rotate(int rot_deg, double ax, double ay, double *sx, double *sy)
{
    switch (rot_deg) {
    case 90: *sx = -ay; *sy = ax; break;
    case 180: *sx = -ax; *sy = -ay; break;
    case 270: *sx = ay; *sy = -ax; break;
    default: *sx = ax; *sy = ay; break;
    }
}

int sc_grid_find_view(const sc_grid_plan *p, int rot_deg, int shift_x, int shift_y)
{
    for (int v = 0; v < p->n_views; ++v)
        if (p->view[v].rot_deg == rot_deg && p->view[v].shift_x == shift_x &&
            p->view[v].shift_y == shift_y)
            return v;
    return -1;
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

/* 1 if a stage dimension is valid: 0 (the plate's own N) or odd in 3..SC_GRID_MAX_STAGE. */
static int stage_dim_ok(int m)
{
    return m == 0 || (m >= 3 && m % 2 == 1 && m <= SC_GRID_MAX_STAGE);
}

/* The plate's N, the stage size, the pitch and the origin of p. */
static sc_status plan_size_check(const sc_grid_plan *p, sc_error *err)
{
    if (p->n < 3 || p->n > SC_GRID_MAX_N || p->n % 2 == 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "N must be odd and in 3..%d (got %d)",
                            SC_GRID_MAX_N, p->n);
    if (!stage_dim_ok(p->stage_nx) || !stage_dim_ok(p->stage_ny))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "stage NX, NY must be odd and in 3..%d (got %d,%d)", SC_GRID_MAX_STAGE,
                            p->stage_nx, p->stage_ny);
    /* the readers' limits (a plan made in memory must write a file that reads back) */
    if (!(p->pitch_mm >= SC_GRID_MIN_PITCH_MM) || !(p->pitch_mm <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the pitch must be %g to %g mm, got %g", SC_GRID_MIN_PITCH_MM,
                            SC_INPUT_MAX_ABS, p->pitch_mm);
    if (!(fabs(p->origin_mm[0]) <= SC_INPUT_MAX_ABS) || !(fabs(p->origin_mm[1]) <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the origin must be within +-%g mm",
                            SC_INPUT_MAX_ABS);
    return SC_OK;
}

/* View v of p: its σ, its rotation, and at least one mark landing on the stage grid. */
static sc_status plan_view_check(const sc_grid_plan *p, int v, sc_error *err)
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
    if (st != SC_OK)
        return st;
    if (p->n_views < 1 || p->n_views > SC_GRID_VIEW_LIMIT || !p->view)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "number of views must be 1..%d",
                            SC_GRID_VIEW_LIMIT);
    for (int v = 0; v < p->n_views; ++v)
        if ((st = plan_view_check(p, v, err)) != SC_OK)
            return st;
    return grid_scale_check(p, err);
}

double sc_grid_view_scale_ppm(const sc_grid_plan *p, int v)
{
    const sc_grid_scale *sc = &p->scale;
    double s = sc->has_plate_scale ? sc->plate_scale_ppm : 0.0;
    if (sc->has_temps && sc->has_cte && v >= 0 && v < p->n_views)
        s += sc->cte_ppm_per_K * (p->view[v].temp_C - SC_GRID_REF_TEMP_C);
    return s;
}

void sc_grid_synthesize(const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                        const double *ax_um, const double *ay_um, const double *tx_um,
                        const double *ty_um, const double *theta_urad, sc_grid_data *d)
{
    int n = p->n, snx = sc_grid_stage_nx(p);
    for (int v = 0; v < p->n_views; ++v) {
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                int k = i * n + j, ni = 0, nj = 0;
                if (!sc_grid_view_measures(p, v, i, j)) {
                    d->dx_um[v][k] = NAN;
                    d->dy_um[v][k] = NAN;
                    continue;
                }
                sc_grid_mark_node(p, v, i, j, &ni, &nj);
                int q = ni * snx + nj;
                double x, y, rax, ray;
                sc_grid_node_xy_mm(p, ni, nj, &x, &y);
                sc_grid_rotate(p->view[v].rot_deg, ax_um[k], ay_um[k], &rax, &ray);
                d->dx_um[v][k] = gx_um[q] + rax + tx_um[v] - theta_urad[v] * y * 1e-3;
                d->dy_um[v][k] = gy_um[q] + ray + ty_um[v] + theta_urad[v] * x * 1e-3;
            }
    }
}

/* Project out span{(1,0), (0,1), (-y,x), (x,y)} — the four are mutually orthogonal over a
 * centred square grid, so the projection is four independent dot products. */
void sc_grid_gauge_stage(const sc_grid_plan *p, double *gx, double *gy)
{
    int nxs = sc_grid_stage_nx(p), nys = sc_grid_stage_ny(p), nn = nxs * nys;
    double sx = 0, sy = 0, srot = 0, smag = 0, r2 = 0;
    for (int i = 0; i < nys; ++i)
        for (int j = 0; j < nxs; ++j) {
            double x, y;
            sc_grid_node_xy_mm(p, i, j, &x, &y);
            int k = i * nxs + j;
            sx += gx[k];
            sy += gy[k];
            srot += x * gy[k] - y * gx[k];
            smag += x * gx[k] + y * gy[k];
            r2 += x * x + y * y;
        }
    double tx = sx / nn, ty = sy / nn, rot = srot / r2, mag = smag / r2;
    for (int i = 0; i < nys; ++i)
        for (int j = 0; j < nxs; ++j) {
            double x, y;
            sc_grid_node_xy_mm(p, i, j, &x, &y);
            int k = i * nxs + j;
            gx[k] -= tx - rot * y + mag * x;
            gy[k] -= ty + rot * x + mag * y;
        }
}

void sc_grid_gauge_plate(const sc_grid_plan *p, double *ax, double *ay)
{
    int n = p->n, nn = n * n;
    double sx = 0, sy = 0, srot = 0, r2 = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double x, y;
            sc_grid_mark_xy_mm(p, i, j, &x, &y);
            int k = i * n + j;
            sx += ax[k];
            sy += ay[k];
            srot += x * ay[k] - y * ax[k];
            r2 += x * x + y * y;
        }
    double tx = sx / nn, ty = sy / nn, rot = srot / r2;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double x, y;
            sc_grid_mark_xy_mm(p, i, j, &x, &y);
            int k = i * n + j;
            ax[k] -= tx - rot * y;
            ay[k] -= ty + rot * x;
        }
}

void sc_grid_first_order(const sc_grid_plan *p, const double *gx, const double *gy, double *O,
                         double *R)
{
    int nxs = sc_grid_stage_nx(p), nys = sc_grid_stage_ny(p);
    double so = 0, sr = 0, r2 = 0;
    for (int i = 0; i < nys; ++i)
        for (int j = 0; j < nxs; ++j) {
            double x, y;
            sc_grid_node_xy_mm(p, i, j, &x, &y);
            int k = i * nxs + j;
            so += x * gy[k] + y * gx[k];
            sr += x * gx[k] - y * gy[k];
            r2 += x * x + y * y;
        }
    /* G in µm, x and y in mm: µm/mm -> dimensionless (µm/µm) */
    *O = so / r2 * 1e-3;
    *R = sr / r2 * 1e-3;
}
