/* selfcal report profile — the report of a straightness profile reconstruction (two-set
 * two-point method) as one self-contained HTML file (SPEC §9): the set-up, the method, the noise
 * given and estimated with its χ² test, the residuals of each scan, f with its uncertainty (k = 1
 * and k = 2), u(f), e_y, and the provenance. Computed by the same code as `selfcal profile`. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "plots.h"
#include "selfcal/profile_calibrate.h"
#include "report_cert.h"
#include "report_html.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"

static const char USAGE[] =
    "usage: selfcal report profile IN.csv -o R.html|--pdf R.pdf [--method lsq|dft]\n"
    "                              [--sigma-disp-um X] [--sigma-angle-urad Y]\n"
    "                              [--info KEY=VALUE ...] [--info-file F]\n"
    "\n"
    "Writes one self-contained HTML file (figures inline as SVG, nothing fetched from outside;\n"
    "prints to PDF from a browser): the set-up (N, s, d1, d2), the method, the sensor noise given\n"
    "(options win over the file's header lines) and estimated from the residuals, the variance\n"
    "factor and its chi-square test, the residuals of each scan (statistics and histogram), the\n"
    "profile f with bands of its standard (k = 1) and expanded (k = 2) uncertainty, u(f), the\n"
    "stage's straightness motion error e_y, and the provenance (selfcal version, date, command\n"
    "line, SHA-256 of the input). Default method: lsq. --info, --info-file and --pdf as for\n"
    "selfcal report grid (see its --help). Exit 0, or 2 on bad input (one line naming the file\n"
    "and line; no report is left).\n";

/* The calibration as `selfcal profile` computes it, plus what the residuals need. */
typedef struct profile_run {
    int n;
    double *blk;
    double *y1, *y2;    /* the combined differences (N - d_k values) */
    double *f, *uf, *ey; /* the chosen method's result */
    double *fres;       /* the least-squares f the residuals are taken from */
    sc_profile_solution sol;
} profile_run;

static sc_status profile_run_compute(const sc_profile_data *d, sc_profile_method method,
                                     double sd, double sa, profile_run *r, sc_error *err)
{
    int n = d->n;
    r->n = n;
    r->blk = malloc((size_t)7 * n * sizeof(double));
    if (!r->blk)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    r->y1 = r->blk, r->y2 = r->y1 + n, r->f = r->y2 + n, r->uf = r->f + n, r->ey = r->uf + n;
    r->fres = r->ey + n;
    double *scratch = r->fres + n;
    sc_profile_combine(d, 0, r->y1);
    sc_profile_combine(d, 1, r->y2);
    sc_profile_options o;
    sc_profile_options_default(&o);
    o.method = method;
    o.sigma_disp_um = sd;
    o.sigma_angle_urad = sa;
    r->sol = (sc_profile_solution){.f_um = r->f, .uf_um = r->uf, .ey_um = r->ey};
    sc_status st = sc_profile_calibrate(d, &o, &r->sol, err);
    if (st != SC_OK)
        return st;
    if (method == SC_PROFILE_LSQ) {
        memcpy(r->fres, r->f, (size_t)n * sizeof(double));
        return SC_OK;
    }
    /* the residuals (and the noise estimate) are those of the least-squares fit */
    o.method = SC_PROFILE_LSQ;
    sc_profile_solution ls = {.f_um = r->fres, .uf_um = NULL, .ey_um = scratch};
    return sc_profile_calibrate(d, &o, &ls, err);
}

static void profile_run_free(profile_run *r)
{
    free(r->blk);
    r->blk = NULL;
}

typedef struct fig_prof {
    const sc_profile_result *a;
    const profile_plot_opts *o;
} fig_prof;

static void draw_prof(FILE *fp, const void *ctx)
{
    const fig_prof *f = ctx;
    profile_plot_svg(fp, f->a, NULL, NULL, f->o, NULL);
}

typedef struct fig_hist {
    const double *v;
    long n;
    double sigma;
    const char *title;
} fig_hist;

