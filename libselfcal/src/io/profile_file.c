/* profile_file.c — owns the `selfcal-profile v1` measurement file (SPEC §2): the data type's
 * allocation, the strict reader (header through the declarative parser of common/header.c) and
 * the writer.
 *
 * The reader makes up to two passes. The fast pass (a regular file) keeps one bit per sample
 * instead of each row's line and, when the data rows fill at least SC_PROFILE_PARALLEL_FROM
 * bytes and a second core is there, reads the second half of the rows on a second thread (the
 * rows say their own scan and n, so the halves fill disjoint samples). Anything wrong in it (a
 * bad row, a duplicate, a gap) sends the file to the exact pass: one thread, each row's line
 * kept, every message and line number as they always were (running out of memory is reported as
 * it is). Readers of a pipe make the exact pass only. */
#include "selfcal/profile_file.h"
#include "profile_file_internal.h"

#include <ctype.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/header.h"
#include "selfcal/number.h"
#include "io_internal.h"
#include "../common/big_alloc.h"
#include "../common/csv_internal.h"

/* The shortest data row a valid file can have: "1,0,0,0,0\n". */
#define SC_PROFILE_MIN_ROW_BYTES 10
/* Up to this N (about 3 MB of arrays) a short file is read to its first bad line instead, so
 * its message points at the line that is missing or wrong. */
#define SC_PROFILE_SMALL_N 65536

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
        d->m1_um[k] = sc_big_alloc(m, sizeof(double), 1);
        d->m2_um[k] = sc_big_alloc(m, sizeof(double), 1);
        d->m3_urad[k] = sc_big_alloc(m, sizeof(double), 1);
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

/* ---- reader ---- */

/* The `# key = value` lines, declared once. */
typedef struct profile_header {
    long n;
    double s_mm, sigma_disp_um, sigma_angle_urad;
    double probe_gain[2], angle_scale[2], spacing_u_mm; /* SPEC §2a */
} profile_header;

static const sc_header_key header_keys[] = {
    {"N", SC_HEADER_LONG, offsetof(profile_header, n), 1, 3, SC_PROFILE_MAX_N, 0},
    {"s_mm", SC_HEADER_DOUBLE, offsetof(profile_header, s_mm), 1, 0, SC_INPUT_MAX_ABS,
     SC_HEADER_MIN_EXCLUSIVE},
    {"sigma_disp_um", SC_HEADER_DOUBLE, offsetof(profile_header, sigma_disp_um), 0, 0,
     SC_INPUT_MAX_ABS, 0},
    {"sigma_angle_urad", SC_HEADER_DOUBLE, offsetof(profile_header, sigma_angle_urad), 0, 0,
     SC_INPUT_MAX_ABS, 0},
    /* K, U: K checked > 0 after the header (the range is each number's) */
    {"probe_gain", SC_HEADER_DOUBLE_PAIR, offsetof(profile_header, probe_gain), 0, 0, 1e3, 0},
    {"angle_scale", SC_HEADER_DOUBLE_PAIR, offsetof(profile_header, angle_scale), 0, 0, 1e3, 0},
    {"spacing_u_mm", SC_HEADER_DOUBLE, offsetof(profile_header, spacing_u_mm), 0, 0,
     SC_INPUT_MAX_ABS, 0},
};

typedef struct profile_reader {
    sc_csv csv;
    sc_header hdr;
    profile_header v;
    long d[2], line_scan[2];
    int exact;          /* the exact pass (row_line) or the fast pass (seen) */
    long *row_line[2];  /* exact: per scan and n, the line of the row (0 = not seen) */
    uint64_t *seen[2];  /* fast: per scan, one bit per sample this thread stored */
    long stored[2];     /* rows this thread stored, per scan */
    long long stop_at;  /* fast, first half: the offset of the second half's first line (-1: none) */
    sc_profile_data data;
    struct header_hook *hook; /* told of the header once hook_after rows are stored (or NULL) */
    long hook_after;
} profile_reader;

static void tell_hook(profile_reader *pr);

