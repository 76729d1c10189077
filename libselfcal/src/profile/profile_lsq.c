/* profile_lsq.c — the two-set two-point straightness method by least squares (Ding §2.3), solved
 * through the banded structure of the normal matrix instead of the paper's dense O(N³) solve.
 *
 * Unknowns f(0..N-1), c1, c2. The normal matrix of the f-part is the weighted Laplacian of the
 * graph n ~ n+d1 (weight w1), n ~ n+d2 (weight w2): banded with half-width bw = max(d1, d2).
 * The 2-dimensional null space {f = a + b·n, c_k = -b·d_k} is removed by pinning f(0) = f(N-1) = 0
 * (rows/columns replaced by the identity, which keeps the band), the banded block B is factored
 * B = L·Lᵀ (Cholesky, row-band storage), the two border unknowns c1, c2 are eliminated by their
 * 2×2 Schur complement S, and the result is mapped to the least-squares-line gauge by projecting
 * out span{1, n}. The covariance's diagonal in that gauge comes from the banded factor's selected
 * inverse (Takahashi recurrences over a sliding window) plus the low-rank corrections from the
 * border and from the projection. The derivation is in docs/profile-lsq.md.
 */
#include "selfcal/profile_lsq.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "profile_lsq_kernels.h"

struct sc_profile_lsq {
    int n, d1, d2, bw;
    double w1, w2;
    size_t ld;      /* row stride of band: bw + 1 */
    double *band;   /* row i: L[i][i-bw .. i-1] at [0 .. bw-1], L[i][i] at [bw] */
    double *z;      /* 2 columns of n: Z = B⁻¹·E (the border columns c1, c2 through B) */
    double *e;      /* 2 columns of n: E, the f-c block of the normal matrix (pinned rows 0) */
    double g[2];    /* diagonal c-c block: w_k (n - d_k) */
    double sinv[4]; /* S⁻¹, S = G - Eᵀ Z (row-major 2×2) */
};

static int gcd_int(int a, int b)
{
    while (b) {
        int t = a % b;
        a = b;
        b = t;
    }
    return a;
}

int sc_profile_lsq_solvable(int n, int d1, int d2, sc_error *err)
{
    if (d1 < 1 || d2 < 1) {
        sc_error_set(err, SC_E_INPUT, NULL, 0,
                     "sensor spacings must be at least 1 sample (d1 = %d, d2 = %d)", d1, d2);
        return 0;
    }
    int g = gcd_int(d1, d2);
    if (g != 1) {
        sc_error_set(err, SC_E_INPUT, NULL, 0,
                     "d1 = %d and d2 = %d have the common divisor %d: the profile splits into %d "
                     "interleaved sub-profiles whose relative heights are not measured",
                     d1, d2, g, g);
        return 0;
    }
    if (n < 2 || (long)n < (long)d1 + d2) {
        sc_error_set(err, SC_E_INPUT, NULL, 0,
                     "N = %d is too small for d1 = %d, d2 = %d: least squares needs N >= d1 + d2 "
                     "= %ld (with fewer points the zero-point difference of the two scans is not "
                     "determined)",
                     n, d1, d2, (long)d1 + d2);
        return 0;
    }
    if (n > INT32_MAX / 2) {
        sc_error_set(err, SC_E_INPUT, NULL, 0, "N = %d is too large", n);
        return 0;
    }
    return 1;
}

/* Normal-matrix entry of the f-block (before pinning), j <= i, |i-j| <= bw. */
static double normal_ff(const sc_profile_lsq *p, int i, int j)
{
    int n = p->n;
    if (i == j) {
        double a = 0.0;
        if (i >= p->d1) a += p->w1;
        if (i <= n - 1 - p->d1) a += p->w1;
        if (i >= p->d2) a += p->w2;
        if (i <= n - 1 - p->d2) a += p->w2;
        return a;
    }
    int d = i - j;
    double a = 0.0;
    if (d == p->d1) a -= p->w1;
    if (d == p->d2) a -= p->w2;
    return a;
}

static int is_pinned(const sc_profile_lsq *p, int i) { return i == 0 || i == p->n - 1; }

