/* selfcal profile — reconstruct a straightness profile from two-scan data (SPEC §2) by the DFT
 * or the least-squares method, with per-point uncertainty and the stage's e_y. The calibration's
 * plan (which needs only the file's header) is made while the rows are read
 * (sc_profile_read_and_plan). */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "cli_opts.h"
#include "../../libselfcal/src/common/big_alloc.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "plots.h"

static const char USAGE[] =
    "usage: selfcal profile --method {dft,lsq} IN.csv --out P.csv [--sigma-disp-um X]\n"
    "                       [--sigma-angle-urad Y] [--mc K] [--seed S] [--plot p.svg] [--quiet]\n"
    "                       [--drift linear|quadratic] [--residuals R.csv] [--reject-outliers]\n"
    "\n"
    "Reconstructs f (relative to its least-squares line) with its standard uncertainty and the\n"
    "stage's straightness motion error e_y; writes n,x_mm,f_um,uf_um,ey_um.\n"
    "Noise: the options win over the file's '# sigma_disp_um' / '# sigma_angle_urad' lines; with\n"
    "neither, it is estimated from the least-squares residuals (equal scan weights). The Monte\n"
    "Carlo's trials (--mc) are seeded and replace the analytic formula.\n"
    "Real rigs (lsq; docs/profile.md): missing rows and empty fields are solved around (points\n"
    "no row determines are left empty and named); the header's probe_gain, angle_scale and\n"
    "spacing_u_mm correct the data and enter uf_um (budget in the summary).\n"
    "A drift costs uncertainty (the summary's drift_cost). The residuals: scan,n,r_um,t,outlier\n"
    "(data snooping, 5 %); each outlier is a warning.\n"
    "With the noise stated, a chi-square test of the residuals (95 %): when it fails high,\n"
    "uf_um is scaled by sqrt(wrss/dof).\n";


static void progress_cb(void *ctx, long done, long total)
{
    (void)ctx;
    fprintf(stderr, "\rMonte Carlo: %3ld%% (%ld/%ld)", done * 100 / total, done, total);
    if (done == total)
        fputc('\n', stderr);
    fflush(stderr);
}

/* The command line. */
typedef struct profile_args {
    const char *in, *out, *method_s, *plot, *residuals;
    sc_profile_method method;
    int drift, reject;
    int drift_ix; /* --drift: 0 linear, 1 quadratic; -1 none */
    double sigma_disp_um, sigma_angle_urad; /* NaN: not given */
    long mc;
    uint64_t seed;
    int quiet;
} profile_args;

#define PARSE_GO_ON (-1) /* parse_args: no exit code, carry on */

#define F(field) offsetof(profile_args, field)
/* profile's options (cli_opts.h), in the order of its --help */
static const cli_opt PROFILE_OPTS[] = {
    {"--method", CLI_STRING, F(method_s), "dft|lsq", .help = "the method (required)"},
    {"--out|-o", CLI_STRING, F(out), "P.csv", .help = "the profile (required; - for stdout)"},
    {"--sigma-disp-um", CLI_CUSTOM, F(sigma_disp_um), "X", 0, SC_INPUT_MAX_ABS, .parse = cli_opt_noise,
     .def = "the file's, else estimated", .help = "the displacement probes' noise (um)"},
    {"--sigma-angle-urad", CLI_CUSTOM, F(sigma_angle_urad), "Y", 0, SC_INPUT_MAX_ABS,
     .parse = cli_opt_noise, .def = "the file's, else estimated",
     .help = "the angle probe's noise (urad)"},
    {"--mc", CLI_LONG, F(mc), "K", 2, 100000000, .bad = "--mc: '%s' must be a whole number >= 2",
     .help = "the uncertainty by K Monte Carlo trials"},
    {"--seed", CLI_CUSTOM, F(seed), "S", .parse = cli_opt_seed, .def = "1",
     .help = "the Monte Carlo's seed, 0 to 2^64-1"},
    {"--plot", CLI_STRING, F(plot), "p.svg", .help = "a plot of the profile"},
    {"--quiet", CLI_FLAG, F(quiet), .help = "no summary on stdout"},
    {"--drift", CLI_CHOICE, F(drift_ix), "linear|quadratic", .choices = "linear|quadratic",
     .bad = "--drift must be linear or quadratic, not '%s'", .def = "none",
     .help = "lsq: a drift common to both scans"},
    {"--residuals", CLI_STRING, F(residuals), "R.csv", .help = "lsq: the residuals and outlier test"},
    {"--reject-outliers", CLI_FLAG, F(reject), .help = "lsq: remove the worst outlier, solve again"},
};
#undef F

