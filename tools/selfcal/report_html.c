/* report_html.c — the HTML building blocks of `selfcal report` (report_html.h). Hand-written: the
 * page is a few element types, and it must stay one file with nothing fetched from outside. */
#define _GNU_SOURCE /* open_memstream */
#include "report_html.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli.h"
#include "selfcal/grid_lsq.h" /* sc_chi2_quantile */
#include "selfcal/sha256.h"
#include "selfcal/version.h"
#include "svg.h"

static const char *CSS =
    "body{font-family:'DejaVu Sans',Arial,sans-serif;max-width:1100px;margin:1.5em auto;"
    "padding:0 1em;color:#111;line-height:1.35}\n"
    "h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.25em;border-bottom:1px solid #999;"
    "margin-top:1.6em}h3{font-size:1.05em}\n"
    "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:.2em .55em;"
    "text-align:right;font-variant-numeric:tabular-nums}th{background:#eef1f6}"
    "td.l,th.l{text-align:left}\n"
    "figure{margin:1em 0;break-inside:avoid;page-break-inside:avoid}"
    "figure svg{max-width:100%;height:auto;display:block}figcaption{font-size:.9em;color:#333}\n"
    ".pass{color:#11602a;font-weight:bold}.fail{color:#a3121c;font-weight:bold}"
    ".inconclusive{color:#8a5a00;font-weight:bold}"
    ".note{background:#fff7e0;border-left:4px solid #e0a800;padding:.4em .8em}"
    ".mono{font-family:'DejaVu Sans Mono',monospace;font-size:.85em;word-break:break-all}\n"
    ".summary{background:#f3f6fb;border:1px solid #c5d0e0;padding:.5em 1em}\n"
    ".cert th{width:16em}.statement{border-left:4px solid #5a7bb5;padding:.3em .8em}\n"
    "@media print{body{max-width:none;margin:0;font-size:10pt}h1,h2,h3{break-after:avoid;"
    "page-break-after:avoid}section{break-inside:auto}table,figure{break-inside:avoid;"
    "page-break-inside:avoid}table.map{break-inside:auto;page-break-inside:auto;font-size:8pt}"
    "thead{display:table-header-group}tr{break-inside:avoid;page-break-inside:avoid}"
    "figure svg{max-height:120mm;width:auto;max-width:100%}"
    "details>summary{display:none}details{display:block}"
    "a{color:inherit;text-decoration:none}@page{size:A4;margin:15mm}}\n";

void html_esc(FILE *fp, const char *s) { svg_escape(fp, s); }

void html_textf(FILE *fp, const char *fmt, ...)
{
    char buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    html_esc(fp, buf);
}

void html_begin(FILE *fp, const char *title)
{
    fputs("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
          "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>",
          fp);
    html_esc(fp, title);
    fprintf(fp, "</title>\n<style>\n%s</style>\n</head>\n<body>\n", CSS);
}

void html_end(FILE *fp) { fputs("</body>\n</html>\n", fp); }

sc_status html_figure(FILE *fp, html_draw_fn draw, const void *ctx, const char *caption,
                      sc_error *err)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *ms = open_memstream(&buf, &len);
    if (!ms)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (figure)");
    draw(ms, ctx);
    if (fclose(ms) != 0 || !buf) {
        free(buf);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (figure)");
    }
    /* inline SVG needs neither the XML prolog nor the namespace attribute (HTML5 puts <svg> in
     * the SVG namespace): the page then holds no URL at all */
    const char *svg = strstr(buf, "<svg");
    fputs("<figure>\n", fp);
    if (svg) {
        static const char ns[] = " xmlns=\"http://www.w3.org/2000/svg\"";
        const char *at = strstr(svg, ns);
        if (at && at < strchr(svg, '>')) {
            fwrite(svg, 1, (size_t)(at - svg), fp);
            fputs(at + sizeof ns - 1, fp);
        } else
            fputs(svg, fp);
    }
    if (caption) {
        fputs("<figcaption>", fp);
        html_esc(fp, caption);
        fputs("</figcaption>\n", fp);
    }
    fputs("</figure>\n", fp);
    free(buf);
    return SC_OK;
}

/* <tag id data-v>fmt</tag>, or "—" when v is not finite. */
static void num_element(FILE *fp, const char *tag, const char *id, const char *fmt, double v)
{
    fprintf(fp, "<%s", tag);
    if (id)
        fprintf(fp, " id=\"%s\"", id);
    if (isfinite(v)) {
        fprintf(fp, " data-v=\"%.17g\">", v);
        fprintf(fp, fmt, v);
    } else
        fputs(">—", fp);
    fprintf(fp, "</%s>", tag);
}

