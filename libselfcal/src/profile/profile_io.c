/* The `selfcal-profile v1` input file (SPEC §2), read strictly and written exactly, and the
 * profile output file `n,x_mm,f_um,uf_um,ey_um`. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/number.h"
#include "selfcal/profile.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"

/* Upper bound on N, so that a typo cannot ask for terabytes. */
#define SC_PROFILE_MAX_N 100000000
/* The shortest data row a valid file can have: "1,0,0,0,0\n". */
#define SC_PROFILE_MIN_ROW_BYTES 10

sc_status sc_profile_data_init(sc_profile_data *d, int n, double s_mm, int d1, int d2,
                               sc_error *err)
{
    memset(d, 0, sizeof *d);
    if (n < 2 || n > SC_PROFILE_MAX_N)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "N = %d is out of range (2..%d)", n,
                            SC_PROFILE_MAX_N);
    if (!(s_mm > 0) || !isfinite(s_mm))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "s_mm must be positive");
    if (d1 < 1 || d2 < 1 || d1 >= n || d2 >= n)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "sensor spacings d1 = %d, d2 = %d must be in 1..N-1 (N = %d)", d1, d2,
                            n);
    d->n = n;
    d->s_mm = s_mm;
    d->d[0] = d1;
    d->d[1] = d2;
    for (int k = 0; k < 2; ++k) {
        size_t m = (size_t)(n - d->d[k]);
        d->m1_um[k] = calloc(m, sizeof(double));
        d->m2_um[k] = calloc(m, sizeof(double));
        d->m3_urad[k] = calloc(m, sizeof(double));
        if (!d->m1_um[k] || !d->m2_um[k] || !d->m3_urad[k]) {
            sc_profile_data_free(d);
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
        }
    }
    return SC_OK;
}

void sc_profile_data_free(sc_profile_data *d)
{
    if (!d)
        return;
    for (int k = 0; k < 2; ++k) {
        free(d->m1_um[k]);
        free(d->m2_um[k]);
        free(d->m3_urad[k]);
        d->m1_um[k] = d->m2_um[k] = d->m3_urad[k] = NULL;
    }
}

/* "# scan K: d=V" -> 1 and K, V; 0 if the line is not a scan line; -1 if malformed. */
static int parse_scan_line(const char *line, long *k, long *dv)
{
    const char *p = line;
    if (*p++ != '#')
        return 0;
    while (*p == ' ' || *p == '\t')
        ++p;
    if (strncmp(p, "scan", 4) != 0 || !(p[4] == ' ' || p[4] == '\t'))
        return 0;
    p += 4;
    char *end;
    while (*p == ' ' || *p == '\t')
        ++p;
    if (!isdigit((unsigned char)*p))
        return -1;
    *k = strtol(p, &end, 10);
    p = end;
    while (*p == ' ' || *p == '\t')
        ++p;
    if (*p++ != ':')
        return -1;
    while (*p == ' ' || *p == '\t')
        ++p;
    if (strncmp(p, "d", 1) != 0)
        return -1;
    ++p;
    while (*p == ' ' || *p == '\t')
        ++p;
    if (*p++ != '=')
        return -1;
    while (*p == ' ' || *p == '\t')
        ++p;
    if (!isdigit((unsigned char)*p) && *p != '-' && *p != '+')
        return -1;
    *dv = strtol(p, &end, 10);
    p = end;
    while (*p == ' ' || *p == '\t')
        ++p;
    return *p ? -1 : 1;
}

static int is_blank_str(const char *s)
{
    for (; *s; ++s)
        if (!isspace((unsigned char)*s))
            return 0;
    return 1;
}

