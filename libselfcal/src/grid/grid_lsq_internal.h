/* grid_lsq_internal.h — private to the grid area (its tests and benchmarks): the reduced, pinned
 * normal matrix a plan factors, so a benchmark can hand the very same matrix to another solver;
 * the variance components, refitted misalignments and plate magnification the calibration uses;
 * and, below, the plan itself and the functions the estimator's four files share. */
#ifndef SELFCAL_GRID_LSQ_INTERNAL_H
#define SELFCAL_GRID_LSQ_INTERNAL_H

#include "selfcal/grid_lsq.h"
#include "../linalg/sparse_sym.h"
#include "../linalg/stats.h" /* sc_grid_sidak_share, the quantiles */
#include "grid_lsq_full.h"
#include "selfcal/error.h"

/* Unknowns per view at most (tx, ty, φ, vx, vy): the size of a view's own small blocks. */
#define SC_GRID_LSQ_MAX_NB 5

/* The matrix of q: n x n, upper triangle in compressed columns (borrowed from q). */
void sc_grid_lsq_matrix(const sc_grid_lsq_plan *q, int *n, const long **Ap, const int **Ai,
                        const double **Ax);

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

/* How many solves so far had CHOLMOD make its solve workspace anew (execute must add none). */
long sc_grid_lsq_workspace_made(const sc_grid_lsq_plan *q);

/* The plate's magnification m = 1e3·Σ(x·Ax + y·Ay)/Σ(x² + y²) over the measured marks (ppm) of
 * a result of q (the part of the scale SPEC §11 moves to the stage): *var_m = Var(m)/σ0² and
 * cov_gx, cov_gy (stage nodes) = Cov(G, m)/σ0² in the SPEC gauge, per unit σ0 as the plan's
 * node σ ratios. Returns 0, -1 if the plan does not identify G or memory ran out. */
int sc_grid_lsq_plate_magnification(const sc_grid_lsq_plan *q, double *var_m, double *cov_gx,
                                    double *cov_gy);

/* ---- for the test references only (tests/unit/grid_lsq_reference.c; grid_lsq_probe.c) ----
 * Each uncertainty of a plan is a quadratic form vᵀΣv of the pinned inverse Σ (0 on pins) over
 * the n_red reduced unknowns; these give v and the plan's own value, so that a test can compute
 * the form independently (refined solves). */

/* What a reference reads of q's sizes: the reduced unknowns (ng of them G), the stage nodes,
 * the misalignment unknowns and the equations; pinned: per reduced unknown (borrowed). */
typedef struct sc_grid_lsq_probe {
    int n_red, ng, ns, nm;
    long neq;
    const unsigned char *pinned;
} sc_grid_lsq_probe;
void sc_grid_lsq_probe_get(const sc_grid_lsq_plan *q, sc_grid_lsq_probe *p);

/* b := the pinned solve of b (n_red; zero on pins) with q's factor, unrefined. 0, -1 if memory
 * ran out. */
int sc_grid_lsq_probe_solve(const sc_grid_lsq_plan *q, double *b);

/* (σ_x of stage node k / σ)² = vᵀΣv with v = P⊥ e_x(k); *plan: the plan's σ_x ratio. Returns 0,
 * -1 if the plan has no node σ or memory ran out. */
int sc_grid_lsq_probe_node(const sc_grid_lsq_plan *q, int k, double *v, double *plan);

/* The leverage of equation e is c + w·vᵀΣv (v = its row minus its A group's weighted mean row,
 * c = w_e/W_a, w = w_e); *plan: the plan's leverage. Returns 0, -1 if the plan has none. */
int sc_grid_lsq_probe_equation(const sc_grid_lsq_plan *q, long e, double *v, double *c,
                               double *w, double *plan);

/* Var/σ0² of misalignment unknown t is vᵀΣv + c; *plan: the plan's. Returns 0; 1 if the plan
 * gives it no uncertainty (not estimable, or its view's own free column); -1 if the plan has no
 * misalignment variances or memory ran out. */
