/* Grid least squares with the plate unknowns kept (issue 33, grid_lsq_full.c): the full solver
 * gives the reduced one's results (G, A, misalignments, every σ, leverages, residuals) to 1e-9
 * relative where both run; the automatic choice; the sampled node σ against the plan's exact
 * ones and against refined solves; SC_GRID_NODE_SIGMA_NONE. The large case (401², 41-mark plate,
 * hundreds of placements) is test_grid_lsq_large. */
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
#include "grid_lsq_reference.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/rng.h"

typedef struct run {
    sc_grid_result r;
    double *buf;
    double *rx, *ry, *tx, *ty, *h;
} run;

/* Data of a random G, A and misalignments on plan p, with noise sigma (0: none). */
static void make_data(sc_grid_data *d, const sc_grid_plan *p, double sigma, uint64_t seed,
                      int with_time)
{
    sc_rng r;
    sc_rng_seed(&r, seed);
    long ns = sc_grid_stage_nodes(p), nn = (long)p->n * p->n;
    int nv = p->n_views;
    double *gx = malloc(sizeof(double) * ns), *gy = malloc(sizeof(double) * ns);
    double *ax = malloc(sizeof(double) * nn), *ay = malloc(sizeof(double) * nn);
    double *tx = malloc(sizeof(double) * 3 * nv), *ty = tx + nv, *th = ty + nv;
    for (long k = 0; k < ns; ++k)
        gx[k] = sc_rng_normal(&r), gy[k] = sc_rng_normal(&r);
    for (long k = 0; k < nn; ++k)
        ax[k] = sc_rng_normal(&r), ay[k] = sc_rng_normal(&r);
    for (int v = 0; v < nv; ++v)
        tx[v] = 2 * sc_rng_normal(&r), ty[v] = 2 * sc_rng_normal(&r), th[v] = 30 * sc_rng_normal(&r);
    memset(d, 0, sizeof *d);
    assert_int_equal(sc_grid_plan_copy(&d->plan, p, NULL), SC_OK);
    assert_int_equal(sc_grid_data_alloc(d, NULL), SC_OK);
    assert_int_equal(sc_grid_data_alloc_extra(d, 0, with_time, NULL), SC_OK);
    sc_grid_synthesize(p, gx, gy, ax, ay, tx, ty, th, d);
    for (int v = 0; v < nv; ++v)
        for (long k = 0; k < nn; ++k) {
            if (!isfinite(d->dx_um[v][k]))
                continue;
            d->dx_um[v][k] += sigma * sc_rng_normal(&r);
            d->dy_um[v][k] += sigma * sc_rng_normal(&r);
            if (with_time) /* a drift of 0.01 µm/s, the marks of a view in random order */
                d->t_s[v][k] = (double)(v * nn) + (double)nn * sc_rng_uniform(&r),
                d->dx_um[v][k] += 0.01 * d->t_s[v][k];
        }
    free(gx), free(gy), free(ax), free(ay), free(tx);
}

static void run_solve(run *o, const sc_grid_plan *p, const sc_grid_data *d,
                      const sc_grid_lsq_opts *opts, sc_grid_lsq_stats *st)
{
    long ns = sc_grid_stage_nodes(p), nn = (long)p->n * p->n, m = nn * p->n_views;
    memset(o, 0, sizeof *o);
    o->buf = malloc(sizeof(double) * (4 * ns + 2 * nn + 5 * m));
    o->r.gx_um = o->buf, o->r.gy_um = o->buf + ns, o->r.ugx_um = o->buf + 2 * ns;
    o->r.ugy_um = o->buf + 3 * ns, o->r.ax_um = o->buf + 4 * ns, o->r.ay_um = o->buf + 4 * ns + nn;
    o->rx = o->buf + 4 * ns + 2 * nn, o->ry = o->rx + m, o->tx = o->ry + m, o->ty = o->tx + m;
    o->h = o->ty + m;
    assert_int_equal(sc_grid_result_views(&o->r, p->n_views, NULL), SC_OK);
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    sc_status rc = sc_grid_lsq_plan_create(p, d, opts, &q, &err);
    if (rc != SC_OK)
        fprintf(stderr, "plan: %s\n", err.msg);
    assert_int_equal(rc, SC_OK);
    sc_grid_lsq_get_stats(q, st);
    rc = sc_grid_lsq_execute(q, d, 0, &o->r, &err);
    if (rc != SC_OK)
        fprintf(stderr, "execute: %s\n", err.msg);
    assert_int_equal(rc, SC_OK);
    assert_int_equal(sc_grid_lsq_residuals(q, d, &o->r, o->rx, o->ry, o->tx, o->ty, o->h, &err),
                     SC_OK);
    sc_grid_lsq_plan_destroy(q);
}

