/* selfcal report grid — the calibration report of a grid plate self-calibration as one
 * self-contained HTML file (SPEC §9): plan, method, noise and its χ² test, residuals per view,
 * outliers, O, R and misalignments with uncertainties (k = 1 and k = 2), the maps as figures,
 * optionally the verification of the compensated machine, and the provenance. Everything is
 * computed here by calling the library, as `selfcal grid` does, never read back from its output. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "cli_opts.h"
#include "plots.h"
#include "report_cert.h"
#include "report_html.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "verify.h"

static const char USAGE[] =
    "usage: selfcal report grid IN.csv -o R.html|--pdf R.pdf [--method lsq|ye|double-shift]\n"
    "                           [--sigma-r-um S] [--info KEY=VALUE ...] [--info-file F]\n"
    "                           [--outlier-alpha A | --outlier-alpha-each A]\n"
    "                           [--view-noise stated|estimate] [--view-scale model|free]\n"
    "                           [--verify V.csv --table T.lut [--tolerance-um T] [--raw]\n"
    "                            [--decision-rule simple|guarded] [--u-verify-um U]\n"
    "                            [--verify-sigma-um S] [--u-plate-um UA]]\n"
    "\n"
    "Writes one self-contained HTML file (figures inline as SVG, nothing fetched from outside;\n"
    "prints to PDF from a browser) with the plan and whether it identifies G, the method, the\n"
    "noise given and estimated with the variance factor and its chi-square test, the residuals\n"
    "per view (statistics, histogram, largest ones, flagged outliers), O, R and the view\n"
    "misalignments with their uncertainties (k = 1 and expanded, k = 2), the stage error map as\n"
    "arrows, Gx, Gy, u(Gx), u(Gy) as colour maps, the plate error A, and the provenance (selfcal\n"
    "version, date, command line, SHA-256 of every input). Default method: lsq.\n"
    "Residuals and the noise estimate always come from the least-squares fit of the data (the\n"
    "closed forms are not least-squares estimates); the outlier test's options and --view-noise\n"
    "are selfcal grid's, and so is --view-scale. The plate's scale and temperature lines (SPEC 11)\n"
    "add a section with the stage's magnification, the views' scales and the uncertainty budget\n"
    "(each source, its u, sensitivity and contribution at the worst node, combined and expanded).\n"
    "--verify adds the check of the compensated\n"
    "machine (see selfcal verify --help) against the plate error of this calibration.\n"
    "--info KEY=VALUE (repeatable) and --info-file F (lines 'key = value') identify the report\n"
    "as a certificate: report_id, item, plate, instrument, customer, operator, measured_on,\n"
    "conditions, approved_by (other keys are listed as given); every printed page carries the\n"
    "report id and 'page n of m'. --pdf R.pdf prints the report through headless Chromium\n"
    "(SELFCAL_CHROMIUM, else chromium on PATH; without it: exit 1, nothing written).\n"
    "Exit 0, or 2 on bad input (one line naming the file and line; no report is left).\n";

/* Everything the report shows, computed once. */
typedef struct grid_report {
    const char *in, *method;
    const cli_input *src; /* in as read (a pipe from its in-memory copy) */
    const char *verify_name, *table_name; /* --verify V.csv --table T.lut as given */
    const cli_input *vsrc[2];             /* ... as read */
    double sigma_r_given; /* 0: not given */
    sc_grid_options test; /* the fit's options: outlier_alpha, _each, estimate_view_noise */
    sc_grid_data d;
    sc_grid_file_info info;
    sc_grid_lsq_info qi;
    int identifiable;
    sc_grid_solution sol;  /* the chosen method's calibration (closed forms only) */
    sc_grid_solution lsol; /* the least-squares one (residuals, noise) */
    sc_grid_result res;  /* the chosen method's result (arrays in sol or lsol) */
    sc_grid_result lres; /* the least-squares fit (residuals, noise) */
    const double *rx, *ry, *tx, *ty; /* residuals per view, n_views*n*n (NaN: not measured) */
    sc_stage_map gm, am;       /* G and A as maps for the figures (views on res) */
} grid_report;

#define NSQ(r) ((size_t)(r)->d.plan.n * (size_t)(r)->d.plan.n) /* plate marks */
#define NG(r) ((size_t)sc_grid_stage_nx(&(r)->d.plan) * (size_t)sc_grid_stage_ny(&(r)->d.plan)) /* stage nodes */

/* The map views of G (stage nodes) and A (plate marks, plate frame) the plot functions draw. */
static void make_maps(grid_report *r)
{
    const sc_grid_plan *p = &r->d.plan;
    r->gm = sc_grid_stage_map(p, r->res.gx_um, r->res.gy_um, r->res.ugx_um, r->res.ugy_um);
    sc_stage_map *a = &r->am; /* the plate: N x N marks, plate-centred */
    memset(a, 0, sizeof *a);
    a->nx = a->ny = p->n;
    a->px_mm = a->py_mm = p->pitch_mm;
    a->x0_mm = a->y0_mm = -0.5 * (p->n - 1) * p->pitch_mm;
    a->gx_um = r->res.ax_um;
    a->gy_um = r->res.ay_um;
}

/* Read, check and calibrate by the chosen method, and by least squares for the residuals and the
 * noise (the same calibration as `selfcal grid`, sc_grid_calibrate). */
static sc_status run(grid_report *r, sc_error *err)
{
    sc_status st = sc_grid_read(r->src ? r->src->path : r->in, &r->d, &r->info, err);
    if (st != SC_OK)
        return st;
    sc_grid_options o;
    sc_grid_options_default(&o);
    o.max_bytes = cli_memory_bytes();
    int m = sc_grid_method_from_name(r->method);
    o.method = m < 0 ? SC_GRID_METHOD_LSQ : (sc_grid_method)m;
    o.sigma_r_um = r->sigma_r_given;
    /* the chosen method's requirements first: its messages are the ones `selfcal grid` gives */
    st = sc_grid_check_method(&r->d, &r->info, r->in, &o, err);
    if (st == SC_OK && o.method != SC_GRID_METHOD_LSQ)
        st = sc_grid_calibrate(&r->d, &r->info, r->in, &o, &r->sol, err);
    sc_grid_options lo = o;
    lo.method = SC_GRID_METHOD_LSQ;
    lo.outlier_alpha = r->test.outlier_alpha; /* the test runs on the least-squares fit */
    lo.outlier_alpha_each = r->test.outlier_alpha_each;
    lo.estimate_view_noise = r->test.estimate_view_noise;
    lo.view_scale_free = r->test.view_scale_free;
    if (st == SC_OK) /* residuals, standardized residuals (exact leverage), Baarda's test */
        st = sc_grid_calibrate(&r->d, &r->info, r->in, &lo, &r->lsol, err);
    if (st != SC_OK)
        return st;
    r->qi = r->lsol.plan_info;
    r->identifiable = r->qi.identifiable;
    r->lres = r->lsol.res;
    r->res = o.method == SC_GRID_METHOD_LSQ ? r->lsol.res : r->sol.res;
    if (o.method != SC_GRID_METHOD_LSQ) /* the closed forms' noise and dof: least squares' */
        r->res.dof = r->lres.dof;
    r->rx = r->lsol.rx_um, r->ry = r->lsol.ry_um, r->tx = r->lsol.tx, r->ty = r->lsol.ty;
    make_maps(r);
    return SC_OK;
}