/* "# scan K: d=V" -> 1 and K, V; 0 if the line is not a scan line; -1 if malformed. */
static int parse_scan_line(const char *line, long *k, long *dv)
{
    const char *p = line + 1;
    char *end;
    p += strspn(p, " \t");
    if (line[0] != '#' || strncmp(p, "scan", 4) != 0 || !(p[4] == ' ' || p[4] == '\t'))
        return 0;
    p += 4;
    p += strspn(p, " \t");
    if (!isdigit((unsigned char)*p))
        return -1;
    *k = strtol(p, &end, 10);
    p = end + strspn(end, " \t");
    if (*p++ != ':')
        return -1;
    p += strspn(p, " \t");
    if (*p++ != 'd')
        return -1;
    p += strspn(p, " \t");
    if (*p++ != '=')
        return -1;
    p += strspn(p, " \t");
    if (!isdigit((unsigned char)*p) && *p != '-' && *p != '+')
        return -1;
    *dv = strtol(p, &end, 10);
    p = end + strspn(end, " \t");
    return *p ? -1 : 1;
}

static sc_status scan_line(profile_reader *pr, long k, long dv, sc_error *err)
{
    const char *P = pr->csv.path;
    long line = pr->csv.line;
    if (k != 1 && k != 2)
        return sc_error_set(err, SC_E_INPUT, P, line, "scan %ld: only scans 1 and 2 exist", k);
    if (pr->line_scan[k - 1])
        return sc_error_set(err, SC_E_INPUT, P, line, "scan %ld declared twice (first at line %ld)",
                            k, pr->line_scan[k - 1]);
    if (dv < 1)
        return sc_error_set(err, SC_E_INPUT, P, line, "scan %ld: spacing d = %ld must be >= 1", k,
                            dv);
    pr->d[k - 1] = dv;
    pr->line_scan[k - 1] = line;
    return SC_OK;
}

/* The first line names the format. */
static sc_status read_magic(profile_reader *pr, sc_error *err)
{
    int rc = sc_csv_next_line(&pr->csv, err);
    if (rc < 0)
        return err ? err->code : SC_E_INPUT;
    if (rc == 0)
        return sc_error_set(err, SC_E_INPUT, pr->csv.path, 1,
                            "empty file (expected '# selfcal-profile v1')");
    char buf[64];
    snprintf(buf, sizeof buf, "%s", pr->csv.text);
    if (strcmp(sc_str_trim(buf), "# selfcal-profile v1") != 0)
        return sc_error_set(err, SC_E_INPUT, pr->csv.path, pr->csv.line,
                            "not a selfcal-profile v1 file (first line must be "
                            "'# selfcal-profile v1')");
    return SC_OK;
}

/* Memory follows what the file can hold, not what its header claims: a valid file has a row of
 * at least SC_PROFILE_MIN_ROW_BYTES ("1,0,0,0,0\n") for at least half of each scan's samples
 * (check_complete), so a regular file of S bytes cannot need N beyond about S / 10 (a pipe is
 * read up to SC_PROFILE_MAX_N). Memory: at most max(what the file can hold, SC_PROFILE_SMALL_N). */
static sc_status check_size(const profile_reader *pr, sc_error *err)
{
    struct stat sb;
    long long rows = (2 * (long long)pr->v.n - pr->d[0] - pr->d[1] + 1) / 2;
    if (pr->v.n > SC_PROFILE_SMALL_N && fstat(fileno(pr->csv.fp), &sb) == 0 &&
        S_ISREG(sb.st_mode) && rows * SC_PROFILE_MIN_ROW_BYTES > (long long)sb.st_size)
        return sc_error_set(err, SC_E_INPUT, pr->csv.path, sc_header_line_of(&pr->hdr, "N"),
                            "N = %ld needs at least %lld data rows (half of each scan), more than "
                            "this %lld-byte file can hold",
                            pr->v.n, rows, (long long)sb.st_size);
    return SC_OK;
}

