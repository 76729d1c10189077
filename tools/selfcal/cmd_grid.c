/* selfcal grid — separate the stage error G from the plate error A (Ye, double shift, least squares). */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "plots.h"


static const char USAGE[] =
    "usage: selfcal grid --method {ye,double-shift,lsq} IN.csv --map G.csv\n"
    "                    [--artifact A.csv] [--summary S.json] [--sigma-r-um X] [--plot map.svg]\n"
    "                    [--residuals R.csv] [--reject-outliers] [--covariance C.npy]\n"
    "                    [--outlier-alpha A | --outlier-alpha-each A] [--drift linear]\n"
    "                    [--view-noise stated|estimate] [--view-scale model|free]\n"
    "                    [--monte-carlo M [--seed S] [--monte-carlo-out MC.csv]] [--quiet]\n"
    "                    [--progress] [--max-memory SIZE] [--solver auto|reduced|full]\n"
    "                    [--node-sigma all|none|sample:K]\n"
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
    "                --covariance C.npy  the covariance of G (um^2, numpy .npy, 2*NX*NY square,\n"
    "                node by node, gx then gy; stages up to 1681 nodes).\n"
    "                --view-noise estimate  each view's noise estimated from its residuals\n"
    "                (variance components, re-weighted until it settles): views measured with\n"
    "                different noise get their own weights and the uncertainties use them; on a\n"
    "                file stating uncertainties, a factor on them per view. Printed and in the\n"
    "                summary (sigma_um_est per view, u_sigma_um_est its standard uncertainty).\n"
    "                Excludes --sigma-r-um.\n"
    "Scale and temperature (SPEC 11): with '# plate_scale_ppm = E, U' G includes the stage's\n"
    "magnification M (summary: magnification_ppm, u_magnification_ppm); without it G carries no\n"
    "magnification: the scale is not included. With '# plate_cte_ppm_per_K = A, U' and temp_C=\n"
    "on every view line, the plate of each view is brought to 20 C first. With least squares the\n"
    "map's ugx_um, ugy_um then combine the noise with the contributions of U, of A's uncertainty\n"
    "and of the temperatures' (# temp_u_K, default 0.05 K), and the summary has the budget at\n"
    "the worst node (k = 2, or Welch-Satterthwaite's t when sigma_r has few degrees of freedom).\n"
    "                --view-scale free  each view's scale relative to the others is an unknown\n"
    "                (a laboratory without a temperature log); their mean is the plate's model\n"
    "                scale. Printed with their uncertainties; a warning when they are significant.\n"
    "                --monte-carlo M  validates the budget (JCGM 101): M trials drawing the noise,\n"
    "                E, A and every temperature, the whole estimator each time, on both cores;\n"
    "                --seed S (default 1); the summary's monte_carlo: the ratios MC u / budget u;\n"
    "                --monte-carlo-out: per node the MC u, the ratio and 95 % coverage intervals.\n"
    "Extra views in the file are ignored by the exact methods. Exit 2 on bad input.\n"
    "Prints a short summary (method, noise, residual RMS, O, R, the largest |G|) unless --quiet.\n"
    "--progress: the phase of a least-squares solve (read, assemble, analyse, factor, selected\n"
    "inverse, solve, residuals, write), the time so far and, once the factor's rate is known, the\n"
    "time left, and the peak memory estimated before the assembly, on stderr (shown anyway on a\n"
    "terminal: one line, rewritten). A plan whose estimated peak exceeds the memory allowed is\n"
    "refused before it is assembled or factored (exit 1): by default the machine's available\n"
    "memory (MemAvailable), or --max-memory SIZE (bytes, or K, M, G, T: powers of 1024).\n"
    "--solver (lsq): which normal matrix is factored: reduced (the plate error A eliminated:\n"
    "plate-sized stages, a few views), full (A kept as unknowns: stitched stages of hundreds of\n"
    "placements, where eliminating A would couple every node a mark lands on to every other) or\n"
    "auto (the default: full when a mark is measured in more than about 17 views on average;\n"
    "docs/grid-lsq.md gives the rule). Both give the same results.\n"
    "--node-sigma (lsq): all (the default): every node's uncertainty and every measurement's\n"
    "leverage (the selected inverse, about the factor's cost again; the outlier test needs it);\n"
    "none: neither (ugx_um, ugy_um and the residuals' t left empty, no outlier test);\n"
    "sample:K: the uncertainty of K nodes spread over the stage, by solves (the others empty).\n"
    "none and sample:K exclude --reject-outliers and --view-noise estimate.\n";

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
    const char *method, *in, *map, *art, *sum, *plot, *residuals, *covariance, *mc_out;
    sc_grid_options opt;
    int quiet, progress;
    long mc_trials;          /* --monte-carlo M (0: none) */
    uint64_t mc_seed;
} grid_args;

