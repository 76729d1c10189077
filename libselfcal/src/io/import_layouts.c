/* import_layouts.c — the other layouts of sc_table_read_layout (SPEC §10a):
 *   - one row per axis (PC-DMIS, CALYPSO *_chr.txt, GEOPAK): rows with the same ID form a point,
 *     the AXIS value says which coordinate the row's VALUE is;
 *   - items in columns (a spreadsheet with one column per point): the rows are labelled X, Y, ...
 *     by their first field, each further column is a point.
 * Both share the field, name and number rules of import_table.c (import_table_internal.h). */
#include <ctype.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "import_table_internal.h"

#define LONG_MAX_COLS 16
#define MAX_ITEMS (SC_CSV_MAX_LINE / 2 + 1) /* the most fields a line can hold */

/* ---- one row per axis ---- */

/* A point being gathered: its coordinates as rows come (values, then nominals). */
typedef struct long_reader {
    const char *path;
    int n_cols, n_out;        /* axes, and columns of the table (2 n_cols with nominals) */
    const char *const *names; /* the axes' names */
    long max_rows;
    char *ids;                /* every point's ID, NUL-terminated, one after another */
    size_t ids_len, ids_cap;
    size_t *id_at;            /* per point: its ID's offset in ids */
    unsigned *seen, *have;    /* per point: axes with a row, axes with a value */
    long *line;               /* per point: its first row's line */
    double *value;            /* per point: n_out values */
    long n_points, cap;
    long n_used;              /* rows that gave a point a coordinate (or its absence) */
    long *slot;               /* hash table of points (-1 empty), n_slots a power of 2 */
    size_t n_slots;
    /* the file being read */
    const sc_table_layout *lay;
    const double *scale;      /* per output column (NULL: 1) */
    sc_table *t;
    sc_table_notes *notes;
    sc_csv r;
    const char *cols[4 + SC_TABLE_MAX_WHERE]; /* id, axis, value [, nominal], where... */
    int col_of[4 + SC_TABLE_MAX_WHERE], n_need; /* where each is, how many */
    int n_header, in_rows;    /* the header's fields; whether it was found */
    int best_named;           /* the columns the last line before the header named */
    int best;                 /* the most columns a line before the header named (-1: none), */
    long best_line;           /* that line and its text, for the error when no header is found */
    char best_text[4096];
    long preamble, first_row, no_row_run; /* lines before the header, the first row (no header),
                                             lines in a row that gave no point a value */
    sc_imp_marks marks;
    char *field[SC_IMP_MAX_FIELDS];
    unsigned char quoted[SC_IMP_MAX_FIELDS];
} long_reader;

static uint64_t hash_id(const char *s)
{
    uint64_t h = 1469598103934665603ull; /* FNV-1a */
    for (; *s; ++s)
        h = (h ^ (unsigned char)*s) * 1099511628211ull;
    return h;
}

/* Room for one more point (and the hash table kept at most half full). */
static sc_status long_grow(long_reader *lr, long ln, sc_error *err)
{
    if (lr->n_points >= lr->max_rows)
        return sc_error_set(err, SC_E_INPUT, lr->path, ln,
                            "more than %ld points, the most this import takes", lr->max_rows);
    if (lr->n_points < lr->cap)
        return SC_OK;
    long ncap = lr->cap ? 2 * lr->cap : 256;
    if (ncap > lr->max_rows)
        ncap = lr->max_rows;
    size_t nc = (size_t)ncap;
    size_t *a = realloc(lr->id_at, nc * sizeof *a);
    if (a) lr->id_at = a;
    unsigned *b = a ? realloc(lr->seen, nc * sizeof *b) : NULL;
    if (b) lr->seen = b;
    unsigned *c = b ? realloc(lr->have, nc * sizeof *c) : NULL;
    if (c) lr->have = c;
    long *d = c ? realloc(lr->line, nc * sizeof *d) : NULL;
    if (d) lr->line = d;
    double *e = d ? realloc(lr->value, nc * (size_t)lr->n_out * sizeof *e) : NULL;
    if (e) lr->value = e;
    size_t nslots = 1;
    while (nslots < 2 * nc)
        nslots *= 2;
    long *f = e ? malloc(nslots * sizeof *f) : NULL;
    if (!f)
        return sc_error_set(err, SC_E_NOMEM, lr->path, ln, "out of memory (%ld points)", ncap);
    for (size_t k = 0; k < nslots; ++k)
        f[k] = -1;
    for (long p = 0; p < lr->n_points; ++p) { /* rehash */
        size_t h = (size_t)hash_id(lr->ids + lr->id_at[p]) & (nslots - 1);
        while (f[h] >= 0)
            h = (h + 1) & (nslots - 1);
        f[h] = p;
    }
    free(lr->slot);
    lr->slot = f;
    lr->n_slots = nslots;
    lr->cap = ncap;
    return SC_OK;
}

