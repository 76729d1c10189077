/* Unit tests of the fast profile least squares (selfcal/profile_lsq.h): solvability against the
 * rank of the dense system, noise-free reconstruction (simulated and DABAM profiles), agreement
 * with the dense LAPACK reference, uncertainties against Monte Carlo and against a long-double
 * computation in another gauge at N = 10⁶, the paper's set-up. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "profile_lsq_dense.h"
#include "selfcal/profile_lsq.h"
#include "../../libselfcal/src/profile/profile_lsq_tuning.h" /* the internal tuning flags */
#include "selfcal/rng.h"

/* ---------- helpers ---------- */

static double *dalloc(size_t n)
{
    double *p = calloc(n ? n : 1, sizeof(double));
    assert_non_null(p);
    return p;
}

/* Remove the least-squares line of v over its index (plain formulas, long double sums). */
static void remove_line(int n, double *v)
{
    long double s0 = 0, s1 = 0, nc = 0.5L * (n - 1), sxx = 0;
    for (int i = 0; i < n; i++) {
        s0 += v[i];
        s1 += (i - nc) * v[i];
        sxx += (i - nc) * (i - nc);
    }
    long double mean = s0 / n, slope = s1 / sxx;
    for (int i = 0; i < n; i++) v[i] = (double)(v[i] - mean - slope * (i - nc));
}

static double ls_slope(int n, const double *v)
{
    long double s1 = 0, nc = 0.5L * (n - 1), sxx = 0;
    for (int i = 0; i < n; i++) {
        s1 += (i - nc) * v[i];
        sxx += (i - nc) * (i - nc);
    }
    return (double)(s1 / sxx);
}

/* y_k(j) = f(j + d_k) - f(j) + c_k (+ noise of standard deviation sigma_k if rng) */
static void simulate(int n, int d1, int d2, const double *f, double c1, double c2, double *y1,
                     double *y2, sc_rng *rng, double sigma1, double sigma2)
{
    for (int j = 0; j + d1 < n; j++)
        y1[j] = f[j + d1] - f[j] + c1 + (rng ? sigma1 * sc_rng_normal(rng) : 0.0);
    for (int j = 0; j + d2 < n; j++)
        y2[j] = f[j + d2] - f[j] + c2 + (rng ? sigma2 * sc_rng_normal(rng) : 0.0);
}

/* A random profile: smooth waves + white roughness + a line (µm). */
static void random_profile(int n, sc_rng *rng, double *f)
{
    double a[4], ph[4];
    for (int q = 0; q < 4; q++) {
        a[q] = sc_rng_normal(rng);
        ph[q] = 6.283185307179586 * sc_rng_uniform(rng);
    }
    double tilt = 0.3 * sc_rng_normal(rng), off = sc_rng_normal(rng);
    for (int i = 0; i < n; i++) {
        double x = (double)i / n;
        f[i] = off + tilt * i * 1e-2 + 0.05 * sc_rng_normal(rng);
        for (int q = 0; q < 4; q++) f[i] += a[q] * sin(6.283185307179586 * (q + 1) * x + ph[q]);
    }
}

/* Reconstruct noise-free data of profile f and return max |f_hat - f| after the LS line. */
static double noise_free_error(int n, int d1, int d2, const double *f_in, double c1, double c2)
{
    double *f = dalloc((size_t)n), *y1 = dalloc((size_t)n), *y2 = dalloc((size_t)n);
    double *fh = dalloc((size_t)n);
    memcpy(f, f_in, (size_t)n * sizeof(double));
    simulate(n, d1, d2, f, c1, c2, y1, y2, NULL, 0, 0);
    double slope = ls_slope(n, f);
    remove_line(n, f);
    sc_profile_lsq_plan *p = NULL;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1.0, 2.0, &p, &err), SC_OK);
    double c[2], wrss;
    assert_int_equal(sc_profile_lsq_execute(p, y1, y2, fh, c, &wrss, &err), SC_OK);
    double e = 0.0;
    for (int i = 0; i < n; i++) e = fmax(e, fabs(fh[i] - f[i]));
    /* the offsets in the LS-line gauge: c_k + slope·d_k */
    e = fmax(e, fabs(c[0] - (c1 + slope * d1)));
    e = fmax(e, fabs(c[1] - (c2 + slope * d2)));
    assert_true(wrss < 1e-15 * n);
    sc_profile_lsq_plan_destroy(p);
    free(f);
    free(y1);
    free(y2);
    free(fh);
    return e;
}

/* ---------- solvability ---------- */

static void test_solvable_matches_dense_rank(void **state)
{
    (void)state;
    int checked = 0, solvable = 0;
    for (int n = 2; n <= 40; n++)
        for (int d1 = 1; d1 <= n; d1++)
            for (int d2 = 1; d2 <= n; d2++) {
                sc_error err;
                sc_error_clear(&err);
                int s = sc_profile_lsq_is_solvable(n, d1, d2, &err);
                int rank = sc_profile_lsq_dense_rank(n, d1, d2);
                assert_true(rank >= 0);
                if (s != (rank == n)) {
                    print_error("N=%d d1=%d d2=%d: solvable=%d but rank %d\n", n, d1, d2, s,
                                rank);
                    fail();
                }
                if (!s) {
                    assert_int_equal(err.code, SC_E_INPUT);
                    assert_true(strlen(err.msg) > 10);
                }
                checked++;
                solvable += s;
            }
    print_message("solvability: %d cases (2 <= N <= 40, 1 <= d1, d2 <= N), %d solvable, all equal "
                  "to (SVD rank == N)\n", checked, solvable);
    assert_true(checked > 10000 && solvable > 1000);
}

