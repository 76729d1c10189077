/* Unit tests of the straightness-profile area: both methods against simulated truth (random and
 * DABAM profiles, stage errors, zero-point errors), the DFT method's analytic uncertainty against
 * its brute-force linear response and against Monte Carlo, the strict reader, the simulation. */
#define _GNU_SOURCE /* sched_getaffinity: is there a second core for the two-thread reader */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid_exact.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"
#include "selfcal/profile_sim.h"
#include "../../libselfcal/src/io/profile_file_internal.h" /* the reader's two-thread switch */

#define TMP SELFCAL_TEST_TMP
#define DABAM SELFCAL_TEST_DATA_DIR "/dabam/"

/* Simulate a noise-free measurement of f with stage and zero-point errors; reconstruct it with
 * method; return the worst |f - f_true| and |e_y - e_y true| (µm). */
static void reconstruct_noise_free(int n, int d1, int d2, const double *f_true, sc_profile_method m,
                                   double *err_f, double *err_ey)
{
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    p.d1 = d1;
    p.d2 = d2;
    p.sigma_disp_um = p.sigma_angle_urad = 0;
    p.seed = 1000u + (unsigned)n + 7u * (unsigned)d1;
    sc_profile_data d;
    sc_error err;
    double *ey_true = malloc((size_t)n * sizeof(double)), *f = malloc((size_t)n * sizeof(double));
    double *y1 = malloc((size_t)n * sizeof(double)), *y2 = malloc((size_t)n * sizeof(double));
    double *ey = malloc((size_t)n * sizeof(double));
    assert_int_equal(sc_profile_simulate(&p, f_true, &d, ey_true, &err), SC_OK);
    sc_profile_combine(&d, 0, y1);
    sc_profile_combine(&d, 1, y2);
    /* unequal weights as for the real noise model */
    double w1 = 1.0 / sc_profile_y_variance(d1, 1.0, 0.01, 1.0);
    double w2 = 1.0 / sc_profile_y_variance(d2, 1.0, 0.01, 1.0);
    if (m == SC_PROFILE_DFT) {
        sc_profile_dft_plan *pl;
        assert_int_equal(sc_profile_dft_plan_create(n, d1, d2, w1, w2, &pl, &err), SC_OK);
        assert_int_equal(sc_profile_dft_execute(pl, y1, y2, f, &err), SC_OK);
        sc_profile_dft_plan_destroy(pl);
    } else {
        sc_profile_lsq_plan *pl;
        assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, w1, w2, &pl, &err), SC_OK);
        assert_int_equal(sc_profile_lsq_execute(pl, y1, y2, f, NULL, NULL, &err), SC_OK);
        sc_profile_lsq_plan_destroy(pl);
    }
    sc_profile_stage_error(&d, f, ey);
    sc_profile_remove_line(n - d1, ey_true);
    *err_f = *err_ey = 0;
    for (int i = 0; i < n; ++i)
        *err_f = fmax(*err_f, fabs(f[i] - f_true[i]));
    for (int i = 0; i < n - d1; ++i)
        *err_ey = fmax(*err_ey, fabs(ey[i] - ey_true[i]));
    sc_profile_data_free(&d);
    free(ey_true), free(f), free(y1), free(y2), free(ey);
}

static void random_profile(int n, uint64_t seed, double *f)
{
    sc_rng r;
    sc_rng_seed(&r, seed);
    sc_profile_random_smooth(n, 1.0, 40, &r, f);
}

static const int CONFIGS[][3] = {{330, 10, 11}, {330, 3, 11}, {110, 10, 11}, {2310, 10, 11}};

static void test_noise_free_both_methods(void **state)
{
    (void)state;
    for (size_t c = 0; c < sizeof CONFIGS / sizeof CONFIGS[0]; ++c) {
        int n = CONFIGS[c][0], d1 = CONFIGS[c][1], d2 = CONFIGS[c][2];
        double *f = malloc((size_t)n * sizeof(double));
        random_profile(n, 42 + c, f);
        for (int m = 0; m < 2; ++m) {
            double ef, ey;
            reconstruct_noise_free(n, d1, d2, f, (sc_profile_method)m, &ef, &ey);
            print_message("N=%d d=%d/%d %s: max |f err| %.2e um, max |e_y err| %.2e um\n", n, d1, d2,
                          m ? "lsq" : "dft", ef, ey);
            assert_true(ef <= 1e-9);
            assert_true(ey <= 1e-9);
        }
        free(f);
    }
}

static void test_lsq_noise_free_any_n(void **state)
{
    (void)state;
    static const int cfg[][3] = {{331, 10, 11}, {500, 7, 13}, {21, 10, 11}, {1000, 97, 101}, {257, 2, 3}};
    for (size_t c = 0; c < sizeof cfg / sizeof cfg[0]; ++c) {
        int n = cfg[c][0];
        double *f = malloc((size_t)n * sizeof(double)), ef, ey;
        random_profile(n, 7 + c, f);
        reconstruct_noise_free(n, cfg[c][1], cfg[c][2], f, SC_PROFILE_LSQ, &ef, &ey);
        print_message("lsq N=%d d=%d/%d: %.2e / %.2e um\n", n, cfg[c][1], cfg[c][2], ef, ey);
        assert_true(ef <= 1e-9);
        assert_true(ey <= 1e-9);
        free(f);
    }
}

static void test_dabam_profiles(void **state)
{
    (void)state;
    static const char *files[] = {"dabam-001.dat", "dabam-002.dat", "dabam-010.dat", "dabam-020.dat",
                                  "dabam-030.dat"};
    for (size_t k = 0; k < sizeof files / sizeof files[0]; ++k) {
        char path[512], info[512];
        snprintf(path, sizeof path, DABAM "%s", files[k]);
        for (int cfg = 0; cfg < 2; ++cfg) {
            int n = cfg ? 401 : 330, d1 = cfg ? 7 : 10, d2 = cfg ? 13 : 11;
            double *f = malloc((size_t)n * sizeof(double)), ef, ey;
            sc_error err;
            assert_int_equal(sc_profile_load_dabam(path, n, 1.0, f, info, sizeof info, &err), SC_OK);
            double ss = 0;
            for (int i = 0; i < n; ++i)
                ss += f[i] * f[i];
            assert_true(sqrt(ss / n) > 1e-4); /* a real profile, not zeros */
            for (int m = cfg ? 1 : 0; m < 2; ++m) {
                reconstruct_noise_free(n, d1, d2, f, (sc_profile_method)m, &ef, &ey);
                print_message("%s (rms %.3f um) %s N=%d: %.2e um\n", info, sqrt(ss / n), m ? "lsq" : "dft",
                              n, ef);
                assert_true(ef <= 1e-9);
                assert_true(ey <= 1e-9);
            }
            free(f);
        }
    }
}

/* A slope profile (linear slope) integrates exactly by the trapezoid rule to a parabola. */
static void test_dabam_slope_integration(void **state)
{
    (void)state;
    FILE *fp = fopen(TMP "/fake-dabam.txt", "w");
    assert_non_null(fp);
    fprintf(fp, "{\n \"FILE_FORMAT\": 1,\n \"FILE_HEADER_LINES\": 2,\n \"X1_FACTOR\": 0.001,\n"
                " \"Y1_FACTOR\": 1e-06,\n \"PLOT_TITLE_Y1\": \"Slope (urad)\"\n}\n");
    fclose(fp);
    fp = fopen(TMP "/fake-dabam.dat", "w");
    assert_non_null(fp);
    fprintf(fp, "header one\r\nx(mm)\tslope(urad)\r\n");
    /* slope(x) = 2 + 0.5 x  (x in mm, slope in µrad) -> height = 2x + x²/4 (µrad·mm = nm) */
    for (int i = 0; i <= 200; ++i)
        fprintf(fp, "%d\t%.10g\r\n", i - 100, 2 + 0.5 * (i - 100));
    fclose(fp);
    int n = 101;
    double f[101], g[101];
    sc_error err;
    assert_int_equal(sc_profile_load_dabam(TMP "/fake-dabam.dat", n, 2.0, f, NULL, 0, &err), SC_OK);
    for (int i = 0; i < n; ++i) {
        double x = -100 + 2.0 * i;
        g[i] = (2 * x + 0.25 * x * x) * 1e-3; /* µm */
    }
    sc_profile_remove_line(n, g);
    for (int i = 0; i < n; ++i)
        assert_true(fabs(f[i] - g[i]) < 1e-9);
    /* longer than the file: stretched, still the parabola's shape */
    assert_int_equal(sc_profile_load_dabam(TMP "/fake-dabam.dat", n, 5.0, f, NULL, 0, &err), SC_OK);
    for (int i = 0; i < n; ++i)
        assert_true(fabs(f[i] - g[i]) < 1e-9);
}

