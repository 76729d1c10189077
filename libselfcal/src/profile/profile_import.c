/* profile_import.c — owns sc_profile_import: the two scans' sensor logs of a straightness
 * measurement (read with sc_table_read) checked for a constant step, gaps, repeats, a common
 * start, whole-step spacings and equal coverage, and turned into a selfcal-profile v1 data set. */
#include "selfcal/import.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/profile.h"

void sc_profile_import_defaults(sc_profile_import_params *p)
{
    memset(p, 0, sizeof *p);
    p->step_tolerance = 0.1;
}

typedef struct pos_row {
    double pos;
    long row;
} pos_row;

static int cmp_pos(const void *a, const void *b)
{
    const pos_row *x = a, *y = b;
    if (x->pos != y->pos)
        return (x->pos > y->pos) - (x->pos < y->pos);
    return (x->row > y->row) - (x->row < y->row);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Scan k (rows sorted in o) on the grid p0 + n·step, n = 0, 1, ... without repeats; each row's n
 * into idx. A gap (positions not sampled) is passed on (SPEC §2a: least squares solves around
 * it), up to half of the scan's samples (as the reader of the file written: gap_check). */
static sc_status check_steps(const sc_table *t, const pos_row *o, int k, double p0, double step,
                             double tol, long *idx, sc_error *err)
{
    long prev = -1, prev_row = -1;
    for (long q = 0; q < t->n_rows; ++q) {
        long r = o[q].row;
        double pos = o[q].pos, fn = (pos - p0) / step;
        long n = lround(fn);
        if (fabs(fn - n) > tol)
            return sc_error_set(err, SC_E_INPUT, t->path, t->line[r],
                                "position %.6f mm is %.3f steps off the sampling grid (%.6f mm + "
                                "n x %.6f mm; tolerance %g steps): the step is not constant",
                                pos, fabs(fn - n), p0, step, tol);
        if (q == 0 && n != 0)
            return sc_error_set(err, SC_E_INPUT, t->path, t->line[r],
                                "scan %d starts at %.6f mm, scan 1 at %.6f mm: both scans must "
                                "start at the same position",
                                k + 1, pos, p0);
        if (q > 0 && n == prev)
            return sc_error_set(err, SC_E_INPUT, t->path, t->line[r],
                                "position %.6f mm is sampled twice (also line %ld)", pos,
                                t->line[prev_row]);
        idx[q] = n;
        prev = n;
        prev_row = r;
    }
    return SC_OK;
}

/* The median step between consecutive sorted positions. */
static sc_status median_step(const sc_table *t, const pos_row *o, double *step, sc_error *err)
{
    if (t->n_rows < 2)
        return sc_error_set(err, SC_E_INPUT, t->path, t->line[0],
                            "one sample: cannot tell the step (give the step)");
    double *diff = malloc((size_t)(t->n_rows - 1) * sizeof(double));
    if (!diff)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (long q = 1; q < t->n_rows; ++q)
        diff[q - 1] = o[q].pos - o[q - 1].pos;
    qsort(diff, (size_t)(t->n_rows - 1), sizeof(double), cmp_double);
    *step = diff[(t->n_rows - 1) / 2];
    free(diff);
    if (!(*step > 0))
        return sc_error_set(err, SC_E_INPUT, t->path, t->header_line,
                            "the median step between positions is 0: repeated positions?");
    return SC_OK;
}

#define OFF_GRID LONG_MIN /* a sample chain_indices could not number */

/* The sample index of each sorted position of scan 1, chained from the last sample it numbered
 * (each difference rounded to whole steps: a position's jitter never adds up along the scan),
 * into n; a sample more than tol steps off the whole steps from it gets OFF_GRID and is left out
 * of the chain (check_steps then names it), so one bad position cannot shift every index after
 * it and skew the step fitted from them. */
static void chain_indices(const sc_table *t, const pos_row *o, double step, double tol, long *n)
{
    long good = 0;
    n[0] = 0;
    for (long q = 1; q < t->n_rows; ++q) {
        double f = (o[q].pos - o[good].pos) / step;
        long r = lround(f);
        if (fabs(f - (double)r) > tol) {
            n[q] = OFF_GRID;
            continue;
        }
        n[q] = n[good] + r;
        good = q;
    }
}

/* The slope of the least-squares line p = a + s·n through the positions and their indices (0 if
 * it cannot be fitted: one index). */
static double fit_step(const sc_table *t, const pos_row *o, const long *n)
{
    double mn = 0, mp = 0, snn = 0, snp = 0, cnt = 0;
    for (long q = 0; q < t->n_rows; ++q)
        if (n[q] != OFF_GRID)
            mn += (double)n[q], mp += o[q].pos, cnt += 1;
    if (cnt < 2)
        return 0;
    mn /= cnt, mp /= cnt;
    for (long q = 0; q < t->n_rows; ++q) {
        if (n[q] == OFF_GRID)
            continue;
        snn += ((double)n[q] - mn) * ((double)n[q] - mn);
        snp += ((double)n[q] - mn) * (o[q].pos - mp);
    }
    return snn > 0 ? snp / snn : 0;
}

/* The grid's origin p0: the median over scan 1 of p - n·step (robust to a jittered first
 * sample); n: chain_indices'. */
static sc_status median_origin(const sc_table *t, const pos_row *o, const long *n, double step,
                               double *p0, sc_error *err)
{
    double *r = malloc((size_t)t->n_rows * sizeof(double));
    if (!r)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    long m = 0;
    for (long q = 0; q < t->n_rows; ++q)
        if (n[q] != OFF_GRID)
            r[m++] = o[q].pos - (double)n[q] * step;
    qsort(r, (size_t)m, sizeof(double), cmp_double);
    *p0 = r[m / 2]; /* m >= 1: the first sample is always numbered */
    free(r);
    return SC_OK;
}

/* The step and the spacings in steps: the step given, or found from scan 1's positions (the
 * median difference, refined by a line through them) and then made exactly D1/d1 — the spacing
 * the user states is the truth the reconstruction uses (D_k = d_k·s). */
static sc_status step_and_spacings(const sc_profile_import_params *p, const sc_table *t0,
                                   const pos_row *o0, long *n0, double *step, int dk[2],
                                   const char *const path[2], sc_error *err)
{
    sc_status st = SC_OK;
    int given = p->step_mm > 0;
    double s = p->step_mm;
    if (!given && (st = median_step(t0, o0, &s, err)) != SC_OK)
        return st;
    chain_indices(t0, o0, s, p->step_tolerance, n0);
    double s_fit = given ? 0 : fit_step(t0, o0, n0);
    if (s_fit > 0)
        s = s_fit;
    for (int k = 0; k < 2; ++k) {
        double fd = p->spacing_mm[k] / s;
        dk[k] = fd < 1e8 ? (int)lround(fd) : 0;
        /* a given step must divide the spacing exactly; a found one to the step tolerance */
        double tol = given ? 1e-6 * fd : p->step_tolerance;
        if (dk[k] < 1 || fabs(fd - dk[k]) > tol)
            return sc_error_set(err, SC_E_INPUT, path[k], 0,
                                "the sensor spacing %g mm is not a whole number of steps (step "
                                "%.9g mm%s: %.6f steps)",
                                p->spacing_mm[k], s, given ? "" : ", found from the positions",
                                fd);
    }
    if (!given) {
        s = p->spacing_mm[0] / dk[0];
        if (fabs(p->spacing_mm[1] / dk[1] - s) > 1e-6 * s)
            return sc_error_set(err, SC_E_INPUT, path[1], 0,
                                "the sensor spacings %g and %g mm are not whole multiples of one "
                                "step (%g / %d and %g / %d differ; give the step with --step-mm)",
                                p->spacing_mm[0], p->spacing_mm[1], p->spacing_mm[0], dk[0],
                                p->spacing_mm[1], dk[1]);
        chain_indices(t0, o0, s, p->step_tolerance, n0); /* the indices for the exact step */
    }
    *step = s;
    return SC_OK;
}

/* At most half of scan k's samples (0..idx[last]) missing, as the profile reader allows; else
 * SC_E_INPUT at the row after its largest gap. */
static sc_status gap_check(const sc_table *t, const pos_row *o, const long *idx, int k,
                           sc_error *err)
{
    long m = idx[t->n_rows - 1] + 1, best = 0, at = 0;
    if (2 * t->n_rows >= m)
        return SC_OK;
    for (long q = 1; q < t->n_rows; ++q)
        if (idx[q] - idx[q - 1] - 1 > best)
            best = idx[q] - idx[q - 1] - 1, at = q;
    return sc_error_set(err, SC_E_INPUT, t->path, t->line[o[at].row],
                        "scan %d: %ld of its %ld samples present (the largest gap: %ld samples "
                        "before %.6f mm): at most half of a scan may be missing",
                        k + 1, t->n_rows, m, best, o[at].pos);
}

/* The logged samples into out at their indices; a sample not logged is a gap (NaN). */
static void fill_samples(const sc_table *const scan[2], const pos_row *const o[2],
                         const long *const idx[2], sc_profile_data *out)
{
    for (int k = 0; k < 2; ++k) {
        for (long j = 0; j < out->n - out->d[k]; ++j)
            out->m1_um[k][j] = out->m2_um[k][j] = out->m3_urad[k][j] = NAN;
        for (long q = 0; q < scan[k]->n_rows; ++q) {
            const double *row = &scan[k]->value[o[k][q].row * 4];
            out->m1_um[k][idx[k][q]] = row[1];
            out->m2_um[k][idx[k][q]] = row[2];
            out->m3_urad[k][idx[k][q]] = row[3];
        }
    }
}

/* The request: two scans of 4 columns with samples, positive spacings and step, the step
 * tolerance in (0, 0.5). */
static sc_status import_check(const sc_profile_import_params *p, const sc_table *const scan[2],
                              sc_error *err)
{
    for (int k = 0; k < 2; ++k)
        if (scan[k]->n_cols != 4 || scan[k]->n_rows < 1)
            return sc_error_set(err, SC_E_INPUT, scan[k]->path, 0,
                                "a scan log needs 4 columns and at least one sample");
    if (!(p->step_tolerance > 0 && p->step_tolerance < 0.5) || !(p->step_mm >= 0) ||
        !(p->spacing_mm[0] > 0) || !(p->spacing_mm[1] > 0))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "spacings and step must be positive, the step tolerance in (0, 0.5)");
    return SC_OK;
}

