/* import_table.c — owns sc_table_read: the named numeric columns of a measuring machine's export
 * (SPEC §10), with the delimiter and decimal mark detected. Written by hand: Debian's CSV
 * libraries (libcsv) neither detect the delimiter nor read decimal commas, and the file:line
 * error convention needs the line of every value. Line reading is the strict sc_csv reader. */
#include "selfcal/import.h"

#include <ctype.h>
#include <iconv.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "import_table_internal.h"
#include "selfcal/csv.h"

#define MAX_TABLE_FIELDS SC_IMP_MAX_FIELDS
#define PREAMBLE_MAX SC_IMP_PREAMBLE_MAX

/* Split line s at delim in place (double-quoted fields may hold the delimiter; the quotes are
 * removed), trimming blanks; returns the field count or -1 if there are too many. quoted (may be
 * NULL): 1 for each field that was in quotes. */
int sc_imp_split_fields(char *s, char delim, char **field, unsigned char *quoted, int max)
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

int sc_imp_name_equal(const char *a, const char *b)
{
    for (; *a && *b; ++a, ++b)
        if (tolower((unsigned char)*a) != tolower((unsigned char)*b))
            return 0;
    return *a == *b;
}

int sc_imp_find_column(char *const *field, int n, const char *name)
{
    for (int f = 0; f < n; ++f)
        if (sc_imp_name_equal(field[f], name))
            return f;
    long num = sc_imp_column_number(name);
    return num >= 1 && num <= n ? (int)(num - 1) : -1;
}

void sc_imp_set_decimal(const sc_imp_marks *m, sc_table *t, sc_table_notes *notes)
{
    t->decimal = m->mark ? m->mark : '.';
    if (notes)
        notes->decimals = m->decimals;
}

/* A column given by its number ("2": the second), or 0 if name is not a whole number. */
long sc_imp_column_number(const char *name)
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
int sc_imp_parse_number(const char *s, double *out, char *mark_seen)
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

int sc_imp_decimals(const char *s)
{
    const char *m = strpbrk(s, ".,");
    int n = 0;
    if (m)
        for (++m; isdigit((unsigned char)*m); ++m)
            ++n;
    return n;
}

bool sc_imp_utf8_valid(const char *s)
{
    const unsigned char *p = (const unsigned char *)s;
    while (*p) {
        int more = *p < 0x80 ? 0 : (*p & 0xE0) == 0xC0 ? 1 : (*p & 0xF0) == 0xE0 ? 2
                 : (*p & 0xF8) == 0xF0 ? 3 : -1;
        if (more < 0 || (more == 1 && *p < 0xC2))
            return false;
        ++p;
        for (int k = 0; k < more; ++k, ++p)
            if ((*p & 0xC0) != 0x80)
                return false;
    }
    return true;
}

bool sc_imp_is_placeholder(const sc_table_layout *lay, const char *s)
{
    for (int k = 0; lay && k < lay->n_missing; ++k)
        if (!strcmp(s, lay->missing[k]))
            return true;
    return false;
}

sc_status sc_imp_conv_open(sc_imp_conv *c, sc_table_encoding enc, const char *path, sc_error *err)
{
    static const char *const names[] = {"UTF-8", "CP1252", "ISO-8859-1", "CP932"};
    static const char *const shown[] = {"utf-8", "cp1252", "latin-1", "shift-jis"};
    memset(c, 0, sizeof *c);
    if ((int)enc < 0 || (int)enc > SC_ENC_SHIFT_JIS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "unknown text encoding %d", (int)enc);
    c->name = shown[enc];
    if (enc == SC_ENC_UTF8)
        return SC_OK;
    iconv_t cd = iconv_open("UTF-8", names[enc]);
    if (cd == (iconv_t)-1)
        return sc_error_set(err, SC_E_IO, path, 0, "the %s converter is not available", c->name);
    c->buf = malloc(3 * (size_t)SC_CSV_MAX_LINE + 1); /* every byte may become 3 */
    if (!c->buf) {
        iconv_close(cd);
        return sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    c->cd = cd;
    return SC_OK;
}

sc_status sc_imp_conv_line(sc_imp_conv *c, sc_csv *r, sc_error *err)
{
    if (!c->cd)
        return SC_OK;
    char *in = r->text, *out = c->buf;
    size_t inleft = r->len, outleft = 3 * (size_t)SC_CSV_MAX_LINE;
    iconv((iconv_t)c->cd, NULL, NULL, NULL, NULL);
    if (iconv((iconv_t)c->cd, &in, &inleft, &out, &outleft) == (size_t)-1)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "byte %ld of this line is not %s text (another --encoding?)",
                            (long)(in - r->text) + 1, c->name);
    *out = '\0';
    r->text = c->buf;
    r->len = (size_t)(out - c->buf);
    return SC_OK;
}

void sc_imp_conv_close(sc_imp_conv *c)
{
    if (c->cd)
        iconv_close((iconv_t)c->cd);
    free(c->buf);
    memset(c, 0, sizeof *c);
}

