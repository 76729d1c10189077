/* Real rigs (SPEC §2a, docs/profile.md "Real rigs"): gaps, probe gain and angle scale with their
 * uncertainties, a common drift, residuals and outliers, the χ² verdict and the coverage of u(f),
 * on simulated rigs (sc_profile_simulate, then the rig's effect applied to its readings). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "selfcal/profile_sim.h"
#include "selfcal/rng.h"

/* A simulated measurement and its truth (f relative to its least-squares line). */
typedef struct rig {
    sc_profile_data d;
    double *truth, *f, *uf, *ey;
    int n;
} rig;

static void rig_make(rig *r, int n, int d1, int d2, double sd, double sa, uint64_t seed)
{
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    p.n = n, p.d1 = d1, p.d2 = d2, p.sigma_disp_um = sd, p.sigma_angle_urad = sa, p.seed = seed;
    r->n = n;
    r->truth = malloc((size_t)n * sizeof(double));
    r->f = malloc((size_t)n * sizeof(double));
    r->uf = malloc((size_t)n * sizeof(double));
    r->ey = malloc((size_t)n * sizeof(double));
    double *ey = malloc((size_t)n * sizeof(double));
    assert_non_null(r->truth);
    assert_non_null(ey);
    sc_profile_sim_random_truth(&p, 1.0, 20, r->truth);
    sc_error err;
    assert_int_equal(sc_profile_simulate(&p, r->truth, &r->d, ey, &err), SC_OK);
    sc_profile_remove_line(n, r->truth);
    free(ey);
}

static void rig_free(rig *r)
{
    sc_profile_data_free(&r->d);
    free(r->truth), free(r->f), free(r->uf), free(r->ey);
}

static sc_status rig_solve(rig *r, const sc_profile_options *o, sc_profile_solution *s,
                           sc_error *err)
{
    memset(s, 0, sizeof *s);
    s->f_um = r->f, s->uf_um = r->uf, s->ey_um = r->ey;
    return sc_profile_calibrate(&r->d, o, s, err);
}

/* Largest |f - truth| over the points determined, the truth relative to its least-squares line
 * over those same points. */
static double rig_error(const rig *r)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0, worst = 0;
    for (int i = 0; i < r->n; ++i)
        if (isfinite(r->f[i]))
            m += 1, sx += i, sy += r->truth[i];
    double xm = sx / m, ym = sy / m;
    for (int i = 0; i < r->n; ++i)
        if (isfinite(r->f[i]))
            sxx += (i - xm) * (i - xm), sxy += (i - xm) * (r->truth[i] - ym);
    double b = sxy / sxx;
    for (int i = 0; i < r->n; ++i)
        if (isfinite(r->f[i])) {
            double e = fabs(r->f[i] - (r->truth[i] - ym - b * (i - xm)));
            worst = e > worst ? e : worst;
        }
    return worst;
}

/* The rig solver (forced by asking for residuals) gives the fast solver's f and u(f) on complete
 * data. */
static void test_rig_matches_fast(void **state)
{
    (void)state;
    static const int cases[][3] = {{330, 10, 11}, {331, 10, 11}, {500, 7, 13}, {1000, 97, 101},
                                   {21, 10, 11}, {40, 1, 2}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        rig r;
        rig_make(&r, cases[c][0], cases[c][1], cases[c][2], 0.01, 1.0, 7 + c);
        int n = r.n;
        double *f0 = malloc((size_t)n * sizeof(double)), *u0 = malloc((size_t)n * sizeof(double));
        sc_profile_options o;
        sc_profile_options_default(&o);
        sc_profile_solution s;
        sc_error err;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_int_equal(s.rig, 0);
        memcpy(f0, r.f, (size_t)n * sizeof(double));
        memcpy(u0, r.uf, (size_t)n * sizeof(double));
        o.want_residuals = 1; /* no arrays: the rig solver runs, nothing is tested */
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_int_equal(s.rig, 1);
        for (int i = 0; i < n; ++i) {
            assert_true(fabs(r.f[i] - f0[i]) < 1e-10);
            assert_true(fabs(r.uf[i] / u0[i] - 1) < 1e-9);
        }
        free(f0), free(u0);
        rig_free(&r);
    }
}

static void drop_row(sc_profile_data *d, int k, int j)
{
    d->m1_um[k][j] = d->m2_um[k][j] = d->m3_urad[k][j] = NAN;
}

/* Noise-free data with gaps (20 missing rows, an empty field) solve exactly; a point no row ties
 * to the rest is left empty and counted; u rises a little. */