/* Assemble row i of B (pinned rows/columns are the identity) into its band slot. */
static void assemble_row(const sc_profile_lsq *p, int i)
{
    int bw = p->bw;
    double *ri = p->band + (size_t)i * p->ld;
    for (int m = 0; m < bw; m++) ri[m] = 0.0;
    if (is_pinned(p, i)) {
        ri[bw] = 1.0;
        return;
    }
    if (i - p->d1 >= 0 && !is_pinned(p, i - p->d1)) ri[bw - p->d1] += -p->w1;
    if (i - p->d2 >= 0 && !is_pinned(p, i - p->d2)) ri[bw - p->d2] += -p->w2;
    ri[bw] = normal_ff(p, i, i);
}

/* Right-looking banded Cholesky B = L·Lᵀ in row-band storage: for column j, take the square root
 * of the (fully updated) pivot, scale the column below it, and subtract its outer product from
 * the trailing bw×bw triangle — row by row, each a contiguous axpy (independent, vectorizable).
 * Rows are assembled just before the first column that touches them, so the working window stays
 * in cache. The diagonal slot keeps 1/L[i][i] (every later use multiplies by it). */
static sc_status factor(sc_profile_lsq *p, sc_error *err)
{
    int n = p->n, bw = p->bw;
    size_t ld = p->ld;
    double *col = malloc((size_t)(bw + 1) * sizeof(double));
    if (!col) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (factor)");
    for (int i = 0; i <= bw && i < n; i++) assemble_row(p, i);
    for (int j = 0; j < n; j++) {
        if (j + bw < n && j > 0) assemble_row(p, j + bw);
        double *rj = p->band + (size_t)j * ld;
        double djj = rj[bw];
        if (!(djj > 0.0) || !isfinite(djj)) {
            free(col);
            return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                                "banded Cholesky factor lost positive definiteness at row %d", j);
        }
        double inv = 1.0 / sqrt(djj);
        rj[bw] = inv;
        int cnt = (j + bw < n - 1 ? j + bw : n - 1) - j;
        double *rk = rj + ld + (bw - 1); /* L[j+1][j] */
        for (int q = 0; q < cnt; q++, rk += ld - 1) {
            double v = *rk * inv;
            *rk = v;
            col[q] = v;
        }
        for (int q = 0; q < cnt; q++) {
            if (col[q] == 0.0) continue;
            double *rowk = p->band + (size_t)(j + 1 + q) * ld;
            /* row k = j+1+q, columns j+1..k: positions bw-q-... contiguous up to the diagonal */
            sc_lsq_axpy(rowk + (bw - q), -col[q], col, q + 1);
        }
    }
    free(col);
    return SC_OK;
}

/* x <- B⁻¹ x in place (and y <- B⁻¹ y when y is not NULL: two right-hand sides in one pass). */
static void band_solve2(const sc_profile_lsq *p, double *x, double *y)
{
    int n = p->n, bw = p->bw;
    for (int i = 0; i < n; i++) {
        const double *ri = p->band + (size_t)i * p->ld;
        int k0 = i - bw < 0 ? 0 : i - bw;
        x[i] = (x[i] - sc_lsq_dot(ri + (k0 - i + bw), x + k0, i - k0)) * ri[bw];
        if (y) y[i] = (y[i] - sc_lsq_dot(ri + (k0 - i + bw), y + k0, i - k0)) * ri[bw];
    }
    for (int i = n - 1; i >= 0; i--) {
        const double *ri = p->band + (size_t)i * p->ld;
        int k0 = i - bw < 0 ? 0 : i - bw;
        double xi = x[i] * ri[bw];
        x[i] = xi;
        sc_lsq_axpy(x + k0, -xi, ri + (k0 - i + bw), i - k0);
        if (y) {
            double yi = y[i] * ri[bw];
            y[i] = yi;
            sc_lsq_axpy(y + k0, -yi, ri + (k0 - i + bw), i - k0);
        }
    }
}

static void band_solve(const sc_profile_lsq *p, double *x) { band_solve2(p, x, NULL); }

