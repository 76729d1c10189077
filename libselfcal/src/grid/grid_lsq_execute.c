/* Executing a least-squares plan on data (sc_grid_lsq_execute): the refined solve, the gauge of
 * the solution, the fit of each view's misalignment, the noise figures and the result. No
 * allocation: the plan holds the workspace. */
#include "grid_lsq_internal.h"

#include <math.h>
#include <string.h>

#include "selfcal/grid_sim.h"

static double eq_data(const sc_grid_lsq_plan *q, const sc_grid_data *d, long e)
{
    int v = q->eq_v[e], k = q->eq_k[e];
    return q->eq_c[e] ? d->dy_um[v][k] : d->dx_um[v][k];
}

/* s_e·d_e − w_e·x for equation e (the part of the equation the group's A must absorb). */
static double eq_misfit(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *x, long e)
{
    int idx[ROW_MAX];
    double val[ROW_MAX];
    int len = sc_lsq_eq_row(q, e, idx, val);
    double z = q->eq_s[e] * eq_data(q, d, e);
    for (int r = 0; r < len; ++r)
        z -= val[r] * x[idx[r]];
    return z;
}

/* r = b - S x evaluated from the equations themselves (not the assembled matrix, whose rounding
 * slightly moves the gauge null space): r = Σ_e w_e r_e (z_e - weighted group mean of z),
 * z_e = s_e d_e - r_e·x. Zero on pins. */
static void data_residual(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *x, double *r)
{
    int idx[ROW_MAX];
    double val[ROW_MAX];
    memset(r, 0, sizeof(double) * (size_t)q->n_red);
    for (int c = 0; c < 2 * q->nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        if (cnt < 2)
            continue;
        double mean = 0, W = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            mean += q->eq_w[e] * eq_misfit(q, d, x, e);
            W += q->eq_w[e];
        }
        mean /= W;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            double z = q->eq_w[e] * (eq_misfit(q, d, x, e) - mean);
            int len = sc_lsq_eq_row(q, e, idx, val);
            for (int k = 0; k < len; ++k)
                r[idx[k]] += val[k] * z;
        }
    }
    for (int i = 0; i < q->n_red; ++i)
        if (q->pinned[i])
            r[i] = 0;
}

sc_status sc_lsq_check_data(const sc_grid_lsq_plan *q, const sc_grid_data *d, sc_error *err)
{
    int n = q->n, nn = q->nn, nv = q->nv;
    if (d->plan.n != n || d->plan.n_views != nv ||
        sc_grid_stage_nx(&d->plan) != q->stage_nx || sc_grid_stage_ny(&d->plan) != q->stage_ny)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "data has N = %d and %d views, the estimator N = %d and %d views "
                            "(or the stages differ)",
                            d->plan.n, d->plan.n_views, n, nv);
    for (int v = 0; v < nv; ++v) {
        const sc_grid_view *a = &d->plan.view[v], *b = &q->plan.view[v];
        if (a->rot_deg != b->rot_deg || a->shift_x != b->shift_x || a->shift_y != b->shift_y)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "view %d of the data (rot %d shift %d,%d) differs from the "
                                "estimator's (rot %d shift %d,%d)",
                                v, a->rot_deg, a->shift_x, a->shift_y, b->rot_deg, b->shift_x,
                                b->shift_y);
        for (int k = 0; k < nn; ++k) {
            int fx = d->dx_um[v] && isfinite(d->dx_um[v][k]);
            int fy = d->dy_um[v] && isfinite(d->dy_um[v][k]);
            if (fx != fy || fx != q->meas[v * nn + k])
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "view %d mark (%d,%d): %s", v, k / n, k % n,
                                    fx != fy ? "only one of dx, dy is given"
                                    : fx    ? "measured, but the estimator was made without it"
                                            : "not measured, but the estimator expects it");
        }
    }
    if (!q->info.identifiable)
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0,
                            "the plan does not identify G (%ld free degrees of freedom)",
                            q->info.free_dof);
    return SC_OK;
}

/* G (x's first ng entries, interleaved) in the gauge, A as weighted group means moved with G's
 * magnification and gauged over the measured marks (translation, rotation). */
