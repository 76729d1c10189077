/* Unit tests of the least-squares grid estimator against simulated truth: noise-free recovery,
 * plan analysis on known cases, noise estimate, Monte Carlo check of the predicted uncertainty,
 * bad input. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../libselfcal/src/grid/grid_lsq_internal.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "grid_lsq_reference.h"
#include "test_grid_lsq_util.h"

/* Noise-free data from a gauged truth: the estimate must equal the truth. */
static void check_recovery(int n, int kind, uint64_t seed)
{
    sc_grid_plan p;
    tu_plan(&p, n, kind);
    sc_rng r;
    sc_rng_seed(&r, seed);
    tu_truth t;
    sc_grid_data d;
    tu_truth_data(&p, &r, &t, &d);
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
    sc_grid_lsq_info info;
    sc_grid_lsq_get_info(q, &info);
    assert_int_equal(info.identifiable, 1);
    assert_int_equal(info.free_dof, 0);
    tu_res res;
    tu_res_alloc(&res, t.nn);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0.0, &res.r, &err), SC_OK);
    double eg = 0, ea = 0, em = 0, et = 0;
    for (int k = 0; k < t.nn; ++k) {
        eg = fmax(eg, fmax(fabs(res.r.gx_um[k] - t.gx[k]), fabs(res.r.gy_um[k] - t.gy[k])));
        ea = fmax(ea, fmax(fabs(res.r.ax_um[k] - t.ax[k]), fabs(res.r.ay_um[k] - t.ay[k])));
    }
    for (int v = 0; v < p.n_views; ++v) {
        em = fmax(em, fmax(fabs(res.r.tx_um[v] - t.tx[v]), fabs(res.r.ty_um[v] - t.ty[v])));
        et = fmax(et, fabs(res.r.theta_urad[v] - t.th[v]));
    }
    if (!(eg <= 1e-9 && ea <= 1e-9 && em <= 1e-9 && et <= 1e-6))
        fprintf(stderr, "N=%d plan %d: |dG| %.3g |dA| %.3g |dt| %.3g |dθ| %.3g µrad\n", n, kind,
                eg, ea, em, et);
    assert_true(eg <= 1e-9);
    assert_true(ea <= 1e-9);
    assert_true(em <= 1e-9);
    assert_true(et <= 1e-6);
    assert_true(res.r.residual_rms_um < 1e-9);
    /* the fitted model predicts every measurement (rotation included) */
    double worst = 0;
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < t.nn; ++k) {
            if (!isfinite(d.dx_um[v][k]))
                continue;
            double px, py;
            sc_grid_lsq_predict(q, &res.r, v, k / n, k % n, 0.0, &px, &py);
            assert_true(isfinite(px) && isfinite(py)); /* fmax below would pass over a NaN */
            worst = fmax(worst, fmax(fabs(px - d.dx_um[v][k]), fabs(py - d.dy_um[v][k])));
        }
    assert_true(worst < 1e-9);
    /* O and R of the gauged truth */
    double O, R;
    sc_grid_first_order(&p, t.gx, t.gy, &O, &R);
    assert_true(fabs(O - res.r.O) < 1e-12 && fabs(R - res.r.R) < 1e-12);
    for (int k = 0; k < t.nn; ++k)
        assert_true(isfinite(res.r.ugx_um[k]) || res.r.sigma_r_used_um != res.r.sigma_r_used_um);
    tu_res_free(&res);
    sc_grid_lsq_plan_destroy(q);
    tu_data_free(&d);
    tu_truth_free(&t);
    sc_grid_plan_free(&p);
}

static const int sizes[] = {5, 7, 9, 11, 25, 41};

static void test_recovery_ye(void **s)
{
    (void)s;
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; ++i)
        check_recovery(sizes[i], PLAN_YE, 100 + i);
}

static void test_recovery_petro(void **s)
{
    (void)s;
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; ++i)
        check_recovery(sizes[i], PLAN_PETRO, 200 + i);
}

static void test_recovery_rich(void **s)
{
    (void)s;
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; ++i)
        check_recovery(sizes[i], PLAN_RICH, 300 + i);
}

/* The plan's node σ and leverages (selected inverse, its whole misalignment columns, the
 * blocked solves) against solves refined with long-double residuals, at sizes the dense
 * reference (test_grid_lsq_dense) cannot reach. */
