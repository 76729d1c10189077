/* selfcal simulate profile — simulated two-scan straightness data (SPEC §2) plus the truth. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/profile.h"
#include "selfcal/profile_lsq.h"
#include "selfcal/profile_sim.h"
#include "selfcal/stage_map.h"

static const char USAGE[] =
    "usage: selfcal simulate profile --out IN.csv --truth T.csv [options]\n"
    "\n"
    "Writes the selfcal-profile v1 data file and the truth n,x_mm,f_um,uf_um,ey_um (f and e_y\n"
    "relative to their least-squares lines; uf empty; e_y empty where n >= N - d1).\n"
    "--profile FILE.dat: a DABAM profile with its .txt metadata. --probe-gain, --angle-scale,\n"
    "--drift-um, --gap and --outlier simulate a real rig (docs/profile.md, Real rigs): nothing\n"
    "of them is stated in the file's header.\n";

/* The command line besides the simulation's own parameters. */
typedef struct {
    const char *out, *truth, *prof;
    double amp;
    long harmonics;
    /* a real rig's effects on the readings */
    double gain, angle, drift_um, outlier_um;
    long gap[3], outlier[2]; /* scan, first, last (0: none); scan, n */
} sim_profile_args;

/* The whole command line: the simulation's parameters and the rest. */
typedef struct sim_profile_cli {
    sc_profile_sim p;
    sim_profile_args a;
} sim_profile_cli;

/* --gap K:A..B into the sim_profile_args */
static int parse_gap(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_profile_args *a = field;
    int used = 0;
    (void)opt;
    if (sscanf(v, "%ld:%ld..%ld%n", &a->gap[0], &a->gap[1], &a->gap[2], &used) != 3 || v[used] ||
        (a->gap[0] != 1 && a->gap[0] != 2) || a->gap[1] < 0 || a->gap[2] < a->gap[1])
        return cli_usage_error(cmd, "--gap: '%s' is not K:A..B (K 1 or 2, 0 <= A <= B)", v);
    return CLI_OK;
}

/* --outlier K:N:UM into the sim_profile_args */
static int parse_outlier(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_profile_args *a = field;
    int used = 0;
    (void)opt;
    if (sscanf(v, "%ld:%ld:%lf%n", &a->outlier[0], &a->outlier[1], &a->outlier_um, &used) != 3 ||
        v[used] || (a->outlier[0] != 1 && a->outlier[0] != 2) || a->outlier[1] < 0 ||
        !isfinite(a->outlier_um))
        return cli_usage_error(cmd, "--outlier: '%s' is not K:N:UM", v);
    return CLI_OK;
}

/* --noise-free: both noises 0 (a later --sigma-* sets its own again) */
static int set_noise_free(const char *cmd, const char *opt, const char *v, void *field)
{
    sc_profile_sim *p = field;
    (void)cmd, (void)opt, (void)v;
    p->sigma_disp_um = p->sigma_angle_urad = 0;
    return CLI_OK;
}

/* --no-sigma-lines */
static int set_no_sigma_lines(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)cmd, (void)opt, (void)v;
    ((sc_profile_sim *)field)->write_sigma = 0;
    return CLI_OK;
}

#define F(field) offsetof(sim_profile_cli, field)
#define NUM(name, f, v, dflt, text)                                                                \
    {name, CLI_DOUBLE, F(f), v, -HUGE_VAL, HUGE_VAL, .bad = "%s: '%s' is not a number",            \
     .def = dflt, .help = text}
#define WHOLE(kind, name, f, v, lo, hi, dflt, text)                                                \
    {name, kind, F(f), v, lo, hi, .bad = "%s: '%s' must be a whole number in " #lo ".." #hi,        \
     .def = dflt, .help = text}
