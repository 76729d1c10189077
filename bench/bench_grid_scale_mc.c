/* bench_grid_scale_mc — the Monte Carlo check of the grid uncertainty budget (SPEC §11,
 * sc_grid_monte_carlo): wall time of M trials on one and on two threads, and the agreement of
 * the trials' u with the budget's (ratio over every node and component), for Petrò's plan with
 * a certified plate scale, an expansion coefficient, per-view temperatures and a stage
 * magnification (σ_r = 10 nm, seed 1).
 * Usage: bench_grid_scale_mc [--full]   (default N = 25, M = 1000; --full adds N = 51 and
 * M = 10000 at N = 25)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_sim.h"

static void die(const char *what, const sc_error *err)
{
    char buf[1024];
    sc_error_format(err, buf, sizeof buf);
    fprintf(stderr, "bench_grid_scale_mc: %s: %s\n", what, buf);
    exit(1);
}

/* Simulated data with the plate's scale and temperature into d. */
static void make_data(int n, sc_grid_data *d)
{
    sc_error err;
    sc_grid_plan p;
    if (sc_grid_plan_double_shift(n, 1.0, 0, 0, &p, &err) != SC_OK)
        die("plan", &err);
    p.scale = (sc_grid_scale){1, 1.5, 0.1, 1, 8.0, 0.5, 1, 0.05};
    const double T[4] = {20.2, 20.6, 19.9, 20.4};
    for (int v = 0; v < 4; ++v)
        p.view[v].temp_C = T[v];
    memset(d, 0, sizeof *d);
    d->plan = p; /* the data own the plan from here */
    if (sc_grid_data_alloc(d, &err) != SC_OK)
        die("alloc", &err);
    size_t ns = (size_t)n * n, nn = ns;
    double *buf = malloc(sizeof(double) * (4 * ns + 2 * nn + 12 + sc_grid_sim_work_doubles_plan(&p)));
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    t.gx_um = buf, t.gy_um = buf + ns, t.ax_um = buf + 2 * ns, t.ay_um = buf + 2 * ns + nn;
    t.tx_um = buf + 2 * ns + 2 * nn, t.ty_um = t.tx_um + 4, t.theta_urad = t.ty_um + 4;
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    if (sc_grid_sim_run(&p, &sp, &t, d, buf + 2 * ns + 2 * nn + 12, &err) != SC_OK)
        die("simulate", &err);
    sc_grid_sim_scale(&p, 12.0, &t, d);
    free(buf);
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One table row: N, M, threads; the median wall time of 3 runs and the last run's ratios. */
static void row(sc_grid_data *d, const sc_grid_solution *s, long trials, int threads)
{
    sc_grid_options o;
    sc_grid_options_default(&o);
    double t[3];
    sc_grid_mc mc;
    for (int r = 0; r < 3; ++r) {
        sc_error err;
        if (r)
            sc_grid_mc_free(&mc);
        if (sc_grid_monte_carlo(d, &o, s, trials, 1, threads, &mc, &err) != SC_OK)
            die("monte carlo", &err);
        t[r] = mc.seconds;
    }
    qsort(t, 3, sizeof t[0], cmp);
    printf("%4d %7ld %7d %9.3f %10.4f %10.4f %10.4f %12.4g %12.4g\n", d->plan.n, trials,
           mc.threads, t[1], mc.ratio_mean, mc.ratio_min, mc.ratio_max,
           s->budget.u_magnification_ppm, mc.magnification_sd_ppm);
    sc_grid_mc_free(&mc);
}

int main(int argc, char **argv)
{
    int full = argc > 1 && !strcmp(argv[1], "--full");
    printf("# the budget's Monte Carlo (sc_grid_monte_carlo): Petro's plan, sigma_r = 10 nm,\n"
           "# E = 1.5 +- 0.1 ppm, A = 8 +- 0.5 ppm/K, T = 20.2/20.6/19.9/20.4 C +- 0.05 K,\n"
           "# M = 12 ppm; seconds: median wall time of 3 runs; ratio: MC u / budget u over\n"
           "# every node and component; u(M) budget and MC (ppm)\n");
    printf("%4s %7s %7s %9s %10s %10s %10s %12s %12s\n", "N", "trials", "threads", "seconds",
           "ratio_mean", "ratio_min", "ratio_max", "u(M) budget", "u(M) MC");
    int ns[2] = {25, 51};
    for (int k = 0; k < (full ? 2 : 1); ++k) {
        sc_grid_data d;
        make_data(ns[k], &d);
        sc_grid_options o;
        sc_grid_options_default(&o);
        sc_grid_solution s;
        sc_error err;
        if (sc_grid_calibrate(&d, NULL, NULL, &o, &s, &err) != SC_OK)
            die("calibrate", &err);
        row(&d, &s, 1000, 1);
        row(&d, &s, 1000, 0);
        if (full && ns[k] == 25)
            row(&d, &s, 10000, 0);
        sc_grid_solution_free(&s);
        sc_grid_data_free(&d);
    }
    return 0;
}
