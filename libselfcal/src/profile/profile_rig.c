/* profile_rig.c — owns the least squares of a real rig (profile_rig.h; docs/profile-lsq.md §10):
 * rows left out, a common drift, undetermined points, leverages. Plain banded Cholesky of the
 * normal matrix with two far points of the determined set pinned (as profile_lsq.c §3, one-sided),
 * a border of 2 + drift columns by its Schur complement, the band of the inverse by selected
 * inversion. O(N·d²) time, O(N·d) memory. */
#include "profile_rig.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAXP SC_RIG_MAX_PARAMS

struct sc_rig_plan {
    int n, d[2], bw, np, drift;
    double w[2];
    unsigned char *use[2];  /* rows in the fit */
    unsigned char *det;     /* determined points */
    unsigned char *fixed;   /* not a free unknown: pinned or undetermined */
    int ndet, pin[2], dof;
    double *L;              /* band factor: L[i*(bw+1) + (j - i + bw)] = L(i, j), i - bw <= j <= i */
    double *Z;              /* B⁻¹E: n x np (row-major) */
    double Sf[MAXP * MAXP]; /* Cholesky factor of the Schur complement S = G - EᵀB⁻¹E */
    double *Zb;             /* band of B̃⁻¹ (fixed rows zero): Zb[i*(bw+1) + t] = B̃⁻¹(i, i+t) */
};

static double tau(const sc_rig_plan *p, int j)
{
    return p->n > 1 ? (2.0 * j - (p->n - 1)) / (double)(p->n - 1) : 0.0;
}

/* The border part of row (k, j)'s design row. */
static void row_params(const sc_rig_plan *p, int k, int j, double *a)
{
    memset(a, 0, sizeof(double) * MAXP);
    a[k] = 1;
    double t = tau(p, j);
    if (p->drift >= 1)
        a[2] = t;
    if (p->drift >= 2)
        a[3] = t * t;
}

static int find(int *par, int x)
{
    while (par[x] != x)
        x = par[x] = par[par[x]];
    return x;
}

/* The largest connected set of points of the rows in use: the determined points. */
static sc_status components(sc_rig_plan *p, sc_error *err)
{
    const int n = p->n;
    int *par = malloc((size_t)n * sizeof(int)), *size = calloc((size_t)n, sizeof(int));
    if (!par || !size) {
        free(par), free(size);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    }
    for (int i = 0; i < n; ++i)
        par[i] = i;
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < n - p->d[k]; ++j)
            if (p->use[k][j]) {
                int a = find(par, j), b = find(par, j + p->d[k]);
                if (a != b)
                    par[a] = b;
            }
    int best = -1;
    for (int i = 0; i < n; ++i) {
        int r = find(par, i);
        if (++size[r] > (best < 0 ? 0 : size[best]))
            best = r;
    }
    p->ndet = 0;
    p->pin[0] = p->pin[1] = -1;
    for (int i = 0; i < n; ++i) {
        p->det[i] = find(par, i) == best && size[best] > 1;
        if (p->det[i]) {
            if (p->pin[0] < 0)
                p->pin[0] = i;
            p->pin[1] = i;
            p->ndet++;
        }
    }
    free(par), free(size);
    for (int k = 0; k < 2; ++k) /* rows outside the determined set leave the fit */
        for (int j = 0; j < n - p->d[k]; ++j)
            if (p->use[k][j] && !p->det[j])
                p->use[k][j] = 0;
    if (p->ndet < 3)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the rows determine no profile (at most %d points are tied together)",
                            p->ndet);
    for (int i = 0; i < n; ++i)
        p->fixed[i] = !p->det[i] || i == p->pin[0] || i == p->pin[1];
    return SC_OK;
}

#define LB(p, i, j) ((p)->L[(size_t)(i) * (size_t)((p)->bw + 1) + (size_t)((j) - (i) + (p)->bw)])

/* The pinned normal matrix's band into L, E into Z, G into g. */
static void assemble(sc_rig_plan *p, double *g)
{
    const int n = p->n, np = p->np;
    memset(g, 0, sizeof(double) * MAXP * MAXP);
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < n - p->d[k]; ++j) {
            if (!p->use[k][j])
                continue;
            const int idx[2] = {j + p->d[k], j};
            const double s[2] = {1, -1}, w = p->w[k];
            double a[MAXP];
            row_params(p, k, j, a);
            for (int u = 0; u < 2; ++u) {
                if (p->fixed[idx[u]])
                    continue;
                for (int v = 0; v < 2; ++v)
                    if (!p->fixed[idx[v]] && idx[v] <= idx[u])
                        LB(p, idx[u], idx[v]) += w * s[u] * s[v];
                for (int q = 0; q < np; ++q)
                    p->Z[(size_t)idx[u] * np + q] += w * s[u] * a[q];
            }
            for (int q = 0; q < np; ++q)
                for (int r = 0; r < np; ++r)
                    g[q * MAXP + r] += w * a[q] * a[r];
        }
    for (int i = 0; i < n; ++i)
        if (p->fixed[i])
            LB(p, i, i) = 1;
}

