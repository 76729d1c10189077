/* Monte Carlo benchmark of grid least squares on real measurements (issue 10, SPEC §5):
 *  1. weighted least squares: empirical std of G over trials against the predicted u (from the
 *     stated weights), and the unweighted estimator's std on the same data for comparison;
 *  2. the outlier test on clean data: fraction of coordinates (and of measurements) flagged,
 *     against the significance α; the χ² test's false-alarm rate against its 5 %;
 *  3. detection rate of one 5σ and one 10σ outlier;
 *  4. a stitched 101 x 101 stage with a 51 x 51 plate: create (analysis, factorization, every
 *     node's σ) and solve times;
 *  5. each view's noise estimated (sc_grid_options.estimate_view_noise) on data stating none:
 *     the estimates against the simulated noise (mean and spread of σ̂/σ per view), the solves
 *     it took, and the RMS error of G and its predicted u against the fit with the true weights
 *     stated and the unweighted fit, on Ye's plan and on a stitched plan.
 * Usage: bench_grid_real [--trials T] [--no-big]   (default T = 400) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/rng.h"

static double cpu_s(void) { return (double)clock() / CLOCKS_PER_SEC; }

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

typedef struct setup {
    sc_grid_plan p;         /* a copy of the plan (setup_free) */
    sc_grid_data clean, d;  /* noise-free data and a work copy */
    double *gx, *gy;        /* truth */
    sc_grid_result r;
    double *buf;
    long ns, nn;
} setup;

static void setup_make(setup *s, const sc_grid_plan *p, uint64_t seed)
{
    memset(s, 0, sizeof *s);
    sc_grid_plan_copy(&s->p, p, NULL);
    s->ns = sc_grid_stage_nodes(p), s->nn = (long)p->n * p->n;
    long nv = p->n_views;
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.sigma_r_um = 0;
    sp.seed = seed;
    sc_grid_plan_copy(&s->clean.plan, p, NULL);
    sc_grid_plan_copy(&s->d.plan, p, NULL);
    for (int v = 0; v < p->n_views; ++v)
        s->clean.plan.view[v].sigma_um = 0; /* no noise: the views' sigma_um are the weights */
    sc_grid_data_alloc(&s->clean, NULL);
    sc_grid_data_alloc(&s->d, NULL);
    s->buf = malloc(sizeof(double) *
                    (8 * s->ns + 4 * s->nn + 3 * nv + sc_grid_sim_work_doubles_plan(p)));
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    s->gx = s->buf, s->gy = s->buf + s->ns;
    t.gx_um = s->gx, t.gy_um = s->gy, t.ax_um = s->buf + 2 * s->ns, t.ay_um = t.ax_um + s->nn;
    t.tx_um = t.ay_um + s->nn, t.ty_um = t.tx_um + nv, t.theta_urad = t.ty_um + nv;
    sc_grid_sim_run(&s->clean.plan, &sp, &t, &s->clean, t.theta_urad + nv, NULL);
    double *o = t.theta_urad + nv + sc_grid_sim_work_doubles_plan(p);
    sc_grid_result_views(&s->r, p->n_views, NULL);
    s->r.gx_um = o, s->r.gy_um = o + s->ns, s->r.ugx_um = o + 2 * s->ns, s->r.ugy_um = o + 3 * s->ns;
    s->r.ax_um = o + 4 * s->ns, s->r.ay_um = o + 4 * s->ns + s->nn;
}

static void setup_free(setup *s)
{
    free(s->buf);
    sc_grid_data_free(&s->clean), sc_grid_data_free(&s->d);
    sc_grid_result_free_views(&s->r);
    sc_grid_plan_free(&s->p);
}

/* d = clean + noise (each view its own σ) + optional outlier; returns nothing. */
static void noisy(setup *s, sc_rng *rng, const double *sig)
{
    for (int v = 0; v < s->p.n_views; ++v)
        for (long k = 0; k < s->nn; ++k) {
            double x = s->clean.dx_um[v][k], y = s->clean.dy_um[v][k];
            s->d.dx_um[v][k] = isfinite(x) ? x + sig[v] * sc_rng_normal(rng) : NAN;
            s->d.dy_um[v][k] = isfinite(y) ? y + sig[v] * sc_rng_normal(rng) : NAN;
        }
}

