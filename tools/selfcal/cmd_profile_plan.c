/* selfcal profile-plan — rank the usable sensor spacings (d1, d2) for a straightness measurement
 * by the predicted uncertainty of the profile, before the fixture is built. */
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/csv.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"

static const char USAGE[] =
    "usage: selfcal profile-plan --n N --s-mm S --sigma-disp-um X --sigma-angle-urad Y\n"
    "                            [--d-min A (2)] [--d-max D (30)] [--top K (20)] [--sort rms|max]\n"
    "                            [--drift linear|quadratic]\n"
    "\n"
    "Ranks the pairs A <= d1 < d2 <= D that least squares can solve by the predicted RMS (or the\n"
    "worst point) of u(f) over the profile; the DFT method's figures where N = p·d1·d2.\n"
    "Prints CSV: rank,d1,d2,D1_mm,D2_mm,lsq_rms_nm,lsq_max_nm,dft_rms_nm,dft_max_nm.\n"
    "With a drift, the least squares also with drift terms common to both scans (as selfcal\n"
    "profile --drift): the columns drift_rms_nm,drift_max_nm,drift_cost (its RMS u over\n"
    "lsq_rms_nm), ranked by them.\n";

typedef struct plan_row {
    int d1, d2;
    double lsq_rms, lsq_max, dft_rms, dft_max; /* nm; NaN where not usable */
    double drift_rms, drift_max, drift_cost;   /* with --drift (nm; the ratio to lsq_rms) */
} plan_row;

static int sort_by_max, sort_by_drift;

static int cmp_rows(const void *a, const void *b)
{
    const plan_row *x = a, *y = b;
    double kx = sort_by_max ? x->lsq_max : x->lsq_rms, ky = sort_by_max ? y->lsq_max : y->lsq_rms;
    if (sort_by_drift) /* with --drift: by the u the drift terms leave */
        kx = sort_by_max ? x->drift_max : x->drift_rms, ky = sort_by_max ? y->drift_max : y->drift_rms;
    if (kx != ky)
        return kx < ky ? -1 : 1;
    double lx = sort_by_max ? x->lsq_rms : x->lsq_max, ly = sort_by_max ? y->lsq_rms : y->lsq_max;
    if (lx != ly)
        return lx < ly ? -1 : 1;
    return x->d1 != y->d1 ? x->d1 - y->d1 : x->d2 - y->d2;
}

static void stats(const double *u, int n, double *rms, double *mx)
{
    double ss = 0, m = 0;
    for (int i = 0; i < n; ++i) {
        ss += u[i] * u[i];
        if (u[i] > m)
            m = u[i];
    }
    *rms = sqrt(ss / n) * 1e3;
    *mx = m * 1e3;
}

static void print_num(double v)
{
    if (isfinite(v))
        printf(",%.4f", v);
    else
        printf(",");
}

/* The command line, as given. */
typedef struct {
    long n, dmin, dmax, top;
    double s, sd, sa; /* s_mm, sigma_disp_um, sigma_angle_urad */
    int drift;        /* 0, 1 linear, 2 quadratic */
    int drift_ix;     /* --drift: 0 linear, 1 quadratic; -1 not given */
    int sort_max;     /* --sort: 0 rms, 1 max */
} plan_args;

#define F(field) offsetof(plan_args, field)
#define WHOLE(name, f, dflt, text)                                                                  \
    {name, CLI_LONG, F(f), "K", 1, (double)LONG_MAX, .bad = "%s: '%s' must be a positive whole number",    \
     .def = dflt, .help = text}
#define NONNEG(name, f, v, text)                                                                   \
    {name, CLI_DOUBLE, F(f), v, 0, HUGE_VAL, .bad = "%s: '%s' must be a non-negative number",      \
     .help = text}
/* profile-plan's options (cli_opts.h), in the order of its --help */
static const cli_opt PLAN_OPTS[] = {
    WHOLE("--n", n, NULL, "the number of points (required)"),
    NONNEG("--s-mm", s, "S", "the sampling step, mm (required; above 0)"),
    NONNEG("--sigma-disp-um", sd, "X", "the displacement probes' noise, um (required)"),
    NONNEG("--sigma-angle-urad", sa, "Y", "the angle probe's noise, urad (required)"),
    WHOLE("--d-min", dmin, "2", "the smallest spacing, in steps"),
    WHOLE("--d-max", dmax, "30", "the largest spacing, in steps (at most N - 1)"),
    WHOLE("--top", top, "20", "the pairs printed"),
    {"--sort", CLI_CHOICE, F(sort_max), "rms|max", .choices = "rms|max",
     .bad = "--sort must be rms or max, not '%s'", .def = "rms", .help = "rank by the RMS or the worst point"},
    {"--drift", CLI_CHOICE, F(drift_ix), "linear|quadratic", .choices = "linear|quadratic",
     .bad = "--drift must be linear or quadratic, not '%s'", .def = "none",
     .help = "the least squares with drift terms"},
};
#undef WHOLE
#undef NONNEG
#undef F

