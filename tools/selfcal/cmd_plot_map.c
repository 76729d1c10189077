/* selfcal plot map — arrow plot of a stage error map (and of its estimation error vs a truth). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/stage_map.h"
#include "plots.h"
#include "svg.h"

static const char *USAGE =
    "usage: selfcal plot map G.csv -o map.svg [--truth G_true.csv] [--scale-um-per-pitch X]\n"
    "\n"
    "Draws the stage error map as arrows at the stage nodes (stage frame, mm), with a scale bar,\n"
    "the RMS and maximum of |G| in the title and, when the map has uncertainty columns, an\n"
    "ellipse of semi-axes (ugx, ugy) (k = 1) at each arrow tip. With --truth, a second panel shows\n"
    "the estimation error G - G_true (both maps on the same grid). --scale-um-per-pitch: the error\n"
    "drawn as long as one pitch (default: a round number at or above half the largest error,\n"
    "so the longest arrow is at most two pitches).\n";

/* A round number (1, 2, 2.5, 5 x 10^k) at or above v. */
static double round_up(double v)
{
    if (!(v > 0) || !isfinite(v))
        return 1.0;
    double mag = pow(10.0, floor(log10(v))), f = v / mag;
    return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 2.5 ? 2.5 : f <= 5 ? 5 : 10) * mag;
}

typedef struct stats {
    double rms, max, rms_x, rms_y;
    int imax, jmax;
} stats;

static stats map_stats(int nx, int ny, const double *gx, const double *gy)
{
    stats s = {0, 0, 0, 0, 0, 0};
    int nn = nx * ny;
    for (int k = 0; k < nn; ++k) {
        double a = gx[k] * gx[k] + gy[k] * gy[k];
        s.rms += a;
        s.rms_x += gx[k] * gx[k];
        s.rms_y += gy[k] * gy[k];
        if (sqrt(a) > s.max) {
            s.max = sqrt(a);
            s.imax = k / nx;
            s.jmax = k % nx;
        }
    }
    s.rms = sqrt(s.rms / nn);
    s.rms_x = sqrt(s.rms_x / nn);
    s.rms_y = sqrt(s.rms_y / nn);
    return s;
}

/* One panel: arrows at nodes; returns nothing, draws into fp at (x0, y0) with plot size sz px. */
static void panel(FILE *fp, double x0, double y0, double sz, const sc_stage_map *m,
                  const double *gx, const double *gy, const double *ugx, const double *ugy,
                  double scale_um_per_pitch, const char *title, const char *what,
                  int ellipse_at_node, const char *color)
{
    int n = m->nx > m->ny ? m->nx : m->ny, nn = m->nx * m->ny;
    double xmin = sc_stage_map_x_mm(m, 0), xmax = sc_stage_map_x_mm(m, m->nx - 1);
    double ymin = sc_stage_map_y_mm(m, 0), ymax = sc_stage_map_y_mm(m, m->ny - 1);
    double pad = m->px_mm;
    xmin -= pad, xmax += pad, ymin -= pad, ymax += pad;
    /* Square data range, so that x and y have the same scale and arrows keep their direction. */
    double span = fmax(xmax - xmin, ymax - ymin), cx = (xmin + xmax) / 2, cy = (ymin + ymax) / 2;
    svg_chart c;
    svg_chart_init(&c, fp, x0, y0, sz, sz, cx - span / 2, cx + span / 2, cy - span / 2,
                   cy + span / 2);
    svg_axes(&c, "x (mm, stage)", "y (mm, stage)", NULL);
    stats s = map_stats(m->nx, m->ny, gx, gy);
    /* Default: a round number at or above half the largest arrow (longest arrow <= 2 pitches). */
    double scale = scale_um_per_pitch > 0 ? scale_um_per_pitch : round_up(0.5 * s.max);
    double mm_per_um = m->px_mm / scale;
    svg_text(fp, x0 + sz / 2, y0 - 30, 15, "middle", "#000", "%s", title);
    svg_text(fp, x0 + sz / 2, y0 - 12, 12, "middle", "#333",
             "RMS |%s| = %.3g µm (x %.3g, y %.3g)   max |%s| = %.3g µm at node (%d,%d)", what,
             s.rms, s.rms_x, s.rms_y, what, s.max, s.imax, s.jmax);
    double dot = fmax(1.0, fmin(2.5, sz / n / 10));
    double width = fmax(0.7, fmin(1.6, sz / n / 18));
    for (int k = 0; k < nn; ++k) {
        double xk = sc_stage_map_x_mm(m, k % m->nx), yk = sc_stage_map_y_mm(m, k / m->nx);
        double px = svg_px(&c, xk), py = svg_py(&c, yk);
        svg_dot(fp, px, py, dot, "#9a9a9a");
        double tx = svg_px(&c, xk + gx[k] * mm_per_um);
        double ty = svg_py(&c, yk + gy[k] * mm_per_um);
        if (ugx && ugy && isfinite(ugx[k]) && isfinite(ugy[k])) {
            double rx = fabs(svg_px(&c, ugx[k] * mm_per_um) - svg_px(&c, 0));
            double ry = fabs(svg_py(&c, ugy[k] * mm_per_um) - svg_py(&c, 0));
            fprintf(fp,
                    "<ellipse cx=\"%.2f\" cy=\"%.2f\" rx=\"%.2f\" ry=\"%.2f\" fill=\"#f0a30a\" "
                    "fill-opacity=\"0.25\" stroke=\"#c47f00\" stroke-width=\"0.6\"/>\n",
                    ellipse_at_node ? px : tx, ellipse_at_node ? py : ty, rx, ry);
        }
        svg_arrow(fp, px, py, tx, ty, color, width);
    }
    /* Scale bar: one pitch = scale µm, below the plot area. */
    double bx = x0 + 10, by = y0 + sz + 52;
    double blen = svg_px(&c, m->px_mm) - svg_px(&c, 0);
    svg_arrow(fp, bx, by, bx + blen, by, color, width + 0.4);
    svg_text(fp, bx + blen + 8, by + 4, 12, "start", "#000",
             "%g µm   (scale: an arrow one pitch long, %g mm, is %g µm)", scale, m->px_mm,
             scale);
    if (ugx && ugy && isfinite(ugx[0]))
        svg_text(fp, bx, by + 22, 12, "start", "#c47f00",
                 "ellipses: standard uncertainty (k = 1) of gx, gy, same scale, %s",
                 ellipse_at_node ? "centred on the node" : "at the arrow tip");
}