static void test_reference_accuracy(void **s)
{
    (void)s;
    const int kinds[] = {PLAN_YE, PLAN_PETRO, PLAN_RICH}, n = 61, ns = 24;
    for (int t = 0; t < 3; ++t) {
        sc_grid_plan p;
        tu_plan(&p, n, kinds[t]);
        sc_grid_lsq_plan *q = NULL;
        sc_error err;
        assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
        /* execute's solves find CHOLMOD's workspace made (sc_spsym_reserve_solve) */
        sc_rng r;
        sc_rng_seed(&r, 90 + t);
        tu_truth tr;
        sc_grid_data d;
        tu_truth_data(&p, &r, &tr, &d);
        sc_grid_result res;
        tu_res res_arrays;
        tu_res_alloc(&res_arrays, p.n * p.n);
        res = res_arrays.r;
        long made = sc_grid_lsq_workspace_made(q);
        assert_int_equal(sc_grid_lsq_execute(q, &d, 0.01, &res, &err), SC_OK);
        assert_int_equal(sc_grid_lsq_workspace_made(q), made);
        tu_res_free(&res_arrays);
        tu_data_free(&d);
        tu_truth_free(&tr);
        int node[ns];
        long eq[ns];
        double sref[ns], splan[ns], href[ns], hplan[ns];
        assert_int_equal(sc_grid_lsq_reference(q, ns, node, sref, splan, eq, href, hplan), 0);
        for (int k = 0; k < ns; ++k) {
            assert_true(sref[k] > 0 && href[k] > 0 && href[k] < 1);
            assert_true(fabs(splan[k] - sref[k]) <= 1e-10 * sref[k]);
            assert_true(fabs(hplan[k] - href[k]) <= 1e-10 * href[k]);
        }
        double vref[5 * TU_RES_VIEWS], vplan[5 * TU_RES_VIEWS];
        assert_int_equal(sc_grid_lsq_reference_misalignments(q, vref, vplan), 0);
        int compared = 0;
        for (int t = 0; t < 3 * p.n_views; ++t)
            if (!isnan(vref[t])) {
                assert_true(fabs(vplan[t] - vref[t]) <= 1e-10 * vref[t]);
                compared++;
            }
        assert_true(compared >= 3 * (p.n_views - 1)); /* the pinned view's may be 0 */
        sc_grid_lsq_plan_destroy(q);
        sc_grid_plan_free(&p);
    }
}

static long plan_free_dof(int n, int kind, int *identifiable)
{
    sc_grid_plan p;
    tu_plan(&p, n, kind);
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
    sc_grid_lsq_info info;
    sc_grid_lsq_get_info(q, &info);
    sc_grid_lsq_stats st;
    sc_grid_lsq_get_stats(q, &st);
    /* the rank decisions must have a wide margin on both sides of the tolerance (1e-9) */
    assert_true(st.min_kept_pivot_ratio > 1e-7);
    assert_true(st.max_null_pivot_ratio < 1e-12);
    *identifiable = info.identifiable;
    if (info.identifiable) {
        assert_true(info.sigma_c_ratio_rms > 0 && info.sigma_c_ratio_max >= info.sigma_c_ratio_rms);
    } else {
        assert_true(isnan(info.sigma_c_ratio_rms));
        assert_int_equal(sc_grid_lsq_sigma_ratio(q, NULL, NULL, &err), SC_E_UNSOLVABLE);
    }
    sc_grid_lsq_plan_destroy(q);
    sc_grid_plan_free(&p);
    return info.free_dof;
}

static void test_plan_cases(void **s)
{
    (void)s;
    const int ns[] = {5, 7, 9, 11, 15};
    for (size_t i = 0; i < sizeof ns / sizeof *ns; ++i) {
        int n = ns[i], id;
        assert_int_equal(plan_free_dof(n, PLAN_YE, &id), 0);
        assert_int_equal(id, 1);
        assert_int_equal(plan_free_dof(n, PLAN_PETRO, &id), 0);
        assert_int_equal(id, 1);
        assert_int_equal(plan_free_dof(n, PLAN_RICH, &id), 0);
        assert_int_equal(id, 1);
        long k0 = plan_free_dof(n, PLAN_0_90, &id);
        assert_int_equal(id, 0);
        assert_true(k0 > 0);
        long k1 = plan_free_dof(n, PLAN_0_180_1X, &id);
        assert_int_equal(id, 0);
        assert_true(k1 > 0);
        long k2 = plan_free_dof(n, PLAN_0_90_2X, &id);
        fprintf(stderr, "N=%2d: free dof {0,90}: %ld  {0,180,+1x}: %ld  {0,90,+2x}: %ld\n", n, k0,
                k1, k2);
        /* a 2-pitch x shift alone is blind to patterns G(i) of the row and to (-1)^j column
         * parity, but the 90° view sees both: least squares identifies G without view 3 */
        assert_int_equal(id, 1);
        assert_int_equal(k2, 0);
        /* {0,90}: every G with G(Rk) = Rot G(k) up to a rigid motion stays free */
        assert_int_equal(k0, (long)(n * n - 5) / 2);
        assert_int_equal(k1, n - 1);
        /* without a rotation O and R are invisible: shifts see only differences of neighbours,
         * and O·(y, x), R·(x, -y) change by a constant per shift */
        assert_int_equal(plan_free_dof(n, PLAN_SHIFTS, &id), 2);
        assert_int_equal(id, 0);
    }
}

