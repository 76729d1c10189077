/* selfcal simulate grid — simulated plate measurements (Petrò 2019 §5) and their truth. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_io.h"
#include "selfcal/correct.h"
#include "selfcal/grid_sim.h"
#include "selfcal/lut.h"

static const char USAGE[] =
    "usage: selfcal simulate grid --plan {ye,double-shift,stitch,PLAN.csv} --out IN.csv --truth-map G_true.csv\n"
    "                             [--n 25] [--pitch-mm 1] [--origin-mm X,Y]\n"
    "                             [--sigma-g-um 1] [--sigma-a-um 1] [--sigma-r-um 0.01]\n"
    "                             [--O-urad 10] [--R-ppm 10] [--rho 0.9]\n"
    "                             [--sigma-t-um 0.1] [--sigma-theta-urad 100] [--seed 1]\n"
    "                             [--truth-artifact A_true.csv] [--truth-summary T.json]\n"
    "                             [--compensate-with T.lut]\n"
    "                             [--stage NX,NY] [--view-sigma-r-um S0,S1,...]\n"
    "                             [--dt-s DT] [--drift-um-s VX,VY]\n"
    "                             [--plate-scale-ppm E[,U]] [--plate-cte-ppm-per-k A[,U]]\n"
    "                             [--view-temp-c T0,T1,...] [--temp-u-k U]\n"
    "                             [--magnification-ppm M]\n"
    "\n"
    "Simulates a stage error G (first-order O, R plus a SAR(1) field with row-standardised\n"
    "4-neighbour weights, scaled so that the std of all Gx, Gy values is sigma-g-um), a Gaussian\n"
    "plate error A (sigma-a-um), a random misalignment per view (sigma-t-um, sigma-theta-urad) and\n"
    "measurement noise (sigma-r-um), and writes the selfcal-grid v1 input file (--out) and the truth\n"
    "in the SPEC gauge: G (--truth-map, map format, no uncertainties), A (--truth-artifact) and a\n"
    "JSON summary (--truth-summary: O_urad, R_ppm, misalignments, sigmas, seed).\n"
    "--O-urad, --R-ppm: the first-order terms in urad and ppm (--O, --R: the same dimensionless,\n"
    "1e-5 = 10 urad; kept through version 0.3).\n"
    "--plan ye: {rot 0}, {rot 90}, {shift +1,0}; double-shift: {rot 0}, {rot 90}, {shift +2,0},\n"
    "{shift -3,0 rows=c cols=c,c+1} (N >= 7); a file: its header gives N, pitch, origin and views\n"
    "(then --n, --pitch-mm and --origin-mm must agree with it or be left out).\n"
    "--stage NX,NY: a stage grid larger than the plate (both odd); with --plan stitch the plate is\n"
    "placed at rot 0 on a raster covering the stage (steps of about N/2 pitches), plus a rot 90\n"
    "and a shift +1,0 placement at the centre (the plan 'selfcal plan --design' proposes).\n"
    "--view-sigma-r-um: each view its own noise (written as sigma_um= on the view lines).\n"
    "--dt-s: each measurement gets a time (column t_s, serpentine order, views in sequence);\n"
    "--drift-um-s adds a translation drift (vx, vy)·(t - start of its view).\n"
    "Same seed and options: the same files. G and A depend only on N, the sigmas and the seed,\n"
    "not on the views: a one-view plan with the calibration's seed re-measures the same stage\n"
    "and plate. --compensate-with: the machine measures with this table active (each reading\n"
    "p becomes p - G_table(p), the table's measure-mode correction, as selfcald computes it):\n"
    "a re-measurement after compensation for 'selfcal verify'.\n"
    "Scale and temperature (SPEC 11): --plate-scale-ppm E,U writes '# plate_scale_ppm = E, U'\n"
    "(U default 0): the plate's true pitch is P(1 + E 1e-6), its simulated error A is taken to\n"
    "have no magnification, and the truth G includes the stage's magnification\n"
    "--magnification-ppm M (M 1e-3 (x, y) um at the node). --plate-cte-ppm-per-k A,U and\n"
    "--view-temp-c (one temperature per view, written as temp_C= on the view lines): the plate\n"
    "of view v is scaled by E + A (T_v - 20) ppm. --temp-u-k: the temperatures' standard\n"
    "uncertainty written as '# temp_u_K' (default 0.05). Without --plate-scale-ppm the truth G\n"
    "stays in the SPEC gauge (no magnification).\n";

static int parse_num(const char *opt, const char *s, double *out)
{
    if (sc_parse_double(s, out) != 0)
        return cli_usage_error("simulate grid", "%s needs a finite number, got '%s'", opt, s);
    return 0;
}

static void fprint_truth_summary(FILE *fp, const char *plan_name, const sc_grid_plan *p,
                                 const sc_grid_sim_params *sp, const sc_grid_sim_truth *t,
                                 double magnification_ppm)
{
    fprintf(fp, "{\n  \"format\": \"selfcal-grid-truth v1\",\n  \"plan\": \"");
    for (const char *c = plan_name; *c; ++c)
        fprintf(fp, (*c == '"' || *c == '\\') ? "\\%c" : "%c", *c);
    fprintf(fp, "\",\n  \"N\": %d,\n  \"pitch_mm\": %.15g,\n  \"origin_mm\": [%.15g, %.15g],\n",
            p->n, p->pitch_mm, p->origin_mm[0], p->origin_mm[1]);
    fprintf(fp, "  \"stage\": [%d, %d],\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    fprintf(fp, "  \"O\": %.15g,\n  \"R\": %.15g,\n", t->O, t->R);
    fprintf(fp, "  \"O_urad\": %.15g,\n  \"R_ppm\": %.15g,\n", t->O * 1e6, t->R * 1e6);
    fprintf(fp, "  \"dt_s\": %.15g,\n  \"drift_um_s\": [%.15g, %.15g],\n", sp->dt_s,
            sp->drift_vx_um_s, sp->drift_vy_um_s);
    fprintf(fp, "  \"sigma_g_um\": %.15g,\n  \"rho\": %.15g,\n  \"sar_weights\": \"row-standardised 4-neighbour\",\n",
            sp->sigma_g_um, sp->rho);
    fprintf(fp, "  \"sigma_a_um\": %.15g,\n  \"sigma_t_um\": %.15g,\n  \"sigma_theta_urad\": %.15g,\n",
            sp->sigma_a_um, sp->sigma_t_um, sp->sigma_theta_urad);
    fprintf(fp, "  \"sigma_r_um\": %.15g,\n  \"seed\": %llu,\n", sp->sigma_r_um,
            (unsigned long long)sp->seed);
    if (p->scale.has_plate_scale)
        fprintf(fp, "  \"magnification_ppm\": %.15g,\n", magnification_ppm);
    fprintf(fp, "  \"views\": [\n");
    for (int v = 0; v < p->n_views; ++v)
        fprintf(fp,
                "    {\"view\": %d, \"rot\": %d, \"shift\": [%d, %d], \"tx_um\": %.15g, \"ty_um\": "
                "%.15g, \"theta_urad\": %.15g}%s\n",
                v, p->view[v].rot_deg, p->view[v].shift_x, p->view[v].shift_y, t->tx_um[v],
                t->ty_um[v], t->theta_urad[v], v + 1 < p->n_views ? "," : "");
    fprintf(fp, "  ]\n}\n");
}

/* The readings of a machine with the table active: p -> p - G_table(p) (measure mode). */
static sc_status compensate(sc_grid_data *d, const char *table, sc_error *err)
{
    sc_corr_table *t = malloc(sizeof *t);
    if (!t)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    sc_status st = sc_lut_load_corr_file(table, t, err);
    const sc_grid_plan *p = &d->plan;
    int n = p->n;
    for (int v = 0; st == SC_OK && v < p->n_views; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                int k = i * n + j, ni, nj;
                if (!isfinite(d->dx_um[v][k]) || !sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    continue;
                double x, y;
                sc_grid_node_xy_mm(p, ni, nj, &x, &y);
                x += p->origin_mm[0];
                y += p->origin_mm[1];
                double in[3] = {x + d->dx_um[v][k] * 1e-3, y + d->dy_um[v][k] * 1e-3, 0}, out[3];
                sc_corr_apply(t, SC_CORR_MEASURE, in, out);
                d->dx_um[v][k] = (out[0] - x) * 1e3;
                d->dy_um[v][k] = (out[1] - y) * 1e3;
            }
    free(t);
    return st;
}

/* The command line, as given. */
typedef struct {
    const char *plan_arg, *out, *truth_map, *truth_art, *truth_sum, *comp_table;
    double n_d, pitch, ox, oy;
    int n_given, pitch_given, origin_given, n_vs;
    long stage_x, stage_y;
    double *view_sigma;     /* n_vs values (--view-sigma-r-um), freed by cmd_simulate_grid */
    sc_grid_sim_params sp;
    sc_grid_scale scale;       /* --plate-scale-ppm, --plate-cte-ppm-per-k, --temp-u-k */
    int n_temps, temp_u_given;
    double *temps;             /* n_temps values (--view-temp-c), freed by cmd_simulate_grid */
    double magnification_ppm;
} sim_args;

/* "A,B" into its two halves (in buf); NULL when there is no comma. */
static const char *split_pair(const char *v, char *buf, size_t cap)
{
    snprintf(buf, cap, "%s", v);
    char *comma = strchr(buf, ',');
    if (!comma)
        return NULL;
    *comma = '\0';
    return comma + 1;
}

static int parse_origin(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_args *a = field;
    (void)cmd, (void)opt;
    char buf[128];
    const char *second = split_pair(v, buf, sizeof buf);
    if (!second || sc_parse_double(buf, &a->ox) || sc_parse_double(second, &a->oy))
        return cli_usage_error("simulate grid", "--origin-mm needs X,Y, got '%s'", v);
    a->origin_given = 1;
    return CLI_OK;
}

static int parse_stage(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_args *a = field;
    (void)cmd, (void)opt;
    char buf[64];
    const char *second = split_pair(v, buf, sizeof buf);
    if (!second || sc_parse_long(buf, &a->stage_x) || sc_parse_long(second, &a->stage_y) ||
        a->stage_x < 3 || a->stage_y < 3 || a->stage_x % 2 == 0 || a->stage_y % 2 == 0 ||
        a->stage_x > SC_GRID_MAX_STAGE || a->stage_y > SC_GRID_MAX_STAGE)
        return cli_usage_error("simulate grid", "--stage needs NX,NY, both odd and >= 3, got '%s'", v);
    return CLI_OK;
}

/* A comma list of numbers into a fresh array *out, *n of them, each accepted by ok: 0; 1 at a
 * bad item; -1 without memory. */
static int parse_number_list(const char *v, int (*ok)(double), double **out, int *n)
{
    size_t len = strlen(v), cap = 1;
    for (const char *c = v; *c; ++c)
        cap += *c == ',';
    char *buf = malloc(len + 1);
    free(*out);
    *out = malloc(cap * sizeof **out);
    *n = 0;
    if (!buf || !*out) {
        free(buf);
        return -1;
    }
    memcpy(buf, v, len + 1);
    int rc = 0;
    for (char *t = strtok(buf, ","); t && rc == 0; t = strtok(NULL, ",")) {
        double x;
        if ((size_t)*n == cap || sc_parse_double(t, &x) || !ok(x))
            rc = 1;
        else
            (*out)[(*n)++] = x;
    }
    free(buf);
    return rc;
}

static int view_sigma_ok(double s_um)
{
    return s_um > 0 && s_um <= 1e6;
}

static int parse_view_sigmas(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_args *a = field;
    (void)cmd, (void)opt;
    const int rc = parse_number_list(v, view_sigma_ok, &a->view_sigma, &a->n_vs);
    if (rc < 0)
        return cli_usage_error("simulate grid", "--view-sigma-r-um: out of memory");
    if (rc > 0)
        return cli_usage_error("simulate grid", "--view-sigma-r-um needs positive numbers, got '%s'", v);
    return CLI_OK;
}

static int parse_drift(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_args *a = field;
    (void)cmd, (void)opt;
    char buf[128];
    const char *second = split_pair(v, buf, sizeof buf);
    if (!second || sc_parse_double(buf, &a->sp.drift_vx_um_s) ||
        sc_parse_double(second, &a->sp.drift_vy_um_s))
        return cli_usage_error("simulate grid", "--drift-um-s needs VX,VY, got '%s'", v);
    return CLI_OK;
}

/* "V" or "V,U" with U >= 0 (U 0 when left out). */
static int parse_value_u(const char *opt, const char *v, double lim, double *val, double *u)
{
    char buf[128];
    const char *second = split_pair(v, buf, sizeof buf);
    *u = 0;
    if (sc_parse_double(buf, val) || !(fabs(*val) <= lim) ||
        (second && (sc_parse_double(second, u) || !(*u >= 0) || !(*u <= lim))))
        return cli_usage_error("simulate grid", "%s needs V or V,U (|V| and U <= %g, U >= 0), "
                                                "got '%s'", opt, lim, v);
    return CLI_OK;
}

static int temp_ok(double t_C)
{
    return t_C >= SC_GRID_MIN_TEMP_C && t_C <= SC_GRID_MAX_TEMP_C;
}

static int parse_temps(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_args *a = field;
    (void)cmd, (void)opt;
    const int rc = parse_number_list(v, temp_ok, &a->temps, &a->n_temps);
    if (rc < 0)
        return cli_usage_error("simulate grid", "--view-temp-c: out of memory");
    if (rc > 0)
        return cli_usage_error("simulate grid", "--view-temp-c needs temperatures of %g to %g "
                                                "C, got '%s'", SC_GRID_MIN_TEMP_C,
                               SC_GRID_MAX_TEMP_C, v);
    return CLI_OK;
}

/* --plate-scale-ppm E[,U], --plate-cte-ppm-per-k A[,U] into the sc_grid_scale */
static int parse_scale(const char *cmd, const char *o, const char *v, void *field)
{
    sc_grid_scale *sc = field;
    (void)cmd;
    if (!strcmp(o, "--plate-scale-ppm")) {
        sc->has_plate_scale = 1;
        return parse_value_u(o, v, SC_GRID_MAX_SCALE_PPM, &sc->plate_scale_ppm,
                             &sc->u_plate_scale_ppm);
    }
    sc->has_cte = 1;
    return parse_value_u(o, v, SC_GRID_MAX_CTE, &sc->cte_ppm_per_K, &sc->u_cte_ppm_per_K);
}

/* --temp-u-k U into the sim_args */
static int parse_temp_u(const char *cmd, const char *opt, const char *v, void *field)
{
    sim_args *a = field;
    sc_grid_scale *sc = &a->scale;
    (void)opt;
    a->temp_u_given = 1;
    if (sc_parse_double(v, &sc->temp_u_K) || !(sc->temp_u_K >= 0) ||
        !(sc->temp_u_K <= SC_GRID_MAX_TEMP_U_K))
        return cli_usage_error(cmd, "--temp-u-k needs 0 to %g K, got '%s'", SC_GRID_MAX_TEMP_U_K, v);
    return CLI_OK;
}

/* --magnification-ppm M into the double */
static int parse_magnification(const char *cmd, const char *opt, const char *v, void *field)
{
    double *m = field;
    (void)opt;
    if (sc_parse_double(v, m) || !(fabs(*m) <= SC_GRID_MAX_SCALE_PPM))
        return cli_usage_error(cmd, "--magnification-ppm needs a number of ppm (|M| <= %g), got '%s'",
                               SC_GRID_MAX_SCALE_PPM, v);
    return CLI_OK;
}

/* --n, --pitch-mm (given), --O-urad, --R-ppm (scaled), --dt-s (positive) into the sim_args; with
 * another option (the table's other), a value that is no number is named first */
static int sim_number(const char *cmd, const char *o, const char *v, void *field)
{
    sim_args *a = field;
    double x;
    if (parse_num(o, v, &x))
        return CLI_BAD_INPUT;
    sc_grid_sim_params *sp = &a->sp;
    if (!strcmp(o, "--n")) a->n_d = x, a->n_given = 1;
    else if (!strcmp(o, "--pitch-mm")) a->pitch = x, a->pitch_given = 1;
    else if (!strcmp(o, "--O-urad")) sp->O = x * 1e-6;
    else if (!strcmp(o, "--R-ppm")) sp->R = x * 1e-6;
    else if (!strcmp(o, "--dt-s")) {
        if (!(x > 0) || x > 1e6)
            return cli_usage_error(cmd, "--dt-s needs a positive number");
        sp->dt_s = x;
    } else
        return cli_usage_error(cmd, "unknown option '%s' (see --help)", o);
    return CLI_OK;
}

#define F(field) offsetof(sim_args, field)
#define NUM(name, f, v, dflt, text)                                                                \
    {name, CLI_DOUBLE, F(f), v, -HUGE_VAL, HUGE_VAL, .bad = "%s needs a finite number, got '%s'",  \
     .def = dflt, .help = text}
#define WHOLE(name, v, fn, dflt, text) /* a parse function of the whole sim_args */                \
    {name, CLI_CUSTOM, 0, v, .parse = fn, .def = dflt, .help = text}
/* simulate grid's options (cli_opts.h), in the order of its --help */
static const cli_opt SIM_GRID_OPTS[] = {
    {"--plan", CLI_STRING, F(plan_arg), "ye|double-shift|stitch|PLAN.csv",
     .help = "the views (required)"},
    {"--out", CLI_STRING, F(out), "IN.csv", .help = "the measurement file (required)"},
    {"--truth-map", CLI_STRING, F(truth_map), "G_true.csv", .help = "the true G (required)"},
    WHOLE("--n", "N", sim_number, "25", "the plate's marks per side (odd)"),
    WHOLE("--pitch-mm", "P", sim_number, "1", "the pitch (mm)"),
    WHOLE("--origin-mm", "X,Y", parse_origin, "0,0", "the stage node (0,0)'s position (mm)"),
    NUM("--sigma-g-um", sp.sigma_g_um, "X", "1", "the std of G (um)"),
    NUM("--sigma-a-um", sp.sigma_a_um, "X", "1", "the std of the plate error A (um)"),
    NUM("--sigma-r-um", sp.sigma_r_um, "X", "0.01", "the measurement noise (um)"),
    WHOLE("--O-urad", "O", sim_number, "10", "the non-orthogonality (urad)"),
    WHOLE("--R-ppm", "R", sim_number, "10", "the scale difference (ppm)"),
    NUM("--rho", sp.rho, "RHO", "0.9", "the SAR(1) field's correlation"),
    NUM("--sigma-t-um", sp.sigma_t_um, "X", "0.1", "the views' misplacement (um)"),
    NUM("--sigma-theta-urad", sp.sigma_theta_urad, "X", "100", "the views' misrotation (urad)"),
    {"--seed", CLI_CUSTOM, F(sp.seed), "S", .parse = cli_opt_seed, .def = "1",
     .help = "the seed, 0 to 2^64-1"},
    {"--truth-artifact", CLI_STRING, F(truth_art), "A_true.csv", .help = "the true plate error"},
    {"--truth-summary", CLI_STRING, F(truth_sum), "T.json", .help = "the truth's summary"},
    {"--compensate-with", CLI_STRING, F(comp_table), "T.lut",
     .help = "the machine measures with this table active"},
    WHOLE("--stage", "NX,NY", parse_stage, "the plate's", "the stage's nodes (odd)"),
    WHOLE("--view-sigma-r-um", "S0,S1,...", parse_view_sigmas, NULL, "each view's noise (um)"),
    WHOLE("--dt-s", "DT", sim_number, NULL, "each measurement's time step (s)"),
    WHOLE("--drift-um-s", "VX,VY", parse_drift, "0,0", "a translation drift (um/s)"),
    {"--plate-scale-ppm", CLI_CUSTOM, F(scale), "E[,U]", .parse = parse_scale,
     .help = "the plate's certified scale error (ppm) and its uncertainty"},
    {"--plate-cte-ppm-per-k", CLI_CUSTOM, F(scale), "A[,U]", .parse = parse_scale,
     .help = "the plate's expansion coefficient and its uncertainty"},
    WHOLE("--view-temp-c", "T0,T1,...", parse_temps, NULL, "each view's plate temperature (C)"),
    WHOLE("--temp-u-k", "U", parse_temp_u, "0.05", "the temperatures' uncertainty (K)"),
    {"--magnification-ppm", CLI_CUSTOM, F(magnification_ppm), "M", .parse = parse_magnification,
     .def = "0", .help = "the stage's magnification (ppm)"},
    NUM("--O", sp.O, "O", NULL, "the non-orthogonality, dimensionless (kept through 0.3)"),
    NUM("--R", sp.R, "R", NULL, "the scale difference, dimensionless (kept through 0.3)"),
};
#undef NUM
#undef WHOLE
#undef F

const cli_cmd_opts cli_simulate_grid_opts = {
    "simulate grid", USAGE, SIM_GRID_OPTS, (int)(sizeof SIM_GRID_OPTS / sizeof SIM_GRID_OPTS[0]),
    0, NULL, NULL, "unknown option or missing value: '%s' (see --help)", NULL, CLI_NO_OPERAND,
    NULL, sim_number,
};

/* argv into a, with the required options and ranges checked: -1 to go on, else the exit
 * status (--help, a usage error). */
static int parse_args(int argc, char **argv, sim_args *a)
{
    memset(a, 0, sizeof *a);
    a->n_d = 25;
    a->pitch = 1;
    sc_grid_sim_defaults(&a->sp);
    int rc = cli_opts_parse(&cli_simulate_grid_opts, argc, argv, a);
    if (rc >= 0)
        return rc;
    if (!a->plan_arg || !a->out || !a->truth_map)
        return cli_usage_error("simulate grid", "--plan, --out and --truth-map are required (see --help)");
    if (a->n_d != floor(a->n_d) || a->n_d < 3 || a->n_d > SC_GRID_MAX_N || fmod(a->n_d, 2) == 0)
        return cli_usage_error("simulate grid", "--n must be odd and in 3..%d", SC_GRID_MAX_N);
    if (!(a->pitch > 0))
        return cli_usage_error("simulate grid", "--pitch-mm must be positive");
    if ((a->sp.drift_vx_um_s != 0 || a->sp.drift_vy_um_s != 0) && !(a->sp.dt_s > 0))
        return cli_usage_error("simulate grid", "--drift-um-s needs --dt-s");
    if (!strcmp(a->plan_arg, "stitch") && !a->stage_x)
        return cli_usage_error("simulate grid", "--plan stitch needs --stage NX,NY");
    if (a->n_temps && !a->scale.has_cte)
        return cli_usage_error("simulate grid", "--view-temp-c needs --plate-cte-ppm-per-k");
    if (a->temp_u_given && !a->n_temps)
        return cli_usage_error("simulate grid", "--temp-u-k needs --view-temp-c");
    return -1;
}

/* The scale and temperature options into the plan (a plan file's own lines stay unless an
 * option replaces them). */
static sc_status apply_scale(const sim_args *a, sc_grid_plan *plan, int *usage_rc)
{
    sc_grid_scale *sc = &plan->scale;
    if (a->scale.has_plate_scale) {
        sc->has_plate_scale = 1;
        sc->plate_scale_ppm = a->scale.plate_scale_ppm;
        sc->u_plate_scale_ppm = a->scale.u_plate_scale_ppm;
    }
    if (a->scale.has_cte) {
        sc->has_cte = 1;
        sc->cte_ppm_per_K = a->scale.cte_ppm_per_K;
        sc->u_cte_ppm_per_K = a->scale.u_cte_ppm_per_K;
    }
    if (!sc->has_temps)
        sc->temp_u_K = SC_GRID_TEMP_U_K_DEFAULT;
    if (a->temp_u_given)
        sc->temp_u_K = a->scale.temp_u_K;
    if (a->n_temps) {
        if (a->n_temps != plan->n_views) {
            *usage_rc = cli_usage_error("simulate grid", "--view-temp-c gives %d values for %d "
                                                         "views", a->n_temps, plan->n_views);
            return SC_E_INPUT;
        }
        sc->has_temps = 1;
        for (int v = 0; v < plan->n_views; ++v)
            plan->view[v].temp_C = a->temps[v];
    }
    return SC_OK;
}

/* The plan: a named one (stitch, ye, double-shift) or a file's header; then --stage and
 * --view-sigma-r-um. *usage_rc is set (and an error returned) for a usage problem. */
static sc_status build_plan(const sim_args *a, sc_grid_plan *plan, int *usage_rc, sc_error *err)
{
    const int n = (int)a->n_d;
    sc_status st;
    *usage_rc = CLI_OK;
    if (!strcmp(a->plan_arg, "stitch")) {
        st = sc_grid_plan_stitch(n, (int)a->stage_x, (int)a->stage_y, a->pitch, a->ox, a->oy, plan,
                                 err);
    } else if (!strcmp(a->plan_arg, "ye")) {
        st = sc_grid_plan_ye(n, a->pitch, a->ox, a->oy, plan, err);
    } else if (!strcmp(a->plan_arg, "double-shift")) {
        st = sc_grid_plan_double_shift(n, a->pitch, a->ox, a->oy, plan, err);
    } else {
        sc_grid_data pf;
        sc_grid_file_info info;
        st = sc_grid_read(a->plan_arg, &pf, &info, err);
        if (st != SC_OK)
            return st;
        st = sc_grid_plan_copy(plan, &pf.plan, err);
        sc_grid_data_free(&pf);
        sc_grid_file_info_free(&info);
        if (st != SC_OK)
            return st;
        if ((a->n_given && n != plan->n) || (a->pitch_given && a->pitch != plan->pitch_mm) ||
            (a->origin_given && (a->ox != plan->origin_mm[0] || a->oy != plan->origin_mm[1]))) {
            *usage_rc = cli_usage_error("simulate grid",
                                        "--n/--pitch-mm/--origin-mm disagree with the header of %s",
                                        a->plan_arg);
            return SC_E_INPUT;
        }
    }
    if (st == SC_OK && a->stage_x && strcmp(a->plan_arg, "stitch") != 0) {
        plan->stage_nx = (int)a->stage_x;
        plan->stage_ny = (int)a->stage_y;
        st = sc_grid_plan_check(plan, err);
    }
    if (st == SC_OK && a->n_vs) {
        if (a->n_vs != plan->n_views) {
            *usage_rc = cli_usage_error("simulate grid",
                                        "--view-sigma-r-um gives %d values for %d views", a->n_vs,
                                        plan->n_views);
            return SC_E_INPUT;
        }
        for (int v = 0; v < a->n_vs; ++v)
            plan->view[v].sigma_um = a->view_sigma[v];
    }
    return st == SC_OK ? apply_scale(a, plan, usage_rc) : st;
}

/* Every file written, then committed together: all or none. */
static sc_status write_outputs(const sim_args *a, const sc_grid_data *d,
                               const sc_grid_sim_truth *t, sc_error *err)
{
    sc_afile f[4];
    memset(f, 0, sizeof f); /* entries not opened stay closed (fp == NULL) */
    const char *paths[4] = {a->out, a->truth_map, a->truth_art, a->truth_sum};
    sc_status st = SC_OK;
    int opened = 0;
    for (; opened < 4; ++opened) {
        if (!paths[opened])
            continue;
        st = sc_afile_open(&f[opened], paths[opened], err);
        if (st != SC_OK)
            break;
        switch (opened) {
        case 0: sc_grid_fprint_input(f[0].fp, d); break;
        case 1: sc_grid_fprint_map(f[1].fp, &d->plan, t->gx_um, t->gy_um, NULL, NULL); break;
        case 2: sc_grid_fprint_artifact(f[2].fp, &d->plan, t->ax_um, t->ay_um); break;
        case 3: fprint_truth_summary(f[3].fp, a->plan_arg, &d->plan, &a->sp, t, a->magnification_ppm); break;
        }
    }
    /* all files or none: sync every one, then rename them together */
    return sc_afile_finish_all(f, opened, st, err);
}

static int simulate_grid(sim_args *a);

int cmd_simulate_grid(int argc, char **argv)
{
    sim_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc < 0)
        rc = simulate_grid(&a);
    free(a.view_sigma);
    free(a.temps);
    return rc;
}