static void test_gaps_exact(void **state)
{
    (void)state;
    rig r;
    rig_make(&r, 330, 10, 11, 0, 0, 3);
    for (int j = 100; j < 120; ++j)
        drop_row(&r.d, 0, j);
    r.d.m2_um[1][200] = NAN;
    assert_true(sc_profile_has_gaps(&r.d));
    sc_profile_options o;
    sc_profile_options_default(&o);
    sc_profile_solution s;
    sc_error err;
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    assert_int_equal(s.rig, 1);
    assert_int_equal(s.n_undetermined, 0);
    assert_true(rig_error(&r) < 1e-11);
    /* e_y where scan 1 has a gap comes from scan 2's m1: complete, and as without the gap */
    for (int i = 0; i < 330 - 10; ++i)
        assert_true(isfinite(r.ey[i]));
    {
        rig c;
        rig_make(&c, 330, 10, 11, 0, 0, 3);
        assert_int_equal(rig_solve(&c, &o, &s, &err), SC_OK);
        for (int i = 0; i < 330 - 10; ++i)
            assert_true(fabs(r.ey[i] - c.ey[i]) < 1e-11);
        rig_free(&c);
    }
    /* point 150 is in scan 1 rows 140, 150 and scan 2 rows 139, 150 only */
    drop_row(&r.d, 0, 150);
    drop_row(&r.d, 0, 140);
    drop_row(&r.d, 1, 150);
    drop_row(&r.d, 1, 139);
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    assert_int_equal(s.n_undetermined, 1);
    assert_true(isnan(r.f[150]) && isnan(r.uf[150]) && isnan(r.ey[150]) && isfinite(r.ey[149]));
    assert_true(isfinite(r.f[149]) && isfinite(r.f[151]));
    assert_true(rig_error(&r) < 1e-11);
    /* with noise stated: u rises a little (Ding's 12.87 nm RMS at 10/11) */
    rig_free(&r);
    rig_make(&r, 330, 10, 11, 0.01, 1.0, 3);
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    double rms0 = 0, rms1 = 0;
    for (int i = 0; i < 330; ++i)
        rms0 += r.uf[i] * r.uf[i];
    for (int j = 100; j < 120; ++j)
        drop_row(&r.d, 0, j);
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    for (int i = 0; i < 330; ++i)
        rms1 += r.uf[i] * r.uf[i];
    rms0 = sqrt(rms0 / 330), rms1 = sqrt(rms1 / 330);
    assert_true(rms0 > 0.0125 && rms0 < 0.0132);
    assert_true(rms1 > rms0 && rms1 < 1.2 * rms0);
    rig_free(&r);
}

/* The DFT method refuses gaps, naming the scan's header line and --method lsq. */
static void test_dft_refuses_gaps(void **state)
{
    (void)state;
    rig r;
    rig_make(&r, 330, 10, 11, 0.01, 1.0, 3);
    r.d.line_scan[0] = 4, r.d.line_scan[1] = 5;
    snprintf(r.d.path, sizeof r.d.path, "in.csv");
    r.d.m3_urad[1][77] = NAN;
    sc_profile_options o;
    sc_profile_options_default(&o);
    o.method = SC_PROFILE_DFT;
    sc_profile_solution s;
    sc_error err;
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "--method lsq"));
    assert_non_null(strstr(err.msg, "scan 2"));
    assert_int_equal(err.line, 5);
    /* a gap running to the scan's last reading: named to its end */
    r.d.m3_urad[1][77] = 0;
    for (int j = 330 - 11 - 3; j < 330 - 11; ++j)
        r.d.m1_um[1][j] = NAN;
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "scan 2 has no complete sample for n = 316..318:"));
    rig_free(&r);
}

/* Probe 2 reading K times (m2·K) and the angle sensor K_a times: stated, the bias is removed
 * exactly; not stated, it is not. */
static void test_gain_and_angle_scale_exact(void **state)
{
    (void)state;
    for (int which = 0; which < 2; ++which) {
        rig r;
        rig_make(&r, 330, 10, 11, 0, 0, 5);
        const double K = which ? 1.01 : 1.001;
        for (int k = 0; k < 2; ++k)
            for (int j = 0; j < 330 - r.d.d[k]; ++j) {
                if (which)
                    r.d.m3_urad[k][j] *= K;
                else
                    r.d.m2_um[k][j] *= K;
            }
        sc_profile_options o;
        sc_profile_options_default(&o);
        sc_profile_solution s;
        sc_error err;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_true(rig_error(&r) > 1e-4); /* the bias, not seen by the residuals */
        double *g = which ? r.d.angle_scale : r.d.probe_gain;
        g[0] = K, g[1] = 0;
        if (which)
            r.d.has_angle_scale = 1;
        else
            r.d.has_probe_gain = 1;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_true(rig_error(&r) < 1e-11);
        rig_free(&r);
    }
}

