/* Each view's noise in a least-squares grid calibration (sc_grid_calibrate's
 * estimate_view_noise option; docs/grid.md): Förstner's variance components, iterated with an
 * accelerated fixed point, and how well they are determined (probes on the factored plan). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "grid_calibrate_common.h"
#include "grid_view_noise.h"
#include "grid_lsq_internal.h"
#include "selfcal/rng.h"

/* ---- each view's noise: Förstner's variance components ----
 * A view's weighted residual sum of squares has the expectation k_v·r_v, r_v = Σ(1 − h) over its
 * equations and k_v the factor its noise has on its current uncertainties; so k_v = wrss_v / r_v,
 * the uncertainties are multiplied by √k_v and the fit made again, until every k_v is 1 within
 * VCE_TOL. A view with less redundancy than VCE_MIN_RED is pooled with the other such views (or,
 * if they are too few together, takes the factor of all views). */
#define VCE_MIN_RED 3.0
#define VCE_TOL 1e-5
#define VCE_MAX_IT 30
#define VCE_COLLAPSE 1e-2 /* a view's σ below this fraction of the views' RMS: not separable */


/* Save d's uncertainties into vn if the noise per view is to be estimated (else nothing). */
sc_status sc_grid_view_noise_save(const sc_grid_data *d, int estimate, view_noise *vn,
                                 sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n;
    memset(vn, 0, sizeof *vn);
    if (!estimate)
        return SC_OK;
    if (!(vn->sigma_um = malloc(2 * (size_t)p->n_views * sizeof(double))))
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    vn->f = vn->sigma_um + p->n_views;
    vn->active = 1;
    int rows = 0;
    for (int v = 0; v < p->n_views; ++v) {
        vn->sigma_um[v] = p->view[v].sigma_um;
        vn->f[v] = 1;
        rows |= d->ux_um[v] != NULL;
    }
    if (rows && !(vn->u = malloc(2 * nn * (size_t)p->n_views * sizeof(double))))
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (int v = 0; rows && v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k) {
            vn->u[(2 * v) * nn + k] = d->ux_um[v] ? d->ux_um[v][k] : NAN;
            vn->u[(2 * v + 1) * nn + k] = d->uy_um[v] ? d->uy_um[v][k] : NAN;
        }
    return SC_OK;
}

/* d's uncertainties := as read times f, or with f NULL as read (a view that states none counts,
 * times f, as 1 µm: the unit weight of unweighted least squares, so that its factor is its
 * noise in µm). Nothing unless vn is active. */
static void view_noise_apply(sc_grid_data *d, const view_noise *vn, const double *f)
{
    sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n;
    for (int v = 0; vn->active && v < p->n_views; ++v) {
        double fv = f ? f[v] : 1.0;
        p->view[v].sigma_um = f ? (vn->sigma_um[v] > 0 ? vn->sigma_um[v] : 1.0) * fv
                                : vn->sigma_um[v];
        for (size_t k = 0; vn->u && k < nn; ++k) {
            if (d->ux_um[v])
                d->ux_um[v][k] = vn->u[(2 * v) * nn + k] * fv;
            if (d->uy_um[v])
                d->uy_um[v][k] = vn->u[(2 * v + 1) * nn + k] * fv;
        }
    }
}

/* d's uncertainties as read and vn's factors back to 1 (vn kept). */
void sc_grid_view_noise_as_read(sc_grid_data *d, view_noise *vn)
{
    for (int v = 0; vn->active && v < d->plan.n_views; ++v)
        vn->f[v] = 1;
    view_noise_apply(d, vn, NULL);
}

/* d's uncertainties as read; vn released. */
void sc_grid_view_noise_restore(sc_grid_data *d, view_noise *vn)
{
    view_noise_apply(d, vn, NULL);
    free(vn->u);
    free(vn->sigma_um);
    vn->u = vn->sigma_um = vn->f = NULL;
    vn->active = 0;
}

