/* The exact grid self-calibration methods — Ye et al. (views 0°, 90°, +1) and Petrò's double
 * shift (views 0°, 90°, +2, -3 partial) — in Petrò's matrix formulation with the centred DFT
 * W M W of his eq. (23), computed with FFTW. The method-specific step (the wrap-around columns
 * of H) is in grid_ye.c and grid_double_shift.c; the derivation is in docs/grid-exact.md.
 */
#include "../common/fft_planner.h"
#include "grid_exact_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define IDX(i, j) ((i) * n + (j))

static const char *method_name(sc_grid_exact_method m)
{
    return m == SC_GRID_YE ? "Ye's method" : "the double-shift method";
}

/* The views of each method, by role: the one place they are written down. */
static const sc_grid_view_need needs_ye[3] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 1, 0, 0}};
static const sc_grid_view_need needs_ds[4] = {
    {0, 0, 0, 0}, {90, 0, 0, 0}, {0, 2, 0, 0}, {0, -3, 0, 1}};

int sc_grid_exact_needs(sc_grid_exact_method m, sc_grid_view_need need[4])
{
    int k = m == SC_GRID_YE ? 3 : 4;
    memcpy(need, m == SC_GRID_YE ? needs_ye : needs_ds, (size_t)k * sizeof *need);
    return k;
}

int sc_grid_exact_min_n(sc_grid_exact_method m)
{
    return m == SC_GRID_YE ? 3 : 7;
}

bool sc_grid_exact_uses_mark(sc_grid_exact_method m, int n, int r, int i, int j)
{
    sc_grid_view_need need[4];
    int k = sc_grid_exact_needs(m, need), c = (n - 1) / 2;
    if (r < 0 || r >= k)
        return false;
    int sx = need[r].shift_x;
    if (j + sx < 0 || j + sx > n - 1) /* lands off the grid (rot 0 views shift along x) */
        return false;
    return !need[r].partial || i == c || j == c || j == c + 1;
}

void sc_grid_exact_plan_destroy(sc_grid_exact_plan *p)
{
    if (!p)
        return;
    sc_fft_planner_lock();
    if (p->fwd)
        fftw_destroy_plan(p->fwd);
    if (p->bwd)
        fftw_destroy_plan(p->bwd);
    sc_fft_planner_unlock();
    fftw_free(p->buf);
    fftw_free(p->sp);
    fftw_free(p->sq);
    fftw_free(p->shx);
    fftw_free(p->shy);
    fftw_free(p->phx);
    fftw_free(p->phy);
    double **arrays[] = {&p->w, &p->mu_re, &p->mu_im, &p->u0x, &p->u0y, &p->u1x, &p->u1y,
                         &p->P, &p->Q, &p->ex, &p->ey, &p->hx, &p->hy, &p->fx, &p->fy, &p->gx,
                         &p->gy, &p->ax, &p->ay, &p->bx, &p->by, &p->crow_x, &p->crow_y};
    for (size_t k = 0; k < sizeof arrays / sizeof arrays[0]; ++k)
        free(*arrays[k]);
    free(p);
}

