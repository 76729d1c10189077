/* selfcal grid — separate the stage error G from the plate error A (Ye, double shift, least squares). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_exact.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "plots.h"
#include "grid_run.h"


static const char *USAGE =
    "usage: selfcal grid --method {ye,double-shift,lsq} IN.csv --map G.csv\n"
    "                    [--artifact A.csv] [--summary S.json] [--sigma-r-um X] [--plot map.svg]\n"
    "                    [--residuals R.csv] [--reject-outliers] [--covariance C.npy]\n"
    "                    [--drift linear] [--quiet]\n"
    "\n"
    "Separates the stage error G from the plate error A in a selfcal-grid v1 file and writes G in\n"
    "the SPEC gauge (--map: i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um), the plate error (--artifact:\n"
    "i,j,ax_um,ay_um), a JSON summary (--summary: O, R, misalignment per view, residual RMS, noise\n"
    "estimated and used) and an arrow plot (--plot).\n"
    "  ye            Ye et al.: views {rot 0}, {rot 90}, {shift +1,0}, all marks on the grid.\n"
    "  double-shift  Petro: {rot 0}, {rot 90}, {shift +2,0}, {shift -3,0: row c, cols c, c+1}; N >= 9.\n"
    "  lsq           optimal least squares for any plan that identifies G (see selfcal plan);\n"
    "                uncertainties (k = 1) use --sigma-r-um if given, else the noise estimated from\n"
    "                the residuals. The exact methods give no uncertainties (columns left empty).\n"
    "                With ux_um,uy_um columns or sigma_um= on view lines the measurements are\n"
    "                weighted by 1/u^2, the uncertainties use the stated u, and the summary gives\n"
    "                the variance factor and its chi^2 test at 95 %.\n"
    "  lsq options:  --residuals R.csv  view,i,j,rx_um,ry_um,tx,ty,outlier (t: standardized\n"
    "                residuals with the exact leverage; outlier: Baarda's data snooping at\n"
    "                alpha = 0.001, |t| > 3.29); each outlier is a warning on stderr.\n"
    "                --reject-outliers  remove the worst outlier, solve again, repeat.\n"
    "                --covariance C.npy  the covariance of G (um^2, numpy .npy, 2*NX*NY square,\n"
    "                node by node, gx then gy; stages up to 1681 nodes).\n"
    "                --drift linear  per-view drift rates from the t_s column as unknowns.\n"
    "Extra views in the file are ignored by the exact methods. Exit 2 on bad input.\n"
    "Prints a short summary (method, noise, residual RMS, O, R, the largest |G|) unless --quiet.\n";

typedef struct need_view {
    int rot, sx, sy;
    int partial; /* 1: only plate row c and columns c, c+1 are needed (double shift view 3) */
} need_view;

/* Check that the views a closed-form method needs are declared and completely measured. */
static sc_status check_views(const char *path, const sc_grid_data *d, const sc_grid_file_info *info,
                             const char *method, const need_view *need, int n_need, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    int n = p->n, c = (n - 1) / 2;
    for (int k = 0; k < n_need; ++k) {
        int v = sc_grid_find_view(p, need[k].rot, need[k].sx, need[k].sy);
        if (v < 0)
            return sc_error_set(err, SC_E_INPUT, path, info->header_end_line,
                                "method %s needs a view rot=%d shift=%d,%d, which the header does "
                                "not declare",
                                method, need[k].rot, need[k].sx, need[k].sy);
        if (info->view_rows[v] == 0)
            return sc_error_set(err, SC_E_INPUT, path, info->view_line[v],
                                "view %d (rot=%d shift=%d,%d), needed by method %s, has no data rows",
                                info->view_id[v], need[k].rot, need[k].sx, need[k].sy, method);
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                int ni, nj;
                if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    continue;
                if (need[k].partial && i != c && j != c && j != c + 1)
                    continue;
                if (!isfinite(d->dx_um[v][i * n + j]))
                    return sc_error_set(err, SC_E_INPUT, path, info->view_line[v],
                                        "view %d (rot=%d shift=%d,%d) lacks mark (%d,%d), which "
                                        "method %s needs",
                                        info->view_id[v], need[k].rot, need[k].sx, need[k].sy, i,
                                        j, method);
            }
    }
    return SC_OK;
}

