/* profile_calibrate.c — owns the end-to-end straightness calibration (selfcal/profile_calibrate.h):
 * noise precedence, scan weights, the method's plan, the residual noise estimate, uncertainties
 * (analytic or Monte Carlo) and e_y, whole or in two steps (the plan from the header, then the
 * run on the data), and the reading of a file with the plan made on a thread of its own while
 * the rows are read. The command line and the Python package call only this. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/profile_calibrate.h"
#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS */
#include "../common/big_alloc.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"
#include "../linalg/stats.h" /* sc_chi2_quantile, sc_grid_outlier_critical: the same tests as grids */
#include "profile_lsq_tuning.h"
#include "profile_rig.h"

void sc_profile_options_default(sc_profile_options *o)
{
    o->method = SC_PROFILE_LSQ;
    o->sigma_disp_um = NAN;
    o->sigma_angle_urad = NAN;
    o->mc_trials = 0;
    o->mc_seed = 1;
    o->progress = NULL;
    o->progress_ctx = NULL;
    o->residual_check = 1;
    o->drift = 0;
    o->reject_outliers = 0;
    o->want_residuals = 0;
}

typedef struct solver_ctx {
    sc_profile_method method;
    sc_profile_dft_plan *dft;
    sc_profile_lsq_plan *lsq;
    sc_rig_plan *rig; /* the rig solver's plan of this run (it wins when set) */
} solver_ctx;

static sc_status solve_cb(void *vctx, const double *y1, const double *y2, double *f, sc_error *err)
{
    solver_ctx *c = vctx;
    if (c->rig)
        return sc_rig_solve(c->rig, y1, y2, f, NULL, NULL, err);
    if (c->method == SC_PROFILE_DFT)
        return sc_profile_dft_execute(c->dft, y1, y2, f, err);
    return sc_profile_lsq_execute(c->lsq, y1, y2, f, NULL, NULL, err);
}

/* The noise of the scans: options > header > unknown. Sets s's noise fields and the variances
 * of y1, y2 (1, 1 when unknown: only the ratio of the weights matters then). */
static void choose_noise(const sc_profile_data *d, const sc_profile_options *o,
                         sc_profile_solution *s, double var[2])
{
    double sd = o->sigma_disp_um, sa = o->sigma_angle_urad;
    int have_sd = !isnan(sd) || d->has_sigma_disp, have_sa = !isnan(sa) || d->has_sigma_angle;
    if (isnan(sd))
        sd = d->has_sigma_disp ? d->sigma_disp_um : 0.0;
    if (isnan(sa))
        sa = d->has_sigma_angle ? d->sigma_angle_urad : 0.0;
    s->noise_known = have_sd || have_sa;
    s->sigma_disp_um = s->noise_known ? sd : NAN;
    s->sigma_angle_urad = s->noise_known ? sa : NAN;
    var[0] = var[1] = 1.0;
    if (s->noise_known) {
        var[0] = sc_profile_y_variance(d->d[0], d->s_mm, sd, sa);
        var[1] = sc_profile_y_variance(d->d[1], d->s_mm, sd, sa);
    }
}

/* Uncertainties of every point into uf (scaled by `scale`): Monte Carlo or the method's formula. */
static sc_status uncertainty(const sc_profile_data *d, const sc_profile_options *o, solver_ctx *ctx,
                             const double var[2], double scale, double *uf, sc_error *err)
{
    sc_status st;
    if (o->mc_trials > 0)
        st = sc_profile_mc_uncertainty(d->n, d->d[0], d->d[1], sqrt(var[0]), sqrt(var[1]), solve_cb,
                                       ctx, o->mc_trials, o->mc_seed, o->progress, o->progress_ctx,
                                       uf, err);
    else if (ctx->rig)
        st = sc_rig_uncertainty(ctx->rig, uf, err);
    else if (o->method == SC_PROFILE_DFT)
        st = sc_profile_dft_uncertainty(ctx->dft, uf, NULL, err);
    else
        st = sc_profile_lsq_uncertainty(ctx->lsq, uf, NULL, err);
    if (st == SC_OK)
        for (int i = 0; i < d->n; ++i)
            uf[i] *= scale;
    return st;
}

/* The residual noise always comes from the least-squares fit: the DFT estimate is not the
 * least-squares one, and its residuals overstate the noise. The DFT method pays for that extra
 * least-squares solve only when the noise must be estimated, or when the caller wants the
 * residual ratio of given noise (residual_check). */