sc_status sc_grid_exact_plan_create(sc_grid_exact_method m, int n, sc_grid_exact_plan **out,
                                    sc_error *err)
{
    if (!out)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "exact grid plan: no output pointer");
    *out = NULL;
    if (m != SC_GRID_YE && m != SC_GRID_DOUBLE_SHIFT)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "unknown exact grid method %d", (int)m);
    int nmin = sc_grid_exact_min_n(m);
    if (n % 2 == 0 || n < nmin || n > SC_GRID_MAX_N)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "%s needs an odd N with %d <= N <= %d (got N = %d)", method_name(m),
                            nmin, SC_GRID_MAX_N, n);

    sc_grid_exact_plan *p = calloc(1, sizeof *p);
    if (!p)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "exact grid plan: out of memory");
    p->method = m;
    p->n = n;
    p->c = (n - 1) / 2;
    p->shift = (m == SC_GRID_YE ? needs_ye : needs_ds)[2].shift_x; /* the +shift view */
    size_t nn = (size_t)n * (size_t)n;

    int ok = 1;
    double **vec[] = {&p->w, &p->mu_re, &p->mu_im, &p->crow_x, &p->crow_y};
    for (size_t k = 0; k < sizeof vec / sizeof vec[0]; ++k)
        ok &= (*vec[k] = calloc((size_t)n, sizeof(double))) != NULL;
    double **mat[] = {&p->u0x, &p->u0y, &p->u1x, &p->u1y, &p->P, &p->Q, &p->ex, &p->ey, &p->hx,
                      &p->hy, &p->fx, &p->fy, &p->gx, &p->gy, &p->ax, &p->ay, &p->bx, &p->by};
    for (size_t k = 0; k < sizeof mat / sizeof mat[0]; ++k)
        ok &= (*mat[k] = calloc(nn, sizeof(double))) != NULL;
    fftw_complex **spec[] = {&p->buf, &p->sp, &p->sq, &p->shx, &p->shy, &p->phx, &p->phy};
    for (size_t k = 0; k < sizeof spec / sizeof spec[0]; ++k)
        ok &= (*spec[k] = fftw_malloc(nn * sizeof(fftw_complex))) != NULL;
    if (!ok) {
        sc_grid_exact_plan_destroy(p);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "exact grid plan: out of memory (N = %d)", n);
    }
    sc_fft_planner_lock();
    p->fwd = fftw_plan_dft_2d(n, n, p->buf, p->buf, FFTW_FORWARD, FFTW_ESTIMATE);
    p->bwd = fftw_plan_dft_2d(n, n, p->buf, p->buf, FFTW_BACKWARD, FFTW_ESTIMATE);
    sc_fft_planner_unlock();
    if (!p->fwd || !p->bwd) {
        sc_grid_exact_plan_destroy(p);
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "exact grid plan: FFTW planning failed");
    }

    /* Summation-by-parts weights (docs §4): w_k = w_{k-s} - (k - c), w_{<0} = 0, k <= N-1-s;
     * the identity also needs w_{k-s} = k - c for k > N-1-s, which holds for s = 1, 2, N odd. */
    int s = p->shift, c = p->c;
    p->w_sum = p->w_xsum = 0;
    for (int k = 0; k <= n - 1 - s; ++k) {
        p->w[k] = (k >= s ? p->w[k - s] : 0.0) - (k - c);
        p->w_sum += p->w[k];
        p->w_xsum += p->w[k] * (k - c);
    }
    for (int k = n - s; k < n; ++k)
        if (p->w[k - s] != (double)(k - c)) {
            sc_grid_exact_plan_destroy(p);
            return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                                "exact grid plan: inconsistent summation weights");
        }
    for (int k = 0; k < n; ++k) {
        double phi = 2.0 * M_PI * s * (k - c) / n;
        p->mu_re[k] = cos(phi) - 1.0;
        p->mu_im[k] = sin(phi);
    }
    p->mu_re[c] = p->mu_im[c] = 0.0;
    *out = p;
    return SC_OK;
}

/* ---- the centred DFT of eq. (23): out = W M W (with W's 1/N factors), centred indices ---- */

static void dft_centred(sc_grid_exact_plan *p, const double *m, fftw_complex *out)
{
    int n = p->n, c = p->c;
    double scale = 1.0 / ((double)n * n);
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
            int k = ((a + c + 1) % n) * n + (b + c + 1) % n;
            p->buf[k][0] = m[IDX(a, b)];
            p->buf[k][1] = 0.0;
        }
    fftw_execute(p->fwd);
    for (int h = 0; h < n; ++h)
        for (int k = 0; k < n; ++k) {
            int q = ((h + c + 1) % n) * n + (k + c + 1) % n;
            out[IDX(h, k)][0] = p->buf[q][0] * scale;
            out[IDX(h, k)][1] = p->buf[q][1] * scale;
        }
}

/* Inverse of dft_centred: m = real part of N^2 S W phi W S. */
static void idft_centred(sc_grid_exact_plan *p, const fftw_complex *phi, double *m)
{
    int n = p->n, c = p->c;
    for (int h = 0; h < n; ++h)
        for (int k = 0; k < n; ++k) {
            int q = ((h + c + 1) % n) * n + (k + c + 1) % n;
            p->buf[q][0] = phi[IDX(h, k)][0];
            p->buf[q][1] = phi[IDX(h, k)][1];
        }
    fftw_execute(p->bwd);
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b)
            m[IDX(a, b)] = p->buf[((a + c + 1) % n) * n + (b + c + 1) % n][0];
}

/* ---- input checks ---- */

static int mark_used(const sc_grid_exact_plan *p, int r, int i, int j)
{
    return sc_grid_exact_uses_mark(p->method, p->n, r, i, j);
}

