/* selfcal plot profile — charts of a profile result: f, its uncertainty, its error against a
 * truth file, and the stage's e_y; optionally a second result to compare. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/atomic_file.h"
#include "selfcal/profile.h"
#include "plots.h"
#include "svg.h"


static const char *COL_A = "#1f5fbf", *COL_B = "#d9731a", *COL_T = "#222222", *COL_U = "#999999";

static void range_of(const double *v, int n, double scale, double *lo, double *hi)
{
    for (int i = 0; v && i < n; ++i)
        if (isfinite(v[i])) {
            double x = v[i] * scale;
            if (x < *lo)
                *lo = x;
            if (x > *hi)
                *hi = x;
        }
}

static int any_finite(const double *v, int n)
{
    for (int i = 0; v && i < n; ++i)
        if (isfinite(v[i]))
            return 1;
    return 0;
}

/* a little headroom, then round numbers */
static void pad_nice(double *lo, double *hi)
{
    double span = *hi - *lo;
    if (span > 0) {
        if (*lo != 0)
            *lo -= 0.04 * span;
        *hi += 0.04 * span;
    }
    svg_nice_range(lo, hi);
}

/* scaled copy into buf */
static const double *scaled(const double *v, int n, double s, double *buf)
{
    for (int i = 0; i < n; ++i)
        buf[i] = v[i] * s;
    return buf;
}

/* A second profile whose length differs from the first: bad input, naming both files. */
static int report_length_mismatch(sc_error *err, const char *path, int n, int n_main, const char *main_path)
{
    sc_error_set(err, SC_E_INPUT, path, 0, "%d points, but %s has %d: not the same profile", n,
                 main_path, n_main);
    return cli_report(err);
}

/* What every panel of the profile plot shares. */
typedef struct {
    FILE *fp;
    const sc_profile_result *a, *truth, *cmp;
    const char *la, *lb; /* legend labels of a and cmp */
    int W, PH;           /* width, panel height (px) */
    double xmin, xmax;
    double *b1, *b2, *b3; /* n doubles each */
} plot_panels;

/* A panel's chart at height y0: y from lo to hi (widened to nice ticks), x along the profile. */
static void panel_chart(const plot_panels *P, svg_chart *c, double y0, double lo, double hi,
                        const char *ylabel, const char *title)
{
    pad_nice(&lo, &hi);
    svg_chart_init(c, P->fp, 80, y0 + 30, P->W - 110, P->PH, P->xmin, P->xmax, lo, hi);
    svg_axes(c, "x (mm)", ylabel, title);
}

/* The profile f with its k = 1 and k = 2 bands, the truth and the compared profile. */
static void panel_profile(const plot_panels *P, double y0)
{
    FILE *fp = P->fp;
    const sc_profile_result *a = P->a, *truth = P->truth, *cmp = P->cmp;
    const int n = a->n;
    const char *la = P->la, *lb = P->lb;
    double *b1 = P->b1, *b2 = P->b2;
    svg_chart c;
    double lo = INFINITY, hi = -INFINITY;
    int band = any_finite(a->uf_um, n);
    for (int i = 0; i < n; ++i) { /* f ± U (k = 2) in b1/b2, then f ± u (k = 1) */
        double u = a->uf_um ? a->uf_um[i] : NAN;
        b1[i] = a->f_um[i] - 2 * u;
        b2[i] = a->f_um[i] + 2 * u;
    }
    range_of(a->f_um, n, 1, &lo, &hi);
    if (band) {
        range_of(b1, n, 1, &lo, &hi);
        range_of(b2, n, 1, &lo, &hi);
    }
    if (truth)
        range_of(truth->f_um, n, 1, &lo, &hi);
    if (cmp)
        range_of(cmp->f_um, n, 1, &lo, &hi);
    panel_chart(P, &c, y0, lo, hi, "f (µm)", "profile f, relative to its least-squares line");
    int k = 0;
    if (band) {
        svg_band(&c, a->x_mm, b1, b2, n, COL_A, 0.15);
        for (int i = 0; i < n; ++i) {
            b1[i] = a->f_um[i] - a->uf_um[i];
            b2[i] = a->f_um[i] + a->uf_um[i];
        }
        svg_band(&c, a->x_mm, b1, b2, n, COL_A, 0.30);
        double umax = 0;
        for (int i = 0; i < n; ++i)
            if (isfinite(a->uf_um[i]) && a->uf_um[i] > umax)
                umax = a->uf_um[i];
        svg_text(fp, c.x + 8, c.y + 16, 11, "start", "#333",
                 "bands: f ± u(f) (k = 1, dark) and f ± 2u(f) (k = 2, light); max u(f) = %.3g nm",
                 umax * 1e3);
    }
    if (truth) {
        svg_polyline(&c, truth->x_mm, truth->f_um, n, COL_T, 1.2, "5,3");
        svg_legend(&c, k++, "truth", COL_T, "5,3");
    }
    svg_polyline(&c, a->x_mm, a->f_um, n, COL_A, 1.5, NULL);
    svg_legend(&c, k++, la, COL_A, NULL);
    if (cmp) {
        svg_polyline(&c, cmp->x_mm, cmp->f_um, n, COL_B, 1.2, "2,2");
        svg_legend(&c, k++, lb, COL_B, "2,2");
    }
}

