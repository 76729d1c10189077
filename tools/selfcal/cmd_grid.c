/* selfcal grid — separate the stage error G from the plate error A (Ye, double shift, least squares). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "plots.h"


static const char *USAGE =
    "usage: selfcal grid --method {ye,double-shift,lsq} IN.csv --map G.csv\n"
    "                    [--artifact A.csv] [--summary S.json] [--sigma-r-um X] [--plot map.svg]\n"
    "                    [--residuals R.csv] [--reject-outliers] [--covariance C.npy]\n"
    "                    [--outlier-alpha A | --outlier-alpha-each A] [--drift linear]\n"
    "                    [--view-noise stated|estimate] [--quiet]\n"
    "\n"
    "Separates the stage error G from the plate error A in a selfcal-grid v1 file and writes G in\n"
    "the SPEC gauge (--map: i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um), the plate error (--artifact:\n"
    "i,j,ax_um,ay_um), a JSON summary (--summary: O, R, misalignment per view, residual RMS, noise\n"
    "estimated and used) and an arrow plot (--plot).\n"
    "  ye            Ye et al.: views {rot 0}, {rot 90}, {shift +1,0}, all marks on the grid.\n"
    "  double-shift  Petro: {rot 0}, {rot 90}, {shift +2,0}, {shift -3,0: row c, cols c, c+1}; N >= 7.\n"
    "  lsq           optimal least squares for any plan that identifies G (see selfcal plan);\n"
    "                uncertainties (k = 1) use --sigma-r-um if given, else the noise estimated from\n"
    "                the residuals. The exact methods give no uncertainties (columns left empty).\n"
    "                With ux_um,uy_um columns or sigma_um= on view lines the measurements are\n"
    "                weighted by 1/u^2, the uncertainties use the stated u, and the summary gives\n"
    "                the variance factor and its chi^2 test at 95 %. The uncertainties of O, R\n"
    "                and the misalignments are computed for --summary only (less work without).\n"
    "  lsq options:  --residuals R.csv  view,i,j,rx_um,ry_um,tx,ty,outlier (t: standardized\n"
    "                residuals with the exact leverage; outlier: |t| beyond the critical value\n"
    "                of Baarda's data snooping); each outlier is a warning on stderr.\n"
    "                --outlier-alpha A  the test's significance for the whole data set (default\n"
    "                0.05: clean data raise a flag in 1 calibration of 20, whatever their size;\n"
    "                each of the m coordinates is tested at 1-(1-A)^(1/m), e.g. |t| > 4.4 for\n"
    "                m = 4000). --outlier-alpha-each A: A for each coordinate on its own\n"
    "                (Baarda's classical 0.001, |t| > 3.29: ~1 flag per 1000 clean coordinates).\n"
    "                --reject-outliers  remove the worst outlier, solve again, repeat.\n"
    "                --covariance C.npy  the covariance of G (um^2, numpy .npy, 2*NX*NY square,\n"
    "                node by node, gx then gy; stages up to 1681 nodes).\n"
    "                --drift linear  per-view drift rates from the t_s column as unknowns.\n"
    "                --view-noise estimate  each view's noise estimated from its residuals\n"
    "                (variance components, re-weighted until it settles): views measured with\n"
    "                different noise get their own weights and the uncertainties use them; on a\n"
    "                file stating uncertainties, a factor on them per view. Printed and in the\n"
    "                summary (sigma_um_est per view, u_sigma_um_est its standard uncertainty).\n"
    "                Excludes --sigma-r-um.\n"
    "Extra views in the file are ignored by the exact methods. Exit 2 on bad input.\n"
    "Prints a short summary (method, noise, residual RMS, O, R, the largest |G|) unless --quiet.\n";

/* Warnings of the calibration (outliers, the χ² test) go to stderr, one line each. */
static void warn_stderr(void *ctx, const char *msg)
{
    (void)ctx;
    fprintf(stderr, "selfcal: warning: %s\n", msg);
}

/* The short summary on stdout (as `selfcal profile` prints one): key: value lines. stated: the
 * data stated their uncertainties (no --sigma-r-um), so that the σ figures are factors on them. */