static void draw_hist(FILE *fp, const void *ctx)
{
    const fig_hist *f = ctx;
    plot_histogram_svg(fp, f->v, f->n, f->sigma, f->title, "residual (nm)");
}

/* Residuals (nm) of scan k against the least-squares f: y_k(n) − (f(n+d) − f(n)) − c_k with c_k
 * their mean (the least-squares offset for that f), over the samples with a residual (a gap, or a
 * point left undetermined, has none: SPEC §2a). Returns their count (m = N − d without gaps). */
static int scan_residuals(const profile_run *r, int d, const double *y, double *res_nm)
{
    int m = r->n - d, got = 0;
    double c = 0;
    for (int i = 0; i < m; ++i) {
        double v = y[i] - (r->fres[i + d] - r->fres[i]);
        if (isfinite(v))
            c += v, res_nm[got++] = v;
    }
    c /= got > 0 ? got : 1;
    for (int i = 0; i < got; ++i)
        res_nm[i] = (res_nm[i] - c) * 1e3;
    return got;
}

static double rms_max(const double *v, int n, double *mx)
{
    double s = 0;
    int c = 0;
    *mx = 0;
    for (int i = 0; i < n; ++i)
        if (isfinite(v[i])) {
            s += v[i] * v[i];
            *mx = fmax(*mx, fabs(v[i]));
            c++;
        }
    if (!c)
        *mx = NAN;
    return c ? sqrt(s / c) : NAN;
}

static double peak_to_valley(const double *v, int n)
{
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < n; ++i)
        if (isfinite(v[i]))
            lo = fmin(lo, v[i]), hi = fmax(hi, v[i]);
    return hi >= lo ? hi - lo : NAN;
}

/* The figures the summary and the results both state, computed once. */
typedef struct profile_figures {
    double umax, urms, fpv, frms, eypv, eyrms;
} profile_figures;

static profile_figures figures_of(const sc_profile_data *d, const profile_run *r)
{
    profile_figures g;
    double mx;
    g.urms = rms_max(r->uf, d->n, &g.umax);
    g.fpv = peak_to_valley(r->f, d->n);
    g.eypv = peak_to_valley(r->ey, d->n);
    g.frms = rms_max(r->f, d->n, &mx);
    g.eyrms = rms_max(r->ey, d->n, &mx);
    return g;
}

/* Title and the summary paragraph. */
static void report_summary(FILE *fp, const char *in, const char *method_s,
                           const sc_profile_data *d, const profile_figures *g,
                           const report_info *ri)
{
    const int n = d->n;
    char title[600];
    snprintf(title, sizeof title, "Straightness profile report — %s", cli_basename(in));
    html_begin(fp, title);
    report_page_css(fp, ri);
    fputs("<h1>", fp);
    html_esc(fp, title);
    fputs("</h1>\n", fp);
    report_info_html(fp, ri, "report");
    double umax = g->umax, fpv = g->fpv;
    fprintf(fp, "<div class=\"summary\" id=\"summary\"><p>Method <b>%s</b>; N = %d points, s = %g mm, "
                "d1 = %d, d2 = %d. Straightness of f (peak to valley) %.4g µm",
            method_s, n, d->s_mm, d->d[0], d->d[1], fpv);
    if (isfinite(umax))
        fprintf(fp, "; largest u(f) %.4g nm (k = 1), U = %.4g nm (k = 2)", umax * 1e3, 2e3 * umax);
    fputs(".</p></div>\n", fp);
}