sc_status grid_check_exact_views(const char *path, const sc_grid_data *d,
                                 const sc_grid_file_info *info, int double_shift, sc_error *err)
{
    if (!double_shift) {
        need_view need[3] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 1, 0, 0}};
        return check_views(path, d, info, "ye", need, 3, err);
    }
    if (d->plan.n < 9)
        return sc_error_set(err, SC_E_INPUT, path, info->n_line,
                            "method double-shift needs N >= 9 (N = %d)", d->plan.n);
    need_view need[4] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 2, 0, 0}, {0, -3, 0, 1}};
    return check_views(path, d, info, "double-shift", need, 4, err);
}

/* The measurement noise behind data solved by a closed form: the closed forms are not
 * least-squares fits, so their residuals do not estimate σ_r without bias; the least-squares
 * residuals of the same data and model do (sqrt(RSS/dof)). NaN if the data leave no
 * redundancy or do not identify the model. */
static double exact_noise_estimate(const sc_grid_plan *p, const sc_grid_data *d)
{
    sc_grid_lsq *q = NULL;
    sc_grid_result r;
    memset(&r, 0, sizeof r); /* no arrays: only the scalars are wanted */
    r.sigma_r_est_um = NAN;
    sc_grid_lsq_info qi;
    if (sc_grid_lsq_create(p, d, &q, NULL) == SC_OK) {
        sc_grid_lsq_get_info(q, &qi);
        if (!qi.identifiable || sc_grid_lsq_solve(q, d, 0.0, &r, NULL) != SC_OK)
            r.sigma_r_est_um = NAN;
    }
    sc_grid_lsq_destroy(q);
    return r.sigma_r_est_um;
}

/* What the least-squares run adds to the outputs. */
typedef struct lsq_extra {
    const char *residuals, *covariance;
    int reject, drift;
    double *rx, *ry, *tx, *ty; /* n_views*n*n */
    unsigned char *outlier;
    double *cov;
    long n_cov;
} lsq_extra;

static void lsq_extra_free(lsq_extra *x)
{
    free(x->rx), free(x->ry), free(x->tx), free(x->ty), free(x->outlier), free(x->cov);
}

/* The worst flagged measurement not yet removed: index v*n*n + k, or -1. */
static long worst_outlier(const lsq_extra *x, size_t tot)
{
    long best = -1;
    double bt = SC_GRID_BAARDA_CRIT;
    for (size_t k = 0; k < tot; ++k) {
        double t = fmax(isfinite(x->tx[k]) ? fabs(x->tx[k]) : 0, isfinite(x->ty[k]) ? fabs(x->ty[k]) : 0);
        if (!x->outlier[k] && t > bt)
            bt = t, best = (long)k;
    }
    return best;
}

/* After the last solve: residuals of the removed rows against the final solution (and their
 * values back into d), the flags and warnings of the rows still in, the chi-square warning. */
static void finish_outliers(const char *in, sc_grid_data *d, const sc_grid_file_info *info,
                            const sc_grid_result *res, lsq_extra *x, const sc_grid_lsq *q,
                            const double *keep, double sigma_r)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n, tot = (size_t)p->n_views * nn;
    for (size_t k = 0; k < tot; ++k) {
        int v = (int)(k / nn), m = (int)(k % nn);
        if (x->outlier[k]) { /* removed: residual against the final solution */
            double px, py, t = d->t_s[v] ? d->t_s[v][m] : NAN;
            sc_grid_lsq_predict(q, res, v, m / p->n, m % p->n, t, &px, &py);
            x->rx[k] = keep[k] - px, x->ry[k] = keep[tot + k] - py;
            x->tx[k] = x->ty[k] = NAN;
            d->dx_um[v][m] = keep[k], d->dy_um[v][m] = keep[tot + k];
        } else if (fabs(x->tx[k]) > SC_GRID_BAARDA_CRIT || fabs(x->ty[k]) > SC_GRID_BAARDA_CRIT) {
            x->outlier[k] = 1;
            fprintf(stderr,
                    "selfcal: warning: %s: view %d mark (%d,%d) is an outlier (standardized "
                    "residuals tx %.3g, ty %.3g beyond %.3f: Baarda, alpha = %g)\n",
                    in, info->view_id[v], m / p->n, m % p->n, x->tx[k], x->ty[k],
                    SC_GRID_BAARDA_CRIT, SC_GRID_BAARDA_ALPHA);
        }
    }
    if (!res->chi2_pass)
        fprintf(stderr,
                "selfcal: warning: %s: the residuals disagree with the %s noise: variance "
                "factor %.4g outside the chi^2 95 %% interval [%.4g, %.4g]%s\n",
                in, sigma_r > 0 ? "given" : "stated", res->variance_factor, res->chi2_lo,
                res->chi2_hi,
                sigma_r > 0 ? " (compare sigma_r_est_um in the summary with --sigma-r-um)"
                            : "");
}