int sc_grid_lsq_probe_misalignment(const sc_grid_lsq_plan *q, int t, double *v, double *c,
                                   double *plan);

/* ---------------------------------------------------------------------------------------------
 * Shared by the estimator's files (grid_lsq_plan.c, grid_lsq_execute.c, grid_lsq_functionals.c,
 * grid_lsq_residuals.c, grid_lsq_probe.c); nothing else uses them. The method:
 *
 * Unknowns: G (2 per node), A (2 per measured mark), (tx, ty, φ) per view with φ = θ·L·1e-3 µm
 * (L = c·P, so the rotation column is scaled like the others). Each scalar equation touches one
 * G component, one A component (coefficient ±1) and its view's misalignment.
 *
 * 1. A is eliminated exactly: its block of the normal matrix is diagonal (the number of views
 *    measuring the mark); per A component the equations form a group and elimination centres
 *    the group. What is left is S x = b on x = (g, m).
 * 2. The 7-dimensional gauge null space of S (G translation/rotation/magnification, plate
 *    translation/rotation seen through the misalignments) is removed by pinning: both components
 *    of G at two distinct measured nodes and the misalignment of one view are fixed at 0. The
 *    pinned matrix is S with those rows/columns replaced by identity rows; it is nonsingular iff
 *    the plan identifies G (and every view's misalignment). The G of the pinned solution differs
 *    from the gauged one by a gauge pattern, so G = P⊥ g_pin (P⊥ the orthogonal projector of
 *    sc_grid_gauge_stage), exactly.
 * 3. The pinned matrix is factored once per plan (sparse_sym.h: CHOLMOD's supernodal Cholesky in
 *    the order of AMD with the free misalignments last; a rank-revealing LDLᵀ
 *    when it is numerically singular); null pivots are decided with a relative tolerance.
 * 4. Everything that does not depend on the measured values is computed by the plan: per-node
 *    variances Cov(G)/σ² = P⊥ Σ P⊥ with Σ = pinned inverse (zero on pins), diag(Σ) by the
 *    supernodal selected inverse and the projection from W = ΣU (4 columns); the leverage of every
 *    equation (the selected inverse on S's pattern and the free misalignments' whole columns of
 *    Σ, which the same selected inverse gives); the variances of O, R and the misalignments per
 *    unit σ (W, 5 more columns, the misalignment columns; left out with node_sigma_only). Two
 *    blocked solves: W (4 columns), then the 5 functional ones.
 * 5. Execute: one solve refined against the equations (up to 3 steps), the gauge, the residual
 *    sums; no allocation (the plan holds the workspace, so one plan serves one thread at a time).
 * ------------------------------------------------------------------------------------------- */

#define LSQ_PIVOT_TOL 1e-9 /* pivot / original diagonal below this: null */
#define LSQ_SMALL_TOL 1e-11 /* relative tolerance of the small dense rank decision */
#define LSQ_NOMEM_MSG "out of memory building the least-squares system"
#define ROW_MAX 4 /* entries of one equation's row */
#define SOLVE_CHUNK 8 /* right-hand sides per blocked solve (workspace 2·n_red·SOLVE_CHUNK) */

