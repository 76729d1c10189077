/* cmd_lut.c — `selfcal lut build|dump|info`: build the binary lookup table from the SPEC map and
 * profile files, print it back as CSV (SPEC §3), show its provenance. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "cli_opts.h"
#include "input_once.h"
#include "selfcal/correct.h"
#include "selfcal/csv.h"
#include "selfcal/lut.h"
#include "selfcal/sha256.h"

#define LUT_STR_(x) #x
#define LUT_STR(x) LUT_STR_(x)
static const char USAGE[] =
    "usage: selfcal lut build --map G.csv [--profile AXIS:DIR:P.csv[@OFFSET_MM] ...] -o TABLE\n"
    "                         [--method NAME] [--sigma UM] [--encoding auto|int16|int32]\n"
    "                         [--created UNIX_SECONDS] [--max-nodes N]\n"
    "       selfcal lut dump TABLE     print the table as CSV (grid, then profiles)\n"
    "       selfcal lut info TABLE     print size, encoding, quantization, bounds, |G| and\n"
    "                                  slope, and provenance\n"
    "\n"
    "A profile (--profile, up to " LUT_STR(SC_LUT_MAX_PROFILES) ") is the ey_um column of a profile output file as the\n"
    "error of coordinate DIR (x|y|z) along AXIS (x|y|z); its x_mm is placed at machine position\n"
    "x_mm + OFFSET_MM along AXIS (default offset 0); a profile that does not overlap the map gets\n"
    "a warning on stderr. A map with more than N nodes along an axis (--max-nodes; a table holds\n"
    "101) gets N table nodes there spanning it, fitted by least squares; the fit's error at the\n"
    "map's nodes is printed. --method, --sigma and --created are provenance only.\n";

typedef struct profile_arg {
    int axis, dir;
    char path[4096];
    double offset_mm; /* machine position of the profile's x_mm = 0 along axis */
} profile_arg;

static int parse_profile_arg(const char *s, profile_arg *pa)
{
    return cli_parse_profile_placed(s, &pa->axis, &pa->dir, pa->path, sizeof pa->path,
                                    &pa->offset_mm);
}

/* Warn (stderr; the build still succeeds) when profile k lies beside the map along its axis. */
static void warn_if_apart(const sc_lut *lut, const sc_lut_profile *p, const char *path)
{
    double lo, hi;
    if (p->axis == SC_CORR_AXIS_X) {
        lo = lut->x0_mm;
        hi = lut->x0_mm + (lut->nx - 1) * lut->px_mm;
    } else if (p->axis == SC_CORR_AXIS_Y) {
        lo = lut->y0_mm;
        hi = lut->y0_mm + (lut->ny - 1) * lut->py_mm;
    } else {
        return; /* the map has no extent along z */
    }
    double a = p->start_mm, b = p->start_mm + (p->n - 1) * p->step_mm;
    if (b < lo || a > hi)
        fprintf(stderr,
                "selfcal lut build: warning: profile %s covers %s = %g..%g mm, the map %g..%g mm: "
                "they do not overlap (place it with --profile %s:%s:%s@OFFSET_MM)\n",
                path, sc_lut_axis_name(p->axis), a, b, lo, hi, sc_lut_axis_name(p->axis),
                sc_lut_axis_name(p->dir), path);
}

/* lut build's command line, as given. */
typedef struct {
    const char *map, *out, *method;
    double sigma;
    long long created;
    int max_nodes; /* 0: the map as it is */
    sc_lut_encoding enc;
    int enc_ix; /* --encoding: 0 auto, 1 int16, 2 int32 (sc_lut_encoding's values) */
    profile_arg pa[SC_LUT_MAX_PROFILES];
    int np;
} build_args;

