/* After execute: the residuals of a result and the outlier test's flag, Förstner's variance
 * components per view, the refitted misalignments, the covariance of G and the prediction of a
 * view's measurement. */
#include "grid_lsq_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid_sim.h"

int sc_grid_outlier_beyond(const sc_grid_result *res, double t)
{
    return isfinite(t) && fabs(t) > res->outlier_crit;
}

void sc_grid_lsq_fit_misalignments(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                   const sc_grid_result *res, double *m, int *determined)
{
    sc_lsq_fit_misalignments(q, d, res->gx_um, res->gy_um, res->ax_um, res->ay_um, 1, m);
    for (int v = 0; determined && v < q->nv; ++v)
        determined[v] = !q->view_free[v];
}

sc_status sc_grid_lsq_residuals(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                const sc_grid_result *res, double *rx_um, double *ry_um,
                                double *tx, double *ty, double *h_out, sc_error *err)
{
    sc_status st = sc_lsq_check_data(q, d, err);
    if (st != SC_OK)
        return st;
    if (!res->gx_um || !res->gy_um || !res->ax_um || !res->ay_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "residuals need the result's G and A");
    if (!isfinite(res->sigma_r_used_um))
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "residuals asked before a solve");
    double tscale = sc_lsq_residual_scale(res), *m = q->mis_work;
    sc_grid_lsq_fit_misalignments(q, d, res, m, NULL);
    size_t tot = (size_t)q->nv * q->nn;
    double *outs[5] = {rx_um, ry_um, tx, ty, h_out};
    for (int o = 0; o < 5; ++o)
        for (size_t k = 0; outs[o] && k < tot; ++k)
            outs[o][k] = NAN;
    for (long e = 0; e < q->neq; ++e) {
        size_t at = (size_t)q->eq_v[e] * q->nn + (size_t)q->eq_k[e];
        int c = q->eq_c[e], node = q->eq_g[e] / 2, k = q->eq_a[e] / 2;
        double gv = c ? res->gy_um[node] : res->gx_um[node];
        double av = q->eq_a[e] % 2 ? res->ay_um[k] : res->ax_um[k], h = q->eq_h[e];
        double r = sc_lsq_eq_residual(q, d, e, gv, av, m);
        double sd = tscale / sqrt(q->eq_w[e]) * sqrt(fmax(0.0, 1.0 - h));
        double t = 1.0 - h > 1e-9 && sd > 0 ? r / sd : NAN;
        if (c == 0) {
            if (rx_um) rx_um[at] = r;
            if (tx) tx[at] = t;
        } else {
            if (ry_um) ry_um[at] = r;
            if (ty) ty[at] = t;
        }
        if (h_out && (c == 0 || !(h_out[at] >= h)))
            h_out[at] = h;
    }
    return SC_OK;
}

sc_status sc_grid_lsq_view_components(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                      const sc_grid_result *res, double *wrss, double *red,
                                      double *u2, sc_error *err)
{
    sc_status st = sc_lsq_check_data(q, d, err);
    if (st != SC_OK)
        return st;
    if (!res->gx_um || !res->gy_um || !res->ax_um || !res->ay_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "variance components need G and A");
    double *m = q->mis_work, *cnt = m + q->nm;
    sc_grid_lsq_fit_misalignments(q, d, res, m, NULL);
    for (int v = 0; v < q->nv; ++v)
        wrss[v] = red[v] = u2[v] = cnt[v] = 0;
    for (long e = 0; e < q->neq; ++e) {
        int v = q->eq_v[e], c = q->eq_c[e], node = q->eq_g[e] / 2, k = q->eq_a[e] / 2;
        double gv = c ? res->gy_um[node] : res->gx_um[node];
        double av = q->eq_a[e] % 2 ? res->ay_um[k] : res->ax_um[k];
        double r = sc_lsq_eq_residual(q, d, e, gv, av, m);
        wrss[v] += q->eq_w[e] * r * r;
        red[v] += fmax(0.0, 1.0 - q->eq_h[e]);
        u2[v] += 1.0 / q->eq_w[e], cnt[v] += 1;
    }
    for (int v = 0; v < q->nv; ++v)
        u2[v] = cnt[v] > 0 ? u2[v] / cnt[v] : NAN;
    return SC_OK;
}

/* cov (ng x ng) := the G block of the pinned inverse Σ, by blocked solves of unit columns. */
static int pinned_inverse_g(const sc_grid_lsq_plan *q, double *cov)
{
    int ng = q->ng;
    size_t n = (size_t)q->n_red;
    double *X = malloc(sizeof(double) * 3 * n * SOLVE_CHUNK);
    if (!X)
        return -1;
    for (int j0 = 0; j0 < ng; j0 += SOLVE_CHUNK) {
        int k = ng - j0 < SOLVE_CHUNK ? ng - j0 : SOLVE_CHUNK;
        memset(X, 0, sizeof(double) * n * (size_t)k);
        for (int c = 0; c < k; ++c)
            X[(size_t)c * n + (size_t)(j0 + c)] = 1;
        if (sc_lsq_pinned_solve(q, X, k, 1, X + n * SOLVE_CHUNK, X + 2 * n * SOLVE_CHUNK) != 0) {
            free(X);
            return -1;
        }
        for (int c = 0; c < k; ++c)
            memcpy(cov + (size_t)(j0 + c) * ng, X + (size_t)c * n, sizeof(double) * (size_t)ng);
    }
    free(X);
    return 0;
}