/* A stated U of the gain, angle scale or spacing enters uf as |∂f/∂K|·U: checked against a
 * finite difference of the solution, and shown in the budget. */
static void test_instrument_u_enters_uf(void **state)
{
    (void)state;
    for (int src = SC_PROFILE_U_PROBE_GAIN; src < SC_PROFILE_U_N; ++src) {
        rig r;
        rig_make(&r, 330, 10, 11, 0.01, 1.0, 9);
        const int n = 330;
        sc_profile_options o;
        sc_profile_options_default(&o);
        sc_profile_solution s;
        sc_error err;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        double *u0 = malloc(n * sizeof(double)), *f0 = malloc(n * sizeof(double));
        memcpy(u0, r.uf, n * sizeof(double));
        memcpy(f0, r.f, n * sizeof(double));
        const double U = src == SC_PROFILE_U_SPACING ? 0.01 : 1e-3, h = 1e-4;
        if (src == SC_PROFILE_U_PROBE_GAIN)
            r.d.has_probe_gain = 1, r.d.probe_gain[0] = 1 + h, r.d.probe_gain[1] = U;
        else if (src == SC_PROFILE_U_ANGLE_SCALE)
            r.d.has_angle_scale = 1, r.d.angle_scale[0] = 1 + h, r.d.angle_scale[1] = U;
        else
            r.d.has_spacing_u = 1, r.d.spacing_u_mm = U;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_true(s.budget_rms_um[src] > 0);
        for (int other = 1; other < SC_PROFILE_U_N; ++other)
            if (other != src)
                assert_true(s.budget_rms_um[other] == 0);
        if (src != SC_PROFILE_U_SPACING) { /* finite difference of f in K (f linear in 1/K) */
            for (int i = 0; i < n; i += 7) {
                double sens = (r.f[i] - f0[i]) / h; /* per unit of K near 1 */
                double expect = sqrt(u0[i] * u0[i] + sens * U * sens * U);
                assert_true(fabs(r.uf[i] - expect) < 1e-3 * expect + 1e-7);
            }
        } else {
            /* each spacing D_k by itself (independent): scan k's angle readings scaled by
             * 1 + U/D_k move y_k by exactly U times its sensitivity to D_k (-m3) */
            double *df[2], *m3[2];
            for (int k = 0; k < 2; ++k) {
                const int m = n - r.d.d[k];
                const double D = r.d.d[k] * r.d.s_mm;
                df[k] = malloc(n * sizeof(double));
                m3[k] = malloc(m * sizeof(double));
                memcpy(m3[k], r.d.m3_urad[k], m * sizeof(double));
                r.d.has_spacing_u = 0;
                for (int j = 0; j < m; ++j)
                    r.d.m3_urad[k][j] *= 1 + U / D;
                assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
                for (int i = 0; i < n; ++i)
                    df[k][i] = r.f[i] - f0[i];
                memcpy(r.d.m3_urad[k], m3[k], m * sizeof(double));
            }
            r.d.has_spacing_u = 1;
            assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
            double ss = 0;
            for (int i = 0; i < n; ++i) {
                double b2 = df[0][i] * df[0][i] + df[1][i] * df[1][i];
                double expect = sqrt(u0[i] * u0[i] + b2);
                assert_true(fabs(r.uf[i] - expect) < 1e-6 * expect + 1e-9);
                ss += b2;
            }
            assert_true(fabs(s.budget_rms_um[src] - sqrt(ss / n)) < 1e-6 * s.budget_rms_um[src]);
            for (int k = 0; k < 2; ++k)
                free(df[k]), free(m3[k]);
        }
        free(u0), free(f0);
        rig_free(&r);
    }
}

/* A differential drift a·τ + b·τ² in both scans' m2: fitted, the bias goes exactly; not fitted,
 * it stays; and u grows (drift_cost > 1). */
