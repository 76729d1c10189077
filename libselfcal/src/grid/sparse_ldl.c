/* Sparse LDLᵀ with nested dissection, pivot-tolerance rank decisions and the Takahashi selected
 * inverse. See sparse_ldl.h and docs/grid-lsq.md. */
#include "sparse_ldl.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- nested dissection ordering */

#define ND_LEAF 48

typedef struct nd_ws {
    const long *ptr;
    const int *idx;
    int *lab, *level, *queue, *stamp, *tmp;
    int cur_stamp;
} nd_ws;

/* Breadth-first search from s over nodes labelled L; fills queue (BFS order) and level.
 * Returns the number of nodes reached; *height = the last level. */
static int nd_bfs(nd_ws *w, int s, int L, int *height)
{
    int head = 0, tail = 0;
    w->cur_stamp++;
    w->queue[tail++] = s;
    w->stamp[s] = w->cur_stamp;
    w->level[s] = 0;
    while (head < tail) {
        int v = w->queue[head++];
        for (long p = w->ptr[v]; p < w->ptr[v + 1]; ++p) {
            int u = w->idx[p];
            if (w->lab[u] != L || w->stamp[u] == w->cur_stamp)
                continue;
            w->stamp[u] = w->cur_stamp;
            w->level[u] = w->level[v] + 1;
            w->queue[tail++] = u;
        }
    }
    *height = w->level[w->queue[tail - 1]];
    return tail;
}

