/* Allocation-failure injection in the manner of SQLite's: for each library call below, run it
 * once failing the 1st allocation, again failing the 2nd, and so on until a run needs no failed
 * allocation. Every run that hit a failure must return SC_E_NOMEM (never SC_OK with work
 * silently skipped, never a crash), free what it allocated (LeakSanitizer checks at exit in the
 * sanitizer build) and leave its outputs empty.
 *
 * The hook is the linker's --wrap (see alloc_fail.cmake): in this test executable only, the
 * library's malloc/calloc/realloc/posix_memalign/aligned_alloc calls go through the counting
 * wrappers below. The library itself has no hook, no global state and no cost for it. */
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

#include "selfcal/grid_exact.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"
#include "selfcal/lut.h"
#include "selfcal/plate_map.h"
#include "selfcal/profile.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"
#include "selfcal/stage_map.h"
#include "../../libselfcal/src/io/profile_file_internal.h"

#define TMP SELFCAL_TEST_TMP "/allocfail_"

/* ---- the hook ---- */

static long fail_at;  /* fail the allocation with this number (1-based); 0: never */
static long counted;  /* allocations seen since the hook was armed */
static int injected;  /* 1 once a failure was injected */

static int fail_now(void)
{
    if (!fail_at)
        return 0;
    long k = __atomic_add_fetch(&counted, 1, __ATOMIC_SEQ_CST);
    if (k != fail_at)
        return 0;
    __atomic_store_n(&injected, 1, __ATOMIC_SEQ_CST);
    return 1;
}

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t m);
void *__real_realloc(void *p, size_t n);
int __real_posix_memalign(void **p, size_t a, size_t n);
void *__real_aligned_alloc(size_t a, size_t n);

void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t n, size_t m);
void *__wrap_realloc(void *p, size_t n);
int __wrap_posix_memalign(void **p, size_t a, size_t n);
void *__wrap_aligned_alloc(size_t a, size_t n);

void *__wrap_malloc(size_t n) { return fail_now() ? NULL : __real_malloc(n); }
void *__wrap_calloc(size_t n, size_t m) { return fail_now() ? NULL : __real_calloc(n, m); }
void *__wrap_realloc(void *p, size_t n) { return fail_now() ? NULL : __real_realloc(p, n); }
int __wrap_posix_memalign(void **p, size_t a, size_t n)
{
    return fail_now() ? 12 /* ENOMEM */ : __real_posix_memalign(p, a, n);
}
void *__wrap_aligned_alloc(size_t a, size_t n)
{
    return fail_now() ? NULL : __real_aligned_alloc(a, n);
}

typedef sc_status (*call_fn)(void *ctx, sc_error *err);

/* Run fn failing allocation k = 1, 2, ... until a run completes without a failure. */
static void every_allocation(const char *name, call_fn fn, void *ctx)
{
    /* SELFCAL_ALLOC_FROM=K starts at the K-th allocation (to debug one failure in gdb:
     * break fail_now if counted == K - 1). */
    const char *from = getenv("SELFCAL_ALLOC_FROM");
    long k0 = from ? atol(from) : 1;
    for (long k = k0 > 0 ? k0 : 1;; ++k) {
        sc_error err;
        sc_error_clear(&err);
        counted = 0;
        injected = 0;
        fail_at = k;
        sc_status st = fn(ctx, &err);
        fail_at = 0;
        if (!injected) {
            if (st != SC_OK)
                fail_msg("%s: status %d without an injected failure: %s", name, st, err.msg);
            print_message("%s: %ld allocations, each failure reported\n", name, k - 1);
            return;
        }
        if (st != SC_E_NOMEM)
            fail_msg("%s: allocation %ld failed but the call returned %d (%s)", name, k, st,
                     st == SC_OK ? "the failure was skipped" : err.msg);
        /* said in a message; a line number only with the file it is in */
        if (!err.msg[0] || (!err.file[0] && err.line != 0))
            fail_msg("%s: allocation %ld: message '%s', file '%s', line %ld", name, k, err.msg,
                     err.file, err.line);
        if (k > 100000)
            fail_msg("%s: no end of allocations", name);
    }
}

/* ---- the calls ---- */

