/* Run-time sized per-view storage (no cap on the number of views): a plan's views, copies and
 * frees; a result's per-view arrays; a plan of 10 002 views through the file writer and reader;
 * 363 views through least squares, its noise-free solution equal to the truth. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cmocka.h>

#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/rng.h"
#include "test_grid_sim_util.h"

static void tmp_path(char *buf, size_t n, const char *name)
{
    mkdir(SELFCAL_TEST_TMP, 0777);
    snprintf(buf, n, "%s/grid_views_%s", SELFCAL_TEST_TMP, name);
}

/* Sizing keeps the views there, zeroes new ones; a copy is deep; free leaves nothing. */
static void test_plan_views(void **state)
{
    (void)state;
    sc_grid_plan p = {0}, c = {0};
    p.n = 5, p.pitch_mm = 1;
    assert_int_equal(sc_grid_plan_views(&p, 2, NULL), SC_OK);
    p.view[1].rot_deg = 90;
    assert_int_equal(sc_grid_plan_views(&p, 40000, NULL), SC_OK);
    assert_int_equal(p.n_views, 40000);
    assert_int_equal(p.view[1].rot_deg, 90);
    assert_int_equal(p.view[39999].rot_deg, 0);
    assert_int_equal(p.view[39999].restricted, 0);
    assert_int_equal(sc_grid_plan_check(&p, NULL), SC_OK); /* 40 000 views of one place */
    assert_int_equal(sc_grid_plan_copy(&c, &p, NULL), SC_OK);
    assert_ptr_not_equal(c.view, p.view);
    c.view[1].rot_deg = 180;
    assert_int_equal(p.view[1].rot_deg, 90);
    assert_int_equal(sc_grid_plan_copy(&c, &p, NULL), SC_OK); /* into a plan holding views */
    assert_int_equal(c.view[1].rot_deg, 90);
    sc_error err;
    assert_int_equal(sc_grid_plan_views(&p, 0, &err), SC_E_INPUT);
    assert_int_equal(sc_grid_plan_views(&p, SC_GRID_VIEW_LIMIT + 1, &err), SC_E_INPUT);
    assert_int_equal(p.n_views, 40000); /* unchanged by a refused size */
    sc_grid_plan_free(&p);
    assert_null(p.view);
    assert_int_equal(p.n_views, 0);
    sc_grid_plan_free(&p); /* twice: nothing */
    sc_grid_plan_free(&c);
    /* a plan whose views were never made is refused by the check, not read */
    p.n = 5, p.pitch_mm = 1, p.n_views = 3;
    assert_int_equal(sc_grid_plan_check(&p, &err), SC_E_INPUT);
}

/* sc_grid_result_views: every per-view array, NaN, one block; freed. */
static void test_result_views(void **state)
{
    (void)state;
    sc_grid_result r;
    memset(&r, 0, sizeof r);
    assert_int_equal(sc_grid_result_views(&r, 12345, NULL), SC_OK);
    const double *a[SC_GRID_RESULT_VIEW_ARRAYS] = {
        r.tx_um,   r.ty_um,    r.theta_urad, r.utx_um,        r.uty_um,
        r.utheta_urad, r.vx_um_s, r.vy_um_s, r.uvx_um_s,     r.uvy_um_s,
        r.view_sigma_um, r.view_noise_factor, r.view_sigma_u_um};
    for (int t = 0; t < SC_GRID_RESULT_VIEW_ARRAYS; ++t) {
        assert_non_null(a[t]);
        assert_true(isnan(a[t][0]) && isnan(a[t][12344]));
        if (t)
            assert_true(a[t] == a[t - 1] + 12345); /* one block, in order */
    }
    sc_grid_result_free_views(&r);
    assert_null(r.tx_um);
    assert_null(r.view_sigma_u_um);
    assert_null(r.view_block);
    sc_grid_result_free_views(&r);
}

/* A stitched plan of 10 002 views (N = 3 plate, 201 x 201 stage, step 2): simulated, written,
 * read back; plan and every deviation survive to 1e-9 µm, the file info has each view's line. */
