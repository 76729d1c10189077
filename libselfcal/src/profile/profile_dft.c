/* The two-set two-point method by the DFT (Ding et al. §2.2), with its exact per-point
 * uncertainty in O(N log N). Derivation and notation: docs/profile.md, section "DFT method".
 *
 * In sample units (s = 1): scan k sees h_k(n) = f(n) + a_k·n with a_k = c_k/d_k, because
 * y_k(n) = h_k(n + d_k) - h_k(n). The natural extension x_k(N-d_k+r) = -sum_{j=0}^{M_k-2}
 * y_k(r + j·d_k) (M_k = N/d_k) makes x_k the periodic difference of h_k, so with X_k = DFT(x_k)
 * and E_k(q) = exp(+2πi·d_k·q/N) - 1:  Y_k(q) = X_k(q)/E_k(q) = F(q) + a_k·Z(q) where E_k ≠ 0,
 * Z(q) = DFT(n)(q) = N/(exp(-2πi·q/N) - 1). Var Y_k(q) = σ_k²·N/(2 sin²(π d_k q/N)) = δ_k(q).
 */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "../common/fft_planner.h"
#include "selfcal/profile.h"
#include "selfcal/profile_dft.h"

struct sc_profile_dft_plan {
    int n, d[2], nh;
    double w[2];
    double *rbuf;               /* N reals (FFTW buffer) */
    fftw_complex *cbuf;         /* N/2+1 complex (FFTW buffer) */
    fftw_plan r2c, c2r;
    double complex *alpha[2];   /* F(q) = alpha1·X1 + alpha2·X2 + a12·zeta */
    double complex *zeta;
    double complex *beta[2];    /* a12 = Re sum_q beta1·X1 - Re sum_q beta2·X2 (half spectrum) */
    double complex *x1;         /* workspace: X1 */
};

static long gcd_l(long a, long b)
{
    while (b) {
        long t = a % b;
        a = b;
        b = t;
    }
    return a < 0 ? -a : a;
}

bool sc_profile_dft_is_usable(int n, int d1, int d2, sc_error *err)
{
    if (d1 < 1 || d2 < 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "sensor spacings must be >= 1 (d1 = %d, d2 = %d)", d1, d2),
               false;
    if (d1 == d2)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "d1 = d2 = %d: the DFT method combines two different spacings (the "
                            "lsq method takes d1 = d2 = 1)",
                            d1),
               false;
    if (gcd_l(d1, d2) != 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "d1 = %d and d2 = %d are not coprime (gcd = %ld): the harmonics that both "
                            "scans lose cannot be recovered",
                            d1, d2, gcd_l(d1, d2)),
               false;
    long prod = (long)d1 * d2;
    if (n < 2 * (d1 > d2 ? d1 : d2) || n % prod != 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "N = %d is not a multiple of d1*d2 = %ld (the DFT method needs N = p*d1*d2; "
                            "nearest: %ld; the lsq method has no such restriction)",
                            n, prod, prod * (n / prod < 1 ? 1 : (n % prod) * 2 >= prod ? n / prod + 1 : n / prod)),
               false;
    return true;
}

/* The natural extension of y (n - d values) to a full period x (n values). */
static void extend(int n, int d, const double *y, double *x)
{
    int m = n - d;
    memcpy(x, y, (size_t)m * sizeof(double));
    for (int r = 0; r < d; ++r) {
        double s = 0;
        for (int i = r; i < m; i += d)
            s += y[i];
        x[m + r] = -s;
    }
}