struct sc_grid_lsq_plan {
    sc_grid_plan plan;
    int n, nn, nv;          /* plate N, its N² marks, views */
    int stage_nx, stage_ny, ns; /* stage grid NX, NY and its node count */
    int nb;                 /* unknowns per view: tx, ty, φ (+ vx, vy with drift) */
    int drift;
    int node_sigma_only;    /* no σ of O, R and the misalignments (sc_grid_lsq_opts) */
    double max_bytes;       /* > 0: refuse a plan estimated to need more (sc_grid_lsq_opts) */
    sc_grid_progress_fn progress; /* sc_grid_lsq_opts' (NULL: none) */
    void *progress_ctx;
    double peak_est;        /* the peak memory estimated so far, bytes (0: not yet) */
    double work_total;      /* multiply-adds of the factor and selected inverse (0: not known) */
    int weighted;           /* weights were stated (1/u²); else all 1 */
    int unit_weights;       /* sc_grid_lsq_opts.unit_weights: stated weights ignored */
    double *eq_w;           /* weight of each scalar equation */
    double *eq_dt;          /* drift column: (t - mean t of the view) / T_v */
    /* per view (nv each, one block: view_block; plan_init) */
    double *drift_T;        /* T_v: the scale of each view's drift column, s */
    double *drift_t0;       /* mean time of each view's measurements, s */
    unsigned char *view_free; /* a view that leaves its own columns free */
    double *view_block;
    double *fit_work;       /* fit_misalignments' nb x nb normal matrix and nb right-hand side
                               per view: nv (nb² + nb) doubles, then mis_work */
    double *mis_work;       /* residuals' and view components' misalignments and counts:
                               nm + nv doubles (so that they allocate nothing) */
    double L_mm;            /* rotation scale c·P */
    double r2_mm2;          /* Σ x² + y² over the stage nodes (gauge basis, O and R functionals) */
    unsigned char *meas;    /* nv*nn: view v measures mark k */
    int *mark_views;        /* per mark: number of views measuring it */
    long n_meas_marks;
    long neq;               /* scalar equations */
    int *eq_g, *eq_v, *eq_k, *eq_a;
    unsigned char *eq_c;    /* 0: dx, 1: dy */
    signed char *eq_s;      /* sign of the A component */
    double *eq_pos;         /* coefficient of φ */
    long *grp_ptr;          /* equations of each A component (2*nn groups) */
    long *grp_eq;
    int ng, nm;             /* G unknowns (2 per stage node), misalignment unknowns (nb per view) */
    int n_red;              /* unknowns of the reduced system: ng + nm */
    long *Ap;               /* the pinned reduced matrix: upper CSC, original index space */
    int *Ai;
    double *Ax;
    sc_spsym *f;            /* its factorization (sparse_sym.h) */
    sc_lsq_full *full;      /* A kept as unknowns (grid_lsq_full.h): f factors that matrix */
    int n_fac;              /* unknowns of the factored matrix: n_red, or more with A kept */
    int solver;             /* sc_grid_lsq_opts.solver as asked (AUTO, REDUCED, FULL) */
    int node_sigma, node_sigma_sample; /* sc_grid_lsq_opts' */
    double *m_rows;         /* with A kept: per misalignment, its entries of W (4) and of the
                               solves of D (3), for the misalignments' σ (plan_uncertainties) */
    unsigned char *pinned;  /* per unknown (original index) */
    int pin_node[2], pin_view;
    int nullity_pin, nullity_T;
    sc_grid_lsq_info info;
    long rank;
    /* what does not depend on the measured values, computed by the plan (per unit σ) */
    double *sgx, *sgy;      /* std/σ_r per node (NaN if not identified) */
    double *eq_h;           /* leverage of each equation */
    double var_O, var_R;    /* Var(O)/σ0², Var(R)/σ0² (NaN if not computed) */
    double *var_m;          /* nm: Var(misalignment unknown)/σ0² (NaN where not unique) */
    int misalignment_unique;    /* every view's misalignment determined (nullity_T = 3) */
    /* the misalignments free beyond the gauge are only views' own (a view of one mark: its
     * rotation; of none: all): the others are estimable, with uncertainties */
    int misalignment_estimable;
    double *work;           /* execute's workspace: 4 n_red + ng + 2 nn + nm doubles */
    size_t bytes;
};

/* ---- grid_lsq_plan.c ---- */

/* Tell the caller's progress function (if any) the phase and the work done so far. */
void sc_lsq_progress(const sc_grid_lsq_plan *q, const char *phase, double done);