/* Factors and values beyond any mirror are refused with the file (and line), never turned into
 * NaN heights (fuzz_dabam: X1_FACTOR = 1e306 made every height NaN); so is an over-long line. */
static void test_dabam_refusals(void **state)
{
    (void)state;
    static const struct {
        const char *xf, *yf, *row;
        long line;
    } bad[] = {
        {"1e306", "1e-06", "1\t2\n", 0},  {"0", "1e-06", "1\t2\n", 0},
        {"-0.001", "1e-06", "1\t2\n", 0}, {"0.001", "0", "1\t2\n", 0},
        {"0.001", "1e300", "1\t2\n", 0},  {"0.001", "1e-06", "1e300\t2\n", 4},
        {"0.001", "1e-06", "1\t2e300\n", 4},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0] + 1; ++k) {
        int last = k == sizeof bad / sizeof bad[0]; /* a line longer than the reader's buffer */
        FILE *fp = fopen(TMP "/bad-dabam.txt", "w");
        assert_non_null(fp);
        fprintf(fp, "{\n \"FILE_HEADER_LINES\": 1,\n \"X1_FACTOR\": %s,\n \"Y1_FACTOR\": %s\n}\n",
                last ? "0.001" : bad[k].xf, last ? "1e-06" : bad[k].yf);
        fclose(fp);
        fp = fopen(TMP "/bad-dabam.dat", "w");
        assert_non_null(fp);
        fprintf(fp, "x\ty\n0\t1\n0.5\t1\n");
        if (last)
            fprintf(fp, "%5000s1\t2\n", "");
        else
            fputs(bad[k].row, fp);
        fprintf(fp, "2\t1\n3\t1\n");
        fclose(fp);
        double f[16];
        sc_error err;
        sc_error_clear(&err);
        assert_int_equal(sc_profile_load_dabam(TMP "/bad-dabam.dat", 16, 0.1, f, NULL, 0, &err), SC_E_INPUT);
        long want = last ? 4 : bad[k].line;
        if (err.line != want)
            fail_msg("case %zu: line %ld, want %ld (%s)", k, err.line, want, err.msg);
        assert_non_null(strstr(err.file, want ? "bad-dabam.dat" : "bad-dabam.txt"));
    }
    /* a .dat that does not exist (its .txt does): the error names the .dat the caller gave */
    remove(TMP "/gone-dabam.dat");
    FILE *fp = fopen(TMP "/gone-dabam.txt", "w");
    assert_non_null(fp);
    fprintf(fp, "{\n \"FILE_HEADER_LINES\": 1\n}\n");
    fclose(fp);
    double f[16];
    sc_error err;
    sc_error_clear(&err);
    assert_int_not_equal(sc_profile_load_dabam(TMP "/gone-dabam.dat", 16, 0.1, f, NULL, 0, &err), SC_OK);
    assert_non_null(strstr(err.file, "gone-dabam.dat"));
    assert_non_null(strstr(err.msg, "cannot open"));
}

/* The DFT method's analytic uncertainty equals the one from its brute-force linear response. */
static void test_dft_uncertainty_exact(void **state)
{
    (void)state;
    static const int cfg[][3] = {{66, 3, 11}, {110, 10, 11}, {60, 4, 5}, {105, 5, 7}};
    for (size_t c = 0; c < sizeof cfg / sizeof cfg[0]; ++c) {
        int n = cfg[c][0], d1 = cfg[c][1], d2 = cfg[c][2];
        double w[2] = {3.0, 0.7};
        sc_profile_dft_plan *p;
        sc_error err;
        assert_int_equal(sc_profile_dft_plan_create(n, d1, d2, w[0], w[1], &p, &err), SC_OK);
        double *u = malloc((size_t)n * sizeof(double)), *var = calloc((size_t)n, sizeof(double));
        double *y[2] = {calloc((size_t)n, sizeof(double)), calloc((size_t)n, sizeof(double))};
        double *f = malloc((size_t)n * sizeof(double));
        assert_int_equal(sc_profile_dft_uncertainty(p, u, NULL, &err), SC_OK);
        for (int k = 0; k < 2; ++k)
            for (int i = 0; i < n - cfg[c][1 + k]; ++i) {
                y[k][i] = 1.0;
                assert_int_equal(sc_profile_dft_execute(p, y[0], y[1], f, &err), SC_OK);
                y[k][i] = 0.0;
                for (int j = 0; j < n; ++j)
                    var[j] += f[j] * f[j] / w[k];
            }
        double worst = 0;
        for (int j = 0; j < n; ++j)
            worst = fmax(worst, fabs(u[j] - sqrt(var[j])) / sqrt(var[j]));
        print_message("dft N=%d d=%d/%d: analytic vs response, worst relative difference %.2e\n", n, d1,
                      d2, worst);
        assert_true(worst < 1e-9);
        sc_profile_dft_plan_destroy(p);
        free(u), free(var), free(y[0]), free(y[1]), free(f);
    }
}

typedef struct mc_ctx {
    sc_profile_dft_plan *dft;
    sc_profile_lsq_plan *lsq;
} mc_ctx;

static sc_status mc_solve(void *vc, const double *y1, const double *y2, double *f, sc_error *err)
{
    mc_ctx *c = vc;
    if (c->dft)
        return sc_profile_dft_execute(c->dft, y1, y2, f, err);
    return sc_profile_lsq_execute(c->lsq, y1, y2, f, NULL, NULL, err);
}

/* The paper's set-up: predicted uncertainty equals Monte Carlo; LS about 12 nm in the middle. */
static void test_paper_setup_mc(void **state)
{
    (void)state;
    const int n = 330;
    const long trials = 3000;
    static const int pairs[][2] = {{10, 11}, {3, 11}};
    for (int pi = 0; pi < 2; ++pi) {
        int d1 = pairs[pi][0], d2 = pairs[pi][1];
        double v1 = sc_profile_y_variance(d1, 1.0, 0.010, 1.0), v2 = sc_profile_y_variance(d2, 1.0, 0.010, 1.0);
        for (int m = 0; m < 2; ++m) {
            mc_ctx c = {NULL, NULL};
            sc_error err;
            double *u = malloc(n * sizeof(double)), *umc = malloc(n * sizeof(double));
            if (m == 0) {
                assert_int_equal(sc_profile_dft_plan_create(n, d1, d2, 1 / v1, 1 / v2, &c.dft, &err), SC_OK);
                assert_int_equal(sc_profile_dft_uncertainty(c.dft, u, NULL, &err), SC_OK);
            } else {
                assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1 / v1, 1 / v2, &c.lsq, &err), SC_OK);
                assert_int_equal(sc_profile_lsq_uncertainty(c.lsq, u, NULL, &err), SC_OK);
            }
            assert_int_equal(sc_profile_mc_uncertainty(n, d1, d2, sqrt(v1), sqrt(v2), mc_solve, &c, trials,
                                                       99 + pi, NULL, NULL, umc, &err),
                             SC_OK);
            double s1 = 0, s2 = 0, worst = 0;
            for (int i = 0; i < n; ++i) {
                s1 += u[i] * u[i];
                s2 += umc[i] * umc[i];
                worst = fmax(worst, fabs(umc[i] / u[i] - 1));
            }
            double ratio = sqrt(s2 / s1);
            print_message("%s d=%d/%d: u(mid) %.2f nm, u(0) %.2f nm, MC/predicted RMS %.4f, worst point %.3f\n",
                          m ? "lsq" : "dft", d1, d2, u[n / 2] * 1e3, u[0] * 1e3, ratio, worst);
            assert_true(fabs(ratio - 1) < 0.03);
            assert_true(worst < 0.10); /* 3000 trials: 1.3 % per point standard error */
            /* "most of the values close to 12 nm" in the middle */
            assert_true(u[n / 2] > 0.010 && u[n / 2] < 0.014);
            sc_profile_dft_plan_destroy(c.dft);
            sc_profile_lsq_plan_destroy(c.lsq);
            free(u), free(umc);
        }
    }
}

