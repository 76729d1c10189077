/* The plate's scale and temperature (SPEC §11, grid_scale.c): Student's t, the noise of the
 * magnification gauge against a brute-force propagation, the reader and writer of the scale lines,
 * and the model recovered from noise-free data. */
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
#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_scale.h"
#include "selfcal/grid_sim.h"

/* Reference values of t_0.975 (and one lower quantile): tables, and for 2.5 degrees of freedom
 * the root of the numerically integrated density. */
static void test_student_t(void **state)
{
    (void)state;
    assert_true(fabs(sc_student_t_quantile(0.975, 1) - 12.706204736) < 1e-7);
    assert_true(fabs(sc_student_t_quantile(0.975, 10) - 2.228138852) < 1e-8);
    assert_true(fabs(sc_student_t_quantile(0.975, 30) - 2.042272456) < 1e-8);
    assert_true(fabs(sc_student_t_quantile(0.975, 2.5) - 3.574654842) < 1e-7);
    assert_true(fabs(sc_student_t_quantile(0.025, 5) + 2.570581836) < 1e-8);
    assert_true(fabs(sc_student_t_quantile(0.975, INFINITY) - 1.959963985) < 1e-8);
    assert_true(isnan(sc_student_t_quantile(1.0, 5)));
    assert_true(isnan(sc_student_t_quantile(0.5, 0)));
}

/* The estimator's answer for data d: G in the SPEC gauge and the plate's magnification m. */
static void solve(const sc_grid_lsq_plan *q, const sc_grid_data *d, sc_grid_result *r, double *m)
{
    sc_error err;
    assert_int_equal(sc_grid_lsq_execute(q, d, 1.0, r, &err), SC_OK);
    const sc_grid_plan *p = &d->plan;
    double s = 0, r2 = 0;
    for (int k = 0; k < p->n * p->n; ++k) {
        double x, y;
        if (!isfinite(r->ax_um[k]))
            continue;
        sc_grid_mark_xy_mm(p, k / p->n, k % p->n, &x, &y);
        s += x * r->ax_um[k] + y * r->ay_um[k];
        r2 += x * x + y * y;
    }
    *m = 1e3 * s / r2;
}

/* Var(m) and Cov(G, m) of sc_grid_lsq_plate_magnification against the estimator applied to each
 * unit equation in turn (unit weights: Var = Σ_e L_e², Cov = Σ_e L_G,e L_m,e), on a plan with a
 * partial view and a 180° one. */
static void test_magnification_noise(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    memset(&p, 0, sizeof p);
    p.n = 7, p.pitch_mm = 2.0;
    assert_int_equal(sc_grid_plan_views(&p, 4, &err), SC_OK);
    p.view[1].rot_deg = 90;
    p.view[2].shift_x = 1;
    p.view[3].rot_deg = 180, p.view[3].shift_y = -1;
    assert_int_equal(sc_grid_plan_check(&p, &err), SC_OK);
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    d.plan = p; /* the data own the plan from here */
    assert_int_equal(sc_grid_data_alloc(&d, &err), SC_OK);
    int nn = p.n * p.n, ns = (int)sc_grid_stage_nodes(&p);
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < nn; ++k)
            if (sc_grid_view_measures(&p, v, k / p.n, k % p.n))
                d.dx_um[v][k] = d.dy_um[v][k] = 0;
    sc_grid_lsq_plan *q = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&p, &d, NULL, &q, &err), SC_OK);
    double *buf = calloc(8 * (size_t)ns + 2 * (size_t)nn, sizeof(double));
    sc_grid_result r;
    memset(&r, 0, sizeof r);
    r.gx_um = buf, r.gy_um = buf + ns, r.ugx_um = buf + 2 * ns, r.ugy_um = buf + 3 * ns;
    r.ax_um = buf + 4 * ns, r.ay_um = buf + 4 * ns + nn;
    double *cx = buf + 4 * ns + 2 * nn, *cy = cx + ns, *refx = cy + ns, *refy = refx + ns;
    double var_m, ref_vm = 0;
    assert_int_equal(sc_grid_lsq_plate_magnification(q, &var_m, cx, cy), 0);
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < nn; ++k)
            for (int c = 0; c < 2 && isfinite(d.dx_um[v][k]); ++c) {
                double m;
                (c ? d.dy_um : d.dx_um)[v][k] = 1;
                solve(q, &d, &r, &m);
                (c ? d.dy_um : d.dx_um)[v][k] = 0;
                ref_vm += m * m;
                for (int i = 0; i < ns; ++i)
                    refx[i] += r.gx_um[i] * m, refy[i] += r.gy_um[i] * m;
            }
    assert_true(var_m > 0);
    assert_true(fabs(var_m - ref_vm) < 1e-9 * ref_vm);
    double scale = 0;
    for (int i = 0; i < ns; ++i)
        scale = fmax(scale, fmax(fabs(refx[i]), fabs(refy[i])));
    assert_true(scale > 0);
    for (int i = 0; i < ns; ++i) {
        assert_true(fabs(cx[i] - refx[i]) < 1e-9 * scale);
        assert_true(fabs(cy[i] - refy[i]) < 1e-9 * scale);
    }
    sc_grid_lsq_plan_destroy(q);
    sc_grid_data_free(&d);
    free(buf);
}

