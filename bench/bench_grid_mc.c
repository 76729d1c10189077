/* bench_grid_mc — Monte Carlo of Petrò (2019) §5: how much of the measurement noise σ_r ends up in
 * the estimated stage error, for Ye's method, the double shift and least squares.
 *
 * σ_C = sample standard deviation of all values of Ĝx − Gx and Ĝy − Gy (the truth in the SPEC
 * gauge), per simulation; a table entry is sqrt(mean σ_C²) over the trials, divided by σ_r.
 * Usage: bench_grid_mc [--full] [--trials T]   (default: a short run; --full: the complete one)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "selfcal/grid_exact.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"

enum { M_YE, M_DS, M_LSQ_YE, M_LSQ_DS, N_METHODS };
static const char *method_name[N_METHODS] = {"ye", "double-shift", "lsq (Ye views)",
                                             "lsq (Petro views)"};

typedef struct estimator {
    int method, n;
    sc_grid_plan plan;
    sc_grid_exact_plan *xp;
    sc_grid_lsq_plan *q;
    double pred_rms; /* lsq: predicted RMS std(G)/σ_r */
} estimator;

static void die(const char *what, const sc_error *err)
{
    char buf[1024];
    sc_error_format(err, buf, sizeof buf);
    fprintf(stderr, "bench_grid_mc: %s: %s\n", what, buf);
    exit(1);
}

static void est_make(estimator *e, int method, int n)
{
    sc_error err;
    memset(e, 0, sizeof *e);
    e->method = method;
    e->n = n;
    e->pred_rms = NAN;
    int ye_views = method == M_YE || method == M_LSQ_YE;
    sc_status st = ye_views ? sc_grid_plan_ye(n, 1.0, 0, 0, &e->plan, &err)
                            : sc_grid_plan_double_shift(n, 1.0, 0, 0, &e->plan, &err);
    if (st != SC_OK)
        die("plan", &err);
    if (method == M_YE || method == M_DS) {
        st = sc_grid_exact_plan_create(method == M_YE ? SC_GRID_YE : SC_GRID_DOUBLE_SHIFT, n,
                                       &e->xp, &err);
    } else {
        st = sc_grid_lsq_plan_create(&e->plan, NULL, NULL, &e->q, &err);
        if (st == SC_OK) {
            sc_grid_lsq_info info;
            sc_grid_lsq_get_info(e->q, &info);
            e->pred_rms = info.sigma_c_ratio_rms;
        }
    }
    if (st != SC_OK)
        die("estimator", &err);
}

static void est_free(estimator *e)
{
    sc_grid_exact_plan_destroy(e->xp);
    sc_grid_lsq_plan_destroy(e->q);
    sc_grid_plan_free(&e->plan);
}

/* One simulation + estimate; returns σ_C (µm). */
static double trial(estimator *e, const sc_grid_sim_params *sp)
{
    int n = e->n, nn = n * n;
    sc_error err;
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    if (sc_grid_plan_copy(&d.plan, &e->plan, &err) != SC_OK ||
        sc_grid_data_alloc(&d, &err) != SC_OK)
        die("alloc", &err);
    int nv = d.plan.n_views;
    /* G, A, workspace, result; then the truth's and the result's per-view arrays */
    double *buf = malloc((size_t)(10 * nn + (3 + SC_GRID_RESULT_VIEW_ARRAYS) * nv) *
                         sizeof(double));
    if (!buf) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    t.gx_um = buf, t.gy_um = buf + nn, t.ax_um = buf + 2 * nn, t.ay_um = buf + 3 * nn;
    t.tx_um = buf + 10 * nn, t.ty_um = t.tx_um + nv, t.theta_urad = t.ty_um + nv;
    if (sc_grid_sim_run(&d.plan, sp, &t, &d, buf + 4 * nn, &err) != SC_OK)
        die("simulate", &err);
    sc_grid_result r;
    memset(&r, 0, sizeof r);
    r.gx_um = buf + 6 * nn, r.gy_um = buf + 7 * nn, r.ax_um = buf + 8 * nn, r.ay_um = buf + 9 * nn;
    r.tx_um = t.theta_urad + nv, r.ty_um = r.tx_um + nv, r.theta_urad = r.ty_um + nv;
    sc_status st = e->xp ? sc_grid_exact_execute(e->xp, &d, &r, &err)
                         : sc_grid_lsq_execute(e->q, &d, sp->sigma_r_um, &r, &err);
    if (st != SC_OK)
        die("solve", &err);
    double mean = 0, var = 0;
    for (int k = 0; k < nn; ++k)
        mean += (r.gx_um[k] - t.gx_um[k]) + (r.gy_um[k] - t.gy_um[k]);
    mean /= 2 * nn;
    for (int k = 0; k < nn; ++k) {
        double ex = r.gx_um[k] - t.gx_um[k] - mean, ey = r.gy_um[k] - t.gy_um[k] - mean;
        var += ex * ex + ey * ey;
    }
    sc_grid_data_free(&d);
    free(buf);
    return sqrt(var / (2 * nn - 1));
}