sc_status sc_profile_read(const char *path, sc_profile_data *out, sc_error *err)
{
    memset(out, 0, sizeof *out);
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    const char *P = r.path;
    long n_val = -1, d_val[2] = {-1, -1};
    double s_val = NAN;
    long line_s = 0, line_n = 0, line_scan[2] = {0, 0}, line_hdr = 0;
    int have_sd = 0, have_sa = 0;
    double sd = 0, sa = 0;
    int rc;
    /* line numbers of the rows, per scan and n, to report duplicates and gaps */
    long *row_line[2] = {NULL, NULL};
    sc_profile_data d;
    memset(&d, 0, sizeof d);
    int data_ready = 0;

    rc = sc_csv_next_line(&r, err);
    if (rc <= 0) {
        sc_csv_close(&r);
        if (rc == 0)
            return sc_error_set(err, SC_E_INPUT, P, 1, "empty file (expected '# selfcal-profile v1')");
        return err ? err->code : SC_E_INPUT;
    }
    {
        char *t = r.text;
        while (*t == ' ' || *t == '\t')
            ++t;
        char buf[64];
        snprintf(buf, sizeof buf, "%s", t);
        for (char *e = buf + strlen(buf); e > buf && isspace((unsigned char)e[-1]); --e)
            e[-1] = '\0';
        if (strcmp(buf, "# selfcal-profile v1") != 0) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line,
                              "not a selfcal-profile v1 file (first line must be '# selfcal-profile v1')");
            goto fail;
        }
    }
    /* header */
    while ((rc = sc_csv_next_line(&r, err)) == 1) {
        if (sc_csv_is_blank(&r))
            continue;
        if (r.text[0] != '#')
            break;
        long k, dv;
        int sl = parse_scan_line(r.text, &k, &dv);
        if (sl < 0) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "malformed scan line (expected '# scan K: d=D')");
            goto fail;
        }
        if (sl == 1) {
            if (k != 1 && k != 2) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "scan %ld: only scans 1 and 2 exist", k);
                goto fail;
            }
            if (line_scan[k - 1]) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "scan %ld declared twice (first at line %ld)",
                                  k, line_scan[k - 1]);
                goto fail;
            }
            if (dv < 1) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "scan %ld: spacing d = %ld must be >= 1", k, dv);
                goto fail;
            }
            d_val[k - 1] = dv;
            line_scan[k - 1] = r.line;
            continue;
        }
        char key[64], *val;
        if (!sc_header_kv(r.text, key, sizeof key, &val))
            continue; /* a free comment */
        double *dst = NULL;
        long *lp = NULL;
        if (!strcmp(key, "N")) {
            long v;
            if (line_n) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "N given twice");
                goto fail;
            }
            if (sc_parse_long(val, &v) != 0) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "N: '%s' is not a whole number", val);
                goto fail;
            }
            if (v < 3 || v > SC_PROFILE_MAX_N) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "N = %ld is out of range (3..%d)", v,
                                  SC_PROFILE_MAX_N);
                goto fail;
            }
            n_val = v;
            line_n = r.line;
            continue;
        } else if (!strcmp(key, "s_mm")) {
            dst = &s_val;
            lp = &line_s;
        } else if (!strcmp(key, "sigma_disp_um")) {
            if (have_sd) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "sigma_disp_um given twice");
                goto fail;
            }
            dst = &sd;
            have_sd = 1;
        } else if (!strcmp(key, "sigma_angle_urad")) {
            if (have_sa) {
                st = sc_error_set(err, SC_E_INPUT, P, r.line, "sigma_angle_urad given twice");
                goto fail;
            }
            dst = &sa;
            have_sa = 1;
        } else {
            continue; /* other keys: extensions, ignored */
        }
        if (lp && *lp) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "%s given twice", key);
            goto fail;
        }
        if (sc_parse_double(val, dst) != 0) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "%s: '%s' is not a number", key, val);
            goto fail;
        }
        if (lp)
            *lp = r.line;
        if (dst == &s_val ? !(s_val > 0) : !(*dst >= 0)) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "%s = %s must be %s", key, val,
                              dst == &s_val ? "positive" : "non-negative");
            goto fail;
        }
        if (*dst > SC_INPUT_MAX_ABS) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "%s = %s is beyond any real set-up", key,
                              val);
            goto fail;
        }
    }
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    if (rc == 0) {
        st = sc_error_set(err, SC_E_INPUT, P, r.line, "no column header 'scan,n,m1_um,m2_um,m3_urad'");
        goto fail;
    }
    line_hdr = r.line;
    if (!line_n) {
        st = sc_error_set(err, SC_E_INPUT, P, line_hdr, "header line '# N = ...' missing");
        goto fail;
    }
    if (!line_s) {
        st = sc_error_set(err, SC_E_INPUT, P, line_hdr, "header line '# s_mm = ...' missing");
        goto fail;
    }
    for (int k = 0; k < 2; ++k) {
        if (!line_scan[k]) {
            st = sc_error_set(err, SC_E_INPUT, P, line_hdr,
                              "scan %d missing: header line '# scan %d: d=...' not found", k + 1, k + 1);
            goto fail;
        }
        if (d_val[k] >= n_val) {
            st = sc_error_set(err, SC_E_INPUT, P, line_n,
                              "N too small: scan %d spacing d = %ld leaves no sample (N = %ld)", k + 1,
                              d_val[k], n_val);
            goto fail;
        }
    }
    /* Memory follows what the file can hold, not what its header claims: a valid file has a row
     * of at least SC_PROFILE_MIN_ROW_BYTES ("1,0,0,0,0\n") for each of the 2N - d1 - d2 samples,
     * so a regular file of S bytes cannot need N beyond about S / 20 (a pipe is read up to
     * SC_PROFILE_MAX_N). */
    {
        struct stat sb;
        long long rows = 2 * (long long)n_val - d_val[0] - d_val[1];
        if (fstat(fileno(r.fp), &sb) == 0 && S_ISREG(sb.st_mode) &&
            rows * SC_PROFILE_MIN_ROW_BYTES > (long long)sb.st_size) {
            st = sc_error_set(err, SC_E_INPUT, P, line_n,
                              "N = %ld needs %lld data rows, more than this %lld-byte file can hold",
                              n_val, rows, (long long)sb.st_size);
            goto fail;
        }
    }
    /* column header */
    {
        int nf = sc_csv_split(&r, err);
        static const char *names[5] = {"scan", "n", "m1_um", "m2_um", "m3_urad"};
        if (nf < 0) {
            st = err ? err->code : SC_E_INPUT;
            goto fail;
        }
        int ok = nf >= 5;
        for (int c = 0; ok && c < 5; ++c)
            ok = !strcmp(r.field[c], names[c]);
        if (!ok) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line,
                              "expected the column header 'scan,n,m1_um,m2_um,m3_urad'");
            goto fail;
        }
    }
    st = sc_profile_data_init(&d, (int)n_val, s_val, (int)d_val[0], (int)d_val[1], err);
    if (st != SC_OK) {
        if (err)
            snprintf(err->file, sizeof err->file, "%s", P), err->line = line_n;
        goto fail;
    }
    data_ready = 1;
    for (int k = 0; k < 2; ++k) {
        row_line[k] = calloc((size_t)(n_val - d_val[k]), sizeof(long));
        if (!row_line[k]) {
            st = sc_error_set(err, SC_E_NOMEM, P, 0, "out of memory");
            goto fail;
        }
    }
    long nrows = 0;
    while ((rc = sc_csv_next_line(&r, err)) == 1) {
        if (sc_csv_is_blank(&r))
            continue;
        if (r.text[0] == '#')
            continue;
        int nf = sc_csv_split(&r, err);
        if (nf < 0) {
            st = err ? err->code : SC_E_INPUT;
            goto fail;
        }
        if (nf < 5) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "expected 5 fields (scan,n,m1_um,m2_um,m3_urad), got %d", nf);
            goto fail;
        }
        long k, idx;
        double v1, v2, v3;
        if ((st = sc_csv_long(&r, 0, "scan", &k, err)) != SC_OK ||
            (st = sc_csv_long(&r, 1, "n", &idx, err)) != SC_OK ||
            (st = sc_csv_double(&r, 2, "m1_um", &v1, err)) != SC_OK ||
            (st = sc_csv_double(&r, 3, "m2_um", &v2, err)) != SC_OK ||
            (st = sc_csv_double(&r, 4, "m3_urad", &v3, err)) != SC_OK)
            goto fail;
        if (!(fabs(v1) <= SC_INPUT_MAX_ABS && fabs(v2) <= SC_INPUT_MAX_ABS &&
              fabs(v3) <= SC_INPUT_MAX_ABS)) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line,
                              "a reading beyond 1 m (m1_um, m2_um) or 1 rad (m3_urad) is not a "
                              "sensor reading");
            goto fail;
        }
        if (k != 1 && k != 2) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "scan %ld: only scans 1 and 2 exist", k);
            goto fail;
        }
        long m = n_val - d_val[k - 1];
        if (idx < 0 || idx >= m) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line,
                              "n = %ld out of range for scan %ld (0..%ld: N - d = %ld samples)", idx, k,
                              m - 1, m);
            goto fail;
        }
        if (row_line[k - 1][idx]) {
            st = sc_error_set(err, SC_E_INPUT, P, r.line, "duplicate sample: scan %ld, n = %ld (first at line %ld)",
                              k, idx, row_line[k - 1][idx]);
            goto fail;
        }
        row_line[k - 1][idx] = r.line;
        d.m1_um[k - 1][idx] = v1;
        d.m2_um[k - 1][idx] = v2;
        d.m3_urad[k - 1][idx] = v3;
        ++nrows;
    }
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    long last_line = r.line;
    for (int k = 0; k < 2; ++k) {
        long m = n_val - d_val[k], present = 0;
        for (long i = 0; i < m; ++i)
            present += row_line[k][i] != 0;
        if (present == 0) {
            st = sc_error_set(err, SC_E_INPUT, P, line_scan[k], "scan %d missing: no data rows", k + 1);
            goto fail;
        }
        for (long i = 0; i < m; ++i) {
            if (row_line[k][i])
                continue;
            /* a gap: report it at the first row of this scan after it (or the end of the file) */
            long at = 0;
            for (long j = i + 1; j < m && !at; ++j)
                at = row_line[k][j];
            long j = i;
            while (j < m && !row_line[k][j])
                ++j;
            st = sc_error_set(err, SC_E_INPUT, P, at ? at : last_line,
                              "gap in scan %d: no sample for n = %ld%s%ld (scan %d needs n = 0..%ld)", k + 1,
                              i, j - 1 > i ? "..": "", j - 1 > i ? j - 1 : i, k + 1, m - 1);
            if (j - 1 <= i && err) /* a single missing n: drop the "..i" suffix */
                snprintf(err->msg, sizeof err->msg, "gap in scan %d: no sample for n = %ld (scan %d needs n = 0..%ld)",
                         k + 1, i, k + 1, m - 1);
            goto fail;
        }
    }
    (void)nrows;
    (void)is_blank_str;
    d.has_sigma_disp = have_sd;
    d.has_sigma_angle = have_sa;
    d.sigma_disp_um = sd;
    d.sigma_angle_urad = sa;
    d.line_n = line_n;
    d.line_scan[0] = line_scan[0];
    d.line_scan[1] = line_scan[1];
    snprintf(d.path, sizeof d.path, "%s", P);
    free(row_line[0]);
    free(row_line[1]);
    sc_csv_close(&r);
    *out = d;
    return SC_OK;
