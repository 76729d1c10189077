/* selfcal plot xy — a line chart of the columns of a CSV file (one x column, one or more y
 * columns, linear or logarithmic axes): the figures of scripts/figs-grid.sh, and any table a
 * benchmark writes. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "plots.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "svg.h"

static const char USAGE[] =
    "usage: selfcal plot xy DATA.csv -o chart.svg [--x COL] [--y COL ...] [--logx] [--logy]\n"
    "                       [--title T] [--xlabel L] [--ylabel L]\n"
    "\n"
    "A line chart of a CSV file with a header line: x from one column, one line with markers per\n"
    "y column; empty fields are gaps. On a logarithmic axis values <= 0 are left out. At most\n"
    "10^8 values (rows x columns).\n";

#define XY_MAX_SERIES 16
#define XY_STR_(x) #x
#define XY_STR(x) XY_STR_(x)
/* the most values read (rows x columns, 800 MB): an endless pipe is refused there instead of
 * read until memory runs out; series are thinned to the figure's width when drawn */
#define XY_MAX_VALUES 100000000L

typedef struct xy_data {
    int ncol;
    char names[SC_CSV_MAX_FIELDS][64];
    long nrows, cap;
    double *v; /* nrows x ncol */
} xy_data;

static sc_status read_xy(const char *path, xy_data *t,
                         sc_error *err)
{
    memset(t, 0, sizeof *t);
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    int got;
    while ((got = sc_csv_next_line(&r, err)) > 0) {
        if (sc_csv_is_blank(&r) || r.text[0] == '#')
            continue;
        if (sc_csv_split(&r, err) < 0) {
            got = -1;
            break;
        }
        if (!t->ncol) {
            t->ncol = r.nfields;
            if (t->ncol < 2) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, "need a header with at least two columns");
                goto fail;
            }
            for (int k = 0; k < t->ncol; ++k)
                snprintf(t->names[k], sizeof t->names[k], "%s", r.field[k]);
            continue;
        }
        if (r.nfields != t->ncol) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "expected %d fields, got %d", t->ncol,
                              r.nfields);
            goto fail;
        }
        const long max_rows = XY_MAX_VALUES / t->ncol;
        if (t->nrows == max_rows) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "more than %ld rows of %d columns, the most a chart reads (10^8 "
                              "values)", max_rows, t->ncol);
            goto fail;
        }
        if (t->nrows == t->cap) {
            t->cap = t->cap ? 2 * t->cap : 64;
            if (t->cap > max_rows)
                t->cap = max_rows;
            double *nv = realloc(t->v, (size_t)t->cap * t->ncol * sizeof(double));
            if (!nv) {
                st = sc_error_set(err, SC_E_NOMEM, path, r.line, "out of memory");
                goto fail;
            }
            t->v = nv;
        }
        double *row = t->v + t->nrows * t->ncol;
        for (int k = 0; k < t->ncol; ++k) {
            row[k] = NAN;
            if (!r.field[k][0])
                continue;
            if ((st = sc_csv_double(&r, k, t->names[k], &row[k], err)) != SC_OK)
                goto fail;
            if (!(fabs(row[k]) <= 1e300)) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, "%s = %g is beyond +-1e300",
                                  t->names[k], row[k]);
                goto fail;
            }
        }
        t->nrows++;
    }
    if (got < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    if (t->nrows == 0) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line, "no data rows");
        goto fail;
    }
    sc_csv_close(&r);
    return SC_OK;
fail:
    sc_csv_close(&r);
    free(t->v);
    t->v = NULL;
    return st;
}

static const char *COLORS[8] = {"#1f5fbf", "#d9731a", "#2a9d3a", "#b3261e",
                                "#7b4bb7", "#8c564b", "#e377c2", "#555555"};
static const char *DASHES[4] = {NULL, "6,3", "2,2", "8,3,2,3"};

/* The command line, as given. */
typedef struct {
    const char *in, *out, *xname, *title, *xlabel, *ylabel;
    const char *ynames[XY_MAX_SERIES];
    int ny, logx, logy;
} xy_args;