/* The scale lines written and read back; bad ones refused with the line. */
static void test_scale_lines(void **state)
{
    (void)state;
    const char *path = "test_grid_scale_lines.csv";
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_ye(5, 1.0, 0, 0, &p, &err), SC_OK);
    p.scale.has_plate_scale = 1, p.scale.plate_scale_ppm = -1.25, p.scale.u_plate_scale_ppm = 0.1;
    p.scale.has_cte = 1, p.scale.cte_ppm_per_K = 11.5, p.scale.u_cte_ppm_per_K = 0.25;
    p.scale.has_temps = 1, p.scale.temp_u_K = 0.02;
    for (int v = 0; v < p.n_views; ++v)
        p.view[v].temp_C = 20.0 + 0.125 * v;
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    sc_grid_write_header(fp, &p);
    fclose(fp);
    sc_grid_data d;
    sc_grid_file_info info;
    assert_int_equal(sc_grid_read(path, &d, &info, &err), SC_OK);
    const sc_grid_scale *s = &d.plan.scale;
    assert_true(s->has_plate_scale && s->has_cte && s->has_temps);
    assert_true(s->plate_scale_ppm == -1.25 && s->u_plate_scale_ppm == 0.1);
    assert_true(s->cte_ppm_per_K == 11.5 && s->u_cte_ppm_per_K == 0.25 && s->temp_u_K == 0.02);
    for (int v = 0; v < p.n_views; ++v)
        assert_true(d.plan.view[v].temp_C == 20.0 + 0.125 * v);
    assert_true(fabs(sc_grid_view_scale_ppm(&d.plan, 2) - (-1.25 + 11.5 * 0.25)) < 1e-12);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&info);
    sc_grid_plan_free(&p);
    static const struct {
        const char *text;
        long line;
    } bad[] = {
        {"# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# plate_scale_ppm = 1, -0.5\n"
         "# view 0: rot=0 shift=0,0\n", 4},
        {"# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# plate_cte_ppm_per_K = 8, -1\n"
         "# view 0: rot=0 shift=0,0\n", 4},
        {"# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# view 0: rot=0 shift=0,0 temp_C=20\n", 4},
        {"# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# plate_cte_ppm_per_K = 8, 1\n"
         "# view 0: rot=0 shift=0,0 temp_C=20\n# view 1: rot=90 shift=0,0\n", 6},
        {"# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# plate_cte_ppm_per_K = 8, 1\n"
         "# view 0: rot=0 shift=0,0 temp_C=hot\n", 5},
        {"# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n# temp_u_K = -1\n"
         "# view 0: rot=0 shift=0,0\n", 4},
    };
    for (size_t t = 0; t < sizeof bad / sizeof bad[0]; ++t) {
        fp = fopen(path, "w");
        assert_non_null(fp);
        fputs(bad[t].text, fp);
        fclose(fp);
        sc_error_clear(&err);
        assert_int_equal(sc_grid_read(path, &d, &info, &err), SC_E_INPUT);
        assert_int_equal(err.line, bad[t].line);
        sc_grid_file_info_free(&info);
    }
    remove(path);
}

