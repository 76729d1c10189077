/* Simulated grid-plate measurements after Petrò (2019) §5 (see selfcal/grid_sim.h). */
#include "selfcal/grid_exact.h"
#include "selfcal/grid_sim.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h" /* SC_INPUT_MAX_ABS: the readers' limit */
#include "selfcal/rng.h"

void sc_grid_sim_defaults(sc_grid_sim_params *sp)
{
    sp->sigma_g_um = 1.0;
    sp->rho = 0.9;
    sp->O = 1e-5;
    sp->R = 1e-5;
    sp->sigma_a_um = 1.0;
    sp->sigma_t_um = 0.1;
    sp->sigma_theta_urad = 100.0;
    sp->sigma_r_um = 0.01;
    sp->seed = 1;
    sp->drift_vx_um_s = sp->drift_vy_um_s = 0;
    sp->dt_s = 0;
}

long sc_grid_serpentine_index(int n, int k)
{
    int i = k / n, j = k % n;
    return (long)i * n + (i % 2 ? n - 1 - j : j);
}

size_t sc_grid_sim_work_doubles(int n) { return 2 * (size_t)n * (size_t)n; }

size_t sc_grid_sim_work_doubles_plan(const sc_grid_plan *p)
{
    size_t a = 2 * (size_t)p->n * (size_t)p->n, b = 2 * (size_t)sc_grid_stage_nodes(p);
    return a > b ? a : b;
}

/* Finish a plan made here: its check, and no views kept when it fails. */
static sc_status plan_done(sc_grid_plan *p, sc_error *err)
{
    sc_status st = sc_grid_plan_check(p, err);
    if (st != SC_OK)
        sc_grid_plan_free(p);
    return st;
}

/* The plan's geometry; pitch and origin are judged by sc_grid_plan_check, which every plan made
 * here ends with (the views' layout below uses neither). */
static void plan_base(int n, double pitch_mm, double ox, double oy, sc_grid_plan *p)
{
    memset(p, 0, sizeof *p);
    p->n = n;
    p->pitch_mm = pitch_mm;
    p->origin_mm[0] = ox;
    p->origin_mm[1] = oy;
}

/* The plan of an exact method, from the views the method states it needs (grid_exact.c). */
static sc_status plan_exact(sc_grid_exact_method m, int n, double pitch_mm, double ox, double oy,
                            sc_grid_plan *p, sc_error *err)
{
    plan_base(n, pitch_mm, ox, oy, p);
    if (n < sc_grid_exact_min_n(m) || n > SC_GRID_MAX_N || n % 2 == 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "%s needs N odd and >= %d (got %d)",
                            m == SC_GRID_YE ? "Ye's method" : "double shift",
                            sc_grid_exact_min_n(m), n);
    sc_grid_view_need need[4];
    int c = (n - 1) / 2;
    sc_status st = sc_grid_plan_views(p, sc_grid_exact_needs(m, need), err);
    if (st != SC_OK)
        return st;
    for (int v = 0; v < p->n_views; ++v) {
        sc_grid_view *w = &p->view[v];
        w->rot_deg = need[v].rot_deg;
        w->shift_x = need[v].shift_x;
        w->shift_y = need[v].shift_y;
        w->restricted = need[v].partial;
        if (need[v].partial)
            w->row_sel[c] = w->col_sel[c] = w->col_sel[c + 1] = 1;
    }
    return plan_done(p, err);
}

sc_status sc_grid_plan_ye(int n, double pitch_mm, double ox, double oy, sc_grid_plan *p,
                          sc_error *err)
{
    return plan_exact(SC_GRID_YE, n, pitch_mm, ox, oy, p, err);
}

sc_status sc_grid_plan_double_shift(int n, double pitch_mm, double ox, double oy,
                                    sc_grid_plan *p, sc_error *err)
{
    return plan_exact(SC_GRID_DOUBLE_SHIFT, n, pitch_mm, ox, oy, p, err);
}

/* Number of placements along one axis (stitch_offset). */
static long stitch_count(int ns, int n, int step)
{
    long reach = (ns - 1) / 2 - (n - 1) / 2;
    return reach <= 0 ? 1 : (2 * reach + step - 1) / step + 1;
}

/* Placement t of k along one axis: the plate centre's offset from the stage centre, in pitches,
 * evenly spaced at most `step` apart from -(cs - c) to cs - c (just 0 when the plate covers it). */
static int stitch_offset(int ns, int n, long k, long t)
{
    int reach = (ns - 1) / 2 - (n - 1) / 2;
    return k <= 1 ? 0 : -reach + (int)lround((double)t * 2 * reach / (double)(k - 1));
}