/* sqrt(mean σ_C²)/σ_r over `trials` simulations with seeds seed0, seed0+1, ... */
static double ratio(estimator *e, double sigma_r, double sigma_g, int trials, unsigned seed0,
                    double *rel_se)
{
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.sigma_r_um = sigma_r;
    sp.sigma_g_um = sigma_g;
    sp.O = sp.R = 1e-5 * sigma_g; /* keeps the first-order share of σ_G the same for any σ_G */
    double s2 = 0, s4 = 0;
    for (int k = 0; k < trials; ++k) {
        sp.seed = seed0 + (unsigned)k;
        double c = trial(e, &sp);
        s2 += c * c;
        s4 += c * c * c * c;
    }
    double m2 = s2 / trials, v2 = trials > 1 ? (s4 / trials - m2 * m2) / (trials - 1) : 0;
    if (rel_se)
        *rel_se = 0.5 * sqrt(fmax(v2, 0)) / m2; /* standard error of sqrt(mean σ_C²), relative */
    return sqrt(m2) / sigma_r;
}

int main(int argc, char **argv)
{
    int full = 0, trials = 0;
    for (int a = 1; a < argc; ++a) {
        if (!strcmp(argv[a], "--full"))
            full = 1;
        else if (!strcmp(argv[a], "--trials") && a + 1 < argc)
            trials = atoi(argv[++a]);
        else {
            fprintf(stderr, "usage: bench_grid_mc [--full] [--trials T]\n");
            return 2;
        }
    }
    if (trials <= 0)
        trials = full ? 200 : 10;
    const int ns_full[4] = {9, 15, 25, 41}, ns_short[4] = {9, 15, 25, 41};
    const int *ns = full ? ns_full : ns_short;
    const int n_n = 4;
    const double srs[4] = {0.001, 0.01, 0.1, 1.0};
    clock_t t0 = clock();

    printf("# Grid self-calibration Monte Carlo (Petrò 2019 §5): sigma_C / sigma_r\n");
    printf("# simulation: sigma_G = 1 um, SAR(1) rho = 0.9 (row-standardised weights), O = R = 1e-5,\n"
           "# sigma_A = 1 um, misalignment sigma_t = 0.1 um, sigma_theta = 100 urad; pitch 1 mm;\n"
           "# %d trials per entry (%s run); sigma_C = sample std of all Ghat-G values (gauged truth).\n\n",
           trials, full ? "full" : "short");

    /* Table 1: σ_C/σ_r for every N, σ_r, method. */
    double tab[4][N_METHODS][4], pred[4][N_METHODS], se[4][N_METHODS][4];
    printf("## 1. sigma_C / sigma_r\n\n");
    printf("| N  | method            | sr=0.001 | sr=0.01  | sr=0.1   | sr=1     | lsq predicted |\n");
    printf("|----|-------------------|----------|----------|----------|----------|---------------|\n");
    for (int a = 0; a < n_n; ++a) {
        for (int m = 0; m < N_METHODS; ++m) {
            estimator e;
            est_make(&e, m, ns[a]);
            pred[a][m] = e.pred_rms;
            printf("| %-2d | %-17s |", ns[a], method_name[m]);
            for (int s = 0; s < 4; ++s) {
                tab[a][m][s] = ratio(&e, srs[s], 1.0, trials, 1000u * (unsigned)(s + 1), &se[a][m][s]);
                printf(" %8.4f |", tab[a][m][s]);
            }
            if (isfinite(e.pred_rms))
                printf(" %13.4f |\n", e.pred_rms);
            else
                printf("             - |\n");
            fflush(stdout);
            est_free(&e);
        }
    }

    /* Table 2: least squares, empirical vs predicted (pooled over the four σ_r). */
    printf("\n## 2. least squares: empirical sigma_C/sigma_r vs predicted (sigma_c_ratio_rms)\n\n");
    char head[64];
    snprintf(head, sizeof head, "empirical (4 x %d trials)", trials);
    printf("| N  | views  | %-26s | predicted | empirical/predicted | +- (1 s.e.) |\n", head);
    printf("|----|--------|----------------------------|-----------|---------------------|-------------|\n");
    for (int a = 0; a < n_n; ++a)
        for (int m = M_LSQ_YE; m <= M_LSQ_DS; ++m) {
            double s2 = 0, r2 = 0;
            for (int s = 0; s < 4; ++s)
                s2 += tab[a][m][s] * tab[a][m][s], r2 += se[a][m][s] * se[a][m][s];
            double emp = sqrt(s2 / 4), rse = sqrt(r2) / 4;
            printf("| %-2d | %-6s | %26.4f | %9.4f | %19.4f | %11.4f |\n", ns[a],
                   m == M_LSQ_YE ? "Ye" : "Petro", emp, pred[a][m], emp / pred[a][m], rse);
        }

    /* Table 3: σ_C does not depend on σ_G (same seeds: same noise, different G). */
    printf("\n## 3. sigma_C does not depend on sigma_G (N = 25, sigma_r = 0.01 um, O = R = 1e-5 x sigma_G/um,\n"
           "##    the same seeds for every sigma_G: same noise and plate, G scaled)\n\n");
    printf("| method            | sG=0.1 um | sG=1 um   | sG=10 um  | max rel. difference |\n");
    printf("|-------------------|-----------|-----------|-----------|---------------------|\n");
    int tg = full ? 20 : 3;
    for (int m = 0; m < N_METHODS; ++m) {
        estimator e;
        est_make(&e, m, 25);
        double v[3];
        const double sg[3] = {0.1, 1.0, 10.0};
        for (int k = 0; k < 3; ++k)
            v[k] = ratio(&e, 0.01, sg[k], tg, 777u, NULL);
        double dmax = fmax(fabs(v[0] - v[1]), fabs(v[2] - v[1])) / v[1];
        printf("| %-17s | %9.5f | %9.5f | %9.5f | %19.2e |\n", method_name[m], v[0], v[1], v[2],
               dmax);
        est_free(&e);
    }

    /* Table 4: growth with N, fits of σ_C/σ_r (mean over σ_r) = a·N^b and = a + b·N. */
    printf("\n## 4. growth of sigma_C/sigma_r with N (mean over sigma_r), least-squares fits:\n"
           "##    power law a*N^b, line a + b*N, logarithm a + b*ln(N) (rms misfit of each)\n\n");
    printf("| method            |");
    for (int a = 0; a < n_n; ++a)
        printf(" N=%-2d   |", ns[a]);
    printf(" power a, b     misfit | line a, b        misfit | log a, b        misfit |\n");
    printf("|-------------------|");
    for (int a = 0; a < n_n; ++a)
        printf("--------|");
    printf("------------------------|-------------------------|------------------------|\n");
    for (int m = 0; m < N_METHODS; ++m) {
        double X[4], Y[4], L[4], sx = 0, sy = 0, sxx = 0, sxy = 0, lx = 0, ly = 0, lxx = 0, lxy = 0;
        printf("| %-17s |", method_name[m]);
        for (int a = 0; a < n_n; ++a) {
            double s = 0;
            for (int k = 0; k < 4; ++k)
                s += tab[a][m][k];
            Y[a] = s / 4;
            X[a] = log(ns[a]);
            L[a] = log(Y[a]);
            printf(" %6.3f |", Y[a]);
            sx += X[a], sy += L[a], sxx += X[a] * X[a], sxy += X[a] * L[a];
            lx += ns[a], ly += Y[a], lxx += (double)ns[a] * ns[a], lxy += ns[a] * Y[a];
        }
        double b = (n_n * sxy - sx * sy) / (n_n * sxx - sx * sx), la = (sy - b * sx) / n_n;
        double bl = (n_n * lxy - lx * ly) / (n_n * lxx - lx * lx), al = (ly - bl * lx) / n_n;
        /* a + b ln N: regress Y on X = ln N. */
        double gx = 0, gy = 0, gxx = 0, gxy = 0;
        for (int a = 0; a < n_n; ++a)
            gx += X[a], gy += Y[a], gxx += X[a] * X[a], gxy += X[a] * Y[a];
        double bg = (n_n * gxy - gx * gy) / (n_n * gxx - gx * gx), ag = (gy - bg * gx) / n_n;
        double e1 = 0, e2 = 0, e3 = 0;
        for (int a = 0; a < n_n; ++a) {
            double r1 = exp(la) * pow(ns[a], b) - Y[a], r2 = al + bl * ns[a] - Y[a],
                   r3 = ag + bg * X[a] - Y[a];
            e1 += r1 * r1, e2 += r2 * r2, e3 += r3 * r3;
        }
        printf(" %6.4f %6.4f %8.1e | %6.4f %7.5f %8.1e | %6.4f %6.4f %8.1e |\n", exp(la), b,
               sqrt(e1 / n_n), al, bl, sqrt(e2 / n_n), ag, bg, sqrt(e3 / n_n));
    }
    /* Table 5 (--full): least squares' predicted ratio over a wider range of N (no simulation). */
    if (full) {
        const int big[7] = {9, 15, 25, 41, 61, 81, 101};
        printf("\n## 5. least squares, predicted sigma_c_ratio_rms (and max) over a wider range of N\n\n");
        printf("| views  |");
        for (int a = 0; a < 7; ++a)
            printf(" N=%-3d         |", big[a]);
        printf("\n|--------|");
        for (int a = 0; a < 7; ++a)
            printf("---------------|");
        printf("\n");
        for (int m = M_LSQ_YE; m <= M_LSQ_DS; ++m) {
            printf("| %-6s |", m == M_LSQ_YE ? "Ye" : "Petro");
            for (int a = 0; a < 7; ++a) {
                estimator e;
                est_make(&e, m, big[a]);
                sc_grid_lsq_info info;
                sc_grid_lsq_get_info(e.q, &info);
                printf(" %.4f (%.3f) |", info.sigma_c_ratio_rms, info.sigma_c_ratio_max);
                fflush(stdout);
                est_free(&e);
            }
            printf("\n");
        }
    }
    printf("\n# CPU time: %.1f s\n", (double)(clock() - t0) / CLOCKS_PER_SEC);
    return 0;
}