static void print_grid_summary(const char *method, const sc_grid_plan *p,
                               const sc_grid_solution *s, int stated)
{
    const sc_grid_result *r = &s->res;
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
    if (r->view_noise_estimated) {
        printf("sigma_r_est_um: %.6g (each view weighted by its estimated noise, view_sigma_um "
               "below: the residuals' scale on it, 1 by construction; dof %ld)\n",
               r->sigma_r_est_um, r->dof);
        printf("sigma_r_used_um: %.6g (the views' estimated noise, unscaled)\n", r->sigma_r_used_um);
    } else if (stated) {
        printf("sigma_r_est_um: %.6g (the data state their uncertainties: this is the residuals' "
               "scale on them, 1 = as stated; dof %ld)\n", r->sigma_r_est_um, r->dof);
        printf("sigma_r_used_um: %.6g (the stated uncertainties, unscaled)\n", r->sigma_r_used_um);
    } else {
        printf("sigma_r_est_um: %.6g (from the least-squares residuals, dof %ld)\n",
               r->sigma_r_est_um, r->dof);
        if (isfinite(r->sigma_r_used_um))
            printf("sigma_r_used_um: %.6g (for the uncertainties)\n", r->sigma_r_used_um);
    }
    printf("residual_rms_um: %.6g\nO: %.6g\nR: %.6g\n", r->residual_rms_um, r->O, r->R);
    printf("O_urad: %.6g\nR_ppm: %.6g\n", r->O * 1e6, r->R * 1e6);
    printf("worst_node: %d,%d at (%g, %g) mm: |G| = %.6g um (gx %.6g, gy %.6g)", i, j,
           x_mm + p->origin_mm[0], y_mm + p->origin_mm[1], worst_um, r->gx_um[worst], r->gy_um[worst]);
    if (isfinite(r->ugx_um[worst]))
        printf(", u = %.3g, %.3g um", r->ugx_um[worst], r->ugy_um[worst]);
    putchar('\n');
    if (r->view_noise_estimated) {
        printf("view_sigma_um:");
        for (int v = 0; v < p->n_views; ++v)
            printf(" %.4g", r->view_sigma_um[v]);
        printf(" (estimated per view, %d re-weighted solves)\nview_sigma_u_um:",
               r->view_noise_iterations);
        for (int v = 0; v < p->n_views; ++v)
            printf(" %.2g", r->view_sigma_u_um[v]);
        printf(" (their standard uncertainties)\n");
    }
    if (isfinite(r->outlier_crit))
        printf("outliers: %ld flagged, %ld removed (|t| > %.4g: alpha %g %s)\n", s->n_flagged,
               s->n_removed, r->outlier_crit, r->outlier_alpha,
               r->outlier_alpha_each ? "for each coordinate" : "for the whole data set");
}

/* What the command line asks for. */
typedef struct grid_args {
    const char *method, *in, *map, *art, *sum, *plot, *residuals, *covariance;
    sc_grid_options opt;
    int quiet;
} grid_args;

/* Parse the arguments into g: -1 to go on, else the exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, grid_args *g)
{
    memset(g, 0, sizeof *g);
    sc_grid_options_default(&g->opt);
    g->opt.max_bytes = cli_memory_bytes();
    g->opt.warn = warn_stderr;
    for (int a = 1; a < argc; ++a) {
        const char *o = argv[a];
        if (!strcmp(o, "--help") || !strcmp(o, "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        if (!strcmp(o, "--reject-outliers")) {
            g->opt.reject_outliers = 1;
            continue;
        }
        if (!strcmp(o, "--quiet")) {
            g->quiet = 1;
            continue;
        }
        if (o[0] != '-' || !strcmp(o, "-")) {
            if (g->in)
                return cli_usage_error("grid", "more than one input file ('%s', '%s')", g->in, o);
            g->in = o;
            continue;
        }
        if (a + 1 >= argc)
            return cli_usage_error("grid", "%s: unknown option or missing value (see --help)", o);
        const char *v = argv[++a];
        int rc = cli_parse_lsq_option("grid", o, v, &g->opt); /* the outlier test, view noise */
        if (rc >= 0) {
            if (rc != CLI_OK)
                return rc;
            continue;
        }
        if (!strcmp(o, "--method")) g->method = v;
        else if (!strcmp(o, "--map")) g->map = v;
        else if (!strcmp(o, "--artifact")) g->art = v;
        else if (!strcmp(o, "--summary")) g->sum = v;
        else if (!strcmp(o, "--plot")) g->plot = v;
        else if (!strcmp(o, "--residuals")) g->residuals = v;
        else if (!strcmp(o, "--covariance")) g->covariance = v;
        else if (!strcmp(o, "--drift")) {
            if (strcmp(v, "linear") != 0 && strcmp(v, "none") != 0)
                return cli_usage_error("grid", "--drift must be linear or none, got '%s'", v);
            g->opt.drift = !strcmp(v, "linear");
        }
        else if (!strcmp(o, "--sigma-r-um")) {
            if (sc_parse_double(v, &g->opt.sigma_r_um) || !(g->opt.sigma_r_um > 0) ||
                !(g->opt.sigma_r_um <= SC_INPUT_MAX_ABS))
                return cli_usage_error("grid", "--sigma-r-um needs a positive number of um (at "
                                               "most 1e6), got '%s'", v);
        } else
            return cli_usage_error("grid", "unknown option '%s' (see --help)", o);
    }
    if (!g->method || !g->in || !g->map)
        return cli_usage_error("grid", "--method, IN.csv and --map are required (see --help)");
    int m = sc_grid_method_from_name(g->method);
    if (m < 0)
        return cli_usage_error("grid", "--method must be ye, double-shift or lsq (got '%s')",
                               g->method);
    g->opt.method = (sc_grid_method)m;
    if (g->opt.estimate_view_noise && g->opt.sigma_r_um > 0) /* options, not the file's lines */
        return cli_usage_error("grid", "--sigma-r-um and --view-noise estimate exclude each other "
                                       "(a given noise, or each view's estimated)");
    g->opt.covariance = g->covariance != NULL;
    /* the σ of O, R and the misalignments goes to the summary file only: not computed without it
     * (every node's σ and the outlier test are the same either way) */
    g->opt.node_sigma_only = g->sum == NULL;
    if (m != SC_GRID_METHOD_LSQ &&
        (g->residuals || g->covariance || g->opt.reject_outliers || g->opt.drift))
        return cli_usage_error("grid", "--residuals, --reject-outliers, --covariance and --drift "
                                       "need --method lsq");
    return -1;
}

