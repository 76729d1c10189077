/* grid_calibrate.c — owns the end-to-end grid calibration (selfcal/grid_calibrate.h): which views
 * each closed-form method needs (stated once, here), the checks of the data against the method,
 * the solve, the exact methods' noise estimate, and least squares' residuals, outlier test and
 * rejection loop and covariance. The command line, the report and Python call only this.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid_calibrate.h"
#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS */
#include "selfcal/grid_exact.h"
#include "grid_calibrate_common.h"
#include "grid_view_noise.h"
#include "grid_lsq_internal.h"
#include "grid_scale_internal.h"
#include "selfcal/rng.h"

int sc_grid_method_from_name(const char *name)
{
    if (!name)
        return -1;
    if (!strcmp(name, "ye"))
        return SC_GRID_METHOD_YE;
    if (!strcmp(name, "double-shift"))
        return SC_GRID_METHOD_DOUBLE_SHIFT;
    if (!strcmp(name, "lsq"))
        return SC_GRID_METHOD_LSQ;
    return -1;
}

const char *sc_grid_method_name(sc_grid_method m)
{
    switch (m) {
    case SC_GRID_METHOD_YE: return "ye";
    case SC_GRID_METHOD_DOUBLE_SHIFT: return "double-shift";
    default: return "lsq";
    }
}

void sc_grid_options_default(sc_grid_options *o)
{
    memset(o, 0, sizeof *o);
    o->method = SC_GRID_METHOD_LSQ;
}

/* ---- the closed forms' views ---- */

static long line_of(const sc_grid_file_info *info, int which, int v)
{
    if (!info)
        return 0;
    return which == 0 ? info->header_end_line : which == 1 ? info->n_line : info->view_line[v];
}

/* One needed view: declared, with data, every needed mark measured. */
static sc_status check_view(const sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                            const char *method, const sc_grid_view_need *w, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    int n = p->n, c = (n - 1) / 2;
    int v = sc_grid_find_view(p, w->rot_deg, w->shift_x, w->shift_y);
    if (v < 0)
        return sc_error_set(err, SC_E_INPUT, path, line_of(info, 0, 0),
                            "method %s needs a view rot=%d shift=%d,%d, which the header does not "
                            "declare",
                            method, w->rot_deg, w->shift_x, w->shift_y);
    int any = 0;
    for (long k = 0; k < (long)n * n && !any; ++k)
        any = isfinite(d->dx_um[v][k]);
    if (!any)
        return sc_error_set(err, SC_E_INPUT, path, line_of(info, 2, v),
                            "view %d (rot=%d shift=%d,%d), needed by method %s, has no data rows",
                            sc_grid_view_id(info, v), w->rot_deg, w->shift_x, w->shift_y, method);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int ni, nj;
            if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
                continue;
            if (w->partial && i != c && j != c && j != c + 1)
                continue;
            if (!isfinite(d->dx_um[v][i * n + j]))
                return sc_error_set(err, SC_E_INPUT, path, line_of(info, 2, v),
                                    "view %d (rot=%d shift=%d,%d) lacks mark (%d,%d), which method "
                                    "%s needs",
                                    sc_grid_view_id(info, v), w->rot_deg, w->shift_x, w->shift_y, i, j,
                                    method);
        }
    return SC_OK;
}

