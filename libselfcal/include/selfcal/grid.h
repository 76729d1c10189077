/* selfcal/grid.h — grid-plate self-calibration of an XY stage: shared types and geometry.
 *
 * Conventions (SPEC §1): N x N marks, N odd, pitch P (mm), c = (N-1)/2. Mark (i, j): i = plate row
 * (y), j = plate column (x). Stage node (i, j) sits at origin + ((j-c)P, (i-c)P). A view places the
 * plate rotated by rot (CCW, degrees) and shifted by (sx, sy) pitches. Arrays over marks or nodes
 * are row-major, index i*N + j.
 *
 * Model, all in µm: dev = measured - nominal stage position
 *       = G(node) + Rot(A(mark)) + (tx - θ·y, ty + θ·x) + noise,
 * with (x, y) the node's nominal position relative to the grid centre in mm and θ in µrad
 * (1 µrad × 1 mm = 1 nm = 1e-3 µm).
 * Gauge of the reported maps: ΣGx = ΣGy = 0, Σ(x·Gy - y·Gx) = 0, Σ(x·Gx + y·Gy) = 0 over the
 * stage nodes; ΣAx = ΣAy = 0, Σ(x·Ay - y·Ax) = 0 over the marks. O and R as Petrò eqs. (4)-(6):
 * Gx = O·y + R·x + Fx, Gy = O·x - R·y + Fy (O and R dimensionless, µm per µm).
 */
#ifndef SELFCAL_GRID_H
#define SELFCAL_GRID_H

#include <stdbool.h>
#include "selfcal/api.h"
#include "selfcal/error.h"
#include "selfcal/stage_map.h" /* SC_STAGE_MAP_MIN_PITCH_MM */