/* Noise estimated from the residuals (weights unknown) comes out near the simulated noise. */
static void test_residual_noise_estimate(void **state)
{
    (void)state;
    const int n = 1100, d1 = 10, d2 = 11;
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    p.sigma_angle_urad = 0; /* y noise = sqrt(2)·σ_disp on both scans */
    p.sigma_disp_um = 0.02;
    double *f = malloc(n * sizeof(double)), *ey = malloc(n * sizeof(double)), *fe = malloc(n * sizeof(double));
    double *y1 = malloc(n * sizeof(double)), *y2 = malloc(n * sizeof(double));
    random_profile(n, 3, f);
    sc_profile_data d;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &d, ey, &err), SC_OK);
    sc_profile_combine(&d, 0, y1);
    sc_profile_combine(&d, 1, y2);
    sc_profile_lsq_plan *pl;
    assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1, 1, &pl, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_execute(pl, y1, y2, fe, NULL, NULL, &err), SC_OK);
    int dof;
    double ss = sc_profile_residual_ss(n, d1, d2, y1, y2, fe, 1, 1, &dof);
    double est = sqrt(ss / dof), truth = sqrt(2) * 0.02;
    print_message("estimated sigma_y %.5f um, simulated %.5f um\n", est, truth);
    assert_true(fabs(est / truth - 1) < 0.08);
    sc_profile_lsq_plan_destroy(pl);
    sc_profile_data_free(&d);
    free(f), free(ey), free(fe), free(y1), free(y2);
}

/* The sensors' zero points, end to end: a zero offset of scan k's second displacement sensor
 * (m2 + e_k) is the offset c_k of y_k = m2 - m1 - D_k·m3, which the fit estimates and which must
 * change nothing else. Through the calibration the CLI runs (both methods, noise estimated from
 * the residuals, whose fit has its own c_k): the same f, u(f), e_y and residual sum; through
 * least squares: c moves by exactly (+e_1, +e_2), with the sign of the data's own offsets. */
static void test_zero_point_offsets(void **state)
{
    (void)state;
    const int n = 1100;
    const double e[2] = {3.0, -2.0};
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    double *f = malloc(n * sizeof(double)), *ey = malloc(n * sizeof(double));
    random_profile(n, 21, f);
    sc_profile_data a, b;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &a, ey, &err), SC_OK);
    assert_int_equal(sc_profile_simulate(&p, f, &b, ey, &err), SC_OK);
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < n - b.d[k]; ++j)
            b.m2_um[k][j] += e[k];
    double *ra = malloc(3 * n * sizeof(double)), *rb = malloc(3 * n * sizeof(double));
    for (int m = 0; m < 2; ++m) {
        sc_profile_options o;
        sc_profile_options_default(&o);
        o.method = m ? SC_PROFILE_DFT : SC_PROFILE_LSQ;
        a.has_sigma_disp = a.has_sigma_angle = b.has_sigma_disp = b.has_sigma_angle = 0;
        sc_profile_solution sa = {.f_um = ra, .uf_um = ra + n, .ey_um = ra + 2 * n};
        sc_profile_solution sb = {.f_um = rb, .uf_um = rb + n, .ey_um = rb + 2 * n};
        assert_int_equal(sc_profile_calibrate(&a, &o, &sa, &err), SC_OK);
        assert_int_equal(sc_profile_calibrate(&b, &o, &sb, &err), SC_OK);
        double worst = 0;
        for (int i = 0; i < n; ++i)
            worst = fmax(worst, fabs(ra[i] - rb[i]));
        print_message("%s: zero offsets (%+g, %+g) um move f by at most %.3g um; wrss %.6g vs %.6g\n",
                      m ? "dft" : "lsq", e[0], e[1], worst, sa.wrss, sb.wrss);
        for (int i = 0; i < 3 * n; ++i)
            if (!(isnan(ra[i]) && isnan(rb[i])))
                assert_true(fabs(ra[i] - rb[i]) < 1e-9);
        assert_true(isfinite(sa.wrss) && sa.wrss > 0);
        assert_true(fabs(sb.wrss / sa.wrss - 1) < 1e-9);
    }
    /* least squares' own c: the offsets of the data, sign included */
    double *y1a = malloc(n * sizeof(double)), *y2a = malloc(n * sizeof(double));
    double *y1b = malloc(n * sizeof(double)), *y2b = malloc(n * sizeof(double));
    sc_profile_combine(&a, 0, y1a), sc_profile_combine(&a, 1, y2a);
    sc_profile_combine(&b, 0, y1b), sc_profile_combine(&b, 1, y2b);
    sc_profile_lsq_plan *pl;
    assert_int_equal(sc_profile_lsq_plan_create(n, a.d[0], a.d[1], 1, 1, &pl, &err), SC_OK);
    double ca[2], cb[2], wa, wb;
    assert_int_equal(sc_profile_lsq_execute(pl, y1a, y2a, ra, ca, &wa, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_execute(pl, y1b, y2b, rb, cb, &wb, &err), SC_OK);
    assert_true(fabs(cb[0] - ca[0] - e[0]) < 1e-9 && fabs(cb[1] - ca[1] - e[1]) < 1e-9);
    assert_true(fabs(wb / wa - 1) < 1e-9);
    /* the residual sum of a given f fits the offsets itself: the same with and without them */
    int dof;
    double sa_ss = sc_profile_residual_ss(n, a.d[0], a.d[1], y1a, y2a, ra, 1, 1, &dof);
    double sb_ss = sc_profile_residual_ss(n, a.d[0], a.d[1], y1b, y2b, ra, 1, 1, &dof);
    assert_true(fabs(sb_ss / sa_ss - 1) < 1e-9);
    sc_profile_lsq_plan_destroy(pl);
    sc_profile_data_free(&a);
    sc_profile_data_free(&b);
    free(f), free(ey), free(ra), free(rb), free(y1a), free(y2a), free(y1b), free(y2b);
}

/* Where the noise comes from: the options, else the header, else the residuals. Each source on
 * its own is used (a displacement noise alone, an angle noise alone); with none, every point's
 * uncertainty is the plan's unit uncertainty times sqrt(wrss/dof), the first and last included. */