static sc_status check_exact(const sc_grid_data *d, const sc_grid_file_info *info,
                             const char *path, sc_grid_method m, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    const char *name = sc_grid_method_name(m);
    if (!sc_grid_stage_is_plate(p))
        return sc_error_set(err, SC_E_INPUT, path, line_of(info, 0, 0),
                            "method %s needs the stage grid to be the plate's N x N (this file has "
                            "a %dx%d stage: use --method lsq)",
                            name, sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    /* what the method needs is the method's to say (grid_exact.c), stated once */
    sc_grid_exact_method em = m == SC_GRID_METHOD_YE ? SC_GRID_YE : SC_GRID_DOUBLE_SHIFT;
    if (p->n < sc_grid_exact_min_n(em))
        return sc_error_set(err, SC_E_INPUT, path, line_of(info, 1, 0),
                            "method %s needs N >= %d (N = %d)", name, sc_grid_exact_min_n(em),
                            p->n);
    sc_grid_view_need need[4];
    int n_need = sc_grid_exact_needs(em, need);
    for (int k = 0; k < n_need; ++k) {
        sc_status st = check_view(d, info, path, name, &need[k], err);
        if (st != SC_OK)
            return st;
    }
    return SC_OK;
}

static int has_stated_u(const sc_grid_data *d)
{
    for (int v = 0; v < d->plan.n_views; ++v)
        if (d->ux_um[v] || d->uy_um[v])
            return 1;
    return 0;
}

static int has_times(const sc_grid_data *d)
{
    for (int v = 0; v < d->plan.n_views; ++v)
        if (d->t_s[v])
            return 1;
    return 0;
}

/* The σ_r given on the command line, or 0 when the data state their uncertainties (ux_um,uy_um
 * or sigma_um=): the stated uncertainties are the noise model and win over --sigma-r-um. */
static double given_sigma_r(const sc_grid_data *d, const sc_grid_file_info *info,
                            const sc_grid_options *o)
{
    int stated = info ? info->has_u : has_stated_u(d);
    for (int v = 0; v < d->plan.n_views; ++v)
        stated |= d->plan.view[v].sigma_um > 0;
    return stated ? 0.0 : o->sigma_r_um;
}

static sc_status check_lsq(const sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                           const sc_grid_options *o, sc_error *err)
{
    if (o->estimate_view_noise && o->sigma_r_um > 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "a given noise (--sigma-r-um) and the noise estimated per view "
                            "(--view-noise estimate) exclude each other");
    if (!(o->outlier_alpha >= 0 && o->outlier_alpha < 1))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the outlier test's significance must lie between 0 and 1, got %g",
                            o->outlier_alpha);
    if (o->drift && !(info ? info->has_t : has_times(d)))
        return sc_error_set(err, SC_E_INPUT, path, line_of(info, 0, 0),
                            "--drift linear needs the time of each measurement (column t_s)");
    long nodes = sc_grid_stage_nodes(&d->plan); /* refused before the solve, not after it */
    if (o->covariance && nodes > SC_GRID_LSQ_COV_MAX_NODES)
        return sc_error_set(err, SC_E_INPUT, path, line_of(info, 0, 0),
                            "--covariance: %ld stage nodes exceed the limit of %d", nodes,
                            SC_GRID_LSQ_COV_MAX_NODES);
    return SC_OK;
}

sc_status sc_grid_check_method(const sc_grid_data *d, const sc_grid_file_info *info,
                               const char *path, const sc_grid_options *o, sc_error *err)
{
    if (info && info->n_rows == 0)
        return sc_error_set(err, SC_E_INPUT, path, info->header_end_line,
                            "no data rows (a plan file? use 'selfcal plan' for plans)");
    /* 0: not given; else what the map's uncertainties can carry (its reader's limit, 1 m) */
    if (!(o->sigma_r_um >= 0 && o->sigma_r_um <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the given noise sigma_r must be positive and at most %g um, got %g",
                            SC_INPUT_MAX_ABS, o->sigma_r_um);
    if (o->method == SC_GRID_METHOD_LSQ)
        return check_lsq(d, info, path, o, err);
    if (o->drift || o->reject_outliers || o->covariance || o->outlier_alpha != 0 ||
        o->outlier_alpha_each || o->estimate_view_noise)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "residuals, the outlier test, covariance, drift and the noise per view "
                            "need least squares");
    return check_exact(d, info, path, o->method, err);
}

/* ---- solving ---- */

