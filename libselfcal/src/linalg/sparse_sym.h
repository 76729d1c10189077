/* sparse_sym.h — private to linalg/: the symmetric sparse solver behind the grid least
 * squares (the grid_lsq_*.c files call only this). One object per plan:
 *
 *   analyze(pattern)  once: fill-reducing order and symbolic factorization, chosen once
 *                     (CHOLMOD's choice, or the order a hint describes);
 *   factor(values)    numeric factorization with rank decisions (pivot tolerance);
 *   solve / matvec    in the ORIGINAL index space (the order is internal);
 *   selinv            selected inverse: the entries of A⁻¹ on the factor's pattern, computed
 *                     supernode by supernode; kept: the diagonal and A's own pattern, and
 *                     whole columns of A⁻¹ for a few unknowns asked for;
 *   inv(i, j)         one such entry; inv_column / inv_cols_at: the whole columns.
 *
 * The matrix is symmetric positive semidefinite, given by its upper triangle in compressed
 * columns (column j holds rows i <= j; no duplicates). Pivots judged null (d_k <= tol·A_kk) are
 * counted (nullity) and give zero components in solves and zero rows/columns in the inverse;
 * the count is exact for matrices whose numerical rank is clear (a wide gap around tol), which
 * the stats' min_kept_ratio / max_null_ratio show.
 */
#ifndef SELFCAL_SPARSE_SYM_H
#define SELFCAL_SPARSE_SYM_H

#include <stddef.h>

typedef struct sc_spsym sc_spsym;

typedef struct sc_spsym_stats {
    long nnz_factor;        /* entries of L below the diagonal */
    double factor_flops;    /* multiply-adds of the factorization */
    double selinv_work;     /* multiply-adds of the selected inverse (0 before it) */
    int ordering;           /* backend-specific code of the order used (sc_spsym_ordering_name) */
    int n_null;             /* pivots judged null */
    double min_kept_ratio;  /* smallest pivot/diagonal among kept pivots */
    double max_null_ratio;  /* largest pivot/diagonal among null pivots (0 if none) */
    size_t bytes;           /* memory the object holds */
    int tracked_by_solves;  /* the selected inverse's whole columns came from solves */
    long workspace_made;    /* solves that had to make CHOLMOD's solve workspace anew */
} sc_spsym_stats;

/* What the caller knows of its unknowns' graph, for the order: the n_last unknowns `last`
 * (couplings to nearly everything: the misalignments) are ordered last, in this order, as
 * minimum degree would place them, and then their whole columns of A⁻¹ cost the selected inverse
 * little (sc_spsym_selinv); AMD orders the others. group > 1: the unknowns [0, n_grouped) come in
 * consecutive groups of `group` that AMD orders as one vertex each (the grid solver used a node's
 * x and y as one vertex until it measured that their own graph needs 17-40 % fewer flops). */
typedef struct sc_spsym_hint {
    int group, n_grouped;
    const int *last;
    int n_last;
} sc_spsym_hint;

/* 1 unless an address space limit (RLIMIT_AS, ulimit -v) leaves less than 768 MiB beyond what the
 * process maps: OpenBLAS, which CHOLMOD loads, hangs rather than fails below that. */
int sc_spsym_memory_headroom_ok(void);

#define SC_SPSYM_ORDER_HINTED_AMD 1000 /* ordering code of a hinted analysis */

/* Analyze the n x n pattern (upper CSC Ap[n+1], Ai[Ap[n]]; borrowed: it must stay unchanged
 * until sc_spsym_destroy): one fill-reducing order, chosen here once: CHOLMOD's own choice when
 * hint is NULL, else AMD of the hint's graph with its last unknowns last.
 * Returns 0, -1 if memory ran out (or a bad hint), -2 if CHOLMOD cannot be loaded, -3 if the
 * address space limit leaves too little room to load it (sc_spsym_memory_headroom_ok). */
int sc_spsym_analyze(int n, const long *Ap, const int *Ai, const sc_spsym_hint *hint,
                     sc_spsym **out);

/* The bytes the numeric factor will hold, known from the analysis (CHOLMOD's supernodal sizes). */
size_t sc_spsym_factor_bytes(const sc_spsym *s);

/* Numeric factorization of the values Ax (same layout as the analyzed pattern; borrowed until
 * the next factorization or destroy; matvec uses them).
 * Pivots with d_k <= tol·A_kk are null. Returns 0, or -1 if memory ran out. */
int sc_spsym_factor(sc_spsym *s, const double *Ax, double tol);

/* Number of null pivots of the last factorization. */
int sc_spsym_nullity(const sc_spsym *s);

/* X := A⁻¹ B in place for ncol right-hand sides (B given in X, n x ncol, column after column;
 * null pivots give 0 components): one blocked solve (BLAS-3 on the supernodes). The solve
 * workspace is kept in s and reused: not thread-safe on one s. Returns 0, -1 no memory. */
int sc_spsym_solve(sc_spsym *s, double *X, int ncol);

/* Make the solve workspace for ncol right-hand sides now, so that later sc_spsym_solve calls of
 * ncol columns allocate nothing. 0, or -1 if memory ran out. */
int sc_spsym_reserve_solve(sc_spsym *s, int ncol);

/* Y = A X for ncol vectors (n x ncol, column after column; the factored values). */
void sc_spsym_matvec(const sc_spsym *s, const double *X, double *Y, int ncol);

/* Selected inverse on the factor's pattern; kept: the diagonal, A's pattern in its first
 * keep_cols columns (-1: all), and the whole columns of A⁻¹ of the ncols unknowns cols (may be
 * 0): within the recurrences (one small product per supernode) when they are the last pivots,
 * as a hint's last unknowns are, else by solves. Returns 0, or -1 if memory ran out. */
int sc_spsym_selinv(sc_spsym *s, int keep_cols, const int *cols, int ncols);

/* Row i of the whole columns: out[t] = (A⁻¹)(i, cols[t]) for every t (NaN if not computed). */
void sc_spsym_inv_cols_at(const sc_spsym *s, int i, double *out);

/* The whole column cols[t] of A⁻¹ into out (n); -1 if it was not computed (or dropped). */
int sc_spsym_inv_column(const sc_spsym *s, int t, double *out);

/* (A⁻¹)_ij after sc_spsym_selinv, for i == j or (i, j) in the kept part of A's pattern; NaN if
 * (i, j) is not on it or the selected inverse was not computed (or dropped). */
double sc_spsym_inv(const sc_spsym *s, int i, int j);

/* Free the selected inverse (sc_spsym_inv gives NaN after); the factor stays for solves. */
void sc_spsym_drop_inverse(sc_spsym *s);

/* Name of an ordering code of the stats. */
const char *sc_spsym_ordering_name(int ordering);

void sc_spsym_get_stats(const sc_spsym *s, sc_spsym_stats *st);

/* Free everything (NULL is fine). */
void sc_spsym_destroy(sc_spsym *s);

#endif