/* The point of ID id, made if new (*made = 1); -1 on error. */
static long long_point(long_reader *lr, const char *id, long ln, int *made, sc_error *err)
{
    *made = 0;
    if (lr->n_slots) {
        size_t h = (size_t)hash_id(id) & (lr->n_slots - 1);
        for (; lr->slot[h] >= 0; h = (h + 1) & (lr->n_slots - 1))
            if (!strcmp(lr->ids + lr->id_at[lr->slot[h]], id))
                return lr->slot[h];
    }
    if (long_grow(lr, ln, err) != SC_OK)
        return -1;
    size_t len = strlen(id) + 1;
    if (lr->ids_len + len > lr->ids_cap) {
        size_t ncap = lr->ids_cap ? 2 * lr->ids_cap : 4096;
        while (ncap < lr->ids_len + len)
            ncap *= 2;
        char *n = realloc(lr->ids, ncap);
        if (!n) {
            sc_error_set(err, SC_E_NOMEM, lr->path, ln, "out of memory");
            return -1;
        }
        lr->ids = n;
        lr->ids_cap = ncap;
    }
    long p = lr->n_points++;
    memcpy(lr->ids + lr->ids_len, id, len);
    lr->id_at[p] = lr->ids_len;
    lr->ids_len += len;
    lr->seen[p] = lr->have[p] = 0;
    lr->line[p] = ln;
    for (int k = 0; k < lr->n_out; ++k)
        lr->value[(size_t)p * lr->n_out + k] = 0;
    size_t h = (size_t)hash_id(id) & (lr->n_slots - 1);
    while (lr->slot[h] >= 0)
        h = (h + 1) & (lr->n_slots - 1);
    lr->slot[h] = p;
    *made = 1;
    return p;
}

static void long_free(long_reader *lr)
{
    free(lr->ids);
    free(lr->id_at);
    free(lr->seen);
    free(lr->have);
    free(lr->line);
    free(lr->value);
    free(lr->slot);
}

/* The columns a long read needs: id, axis, value [, nominal], then the where filters. */
static int long_columns(const sc_table_layout *lay, const char **cols)
{
    int n = 0;
    cols[n++] = lay->id_col;
    cols[n++] = lay->axis_col;
    cols[n++] = lay->value_col;
    if (lay->nominal_col)
        cols[n++] = lay->nominal_col;
    for (int w = 0; w < lay->n_where; ++w)
        cols[n++] = lay->where_col[w];
    return n;
}

/* Whether a row of a long table is passed over (counted as what it is): the header again, a row
 * the where filters leave out, another axis, a statistic; else *k is its axis. */
static int long_skipped(long_reader *lr, long ln, int *k)
{
    const sc_table_layout *lay = lr->lay;
    char **field = lr->field;
    const int *col_of = lr->col_of, *where_of = col_of + 3 + (lay->nominal_col ? 1 : 0);
    if (sc_imp_name_equal(field[col_of[1]], lay->axis_col) &&
        sc_imp_name_equal(field[col_of[2]], lay->value_col)) { /* the header again */
        if (!lr->t->n_header_repeats++)
            lr->t->header_repeat_line = ln;
        return 1;
    }
    for (int w = 0; w < lay->n_where; ++w)
        if (!sc_imp_name_equal(field[where_of[w]], lay->where_value[w])) {
            if (!lr->notes->n_filtered++)
                lr->notes->filtered_line = ln;
            return 1;
        }
    *k = -1;
    for (int a = 0; a < lr->n_cols && *k < 0; ++a)
        if (sc_imp_name_equal(field[col_of[1]], lr->names[a]))
            *k = a;
    if (*k < 0) { /* Z, D, roundness, ...: not read */
        lr->notes->n_other_axis++;
        return 1;
    }
    if (sc_imp_names_statistic(field[col_of[0]])) { /* "Mittelwert;X;12.5": a statistic */
        if (!lr->t->n_summary++)
            lr->t->summary_line = ln;
        return 1;
    }
    return 0;
}

