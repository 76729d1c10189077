/* The DABAM mirror profiles (a .dat file of two columns, abscissa and slope or height, with its
 * .txt metadata, a flat JSON object: FILE_HEADER_LINES, X1_FACTOR, Y1_FACTOR, PLOT_TITLE_Y1 or
 * FILE_FORMAT): the reader, strict as every reader of io/. What becomes of the points (heights on
 * the scan of a simulated measurement) is profile/profile_sim.c's. */
#include "dabam_internal.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"
#include "../common/csv_internal.h"

/* The value text of "key" in a flat JSON object (NULL if absent); copies at most len-1 chars. */
static int json_value(const char *json, const char *key, char *out, size_t len)
{
    char pat[96];
    snprintf(pat, sizeof pat, "\"%s\"", key);
    const char *p = strstr(json, pat);
    if (!p)
        return 0;
    p += strlen(pat);
    while (isspace((unsigned char)*p))
        ++p;
    if (*p != ':')
        return 0;
    ++p;
    while (isspace((unsigned char)*p))
        ++p;
    size_t k = 0;
    if (*p == '"') {
        ++p;
        while (*p && *p != '"' && k + 1 < len)
            out[k++] = *p++;
    } else {
        while (*p && *p != ',' && *p != '}' && !isspace((unsigned char)*p) && k + 1 < len)
            out[k++] = *p++;
    }
    out[k] = '\0';
    return 1;
}

static char *read_all(const char *path, sc_error *err)
{
    FILE *f = sc_open_input(path, err);
    if (!f)
        return NULL;
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    size_t got;
    while (buf && (got = fread(buf + len, 1, cap - len - 1, f)) > 0) {
        len += got;
        if (len + 1 == cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                buf = NULL;
                break;
            }
            buf = nb;
            cap *= 2;
        }
    }
    fclose(f);
    if (!buf) {
        sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
        return NULL;
    }
    buf[len] = '\0';
    return buf;
}

/* What the DABAM metadata (.txt, JSON) says about the .dat file. */
typedef struct {
    long header_lines;
    double x_factor; /* metres per abscissa unit */
    double y_factor; /* radians (slopes) or metres (heights) per ordinate unit */
    int is_slope;
} dabam_meta;

/* Slopes or heights: PLOT_TITLE_Y1 says, else FILE_FORMAT (1 = slopes, 2 = heights). */
static int dabam_is_slope(const char *meta)
{
    char title[128] = "", v[128];
    if (json_value(meta, "PLOT_TITLE_Y1", title, sizeof title)) {
        char low[128];
        size_t k = 0;
        for (; title[k] && k + 1 < sizeof low; ++k)
            low[k] = (char)tolower((unsigned char)title[k]);
        low[k] = '\0';
        if (strstr(low, "slope"))
            return 1;
        if (strstr(low, "height") || strstr(low, "heigth"))
            return 0;
        return 1;
    }
    if (json_value(meta, "FILE_FORMAT", v, sizeof v))
        return strcmp(v, "2") != 0;
    return 1;
}

static sc_status dabam_read_meta(const char *meta_path, dabam_meta *m, sc_error *err)
{
    char *meta = read_all(meta_path, err);
    if (!meta)
        return err ? err->code : SC_E_INPUT;
    char v[128];
    sc_status st = SC_OK;
    m->x_factor = 1e-3;
    m->y_factor = 1.0;
    if (!json_value(meta, "FILE_HEADER_LINES", v, sizeof v) ||
        sscanf(v, "%ld", &m->header_lines) != 1 || m->header_lines < 0) {
        st = sc_error_set(err, SC_E_INPUT, meta_path, 0, "no valid FILE_HEADER_LINES");
    } else if (!json_value(meta, "X1_FACTOR", v, sizeof v) ||
               sc_parse_double(v, &m->x_factor) != 0 ||
               !json_value(meta, "Y1_FACTOR", v, sizeof v) ||
               sc_parse_double(v, &m->y_factor) != 0) {
        st = sc_error_set(err, SC_E_INPUT, meta_path, 0, "no valid X1_FACTOR / Y1_FACTOR");
    } else if (!(m->x_factor > 0 && m->x_factor <= 1) ||
               !(m->y_factor != 0 && fabs(m->y_factor) <= 1)) {
        /* DABAM uses 1e-3 and 1e-6; beyond 1 a mirror would be longer than a kilometre or its
         * slopes beyond 1 rad, and the heights could overflow (a fuzzed X1_FACTOR = 1e306
         * made them NaN) */
        st = sc_error_set(err, SC_E_INPUT, meta_path, 0,
                          "X1_FACTOR must be in (0, 1] and Y1_FACTOR nonzero within [-1, 1]");
    } else {
        m->is_slope = dabam_is_slope(meta);
    }
    free(meta);
    return st;
}

void sc_dabam_points_free(sc_dabam_points *d)
{
    free(d->xs);
    free(d->ys);
}

