/* bench_profile_lsq — time and peak memory of the profile least squares: the dense LAPACK
 * reference (KKT system, O(N³)) against the fast banded solver (O(N·d²)), without and with the
 * per-point uncertainties, for N = 10³..10⁶ and d = 10/11, 97/101.
 *
 * Every measurement runs in its own child process, so that the peak resident memory (ru_maxrss of
 * that child) belongs to that measurement alone. Usage: bench_profile_lsq [--full] [--serial] [--reps R]
 *   default: N = 10³..10⁶ for d = 10/11, N = 10³..10⁵ for d = 97/101, dense up to N = 4000;
 *   --full:  also N = 10⁶ for d = 97/101 (about 0.4 GB of factor, a few seconds).
 * Times are CPU seconds of the measured part (all threads; the machine is shared; OpenBLAS runs on
 * one thread) and wall-clock seconds, each the best of R runs (default 3). --serial adds the
 * one-sided banded factor on one thread (SC_PROFILE_LSQ_SERIAL | SC_PROFILE_LSQ_ONE_THREAD). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "profile_lsq_dense.h"
#include "selfcal/profile_lsq.h"
#include "../libselfcal/src/profile/profile_lsq_tuning.h" /* internal tuning flags */
#include "selfcal/rng.h"

enum mode { DENSE_SOLVE, DENSE_UNC, FAST_SOLVE, FAST_UNC, EARLY_UNC, HUGE_UNC, SERIAL_UNC, BASELINE };

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double wall_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Simulated data for (n, d1, d2): a smooth profile plus Ding's sensor noise. */
static void make_data(int n, int d1, int d2, double *y1, double *y2, double *w1, double *w2)
{
    sc_rng r;
    sc_rng_seed(&r, 1234);
    double v1 = 2e-4 + (d1 * 1e-3) * (d1 * 1e-3), v2 = 2e-4 + (d2 * 1e-3) * (d2 * 1e-3);
    *w1 = 1 / v1;
    *w2 = 1 / v2;
    double *f = malloc((size_t)n * sizeof *f);
    if (!f) exit(3);
    for (int i = 0; i < n; i++) f[i] = sin(6.283185307179586 * 3.0 * i / n) + 1e-3 * i;
    for (int j = 0; j + d1 < n; j++) y1[j] = f[j + d1] - f[j] + 0.1 + sqrt(v1) * sc_rng_normal(&r);
    for (int j = 0; j + d2 < n; j++) y2[j] = f[j + d2] - f[j] - 0.2 + sqrt(v2) * sc_rng_normal(&r);
    free(f);
}

/* Run one measurement in this (child) process; returns the CPU seconds of the timed part (all
 * threads of the process), its wall-clock seconds in *wall. */
static double run(enum mode m, int n, int d1, int d2, double *wall)
{
    double *y1 = malloc((size_t)n * sizeof(double)), *y2 = malloc((size_t)n * sizeof(double));
    double *f = malloc((size_t)n * sizeof(double)), *uf = malloc((size_t)n * sizeof(double));
    if (!y1 || !y2 || !f || !uf) exit(3);
    double w1, w2;
    make_data(n, d1, d2, y1, y2, &w1, &w2);
    double t0 = now_s(), w0 = wall_s(), t;
    if (m == BASELINE) {
        t = 0;
    } else if (m == DENSE_SOLVE || m == DENSE_UNC) {
        if (sc_profile_lsq_dense_solve(n, d1, d2, w1, w2, y1, y2, f, NULL,
                                       m == DENSE_UNC ? uf : NULL) != 0)
            exit(4);
        t = now_s() - t0;
    } else {
        sc_profile_lsq_plan *p = NULL;
        sc_error err;
        unsigned flags = m == SERIAL_UNC ? SC_PROFILE_LSQ_SERIAL | SC_PROFILE_LSQ_ONE_THREAD
                         : m == HUGE_UNC ? SC_PROFILE_LSQ_HUGE_PAGES
                         : m == EARLY_UNC ? SC_PROFILE_LSQ_EARLY_UNCERTAINTY
                                          : 0u;
        if (sc_profile_lsq_plan_create_tuned(n, d1, d2, w1, w2, flags, &p, &err) != SC_OK) exit(5);
        if (sc_profile_lsq_execute(p, y1, y2, f, NULL, NULL, &err) != SC_OK) exit(6);
        if (m != FAST_SOLVE && sc_profile_lsq_uncertainty(p, uf, NULL, &err) != SC_OK) exit(7);
        t = now_s() - t0;
        sc_profile_lsq_plan_destroy(p);
    }
    *wall = wall_s() - w0;
    free(y1);
    free(y2);
    free(f);
    free(uf);
    return t;
}