/* The value [and nominal] of a row of axis k into v; *present: it has a value (a nominal without
 * one is not measured). */
static sc_status long_values(long_reader *lr, int k, long ln, double *v, int *present,
                             sc_error *err)
{
    const sc_table_layout *lay = lr->lay;
    int vcols = lay->nominal_col ? 2 : 1;
    *present = 0;
    for (int c = 0; c < vcols; ++c) {
        char *s = lr->field[lr->col_of[2 + c]];
        const char *cname = c ? lay->nominal_col : lay->value_col;
        if (sc_imp_is_placeholder(lay, s)) {
            s[0] = '\0';
            if (!lr->notes->n_placeholder++)
                lr->notes->placeholder_line = ln;
        }
        if (!s[0]) {
            if (c == 1 && *present)
                return sc_error_set(err, SC_E_INPUT, lr->path, ln,
                                    "column '%s': no nominal for this %s value", cname,
                                    lr->names[k]);
            continue;
        }
        if (c == 1 && !*present)
            continue; /* a nominal without a measurement: not measured */
        sc_status st = sc_imp_value(&lr->marks, lr->path, ln, cname, s,
                                    lr->quoted[lr->col_of[2 + c]], lr->t->delimiter, &v[c], err);
        if (st != SC_OK)
            return st;
        *present |= c == 0;
    }
    return SC_OK;
}

/* One row of a long table (its fields at lr->field): a coordinate of the point its ID names. */
static sc_status long_row(long_reader *lr, long ln, sc_error *err)
{
    int k;
    if (long_skipped(lr, ln, &k))
        return SC_OK;
    const char *id = lr->field[lr->col_of[0]];
    if (!id[0])
        return sc_error_set(err, SC_E_INPUT, lr->path, ln, "column '%s': no ID for this %s row",
                            lr->lay->id_col, lr->names[k]);
    double v[2] = {0, 0};
    int present;
    sc_status st = long_values(lr, k, ln, v, &present, err);
    if (st != SC_OK)
        return st;
    int made;
    long p = long_point(lr, id, ln, &made, err);
    if (p < 0)
        return err ? err->code : SC_E_INPUT;
    if (lr->seen[p] & (1u << k))
        return sc_error_set(err, SC_E_INPUT, lr->path, ln,
                            "'%s' has a second %s row (the first is on or after line %ld): one ID "
                            "names one point (two views in one file? --where COL=VALUE picks one)",
                            id, lr->names[k], lr->line[p]);
    lr->seen[p] |= 1u << k;
    lr->n_used++;
    if (present) {
        const double *scale = lr->scale;
        lr->have[p] |= 1u << k;
        lr->value[(size_t)p * lr->n_out + k] = v[0] * (scale ? scale[k] : 1.0);
        if (lr->lay->nominal_col)
            lr->value[(size_t)p * lr->n_out + lr->n_cols + k] =
                v[1] * (scale ? scale[lr->n_cols + k] : 1.0);
    }
    return SC_OK;
}

/* The gathered points into t: complete ones as rows (in the order of their first rows), the
 * others counted. */
static sc_status long_finish(long_reader *lr, sc_table *t, sc_table_notes *notes, long ln,
                             sc_error *err)
{
    unsigned all = (1u << lr->n_cols) - 1;
    long n = 0;
    for (long p = 0; p < lr->n_points; ++p)
        n += lr->have[p] == all;
    t->value = malloc((size_t)(n ? n : 1) * (size_t)lr->n_out * sizeof(double));
    t->line = malloc((size_t)(n ? n : 1) * sizeof(long));
    if (!t->value || !t->line)
        return sc_error_set(err, SC_E_NOMEM, lr->path, ln, "out of memory");
    for (long p = 0; p < lr->n_points; ++p) {
        if (lr->have[p] == all) {
            memcpy(t->value + (size_t)t->n_rows * lr->n_out, lr->value + (size_t)p * lr->n_out,
                   (size_t)lr->n_out * sizeof(double));
            t->line[t->n_rows++] = lr->line[p];
        } else if (lr->have[p] == 0) {
            if (!t->n_no_values++)
                t->no_values_line = lr->line[p];
        } else if (!notes->n_incomplete++) {
            notes->incomplete_line = lr->line[p];
            snprintf(notes->incomplete_id, sizeof notes->incomplete_id, "%s",
                     lr->ids + lr->id_at[p]);
            for (int k = lr->n_cols - 1; k >= 0; --k)
                if (!(lr->have[p] & (1u << k)))
                    snprintf(notes->incomplete_axis, sizeof notes->incomplete_axis, "%s",
                             lr->names[k]);
        }
    }
    return SC_OK;
}

