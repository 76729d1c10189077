/* grid_lsq_internal.h — private to the grid area (its tests and benchmarks): the reduced, pinned
 * normal matrix a plan factors, so a benchmark can hand the very same matrix to another solver,
 * and reference values of the plan's uncertainties by refined solves. */
#ifndef SELFCAL_GRID_LSQ_INTERNAL_H
#define SELFCAL_GRID_LSQ_INTERNAL_H

#include "selfcal/grid_lsq.h"

/* Unknowns per view at most (tx, ty, φ, vx, vy): the size of a view's own small blocks. */
#define SC_GRID_LSQ_MAX_NB 5

/* The matrix of q: n x n, upper triangle in compressed columns (borrowed from q). */
void sc_grid_lsq_matrix(const sc_grid_lsq_plan *q, int *n, const long **Ap, const int **Ai,
                        const double **Ax);

/* Reference values for accuracy tests, independent of the selected inverse: for nsample nodes
 * spread over the stage, the σ_x ratio by one solve refined against long-double residuals
 * (sx_ref) next to the plan's (sx_plan); for nsample equations spread over the list, the leverage
 * likewise (h_ref, h_plan). Slow (2 nsample refined solves): tests and benchmarks only.
 * Returns 0, -1 if memory ran out or the plan has no uncertainties. */
int sc_grid_lsq_reference(const sc_grid_lsq_plan *q, int nsample, int *node, double *sx_ref,
                          double *sx_plan, long *eq, double *h_ref, double *h_plan);

/* The same for the variance per unit σ of every misalignment unknown (q's nm of them; NaN
 * where the plan has none): var_ref by refined solves, var_plan the plan's. */
int sc_grid_lsq_reference_misalignments(const sc_grid_lsq_plan *q, double *var_ref,
                                        double *var_plan);

/* Förstner's variance components of d's views against a result of q on d: per view v,
 * wrss[v] = Σ w_e r_e² and red[v] = Σ (1 − h_e) over its equations (E[wrss] = σ_v²·red when the
 * view's noise is σ_v times its weights' 1/√w), and u2[v] the mean 1/w_e (µm²; NaN for a view
 * without equations). Arrays of q's views. */
sc_status sc_grid_lsq_view_components(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                      const sc_grid_result *res, double *wrss, double *red,
                                      double *u2, sc_error *err);

/* m := the misalignment unknowns of a result of q on d, refitted from its G and A (nb per view,
 * in the equations' units: tx, ty µm, φ·L µm, drift v·T µm): res's own where a view determines
 * them, else the particular solution whose residuals are the least-squares ones (the columns
 * a view cannot determine, e.g. φ of a view with one mark, at 0; NaN for a view without
 * equations). determined (may be NULL): per view, 1 where its misalignment is determined. */
void sc_grid_lsq_fit_misalignments(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                   const sc_grid_result *res, double *m, int *determined);

/* sc_grid_lsq_predict with the misalignments m (as sc_grid_lsq_fit_misalignments gives them)
 * instead of res's. */
void sc_grid_lsq_predict_with(const sc_grid_lsq_plan *q, const sc_grid_result *res,
                              const double *m, int v, int i, int j, double t_s, double *dx_um,
                              double *dy_um);

/* Šidák's share of a significance alpha over m tests: 1 − (1 − alpha)^(1/m), each test's own. */
double sc_grid_sidak_share(double alpha, long m);

/* How many solves so far had CHOLMOD make its solve workspace anew (execute must add none). */
long sc_grid_lsq_workspace_made(const sc_grid_lsq_plan *q);

/* The plate's magnification m = 1e3·Σ(x·Ax + y·Ay)/Σ(x² + y²) over the measured marks (ppm) of
 * a result of q (the part of the scale SPEC §11 moves to the stage): *var_m = Var(m)/σ0² and
 * cov_gx, cov_gy (stage nodes) = Cov(G, m)/σ0² in the SPEC gauge, per unit σ0 as the plan's
 * node σ ratios. Returns 0, -1 if the plan does not identify G or memory ran out. */
int sc_grid_lsq_plate_magnification(const sc_grid_lsq_plan *q, double *var_m, double *cov_gx,
                                    double *cov_gy);

#endif