/* With noise: σ_r estimated from the residuals, and uncertainties scale with the σ_r used. */
static void test_sigma_estimate(void **s)
{
    (void)s;
    int kinds[] = {PLAN_YE, PLAN_PETRO, PLAN_RICH};
    for (int c = 0; c < 3; ++c) {
        sc_grid_plan p;
        tu_truth t;
        sc_grid_data d;
        tu_noisy_case(&p, 25, kinds[c], 77 + c, 0.05, &t, &d);
        sc_grid_lsq_plan *q = NULL;
        sc_error err;
        assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
        tu_res res;
        tu_res_alloc(&res, t.nn);
        assert_int_equal(sc_grid_lsq_execute(q, &d, 0.0, &res.r, &err), SC_OK);
        /* dof ≈ 600..2500 here: the estimate is within a few per cent */
        fprintf(stderr, "N=25 plan %d: sigma_r estimate %.5f (true 0.05), dof %ld\n", kinds[c],
                res.r.sigma_r_est_um, res.r.dof);
        assert_true(res.r.dof > 100);
        assert_true(fabs(res.r.sigma_r_est_um / 0.05 - 1) < 0.08);
        assert_true(res.r.sigma_r_used_um == res.r.sigma_r_est_um);
        /* exactly the residuals' sum of squares (every equation's, from sc_grid_lsq_residuals) */
        size_t tot = (size_t)p.n_views * t.nn;
        double *rx = malloc(sizeof(double) * tot), *ry = malloc(sizeof(double) * tot), rss = 0;
        long cnt = 0;
        assert_int_equal(sc_grid_lsq_residuals(q, &d, &res.r, rx, ry, NULL, NULL, NULL, &err), SC_OK);
        for (size_t k = 0; k < tot; ++k)
            if (isfinite(rx[k]))
                rss += rx[k] * rx[k] + ry[k] * ry[k], cnt += 2;
        assert_int_equal(cnt, res.r.n_measurements);
        assert_true(fabs(res.r.sigma_r_est_um * res.r.sigma_r_est_um * res.r.dof / rss - 1) < 1e-9);
        assert_true(fabs(res.r.residual_rms_um * res.r.residual_rms_um * cnt / rss - 1) < 1e-9);
        free(rx), free(ry);
        double u_est = res.r.ugx_um[3];
        assert_int_equal(sc_grid_lsq_execute(q, &d, 0.2, &res.r, &err), SC_OK);
        assert_true(res.r.sigma_r_used_um == 0.2);
        assert_true(fabs(res.r.ugx_um[3] / u_est - 0.2 / res.r.sigma_r_est_um) < 1e-12);
        tu_res_free(&res);
        sc_grid_lsq_plan_destroy(q);
        tu_data_free(&d);
        tu_truth_free(&t);
        sc_grid_plan_free(&p);
    }
}

/* max_bytes: a plan estimated to need more memory is refused before it is factored, saying how
 * much; one allowed about twice what it holds is made (the estimate is near the real peak). */
static void test_memory_limit(void **s)
{
    (void)s;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_stitch_step(33, 129, 129, 32, 1.0, 0, 0, &p, &err), SC_OK);
    sc_grid_lsq_plan *q = NULL;
    /* the reduced matrix's estimates (A kept: test_grid_lsq_full) */
    sc_grid_lsq_opts free_opts = {.node_sigma_only = 1, .solver = SC_GRID_SOLVER_REDUCED};
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &free_opts, &q, &err), SC_OK);
    sc_grid_lsq_stats st;
    sc_grid_lsq_get_stats(q, &st);
    sc_grid_lsq_plan_destroy(q);
    q = NULL;
    sc_grid_lsq_opts tight = {.node_sigma_only = 1, .max_bytes = (double)st.bytes / 3,
                              .solver = SC_GRID_SOLVER_REDUCED};
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &tight, &q, &err), SC_E_NOMEM);
    assert_null(q);
    assert_non_null(strstr(err.msg, "needs about"));
    assert_non_null(strstr(err.msg, "33336 unknowns"));
    sc_grid_lsq_opts room = {.node_sigma_only = 1, .max_bytes = 2.0 * (double)st.bytes,
                             .solver = SC_GRID_SOLVER_REDUCED};
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &room, &q, &err), SC_OK);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_plan_free(&p);
}

/* node_sigma_only: the same estimate, node σ and leverages to the last bit (W is solved alone in
 * both modes), only the σ of O, R and the misalignments left out (NaN); the default gives them. */
