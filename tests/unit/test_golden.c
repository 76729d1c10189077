/* Golden files in the manner of gpsd's regressions: a stage map, a plate error, a profile result,
 * a grid summary and a version-1 table are committed in tests/data/golden/. Each test reads its
 * fixture with today's code and checks exact values, then writes the same content again and
 * compares byte for byte, so that a change of any format cannot slip in unnoticed.
 *
 * After a deliberate format change (with its version, docs and SPEC consequences), regenerate:
 *     SELFCAL_GOLDEN_REGEN=1 build/tests/test_golden    (writes into tests/data/golden/)
 * and review the diff before committing it. */
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

#include "selfcal/correct.h"
#include "selfcal/grid_io.h"
#include "selfcal/lut.h"
#include "selfcal/plate_map.h"
#include "selfcal/profile_file.h"
#include "selfcal/stage_map.h"

#define GOLDEN SELFCAL_GOLDEN_DIR "/"
#define TMP SELFCAL_TEST_TMP "/golden_"

static int regen(void)
{
    const char *e = getenv("SELFCAL_GOLDEN_REGEN");
    return e && *e && strcmp(e, "0") != 0;
}

/* Contents of a file (NUL-terminated, *len bytes); NULL if unreadable. */
static unsigned char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    unsigned char *buf = NULL;
    size_t cap = 0, n = 0, got;
    do {
        if (n + 4096 + 1 > cap) {
            cap = 2 * cap + 8192;
            unsigned char *nb = realloc(buf, cap);
            assert_non_null(nb);
            buf = nb;
        }
        got = fread(buf + n, 1, 4096, f);
        n += got;
    } while (got > 0);
    fclose(f);
    buf[n] = 0;
    *len = n;
    return buf;
}

/* The freshly written file must equal the golden one byte for byte (or, when regenerating,
 * becomes it). */
static void same_bytes(const char *fresh, const char *golden)
{
    size_t la, lb;
    unsigned char *a = slurp(fresh, &la);
    assert_non_null(a);
    if (regen()) {
        FILE *f = fopen(golden, "wb");
        assert_non_null(f);
        assert_int_equal(fwrite(a, 1, la, f), la);
        fclose(f);
        print_message("regenerated %s\n", golden);
    }
    unsigned char *b = slurp(golden, &lb);
    if (!b)
        fail_msg("golden file %s is missing", golden);
    if (la != lb || memcmp(a, b, la) != 0) {
        size_t k = 0;
        while (k < la && k < lb && a[k] == b[k])
            ++k;
        free(a);
        free(b);
        fail_msg("%s differs from the golden %s at byte %zu (sizes %zu, %zu): a format changed",
                 fresh, golden, k, la, lb);
    }
    free(a);
    free(b);
}

/* ---- the fixtures' contents, exactly representable (multiples of 1/8 µm and 1/64) ---- */

enum { MAP_NX = 5, MAP_NY = 3, PLATE_N = 3, PROF_N = 8, PROF_NEY = 6 };

static double map_gx(int k) { return 0.125 * (k - 7); }
static double map_gy(int k) { return -0.25 + 0.0625 * k; }
static double map_u(int k) { return k == 4 ? NAN : (1 + k) / 64.0; }
static double prof_f(int i) { return 0.125 * i * (i - 3); }
static double prof_ey(int i) { return 0.25 - 0.125 * i; }

static void test_golden_stage_map(void **state)
{
    (void)state;
    if (regen()) {
        double gx[MAP_NX * MAP_NY], gy[MAP_NX * MAP_NY], u[MAP_NX * MAP_NY];
        for (int k = 0; k < MAP_NX * MAP_NY; ++k)
            gx[k] = map_gx(k), gy[k] = map_gy(k), u[k] = map_u(k);
        sc_stage_map m = {MAP_NX, MAP_NY, -5.0, 2.5, 2.5, 1.25, gx, gy, u, u};
        sc_error err;
        assert_int_equal(sc_stage_map_write(GOLDEN "stage_map.csv", &m, &err), SC_OK);
    }
    sc_stage_map m;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_stage_map_read(GOLDEN "stage_map.csv", &m, &err), SC_OK);
    assert_int_equal(m.nx, MAP_NX);
    assert_int_equal(m.ny, MAP_NY);
    assert_true(m.x0_mm == -5.0 && m.y0_mm == 2.5 && m.px_mm == 2.5 && m.py_mm == 1.25);
    for (int k = 0; k < MAP_NX * MAP_NY; ++k) {
        assert_true(m.gx_um[k] == map_gx(k) && m.gy_um[k] == map_gy(k));
        assert_true(k == 4 ? isnan(m.ugx_um[k]) : m.ugx_um[k] == map_u(k));
    }
    assert_int_equal(sc_stage_map_write(TMP "stage_map.csv", &m, &err), SC_OK);
    same_bytes(TMP "stage_map.csv", GOLDEN "stage_map.csv");
    sc_stage_map_free(&m);
}

