/* Benchmark: selfcal's whole least-squares grid solve against SuiteSparse CHOLMOD on the same
 * matrix, in one run (issue 11's targets: time within 2.5x, memory within 1.5x of CHOLMOD's
 * analyze+factor+solve; N = 201 under 1.5 s, N = 401 under 30 s).
 *
 * Per N (Petrò's plan {0°, 90°, +2x, -3x partial}), three child processes, so each peak RSS is
 * its own:
 *   selfcal  sc_grid_lsq_create (assembly, ordering, factorization, every node's sigma by the
 *            selected inverse) + sc_grid_lsq_solve on noisy data;
 *   export   builds the estimator once and writes its reduced pinned matrix to a temporary file;
 *   CHOLMOD  reads that matrix and runs cholmod_analyze + cholmod_factorize + cholmod_solve with
 *            CHOLMOD's defaults (no selected inverse: CHOLMOD has none).
 * Time is the CPU time (user + system, all threads) of the measured part, with OpenBLAS on one
 * thread for both (the program re-executes itself with OPENBLAS_NUM_THREADS=1 unless it is set):
 * on this shared 2-core machine wall clock mostly measures the other builds, and idle OpenBLAS
 * threads spin. Wall clock is printed too. Memory is the child's peak RSS minus the RSS it had
 * before the measured part (the matrix file's read is outside CHOLMOD's part but its copy counts).
 * Usage: bench_grid_cholmod [N ...]   (default 101 201 301; e.g. 401 for the large target) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <suitesparse/cholmod.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "../libselfcal/src/grid/grid_lsq_internal.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/rng.h"

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* Current and peak resident set, MiB (from /proc/self/status). */
static void rss_mib(double *cur, double *peak)
{
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    *cur = *peak = NAN;
    while (f && fgets(line, sizeof line, f)) {
        long kb;
        if (sscanf(line, "VmRSS: %ld kB", &kb) == 1)
            *cur = kb / 1024.0;
        if (sscanf(line, "VmHWM: %ld kB", &kb) == 1)
            *peak = kb / 1024.0;
    }
    if (f)
        fclose(f);
}

static void petro_plan(sc_grid_plan *p, int n)
{
    memset(p, 0, sizeof *p);
    p->n = n;
    p->pitch_mm = 1.0;
    int c = (n - 1) / 2;
    const int rot[] = {0, 90, 0, 0}, sx[] = {0, 0, 2, -3};
    for (int v = 0; v < 4; ++v) {
        p->view[v].rot_deg = rot[v];
        p->view[v].shift_x = sx[v];
    }
    p->n_views = 4;
    p->view[3].restricted = 1;
    p->view[3].row_sel[c] = p->view[3].col_sel[c] = p->view[3].col_sel[c + 1] = 1;
}