sc_status sc_profile_lsq_create(int n, int d1, int d2, double w1, double w2, sc_profile_lsq **out,
                                sc_error *err)
{
    if (out) *out = NULL;
    if (!out) return sc_error_set(err, SC_E_INPUT, NULL, 0, "no output pointer");
    if (!sc_profile_lsq_solvable(n, d1, d2, err)) return SC_E_INPUT;
    if (!(w1 > 0.0) || !(w2 > 0.0) || !isfinite(w1) || !isfinite(w2))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "scan weights must be positive and finite (w1 = %g, w2 = %g)", w1, w2);
    sc_profile_lsq *p = calloc(1, sizeof *p);
    if (!p) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    p->n = n;
    p->d1 = d1;
    p->d2 = d2;
    p->bw = d1 > d2 ? d1 : d2;
    p->w1 = w1;
    p->w2 = w2;
    p->ld = (size_t)p->bw + 1;
    if ((size_t)n > SIZE_MAX / sizeof(double) / (p->ld + 4)) {
        int bw = p->bw;
        free(p);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "N = %d with d = %d needs too much memory",
                            n, bw);
    }
    p->band = malloc((size_t)n * p->ld * sizeof(double));
    p->z = malloc((size_t)2 * n * sizeof(double));
    p->e = malloc((size_t)2 * n * sizeof(double));
    if (!p->band || !p->z || !p->e) {
        int bw = p->bw;
        sc_profile_lsq_destroy(p);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0,
                            "out of memory for the banded factor (N = %d, d = %d: %.0f MB)", n,
                            bw, (double)n * (double)(bw + 1) * 8.0 / 1e6);
    }
    sc_status st = factor(p, err);
    if (st != SC_OK) {
        sc_profile_lsq_destroy(p);
        return st;
    }
    /* border: E column k = d(normal eq. of f)/d c_k; G = diag(w_k (n - d_k)) */
    const int dk[2] = {d1, d2};
    const double wk[2] = {w1, w2};
    for (int k = 0; k < 2; k++) {
        double *e = p->e + (size_t)k * n;
        for (int i = 0; i < n; i++) {
            double v = 0.0;
            if (!is_pinned(p, i)) {
                if (i >= dk[k]) v += wk[k];
                if (i <= n - 1 - dk[k]) v -= wk[k];
            }
            e[i] = v;
        }
        memcpy(p->z + (size_t)k * n, e, (size_t)n * sizeof(double));
        p->g[k] = wk[k] * (double)(n - dk[k]);
    }
    band_solve2(p, p->z, p->z + n);
    double s[4];
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            s[2 * a + b] = (a == b ? p->g[a] : 0.0) -
                           sc_lsq_dot(p->e + (size_t)a * n, p->z + (size_t)b * n, n);
    double sym = 0.5 * (s[1] + s[2]);
    s[1] = s[2] = sym;
    double det = s[0] * s[3] - s[1] * s[2];
    if (!(s[0] > 0.0) || !(det > 1e-14 * s[0] * s[3])) {
        sc_profile_lsq_destroy(p);
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                            "the zero-point offsets c1, c2 are numerically undetermined "
                            "(Schur complement det %g)", det);
    }
    p->sinv[0] = s[3] / det;
    p->sinv[3] = s[0] / det;
    p->sinv[1] = p->sinv[2] = -s[1] / det;
    *out = p;
    return SC_OK;
}

/* Least-squares line of v[0..n-1] over n: v = mean + slope·(i - (n-1)/2) + residual. */
static void ls_line(int n, const double *v, double *mean, double *slope)
{
    double nc = 0.5 * (double)(n - 1);
    double s0 = 0.0, s1 = 0.0, c0 = 0.0, c1 = 0.0; /* Kahan-compensated sums */
    for (int i = 0; i < n; i++) {
        double y = v[i] - c0;
        double t = s0 + y;
        c0 = (t - s0) - y;
        s0 = t;
        y = ((double)i - nc) * v[i] - c1;
        t = s1 + y;
        c1 = (t - s1) - y;
        s1 = t;
    }
    double sxx = (double)n * ((double)n * (double)n - 1.0) / 12.0;
    *mean = s0 / n;
    *slope = s1 / sxx;
}