static void free_report(grid_report *r)
{
    sc_grid_solution_free(&r->sol);
    sc_grid_solution_free(&r->lsol);
    sc_grid_data_free(&r->d);
    sc_grid_file_info_free(&r->info);
}

/* ---- figures ---- */

typedef struct fig_cm {
    const sc_stage_map *m;
    int plate;
    const double *v;
    const char *title, *unit;
    int diverging;
} fig_cm;

static void draw_cm(FILE *fp, const void *ctx)
{
    const fig_cm *f = ctx;
    plot_colormap_svg(fp, f->m, f->plate, f->v, f->title, f->unit, f->diverging);
}

typedef struct fig_ar {
    const sc_stage_map *m;
    int plate;
    const char *title, *what;
} fig_ar;

static void draw_ar(FILE *fp, const void *ctx)
{
    const fig_ar *f = ctx;
    plot_arrows_svg(fp, f->m, f->plate, 0, f->title, f->what);
}

typedef struct fig_hist {
    const double *v;
    long n;
    double sigma;
    const char *title, *xlabel;
} fig_hist;

static void draw_hist(FILE *fp, const void *ctx)
{
    const fig_hist *f = ctx;
    plot_histogram_svg(fp, f->v, f->n, f->sigma, f->title, f->xlabel);
}

/* ---- sections ---- */

static void section_plan(FILE *fp, const grid_report *r)
{
    const sc_grid_plan *p = &r->d.plan;
    int n = p->n;
    fputs("<section id=\"plan\">\n<h2>1. Plan</h2>\n<table>\n", fp);
    fprintf(fp, "<tr><th class=\"l\">marks per side N</th><td id=\"N\">%d</td></tr>\n", n);
    fprintf(fp, "<tr><th class=\"l\">stage grid (nodes along x × y)</th><td id=\"stage\">%d × %d</td></tr>\n",
            sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    fprintf(fp, "<tr><th class=\"l\">pitch P</th><td id=\"pitch_mm\">%g mm</td></tr>\n", p->pitch_mm);
    fprintf(fp, "<tr><th class=\"l\">stage grid origin</th><td>(%g, %g) mm</td></tr>\n",
            p->origin_mm[0], p->origin_mm[1]);
    fprintf(fp, "<tr><th class=\"l\">views</th><td>%d</td></tr>\n", p->n_views);
    fprintf(fp, "<tr><th class=\"l\">measured marks (rows)</th><td id=\"n_rows\">%ld</td></tr>\n",
            r->info.n_rows);
    fprintf(fp, "<tr><th class=\"l\">scalar equations / unknowns / gauge constraints</th>"
                "<td>%ld / %ld / %ld</td></tr>\n",
            r->qi.n_equations, r->qi.n_unknowns, r->qi.n_constraints);
    fprintf(fp, "<tr><th class=\"l\">identifies G</th><td id=\"identifiable\" class=\"%s\">%s</td></tr>\n",
            r->qi.identifiable ? "pass" : "fail", r->qi.identifiable ? "yes" : "no");
    fprintf(fp, "<tr><th class=\"l\">free degrees of freedom beyond the gauge</th><td id=\"free\">%ld</td></tr>\n",
            r->qi.free_dof);
    fputs("<tr><th class=\"l\">predicted std(G)/σ_r, RMS over nodes (least squares)</th>", fp);
    html_num_cell(fp, "sigma_c_ratio_rms", "%.4f", r->qi.sigma_c_ratio_rms);
    fputs("</tr>\n<tr><th class=\"l\">predicted std(G)/σ_r, worst node</th>", fp);
    html_num_cell(fp, "sigma_c_ratio_max", "%.4f", r->qi.sigma_c_ratio_max);
    if (r->qi.n_testable > 0) { /* Baarda's internal reliability (selfcal plan) */
        const sc_grid_result *l = &r->lres;
        fprintf(fp, "</tr>\n<tr><th class=\"l\">coordinate equations the outlier test can check "
                    "/ cannot (a mark seen in one view only)</th><td><span id=\"n_testable\">%ld"
                    "</span> / <span id=\"n_untestable\">%ld</span></td>",
                r->qi.n_testable, r->qi.n_untestable);
        fputs("</tr>\n<tr><th class=\"l\">redundancy r = 1 − h, smallest / mean</th>", fp);
        fprintf(fp, "<td>%.4f / %.4f</td>", r->qi.redundancy_min, r->qi.redundancy_mean);
        fputs("</tr>\n<tr><th class=\"l\">smallest blunder found with 80 % power by this "
              "report's outlier test, in σ of the coordinate: at the smallest / the mean r</th>",
              fp);
        fprintf(fp, "<td><span id=\"mdb_ratio_max\">%.3g</span> / %.3g</td>",
                sc_grid_mdb_ratio(l->outlier_crit, 0.8, r->qi.redundancy_min),
                sc_grid_mdb_ratio(l->outlier_crit, 0.8, r->qi.redundancy_mean));
    }
    fputs("</tr>\n</table>\n<table>\n<tr><th>view</th><th>rot (°)</th><th>shift (pitches)</th>"
          "<th class=\"l\">measures</th><th>rows in file</th></tr>\n",
          fp);
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "<tr><td>%d</td><td>%d</td><td>%d, %d</td><td class=\"l\">", r->info.view_id[v],
                w->rot_deg, w->shift_x, w->shift_y);
        if (w->restricted) {
            fputs("rows ", fp);
            int first = 1;
            for (int i = 0; i < n; ++i)
                if (w->row_sel[i])
                    fprintf(fp, "%s%d", first ? "" : ",", i), first = 0;
            fputs(first ? "none" : "", fp);
            fputs("; columns ", fp);
            first = 1;
            for (int j = 0; j < n; ++j)
                if (w->col_sel[j])
                    fprintf(fp, "%s%d", first ? "" : ",", j), first = 0;
            fputs(first ? "none" : "", fp);
        } else
            fputs("every mark on the stage grid", fp);
        fprintf(fp, "</td><td>%ld</td></tr>\n", r->info.view_rows[v]);
    }
    fputs("</table>\n</section>\n", fp);
}

