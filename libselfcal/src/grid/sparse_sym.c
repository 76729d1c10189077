/* The symmetric sparse solver of the grid area (sparse_sym.h).
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
#include "sparse_sym.h"

#include <dlfcn.h>
#include <stdio.h>
#include <sys/resource.h>
#include <unistd.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <suitesparse/cholmod.h>

#include "../common/big_alloc.h"
#include "sparse_ldl.h"

/* CHOLMOD and the BLAS/LAPACK it uses are loaded at the first analysis (dlopen), not linked:
 * loading OpenBLAS starts its thread pool, and processes that never solve a grid (selfcald, the
 * LinuxCNC component, every other command) must not carry threads that take their signals. The
 * table is filled once per process (pthread_once) and never changes after: a cache of the
 * dynamic linker's answers, not state. The dense kernels are the Fortran BLAS/LAPACK entry points
 * CHOLMOD itself calls (gfortran ABI: hidden character lengths passed explicitly). */
typedef struct cholmod_api {
    int (*start)(cholmod_common *);
    int (*finish)(cholmod_common *);
    cholmod_factor *(*analyze)(cholmod_sparse *, cholmod_common *);
    cholmod_factor *(*analyze_p)(cholmod_sparse *, int *, int *, size_t, cholmod_common *);
    int (*amd)(cholmod_sparse *, int *, size_t, int *, cholmod_common *);
    int (*factorize)(cholmod_sparse *, cholmod_factor *, cholmod_common *);
    int (*solve2)(int, cholmod_factor *, cholmod_dense *, cholmod_sparse *, cholmod_dense **,
                  cholmod_sparse **, cholmod_dense **, cholmod_dense **, cholmod_common *);
    int (*free_factor)(cholmod_factor **, cholmod_common *);
    int (*free_dense)(cholmod_dense **, cholmod_common *);
    cholmod_dense *(*allocate_dense)(size_t, size_t, size_t, int, cholmod_common *);
    void (*dtrsm)(const char *, const char *, const char *, const char *, const int *, const int *,
                  const double *, const double *, const int *, double *, const int *, size_t,
                  size_t, size_t, size_t);
    void (*dsymm)(const char *, const char *, const int *, const int *, const double *,
                  const double *, const int *, const double *, const int *, const double *,
                  double *, const int *, size_t, size_t);
    void (*dgemm)(const char *, const char *, const int *, const int *, const int *,
                  const double *, const double *, const int *, const double *, const int *,
                  const double *, double *, const int *, size_t, size_t);
    void (*dpotri)(const char *, const int *, double *, const int *, int *, size_t);
    int ok;
} cholmod_api;

#define SC_STR_(x) #x
#define SC_STR(x) SC_STR_(x)

static cholmod_api g_api;
static pthread_once_t g_api_once = PTHREAD_ONCE_INIT;

static void load_api(void)
{
    /* the CHOLMOD whose headers this was compiled with: its structures (cholmod_common,
     * cholmod_factor) change between major versions, so no other may be taken */
    void *h = dlopen("libcholmod.so." SC_STR(CHOLMOD_MAIN_VERSION), RTLD_NOW | RTLD_LOCAL);
    if (!h)
        return;
    enum { NSYM = 14 };
    void *sym[NSYM];
    static const char *names[NSYM] = {"cholmod_start",      "cholmod_finish",
                                      "cholmod_analyze",    "cholmod_analyze_p",
                                      "cholmod_amd",        "cholmod_factorize",
                                      "cholmod_solve2",     "cholmod_free_factor",
                                      "cholmod_free_dense", "dtrsm_",
                                      "dsymm_",             "dgemm_",
                                      "dpotri_",            "cholmod_allocate_dense"};
    for (int k = 0; k < NSYM; ++k)
        if (!(sym[k] = dlsym(h, names[k])))
            return;
    /* object pointer to function pointer: POSIX guarantees dlsym's results convert */
    void *slot[NSYM] = {&g_api.start,       &g_api.finish,     &g_api.analyze, &g_api.analyze_p,
                        &g_api.amd,         &g_api.factorize,  &g_api.solve2,  &g_api.free_factor,
                        &g_api.free_dense,  &g_api.dtrsm,      &g_api.dsymm,   &g_api.dgemm,
                        &g_api.dpotri,      &g_api.allocate_dense};
    for (int k = 0; k < NSYM; ++k)
        memcpy(slot[k], &sym[k], sizeof sym[k]);
    g_api.ok = 1;
}

/* OpenBLAS (loaded with CHOLMOD) reserves a buffer of 32-128 MiB per thread at its first call
 * and, when the address space limit (ulimit -v) refuses it, retries forever, then waits on its
 * workers at exit: a hang, not an error. Under a limit leaving less than this much room, the
 * solver is not loaded and the caller is told it lacks memory. */
#define SPSYM_MIN_HEADROOM ((double)768 * 1024 * 1024)

int sc_spsym_memory_headroom_ok(void)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY)
        return 1;
    long pages = 0, page = sysconf(_SC_PAGESIZE);
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld", &pages) != 1)
            pages = 0;
        fclose(f);
    }
    double used = (double)pages * (double)(page > 0 ? page : 4096);
    return (double)rl.rlim_cur - used >= SPSYM_MIN_HEADROOM;
}

static const cholmod_api *api(void)
{
    pthread_once(&g_api_once, load_api);
    return g_api.ok ? &g_api : NULL;
}

struct sc_spsym {
    int n;
    const long *Ap;       /* borrowed pattern (upper CSC, original index space) */
    const int *Ai;
    const double *Ax;     /* borrowed values of the last factorization */
    const cholmod_api *api;
    cholmod_common *cm;
    cholmod_sparse A;     /* CHOLMOD's view of the matrix (p copied to int, i/x borrowed) */
    int *Ap_int;
    cholmod_factor *L;    /* symbolic after analyze, supernodal LLᵀ after a good factor */
    int *iperm;           /* iperm[original] = pivot position */
    int ordering;         /* CHOLMOD's ordering code */
    int use_ldl;          /* the last factorization is the rank-revealing LDLᵀ */
    int sorted;           /* rows ascending within each column of the pattern */
    int keep_cols;        /* the selected inverse keeps A's pattern in columns [0, keep_cols) */
    /* supernodal selected inverse: what is kept of it */
    int *col2super;
    double *Zd;           /* (A⁻¹)_kk by pivot position k */
    double *ZA;           /* A⁻¹ on A's pattern, entry by entry as Ax */
    int n_track;          /* whole columns of A⁻¹ asked of the selected inverse */
    int *track_slot;      /* the caller's column t is slot track_slot[t] of Zt */
    int track_solved;     /* Zt came from solves (its unknowns were not the last pivots) */
    double *Zt;           /* by pivot position k: Zt[k·n_track + slot] = (A⁻¹)(perm[k], column) */
    /* solve workspace, reused from one solve to the next (cholmod_solve2) */
    cholmod_dense *X, *Y, *E;
    long workspace_made;  /* solves that had CHOLMOD make that workspace anew */
    /* rank-revealing fallback: the permuted matrix and its scalar LDLᵀ */
    long *Pp;
    int *Pi;
    double *Px;
    sc_ldl f;
    /* stats of the last factorization */
    long nnz_factor;
    double flops, selinv_work, min_kept, max_null;
    int n_null;
    size_t bytes;
};

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
    s->api = api();
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