static void test_refuses_bad_input(void **state)
{
    (void)state;
    sc_profile_lsq_plan *p = (sc_profile_lsq_plan *)&p;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_profile_lsq_plan_create(330, 10, 12, 1, 1, &p, &err), SC_E_INPUT);
    assert_null(p);
    assert_non_null(strstr(err.msg, "common divisor"));
    assert_int_equal(sc_profile_lsq_plan_create(20, 10, 11, 1, 1, &p, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "too small"));
    assert_int_equal(sc_profile_lsq_plan_create(330, 0, 11, 1, 1, &p, &err), SC_E_INPUT);
    assert_int_equal(sc_profile_lsq_plan_create(330, 10, 11, 0, 1, &p, &err), SC_E_INPUT);
    assert_int_equal(sc_profile_lsq_plan_create(330, 10, 11, 1, NAN, &p, &err), SC_E_INPUT);
    assert_int_equal(sc_profile_lsq_plan_create(330, 10, 11, 1, -1, &p, &err), SC_E_INPUT);
    /* exactly N = d1 + d2 is solvable (no redundancy): see docs/profile-lsq.md */
    assert_int_equal(sc_profile_lsq_plan_create(21, 10, 11, 1, 1, &p, &err), SC_OK);
    double y1[11] = {0}, y2[10] = {0}, f[21];
    y1[3] = NAN;
    assert_int_equal(sc_profile_lsq_execute(p, y1, y2, f, NULL, NULL, &err), SC_E_INPUT);
    /* named by scan and index; the library's arrays have no file or line */
    assert_non_null(strstr(err.msg, "y1(3) is not a finite number"));
    assert_int_equal(err.line, 0);
    assert_string_equal(err.file, "");
    sc_profile_lsq_plan_destroy(p);
    sc_profile_lsq_plan_destroy(NULL);
    /* N up to INT32_MAX / 2 - 8 keeps the indices (up to 2N + a few) in int; one more is refused */
    sc_error_clear(&err);
    assert_true(sc_profile_lsq_is_solvable(INT32_MAX / 2 - 8, 1, 2, &err));
    assert_false(sc_profile_lsq_is_solvable(INT32_MAX / 2 - 7, 1, 2, &err));
    assert_non_null(strstr(err.msg, "too large"));
}

/* Only the ratio of the weights matters: both scaled by 1e-100 or 1e100 (σ of 1e50 or 1e-50 µm)
 * give the same f and c, and u(f) scales by 1/sqrt of the factor (the zero-point offsets'
 * 2 x 2 system is judged relative to its own size, not to 1). */
static void test_weight_scale_invariance(void **state)
{
    (void)state;
    const int n = 330, d1 = 10, d2 = 11;
    sc_rng rng;
    sc_rng_seed(&rng, 4343);
    double *f = dalloc(n), *y1 = dalloc(n), *y2 = dalloc(n), *f0 = dalloc(n), *fs = dalloc(n);
    double *u0 = dalloc(n), *us = dalloc(n);
    random_profile(n, &rng, f);
    simulate(n, d1, d2, f, 0.1, -0.2, y1, y2, &rng, 0.01, 0.012);
    const double scale[3] = {1.0, 1e-100, 1e100};
    double c0[2], cs[2];
    for (int k = 0; k < 3; k++) {
        sc_profile_lsq_plan *p = NULL;
        sc_error err;
        sc_error_clear(&err);
        assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1e4 * scale[k], 7e3 * scale[k], &p, &err),
                         SC_OK);
        assert_int_equal(sc_profile_lsq_execute(p, y1, y2, k ? fs : f0, k ? cs : c0, NULL, &err), SC_OK);
        assert_int_equal(sc_profile_lsq_uncertainty(p, k ? us : u0, NULL, &err), SC_OK);
        sc_profile_lsq_plan_destroy(p);
        if (k == 0)
            continue;
        for (int i = 0; i < n; i++) {
            assert_true(fabs(fs[i] - f0[i]) <= 1e-9 * (1 + fabs(f0[i])));
            assert_true(fabs(us[i] * sqrt(scale[k]) - u0[i]) <= 1e-9 * u0[i] + 1e-300);
        }
        for (int j = 0; j < 2; j++)
            assert_true(fabs(cs[j] - c0[j]) <= 1e-9 * (1 + fabs(c0[j])));
    }
    free(f), free(y1), free(y2), free(f0), free(fs), free(u0), free(us);
}

/* ---------- noise-free reconstruction ---------- */

