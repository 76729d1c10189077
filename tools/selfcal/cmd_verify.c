/* selfcal verify — after the table is loaded into the machine, compare a new measurement of the
 * plate with what the calibration predicts (model: verify.h); statistics before and after
 * compensation, pass/fail against a tolerance, optional residual file, plot and HTML report. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "plots.h"
#include "report_html.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "verify.h"

static const char USAGE[] =
    "usage: selfcal verify V.csv --table T.lut --artifact A.csv --tolerance-um T [--raw]\n"
    "                      [--decision-rule simple|guarded] [--u-verify-um U]\n"
    "                      [--sigma-r-um S] [--u-plate-um UA]\n"
    "                      [--residuals R.csv] [--plot V.svg] [--html V.html]\n"
    "\n"
    "V.csv: the plate measured again after the table T.lut was loaded into the machine (a\n"
    "selfcal-grid v1 file, typically one view, rot 0), as the compensated machine reads it\n"
    "(--raw: uncompensated readings; the table's measure-mode correction is applied here).\n"
    "A.csv: the plate error from the same calibration (selfcal grid --artifact).\n"
    "From each mark's deviation the plate error (rotated into the view) and a least-squares\n"
    "misalignment (tx, ty, theta) per view are removed; what is left after compensation is the\n"
    "stage error the table did not remove, plus noise. 'Before' is the same measurement as the\n"
    "machine would have read it without the table (the table's position-mode correction undoes\n"
    "the compensation), i.e. about G. Corrections use selfcald's correction core.\n"
    "Prints the statistics (RMS and max |r|, before and after), the expanded uncertainty U\n"
    "(k = 2) of a residual and the verdict under the decision rule (default simple):\n"
    "  simple:  pass if max |r| after compensation <= T (um)     exit 0\n"
    "           fail otherwise                                    exit 3\n"
    "  guarded (ISO 14253-1):  pass if max |r| + U <= T           exit 0\n"
    "           fail if max |r| - U > T                           exit 3\n"
    "           inconclusive otherwise                            exit 4\n"
    "U = 2 sqrt(s^2 + uA^2 + uq^2): s the re-measurement's noise (--sigma-r-um, else stated in\n"
    "V.csv, else the RMS per coordinate of the residuals after, an upper bound), uA the plate\n"
    "error's (--u-plate-um, else taken equal to s), uq the table's quantization (q/sqrt 3);\n"
    "or U given by --u-verify-um.\n"
    "Bad input: exit 2 with one line FILE:LINE: reason, and no output file. Other errors: 1.\n"
    "--residuals: view,i,j,x_mm,y_mm,before_rx_um,before_ry_um,after_rx_um,after_ry_um\n"
    "--plot: the residual maps before and after, side by side; --html: a self-contained report.\n";

enum { VERIFY_FAIL_EXIT = 3, VERIFY_INCONCLUSIVE_EXIT = 4 };


static void print_residuals(FILE *fp, const sc_verify_result *r)
{
    const sc_grid_plan *p = &r->d.plan;
    int n = p->n;
    size_t nn = (size_t)n * n;
    fputs("view,i,j,x_mm,y_mm,before_rx_um,before_ry_um,after_rx_um,after_ry_um\n", fp);
    for (int v = 0; v < p->n_views; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                size_t g = (size_t)v * nn + (size_t)i * n + j;
                int ni, nj;
                if (!isfinite(r->ax[g]) || !sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    continue;
                fprintf(fp, "%d,%d,%d,%.15g,%.15g,%.9g,%.9g,%.9g,%.9g\n", r->info.view_id[v], i, j,
                        sc_stage_map_x_mm(&r->before, nj), sc_stage_map_y_mm(&r->before, ni), r->bx[g],
                        r->by[g], r->ax[g], r->ay[g]);
            }
}

static void draw_plot(FILE *fp, const sc_verify_result *r)
{
    plot_arrows_pair_svg(fp, &r->before, "before compensation (A, placement removed)", &r->after,
                         "after compensation (own arrow scale)",
                         "Re-measurement of the plate: residual maps before and after compensation");
}

/* The optional outputs: residuals, plot, HTML section; the inputs as named and as read. */
typedef struct {
    const char *res_path, *plot, *html;
    const char *names[3];    /* measurement, table, artifact as given */
    const cli_input *src[3]; /* as read (a pipe from its in-memory copy) */
} verify_outputs;

/* What the command line asks for: the verification's options and the outputs. */
typedef struct verify_args {
    sc_verify_opts o;
    verify_outputs out;
} verify_args;

#define F(field) offsetof(verify_args, field)
#define VERIFY_UM(name, text)                                                                      \
    {name, CLI_CUSTOM, F(o), "U", 0, SC_INPUT_MAX_ABS, .parse = verify_parse_opt, .help = text}
/* verify's options (cli_opts.h), in the order of its --help */
static const cli_opt VERIFY_OPTS[] = {
    {"--table", CLI_STRING, F(out.names[1]), "T.lut", .help = "the table the machine ran (required)"},
    {"--artifact", CLI_STRING, F(out.names[2]), "A.csv",
     .help = "the calibration's plate error (required)"},
    {"--tolerance-um", CLI_DOUBLE, F(o.tolerance_um), "T", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .bad = "--tolerance-um needs a positive number, got '%s'", .help = "the tolerance (um; required)"},
    {"--raw", CLI_FLAG, F(o.raw), .help = "the re-measurement is of the uncompensated machine"},
    {"--decision-rule", CLI_CUSTOM, F(o), "simple|guarded", .choices = "simple|guarded",
     .parse = verify_parse_opt, .help = "the verdict's decision rule"},
    VERIFY_UM("--u-verify-um", "the re-measurement's uncertainty (um)"),
    VERIFY_UM("--u-plate-um", "the plate error's uncertainty (um)"),
    VERIFY_UM("--sigma-r-um", "the re-measurement's noise (um)"),
    {"--residuals", CLI_STRING, F(out.res_path), "R.csv", .help = "the residuals before and after"},
    {"--plot", CLI_STRING, F(out.plot), "P.svg", .help = "the residual maps"},
    {"--html", CLI_STRING, F(out.html), "V.html", .help = "the verification as a page"},
};
#undef VERIFY_UM
#undef F