static void section_method(FILE *fp, const grid_report *r)
{
    fputs("<section id=\"method\">\n<h2>2. Method</h2>\n<p>Method: <b id=\"method-name\">", fp);
    html_esc(fp, r->method);
    fputs("</b>. ", fp);
    if (!strcmp(r->method, "lsq"))
        fputs("Least squares over every measured mark of every view: unknowns G at each stage node, "
              "the plate error A at each mark and a misalignment (tx, ty, θ) per view, the gauge "
              "(G without translation, rotation or magnification; A without translation or "
              "rotation) as hard constraints. Uncertainties are the square roots of the diagonal "
              "of the estimator covariance, scaled by σ_r.",
              fp);
    else if (!strcmp(r->method, "ye"))
        fputs("Ye et al.'s closed form: views rot 0°, rot 90° and a shift by one pitch. The closed "
              "form gives no uncertainties; the residuals and the noise below are those of the "
              "least-squares fit of the same data and model.",
              fp);
    else
        fputs("Petrò's double shift (closed form): views rot 0°, rot 90°, shift +2 and a partial "
              "shift −3 pitches. The closed form gives no uncertainties; the residuals and the "
              "noise below are those of the least-squares fit of the same data and model.",
              fp);
    fputs("</p>\n<p>Model (µm): measured − nominal = G(node) + Rot(A(mark)) + (tx − θ·y, ty + θ·x) "
          "+ noise. G = indicated − true position.</p>\n</section>\n",
          fp);
}

static void section_noise(FILE *fp, const grid_report *r, int *chi2_pass)
{
    const sc_grid_result *l = &r->lres;
    fputs("<section id=\"noise\">\n<h2>3. Measurement noise</h2>\n<table>\n", fp);
    if (l->stated_u) { /* the file's own uncertainties: σ figures are factors on them */
        fputs("<tr><th class=\"l\">σ_r given (--sigma-r-um)</th>", fp);
        html_num_cell(fp, "sigma_r_given_um", r->sigma_r_given > 0 ? "%.4g µm, unused: the file "
                      "states its uncertainties" : "%.4g", r->sigma_r_given > 0 ? r->sigma_r_given
                                                                               : NAN);
        fputs("</tr>\n<tr><th class=\"l\">the residuals' scale on the file's stated uncertainties, "
              "√(weighted RSS/dof) (1 = as stated)</th>", fp);
        html_num_cell(fp, "sigma_r_est_um", "%.4g", l->sigma_r_est_um);
        fputs("</tr>\n<tr><th class=\"l\">used for the uncertainties</th>", fp);
        html_num_cell(fp, "sigma_r_used_um", "%.4g × the stated uncertainties",
                      r->res.sigma_r_used_um);
    } else {
        fputs("<tr><th class=\"l\">σ_r given (--sigma-r-um)</th>", fp);
        html_num_cell(fp, "sigma_r_given_um", "%.4g µm",
                      r->sigma_r_given > 0 ? r->sigma_r_given : NAN);
        fputs("</tr>\n<tr><th class=\"l\">σ_r estimated from the residuals, √(RSS/dof)</th>", fp);
        html_num_cell(fp, "sigma_r_est_um", "%.4g µm", l->sigma_r_est_um);
        fputs("</tr>\n<tr><th class=\"l\">σ_r used for the uncertainties</th>", fp);
        html_num_cell(fp, "sigma_r_used_um", "%.4g µm", r->res.sigma_r_used_um);
    }
    fputs("</tr>\n<tr><th class=\"l\">residual RMS</th>", fp);
    html_num_cell(fp, "residual_rms_um", "%.4g µm", l->residual_rms_um);
    fprintf(fp, "</tr>\n<tr><th class=\"l\">scalar measurements / residual degrees of freedom</th>"
                "<td><span id=\"n_measurements\">%ld</span> / <span id=\"dof\">%ld</span></td></tr>\n",
            l->n_measurements, l->dof);
    /* the library's test of the stated noise (--sigma-r-um or the file's uncertainties) */
    double vf = l->weighted ? l->variance_factor : NAN, lo = l->chi2_lo, hi = l->chi2_hi;
    int pass = l->weighted && isfinite(vf) && l->dof > 0 && isfinite(lo) ? l->chi2_pass : -1;
    *chi2_pass = pass;
    fputs("<tr><th class=\"l\">variance factor σ̂²/σ² (weighted RSS / dof)</th>", fp);
    html_num_cell(fp, "variance_factor", "%.4f", vf);
    fputs("</tr>\n<tr><th class=\"l\">χ² test at 95 % (two-sided): accept if within</th>", fp);
    if (pass >= 0)
        fprintf(fp, "<td id=\"chi2_interval\">[%.4f, %.4f]</td></tr>\n<tr><th class=\"l\">χ² test</th>"
                    "<td id=\"chi2\" class=\"%s\">%s</td>",
                lo, hi, pass ? "pass" : "fail", pass ? "pass" : "fail");
    else
        fputs("<td>—</td></tr>\n<tr><th class=\"l\">χ² test</th><td id=\"chi2\">not applicable</td>", fp);
    if (l->view_noise_estimated) {
        fputs("</tr>\n<tr><th class=\"l\">each view's noise, estimated from its residuals "
              "(variance components), views in file order</th><td id=\"view_sigma_um\">",
              fp);
        for (int v = 0; v < r->d.plan.n_views; ++v)
            fprintf(fp, "%s%.4g", v ? ", " : "", l->view_sigma_um[v]);
        fputs(" µm</td></tr>\n<tr><th class=\"l\">their standard uncertainties</th>"
              "<td id=\"view_sigma_u_um\">", fp);
        for (int v = 0; v < r->d.plan.n_views; ++v)
            fprintf(fp, "%s%.2g", v ? ", " : "", l->view_sigma_u_um[v]);
        fputs(" µm</td>", fp);
    }
    fputs("</tr>\n</table>\n", fp);
    if (l->view_noise_estimated)
        fputs("<p class=\"note\">Each view's noise was estimated from its own residuals "
              "(--view-noise estimate): the views are weighted by it and the uncertainties use "
              "it, so the variance factor is 1 by construction and there is nothing to test.</p>\n",
              fp);
    else if (pass < 0)
        fputs("<p class=\"note\">No noise level was stated (neither --sigma-r-um nor uncertainties "
              "in the file), so σ_r is estimated from the residuals and the variance factor is 1 "
              "by construction: there is nothing to test. Give the instrument's σ_r to test it.</p>\n",
              fp);
    else if (!pass)
        fputs("<p class=\"note\">The residuals do not agree with the stated noise: either σ_r is "
              "wrong, the data hold outliers (below), or the model misses an effect (drift, "
              "thermal expansion, a plate that moved between views).</p>\n",
              fp);
    fputs("</section>\n", fp);
}

typedef struct worst {
    int v, i, j;
    double r, rx, ry, t;
} worst;

static int cmp_worst(const void *a, const void *b)
{
    double x = ((const worst *)a)->r, y = ((const worst *)b)->r;
    return x < y ? 1 : x > y ? -1 : 0;
}