static void test_ten_thousand_views_file(void **state)
{
    (void)state;
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    sc_error err;
    assert_int_equal(sc_grid_plan_stitch_step(3, 201, 201, 2, 0.5, 7, -2, &d.plan, &err), SC_OK);
    int nv = d.plan.n_views, nn = 9;
    assert_int_equal(nv, 100 * 100 + 2);
    assert_int_equal(sc_grid_data_alloc(&d, &err), SC_OK);
    assert_int_equal(sc_grid_data_alloc_extra(&d, 1, 0, &err), SC_OK);
    sc_grid_sim_truth t;
    double *work, *buf = tu_sim_buffer(&d.plan, &t, &work);
    assert_non_null(buf);
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    assert_int_equal(sc_grid_sim_run(&d.plan, &sp, &t, &d, work, &err), SC_OK);
    for (int v = 0; v < nv; ++v) /* each row its stated uncertainties */
        for (int k = 0; k < nn; ++k)
            if (isfinite(d.dx_um[v][k]))
                d.ux_um[v][k] = 0.25 * (1 + (v + k) % 3), d.uy_um[v][k] = 0.5;
    char path[512];
    tmp_path(path, sizeof path, "10k.csv");
    assert_int_equal(sc_grid_write_input(path, &d, &err), SC_OK);
    sc_grid_data r;
    sc_grid_file_info info;
    if (sc_grid_read(path, &r, &info, &err) != SC_OK)
        fail_msg("%s:%ld: %s", err.file, err.line, err.msg);
    assert_int_equal(r.plan.n_views, nv);
    assert_int_equal(sc_grid_stage_nx(&r.plan), 201);
    long rows = 0;
    for (int v = 0; v < nv; ++v) {
        assert_int_equal(r.plan.view[v].rot_deg, d.plan.view[v].rot_deg);
        assert_int_equal(r.plan.view[v].shift_x, d.plan.view[v].shift_x);
        assert_int_equal(r.plan.view[v].shift_y, d.plan.view[v].shift_y);
        assert_int_equal(info.view_id[v], v);
        assert_int_equal(info.view_line[v], 6 + v); /* tag, N, pitch, origin, stage, views */
        rows += info.view_rows[v];
        for (int k = 0; k < nn; ++k) {
            assert_true(isfinite(r.dx_um[v][k]) == isfinite(d.dx_um[v][k]));
            if (!isfinite(d.dx_um[v][k]))
                continue;
            assert_true(fabs(r.dx_um[v][k] - d.dx_um[v][k]) < 1e-9);
            assert_true(fabs(r.dy_um[v][k] - d.dy_um[v][k]) < 1e-9);
            assert_true(sc_grid_data_u_um(&r, v, k, 0) == 0.25 * (1 + (v + k) % 3));
            assert_true(sc_grid_data_u_um(&r, v, k, 1) == 0.5);
        }
    }
    assert_int_equal(rows, info.n_rows);
    sc_grid_file_info_free(&info);
    assert_null(info.view_line);
    sc_grid_data_free(&r);
    assert_null(r.plan.view);
    assert_null(r.dx_um);
    free(buf);
    sc_grid_data_free(&d);
}

/* Views declared in any order and numbering, data rows in any order: found by their number. */
static void test_view_numbers(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "numbers.csv");
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fprintf(fp, "# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# stage = 41,41\n");
    for (int v = 0; v < 300; ++v) /* numbers 3 apart, counting down */
        fprintf(fp, "# view %d: rot=0 shift=%d,%d\n", 3 * (299 - v), v % 19 - 9, v / 19 - 8);
    fprintf(fp, "view,i,j,x_mm,y_mm\n");
    for (int v = 299; v >= 0; v -= 7) /* view 0 last, row (1,1) of each */
        fprintf(fp, "%d,1,1,%d,%d\n", 3 * (299 - v), v % 19 - 9, v / 19 - 8);
    fprintf(fp, "%d,1,1,%d,%d\n", 3 * 299, 0 % 19 - 9, 0 / 19 - 8);
    fclose(fp);
    sc_grid_data d;
    sc_grid_file_info info;
    sc_error err;
    assert_int_equal(sc_grid_read(path, &d, &info, &err), SC_OK);
    assert_int_equal(d.plan.n_views, 300);
    assert_int_equal(info.view_id[0], 897);
    assert_int_equal(info.view_id[299], 0);
    assert_true(d.dx_um[0][4] == 0 && d.dx_um[299][4] == 0 && isnan(d.dx_um[1][4]));
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);
    /* a view number declared twice, the second time far down the header */
    fp = fopen(path, "w");
    fprintf(fp, "# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# stage = 41,41\n");
    for (int v = 0; v < 300; ++v)
        fprintf(fp, "# view %d: rot=0 shift=0,0\n", v == 250 ? 17 : v);
    fclose(fp);
    assert_int_equal(sc_grid_read(path, &d, &info, &err), SC_E_INPUT);
    assert_int_equal(err.line, 4 + 251);
    assert_non_null(strstr(err.msg, "view 17 is declared twice (first on line 22)"));
}

