/* The noise-free forward model and the gauge of SPEC §1, on the plan's geometry (where a view
 * puts each mark: io/grid_plan.c, with the format that defines it). */
#include "selfcal/grid.h"
#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS */

#include <math.h>

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