const char *sc_imp_encoding_hint(const sc_table_layout *lay, const char *header_text)
{
    if ((lay && lay->encoding != SC_ENC_UTF8) || sc_imp_utf8_valid(header_text))
        return "";
    return " (this header line is not UTF-8 text: give the file's encoding, --encoding "
           "cp1252|latin-1|shift-jis)";
}

/* Append hint to err's message (as much as fits). */
static void append_hint(sc_error *err, const char *hint)
{
    if (!err || !hint[0])
        return;
    size_t n = strlen(err->msg);
    snprintf(err->msg + n, sizeof err->msg - n, "%s", hint);
}

#define PREAMBLE_LINE_MAX 4096
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
    long cap;
    long max_rows; /* refused beyond */
    sc_imp_marks marks; /* the decimal mark seen so far (0 if none), its line, decimals */
    long after_header; /* lines read since the header (or its repetition) */
    long provisional, provisional_line; /* the last rows read, summary rows ("Mean;..."), and the
                                           first one's line: dropped if nothing but summaries
                                           and a footer follows them */
    sc_error footer_err; /* the first line after the rows that is not a row (its error), while
                            the lines after it are footer too */
    const sc_table_layout *lay; /* NULL: none */
    sc_table_notes *notes;      /* never NULL (a local one if the caller gives none) */
    int n_named;                /* the header's fields up to its last non-empty one */
    int where_of[SC_TABLE_MAX_WHERE]; /* the where filters' columns */
    int in_rows;                /* the header (or, without one, the first row) was found */
    long first_row_line;        /* without a header line: the first row's line */
    char header_text[PREAMBLE_LINE_MAX]; /* the header line as read (for hints) */
    /* finding the header (sc_imp_read_wide): it is the first line naming every wanted column;
     * lines before it that are not data (a machine's preamble: program, date, operator) are
     * skipped, up to PREAMBLE_MAX of them. If none names them all, the first line naming some
     * of them (else the first line) is taken for the header and its error told. */
    char *first;       /* that line, its number, whether it names some */
    long first_line;
    int first_named;
    long preamble;     /* lines before the header */
    int hash_rows;     /* the header began with '#' ("#;X;Y": the point number's column), so rows
                          starting "#<digit>" are rows, not comments */
    int numbers;       /* every wanted column given by number (all_by_number) */
    int no_header;     /* the layout says there is no header line */
    char *prev;        /* with columns by number: the last line before the data, its number */
    long prev_line;
    long no_row_run;   /* lines in a row after the header that were no row */
} table_reader;

#define FOOTER_MAX 20 /* lines after the last row that are not rows, taken for a footer */

/* The delimiter of a line: a tab if it has one, else ';' if it has one, else ',' if it has one,
 * else blanks (columns aligned by spaces, as some machines print their tables). */
char sc_imp_delimiter_of(const char *text)
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
#define PREAMBLE_LINE PREAMBLE_LINE_MAX
static int split_copy(const char *text, char *buf, char **field)
{
    size_t len = strlen(text);
    if (len >= PREAMBLE_LINE)
        return -2;
    memcpy(buf, text, len + 1);
    return sc_imp_split_fields(buf, sc_imp_delimiter_of(buf), field, NULL, MAX_TABLE_FIELDS);
}

/* The header line, text (split in place) at line ln: the delimiter, and where each wanted
 * column is (exactly once; a name no column has that is a whole number N is the N-th column). */
static sc_status read_header_line(table_reader *tr, char *text, long ln, sc_error *err)
{
    sc_table *t = tr->t;
    t->header_line = ln;
    tr->in_rows = 1;
    snprintf(tr->header_text, sizeof tr->header_text, "%s", text);
    t->delimiter = sc_imp_delimiter_of(text);
    tr->n_header = sc_imp_split_fields(text, t->delimiter, tr->field, NULL, MAX_TABLE_FIELDS);
    if (tr->n_header < 0)
        return sc_error_set(err, SC_E_INPUT, tr->path, ln,
                            "more than %d columns (items in columns, one column per point? "
                            "--transpose)", MAX_TABLE_FIELDS);
    tr->n_named = tr->n_header; /* trailing empty names (a header ending in a tab): no columns */
    while (tr->n_named > 1 && !tr->field[tr->n_named - 1][0])
        --tr->n_named;
    tr->notes->header_fields = tr->n_header;
    tr->notes->named_fields = tr->n_named;
    for (int w = 0; tr->lay && w < tr->lay->n_where; ++w) { /* the filters' columns */
        tr->where_of[w] = sc_imp_find_column(tr->field, tr->n_header, tr->lay->where_col[w]);
        if (tr->where_of[w] < 0)
            return sc_error_set(err, SC_E_INPUT, tr->path, ln,
                                "no column named '%s' (--where) in this header line%s",
                                tr->lay->where_col[w],
                                sc_imp_encoding_hint(tr->lay, tr->header_text));
    }
    for (int k = 0; k < tr->n_cols; ++k) {
        tr->col_of[k] = -1;
        for (int f = 0; f < tr->n_header; ++f)
            if (sc_imp_name_equal(tr->field[f], tr->names[k])) {
                if (tr->col_of[k] >= 0)
                    return sc_error_set(err, SC_E_INPUT, tr->path, ln,
                                        "two columns are named '%s' (columns %d and %d: give the "
                                        "column by its number)",
                                        tr->names[k], tr->col_of[k] + 1, f + 1);
                tr->col_of[k] = f;
            }
        long num = sc_imp_column_number(tr->names[k]); /* no column of that name: its number (1-based) */
        if (tr->col_of[k] < 0 && num >= 1 && num <= tr->n_header)
            tr->col_of[k] = (int)(num - 1);
        if (tr->col_of[k] < 0)
            return sc_error_set(err, SC_E_INPUT, tr->path, ln,
                                "no column named '%s' in this header line (delimiter '%s')%s",
                                tr->names[k],
                                t->delimiter == '\t'  ? "tab"
                                : t->delimiter == ';' ? ";"
                                : t->delimiter == ' ' ? "blanks"
                                                      : ",",
                                sc_imp_encoding_hint(tr->lay, tr->header_text));
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
            found = sc_imp_name_equal(field[f], tr->names[k]);
        long num = sc_imp_column_number(tr->names[k]); /* a column by number: a line that long */
        named += found;
        by_number += !found && num >= 1 && num <= n;
    }
    return named > 0 ? named + by_number : 0; /* numbers count beside a name only */
}