static sc_status residuals(const sc_profile_data *d, solver_ctx *ctx, const double *y1,
                           const double *y2, const double *f, const double w[2], double *tmp,
                           int residual_check, sc_profile_solution *s, sc_error *err)
{
    const int n = d->n, d1 = d->d[0], d2 = d->d[1];
    const double *fres = f;
    sc_profile_lsq_plan *lres = NULL;
    if (ctx->method == SC_PROFILE_DFT && s->noise_known && !residual_check) {
        s->wrss = NAN;
        s->dof = n - d1 - d2;
        return SC_OK;
    }
    if (ctx->method == SC_PROFILE_DFT) {
        sc_status st = sc_profile_lsq_plan_create(n, d1, d2, w[0], w[1], &lres, err);
        if (st == SC_OK)
            st = sc_profile_lsq_execute(lres, y1, y2, tmp, NULL, NULL, err);
        sc_profile_lsq_plan_destroy(lres);
        if (st != SC_OK)
            return st;
        fres = tmp;
    }
    s->wrss = sc_profile_residual_ss(n, d1, d2, y1, y2, fres, w[0], w[1], &s->dof);
    return SC_OK;
}

/* What sc_profile_calibration_create decides from the header alone. */
struct sc_profile_calibration {
    sc_profile_options o;
    int n, d1, d2;
    double s_mm;
    int noise_known, zero_noise;
    double sigma_disp_um, sigma_angle_urad, var[2], w[2];
    solver_ctx ctx;
};

/* The options as profile_calibrate.h states them: a known method, noise NaN (not given) or
 * >= 0 and finite, analytic (0) or Monte Carlo (>= 2), drift 0..2 and only with lsq. */
static sc_status check_options(const sc_profile_options *o, sc_error *err)
{
    if (o->method != SC_PROFILE_DFT && o->method != SC_PROFILE_LSQ)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "unknown method %d", (int)o->method);
    if (!isnan(o->sigma_disp_um) && !(o->sigma_disp_um >= 0 && o->sigma_disp_um <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "sigma_disp_um must be >= 0 and finite (NaN: not given), got %g",
                            o->sigma_disp_um);
    if (!isnan(o->sigma_angle_urad) &&
        !(o->sigma_angle_urad >= 0 && o->sigma_angle_urad <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "sigma_angle_urad must be >= 0 and finite (NaN: not given), got %g",
                            o->sigma_angle_urad);
    if (o->mc_trials < 0 || o->mc_trials == 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "mc_trials must be 0 (analytic) or at least 2, got %ld", o->mc_trials);
    if (o->drift < 0 || o->drift > 2)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "drift must be 0, 1 or 2, got %d", o->drift);
    if (o->method == SC_PROFILE_DFT && (o->drift || o->reject_outliers || o->want_residuals))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "drift terms, residuals and outlier rejection need --method lsq");
    return SC_OK;
}

/* The noise and the scan weights of calibration c from the header and the options. */
static void set_noise(sc_profile_calibration *c, const sc_profile_data *hdr,
                      const sc_profile_options *o)
{
    sc_profile_solution noise;
    choose_noise(hdr, o, &noise, c->var);
    c->noise_known = noise.noise_known;
    c->sigma_disp_um = noise.sigma_disp_um;
    c->sigma_angle_urad = noise.sigma_angle_urad;
    c->zero_noise = c->noise_known && !(c->var[0] > 0 && c->var[1] > 0);
    if (c->zero_noise)
        c->var[0] = c->var[1] = 1; /* the weights are then arbitrary; uncertainties 0 */
    c->w[0] = 1.0 / c->var[0];
    c->w[1] = 1.0 / c->var[1];
}

sc_status sc_profile_calibration_create(const sc_profile_data *hdr, const sc_profile_options *o,
                                        sc_profile_calibration **out, sc_error *err)
{
    *out = NULL;
    sc_status st = check_options(o, err);
    if (st == SC_OK)
        st = sc_profile_check_method(hdr, o->method, err);
    if (st != SC_OK)
        return st;
    sc_profile_calibration *c = calloc(1, sizeof *c);
    if (!c)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    c->o = *o;
    c->n = hdr->n, c->d1 = hdr->d[0], c->d2 = hdr->d[1], c->s_mm = hdr->s_mm;
    set_noise(c, hdr, o);
    c->ctx.method = o->method;
    if (o->method == SC_PROFILE_DFT)
        st = sc_profile_dft_plan_create(c->n, c->d1, c->d2, c->w[0], c->w[1], &c->ctx.dft, err);
    else if (o->drift || o->reject_outliers || o->want_residuals)
        st = SC_OK; /* the rig solver's plan is made with the data (profile_rig.h) */
    else /* every point's uncertainty follows: start the selected inversion on a second core */
        st = sc_profile_lsq_plan_create_tuned(c->n, c->d1, c->d2, c->w[0], c->w[1],
                                              SC_PROFILE_LSQ_EARLY_UNCERTAINTY, &c->ctx.lsq, err);
    if (st != SC_OK) {
        sc_profile_calibration_destroy(c);
        return st;
    }
    *out = c;
    return SC_OK;
}