/* The per-view table of residuals; the flagged and the measured counts out. */
static void residual_table(FILE *fp, const grid_report *r, long *flagged, long *measured)
{
    const sc_grid_plan *p = &r->d.plan;
    const int n = p->n;
    const size_t nn = NSQ(r);
    long n_flag = 0, n_all = 0;
    for (int v = 0; v < p->n_views; ++v) {
        double sx = 0, sy = 0, mx = -1;
        long cnt = 0, fl = 0;
        size_t kmax = 0;
        for (size_t k = 0; k < nn; ++k) {
            double a = r->rx[v * nn + k], b = r->ry[v * nn + k];
            if (!isfinite(a) || !isfinite(b))
                continue;
            sx += a * a;
            sy += b * b;
            cnt++;
            if (hypot(a, b) > mx)
                mx = hypot(a, b), kmax = k;
            if (sc_grid_outlier_beyond(&r->lres, r->tx[v * nn + k]) ||
                sc_grid_outlier_beyond(&r->lres, r->ty[v * nn + k]))
                fl++;
        }
        n_flag += fl;
        n_all += cnt;
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "<tr><td>%d</td><td>%d</td><td>%d, %d</td><td>%ld</td>", r->info.view_id[v],
                w->rot_deg, w->shift_x, w->shift_y, cnt);
        char id[48];
        snprintf(id, sizeof id, "rms-rx-%d", v);
        html_num_cell(fp, id, "%.4g", cnt ? sqrt(sx / cnt) : NAN);
        snprintf(id, sizeof id, "rms-ry-%d", v);
        html_num_cell(fp, id, "%.4g", cnt ? sqrt(sy / cnt) : NAN);
        html_num_cell(fp, NULL, "%.4g", cnt ? mx : NAN);
        int ni = 0, nj = 0;
        if (cnt && sc_grid_mark_node(p, v, (int)(kmax / n), (int)(kmax % n), &ni, &nj))
            fprintf(fp, "<td class=\"l\">(%g, %g)</td>", sc_stage_map_x_mm(&r->gm, nj),
                    sc_stage_map_y_mm(&r->gm, ni));
        else
            fputs("<td class=\"l\">—</td>", fp);
        fprintf(fp, "<td>%ld</td></tr>\n", fl);
    }
    *flagged = n_flag;
    *measured = n_all;
}

/* The histograms of the residual components and of the standardized residuals; every measured
 * mark into ws (*nw of them); all: 2 * views * N² doubles of work. */
static sc_status residual_histograms(FILE *fp, const grid_report *r, double *all, worst *ws,
                                     long *nw_out, sc_error *err)
{
    const sc_grid_plan *p = &r->d.plan;
    const int n = p->n;
    const size_t nn = NSQ(r);
    long m = 0, nw = 0;
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k) {
            double a = r->rx[v * nn + k], b = r->ry[v * nn + k];
            if (!isfinite(a) || !isfinite(b))
                continue;
            all[m++] = a;
            all[m++] = b;
            double t = fmax(fabs(r->tx[v * nn + k]), fabs(r->ty[v * nn + k]));
            ws[nw++] = (worst){v, (int)(k / n), (int)(k % n), hypot(a, b), a, b, t};
        }
    /* residuals spread less than the noise: E[Σr²] = σ²·dof over n_measurements components */
    double spread = r->lres.sigma_r_est_um *
                    sqrt((double)r->lres.dof / (double)(r->lres.n_measurements > 0 ? r->lres.n_measurements : 1));
    fig_hist fh = {all, m, spread, "residuals r_x and r_y of every measured mark (µm)",
                   "residual (µm)"};
    sc_status st = html_figure(fp, draw_hist, &fh,
                               "Histogram of the residual components with the normal density of "
                               "their expected spread, σ̂_r·√(dof / n) (residuals are smaller than "
                               "the noise by the leverage of each measurement).",
                               err);
    /* the standardized residuals: N(0, 1) when the model and the stated or estimated noise hold */
    long mt = 0;
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k) {
            if (isfinite(r->tx[v * nn + k]) && isfinite(r->ty[v * nn + k])) {
                all[mt++] = r->tx[v * nn + k];
                all[mt++] = r->ty[v * nn + k];
            }
        }
    fig_hist ft = {all, mt, 1.0, "standardized residuals t_x and t_y", "t = r / (σ·√(1 − h))"};
    char caption[256]; /* the test's own critical value (the Outliers section's) */
    double crit = r->lres.outlier_crit;
    snprintf(caption, sizeof caption,
             "Histogram of the standardized residuals with the standard normal density%s",
             crit > 0 && isfinite(crit) ? "" : ".");
    if (crit > 0 && isfinite(crit))
        snprintf(caption + strlen(caption), sizeof caption - strlen(caption),
                 "; beyond ±%.2f a measurement is flagged (Outliers, below).", crit);
    if (st == SC_OK && mt > 0)
        st = html_figure(fp, draw_hist, &ft, caption, err);
    *nw_out = nw;
    return st;
}

/* The ten worst measurements and Baarda's test. */
static void outlier_table(FILE *fp, const grid_report *r, worst *ws, long nw, long n_flag)
{
    qsort(ws, (size_t)nw, sizeof *ws, cmp_worst);
    fputs("<h3>Outliers</h3>\n", fp);
    const sc_grid_result *l = &r->lres;
    fprintf(fp, "<p>Baarda's data snooping: a measurement is flagged when a standardized residual "
                "|t| = |r|/(σ·√(1 − h)), h its leverage, exceeds <span id=\"outlier_crit\">%.4f"
                "</span> (two-sided; a mark seen in one view only has h = 1 and is not tested): ",
            l->outlier_crit);
    if (l->outlier_alpha_each)
        fprintf(fp, "significance %g for each coordinate on its own, so that about %.3g of the "
                    "%ld coordinates tested would be flagged on clean data. ",
                l->outlier_alpha, l->outlier_alpha * (double)l->n_outlier_tests, l->n_outlier_tests);
    else
        fprintf(fp, "significance %g for the whole data set (%ld coordinates tested, each at "
                    "%.3g: Šidák), so that clean data raise a flag in a fraction %g of "
                    "calibrations. ",
                l->outlier_alpha, l->n_outlier_tests, l->outlier_alpha_coord, l->outlier_alpha);
    fprintf(fp, "<b id=\"n_outliers\">%ld</b> measurement(s) flagged. <code>selfcal grid --method "
                "lsq --reject-outliers</code> removes them one by one and solves again.</p>\n",
            n_flag);
    fputs("<table id=\"worst-residuals\">\n<tr><th>view</th><th>mark i</th><th>mark j</th>"
          "<th>r<sub>x</sub> (µm)</th><th>r<sub>y</sub> (µm)</th><th>|r|/σ̂_r</th><th>max |t|</th>"
          "<th>flagged</th></tr>\n",
          fp);
    for (long q = 0; q < nw && q < 10; ++q) {
        const worst *w = &ws[q];
        fprintf(fp, "<tr><td>%d</td><td>%d</td><td>%d</td>", r->info.view_id[w->v], w->i, w->j);
        html_num_cell(fp, NULL, "%.4g", w->rx);
        html_num_cell(fp, NULL, "%.4g", w->ry);
        html_num_cell(fp, NULL, "%.2f", w->r / r->lres.sigma_r_est_um);
        html_num_cell(fp, NULL, "%.2f", w->t);
        int flag = sc_grid_outlier_beyond(&r->lres, w->t);
        fprintf(fp, "<td class=\"%s\">%s</td></tr>\n", flag ? "fail" : "",
                !isfinite(w->t) ? "not tested" : flag ? "yes" : "no");
    }
    fputs("</table>\n</section>\n", fp);
}

