/* Writing the grid files of SPEC §1 and §5 (selfcal-grid v1 input/plan, map, artifact, summary,
 * residuals, .npy covariance) and the measurement arrays; the reader of selfcal-grid v1 is
 * io/grid_read.c. */
#include "selfcal/grid_io.h"
#include "selfcal/grid_calibrate.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/plate_map.h"
#include "selfcal/number.h"
#include "../io/io_internal.h"

#define COLUMN_HEADER "view,i,j,x_mm,y_mm"

static void data_free_arrays(sc_grid_data *d);

sc_status sc_grid_data_alloc(sc_grid_data *d, sc_error *err)
{
    size_t nn = (size_t)d->plan.n * (size_t)d->plan.n;
    d->dx_um = NULL; /* whatever it held is not d's (a fresh d) */
    sc_status st = sc_grid_data_views(d, err);
    if (st != SC_OK)
        return st;
    for (int v = 0; v < d->plan.n_views; ++v) {
        d->dx_um[v] = malloc(nn * sizeof(double));
        d->dy_um[v] = malloc(nn * sizeof(double));
        if (!d->dx_um[v] || !d->dy_um[v]) {
            data_free_arrays(d);
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data, N = %d)",
                                d->plan.n);
        }
        for (size_t k = 0; k < nn; ++k)
            d->dx_um[v][k] = d->dy_um[v][k] = NAN;
    }
    return SC_OK;
}

sc_status sc_grid_data_alloc_extra(sc_grid_data *d, int weights, int times, sc_error *err)
{
    size_t nn = (size_t)d->plan.n * (size_t)d->plan.n;
    sc_status st = sc_grid_data_views(d, err);
    if (st != SC_OK)
        return st;
    for (int v = 0; v < d->plan.n_views; ++v) {
        double **a[3] = {&d->ux_um[v], &d->uy_um[v], &d->t_s[v]};
        for (int t = 0; t < 3; ++t) {
            if ((t < 2 && !weights) || (t == 2 && !times) || *a[t])
                continue;
            *a[t] = malloc(nn * sizeof(double));
            if (!*a[t])
                return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data)");
            for (size_t k = 0; k < nn; ++k)
                (*a[t])[k] = NAN;
        }
    }
    return SC_OK;
}

/* Free d's arrays and per-view tables, not its plan. */
static void data_free_arrays(sc_grid_data *d)
{
    if (d->dx_um)
        for (int v = 0; v < d->plan.n_views; ++v) {
            free(d->dx_um[v]);
            free(d->dy_um[v]);
            free(d->ux_um[v]);
            free(d->uy_um[v]);
            free(d->t_s[v]);
        }
    free(d->dx_um); /* the one block of the five tables */
    d->dx_um = d->dy_um = d->ux_um = d->uy_um = d->t_s = NULL;
}

void sc_grid_data_free(sc_grid_data *d)
{
    data_free_arrays(d);
    sc_grid_plan_free(&d->plan);
}

void sc_grid_file_info_free(sc_grid_file_info *info)
{
    if (!info)
        return;
    free(info->view_line), free(info->view_id), free(info->view_rows);
    info->view_line = NULL, info->view_id = NULL, info->view_rows = NULL;
}

/* ---------------------------------------------------------------------------------------------
 * Writers
 * ------------------------------------------------------------------------------------------- */

void sc_grid_write_header(FILE *fp, const sc_grid_plan *p)
{
    fprintf(fp, "# selfcal-grid v1\n# N = %d\n# pitch_mm = %.15g\n", p->n, p->pitch_mm);
    fprintf(fp, "# origin_mm = %.15g,%.15g\n", p->origin_mm[0], p->origin_mm[1]);
    if (p->stage_nx > 0 || p->stage_ny > 0)
        fprintf(fp, "# stage = %d,%d\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    const sc_grid_scale *sc = &p->scale;
    if (sc->has_plate_scale)
        fprintf(fp, "# plate_scale_ppm = %.15g, %.15g\n", sc->plate_scale_ppm,
                sc->u_plate_scale_ppm);
    if (sc->has_cte)
        fprintf(fp, "# plate_cte_ppm_per_K = %.15g, %.15g\n", sc->cte_ppm_per_K,
                sc->u_cte_ppm_per_K);
    if (sc->has_temps && sc->temp_u_K != SC_GRID_TEMP_U_K_DEFAULT)
        fprintf(fp, "# temp_u_K = %.15g\n", sc->temp_u_K);
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "# view %d: rot=%d shift=%d,%d", v, w->rot_deg, w->shift_x, w->shift_y);
        if (w->sigma_um > 0)
            fprintf(fp, " sigma_um=%.15g", w->sigma_um);
        if (sc->has_temps)
            fprintf(fp, " temp_C=%.15g", w->temp_C);
        if (w->restricted) {
            const char *sep = " rows=";
            for (int k = 0; k < p->n; ++k)
                if (w->row_sel[k]) {
                    fprintf(fp, "%s%d", sep, k);
                    sep = ",";
                }
            sep = " cols=";
            for (int k = 0; k < p->n; ++k)
                if (w->col_sel[k]) {
                    fprintf(fp, "%s%d", sep, k);
                    sep = ",";
                }
        }
        fputc('\n', fp);
    }
}