/* The plan's spectral weights alpha, zeta, beta (eqs. 8, 9), from its N, d_k and w_k. */
static sc_status spectral_weights(sc_profile_dft_plan *p, sc_error *err)
{
    const int n = p->n;
    /* spectral weights (eqs. 8, 9 with the scans' own noise variances 1/w_k). Every
     * trigonometric value comes from one table H(j) = exp(iπj/N), j <= N/2 (kept in the x1
     * workspace until the first solve): sin(πr/N) = Im H(r), exp(2πir/N) - 1 = 2i·sin(πr/N)·H(r)
     * (no cancellation for small r), H(N - r) = -conj(H(r)). */
    double complex *H = p->x1;
    for (int j = 0; j < p->nh; ++j)
        H[j] = cexp(I * M_PI * (double)j / n);
    const double var[2] = {1.0 / p->w[0], 1.0 / p->w[1]};
    double wsum = 0;
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 1) {
            if (!(wsum > 0)) {
                return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0, "no harmonic seen by both scans");
            }
            p->alpha[0][0] = p->alpha[1][0] = p->zeta[0] = p->beta[0][0] = p->beta[1][0] = 0;
        }
        for (int q = 1; q < p->nh; ++q) {
            int ok[2];
            double delta[2];
            double complex e[2];
            for (int k = 0; k < 2; ++k) {
                long long r = ((long long)p->d[k] * q) % n;
                double complex h = 2 * r <= n ? H[r] : -conj(H[n - r]);
                double sn = cimag(h);
                ok[k] = r != 0;
                delta[k] = ok[k] ? var[k] * n / (2.0 * sn * sn) : INFINITY;
                e[k] = 2.0 * I * sn * h; /* exp(2πi·d_k·q/N) - 1 */
            }
            /* Z(q) = N/(exp(-2πiq/N) - 1) = N / conj(2i·sin(πq/N)·H(q)) */
            double complex z = n / conj(2.0 * I * cimag(H[q]) * H[q]);
            double z2 = creal(z * conj(z));
            double mult = (2 * q == n) ? 1.0 : 2.0;
            if (pass == 0) {
                if (ok[0] && ok[1])
                    wsum += mult * z2 / (delta[0] + delta[1]);
                continue;
            }
            double w1q = ok[0] ? 1.0 / delta[0] : 0.0;
            double w2q = ok[1] ? 1.0 / (delta[1] + z2 / wsum) : 0.0;
            double ws = w1q + w2q; /* > 0: every q is seen by one scan at least (gcd = 1, N = p·d1·d2) */
            p->alpha[0][q] = ok[0] ? w1q / (ws * e[0]) : 0;
            p->alpha[1][q] = ok[1] ? w2q / (ws * e[1]) : 0;
            p->zeta[q] = w2q * z / ws;
            if (ok[0] && ok[1]) {
                double wa = z2 / (delta[0] + delta[1]);
                double complex b = mult * wa / (wsum * z);
                p->beta[0][q] = b / e[0];
                p->beta[1][q] = b / e[1];
            } else {
                p->beta[0][q] = p->beta[1][q] = 0;
            }
        }
    }
    return SC_OK;
}

sc_status sc_profile_dft_plan_create(int n, int d1, int d2, double w1, double w2,
                                     sc_profile_dft_plan **out, sc_error *err)
{
    *out = NULL;
    if (!sc_profile_dft_is_usable(n, d1, d2, err))
        return SC_E_INPUT;
    if (!(w1 > 0) || !(w2 > 0) || !isfinite(w1) || !isfinite(w2))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "scan weights must be positive (w1 = %g, w2 = %g)", w1, w2);
    sc_profile_dft_plan *p = calloc(1, sizeof *p);
    if (!p)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    p->n = n;
    p->d[0] = d1;
    p->d[1] = d2;
    p->w[0] = w1;
    p->w[1] = w2;
    p->nh = n / 2 + 1;
    size_t nh = (size_t)p->nh;
    p->rbuf = fftw_alloc_real((size_t)n);
    p->cbuf = fftw_alloc_complex(nh);
    p->zeta = malloc(nh * sizeof(double complex));
    p->x1 = malloc(nh * sizeof(double complex));
    for (int k = 0; k < 2; ++k) {
        p->alpha[k] = malloc(nh * sizeof(double complex));
        p->beta[k] = malloc(nh * sizeof(double complex));
    }
    if (!p->rbuf || !p->cbuf || !p->zeta || !p->x1 || !p->alpha[0] || !p->alpha[1] || !p->beta[0] ||
        !p->beta[1]) {
        sc_profile_dft_plan_destroy(p);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    }
    sc_fft_planner_lock();
    p->r2c = fftw_plan_dft_r2c_1d(n, p->rbuf, p->cbuf, FFTW_ESTIMATE);
    p->c2r = fftw_plan_dft_c2r_1d(n, p->cbuf, p->rbuf, FFTW_ESTIMATE);
    sc_fft_planner_unlock();
    if (!p->r2c || !p->c2r) {
        sc_profile_dft_plan_destroy(p);
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "FFTW could not plan size %d", n);
    }
    sc_status st = spectral_weights(p, err);
    if (st != SC_OK) {
        sc_profile_dft_plan_destroy(p);
        return st;
    }
    *out = p;
    return SC_OK;
}