static void test_noise_free_simulated(void **state)
{
    (void)state;
    static const int cases[][3] = {
        {330, 10, 11}, {330, 3, 11}, {110, 10, 11}, {2310, 10, 11}, /* the acceptance set */
        {331, 10, 11}, {500, 10, 11}, {257, 7, 5},  {1000, 3, 8},   /* N not a multiple */
        {21, 10, 11},  {22, 11, 10},  {40, 1, 2},   {60, 2, 1},     /* N = d1 + d2, d = 1 */
        {5, 1, 1},     {777, 97, 101}, {1200, 13, 4}, {4000, 97, 101}};
    sc_rng rng;
    sc_rng_seed(&rng, 20261121);
    for (size_t q = 0; q < sizeof cases / sizeof cases[0]; q++) {
        int n = cases[q][0], d1 = cases[q][1], d2 = cases[q][2];
        double *f = dalloc((size_t)n);
        random_profile(n, &rng, f);
        double e = noise_free_error(n, d1, d2, f, 0.7, -1.3);
        print_message("noise-free N=%d d=%d/%d: max error %.2g um\n", n, d1, d2, e);
        if (!(e <= 1e-9)) {
            print_error("N=%d d1=%d d2=%d: max error %.3g um\n", n, d1, d2, e);
            fail();
        }
        free(f);
    }
}

/* A DABAM profile as heights in µm (native sampling), relative to its LS line. */
static int read_dabam(const char *id, double **h_out)
{
    char path[512], buf[4096];
    snprintf(path, sizeof path, "%s/dabam/dabam-%s.txt", SELFCAL_TEST_DATA_DIR, id);
    FILE *fp = fopen(path, "r");
    assert_non_null(fp);
    size_t len = fread(buf, 1, sizeof buf - 1, fp);
    buf[len] = 0;
    fclose(fp);
    const char *keys[4] = {"\"FILE_HEADER_LINES\"", "\"X1_FACTOR\"", "\"Y1_FACTOR\"",
                           "\"FILE_FORMAT\""};
    double v[4];
    for (int k = 0; k < 4; k++) {
        char *s = strstr(buf, keys[k]);
        assert_non_null(s);
        s = strchr(s, ':');
        assert_non_null(s);
        v[k] = strtod(s + 1, NULL);
    }
    int header = (int)v[0], slopes = (int)v[3] == 1 || (int)v[3] == 3;
    assert_true((int)v[3] >= 1 && (int)v[3] <= 4);
    snprintf(path, sizeof path, "%s/dabam/dabam-%s.dat", SELFCAL_TEST_DATA_DIR, id);
    fp = fopen(path, "r");
    assert_non_null(fp);
    int cap = 4096, n = 0, line = 0;
    double *x = dalloc((size_t)cap), *y = dalloc((size_t)cap);
    while (fgets(buf, sizeof buf, fp)) {
        if (line++ < header) continue;
        char *end;
        double a = strtod(buf, &end);
        if (end == buf) continue; /* blank line */
        double b = strtod(end, NULL);
        assert_true(n < cap);
        x[n] = a * v[1];
        y[n] = b * v[2];
        n++;
    }
    fclose(fp);
    double *h = dalloc((size_t)n);
    if (slopes) {
        h[0] = 0.0; /* cumulative trapezoid: rad·m = m */
        for (int i = 1; i < n; i++) h[i] = h[i - 1] + 0.5 * (y[i] + y[i - 1]) * (x[i] - x[i - 1]);
    } else {
        memcpy(h, y, (size_t)n * sizeof(double));
    }
    for (int i = 0; i < n; i++) h[i] *= 1e6; /* m -> µm */
    remove_line(n, h);
    free(x);
    free(y);
    *h_out = h;
    return n;
}

static void test_noise_free_dabam(void **state)
{
    (void)state;
    const char *ids[] = {"001", "002", "010", "020", "030"};
    for (int q = 0; q < 5; q++) {
        double *h;
        int n = read_dabam(ids[q], &h);
        assert_true(n > 200);
        double rms = 0;
        for (int i = 0; i < n; i++) rms += h[i] * h[i];
        rms = sqrt(rms / n);
        assert_true(rms > 1e-4); /* a real, non-flat profile (µm) */
        double e1 = noise_free_error(n, 10, 11, h, 0.25, -0.4);
        double e2 = noise_free_error(n, 3, 11, h, 0.25, -0.4);
        double e3 = noise_free_error(n, 101, 97, h, 0.25, -0.4);
        print_message("dabam-%s N=%d (rms %.3g um): max error %.2g %.2g %.2g um (d 10/11, 3/11, "
                      "101/97)\n", ids[q], n, rms, e1, e2, e3);
        if (!(e1 <= 1e-9 && e2 <= 1e-9 && e3 <= 1e-9)) {
            print_error("dabam-%s (N=%d, rms %.3g um): errors %.3g %.3g %.3g um\n", ids[q], n,
                        rms, e1, e2, e3);
            fail();
        }
        free(h);
    }
}

/* ---------- fast vs dense ---------- */

