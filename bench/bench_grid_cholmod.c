/* Benchmark: the whole `selfcal grid --method lsq` command against SuiteSparse CHOLMOD on the
 * same matrix, in one run (issue 11's targets: time within 2.5x, peak memory within 1.5x of
 * CHOLMOD's analyze+factor+solve; N = 201 under 1.5 s, N = 401 under 30 s).
 *
 * Per N (Petrò's plan {0°, 90°, +2x, -3x partial}, pitch 1 mm):
 *   data     `selfcal simulate grid --plan double-shift` writes a noisy measurement file (not timed;
 *            O = R = 2e-6 so that σ_G = 1 µm stays above their dispersion up to N = 401);
 *   selfcal  `selfcal grid --method lsq FILE --map G.csv --residuals R.csv --quiet`: the whole
 *            command (reading, analysis, factorization, every node's σ by the selected inverse,
 *            the leverages and Baarda's outlier test, O/R/misalignment uncertainties, writing),
 *            run as a child process: its CPU time and peak RSS from wait4;
 *   export   a child builds the plan of the same view plan and writes its reduced pinned matrix;
 *   CHOLMOD  a child reads that matrix and runs cholmod_analyze + cholmod_factorize +
 *            cholmod_solve (one right-hand side) with CHOLMOD's defaults (no selected inverse:
 *            CHOLMOD has none); its CPU time of those calls and the process's peak RSS.
 * Time is CPU time (user + system, all threads): on this shared 2-core machine the wall clock
 * mostly measures the other builds (printed too). Both sides run with the same thread settings:
 * OPENBLAS_NUM_THREADS and OMP_NUM_THREADS are 1 unless set (the program re-executes itself so
 * that every child inherits them), and the table says which; OpenMP's parallel regions run on
 * one thread on both sides (CHOLMOD opens four-thread regions whatever OMP_NUM_THREADS says). Memory is each process's peak RSS.
 * Each side runs REPEAT times (default 3), interleaved; the table keeps each side's fastest run
 * and the median of the ratios of the runs made side by side (on the shared machine a run's CPU
 * time moved by up to 40 % from one run to the next, 23-26 Nov, and both sides moved together).
 * Usage: [REPEAT=3] bench_grid_cholmod [N | S:N ...]   (default 101 201 301; add 401 for the
 * large target). S:N: a stitched S x S stage and an N x N plate instead (`--plan stitch`: rot-0
 * placements at step (N-1)/2 plus a rot-90 and a +1,0 at the centre; hundreds of views, issue 33);
 * the table then gives S, N and the number of views.
 * Stitched stages (issue 33): the data carry a noise of 1e-8 µm only (so that G's error shows the
 * solver's accuracy while the outlier test still has a noise to test), and the table gives the
 * largest |G − truth| (target 1e-6 µm); the matrix exported and handed to CHOLMOD is the one the
 * plan factors (reduced, or with A kept: `solver`), with its factor's nonzeros and flops from
 * selfcal's analysis. SELFCAL_PREV=path: the previous release's selfcal runs the same command
 * (once per repeat), its CPU time and peak memory, or how it failed (exit status). */
#define _GNU_SOURCE /* RTLD_DEFAULT */
#include <dlfcn.h>
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
#include "selfcal/grid_sim.h"

#ifndef SELFCAL_CLI
#error "SELFCAL_CLI (the selfcal executable) must be defined by the build"
#endif

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static double cpu_s(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

static double peak_rss_mib(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss / 1024.0;
}

static void petro_plan(sc_grid_plan *p, int n)
{
    memset(p, 0, sizeof *p);
    p->n = n;
    p->pitch_mm = 1.0;
    int c = (n - 1) / 2;
    const int rot[] = {0, 90, 0, 0}, sx[] = {0, 0, 2, -3};
    if (sc_grid_plan_views(p, 4, NULL) != SC_OK)
        exit(1);
    for (int v = 0; v < 4; ++v) {
        p->view[v].rot_deg = rot[v];
        p->view[v].shift_x = sx[v];
    }
    p->view[3].restricted = 1;
    p->view[3].row_sel[c] = p->view[3].col_sel[c] = p->view[3].col_sel[c + 1] = 1;
}

typedef struct figures {
    double seconds, wall, mib;
    char ordering[32];
    long n_red;      /* the export's: unknowns of the matrix factored */
    int views;       /* and the plan's views */
    int solver;      /* the export's: SC_GRID_SOLVER_REDUCED or _FULL */
    long nnz_l;      /* the export's: nonzeros of the factor, and its flops */
    double flops;
    int status;      /* run_command: the child's exit status (-1: a signal) */
} figures;

/* Run argv as a child; its CPU time, wall time and peak RSS. 0 if it exited 0. */
static int run_command(char *const argv[], figures *out)
{
    double t0 = now_s();
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        FILE *null = freopen("/dev/null", "w", stderr);
        (void)null;
        execv(argv[0], argv);
        _exit(127);
    }
    int status = 0;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) != pid)
        return -1;
    out->wall = now_s() - t0;
    out->seconds = ru.ru_utime.tv_sec + ru.ru_stime.tv_sec +
                   1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    out->mib = ru.ru_maxrss / 1024.0;
    out->status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : -1;
}

