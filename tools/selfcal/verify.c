/* verify.c — the report section of the check of a compensated machine (the computation, the
 * uncertainty and the decision rule are the library's: selfcal/verify.h). */
#include "verify.h"

#include <math.h>
#include <string.h>

#include "cli.h"
#include "plots.h"
#include "report_html.h"
#include "selfcal/csv.h"

static void draw_v(FILE *fp, const void *ctx)
{
    const sc_verify_result *r = ctx;
    plot_arrows_pair_svg(fp, &r->before, "before compensation (A, placement removed)", &r->after,
                         "after compensation (A, placement removed)", NULL);
}

static void stats_row(FILE *fp, const char *name, const char *id, const sc_verify_stats *s)
{
    char b[64];
    fprintf(fp, "<tr><td class=\"l\">%s</td><td>%ld</td>", name, s->count);
    snprintf(b, sizeof b, "%s-rms-x", id);
    html_num_cell(fp, b, "%.4g", s->rms_x);
    snprintf(b, sizeof b, "%s-rms-y", id);
    html_num_cell(fp, b, "%.4g", s->rms_y);
    snprintf(b, sizeof b, "%s-rms", id);
    html_num_cell(fp, b, "%.4g", s->rms);
    snprintf(b, sizeof b, "%s-max", id);
    html_num_cell(fp, b, "%.4g", s->max);
    fprintf(fp, "<td class=\"l\">(%g, %g)</td></tr>\n", s->max_x_mm, s->max_y_mm);
}

/* The decision rule, U and its parts. */
static void rule_paragraph(FILE *fp, const sc_verify_opts *o, const sc_verify_result *r)
{
    const sc_verify_u *u = &r->u;
    fputs("<h3>Decision rule</h3>\n<table id=\"verify-u\">\n", fp);
    fprintf(fp, "<tr><th class=\"l\">decision rule</th><td class=\"l\" id=\"verify-rule\">%s</td></tr>\n",
            r->rule == SC_VERIFY_RULE_GUARDED
                ? "guarded acceptance (ISO 14253-1): pass if max |r| + U ≤ T, fail if "
                  "max |r| − U &gt; T, inconclusive otherwise"
                : "simple acceptance: pass if max |r| ≤ T, fail otherwise (U is stated, not "
                  "used; ILAC-G8: the risk of a false decision is then up to the user)");
    fputs("<tr><th class=\"l\">tolerance T on max |r| after compensation</th>", fp);
    html_num_cell(fp, "verify-tolerance", "%.4g µm", o->tolerance_um);
    fputs("</tr>\n<tr><th class=\"l\">max |r| after compensation</th>", fp);
    html_num_cell(fp, "verify-max", "%.4g µm", r->st_after.max);
    if (u->given) {
        fputs("</tr>\n<tr><th class=\"l\">expanded uncertainty U of a residual (given, "
              "--u-verify-um)</th>", fp);
        html_num_cell(fp, "verify-U", "%.4g µm", u->U_um);
    } else {
        static const char *src[3] = {"given (--sigma-r-um)", "stated in the re-measurement's file",
                                     ("the residuals' RMS per coordinate (an upper bound: "
                                      "it holds what the table left too)")};
        fprintf(fp, "</tr>\n<tr><th class=\"l\">re-measurement noise σ (k = 1), %s</th>",
                src[u->sigma_source]);
        html_num_cell(fp, "verify-sigma", "%.4g µm", u->sigma_um);
        fprintf(fp, "</tr>\n<tr><th class=\"l\">plate error u(A) (k = 1), %s</th>",
                u->u_plate_given ? "given (--u-plate-um)" : "taken equal to σ");
        html_num_cell(fp, "verify-uA", "%.4g µm", u->u_plate_um);
        fputs("</tr>\n<tr><th class=\"l\">table quantization ±q, u = q/√3</th>", fp);
        fprintf(fp, "<td>±%.3g µm, %.3g µm</td>", u->quant_um, u->u_quant_um);
        fputs("</tr>\n<tr><th class=\"l\">combined u = √(σ² + u(A)² + u_q²)</th>", fp);
        html_num_cell(fp, "verify-u", "%.4g µm", u->u_um);
        fputs("</tr>\n<tr><th class=\"l\">expanded uncertainty U = k·u, k = 2 (about 95 %)</th>", fp);
        html_num_cell(fp, "verify-U", "%.4g µm", u->U_um);
    }
    fputs("</tr>\n</table>\n", fp);
}