/* Where the needed columns are among the n fields hf of a line: by name, and by number beside a
 * name (or without a header); whether all were found. */
static int long_match_columns(long_reader *lr, char *const *hf, int n)
{
    int named = 0, all = 1, no_header = lr->lay->no_header;
    for (int c = 0; c < lr->n_need; ++c) { /* by name; by number beside a name */
        const char *col = lr->cols[c];
        lr->col_of[c] = no_header ? -1 : sc_imp_find_column(hf, n, col);
        if (lr->col_of[c] >= 0 && sc_imp_column_number(col) >= 1 &&
            !sc_imp_name_equal(hf[lr->col_of[c]], col))
            lr->col_of[c] = -1;
        named += lr->col_of[c] >= 0;
    }
    for (int c = 0; c < lr->n_need; ++c) {
        long num = sc_imp_column_number(lr->cols[c]);
        if (lr->col_of[c] < 0 && num >= 1 && num <= n && (no_header || named > 0))
            lr->col_of[c] = (int)(num - 1);
        all &= lr->col_of[c] >= 0;
    }
    lr->best_named = named;
    return all;
}

/* Without a header line: every column given by number, within the first row's n fields. */
static sc_status long_first_row(long_reader *lr, int n, sc_error *err)
{
    for (int c = 0; c < lr->n_need; ++c)
        if (sc_imp_column_number(lr->cols[c]) < 1)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "without a header line, columns are given by number, not '%s'",
                                lr->cols[c]);
        else if (lr->col_of[c] < 0)
            return sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line,
                                "column %s asked for, the first row has %d fields", lr->cols[c],
                                n);
    lr->n_header = n;
    lr->first_row = lr->r.line;
    lr->in_rows = 1;
    return SC_OK;
}

enum { LONG_NEXT, LONG_STOP, LONG_ROW }; /* the next line, stop reading, or read it as a row */

/* A line before the data: the header (all columns named), the first row (no header line), or a
 * preamble line, the one naming most columns kept for the error if no header follows. */
static int long_header(long_reader *lr, sc_status *st, sc_error *err)
{
    char buf[4096], *hf[SC_IMP_MAX_FIELDS];
    size_t len = strlen(lr->r.text);
    if (len >= sizeof buf) {
        *st = sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line, "a header line of %zu bytes",
                           len);
        return LONG_STOP;
    }
    memcpy(buf, lr->r.text, len + 1);
    lr->t->delimiter = sc_imp_delimiter_of(buf);
    int n = sc_imp_split_fields(buf, lr->t->delimiter, hf, NULL, SC_IMP_MAX_FIELDS);
    if (n < 0) {
        *st = sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line, "more than %d columns",
                           SC_IMP_MAX_FIELDS);
        return LONG_STOP;
    }
    int all = long_match_columns(lr, hf, n);
    if (lr->lay->no_header) {
        *st = long_first_row(lr, n, err);
        return *st == SC_OK ? LONG_ROW : LONG_STOP; /* this line is a row */
    }
    if (all) {
        lr->n_header = n;
        lr->t->header_line = lr->r.line;
        lr->in_rows = 1;
        lr->notes->header_fields = lr->notes->named_fields = n;
        while (lr->notes->named_fields > 1 && !hf[lr->notes->named_fields - 1][0])
            lr->notes->named_fields--;
        return LONG_NEXT;
    }
    if (lr->best_named > lr->best) {
        lr->best = lr->best_named;
        lr->best_line = lr->r.line;
        snprintf(lr->best_text, sizeof lr->best_text, "%s", lr->r.text);
    }
    return ++lr->preamble > SC_IMP_PREAMBLE_MAX ? LONG_STOP : LONG_NEXT;
}