/* The factor k_v of every view from its components (pooling those with little redundancy). */
static void vce_factors(int nv, const double *wrss, const double *red, double *k)
{
    double w_all = 0, r_all = 0, w_low = 0, r_low = 0;
    for (int v = 0; v < nv; ++v) {
        w_all += wrss[v], r_all += red[v];
        if (red[v] < VCE_MIN_RED)
            w_low += wrss[v], r_low += red[v];
    }
    double k_all = r_all > 0 ? w_all / r_all : 1.0;
    double k_low = r_low >= VCE_MIN_RED ? w_low / r_low : k_all;
    for (int v = 0; v < nv; ++v)
        k[v] = red[v] >= VCE_MIN_RED ? wrss[v] / red[v] : k_low;
}

/* a (n x n, row stride lda, lower triangle read) := its Cholesky factor L in the lower triangle;
 * 0 if a is not positive definite. n is a number of view groups (n³/6 flops, small next to the
 * probes' solves): by hand, as the library links no LAPACK. */
static int chol_small(int n, double *a, int lda)
{
    for (int i = 0; i < n; ++i)
        for (int j = 0; j <= i; ++j) {
            double t = a[i * lda + j];
            for (int k = 0; k < j; ++k)
                t -= a[i * lda + k] * a[j * lda + k];
            if (j < i)
                a[i * lda + j] = t / a[j * lda + j];
            else if (t > 0)
                a[i * lda + i] = sqrt(t);
            else
                return 0;
        }
    return 1;
}

/* The plain iteration, log f += ½ log k, converges linearly, slowly where the views share
 * their redundancy (every mark seen in three views: 7 % per step measured on Ye's plan). Anderson
 * acceleration (Walker & Ni 2011) on x = log f with the last VCE_HIST steps settles it in a few
 * solves; a step that makes the change larger than the last one's restarts the history. */
#define VCE_HIST 5
typedef struct vce_accel {
    int nv, nh;                               /* views, steps in the history */
    double *px, *pg;                          /* the last x and its g = ½ log k (nv each) */
    double *dx[VCE_HIST], *dg[VCE_HIST];      /* the history (nv each) */
    double *x, *g;                            /* a step's own x and g (nv each) */
    double *block;                            /* all of them: (4 + 2 VCE_HIST) nv doubles */
    double last_norm;                         /* |g| of the last step (-1: none yet) */
} vce_accel;

static sc_status vce_accel_init(vce_accel *a, int nv, sc_error *err)
{
    memset(a, 0, sizeof *a);
    a->nv = nv;
    a->last_norm = -1;
    size_t n = (size_t)nv;
    if (!(a->block = calloc((4 + 2 * VCE_HIST) * n, sizeof(double))))
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    a->px = a->block, a->pg = a->block + n, a->x = a->block + 2 * n, a->g = a->block + 3 * n;
    for (int h = 0; h < VCE_HIST; ++h)
        a->dx[h] = a->block + (4 + 2 * (size_t)h) * n, a->dg[h] = a->dx[h] + n;
    return SC_OK;
}

static void vce_accel_free(vce_accel *a)
{
    free(a->block);
    a->block = NULL;
}