static int simulate_grid(sim_args *ap)
{
    const sim_args a = *ap;
    int rc = CLI_OK;
    sc_error err;
    sc_error_clear(&err);
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    sc_status st = build_plan(&a, &d.plan, &rc, &err);
    if (rc != CLI_OK || st != SC_OK) {
        sc_grid_plan_free(&d.plan);
        return rc != CLI_OK ? rc : cli_report(&err);
    }
    size_t nn = (size_t)d.plan.n * d.plan.n, ns = (size_t)sc_grid_stage_nodes(&d.plan);
    size_t nv = (size_t)d.plan.n_views;
    sc_grid_sim_truth t;
    memset(&t, 0, sizeof t);
    /* truth G, A and misalignments, then the simulator's workspace */
    double *buf = malloc((4 * ns + 2 * nn + 3 * nv + sc_grid_sim_work_doubles_plan(&d.plan)) *
                         sizeof(double));
    if (!buf) {
        sc_grid_plan_free(&d.plan);
        sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
        return cli_report(&err);
    }
    t.gx_um = buf;
    t.gy_um = buf + ns;
    t.ax_um = buf + 2 * ns;
    t.ay_um = buf + 2 * ns + nn;
    t.tx_um = buf + 2 * ns + 2 * nn;
    t.ty_um = t.tx_um + nv;
    t.theta_urad = t.ty_um + nv;
    st = sc_grid_data_alloc(&d, &err);
    if (st == SC_OK)
        st = sc_grid_data_alloc_extra(&d, 0, a.sp.dt_s > 0, &err);
    if (st == SC_OK)
        st = sc_grid_sim_run(&d.plan, &a.sp, &t, &d, buf + 2 * ns + 2 * nn + 3 * nv, &err);
    if (st == SC_OK)
        sc_grid_sim_scale(&d.plan, a.magnification_ppm, &t, &d);
    if (st == SC_OK && a.comp_table)
        st = compensate(&d, a.comp_table, &err);
    /* Everything is computed: write all files, commit them together. */
    if (st == SC_OK)
        st = write_outputs(&a, &d, &t, &err);
    free(buf);
    sc_grid_data_free(&d);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}
