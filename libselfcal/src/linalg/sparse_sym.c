/* The symmetric sparse solver of linalg/ (sparse_sym.h): analysis, factorization and solves.
 *
 * Ordering and factorization are SuiteSparse CHOLMOD's (Debian libsuitesparse-dev): one analysis
 * per pattern (CHOLMOD's own choice between AMD and METIS, or CHOLMOD's AMD with the caller's
 * given unknowns last: sc_spsym_hint), supernodal LLᵀ with BLAS-3 kernels.
 * CHOLMOD has no selected inverse, so that part is ours: the blocked Takahashi
 * recurrences on CHOLMOD's supernodes (dense kernels: the BLAS/LAPACK CHOLMOD uses, OpenBLAS):
 * for a supernode J with diagonal block L_JJ and rows R below it, L̂ = L_RJ L_JJ⁻¹ and
 *     Z_RJ = -Z_RR L̂,   Z_JJ = (L_JJ L_JJᵀ)⁻¹ + L̂ᵀ Z_RR L̂,
 * from the last supernode to the first; R is a clique of the filled graph, so Z_RR lies on the
 * factor's pattern in the supernodes already done (gathered through a relative row map). R lies
 * in J's ancestors, so a supernode's block of Z is freed once its subtree is done: the selected
 * inverse never holds a second copy of the factor, only the path to the root; what is kept is
 * the diagonal, the entries on A's own pattern (what the grid least squares asks for) and the
 * whole columns of the last pivots asked for (for a row t after J, Z_tJ = −Z_tR L̂ too). Solves
 * take many right-hand sides at once (cholmod_solve2 with its workspace kept).
 *
 * Rank decisions: a Cholesky pivot d_k = L_kk² with d_k <= tol·A_kk (or a failed factorization)
 * means the matrix is numerically singular at that tolerance. CHOLMOD then gives no usable
 * factor, so that case (plans that do not identify G, plans with idle misalignments) is factored
 * again, in CHOLMOD's order, by the rank-revealing scalar LDLᵀ of sparse_ldl.c, which zeroes
 * null pivots and counts them exactly as before. Identifiable plans never take that path.
 */
#include "sparse_sym_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/big_alloc.h"

void sc_spsym_destroy(sc_spsym *s)
{
    if (!s)
        return;
    if (s->cm) {
        if (s->L)
            s->api->free_factor(&s->L, s->cm);
        s->api->free_dense(&s->X, s->cm);
        s->api->free_dense(&s->Y, s->cm);
        s->api->free_dense(&s->E, s->cm);
        s->api->finish(s->cm);
        free(s->cm);
    }
    free(s->Ap_int), free(s->iperm), free(s->col2super), free(s->Zd), free(s->ZA), free(s->Zt);
    free(s->track_slot);
    free(s->Pp), free(s->Pi), free(s->Px);
    sc_ldl_free(&s->f);
    free(s);
}

/* The selected inverse's storage is the solver object's, so it is freed here (the recurrences
 * of sparse_sym_selinv.c fill it; a new factorization drops it). */
void sc_spsym_drop_inverse(sc_spsym *s)
{
    if (s->Zt) {
        s->bytes -= (size_t)s->n_track * ((size_t)s->n * sizeof(double) + sizeof(int));
        free(s->Zt), free(s->track_slot);
        s->Zt = NULL;
        s->track_slot = NULL;
    }
    if (s->use_ldl) {
        free(s->f.Zx), free(s->f.Zd);
        s->f.Zx = s->f.Zd = NULL;
    } else if (s->Zd) {
        free(s->Zd), free(s->ZA), free(s->col2super);
        s->Zd = s->ZA = NULL;
        s->col2super = NULL;
        s->bytes -= ((size_t)s->n + (size_t)s->Ap[s->keep_cols]) * sizeof(double) +
                    (size_t)(s->n + 1) * sizeof(int);
    }
}

const char *sc_spsym_ordering_name(int ordering)
{
    switch (ordering) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_AMD: return "AMD (CHOLMOD)";
    case CHOLMOD_METIS: return "METIS (CHOLMOD)";
    case CHOLMOD_NESDIS: return "NESDIS (CHOLMOD)";
    case CHOLMOD_COLAMD: return "COLAMD (CHOLMOD)";
    case SC_SPSYM_ORDER_HINTED_AMD: return "AMD, given unknowns last (CHOLMOD)";
    default: return "?";
    }
}

