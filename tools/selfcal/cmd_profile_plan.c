/* selfcal profile-plan — rank the usable sensor spacings (d1, d2) for a straightness measurement
 * by the predicted uncertainty of the profile, before the fixture is built. */
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

static const char *USAGE =
    "usage: selfcal profile-plan --n N --s-mm S --sigma-disp-um X --sigma-angle-urad Y\n"
    "                            [--d-min A (2)] [--d-max D (30)] [--top K (20)] [--sort rms|max]\n"
    "  Ranks the pairs A <= d1 < d2 <= D that least squares can solve by the predicted RMS (or the\n"
    "  worst point) of u(f) over the profile; the DFT method's figures where N = p·d1·d2.\n"
    "  Prints CSV: rank,d1,d2,D1_mm,D2_mm,lsq_rms_nm,lsq_max_nm,dft_rms_nm,dft_max_nm.\n";

typedef struct plan_row {
    int d1, d2;
    double lsq_rms, lsq_max, dft_rms, dft_max; /* nm; NaN where not usable */
} plan_row;

static int sort_by_max;

static int cmp_rows(const void *a, const void *b)
{
    const plan_row *x = a, *y = b;
    double kx = sort_by_max ? x->lsq_max : x->lsq_rms, ky = sort_by_max ? y->lsq_max : y->lsq_rms;
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

int cmd_profile_plan(int argc, char **argv)
{
    const char *cmd = "profile-plan";
    long n = 0, dmin = 2, dmax = 30, top = 20;
    double s = NAN, sd = NAN, sa = NAN;
    sort_by_max = 0;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        int hv = i + 1 < argc;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        long *lp = NULL;
        double *dp = NULL;
        if (!strcmp(a, "--n") && hv)
            lp = &n;
        else if (!strcmp(a, "--d-min") && hv)
            lp = &dmin;
        else if (!strcmp(a, "--d-max") && hv)
            lp = &dmax;
        else if (!strcmp(a, "--top") && hv)
            lp = &top;
        else if (!strcmp(a, "--s-mm") && hv)
            dp = &s;
        else if (!strcmp(a, "--sigma-disp-um") && hv)
            dp = &sd;
        else if (!strcmp(a, "--sigma-angle-urad") && hv)
            dp = &sa;
        else if (!strcmp(a, "--sort") && hv) {
            const char *v = argv[++i];
            if (!strcmp(v, "rms"))
                sort_by_max = 0;
            else if (!strcmp(v, "max"))
                sort_by_max = 1;
            else
                return cli_usage_error(cmd, "--sort must be rms or max, not '%s'", v);
            continue;
        } else
            return cli_usage_error(cmd, "unknown option or missing value: %s (see --help)", a);
        const char *v = argv[++i];
        if (lp && (sc_parse_long(v, lp) != 0 || *lp < 1))
            return cli_usage_error(cmd, "%s: '%s' must be a positive whole number", a, v);
        if (dp && (sc_parse_double(v, dp) != 0 || *dp < 0))
            return cli_usage_error(cmd, "%s: '%s' must be a non-negative number", a, v);
    }
    if (n <= 0 || isnan(s) || isnan(sd) || isnan(sa)) {
        return cli_usage_error(cmd, "--n, --s-mm, --sigma-disp-um and --sigma-angle-urad are required (see --help)");
    }
    if (!(s > 0))
        return cli_usage_error(cmd, "--s-mm must be positive");
    if (n > 100000000)
        return cli_usage_error(cmd, "--n %ld is too large", n);
    if (dmax >= n)
        dmax = n - 1;
    if (dmin < 1 || dmin >= dmax)
        return cli_usage_error(cmd, "need 1 <= d-min < d-max < N (d-min %ld, d-max %ld)", dmin, dmax);
    if (!(sd > 0 || sa > 0))
        return cli_usage_error(cmd, "give a positive --sigma-disp-um or --sigma-angle-urad");
    size_t cap = (size_t)(dmax - dmin + 1) * (size_t)(dmax - dmin + 1) / 2 + 1;
    plan_row *rows = malloc(cap * sizeof *rows);
    double *u = malloc((size_t)n * sizeof(double));
    if (!rows || !u) {
        free(rows);
        free(u);
        sc_error err;
        sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
        return cli_report(&err);
    }
    size_t cnt = 0;
    int rc = CLI_OK;
    const int tty = isatty(STDERR_FILENO);
    for (long d1 = dmin; d1 <= dmax && rc == CLI_OK; ++d1) {
        if (tty)
            fprintf(stderr, "\rprofile-plan: d1 = %ld of %ld", d1, dmax), fflush(stderr);
        for (long d2 = d1 + 1; d2 <= dmax; ++d2) {
            sc_error err;
            sc_error_clear(&err);
            if (!sc_profile_lsq_is_solvable((int)n, (int)d1, (int)d2, NULL))
                continue;
            double w1 = 1.0 / sc_profile_y_variance((int)d1, s, sd, sa);
            double w2 = 1.0 / sc_profile_y_variance((int)d2, s, sd, sa);
            plan_row r = {(int)d1, (int)d2, NAN, NAN, NAN, NAN};
            sc_profile_lsq_plan *lp = NULL;
            if (sc_profile_lsq_plan_create((int)n, (int)d1, (int)d2, w1, w2, &lp, &err) != SC_OK ||
                sc_profile_lsq_uncertainty(lp, u, NULL, &err) != SC_OK) {
                sc_profile_lsq_plan_destroy(lp);
                rc = cli_report(&err);
                break;
            }
            sc_profile_lsq_plan_destroy(lp);
            stats(u, (int)n, &r.lsq_rms, &r.lsq_max);
            if (sc_profile_dft_is_usable((int)n, (int)d1, (int)d2, NULL)) {
                sc_profile_dft_plan *dp = NULL;
                if (sc_profile_dft_plan_create((int)n, (int)d1, (int)d2, w1, w2, &dp, &err) != SC_OK ||
                    sc_profile_dft_uncertainty(dp, u, NULL, &err) != SC_OK) {
                    sc_profile_dft_plan_destroy(dp);
                    rc = cli_report(&err);
                    break;
                }
                sc_profile_dft_plan_destroy(dp);
                stats(u, (int)n, &r.dft_rms, &r.dft_max);
            }
            rows[cnt++] = r;
        }
    }
    if (tty)
        fprintf(stderr, "\r%40s\r", "");
    if (rc == CLI_OK) {
        if (cnt == 0) {
            sc_error err;
            sc_error_set(&err, SC_E_UNSOLVABLE, NULL, 0,
                         "no usable pair with %ld <= d1 < d2 <= %ld for N = %ld", dmin, dmax, n);
            rc = cli_report(&err);
        } else {
            qsort(rows, cnt, sizeof *rows, cmp_rows);
            printf("# profile-plan: N = %ld, s_mm = %g, sigma_disp_um = %g, sigma_angle_urad = %g; "
                   "%zu usable pairs with %ld <= d1 < d2 <= %ld, ranked by least-squares %s of u(f)\n",
                   n, s, sd, sa, cnt, dmin, dmax, sort_by_max ? "worst point" : "RMS");
            printf("rank,d1,d2,D1_mm,D2_mm,lsq_rms_nm,lsq_max_nm,dft_rms_nm,dft_max_nm\n");
            for (size_t i = 0; i < cnt && (long)i < top; ++i) {
                printf("%zu,%d,%d,%g,%g", i + 1, rows[i].d1, rows[i].d2, rows[i].d1 * s, rows[i].d2 * s);
                print_num(rows[i].lsq_rms);
                print_num(rows[i].lsq_max);
                print_num(rows[i].dft_rms);
                print_num(rows[i].dft_max);
                printf("\n");
            }
        }
    }
    free(rows);
    free(u);
    return rc;
}
