/* Sparse LDLᵀ with nested dissection, pivot-tolerance rank decisions and the Takahashi selected
 * inverse. See sparse_ldl.h and docs/grid-lsq.md. */
#include "sparse_ldl.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- nested dissection ordering */

int sc_amd_order(int n, const long *ptr, const int *idx, int *perm);


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

/* Order the segment perm[lo, hi) (nodes labelled L) by minimum degree on its induced subgraph. */
static int nd_leaf_amd(nd_ws *w, int *perm, int lo, int hi, int L)
{
    int m = hi - lo;
    if (m < 3)
        return 0;
    long ne = 0;
    for (int t = lo; t < hi; ++t) {
        int v = perm[t];
        w->level[v] = t - lo; /* local index */
        ne += w->ptr[v + 1] - w->ptr[v];
    }
    long *sp = malloc(sizeof(long) * (size_t)(m + 1));
    int *si = malloc(sizeof(int) * (size_t)(ne + 1));
    int *sperm = malloc(sizeof(int) * (size_t)(m + 1));
    if (!sp || !si || !sperm) {
        free(sp), free(si), free(sperm);
        return -1;
    }
    sp[0] = 0;
    long a = 0;
    for (int t = 0; t < m; ++t) {
        int v = perm[lo + t];
        for (long p = w->ptr[v]; p < w->ptr[v + 1]; ++p)
            if (w->lab[w->idx[p]] == L)
                si[a++] = w->level[w->idx[p]];
        sp[t + 1] = a;
    }
    int rc = sc_amd_order(m, sp, si, sperm);
    if (rc == 0) {
        for (int t = 0; t < m; ++t)
            w->tmp[t] = perm[lo + sperm[t]];
        memcpy(perm + lo, w->tmp, sizeof(int) * (size_t)m);
    }
    free(sp), free(si), free(sperm);
    return rc;
}

int sc_nd_order(int n, const long *ptr, const int *idx, int *perm, int leaf, int amd_leaves)
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
        if (size <= leaf) {
            if (amd_leaves && nd_leaf_amd(&w, perm, lo, hi, L) != 0)
                goto nomem;
            continue;
        }
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
        if (h < 2) { /* (nearly) a clique */
            if (amd_leaves && nd_leaf_amd(&w, perm, lo, hi, L) != 0)
                goto nomem;
            continue;
        }
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
        int n1 = 0, n2 = 0;
        for (int q = 0; q < reached; ++q) {
            int v = w.queue[q];
            if (w.level[v] < m)
                n1++;
            else if (w.level[v] > m)
                n2++;
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
        memcpy(perm + lo, w.tmp, sizeof(int) * (size_t)size);
        stk[sp++] = lo, stk[sp++] = lo + n1, stk[sp++] = L1;
        stk[sp++] = lo + n1, stk[sp++] = lo + n1 + n2, stk[sp++] = L2;
    }
    free(w.lab), free(w.level), free(w.queue), free(w.stamp), free(w.tmp), free(stk), free(cnt);
    return 0;
nomem:
    free(w.lab), free(w.level), free(w.queue), free(w.stamp), free(w.tmp), free(stk), free(cnt);
    return -1;
}

/* ---------------------------------------------------------------- approximate minimum degree */

/* A growable list of ints. */
typedef struct ilist {
    int *v;
    int len, cap;
} ilist;

static int il_push(ilist *l, int x)
{
    if (l->len == l->cap) {
        int nc = l->cap ? 2 * l->cap : 4;
        int *nv = realloc(l->v, sizeof(int) * (size_t)nc);
        if (!nv)
            return -1;
        l->v = nv;
        l->cap = nc;
    }
    l->v[l->len++] = x;
    return 0;
}

/* Minimum degree on the quotient graph (variables and elements), with the approximate external
 * degree and aggressive element absorption of Amestoy, Davis & Duff (AMD, 1996); no
 * supervariables. */