/* CHOLMOD's view of an n x n symmetric pattern given by its upper triangle in compressed columns
 * (int pointers p[n+1], rows i; borrowed), no values. */
static void upper_pattern(cholmod_sparse *M, int n, int *p, int *i)
{
    memset(M, 0, sizeof *M);
    M->nrow = M->ncol = (size_t)n;
    M->nzmax = (size_t)p[n];
    M->p = p;
    M->i = i;
    M->stype = 1;
    M->itype = CHOLMOD_INT;
    M->xtype = CHOLMOD_PATTERN;
    M->dtype = CHOLMOD_DOUBLE;
    M->sorted = 0;
    M->packed = 1;
}

/* The neighbours w < v of vertex v in the grouped graph (A's pattern between the vertices'
 * unknowns), each once (mark: stamps by vertex), written to out when out is not NULL; the count. */
static long vertex_neighbours(const sc_spsym *s, const int *vid, const int *first, int nv, int v,
                              int *mark, int *out)
{
    long cnt = 0;
    int u1 = v + 1 < nv ? first[v + 1] : s->n;
    for (int u = first[v]; u < u1; ++u) {
        if (vid[u] != v)
            continue;
        for (long p = s->Ap[u]; p < s->Ap[u + 1]; ++p) {
            int w = vid[s->Ai[p]];
            if (w < 0 || w >= v || mark[w] == v)
                continue;
            mark[w] = v;
            if (out)
                out[cnt] = w;
            ++cnt;
        }
    }
    return cnt;
}

/* The grouped graph, upper CSC in G (rows < column; G->p and G->i allocated here). A vertex's
 * unknowns are first[v] .. first[v+1]-1 with vid == v (vid -1: ordered last, not in the graph);
 * vid is nondecreasing over the unknowns it numbers, so A's upper pattern maps to an upper one. */
static int grouped_graph(const sc_spsym *s, const int *vid, const int *first, int nv,
                         cholmod_sparse *G)
{
    int *mark = malloc(sizeof(int) * ((size_t)nv + 1));
    int *Gp = malloc(sizeof(int) * ((size_t)nv + 1)), *Gi = NULL;
    long cnt = 0;
    if (!mark || !Gp)
        goto fail;
    for (int v = 0; v < nv; ++v)
        mark[v] = -1;
    Gp[0] = 0;
    for (int v = 0; v < nv; ++v) {
        cnt += vertex_neighbours(s, vid, first, nv, v, mark, NULL);
        if (cnt > 2147483647L)
            goto fail;
        Gp[v + 1] = (int)cnt;
    }
    if (!(Gi = malloc(sizeof(int) * ((size_t)cnt + 1))))
        goto fail;
    for (int v = 0; v < nv; ++v)
        mark[v] = -1;
    for (int v = 0; v < nv; ++v)
        vertex_neighbours(s, vid, first, nv, v, mark, Gi + Gp[v]);
    free(mark);
    upper_pattern(G, nv, Gp, Gi);
    return 0;
fail:
    free(mark), free(Gp), free(Gi);
    return -1;
}

/* The order a hint asks for (sc_spsym_hint): CHOLMOD's AMD of the graph without h->last (a
 * vertex per unknown, or per group of them), each vertex's unknowns together, then h->last in
 * its order. perm: n. Returns 0, -1 (no memory, AMD failed). */