static void test_drift_removed(void **state)
{
    (void)state;
    double cost1 = 0;
    for (int order = 1; order <= 2; ++order) {
        rig r;
        rig_make(&r, 330, 10, 11, 0, 0, 11);
        const double a = 0.005, b = order == 2 ? -0.003 : 0; /* µm */
        for (int k = 0; k < 2; ++k)
            for (int j = 0; j < 330 - r.d.d[k]; ++j) {
                double t = (2.0 * j - 329) / 329;
                r.d.m2_um[k][j] += a * t + b * t * t;
            }
        sc_profile_options o;
        sc_profile_options_default(&o);
        sc_profile_solution s;
        sc_error err;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_true(rig_error(&r) > 1e-4);
        o.drift = order;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_true(rig_error(&r) < 1e-9);
        assert_true(fabs(s.drift_um[0] - a) < 1e-10);
        if (order == 2)
            assert_true(fabs(s.drift_um[1] - b) < 1e-10);
        rig_free(&r);
        /* the cost in u, with noise stated */
        rig_make(&r, 330, 10, 11, 0.01, 1.0, 11);
        o.drift = order;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        print_message("drift order %d: cost %.4g\n", order, s.drift_cost);
        assert_true(s.drift_cost > 1.5);
        /* docs/profile.md: 4.9x linear (12.87 -> 62.8 nm), 5.9x with the quadratic term (75.7
         * nm); u does not depend on the data */
        assert_true(fabs(s.drift_cost - (order == 1 ? 4.878 : 5.885)) < 0.01);
        if (order == 2)
            assert_true(s.drift_cost > cost1);
        cost1 = s.drift_cost;
        rig_free(&r);
    }
}

/* One 10σ outlier: flagged in the residuals, removed with reject_outliers, and the profile then
 * as without it. */
static void test_outlier_flagged_and_removed(void **state)
{
    (void)state;
    rig r;
    rig_make(&r, 330, 10, 11, 0.01, 1.0, 13);
    const int n = 330, m0 = n - 10, m1 = n - 11;
    double *r_um = malloc((size_t)(m0 + m1) * sizeof(double));
    double *t = malloc((size_t)(m0 + m1) * sizeof(double));
    unsigned char *out = malloc((size_t)(m0 + m1));
    double *fclean = malloc(n * sizeof(double));
    sc_profile_options o;
    sc_profile_options_default(&o);
    o.want_residuals = 1;
    sc_profile_solution s;
    sc_error err;
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    memcpy(fclean, r.f, n * sizeof(double));
    const double sy = sqrt(sc_profile_y_variance(10, 1.0, 0.01, 1.0));
    r.d.m2_um[0][150] += 10 * sy;
#define ARRAYS(s)                                                                                   \
    (s).r_um[0] = r_um, (s).r_um[1] = r_um + m0, (s).t[0] = t, (s).t[1] = t + m0,                  \
    (s).outlier[0] = out, (s).outlier[1] = out + m0
    memset(&s, 0, sizeof s);
    s.f_um = r.f, s.uf_um = r.uf, s.ey_um = r.ey;
    ARRAYS(s);
    assert_int_equal(sc_profile_calibrate(&r.d, &o, &s, &err), SC_OK);
    assert_int_equal(out[150], 1);
    assert_true(fabs(t[150]) > s.outlier_crit);
    assert_true(s.n_flagged >= 1 && s.n_removed == 0);
    o.reject_outliers = 1;
    memset(&s, 0, sizeof s);
    s.f_um = r.f, s.uf_um = r.uf, s.ey_um = r.ey;
    ARRAYS(s);
    assert_int_equal(sc_profile_calibrate(&r.d, &o, &s, &err), SC_OK);
    assert_int_equal(out[150], 2);
    assert_true(s.n_removed >= 1);
    assert_true(fabs(r_um[150] - 10 * sy) < 5 * sy); /* its residual against the final fit */
    for (int i = 0; i < n; ++i)
        assert_true(fabs(r.f[i] - fclean[i]) < 0.5 * r.uf[i]);
    free(r_um), free(t), free(out), free(fclean);
    rig_free(&r);
}

/* The calibration's edges: an outlier at the very first reading, rejected also when the caller
 * gives no residual arrays; e_y relative to its own least-squares line when a point is missing;
 * a data file named with one character named in the error; the defaults' residual check; and a
 * caller who wants neither f nor u(f) gets the same noise and e_y. */