/* x (N values, any real sequence) -> p->cbuf = DFT(x). */
static void forward(sc_profile_dft_plan *p, const double *x)
{
    memcpy(p->rbuf, x, (size_t)p->n * sizeof(double));
    fftw_execute(p->r2c);
}

/* The estimator before the removal of the line: y1, y2 -> f_raw (N values) with mean 0. */
static void solve_raw(sc_profile_dft_plan *p, const double *y1, const double *y2, double *f)
{
    int n = p->n, nh = p->nh;
    double complex *c = (double complex *)p->cbuf;
    extend(n, p->d[0], y1, p->rbuf);
    fftw_execute(p->r2c);
    memcpy(p->x1, c, (size_t)nh * sizeof(double complex));
    extend(n, p->d[1], y2, p->rbuf);
    fftw_execute(p->r2c);
    double a12 = 0;
    for (int q = 1; q < nh; ++q)
        a12 += creal(p->beta[0][q] * p->x1[q]) - creal(p->beta[1][q] * c[q]);
    c[0] = 0;
    for (int q = 1; q < nh; ++q)
        c[q] = p->alpha[0][q] * p->x1[q] + p->alpha[1][q] * c[q] + a12 * p->zeta[q];
    if (n % 2 == 0)
        c[nh - 1] = creal(c[nh - 1]);
    fftw_execute(p->c2r);
    for (int i = 0; i < n; ++i)
        f[i] = p->rbuf[i] / n;
}

sc_status sc_profile_dft_execute(sc_profile_dft_plan *p, const double *y1_um, const double *y2_um,
                                 double *f_um, sc_error *err)
{
    const double *yk[2] = {y1_um, y2_um};
    const int dk[2] = {p->d[0], p->d[1]};
    for (int k = 0; k < 2; ++k) /* as least squares: a NaN would spread over the whole spectrum */
        for (int j = 0; j < p->n - dk[k]; ++j)
            if (!isfinite(yk[k][j])) {
                for (int i = 0; i < p->n; ++i)
                    f_um[i] = 0.0;
                return sc_error_set(err, SC_E_INPUT, NULL, 0, "y%d(%d) is not a finite number",
                                    k + 1, j);
            }
    solve_raw(p, y1_um, y2_um, f_um);
    sc_profile_remove_line(p->n, f_um);
    return SC_OK;
}

/* out = IDFT(spec) (N reals) for a half spectrum spec (Hermitian). */
static void inverse(sc_profile_dft_plan *p, const double complex *spec, double *out)
{
    double complex *c = (double complex *)p->cbuf;
    memcpy(c, spec, (size_t)p->nh * sizeof(double complex));
    c[0] = creal(c[0]);
    if (p->n % 2 == 0)
        c[p->nh - 1] = creal(c[p->nh - 1]);
    fftw_execute(p->c2r);
    for (int i = 0; i < p->n; ++i)
        out[i] = p->rbuf[i] / p->n;
}

/* out = h ⊛ u (circular convolution, N values); H = DFT(h) given. */
static void convolve(sc_profile_dft_plan *p, const double complex *H, const double *u, double *out,
                     double complex *tmp)
{
    forward(p, u);
    const double complex *c = (const double complex *)p->cbuf;
    for (int q = 0; q < p->nh; ++q)
        tmp[q] = H[q] * c[q];
    inverse(p, tmp, out);
}

/* Reals of the uncertainty's workspace: 10 arrays of N, 2 prefix arrays of 2N+1, d sums (even,
 * so that the 3 half spectra after them stay aligned as double complex). */
static size_t work_reals(const sc_profile_dft_plan *p)
{
    const int dmax = p->d[0] > p->d[1] ? p->d[0] : p->d[1];
    size_t nreal = 10 * (size_t)p->n + 2 * (2 * (size_t)p->n + 1) + (size_t)dmax;
    return (nreal + 1) & ~(size_t)1;
}

