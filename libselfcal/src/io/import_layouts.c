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

/* Where column name is among the n fields of a header line (by name, else by number); -1. */
static int find_column(char *const *field, int n, const char *name)
{
    for (int f = 0; f < n; ++f)
        if (sc_imp_name_equal(field[f], name))
            return f;
    long num = sc_imp_column_number(name);
    return num >= 1 && num <= n ? (int)(num - 1) : -1;
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

/* One row of a long table (nf fields; col_of: id, axis, value [, nominal], where...). */
static sc_status long_row(long_reader *lr, const sc_table_layout *lay, const char *const *names,
                          const double *scale, char **field, const unsigned char *quoted, int nf,
                          const int *col_of, int n_need, char delim, long ln, sc_imp_marks *marks,
                          sc_table *t, sc_table_notes *notes, sc_error *err)
{
    (void)nf;
    int vcols = lay->nominal_col ? 2 : 1;
    const int *where_of = col_of + 2 + vcols;
    if (sc_imp_name_equal(field[col_of[1]], lay->axis_col) &&
        sc_imp_name_equal(field[col_of[2]], lay->value_col)) { /* the header again */
        if (!t->n_header_repeats++)
            t->header_repeat_line = ln;
        return SC_OK;
    }
    for (int w = 0; w < lay->n_where; ++w)
        if (!sc_imp_name_equal(field[where_of[w]], lay->where_value[w])) {
            if (!notes->n_filtered++)
                notes->filtered_line = ln;
            return SC_OK;
        }
    (void)n_need;
    int k = -1;
    for (int a = 0; a < lr->n_cols && k < 0; ++a)
        if (sc_imp_name_equal(field[col_of[1]], names[a]))
            k = a;
    if (k < 0) { /* Z, D, roundness, ...: not read */
        notes->n_other_axis++;
        return SC_OK;
    }
    const char *id = field[col_of[0]];
    if (sc_imp_names_statistic(id)) { /* "Mittelwert;X;12.5": a statistic, no point */
        if (!t->n_summary++)
            t->summary_line = ln;
        return SC_OK;
    }
    if (!id[0])
        return sc_error_set(err, SC_E_INPUT, lr->path, ln, "column '%s': no ID for this %s row",
                            lay->id_col, names[k]);
    double v[2] = {0, 0};
    int present = 0;
    for (int c = 0; c < vcols; ++c) {
        char *s = field[col_of[2 + c]];
        const char *cname = c ? lay->nominal_col : lay->value_col;
        if (sc_imp_is_placeholder(lay, s)) {
            s[0] = '\0';
            if (!notes->n_placeholder++)
                notes->placeholder_line = ln;
        }
        if (!s[0]) {
            if (c == 1 && present)
                return sc_error_set(err, SC_E_INPUT, lr->path, ln,
                                    "column '%s': no nominal for this %s value", cname, names[k]);
            continue;
        }
        if (c == 1 && !present)
            continue; /* a nominal without a measurement: not measured */
        sc_status st = sc_imp_value(marks, lr->path, ln, cname, s, quoted[col_of[2 + c]], delim,
                                    &v[c], err);
        if (st != SC_OK)
            return st;
        present |= c == 0;
    }
    int made;
    long p = long_point(lr, id, ln, &made, err);
    if (p < 0)
        return err ? err->code : SC_E_INPUT;
    if (lr->seen[p] & (1u << k))
        return sc_error_set(err, SC_E_INPUT, lr->path, ln,
                            "'%s' has a second %s row (the first is on or after line %ld): one ID "
                            "names one point (two views in one file? --where COL=VALUE picks one)",
                            id, names[k], lr->line[p]);
    lr->seen[p] |= 1u << k;
    lr->n_used++;
    if (present) {
        lr->have[p] |= 1u << k;
        lr->value[(size_t)p * lr->n_out + k] = v[0] * (scale ? scale[k] : 1.0);
        if (vcols == 2)
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

sc_status sc_imp_read_long(const char *path, int n_cols, const char *const *names,
                           const double *scale, long max_rows, const sc_table_layout *lay,
                           sc_table_notes *notes, sc_table *t, sc_error *err)
{
    if (n_cols > LONG_MAX_COLS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "one row per axis reads up to %d axes",
                            LONG_MAX_COLS);
    const char *cols[4 + SC_TABLE_MAX_WHERE];
    int n_need = long_columns(lay, cols), col_of[4 + SC_TABLE_MAX_WHERE];
    long_reader lr;
    memset(&lr, 0, sizeof lr);
    lr.path = path;
    lr.n_cols = n_cols;
    lr.names = names;
    lr.n_out = lay->nominal_col ? 2 * n_cols : n_cols;
    lr.max_rows = max_rows;
    t->n_cols = lr.n_out;
    sc_imp_conv conv;
    sc_status st = sc_imp_conv_open(&conv, lay->encoding, path, err);
    if (st != SC_OK)
        return st;
    sc_csv r;
    st = sc_csv_open(&r, path, err);
    if (st != SC_OK) {
        sc_imp_conv_close(&conv);
        return st;
    }
    char *field[SC_IMP_MAX_FIELDS];
    unsigned char quoted[SC_IMP_MAX_FIELDS];
    int n_header = 0, in_rows = 0, got, best = -1;
    long preamble = 0, best_line = 0, first_row = 0, no_row_run = 0;
    sc_imp_marks marks = {0, 0, 0};
    char best_text[4096] = "";
    while (st == SC_OK && (got = sc_csv_next_line(&r, err)) == 1) {
        if (sc_csv_is_blank(&r) || r.text[0] == '#')
            continue;
        if ((st = sc_imp_conv_line(&conv, &r, err)) != SC_OK)
            break;
        if (!in_rows) {
            char buf[4096], *hf[SC_IMP_MAX_FIELDS];
            size_t len = strlen(r.text);
            if (len >= sizeof buf) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, "a header line of %zu bytes", len);
                break;
            }
            memcpy(buf, r.text, len + 1);
            t->delimiter = sc_imp_delimiter_of(buf);
            int n = sc_imp_split_fields(buf, t->delimiter, hf, NULL, SC_IMP_MAX_FIELDS), named = 0;
            if (n < 0) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, "more than %d columns",
                                  SC_IMP_MAX_FIELDS);
                break;
            }
            for (int c = 0; c < n_need; ++c) { /* by name; by number beside a name */
                col_of[c] = lay->no_header ? -1 : find_column(hf, n, cols[c]);
                if (col_of[c] >= 0 && sc_imp_column_number(cols[c]) >= 1 &&
                    !sc_imp_name_equal(hf[col_of[c]], cols[c]))
                    col_of[c] = -1;
                named += col_of[c] >= 0;
            }
            for (int c = 0; c < n_need; ++c) {
                long num = sc_imp_column_number(cols[c]);
                if (col_of[c] < 0 && num >= 1 && num <= n && (lay->no_header || named > 0))
                    col_of[c] = (int)(num - 1);
            }
            int all = 1;
            for (int c = 0; c < n_need; ++c)
                all &= col_of[c] >= 0;
            if (lay->no_header) {
                for (int c = 0; c < n_need && st == SC_OK; ++c)
                    if (sc_imp_column_number(cols[c]) < 1)
                        st = sc_error_set(err, SC_E_INPUT, NULL, 0,
                                          "without a header line, columns are given by number, "
                                          "not '%s'", cols[c]);
                    else if (col_of[c] < 0)
                        st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                          "column %s asked for, the first row has %d fields",
                                          cols[c], n);
                if (st != SC_OK)
                    break;
                n_header = n;
                first_row = r.line;
                in_rows = 1; /* and this line is a row: below */
            } else if (all) {
                n_header = n;
                t->header_line = r.line;
                in_rows = 1;
                notes->header_fields = notes->named_fields = n;
                while (notes->named_fields > 1 && !hf[notes->named_fields - 1][0])
                    notes->named_fields--;
                continue;
            } else {
                if (named > best) {
                    best = named;
                    best_line = r.line;
                    snprintf(best_text, sizeof best_text, "%s", r.text);
                }
                if (++preamble > SC_IMP_PREAMBLE_MAX)
                    break;
                continue;
            }
        }
        int nf = sc_imp_split_fields(r.text, t->delimiter, field, quoted, SC_IMP_MAX_FIELDS);
        int fits = nf >= 0;
        for (int c = 0; c < n_need && fits; ++c)
            fits = col_of[c] < nf;
        for (int f = n_header; f < nf && fits; ++f) /* unlabelled trailing fields: no numbers */
            fits = sc_imp_not_a_number(field[f]);
        if (!fits) {
            int empty = nf >= 0, text = nf >= 0;
            for (int f = 0; f < nf && empty; ++f)
                empty = !field[f][0];
            for (int f = 0; f < nf && text; ++f)
                text = sc_imp_not_a_number(field[f]);
            if (text && !empty && ++no_row_run <= SC_CSV_MAX_SKIP_RUN) { /* no digit: no row
                                           (a footer, a title between blocks); counted */
                if (!t->n_footer++)
                    t->footer_line = r.line;
                continue;
            }
            if (empty && ++no_row_run <= SC_CSV_MAX_SKIP_RUN)
                continue; /* a spreadsheet's ";;;;" */
            if (empty) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, SC_IMP_NO_ROW_RUN_MSG,
                                  SC_CSV_MAX_SKIP_RUN);
                break;
            }
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "%d fields, the %s (line %ld) has %d",
                              nf < 0 ? SC_IMP_MAX_FIELDS : nf,
                              t->header_line ? "header line" : "first row",
                              t->header_line ? t->header_line : first_row, n_header);
            break;
        }
        if (nf > n_header && !notes->n_ragged++) {
            notes->ragged_line = r.line;
            notes->ragged_fields = nf;
        }
        long used = lr.n_used;
        st = long_row(&lr, lay, names, scale, field, quoted, nf, col_of, n_need, t->delimiter,
                      r.line, &marks, t, notes, err);
        no_row_run = lr.n_used > used ? 0 : no_row_run + 1;
        if (st == SC_OK && no_row_run > SC_CSV_MAX_SKIP_RUN)
            st = sc_error_set(err, SC_E_INPUT, path, r.line, SC_IMP_NO_ROW_RUN_MSG,
                              SC_CSV_MAX_SKIP_RUN);
    }
    if (st == SC_OK && got < 0)
        st = err ? err->code : SC_E_INPUT;
    if (st == SC_OK && !in_rows) {
        if (best >= 0) {
            int c = 0;
            char hbuf[4096], *hf[SC_IMP_MAX_FIELDS];
            snprintf(hbuf, sizeof hbuf, "%s", best_text);
            int n = sc_imp_split_fields(hbuf, sc_imp_delimiter_of(hbuf), hf, NULL,
                                        SC_IMP_MAX_FIELDS);
            while (c < n_need - 1 && find_column(hf, n, cols[c]) >= 0)
                ++c;
            st = sc_error_set(err, SC_E_INPUT, path, best_line,
                              "no column named '%s' in this header line%s", cols[c],
                              sc_imp_encoding_hint(lay, best_text));
        } else {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "no header line naming the columns");
        }
    }
    if (st == SC_OK)
        st = long_finish(&lr, t, notes, r.line, err);
    if (st == SC_OK && t->n_rows == 0)
        st = sc_error_set(err, SC_E_INPUT, path, t->header_line ? t->header_line : r.line,
                          "no point has all of its coordinates (%ld IDs read%s)", lr.n_points,
                          notes->n_other_axis ? "; the AXIS column holds other names: "
                                                "--axis-names" : "");
    if (st == SC_OK) {
        t->decimal = marks.mark ? marks.mark : '.';
        notes->decimals = marks.decimals;
    }
    long_free(&lr);
    sc_csv_close(&r);
    sc_imp_conv_close(&conv);
    if (st != SC_OK)
        sc_table_free(t);
    return st;
}

