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
#if defined(__linux__)
#include <sys/mman.h>
#endif
#if defined(__linux__) && defined(MADV_POPULATE_WRITE)
#include <pthread.h>
#include <stdatomic.h>
#define SC_LSQ_PREFAULT 1
#else
#define SC_LSQ_PREFAULT 0
#endif

#include "profile_lsq_band.h"
#include "profile_lsq_tuning.h"
#include "profile_lsq_kernels.h"

struct sc_profile_lsq_plan {
    int n, d1, d2, bw;
    double w1, w2;
    sc_lsq_band band; /* B and its factor (profile_lsq_band.h) */
    double *z;        /* 2 columns of n: Z = B⁻¹·E (the border columns c1, c2 through B) */
    double *e;        /* 2 columns of n: E, the f-c block of the normal matrix (pinned rows 0) */
    double *bu;       /* 2 columns of n: B⁻¹·U, U = the orthonormal basis of span{1, n} (pins 0) */
    double g[2];      /* diagonal c-c block: w_k (n - d_k) */
    /* twisted factorization (docs/profile-lsq.md §3): B is persymmetric, so with the order
     * T = 0..m-1, then N-1 down to m+s, then the separator S = m..m+s-1, both halves share one
     * factor L_A (rows 0..m-1 of the band storage; rows m..m+s-1 hold L_C = B_ST·L_A⁻ᵀ) and the
     * separator's Schur complement is factored densely: ls = L_S (s×s row-major, lower). */
    int twisted, m, s;
    double *ls;
#if SC_LSQ_PREFAULT
    /* SC_PROFILE_LSQ_EARLY_UNCERTAINTY: diag(B⁻¹) computed on a second thread from create on */
    int bg, bg_joined;
    pthread_t bg_thread;
    pthread_mutex_t bg_lock; /* guards the one join (uncertainty may run concurrently) */
    double *bg_diag, *bg_win;
#endif
    double sinv[4];   /* S⁻¹, S = G - Eᵀ Z (row-major 2×2) */
};

static size_t inverse_scratch(const sc_profile_lsq_plan *p);
#if SC_LSQ_PREFAULT
static void *early_inverse_run(void *arg);
#endif

static int gcd_int(int a, int b)
{
    while (b) {
        int t = a % b;
        a = b;
        b = t;
    }
    return a;
}

int sc_profile_lsq_dof(const sc_profile_lsq_plan *p) { return p ? p->n - p->d1 - p->d2 : 0; }

bool sc_profile_lsq_uses_simd(const sc_profile_lsq_plan *p) { return p && p->band.simd; }

bool sc_profile_lsq_is_solvable(int n, int d1, int d2, sc_error *err)
{
    if (d1 < 1 || d2 < 1) {
        sc_error_set(err, SC_E_INPUT, NULL, 0,
                     "sensor spacings must be at least 1 sample (d1 = %d, d2 = %d)", d1, d2);
        return false;
    }
    int g = gcd_int(d1, d2);
    if (g != 1) {
        sc_error_set(err, SC_E_INPUT, NULL, 0,
                     "d1 = %d and d2 = %d have the common divisor %d: the profile splits into %d "
                     "interleaved sub-profiles whose relative heights are not measured",
                     d1, d2, g, g);
        return false;
    }
    if (n < 2 || (long)n < (long)d1 + d2) {
        sc_error_set(err, SC_E_INPUT, NULL, 0,
                     "N = %d is too small for d1 = %d, d2 = %d: least squares needs N >= d1 + d2 "
                     "= %ld (with fewer points the zero-point difference of the two scans is not "
                     "determined)",
                     n, d1, d2, (long)d1 + d2);
        return false;
    }
    if (n > INT32_MAX / 2 - 8) { /* indices up to 2N + a few stay in int */
        sc_error_set(err, SC_E_INPUT, NULL, 0, "N = %d is too large", n);
        return false;
    }
    return true;
}

static int is_pinned(const sc_profile_lsq_plan *p, int i) { return i == 0 || i == p->n - 1; }