static void run_free(run *o)
{
    free(o->buf);
    sc_grid_result_free_views(&o->r);
}

/* max |a − b| over n entries, relative to max |a|; NaN in both places agrees. */
static double rel_diff(const double *a, const double *b, long n)
{
    double d = 0, s = 0;
    for (long k = 0; k < n; ++k) {
        if (isnan(a[k]) || isnan(b[k])) {
            assert_true(isnan(a[k]) && isnan(b[k]));
            continue;
        }
        d = fmax(d, fabs(a[k] - b[k]));
        s = fmax(s, fabs(a[k]));
    }
    return s > 0 ? d / s : d;
}

static double rel1(double a, double b)
{
    if (isnan(a) || isnan(b)) {
        assert_true(isnan(a) && isnan(b));
        return 0;
    }
    return fabs(a - b) / fmax(fabs(a), 1e-300);
}

/* The misalignment block's nullity (ν₂) the dense way (sc_lsq_small_nullity) and from the sparse
 * factor of the block bordered by A: the same count. */
static int check_nullity_rules(const sc_grid_plan *p, const sc_grid_data *d, int drift)
{
    sc_grid_lsq_opts o = {.drift = drift, .solver = SC_GRID_SOLVER_FULL};
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    sc_status rc = sc_grid_lsq_plan_create(p, d, &o, &q, &err);
    if (rc != SC_OK)
        fprintf(stderr, "plan: %s\n", err.msg);
    assert_int_equal(rc, SC_OK);
    sc_lsq_full_desc fd;
    sc_lsq_full_desc_of(q, &fd);
    int dense = sc_lsq_misalignment_nullity(&fd, fd.nm);
    int sparse = sc_lsq_misalignment_nullity(&fd, 0);
    assert_true(dense >= 3);
    assert_int_equal(sparse, dense);
    /* the bordered matrix grows with the views and marks, not with nm² */
    long *Ap = NULL;
    int *Ai = NULL, n = 0;
    double *Ax = NULL;
    assert_int_equal(sc_lsq_full_misalignment_bordered(&fd, &n, &Ap, &Ai, &Ax), 0);
    assert_true(n >= fd.nm && Ap[n] <= (long)fd.nm * (fd.nb + 1) / 2 + fd.neq * fd.nb + n);
    for (int j = 0; j < n; ++j) /* upper, rows ascending, the diagonal last */
        for (long k = Ap[j]; k < Ap[j + 1]; ++k)
            assert_true(Ai[k] <= j && (k == Ap[j] || Ai[k] > Ai[k - 1]) &&
                        (k + 1 < Ap[j + 1] || Ai[k] == j));
    free(Ap), free(Ai), free(Ax);
    sc_grid_lsq_plan_destroy(q);
    return dense;
}