const cli_cmd_opts cli_verify_opts = {
    "verify", USAGE, VERIFY_OPTS, (int)(sizeof VERIFY_OPTS / sizeof VERIFY_OPTS[0]),
    offsetof(verify_args, out.names[0]), NULL, "more than one measurement ('%s', '%s')", NULL,
    NULL, 0, NULL, NULL,
};

/* The standalone HTML page of the verification. */
static sc_status write_html(FILE *fp, const verify_outputs *out, const sc_verify_opts *o,
                            const sc_verify_result *r, int argc, char **argv, sc_error *err)
{
    html_begin(fp, "Verification of a compensated stage");
    fputs("<h1>Verification of a compensated stage</h1>\n", fp);
    sc_status st = verify_html_section(fp, o, out->names[0], r, "Re-measurement after compensation",
                                       err);
    const cli_input *inputs[3] = {out->src[0], out->src[1], out->src[2]};
    const char *roles[3] = {"re-measurement (selfcal-grid v1)", "lookup table",
                            "plate error of the calibration"};
    if (st == SC_OK)
        st = html_provenance(fp, argc, argv, inputs, roles, 3, err);
    html_end(fp);
    return st;
}

/* Every output asked for, committed together: all or none. */
static sc_status write_outputs(const verify_outputs *out, const sc_verify_opts *o,
                               const sc_verify_result *r, int argc, char **argv, sc_error *err)
{
    const char *paths[3] = {out->res_path, out->plot, out->html};
    sc_afile f[3];
    memset(f, 0, sizeof f);
    sc_status st = SC_OK;
    int opened = 0;
    for (; opened < 3 && st == SC_OK; ++opened) {
        if (!paths[opened])
            continue;
        st = sc_afile_open(&f[opened], paths[opened], err);
        if (st != SC_OK)
            break;
        FILE *fp = f[opened].fp;
        if (opened == 0)
            print_residuals(fp, r);
        else if (opened == 1)
            draw_plot(fp, r);
        else
            st = write_html(fp, out, o, r, argc, argv, err);
    }
    /* all files or none: sync every one, then rename them together */
    return sc_afile_finish_all(f, opened, st, err);
}

/* stdout: the statistics, U and the verdict, one `key: value` per line. */
static void print_summary(const sc_verify_opts *o, const sc_verify_result *r)
{
    const sc_verify_stats *b = &r->st_before, *a = &r->st_after;
    printf("marks: %ld\n", a->count);
    printf("before_rms_um: %.6g\nbefore_max_um: %.6g\n", b->rms, b->max);
    printf("after_rms_um: %.6g\nafter_max_um: %.6g\n", a->rms, a->max);
    printf("after_max_at_mm: %g,%g\n", a->max_x_mm, a->max_y_mm);
    printf("tolerance_um: %g\n", o->tolerance_um);
    printf("decision_rule: %s\n", sc_verify_rule_name(r->rule));
    printf("U_verify_um: %.4g\n", r->u.U_um);
    char line[128];
    verify_verdict_text(line, sizeof line, r);
    printf("verdict: %s\n", line);
}

int cmd_verify(int argc, char **argv)
{
    verify_args g;
    memset(&g, 0, sizeof g);
    sc_verify_opts_init(&g.o);
    int rc = cli_opts_parse(&cli_verify_opts, argc, argv, &g);
    if (rc >= 0)
        return rc;
    sc_verify_opts o = g.o;
    verify_outputs out = g.out;
    if (!out.names[0] || !out.names[1] || !out.names[2] || !isfinite(o.tolerance_um))
        return cli_usage_error("verify", "V.csv, --table, --artifact and --tolerance-um are required (see --help)");
    sc_error err;
    sc_error_clear(&err);
    sc_verify_result r;
    memset(&r, 0, sizeof r);
    cli_input src[3]; /* pipes read once, into memory, hashed on the way */
    int opened;
    sc_status st = cli_input_open_all(src, out.names, 3, 1u << 1 /* the table */, &opened, &err);
    for (int k = 0; k < 3; ++k)
        out.src[k] = &src[k];
    if (st == SC_OK) {
        o.measurement = src[0].path, o.table = src[1].path, o.artifact = src[2].path;
        st = sc_verify_run(&o, &r, &err);
    }
    if (st == SC_OK)
        st = write_outputs(&out, &o, &r, argc, argv, &err);
    rc = st == SC_OK ? CLI_OK : cli_report(&err);
    cli_input_close_all(src, opened);
    if (st != SC_OK) {
        sc_verify_result_free(&r);
        return rc;
    }
    if (r.n_unmeasured || r.n_unseen)
        fprintf(stderr, "selfcal verify: left out of the statistics: %ld mark(s) the views place "
                        "on the stage without a point in %s, %ld the calibration saw no error for "
                        "(empty in %s)\n",
                r.n_unmeasured, out.names[0], r.n_unseen, out.names[2]);
    print_summary(&o, &r);
    sc_verify_verdict v = r.verdict;
    sc_verify_result_free(&r);
    return v == SC_VERIFY_PASS ? CLI_OK
           : v == SC_VERIFY_INCONCLUSIVE ? VERIFY_INCONCLUSIVE_EXIT : VERIFY_FAIL_EXIT;
}
