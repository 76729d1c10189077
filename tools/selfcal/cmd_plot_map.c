/* selfcal plot map — arrow plot of a stage error map (and of its estimation error vs a truth). */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "input_once.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_io.h"
#include "selfcal/stage_map.h"
#include "plots.h"
#include "svg.h"

static const char USAGE[] =
    "usage: selfcal plot map G.csv|A.csv -o map.svg [--truth TRUE.csv] [--scale-um-per-pitch X]\n"
    "                        [--pitch-mm P]\n"
    "\n"
    "Draws a stage error map (i,j,x_mm,y_mm,gx_um,gy_um,...) as arrows at the stage nodes (stage\n"
    "frame, mm), with a scale bar and the RMS and maximum of |G| (and where it is, in mm) above it;\n"
    "when the map has uncertainty columns, a second panel shows u(G) (the larger of u(gx), u(gy),\n"
    "k = 1) as a colour map. A plate error file (i,j,ax_um,ay_um, from grid --artifact) is drawn\n"
    "the same way at the nominal mark positions in the plate frame (--pitch-mm: the plate's pitch,\n"
    "default 1; marks no view measured are hollow circles). With --truth, a panel shows the\n"
    "estimation error against a truth file of the same kind and grid. --scale-um-per-pitch: the\n"
    "error drawn as long as one pitch (default: a round number at or above half the largest\n"
    "error, so the longest arrow is at most two pitches; the frame always holds every arrow).\n";

/* A round number (1, 2, 2.5, 5 x 10^k) at or above v. */
static double round_up(double v)
{
    if (!(v > 0) || !isfinite(v))
        return 1.0;
    double mag = pow(10.0, floor(log10(v))), f = v / mag;
    return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 2.5 ? 2.5 : f <= 5 ? 5 : 10) * mag;
}

/* The map's geometry, in one place (the type is being generalized to NX x NY stages). */
static long map_nodes(const sc_stage_map *m) { return (long)m->nx * m->ny; }
static int map_nside(const sc_stage_map *m) { return m->nx > m->ny ? m->nx : m->ny; }
static double map_x(const sc_stage_map *m, long k) { return sc_stage_map_x_mm(m, (int)(k % m->nx)); }
static double map_y(const sc_stage_map *m, long k) { return sc_stage_map_y_mm(m, (int)(k / m->nx)); }
static double map_pitch(const sc_stage_map *m) { return m->px_mm; }

typedef struct stats {
    double rms, max, rms_x, rms_y;
    int kmax; /* node of the largest |vector| */
    long count;
} stats;

/* RMS and maximum over the finite vectors of n values (missing marks are NaN). */
static stats map_stats(long n, const double *gx, const double *gy)
{
    stats s = {0, 0, 0, 0, 0, 0};
    for (long k = 0; k < n; ++k) {
        if (!isfinite(gx[k]) || !isfinite(gy[k]))
            continue;
        double a = gx[k] * gx[k] + gy[k] * gy[k];
        s.rms += a;
        s.rms_x += gx[k] * gx[k];
        s.rms_y += gy[k] * gy[k];
        s.count++;
        if (sqrt(a) > s.max) {
            s.max = sqrt(a);
            s.kmax = (int)k;
        }
    }
    if (s.count) {
        s.rms = sqrt(s.rms / s.count);
        s.rms_x = sqrt(s.rms_x / s.count);
        s.rms_y = sqrt(s.rms_y / s.count);
    }
    return s;
}

/* The square data range (mm) of a map's nodes, widened by pad_mm on every side. */
static void node_range(const sc_stage_map *m, double pad_mm, double *lo_x, double *lo_y,
                       double *span)
{
    long nn = map_nodes(m);
    double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY;
    for (long k = 0; k < nn; ++k) {
        xmin = fmin(xmin, map_x(m, k));
        xmax = fmax(xmax, map_x(m, k));
        ymin = fmin(ymin, map_y(m, k));
        ymax = fmax(ymax, map_y(m, k));
    }
    *span = fmax(xmax - xmin, ymax - ymin) + 2 * pad_mm;
    *lo_x = (xmin + xmax) / 2 - *span / 2;
    *lo_y = (ymin + ymax) / 2 - *span / 2;
}

