/* Private to the table reader of measuring machines' exports (import_table.c) and its other
 * layouts (import_layouts.c: one row per axis, items in columns): the field splitting, name
 * matching and number rules they share, and the text encodings. */
#ifndef SELFCAL_IMPORT_TABLE_INTERNAL_H
#define SELFCAL_IMPORT_TABLE_INTERNAL_H

#include <stdbool.h>

#include "selfcal/csv.h"
#include "selfcal/import.h"

#define SC_IMP_MAX_FIELDS 256 /* fields of a line (items in columns: SC_IMP_MAX_ITEMS) */
#define SC_IMP_PREAMBLE_MAX 100 /* lines before the header line that name no columns */
/* More than SC_CSV_MAX_SKIP_RUN lines in a row that give no row (filtered, other axes, empty,
 * unlabelled) are refused: an endless input of them would otherwise be read forever. */
#define SC_IMP_NO_ROW_RUN_MSG \
    "more than %ld lines in a row that are no row (left out by --where, other axes, empty): not " \
    "this table's data (an endless input?)"

/* Split s at delim in place (double-quoted fields may hold it; quotes removed), trimming blanks;
 * the field count, or -1 beyond max. quoted (may be NULL): 1 for each quoted field. */
int sc_imp_split_fields(char *s, char delim, char **field, unsigned char *quoted, int max);
/* Names equal ignoring ASCII case. */
int sc_imp_name_equal(const char *a, const char *b);
/* A column given by its number ("2": the second), or 0 if name is no whole number. */
long sc_imp_column_number(const char *name);
/* Where column name is among the n fields of a header line: the first field of that name
 * (ignoring ASCII case), else its number (1..n), else -1. */
int sc_imp_find_column(char *const *field, int n, const char *name);
/* A field as a number with either decimal mark (*mark_seen: '.', ',' or 0); 0 ok, -2 both marks,
 * -1 no number. */
int sc_imp_parse_number(const char *s, double *out, char *mark_seen);
/* The delimiter of a line: tab, ';', ',' (in that order), else ' ' (blank-aligned columns). */
char sc_imp_delimiter_of(const char *text);
/* Whether text names a statistic (Mean, Mittelwert, Stabw., ...): a summary row's label. */
int sc_imp_names_statistic(const char *text);
/* Whether s has no digit (empty, a unit name, a label). */
int sc_imp_not_a_number(const char *s);
/* Digits after the decimal mark of a number as written ("12.3400": 4). */
int sc_imp_decimals(const char *s);
/* Whether s is valid UTF-8. */
bool sc_imp_utf8_valid(const char *s);
/* Whether field s is one of the layout's placeholder tokens (a mark not measured). */
bool sc_imp_is_placeholder(const sc_table_layout *lay, const char *s);

/* The decimal mark a file uses (0 until a number with a fraction is seen), where it was first
 * seen, and the most digits after it. */
typedef struct sc_imp_marks {
    char mark;
    long mark_line;
    int decimals;
} sc_imp_marks;
/* The end of a read: t's decimal mark (m's, '.' if no number had a fraction) and, with notes,
 * the most decimals seen. */
void sc_imp_set_decimal(const sc_imp_marks *m, sc_table *t, sc_table_notes *notes);
/* A wanted field as a number: one decimal mark per file, no unquoted decimal comma in a
 * comma-separated file, within SC_INPUT_MAX_ABS; SC_E_INPUT at path:ln naming the column. */
sc_status sc_imp_value(sc_imp_marks *m, const char *path, long ln, const char *name,
                       const char *s, int quoted, char delimiter, double *out, sc_error *err);

/* A line's text converted to UTF-8 from the layout's encoding (nothing for UTF-8). */
typedef struct sc_imp_conv {
    void *cd;  /* iconv_t, NULL for UTF-8 */
    char *buf; /* the converted line */
    const char *name;
} sc_imp_conv;
sc_status sc_imp_conv_open(sc_imp_conv *c, sc_table_encoding enc, const char *path, sc_error *err);
/* Convert r's current line in place of r->text (its bytes must be valid in the encoding). */
sc_status sc_imp_conv_line(sc_imp_conv *c, sc_csv *r, sc_error *err);
void sc_imp_conv_close(sc_imp_conv *c);
/* The hint for a header line that is not UTF-8, "" if it is (or an encoding was given). */
const char *sc_imp_encoding_hint(const sc_table_layout *lay, const char *header_text);

/* Open path for a layout: the encoding's converter into c, the line reader r (on failure neither
 * is left open). */
sc_status sc_imp_open(sc_imp_conv *c, sc_csv *r, sc_table_encoding enc, const char *path,
                      sc_error *err);
/* The next line of r that is neither blank nor a comment ('#'), converted to UTF-8 (the lines of
 * one row per axis and of items in columns): 1; 0 at the end; -1 with *st and err set. */
int sc_imp_next_line(sc_csv *r, sc_imp_conv *c, sc_status *st, sc_error *err);
/* The end of every layout's read: r and c closed, and t freed when st is not SC_OK; returns st. */
sc_status sc_imp_close(sc_imp_conv *c, sc_csv *r, sc_table *t, sc_status st);

/* The asked-for names (before anything is read): 1..16 distinct, scales finite and nonzero, the
 * layout's options consistent. */
sc_status sc_imp_check_request(int n_cols, const char *const *names, const double *scale,
                               long max_rows, const sc_table_layout *lay, sc_error *err);
/* What every layout does first: t zeroed with its path and column count, notes zeroed, the
 * request checked (sc_imp_check_request). */
sc_status sc_imp_begin(const char *path, int n_cols, const char *const *names,
                       const double *scale, long max_rows, const sc_table_layout *lay,
                       sc_table_notes *notes, sc_table *t, sc_error *err);
/* Columns of a header line, one row per item: the table reader itself (import_table.c); it
 * begins with sc_imp_begin. */
sc_status sc_imp_read_wide(const char *path, int n_cols, const char *const *names,
                           const double *scale, long max_rows, const sc_table_layout *lay,
                           sc_table_notes *notes, sc_table *t, sc_error *err);
/* The other layouts of sc_table_read_layout (import_layouts.c; arguments checked there, t
 * zeroed with its path). */
sc_status sc_imp_read_long(const char *path, int n_cols, const char *const *names,
                           const double *scale, long max_rows, const sc_table_layout *lay,
                           sc_table_notes *notes, sc_table *t, sc_error *err);
sc_status sc_imp_read_transposed(const char *path, int n_cols, const char *const *names,
                                 const double *scale, long max_rows, const sc_table_layout *lay,
                                 sc_table_notes *notes, sc_table *t, sc_error *err);

#endif