/* --method NAME (at most SC_LUT_METHOD_LEN - 1 characters) into the const char * */
static int parse_method(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    if (strlen(v) >= SC_LUT_METHOD_LEN)
        return cli_usage_error(cmd, "--method: at most %d characters", SC_LUT_METHOD_LEN - 1);
    memcpy(field, &v, sizeof v);
    return CLI_OK;
}

/* --created UNIX_SECONDS into the long long */
static int parse_created(const char *cmd, const char *opt, const char *v, void *field)
{
    long c;
    (void)opt;
    if (sc_parse_long(v, &c) != 0 || c < 0)
        return cli_usage_error(cmd, "--created: Unix seconds, not '%s'", v);
    *(long long *)field = c;
    return CLI_OK;
}

/* --profile AXIS:DIR:P.csv[@OFFSET_MM], one more into the build_args */
static int parse_profile(const char *cmd, const char *opt, const char *v, void *field)
{
    build_args *b = field;
    (void)opt;
    if (b->np == SC_LUT_MAX_PROFILES)
        return cli_usage_error(cmd, "at most %d profiles", SC_LUT_MAX_PROFILES);
    if (parse_profile_arg(v, &b->pa[b->np]) != 0)
        return cli_usage_error(cmd, "--profile: AXIS:DIR:FILE[@OFFSET_MM] with AXIS, DIR in x, y, z and |OFFSET_MM| <= 1e6; not '%s'", v);
    if (b->pa[b->np].axis == b->pa[b->np].dir) /* allowed (SPEC §3), but rarely meant */
        fprintf(stderr, "selfcal lut build: warning: --profile %s: DIR = AXIS makes it an "
                        "error along its own axis (a scale error), not a straightness; the "
                        "controller exports refuse it\n", v);
    ++b->np;
    return CLI_OK;
}

/* a word that is no option */
static int options_only(const char *cmd, const char *opt, const char *v, void *args)
{
    (void)opt, (void)args;
    return cli_usage_error(cmd, "'%s': lut build takes options only (--map G.csv ... -o TABLE; see "
                                "--help)", v);
}

#define F(field) offsetof(build_args, field)
/* lut build's options (cli_opts.h), in the order of its --help */
static const cli_opt LUT_BUILD_OPTS[] = {
    {"--map", CLI_STRING, F(map), "G.csv", .help = "the stage error map (required)"},
    {"--profile", CLI_CUSTOM, 0, "AXIS:DIR:P.csv[@OFFSET_MM]", .parse = parse_profile,
     .help = "a profile's ey_um as the error of DIR along AXIS (repeatable, up to "
             LUT_STR(SC_LUT_MAX_PROFILES) ")"},
    {"-o|--out", CLI_STRING, F(out), "TABLE", .help = "the table (required)"},
    {"--method", CLI_CUSTOM, F(method), "NAME", .parse = parse_method,
     .help = "the method, as provenance (at most 31 characters)"},
    {"--sigma", CLI_DOUBLE, F(sigma), "UM", 0, HUGE_VAL,
     .bad = "--sigma: a non-negative number in um, not '%s'", .help = "the map's sigma, as provenance"},
    {"--encoding", CLI_CHOICE, F(enc_ix), "auto|int16|int32", .choices = "auto|int16|int32",
     .bad = "--encoding: auto, int16 or int32, not '%s'", .def = "auto",
     .help = "the grid's codes (auto: int16 if fine enough)"},
    {"--created", CLI_CUSTOM, F(created), "UNIX_SECONDS", .parse = parse_created,
     .def = "SOURCE_DATE_EPOCH, else now", .help = "the creation time recorded"},
    {"--max-nodes", CLI_CUSTOM, F(max_nodes), "N", 2, SC_LUT_MAX_NX, .parse = cli_opt_max_nodes,
     .def = "the map as it is", .help = "a larger map fitted by N nodes per axis"},
};
#undef F

const cli_cmd_opts cli_lut_build_opts = {
    "lut build", USAGE, LUT_BUILD_OPTS, (int)(sizeof LUT_BUILD_OPTS / sizeof LUT_BUILD_OPTS[0]), 0,
    options_only, NULL, NULL, NULL, CLI_DASH_OPTION, NULL, NULL,
};