void plot_map_svg(FILE *fp, const sc_stage_map *m, const sc_stage_map *truth,
                  double scale_um_per_pitch, const char *name)
{
    int has_u = sc_stage_map_has_u(m);
    double sz = 560, margin_l = 80, margin_t = 100, gap = 110, bottom = 100;
    int panels = truth ? 2 : 1;
    int w = (int)(margin_l + panels * sz + (panels - 1) * gap + 30);
    int h = (int)(margin_t + sz + bottom);
    svg_begin(fp, w, h);
    if (m->nx == m->ny && m->px_mm == m->py_mm)
        svg_text(fp, w / 2.0, 24, 17, "middle", "#000",
                 "Stage error map — %s (N = %d, pitch %g mm)", name, m->nx, m->px_mm);
    else
        svg_text(fp, w / 2.0, 24, 17, "middle", "#000",
                 "Stage error map — %s (%d x %d nodes, pitch %g x %g mm)", name, m->nx, m->ny,
                 m->px_mm, m->py_mm);
    svg_text(fp, w / 2.0, 42, 11, "middle", "#555",
             "stage error G = indicated − true position; SPEC gauge: no translation, rotation or "
             "magnification");
    panel(fp, margin_l, margin_t, sz, m, m->gx_um, m->gy_um, has_u ? m->ugx_um : NULL,
          has_u ? m->ugy_um : NULL, scale_um_per_pitch, "stage error G", "G", 0, "#1f4e9c");
    if (truth) {
        size_t nn = (size_t)m->nx * m->ny;
        double *ex = malloc(2 * nn * sizeof(double));
        if (ex) {
            for (size_t k = 0; k < nn; ++k) {
                ex[k] = m->gx_um[k] - truth->gx_um[k];
                ex[nn + k] = m->gy_um[k] - truth->gy_um[k];
            }
            panel(fp, margin_l + sz + gap, margin_t, sz, m, ex, ex + nn,
                  has_u ? m->ugx_um : NULL, has_u ? m->ugy_um : NULL, 0,
                  "estimation error G − G_true", "error", 1, "#b3261e");
            free(ex);
        }
    }
    svg_end(fp);
}

int cmd_plot_map(int argc, char **argv)
{
    const char *in = NULL, *out = NULL, *truth_path = NULL;
    double scale = 0;
    for (int a = 1; a < argc; ++a) {
        const char *o = argv[a];
        if (!strcmp(o, "--help") || !strcmp(o, "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        if (o[0] != '-' || !strcmp(o, "-")) {
            if (in)
                return cli_usage_error("plot map", "more than one map ('%s', '%s')", in, o);
            in = o;
            continue;
        }
        if (a + 1 >= argc)
            return cli_usage_error("plot map", "'%s' needs a value (see --help)", o);
        const char *v = argv[++a];
        if (!strcmp(o, "-o") || !strcmp(o, "--out")) out = v;
        else if (!strcmp(o, "--truth")) truth_path = v;
        else if (!strcmp(o, "--scale-um-per-pitch")) {
            if (sc_parse_double(v, &scale) || !(scale > 0))
                return cli_usage_error("plot map", "--scale-um-per-pitch needs a positive number");
        } else
            return cli_usage_error("plot map", "unknown option '%s' (see --help)", o);
    }
    if (!in || !out)
        return cli_usage_error("plot map", "G.csv and -o map.svg are required (see --help)");
    sc_error err;
    sc_error_clear(&err);
    sc_stage_map m, t;
    memset(&t, 0, sizeof t);
    sc_status st = sc_stage_map_read(in, &m, &err);
    if (st != SC_OK)
        return cli_report(&err);
    if (truth_path) {
        st = sc_stage_map_read(truth_path, &t, &err);
        if (st == SC_OK && (t.nx != m.nx || t.ny != m.ny ||
                            fabs(t.px_mm - m.px_mm) > 1e-9 * m.px_mm ||
                            fabs(t.py_mm - m.py_mm) > 1e-9 * m.py_mm ||
                            fabs(t.x0_mm - m.x0_mm) > 1e-6 || fabs(t.y0_mm - m.y0_mm) > 1e-6))
            st = sc_error_set(&err, SC_E_INPUT, truth_path, 0,
                              "the truth map is not on the grid of %s (%d x %d vs %d x %d nodes)",
                              in, t.nx, t.ny, m.nx, m.ny);
    }
    if (st == SC_OK) {
        sc_afile f;
        st = sc_afile_open(&f, out, &err);
        if (st == SC_OK) {
            const char *base = strrchr(in, '/');
            plot_map_svg(f.fp, &m, truth_path ? &t : NULL, scale, base ? base + 1 : in);
            st = sc_afile_commit(&f, &err);
        }
    }
    sc_stage_map_free(&m);
    sc_stage_map_free(&t);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}