static void test_rig_edges(void **state)
{
    (void)state;
    const int n = 330;
    rig r;
    sc_profile_options o;
    sc_profile_solution s;
    sc_error err;
    double *fclean = malloc(n * sizeof(double)), *ey0 = malloc(n * sizeof(double));
    unsigned char *out = malloc((size_t)(2 * n));
    double *ra = malloc(2 * n * sizeof(double)), *ta = malloc(2 * n * sizeof(double));
    assert_true(fclean && ey0 && out && ra && ta);
    /* An outlier in point 0's first reading: point 0 has two readings only (y1(0), y2(0)), so
     * their standardized residuals are equal but for rounding and either may be the one removed
     * (the largest |t| found first); one of them is, with or without the caller's arrays, and the
     * rest of f is as without the outlier. */
    int first = 0;
    for (int seed = 0; seed < 8; ++seed) {
        const int d1 = seed < 4 ? 10 : 11, m0 = n - d1; /* either scan the finer */
        rig_make(&r, n, d1, 21 - d1, 0.01, 1.0, 23 + (uint64_t)seed);
        sc_profile_options_default(&o);
        o.want_residuals = 1;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        memcpy(fclean, r.f, n * sizeof(double));
        const double sy = sqrt(sc_profile_y_variance(d1, 1.0, 0.01, 1.0));
        r.d.m2_um[0][0] += 30 * sy;
        o.want_residuals = 0;
        o.reject_outliers = 1; /* no arrays given: the calibration's own */
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        assert_int_equal(s.n_removed, 1);
        for (int i = 1; i < n; ++i) /* f(0) keeps the outlier if y2(0) went */
            assert_true(fabs(r.f[i] - fclean[i]) < 2 * r.uf[i]);
        memset(&s, 0, sizeof s); /* the caller's arrays: which reading went */
        s.f_um = r.f, s.uf_um = r.uf, s.ey_um = r.ey;
        s.r_um[0] = ra, s.r_um[1] = ra + m0, s.t[0] = ta, s.t[1] = ta + m0;
        s.outlier[0] = out, s.outlier[1] = out + m0;
        assert_int_equal(sc_profile_calibrate(&r.d, &o, &s, &err), SC_OK);
        assert_int_equal(s.n_removed, 1);
        assert_true(out[0] == 2 || out[m0] == 2);
        first += out[0] == 2;
        rig_free(&r);
    }
    print_message("an outlier in y1(0): y1(0) itself removed in %d of 8 runs, y2(0) in the others\n",
                  first);
    rig_make(&r, n, 10, 11, 0.01, 1.0, 23);
    sc_profile_options_default(&o);

    /* point 150 in no complete row of either scan: e_y has a hole there, and is the residual of
     * its own least-squares line over the points it has */
    drop_row(&r.d, 0, 150);
    drop_row(&r.d, 0, 140);
    drop_row(&r.d, 1, 150);
    drop_row(&r.d, 1, 139);
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    assert_true(isnan(r.ey[150]));
    double cnt = 0, sx = 0, sum = 0, mom = 0, scale = 0;
    for (int i = 0; i < n - 10; ++i)
        if (isfinite(r.ey[i]))
            cnt += 1, sx += i, sum += r.ey[i], scale = fmax(scale, fabs(r.ey[i]));
    for (int i = 0; i < n - 10; ++i)
        if (isfinite(r.ey[i]))
            mom += (i - sx / cnt) * r.ey[i];
    assert_true(cnt == n - 10 - 1 && scale > 0);
    assert_true(fabs(sum) < 1e-9 * scale * cnt);
    assert_true(fabs(mom) < 1e-9 * scale * cnt * cnt);

    /* part of the residual arrays given: none is written, no test (all six or none) */
    {
        double *r1 = malloc(n * sizeof(double));
        for (int i = 0; i < n; ++i)
            r1[i] = -7.0;
        memset(&s, 0, sizeof s);
        s.f_um = r.f, s.uf_um = r.uf, s.ey_um = r.ey;
        s.r_um[1] = r1, s.t[0] = r1, s.t[1] = r1, s.outlier[0] = out, s.outlier[1] = out;
        assert_int_equal(sc_profile_calibrate(&r.d, &o, &s, &err), SC_OK);
        for (int i = 0; i < n; ++i)
            assert_true(r1[i] == -7.0);
        free(r1);
    }
    /* neither f nor u(f) wanted: the same noise, wrss and e_y */
    memcpy(ey0, r.ey, n * sizeof(double));
    const double wrss = s.wrss, sig = s.sigma_y_um[0];
    memset(&s, 0, sizeof s);
    s.ey_um = r.ey;
    assert_int_equal(sc_profile_calibrate(&r.d, &o, &s, &err), SC_OK);
    assert_true(fabs(s.wrss - wrss) <= 1e-9 * wrss && fabs(s.sigma_y_um[0] - sig) <= 1e-12 * sig);
    for (int i = 0; i < n; ++i)
        assert_true(isnan(ey0[i]) ? isnan(r.ey[i]) : fabs(r.ey[i] - ey0[i]) < 1e-12);

    /* a scan with no complete sample, in a file named "p": the file and the scan's line */
    snprintf(r.d.path, sizeof r.d.path, "p");
    r.d.line_scan[0] = 4, r.d.line_scan[1] = 5;
    for (int j = 0; j < n - 11; ++j)
        drop_row(&r.d, 1, j);
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "scan 2 has no complete sample"));
    assert_string_equal(err.file, "p");
    assert_int_equal(err.line, 5);
    rig_free(&r);

    /* the defaults check the residuals against given noise, the DFT method too */
    rig_make(&r, n, 10, 11, 0.01, 1.0, 29);
    sc_profile_options_default(&o);
    assert_int_equal(o.residual_check, 1);
    o.method = SC_PROFILE_DFT;
    o.sigma_disp_um = 0.01, o.sigma_angle_urad = 1.0;
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    assert_true(s.noise_known);
    assert_true(isfinite(s.wrss) && s.wrss > 0);
    assert_true(s.residual_ratio > 0.8 && s.residual_ratio < 1.2);
    free(fclean), free(ey0), free(out), free(ra), free(ta);
    rig_free(&r);
}