#define F(field) offsetof(xy_args, field)
/* plot xy's options (cli_opts.h), in the order of its --help */
static const cli_opt PLOT_XY_OPTS[] = {
    {"-o|--out", CLI_STRING, F(out), "chart.svg", .help = "the chart (SVG)"},
    {"--x", CLI_STRING, F(xname), "COL", .def = "the first column", .help = "the x column"},
    {"--y", CLI_LIST, F(ynames), "COL", 0, XY_MAX_SERIES, .count = F(ny),
     .bad = "at most " XY_STR(XY_MAX_SERIES) " --y columns", .def = "every other column",
     .help = "a series' column (repeatable)"},
    {"--logx", CLI_FLAG, F(logx), .help = "a logarithmic x axis"},
    {"--logy", CLI_FLAG, F(logy), .help = "a logarithmic y axis"},
    {"--title", CLI_STRING, F(title), "T", .help = "the chart's title"},
    {"--xlabel", CLI_STRING, F(xlabel), "L", .def = "the x column's name", .help = "the x axis' label"},
    {"--ylabel", CLI_STRING, F(ylabel), "L", .def = "the y columns' names", .help = "the y axis' label"},
};
#undef F

const cli_cmd_opts cli_plot_xy_opts = {
    "plot xy", USAGE, PLOT_XY_OPTS, (int)(sizeof PLOT_XY_OPTS / sizeof PLOT_XY_OPTS[0]),
    offsetof(xy_args, in), NULL, NULL, NULL, NULL, 0, NULL, NULL,
};

/* The x column and the series' columns (--y, or every other column). */
static sc_status select_columns(const xy_args *a, const xy_data *t, int *xc, int *yc, int *nser,
                                sc_error *err)
{
    *xc = 0;
    *nser = 0;
    if (a->xname) {
        *xc = -1;
        for (int k = 0; k < t->ncol; ++k)
            if (!strcmp(t->names[k], a->xname))
                *xc = k;
    }
    if (*xc < 0)
        return sc_error_set(err, SC_E_INPUT, a->in, 1, "no column '%s'", a->xname);
    for (int q = 0; q < a->ny; ++q) {
        yc[*nser] = -1;
        for (int k = 0; k < t->ncol; ++k)
            if (!strcmp(t->names[k], a->ynames[q]))
                yc[*nser] = k;
        if (yc[*nser] < 0)
            return sc_error_set(err, SC_E_INPUT, a->in, 1, "no column '%s'", a->ynames[q]);
        (*nser)++;
    }
    for (int k = 0; !a->ny && k < t->ncol && *nser < XY_MAX_SERIES; ++k)
        if (k != *xc)
            yc[(*nser)++] = k;
    return SC_OK;
}

/* One axis' range from its finite values: whole decades on a log axis, else a nice range
 * (with 5 % margins for y). */
static void axis_range(int is_log, double margin, double *lo, double *hi)
{
    if (!(*lo <= *hi))
        *lo = 0, *hi = 1;
    if (is_log) {
        *lo = floor(*lo), *hi = ceil(*hi);
        if (*hi <= *lo)
            *hi = *lo + 1;
        return;
    }
    double span = *hi - *lo;
    *lo -= margin * span, *hi += margin * span;
    svg_nice_range(lo, hi);
}

/* The plotted range of x and of every series' y; values <= 0 on a log axis are gaps. */
static void data_range(const xy_args *a, const xy_data *t, int xc, const int *yc, int nser,
                       double range[4])
{
    double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
    for (long r = 0; r < t->nrows; ++r) {
        double x = t->v[r * t->ncol + xc];
        x = a->logx ? log10(x) : x;
        if (!isfinite(x))
            continue;
        xlo = fmin(xlo, x), xhi = fmax(xhi, x);
        for (int q = 0; q < nser; ++q) {
            double y = t->v[r * t->ncol + yc[q]];
            y = a->logy ? log10(y) : y;
            if (isfinite(y))
                ylo = fmin(ylo, y), yhi = fmax(yhi, y);
        }
    }
    axis_range(a->logx, 0.0, &xlo, &xhi);
    axis_range(a->logy, 0.05, &ylo, &yhi);
    range[0] = xlo, range[1] = xhi, range[2] = ylo, range[3] = yhi;
}