static void compare_with_dense(int n, int d1, int d2, double w1, double w2, uint64_t seed)
{
    sc_rng rng;
    sc_rng_seed(&rng, seed);
    double *f = dalloc((size_t)n), *y1 = dalloc((size_t)n), *y2 = dalloc((size_t)n);
    double *ff = dalloc((size_t)n), *uf = dalloc((size_t)n), *fd = dalloc((size_t)n),
           *ud = dalloc((size_t)n);
    random_profile(n, &rng, f);
    simulate(n, d1, d2, f, 0.3, 0.1, y1, y2, &rng, 1 / sqrt(w1), 1 / sqrt(w2));
    sc_profile_lsq_plan *p = NULL;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, w1, w2, &p, &err), SC_OK);
    double cf[2], cd[2];
    assert_int_equal(sc_profile_lsq_execute(p, y1, y2, ff, cf, NULL, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_uncertainty(p, uf, NULL, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_dense_solve(n, d1, d2, w1, w2, y1, y2, fd, cd, ud), 0);
    double fmax_ = 0, df = 0, du = 0;
    for (int i = 0; i < n; i++) {
        fmax_ = fmax(fmax_, fabs(fd[i]));
        df = fmax(df, fabs(ff[i] - fd[i]));
        assert_true(ud[i] > 0);
        du = fmax(du, fabs(uf[i] - ud[i]) / ud[i]);
    }
    double dc = fmax(fabs(cf[0] - cd[0]), fabs(cf[1] - cd[1])) / fmax(fabs(cd[0]), fabs(cd[1]));
    print_message("fast vs dense N=%d d=%d/%d: rel diff f %.2g, uf %.2g, c %.2g\n", n, d1, d2,
                  df / fmax_, du, dc);
    if (!(df <= 1e-9 * fmax_ && du <= 1e-9 && dc <= 1e-9)) {
        print_error("N=%d d1=%d d2=%d: rel diff f %.3g, uf %.3g, c %.3g\n", n, d1, d2,
                    df / fmax_, du, dc);
        fail();
    }
    sc_profile_lsq_plan_destroy(p);
    free(f);
    free(y1);
    free(y2);
    free(ff);
    free(uf);
    free(fd);
    free(ud);
}

static void test_fast_matches_dense(void **state)
{
    (void)state;
    compare_with_dense(330, 10, 11, 1.0 / 3e-4, 1.0 / 3.21e-4, 1);
    compare_with_dense(330, 3, 11, 1.0, 1.0, 2);
    compare_with_dense(331, 11, 10, 2.0, 0.5, 3);
    compare_with_dense(110, 10, 11, 1.0, 1.0, 4);
    compare_with_dense(21, 10, 11, 1.0, 3.0, 5);
    compare_with_dense(60, 1, 2, 1.0, 1.0, 6);
    compare_with_dense(50, 1, 1, 1.0, 4.0, 7);
    compare_with_dense(700, 97, 101, 1.0, 1.0, 8);
    /* the edges of the blocked kernels: half-width 4 (smallest blocked), N close to d1 + d2 */
    compare_with_dense(50, 3, 4, 1.0, 2.0, 10);
    compare_with_dense(9, 4, 5, 1.0, 1.0, 11);
    compare_with_dense(30, 1, 4, 3.0, 1.0, 12);
    compare_with_dense(17, 5, 12, 1.0, 1.0, 13);
    compare_with_dense(198, 97, 101, 1.0, 1.0, 14);
    compare_with_dense(203, 101, 97, 1.0, 2.0, 15);
    compare_with_dense(2000, 10, 11, 1.0 / 3e-4, 1.0 / 3.21e-4, 9);
}

/* The AVX2/FMA kernels (where the CPU has them) and the portable ones give the same answers. */
static void test_portable_and_simd_agree(void **state)
{
    (void)state;
    static const int cases[][3] = {{330, 10, 11}, {1003, 97, 101}, {64, 1, 2}, {23, 11, 12},
                                   {50, 3, 4},    {9, 4, 5},       {31, 1, 4}, {206, 101, 97}};
    for (size_t q = 0; q < sizeof cases / sizeof cases[0]; q++) {
        int n = cases[q][0], d1 = cases[q][1], d2 = cases[q][2];
        sc_rng rng;
        sc_rng_seed(&rng, 100 + q);
        double *f = dalloc(n), *y1 = dalloc(n), *y2 = dalloc(n);
        double *fa = dalloc(n), *fb = dalloc(n), *ua = dalloc(n), *ub = dalloc(n);
        random_profile(n, &rng, f);
        simulate(n, d1, d2, f, 0.1, 0.2, y1, y2, &rng, 0.01, 0.012);
        sc_profile_lsq_plan *pa = NULL, *pb = NULL;
        sc_error err;
        sc_error_clear(&err);
        assert_int_equal(sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3, 0u, &pa, &err), SC_OK);
        assert_int_equal(
            sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3, SC_PROFILE_LSQ_PORTABLE, &pb, &err),
            SC_OK);
        assert_false(sc_profile_lsq_uses_simd(pb));
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
        /* without the flag, the AVX2 kernels wherever the processor has them */
        __builtin_cpu_init();
        assert_int_equal(sc_profile_lsq_uses_simd(pa),
                         __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"));
#endif
        assert_int_equal(sc_profile_lsq_dof(pa), n - d1 - d2);
        assert_int_equal(sc_profile_lsq_execute(pa, y1, y2, fa, NULL, NULL, &err), SC_OK);
        assert_int_equal(sc_profile_lsq_execute(pb, y1, y2, fb, NULL, NULL, &err), SC_OK);
        assert_int_equal(sc_profile_lsq_uncertainty(pa, ua, NULL, &err), SC_OK);
        assert_int_equal(sc_profile_lsq_uncertainty(pb, ub, NULL, &err), SC_OK);
        double fs = 0, df = 0, du = 0;
        for (int i = 0; i < n; i++) {
            fs = fmax(fs, fabs(fb[i]));
            df = fmax(df, fabs(fa[i] - fb[i]));
            du = fmax(du, fabs(ua[i] - ub[i]) / ub[i]);
        }
        print_message("simd=%d vs portable N=%d d=%d/%d: rel diff f %.2g, uf %.2g\n",
                      sc_profile_lsq_uses_simd(pa), n, d1, d2, df / fs, du);
        assert_true(df <= 1e-11 * fs && du <= 1e-11);
        sc_profile_lsq_plan_destroy(pa);
        sc_profile_lsq_plan_destroy(pb);
        free(f);
        free(y1);
        free(y2);
        free(fa);
        free(fb);
        free(ua);
        free(ub);
    }
}