static sc_status find_views(const sc_grid_exact_plan *p, const sc_grid_data *d, int *views,
                            sc_error *err)
{
    int n = p->n, c = p->c;
    sc_grid_view_need need[4];
    int nroles = sc_grid_exact_needs(p->method, need);
    for (int r = 0; r < nroles; ++r) {
        int sx = need[r].shift_x, rot = need[r].rot_deg;
        int v = sc_grid_find_view(&d->plan, rot, sx, need[r].shift_y);
        if (v < 0) {
            if (need[r].partial)
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "%s needs view %d: rot=0 shift=%d,0 measuring plate row %d "
                                    "and columns %d,%d; the plan has no such view",
                                    method_name(p->method), r, sx, c, c, c + 1);
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "%s needs view %d: rot=%d shift=%d,0; the plan has no such view",
                                method_name(p->method), r, rot, sx);
        }
        views[r] = v;
        const double *dx = d->dx_um[v], *dy = d->dy_um[v];
        long missing = 0, needed = 0;
        int fi = -1, fj = -1;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                if (!mark_used(p, r, i, j))
                    continue;
                ++needed;
                if (dx && dy && isfinite(dx[IDX(i, j)]) && isfinite(dy[IDX(i, j)]))
                    continue;
                if (missing++ == 0) {
                    fi = i;
                    fj = j;
                }
            }
        if (missing) {
            const char *what = need[r].partial
                                   ? "plate row %d and columns %d,%d (marks landing on the grid)"
                                   : "every mark that lands on the stage grid";
            char need[160];
            snprintf(need, sizeof need, what, c, c, c + 1);
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "view %d (rot=%d shift=%d,0) lacks %ld of the %ld marks %s needs "
                                "(first: mark i=%d j=%d); it must measure %s",
                                v, rot, sx, missing, needed, method_name(p->method), fi,
                                fj, need);
        }
    }
    return SC_OK;
}

/* ---- step 1: views 0 and 1 (Petrò §4.1-4.2.2, eqs. 11-21, 33, 37) ---- */

static void views_0_1(sc_grid_exact_plan *p, sc_grid_exact_run *x)
{
    int n = p->n, c = p->c;
    double s0x = 0, s0y = 0, s1x = 0, s1y = 0, r0 = 0, r1 = 0, den = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int k = IDX(i, j);
            double X = j - c, Y = i - c;
            s0x += x->v0x[k];
            s0y += x->v0y[k];
            s1x += x->v1x[k];
            s1y += x->v1y[k];
            r0 += X * x->v0y[k] - Y * x->v0x[k];
            r1 += X * x->v1x[k] + Y * x->v1y[k];
            den += X * X + Y * Y;
        }
    double nn = (double)n * n;
    double t0x = s0x / nn, t0y = s0y / nn, t1x = s1x / nn, t1y = s1y / nn;
    double th0 = r0 / den, th1 = -r1 / den; /* eqs. 12, 15 */
    double so = 0, sr = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int k = IDX(i, j);
            double X = j - c, Y = i - c;
            p->u0x[k] = x->v0x[k] - t0x + th0 * Y; /* eq. 16 */
            p->u0y[k] = x->v0y[k] - t0y - th0 * X;
            p->u1x[k] = x->v1x[k] - t1x + th1 * X; /* eq. 17 */
            p->u1y[k] = x->v1y[k] - t1y + th1 * Y;
            double a = p->u0x[k] - p->u1y[k], b = p->u0y[k] + p->u1x[k]; /* eq. 18 */
            so += X * b + Y * a;
            sr += X * a - Y * b;
        }
    x->O = so / (2 * den); /* eq. 19 */
    x->R = sr / (2 * den); /* eq. 20 */
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int k = IDX(i, j);
            double X = j - c, Y = i - c;
            p->P[k] = p->u0x[k] - p->u1y[k] - 2 * x->O * Y - 2 * x->R * X; /* eq. 21 */
            p->Q[k] = p->u0y[k] + p->u1x[k] - 2 * x->O * X + 2 * x->R * Y;
        }
    /* even parts: Fx + S Fx S = P + S Q^T (33), Fy + S Fy S = Q - S P^T (37) */
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int k = IDX(i, j), t = IDX(j, n - 1 - i);
            p->ex[k] = 0.5 * (p->P[k] + p->Q[t]);
            p->ey[k] = 0.5 * (p->Q[k] - p->P[t]);
        }
}

/* ---- step 2: view 2, its misalignment and H (eqs. 30-40, re-derived: docs §4) ---- */