static void gauge_solution(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *x, double *gx,
                           double *gy, double *a)
{
    int n = q->n, nn = q->nn, ns = q->ns, stage_nx = q->stage_nx;
    for (int k = 0; k < ns; ++k) {
        gx[k] = x[2 * k];
        gy[k] = x[2 * k + 1];
    }
    double smag = 0, r2 = 0;
    for (int k = 0; k < ns; ++k) {
        double px, py;
        sc_grid_node_xy_mm(&q->plan, k / stage_nx, k % stage_nx, &px, &py);
        smag += px * gx[k] + py * gy[k];
        r2 += px * px + py * py;
    }
    double mu = smag / r2;
    for (int c = 0; c < 2 * nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        double s = 0, W = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            s += q->eq_w[e] * eq_misfit(q, d, x, e);
            W += q->eq_w[e];
        }
        a[c] = cnt > 0 ? s / W : NAN;
    }
    sc_grid_gauge_stage(&q->plan, gx, gy);
    double m3[9] = {0}, rhs[3] = {0};
    for (int k = 0; k < nn; ++k) {
        if (!q->mark_views[k])
            continue;
        double px, py;
        sc_grid_mark_xy_mm(&q->plan, k / n, k % n, &px, &py);
        a[2 * k] += mu * px;
        a[2 * k + 1] += mu * py;
        m3[0] += 1, m3[4] += 1, m3[2] -= py, m3[5] += px, m3[8] += px * px + py * py;
        rhs[0] += a[2 * k], rhs[1] += a[2 * k + 1], rhs[2] += px * a[2 * k + 1] - py * a[2 * k];
    }
    m3[6] = m3[2], m3[7] = m3[5];
    sc_lsq_small_solve(m3, rhs, 3);
    for (int k = 0; k < nn; ++k) {
        if (!q->mark_views[k] || !isfinite(rhs[0]))
            continue;
        double px, py;
        sc_grid_mark_xy_mm(&q->plan, k / n, k % n, &px, &py);
        a[2 * k] -= rhs[0] - rhs[2] * py;
        a[2 * k + 1] -= rhs[1] + rhs[2] * px;
    }
}

/* Misalignments (and drift): per view, weighted least squares of d - G - Rot A on its nb columns,
 * G as gx | gy (ns each), A's x and y of mark k at ax[k·as] and ay[k·as] (as: 2 for the solve's
 * interleaved A, 1 for a result's). m: nm, a particular solution where a view does not determine
 * its columns (fit_view; q->view_free says which). Uses q->fit_work (one plan, one thread). */
void sc_lsq_fit_misalignments(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *gx,
                              const double *gy, const double *ax, const double *ay, int as,
                              double *m)
{
    int nb = q->nb;
    double *nrm = q->fit_work, *rh = nrm + (size_t)q->nv * nb * nb;
    memset(nrm, 0, sizeof(double) * (size_t)q->nv * (nb * nb + nb));
    int idx[ROW_MAX];
    double val[ROW_MAX];
    for (long e = 0; e < q->neq; ++e) {
        int v = q->eq_v[e], len = sc_lsq_eq_row(q, e, idx, val), node = q->eq_g[e] / 2,
            k = q->eq_a[e] / 2;
        double w = q->eq_w[e], s = q->eq_s[e];
        double r = eq_data(q, d, e) - (q->eq_g[e] % 2 ? gy : gx)[node] -
                   s * (q->eq_a[e] % 2 ? ay : ax)[(size_t)k * as];
        for (int i = 1; i < len; ++i)
            rh[v * nb + idx[i] - q->ng - nb * v] += w * s * val[i] * r;
        sc_lsq_view_normal_add(q, e, idx, val, len, nrm);
    }
    for (int v = 0; v < q->nv; ++v)
        sc_lsq_fit_view(nrm + (size_t)v * nb * nb, rh + (size_t)v * nb, nb, m + v * nb);
}