/* f := the next factors from the current f and its k (k_v = 1 at the fixed point). */
static void vce_accel_step(vce_accel *a, double *f, const double *k)
{
    int nv = a->nv;
    double *x = a->x, *g = a->g, norm = 0;
    for (int v = 0; v < nv; ++v) {
        x[v] = log(f[v]), g[v] = 0.5 * log(k[v]);
        norm += g[v] * g[v];
    }
    if (a->last_norm >= 0 && norm > a->last_norm)
        a->nh = 0; /* worse than before: start again from the plain step */
    else if (a->last_norm >= 0) { /* the newest difference into the history */
        if (a->nh == VCE_HIST) { /* the oldest out: rotate the rows' pointers */
            double *ox = a->dx[0], *og = a->dg[0];
            memmove(a->dx, a->dx + 1, sizeof a->dx[0] * (VCE_HIST - 1));
            memmove(a->dg, a->dg + 1, sizeof a->dg[0] * (VCE_HIST - 1));
            a->dx[VCE_HIST - 1] = ox, a->dg[VCE_HIST - 1] = og;
            a->nh--;
        }
        for (int v = 0; v < nv; ++v)
            a->dx[a->nh][v] = x[v] - a->px[v], a->dg[a->nh][v] = g[v] - a->pg[v];
        a->nh++;
    }
    memcpy(a->px, x, sizeof *x * (size_t)nv);
    memcpy(a->pg, g, sizeof *g * (size_t)nv);
    a->last_norm = norm;
    /* γ = argmin |g − ΔG γ| by the normal equations (m ≤ VCE_HIST, Cholesky with a tiny ridge);
     * x += g − (ΔX + ΔG) γ */
    int m = a->nh;
    double A[VCE_HIST][VCE_HIST], b[VCE_HIST], gam[VCE_HIST];
    for (int i = 0; i < m; ++i) {
        b[i] = 0;
        for (int v = 0; v < nv; ++v)
            b[i] += a->dg[i][v] * g[v];
        for (int j = 0; j <= i; ++j) {
            double t = 0;
            for (int v = 0; v < nv; ++v)
                t += a->dg[i][v] * a->dg[j][v];
            A[i][j] = A[j][i] = t;
        }
    }
    double tr = 0;
    for (int i = 0; i < m; ++i)
        tr += A[i][i];
    for (int i = 0; i < m; ++i)
        A[i][i] += 1e-12 * tr + 1e-300;
    int ok = chol_small(m, &A[0][0], VCE_HIST); /* in place: A = L Lᵀ */
    for (int i = 0; i < m && ok; ++i) { /* L y = b, Lᵀ γ = y */
        double t = b[i];
        for (int q = 0; q < i; ++q)
            t -= A[i][q] * gam[q];
        gam[i] = t / A[i][i];
    }
    for (int i = m - 1; i >= 0 && ok; --i) {
        double t = gam[i];
        for (int q = i + 1; q < m; ++q)
            t -= A[q][i] * gam[q];
        gam[i] = t / A[i][i];
    }
    if (!ok)
        m = a->nh = 0;
    for (int v = 0; v < nv; ++v) {
        double extra = 0; /* the extrapolation beyond the plain step, at most a factor e */
        for (int i = 0; i < m; ++i)
            extra -= (a->dx[i][v] + a->dg[i][v]) * gam[i];
        extra = isfinite(extra) ? fmax(-1.0, fmin(1.0, extra)) : 0.0;
        f[v] = exp(x[v] + g[v] + extra);
    }
}

/* d's uncertainties back to vn's start (as read), *qp and s->res the fit with them. */
static sc_status view_noise_reset(sc_grid_data *d, const sc_grid_options *o, view_noise *vn,
                                  sc_grid_solution *s, sc_grid_lsq_plan **qp, sc_error *err)
{
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    sc_grid_view_noise_as_read(d, vn);
    sc_grid_lsq_plan_destroy(*qp);
    *qp = NULL;
    sc_status st = sc_grid_lsq_plan_create(&d->plan, d, &opts, qp, err);
    if (st == SC_OK)
        st = sc_grid_lsq_execute(*qp, d, 0, &s->res, err);
    return st;
}

/* How well the estimates are determined. At the fixed point (every view's weights its estimated
 * noise, normalized θ_v = 1) E[wrss_u] = Σ_v θ_v F_uv with F_uv = Σ_{e∈u, f∈v} R_ef², R = I − H the
 * weighted residual projector; under normal noise Cov(wrss) = 2F, so Cov(θ̂) = 2F⁻¹ and a σ̂_v
 * (= √θ_v) has the relative standard deviation √((F⁻¹)_vv / 2) — 1/√(2 r_v) for a view whose
 * redundancy is its own, far more where views trade their noise. F's column v is
 * E[Σ_{e∈u} w_e r_e²] over residuals r of random ±u data on view v alone (Rademacher probes,
 * VCE_PROBES per view: a few % on F at these sizes): nv·VCE_PROBES solves on the factored plan.
 * Pooled views share one θ: their rows and columns of F are summed. rel_sd: per view; NaN where
 * F is not positive definite. */
#define VCE_PROBES 8

/* The group of every view in F (grp[v]: its own when its redundancy red[v] is at least
 * VCE_MIN_RED, else the one pooled group; -1 for a declared view with no rows); returns the
 * number of groups. rel_sd := NaN. */