/* The arrays of s and the NaN/neutral defaults of its result. */
static sc_status solution_alloc(const sc_grid_plan *p, const sc_grid_options *o,
                                sc_grid_solution *s, sc_error *err)
{
    memset(s, 0, sizeof *s);
    s->n_nodes = sc_grid_stage_nodes(p);
    s->n_marks = (long)p->n * p->n;
    s->n_views = p->n_views;
    size_t ns = (size_t)s->n_nodes, nm = (size_t)s->n_marks, tot = (size_t)p->n_views * nm;
    size_t nbuf = 4 * ns + 2 * nm + (o->method == SC_GRID_METHOD_LSQ ? 4 * tot : 0);
    double *buf = malloc(nbuf * sizeof(double));
    if (!buf)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (size_t k = 0; k < nbuf; ++k)
        buf[k] = NAN;
    sc_grid_result *r = &s->res;
    r->gx_um = buf, r->gy_um = buf + ns, r->ugx_um = buf + 2 * ns, r->ugy_um = buf + 3 * ns;
    r->ax_um = buf + 4 * ns, r->ay_um = buf + 4 * ns + nm;
    if (o->method == SC_GRID_METHOD_LSQ) {
        double *rb = buf + 4 * ns + 2 * nm;
        s->rx_um = rb, s->ry_um = rb + tot, s->tx = rb + 2 * tot, s->ty = rb + 3 * tot;
        if (!(s->outlier = calloc(tot ? tot : 1, 1)))
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    r->O = r->R = r->residual_rms_um = r->sigma_r_est_um = r->sigma_r_used_um = NAN;
    r->uO = r->uR = r->variance_factor = r->chi2_lo = r->chi2_hi = NAN;
    r->chi2_pass = 1;
    r->outlier_alpha = r->outlier_alpha_coord = r->outlier_crit = NAN;
    r->misalignment_unique = 1;
    r->stated_u = 0;
    return sc_grid_result_views(r, p->n_views, err); /* every per-view value NaN */
}

void sc_grid_solution_free(sc_grid_solution *s)
{
    free(s->budget.view_scale_ppm); /* the budget's one block */
    free(s->res.gx_um); /* the block of every double array but the covariance */
    sc_grid_result_free_views(&s->res);
    free(s->outlier);
    free(s->cov_um2);
    memset(s, 0, sizeof *s);
}

/* The measurement noise behind data solved by a closed form: the closed forms are not
 * least-squares fits, so their residuals do not estimate σ_r without bias; the least-squares
 * residuals of the same data and model do (sqrt(RSS/dof)), with every measurement weighted
 * equally as the closed forms weigh them (stated uncertainties would make it a factor on them,
 * not a noise in µm), over all the data (extra views too). Into res: sigma_r_est_um and that
 * fit's n_measurements and dof; NaN (and the closed form's own counts kept) if the data leave
 * no redundancy or do not identify the model. */
static void exact_noise_estimate(const sc_grid_plan *p, const sc_grid_data *d, sc_grid_result *res)
{
    sc_grid_lsq_plan *q = NULL;
    sc_grid_lsq_opts uo = {.unit_weights = 1, .node_sigma_only = 1};
    sc_grid_result r;
    memset(&r, 0, sizeof r); /* no arrays: only the scalars are wanted */
    res->sigma_r_est_um = NAN;
    sc_grid_lsq_info qi;
    if (sc_grid_lsq_plan_create(p, d, &uo, &q, NULL) == SC_OK) {
        sc_grid_lsq_get_info(q, &qi);
        if (qi.identifiable && sc_grid_lsq_execute(q, d, 0.0, &r, NULL) == SC_OK &&
            isfinite(r.sigma_r_est_um)) {
            res->sigma_r_est_um = r.sigma_r_est_um;
            res->n_measurements = r.n_measurements;
            res->dof = r.dof;
        }
    }
    sc_grid_lsq_plan_destroy(q);
}

static sc_status run_exact(sc_grid_data *d, const sc_grid_options *o, sc_grid_solution *s,
                           sc_error *err)
{
    sc_grid_exact_plan *xp = NULL;
    sc_status st = sc_grid_exact_plan_create(
        o->method == SC_GRID_METHOD_YE ? SC_GRID_YE : SC_GRID_DOUBLE_SHIFT, d->plan.n, &xp, err);
    if (st == SC_OK)
        st = sc_grid_exact_execute(xp, d, &s->res, err);
    sc_grid_exact_plan_destroy(xp);
    if (st != SC_OK)
        return st;
    /* no uncertainties from the closed forms: a given σ_r has nothing to scale */
    for (long k = 0; k < s->n_nodes; ++k)
        s->res.ugx_um[k] = s->res.ugy_um[k] = NAN;
    s->res.sigma_r_used_um = NAN;
    exact_noise_estimate(&d->plan, d, &s->res);
    return SC_OK;
}

/* Below this noise (µm) the residuals are floating-point rounding, not measurement noise: they
 * are not normal, and Baarda's test is not applied (noise-free simulations, 1e-13 µm). */

static int outlier_test_applies(const sc_grid_result *r)
{
    return !(r->sigma_r_est_um < NOISE_FLOOR_UM) || (r->weighted && !(r->sigma_r_used_um < NOISE_FLOOR_UM));
}

/* The outlier test's figures in s->res from the first solution's standardized residuals: the
 * coordinates tested (finite t) and the critical value for o's significance. */
static void outlier_test_set(const sc_grid_options *o, sc_grid_solution *s, size_t tot)
{
    sc_grid_result *r = &s->res;
    long m = 0;
    for (size_t k = 0; k < tot; ++k)
        m += isfinite(s->tx[k]) + isfinite(s->ty[k]);
    r->outlier_alpha = o->outlier_alpha > 0 ? o->outlier_alpha : SC_GRID_OUTLIER_ALPHA;
    r->outlier_alpha_each = o->outlier_alpha_each != 0;
    r->n_outlier_tests = m;
    r->outlier_alpha_coord = r->outlier_alpha_each || m < 1
                                 ? r->outlier_alpha
                                 : sc_grid_sidak_share(r->outlier_alpha, m);
    r->outlier_crit = sc_grid_outlier_critical(r->outlier_alpha, m, r->outlier_alpha_each);
}

/* The worst flagged measurement not yet removed: index v*n*n + k, or -1. */
static long worst_outlier(const sc_grid_solution *s, size_t tot)
{
    long best = -1;
    if (!outlier_test_applies(&s->res) || !isfinite(s->res.outlier_crit))
        return -1;
    double bt = s->res.outlier_crit;
    for (size_t k = 0; k < tot; ++k) {
        double t = fmax(isfinite(s->tx[k]) ? fabs(s->tx[k]) : 0,
                        isfinite(s->ty[k]) ? fabs(s->ty[k]) : 0);
        if (!s->outlier[k] && t > bt)
            bt = t, best = (long)k;
    }
    return best;
}

/* Solve, then while asked remove the worst flagged measurement and solve again. A removal is
 * confirmed (and warned about) once the views still identify G without it; an outlier that is
 * the only link is kept, with a warning, and rejection stops. keep: the data as they came. */
static sc_status lsq_loop(sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                          const sc_grid_options *o, const double *keep, view_noise *vn,
                          sc_grid_solution *s, sc_grid_lsq_plan **qp, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n, tot = (size_t)p->n_views * nn;
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    const char *src = path ? path : "data";
    long pending = -1; /* the row just removed, confirmed once G stays identified without it */
    int stop = 0;
    double sigma_r = given_sigma_r(d, info, o);
    if (o->sigma_r_um > 0 && !(sigma_r > 0))
        sc_grid_warnf(o, "%s: the file states its uncertainties (ux_um,uy_um or sigma_um=): "
                         "--sigma-r-um %g is ignored",
              src, o->sigma_r_um);
    for (int first = 1;; first = 0) {
        if (!first || !*qp) { /* the first plan may come made (sc_grid_calibrate) */
            sc_grid_lsq_plan_destroy(*qp);
            *qp = NULL;
            /* each pass estimates the noise per view afresh from the weights as read: a
             * removed outlier no longer pulls it */
            sc_grid_view_noise_as_read(d, vn);
            sc_status st = sc_grid_lsq_plan_create(p, d, &opts, qp, err);
            if (st != SC_OK)
                return st;
        }
        sc_grid_lsq_get_info(*qp, &s->plan_info);
        if (pending >= 0) {
            int v = (int)(pending / (long)nn), k = (int)(pending % (long)nn);
            if (!s->plan_info.identifiable) { /* the outlier is the only link: keep it, stop */
                d->dx_um[v][k] = keep[pending], d->dy_um[v][k] = keep[tot + pending];
                s->outlier[pending] = 0;
                s->n_removed--;
                sc_grid_warnf(o, "%s: outlier view %d mark (%d,%d) kept: without it the views "
                                 "would not identify G",
                      src, sc_grid_view_id(info, v), k / p->n, k % p->n);
                pending = -1, stop = 1;
                continue;
            }
            sc_grid_warnf(o, "%s: removed outlier view %d mark (%d,%d) (tx %.3g, ty %.3g; critical "
                             "value %.3f) and solved again",
                  src, sc_grid_view_id(info, v), k / p->n, k % p->n, s->tx[pending], s->ty[pending],
                  s->res.outlier_crit);
            pending = -1;
        }
        if (!s->plan_info.identifiable)
            return sc_error_set(err, SC_E_UNSOLVABLE, path, line_of(info, 0, 0),
                                "the measured views do not identify G: %ld degree(s) of freedom "
                                "beyond the gauge stay free (see 'selfcal plan')",
                                s->plan_info.free_dof);
        sc_status st = sc_grid_lsq_execute(*qp, d, sigma_r, &s->res, err);
        if (st == SC_OK && o->estimate_view_noise)
            st = sc_grid_estimate_view_noise(d, info, o, vn, s, qp, src, err);
        if (st == SC_OK && o->progress)
            o->progress(o->progress_ctx, "residuals", 1, 1, 0);
        if (st == SC_OK)
            st = sc_grid_lsq_residuals(*qp, d, &s->res, s->rx_um, s->ry_um, s->tx, s->ty, NULL, err);
        if (st != SC_OK)
            return st;
        if (first) /* the test is fixed by the data as they came (execute leaves it alone) */
            outlier_test_set(o, s, tot);
        if (!o->reject_outliers || stop)
            return st;
        long w = worst_outlier(s, tot);
        if (w < 0)
            return SC_OK;
        s->outlier[w] = 1;
        s->n_removed++;
        d->dx_um[w / (long)nn][w % (long)nn] = d->dy_um[w / (long)nn][w % (long)nn] = NAN;
        pending = w;
    }
}

/* After the loop: the removed measurements get back their values and their residuals against the
 * final solution; flagged ones are counted and warned about; the χ² test's verdict. */
static void lsq_finish(sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                       const sc_grid_options *o, const double *keep, sc_grid_solution *s,
                       sc_grid_lsq_plan *q)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n, tot = (size_t)p->n_views * nn;
    const char *src = path ? path : "data";
    /* the final solution's misalignments as fitted to the data it was solved on; a view the
     * removals left undetermined (one mark: its rotation free) cannot predict its removed
     * marks, whose residuals are then not estimable (empty) */
    double *mis = malloc((size_t)p->n_views * SC_GRID_LSQ_MAX_NB * sizeof *mis);
    int *determined = malloc((size_t)p->n_views * sizeof *determined);
    if (!mis || !determined) { /* no memory left for them: removed marks' residuals empty */
        free(mis), free(determined);
        mis = NULL, determined = NULL;
    } else {
        sc_grid_lsq_fit_misalignments(q, d, &s->res, mis, determined);
    }
    for (size_t k = 0; k < tot; ++k) {
        int v = (int)(k / nn), m = (int)(k % nn);
        if (s->outlier[k]) { /* removed: residual against the final solution */
            double px, py, t = d->t_s[v] ? d->t_s[v][m] : NAN;
            px = py = NAN;
            if (mis)
                sc_grid_lsq_predict_with(q, &s->res, mis, v, m / p->n, m % p->n, t, &px, &py);
            s->rx_um[k] = mis && determined[v] ? keep[k] - px : NAN;
            s->ry_um[k] = mis && determined[v] ? keep[tot + k] - py : NAN;
            s->tx[k] = s->ty[k] = NAN;
            d->dx_um[v][m] = keep[k], d->dy_um[v][m] = keep[tot + k];
            s->n_flagged++;
        } else if (outlier_test_applies(&s->res) &&
                   (sc_grid_outlier_beyond(&s->res, s->tx[k]) ||
                    sc_grid_outlier_beyond(&s->res, s->ty[k]))) {
            s->outlier[k] = 1;
            s->n_flagged++;
            if (s->res.outlier_alpha_each)
                sc_grid_warnf(o, "%s: view %d mark (%d,%d) is an outlier (standardized residuals "
                                 "tx %.3g, ty %.3g beyond %.3f: data snooping, alpha = %g for each "
                                 "coordinate)",
                      src, sc_grid_view_id(info, v), m / p->n, m % p->n, s->tx[k], s->ty[k],
                      s->res.outlier_crit, s->res.outlier_alpha);
            else
                sc_grid_warnf(o, "%s: view %d mark (%d,%d) is an outlier (standardized residuals "
                                 "tx %.3g, ty %.3g beyond %.3f: data snooping, alpha = %g over %ld "
                                 "coordinates)",
                      src, sc_grid_view_id(info, v), m / p->n, m % p->n, s->tx[k], s->ty[k],
                      s->res.outlier_crit, s->res.outlier_alpha, s->res.n_outlier_tests);
        }
    }
    if (!s->res.chi2_pass)
        sc_grid_warnf(o, "%s: the residuals disagree with the %s noise: variance factor %.4g "
                         "outside the chi^2 95 %% interval [%.4g, %.4g]%s%s",
              src, given_sigma_r(d, info, o) > 0 ? "given" : "stated", s->res.variance_factor,
              s->res.chi2_lo, s->res.chi2_hi,
              given_sigma_r(d, info, o) > 0
                  ? " (compare sigma_r_est_um in the summary with --sigma-r-um)"
                  : "",
              s->res.variance_factor > s->res.chi2_hi
                  ? "; the outlier test's standardized residuals use that noise scaled by "
                    "sqrt(variance factor), so that it does not flag everything"
                  : "");
    free(mis), free(determined);
}