/* simulate profile's options (cli_opts.h), in the order of its --help */
static const cli_opt SIM_PROFILE_OPTS[] = {
    {"--out|-o", CLI_STRING, F(a.out), "IN.csv", .help = "the data file (required)"},
    {"--truth", CLI_STRING, F(a.truth), "T.csv", .help = "the true profile (required)"},
    WHOLE(CLI_INT, "--n|--N", p.n, "N", 3, 100000000, "330", "the number of points"),
    NUM("--s-mm", p.s_mm, "S", "1", "the sampling step (mm)"),
    WHOLE(CLI_INT, "--d1", p.d1, "D1", 1, 100000000, "10", "scan 1's sensor spacing (samples)"),
    WHOLE(CLI_INT, "--d2", p.d2, "D2", 1, 100000000, "11", "scan 2's sensor spacing (samples)"),
    {"--profile", CLI_STRING, F(a.prof), "random|FILE.dat", .def = "random",
     .help = "the profile: random, or a DABAM file"},
    NUM("--amp-um", a.amp, "A", "1", "a random profile's RMS (um)"),
    WHOLE(CLI_LONG, "--harmonics", a.harmonics, "H", 1, 100000, "40", "a random profile's harmonics"),
    NUM("--sigma-disp-um", p.sigma_disp_um, "X", "0.01", "the displacement probes' noise (um)"),
    NUM("--sigma-angle-urad", p.sigma_angle_urad, "Y", "1", "the angle probe's noise (urad)"),
    {"--noise-free", CLI_FLAG, F(p), .parse = set_noise_free, .help = "both noises 0"},
    {"--no-sigma-lines", CLI_FLAG, F(p), .parse = set_no_sigma_lines,
     .help = "no noise header lines in the data file"},
    NUM("--ey-um", p.ey_amp_um, "A", "0.5", "the stage's motion error amplitude (um)"),
    NUM("--ep-urad", p.ep_amp_urad, "A", "2", "the stage's pitch error amplitude (urad)"),
    NUM("--u1-um", p.u1_um, "U", "1.5", "probe 1's zero point (um)"),
    NUM("--u2-um", p.u2_um, "U", "-0.7", "probe 2's zero point (um)"),
    NUM("--u3-urad", p.u3_urad, "U", "3", "the angle probe's zero point (urad)"),
    NUM("--b0-um", p.b0_um, "B", "20", "the offset (um)"),
    {"--seed", CLI_CUSTOM, F(p.seed), "S", .parse = cli_opt_seed, .def = "1",
     .help = "the seed, 0 to 2^64-1"},
    NUM("--probe-gain", a.gain, "K", "1", "m2 read K times (0.001 to 1000)"),
    NUM("--angle-scale", a.angle, "K", "1", "m3 read K times (0.001 to 1000)"),
    NUM("--drift-um", a.drift_um, "A", "0", "A times tau added to every m2 (tau -1..1)"),
    {"--gap", CLI_CUSTOM, F(a), "K:A..B", .parse = parse_gap, .help = "scan K's rows A..B left out"},
    {"--outlier", CLI_CUSTOM, F(a), "K:N:UM", .parse = parse_outlier,
     .help = "UM added to scan K's m2 at n = N"},
};
#undef NUM
#undef WHOLE
#undef F

const cli_cmd_opts cli_simulate_profile_opts = {
    "simulate profile", USAGE, SIM_PROFILE_OPTS,
    (int)(sizeof SIM_PROFILE_OPTS / sizeof SIM_PROFILE_OPTS[0]), 0, cli_opt_no_operand, NULL,
    "unknown option or missing value: %s (see --help)",
    "unknown option or missing value: %s (see --help)", 0, NULL, NULL,
};

static int check_args(const sc_profile_sim *p, const sim_profile_args *a)
{
    if (!a->out || !a->truth)
        return cli_usage_error("simulate profile", "--out and --truth are required (see --help)");
    /* the profile output's limits (its x_mm a map's pitch and within 1 km), as lut build and
     * plot read them */
    if (!(p->s_mm >= SC_STAGE_MAP_MIN_PITCH_MM) || !((p->n - 1) * p->s_mm <= SC_INPUT_MAX_ABS))
        return cli_usage_error("simulate profile", "--s-mm must be at least %g mm and the profile "
                               "(N - 1)·s at most %g mm", SC_STAGE_MAP_MIN_PITCH_MM,
                               SC_INPUT_MAX_ABS);
    if (p->d1 >= p->n || p->d2 >= p->n)
        return cli_usage_error("simulate profile", "spacings d1 = %d, d2 = %d leave no sample for N = %d",
                               p->d1, p->d2, p->n);
    sc_error why; /* data `selfcal profile` could not use: refused now, not after writing them */
    if (!sc_profile_lsq_is_solvable(p->n, p->d1, p->d2, &why))
        return cli_usage_error("simulate profile", "%s", why.msg);
    if (p->sigma_disp_um < 0 || p->sigma_angle_urad < 0 || a->amp < 0)
        return cli_usage_error("simulate profile", "noise levels and amplitudes must be non-negative");
    if (!(a->gain >= 1e-3 && a->gain <= 1e3) || !(a->angle >= 1e-3 && a->angle <= 1e3))
        return cli_usage_error("simulate profile", "--probe-gain and --angle-scale must be in "
                               "[0.001, 1000]");
    const int dk[2] = {p->d1, p->d2};
    if (a->gap[0] && a->gap[2] >= p->n - dk[a->gap[0] - 1])
        return cli_usage_error("simulate profile", "--gap: n = %ld is beyond scan %ld (n < %d)",
                               a->gap[2], a->gap[0], p->n - dk[a->gap[0] - 1]);
    if (a->outlier[0] && a->outlier[1] >= p->n - dk[a->outlier[0] - 1])
        return cli_usage_error("simulate profile", "--outlier: n = %ld is beyond scan %ld (n < %d)",
                               a->outlier[1], a->outlier[0], p->n - dk[a->outlier[0] - 1]);
    return CLI_OK;
}