/* Whether every wanted column is given by number: the header is then the line before the data. */
static int all_by_number(const table_reader *tr)
{
    for (int k = 0; k < tr->n_cols; ++k)
        if (sc_imp_column_number(tr->names[k]) < 1)
            return 0;
    return 1;
}

/* Whether field s is empty, or text without a digit ("MM", "Mittelwert": no number at all,
 * where "1.5.5" is a malformed one). */
int sc_imp_not_a_number(const char *s)
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
        long num = sc_imp_column_number(tr->names[k]);
        double v;
        char mark;
        if (num > n || sc_imp_parse_number(field[num - 1], &v, &mark) != 0)
            ok = 0;
        digits |= num <= n && !sc_imp_not_a_number(field[num - 1]);
    }
    return ok ? 1 : digits ? -1 : 0;
}

/* Whether a line starting with '#' is a header whose first column is the point number's, "#":
 * '#' a field of its own at a delimiter (not blanks: "# x y" is a comment) and every wanted
 * column named. */
static int hash_header(const table_reader *tr, const char *text)
{
    char d = sc_imp_delimiter_of(text), *q = strchr(text, d);
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
    if (sc_imp_delimiter_of(text) == ' ')
        return 0; /* "17 05 2024" in a preamble is no row: blank-aligned rows need a header */
    int n = split_copy(text, buf, field);
    if (n == -2)
        return 1; /* no preamble line is that long */
    if (n < 2)
        return 0;
    for (int f = 0; f < n; ++f) {
        double v;
        char mark;
        if (sc_imp_parse_number(field[f], &v, &mark) != 0)
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
sc_status sc_imp_value(sc_imp_marks *m, const char *path, long ln, const char *name,
                       const char *s, int quoted, char delimiter, double *out, sc_error *err)
{
    char seen = 0;
    int rc = sc_imp_parse_number(s, out, &seen);
    if (rc == -2)
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': '%s' has both '.' and ',' (no thousands separators, please)",
                            name, s);
    if (rc != 0)
        return sc_error_set(err, SC_E_INPUT, path, ln, "column '%s': '%s' is not a number%s", name,
                            s, sc_imp_not_a_number(s) && s[0] ? " (a placeholder for a mark not "
                            "measured? --missing TOKEN)" : "");
    if (seen == ',' && delimiter == ',' && !quoted)
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': decimal comma in a comma-separated file (quote the "
                            "field, or use ';' or tab as delimiter)", name);
    if (seen && m->mark && seen != m->mark)
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': decimal '%c' here but '%c' on line %ld (mixed decimal marks)",
                            name, seen, m->mark, m->mark_line);
    if (seen && !m->mark) {
        m->mark = seen;
        m->mark_line = ln;
    }
    int dec = sc_imp_decimals(s);
    if (dec > m->decimals)
        m->decimals = dec;
    if (!(fabs(*out) <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "column '%s': %s is beyond any plausible measurement", name, s);
    return SC_OK;
}

/* The value of wanted column k in the current line (sc_imp_value's rules). */
static sc_status parse_value(table_reader *tr, int k, double *out, sc_error *err)
{
    sc_status st = sc_imp_value(&tr->marks, tr->path, tr->r.line, tr->names[k],
                                tr->field[tr->col_of[k]], tr->quoted[tr->col_of[k]],
                                tr->t->delimiter, out, err);
    if (tr->marks.decimals > tr->notes->decimals)
        tr->notes->decimals = tr->marks.decimals;
    return st;
}

static sc_status read_row(table_reader *tr, int nf, sc_error *err);

/* Whether a line of nf fields (at tr->field) fits the header: as many fields; or fewer, where
 * the header's last fields are empty (a header ending in a tab); or more, where the extra
 * fields hold no number (an unlabelled column: a tolerance bar). */
