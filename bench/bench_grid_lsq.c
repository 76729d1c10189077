/* Benchmark of the least-squares grid estimator: create (analysis, ordering, factorization,
 * selected inverse for the per-node uncertainties) and solve time, peak memory, factor size, and
 * the recovery error on noise-free data, for N = 25, 51, 101 on Ye's and Petrò's plans.
 * Usage: bench_grid_lsq [--plans] [--big]   (--plans: plan analysis table for several N;
 *                                            --big: also N = 151 and 201) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/rng.h"

enum { YE, PETRO, RICH, P0_90_2X, P0_90, P0_180_1X };
static const char *plan_name[] = {"Ye {0,90,+1x}", "Petro {0,90,+2x,-3x part}",
                                  "rich {0,90,180,+1x,270/-2y}", "{0,90,+2x}", "{0,90}",
                                  "{0,180,+1x}"};

static void add_view(sc_grid_plan *p, int rot, int sx, int sy)
{
    if (sc_grid_plan_views(p, p->n_views + 1, NULL) != SC_OK)
        exit(1);
    sc_grid_view *w = &p->view[p->n_views - 1];
    w->rot_deg = rot, w->shift_x = sx, w->shift_y = sy;
}

static void make_plan(sc_grid_plan *p, int n, int kind)
{
    memset(p, 0, sizeof *p);
    p->n = n;
    p->pitch_mm = 1.0;
    int c = (n - 1) / 2;
    switch (kind) {
    case YE: add_view(p, 0, 0, 0), add_view(p, 90, 0, 0), add_view(p, 0, 1, 0); break;
    case PETRO:
        add_view(p, 0, 0, 0), add_view(p, 90, 0, 0), add_view(p, 0, 2, 0), add_view(p, 0, -3, 0);
        p->view[3].restricted = 1;
        p->view[3].row_sel[c] = p->view[3].col_sel[c] = p->view[3].col_sel[c + 1] = 1;
        break;
    case RICH:
        add_view(p, 0, 0, 0), add_view(p, 90, 0, 0), add_view(p, 180, 0, 0);
        add_view(p, 0, 1, 0), add_view(p, 270, 0, -2);
        break;
    case P0_90_2X: add_view(p, 0, 0, 0), add_view(p, 90, 0, 0), add_view(p, 0, 2, 0); break;
    case P0_90: add_view(p, 0, 0, 0), add_view(p, 90, 0, 0); break;
    case P0_180_1X: add_view(p, 0, 0, 0), add_view(p, 180, 0, 0), add_view(p, 0, 1, 0); break;
    }
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static double cpu_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static double peak_mib(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss / 1024.0;
}

static void run(int n, int kind)
{
    sc_grid_plan p;
    make_plan(&p, n, kind);
    int nn = n * n;
    sc_rng r;
    sc_rng_seed(&r, 1000 + n);
    double *buf = malloc(sizeof(double) * 12 * nn);
    double *gx = buf, *gy = buf + nn, *ax = buf + 2 * nn, *ay = buf + 3 * nn;
    sc_grid_result res;
    memset(&res, 0, sizeof res);
    res.gx_um = buf + 4 * nn, res.gy_um = buf + 5 * nn, res.ugx_um = buf + 6 * nn;
    res.ugy_um = buf + 7 * nn, res.ax_um = buf + 8 * nn, res.ay_um = buf + 9 * nn;
    for (int k = 0; k < nn; ++k)
        gx[k] = sc_rng_normal(&r), gy[k] = sc_rng_normal(&r), ax[k] = sc_rng_normal(&r),
        ay[k] = sc_rng_normal(&r);
    sc_grid_gauge_stage(&p, gx, gy);
    sc_grid_gauge_plate(&p, ax, ay);
    double tx[32], ty[32], th[32]; /* the random stream of the old fixed view count */
    for (int v = 0; v < 32; ++v)
        tx[v] = sc_rng_normal(&r), ty[v] = sc_rng_normal(&r), th[v] = 20 * sc_rng_normal(&r);
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    if (sc_grid_plan_copy(&d.plan, &p, NULL) != SC_OK || sc_grid_data_views(&d, NULL) != SC_OK)
        exit(1);
    if (sc_grid_result_views(&res, p.n_views, NULL) != SC_OK)
        exit(1);
    for (int v = 0; v < p.n_views; ++v) {
        d.dx_um[v] = malloc(sizeof(double) * nn);
        d.dy_um[v] = malloc(sizeof(double) * nn);
    }
    sc_grid_synthesize(&p, gx, gy, ax, ay, tx, ty, th, &d);
    sc_error err;
    sc_grid_lsq_plan *q = NULL;
    double c0 = cpu_s(), t0 = now_s();
    if (sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err) != SC_OK) {
        printf("create failed: %s\n", err.msg);
        exit(1);
    }
    double t1 = now_s(), c1 = cpu_s();
    sc_status st = sc_grid_lsq_execute(q, &d, 0.0, &res, &err);
    double t2 = now_s(), c2 = cpu_s();
    sc_grid_lsq_info info;
    sc_grid_lsq_stats sst;
    sc_grid_lsq_get_info(q, &info);
    sc_grid_lsq_get_stats(q, &sst);
    double eg = 0;
    if (st == SC_OK)
        for (int k = 0; k < nn; ++k)
            eg = fmax(eg, fmax(fabs(res.gx_um[k] - gx[k]), fabs(res.gy_um[k] - gy[k])));
    printf("  [cpu create %.3f s, solve %.3f s; flops %.3g selinv %.3g; order %s]\n", c1 - c0,
           c2 - c1, sst.factor_flops, sst.selinv_work, sst.ordering);
    printf("%-28s %4d %7ld %8ld %9ld %8.3f %8.3f %9.1f %9.1f %9.2e %7.3f %7.3f %8.1e\n",
           plan_name[kind], n, info.n_unknowns, sst.nnz_matrix, sst.nnz_factor, t1 - t0, t2 - t1,
           sst.bytes / 1048576.0, peak_mib(), st == SC_OK ? eg : NAN, info.sigma_c_ratio_rms,
           info.sigma_c_ratio_max, sst.min_kept_pivot_ratio);
    fflush(stdout);
    sc_grid_lsq_plan_destroy(q);
    sc_grid_data_free(&d);
    sc_grid_result_free_views(&res);
    sc_grid_plan_free(&p);
    free(buf);
}