/* Whether a line of nf fields fits the header: every needed column there, and no number in the
 * unlabelled trailing fields. */
static int long_fits(const long_reader *lr, int nf)
{
    int fits = nf >= 0;
    for (int c = 0; c < lr->n_need && fits; ++c)
        fits = lr->col_of[c] < nf;
    for (int f = lr->n_header; f < nf && fits; ++f) /* unlabelled trailing fields: no numbers */
        fits = sc_imp_not_a_number(lr->field[f]);
    return fits;
}

/* A line of nf fields that does not fit: text without a digit (a footer, a title between
 * blocks) and empty lines are counted and passed over, up to a run of SC_CSV_MAX_SKIP_RUN;
 * anything else is an error. */
static int long_misfit(long_reader *lr, int nf, sc_status *st, sc_error *err)
{
    int empty = nf >= 0, text = nf >= 0;
    for (int f = 0; f < nf && empty; ++f)
        empty = !lr->field[f][0];
    for (int f = 0; f < nf && text; ++f)
        text = sc_imp_not_a_number(lr->field[f]);
    if (text && !empty && ++lr->no_row_run <= SC_CSV_MAX_SKIP_RUN) { /* no digit: no row */
        if (!lr->t->n_footer++)
            lr->t->footer_line = lr->r.line;
        return LONG_NEXT;
    }
    if (empty && ++lr->no_row_run <= SC_CSV_MAX_SKIP_RUN)
        return LONG_NEXT; /* a spreadsheet's ";;;;" */
    if (empty)
        *st = sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line, SC_IMP_NO_ROW_RUN_MSG,
                           SC_CSV_MAX_SKIP_RUN);
    else
        *st = sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line,
                           "%d fields, the %s (line %ld) has %d", nf < 0 ? SC_IMP_MAX_FIELDS : nf,
                           lr->t->header_line ? "header line" : "first row",
                           lr->t->header_line ? lr->t->header_line : lr->first_row, lr->n_header);
    return LONG_STOP;
}

/* A line of data: a row (long_row), with the run of lines that give no point a value bounded. */
static int long_data_line(long_reader *lr, sc_status *st, sc_error *err)
{
    int nf = sc_imp_split_fields(lr->r.text, lr->t->delimiter, lr->field, lr->quoted,
                                 SC_IMP_MAX_FIELDS);
    if (!long_fits(lr, nf))
        return long_misfit(lr, nf, st, err);
    if (nf > lr->n_header && !lr->notes->n_ragged++) {
        lr->notes->ragged_line = lr->r.line;
        lr->notes->ragged_fields = nf;
    }
    long used = lr->n_used;
    *st = long_row(lr, lr->r.line, err);
    lr->no_row_run = lr->n_used > used ? 0 : lr->no_row_run + 1;
    if (*st == SC_OK && lr->no_row_run > SC_CSV_MAX_SKIP_RUN)
        *st = sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line, SC_IMP_NO_ROW_RUN_MSG,
                           SC_CSV_MAX_SKIP_RUN);
    return LONG_NEXT;
}

/* No header line was found: the error names the first column the best line lacks. */
static sc_status long_no_header(long_reader *lr, sc_error *err)
{
    if (lr->best < 0)
        return sc_error_set(err, SC_E_INPUT, lr->path, lr->r.line,
                            "no header line naming the columns");
    int c = 0;
    char hbuf[4096], *hf[SC_IMP_MAX_FIELDS];
    snprintf(hbuf, sizeof hbuf, "%s", lr->best_text);
    int n = sc_imp_split_fields(hbuf, sc_imp_delimiter_of(hbuf), hf, NULL, SC_IMP_MAX_FIELDS);
    while (c < lr->n_need - 1 && sc_imp_find_column(hf, n, lr->cols[c]) >= 0)
        ++c;
    return sc_error_set(err, SC_E_INPUT, lr->path, lr->best_line,
                        "no column named '%s' in this header line%s", lr->cols[c],
                        sc_imp_encoding_hint(lr->lay, lr->best_text));
}

