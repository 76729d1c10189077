/* sparse_ldl.h — private to linalg/: a scalar sparse LDLᵀ factorization of a symmetric
 * positive semidefinite matrix with rank decisions by a relative pivot tolerance, solves, and the
 * Takahashi selected inverse on the factor's pattern. Only sparse_sym.c uses it, as the
 * rank-revealing path for matrices CHOLMOD's Cholesky cannot factor (numerically singular).
 *
 * Everything here works in the PERMUTED index space: the caller builds the upper triangle of
 * P·A·Pᵀ in compressed columns (column k holds rows i <= k) with a fill-reducing order (CHOLMOD's).
 * The up-looking algorithm is T. A. Davis' LDL (ACM TOMS 2005): row k of L is a
 * sparse triangular solve whose pattern is the reach of the elimination tree.
 */
#ifndef SELFCAL_SPARSE_LDL_H
#define SELFCAL_SPARSE_LDL_H

#include <stddef.h>

typedef struct sc_ldl {
    int n;
    const long *Ap;      /* the matrix (permuted, upper, CSC), borrowed from the caller */
    const int *Ai;
    const double *Ax;
    int *parent;         /* elimination tree */
    long *Lp;            /* column pointers of L (strictly lower part, unit diagonal implied) */
    int *Li;             /* row indices, ascending within each column */
    double *Lx;
    double *D;           /* pivots; 0 where the pivot was judged null */
    int n_null;          /* pivots judged null (numerical nullity) */
    double min_kept_ratio;  /* smallest pivot/diagonal among kept pivots */
    double max_null_ratio;  /* largest pivot/diagonal among null pivots (0 if none) */
    double *Zx, *Zd;     /* selected inverse on L's pattern (after sc_ldl_selinv) */
    double flops;        /* multiply-adds of the factorization (sum of squared column counts) */
    double selinv_work;  /* multiply-adds of the selected inverse */
    size_t bytes;        /* memory held by this object */
} sc_ldl;

/* Symbolic + numeric factorization of the n x n matrix (Ap, Ai, Ax). A pivot d_k with
 * d_k <= tol * A_kk (or A_kk <= 0) is judged null: its column of L is set to zero and it is
 * counted in n_null (exact for positive semidefinite matrices). Returns 0, -1 on no memory. */
int sc_ldl_factor(sc_ldl *f, int n, const long *Ap, const int *Ai, const double *Ax, double tol);

/* x := A⁺-like solve: L D Lᵀ x = b in place (null pivots give 0 components). */
void sc_ldl_solve(const sc_ldl *f, double *x);

/* y = A x with the stored upper triangle (symmetric product). */
void sc_ldl_matvec(const sc_ldl *f, const double *x, double *y);

/* Selected inverse Z = (L D Lᵀ)⁻¹ on the pattern of L (Takahashi recurrences); fills Zd (the
 * diagonal) and Zx. Returns 0, -1 on no memory. */
int sc_ldl_selinv(sc_ldl *f);

/* Free everything the factor holds (not the matrix). */
void sc_ldl_free(sc_ldl *f);

#endif