/* Best CPU time of reps runs (each in a child), the best wall time, and the peak RSS (MB). */
static int measure(enum mode m, int n, int d1, int d2, int reps, double *best_s, double *best_wall,
                   double *peak_mb)
{
    *best_s = INFINITY;
    *best_wall = INFINITY;
    *peak_mb = 0;
    for (int r = 0; r < reps; r++) {
        int fd[2];
        if (pipe(fd) != 0) return -1;
        pid_t pid = fork();
        if (pid < 0) return -1;
        if (pid == 0) {
            close(fd[0]);
            double tw[2];
            tw[0] = run(m, n, d1, d2, &tw[1]);
            if (write(fd[1], tw, sizeof tw) != (ssize_t)sizeof tw) _exit(8);
            _exit(0);
        }
        close(fd[1]);
        double tw[2] = {NAN, NAN};
        ssize_t got = read(fd[0], tw, sizeof tw);
        close(fd[0]);
        int status;
        struct rusage ru;
        if (wait4(pid, &status, 0, &ru) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0 ||
            got != (ssize_t)sizeof tw)
            return -1;
        if (tw[0] < *best_s) *best_s = tw[0];
        if (tw[1] < *best_wall) *best_wall = tw[1];
        double mb = ru.ru_maxrss / 1024.0;
        if (mb > *peak_mb) *peak_mb = mb;
    }
    return 0;
}

int main(int argc, char **argv)
{
    /* one core for everyone: OpenBLAS single-threaded (it reads the variable when loaded) */
    if (!getenv("OPENBLAS_NUM_THREADS")) {
        setenv("OPENBLAS_NUM_THREADS", "1", 1);
        execv("/proc/self/exe", argv);
    }
    int full = 0, reps = 3, serial = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--full"))
            full = 1;
        else if (!strcmp(argv[i], "--serial"))
            serial = 1;
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
            reps = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: %s [--full] [--serial] [--reps R]\n", argv[0]);
            return 2;
        }
    }
    if (reps < 1) reps = 1;
    static const int ds[2][2] = {{10, 11}, {97, 101}};
    static const int ns[] = {1000, 2000, 4000, 10000, 100000, 1000000};
    printf("# profile least squares: dense LAPACK (KKT, dsytrf/dsytrs, +dsytri for the "
           "uncertainties) vs fast banded (O(N d^2))\n");
    printf("# CPU seconds, best of %d runs, each in its own process (OpenBLAS on 1 thread); memory "
           "= peak RSS of that process minus the same process only holding the data\n", reps);
    {
        sc_profile_lsq_plan *p = NULL;
        sc_error err;
        if (sc_profile_lsq_plan_create(21, 10, 11, 1, 1, &p, &err) == SC_OK)
            printf("# fast kernels: %s\n", sc_profile_lsq_uses_simd(p) ? "AVX2/FMA" : "portable");
        sc_profile_lsq_plan_destroy(p);
    }
    printf("# fast = twisted factor (both halves from one, by persymmetry) + page-fault helper thread;"
           " '... early uncert. thread' = with SC_PROFILE_LSQ_EARLY_UNCERTAINTY (the selected"
           " inversion on a second thread from the end of the factorization on); '... huge pages' ="
           " with SC_PROFILE_LSQ_HUGE_PAGES; --serial adds the one-sided factor on one thread\n");
    printf("%-8s %-8s %-24s %12s %12s %12s\n", "d1/d2", "N", "method", "cpu_s", "wall_s",
           "peak_MB");
    for (int q = 0; q < 2; q++) {
        int d1 = ds[q][0], d2 = ds[q][1];
        for (size_t k = 0; k < sizeof ns / sizeof ns[0]; k++) {
            int n = ns[k];
            if (n == 1000000 && d2 > 11 && !full) continue;
            double tb, wb, mb_base;
            if (measure(BASELINE, n, d1, d2, 1, &tb, &wb, &mb_base) != 0) return 1;
            static const char *names[] = {"dense LS", "dense LS + uncert.", "fast LS",
                                          "fast LS + uncert.", "... early uncert. thread",
                                          "... huge pages", "one-sided LS + uncert."};
            for (int m = DENSE_SOLVE; m <= SERIAL_UNC; m++) {
                if ((m == DENSE_SOLVE || m == DENSE_UNC) && n > 4000)
                    continue;
                if (m == SERIAL_UNC && !serial) continue;
                if ((m == HUGE_UNC || m == EARLY_UNC) && n < 100000) continue;
                double t, w, mb;
                int r = (m <= DENSE_UNC && n >= 2000) ? 1 : reps;
                if (measure((enum mode)m, n, d1, d2, r, &t, &w, &mb) != 0) {
                    printf("%3d/%-4d %-8d %-24s %12s %12s %12s\n", d1, d2, n, names[m], "failed",
                           "-", "-");
                    continue;
                }
                char dd[16];
                snprintf(dd, sizeof dd, "%d/%d", d1, d2);
                printf("%-8s %-8d %-24s %12.4f %12.4f %12.1f\n", dd, n, names[m], t, w,
                       mb - mb_base);
                fflush(stdout);
            }
        }
    }
    return 0;
}