void sc_profile_calibration_destroy(sc_profile_calibration *c)
{
    if (!c)
        return;
    sc_profile_dft_plan_destroy(c->ctx.dft);
    sc_profile_lsq_plan_destroy(c->ctx.lsq);
    free(c);
}

/* The DFT method needs complete scans: the first gap named, at its scan's header line. */
static sc_status refuse_gaps(const sc_profile_data *d, const double *y1, const double *y2,
                             sc_error *err)
{
    const double *y[2] = {y1, y2};
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < d->n - d->d[k]; ++j)
            if (isnan(y[k][j])) {
                int e = j;
                while (e + 1 < d->n - d->d[k] && isnan(y[k][e + 1]))
                    ++e;
                return sc_error_set(err, SC_E_INPUT, d->path[0] ? d->path : NULL,
                                    d->line_scan[k],
                                    "scan %d has no complete sample for n = %d..%d: the dft "
                                    "method needs complete scans; --method lsq solves around "
                                    "gaps", k + 1, j, e);
            }
    return SC_OK;
}

/* The noise scale from the residuals and the χ² test of a stated noise (s's fields); returns
 * the factor on the plan's unit uncertainties. */
static double noise_scale(const sc_profile_calibration *c, sc_profile_solution *s)
{
    double scale = 1.0;
    s->have_uf = 1;
    s->residual_ratio = NAN;
    s->chi2_lo = s->chi2_hi = NAN;
    s->chi2_pass = 1;
    s->u_scaled = 0;
    if (c->zero_noise)
        return 0.0;
    if (!s->noise_known && s->dof <= 0)
        s->have_uf = 0; /* no redundancy: the noise is not estimable */
    else if (!s->noise_known)
        scale = sqrt(s->wrss / s->dof);
    else if (s->dof > 0 && !isnan(s->wrss)) {
        double vf = s->wrss / s->dof;
        s->residual_ratio = sqrt(vf);
        s->chi2_lo = sc_chi2_quantile(0.025, s->dof) / s->dof;
        s->chi2_hi = sc_chi2_quantile(0.975, s->dof) / s->dof;
        s->chi2_pass = vf >= s->chi2_lo && vf <= s->chi2_hi;
        if (vf > s->chi2_hi) /* the stated noise is too small for the residuals: a posteriori */
            scale = sqrt(vf), s->u_scaled = 1;
    }
    return scale;
}

/* The residuals of every row against the solution f, q of the plan in ctx, standardized with
 * the scans' σ (sigma[k]); the rows flagged by data snooping (outlier 1; rows out of the fit
 * keep their mark). Returns the worst flagged row in the fit (as k·N + j) or -1. */
static long residual_test(const sc_rig_plan *rig, const sc_profile_data *d, const double *y[2],
                          const double *f, const double *q, const double sigma[2],
                          sc_profile_solution *s)
{
    long tested = 0, worst = -1;
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < d->n - d->d[k]; ++j) {
            double r = NAN, t = NAN, h = sc_rig_leverage(rig, k, j);
            if (isfinite(y[k][j]) && isfinite(h)) {
                r = y[k][j] - sc_rig_predict(rig, k, j, f, q);
                int in = sc_rig_row_used(rig, k, j);
                double v = in ? 1 - h : 1 + h;
                if (v > 1e-9 && sigma[k] > 0)
                    t = r / (sigma[k] * sqrt(v));
                tested += in && isfinite(t);
            }
            s->r_um[k][j] = r;
            s->t[k][j] = t;
        }
    s->outlier_crit = tested > 0 ? sc_grid_outlier_critical(SC_GRID_OUTLIER_ALPHA, tested, 0) : NAN;
    s->n_flagged = 0;
    double tmax = 0;
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < d->n - d->d[k]; ++j) {
            if (s->outlier[k][j] == 2)
                continue;
            int flag = isfinite(s->t[k][j]) && fabs(s->t[k][j]) > s->outlier_crit;
            s->outlier[k][j] = (unsigned char)flag;
            s->n_flagged += flag;
            if (flag && fabs(s->t[k][j]) > tmax)
                tmax = fabs(s->t[k][j]), worst = (long)k * d->n + j;
        }
    return worst;
}