/* Reduced and full on the same data: every output to 1e-9 relative. */
static void check_same(const sc_grid_plan *p, int drift, uint64_t seed)
{
    sc_grid_data d;
    make_data(&d, p, 0.05, seed, drift);
    sc_grid_lsq_opts o1 = {.drift = drift, .solver = SC_GRID_SOLVER_REDUCED};
    sc_grid_lsq_opts o2 = {.drift = drift, .solver = SC_GRID_SOLVER_FULL};
    sc_grid_lsq_stats s1, s2;
    run a, b;
    run_solve(&a, p, &d, &o1, &s1);
    run_solve(&b, p, &d, &o2, &s2);
    assert_int_equal(s1.solver, SC_GRID_SOLVER_REDUCED);
    assert_int_equal(s2.solver, SC_GRID_SOLVER_FULL);
    assert_true(s2.n_factored > s2.n_reduced);
    assert_int_equal(s1.n_null_pivots, s2.n_null_pivots);
    assert_int_equal(s1.nullity_misalignment, s2.nullity_misalignment);
    assert_int_equal(check_nullity_rules(p, &d, drift), s2.nullity_misalignment);
    long ns = sc_grid_stage_nodes(p), nn = (long)p->n * p->n, m = nn * p->n_views;
    int nv = p->n_views;
    const double tol = 1e-9;
    assert_true(rel_diff(a.r.gx_um, b.r.gx_um, ns) < tol);
    assert_true(rel_diff(a.r.gy_um, b.r.gy_um, ns) < tol);
    assert_true(rel_diff(a.r.ugx_um, b.r.ugx_um, ns) < tol);
    assert_true(rel_diff(a.r.ugy_um, b.r.ugy_um, ns) < tol);
    assert_true(rel_diff(a.r.ax_um, b.r.ax_um, nn) < tol);
    assert_true(rel_diff(a.r.ay_um, b.r.ay_um, nn) < tol);
    assert_true(rel_diff(a.r.tx_um, b.r.tx_um, nv) < tol);
    assert_true(rel_diff(a.r.theta_urad, b.r.theta_urad, nv) < tol);
    assert_true(rel_diff(a.r.utx_um, b.r.utx_um, nv) < tol);
    assert_true(rel_diff(a.r.uty_um, b.r.uty_um, nv) < tol);
    assert_true(rel_diff(a.r.utheta_urad, b.r.utheta_urad, nv) < tol);
    if (drift) {
        assert_true(rel_diff(a.r.vx_um_s, b.r.vx_um_s, nv) < tol);
        assert_true(rel_diff(a.r.uvx_um_s, b.r.uvx_um_s, nv) < tol);
    }
    assert_true(rel1(a.r.uO, b.r.uO) < tol && rel1(a.r.uR, b.r.uR) < tol);
    assert_true(rel1(a.r.O, b.r.O) < 1e-7 && rel1(a.r.R, b.r.R) < 1e-7);
    assert_true(rel1(a.r.sigma_r_est_um, b.r.sigma_r_est_um) < tol);
    assert_int_equal(a.r.dof, b.r.dof);
    assert_true(rel_diff(a.rx, b.rx, m) < tol);
    assert_true(rel_diff(a.ry, b.ry, m) < tol);
    assert_true(rel_diff(a.tx, b.tx, m) < tol);
    assert_true(rel_diff(a.ty, b.ty, m) < tol);
    assert_true(rel_diff(a.h, b.h, m) < tol);
    run_free(&a), run_free(&b);
    sc_grid_data_free(&d);
}

static void test_full_equals_reduced(void **s)
{
    (void)s;
    sc_grid_plan p;
    /* plate-sized: Ye's plan and a rich one */
    assert_int_equal(sc_grid_plan_ye(9, 1.0, 0, 0, &p, NULL), SC_OK);
    check_same(&p, 0, 1);
    sc_grid_plan_free(&p);
    /* stitched, with a rectangular stage; with drift */
    assert_int_equal(sc_grid_plan_stitch(7, 13, 13, 1.5, 3, -2, &p, NULL), SC_OK);
    check_same(&p, 0, 2);
    check_same(&p, 1, 3);
    sc_grid_plan_free(&p);
    assert_int_equal(sc_grid_plan_stitch(5, 17, 9, 1.0, 0, 0, &p, NULL), SC_OK);
    check_same(&p, 0, 4);
    sc_grid_plan_free(&p);
    /* many placements of a small plate: 2-step raster (each mark in tens of views) */
    assert_int_equal(sc_grid_plan_stitch_step(5, 21, 21, 2, 1.0, 0, 0, &p, NULL), SC_OK);
    check_same(&p, 0, 5);
    sc_grid_plan_free(&p);
}

/* A rank-deficient misalignment block: a view that measures one mark leaves one more
 * combination free; the dense and the sparse rule both count it. */
