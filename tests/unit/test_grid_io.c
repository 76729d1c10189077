/* Unit tests of the selfcal-grid v1 reader and the map/artifact/summary writers. */
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
#include "selfcal/grid_sim.h"

static void tmp_path(char *buf, size_t n, const char *name)
{
    mkdir(SELFCAL_TEST_TMP, 0777);
    snprintf(buf, n, "%s/grid_io_%s", SELFCAL_TEST_TMP, name);
}

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    fputs(text, fp);
    fclose(fp);
}

/* Simulated double-shift data (N = 9, pitch 1.5 mm, origin away from 0) written and read back:
 * plan and every deviation survive to 1e-9 µm. */
static void test_input_round_trip(void **state)
{
    (void)state;
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    sc_error err;
    assert_int_equal(sc_grid_plan_double_shift(9, 1.5, 120.25, -37.5, &d.plan, &err), SC_OK);
    assert_int_equal(sc_grid_data_alloc(&d, &err), SC_OK);
    int n = 9, nn = 81;
    double g[4 * 81 + 3 * 4], work[2 * 81];
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    t.gx_um = g, t.gy_um = g + nn, t.ax_um = g + 2 * nn, t.ay_um = g + 3 * nn;
    t.tx_um = g + 4 * nn, t.ty_um = t.tx_um + 4, t.theta_urad = t.ty_um + 4; /* 4 views */
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.sigma_r_um = 0.05;
    assert_int_equal(sc_grid_sim_run(&d.plan, &sp, &t, &d, work, &err), SC_OK);
    char path[512];
    tmp_path(path, sizeof path, "rt.csv");
    assert_int_equal(sc_grid_write_input(path, &d, &err), SC_OK);

    sc_grid_data r;
    sc_grid_file_info info;
    assert_int_equal(sc_grid_read(path, &r, &info, &err), SC_OK);
    assert_int_equal(r.plan.n, n);
    assert_true(r.plan.pitch_mm == 1.5);
    assert_true(r.plan.origin_mm[0] == 120.25 && r.plan.origin_mm[1] == -37.5);
    assert_int_equal(r.plan.n_views, 4);
    long expect_rows = 0;
    for (int v = 0; v < 4; ++v) {
        assert_int_equal(r.plan.view[v].rot_deg, d.plan.view[v].rot_deg);
        assert_int_equal(r.plan.view[v].shift_x, d.plan.view[v].shift_x);
        assert_int_equal(r.plan.view[v].shift_y, d.plan.view[v].shift_y);
        assert_int_equal(r.plan.view[v].restricted, d.plan.view[v].restricted);
        for (int k = 0; k < n; ++k) {
            assert_int_equal(r.plan.view[v].row_sel[k], d.plan.view[v].row_sel[k]);
            assert_int_equal(r.plan.view[v].col_sel[k], d.plan.view[v].col_sel[k]);
        }
        for (int k = 0; k < nn; ++k) {
            assert_int_equal(isfinite(r.dx_um[v][k]), isfinite(d.dx_um[v][k]));
            if (!isfinite(d.dx_um[v][k]))
                continue;
            ++expect_rows;
            assert_true(fabs(r.dx_um[v][k] - d.dx_um[v][k]) < 1e-9);
            assert_true(fabs(r.dy_um[v][k] - d.dy_um[v][k]) < 1e-9);
        }
    }
    assert_int_equal(info.n_rows, expect_rows);
    /* Petrò's view 3 for N = 9 measures row 4 and columns 4, 5 where they land: 9 - 3 + 2*9 - ... */
    assert_int_equal(info.view_rows[3], 6 + 9 + 9 - 2);
    sc_grid_data_free(&r);
    sc_grid_file_info_free(&info);

    /* Map round trip through the one stage-map reader (io/). */
    double u[2 * 81];
    for (int k = 0; k < 2 * nn; ++k)
        u[k] = 0.001 * (k + 1);
    u[5] = NAN;
    tmp_path(path, sizeof path, "map.csv");
    assert_int_equal(sc_grid_write_map(path, &d.plan, t.gx_um, t.gy_um, u, u + nn, &err), SC_OK);
    sc_stage_map m;
    assert_int_equal(sc_stage_map_read(path, &m, &err), SC_OK);
    assert_int_equal(m.nx, n);
    assert_int_equal(m.ny, n);
    assert_true(fabs(m.px_mm - 1.5) < 1e-12 && fabs(m.py_mm - 1.5) < 1e-12);
    int c = (n - 1) / 2;
    assert_true(fabs(sc_stage_map_x_mm(&m, c) - 120.25) < 1e-12);
    assert_true(fabs(sc_stage_map_y_mm(&m, c) + 37.5) < 1e-12);
    assert_true(sc_stage_map_has_u(&m));
    for (int k = 0; k < nn; ++k) {
        assert_true(fabs(m.gx_um[k] - t.gx_um[k]) < 1e-12);
        assert_true(fabs(m.gy_um[k] - t.gy_um[k]) < 1e-12);
        if (k == 5)
            assert_true(isnan(m.ugx_um[k]));
        else
            assert_true(fabs(m.ugx_um[k] - u[k]) < 1e-15);
        double x, y;
        sc_grid_node_xy_mm(&d.plan, k / n, k % n, &x, &y);
        assert_true(fabs(sc_stage_map_x_mm(&m, k % n) - (x + 120.25)) < 1e-12);
        assert_true(fabs(sc_stage_map_y_mm(&m, k / n) - (y - 37.5)) < 1e-12);
    }
    sc_stage_map_free(&m);
    sc_grid_data_free(&d);
}