/* What the drift terms cost: the RMS unit uncertainty with them (uf) over the one without
 * them, on the same rows. */
static sc_status drift_cost(const sc_profile_calibration *c, const sc_profile_data *d,
                            const unsigned char *const use[2], const double *uf,
                            sc_profile_solution *s, sc_error *err)
{
    const int n = d->n;
    sc_rig_plan *p0 = NULL;
    double *u0 = malloc((size_t)n * sizeof(double));
    sc_status st = u0 ? sc_rig_plan_create(n, d->d[0], d->d[1], c->w, use, 0, &p0, err)
                      : sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    if (st == SC_OK)
        st = sc_rig_uncertainty(p0, u0, err);
    if (st == SC_OK) {
        double a = 0, b = 0;
        for (int i = 0; i < n; ++i)
            if (isfinite(uf[i]) && isfinite(u0[i]))
                a += uf[i] * uf[i], b += u0[i] * u0[i];
        s->drift_cost = b > 0 ? sqrt(a / b) : NAN;
    }
    sc_rig_plan_destroy(p0);
    free(u0);
    return st;
}

/* The rows present (y finite) into use[k]; a scan with none is refused at its header line. */
static sc_status rig_rows(const sc_profile_data *d, const double *y[2], unsigned char *use[2],
                          sc_error *err)
{
    for (int k = 0; k < 2; ++k) {
        long used = 0;
        for (int j = 0; j < d->n - d->d[k]; ++j)
            used += use[k][j] = isfinite(y[k][j]);
        if (!used)
            return sc_error_set(err, SC_E_INPUT, d->path[0] ? d->path : NULL, d->line_scan[k],
                                "scan %d has no complete sample (m1, m2 and m3 all given): its "
                                "offset, and so the profile, is not determined", k + 1);
    }
    return SC_OK;
}

/* One pass of the rig solver on the rows in use: a new plan in c->ctx.rig, f and q, the noise
 * (s's fields, *scale) and the unit uncertainties into uf. A singular plan is named at the
 * file's N line. */
static sc_status rig_pass(sc_profile_calibration *c, const sc_profile_data *d, const double *y1,
                          const double *y2, unsigned char *use[2], double *f, double *q,
                          double *uf, sc_profile_solution *s, double *scale, sc_error *err)
{
    sc_rig_plan_destroy(c->ctx.rig);
    c->ctx.rig = NULL;
    sc_status st = sc_rig_plan_create(d->n, d->d[0], d->d[1], c->w,
                                      (const unsigned char *const *)use, c->o.drift, &c->ctx.rig,
                                      err);
    if (st != SC_OK) {
        if (err && err->code == SC_E_INPUT && d->path[0])
            snprintf(err->file, sizeof err->file, "%s", d->path), err->line = d->line_n;
        return st;
    }
    s->dof = sc_rig_dof(c->ctx.rig);
    if ((st = sc_rig_solve(c->ctx.rig, y1, y2, f, q, &s->wrss, err)) != SC_OK)
        return st;
    *scale = noise_scale(c, s);
    return sc_rig_uncertainty(c->ctx.rig, uf, err);
}

/* The factor on the scans' σ for the residual test: none without noise to test against (t
 * empty), the a-posteriori scale when the noise was estimated or found too small. */
static double residual_sigma_factor(const sc_profile_solution *s, double scale)
{
    if (!s->have_uf)
        return 0.0;
    return s->noise_known ? (s->u_scaled ? scale : 1.0) : scale;
}

/* The rig solver (gaps, drift, residuals, outliers): plan from the rows present, solve, noise,
 * unit uncertainties, residual test, and with reject_outliers the worst flagged row out and
 * again. The plan stays in c->ctx.rig for the sensitivities; uf gets the unit uncertainties,
 * *scale the noise factor. */