/* B[i][j] (pinned rows and columns are the identity), as assembled by the band kernels. */
static double b_entry(const sc_profile_lsq_plan *p, int i, int j)
{
    int n = p->n;
    if (i == j) {
        if (is_pinned(p, i)) return 1.0;
        double aii = 0.0;
        if (i >= p->d1) aii += p->w1;
        if (i <= n - 1 - p->d1) aii += p->w1;
        if (i >= p->d2) aii += p->w2;
        if (i <= n - 1 - p->d2) aii += p->w2;
        return aii;
    }
    if (is_pinned(p, i) || is_pinned(p, j)) return 0.0;
    int dist = i > j ? i - j : j - i;
    double v = 0.0;
    if (dist == p->d1) v += -p->w1;
    if (dist == p->d2) v += -p->w2;
    return v;
}

/* Row r (0 <= r < s) of L_C: its entries L[m+r][c], c = c0 .. m-1, in the band storage. */
static const double *lc_row(const sc_profile_lsq_plan *p, int r, int *c0)
{
    int k = p->m + r;
    int lo = k - p->bw < 0 ? 0 : k - p->bw;
    *c0 = lo;
    return p->band.a + (size_t)k * p->band.ld + (size_t)(lo - k + p->bw);
}

/* The separator: S_c = G + J·G·J - B_SS (G = the separator rows' block left by eliminating T,
 * J the reversal of S) into ls, then its dense Cholesky in place. 0 if it is not positive. */
static int twisted_separator(sc_profile_lsq_plan *p)
{
    int s = p->s, m = p->m, bw = p->bw;
    size_t ld = p->band.ld;
    const double *a = p->band.a;
    double *l = p->ls;
    for (int r = 0; r < s; r++) {
        for (int c = 0; c <= r; c++) {
            double g = r - c <= bw ? a[(size_t)(m + r) * ld + (size_t)(c - r + bw)] : 0.0;
            int rm = s - 1 - c, cm = s - 1 - r; /* (J G J)[r][c] = G[s-1-r][s-1-c], rm >= cm */
            double gm = rm - cm <= bw ? a[(size_t)(m + rm) * ld + (size_t)(cm - rm + bw)] : 0.0;
            l[(size_t)r * s + c] = g + gm - b_entry(p, m + r, m + c);
        }
        for (int c = r + 1; c < s; c++) l[(size_t)r * s + c] = 0.0;
    }
    for (int j = 0; j < s; j++) {
        double djj = l[(size_t)j * s + j];
        for (int k = 0; k < j; k++) djj -= l[(size_t)j * s + k] * l[(size_t)j * s + k];
        if (!(djj > 0.0) || !isfinite(djj)) return 0;
        double ljj = sqrt(djj);
        l[(size_t)j * s + j] = ljj;
        for (int i = j + 1; i < s; i++) {
            double v = l[(size_t)i * s + j];
            for (int k = 0; k < j; k++) v -= l[(size_t)i * s + k] * l[(size_t)j * s + k];
            l[(size_t)i * s + j] = v / ljj;
        }
    }
    return 1;
}

static void reverse(double *x, int len)
{
    for (int i = 0, j = len - 1; i < j; i++, j--) {
        double t = x[i];
        x[i] = x[j];
        x[j] = t;
    }
}

/* xs[r] <- B⁻¹·xs[r] (r < nrhs <= 4) through the twisted factor: the two halves T and reversed
 * bottom share each pass over L_A, the separator in between. */