static int spread_groups(const sc_grid_data *d, const double *red, int *grp, double *rel_sd)
{
    const sc_grid_plan *p = &d->plan;
    int nv = p->n_views, nn = p->n * p->n, ng = 0, low = -1;
    for (int v = 0; v < nv; ++v) {
        rel_sd[v] = NAN;
        int rows = 0; /* a declared view with no rows has no component: left out of F */
        for (int k = 0; k < nn && !rows; ++k)
            rows = isfinite(d->dx_um[v][k]);
        if (!rows)
            grp[v] = -1;
        else if (red[v] >= VCE_MIN_RED)
            grp[v] = ng++;
        else
            grp[v] = low >= 0 ? low : (low = ng++);
    }
    return ng;
}

/* d's data := one Rademacher probe on view v (±u at its measured marks, 1 where it states no
 * u), 0 on the other views' measured marks (save: d's values, dx then dy). */
static void spread_probe(sc_grid_data *d, const double *save, int v, sc_rng *rng)
{
    const sc_grid_plan *p = &d->plan;
    int nv = p->n_views, nn = p->n * p->n;
    for (int w = 0; w < nv; ++w)
        for (int k = 0; k < nn; ++k) {
            if (!isfinite(save[w * nn + k]))
                continue;
            double ux = sc_grid_data_u_um(d, w, k, 0), uy = sc_grid_data_u_um(d, w, k, 1);
            int on = w == v;
            d->dx_um[w][k] = on ? (sc_rng_u64(rng) & 1 ? 1 : -1) * (ux > 0 ? ux : 1) : 0;
            d->dy_um[w][k] = on ? (sc_rng_u64(rng) & 1 ? 1 : -1) * (uy > 0 ? uy : 1) : 0;
        }
}

/* F's columns by the probes (F: ng groups, row stride nv; wrss, rd, u2: nv scratch each): the
 * probes' solves on q overwrite d's values, which are restored before the return. */
static sc_status spread_probes(sc_grid_data *d, sc_grid_lsq_plan *q, const int *grp, double *F,
                               double *wrss, double *rd, double *u2, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    int nv = p->n_views, nn = p->n * p->n;
    long ns = sc_grid_stage_nodes(p);
    size_t nvz = (size_t)nv, tot = (size_t)nv * nn;
    double *buf = malloc(sizeof(double) * (2 * tot + 4 * (size_t)ns + 2 * (size_t)nn));
    if (!buf)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    double *save = buf, *o = buf + 2 * tot;
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k)
            save[v * nn + k] = d->dx_um[v][k], save[tot + v * nn + k] = d->dy_um[v][k];
    sc_grid_result res = {0};
    res.gx_um = o, res.gy_um = o + ns, res.ugx_um = o + 2 * ns, res.ugy_um = o + 3 * ns;
    res.ax_um = o + 4 * ns, res.ay_um = o + 4 * ns + nn;
    sc_status st = sc_grid_result_views(&res, nv, err);
    sc_rng rng;
    sc_rng_seed(&rng, 20261127); /* the same probes every run: reproducible figures */
    for (int v = 0; v < nv && st == SC_OK; ++v)
        for (int t = 0; grp[v] >= 0 && t < VCE_PROBES && st == SC_OK; ++t) {
            spread_probe(d, save, v, &rng);
            st = sc_grid_lsq_execute(q, d, 0, &res, err);
            if (st == SC_OK)
                st = sc_grid_lsq_view_components(q, d, &res, wrss, rd, u2, err);
            for (int u = 0; u < nv && st == SC_OK; ++u)
                if (grp[u] >= 0)
                    F[(size_t)grp[u] * nvz + (size_t)grp[v]] += wrss[u] / VCE_PROBES;
        }
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k)
            d->dx_um[v][k] = save[v * nn + k], d->dy_um[v][k] = save[tot + v * nn + k];
    free(buf);
    sc_grid_result_free_views(&res);
    return st;
}