static void export_child(int n, int stage, const char *path, figures *fg)
{
    sc_grid_plan p;
    if (stage > 0) {
        if (sc_grid_plan_stitch(n, stage, stage, 1.0, 0, 0, &p, NULL) != SC_OK)
            exit(1);
    } else {
        petro_plan(&p, n);
    }
    fg->views = p.n_views;
    sc_error err;
    sc_grid_lsq_plan *q = NULL;
    sc_grid_lsq_opts opts = {.node_sigma = SC_GRID_NODE_SIGMA_NONE}; /* the matrix is the same */
    if (sc_grid_lsq_plan_create(&p, NULL, &opts, &q, &err) != SC_OK)
        exit(1);
    sc_grid_lsq_stats st;
    sc_grid_lsq_get_stats(q, &st);
    fg->solver = st.solver, fg->nnz_l = st.nnz_factor, fg->flops = st.factor_flops;
    int n_red;
    const long *Ap;
    const int *Ai;
    const double *Ax;
    sc_grid_lsq_matrix(q, &n_red, &Ap, &Ai, &Ax);
    fg->n_red = n_red;
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(&n_red, sizeof n_red, 1, f) != 1 ||
        fwrite(Ap, sizeof(long), n_red + 1, f) != (size_t)n_red + 1 ||
        fwrite(Ai, sizeof(int), Ap[n_red], f) != (size_t)Ap[n_red] ||
        fwrite(Ax, sizeof(double), Ap[n_red], f) != (size_t)Ap[n_red] || fclose(f) != 0)
        exit(1);
    sc_grid_lsq_plan_destroy(q);
}

/* The CHOLMOD side runs OpenMP regions on one thread, as the selfcal command line does
 * (tools/selfcal/main.c): with an idle second core, CHOLMOD's four-thread regions spin there and
 * their CPU time would flatter the ratio; on a busy one they wait. Same settings on both sides. */
static void openmp_regions_serial(void)
{
    void *sym = dlsym(RTLD_DEFAULT, "omp_set_max_active_levels");
    if (!sym)
        return;
    void (*set_levels)(int);
    memcpy(&set_levels, &sym, sizeof sym);
    set_levels(0);
}

static void cholmod_child(const char *path, int serial_openmp, figures *out)
{
    if (serial_openmp)
        openmp_regions_serial();
    FILE *f = fopen(path, "rb");
    int n_red;
    if (!f || fread(&n_red, sizeof n_red, 1, f) != 1)
        exit(1);
    long *Ap = malloc(sizeof(long) * (n_red + 1));
    if (fread(Ap, sizeof(long), n_red + 1, f) != (size_t)n_red + 1)
        exit(1);
    long nnz = Ap[n_red];
    cholmod_common c;
    cholmod_start(&c);
    cholmod_sparse *A = cholmod_allocate_sparse(n_red, n_red, nnz, 0, 1, 1, CHOLMOD_REAL, &c);
    int *p = A->p;
    for (int k = 0; k <= n_red; ++k)
        p[k] = (int)Ap[k];
    free(Ap);
    if (fread(A->i, sizeof(int), nnz, f) != (size_t)nnz ||
        fread(A->x, sizeof(double), nnz, f) != (size_t)nnz)
        exit(1);
    fclose(f);
    cholmod_dense *b = cholmod_ones(n_red, 1, CHOLMOD_REAL, &c);
    double t0 = now_s(), c0 = cpu_s();
    cholmod_factor *L = cholmod_analyze(A, &c);
    cholmod_factorize(A, L, &c);
    cholmod_dense *x = cholmod_solve(CHOLMOD_A, L, b, &c);
    out->seconds = cpu_s() - c0;
    out->wall = now_s() - t0;
    out->mib = peak_rss_mib();
    if (!x || c.status != CHOLMOD_OK)
        exit(1);
    snprintf(out->ordering, sizeof out->ordering, "%s",
             c.method[c.selected].ordering == CHOLMOD_METIS ? "METIS" : "AMD");
    cholmod_free_dense(&x, &c);
    cholmod_free_dense(&b, &c);
    cholmod_free_factor(&L, &c);
    cholmod_free_sparse(&A, &c);
    cholmod_finish(&c);
}