const cli_cmd_opts cli_profile_opts = {
    "profile", USAGE, PROFILE_OPTS, (int)(sizeof PROFILE_OPTS / sizeof PROFILE_OPTS[0]),
    offsetof(profile_args, in), NULL, "more than one input file (%s, %s)",
    "unknown option or missing value: %s (see --help)",
    "unknown option or missing value: %s (see --help)", 0, NULL, NULL,
};

/* The whole command line into pa: PARSE_GO_ON, or an exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, profile_args *pa)
{
    const char *cmd = "profile";
    *pa = (profile_args){.sigma_disp_um = NAN, .sigma_angle_urad = NAN, .seed = 1, .drift_ix = -1};
    int rc = cli_opts_parse(&cli_profile_opts, argc, argv, pa);
    if (rc != PARSE_GO_ON)
        return rc;
    pa->drift = pa->drift_ix + 1;
    if (!pa->method_s || !pa->in || !pa->out)
        return cli_usage_error(cmd, "--method, IN.csv and --out are required (see --help)");
    if (!strcmp(pa->out, "-"))
        pa->quiet = 1; /* the result goes to stdout: no summary there */
    if (!strcmp(pa->method_s, "dft"))
        pa->method = SC_PROFILE_DFT;
    else if (!strcmp(pa->method_s, "lsq"))
        pa->method = SC_PROFILE_LSQ;
    else
        return cli_usage_error(cmd, "--method must be dft or lsq, not '%s'", pa->method_s);
    if (pa->method == SC_PROFILE_DFT && (pa->drift || pa->residuals || pa->reject))
        return cli_usage_error(cmd, "--drift, --residuals and --reject-outliers need --method lsq");
    return PARSE_GO_ON;
}

/* The library's options from the command line. */
static void calibrate_options(const profile_args *pa, sc_profile_options *opt)
{
    sc_profile_options_default(opt);
    opt->method = pa->method;
    opt->sigma_disp_um = pa->sigma_disp_um;
    opt->sigma_angle_urad = pa->sigma_angle_urad;
    opt->mc_trials = pa->mc;
    opt->mc_seed = (uint64_t)pa->seed;
    /* the summary's residual_ratio line is the least-squares method's: DFT skips its extra solve */
    opt->residual_check = pa->method == SC_PROFILE_LSQ;
    opt->progress = pa->mc > 0 && isatty(STDERR_FILENO) && !pa->quiet ? progress_cb : NULL;
    opt->drift = pa->drift;
    opt->reject_outliers = pa->reject;
    opt->want_residuals = pa->residuals != NULL || pa->reject;
}

/* --plot: the profile with its uncertainty band as SVG, into fp. */
static sc_status write_plot(FILE *fp, const profile_args *pa, const sc_profile_data *d,
                            const sc_profile_solution *sol, sc_error *err)
{
    const int n = d->n;
    double *x = malloc((size_t)n * sizeof(double));
    if (!x)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (int i = 0; i < n; ++i)
        x[i] = i * d->s_mm;
    sc_profile_result r = {.n = n, .x_mm = x, .f_um = sol->f_um, .uf_um = sol->uf_um,
                           .ey_um = sol->ey_um};
    char title[128];
    snprintf(title, sizeof title, "%s method, N = %d, d = %d/%d", pa->method_s, n, d->d[0],
             d->d[1]);
    profile_plot_opts o = {title, pa->method_s, NULL, 0};
    sc_status st = profile_plot_svg(fp, &r, NULL, NULL, &o, err);
    free(x);
    return st;
}