static sc_status section_residuals(FILE *fp, const grid_report *r, long *n_out, sc_error *err)
{
    const sc_grid_plan *p = &r->d.plan;
    fputs("<section id=\"residuals\">\n<h2>4. Residuals</h2>\n<p>Residual r = measured − fitted "
          "position of each mark in each view (least-squares fit).</p>\n<table id=\"residual-table\">\n"
          "<tr><th>view</th><th>rot</th><th>shift</th><th>marks</th><th>RMS r<sub>x</sub> (µm)</th>"
          "<th>RMS r<sub>y</sub> (µm)</th><th>max |r| (µm)</th><th class=\"l\">at node (x, y) mm</th>"
          "<th>flagged</th></tr>\n",
          fp);
    long n_flag, n_all, nw = 0;
    residual_table(fp, r, &n_flag, &n_all);
    fputs("</table>\n", fp);
    size_t nres = (size_t)p->n_views * NSQ(r);
    double *all = malloc(2 * nres * sizeof(double));
    worst *ws = malloc((size_t)(n_all > 0 ? n_all : 1) * sizeof(worst));
    if (!all || !ws) {
        free(all);
        free(ws);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    sc_status st = residual_histograms(fp, r, all, ws, &nw, err);
    free(all);
    if (st == SC_OK)
        outlier_table(fp, r, ws, nw, n_flag);
    free(ws);
    *n_out = n_flag;
    return st;
}

static double rms_of(const double *v, size_t n, double *max_abs)
{
    double s = 0, mx = 0;
    size_t c = 0;
    for (size_t k = 0; k < n; ++k)
        if (isfinite(v[k])) {
            s += v[k] * v[k];
            mx = fmax(mx, fabs(v[k]));
            c++;
        }
    if (max_abs)
        *max_abs = c ? mx : NAN;
    return c ? sqrt(s / c) : NAN;
}

/* O, R and every view's misalignment with their uncertainties. */
static void results_first_order(FILE *fp, const grid_report *r)
{
    const sc_grid_plan *p = &r->d.plan;
    const sc_grid_result *s = &r->res;
    const double uO = s->uO, uR = s->uR;
    /* ids O and R (their values in µrad and ppm, as the summary's O_urad and R_ppm) */
    html_u_row(fp, "O, non-orthogonality (Petrò eq. 4)", "O", s->O * 1e6, uO * 1e6, "%.5g", "µrad");
    html_u_row(fp, "R, scale (Petrò eq. 5)", "R", s->R * 1e6, uR * 1e6, "%.5g", "ppm (µm/m)");
    for (int v = 0; v < p->n_views; ++v) {
        const double ut = s->utx_um[v], uu = s->uty_um[v], uth = s->utheta_urad[v];
        char name[96], id[32];
        snprintf(name, sizeof name, "view %d: tx", r->info.view_id[v]);
        snprintf(id, sizeof id, "tx-%d", v);
        html_u_row(fp, name, id, s->tx_um[v], ut, "%.5g", "µm");
        snprintf(name, sizeof name, "view %d: ty", r->info.view_id[v]);
        snprintf(id, sizeof id, "ty-%d", v);
        html_u_row(fp, name, id, s->ty_um[v], uu, "%.5g", "µm");
        snprintf(name, sizeof name, "view %d: θ", r->info.view_id[v]);
        snprintf(id, sizeof id, "theta-%d", v);
        html_u_row(fp, name, id, s->theta_urad[v], uth, "%.5g", "µrad");
    }
    fputs("</table>\n", fp);
    if (!isfinite(uO))
        fputs("<p class=\"note\">The closed forms give no uncertainties of O, R and the "
              "misalignments (—); use --method lsq.</p>\n",
              fp);
}

/* The statistics of G, u(G) and A. */
static void results_g_table(FILE *fp, const grid_report *r)
{
    const sc_grid_result *s = &r->res;
    const size_t nn = NSQ(r);
    double mgx, mgy, mux, muy, ma;
    size_t ng = NG(r);
    double rgx = rms_of(s->gx_um, ng, &mgx), rgy = rms_of(s->gy_um, ng, &mgy);
    double rux = rms_of(s->ugx_um, ng, &mux), ruy = rms_of(s->ugy_um, ng, &muy);
    double rax = rms_of(s->ax_um, nn, &ma), ray = rms_of(s->ay_um, nn, NULL);
    fputs("<h3>Stage error G</h3>\n<table>\n<tr><th class=\"l\">quantity</th><th>RMS</th>"
          "<th>max |·|</th><th class=\"l\">unit</th></tr>\n",
          fp);
    fputs("<tr><td class=\"l\">G<sub>x</sub></td>", fp);
    html_num_cell(fp, "gx-rms", "%.4g", rgx);
    html_num_cell(fp, "gx-max", "%.4g", mgx);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">G<sub>y</sub></td>", fp);
    html_num_cell(fp, "gy-rms", "%.4g", rgy);
    html_num_cell(fp, "gy-max", "%.4g", mgy);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">u(G<sub>x</sub>), k = 1</td>", fp);
    html_num_cell(fp, "ugx-rms", "%.4g", rux);
    html_num_cell(fp, "ugx-max", "%.4g", mux);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">u(G<sub>y</sub>), k = 1</td>", fp);
    html_num_cell(fp, "ugy-rms", "%.4g", ruy);
    html_num_cell(fp, "ugy-max", "%.4g", muy);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">U(G<sub>x</sub>) = 2u, k = 2</td>", fp);
    html_num_cell(fp, "Ugx-rms", "%.4g", 2 * rux);
    html_num_cell(fp, "Ugx-max", "%.4g", 2 * mux);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">U(G<sub>y</sub>) = 2u, k = 2</td>", fp);
    html_num_cell(fp, "Ugy-rms", "%.4g", 2 * ruy);
    html_num_cell(fp, "Ugy-max", "%.4g", 2 * muy);
    fputs("<td class=\"l\">µm</td></tr>\n<tr><td class=\"l\">plate error A<sub>x</sub>, A<sub>y</sub> (RMS)</td>", fp);
    html_num_cell(fp, "ax-rms", "%.4g", rax);
    html_num_cell(fp, "ay-rms", "%.4g", ray);
    fputs("<td class=\"l\">µm</td></tr>\n</table>\n", fp);

}