/* A hand-written file: dev = (measured - origin - rot(plate position) - shift P) * 1000. */
static void test_hand_written_values(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "hand.csv");
    write_text(path, "# selfcal-grid v1\n"
                     "# N = 3\n"
                     "# pitch_mm = 2\n"
                     "# origin_mm = 10, 20\n"
                     "# a free comment line\n"
                     "# view 7: rot=90 shift=0,0\n"
                     "# view 2: rot=0 shift=1,0 rows=0\n"
                     "view,i,j,x_mm,y_mm\n"
                     "\n"
                     "7,0,2,12.0001,22.0002\n" /* mark (0,2): plate (2,-2) -> rot90 (2,2) */
                     "2,0,1,12.0,17.9995\n");  /* mark (0,1): plate (0,-2) + (2,0) */
    sc_grid_data d;
    sc_grid_file_info info;
    sc_error err;
    assert_int_equal(sc_grid_read(path, &d, &info, &err), SC_OK);
    assert_int_equal(d.plan.n_views, 2);
    assert_int_equal(info.view_id[0], 7);
    assert_int_equal(info.view_id[1], 2);
    assert_int_equal(info.view_line[1], 7);
    assert_int_equal(info.n_line, 2);
    assert_int_equal(info.header_end_line, 8);
    assert_int_equal(d.plan.view[1].restricted, 1);
    assert_true(fabs(d.dx_um[0][0 * 3 + 2] - 0.1) < 1e-9);
    assert_true(fabs(d.dy_um[0][0 * 3 + 2] - 0.2) < 1e-9);
    assert_true(fabs(d.dx_um[1][1] - 0.0) < 1e-9);
    assert_true(fabs(d.dy_um[1][1] + 0.5) < 1e-9);
    assert_true(isnan(d.dx_um[0][0]));
    assert_int_equal(info.n_rows, 2);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);

    /* A plan file: header only. */
    write_text(path, "# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0\n");
    assert_int_equal(sc_grid_read(path, &d, &info, &err), SC_OK);
    assert_int_equal(info.n_rows, 0);
    assert_int_equal(d.plan.n, 5);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);
}

typedef struct bad_case {
    const char *text;
    long line;
    const char *needle;
} bad_case;

#define HDR "# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0\n# view 1: rot=0 shift=1,0\n"
#define COLS "view,i,j,x_mm,y_mm\n"