/* 1. Set-up and 2. Method. */
static void section_setup_method(FILE *fp, const char *method_s, const sc_profile_data *d)
{
    const int n = d->n, d1 = d->d[0], d2 = d->d[1];
    fputs("<section id=\"setup\">\n<h2>1. Set-up</h2>\n<table>\n", fp);
    fprintf(fp, "<tr><th class=\"l\">points N</th><td id=\"N\">%d</td></tr>\n", n);
    fprintf(fp, "<tr><th class=\"l\">sampling interval s</th><td id=\"s_mm\">%g mm</td></tr>\n", d->s_mm);
    fprintf(fp, "<tr><th class=\"l\">sensor spacings d1, d2 (samples)</th><td><span id=\"d1\">%d</span>, "
                "<span id=\"d2\">%d</span></td></tr>\n", d1, d2);
    fprintf(fp, "<tr><th class=\"l\">sensor spacings D1, D2</th><td>%g mm, %g mm</td></tr>\n",
            d1 * d->s_mm, d2 * d->s_mm);
    fprintf(fp, "<tr><th class=\"l\">samples per scan</th><td>%d, %d</td></tr>\n</table>\n</section>\n",
            n - d1, n - d2);

    fputs("<section id=\"method\">\n<h2>2. Method</h2>\n<p>Method: <b id=\"method-name\">", fp);
    html_esc(fp, method_s);
    fputs("</b>. ", fp);
    if (!strcmp(method_s, "lsq"))
        fputs("Least squares (Ding et al. §2.3): f at every point and the offsets c1, c2 from "
              "y_k(n) = f(n + d_k) − f(n) + c_k, each scan weighted by the inverse variance of "
              "y_k; f relative to its least-squares line. u(f): square roots of the diagonal of "
              "the estimator covariance.",
              fp);
    else
        fputs("Discrete Fourier transform (Ding et al. §2.2): natural extension of y_k, zero-point "
              "compensation, combined coefficients, inverse transform; f relative to its "
              "least-squares line. u(f): exact from the method's linear response. Residuals and "
              "the noise estimate come from the least-squares fit of the same data.",
              fp);
    fputs("</p>\n<p>Model: y_k = m2 − m1 − D_k·m3 = f(n + d_k) − f(n) + c_k; e_y = m1 − f from "
          "scan 1, relative to its least-squares line.</p>\n</section>\n",
          fp);

}

/* 3. Noise: the given and used sigmas, the variance factor and its χ² test. */
static void section_noise(FILE *fp, const sc_profile_solution *so)
{
    fputs("<section id=\"noise\">\n<h2>3. Noise</h2>\n<table>\n", fp);
    fputs("<tr><th class=\"l\">σ_disp given (each displacement sensor)</th>", fp);
    html_num_cell(fp, "sigma_disp_um", "%.4g µm", so->noise_known ? so->sigma_disp_um : NAN);
    fputs("</tr>\n<tr><th class=\"l\">σ_angle given</th>", fp);
    html_num_cell(fp, "sigma_angle_urad", "%.4g µrad", so->noise_known ? so->sigma_angle_urad : NAN);
    fputs("</tr>\n<tr><th class=\"l\">σ(y1), σ(y2) used for u(f)</th>", fp);
    fputs("<td>", fp);
    html_num_span(fp, "sigma_y1_um", "%.4g", so->sigma_y_um[0]);
    fputs(", ", fp);
    html_num_span(fp, "sigma_y2_um", "%.4g", so->sigma_y_um[1]);
    fputs(" µm</td></tr>\n", fp);
    fprintf(fp, "<tr><th class=\"l\">residual degrees of freedom N − d1 − d2</th><td id=\"dof\">%d</td></tr>\n",
            so->dof);
    double vf = isfinite(so->residual_ratio) ? so->residual_ratio * so->residual_ratio : NAN;
    fputs("<tr><th class=\"l\">variance factor (weighted RSS / dof)</th>", fp);
    html_num_cell(fp, "variance_factor", "%.4f", vf);
    double lo, hi;
    int pass = html_chi2_interval(vf, so->dof, &lo, &hi);
    fputs("</tr>\n<tr><th class=\"l\">χ² test at 95 % (two-sided)</th>", fp);
    if (pass >= 0)
        fprintf(fp, "<td><span id=\"chi2_interval\">[%.4f, %.4f]</span>: <b id=\"chi2\" class=\"%s\">%s</b></td>",
                lo, hi, pass ? "pass" : "fail", pass ? "pass" : "fail");
    else
        fputs("<td id=\"chi2\">not applicable</td>", fp);
    fputs("</tr>\n</table>\n", fp);
    if (!so->noise_known)
        fputs("<p class=\"note\">No sensor noise was stated (neither the file's header lines nor "
              "the options): it is estimated from the residuals with equal scan weights, and the "
              "variance factor is 1 by construction.</p>\n",
              fp);
    fputs("</section>\n", fp);

}