const cli_cmd_opts cli_profile_plan_opts = {
    "profile-plan", USAGE, PLAN_OPTS, (int)(sizeof PLAN_OPTS / sizeof PLAN_OPTS[0]), 0,
    cli_opt_no_operand, NULL, "unknown option or missing value: %s (see --help)",
    "unknown option or missing value: %s (see --help)", 0, NULL, NULL,
};

/* argv into a (sort_by_max too): -1 to go on, else the exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, plan_args *a)
{
    *a = (plan_args){0, 2, 30, 20, NAN, NAN, NAN, 0, -1, 0};
    int rc = cli_opts_parse(&cli_profile_plan_opts, argc, argv, a);
    a->drift = a->drift_ix + 1;
    sort_by_max = a->sort_max;
    return rc;
}

/* The required options and their ranges; d-max is clamped to N - 1. */
static int check_args(plan_args *a)
{
    const char *cmd = "profile-plan";
    if (a->n <= 0 || isnan(a->s) || isnan(a->sd) || isnan(a->sa))
        return cli_usage_error(cmd, "--n, --s-mm, --sigma-disp-um and --sigma-angle-urad are required (see --help)");
    if (!(a->s > 0))
        return cli_usage_error(cmd, "--s-mm must be positive");
    if (a->n > 100000000)
        return cli_usage_error(cmd, "--n %ld is too large", a->n);
    if (a->dmax >= a->n)
        a->dmax = a->n - 1;
    if (a->dmin < 1 || a->dmin >= a->dmax)
        return cli_usage_error(cmd, "need 1 <= d-min < d-max < N (d-min %ld, d-max %ld)", a->dmin,
                               a->dmax);
    if (!(a->sd > 0 || a->sa > 0))
        return cli_usage_error(cmd, "give a positive --sigma-disp-um or --sigma-angle-urad");
    /* Each pair's least-squares factor holds 8·N·(d2 + 1) bytes, its vectors and the DFT's
     * buffers about 200 bytes a point: refused up front where that exceeds the machine's memory
     * (it would be killed there after a long time, or take the machine down with it). */
    double need = 8.0 * (double)a->n * (double)(a->dmax + 1) + 200.0 * (double)a->n;
    double have = cli_memory_bytes();
    if (have > 0 && need > have)
        return cli_usage_error(cmd, "--n %ld with --d-max %ld needs about %.1f GB, more than this "
                                    "machine's %.1f GB: lower --n or --d-max",
                               a->n, a->dmax, need / 1e9, have / 1e9);
    return CLI_OK;
}

/* One pair's uncertainty figures by both methods (the DFT's only where it is usable); u: N
 * doubles of work. */
static sc_status evaluate_pair(const plan_args *a, int d1, int d2, double *u, plan_row *r,
                               sc_error *err)
{
    const int n = (int)a->n;
    double w1 = 1.0 / sc_profile_y_variance(d1, a->s, a->sd, a->sa);
    double w2 = 1.0 / sc_profile_y_variance(d2, a->s, a->sd, a->sa);
    *r = (plan_row){d1, d2, NAN, NAN, NAN, NAN, NAN, NAN, NAN};
    sc_profile_lsq_plan *lp = NULL;
    sc_status st = sc_profile_lsq_plan_create(n, d1, d2, w1, w2, &lp, err);
    if (st == SC_OK)
        st = sc_profile_lsq_uncertainty(lp, u, NULL, err);
    sc_profile_lsq_plan_destroy(lp);
    if (st != SC_OK)
        return st;
    stats(u, n, &r->lsq_rms, &r->lsq_max);
    if (!sc_profile_dft_is_usable(n, d1, d2, NULL))
        return SC_OK;
    sc_profile_dft_plan *dp = NULL;
    st = sc_profile_dft_plan_create(n, d1, d2, w1, w2, &dp, err);
    if (st == SC_OK)
        st = sc_profile_dft_uncertainty(dp, u, NULL, err);
    sc_profile_dft_plan_destroy(dp);
    if (st == SC_OK)
        stats(u, n, &r->dft_rms, &r->dft_max);
    return st;
}

/* With --drift: the least squares with the drift terms (the rig solver of `selfcal profile
 * --drift`, run on a data set of zeros with the noise stated: u does not depend on the data);
 * u: 3N doubles of work. */