static int fields_fit(const table_reader *tr, int nf)
{
    if (nf == tr->n_header)
        return 1;
    if (nf < 0 || nf < tr->n_named)
        return 0;
    for (int k = 0; k < tr->n_cols; ++k)
        if (tr->col_of[k] >= nf)
            return 0;
    for (int w = 0; tr->lay && w < tr->lay->n_where; ++w)
        if (tr->where_of[w] >= nf)
            return 0;
    for (int f = tr->n_header; f < nf; ++f)
        if (!sc_imp_not_a_number(tr->field[f]))
            return 0;
    return 1;
}

/* Whether the where filters let the current line (nf fields that fit) through. */
static int where_passes(const table_reader *tr)
{
    for (int w = 0; tr->lay && w < tr->lay->n_where; ++w)
        if (!sc_imp_name_equal(tr->field[tr->where_of[w]], tr->lay->where_value[w]))
            return 0;
    return 1;
}


/* Whether text (a field no wanted column is read from) names a statistic, as the summary rows
 * machines add under a table do ("Mean", "Mittelwert", "Max.", "Std dev:"): such a row's numbers
 * are no measurement, though they may well fall near a mark (the mean of a plate's points lies
 * on its centre mark). */
int sc_imp_names_statistic(const char *text)
{
    static const char *const words[] = {
        "mean", "average", "avg", "min", "max", "minimum", "maximum", "std", "stdev", "stddev",
        "std dev", "std. dev", "sigma", "range", "sum", "total", "statistics", "mittelwert",
        "durchschnitt", "streuung", "standardabweichung", "spannweite", "summe", "moyenne",
        "ecart type", "media", "promedio", "media aritmetica",
        /* German (Excel's function names and CMM reports) */
        "stabw", "stabwn", "stabw.s", "stabw.n", "standardabw", "std.-abw", "std.abw", "mittel",
        "mittelw", "minimal", "maximal", "anzahl", "varianz",
        /* French */
        "écart type", "écart-type", "ecart-type", "Écart type", "Écart-type", "moyenne arithmétique",
        "étendue", "Étendue", "etendue", "somme", "écart", "Écart",
        /* Italian */
        "deviazione standard", "dev. std", "dev.std", "dev std", "minimo", "massimo", "intervallo",
        "campo di variazione", "somma", "media aritmetica",
        /* Spanish */
        "desviación estándar", "desviacion estandar", "desv. est", "desvest", "mínimo", "máximo",
        "rango", "suma",
        /* Japanese (Mitutoyo, Keyence, Excel in Japanese) */
        "平均", "平均値", "最大", "最大値", "最小", "最小値", "標準偏差", "範囲", "合計", "レンジ",
        "シグマ"};
    char w[64];
    size_t n = strlen(text);
    while (n > 0 && (text[n - 1] == ':' || text[n - 1] == '.' || text[n - 1] == ' '))
        --n;
    if (n == 0 || n >= sizeof w)
        return 0;
    memcpy(w, text, n);
    w[n] = '\0';
    for (size_t k = 0; k < sizeof words / sizeof words[0]; ++k)
        if (sc_imp_name_equal(w, words[k]))
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
    int empty = 1, same = fields_fit(tr, nf), header = same, texts = same, blanks = same;
    int some_text = 0;
    for (int f = 0; f < nf; ++f)
        empty &= !tr->field[f][0];
    if (empty)
        return 1;
    for (int k = 0; k < tr->n_cols && same; ++k) { /* every wanted field, each test its own */
        const char *s = tr->field[tr->col_of[k]];
        header = header && sc_imp_name_equal(s, tr->names[k]);
        texts = texts && sc_imp_not_a_number(s); /* unit names or empty (";nm;nm": no unit for n) */
        some_text |= s[0] != 0;
        blanks = blanks && !s[0];
    }
    texts = texts && some_text;
    if (header && !tr->t->header_line) /* no header line: "1;2" is a row, not its repetition */
        header = 0;
    if (header)
        return 2;
    if (texts && tr->after_header == 1 && tr->t->header_line)
        return 3;
    if (blanks)
        return 4;
    for (int f = 0; f < nf; ++f) {
        int wanted = 0;
        for (int k = 0; k < tr->n_cols; ++k)
            wanted |= tr->col_of[k] == f;
        if (!wanted && sc_imp_names_statistic(tr->field[f]))
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
    if (nf >= 1 && sc_imp_parse_number(tr->field[0], &v, &mark) == 0)
        return 1;
    for (int k = 0; k < tr->n_cols; ++k)
        if (tr->col_of[k] < nf && sc_imp_parse_number(tr->field[tr->col_of[k]], &v, &mark) == 0)
            return 1;
    return 0;
}

/* Whether the current line (nf fields at tr->field) is no row at all: another field count, or a
 * wanted field that is no number — a footer's line if no row follows. */
static int not_a_row(const table_reader *tr, int nf)
{
    if (!fields_fit(tr, nf))
        return 1;
    for (int k = 0; k < tr->n_cols; ++k)
        if (sc_imp_not_a_number(tr->field[tr->col_of[k]]))
            return 1;
    return 0;
}

/* The layout's rules on a line of nf fields that fit: whether the where filters leave it out
 * (counted), and its placeholders of unmeasured marks emptied (counted). */
static int layout_leaves_out(table_reader *tr, int nf)
{
    if (nf < 0 || !tr->lay || !fields_fit(tr, nf))
        return 0;
    if (!where_passes(tr)) { /* another feature or characteristic: not read */
        if (!tr->notes->n_filtered++)
            tr->notes->filtered_line = tr->r.line;
        return 1;
    }
    for (int k = 0; k < tr->n_cols; ++k) /* placeholders of unmeasured marks: empty */
        if (sc_imp_is_placeholder(tr->lay, tr->field[tr->col_of[k]])) {
            tr->field[tr->col_of[k]][0] = '\0';
            if (!tr->notes->n_placeholder++)
                tr->notes->placeholder_line = tr->r.line;
        }
    return 0;
}

/* A line while in a footer (tr->footer_err set): a row after it makes the footer's first line
 * an error, as do more than FOOTER_MAX lines of it. */
static sc_status footer_line(table_reader *tr, int nf, sc_error *err)
{
    int row = nf >= 0 && !not_a_row(tr, nf) && skipped_kind(tr, nf) == 0;
    if (row || ++tr->t->n_footer > FOOTER_MAX) {
        if (err)
            *err = tr->footer_err;
        return tr->footer_err.code;
    }
    return SC_OK;
}

/* Whether a line of skipped_kind kind 1..4 is passed over (each kind counted as it is). */
static int skipped_line(table_reader *tr, int kind)
{
    sc_table *t = tr->t;
    if (kind == 2) { /* a units line may follow it again */
        if (!t->n_header_repeats++)
            t->header_repeat_line = tr->r.line;
        tr->after_header = 0;
    }
    if (kind == 3 && !t->units_line)
        t->units_line = tr->r.line;
    if (kind == 4 && !t->n_no_values++)
        t->no_values_line = tr->r.line;
    return kind >= 1 && kind <= 4;
}

/* One line after the header: a row (as many fields as the header, every wanted value, scaled),
 * a line machines write that is skipped and counted (skipped_kind), or, after some rows, the
 * start of a footer: its error kept and reported only if a row follows. */
static sc_status read_data_line(table_reader *tr, sc_error *err)
{
    sc_table *t = tr->t;
    tr->after_header++;
    int nf = sc_imp_split_fields(tr->r.text, t->delimiter, tr->field, tr->quoted, MAX_TABLE_FIELDS);
    if (layout_leaves_out(tr, nf))
        return SC_OK;
    if (tr->footer_err.code) /* in a footer: a row after it makes its first line an error */
        return footer_line(tr, nf, err);
    int kind = nf >= 0 ? skipped_kind(tr, nf) : 0;
    if (skipped_line(tr, kind))
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
    if (err)
        *err = e;
    return st;
}

/* One row: as many fields as the header, every wanted value, scaled. */
static sc_status read_row(table_reader *tr, int nf, sc_error *err)
{
    sc_table *t = tr->t;
    if (!fields_fit(tr, nf))
        return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                            "%d fields, the %s (line %ld) has %d%s", nf < 0 ? MAX_TABLE_FIELDS : nf,
                            t->header_line ? "header line" : "first row",
                            t->header_line ? t->header_line : tr->first_row_line, tr->n_header,
                            t->delimiter == ',' ? " (decimal commas need ';' or tab as delimiter)" : "");
    if (nf > tr->n_header && !tr->notes->n_ragged++) { /* an unlabelled column's fields */
        tr->notes->ragged_line = tr->r.line;
        tr->notes->ragged_fields = nf;
    }
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
    return sc_imp_read_wide(path, n_cols, names, scale, max_rows, NULL, NULL, t, err);
}