/* The map and the profiles read, their hashes as provenance, the table written. */
static sc_status build_table(const build_args *b, sc_lut *lut, sc_lut_fit_report *fit,
                             sc_error *err)
{
    sc_lut_init(lut);
    /* each source read once (a pipe into memory, hashed on the way), then hashed as
     * provenance, as `sha256sum` prints it */
    static cli_input src[1 + SC_LUT_MAX_PROFILES];
    const char *paths[1 + SC_LUT_MAX_PROFILES] = {b->map};
    for (int k = 0; k < b->np; ++k)
        paths[k + 1] = b->pa[k].path;
    int opened;
    sc_status st = cli_input_open_all(src, paths, 1 + b->np, 0, &opened, err);
    if (st == SC_OK)
        st = cli_read_map(src[0].path, b->max_nodes, lut, fit, err);
    for (int k = 0; st == SC_OK && k < b->np; ++k) {
        const profile_arg *pa = &b->pa[k];
        st = sc_lut_read_profile(src[k + 1].path, pa->axis, pa->dir, &lut->profile[k], err);
        lut->profile[k].start_mm += pa->offset_mm;
        lut->n_profiles = k + 1;
    }
    long long size;
    for (int k = 0; st == SC_OK && k < 1 + b->np; ++k)
        st = cli_input_sha256(&src[k], lut->prov.sha256[k], &size, err);
    if (st != SC_OK)
        cli_input_rename_in_error(err);
    cli_input_close_all(src, opened);
    if (st != SC_OK)
        return st;
    lut->prov.n_sources = 1 + b->np;
    lut->prov.created_unix_s = b->created;
    lut->prov.sigma_um = b->sigma;
    if (b->method)
        snprintf(lut->prov.method, sizeof lut->prov.method, "%s", b->method);
    return sc_lut_write_file(b->out, lut, b->enc, err);
}

/* What the table commands: the figures selfcald's --max-correction-um and
 * --max-gradient-um-per-mm are compared with. */
static void print_bounds(const sc_lut *lut)
{
    double corr_um, grad;
    sc_lut_bounds(lut, &corr_um, &grad);
    printf("bounds: max correction %.6f um, max gradient %.6f um/mm\n", corr_um, grad);
}

static int lut_build(int argc, char **argv)
{
    static build_args b;
    memset(&b, 0, sizeof b);
    b.sigma = -1.0;
    b.created = -1;
    int rc = cli_opts_parse(&cli_lut_build_opts, argc, argv, &b);
    if (rc >= 0)
        return rc;
    b.enc = (sc_lut_encoding)b.enc_ix;
    if (!b.map || !b.out)
        return cli_usage_error("lut build", "--map and -o are required (see --help)");
    if (b.created < 0) {
        const char *sde = getenv("SOURCE_DATE_EPOCH");
        long c;
        b.created = (sde && sc_parse_long(sde, &c) == 0 && c >= 0) ? c : (long long)time(NULL);
    }
    sc_lut *lut = malloc(sizeof *lut);
    if (!lut) {
        fprintf(stderr, "selfcal lut build: out of memory\n");
        return CLI_FAIL;
    }
    sc_error err;
    sc_error_clear(&err);
    sc_lut_fit_report fit;
    sc_status st = build_table(&b, lut, &fit, &err);
    if (st != SC_OK) {
        free(lut);
        return cli_report(&err);
    }
    for (int k = 0; k < b.np; ++k)
        warn_if_apart(lut, &lut->profile[k], b.pa[k].path);
    if (fit.fitted)
        cli_print_fit(b.map, lut, &fit);
    size_t bytes = sc_lut_encoded_size(lut, b.enc); /* what was just written */
    printf("table %s: %d x %d nodes, pitch %.6f x %.6f mm, %d profile(s), %zu bytes, "
           "map quantization <= %.4f nm (%s)\n",
           b.out, lut->nx, lut->ny, lut->px_mm, lut->py_mm, lut->n_profiles, bytes,
           1e3 * sc_lut_quantization_um(lut->grid_scale_pm),
           lut->grid_encoding == SC_LUT_ENC_INT16 ? "int16" : "int32");
    print_bounds(lut);
    free(lut);
    return CLI_OK;
}