static void test_noise_sources(void **state)
{
    (void)state;
    const int n = 1100;
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    double *f = malloc(n * sizeof(double)), *ey = malloc(n * sizeof(double));
    double *r = malloc(3 * n * sizeof(double)), *u = malloc(n * sizeof(double));
    random_profile(n, 5, f);
    sc_profile_data d;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &d, ey, &err), SC_OK);
    const struct {
        int hdr_sd, hdr_sa;       /* the header states them (0.02 um, 0.5 urad) */
        double opt_sd, opt_sa;    /* the options' (NaN: not given) */
        int known;
        double sd, sa;            /* the noise used */
    } cases[] = {
        {1, 1, NAN, NAN, 1, 0.02, 0.5},  {0, 0, 0.03, 0.7, 1, 0.03, 0.7},
        {0, 0, 0.03, NAN, 1, 0.03, 0.0}, {0, 0, NAN, 0.7, 1, 0.0, 0.7},
        {1, 0, NAN, NAN, 1, 0.02, 0.0},  {0, 1, NAN, NAN, 1, 0.0, 0.5},
        {1, 1, 0.03, NAN, 1, 0.03, 0.5}, {0, 0, NAN, NAN, 0, NAN, NAN},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k)
        for (int m = 0; m < 2; ++m) {
            sc_profile_options o;
            sc_profile_options_default(&o);
            o.method = m ? SC_PROFILE_DFT : SC_PROFILE_LSQ;
            o.sigma_disp_um = cases[k].opt_sd;
            o.sigma_angle_urad = cases[k].opt_sa;
            d.has_sigma_disp = cases[k].hdr_sd, d.sigma_disp_um = 0.02;
            d.has_sigma_angle = cases[k].hdr_sa, d.sigma_angle_urad = 0.5;
            sc_profile_solution s = {.f_um = r, .uf_um = r + n, .ey_um = r + 2 * n};
            assert_int_equal(sc_profile_calibrate(&d, &o, &s, &err), SC_OK);
            assert_int_equal(s.noise_known, cases[k].known);
            assert_int_equal(s.have_uf, 1);
            if (cases[k].known) {
                assert_true(s.sigma_disp_um == cases[k].sd);
                assert_true(s.sigma_angle_urad == cases[k].sa);
                continue;
            }
            /* estimated: equal weights, unit uncertainties scaled by sqrt(wrss/dof) */
            assert_true(isnan(s.sigma_disp_um) && isnan(s.sigma_angle_urad));
            double scale = sqrt(s.wrss / s.dof);
            assert_true(s.sigma_y_um[0] == scale && s.sigma_y_um[1] == scale);
            if (m == 0) {
                sc_profile_lsq_plan *pl;
                assert_int_equal(sc_profile_lsq_plan_create(n, d.d[0], d.d[1], 1, 1, &pl, &err), SC_OK);
                assert_int_equal(sc_profile_lsq_uncertainty(pl, u, NULL, &err), SC_OK);
                for (int i = 0; i < n; ++i)
                    assert_true(fabs(r[n + i] / (scale * u[i]) - 1) < 1e-12);
                sc_profile_lsq_plan_destroy(pl);
            }
        }
    sc_profile_data_free(&d);
    free(f), free(ey), free(r), free(u);
}

/* ---- the calibration in two steps (plan from the header, run on the data) ------------------- */

/* sc_profile_calibrate(d, o) and create(header of d, o) + run (twice): the same values, bit for bit. */
static void same_calibration(const sc_profile_data *d, const sc_profile_options *o)
{
    int n = d->n;
    size_t bytes = (size_t)n * sizeof(double);
    double *a = malloc(3 * bytes), *b = malloc(3 * bytes);
    sc_profile_solution sa = {.f_um = a, .uf_um = a + n, .ey_um = a + 2 * n};
    sc_error err;
    assert_int_equal(sc_profile_calibrate(d, o, &sa, &err), SC_OK);
    sc_profile_data hdr = *d; /* the header's fields only: the plan may not read the arrays */
    for (int k = 0; k < 2; ++k)
        hdr.m1_um[k] = hdr.m2_um[k] = hdr.m3_urad[k] = NULL;
    sc_profile_calibration *c;
    assert_int_equal(sc_profile_calibration_create(&hdr, o, &c, &err), SC_OK);
    for (int run = 0; run < 2; ++run) {
        memset(b, 0x5a, 3 * bytes);
        sc_profile_solution sb = {.f_um = b, .uf_um = b + n, .ey_um = b + 2 * n};
        assert_int_equal(sc_profile_calibration_run(c, d, &sb, &err), SC_OK);
        assert_memory_equal(a, b, 3 * bytes);
        assert_int_equal(sa.have_uf, sb.have_uf);
        assert_int_equal(sa.noise_known, sb.noise_known);
        assert_int_equal(sa.dof, sb.dof);
        double x[] = {sa.sigma_disp_um, sa.sigma_angle_urad, sa.sigma_y_um[0], sa.sigma_y_um[1],
                      sa.wrss, sa.residual_ratio};
        double y[] = {sb.sigma_disp_um, sb.sigma_angle_urad, sb.sigma_y_um[0], sb.sigma_y_um[1],
                      sb.wrss, sb.residual_ratio};
        assert_memory_equal(x, y, sizeof x);
    }
    sc_profile_calibration_destroy(c);
    free(a), free(b);
}

static void test_calibration_plan_and_run(void **state)
{
    (void)state;
    const int n = 1100;
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    double *f = malloc(n * sizeof(double)), *ey = malloc(n * sizeof(double));
    random_profile(n, 11, f);
    sc_profile_data d;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &d, ey, &err), SC_OK);
    for (int m = 0; m < 2; ++m)
        for (int noise = 0; noise < 4; ++noise) {
            sc_profile_options o;
            sc_profile_options_default(&o);
            o.method = m ? SC_PROFILE_DFT : SC_PROFILE_LSQ;
            d.has_sigma_disp = d.has_sigma_angle = noise == 0; /* 0: the header's noise */
            if (noise == 2) /* the options' noise */
                o.sigma_disp_um = 0.02, o.sigma_angle_urad = 0.5;
            if (noise == 3) /* Monte Carlo */
                o.mc_trials = 20, o.mc_seed = 9;
            o.residual_check = m == 0;
            same_calibration(&d, &o);
        }
    /* data of another header: refused, nothing written */
    sc_profile_options o;
    sc_profile_options_default(&o);
    sc_profile_calibration *c;
    assert_int_equal(sc_profile_calibration_create(&d, &o, &c, &err), SC_OK);
    sc_profile_data other = d;
    other.n = n - 1;
    double *out = malloc(3 * n * sizeof(double));
    sc_profile_solution s = {.f_um = out, .uf_um = out + n, .ey_um = out + 2 * n};
    assert_int_equal(sc_profile_calibration_run(c, &other, &s, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "not those the calibration was made for"));
    sc_profile_calibration_destroy(c);
    /* a plan the method cannot make: create's error is calibrate's, and *out NULL */
    other.n = 1101; /* not a multiple of d1·d2 = 110 for the DFT */
    o.method = SC_PROFILE_DFT;
    sc_error e1, e2;
    sc_status s1 = sc_profile_calibrate(&other, &o, &s, &e1);
    c = (sc_profile_calibration *)&o; /* must be set to NULL */
    sc_status s2 = sc_profile_calibration_create(&other, &o, &c, &e2);
    assert_int_equal(s1, SC_E_INPUT);
    assert_int_equal(s2, s1);
    assert_null(c);
    assert_string_equal(e1.msg, e2.msg);
    sc_profile_data_free(&d);
    free(f), free(ey), free(out);
}

/* ---- the reader ------------------------------------------------------------------------------ */

typedef struct text {
    int nlines;
    char *line[4096];
} text;

static void text_good(text *t, int n, int d1, int d2)
{
    char buf[256];
    t->nlines = 0;
#define ADD(...) (snprintf(buf, sizeof buf, __VA_ARGS__), t->line[t->nlines++] = strdup(buf))
    ADD("# selfcal-profile v1");
    ADD("# N = %d", n);
    ADD("# s_mm = 1.0");
    ADD("# scan 1: d=%d", d1);
    ADD("# scan 2: d=%d", d2);
    ADD("scan,n,m1_um,m2_um,m3_urad");
    for (int k = 1; k <= 2; ++k)
        for (int i = 0; i < n - (k == 1 ? d1 : d2); ++i)
            ADD("%d,%d,%.6f,%.6f,%.6f", k, i, 0.01 * i, 0.02 * i + k, 0.5);
#undef ADD
}

static void text_free(text *t)
{
    for (int i = 0; i < t->nlines; ++i)
        free(t->line[i]);
    t->nlines = 0;
}