/* After the last line: the points into t, which must have a complete one. */
static sc_status long_end(long_reader *lr, sc_status st, sc_error *err)
{
    sc_table *t = lr->t;
    if (st == SC_OK && !lr->in_rows)
        st = long_no_header(lr, err);
    if (st == SC_OK)
        st = long_finish(lr, t, lr->notes, lr->r.line, err);
    if (st == SC_OK && t->n_rows == 0)
        st = sc_error_set(err, SC_E_INPUT, lr->path, t->header_line ? t->header_line : lr->r.line,
                          "no point has all of its coordinates (%ld IDs read%s)", lr->n_points,
                          lr->notes->n_other_axis ? "; the AXIS column holds other names: "
                                                    "--axis-names" : "");
    if (st == SC_OK)
        sc_imp_set_decimal(&lr->marks, t, lr->notes);
    return st;
}

sc_status sc_imp_read_long(const char *path, int n_cols, const char *const *names,
                           const double *scale, long max_rows, const sc_table_layout *lay,
                           sc_table_notes *notes, sc_table *t, sc_error *err)
{
    if (n_cols > LONG_MAX_COLS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "one row per axis reads up to %d axes",
                            LONG_MAX_COLS);
    long_reader lr;
    memset(&lr, 0, sizeof lr);
    lr.path = path;
    lr.n_cols = n_cols;
    lr.names = names;
    lr.n_out = lay->nominal_col ? 2 * n_cols : n_cols;
    lr.max_rows = max_rows;
    lr.lay = lay, lr.scale = scale, lr.t = t, lr.notes = notes;
    lr.n_need = long_columns(lay, lr.cols);
    lr.best = -1;
    t->n_cols = lr.n_out;
    sc_imp_conv conv;
    sc_status st = sc_imp_open(&conv, &lr.r, lay->encoding, path, err);
    if (st != SC_OK)
        return st;
    int next = LONG_NEXT;
    while (st == SC_OK && next != LONG_STOP && sc_imp_next_line(&lr.r, &conv, &st, err) == 1) {
        next = lr.in_rows ? LONG_ROW : long_header(&lr, &st, err);
        if (next == LONG_ROW)
            next = long_data_line(&lr, &st, err);
    }
    st = long_end(&lr, st, err);
    long_free(&lr);
    return sc_imp_close(&conv, &lr.r, t, st);
}

/* ---- items in columns ---- */

/* The state of one read of items in columns. */
typedef struct trans_reader {
    const char *path;
    int n_cols;
    const char *const *names;
    const double *scale;
    long max_rows;
    const sc_table_layout *lay;
    sc_table_notes *notes;
    sc_table *t;
    sc_csv r;
    char *text[16];           /* the labelled rows (each wanted label's), their lines */
    long line[16];
    char *prev, *items;       /* the last unlabelled line; the item names (the line before the
                                 first labelled row) */
    long prev_line, items_line, n_lines, unlabelled;
    char **field;             /* n_cols rows of MAX_ITEMS fields, then the item names */
    unsigned char *quoted;
    int nf[17], n_items;
    char d;                   /* the delimiter */
    sc_imp_marks marks;
} trans_reader;

/* The first field of a line (its label), trimmed and unquoted, in label (cap bytes). */
static char *row_label(const char *text, char *label, size_t cap)
{
    char d = sc_imp_delimiter_of(text);
    const char *q = strchr(text, d);
    size_t flen = q ? (size_t)(q - text) : strlen(text);
    if (flen >= cap)
        flen = cap - 1;
    memcpy(label, text, flen);
    label[flen] = '\0';
    char *lab = sc_str_trim(label);
    if (lab[0] == '"') {
        ++lab;
        char *e = strchr(lab, '"');
        if (e)
            *e = '\0';
    }
    return lab;
}

/* The wanted row a line is (by its label, or by its number without a header), or -1. */
static int trans_row_of(const trans_reader *tr, const char *text)
{
    char label[128];
    const char *lab = row_label(text, label, sizeof label);
    for (int a = 0; a < tr->n_cols; ++a) {
        long num = tr->lay->no_header ? sc_imp_column_number(tr->names[a]) : 0;
        if (num ? num == tr->n_lines : sc_imp_name_equal(lab, tr->names[a]))
            return a;
    }
    return -1;
}

/* One line (not blank, converted): a wanted row kept, or an unlabelled line remembered (the one
 * before the first wanted row names the items). */