static sc_status finish(sc_afile *f, sc_error *err)
{
    return sc_afile_commit(f, err); /* a write that failed: "write error: <reason>" */
}

static void put_num(FILE *fp, const double *a, int k)
{
    char b[SC_NUMBER_BUF];
    fwrite(b, 1, (size_t)(sc_io_put_15g_opt(b, a, (size_t)k, 0) - b), fp);
}

void sc_grid_fprint_input(FILE *fp, const sc_grid_data *d)
{
    const sc_grid_plan *p = &d->plan;
    sc_grid_write_header(fp, p);
    int has_u = 0, has_t = 0;
    for (int v = 0; v < p->n_views; ++v)
        has_u |= d->ux_um[v] != NULL, has_t |= d->t_s[v] != NULL;
    fprintf(fp, COLUMN_HEADER "%s%s\n", has_u ? ",ux_um,uy_um" : "", has_t ? ",t_s" : "");
    int n = p->n;
    for (int v = 0; v < p->n_views; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                int k = i * n + j;
                double x, y;
                if (!isfinite(d->dx_um[v][k]) || !isfinite(d->dy_um[v][k]) ||
                    !sc_grid_mark_stage_xy_mm(p, v, i, j, &x, &y))
                    continue;
                x += p->origin_mm[0] + d->dx_um[v][k] * 1e-3;
                y += p->origin_mm[1] + d->dy_um[v][k] * 1e-3;
                fprintf(fp, "%d,%d,%d,%.15f,%.15f", v, i, j, x, y);
                if (has_u) {
                    fputc(',', fp);
                    put_num(fp, d->ux_um[v], k);
                    fputc(',', fp);
                    put_num(fp, d->uy_um[v], k);
                }
                if (has_t) {
                    fputc(',', fp);
                    put_num(fp, d->t_s[v], k);
                }
                fputc('\n', fp);
            }
}