/* Banded Cholesky in place (row by row). */
static sc_status factor(sc_rig_plan *p, sc_error *err)
{
    const int n = p->n, bw = p->bw;
    for (int i = 0; i < n; ++i) {
        int lo = i - bw > 0 ? i - bw : 0;
        for (int j = lo; j <= i; ++j) {
            double s = LB(p, i, j);
            int klo = j - bw > lo ? j - bw : lo;
            for (int k = klo; k < j; ++k)
                s -= LB(p, i, k) * LB(p, j, k);
            if (j < i)
                LB(p, i, j) = s / LB(p, j, j);
            else if (!(s > 0))
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "the normal matrix is singular at point %d", i);
            else
                LB(p, i, i) = sqrt(s);
        }
    }
    return SC_OK;
}

/* x = B⁻¹b in place (fixed entries of b must be 0; they stay 0). */
static void band_solve(const sc_rig_plan *p, double *x)
{
    const int n = p->n, bw = p->bw;
    for (int i = 0; i < n; ++i) {
        double s = x[i];
        for (int j = i - bw > 0 ? i - bw : 0; j < i; ++j)
            s -= LB(p, i, j) * x[j];
        x[i] = s / LB(p, i, i);
    }
    for (int i = n - 1; i >= 0; --i) {
        double s = x[i];
        int hi = i + bw < n - 1 ? i + bw : n - 1;
        for (int k = i + 1; k <= hi; ++k)
            s -= LB(p, k, i) * x[k];
        x[i] = s / LB(p, i, i);
    }
}

/* Small dense Cholesky of a (m x m, stride MAXP) in place; 0 if not positive definite relative
 * to its diagonal. */
static int small_chol(double *a, int m)
{
    for (int j = 0; j < m; ++j) {
        double s = a[j * MAXP + j], d0 = s;
        for (int k = 0; k < j; ++k)
            s -= a[j * MAXP + k] * a[j * MAXP + k];
        if (!(s > 1e-11 * d0))
            return 0;
        a[j * MAXP + j] = sqrt(s);
        for (int i = j + 1; i < m; ++i) {
            double t = a[i * MAXP + j];
            for (int k = 0; k < j; ++k)
                t -= a[i * MAXP + k] * a[j * MAXP + k];
            a[i * MAXP + j] = t / a[j * MAXP + j];
        }
    }
    return 1;
}

static void small_solve(const double *l, int m, double *x)
{
    for (int i = 0; i < m; ++i) {
        double s = x[i];
        for (int k = 0; k < i; ++k)
            s -= l[i * MAXP + k] * x[k];
        x[i] = s / l[i * MAXP + i];
    }
    for (int i = m - 1; i >= 0; --i) {
        double s = x[i];
        for (int k = i + 1; k < m; ++k)
            s -= l[k * MAXP + i] * x[k];
        x[i] = s / l[i * MAXP + i];
    }
}

/* Z = B⁻¹E column by column, then S = G - EᵀZ and its factor. */
static sc_status border(sc_rig_plan *p, const double *g, sc_error *err)
{
    const int n = p->n, np = p->np;
    double *col = malloc((size_t)n * (size_t)np * sizeof(double));
    if (!col)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    for (int q = 0; q < np; ++q) {
        double *c = col + (size_t)q * n;
        for (int i = 0; i < n; ++i)
            c[i] = p->Z[(size_t)i * np + q];
        band_solve(p, c);
    }
    double ez[MAXP * MAXP] = {0};
    for (int r = 0; r < np; ++r)
        for (int q = 0; q < np; ++q) {
            double s = 0;
            for (int i = 0; i < n; ++i)
                s += p->Z[(size_t)i * np + r] * col[(size_t)q * n + i];
            ez[r * MAXP + q] = s;
        }
    for (int q = 0; q < np; ++q)
        for (int i = 0; i < n; ++i)
            p->Z[(size_t)i * np + q] = col[(size_t)q * n + i];
    free(col);
    for (int q = 0; q < np; ++q)
        for (int r = 0; r < np; ++r)
            p->Sf[q * MAXP + r] = g[q * MAXP + r] - 0.5 * (ez[q * MAXP + r] + ez[r * MAXP + q]);
    if (!small_chol(p->Sf, np))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            p->drift ? "the drift terms cannot be told from the profile with these "
                                       "rows and spacings (the problem is singular)"
                                     : "the rows do not determine the profile's line: no cycle of "
                                       "the two spacings is left (the problem is singular)");
    return SC_OK;
}