/* The uncertainty budget (SPEC §2a): what each stated instrument constant adds to u(f), with
 * the noise's part; only when a constant is stated. */
static void section_budget(FILE *fp, const sc_profile_data *d, const sc_profile_solution *so)
{
    static const char *const name[SC_PROFILE_U_N] = {
        "sensor noise", "probe gain K (m2 / K)", "angle scale K (m3 / K)", "probe spacings D1, D2"};
    static const char *const unit[SC_PROFILE_U_N] = {"", "", "", " mm"};
    const double K[SC_PROFILE_U_N] = {NAN, d->has_probe_gain ? d->probe_gain[0] : NAN,
                                      d->has_angle_scale ? d->angle_scale[0] : NAN, NAN};
    const double U[SC_PROFILE_U_N] = {NAN, d->has_probe_gain ? d->probe_gain[1] : 0,
                                      d->has_angle_scale ? d->angle_scale[1] : 0,
                                      d->has_spacing_u ? d->spacing_u_mm : 0};
    if (!(d->has_probe_gain || d->has_angle_scale || d->has_spacing_u) || !so->have_uf)
        return;
    fputs("<section id=\"budget\">\n<h3>Uncertainty budget</h3>\n<table>\n<tr><th class=\"l\">"
          "source</th><th>value</th><th>standard uncertainty</th><th>u(f), RMS (nm)</th>"
          "<th>u(f), largest (nm)</th></tr>\n", fp);
    for (int i = 0; i < SC_PROFILE_U_N; ++i) {
        if (i > 0 && !(U[i] > 0) && !isfinite(K[i]))
            continue;
        fprintf(fp, "<tr><td class=\"l\">%s</td>", name[i]);
        html_num_cell(fp, NULL, "%.9g", K[i]);
        if (i == 0)
            fputs("<td>stated or estimated (section 3)</td>", fp);
        else
            fprintf(fp, "<td>%.4g%s</td>", U[i], unit[i]);
        char id[32];
        snprintf(id, sizeof id, "budget-rms-%d", i);
        html_num_cell(fp, id, "%.4g", so->budget_rms_um[i] * 1e3);
        snprintf(id, sizeof id, "budget-max-%d", i);
        html_num_cell(fp, id, "%.4g", so->budget_max_um[i] * 1e3);
        fputs("</tr>\n", fp);
    }
    fputs("</table>\n<p class=\"note\">Each constant's part is its U times the response of f to it "
          "(the estimator is linear in y: one solve each); u(f) is the root sum of squares of "
          "the parts. The constants themselves correct the data before the model (m2 / K, "
          "m3 / K). The method cannot see them in its residuals: they are calibrated apart "
          "(docs/profile.md, Real rigs).</p>\n</section>\n", fp);
}