sc_status sc_grid_write_input(const char *path, const sc_grid_data *d, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_input(f.fp, d);
    return finish(&f, err);
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

static void json_num(FILE *fp, double v)
{
    if (isfinite(v))
        fprintf(fp, "%.15g", v);
    else
        fputs("null", fp);
}

static void json_kv(FILE *fp, const char *key, double v)
{
    fprintf(fp, ", \"%s\": ", key);
    json_num(fp, v);
}

/* Everything of the summary but its closing brace; views numbered by view_id (NULL: position),
 * with the budget's per-view figures when b applies. */
static void summary_body(FILE *fp, const char *method, const sc_grid_plan *p,
                         const sc_grid_result *res, const int *view_id, const sc_grid_budget *b)
{
    fprintf(fp, "{\n  \"format\": \"selfcal-grid-summary v1\",\n  \"method\": \"%s\",\n", method);
    fprintf(fp, "  \"N\": %d,\n  \"pitch_mm\": %.15g,\n  \"origin_mm\": [%.15g, %.15g],\n", p->n,
            p->pitch_mm, p->origin_mm[0], p->origin_mm[1]);
    fprintf(fp, "  \"stage\": [%d, %d],\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    fputs("  \"O\": ", fp);
    json_num(fp, res->O);
    fputs(",\n  \"uO\": ", fp);
    json_num(fp, res->uO);
    fputs(",\n  \"R\": ", fp);
    json_num(fp, res->R);
    fputs(",\n  \"uR\": ", fp);
    json_num(fp, res->uR);
    /* the same with their units in the key (the dimensionless keys above: kept through 0.3) */
    fputs(",\n  \"O_urad\": ", fp);
    json_num(fp, res->O * 1e6);
    fputs(",\n  \"uO_urad\": ", fp);
    json_num(fp, res->uO * 1e6);
    fputs(",\n  \"R_ppm\": ", fp);
    json_num(fp, res->R * 1e6);
    fputs(",\n  \"uR_ppm\": ", fp);
    json_num(fp, res->uR * 1e6);
    fputs(",\n  \"views\": [\n", fp);
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "    {\"view\": %d, \"rot\": %d, \"shift\": [%d, %d]",
                view_id ? view_id[v] : v, w->rot_deg, w->shift_x, w->shift_y);
#define VIEW_VALUE(arr) (res->arr ? res->arr[v] : NAN) /* an array not given: null */
        json_kv(fp, "tx_um", VIEW_VALUE(tx_um));
        json_kv(fp, "ty_um", VIEW_VALUE(ty_um));
        json_kv(fp, "theta_urad", VIEW_VALUE(theta_urad));
        json_kv(fp, "utx_um", VIEW_VALUE(utx_um));
        json_kv(fp, "uty_um", VIEW_VALUE(uty_um));
        json_kv(fp, "utheta_urad", VIEW_VALUE(utheta_urad));
        if (res->view_noise_estimated) {
            json_kv(fp, "sigma_um_est", VIEW_VALUE(view_sigma_um));
            json_kv(fp, "u_sigma_um_est", VIEW_VALUE(view_sigma_u_um));
            json_kv(fp, "noise_factor", VIEW_VALUE(view_noise_factor));
        }
        if (b && b->applies) {
            if (p->scale.has_temps)
                json_kv(fp, "temp_C", w->temp_C);
            json_kv(fp, "scale_ppm", b->view_scale_ppm[v]);
            if (b->view_scale_free) {
                json_kv(fp, "scale_free_ppm", b->view_scale_free_ppm[v]);
                json_kv(fp, "u_scale_free_ppm", b->u_view_scale_free_ppm[v]);
            }
        }
        if (res->drift) {
            json_kv(fp, "vx_um_s", VIEW_VALUE(vx_um_s));
            json_kv(fp, "vy_um_s", VIEW_VALUE(vy_um_s));
            json_kv(fp, "uvx_um_s", VIEW_VALUE(uvx_um_s));
            json_kv(fp, "uvy_um_s", VIEW_VALUE(uvy_um_s));
        }
#undef VIEW_VALUE
        fprintf(fp, "}%s\n", v + 1 < p->n_views ? "," : "");
    }
    fputs("  ],\n  \"residual_rms_um\": ", fp);
    json_num(fp, res->residual_rms_um);
    fputs(",\n  \"sigma_r_est_um\": ", fp);
    json_num(fp, res->sigma_r_est_um);
    fputs(",\n  \"sigma_r_used_um\": ", fp);
    json_num(fp, res->sigma_r_used_um);
    fprintf(fp, ",\n  \"weighted\": %s,\n  \"stated_uncertainties\": %s,\n  \"variance_factor\": ",
            res->weighted ? "true" : "false", res->stated_u ? "true" : "false");
    json_num(fp, res->variance_factor);
    fputs(",\n  \"chi2_95_interval\": [", fp);
    json_num(fp, res->chi2_lo);
    fputs(", ", fp);
    json_num(fp, res->chi2_hi);
    fprintf(fp, "],\n  \"chi2_test\": \"%s\",\n  \"drift\": \"%s\"",
            !isfinite(res->variance_factor) || !isfinite(res->chi2_lo) ? "n/a"
            : res->chi2_pass                                          ? "pass"
                                                                      : "fail",
            res->drift ? "linear" : "none");
    if (isfinite(res->outlier_crit) && res->outlier_crit > 0) { /* the least squares' test ran */
        fprintf(fp, ",\n  \"outlier_test\": {\"alpha\": %.6g, \"for\": \"%s\", ",
                res->outlier_alpha, res->outlier_alpha_each ? "each coordinate" : "data set");
        fputs("\"alpha_coordinate\": ", fp);
        json_num(fp, res->outlier_alpha_coord);
        fputs(", \"critical_t\": ", fp);
        json_num(fp, res->outlier_crit);
        fprintf(fp, ", \"coordinates_tested\": %ld}", res->n_outlier_tests);
    }
    fprintf(fp, ",\n  \"view_noise\": \"%s\"", res->view_noise_estimated ? "estimated" : "stated");
    fprintf(fp, ",\n  \"misalignment_unique\": %s", res->misalignment_unique ? "true" : "false");
    fprintf(fp, ",\n  \"n_measurements\": %ld,\n  \"dof\": %ld", res->n_measurements, res->dof);
}

void sc_grid_fprint_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                            const sc_grid_result *res)
{
    summary_body(fp, method, p, res, NULL, NULL);
    fputs("\n}\n", fp);
}

/* "key": [a, b] or null. */
static void json_pair(FILE *fp, const char *key, int have, double a, double b)
{
    fprintf(fp, ",\n  \"%s\": ", key);
    if (!have) {
        fputs("null", fp);
        return;
    }
    fputc('[', fp);
    json_num(fp, a);
    fputs(", ", fp);
    json_num(fp, b);
    fputc(']', fp);
}