/* The figures: G as arrows and colour maps, u(G) where known, A as arrows. */
static sc_status results_figures(FILE *fp, const grid_report *r, sc_error *err)
{
    const sc_grid_result *s = &r->res;
    fig_ar far = {&r->gm, 0, "stage error G (arrows)", "G"};
    sc_status st = html_figure(fp, draw_ar, &far, "The stage error map G at the stage nodes.", err);
    fig_cm cgx = {&r->gm, 0, s->gx_um, "Gx (µm)", "µm", 1};
    fig_cm cgy = {&r->gm, 0, s->gy_um, "Gy (µm)", "µm", 1};
    if (st == SC_OK)
        st = html_figure(fp, draw_cm, &cgx, "Gx as a colour map.", err);
    if (st == SC_OK)
        st = html_figure(fp, draw_cm, &cgy, "Gy as a colour map.", err);
    if (st == SC_OK && sc_stage_map_has_u(&r->gm)) {
        fig_cm cux = {&r->gm, 0, s->ugx_um, "u(Gx), k = 1 (µm)", "µm", 0};
        fig_cm cuy = {&r->gm, 0, s->ugy_um, "u(Gy), k = 1 (µm)", "µm", 0};
        st = html_figure(fp, draw_cm, &cux,
                         "Standard uncertainty of Gx (k = 1); the expanded uncertainty (k = 2) is twice it.",
                         err);
        if (st == SC_OK)
            st = html_figure(fp, draw_cm, &cuy,
                             "Standard uncertainty of Gy (k = 1); the expanded uncertainty (k = 2) is twice it.",
                             err);
    } else if (st == SC_OK)
        fputs("<p class=\"note\">No uncertainty map: the closed-form methods give none (use "
              "--method lsq).</p>\n",
              fp);
    fig_ar fa = {&r->am, 1, "plate error A (arrows, plate frame)", "A"};
    if (st == SC_OK)
        st = html_figure(fp, draw_ar, &fa,
                         "The plate error A at the plate's marks (plate frame), as separated from G.",
                         err);
    return st;
}

/* The plate's scale and temperature (SPEC §11) and the budget at the worst node. */
static void results_scale(FILE *fp, const grid_report *r)
{
    const sc_grid_plan *p = &r->d.plan;
    int lsq = sc_grid_method_from_name(r->method) == SC_GRID_METHOD_LSQ;
    const sc_grid_budget *b = lsq ? &r->lsol.budget : &r->sol.budget;
    fputs("<h3>Scale, temperature and uncertainty budget</h3>\n", fp);
    if (!b->applies || !b->magnification)
        fputs("<p><b>Scale not included.</b> The file gives no certified plate scale ('# "
              "plate_scale_ppm = E, U'): self-calibration cannot tell the stage's isotropic "
              "scale from the plate's, so G carries no magnification (SPEC §1 gauge) and the "
              "stage's scale error is not in G or its uncertainty.</p>\n",
              fp);
    if (!b->applies)
        return;
    fputs("<table>\n<tr><th class=\"l\">quantity</th><th>value</th><th>u (k = 1)</th>"
          "<th>U (k = 2)</th><th class=\"l\">unit</th></tr>\n", fp);
    if (b->magnification)
        html_u_row(fp, "M, the stage's magnification", "magnification", b->magnification_ppm,
                   b->u_magnification_ppm, "%.5g", "ppm");
    for (int v = 0; v < p->n_views; ++v) {
        char name[96], id[32];
        snprintf(name, sizeof name, "view %d: plate scale s_v%s", r->info.view_id[v],
                 p->scale.has_temps ? " = E + A·(T_v − 20)" : "");
        snprintf(id, sizeof id, "scale-%d", v);
        html_u_row(fp, name, id, b->view_scale_ppm[v],
                   b->view_scale_free ? b->u_view_scale_free_ppm[v] : NAN, "%.5g", "ppm");
    }
    fputs("</table>\n", fp);
    if (b->view_scale_free)
        fprintf(fp, "<p>The views' scales are free (--view-scale free): their mean is the "
                       "plate's model scale, χ² of their differences %.4g (95 %% limit %.4g): "
                       "%s.</p>\n", b->view_scale_chi2, b->view_scale_chi2_crit,
                   b->view_scale_significant ? "significant" : "not significant");
    if (b->n_rows == 0)
        return;
    int nx = sc_grid_stage_nx(p);
    fprintf(fp, "<p>Budget (GUM) at node (%ld, %ld), %s, where the combined uncertainty is "
                   "largest:</p>\n<table>\n<tr><th class=\"l\">source</th><th>u</th>"
                   "<th class=\"l\">unit</th><th>sensitivity (µm per unit)</th>"
                   "<th>contribution (µm)</th><th>dof</th></tr>\n",
               b->worst_node / nx, b->worst_node % nx, b->worst_comp ? "G<sub>y</sub>" : "G<sub>x</sub>");
    for (int k = 0; k < b->n_rows; ++k) {
        const sc_grid_budget_row *w = &b->row[k];
        fprintf(fp, "<tr><td class=\"l\">%s</td>", w->source);
        html_num_cell(fp, NULL, "%.4g", w->u);
        fprintf(fp, "<td class=\"l\">%s</td>", w->unit);
        html_num_cell(fp, NULL, "%.4g", w->c);
        html_num_cell(fp, NULL, "%.4g", w->contrib_um);
        html_num_cell(fp, NULL, "%.4g", w->dof);
        fputs("</tr>\n", fp);
    }
    fprintf(fp, "</table>\n<p>Combined standard uncertainty u<sub>c</sub> = %.4g µm; "
                   "effective degrees of freedom %.4g; expanded U = %.4g µm with k = %.4g (%s).</p>\n",
               b->u_c_um, b->nu_eff, b->U_um, b->k,
               b->k_welch ? "Student's t at 95 % for the Welch–Satterthwaite degrees of freedom"
                          : "k = 2: the degrees of freedom are large");
}

static void uncertainty_statement(FILE *fp, const grid_report *r);

static sc_status section_results(FILE *fp, const grid_report *r, sc_error *err)
{
    fputs("<section id=\"results\">\n<h2>5. Results</h2>\n<h3>First-order terms and misalignments</h3>\n"
          "<table>\n<tr><th class=\"l\">quantity</th><th>value</th><th>u (k = 1)</th>"
          "<th>U (k = 2)</th><th class=\"l\">unit</th></tr>\n",
          fp);
    results_first_order(fp, r);
    results_scale(fp, r);
    results_g_table(fp, r);
    sc_status st = results_figures(fp, r, err);
    uncertainty_statement(fp, r);
    fputs("</section>\n", fp);
    return st;
}

/* The whole map as a table, every node (print repeats the header row on every page). */
static void appendix_table(FILE *fp, const grid_report *r)
{
    int nx = sc_grid_stage_nx(&r->d.plan), ny = sc_grid_stage_ny(&r->d.plan);
    fprintf(fp, "<p>The stage error at every one of the %d × %d nodes (the map file written by "
                "<code>selfcal grid --map</code> holds the same values).</p>\n", nx, ny);
    fputs("<table class=\"map\" id=\"node-table\">\n<thead><tr><th>i</th><th>j</th><th>x (mm)</th>"
          "<th>y (mm)</th><th>G<sub>x</sub> (µm)</th><th>G<sub>y</sub> (µm)</th>"
          "<th>u(G<sub>x</sub>) (µm)</th><th>u(G<sub>y</sub>) (µm)</th><th>U(G<sub>x</sub>), k = 2</th>"
          "<th>U(G<sub>y</sub>), k = 2</th></tr></thead>\n<tbody>\n",
          fp);
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j) {
            int k = i * nx + j;
            fprintf(fp, "<tr class=\"node\" data-i=\"%d\" data-j=\"%d\"><td>%d</td><td>%d</td><td>%g</td><td>%g</td>",
                    i, j, i, j, sc_stage_map_x_mm(&r->gm, j), sc_stage_map_y_mm(&r->gm, i));
            html_num_cell(fp, NULL, "%.5f", r->res.gx_um[k]);
            html_num_cell(fp, NULL, "%.5f", r->res.gy_um[k]);
            html_num_cell(fp, NULL, "%.5f", r->res.ugx_um[k]);
            html_num_cell(fp, NULL, "%.5f", r->res.ugy_um[k]);
            html_num_cell(fp, NULL, "%.5f", 2 * r->res.ugx_um[k]);
            html_num_cell(fp, NULL, "%.5f", 2 * r->res.ugy_um[k]);
            fputs("</tr>\n", fp);
        }
    fputs("</tbody>\n</table>\n", fp);
}