/* line numbers are 1-based */
static void text_delete(text *t, int ln)
{
    free(t->line[ln - 1]);
    memmove(&t->line[ln - 1], &t->line[ln], (size_t)(t->nlines - ln) * sizeof(char *));
    t->nlines--;
}

static void text_set(text *t, int ln, const char *s)
{
    free(t->line[ln - 1]);
    t->line[ln - 1] = strdup(s);
}

/* The lines, each ended by eol (the last one too unless last_eol is 0). */
static const char *text_write_ends(const text *t, const char *eol, int last_eol)
{
    static const char *path = TMP "/profile_reader.csv";
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    for (int i = 0; i < t->nlines; ++i)
        fprintf(fp, "%s%s", t->line[i], i + 1 < t->nlines || last_eol ? eol : "");
    fclose(fp);
    return path;
}

static const char *text_write(const text *t)
{
    return text_write_ends(t, "\n", 1);
}

static void assert_same_data(const sc_profile_data *a, const sc_profile_data *b)
{
    assert_int_equal(a->n, b->n);
    assert_int_equal(a->d[0], b->d[0]);
    assert_int_equal(a->d[1], b->d[1]);
    assert_true(a->s_mm == b->s_mm);
    for (int k = 0; k < 2; ++k) {
        size_t bytes = (size_t)(a->n - a->d[k]) * sizeof(double);
        assert_memory_equal(a->m1_um[k], b->m1_um[k], bytes);
        assert_memory_equal(a->m2_um[k], b->m2_um[k], bytes);
        assert_memory_equal(a->m3_urad[k], b->m3_urad[k], bytes);
    }
}

/* Two cores for this process: then the reader must have used both. */
static int two_cpus(void)
{
    cpu_set_t set;
    return sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 1;
}

/* The file at path read with its rows split between two threads (threshold 0) and by one: same
 * status, same message and line, same values. The two-thread read's status. */
static sc_status read_both_ways(const char *path, int *threads)
{
    sc_profile_data a, b;
    sc_error ea, eb;
    sc_error_clear(&ea);
    sc_error_clear(&eb);
    int one = -1;
    sc_status sa = sc_profile_read_tuned(path, 0, threads, &a, &ea);
    sc_status sb = sc_profile_read_tuned(path, LLONG_MAX, &one, &b, &eb);
    assert_int_equal(sa, sb);
    if (sa != SC_OK) {
        assert_int_equal(ea.line, eb.line);
        assert_string_equal(ea.msg, eb.msg);
        assert_int_equal(*threads, 0);
        return sa;
    }
    assert_int_equal(one, 1);
    assert_same_data(&a, &b);
    assert_true(a.line_n == b.line_n && a.line_scan[0] == b.line_scan[0] &&
                a.line_scan[1] == b.line_scan[1] && a.has_sigma_disp == b.has_sigma_disp);
    sc_profile_data_free(&a);
    sc_profile_data_free(&b);
    return sa;
}

/* A file with gaps (SPEC §2a) reads, both ways alike, with NaN in the missing sample (scan k,
 * n = idx) and the samples beside it present. */
static void expect_gap(const text *t, int k, int idx)
{
    int threads;
    assert_int_equal(read_both_ways(text_write(t), &threads), SC_OK);
    sc_profile_data d;
    sc_error err;
    assert_int_equal(sc_profile_read(text_write(t), &d, &err), SC_OK);
    for (int i = 0; idx < 0 && i < d.n - d.d[k]; ++i) /* -1: wherever it is */
        if (isnan(d.m1_um[k][i]))
            idx = i;
    assert_true(idx >= 0);
    assert_true(isnan(d.m1_um[k][idx]) && isnan(d.m2_um[k][idx]) && isnan(d.m3_urad[k][idx]));
    assert_true(idx == 0 || isfinite(d.m1_um[k][idx - 1]));
    assert_true(sc_profile_has_gaps(&d));
    sc_profile_data_free(&d);
}

static void expect_bad(const text *t, long line, const char *what, int method)
{
    sc_profile_data d;
    sc_error err;
    sc_error_clear(&err);
    sc_status st = sc_profile_read(text_write(t), &d, &err);
    if (st == SC_OK && method >= 0) {
        st = sc_profile_check_method(&d, (sc_profile_method)method, &err);
        sc_profile_data_free(&d);
    } else if (st == SC_OK) {
        sc_profile_data_free(&d);
    }
    char msg[1024];
    sc_error_format(&err, msg, sizeof msg);
    print_message("  %s -> %s\n", what, msg);
    int threads;
    read_both_ways(text_write(t), &threads); /* the same message from the two-thread reader */
    assert_int_equal(st, SC_E_INPUT);
    assert_int_equal(err.line, line);
    assert_non_null(strstr(err.file, "profile_reader.csv"));
    assert_non_null(strstr(err.msg, what));
}