void html_num_cell(FILE *fp, const char *id, const char *fmt, double v)
{
    num_element(fp, "td", id, fmt, v);
}

void html_num_span(FILE *fp, const char *id, const char *fmt, double v)
{
    num_element(fp, "span", id, fmt, v);
}

void html_u_row(FILE *fp, const char *name, const char *id, double v, double u, const char *fmt,
                const char *unit)
{
    char a[96], b[96];
    fputs("<tr><td class=\"l\">", fp);
    html_esc(fp, name);
    fputs("</td>", fp);
    html_num_cell(fp, id, fmt, v);
    snprintf(a, sizeof a, "%s-u", id);
    snprintf(b, sizeof b, "%s-U2", id);
    html_num_cell(fp, a, fmt, u);
    html_num_cell(fp, b, fmt, 2 * u);
    fputs("<td class=\"l\">", fp);
    html_esc(fp, unit);
    fputs("</td></tr>\n", fp);
}

int html_chi2_interval(double vf, long dof, double *lo, double *hi)
{
    *lo = *hi = NAN;
    if (dof <= 0 || !isfinite(vf))
        return -1;
    *lo = sc_chi2_quantile(0.025, (double)dof) / dof;
    *hi = sc_chi2_quantile(0.975, (double)dof) / dof;
    return vf >= *lo && vf <= *hi;
}

sc_status html_provenance(FILE *fp, int argc, char **argv, const cli_input *const *inputs,
                          const char *const *roles, int n_inputs, sc_error *err)
{
    time_t now = time(NULL);
    const char *sde = getenv("SOURCE_DATE_EPOCH");
    if (sde && *sde) {
        char *e;
        long long v = strtoll(sde, &e, 10);
        if (!*e && v >= 0)
            now = (time_t)v;
    }
    struct tm tm;
    char date[64];
    gmtime_r(&now, &tm);
    strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", &tm);
    fputs("<section id=\"provenance\">\n<h2>Provenance</h2>\n<table>\n", fp);
    fputs("<tr><th class=\"l\">tool</th><td class=\"l\" id=\"version\">selfcal ", fp);
    html_esc(fp, sc_version());
    fprintf(fp, "</td></tr>\n<tr><th class=\"l\">created (UTC)</th><td class=\"l\" id=\"date\">%s</td></tr>\n", date);
    fputs("<tr><th class=\"l\">command line</th><td class=\"l mono\" id=\"cmdline\">selfcal", fp);
    for (int a = 0; a < argc; ++a) {
        fputc(' ', fp);
        int plain = argv[a][0] != '\0';
        for (const char *c = argv[a]; *c; ++c)
            if (!strchr("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_./=:,+@%", *c))
                plain = 0;
        if (plain) {
            html_esc(fp, argv[a]);
        } else { /* shell single quotes, so that the line can be pasted back */
            fputc('\'', fp);
            for (const char *c = argv[a]; *c; ++c) {
                if (*c == '\'')
                    fputs("'\\''", fp);
                else {
                    char one[2] = {*c, 0};
                    html_esc(fp, one);
                }
            }
            fputc('\'', fp);
        }
    }
    fputs("</td></tr>\n</table>\n<table>\n<tr><th class=\"l\">input</th><th class=\"l\">file</th>"
          "<th>bytes</th><th class=\"l\">SHA-256</th></tr>\n", fp);
    for (int k = 0; k < n_inputs; ++k) {
        uint8_t dig[SC_SHA256_BYTES];
        char hex[2 * SC_SHA256_BYTES + 1];
        long long size;
        sc_status st = cli_input_sha256(inputs[k], dig, &size, err);
        if (st != SC_OK) {
            if (err) {
                err->code = SC_E_INPUT;
                snprintf(err->file, sizeof err->file, "%s", inputs[k]->orig);
            }
            return SC_E_INPUT;
        }
        sc_sha256_hex(dig, hex);
        fputs("<tr><td class=\"l\">", fp);
        html_esc(fp, roles[k]);
        fputs("</td><td class=\"l mono\">", fp);
        html_esc(fp, inputs[k]->orig);
        fprintf(fp, "</td><td>%lld</td><td class=\"l mono sha256\">%s</td></tr>\n", size, hex);
    }
    fputs("</table>\n<p>Check an input with <code>sha256sum FILE</code>. Uncertainties are standard "
          "uncertainties u (k = 1) and expanded uncertainties U = k·u with coverage factor k = 2 "
          "(about 95 % coverage for a normal distribution), as the GUM (JCGM 100) states them.</p>\n"
          "</section>\n",
          fp);
    return SC_OK;
}