static void twisted_solve(const sc_profile_lsq_plan *p, double *const *xs, int nrhs)
{
    int m = p->m, s = p->s;
    double *half[8];
    for (int r = 0; r < nrhs; r++) {
        reverse(xs[r] + m + s, m); /* the bottom, N-1 down to m+s */
        half[2 * r] = xs[r];
        half[2 * r + 1] = xs[r] + m + s;
    }
    sc_lsq_band view = p->band;
    view.n = m;
    sc_lsq_band_forward(&view, half, 2 * nrhs);
    const double *l = p->ls;
    for (int r = 0; r < nrhs; r++) {
        double *yt = xs[r], *xsep = xs[r] + m, *yb = xs[r] + m + s;
        /* y_S = L_S⁻¹ (b_S - L_C y_T - J L_C y_B) */
        for (int q = 0; q < s; q++) {
            int c0, c1;
            const double *lq = lc_row(p, q, &c0), *lm = lc_row(p, s - 1 - q, &c1);
            double v = xsep[q];
            for (int c = c0; c < m; c++) v -= lq[c - c0] * yt[c];
            for (int c = c1; c < m; c++) v -= lm[c - c1] * yb[c];
            for (int k = 0; k < q; k++) v -= l[(size_t)q * s + k] * xsep[k];
            xsep[q] = v / l[(size_t)q * s + q];
        }
        /* x_S = L_S⁻ᵀ y_S */
        for (int q = s - 1; q >= 0; q--) {
            double v = xsep[q];
            for (int k = q + 1; k < s; k++) v -= l[(size_t)k * s + q] * xsep[k];
            xsep[q] = v / l[(size_t)q * s + q];
        }
        /* y_T -= L_Cᵀ x_S, y_B -= L_Cᵀ J x_S */
        for (int q = 0; q < s; q++) {
            int c0;
            const double *lq = lc_row(p, q, &c0);
            double xa = xsep[q], xb = xsep[s - 1 - q];
            for (int c = c0; c < m; c++) {
                yt[c] -= lq[c - c0] * xa;
                yb[c] -= lq[c - c0] * xb;
            }
        }
    }
    sc_lsq_band_backward(&view, half, 2 * nrhs);
    for (int r = 0; r < nrhs; r++) reverse(xs[r] + m + s, m);
}

static void solve_many(const sc_profile_lsq_plan *p, double *const *xs, int nrhs)
{
    if (p->twisted)
        twisted_solve(p, xs, nrhs);
    else
        sc_lsq_band_solve(&p->band, xs, nrhs);
}

static void band_solve(const sc_profile_lsq_plan *p, double *x)
{
    double *xs[1] = {x};
    solve_many(p, xs, 1);
}

/* Allocate a large array, page-aligned (the page-fault helper below works in whole pages);
 * huge: 2 MB-aligned and marked for transparent huge pages. Not by default: on the 2-vCPU VM of
 * the benchmarks, huge pages made the first touch of memory the host had taken back cost ~1 s for
 * 440 MB (against 0.05 s when it had not, and ~0.2 s with small pages either way) —
 * docs/profile-lsq.md §5. Free with free(). */
static double *alloc_doubles(size_t count, int huge)
{
    size_t bytes = count * sizeof(double);
    if (bytes >= ((size_t)1 << 20)) {
        size_t align = 4096;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (huge) align = (size_t)2 << 20;
#else
        (void)huge;
#endif
        size_t len = (bytes + align - 1) & ~(align - 1);
        void *q = NULL;
        if (posix_memalign(&q, align, len) != 0) return NULL;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (huge) (void)madvise(q, len, MADV_HUGEPAGE);
#endif
        return q;
    }
    return malloc(bytes ? bytes : 1);
}

#if SC_LSQ_PREFAULT
/* The factor's pages are faulted in (kernel zeroing, huge-page compaction: as much time as the
 * factorization itself at N·d = 10⁸) by a second thread while the first factors: it populates
 * the block from its end backwards, the factorization runs forwards and faults what the helper
 * has not reached yet; it stops (after at most one 2 MB chunk) when the factorization is done.
 * MADV_POPULATE_WRITE never changes the content of a page (pages already present are left alone),
 * so the two threads share no data but the stop flag. */
typedef struct {
    char *base;
    size_t len;
    atomic_int stop; /* set by the factorizing thread when it is done: no use going on */
} prefault_job;