static const char *axis_x(int plate) { return plate ? "x (mm, plate frame)" : "x (mm, stage)"; }
static const char *axis_y(int plate) { return plate ? "y (mm, plate frame)" : "y (mm, stage)"; }

/* A map of more nodes than this on a side is drawn at every stride-th node in x and y (arrows) or
 * in blocks of stride × stride nodes (colour cells): at N = 401 a panel had 160 000 arrows about
 * 1.4 px apart (a 37 MB drawing nobody can read); with the stride the arrows stay ~10 px apart. */
#define MAP_MAX_ARROWS 56
#define MAP_MAX_CELLS 140
/* Above this many nodes on a side, an arrow panel draws |G| as a colour map under the arrows and
 * thins the arrows to at most MAP_MAX_ARROWS_BACKDROP on a side (about 20 px apart), so that
 * each arrow can be read and the colour shows where the error is large (at N = 101 the arrows
 * of every second node were specks). */
#define MAP_BACKDROP_N 41
#define MAP_MAX_ARROWS_BACKDROP 26
#define MAP_BAR_W 16 /* colour bar width, px */

static int map_stride(const sc_stage_map *m, int most)
{
    int n = map_nside(m);
    return n > most ? (n + most - 1) / most : 1;
}

/* Does an arrow panel of m draw |G| under its arrows? */
static int map_has_backdrop(const sc_stage_map *m) { return map_nside(m) > MAP_BACKDROP_N; }

/* Colour cells of v on chart c for [lo, hi]: a cell per node, or per block of stride × stride
 * nodes of a large map: the block's value of largest magnitude (its worst node), grey where it
 * has none. */
static void colormap_cells(FILE *fp, const svg_chart *c, const sc_stage_map *m, const double *v,
                           double lo, double hi, int palette)
{
    int st = map_stride(m, MAP_MAX_CELLS);
    double cell = svg_px(c, m->px_mm) - svg_px(c, 0), cell_h = svg_px(c, m->py_mm) - svg_px(c, 0);
    char col[8];
    for (int by = 0; by < m->ny; by += st)
        for (int bx = 0; bx < m->nx; bx += st) {
            int ex = bx + st < m->nx ? bx + st : m->nx, ey = by + st < m->ny ? by + st : m->ny;
            double val = NAN;
            for (int iy = by; iy < ey; ++iy)
                for (int ix = bx; ix < ex; ++ix) {
                    double w = v[(long)iy * m->nx + ix];
                    if (isfinite(w) && (isnan(val) || fabs(w) > fabs(val)))
                        val = w; /* the first of the largest magnitude */
                }
            if (isfinite(val))
                svg_palette((val - lo) / (hi - lo), palette, col);
            else
                snprintf(col, sizeof col, "#d0d0d0");
            /* from the block's first node's cell corner to its last node's */
            double ax = svg_px(c, sc_stage_map_x_mm(m, bx)), ay = svg_py(c, sc_stage_map_y_mm(m, by));
            double zx = svg_px(c, sc_stage_map_x_mm(m, ex - 1)), zy = svg_py(c, sc_stage_map_y_mm(m, ey - 1));
            double x_lo = fmin(ax, zx) - cell / 2, y_lo = fmin(ay, zy) - cell_h / 2;
            fprintf(fp, "<rect x=\"%.2f\" y=\"%.2f\" width=\"%.2f\" height=\"%.2f\" fill=\"%s\"/>\n",
                    x_lo, y_lo, fabs(zx - ax) + cell + 0.3, fabs(zy - ay) + cell_h + 0.3, col);
        }
}

/* The colour bar of |what| beside an arrow panel whose largest arrow is vmax µm: its label. */
static void backdrop_label(char *buf, size_t cap, const char *what)
{
    snprintf(buf, cap, "|%s| (µm)", what);
}

/* What an arrow panel of m needs right of its frame (its |G| colour bar), px; 0 without. */
static double arrow_panel_right(const sc_stage_map *m, const double *gx, const double *gy,
                                const char *what, int backdrop)
{
    if (!backdrop || !map_has_backdrop(m))
        return 0;
    stats s = map_stats(map_nodes(m), gx, gy);
    char lab[64];
    backdrop_label(lab, sizeof lab, what);
    return 18 + svg_color_bar_extent(MAP_BAR_W, 0, s.max > 0 ? s.max : 1, lab);
}