sc_status sc_grid_plan_stitch_step(int n, int nx, int ny, int step, double pitch_mm, double ox,
                                   double oy, sc_grid_plan *p, sc_error *err)
{
    plan_base(n, pitch_mm, ox, oy, p);
    p->stage_nx = nx;
    p->stage_ny = ny;
    if (n < 3 || n % 2 == 0 || nx < 3 || ny < 3 || nx % 2 == 0 || ny % 2 == 0 || step < 1)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "stitching needs N, NX, NY odd and >= 3 and a step >= 1");
    long kx = stitch_count(nx, n, step), ky = stitch_count(ny, n, step);
    if (kx * ky + 2 > SC_GRID_VIEW_LIMIT)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "a %dx%d stage needs %ld placements of an N = %d plate at step %d, "
                            "more than %d",
                            nx, ny, kx * ky + 2, n, step, SC_GRID_VIEW_LIMIT);
    sc_status st = sc_grid_plan_views(p, (int)(kx * ky + 2), err);
    if (st != SC_OK)
        return st;
    int v = 0;
    for (long a = 0; a < ky; ++a)
        for (long b = 0; b < kx; ++b) {
            sc_grid_view *w = &p->view[v++];
            w->shift_x = stitch_offset(nx, n, kx, b);
            w->shift_y = stitch_offset(ny, n, ky, a);
        }
    p->view[v++].rot_deg = 90;
    p->view[v++].shift_x = 1;
    return plan_done(p, err);
}

sc_status sc_grid_plan_stitch(int n, int nx, int ny, double pitch_mm, double ox, double oy,
                              sc_grid_plan *p, sc_error *err)
{
    int step = (n - 1) / 2 > 0 ? (n - 1) / 2 : 1;
    return sc_grid_plan_stitch_step(n, nx, ny, step, pitch_mm, ox, oy, p, err);
}

/* Solve (I − ρW) f = e in place (f holds e on entry) by Gauss-Seidel, W row-standardised
 * 4-neighbour adjacency. Returns the sweeps used, or -1 if it did not converge. */
static int sar_solve(int nx, int ny, double rho, const double *e, double *f)
{
    size_t nn = (size_t)nx * ny;
    memcpy(f, e, nn * sizeof *f);
    for (int sweep = 1; sweep <= 100000; ++sweep) {
        double change = 0, size = 0;
        for (int i = 0; i < ny; ++i)
            for (int j = 0; j < nx; ++j) {
                double s = 0;
                int deg = 0;
                if (i > 0) s += f[(i - 1) * nx + j], ++deg;
                if (i < ny - 1) s += f[(i + 1) * nx + j], ++deg;
                if (j > 0) s += f[i * nx + j - 1], ++deg;
                if (j < nx - 1) s += f[i * nx + j + 1], ++deg;
                int k = i * nx + j;
                double nv = e[k] + rho * s / deg;
                change = fmax(change, fabs(nv - f[k]));
                size = fmax(size, fabs(nv));
                f[k] = nv;
            }
        if (change <= 1e-15 * size || size == 0)
            return sweep;
    }
    return -1;
}

/* Times and drift: each view measured mark by mark in serpentine plate order (row 0 left to
 * right, row 1 right to left, ...), one raster position every dt seconds, the views one after
 * another; translation drift (vx, vy)·t with t from the view's start. */
static sc_status add_times_and_drift(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                                     sc_grid_data *d, sc_error *err)
{
    int n = plan->n;
    size_t nn = (size_t)n * n;
    double t0 = 0;
    for (int v = 0; v < plan->n_views; ++v) {
        if (!d->t_s[v])
            return sc_error_set(err, SC_E_INPUT, NULL, 0, "t_s arrays are needed for dt > 0");
        for (size_t k = 0; k < nn; ++k) {
            d->t_s[v][k] = NAN;
            if (!isfinite(d->dx_um[v][k]))
                continue;
            double tv = (double)sc_grid_serpentine_index(n, (int)k) * sp->dt_s;
            d->t_s[v][k] = t0 + tv;
            d->dx_um[v][k] += sp->drift_vx_um_s * tv;
            d->dy_um[v][k] += sp->drift_vy_um_s * tv;
        }
        t0 += (double)nn * sp->dt_s; /* the next view starts after this one's raster */
    }
    return SC_OK;
}