static void *prefault_run(void *arg)
{
    prefault_job *job = arg;
    const size_t chunk = (size_t)2 << 20;
    size_t end = job->len;
    while (end > 0 && !atomic_load_explicit(&job->stop, memory_order_relaxed)) {
        size_t beg = end > chunk ? end - chunk : 0;
        if (madvise(job->base + beg, end - beg, MADV_POPULATE_WRITE) != 0) break;
        end = beg;
    }
    return NULL;
}
#endif

/* 1 if the environment variable is set to something other than "" or "0". */
static int env_on(const char *name)
{
    const char *v = getenv(name);
    return v && *v && strcmp(v, "0") != 0;
}

sc_status sc_profile_lsq_plan_create(int n, int d1, int d2, double w1, double w2, sc_profile_lsq_plan **out,
                                     sc_error *err)
{
    unsigned flags = (env_on("SELFCAL_PROFILE_LSQ_ONE_THREAD") ? SC_PROFILE_LSQ_ONE_THREAD : 0u) |
                     (env_on("SELFCAL_PROFILE_LSQ_HUGE_PAGES") ? SC_PROFILE_LSQ_HUGE_PAGES : 0u);
    return sc_profile_lsq_plan_create_tuned(n, d1, d2, w1, w2, flags, out, err);
}

/* The plan's sizes and the band's layout: one-sided, or twisted with separator s in
 * [bw, bw+15], s ≡ N (mod 16), so that m = (N - s)/2 is a multiple of 8 (whole panels); twisted
 * only where both halves are long against the band. */
static void plan_layout(sc_profile_lsq_plan *p, int n, int d1, int d2, double w1, double w2,
                        unsigned flags)
{
    p->n = n;
    p->d1 = d1;
    p->d2 = d2;
    p->bw = d1 > d2 ? d1 : d2;
    p->w1 = w1;
    p->w2 = w2;
    sc_lsq_band *bd = &p->band;
    bd->n = n;
    bd->bw = p->bw;
    bd->d1 = d1;
    bd->d2 = d2;
    bd->w1 = w1;
    bd->w2 = w2;
    bd->ld = (size_t)p->bw + 1;
    bd->simd = (flags & SC_PROFILE_LSQ_PORTABLE) ? 0 : sc_lsq_band_cpu_has_simd();
    bd->nrow = bd->ncol = n;
    if (!(flags & SC_PROFILE_LSQ_SERIAL) && (long)n >= 4L * p->bw + 32) {
        int sep = p->bw;
        while ((n - sep) % 16 != 0) sep++;
        p->twisted = 1;
        p->s = sep;
        p->m = (n - sep) / 2;
        bd->nrow = p->m + sep;
        bd->ncol = p->m;
    }
}

/* Factor the band (col: the factor's column scratch). Factors of 16 MB and more have their pages
 * faulted in by a helper thread meanwhile (where the faults cost more than a thread). */
static sc_status factor_band(sc_profile_lsq_plan *p, unsigned flags, double *col, sc_error *err)
{
    sc_lsq_band *bd = &p->band;
#if SC_LSQ_PREFAULT
    /* only where the faults cost more than a thread: factors of 16 MB and more, page-aligned */
    prefault_job job;
    job.base = (char *)bd->a;
    job.len = (size_t)bd->nrow * bd->ld * sizeof(double) & ~(size_t)4095;
    atomic_init(&job.stop, 0);
    pthread_t helper;
    int helping = !(flags & (SC_PROFILE_LSQ_SERIAL | SC_PROFILE_LSQ_ONE_THREAD)) && job.len >= ((size_t)16 << 20) &&
                  ((uintptr_t)bd->a & 4095) == 0 &&
                  pthread_create(&helper, NULL, prefault_run, &job) == 0;
#else
    (void)flags;
#endif
    int bad = sc_lsq_band_factor(bd, col);
#if SC_LSQ_PREFAULT
    if (helping) {
        atomic_store_explicit(&job.stop, 1, memory_order_relaxed);
        pthread_join(helper, NULL);
    }
#endif
    if (bad >= 0)
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                            "banded Cholesky factor lost positive definiteness at row %d", bad);
    if (p->twisted && !twisted_separator(p))
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                            "the separator block of the twisted factor is not positive definite");
    return SC_OK;
}