/* The statement of what U covers (SPEC §12), at the end of the results. */
static void uncertainty_statement(FILE *fp, const grid_report *r)
{
    fputs("<h3>Statement of uncertainty</h3>\n", fp);
    if (!sc_stage_map_has_u(&r->gm)) {
        fputs("<p id=\"uncertainty-statement\" class=\"statement\">The closed-form method "
              "gives no uncertainty of G: this report states none (use --method lsq).</p>\n", fp);
        return;
    }
    const char *noise =
        r->lres.stated_u
            ? "the measurement noise of the calibration data, as the file states it per "
              "measurement and scaled by the residuals (section 3), propagated through the "
              "least-squares estimate to every node of G, to O, R and to the misalignments"
            : "the measurement noise of the calibration data (σ_r used, section 3), propagated "
              "through the least-squares estimate to every node of G, to O, R and to the "
              "misalignments";
    const char *after = "the stage's drift and repeatability after the measurement, and the "
                        "interpolation of a table between the nodes.";
    /* with the plate's scale and temperature lines (SPEC §11) the map's u is the budget's */
    const sc_grid_budget *b = &r->lsol.budget;
    char covers[1024], excluded[512];
    if (b->applies && b->n_rows > 0) {
        snprintf(covers, sizeof covers, "%s; and, combined with it at every node (the budget of "
                 "section 'Scale, temperature and uncertainty budget'), the uncertainty of %s%s.",
                 noise, b->magnification ? "the plate's certified scale, " : "",
                 r->d.plan.scale.has_temps ? "the plate's expansion coefficient and the "
                                             "temperature of each view"
                                           : "the plate's expansion coefficient");
        snprintf(excluded, sizeof excluded, "Not included: %s%s",
                 b->magnification ? "" : "the scale of the plate (no certified scale was given: "
                                         "G carries no magnification), ",
                 after);
    } else {
        snprintf(covers, sizeof covers, "%s.", noise);
        snprintf(excluded, sizeof excluded, "Not included: the scale of the plate and its "
                 "thermal expansion (self-calibration cannot tell the stage's isotropic scale "
                 "from the plate's: G carries no magnification; the file gives no "
                 "'# plate_scale_ppm' and no temperatures), the temperatures of stage and plate "
                 "during the measurement, %s", after);
    }
    report_uncertainty_statement(fp, covers, excluded);
}

/* What the command line asks for: the report, the verification's options, the certificate's
 * information and the HTML output. */
typedef struct report_grid_args {
    grid_report r;
    sc_verify_opts vo;
    report_info ri;
    const char *out;
} report_grid_args;

#define F(field) offsetof(report_grid_args, field)
#define VERIFY_UM(name, text)                                                                      \
    {name, CLI_CUSTOM, F(vo), "U", 0, SC_INPUT_MAX_ABS, .parse = verify_parse_opt, .help = text}
/* report grid's options (cli_opts.h), in the order of its --help */
static const cli_opt REPORT_GRID_OPTS[] = {
    {"-o|--out", CLI_STRING, F(out), "R.html", .help = "the report (HTML)"},
    {"--pdf", CLI_CUSTOM, F(ri), "R.pdf", .parse = report_info_opt, .help = "the report as PDF"},
    {"--method", CLI_STRING, F(r.method), "lsq|ye|double-shift", .def = "lsq", .help = "the method"},
    {"--sigma-r-um", CLI_DOUBLE, F(r.sigma_r_given), "S", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .bad = "--sigma-r-um needs a positive number, got '%s'", .def = "estimated from the residuals",
     .help = "the measurement noise (um)"},
    {"--outlier-alpha", CLI_CUSTOM, F(r.test), "A", 0, 1, CLI_MIN_OPEN | CLI_MAX_OPEN,
     .parse = cli_opt_lsq, .def = "0.05", .help = "the outlier test's significance for the data set"},
    {"--outlier-alpha-each", CLI_CUSTOM, F(r.test), "A", 0, 1, CLI_MIN_OPEN | CLI_MAX_OPEN,
     .parse = cli_opt_lsq, .help = "the outlier test's significance for each coordinate"},
    {"--view-noise", CLI_CUSTOM, F(r.test), "stated|estimate", .choices = "stated|estimate",
     .parse = cli_opt_lsq, .def = "stated", .help = "each view's noise estimated"},
    {"--view-scale", CLI_CUSTOM, F(r.test), "model|free", .choices = "model|free",
     .parse = cli_opt_lsq, .def = "model", .help = "each view's scale an unknown"},
    {"--verify", CLI_STRING, F(r.verify_name), "V.csv", .help = "a re-measurement (with --table)"},
    {"--table", CLI_STRING, F(r.table_name), "T.lut", .help = "the table it was measured with"},
    {"--tolerance-um", CLI_DOUBLE, F(vo.tolerance_um), "T", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .bad = "--tolerance-um needs a positive number, got '%s'", .help = "the verdict's tolerance (um)"},
    {"--raw", CLI_FLAG, F(vo.raw), .help = "the re-measurement is of the uncompensated machine"},
    {"--decision-rule", CLI_CUSTOM, F(vo), "simple|guarded", .choices = "simple|guarded",
     .parse = verify_parse_opt, .help = "the verdict's decision rule"},
    VERIFY_UM("--u-verify-um", "the re-measurement's uncertainty (um)"),
    VERIFY_UM("--u-plate-um", "the plate error's uncertainty (um)"),
    VERIFY_UM("--verify-sigma-um", "the re-measurement's noise (um)"),
    {"--info", CLI_CUSTOM, F(ri), "KEY=VALUE", .parse = report_info_opt, .help = "a certificate field"},
    {"--info-file", CLI_CUSTOM, F(ri), "F", .parse = report_info_opt, .help = "certificate fields from a file"},
};
#undef VERIFY_UM
#undef F

const cli_cmd_opts cli_report_grid_opts = {
    "report grid", USAGE, REPORT_GRID_OPTS,
    (int)(sizeof REPORT_GRID_OPTS / sizeof REPORT_GRID_OPTS[0]), offsetof(report_grid_args, r.in),
    NULL, NULL, NULL, NULL, 0, NULL, NULL,
};

