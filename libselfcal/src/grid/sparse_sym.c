/* The symmetric sparse solver of the grid area (sparse_sym.h), on the scalar LDLᵀ of
 * sparse_ldl.c: dense columns (the misalignments) are ordered last, the rest by the best of the
 * hand-written orderings, chosen once at analysis. */
#include "sparse_sym.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sparse_ldl.h"

struct sc_spsym {
    int n;
    int *perm, *iperm;  /* perm[k] = original index of pivot k */
    long *Pp;           /* permuted upper CSC */
    int *Pi;
    double *Px;
    long *map;          /* original entry p -> permuted entry */
    int ordering;
    int factored;
    sc_ldl f;
    double *work;
    size_t bytes;
};

void sc_spsym_destroy(sc_spsym *s)
{
    if (!s)
        return;
    free(s->perm), free(s->iperm), free(s->Pp), free(s->Pi), free(s->Px), free(s->map);
    free(s->work);
    sc_ldl_free(&s->f);
    free(s);
}

const char *sc_spsym_ordering_name(int ordering)
{
    static const char *names[] = {"nested dissection", "minimum degree", "ND + MD"};
    return ordering >= 0 && ordering < 3 ? names[ordering] : "?";
}

/* The order: columns of degree above a dense threshold last (in their index order), the others
 * by the cheapest of three hand-written orderings. */
static int order(sc_spsym *s, const long *Ap, const int *Ai)
{
    int n = s->n, rc = -1;
    long *deg = calloc((size_t)n + 1, sizeof(long));
    int *sub = malloc(sizeof(int) * ((size_t)n + 1)), *loc = malloc(sizeof(int) * ((size_t)n + 1));
    long *gp = NULL;
    int *gi = NULL, *alt = NULL, *best = NULL;
    if (!deg || !sub || !loc)
        goto out;
    for (int j = 0; j < n; ++j)
        for (long p = Ap[j]; p < Ap[j + 1]; ++p)
            if (Ai[p] != j)
                deg[j]++, deg[Ai[p]]++;
    double dense = 10 * sqrt((double)n);
    if (dense < 16)
        dense = 16;
    int m = 0, k = 0;
    for (int j = 0; j < n; ++j)
        loc[j] = deg[j] > dense ? -1 : m++;
    for (int j = 0; j < n; ++j)
        if (loc[j] >= 0)
            sub[loc[j]] = j;
    gp = calloc((size_t)m + 1, sizeof(long));
    if (!gp)
        goto out;
    for (int j = 0; j < n; ++j)
        for (long p = Ap[j]; p < Ap[j + 1]; ++p) {
            int i = Ai[p];
            if (i != j && loc[i] >= 0 && loc[j] >= 0)
                gp[loc[i] + 1]++, gp[loc[j] + 1]++;
        }
    for (int t = 0; t < m; ++t)
        gp[t + 1] += gp[t];
    gi = malloc(sizeof(int) * ((size_t)gp[m] + 1));
    alt = malloc(sizeof(int) * ((size_t)m + 1));
    best = malloc(sizeof(int) * ((size_t)m + 1));
    if (!gi || !alt || !best)
        goto out;
    memcpy(deg, gp, sizeof(long) * (size_t)m);
    for (int j = 0; j < n; ++j)
        for (long p = Ap[j]; p < Ap[j + 1]; ++p) {
            int i = Ai[p];
            if (i != j && loc[i] >= 0 && loc[j] >= 0) {
                gi[deg[loc[i]]++] = loc[j];
                gi[deg[loc[j]]++] = loc[i];
            }
        }
    double fbest = -1;
    for (int o = 0; o < 3; ++o) {
        int r = o == 0   ? sc_nd_order(m, gp, gi, alt, 48, 0)
                : o == 1 ? sc_amd_order(m, gp, gi, alt)
                         : sc_nd_order(m, gp, gi, alt, 2000, 1);
        if (r != 0)
            goto out;
        double f = sc_order_flops(m, gp, gi, alt);
        if (f >= 0 && (fbest < 0 || f < fbest)) {
            fbest = f;
            s->ordering = o;
            memcpy(best, alt, sizeof(int) * (size_t)m);
        }
    }
    for (int t = 0; t < m; ++t)
        s->perm[k++] = sub[best[t]];
    for (int j = 0; j < n; ++j)
        if (loc[j] < 0)
            s->perm[k++] = j;
    for (int t = 0; t < n; ++t)
        s->iperm[s->perm[t]] = t;
    rc = 0;
out:
    free(deg), free(sub), free(loc), free(gp), free(gi), free(alt), free(best);
    return rc;
}