sc_status sc_grid_lsq_covariance(const sc_grid_lsq_plan *q, const sc_grid_result *res,
                                 double *cov, sc_error *err)
{
    int ng = q->ng;
    if (!q->info.identifiable || !(res->sigma_r_used_um > 0))
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0, "no solution to take a covariance of");
    if (q->ns > SC_GRID_LSQ_COV_MAX_NODES)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the covariance of %d stage nodes is too large (limit %d nodes)",
                            q->ns, SC_GRID_LSQ_COV_MAX_NODES);
    double *U = malloc(sizeof(double) * (size_t)4 * ng);
    double *SU = calloc((size_t)4 * ng, sizeof(double)), scale[4];
    if (!U || !SU || pinned_inverse_g(q, cov) != 0) {
        free(U), free(SU);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (covariance)");
    }
    sc_lsq_gauge_basis(q, U, scale);
    /* P⊥ Σ P⊥ = Σ - U(ΣU)ᵀ - (ΣU)Uᵀ + U(UᵀΣU)Uᵀ */
    for (int c = 0; c < 4; ++c)
        for (int i = 0; i < ng; ++i) {
            double s = 0;
            for (int j = 0; j < ng; ++j)
                s += cov[(size_t)i * ng + j] * U[(size_t)c * ng + j];
            SU[(size_t)c * ng + i] = s;
        }
    double M[4][4];
    for (int c = 0; c < 4; ++c)
        for (int d = 0; d < 4; ++d) {
            double s = 0;
            for (int i = 0; i < ng; ++i)
                s += U[(size_t)c * ng + i] * SU[(size_t)d * ng + i];
            M[c][d] = s;
        }
    double v2 = res->sigma_r_used_um * res->sigma_r_used_um;
    for (int i = 0; i < ng; ++i)
        for (int j = 0; j < ng; ++j) {
            double s = cov[(size_t)i * ng + j];
            for (int c = 0; c < 4; ++c) {
                s -= U[(size_t)c * ng + i] * SU[(size_t)c * ng + j] +
                     SU[(size_t)c * ng + i] * U[(size_t)c * ng + j];
                for (int d = 0; d < 4; ++d)
                    s += U[(size_t)c * ng + i] * M[c][d] * U[(size_t)d * ng + j];
            }
            cov[(size_t)i * ng + j] = s * v2;
        }
    free(U), free(SU);
    return SC_OK;
}

/* The prediction of mark (i, j) in view v from its misalignment unknowns mv (nb). */
static void predict_view(const sc_grid_lsq_plan *q, const sc_grid_result *res, const double *mv,
                         int v, int i, int j, double t_s, double *dx_um, double *dy_um)
{
    int ni, nj;
    *dx_um = *dy_um = NAN;
    if (v < 0 || v >= q->nv || i < 0 || i >= q->n || j < 0 || j >= q->n || !res->gx_um ||
        !res->ax_um || !sc_grid_mark_node(&q->plan, v, i, j, &ni, &nj))
        return;
    int node = ni * q->stage_nx + nj, k = i * q->n + j;
    double x, y, rax, ray, phi = mv[2] / (q->L_mm * 1e-3); /* µrad */
    sc_grid_node_xy_mm(&q->plan, ni, nj, &x, &y);
    sc_grid_rotate(q->plan.view[v].rot_deg, res->ax_um[k], res->ay_um[k], &rax, &ray);
    *dx_um = res->gx_um[node] + rax + mv[0] - phi * y * 1e-3;
    *dy_um = res->gy_um[node] + ray + mv[1] + phi * x * 1e-3;
    if (q->drift) {
        *dx_um += mv[3] / q->drift_T[v] * (t_s - q->drift_t0[v]);
        *dy_um += mv[4] / q->drift_T[v] * (t_s - q->drift_t0[v]);
    }
}

void sc_grid_lsq_predict_with(const sc_grid_lsq_plan *q, const sc_grid_result *res,
                              const double *m, int v, int i, int j, double t_s, double *dx_um,
                              double *dy_um)
{
    *dx_um = *dy_um = NAN;
    if (v >= 0 && v < q->nv)
        predict_view(q, res, m + (size_t)v * q->nb, v, i, j, t_s, dx_um, dy_um);
}

void sc_grid_lsq_predict(const sc_grid_lsq_plan *q, const sc_grid_result *res, int v, int i, int j,
                         double t_s, double *dx_um, double *dy_um)
{
    double mv[SC_GRID_LSQ_MAX_NB] = {0};
    *dx_um = *dy_um = NAN;
    if (v < 0 || v >= q->nv || !res->tx_um || !res->ty_um || !res->theta_urad ||
        (q->drift && (!res->vx_um_s || !res->vy_um_s)))
        return; /* no misalignments in res: nothing to predict with */
    mv[0] = res->tx_um[v], mv[1] = res->ty_um[v];
    mv[2] = res->theta_urad[v] * (q->L_mm * 1e-3);
    if (q->drift)
        mv[3] = res->vx_um_s[v] * q->drift_T[v], mv[4] = res->vy_um_s[v] * q->drift_T[v];
    predict_view(q, res, mv, v, i, j, t_s, dx_um, dy_um);
}
