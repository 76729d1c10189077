/* profile_rig.h (internal) — the least squares of a real rig (SPEC §2a): the two-scan model with
 * rows left out (gaps, rejected outliers), a drift common to the scans (polynomial in the sample
 * index), the points the rows cannot determine found and left out, and what the residual test
 * needs (every row's leverage). One-sided banded Cholesky of the pinned normal matrix with a
 * border of 2 + drift columns, selected inversion of its band (docs/profile-lsq.md §10). The
 * complete, drift-free case keeps the fast solver of profile_lsq.c. */
#ifndef SELFCAL_PROFILE_RIG_H
#define SELFCAL_PROFILE_RIG_H

#include "selfcal/error.h"

typedef struct sc_rig_plan sc_rig_plan;

#define SC_RIG_MAX_PARAMS 4 /* c1, c2 and up to two drift terms */

/* Factor the problem: use[k][j] != 0 for the rows (scan k, n = j) to fit (n - d[k] each);
 * w[k] > 0: the scans' weights (1/µm²); drift: 0 none, 1 linear, 2 linear + quadratic (a common
 * term a·τ + b·τ² in y_k(j), τ = (2j - (N-1))/(N-1)). SC_E_INPUT when nothing can be solved
 * (the rows determine no profile, or the drift cannot be told from it). */
sc_status sc_rig_plan_create(int n, int d1, int d2, const double w[2],
                             const unsigned char *const use[2], int drift, sc_rig_plan **out,
                             sc_error *err);
void sc_rig_plan_destroy(sc_rig_plan *p);

/* Points determined (1) or not (0: left out, no row ties them to the rest): n values. */
const unsigned char *sc_rig_determined(const sc_rig_plan *p);
int sc_rig_n_determined(const sc_rig_plan *p);
/* Degrees of freedom: rows fitted - (determined points - 2) - parameters. */
int sc_rig_dof(const sc_rig_plan *p);
/* Is row (k, j) in the fit? */
int sc_rig_row_used(const sc_rig_plan *p, int k, int j);

/* Solve for the data y (rows not in the fit are not read): f (n values, LS line over the
 * determined points removed, NaN elsewhere), q (2 + drift values: c1, c2 in the LS gauge, then
 * the drift's a, b in µm; may be NULL), wrss (may be NULL). */
sc_status sc_rig_solve(const sc_rig_plan *p, const double *y1, const double *y2, double *f,
                       double *q, double *wrss, sc_error *err);

/* Unit uncertainty (for the plan's weights) of every f (NaN where undetermined). Computes and
 * keeps the band of the inverse for sc_rig_leverage. */
sc_status sc_rig_uncertainty(sc_rig_plan *p, double *uf, sc_error *err);

/* w_k·a·C·aᵀ for row (k, j) (a its design row; in the fit: its leverage h; out of it: the
 * prediction's share); needs sc_rig_uncertainty first. NaN if the row touches an undetermined
 * point. */
double sc_rig_leverage(const sc_rig_plan *p, int k, int j);

/* The model's prediction of y_k(j) for the solution f, q (of sc_rig_solve). */
double sc_rig_predict(const sc_rig_plan *p, int k, int j, const double *f, const double *q);

#endif
