/* selfcal/grid_lsq.h — the optimal (least-squares) grid self-calibration for any view plan.
 *
 * Unknowns: G at every stage node, A at every mark, (tx, ty, θ) per view; the SPEC gauge as hard
 * constraints. Plan verbs as FFTW's: sc_grid_lsq_plan_create, sc_grid_lsq_execute,
 * sc_grid_lsq_plan_destroy. The structure (which marks each view measures) is analysed once when
 * the plan is created: whether the plan identifies G, how many degrees of freedom stay free, and each node's
 * standard uncertainty per unit σ_r from the exact estimator covariance. Sparse: each measurement
 * touches one node, one mark, one view.
 */
#ifndef SELFCAL_GRID_LSQ_H
#define SELFCAL_GRID_LSQ_H

#include "selfcal/api.h"
#include "selfcal/grid.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_grid_lsq_plan sc_grid_lsq_plan;

typedef struct sc_grid_lsq_info {
    int identifiable;         /* 1 if the plan determines G (in the SPEC gauge) */
    long free_dof;            /* independent G patterns beyond the gauge left free; 0 if identifiable */
    long n_unknowns;          /* G, A and misalignment unknowns */
    long n_equations;         /* scalar measurement equations (2 per measured mark) */
    long n_constraints;       /* gauge constraints */
    double sigma_c_ratio_rms; /* predicted RMS over nodes and both components of std(G)/σ_r;
                                 with stated uncertainties (weighted), std(G) itself in µm */
    double sigma_c_ratio_max; /* the worst node component */
    long n_stage_unmeasured;  /* stage nodes no measurement touches (each leaves G free there) */
    /* internal reliability (Baarda), identifying plans only (else NaN and 0): the redundancy
     * number r = 1 − h of each coordinate's equation, h its leverage */
    long n_testable;          /* equations the outlier test can check (r > 1e-9) */
    long n_untestable;        /* equations with r = 0 (a mark seen in one view only: its plate
                                 error absorbs any error there, which no test can see) */
    double redundancy_min;    /* the smallest r of a testable equation */
    double redundancy_mean;   /* the mean r of the testable equations */
    double mdb_ratio_max;     /* the minimal detectable blunder (sc_grid_mdb_ratio, 80 % power)
                                 of the default test (SC_GRID_OUTLIER_ALPHA over the testable
                                 equations) at redundancy_min, in units of the coordinate's σ */
    double mdb_ratio_mean_r;  /* the same at redundancy_mean */
    long residual_dof;        /* equations minus the rank: the residuals' degrees of freedom
                                 (identifying plans; the dof of sc_grid_lsq_execute's result) */
    int weighted;             /* 1: the plan's views or data state uncertainties, which weight
                                 it (sigma_c_ratio_* are then in µm; unit_weights for ratios) */
} sc_grid_lsq_info;

/* Progress of a long computation (called from the computing thread): phase is "assemble",
 * "analyse", "factor", "selected inverse" or "solve" (sc_grid_calibrate adds "residuals");
 * work_done of work_total multiply-adds of the factor and the selected inverse are done (both 0
 * until the analysis has counted them, work_done = work_total at the end); peak_bytes is the peak
 * memory estimated so far (from the plan before the assembly, from the analysis after it; 0:
 * not yet). */
typedef void (*sc_grid_progress_fn)(void *ctx, const char *phase, double work_done,
                                    double work_total, double peak_bytes);

/* Model options. */
typedef struct sc_grid_lsq_opts {
    int drift;                /* 1: per-view translation drift rates (vx, vy)·(t − mean t) as
                                 unknowns; times from the data's t_s, or for a plan without data
                                 the serpentine order of measurement, one per second */
    int node_sigma_only;      /* 1: every node's σ and every leverage, but not the σ of O, R and
                                 the misalignments (NaN in sc_grid_result): less work (N = 101:
                                 10 ms of 0.15 s); node σ identical either way. 0: all of them */
    double max_bytes;         /* > 0: refuse (SC_E_NOMEM, saying how much it needs) a plan whose
                                 peak memory exceeds it: estimated from the plan before the
                                 assembly (its dense node-misalignment block and the pairs of
                                 unknowns each plate mark couples), then from the factor's
                                 analysis (about 4x the factor) before factoring; 0: no limit */
    int unit_weights;         /* 1: every equation weight 1, stated uncertainties ignored: the
                                 plan's geometry alone (its σ_C ratios per unit σ_r) */
    sc_grid_progress_fn progress; /* NULL: none */
    void *progress_ctx;
    int solver;               /* SC_GRID_SOLVER_AUTO (0), _REDUCED or _FULL: which normal
                                 matrix is factored (docs/grid-lsq.md, "Large stages") */
    int node_sigma;           /* SC_GRID_NODE_SIGMA_ALL (0), _NONE or _SAMPLE */
    int node_sigma_sample;    /* SC_GRID_NODE_SIGMA_SAMPLE: the number K of stage nodes whose
                                 σ is computed (by solves; spread over the measured nodes) */
} sc_grid_lsq_opts;

