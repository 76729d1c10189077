/* Private to the exact grid methods (grid_exact.c, grid_ye.c, grid_double_shift.c).
 *
 * Internal units: deviations in µm, node/mark coordinates in pitches relative to the grid centre
 * (X(j) = j - c, Y(i) = i - c), rotations in µm per pitch. Matrices are N x N, row-major, row i = y,
 * column j = x, exactly as in Petrò's paper (with 0-based indices; c = s - 1 of the paper).
 * See docs/grid-exact.md for the derivation of every step.
 */
#ifndef SELFCAL_GRID_EXACT_INTERNAL_H
#define SELFCAL_GRID_EXACT_INTERNAL_H

#include "selfcal/grid_exact.h"

#include <fftw3.h>

struct sc_grid_exact_plan {
    sc_grid_exact_method method;
    int n, c;   /* N and the centre index (N-1)/2 */
    int shift;  /* x shift of view 2 in pitches: 1 (Ye) or 2 (double shift) */

    /* FFTW: one in-place buffer and its two plans, made once in create */
    fftw_complex *buf;
    fftw_plan fwd, bwd;

    /* weights w_j (j = 0..N-1-shift) with sum_j w_j (F(j+shift) - F(j)) = sum_j (j-c) F(j) */
    double *w;
    double w_sum, w_xsum; /* sum_j w_j and sum_j w_j (j-c) */
    double *mu_re, *mu_im; /* mu(k) = exp(2 pi i shift (k-c)/N) - 1, centred column index k */

    /* spatial work arrays, N*N each */
    double *u0x, *u0y, *u1x, *u1y; /* views 0 and 1 without their misalignment */
    double *P, *Q;                 /* eq. 21 */
    double *ex, *ey;               /* point-symmetric (even) parts of Fx, Fy (eqs. 33, 37) */
    double *hx, *hy;               /* H = F (T_shift - I), periodic, all N columns (eq. 40 + wrap) */
    double *fx, *fy;               /* second-order stage error F */
    double *gx, *gy, *ax, *ay, *bx, *by; /* final G, A and a scratch pair */
    /* centred spectra (W M W), N*N each */
    fftw_complex *sp, *sq, *shx, *shy, *phx, *phy;
    double *crow_x, *crow_y; /* central row of Fx, Fy (double shift) */

};

/* One execution: the data of the views in their roles and the first-order terms found. It lives
 * on the stack of sc_grid_exact_execute and is passed between the steps: a plan keeps nothing of
 * an execution but the contents of its workspace arrays. */
typedef struct sc_grid_exact_run {
    const double *v0x, *v0y, *v1x, *v1y, *v2x, *v2y, *v3x, *v3y;
    double O, R; /* first-order terms, µm per pitch */
} sc_grid_exact_run;

/* Double shift: fill the last two (wrap-around) columns of hx, hy from view 3 (docs §6).
 * Needs ex, ey, the first N-2 columns of hx, hy, u0x, u0y and v3x, v3y. */
void sc_grid_ds_complete_h(struct sc_grid_exact_plan *p, const sc_grid_exact_run *x);

/* Ye: fill the last (wrap-around) column of hx, hy by telescoping (docs §5). */
void sc_grid_ye_complete_h(struct sc_grid_exact_plan *p);

#endif