static sc_status rig_run(sc_profile_calibration *c, const sc_profile_data *d, const double *y1,
                         const double *y2, double *f, double *uf, sc_profile_solution *s,
                         double *scale, sc_error *err)
{
    const int n = d->n;
    const double *y[2] = {y1, y2};
    unsigned char *use[2] = {malloc((size_t)(n - d->d[0])), malloc((size_t)(n - d->d[1]))};
    sc_status st = use[0] && use[1] ? rig_rows(d, y, use, err)
                                    : sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    int test = s->r_um[0] && s->r_um[1] && s->t[0] && s->t[1] && s->outlier[0] && s->outlier[1];
    for (int k = 0; k < 2 && st == SC_OK && test; ++k)
        memset(s->outlier[k], 0, (size_t)(n - d->d[k]));
    s->n_removed = 0;
    double q[SC_RIG_MAX_PARAMS];
    while (st == SC_OK) {
        st = rig_pass(c, d, y1, y2, use, f, q, uf, s, scale, err);
        if (st != SC_OK || !test)
            break;
        double res = residual_sigma_factor(s, *scale);
        const double sigma[2] = {sqrt(c->var[0]) * res, sqrt(c->var[1]) * res};
        long worst = residual_test(c->ctx.rig, d, y, f, q, sigma, s);
        if (!c->o.reject_outliers || worst < 0)
            break;
        int k = (int)(worst / n), j = (int)(worst % n);
        use[k][j] = 0;
        s->outlier[k][j] = 2;
        s->n_removed++;
    }
    if (st == SC_OK && c->o.drift)
        st = drift_cost(c, d, (const unsigned char *const *)use, uf, s, err);
    if (st == SC_OK) {
        s->rig = 1;
        s->n_undetermined = n - sc_rig_n_determined(c->ctx.rig);
        s->drift_um[0] = c->o.drift >= 1 ? q[2] : NAN;
        s->drift_um[1] = c->o.drift >= 2 ? q[3] : NAN;
    }
    free(use[0]), free(use[1]);
    return st;
}

/* The standard uncertainty of instrument constant src (SC_PROFILE_U_*; 0: not stated). */
static double instrument_u(const sc_profile_data *d, int src)
{
    return src == SC_PROFILE_U_PROBE_GAIN    ? (d->has_probe_gain ? d->probe_gain[1] : 0)
           : src == SC_PROFILE_U_ANGLE_SCALE ? (d->has_angle_scale ? d->angle_scale[1] : 0)
                                             : (d->has_spacing_u ? d->spacing_u_mm : 0);
}

/* The change of y (per unit of an instrument constant) for source src (SC_PROFILE_U_*), into
 * dy[k]; the constant's standard uncertainty returned (0: not stated). */
static double instrument_dy(const sc_profile_data *d, int src, double *dy[2])
{
    if (!(instrument_u(d, src) > 0))
        return 0;
    double kg = d->has_probe_gain ? d->probe_gain[0] : 1.0;
    double ka = d->has_angle_scale ? d->angle_scale[0] : 1.0;
    for (int k = 0; k < 2; ++k) {
        double D = d->d[k] * d->s_mm;
        for (int j = 0; j < d->n - d->d[k]; ++j) {
            double m2 = d->m2_um[k][j], m3 = d->m3_urad[k][j];
            dy[k][j] = src == SC_PROFILE_U_PROBE_GAIN    ? -m2 / (kg * kg)
                       : src == SC_PROFILE_U_ANGLE_SCALE ? D * m3 / (ka * ka) * 1e-3
                                                         : -m3 / ka * 1e-3;
        }
    }
    return instrument_u(d, src);
}

static void budget_entry(sc_profile_solution *s, int src, const double *u, int n)
{
    double ss = 0, mx = 0;
    int m = 0;
    for (int i = 0; i < n; ++i)
        if (isfinite(u[i]))
            ss += u[i] * u[i], m++, mx = u[i] > mx ? u[i] : mx;
    s->budget_rms_um[src] = m ? sqrt(ss / m) : 0;
    s->budget_max_um[src] = mx;
}

/* The instrument constants' uncertainties into uf (root sum of squares), each by the response
 * of the estimator to its change (one solve each, two for the spacings D1, D2, taken as
 * independent: the estimator is linear in y); work: 4n doubles. */