/* 4. Residuals of both scans, with their histogram. */
static sc_status section_residuals(FILE *fp, const sc_profile_data *d, const profile_run *r,
                                   sc_error *err)
{
    const int n = d->n, d1 = d->d[0], d2 = d->d[1];
    double *res = malloc((size_t)(2 * n) * sizeof(double));
    if (!res)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    int m1 = scan_residuals(r, d1, r->y1, res);
    int m2 = scan_residuals(r, d2, r->y2, res + m1);
    fputs("<section id=\"residuals\">\n<h2>4. Residuals</h2>\n<table>\n<tr><th>scan</th><th>d</th>"
          "<th>samples</th><th>RMS (nm)</th><th>max |r| (nm)</th></tr>\n",
          fp);
    double mx1, mx2, rr1 = rms_max(res, m1, &mx1), rr2 = rms_max(res + m1, m2, &mx2);
    fprintf(fp, "<tr><td>1</td><td>%d</td><td>%d</td>", d1, m1);
    html_num_cell(fp, "res-rms-1", "%.4g", rr1);
    html_num_cell(fp, "res-max-1", "%.4g", mx1);
    fprintf(fp, "</tr>\n<tr><td>2</td><td>%d</td><td>%d</td>", d2, m2);
    html_num_cell(fp, "res-rms-2", "%.4g", rr2);
    html_num_cell(fp, "res-max-2", "%.4g", mx2);
    fputs("</tr>\n</table>\n", fp);
    double s_all = sqrt((rr1 * rr1 * m1 + rr2 * rr2 * m2) / (m1 + m2));
    fig_hist fh = {res, m1 + m2, s_all, "residuals of y1 and y2 (nm)"};
    sc_status st = html_figure(fp, draw_hist, &fh,
                               "Histogram of the residuals of both scans with the normal density "
                               "of their RMS.",
                               err);
    free(res);
    fputs("</section>\n", fp);
    if (st != SC_OK)
        return st;

    return SC_OK;
}

/* 5. Results: the table and the profile figure; x: the abscissae (mm). */
static sc_status section_results(FILE *fp, const char *method_s, const sc_profile_data *d,
                                 const profile_run *r, const profile_figures *g, double *x,
                                 sc_error *err)
{
    const int n = d->n, d1 = d->d[0], d2 = d->d[1];
    double umax = g->umax, urms = g->urms, fpv = g->fpv, eypv = g->eypv;
    double frms = g->frms, eyrms = g->eyrms;
    fputs("<section id=\"results\">\n<h2>5. Results</h2>\n<table>\n<tr><th class=\"l\">quantity</th>"
          "<th>value</th><th class=\"l\">unit</th></tr>\n",
          fp);
    fputs("<tr><td class=\"l\">f, peak to valley</td>", fp);
    html_num_cell(fp, "f-pv", "%.5g", fpv);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">f, RMS</td>", fp);
    html_num_cell(fp, "f-rms", "%.5g", frms);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">u(f), RMS over the points (k = 1)</td>", fp);
    html_num_cell(fp, "uf-rms", "%.4g", urms * 1e3);
    fputs("<td class=\"l\">nm</td></tr>\n<tr><td class=\"l\">u(f), largest (k = 1)</td>", fp);
    html_num_cell(fp, "uf-max", "%.4g", umax * 1e3);
    fputs("<td class=\"l\">nm</td></tr>\n<tr><td class=\"l\">U(f) = 2u, largest (k = 2)</td>", fp);
    html_num_cell(fp, "Uf-max", "%.4g", 2 * umax * 1e3);
    fputs("<td class=\"l\">nm</td></tr>\n<tr><td class=\"l\">e_y, peak to valley</td>", fp);
    html_num_cell(fp, "ey-pv", "%.5g", eypv);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">e_y, RMS</td>", fp);
    html_num_cell(fp, "ey-rms", "%.5g", eyrms);
    fputs("<td class=\"l\">µm</td></tr>\n</table>\n", fp);
    if (!r->sol.have_uf)
        fputs("<p class=\"note\">No redundancy (N = d1 + d2): the noise cannot be estimated and "
              "no uncertainty is given.</p>\n",
              fp);
    sc_profile_result pr = {.n = n, .x_mm = x, .f_um = r->f, .uf_um = r->uf, .ey_um = r->ey};
    char t2[128];
    snprintf(t2, sizeof t2, "%s method, N = %d, d = %d/%d", method_s, n, d1, d2);
    profile_plot_opts po = {t2, method_s, NULL, 0};
    fig_prof fpf = {&pr, &po};
    sc_status st = html_figure(fp, draw_prof, &fpf,
                     "The profile f with bands f ± u(f) (k = 1) and f ± 2u(f) (k = 2), its standard "
                     "uncertainty u(f) and the stage's straightness motion error e_y.",
                     err);
    if (r->sol.have_uf) {
        fputs("<h3>Statement of uncertainty</h3>\n", fp);
        report_uncertainty_statement(
            fp, "the noise of the displacement and angle sensors (section 3), propagated through "
                "the estimate to every point of f.",
            "Not included: the sensors' calibration (scale) and their temperature, the spacings' "
            "errors, the stage's repeatability after the measurement and the interpolation of a "
            "table between the points.");
    }
    fputs("</section>\n", fp);
    return st;
}