/* ---------- uncertainty ---------- */


/* The twisted factorization (two halves sharing one factor by persymmetry, separator of
 * s ≡ N (mod 8) rows) and the one-sided banded one give the same f, c, wrss and u(f), for every
 * separator size s - bw = 0..7, at the threshold N = 4·bw + 32, and with both kernel sets. */
static void test_twisted_matches_serial(void **state)
{
    (void)state;
    static const int cases[][3] = {
        {330, 10, 11},  {331, 10, 11},  {332, 10, 11}, {333, 10, 11}, {334, 10, 11},
        {335, 10, 11},  {336, 10, 11},  {337, 10, 11}, {76, 10, 11},  {77, 11, 10},
        {1003, 97, 101}, {436, 97, 101}, {1200, 101, 97}, {2001, 3, 11}, {40, 1, 2},
        {41, 2, 1},     {36, 1, 1},     {20011, 10, 11}, {4001, 13, 4}};
    for (size_t q = 0; q < sizeof cases / sizeof cases[0]; q++) {
        int n = cases[q][0], d1 = cases[q][1], d2 = cases[q][2];
        for (unsigned portable = 0; portable <= SC_PROFILE_LSQ_PORTABLE; portable++) {
            sc_rng rng;
            sc_rng_seed(&rng, 300 + q);
            double *f = dalloc(n), *y1 = dalloc(n), *y2 = dalloc(n);
            double *fa = dalloc(n), *fb = dalloc(n), *ua = dalloc(n), *ub = dalloc(n);
            random_profile(n, &rng, f);
            simulate(n, d1, d2, f, 0.1, -0.2, y1, y2, &rng, 0.01, 0.012);
            sc_profile_lsq_plan *pa = NULL, *pb = NULL;
            sc_error err;
            sc_error_clear(&err);
            assert_int_equal(sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3, portable, &pa, &err),
                             SC_OK);
            assert_int_equal(sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3,
                                                              portable | SC_PROFILE_LSQ_SERIAL, &pb, &err),
                             SC_OK);
            double ca[2], cb[2], wa, wb;
            assert_int_equal(sc_profile_lsq_execute(pa, y1, y2, fa, ca, &wa, &err), SC_OK);
            assert_int_equal(sc_profile_lsq_execute(pb, y1, y2, fb, cb, &wb, &err), SC_OK);
            assert_int_equal(sc_profile_lsq_uncertainty(pa, ua, NULL, &err), SC_OK);
            assert_int_equal(sc_profile_lsq_uncertainty(pb, ub, NULL, &err), SC_OK);
            double fs = 0, df = 0, du = 0;
            for (int i = 0; i < n; i++) {
                fs = fmax(fs, fabs(fb[i]));
                df = fmax(df, fabs(fa[i] - fb[i]));
                du = fmax(du, fabs(ua[i] - ub[i]) / ub[i]);
            }
            double dc = fmax(fabs(ca[0] - cb[0]), fabs(ca[1] - cb[1])) /
                        fmax(fabs(cb[0]), fabs(cb[1]));
            double dw = fabs(wa - wb) / wb;
            if (q % 6 == 0 || n > 10000)
                print_message("twisted vs serial N=%d d=%d/%d portable=%u: rel diff f %.2g, "
                              "c %.2g, wrss %.2g, uf %.2g\n",
                              n, d1, d2, portable, df / fs, dc, dw, du);
            assert_true(df <= 1e-12 * fs);
            assert_true(dc <= 1e-12);
            assert_true(dw <= 1e-12);
            assert_true(du <= 1e-12);
            sc_profile_lsq_plan_destroy(pa);
            sc_profile_lsq_plan_destroy(pb);
            free(f);
            free(y1);
            free(y2);
            free(fa);
            free(fb);
            free(ua);
            free(ub);
        }
    }
}


/* The helper thread that faults the factor's pages in (factors of 16 MB and more), the early
 * selected inversion on a second thread and the huge pages option change nothing: bit-identical
 * f, c, wrss and u(f) with and without them. */