int sc_nd_order(int n, const long *ptr, const int *idx, int *perm)
{
    nd_ws w;
    memset(&w, 0, sizeof w);
    w.ptr = ptr;
    w.idx = idx;
    w.lab = malloc(sizeof(int) * (size_t)(n + 1));
    w.level = malloc(sizeof(int) * (size_t)(n + 1));
    w.queue = malloc(sizeof(int) * (size_t)(n + 1));
    w.stamp = calloc((size_t)n + 1, sizeof(int));
    w.tmp = malloc(sizeof(int) * (size_t)(n + 1));
    int *stk = malloc(sizeof(int) * (size_t)(3 * (n + 2)));
    int *cnt = malloc(sizeof(int) * (size_t)(n + 2));
    if (!w.lab || !w.level || !w.queue || !w.stamp || !w.tmp || !stk || !cnt) {
        free(w.lab), free(w.level), free(w.queue), free(w.stamp), free(w.tmp), free(stk), free(cnt);
        return -1;
    }
    for (int i = 0; i < n; ++i) {
        perm[i] = i;
        w.lab[i] = 0;
    }
    int next_label = 1, sp = 0;
    stk[sp++] = 0, stk[sp++] = n, stk[sp++] = 0;
    while (sp > 0) {
        int L = stk[--sp], hi = stk[--sp], lo = stk[--sp];
        int size = hi - lo;
        if (size <= ND_LEAF)
            continue;
        int h, start = perm[lo];
        int reached = nd_bfs(&w, start, L, &h);
        int L1 = next_label++, L2 = next_label++;
        if (reached < size) {
            /* disconnected: the component reached, then the rest */
            for (int q = 0; q < reached; ++q)
                w.lab[w.queue[q]] = L1;
            int a = 0;
            for (int q = 0; q < reached; ++q)
                w.tmp[a++] = w.queue[q];
            for (int q = lo; q < hi; ++q)
                if (w.lab[perm[q]] == L) {
                    w.lab[perm[q]] = L2;
                    w.tmp[a++] = perm[q];
                }
            memcpy(perm + lo, w.tmp, sizeof(int) * (size_t)size);
            stk[sp++] = lo, stk[sp++] = lo + reached, stk[sp++] = L1;
            stk[sp++] = lo + reached, stk[sp++] = hi, stk[sp++] = L2;
            continue;
        }
        /* pseudo-peripheral start: move to the far end while the height grows */
        for (int it = 0; it < 6; ++it) {
            int cand = w.queue[reached - 1], h2;
            nd_bfs(&w, cand, L, &h2);
            if (h2 <= h) {
                h = h2; /* the level structure in place is cand's */
                break;
            }
            h = h2;
            start = cand;
        }
        if (h < 2)
            continue; /* (nearly) a clique: order as it is */
        for (int l = 0; l <= h; ++l)
            cnt[l] = 0;
        for (int q = 0; q < reached; ++q)
            cnt[w.level[w.queue[q]]]++;
        /* Candidate separators: level l, thinned to the vertices that have a neighbour in
         * level l+1 (the others are moved to the lower part: they touch nothing above). Among
         * the levels that keep both parts >= size/4, take the smallest separator. */
        int m = -1, best_sep = 1 << 30;
        {
            int cum = 0;
            for (int l = 0; l <= h; ++l) {
                int below = cum;
                cum += cnt[l];
                if (l < 1 || l > h - 1)
                    continue;
                int need = 0;
                for (int q = 0; q < reached; ++q) {
                    int v = w.queue[q];
                    if (w.level[v] != l)
                        continue;
                    for (long pp = ptr[v]; pp < ptr[v + 1]; ++pp) {
                        int u = idx[pp];
                        if (w.lab[u] == L && w.stamp[u] == w.cur_stamp && w.level[u] == l + 1) {
                            need++;
                            break;
                        }
                    }
                }
                int lower = below + cnt[l] - need, upper = size - below - cnt[l];
                if (lower * 4 < size || upper * 4 < size)
                    continue;
                if (need < best_sep)
                    best_sep = need, m = l;
            }
        }
        if (m < 0) {
            int cum = 0;
            m = 0;
            while (m < h && cum + cnt[m] < size / 2)
                cum += cnt[m++];
            if (m < 1)
                m = 1;
            if (m > h - 1)
                m = h - 1;
        }
        /* thin: separator vertices of level m without a neighbour in level m+1 go down */
        for (int q = 0; q < reached; ++q) {
            int v = w.queue[q];
            if (w.level[v] != m)
                continue;
            int up = 0;
            for (long pp = ptr[v]; pp < ptr[v + 1] && !up; ++pp) {
                int u = idx[pp];
                up = w.lab[u] == L && w.stamp[u] == w.cur_stamp && w.level[u] == m + 1;
            }
            if (!up)
                w.level[v] = m - 1;
        }
        int n1 = 0, n2 = 0, ns = 0;
        for (int q = 0; q < reached; ++q) {
            int v = w.queue[q];
            if (w.level[v] < m)
                n1++;
            else if (w.level[v] > m)
                n2++;
            else
                ns++;
        }
        int a1 = 0, a2 = n1, as = n1 + n2;
        for (int q = 0; q < reached; ++q) {
            int v = w.queue[q];
            if (w.level[v] < m) {
                w.tmp[a1++] = v;
                w.lab[v] = L1;
            } else if (w.level[v] > m) {
                w.tmp[a2++] = v;
                w.lab[v] = L2;
            } else {
                w.tmp[as++] = v;
                w.lab[v] = -1;
            }
        }
        (void)ns;
        memcpy(perm + lo, w.tmp, sizeof(int) * (size_t)size);
        stk[sp++] = lo, stk[sp++] = lo + n1, stk[sp++] = L1;
        stk[sp++] = lo + n1, stk[sp++] = lo + n1 + n2, stk[sp++] = L2;
    }
    free(w.lab), free(w.level), free(w.queue), free(w.stamp), free(w.tmp), free(stk), free(cnt);
    return 0;
}

/* ---------------------------------------------------------------- factorization */

void sc_ldl_free(sc_ldl *f)
{
    if (!f)
        return;
    free(f->parent), free(f->Lp), free(f->Li), free(f->Lx), free(f->D), free(f->Zx), free(f->Zd);
    memset(f, 0, sizeof *f);
}