/* Each scan's rows in the order of their positions (o[k], allocated here). */
static sc_status sort_positions(const sc_table *const scan[2], pos_row *o[2], sc_error *err)
{
    for (int k = 0; k < 2; ++k) {
        const sc_table *t = scan[k];
        o[k] = malloc((size_t)t->n_rows * sizeof(pos_row));
        if (!o[k])
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        for (long q = 0; q < t->n_rows; ++q)
            o[k][q] = (pos_row){t->value[q * 4], q};
        qsort(o[k], (size_t)t->n_rows, sizeof(pos_row), cmp_pos);
    }
    return SC_OK;
}

/* The step, the spacings in steps and the origin p0 from scan 1 (its indices in a temporary
 * array). */
static sc_status step_and_origin(const sc_profile_import_params *p, const sc_table *const scan[2],
                                 pos_row *const o[2], double *step, int dk[2], double *p0,
                                 sc_error *err)
{
    long *n0 = malloc((size_t)scan[0]->n_rows * sizeof(long));
    if (!n0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    const char *paths[2] = {scan[0]->path, scan[1]->path};
    sc_status st = step_and_spacings(p, scan[0], o[0], n0, step, dk, paths, err);
    if (st == SC_OK)
        st = median_origin(scan[0], o[0], n0, *step, p0, err);
    free(n0);
    return st;
}

/* out sized for the profile both scans cover (the same number of points). */
static sc_status import_init(const sc_table *const scan[2], pos_row *const o[2],
                             long *const idx[2], double step, const int dk[2],
                             sc_profile_data *out, sc_error *err)
{
    long m1 = idx[0][scan[0]->n_rows - 1] + 1, m2 = idx[1][scan[1]->n_rows - 1] + 1;
    long n1 = m1 + dk[0], n2 = m2 + dk[1];
    if (n1 != n2)
        return sc_error_set(err, SC_E_INPUT, scan[1]->path,
                            scan[1]->line[o[1][scan[1]->n_rows - 1].row],
                            "scan 2 covers %ld points (%ld samples + d2 = %d), scan 1 covers %ld "
                            "(%ld samples + d1 = %d): both scans must cover the same profile",
                            n2, m2, dk[1], n1, m1, dk[0]);
    if (n1 > 100000000L)
        return sc_error_set(err, SC_E_INPUT, scan[0]->path, 0, "more than 1e8 points");
    return sc_profile_data_init(out, (int)n1, step, dk[0], dk[1], err);
}

sc_status sc_profile_import(const sc_profile_import_params *p, const sc_table *const scan[2],
                            sc_profile_data *out, double *p0_mm, sc_error *err)
{
    memset(out, 0, sizeof *out);
    sc_status st = import_check(p, scan, err);
    if (st != SC_OK)
        return st;
    pos_row *o[2] = {NULL, NULL};
    double step = 0, p0 = 0;
    int dk[2] = {0, 0};
    st = sort_positions(scan, o, err);
    if (st == SC_OK)
        st = step_and_origin(p, scan, o, &step, dk, &p0, err);
    long *idx[2] = {NULL, NULL};
    for (int k = 0; k < 2 && st == SC_OK; ++k) {
        idx[k] = malloc((size_t)scan[k]->n_rows * sizeof(long));
        st = idx[k] ? check_steps(scan[k], o[k], k, p0, step, p->step_tolerance, idx[k], err)
                    : sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        if (st == SC_OK)
            st = gap_check(scan[k], o[k], idx[k], k, err);
    }
    if (st == SC_OK)
        st = import_init(scan, o, idx, step, dk, out, err);
    if (st == SC_OK)
        fill_samples(scan, (const pos_row *const *)o, (const long *const *)idx, out);
    free(idx[0]);
    free(idx[1]);
    free(o[0]);
    free(o[1]);
    if (p0_mm)
        *p0_mm = p0;
    return st;
}