/* 363 placements (N = 3 plate, 21 x 21 stage, step 1): noise-free data, least squares recovers
 * G, A and every view's misalignment, with their uncertainties; a prediction from the result's
 * per-view arrays equals the data. */
static void test_lsq_363_views(void **state)
{
    (void)state;
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    sc_error err;
    assert_int_equal(sc_grid_plan_stitch_step(3, 21, 21, 1, 1.0, 0, 0, &d.plan, &err), SC_OK);
    int nv = d.plan.n_views, nn = 9;
    assert_int_equal(nv, 363);
    assert_int_equal(sc_grid_data_alloc(&d, &err), SC_OK);
    size_t ns = (size_t)sc_grid_stage_nodes(&d.plan);
    sc_grid_sim_truth t;
    double *work, *buf = tu_sim_buffer(&d.plan, &t, &work);
    assert_non_null(buf);
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.sigma_r_um = 0;
    assert_int_equal(sc_grid_sim_run(&d.plan, &sp, &t, &d, work, &err), SC_OK);
    sc_grid_lsq_plan *q = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&d.plan, &d, NULL, &q, &err), SC_OK);
    sc_grid_lsq_info qi;
    sc_grid_lsq_get_info(q, &qi);
    assert_true(qi.identifiable);
    sc_grid_result res;
    memset(&res, 0, sizeof res);
    double *out = malloc(sizeof(double) * (4 * ns + 2 * nn));
    res.gx_um = out, res.gy_um = out + ns, res.ugx_um = out + 2 * ns, res.ugy_um = out + 3 * ns;
    res.ax_um = out + 4 * ns, res.ay_um = out + 4 * ns + nn;
    assert_int_equal(sc_grid_result_views(&res, nv, &err), SC_OK);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0.01, &res, &err), SC_OK);
    double eg = 0, ea = 0, em = 0, et = 0;
    for (size_t k = 0; k < ns; ++k)
        eg = fmax(eg, fmax(fabs(res.gx_um[k] - t.gx_um[k]), fabs(res.gy_um[k] - t.gy_um[k])));
    for (int k = 0; k < nn; ++k)
        ea = fmax(ea, fmax(fabs(res.ax_um[k] - t.ax_um[k]), fabs(res.ay_um[k] - t.ay_um[k])));
    for (int v = 0; v < nv; ++v) {
        em = fmax(em, fmax(fabs(res.tx_um[v] - t.tx_um[v]), fabs(res.ty_um[v] - t.ty_um[v])));
        et = fmax(et, fabs(res.theta_urad[v] - t.theta_urad[v]));
        assert_true(res.utx_um[v] > 0 && isfinite(res.utheta_urad[v]));
    }
    fprintf(stderr, "363 views: |dG| %.3g |dA| %.3g |dt| %.3g um |dθ| %.3g urad\n", eg, ea, em,
            et);
    assert_true(eg <= 1e-9 && ea <= 1e-9 && em <= 1e-9 && et <= 1e-6);
    /* the prediction of a mark from the result's per-view arrays equals the data */
    double px, py;
    sc_grid_lsq_predict(q, &res, 200, 1, 2, 0, &px, &py);
    assert_true(fabs(px - d.dx_um[200][5]) < 1e-9 && fabs(py - d.dy_um[200][5]) < 1e-9);
    for (size_t k = 0; k < ns; ++k) /* σ_r = 0.01 µm given: every node's σ a few σ_r */
        assert_true(res.ugx_um[k] > 0.001 && res.ugx_um[k] < 0.1);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_result_free_views(&res);
    free(out), free(buf);
    sc_grid_data_free(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_plan_views),
        cmocka_unit_test(test_result_views),
        cmocka_unit_test(test_ten_thousand_views_file),
        cmocka_unit_test(test_view_numbers),
        cmocka_unit_test(test_lsq_363_views),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
