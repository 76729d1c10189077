/* import_table.c — owns sc_table_read: the named numeric columns of a measuring machine's export
 * (SPEC §10), with the delimiter and decimal mark detected. Written by hand: Debian's CSV
 * libraries (libcsv) neither detect the delimiter nor read decimal commas, and the file:line
 * error convention needs the line of every value. Line reading is the strict sc_csv reader. */
#include "selfcal/import.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"

#define MAX_TABLE_FIELDS 256
#define PREAMBLE_MAX 100 /* lines before the header line that name no columns */

/* Split line s at delim in place (double-quoted fields may hold the delimiter; the quotes are
 * removed), trimming blanks; returns the field count or -1 if there are too many. quoted (may be
 * NULL): 1 for each field that was in quotes. */
static int split_fields(char *s, char delim, char **field, unsigned char *quoted, int max)
{
    int n = 0;
    char *p = s;
    if (delim == ' ') { /* columns aligned by blanks: runs of them part fields, none ends a line */
        size_t len = strlen(s);
        while (len > 0 && (s[len - 1] == ' ' || s[len - 1] == '\t'))
            s[--len] = '\0';
    }
    for (;;) {
        if (n == max)
            return -1;
        while (*p == ' ' || (*p == '\t' && delim != '\t'))
            ++p;
        char *start = p, *end;
        if (quoted)
            quoted[n] = *p == '"';
        if (*p == '"') {
            start = ++p;
            char *q = strchr(p, '"');
            end = q ? q : p + strlen(p);
            p = q ? q + 1 : end;
            while (*p && *p != delim)
                ++p;
        } else {
            while (*p && *p != delim)
                ++p;
            end = p;
            while (end > start && (end[-1] == ' ' || (end[-1] == '\t' && delim != '\t')))
                --end;
        }
        int more = *p == delim;
        *end = '\0';
        field[n++] = start;
        if (!more)
            return n;
        ++p;
    }
}

static int name_equal(const char *a, const char *b)
{
    for (; *a && *b; ++a, ++b)
        if (tolower((unsigned char)*a) != tolower((unsigned char)*b))
            return 0;
    return *a == *b;
}

/* A column given by its number ("2": the second), or 0 if name is not a whole number. */
static long column_number(const char *name)
{
    long v = 0;
    if (!*name)
        return 0;
    for (const char *s = name; *s; ++s) {
        if (!isdigit((unsigned char)*s) || v > 100000)
            return 0;
        v = 10 * v + (*s - '0');
    }
    return v;
}

void sc_table_free(sc_table *t)
{
    free(t->value);
    free(t->line);
    t->value = NULL;
    t->line = NULL;
    t->n_rows = 0;
}

/* Parse a field with the file's decimal mark. *mark_seen gets '.', ',' or 0 (no fraction). */
static int parse_number(const char *s, double *out, char *mark_seen)
{
    char buf[128];
    size_t len = strlen(s);
    if (len == 0 || len >= sizeof buf)
        return -1;
    const char *dot = strchr(s, '.'), *comma = strchr(s, ',');
    if (dot && comma)
        return -2;
    if (comma && strchr(comma + 1, ','))
        return -1;
    *mark_seen = dot ? '.' : comma ? ',' : 0;
    memcpy(buf, s, len + 1);
    if (comma)
        buf[comma - s] = '.';
    return sc_parse_double(buf, out);
}

/* The state of one sc_table_read. */
typedef struct table_reader {
    sc_csv r;
    sc_table *t;
    const char *path;
    int n_cols;
    const char *const *names;
    const double *scale;
    char *field[MAX_TABLE_FIELDS];
    unsigned char quoted[MAX_TABLE_FIELDS]; /* the data line's fields that were in quotes */
    int col_of[16], n_header;
    long cap, mark_line;
    long max_rows; /* refused beyond */
    char mark; /* the decimal mark seen so far, 0 if none */
    long after_header; /* lines read since the header (or its repetition) */
    long provisional, provisional_line; /* the last rows read, summary rows ("Mean;..."), and the
                                           first one's line: dropped if nothing but summaries
                                           and a footer follows them */
    sc_error footer_err; /* the first line after the rows that is not a row (its error), while
                            the lines after it are footer too */
} table_reader;

#define FOOTER_MAX 20 /* lines after the last row that are not rows, taken for a footer */

/* The delimiter of a line: a tab if it has one, else ';' if it has one, else ',' if it has one,
 * else blanks (columns aligned by spaces, as some machines print their tables). */