static sc_status run_lsq(sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                         const sc_grid_options *o, sc_grid_lsq_plan *q0, sc_grid_solution *s,
                         sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n, tot = (size_t)p->n_views * nn;
    double *keep = malloc((2 * tot + 1) * sizeof(double));
    if (!keep) {
        sc_grid_lsq_plan_destroy(q0);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k)
            keep[v * nn + k] = d->dx_um[v][k], keep[tot + v * nn + k] = d->dy_um[v][k];
    sc_grid_lsq_plan *q = q0;
    view_noise vn;
    sc_status st = sc_grid_view_noise_save(d, o->estimate_view_noise, &vn, err);
    if (st != SC_OK) {
        free(keep);
        sc_grid_lsq_plan_destroy(q0);
        return st;
    }
    st = lsq_loop(d, info, path, o, keep, &vn, s, &q, err);
    if (st == SC_OK)
        lsq_finish(d, info, path, o, keep, s, q);
    else /* the data as they came, whatever was removed */
        for (int v = 0; v < p->n_views; ++v)
            for (size_t k = 0; k < nn; ++k)
                d->dx_um[v][k] = keep[v * nn + k], d->dy_um[v][k] = keep[tot + v * nn + k];
    if (st == SC_OK && o->covariance) {
        long m = 2 * s->n_nodes; /* at most SC_GRID_LSQ_COV_MAX_NODES (check_lsq) */
        if (!(s->cov_um2 = malloc((size_t)m * m * sizeof(double))))
            st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (covariance)");
        else
            st = sc_grid_lsq_covariance(q, &s->res, s->cov_um2, err);
        s->n_cov = m;
    }
    sc_grid_view_noise_restore(d, &vn); /* the uncertainties as they came */
    sc_grid_lsq_plan_destroy(q);
    free(keep);
    return st;
}