int sc_ldl_factor(sc_ldl *f, int n, const long *Ap, const int *Ai, const double *Ax, double tol)
{
    memset(f, 0, sizeof *f);
    f->n = n;
    f->Ap = Ap;
    f->Ai = Ai;
    f->Ax = Ax;
    f->parent = malloc(sizeof(int) * (size_t)(n + 1));
    f->Lp = malloc(sizeof(long) * (size_t)(n + 1));
    f->D = malloc(sizeof(double) * (size_t)(n + 1));
    int *flag = malloc(sizeof(int) * (size_t)(n + 1));
    long *lnz = malloc(sizeof(long) * (size_t)(n + 1));
    int *pattern = malloc(sizeof(int) * (size_t)(n + 1));
    double *y = calloc((size_t)n + 1, sizeof(double));
    if (!f->parent || !f->Lp || !f->D || !flag || !lnz || !pattern || !y)
        goto nomem;
    /* symbolic: elimination tree and column counts */
    for (int k = 0; k < n; ++k) {
        f->parent[k] = -1;
        flag[k] = k;
        lnz[k] = 0;
        for (long p = Ap[k]; p < Ap[k + 1]; ++p) {
            int i = Ai[p];
            if (i >= k)
                continue;
            for (; flag[i] != k; i = f->parent[i]) {
                if (f->parent[i] == -1)
                    f->parent[i] = k;
                lnz[i]++;
                flag[i] = k;
            }
        }
    }
    f->Lp[0] = 0;
    for (int k = 0; k < n; ++k) {
        f->Lp[k + 1] = f->Lp[k] + lnz[k];
        f->flops += (double)lnz[k] * (double)lnz[k];
    }
    long nz = f->Lp[n];
    f->Li = malloc(sizeof(int) * (size_t)(nz + 1));
    f->Lx = malloc(sizeof(double) * (size_t)(nz + 1));
    if (!f->Li || !f->Lx)
        goto nomem;
    f->bytes = (size_t)nz * (sizeof(int) + sizeof(double)) +
               (size_t)(n + 1) * (sizeof(int) + sizeof(long) + sizeof(double));
    /* numeric, up-looking */
    f->min_kept_ratio = INFINITY;
    f->max_null_ratio = 0;
    for (int k = 0; k < n; ++k) {
        int top = n;
        double akk = 0;
        y[k] = 0;
        flag[k] = k;
        lnz[k] = 0;
        for (long p = Ap[k]; p < Ap[k + 1]; ++p) {
            int i = Ai[p];
            if (i > k)
                continue;
            y[i] += Ax[p];
            if (i == k)
                akk += Ax[p];
            int len = 0;
            for (; flag[i] != k; i = f->parent[i]) {
                pattern[len++] = i;
                flag[i] = k;
            }
            while (len > 0)
                pattern[--top] = pattern[--len];
        }
        double dk = y[k];
        y[k] = 0;
        for (; top < n; ++top) {
            int i = pattern[top];
            double yi = y[i];
            y[i] = 0;
            long p2 = f->Lp[i] + lnz[i], p;
            for (p = f->Lp[i]; p < p2; ++p)
                y[f->Li[p]] -= f->Lx[p] * yi;
            double lki = f->D[i] != 0 ? yi / f->D[i] : 0.0;
            dk -= lki * yi;
            f->Li[p] = k;
            f->Lx[p] = lki;
            lnz[i]++;
        }
        double ratio = akk > 0 ? dk / akk : 0.0;
        if (!(akk > 0) || !(ratio > tol)) {
            f->D[k] = 0;
            f->n_null++;
            if (ratio > f->max_null_ratio)
                f->max_null_ratio = ratio;
        } else {
            f->D[k] = dk;
            if (ratio < f->min_kept_ratio)
                f->min_kept_ratio = ratio;
        }
    }
    free(flag), free(lnz), free(pattern), free(y);
    return 0;
nomem:
    free(flag), free(lnz), free(pattern), free(y);
    sc_ldl_free(f);
    return -1;
}