#define F(field) offsetof(grid_args, field)
/* grid's options (cli_opts.h), in the order of its --help */
static const cli_opt GRID_OPTS[] = {
    {"--method", CLI_STRING, F(method), "ye|double-shift|lsq", .help = "the method (required)"},
    {"--map", CLI_STRING, F(map), "G.csv", .help = "the stage error G (required)"},
    {"--artifact", CLI_STRING, F(art), "A.csv", .help = "the plate error A"},
    {"--summary", CLI_STRING, F(sum), "S.json", .help = "a JSON summary"},
    {"--sigma-r-um", CLI_DOUBLE, F(opt.sigma_r_um), "X", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .bad = "--sigma-r-um needs a positive number of um (at most 1e6), got '%s'",
     .def = "estimated from the residuals", .help = "the measurement noise for the uncertainties (um)"},
    {"--plot", CLI_STRING, F(plot), "map.svg", .help = "an arrow plot of G"},
    {"--residuals", CLI_STRING, F(residuals), "R.csv",
     .help = "lsq: the residuals, standardized, and the outlier test"},
    {"--reject-outliers", CLI_FLAG, F(opt.reject_outliers),
     .help = "lsq: remove the worst outlier, solve again, repeat"},
    {"--covariance", CLI_STRING, F(covariance), "C.npy", .help = "lsq: the covariance of G (um^2)"},
    {"--outlier-alpha", CLI_CUSTOM, F(opt), "A", 0, 1, CLI_MIN_OPEN | CLI_MAX_OPEN,
     .parse = cli_opt_lsq, .def = "0.05", .help = "lsq: the outlier test's significance for the data set"},
    {"--outlier-alpha-each", CLI_CUSTOM, F(opt), "A", 0, 1, CLI_MIN_OPEN | CLI_MAX_OPEN,
     .parse = cli_opt_lsq, .help = "lsq: the outlier test's significance for each coordinate"},
    {"--drift", CLI_CHOICE, F(opt.drift), "linear|none", .choices = "none|linear",
     .bad = "--drift must be linear or none, got '%s'", .def = "none",
     .help = "lsq: per-view drift rates from the t_s column"},
    {"--view-noise", CLI_CUSTOM, F(opt), "stated|estimate", .choices = "stated|estimate",
     .parse = cli_opt_lsq, .def = "stated", .help = "lsq: each view's noise estimated"},
    {"--view-scale", CLI_CUSTOM, F(opt), "model|free", .choices = "model|free",
     .parse = cli_opt_lsq, .def = "model", .help = "lsq: each view's scale an unknown"},
    {"--monte-carlo", CLI_LONG, F(mc_trials), "M", 2, 1e7,
     .bad = "--monte-carlo needs a number of trials of 2 to 1e7, got '%s'",
     .help = "lsq: the budget validated by M trials"},
    {"--seed", CLI_CUSTOM, F(mc_seed), "S", .parse = cli_opt_seed, .def = "1",
     .help = "the Monte Carlo's seed, 0 to 2^64-1"},
    {"--monte-carlo-out", CLI_STRING, F(mc_out), "MC.csv",
     .help = "per node the Monte Carlo u, the ratio and the 95 % intervals"},
    {"--quiet", CLI_FLAG, F(quiet), .help = "no summary on stdout"},
    {"--progress", CLI_FLAG, F(progress), .help = "the phases of a least-squares solve on stderr"},
    {"--max-memory", CLI_CUSTOM, F(opt.max_bytes), "SIZE", .parse = cli_opt_max_memory,
     .def = "the available memory", .help = "refuse a plan estimated to need more (K, M, G, T)"},
    {"--solver", CLI_CUSTOM, F(opt.solver), "auto|reduced|full", .parse = cli_opt_solver,
     .def = "auto", .help = "lsq: the normal matrix factored (A eliminated or kept)"},
    {"--node-sigma", CLI_CUSTOM, F(opt), "all|none|sample:K", .parse = cli_opt_node_sigma,
     .def = "all", .help = "lsq: every node's sigma and leverage, none, or K nodes' sigma"},
};
#undef F