/* ---- items in columns ---- */

sc_status sc_imp_read_transposed(const char *path, int n_cols, const char *const *names,
                                 const double *scale, long max_rows, const sc_table_layout *lay,
                                 sc_table_notes *notes, sc_table *t, sc_error *err)
{
    sc_imp_conv conv;
    sc_status st = sc_imp_conv_open(&conv, lay->encoding, path, err);
    if (st != SC_OK)
        return st;
    sc_csv r;
    st = sc_csv_open(&r, path, err);
    if (st != SC_OK) {
        sc_imp_conv_close(&conv);
        return st;
    }
    char *text[16] = {0}, *prev = NULL, *items = NULL; /* the labelled rows, the item names */
    long line[16] = {0}, prev_line = 0, items_line = 0, n_lines = 0, unlabelled = 0;
    int got;
    while (st == SC_OK && (got = sc_csv_next_line(&r, err)) == 1) {
        if (sc_csv_is_blank(&r) || r.text[0] == '#')
            continue;
        if ((st = sc_imp_conv_line(&conv, &r, err)) != SC_OK)
            break;
        ++n_lines;
        char d = sc_imp_delimiter_of(r.text), *q = strchr(r.text, d);
        size_t flen = q ? (size_t)(q - r.text) : strlen(r.text);
        char label[128];
        if (flen >= sizeof label)
            flen = sizeof label - 1;
        memcpy(label, r.text, flen);
        label[flen] = '\0';
        char *lab = sc_str_trim(label);
        if (lab[0] == '"') {
            ++lab;
            char *e = strchr(lab, '"');
            if (e)
                *e = '\0';
        }
        int k = -1;
        for (int a = 0; a < n_cols && k < 0; ++a) {
            long num = lay->no_header ? sc_imp_column_number(names[a]) : 0;
            if (num ? num == n_lines : sc_imp_name_equal(lab, names[a]))
                k = a;
        }
        if (k < 0 && ++unlabelled > SC_CSV_MAX_SKIP_RUN) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "more than %ld lines in a row without a wanted label: not this "
                              "table's data (an endless input?)", SC_CSV_MAX_SKIP_RUN);
            break;
        }
        if (k < 0) {
            free(prev);
            prev = strdup(r.text);
            prev_line = r.line;
            if (!prev)
                st = sc_error_set(err, SC_E_NOMEM, path, r.line, "out of memory");
            continue;
        }
        unlabelled = 0;
        if (text[k]) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "a second row labelled '%s' (the first: line %ld)", names[k], line[k]);
            break;
        }
        text[k] = strdup(r.text);
        line[k] = r.line;
        if (!text[k])
            st = sc_error_set(err, SC_E_NOMEM, path, r.line, "out of memory");
        if (!items && prev && prev_line < r.line) { /* the line before the first labelled row */
            items = prev;
            items_line = prev_line;
            prev = NULL;
        }
    }
    if (st == SC_OK && got < 0)
        st = err ? err->code : SC_E_INPUT;
    for (int k = 0; k < n_cols && st == SC_OK; ++k)
        if (!text[k])
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "no row labelled '%s' (items in columns: the rows' first fields "
                              "name X, Y, ...)%s", names[k], sc_imp_encoding_hint(lay, prev ? prev : ""));
    char **field = st == SC_OK ? malloc((size_t)(n_cols + 1) * MAX_ITEMS * sizeof(char *)) : NULL;
    unsigned char *quoted = field ? malloc((size_t)n_cols * MAX_ITEMS) : NULL;
    int nf[17] = {0};
    if (st == SC_OK && (!field || !quoted))
        st = sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    char d = st == SC_OK ? sc_imp_delimiter_of(text[0]) : ',';
    t->delimiter = d;
    t->header_line = items_line;
    for (int k = 0; k < n_cols && st == SC_OK; ++k) {
        nf[k] = sc_imp_split_fields(text[k], d, field + (size_t)k * MAX_ITEMS,
                                    quoted + (size_t)k * MAX_ITEMS, MAX_ITEMS);
        while (nf[k] > 1 && !field[(size_t)k * MAX_ITEMS + nf[k] - 1][0])
            --nf[k]; /* trailing empty fields */
        if (k > 0 && nf[k] != nf[0])
            st = sc_error_set(err, SC_E_INPUT, path, line[k],
                              "%d items here, %d in the row labelled '%s' (line %ld)", nf[k] - 1,
                              nf[0] - 1, names[0], line[0]);
    }
    char **item = field ? field + (size_t)n_cols * MAX_ITEMS : NULL; /* none on an error */
    int n_items = 0;
    if (st == SC_OK && items)
        n_items = sc_imp_split_fields(items, d, item, NULL, MAX_ITEMS);
    long n = st == SC_OK ? nf[0] - 1 : 0;
    if (st == SC_OK && n > max_rows)
        st = sc_error_set(err, SC_E_INPUT, path, line[0], "more than %ld items, the most this "
                          "import takes", max_rows);
    if (st == SC_OK) {
        t->value = malloc((size_t)(n ? n : 1) * (size_t)n_cols * sizeof(double));
        t->line = malloc((size_t)(n ? n : 1) * sizeof(long));
        if (!t->value || !t->line)
            st = sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    sc_imp_marks marks = {0, 0, 0};
    for (long c = 1; c <= n && st == SC_OK; ++c) {
        if (c < n_items && sc_imp_names_statistic(item[c])) { /* a "Mittelwert" column */
            if (!t->n_summary++)
                t->summary_line = items_line;
            continue;
        }
        int empty = 0;
        for (int k = 0; k < n_cols; ++k) {
            char *s = field[(size_t)k * MAX_ITEMS + c];
            if (sc_imp_is_placeholder(lay, s)) {
                s[0] = '\0';
                if (!notes->n_placeholder++)
                    notes->placeholder_line = line[k];
            }
            empty += !s[0];
        }
        if (empty == n_cols) {
            if (!t->n_no_values++)
                t->no_values_line = line[0];
            continue;
        }
        for (int k = 0; k < n_cols && st == SC_OK; ++k) {
            double v = 0;
            char what[64];
            snprintf(what, sizeof what, "%s, item %ld", names[k], c);
            const char *s = field[(size_t)k * MAX_ITEMS + c];
            st = sc_imp_value(&marks, path, line[k], what, s, quoted[(size_t)k * MAX_ITEMS + c], d,
                              &v, err);
            t->value[t->n_rows * n_cols + k] = v * (scale ? scale[k] : 1.0);
        }
        if (st == SC_OK)
            t->line[t->n_rows++] = line[0];
    }
    if (st == SC_OK && t->n_rows == 0)
        st = sc_error_set(err, SC_E_INPUT, path, line[0], "no item with values");
    if (st == SC_OK) {
        t->decimal = marks.mark ? marks.mark : '.';
        notes->decimals = marks.decimals;
    }
    for (int k = 0; k < 16; ++k)
        free(text[k]);
    free(prev);
    free(items);
    free(field);
    free(quoted);
    sc_csv_close(&r);
    sc_imp_conv_close(&conv);
    if (st != SC_OK)
        sc_table_free(t);
    return st;
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
