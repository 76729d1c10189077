#include "svg.h"

#include <math.h>
#include <stdarg.h>

void svg_begin(FILE *fp, int w, int h)
{
    fprintf(fp,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" "
            "viewBox=\"0 0 %d %d\" font-family=\"DejaVu Sans, Arial, sans-serif\">\n"
            "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
            w, h, w, h);
}

void svg_end(FILE *fp) { fprintf(fp, "</svg>\n"); }

void svg_chart_init(svg_chart *c, FILE *fp, double x, double y, double w, double h, double xmin,
                    double xmax, double ymin, double ymax)
{
    c->fp = fp;
    c->x = x;
    c->y = y;
    c->w = w;
    c->h = h;
    if (!(xmax > xmin)) {
        xmin -= 0.5;
        xmax = xmin + 1.0;
    }
    if (!(ymax > ymin)) {
        ymin -= 0.5;
        ymax = ymin + 1.0;
    }
    c->xmin = xmin;
    c->xmax = xmax;
    c->ymin = ymin;
    c->ymax = ymax;
}

double svg_px(const svg_chart *c, double xv) { return c->x + (xv - c->xmin) / (c->xmax - c->xmin) * c->w; }
double svg_py(const svg_chart *c, double yv) { return c->y + c->h - (yv - c->ymin) / (c->ymax - c->ymin) * c->h; }

static double nice_step(double span, int target)
{
    double raw = span / target, mag = pow(10.0, floor(log10(raw))), f = raw / mag;
    return (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10) * mag;
}

void svg_nice_range(double *lo, double *hi)
{
    if (!(*hi > *lo)) {
        double m = *lo;
        *lo = m - (fabs(m) > 0 ? fabs(m) * 0.1 : 1);
        *hi = m + (fabs(m) > 0 ? fabs(m) * 0.1 : 1);
    }
    double st = nice_step(*hi - *lo, 6);
    *lo = floor(*lo / st) * st;
    *hi = ceil(*hi / st) * st;
}

static void text_escaped(FILE *fp, const char *s)
{
    for (; *s; ++s) {
        switch (*s) {
        case '<': fputs("&lt;", fp); break;
        case '>': fputs("&gt;", fp); break;
        case '&': fputs("&amp;", fp); break;
        case '"': fputs("&quot;", fp); break;
        default: fputc(*s, fp);
        }
    }
}

void svg_text(FILE *fp, double x, double y, double size, const char *anchor, const char *color,
              const char *fmt, ...)
{
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    fprintf(fp, "<text x=\"%.1f\" y=\"%.1f\" font-size=\"%.1f\" text-anchor=\"%s\" fill=\"%s\">", x,
            y, size, anchor, color);
    text_escaped(fp, buf);
    fputs("</text>\n", fp);
}

void svg_axes(const svg_chart *c, const char *xlabel, const char *ylabel, const char *title)
{
    FILE *fp = c->fp;
    double sx = nice_step(c->xmax - c->xmin, 8), sy = nice_step(c->ymax - c->ymin, 6);
    for (double t = ceil(c->xmin / sx) * sx; t <= c->xmax + 1e-9 * sx; t += sx) {
        double px = svg_px(c, t);
        fprintf(fp, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e4e4e4\"/>\n",
                px, c->y, px, c->y + c->h);
        svg_text(fp, px, c->y + c->h + 16, 11, "middle", "#333", "%g", fabs(t) < 1e-12 * sx ? 0.0 : t);
    }
    for (double t = ceil(c->ymin / sy) * sy; t <= c->ymax + 1e-9 * sy; t += sy) {
        double py = svg_py(c, t);
        fprintf(fp, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e4e4e4\"/>\n",
                c->x, py, c->x + c->w, py);
        svg_text(fp, c->x - 6, py + 4, 11, "end", "#333", "%g", fabs(t) < 1e-12 * sy ? 0.0 : t);
    }
    fprintf(fp, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" stroke=\"#333\"/>\n",
            c->x, c->y, c->w, c->h);
    if (xlabel)
        svg_text(fp, c->x + c->w / 2, c->y + c->h + 36, 13, "middle", "#000", "%s", xlabel);
    if (ylabel) {
        fprintf(fp, "<g transform=\"translate(%.1f,%.1f) rotate(-90)\">\n", c->x - 52, c->y + c->h / 2);
        svg_text(fp, 0, 0, 13, "middle", "#000", "%s", ylabel);
        fputs("</g>\n", fp);
    }
    if (title)
        svg_text(fp, c->x + c->w / 2, c->y - 12, 15, "middle", "#000", "%s", title);
}

void svg_polyline(const svg_chart *c, const double *xv, const double *yv, int n,
                  const char *color, double width, const char *dash)
{
    int open = 0;
    for (int k = 0; k < n; ++k) {
        if (!isfinite(xv[k]) || !isfinite(yv[k])) {
            if (open)
                fputs("\"/>\n", c->fp);
            open = 0;
            continue;
        }
        if (!open) {
            fprintf(c->fp, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"%.2f\"%s%s%s points=\"",
                    color, width, dash ? " stroke-dasharray=\"" : "", dash ? dash : "", dash ? "\"" : "");
            open = 1;
        }
        fprintf(c->fp, "%.2f,%.2f ", svg_px(c, xv[k]), svg_py(c, yv[k]));
    }
    if (open)
        fputs("\"/>\n", c->fp);
}

void svg_legend(const svg_chart *c, int k, const char *label, const char *color, const char *dash)
{
    double x = c->x + c->w - 220, y = c->y + 18 + 18 * k;
    fprintf(c->fp, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\" stroke-width=\"2\"%s%s%s/>\n",
            x, y - 4, x + 28, y - 4, color, dash ? " stroke-dasharray=\"" : "", dash ? dash : "", dash ? "\"" : "");
    svg_text(c->fp, x + 34, y, 12, "start", "#000", "%s", label);
}

void svg_arrow(FILE *fp, double x1, double y1, double x2, double y2, const char *color, double width)
{
    double dx = x2 - x1, dy = y2 - y1, len = sqrt(dx * dx + dy * dy);
    fprintf(fp, "<line x1=\"%.2f\" y1=\"%.2f\" x2=\"%.2f\" y2=\"%.2f\" stroke=\"%s\" stroke-width=\"%.2f\"/>\n",
            x1, y1, x2, y2, color, width);
    if (len < 1e-9)
        return;
    double head = len < 12 ? len * 0.35 : 4.5, ux = dx / len, uy = dy / len;
    fprintf(fp, "<polygon points=\"%.2f,%.2f %.2f,%.2f %.2f,%.2f\" fill=\"%s\"/>\n", x2, y2,
            x2 - head * ux + head * 0.5 * uy, y2 - head * uy - head * 0.5 * ux,
            x2 - head * ux - head * 0.5 * uy, y2 - head * uy + head * 0.5 * ux, color);
}

void svg_dot(FILE *fp, double x, double y, double r, const char *color)
{
    fprintf(fp, "<circle cx=\"%.2f\" cy=\"%.2f\" r=\"%.2f\" fill=\"%s\"/>\n", x, y, r, color);
}
