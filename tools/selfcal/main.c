/* selfcal — the command line: simulate, calibrate, build and inspect tables, draw. */
#include <dlfcn.h>
#include <errno.h>
#include <stdlib.h>
#include <malloc.h>
#include <stdio.h>
#include <string.h>

#include "../../libselfcal/src/common/big_alloc.h"
#include "cli.h"
#include "cli_opts.h"
#include "selfcal/atomic_file.h"
#include "selfcal/version.h"

/* The process-wide allocator and threading settings a command runs with (run_command, which
 * says why): glibc's own (none), those of the commands that factor a grid's normal matrix, or the
 * heap thresholds of the profile's transforms. */
typedef enum { TUNE_NONE = 0, TUNE_FACTOR, TUNE_TRANSFORM } tuning;

/* One row per command line that `selfcal --help` lists. run == NULL: a line of the help only
 * (more forms of a command dispatched by an earlier row, e.g. lut dump). what may be NULL. */
typedef struct command {
    const char *name, *sub; /* sub: second word, or NULL */
    int (*run)(int argc, char **argv);
    const char *synopsis, *what;
    const char *outputs; /* its output options, space separated (cli_check_output_paths) */
    tuning tune;         /* its allocator tuning (run_command) */
    const cli_cmd_opts *opts; /* its option table (cli_opts.h), NULL where not converted yet */
} command;

static const command commands[] = {
    {"grid", NULL, cmd_grid, "grid --method {ye,double-shift,lsq} IN.csv --map G.csv [...]",
     "separate stage error G from plate error A", "--map --artifact --summary --residuals --covariance --plot",
     TUNE_FACTOR, &cli_grid_opts},
    {"plan", NULL, cmd_plan, "plan PLAN.csv | plan --design ...", "does a plan identify G? its uncertainty; design one", "-o --out",
     TUNE_FACTOR, &cli_plan_opts},
    {"profile", NULL, cmd_profile, "profile --method {dft,lsq} IN.csv --out P.csv",
     "straightness profile + stage motion error", "--out -o --plot --residuals", TUNE_TRANSFORM,
     &cli_profile_opts},
    {"profile-plan", NULL, cmd_profile_plan, "profile-plan --n N --s-mm S ...", "rank sensor spacings (d1, d2)", NULL, TUNE_NONE,
     &cli_profile_plan_opts},
    {"lut", NULL, cmd_lut, "lut build --map G.csv [--profile AXIS:DIR:P.csv[@OFFSET_MM]] -o TABLE",
     "build a correction table", "-o --out", TUNE_NONE, &cli_lut_build_opts},
    {"lut", NULL, NULL, "lut dump TABLE", "print a table as CSV", NULL, TUNE_NONE, NULL},
    {"lut", NULL, NULL, "lut info TABLE", "size, encoding, quantization, provenance", NULL, TUNE_NONE, NULL},
    {"export", NULL, cmd_export, "export --format F --map G.csv -o OUT", "resample the map for a machine controller", "-o --out", TUNE_NONE,
     &cli_export_opts},
    {"import", "grid", cmd_import_grid, "import grid --n N --pitch-mm P --view \"rot=R shift=SX,SY\" FILE ... -o IN.csv",
     "a measuring machine's export -> selfcal-grid v1", "-o --out", TUNE_NONE,
     &cli_import_grid_opts},
    {"import", "profile", cmd_import_profile, "import profile --spacing-mm D1 LOG1 --spacing-mm D2 LOG2 -o IN.csv",
     "two scans' logs -> selfcal-profile v1", "-o --out", TUNE_NONE,
     &cli_import_profile_opts},
    {"simulate", "grid", cmd_simulate_grid, "simulate grid --plan P --out IN.csv --truth-map T.csv",
     "simulated plate measurements + truth", "--out --truth-map --truth-artifact --truth-summary", TUNE_NONE,
     &cli_simulate_grid_opts},
    {"simulate", "profile", cmd_simulate_profile, "simulate profile --out IN.csv --truth T.csv",
     "simulated two-scan data + truth", "--out -o --truth", TUNE_NONE,
     &cli_simulate_profile_opts},
    {"simulate", "exports", cmd_simulate_exports, "simulate exports IN.csv --dir DIR", "a measuring machine's files", NULL, TUNE_NONE,
     &cli_simulate_exports_opts},
    {"plot", "map", cmd_plot_map, "plot map G.csv -o map.svg", "arrow plot of an error map", "-o --out", TUNE_NONE,
     &cli_plot_map_opts},
    {"plot", "profile", cmd_plot_profile, "plot profile P.csv -o p.svg", "profile and uncertainty curves", "-o --out", TUNE_NONE,
     &cli_plot_profile_opts},
    {"plot", "xy", cmd_plot_xy, "plot xy DATA.csv -o c.svg [--logx] [--logy]", "line chart of CSV columns", "-o --out", TUNE_NONE,
     &cli_plot_xy_opts},
    {"report", "grid", cmd_report_grid, "report grid IN.csv -o R.html [--method M]", "calibration report (HTML, PDF)", "-o --out --pdf",
     TUNE_FACTOR, &cli_report_grid_opts},
    {"report", "profile", cmd_report_profile, "report profile IN.csv -o R.html [--method M]",
     "profile report (HTML, PDF)", "-o --out --pdf", TUNE_NONE,
     &cli_report_profile_opts},
    {"verify", NULL, cmd_verify, "verify V.csv --table T.lut --artifact A.csv --tolerance-um T",
     "check a compensated stage", "--html --plot --residuals", TUNE_NONE,
     &cli_verify_opts},
};
#define N_COMMANDS (sizeof commands / sizeof commands[0])