static char delimiter_of(const char *text)
{
    if (strchr(text, '\t'))
        return '\t';
    if (strchr(text, ';'))
        return ';';
    if (strchr(text, ','))
        return ',';
    const char *p = text;
    while (*p == ' ')
        ++p;
    return strchr(p, ' ') ? ' ' : ',';
}

/* text (not modified) copied into buf (PREAMBLE_LINE bytes) and split there at its delimiter
 * into field; the field count, or -2 if the line is longer than buf. */
#define PREAMBLE_LINE 4096
static int split_copy(const char *text, char *buf, char **field)
{
    size_t len = strlen(text);
    if (len >= PREAMBLE_LINE)
        return -2;
    memcpy(buf, text, len + 1);
    return split_fields(buf, delimiter_of(buf), field, NULL, MAX_TABLE_FIELDS);
}

/* The header line, text (split in place) at line ln: the delimiter, and where each wanted
 * column is (exactly once; a name no column has that is a whole number N is the N-th column). */
static sc_status read_header_line(table_reader *tr, char *text, long ln, sc_error *err)
{
    sc_table *t = tr->t;
    t->header_line = ln;
    t->delimiter = delimiter_of(text);
    tr->n_header = split_fields(text, t->delimiter, tr->field, NULL, MAX_TABLE_FIELDS);
    if (tr->n_header < 0)
        return sc_error_set(err, SC_E_INPUT, tr->path, ln, "more than %d columns",
                            MAX_TABLE_FIELDS);
    for (int k = 0; k < tr->n_cols; ++k) {
        tr->col_of[k] = -1;
        for (int f = 0; f < tr->n_header; ++f)
            if (name_equal(tr->field[f], tr->names[k])) {
                if (tr->col_of[k] >= 0)
                    return sc_error_set(err, SC_E_INPUT, tr->path, ln,
                                        "two columns are named '%s' (columns %d and %d: give the "
                                        "column by its number)",
                                        tr->names[k], tr->col_of[k] + 1, f + 1);
                tr->col_of[k] = f;
            }
        long num = column_number(tr->names[k]); /* no column of that name: its number (1-based) */
        if (tr->col_of[k] < 0 && num >= 1 && num <= tr->n_header)
            tr->col_of[k] = (int)(num - 1);
        if (tr->col_of[k] < 0)
            return sc_error_set(err, SC_E_INPUT, tr->path, ln,
                                "no column named '%s' in this header line (delimiter '%s')",
                                tr->names[k],
                                t->delimiter == '\t'  ? "tab"
                                : t->delimiter == ';' ? ";"
                                : t->delimiter == ' ' ? "blanks"
                                                      : ",");
    }
    return SC_OK;
}

/* How many of the wanted columns text (not modified) names: all of them, the header line. */
static int names_count(const table_reader *tr, const char *text)
{
    char buf[PREAMBLE_LINE], *field[MAX_TABLE_FIELDS];
    int n = split_copy(text, buf, field), named = 0;
    if (n == -2)
        return tr->n_cols; /* read_header_line decides */
    int by_number = 0;
    for (int k = 0; k < tr->n_cols; ++k) {
        int found = 0;
        for (int f = 0; f < n && !found; ++f)
            found = name_equal(field[f], tr->names[k]);
        long num = column_number(tr->names[k]); /* a column by number: a line that long */
        named += found;
        by_number += !found && num >= 1 && num <= n;
    }
    return named > 0 ? named + by_number : 0; /* numbers count beside a name only */
}

/* Whether every wanted column is given by number: the header is then the line before the data. */
static int all_by_number(const table_reader *tr)
{
    for (int k = 0; k < tr->n_cols; ++k)
        if (column_number(tr->names[k]) < 1)
            return 0;
    return 1;
}

/* Whether field s is empty, or text without a digit ("MM", "Mittelwert": no number at all,
 * where "1.5.5" is a malformed one). */
static int not_a_number(const char *s)
{
    for (; *s; ++s)
        if (isdigit((unsigned char)*s))
            return 0;
    return 1;
}

/* With every column by number: whether text (not modified) is a row, every numbered field there
 * and a number ("A;1;2;3;4" for columns 2 and 3): 1; a damaged row (a numbered field has a
 * digit, yet the line is no row: "P1;2000,87.6;1,67", "P1;;1,67"): -1; else (a header or
 * preamble line, no digit in the numbered fields): 0. */