/* `lut dump --help`, `lut info --help`: their own usage, not lut build's */
static void lut_table_usage(const char *cmd, FILE *to)
{
    if (!strcmp(cmd, "lut dump"))
        fprintf(to, "usage: selfcal lut dump TABLE\n\n"
                    "Prints the table as CSV on stdout: the grid nodes, then the profiles.\n");
    else
        fprintf(to, "usage: selfcal lut info TABLE\n\n"
                    "Prints the table's size, encoding, quantization and provenance.\n");
}

static int load_table(const char *cmd, int argc, char **argv, sc_lut **out)
{
    for (int k = 1; k < argc; ++k) /* --help anywhere: the usage, as the other commands */
        if (!strcmp(argv[k], "--help") || !strcmp(argv[k], "-h")) {
            lut_table_usage(cmd, stdout);
            return -1;
        }
    if (argc != 2)
        return cli_usage_error(cmd, "expected one table file (see --help)");
    sc_lut *lut = malloc(sizeof *lut);
    if (!lut) {
        fprintf(stderr, "selfcal %s: out of memory\n", cmd);
        return CLI_FAIL;
    }
    sc_error err;
    sc_error_clear(&err);
    if (sc_lut_read_file(argv[1], lut, &err) != SC_OK) {
        free(lut);
        return cli_report(&err);
    }
    *out = lut;
    return CLI_OK;
}

/* v for printing with 6 decimals: values that would print as "-0.000000" print as 0. */
/* v for printing with 9 decimals, without a "-0.000000000" (1e-9 µm = 1 fm, well below the
 * table's finest quantization, 0.5 pm: the dump adds no rounding of its own). */
static double print9(double v)
{
    return (v < 5e-10 && v > -5e-10) ? 0.0 : v;
}

static int lut_dump(int argc, char **argv)
{
    sc_lut *lut = NULL;
    int rc = load_table("lut dump", argc, argv, &lut);
    if (rc != CLI_OK || !lut)
        return rc < 0 ? CLI_OK : rc;
    /* Values are whole picometres (code x integer pm scale): %.6f um prints them exactly. */
    printf("i,j,x_mm,y_mm,gx_um,gy_um\n");
    for (int i = 0; i < lut->ny; ++i)
        for (int j = 0; j < lut->nx; ++j) {
            size_t k = (size_t)i * lut->nx + j;
            printf("%d,%d,%.9f,%.9f,%.9f,%.9f\n", i, j, print9(lut->x0_mm + j * lut->px_mm),
                   print9(lut->y0_mm + i * lut->py_mm), print9(lut->gx_um[k]),
                   print9(lut->gy_um[k]));
        }
    for (int k = 0; k < lut->n_profiles; ++k) {
        const sc_lut_profile *p = &lut->profile[k];
        printf("# profile %d: axis=%s dir=%s\n", k, sc_lut_axis_name(p->axis),
               sc_lut_axis_name(p->dir));
        printf("n,pos_mm,err_um\n");
        for (int n = 0; n < p->n; ++n)
            printf("%d,%.9f,%.9f\n", n, print9(p->start_mm + n * p->step_mm), print9(p->err_um[n]));
    }
    free(lut);
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "selfcal lut dump: write error on standard output\n");
        return CLI_FAIL;
    }
    return CLI_OK;
}

static const char *enc_name(int enc)
{
    return enc == SC_LUT_ENC_INT16 ? "int16" : enc == SC_LUT_ENC_INT32 ? "int32" : "?";
}

