/* selfcal/grid_sim.h — simulated grid-plate measurements after Petrò (2019) §5.
 *
 * Truth, all in the SPEC gauge:
 *   G = first-order part (Gx = O·y + R·x, Gy = O·x − R·y; x, y in µm from the grid centre)
 *       + s·F, with F a SAR(1) field per component: F = ρ·W·F + ε, ε white N(0, 1),
 *       W the first-order (4-neighbour) adjacency matrix ROW-STANDARDISED (each row sums to 1, so
 *       an edge node's 3 neighbours weigh 1/3 each). With W row-standardised, I − ρW is invertible
 *       for |ρ| < 1 (Petrò's ρ = 0.9 with a plain 0/1 matrix, spectral radius ~4, is not a valid
 *       SAR model). F is solved to machine precision (Gauss-Seidel), then its translation, rotation,
 *       magnification, O and R components are removed, and s is chosen so that the sample standard
 *       deviation of all 2N² values of Gx and Gy (first-order part included) is σ_G.
 *   A: independent Gaussian N(0, σ_A²) per mark and component, then gauged (no translation/rotation).
 *   Per view: tx, ty ~ N(0, σ_t²), θ ~ N(0, σ_θ²).
 *   Measured dev = forward model (sc_grid_synthesize) + N(0, σ_r²) per measured coordinate.
 * Random draws, from one sc_rng seeded with `seed`, in this order: ε_x (N² values, row-major),
 * ε_y, A_x, A_y, then per view (tx, ty, θ), then per view, per measured mark in row-major order,
 * (noise x, noise y). Same seed, plan and parameters: the same numbers on every platform.
 * Stage grids larger than the plate (SPEC §5): G lives on the NX x NY stage nodes. With dt_s > 0
 * every measurement gets a time (serpentine plate order within a view, one raster position per
 * dt_s, views in sequence) and a
 * translation drift (vx, vy)·(t − start of its view) is added.
 */
#ifndef SELFCAL_GRID_SIM_H
#define SELFCAL_GRID_SIM_H

#include <stddef.h>
#include <stdint.h>

#include "selfcal/api.h"
#include "selfcal/grid.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_grid_sim_params {
    double sigma_g_um;       /* total dispersion of G (sample std of all Gx, Gy values), µm */
    double rho;              /* SAR(1) correlation coefficient, |rho| < 1 (Petrò: 0.9) */
    double O, R;             /* non-orthogonality and scale, dimensionless (µm per µm) */
    double sigma_a_um;       /* plate error std per component, µm */
    double sigma_t_um;       /* misalignment translation std, µm (Petrò: 0.1) */
    double sigma_theta_urad; /* misalignment rotation std, µrad (Petrò: 100) */
    double sigma_r_um;       /* measurement noise std per coordinate, µm (a view whose plan
                                states sigma_um gets that instead: each view its own noise) */
    uint64_t seed;
    double dt_s;             /* > 0: time between measurements (s); d->t_s must be allocated */
    double drift_vx_um_s, drift_vy_um_s; /* translation drift during each view, µm/s (dt_s > 0) */
} sc_grid_sim_params;

/* The truth of a simulation. Arrays (G: NX*NY stage nodes, A: n*n marks, misalignments: one per
 * view) are the caller's, all of them required. */
typedef struct sc_grid_sim_truth {
    double *gx_um, *gy_um;  /* stage error at each node, SPEC gauge */
    double *ax_um, *ay_um;  /* plate error at each mark, plate frame, SPEC gauge */
    double O, R;            /* first-order terms of G (as requested) */
    double *tx_um, *ty_um, *theta_urad; /* per view misalignment (n_views each) */
    double sar_scale;       /* s: the factor applied to the unit-variance SAR field */
    int sar_iterations;     /* Gauss-Seidel sweeps used */
} sc_grid_sim_truth;