static int row_by_number(const table_reader *tr, const char *text)
{
    char buf[PREAMBLE_LINE], *field[MAX_TABLE_FIELDS];
    int n = split_copy(text, buf, field), ok = 1, digits = 0;
    if (n == -2)
        return 1;
    for (int k = 0; k < tr->n_cols; ++k) {
        long num = column_number(tr->names[k]);
        double v;
        char mark;
        if (num > n || parse_number(field[num - 1], &v, &mark) != 0)
            ok = 0;
        digits |= num <= n && !not_a_number(field[num - 1]);
    }
    return ok ? 1 : digits ? -1 : 0;
}

/* Whether a line starting with '#' is a header whose first column is the point number's, "#":
 * '#' a field of its own at a delimiter (not blanks: "# x y" is a comment) and every wanted
 * column named. */
static int hash_header(const table_reader *tr, const char *text)
{
    char d = delimiter_of(text), *q = strchr(text, d);
    if (d == ' ' || !q)
        return 0;
    const char *s = text + 1;
    while (s < q && (*s == ' ' || *s == '"'))
        ++s;
    return s == q && names_count(tr, text) >= tr->n_cols;
}

/* Whether text (not modified) is a row of numbers: a data line, so no header comes before it. */
static int looks_like_data(const char *text)
{
    char buf[PREAMBLE_LINE], *field[MAX_TABLE_FIELDS];
    if (delimiter_of(text) == ' ')
        return 0; /* "17 05 2024" in a preamble is no row: blank-aligned rows need a header */
    int n = split_copy(text, buf, field);
    if (n == -2)
        return 1; /* no preamble line is that long */
    if (n < 2)
        return 0;
    for (int f = 0; f < n; ++f) {
        double v;
        char mark;
        if (parse_number(field[f], &v, &mark) != 0)
            return 0;
    }
    return 1;
}

/* Room for one more row. */
static sc_status grow(table_reader *tr, sc_error *err)
{
    sc_table *t = tr->t;
    if (t->n_rows >= tr->max_rows)
        return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                            "more than %ld rows, the most this import takes", tr->max_rows);
    if (t->n_rows < tr->cap)
        return SC_OK;
    long ncap = tr->cap ? 2 * tr->cap : 1024;
    if (ncap > tr->max_rows)
        ncap = tr->max_rows;
    double *nv = realloc(t->value, (size_t)ncap * (size_t)tr->n_cols * sizeof(double));
    if (nv)
        t->value = nv;
    long *nl = nv ? realloc(t->line, (size_t)ncap * sizeof(long)) : NULL;
    if (!nv || !nl)
        return sc_error_set(err, SC_E_NOMEM, tr->path, tr->r.line, "out of memory (%ld rows)", ncap);
    t->line = nl;
    tr->cap = ncap;
    return SC_OK;
}

/* The value of wanted column k in the current line: a number, one decimal mark in the whole file,
 * no decimal comma in a comma-separated file unless the field is quoted ("99,5"), within any
 * plausible measurement. */