static double cpu_s(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

typedef struct figures {
    double seconds, wall, mib, check;
    char ordering[32];
} figures;

static void selfcal_child(int n, figures *out)
{
    sc_grid_plan p;
    petro_plan(&p, n);
    int nn = n * n;
    sc_rng r;
    sc_rng_seed(&r, 1000 + n);
    double *g = malloc(sizeof(double) * 4 * nn), *res_buf = malloc(sizeof(double) * 6 * nn);
    for (int k = 0; k < 4 * nn; ++k)
        g[k] = sc_rng_normal(&r);
    sc_grid_gauge_stage(&p, g, g + nn);
    sc_grid_gauge_plate(&p, g + 2 * nn, g + 3 * nn);
    double tx[SC_GRID_MAX_VIEWS] = {0}, ty[SC_GRID_MAX_VIEWS] = {0}, th[SC_GRID_MAX_VIEWS] = {0};
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    d.plan = p;
    for (int v = 0; v < p.n_views; ++v) {
        d.dx_um[v] = malloc(sizeof(double) * nn);
        d.dy_um[v] = malloc(sizeof(double) * nn);
    }
    sc_grid_synthesize(&p, g, g + nn, g + 2 * nn, g + 3 * nn, tx, ty, th, &d);
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < nn; ++k)
            if (isfinite(d.dx_um[v][k]))
                d.dx_um[v][k] += 0.01 * sc_rng_normal(&r), d.dy_um[v][k] += 0.01 * sc_rng_normal(&r);
    sc_grid_result res;
    memset(&res, 0, sizeof res);
    res.gx_um = res_buf, res.gy_um = res_buf + nn, res.ugx_um = res_buf + 2 * nn;
    res.ugy_um = res_buf + 3 * nn, res.ax_um = res_buf + 4 * nn, res.ay_um = res_buf + 5 * nn;
    double base, peak;
    rss_mib(&base, &peak);
    sc_error err;
    sc_grid_lsq_plan *q = NULL;
    double t0 = now_s(), c0 = cpu_s();
    if (sc_grid_lsq_plan_create(&p, &d, NULL, &q, &err) != SC_OK ||
        sc_grid_lsq_execute(q, &d, 0.0, &res, &err) != SC_OK) {
        fprintf(stderr, "selfcal failed: %s\n", err.msg);
        exit(1);
    }
    out->seconds = cpu_s() - c0;
    out->wall = now_s() - t0;
    rss_mib(&base, &peak);
    double cur0 = base;
    (void)cur0;
    sc_grid_lsq_stats st;
    sc_grid_lsq_get_stats(q, &st);
    snprintf(out->ordering, sizeof out->ordering, "%s", st.ordering);
    double rms = 0;
    for (int k = 0; k < nn; ++k)
        rms += res.ugx_um[k] * res.ugx_um[k];
    out->check = sqrt(rms / nn);
    sc_grid_lsq_plan_destroy(q);
}

static void export_child(int n, const char *path)
{
    sc_grid_plan p;
    petro_plan(&p, n);
    sc_error err;
    sc_grid_lsq_plan *q = NULL;
    if (sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err) != SC_OK)
        exit(1);
    int nx;
    const long *Ap;
    const int *Ai;
    const double *Ax;
    sc_grid_lsq_matrix(q, &nx, &Ap, &Ai, &Ax);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(&nx, sizeof nx, 1, f) != 1 || fwrite(Ap, sizeof(long), nx + 1, f) != (size_t)nx + 1 ||
        fwrite(Ai, sizeof(int), Ap[nx], f) != (size_t)Ap[nx] ||
        fwrite(Ax, sizeof(double), Ap[nx], f) != (size_t)Ap[nx] || fclose(f) != 0)
        exit(1);
    sc_grid_lsq_plan_destroy(q);
}

static void cholmod_child(const char *path, figures *out)
{
    FILE *f = fopen(path, "rb");
    int nx;
    if (!f || fread(&nx, sizeof nx, 1, f) != 1)
        exit(1);
    long *Ap = malloc(sizeof(long) * (nx + 1));
    if (fread(Ap, sizeof(long), nx + 1, f) != (size_t)nx + 1)
        exit(1);
    long nnz = Ap[nx];
    double base, peak;
    rss_mib(&base, &peak);
    cholmod_common c;
    cholmod_start(&c);
    cholmod_sparse *A = cholmod_allocate_sparse(nx, nx, nnz, 0, 1, 1, CHOLMOD_REAL, &c);
    int *p = A->p, *ip = malloc(sizeof(int) * nnz);
    for (int k = 0; k <= nx; ++k)
        p[k] = (int)Ap[k];
    if (fread(ip, sizeof(int), nnz, f) != (size_t)nnz || fread(A->x, sizeof(double), nnz, f) != (size_t)nnz)
        exit(1);
    memcpy(A->i, ip, sizeof(int) * nnz);
    free(ip);
    fclose(f);
    cholmod_dense *b = cholmod_ones(nx, 1, CHOLMOD_REAL, &c);
    double t0 = now_s(), c0 = cpu_s();
    cholmod_factor *L = cholmod_analyze(A, &c);
    cholmod_factorize(A, L, &c);
    cholmod_dense *x = cholmod_solve(CHOLMOD_A, L, b, &c);
    out->seconds = cpu_s() - c0;
    out->wall = now_s() - t0;
    double cur;
    rss_mib(&cur, &peak);
    out->mib = peak - base;
    out->check = c.status;
    snprintf(out->ordering, sizeof out->ordering, "%s",
             c.method[c.selected].ordering == CHOLMOD_METIS ? "METIS" : "AMD");
    cholmod_free_dense(&x, &c);
    cholmod_free_dense(&b, &c);
    cholmod_free_factor(&L, &c);
    cholmod_free_sparse(&A, &c);
    cholmod_finish(&c);
}