static void test_reader_good_and_bad(void **state)
{
    (void)state;
    const int n = 30, d1 = 3, d2 = 5; /* 30 = 2·3·5: both methods */
    const int s1 = 7, s2 = 7 + (n - d1); /* first data lines of scans 1 and 2 */
    text t;
    sc_profile_data d;
    sc_error err;
    text_good(&t, n, d1, d2);
    assert_int_equal(sc_profile_read(text_write(&t), &d, &err), SC_OK);
    assert_int_equal(d.n, n);
    assert_int_equal(d.d[0], d1);
    assert_int_equal(d.d[1], d2);
    assert_int_equal(d.has_sigma_disp, 0);
    assert_true(d.m2_um[1][4] == 0.02 * 4 + 2);
    assert_int_equal(sc_profile_check_method(&d, SC_PROFILE_DFT, &err), SC_OK);
    assert_int_equal(sc_profile_check_method(&d, SC_PROFILE_LSQ, &err), SC_OK);
    sc_profile_data_free(&d);

    /* a scan missing: its header line, or all its rows */
    text_delete(&t, 5);
    expect_bad(&t, 5, "scan 2 missing", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    while (t.nlines >= s2)
        text_delete(&t, t.nlines);
    expect_bad(&t, 5, "scan 2 missing", -1);
    text_free(&t);
    /* not coprime: for both methods, at the scan line */
    text_good(&t, n, 6, 10);
    expect_bad(&t, 5, "common divisor", SC_PROFILE_LSQ);
    expect_bad(&t, 5, "not coprime", SC_PROFILE_DFT);
    text_free(&t);
    /* N not a multiple of d1·d2: DFT only */
    text_good(&t, 31, d1, d2);
    expect_bad(&t, 2, "not a multiple", SC_PROFILE_DFT);
    text_free(&t);
    /* N too small: for least squares (N < d1 + d2) and with no sample at all */
    text_good(&t, 7, d1, d2);
    expect_bad(&t, 2, "too small", SC_PROFILE_LSQ);
    text_free(&t);
    text_good(&t, 8, 3, 5);
    text_set(&t, 2, "# N = 5");
    expect_bad(&t, 2, "N too small", -1);
    text_free(&t);
    /* a gap in n: read as NaN (SPEC §2a; the DFT refuses it, test_profile_rig) */
    text_good(&t, n, d1, d2);
    text_delete(&t, s1 + 4);
    expect_gap(&t, 0, 4);
    text_free(&t);
    /* a gap at the end of scan 2 */
    text_good(&t, n, d1, d2);
    text_delete(&t, t.nlines);
    expect_gap(&t, 1, n - d2 - 1);
    text_free(&t);
    /* more than half of a scan missing: refused at the row after its largest gap */
    text_good(&t, n, d1, d2);
    for (int i = 0; i < (n - d1) / 2 + 1; ++i)
        text_delete(&t, s1 + 2);
    expect_bad(&t, s1 + 2, "gap in scan 1: no sample for n = 2..", -1);
    text_free(&t);
    /* a duplicate */
    text_good(&t, n, d1, d2);
    text_set(&t, s1 + 6, "1,5,0,0,0");
    expect_bad(&t, s1 + 6, "duplicate", -1);
    text_free(&t);
    /* n out of range */
    text_good(&t, n, d1, d2);
    text_set(&t, s2 + 2, "2,25,0,0,0");
    expect_bad(&t, s2 + 2, "out of range", -1);
    text_free(&t);
    /* non-numeric fields */
    text_good(&t, n, d1, d2);
    text_set(&t, s1 + 3, "1,3,0.1,abc,0");
    expect_bad(&t, s1 + 3, "m2_um", -1);
    text_set(&t, s1 + 3, "1,3.5,0.1,0.2,0");
    expect_bad(&t, s1 + 3, "n", -1);
    text_set(&t, s1 + 3, "1,3,0.1,0.2,nan");
    expect_bad(&t, s1 + 3, "m3_urad", -1);
    text_free(&t);
    /* header problems */
    text_good(&t, n, d1, d2);
    text_set(&t, 1, "# selfcal-grid v1");
    expect_bad(&t, 1, "selfcal-profile v1", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    text_set(&t, 3, "# s_mm = fast");
    expect_bad(&t, 3, "s_mm", -1);
    text_set(&t, 3, "# s_mm = 1");
    text_set(&t, 6, "scan,n,m1,m2,m3");
    expect_bad(&t, 6, "column header", -1);
    text_free(&t);
    /* impossible magnitudes, caught where read (fuzzing found inf results from them) */
    text_good(&t, n, d1, d2);
    text_set(&t, s1 + 2, "1,2,1e300,0.2,0");
    expect_bad(&t, s1 + 2, "not a sensor reading", -1);
    text_set(&t, s1 + 2, "1,2,0.1,0.2,-3e6");
    expect_bad(&t, s1 + 2, "not a sensor reading", -1);
    text_set(&t, s1 + 2, "1,2,0.1,0.2,0");
    text_set(&t, 3, "# s_mm = 1e9");
    expect_bad(&t, 3, "beyond any real set-up", -1);
    text_free(&t);
}

/* The fast pass on two threads (profile_file.c): what it reads is what one thread reads, on files
 * that split anywhere; whatever is wrong sends it to the exact pass and its messages. */
/* The header hook: called once with the header's fields and no arrays, before the rows; the data
 * and the errors as sc_profile_read's; never for a wrong header; once when the fast pass fails
 * and the exact pass reads the file again. */
typedef struct hook_seen {
    int calls;
    sc_profile_data hdr;
} hook_seen;

static void record_header(void *ctx, const sc_profile_data *hdr)
{
    hook_seen *h = ctx;
    h->calls++;
    h->hdr = *hdr;
}

static void test_read_hooked(void **state)
{
    (void)state;
    text t;
    text_good(&t, 300, 10, 11);
    text_set(&t, 3, "# s_mm = 0.25");
    memmove(&t.line[4], &t.line[3], (size_t)(t.nlines - 3) * sizeof(char *));
    t.nlines++;
    t.line[3] = strdup("# sigma_disp_um = 0.03"); /* line 4: the rows start at line 8 */
    sc_profile_data a, b;
    sc_error ea, eb;
    hook_seen h = {0};
    assert_int_equal(sc_profile_read_hooked(text_write(&t), record_header, &h, &a, &ea), SC_OK);
    assert_int_equal(sc_profile_read(text_write(&t), &b, &eb), SC_OK);
    assert_int_equal(h.calls, 1);
    assert_same_data(&a, &b);
    assert_int_equal(h.hdr.n, 300);
    assert_int_equal(h.hdr.d[0], 10);
    assert_int_equal(h.hdr.d[1], 11);
    assert_true(h.hdr.s_mm == 0.25);
    assert_true(h.hdr.has_sigma_disp && h.hdr.sigma_disp_um == 0.03 && !h.hdr.has_sigma_angle);
    assert_int_equal(h.hdr.line_n, a.line_n);
    assert_string_equal(h.hdr.path, a.path);
    for (int k = 0; k < 2; ++k)
        assert_true(!h.hdr.m1_um[k] && !h.hdr.m2_um[k] && !h.hdr.m3_urad[k]);
    sc_profile_data_free(&a);
    sc_profile_data_free(&b);
    /* a bad row: the same error, the hook heard once over both passes */
    text_set(&t, 200, "1,190,0.5,x,0.5");
    h.calls = 0;
    sc_error_clear(&ea);
    sc_error_clear(&eb);
    assert_int_equal(sc_profile_read_hooked(text_write(&t), record_header, &h, &a, &ea),
                     SC_E_INPUT);
    assert_int_equal(sc_profile_read(text_write(&t), &b, &eb), SC_E_INPUT);
    assert_int_equal(h.calls, 1);
    assert_int_equal(ea.line, 200);
    assert_int_equal(ea.line, eb.line);
    assert_string_equal(ea.msg, eb.msg);
    /* a wrong header: never heard */
    text_set(&t, 2, "# N = 3.5");
    h.calls = 0;
    assert_int_equal(sc_profile_read_hooked(text_write(&t), record_header, &h, &a, &ea),
                     SC_E_INPUT);
    assert_int_equal(h.calls, 0);
    /* NULL hook: a plain read */
    text_free(&t);
    text_good(&t, 300, 10, 11);
    assert_int_equal(sc_profile_read_hooked(text_write(&t), NULL, NULL, &a, &ea), SC_OK);
    sc_profile_data_free(&a);
    text_free(&t);
}

/* sc_profile_read_and_plan, as `selfcal profile` uses it: the plan made on a thread started by
 * the header hook while two threads read the rows (a file above the two-thread threshold), then
 * run: the values of sc_profile_calibrate on the data read plainly; the reading's error before
 * the plan's, and nothing left to free after either (TSan and ASan run this test). */
static void test_plan_while_reading(void **state)
{
    (void)state;
    const int n = 66000; /* about 4.4 MB of rows */
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    double *f = malloc(n * sizeof(double)), *ey = malloc(n * sizeof(double));
    random_profile(n, 12, f);
    sc_profile_data d, r;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &d, ey, &err), SC_OK);
    const char *path = TMP "/profile_plan_while_reading.csv";
    assert_int_equal(sc_profile_write(path, &d, &err), SC_OK);
    sc_profile_data_free(&d);
    assert_int_equal(sc_profile_read(path, &d, &err), SC_OK);
    for (int m = 0; m < 2; ++m) {
        sc_profile_options o;
        sc_profile_options_default(&o);
        o.method = m ? SC_PROFILE_DFT : SC_PROFILE_LSQ;
        sc_profile_calibration *c;
        assert_int_equal(sc_profile_read_and_plan(path, &o, &r, &c, &err), SC_OK);
        assert_same_data(&d, &r);
        double *a = malloc(3 * (size_t)n * sizeof(double)), *b = malloc(3 * (size_t)n * sizeof(double));
        sc_profile_solution sa = {.f_um = a, .uf_um = a + n, .ey_um = a + 2 * n};
        sc_profile_solution sb = {.f_um = b, .uf_um = b + n, .ey_um = b + 2 * n};
        assert_int_equal(sc_profile_calibrate(&d, &o, &sa, &err), SC_OK);
        assert_int_equal(sc_profile_calibration_run(c, &r, &sb, &err), SC_OK);
        assert_memory_equal(a, b, 3 * (size_t)n * sizeof(double));
        sc_profile_calibration_destroy(c);
        sc_profile_data_free(&r);
        free(a), free(b);
    }
    /* errors: a bad row (the reading's), a plan the method cannot make (the plan's) */
    text t;
    text_good(&t, 1101, 10, 11); /* not a multiple of d1·d2 for the DFT */
    sc_profile_options o;
    sc_profile_options_default(&o);
    o.method = SC_PROFILE_DFT;
    sc_profile_calibration *c = (sc_profile_calibration *)&o;
    sc_error e2;
    assert_int_equal(sc_profile_read_and_plan(text_write(&t), &o, &r, &c, &err), SC_E_INPUT);
    assert_null(c);
    assert_null(r.m1_um[0]);
    assert_int_equal(sc_profile_read(text_write(&t), &r, &e2), SC_OK);
    assert_int_equal(sc_profile_check_method(&r, SC_PROFILE_DFT, &e2), SC_E_INPUT);
    assert_string_equal(err.msg, e2.msg);
    assert_int_equal(err.line, e2.line);
    sc_profile_data_free(&r);
    text_set(&t, 300, "1,292,0.5,0.5"); /* a field short, and still the DFT refusal to come */
    assert_int_equal(sc_profile_read_and_plan(text_write(&t), &o, &r, &c, &err), SC_E_INPUT);
    assert_null(c);
    assert_int_equal(err.line, 300);
    assert_non_null(strstr(err.msg, "expected 5 fields"));
    text_free(&t);
    sc_profile_data_free(&d);
    remove(path);
    free(f), free(ey);
}