static void view_2(sc_grid_exact_plan *p, const sc_grid_exact_run *x)
{
    int n = p->n, c = p->c, s = p->shift, last = n - 1 - s;
    /* D2 = V2 - U0 on the measured columns; kept in hx, hy until H is formed */
    for (int i = 0; i < n; ++i)
        for (int j = 0; j <= last; ++j) {
            int k = IDX(i, j);
            p->hx[k] = x->v2x[k] - p->u0x[k];
            p->hy[k] = x->v2y[k] - p->u0y[k];
        }
    /* rotation (eqs. 36, 38): D(i,j) - D(N-1-i, N-1-s-j) involves only the even part of F */
    double sab = 0, saa = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j <= last; ++j) {
            int k = IDX(i, j), kr = IDX(n - 1 - i, last - j);
            double ax = i - c;
            double bx = (p->ex[k + s] - p->ex[k]) - 0.5 * (p->hx[k] - p->hx[kr]);
            double ay = (j - c) + 0.5 * s;
            double by = 0.5 * (p->hy[k] - p->hy[kr]) - (p->ey[k + s] - p->ey[k]);
            sab += ax * bx + ay * by;
            saa += ax * ax + ay * ay;
        }
    double th = sab / saa;
    /* translations (eqs. 32, 39): sum_j w_j H(i,j) = sum_j X(j) F(i,j), which sums to 0 */
    double swx = 0, swy = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j <= last; ++j) {
            swx += p->w[j] * p->hx[IDX(i, j)];
            swy += p->w[j] * p->hy[IDX(i, j)];
        }
    double kx = swx / (n * p->w_sum);
    double ky = (swy - th * n * p->w_xsum) / (n * p->w_sum);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j <= last; ++j) {
            int k = IDX(i, j);
            p->hx[k] += -kx + th * (i - c); /* H = F(T_s - I), eq. 40 */
            p->hy[k] += -ky - th * (j - c);
        }
}

/* ---- step 3: the spectra of Fx, Fy (eqs. 27, 28, 54, 55) and F ---- */

static void assemble_f(sc_grid_exact_plan *p)
{
    int n = p->n;
    dft_centred(p, p->P, p->sp);
    dft_centred(p, p->Q, p->sq);
    dft_centred(p, p->hx, p->shx);
    dft_centred(p, p->hy, p->shy);
    const double *mr = p->mu_re, *mi = p->mu_im;
    for (int h = 0; h < n; ++h)
        for (int k = 0; k < n; ++k) {
            int q = IDX(h, k);            /* Fx index */
            int t = IDX(n - 1 - k, h);    /* (W Q W)^T S at (h,k) = sq[N-1-k][h] */
            int qy = IDX(k, n - 1 - h);   /* the Fy index (28) ties to (h,k) */
            /* real parts, eq. (27) */
            double rex = 0.5 * (p->sp[q][0] + p->sq[t][0]);
            double rey = 0.5 * (p->sq[qy][0] - p->sp[IDX(h, k)][0]);
            /* eq. (28): Im X(h,k) - Im Y(k, N-1-h) = jhk */
            double jhk = 0.5 * (p->sp[q][1] + p->sq[t][1]);
            /* eq. (55), both ways: from H_x at column k, and from H_y at column N-1-h via (28);
             * weighted by 1/|Z|^2 = |mu|^2 (the paper's advice to use the smaller |Z|) */
            double w1 = mr[k] * mr[k] + mi[k] * mi[k];
            double w2 = mr[n - 1 - h] * mr[n - 1 - h] + mi[n - 1 - h] * mi[n - 1 - h];
            double u = 0;
            if (w1 + w2 > 0) {
                double e1 = 0, e2 = 0;
                if (w1 > 0) /* Im(Hx / mu) */
                    e1 = (p->shx[q][1] * mr[k] - p->shx[q][0] * mi[k]) / w1;
                if (w2 > 0) {
                    int kk = n - 1 - h;
                    e2 = jhk + (p->shy[qy][1] * mr[kk] - p->shy[qy][0] * mi[kk]) / w2;
                }
                u = (w1 * e1 + w2 * e2) / (w1 + w2);
            }
            p->phx[q][0] = rex;
            p->phx[q][1] = u;
            p->phy[qy][0] = rey;
            p->phy[qy][1] = u - jhk;
        }
    idft_centred(p, p->phx, p->fx);
    idft_centred(p, p->phy, p->fy);
}

/* ---- final: G, A in the SPEC gauge, misalignments, residuals ---- */