/* The appendix: the profile at every point. */
static void report_appendix(FILE *fp, int n, const double *x, const profile_run *r)
{
    fputs("<h2>Appendix</h2>\n<p>The profile at every point.</p>\n<table class=\"profile map\" "
          "id=\"profile-table\">\n<thead><tr><th>n</th><th>x (mm)</th>"
          "<th>f (µm)</th><th>u(f) (µm)</th><th>U(f), k = 2 (µm)</th><th>e_y (µm)</th></tr></thead>\n",
          fp);
    for (int i = 0; i < n; ++i) {
        fprintf(fp, "<tr class=\"pt\"><td>%d</td><td>%g</td>", i, x[i]);
        html_num_cell(fp, NULL, "%.6f", r->f[i]);
        html_num_cell(fp, NULL, "%.6f", r->uf[i]);
        html_num_cell(fp, NULL, "%.6f", 2 * r->uf[i]);
        html_num_cell(fp, NULL, "%.6f", r->ey[i]);
        fputs("</tr>\n", fp);
    }
    fputs("</table>\n", fp);
}

static sc_status write_report(FILE *fp, const cli_input *src, const char *method_s,
                              const sc_profile_data *d, const profile_run *r,
                              const report_info *ri, int argc, char **argv, sc_error *err)
{
    const int n = d->n;
    profile_figures g = figures_of(d, r);
    report_summary(fp, src->orig, method_s, d, &g, ri);
    section_setup_method(fp, method_s, d);
    section_noise(fp, &r->sol);
    section_budget(fp, d, &r->sol);
    sc_status st = section_residuals(fp, d, r, err);
    if (st != SC_OK)
        return st;
    double *x = malloc((size_t)n * sizeof(double));
    if (!x)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (int i = 0; i < n; ++i)
        x[i] = i * d->s_mm;
    st = section_results(fp, method_s, d, r, &g, x, err);
    const cli_input *inputs[1] = {src};
    const char *roles[1] = {"measurement (selfcal-profile v1)"};
    if (st == SC_OK)
        st = html_provenance(fp, argc, argv, inputs, roles, 1, err);
    if (st == SC_OK && n <= 5000)
        report_appendix(fp, n, x, r);
    free(x);
    html_end(fp);
    return st;
}

/* What the command line asks for. */
typedef struct report_profile_args {
    const char *in, *out, *method_s;
    double sd, sa; /* the noise given, NaN if not */
    report_info ri;
    sc_profile_method method;
} report_profile_args;

#define F(field) offsetof(report_profile_args, field)
/* report profile's options (cli_opts.h), in the order of its --help */
static const cli_opt REPORT_PROFILE_OPTS[] = {
    {"-o|--out", CLI_STRING, F(out), "R.html", .help = "the report (HTML)"},
    {"--pdf", CLI_CUSTOM, F(ri), "R.pdf", .parse = report_info_opt, .help = "the report as PDF"},
    {"--method", CLI_STRING, F(method_s), "lsq|dft", .def = "lsq", .help = "the method"},
    {"--sigma-disp-um", CLI_CUSTOM, F(sd), "X", 0, SC_INPUT_MAX_ABS, .parse = cli_opt_noise,
     .def = "the file's, else estimated", .help = "the displacement probes' noise (um)"},
    {"--sigma-angle-urad", CLI_CUSTOM, F(sa), "Y", 0, SC_INPUT_MAX_ABS, .parse = cli_opt_noise,
     .def = "the file's, else estimated", .help = "the angle probe's noise (urad)"},
    {"--info", CLI_CUSTOM, F(ri), "KEY=VALUE", .parse = report_info_opt, .help = "a certificate field"},
    {"--info-file", CLI_CUSTOM, F(ri), "F", .parse = report_info_opt,
     .help = "certificate fields from a file"},
};
#undef F

