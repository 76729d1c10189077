/* stats.h — private to the library: the statistics the least-squares tests use (stats.c), for
 * the grid and profile areas alike. The functions are part of the public API too (declared in
 * selfcal/grid_lsq.h and selfcal/grid_scale.h, where callers of the library find them); this
 * header lets an area use them without including the grid's headers. Depends on nothing but
 * selfcal/api.h. */
#ifndef SELFCAL_LINALG_STATS_H
#define SELFCAL_LINALG_STATS_H

#include "selfcal/api.h"

/* The p-quantile of the χ² distribution with dof degrees of freedom (NaN for bad arguments). */
SC_API double sc_chi2_quantile(double p, double dof);

/* z > 0 with P(|Z| > z) = alpha for a standard normal Z (0 < alpha < 1, else NaN). */
SC_API double sc_normal_two_sided_critical(double alpha);

/* Student's t quantile: t with P(T <= t) = p for dof degrees of freedom (dof > 0, may be
 * fractional; INFINITY: the normal's). NaN for bad arguments. */
SC_API double sc_student_t_quantile(double p, double dof);

/* Šidák's share of a significance alpha over m tests: 1 − (1 − alpha)^(1/m), each test's own. */
double sc_grid_sidak_share(double alpha, long m);

/* The |t| beyond which the outlier test flags a coordinate: alpha for the whole set of n_tests
 * coordinates (each = 0), or for each coordinate on its own (each = 1). NaN for bad arguments. */
SC_API double sc_grid_outlier_critical(double alpha, long n_tests, int each);

/* The default significance of the outlier test over a whole data set; the same definition as
 * selfcal/grid_lsq.h's (an identical macro redefinition), so the two cannot differ silently. */
#define SC_GRID_OUTLIER_ALPHA 0.05

/* Baarda's minimal detectable bias of an equation with redundancy r, in units of its σ:
 * (crit + z_power)/√r. NaN for r ≤ 0 or power outside (0, 1). */
SC_API double sc_grid_mdb_ratio(double crit, double power, double r);

#endif
