/* bench_profile — time and peak memory of the straightness-profile solvers: the dense LAPACK
 * least squares (reference, O(N³)), the fast banded least squares with per-point uncertainties
 * (O(N·d²)), and the DFT method (O(N log N)) with its analytic uncertainty.
 *
 * Every measurement runs in its own forked child, so that its peak resident memory (ru_maxrss of
 * the child, minus that of an idle child) is its own. Build Release, without sanitizers.
 *
 * usage: bench_profile [--full] [--n N ...]
 *   default: N = 10³, 10⁴, 10⁵, 10⁶; d = 10/11 and 97/101; dense at N <= 2000 (--full: <= 4000).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "selfcal/profile.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"
#include "selfcal/rng.h"
#ifdef SELFCAL_BENCH_DENSE
#include "profile_lsq_dense.h"
#endif

typedef struct result {
    int ok;
    double create_s, solve_s, unc_s; /* seconds: plan/factor, one solve, all uncertainties */
    double check;                    /* method-specific check value (see the table notes) */
} result;

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t); /* CPU time: the machine is shared */
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

enum { M_IDLE, M_DENSE, M_LSQ, M_DFT };

static void make_y(int n, int d1, int d2, double *y1, double *y2)
{
    sc_rng r;
    sc_rng_seed(&r, 12345);
    for (int i = 0; i < n - d1; ++i)
        y1[i] = 0.01 * sc_rng_normal(&r) + 1e-3 * sin(0.01 * i);
    for (int i = 0; i < n - d2; ++i)
        y2[i] = 0.01 * sc_rng_normal(&r) + 1e-3 * sin(0.011 * i);
}

/* Run one measurement in this process. */
static result measure(int method, int n, int d1, int d2)
{
    result res = {0, 0, 0, 0, NAN};
    if (method == M_IDLE) {
        res.ok = 1;
        return res;
    }
    double w1 = 1.0 / sc_profile_y_variance(d1, 1.0, 0.01, 1.0), w2 = 1.0 / sc_profile_y_variance(d2, 1.0, 0.01, 1.0);
    double *y1 = malloc((size_t)n * sizeof(double)), *y2 = malloc((size_t)n * sizeof(double));
    double *f = malloc((size_t)n * sizeof(double)), *uf = malloc((size_t)n * sizeof(double));
    if (!y1 || !y2 || !f || !uf)
        return res;
    make_y(n, d1, d2, y1, y2);
    sc_error err;
    double t0 = now();
    if (method == M_LSQ) {
        sc_profile_lsq_plan *p;
        if (sc_profile_lsq_plan_create(n, d1, d2, w1, w2, &p, &err) != SC_OK)
            return res;
        double t1 = now();
        int reps = 0;
        double t2;
        do {
            sc_profile_lsq_execute(p, y1, y2, f, NULL, NULL, &err);
            ++reps;
            t2 = now();
        } while (t2 - t1 < 0.05 && reps < 50);
        double t3 = now();
        if (sc_profile_lsq_uncertainty(p, uf, NULL, &err) != SC_OK)
            return res;
        double t4 = now();
        res.create_s = t1 - t0;
        res.solve_s = (t2 - t1) / reps;
        res.unc_s = t4 - t3;
        res.check = uf[n / 2] * 1e3;
        sc_profile_lsq_plan_destroy(p);
    } else if (method == M_DFT) {
        sc_profile_dft_plan *p;
        if (sc_profile_dft_plan_create(n, d1, d2, w1, w2, &p, &err) != SC_OK)
            return res;
        double t1 = now();
        int reps = 0;
        double t2;
        do {
            sc_profile_dft_execute(p, y1, y2, f, &err);
            ++reps;
            t2 = now();
        } while (t2 - t1 < 0.05 && reps < 50);
        double t3 = now();
        if (sc_profile_dft_uncertainty(p, uf, NULL, &err) != SC_OK)
            return res;
        double t4 = now();
        res.create_s = t1 - t0;
        res.solve_s = (t2 - t1) / reps;
        res.unc_s = t4 - t3;
        res.check = uf[n / 2] * 1e3;
        sc_profile_dft_plan_destroy(p);
    } else {
#ifdef SELFCAL_BENCH_DENSE
        double c[2];
        if (sc_profile_lsq_dense_solve(n, d1, d2, w1, w2, y1, y2, f, c, uf) != 0)
            return res;
        double t1 = now();
        res.create_s = 0;
        res.solve_s = t1 - t0; /* factor + solve + inverse together */
        res.unc_s = 0;
        /* agreement with the fast solver: max |f_dense - f_fast| / max |f| */
        sc_profile_lsq_plan *p;
        double *g = malloc((size_t)n * sizeof(double)), *ug = malloc((size_t)n * sizeof(double));
        if (g && ug && sc_profile_lsq_plan_create(n, d1, d2, w1, w2, &p, &err) == SC_OK) {
            sc_profile_lsq_execute(p, y1, y2, g, NULL, NULL, &err);
            sc_profile_lsq_uncertainty(p, ug, NULL, &err);
            double df = 0, fm = 0, du = 0;
            for (int i = 0; i < n; ++i) {
                df = fmax(df, fabs(f[i] - g[i]));
                fm = fmax(fm, fabs(f[i]));
                du = fmax(du, fabs(uf[i] - ug[i]) / uf[i]);
            }
            res.check = fmax(df / fm, du);
            sc_profile_lsq_plan_destroy(p);
        }
        free(g);
        free(ug);
#else
        return res;
#endif
    }
    free(y1), free(y2), free(f), free(uf);
    res.ok = 1;
    return res;
}

