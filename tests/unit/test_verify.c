/* Unit tests of the verification of a compensated machine and its decision rule
 * (selfcal/verify.h): the three verdicts of the guarded rule and the simple rule at and around
 * their boundaries, U from its parts (given noise, stated noise, the residuals) and given
 * outright, on re-measurements built here with a known largest residual. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/lut.h"
#include "selfcal/plate_map.h"
#include "selfcal/verify.h"

#define TMP SELFCAL_TEST_TMP "/verify_"

static void test_decide(void **state)
{
    (void)state;
    const sc_verify_rule G = SC_VERIFY_RULE_GUARDED, S = SC_VERIFY_RULE_SIMPLE;
    /* guarded: max 1, U 0.25 */
    assert_int_equal(sc_verify_decide(G, 1.0, 1.25, 0.25), SC_VERIFY_PASS);  /* max + U = T */
    assert_int_equal(sc_verify_decide(G, 1.0, 2.0, 0.25), SC_VERIFY_PASS);
    assert_int_equal(sc_verify_decide(G, 1.0, 1.2, 0.25), SC_VERIFY_INCONCLUSIVE);
    assert_int_equal(sc_verify_decide(G, 1.0, 1.0, 0.25), SC_VERIFY_INCONCLUSIVE);
    assert_int_equal(sc_verify_decide(G, 1.0, 0.75, 0.25), SC_VERIFY_INCONCLUSIVE); /* max − U = T */
    assert_int_equal(sc_verify_decide(G, 1.0, 0.7, 0.25), SC_VERIFY_FAIL);
    assert_int_equal(sc_verify_decide(G, 1.0, 1.0, NAN), SC_VERIFY_INCONCLUSIVE); /* no U */
    assert_int_equal(sc_verify_decide(G, 1.0, NAN, 0.25), SC_VERIFY_NO_VERDICT);
    /* simple: U plays no part */
    assert_int_equal(sc_verify_decide(S, 1.0, 1.0, 0.25), SC_VERIFY_PASS);
    assert_int_equal(sc_verify_decide(S, 1.0, 0.99, 0.0), SC_VERIFY_FAIL);
    assert_int_equal(sc_verify_decide(S, 1.0, 1.2, 5.0), SC_VERIFY_PASS);
    assert_string_equal(sc_verify_verdict_name(SC_VERIFY_INCONCLUSIVE), "inconclusive");
    assert_string_equal(sc_verify_rule_name(G), "guarded");
    assert_int_equal(sc_verify_rule_from_name("guarded"), G);
    assert_int_equal(sc_verify_rule_from_name("simple"), S);
    assert_int_equal(sc_verify_rule_from_name("strict"), -1);
}

/* The fixtures: a plate error of N = 5 (zero), a zero table over the stage, and a re-measurement
 * (one view, rot 0) with every mark where it belongs except mark (2, 2) off by d µm in x;
 * sigma_um: the view's stated noise (NaN: none). */
static void fixtures(double d_um, double sigma_um)
{
    const int n = 5;
    double ax[25] = {0}, ay[25] = {0};
    sc_plate_map m = {n, ax, ay};
    sc_error err;
    assert_int_equal(sc_plate_map_write(TMP "A.csv", &m, &err), SC_OK);
    sc_lut *lut = malloc(sizeof *lut);
    assert_non_null(lut);
    sc_lut_init(lut);
    lut->nx = lut->ny = 5;
    lut->x0_mm = lut->y0_mm = -2.0;
    lut->px_mm = lut->py_mm = 1.0;
    for (int k = 0; k < 25; ++k)
        lut->gx_um[k] = lut->gy_um[k] = 0.0;
    assert_int_equal(sc_lut_write_file(TMP "T.lut", lut, SC_LUT_ENC_AUTO, &err), SC_OK);
    free(lut);
    FILE *f = fopen(TMP "V.csv", "w");
    assert_non_null(f);
    fputs("# selfcal-grid v1\n# N = 5\n# pitch_mm = 1\n", f);
    if (isfinite(sigma_um))
        fprintf(f, "# view 0: rot=0 shift=0,0 sigma_um=%g\n", sigma_um);
    else
        fputs("# view 0: rot=0 shift=0,0\n", f);
    fputs("view,i,j,x_mm,y_mm\n", f);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            fprintf(f, "0,%d,%d,%.12f,%.12f\n", i, j, (j - 2) + (i == 2 && j == 2 ? d_um * 1e-3 : 0),
                    (double)(i - 2));
    fclose(f);
}