/* The noise figures of res from the residual sums; the σ scale the uncertainties use. */
static double fill_result_noise(const sc_grid_lsq_plan *q, double wrss, double rss,
                                double sigma_r_um, sc_grid_result *res)
{
    long dof = q->neq - q->rank;
    double sigma0;
    res->n_measurements = q->neq;
    res->dof = dof;
    res->residual_rms_um = q->neq > 0 ? sqrt(rss / (double)q->neq) : NAN;
    res->weighted = q->weighted || sigma_r_um > 0;
    res->stated_u = q->weighted;
    res->variance_factor = res->chi2_lo = res->chi2_hi = NAN;
    res->chi2_pass = 1;
    if (q->weighted) {
        /* stated uncertainties: σ̂ is the factor on them; the uncertainties use them as stated */
        res->sigma_r_est_um = dof > 0 ? sqrt(wrss / (double)dof) : NAN;
        res->sigma_r_used_um = 1.0;
        sigma0 = 1.0;
        if (dof > 0)
            res->variance_factor = wrss / (double)dof;
    } else {
        res->sigma_r_est_um = dof > 0 ? sqrt(rss / (double)dof) : NAN;
        res->sigma_r_used_um = sigma_r_um > 0 ? sigma_r_um : res->sigma_r_est_um;
        sigma0 = res->sigma_r_used_um;
        if (sigma_r_um > 0 && dof > 0)
            res->variance_factor = rss / (double)dof / (sigma_r_um * sigma_r_um);
    }
    if (isfinite(res->variance_factor)) {
        res->chi2_lo = sc_chi2_quantile(0.025, (double)dof) / (double)dof;
        res->chi2_hi = sc_chi2_quantile(0.975, (double)dof) / (double)dof;
        res->chi2_pass = res->variance_factor >= res->chi2_lo && res->variance_factor <= res->chi2_hi;
    }
    return sigma0;
}

/* σ scale of the standardized residuals of a result: its σ0, or when the stated noise is too
 * small for the residuals (χ² test failed high) a posteriori (Pope's τ): data snooping with the
 * stated noise would flag nearly everything. */
double sc_lsq_residual_scale(const sc_grid_result *res)
{
    double s = res->sigma_r_used_um;
    if (isfinite(res->variance_factor) && res->variance_factor > res->chi2_hi)
        s *= sqrt(res->variance_factor);
    return s;
}

/* Residual of equation e: data − G − s·A − misalignment (and drift) terms; gv, av: the G and A
 * components the equation touches, m: the misalignment unknowns (nm). */
double sc_lsq_eq_residual(const sc_grid_lsq_plan *q, const sc_grid_data *d, long e, double gv,
                          double av, const double *m)
{
    int idx[ROW_MAX];
    double val[ROW_MAX], mis = 0;
    int len = sc_lsq_eq_row(q, e, idx, val);
    for (int t = 1; t < len; ++t)
        mis += q->eq_s[e] * val[t] * m[idx[t] - q->ng];
    if (!isfinite(mis))
        mis = 0;
    return eq_data(q, d, e) - gv - q->eq_s[e] * av - mis;
}

/* x := the pinned reduced solution for d: b − S·0 from the equations, then up to 3 refinement
 * steps against the equations, stopping after a step whose correction was at the level of the
 * residual's own rounding (‖dx‖∞ ≤ 1e-12‖x‖∞: measured 1e-14 relative after the first step at
 * N = 101 and 201, where the first corrects 1e-10; a further step only moves x by as much again);
 * r, b, r2: workspace (n_red each). */
static int solve_reduced(const sc_grid_lsq_plan *q, const sc_grid_data *d, double *x, double *r,
                         double *b, double *r2)
{
    int n_red = q->n_red;
    memset(x, 0, sizeof(double) * (size_t)n_red);
    data_residual(q, d, x, r);
    memcpy(x, r, sizeof(double) * (size_t)n_red);
    if (sc_lsq_pinned_solve(q, x, 1, 0, b, r2) != 0)
        return -1;
    for (int it = 0; it < 3; ++it) {
        data_residual(q, d, x, r);
        if (sc_lsq_pinned_solve(q, r, 1, 0, b, r2) != 0)
            return -1;
        double dx = 0, xm = 0;
        for (int i = 0; i < n_red; ++i) {
            x[i] += r[i];
            dx = fmax(dx, fabs(r[i]));
            xm = fmax(xm, fabs(x[i]));
        }
        /* converged: a step at rounding level; or the first step, when it corrected less than
         * 1e-8 of x: the error it leaves is then its own ratio times it, below the residual's
         * rounding floor (at N = 201 the first step corrects 2.6e-10, the second 7.6e-14: the
         * floor, noise rather than a gain), so a third solve would only move x within it */
        if (dx <= 1e-12 * xm || (it == 0 && dx <= 1e-8 * xm))
            break;
    }
    return 0;
}