static void test_misalignment_nullity_deficient(void **s)
{
    (void)s;
    sc_grid_plan p;
    assert_int_equal(sc_grid_plan_stitch(7, 13, 13, 1.5, 3, -2, &p, NULL), SC_OK);
    {
        sc_grid_data d;
        make_data(&d, &p, 0.05, 21, 0);
        int nu = check_nullity_rules(&p, &d, 0);
        long nn = (long)p.n * p.n, kept = -1;
        for (long k = 0; k < nn; ++k) {
            if (kept < 0 && isfinite(d.dx_um[1][k]))
                kept = k;
            else
                d.dx_um[1][k] = d.dy_um[1][k] = NAN;
        }
        assert_true(kept >= 0);
        assert_int_equal(check_nullity_rules(&p, &d, 0), nu + 1);
        sc_grid_data_free(&d);
    }
    sc_grid_plan_free(&p);
}

/* The automatic choice follows the pairs rule. */
static void test_auto_choice(void **s)
{
    (void)s;
    sc_grid_plan p;
    sc_grid_data d;
    sc_grid_lsq_stats st;
    run a;
    assert_int_equal(sc_grid_plan_ye(9, 1.0, 0, 0, &p, NULL), SC_OK);
    make_data(&d, &p, 0.05, 7, 0);
    run_solve(&a, &p, &d, NULL, &st);
    assert_int_equal(st.solver, SC_GRID_SOLVER_REDUCED); /* 3 views */
    assert_int_equal(st.n_factored, st.n_reduced);
    run_free(&a), sc_grid_data_free(&d), sc_grid_plan_free(&p);
    /* 11 placements of a 7-mark plate: each mark in 11 views, 5 pairs per equation */
    assert_int_equal(sc_grid_plan_stitch(7, 13, 13, 1.0, 0, 0, &p, NULL), SC_OK);
    assert_int_equal(p.n_views, 11);
    make_data(&d, &p, 0.05, 9, 0);
    run_solve(&a, &p, &d, NULL, &st);
    assert_int_equal(st.solver, SC_GRID_SOLVER_REDUCED);
    run_free(&a), sc_grid_data_free(&d), sc_grid_plan_free(&p);
    /* step 2 raster of a 5-mark plate on a 13² stage: 27 placements, 13 pairs per equation */
    assert_int_equal(sc_grid_plan_stitch_step(5, 13, 13, 2, 1.0, 0, 0, &p, NULL), SC_OK);
    assert_int_equal(p.n_views, 27);
    make_data(&d, &p, 0.05, 8, 0);
    run_solve(&a, &p, &d, NULL, &st);
    assert_int_equal(st.solver, SC_GRID_SOLVER_FULL);
    assert_true(st.n_factored > st.n_reduced);
    run_free(&a), sc_grid_data_free(&d), sc_grid_plan_free(&p);
}

/* Sampled σ: the plan's exact σ at the sampled nodes, NaN at the others; against refined
 * solves (sc_grid_lsq_reference) too. NONE: NaN σ and no leverages, the same G. */