static int hinted_order(sc_spsym *s, const sc_spsym_hint *h, int *perm)
{
    int n = s->n, group = h->group > 0 ? h->group : 1, nv = 0, prev = -1, rc = -1;
    int *vid = malloc(sizeof(int) * ((size_t)n + 1)), *first = malloc(sizeof(int) * ((size_t)n + 1));
    int *vperm = malloc(sizeof(int) * ((size_t)n + 1));
    cholmod_sparse G;
    if (!vid || !first || !vperm)
        goto out;
    memset(vid, 0, sizeof(int) * (size_t)n);
    for (int t = 0; t < h->n_last; ++t) {
        if (h->last[t] < 0 || h->last[t] >= n || vid[h->last[t]] < 0)
            goto out; /* out of range or twice */
        vid[h->last[t]] = -1;
    }
    for (int u = 0; u < n; ++u) {
        if (vid[u] < 0)
            continue;
        int g = u < h->n_grouped ? u / group : -1;
        if (g < 0 || g != prev)
            first[nv++] = u;
        vid[u] = nv - 1;
        prev = g;
    }
    if (grouped_graph(s, vid, first, nv, &G) != 0)
        goto out;
    int ok = nv == 0 || s->api->amd(&G, NULL, 0, vperm, s->cm);
    free(G.p), free(G.i);
    if (!ok || s->cm->status < CHOLMOD_OK)
        goto out;
    int k = 0;
    for (int t = 0; t < nv; ++t) {
        int v = vperm[t], u1 = v + 1 < nv ? first[v + 1] : n;
        for (int u = first[v]; u < u1; ++u)
            if (vid[u] == v)
                perm[k++] = u;
    }
    for (int t = 0; t < h->n_last; ++t)
        perm[k++] = h->last[t];
    rc = k == n ? 0 : -1;
out:
    free(vid), free(first), free(vperm);
    return rc;
}

int sc_spsym_analyze(int n, const long *Ap, const int *Ai, const sc_spsym_hint *hint,
                     sc_spsym **out)
{
    *out = NULL;
    sc_spsym *s = calloc(1, sizeof *s);
    if (!s)
        return -1;
    s->n = n;
    s->Ap = Ap;
    s->Ai = Ai;
    if (!sc_spsym_memory_headroom_ok()) {
        free(s);
        return -3;
    }
    s->api = sc_spsym_api();
    if (!s->api) {
        free(s);
        return -2;
    }
    s->cm = malloc(sizeof *s->cm);
    s->Ap_int = malloc(sizeof(int) * ((size_t)n + 1));
    s->iperm = malloc(sizeof(int) * ((size_t)n + 1));
    if (!s->cm || !s->Ap_int || !s->iperm || Ap[n] > 2147483647L) {
        free(s->cm);
        s->cm = NULL;
        sc_spsym_destroy(s);
        return -1;
    }
    s->api->start(s->cm);
    s->cm->print = 0;
    s->cm->error_handler = NULL;
    s->cm->supernodal = CHOLMOD_SUPERNODAL;
    s->cm->quick_return_if_not_posdef = 1;
    for (int k = 0; k <= n; ++k)
        s->Ap_int[k] = (int)Ap[k];
    s->sorted = 1;
    for (int j = 0; j < n; ++j)
        for (long p = Ap[j] + 1; p < Ap[j + 1]; ++p)
            s->sorted &= Ai[p - 1] < Ai[p];
    cholmod_sparse *A = &s->A;
    upper_pattern(A, n, s->Ap_int, (int *)Ai); /* CHOLMOD reads Ai, never writes it */
    if (hint) {
        int *perm = malloc(sizeof(int) * ((size_t)n + 1));
        if (perm && hinted_order(s, hint, perm) == 0) {
            s->cm->nmethods = 1;
            s->cm->method[0].ordering = CHOLMOD_GIVEN;
            s->cm->postorder = 1;
            s->L = s->api->analyze_p(A, perm, NULL, 0, s->cm);
        }
        free(perm);
    } else {
        s->L = s->api->analyze(A, s->cm);
    }
    if (!s->L || s->cm->status < CHOLMOD_OK) {
        sc_spsym_destroy(s);
        return -1;
    }
    s->ordering = hint ? SC_SPSYM_ORDER_HINTED_AMD : s->cm->method[s->cm->selected].ordering;
    const int *perm = s->L->Perm;
    for (int k = 0; k < n; ++k)
        s->iperm[perm[k]] = k;
    s->bytes = sizeof *s + sizeof *s->cm + (size_t)(n + 1) * 2 * sizeof(int);
    *out = s;
    return 0;
}