/* inv_diag[g] := (F⁻¹)_gg for the ng groups by Cholesky of the symmetrized F (its two
 * estimates of F_uv averaged), in place (row stride lda; the lower triangle becomes L); y:
 * scratch of ng. Returns 0 when F is not positive definite. */
static int spread_inverse_diag(int ng, double *F, int lda, double *y, double *inv_diag)
{
    size_t nvz = (size_t)lda;
    double *L = F;
    for (int i = 0; i < ng; ++i)
        for (int j = 0; j < i; ++j)
            L[(size_t)i * nvz + j] = 0.5 * (F[(size_t)i * nvz + j] + F[(size_t)j * nvz + i]);
    if (!chol_small(ng, L, lda))
        return 0;
    for (int g = 0; g < ng; ++g) { /* column g of L⁻¹: (F⁻¹)_gg = Σ_i (L⁻¹)_ig² */
        double sum = 0;
        for (int i = g; i < ng; ++i) {
            double t = i == g ? 1.0 : 0.0;
            for (int k = g; k < i; ++k)
                t -= L[(size_t)i * nvz + k] * y[k];
            y[i] = t / L[(size_t)i * nvz + i];
            sum += y[i] * y[i];
        }
        inv_diag[g] = sum;
    }
    return 1;
}

/* rel_sd: the relative standard deviation of every view's σ estimate (the method above), from
 * the probes' F; red: the views' redundancies. */