static void check_sampled(const sc_grid_plan *p, int solver)
{
    sc_grid_data d;
    make_data(&d, p, 0.05, 11, 0);
    sc_grid_lsq_opts all = {.solver = solver};
    sc_grid_lsq_opts smp = {.solver = solver, .node_sigma = SC_GRID_NODE_SIGMA_SAMPLE,
                            .node_sigma_sample = 9};
    sc_grid_lsq_opts none = {.solver = solver, .node_sigma = SC_GRID_NODE_SIGMA_NONE};
    sc_grid_lsq_plan *qa = NULL, *qs = NULL, *qn = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(p, &d, &all, &qa, &err), SC_OK);
    assert_int_equal(sc_grid_lsq_plan_create(p, &d, &smp, &qs, &err), SC_OK);
    assert_int_equal(sc_grid_lsq_plan_create(p, &d, &none, &qn, &err), SC_OK);
    long ns = sc_grid_stage_nodes(p);
    double *buf = malloc(sizeof(double) * 6 * ns);
    double *ax = buf, *ay = buf + ns, *sx = buf + 2 * ns, *sy = buf + 3 * ns;
    double *nx = buf + 4 * ns, *ny = buf + 5 * ns;
    assert_int_equal(sc_grid_lsq_sigma_ratio(qa, ax, ay, &err), SC_OK);
    assert_int_equal(sc_grid_lsq_sigma_ratio(qs, sx, sy, &err), SC_OK);
    assert_int_equal(sc_grid_lsq_sigma_ratio(qn, nx, ny, &err), SC_OK);
    int sampled = 0;
    for (long k = 0; k < ns; ++k) {
        assert_true(isnan(nx[k]) && isnan(ny[k]));
        assert_true(isnan(sx[k]) == isnan(sy[k]));
        if (isnan(sx[k]))
            continue;
        sampled++;
        assert_true(fabs(sx[k] - ax[k]) <= 1e-9 * ax[k]);
        assert_true(fabs(sy[k] - ay[k]) <= 1e-9 * ay[k]);
    }
    assert_int_equal(sampled, 9);
    sc_grid_lsq_info ia, is;
    sc_grid_lsq_get_info(qa, &ia);
    sc_grid_lsq_get_info(qs, &is);
    assert_true(is.sigma_c_ratio_max <= ia.sigma_c_ratio_max * (1 + 1e-12));
    assert_true(isnan(is.redundancy_min) && is.n_testable == 0);
    /* the exact σ against refined solves, at nodes of the reference's own choice */
    int node[6];
    long eq[6];
    double sref[6], splan[6], href[6], hplan[6];
    assert_int_equal(sc_grid_lsq_reference(qa, 6, node, sref, splan, eq, href, hplan), 0);
    for (int t = 0; t < 6; ++t) {
        assert_true(fabs(sref[t] - splan[t]) <= 1e-9 * sref[t]);
        assert_true(fabs(href[t] - hplan[t]) <= 1e-9);
    }
    /* the same G whatever is asked of σ */
    run a, n;
    sc_grid_lsq_stats st;
    run_solve(&a, p, &d, &all, &st);
    run_solve(&n, p, &d, &none, &st);
    assert_true(rel_diff(a.r.gx_um, n.r.gx_um, ns) == 0);
    for (long k = 0; k < (long)p->n * p->n * p->n_views; ++k)
        assert_true(isnan(n.tx[k]));
    run_free(&a), run_free(&n);
    free(buf);
    sc_grid_lsq_plan_destroy(qa), sc_grid_lsq_plan_destroy(qs), sc_grid_lsq_plan_destroy(qn);
    sc_grid_data_free(&d);
}

static void test_sampled_sigma(void **s)
{
    (void)s;
    sc_grid_plan p;
    assert_int_equal(sc_grid_plan_stitch(7, 13, 13, 1.5, 3, -2, &p, NULL), SC_OK);
    check_sampled(&p, SC_GRID_SOLVER_REDUCED);
    check_sampled(&p, SC_GRID_SOLVER_FULL);
    sc_grid_plan_free(&p);
}

/* max_bytes with A kept: refused below the estimate, made with room of three times what the plan
 * holds after it (the selected inverse's peak is 3x the factor, which the plan then holds once;
 * here 23 MB held, 52 MB estimated). */
static void test_memory_limit_full(void **s)
{
    (void)s;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_stitch_step(33, 129, 129, 32, 1.0, 0, 0, &p, &err), SC_OK);
    sc_grid_lsq_plan *q = NULL;
    sc_grid_lsq_opts o = {.node_sigma_only = 1, .solver = SC_GRID_SOLVER_FULL};
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &o, &q, &err), SC_OK);
    sc_grid_lsq_stats st;
    sc_grid_lsq_get_stats(q, &st);
    sc_grid_lsq_plan_destroy(q);
    q = NULL;
    o.max_bytes = (double)st.bytes / 3;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, &o, &q, &err), SC_E_NOMEM);
    assert_null(q);
    assert_non_null(strstr(err.msg, "needs about"));
    o.max_bytes = 3.0 * (double)st.bytes;
    sc_status rc = sc_grid_lsq_plan_create(&p, NULL, &o, &q, &err);
    if (rc != SC_OK)
        fprintf(stderr, "holds %zu bytes: %s\n", st.bytes, err.msg);
    assert_int_equal(rc, SC_OK);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_plan_free(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_full_equals_reduced),
        cmocka_unit_test(test_auto_choice),
        cmocka_unit_test(test_misalignment_nullity_deficient),
        cmocka_unit_test(test_sampled_sigma),
        cmocka_unit_test(test_memory_limit_full),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
