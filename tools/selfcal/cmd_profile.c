/* selfcal profile — reconstruct a straightness profile from two-scan data (SPEC §2) by the DFT
 * or the least-squares method, with per-point uncertainty and the stage's e_y. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "selfcal/csv.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "plots.h"

static const char *USAGE =
    "usage: selfcal profile --method {dft,lsq} IN.csv --out P.csv [--sigma-disp-um X]\n"
    "                       [--sigma-angle-urad Y] [--mc K] [--seed S] [--plot p.svg] [--quiet]\n"
    "  Reconstructs f (relative to its least-squares line) with its standard uncertainty and the\n"
    "  stage's straightness motion error e_y; writes n,x_mm,f_um,uf_um,ey_um.\n"
    "  Noise: the options win over the file's '# sigma_disp_um' / '# sigma_angle_urad' lines; with\n"
    "  neither, it is estimated from the least-squares residuals (equal scan weights).\n"
    "  --mc K: uncertainty by K seeded Monte Carlo trials instead of the analytic formula.\n";


static void progress_cb(void *ctx, long done, long total)
{
    (void)ctx;
    fprintf(stderr, "\rMonte Carlo: %3ld%% (%ld/%ld)", done * 100 / total, done, total);
    if (done == total)
        fputc('\n', stderr);
    fflush(stderr);
}

static int parse_pos_double(const char *cmd, const char *opt, const char *s, double *out)
{
    if (sc_parse_double(s, out) != 0 || *out < 0)
        return cli_usage_error(cmd, "%s: '%s' is not a non-negative number", opt, s);
    return 0;
}

int cmd_profile(int argc, char **argv)
{
    const char *cmd = "profile";
    const char *in = NULL, *out = NULL, *method_s = NULL, *plot = NULL;
    double sd = NAN, sa = NAN;
    long mc = 0;
    unsigned long long seed = 1;
    int quiet = 0;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        int has_val = i + 1 < argc;
        if (!strcmp(a, "--method") && has_val)
            method_s = argv[++i];
        else if ((!strcmp(a, "--out") || !strcmp(a, "-o")) && has_val)
            out = argv[++i];
        else if (!strcmp(a, "--plot") && has_val)
            plot = argv[++i];
        else if (!strcmp(a, "--sigma-disp-um") && has_val) {
            if (parse_pos_double(cmd, a, argv[++i], &sd))
                return CLI_BAD_INPUT;
        } else if (!strcmp(a, "--sigma-angle-urad") && has_val) {
            if (parse_pos_double(cmd, a, argv[++i], &sa))
                return CLI_BAD_INPUT;
        } else if (!strcmp(a, "--mc") && has_val) {
            char *e;
            mc = strtol(argv[++i], &e, 10);
            if (*e || mc < 2 || mc > 100000000)
                return cli_usage_error(cmd, "--mc: '%s' must be a whole number >= 2", argv[i]);
        } else if (!strcmp(a, "--seed") && has_val) {
            char *e;
            seed = strtoull(argv[++i], &e, 10);
            if (*e || !*argv[i])
                return cli_usage_error(cmd, "--seed: '%s' is not a whole number", argv[i]);
        } else if (!strcmp(a, "--quiet"))
            quiet = 1;
        else if (a[0] == '-' && a[1])
            return cli_usage_error(cmd, "unknown option or missing value: %s (see --help)", a);
        else if (!in)
            in = a;
        else
            return cli_usage_error(cmd, "more than one input file (%s, %s)", in, a);
    }
    if (!method_s || !in || !out) {
        return cli_usage_error(cmd, "--method, IN.csv and --out are required (see --help)");
    }
    if (!strcmp(out, "-"))
        quiet = 1; /* the result goes to stdout: no summary there */
    sc_profile_method method;
    if (!strcmp(method_s, "dft"))
        method = SC_PROFILE_DFT;
    else if (!strcmp(method_s, "lsq"))
        method = SC_PROFILE_LSQ;
    else
        return cli_usage_error(cmd, "--method must be dft or lsq, not '%s'", method_s);

    sc_error err;
    sc_error_clear(&err);
    sc_profile_data d;
    if (sc_profile_read(in, &d, &err) != SC_OK)
        return cli_report(&err);
    const int n = d.n, d1 = d.d[0], d2 = d.d[1];
    sc_profile_options opt;
    sc_profile_options_default(&opt);
    opt.method = method;
    opt.sigma_disp_um = sd;
    opt.sigma_angle_urad = sa;
    opt.mc_trials = mc;
    opt.mc_seed = (uint64_t)seed;
    /* the summary's residual_ratio line is the least-squares method's: DFT skips its extra solve */
    opt.residual_check = method == SC_PROFILE_LSQ;
    opt.progress = mc > 0 && isatty(STDERR_FILENO) && !quiet ? progress_cb : NULL;
    int rc = CLI_FAIL;
    sc_status st;
    double *blk = malloc((size_t)3 * n * sizeof(double));
    if (!blk) {
        sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
        goto done;
    }
    double *f = blk, *uf = f + n, *ey = uf + n;
    sc_profile_solution sol = {.f_um = f, .uf_um = uf, .ey_um = ey};
    if ((st = sc_profile_calibrate(&d, &opt, &sol, &err)) != SC_OK)
        goto done;
    int have_uf = sol.have_uf;
    if (!have_uf && !quiet)
        fprintf(stderr, "selfcal profile: no redundancy (N - d1 - d2 = %d): noise not estimable, "
                        "uf_um left empty\n", sol.dof);
    if ((st = sc_profile_write_result(out, n, d.s_mm, f, have_uf ? uf : NULL, ey, n - d1, &err)) != SC_OK)
        goto done;
    if (plot) {
        double *x = malloc((size_t)n * sizeof(double));
        if (!x) {
            sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
            goto done;
        }
        for (int i = 0; i < n; ++i)
            x[i] = i * d.s_mm;
        sc_profile_result r = {.n = n, .x_mm = x, .f_um = f, .uf_um = uf, .ey_um = ey};
        char title[128];
        snprintf(title, sizeof title, "%s method, N = %d, d = %d/%d", method_s, n, d1, d2);
        profile_plot_opts o = {title, method_s, NULL, 0};
        st = profile_plot_write(plot, &r, NULL, NULL, &o, &err);
        free(x);
        if (st != SC_OK)
            goto done;
    }
    if (!quiet) {
        double ss = 0, mx = 0;
        for (int i = 0; have_uf && i < n; ++i) {
            ss += uf[i] * uf[i];
            if (uf[i] > mx)
                mx = uf[i];
        }
        printf("method: %s\nN: %d\ns_mm: %g\nd1: %d\nd2: %d\n", method_s, n, d.s_mm, d1, d2);
        if (sol.noise_known)
            printf("noise: given (sigma_disp_um = %g, sigma_angle_urad = %g)\n", sol.sigma_disp_um,
                   sol.sigma_angle_urad);
        else
            printf("noise: estimated from residuals\n");
        if (have_uf)
            printf("sigma_y1_um: %.6g\nsigma_y2_um: %.6g\n", sol.sigma_y_um[0], sol.sigma_y_um[1]);
        if (!isnan(sol.residual_ratio))
            printf("residual_ratio: %.4g (RMS of residual/given sigma; dof %d)\n", sol.residual_ratio,
                   sol.dof);
        if (have_uf)
            printf("uncertainty: %s\nuf_rms_um: %.6g\nuf_max_um: %.6g\n",
                   mc > 0 ? "Monte Carlo" : "analytic", sqrt(ss / n), mx);
    }
    rc = CLI_OK;
done:
    if (rc != CLI_OK && err.code != SC_OK)
        rc = cli_report(&err);
    free(blk);
    sc_profile_data_free(&d);
    return rc;
}