/* The command line into g: -1 to go on, else the exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, report_grid_args *g)
{
    const char *cmd = "report grid";
    memset(g, 0, sizeof *g);
    g->r.method = "lsq";
    sc_verify_opts_init(&g->vo);
    int rc = cli_opts_parse(&cli_report_grid_opts, argc, argv, g);
    if (rc >= 0)
        return rc;
    grid_report *r = &g->r;
    if (!r->in || (!g->out && !g->ri.pdf))
        return cli_usage_error(cmd, "IN.csv and -o R.html or --pdf R.pdf are required (see --help)");
    if (strcmp(r->method, "lsq") && strcmp(r->method, "ye") && strcmp(r->method, "double-shift"))
        return cli_usage_error(cmd, "--method must be lsq, ye or double-shift (got '%s')", r->method);
    if (!r->verify_name != !r->table_name)
        return cli_usage_error(cmd, "--verify and --table go together (see --help)");
    if (r->test.estimate_view_noise && r->sigma_r_given > 0)
        return cli_usage_error(cmd, "--sigma-r-um and --view-noise estimate exclude each other "
                                    "(a given noise, or each view's estimated)");
    return -1;
}

/* Title and the summary paragraph (its numbers from the run and the verification). */
/* The page head: title, the printed pages' label, the certificate block. */
static void report_head(FILE *fp, const grid_report *r, const report_info *ri)
{
    char title[600];
    snprintf(title, sizeof title, "Grid plate self-calibration report — %s", cli_basename(r->in));
    html_begin(fp, title);
    report_page_css(fp, ri);
    fputs("<h1>", fp);
    html_esc(fp, title);
    fputs("</h1>\n", fp);
    report_info_html(fp, ri, "report");
}

static void report_summary(FILE *fp, const grid_report *r, const sc_verify_result *vr)
{
    double mux, muy;
    rms_of(r->res.ugx_um, NG(r), &mux);
    rms_of(r->res.ugy_um, NG(r), &muy);
    fprintf(fp, "<div class=\"summary\" id=\"summary\"><p>Method <b>%s</b>; N = %d, pitch %g mm, "
                "%d views, %ld measured marks. G identified: <b>%s</b>. %s",
            r->method, r->d.plan.n, r->d.plan.pitch_mm, r->d.plan.n_views, r->info.n_rows,
            r->identifiable ? "yes" : "no",
            r->lres.stated_u ? "The residuals' scale on the file's stated uncertainties "
                             : "σ_r estimated ");
    html_num_span(fp, NULL, "%.4g", r->lres.sigma_r_est_um);
    if (!r->lres.stated_u) {
        fputs(" µm", fp);
        if (r->sigma_r_given > 0)
            fprintf(fp, " (given %.4g µm)", r->sigma_r_given);
    }
    fputs(".", fp);
    if (isfinite(mux))
        fprintf(fp, " Largest u(G): %.4g µm (k = 1), U = %.4g µm (k = 2).", fmax(mux, muy),
                2 * fmax(mux, muy));
    if (r->verify_name && vr->verdict != SC_VERIFY_NO_VERDICT)
        fprintf(fp, " Verification: <b class=\"%s\">%s</b> (%s rule).",
                vr->verdict == SC_VERIFY_PASS ? "pass" : vr->verdict == SC_VERIFY_FAIL ? "fail" : "inconclusive",
                sc_verify_verdict_name(vr->verdict), sc_verify_rule_name(vr->rule));
    fputs("</p></div>\n", fp);
}

/* The whole report into fp: summary, sections 1-6, provenance, appendix. */
static sc_status write_report(FILE *fp, const grid_report *r, const sc_verify_opts *vo,
                              const sc_verify_result *vr, const report_info *ri, int argc,
                              char **argv, sc_error *err)
{
    report_head(fp, r, ri);
    report_summary(fp, r, vr);
    section_plan(fp, r);
    section_method(fp, r);
    int chi2;
    section_noise(fp, r, &chi2);
    long n_out = 0;
    sc_status st = section_residuals(fp, r, &n_out, err);
    if (st == SC_OK)
        st = section_results(fp, r, err);
    if (st == SC_OK && r->verify_name)
        st = verify_html_section(fp, vo, r->verify_name, vr,
                                 "6. Verification of the compensated machine", err);
    const cli_input *inputs[3] = {r->src, r->vsrc[0], r->vsrc[1]};
    const char *roles[3] = {"measurement (selfcal-grid v1)", "re-measurement (verify)",
                            "lookup table (verify)"};
    if (st == SC_OK)
        st = html_provenance(fp, argc + 1, argv - 1, inputs, roles, r->verify_name ? 3 : 1, err);
    if (st == SC_OK) {
        fputs("<h2>Appendix</h2>\n", fp);
        appendix_table(fp, r);
        html_end(fp);
    }
    return st;
}

int cmd_report_grid(int argc, char **argv)
{
    report_grid_args g;
    int rc = parse_args(argc, argv, &g);
    if (rc >= 0)
        return rc;
    grid_report *rp = &g.r;
    sc_verify_opts *vop = &g.vo;
    report_info *rip = &g.ri;
    const char *out = g.out;
    sc_error err;
    sc_error_clear(&err);
    cli_input src[3]; /* pipes read once, into memory, hashed on the way */
    const char *names[3] = {rp->in, rp->verify_name, rp->table_name};
    int opened = 0;
    report_out ro;
    memset(&ro, 0, sizeof ro);
    sc_status st = report_info_load(rip, &err);
    if (st == SC_OK)
        st = report_out_prepare(&ro, rip, out, &err); /* Chromium first: nothing written without */
    if (st == SC_OK)
        st = cli_input_open_all(src, names, rp->verify_name ? 3 : 1, 1u << 2 /* the table */,
                                &opened, &err);
    rp->src = &src[0];
    if (rp->verify_name)
        rp->vsrc[0] = &src[1], rp->vsrc[1] = &src[2];
    if (st == SC_OK)
        st = run(rp, &err);
    sc_verify_result vr;
    memset(&vr, 0, sizeof vr);
    if (st == SC_OK && rp->verify_name) {
        vop->plate = &rp->am;
        vop->measurement = src[1].path, vop->table = src[2].path;
        st = sc_verify_run(vop, &vr, &err);
    }
    sc_afile f;
    memset(&f, 0, sizeof f);
    if (st == SC_OK)
        st = sc_afile_open(&f, ro.html, &err);
    if (st == SC_OK) {
        st = write_report(f.fp, rp, vop, &vr, rip, argc, argv, &err);
        st = sc_afile_finish(&f, st, &err);
        st = report_out_finish(&ro, rip, st, &err);
    } else if (ro.temp)
        unlink(ro.html);
    sc_verify_result_free(&vr);
    free_report(rp);
    report_info_free(rip);
    rc = CLI_OK;
    if (st != SC_OK) {
        if (!err.file[0] && (err.code == SC_E_INPUT || err.code == SC_E_UNSOLVABLE))
            snprintf(err.file, sizeof err.file, "%s", rp->in);
        rc = cli_report(&err);
    }
    cli_input_close_all(src, opened);
    return rc;
}