static sc_status check_params(const sc_grid_sim_params *sp, sc_error *err)
{
    if (!(fabs(sp->rho) < 1))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "SAR rho must be in (-1, 1) (got %g)",
                            sp->rho);
    if (!(sp->sigma_g_um >= 0) || !(sp->sigma_a_um >= 0) || !(sp->sigma_t_um >= 0) ||
        !(sp->sigma_theta_urad >= 0) || !(sp->sigma_r_um >= 0) || !isfinite(sp->sigma_g_um) ||
        !isfinite(sp->sigma_a_um) || !isfinite(sp->sigma_t_um) ||
        !isfinite(sp->sigma_theta_urad) || !isfinite(sp->sigma_r_um))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "standard deviations must be finite and >= 0");
    /* the readers' limits: what a simulation writes must read back (errors within 1 m, SC_INPUT_MAX_ABS µm) */
    if (sp->sigma_g_um > SC_INPUT_MAX_ABS || sp->sigma_a_um > SC_INPUT_MAX_ABS ||
        sp->sigma_t_um > SC_INPUT_MAX_ABS || sp->sigma_r_um > SC_INPUT_MAX_ABS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "standard deviations in um must be at most %g (1 m)", SC_INPUT_MAX_ABS);
    if (sp->sigma_theta_urad > 1e6)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "sigma_theta = %g urad is beyond a plate's placement (at most 1 rad)",
                            sp->sigma_theta_urad);
    if (!(fabs(sp->O) <= 0.1) || !(fabs(sp->R) <= 0.1))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "O and R must be finite and within +-0.1 (100 mm/m), got %g, %g",
                            sp->O, sp->R);
    if (!isfinite(sp->drift_vx_um_s) || !isfinite(sp->drift_vy_um_s) || !(sp->dt_s >= 0) ||
        !isfinite(sp->dt_s))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "drift rates and dt must be finite");
    return SC_OK;
}

/* The second-order part of G: SAR(1) fields over the stage nodes from unit white noise (drawn
 * into work: 2·NX·NY doubles), gauged, with its own O and R components removed. */
static sc_status stage_sar_fields(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                                  sc_rng *rng, double *work, sc_grid_sim_truth *truth,
                                  sc_error *err)
{
    int snx = sc_grid_stage_nx(plan), sny = sc_grid_stage_ny(plan);
    size_t ns = (size_t)snx * sny;
    double *ex = work, *ey = work + ns;
    for (size_t k = 0; k < ns; ++k)
        ex[k] = sc_rng_normal(rng);
    for (size_t k = 0; k < ns; ++k)
        ey[k] = sc_rng_normal(rng);
    int it1 = sar_solve(snx, sny, sp->rho, ex, truth->gx_um);
    int it2 = sar_solve(snx, sny, sp->rho, ey, truth->gy_um);
    if (it1 < 0 || it2 < 0)
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "SAR(1) solve did not converge");
    truth->sar_iterations = it1 > it2 ? it1 : it2;
    sc_grid_gauge_stage(plan, truth->gx_um, truth->gy_um);
    return SC_OK;
}

/* Σ over the stage nodes of |first-order terms of O, R|² (µm²), and the sum of squares that
 * gives G the dispersion sigma_G; refused when the first exceeds the second (before the SAR
 * fields, whose solve takes a minute on the largest stages). */
static sc_status first_order_budget(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                                    double *first2, double *target2, sc_error *err)
{
    int snx = sc_grid_stage_nx(plan), sny = sc_grid_stage_ny(plan);
    size_t ns = (size_t)snx * sny;
    *first2 = 0;
    for (int i = 0; i < sny; ++i)
        for (int j = 0; j < snx; ++j) {
            double x, y;
            sc_grid_node_xy_mm(plan, i, j, &x, &y);
            double gx1 = (sp->O * y + sp->R * x) * 1e3, gy1 = (sp->O * x - sp->R * y) * 1e3;
            *first2 += gx1 * gx1 + gy1 * gy1;
        }
    /* All parts have zero mean, so the sample variance of the 2N² values is sum of squares / (2N²−1). */
    *target2 = sp->sigma_g_um * sp->sigma_g_um * (double)(2 * ns - 1);
    if (*first2 > *target2 * (1 + 1e-12))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "sigma_G = %g um is smaller than the dispersion of the first-order "
                            "terms alone (%g um for O = %g, R = %g): raise sigma_G or lower O, R",
                            sp->sigma_g_um, sqrt(*first2 / (double)(2 * ns - 1)), sp->O, sp->R);
    return SC_OK;
}

/* G = s·F + the first-order terms of O and R, with the scale s that gives G the dispersion
 * sigma_G (first2, target2: first_order_budget's sums); F is the SAR part (stage_sar_fields).
 * The O and R patterns (y, x) and (x, -y) are taken out of F first (orthogonal to the gauge). */