fail:
    free(row_line[0]);
    free(row_line[1]);
    if (data_ready)
        sc_profile_data_free(&d);
    sc_csv_close(&r);
    return st;
}

sc_status sc_profile_check_method(const sc_profile_data *d, sc_profile_method method,
                                  sc_error *err)
{
    sc_error e;
    sc_error_clear(&e);
    int ok = method == SC_PROFILE_DFT ? sc_profile_dft_usable(d->n, d->d[0], d->d[1], &e)
                                      : sc_profile_lsq_solvable(d->n, d->d[0], d->d[1], &e);
    if (ok)
        return SC_OK;
    /* point at the header line the condition is about: the scan lines for the spacings, the N
     * line for the length */
    long line = d->line_scan[1] ? d->line_scan[1] : d->line_n;
    if (strstr(e.msg, "N ") == e.msg || strstr(e.msg, "too small") || strstr(e.msg, "multiple"))
        line = d->line_n ? d->line_n : line;
    return sc_error_set(err, e.code == SC_OK ? SC_E_INPUT : e.code, d->path[0] ? d->path : NULL,
                        line, "%s method: %s", method == SC_PROFILE_DFT ? "dft" : "lsq", e.msg);
}

/* Append v's shortest round-trip text (selfcal/number.h), then sep unless it is 0. */
static char *put_number(char *p, double v, char sep)
{
    p += sc_number_format(v, p);
    if (sep)
        *p++ = sep;
    return p;
}