static void test_node_sigma_only(void **s)
{
    (void)s;
    int kinds[] = {PLAN_YE, PLAN_PETRO, PLAN_RICH};
    for (int c = 0; c < 3; ++c) {
        sc_grid_plan p;
        tu_truth t;
        sc_grid_data d; /* N = 41: large enough that 4 and 9 columns solve differently */
        tu_noisy_case(&p, 41, kinds[c], 55 + c, 0.05, &t, &d);
        sc_grid_lsq_plan *q[2] = {NULL, NULL};
        sc_error err;
        sc_grid_lsq_opts opts[2] = {{.node_sigma_only = 0}, {.node_sigma_only = 1}};
        tu_res res[2];
        size_t tot = (size_t)p.n_views * t.nn;
        double *rt[2];
        for (int m = 0; m < 2; ++m) {
            assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &opts[m], &q[m], &err), SC_OK);
            tu_res_alloc(&res[m], t.nn);
            assert_int_equal(sc_grid_lsq_execute(q[m], &d, 0.0, &res[m].r, &err), SC_OK);
            rt[m] = malloc(sizeof(double) * 3 * tot);
            assert_non_null(rt[m]);
            assert_int_equal(sc_grid_lsq_residuals(q[m], &d, &res[m].r, NULL, NULL, rt[m],
                                                   rt[m] + tot, rt[m] + 2 * tot, &err), SC_OK);
        }
        assert_memory_equal(res[0].buf, res[1].buf, sizeof(double) * 6 * t.nn); /* G, u, A */
        assert_memory_equal(rt[0], rt[1], sizeof(double) * 3 * tot); /* t and leverages */
        assert_true(res[0].r.sigma_r_est_um == res[1].r.sigma_r_est_um);
        assert_true(isfinite(res[0].r.uO) && isfinite(res[0].r.uR) && res[0].r.uO > 0);
        assert_true(isnan(res[1].r.uO) && isnan(res[1].r.uR));
        for (int v = 0; v < p.n_views; ++v) {
            assert_true(res[0].r.tx_um[v] == res[1].r.tx_um[v]);
            assert_true(res[0].r.theta_urad[v] == res[1].r.theta_urad[v]);
            assert_true(isfinite(res[0].r.utx_um[v]) && isfinite(res[0].r.utheta_urad[v]));
            assert_true(isnan(res[1].r.utx_um[v]) && isnan(res[1].r.uty_um[v]) &&
                        isnan(res[1].r.utheta_urad[v]));
        }
        for (int m = 0; m < 2; ++m) {
            free(rt[m]);
            tu_res_free(&res[m]);
            sc_grid_lsq_plan_destroy(q[m]);
        }
        tu_data_free(&d);
        tu_truth_free(&t);
        sc_grid_plan_free(&p);
    }
}

/* The plan's summary of std(G) is that of its per-node values (sc_grid_lsq_sigma_ratio): the
 * RMS and the largest, also when every node is below 1 (stated uncertainties of 0.01 µm: std(G)
 * in µm) and with none stated (ratios to σ_r). */
static void test_sigma_ratio_summary(void **s)
{
    (void)s;
    const int n = 9, nn = n * n;
    for (int weighted = 0; weighted < 2; ++weighted) {
        sc_grid_plan p;
        tu_plan(&p, n, PLAN_RICH);
        for (int v = 0; weighted && v < p.n_views; ++v)
            p.view[v].sigma_um = 0.01;
        sc_grid_lsq_plan *q = NULL;
        sc_error err;
        assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
        sc_grid_lsq_info info;
        sc_grid_lsq_get_info(q, &info);
        assert_int_equal(info.weighted, weighted);
        double *sgx = malloc(sizeof(double) * nn), *sgy = malloc(sizeof(double) * nn);
        assert_int_equal(sc_grid_lsq_sigma_ratio(q, sgx, sgy, &err), SC_OK);
        double mx = 0, ss = 0;
        for (int k = 0; k < nn; ++k) {
            mx = fmax(mx, fmax(sgx[k], sgy[k]));
            ss += sgx[k] * sgx[k] + sgy[k] * sgy[k];
        }
        if (weighted)
            assert_true(mx < 0.1); /* std(G) in µm, of the order of the 0.01 µm stated */
        assert_true(info.sigma_c_ratio_max == mx);
        assert_true(fabs(info.sigma_c_ratio_rms - sqrt(ss / (2 * nn))) <= 1e-12 * info.sigma_c_ratio_rms);
        free(sgx), free(sgy);
        sc_grid_lsq_plan_destroy(q);
        sc_grid_plan_free(&p);
    }
}

/* The peak memory reported before the assembly (the plan's estimate, progress and --max-memory)
 * holds at least the dense node-misalignment block and the pairs of stage unknowns each plate
 * mark component couples: k views seeing it, k(k+1)/2 entries of 12 bytes held twice (16
 * views: k above 12). The work is counted once the factor
 * has (the sparse solver counts it while factoring): the solve's report is all of it, > 0. */
typedef struct peak_log {
    double first;      /* the peak of the first report (the assembly's: the plan's estimate) */
    double done, total; /* the work of the last report */
    int calls;
} peak_log;

static void record_peak(void *ctx, const char *phase, double done, double total, double peak)
{
    (void)phase;
    peak_log *l = ctx;
    if (l->calls == 0)
        l->first = peak;
    l->done = done, l->total = total;
    l->calls++;
}

