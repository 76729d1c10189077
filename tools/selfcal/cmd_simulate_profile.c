/* selfcal simulate profile — simulated two-scan straightness data (SPEC §2) plus the truth. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/profile.h"
#include "selfcal/profile_lsq.h"
#include "selfcal/profile_sim.h"
#include "selfcal/stage_map.h"

static const char *USAGE =
    "usage: selfcal simulate profile --out IN.csv --truth T.csv [options]\n"
    "  --n N (330)  --s-mm S (1)  --d1 D1 (10)  --d2 D2 (11)\n"
    "  --profile random|FILE.dat (random; FILE.dat: a DABAM profile with its .txt metadata)\n"
    "  --amp-um A (1: RMS of a random profile)  --harmonics H (40)\n"
    "  --sigma-disp-um X (0.01)  --sigma-angle-urad Y (1)  [--noise-free] [--no-sigma-lines]\n"
    "  --ey-um A (0.5)  --ep-urad A (2)  --u1-um U (1.5)  --u2-um U (-0.7)  --u3-urad U (3)\n"
    "  --b0-um B (20)  --seed S (1)\n"
    "  A real rig (docs/profile.md, Real rigs; nothing stated in the file's header):\n"
    "  --probe-gain K (1: m2 read K times)  --angle-scale K (1: m3 read K times)\n"
    "  --drift-um A (0: A·tau added to every m2, tau = -1..1 along the scan)\n"
    "  --gap K:A..B (scan K's rows n = A..B left out)  --outlier K:N:UM (UM added to scan K's m2 at n = N)\n"
    "  Writes the selfcal-profile v1 data file and the truth n,x_mm,f_um,uf_um,ey_um (f and e_y\n"
    "  relative to their least-squares lines; uf empty; e_y empty where n >= N - d1).\n";

static int get_double(const char *opt, const char *s, double *out)
{
    if (sc_parse_double(s, out) != 0)
        return cli_usage_error("simulate profile", "%s: '%s' is not a number", opt, s);
    return 0;
}

static int get_int(const char *opt, const char *s, long lo, long hi, long *out)
{
    if (sc_parse_long(s, out) != 0 || *out < lo || *out > hi)
        return cli_usage_error("simulate profile", "%s: '%s' must be a whole number in %ld..%ld", opt,
                               s, lo, hi);
    return 0;
}

/* The command line besides the simulation's own parameters. */
typedef struct {
    const char *out, *truth, *prof;
    double amp;
    long harmonics;
    /* a real rig's effects on the readings */
    double gain, angle, drift_um, outlier_um;
    long gap[3], outlier[2]; /* scan, first, last (0: none); scan, n */
} sim_profile_args;

enum { NOT_NUMERIC = -1 };

/* The options with a number: into the parameters p or a. Returns NOT_NUMERIC for others. */
static int parse_number_option(const char *o, const char *v, sc_profile_sim *p,
                               sim_profile_args *a)
{
    const struct {
        const char *name;
        double *dst;
    } reals[] = {
        {"--s-mm", &p->s_mm},
        {"--amp-um", &a->amp},
        {"--sigma-disp-um", &p->sigma_disp_um},
        {"--sigma-angle-urad", &p->sigma_angle_urad},
        {"--ey-um", &p->ey_amp_um},
        {"--ep-urad", &p->ep_amp_urad},
        {"--u1-um", &p->u1_um},
        {"--u2-um", &p->u2_um},
        {"--u3-urad", &p->u3_urad},
        {"--b0-um", &p->b0_um},
        {"--probe-gain", &a->gain},
        {"--angle-scale", &a->angle},
        {"--drift-um", &a->drift_um},
    };
    for (size_t k = 0; k < sizeof reals / sizeof reals[0]; ++k)
        if (!strcmp(o, reals[k].name))
            return get_double(o, v, reals[k].dst);
    const struct {
        const char *name;
        int *dst;
    } ints[] = {{"--n", &p->n}, {"--N", &p->n}, {"--d1", &p->d1}, {"--d2", &p->d2}};
    long l;
    for (size_t k = 0; k < sizeof ints / sizeof ints[0]; ++k)
        if (!strcmp(o, ints[k].name)) {
            int bad = get_int(o, v, k < 2 ? 3 : 1, 100000000, &l);
            if (!bad)
                *ints[k].dst = (int)l;
            return bad;
        }
    if (!strcmp(o, "--harmonics"))
        return get_int(o, v, 1, 100000, &a->harmonics);
    if (!strcmp(o, "--seed")) {
        uint64_t s;
        if (cli_parse_seed("simulate profile", v, &s) != CLI_OK)
            return CLI_BAD_INPUT;
        p->seed = s;
        return CLI_OK;
    }
    return NOT_NUMERIC;
}

/* One option (with its value from argv[*i + 1]). */
static int parse_option(int argc, char **argv, int *i, sc_profile_sim *p, sim_profile_args *a)
{
    const char *o = argv[*i];
    const int hv = *i + 1 < argc;
    if ((!strcmp(o, "--out") || !strcmp(o, "-o")) && hv)
        a->out = argv[++*i];
    else if (!strcmp(o, "--truth") && hv)
        a->truth = argv[++*i];
    else if (!strcmp(o, "--profile") && hv)
        a->prof = argv[++*i];
    else if (!strcmp(o, "--noise-free"))
        p->sigma_disp_um = p->sigma_angle_urad = 0;
    else if (!strcmp(o, "--no-sigma-lines"))
        p->write_sigma = 0;
    else if (!strcmp(o, "--gap") && hv) {
        const char *v = argv[++*i];
        int used = 0;
        if (sscanf(v, "%ld:%ld..%ld%n", &a->gap[0], &a->gap[1], &a->gap[2], &used) != 3 ||
            v[used] || (a->gap[0] != 1 && a->gap[0] != 2) || a->gap[1] < 0 || a->gap[2] < a->gap[1])
            return cli_usage_error("simulate profile", "--gap: '%s' is not K:A..B (K 1 or 2, "
                                   "0 <= A <= B)", v);
    } else if (!strcmp(o, "--outlier") && hv) {
        const char *v = argv[++*i];
        int used = 0;
        if (sscanf(v, "%ld:%ld:%lf%n", &a->outlier[0], &a->outlier[1], &a->outlier_um, &used) != 3 ||
            v[used] || (a->outlier[0] != 1 && a->outlier[0] != 2) || a->outlier[1] < 0 ||
            !isfinite(a->outlier_um))
            return cli_usage_error("simulate profile", "--outlier: '%s' is not K:N:UM", v);
    }
    else {
        int rc = hv ? parse_number_option(o, argv[*i + 1], p, a) : NOT_NUMERIC;
        if (rc == NOT_NUMERIC)
            return cli_usage_error("simulate profile",
                                   "unknown option or missing value: %s (see --help)", o);
        ++*i;
        return rc ? CLI_BAD_INPUT : CLI_OK;
    }
    return CLI_OK;
}

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
    sc_profile_sim p;
    sc_profile_sim_defaults(&p);
    sim_profile_args a = {NULL, NULL, "random", 1.0, 40, 1.0, 1.0, 0.0, 0.0, {0, 0, 0}, {0, 0}};
    for (int i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        int rc = parse_option(argc, argv, &i, &p, &a);
        if (rc != CLI_OK)
            return rc;
    }
    int rc = check_args(&p, &a);
    if (rc != CLI_OK)
        return rc;
    sc_error err;
    sc_error_clear(&err);
    return simulate_and_write(&p, &a, &err) == SC_OK ? CLI_OK : cli_report(&err);
}