/* Append a whole number in decimal, then sep. */
static char *put_long(char *p, long v, char sep)
{
    char tmp[24];
    int k = 0;
    unsigned long u = v < 0 ? 0UL - (unsigned long)v : (unsigned long)v;
    do
        tmp[k++] = (char)('0' + u % 10);
    while ((u /= 10) > 0);
    if (v < 0)
        *p++ = '-';
    while (k > 0)
        *p++ = tmp[--k];
    *p++ = sep;
    return p;
}

sc_status sc_profile_write(const char *path, const sc_profile_data *d, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    fprintf(f.fp, "# selfcal-profile v1\n# N = %d\n# s_mm = %.17g\n# scan 1: d=%d\n# scan 2: d=%d\n",
            d->n, d->s_mm, d->d[0], d->d[1]);
    if (d->has_sigma_disp)
        fprintf(f.fp, "# sigma_disp_um = %.17g\n", d->sigma_disp_um);
    if (d->has_sigma_angle)
        fprintf(f.fp, "# sigma_angle_urad = %.17g\n", d->sigma_angle_urad);
    fprintf(f.fp, "scan,n,m1_um,m2_um,m3_urad\n");
    for (int k = 0; k < 2; ++k)
        for (int i = 0; i < d->n - d->d[k]; ++i) {
            char line[8 + 3 * SC_NUMBER_BUF + 16], *p = line;
            p = put_long(p, k + 1, ',');
            p = put_long(p, i, ',');
            p = put_number(p, d->m1_um[k][i], ',');
            p = put_number(p, d->m2_um[k][i], ',');
            p = put_number(p, d->m3_urad[k][i], '\n');
            fwrite(line, 1, (size_t)(p - line), f.fp);
        }
    if (ferror(f.fp)) {
        sc_afile_abort(&f);
        return sc_error_set(err, SC_E_IO, path, 0, "write failed");
    }
    return sc_afile_commit(&f, err);
}