/* Header lines up to the column header (left as the current line), then the header's checks. */
static sc_status read_header(profile_reader *pr, sc_error *err)
{
    sc_csv *r = &pr->csv;
    sc_status st;
    int rc;
    while ((rc = sc_csv_next_line(r, err)) == 1) {
        if (sc_csv_is_blank(r))
            continue;
        if (r->text[0] != '#')
            break;
        long k, dv;
        int sl = parse_scan_line(r->text, &k, &dv);
        if (sl < 0)
            return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                                "malformed scan line (expected '# scan K: d=D')");
        st = sl ? scan_line(pr, k, dv, err)
                : sc_header_line(&pr->hdr, r->path, r->line, r->text, NULL, err);
        if (st != SC_OK)
            return st; /* other lines: free comments and extensions */
    }
    if (rc < 0)
        return err ? err->code : SC_E_INPUT;
    if (rc == 0)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "no column header 'scan,n,m1_um,m2_um,m3_urad'");
    if ((st = sc_header_finish(&pr->hdr, r->path, r->line, err)) != SC_OK)
        return st;
    static const char *const gain_key[2] = {"probe_gain", "angle_scale"};
    const double *gain[2] = {pr->v.probe_gain, pr->v.angle_scale};
    for (int g = 0; g < 2; ++g)
        if (sc_header_line_of(&pr->hdr, gain_key[g]) && !(gain[g][0] >= 1e-3))
            return sc_error_set(err, SC_E_INPUT, r->path, sc_header_line_of(&pr->hdr, gain_key[g]),
                                "%s = K, U: the factor K must be at least 1e-3 (K = 1: a perfect "
                                "sensor), got %g", gain_key[g], gain[g][0]);
    long line_n = sc_header_line_of(&pr->hdr, "N");
    for (int k = 0; k < 2; ++k) {
        if (!pr->line_scan[k])
            return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                                "scan %d missing: header line '# scan %d: d=...' not found", k + 1,
                                k + 1);
        if (pr->d[k] >= pr->v.n)
            return sc_error_set(err, SC_E_INPUT, r->path, line_n,
                                "N too small: scan %d spacing d = %ld leaves no sample (N = %ld)",
                                k + 1, pr->d[k], pr->v.n);
    }
    return check_size(pr, err);
}

/* The rows' bookkeeping: each row's line (exact pass) or a bit per sample (fast pass). */
static sc_status alloc_row_marks(profile_reader *pr, sc_error *err)
{
    for (int k = 0; k < 2; ++k) {
        size_t m = (size_t)(pr->v.n - pr->d[k]);
        if (pr->exact)
            pr->row_line[k] = sc_big_alloc(m, sizeof(long), 1);
        else
            pr->seen[k] = calloc((m + 63) / 64, sizeof(uint64_t));
        if (pr->exact ? !pr->row_line[k] : !pr->seen[k])
            return sc_error_set(err, SC_E_NOMEM, pr->csv.path, 0, "out of memory");
    }
    return SC_OK;
}

static void free_row_marks(profile_reader *pr)
{
    for (int k = 0; k < 2; ++k) {
        free(pr->row_line[k]);
        free(pr->seen[k]);
        pr->row_line[k] = NULL;
        pr->seen[k] = NULL;
    }
}

/* The column header (current line), then the data set and the row bookkeeping. */
static sc_status start_data(profile_reader *pr, sc_error *err)
{
    static const char *names[5] = {"scan", "n", "m1_um", "m2_um", "m3_urad"};
    sc_csv *r = &pr->csv;
    int nf = sc_csv_split(r, err);
    if (nf < 0)
        return err ? err->code : SC_E_INPUT;
    int ok = nf == 5;
    for (int c = 0; ok && c < 5; ++c)
        ok = !strcmp(r->field[c], names[c]);
    if (!ok)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "expected the column header 'scan,n,m1_um,m2_um,m3_urad' (5 columns, "
                            "got %d)", nf);
    sc_status st = sc_profile_data_init(&pr->data, (int)pr->v.n, pr->v.s_mm, (int)pr->d[0],
                                        (int)pr->d[1], err);
    if (st != SC_OK) {
        if (err)
            snprintf(err->file, sizeof err->file, "%s", r->path),
                err->line = sc_header_line_of(&pr->hdr, "N");
        return st;
    }
    return alloc_row_marks(pr, err);
}