/* Numerical rank deficiency of a small dense symmetric PSD matrix (m x m, destroyed) by
 * Cholesky with diagonal pivoting; pivots below tol·(largest diagonal) end it. */
int sc_lsq_small_nullity(double *a, int m, double tol);

/* Misalignment blocks of up to this many unknowns (or the plate's 2N² A components where there
 * are more) get their nullity densely (sc_lsq_small_nullity, 8·nm² bytes: 2.9 MB here); larger
 * ones from the sparse factor (docs/grid-lsq.md, "The misalignment block's nullity"). */
#define LSQ_MM_DENSE_MAX 600

/* ν₂, the nullity of the full system's misalignment block (A eliminated, G held at 0): dense
 * (LSQ_SMALL_TOL of the largest diagonal) when nm <= dense_max, else sparse (LSQ_SMALL_TOL of
 * each pivot's own diagonal). The nullity, or -1 no memory, -2 no CHOLMOD, -3 address space. */
int sc_lsq_misalignment_nullity(const sc_lsq_full_desc *fd, int dense_max);

/* Coefficients of w_e = s_e·J_e over x = (g, m): 3 (index, value) pairs, 4 with drift. */
int sc_lsq_eq_row(const sc_grid_lsq_plan *q, long e, int *idx, double *val);

/* q's equations as grid_lsq_full.h takes them. */
void sc_lsq_full_desc_of(const sc_grid_lsq_plan *q, sc_lsq_full_desc *d);

/* The free (unpinned) misalignment unknowns: their original indices into at (ascending; may be
 * NULL), and into slot each misalignment's place among them, which is its whole column's in the
 * selected inverse (-1 pinned; may be NULL); their count. */
int sc_lsq_free_misalignments(const sc_grid_lsq_plan *q, int *at, int *slot);

/* X (n_red x ncol, column after column) := pinned-system solves of its columns (original index
 * space), with `refine` steps of iterative refinement against the assembled matrix; B and R:
 * workspace of n_red·ncol each (unused, may be NULL, without refinement). Returns 0, -1 if the
 * solver ran out of memory. */
int sc_lsq_pinned_solve(const sc_grid_lsq_plan *q, double *X, int ncol, int refine, double *B,
                        double *R);

/* X (n_red x ncol) := 0 at the pinned unknowns. */
void sc_lsq_zero_pinned(const sc_grid_lsq_plan *q, double *X, int ncol);

/* Equation e's part (its row idx, val, len: eq_row's) of its view's block of the misalignment
 * normal matrix, G and A held (nrm: nb x nb per view). */
void sc_lsq_view_normal_add(const sc_grid_lsq_plan *q, long e, const int *idx, const double *val,
                            int len, double *nrm);

/* The redundancy figures of q->info from the leverages. */
void sc_lsq_redundancy_info(sc_grid_lsq_plan *q);

/* ---- grid_lsq_functionals.c ---- */

/* U (4 x ng, row after row): the orthonormal basis of G's gauge patterns (translations, rotation,
 * magnification) that sc_grid_gauge_stage projects out. */
void sc_lsq_gauge_basis(const sc_grid_lsq_plan *q, double *U, double scale[4]);

/* (CᵀN)⁻ᵀ, 7 x 7 row-major; 0 if singular. */
int sc_lsq_gauge_matrix(const sc_grid_lsq_plan *q, double *Minv_T);

/* u = Qᵀ f for the functional f given on G (fg, ng, may be NULL) and m (fm, nm, may be NULL):
 * ux on the reduced unknowns (n_red), uA on the A components (2 nn); u = f − Σ_t γ_t C_t. */
void sc_lsq_functional_vectors(const sc_grid_lsq_plan *q, const double *Minv_T, const double *fg,
                               const double *fm, double *ux, double *uA, double gam[7]);