/* The file size from the stored encodings (docs/lut-format.md, "Size"). */
static size_t stored_size(const sc_lut *lut)
{
    size_t cb = lut->grid_encoding == SC_LUT_ENC_INT16 ? 2 : 4;
    size_t size = 64 + 2 * (size_t)lut->nx * (size_t)lut->ny * cb;
    for (int k = 0; k < lut->n_profiles; ++k)
        size += 28 + (size_t)lut->profile[k].n * (lut->profile[k].encoding == SC_LUT_ENC_INT16 ? 2 : 4);
    return size + 56 + 32 * (size_t)lut->prov.n_sources + 4;
}

/* The bounds an integrator sizes margins from (docs/linuxcnc.md, "Margins"): the largest |G| at
 * the nodes (bilinear interpolation stays within them), and the largest slope of G, dimensionless
 * (um per um): the largest difference of a component between neighbouring nodes over their pitch
 * (a bilinear cell's partial derivatives are largest on its edges). Then the same bounds for the
 * whole correction C = G + profile offsets, per coordinate. */
typedef struct corr_bounds {
    double gmax_um, cmax_um[3]; /* the largest |G|; of each coordinate's correction */
    double slope_g, slope_c[3]; /* the largest slope of G; of each coordinate's correction */
} corr_bounds;

/* The slopes of G from node (i, j) to its neighbours along x (j + 1) and y (i + 1) into b. */
static void node_slopes(const sc_lut *lut, int i, int j, corr_bounds *b)
{
    const size_t k = (size_t)i * lut->nx + j;
    const double gx = lut->gx_um[k], gy = lut->gy_um[k];
    for (int d = 0; d < 2; ++d) {
        if ((d == 0 && j + 1 >= lut->nx) || (d == 1 && i + 1 >= lut->ny))
            continue;
        const size_t k2 = d == 0 ? k + 1 : k + (size_t)lut->nx;
        const double pitch_um = 1e3 * (d == 0 ? lut->px_mm : lut->py_mm);
        const double sx = fabs(lut->gx_um[k2] - gx) / pitch_um;
        const double sy = fabs(lut->gy_um[k2] - gy) / pitch_um;
        b->slope_g = sx > b->slope_g ? sx : b->slope_g;
        b->slope_g = sy > b->slope_g ? sy : b->slope_g;
        b->slope_c[0] = sx > b->slope_c[0] ? sx : b->slope_c[0];
        b->slope_c[1] = sy > b->slope_c[1] ? sy : b->slope_c[1];
    }
}

/* A profile adds its largest |error| and slope to its coordinate's bounds. */
static void profile_bounds(const sc_lut_profile *p, corr_bounds *b)
{
    double emax_um = 0, smax = 0;
    for (int n = 0; n < p->n; ++n) {
        emax_um = fabs(p->err_um[n]) > emax_um ? fabs(p->err_um[n]) : emax_um;
        if (n + 1 < p->n) {
            const double s = fabs(p->err_um[n + 1] - p->err_um[n]) / (1e3 * p->step_mm);
            smax = s > smax ? s : smax;
        }
    }
    if (p->dir >= 0 && p->dir < 3) {
        b->cmax_um[p->dir] += emax_um;
        b->slope_c[p->dir] += smax;
    }
}