/* Store one data row's values (scan k, sample idx, the three readings) after its checks. */
static sc_status store_row(profile_reader *pr, long k, long idx, const double v[3], sc_error *err)
{
    const sc_csv *r = &pr->csv;
    const char *P = r->path;
    if (!((isnan(v[0]) || fabs(v[0]) <= SC_INPUT_MAX_ABS) &&
          (isnan(v[1]) || fabs(v[1]) <= SC_INPUT_MAX_ABS) &&
          (isnan(v[2]) || fabs(v[2]) <= SC_INPUT_MAX_ABS)))
        return sc_error_set(err, SC_E_INPUT, P, r->line,
                            "a reading beyond 1 m (m1_um, m2_um) or 1 rad (m3_urad) is not a "
                            "sensor reading");
    if (k != 1 && k != 2)
        return sc_error_set(err, SC_E_INPUT, P, r->line, "scan %ld: only scans 1 and 2 exist", k);
    long m = pr->v.n - pr->d[k - 1];
    if (idx < 0 || idx >= m)
        return sc_error_set(err, SC_E_INPUT, P, r->line,
                            "n = %ld out of range for scan %ld (0..%ld: N - d = %ld samples)", idx,
                            k, m - 1, m);
    if (pr->exact) {
        long *seen = &pr->row_line[k - 1][idx];
        if (*seen)
            return sc_error_set(err, SC_E_INPUT, P, r->line,
                                "duplicate sample: scan %ld, n = %ld (first at line %ld)", k, idx,
                                *seen);
        *seen = r->line;
    } else {
        uint64_t *w = &pr->seen[k - 1][idx >> 6], bit = (uint64_t)1 << (idx & 63);
        if (*w & bit) /* the exact pass says where it was first */
            return sc_error_set(err, SC_E_INPUT, P, r->line, "duplicate sample");
        *w |= bit;
    }
    pr->stored[k - 1]++;
    /* Relaxed atomic stores, plain moves: in the fast pass a sample given in both halves (a
     * duplicate, found after both and read again exactly) is written by both threads. */
    double m1 = v[0], m2 = v[1], m3 = v[2];
    __atomic_store(&pr->data.m1_um[k - 1][idx], &m1, __ATOMIC_RELAXED);
    __atomic_store(&pr->data.m2_um[k - 1][idx], &m2, __ATOMIC_RELAXED);
    __atomic_store(&pr->data.m3_urad[k - 1][idx], &m3, __ATOMIC_RELAXED);
    return SC_OK;
}

/* One data row (already split): its fields, then store_row. */
static sc_status data_row(profile_reader *pr, sc_error *err)
{
    sc_csv *r = &pr->csv;
    if (r->nfields != 5) /* more: a decimal comma would otherwise shift a reading silently */
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "expected 5 fields (scan,n,m1_um,m2_um,m3_urad), got %d%s", r->nfields,
                            r->nfields > 5 ? " (the decimal mark is '.')" : "");
    static const char *const name[3] = {"m1_um", "m2_um", "m3_urad"};
    long k, idx;
    double v[3];
    sc_status st;
    if ((st = sc_csv_long(r, 0, "scan", &k, err)) != SC_OK ||
        (st = sc_csv_long(r, 1, "n", &idx, err)) != SC_OK)
        return st;
    for (int c = 0; c < 3; ++c) { /* an empty reading is a gap (SPEC §2a): NaN */
        const char *f = r->field[2 + c];
        if (f[strspn(f, " \t")] == '\0')
            v[c] = NAN;
        else if ((st = sc_csv_double(r, 2 + c, name[c], &v[c], err)) != SC_OK)
            return st;
    }
    return store_row(pr, k, idx, v, err);
}

/* Each scan has rows; a sample without a row is a gap (SPEC §2a): NaN in all three readings,
 * for the least squares to solve around (the DFT method refuses it, profile_calibrate.c). A
 * scan missing more than half its samples is refused at its largest gap (a header claiming a
 * large N over a few rows is not a measurement, and is refused before its arrays are touched). */
static sc_status check_complete(profile_reader *pr, sc_error *err)
{
    const char *P = pr->csv.path;
    for (int k = 0; k < 2; ++k) {
        long m = pr->v.n - pr->d[k], present = 0;
        const long *rl = pr->row_line[k];
        for (long i = 0; i < m; ++i)
            present += rl[i] != 0;
        if (present == 0)
            return sc_error_set(err, SC_E_INPUT, P, pr->line_scan[k],
                                "scan %d missing: no data rows", k + 1);
        if (2 * present < m) {
            long best = 0, b0 = 0, at = pr->csv.line;
            for (long i = 0; i < m;) {
                long j = i;
                while (j < m && !rl[j])
                    ++j;
                if (j - i > best)
                    best = j - i, b0 = i, at = j < m ? rl[j] : pr->csv.line;
                i = j + 1;
            }
            return sc_error_set(err, SC_E_INPUT, P, at,
                                "gap in scan %d: no sample for n = %ld..%ld (%ld of its %ld "
                                "samples present: at most half of a scan may be missing)",
                                k + 1, b0, b0 + best - 1, present, m);
        }
    }
    /* the profile's first point is read only by the first sample of each scan, its last by the
     * last: without them the header's N (or the scans' start) contradicts the data */
    long last0 = pr->v.n - pr->d[0] - 1, last1 = pr->v.n - pr->d[1] - 1;
    if (!pr->row_line[0][last0] && !pr->row_line[1][last1])
        return sc_error_set(err, SC_E_INPUT, P, sc_header_line_of(&pr->hdr, "N"),
                            "no row reaches the profile's last point n = %ld (scan 1 ends before "
                            "n = %ld, scan 2 before n = %ld): N = %ld contradicts the data",
                            pr->v.n - 1, last0, last1, pr->v.n);
    if (!pr->row_line[0][0] && !pr->row_line[1][0])
        return sc_error_set(err, SC_E_INPUT, P, pr->line_scan[0],
                            "no row reaches the profile's first point: both scans lack n = 0");
    for (int k = 0; k < 2; ++k)
        for (long i = 0; i < pr->v.n - pr->d[k]; ++i)
            if (!pr->row_line[k][i])
                pr->data.m1_um[k][i] = pr->data.m2_um[k][i] = pr->data.m3_urad[k][i] = NAN;
    return SC_OK;
}