static sc_verify_verdict run_case(sc_verify_opts *o, sc_verify_result *r)
{
    o->measurement = TMP "V.csv";
    o->table = TMP "T.lut";
    o->artifact = TMP "A.csv";
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_verify_run(o, r, &err), SC_OK);
    return r->verdict;
}

/* A mark 1 µm off: the per-view misalignment takes 1/25 of it, so max |r| = 0.96 µm; with U
 * = 0.2 µm the guarded rule passes at T ≥ 1.16, fails below 0.76, and is inconclusive between. */
static void test_three_verdicts(void **state)
{
    (void)state;
    fixtures(1.0, NAN);
    const double T[3] = {1.2, 0.7, 1.0};
    const sc_verify_verdict want[3] = {SC_VERIFY_PASS, SC_VERIFY_FAIL, SC_VERIFY_INCONCLUSIVE};
    for (int c = 0; c < 3; ++c) {
        sc_verify_opts o;
        sc_verify_opts_init(&o);
        o.rule = SC_VERIFY_RULE_GUARDED;
        o.u_verify_um = 0.2;
        o.tolerance_um = T[c];
        sc_verify_result r;
        assert_int_equal(run_case(&o, &r), want[c]);
        assert_true(fabs(r.st_after.max - 0.96) < 1e-6);
        assert_true(r.u.given && r.u.U_um == 0.2);
        sc_verify_result_free(&r);
        o.rule = SC_VERIFY_RULE_SIMPLE; /* the same case under simple acceptance */
        assert_int_equal(run_case(&o, &r), T[c] >= 0.96 ? SC_VERIFY_PASS : SC_VERIFY_FAIL);
        sc_verify_result_free(&r);
    }
}

/* U from its parts: σ given, stated in the file, or from the residuals; u(A) given or σ. */
static void test_u_parts(void **state)
{
    (void)state;
    fixtures(1.0, 0.03);
    sc_verify_opts o;
    sc_verify_opts_init(&o);
    o.rule = SC_VERIFY_RULE_GUARDED;
    o.tolerance_um = 1.0;
    sc_verify_result r;
    run_case(&o, &r); /* stated: σ = 0.03, u(A) = σ */
    assert_int_equal(r.u.sigma_source, SC_VERIFY_NOISE_STATED);
    assert_true(fabs(r.u.sigma_um - 0.03) < 1e-12);
    assert_false(r.u.u_plate_given);
    assert_true(r.u.quant_um >= 0 && r.u.quant_um < 1e-4);
    double q = r.u.quant_um / sqrt(3.0);
    assert_true(fabs(r.u.U_um - 2 * sqrt(2 * 0.03 * 0.03 + q * q)) < 1e-12);
    sc_verify_result_free(&r);
    o.sigma_r_um = 0.05; /* given wins over stated */
    o.u_plate_um = 0.12;
    run_case(&o, &r);
    assert_int_equal(r.u.sigma_source, SC_VERIFY_NOISE_GIVEN);
    assert_true(fabs(r.u.U_um - 2 * sqrt(0.05 * 0.05 + 0.12 * 0.12 + q * q)) < 1e-12);
    /* max 0.96, U = 0.26: T = 1 is inconclusive */
    assert_int_equal(r.verdict, SC_VERIFY_INCONCLUSIVE);
    sc_verify_result_free(&r);
    fixtures(1.0, NAN); /* nothing stated: the residuals' RMS per coordinate */
    sc_verify_opts_init(&o);
    o.rule = SC_VERIFY_RULE_GUARDED;
    o.tolerance_um = 1.0;
    run_case(&o, &r);
    assert_int_equal(r.u.sigma_source, SC_VERIFY_NOISE_RESIDUALS);
    assert_true(fabs(r.u.sigma_um - r.st_after.rms / sqrt(2.0)) < 1e-12);
    assert_true(r.u.sigma_um > 0);
    sc_verify_result_free(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_decide),
        cmocka_unit_test(test_three_verdicts),
        cmocka_unit_test(test_u_parts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
