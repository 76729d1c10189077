/* The files of a grid result (SPEC §1 and §5): the stage error map and the plate error map (as
 * views on a result's arrays, written by the one writer of each format: stage_map.c,
 * plate_map.c), the JSON run summary of a result (a calibration's further figures are added by
 * grid/grid_summary.c through the hooks of grid_results_internal.h) and the residuals. The measurement file is grid_file.c's,
 * the .npy covariance npy.c's. */
#include "selfcal/grid_io.h"

#include <math.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/plate_map.h"
#include "selfcal/number.h"
#include "grid_results_internal.h"
#include "io_internal.h"

/* ---------------------------------------------------------------------------------------------
 * Writers
 * ------------------------------------------------------------------------------------------- */

static sc_status finish(sc_afile *f, sc_error *err)
{
    return sc_afile_commit(f, err); /* a write that failed: "write error: <reason>" */
}

sc_stage_map sc_grid_stage_map(const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                               const double *ugx_um, const double *ugy_um)
{
    sc_stage_map m;
    m.nx = sc_grid_stage_nx(p);
    m.ny = sc_grid_stage_ny(p);
    sc_grid_node_xy_mm(p, 0, 0, &m.x0_mm, &m.y0_mm);
    m.x0_mm += p->origin_mm[0];
    m.y0_mm += p->origin_mm[1];
    m.px_mm = m.py_mm = p->pitch_mm;
    /* a view: the arrays stay the caller's and are only read */
    m.gx_um = (double *)(uintptr_t)gx_um;
    m.gy_um = (double *)(uintptr_t)gy_um;
    m.ugx_um = (double *)(uintptr_t)ugx_um;
    m.ugy_um = (double *)(uintptr_t)ugy_um;
    return m;
}

void sc_grid_fprint_map(FILE *fp, const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                        const double *ugx_um, const double *ugy_um)
{
    sc_stage_map m = sc_grid_stage_map(p, gx_um, gy_um, ugx_um, ugy_um);
    sc_stage_map_fprint(fp, &m);
}

sc_status sc_grid_write_map(const char *path, const sc_grid_plan *p, const double *gx_um,
                            const double *gy_um, const double *ugx_um, const double *ugy_um,
                            sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_map(f.fp, p, gx_um, gy_um, ugx_um, ugy_um);
    return finish(&f, err);
}

void sc_grid_fprint_artifact(FILE *fp, const sc_grid_plan *p, const double *ax_um,
                             const double *ay_um)
{
    /* a view: the arrays stay the caller's and are only read */
    sc_plate_map m = {p->n, (double *)(uintptr_t)ax_um, (double *)(uintptr_t)ay_um};
    sc_plate_map_fprint(fp, &m);
}

sc_status sc_grid_write_artifact(const char *path, const sc_grid_plan *p, const double *ax_um,
                                 const double *ay_um, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_artifact(f.fp, p, ax_um, ay_um);
    return finish(&f, err);
}

void sc_io_json_num(FILE *fp, double v)
{
    if (isfinite(v))
        fprintf(fp, "%.15g", v);
    else
        fputs("null", fp);
}

void sc_io_json_kv(FILE *fp, const char *key, double v)
{
    fprintf(fp, ", \"%s\": ", key);
    sc_io_json_num(fp, v);
}

void sc_io_json_pair(FILE *fp, const char *key, int have, double a, double b)
{
    fprintf(fp, ",\n  \"%s\": ", key);
    if (!have) {
        fputs("null", fp);
        return;
    }
    fputc('[', fp);
    sc_io_json_num(fp, a);
    fputs(", ", fp);
    sc_io_json_num(fp, b);
    fputc(']', fp);
}

/* `,\n  "key": v` (the top-level members after the first). */
static void json_member(FILE *fp, const char *key, double v)
{
    fprintf(fp, ",\n  \"%s\": ", key);
    sc_io_json_num(fp, v);
}