/* One arrow panel at (x0, y0), sz px square: arrows at nodes (every stride-th of a large map, and
 * always the largest), missing marks, the statistics line above, the scale bar below. The data
 * range holds the longest arrow, so no arrow crosses the frame. */
static void arrow_panel(FILE *fp, double x0, double y0, double sz, const sc_stage_map *m, int plate,
                        const double *gx, const double *gy, double scale_um_per_pitch,
                        const char *title, const char *what, const char *color, int backdrop)
{
    backdrop = backdrop && map_has_backdrop(m);
    int stride = map_stride(m, backdrop ? MAP_MAX_ARROWS_BACKDROP : MAP_MAX_ARROWS);
    int n = (map_nside(m) + stride - 1) / stride; /* arrows on a side */
    long nn = map_nodes(m);
    stats s = map_stats(nn, gx, gy);
    /* Default: a round number at or above half the largest arrow (longest arrow <= 2 of the
     * arrows' spacing: stride pitches). */
    double scale = scale_um_per_pitch > 0 ? scale_um_per_pitch : round_up(0.5 * s.max / stride);
    double mm_per_um = map_pitch(m) / scale;
    double lo_x, lo_y, span;
    node_range(m, fmax(0.7 * map_pitch(m), s.max * mm_per_um + 0.3 * map_pitch(m)), &lo_x, &lo_y,
               &span);
    svg_chart c;
    svg_chart_init(&c, fp, x0, y0, sz, sz, lo_x, lo_x + span, lo_y, lo_y + span);
    svg_axes(&c, axis_x(plate), axis_y(plate), NULL);
    double *mag = backdrop ? malloc((size_t)nn * sizeof(double)) : NULL;
    if (mag) { /* |G| under the arrows, with its colour bar */
        for (long k = 0; k < nn; ++k)
            mag[k] = hypot(gx[k], gy[k]);
        double hi = s.max > 0 ? s.max : 1;
        colormap_cells(fp, &c, m, mag, 0, hi, SVG_PALETTE_HEAT);
        fprintf(fp, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" stroke=\"#333\"/>\n",
                c.x, c.y, c.w, c.h);
        char lab[64];
        backdrop_label(lab, sizeof lab, what);
        svg_color_bar(fp, x0 + sz + 18, y0 + 10, MAP_BAR_W, sz - 20, 0, hi, SVG_PALETTE_HEAT, lab);
        free(mag);
    }
    svg_text_fit(fp, x0 + sz / 2, y0 - 30, 15, sz + 60, "middle", "#000", "%s", title);
    if (s.count)
        svg_text_fit(fp, x0 + sz / 2, y0 - 12, 12, sz + 60, "middle", "#333",
                     "RMS |%s| = %.3g µm (x %.3g, y %.3g)   max |%s| = %.3g µm at (%g, %g) mm",
                     what, s.rms, s.rms_x, s.rms_y, what, s.max, map_x(m, s.kmax), map_y(m, s.kmax));
    double dot = fmax(1.0, fmin(2.5, sz / n / 10));
    double width = fmax(0.7, fmin(1.6, sz / n / 18));
    for (long k = 0; k < nn; ++k) {
        double px = svg_px(&c, map_x(m, k)), py = svg_py(&c, map_y(m, k));
        if (!isfinite(gx[k]) || !isfinite(gy[k])) { /* a missing mark: a hollow circle */
            fprintf(fp, "<circle cx=\"%.2f\" cy=\"%.2f\" r=\"%.2f\" fill=\"none\" stroke=\"#b3261e\"/>\n",
                    px, py, dot + 1.5);
            continue;
        }
        if ((k % m->nx % stride || k / m->nx % stride) && k != s.kmax)
            continue;
        svg_dot(fp, px, py, dot, "#9a9a9a");
        svg_arrow(fp, px, py, svg_px(&c, map_x(m, k) + gx[k] * mm_per_um),
                  svg_py(&c, map_y(m, k) + gy[k] * mm_per_um), color, width);
    }
    /* Scale bar: one pitch = scale µm (stride pitches = stride·scale µm), below the plot area. */
    double bx = x0 + 10, by = y0 + sz + 52;
    double blen = svg_px(&c, stride * map_pitch(m)) - svg_px(&c, 0);
    svg_arrow(fp, bx, by, bx + blen, by, color, width + 0.4);
    if (stride == 1)
        svg_text(fp, bx + blen + 8, by + 4, 12, "start", "#000",
                 "%g µm   (scale: an arrow one pitch long, %g mm, is %g µm)", scale, map_pitch(m),
                 scale);
    else
        svg_text(fp, bx + blen + 8, by + 4, 12, "start", "#000",
                 "%g µm   (an arrow %d pitches long, %g mm, is %g µm; one node in %d drawn each way%s)",
                 stride * scale, stride, stride * map_pitch(m), stride * scale, stride,
                 backdrop ? "; colour: |G| at every node" : "");
}

