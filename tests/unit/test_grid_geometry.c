/* The SPEC §1 geometry, checked against an independent computation with cos/sin:
 * nominal stage position = origin + R(rot)·plate-centred position + shift·P. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid.h"

static sc_grid_plan make_plan(int n, double pitch)
{
    sc_grid_plan p;
    memset(&p, 0, sizeof p);
    p.n = n;
    p.pitch_mm = pitch;
    p.n_views = 0;
    return p;
}

static void add_view(sc_grid_plan *p, int rot, int sx, int sy)
{
    assert_int_equal(sc_grid_plan_views(p, p->n_views + 1, NULL), SC_OK);
    sc_grid_view *v = &p->view[p->n_views - 1];
    v->rot_deg = rot;
    v->shift_x = sx;
    v->shift_y = sy;
}

static void test_mark_node_matches_rotation_matrix(void **state)
{
    (void)state;
    const int rots[4] = {0, 90, 180, 270};
    sc_grid_plan p = make_plan(7, 1.5);
    for (int r = 0; r < 4; ++r)
        add_view(&p, rots[r], r - 1, 2 - r);
    double c = (p.n - 1) / 2.0;
    for (int v = 0; v < p.n_views; ++v) {
        double a = p.view[v].rot_deg * M_PI / 180.0;
        for (int i = 0; i < p.n; ++i)
            for (int j = 0; j < p.n; ++j) {
                double x = (j - c) * p.pitch_mm, y = (i - c) * p.pitch_mm;
                double X = cos(a) * x - sin(a) * y + p.view[v].shift_x * p.pitch_mm;
                double Y = sin(a) * x + cos(a) * y + p.view[v].shift_y * p.pitch_mm;
                double fj = X / p.pitch_mm + c, fi = Y / p.pitch_mm + c;
                int on = fabs(fj - lround(fj)) < 1e-9 && fabs(fi - lround(fi)) < 1e-9 &&
                         lround(fj) >= 0 && lround(fj) < p.n && lround(fi) >= 0 && lround(fi) < p.n;
                int ni = -1, nj = -1;
                int got = sc_grid_mark_node(&p, v, i, j, &ni, &nj);
                assert_int_equal(got, on);
                if (on) {
                    assert_int_equal(ni, lround(fi));
                    assert_int_equal(nj, lround(fj));
                }
            }
        /* a plate-frame vector rotates the same way */
        double sx, sy;
        sc_grid_rotate(p.view[v].rot_deg, 0.3, -0.7, &sx, &sy);
        assert_true(fabs(sx - (cos(a) * 0.3 + sin(a) * 0.7)) < 1e-12);
        assert_true(fabs(sy - (sin(a) * 0.3 - cos(a) * 0.7)) < 1e-12);
    }
    sc_grid_plan_free(&p);
}

static void test_restricted_view(void **state)
{
    (void)state;
    sc_grid_plan p = make_plan(9, 1.0);
    add_view(&p, 0, -3, 0);
    p.view[0].restricted = 1;
    p.view[0].row_sel[4] = 1;
    p.view[0].col_sel[4] = p.view[0].col_sel[5] = 1;
    int count = 0;
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j)
            count += sc_grid_view_measures(&p, 0, i, j);
    /* row 4: columns 3..8 land on the grid (j-3 >= 0) -> 6; columns 4, 5: 9 rows each minus row 4 */
    assert_int_equal(count, 6 + 2 * 8);
    sc_grid_plan_free(&p);
}

