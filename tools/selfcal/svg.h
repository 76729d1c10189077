/* svg.h — just enough SVG to draw charts: axes with round ticks, polylines, bands, arrows, text,
 * colour scales and histogram bars. Shared by `selfcal plot`, `grid/profile --plot` and `report`. */
#ifndef SELFCAL_SVG_H
#define SELFCAL_SVG_H

#include <stdio.h>

typedef struct svg_chart {
    FILE *fp;
    double x, y, w, h;             /* plot area in px */
    double xmin, xmax, ymin, ymax; /* data range */
    int logx, logy;                /* 1: the data are log10 of the values; ticks read 10^k */
} svg_chart;

/* Start a document of w x h px (white background) / close it. */
void svg_begin(FILE *fp, int w, int h);
void svg_end(FILE *fp);

/* A chart whose plot area is (x, y, w, h) px, showing [xmin, xmax] x [ymin, ymax]. */
void svg_chart_init(svg_chart *c, FILE *fp, double x, double y, double w, double h, double xmin,
                    double xmax, double ymin, double ymax);

/* Data -> px. */
double svg_px(const svg_chart *c, double xv);
double svg_py(const svg_chart *c, double yv);

/* Frame, grid lines, round-number ticks, axis labels and title. */
void svg_axes(const svg_chart *c, const char *xlabel, const char *ylabel, const char *title);

/* A polyline through n data points (NaN points break the line); dash may be NULL. */
void svg_polyline(const svg_chart *c, const double *xv, const double *yv, int n,
                  const char *color, double width, const char *dash);

/* Legend entry number k (top-right of the plot area). */
void svg_legend(const svg_chart *c, int k, const char *label, const char *color, const char *dash);

/* An arrow from (x1, y1) to (x2, y2) in px. */
void svg_arrow(FILE *fp, double x1, double y1, double x2, double y2, const char *color,
               double width);

/* A circle of radius r px. */
void svg_dot(FILE *fp, double x, double y, double r, const char *color);

/* Text at (x, y) px; anchor "start", "middle" or "end"; XML special characters are escaped. */
void svg_text(FILE *fp, double x, double y, double size, const char *anchor, const char *color,
              const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 7, 8)))
#endif
    ;

/* Write s with the XML special characters & < > " escaped (also what the HTML report uses). */
void svg_escape(FILE *fp, const char *s);

/* Text like svg_text that fits in max_w px: the font shrinks (down to 8 px) and, if that is
 * not enough, the middle of the text is replaced by "…" (long file paths keep both ends). */
void svg_text_fit(FILE *fp, double x, double y, double size, double max_w, const char *anchor,
                  const char *color, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 8, 9)))
#endif
    ;

/* Approximate width in px of text at font size (DejaVu Sans average advance). */
double svg_text_width(const char *text, double size);

/* Round the range [lo, hi] out to "nice" numbers (1, 2, 5 x 10^k). */
void svg_nice_range(double *lo, double *hi);

/* A round tick step for a span shown with about target ticks. */
double svg_nice_step(double span, int target);

/* Colour of t in [0, 1] on a palette: diverging (blue, white, red; 0.5 = white) for signed
 * values, else sequential (light yellow to dark blue) for magnitudes. Writes "#rrggbb". */
void svg_palette(double t, int diverging, char out[8]);
#define SVG_PALETTE_HEAT 2 /* diverging = 2: a light yellow-to-red scale (under blue arrows) */

/* Filled band between lo[] and hi[] over xv[] (data coordinates; a NaN in any breaks the band). */
void svg_band(const svg_chart *c, const double *xv, const double *lo, const double *hi, int n,
              const char *color, double opacity);

/* How far right of x a colour bar of width w drawn by svg_color_bar reaches (its tick labels, its
 * label above it), in px: what a drawing must leave for it. */
double svg_color_bar_extent(double w, double vmin, double vmax, const char *label);

/* A colour scale bar at (x, y) px, w x h (vertical), for [vmin, vmax], with round ticks and a
 * label (unit) above it. */
void svg_color_bar(FILE *fp, double x, double y, double w, double h, double vmin, double vmax,
                   int diverging, const char *label);

/* Vertical bars of a histogram on chart c: nb bins of equal width from lo to hi, counts cnt. */
void svg_bars(const svg_chart *c, double lo, double hi, const long *cnt, int nb, const char *color);

#endif