/* One colour-map panel at (x0, y0), sz px square: a cell per node coloured by v (NaN: grey),
 * a colour scale to the right (symmetric about 0 when diverging, from 0 otherwise). */
static void colormap_panel(FILE *fp, double x0, double y0, double sz, const sc_stage_map *m, int plate,
                           const double *v, const char *title, const char *unit, int diverging)
{
    long nn = map_nodes(m);
    double vmax = 0, vmin = INFINITY, vsum2 = 0;
    long cnt = 0;
    int kmax = 0;
    for (long k = 0; k < nn; ++k)
        if (isfinite(v[k])) {
            if (fabs(v[k]) > vmax)
                vmax = fabs(v[k]), kmax = (int)k;
            vmin = fmin(vmin, v[k]);
            vsum2 += v[k] * v[k];
            cnt++;
        }
    double lo = diverging ? -vmax : 0, hi = vmax;
    if (!(hi > lo))
        hi = lo + 1;
    double lo_x, lo_y, span;
    node_range(m, 0.5 * map_pitch(m), &lo_x, &lo_y, &span);
    svg_chart c;
    svg_chart_init(&c, fp, x0, y0, sz, sz, lo_x, lo_x + span, lo_y, lo_y + span);
    svg_axes(&c, axis_x(plate), axis_y(plate), NULL);
    colormap_cells(fp, &c, m, v, lo, hi, diverging);
    fprintf(fp, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" stroke=\"#333\"/>\n",
            c.x, c.y, c.w, c.h);
    svg_text_fit(fp, x0 + sz / 2, y0 - 30, 15, sz + 60, "middle", "#000", "%s", title);
    if (cnt)
        svg_text_fit(fp, x0 + sz / 2, y0 - 12, 12, sz + 60, "middle", "#333",
                     "RMS %.3g %s   max |v| %.3g %s at (%g, %g) mm", sqrt(vsum2 / cnt), unit,
                     vmax, unit, map_x(m, kmax), map_y(m, kmax));
    svg_color_bar(fp, x0 + sz + 18, y0 + 10, 16, sz - 20, lo, hi, diverging, unit);
}

/* What a colour-map panel of v needs right of its frame (its colour bar), px. */
static double colormap_right(const sc_stage_map *m, const double *v, int diverging, const char *unit)
{
    double vmax = 0;
    for (long k = 0; k < map_nodes(m); ++k)
        if (isfinite(v[k]))
            vmax = fmax(vmax, fabs(v[k]));
    double lo = diverging ? -vmax : 0, hi = vmax;
    if (!(hi > lo))
        hi = lo + 1;
    return 18 + svg_color_bar_extent(MAP_BAR_W, lo, hi, unit);
}