/* The scale model (SPEC §11) and the budget table. */
static void summary_budget(FILE *fp, const sc_grid_plan *p, const sc_grid_budget *b)
{
    const sc_grid_scale *sc = &p->scale;
    int mag = b->applies && b->magnification;
    fprintf(fp, ",\n  \"scale_included\": %s", mag ? "true" : "false");
    fputs(",\n  \"magnification_ppm\": ", fp);
    json_num(fp, mag ? b->magnification_ppm : NAN);
    fputs(",\n  \"u_magnification_ppm\": ", fp);
    json_num(fp, mag ? b->u_magnification_ppm : NAN);
    json_pair(fp, "plate_scale_ppm", sc->has_plate_scale, sc->plate_scale_ppm,
              sc->u_plate_scale_ppm);
    json_pair(fp, "plate_cte_ppm_per_K", sc->has_cte, sc->cte_ppm_per_K, sc->u_cte_ppm_per_K);
    fputs(",\n  \"temp_u_K\": ", fp);
    json_num(fp, sc->has_temps ? sc->temp_u_K : NAN);
    fprintf(fp, ",\n  \"view_scale\": \"%s\"", b->applies && b->view_scale_free ? "free" : "model");
    if (!b->applies || b->n_rows == 0)
        return;
    if (b->view_scale_free) {
        fputs(",\n  \"view_scale_chi2\": ", fp);
        json_num(fp, b->view_scale_chi2);
        fputs(", \"view_scale_chi2_95\": ", fp);
        json_num(fp, b->view_scale_chi2_crit);
    }
    int nx = sc_grid_stage_nx(p);
    fprintf(fp, ",\n  \"budget\": {\"node\": [%ld, %ld], \"component\": \"%s\", \"rows\": [\n",
            b->worst_node / nx, b->worst_node % nx, b->worst_comp ? "gy" : "gx");
    for (int r = 0; r < b->n_rows; ++r) {
        const sc_grid_budget_row *w = &b->row[r];
        fprintf(fp, "    {\"source\": \"%s\", \"unit\": \"%s\"", w->source, w->unit);
        json_kv(fp, "u", w->u);
        json_kv(fp, "sensitivity_um_per_unit", w->c);
        json_kv(fp, "contribution_um", w->contrib_um);
        json_kv(fp, "dof", w->dof);
        fprintf(fp, "}%s\n", r + 1 < b->n_rows ? "," : "");
    }
    fputs("  ], \"u_c_um\": ", fp);
    json_num(fp, b->u_c_um);
    fputs(", \"nu_eff\": ", fp);
    json_num(fp, b->nu_eff);
    fputs(", \"k\": ", fp);
    json_num(fp, b->k);
    fprintf(fp, ", \"k_from\": \"%s\", \"U_um\": ",
            b->k_welch ? "Welch-Satterthwaite t95(nu_eff)" : "k = 2");
    json_num(fp, b->U_um);
    fputc('}', fp);
}

static void summary_mc(FILE *fp, const sc_grid_mc *mc)
{
    fprintf(fp, ",\n  \"monte_carlo\": {\"trials\": %ld, \"seed\": %llu, \"threads\": %d",
            mc->trials, (unsigned long long)mc->seed, mc->threads);
    json_kv(fp, "seconds", mc->seconds);
    json_kv(fp, "ratio_min", mc->ratio_min);
    json_kv(fp, "ratio_max", mc->ratio_max);
    json_kv(fp, "ratio_mean", mc->ratio_mean);
    json_kv(fp, "magnification_sd_ppm", mc->magnification_sd_ppm);
    fputc('}', fp);
}

void sc_grid_fprint_solution_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                                     const sc_grid_solution *s, const int *view_id,
                                     const sc_grid_mc *mc)
{
    summary_body(fp, method, p, &s->res, view_id, &s->budget);
    summary_budget(fp, p, &s->budget);
    if (mc && mc->trials > 0)
        summary_mc(fp, mc);
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
 * Residuals (SPEC §5) and numpy .npy matrices
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

void sc_fprint_npy(FILE *fp, const double *a, long rows, long cols)
{
    char head[128];
    int len = snprintf(head, sizeof head,
                       "{'descr': '<f8', 'fortran_order': False, 'shape': (%ld, %ld), }", rows,
                       cols);
    int total = 10 + len + 1, pad = (64 - total % 64) % 64;
    unsigned hl = (unsigned)(len + pad + 1);
    fwrite("\x93NUMPY\x01\x00", 1, 8, fp);
    fputc((int)(hl & 0xff), fp);
    fputc((int)(hl >> 8), fp);
    fwrite(head, 1, (size_t)len, fp);
    for (int k = 0; k < pad; ++k)
        fputc(' ', fp);
    fputc('\n', fp);
    const unsigned one = 1;
    int little = *(const unsigned char *)&one == 1;
    for (long k = 0; k < rows * cols; ++k) {
        unsigned char b[8];
        memcpy(b, &a[k], 8);
        if (!little)
            for (int t = 0; t < 4; ++t) {
                unsigned char c = b[t];
                b[t] = b[7 - t];
                b[7 - t] = c;
            }
        fwrite(b, 1, 8, fp);
    }
}
