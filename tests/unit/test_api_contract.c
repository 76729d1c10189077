/* test_api_contract.c — what the public headers promise at their edges, found by an audit that
 * used the library from its headers alone (stop 27): documented preconditions give an error
 * code and a message, never a crash or a silent wrong answer; sizes as the headers state them. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/import.h"
#include "selfcal/lut.h"
#include "selfcal/profile.h"
#include "selfcal/profile_calibrate.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_sim.h"

/* An empty table (sc_lut_init) has no grid: NaN and "outside", not a read out of bounds. */
static void test_lut_eval_empty(void **state)
{
    (void)state;
    sc_lut *lut = malloc(sizeof *lut);
    assert_non_null(lut);
    sc_lut_init(lut);
    double gx = 0, gy = 0;
    assert_true(sc_lut_grid_eval(lut, 0.0, 0.0, &gx, &gy));
    assert_true(isnan(gx) && isnan(gy));
    uint8_t buf[64];
    size_t len;
    sc_error err;
    assert_int_equal(sc_lut_encode(lut, (sc_lut_encoding)7, buf, sizeof buf, &len, &err),
                     SC_E_INPUT);
    free(lut);
}

/* The DFT refuses a NaN as least squares does (it spread over the whole profile before). */
static void test_dft_execute_nan(void **state)
{
    (void)state;
    sc_profile_dft_plan *p;
    sc_error err;
    assert_int_equal(sc_profile_dft_plan_create(330, 10, 11, 1.0, 1.0, &p, &err), SC_OK);
    double y1[330] = {0}, y2[330] = {0}, f[330];
    y1[7] = NAN;
    assert_int_equal(sc_profile_dft_execute(p, y1, y2, f, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "y1(7)"));
    sc_profile_dft_plan_destroy(p);
}

/* sc_profile_calibrate's options as profile_calibrate.h states them. */
static void test_profile_options_checked(void **state)
{
    (void)state;
    sc_profile_data d;
    sc_error err;
    sc_profile_sim sp;
    sc_profile_sim_defaults(&sp);
    double *truth = malloc(330 * sizeof(double)), *ey = malloc(330 * sizeof(double));
    sc_profile_sim_random_truth(&sp, 1.0, 5, truth);
    assert_int_equal(sc_profile_simulate(&sp, truth, &d, ey, &err), SC_OK);
    double f[330], uf[330], e2[330];
    sc_profile_solution s = {.f_um = f, .uf_um = uf, .ey_um = e2};
    sc_profile_options o;
    const struct {
        int what;
        double v;
    } bad[] = {{0, -1.0}, {0, INFINITY}, {1, -2.0}, {2, -5}, {2, 1}, {3, 5}};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        sc_profile_options_default(&o);
        o.method = SC_PROFILE_LSQ;
        if (bad[k].what == 0)
            o.sigma_disp_um = bad[k].v;
        else if (bad[k].what == 1)
            o.sigma_angle_urad = bad[k].v;
        else if (bad[k].what == 2)
            o.mc_trials = (long)bad[k].v;
        else
            o.method = (sc_profile_method)(int)bad[k].v;
        assert_int_equal(sc_profile_calibrate(&d, &o, &s, &err), SC_E_INPUT);
    }
    sc_profile_options_default(&o);
    assert_int_equal(sc_profile_calibrate(&d, &o, &s, &err), SC_OK);
    free(truth), free(ey);
    sc_profile_data_free(&d);
}

/* A stage larger than the plate: sc_grid_lsq_sigma_ratio fills NX·NY values (the header said
 * n*n); the plan's own workspace size for the simulation; the required truth arrays. */
static void test_stage_sizes_and_required_arrays(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_stitch(5, 9, 9, 10.0, 0, 0, &p, &err), SC_OK);
    sc_grid_lsq_plan *q = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
    size_t ns = (size_t)sc_grid_stage_nx(&p) * sc_grid_stage_ny(&p);
    assert_int_equal((int)ns, 81);
    double *a = malloc(ns * sizeof(double)), *b = malloc(ns * sizeof(double));
    assert_int_equal(sc_grid_lsq_sigma_ratio(q, a, b, &err), SC_OK);
    for (size_t k = 0; k < ns; ++k)
        assert_true(a[k] > 0 && b[k] > 0);
    /* a view beyond the plan, a mark off the plate: NaN, not a crash */
    sc_grid_result res;
    memset(&res, 0, sizeof res);
    double dx = 0, dy = 0;
    sc_grid_lsq_predict(q, &res, 99, 0, 0, 0, &dx, &dy);
    assert_true(isnan(dx) && isnan(dy));
    sc_grid_lsq_plan_destroy(q);
    free(a), free(b);

    assert_true(sc_grid_sim_work_doubles_plan(&p) > sc_grid_sim_work_doubles(p.n));
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    double g[2 * 81], pl[2 * 25];
    t.gx_um = g, t.gy_um = g + 81, t.ay_um = pl + 25; /* ax_um missing */
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    double *work = malloc(sc_grid_sim_work_doubles_plan(&p) * sizeof(double));
    assert_int_equal(sc_grid_sim_run(&p, &sp, &t, &d, work, &err), SC_E_INPUT);
    free(work);

    /* a NaN origin or a view noise that is neither 0 (not stated) nor positive */
    sc_grid_plan bad = {0};
    assert_int_equal(sc_grid_plan_copy(&bad, &p, &err), SC_OK);
    bad.origin_mm[0] = NAN;
    assert_int_equal(sc_grid_plan_check(&bad, &err), SC_E_INPUT);
    assert_int_equal(sc_grid_plan_copy(&bad, &p, &err), SC_OK);
    bad.view[1].sigma_um = -1;
    assert_int_equal(sc_grid_plan_check(&bad, &err), SC_E_INPUT);
    bad.view[1].sigma_um = NAN;
    assert_int_equal(sc_grid_plan_check(&bad, &err), SC_E_INPUT);
    /* a plan without its views is refused, not read through NULL */
    assert_int_equal(sc_grid_plan_check(&p, &err), SC_OK);
    sc_grid_view *keep = p.view;
    p.view = NULL;
    assert_int_equal(sc_grid_plan_check(&p, &err), SC_E_INPUT);
    p.view = keep;
    sc_grid_plan_free(&p);
    sc_grid_plan_free(&bad);
}

/* sc_table_read's parameters: SC_E_INPUT (it said SC_E_INTERNAL), a NaN scale refused. */
static void test_table_read_parameters(void **state)
{
    (void)state;
    sc_table t;
    sc_error err;
    const char *names[2] = {"x", "y"};
    const double nan_scale[2] = {1.0, NAN};
    assert_int_equal(sc_table_read("/nonexistent", 0, names, NULL, &t, &err), SC_E_INPUT);
    assert_int_equal(sc_table_read("/nonexistent", 2, names, nan_scale, &t, &err), SC_E_INPUT);
    const char *same[2] = {"x", "X"};
    assert_int_equal(sc_table_read("/nonexistent", 2, same, NULL, &t, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "twice"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lut_eval_empty),
        cmocka_unit_test(test_dft_execute_nan),
        cmocka_unit_test(test_profile_options_checked),
        cmocka_unit_test(test_stage_sizes_and_required_arrays),
        cmocka_unit_test(test_table_read_parameters),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
