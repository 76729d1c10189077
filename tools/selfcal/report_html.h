/* report_html.h — the pieces of a self-contained HTML calibration report: page head and print
 * style, escaped text, figures inlined as SVG, numbers with ids a test can find, provenance. */
#ifndef SELFCAL_REPORT_HTML_H
#define SELFCAL_REPORT_HTML_H

#include <stdio.h>

#include "selfcal/error.h"
#include "input_once.h"

/* Start the page (doctype, inline CSS with @media print) with a title; end it. */
void html_begin(FILE *fp, const char *title);
void html_end(FILE *fp);

/* Write s with &, <, >, " escaped. */
void html_esc(FILE *fp, const char *s);

/* printf into the page, escaping the formatted text. */
void html_textf(FILE *fp, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* A figure: draw() writes a whole SVG document to the stream it is given; it is inlined
 * (without its XML prolog) with a caption. SC_E_NOMEM if the memory stream fails. */
typedef void (*html_draw_fn)(FILE *fp, const void *ctx);
sc_status html_figure(FILE *fp, html_draw_fn draw, const void *ctx, const char *caption,
                      sc_error *err);

/* A table cell holding v with printf format fmt, id'd (id may be NULL) and with the full value in
 * data-v so that a reader can compare it to the summary files; NaN prints "—". */
void html_num_cell(FILE *fp, const char *id, const char *fmt, double v);

/* The number v in running text: <span id data-v>fmt</span>, or "—" when v is not finite (no
 * "nan" in a report). id may be NULL. */
void html_num_span(FILE *fp, const char *id, const char *fmt, double v);

/* A row "name | value | u (k = 1) | U (k = 2) | unit" (u NaN: "—"); id prefixes the cells' ids
 * (id, id-u, id-U2). */
void html_u_row(FILE *fp, const char *name, const char *id, double v, double u, const char *fmt,
                const char *unit);

/* The provenance section: tool version, creation time (UTC; SOURCE_DATE_EPOCH if set), command
 * line, and the size and SHA-256 of every input (SC_E_INPUT naming the file if one is unreadable). */
sc_status html_provenance(FILE *fp, int argc, char **argv, const cli_input *const *inputs,
                          const char *const *roles, int n_inputs, sc_error *err);

/* The χ² test of a variance factor vf with dof degrees of freedom at 95 % (two-sided): writes
 * the interval and returns 1 pass, 0 fail, -1 not applicable. */
int html_chi2_interval(double vf, long dof, double *lo, double *hi);

#endif