/* The summary's opening: format, method, the plan's size and the gauge terms O and R. */
static void summary_head(FILE *fp, const char *method, const sc_grid_plan *p,
                         const sc_grid_result *res)
{
    fprintf(fp, "{\n  \"format\": \"selfcal-grid-summary v1\",\n  \"method\": \"%s\",\n", method);
    fprintf(fp, "  \"N\": %d,\n  \"pitch_mm\": %.15g,\n  \"origin_mm\": [%.15g, %.15g],\n", p->n,
            p->pitch_mm, p->origin_mm[0], p->origin_mm[1]);
    fprintf(fp, "  \"stage\": [%d, %d],\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    fputs("  \"O\": ", fp);
    sc_io_json_num(fp, res->O);
    json_member(fp, "uO", res->uO);
    json_member(fp, "R", res->R);
    json_member(fp, "uR", res->uR);
    /* the same with their units in the key (the dimensionless keys above: kept through 0.3) */
    json_member(fp, "O_urad", res->O * 1e6);
    json_member(fp, "uO_urad", res->uO * 1e6);
    json_member(fp, "R_ppm", res->R * 1e6);
    json_member(fp, "uR_ppm", res->uR * 1e6);
}

/* One view's object: its placement, misalignment, estimated noise, the caller's extra figures
 * (extra(fp, ctx, v), may be NULL) and its drift. */
static void summary_view(FILE *fp, const sc_grid_plan *p, const sc_grid_result *res,
                         const int *view_id, int v, sc_io_summary_view_fn extra, const void *ctx)
{
    const sc_grid_view *w = &p->view[v];
    fprintf(fp, "    {\"view\": %d, \"rot\": %d, \"shift\": [%d, %d]", view_id ? view_id[v] : v,
            w->rot_deg, w->shift_x, w->shift_y);
#define VIEW_VALUE(arr) (res->arr ? res->arr[v] : NAN) /* an array not given: null */
    sc_io_json_kv(fp, "tx_um", VIEW_VALUE(tx_um));
    sc_io_json_kv(fp, "ty_um", VIEW_VALUE(ty_um));
    sc_io_json_kv(fp, "theta_urad", VIEW_VALUE(theta_urad));
    sc_io_json_kv(fp, "utx_um", VIEW_VALUE(utx_um));
    sc_io_json_kv(fp, "uty_um", VIEW_VALUE(uty_um));
    sc_io_json_kv(fp, "utheta_urad", VIEW_VALUE(utheta_urad));
    if (res->view_noise_estimated) {
        sc_io_json_kv(fp, "sigma_um_est", VIEW_VALUE(view_sigma_um));
        sc_io_json_kv(fp, "u_sigma_um_est", VIEW_VALUE(view_sigma_u_um));
        sc_io_json_kv(fp, "noise_factor", VIEW_VALUE(view_noise_factor));
    }
    if (extra)
        extra(fp, ctx, p, v);
    if (res->drift) {
        sc_io_json_kv(fp, "vx_um_s", VIEW_VALUE(vx_um_s));
        sc_io_json_kv(fp, "vy_um_s", VIEW_VALUE(vy_um_s));
        sc_io_json_kv(fp, "uvx_um_s", VIEW_VALUE(uvx_um_s));
        sc_io_json_kv(fp, "uvy_um_s", VIEW_VALUE(uvy_um_s));
    }
#undef VIEW_VALUE
    fprintf(fp, "}%s\n", v + 1 < p->n_views ? "," : "");
}