static sc_status instrument_budget(sc_profile_calibration *c, const sc_profile_data *d,
                                   double *uf, double *work, sc_profile_solution *s, sc_error *err)
{
    const int n = d->n;
    double *dy[2] = {work, work + n}, *df = work + 2 * (size_t)n, *acc = work + 3 * (size_t)n;
    for (int src = SC_PROFILE_U_PROBE_GAIN; src < SC_PROFILE_U_N; ++src) {
        int parts = src == SC_PROFILE_U_SPACING ? 2 : 1;
        double u = 0;
        for (int i = 0; i < n; ++i)
            acc[i] = 0;
        for (int part = 0; part < parts; ++part) {
            u = instrument_dy(d, src, dy);
            if (!(u > 0))
                break;
            if (parts == 2) /* only scan `part`'s spacing */
                for (int j = 0; j < n - d->d[1 - part]; ++j)
                    dy[1 - part][j] = 0;
            sc_status st = solve_cb(&c->ctx, dy[0], dy[1], df, err);
            if (st != SC_OK)
                return st;
            for (int i = 0; i < n; ++i)
                acc[i] += df[i] * u * df[i] * u;
        }
        if (!(u > 0))
            continue;
        for (int i = 0; i < n; ++i) {
            acc[i] = sqrt(acc[i]);
            uf[i] = sqrt(uf[i] * uf[i] + acc[i] * acc[i]);
        }
        budget_entry(s, src, acc, n);
    }
    return SC_OK;
}

/* Where scan 1 has no m1 but scan 2 has (the same probe over the same stage position), e_y from
 * scan 2's m1, less the mean offset of scan 2's m1 from scan 1's over the samples both have. */
static void stage_error_from_scan2(const sc_profile_data *d, const double *f, double *ey)
{
    const int m = d->n - d->d[0], m2 = d->n - d->d[1] < m ? d->n - d->d[1] : m;
    const double *a = d->m1_um[0], *b = d->m1_um[1];
    double off = 0, cnt = 0;
    for (int i = 0; i < m2; ++i)
        if (isfinite(a[i]) && isfinite(b[i]))
            off += b[i] - a[i], cnt += 1;
    if (cnt == 0)
        return;
    off /= cnt;
    for (int i = 0; i < m2; ++i)
        if (!isfinite(a[i]) && isfinite(b[i]))
            ey[i] = b[i] - off - f[i];
}

/* e_y = m1 - f of scan 1 (of scan 2 where scan 1 has a gap), relative to its least-squares line
 * over the samples where it is known (NaN elsewhere and for n >= N - d1). */
static void stage_error(const sc_profile_data *d, const double *f, double *ey)
{
    const int m = d->n - d->d[0];
    double sx = 0, sy = 0, sxx = 0, sxy = 0, cnt = 0;
    for (int i = 0; i < m; ++i)
        ey[i] = d->m1_um[0][i] - f[i];
    for (int i = 0; i < m; ++i)
        if (!isfinite(ey[i])) { /* a gap: scan 2 may have the sample */
            stage_error_from_scan2(d, f, ey);
            break;
        }
    for (int i = 0; i < m; ++i)
        if (isfinite(ey[i]))
            cnt += 1, sx += i, sy += ey[i];
    for (int i = m; i < d->n; ++i)
        ey[i] = NAN;
    if (cnt == m) { /* no gap: the library's own line removal, to the last bit as always */
        sc_profile_remove_line(m, ey);
        return;
    }
    double xm = cnt > 0 ? sx / cnt : 0, ym = cnt > 0 ? sy / cnt : 0;
    for (int i = 0; i < m; ++i)
        if (isfinite(ey[i]))
            sxx += (i - xm) * (i - xm), sxy += (i - xm) * (ey[i] - ym);
    double b = sxx > 0 ? sxy / sxx : 0;
    for (int i = 0; i < m; ++i)
        ey[i] = isfinite(ey[i]) ? ey[i] - ym - b * (i - xm) : NAN;
    for (int i = m; i < d->n; ++i)
        ey[i] = NAN;
}

/* f and the noise (s's fields, *scale on the unit uncertainties): the DFT refuses gaps; the rig
 * solver (rig) for gaps, drift, residuals; else the plan's method and its residual check. */
static sc_status solve_step(sc_profile_calibration *c, const sc_profile_data *d, int gaps, int rig,
                            const double *y1, const double *y2, double *f, double *uf, double *tmp,
                            sc_profile_solution *s, double *scale, sc_error *err)
{
    if (c->o.method == SC_PROFILE_DFT && gaps)
        return refuse_gaps(d, y1, y2, err);
    if (rig)
        return rig_run(c, d, y1, y2, f, uf, s, scale, err);
    sc_status st = solve_cb(&c->ctx, y1, y2, f, err);
    if (st == SC_OK)
        /* a noise stated as 0 is checked against the residuals (the caller warns if they are
         * not 0): the DFT's extra least-squares solve is paid then too */
        st = residuals(d, &c->ctx, y1, y2, f, c->w, tmp, c->o.residual_check || c->zero_noise, s,
                       err);
    if (st == SC_OK)
        *scale = noise_scale(c, s);
    return st;
}