int sc_amd_order(int n, const long *ptr, const int *idx, int *perm)
{
    ilist *A = calloc((size_t)n + 1, sizeof(ilist)); /* variable neighbours */
    ilist *E = calloc((size_t)n + 1, sizeof(ilist)); /* adjacent elements */
    ilist *Le = calloc((size_t)n + 1, sizeof(ilist)); /* element members */
    int *deg = malloc(sizeof(int) * (size_t)(n + 1));
    int *head = malloc(sizeof(int) * (size_t)(n + 1)); /* degree buckets */
    int *next = malloc(sizeof(int) * (size_t)(n + 1));
    int *prev = malloc(sizeof(int) * (size_t)(n + 1));
    int *w = malloc(sizeof(int) * (size_t)(n + 1));
    int *wstamp = malloc(sizeof(int) * (size_t)(n + 1));
    int *mark = malloc(sizeof(int) * (size_t)(n + 1));
    unsigned char *state = calloc((size_t)n + 1, 1); /* 0 variable, 1 element (live), 2 dead */
    int ok = A && E && Le && deg && head && next && prev && w && wstamp && mark && state;
    for (int i = 0; ok && i < n; ++i) {
        A[i].cap = (int)(ptr[i + 1] - ptr[i]);
        A[i].v = malloc(sizeof(int) * (size_t)(A[i].cap + 1));
        if (!A[i].v) {
            ok = 0;
            break;
        }
        for (long p = ptr[i]; p < ptr[i + 1]; ++p)
            if (idx[p] != i)
                A[i].v[A[i].len++] = idx[p];
    }
    if (ok) {
        for (int d = 0; d <= n; ++d)
            head[d] = -1;
        for (int i = 0; i < n; ++i) {
            deg[i] = A[i].len;
            wstamp[i] = -1;
            mark[i] = -1;
            next[i] = head[deg[i]];
            prev[i] = -1;
            if (head[deg[i]] >= 0)
                prev[head[deg[i]]] = i;
            head[deg[i]] = i;
        }
    }
    int mindeg = 0;
    for (int k = 0; ok && k < n; ++k) {
        while (mindeg < n && head[mindeg] < 0)
            mindeg++;
        int p = head[mindeg];
        /* unlink p */
        head[mindeg] = next[p];
        if (next[p] >= 0)
            prev[next[p]] = -1;
        perm[k] = p;
        state[p] = 1;
        /* L_p = (A_p ∪ L_e for e ∈ E_p) \ {p}, over variables */
        ilist *L = &Le[p];
        mark[p] = k;
        for (int t = 0; t < A[p].len; ++t) {
            int j = A[p].v[t];
            if (state[j] == 0 && mark[j] != k) {
                mark[j] = k;
                if (il_push(L, j)) ok = 0;
            }
        }
        for (int t = 0; t < E[p].len; ++t) {
            int e = E[p].v[t];
            if (state[e] != 1)
                continue;
            for (int s = 0; s < Le[e].len; ++s) {
                int j = Le[e].v[s];
                if (state[j] == 0 && mark[j] != k) {
                    mark[j] = k;
                    if (il_push(L, j)) ok = 0;
                }
            }
            state[e] = 2; /* absorbed into p */
            free(Le[e].v);
            Le[e].v = NULL;
            Le[e].len = Le[e].cap = 0;
        }
        free(A[p].v), free(E[p].v);
        A[p].v = E[p].v = NULL;
        A[p].len = E[p].len = A[p].cap = E[p].cap = 0;
        if (!ok)
            break;
        /* clean the lists of the members; |L_e \ L_p| for their other elements */
        for (int t = 0; t < L->len; ++t) {
            int i = L->v[t];
            int a = 0;
            for (int s = 0; s < A[i].len; ++s) {
                int j = A[i].v[s];
                if (state[j] == 0 && mark[j] != k)
                    A[i].v[a++] = j;
            }
            A[i].len = a;
            a = 0;
            for (int s = 0; s < E[i].len; ++s) {
                int e = E[i].v[s];
                if (state[e] != 1)
                    continue;
                E[i].v[a++] = e;
                if (wstamp[e] != k) {
                    wstamp[e] = k;
                    w[e] = Le[e].len;
                }
                w[e]--;
            }
            E[i].len = a;
            if (il_push(&E[i], p)) {
                ok = 0;
                break;
            }
        }
        if (!ok)
            break;
        /* approximate degrees; elements inside L_p are absorbed */
        int lp = L->len;
        for (int t = 0; t < lp; ++t) {
            int i = L->v[t];
            long d = A[i].len + (lp - 1);
            int a = 0;
            for (int s = 0; s < E[i].len; ++s) {
                int e = E[i].v[s];
                if (e != p && state[e] == 1 && w[e] == 0) {
                    state[e] = 2;
                    free(Le[e].v);
                    Le[e].v = NULL;
                    Le[e].len = Le[e].cap = 0;
                    continue;
                }
                if (state[e] != 1)
                    continue;
                E[i].v[a++] = e;
                if (e != p)
                    d += w[e];
            }
            E[i].len = a;
            if (d > n - k - 1)
                d = n - k - 1;
            /* move i to bucket d */
            if (prev[i] >= 0)
                next[prev[i]] = next[i];
            else
                head[deg[i]] = next[i];
            if (next[i] >= 0)
                prev[next[i]] = prev[i];
            deg[i] = (int)d;
            next[i] = head[d];
            prev[i] = -1;
            if (head[d] >= 0)
                prev[head[d]] = i;
            head[d] = i;
            if (d < mindeg)
                mindeg = (int)d;
        }
    }
    for (int i = 0; A && i < n; ++i)
        free(A[i].v);
    for (int i = 0; E && i < n; ++i)
        free(E[i].v);
    for (int i = 0; Le && i < n; ++i)
        free(Le[i].v);
    free(A), free(E), free(Le), free(deg), free(head), free(next), free(prev), free(w);
    free(wstamp), free(mark), free(state);
    return ok ? 0 : -1;
}