/* For a header that is a data row (it has a number) taken because one of its fields matched a
 * wanted column's name (an AXIS value X against the column x): the hint saying so, else "". */
static const char *row_taken_hint(const table_reader *tr, const char *text, char *hint, size_t cap)
{
    char buf[PREAMBLE_LINE], *field[MAX_TABLE_FIELDS];
    int n = split_copy(text, buf, field), number = 0;
    const char *matched = NULL;
    hint[0] = '\0';
    for (int f = 0; f < n; ++f) {
        double v;
        char mark;
        number |= sc_imp_parse_number(field[f], &v, &mark) == 0;
        for (int k = 0; k < tr->n_cols && !matched; ++k)
            if (sc_imp_name_equal(field[f], tr->names[k]))
                matched = field[f];
    }
    if (number && matched)
        snprintf(hint, cap,
                 ": this line is a data row, taken for the header because its value '%.40s' "
                 "matches a column's name (one row per axis? --id-col, --axis-col, --value-col)",
                 matched);
    return hint;
}

/* Without a header line (layout no_header): the first row (at tr->r) sets the delimiter and the
 * field count, every wanted column is a number. */
static sc_status first_row_as_header(table_reader *tr, sc_error *err)
{
    sc_table *t = tr->t;
    char buf[PREAMBLE_LINE], *field[MAX_TABLE_FIELDS];
    int n = split_copy(tr->r.text, buf, field);
    if (n < 0)
        return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line, "more than %d columns",
                            MAX_TABLE_FIELDS);
    t->delimiter = sc_imp_delimiter_of(tr->r.text);
    tr->n_header = tr->n_named = n;
    tr->notes->header_fields = tr->notes->named_fields = n;
    tr->first_row_line = tr->r.line;
    tr->in_rows = 1;
    for (int k = 0; k < tr->n_cols; ++k) {
        long num = sc_imp_column_number(tr->names[k]);
        if (num < 1)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "without a header line, columns are given by number, not '%s'",
                                tr->names[k]);
        if (num > n)
            return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                                "column %ld asked for, the first row has %d fields", num, n);
        tr->col_of[k] = (int)(num - 1);
    }
    for (int w = 0; tr->lay && w < tr->lay->n_where; ++w) {
        long num = sc_imp_column_number(tr->lay->where_col[w]);
        if (num < 1 || num > n)
            return sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                                "--where %s: without a header line, a column number in 1..%d",
                                tr->lay->where_col[w], n);
        tr->where_of[w] = (int)(num - 1);
    }
    return SC_OK;
}