static void test_gauge_projection(void **state)
{
    (void)state;
    sc_grid_plan p = make_plan(9, 2.0);
    int nn = 81;
    double gx[81], gy[81];
    srand(3);
    for (int k = 0; k < nn; ++k) {
        gx[k] = rand() / (double)RAND_MAX - 0.5;
        gy[k] = rand() / (double)RAND_MAX - 0.5;
    }
    sc_grid_gauge_stage(&p, gx, gy);
    double st[4] = {0};
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j) {
            double x, y;
            sc_grid_node_xy_mm(&p, i, j, &x, &y);
            int k = i * 9 + j;
            st[0] += gx[k];
            st[1] += gy[k];
            st[2] += x * gy[k] - y * gx[k];
            st[3] += x * gx[k] + y * gy[k];
        }
    for (int q = 0; q < 4; ++q)
        assert_true(fabs(st[q]) < 1e-12);
    /* projecting twice changes nothing */
    double hx[81], hy[81];
    memcpy(hx, gx, sizeof hx);
    memcpy(hy, gy, sizeof hy);
    sc_grid_gauge_stage(&p, hx, hy);
    for (int k = 0; k < nn; ++k)
        assert_true(fabs(hx[k] - gx[k]) < 1e-14 && fabs(hy[k] - gy[k]) < 1e-14);
    /* O and R of a pure first-order map */
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j) {
            double x, y;
            sc_grid_node_xy_mm(&p, i, j, &x, &y);
            gx[i * 9 + j] = 2e-5 * y * 1e3 + 3e-5 * x * 1e3;
            gy[i * 9 + j] = 2e-5 * x * 1e3 - 3e-5 * y * 1e3;
        }
    double O, R;
    sc_grid_first_order(&p, gx, gy, &O, &R);
    assert_true(fabs(O - 2e-5) < 1e-18 && fabs(R - 3e-5) < 1e-18); /* dimensionless */
    sc_grid_plan_free(&p);
}

static void test_synthesize_model(void **state)
{
    (void)state;
    sc_grid_plan p = make_plan(5, 1.0);
    add_view(&p, 90, 0, 0);
    add_view(&p, 0, 1, 0);
    double gx[25], gy[25], ax[25], ay[25], dx0[25], dy0[25], dx1[25], dy1[25];
    for (int k = 0; k < 25; ++k) {
        gx[k] = k;
        gy[k] = 100 + k;
        ax[k] = 1000 + k;
        ay[k] = 2000 + k;
    }
    double tx[2] = {0.5, -0.25}, ty[2] = {0.125, 2}, th[2] = {1000, -500};
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    double *tables[10] = {0}; /* the caller's own per-view tables (5 kinds x 2 views) */
    d.plan = p; /* borrowed: d is not freed */
    d.dx_um = tables, d.dy_um = tables + 2, d.ux_um = tables + 4, d.uy_um = tables + 6;
    d.t_s = tables + 8;
    d.dx_um[0] = dx0;
    d.dy_um[0] = dy0;
    d.dx_um[1] = dx1;
    d.dy_um[1] = dy1;
    sc_grid_synthesize(&p, gx, gy, ax, ay, tx, ty, th, &d);
    /* view 0 (rot 90): mark (i=0, j=4) at plate (2, -2) -> stage (2, 2) = node (4, 4) */
    int k = 0 * 5 + 4, q = 4 * 5 + 4;
    assert_true(fabs(dx0[k] - (gx[q] - ay[k] + 0.5 - 1000 * 2.0 * 1e-3)) < 1e-12);
    assert_true(fabs(dy0[k] - (gy[q] + ax[k] + 0.125 + 1000 * 2.0 * 1e-3)) < 1e-12);
    /* view 1 (shift +1): column 4 falls off the grid */
    assert_true(isnan(dx1[2 * 5 + 4]));
    /* mark (1, 1) -> node (1, 2) at (0, -1) mm */
    k = 1 * 5 + 1;
    q = 1 * 5 + 2;
    assert_true(fabs(dx1[k] - (gx[q] + ax[k] - 0.25 - (-500) * (-1.0) * 1e-3)) < 1e-12);
    assert_true(fabs(dy1[k] - (gy[q] + ay[k] + 2 + (-500) * 0.0)) < 1e-12);
    sc_grid_plan_free(&p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mark_node_matches_rotation_matrix),
        cmocka_unit_test(test_restricted_view),
        cmocka_unit_test(test_gauge_projection),
        cmocka_unit_test(test_synthesize_model),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
