/* tests/fuzz/fuzz_import.c — libFuzzer target: `selfcal import`, the readers of real instrument
 * exports (SPEC §10): the delimited-table reader (sc_table_read, delimiter and decimal mark
 * detected), the numbering of a view's points (sc_grid_import_assign) and the straightness-log
 * import (sc_profile_import).
 *
 * Input: two control bytes, then the export. Byte 0 bit 0 selects the family:
 *   0 grid:    bits 1-2 N (3, 5, 7, 9), bits 3-4 pitch (1, 2, 5, 10 mm), bit 5 uncertainty
 *              columns ux, uy too, bit 6 positions in µm (else mm), bit 7 a stage of N + 2 nodes;
 *              byte 1: bits 0-1 rot (0, 90, 180, 270), bits 2-4 shift x - 4, bits 5-7 shift y - 4
 *              (pitches). Columns X, Y [, ux, uy], as `selfcal simulate exports` writes them.
 *   1 profile: the two scan logs, split at the first form feed (none: the same log twice);
 *              bits 1-3 d1 - 1 and bits 4-6 d2 - 1 (sensor spacings in steps of 0.5 mm), bit 7
 *              the step given (0.5 mm; else the median step of scan 1); byte 1 bit 0 a step
 *              tolerance of 0.45 (else 0.1). Columns Position, SensorA, SensorB, Angle.
 * Checks beyond "no memory error, no undefined behaviour":
 *   - every failure is a one-line error;
 *   - a table read holds n_rows >= 1 finite values within SC_INPUT_MAX_ABS of the file's unit,
 *     lines increasing after the header, a detected delimiter and decimal mark;
 *   - a numbered view: point_mark and mark_point are inverse on the assigned points, every
 *     assigned mark is one the view measures, assigned + left out = points, assigned >= the
 *     share, and each assigned point lies within the tolerance of its mark placed by the
 *     reported fit (recomputed here from tx, ty, theta);
 *   - an imported profile has N >= samples + d for both scans (gaps: NaN, at most half of a
 *     scan), d = D / s (within 1e-6 of D / s),
 *     and its values are the
 *     logs' values (the same multiset per column); written by sc_profile_write, the selfcal-profile
 *     v1 reader reads back exactly the same data set (what `selfcal import profile` promises). */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/csv.h"
#include "selfcal/import.h"
#include "selfcal/profile.h"

#define EPS_MM(x, y) (1e-9 * (1.0 + fabs(x) + fabs(y)))

static void check_table(const sc_table *t, int n_cols, const double *scale)
{
    FUZZ_CHECK(t->n_rows >= 1 && t->n_cols == n_cols && t->header_line >= 1);
    FUZZ_CHECK(t->delimiter == ',' || t->delimiter == ';' || t->delimiter == '\t');
    FUZZ_CHECK(t->decimal == '.' || t->decimal == ',');
    for (long r = 0; r < t->n_rows; ++r) {
        FUZZ_CHECK(t->line[r] > (r ? t->line[r - 1] : t->header_line));
        for (int k = 0; k < n_cols; ++k) {
            double v = t->value[r * n_cols + k];
            FUZZ_CHECK(isfinite(v) && fabs(v) <= SC_INPUT_MAX_ABS * scale[k]);
        }
    }
}

/* Where the fit puts mark (i, j) of view v (absolute stage mm): origin + t + Rot(th)·nominal. */
static void fitted_mark(const sc_grid_import_params *p, const sc_grid_view *v,
                        const sc_grid_import_fit *fit, int i, int j, double *x, double *y)
{
    double c = (p->n - 1) / 2.0, P = p->pitch_mm, px = (j - c) * P, py = (i - c) * P, nx, ny;
    switch (v->rot_deg) {
    case 90: nx = -py, ny = px; break;
    case 180: nx = -px, ny = -py; break;
    case 270: nx = py, ny = -px; break;
    default: nx = px, ny = py; break;
    }
    nx += v->shift_x * P;
    ny += v->shift_y * P;
    double th = fit->theta_urad * 1e-6, cs = cos(th), sn = sin(th);
    *x = p->origin_mm[0] + fit->tx_um * 1e-3 + cs * nx - sn * ny;
    *y = p->origin_mm[1] + fit->ty_um * 1e-3 + sn * nx + cs * ny;
}