/* uᵀ Σ u in two halves: z_x = S⁻¹(u_x − Σ_a (u_A[a]/W_a) Σ_e w_e ρ_e), then z_A[a] = (u_A[a] −
 * Σ_e w_e ρ_e·z_x)/W_a (functional_form). This subtracts the A part of the right-hand side from z. */
void sc_lsq_a_correction(const sc_grid_lsq_plan *q, const double *uA, double *z);

/* The affine form behind uᵀΣu (a_correction): uxᵀz − Σ_a u_A[a]·(Σ_e w_e ρ_e·z)/W_a, plus the
 * constant Σ_a u_A[a]²/W_a when with_const. Linear in z, so a z combined from several columns of
 * Σ can be taken column by column. */
double sc_lsq_functional_form(const sc_grid_lsq_plan *q, const double *ux, const double *uA,
                              const double *z, int with_const);

/* Everything of an identifying plan that does not depend on the measured values. First blocked
 * solves on the factor: W = ΣU (the gauge columns, 4) for the projection's part of every node's
 * σ, and B = Σ·functional_basis_rhs (5) for the σ of O and R; then the selected inverse (kept: the
 * diagonal, the G pairs on S's pattern, the free misalignments' whole columns) for diag(Σ), the
 * misalignments' σ and every leverage. The selected inverse and the columns are dropped after.
 * W and B are two solves, so that every node's σ is the same to the last bit whether or not the
 * σ of O, R and the misalignments is asked for (node_sigma_only skips B and what uses it: 10 ms
 * of the 0.15 s grid command at N = 101). No iterative refinement: diag(Σ) and the misalignment
 * columns come from the recurrences on the same factor, so refined columns would not make the
 * results more accurate (docs/grid-lsq.md). */
sc_status sc_lsq_plan_uncertainties(sc_grid_lsq_plan *q, sc_error *err);

/* ---- grid_lsq_execute.c ---- */

sc_status sc_lsq_check_data(const sc_grid_lsq_plan *q, const sc_grid_data *d, sc_error *err);

/* Solve a small dense symmetric system m x m (row-major, destroyed) in place of rhs by Gaussian
 * elimination with partial pivoting; a null pivot gives a NaN solution. */
void sc_lsq_small_solve(double *a, double *rhs, int m);

/* One view's misalignment fit from its normal equations nrm (nb x nb, row-major) and rh: the
 * columns taken in order (tx, ty, φ, vx, vy), each kept when the system stays regular with it
 * (Cholesky with diagonal pivoting, LSQ_SMALL_TOL), the kept ones solved, the others 0 — a
 * particular least-squares solution, so the residuals are right whatever the view determines
 * (a single mark: tx, ty fit it exactly, φ stays 0). m: nb values (NaN for a view without
 * equations); returns how many columns were kept (nb: the misalignments are determined). */
int sc_lsq_fit_view(const double *nrm, const double *rh, int nb, double *m);

/* Misalignments (and drift): per view, weighted least squares of d - G - Rot A on its nb columns,
 * G as gx | gy (ns each), A's x and y of mark k at ax[k·as] and ay[k·as] (as: 2 for the solve's
 * interleaved A, 1 for a result's). m: nm, a particular solution where a view does not determine
 * its columns (fit_view; q->view_free says which). Uses q->fit_work (one plan, one thread). */
void sc_lsq_fit_misalignments(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *gx,
                              const double *gy, const double *ax, const double *ay, int as,
                              double *m);

/* σ scale of the standardized residuals of a result: its σ0, or when the stated noise is too
 * small for the residuals (χ² test failed high) a posteriori (Pope's τ): data snooping with the
 * stated noise would flag nearly everything. */
double sc_lsq_residual_scale(const sc_grid_result *res);

/* Residual of equation e: data − G − s·A − misalignment (and drift) terms; gv, av: the G and A
 * components the equation touches, m: the misalignment unknowns (nm). */
double sc_lsq_eq_residual(const sc_grid_lsq_plan *q, const sc_grid_data *d, long e, double gv,
                          double av, const double *m);

#endif