sc_status sc_imp_begin(const char *path, int n_cols, const char *const *names,
                       const double *scale, long max_rows, const sc_table_layout *lay,
                       sc_table_notes *notes, sc_table *t, sc_error *err)
{
    memset(t, 0, sizeof *t);
    snprintf(t->path, sizeof t->path, "%s", path);
    t->n_cols = n_cols;
    memset(notes, 0, sizeof *notes);
    return sc_imp_check_request(n_cols, names, scale, max_rows, lay, err);
}

/* The request's sizes: 1..16 columns, 1..SC_TABLE_MAX_ROWS rows, every scale finite and nonzero
 * (two per column with a nominal column). */
static sc_status check_sizes(int n_cols, const char *const *names, const double *scale,
                             long max_rows, const sc_table_layout *lay, sc_error *err)
{
    if (n_cols < 1 || n_cols > 16 || !names)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "a table read asks for 1..16 columns, got %d",
                            n_cols);
    if (max_rows < 1 || max_rows > SC_TABLE_MAX_ROWS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "a table read takes 1..%ld rows at most, "
                            "not %ld", SC_TABLE_MAX_ROWS, max_rows);
    int n_scale = lay && lay->nominal_col ? 2 * n_cols : n_cols;
    for (int a = 0; scale && a < n_scale; ++a)
        if (!isfinite(scale[a]) || scale[a] == 0)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "the scale of column '%s' must be finite and nonzero, got %g",
                                names[a % n_cols], scale[a]);
    return SC_OK;
}

/* One column cannot be two quantities: the names asked for are distinct. */
static sc_status check_distinct(int n_cols, const char *const *names, int is_long, sc_error *err)
{
    static const char *const nth[] = {"1st", "2nd", "3rd", "4th"};
    for (int a = 0; a < n_cols; ++a)
        for (int b = 0; b < a; ++b)
            if (sc_imp_name_equal(names[a], names[b]))
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "the %s '%s' is asked for twice (as the %s and the %s "
                                    "quantity)%s", is_long ? "axis" : "column", names[a],
                                    nth[b < 2 ? b : 2], nth[a < 3 ? a : 3],
                                    is_long ? "" : " (one row per axis, X and Y in one column? "
                                    "--id-col, --axis-col, --value-col)");
    return SC_OK;
}

/* The layout's options go together. */
static sc_status check_layout(const sc_table_layout *lay, int is_long, sc_error *err)
{
    if (!lay)
        return SC_OK;
    if (lay->n_where < 0 || lay->n_where > SC_TABLE_MAX_WHERE || lay->n_missing < 0 ||
        lay->n_missing > SC_TABLE_MAX_MISSING)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "at most %d row filters and %d placeholders",
                            SC_TABLE_MAX_WHERE, SC_TABLE_MAX_MISSING);
    if (is_long && (!lay->id_col || !lay->axis_col || !lay->value_col))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "one row per axis needs the id, axis and value columns together");
    if (lay->nominal_col && !is_long)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "a nominal column per row goes with one row per axis");
    if (is_long && lay->transpose)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "one row per axis and items in columns do not go together");
    if (lay->transpose && lay->n_where)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "row filters do not apply to items in columns");
    return SC_OK;
}

sc_status sc_imp_check_request(int n_cols, const char *const *names, const double *scale,
                                long max_rows, const sc_table_layout *lay, sc_error *err)
{
    int is_long = lay && (lay->id_col || lay->axis_col || lay->value_col);
    sc_status st = check_sizes(n_cols, names, scale, max_rows, lay, err);
    if (st == SC_OK)
        st = check_distinct(n_cols, names, is_long, err);
    if (st == SC_OK)
        st = check_layout(lay, is_long, err);
    return st;
}