/* The standard uncertainty u(f) in nm. */
static void panel_uncertainty(const plot_panels *P, double y0)
{
    const sc_profile_result *a = P->a, *cmp = P->cmp;
    const int n = a->n;
    const char *la = P->la, *lb = P->lb;
    double *b1 = P->b1;
    svg_chart c;
    double lo = 0, hi = -INFINITY;
    range_of(a->uf_um, n, 1e3, &lo, &hi);
    if (cmp)
        range_of(cmp->uf_um, n, 1e3, &lo, &hi);
    panel_chart(P, &c, y0, lo, hi, "u(f) (nm)", "standard uncertainty of f (k = 1)");
    int k = 0;
    if (any_finite(a->uf_um, n)) {
        svg_polyline(&c, a->x_mm, scaled(a->uf_um, n, 1e3, b1), n, COL_A, 1.5, NULL);
        svg_legend(&c, k++, la, COL_A, NULL);
    }
    if (cmp && any_finite(cmp->uf_um, n)) {
        svg_polyline(&c, cmp->x_mm, scaled(cmp->uf_um, n, 1e3, b1), n, COL_B, 1.5, "6,3");
        svg_legend(&c, k++, lb, COL_B, "6,3");
    }
}

/* The error of f against the truth, with ± u(f). */
static void panel_error(const plot_panels *P, double y0)
{
    const sc_profile_result *a = P->a, *truth = P->truth, *cmp = P->cmp;
    const int n = a->n;
    const char *la = P->la, *lb = P->lb;
    double *b1 = P->b1, *b2 = P->b2, *b3 = P->b3;
    svg_chart c;
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < n; ++i) {
        b1[i] = (a->f_um[i] - truth->f_um[i]) * 1e3;
        b2[i] = a->uf_um ? a->uf_um[i] * 1e3 : NAN;
        b3[i] = -b2[i];
    }
    range_of(b1, n, 1, &lo, &hi);
    range_of(b2, n, 1, &lo, &hi);
    range_of(b3, n, 1, &lo, &hi);
    if (cmp)
        for (int i = 0; i < n; ++i) {
            double e = (cmp->f_um[i] - truth->f_um[i]) * 1e3;
            if (isfinite(e))
                lo = e < lo ? e : lo, hi = e > hi ? e : hi;
        }
    panel_chart(P, &c, y0, lo, hi, "error (nm)", "error of f against the truth");
    int k = 0;
    svg_polyline(&c, a->x_mm, b1, n, COL_A, 1.2, NULL);
    svg_legend(&c, k++, la, COL_A, NULL);
    if (any_finite(b2, n)) {
        svg_polyline(&c, a->x_mm, b2, n, COL_U, 1.0, "4,3");
        svg_polyline(&c, a->x_mm, b3, n, COL_U, 1.0, "4,3");
        svg_legend(&c, k++, "± u(f)", COL_U, "4,3");
    }
    if (cmp) {
        for (int i = 0; i < n; ++i)
            b1[i] = (cmp->f_um[i] - truth->f_um[i]) * 1e3;
        svg_polyline(&c, cmp->x_mm, b1, n, COL_B, 1.0, "2,2");
        svg_legend(&c, k++, lb, COL_B, "2,2");
    }
}