static sc_status parse_value(table_reader *tr, int k, double *out, sc_error *err)
{
    const char *s = tr->field[tr->col_of[k]], *name = tr->names[k], *path = tr->path;
    long ln = tr->r.line;
    char seen = 0;
    int rc = parse_number(s, out, &seen);
    if (rc == -2)
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': '%s' has both '.' and ',' (no thousands separators, please)",
                            name, s);
    if (rc != 0)
        return sc_error_set(err, SC_E_INPUT, path, ln, "column '%s': '%s' is not a number", name,
                            s);
    if (seen == ',' && tr->t->delimiter == ',' && !tr->quoted[tr->col_of[k]])
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': decimal comma in a comma-separated file (quote the "
                            "field, or use ';' or tab as delimiter)", name);
    if (seen && tr->mark && seen != tr->mark)
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': decimal '%c' here but '%c' on line %ld (mixed decimal marks)",
                            name, seen, tr->mark, tr->mark_line);
    if (seen && !tr->mark) {
        tr->mark = seen;
        tr->mark_line = ln;
    }
    if (!(fabs(*out) <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': %s is beyond any plausible measurement", name, s);
    return SC_OK;
}

static sc_status read_row(table_reader *tr, int nf, sc_error *err);


/* Whether text (a field no wanted column is read from) names a statistic, as the summary rows
 * machines add under a table do ("Mean", "Mittelwert", "Max.", "Std dev:"): such a row's numbers
 * are no measurement, though they may well fall near a mark (the mean of a plate's points lies
 * on its centre mark). */
static int names_statistic(const char *text)
{
    static const char *const words[] = {
        "mean", "average", "avg", "min", "max", "minimum", "maximum", "std", "stdev", "stddev",
        "std dev", "std. dev", "sigma", "range", "sum", "total", "statistics", "mittelwert",
        "durchschnitt", "streuung", "standardabweichung", "spannweite", "summe", "moyenne",
        "ecart type", "media", "promedio", "media aritmetica"};
    char w[32];
    size_t n = strlen(text);
    while (n > 0 && (text[n - 1] == ':' || text[n - 1] == '.' || text[n - 1] == ' '))
        --n;
    if (n == 0 || n >= sizeof w)
        return 0;
    memcpy(w, text, n);
    w[n] = '\0';
    for (size_t k = 0; k < sizeof words / sizeof words[0]; ++k)
        if (name_equal(w, words[k]))
            return 1;
    return 0;
}

/* The lines after the header that are not rows, but what machines write between and after
 * them (nf fields split at tr->field): a line of empty fields (a spreadsheet's ";;;;"): 1; the
 * header again (a page break): 2; a line of unit names right under the header ("MM","MM"): 3; a
 * row without any of the wanted values (a feature the machine failed to measure): 4; a summary
 * row (another field names a statistic: "Mean;12.5;3.1"): 5; else 0. */
static int skipped_kind(const table_reader *tr, int nf)
{
    int empty = 1, same = nf == tr->n_header, header = same, texts = same, blanks = same;
    int some_text = 0;
    for (int f = 0; f < nf; ++f)
        empty &= !tr->field[f][0];
    if (empty)
        return 1;
    for (int k = 0; k < tr->n_cols && same; ++k) { /* every wanted field, each test its own */
        const char *s = tr->field[tr->col_of[k]];
        header = header && name_equal(s, tr->names[k]);
        texts = texts && not_a_number(s); /* unit names or empty (";nm;nm": no unit for n) */
        some_text |= s[0] != 0;
        blanks = blanks && !s[0];
    }
    texts = texts && some_text;
    if (header)
        return 2;
    if (texts && tr->after_header == 1)
        return 3;
    if (blanks)
        return 4;
    for (int f = 0; f < nf; ++f) {
        int wanted = 0;
        for (int k = 0; k < tr->n_cols; ++k)
            wanted |= tr->col_of[k] == f;
        if (!wanted && names_statistic(tr->field[f]))
            return 5;
    }
    return 0;
}

/* Whether the current line (nf fields at tr->field), which failed as a row, is a damaged row
 * rather than a footer's text: its first field is a number (a point number), or a wanted field
 * it has is one (a truncated or garbled row: "2;1.5", "2;nan;3", "P12;1.5"). */
static int damaged_row(const table_reader *tr, int nf)
{
    double v;
    char mark;
    if (nf >= 1 && parse_number(tr->field[0], &v, &mark) == 0)
        return 1;
    for (int k = 0; k < tr->n_cols; ++k)
        if (tr->col_of[k] < nf && parse_number(tr->field[tr->col_of[k]], &v, &mark) == 0)
            return 1;
    return 0;
}

/* Whether the current line (nf fields at tr->field) is no row at all: another field count, or a
 * wanted field that is no number — a footer's line if no row follows. */
static int not_a_row(const table_reader *tr, int nf)
{
    if (nf != tr->n_header)
        return 1;
    for (int k = 0; k < tr->n_cols; ++k)
        if (not_a_number(tr->field[tr->col_of[k]]))
            return 1;
    return 0;
}

/* One line after the header: a row (as many fields as the header, every wanted value, scaled),
 * a line machines write that is skipped and counted (skipped_kind), or, after some rows, the
 * start of a footer: its error kept and reported only if a row follows. */
static sc_status read_data_line(table_reader *tr, sc_error *err)
{
    sc_table *t = tr->t;
    tr->after_header++;
    int nf = split_fields(tr->r.text, t->delimiter, tr->field, tr->quoted, MAX_TABLE_FIELDS);
    if (tr->footer_err.code) { /* in a footer: a row after it makes its first line an error */
        if (nf >= 0 && !not_a_row(tr, nf) && skipped_kind(tr, nf) == 0) {
            if (err)
                *err = tr->footer_err;
            return tr->footer_err.code;
        }
        if (++t->n_footer > FOOTER_MAX) {
            if (err)
                *err = tr->footer_err;
            return tr->footer_err.code;
        }
        return SC_OK;
    }
    int kind = nf >= 0 ? skipped_kind(tr, nf) : 0;
    if (kind == 1)
        return SC_OK;
    if (kind == 2) { /* a units line may follow it again */
        if (!t->n_header_repeats++)
            t->header_repeat_line = tr->r.line;
        tr->after_header = 0;
        return SC_OK;
    }
    if (kind == 3 && !t->units_line)
        t->units_line = tr->r.line;
    if (kind == 4 && !t->n_no_values++)
        t->no_values_line = tr->r.line;
    if (kind == 3 || kind == 4)
        return SC_OK;
    sc_error e;
    sc_error_clear(&e);
    sc_status st = read_row(tr, nf, &e);
    if (st == SC_OK) { /* a summary row is a row until only summaries and a footer follow it */
        if (kind == 5 && !tr->provisional++)
            tr->provisional_line = tr->r.line;
        if (kind != 5)
            tr->provisional = 0;
        return SC_OK;
    }
    if (st == SC_E_INPUT && t->n_rows > 0 && (nf < 0 || (not_a_row(tr, nf) && !damaged_row(tr, nf)))) {
        tr->footer_err = e; /* perhaps a footer: decided by what follows */
        t->footer_line = tr->r.line;
        t->n_footer = 1;
        return SC_OK;
    }
    if (st != SC_OK && err)
        *err = e;
    return st;
}

/* One row: as many fields as the header, every wanted value, scaled. */
static sc_status read_row(table_reader *tr, int nf, sc_error *err)
{
    sc_table *t = tr->t;
    if (nf != tr->n_header)
        return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                            "%d fields, the header line (line %ld) has %d%s", nf < 0 ? MAX_TABLE_FIELDS : nf,
                            t->header_line, tr->n_header,
                            t->delimiter == ',' ? " (decimal commas need ';' or tab as delimiter)" : "");
    sc_status st = grow(tr, err);
    if (st != SC_OK)
        return st;
    for (int k = 0; k < tr->n_cols && st == SC_OK; ++k) {
        double v;
        st = parse_value(tr, k, &v, err);
        if (st == SC_OK)
            t->value[t->n_rows * tr->n_cols + k] = v * (tr->scale ? tr->scale[k] : 1.0);
    }
    if (st == SC_OK)
        t->line[t->n_rows++] = tr->r.line;
    return st;
}