static void test_helper_thread_changes_nothing(void **state)
{
    (void)state;
    int n = 40000, d1 = 97, d2 = 101; /* factor (n/2 + 101)·102·8 bytes ≈ 16.4 MB */
    sc_rng rng;
    sc_rng_seed(&rng, 77);
    double *f = dalloc(n), *y1 = dalloc(n), *y2 = dalloc(n);
    double *fa = dalloc(n), *fb = dalloc(n), *ua = dalloc(n), *ub = dalloc(n);
    random_profile(n, &rng, f);
    simulate(n, d1, d2, f, 0.1, -0.2, y1, y2, &rng, 0.01, 0.012);
    sc_profile_lsq_plan *pa = NULL, *pb = NULL;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3, 0u, &pa, &err), SC_OK);
    assert_int_equal(
        sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3, SC_PROFILE_LSQ_ONE_THREAD, &pb, &err), SC_OK);
    double ca[2], cb[2], wa, wb;
    assert_int_equal(sc_profile_lsq_execute(pa, y1, y2, fa, ca, &wa, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_execute(pb, y1, y2, fb, cb, &wb, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_uncertainty(pa, ua, NULL, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_uncertainty(pb, ub, NULL, &err), SC_OK);
    assert_memory_equal(fa, fb, (size_t)n * sizeof(double));
    assert_memory_equal(ua, ub, (size_t)n * sizeof(double));
    assert_memory_equal(ca, cb, sizeof ca);
    assert_true(wa == wb);
    sc_profile_lsq_plan_destroy(pb);
    /* the selected inversion started early on a second thread: the same; and a plan with that
     * thread destroyed without asking for the uncertainty (the thread is joined, nothing leaks) */
    assert_int_equal(sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3,
                                                      SC_PROFILE_LSQ_EARLY_UNCERTAINTY, &pb, &err),
                     SC_OK);
    assert_int_equal(sc_profile_lsq_execute(pb, y1, y2, fb, cb, &wb, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_uncertainty(pb, ub, NULL, &err), SC_OK);
    assert_memory_equal(fa, fb, (size_t)n * sizeof(double));
    assert_memory_equal(ua, ub, (size_t)n * sizeof(double));
    assert_int_equal(sc_profile_lsq_uncertainty(pb, ub, NULL, &err), SC_OK); /* again: no second join */
    assert_memory_equal(ua, ub, (size_t)n * sizeof(double));
    sc_profile_lsq_plan_destroy(pb);
    assert_int_equal(sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3,
                                                      SC_PROFILE_LSQ_EARLY_UNCERTAINTY, &pb, &err),
                     SC_OK);
    sc_profile_lsq_plan_destroy(pb);
    /* the factor in transparent huge pages: the same */
    assert_int_equal(
        sc_profile_lsq_plan_create_tuned(n, d1, d2, 1e4, 7e3, SC_PROFILE_LSQ_HUGE_PAGES, &pb, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_execute(pb, y1, y2, fb, cb, &wb, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_uncertainty(pb, ub, NULL, &err), SC_OK);
    assert_memory_equal(fa, fb, (size_t)n * sizeof(double));
    assert_memory_equal(ua, ub, (size_t)n * sizeof(double));
    assert_memory_equal(ca, cb, sizeof ca);
    assert_true(wa == wb);
    sc_profile_lsq_plan_destroy(pa);
    sc_profile_lsq_plan_destroy(pb);
    free(f);
    free(y1);
    free(y2);
    free(fa);
    free(fb);
    free(ua);
    free(ub);
}

/* Ding's set-up: s = 1 mm, σ_disp = 10 nm, σ_angle = 1 nm/mm: var y_k = 2σ_disp² + (D_k σ_angle)². */
static double ding_variance_um2(int d) { return 2 * 0.01 * 0.01 + (d * 1e-3) * (d * 1e-3); }

static void test_uncertainty_vs_monte_carlo(void **state)
{
    (void)state;
    const int n = 330, d1 = 10, d2 = 11, trials = 20000;
    double v1 = ding_variance_um2(d1), v2 = ding_variance_um2(d2);
    sc_profile_lsq_plan *p = NULL;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1 / v1, 1 / v2, &p, &err), SC_OK);
    double *uf = dalloc(n), *f = dalloc(n), *ft = dalloc(n), *y1 = dalloc(n), *y2 = dalloc(n);
    double *acc = dalloc(n);
    assert_int_equal(sc_profile_lsq_uncertainty(p, uf, NULL, &err), SC_OK);
    sc_rng rng;
    sc_rng_seed(&rng, 42);
    random_profile(n, &rng, ft);
    simulate(n, d1, d2, ft, 0, 0, y1, y2, NULL, 0, 0);
    remove_line(n, ft);
    double wrss_sum = 0;
    for (int t = 0; t < trials; t++) {
        simulate(n, d1, d2, ft, 0.5, -0.2, y1, y2, &rng, sqrt(v1), sqrt(v2));
        double wrss;
        assert_int_equal(sc_profile_lsq_execute(p, y1, y2, f, NULL, &wrss, &err), SC_OK);
        wrss_sum += wrss;
        for (int i = 0; i < n; i++) acc[i] += (f[i] - ft[i]) * (f[i] - ft[i]);
    }
    double worst = 0, mean_ratio = 0;
    for (int i = 0; i < n; i++) {
        double mc = sqrt(acc[i] / trials);
        double r = mc / uf[i];
        worst = fmax(worst, fabs(r - 1));
        mean_ratio += r / n;
    }
    /* statistical error of a standard deviation from 20000 samples: 0.5 % */
    print_message("Monte Carlo (%d trials) / predicted: worst point %.4f, mean ratio %.4f\n",
                  trials, worst, mean_ratio);
    if (!(worst < 0.03 && fabs(mean_ratio - 1) < 0.01)) {
        print_error("MC vs predicted: worst %.4f, mean ratio %.4f\n", worst, mean_ratio);
        fail();
    }
    /* E[wrss] = degrees of freedom N - d1 - d2 */
    double dof = n - d1 - d2;
    assert_true(fabs(wrss_sum / trials / dof - 1) < 0.01);
    sc_profile_lsq_plan_destroy(p);
    free(uf);
    free(f);
    free(ft);
    free(y1);
    free(y2);
    free(acc);
}

static void test_paper_setup(void **state)
{
    (void)state;
    const int n = 330;
    const int ds[2][2] = {{10, 11}, {3, 11}};
    for (int q = 0; q < 2; q++) {
        int d1 = ds[q][0], d2 = ds[q][1];
        sc_profile_lsq_plan *p = NULL;
        sc_error err;
        sc_error_clear(&err);
        assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1 / ding_variance_um2(d1),
                                                    1 / ding_variance_um2(d2), &p, &err),
                         SC_OK);
        double uf[330];
        assert_int_equal(sc_profile_lsq_uncertainty(p, uf, NULL, &err), SC_OK);
        print_message("paper set-up d = %d/%d: uf(0) = %.2f nm, uf(N/4) = %.2f nm, uf(N/2) = %.2f "
                      "nm\n",
                      d1, d2, uf[0] * 1e3, uf[n / 4] * 1e3, uf[n / 2] * 1e3);
        if (q == 0) {
            /* Ding Fig. 4: about 12 nm in the middle */
            assert_true(uf[n / 2] > 0.010 && uf[n / 2] < 0.014);
        }
        sc_profile_lsq_plan_destroy(p);
    }
}