/* sc_grid_lsq_opts.solver. REDUCED: A eliminated, the normal matrix of G and the misalignments
 * (small and fast when each mark is measured in a few views). FULL: A kept as unknowns, the
 * matrix of every unknown with the misalignments ordered last (its size grows with the
 * equations only: stitched plans of hundreds of placements). AUTO: FULL when the pairs of stage
 * unknowns eliminating A would couple, Σ k(k−1)/2 over the plate mark components measured k
 * times, exceed 8 per equation (k > 17); REDUCED otherwise. Both give the same results (to rounding). */
#define SC_GRID_SOLVER_AUTO 0
#define SC_GRID_SOLVER_REDUCED 1
#define SC_GRID_SOLVER_FULL 2

/* sc_grid_lsq_opts.node_sigma. ALL: every node's σ and every equation's leverage by the selected
 * inverse (the outlier test needs the leverages). NONE: neither (σ NaN, no leverages, so no
 * standardized residuals and no outlier test): the factor and the solve only. SAMPLE: the σ of
 * node_sigma_sample nodes by solves (2 per node), the others NaN, no leverages. */
#define SC_GRID_NODE_SIGMA_ALL 0
#define SC_GRID_NODE_SIGMA_NONE 1
#define SC_GRID_NODE_SIGMA_SAMPLE 2

/* The memory a plan may take by default, in bytes: the machine's available memory (Linux's
 * MemAvailable: free plus reclaimable caches), else its physical memory; 0 when unknown. */
SC_API double sc_memory_available_bytes(void);

/* The outlier test, Baarda's data snooping (docs/grid-lsq.md): on clean data each standardized
 * residual t is N(0, 1); a coordinate is flagged when |t| exceeds a two-sided critical value. By
 * default its significance α holds for the whole data set: the chance that clean data raise any
 * flag among the m coordinates tested, each tested at 1 − (1 − α)^(1/m) (Šidák), so that a clean
 * calibration stays quiet whatever its size; SC_GRID_OUTLIER_ALPHA is that default. Baarda's
 * classical choice, α0 = 0.001 for each coordinate on its own (|t| > 3.29), flags ~1 coordinate in
 * 1000 of clean data: several on every plate of a few thousand measurements. */
#define SC_GRID_OUTLIER_ALPHA 0.05

/* z > 0 with P(|Z| > z) = alpha for a standard normal Z (0 < alpha < 1, else NaN): 1.96 for
 * 0.05, 3.2905 for 0.001. Accurate to a few ulps of z down to the smallest alpha. */
SC_API double sc_normal_two_sided_critical(double alpha);

/* Baarda's minimal detectable bias of an equation with redundancy r, in units of its σ: the
 * blunder the test at critical value crit (sc_grid_outlier_critical) finds with probability
 * power, (crit + z_power)/√r, z_power the one-sided normal quantile of power (0.80: 0.8416).
 * NaN for r ≤ 0 or power outside (0, 1). */
SC_API double sc_grid_mdb_ratio(double crit, double power, double r);

/* The |t| beyond which the outlier test flags a coordinate: alpha for the whole set of n_tests
 * coordinates (each = 0), or for each coordinate on its own (each = 1; n_tests unused). NaN for
 * alpha outside (0, 1), or n_tests < 1 with each = 0. */
SC_API double sc_grid_outlier_critical(double alpha, long n_tests, int each);

/* Whether a standardized residual t fails the outlier test a result ran (res->outlier_crit, of
 * sc_grid_calibrate); NaN t (not tested) never does. */
SC_API int sc_grid_outlier_beyond(const sc_grid_result *res, double t);

/* The largest stage (nodes) whose full covariance sc_grid_lsq_covariance writes (41 x 41). */
#define SC_GRID_LSQ_COV_MAX_NODES 1681

/* Analyse and factor a plan: everything that does not depend on the measured values is done
 * here (the factorization, every node's σ by the selected inverse, the leverage of every
 * measurement, the σ of O, R and the misalignments per unit noise). mask: NULL to measure what
 * the plan says (sc_grid_view_measures), else the marks with finite values in mask->dx_um are
 * the measured ones (dx and dy finite together, on marks that land on the grid: SC_E_INPUT
 * otherwise). With weights stated in mask (ux_um/uy_um, a view's sigma_um) or, for a plan
 * without data, in the views' sigma_um, each coordinate weighs 1/u². opts: model options (NULL:
 * none). A plan that does not identify G is not an error here: *out is made and its info says
 * so. Cost ~N³ time, ~N² log N memory (N = 101: ~0.3 s CPU, ~35 MiB); see docs/grid-lsq.md. */
SC_API sc_status sc_grid_lsq_plan_create(const sc_grid_plan *plan, const sc_grid_data *mask,
                                         const sc_grid_lsq_opts *opts, sc_grid_lsq_plan **out,
                                         sc_error *err);