/* The real-rig part of the summary: the uncertainty budget, drift, gaps, outliers. */
static void print_rig_summary(const sc_profile_data *d, const sc_profile_solution *sol)
{
    static const char *const src[SC_PROFILE_U_N] = {"noise", "probe_gain", "angle_scale",
                                                    "spacing"};
    const double U[SC_PROFILE_U_N] = {NAN, d->has_probe_gain ? d->probe_gain[1] : 0,
                                      d->has_angle_scale ? d->angle_scale[1] : 0,
                                      d->spacing_u_mm};
    if (sol->have_uf && (U[1] > 0 || U[2] > 0 || U[3] > 0)) {
        printf("budget: source,U,u_rms_um,u_max_um\n");
        for (int i = 0; i < SC_PROFILE_U_N; ++i)
            if (i == 0)
                printf("budget: %s,,%.6g,%.6g\n", src[i], sol->budget_rms_um[i],
                       sol->budget_max_um[i]);
            else if (U[i] > 0)
                printf("budget: %s,%.6g,%.6g,%.6g\n", src[i], U[i], sol->budget_rms_um[i],
                       sol->budget_max_um[i]);
    }
    if (d->has_probe_gain || d->has_angle_scale)
        printf("instrument: probe_gain %.9g, angle_scale %.9g (applied to m2, m3)\n",
               d->has_probe_gain ? d->probe_gain[0] : 1.0,
               d->has_angle_scale ? d->angle_scale[0] : 1.0);
    if (isfinite(sol->drift_um[0]) && isfinite(sol->drift_um[1]))
        printf("drift_um: a %.6g, b %.6g (y_k += a*tau + b*tau^2, tau = -1..1 over n)\n",
               sol->drift_um[0], sol->drift_um[1]);
    else if (isfinite(sol->drift_um[0]))
        printf("drift_um: a %.6g (y_k += a*tau, tau = -1..1 over n)\n", sol->drift_um[0]);
    if (isfinite(sol->drift_cost))
        printf("drift_cost: %.4g (RMS uf with the drift terms / without them)\n", sol->drift_cost);
    if (sol->rig)
        printf("solver: rig (rows fitted: dof %d; undetermined points %d)\n", sol->dof,
               sol->n_undetermined);
    if (isfinite(sol->outlier_crit))
        printf("outliers: %d flagged, %d removed (|t| > %.4g: data snooping, alpha 0.05 for the "
               "whole data set)\n", sol->n_flagged, sol->n_removed, sol->outlier_crit);
}

/* The points the data cannot determine, named as ranges of n on stderr. */
static void warn_undetermined(const profile_args *pa, const sc_profile_data *d,
                              const sc_profile_solution *sol)
{
    if (sol->n_undetermined <= 0)
        return;
    fprintf(stderr, "selfcal: warning: %s: %d point%s no row ties to the rest, left empty: n =",
            pa->in, sol->n_undetermined, sol->n_undetermined == 1 ? "" : "s");
    int shown = 0;
    for (int i = 0; i < d->n && shown < 20; ++i) {
        if (isfinite(sol->f_um[i]))
            continue;
        int e = i;
        while (e + 1 < d->n && !isfinite(sol->f_um[e + 1]))
            ++e;
        fprintf(stderr, shown ? ", %d" : " %d", i);
        if (e > i)
            fprintf(stderr, "..%d", e);
        ++shown;
        i = e;
    }
    fprintf(stderr, "%s\n", shown == 20 ? ", ..." : "");
}