/* Copy the solution (G as gx | gy, A interleaved, misalignments m) and the uncertainties the plan
 * computed (scaled by σ0) into res. */
static void fill_result_values(const sc_grid_lsq_plan *q, const double *g, const double *a,
                               const double *m, double sigma0, sc_grid_result *res)
{
    int nb = q->nb, ns = q->ns;
    const double *gx = g, *gy = g + ns;
    res->drift = q->drift;
    res->misalignment_unique = q->misalignment_unique;
    res->uO = sigma0 * sqrt(q->var_O);
    res->uR = sigma0 * sqrt(q->var_R);
#define PUT_VIEW(arr, v, val) do { if (res->arr) res->arr[v] = (val); } while (0)
    for (int v = 0; v < q->nv; ++v) { /* the per-view arrays the caller gave */
        const double *um = q->var_m + v * nb;
        double L = q->L_mm * 1e-3;
        PUT_VIEW(tx_um, v, m[v * nb]);
        PUT_VIEW(ty_um, v, m[v * nb + 1]);
        PUT_VIEW(theta_urad, v, m[v * nb + 2] / L);
        PUT_VIEW(vx_um_s, v, q->drift ? m[v * nb + 3] / q->drift_T[v] : NAN);
        PUT_VIEW(vy_um_s, v, q->drift ? m[v * nb + 4] / q->drift_T[v] : NAN);
        PUT_VIEW(utx_um, v, sigma0 * sqrt(um[0]));
        PUT_VIEW(uty_um, v, sigma0 * sqrt(um[1]));
        PUT_VIEW(utheta_urad, v, sigma0 * sqrt(um[2]) / L);
        PUT_VIEW(uvx_um_s, v, q->drift ? sigma0 * sqrt(um[3]) / q->drift_T[v] : NAN);
        PUT_VIEW(uvy_um_s, v, q->drift ? sigma0 * sqrt(um[4]) / q->drift_T[v] : NAN);
    }
#undef PUT_VIEW
    sc_grid_first_order(&q->plan, gx, gy, &res->O, &res->R);
    for (int k = 0; k < ns; ++k) {
        if (res->gx_um)
            res->gx_um[k] = gx[k];
        if (res->gy_um)
            res->gy_um[k] = gy[k];
        if (res->ugx_um)
            res->ugx_um[k] = sigma0 * q->sgx[k];
        if (res->ugy_um)
            res->ugy_um[k] = sigma0 * q->sgy[k];
    }
    for (int k = 0; k < q->nn; ++k) {
        if (res->ax_um)
            res->ax_um[k] = q->mark_views[k] ? a[2 * k] : NAN;
        if (res->ay_um)
            res->ay_um[k] = q->mark_views[k] ? a[2 * k + 1] : NAN;
    }
}

sc_status sc_grid_lsq_execute(const sc_grid_lsq_plan *q, const sc_grid_data *d, double sigma_r_um,
                              sc_grid_result *res, sc_error *err)
{
    int ns = q->ns;
    sc_status st = sc_lsq_check_data(q, d, err);
    if (st != SC_OK)
        return st;
    sc_lsq_progress(q, "solve", q->work_total);
    size_t n = (size_t)q->n_red;
    double *x = q->work, *r = x + n, *b = r + n, *r2 = b + n, *g = r2 + n, *a = g + q->ng;
    double *m = a + 2 * (size_t)q->nn;
    if (solve_reduced(q, d, x, r, b, r2) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (least-squares solve)");
    gauge_solution(q, d, x, g, g + ns, a);
    sc_lsq_fit_misalignments(q, d, g, g + ns, a, a + 1, 2, m);
    double rss = 0, wrss = 0;
    for (long e = 0; e < q->neq; ++e) {
        int c = q->eq_g[e] % 2, node = q->eq_g[e] / 2;
        double re = sc_lsq_eq_residual(q, d, e, g[c * ns + node], a[q->eq_a[e]], m);
        rss += re * re;
        wrss += q->eq_w[e] * re * re;
    }
    double sigma0 = fill_result_noise(q, wrss, rss, sigma_r_um, res);
    for (int v = 0; v < q->nv; ++v) /* reported only where the view determines them */
        for (int c = 0; q->view_free[v] && c < q->nb; ++c)
            m[v * q->nb + c] = NAN;
    fill_result_values(q, g, a, m, sigma0, res);
    return SC_OK;
}