int sc_profile_has_gaps(const sc_profile_data *d)
{
    for (int k = 0; k < 2; ++k)
        for (int i = 0; i < d->n - d->d[k]; ++i)
            if (isnan(d->m1_um[k][i]) || isnan(d->m2_um[k][i]) || isnan(d->m3_urad[k][i]))
                return 1;
    return 0;
}

/* The data rows (up to the line at pr->stop_at, if any). A plain row (five fields, no blanks:
 * what writers write) is parsed in place by sc_csv_is_plain_row; any other line takes the general
 * path (comments, blanks, split, the fields' own messages), so both give the same values and the
 * same errors. The exact pass then checks that no sample is missing; the fast pass's caller
 * checks it over both halves. */
static sc_status read_rows(profile_reader *pr, sc_error *err)
{
    sc_csv *r = &pr->csv;
    int rc;
    sc_status st;
    while ((rc = sc_csv_next_line(r, err)) == 1) {
        if (pr->stop_at >= 0 && sc_csv_line_offset(r) >= pr->stop_at)
            return SC_OK;
        long kn[2];
        double v[3];
        if (sc_csv_is_plain_row(r, "LLDDD", kn, v))
            st = store_row(pr, kn[0], kn[1], v, err);
        else if (r->text[0] == '#' || sc_csv_is_blank(r))
            continue;
        else if (sc_csv_split(r, err) < 0)
            return err ? err->code : SC_E_INPUT;
        else
            st = data_row(pr, err);
        if (st != SC_OK)
            return st;
        if (pr->hook && pr->stored[0] + pr->stored[1] >= pr->hook_after)
            tell_hook(pr);
    }
    if (rc < 0)
        return err ? err->code : SC_E_INPUT;
    return pr->exact ? check_complete(pr, err) : SC_OK;
}

/* The offset of the first line that starts at or after the middle of [from, size) of the file
 * r reads, or -1 if there is none within a line's length of it. */
static long long middle_line(const sc_csv *r, long long from, long long size)
{
    char buf[4096];
    long long at = from + (size - from) / 2 - 1;
    for (long long end = at + SC_CSV_MAX_LINE + 2; at < size && at < end;) {
        ssize_t got = pread(fileno(r->fp), buf, sizeof buf, (off_t)at);
        if (got <= 0)
            return -1;
        const char *nl = memchr(buf, '\n', (size_t)got);
        if (nl)
            return at + (nl - buf) + 1 < size ? at + (nl - buf) + 1 : -1;
        at += got;
    }
    return -1;
}

/* The second half's thread: its own reader, the same data arrays. */
typedef struct half_job {
    profile_reader r;
    sc_error err;
    sc_status st;
} half_job;

static void *read_half(void *arg)
{
    half_job *j = arg;
    j->st = read_rows(&j->r, &j->err);
    return NULL;
}

/* The fast pass's rows: the second half on a second thread where it pays (*threads = 2), then
 * every sample once over both halves. Any failure is the exact pass's to explain. */