static int is_help(const char *a)
{
    return !strcmp(a, "--help") || !strcmp(a, "-h") || !strcmp(a, "help");
}

/* The command lines whose first word is name (all of them if name is NULL). */
static void usage(FILE *to, const char *name)
{
    if (name)
        fprintf(to, "usage: selfcal %s SUBCOMMAND [options]   (selfcal %s SUBCOMMAND --help for details)\n\n",
                name, name);
    else
        fprintf(to, "usage: selfcal COMMAND [options]   (selfcal COMMAND --help for details)\n"
                    "       selfcal --help | --version\n\n");
    for (size_t k = 0; k < N_COMMANDS; ++k) {
        const command *c = &commands[k];
        if (name && strcmp(c->name, name) != 0)
            continue;
        if (!c->what)
            fprintf(to, "  selfcal %s\n", c->synopsis);
        else if (strlen(c->synopsis) <= 40)
            fprintf(to, "  selfcal %-40s %s\n", c->synopsis, c->what);
        else
            fprintf(to, "  selfcal %s\n  %-48s %s\n", c->synopsis, "", c->what);
    }
    if (!name)
        fprintf(to, "\n  selfcal --help, -h    this list\n"
                    "  selfcal --version     the version (%s)\n\n"
                    "Exit status: 0 success, 2 bad input (one stderr line: selfcal: FILE:LINE: reason),\n"
                    "1 other failures; verify: 3 when the machine fails. Manual: man selfcal.\n",
                sc_version());
}

/* selfcal --options COMMAND [SUBCOMMAND]: the command's option table (cli_opts_print), from
 * which selfcal(1)'s option lists are made. */
static int print_options(int argc, char **argv)
{
    char want[64] = "";
    for (int k = 0; k < argc && k < 2; ++k)
        snprintf(want + strlen(want), sizeof want - strlen(want), "%s%.30s", k ? " " : "", argv[k]);
    for (size_t k = 0; k < N_COMMANDS; ++k)
        if (commands[k].opts && !strcmp(commands[k].opts->cmd, want)) {
            cli_opts_print(stdout, commands[k].opts);
            return CLI_OK;
        }
    fprintf(stderr, "selfcal --options: no option table for '%s'\n", want);
    return CLI_BAD_INPUT;
}

/* Whatever a command printed must have reached stdout: a full disk, /dev/full or a closed pipe
 * makes the command fail (exit 1, one line) instead of reporting success with nothing written. */
static int finish(int rc)
{
    errno = 0;
    if (fflush(stdout) != 0 || ferror(stdout)) {
        if (rc != CLI_OK) /* the command failed and said so already: one line */
            return rc;
        fprintf(stderr, "selfcal: cannot write to standard output: %s\n",
                errno ? strerror(errno) : "write error");
        return CLI_FAIL;
    }
    return rc;
}