/* The plan's arrays (rows used copied from use[]); SC_E_NOMEM when one cannot be had. */
static sc_status plan_alloc(sc_rig_plan *p, const unsigned char *const use[2], sc_error *err)
{
    const int n = p->n, d1 = p->d[0], d2 = p->d[1];
    size_t band = (size_t)n * (size_t)(p->bw + 1);
    p->use[0] = malloc((size_t)(n - d1));
    p->use[1] = malloc((size_t)(n - d2));
    p->det = malloc((size_t)n);
    p->fixed = malloc((size_t)n);
    p->L = calloc(band, sizeof(double));
    p->Z = calloc((size_t)n * (size_t)p->np, sizeof(double));
    if (!p->use[0] || !p->use[1] || !p->det || !p->fixed || !p->L || !p->Z)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    memcpy(p->use[0], use[0], (size_t)(n - d1));
    memcpy(p->use[1], use[1], (size_t)(n - d2));
    return SC_OK;
}

/* The degrees of freedom: rows used less the unknowns (points but the gauge's two, parameters). */
static sc_status plan_dof(sc_rig_plan *p, sc_error *err)
{
    long rows = 0;
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < p->n - p->d[k]; ++j)
            rows += p->use[k][j] != 0;
    p->dof = (int)(rows - (p->ndet - 2) - p->np);
    if (p->dof < 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "fewer rows (%ld) than unknowns (%d)", rows,
                            p->ndet - 2 + p->np);
    return SC_OK;
}

sc_status sc_rig_plan_create(int n, int d1, int d2, const double w[2],
                             const unsigned char *const use[2], int drift, sc_rig_plan **out,
                             sc_error *err)
{
    *out = NULL;
    if (n < 3 || d1 < 1 || d2 < 1 || d1 >= n || d2 >= n || drift < 0 || drift > 2 ||
        !(w[0] > 0) || !(w[1] > 0))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "bad least-squares problem (N = %d, d = %d/%d)",
                            n, d1, d2);
    sc_rig_plan *p = calloc(1, sizeof *p);
    if (!p)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    p->n = n, p->d[0] = d1, p->d[1] = d2, p->bw = d1 > d2 ? d1 : d2;
    p->drift = drift, p->np = 2 + drift, p->w[0] = w[0], p->w[1] = w[1];
    sc_status st = plan_alloc(p, use, err);
    if (st == SC_OK)
        st = components(p, err);
    double g[MAXP * MAXP];
    if (st == SC_OK) {
        assemble(p, g);
        st = factor(p, err);
    }
    if (st == SC_OK)
        st = border(p, g, err);
    if (st == SC_OK)
        st = plan_dof(p, err);
    if (st != SC_OK) {
        sc_rig_plan_destroy(p);
        return st;
    }
    *out = p;
    return SC_OK;
}

void sc_rig_plan_destroy(sc_rig_plan *p)
{
    if (!p)
        return;
    free(p->use[0]), free(p->use[1]), free(p->det), free(p->fixed), free(p->L), free(p->Z);
    free(p->Zb);
    free(p);
}

const unsigned char *sc_rig_determined(const sc_rig_plan *p) { return p->det; }
int sc_rig_n_determined(const sc_rig_plan *p) { return p->ndet; }
int sc_rig_dof(const sc_rig_plan *p) { return p->dof; }
int sc_rig_row_used(const sc_rig_plan *p, int k, int j) { return p->use[k][j] != 0; }

double sc_rig_predict(const sc_rig_plan *p, int k, int j, const double *f, const double *q)
{
    double a[MAXP], v = f[j + p->d[k]] - f[j];
    row_params(p, k, j, a);
    for (int r = 0; r < p->np; ++r)
        v += a[r] * q[r];
    return v;
}

/* Remove the least-squares line over the determined points from f (NaN elsewhere); the slope
 * removed (per sample) into *beta. */
static void to_line_gauge(const sc_rig_plan *p, double *f, double *beta)
{
    double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
    for (int i = 0; i < p->n; ++i)
        if (p->det[i])
            m += 1, sx += i, sy += f[i];
    double xm = sx / m, ym = sy / m;
    for (int i = 0; i < p->n; ++i)
        if (p->det[i])
            sxx += (i - xm) * (i - xm), sxy += (i - xm) * (f[i] - ym);
    double b = sxx > 0 ? sxy / sxx : 0;
    for (int i = 0; i < p->n; ++i)
        f[i] = p->det[i] ? f[i] - ym - b * (i - xm) : NAN;
    *beta = b;
}