/* Multiply-adds of the LDLᵀ factorization of the graph's matrix under perm (column counts from
 * the elimination tree); -1 if memory ran out. */
double sc_order_flops(int n, const long *ptr, const int *idx, const int *perm)
{
    int *iperm = malloc(sizeof(int) * (size_t)(n + 1));
    int *parent = malloc(sizeof(int) * (size_t)(n + 1));
    int *flag = malloc(sizeof(int) * (size_t)(n + 1));
    long *cnt = calloc((size_t)n + 1, sizeof(long));
    if (!iperm || !parent || !flag || !cnt) {
        free(iperm), free(parent), free(flag), free(cnt);
        return -1;
    }
    for (int k = 0; k < n; ++k)
        iperm[perm[k]] = k;
    for (int k = 0; k < n; ++k) {
        parent[k] = -1;
        flag[k] = k;
        int v = perm[k];
        for (long p = ptr[v]; p < ptr[v + 1]; ++p) {
            int i = iperm[idx[p]];
            if (i >= k)
                continue;
            for (; flag[i] != k; i = parent[i]) {
                if (parent[i] == -1)
                    parent[i] = k;
                cnt[i]++;
                flag[i] = k;
            }
        }
    }
    double f = 0;
    for (int k = 0; k < n; ++k)
        f += (double)cnt[k] * (double)cnt[k];
    free(iperm), free(parent), free(flag), free(cnt);
    return f;
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
    if (!f->Zx || !f->Zd || !acc || !wl) {
        free(acc), free(wl);
        free(f->Zx), free(f->Zd);
        f->Zx = f->Zd = NULL;
        return -1;
    }
    f->bytes += (size_t)nz * sizeof(double) + (size_t)(n + 1) * sizeof(double);
    /* wl holds column j of L scattered (zero elsewhere), so the inner loop needs no test:
     * acc[r] for rows r outside S_j collects garbage that is never read (acc[i], i ∈ S_j, is
     * cleared first). */
    for (int j = n - 1; j >= 0; --j) {
        long p0 = f->Lp[j], p1 = f->Lp[j + 1];
        double dinv = f->D[j] != 0 ? 1.0 / f->D[j] : 0.0;
        for (long p = p0; p < p1; ++p) {
            int k = f->Li[p];
            wl[k] = f->Lx[p];
            acc[k] = 0;
        }
        for (long p = p0; p < p1; ++p) {
            int k = f->Li[p];
            double lkj = f->Lx[p], sk = f->Zd[k] * lkj;
            long q0 = f->Lp[k], q1 = f->Lp[k + 1];
            const int *ri = f->Li;
            const double *zx = f->Zx;
            f->selinv_work += (double)(q1 - q0);
            for (long q = q0; q < q1; ++q) {
                int r = ri[q];
                double z = zx[q]; /* Z_rk, r > k */
                acc[r] += z * lkj;
                sk += z * wl[r];
            }
            acc[k] += sk;
        }
        double zjj = dinv;
        for (long p = p0; p < p1; ++p) {
            int i = f->Li[p];
            f->Zx[p] = -acc[i];
            zjj += f->Lx[p] * acc[i];
            wl[i] = 0;
        }
        f->Zd[j] = f->D[j] != 0 ? zjj : 0.0;
        if (f->D[j] == 0)
            for (long p = p0; p < p1; ++p)
                f->Zx[p] = 0;
    }
    free(acc), free(wl);
    return 0;
}