static void plans_table(void)
{
    printf("\nPlan analysis (free dof K beyond the gauge; predicted std(G)/sigma_r; pivot margins)\n");
    printf("%-28s %4s %6s %4s %9s %9s %10s %10s\n", "plan", "N", "ident", "K", "rms", "max",
           "min kept", "max null");
    const int ns[] = {5, 7, 9, 11, 13, 15, 17, 25, 41, 51};
    for (int kind = 0; kind < 6; ++kind)
        for (size_t i = 0; i < sizeof ns / sizeof *ns; ++i) {
            sc_grid_plan p;
            make_plan(&p, ns[i], kind);
            sc_grid_lsq_plan *q = NULL;
            sc_error err;
            if (sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err) != SC_OK) {
                printf("%-28s %4d create failed: %s\n", plan_name[kind], ns[i], err.msg);
                sc_grid_plan_free(&p);
                continue;
            }
            sc_grid_lsq_info info;
            sc_grid_lsq_stats st;
            sc_grid_lsq_get_info(q, &info);
            sc_grid_lsq_get_stats(q, &st);
            printf("%-28s %4d %6s %4ld %9.4f %9.4f %10.2e %10.2e\n", plan_name[kind], ns[i],
                   info.identifiable ? "yes" : "no", info.free_dof, info.sigma_c_ratio_rms,
                   info.sigma_c_ratio_max, st.min_kept_pivot_ratio, st.max_null_pivot_ratio);
            sc_grid_lsq_plan_destroy(q);
            sc_grid_plan_free(&p);
        }
}

int main(int argc, char **argv)
{
    int plans = 0, big = 0;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--plans"))
            plans = 1;
        else if (!strcmp(argv[i], "--big"))
            big = 1;
        else {
            fprintf(stderr, "usage: %s [--plans] [--big]\n", argv[0]);
            return 2;
        }
    }
    printf("Least-squares grid estimator: create = analysis + ordering + LDL^T + selected "
           "inverse (per-node sigma);\nsolve = estimate from noise-free data with "
           "uncertainties; times are wall clock (CPU time in the [..] line);\ncounted = the "
           "estimator's byte accounting (held + assembly buffers); peak = process max RSS so "
           "far;\nerr = max |G - G_true|.\n");
    printf("%-28s %4s %7s %8s %9s %8s %8s %9s %9s %9s %7s %7s %8s\n", "plan", "N", "unknown",
           "nnz(S)", "nnz(L)", "create_s", "solve_s", "cnt_MiB", "peak_MiB", "err_um",
           "rms_s/r", "max_s/r", "pivmarg");
    const int ns[] = {25, 51, 101, 151, 201};
    int count = big ? 5 : 3;
    for (int kind = 0; kind < 2; ++kind)
        for (int i = 0; i < count; ++i)
            run(ns[i], kind);
    run(101, RICH);
    if (plans)
        plans_table();
    return 0;
}