const cli_cmd_opts cli_grid_opts = {
    "grid", USAGE, GRID_OPTS, (int)(sizeof GRID_OPTS / sizeof GRID_OPTS[0]),
    offsetof(grid_args, in), NULL, NULL, NULL, NULL, 0, NULL, NULL,
};

/* Parse the arguments into g: -1 to go on, else the exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, grid_args *g)
{
    memset(g, 0, sizeof *g);
    g->mc_seed = 1;
    sc_grid_options_default(&g->opt);
    g->opt.max_bytes = cli_memory_bytes();
    g->opt.warn = warn_stderr;
    int rc = cli_opts_parse(&cli_grid_opts, argc, argv, g);
    if (rc >= 0)
        return rc;
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
        (g->residuals || g->covariance || g->opt.reject_outliers || g->opt.drift ||
         g->opt.view_scale_free || g->mc_trials))
        return cli_usage_error("grid", "--residuals, --reject-outliers, --covariance, --drift, "
                                       "--view-scale free and --monte-carlo need --method lsq");
    if (g->opt.node_sigma != SC_GRID_NODE_SIGMA_ALL &&
        (g->opt.reject_outliers || g->opt.estimate_view_noise || g->mc_trials))
        return cli_usage_error("grid", "--reject-outliers, --view-noise estimate and --monte-carlo "
                                       "need every leverage: --node-sigma all");
    if (g->mc_out && !g->mc_trials)
        return cli_usage_error("grid", "--monte-carlo-out needs --monte-carlo M");
    return -1;
}

/* The Monte Carlo per node: its u, the ratio to the budget's and the 95 % coverage intervals. */
static void fprint_mc(FILE *fp, const sc_grid_plan *p, const sc_grid_mc *mc)
{
    int nx = sc_grid_stage_nx(p);
    fputs("i,j,x_mm,y_mm,ugx_mc_um,ugy_mc_um,ratio_x,ratio_y,gx_lo_um,gx_hi_um,gy_lo_um,gy_hi_um\n",
          fp);
    for (long k = 0; k < sc_grid_stage_nodes(p); ++k) {
        double x, y;
        sc_grid_node_xy_mm(p, (int)(k / nx), (int)(k % nx), &x, &y);
        fprintf(fp, "%ld,%ld,%.15g,%.15g,%.6g,%.6g,%.6g,%.6g,%.15g,%.15g,%.15g,%.15g\n", k / nx,
                k % nx, x + p->origin_mm[0], y + p->origin_mm[1], mc->ugx_um[k], mc->ugy_um[k],
                mc->ratio_x[k], mc->ratio_y[k], mc->gx_lo_um[k], mc->gx_hi_um[k], mc->gy_lo_um[k],
                mc->gy_hi_um[k]);
    }
}

/* The scale model, the budget and the Monte Carlo on stdout. */
static void print_budget(const sc_grid_plan *p, const sc_grid_solution *s, const sc_grid_mc *mc,
                         const sc_grid_file_info *info)
{
    const sc_grid_budget *b = &s->budget;
    if (!b->applies) {
        printf("scale: not included (no '# plate_scale_ppm' line: G carries no magnification)\n");
    } else if (b->magnification) {
        printf("magnification_ppm: %.6g (u %.3g ppm, of which the noise %.3g)\n",
               b->magnification_ppm, b->u_magnification_ppm, b->u_magnification_noise_ppm);
    } else {
        printf("scale: not included (no '# plate_scale_ppm' line: G carries no magnification)\n");
    }
    if (b->applies && b->view_scale_free) {
        printf("view_scale_free_ppm:");
        for (int v = 0; v < p->n_views; ++v)
            printf(" %d:%.4g(%.2g)", info->view_id[v], b->view_scale_free_ppm[v],
                   b->u_view_scale_free_ppm[v]);
        printf(" (value(u); chi^2 %.3g, 95 %% limit %.3g)\n", b->view_scale_chi2,
               b->view_scale_chi2_crit);
    }
    if (b->applies && b->n_rows > 0) {
        int nx = sc_grid_stage_nx(p);
        printf("budget at node %ld,%ld %s:", b->worst_node / nx, b->worst_node % nx,
               b->worst_comp ? "gy" : "gx");
        for (int r = 0; r < b->n_rows; ++r)
            printf("%s %s %.3g um", r ? ";" : "", b->row[r].source, b->row[r].contrib_um);
        printf("; u_c %.3g um, U %.3g um (k = %.3g%s)\n", b->u_c_um, b->U_um, b->k,
               b->k_welch ? ", Welch-Satterthwaite" : "");
    }
    if (mc && mc->trials > 0)
        printf("monte_carlo: %ld trials on %d thread(s) in %.2f s; MC u / budget u: mean %.4f, "
               "min %.4f, max %.4f\n",
               mc->trials, mc->threads, mc->seconds, mc->ratio_mean, mc->ratio_min,
               mc->ratio_max);
}