static void stage_scale_and_first_order(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                                        double first2, double target2, sc_grid_sim_truth *truth)
{
    int snx = sc_grid_stage_nx(plan), sny = sc_grid_stage_ny(plan);
    double *fx = truth->gx_um, *fy = truth->gy_um;
    double O_f, R_f, f2 = 0;
    sc_grid_first_order(plan, fx, fy, &O_f, &R_f); /* dimensionless; x, y in mm -> ×1e3 µm */
    for (int i = 0; i < sny; ++i)
        for (int j = 0; j < snx; ++j) {
            double x, y;
            sc_grid_node_xy_mm(plan, i, j, &x, &y);
            int k = i * snx + j;
            fx[k] -= (O_f * y + R_f * x) * 1e3;
            fy[k] -= (O_f * x - R_f * y) * 1e3;
            f2 += fx[k] * fx[k] + fy[k] * fy[k];
        }
    double s = f2 > 0 ? sqrt(fmax(0.0, target2 - first2) / f2) : 0.0;
    truth->sar_scale = s;
    for (int i = 0; i < sny; ++i)
        for (int j = 0; j < snx; ++j) {
            double x, y;
            sc_grid_node_xy_mm(plan, i, j, &x, &y);
            int k = i * snx + j;
            fx[k] = s * fx[k] + (sp->O * y + sp->R * x) * 1e3;
            fy[k] = s * fy[k] + (sp->O * x - sp->R * y) * 1e3;
        }
    /* On a rectangular stage the O and R patterns are not orthogonal to rotation and
     * magnification: gauge again and report O and R of the gauged truth (a no-op when square). */
    sc_grid_gauge_stage(plan, fx, fy);
    sc_grid_first_order(plan, fx, fy, &truth->O, &truth->R);
}

/* Plate error A (gauged) and the views' misalignments, drawn in that order. */
static void plate_and_misalignment(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                                   sc_rng *rng, sc_grid_sim_truth *truth)
{
    size_t nn = (size_t)plan->n * plan->n;
    for (size_t k = 0; k < nn; ++k)
        truth->ax_um[k] = sp->sigma_a_um * sc_rng_normal(rng);
    for (size_t k = 0; k < nn; ++k)
        truth->ay_um[k] = sp->sigma_a_um * sc_rng_normal(rng);
    sc_grid_gauge_plate(plan, truth->ax_um, truth->ay_um);
    for (int v = 0; v < plan->n_views; ++v) {
        truth->tx_um[v] = sp->sigma_t_um * sc_rng_normal(rng);
        truth->ty_um[v] = sp->sigma_t_um * sc_rng_normal(rng);
        truth->theta_urad[v] = sp->sigma_theta_urad * sc_rng_normal(rng);
    }
}

/* The measurements of the truth, with each view's reading noise. */
static void measure(const sc_grid_plan *plan, const sc_grid_sim_params *sp, sc_rng *rng,
                    const sc_grid_sim_truth *truth, sc_grid_data *d)
{
    size_t nn = (size_t)plan->n * plan->n;
    sc_grid_synthesize(plan, truth->gx_um, truth->gy_um, truth->ax_um, truth->ay_um, truth->tx_um,
                       truth->ty_um, truth->theta_urad, d);
    for (int v = 0; v < plan->n_views; ++v) {
        double sr = plan->view[v].sigma_um > 0 ? plan->view[v].sigma_um : sp->sigma_r_um;
        for (size_t k = 0; k < nn; ++k) {
            if (!isfinite(d->dx_um[v][k]))
                continue;
            d->dx_um[v][k] += sr * sc_rng_normal(rng);
            d->dy_um[v][k] += sr * sc_rng_normal(rng);
        }
    }
}

sc_status sc_grid_sim_run(const sc_grid_plan *plan, const sc_grid_sim_params *sp,
                          sc_grid_sim_truth *truth, sc_grid_data *d, double *work, sc_error *err)
{
    if (!truth->gx_um || !truth->gy_um || !truth->ax_um || !truth->ay_um || !truth->tx_um ||
        !truth->ty_um || !truth->theta_urad || !work)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the truth's gx_um, gy_um, ax_um, ay_um, tx_um, ty_um, theta_urad "
                            "and the workspace are required");
    if (!d->dx_um || d->plan.n_views != plan->n_views || d->plan.n != plan->n)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the data's plan and arrays must be the plan's (sc_grid_data_alloc)");
    sc_status st = sc_grid_plan_check(plan, err);
    if (st == SC_OK)
        st = check_params(sp, err);
    double first2, target2;
    if (st == SC_OK)
        st = first_order_budget(plan, sp, &first2, &target2, err);
    if (st != SC_OK)
        return st;
    sc_rng rng;
    sc_rng_seed(&rng, sp->seed);
    if ((st = stage_sar_fields(plan, sp, &rng, work, truth, err)) != SC_OK)
        return st;
    stage_scale_and_first_order(plan, sp, first2, target2, truth);
    plate_and_misalignment(plan, sp, &rng, truth);
    measure(plan, sp, &rng, truth, d);
    return sp->dt_s > 0 ? add_times_and_drift(plan, sp, d, err) : SC_OK;
}