sc_status sc_profile_lsq_solve(const sc_profile_lsq *p, const double *y1_um, const double *y2_um,
                               double *f_um, double *c_um, double *wrss, sc_error *err)
{
    if (!p || !y1_um || !y2_um || !f_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "missing argument");
    int n = p->n;
    const int dk[2] = {p->d1, p->d2};
    const double wk[2] = {p->w1, p->w2};
    const double *yk[2] = {y1_um, y2_um};
    /* right-hand side of the f-part in f_um, of the c-part in rc */
    double rc[2];
    for (int i = 0; i < n; i++) f_um[i] = 0.0;
    for (int k = 0; k < 2; k++) {
        int m = n - dk[k];
        double sum = 0.0;
        for (int j = 0; j < m; j++) {
            double y = yk[k][j];
            if (!isfinite(y)) {
                for (int i = 0; i < n; i++) f_um[i] = 0.0;
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "y%d(%d) is not a finite number", k + 1, j);
            }
            f_um[j + dk[k]] += wk[k] * y;
            f_um[j] -= wk[k] * y;
            sum += y;
        }
        rc[k] = wk[k] * sum;
    }
    f_um[0] = 0.0;
    f_um[n - 1] = 0.0;
    band_solve(p, f_um); /* u = B⁻¹ r_f */
    double t[2];
    for (int k = 0; k < 2; k++) t[k] = rc[k] - sc_lsq_dot(p->e + (size_t)k * n, f_um, n);
    double c[2] = {p->sinv[0] * t[0] + p->sinv[1] * t[1], p->sinv[2] * t[0] + p->sinv[3] * t[1]};
    const double *z1 = p->z, *z2 = p->z + n;
    for (int i = 0; i < n; i++) f_um[i] -= z1[i] * c[0] + z2[i] * c[1];
    /* to the least-squares-line gauge */
    double mean, slope;
    ls_line(n, f_um, &mean, &slope);
    double nc = 0.5 * (double)(n - 1);
    for (int i = 0; i < n; i++) f_um[i] -= mean + slope * ((double)i - nc);
    c[0] += slope * dk[0];
    c[1] += slope * dk[1];
    if (c_um) {
        c_um[0] = c[0];
        c_um[1] = c[1];
    }
    if (wrss) {
        double s = 0.0;
        for (int k = 0; k < 2; k++) {
            int m = n - dk[k];
            double sk = 0.0;
            for (int j = 0; j < m; j++) {
                double r = yk[k][j] - (f_um[j + dk[k]] - f_um[j] + c[k]);
                sk += r * r;
            }
            s += wk[k] * sk;
        }
        *wrss = s;
    }
    return SC_OK;
}

/* diag(B⁻¹) by the Takahashi recurrences on the banded Cholesky factor, i = n-1 down to 0:
 *   Z[i][j] = -(1/L[i][i]) Σ_{k=i+1}^{i+bw} L[k][i] Z[k][j]   (j = i+1 .. i+bw)
 *   Z[i][i] = (1/L[i][i]) (1/L[i][i] - Σ_k L[k][i] Z[k][i])
 * keeping only the (bw+1)×(bw+1) window of Z that the next step needs, in a circular buffer. */
static sc_status selected_inverse_diag(const sc_profile_lsq *p, double *diag, sc_error *err)
{
    int n = p->n, bw = p->bw;
    size_t w = (size_t)bw + 1;
    double *win = calloc(w * w + 2 * w, sizeof(double));
    if (!win) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (selected inverse)");
    double *t = win + w * w; /* accumulator over all w slots */
    double *l = t + w;       /* column i of L below the diagonal, l[k - i - 1] */
    for (int i = n - 1; i >= 0; i--) {
        const double rii = p->band[(size_t)i * p->ld + bw]; /* 1/L[i][i] */
        int kmax = i + bw < n - 1 ? i + bw : n - 1;
        int cnt = kmax - i;
        for (int q = 0; q < cnt; q++) {
            int k = i + 1 + q;
            l[q] = p->band[(size_t)k * p->ld + (size_t)(i - k + bw)];
        }
        for (size_t s = 0; s < w; s++) t[s] = 0.0;
        int q = 0;
        for (; q + 4 <= cnt; q += 4) {
            int k = i + 1 + q;
            sc_lsq_axpy4(t, l + q, win + (size_t)(k % (int)w) * w,
                         win + (size_t)((k + 1) % (int)w) * w, win + (size_t)((k + 2) % (int)w) * w,
                         win + (size_t)((k + 3) % (int)w) * w, (int)w);
        }
        for (; q < cnt; q++) {
            int k = i + 1 + q;
            sc_lsq_axpy(t, l[q], win + (size_t)(k % (int)w) * w, (int)w);
        }
        size_t si = (size_t)(i % (int)w);
        double *row_i = win + si * w;
        double acc = 0.0;
        for (int q = 0; q < cnt; q++) {
            int k = i + 1 + q;
            size_t sk = (size_t)(k % (int)w);
            double zik = -t[sk] * rii;
            row_i[sk] = zik;
            win[sk * w + si] = zik;
            acc += l[q] * zik;
        }
        double zii = (rii - acc) * rii;
        row_i[si] = zii;
        diag[i] = zii;
    }
    free(win);
    return SC_OK;
}

