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

/* Split line s at delim in place (double-quoted fields may hold the delimiter; the quotes are
 * removed), trimming blanks; returns the field count or -1 if there are too many. */
static int split_fields(char *s, char delim, char **field, int max)
{
    int n = 0;
    char *p = s;
    for (;;) {
        if (n == max)
            return -1;
        while (*p == ' ' || (*p == '\t' && delim != '\t'))
            ++p;
        char *start = p, *end;
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

sc_status sc_table_read(const char *path, int n_cols, const char *const *names,
                        const double *scale, sc_table *t, sc_error *err)
{
    memset(t, 0, sizeof *t);
    snprintf(t->path, sizeof t->path, "%s", path);
    t->n_cols = n_cols;
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    char *field[MAX_TABLE_FIELDS];
    int col_of[16], n_header = 0;
    long cap = 0, mark_line = 0;
    char mark = 0;
    int got;
    if (n_cols < 1 || n_cols > 16) {
        st = sc_error_set(err, SC_E_INTERNAL, NULL, 0, "sc_table_read: 1..16 columns");
        goto done;
    }
    while ((got = sc_csv_next_line(&r, err)) == 1) {
        if (sc_csv_is_blank(&r) || r.text[0] == '#')
            continue;
        if (!t->header_line) {
            t->header_line = r.line;
            t->delimiter = strchr(r.text, '\t') ? '\t' : strchr(r.text, ';') ? ';' : ',';
            n_header = split_fields(r.text, t->delimiter, field, MAX_TABLE_FIELDS);
            if (n_header < 0) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, "more than %d columns",
                                  MAX_TABLE_FIELDS);
                goto done;
            }
            for (int k = 0; k < n_cols; ++k) {
                col_of[k] = -1;
                for (int f = 0; f < n_header; ++f)
                    if (name_equal(field[f], names[k])) {
                        if (col_of[k] >= 0) {
                            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                              "two columns are named '%s'", names[k]);
                            goto done;
                        }
                        col_of[k] = f;
                    }
                if (col_of[k] < 0) {
                    st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                      "no column named '%s' in this header line (delimiter '%s')",
                                      names[k], t->delimiter == '\t' ? "tab" : t->delimiter == ';' ? ";" : ",");
                    goto done;
                }
            }
            continue;
        }
        int nf = split_fields(r.text, t->delimiter, field, MAX_TABLE_FIELDS);
        if (nf != n_header) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "%d fields, the header line (line %ld) has %d%s", nf < 0 ? MAX_TABLE_FIELDS : nf,
                              t->header_line, n_header,
                              t->delimiter == ',' ? " (decimal commas need ';' or tab as delimiter)" : "");
            goto done;
        }
        if (t->n_rows == cap) {
            long ncap = cap ? 2 * cap : 1024;
            double *nv = realloc(t->value, (size_t)ncap * (size_t)n_cols * sizeof(double));
            if (nv)
                t->value = nv;
            long *nl = nv ? realloc(t->line, (size_t)ncap * sizeof(long)) : NULL;
            if (!nv || !nl) {
                st = sc_error_set(err, SC_E_NOMEM, path, r.line, "out of memory (%ld rows)", ncap);
                goto done;
            }
            t->line = nl;
            cap = ncap;
        }
        for (int k = 0; k < n_cols; ++k) {
            const char *s = field[col_of[k]];
            double v;
            char seen = 0;
            int rc = parse_number(s, &v, &seen);
            if (rc == -2) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                  "column '%s': '%s' has both '.' and ',' (no thousands separators, please)",
                                  names[k], s);
                goto done;
            }
            if (rc != 0) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line, "column '%s': '%s' is not a number",
                                  names[k], s);
                goto done;
            }
            if (seen == ',' && t->delimiter == ',') {
                st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                  "column '%s': decimal comma in a comma-separated file", names[k]);
                goto done;
            }
            if (seen && mark && seen != mark) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                  "column '%s': decimal '%c' here but '%c' on line %ld (mixed decimal marks)",
                                  names[k], seen, mark, mark_line);
                goto done;
            }
            if (seen && !mark) {
                mark = seen;
                mark_line = r.line;
            }
            if (!(fabs(v) <= SC_INPUT_MAX_ABS)) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                  "column '%s': %s is beyond any plausible measurement", names[k], s);
                goto done;
            }
            t->value[t->n_rows * n_cols + k] = v * (scale ? scale[k] : 1.0);
        }
        t->line[t->n_rows++] = r.line;
    }
    if (got < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto done;
    }
    if (!t->header_line) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line, "no header line naming the columns");
        goto done;
    }
    if (t->n_rows == 0) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line, "no data lines after the header");
        goto done;
    }
    t->decimal = mark ? mark : '.';
done:
    sc_csv_close(&r);
    if (st != SC_OK)
        sc_table_free(t);
    return st;
}