/* Petrò's values: σ_G 1 µm, ρ 0.9, O = R = 1e-5, σ_A 1 µm, σ_t 0.1 µm, σ_θ 100 µrad,
 * σ_r 0.01 µm, seed 1. */
SC_API void sc_grid_sim_defaults(sc_grid_sim_params *sp);

/* Position of mark k (i*n + j) in serpentine measuring order: row i left to right when i is even,
 * right to left when odd (the order the simulator and the drift plan analysis assume). */
SC_API long sc_grid_serpentine_index(int n, int k);

/* Workspace needed by sc_grid_sim_run for plate size n on an N x N stage (no `stage` larger than
 * the plate: use sc_grid_sim_work_doubles_plan for those), in doubles. */
SC_API size_t sc_grid_sim_work_doubles(int n);

/* Workspace needed by sc_grid_sim_run for a plan (any stage), in doubles. */
SC_API size_t sc_grid_sim_work_doubles_plan(const sc_grid_plan *p);

/* The standard plans: Ye {rot 0}, {rot 90}, {shift +1,0}; double shift {rot 0}, {rot 90},
 * {shift +2,0}, {shift -3,0 rows=c cols=c,c+1}. SC_E_INPUT if n is not valid for the plan. */
SC_API sc_status sc_grid_plan_ye(int n, double pitch_mm, double origin_x_mm, double origin_y_mm,
                                 sc_grid_plan *p, sc_error *err);
SC_API sc_status sc_grid_plan_double_shift(int n, double pitch_mm, double origin_x_mm,
                                           double origin_y_mm, sc_grid_plan *p, sc_error *err);

/* Stitching plan for an NX x NY stage and an N x N plate: rot-0 placements on a raster covering
 * the stage (plate centres at most `step` pitches apart, evenly spread), then a rot-90 and a
 * shift +1,0 placement at the centre. sc_grid_plan_stitch uses step (N-1)/2. SC_E_INPUT if
 * more than SC_GRID_VIEW_LIMIT views would be needed.
 * The plan makers overwrite *p (views it held are not freed) and give it views of its own
 * (sc_grid_plan_free), none when they fail. */
SC_API sc_status sc_grid_plan_stitch_step(int n, int nx, int ny, int step, double pitch_mm, double ox,
                                          double oy, sc_grid_plan *p, sc_error *err);
SC_API sc_status sc_grid_plan_stitch(int n, int nx, int ny, double pitch_mm, double ox, double oy,
                                     sc_grid_plan *p, sc_error *err);

/* Simulate: fill truth and d (d->plan must be a copy of *plan, or plan be &d->plan, and d's
 * arrays be allocated, e.g. with sc_grid_data_alloc). work: sc_grid_sim_work_doubles_plan(plan) doubles.
 * SC_E_INPUT for invalid parameters (|ρ| >= 1, negative σ, or σ_G too small to hold the
 * requested O and R). */
SC_API sc_status sc_grid_sim_run(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                                 sc_grid_sim_truth *truth, sc_grid_data *d, double *work, sc_error *err);

/* The plate's scale and temperature and the stage's magnification (SPEC §11) added to a
 * simulation made by sc_grid_sim_run on the same plan: each view's data get
 * M·1e-3·(x, y) (the stage's magnification M ppm at the node) and (s_v − a)·1e-3·Rot_v(p) (the
 * plate of view v scaled by s_v = sc_grid_view_scale_ppm), where a is the magnification of the
 * simulated plate error, which is taken out of it (with plate_scale_ppm the certificate states the
 * plate's whole scale). With plate_scale_ppm the truth's G gets M·1e-3·(x, y) (G's gauge keeps
 * the magnification), else G stays in the SPEC gauge and A as simulated. Noise-free in itself. */
SC_API void sc_grid_sim_scale(const sc_grid_plan *plan, double magnification_ppm,
                              sc_grid_sim_truth *truth, sc_grid_data *d);

#ifdef __cplusplus
}
#endif
#endif