sc_status sc_rig_solve(const sc_rig_plan *p, const double *y1, const double *y2, double *f,
                       double *q, double *wrss, sc_error *err)
{
    const int n = p->n, np = p->np;
    const double *y[2] = {y1, y2};
    double rq[MAXP] = {0}, qq[MAXP];
    memset(f, 0, (size_t)n * sizeof(double));
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < n - p->d[k]; ++j) {
            if (!p->use[k][j])
                continue;
            double v = y[k][j], a[MAXP];
            if (!isfinite(v))
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "scan %d n = %d: y is not finite", k + 1, j);
            v *= p->w[k];
            if (!p->fixed[j + p->d[k]])
                f[j + p->d[k]] += v;
            if (!p->fixed[j])
                f[j] -= v;
            row_params(p, k, j, a);
            for (int r = 0; r < np; ++r)
                rq[r] += a[r] * v;
        }
    for (int r = 0; r < np; ++r) { /* Eᵀu = EᵀB⁻¹r_f = Zᵀr_f */
        double s = rq[r];
        for (int i = 0; i < n; ++i)
            s -= p->Z[(size_t)i * np + r] * f[i];
        qq[r] = s;
    }
    band_solve(p, f);
    small_solve(p->Sf, np, qq);
    for (int i = 0; i < n; ++i)
        for (int r = 0; r < np; ++r)
            f[i] -= p->Z[(size_t)i * np + r] * qq[r];
    if (wrss) {
        double ss = 0;
        for (int k = 0; k < 2; ++k)
            for (int j = 0; j < n - p->d[k]; ++j)
                if (p->use[k][j]) {
                    double r = y[k][j] - sc_rig_predict(p, k, j, f, qq);
                    ss += p->w[k] * r * r;
                }
        *wrss = ss;
    }
    double beta;
    to_line_gauge(p, f, &beta);
    qq[0] += beta * p->d[0];
    qq[1] += beta * p->d[1];
    if (q)
        memcpy(q, qq, (size_t)np * sizeof(double));
    return SC_OK;
}

/* The band of B⁻¹ by selected inversion (Takahashi), fixed rows zeroed. */
static sc_status band_inverse(sc_rig_plan *p, sc_error *err)
{
    const int n = p->n, bw = p->bw, ld = bw + 1;
    if (p->Zb)
        return SC_OK;
    double *Zb = malloc((size_t)n * (size_t)ld * sizeof(double));
    if (!Zb)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
#define ZB(i, t) Zb[(size_t)(i) * (size_t)ld + (size_t)(t)]
    for (int i = n - 1; i >= 0; --i) {
        int hi = i + bw < n - 1 ? i + bw : n - 1;
        double lii = LB(p, i, i);
        for (int j = hi; j > i; --j) {
            double s = 0;
            for (int k = i + 1; k <= hi; ++k) {
                double z = k <= j ? ZB(k, j - k) : ZB(j, k - j);
                s += LB(p, k, i) * z;
            }
            ZB(i, j - i) = -s / lii;
        }
        for (int j = hi + 1; j <= i + bw; ++j)
            ZB(i, j - i) = 0;
        double s = 0;
        for (int k = i + 1; k <= hi; ++k)
            s += LB(p, k, i) * ZB(i, k - i);
        ZB(i, 0) = (1.0 / lii - s) / lii;
    }
    for (int i = 0; i < n; ++i)
        if (p->fixed[i])
            ZB(i, 0) = 0; /* a fixed point's row and column: its identity row only */
#undef ZB
    p->Zb = Zb;
    return SC_OK;
}

/* zᵢᵀ S⁻¹ zⱼ for rows i, j of Z. */
static double zsz(const sc_rig_plan *p, int i, int j)
{
    double x[MAXP];
    memcpy(x, &p->Z[(size_t)j * p->np], (size_t)p->np * sizeof(double));
    small_solve(p->Sf, p->np, x);
    double s = 0;
    for (int r = 0; r < p->np; ++r)
        s += p->Z[(size_t)i * p->np + r] * x[r];
    return s;
}

/* U: an orthonormal basis of {1, i} over the determined points (zero elsewhere). */
typedef struct line_basis {
    double m, xm, sxx; /* count, mean index and sum of squared deviations of the points */
} line_basis;