static void test_peak_estimate(void **s)
{
    (void)s;
    const int n = 9, nn = n * n, nv = 16;
    sc_grid_plan p;
    memset(&p, 0, sizeof p);
    p.n = n;
    p.pitch_mm = 2.5;
    for (int v = 0; v < nv; ++v) /* the four rotations at four shifts */
        tu_add_view(&p, 90 * (v % 4), (v / 4) % 2, v / 8);
    sc_grid_lsq_opts o;
    memset(&o, 0, sizeof o);
    peak_log l = {0, 0, 0, 0};
    o.progress = record_peak;
    o.progress_ctx = &l;
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &o, &q, &err), SC_OK);
    sc_grid_lsq_info info;
    sc_grid_lsq_get_info(q, &info);
    assert_int_equal(info.identifiable, 1);
    /* Σ k(k+1)/2 over the 2 nn mark components, k summing to the equations: at least its value
     * for equal k (convexity) */
    const double nm = 3.0 * nv, ne = (double)info.n_equations, ka = ne / (2.0 * nn);
    const double pairs = 2.0 * nn * ka * (ka + 1) / 2;
    const double ng = (double)info.n_unknowns - 2 * nn - nm; /* the stage's nodes, both axes */
    assert_true(ng >= 2 * nn && ka > 12);
    const double bound = 8 * ng * nm + 2 * 12 * (pairs + ng);
    assert_true(l.calls > 0);
    assert_true(l.first >= bound);
    /* a solve: the last report is the whole work, counted by the factor */
    sc_rng r;
    sc_rng_seed(&r, 43);
    sc_grid_data d;
    tu_data_alloc(&d, &p);
    tu_truth t;
    tu_truth_make(&t, &p, &r);
    sc_grid_synthesize(&p, t.gx, t.gy, t.ax, t.ay, t.tx, t.ty, t.th, &d);
    tu_res res;
    tu_res_alloc(&res, nn);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0.01, &res.r, &err), SC_OK);
    assert_true(l.total > 0 && l.done == l.total);
    tu_truth_free(&t);
    tu_res_free(&res);
    tu_data_free(&d);
    /* and a limit below it refuses the plan before anything is assembled */
    o.progress = NULL;
    o.max_bytes = bound / 2;
    sc_grid_lsq_plan *q2 = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &o, &q2, &err), SC_E_NOMEM);
    assert_non_null(strstr(err.msg, "needs about"));
    assert_null(q2);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_plan_free(&p);
}

/* Monte Carlo: the empirical per-node std of G equals the predicted one. */
static void test_monte_carlo(void **s)
{
    (void)s;
    const int n = 9, runs = 300;
    const double sigma = 0.1;
    int kinds[] = {PLAN_PETRO, PLAN_YE};
    for (int c = 0; c < 2; ++c) {
        sc_grid_plan p;
        tu_plan(&p, n, kinds[c]);
        int nn = n * n;
        sc_grid_lsq_plan *q = NULL;
        sc_error err;
        assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
        double *sgx = malloc(sizeof(double) * nn), *sgy = malloc(sizeof(double) * nn);
        double *acc = calloc(2 * nn, sizeof(double));
        assert_int_equal(sc_grid_lsq_sigma_ratio(q, sgx, sgy, &err), SC_OK);
        sc_rng r;
        sc_rng_seed(&r, 4242 + c);
        sc_grid_data d;
        tu_data_alloc(&d, &p);
        tu_res res;
        tu_res_alloc(&res, nn);
        double est_sum = 0;
        for (int run = 0; run < runs; ++run) {
            tu_truth t;
            tu_truth_make(&t, &p, &r);
            sc_grid_synthesize(&p, t.gx, t.gy, t.ax, t.ay, t.tx, t.ty, t.th, &d);
            tu_add_noise(&d, sigma, &r);
            assert_int_equal(sc_grid_lsq_execute(q, &d, sigma, &res.r, &err), SC_OK);
            for (int k = 0; k < nn; ++k) {
                double ex = res.r.gx_um[k] - t.gx[k], ey = res.r.gy_um[k] - t.gy[k];
                acc[2 * k] += ex * ex;
                acc[2 * k + 1] += ey * ey;
            }
            est_sum += res.r.sigma_r_est_um;
            tu_truth_free(&t);
        }
        double sp = 0, se = 0, worst = 0;
        int beyond10 = 0;
        for (int k = 0; k < nn; ++k)
            for (int cc = 0; cc < 2; ++cc) {
                double pred = sigma * (cc ? sgy[k] : sgx[k]);
                double emp = sqrt(acc[2 * k + cc] / runs);
                sp += pred * pred;
                se += emp * emp;
                double rel = fabs(emp / pred - 1);
                worst = fmax(worst, rel);
                beyond10 += rel > 0.10;
            }
        double rms_rel = sqrt(se / sp) - 1;
        fprintf(stderr, "MC N=%d plan %d: RMS empirical/predicted - 1 = %+.4f, worst node %.3f, "
                        "%d of %d beyond 10%%, mean σ_r est %.4f\n",
                n, kinds[c], rms_rel, worst, beyond10, 2 * nn, est_sum / runs);
        /* 300 runs: per-node relative SE of a std ≈ 4 %; over 162 components */
        assert_true(fabs(rms_rel) < 0.03);
        assert_true(worst < 0.16);
        assert_true(beyond10 <= 2 * nn / 10);
        assert_true(fabs(est_sum / runs / sigma - 1) < 0.03);
        tu_res_free(&res);
        tu_data_free(&d);
        free(sgx), free(sgy), free(acc);
        sc_grid_lsq_plan_destroy(q);
        sc_grid_plan_free(&p);
    }
}