void sc_ldl_solve(const sc_ldl *f, double *x)
{
    int n = f->n;
    for (int j = 0; j < n; ++j) {
        double xj = x[j];
        if (xj != 0)
            for (long p = f->Lp[j]; p < f->Lp[j + 1]; ++p)
                x[f->Li[p]] -= f->Lx[p] * xj;
    }
    for (int j = 0; j < n; ++j)
        x[j] = f->D[j] != 0 ? x[j] / f->D[j] : 0.0;
    for (int j = n - 1; j >= 0; --j) {
        double s = x[j];
        for (long p = f->Lp[j]; p < f->Lp[j + 1]; ++p)
            s -= f->Lx[p] * x[f->Li[p]];
        x[j] = f->D[j] != 0 ? s : 0.0;
    }
}

void sc_ldl_matvec(const sc_ldl *f, const double *x, double *y)
{
    int n = f->n;
    for (int j = 0; j < n; ++j)
        y[j] = 0;
    for (int j = 0; j < n; ++j)
        for (long p = f->Ap[j]; p < f->Ap[j + 1]; ++p) {
            int i = f->Ai[p];
            if (i > j)
                continue;
            y[i] += f->Ax[p] * x[j];
            if (i != j)
                y[j] += f->Ax[p] * x[i];
        }
}

/* Takahashi: Z = D⁻¹L⁻¹ + (I - Lᵀ)Z gives, column by column from the last,
 * Z_ij = -Σ_{k∈S_j} Z_ik L_kj (i ∈ S_j) and Z_jj = 1/d_j - Σ_{k∈S_j} L_kj Z_kj, with S_j the
 * pattern of column j of L. S_j ∪ {j} is a clique of the filled graph and, for i ∈ S_j, every
 * k ∈ S_j with k > i lies in S_i, so all Z_ik needed are on L's pattern. */
int sc_ldl_selinv(sc_ldl *f)
{
    int n = f->n;
    long nz = f->Lp[n];
    free(f->Zx), free(f->Zd);
    f->Zx = malloc(sizeof(double) * (size_t)(nz + 1));
    f->Zd = malloc(sizeof(double) * (size_t)(n + 1));
    double *acc = calloc((size_t)n + 1, sizeof(double));
    double *wl = calloc((size_t)n + 1, sizeof(double));
    int *mark = malloc(sizeof(int) * (size_t)(n + 1));
    if (!f->Zx || !f->Zd || !acc || !wl || !mark) {
        free(acc), free(wl), free(mark);
        free(f->Zx), free(f->Zd);
        f->Zx = f->Zd = NULL;
        return -1;
    }
    f->bytes += (size_t)nz * sizeof(double) + (size_t)(n + 1) * sizeof(double);
    for (int i = 0; i < n; ++i)
        mark[i] = -1;
    for (int j = n - 1; j >= 0; --j) {
        long p0 = f->Lp[j], p1 = f->Lp[j + 1];
        double dinv = f->D[j] != 0 ? 1.0 / f->D[j] : 0.0;
        for (long p = p0; p < p1; ++p) {
            int k = f->Li[p];
            mark[k] = j;
            wl[k] = f->Lx[p];
            acc[k] = 0;
        }
        for (long p = p0; p < p1; ++p) {
            int k = f->Li[p];
            double lkj = f->Lx[p];
            acc[k] += f->Zd[k] * lkj;
            f->selinv_work += (double)(f->Lp[k + 1] - f->Lp[k]);
            for (long q = f->Lp[k]; q < f->Lp[k + 1]; ++q) {
                int r = f->Li[q];
                if (mark[r] != j)
                    continue;
                double z = f->Zx[q]; /* Z_rk, r > k */
                acc[r] += z * lkj;
                acc[k] += z * wl[r];
            }
        }
        double zjj = dinv;
        for (long p = p0; p < p1; ++p) {
            int i = f->Li[p];
            f->Zx[p] = -acc[i];
            zjj += f->Lx[p] * acc[i];
        }
        f->Zd[j] = f->D[j] != 0 ? zjj : 0.0;
        if (f->D[j] == 0)
            for (long p = p0; p < p1; ++p)
                f->Zx[p] = 0;
    }
    free(acc), free(wl), free(mark);
    return 0;
}