sc_status sc_profile_write_result(const char *path, int n, double s_mm, const double *f_um,
                                  const double *uf_um, const double *ey_um, int n_ey,
                                  sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    fprintf(f.fp, "n,x_mm,f_um,uf_um,ey_um\n");
    for (int i = 0; i < n; ++i) {
        char line[24 + 4 * SC_NUMBER_BUF], *p = line;
        p = put_long(p, i, ',');
        p = put_number(p, i * s_mm, ',');
        p = put_number(p, f_um[i], ',');
        if (uf_um)
            p = put_number(p, uf_um[i], 0);
        *p++ = ',';
        if (ey_um && i < n_ey)
            p = put_number(p, ey_um[i], 0);
        *p++ = '\n';
        fwrite(line, 1, (size_t)(p - line), f.fp);
    }
    if (ferror(f.fp)) {
        sc_afile_abort(&f);
        return sc_error_set(err, SC_E_IO, path, 0, "write failed");
    }
    return sc_afile_commit(&f, err);
}

void sc_profile_result_free(sc_profile_result *r)
{
    if (!r)
        return;
    free(r->x_mm);
    free(r->f_um);
    free(r->uf_um);
    free(r->ey_um);
    memset(r, 0, sizeof *r);
}

sc_status sc_profile_read_result(const char *path, sc_profile_result *out, sc_error *err)
{
    memset(out, 0, sizeof *out);
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    int rc, col[5] = {-1, -1, -1, -1, -1}, ncol = 0;
    static const char *names[5] = {"n", "x_mm", "f_um", "uf_um", "ey_um"};
    size_t cap = 0;
    int count = 0;
    sc_profile_result res;
    memset(&res, 0, sizeof res);
    while ((rc = sc_csv_next_line(&r, err)) == 1) {
        if (sc_csv_is_blank(&r) || r.text[0] == '#')
            continue;
        int nf = sc_csv_split(&r, err);
        if (nf < 0) {
            st = err ? err->code : SC_E_INPUT;
            goto fail;
        }
        if (!ncol) {
            for (int c = 0; c < nf; ++c)
                for (int j = 0; j < 5; ++j)
                    if (!strcmp(r.field[c], names[j]))
                        col[j] = c;
            if (col[0] < 0 || col[1] < 0 || col[2] < 0) {
                st = sc_error_set(err, SC_E_INPUT, r.path, r.line,
                                  "expected a header naming the columns n, x_mm and f_um");
                goto fail;
            }
            ncol = nf;
            continue;
        }
        if (nf != ncol) {
            st = sc_error_set(err, SC_E_INPUT, r.path, r.line, "expected %d fields, got %d", ncol, nf);
            goto fail;
        }
        long idx;
        if ((st = sc_csv_long(&r, col[0], "n", &idx, err)) != SC_OK)
            goto fail;
        if (idx != count) {
            st = sc_error_set(err, SC_E_INPUT, r.path, r.line, "expected n = %d, got %ld", count, idx);
            goto fail;
        }
        if ((size_t)count == cap) {
            cap = cap ? 2 * cap : 1024;
            double *a[4];
            double **fld[4] = {&res.x_mm, &res.f_um, &res.uf_um, &res.ey_um};
            for (int j = 0; j < 4; ++j) {
                a[j] = realloc(*fld[j], cap * sizeof(double));
                if (!a[j]) {
                    st = sc_error_set(err, SC_E_NOMEM, r.path, r.line, "out of memory");
                    goto fail;
                }
                *fld[j] = a[j];
            }
        }
        double *dst[4] = {res.x_mm, res.f_um, res.uf_um, res.ey_um};
        for (int j = 1; j < 5; ++j) {
            double v = NAN;
            if (col[j] >= 0 && !is_blank_str(r.field[col[j]]))
                if ((st = sc_csv_double(&r, col[j], names[j], &v, err)) != SC_OK)
                    goto fail;
            if (!(fabs(v) <= SC_INPUT_MAX_ABS) && !isnan(v)) {
                st = sc_error_set(err, SC_E_INPUT, r.path, r.line,
                                  "%s = %g is beyond 1 m (or 1 km for x_mm)", names[j], v);
                goto fail;
            }
            dst[j - 1][count] = v;
        }
        ++count;
    }
    if (rc < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    if (count == 0) {
        st = sc_error_set(err, SC_E_INPUT, r.path, r.line, "no data rows");
        goto fail;
    }
    res.n = count;
    sc_csv_close(&r);
    *out = res;
    return SC_OK;
fail:
    sc_profile_result_free(&res);
    sc_csv_close(&r);
    return st;
}
