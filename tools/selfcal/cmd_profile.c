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
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"
#include "plots.h"

static const char *USAGE =
    "usage: selfcal profile --method {dft,lsq} IN.csv --out P.csv [--sigma-disp-um X]\n"
    "                       [--sigma-angle-urad Y] [--mc K] [--seed S] [--plot p.svg] [--quiet]\n"
    "  Reconstructs f (relative to its least-squares line) with its standard uncertainty and the\n"
    "  stage's straightness motion error e_y; writes n,x_mm,f_um,uf_um,ey_um.\n"
    "  Noise: the options win over the file's '# sigma_disp_um' / '# sigma_angle_urad' lines; with\n"
    "  neither, it is estimated from the least-squares residuals (equal scan weights).\n"
    "  --mc K: uncertainty by K seeded Monte Carlo trials instead of the analytic formula.\n";


typedef struct solver_ctx {
    sc_profile_method method;
    sc_profile_dft *dft;
    sc_profile_lsq *lsq;
} solver_ctx;

static sc_status solve_cb(void *vctx, const double *y1, const double *y2, double *f, sc_error *err)
{
    solver_ctx *c = vctx;
    if (c->method == SC_PROFILE_DFT)
        return sc_profile_dft_solve(c->dft, y1, y2, f, err);
    return sc_profile_lsq_solve(c->lsq, y1, y2, f, NULL, NULL, err);
}

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
    if (sc_profile_check_method(&d, method, &err) != SC_OK) {
        sc_profile_data_free(&d);
        return cli_report(&err);
    }
    const int n = d.n, d1 = d.d[0], d2 = d.d[1];
    /* noise: command line > header > residuals */
    int have_sd = !isnan(sd) || d.has_sigma_disp, have_sa = !isnan(sa) || d.has_sigma_angle;
    if (isnan(sd))
        sd = d.has_sigma_disp ? d.sigma_disp_um : 0.0;
    if (isnan(sa))
        sa = d.has_sigma_angle ? d.sigma_angle_urad : 0.0;
    int noise_known = have_sd || have_sa;
    double var1 = 1, var2 = 1;
    if (noise_known) {
        var1 = sc_profile_y_variance(d1, d.s_mm, sd, sa);
        var2 = sc_profile_y_variance(d2, d.s_mm, sd, sa);
    }
    int zero_noise = noise_known && !(var1 > 0 && var2 > 0);
    if (zero_noise)
        var1 = var2 = 1; /* weights are then arbitrary; uncertainties 0 */
    int rc = CLI_FAIL;
    double *blk = malloc((size_t)(2 * n + 4 * n) * sizeof(double));
    solver_ctx ctx = {method, NULL, NULL};
    sc_profile_lsq *lres = NULL;
    if (!blk) {
        sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
        goto done;
    }
    double *y1 = blk, *y2 = y1 + n, *f = y2 + n, *uf = f + n, *ey = uf + n, *tmp = ey + n;
    sc_profile_combine(&d, 0, y1);
    sc_profile_combine(&d, 1, y2);
    sc_status st;
    if (method == SC_PROFILE_DFT)
        st = sc_profile_dft_create(n, d1, d2, 1.0 / var1, 1.0 / var2, &ctx.dft, &err);
    else
        /* the command reports every point's uncertainty: start the selected inversion on the
         * second core while the solve runs */
        st = sc_profile_lsq_create_ex(n, d1, d2, 1.0 / var1, 1.0 / var2,
                                      SC_PROFILE_LSQ_EARLY_UNCERTAINTY, &ctx.lsq, &err);
    if (st != SC_OK || (st = solve_cb(&ctx, y1, y2, f, &err)) != SC_OK)
        goto done;
    /* residual noise (weighted by the plan's weights), always from the least-squares fit: the
     * DFT estimate is not the least-squares one, and its residuals overstate the noise */
    const double *fres = f;
    if (method == SC_PROFILE_DFT) {
        if ((st = sc_profile_lsq_create(n, d1, d2, 1.0 / var1, 1.0 / var2, &lres, &err)) != SC_OK ||
            (st = sc_profile_lsq_solve(lres, y1, y2, tmp, NULL, NULL, &err)) != SC_OK)
            goto done;
        fres = tmp;
    }
    int dof;
    double wrss = sc_profile_residual_ss(n, d1, d2, y1, y2, fres, 1.0 / var1, 1.0 / var2, &dof);
    double scale = 1.0; /* multiplies the plan's unit uncertainties */
    int have_uf = 1;
    if (zero_noise) {
        scale = 0.0;
    } else if (!noise_known) {
        if (dof <= 0) {
            have_uf = 0;
            if (!quiet)
                fprintf(stderr, "selfcal profile: no redundancy (N - d1 - d2 = %d): noise not estimable, "
                                "uf_um left empty\n", dof);
        } else {
            scale = sqrt(wrss / dof);
        }
    }
    if (have_uf) {
        if (mc > 0) {
            int tty = isatty(STDERR_FILENO) && !quiet;
            st = sc_profile_mc_uncertainty(n, d1, d2, sqrt(var1), sqrt(var2), solve_cb, &ctx, mc,
                                           (uint64_t)seed, tty ? progress_cb : NULL, NULL, uf, &err);
        } else if (method == SC_PROFILE_DFT) {
            st = sc_profile_dft_uncertainty(ctx.dft, uf, &err);
        } else {
            st = sc_profile_lsq_uncertainty(ctx.lsq, uf, &err);
        }
        if (st != SC_OK)
            goto done;
        for (int i = 0; i < n; ++i)
            uf[i] *= scale;
    }
    sc_profile_stage_error(&d, f, ey);
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
        for (int i = n - d1; i < n; ++i)
            ey[i] = NAN;
        if (!have_uf)
            for (int i = 0; i < n; ++i)
                uf[i] = NAN;
        sc_profile_result r = {n, x, f, uf, ey};
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
        if (noise_known)
            printf("noise: given (sigma_disp_um = %g, sigma_angle_urad = %g)\n", sd, sa);
        else
            printf("noise: estimated from residuals\n");
        printf("sigma_y1_um: %.6g\nsigma_y2_um: %.6g\n", sqrt(var1) * scale, sqrt(var2) * scale);
        if (dof > 0 && noise_known && !zero_noise)
            printf("residual_ratio: %.4g (RMS of residual/given sigma; dof %d)\n", sqrt(wrss / dof), dof);
        if (have_uf)
            printf("uncertainty: %s\nuf_rms_um: %.6g\nuf_max_um: %.6g\n",
                   mc > 0 ? "Monte Carlo" : "analytic", sqrt(ss / n), mx);
    }
    rc = CLI_OK;
done:
    if (rc != CLI_OK && err.code != SC_OK)
        rc = cli_report(&err);
    sc_profile_dft_destroy(ctx.dft);
    sc_profile_lsq_destroy(ctx.lsq);
    sc_profile_lsq_destroy(lres);
    free(blk);
    sc_profile_data_free(&d);
    return rc;
}