static void monte_carlo(int trials)
{
    sc_grid_plan p;
    sc_grid_plan_ye(15, 1.0, 0, 0, &p, NULL);
    const double sig[3] = {0.01, 0.03, 0.02};
    for (int v = 0; v < 3; ++v)
        p.view[v].sigma_um = sig[v];
    setup s;
    setup_make(&s, &p, 7);
    sc_grid_plan_copy(&s.d.plan, &p, NULL); /* weights from the views' sigma_um */
    sc_grid_plan pu = {0};
    sc_grid_plan_copy(&pu, &p, NULL);
    for (int v = 0; v < 3; ++v)
        pu.view[v].sigma_um = 0;
    sc_grid_lsq_plan *qw = NULL, *qu = NULL;
    sc_rng rng;
    sc_rng_seed(&rng, 2026);
    noisy(&s, &rng, sig); /* the mask: which marks are measured */
    sc_grid_lsq_plan_create(&p, &s.d, NULL, &qw, NULL);
    sc_grid_data du = s.d; /* s.d's arrays, pu's views: borrowed, not freed */
    du.plan = pu;
    sc_grid_lsq_plan_create(&pu, &du, NULL, &qu, NULL);
    long ns = s.ns, tot = (long)p.n_views * s.nn;
    double *se_w = calloc(2 * ns, sizeof(double)), *se_u = calloc(2 * ns, sizeof(double));
    double *rx = malloc(sizeof(double) * tot), *ry = malloc(sizeof(double) * tot);
    double *tx = malloc(sizeof(double) * tot), *ty = malloc(sizeof(double) * tot);
    double *h = malloc(sizeof(double) * tot);
    double *ugx = malloc(sizeof(double) * ns), *ugy = malloc(sizeof(double) * ns);
    long coords = 0, flag_c = 0, meas = 0, flag_m = 0, chi_fail = 0, fam_fail = 0, m_tests = 0;
    /* the two tests: Baarda's classical alpha0 for each coordinate, and the default alpha for the
     * whole data set (its critical value from the number of coordinates tested, found at t = 0) */
    const double a_each = 0.001, crit_each = sc_grid_outlier_critical(a_each, 0, 1);
    double crit_fam = NAN;
    sc_grid_result ru = s.r;
    double *ubuf = malloc(sizeof(double) * (4 * ns + 2 * s.nn));
    ru.gx_um = ubuf, ru.gy_um = ubuf + ns, ru.ugx_um = ubuf + 2 * ns, ru.ugy_um = ubuf + 3 * ns;
    ru.ax_um = ubuf + 4 * ns, ru.ay_um = ubuf + 4 * ns + s.nn;
    double t0 = now_s();
    for (int t = 0; t < trials; ++t) {
        noisy(&s, &rng, sig);
        sc_grid_lsq_execute(qw, &s.d, 0, &s.r, NULL);
        if (t == 0)
            memcpy(ugx, s.r.ugx_um, sizeof(double) * ns), memcpy(ugy, s.r.ugy_um, sizeof(double) * ns);
        sc_grid_lsq_residuals(qw, &s.d, &s.r, rx, ry, tx, ty, h, NULL);
        chi_fail += !s.r.chi2_pass;
        for (long k = 0; k < ns; ++k) {
            double ex = s.r.gx_um[k] - s.gx[k], ey = s.r.gy_um[k] - s.gy[k];
            se_w[2 * k] += ex * ex, se_w[2 * k + 1] += ey * ey;
        }
        if (t == 0) {
            for (long k = 0; k < tot; ++k)
                m_tests += isfinite(tx[k]) + isfinite(ty[k]);
            crit_fam = sc_grid_outlier_critical(SC_GRID_OUTLIER_ALPHA, m_tests, 0);
        }
        int any = 0;
        for (long k = 0; k < tot; ++k) {
            if (!isfinite(tx[k]) || !isfinite(ty[k]))
                continue;
            int fx = fabs(tx[k]) > crit_each, fy = fabs(ty[k]) > crit_each;
            coords += 2, flag_c += fx + fy, meas += 1, flag_m += fx || fy;
            any |= fabs(tx[k]) > crit_fam || fabs(ty[k]) > crit_fam;
        }
        fam_fail += any;
        du.plan = pu;
        for (int v = 0; v < 3; ++v)
            du.dx_um[v] = s.d.dx_um[v], du.dy_um[v] = s.d.dy_um[v];
        sc_grid_lsq_execute(qu, &du, 0, &ru, NULL);
        for (long k = 0; k < ns; ++k) {
            double ex = ru.gx_um[k] - s.gx[k], ey = ru.gy_um[k] - s.gy[k];
            se_u[2 * k] += ex * ex, se_u[2 * k + 1] += ey * ey;
        }
    }
    double el = now_s() - t0;
    double rat2 = 0, rmin = 1e300, rmax = 0, uw2 = 0, uu2 = 0;
    for (long k = 0; k < 2 * ns; ++k) {
        double pred = k % 2 ? ugy[k / 2] : ugx[k / 2], emp = sqrt(se_w[k] / trials);
        double r = emp / pred;
        rat2 += r * r, rmin = fmin(rmin, r), rmax = fmax(rmax, r);
        uw2 += se_w[k] / trials, uu2 += se_u[k] / trials;
    }
    printf("1. weighted least squares, Ye N = 15, views sigma 0.01/0.03/0.02 um, %d trials (%.1f s)\n",
           trials, el);
    printf("   empirical std / predicted u over %ld node components: RMS %.4f, min %.4f, max %.4f\n",
           2 * ns, sqrt(rat2 / (2 * ns)), rmin, rmax);
    printf("   (per-node sampling spread of a std from %d trials: +-%.1f %%)\n", trials,
           100 / sqrt(2.0 * trials));
    printf("   RMS error of G: weighted %.5f um, unweighted %.5f um (same data)\n",
           sqrt(uw2 / (2 * ns)), sqrt(uu2 / (2 * ns)));
    printf("2. outlier test on clean data, alpha = %g per coordinate (Baarda's alpha0, |t| > %.4f):\n",
           a_each, crit_each);
    printf("   flagged coordinates %.5f (alpha %.5f), flagged measurements %.5f (1-(1-alpha)^2 = %.5f)\n",
           (double)flag_c / coords, a_each, (double)flag_m / meas, 1 - (1 - a_each) * (1 - a_each));
    printf("   the default, alpha = %g for the whole data set (%ld coordinates, |t| > %.4f):\n"
           "   calibrations with any flag %.4f (%g for independent tests, at most that for correlated\n"
           "   ones by Sidak's inequality; sampling +- %.4f)\n",
           SC_GRID_OUTLIER_ALPHA, m_tests, crit_fam, (double)fam_fail / trials,
           SC_GRID_OUTLIER_ALPHA, sqrt(SC_GRID_OUTLIER_ALPHA * (1 - SC_GRID_OUTLIER_ALPHA) / trials));
    printf("   chi2 test (95 %%, two-sided) false alarms: %.4f (expected 0.05 +- %.4f)\n",
           (double)chi_fail / trials, sqrt(0.05 * 0.95 / trials));
    /* 3. detection */
    for (int size = 5; size <= 20; size *= 2) {
        long det = 0, det_fam = 0, n = 0;
        for (int t = 0; t < trials; ++t) {
            noisy(&s, &rng, sig);
            int v = (int)(sc_rng_uniform(&rng) * 3), k;
            do
                k = (int)(sc_rng_uniform(&rng) * s.nn);
            while (!isfinite(s.d.dx_um[v][k]));
            s.d.dx_um[v][k] += size * sig[v];
            sc_grid_lsq_execute(qw, &s.d, 0, &s.r, NULL);
            sc_grid_lsq_residuals(qw, &s.d, &s.r, rx, ry, tx, ty, h, NULL);
            long at = (long)v * s.nn + k;
            if (!isfinite(tx[at]))
                continue; /* a mark seen once is not testable */
            n++;
            det += fabs(tx[at]) > crit_each;
            det_fam += fabs(tx[at]) > crit_fam;
        }
        printf("3. one %2d sigma outlier: detected in %.3f of %ld trials (alpha0 = %g each), "
               "%.3f (alpha = %g for all)\n",
               size, (double)det / n, n, a_each, (double)det_fam / n, SC_GRID_OUTLIER_ALPHA);
    }
    sc_grid_lsq_plan_destroy(qw), sc_grid_lsq_plan_destroy(qu);
    free(se_w), free(se_u), free(rx), free(ry), free(tx), free(ty), free(h), free(ugx), free(ugy);
    free(ubuf);
    setup_free(&s);
    sc_grid_plan_free(&pu);
    sc_grid_plan_free(&p);
}