/* The p-quantile of the χ² distribution with dof degrees of freedom (NaN for bad arguments). */
SC_API double sc_chi2_quantile(double p, double dof);

/* The plan's analysis. */
SC_API void sc_grid_lsq_get_info(const sc_grid_lsq_plan *q, sc_grid_lsq_info *info);

/* Per-node std(Gx)/σ_r and std(Gy)/σ_r (arrays of the stage's NX·NY nodes, sc_grid_stage_nx(plan)
 * · sc_grid_stage_ny(plan): n*n on an N x N stage; caller-owned). SC_E_UNSOLVABLE if G is not identified. */
SC_API sc_status sc_grid_lsq_sigma_ratio(const sc_grid_lsq_plan *q, double *sgx, double *sgy, sc_error *err);

/* Estimate from data measured as the plan was made for (same marks; the weights are the plan's,
 * from its mask). Weighted data: the uncertainties use the stated u as they are and
 * res->variance_factor tests them. Unweighted: sigma_r_um > 0 is used for the uncertainties (and
 * tested), otherwise the noise estimated from the residuals. Also fills O, R, misalignment and
 * drift uncertainties. The plan is not changed, but its solve workspace is used: not
 * thread-safe on one plan (one plan per thread). SC_E_UNSOLVABLE if G is not identified;
 * SC_E_INPUT if d's measured marks differ from the plan's. */
SC_API sc_status sc_grid_lsq_execute(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                     double sigma_r_um, sc_grid_result *res, sc_error *err);

/* Residuals of d against a result res of sc_grid_lsq_execute on d (res with its G and A arrays):
 * r = measured − fitted (µm) and standardized residuals t = r / (σ·√(1−h)) with h the exact
 * leverage of that coordinate's equation, σ its stated or estimated standard deviation (scaled
 * by √(variance factor) when the stated noise fails the χ² test on the high side); h_out: the
 * larger leverage of the two coordinates. Arrays n_views*n*n (index v*n*n + i*n + j),
 * caller-owned, NULL to skip; NaN where a mark is not measured (and t NaN where h = 1: a mark
 * seen in one view only is not tested). */
SC_API sc_status sc_grid_lsq_residuals(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                       const sc_grid_result *res, double *rx_um, double *ry_um,
                                       double *tx, double *ty, double *h_out, sc_error *err);

/* The fitted dev (µm) of mark (i, j) in view v from a result of this plan (NaN where the
 * plate error is unknown, where the view's misalignment is undetermined (res reports it NaN:
 * a view of one mark), or v, i, j name no mark the view puts on the stage); t_s: its time,
 * used with drift. For measurements left out of the plan (rejected outliers). */
SC_API void sc_grid_lsq_predict(const sc_grid_lsq_plan *q, const sc_grid_result *res, int v, int i,
                                int j, double t_s, double *dx_um, double *dy_um);

/* The full covariance of G in the SPEC gauge for a result res of this plan (its
 * sigma_r_used_um), µm², (2·NX·NY)² doubles row-major, unknowns ordered node by node
 * (i*NX + j), Gx before Gy. SC_E_INPUT beyond SC_GRID_LSQ_COV_MAX_NODES nodes. Uses the plan's
 * solve workspace: not thread-safe on one plan. */
SC_API sc_status sc_grid_lsq_covariance(const sc_grid_lsq_plan *q, const sc_grid_result *res,
                                        double *cov, sc_error *err);

/* Internals of the sparse factorization, for benchmarks and diagnostics. */
typedef struct sc_grid_lsq_stats {
    long n_reduced;              /* unknowns after eliminating A: 2N² (G) + 3V (misalignments) */
    long nnz_matrix;             /* stored entries of the reduced matrix (upper triangle) */
    long nnz_factor;             /* entries of L (strictly lower) */
    double factor_flops;         /* multiply-adds of the LDLᵀ factorization */
    double selinv_work;          /* multiply-adds of the selected inverse */
    const char *ordering;        /* fill-reducing order used (a static name) */
    int solver;                  /* SC_GRID_SOLVER_REDUCED or _FULL: the matrix factored */
    long n_factored;             /* its unknowns (n_reduced, or with A kept: + the A components) */
    int n_null_pivots;           /* pivots judged null in the pinned reduced matrix */
    int nullity_misalignment;    /* null space of the misalignment block with G held (3 = plate motion) */
    double min_kept_pivot_ratio; /* smallest pivot/diagonal kept: the margin to the tolerance */
    double max_null_pivot_ratio; /* largest pivot/diagonal judged null (0 if none) */
    size_t bytes;                /* memory the plan holds (and used for assembly), bytes */
} sc_grid_lsq_stats;

/* Fill st with the plan's internals. */
SC_API void sc_grid_lsq_get_stats(const sc_grid_lsq_plan *q, sc_grid_lsq_stats *st);

/* Free the plan (NULL is fine). */
SC_API void sc_grid_lsq_plan_destroy(sc_grid_lsq_plan *q);

#ifdef __cplusplus
}
#endif
#endif
