/* profile_calibrate.c — owns the end-to-end straightness calibration (selfcal/profile_calibrate.h):
 * noise precedence, scan weights, the method's plan, the residual noise estimate, uncertainties
 * (analytic or Monte Carlo) and e_y, whole or in two steps (the plan from the header, then the
 * run on the data), and the reading of a file with the plan made on a thread of its own while
 * the rows are read. The command line and the Python package call only this. */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>

#include "selfcal/profile_calibrate.h"
#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS */
#include "../common/big_alloc.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"
#include "profile_lsq_tuning.h"

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
}

typedef struct solver_ctx {
    sc_profile_method method;
    sc_profile_dft_plan *dft;
    sc_profile_lsq_plan *lsq;
} solver_ctx;

static sc_status solve_cb(void *vctx, const double *y1, const double *y2, double *f, sc_error *err)
{
    solver_ctx *c = vctx;
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

sc_status sc_profile_calibration_create(const sc_profile_data *hdr, const sc_profile_options *o,
                                        sc_profile_calibration **out, sc_error *err)
{
    *out = NULL;
    /* the options as profile_calibrate.h states them: a known method, noise NaN (not given) or
     * >= 0 and finite, analytic (0) or Monte Carlo (>= 2) */
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
    sc_status st = sc_profile_check_method(hdr, o->method, err);
    if (st != SC_OK)
        return st;
    sc_profile_calibration *c = calloc(1, sizeof *c);
    if (!c)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    c->o = *o;
    c->n = hdr->n, c->d1 = hdr->d[0], c->d2 = hdr->d[1], c->s_mm = hdr->s_mm;
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
    c->ctx.method = o->method;
    if (o->method == SC_PROFILE_DFT)
        st = sc_profile_dft_plan_create(c->n, c->d1, c->d2, c->w[0], c->w[1], &c->ctx.dft, err);
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

sc_status sc_profile_calibration_run(sc_profile_calibration *c, const sc_profile_data *d,
                                     sc_profile_solution *s, sc_error *err)
{
    const sc_profile_options *o = &c->o;
    const int n = d->n, d1 = d->d[0], d2 = d->d[1];
    if (n != c->n || d1 != c->d1 || d2 != c->d2 || d->s_mm != c->s_mm)
        return sc_error_set(err, SC_E_INPUT, d->path[0] ? d->path : NULL, 0,
                            "the data (N = %d, d = %d/%d, s_mm = %g) are not those the "
                            "calibration was made for (N = %d, d = %d/%d, s_mm = %g)",
                            n, d1, d2, d->s_mm, c->n, c->d1, c->d2, c->s_mm);
    s->noise_known = c->noise_known;
    s->sigma_disp_um = c->sigma_disp_um;
    s->sigma_angle_urad = c->sigma_angle_urad;
    const double *var = c->var, *w = c->w;
    /* y1, y2, and f, uf where the caller wants none (they are written in place), tmp for the
     * DFT's residuals */
    size_t own = 2 + !s->f_um + !s->uf_um + (o->method == SC_PROFILE_DFT);
    double *blk = sc_big_alloc(own * (size_t)n, sizeof(double), 0);
    if (!blk)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    double *y1 = blk, *y2 = y1 + n, *next = y2 + n, *f = s->f_um, *uf = s->uf_um;
    if (!f)
        f = next, next += n;
    if (!uf)
        uf = next, next += n;
    double *tmp = o->method == SC_PROFILE_DFT ? next : NULL;
    sc_profile_combine(d, 0, y1);
    sc_profile_combine(d, 1, y2);
    sc_status st = solve_cb(&c->ctx, y1, y2, f, err);
    if (st == SC_OK)
        /* a noise stated as 0 is checked against the residuals (the caller warns if they are
         * not 0): the DFT's extra least-squares solve is paid then too */
        st = residuals(d, &c->ctx, y1, y2, f, w, tmp, o->residual_check || c->zero_noise, s, err);
    if (st != SC_OK)
        goto done;
    double scale = 1.0; /* multiplies the plan's unit uncertainties */
    s->have_uf = 1;
    s->residual_ratio = NAN;
    if (c->zero_noise)
        scale = 0.0;
    else if (!s->noise_known && s->dof <= 0)
        s->have_uf = 0; /* no redundancy: the noise is not estimable */
    else if (!s->noise_known)
        scale = sqrt(s->wrss / s->dof);
    else if (s->dof > 0 && !isnan(s->wrss))
        s->residual_ratio = sqrt(s->wrss / s->dof);
    s->sigma_y_um[0] = s->have_uf ? sqrt(var[0]) * scale : NAN;
    s->sigma_y_um[1] = s->have_uf ? sqrt(var[1]) * scale : NAN;
    if (s->have_uf)
        st = uncertainty(d, o, &c->ctx, var, scale, uf, err);
    else
        for (int i = 0; i < n; ++i)
            uf[i] = NAN;
    if (st != SC_OK)
        goto done;
    if (s->ey_um) {
        sc_profile_stage_error(d, f, s->ey_um);
        for (int i = n - d1; i < n; ++i)
            s->ey_um[i] = NAN;
    }
done:
    free(blk);
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