/* The fallback: P A Pᵀ (upper CSC) and its rank-revealing scalar LDLᵀ. */
static int factor_ldl(sc_spsym *s, double tol)
{
    int n = s->n;
    long nnz = s->Ap[n];
    if (!s->Pp) {
        s->Pp = calloc((size_t)n + 1, sizeof(long));
        s->Pi = malloc(sizeof(int) * ((size_t)nnz + 1));
        s->Px = malloc(sizeof(double) * ((size_t)nnz + 1));
        if (!s->Pp || !s->Pi || !s->Px)
            return -1;
    }
    memset(s->Pp, 0, sizeof(long) * ((size_t)n + 1));
    for (int j = 0; j < n; ++j)
        for (long p = s->Ap[j]; p < s->Ap[j + 1]; ++p) {
            int pi = s->iperm[s->Ai[p]], pj = s->iperm[j];
            s->Pp[(pi > pj ? pi : pj) + 1]++;
        }
    for (int k = 0; k < n; ++k)
        s->Pp[k + 1] += s->Pp[k];
    long *fill = malloc(sizeof(long) * ((size_t)n + 1));
    if (!fill)
        return -1;
    memcpy(fill, s->Pp, sizeof(long) * (size_t)n);
    for (int j = 0; j < n; ++j)
        for (long p = s->Ap[j]; p < s->Ap[j + 1]; ++p) {
            int pi = s->iperm[s->Ai[p]], pj = s->iperm[j];
            long at = fill[pi > pj ? pi : pj]++;
            s->Pi[at] = pi > pj ? pj : pi;
            s->Px[at] = s->Ax[p];
        }
    free(fill);
    if (sc_ldl_factor(&s->f, n, s->Pp, s->Pi, s->Px, tol) != 0)
        return -1;
    s->use_ldl = 1;
    s->nnz_factor = s->f.Lp[n];
    s->flops = s->f.flops;
    s->n_null = s->f.n_null;
    s->min_kept = s->f.min_kept_ratio;
    s->max_null = s->f.max_null_ratio;
    return 0;
}

size_t sc_spsym_factor_bytes(const sc_spsym *s)
{
    const cholmod_factor *L = s->L;
    if (L->is_super)
        return L->xsize * sizeof(double) + L->ssize * sizeof(int) +
               (L->nsuper + 1) * 3 * sizeof(int);
    size_t lnz = 0; /* a simplicial analysis: its column counts */
    for (size_t j = 0; j < L->n; ++j)
        lnz += (size_t)((const int *)L->ColCount)[j];
    return lnz * (sizeof(double) + sizeof(int));
}

int sc_spsym_factor(sc_spsym *s, const double *Ax, double tol)
{
    int n = s->n;
    s->Ax = Ax;
    sc_spsym_drop_inverse(s);
    free(s->col2super);
    s->col2super = NULL;
    sc_ldl_free(&s->f);
    s->use_ldl = 0;
    s->selinv_work = 0;
    s->n_null = 0;
    s->A.x = (void *)Ax;
    s->A.xtype = CHOLMOD_REAL;
    int ok = s->api->factorize(&s->A, s->L, s->cm);
    s->A.xtype = CHOLMOD_PATTERN;
    s->A.x = NULL;
    if (!ok && s->cm->status == CHOLMOD_OUT_OF_MEMORY)
        return -1;
    int good = s->cm->status == CHOLMOD_OK && s->L->is_super && s->L->minor == (size_t)n;
    /* pivot ratios d_k / A_kk against the tolerance */
    double *diag = calloc((size_t)n + 1, sizeof(double));
    if (!diag)
        return -1;
    for (int j = 0; j < n; ++j)
        for (long p = s->Ap[j]; p < s->Ap[j + 1]; ++p)
            if (s->Ai[p] == j)
                diag[j] += Ax[p];
    s->min_kept = INFINITY;
    s->max_null = 0;
    s->nnz_factor = 0;
    s->flops = 0;
    if (good) {
        const int *Super = s->L->super, *Lpi = s->L->pi, *Lpx = s->L->px, *perm = s->L->Perm;
        const double *Lx = s->L->x;
        for (size_t J = 0; J < s->L->nsuper && good; ++J) {
            int k1 = Super[J], nc = Super[J + 1] - k1, nr = Lpi[J + 1] - Lpi[J];
            for (int t = 0; t < nc; ++t) {
                double l = Lx[Lpx[J] + (long)t * nr + t], akk = diag[perm[k1 + t]];
                double ratio = akk > 0 ? l * l / akk : 0.0;
                if (!(ratio > tol)) {
                    good = 0;
                    break;
                }
                if (ratio < s->min_kept)
                    s->min_kept = ratio;
                double below = nr - t - 1;
                s->nnz_factor += (long)below;
                s->flops += below * below;
            }
        }
    }
    free(diag);
    if (good) {
        s->bytes = sizeof *s + sizeof *s->cm + (size_t)(n + 1) * 2 * sizeof(int) +
                   s->L->xsize * sizeof(double) + s->L->ssize * sizeof(int) +
                   (s->L->nsuper + 1) * 3 * sizeof(int);
        return 0;
    }
    /* numerically singular at this tolerance: the rank-revealing LDLᵀ decides */
    int rc = factor_ldl(s, tol);
    s->bytes = sizeof *s + sizeof *s->cm + (size_t)(n + 1) * 2 * sizeof(int) + s->f.bytes +
               (size_t)s->Ap[n] * (sizeof(int) + sizeof(double));
    return rc;
}