/* Least-squares (tx, ty, θ) of view v from G and A over its measured marks (only those the
 * method uses if the view has role r >= 0); returns the number of marks used. */
static long fit_view(const sc_grid_exact_plan *p, const sc_grid_plan *pl, const sc_grid_data *d,
                     int v, int r, const double *gx, const double *gy, const double *ax,
                     const double *ay, double *tx, double *ty, double *th_urad)
{
    int n = pl->n;
    double m = 0, sx = 0, sy = 0, sr = 0, bx = 0, by = 0, bt = 0;
    *tx = *ty = *th_urad = NAN;
    if (!d->dx_um[v] || !d->dy_um[v])
        return 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int ni, nj, k = IDX(i, j);
            if (!sc_grid_mark_node(pl, v, i, j, &ni, &nj) || (r >= 0 && !mark_used(p, r, i, j)))
                continue;
            double dx = d->dx_um[v][k], dy = d->dy_um[v][k];
            if (!isfinite(dx) || !isfinite(dy))
                continue;
            double x, y, rax, ray;
            sc_grid_node_xy_mm(pl, ni, nj, &x, &y);
            sc_grid_rotate(pl->view[v].rot_deg, ax[k], ay[k], &rax, &ray);
            double ex = dx - gx[IDX(ni, nj)] - rax, ey = dy - gy[IDX(ni, nj)] - ray;
            m += 1;
            sx += x;
            sy += y;
            sr += x * x + y * y;
            bx += ex;
            by += ey;
            bt += x * ey - y * ex;
        }
    if (m < 1)
        return 0;
    /* normal equations [m 0 -sy; 0 m sx; -sy sx sr] [tx ty θ'] = [bx by bt], θ' in µm/mm */
    double den = m * sr - sx * sx - sy * sy;
    if (m >= 2 && den > 1e-12 * m * sr) {
        double thp = (m * bt + sy * bx - sx * by) / den;
        *th_urad = thp * 1e3;
        *tx = (bx + sy * thp) / m;
        *ty = (by - sx * thp) / m;
    } else {
        *tx = bx / m;
        *ty = by / m;
        *th_urad = 0.0;
    }
    return (long)m;
}

/* G = O Y + R X + F (eq. 6) and A from views 0 and 1 (eqs. 10, 13), in the SPEC gauge. */
static void finish_g_and_a(sc_grid_exact_plan *p, const sc_grid_exact_run *x,
                           const sc_grid_plan *pl)
{
    const int n = p->n, c = p->c;
    const size_t nn = (size_t)n * n;
    /* G, then the SPEC gauge (a no-op without noise) */
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int k = IDX(i, j);
            p->gx[k] = x->O * (i - c) + x->R * (j - c) + p->fx[k];
            p->gy[k] = x->O * (j - c) - x->R * (i - c) + p->fy[k];
        }
    sc_grid_gauge_stage(pl, p->gx, p->gy);
    /* A from view 0 and from view 1 (eqs. 10, 13), each without translation and rotation,
     * averaged */
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int k = IDX(i, j), t = IDX(j, n - 1 - i);
            p->ax[k] = x->v0x[k] - p->gx[k];
            p->ay[k] = x->v0y[k] - p->gy[k];
            p->bx[k] = x->v1y[k] - p->gy[t];
            p->by[k] = -(x->v1x[k] - p->gx[t]);
        }
    sc_grid_gauge_plate(pl, p->ax, p->ay);
    sc_grid_gauge_plate(pl, p->bx, p->by);
    for (size_t k = 0; k < nn; ++k) {
        p->ax[k] = 0.5 * (p->ax[k] + p->bx[k]);
        p->ay[k] = 0.5 * (p->ay[k] + p->by[k]);
    }
}

/* The residuals over the marks the method used: their sum of squares, *nm components. */
static double finish_residuals(const sc_grid_exact_plan *p, const sc_grid_data *d,
                               const int *views, int nroles, const sc_grid_result *res, long *nm_out)
{
    const int n = p->n;
    const sc_grid_plan *pl = &d->plan;
    double ss = 0;
    long nm = 0;
    for (int r = 0; r < nroles; ++r) {
        int v = views[r];
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                int ni, nj, k = IDX(i, j);
                if (!mark_used(p, r, i, j) || !sc_grid_mark_node(pl, v, i, j, &ni, &nj))
                    continue;
                double x, y, rax, ray;
                sc_grid_node_xy_mm(pl, ni, nj, &x, &y);
                sc_grid_rotate(pl->view[v].rot_deg, p->ax[k], p->ay[k], &rax, &ray);
                double th = res->theta_urad[v] * 1e-3;
                double mx = p->gx[IDX(ni, nj)] + rax + res->tx_um[v] - th * y;
                double my = p->gy[IDX(ni, nj)] + ray + res->ty_um[v] + th * x;
                double rx = d->dx_um[v][k] - mx, ry = d->dy_um[v][k] - my;
                ss += rx * rx + ry * ry;
                nm += 2;
            }
    }
    *nm_out = nm;
    return ss;
}