/* Stated noise too small: the χ² test fails high and uf is scaled by sqrt(wrss/dof). */
static void test_chi2_verdict(void **state)
{
    (void)state;
    rig r;
    rig_make(&r, 330, 10, 11, 0.01, 1.0, 17);
    sc_profile_options o;
    sc_profile_options_default(&o);
    sc_profile_solution s;
    sc_error err;
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    assert_true(isfinite(s.chi2_lo) && s.chi2_lo < 1 && s.chi2_hi > 1);
    double u = r.uf[100];
    o.sigma_disp_um = 0.005, o.sigma_angle_urad = 0.5; /* half the true noise */
    assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
    assert_int_equal(s.chi2_pass, 0);
    assert_int_equal(s.u_scaled, 1);
    assert_true(fabs(r.uf[100] / u - 1) < 0.15); /* back near the true noise's u */
    rig_free(&r);
}

/* Coverage: 200 noisy runs, the noise and a probe gain's U stated (the true gain drawn from
 * N(1, U) each run): |f - truth| <= 2u for 95 ± 2 % of the points. */
static void test_coverage(void **state)
{
    (void)state;
    sc_rng rng;
    sc_rng_seed(&rng, 42);
    long in = 0, all = 0;
    for (int run = 0; run < 200; ++run) {
        rig r;
        rig_make(&r, 330, 10, 11, 0.01, 1.0, 1000 + run);
        const double U = 1e-3, K = 1 + U * sc_rng_normal(&rng);
        for (int k = 0; k < 2; ++k)
            for (int j = 0; j < 330 - r.d.d[k]; ++j)
                r.d.m2_um[k][j] *= K;
        r.d.has_probe_gain = 1, r.d.probe_gain[0] = 1, r.d.probe_gain[1] = U;
        if (run % 2) /* half of them with a gap */
            for (int j = 60; j < 80; ++j)
                drop_row(&r.d, 1, j);
        sc_profile_options o;
        sc_profile_options_default(&o);
        sc_profile_solution s;
        sc_error err;
        assert_int_equal(rig_solve(&r, &o, &s, &err), SC_OK);
        for (int i = 0; i < 330; ++i) {
            in += fabs(r.f[i] - r.truth[i]) <= 2 * r.uf[i];
            all++;
        }
        rig_free(&r);
    }
    double cov = (double)in / (double)all;
    print_message("coverage of 2u over 200 runs: %.4f\n", cov);
    assert_true(cov > 0.93 && cov < 0.97);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rig_matches_fast),
        cmocka_unit_test(test_gaps_exact),
        cmocka_unit_test(test_dft_refuses_gaps),
        cmocka_unit_test(test_gain_and_angle_scale_exact),
        cmocka_unit_test(test_instrument_u_enters_uf),
        cmocka_unit_test(test_drift_removed),
        cmocka_unit_test(test_outlier_flagged_and_removed),
        cmocka_unit_test(test_rig_edges),
        cmocka_unit_test(test_chi2_verdict),
        cmocka_unit_test(test_coverage),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