sc_status sc_profile_lsq_uncertainty(const sc_profile_lsq *p, double *uf_um, sc_error *err)
{
    if (!p || !uf_um) return sc_error_set(err, SC_E_INPUT, NULL, 0, "missing argument");
    int n = p->n;
    double *cu = malloc((size_t)2 * n * sizeof(double));
    if (!cu) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (uncertainty)");
    sc_status st = selected_inverse_diag(p, uf_um, err);
    if (st != SC_OK) {
        free(cu);
        return st;
    }
    /* C = B⁻¹ (pinned entries 0) + Z S⁻¹ Zᵀ: the pinned-gauge covariance of f */
    const double *z1 = p->z, *z2 = p->z + n;
    const double *si = p->sinv;
    uf_um[0] = 0.0;
    uf_um[n - 1] = 0.0;
    for (int i = 0; i < n; i++)
        uf_um[i] += z1[i] * (si[0] * z1[i] + si[1] * z2[i]) +
                    z2[i] * (si[2] * z1[i] + si[3] * z2[i]);
    /* orthonormal basis of span{1, n}: u1 = 1/√N, u2 = (i - nc)/√sxx */
    double nc = 0.5 * (double)(n - 1);
    double sxx = (double)n * ((double)n * (double)n - 1.0) / 12.0;
    double a1 = 1.0 / sqrt((double)n), a2 = 1.0 / sqrt(sxx);
    double *cu1 = cu, *cu2 = cu + n;
    for (int i = 0; i < n; i++) {
        int pin = is_pinned(p, i);
        cu1[i] = pin ? 0.0 : a1;
        cu2[i] = pin ? 0.0 : a2 * ((double)i - nc);
    }
    band_solve2(p, cu1, cu2);
    /* + Z S⁻¹ (Zᵀ U) */
    double ztu[4]; /* ztu[2a+b] = z_a · u_b */
    double s01 = 0, s11 = 0, s02 = 0, s12 = 0;
    for (int i = 0; i < n; i++) {
        double u2 = a2 * ((double)i - nc);
        s01 += z1[i];
        s11 += z1[i] * u2;
        s02 += z2[i];
        s12 += z2[i] * u2;
    }
    ztu[0] = a1 * s01;
    ztu[1] = s11;
    ztu[2] = a1 * s02;
    ztu[3] = s12;
    double m[4]; /* S⁻¹ (Zᵀ U): m[2a+b] */
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++) m[2 * a + b] = si[2 * a] * ztu[b] + si[2 * a + 1] * ztu[2 + b];
    for (int i = 0; i < n; i++) {
        cu1[i] += z1[i] * m[0] + z2[i] * m[2];
        cu2[i] += z1[i] * m[1] + z2[i] * m[3];
    }
    /* Q = Uᵀ C U */
    double q11 = 0, q12 = 0, q21 = 0, q22 = 0;
    for (int i = 0; i < n; i++) {
        double u2 = a2 * ((double)i - nc);
        q11 += a1 * cu1[i];
        q12 += a1 * cu2[i];
        q21 += u2 * cu1[i];
        q22 += u2 * cu2[i];
    }
    double q12s = 0.5 * (q12 + q21);
    /* diag(P C P) = diag(C) - 2 diag(U (CU)ᵀ) + diag(U Q Uᵀ) */
    for (int i = 0; i < n; i++) {
        double u2 = a2 * ((double)i - nc);
        double v = uf_um[i] - 2.0 * (a1 * cu1[i] + u2 * cu2[i]) + a1 * a1 * q11 +
                   2.0 * a1 * u2 * q12s + u2 * u2 * q22;
        uf_um[i] = v > 0.0 ? sqrt(v) : 0.0;
    }
    free(cu);
    return SC_OK;
}

void sc_profile_lsq_destroy(sc_profile_lsq *p)
{
    if (!p) return;
    free(p->band);
    free(p->z);
    free(p->e);
    free(p);
}