static sc_status read_stage_map(void *ctx, sc_error *err)
{
    sc_stage_map m;
    sc_status st = sc_stage_map_read((const char *)ctx, &m, err);
    if (st != SC_OK)
        assert_null(m.gx_um);
    sc_stage_map_free(&m);
    return st;
}

static sc_status read_plate_map(void *ctx, sc_error *err)
{
    sc_plate_map m;
    sc_status st = sc_plate_map_read((const char *)ctx, &m, err);
    if (st != SC_OK)
        assert_null(m.ax_um);
    sc_plate_map_free(&m);
    return st;
}

static sc_status read_profile(void *ctx, sc_error *err)
{
    sc_profile_data d;
    sc_status st = sc_profile_read((const char *)ctx, &d, err);
    if (st != SC_OK)
        assert_null(d.m1_um[0]);
    sc_profile_data_free(&d);
    return st;
}

/* A result file above the writers' two-thread threshold: on failure, no file at all. */
static sc_status write_profile_result(void *ctx, sc_error *err)
{
    (void)ctx;
    enum { n = 40000 };
    static double f[n];
    const char *path = TMP "result_large.csv";
    remove(path);
    sc_status st = sc_profile_write_result(path, n, 0.5, f, f, f, n, err);
    struct stat sb;
    assert_int_equal(stat(path, &sb) == 0, st == SC_OK);
    return st;
}

/* The same file with its rows read by two threads (profile_file.c's fast pass at any size). */
static sc_status read_profile_two_threads(void *ctx, sc_error *err)
{
    sc_profile_data d;
    sc_status st = sc_profile_read_tuned((const char *)ctx, 0, NULL, &d, err);
    if (st != SC_OK)
        assert_null(d.m1_um[0]);
    sc_profile_data_free(&d);
    return st;
}

static sc_status read_profile_result(void *ctx, sc_error *err)
{
    sc_profile_result r;
    sc_status st = sc_profile_read_result((const char *)ctx, &r, err);
    if (st != SC_OK)
        assert_null(r.f_um);
    sc_profile_result_free(&r);
    return st;
}

static sc_status read_grid(void *ctx, sc_error *err)
{
    sc_grid_data d;
    sc_status st = sc_grid_read((const char *)ctx, &d, NULL, err);
    if (st == SC_OK)
        sc_grid_data_free(&d);
    return st;
}

static sc_status lut_from_files(void *ctx, sc_error *err)
{
    const char **paths = ctx;
    sc_lut *lut = __real_malloc(sizeof *lut);
    assert_non_null(lut);
    sc_lut_init(lut);
    sc_status st = sc_lut_read_map(paths[0], lut, err);
    if (st == SC_OK)
        st = sc_lut_read_profile(paths[1], 0, 1, &lut->profile[0], err);
    lut->n_profiles = 1;
    if (st == SC_OK)
        st = sc_lut_write_file(paths[2], lut, SC_LUT_ENC_AUTO, err);
    free(lut);
    return st;
}

typedef struct grid_ctx {
    sc_grid_data d;
    double *out; /* 6 n*n arrays for the result, then its per-view arrays */
} grid_ctx;

static void result_arrays(grid_ctx *g, sc_grid_result *res)
{
    size_t nn = (size_t)g->d.plan.n * (size_t)g->d.plan.n;
    memset(res, 0, sizeof *res);
    res->gx_um = g->out;
    res->gy_um = g->out + nn;
    res->ugx_um = g->out + 2 * nn;
    res->ugy_um = g->out + 3 * nn;
    res->ax_um = g->out + 4 * nn;
    res->ay_um = g->out + 5 * nn;
    size_t nv = (size_t)g->d.plan.n_views; /* per view: the caller's arrays, allocated here */
    double **pv[SC_GRID_RESULT_VIEW_ARRAYS] = {
        &res->tx_um, &res->ty_um, &res->theta_urad, &res->utx_um, &res->uty_um,
        &res->utheta_urad, &res->vx_um_s, &res->vy_um_s, &res->uvx_um_s, &res->uvy_um_s,
        &res->view_sigma_um, &res->view_noise_factor, &res->view_sigma_u_um};
    for (int a = 0; a < SC_GRID_RESULT_VIEW_ARRAYS; ++a)
        *pv[a] = g->out + 6 * nn + (size_t)a * nv;
}