/* Series of more points than this are drawn without a dot per point: the dots would merge into a
 * thick line (and a series of 10⁶ points made a 116 MB drawing). */
#define XY_MAX_DOTS 200

/* The chart: axes, one polyline (with dots where there are few points) and a legend entry per
 * series; xs, ys: nrows each. */
static void draw_chart(FILE *fp, const xy_args *a, const xy_data *t, int xc, const int *yc,
                       int nser, double *xs, double *ys)
{
    double range[4];
    data_range(a, t, xc, yc, nser, range);
    const int W = 760, H = 460;
    svg_begin(fp, W, H);
    svg_chart c;
    svg_chart_init(&c, fp, 85, 50, W - 115, H - 120, range[0], range[1], range[2], range[3]);
    c.logx = a->logx;
    c.logy = a->logy;
    /* every axis has a title: without --ylabel, the series' column names (as the legend) */
    char ylab[160] = "";
    for (int q = 0; q < nser && !a->ylabel; ++q) {
        size_t len = strlen(ylab);
        if (len + strlen(t->names[yc[q]]) + 3 >= sizeof ylab) {
            snprintf(ylab, sizeof ylab, "%s", nser > 1 ? "values of the series (legend)" : "value");
            break;
        }
        snprintf(ylab + len, sizeof ylab - len, "%s%s", q ? ", " : "", t->names[yc[q]]);
    }
    svg_axes(&c, a->xlabel ? a->xlabel : t->names[xc], a->ylabel ? a->ylabel : ylab, a->title);
    for (int q = 0; q < nser; ++q) {
        const char *col = COLORS[q % 8], *dash = DASHES[(q / 8 + q) % 4];
        for (long r = 0; r < t->nrows; ++r) {
            double x = t->v[r * t->ncol + xc], y = t->v[r * t->ncol + yc[q]];
            xs[r] = a->logx ? log10(x) : x;
            ys[r] = a->logy ? log10(y) : y;
        }
        svg_polyline(&c, xs, ys, (int)t->nrows, col, 1.6, dash);
        long shown = 0;
        for (long r = 0; r < t->nrows; ++r)
            shown += isfinite(xs[r]) && isfinite(ys[r]);
        for (long r = 0; shown <= XY_MAX_DOTS && r < t->nrows; ++r)
            if (isfinite(xs[r]) && isfinite(ys[r]))
                svg_dot(fp, svg_px(&c, xs[r]), svg_py(&c, ys[r]), 2.8, col);
        svg_legend(&c, q, t->names[yc[q]], col, dash);
    }
    svg_end(fp);
}

int cmd_plot_xy(int argc, char **argv)
{
    xy_args a;
    memset(&a, 0, sizeof a);
    int rc = cli_opts_parse(&cli_plot_xy_opts, argc, argv, &a);
    if (rc >= 0)
        return rc;
    if (!a.in || !a.out)
        return cli_usage_error("plot xy", "DATA.csv and -o chart.svg are required (see --help)");
    sc_error err;
    sc_error_clear(&err);
    xy_data t;
    sc_status st = read_xy(a.in, &t, &err);
    if (st != SC_OK)
        return cli_report(&err);
    int xc, yc[XY_MAX_SERIES], nser;
    st = select_columns(&a, &t, &xc, yc, &nser, &err);
    double *xs = NULL, *ys = NULL;
    if (st == SC_OK) {
        xs = malloc((size_t)t.nrows * sizeof(double));
        ys = malloc((size_t)t.nrows * sizeof(double));
        if (!xs || !ys)
            st = sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    sc_afile f;
    if (st == SC_OK)
        st = sc_afile_open(&f, a.out, &err);
    if (st == SC_OK) {
        draw_chart(f.fp, &a, &t, xc, yc, nser, xs, ys);
        st = sc_afile_finish(&f, SC_OK, &err); /* a failed write: "write error: <reason>" */
    }
    free(xs);
    free(ys);
    free(t.v);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}