static void test_reader_two_threads(void **state)
{
    (void)state;
    const int n = 300, d1 = 7, d2 = 11;
    const int rows = 2 * n - d1 - d2, s1 = 7; /* first data line */
    text t;
    int threads;
    /* a plain file, and the same ended by CR LF, and without the last line end */
    text_good(&t, n, d1, d2);
    assert_int_equal(read_both_ways(text_write(&t), &threads), SC_OK);
    if (two_cpus())
        assert_int_equal(threads, 2);
    assert_int_equal(read_both_ways(text_write_ends(&t, "\r\n", 1), &threads), SC_OK);
    assert_int_equal(read_both_ways(text_write_ends(&t, "\n", 0), &threads), SC_OK);
    /* comments, blank lines and rows with blanks (the general path) all through the file */
    for (int i = s1 + 5; i < t.nlines; i += 37) {
        char buf[128];
        snprintf(buf, sizeof buf, " %s ", t.line[i - 1]);
        for (char *c = strchr(buf, ','); c; c = strchr(c + 2, ','))
            memmove(c + 1, c, strlen(c) + 1), c[0] = ' ', c++; /* "a ,b" */
        text_set(&t, i, buf);
    }
    char *extra[] = {"# a remark", "", "   ", "#"};
    for (int i = 0; i < 4; ++i) { /* insert at four places */
        int at = s1 + (i + 1) * rows / 5;
        memmove(&t.line[at], &t.line[at - 1], (size_t)(t.nlines - at + 1) * sizeof(char *));
        t.line[at - 1] = strdup(extra[i]);
        t.nlines++;
    }
    assert_int_equal(read_both_ways(text_write(&t), &threads), SC_OK);
    if (two_cpus())
        assert_int_equal(threads, 2);
    text_free(&t);
    /* the scans' rows interleaved, then in reverse order */
    text_good(&t, n, d1, d2);
    for (int i = 0; i < (n - d2) / 2; ++i) { /* swap scan 1's odd rows with scan 2's even rows */
        char *a = t.line[s1 - 1 + 2 * i + 1];
        t.line[s1 - 1 + 2 * i + 1] = t.line[s1 - 1 + (n - d1) + 2 * i];
        t.line[s1 - 1 + (n - d1) + 2 * i] = a;
    }
    assert_int_equal(read_both_ways(text_write(&t), &threads), SC_OK);
    for (int i = 0; i < rows / 2; ++i) {
        char *a = t.line[s1 - 1 + i];
        t.line[s1 - 1 + i] = t.line[t.nlines - 1 - i];
        t.line[t.nlines - 1 - i] = a;
    }
    assert_int_equal(read_both_ways(text_write(&t), &threads), SC_OK);
    text_free(&t);
    /* wrong files, where the fault lies in either half or across them: the exact messages */
    text_good(&t, n, d1, d2);
    t.line[t.nlines++] = strdup("1,0,0,0,0"); /* a duplicate of the first row, at the end */
    expect_bad(&t, t.nlines, "duplicate sample: scan 1, n = 0 (first at line 7)", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    text_delete(&t, s1 + 5); /* a gap and a duplicate: as many rows as samples */
    t.line[t.nlines++] = strdup("1,0,0,0,0");
    expect_bad(&t, t.nlines, "duplicate sample: scan 1, n = 0 (first at line 7)", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    text_set(&t, s1 + 3, t.line[t.nlines - 2]); /* the second last row, early */
    expect_bad(&t, t.nlines - 1, "duplicate sample", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    int gap = t.nlines - 40;
    text_delete(&t, gap); /* a gap in the second half: read as NaN */
    expect_gap(&t, 1, -1);
    text_set(&t, t.nlines - 5, "2,7,0,0,x"); /* and a bad field after it: the field */
    expect_bad(&t, t.nlines - 5, "m3_urad", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    text_set(&t, s1 + 4, "1,4,0,0"); /* a short row in the first half */
    text_set(&t, t.nlines - 3, "2,4,0,0,0,"); /* and a long one in the second */
    expect_bad(&t, s1 + 4, "expected 5 fields", -1);
    text_free(&t);
    text_good(&t, n, d1, d2);
    text_delete(&t, t.nlines); /* the last row missing: a gap */
    expect_gap(&t, 1, n - d2 - 1);
    text_free(&t);
}

static void test_write_read_roundtrip(void **state)
{
    (void)state;
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = 110;
    double f[110], ey[110];
    random_profile(110, 5, f);
    sc_profile_data a, b;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &a, ey, &err), SC_OK);
    assert_int_equal(sc_profile_write(TMP "/profile_rt.csv", &a, &err), SC_OK);
    assert_int_equal(sc_profile_read(TMP "/profile_rt.csv", &b, &err), SC_OK);
    assert_int_equal(b.has_sigma_disp, 1);
    assert_true(b.sigma_disp_um == p.sigma_disp_um && b.sigma_angle_urad == p.sigma_angle_urad);
    for (int k = 0; k < 2; ++k)
        for (int i = 0; i < p.n - a.d[k]; ++i) {
            assert_true(a.m1_um[k][i] == b.m1_um[k][i]);
            assert_true(a.m2_um[k][i] == b.m2_um[k][i]);
            assert_true(a.m3_urad[k][i] == b.m3_urad[k][i]);
        }
    /* the result file round trip, with the empty e_y tail */
    double uf[110];
    for (int i = 0; i < 110; ++i)
        uf[i] = 0.001 * i;
    assert_int_equal(sc_profile_write_result(TMP "/profile_res.csv", 110, 1.0, f, uf, ey, 100, &err), SC_OK);
    sc_profile_result r;
    assert_int_equal(sc_profile_read_result(TMP "/profile_res.csv", &r, &err), SC_OK);
    assert_int_equal(r.n, 110);
    for (int i = 0; i < 110; ++i) {
        assert_true(r.f_um[i] == f[i] && r.uf_um[i] == uf[i] && r.x_mm[i] == i);
        assert_true(i < 100 ? r.ey_um[i] == ey[i] : isnan(r.ey_um[i]));
    }
    sc_profile_result_free(&r);
    sc_profile_data_free(&a);
    sc_profile_data_free(&b);
}

/* Files above the writers' two-thread threshold (SC_IO_PARALLEL_ROWS rows) read back exactly. */
static void test_write_read_large(void **state)
{
    (void)state;
    const int n = 20000; /* 2n - d1 - d2 data rows, n result rows: both written by two threads */
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n;
    double *f = malloc(sizeof(double) * n), *ey = malloc(sizeof(double) * n);
    double *uf = malloc(sizeof(double) * n);
    assert_non_null(f), assert_non_null(ey), assert_non_null(uf);
    random_profile(n, 9, f);
    sc_profile_data a, b;
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, f, &a, ey, &err), SC_OK);
    assert_int_equal(sc_profile_write(TMP "/profile_large.csv", &a, &err), SC_OK);
    assert_int_equal(sc_profile_read(TMP "/profile_large.csv", &b, &err), SC_OK);
    assert_same_data(&a, &b);
    for (int i = 0; i < n; ++i)
        uf[i] = 1e-3 * i;
    assert_int_equal(sc_profile_write_result(TMP "/profile_large_res.csv", n, 0.25, f, uf, ey,
                                             n - 30, &err), SC_OK);
    sc_profile_result r;
    assert_int_equal(sc_profile_read_result(TMP "/profile_large_res.csv", &r, &err), SC_OK);
    assert_int_equal(r.n, n);
    for (int i = 0; i < n; ++i) {
        assert_true(r.f_um[i] == f[i] && r.uf_um[i] == uf[i] && r.x_mm[i] == 0.25 * i);
        assert_true(i < n - 30 ? r.ey_um[i] == ey[i] : isnan(r.ey_um[i]));
    }
    sc_profile_result_free(&r);
    sc_profile_data_free(&a);
    sc_profile_data_free(&b);
    free(f), free(ey), free(uf);
}