/* ---------- N = 10⁶: against a long-double computation in another gauge ---------- */

typedef long double ld;

/* The pinned normal system in long double with pins a and b (other than the library's), solved
 * by banded LDLᵀ; returns f for the data and the LS-gauge variance of f at the points idx. */
static void long_double_reference(int n, int d1, int d2, double w1, double w2, const double *y1,
                                  const double *y2, int pa, int pb, double *f_out, int npts,
                                  const int *idx, double *var_out)
{
    int bw = d1 > d2 ? d1 : d2;
    size_t ld_ = (size_t)bw + 1;
    ld *l = calloc((size_t)n * ld_, sizeof(ld)), *dd = calloc((size_t)n, sizeof(ld));
    ld *x = calloc((size_t)n, sizeof(ld)), *z1 = calloc((size_t)n, sizeof(ld)),
       *z2 = calloc((size_t)n, sizeof(ld)), *e1 = calloc((size_t)n, sizeof(ld)),
       *e2 = calloc((size_t)n, sizeof(ld));
    assert_true(l && dd && x && z1 && z2 && e1 && e2);
#define PIN(i) ((i) == pa || (i) == pb)
    /* LDLᵀ with row-band storage: l[i][m] = L[i][i-bw+m] */
    for (int i = 0; i < n; i++) {
        ld *ri = l + (size_t)i * ld_;
        int k0 = i - bw < 0 ? 0 : i - bw;
        if (!PIN(i)) {
            if (i - d1 >= 0 && !PIN(i - d1)) ri[bw - d1] -= w1;
            if (i - d2 >= 0 && !PIN(i - d2)) ri[bw - d2] -= w2;
        }
        ld aii = 1;
        if (!PIN(i)) {
            aii = 0;
            if (i >= d1) aii += w1;
            if (i < n - d1) aii += w1;
            if (i >= d2) aii += w2;
            if (i < n - d2) aii += w2;
        }
        for (int j = k0; j < i; j++) {
            ld *rj = l + (size_t)j * ld_, s = ri[j - i + bw];
            for (int k = k0; k < j; k++) s -= ri[k - i + bw] * dd[k] * rj[k - j + bw];
            ri[j - i + bw] = s / dd[j];
        }
        for (int k = k0; k < i; k++) aii -= ri[k - i + bw] * ri[k - i + bw] * dd[k];
        dd[i] = aii;
    }
    /* solve B x = r in place */
#define BSOLVE(v)                                                                                  \
    do {                                                                                           \
        for (int i = 0; i < n; i++) {                                                              \
            ld *ri = l + (size_t)i * ld_;                                                          \
            int k0 = i - bw < 0 ? 0 : i - bw;                                                      \
            for (int k = k0; k < i; k++) (v)[i] -= ri[k - i + bw] * (v)[k];                        \
        }                                                                                          \
        for (int i = 0; i < n; i++) (v)[i] /= dd[i];                                               \
        for (int i = n - 1; i >= 0; i--) {                                                         \
            ld *ri = l + (size_t)i * ld_;                                                          \
            int k0 = i - bw < 0 ? 0 : i - bw;                                                      \
            for (int k = k0; k < i; k++) (v)[k] -= ri[k - i + bw] * (v)[i];                        \
        }                                                                                          \
    } while (0)
    for (int i = 0; i < n; i++) {
        e1[i] = PIN(i) ? 0 : (ld)w1 * ((i >= d1) - (i < n - d1));
        e2[i] = PIN(i) ? 0 : (ld)w2 * ((i >= d2) - (i < n - d2));
        z1[i] = e1[i];
        z2[i] = e2[i];
    }
    BSOLVE(z1);
    BSOLVE(z2);
    ld s11 = (ld)w1 * (n - d1), s22 = (ld)w2 * (n - d2), s12 = 0;
    for (int i = 0; i < n; i++) {
        s11 -= e1[i] * z1[i];
        s22 -= e2[i] * z2[i];
        s12 -= e1[i] * z2[i];
    }
    ld det = s11 * s22 - s12 * s12;
    ld nc = 0.5L * (n - 1), sxx = (ld)n * ((ld)n * n - 1) / 12;
    /* data */
    for (int i = 0; i < n; i++) x[i] = 0;
    ld r1 = 0, r2 = 0;
    for (int j = 0; j + d1 < n; j++) {
        x[j + d1] += (ld)w1 * y1[j];
        x[j] -= (ld)w1 * y1[j];
        r1 += (ld)w1 * y1[j];
    }
    for (int j = 0; j + d2 < n; j++) {
        x[j + d2] += (ld)w2 * y2[j];
        x[j] -= (ld)w2 * y2[j];
        r2 += (ld)w2 * y2[j];
    }
    x[pa] = x[pb] = 0;
    BSOLVE(x);
    ld t1 = r1, t2 = r2;
    for (int i = 0; i < n; i++) {
        t1 -= e1[i] * x[i];
        t2 -= e2[i] * x[i];
    }
    ld c1 = (s22 * t1 - s12 * t2) / det, c2 = (s11 * t2 - s12 * t1) / det;
    ld m0 = 0, m1 = 0;
    for (int i = 0; i < n; i++) {
        x[i] -= z1[i] * c1 + z2[i] * c2;
        m0 += x[i];
        m1 += (i - nc) * x[i];
    }
    for (int i = 0; i < n; i++) f_out[i] = (double)(x[i] - m0 / n - m1 / sxx * (i - nc));
    /* variance at idx[q]: v = P e_i; C v = [M_r⁻¹ (v, 0)]_f; var = vᵀ C v */
    for (int q = 0; q < npts; q++) {
        int ii = idx[q];
        for (int i = 0; i < n; i++) {
            ld v = (i == ii) - 1.0L / n - (i - nc) * (ii - nc) / sxx;
            x[i] = PIN(i) ? 0 : v;
        }
        BSOLVE(x);
        ld u1 = 0, u2 = 0;
        for (int i = 0; i < n; i++) {
            u1 -= e1[i] * x[i];
            u2 -= e2[i] * x[i];
        }
        ld cc1 = (s22 * u1 - s12 * u2) / det, cc2 = (s11 * u2 - s12 * u1) / det;
        ld var = 0;
        for (int i = 0; i < n; i++) {
            ld cx = PIN(i) ? 0 : x[i] - z1[i] * cc1 - z2[i] * cc2;
            ld v = (i == ii) - 1.0L / n - (i - nc) * (ii - nc) / sxx;
            var += v * cx;
        }
        var_out[q] = (double)var;
    }
#undef BSOLVE
#undef PIN
    free(l);
    free(dd);
    free(x);
    free(z1);
    free(z2);
    free(e1);
    free(e2);
}