/* Fork, measure in the child, return its result and peak RSS (kB). */
static result run_child(int method, int n, int d1, int d2, long *maxrss_kb)
{
    result res = {0, 0, 0, 0, NAN};
    int fd[2];
    if (pipe(fd) != 0)
        return res;
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        result r = measure(method, n, d1, d2);
        ssize_t wr = write(fd[1], &r, sizeof r);
        (void)wr;
        _exit(0);
    }
    close(fd[1]);
    ssize_t got = read(fd[0], &res, sizeof res);
    close(fd[0]);
    int status;
    struct rusage ru;
    if (pid < 0 || wait4(pid, &status, 0, &ru) < 0 || got != (ssize_t)sizeof res) {
        res.ok = 0;
        return res;
    }
    *maxrss_kb = ru.ru_maxrss;
    return res;
}

static int nearest_multiple(int n, int m)
{
    int p = (n + m / 2) / m;
    return (p < 1 ? 1 : p) * m;
}

int main(int argc, char **argv)
{
    int full = 0, ns[16], nn = 0;
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--full"))
            full = 1;
        else if (!strcmp(argv[i], "--n") && i + 1 < argc && nn < 16)
            ns[nn++] = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_profile [--full] [--n N ...]\n");
            return 2;
        }
    }
    if (!nn) {
        int def[] = {1000, 10000, 100000, 1000000};
        for (int i = 0; i < 4; ++i)
            ns[nn++] = def[i];
        if (full)
            ns[nn++] = 4000;
    }
    const int dense_max = full ? 4000 : 2000;
    static const int pairs[2][2] = {{10, 11}, {97, 101}};
    long idle_kb = 0;
    run_child(M_IDLE, 0, 0, 0, &idle_kb);
    printf("# bench_profile: CPU times in ms (solve: one data set with the plan reused; uncertainty: all N\n"
           "# points); peak = the child's peak RSS minus an idle child's (%ld kB). u_mid: u(f) at N/2\n"
           "# (nm, sigma_disp 10 nm, sigma_angle 1 urad, s = 1 mm). dense: factor+solve+inverse in\n"
           "# one; its check = max relative difference to the fast solver (f and u).\n", idle_kb);
    printf("%-6s %8s %8s %10s %10s %10s %11s %10s %9s  %s\n", "method", "N", "d1/d2", "create_ms",
           "solve_ms", "uncert_ms", "total_ms", "peak_MB", "u_mid_nm", "note");
    for (int pi = 0; pi < 2; ++pi) {
        int d1 = pairs[pi][0], d2 = pairs[pi][1];
        for (int k = 0; k < nn; ++k) {
            int n = ns[k];
            for (int method = M_DENSE; method <= M_DFT; ++method) {
                int nm = n;
                char note[96] = "";
                if (method == M_DENSE) {
#ifndef SELFCAL_BENCH_DENSE
                    continue;
#endif
                    if (n > dense_max)
                        continue;
                }
                if (method == M_DFT && n % (d1 * d2) != 0) {
                    nm = nearest_multiple(n, d1 * d2);
                    snprintf(note, sizeof note, "N = %d = %d*%d*%d (%s multiple of d1*d2)", nm, nm / (d1 * d2),
                             d1, d2, nm > 2 * n ? "smallest" : "nearest");
                }
                long kb = 0;
                result r = run_child(method, nm, d1, d2, &kb);
                static const char *names[] = {"idle", "dense", "lsq", "dft"};
                char dd[16];
                snprintf(dd, sizeof dd, "%d/%d", d1, d2);
                if (!r.ok) {
                    printf("%-6s %8d %8s  failed (out of memory or error)\n", names[method], nm, dd);
                    continue;
                }
                if (method == M_DENSE)
                    snprintf(note, sizeof note, "check %.1e", r.check);
                double total = r.create_s + r.solve_s + r.unc_s;
                printf("%-6s %8d %8s %10.2f %10.3f %10.2f %11.2f %10.1f %9.3f  %s\n", names[method], nm, dd,
                       r.create_s * 1e3, r.solve_s * 1e3, r.unc_s * 1e3, total * 1e3,
                       (kb - idle_kb) / 1024.0, method == M_DENSE ? NAN : r.check, note);
                fflush(stdout);
            }
        }
    }
    return 0;
}