/* Run fn in a child; its figures come back through a pipe. */
static int in_child(figures *out, int which, int n, const char *path)
{
    int fd[2];
    if (pipe(fd) != 0)
        return -1;
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        figures fg;
        memset(&fg, 0, sizeof fg);
        double base, peak;
        rss_mib(&base, &peak);
        if (which == 0) {
            /* memory of selfcal: peak minus the RSS before the estimator (data included) */
            selfcal_child(n, &fg);
            double b2;
            rss_mib(&b2, &peak);
            fg.mib = peak - base;
        } else if (which == 1) {
            export_child(n, path);
        } else {
            cholmod_child(path, &fg);
        }
        if (write(fd[1], &fg, sizeof fg) != (ssize_t)sizeof fg)
            _exit(1);
        _exit(0);
    }
    close(fd[1]);
    ssize_t got = read(fd[0], out, sizeof *out);
    close(fd[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    return got == (ssize_t)sizeof *out && WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : -1;
}

int main(int argc, char **argv)
{
    if (!getenv("OPENBLAS_NUM_THREADS")) {
        setenv("OPENBLAS_NUM_THREADS", "1", 1);
        execv("/proc/self/exe", argv);
    }
    int ns[16], count = 0;
    for (int i = 1; i < argc && count < 16; ++i)
        ns[count++] = atoi(argv[i]);
    if (count == 0)
        ns[0] = 101, ns[1] = 201, ns[2] = 301, count = 3;
    char path[64];
    snprintf(path, sizeof path, "/tmp/bench_grid_cholmod.%d", (int)getpid());
    printf("Grid least squares (Petro's plan): selfcal create+solve with every node's sigma vs\n"
           "CHOLMOD analyze+factor+solve of the same reduced matrix (targets: time ratio <= 2.5,\n"
           "memory ratio <= 1.5; N = 201 < 1.5 s, N = 401 < 30 s)\n");
    printf("(CPU seconds, OpenBLAS threads: %s; wall seconds in brackets)\n",
           getenv("OPENBLAS_NUM_THREADS"));
    printf("%5s %8s | %8s %8s %7s %-16s | %8s %8s %7s %-6s | %6s %6s\n", "N", "reduced",
           "selfcal", "(wall)", "MiB", "order", "CHOLMOD", "(wall)", "MiB", "order", "time x",
           "mem x");
    for (int t = 0; t < count; ++t) {
        int n = ns[t];
        figures a, e, c;
        if (in_child(&a, 0, n, path) != 0 || in_child(&e, 1, n, path) != 0 ||
            in_child(&c, 2, n, path) != 0) {
            printf("%5d failed\n", n);
            continue;
        }
        remove(path);
        printf("%5d %8d | %8.3f %8.2f %7.1f %-16s | %8.3f %8.2f %7.1f %-6s | %6.2f %6.2f\n", n,
               2 * n * n + 12, a.seconds, a.wall, a.mib, a.ordering, c.seconds, c.wall, c.mib,
               c.ordering, a.seconds / c.seconds, a.mib / c.mib);
        fflush(stdout);
    }
    remove(path);
    return 0;
}