static void test_golden_plate_map(void **state)
{
    (void)state;
    double ax[PLATE_N * PLATE_N], ay[PLATE_N * PLATE_N];
    for (int k = 0; k < PLATE_N * PLATE_N; ++k)
        ax[k] = 0.5 - 0.125 * k, ay[k] = 0.0625 * k;
    ax[2] = ay[2] = NAN; /* a mark no method determined */
    sc_plate_map want = {PLATE_N, ax, ay}, m;
    sc_error err;
    if (regen())
        assert_int_equal(sc_plate_map_write(GOLDEN "plate_error.csv", &want, &err), SC_OK);
    assert_int_equal(sc_plate_map_read(GOLDEN "plate_error.csv", &m, &err), SC_OK);
    assert_int_equal(m.n, PLATE_N);
    for (int k = 0; k < PLATE_N * PLATE_N; ++k)
        assert_true(k == 2 ? isnan(m.ax_um[k]) && isnan(m.ay_um[k])
                           : m.ax_um[k] == ax[k] && m.ay_um[k] == ay[k]);
    assert_int_equal(sc_plate_map_write(TMP "plate_error.csv", &m, &err), SC_OK);
    same_bytes(TMP "plate_error.csv", GOLDEN "plate_error.csv");
    sc_plate_map_free(&m);
}

static void test_golden_profile_result(void **state)
{
    (void)state;
    double f[PROF_N], uf[PROF_N], ey[PROF_N];
    for (int i = 0; i < PROF_N; ++i)
        f[i] = prof_f(i), uf[i] = 1 / 64.0, ey[i] = prof_ey(i);
    sc_error err;
    if (regen())
        assert_int_equal(sc_profile_write_result(GOLDEN "profile_result.csv", PROF_N, 0.5, f, uf, ey,
                                                 PROF_NEY, &err),
                         SC_OK);
    sc_profile_result r;
    assert_int_equal(sc_profile_read_result(GOLDEN "profile_result.csv", &r, &err), SC_OK);
    assert_int_equal(r.n, PROF_N);
    assert_int_equal(r.n_ey, PROF_NEY);
    for (int i = 0; i < PROF_N; ++i) {
        assert_true(r.x_mm[i] == 0.5 * i && r.f_um[i] == f[i] && r.uf_um[i] == uf[i]);
        assert_true(i < PROF_NEY ? r.ey_um[i] == ey[i] : isnan(r.ey_um[i]));
    }
    assert_int_equal(sc_profile_write_result(TMP "profile_result.csv", r.n, 0.5, r.f_um, r.uf_um,
                                             r.ey_um, r.n_ey, &err),
                     SC_OK);
    same_bytes(TMP "profile_result.csv", GOLDEN "profile_result.csv");
    sc_profile_result_free(&r);
}

/* A summary has no reader: the fixed result is written and compared. */
static void test_golden_summary(void **state)
{
    (void)state;
    sc_grid_plan p;
    memset(&p, 0, sizeof p);
    p.n = 9;
    p.pitch_mm = 1.5;
    p.origin_mm[0] = 120.25;
    p.origin_mm[1] = -37.5;
    assert_int_equal(sc_grid_plan_views(&p, 4, NULL), SC_OK);
    p.view[1].rot_deg = 90;
    p.view[2].shift_x = 2;
    p.view[3].shift_x = -3;
    sc_grid_result res;
    memset(&res, 0, sizeof res);
    assert_int_equal(sc_grid_result_views(&res, 4, NULL), SC_OK);
    memset(res.view_block, 0, sizeof(double) * 4 * SC_GRID_RESULT_VIEW_ARRAYS); /* as before: 0 */
    res.O = 1.25e-6;
    res.R = -2.5e-7;
    for (int v = 0; v < 4; ++v) {
        res.tx_um[v] = 0.125 * v;
        res.ty_um[v] = -0.0625 * v;
        res.theta_urad[v] = v == 3 ? NAN : 0.5 * v;
    }
    res.residual_rms_um = 0.0078125;
    res.outlier_alpha = 0.05; /* the least squares' outlier test */
    res.outlier_alpha_coord = 2.1371e-5;
    res.outlier_crit = 4.25;
    res.n_outlier_tests = 2400;
    res.sigma_r_est_um = 0.009765625;
    res.sigma_r_used_um = NAN;
    res.n_measurements = 566;
    res.dof = 237;
    /* the least-squares fields (an exact method leaves them NaN) */
    res.uO = 0.125e-6;
    res.uR = NAN;
    for (int v = 0; v < 4; ++v)
        res.utx_um[v] = res.uty_um[v] = 0.0078125, res.utheta_urad[v] = 0.25;
    res.misalignment_unique = 1;
    res.weighted = 1;
    res.variance_factor = 1.0625;
    res.chi2_lo = 0.8125;
    res.chi2_hi = 1.1875;
    res.chi2_pass = 1;
    sc_error err;
    assert_int_equal(sc_grid_write_summary(TMP "summary.json", "double-shift", &p, &res, &err),
                     SC_OK);
    same_bytes(TMP "summary.json", GOLDEN "summary.json");
    sc_grid_result_free_views(&res);
    sc_grid_plan_free(&p);
}