/* Run the export (which = 1), CHOLMOD with OpenMP regions on one thread (2) or as shipped (3) in
 * a child; figures come back through a pipe. */
static int in_child(figures *out, int which, int n, int stage, const char *path)
{
    int fd[2];
    if (pipe(fd) != 0)
        return -1;
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        figures fg;
        memset(&fg, 0, sizeof fg);
        if (which == 1)
            export_child(n, stage, path, &fg);
        else
            cholmod_child(path, which == 2, &fg);
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

/* The file names of one N's run in dir. */
typedef struct bench_files {
    char n[16], stage[32], in[256], truth[256], map[256], res[256];
} bench_files;

static void bench_files_init(bench_files *f, int n, int stage, const char *dir)
{
    snprintf(f->n, sizeof f->n, "%d", n);
    snprintf(f->stage, sizeof f->stage, "%d,%d", stage, stage);
    snprintf(f->in, sizeof f->in, "%s/in.csv", dir);
    snprintf(f->truth, sizeof f->truth, "%s/truth.csv", dir);
    snprintf(f->map, sizeof f->map, "%s/G.csv", dir);
    snprintf(f->res, sizeof f->res, "%s/R.csv", dir);
}

/* selfcal simulate grid (untimed). */
static int selfcal_data(bench_files *f)
{
    char *sim[] = {SELFCAL_CLI, "simulate", "grid", "--plan", "double-shift", "--n", f->n, "--out",
                   f->in, "--truth-map", f->truth, "--seed", "7", "--O", "2e-6", "--R", "2e-6",
                   NULL, NULL, NULL, NULL, NULL};
    if (strcmp(f->stage, "0,0") != 0)
        sim[4] = "stitch", sim[17] = "--stage", sim[18] = f->stage, sim[19] = "--sigma-r-um",
        sim[20] = "1e-8";
    figures sim_fg;
    return run_command(sim, &sim_fg);
}

/* The largest |G − truth| (µm) of a map against the truth map (both i,j,x_mm,y_mm,gx_um,gy_um,...
 * in the same node order); NaN if they cannot be read. */
static double map_error(const char *map, const char *truth)
{
    FILE *a = fopen(map, "r"), *b = fopen(truth, "r");
    char la[512], lb[512];
    double e = a && b ? 0 : NAN;
    long rows = 0;
    while (a && b && fgets(la, sizeof la, a) && fgets(lb, sizeof lb, b)) {
        int i1, j1, i2, j2;
        double x, y, gx1, gy1, gx2, gy2;
        if (sscanf(la, "%d,%d,%lf,%lf,%lf,%lf", &i1, &j1, &x, &y, &gx1, &gy1) != 6)
            continue; /* headers */
        if (sscanf(lb, "%d,%d,%lf,%lf,%lf,%lf", &i2, &j2, &x, &y, &gx2, &gy2) != 6 || i1 != i2 ||
            j1 != j2) {
            e = NAN;
            break;
        }
        e = fmax(e, fmax(fabs(gx1 - gx2), fabs(gy1 - gy2)));
        rows++;
    }
    if (a)
        fclose(a);
    if (b)
        fclose(b);
    return rows > 0 ? e : NAN;
}

/* Measurements flagged as outliers in a residuals file (its last column 1); -1 if unreadable. */
static long flagged(const char *res)
{
    FILE *f = fopen(res, "r");
    char line[512];
    long n = 0;
    while (f && fgets(line, sizeof line, f)) {
        size_t len = strlen(line);
        while (len > 0 && (line[len - 1] == '\n' || line[len - 1] == '\r'))
            line[--len] = '\0';
        if (len >= 2 && line[len - 1] == '1' && line[len - 2] == ',')
            n++;
    }
    if (!f)
        return -1;
    fclose(f);
    return n;
}

/* The whole selfcal grid command (timed); exe: this tree's or the previous release's. */
static int selfcal_command(bench_files *f, figures *out, const char *exe)
{
    char *grid[] = {(char *)exe, "grid", "--method", "lsq", f->in, "--map", f->map,
                    "--residuals", f->res, "--quiet", NULL};
    if (run_command(grid, out) != 0)
        return -1;
    snprintf(out->ordering, sizeof out->ordering, "-");
    return 0;
}

/* Keep the fastest run's time (the machine is shared: the others measure its tenants) and the
 * largest peak memory. */
static void keep_best(figures *best, const figures *run, int first)
{
    if (first) {
        *best = *run;
        return;
    }
    if (run->seconds < best->seconds) {
        best->seconds = run->seconds;
        best->wall = run->wall;
    }
    if (run->mib > best->mib)
        best->mib = run->mib;
}

/* One N: the data, the matrix, then REPEAT runs of each side, interleaved. */
static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

static int bench_one(int n, int stage, const char *dir, const char *path, int repeat,
                     figures *a, figures *c, figures *shipped, double *ratio, figures *e,
                     figures *prev, double *g_err, long *n_flagged)
{
    const char *prev_exe = getenv("SELFCAL_PREV");
    double ratios[64];
    if (repeat > 64)
        repeat = 64;
    bench_files f;
    bench_files_init(&f, n, stage, dir);
    figures run;
    if (selfcal_data(&f) != 0 || in_child(e, 1, n, stage, path) != 0)
        return -1;
    for (int r = 0; r < repeat; ++r) {
        memset(&run, 0, sizeof run);
        if (selfcal_command(&f, &run, SELFCAL_CLI) != 0)
            return -1;
        keep_best(a, &run, r == 0);
        if (r == 0)
            *g_err = map_error(f.map, f.truth), *n_flagged = flagged(f.res);
        double mine = run.seconds;
        if (prev_exe) { /* a failure (refused, killed) is a figure too: its status */
            figures pr;
            memset(&pr, 0, sizeof pr);
            if (selfcal_command(&f, &pr, prev_exe) != 0)
                pr.seconds = -pr.seconds - 1e-9; /* negative: failed after that many seconds */
            keep_best(prev, &pr, r == 0);
        }
        if (in_child(&run, 2, n, stage, path) != 0)
            return -1;
        keep_best(c, &run, r == 0);
        ratios[r] = mine / run.seconds;
        if (in_child(&run, 3, n, stage, path) != 0)
            return -1;
        keep_best(shipped, &run, r == 0);
    }
    qsort(ratios, (size_t)repeat, sizeof ratios[0], cmp_double);
    *ratio = repeat % 2 ? ratios[repeat / 2] : 0.5 * (ratios[repeat / 2 - 1] + ratios[repeat / 2]);
    remove(f.in), remove(f.truth), remove(f.map), remove(f.res), remove(path);
    return 0;
}

int main(int argc, char **argv)
{
    if (!getenv("OPENBLAS_NUM_THREADS") || !getenv("OMP_NUM_THREADS")) {
        setenv("OPENBLAS_NUM_THREADS", "1", 0);
        setenv("OMP_NUM_THREADS", "1", 0);
        execv("/proc/self/exe", argv);
    }
    int ns[16], stages[16] = {0}, count = 0;
    int repeat = getenv("REPEAT") ? atoi(getenv("REPEAT")) : 3;
    if (repeat < 1)
        repeat = 1;
    for (int i = 1; i < argc && count < 16; ++i) {
        const char *colon = strchr(argv[i], ':');
        stages[count] = colon ? atoi(argv[i]) : 0;
        ns[count++] = atoi(colon ? colon + 1 : argv[i]);
    }
    if (count == 0)
        ns[0] = 101, ns[1] = 201, ns[2] = 301, count = 3;
    char dir[64], path[96];
    snprintf(dir, sizeof dir, "/tmp/bench_grid_cholmod.XXXXXX");
    if (!mkdtemp(dir))
        return 1;
    snprintf(path, sizeof path, "%s/matrix.bin", dir);
    printf("Grid least squares (Petro's plan, or S:N stitched): the whole `selfcal grid --method lsq`\n"
           "command (read, every node's sigma, leverages and outlier test, write) vs CHOLMOD\n"
           "analyze+factor+solve of the same matrix (targets: time ratio <= 2.5, memory ratio <= 1.5;\n"
           "N = 201 < 1.5 s, N = 401 < 30 s; stitched 401:41 < 20 s, 1001:101 < 2 min and 12 GiB\n"
           "within 2x CHOLMOD's time and 1.5x its memory)\n");
    printf("(CPU seconds, both sides with OPENBLAS_NUM_THREADS=%s OMP_NUM_THREADS=%s; wall seconds\n"
           "in brackets; memory: each process's peak RSS, MiB; each side run %d times, interleaved:\n"
           "the fastest run's time, the largest peak; time x: the median of the runs' paired ratios)\n",
           getenv("OPENBLAS_NUM_THREADS"), getenv("OMP_NUM_THREADS"), repeat);
    printf("(CHOLMOD: OpenMP regions on one thread, as selfcal's command line runs them: the target's\n"
           "ratios; shipped: CHOLMOD's own four-thread regions, whose idle threads spin or wait;\n"
           "its CPU s and the ratio of the fastest runs, for reference)\n");
    const char *huge = getenv("SELFCAL_HUGEPAGES");
    printf("(selfcal %s huge pages for SuiteSparse's large blocks; the CHOLMOD child uses\n"
           "SuiteSparse's own allocator: SELFCAL_HUGEPAGES=0 runs selfcal the same way)\n",
           huge && !strcmp(huge, "0") ? "without" : "with");
    printf("(factored: reduced = A eliminated, full = A kept (issue 33); unknowns, nnz(L) and flops\n"
           "of selfcal's analysis; G err: the largest |G - truth| in um on stitched stages, whose\n"
           "data carry 1e-8 um of noise; prev: SELFCAL_PREV's CPU s and MiB, '-' if not given,\n"
           "'exit S after T s' if it failed; flags: measurements the outlier test flagged)\n");
    printf("%5s %5s %5s %7s %8s %9s %8s | %8s %8s %7s | %8s %8s %7s %-6s | %6s %6s | %8s %6s | "
           "%8s %5s | %s\n", "stage", "N", "views", "matrix", "unknowns", "nnz(L)", "flops", "selfcal",
           "(wall)", "MiB", "CHOLMOD", "(wall)", "MiB", "order", "time x", "mem x", "shipped", "x",
           "G err", "flags", "prev");
    for (int t = 0; t < count; ++t) {
        int n = ns[t];
        figures a, c, sh, e, pv;
        double g_err = NAN;
        long n_flagged = -1;
        memset(&pv, 0, sizeof pv);
        memset(&a, 0, sizeof a);
        memset(&c, 0, sizeof c);
        memset(&sh, 0, sizeof sh);
        memset(&e, 0, sizeof e);
        double ratio;
        int st = stages[t] > 0 ? stages[t] : n;
        if (bench_one(n, stages[t], dir, path, repeat, &a, &c, &sh, &ratio, &e, &pv, &g_err, &n_flagged) != 0) {
            printf("%5d %5d failed\n", st, n);
            continue;
        }
        char prev[96] = "-";
        if (getenv("SELFCAL_PREV") && pv.seconds >= 0)
            snprintf(prev, sizeof prev, "%.3f s %.1f MiB", pv.seconds, pv.mib);
        else if (getenv("SELFCAL_PREV"))
            snprintf(prev, sizeof prev, "exit %d after %.3f s (%.2f wall), %.1f MiB", pv.status,
                     -pv.seconds, pv.wall, pv.mib);
        printf("%5d %5d %5d %7s %8ld %9ld %8.2g | %8.3f %8.2f %7.1f | %8.3f %8.2f %7.1f %-6s | "
               "%6.2f %6.2f | %8.3f %6.2f | %8.2g %5ld | %s\n",
               st, n, e.views, e.solver == SC_GRID_SOLVER_FULL ? "full" : "reduced", e.n_red,
               e.nnz_l, e.flops, a.seconds, a.wall, a.mib, c.seconds, c.wall, c.mib, c.ordering,
               ratio, a.mib / c.mib, sh.seconds, a.seconds / sh.seconds, g_err, n_flagged, prev);
        fflush(stdout);
    }
    remove(path);
    rmdir(dir);
    return 0;
}