/* SC_PROFILE_LSQ_EARLY_UNCERTAINTY: the selected inversion needs only the factor, so it runs on a
 * second thread from here on, while this one does the border solves and the caller its solves. */
static sc_status start_early_uncertainty(sc_profile_lsq_plan *p, unsigned flags, sc_error *err)
{
#if SC_LSQ_PREFAULT
    if (flags & SC_PROFILE_LSQ_EARLY_UNCERTAINTY) {
        p->bg_diag = malloc((size_t)p->n * sizeof(double));
        p->bg_win = malloc(inverse_scratch(p) * sizeof(double));
        if (!p->bg_diag || !p->bg_win)
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (early uncertainty)");
        if (pthread_mutex_init(&p->bg_lock, NULL) == 0) {
            if (pthread_create(&p->bg_thread, NULL, early_inverse_run, p) == 0)
                p->bg = 1;
            else
                pthread_mutex_destroy(&p->bg_lock);
        }
    }
#else
    (void)p;
    (void)flags;
    (void)err;
#endif
    return SC_OK;
}

/* The border of the offsets c1, c2: E column k = d(normal eq. of f)/d c_k, G = diag(w_k (n - d_k)),
 * Z = B⁻¹E, B⁻¹U for the uncertainty (U = [1/√N, (i - nc)/√sxx], pinned entries zeroed) and the
 * inverse of the Schur complement S = G - EᵀZ. */
static sc_status border(sc_profile_lsq_plan *p, sc_error *err)
{
    const int n = p->n;
    const int dk[2] = {p->d1, p->d2};
    const double wk[2] = {p->w1, p->w2};
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
    double nc = 0.5 * (double)(n - 1);
    double sxx = (double)n * ((double)n * (double)n - 1.0) / 12.0;
    double a1 = 1.0 / sqrt((double)n), a2 = 1.0 / sqrt(sxx);
    for (int i = 0; i < n; i++) {
        int pin = is_pinned(p, i);
        p->bu[i] = pin ? 0.0 : a1;
        p->bu[n + i] = pin ? 0.0 : a2 * ((double)i - nc);
    }
    double *rhs[4] = {p->z, p->z + n, p->bu, p->bu + n};
    solve_many(p, rhs, 4);
    double s[4];
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            s[2 * a + b] = (a == b ? p->g[a] : 0.0) -
                           sc_lsq_dot(p->e + (size_t)a * n, p->z + (size_t)b * n, n);
    double sym = 0.5 * (s[1] + s[2]);
    s[1] = s[2] = sym;
    double det = s[0] * s[3] - s[1] * s[2];
    if (!(s[0] > 0.0) || !(det > 1e-14 * s[0] * s[3]))
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0,
                            "the zero-point offsets c1, c2 are numerically undetermined "
                            "(Schur complement det %g)", det);
    p->sinv[0] = s[3] / det;
    p->sinv[3] = s[0] / det;
    p->sinv[1] = p->sinv[2] = -s[1] / det;
    return SC_OK;
}