/* A data set measured on a subset of marks: an estimator made with it as the mask recovers G;
 * unmeasured marks get NaN plate errors. */
static void test_mask_subset(void **s)
{
    (void)s;
    int n = 11, nn = n * n;
    sc_grid_plan p;
    tu_plan(&p, n, PLAN_RICH);
    sc_rng r;
    sc_rng_seed(&r, 9);
    tu_truth t;
    sc_grid_data d;
    tu_truth_data(&p, &r, &t, &d);
    /* drop ~10 % of the measurements at random, and mark 0 from every view */
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < nn; ++k)
            if (k == 0 || sc_rng_uniform(&r) < 0.1)
                d.dx_um[v][k] = d.dy_um[v][k] = NAN;
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, &d, NULL, &q, &err), SC_OK);
    sc_grid_lsq_info info;
    sc_grid_lsq_get_info(q, &info);
    assert_int_equal(info.identifiable, 1);
    tu_res res;
    tu_res_alloc(&res, nn);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_OK);
    double eg = 0;
    for (int k = 0; k < nn; ++k)
        eg = fmax(eg, fmax(fabs(res.r.gx_um[k] - t.gx[k]), fabs(res.r.gy_um[k] - t.gy[k])));
    assert_true(eg < 1e-9);
    assert_true(isnan(res.r.ax_um[0]) && isnan(res.r.ay_um[0]));
    /* A is in its gauge over the measured marks: compare with the truth regauged there */
    double sx = 0, sy = 0, srot = 0;
    for (int k = 1; k < nn; ++k) {
        double x, y;
        sc_grid_node_xy_mm(&p, k / n, k % n, &x, &y);
        assert_true(isfinite(res.r.ax_um[k]));
        sx += res.r.ax_um[k], sy += res.r.ay_um[k];
        srot += x * res.r.ay_um[k] - y * res.r.ax_um[k];
    }
    assert_true(fabs(sx) < 1e-9 && fabs(sy) < 1e-9 && fabs(srot) < 1e-9);
    /* the truth regauged over the measured marks (a rigid motion fitted and removed) */
    double m3[3][3] = {{0}}, rh[3] = {0};
    for (int k = 1; k < nn; ++k) {
        double x, y;
        sc_grid_node_xy_mm(&p, k / n, k % n, &x, &y);
        double bx[3] = {1, 0, -y}, by[3] = {0, 1, x};
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b)
                m3[a][b] += bx[a] * bx[b] + by[a] * by[b];
            rh[a] += bx[a] * t.ax[k] + by[a] * t.ay[k];
        }
    }
    /* solve the 3x3 by Cramer's rule */
    double det = m3[0][0] * (m3[1][1] * m3[2][2] - m3[1][2] * m3[2][1]) -
                 m3[0][1] * (m3[1][0] * m3[2][2] - m3[1][2] * m3[2][0]) +
                 m3[0][2] * (m3[1][0] * m3[2][1] - m3[1][1] * m3[2][0]);
    double sol[3];
    for (int c = 0; c < 3; ++c) {
        double m[3][3];
        memcpy(m, m3, sizeof m);
        for (int a = 0; a < 3; ++a)
            m[a][c] = rh[a];
        sol[c] = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                  m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                  m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])) / det;
    }
    double ea = 0;
    for (int k = 1; k < nn; ++k) {
        double x, y;
        sc_grid_node_xy_mm(&p, k / n, k % n, &x, &y);
        ea = fmax(ea, fabs(res.r.ax_um[k] - (t.ax[k] - sol[0] + sol[2] * y)));
        ea = fmax(ea, fabs(res.r.ay_um[k] - (t.ay[k] - sol[1] - sol[2] * x)));
    }
    assert_true(ea < 1e-9);
    tu_res_free(&res);
    sc_grid_lsq_plan_destroy(q);
    tu_data_free(&d);
    tu_truth_free(&t);
    sc_grid_plan_free(&p);
}