/* The data must be those the calibration was made for (N, the spacings, the step). */
static sc_status check_shape(const sc_profile_calibration *c, const sc_profile_data *d,
                             sc_error *err)
{
    const int n = d->n, d1 = d->d[0], d2 = d->d[1];
    if (n != c->n || d1 != c->d1 || d2 != c->d2 || d->s_mm != c->s_mm)
        return sc_error_set(err, SC_E_INPUT, d->path[0] ? d->path : NULL, 0,
                            "the data (N = %d, d = %d/%d, s_mm = %g) are not those the "
                            "calibration was made for (N = %d, d = %d/%d, s_mm = %g)",
                            n, d1, d2, d->s_mm, c->n, c->d1, c->d2, c->s_mm);
    return SC_OK;
}

/* s's summary fields before a run: the noise chosen at create, nothing found yet. */
static void solution_reset(const sc_profile_calibration *c, sc_profile_solution *s)
{
    s->noise_known = c->noise_known;
    s->sigma_disp_um = c->sigma_disp_um;
    s->sigma_angle_urad = c->sigma_angle_urad;
    s->rig = 0, s->n_undetermined = 0, s->n_flagged = s->n_removed = 0;
    s->drift_um[0] = s->drift_um[1] = s->outlier_crit = s->drift_cost = NAN;
    for (int i = 0; i < SC_PROFILE_U_N; ++i)
        s->budget_rms_um[i] = s->budget_max_um[i] = 0;
}

/* Whether the header states an instrument constant with its uncertainty (a budget to add). */
static int has_budget(const sc_profile_data *d)
{
    return instrument_u(d, SC_PROFILE_U_PROBE_GAIN) > 0 ||
           instrument_u(d, SC_PROFILE_U_ANGLE_SCALE) > 0 ||
           instrument_u(d, SC_PROFILE_U_SPACING) > 0;
}

/* The arrays of one run: blk and work are owned (freed at the end), the others point into
 * them or into the caller's solution. */
typedef struct run_arrays {
    double *blk, *work;
    double *y1, *y2, *f, *uf, *tmp;
    int own_res, budget;
} run_arrays;

/* y1, y2, and f, uf where the caller wants none (they are written in place), tmp for the DFT's
 * residuals, the instrument budget's work (4n) and the residual arrays when not the caller's
 * (4n + marks, handed to s for the run). */
static sc_status run_alloc(const sc_profile_calibration *c, const sc_profile_data *d,
                           sc_profile_solution *s, run_arrays *a, sc_error *err)
{
    const sc_profile_options *o = &c->o;
    const int n = d->n;
    a->own_res = (o->want_residuals || o->reject_outliers) && !s->r_um[0];
    a->budget = has_budget(d);
    size_t own = 2 + !s->f_um + !s->uf_um + (o->method == SC_PROFILE_DFT);
    a->blk = sc_big_alloc(own * (size_t)n, sizeof(double), 0);
    a->work = a->budget || a->own_res
                  ? malloc((4 + 5 * (size_t)a->own_res) * (size_t)n * sizeof(double))
                  : NULL;
    if (!a->blk || ((a->budget || a->own_res) && !a->work)) {
        free(a->blk), free(a->work);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    }
    double *next = a->blk + 2 * (size_t)n;
    a->y1 = a->blk, a->y2 = a->blk + n, a->f = s->f_um, a->uf = s->uf_um;
    if (!a->f)
        a->f = next, next += n;
    if (!a->uf)
        a->uf = next, next += n;
    a->tmp = o->method == SC_PROFILE_DFT ? next : NULL;
    if (a->own_res) {
        double *r = a->work + 4 * (size_t)n;
        s->r_um[0] = r, s->r_um[1] = r + n, s->t[0] = r + 2 * (size_t)n;
        s->t[1] = r + 3 * (size_t)n;
        s->outlier[0] = (unsigned char *)(r + 4 * (size_t)n), s->outlier[1] = s->outlier[0] + n;
    }
    return SC_OK;
}

/* The scans' σ and every point's uncertainty (the noise scaled by `scale`: Monte Carlo, the
 * method's formula or the rig solver's unit uncertainties already in a->uf), then the budget:
 * the noise and each instrument constant stated. */