/* The stage's straightness motion error e_y. */
static void panel_motion(const plot_panels *P, double y0)
{
    const sc_profile_result *a = P->a, *truth = P->truth;
    const int n = a->n;
    const char *la = P->la;
    svg_chart c;
    double lo = INFINITY, hi = -INFINITY;
    range_of(a->ey_um, n, 1, &lo, &hi);
    if (truth)
        range_of(truth->ey_um, n, 1, &lo, &hi);
    panel_chart(P, &c, y0, lo, hi, "e_y (µm)", "stage straightness motion error e_y (scan 1)");
    int k = 0;
    if (truth && any_finite(truth->ey_um, n)) {
        svg_polyline(&c, truth->x_mm, truth->ey_um, n, COL_T, 1.2, "5,3");
        svg_legend(&c, k++, "truth", COL_T, "5,3");
    }
    svg_polyline(&c, a->x_mm, a->ey_um, n, COL_A, 1.5, NULL);
    svg_legend(&c, k++, la, COL_A, NULL);
}

sc_status profile_plot_svg(FILE *fp, const sc_profile_result *a, const sc_profile_result *truth,
                           const sc_profile_result *cmp, const profile_plot_opts *o, sc_error *err)
{
    const int n = a->n;
    if (truth && truth->n != n)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "truth has %d points, the profile %d", truth->n, n);
    if (cmp && cmp->n != n)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the compared profile has %d points, the profile %d",
                            cmp->n, n);
    int uonly = o && o->uncertainty_only;
    int p_f = !uonly, p_u = any_finite(a->uf_um, n) || (cmp && any_finite(cmp->uf_um, n));
    int p_e = !uonly && truth, p_y = !uonly && any_finite(a->ey_um, n);
    int panels = p_f + p_u + p_e + p_y;
    if (!panels)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "nothing to plot (no uncertainty column)");
    double *b1 = malloc((size_t)n * sizeof(double) * 3);
    if (!b1)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    plot_panels P = {fp, a, truth, cmp,
                     o && o->label_a ? o->label_a : "profile",
                     o && o->label_b ? o->label_b : "compare",
                     900, 250, a->x_mm[0], a->x_mm[n - 1], b1, b1 + n, b1 + 2 * n};
    const int top = o && o->title ? 40 : 15;
    const int H = top + panels * (P.PH + 80) + 10;
    svg_begin(fp, P.W, H);
    if (o && o->title)
        svg_text_fit(fp, P.W / 2.0, 26, 16, P.W - 20, "middle", "#000", "%s", o->title);
    double y0 = top;
    void (*const draw[4])(const plot_panels *, double) = {panel_profile, panel_uncertainty,
                                                          panel_error, panel_motion};
    const int shown[4] = {p_f, p_u, p_e, p_y};
    for (int k = 0; k < 4; ++k)
        if (shown[k]) {
            draw[k](&P, y0);
            y0 += P.PH + 80;
        }
    svg_end(fp);
    free(b1);
    return SC_OK;
}

sc_status profile_plot_write(const char *path, const sc_profile_result *a,
                             const sc_profile_result *truth, const sc_profile_result *cmp,
                             const profile_plot_opts *o, sc_error *err)
{
    sc_afile af;
    sc_status st = sc_afile_open(&af, path, err);
    if (st != SC_OK)
        return st;
    st = profile_plot_svg(af.fp, a, truth, cmp, o, err);
    if (st != SC_OK) {
        sc_afile_abort(&af);
        return st;
    }
    return sc_afile_commit(&af, err); /* a write that failed: "write error: <reason>" */
}