static void big_stitched(void)
{
    sc_grid_plan p;
    if (sc_grid_plan_stitch(51, 101, 101, 1.0, 0, 0, &p, NULL) != SC_OK)
        return;
    setup s;
    setup_make(&s, &p, 3);
    double t0 = now_s(), c0 = cpu_s();
    sc_grid_lsq_plan *q = NULL;
    if (sc_grid_lsq_plan_create(&p, &s.clean, NULL, &q, NULL) != SC_OK)
        return;
    double t1 = now_s(), c1 = cpu_s();
    sc_grid_lsq_info qi;
    sc_grid_lsq_get_info(q, &qi);
    sc_grid_lsq_execute(q, &s.clean, 0.01, &s.r, NULL);
    double t2 = now_s(), c2 = cpu_s();
    double e = 0;
    for (long k = 0; k < s.ns; ++k)
        e = fmax(e, fmax(fabs(s.r.gx_um[k] - s.gx[k]), fabs(s.r.gy_um[k] - s.gy[k])));
    printf("4. stitched 101 x 101 stage, 51 x 51 plate, %d views (%ld equations): identifiable %s\n",
           p.n_views, qi.n_equations, qi.identifiable ? "yes" : "no");
    printf("   create (analysis, factorization, sigma of all %ld nodes) %.2f s wall, %.2f s CPU;\n"
           "   solve (with O, R, misalignment uncertainties) %.2f s wall, %.2f s CPU;\n"
           "   sigma_c_ratio rms %.4f max %.4f; noise-free error %.2e um\n",
           s.ns, t1 - t0, c1 - c0, t2 - t1, c2 - c1, qi.sigma_c_ratio_rms, qi.sigma_c_ratio_max, e);
    sc_grid_lsq_plan_destroy(q);
    setup_free(&s);
    sc_grid_plan_free(&p);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Counts the estimate's fallbacks by their warning: [0] did not settle, [1] ran to zero. */
static void count_fallback(void *ctx, const char *msg)
{
    long *c = ctx;
    c[0] += strstr(msg, "did not settle") != NULL;
    c[1] += strstr(msg, "runs to zero") != NULL;
}

/* 5. the noise per view on one plan: trials calibrations of data with views' noise sig. */
static void view_noise_mc(const char *name, const sc_grid_plan *plan, const double *sig,
                          int trials)
{
    int nv = plan->n_views;
    setup s;
    setup_make(&s, plan, 11);
    sc_rng rng;
    sc_rng_seed(&rng, 77);
    double *m1 = calloc(2 * (size_t)nv, sizeof(double)), *m2 = m1 + nv;
    double *pu = malloc(sizeof(double) * (size_t)trials * nv); /* stated relative u, per trial */
    double e2[3] = {0}, u2[3] = {0}; /* estimated, true stated, unweighted */
    long its = 0, fails = 0, n = 0, why[2] = {0, 0};
    double t0 = now_s();
    for (int t = 0; t < trials; ++t) {
        noisy(&s, &rng, sig);
        for (int mode = 0; mode < 3; ++mode) {
            sc_grid_options o;
            sc_grid_options_default(&o);
            o.node_sigma_only = 1;
            o.estimate_view_noise = mode == 0;
            o.warn = count_fallback, o.warn_ctx = why;
            for (int v = 0; v < nv; ++v)
                s.d.plan.view[v].sigma_um = mode == 1 ? sig[v] : 0;
            sc_grid_solution sol;
            if (sc_grid_calibrate(&s.d, NULL, NULL, &o, &sol, NULL) != SC_OK) {
                fails++;
                sc_grid_solution_free(&sol);
                continue;
            }
            const sc_grid_result *r = &sol.res;
            if (mode == 0 && !r->view_noise_estimated)
                fails++;
            else if (mode == 0) {
                its += r->view_noise_iterations;
                for (int v = 0; v < nv; ++v) {
                    double q = r->view_sigma_um[v] / sig[v];
                    m1[v] += q, m2[v] += q * q;
                    pu[n * nv + v] = r->view_sigma_u_um[v] / r->view_sigma_um[v];
                }
                n++;
            }
            for (long k = 0; k < s.ns; ++k) {
                double ex = r->gx_um[k] - s.gx[k], ey = r->gy_um[k] - s.gy[k];
                e2[mode] += ex * ex + ey * ey;
                u2[mode] += r->ugx_um[k] * r->ugx_um[k] + r->ugy_um[k] * r->ugy_um[k];
            }
            sc_grid_solution_free(&sol);
        }
    }
    double el = now_s() - t0;
    printf("5. noise per view estimated, %s, %d views, %d trials (%.1f s)\n"
           "   not estimated (stated weights kept): %ld (did not settle %ld, ran to zero %ld)\n",
           name, nv, trials, el, fails, why[0], why[1]);
    double worst_mean = 0, worst_sd = 0, ratio_lo = 1e300, ratio_hi = 0;
    for (int v = 0; v < nv; ++v) {
        double mean = m1[v] / n, sd = sqrt(fmax(0, m2[v] / n - mean * mean));
        double *col = malloc(sizeof(double) * (size_t)n);
        for (long t = 0; t < n; ++t)
            col[t] = pu[t * nv + v];
        qsort(col, (size_t)n, sizeof(double), cmp_double);
        double pred = col[n / 2]; /* the median: where F is nearly singular the stated u has a
                                     long tail */
        free(col);
        if (nv <= 4)
            printf("   view %d: sigma %.3g um, estimate/sigma mean %.3f, spread %.3f (its stated "
                   "u, median: %.3f)\n",
                   v, sig[v], mean, sd, pred);
        worst_mean = fmax(worst_mean, fabs(mean - 1));
        worst_sd = fmax(worst_sd, sd);
        ratio_lo = fmin(ratio_lo, pred / sd), ratio_hi = fmax(ratio_hi, pred / sd);
    }
    if (nv > 4)
        printf("   estimate/sigma over the views: mean within 1 +- %.3f, spread at most %.3f;\n"
               "   its stated u (median) / the spread: %.2f to %.2f over the views\n",
               worst_mean, worst_sd, ratio_lo, ratio_hi);
    printf("   %.1f re-weighted solves each; RMS error of G / its predicted u (all trials):\n",
           (double)its / n);
    static const char *lab[3] = {"estimated weights", "true weights stated", "unweighted"};
    for (int mode = 0; mode < 3; ++mode)
        printf("   %-20s %.5f um / %.5f um\n", lab[mode], sqrt(e2[mode] / (2.0 * s.ns * trials)),
               sqrt(u2[mode] / (2.0 * s.ns * trials)));
    free(pu), free(m1);
    setup_free(&s);
}

static void view_noise_bench(int trials)
{
    sc_grid_plan ye, st;
    sc_grid_plan_ye(15, 1.0, 0, 0, &ye, NULL);
    const double sig_ye[3] = {0.01, 0.03, 0.02};
    view_noise_mc("Ye N = 15", &ye, sig_ye, trials / 4 > 10 ? trials / 4 : 10);
    sc_grid_plan_stitch(15, 41, 31, 1.0, 0, 0, &st, NULL);
    double *sig_st = malloc(sizeof(double) * (size_t)st.n_views);
    for (int v = 0; v < st.n_views; ++v)
        sig_st[v] = v == 1 ? 0.02 : v == 3 ? 0.03 : v == 20 ? 0.05 : 0.01;
    view_noise_mc("stitched 41 x 31 stage, 15 x 15 plate", &st, sig_st,
                  trials / 10 > 5 ? trials / 10 : 5);
    free(sig_st);
    sc_grid_plan_free(&ye), sc_grid_plan_free(&st);
}

int main(int argc, char **argv)
{
    int trials = 400, big = 1;
    for (int a = 1; a < argc; ++a) {
        if (!strcmp(argv[a], "--trials") && a + 1 < argc)
            trials = atoi(argv[++a]);
        else if (!strcmp(argv[a], "--no-big"))
            big = 0;
    }
    if (trials < 10)
        trials = 10;
    monte_carlo(trials);
    if (big)
        big_stitched();
    view_noise_bench(trials);
    return 0;
}