/* Everything is computed: write every output asked for, commit them together (all or none). */
static sc_status write_outputs(const grid_args *g, const sc_grid_plan *p,
                               const sc_grid_solution *sol, const sc_grid_file_info *info,
                               const sc_grid_mc *mc, sc_error *err)
{
    const sc_grid_result *res = &sol->res;
    const char *paths[7] = {g->map, g->art, g->sum, g->plot, g->residuals, g->covariance, g->mc_out};
    sc_afile f[7];
    memset(f, 0, sizeof f); /* entries not opened stay closed (fp == NULL) */
    int opened = 0;
    sc_status st = SC_OK;
    sc_stage_map gm = sc_grid_stage_map(p, res->gx_um, res->gy_um, res->ugx_um, res->ugy_um);
    for (; opened < 7; ++opened) {
        if (!paths[opened])
            continue;
        st = sc_afile_open(&f[opened], paths[opened], err);
        if (st != SC_OK)
            break;
        switch (opened) {
        case 0: sc_grid_fprint_map(f[0].fp, p, res->gx_um, res->gy_um, res->ugx_um, res->ugy_um); break;
        case 1: sc_grid_fprint_artifact(f[1].fp, p, res->ax_um, res->ay_um); break;
        case 2:
            sc_grid_fprint_solution_summary(f[2].fp, g->method, p, sol, info->view_id,
                                            g->mc_trials ? mc : NULL);
            break;
        case 3: plot_map_svg(f[3].fp, &gm, NULL, 0, cli_basename(g->in), 0); break;
        case 4:
            sc_grid_fprint_residuals(f[4].fp, p, info->view_id, sol->rx_um, sol->ry_um, sol->tx,
                                     sol->ty, sol->outlier);
            break;
        case 5: sc_fprint_npy(f[5].fp, sol->cov_um2, sol->n_cov, sol->n_cov); break;
        case 6: fprint_mc(f[6].fp, p, mc); break;
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
    cli_progress pr;
    cli_progress_init(&pr, "grid", g.progress, g.opt.max_bytes);
    if (g.opt.method == SC_GRID_METHOD_LSQ)
        g.opt.progress = cli_progress_lsq, g.opt.progress_ctx = &pr;
    cli_progress_phase(&pr, "read", 0, 0, 0);
    sc_status st = sc_grid_read(g.in, &d, &info, &err);
    if (st != SC_OK) {
        cli_progress_end(&pr);
        return cli_report(&err);
    }
    sc_grid_solution sol;
    sc_grid_mc mc;
    memset(&mc, 0, sizeof mc);
    st = sc_grid_calibrate(&d, &info, g.in, &g.opt, &sol, &err);
    if (st == SC_OK && g.mc_trials)
        st = sc_grid_monte_carlo(&d, &g.opt, &sol, g.mc_trials, g.mc_seed, 0, &mc, &err);
    if (st == SC_OK)
        cli_progress_phase(&pr, "write", 1, 1, 0);
    if (st == SC_OK)
        st = write_outputs(&g, &d.plan, &sol, &info, &mc, &err);
    cli_progress_end(&pr);
    if (st == SC_OK && !g.quiet) {
        print_grid_summary(g.method, &d.plan, &sol, sol.res.stated_u);
        print_budget(&d.plan, &sol, &mc, &info);
    }
    sc_grid_mc_free(&mc);
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