/* A real rig's effects on the simulated readings (the truth stays the same). */
static void apply_rig(const sim_profile_args *a, sc_profile_data *d)
{
    for (int k = 0; k < 2; ++k) {
        const int m = d->n - d->d[k];
        for (int j = 0; j < m; ++j) {
            double tau = d->n > 1 ? (2.0 * j - (d->n - 1)) / (double)(d->n - 1) : 0;
            d->m2_um[k][j] = d->m2_um[k][j] * a->gain + a->drift_um * tau;
            d->m3_urad[k][j] *= a->angle;
        }
    }
    if (a->outlier[0])
        d->m2_um[a->outlier[0] - 1][a->outlier[1]] += a->outlier_um;
    for (long j = a->gap[1]; a->gap[0] && j <= a->gap[2]; ++j) {
        int k = (int)a->gap[0] - 1;
        d->m1_um[k][j] = d->m2_um[k][j] = d->m3_urad[k][j] = NAN;
    }
}

/* The truth (random or a DABAM mirror), the two scans, and both files written. */
static sc_status simulate_and_write(const sc_profile_sim *p, const sim_profile_args *a,
                                    sc_error *err)
{
    const int n = p->n;
    double *f = malloc((size_t)n * sizeof(double)), *ey = malloc((size_t)n * sizeof(double));
    sc_profile_data d;
    memset(&d, 0, sizeof d);
    char info[512] = "random smooth profile";
    sc_status st = SC_OK;
    if (!f || !ey)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    else if (!strcmp(a->prof, "random"))
        sc_profile_sim_random_truth(p, a->amp, (int)a->harmonics, f);
    else
        st = sc_profile_load_dabam(a->prof, n, p->s_mm, f, info, sizeof info, err);
    if (st == SC_OK)
        st = sc_profile_simulate(p, f, &d, ey, err);
    if (st == SC_OK) {
        apply_rig(a, &d);
        sc_profile_remove_line(n - p->d1, ey);
        /* both files are computed; the data and the truth: both written or neither */
        sc_afile af[2];
        memset(af, 0, sizeof af);
        st = sc_afile_open(&af[0], a->out, err);
        if (st == SC_OK)
            st = sc_afile_open(&af[1], a->truth, err);
        if (st == SC_OK)
            st = sc_profile_write_to(&af[0], &d, err);
        if (st == SC_OK)
            st = sc_profile_write_result_to(&af[1], n, p->s_mm, f, NULL, ey, n - p->d1, err);
        st = sc_afile_finish_all(af, 2, st, err);
    }
    if (st == SC_OK)
        printf("%s\n", info);
    sc_profile_data_free(&d);
    free(f);
    free(ey);
    return st;
}

int cmd_simulate_profile(int argc, char **argv)
{
    sim_profile_cli c = {.a = {NULL, NULL, "random", 1.0, 40, 1.0, 1.0, 0.0, 0.0, {0, 0, 0}, {0, 0}}};
    sc_profile_sim_defaults(&c.p);
    int rc = cli_opts_parse(&cli_simulate_profile_opts, argc, argv, &c);
    if (rc >= 0)
        return rc;
    rc = check_args(&c.p, &c.a);
    if (rc != CLI_OK)
        return rc;
    sc_error err;
    sc_error_clear(&err);
    return simulate_and_write(&c.p, &c.a, &err) == SC_OK ? CLI_OK : cli_report(&err);
}
