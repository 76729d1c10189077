/* The JSON summary of a calibration (sc_grid_fprint_solution_summary, grid_calibrate.h): the
 * summary of its result (io/grid_results.c, the format) with the scale model, the uncertainty
 * budget (grid_scale.h) and the Monte Carlo check added: figures of this folder's methods, which
 * io/ does not know. */
#include "selfcal/grid_calibrate.h"
#include "selfcal/grid_scale.h"

#include <math.h>
#include <stdio.h>

#include "../io/grid_results_internal.h"

/* View v's scale figures of the budget b (ctx), when the budget applies. */
static void budget_view(FILE *fp, const void *ctx, const sc_grid_plan *p, int v)
{
    const sc_grid_budget *b = ctx;
    if (!b || !b->applies)
        return;
    if (p->scale.has_temps)
        sc_io_json_kv(fp, "temp_C", p->view[v].temp_C);
    sc_io_json_kv(fp, "scale_ppm", b->view_scale_ppm[v]);
    if (b->view_scale_free) {
        sc_io_json_kv(fp, "scale_free_ppm", b->view_scale_free_ppm[v]);
        sc_io_json_kv(fp, "u_scale_free_ppm", b->u_view_scale_free_ppm[v]);
    }
}

/* The scale model (SPEC §11) and the budget table. */
static void summary_budget(FILE *fp, const sc_grid_plan *p, const sc_grid_budget *b)
{
    const sc_grid_scale *sc = &p->scale;
    int mag = b->applies && b->magnification;
    fprintf(fp, ",\n  \"scale_included\": %s", mag ? "true" : "false");
    fputs(",\n  \"magnification_ppm\": ", fp);
    sc_io_json_num(fp, mag ? b->magnification_ppm : NAN);
    fputs(",\n  \"u_magnification_ppm\": ", fp);
    sc_io_json_num(fp, mag ? b->u_magnification_ppm : NAN);
    sc_io_json_pair(fp, "plate_scale_ppm", sc->has_plate_scale, sc->plate_scale_ppm,
                    sc->u_plate_scale_ppm);
    sc_io_json_pair(fp, "plate_cte_ppm_per_K", sc->has_cte, sc->cte_ppm_per_K,
                    sc->u_cte_ppm_per_K);
    fputs(",\n  \"temp_u_K\": ", fp);
    sc_io_json_num(fp, sc->has_temps ? sc->temp_u_K : NAN);
    fprintf(fp, ",\n  \"view_scale\": \"%s\"", b->applies && b->view_scale_free ? "free" : "model");
    if (!b->applies || b->n_rows == 0)
        return;
    if (b->view_scale_free) {
        fputs(",\n  \"view_scale_chi2\": ", fp);
        sc_io_json_num(fp, b->view_scale_chi2);
        fputs(", \"view_scale_chi2_95\": ", fp);
        sc_io_json_num(fp, b->view_scale_chi2_crit);
    }
    int nx = sc_grid_stage_nx(p);
    fprintf(fp, ",\n  \"budget\": {\"node\": [%ld, %ld], \"component\": \"%s\", \"rows\": [\n",
            b->worst_node / nx, b->worst_node % nx, b->worst_comp ? "gy" : "gx");
    for (int r = 0; r < b->n_rows; ++r) {
        const sc_grid_budget_row *w = &b->row[r];
        fprintf(fp, "    {\"source\": \"%s\", \"unit\": \"%s\"", w->source, w->unit);
        sc_io_json_kv(fp, "u", w->u);
        sc_io_json_kv(fp, "sensitivity_um_per_unit", w->c);
        sc_io_json_kv(fp, "contribution_um", w->contrib_um);
        sc_io_json_kv(fp, "dof", w->dof);
        fprintf(fp, "}%s\n", r + 1 < b->n_rows ? "," : "");
    }
    fputs("  ], \"u_c_um\": ", fp);
    sc_io_json_num(fp, b->u_c_um);
    fputs(", \"nu_eff\": ", fp);
    sc_io_json_num(fp, b->nu_eff);
    fputs(", \"k\": ", fp);
    sc_io_json_num(fp, b->k);
    fprintf(fp, ", \"k_from\": \"%s\", \"U_um\": ",
            b->k_welch ? "Welch-Satterthwaite t95(nu_eff)" : "k = 2");
    sc_io_json_num(fp, b->U_um);
    fputc('}', fp);
}

static void summary_mc(FILE *fp, const sc_grid_mc *mc)
{
    fprintf(fp, ",\n  \"monte_carlo\": {\"trials\": %ld, \"seed\": %llu, \"threads\": %d",
            mc->trials, (unsigned long long)mc->seed, mc->threads);
    sc_io_json_kv(fp, "seconds", mc->seconds);
    sc_io_json_kv(fp, "ratio_min", mc->ratio_min);
    sc_io_json_kv(fp, "ratio_max", mc->ratio_max);
    sc_io_json_kv(fp, "ratio_mean", mc->ratio_mean);
    sc_io_json_kv(fp, "magnification_sd_ppm", mc->magnification_sd_ppm);
    fputc('}', fp);
}

void sc_grid_fprint_solution_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                                     const sc_grid_solution *s, const int *view_id,
                                     const sc_grid_mc *mc)
{
    sc_io_grid_summary_body(fp, method, p, &s->res, view_id, budget_view, &s->budget);
    summary_budget(fp, p, &s->budget);
    if (mc && mc->trials > 0)
        summary_mc(fp, mc);
    fputs("\n}\n", fp);
}
