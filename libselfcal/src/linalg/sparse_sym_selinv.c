/* The supernodal selected inverse of the sparse symmetric solver (sparse_sym.h; the recurrences
 * are described at the top of sparse_sym.c and in docs/grid-lsq.md): Takahashi's recurrences on
 * CHOLMOD's supernodes with the dense kernels of the loaded BLAS/LAPACK, the entries kept, and
 * their accessors. */
#include "sparse_sym_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/big_alloc.h"

/* The supernodal elimination tree: parent[J] (-1 at a root) is the supernode holding J's first
 * row below its diagonal block; first[J] the lowest-numbered supernode of J's subtree (CHOLMOD
 * numbers supernodes in postorder, so J's subtree is first[J] .. J). */
static void super_tree(const cholmod_factor *L, const int *col2super, int *parent, int *first)
{
    const int *Super = L->super, *Lpi = L->pi, *Ls = L->s;
    int nsuper = (int)L->nsuper;
    for (int J = 0; J < nsuper; ++J) {
        int nc = Super[J + 1] - Super[J], nr = Lpi[J + 1] - Lpi[J];
        parent[J] = nr > nc ? col2super[Ls[Lpi[J] + nc]] : -1;
        first[J] = J;
    }
    for (int J = 0; J < nsuper; ++J)
        if (parent[J] >= 0 && parent[J] <= J) { /* not a postorder: keep every block to the end */
            for (int S = 0; S < nsuper; ++S)
                first[S] = 0;
            return;
        }
    for (int J = 0; J < nsuper; ++J)
        if (parent[J] >= 0 && first[J] < first[parent[J]])
            first[parent[J]] = first[J];
}

/* Entries of A in its first keep columns by the earlier pivot of their two ends: the entries p
 * whose pivot min(iperm[i], iperm[j]) is k are bucket[ptr[k] .. ptr[k+1]), each as p when that
 * pivot is its column's (the other end is its row Ai[p]), else as -1 - j (the other end is its
 * column j; p is found in column j by its row). No second index per entry: the selected inverse
 * holds these at its peak. */
static int bucket_entries(const sc_spsym *s, long **ptr_out, int **bucket_out)
{
    int n = s->n, keep = s->keep_cols;
    long nnz = s->Ap[keep], *ptr = calloc((size_t)n + 1, sizeof(long));
    int *bucket = sc_big_alloc((size_t)nnz + 1, sizeof(int), 0); /* nnz < 2^31 (analyze) */
    long *fill = malloc(sizeof(long) * ((size_t)n + 1));
    if (!ptr || !bucket || !fill) {
        free(ptr), free(bucket), free(fill);
        return -1;
    }
    for (int j = 0; j < keep; ++j)
        for (long p = s->Ap[j]; p < s->Ap[j + 1]; ++p) {
            int a = s->iperm[s->Ai[p]], b = s->iperm[j];
            ptr[(a < b ? a : b) + 1]++;
        }
    for (int k = 0; k < n; ++k)
        ptr[k + 1] += ptr[k];
    memcpy(fill, ptr, sizeof(long) * (size_t)n);
    for (int j = 0; j < keep; ++j)
        for (long p = s->Ap[j]; p < s->Ap[j + 1]; ++p) {
            int a = s->iperm[s->Ai[p]], b = s->iperm[j];
            bucket[fill[a < b ? a : b]++] = b <= a ? (int)p : -1 - j;
        }
    free(fill);
    *ptr_out = ptr, *bucket_out = bucket;
    return 0;
}

/* The position of row r among rows[lo .. hi) (ascending when sorted, else in any order), or -1:
 * an entry of A's pattern (sc_spsym_inv, the selected inverse's extraction) or of the fallback's
 * factor. */