static int trans_line(trans_reader *tr, sc_status *st, sc_error *err)
{
    const sc_csv *r = &tr->r;
    ++tr->n_lines;
    int k = trans_row_of(tr, r->text);
    if (k < 0 && ++tr->unlabelled > SC_CSV_MAX_SKIP_RUN) {
        *st = sc_error_set(err, SC_E_INPUT, tr->path, r->line,
                           "more than %ld lines in a row without a wanted label: not this "
                           "table's data (an endless input?)", SC_CSV_MAX_SKIP_RUN);
        return LONG_STOP;
    }
    if (k < 0) {
        free(tr->prev);
        tr->prev = strdup(r->text);
        tr->prev_line = r->line;
        if (!tr->prev)
            *st = sc_error_set(err, SC_E_NOMEM, tr->path, r->line, "out of memory");
        return LONG_NEXT;
    }
    tr->unlabelled = 0;
    if (tr->text[k]) {
        *st = sc_error_set(err, SC_E_INPUT, tr->path, r->line,
                           "a second row labelled '%s' (the first: line %ld)", tr->names[k],
                           tr->line[k]);
        return LONG_STOP;
    }
    tr->text[k] = strdup(r->text);
    tr->line[k] = r->line;
    if (!tr->text[k])
        *st = sc_error_set(err, SC_E_NOMEM, tr->path, r->line, "out of memory");
    if (!tr->items && tr->prev && tr->prev_line < r->line) { /* the line before the first row */
        tr->items = tr->prev;
        tr->items_line = tr->prev_line;
        tr->prev = NULL;
    }
    return LONG_NEXT;
}

/* Every wanted row there, split into fields (as many items in each), and the item names. */
static sc_status trans_split(trans_reader *tr, sc_error *err)
{
    for (int k = 0; k < tr->n_cols; ++k)
        if (!tr->text[k])
            return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                                "no row labelled '%s' (items in columns: the rows' first fields "
                                "name X, Y, ...)%s", tr->names[k],
                                sc_imp_encoding_hint(tr->lay, tr->prev ? tr->prev : ""));
    tr->field = malloc((size_t)(tr->n_cols + 1) * MAX_ITEMS * sizeof(char *));
    tr->quoted = tr->field ? malloc((size_t)tr->n_cols * MAX_ITEMS) : NULL;
    if (!tr->field || !tr->quoted)
        return sc_error_set(err, SC_E_NOMEM, tr->path, 0, "out of memory");
    tr->d = sc_imp_delimiter_of(tr->text[0]);
    for (int k = 0; k < tr->n_cols; ++k) {
        char **f = tr->field + (size_t)k * MAX_ITEMS;
        tr->nf[k] = sc_imp_split_fields(tr->text[k], tr->d, f, tr->quoted + (size_t)k * MAX_ITEMS,
                                        MAX_ITEMS);
        while (tr->nf[k] > 1 && !f[tr->nf[k] - 1][0])
            --tr->nf[k]; /* trailing empty fields */
        if (k > 0 && tr->nf[k] != tr->nf[0])
            return sc_error_set(err, SC_E_INPUT, tr->path, tr->line[k],
                                "%d items here, %d in the row labelled '%s' (line %ld)",
                                tr->nf[k] - 1, tr->nf[0] - 1, tr->names[0], tr->line[0]);
    }
    if (tr->items)
        tr->n_items = sc_imp_split_fields(tr->items, tr->d, tr->field + (size_t)tr->n_cols *
                                          MAX_ITEMS, NULL, MAX_ITEMS);
    return SC_OK;
}

/* Item c (a column of the wanted rows): its values as a row of t, or passed over and counted
 * (a statistic's column, an item without values). */
static sc_status trans_item(trans_reader *tr, long c, sc_error *err)
{
    sc_table *t = tr->t;
    const char *item = c < tr->n_items ? tr->field[(size_t)tr->n_cols * MAX_ITEMS + c] : NULL;
    if (item && sc_imp_names_statistic(item)) { /* a "Mittelwert" column */
        if (!t->n_summary++)
            t->summary_line = tr->items_line;
        return SC_OK;
    }
    int empty = 0;
    for (int k = 0; k < tr->n_cols; ++k) {
        char *s = tr->field[(size_t)k * MAX_ITEMS + c];
        if (sc_imp_is_placeholder(tr->lay, s)) {
            s[0] = '\0';
            if (!tr->notes->n_placeholder++)
                tr->notes->placeholder_line = tr->line[k];
        }
        empty += !s[0];
    }
    if (empty == tr->n_cols) {
        if (!t->n_no_values++)
            t->no_values_line = tr->line[0];
        return SC_OK;
    }
    sc_status st = SC_OK;
    for (int k = 0; k < tr->n_cols && st == SC_OK; ++k) {
        double v = 0;
        char what[64];
        snprintf(what, sizeof what, "%s, item %ld", tr->names[k], c);
        size_t at = (size_t)k * MAX_ITEMS + c;
        st = sc_imp_value(&tr->marks, tr->path, tr->line[k], what, tr->field[at], tr->quoted[at],
                          tr->d, &v, err);
        t->value[t->n_rows * tr->n_cols + k] = v * (tr->scale ? tr->scale[k] : 1.0);
    }
    if (st == SC_OK)
        t->line[t->n_rows++] = tr->line[0];
    return st;
}