static sc_status grid_lsq(void *ctx, sc_error *err)
{
    grid_ctx *g = ctx;
    sc_grid_lsq_plan *q = NULL;
    sc_grid_result res;
    result_arrays(g, &res);
    sc_status st = sc_grid_lsq_plan_create(&g->d.plan, &g->d, NULL, &q, err);
    if (st != SC_OK)
        assert_null(q);
    if (st == SC_OK)
        st = sc_grid_lsq_execute(q, &g->d, 0.01, &res, err);
    sc_grid_lsq_plan_destroy(q);
    return st;
}

static sc_status grid_exact(void *ctx, sc_error *err)
{
    grid_ctx *g = ctx;
    sc_grid_exact_plan *p = NULL;
    sc_grid_result res;
    result_arrays(g, &res);
    sc_status st = sc_grid_exact_plan_create(SC_GRID_DOUBLE_SHIFT, g->d.plan.n, &p, err);
    if (st != SC_OK)
        assert_null(p);
    if (st == SC_OK)
        st = sc_grid_exact_execute(p, &g->d, &res, err);
    sc_grid_exact_plan_destroy(p);
    return st;
}

typedef struct profile_ctx {
    int n, d1, d2;
    double *y1, *y2, *f, *uf;
} profile_ctx;

static sc_status profile_lsq(void *ctx, sc_error *err)
{
    profile_ctx *c = ctx;
    sc_profile_lsq_plan *p = NULL;
    sc_status st = sc_profile_lsq_plan_create(c->n, c->d1, c->d2, 1, 1, &p, err);
    if (st != SC_OK)
        assert_null(p);
    if (st == SC_OK)
        st = sc_profile_lsq_execute(p, c->y1, c->y2, c->f, NULL, NULL, err);
    if (st == SC_OK)
        st = sc_profile_lsq_uncertainty(p, c->uf, NULL, err);
    sc_profile_lsq_plan_destroy(p);
    return st;
}

static sc_status profile_dft(void *ctx, sc_error *err)
{
    profile_ctx *c = ctx;
    sc_profile_dft_plan *p = NULL;
    sc_status st = sc_profile_dft_plan_create(c->n, c->d1, c->d2, 1, 1, &p, err);
    if (st != SC_OK)
        assert_null(p);
    if (st == SC_OK)
        st = sc_profile_dft_execute(p, c->y1, c->y2, c->f, err);
    if (st == SC_OK)
        st = sc_profile_dft_uncertainty(p, c->uf, NULL, err);
    sc_profile_dft_plan_destroy(p);
    return st;
}

/* ---- fixtures ---- */

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    fputs(text, fp);
    fclose(fp);
}

static void test_readers(void **state)
{
    (void)state;
    write_text(TMP "map.csv", "i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n0,0,0,0,1,2,0.1,\n"
                              "0,1,1,0,3,4,,\n1,0,0,1,5,6,,\n1,1,1,1,7,8,,\n");
    write_text(TMP "plate.csv", "i,j,ax_um,ay_um\n0,0,1,1\n0,1,1,1\n0,2,1,1\n1,0,1,1\n1,1,,\n"
                                "1,2,1,1\n2,0,1,1\n2,1,1,1\n2,2,1,1\n");
    write_text(TMP "profile.csv", "# selfcal-profile v1\n# N = 6\n# s_mm = 1\n# scan 1: d=1\n"
                                  "# scan 2: d=2\n# sigma_disp_um = 0.01\nscan,n,m1_um,m2_um,m3_urad\n"
                                  "1,0,0,0,0\n1,1,0,0,0\n1,2,0,0,0\n1,3,0,0,0\n1,4,0,0,0\n"
                                  "2,0,0,0,0\n2,1,0,0,0\n2,2,0,0,0\n2,3,0,0,0\n");
    write_text(TMP "result.csv", "n,x_mm,f_um,uf_um,ey_um\n0,0,1,0.1,1\n1,1,2,0.1,2\n2,2,3,0.1,\n");
    every_allocation("sc_stage_map_read", read_stage_map, TMP "map.csv");
    every_allocation("sc_plate_map_read", read_plate_map, TMP "plate.csv");
    every_allocation("sc_profile_read", read_profile, TMP "profile.csv");
    every_allocation("sc_profile_read (two threads)", read_profile_two_threads, TMP "profile.csv");
    every_allocation("sc_profile_write_result (two threads)", write_profile_result, NULL);
    every_allocation("sc_profile_read_result", read_profile_result, TMP "result.csv");
    const char *paths[3] = {TMP "map.csv", TMP "result.csv", TMP "table.lut"};
    every_allocation("lut build (read map, profile, write)", lut_from_files, paths);
}