static const char USAGE[] =
    "usage: selfcal plot profile P.csv -o p.svg [--truth T.csv] [--compare Q.csv]\n"
    "                            [--label A] [--compare-label B] [--title T] [--uncertainty-only]\n"
    "\n"
    "Charts of a profile result (n,x_mm,f_um,uf_um,ey_um): f, u(f), the error against a truth\n"
    "file (selfcal simulate profile --truth) and e_y.\n";

/* What the command line asks for. */
typedef struct plot_profile_args {
    const char *in, *out, *tpath, *cpath;
    profile_plot_opts o;
} plot_profile_args;

#define F(field) offsetof(plot_profile_args, field)
/* plot profile's options (cli_opts.h), in the order of its --help */
static const cli_opt PLOT_PROFILE_OPTS[] = {
    {"-o|--out", CLI_STRING, F(out), "p.svg", .help = "the plot (SVG)"},
    {"--truth", CLI_STRING, F(tpath), "T.csv", .help = "the true profile: the error against it"},
    {"--compare", CLI_STRING, F(cpath), "Q.csv", .help = "a second result drawn beside"},
    {"--label", CLI_STRING, F(o.label_a), "A", .help = "the result's name in the legend"},
    {"--compare-label", CLI_STRING, F(o.label_b), "B", .help = "the second result's name"},
    {"--title", CLI_STRING, F(o.title), "T", .help = "the chart's title"},
    {"--uncertainty-only", CLI_FLAG, F(o.uncertainty_only), .help = "only the u(f) chart"},
};
#undef F

const cli_cmd_opts cli_plot_profile_opts = {
    "plot profile", USAGE, PLOT_PROFILE_OPTS,
    (int)(sizeof PLOT_PROFILE_OPTS / sizeof PLOT_PROFILE_OPTS[0]), offsetof(plot_profile_args, in),
    NULL, "more than one input file (%s, %s)", "unknown option or missing value: %s (see --help)",
    "unknown option or missing value: %s (see --help)", 0, NULL, NULL,
};

int cmd_plot_profile(int argc, char **argv)
{
    const char *cmd = "plot profile";
    plot_profile_args p;
    memset(&p, 0, sizeof p);
    int rc = cli_opts_parse(&cli_plot_profile_opts, argc, argv, &p);
    if (rc >= 0)
        return rc;
    const char *in = p.in, *out = p.out, *tpath = p.tpath, *cpath = p.cpath;
    profile_plot_opts o = p.o;
    if (!in || !out) {
        return cli_usage_error(cmd, "IN.csv and -o OUT.svg are required (see --help)");
    }
    sc_error err;
    sc_error_clear(&err);
    sc_profile_result a, t, c;
    memset(&t, 0, sizeof t);
    memset(&c, 0, sizeof c);
    if (sc_profile_read_result(in, &a, &err) != SC_OK)
        return cli_report(&err);
    rc = CLI_OK;
    if ((tpath && sc_profile_read_result(tpath, &t, &err) != SC_OK) ||
        (cpath && sc_profile_read_result(cpath, &c, &err) != SC_OK))
        rc = cli_report(&err);
    else if (tpath && t.n != a.n)
        rc = report_length_mismatch(&err, tpath, t.n, a.n, in);
    else if (cpath && c.n != a.n)
        rc = report_length_mismatch(&err, cpath, c.n, a.n, in);
    else if (profile_plot_write(out, &a, tpath ? &t : NULL, cpath ? &c : NULL, &o, &err) != SC_OK) {
        if (err.code == SC_E_INPUT && !err.file[0]) { /* about the data: the input file's */
            snprintf(err.file, sizeof err.file, "%s", in);
            err.line = a.header_line;
        }
        rc = cli_report(&err);
    }
    sc_profile_result_free(&a);
    sc_profile_result_free(&t);
    sc_profile_result_free(&c);
    return rc;
}
