/* sparse_sym_internal.h — private to linalg/'s sparse symmetric solver (sparse_sym.c, its loader
 * sparse_sym_load.c and its selected inverse sparse_sym_selinv.c): the table of CHOLMOD's entry
 * points and the solver object they share. Nothing outside those three files includes it. */
#ifndef SELFCAL_SPARSE_SYM_INTERNAL_H
#define SELFCAL_SPARSE_SYM_INTERNAL_H

#include <stddef.h>
#include <suitesparse/cholmod.h>

#include "sparse_ldl.h"
#include "sparse_sym.h"

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

/* The table of CHOLMOD's entry points, loaded at the first call (sparse_sym_load.c); NULL when
 * the library or one of its symbols is missing. */
const cholmod_api *sc_spsym_api(void);

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

#endif