static sc_status read_rows_fast(profile_reader *pr, long long parallel_from, int *threads,
                                sc_error *err)
{
    struct stat sb;
    long long from = sc_csv_line_offset(&pr->csv), split = -1;
    if (fstat(fileno(pr->csv.fp), &sb) == 0 && sb.st_size - from >= parallel_from &&
        sb.st_size - from > 1 && sc_io_cpus_available() > 1)
        split = middle_line(&pr->csv, from, sb.st_size);
    half_job *job = NULL;
    pthread_t helper;
    if (split > 0) { /* no memory: SC_E_NOMEM; the file not to be opened again: one thread */
        if (!(job = calloc(1, sizeof *job)))
            return sc_error_set(err, SC_E_NOMEM, pr->csv.path, 0, "out of memory");
        job->r = *pr; /* the header's values; a reader, marks and counts of its own */
        memset(&job->r.csv, 0, sizeof job->r.csv);
        job->r.stored[0] = job->r.stored[1] = 0;
        job->r.stop_at = -1;
        job->r.hook = NULL; /* the first half's reader tells it */
        job->r.seen[0] = job->r.seen[1] = NULL;
        sc_status st = alloc_row_marks(&job->r, err);
        if (st != SC_OK || sc_csv_open_at(&job->r.csv, &pr->csv, split, NULL) != SC_OK ||
            pthread_create(&helper, NULL, read_half, job) != 0) {
            free_row_marks(&job->r);
            sc_csv_close(&job->r.csv);
            free(job);
            job = NULL;
            if (st != SC_OK)
                return st;
        }
    }
    pr->stop_at = job ? split : -1;
    sc_status st = read_rows(pr, err);
    if (job) {
        pthread_join(helper, NULL);
        *threads = 2;
        if (job->st != SC_OK && (st == SC_OK || job->st == SC_E_NOMEM))
            st = sc_error_set(err, job->st, pr->csv.path, 0, "%s", job->err.msg);
        for (int k = 0; k < 2 && st == SC_OK; ++k) {
            size_t words = (size_t)(pr->v.n - pr->d[k] + 63) / 64;
            for (size_t i = 0; i < words && st == SC_OK; ++i)
                if (pr->seen[k][i] & job->r.seen[k][i])
                    st = sc_error_set(err, SC_E_INPUT, pr->csv.path, 0, "duplicate sample");
            pr->stored[k] += job->r.stored[k];
        }
        free_row_marks(&job->r);
        sc_csv_close(&job->r.csv);
        free(job);
    }
    for (int k = 0; k < 2 && st == SC_OK; ++k)
        if (pr->stored[k] != pr->v.n - pr->d[k])
            st = sc_error_set(err, SC_E_INPUT, pr->csv.path, 0, "samples missing");
    return st;
}

/* The header's fields of pr into d (d's arrays untouched). */
static void header_fields(const profile_reader *pr, sc_profile_data *d)
{
    d->has_sigma_disp = sc_header_line_of(&pr->hdr, "sigma_disp_um") != 0;
    d->has_sigma_angle = sc_header_line_of(&pr->hdr, "sigma_angle_urad") != 0;
    d->has_probe_gain = sc_header_line_of(&pr->hdr, "probe_gain") != 0;
    d->has_angle_scale = sc_header_line_of(&pr->hdr, "angle_scale") != 0;
    d->has_spacing_u = sc_header_line_of(&pr->hdr, "spacing_u_mm") != 0;
    for (int i = 0; i < 2; ++i) {
        d->probe_gain[i] = d->has_probe_gain ? pr->v.probe_gain[i] : (double)(1 - i);
        d->angle_scale[i] = d->has_angle_scale ? pr->v.angle_scale[i] : (double)(1 - i);
    }
    d->spacing_u_mm = d->has_spacing_u ? pr->v.spacing_u_mm : 0.0;
    d->sigma_disp_um = pr->v.sigma_disp_um;
    d->sigma_angle_urad = pr->v.sigma_angle_urad;
    d->line_n = sc_header_line_of(&pr->hdr, "N");
    d->line_scan[0] = pr->line_scan[0];
    d->line_scan[1] = pr->line_scan[1];
    snprintf(d->path, sizeof d->path, "%s", pr->csv.path);
}

/* Who hears of the header, and whether it has (sc_profile_read_hooked). */
typedef struct header_hook {
    sc_profile_header_fn fn;
    void *ctx;
    int called;
} header_hook;

/* The header to the hook (once): after the first 1/32 of the rows were stored, so that a file
 * whose header promises a large N but whose rows soon go wrong (or end) is refused before any
 * work the size of N starts (a plan of 10 GB for a header line and two rows). */
