/* grid_lsq_full.h — private to the grid area: the least-squares normal matrix with the plate
 * unknowns A kept (the "full" system), for stitched plans of hundreds of placements, where
 * eliminating A would couple every stage node a mark lands on to every other (docs/grid-lsq.md,
 * "Large stages"). grid_lsq.c describes its equations here and factors the matrix as it factors
 * the reduced one; the unknowns are the reduced system's (G, then the misalignments m) followed
 * by one A component per group of at least two equations, so that a solve of the full matrix
 * with zeros on the A rows is a solve of the reduced one (its Schur complement).
 */
#ifndef SELFCAL_GRID_LSQ_FULL_H
#define SELFCAL_GRID_LSQ_FULL_H

#include "../linalg/sparse_sym.h"

/* The weighted row w_e = s_e·J_e of equation e over the reduced unknowns (its G unknown first): its length, the
 * indices into idx and the coefficients into val (at most row_max of them). Its A coefficient
 * is s_e·s_e = 1. */
typedef int (*sc_lsq_row_fn)(const void *ctx, long e, int *idx, double *val);

typedef struct sc_lsq_full_desc {
    int n_red, ng, nm;              /* reduced unknowns: ng G unknowns, then nm misalignments */
    int nb;                         /* misalignments per view (consecutive: view v's from nb·v) */
    long neq;                       /* scalar equations */
    int n_groups;                   /* A components (2 per mark) */
    const long *grp_ptr, *grp_eq;   /* the equations of each A component */
    const double *w;                /* weight of each equation */
    const unsigned char *pinned;    /* per reduced unknown: fixed at 0 (identity row) */
    sc_lsq_row_fn row;
    const void *ctx;
    int row_max;
} sc_lsq_full_desc;

typedef struct sc_lsq_full sc_lsq_full;

/* The automatic choice, from the plan's counts: 1 (full) when the pairs of stage unknowns that
 * eliminating A would couple, Σ k(k−1)/2 over the A components of k equations, exceed
 * SC_LSQ_FULL_PAIRS_PER_EQ times the equations; 0 (reduced) otherwise. */
#define SC_LSQ_FULL_PAIRS_PER_EQ 8.0
int sc_lsq_full_preferred(const sc_lsq_full_desc *d);

/* The pairs Σ k(k−1)/2 of the rule above. */
double sc_lsq_full_pairs(const sc_lsq_full_desc *d);

/* Estimated bytes of the full matrix (upper CSC) before it is assembled. */
double sc_lsq_full_matrix_bytes(const sc_lsq_full_desc *d);

/* Assemble the pinned full matrix: upper triangle in compressed columns (rows sorted, no
 * duplicates; pinned rows/columns identity), *n_full unknowns; *out keeps the A columns and the
 * solve workspace. Returns 0, -1 if memory ran out. */
int sc_lsq_full_assemble(const sc_lsq_full_desc *d, sc_lsq_full **out, long **Ap, int **Ai,
                         double **Ax, int *n_full);

/* The misalignment block of the reduced matrix, G held at 0 (A eliminated), dense nm x nm
 * row-major into mm (its nullity is the plan's ν₂), without the reduced matrix. 0 or -1. */
int sc_lsq_full_misalignment_block(const sc_lsq_full_desc *d, double *mm);

/* The misalignment block bordered by the A components it came from, K = [D Uᵀ; U W] over
 * (m, A): D the views' own blocks Σ w r rᵀ (nb x nb each), U's column Σ_e w_e r_e of a group of
 * two or more equations (one per view: one entry per view and misalignment), W its weight
 * Σ w_e. W is positive, so nullity(K) = nullity(D − U W⁻¹ Uᵀ), the block's; K has
 * nm·(nb+1)/2 + Σ k·nb + groups entries, linear in the views, though the block itself is dense
 * when every view places the same plate. Upper CSC, rows sorted, *n = nm + groups unknowns (the
 * caller frees *Ap, *Ai, *Ax). 0 or -1 (no memory). */
int sc_lsq_full_misalignment_bordered(const sc_lsq_full_desc *d, int *n, long **Ap, int **Ai,
                                      double **Ax);

/* Nullity of the misalignment block from the sparse factor of K (sc_spsym, hinted: the A
 * components ordered last): pivots d_k <= tol·K_kk null, relative to the pivot's own diagonal. The nullity, -1 no memory, -2 CHOLMOD cannot be
 * loaded, -3 the address space limit leaves it too little room (sc_spsym_analyze). */
int sc_lsq_full_misalignment_nullity_sparse(const sc_lsq_full_desc *d, double tol);

/* X (n_red x ncol, column after column) := solves of the reduced (pinned) system through the full
 * factor f; refine: steps of iterative refinement against the full matrix. 0, or -1 if memory
 * ran out. One right-hand side uses the object's own workspace (allocates nothing). */
int sc_lsq_full_solve(sc_lsq_full *x, sc_spsym *f, double *X, int ncol, int refine);

/* Leverage of every equation into h (by equation index) from the selected inverse of the full
 * matrix kept on its own pattern (sc_spsym_selinv with keep_cols -1): every pair of unknowns of
 * one equation is an entry of the matrix. An equation alone in its group: 1. */
void sc_lsq_full_leverages(const sc_lsq_full *x, const sc_lsq_full_desc *d, const sc_spsym *f,
                           double *h);

/* Unknowns of the full system. */
int sc_lsq_full_n(const sc_lsq_full *x);

/* Bytes held by the object. */
size_t sc_lsq_full_bytes(const sc_lsq_full *x);

void sc_lsq_full_destroy(sc_lsq_full *x);

#endif