size_t sc_profile_dft_work_size(const sc_profile_dft_plan *p)
{
    return p ? work_reals(p) + 3 * 2 * (size_t)p->nh : 0;
}

/* The uncertainty's workspace, cut from the caller's (or an own) block. */
typedef struct {
    double *h, *v, *g, *u, *psi, *t1, *t2, *gam, *b, *var, *pre, *pre2, *csum;
    double complex *tmp, *Psi, *Hs;
    double tc;   /* the centre of the abscissae, (N - 1) / 2 */
    double psiv; /* psi · v */
} dft_unc_work;

static void unc_work_split(const sc_profile_dft_plan *p, double *work, dft_unc_work *w)
{
    const int n = p->n, nh = p->nh;
    w->h = work;
    w->v = w->h + n;
    w->g = w->v + n;
    w->u = w->g + n;
    w->psi = w->u + n;
    w->t1 = w->psi + n;
    w->t2 = w->t1 + n;
    w->gam = w->t2 + n;
    w->b = w->gam + n;
    w->var = w->b + n;
    w->pre = w->var + n;
    w->pre2 = w->pre + 2 * n + 1;
    w->csum = w->pre2 + 2 * n + 1;
    w->tmp = (double complex *)(work + work_reals(p));
    w->Psi = w->tmp + nh;
    w->Hs = w->Psi + nh;
}

/* psi(n) = t_n / sum t², the slope functional of the least-squares line (the estimator's
 * output has mean 0 already: its zero-frequency coefficient is 0); v = IDFT(zeta). */
static void unc_slope_functional(sc_profile_dft_plan *p, dft_unc_work *w)
{
    const int n = p->n;
    double tss = 0;
    w->tc = 0.5 * (n - 1);
    for (int i = 0; i < n; ++i)
        tss += (i - w->tc) * (i - w->tc);
    for (int i = 0; i < n; ++i)
        w->psi[i] = (i - w->tc) / tss;
    forward(p, w->psi);
    memcpy(w->Psi, p->cbuf, (size_t)p->nh * sizeof(double complex));
    inverse(p, p->zeta, w->v);
    w->psiv = 0;
    for (int i = 0; i < n; ++i)
        w->psiv += w->psi[i] * w->v[i];
}

/* Scan k: h = IDFT(alpha_k), the convolution kernel of its extended data (and its DFT Hs);
 * gamma(m) = Re sum_q beta_k(q) e^{-2πi q m/N}, so that a12 = sum_m x_k(m)·gamma(m); and
 * g_i = gamma(i) - gamma(e(i)), e(i) = N - d + (i mod d), a12's weight of y_k(i). Returns |g|². */
static double unc_scan_weights(sc_profile_dft_plan *p, int k, dft_unc_work *w)
{
    const int n = p->n, nh = p->nh, d = p->d[k], m = n - d;
    const double sgn = k == 0 ? 1.0 : -1.0;
    inverse(p, p->alpha[k], w->h);
    forward(p, w->h);
    memcpy(w->Hs, p->cbuf, (size_t)nh * sizeof(double complex));
    for (int q = 0; q < nh; ++q)
        w->tmp[q] = conj(p->beta[k][q]) / ((q == 0 || 2 * q == n) ? 1.0 : 2.0);
    inverse(p, w->tmp, w->gam);
    for (int i = 0; i < n; ++i)
        w->gam[i] *= n * sgn;
    double g2 = 0;
    for (int i = 0; i < m; ++i) {
        w->g[i] = w->gam[i] - w->gam[m + i % d];
        g2 += w->g[i] * w->g[i];
    }
    return g2;
}

/* t1(n) = Q(n) = sum_i R(n,i)² = A + B + v²|g|² - 2 Cx + 2 v (E - F), with cyclic windows:
 * A(n) = sum_{i<m} h(n-i)², B(n) = (M-1) sum_{j=n+1}^{n+d} h(j)²,
 * Cx(n) = sum_{j=n+1}^{n+d} h(j)·C(j mod d) - h(j)², C(r) = sum_{j ≡ r} h(j);
 * E - F = h ⊛ u with u(i) = g_i (i < m), u(m + r) = -sum_{i ≡ r mod d} g_i. */