#ifdef __cplusplus
extern "C" {
#endif

/* Views are sized at run time (no cap in any struct). SC_GRID_VIEW_LIMIT is only the readers' and
 * plan check's sanity limit (a view costs about 1 KiB of plan and 2·N² doubles of data). */
#define SC_GRID_VIEW_LIMIT 100000
#define SC_GRID_MAX_N 513
#define SC_GRID_MAX_STAGE 4097 /* largest NX or NY */
/* The smallest pitch (1 nm: what a table can place) and the smallest stated standard
 * uncertainty (1 pm) a grid file, a plan or an import takes: below them no measuring set-up
 * exists, and the arithmetic (Σ x², 1/σ²) leaves the range of doubles. */
#define SC_GRID_MIN_PITCH_MM SC_STAGE_MAP_MIN_PITCH_MM
#define SC_GRID_MIN_SIGMA_UM 1e-6

typedef struct sc_grid_view {
    int rot_deg;                        /* 0, 90, 180 or 270, counter-clockwise */
    int shift_x, shift_y;               /* in pitches */
    int restricted;                     /* 1: only the rows/cols selected below are measured */
    unsigned char row_sel[SC_GRID_MAX_N]; /* plate rows measured (when restricted) */
    unsigned char col_sel[SC_GRID_MAX_N]; /* plate columns measured (when restricted) */
    double sigma_um;                    /* `sigma_um=` of the view line: standard uncertainty of
                                           each coordinate of its rows, µm; 0 = not stated */
    double temp_C;                      /* `temp_C=` of the view line (SPEC §11): the plate's
                                           temperature during the view, °C; read only when the
                                           plan's scale.has_temps */
} sc_grid_view;

/* The plate's scale and temperature (SPEC §11, optional header lines). The plate of view v is
 * the 20 °C plate scaled by s_v = E + A·(T_v − 20) ppm (sc_grid_view_scale_ppm). */
typedef struct sc_grid_scale {
    int has_plate_scale;        /* `# plate_scale_ppm = E, U` given: G carries the magnification */
    double plate_scale_ppm;     /* E: the plate's certified scale error at 20 °C, ppm */
    double u_plate_scale_ppm;   /* U: its standard uncertainty, ppm (>= 0) */
    int has_cte;                /* `# plate_cte_ppm_per_K = A, U` given */
    double cte_ppm_per_K;       /* A: the plate's linear expansion coefficient, ppm/K */
    double u_cte_ppm_per_K;     /* its standard uncertainty, ppm/K (>= 0) */
    int has_temps;              /* every view line carries temp_C= (needs has_cte) */
    double temp_u_K;            /* `# temp_u_K`: standard uncertainty of each temperature, K
                                   (SC_GRID_TEMP_U_K_DEFAULT when not given) */
} sc_grid_scale;

#define SC_GRID_TEMP_U_K_DEFAULT 0.05
#define SC_GRID_REF_TEMP_C 20.0
/* The ranges the files take: |E| and U to 1e4 ppm, |A| and its U to 1e3 ppm/K, temperatures
 * -100 to 200 °C, temp_u_K to 100 K. */
#define SC_GRID_MAX_SCALE_PPM 1e4
#define SC_GRID_MAX_CTE 1e3
#define SC_GRID_MIN_TEMP_C -100.0
#define SC_GRID_MAX_TEMP_C 200.0
#define SC_GRID_MAX_TEMP_U_K 100.0

typedef struct sc_grid_plan {
    int n;                /* marks per side (odd) */
    double pitch_mm;      /* P */
    double origin_mm[2];  /* stage position of the grid centre */
    int n_views;
    sc_grid_view *view;   /* n_views entries, owned by the plan (sc_grid_plan_views sizes them,
                             sc_grid_plan_copy copies them, sc_grid_plan_free frees them) */
    int stage_nx, stage_ny; /* stage grid (SPEC §5 `# stage = NX,NY`, odd >= 3); 0: N x N */
    sc_grid_scale scale;    /* plate scale and temperatures (SPEC §11); all 0: none given */
} sc_grid_plan;

/* Measurements: dev = measured - nominal stage position in µm for mark (i, j) of each view;
 * NaN where the mark was not measured. Arrays are n*n (plate marks), owned by whoever filled them.
 * ux/uy (SPEC §5 columns ux_um, uy_um): NULL when the file has no such columns, else the stated
 * standard uncertainty of each row's x and y (µm; NaN: the view's sigma_um applies).
 * t_s: NULL without the column t_s, else the time of each measurement (s).
 * The data own their plan (a deep copy: sc_grid_plan_copy) and the per-view tables below
 * (plan.n_views pointers each, made by sc_grid_data_views or sc_grid_data_alloc in grid_io.h;
 * sc_grid_data_free frees the plan, the tables and every array they point to). */
typedef struct sc_grid_data {
    sc_grid_plan plan;
    double **dx_um;
    double **dy_um;
    double **ux_um;
    double **uy_um;
    double **t_s;
} sc_grid_data;

/* What a method reports. The caller allocates every array it wants filled and sets the pointer
 * (G arrays: one per stage node, NX*NY = sc_grid_stage_nodes; A arrays: n*n; per-view arrays:
 * n_views each, all of them at once with sc_grid_result_views); a NULL array is skipped.
 * Uncertainties are NaN where the method gives none. */
typedef struct sc_grid_result {
    double *gx_um, *gy_um;    /* stage error at node (i, j), index i*NX + j */
    double *ugx_um, *ugy_um;  /* standard uncertainty (k = 1) of gx, gy */
    double *ax_um, *ay_um;    /* plate error of mark (i, j), plate frame; NaN where unmeasured */
    double O, R;              /* non-orthogonality and scale, dimensionless */
    double *tx_um, *ty_um;    /* per view misalignment (n_views each) */
    double *theta_urad;
    double residual_rms_um;   /* RMS of the measurement residuals (NaN if not defined) */
    double sigma_r_est_um;    /* noise estimated from the residuals (NaN if no redundancy) */
    double sigma_r_used_um;   /* the σ_r the uncertainties were computed with */
    long n_measurements;      /* scalar equations used (2 per measured mark) */
    long dof;                 /* residual degrees of freedom */
    /* least squares only (NaN otherwise): */
    double uO, uR;            /* standard uncertainties of O and R */
    double *utx_um, *uty_um, *utheta_urad; /* per view */
    int drift;                /* 1: per-view translation drift rates were estimated */
    int misalignment_unique;  /* 0: misalignments/drift rates are not determined by the data
                                 (e.g. a drift common to all views in the plate frame equals a
                                 plate error): values by convention, uncertainties NaN */
    double *vx_um_s, *vy_um_s;   /* per view drift rates, µm/s */
    double *uvx_um_s, *uvy_um_s; /* their uncertainties */
    int weighted;             /* 1: the data stated uncertainties (or σ_r was given) */
    double variance_factor;   /* weighted RSS / dof (σ̂²/σ² of the stated noise); NaN if not weighted */
    double chi2_lo, chi2_hi;  /* the 95 % acceptance interval of variance_factor (two-sided) */
    int chi2_pass;            /* 1 if variance_factor lies in it (or the test does not apply) */
    /* least squares' outlier test (sc_grid_calibrate; NaN and 0 where it was not run): */
    double outlier_alpha;     /* its significance, for the whole data set or (outlier_alpha_each)
                                 for each coordinate on its own */
    int outlier_alpha_each;   /* 1: outlier_alpha is each coordinate's (Baarda's α0) */
    double outlier_alpha_coord; /* each coordinate's own significance (the Šidák share) */
    double outlier_crit;      /* |t| beyond which a coordinate is flagged */
    long n_outlier_tests;     /* coordinates tested (finite t in the first solution) */
    /* each view's noise estimated (sc_grid_options.estimate_view_noise; 0 and NaN otherwise): */
    int view_noise_estimated; /* 1: the weights are the estimated ones */
    int view_noise_iterations; /* the re-weighted solves it took */
    double *view_sigma_um;     /* per view: RMS standard deviation of a coordinate of the
                                  view, as estimated */
    double *view_noise_factor; /* per view: the factor on the view's stated uncertainties (NaN
                                  if it stated none) */
    double *view_sigma_u_um;   /* per view: the standard uncertainty of view_sigma_um (REML's
                                  2F⁻¹, F by random probes; NaN if it could not be had) */
    int stated_u;             /* 1: the data stated their own uncertainties (ux_um,uy_um or
                                 sigma_um=): σ figures are factors on them, a given σ_r unused */
    double *view_block;       /* the one block sc_grid_result_views made for the per-view arrays
                                 (NULL if the caller set them itself) */
} sc_grid_result;

/* The number of per-view arrays of sc_grid_result (tx_um ... view_sigma_u_um). */
#define SC_GRID_RESULT_VIEW_ARRAYS 13

/* ---- run-time sized per-view storage (io/grid_plan.c; a result's: grid/grid_views.c) ---- */

/* Size p's views to n_views (1..SC_GRID_VIEW_LIMIT): the entries kept keep their content, new
 * ones are zero (rot 0, shift 0,0, not restricted, sigma_um not stated). p must be zeroed or
 * hold views of its own. SC_E_NOMEM, SC_E_INPUT (a count out of range); p unchanged then. */
SC_API sc_status sc_grid_plan_views(sc_grid_plan *p, int n_views, sc_error *err);

/* Deep copy of src into dst (dst's own views are freed first; dst may be zeroed). */
SC_API sc_status sc_grid_plan_copy(sc_grid_plan *dst, const sc_grid_plan *src, sc_error *err);

/* Free p's views (n_views = 0, view = NULL; the other fields kept; safe on a zeroed plan). */
SC_API void sc_grid_plan_free(sc_grid_plan *p);

/* Allocate every per-view array of res (SC_GRID_RESULT_VIEW_ARRAYS arrays of n_views doubles,
 * NaN-filled) in one block (res->view_block); sc_grid_result_free_views frees it. */
SC_API sc_status sc_grid_result_views(sc_grid_result *res, int n_views, sc_error *err);

/* Free the block of sc_grid_result_views and clear the per-view pointers (safe on a zeroed res). */
SC_API void sc_grid_result_free_views(sc_grid_result *res);

/* ---- geometry (io/grid_plan.c: the stage grid, where a view puts a mark, the plan's checks;
 * grid/grid_geometry.c: the forward model and the gauge) ---- */

/* Stage grid size along x (NX) and y (NY): the plan's stage_nx/ny, or N when they are 0. */
SC_API int sc_grid_stage_nx(const sc_grid_plan *p);
SC_API int sc_grid_stage_ny(const sc_grid_plan *p);

/* Number of stage nodes NX·NY. */
SC_API long sc_grid_stage_nodes(const sc_grid_plan *p);

/* True if the stage grid is the plate's N x N (what the closed-form methods need). */
SC_API bool sc_grid_stage_is_plate(const sc_grid_plan *p);

/* Plate-centred nominal position of mark (i, j) in mm: ((j-c)P, (i-c)P). */
SC_API void sc_grid_mark_xy_mm(const sc_grid_plan *p, int i, int j, double *x_mm, double *y_mm);

/* The stated standard uncertainty (µm) of coordinate c (0: x, 1: y) of mark k in view v: the
 * row's own ux/uy if finite, else the view's sigma_um if stated, else NaN (not stated). */
SC_API double sc_grid_data_u_um(const sc_grid_data *d, int v, long k, int c);

/* Stage node where mark (i, j) lands in view v: true and (*ni, *nj) if on the stage grid, else false. */
SC_API bool sc_grid_mark_node(const sc_grid_plan *p, int v, int i, int j, int *ni, int *nj);

/* True if view v measures mark (i, j): it lands on the grid and, if restricted, its row or column is selected. */
SC_API bool sc_grid_view_measures(const sc_grid_plan *p, int v, int i, int j);

/* Nominal stage node position relative to the stage grid centre, in mm: x = (j-cx)P, y = (i-cy)P. */
SC_API void sc_grid_node_xy_mm(const sc_grid_plan *p, int i, int j, double *x_mm, double *y_mm);

/* Nominal stage position of mark (i, j) in view v, relative to the stage grid centre (add the
 * plan's origin_mm for the machine's coordinates), mm: the node it lands on (sc_grid_mark_node)
 * at its sc_grid_node_xy_mm. False (nothing written) if it lands off the stage grid. */
SC_API bool sc_grid_mark_stage_xy_mm(const sc_grid_plan *p, int v, int i, int j, double *x_mm,
                                     double *y_mm);

/* Rotate a plate-frame vector (ax, ay) by rot_deg CCW into the stage frame. */
SC_API void sc_grid_rotate(int rot_deg, double ax, double ay, double *sx, double *sy);

/* Index of the first view with this rot and shift, or -1. */
SC_API int sc_grid_find_view(const sc_grid_plan *p, int rot_deg, int shift_x, int shift_y);

/* Whether u_um is a standard uncertainty a grid file, a plan or an import may state: 1e-6 µm
 * (SC_GRID_MIN_SIGMA_UM) to 1e6 µm (the readers' limit); false for NaN and infinities. */
SC_API bool sc_grid_sigma_valid(double u_um);

/* Check a plan's parameters (n odd, 3 <= n <= SC_GRID_MAX_N, 1 to SC_GRID_VIEW_LIMIT views, stage odd >= 3, pitch
 * SC_GRID_MIN_PITCH_MM to 1e6 mm, origin within 1e6 mm, each view's sigma_um 0 or valid,
 * rotations, shifts, every view landing at least one mark on the stage). */
SC_API sc_status sc_grid_plan_check(const sc_grid_plan *p, sc_error *err);

/* The plate's scale in view v, ppm relative to its nominal pitch: E (if given) + A·(T_v − 20)
 * (if temperatures are given); 0 when neither is. */
SC_API double sc_grid_view_scale_ppm(const sc_grid_plan *p, int v);

/* Forward model without noise: fill d->dx_um/dy_um (arrays provided by the caller) from a stage
 * error G (NX*NY nodes), plate error A (n*n marks, plate frame) and per-view misalignment. NaN
 * where a view does not measure a mark. */
SC_API void sc_grid_synthesize(const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                               const double *ax_um, const double *ay_um, const double *tx_um,
                               const double *ty_um, const double *theta_urad, sc_grid_data *d);

/* Remove translation, rotation and magnification from a stage map (NX*NY) in place (the SPEC gauge). */
SC_API void sc_grid_gauge_stage(const sc_grid_plan *p, double *gx_um, double *gy_um);

/* Remove translation and rotation from a plate error map in place. */
SC_API void sc_grid_gauge_plate(const sc_grid_plan *p, double *ax_um, double *ay_um);

/* O and R of a stage map (Petrò eqs. 4-5). */
SC_API void sc_grid_first_order(const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                                double *O, double *R);

#ifdef __cplusplus
}
#endif
#endif