static const bad_case bad[] = {
    {"# selfcal-grid v2\n# N = 3\n", 1, "selfcal-grid v1"},
    {"view,i,j,x_mm,y_mm\n", 1, "selfcal-grid v1"},
    {"", 1, "selfcal-grid v1"},
    {"# selfcal-grid v1\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0\n" COLS, 4, "N = ...' missing"},
    {"# selfcal-grid v1\n# N = 4\n", 2, "even"},
    {"# selfcal-grid v1\n# N = 1\n", 2, "out of range"},
    {"# selfcal-grid v1\n# N = 9999\n", 2, "out of range"},
    {"# selfcal-grid v1\n# N = 2.5\n", 2, "whole number"},
    {"# selfcal-grid v1\n# N = 3\n# N = 3\n", 3, "twice"},
    {"# selfcal-grid v1\n# N = 3\n# color = red\n", 3, "unknown header"},
    {"# selfcal-grid v1\n# N = 3\n# view 0: rot=0 shift=0,0\n" COLS, 4, "pitch_mm = ...' missing"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = -1\n", 3, "must be >= 1e-06"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1e-170\n", 3, "must be >= 1e-06"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n" COLS, 4, "no '# view"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=45 shift=0,0\n", 4, "rot must be"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=0 shift=1\n", 4, "shift must be"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0 tilt=3\n", 4, "unknown attribute"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=0 shift=3,0\n", 4, "off the"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0 rows=5\n", 4, "off the plate"},
    {HDR "# view 0: rot=90 shift=0,0\n", 6, "declared twice"},
    {HDR "0,0,0,-1,-1\n", 6, "column header"},
    {HDR COLS "0,0,0,-1\n", 7, "expected 5 fields"},
    {HDR COLS "0,0,0,-1,-1,3\n", 7, "expected 5 fields"},
    {HDR COLS "0,0,0,-1,-1\n0,0,1,abc,-1\n", 8, "not a finite number"},
    {HDR COLS "0,0,0,-1,nan\n", 7, "not a finite number"},
    {HDR COLS "0,0,x,-1,-1\n", 7, "whole number"},
    {HDR COLS "5,0,0,-1,-1\n", 7, "view 5 is not declared"},
    {HDR COLS "0,3,0,-1,-1\n", 7, "off the plate"},
    {HDR COLS "0,0,-1,-1,-1\n", 7, "off the plate"},
    {HDR COLS "1,0,2,2,-1\n", 7, "does not land on the stage grid"},
    {HDR COLS "0,1,1,0,0\n0,0,0,-1,-1\n0,1,1,0,0\n", 9, "duplicate"},
    {HDR COLS "0,1,1,0.6,0\n", 7, "contradicts the data"},
    {HDR COLS "1,0,0,0.0,-1.7\n", 7, "contradicts the data"},
    {"# selfcal-grid v1\n# N = 3\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0 rows=0\n" COLS "0,1,1,0,0\n", 6, "not selected"},
    {HDR COLS "0,1,1,0,0\n# N = 5\n", 8, "after the column header"},
};

static void test_parser_errors(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "bad.csv");
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        write_text(path, bad[k].text);
        sc_grid_data d;
        sc_error err;
        sc_error_clear(&err);
        sc_status st = sc_grid_read(path, &d, NULL, &err);
        if (st != SC_E_INPUT || err.line != bad[k].line || !strstr(err.msg, bad[k].needle) ||
            strcmp(err.file, path) != 0)
            fail_msg("case %zu: status %d line %ld (want %ld) msg '%s' (want '%s') file '%s'", k,
                     st, err.line, bad[k].line, err.msg, bad[k].needle, err.file);
        assert_null(d.dx_um); /* nothing held after a failure */
        assert_null(d.plan.view);
    }
    sc_grid_data d;
    sc_error err;
    assert_int_equal(sc_grid_read(SELFCAL_TEST_TMP "/no/such/file.csv", &d, NULL, &err), SC_E_INPUT);
}

/* The summary is valid enough JSON for a quick look: the keys and null for NaN. */
static void test_summary(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_ye(5, 1, 0, 0, &p, &err), SC_OK);
    sc_grid_result r;
    memset(&r, 0, sizeof r);
    assert_int_equal(sc_grid_result_views(&r, p.n_views, NULL), SC_OK);
    r.O = 1.25e-5;
    r.R = NAN;
    r.tx_um[1] = 0.5;
    r.residual_rms_um = 0.01;
    r.sigma_r_est_um = NAN;
    r.sigma_r_used_um = 0.02;
    r.n_measurements = 150;
    r.dof = 12;
    char path[512];
    tmp_path(path, sizeof path, "sum.json");
    assert_int_equal(sc_grid_write_summary(path, "ye", &p, &r, &err), SC_OK);
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    char buf[4096];
    size_t len = fread(buf, 1, sizeof buf - 1, fp);
    buf[len] = 0;
    fclose(fp);
    assert_non_null(strstr(buf, "\"method\": \"ye\""));
    assert_non_null(strstr(buf, "\"O\": 1.25e-05"));
    assert_non_null(strstr(buf, "\"R\": null"));
    assert_non_null(strstr(buf, "\"tx_um\": 0.5"));
    assert_non_null(strstr(buf, "\"sigma_r_est_um\": null"));
    assert_non_null(strstr(buf, "\"n_measurements\": 150"));
    assert_non_null(strstr(buf, "\"dof\": 12"));
    sc_grid_result_free_views(&r);
    sc_grid_plan_free(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_input_round_trip),
        cmocka_unit_test(test_hand_written_values),
        cmocka_unit_test(test_parser_errors),
        cmocka_unit_test(test_summary),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