static void test_million_points_vs_long_double(void **state)
{
    (void)state;
    const int n = 1000000, d1 = 10, d2 = 11;
    double v1 = ding_variance_um2(d1), v2 = ding_variance_um2(d2);
    double *ft = dalloc(n), *y1 = dalloc(n), *y2 = dalloc(n), *f = dalloc(n), *uf = dalloc(n),
           *fr = dalloc(n);
    sc_rng rng;
    sc_rng_seed(&rng, 7);
    random_profile(n, &rng, ft);
    simulate(n, d1, d2, ft, 0.5, -0.2, y1, y2, &rng, sqrt(v1), sqrt(v2));
    sc_profile_lsq_plan *p = NULL;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_profile_lsq_plan_create(n, d1, d2, 1 / v1, 1 / v2, &p, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_execute(p, y1, y2, f, NULL, NULL, &err), SC_OK);
    assert_int_equal(sc_profile_lsq_uncertainty(p, uf, NULL, &err), SC_OK);
    const int idx[5] = {0, 17, n / 3 + 5, n / 2, n - 1};
    double var[5];
    long_double_reference(n, d1, d2, 1 / v1, 1 / v2, y1, y2, n / 4, (3 * n) / 4, fr, 5, idx, var);
    double fscale = 0, df = 0;
    for (int i = 0; i < n; i++) {
        fscale = fmax(fscale, fabs(fr[i]));
        df = fmax(df, fabs(f[i] - fr[i]));
    }
    print_message("N = 1e6: max |f - f_ref| = %.3g um (max |f| %.3g um)\n", df, fscale);
    assert_true(df <= 1e-8 * fscale);
    for (int q = 0; q < 5; q++) {
        double ref = sqrt(var[q]);
        print_message("N = 1e6: uf(%d) = %.12g um, long double in another gauge %.12g um "
                      "(rel %.2g)\n", idx[q], uf[idx[q]], ref, fabs(uf[idx[q]] - ref) / ref);
        assert_true(fabs(uf[idx[q]] - ref) <= 1e-8 * ref);
    }
    sc_profile_lsq_plan_destroy(p);
    free(ft);
    free(y1);
    free(y2);
    free(f);
    free(uf);
    free(fr);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_solvable_matches_dense_rank),
        cmocka_unit_test(test_refuses_bad_input),
        cmocka_unit_test(test_weight_scale_invariance),
        cmocka_unit_test(test_noise_free_simulated),
        cmocka_unit_test(test_noise_free_dabam),
        cmocka_unit_test(test_fast_matches_dense),
        cmocka_unit_test(test_portable_and_simd_agree),
        cmocka_unit_test(test_twisted_matches_serial),
        cmocka_unit_test(test_helper_thread_changes_nothing),
        cmocka_unit_test(test_uncertainty_vs_monte_carlo),
        cmocka_unit_test(test_paper_setup),
        cmocka_unit_test(test_million_points_vs_long_double),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