static sc_status calibrate_plain(sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                               const sc_grid_options *o, sc_grid_solution *s, sc_error *err)
{
    memset(s, 0, sizeof *s);
    sc_status st = sc_grid_check_method(d, info, path, o, err);
    /* the least squares' first plan before the solution's arrays: its selected inverse sets the
     * command's peak memory, and the arrays are not needed yet */
    sc_grid_lsq_plan *q0 = NULL;
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    if (st == SC_OK && o->method == SC_GRID_METHOD_LSQ)
        st = sc_grid_lsq_plan_create(&d->plan, d, &opts, &q0, err);
    if (st == SC_OK)
        st = solution_alloc(&d->plan, o, s, err);
    if (st == SC_OK)
        st = o->method == SC_GRID_METHOD_LSQ ? run_lsq(d, info, path, o, q0, s, err)
                                             : run_exact(d, o, s, err);
    else
        sc_grid_lsq_plan_destroy(q0);
    if (st != SC_OK)
        return st;
    /* O and R come with the result: every method computes them (sc_grid_first_order) */
    for (long k = 0; k < s->n_nodes; ++k)
        if (!isfinite(s->res.gx_um[k]) || !isfinite(s->res.gy_um[k]))
            return sc_error_set(err, SC_E_INTERNAL, path, 0, "the %s solution is not finite",
                                sc_grid_method_name(o->method));
    for (long k = 0; k < s->n_marks; ++k)
        if (isfinite(s->res.ax_um[k]) != isfinite(s->res.ay_um[k]))
            return sc_error_set(err, SC_E_INTERNAL, path, 0, "the %s solution is not finite",
                                sc_grid_method_name(o->method));
    return SC_OK;
}