/* The drawing's title and subtitle (w pixels wide). */
static void map_titles(FILE *fp, int w, const sc_stage_map *m, const char *name, int plate)
{
    if (m->nx == m->ny && m->px_mm == m->py_mm)
        svg_text_fit(fp, w / 2.0, 24, 17, w - 20, "middle", "#000", "%s — %s (N = %d, pitch %g mm)",
                     plate ? "Plate error map" : "Stage error map", name, map_nside(m),
                     map_pitch(m));
    else
        svg_text_fit(fp, w / 2.0, 24, 17, w - 20, "middle", "#000",
                     "%s — %s (%d x %d nodes, pitch %g x %g mm)",
                     plate ? "Plate error map" : "Stage error map", name, m->nx, m->ny, m->px_mm,
                     m->py_mm);
    svg_text_fit(fp, w / 2.0, 42, 11, w - 20, "middle", "#555", "%s",
                 plate ? "plate error A = mark position − nominal, plate frame; no "
                                  "translation or rotation"
                                : "stage error G = indicated − true position; SPEC gauge: no "
                                  "translation, rotation or magnification");
}

/* The estimation error panel (map - truth) at x, sz pixels; buf: 2 nn doubles, the first nn
 * holding u(G) when u_panel (then the panel takes a buffer of its own for y). */
static void truth_panel(FILE *fp, double x, double top, double sz, const sc_stage_map *m,
                        const sc_stage_map *truth, int plate, double *buf, int u_panel)
{
    size_t nn = (size_t)map_nodes(m);
    double *ex = buf + (u_panel ? nn : 0), *ey = u_panel ? NULL : buf + nn;
    double *tmp = u_panel ? malloc(nn * sizeof(double)) : NULL;
    if (u_panel)
        ey = tmp;
    if (ey) {
        for (size_t k = 0; k < nn; ++k) {
            ex[k] = m->gx_um[k] - truth->gx_um[k];
            ey[k] = m->gy_um[k] - truth->gy_um[k];
        }
        arrow_panel(fp, x, top, sz, m, plate, ex, ey, 0,
                    plate ? "estimation error A − A_true" : "estimation error G − G_true",
                    "error", "#b3261e", 0);
    }
    free(tmp);
}

void plot_map_svg(FILE *fp, const sc_stage_map *m, const sc_stage_map *truth,
                  double scale_um_per_pitch, const char *name, int plate)
{
    double sz = 560, margin_l = 80, margin_t = 100, gap = 120, bottom = 80;
    int u_panel = sc_stage_map_has_u(m);
    size_t nn = (size_t)map_nodes(m);
    double *buf = malloc(2 * nn * sizeof(double));
    if (buf && u_panel)
        for (size_t k = 0; k < nn; ++k)
            buf[k] = fmax(m->ugx_um[k], m->ugy_um[k]); /* NaN only if both are */
    const char *what = plate ? "A" : "G";
    /* the first panel's |G| colour bar sits in the gap after it (or in the right margin) */
    double right0 = arrow_panel_right(m, m->gx_um, m->gy_um, what, 1);
    double gap0 = fmax(gap, right0 + 75); /* the next panel's axis labels need ~75 px */
    int more = (truth != NULL) + (u_panel && buf);
    double right = more == 0 ? fmax(40, right0 + 10)
                   : u_panel && buf ? fmax(70, colormap_right(m, buf, 0, "µm") + 10) : 40;
    int w = (int)(margin_l + (1 + more) * sz + (more ? gap0 + (more - 1) * gap : 0) + right);
    int h = (int)(margin_t + sz + bottom);
    svg_begin(fp, w, h);
    map_titles(fp, w, m, name, plate);
    double x = margin_l;
    arrow_panel(fp, x, margin_t, sz, m, plate, m->gx_um, m->gy_um, scale_um_per_pitch,
                plate ? "plate error A" : "stage error G", what, "#1f4e9c", 1);
    x += sz + gap0;
    if (!buf) { /* the drawing loses its extra panels, never its frame */
        svg_end(fp);
        return;
    }
    if (truth) {
        truth_panel(fp, x, margin_t, sz, m, truth, plate, buf, u_panel);
        x += sz + gap;
    }
    if (u_panel)
        colormap_panel(fp, x, margin_t, sz, m, plate, buf, "u(G): larger of u(gx), u(gy), k = 1", "µm", 0);
    free(buf);
    svg_end(fp);
}