static void tell_hook(profile_reader *pr)
{
    header_hook *hook = pr->hook;
    pr->hook = NULL;
    if (hook->called)
        return;
    sc_profile_data hdr = pr->data;
    for (int k = 0; k < 2; ++k)
        hdr.m1_um[k] = hdr.m2_um[k] = hdr.m3_urad[k] = NULL;
    header_fields(pr, &hdr);
    hook->called = 1;
    hook->fn(hook->ctx, &hdr);
}

/* One pass over the file (exact or fast, as above). */
static sc_status read_pass(const char *path, int exact, long long parallel_from, int *threads,
                           header_hook *hook, sc_profile_data *out, sc_error *err)
{
    profile_reader pr;
    memset(&pr, 0, sizeof pr);
    pr.exact = exact;
    pr.stop_at = -1;
    sc_header_init(&pr.hdr, header_keys, (int)(sizeof header_keys / sizeof header_keys[0]), &pr.v);
    sc_status st = sc_csv_open(&pr.csv, path, err);
    if (st != SC_OK)
        return st;
    if ((st = read_magic(&pr, err)) == SC_OK && (st = read_header(&pr, err)) == SC_OK &&
        (st = start_data(&pr, err)) == SC_OK) {
        if (hook && hook->fn && !hook->called) {
            long rows = 2 * pr.v.n - pr.d[0] - pr.d[1];
            pr.hook = hook;
            pr.hook_after = rows / 32 > 1 ? rows / 32 : 1;
        }
        st = exact ? read_rows(&pr, err) : read_rows_fast(&pr, parallel_from, threads, err);
    }
    free_row_marks(&pr);
    if (st != SC_OK) {
        sc_profile_data_free(&pr.data);
        sc_csv_close(&pr.csv);
        return st;
    }
    header_fields(&pr, &pr.data);
    sc_csv_close(&pr.csv);
    *out = pr.data;
    return SC_OK;
}

/* A regular file (not a pipe: it can be read twice). */
static int is_regular_file(const char *path)
{
    struct stat sb;
    return strcmp(path, "-") != 0 && stat(path, &sb) == 0 && S_ISREG(sb.st_mode);
}

/* sc_profile_read_tuned with the header hook. */
static sc_status read_file(const char *path, long long parallel_from, int *threads,
                           header_hook *hook, sc_profile_data *out, sc_error *err)
{
    int used = 1;
    memset(out, 0, sizeof *out);
    sc_status st = SC_E_INPUT;
    int fast = is_regular_file(path);
    /* the hook's work (a plan the size of N) only for a regular file, whose size bounds the N
     * its header may claim; a pipe's N is known good only once every row came (the caller then
     * makes the plan after the reading) */
    header_hook *h = fast ? hook : NULL;
    if (fast)
        st = read_pass(path, 0, parallel_from, &used, h, out, err);
    if (!fast || (st != SC_OK && st != SC_E_NOMEM)) /* out of memory stays out of memory */
        used = 1, st = read_pass(path, 1, 0, &used, h, out, err);
    if (threads)
        *threads = st == SC_OK ? used : 0;
    return st;
}

sc_status sc_profile_read_tuned(const char *path, long long parallel_from, int *threads,
                                sc_profile_data *out, sc_error *err)
{
    return read_file(path, parallel_from, threads, NULL, out, err);
}

sc_status sc_profile_read(const char *path, sc_profile_data *out, sc_error *err)
{
    return read_file(path, SC_PROFILE_PARALLEL_FROM, NULL, NULL, out, err);
}

sc_status sc_profile_read_hooked(const char *path, sc_profile_header_fn on_header, void *ctx,
                                 sc_profile_data *out, sc_error *err)
{
    header_hook hook = {on_header, ctx, 0};
    return read_file(path, SC_PROFILE_PARALLEL_FROM, NULL, &hook, out, err);
}

/* ---- writer ---- */

