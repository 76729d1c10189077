/* svg.h — just enough SVG to draw charts: axes with round ticks, polylines, arrows, text. */
#ifndef SELFCAL_SVG_H
#define SELFCAL_SVG_H

#include <stdio.h>

typedef struct svg_chart {
    FILE *fp;
    double x, y, w, h;             /* plot area in px */
    double xmin, xmax, ymin, ymax; /* data range */
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

/* Round the range [lo, hi] out to "nice" numbers (1, 2, 5 x 10^k). */
void svg_nice_range(double *lo, double *hi);

#endif
