/* Grid least squares at a stitched size (issue 33): a 401 x 401 stage from a 41-mark plate in
 * 363 placements (the SAR-like stitched plan of sc_grid_plan_stitch: a raster at step 20 plus a
 * rotated and a shifted placement at the centre), noise-free: the automatic choice keeps A as
 * unknowns, G is recovered to 1e-6 µm, and the σ of sampled nodes (SC_GRID_NODE_SIGMA_SAMPLE)
 * agrees with refined solves of the factored matrix (sc_grid_lsq_reference); the misalignment
 * block's nullity from its sparse factor is the dense rule's. Label `large`: about
 * 6 s CPU in Release, a minute or more under the sanitizers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../../libselfcal/src/grid/grid_lsq_internal.h"
#include "grid_lsq_reference.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/rng.h"

#define K_SAMPLE 8

static void test_stitched_401(void **s)
{
    (void)s;
    sc_grid_plan p;
    assert_int_equal(sc_grid_plan_stitch(41, 401, 401, 1.0, 0, 0, &p, NULL), SC_OK);
    assert_true(p.n_views >= 300);
    long ns = sc_grid_stage_nodes(&p), nn = 41 * 41;
    int nv = p.n_views;
    sc_rng r;
    sc_rng_seed(&r, 33);
    double *gx = malloc(sizeof(double) * ns), *gy = malloc(sizeof(double) * ns);
    double *ax = malloc(sizeof(double) * nn), *ay = malloc(sizeof(double) * nn);
    double *tx = malloc(sizeof(double) * 3 * nv), *ty = tx + nv, *th = ty + nv;
    for (long k = 0; k < ns; ++k)
        gx[k] = sc_rng_normal(&r), gy[k] = sc_rng_normal(&r);
    for (long k = 0; k < nn; ++k)
        ax[k] = sc_rng_normal(&r), ay[k] = sc_rng_normal(&r);
    for (int v = 0; v < nv; ++v)
        tx[v] = 2 * sc_rng_normal(&r), ty[v] = 2 * sc_rng_normal(&r), th[v] = 30 * sc_rng_normal(&r);
    sc_grid_gauge_stage(&p, gx, gy);
    sc_grid_gauge_plate(&p, ax, ay);
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    assert_int_equal(sc_grid_plan_copy(&d.plan, &p, NULL), SC_OK);
    assert_int_equal(sc_grid_data_alloc(&d, NULL), SC_OK);
    sc_grid_synthesize(&p, gx, gy, ax, ay, tx, ty, th, &d);

    sc_grid_lsq_opts opts = {.node_sigma = SC_GRID_NODE_SIGMA_SAMPLE, .node_sigma_sample = K_SAMPLE};
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    sc_status st = sc_grid_lsq_plan_create(&p, &d, &opts, &q, &err);
    if (st != SC_OK)
        fprintf(stderr, "plan: %s\n", err.msg);
    assert_int_equal(st, SC_OK);
    sc_grid_lsq_info qi;
    sc_grid_lsq_get_info(q, &qi);
    assert_true(qi.identifiable);
    sc_grid_lsq_stats sst;
    sc_grid_lsq_get_stats(q, &sst);
    assert_int_equal(sst.solver, SC_GRID_SOLVER_FULL);
    assert_true(sst.n_factored > sst.n_reduced);
    /* ν₂ of 1 089 misalignments (fewer than the plate's 3 362 A components: the plan counts
     * densely): the dense and the sparse rule agree, 3 (a global shift and turn) */
    assert_int_equal(sst.nullity_misalignment, 3);
    sc_lsq_full_desc fd;
    sc_lsq_full_desc_of(q, &fd);
    clock_t c0 = clock();
    assert_int_equal(sc_lsq_misalignment_nullity(&fd, fd.nm), 3);
    clock_t c1 = clock();
    assert_int_equal(sc_lsq_misalignment_nullity(&fd, 0), 3);
    clock_t c2 = clock();
    fprintf(stderr, "misalignment block's nullity, nm = %d: dense %.2f s, sparse %.2f s CPU\n",
            fd.nm, (double)(c1 - c0) / CLOCKS_PER_SEC, (double)(c2 - c1) / CLOCKS_PER_SEC);
    fprintf(stderr, "401x401, %d views: %ld unknowns factored, nnz(L) %ld, %.3g flops\n", nv,
            sst.n_factored, sst.nnz_factor, sst.factor_flops);

    sc_grid_result res;
    memset(&res, 0, sizeof res);
    double *buf = malloc(sizeof(double) * (4 * ns + 2 * nn));
    res.gx_um = buf, res.gy_um = buf + ns, res.ugx_um = buf + 2 * ns, res.ugy_um = buf + 3 * ns;
    res.ax_um = buf + 4 * ns, res.ay_um = buf + 4 * ns + nn;
    assert_int_equal(sc_grid_result_views(&res, nv, NULL), SC_OK);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 1.0, &res, &err), SC_OK);
    double e = 0, ea = 0;
    for (long k = 0; k < ns; ++k)
        e = fmax(e, fmax(fabs(res.gx_um[k] - gx[k]), fabs(res.gy_um[k] - gy[k])));
    for (long k = 0; k < nn; ++k)
        ea = fmax(ea, fmax(fabs(res.ax_um[k] - ax[k]), fabs(res.ay_um[k] - ay[k])));
    fprintf(stderr, "noise-free: max |G - truth| %.3g um, max |A - truth| %.3g um\n", e, ea);
    assert_true(e <= 1e-6);
    assert_true(ea <= 1e-6);

    /* the sampled nodes are the reference's (K spread evenly in node order, every node measured) */
    double sx[K_SAMPLE], splan[K_SAMPLE], href[K_SAMPLE], hplan[K_SAMPLE];
    int node[K_SAMPLE];
    long eq[K_SAMPLE];
    assert_int_equal(sc_grid_lsq_reference(q, K_SAMPLE, node, sx, splan, eq, href, hplan), 0);
    int finite = 0;
    for (long k = 0; k < ns; ++k)
        finite += isfinite(res.ugx_um[k]);
    assert_int_equal(finite, K_SAMPLE);
    for (int t = 0; t < K_SAMPLE; ++t) {
        fprintf(stderr, "node %d: sigma_x/sigma_r %.15g, reference %.15g (%.2g relative)\n",
                node[t], splan[t], sx[t], fabs(splan[t] - sx[t]) / sx[t]);
        assert_true(sx[t] > 0);
        assert_true(fabs(splan[t] - sx[t]) <= 1e-8 * sx[t]); /* 1e-11; the pinned corner node 1.1e-9 */
        assert_true(fabs(res.ugx_um[node[t]] - sx[t]) <= 1e-8 * sx[t]); /* σ_r = 1 given */
        assert_true(href[t] > 0 && href[t] <= 1 + 1e-12);
    }
    sc_grid_lsq_plan_destroy(q);
    sc_grid_result_free_views(&res);
    sc_grid_data_free(&d);
    sc_grid_plan_free(&p);
    free(buf), free(gx), free(gy), free(ax), free(ay), free(tx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stitched_401),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