/* The fit's figures: residuals, noise, the χ² test, drift and the outlier test. */
static void summary_fit(FILE *fp, const sc_grid_result *res)
{
    fputs("  ],\n  \"residual_rms_um\": ", fp);
    sc_io_json_num(fp, res->residual_rms_um);
    json_member(fp, "sigma_r_est_um", res->sigma_r_est_um);
    json_member(fp, "sigma_r_used_um", res->sigma_r_used_um);
    fprintf(fp, ",\n  \"weighted\": %s,\n  \"stated_uncertainties\": %s,\n  \"variance_factor\": ",
            res->weighted ? "true" : "false", res->stated_u ? "true" : "false");
    sc_io_json_num(fp, res->variance_factor);
    fputs(",\n  \"chi2_95_interval\": [", fp);
    sc_io_json_num(fp, res->chi2_lo);
    fputs(", ", fp);
    sc_io_json_num(fp, res->chi2_hi);
    fprintf(fp, "],\n  \"chi2_test\": \"%s\",\n  \"drift\": \"%s\"",
            !isfinite(res->variance_factor) || !isfinite(res->chi2_lo) ? "n/a"
            : res->chi2_pass                                          ? "pass"
                                                                      : "fail",
            res->drift ? "linear" : "none");
    if (isfinite(res->outlier_crit) && res->outlier_crit > 0) { /* the least squares' test ran */
        fprintf(fp, ",\n  \"outlier_test\": {\"alpha\": %.6g, \"for\": \"%s\", ",
                res->outlier_alpha, res->outlier_alpha_each ? "each coordinate" : "data set");
        fputs("\"alpha_coordinate\": ", fp);
        sc_io_json_num(fp, res->outlier_alpha_coord);
        fputs(", \"critical_t\": ", fp);
        sc_io_json_num(fp, res->outlier_crit);
        fprintf(fp, ", \"coordinates_tested\": %ld}", res->n_outlier_tests);
    }
}

void sc_io_grid_summary_body(FILE *fp, const char *method, const sc_grid_plan *p,
                             const sc_grid_result *res, const int *view_id,
                             sc_io_summary_view_fn extra, const void *ctx)
{
    summary_head(fp, method, p, res);
    fputs(",\n  \"views\": [\n", fp);
    for (int v = 0; v < p->n_views; ++v)
        summary_view(fp, p, res, view_id, v, extra, ctx);
    summary_fit(fp, res);
    fprintf(fp, ",\n  \"view_noise\": \"%s\"", res->view_noise_estimated ? "estimated" : "stated");
    fprintf(fp, ",\n  \"misalignment_unique\": %s", res->misalignment_unique ? "true" : "false");
    fprintf(fp, ",\n  \"n_measurements\": %ld,\n  \"dof\": %ld", res->n_measurements, res->dof);
}

void sc_grid_fprint_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                            const sc_grid_result *res)
{
    sc_io_grid_summary_body(fp, method, p, res, NULL, NULL, NULL);
    fputs("\n}\n", fp);
}

sc_status sc_grid_write_summary(const char *path, const char *method, const sc_grid_plan *p,
                                const sc_grid_result *res, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_summary(f.fp, method, p, res);
    return finish(&f, err);
}

/* ---------------------------------------------------------------------------------------------
 * Residuals (SPEC §5)
 * ------------------------------------------------------------------------------------------- */

void sc_grid_fprint_residuals(FILE *fp, const sc_grid_plan *p, const int *view_id,
                              const double *rx_um, const double *ry_um, const double *tx,
                              const double *ty, const unsigned char *outlier)
{
    int n = p->n;
    size_t nn = (size_t)n * n;
    fputs("view,i,j,rx_um,ry_um,tx,ty,outlier\n", fp);
    char line[8 * SC_NUMBER_BUF];
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k) {
            size_t at = (size_t)v * nn + k;
            /* a row: a measurement with a residual, or one removed as an outlier whose residual
             * is not estimable (its view's misalignment undetermined without it): empty fields */
            if (!isfinite(rx_um[at]) && !(outlier && outlier[at]))
                continue;
            char *q = sc_io_put_long(line, view_id ? view_id[v] : v, ',');
            q = sc_io_put_long(q, (long)(k / n), ',');
            q = sc_io_put_long(q, (long)(k % n), ',');
            q = sc_io_put_15g_opt(q, rx_um, at, ',');
            q = sc_io_put_15g_opt(q, ry_um, at, ',');
            q = sc_io_put_15g_opt(q, tx, at, ',');
            q = sc_io_put_15g_opt(q, ty, at, ',');
            q = sc_io_put_long(q, outlier && outlier[at] ? 1 : 0, '\n');
            fwrite(line, 1, (size_t)(q - line), fp);
        }
}