/* ---- the plate's scale and temperature (SPEC §11; grid_scale.c) ---- */

/* The budget's arrays, in one block (freed by sc_grid_solution_free). */
static sc_status budget_alloc(const sc_grid_plan *p, sc_grid_budget *b, sc_error *err)
{
    size_t nv = (size_t)p->n_views, ns = (size_t)sc_grid_stage_nodes(p);
    double *buf = malloc(sizeof(double) * (3 * nv + 2 * ns));
    if (!buf)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    memset(b, 0, sizeof *b);
    b->view_scale_ppm = buf, b->view_scale_free_ppm = buf + nv;
    b->u_view_scale_free_ppm = buf + 2 * nv, b->ugx_noise_um = buf + 3 * nv;
    b->ugy_noise_um = buf + 3 * nv + ns;
    for (size_t k = 0; k < 3 * nv + 2 * ns; ++k)
        buf[k] = NAN;
    b->n_views = p->n_views;
    b->applies = 1;
    b->magnification = p->scale.has_plate_scale;
    b->magnification_ppm = b->u_magnification_ppm = b->u_magnification_noise_ppm = NAN;
    b->view_scale_chi2 = b->view_scale_chi2_crit = NAN;
    b->u_c_um = b->nu_eff = b->k = b->U_um = NAN;
    b->worst_node = -1;
    return SC_OK;
}