/* One warning per flagged row, one line per removed row; the χ² test when it fails. */
static void warn_rig(const profile_args *pa, const sc_profile_data *d,
                     const sc_profile_solution *sol)
{
    warn_undetermined(pa, d, sol);
    for (int k = 0; k < 2 && sol->r_um[0]; ++k)
        for (int j = 0; j < d->n - d->d[k]; ++j)
            if (sol->outlier[k][j])
                fprintf(stderr, "selfcal: warning: %s outlier scan %d n = %d (r %.4g um, t %.3g; "
                                "critical value %.3f)\n",
                        sol->outlier[k][j] == 2 ? "removed" : "flagged", k + 1, j,
                        sol->r_um[k][j], sol->t[k][j], sol->outlier_crit);
    if (!sol->chi2_pass)
        fprintf(stderr, "selfcal: warning: the residuals do not agree with the stated noise "
                        "(chi-square test at 95 %%: wrss/dof = %.4g outside [%.4g, %.4g]); %s\n",
                sol->residual_ratio * sol->residual_ratio, sol->chi2_lo, sol->chi2_hi,
                sol->u_scaled ? "uf_um scaled by sqrt(wrss/dof)"
                              : "uf_um kept as stated (the noise looks smaller than stated)");
    if (isfinite(sol->drift_cost) && sol->drift_cost > 10)
        fprintf(stderr, "selfcal: warning: the drift terms multiply the RMS uncertainty by %.3g "
                        "with these spacings: this plan cannot afford them (a drift reference "
                        "or a reversed scan: docs/profile.md)\n", sol->drift_cost);
}

/* The summary on stdout (not with --quiet). */
static void print_summary(const profile_args *pa, const sc_profile_data *d,
                          const sc_profile_solution *sol)
{
    const int n = d->n;
    const double *uf = sol->uf_um;
    double ss = 0, mx = 0;
    for (int i = 0; sol->have_uf && i < n; ++i) {
        ss += uf[i] * uf[i];
        if (uf[i] > mx)
            mx = uf[i];
    }
    printf("method: %s\nN: %d\ns_mm: %g\nd1: %d\nd2: %d\n", pa->method_s, n, d->s_mm, d->d[0],
           d->d[1]);
    if (sol->noise_known)
        printf("noise: given (sigma_disp_um = %g, sigma_angle_urad = %g)\n", sol->sigma_disp_um,
               sol->sigma_angle_urad);
    else
        printf("noise: estimated from residuals\n");
    if (sol->have_uf)
        printf("sigma_y1_um: %.6g\nsigma_y2_um: %.6g\n", sol->sigma_y_um[0], sol->sigma_y_um[1]);
    if (!isnan(sol->residual_ratio))
        printf("residual_ratio: %.4g (RMS of residual/given sigma; dof %d)\n", sol->residual_ratio,
               sol->dof);
    if (isfinite(sol->chi2_lo))
        printf("chi2_test: %s (wrss/dof %.4g, 95 %% interval [%.4g, %.4g])%s\n",
               sol->chi2_pass ? "pass" : "fail", sol->residual_ratio * sol->residual_ratio,
               sol->chi2_lo, sol->chi2_hi,
               sol->u_scaled ? "; uf_um scaled by sqrt(wrss/dof)" : "");
    if (sol->have_uf)
        printf("uncertainty: %s\nuf_rms_um: %.6g\nuf_max_um: %.6g\n",
               pa->mc > 0 ? "Monte Carlo" : "analytic", sqrt(ss / (n - sol->n_undetermined)), mx);
    print_rig_summary(d, sol);
}

void cli_warn_zero_noise(const char *cmd, const sc_profile_solution *s)
{
    /* 1 pm: noise-free simulations leave rounding residuals of ~1e-13 um */
    if (!s->noise_known || !(s->sigma_y_um[0] == 0 && s->sigma_y_um[1] == 0) || s->dof <= 0 ||
        !(s->wrss >= 0))
        return;
    double scale_um = sqrt(s->wrss / s->dof);
    if (scale_um > 1e-6)
        fprintf(stderr, "%s: warning: the noise is stated as 0 but the residuals' scale is %.3g nm "
                        "(sqrt(RSS/dof), dof %d): every uf_um = 0 understates the uncertainty; "
                        "leave the sigma lines and options out to estimate the noise\n",
                cmd, scale_um * 1e3, s->dof);
}