/* A symbol of a shared library loaded here for a process-wide setting, or NULL: when the
 * environment variable env says keep (the user keeps the library's own setting), or where the
 * library or the symbol is missing (nothing to set then). */
static void *setting_symbol(const char *env, const char *keep, const char *lib, const char *name)
{
    const char *v = getenv(env);
    if (v && !strcmp(v, keep))
        return NULL;
    void *h = dlopen(lib, RTLD_NOW | RTLD_GLOBAL);
    return h ? dlsym(h, name) : NULL;
}

/* CHOLMOD's supernodal factorization (Debian's SuiteSparse 5.12) opens OpenMP parallel regions of
 * a fixed four threads for its small scatter loops, whatever OMP_NUM_THREADS says; its work is in
 * BLAS. On this project's shared 2-core machine the idle threads' futex waits cost the N = 201
 * grid command 0.2-0.3 s of CPU and 22 000 context switches (docs/grid-lsq.md), so the command
 * line runs OpenMP regions on one thread (max-active-levels 0). The library loads CHOLMOD with
 * dlopen at its first grid solve; the command line loads GNU OpenMP's runtime first (the one
 * Debian's CHOLMOD uses; the same instance is shared) and sets that there: no OpenMP runtime is
 * linked, nothing happens where none is installed, and the library itself never changes a
 * process-wide setting. SELFCAL_OPENMP=1 keeps OpenMP's own settings. */
static void openmp_regions_serial(void)
{
    void *sym = setting_symbol("SELFCAL_OPENMP", "1", "libgomp.so.1", "omp_set_max_active_levels");
    if (!sym)
        return;
    void (*set_levels)(int);
    memcpy(&set_levels, &sym, sizeof sym);
    set_levels(0);
}

/* SuiteSparse's large blocks (the factor above all) on transparent huge pages where the system
 * gives them on request (Linux's madvise mode): the factor is written whole once, and with 4 KiB
 * pages each page costs a fault (at N = 201 19 000 of them, about 10 % of the command's CPU).
 * SuiteSparse takes its allocator from SuiteSparse_config, set once by the application before
 * any use (SuiteSparse_config.h): the command line is that application here (the library leaves
 * process-wide settings alone). The library's own allocation with the hint serves
 * (libselfcal/src/common/big_alloc.c, compiled here too): blocks from 2 MiB up start on a 2 MiB
 * boundary (unless asked zeroed) and their 2 MiB-aligned inside is advised before the first
 * touch; freeing is glibc's.
 * SELFCAL_HUGEPAGES=0 leaves SuiteSparse's allocator alone. */
static void *huge_malloc(size_t n)
{
    return sc_big_alloc(n, 1, 0);
}

static void *huge_calloc(size_t k, size_t n)
{
    return sc_big_alloc(k, n, 1);
}

static void suitesparse_huge_pages(void)
{
    struct suitesparse_config { /* the head of SuiteSparse_config_struct (5.x) */
        void *(*malloc_func)(size_t);
        void *(*calloc_func)(size_t, size_t);
        void *(*realloc_func)(void *, size_t);
        void (*free_func)(void *);
    } *c = setting_symbol("SELFCAL_HUGEPAGES", "0", "libsuitesparseconfig.so.5",
                          "SuiteSparse_config");
    if (!c || c->malloc_func != malloc || c->calloc_func != calloc || c->realloc_func != realloc)
        return; /* not SuiteSparse's defaults: someone chose already, or another layout */
    c->malloc_func = huge_malloc;
    c->calloc_func = huge_calloc;
    c->realloc_func = sc_big_realloc;
}

