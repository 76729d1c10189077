/* report_cert.h — what makes a report a calibration certificate (SPEC §12, ISO/IEC 17025 §7.8):
 * the identification given by --info KEY=VALUE and --info-file F, its header block, the page
 * label of every printed page, and the statement of what the uncertainties cover; and the
 * report printed to PDF through headless Chromium (--pdf). Shared by report grid and profile. */
#ifndef SELFCAL_REPORT_CERT_H
#define SELFCAL_REPORT_CERT_H

#include <stdio.h>

#include "selfcal/error.h"

#define REPORT_INFO_MAX 64          /* keys */
#define REPORT_INFO_VALUE_MAX 1000  /* bytes of a value */
#define REPORT_INFO_FILE_MAX 65536  /* bytes of an --info-file */

typedef struct report_info {
    int n;
    char *key[REPORT_INFO_MAX], *val[REPORT_INFO_MAX];
    /* the options as given, in order, resolved by report_info_load */
    int n_opt;
    const char *opt_val[2 * REPORT_INFO_MAX];
    int opt_is_file[2 * REPORT_INFO_MAX];
    const char *pdf; /* --pdf R.pdf, or NULL */
} report_info;

/* --info KEY=VALUE, --info-file F or --pdf R.pdf with its value v into ri: CLI_OK, the usage error,
 * or -1 if opt is none of them. */
int report_info_option(const char *cmd, const char *opt, const char *v, report_info *ri);
/* The same as a parse function of an option table (cli_opts.h): field is the report_info. */
int report_info_opt(const char *cmd, const char *opt, const char *v, void *field);

/* Read the --info-file files and apply the --info values, in the order given (a key given again
 * takes the later value). Bad input: SC_E_INPUT naming the file (and line) or the option. */
sc_status report_info_load(report_info *ri, sc_error *err);

/* Free what report_info_load made. */
void report_info_free(report_info *ri);

/* The value of key, or NULL. */
const char *report_info_get(const report_info *ri, const char *key);

/* The certificate block at the top of the report: every key given (known ones by their label,
 * in a fixed order, then the others as given), each value in an element id "info-KEY". */
void report_info_html(FILE *fp, const report_info *ri, const char *kind);

/* The print style of the page label: "REPORT_ID · page n of m" at the foot of every printed
 * page (just "page n of m" without a report id). */
void report_page_css(FILE *fp, const report_info *ri);

/* The uncertainty statement, as a laboratory writes it: what U covers (covers: a sentence,
 * e.g. "the measurement noise, propagated through the least-squares estimate"), the coverage
 * factor and probability, and what is not included (not_included: a sentence, or NULL). */
void report_uncertainty_statement(FILE *fp, const char *covers, const char *not_included);

/* Before anything is written: the Chromium to print with (SELFCAL_CHROMIUM, else chromium,
 * chromium-browser or google-chrome on PATH) into path; SC_E_IO "--pdf needs Chromium ..." if
 * there is none. */
sc_status report_pdf_find(char *path, size_t cap, sc_error *err);

/* Print the HTML file html_path to pdf_path through headless Chromium (network cut; the PDF
 * written beside pdf_path, then renamed into place: complete or absent). */
sc_status report_pdf_print(const char *chromium, const char *html_path, const char *pdf_path,
                           sc_error *err);

/* The outputs of a report command: -o R.html and/or --pdf R.pdf. Before anything is written,
 * report_out_prepare finds Chromium (with --pdf) and names the HTML file to write: out, or,
 * with --pdf alone, a temporary file beside the PDF. report_out_finish then prints the PDF from
 * it (when st is SC_OK) and removes the temporary file; it returns st or the printing's error. */
typedef struct report_out {
    const char *out;     /* -o, or NULL */
    char html[4200];     /* the HTML file written */
    char chromium[4096]; /* with --pdf */
    int temp;            /* html is a temporary file */
} report_out;
sc_status report_out_prepare(report_out *o, const report_info *ri, const char *out, sc_error *err);
sc_status report_out_finish(report_out *o, const report_info *ri, sc_status st, sc_error *err);
#endif