static sc_status evaluate_drift(const plan_args *a, int d1, int d2, double *u, plan_row *r,
                                sc_error *err)
{
    const int n = (int)a->n;
    sc_profile_data d;
    sc_status st = sc_profile_data_init(&d, n, a->s, d1, d2, err);
    if (st != SC_OK)
        return st;
    d.has_sigma_disp = d.has_sigma_angle = 1;
    d.sigma_disp_um = a->sd, d.sigma_angle_urad = a->sa;
    sc_profile_options o;
    sc_profile_options_default(&o);
    o.drift = a->drift;
    sc_profile_solution so = {.f_um = u + n, .uf_um = u, .ey_um = u + 2 * (size_t)n};
    st = sc_profile_calibrate(&d, &o, &so, err);
    sc_profile_data_free(&d);
    if (st == SC_E_INPUT) { /* the drift cannot be told from the profile with this pair */
        r->drift_rms = r->drift_max = r->drift_cost = INFINITY;
        return SC_OK;
    }
    if (st != SC_OK)
        return st;
    stats(u, n, &r->drift_rms, &r->drift_max);
    r->drift_cost = so.drift_cost;
    return SC_OK;
}

/* The ranking on stdout: a comment line, the header, the best `top` rows. */
static void print_ranking(const plan_args *a, plan_row *rows, size_t cnt)
{
    sort_by_drift = a->drift != 0;
    qsort(rows, cnt, sizeof *rows, cmp_rows);
    printf("# profile-plan: N = %ld, s_mm = %g, sigma_disp_um = %g, sigma_angle_urad = %g; "
           "%zu usable pairs with %ld <= d1 < d2 <= %ld, ranked by least-squares %s of u(f)%s\n",
           a->n, a->s, a->sd, a->sa, cnt, a->dmin, a->dmax, sort_by_max ? "worst point" : "RMS",
           a->drift == 1   ? " with a linear drift fitted"
           : a->drift == 2 ? " with a linear and a quadratic drift fitted"
                           : "");
    printf("rank,d1,d2,D1_mm,D2_mm,lsq_rms_nm,lsq_max_nm,dft_rms_nm,dft_max_nm%s\n",
           a->drift ? ",drift_rms_nm,drift_max_nm,drift_cost" : "");
    for (size_t i = 0; i < cnt && (long)i < a->top; ++i) {
        printf("%zu,%d,%d,%g,%g", i + 1, rows[i].d1, rows[i].d2, rows[i].d1 * a->s,
               rows[i].d2 * a->s);
        print_num(rows[i].lsq_rms);
        print_num(rows[i].lsq_max);
        print_num(rows[i].dft_rms);
        print_num(rows[i].dft_max);
        if (a->drift) {
            print_num(rows[i].drift_rms);
            print_num(rows[i].drift_max);
            print_num(rows[i].drift_cost);
        }
        printf("\n");
    }
}

int cmd_profile_plan(int argc, char **argv)
{
    plan_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc >= 0 || (rc = check_args(&a)) != CLI_OK)
        return rc;
    size_t cap = (size_t)(a.dmax - a.dmin + 1) * (size_t)(a.dmax - a.dmin + 1) / 2 + 1;
    plan_row *rows = malloc(cap * sizeof *rows);
    double *u = malloc((size_t)a.n * 3 * sizeof(double));
    sc_error err;
    sc_error_clear(&err);
    if (!rows || !u) {
        free(rows);
        free(u);
        sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
        return cli_report(&err);
    }
    size_t cnt = 0;
    sc_status st = SC_OK;
    const int tty = isatty(STDERR_FILENO);
    for (long d1 = a.dmin; d1 <= a.dmax && st == SC_OK; ++d1) {
        if (tty)
            fprintf(stderr, "\rprofile-plan: d1 = %ld of %ld", d1, a.dmax), fflush(stderr);
        for (long d2 = d1 + 1; d2 <= a.dmax && st == SC_OK; ++d2)
            if (sc_profile_lsq_is_solvable((int)a.n, (int)d1, (int)d2, NULL) &&
                (st = evaluate_pair(&a, (int)d1, (int)d2, u, &rows[cnt], &err)) == SC_OK &&
                (!a.drift || (st = evaluate_drift(&a, (int)d1, (int)d2, u, &rows[cnt], &err)) ==
                                 SC_OK))
                cnt++;
    }
    if (tty)
        fprintf(stderr, "\r%40s\r", "");
    if (st == SC_OK && cnt == 0)
        st = sc_error_set(&err, SC_E_UNSOLVABLE, NULL, 0,
                          "no usable pair with %ld <= d1 < d2 <= %ld for N = %ld", a.dmin, a.dmax,
                          a.n);
    if (st == SC_OK)
        print_ranking(&a, rows, cnt);
    free(rows);
    free(u);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}