/* With E: move the plate's magnification to the stage (G, A and the views' translations). */
static void magnification_gauge(const sc_grid_plan *p, sc_grid_solution *s)
{
    sc_grid_result *r = &s->res;
    double m = sc_grid_plate_magnification_ppm(p, r->ax_um, r->ay_um);
    int nx = sc_grid_stage_nx(p);
    for (long k = 0; k < s->n_nodes; ++k) {
        double x, y;
        sc_grid_node_xy_mm(p, (int)(k / nx), (int)(k % nx), &x, &y);
        r->gx_um[k] += m * 1e-3 * x, r->gy_um[k] += m * 1e-3 * y;
    }
    for (long k = 0; k < s->n_marks; ++k) {
        double x, y;
        sc_grid_mark_xy_mm(p, (int)(k / p->n), (int)(k % p->n), &x, &y);
        r->ax_um[k] -= m * 1e-3 * x, r->ay_um[k] -= m * 1e-3 * y;
    }
    for (int v = 0; v < p->n_views; ++v) { /* node − Rot(p) = shift·P: a translation per view */
        r->tx_um[v] -= m * 1e-3 * p->view[v].shift_x * p->pitch_mm;
        r->ty_um[v] -= m * 1e-3 * p->view[v].shift_y * p->pitch_mm;
    }
    s->budget.magnification_ppm = m;
}

/* The free scales' rank taken from the residuals' degrees of freedom: σ̂ and the node
 * uncertainties follow (when σ_r is the estimated one). */
static void free_scales_dof(sc_grid_result *r, int rank, long ns)
{
    long dof = r->dof - rank;
    if (rank <= 0 || dof <= 0 || r->dof <= 0)
        return;
    double f = sqrt((double)r->dof / (double)dof);
    int estimated = !r->weighted && !r->view_noise_estimated;
    r->sigma_r_est_um *= f;
    if (estimated) {
        r->sigma_r_used_um = r->sigma_r_est_um;
        for (long k = 0; k < ns; ++k)
            r->ugx_um[k] *= f, r->ugy_um[k] *= f;
    }
    if (isfinite(r->variance_factor))
        r->variance_factor *= f * f;
    r->dof = dof;
}

/* The free view scales' uncertainties and their χ² test (warned when significant). */
static void free_scales_report(const sc_grid_est *e, const sc_grid_file_info *info,
                               const char *path, const sc_grid_options *o, sc_grid_solution *s)
{
    sc_grid_budget *b = &s->budget;
    double s0 = s->res.sigma_r_used_um, chi2 = 0;
    int nv = e->nv, worst = 0;
    for (int v = 0; v < nv; ++v) {
        b->u_view_scale_free_ppm[v] = s0 * sqrt(fmax(e->Mp[v * nv + v], 0));
        for (int c = 0; c < nv; ++c)
            chi2 += b->view_scale_free_ppm[v] * e->M[v * nv + c] * b->view_scale_free_ppm[c];
        if (fabs(b->view_scale_free_ppm[v]) > fabs(b->view_scale_free_ppm[worst]))
            worst = v;
    }
    b->view_scale_chi2 = chi2 / (s0 * s0);
    b->view_scale_chi2_crit = sc_chi2_quantile(0.95, (double)e->rank);
    b->view_scale_significant = b->view_scale_chi2 > b->view_scale_chi2_crit;
    if (b->view_scale_significant)
        sc_grid_warnf(o, "%s: the views' scales differ significantly (chi^2 %.4g > %.4g at 95 %% "
                         "over %d degrees of freedom; largest: view %d, %.4g ppm, u %.2g ppm): the "
                         "plate's temperature changed between the views, or the stage's scale did",
              path ? path : "data", b->view_scale_chi2, b->view_scale_chi2_crit, e->rank,
              sc_grid_view_id(info, worst), b->view_scale_free_ppm[worst],
              b->u_view_scale_free_ppm[worst]);
}

/* After the least squares on the corrected data dc: the magnification gauge and the budget. */
static sc_status scale_finish_lsq(const sc_grid_data *dc, const sc_grid_file_info *info,
                                  const char *path, const sc_grid_options *o,
                                  sc_grid_solution *s, sc_error *err)
{
    const sc_grid_plan *p = &dc->plan;
    sc_grid_data mask;
    sc_status st = sc_grid_data_copy_values(dc, &mask, err);
    if (st != SC_OK)
        return st;
    size_t nn = (size_t)p->n * p->n;
    for (size_t k = 0; o->reject_outliers && k < (size_t)p->n_views * nn; ++k)
        if (s->outlier[k]) /* removed: not in the final solution */
            mask.dx_um[k / nn][k % nn] = mask.dy_um[k / nn][k % nn] = NAN;
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    opts.node_sigma_only = 1;
    sc_grid_est e;
    st = sc_grid_est_make(&mask, &opts, s->budget.magnification, o->view_scale_free, &e, err);
    if (st == SC_OK && o->view_scale_free) {
        free_scales_dof(&s->res, e.rank, s->n_nodes);
        free_scales_report(&e, info, path, o, s);
    }
    int stated = s->res.stated_u || given_sigma_r(dc, info, o) > 0 || s->res.view_noise_estimated;
    if (st == SC_OK)
        st = sc_grid_budget_fill(&e, p, stated ? INFINITY : (double)s->res.dof, &s->res,
                                 &s->budget, err);
    sc_grid_est_free(&e);
    sc_grid_data_copy_free(&mask);
    return st;
}