sc_status sc_profile_lsq_plan_create_tuned(int n, int d1, int d2, double w1, double w2, unsigned flags,
                                           sc_profile_lsq_plan **out, sc_error *err)
{
    if (out) *out = NULL;
    if (!out) return sc_error_set(err, SC_E_INPUT, NULL, 0, "no output pointer");
    if (!sc_profile_lsq_is_solvable(n, d1, d2, err)) return SC_E_INPUT;
    if (!(w1 > 0.0) || !(w2 > 0.0) || !isfinite(w1) || !isfinite(w2))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "scan weights must be positive and finite (w1 = %g, w2 = %g)", w1, w2);
    sc_profile_lsq_plan *p = calloc(1, sizeof *p);
    if (!p) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    plan_layout(p, n, d1, d2, w1, w2, flags);
    sc_lsq_band *bd = &p->band;
    if ((size_t)n > SIZE_MAX / sizeof(double) / (bd->ld + 4)) {
        int bw = p->bw;
        free(p);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "N = %d with d = %d needs too much memory",
                            n, bw);
    }
    bd->a = alloc_doubles((size_t)bd->nrow * bd->ld, (flags & SC_PROFILE_LSQ_HUGE_PAGES) != 0);
    if (p->twisted) p->ls = malloc((size_t)p->s * (size_t)p->s * sizeof(double));
    p->z = malloc((size_t)2 * n * sizeof(double));
    p->e = malloc((size_t)2 * n * sizeof(double));
    p->bu = malloc((size_t)2 * n * sizeof(double));
    double *col = malloc(8 * (bd->ld + 15) * sizeof(double));
    if (!bd->a || !p->z || !p->e || !p->bu || !col || (p->twisted && !p->ls)) {
        int bw = p->bw;
        free(col);
        sc_profile_lsq_plan_destroy(p);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0,
                            "out of memory for the banded factor (N = %d, d = %d: %.0f MB)", n,
                            bw, (double)n * (double)(bw + 1) * 8.0 / 1e6);
    }
    sc_status st = factor_band(p, flags, col, err);
    free(col);
    if (st == SC_OK)
        st = start_early_uncertainty(p, flags, err);
    if (st == SC_OK)
        st = border(p, err);
    if (st != SC_OK) {
        sc_profile_lsq_plan_destroy(p);
        return st;
    }
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