/* Whether a line starting with '#' is a comment; the first that is the header ("#;X;Y") makes
 * every later "#<digit>" line a row. */
static int hash_comment(table_reader *tr)
{
    const char *text = tr->r.text;
    if (tr->hash_rows ? !isdigit((unsigned char)text[1])
                      : (tr->in_rows || tr->numbers || !hash_header(tr, text)))
        return 1;
    tr->hash_rows = 1;
    tr->r.skip_run = 0; /* a row (or the "#;X;Y" header), not a comment */
    return 0;
}

/* A line after the header: read_data_line, with the run of lines that give no row bounded. */
static sc_status rows_line(table_reader *tr, sc_error *err)
{
    long rows_before = tr->t->n_rows;
    sc_status st = read_data_line(tr, err);
    tr->no_row_run = tr->t->n_rows > rows_before ? 0 : tr->no_row_run + 1;
    if (st == SC_OK && tr->no_row_run > SC_CSV_MAX_SKIP_RUN)
        st = sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line, SC_IMP_NO_ROW_RUN_MSG,
                          SC_CSV_MAX_SKIP_RUN);
    return st;
}

/* Take the kept line before the data (tr->prev) for the header line. */
static sc_status header_from_prev(table_reader *tr, sc_error *err)
{
    char *h = tr->prev;
    tr->prev = NULL;
    sc_status st = read_header_line(tr, h, tr->prev_line, err);
    free(h);
    return st;
}

/* Columns by number: a damaged row (the current line) before the first good one, after the
 * header line kept in tr->prev: the row's error. */
static sc_status damaged_first_row(table_reader *tr, sc_error *err)
{
    sc_status st = header_from_prev(tr, err);
    if (st != SC_OK)
        return st;
    sc_error e;
    sc_error_clear(&e);
    int nf = sc_imp_split_fields(tr->r.text, tr->t->delimiter, tr->field, tr->quoted,
                                 MAX_TABLE_FIELDS);
    st = read_row(tr, nf, &e);
    if (st == SC_OK) /* cannot be: it failed as a row above */
        st = sc_error_set(&e, SC_E_INPUT, tr->path, tr->r.line, "not a row");
    if (err)
        *err = e;
    return st;
}

enum { LINE_NEXT, LINE_STOP }; /* go on with the next line, or stop reading */

/* Columns by number, before the data: the header is the line before the first row. */
static int numbered_line(table_reader *tr, sc_status *st, sc_error *err)
{
    int row = row_by_number(tr, tr->r.text);
    if (row < 0 && tr->prev) { /* a damaged row before the first good one: its error */
        *st = damaged_first_row(tr, err);
        return LINE_STOP;
    }
    if (row < 0) { /* a damaged row with no header before it */
        *st = sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                           "not a row, and no header line before it (columns given by "
                           "number need one, or --no-header)");
        return LINE_STOP;
    }
    if (row == 0) {
        free(tr->prev);
        tr->prev = strdup(tr->r.text);
        tr->prev_line = tr->r.line;
        if (!tr->prev)
            *st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        else if (++tr->preamble > PREAMBLE_MAX + 1)
            return LINE_STOP;
        return LINE_NEXT;
    }
    if (!tr->prev) {
        *st = sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                           "no header line before the first row (columns given by number "
                           "need one, or --no-header)");
        return LINE_STOP;
    }
    *st = header_from_prev(tr, err);
    if (*st == SC_OK)
        *st = read_data_line(tr, err);
    return LINE_NEXT;
}

/* Columns by name, before the data: the line naming them all is the header; else the first
 * line naming some (else the first line) is kept, until the data or too long a preamble. */