static void fuzz_grid(uint8_t c0, uint8_t c1, const char *path)
{
    static const int ns[4] = {3, 5, 7, 9};
    static const double pitches[4] = {1, 2, 5, 10};
    static const char *const names[4] = {"X", "Y", "ux", "uy"};
    int n = ns[(c0 >> 1) & 3], nc = c0 & 0x20 ? 4 : 2;
    double unit_mm = c0 & 0x40 ? 1e-3 : 1.0;
    double scale[4] = {unit_mm, unit_mm, unit_mm * 1e3, unit_mm * 1e3};
    sc_grid_import_params p;
    sc_grid_import_defaults(&p, n, pitches[(c0 >> 3) & 3]);
    if (c0 & 0x80)
        p.stage_nx = p.stage_ny = n + 2;
    static sc_grid_view v; /* row_sel/col_sel unused: not restricted */
    v.rot_deg = 90 * (c1 & 3);
    v.shift_x = ((c1 >> 2) & 7) - 4;
    v.shift_y = ((c1 >> 5) & 7) - 4;

    sc_table t;
    sc_error err;
    memset(&err, 0, sizeof err);
    sc_status st = sc_table_read(path, nc, names, scale, &t, &err);
    fuzz_check_error(st, &err);
    if (st != SC_OK) {
        FUZZ_CHECK(t.value == NULL && t.line == NULL);
        return;
    }
    check_table(&t, nc, scale);
    long np = t.n_rows, nn = (long)n * n;
    double *x = malloc((size_t)np * sizeof *x), *y = malloc((size_t)np * sizeof *y);
    double *work = malloc(sc_grid_import_work_doubles(np) * sizeof(double));
    long *point_mark = malloc((size_t)np * sizeof(long)), *mark_point = malloc((size_t)nn * sizeof(long));
    FUZZ_CHECK(x && y && work && point_mark && mark_point);
    for (long q = 0; q < np; ++q) {
        x[q] = t.value[q * nc];
        y[q] = t.value[q * nc + 1];
    }
    sc_grid_import_fit fit;
    memset(&err, 0, sizeof err);
    st = sc_grid_import_assign(&p, &v, np, x, y, t.line, path, t.header_line, point_mark,
                               mark_point, &fit, work, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        FUZZ_CHECK(isfinite(fit.tx_um) && isfinite(fit.ty_um) && isfinite(fit.theta_urad));
        FUZZ_CHECK(fit.n_assigned + fit.n_left_out == np);
        FUZZ_CHECK(fit.n_marks >= 1 && fit.n_assigned <= fit.n_marks);
        FUZZ_CHECK(fit.n_assigned >= 1 && (double)fit.n_assigned >= p.min_share * (double)np);
        FUZZ_CHECK(fit.max_dist_um <= p.tolerance_mm * 1e3 * (1 + 1e-12));
        long assigned = 0;
        for (long m = 0; m < nn; ++m) {
            long k = mark_point[m];
            FUZZ_CHECK(k >= -1 && k < np);
            if (k < 0)
                continue;
            ++assigned;
            FUZZ_CHECK(point_mark[k] == m);
            int i = (int)(m / n), j = (int)(m % n), ni, nj;
            FUZZ_CHECK(sc_grid_import_mark_node(&p, &v, i, j, &ni, &nj));
            double fx, fy;
            fitted_mark(&p, &v, &fit, i, j, &fx, &fy);
            FUZZ_CHECK(hypot(x[k] - fx, y[k] - fy) <= p.tolerance_mm + EPS_MM(x[k], y[k]));
        }
        FUZZ_CHECK(assigned == fit.n_assigned);
        /* -1 beyond T, -2 far beyond the others, -3 on a mark rows=/cols= leave out */
        long left_out = 0;
        for (long k = 0; k < np; ++k) {
            FUZZ_CHECK(point_mark[k] >= -3 && point_mark[k] < nn &&
                       (point_mark[k] < 0 || mark_point[point_mark[k]] == k));
            left_out += point_mark[k] < 0;
        }
        FUZZ_CHECK(left_out == fit.n_left_out && fit.n_assigned + left_out == np);
    }
    free(x);
    free(y);
    free(work);
    free(point_mark);
    free(mark_point);
    sc_table_free(&t);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The values of column k of both logs and of the data set's column k are the same multiset. */
static void check_column(const sc_table *const scan[2], const sc_profile_data *d, int k)
{
    for (int s = 0; s < 2; ++s) {
        long m = scan[s]->n_rows;
        double *a = malloc((size_t)m * sizeof *a), *b = malloc((size_t)m * sizeof *b);
        const double *col = k == 1 ? d->m1_um[s] : k == 2 ? d->m2_um[s] : d->m3_urad[s];
        FUZZ_CHECK(a && b);
        long got = 0; /* the data set's samples that are not gaps (NaN) */
        for (long q = 0; q < d->n - d->d[s]; ++q)
            if (!isnan(col[q])) {
                FUZZ_CHECK(got < m);
                b[got++] = col[q];
            }
        FUZZ_CHECK(got == m);
        for (long q = 0; q < m; ++q)
            a[q] = scan[s]->value[q * 4 + k];
        qsort(a, (size_t)m, sizeof *a, cmp_double);
        qsort(b, (size_t)m, sizeof *b, cmp_double);
        FUZZ_CHECK(memcmp(a, b, (size_t)m * sizeof *a) == 0);
        free(a);
        free(b);
    }
}

static int same_values(const double *a, const double *b, int m)
{
    for (int q = 0; q < m; ++q)
        if (!(a[q] == b[q]) && !(isnan(a[q]) && isnan(b[q]))) /* a gap reads back as a gap */
            return 0;
    return 1;
}

static void fuzz_profile(uint8_t c0, uint8_t c1, const uint8_t *data, size_t size)
{
    static const char *const names[4] = {"Position", "SensorA", "SensorB", "Angle"};
    static const double scale[4] = {1, 1, 1, 1};
    const uint8_t *ff = memchr(data, '\f', size);
    size_t n1 = ff ? (size_t)(ff - data) : size;
    const char *path[2] = {fuzz_file(0, "scan1.csv", data, n1),
                           ff ? fuzz_file(1, "scan2.csv", ff + 1, size - n1 - 1)
                              : fuzz_file(1, "scan2.csv", data, n1)};
    sc_table t[2];
    memset(t, 0, sizeof t);
    sc_error err;
    sc_status st = SC_OK;
    for (int k = 0; k < 2 && st == SC_OK; ++k) {
        memset(&err, 0, sizeof err);
        st = sc_table_read(path[k], 4, names, scale, &t[k], &err);
        fuzz_check_error(st, &err);
        if (st == SC_OK)
            check_table(&t[k], 4, scale);
    }
    if (st == SC_OK) {
        sc_profile_import_params ip;
        sc_profile_import_defaults(&ip);
        ip.spacing_mm[0] = 0.5 * (((c0 >> 1) & 7) + 1);
        ip.spacing_mm[1] = 0.5 * (((c0 >> 4) & 7) + 1);
        ip.step_mm = c0 & 0x80 ? 0.5 : 0;
        ip.step_tolerance = c1 & 1 ? 0.45 : 0.1;
        const sc_table *const logs[2] = {&t[0], &t[1]};
        sc_profile_data d, back;
        double p0 = NAN;
        memset(&err, 0, sizeof err);
        st = sc_profile_import(&ip, logs, &d, &p0, &err);
        fuzz_check_error(st, &err);
        if (st == SC_OK) {
            FUZZ_CHECK(d.s_mm > 0 && isfinite(p0));
            for (int k = 0; k < 2; ++k) {
                /* gaps (SPEC §2a): at most half of the scan's samples missing */
                FUZZ_CHECK(d.d[k] >= 1 && d.n >= t[k].n_rows + d.d[k] &&
                           2 * t[k].n_rows >= d.n - d.d[k]);
                /* D is d whole steps within 1e-6 of D/s (the import's own rule, same rounding:
                 * |d·s - D| <= 1e-6·D, rounded differently, refused D/s = 76923.077 taken as
                 * 76923 steps of 13 nm, which is at the edge; regressions/) */
                double fd = ip.spacing_mm[k] / d.s_mm;
                FUZZ_CHECK(fabs(fd - d.d[k]) <= 1e-6 * fd);
            }
            for (int k = 1; k < 4; ++k)
                check_column(logs, &d, k);
            /* what `selfcal import profile` writes must be a valid selfcal-profile v1 file */
            char out[320];
            snprintf(out, sizeof out, "%s/imported.csv", fuzz_dir());
            memset(&err, 0, sizeof err);
            st = sc_profile_write(out, &d, &err);
            FUZZ_CHECK(st == SC_OK);
            memset(&back, 0, sizeof back);
            st = sc_profile_read(out, &back, &err);
            if (st != SC_OK)
                fprintf(stderr, "read back: %s:%ld: %s\n", err.file, err.line, err.msg);
            FUZZ_CHECK(st == SC_OK);
            FUZZ_CHECK(back.n == d.n && back.s_mm == d.s_mm && back.d[0] == d.d[0] &&
                       back.d[1] == d.d[1]);
            for (int k = 0; k < 2; ++k) {
                int m = d.n - d.d[k];
                FUZZ_CHECK(same_values(back.m1_um[k], d.m1_um[k], m) &&
                           same_values(back.m2_um[k], d.m2_um[k], m) &&
                           same_values(back.m3_urad[k], d.m3_urad[k], m));
            }
            sc_profile_data_free(&back);
            sc_profile_data_free(&d);
        }
    }
    sc_table_free(&t[0]);
    sc_table_free(&t[1]);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    uint8_t c0 = data[0], c1 = data[1];
    data += 2;
    size -= 2;
    if (c0 & 1)
        fuzz_profile(c0, c1, data, size);
    else
        fuzz_grid(c0, c1, fuzz_path(data, size));
    return 0;
}