static void test_grid(void **state)
{
    (void)state;
    grid_ctx g;
    memset(&g, 0, sizeof g);
    sc_error err;
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    assert_int_equal(sc_grid_plan_double_shift(9, 1.0, 0, 0, &g.d.plan, &err), SC_OK);
    assert_int_equal(sc_grid_data_alloc(&g.d, &err), SC_OK);
    size_t nn = 81;
    size_t nv = (size_t)g.d.plan.n_views;
    double *tr = __real_malloc((4 * nn + 3 * nv + sc_grid_sim_work_doubles(9)) * sizeof(double));
    assert_non_null(tr);
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    t.gx_um = tr, t.gy_um = tr + nn, t.ax_um = tr + 2 * nn, t.ay_um = tr + 3 * nn;
    t.tx_um = tr + 4 * nn, t.ty_um = t.tx_um + nv, t.theta_urad = t.ty_um + nv;
    assert_int_equal(sc_grid_sim_run(&g.d.plan, &sp, &t, &g.d, tr + 4 * nn + 3 * nv, &err),
                     SC_OK);
    free(tr);
    assert_int_equal(sc_grid_write_input(TMP "grid.csv", &g.d, &err), SC_OK);
    g.out = __real_malloc((6 * 81 + SC_GRID_RESULT_VIEW_ARRAYS * nv) * sizeof(double));
    assert_non_null(g.out);
    every_allocation("sc_grid_read", read_grid, TMP "grid.csv");
    every_allocation("sc_grid_lsq_plan create + solve", grid_lsq, &g);
    /* execute, residuals and predict allocate nothing: any allocation would fail while they run */
    sc_grid_lsq_plan *q = NULL;
    assert_int_equal(sc_grid_lsq_plan_create(&g.d.plan, &g.d, NULL, &q, &err), SC_OK);
    sc_grid_result res;
    result_arrays(&g, &res);
    double *resid = __real_malloc(5 * 4 * nn * sizeof(double)), px, py;
    assert_non_null(resid);
    counted = 0, injected = 0, fail_at = 1;
    sc_status st1 = sc_grid_lsq_execute(q, &g.d, 0.01, &res, &err);
    sc_status st2 = sc_grid_lsq_residuals(q, &g.d, &res, resid, resid + 4 * nn, resid + 8 * nn,
                                          resid + 12 * nn, resid + 16 * nn, &err);
    sc_grid_lsq_predict(q, &res, 0, 4, 4, 0.0, &px, &py);
    fail_at = 0;
    assert_int_equal(st1, SC_OK);
    assert_int_equal(st2, SC_OK);
    assert_false(injected);
    assert_true(isfinite(px) && isfinite(py));
    free(resid);
    sc_grid_lsq_plan_destroy(q);
    every_allocation("sc_grid_exact double shift create + execute", grid_exact, &g);
    free(g.out);
    sc_grid_data_free(&g.d);
}

static void test_profile(void **state)
{
    (void)state;
    profile_ctx c = {110, 10, 11, NULL, NULL, NULL, NULL};
    c.y1 = __real_calloc((size_t)c.n, sizeof(double));
    c.y2 = __real_calloc((size_t)c.n, sizeof(double));
    c.f = __real_calloc((size_t)c.n, sizeof(double));
    c.uf = __real_calloc((size_t)c.n, sizeof(double));
    assert_true(c.y1 && c.y2 && c.f && c.uf);
    for (int i = 0; i < c.n; ++i)
        c.y1[i] = sin(0.1 * i), c.y2[i] = cos(0.07 * i);
    every_allocation("sc_profile_lsq_plan create + solve + uncertainty", profile_lsq, &c);
    every_allocation("sc_profile_dft_plan create + solve + uncertainty", profile_dft, &c);
    free(c.y1), free(c.y2), free(c.f), free(c.uf);
}

int main(void)
{
    mkdir(SELFCAL_TEST_TMP, 0777);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_readers),
        cmocka_unit_test(test_grid),
        cmocka_unit_test(test_profile),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