/* The table: built from the golden map and profile with fixed provenance; the bytes must equal
 * the golden version-1 table, which decodes to exactly those values and loads in the core. */
static void test_golden_table(void **state)
{
    (void)state;
    sc_lut *lut = malloc(sizeof *lut), *back = malloc(sizeof *back);
    assert_non_null(lut);
    assert_non_null(back);
    sc_lut_init(lut);
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_lut_read_map(GOLDEN "stage_map.csv", lut, &err), SC_OK);
    assert_int_equal(sc_lut_read_profile(GOLDEN "profile_result.csv", SC_CORR_AXIS_X,
                                         SC_CORR_AXIS_Y, &lut->profile[0], &err),
                     SC_OK);
    lut->n_profiles = 1;
    snprintf(lut->prov.method, sizeof lut->prov.method, "golden");
    lut->prov.created_unix_s = 1700000000;
    lut->prov.sigma_um = 0.0078125;
    lut->prov.n_sources = 2;
    assert_int_equal(sc_sha256_file(GOLDEN "stage_map.csv", lut->prov.sha256[0], &err), SC_OK);
    assert_int_equal(sc_sha256_file(GOLDEN "profile_result.csv", lut->prov.sha256[1], &err), SC_OK);
    assert_int_equal(sc_lut_write_file(TMP "table_v1.lut", lut, SC_LUT_ENC_AUTO, &err), SC_OK);
    same_bytes(TMP "table_v1.lut", GOLDEN "table_v1.lut");

    assert_int_equal(sc_lut_read_file(GOLDEN "table_v1.lut", back, &err), SC_OK);
    assert_int_equal(back->nx, MAP_NX);
    assert_int_equal(back->ny, MAP_NY);
    assert_true(back->x0_mm == -5.0 && back->px_mm == 2.5 && back->py_mm == 1.25);
    for (int k = 0; k < MAP_NX * MAP_NY; ++k)
        assert_true(back->gx_um[k] == map_gx(k) && back->gy_um[k] == map_gy(k));
    assert_int_equal(back->n_profiles, 1);
    assert_int_equal(back->profile[0].n, PROF_NEY);
    for (int i = 0; i < PROF_NEY; ++i)
        assert_true(back->profile[0].err_um[i] == prof_ey(i));
    assert_string_equal(back->prov.method, "golden");
    assert_true(back->prov.created_unix_s == 1700000000);

    /* the core: node (i=1, j=2) at x = 0, y = 3.75; the profile (x from 0 mm, 0.5 mm steps)
     * gives ey(0) in y. measure mode: out = in - G - profile offsets. */
    size_t len;
    unsigned char *img = slurp(GOLDEN "table_v1.lut", &len);
    assert_non_null(img);
    sc_corr_table *t = malloc(sizeof *t);
    assert_non_null(t);
    assert_int_equal(sc_corr_load(t, img, len), 0);
    double in[3] = {0.0, 3.75, 0.0}, out[3];
    sc_corr_apply(t, SC_CORR_MEASURE, in, out);
    int k = 1 * MAP_NX + 2;
    assert_true(fabs(out[0] - (0.0 - map_gx(k) * 1e-3)) < 1e-12);
    assert_true(fabs(out[1] - (3.75 - map_gy(k) * 1e-3 - prof_ey(0) * 1e-3)) < 1e-12);
    free(t);
    free(img);
    free(lut);
    free(back);
}

int main(void)
{
    mkdir(SELFCAL_TEST_TMP, 0777);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_golden_stage_map),
        cmocka_unit_test(test_golden_plate_map),
        cmocka_unit_test(test_golden_profile_result),
        cmocka_unit_test(test_golden_summary),
        cmocka_unit_test(test_golden_table),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