static void test_bad_input(void **s)
{
    (void)s;
    int n = 9, nn = n * n;
    sc_grid_plan p;
    tu_plan(&p, n, PLAN_YE);
    sc_rng r;
    sc_rng_seed(&r, 5);
    tu_truth t;
    sc_grid_data d;
    tu_truth_data(&p, &r, &t, &d);
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
    tu_res res;
    tu_res_alloc(&res, nn);
    /* a measured mark missing */
    double keep = d.dx_um[1][40];
    d.dx_um[1][40] = d.dy_um[1][40] = NAN;
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "view 1"));
    d.dx_um[1][40] = keep;
    /* only one component */
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_E_INPUT);
    sc_grid_synthesize(&p, t.gx, t.gy, t.ax, t.ay, t.tx, t.ty, t.th, &d);
    /* a mark the shifted view cannot see (column N-1 falls off the grid) given a value */
    assert_true(isnan(d.dx_um[2][n - 1]));
    d.dx_um[2][n - 1] = d.dy_um[2][n - 1] = 0.5;
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_E_INPUT);
    sc_grid_lsq_plan *q2 = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&p, &d, NULL, &q2, &err), SC_E_INPUT);
    assert_null(q2);
    sc_grid_synthesize(&p, t.gx, t.gy, t.ax, t.ay, t.tx, t.ty, t.th, &d);
    /* a different view in the data */
    d.plan.view[2].shift_x = 2;
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_E_INPUT);
    d.plan.view[2].shift_x = 1;
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_OK);
    /* bad plans */
    sc_grid_plan bad = {0};
    assert_int_equal(sc_grid_plan_copy(&bad, &p, NULL), SC_OK);
    bad.n = 8;
    assert_int_equal(sc_grid_lsq_plan_create(&bad, NULL, NULL, &q2, &err), SC_E_INPUT);
    assert_int_equal(sc_grid_plan_copy(&bad, &p, NULL), SC_OK);
    bad.view[1].rot_deg = 45;
    assert_int_equal(sc_grid_lsq_plan_create(&bad, NULL, NULL, &q2, &err), SC_E_INPUT);
    sc_grid_plan_free(&bad);
    sc_grid_lsq_plan_destroy(q);
    /* a plan that does not identify G: made, but solve refuses */
    sc_grid_plan p2;
    tu_plan(&p2, n, PLAN_0_90);
    sc_grid_data d2;
    tu_data_alloc(&d2, &p2);
    sc_grid_synthesize(&p2, t.gx, t.gy, t.ax, t.ay, t.tx, t.ty, t.th, &d2);
    assert_int_equal(sc_grid_lsq_plan_create(&p2, NULL, NULL, &q, &err), SC_OK);
    assert_int_equal(sc_grid_lsq_execute(q, &d2, 0, &res.r, &err), SC_E_UNSOLVABLE);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_lsq_plan_destroy(NULL);
    tu_data_free(&d2);
    tu_res_free(&res);
    tu_data_free(&d);
    tu_truth_free(&t);
    sc_grid_plan_free(&p);
    sc_grid_plan_free(&p2);
}

/* A plan with a never-measured stage node leaves that node's G free (2 patterns). */
static void test_unmeasured_node(void **s)
{
    (void)s;
    int n = 7, nn = n * n;
    sc_grid_plan p;
    tu_plan(&p, n, PLAN_YE);
    sc_grid_data m;
    tu_data_alloc(&m, &p);
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < nn; ++k)
            m.dx_um[v][k] = m.dy_um[v][k] = sc_grid_view_measures(&p, v, k / n, k % n) ? 0 : NAN;
    /* node (3,3) is hit by mark (3,3) in views 0 and 90 and by mark (3,2) in the shifted view */
    m.dx_um[0][24] = m.dy_um[0][24] = NAN;
    m.dx_um[1][24] = m.dy_um[1][24] = NAN;
    m.dx_um[2][23] = m.dy_um[2][23] = NAN;
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, &m, NULL, &q, &err), SC_OK);
    sc_grid_lsq_info info;
    sc_grid_lsq_get_info(q, &info);
    assert_int_equal(info.identifiable, 0);
    assert_int_equal(info.free_dof, 2);
    sc_grid_lsq_plan_destroy(q);
    tu_data_free(&m);
    sc_grid_plan_free(&p);
}

/* A view measuring a single mark: its misalignment is not determined (3 unknowns, 2 equations),
 * but G is, and is recovered; the view's misalignment is reported NaN. */
static void test_undetermined_view(void **s)
{
    (void)s;
    int n = 9, nn = n * n, c = (n - 1) / 2;
    sc_grid_plan p;
    tu_plan(&p, n, PLAN_YE);
    tu_add_view(&p, 180, 0, 0);
    sc_rng r;
    sc_rng_seed(&r, 12);
    tu_truth t;
    sc_grid_data d;
    tu_truth_data(&p, &r, &t, &d);
    for (int k = 0; k < nn; ++k)
        if (k != c * n + c + 1)
            d.dx_um[3][k] = d.dy_um[3][k] = NAN;
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, &d, NULL, &q, &err), SC_OK);
    sc_grid_lsq_info info;
    sc_grid_lsq_stats st;
    sc_grid_lsq_get_info(q, &info);
    sc_grid_lsq_get_stats(q, &st);
    assert_int_equal(info.identifiable, 1);
    assert_int_equal(st.nullity_misalignment, 4);
    tu_res res;
    tu_res_alloc(&res, nn);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0.01, &res.r, &err), SC_OK);
    double eg = 0;
    for (int k = 0; k < nn; ++k)
        eg = fmax(eg, fmax(fabs(res.r.gx_um[k] - t.gx[k]), fabs(res.r.gy_um[k] - t.gy[k])));
    assert_true(eg < 1e-9);
    assert_true(isnan(res.r.tx_um[3]) && isnan(res.r.theta_urad[3]));
    assert_true(fabs(res.r.tx_um[2] - t.tx[2]) < 1e-9);
    /* the uncertainties equal those of Ye's plan alone: the extra view adds no information */
    sc_grid_plan pye;
    tu_plan(&pye, n, PLAN_YE);
    sc_grid_lsq_plan *qy = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&pye, NULL, NULL, &qy, &err), SC_OK);
    double *sx = malloc(sizeof(double) * nn), *sy = malloc(sizeof(double) * nn);
    assert_int_equal(sc_grid_lsq_sigma_ratio(qy, sx, sy, &err), SC_OK);
    for (int k = 0; k < nn; ++k) {
        assert_true(fabs(res.r.ugx_um[k] - 0.01 * sx[k]) < 1e-12);
        assert_true(fabs(res.r.ugy_um[k] - 0.01 * sy[k]) < 1e-12);
    }
    free(sx), free(sy);
    sc_grid_lsq_plan_destroy(qy);
    tu_res_free(&res);
    sc_grid_lsq_plan_destroy(q);
    tu_data_free(&d);
    tu_truth_free(&t);
    sc_grid_plan_free(&p);
    sc_grid_plan_free(&pye);
}