/* Least squares with residuals, outlier handling and covariance. d is modified (rejected rows
 * become NaN); orig keeps the measured values for their residuals. */
static sc_status run_lsq(const char *in, sc_grid_data *d, const sc_grid_file_info *info,
                         double sigma_r, sc_grid_result *res, lsq_extra *x, sc_grid_lsq **qp,
                         sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n, tot = (size_t)p->n_views * nn;
    sc_grid_lsq_opts opts = {x->drift};
    x->rx = malloc(tot * sizeof(double)), x->ry = malloc(tot * sizeof(double));
    x->tx = malloc(tot * sizeof(double)), x->ty = malloc(tot * sizeof(double));
    x->outlier = calloc(tot, 1);
    double *keep = malloc(2 * tot * sizeof(double));
    if (!x->rx || !x->ry || !x->tx || !x->ty || !x->outlier || !keep) {
        free(keep);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k)
            keep[v * nn + k] = d->dx_um[v][k], keep[tot + v * nn + k] = d->dy_um[v][k];
    sc_status st;
    long pending = -1; /* the row just removed, confirmed once G stays identified without it */
    int stop = 0;
    for (;;) {
        sc_grid_lsq_destroy(*qp);
        *qp = NULL;
        st = sc_grid_lsq_create_ex(p, d, &opts, qp, err);
        if (st != SC_OK)
            break;
        sc_grid_lsq_info qi;
        sc_grid_lsq_get_info(*qp, &qi);
        if (pending >= 0) {
            int v = (int)(pending / (long)nn), k = (int)(pending % (long)nn);
            if (!qi.identifiable) { /* the outlier is the only link: keep it, stop rejecting */
                d->dx_um[v][k] = keep[pending], d->dy_um[v][k] = keep[tot + pending];
                x->outlier[pending] = 0;
                fprintf(stderr,
                        "selfcal: warning: %s: outlier view %d mark (%d,%d) kept: without it "
                        "the views would not identify G\n",
                        in, info->view_id[v], k / p->n, k % p->n);
                pending = -1, stop = 1;
                continue;
            }
            fprintf(stderr,
                    "selfcal: warning: %s: removed outlier view %d mark (%d,%d) (tx %.3g, ty "
                    "%.3g; critical value %.3f) and solved again\n",
                    in, info->view_id[v], k / p->n, k % p->n, x->tx[pending], x->ty[pending],
                    SC_GRID_BAARDA_CRIT);
            pending = -1;
        }
        if (!qi.identifiable) {
            st = sc_error_set(err, SC_E_UNSOLVABLE, in, info->header_end_line,
                              "the measured views do not identify G: %ld degree(s) of freedom "
                              "beyond the gauge stay free (see 'selfcal plan')",
                              qi.free_dof);
            break;
        }
        st = sc_grid_lsq_solve(*qp, d, sigma_r, res, err);
        if (st == SC_OK)
            st = sc_grid_lsq_residuals(*qp, x->rx, x->ry, x->tx, x->ty, NULL, err);
        if (st != SC_OK || !x->reject || stop)
            break;
        long w = worst_outlier(x, tot);
        if (w < 0)
            break;
        x->outlier[w] = 1;
        d->dx_um[w / (long)nn][w % (long)nn] = d->dy_um[w / (long)nn][w % (long)nn] = NAN;
        pending = w;
    }
    if (st == SC_OK)
        finish_outliers(in, d, info, res, x, *qp, keep, sigma_r);
    if (st == SC_OK && x->covariance) {
        long m = 2 * sc_grid_stage_nodes(p);
        x->cov = m <= 2L * SC_GRID_LSQ_COV_MAX_NODES ? malloc((size_t)m * m * sizeof(double)) : NULL;
        if (m > 2L * SC_GRID_LSQ_COV_MAX_NODES)
            st = sc_error_set(err, SC_E_INPUT, in, info->header_end_line,
                              "--covariance: %ld stage nodes exceed the limit of %d",
                              m / 2, SC_GRID_LSQ_COV_MAX_NODES);
        else if (!x->cov)
            st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (covariance)");
        else
            st = sc_grid_lsq_covariance(*qp, x->cov, err);
        x->n_cov = m;
    }
    free(keep);
    return st;
}