void verify_verdict_text(char *buf, size_t size, const sc_verify_result *r)
{
    snprintf(buf, size, "%s (%s, U = %.4g um)", sc_verify_verdict_name(r->verdict),
             sc_verify_rule_name(r->rule), r->u.U_um);
}

int verify_parse_option(const char *cmd, const char *opt, const char *val, sc_verify_opts *o)
{
    double *dst = NULL;
    if (!strcmp(opt, "--decision-rule")) {
        int rule = sc_verify_rule_from_name(val);
        if (rule < 0)
            return cli_usage_error(cmd, "--decision-rule must be simple or guarded (got '%s')", val);
        o->rule = (sc_verify_rule)rule;
        return CLI_OK;
    }
    if (!strcmp(opt, "--u-verify-um"))
        dst = &o->u_verify_um;
    else if (!strcmp(opt, "--u-plate-um"))
        dst = &o->u_plate_um;
    else if (!strcmp(opt, !strcmp(cmd, "verify") ? "--sigma-r-um" : "--verify-sigma-um"))
        dst = &o->sigma_r_um;
    else
        return -1;
    if (sc_parse_double(val, dst) || !(*dst >= 0) || !(*dst <= SC_INPUT_MAX_ABS))
        return cli_usage_error(cmd, "%s needs a number >= 0 (um), got '%s'", opt, val);
    return CLI_OK;
}

int verify_parse_opt(const char *cmd, const char *opt, const char *val, void *field)
{
    return verify_parse_option(cmd, opt, val, field);
}

sc_status verify_html_section(FILE *fp, const sc_verify_opts *o, const char *name,
                              const sc_verify_result *r, const char *heading, sc_error *err)
{
    fputs("<section id=\"verify\">\n<h2>", fp);
    html_esc(fp, heading);
    fputs("</h2>\n<p>The plate was measured again with the table loaded (", fp);
    html_esc(fp, name);
    fputs(o->raw ? "; uncompensated readings, the table's measure-mode correction applied here"
                 : "; readings of the compensated machine",
          fp);
    fputs("). From each mark's deviation the plate error A of the calibration (rotated into the "
          "view) and a fitted misalignment per view are removed. <b>After</b>: what the table "
          "left uncompensated, plus noise. <b>Before</b>: the same measurement as the machine "
          "would have read it without the table (≈ G).</p>\n",
          fp);
    fputs("<table>\n<tr><th class=\"l\"></th><th>marks</th><th>RMS x (µm)</th><th>RMS y (µm)</th>"
          "<th>RMS |r| (µm)</th><th>max |r| (µm)</th><th class=\"l\">largest at (x, y) mm</th></tr>\n",
          fp);
    stats_row(fp, "before compensation", "verify-before", &r->st_before);
    stats_row(fp, "after compensation", "verify-after", &r->st_after);
    fputs("</table>\n", fp);
    if (r->verdict != SC_VERIFY_NO_VERDICT) {
        rule_paragraph(fp, o, r);
        const char *v = sc_verify_verdict_name(r->verdict);
        fprintf(fp, "<p>Verdict: <b id=\"verify-verdict\" class=\"%s\">%s</b> (%s rule, "
                    "U = %.4g µm).",
                r->verdict == SC_VERIFY_PASS ? "pass" : r->verdict == SC_VERIFY_FAIL ? "fail" : "inconclusive",
                v, sc_verify_rule_name(r->rule), r->u.U_um);
        if (r->verdict == SC_VERIFY_INCONCLUSIVE)
            fputs(" The tolerance lies within max |r| ± U: neither conformance nor "
                  "non-conformance is proven.", fp);
    } else
        fputs("<p>No tolerance given (--tolerance-um): no verdict.", fp);
    fprintf(fp, " Improvement of the RMS: ×%.3g.</p>\n", r->st_before.rms / r->st_after.rms);
    sc_status st = html_figure(fp, draw_v, r, "Residual maps before and after compensation (each "
                               "with its own arrow scale).", err);
    fputs("</section>\n", fp);
    return st;
}