sc_status sc_profile_lsq_execute(const sc_profile_lsq_plan *p, const double *y1_um, const double *y2_um,
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

static size_t inverse_scratch(const sc_profile_lsq_plan *p)
{
    size_t nz = p->twisted ? (size_t)p->s * (size_t)p->s : 0;
    return sc_lsq_band_inverse_scratch(p->bw) + 2 * nz + 1;
}

/* diag[0..n-1] = diag(B⁻¹); win: inverse_scratch(p) doubles. */
static void inverse_diag_into(const sc_profile_lsq_plan *p, double *win, double *diag)
{
    if (!p->twisted) {
        sc_lsq_band_inverse_diag(&p->band, win, diag);
        return;
    }
    /* twisted: Z_SS = S_c⁻¹ = L_S⁻ᵀ L_S⁻¹, then the recurrences from m-1 down to 0 (the bottom
     * half's rows of L have no entries in T's columns); B⁻¹ is persymmetric like B, so the
     * bottom half's diagonal is the mirror of the top's */
    size_t nwin = sc_lsq_band_inverse_scratch(p->bw), nz = (size_t)p->s * (size_t)p->s;
    int s = p->s, m = p->m, n = p->n;
    const double *l = p->ls;
    double *li = win + nwin, *zss = li + nz; /* li = L_S⁻¹ (lower) */
    for (int j = 0; j < s; j++) {
        for (int i = 0; i < j; i++) li[(size_t)i * s + j] = 0.0;
        li[(size_t)j * s + j] = 1.0 / l[(size_t)j * s + j];
        for (int i = j + 1; i < s; i++) {
            double v = 0.0;
            for (int k = j; k < i; k++) v -= l[(size_t)i * s + k] * li[(size_t)k * s + j];
            li[(size_t)i * s + j] = v / l[(size_t)i * s + i];
        }
    }
    for (int i = 0; i < s; i++)
        for (int j = 0; j <= i; j++) {
            double v = 0.0;
            for (int k = i; k < s; k++) v += li[(size_t)k * s + i] * li[(size_t)k * s + j];
            zss[(size_t)i * s + j] = zss[(size_t)j * s + i] = v;
        }
    sc_lsq_band_inverse_diag_from(&p->band, win, diag, m - 1, zss, s);
    for (int q = 0; q < s; q++) diag[m + q] = zss[(size_t)q * s + q];
    for (int i = 0; i < m; i++) diag[n - 1 - i] = diag[i];
}

#if SC_LSQ_PREFAULT
static void *early_inverse_run(void *arg)
{
    sc_profile_lsq_plan *p = arg;
    inverse_diag_into(p, p->bg_win, p->bg_diag);
    return NULL;
}

/* Wait for the early selected inversion (once; the plan's only mutable state, under its lock). */
static void early_inverse_join(sc_profile_lsq_plan *p)
{
    pthread_mutex_lock(&p->bg_lock);
    if (!p->bg_joined) {
        pthread_join(p->bg_thread, NULL);
        p->bg_joined = 1;
        free(p->bg_win);
        p->bg_win = NULL;
    }
    pthread_mutex_unlock(&p->bg_lock);
}
#endif

size_t sc_profile_lsq_work_size(const sc_profile_lsq_plan *p) { return p ? inverse_scratch(p) : 0; }

static sc_status selected_inverse_diag(const sc_profile_lsq_plan *p, double *diag, double *work,
                                       sc_error *err)
{
#if SC_LSQ_PREFAULT
    if (p->bg) {
        early_inverse_join((sc_profile_lsq_plan *)p); /* the join is the one write: under the lock */
        memcpy(diag, p->bg_diag, (size_t)p->n * sizeof(double));
        return SC_OK;
    }
#endif
    double *own = NULL;
    if (!work) {
        work = own = malloc(inverse_scratch(p) * sizeof(double));
        if (!own) return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (selected inverse)");
    }
    inverse_diag_into(p, work, diag);
    free(own);
    return SC_OK;
}

sc_status sc_profile_lsq_uncertainty(const sc_profile_lsq_plan *p, double *uf_um, double *work,
                                     sc_error *err)
{
    if (!p || !uf_um) return sc_error_set(err, SC_E_INPUT, NULL, 0, "missing argument");
    int n = p->n;
    sc_status st = selected_inverse_diag(p, uf_um, work, err);
    if (st != SC_OK) return st;
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
    const double *bu1 = p->bu, *bu2 = p->bu + n;
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
    /* CU = B⁻¹U + Z·m, formed on the fly below */
    /* Q = Uᵀ C U */
    double q11 = 0, q12 = 0, q21 = 0, q22 = 0;
    for (int i = 0; i < n; i++) {
        double u2 = a2 * ((double)i - nc);
        double cu1 = bu1[i] + z1[i] * m[0] + z2[i] * m[2];
        double cu2 = bu2[i] + z1[i] * m[1] + z2[i] * m[3];
        q11 += a1 * cu1;
        q12 += a1 * cu2;
        q21 += u2 * cu1;
        q22 += u2 * cu2;
    }
    double q12s = 0.5 * (q12 + q21);
    /* diag(P C P) = diag(C) - 2 diag(U (CU)ᵀ) + diag(U Q Uᵀ) */
    for (int i = 0; i < n; i++) {
        double u2 = a2 * ((double)i - nc);
        double cu1 = bu1[i] + z1[i] * m[0] + z2[i] * m[2];
        double cu2 = bu2[i] + z1[i] * m[1] + z2[i] * m[3];
        double v = uf_um[i] - 2.0 * (a1 * cu1 + u2 * cu2) + a1 * a1 * q11 +
                   2.0 * a1 * u2 * q12s + u2 * u2 * q22;
        uf_um[i] = v > 0.0 ? sqrt(v) : 0.0;
    }
    return SC_OK;
}

void sc_profile_lsq_plan_destroy(sc_profile_lsq_plan *p)
{
    if (!p) return;
#if SC_LSQ_PREFAULT
    if (p->bg) {
        early_inverse_join(p);
        pthread_mutex_destroy(&p->bg_lock);
    }
    free(p->bg_diag);
    free(p->bg_win);
#endif
    free(p->band.a);
    free(p->z);
    free(p->e);
    free(p->bu);
    free(p->ls);
    free(p);
}