/* The commands that factor a grid's normal matrix (grid, plan, report grid) and only they: OpenMP
 * regions on one thread and SuiteSparse's factor on huge pages (above), and large buffers handed
 * back to the system when freed: glibc's
 * dynamic mmap threshold would keep the factorization's freed workspaces in the heap, and the grid
 * least squares' peak memory would carry them (+60 MB at N = 401, bench_grid_cholmod). The fixed
 * threshold is 4 MiB: blocks below it come from the heap and are used again when freed. With
 * 256 KiB every block from there up was mapped, faulted in and unmapped anew: N = 101 took
 * 3 300 more page faults (11 100 against 7 900, about 5 % of its CPU) and N = 401 0.8 s more
 * system time, for 1 MB less peak memory. Not the
 * others: no OpenMP runtime loaded at their start, and FFTW's buffers, mapped and unmapped at
 * every transform with that threshold, made `profile --method dft` at N = 10⁶ spend 0.6 s
 * faulting pages in (1.6 s instead of 1.1 s). `profile` keeps blocks up to 32 MiB in the heap and
 * gives it back above 64 MiB free, fixed: glibc's own thresholds move with the largest block
 * freed so far, and the DFT's transform buffers (8 MB at N = 10⁶) were faulted in anew at every
 * transform (240 000 faults, 1.25 s) or not (65 000, 1.0 s) depending on which array the reader
 * had happened to free before; its peak memory stays (291 MB against 289 at N = 10⁶). Not the
 * others: the same setting raised `report profile`'s peak from 313 to 359–383 MB and `plot
 * profile`'s from 50 to 70 MB for no time saved, so they keep glibc's own. */
static int run_command(const command *c, int argc, char **argv)
{
    if (c->outputs) {
        /* the command as typed: "report profile", "lut build", not "profile", "lut" */
        const char *sub = c->sub                                  ? c->sub
                          : !strcmp(c->name, "lut") && argc > 1 ? argv[1] /* its own verbs */
                                                                 : NULL;
        char full[64];
        snprintf(full, sizeof full, "%s%s%.40s", c->name, sub ? " " : "", sub ? sub : "");
        int rc = cli_check_output_paths(full, c->outputs, argc, argv);
        if (rc >= 0)
            return rc;
    }
    if (c->tune == TUNE_FACTOR) {
        openmp_regions_serial();
        suitesparse_huge_pages();
        mallopt(M_MMAP_THRESHOLD, 4 << 20);
    } else if (c->tune == TUNE_TRANSFORM) {
        mallopt(M_MMAP_THRESHOLD, 32 << 20);
        mallopt(M_TRIM_THRESHOLD, 64 << 20);
    }
    return finish(c->run(argc, argv));
}

int main(int argc, char **argv)
{
    sc_afile_cleanup_on_signals(); /* no *.tmpXXXXXX left by Ctrl-C or a service stop */
    if (argc < 2) {
        fprintf(stderr, "selfcal: a COMMAND is needed (selfcal --help lists them)\n");
        return CLI_BAD_INPUT;
    }
    if (is_help(argv[1])) {
        usage(stdout, NULL);
        return finish(CLI_OK);
    }
    if (!strcmp(argv[1], "--options"))
        return finish(print_options(argc - 2, argv + 2));
    if (!strcmp(argv[1], "--version")) {
        printf("selfcal %s\n", sc_version());
        return finish(CLI_OK);
    }
    for (size_t k = 0; k < N_COMMANDS; ++k) {
        const command *c = &commands[k];
        if (!c->run || strcmp(argv[1], c->name) != 0)
            continue;
        if (!c->sub)
            return run_command(c, argc - 1, argv + 1);
        if (argc >= 3 && !strcmp(argv[2], c->sub))
            return run_command(c, argc - 2, argv + 2);
    }
    /* a known first word whose second word is missing or unknown: list the choices */
    int known = 0;
    for (size_t k = 0; k < N_COMMANDS; ++k)
        known |= commands[k].sub && !strcmp(argv[1], commands[k].name);
    if (known && argc >= 3 && is_help(argv[2])) {
        usage(stdout, argv[1]);
        return finish(CLI_OK);
    }
    known = 0;
    for (size_t k = 0; k < N_COMMANDS; ++k)
        if (commands[k].sub && !strcmp(argv[1], commands[k].name)) {
            if (!known)
                fprintf(stderr, "selfcal %s: %s%s%sexpected one of:", argv[1],
                        argc >= 3 ? "unknown subcommand '" : "", argc >= 3 ? argv[2] : "",
                        argc >= 3 ? "'; " : "");
            fprintf(stderr, " %s", commands[k].sub);
            known = 1;
        }
    if (known) {
        fputc('\n', stderr);
        return CLI_BAD_INPUT;
    }
    fprintf(stderr, "selfcal: unknown command '%s' (selfcal --help lists them)\n", argv[1]);
    return CLI_BAD_INPUT;
}