/* The free view scales of dc (brought to the nominal plate), into b and subtracted from dc. */
static sc_status free_scales_fit(sc_grid_data *dc, const sc_grid_options *o, sc_grid_budget *b,
                                 sc_error *err)
{
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    opts.node_sigma_only = 1;
    sc_grid_est e;
    sc_status st = sc_grid_est_make(dc, &opts, 0, 1, &e, err);
    if (st == SC_OK)
        st = sc_grid_est_free_scales(&e, dc, b->view_scale_free_ppm, err);
    sc_grid_est_free(&e);
    if (st != SC_OK)
        return st;
    sc_grid_scale_subtract(dc, b->view_scale_free_ppm);
    for (int v = 0; v < dc->plan.n_views; ++v)
        b->view_scale_ppm[v] += b->view_scale_free_ppm[v];
    b->view_scale_free = 1;
    return SC_OK;
}

/* SPEC §11: the data brought to the 20 °C plate (E and each view's temperature), free view
 * scales, the calibration, then the magnification moved to the stage and the budget. d itself
 * is not changed (a corrected copy is solved: residuals are against it, i.e. the model's). */
static sc_status calibrate_scaled(sc_grid_data *d, const sc_grid_file_info *info,
                                  const char *path, const sc_grid_options *o,
                                  sc_grid_solution *s, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    int lsq = o->method == SC_GRID_METHOD_LSQ;
    memset(s, 0, sizeof *s);
    if (o->view_scale_free && !lsq)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "free view scales need least squares");
    sc_status st = sc_grid_check_method(d, info, path, o, err);
    sc_grid_budget b;
    sc_grid_data dc;
    memset(&dc, 0, sizeof dc);
    if (st == SC_OK)
        st = budget_alloc(p, &b, err);
    if (st != SC_OK)
        return st;
    for (int v = 0; v < p->n_views; ++v)
        b.view_scale_ppm[v] = sc_grid_view_scale_ppm(p, v);
    st = sc_grid_data_copy_values(d, &dc, err);
    if (st == SC_OK)
        sc_grid_scale_subtract(&dc, b.view_scale_ppm);
    if (st == SC_OK && o->view_scale_free)
        st = free_scales_fit(&dc, o, &b, err);
    if (st == SC_OK)
        st = calibrate_plain(&dc, info, path, o, s, err);
    s->budget = b; /* owned by s from here */
    if (st == SC_OK && b.magnification)
        magnification_gauge(p, s);
    if (st == SC_OK && lsq)
        st = scale_finish_lsq(&dc, info, path, o, s, err);
    sc_grid_data_copy_free(&dc);
    return st;
}

sc_status sc_grid_calibrate(sc_grid_data *d, const sc_grid_file_info *info, const char *path,
                            const sc_grid_options *o, sc_grid_solution *s, sc_error *err)
{
    if (sc_grid_scale_model_applies(&d->plan, o->view_scale_free))
        return calibrate_scaled(d, info, path, o, s, err);
    return calibrate_plain(d, info, path, o, s, err);
}

sc_status sc_grid_monte_carlo(const sc_grid_data *d, const sc_grid_options *o,
                              const sc_grid_solution *s, long trials, uint64_t seed, int threads,
                              sc_grid_mc *mc, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    memset(mc, 0, sizeof *mc);
    if (trials < 2 || o->method != SC_GRID_METHOD_LSQ || !s->rx_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the Monte Carlo needs least squares and at least 2 trials");
    sc_grid_data base;
    sc_status st = sc_grid_data_copy_values(d, &base, err);
    if (st != SC_OK)
        return st;
    size_t nn = (size_t)p->n * p->n;
    for (size_t k = 0; o->reject_outliers && k < (size_t)p->n_views * nn; ++k)
        if (s->outlier[k])
            base.dx_um[k / nn][k % nn] = base.dy_um[k / nn][k % nn] = NAN;
    sc_grid_lsq_opts opts = sc_grid_lsq_opts_of(o);
    opts.node_sigma_only = 1;
    sc_grid_est e;
    int mag = s->budget.applies && s->budget.magnification;
    st = sc_grid_est_make(&base, &opts, mag, s->budget.applies && s->budget.view_scale_free, &e,
                          err);
    if (st == SC_OK)
        st = sc_grid_mc_run(&base, o, s, &e, trials, seed, threads, mc, err);
    sc_grid_est_free(&e);
    sc_grid_data_copy_free(&base);
    return st;
}