static long find_row(const int *rows, long lo, long hi, int r, int sorted)
{
    if (!sorted) {
        for (long p = lo; p < hi; ++p)
            if (rows[p] == r)
                return p;
        return -1;
    }
    long end = hi;
    while (lo < hi) {
        long mid = lo + (hi - lo) / 2;
        if (rows[mid] < r)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < end && rows[lo] == r ? lo : -1;
}

/* Fronts with more rows below their diagonal block than this take Z_RR · L̂ panel by panel (one
 * ancestor's columns of Z_RR at a time) instead of gathering Z_RR whole: the m² workspace of the
 * largest front would otherwise set the selected inverse's peak memory (14 MB at N = 201). */
#define ZRR_MAX 256

/* Workspace of the streaming selected inverse. */
typedef struct selinv_ws {
    double **Z;          /* per supernode: its block of the inverse (nr x nc), while needed */
    int *parent, *first; /* supernodal tree (super_tree) */
    int *map;            /* n: relative row map */
    int *rel;            /* maxm: rows' places in an ancestor (relative_rows) */
    double *Zrr, *W, *Y; /* dense blocks: m x m (m <= ZRR_MAX), m x nc, m x nc */
    double *P;           /* a panel of Z_RR from one ancestor (larger fronts): m x nc */
    double *Gt;          /* the tracked columns' rows R: n_track x m */
    double *Tt;          /* their product for one supernode: n_track x nc */
    int *miss;           /* n_track: the tracked pivots not among a supernode's rows */
    long *bptr;          /* A's entries by factor column (bucket_entries) */
    int *bucket;
} selinv_ws;

static void selinv_ws_free(selinv_ws *w, int nsuper)
{
    for (int J = 0; w->Z && J < nsuper; ++J)
        free(w->Z[J]);
    free(w->Z), free(w->parent), free(w->first), free(w->map), free(w->Zrr), free(w->P), free(w->W);
    free(w->Y), free(w->Gt), free(w->Tt), free(w->miss), free(w->bptr), free(w->bucket);
    free(w->rel);
}

static int selinv_ws_alloc(sc_spsym *s, selinv_ws *w)
{
    const cholmod_factor *L = s->L;
    int n = s->n, nsuper = (int)L->nsuper, maxm = 0, maxc = 0;
    const int *Super = L->super, *Lpi = L->pi;
    memset(w, 0, sizeof *w);
    for (int J = 0; J < nsuper; ++J) {
        int nc = Super[J + 1] - Super[J], m = Lpi[J + 1] - Lpi[J] - nc;
        maxm = m > maxm ? m : maxm;
        maxc = nc > maxc ? nc : maxc;
    }
    s->col2super = malloc(sizeof(int) * ((size_t)n + 1));
    s->Zd = malloc(sizeof(double) * ((size_t)n + 1));
    s->ZA = sc_big_alloc((size_t)s->Ap[s->keep_cols] + 1, sizeof(double), 0);
    w->Z = calloc((size_t)nsuper + 1, sizeof(double *));
    w->parent = malloc(sizeof(int) * ((size_t)nsuper + 1));
    w->first = malloc(sizeof(int) * ((size_t)nsuper + 1));
    w->map = malloc(sizeof(int) * ((size_t)n + 1));
    int mz = maxm < ZRR_MAX ? maxm : ZRR_MAX;
    w->Zrr = malloc(sizeof(double) * ((size_t)mz * mz + 1));
    w->P = maxm > ZRR_MAX ? malloc(sizeof(double) * ((size_t)maxm * maxc + 1)) : NULL;
    w->W = malloc(sizeof(double) * ((size_t)maxm * maxc + 1));
    w->Y = malloc(sizeof(double) * ((size_t)maxm * maxc + 1));
    w->Gt = malloc(sizeof(double) * ((size_t)s->n_track * maxm + 1));
    w->Tt = malloc(sizeof(double) * ((size_t)s->n_track * maxc + 1));
    w->miss = malloc(sizeof(int) * ((size_t)s->n_track + 1));
    w->rel = malloc(sizeof(int) * ((size_t)maxm + 1));
    if (!s->col2super || !s->Zd || !s->ZA || !w->Z || !w->parent || !w->first || !w->map ||
        !w->Zrr || (maxm > ZRR_MAX && !w->P) || !w->W || !w->Y || !w->Gt || !w->Tt || !w->miss ||
        !w->rel || bucket_entries(s, &w->bptr, &w->bucket) != 0)
        return -1;
    for (int J = 0; J < nsuper; ++J)
        for (int k = Super[J]; k < Super[J + 1]; ++k)
            s->col2super[k] = J;
    super_tree(L, s->col2super, w->parent, w->first);
    return 0;
}

/* rel[a - b] := the place of row R[a] among the rows of an ancestor supernode (rowsS, nrS
 * ascending, as CHOLMOD keeps a supernode's rows), for a in [b, m): R[b..m) are all rows of it
 * (R is a clique of the filled graph), so one walk from R[b]'s place (find_row's binary search)
 * finds them, instead of mapping every row of the ancestor for each descendant. */
static void relative_rows(const int *rowsS, int nrS, const int *R, int b, int m, int *rel)
{
    long at = find_row(rowsS, 0, nrS, R[b], 1);
    for (int a = b, t = at < 0 ? 0 : (int)at; a < m; ++a) {
        while (t < nrS - 1 && rowsS[t] != R[a]) /* bounded: found for CHOLMOD's factors */
            ++t;
        rel[a - b] = t++;
    }
}

/* Z_J (nr x nc, column-major, lower part) of supernode J from its ancestors' blocks: Z_JJ =
 * (L_JJ L_JJᵀ)⁻¹ + L̂ᵀ Z_RR L̂ and Z_RJ = −Z_RR L̂ with L̂ = L_RJ L_JJ⁻¹. Returns the work done,
 * or -1 (LAPACK failed). */
static double super_block(sc_spsym *s, selinv_ws *w, int J, double *Zj)
{
    const cholmod_factor *L = s->L;
    const cholmod_api *A = s->api;
    const double one = 1.0, zero = 0.0;
    const int *Super = L->super, *Lpi = L->pi, *Lpx = L->px, *Ls = L->s;
    int nc = Super[J + 1] - Super[J], nr = Lpi[J + 1] - Lpi[J], m = nr - nc, info = 0;
    const int *R = Ls + Lpi[J] + nc;
    const double *Ljj = (const double *)L->x + Lpx[J];
    for (int c = 0; c < nc; ++c)
        memcpy(Zj + (size_t)c * nr + c, Ljj + (size_t)c * nr + c, sizeof(double) * (nc - c));
    A->dpotri("L", &nc, Zj, &nr, &info, 1);
    if (info != 0)
        return -1;
    if (m == 0)
        return (double)nc * nc * nc / 3;
    for (int c = 0; c < nc; ++c)
        memcpy(w->W + (size_t)c * m, Ljj + (size_t)c * nr + nc, sizeof(double) * m);
    A->dtrsm("R", "L", "N", "N", &m, &nc, &one, Ljj, &nr, w->W, &m, 1, 1, 1, 1);
    if (m <= ZRR_MAX) {
        /* gather Z_RR (lower triangle, m x m) from the blocks of R's supernodes (ancestors) */
        for (int b = 0; b < m;) {
            int S = s->col2super[R[b]], p0 = Lpi[S], nrS = Lpi[S + 1] - p0, b0 = b;
            relative_rows(Ls + p0, nrS, R, b0, m, w->rel);
            for (; b < m && s->col2super[R[b]] == S; ++b) {
                const double *zc = w->Z[S] + (size_t)(R[b] - Super[S]) * nrS;
                double *dst = w->Zrr + (size_t)b * m;
                for (int a = b; a < m; ++a)
                    dst[a] = zc[w->rel[a - b0]];
            }
        }
        A->dsymm("L", "L", &m, &nc, &one, w->Zrr, &m, w->W, &m, &zero, w->Y, &m, 1, 1);
    } else {
        /* Y = Z_RR L̂ panel by panel: the columns R[b..e) of one ancestor S give the panel
         * P = Z(R[b..m), R[b..e)) (its top square made symmetric), and Y[b..m) += P L̂[b..e),
         * Y[b..e) += P[e-b..]ᵀ L̂[e..m) (the part of Z_RR above the panel, by symmetry) */
        memset(w->Y, 0, sizeof(double) * (size_t)m * nc);
        for (int b = 0; b < m;) {
            int S = s->col2super[R[b]], p0 = Lpi[S], nrS = Lpi[S + 1] - p0, e = b;
            while (e < m && s->col2super[R[e]] == S)
                ++e;
            int pr = m - b, pc = e - b, below = m - e;
            relative_rows(Ls + p0, nrS, R, b, m, w->rel);
            for (int c = b; c < e; ++c) {
                const double *zc = w->Z[S] + (size_t)(R[c] - Super[S]) * nrS;
                double *dst = w->P + (size_t)(c - b) * pr;
                for (int a = c; a < m; ++a)
                    dst[a - b] = zc[w->rel[a - b]];
                for (int a = b; a < c; ++a) /* the top square's upper part */
                    dst[a - b] = w->P[(size_t)(a - b) * pr + (c - b)];
            }
            A->dgemm("N", "N", &pr, &nc, &pc, &one, w->P, &pr, w->W + b, &m, &one, w->Y + b, &m,
                     1, 1);
            if (below > 0)
                A->dgemm("T", "N", &pc, &nc, &below, &one, w->P + pc, &pr, w->W + e, &m, &one,
                         w->Y + b, &m, 1, 1);
            b = e;
        }
    }
    for (int c = 0; c < nc; ++c) {
        double *zc = Zj + (size_t)c * nr + nc;
        const double *yc = w->Y + (size_t)c * m;
        for (int a = 0; a < m; ++a)
            zc[a] = -yc[a];
    }
    A->dgemm("T", "N", &nc, &nc, &m, &one, w->W, &m, w->Y, &m, &one, Zj, &nr, 1, 1);
    return (double)nc * nc * nc / 3 + (double)m * nc * nc + 2.0 * m * m * nc + (double)nc * nc * m;
}

/* Keep what sc_spsym_inv answers from Z_J: the diagonal and the entries on A's pattern. */
static void super_extract(sc_spsym *s, selinv_ws *w, int J, const double *Zj)
{
    const cholmod_factor *L = s->L;
    const int *Super = L->super, *Lpi = L->pi, *Ls = L->s;
    int nr = Lpi[J + 1] - Lpi[J];
    for (int t = 0; t < nr; ++t)
        w->map[Ls[Lpi[J] + t]] = t;
    for (int k = Super[J]; k < Super[J + 1]; ++k) {
        int c = k - Super[J];
        s->Zd[k] = Zj[(size_t)c * nr + c];
        for (long b = w->bptr[k]; b < w->bptr[k + 1]; ++b) {
            int v = w->bucket[b], other;
            long p;
            if (v >= 0) {
                p = v;
                other = s->Ai[p];
            } else {
                other = -1 - v;
                p = find_row(s->Ai, s->Ap[other], s->Ap[other + 1],
                             ((const int *)L->Perm)[k], s->sorted); /* on A's pattern */
            }
            s->ZA[p] = Zj[(size_t)c * nr + w->map[s->iperm[other]]];
        }
    }
}

/* The tracked columns (the last n_track pivots p0 .. n-1) in the rows of supernode J before
 * them. A tracked pivot t among J's rows R has Z_tJ in the block just made (Z_RJ = −Z_RR L̂): a
 * copy. For the others (t not in R: (L⁻ᵀ)_tJ = 0, so Z_tJ = −Z_tR L̂ all the same) one product of
 * their rows of Z_tR (from Zt) by L̂ (w->W, m x nc, left by super_block). The grid's free
 * misalignments couple with nearly every node, so most are copies (N = 101: the product had all
 * 9 rows, 9 x nnz(L) multiply-adds; a view measuring a few marks keeps its 3 in the product). */
static double track_rule(sc_spsym *s, selinv_ws *w, int J, const double *Zj)
{
    const cholmod_factor *L = s->L;
    const int *Super = L->super, *Lpi = L->pi, *Ls = L->s;
    int nt = s->n_track, nc = Super[J + 1] - Super[J], m = Lpi[J + 1] - Lpi[J] - nc;
    int p0 = s->n - nt, nr = nc + m, in_r = 0, nmiss = 0;
    if (m == 0) /* a root: no coupling to the tracked pivots (their entries stay 0) */
        return 0;
    const int *R = Ls + Lpi[J] + nc;
    double *zt = s->Zt + (size_t)Super[J] * nt;
    while (in_r < m && R[m - 1 - in_r] >= p0) /* R ascends: the tracked pivots in it end it */
        ++in_r;
    for (int t = 0, a = m - in_r; t < nt; ++t) { /* both ascend: one merge */
        if (a < m && R[a] - p0 == t) {
            for (int c = 0; c < nc; ++c)
                zt[(size_t)c * nt + t] = Zj[(size_t)c * nr + nc + a];
            ++a;
        } else {
            w->miss[nmiss++] = t;
        }
    }
    if (nmiss == 0)
        return 0;
    for (int b = 0; b < m; ++b) {
        const double *zr = s->Zt + (size_t)R[b] * nt;
        for (int i = 0; i < nmiss; ++i)
            w->Gt[(size_t)b * nmiss + i] = zr[w->miss[i]];
    }
    const double minus_one = -1.0, zero = 0.0;
    s->api->dgemm("N", "N", &nmiss, &nc, &m, &minus_one, w->Gt, &nmiss, w->W, &m, &zero, w->Tt,
                  &nmiss, 1, 1);
    for (int c = 0; c < nc; ++c)
        for (int i = 0; i < nmiss; ++i)
            zt[(size_t)c * nt + w->miss[i]] = w->Tt[(size_t)c * nmiss + i];
    return (double)nmiss * m * nc;
}

/* The tracked columns in a supernode J that reaches the last pivots: its block holds them all
 * (tracked_on_pattern), copied both ways (Z is symmetric). */
static void track_copy(sc_spsym *s, int J, const double *Zj)
{
    const cholmod_factor *L = s->L;
    const int *Super = L->super, *Lpi = L->pi, *Ls = L->s;
    int nt = s->n_track, p0 = s->n - nt, nr = Lpi[J + 1] - Lpi[J];
    const int *rows = Ls + Lpi[J];
    for (int k = Super[J]; k < Super[J + 1]; ++k) {
        int c = k - Super[J];
        for (int a = c; a < nr; ++a) {
            int r = rows[a];
            if (r < p0)
                continue;
            double z = Zj[(size_t)c * nr + a];
            s->Zt[(size_t)k * nt + (r - p0)] = z;
            if (k >= p0)
                s->Zt[(size_t)r * nt + (k - p0)] = z;
        }
    }
}

/* Whether the recurrences give the tracked columns: every supernode that reaches the last
 * n_track pivots holds, below each of its columns, every later one of those pivots as a row. */
static int tracked_on_pattern(const sc_spsym *s)
{
    const cholmod_factor *L = s->L;
    const int *Super = L->super, *Lpi = L->pi, *Ls = L->s;
    int p0 = s->n - s->n_track;
    for (int J = (int)L->nsuper - 1; J >= 0 && Super[J + 1] > p0; --J) {
        int from = Super[J] > p0 ? Super[J] : p0, have = 0;
        for (long a = Lpi[J]; a < Lpi[J + 1]; ++a)
            have += Ls[a] >= from;
        if (have != s->n - from)
            return 0;
    }
    return 1;
}

/* Blocked Takahashi on the supernodal factor, from the last supernode to the first, streaming:
 * supernode S's block is needed only by its subtree (R of a supernode lies in its ancestors), so
 * it is freed once the first supernode of that subtree is done. What stays is the diagonal, the
 * entries on A's pattern and the tracked columns (when s->Zt is set: they are the last pivots). */
static int super_selinv(sc_spsym *s)
{
    int nsuper = (int)s->L->nsuper, p0 = s->n - s->n_track;
    const int *Lpi = s->L->pi, *Super = s->L->super;
    selinv_ws w;
    double work = 0;
    int rc = selinv_ws_alloc(s, &w);
    for (int J = nsuper - 1; J >= 0 && rc == 0; --J) {
        size_t nr = (size_t)(Lpi[J + 1] - Lpi[J]), nc = (size_t)(Super[J + 1] - Super[J]);
        double got;
        if (!(w.Z[J] = sc_big_alloc(nr * nc, sizeof(double), 0)) ||
            (got = super_block(s, &w, J, w.Z[J])) < 0) {
            rc = -1;
            break;
        }
        work += got;
        if (s->Zt && Super[J + 1] <= p0)
            work += track_rule(s, &w, J, w.Z[J]);
        else if (s->Zt)
            track_copy(s, J, w.Z[J]);
        super_extract(s, &w, J, w.Z[J]);
        for (int S = J; S < nsuper && S >= 0; S = w.parent[S]) /* blocks no longer needed */
            if (w.first[S] == J)
                free(w.Z[S]), w.Z[S] = NULL;
            else
                break;
    }
    selinv_ws_free(&w, nsuper);
    if (rc != 0) {
        free(s->Zd), free(s->ZA);
        s->Zd = s->ZA = NULL;
        return -1;
    }
    s->selinv_work = work;
    s->bytes += ((size_t)s->n + (size_t)s->Ap[s->keep_cols]) * sizeof(double) +
                (size_t)(s->n + 1) * sizeof(int);
    return 0;
}

/* The tracked columns by solves (their unknowns are not the last pivots), into s->Zt. */
static int track_by_solves(sc_spsym *s, const int *cols)
{
    int n = s->n, nt = s->n_track;
    double *X = calloc((size_t)n * (nt < 8 ? nt : 8), sizeof(double));
    if (!X)
        return -1;
    for (int t0 = 0; t0 < nt; t0 += 8) {
        int k = nt - t0 < 8 ? nt - t0 : 8;
        memset(X, 0, sizeof(double) * (size_t)n * k);
        for (int c = 0; c < k; ++c)
            X[(size_t)c * n + cols[t0 + c]] = 1;
        if (sc_spsym_solve(s, X, k) != 0) {
            free(X);
            return -1;
        }
        for (int c = 0; c < k; ++c)
            for (int i = 0; i < n; ++i)
                s->Zt[(size_t)s->iperm[i] * nt + t0 + c] = X[(size_t)c * n + i];
    }
    free(X);
    return 0;
}

int sc_spsym_selinv(sc_spsym *s, int keep_cols, const int *cols, int ncols)
{
    if (!s->use_ldl && s->Zd)
        return 0;
    free(s->Zt), free(s->track_slot);
    s->Zt = NULL;
    s->track_slot = NULL;
    s->n_track = ncols > 0 ? ncols : 0;
    int in_recurrences = 0;
    if (s->n_track) {
        int nt = s->n_track, p0 = s->n - nt;
        s->Zt = sc_big_alloc((size_t)nt * (size_t)s->n, sizeof(double), 1);
        s->track_slot = malloc(sizeof(int) * (size_t)nt);
        if (!s->Zt || !s->track_slot)
            return -1;
        in_recurrences = !s->use_ldl;
        for (int t = 0; t < nt && in_recurrences; ++t)
            in_recurrences = s->iperm[cols[t]] >= p0; /* distinct unknowns: all of p0 .. n-1 */
        in_recurrences = in_recurrences && tracked_on_pattern(s);
        s->track_solved = !in_recurrences;
        for (int t = 0; t < nt; ++t) /* the recurrences store by pivot, the solves as asked */
            s->track_slot[t] = in_recurrences ? s->iperm[cols[t]] - p0 : t;
        if (!in_recurrences && track_by_solves(s, cols) != 0)
            return -1;
        s->bytes += (size_t)nt * ((size_t)s->n * sizeof(double) + sizeof(int));
    }
    if (s->use_ldl) {
        if (sc_ldl_selinv(&s->f) != 0)
            return -1;
        s->selinv_work = s->f.selinv_work;
        return 0;
    }
    s->keep_cols = keep_cols < 0 || keep_cols > s->n ? s->n : keep_cols;
    /* the blocked solves' workspace is not needed meanwhile: give its memory back */
    s->api->free_dense(&s->X, s->cm);
    s->api->free_dense(&s->Y, s->cm);
    s->api->free_dense(&s->E, s->cm);
    double *Zt = s->Zt;
    if (!in_recurrences)
        s->Zt = NULL; /* already filled: the recurrences leave it alone */
    int rc = super_selinv(s);
    s->Zt = Zt;
    if (rc != 0)
        sc_spsym_drop_inverse(s);
    return rc;
}

double sc_spsym_inv(const sc_spsym *s, int i, int j)
{
    int pi = s->iperm[i], pj = s->iperm[j];
    int col = pi < pj ? pi : pj, row = pi < pj ? pj : pi;
    if (s->use_ldl) {
        if (!s->f.Zd)
            return NAN;
        if (row == col)
            return s->f.Zd[col];
        long p = find_row(s->f.Li, s->f.Lp[col], s->f.Lp[col + 1], row, 1); /* ascending */
        return p < 0 ? NAN : s->f.Zx[p];
    }
    if (!s->Zd)
        return NAN;
    if (i == j)
        return s->Zd[pi];
    int c = i > j ? i : j, r = i > j ? j : i; /* A holds (r, c), r <= c, in column c */
    if (c >= s->keep_cols)
        return NAN;
    long p = find_row(s->Ai, s->Ap[c], s->Ap[c + 1], r, s->sorted);
    return p < 0 ? NAN : s->ZA[p];
}

void sc_spsym_inv_cols_at(const sc_spsym *s, int i, double *out)
{
    const double *row = s->Zt ? s->Zt + (size_t)s->iperm[i] * (size_t)s->n_track : NULL;
    for (int t = 0; t < s->n_track; ++t)
        out[t] = row ? row[s->track_slot[t]] : NAN;
}

int sc_spsym_inv_column(const sc_spsym *s, int t, double *out)
{
    if (!s->Zt || t < 0 || t >= s->n_track)
        return -1;
    const int *perm = s->L ? (const int *)s->L->Perm : NULL;
    size_t nt = (size_t)s->n_track, slot = (size_t)s->track_slot[t];
    for (int k = 0; k < s->n; ++k) /* by pivot: Zt read in order */
        out[perm ? perm[k] : k] = s->Zt[(size_t)k * nt + slot];
    return 0;
}

void sc_spsym_get_stats(const sc_spsym *s, sc_spsym_stats *st)
{
    memset(st, 0, sizeof *st);
    st->nnz_factor = s->nnz_factor;
    st->factor_flops = s->flops;
    st->selinv_work = s->selinv_work;
    st->ordering = s->ordering;
    st->n_null = s->n_null;
    st->min_kept_ratio = s->min_kept;
    st->max_null_ratio = s->max_null;
    st->bytes = s->bytes;
    st->tracked_by_solves = s->track_solved;
    st->workspace_made = s->workspace_made;
}