static void print_correction_bounds(const sc_lut *lut)
{
    corr_bounds b = {0, {0, 0, 0}, 0, {0, 0, 0}};
    for (int i = 0; i < lut->ny; ++i)
        for (int j = 0; j < lut->nx; ++j) {
            const size_t k = (size_t)i * lut->nx + j;
            const double gx = lut->gx_um[k], gy = lut->gy_um[k], g = sqrt(gx * gx + gy * gy);
            b.gmax_um = g > b.gmax_um ? g : b.gmax_um;
            b.cmax_um[0] = fabs(gx) > b.cmax_um[0] ? fabs(gx) : b.cmax_um[0];
            b.cmax_um[1] = fabs(gy) > b.cmax_um[1] ? fabs(gy) : b.cmax_um[1];
            node_slopes(lut, i, j, &b);
        }
    for (int k = 0; k < lut->n_profiles; ++k)
        profile_bounds(&lut->profile[k], &b);
    double slope_all = b.slope_c[0] > b.slope_c[1] ? b.slope_c[0] : b.slope_c[1];
    slope_all = b.slope_c[2] > slope_all ? b.slope_c[2] : slope_all;
    printf("largest |G|: %.6f um\n", b.gmax_um);
    printf("largest slope of G: %.6e (um per um)\n", b.slope_g);
    printf("correction bounds (grid and profiles): |cx| <= %.6f um, |cy| <= %.6f um, "
           "slope <= %.6e\n", b.cmax_um[0], b.cmax_um[1], slope_all);
}

static int lut_info(int argc, char **argv)
{
    sc_lut *lut = NULL;
    int rc = load_table("lut info", argc, argv, &lut);
    if (rc != CLI_OK || !lut)
        return rc < 0 ? CLI_OK : rc;
    printf("format: selfcal table v1, %zu bytes\n", stored_size(lut));
    printf("grid: %d x %d nodes, origin %.6f,%.6f mm, pitch %.6f x %.6f mm\n", lut->nx, lut->ny,
           lut->x0_mm, lut->y0_mm, lut->px_mm, lut->py_mm);
    printf("grid encoding: %s, %u pm per code, quantization <= %.4f nm\n",
           enc_name(lut->grid_encoding), (unsigned)lut->grid_scale_pm,
           1e3 * sc_lut_quantization_um(lut->grid_scale_pm));
    for (int k = 0; k < lut->n_profiles; ++k) {
        const sc_lut_profile *p = &lut->profile[k];
        printf("profile %d: error of %s along %s, %d points from %.6f mm step %.6f mm, %s, "
               "%u pm per code\n",
               k, sc_lut_axis_name(p->dir), sc_lut_axis_name(p->axis), p->n, p->start_mm,
               p->step_mm, enc_name(p->encoding), (unsigned)p->scale_pm);
    }
    print_bounds(lut);
    print_correction_bounds(lut);
    printf("method: %s\n", lut->prov.method[0] ? lut->prov.method : "(not recorded)");
    time_t t = (time_t)lut->prov.created_unix_s;
    struct tm tmv;
    char when[64] = "?";
    if (gmtime_r(&t, &tmv))
        strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &tmv);
    printf("created: %s (%lld)\n", when, (long long)lut->prov.created_unix_s);
    if (lut->prov.sigma_um >= 0)
        printf("sigma_um: %g\n", lut->prov.sigma_um);
    else
        printf("sigma_um: (not recorded)\n");
    for (int k = 0; k < lut->prov.n_sources; ++k) {
        char hex[2 * SC_SHA256_BYTES + 1];
        sc_sha256_hex(lut->prov.sha256[k], hex);
        printf("source %d sha256: %s (%s)\n", k, hex, k == 0 ? "map" : "profile");
    }
    free(lut);
    return CLI_OK;
}

int cmd_lut(int argc, char **argv)
{
    if (argc < 2)
        return cli_usage_error("lut", "expected a subcommand: build, dump or info (see --help)");
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        cli_opts_help(stdout, &cli_lut_build_opts);
        return CLI_OK;
    }
    if (!strcmp(argv[1], "build"))
        return lut_build(argc - 1, argv + 1);
    if (!strcmp(argv[1], "dump"))
        return lut_dump(argc - 1, argv + 1);
    if (!strcmp(argv[1], "info"))
        return lut_info(argc - 1, argv + 1);
    return cli_usage_error("lut", "unknown subcommand '%s' (build, dump or info)", argv[1]);
}