/* Row i of the data rows: scan 1's samples, then scan 2's. */
static char *measurement_row(const void *ctx, long i, char *p)
{
    const sc_profile_data *d = ctx;
    int k = i >= d->n - d->d[0];
    long j = k ? i - (d->n - d->d[0]) : i;
    const double v[3] = {d->m1_um[k][j], d->m2_um[k][j], d->m3_urad[k][j]};
    if (isnan(v[0]) && isnan(v[1]) && isnan(v[2]))
        return p; /* a missing row stays missing */
    if (isnan(v[0]) || isnan(v[1]) || isnan(v[2])) { /* empty fields: the general path */
        p = sc_io_put_long(p, k + 1, ',');
        p = sc_io_put_long(p, j, ',');
        for (int c = 0; c < 3; ++c) {
            sc_number_shortest m;
            if (isnan(v[c]))
                *p++ = c < 2 ? ',' : '\n';
            else
                sc_number_find_shortest(v[c], &m), p = sc_io_put_shortest(p, &m, c < 2 ? ',' : '\n');
        }
        return p;
    }
    sc_number_shortest m[3]; /* the three numbers' digits first, then the text */
    sc_number_find_shortest(v[0], &m[0]);
    sc_number_find_shortest(v[1], &m[1]);
    sc_number_find_shortest(v[2], &m[2]);
    p = sc_io_put_long(p, k + 1, ',');
    p = sc_io_put_long(p, j, ',');
    p = sc_io_put_shortest(p, &m[0], ',');
    p = sc_io_put_shortest(p, &m[1], ',');
    return sc_io_put_shortest(p, &m[2], '\n');
}

/* Every sample a finite number or NaN (a gap): only what the reader reads back is written. */
static sc_status check_writable(const sc_profile_data *d, sc_error *err)
{
    static const char *const sensor[3] = {"m1_um", "m2_um", "m3_urad"};
    for (int k = 0; k < 2; ++k) {
        const double *v[3] = {d->m1_um[k], d->m2_um[k], d->m3_urad[k]};
        for (int s = 0; s < 3; ++s)
            for (int j = 0; j < d->n - d->d[k]; ++j)
                if (!isnan(v[s][j]) && !(fabs(v[s][j]) <= SC_INPUT_MAX_ABS))
                    return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                        "scan %d n = %d: %s = %g is not a finite measurement "
                                        "(|value| <= %g)", k + 1, j, sensor[s], v[s][j],
                                        SC_INPUT_MAX_ABS);
    }
    return SC_OK;
}

/* The header and rows of d into o. */
static void write_data(sc_io_out *o, const sc_profile_data *d)
{
    FILE *fp = o->f.fp;
    fprintf(fp, "# selfcal-profile v1\n# N = %d\n# s_mm = %.17g\n# scan 1: d=%d\n# scan 2: d=%d\n",
            d->n, d->s_mm, d->d[0], d->d[1]);
    if (d->has_sigma_disp)
        fprintf(fp, "# sigma_disp_um = %.17g\n", d->sigma_disp_um);
    if (d->has_sigma_angle)
        fprintf(fp, "# sigma_angle_urad = %.17g\n", d->sigma_angle_urad);
    if (d->has_probe_gain)
        fprintf(fp, "# probe_gain = %.17g, %.17g\n", d->probe_gain[0], d->probe_gain[1]);
    if (d->has_angle_scale)
        fprintf(fp, "# angle_scale = %.17g, %.17g\n", d->angle_scale[0], d->angle_scale[1]);
    if (d->has_spacing_u)
        fprintf(fp, "# spacing_u_mm = %.17g\n", d->spacing_u_mm);
    fputs("scan,n,m1_um,m2_um,m3_urad\n", fp);
    sc_io_out_rows(o, 2L * d->n - d->d[0] - d->d[1], measurement_row, d);
}

/* The header and rows of d (checked) into f. */
static sc_status write_checked_to(sc_afile *f, const sc_profile_data *d, sc_error *err)
{
    sc_io_out o;
    sc_status st = sc_io_out_attach(&o, f, err);
    if (st != SC_OK)
        return st;
    write_data(&o, d);
    return sc_io_out_drain(&o, err);
}

sc_status sc_profile_write_to(sc_afile *f, const sc_profile_data *d, sc_error *err)
{
    sc_status st = check_writable(d, err);
    return st == SC_OK ? write_checked_to(f, d, err) : st;
}

sc_status sc_profile_write(const char *path, const sc_profile_data *d, sc_error *err)
{
    sc_status st = check_writable(d, err); /* before the file is opened: nothing written */
    if (st != SC_OK)
        return st;
    sc_afile f;
    if ((st = sc_afile_open(&f, path, err)) != SC_OK)
        return st;
    return sc_afile_finish(&f, write_checked_to(&f, d, err), err);
}