sc_status sc_table_read(const char *path, int n_cols, const char *const *names,
                        const double *scale, sc_table *t, sc_error *err)
{
    return sc_table_read_max(path, n_cols, names, scale, SC_TABLE_MAX_ROWS, t, err);
}

sc_status sc_table_read_max(const char *path, int n_cols, const char *const *names,
                            const double *scale, long max_rows, sc_table *t, sc_error *err)
{
    memset(t, 0, sizeof *t);
    snprintf(t->path, sizeof t->path, "%s", path);
    t->n_cols = n_cols;
    if (n_cols < 1 || n_cols > 16 || !names)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "a table read asks for 1..16 columns, got %d",
                            n_cols);
    if (max_rows < 1 || max_rows > SC_TABLE_MAX_ROWS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "a table read takes 1..%ld rows at most, "
                            "not %ld", SC_TABLE_MAX_ROWS, max_rows);
    for (int a = 0; scale && a < n_cols; ++a)
        if (!isfinite(scale[a]) || scale[a] == 0)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "the scale of column '%s' must be finite and nonzero, got %g",
                                names[a], scale[a]);
    for (int a = 0; a < n_cols; ++a) /* one column cannot be two quantities */
        for (int b = 0; b < a; ++b)
            if (name_equal(names[a], names[b]))
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "the column '%s' is asked for twice (as the %s and the %s "
                                    "quantity)", names[a], b == 0 ? "1st" : b == 1 ? "2nd" : "3rd",
                                    a == 1 ? "2nd" : a == 2 ? "3rd" : "4th");
    table_reader tr;
    memset(&tr, 0, sizeof tr);
    tr.t = t;
    tr.path = path;
    tr.n_cols = n_cols;
    tr.names = names;
    tr.scale = scale;
    tr.max_rows = max_rows;
    sc_status st = sc_csv_open(&tr.r, path, err);
    if (st != SC_OK)
        return st;
    int got = 0;
    /* the header is the first line naming every wanted column; lines before it that are not
     * data (a machine's preamble: program, date, operator) are skipped, up to PREAMBLE_MAX of
     * them. If none names them all, the first line naming some of them (else the first line)
     * is taken for the header and its error told. */
    char *first = NULL; /* that line, and its number */
    long first_line = 0, preamble = 0;
    int first_named = 0;
    int hash_rows = 0; /* the header began with '#' ("#;X;Y": the point number's column), so rows
                          starting "#<digit>" are rows, not comments */
    int numbers = all_by_number(&tr);
    char *prev = NULL; /* with columns by number: the last line before the data, its number */
    long prev_line = 0;
    while (st == SC_OK && (got = sc_csv_next_line(&tr.r, err)) == 1) {
        if (sc_csv_is_blank(&tr.r))
            continue;
        if (tr.r.text[0] == '#') {
            if (hash_rows ? !isdigit((unsigned char)tr.r.text[1])
                          : (t->header_line || numbers || !hash_header(&tr, tr.r.text)))
                continue; /* a comment */
            hash_rows = 1;
            tr.r.skip_run = 0; /* a row (or the "#;X;Y" header), not a comment */
        }
        if (t->header_line) {
            st = read_data_line(&tr, err);
            continue;
        }
        if (numbers) { /* the header: the line before the first row */
            int row = row_by_number(&tr, tr.r.text);
            if (row < 0 && prev) { /* a damaged row before the first good one: its error */
                char *h = prev;
                prev = NULL;
                st = read_header_line(&tr, h, prev_line, err);
                free(h);
                if (st == SC_OK) {
                    sc_error e;
                    sc_error_clear(&e);
                    int nf = split_fields(tr.r.text, t->delimiter, tr.field, tr.quoted,
                                          MAX_TABLE_FIELDS);
                    st = read_row(&tr, nf, &e);
                    if (st == SC_OK) /* cannot be: it failed as a row above */
                        st = sc_error_set(&e, SC_E_INPUT, path, tr.r.line, "not a row");
                    if (err)
                        *err = e;
                }
                break;
            }
            if (row < 0) { /* a damaged row with no header before it */
                st = sc_error_set(err, SC_E_INPUT, path, tr.r.line,
                                  "not a row, and no header line before it (columns given by "
                                  "number need one)");
                break;
            }
            if (row == 0) {
                free(prev);
                prev = strdup(tr.r.text);
                prev_line = tr.r.line;
                if (!prev)
                    st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
                else if (++preamble > PREAMBLE_MAX + 1)
                    break;
                continue;
            }
            if (!prev) {
                st = sc_error_set(err, SC_E_INPUT, path, tr.r.line,
                                  "no header line before the first row (columns given by number "
                                  "need one)");
                break;
            }
            char *h = prev;
            prev = NULL;
            st = read_header_line(&tr, h, prev_line, err);
            free(h);
            if (st == SC_OK)
                st = read_data_line(&tr, err);
            continue;
        }
        int named = names_count(&tr, tr.r.text);
        if (named == n_cols) {
            st = read_header_line(&tr, tr.r.text, tr.r.line, err);
            continue;
        }
        if (!first || (named > 0 && !first_named)) {
            free(first);
            first = strdup(tr.r.text);
            first_line = tr.r.line;
            first_named = named > 0;
            if (!first)
                st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        }
        if (st == SC_OK && (looks_like_data(tr.r.text) || ++preamble > PREAMBLE_MAX))
            break; /* no header before the data: the first line's error */
    }
    if (st == SC_OK && got < 0)
        st = err ? err->code : SC_E_INPUT;
    else if (st == SC_OK && !t->header_line && first)
        st = read_header_line(&tr, first, first_line, err);
    else if (st == SC_OK && !t->header_line)
        st = sc_error_set(err, SC_E_INPUT, path, tr.r.line, "no header line naming the columns");
    free(first);
    free(prev);
    if (st == SC_OK && tr.provisional > 0) { /* trailing summary rows: no measurements */
        t->n_rows -= tr.provisional;
        t->n_summary = tr.provisional;
        t->summary_line = tr.provisional_line;
    }
    if (st == SC_OK && !t->header_line) /* cannot happen: read_header_line failed or set it */
        st = sc_error_set(err, SC_E_INTERNAL, path, tr.r.line, "no header line");
    else if (st == SC_OK && t->n_rows == 0)
        st = sc_error_set(err, SC_E_INPUT, path, tr.r.line, "no data lines after the header");
    if (st == SC_OK)
        t->decimal = tr.mark ? tr.mark : '.';
    sc_csv_close(&tr.r);
    if (st != SC_OK)
        sc_table_free(t);
    return st;
}