static int named_line(table_reader *tr, sc_status *st, sc_error *err)
{
    int named = names_count(tr, tr->r.text);
    if (named == tr->n_cols) {
        *st = read_header_line(tr, tr->r.text, tr->r.line, err);
        return LINE_NEXT;
    }
    if (!tr->first || (named > 0 && !tr->first_named)) {
        free(tr->first);
        tr->first = strdup(tr->r.text);
        tr->first_line = tr->r.line;
        tr->first_named = named > 0;
        if (!tr->first)
            *st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    if (*st == SC_OK && (looks_like_data(tr->r.text) || ++tr->preamble > PREAMBLE_MAX))
        return LINE_STOP; /* no header before the data: the first line's error */
    return LINE_NEXT;
}

/* One line of the file (not blank): *st its status; LINE_STOP where reading ends early. */
static int wide_line(table_reader *tr, sc_imp_conv *conv, sc_status *st, sc_error *err)
{
    if ((*st = sc_imp_conv_line(conv, &tr->r, err)) != SC_OK)
        return LINE_STOP;
    if (tr->r.text[0] == '#' && hash_comment(tr))
        return LINE_NEXT;
    if (!tr->in_rows && tr->no_header) {
        *st = first_row_as_header(tr, err);
        if (*st == SC_OK)
            *st = read_data_line(tr, err);
        return LINE_NEXT;
    }
    if (tr->in_rows) {
        *st = rows_line(tr, err);
        return LINE_NEXT;
    }
    return tr->numbers ? numbered_line(tr, st, err) : named_line(tr, st, err);
}

/* No line named every column: the kept first line read as the header, for its error, with the
 * hint of what the line seems to be. */
static sc_status header_from_first(table_reader *tr, sc_error *err)
{
    char hint[256];
    row_taken_hint(tr, tr->first, hint, sizeof hint);
    int first_is_data = looks_like_data(tr->first); /* before the line is split in place */
    sc_status st = read_header_line(tr, tr->first, tr->first_line, err);
    if (st != SC_OK && hint[0] && err && strstr(err->msg, "no column named")) {
        char *paren = strstr(err->msg, " (delimiter"); /* the hint replaces the details */
        if (paren)
            *paren = '\0';
        append_hint(err, hint);
    } else if (st != SC_OK && err && !hint[0] && first_is_data &&
               strstr(err->msg, "no column named")) {
        append_hint(err, ": this line is a row of numbers (no header line? --no-header "
                         "with the columns by number)");
    }
    return st;
}

/* After the last line (got: the line reader's last answer): the header's error if none was
 * found, the trailing summary rows dropped, and the table checked for rows. */
static sc_status wide_end(table_reader *tr, int got, sc_status st, sc_error *err)
{
    sc_table *t = tr->t;
    if (st == SC_OK && got < 0)
        st = err ? err->code : SC_E_INPUT;
    else if (st == SC_OK && !tr->in_rows && tr->first)
        st = header_from_first(tr, err);
    else if (st == SC_OK && !tr->in_rows)
        st = sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line,
                          "no header line naming the columns");
    if (st == SC_OK && tr->provisional > 0) { /* trailing summary rows: no measurements */
        t->n_rows -= tr->provisional;
        t->n_summary = tr->provisional;
        t->summary_line = tr->provisional_line;
    }
    if (st == SC_OK && !tr->in_rows) /* cannot happen: read_header_line failed or set it */
        st = sc_error_set(err, SC_E_INTERNAL, tr->path, tr->r.line, "no header line");
    else if (st == SC_OK && t->n_rows == 0)
        st = sc_error_set(err, SC_E_INPUT, tr->path, tr->r.line, "no data lines after the %s",
                          t->header_line ? "header" : "filters");
    if (st == SC_OK) /* the decimals were counted as the values came (parse_value) */
        sc_imp_set_decimal(&tr->marks, t, NULL);
    return st;
}

sc_status sc_imp_open(sc_imp_conv *conv, sc_csv *r, sc_table_encoding enc, const char *path,
                      sc_error *err)
{
    sc_status st = sc_imp_conv_open(conv, enc, path, err);
    if (st != SC_OK)
        return st;
    st = sc_csv_open(r, path, err);
    if (st != SC_OK)
        sc_imp_conv_close(conv);
    return st;
}

int sc_imp_next_line(sc_csv *r, sc_imp_conv *conv, sc_status *st, sc_error *err)
{
    int got;
    while ((got = sc_csv_next_line(r, err)) == 1) {
        if (sc_csv_is_blank(r) || r->text[0] == '#')
            continue;
        *st = sc_imp_conv_line(conv, r, err);
        return *st == SC_OK ? 1 : -1;
    }
    if (got < 0)
        *st = err ? err->code : SC_E_INPUT;
    return got;
}

sc_status sc_imp_close(sc_imp_conv *conv, sc_csv *r, sc_table *t, sc_status st)
{
    sc_csv_close(r);
    sc_imp_conv_close(conv);
    if (st != SC_OK)
        sc_table_free(t);
    return st;
}

sc_status sc_imp_read_wide(const char *path, int n_cols, const char *const *names,
                           const double *scale, long max_rows, const sc_table_layout *lay,
                           sc_table_notes *notes, sc_table *t, sc_error *err)
{
    sc_table_notes local_notes;
    if (!notes)
        notes = &local_notes;
    sc_status st = sc_imp_begin(path, n_cols, names, scale, max_rows, lay, notes, t, err);
    if (st != SC_OK)
        return st;
    table_reader tr;
    memset(&tr, 0, sizeof tr);
    tr.t = t;
    tr.path = path;
    tr.n_cols = n_cols;
    tr.names = names;
    tr.scale = scale;
    tr.max_rows = max_rows;
    tr.lay = lay;
    tr.notes = notes;
    tr.numbers = all_by_number(&tr);
    tr.no_header = lay && lay->no_header;
    sc_imp_conv conv;
    st = sc_imp_open(&conv, &tr.r, lay ? lay->encoding : SC_ENC_UTF8, path, err);
    if (st != SC_OK)
        return st;
    int got = 0;
    while (st == SC_OK && (got = sc_csv_next_line(&tr.r, err)) == 1)
        if (!sc_csv_is_blank(&tr.r) && wide_line(&tr, &conv, &st, err) == LINE_STOP)
            break;
    st = wide_end(&tr, got, st, err);
    free(tr.first);
    free(tr.prev);
    return sc_imp_close(&conv, &tr.r, t, st);
}
