/* profile_lsq_band.h — private: the banded part of the profile least squares (profile_lsq.c).
 * B = the f-block of the normal matrix (weighted Laplacian of n ~ n+d1, n ~ n+d2) with the rows and
 * columns of the pinned points 0 and N-1 replaced by the identity; half-width bw = max(d1, d2).
 * Row-band storage: row i holds L[i][i-bw .. i-1] at [0 .. bw-1] and 1/L[i][i] at [bw]. */
#ifndef SELFCAL_PROFILE_LSQ_BAND_H
#define SELFCAL_PROFILE_LSQ_BAND_H

#include <stddef.h>

typedef struct sc_lsq_band {
    int n, bw, d1, d2;
    double w1, w2;
    size_t ld; /* bw + 1 */
    int nrow;  /* rows stored and assembled: n, or m + s for the twisted factorization */
    int ncol;  /* columns eliminated by sc_lsq_band_factor: n, or m (a multiple of 8) */
    double *a; /* nrow·ld doubles */
    int simd;  /* 1: use the AVX2/FMA kernels (set by sc_lsq_band_pick_simd) */
} sc_lsq_band;

/* 1 if this CPU runs the AVX2/FMA kernels (x86-64 with GCC/Clang), else 0. */
int sc_lsq_band_cpu_has_simd(void);

/* Assemble rows 0 .. nrow-1 of B and eliminate columns 0 .. ncol-1 in place (ncol = nrow = n:
 * the whole factor B = L·Lᵀ; ncol < nrow: rows ncol .. nrow-1 keep L[k][0..ncol-1] and, from
 * column ncol on, their block of B minus the contributions of the eliminated columns);
 * col: 8·(bw+16) doubles of scratch. Returns -1 on success, or
 * the row where the pivot was not positive. */
int sc_lsq_band_factor(sc_lsq_band *b, double *col);

/* xs[r] <- B⁻¹·xs[r] for r < nrhs, in place: one pass over the factor forward and one backward
 * for all of them (the factor is larger than the caches; the passes are memory-bound). */
void sc_lsq_band_solve(const sc_lsq_band *b, double *const *xs, int nrhs);

/* The two halves of sc_lsq_band_solve (rows 0 .. b->n-1). */
void sc_lsq_band_forward(const sc_lsq_band *b, double *const *xs, int nrhs);
void sc_lsq_band_backward(const sc_lsq_band *b, double *const *xs, int nrhs);

/* diag[i] = (B⁻¹)[i][i] by the Takahashi recurrences (selected inversion) on the factor;
 * win: sc_lsq_band_inverse_scratch(bw) doubles of scratch. */
size_t sc_lsq_band_inverse_scratch(int bw);
void sc_lsq_band_inverse_diag(const sc_lsq_band *b, double *win, double *diag);
/* The same recurrences for i = i0 down to 0 only, started from the block of B⁻¹ over the indices
 * i0+1 .. i0+s given in zss (s×s row-major, s >= 1; the rows i0+1 .. i0+bw of the storage must
 * hold column i0 .. of L); diag[0 .. i0] is written. */
void sc_lsq_band_inverse_diag_from(const sc_lsq_band *b, double *win, double *diag, int i0,
                                   const double *zss, int s);

#endif