static sc_status dabam_points_push(sc_dabam_points *d, double x, double y)
{
    if (d->count == d->cap) {
        size_t cap = d->cap ? 2 * d->cap : 1024;
        double *nx = realloc(d->xs, cap * sizeof(double));
        if (nx)
            d->xs = nx;
        double *ny = realloc(d->ys, cap * sizeof(double));
        if (ny)
            d->ys = ny;
        if (!nx || !ny)
            return SC_E_NOMEM;
        d->cap = cap;
    }
    d->xs[d->count] = x;
    d->ys[d->count] = y;
    d->count++;
    return SC_OK;
}

/* One data line (past the header): blank and '#' lines are skipped, else two numbers. */
static sc_status dabam_data_line(const char *path, long ln, const char *line, const dabam_meta *m,
                                 sc_dabam_points *d, sc_error *err)
{
    const char *p = line;
    while (isspace((unsigned char)*p))
        ++p;
    if (!*p || *p == '#')
        return SC_OK;
    char *e1, *e2;
    double a = strtod(p, &e1);
    double b = strtod(e1, &e2);
    if (e1 == p || e2 == e1 || !isfinite(a) || !isfinite(b))
        return sc_error_set(err, SC_E_INPUT, path, ln, "expected two numbers (abscissa, ordinate)");
    if (!(fabs(a * m->x_factor) <= 1e3 && fabs(b * m->y_factor) <= 1))
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "beyond any mirror (|x| > 1 km, or a slope or height beyond 1 rad "
                            "or 1 m)");
    if (dabam_points_push(d, a * m->x_factor, b * m->y_factor) != SC_OK)
        return sc_error_set(err, SC_E_NOMEM, path, ln, "out of memory");
    if (d->count > 1 && !(d->xs[d->count - 1] > d->xs[d->count - 2]))
        return sc_error_set(err, SC_E_INPUT, path, ln, "abscissa not increasing");
    return SC_OK;
}

#define SC_DABAM_MAX_HEADER_LINES 1000000L /* FILE_HEADER_LINES beyond this: not DABAM */

static sc_status dabam_read_points(const char *path, const dabam_meta *m, sc_dabam_points *d,
                                   sc_error *err)
{
    FILE *fp = sc_open_input(path, err);
    if (!fp)
        return err ? err->code : SC_E_INPUT;
    char line[4096];
    long ln = 0, skipped = 0; /* comment or blank lines in a row */
    sc_status st = SC_OK;
    while (st == SC_OK && fgets(line, sizeof line, fp)) {
        ++ln;
        skipped = sc_csv_text_skippable(line) ? skipped + 1 : 0;
        if (!strchr(line, '\n') && !feof(fp))
            st = sc_error_set(err, SC_E_INPUT, path, ln, "line longer than %zu bytes",
                              sizeof line - 2);
        else if (skipped > SC_CSV_MAX_SKIP_RUN) /* an endless input, as the CSV reader says */
            st = sc_error_set(err, SC_E_INPUT, path, ln, SC_CSV_SKIP_RUN_MSG, SC_CSV_MAX_SKIP_RUN);
        else if (ln > m->header_lines)
            st = dabam_data_line(path, ln, line, m, d, err);
        else if (ln > SC_DABAM_MAX_HEADER_LINES)
            st = sc_error_set(err, SC_E_INPUT, path, ln, "more header lines than any DABAM file");
    }
    fclose(fp);
    if (st == SC_OK && d->count < 4)
        st = sc_error_set(err, SC_E_INPUT, path, ln, "fewer than 4 points");
    return st;
}

sc_status sc_dabam_read(const char *dat_path, sc_dabam_points *d, sc_error *err)
{
    memset(d, 0, sizeof *d);
    char meta_path[4096];
    size_t L = strlen(dat_path);
    if (L < 4 || strcmp(dat_path + L - 4, ".dat") != 0 || L >= sizeof meta_path)
        return sc_error_set(err, SC_E_INPUT, dat_path, 0,
                            "a DABAM profile is a .dat file (with its .txt metadata)");
    /* the file the caller named first: a missing .dat is reported as such, not as its .txt */
    FILE *probe = fopen(dat_path, "rb");
    if (!probe) {
        int e = errno;
        sc_error_set(err, sc_open_failure_status(e), dat_path, 0, "cannot open: %s", strerror(e));
        if (err)
            err->sys_errno = e;
        return sc_open_failure_status(e);
    }
    fclose(probe);
    memcpy(meta_path, dat_path, L - 4);
    strcpy(meta_path + L - 4, ".txt");
    dabam_meta m;
    sc_status st = dabam_read_meta(meta_path, &m, err);
    if (st != SC_OK)
        return st;
    st = dabam_read_points(dat_path, &m, d, err);
    if (st != SC_OK) {
        sc_dabam_points_free(d);
        memset(d, 0, sizeof *d);
        return st;
    }
    d->is_slope = m.is_slope;
    return SC_OK;
}