int sc_spsym_nullity(const sc_spsym *s)
{
    return s->n_null;
}

int sc_spsym_solve(sc_spsym *s, double *X, int ncol)
{
    int n = s->n;
    if (s->use_ldl) {
        double *b = malloc(sizeof(double) * ((size_t)n + 1));
        if (!b)
            return -1;
        for (int c = 0; c < ncol; ++c) {
            double *x = X + (size_t)c * n;
            for (int i = 0; i < n; ++i)
                b[s->iperm[i]] = x[i];
            sc_ldl_solve(&s->f, b);
            for (int i = 0; i < n; ++i)
                x[i] = b[s->iperm[i]];
        }
        free(b);
        return 0;
    }
    cholmod_dense B = {0};
    B.nrow = B.d = (size_t)n;
    B.ncol = (size_t)ncol;
    B.nzmax = (size_t)n * (size_t)ncol;
    B.x = X;
    B.xtype = CHOLMOD_REAL;
    B.dtype = CHOLMOD_DOUBLE;
    cholmod_dense *was[3] = {s->X, s->Y, s->E};
    size_t shape[3][2];
    for (int w = 0; w < 3; ++w)
        shape[w][0] = was[w] ? was[w]->nrow : 0, shape[w][1] = was[w] ? was[w]->ncol : 0;
    if (!s->api->solve2(CHOLMOD_A, s->L, &B, NULL, &s->X, NULL, &s->Y, &s->E, s->cm))
        return -1;
    cholmod_dense *now[3] = {s->X, s->Y, s->E};
    for (int w = 0; w < 3; ++w) /* CHOLMOD made its workspace anew: shape or place changed */
        if (now[w] != was[w] || now[w]->nrow != shape[w][0] || now[w]->ncol != shape[w][1]) {
            s->workspace_made++;
            break;
        }
    memcpy(X, s->X->x, sizeof(double) * (size_t)n * (size_t)ncol);
    return 0;
}

int sc_spsym_reserve_solve(sc_spsym *s, int ncol)
{
    if (s->use_ldl)
        return 0;
    /* the shapes cholmod_solve2 asks of its workspace for a supernodal factor (SuiteSparse's
     * cholmod_solve.c): X and Y n x ncol, E ncol x maxesize; cholmod_ensure_dense keeps a matrix
     * of exactly that shape, so the solves that follow allocate nothing */
    size_t n = (size_t)s->n, k = (size_t)ncol;
    cholmod_dense **h[3] = {&s->X, &s->Y, &s->E};
    size_t rows[3] = {n, n, k}, cols[3] = {k, k, s->L->maxesize}, ld[3] = {n, n, k};
    for (int w = 0; w < 3; ++w) {
        cholmod_dense *d = *h[w];
        if (d && d->nrow == rows[w] && d->ncol == cols[w] && d->d == ld[w])
            continue;
        s->api->free_dense(h[w], s->cm);
        if (!(*h[w] = s->api->allocate_dense(rows[w], cols[w], ld[w], CHOLMOD_REAL, s->cm)))
            return -1;
    }
    return 0;
}

void sc_spsym_matvec(const sc_spsym *s, const double *X, double *Y, int ncol)
{
    int n = s->n;
    memset(Y, 0, sizeof(double) * (size_t)n * (size_t)ncol);
    for (int j = 0; j < n; ++j)
        for (long p = s->Ap[j]; p < s->Ap[j + 1]; ++p) {
            int i = s->Ai[p];
            double a = s->Ax[p];
            for (int c = 0; c < ncol; ++c) {
                size_t o = (size_t)c * n;
                Y[o + i] += a * X[o + j];
                if (i != j)
                    Y[o + j] += a * X[o + i];
            }
        }
}
