/* svg.c — the SVG primitives of svg.h (charts, text that fits, palettes, bands, bars); written by
 * hand because the output is a few element types and no Debian C library writes SVG charts. */
#include "svg.h"

#include <math.h>
#include <stdarg.h>
#include <string.h>

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
    c->logx = c->logy = 0;
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
    /* a span of a few ulps (1 and 1.0000000000000008: fuzz_plot_xy) is as empty as none: its
     * step would vanish against the values and the tick loops never end */
    if (!(*hi > *lo) || *hi - *lo <= 1e-9 * fmax(fabs(*lo), fabs(*hi))) {
        double m = *lo;
        *lo = m - (fabs(m) > 0 ? fabs(m) * 0.1 : 1);
        *hi = m + (fabs(m) > 0 ? fabs(m) * 0.1 : 1);
    }
    double st = nice_step(*hi - *lo, 6);
    *lo = floor(*lo / st) * st;
    *hi = ceil(*hi / st) * st;
}

void svg_escape(FILE *fp, const char *s)
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
    svg_escape(fp, buf);
    fputs("</text>\n", fp);
}

void svg_axes(const svg_chart *c, const char *xlabel, const char *ylabel, const char *title)
{
    FILE *fp = c->fp;
    double sx = nice_step(c->xmax - c->xmin, 8), sy = nice_step(c->ymax - c->ymin, 6);
    if (c->logx)
        sx = fmax(1.0, ceil(sx)); /* decades */
    if (c->logy)
        sy = fmax(1.0, ceil(sy));
    /* ticks by index, at most 100 each way: t += step could stall on a span of a few ulps */
    double kx = ceil(c->xmin / sx), ky = ceil(c->ymin / sy);
    for (int k = 0; k <= 100 && (kx + k) * sx <= c->xmax + 1e-9 * sx; ++k) {
        double t = (kx + k) * sx;
        double px = svg_px(c, t);
        fprintf(fp, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e4e4e4\"/>\n",
                px, c->y, px, c->y + c->h);
        svg_text(fp, px, c->y + c->h + 16, 11, "middle", "#333", "%g",
                 c->logx ? pow(10.0, round(t)) : fabs(t) < 1e-12 * sx ? 0.0 : t);
    }
    for (int k = 0; k <= 100 && (ky + k) * sy <= c->ymax + 1e-9 * sy; ++k) {
        double t = (ky + k) * sy;
        double py = svg_py(c, t);
        fprintf(fp, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#e4e4e4\"/>\n",
                c->x, py, c->x + c->w, py);
        svg_text(fp, c->x - 6, py + 4, 11, "end", "#333", "%g",
                 c->logy ? pow(10.0, round(t)) : fabs(t) < 1e-12 * sy ? 0.0 : t);
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
        svg_text_fit(fp, c->x + c->w / 2, c->y - 12, 15, c->w, "middle", "#000", "%s", title);
}

/* Long curves are thinned to what the drawing shows (the M4 aggregation: U. Jugel et al., "M4: a
 * visualization-oriented time series data aggregation", VLDB 2014): of consecutive points that
 * fall in the same half-pixel column, the first, the lowest, the highest and the last are kept,
 * in their order along the curve, so the line drawn covers the same pixels; a curve of 10⁶ points
 * (a profile) becomes a few thousand instead of a 100 MB drawing. A curve whose points lie half a
 * pixel apart or more keeps every point. */
static void put_point(const svg_chart *c, const double *xv, const double *yv, int k)
{
    fprintf(c->fp, "%.2f,%.2f ", svg_px(c, xv[k]), svg_py(c, yv[k]));
}

/* One column's kept points: first, the lower and higher in the order met, last (no repeats). */
static void put_column(const svg_chart *c, const double *xv, const double *yv, int first, int low,
                       int high, int last, int step)
{
    int k[4] = {first, low, high, last};
    if ((low - high) * step > 0) {
        k[1] = high;
        k[2] = low;
    }
    for (int i = 0; i < 4; ++i)
        if (i == 0 || k[i] != k[i - 1])
            put_point(c, xv, yv, k[i]);
}

/* Points from, from + step, ... (to excluded; all finite) as "x,y " pairs, thinned per column. */
static void put_thinned(const svg_chart *c, const double *xv, const double *yv, int from, int to,
                        int step)
{
    int first = -1, low = -1, high = -1, last = -1;
    double column = 0;
    for (int k = from; k != to; k += step) {
        double col = floor(2 * svg_px(c, xv[k]));
        if (first >= 0 && col == column) {
            low = yv[k] < yv[low] ? k : low;
            high = yv[k] > yv[high] ? k : high;
            last = k;
            continue;
        }
        if (first >= 0)
            put_column(c, xv, yv, first, low, high, last, step);
        first = low = high = last = k;
        column = col;
    }
    if (first >= 0)
        put_column(c, xv, yv, first, low, high, last, step);
}

void svg_polyline(const svg_chart *c, const double *xv, const double *yv, int n,
                  const char *color, double width, const char *dash)
{
    int k = 0;
    while (k < n) { /* each run of finite points is one polyline */
        while (k < n && !(isfinite(xv[k]) && isfinite(yv[k])))
            ++k;
        int a = k;
        while (k < n && isfinite(xv[k]) && isfinite(yv[k]))
            ++k;
        if (k == a)
            continue;
        fprintf(c->fp, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"%.2f\"%s%s%s points=\"",
                color, width, dash ? " stroke-dasharray=\"" : "", dash ? dash : "", dash ? "\"" : "");
        put_thinned(c, xv, yv, a, k, 1);
        fputs("\"/>\n", c->fp);
    }
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

double svg_nice_step(double span, int target) { return nice_step(span, target); }

double svg_text_width(const char *text, double size)
{
    double w = 0;
    for (const unsigned char *s = (const unsigned char *)text; *s; ++s)
        if ((*s & 0xC0) != 0x80) /* count UTF-8 characters, not bytes */
            w += (*s == ' ' || *s == '.' || *s == ',' || *s == 'i' || *s == 'l' || *s == '/')
                     ? 0.33
                     : (*s >= 'A' && *s <= 'Z') || *s == 'm' || *s == 'w' ? 0.72 : 0.58;
    return w * size;
}

/* Cut the middle of s (UTF-8) so that it is at most max_chars characters, with "…" in the gap. */
static void elide_middle(char *s, size_t cap, int max_chars)
{
    int nchar = 0;
    for (const unsigned char *p = (const unsigned char *)s; *p; ++p)
        nchar += (*p & 0xC0) != 0x80;
    if (nchar <= max_chars || max_chars < 5)
        return;
    int keep_head = (max_chars - 1) / 2, keep_tail = max_chars - 1 - keep_head;
    /* byte offsets of the head end and the tail start */
    size_t head = 0, tail = strlen(s);
    for (int k = 0; k < keep_head; ++k)
        do
            ++head;
        while ((s[head] & 0xC0) == 0x80);
    for (int k = 0; k < keep_tail; ++k)
        do
            --tail;
        while (tail > 0 && (s[tail] & 0xC0) == 0x80);
    /* head bytes, "…" (3 bytes), the tail: never longer than s itself plus 3, cut to cap */
    static const char ell[] = "…";
    size_t tail_len = strlen(s + tail), ell_len = sizeof ell - 1;
    if (head + ell_len + tail_len + 1 > cap)
        return;
    memmove(s + head + ell_len, s + tail, tail_len + 1);
    memcpy(s + head, ell, ell_len);
}

void svg_text_fit(FILE *fp, double x, double y, double size, double max_w, const char *anchor,
                  const char *color, const char *fmt, ...)
{
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    double w = svg_text_width(buf, size);
    if (w > max_w) {
        double s2 = fmax(8.0, size * max_w / w);
        w = w * s2 / size;
        size = s2;
        if (w > max_w) {
            int nchar = 0;
            for (const unsigned char *p = (const unsigned char *)buf; *p; ++p)
                nchar += (*p & 0xC0) != 0x80;
            elide_middle(buf, sizeof buf, (int)(nchar * max_w / w));
        }
    }
    svg_text(fp, x, y, size, anchor, color, "%s", buf);
}

void svg_palette(double t, int diverging, char out[8])
{
    /* control points, linearly interpolated in RGB */
    static const double div[5][3] = {{33, 102, 172}, {146, 197, 222}, {247, 247, 247},
                                     {244, 165, 130}, {178, 24, 43}};
    static const double seq[5][3] = {{255, 255, 217}, {199, 233, 180}, {65, 182, 196},
                                     {34, 94, 168}, {8, 29, 88}};
    static const double heat[5][3] = {{255, 255, 229}, {254, 227, 145}, {254, 178, 76},
                                      {240, 101, 60}, {189, 30, 36}};
    const double(*pal)[3] = diverging == SVG_PALETTE_HEAT ? heat : diverging ? div : seq;
    if (!isfinite(t))
        t = 0.5;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double u = t * 4;
    int k = u >= 4 ? 3 : (int)u;
    double f = u - k;
    int rgb[3];
    for (int a = 0; a < 3; ++a)
        rgb[a] = (int)lround(pal[k][a] + f * (pal[k + 1][a] - pal[k][a]));
    snprintf(out, 8, "#%02x%02x%02x", rgb[0], rgb[1], rgb[2]);
}

void svg_band(const svg_chart *c, const double *xv, const double *lo, const double *hi, int n,
              const char *color, double opacity)
{
    int k = 0;
    while (k < n) {
        while (k < n && !(isfinite(xv[k]) && isfinite(lo[k]) && isfinite(hi[k])))
            ++k;
        int a = k;
        while (k < n && isfinite(xv[k]) && isfinite(lo[k]) && isfinite(hi[k]))
            ++k;
        if (k - a < 2)
            continue;
        fprintf(c->fp, "<polygon fill=\"%s\" fill-opacity=\"%.2f\" stroke=\"none\" points=\"", color,
                opacity);
        put_thinned(c, xv, hi, a, k, 1); /* the upper edge forwards, the lower one back */
        put_thinned(c, xv, lo, k - 1, a - 1, -1);
        fputs("\"/>\n", c->fp);
    }
}

double svg_color_bar_extent(double w, double vmin, double vmax, const char *label)
{
    double ext = w + 6, lab = label ? svg_text_width(label, 12) / 2 + w / 2 : 0;
    if (vmax > vmin) {
        double st = nice_step(vmax - vmin, 5), k0 = ceil(vmin / st), widest = 0;
        for (int k = 0; k <= 100 && (k0 + k) * st <= vmax + 1e-9 * st; ++k) {
            char b[48];
            double t = (k0 + k) * st;
            snprintf(b, sizeof b, "%g", fabs(t) < 1e-12 * st ? 0.0 : t);
            widest = fmax(widest, svg_text_width(b, 11));
        }
        ext += widest;
    }
    return fmax(ext, lab) + 4;
}

void svg_color_bar(FILE *fp, double x, double y, double w, double h, double vmin, double vmax,
                   int diverging, const char *label)
{
    const int steps = 64;
    char col[8];
    for (int s = 0; s < steps; ++s) {
        svg_palette((s + 0.5) / steps, diverging, col);
        fprintf(fp, "<rect x=\"%.1f\" y=\"%.2f\" width=\"%.1f\" height=\"%.2f\" fill=\"%s\"/>\n", x,
                y + h - (s + 1) * h / steps, w, h / steps + 0.3, col);
    }
    fprintf(fp, "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" stroke=\"#333\"/>\n",
            x, y, w, h);
    if (vmax > vmin) {
        double st = nice_step(vmax - vmin, 5);
        double k0 = ceil(vmin / st); /* by index, at most 100: see svg_axes */
        for (int k = 0; k <= 100 && (k0 + k) * st <= vmax + 1e-9 * st; ++k) {
            double t = (k0 + k) * st;
            double py = y + h - (t - vmin) / (vmax - vmin) * h;
            fprintf(fp, "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"#333\"/>\n",
                    x + w, py, x + w + 4, py);
            svg_text(fp, x + w + 6, py + 4, 11, "start", "#333", "%g", fabs(t) < 1e-12 * st ? 0.0 : t);
        }
    }
    if (label)
        svg_text(fp, x + w / 2, y - 8, 12, "middle", "#000", "%s", label);
}

void svg_bars(const svg_chart *c, double lo, double hi, const long *cnt, int nb, const char *color)
{
    double bw = (hi - lo) / nb;
    for (int b = 0; b < nb; ++b) {
        if (cnt[b] <= 0)
            continue;
        double x1 = svg_px(c, lo + b * bw), x2 = svg_px(c, lo + (b + 1) * bw);
        double y1 = svg_py(c, (double)cnt[b]), y0 = svg_py(c, 0);
        fprintf(c->fp,
                "<rect x=\"%.2f\" y=\"%.2f\" width=\"%.2f\" height=\"%.2f\" fill=\"%s\" "
                "stroke=\"white\" stroke-width=\"0.5\"/>\n",
                x1, y1, fmax(0.5, x2 - x1), y0 - y1, color);
    }
}