/* The short summary on stdout (as `selfcal profile` prints one): key: value lines. */
static void print_grid_summary(const char *method, const sc_grid_plan *p, const sc_grid_result *r)
{
    int nx = sc_grid_stage_nx(p);
    long ns = sc_grid_stage_nodes(p), worst = 0;
    double worst_um = -1;
    for (long k = 0; k < ns; ++k) {
        double g = hypot(r->gx_um[k], r->gy_um[k]);
        if (g > worst_um) {
            worst_um = g;
            worst = k;
        }
    }
    int i = (int)(worst / nx), j = (int)(worst % nx);
    double x_mm, y_mm;
    sc_grid_node_xy_mm(p, i, j, &x_mm, &y_mm);
    printf("method: %s\nN: %d\n", method, p->n);
    if (!sc_grid_stage_is_plate(p))
        printf("stage: %d x %d nodes\n", nx, sc_grid_stage_ny(p));
    printf("views: %d\n", p->n_views);
    printf("sigma_r_est_um: %.6g (from the least-squares residuals, dof %ld)\n", r->sigma_r_est_um,
           r->dof);
    if (isfinite(r->sigma_r_used_um))
        printf("sigma_r_used_um: %.6g (for the uncertainties)\n", r->sigma_r_used_um);
    printf("residual_rms_um: %.6g\nO: %.6g\nR: %.6g\n", r->residual_rms_um, r->O, r->R);
    printf("worst_node: %d,%d at (%g, %g) mm: |G| = %.6g um (gx %.6g, gy %.6g)", i, j,
           x_mm + p->origin_mm[0], y_mm + p->origin_mm[1], worst_um, r->gx_um[worst], r->gy_um[worst]);
    if (isfinite(r->ugx_um[worst]))
        printf(", u = %.3g, %.3g um", r->ugx_um[worst], r->ugy_um[worst]);
    putchar('\n');
}