static void test_dft_refuses(void **state)
{
    (void)state;
    sc_error err;
    sc_profile_dft_plan *p = NULL;
    assert_true(sc_profile_dft_is_usable(330, 10, 11, &err));
    assert_false(sc_profile_dft_is_usable(331, 10, 11, &err));
    assert_non_null(strstr(err.msg, "multiple"));
    assert_false(sc_profile_dft_is_usable(360, 10, 12, &err));
    assert_non_null(strstr(err.msg, "coprime"));
    assert_int_equal(sc_profile_dft_plan_create(330, 10, 12, 1, 1, &p, &err), SC_E_INPUT);
    assert_null(p);
    assert_int_equal(sc_profile_dft_plan_create(330, 10, 11, 0, 1, &p, &err), SC_E_INPUT);
    /* the message names the nearest N the method takes (a multiple of d1·d2, at least one) */
    const int ns[][2] = {{331, 330}, {1101, 1100}, {1160, 1210}, {1154, 1100}, {1155, 1210}, {50, 110}};
    for (size_t k = 0; k < sizeof ns / sizeof ns[0]; ++k) {
        char want[32];
        snprintf(want, sizeof want, "nearest: %d;", ns[k][1]);
        assert_false(sc_profile_dft_is_usable(ns[k][0], 10, 11, &err));
        if (!strstr(err.msg, want))
            fail_msg("N = %d: '%s' does not say '%s'", ns[k][0], err.msg, want);
    }
    /* refusals of arguments, not of a file: no file, no line */
    assert_false(sc_profile_dft_is_usable(360, 10, 12, &err));
    assert_true(err.file[0] == '\0' && err.line == 0);
    assert_false(sc_profile_dft_is_usable(331, 10, 11, &err));
    assert_true(err.file[0] == '\0' && err.line == 0);
    assert_false(sc_profile_dft_is_usable(330, 11, 11, &err));
    assert_true(err.file[0] == '\0' && err.line == 0 && strstr(err.msg, "d1 = d2 = 11"));
    /* a value that is not a number is named, scan and index */
    assert_int_equal(sc_profile_dft_plan_create(330, 10, 11, 1, 1, &p, &err), SC_OK);
    double y1[330] = {0}, y2[330] = {0}, f[330];
    y2[7] = NAN;
    assert_int_equal(sc_profile_dft_execute(p, y1, y2, f, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "y2(7) is not a finite number"));
    y2[7] = 0, y1[4] = INFINITY;
    assert_int_equal(sc_profile_dft_execute(p, y1, y2, f, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "y1(4) is not a finite number"));
    sc_profile_dft_plan_destroy(p);
    /* the uncertainty's missing arguments */
    assert_int_equal(sc_profile_dft_plan_create(330, 10, 11, 1, 1, &p, &err), SC_OK);
    assert_int_equal(sc_profile_dft_uncertainty(p, NULL, NULL, &err), SC_E_INPUT);
    double u[330];
    assert_int_equal(sc_profile_dft_uncertainty(NULL, u, NULL, &err), SC_E_INPUT);
    sc_profile_dft_plan_destroy(p);
}

/* A "solver" whose every output is 1000 µm plus y1(0): the Monte Carlo uncertainty of every
 * point is then σ_y1, whatever the large mean (Welford's running mean must follow it). */
static sc_status offset_solver(void *ctx, const double *y1_um, const double *y2_um, double *f_um,
                               sc_error *err)
{
    (void)y2_um, (void)err;
    int n = *(const int *)ctx;
    for (int i = 0; i < n; ++i)
        f_um[i] = 1000.0 + y1_um[0];
    return SC_OK;
}

static void test_mc_large_mean(void **state)
{
    (void)state;
    int n = 40;
    double u[40];
    sc_error err;
    assert_int_equal(sc_profile_mc_uncertainty(n, 3, 5, 0.25, 0.5, offset_solver, &n, 2000, 7, NULL,
                                               NULL, u, &err), SC_OK);
    for (int i = 0; i < n; ++i) {
        if (!(fabs(u[i] / 0.25 - 1) < 0.08))
            fail_msg("u[%d] = %g, expected 0.25 (2000 trials)", i, u[i]);
        assert_true(u[i] == u[0]);
    }
}

/* FFTW's planner is not thread-safe: plans made and destroyed in several threads at once (DFT
 * profile plans and exact grid plans, as two calibrations on separate data would) must neither
 * crash nor give wrong results; the library serializes its planner calls (fft_planner.c). Before
 * that, four threads aborted with "double free or corruption" in most runs. */
static void *plans_in_a_thread(void *arg)
{
    int *bad = arg;
    const int n = 330;
    double y1[330], y2[330], f[330];
    for (int i = 0; i < n; ++i)
        y1[i] = y2[i] = 0.0;
    for (int k = 0; k < 150 && !*bad; ++k) {
        sc_error err;
        sc_profile_dft_plan *p = NULL;
        sc_grid_exact_plan *g = NULL;
        if (sc_profile_dft_plan_create(n, 10, 11, 1.0, 2.0, &p, &err) != SC_OK ||
            sc_profile_dft_execute(p, y1, y2, f, &err) != SC_OK ||
            sc_grid_exact_plan_create(SC_GRID_YE, 9, &g, &err) != SC_OK)
            *bad = 1;
        for (int i = 0; i < n && !*bad; ++i)
            if (f[i] != 0.0)
                *bad = 1;
        sc_grid_exact_plan_destroy(g);
        sc_profile_dft_plan_destroy(p);
    }
    return NULL;
}

static void test_dft_plans_in_threads(void **state)
{
    (void)state;
    pthread_t t[4];
    int bad[4] = {0, 0, 0, 0};
    for (int k = 0; k < 4; ++k)
        assert_int_equal(pthread_create(&t[k], NULL, plans_in_a_thread, &bad[k]), 0);
    for (int k = 0; k < 4; ++k) {
        pthread_join(t[k], NULL);
        assert_int_equal(bad[k], 0);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_noise_free_both_methods),
        cmocka_unit_test(test_lsq_noise_free_any_n),
        cmocka_unit_test(test_dabam_profiles),
        cmocka_unit_test(test_dabam_slope_integration),
        cmocka_unit_test(test_dabam_refusals),
        cmocka_unit_test(test_dft_uncertainty_exact),
        cmocka_unit_test(test_paper_setup_mc),
        cmocka_unit_test(test_residual_noise_estimate),
        cmocka_unit_test(test_zero_point_offsets),
        cmocka_unit_test(test_noise_sources),
        cmocka_unit_test(test_calibration_plan_and_run),
        cmocka_unit_test(test_read_hooked),
        cmocka_unit_test(test_plan_while_reading),
        cmocka_unit_test(test_reader_good_and_bad),
        cmocka_unit_test(test_reader_two_threads),
        cmocka_unit_test(test_write_read_roundtrip),
        cmocka_unit_test(test_write_read_large),
        cmocka_unit_test(test_dft_refuses),
        cmocka_unit_test(test_mc_large_mean),
        cmocka_unit_test(test_dft_plans_in_threads),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