int sc_spsym_analyze(int n, const long *Ap, const int *Ai, sc_spsym **out)
{
    *out = NULL;
    sc_spsym *s = calloc(1, sizeof *s);
    if (!s)
        return -1;
    s->n = n;
    long nnz = Ap[n];
    s->perm = malloc(sizeof(int) * ((size_t)n + 1));
    s->iperm = malloc(sizeof(int) * ((size_t)n + 1));
    s->Pp = calloc((size_t)n + 1, sizeof(long));
    s->Pi = malloc(sizeof(int) * ((size_t)nnz + 1));
    s->Px = malloc(sizeof(double) * ((size_t)nnz + 1));
    s->map = malloc(sizeof(long) * ((size_t)nnz + 1));
    s->work = malloc(sizeof(double) * ((size_t)n + 1));
    if (!s->perm || !s->iperm || !s->Pp || !s->Pi || !s->Px || !s->map || !s->work ||
        order(s, Ap, Ai) != 0) {
        sc_spsym_destroy(s);
        return -1;
    }
    for (int j = 0; j < n; ++j)
        for (long p = Ap[j]; p < Ap[j + 1]; ++p) {
            int pi = s->iperm[Ai[p]], pj = s->iperm[j];
            s->Pp[(pi > pj ? pi : pj) + 1]++;
        }
    for (int k = 0; k < n; ++k)
        s->Pp[k + 1] += s->Pp[k];
    long *fill = malloc(sizeof(long) * ((size_t)n + 1));
    if (!fill) {
        sc_spsym_destroy(s);
        return -1;
    }
    memcpy(fill, s->Pp, sizeof(long) * (size_t)n);
    for (int j = 0; j < n; ++j)
        for (long p = Ap[j]; p < Ap[j + 1]; ++p) {
            int pi = s->iperm[Ai[p]], pj = s->iperm[j];
            long at = fill[pi > pj ? pi : pj]++;
            s->Pi[at] = pi > pj ? pj : pi;
            s->map[p] = at;
        }
    free(fill);
    s->bytes = sizeof *s + (size_t)nnz * (sizeof(int) + sizeof(double) + sizeof(long)) +
               (size_t)(n + 1) * (2 * sizeof(int) + sizeof(long) + sizeof(double));
    *out = s;
    return 0;
}

int sc_spsym_factor(sc_spsym *s, const double *Ax, double tol)
{
    long nnz = s->Pp[s->n];
    for (long p = 0; p < nnz; ++p)
        s->Px[s->map[p]] = Ax[p];
    sc_ldl_free(&s->f);
    s->factored = 0;
    if (sc_ldl_factor(&s->f, s->n, s->Pp, s->Pi, s->Px, tol) != 0)
        return -1;
    s->factored = 1;
    return 0;
}

int sc_spsym_nullity(const sc_spsym *s)
{
    return s->f.n_null;
}

int sc_spsym_solve(const sc_spsym *s, double *x)
{
    int n = s->n;
    double *b = s->work;
    for (int i = 0; i < n; ++i)
        b[s->iperm[i]] = x[i];
    sc_ldl_solve(&s->f, b);
    for (int i = 0; i < n; ++i)
        x[i] = b[s->iperm[i]];
    return 0;
}

void sc_spsym_matvec(const sc_spsym *s, const double *x, double *y)
{
    int n = s->n;
    for (int i = 0; i < n; ++i)
        y[i] = 0;
    for (int j = 0; j < n; ++j)
        for (long p = s->Pp[j]; p < s->Pp[j + 1]; ++p) {
            int i = s->Pi[p];
            double a = s->Px[p];
            int oi = s->perm[i], oj = s->perm[j];
            y[oi] += a * x[oj];
            if (i != j)
                y[oj] += a * x[oi];
        }
}

int sc_spsym_selinv(sc_spsym *s)
{
    return sc_ldl_selinv(&s->f);
}

double sc_spsym_inv(const sc_spsym *s, int i, int j)
{
    if (!s->f.Zd)
        return NAN;
    int pi = s->iperm[i], pj = s->iperm[j];
    if (pi == pj)
        return s->f.Zd[pi];
    int col = pi < pj ? pi : pj, row = pi < pj ? pj : pi;
    long lo = s->f.Lp[col], hi = s->f.Lp[col + 1];
    while (lo < hi) { /* rows ascending within a column */
        long mid = lo + (hi - lo) / 2;
        if (s->f.Li[mid] < row)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < s->f.Lp[col + 1] && s->f.Li[lo] == row ? s->f.Zx[lo] : NAN;
}

void sc_spsym_get_stats(const sc_spsym *s, sc_spsym_stats *st)
{
    memset(st, 0, sizeof *st);
    st->nnz_factor = s->f.Lp ? s->f.Lp[s->n] : 0;
    st->factor_flops = s->f.flops;
    st->selinv_work = s->f.selinv_work;
    st->ordering = s->ordering;
    st->n_null = s->f.n_null;
    st->min_kept_ratio = s->f.min_kept_ratio;
    st->max_null_ratio = s->f.max_null_ratio;
    st->bytes = s->bytes + s->f.bytes;
}