/* Simulated with E, A, temperatures and M, noise-free: G (with M), M and A recovered to 1e-6 µm;
 * the same data without their temperatures give a G off by far more. */
static void test_model_recovered(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_double_shift(15, 1.0, 0, 0, &p, &err), SC_OK);
    p.scale = (sc_grid_scale){1, 3.0, 0.1, 1, 10.0, 0.5, 1, 0.05};
    const double T[4] = {20.4, 19.7, 20.9, 20.2}, M = -12.5;
    for (int v = 0; v < 4; ++v)
        p.view[v].temp_C = T[v];
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    d.plan = p; /* the data own the plan from here */
    assert_int_equal(sc_grid_data_alloc(&d, &err), SC_OK);
    size_t ns = (size_t)sc_grid_stage_nodes(&p), nn = 225;
    double *buf = malloc(sizeof(double) * (4 * ns + 2 * nn + 12 + sc_grid_sim_work_doubles_plan(&p)));
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    t.gx_um = buf, t.gy_um = buf + ns, t.ax_um = buf + 2 * ns, t.ay_um = buf + 2 * ns + nn;
    t.tx_um = buf + 2 * ns + 2 * nn, t.ty_um = t.tx_um + 4, t.theta_urad = t.ty_um + 4;
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.sigma_r_um = 0;
    assert_int_equal(sc_grid_sim_run(&p, &sp, &t, &d, buf + 2 * ns + 2 * nn + 12, &err), SC_OK);
    sc_grid_sim_scale(&p, M, &t, &d);
    sc_grid_options o;
    sc_grid_options_default(&o);
    sc_grid_solution s;
    assert_int_equal(sc_grid_calibrate(&d, NULL, NULL, &o, &s, &err), SC_OK);
    double worst = 0;
    for (size_t k = 0; k < ns; ++k)
        worst = fmax(worst, fmax(fabs(s.res.gx_um[k] - t.gx_um[k]),
                                 fabs(s.res.gy_um[k] - t.gy_um[k])));
    for (size_t k = 0; k < nn; ++k)
        worst = fmax(worst, fmax(fabs(s.res.ax_um[k] - t.ax_um[k]),
                                 fabs(s.res.ay_um[k] - t.ay_um[k])));
    assert_true(worst <= 1e-6);
    assert_true(s.budget.applies && s.budget.magnification);
    assert_true(fabs(s.budget.magnification_ppm - M) < 1e-6);
    assert_true(s.budget.u_magnification_ppm > 0.1); /* at least U of E */
    sc_grid_solution_free(&s);
    d.plan.scale.has_temps = 0; /* the temperatures not known: each view's scale wrong */
    assert_int_equal(sc_grid_calibrate(&d, NULL, NULL, &o, &s, &err), SC_OK);
    worst = 0;
    for (size_t k = 0; k < ns; ++k)
        worst = fmax(worst, fmax(fabs(s.res.gx_um[k] - t.gx_um[k]),
                                 fabs(s.res.gy_um[k] - t.gy_um[k])));
    assert_true(worst > 0.02);
    sc_grid_solution_free(&s);
    sc_grid_data_free(&d);
    free(buf);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_student_t),
        cmocka_unit_test(test_magnification_noise),
        cmocka_unit_test(test_scale_lines),
        cmocka_unit_test(test_model_recovered),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