/* The χ² test of a fit with a stated σ_r: its acceptance interval is the two-sided 95 % one, the
 * 2.5 % and 97.5 % quantiles at the fit's dof divided by the dof, and the verdict follows it. A
 * variance factor between the 95 % and the 97.5 % quantile (and one between 2.5 % and 5 %) passes;
 * one just outside either bound fails. The variance factor is RSS / dof / σ_r², so each case is
 * made by choosing the σ_r stated for the same data. */
static void test_chi2_bounds(void **s)
{
    (void)s;
    sc_grid_plan p;
    tu_truth t;
    sc_grid_data d;
    tu_noisy_case(&p, 11, PLAN_YE, 4242, 0.05, &t, &d);
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
    tu_res res;
    tu_res_alloc(&res, t.nn);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 1.0, &res.r, &err), SC_OK);
    long dof = res.r.dof;
    assert_true(dof > 50);
    double vf1 = res.r.variance_factor; /* at σ_r = 1 µm: RSS / dof */
    assert_true(vf1 > 0);
    double k = (double)dof;
    double q025 = sc_chi2_quantile(0.025, k) / k, q05 = sc_chi2_quantile(0.05, k) / k;
    double q95 = sc_chi2_quantile(0.95, k) / k, q975 = sc_chi2_quantile(0.975, k) / k;
    /* the quantiles themselves, against tables at 100 dof (the interval 0.7422..1.2956) */
    assert_true(fabs(sc_chi2_quantile(0.025, 100) - 74.2219) < 2e-3);
    assert_true(fabs(sc_chi2_quantile(0.975, 100) - 129.5612) < 2e-3);
    assert_true(q025 < q05 && q05 < 1 && 1 < q95 && q95 < q975);
    const struct {
        double vf;
        int pass;
    } cases[] = {
        {0.5 * (q95 + q975), 1}, {0.5 * (q025 + q05), 1}, {1.0, 1},
        {q975 * 1.01, 0},        {q025 * 0.99, 0},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        double sigma = sqrt(vf1 / cases[c].vf);
        assert_int_equal(sc_grid_lsq_execute(q, &d, sigma, &res.r, &err), SC_OK);
        assert_int_equal(res.r.dof, dof);
        assert_true(fabs(res.r.variance_factor / cases[c].vf - 1) < 1e-9);
        assert_true(fabs(res.r.chi2_lo / q025 - 1) < 1e-12);
        assert_true(fabs(res.r.chi2_hi / q975 - 1) < 1e-12);
        if (res.r.chi2_pass != cases[c].pass)
            fprintf(stderr, "dof %ld: variance factor %.4f in [%.4f, %.4f]: pass %d, expected %d\n",
                    dof, res.r.variance_factor, res.r.chi2_lo, res.r.chi2_hi, res.r.chi2_pass,
                    cases[c].pass);
        assert_int_equal(res.r.chi2_pass, cases[c].pass);
    }
    tu_res_free(&res);
    sc_grid_lsq_plan_destroy(q);
    tu_data_free(&d);
    tu_truth_free(&t);
    sc_grid_plan_free(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_recovery_ye),    cmocka_unit_test(test_recovery_petro),
        cmocka_unit_test(test_recovery_rich),  cmocka_unit_test(test_plan_cases),
        cmocka_unit_test(test_reference_accuracy),
        cmocka_unit_test(test_sigma_estimate), cmocka_unit_test(test_node_sigma_only),
        cmocka_unit_test(test_memory_limit),
        cmocka_unit_test(test_sigma_ratio_summary),
        cmocka_unit_test(test_peak_estimate),
        cmocka_unit_test(test_monte_carlo),
        cmocka_unit_test(test_mask_subset),    cmocka_unit_test(test_bad_input),
        cmocka_unit_test(test_unmeasured_node), cmocka_unit_test(test_undetermined_view),
        cmocka_unit_test(test_chi2_bounds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