/* The rows split: every item into t. */
static sc_status trans_items(trans_reader *tr, sc_error *err)
{
    sc_table *t = tr->t;
    long n = tr->nf[0] - 1;
    if (n > tr->max_rows)
        return sc_error_set(err, SC_E_INPUT, tr->path, tr->line[0], "more than %ld items, the "
                            "most this import takes", tr->max_rows);
    t->value = malloc((size_t)(n ? n : 1) * (size_t)tr->n_cols * sizeof(double));
    t->line = malloc((size_t)(n ? n : 1) * sizeof(long));
    if (!t->value || !t->line)
        return sc_error_set(err, SC_E_NOMEM, tr->path, 0, "out of memory");
    sc_status st = SC_OK;
    for (long c = 1; c <= n && st == SC_OK; ++c)
        st = trans_item(tr, c, err);
    if (st == SC_OK && t->n_rows == 0)
        st = sc_error_set(err, SC_E_INPUT, tr->path, tr->line[0], "no item with values");
    if (st == SC_OK)
        sc_imp_set_decimal(&tr->marks, t, tr->notes);
    return st;
}

sc_status sc_imp_read_transposed(const char *path, int n_cols, const char *const *names,
                                 const double *scale, long max_rows, const sc_table_layout *lay,
                                 sc_table_notes *notes, sc_table *t, sc_error *err)
{
    trans_reader tr;
    memset(&tr, 0, sizeof tr);
    tr.path = path, tr.n_cols = n_cols, tr.names = names, tr.scale = scale;
    tr.max_rows = max_rows, tr.lay = lay, tr.notes = notes, tr.t = t;
    sc_imp_conv conv;
    sc_status st = sc_imp_open(&conv, &tr.r, lay->encoding, path, err);
    if (st != SC_OK)
        return st;
    int next = LONG_NEXT;
    while (st == SC_OK && next != LONG_STOP && sc_imp_next_line(&tr.r, &conv, &st, err) == 1)
        next = trans_line(&tr, &st, err);
    if (st == SC_OK)
        st = trans_split(&tr, err);
    t->delimiter = tr.d ? tr.d : ','; /* found once every wanted row was there */
    t->header_line = tr.items_line;
    if (st == SC_OK)
        st = trans_items(&tr, err);
    for (int k = 0; k < 16; ++k)
        free(tr.text[k]);
    free(tr.prev);
    free(tr.items);
    free(tr.field);
    free(tr.quoted);
    return sc_imp_close(&conv, &tr.r, t, st);
}

/* The public entry (import.h): the layout the options ask for. It lives here, beside the layouts
 * it chooses among, so that the table reader (import_table.c) calls nothing of this file. */
sc_status sc_table_read_layout(const char *path, int n_cols, const char *const *names,
                               const double *scale, long max_rows, const sc_table_layout *lay,
                               sc_table_notes *notes, sc_table *t, sc_error *err)
{
    if (!(lay && (lay->id_col || lay->transpose)))
        return sc_imp_read_wide(path, n_cols, names, scale, max_rows, lay, notes, t, err);
    sc_table_notes local_notes;
    if (!notes)
        notes = &local_notes;
    sc_status st = sc_imp_begin(path, n_cols, names, scale, max_rows, lay, notes, t, err);
    if (st != SC_OK)
        return st;
    if (lay->id_col)
        return sc_imp_read_long(path, n_cols, names, scale, max_rows, lay, notes, t, err);
    return sc_imp_read_transposed(path, n_cols, names, scale, max_rows, lay, notes, t, err);
}