static void finish(sc_grid_exact_plan *p, const sc_grid_exact_run *x, const sc_grid_data *d,
                   const int *views, int nroles, sc_grid_result *res)
{
    int n = p->n;
    const sc_grid_plan *pl = &d->plan;
    size_t nn = (size_t)n * n;
    finish_g_and_a(p, x, pl);
    /* misalignment of every view with data (used or not; used views over the marks used) */
    for (int v = 0; v < pl->n_views; ++v) {
        res->tx_um[v] = res->ty_um[v] = res->theta_urad[v] = NAN;
        int role = -1;
        for (int r = 0; r < nroles; ++r)
            if (views[r] == v)
                role = r;
        fit_view(p, pl, d, v, role, p->gx, p->gy, p->ax, p->ay, &res->tx_um[v], &res->ty_um[v],
                 &res->theta_urad[v]);
    }
    long nm;
    double ss = finish_residuals(p, d, views, nroles, res, &nm);
    res->n_measurements = nm;
    long params = 4L * n * n + 3L * nroles - 7;
    res->dof = nm - params;
    res->residual_rms_um = nm > 0 ? sqrt(ss / nm) : NAN;
    res->sigma_r_est_um = NAN;  /* exact methods: the residual is not a least-squares one */
    res->sigma_r_used_um = NAN;
    sc_grid_first_order(pl, p->gx, p->gy, &res->O, &res->R);
    double *outs[] = {res->gx_um, res->gy_um, res->ax_um, res->ay_um};
    const double *ins[] = {p->gx, p->gy, p->ax, p->ay};
    for (int a = 0; a < 4; ++a)
        if (outs[a])
            memcpy(outs[a], ins[a], nn * sizeof(double));
    for (size_t k = 0; k < nn; ++k) {
        if (res->ugx_um)
            res->ugx_um[k] = NAN;
        if (res->ugy_um)
            res->ugy_um[k] = NAN;
    }
}

sc_status sc_grid_exact_execute(sc_grid_exact_plan *p, const sc_grid_data *d, sc_grid_result *res,
                                sc_error *err)
{
    if (!p || !d || !res || !d->dx_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "exact grid method: missing argument");
    if (!res->tx_um || !res->ty_um || !res->theta_urad)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "exact grid method: the result's tx_um, ty_um and theta_urad (one "
                            "per view) are required (sc_grid_result_views)");
    sc_status st = sc_grid_plan_check(&d->plan, err);
    if (st != SC_OK)
        return st;
    if (d->plan.n != p->n)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "%s: the data have N = %d but the plan was made for N = %d",
                            method_name(p->method), d->plan.n, p->n);
    int views[4] = {-1, -1, -1, -1};
    st = find_views(p, d, views, err);
    if (st != SC_OK)
        return st;
    sc_grid_exact_run x = {d->dx_um[views[0]], d->dy_um[views[0]], d->dx_um[views[1]],
                           d->dy_um[views[1]], d->dx_um[views[2]], d->dy_um[views[2]],
                           NULL, NULL, 0, 0};
    if (p->method == SC_GRID_DOUBLE_SHIFT) {
        x.v3x = d->dx_um[views[3]];
        x.v3y = d->dy_um[views[3]];
    }
    views_0_1(p, &x);
    view_2(p, &x);
    if (p->method == SC_GRID_YE)
        sc_grid_ye_complete_h(p);
    else
        sc_grid_ds_complete_h(p, &x);
    assemble_f(p);
    sc_grid_view_need need[4];
    finish(p, &x, d, views, sc_grid_exact_needs(p->method, need), res);
    for (size_t k = 0; k < (size_t)p->n * p->n; ++k)
        if (!isfinite(p->gx[k]) || !isfinite(p->gy[k]))
            return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                                "%s: the result is not finite", method_name(p->method));
    return SC_OK;
}
