/* grid_import.c — owns the numbering of a view's measured points (SPEC §10): the robust fit of
 * the view's placement and the assignment of each point to its plate mark (algorithm in
 * selfcal/import.h and docs/import.md). */
#include "selfcal/import.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"

#define MAX_ITERATIONS 50

void sc_grid_import_defaults(sc_grid_import_params *p, int n, double pitch_mm)
{
    memset(p, 0, sizeof *p);
    p->n = n;
    p->pitch_mm = pitch_mm;
    p->tolerance_mm = pitch_mm / 4;
    p->min_share = 0.5;
}

sc_status sc_grid_import_check(const sc_grid_import_params *p, sc_error *err)
{
    if (p->n < 3 || p->n > SC_GRID_MAX_N || p->n % 2 == 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "N must be odd and in 3..%d, got %d",
                            SC_GRID_MAX_N, p->n);
    if (!(p->pitch_mm >= SC_GRID_MIN_PITCH_MM) || !(p->pitch_mm <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the pitch must be %g to %g mm, got %g",
                            SC_GRID_MIN_PITCH_MM, SC_INPUT_MAX_ABS, p->pitch_mm);
    if (!(fabs(p->origin_mm[0]) <= SC_INPUT_MAX_ABS && fabs(p->origin_mm[1]) <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the origin is beyond any stage");
    int nx = p->stage_nx, ny = p->stage_ny;
    if ((nx || ny) && (nx < 3 || ny < 3 || nx % 2 == 0 || ny % 2 == 0 || nx > SC_GRID_MAX_N * 4 ||
                       ny > SC_GRID_MAX_N * 4))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the stage must be odd and >= 3 nodes each way, got %d,%d", nx, ny);
    if (!(p->tolerance_mm > 0 && p->tolerance_mm < p->pitch_mm / 2))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the tolerance must be positive and below half a pitch (%g mm), got %g mm",
                            p->pitch_mm / 2, p->tolerance_mm);
    if (!(p->min_share >= 0 && p->min_share <= 1))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the share of marks must be in 0..1");
    return SC_OK;
}

size_t sc_grid_import_work_doubles(long n_points)
{
    /* the distances, a median's copy, the points left out as far */
    return (size_t)(n_points > 0 ? 3 * n_points : 1);
}

bool sc_grid_import_mark_node(const sc_grid_import_params *p, const sc_grid_view *v, int i, int j,
                              int *ni, int *nj)
{
    int c = (p->n - 1) / 2;
    int nx = p->stage_nx ? p->stage_nx : p->n, ny = p->stage_ny ? p->stage_ny : p->n;
    int px = j - c, py = i - c, sx, sy;
    switch (v->rot_deg) {
    case 90: sx = -py, sy = px; break;
    case 180: sx = -px, sy = -py; break;
    case 270: sx = py, sy = -px; break;
    default: sx = px, sy = py; break;
    }
    long jj = (long)sx + v->shift_x + (nx - 1) / 2, ii = (long)sy + v->shift_y + (ny - 1) / 2;
    if (ii < 0 || ii >= ny || jj < 0 || jj >= nx)
        return false;
    if (v->restricted && !v->row_sel[i] && !v->col_sel[j])
        return false;
    *ni = (int)ii;
    *nj = (int)jj;
    return true;
}

/* The placement: measured = origin + t + Rot(theta)·(nominal − origin). */
typedef struct placement {
    double tx, ty, c, s; /* mm; cos and sin of theta */
} placement;

/* Nominal position (relative to the origin, mm) of mark (i, j) in view v. */
static void mark_nominal(const sc_grid_import_params *p, const sc_grid_view *v, int i, int j,
                         double *x, double *y)
{
    double c = (p->n - 1) / 2.0, P = p->pitch_mm;
    sc_grid_rotate(v->rot_deg, (j - c) * P, (i - c) * P, x, y);
    *x += v->shift_x * P;
    *y += v->shift_y * P;
}

/* Point (x, y) (absolute, mm) in plate coordinates (fractional mark row fi, column fj) under
 * placement a of view v. */
static void plate_coords(const sc_grid_import_params *p, const sc_grid_view *v, const placement *a,
                         double x, double y, double *fi, double *fj)
{
    double rx = x - p->origin_mm[0] - a->tx, ry = y - p->origin_mm[1] - a->ty;
    double sx = a->c * rx + a->s * ry, sy = -a->s * rx + a->c * ry; /* undo theta */
    sx -= v->shift_x * p->pitch_mm;
    sy -= v->shift_y * p->pitch_mm;
    double px, py;
    sc_grid_rotate((360 - v->rot_deg) % 360, sx, sy, &px, &py); /* undo rot */
    double c = (p->n - 1) / 2.0;
    *fj = px / p->pitch_mm + c, *fi = py / p->pitch_mm + c;
}

/* Whether point (x, y) lies within T of a position of the view's mark lattice (whole plate
 * coordinates, on the plate or beyond it): a point left out there is no dust but a mark the view
 * does not have, as a file in the plate's frame gives them (a shifted view seen unshifted). */
static bool on_the_lattice(const sc_grid_import_params *p, const sc_grid_view *v,
                           const placement *a, double x, double y)
{
    double fi, fj;
    plate_coords(p, v, a, x, y, &fi, &fj);
    return fabs(fj) < 1e9 && fabs(fi) < 1e9 &&
           hypot(fj - round(fj), fi - round(fi)) * p->pitch_mm <= p->tolerance_mm;
}

/* The mark nearest to point (x, y) (absolute, mm) under placement a, its distance (mm), or -1 if
 * the nearest lattice position is not a mark the view measures. */
static long nearest_mark(const sc_grid_import_params *p, const sc_grid_view *v,
                         const placement *a, double x, double y, double *dist)
{
    double fi, fj;
    plate_coords(p, v, a, x, y, &fi, &fj);
    if (!(fabs(fj) < 1e9 && fabs(fi) < 1e9))
        return -1;
    long j = lround(fj), i = lround(fi);
    int ni, nj;
    if (i < 0 || j < 0 || i >= p->n || j >= p->n ||
        !sc_grid_import_mark_node(p, v, (int)i, (int)j, &ni, &nj))
        return -1;
    *dist = hypot(fj - j, fi - i) * p->pitch_mm;
    return i * p->n + j;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, long n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Match every point under a (gate in mm); fills point_mark, mark_point (closer point wins);
 * returns how many point assignments changed. */
static long match(const sc_grid_import_params *p, const sc_grid_view *v, const placement *a,
                  double gate, long n_points, const double *x, const double *y, long *point_mark,
                  long *mark_point, double *dist)
{
    long nn = (long)p->n * p->n, changed = 0;
    for (long m = 0; m < nn; ++m)
        mark_point[m] = -1;
    for (long k = 0; k < n_points; ++k) {
        double d = 0;
        long m = nearest_mark(p, v, a, x[k], y[k], &d);
        if (m >= 0 && d > gate)
            m = -1;
        if (m != point_mark[k])
            ++changed;
        point_mark[k] = m;
        dist[k] = d;
        if (m < 0)
            continue;
        long other = mark_point[m];
        if (other < 0 || d < dist[other])
            mark_point[m] = k;
    }
    return changed;
}

/* Mark m's point *k and the mark's nominal position (mm): false when no point is assigned. */
static bool matched_mark(const sc_grid_import_params *p, const sc_grid_view *v,
                         const long *mark_point, long m, long *k, double *nx, double *ny)
{
    *k = mark_point[m];
    if (*k < 0)
        return false;
    mark_nominal(p, v, (int)(m / p->n), (int)(m % p->n), nx, ny);
    return true;
}

/* Least-squares rigid placement from the pairs point k <-> mark_point (one point per mark). */
static void fit_rigid(const sc_grid_import_params *p, const sc_grid_view *v, long n_points,
                      const double *x, const double *y, const long *mark_point, placement *a)
{
    long nn = (long)p->n * p->n, cnt = 0;
    double mx = 0, my = 0, qx = 0, qy = 0;
    for (long m = 0; m < nn; ++m) {
        long k;
        double nx, ny;
        if (!matched_mark(p, v, mark_point, m, &k, &nx, &ny) || k >= n_points)
            continue;
        mx += nx, my += ny;
        qx += x[k] - p->origin_mm[0], qy += y[k] - p->origin_mm[1];
        ++cnt;
    }
    if (cnt == 0)
        return;
    mx /= cnt, my /= cnt, qx /= cnt, qy /= cnt;
    double sdot = 0, scross = 0;
    for (long m = 0; m < nn; ++m) {
        long k;
        double nx, ny;
        if (!matched_mark(p, v, mark_point, m, &k, &nx, &ny))
            continue;
        double ax = nx - mx, ay = ny - my;
        double bx = x[k] - p->origin_mm[0] - qx, by = y[k] - p->origin_mm[1] - qy;
        sdot += ax * bx + ay * by;
        scross += ax * by - ay * bx;
    }
    double th = cnt >= 2 && (sdot != 0 || scross != 0) ? atan2(scross, sdot) : 0;
    a->c = cos(th);
    a->s = sin(th);
    a->tx = qx - (a->c * mx - a->s * my);
    a->ty = qy - (a->s * mx + a->c * my);
}

/* Step 1 after the nominal matching: the translation is the median offset of the matched
 * points from their marks (robust to wrong points). The offsets are built in work, which the
 * next match overwrites. */
static void median_translation(const sc_grid_import_params *p, const sc_grid_view *v,
                               const double *x_mm, const double *y_mm, const long *mark_point,
                               double *work, placement *a)
{
    long nn = (long)p->n * p->n;
    for (int axis = 0; axis < 2; ++axis) {
        long c2 = 0;
        for (long m = 0; m < nn; ++m) {
            long k;
            double nx, ny;
            if (!matched_mark(p, v, mark_point, m, &k, &nx, &ny))
                continue;
            work[c2++] = axis == 0 ? x_mm[k] - p->origin_mm[0] - nx
                                   : y_mm[k] - p->origin_mm[1] - ny;
        }
        if (c2 == 0)
            return;
        double med = median(work, c2);
        if (axis == 0)
            a->tx = med;
        else
            a->ty = med;
    }
}

#define FAR_FACTOR 20.0  /* a point this many times the median distance from its mark ... */
#define FAR_FLOOR_T 0.2  /* ... and at least this share of the tolerance T from it is no
                            measurement of that mark */

/* After the final matching: a point whose distance to its mark is more than FAR_FACTOR times the
 * median distance of the view's points (and FAR_FLOOR_T of T) is left out (point_mark -2, its
 * mark without a point): a point measured on the wrong feature, a summary row not recognised as
 * one. A plate's own errors and the stage's are alike from mark to mark; such a point is not.
 * Needs 5 matched points for the median; tmp: n_points doubles. Returns how many it left out. */
static long leave_out_far(const sc_grid_import_params *p, long n_points, long *point_mark,
                          long *mark_point, const double *dist, double *tmp,
                          sc_grid_import_fit *fit)
{
    long n = 0, far = 0;
    for (long k = 0; k < n_points; ++k)
        if (point_mark[k] >= 0)
            tmp[n++] = dist[k];
    if (n < 5)
        return 0;
    double med = median(tmp, n), gate = fmax(FAR_FACTOR * med, FAR_FLOOR_T * p->tolerance_mm);
    for (long k = 0; k < n_points; ++k)
        if (point_mark[k] >= 0 && dist[k] > gate) {
            if (mark_point[point_mark[k]] == k)
                mark_point[point_mark[k]] = -1;
            point_mark[k] = -2;
            ++far;
        }
    fit->median_dist_um = med * 1e3;
    return far;
}

/* Step 3, after the final matching at T: a mark claimed by two points is bad input (the later
 * line is named); the others are counted as assigned or left out. */
/* The likely cause of two points on one mark, as a clause for the message ("" if none shows):
 * points spread over less than a pitch are deviations, not positions (they all fall on the
 * mark at the origin); half as many points again as the view has marks are two views in one
 * file. */
static const char *collision_cause(const sc_grid_import_params *p, long n_points,
                                   const double *x_mm, const double *y_mm, long n_marks,
                                   char *buf, size_t cap)
{
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (long k = 0; k < n_points; ++k) {
        lo[0] = fmin(lo[0], x_mm[k]);
        hi[0] = fmax(hi[0], x_mm[k]);
        lo[1] = fmin(lo[1], y_mm[k]);
        hi[1] = fmax(hi[1], y_mm[k]);
    }
    buf[0] = '\0';
    if (n_points >= 3 && hi[0] - lo[0] < p->pitch_mm && hi[1] - lo[1] < p->pitch_mm)
        snprintf(buf, cap, "; the %ld points spread over only %.4g x %.4g mm, less than a pitch: "
                           "deviations rather than positions? (--deviations with the nominal "
                           "columns)", n_points, hi[0] - lo[0], hi[1] - lo[1]);
    else if (2 * n_points >= 3 * n_marks) /* two views: about twice as many */
        snprintf(buf, cap, "; the file has %ld points for the view's %ld marks: two views in one "
                           "file? (--where COL=VALUE reads one)", n_points, n_marks);
    return buf;
}

static sc_status count_assignment(const sc_grid_import_params *p, long n_points,
                                  const long *lines, const char *path, const long *point_mark,
                                  const long *mark_point, const double *dist,
                                  const double *x_mm, const double *y_mm,
                                  sc_grid_import_fit *fit, sc_error *err)
{
    for (long k = 0; k < n_points; ++k) {
        long m = point_mark[k];
        if (m < 0) {
            ++fit->n_left_out;
            continue;
        }
        long other = mark_point[m];
        if (other < 0) { /* its mark went to no one (a far point held it): left out */
            ++fit->n_left_out;
            continue;
        }
        if (other != k) {
            long first = lines[k] < lines[other] ? k : other, second = first == k ? other : k;
            char cause[256];
            collision_cause(p, n_points, x_mm, y_mm, fit->n_marks, cause, sizeof cause);
            return sc_error_set(err, SC_E_INPUT, path, lines[second],
                                "this point and the point on line %ld both fall on mark (%ld,%ld) "
                                "(within %g mm): %s", lines[first], m / p->n, m % p->n,
                                p->tolerance_mm, cause[0] ? cause + 2
                                : "a stray point or a mark measured twice");
        }
        ++fit->n_assigned;
        if (dist[k] * 1e3 > fit->max_dist_um)
            fit->max_dist_um = dist[k] * 1e3;
    }
    return SC_OK;
}

/* The marks view v puts on the stage (fit->n_marks): none is an error. */
static sc_status count_marks(const sc_grid_import_params *p, const sc_grid_view *v,
                             const char *path, sc_grid_import_fit *fit, sc_error *err)
{
    for (int i = 0; i < p->n; ++i)
        for (int j = 0; j < p->n; ++j) {
            int ni, nj;
            fit->n_marks += sc_grid_import_mark_node(p, v, i, j, &ni, &nj);
        }
    if (fit->n_marks == 0)
        return sc_error_set(err, SC_E_INPUT, path, 0,
                            "the view (rot=%d shift=%d,%d) puts no mark on the stage",
                            v->rot_deg, v->shift_x, v->shift_y);
    return SC_OK;
}

/* Steps 1 and 2 of the placement: the nominal one with gate P/2 and the median translation, then
 * the rigid placement refitted on the matched pairs and matched again (gate P/2 once, then T)
 * until nothing changes; the iterations it took. */
static int place_view(const sc_grid_import_params *p, const sc_grid_view *v, placement *a,
                      long n_points, const double *x_mm, const double *y_mm, long *point_mark,
                      long *mark_point, double *work)
{
    double *dist = work, gate = p->pitch_mm / 2;
    match(p, v, a, gate, n_points, x_mm, y_mm, point_mark, mark_point, dist);
    median_translation(p, v, x_mm, y_mm, mark_point, work, a);
    int it = 0;
    for (; it < MAX_ITERATIONS; ++it) {
        long changed = match(p, v, a, gate, n_points, x_mm, y_mm, point_mark, mark_point, dist);
        if (it >= 2 && changed == 0)
            break;
        fit_rigid(p, v, n_points, x_mm, y_mm, mark_point, a);
        gate = p->tolerance_mm;
    }
    return it;
}

/* The points far beyond the others left out (they stay out), the placement fitted again without
 * them (they pulled it) and matched again, until no more go (5 rounds at most). */
static void drop_far_points(const sc_grid_import_params *p, const sc_grid_view *v, placement *a,
                            long n_points, const double *x_mm, const double *y_mm,
                            long *point_mark, long *mark_point, double *work,
                            sc_grid_import_fit *fit)
{
    double *dist = work, *far_out = work + 2 * n_points; /* 1: left out as far (stays out) */
    for (long k = 0; k < n_points; ++k)
        far_out[k] = 0;
    for (int round = 0; round < 5; ++round) {
        long far = leave_out_far(p, n_points, point_mark, mark_point, dist, work + n_points, fit);
        if (far == 0)
            break;
        fit->n_far += far;
        for (long k = 0; k < n_points; ++k)
            if (point_mark[k] == -2)
                far_out[k] = 1;
        fit_rigid(p, v, n_points, x_mm, y_mm, mark_point, a);
        match(p, v, a, p->tolerance_mm, n_points, x_mm, y_mm, point_mark, mark_point, dist);
        for (long k = 0; k < n_points; ++k) /* those left out stay out */
            if (far_out[k] != 0) {
                if (point_mark[k] >= 0 && mark_point[point_mark[k]] == k)
                    mark_point[point_mark[k]] = -1;
                point_mark[k] = -2;
            }
        for (long k = 0; k < n_points; ++k) { /* a mark a far point held: its nearest other */
            long m = point_mark[k];
            if (m >= 0 && (mark_point[m] < 0 || dist[k] < dist[mark_point[m]]))
                mark_point[m] = k;
        }
    }
}

/* The points left out that still lie on the lattice (counted), and those on marks the view's
 * rows=/cols= leave out (-3, not strays). */
static void mark_off_view_points(const sc_grid_import_params *p, const sc_grid_view *v,
                                 const placement *a, long n_points, const double *x_mm,
                                 const double *y_mm, long *point_mark, sc_grid_import_fit *fit)
{
    for (long k = 0; k < n_points; ++k) /* left out, yet on the lattice */
        if (point_mark[k] == -1 && on_the_lattice(p, v, a, x_mm[k], y_mm[k]))
            fit->n_on_lattice++;
    if (!v->restricted)
        return;
    sc_grid_view all = *v;
    all.restricted = 0;
    for (long k = 0; k < n_points; ++k) {
        double d;
        if (point_mark[k] == -1 && nearest_mark(p, &all, a, x_mm[k], y_mm[k], &d) >= 0 &&
            d <= p->tolerance_mm) {
            point_mark[k] = -3;
            fit->n_unselected++;
        }
    }
}

/* Too few points fell on a mark: the error says where the points are against where the view's
 * marks should be (a frame or unit mistake shows there). */
static sc_status too_few_on_marks(const sc_grid_import_params *p, const sc_grid_view *v,
                                  long n_points, const double *x_mm, const double *y_mm,
                                  const char *path, long header_line,
                                  const sc_grid_import_fit *fit, sc_error *err)
{
    double px = 0, py = 0, mx = 0, my = 0;
    for (long k = 0; k < n_points; ++k)
        px += x_mm[k] / (double)n_points, py += y_mm[k] / (double)n_points;
    for (int i = 0; i < p->n; ++i)
        for (int j = 0; j < p->n; ++j) {
            int ni, nj;
            double nx, ny;
            if (!sc_grid_import_mark_node(p, v, i, j, &ni, &nj))
                continue;
            mark_nominal(p, v, i, j, &nx, &ny); /* relative to the origin */
            mx += (nx + p->origin_mm[0]) / (double)fit->n_marks;
            my += (ny + p->origin_mm[1]) / (double)fit->n_marks;
        }
    return sc_error_set(err, SC_E_INPUT, path, header_line,
                        "only %ld of the %ld points lie within %g mm of a mark of view rot=%d "
                        "shift=%d,%d (at least %.0f %% needed): wrong --view, --units or "
                        "columns? The points' centre is at (%.4f, %.4f) mm, the view's marks' "
                        "at (%.4f, %.4f) mm (another frame? --origin-mm)",
                        fit->n_assigned + fit->n_unselected, n_points, p->tolerance_mm,
                        v->rot_deg, v->shift_x, v->shift_y, p->min_share * 100, px, py, mx, my);
}

sc_status sc_grid_import_assign(const sc_grid_import_params *p, const sc_grid_view *v,
                                long n_points, const double *x_mm, const double *y_mm,
                                const long *lines, const char *path, long header_line,
                                long *point_mark, long *mark_point, sc_grid_import_fit *fit,
                                double *work, sc_error *err)
{
    sc_status st = sc_grid_import_check(p, err);
    if (st != SC_OK)
        return st;
    memset(fit, 0, sizeof *fit);
    if ((st = count_marks(p, v, path, fit, err)) != SC_OK)
        return st;
    for (long k = 0; k < n_points; ++k)
        point_mark[k] = -2;
    placement a = {0, 0, 1, 0};
    double *dist = work;
    /* 1, 2: the placement; 3: final matching at T, then the points far beyond the others out */
    fit->iterations = place_view(p, v, &a, n_points, x_mm, y_mm, point_mark, mark_point, work);
    match(p, v, &a, p->tolerance_mm, n_points, x_mm, y_mm, point_mark, mark_point, dist);
    drop_far_points(p, v, &a, n_points, x_mm, y_mm, point_mark, mark_point, work, fit);
    mark_off_view_points(p, v, &a, n_points, x_mm, y_mm, point_mark, fit);
    st = count_assignment(p, n_points, lines, path, point_mark, mark_point, dist, x_mm, y_mm, fit,
                          err);
    if (st != SC_OK)
        return st;
    fit->tx_um = a.tx * 1e3;
    fit->ty_um = a.ty * 1e3;
    fit->theta_urad = atan2(a.s, a.c) * 1e6;
    /* A view may measure few of its marks (a partial view, a damaged plate: SPEC §10, marks
     * without a point are absent); a file whose points mostly fall on no mark is the wrong
     * file, view, units or columns. */
    if (fit->n_assigned == 0 ||
        (double)(fit->n_assigned + fit->n_unselected) < p->min_share * (double)n_points)
        return too_few_on_marks(p, v, n_points, x_mm, y_mm, path, header_line, fit, err);
    return SC_OK;
}
