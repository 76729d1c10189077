/* selfcal/grid_calibrate.h — a grid-plate measurement to a stage error map, end to end: the
 * method's requirements on the views, the solve (Ye, double shift or least squares), O and R, the
 * noise, and for least squares the residuals, Baarda's outlier test with optional rejection, and
 * the covariance of G. What `selfcal grid` and the Python package's calibrate_grid both call.
 */
#ifndef SELFCAL_GRID_CALIBRATE_H
#define SELFCAL_GRID_CALIBRATE_H

#include "selfcal/api.h"
#include "selfcal/grid.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_scale.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sc_grid_method {
    SC_GRID_METHOD_YE = 0,           /* Ye et al.: rot 0, rot 90, shift +1,0 */
    SC_GRID_METHOD_DOUBLE_SHIFT = 1, /* Petrò: rot 0, rot 90, shift +2,0, shift -3,0 (partial) */
    SC_GRID_METHOD_LSQ = 2           /* least squares, any identifying plan */
} sc_grid_method;

/* "ye", "double-shift" or "lsq" to the method; -1 for any other name. */
SC_API int sc_grid_method_from_name(const char *name);

/* The method's name as the command line spells it. */
SC_API const char *sc_grid_method_name(sc_grid_method m);

/* A warning: one line, no newline (an outlier flagged or removed, a χ² test failed). */
typedef void (*sc_grid_warn_fn)(void *ctx, const char *msg);

typedef struct sc_grid_options {
    sc_grid_method method;
    double sigma_r_um;       /* > 0: the measurement noise, given (least squares on data that
                                state no uncertainties); 0: estimated from the residuals */
    int drift;               /* least squares: per-view linear drift rates (needs t_s) */
    int reject_outliers;     /* least squares: remove the worst flagged measurement, solve again,
                                repeat until none is flagged */
    int covariance;          /* least squares: the full covariance of G (stages of at most
                                SC_GRID_LSQ_COV_MAX_NODES nodes) */
    int node_sigma_only;     /* least squares: skip the σ of O, R and the misalignments (NaN);
                                every node's σ and the outlier test are unchanged */
    double outlier_alpha;    /* least squares: the outlier test's significance, in (0, 1); 0:
                                SC_GRID_OUTLIER_ALPHA (0.05) for the whole data set */
    int outlier_alpha_each;  /* 1: outlier_alpha is each coordinate's own (Baarda's α0, e.g.
                                0.001) instead of the whole data set's */
    int estimate_view_noise; /* least squares: each view's noise estimated from its residuals
                                (Förstner's variance components, iterated to convergence): the
                                views are weighted by it and the uncertainties use it. On data
                                stating uncertainties, a factor on them per view; excludes
                                sigma_r_um */
    double max_bytes;        /* least squares: > 0 refuses a plan estimated to need more memory
                                (sc_grid_lsq_opts.max_bytes); 0: no limit */
    sc_grid_warn_fn warn;    /* warnings (NULL: none) */
    void *warn_ctx;
    int view_scale_free;     /* least squares: each view's scale relative to the others is an
                                unknown (mean 0; for a laboratory without a temperature log),
                                with its uncertainty and a warning when significant */
    sc_grid_progress_fn progress; /* least squares: its phases (sc_grid_lsq_opts; NULL: none) */
    void *progress_ctx;
    int solver;              /* least squares: SC_GRID_SOLVER_AUTO (0), _REDUCED, _FULL
                                (sc_grid_lsq_opts.solver) */
    int node_sigma;          /* least squares: SC_GRID_NODE_SIGMA_ALL (0), _NONE, _SAMPLE: every
                                node's σ and the outlier test, neither, or node_sigma_sample
                                nodes' σ (sc_grid_lsq_opts.node_sigma) */
    int node_sigma_sample;
} sc_grid_options;

/* What came out. Allocated by sc_grid_calibrate, freed by sc_grid_solution_free. */
typedef struct sc_grid_solution {
    sc_grid_result res;      /* G (NX·NY nodes), A (N·N marks), O, R, misalignments, noise, ... */
    long n_nodes;            /* NX·NY */
    long n_marks;            /* N·N */
    int n_views;
    /* least squares only (NULL otherwise), n_views·N·N values, index v·N·N + i·N + j, NaN where
     * a mark is not measured: residual r = measured − fitted (µm), standardized residual t,
     * outlier flag (1: flagged or removed; a removed one keeps its residual against the final
     * solution and t NaN) */
    double *rx_um, *ry_um, *tx, *ty;
    unsigned char *outlier;
    long n_flagged;          /* measurements flagged (removed ones included) */
    long n_removed;          /* measurements removed by reject_outliers */
    double *cov_um2;         /* covariance of G, n_cov x n_cov, node by node, gx then gy */
    long n_cov;
    sc_grid_lsq_info plan_info; /* least squares: the plan's analysis */
    sc_grid_budget budget;   /* the plate's scale and temperature (SPEC §11) and the budget */
} sc_grid_solution;

/* Initialise o: least squares, noise estimated, no drift, no rejection, no covariance. */
SC_API void sc_grid_options_default(sc_grid_options *o);

/* Check that d suits method m: the stage grid of a closed form is the plate's, the views it
 * needs are declared and completely measured; for least squares, a given sigma_r_um only on data
 * stating no uncertainties, drift only with times. info and path (may be NULL: data in memory)
 * locate the problem in the file. SC_E_INPUT with the reason. */
SC_API sc_status sc_grid_check_method(const sc_grid_data *d, const sc_grid_file_info *info,
                                      const char *path, const sc_grid_options *o, sc_error *err);

/* Calibrate d by o into s (zeroed first; free it with sc_grid_solution_free even on failure).
 * d is modified while outliers are rejected and restored before returning. SC_E_INPUT for data
 * that do not suit the method, SC_E_UNSOLVABLE when the measured views do not identify G. */
SC_API sc_status sc_grid_calibrate(sc_grid_data *d, const sc_grid_file_info *info,
                                   const char *path, const sc_grid_options *o,
                                   sc_grid_solution *s, sc_error *err);

/* The Monte Carlo check of a least-squares solution s of d (JCGM 101): trials times, every
 * coordinate's noise (as the budget takes it), E, A and each T_v drawn from their stated normal
 * distributions, the whole estimator run (the correction to the 20 °C plate, least squares with
 * the rows s kept, free view scales, the magnification gauge), on two threads when there are two
 * cores (threads: 0 = that; 1 = one). Trial t draws from its own stream (seed, t): the figures do
 * not depend on the threads. SC_E_INPUT for trials < 2 or a solution not made by least squares. */
SC_API sc_status sc_grid_monte_carlo(const sc_grid_data *d, const sc_grid_options *o,
                                     const sc_grid_solution *s, long trials, uint64_t seed,
                                     int threads, sc_grid_mc *mc, sc_error *err);

/* The JSON summary of a solution (sc_grid_fprint_summary's keys) with the views numbered as
 * the file declares them (view_id; NULL: by position), the scale model and the budget (SPEC
 * §11: magnification_ppm, u_magnification_ppm, a "budget" object) and, when mc is not NULL,
 * the Monte Carlo's figures. */
SC_API void sc_grid_fprint_solution_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                                            const sc_grid_solution *s, const int *view_id,
                                            const sc_grid_mc *mc);

/* Free what a solution holds (safe on a zeroed or freed one). */
SC_API void sc_grid_solution_free(sc_grid_solution *s);

#ifdef __cplusplus
}
#endif
#endif