static void unc_row_norms(sc_profile_dft_plan *p, int k, double g2, dft_unc_work *w)
{
    const int n = p->n, d = p->d[k], m = n - d, M = n / d;
    const double *h = w->h;
    extend(n, d, w->g, w->u);
    convolve(p, w->Hs, w->u, w->t2, w->tmp);
    for (int c = 0; c < d; ++c)
        w->csum[c] = 0;
    for (int i = 0; i < n; ++i)
        w->csum[i % d] += h[i];
    w->pre[0] = w->pre2[0] = 0;
    for (int i = 0; i < 2 * n; ++i) {
        double hi = h[i % n];
        w->pre[i + 1] = w->pre[i] + hi * hi;
        w->pre2[i + 1] = w->pre2[i] + hi * w->csum[(i % n) % d];
    }
    for (int i = 0; i < n; ++i) {
        double A = w->pre[i + n + 1] - w->pre[i + n + 1 - m];
        double W2 = w->pre[i + d + 1] - w->pre[i + 1];
        double hc = w->pre2[i + d + 1] - w->pre2[i + 1];
        w->t1[i] = A + (M - 1) * W2 + w->v[i] * w->v[i] * g2 - 2.0 * (hc - W2) +
                   2.0 * w->v[i] * w->t2[i];
    }
}

/* Scan k's share of every point's variance: with b_i = sum_n psi(n) R(n,i)
 * = (psi ⋆ h)(i) - (psi ⋆ h)(e(i)) + g_i (psi·v) and (R b)(n) = h ⊛ (T b) + v(n)·(g·b),
 * Var f'(n) += σ²·(Q - 2 t (R b) + t² |b|²). */
static void unc_add_scan(sc_profile_dft_plan *p, int k, dft_unc_work *w)
{
    const int n = p->n, nh = p->nh, d = p->d[k], m = n - d;
    const double sig2 = 1.0 / p->w[k];
    unc_row_norms(p, k, unc_scan_weights(p, k, w), w);
    for (int q = 0; q < nh; ++q)
        w->tmp[q] = w->Psi[q] * conj(w->Hs[q]);
    inverse(p, w->tmp, w->gam);
    double b2 = 0, gb = 0;
    for (int i = 0; i < m; ++i) {
        w->b[i] = w->gam[i] - w->gam[m + i % d] + w->g[i] * w->psiv;
        b2 += w->b[i] * w->b[i];
        gb += w->g[i] * w->b[i];
    }
    extend(n, d, w->b, w->u);
    convolve(p, w->Hs, w->u, w->t2, w->tmp);
    for (int i = 0; i < n; ++i) {
        double t = i - w->tc;
        double rb = w->t2[i] + w->v[i] * gb;
        w->var[i] += sig2 * (w->t1[i] - 2.0 * t * rb + t * t * b2);
    }
}

sc_status sc_profile_dft_uncertainty(sc_profile_dft_plan *p, double *uf_um, double *work,
                                     sc_error *err)
{
    if (!p || !uf_um) return sc_error_set(err, SC_E_INPUT, NULL, 0, "missing argument");
    const int n = p->n;
    double *own = NULL;
    if (!work) {
        work = own = malloc(sc_profile_dft_work_size(p) * sizeof(double));
        if (!own) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    }
    dft_unc_work w;
    unc_work_split(p, work, &w);
    memset(w.var, 0, (size_t)n * sizeof(double));
    unc_slope_functional(p, &w);
    for (int k = 0; k < 2; ++k)
        unc_add_scan(p, k, &w);
    for (int i = 0; i < n; ++i)
        uf_um[i] = sqrt(w.var[i] > 0 ? w.var[i] : 0);
    free(own);
    return SC_OK;
}

void sc_profile_dft_plan_destroy(sc_profile_dft_plan *p)
{
    if (!p)
        return;
    sc_fft_planner_lock();
    if (p->r2c)
        fftw_destroy_plan(p->r2c);
    if (p->c2r)
        fftw_destroy_plan(p->c2r);
    sc_fft_planner_unlock();
    fftw_free(p->rbuf);
    fftw_free(p->cbuf);
    free(p->zeta);
    free(p->x1);
    for (int k = 0; k < 2; ++k) {
        free(p->alpha[k]);
        free(p->beta[k]);
    }
    free(p);
}