/* Calibrate the data read with the plan (freed then: the writing reuses its memory), then write
 * the result, the plot and the summary. */
static sc_status calibrate_and_write(const profile_args *pa, const sc_profile_data *d,
                                     sc_profile_calibration **cal, double *blk, sc_error *err)
{
    const int n = d->n;
    sc_profile_solution sol = {.f_um = blk, .uf_um = blk + n, .ey_um = blk + 2 * (size_t)n};
    if (pa->residuals || pa->reject) { /* r, t for both scans, then the marks */
        double *r = blk + 3 * (size_t)n;
        sol.r_um[0] = r, sol.r_um[1] = r + n, sol.t[0] = r + 2 * (size_t)n;
        sol.t[1] = r + 3 * (size_t)n;
        sol.outlier[0] = (unsigned char *)(r + 4 * (size_t)n);
        sol.outlier[1] = sol.outlier[0] + n;
    }
    sc_status st = sc_profile_calibration_run(*cal, d, &sol, err);
    sc_profile_calibration_destroy(*cal);
    *cal = NULL;
    if (st != SC_OK)
        return st;
    if (!sol.have_uf && !pa->quiet)
        fprintf(stderr, "selfcal profile: no redundancy (N - d1 - d2 = %d): noise not estimable, "
                        "uf_um left empty\n", sol.dof);
    if (!pa->quiet)
        cli_warn_zero_noise("selfcal profile", &sol);
    warn_rig(pa, d, &sol);
    /* the result, the plot and the residuals: all written or none (one commit) */
    sc_afile f[3];
    memset(f, 0, sizeof f);
    st = sc_afile_open(&f[0], pa->out, err);
    if (st == SC_OK && pa->plot)
        st = sc_afile_open(&f[1], pa->plot, err);
    if (st == SC_OK && pa->residuals)
        st = sc_afile_open(&f[2], pa->residuals, err);
    if (st == SC_OK && pa->residuals)
        st = sc_profile_write_residuals_to(&f[2], n, d->d, (const double *const *)sol.r_um,
                                           (const double *const *)sol.t,
                                           (const unsigned char *const *)sol.outlier, err);
    if (st == SC_OK)
        st = sc_profile_write_result_to(&f[0], n, d->s_mm, sol.f_um,
                                        sol.have_uf ? sol.uf_um : NULL, sol.ey_um, n - d->d[0], err);
    if (st == SC_OK && pa->plot)
        st = write_plot(f[1].fp, pa, d, &sol, err);
    st = sc_afile_finish_all(f, 3, st, err);
    if (st == SC_OK && !pa->quiet)
        print_summary(pa, d, &sol);
    return st;
}

int cmd_profile(int argc, char **argv)
{
    profile_args pa;
    int rc = parse_args(argc, argv, &pa);
    if (rc != PARSE_GO_ON)
        return rc;
    sc_error err;
    sc_error_clear(&err);
    sc_profile_data d;
    sc_profile_options opt;
    calibrate_options(&pa, &opt);
    sc_profile_calibration *cal;
    if (sc_profile_read_and_plan(pa.in, &opt, &d, &cal, &err) != SC_OK)
        return cli_report(&err);
    /* f, uf, ey; with residuals r, t of both scans and the outlier marks */
    size_t cols = pa.residuals || pa.reject ? 3 + 4 + 1 : 3;
    double *blk = sc_big_alloc(cols * (size_t)d.n, sizeof(double), 0);
    sc_status st = blk ? calibrate_and_write(&pa, &d, &cal, blk, &err)
                       : sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", d.n);
    rc = st == SC_OK ? CLI_OK : cli_report(&err);
    free(blk);
    sc_profile_calibration_destroy(cal);
    sc_profile_data_free(&d);
    return rc;
}