int cmd_grid(int argc, char **argv)
{
    const char *method = NULL, *in = NULL, *map = NULL, *art = NULL, *sum = NULL, *plot = NULL;
    double sigma_r = 0;
    lsq_extra lx;
    memset(&lx, 0, sizeof lx);
    int quiet = 0;
    for (int a = 1; a < argc; ++a) {
        const char *o = argv[a];
        if (!strcmp(o, "--help") || !strcmp(o, "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        if (!strcmp(o, "--reject-outliers")) {
            lx.reject = 1;
            continue;
        }
        if (!strcmp(o, "--quiet")) {
            quiet = 1;
            continue;
        }
        if (o[0] != '-' || !strcmp(o, "-")) {
            if (in)
                return cli_usage_error("grid", "more than one input file ('%s', '%s')", in, o);
            in = o;
            continue;
        }
        if (a + 1 >= argc)
            return cli_usage_error("grid", "'%s' needs a value (see --help)", o);
        const char *v = argv[++a];
        if (!strcmp(o, "--method")) method = v;
        else if (!strcmp(o, "--map")) map = v;
        else if (!strcmp(o, "--artifact")) art = v;
        else if (!strcmp(o, "--summary")) sum = v;
        else if (!strcmp(o, "--plot")) plot = v;
        else if (!strcmp(o, "--residuals")) lx.residuals = v;
        else if (!strcmp(o, "--covariance")) lx.covariance = v;
        else if (!strcmp(o, "--drift")) {
            if (strcmp(v, "linear") != 0 && strcmp(v, "none") != 0)
                return cli_usage_error("grid", "--drift must be linear or none, got '%s'", v);
            lx.drift = !strcmp(v, "linear");
        }
        else if (!strcmp(o, "--sigma-r-um")) {
            if (sc_parse_double(v, &sigma_r) || !(sigma_r > 0))
                return cli_usage_error("grid", "--sigma-r-um needs a positive number, got '%s'", v);
        } else
            return cli_usage_error("grid", "unknown option '%s' (see --help)", o);
    }
    if (!method || !in || !map)
        return cli_usage_error("grid", "--method, IN.csv and --map are required (see --help)");
    int m_ye = !strcmp(method, "ye"), m_ds = !strcmp(method, "double-shift"),
        m_lsq = !strcmp(method, "lsq");
    if (!m_ye && !m_ds && !m_lsq)
        return cli_usage_error("grid", "--method must be ye, double-shift or lsq (got '%s')",
                               method);
    if (!m_lsq && (lx.residuals || lx.covariance || lx.reject || lx.drift))
        return cli_usage_error("grid", "--residuals, --reject-outliers, --covariance and --drift "
                                       "need --method lsq");

    sc_error err;
    sc_error_clear(&err);
    sc_grid_data d;
    sc_grid_file_info info;
    sc_status st = sc_grid_read(in, &d, &info, &err);
    if (st != SC_OK)
        return cli_report(&err);
    const sc_grid_plan *p = &d.plan;
    int n = p->n, c = (n - 1) / 2;
    size_t nn = (size_t)n * n, ns = (size_t)sc_grid_stage_nodes(p);
    double *buf = NULL;
    sc_grid_result res;
    memset(&res, 0, sizeof res);
    sc_grid_exact_plan *xp = NULL;
    sc_grid_lsq *q = NULL;

    if (info.n_rows == 0) {
        st = sc_error_set(&err, SC_E_INPUT, in, info.header_end_line,
                          "no data rows (a plan file? use 'selfcal plan' for plans)");
        goto done;
    }
    if (!m_lsq && !sc_grid_stage_is_plate(p)) {
        st = sc_error_set(&err, SC_E_INPUT, in, info.header_end_line,
                          "method %s needs the stage grid to be the plate's N x N (this file has "
                          "a %dx%d stage: use --method lsq)",
                          method, sc_grid_stage_nx(p), sc_grid_stage_ny(p));
        goto done;
    }
    if (m_lsq && sigma_r > 0 && info.has_u) {
        st = sc_error_set(&err, SC_E_INPUT, in, info.header_end_line,
                          "the file states uncertainties (ux_um,uy_um): --sigma-r-um applies to "
                          "files without them");
        goto done;
    }
    for (int v = 0; m_lsq && sigma_r > 0 && v < p->n_views; ++v)
        if (p->view[v].sigma_um > 0) {
            st = sc_error_set(&err, SC_E_INPUT, in, info.view_line[v],
                              "view %d states sigma_um: --sigma-r-um applies to files without "
                              "stated uncertainties",
                              info.view_id[v]);
            goto done;
        }
    if (lx.drift && !info.has_t) {
        st = sc_error_set(&err, SC_E_INPUT, in, info.header_end_line,
                          "--drift linear needs the time of each measurement (column t_s)");
        goto done;
    }
    if (m_ye || m_ds)
        st = grid_check_exact_views(in, &d, &info, m_ds, &err);
    (void)c;
    if (st != SC_OK)
        goto done;

    buf = malloc((4 * ns + 2 * nn) * sizeof(double));
    if (!buf) {
        st = sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto done;
    }
    for (size_t k = 0; k < 4 * ns + 2 * nn; ++k)
        buf[k] = NAN;
    res.gx_um = buf;
    res.gy_um = buf + ns;
    res.ugx_um = buf + 2 * ns;
    res.ugy_um = buf + 3 * ns;
    res.ax_um = buf + 4 * ns;
    res.ay_um = buf + 4 * ns + nn;
    res.O = res.R = res.residual_rms_um = res.sigma_r_est_um = res.sigma_r_used_um = NAN;
    res.uO = res.uR = res.variance_factor = res.chi2_lo = res.chi2_hi = NAN;
    res.chi2_pass = 1;
    res.misalignment_unique = 1;
    for (int v = 0; v < SC_GRID_MAX_VIEWS; ++v)
        res.tx_um[v] = res.ty_um[v] = res.theta_urad[v] = res.utx_um[v] = res.uty_um[v] =
            res.utheta_urad[v] = NAN;

    if (m_lsq) {
        st = run_lsq(in, &d, &info, sigma_r, &res, &lx, &q, &err);
    } else {
        st = sc_grid_exact_plan_create(m_ye ? SC_GRID_YE : SC_GRID_DOUBLE_SHIFT, n, &xp, &err);
        if (st == SC_OK)
            st = sc_grid_exact_execute(xp, &d, &res, &err);
        if (st == SC_OK) {
            /* No uncertainties from the closed forms: --sigma-r-um has nothing to scale. */
            for (size_t k = 0; k < nn; ++k)
                res.ugx_um[k] = res.ugy_um[k] = NAN;
            res.sigma_r_used_um = NAN;
            res.sigma_r_est_um = exact_noise_estimate(p, &d);
        }
    }
    if (st != SC_OK)
        goto done;
    sc_grid_first_order(p, res.gx_um, res.gy_um, &res.O, &res.R);
    for (size_t k = 0; k < ns + nn; ++k) {
        int bad = k < ns ? !isfinite(res.gx_um[k]) || !isfinite(res.gy_um[k])
                         : isfinite(res.ax_um[k - ns]) != isfinite(res.ay_um[k - ns]);
        if (bad) {
            st = sc_error_set(&err, SC_E_INTERNAL, in, 0, "the %s solution is not finite", method);
            goto done;
        }
    }

    /* Everything is computed: write all outputs, commit them together. */
    {
        const char *paths[6] = {map, art, sum, plot, lx.residuals, lx.covariance};
        sc_afile f[6];
        memset(f, 0, sizeof f); /* entries not opened stay closed (fp == NULL) */
        int opened = 0;
        sc_stage_map gm = sc_grid_stage_map(p, res.gx_um, res.gy_um, res.ugx_um, res.ugy_um);
        for (; opened < 6; ++opened) {
            if (!paths[opened])
                continue;
            st = sc_afile_open(&f[opened], paths[opened], &err);
            if (st != SC_OK)
                break;
            switch (opened) {
            case 0: sc_grid_fprint_map(f[0].fp, p, res.gx_um, res.gy_um, res.ugx_um, res.ugy_um); break;
            case 1: sc_grid_fprint_artifact(f[1].fp, p, res.ax_um, res.ay_um); break;
            case 2: sc_grid_fprint_summary(f[2].fp, method, p, &res); break;
            case 3: plot_map_svg(f[3].fp, &gm, NULL, 0, cli_basename(in), 0); break;
            case 4:
                sc_grid_fprint_residuals(f[4].fp, p, info.view_id, lx.rx, lx.ry, lx.tx, lx.ty,
                                         lx.outlier);
                break;
            case 5: sc_fprint_npy(f[5].fp, lx.cov, lx.n_cov, lx.n_cov); break;
            }
        }
        /* all files or none: sync every one, then rename them together */
        if (st == SC_OK)
            st = sc_afile_commit_all(f, opened, &err);
        else
            sc_afile_abort_all(f, opened);
    }
    if (st == SC_OK && !quiet)
        print_grid_summary(method, p, &res);

done:
    lsq_extra_free(&lx);
    sc_grid_lsq_destroy(q);
    sc_grid_exact_plan_destroy(xp);
    free(buf);
    sc_grid_data_free(&d);
    if (st != SC_OK) {
        if (!err.file[0] && (err.code == SC_E_INPUT || err.code == SC_E_UNSOLVABLE)) {
            snprintf(err.file, sizeof err.file, "%s", in);
            if (!err.line)
                err.line = info.header_end_line;
        }
        return cli_report(&err);
    }
    return CLI_OK;
}