static sc_status view_noise_spread(sc_grid_data *d, sc_grid_lsq_plan *q, const double *red,
                                   double *rel_sd, sc_error *err)
{
    int nv = d->plan.n_views;
    /* per view: its group, the components; F (ng x ng, ng <= nv: dense, as Cov(θ̂) = 2F⁻¹ is) */
    size_t nvz = (size_t)nv;
    double *vbuf = calloc(nvz * nvz + 5 * nvz, sizeof(double));
    int *grp = malloc(nvz * sizeof *grp);
    if (!vbuf || !grp) {
        free(vbuf), free(grp);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    double *F = vbuf, *wrss = F + nvz * nvz, *rd = wrss + nvz, *u2 = rd + nvz;
    double *inv_diag = u2 + nvz, *y = inv_diag + nvz;
    int ng = spread_groups(d, red, grp, rel_sd);
    sc_status st = spread_probes(d, q, grp, F, wrss, rd, u2, err);
    if (st == SC_OK && spread_inverse_diag(ng, F, nv, y, inv_diag)) /* else NaN */
        for (int v = 0; v < nv; ++v)
            rel_sd[v] = grp[v] >= 0 ? sqrt(inv_diag[grp[v]] / 2) : NAN;
    free(vbuf), free(grp);
    return st;
}

/* Re-weight the views by their estimated noise and solve again until it settles; *qp and s->res
 * are then the fit with the estimated weights. When it cannot settle in VCE_MAX_IT solves, runs
 * to zero for a view, or the residuals are at the rounding level (noise-free data), the weights
 * as read are kept (and fitted), with a warning. */
static sc_status estimate_view_noise_loop(sc_grid_data *d, const sc_grid_file_info *info,
                                          const sc_grid_options *o, view_noise *vn,
                                          sc_grid_solution *s, sc_grid_lsq_plan **qp,
                                          const char *src, vce_accel *acc, double *wrss,
                                          double *red, double *u2, double *k, double *rel_sd,
                                          sc_error *err);

sc_status sc_grid_estimate_view_noise(sc_grid_data *d, const sc_grid_file_info *info,
                                     const sc_grid_options *o, view_noise *vn,
                                     sc_grid_solution *s, sc_grid_lsq_plan **qp, const char *src,
                                     sc_error *err)
{
    int nv = d->plan.n_views;
    double *wrss = malloc(5 * (size_t)nv * sizeof(double));
    if (!wrss)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    double *red = wrss + nv, *u2 = red + nv, *k = u2 + nv, *rel_sd = k + nv;
    vce_accel acc;
    sc_status st = vce_accel_init(&acc, nv, err);
    if (st == SC_OK)
        st = estimate_view_noise_loop(d, info, o, vn, s, qp, src, &acc, wrss, red, u2, k, rel_sd,
                                      err);
    vce_accel_free(&acc);
    free(wrss);
    return st;
}

/* estimate_view_noise's iteration and outcome, with its per-view arrays (nv each). */
static sc_status estimate_view_noise_loop(sc_grid_data *d, const sc_grid_file_info *info,
                                          const sc_grid_options *o, view_noise *vn,
                                          sc_grid_solution *s, sc_grid_lsq_plan **qp,
                                          const char *src, vce_accel *acc, double *wrss,
                                          double *red, double *u2, double *k, double *rel_sd,
                                          sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    int nv = p->n_views, it = 0;
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    for (;; ++it) {
        sc_status st = sc_grid_lsq_view_components(*qp, d, &s->res, wrss, red, u2, err);
        if (st != SC_OK)
            return st;
        vce_factors(nv, wrss, red, k);
        double worst = 0, s2_all = 0, n_all = 0;
        for (int v = 0; v < nv; ++v)
            if (isfinite(u2[v]))
                s2_all += k[v] * u2[v], n_all += 1;
        s2_all /= n_all > 0 ? n_all : 1; /* the views' mean variance */
        for (int v = 0; v < nv; ++v) {
            if (!isfinite(u2[v]))
                continue;
            if (!(k[v] * u2[v] >= NOISE_FLOOR_UM * NOISE_FLOOR_UM)) {
                sc_grid_warnf(o, "%s: the residuals of view %d are at the rounding level: the "
                                 "noise per view is not estimated (the weights stay as stated)",
                      src, sc_grid_view_id(info, v));
                return it ? view_noise_reset(d, o, vn, s, qp, err) : SC_OK;
            }
            /* a view whose estimate runs to zero against the others' is not separable from
             * them by these views (its equations become the ones the fit must pass through):
             * Förstner's estimator has no answer there */
            if (!(k[v] * u2[v] >= VCE_COLLAPSE * VCE_COLLAPSE * s2_all)) {
                sc_grid_warnf(o, "%s: the noise of view %d runs to zero against the other views' "
                                 "(not separable by this plan, or an outlier elsewhere): the noise "
                                 "per view is not estimated (the weights stay as stated)",
                      src, sc_grid_view_id(info, v));
                return view_noise_reset(d, o, vn, s, qp, err);
            }
            worst = fmax(worst, fabs(k[v] - 1));
        }
        if (worst < VCE_TOL)
            break;
        if (it >= VCE_MAX_IT) {
            sc_grid_warnf(o, "%s: the noise per view did not settle in %d re-weighted solves (its "
                             "factors still change by %.2g): not estimated (the weights stay as "
                             "stated)",
                  src, VCE_MAX_IT, worst);
            return view_noise_reset(d, o, vn, s, qp, err);
        }
        vce_accel_step(acc, vn->f, k);
        view_noise_apply(d, vn, vn->f);
        sc_grid_lsq_plan_destroy(*qp);
        *qp = NULL;
        st = sc_grid_lsq_plan_create(p, d, &opts, qp, err);
        if (st == SC_OK)
            st = sc_grid_lsq_execute(*qp, d, 0, &s->res, err);
        if (st != SC_OK)
            return st;
    }
    sc_status st = view_noise_spread(d, *qp, red, rel_sd, err);
    if (st != SC_OK)
        return st;
    /* the probes' solves wrote into the plan's workspace only; s->res is the fit's */
    sc_grid_result *r = &s->res;
    r->view_noise_estimated = 1;
    r->view_noise_iterations = it;
    for (int v = 0; v < nv; ++v) {
        r->view_sigma_um[v] = sqrt(k[v] * u2[v]);
        r->view_sigma_u_um[v] = r->view_sigma_um[v] * rel_sd[v];
        int stated = vn->sigma_um[v] > 0 || d->ux_um[v] || d->uy_um[v];
        r->view_noise_factor[v] = stated ? vn->f[v] * sqrt(k[v]) : NAN;
    }
    /* the variance factor is 1 by construction: no test of the noise is left */
    r->chi2_lo = r->chi2_hi = NAN;
    r->chi2_pass = 1;
    return SC_OK;
}