static sc_status final_uncertainty(sc_profile_calibration *c, const sc_profile_data *d, int rig,
                                   double scale, run_arrays *a, sc_profile_solution *s,
                                   sc_error *err)
{
    const sc_profile_options *o = &c->o;
    const double *var = c->var;
    double *uf = a->uf;
    sc_status st = SC_OK;
    s->sigma_y_um[0] = s->have_uf ? sqrt(var[0]) * scale : NAN;
    s->sigma_y_um[1] = s->have_uf ? sqrt(var[1]) * scale : NAN;
    if (s->have_uf && (!rig || o->mc_trials > 0))
        st = uncertainty(d, o, &c->ctx, var, scale, uf, err);
    else /* the rig solver's unit uncertainties are in uf already */
        for (int i = 0; i < d->n; ++i)
            uf[i] = s->have_uf ? uf[i] * scale : NAN;
    if (st == SC_OK && s->have_uf) {
        budget_entry(s, SC_PROFILE_U_NOISE, uf, d->n);
        if (a->budget)
            st = instrument_budget(c, d, uf, a->work, s, err);
    }
    return st;
}

sc_status sc_profile_calibration_run(sc_profile_calibration *c, const sc_profile_data *d,
                                     sc_profile_solution *s, sc_error *err)
{
    const sc_profile_options *o = &c->o;
    sc_status st = check_shape(c, d, err);
    if (st != SC_OK)
        return st;
    solution_reset(c, s);
    run_arrays a = {0};
    if ((st = run_alloc(c, d, s, &a, err)) != SC_OK)
        return st;
    sc_profile_combine(d, 0, a.y1);
    sc_profile_combine(d, 1, a.y2);
    int gaps = sc_profile_has_gaps(d), rig = o->method == SC_PROFILE_LSQ &&
              (gaps || o->drift || o->reject_outliers || o->want_residuals);
    double scale = 1.0; /* multiplies the plan's unit uncertainties */
    st = solve_step(c, d, gaps, rig, a.y1, a.y2, a.f, a.uf, a.tmp, s, &scale, err);
    if (st == SC_OK)
        st = final_uncertainty(c, d, rig, scale, &a, s, err);
    if (st == SC_OK && s->ey_um)
        stage_error(d, a.f, s->ey_um);
    if (a.own_res) { /* the caller did not give the arrays: none to hand back */
        s->r_um[0] = s->r_um[1] = s->t[0] = s->t[1] = NULL;
        s->outlier[0] = s->outlier[1] = NULL;
    }
    sc_rig_plan_destroy(c->ctx.rig);
    c->ctx.rig = NULL;
    free(a.work);
    free(a.blk);
    return st;
}

sc_status sc_profile_calibrate(const sc_profile_data *d, const sc_profile_options *o,
                               sc_profile_solution *s, sc_error *err)
{
    sc_profile_calibration *c;
    sc_status st = sc_profile_calibration_create(d, o, &c, err);
    if (st == SC_OK)
        st = sc_profile_calibration_run(c, d, s, err);
    sc_profile_calibration_destroy(c);
    return st;
}

/* The plan made on its own thread, started by the reader's header callback. */
typedef struct plan_job {
    sc_profile_options o;
    sc_profile_data hdr;
    sc_profile_calibration *cal;
    sc_status st;
    sc_error err;
    pthread_t thread;
    int started;
} plan_job;

static void *plan_thread(void *arg)
{
    plan_job *j = arg;
    sc_error_clear(&j->err);
    j->st = sc_profile_calibration_create(&j->hdr, &j->o, &j->cal, &j->err);
    return NULL;
}

static void plan_on_header(void *ctx, const sc_profile_data *hdr)
{
    plan_job *j = ctx;
    j->hdr = *hdr;
    j->started = pthread_create(&j->thread, NULL, plan_thread, j) == 0;
}

sc_status sc_profile_read_and_plan(const char *path, const sc_profile_options *o,
                                   sc_profile_data *out, sc_profile_calibration **cal,
                                   sc_error *err)
{
    *cal = NULL;
    plan_job j = {.o = *o, .st = SC_OK};
    sc_status st = sc_profile_read_hooked(path, plan_on_header, &j, out, err);
    if (j.started)
        pthread_join(j.thread, NULL);
    if (st != SC_OK) { /* the reading's error first: the plan is not wanted */
        sc_profile_calibration_destroy(j.cal);
        return st;
    }
    if (!j.started) /* no thread could start: the plan now */
        plan_thread(&j);
    if (j.st != SC_OK) {
        if (err)
            *err = j.err;
        sc_profile_data_free(out);
        return j.st;
    }
    *cal = j.cal;
    return SC_OK;
}