const cli_cmd_opts cli_report_profile_opts = {
    "report profile", USAGE, REPORT_PROFILE_OPTS,
    (int)(sizeof REPORT_PROFILE_OPTS / sizeof REPORT_PROFILE_OPTS[0]),
    offsetof(report_profile_args, in), NULL, NULL, NULL, NULL, 0, NULL, NULL,
};

/* The command line into p: -1 to go on, else the exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, report_profile_args *p)
{
    const char *cmd = "report profile";
    memset(p, 0, sizeof *p);
    p->method_s = "lsq";
    p->sd = p->sa = NAN;
    int rc = cli_opts_parse(&cli_report_profile_opts, argc, argv, p);
    if (rc >= 0)
        return rc;
    if (!p->in || (!p->out && !p->ri.pdf))
        return cli_usage_error(cmd, "IN.csv and -o R.html or --pdf R.pdf are required (see --help)");
    if (!strcmp(p->method_s, "lsq"))
        p->method = SC_PROFILE_LSQ;
    else if (!strcmp(p->method_s, "dft"))
        p->method = SC_PROFILE_DFT;
    else
        return cli_usage_error(cmd, "--method must be lsq or dft (got '%s')", p->method_s);
    return -1;
}

int cmd_report_profile(int argc, char **argv)
{
    report_profile_args p;
    int rc = parse_args(argc, argv, &p);
    if (rc >= 0)
        return rc;
    const char *in = p.in, *out = p.out, *method_s = p.method_s;
    double sd = p.sd, sa = p.sa;
    sc_profile_method method = p.method;
    report_info ri = p.ri;
    sc_error err;
    sc_error_clear(&err);
    sc_profile_data d;
    report_out ro;
    if (report_info_load(&ri, &err) != SC_OK ||
        report_out_prepare(&ro, &ri, out, &err) != SC_OK) { /* Chromium first */
        report_info_free(&ri);
        return cli_report(&err);
    }
    cli_input src; /* a pipe is read once: into memory, hashed on the way */
    if (cli_input_open(&src, in, 1, &err) != SC_OK) {
        report_out_finish(&ro, &ri, SC_E_INPUT, NULL);
        report_info_free(&ri);
        return cli_report(&err);
    }
    if (sc_profile_read(src.path, &d, &err) != SC_OK) {
        rc = cli_report(&err);
        cli_input_close(&src);
        report_out_finish(&ro, &ri, SC_E_INPUT, NULL);
        report_info_free(&ri);
        return rc;
    }
    profile_run r;
    memset(&r, 0, sizeof r);
    sc_status st = profile_run_compute(&d, method, sd, sa, &r, &err);
    if (st == SC_OK)
        cli_warn_zero_noise("selfcal report profile", &r.sol);
    if (st == SC_OK) {
        sc_afile f;
        st = sc_afile_open(&f, ro.html, &err);
        if (st == SC_OK) {
            st = write_report(f.fp, &src, method_s, &d, &r, &ri, argc + 1, argv - 1, &err);
            st = sc_afile_finish(&f, st, &err);
        }
    }
    st = report_out_finish(&ro, &ri, st, &err); /* the PDF; the temporary HTML removed */
    report_info_free(&ri);
    profile_run_free(&r);
    sc_profile_data_free(&d);
    rc = st == SC_OK ? CLI_OK : cli_report(&err);
    cli_input_close(&src);
    return rc;
}