void plot_arrows_svg(FILE *fp, const sc_stage_map *m, int plate, double scale_um_per_pitch,
                     const char *title, const char *what)
{
    double sz = 520;
    double right = fmax(40, arrow_panel_right(m, m->gx_um, m->gy_um, what, 1) + 10);
    svg_begin(fp, (int)(80 + sz + right), (int)(70 + sz + 75));
    arrow_panel(fp, 80, 60, sz, m, plate, m->gx_um, m->gy_um, scale_um_per_pitch, title, what,
                "#1f4e9c", 1);
    svg_end(fp);
}

void plot_arrows_pair_svg(FILE *fp, const sc_stage_map *a, const char *title_a,
                          const sc_stage_map *b, const char *title_b, const char *heading)
{
    double sz = 480, gap = 110;
    int w = (int)(80 + 2 * sz + gap + 40);
    svg_begin(fp, w, (int)(100 + sz + 75));
    if (heading)
        svg_text_fit(fp, w / 2.0, 24, 17, w - 20, "middle", "#000", "%s", heading);
    arrow_panel(fp, 80, 90, sz, a, 0, a->gx_um, a->gy_um, 0, title_a, "r", "#1f4e9c", 0);
    arrow_panel(fp, 80 + sz + gap, 90, sz, b, 0, b->gx_um, b->gy_um, 0, title_b, "r", "#b3261e", 0);
    svg_end(fp);
}

void plot_colormap_svg(FILE *fp, const sc_stage_map *m, int plate, const double *v,
                       const char *title, const char *unit, int diverging)
{
    double sz = 420;
    double right = fmax(40, colormap_right(m, v, diverging, unit) + 10);
    svg_begin(fp, (int)(80 + sz + right), (int)(70 + sz + 50));
    colormap_panel(fp, 80, 60, sz, m, plate, v, title, unit, diverging);
    svg_end(fp);
}

void plot_histogram_svg(FILE *fp, const double *v, long n, double sigma, const char *title,
                        const char *xlabel)
{
    const int W = 620, H = 340;
    svg_begin(fp, W, H);
    double lo = INFINITY, hi = -INFINITY;
    long cnt_f = 0;
    for (long k = 0; k < n; ++k)
        if (isfinite(v[k])) {
            lo = fmin(lo, v[k]);
            hi = fmax(hi, v[k]);
            cnt_f++;
        }
    if (!cnt_f) {
        svg_text(fp, W / 2.0, H / 2.0, 14, "middle", "#000", "%s: no values", title);
        svg_end(fp);
        return;
    }
    double a = fmax(fabs(lo), fabs(hi));
    if (isfinite(sigma) && sigma > 0)
        a = fmax(a, 4 * sigma);
    if (!(a > 0))
        a = 1;
    lo = -a, hi = a;
    svg_nice_range(&lo, &hi);
    int nb = cnt_f < 50 ? 10 : cnt_f < 500 ? 20 : 40;
    long *cnt = calloc((size_t)nb, sizeof *cnt);
    if (!cnt) {
        svg_end(fp);
        return;
    }
    long cmax = 1;
    for (long k = 0; k < n; ++k)
        if (isfinite(v[k])) {
            int b = (int)((v[k] - lo) / (hi - lo) * nb);
            b = b < 0 ? 0 : b >= nb ? nb - 1 : b;
            if (++cnt[b] > cmax)
                cmax = cnt[b];
        }
    double top = cmax * 1.15;
    /* the normal density of the given sigma, scaled to counts per bin */
    double bw = (hi - lo) / nb, curve_y[101], curve_x[101];
    int has_curve = isfinite(sigma) && sigma > 0;
    for (int q = 0; has_curve && q <= 100; ++q) {
        curve_x[q] = lo + (hi - lo) * q / 100;
        curve_y[q] = cnt_f * bw / (sigma * sqrt(2 * M_PI)) *
                     exp(-0.5 * curve_x[q] * curve_x[q] / (sigma * sigma));
        top = fmax(top, curve_y[q] * 1.05);
    }
    svg_chart c;
    svg_chart_init(&c, fp, 70, 50, W - 100, H - 110, lo, hi, 0, top);
    svg_axes(&c, xlabel, "count", title);
    svg_bars(&c, lo, hi, cnt, nb, "#6b8fc7");
    if (has_curve) {
        svg_polyline(&c, curve_x, curve_y, 101, "#b3261e", 1.5, NULL);
        svg_legend(&c, 0, "normal density, expected spread", "#b3261e", NULL);
    }
    free(cnt);
    svg_end(fp);
}