/* Everything is computed: write every output asked for, commit them together (all or none). */
static sc_status write_outputs(const grid_args *g, const sc_grid_plan *p,
                               const sc_grid_solution *sol, const sc_grid_file_info *info,
                               sc_error *err)
{
    const sc_grid_result *res = &sol->res;
    const char *paths[6] = {g->map, g->art, g->sum, g->plot, g->residuals, g->covariance};
    sc_afile f[6];
    memset(f, 0, sizeof f); /* entries not opened stay closed (fp == NULL) */
    int opened = 0;
    sc_status st = SC_OK;
    sc_stage_map gm = sc_grid_stage_map(p, res->gx_um, res->gy_um, res->ugx_um, res->ugy_um);
    for (; opened < 6; ++opened) {
        if (!paths[opened])
            continue;
        st = sc_afile_open(&f[opened], paths[opened], err);
        if (st != SC_OK)
            break;
        switch (opened) {
        case 0: sc_grid_fprint_map(f[0].fp, p, res->gx_um, res->gy_um, res->ugx_um, res->ugy_um); break;
        case 1: sc_grid_fprint_artifact(f[1].fp, p, res->ax_um, res->ay_um); break;
        case 2: sc_grid_fprint_summary(f[2].fp, g->method, p, res); break;
        case 3: plot_map_svg(f[3].fp, &gm, NULL, 0, cli_basename(g->in), 0); break;
        case 4:
            sc_grid_fprint_residuals(f[4].fp, p, info->view_id, sol->rx_um, sol->ry_um, sol->tx,
                                     sol->ty, sol->outlier);
            break;
        case 5: sc_fprint_npy(f[5].fp, sol->cov_um2, sol->n_cov, sol->n_cov); break;
        }
    }
    /* all files or none: sync every one, then rename them together */
    return sc_afile_finish_all(f, opened, st, err);
}

int cmd_grid(int argc, char **argv)
{
    grid_args g;
    int rc = parse_args(argc, argv, &g);
    if (rc >= 0)
        return rc;
    sc_error err;
    sc_error_clear(&err);
    sc_grid_data d;
    sc_grid_file_info info;
    sc_status st = sc_grid_read(g.in, &d, &info, &err);
    if (st != SC_OK)
        return cli_report(&err);
    sc_grid_solution sol;
    st = sc_grid_calibrate(&d, &info, g.in, &g.opt, &sol, &err);
    if (st == SC_OK)
        st = write_outputs(&g, &d.plan, &sol, &info, &err);
    if (st == SC_OK && !g.quiet)
        print_grid_summary(g.method, &d.plan, &sol, sol.res.stated_u);
    sc_grid_solution_free(&sol);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);
    if (st != SC_OK) {
        if (!err.file[0] && (err.code == SC_E_INPUT || err.code == SC_E_UNSOLVABLE)) {
            snprintf(err.file, sizeof err.file, "%s", g.in);
            if (!err.line)
                err.line = info.header_end_line;
        }
        return cli_report(&err);
    }
    return CLI_OK;
}
