/* cli.h — what the selfcal subcommands share: exit codes, error reporting, small helpers. */
#ifndef SELFCAL_CLI_H
#define SELFCAL_CLI_H

#include <stddef.h>
#include <stdint.h>

#include "selfcal/error.h"

/* Exit statuses (SPEC §3): 0 success, 2 bad input, 1 anything else. */
enum { CLI_OK = 0, CLI_FAIL = 1, CLI_BAD_INPUT = 2 };

/* Print "selfcal: file:line: message" on stderr and return the exit status for err->code. */
int cli_report(const sc_error *err);

/* Print "selfcal <cmd>: message" (a usage problem) on stderr and return CLI_BAD_INPUT. */
int cli_usage_error(const char *cmd, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Before a command runs: its outputs (the values of the options listed in outputs, space
 * separated) against its inputs (every other argument naming an existing file) and each other.
 * An output that is an input, two outputs on one file or an empty path: the usage error
 * (CLI_BAD_INPUT); else -1. */
int cli_check_output_paths(const char *cmd, const char *outputs, int argc, char **argv);

/* A profile calibrated with the noise stated as 0 (every u(f) 0) whose least-squares residuals
 * are not: one warning on stderr naming the residuals' scale (cmd: "selfcal profile", ...). */
struct sc_profile_solution;
void cli_warn_zero_noise(const char *cmd, const struct sc_profile_solution *s);

/* A file a command names after an output option (export's OUT-x, simulate exports' DIR/viewK.csv)
 * checked against the inputs of argv (outputs: the options whose values are not inputs), before
 * anything is written: -1 if it names none, else the exit status of the usage error printed
 * ("OPT: the file it names, PATH, is also an input ..."). */
int cli_check_derived_output(const char *cmd, const char *outputs, const char *opt,
                             const char *path, int argc, char **argv);

/* The last component of a path (for titles: an absolute path says nothing and runs off). */
const char *cli_basename(const char *path);

/* "AXIS:DIR:path" (AXIS, DIR one of x, y, z; the path may itself contain ':') -> 0, or -1. */
int cli_parse_profile_arg(const char *s, int *axis, int *dir, const char **path);

/* "AXIS:DIR:path[@OFFSET_MM]": as above, the path copied into path (cap bytes) and the
 * profile's placement along AXIS in offset_mm (0 without "@"; a path that itself ends in
 * "@number" needs an explicit "@0"; |OFFSET_MM| <= SC_INPUT_MAX_ABS) -> 0, or -1. */
int cli_parse_profile_placed(const char *s, int *axis, int *dir, char *path, size_t cap,
                             double *offset_mm);

/* --seed S: a whole number 0..2^64-1 (digits only) into *out: CLI_OK, or the usage error. */
/* This machine's available memory in bytes (MemAvailable of /proc/meminfo; else the physical
 * memory; 0 if unknown): the limit a command's large work is refused above, up front, instead of
 * being killed after a long time (or taking the machine). progress.c */
double cli_memory_bytes(void);

/* --max-memory SIZE (bytes, or with K, M, G, T: powers of 1024) into *out: CLI_OK, or the usage
 * error (cli.c). */
int cli_parse_max_memory(const char *cmd, const char *v, double *out);

/* --solver auto|reduced|full into *out (SC_GRID_SOLVER_*): CLI_OK, or the usage error.
 * solver_opts.c */
int cli_parse_solver(const char *cmd, const char *v, int *out);

/* --node-sigma all|none|sample:K into *mode (SC_GRID_NODE_SIGMA_*) and *sample (K, else 0):
 * CLI_OK, or the usage error. solver_opts.c */
int cli_parse_node_sigma(const char *cmd, const char *v, int *mode, int *sample);

/* The same as cli_opts.h parse functions: field an int (SC_GRID_SOLVER_*), an sc_grid_options
 * (its node_sigma and node_sigma_sample). solver_opts.c */
int cli_opt_solver(const char *cmd, const char *opt, const char *v, void *field);
int cli_opt_node_sigma(const char *cmd, const char *opt, const char *v, void *field);

/* Progress of a long solve on stderr: on a terminal (one line, rewritten) or when asked (one line
 * per phase): the phase, the time so far, the time left once the factor's rate is known, and the
 * estimated peak memory once (progress.c). */
typedef struct cli_progress {
    const char *cmd;
    int on, tty, open, stated;
    double t0, work_t0, limit_bytes;
} cli_progress;
void cli_progress_init(cli_progress *p, const char *cmd, int asked, double limit_bytes);
void cli_progress_phase(cli_progress *p, const char *phase, double done, double total,
                        double peak_bytes);
/* An sc_grid_progress_fn for a cli_progress (ctx). */
void cli_progress_lsq(void *ctx, const char *phase, double work_done, double work_total,
                      double peak_bytes);
void cli_progress_end(cli_progress *p);

int cli_parse_seed(const char *cmd, const char *v, uint64_t *out);

/* A noise option (--sigma-disp-um, --sigma-angle-urad) of value v: a number from min_val (0 or
 * "more than 0" with positive = 1) to SC_INPUT_MAX_ABS into *out: CLI_OK, or the usage error
 * naming the option and the range (the same words in every command). */
int cli_parse_noise(const char *cmd, const char *opt, const char *v, int positive, double *out);

/* --max-nodes N (2..SC_LUT_MAX_NX) of lut build and export into *out: CLI_OK, or the usage error. */
int cli_parse_max_nodes(const char *cmd, const char *v, int *out);

struct sc_grid_options;
/* The least-squares options grid and report grid share, with their value v, into o:
 * "--outlier-alpha A" (for the whole data set) or "--outlier-alpha-each A" (each coordinate),
 * 0 < A < 1, and "--view-noise stated|estimate". -1 if opt is none of them, else CLI_OK or the
 * usage error. */
int cli_parse_lsq_option(const char *cmd, const char *opt, const char *v,
                         struct sc_grid_options *o);

struct sc_lut;
struct sc_lut_fit_report;
/* The map at path into lut's grid: fitted by at most max_nodes nodes per axis
 * (sc_lut_read_map_fitted, *fit filled), or with max_nodes 0 as it is (sc_lut_read_map, *fit
 * zeroed: not fitted). */
sc_status cli_read_map(const char *path, int max_nodes, struct sc_lut *lut,
                       struct sc_lut_fit_report *fit, sc_error *err);

/* Print (stdout) what a table fitted to a larger map is and how far it is from the map. */
void cli_print_fit(const char *map_path, const struct sc_lut *lut,
                   const struct sc_lut_fit_report *fit);

/* Subcommands: argv[0] is the subcommand's own name. */
int cmd_grid(int argc, char **argv);
int cmd_plan(int argc, char **argv);
int cmd_profile(int argc, char **argv);
int cmd_profile_plan(int argc, char **argv);
int cmd_lut(int argc, char **argv);
int cmd_export(int argc, char **argv);
int cmd_simulate_grid(int argc, char **argv);
int cmd_simulate_exports(int argc, char **argv);
int cmd_import_grid(int argc, char **argv);
int cmd_import_profile(int argc, char **argv);
int cmd_simulate_profile(int argc, char **argv);
int cmd_plot_map(int argc, char **argv);
int cmd_plot_profile(int argc, char **argv);
int cmd_plot_xy(int argc, char **argv);
int cmd_report_grid(int argc, char **argv);
int cmd_report_profile(int argc, char **argv);
int cmd_verify(int argc, char **argv);

#endif