static line_basis line_basis_of(const sc_rig_plan *p)
{
    line_basis b = {0, 0, 0};
    for (int i = 0; i < p->n; ++i)
        if (p->det[i])
            b.m += 1, b.xm += i;
    b.xm /= b.m;
    for (int i = 0; i < p->n; ++i)
        if (p->det[i])
            b.sxx += (i - b.xm) * (i - b.xm);
    return b;
}

/* Column a (0: the constant, 1: the slope) of U at point i. */
static double basis_at(const sc_rig_plan *p, const line_basis *b, int a, int i)
{
    if (!p->det[i])
        return 0.0;
    return a ? (i - b->xm) / sqrt(b->sxx) : 1.0 / sqrt(b->m);
}

/* cu (n x 2, column-major) = CU = B̃⁻¹U + Z S⁻¹ ZᵀU, fixed rows zero. */
static void basis_response(const sc_rig_plan *p, const line_basis *b, double *cu)
{
    const int n = p->n, np = p->np;
    double ztu[2][MAXP] = {{0}};
    for (int a = 0; a < 2; ++a) {
        double *c = cu + (size_t)a * n;
        for (int i = 0; i < n; ++i)
            c[i] = p->fixed[i] ? 0.0 : basis_at(p, b, a, i);
        band_solve(p, c);
        for (int i = 0; i < n; ++i) {
            double u = basis_at(p, b, a, i);
            for (int r = 0; r < np; ++r)
                ztu[a][r] += p->Z[(size_t)i * np + r] * u;
        }
        small_solve(p->Sf, np, ztu[a]);
        for (int i = 0; i < n; ++i) {
            if (p->fixed[i]) {
                c[i] = 0;
                continue;
            }
            for (int r = 0; r < np; ++r)
                c[i] += p->Z[(size_t)i * np + r] * ztu[a][r];
        }
    }
}

sc_status sc_rig_uncertainty(sc_rig_plan *p, double *uf, sc_error *err)
{
    const int n = p->n;
    sc_status st = band_inverse(p, err);
    if (st != SC_OK)
        return st;
    line_basis b = line_basis_of(p);
    double *cu = malloc((size_t)n * 2 * sizeof(double));
    if (!cu)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    basis_response(p, &b, cu);
    double utcu[2][2] = {{0}};
    for (int i = 0; i < n; ++i)
        for (int a = 0; a < 2; ++a) {
            utcu[a][0] += basis_at(p, &b, 0, i) * cu[(size_t)a * n + i];
            utcu[a][1] += basis_at(p, &b, 1, i) * cu[(size_t)a * n + i];
        }
    for (int i = 0; i < n; ++i) {
        if (!p->det[i]) {
            uf[i] = NAN;
            continue;
        }
        double c = p->fixed[i] ? 0.0 : p->Zb[(size_t)i * (size_t)(p->bw + 1)] + zsz(p, i, i);
        double u[2] = {basis_at(p, &b, 0, i), basis_at(p, &b, 1, i)}, v = c;
        for (int a = 0; a < 2; ++a)
            v -= 2 * u[a] * cu[(size_t)a * n + i];
        for (int a = 0; a < 2; ++a)
            for (int q = 0; q < 2; ++q)
                v += u[a] * u[q] * 0.5 * (utcu[a][q] + utcu[q][a]);
        uf[i] = sqrt(v > 0 ? v : 0);
    }
    free(cu);
    return SC_OK;
}

double sc_rig_leverage(const sc_rig_plan *p, int k, int j)
{
    const int np = p->np, i1 = j + p->d[k], i0 = j;
    if (!p->Zb || !p->det[i0] || !p->det[i1])
        return NAN;
    /* a_fᵀ B̃⁻¹ a_f over the free ends */
    double h = 0;
    const int ld = p->bw + 1, lo = i0 < i1 ? i0 : i1, off = abs(i1 - i0);
    if (!p->fixed[i1])
        h += p->Zb[(size_t)i1 * ld];
    if (!p->fixed[i0])
        h += p->Zb[(size_t)i0 * ld];
    if (!p->fixed[i0] && !p->fixed[i1])
        h -= 2 * p->Zb[(size_t)lo * ld + off];
    /* gᵀ S⁻¹ g, g = a_q - Zᵀ a_f */
    double g[MAXP], x[MAXP];
    row_params(p, k, j, g);
    for (int r = 0; r < np; ++r) {
        if (!p->fixed[i1])
            g[r] -= p->Z[(size_t)i1 * np + r];
        if (!p->fixed[i0])
            g[r] += p->Z[(size_t)i0 * np + r];
        x[r] = g[r];
    }
    small_solve(p->Sf, np, x);
    for (int r = 0; r < np; ++r)
        h += g[r] * x[r];
    return p->w[k] * h;
}