/* 1 if the first non-comment, non-blank line of path is the plate error header (looked for in
 * the first SC_CSV_MAX_SKIP_RUN lines: the reader refuses more comments than that). path is read
 * again by the reader: a pipe must come as its in-memory copy (cli_input_open). */
static int is_artifact_file(const char *path)
{
    FILE *fp = fopen(path, "rb");
    char line[256];
    int art = 0;
    long lines = 0;
    while (fp && fgets(line, sizeof line, fp) && ++lines <= SC_CSV_MAX_SKIP_RUN) {
        if (line[0] == '#' || line[0] == '\n' || line[0] == '\r')
            continue;
        art = !strncmp(line, "i,j,ax_um,ay_um", 15);
        break;
    }
    if (fp)
        fclose(fp);
    return art;
}

/* What the command line asks for. */
typedef struct plot_map_args {
    const char *in, *out, *truth_path;
    double scale, pitch; /* 0: not given */
} plot_map_args;

#define F(field) offsetof(plot_map_args, field)
/* plot map's options (cli_opts.h), in the order of its --help */
static const cli_opt PLOT_MAP_OPTS[] = {
    {"-o|--out", CLI_STRING, F(out), "map.svg", .help = "the plot (SVG)"},
    {"--truth", CLI_STRING, F(truth_path), "TRUE.csv", .help = "the true map, drawn beside"},
    {"--scale-um-per-pitch", CLI_DOUBLE, F(scale), "X", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .bad = "--scale-um-per-pitch needs a positive number", .def = "a round number from half the largest error",
     .help = "the arrows' scale: um drawn as one pitch"},
    {"--pitch-mm", CLI_DOUBLE, F(pitch), "P", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .bad = "--pitch-mm needs a positive number", .def = "1", .help = "a plate error file's pitch (mm)"},
};
#undef F

const cli_cmd_opts cli_plot_map_opts = {
    "plot map", USAGE, PLOT_MAP_OPTS, (int)(sizeof PLOT_MAP_OPTS / sizeof PLOT_MAP_OPTS[0]),
    offsetof(plot_map_args, in), NULL, "more than one map ('%s', '%s')", NULL, NULL, 0, NULL, NULL,
};

int cmd_plot_map(int argc, char **argv)
{
    plot_map_args p = {0};
    int rc = cli_opts_parse(&cli_plot_map_opts, argc, argv, &p);
    if (rc >= 0)
        return rc;
    const char *in = p.in, *out = p.out, *truth_path = p.truth_path;
    double scale = p.scale, pitch = p.pitch;
    if (!in || !out)
        return cli_usage_error("plot map", "G.csv and -o map.svg are required (see --help)");
    sc_error err;
    sc_error_clear(&err);
    sc_stage_map m, t;
    memset(&t, 0, sizeof t);
    cli_input src; /* looked at, then read: a pipe from its in-memory copy */
    if (cli_input_open(&src, in, 1, &err) != SC_OK)
        return cli_report(&err);
    int plate = is_artifact_file(src.path);
    sc_status st = plate ? sc_grid_read_artifact(src.path, pitch > 0 ? pitch : 1.0, &m, &err)
                         : sc_stage_map_read(src.path, &m, &err);
    if (st != SC_OK) {
        rc = cli_report(&err);
        cli_input_close(&src);
        return rc;
    }
    if (truth_path) {
        st = plate ? sc_grid_read_artifact(truth_path, m.px_mm, &t, &err)
                   : sc_stage_map_read(truth_path, &t, &err);
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
            plot_map_svg(f.fp, &m, truth_path ? &t : NULL, scale, cli_basename(in), plate);
            st = sc_afile_commit(&f, &err);
        }
    }
    sc_stage_map_free(&m);
    sc_stage_map_free(&t);
    rc = st == SC_OK ? CLI_OK : cli_report(&err);
    cli_input_close(&src);
    return rc;
}
