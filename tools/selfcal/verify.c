/* verify.c — the check of a compensated machine: re-measurement vs what the table predicts (the
 * model is in verify.h), its statistics and verdict, and its report section. */
#include "verify.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "plots.h"
#include "report_html.h"
#include "selfcal/correct.h"
#include "selfcal/csv.h"
#include "selfcal/lut.h"


void verify_opts_init(verify_opts *o)
{
    memset(o, 0, sizeof *o);
    o->tolerance_um = NAN;
}

void verify_result_free(verify_result *r)
{
    free(r->buf);
    sc_grid_data_free(&r->d);
    memset(r, 0, sizeof *r);
}

/* Least-squares misalignment (tx, ty µm; θ µrad) of residuals ex, ey at positions x, y (mm from
 * the grid centre): ex ≈ tx − θ·y·1e-3, ey ≈ ty + θ·x·1e-3. Removes it from ex, ey in place. */
static void remove_misalignment(long m, const double *x, const double *y, double *ex, double *ey,
                                double *tx, double *ty, double *th)
{
    double sx = 0, sy = 0, sex = 0, sey = 0;
    for (long k = 0; k < m; ++k)
        sx += x[k], sy += y[k], sex += ex[k], sey += ey[k];
    *tx = *ty = *th = 0;
    if (m == 0)
        return;
    double mx = sx / m, my = sy / m, mex = sex / m, mey = sey / m;
    /* θ from the centred data: minimise Σ (ex' + θ y'c)² + (ey' − θ x'c)², c = 1e-3 */
    double num = 0, den = 0;
    for (long k = 0; k < m; ++k) {
        double xc = (x[k] - mx) * 1e-3, yc = (y[k] - my) * 1e-3;
        num += (ey[k] - mey) * xc - (ex[k] - mex) * yc;
        den += xc * xc + yc * yc;
    }
    double t = den > 0 ? num / den : 0;
    *th = t;
    *tx = mex + t * my * 1e-3;
    *ty = mey - t * mx * 1e-3;
    for (long k = 0; k < m; ++k) {
        ex[k] -= *tx - t * y[k] * 1e-3;
        ey[k] -= *ty + t * x[k] * 1e-3;
    }
}

static verify_stats stats_of(long m, const double *ex, const double *ey, const double *px,
                             const double *py)
{
    verify_stats s;
    memset(&s, 0, sizeof s);
    s.count = m;
    double sx = 0, sy = 0;
    for (long k = 0; k < m; ++k) {
        sx += ex[k] * ex[k];
        sy += ey[k] * ey[k];
        double a = hypot(ex[k], ey[k]);
        if (a >= s.max) {
            s.max = a;
            s.max_x_mm = px[k];
            s.max_y_mm = py[k];
        }
    }
    s.rms_x = m ? sqrt(sx / m) : NAN;
    s.rms_y = m ? sqrt(sy / m) : NAN;
    s.rms = m ? sqrt((sx + sy) / m) : NAN;
    if (!m)
        s.max = NAN;
    return s;
}

sc_status verify_run(const verify_opts *o, verify_result *r, sc_error *err)
{
    memset(r, 0, sizeof *r);
    r->pass = -1;
    sc_stage_map own_plate;
    memset(&own_plate, 0, sizeof own_plate);
    sc_corr_table *t = malloc(sizeof *t);
    if (!t)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    double *work = NULL;
    sc_status st = sc_grid_read(o->measurement, &r->d, &r->info, err);
    if (st != SC_OK)
        goto done;
    const sc_grid_plan *p = &r->d.plan;
    int n = p->n, nv = p->n_views;
    size_t nn = (size_t)n * n;
    if (r->info.n_rows == 0) {
        st = sc_error_set(err, SC_E_INPUT, o->measurement, r->info.header_end_line,
                          "no data rows: verify needs the re-measured plate");
        goto done;
    }
    const sc_stage_map *plate = o->plate;
    if (!plate) {
        st = sc_grid_read_artifact(o->artifact, p->pitch_mm, &own_plate, err);
        if (st != SC_OK)
            goto done;
        plate = &own_plate;
    }
    if (plate->nx != n || plate->ny != n) {
        st = sc_error_set(err, SC_E_INPUT, o->measurement, r->info.n_line,
                          "N = %d, but the plate error of the calibration has N = %d", n, plate->nx);
        goto done;
    }
    if ((st = sc_lut_load_corr_file(o->table, t, err)) != SC_OK)
        goto done;

    size_t nres = (size_t)nv * nn;
    int snx = sc_grid_stage_nx(p), sny = sc_grid_stage_ny(p);
    size_t ng = (size_t)snx * sny;
    r->buf = malloc((4 * nres + 5 * ng) * sizeof(double));
    work = malloc(6 * nn * sizeof(double));
    if (!r->buf || !work) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto done;
    }
    r->bx = r->buf;
    r->by = r->bx + nres;
    r->ax = r->by + nres;
    r->ay = r->ax + nres;
    for (size_t k = 0; k < 4 * nres; ++k)
        r->buf[k] = NAN;
    /* per-view work: node positions (centred and absolute), before and after */
    double *wx = work, *wy = wx + nn, *ebx = wy + nn, *eby = ebx + nn, *eax = eby + nn,
           *eay = eax + nn;
    long *idx = malloc(nn * sizeof(long));
    double *absx = malloc(2 * nn * sizeof(double));
    if (!idx || !absx) {
        free(idx);
        free(absx);
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto done;
    }
    double *absy = absx + nn;
    /* all views pooled for the statistics */
    double *pbx = calloc(8 * nres + 1, sizeof(double)); /* zeroed: stats_of reads only the pm filled, but GCC -O2 cannot see it */
    if (!pbx) {
        free(idx);
        free(absx);
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto done;
    }
    double *pby = pbx + nres, *pax = pby + nres, *pay = pax + nres, *ppx = pay + nres,
           *ppy = ppx + nres;
    long pm = 0;
    for (int v = 0; v < nv; ++v) {
        long m = 0;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                size_t k = (size_t)i * n + j;
                int ni, nj;
                double dx = r->d.dx_um[v][k], dy = r->d.dy_um[v][k];
                if (!isfinite(dx) || !isfinite(dy) || !sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    continue;
                double pax_um = plate->gx_um[k], pay_um = plate->gy_um[k];
                if (!isfinite(pax_um) || !isfinite(pay_um))
                    continue; /* a mark the calibration could not see */
                double rax, ray;
                sc_grid_rotate(p->view[v].rot_deg, pax_um, pay_um, &rax, &ray);
                double x, y;
                sc_grid_node_xy_mm(p, ni, nj, &x, &y);
                double nx_mm = x + p->origin_mm[0], ny_mm = y + p->origin_mm[1];
                double in[3] = {nx_mm + dx * 1e-3, ny_mm + dy * 1e-3, 0}, o3[3];
                double bdx, bdy, adx, ady;
                if (o->raw) {
                    bdx = dx, bdy = dy;
                    sc_corr_apply(t, SC_CORR_MEASURE, in, o3);
                    adx = (o3[0] - nx_mm) * 1e3, ady = (o3[1] - ny_mm) * 1e3;
                } else {
                    adx = dx, ady = dy;
                    sc_corr_apply(t, SC_CORR_POSITION, in, o3);
                    bdx = (o3[0] - nx_mm) * 1e3, bdy = (o3[1] - ny_mm) * 1e3;
                }
                wx[m] = x, wy[m] = y;
                absx[m] = nx_mm, absy[m] = ny_mm;
                ebx[m] = bdx - rax, eby[m] = bdy - ray;
                eax[m] = adx - rax, eay[m] = ady - ray;
                idx[m] = (long)k;
                ++m;
            }
        double tx, ty, th;
        remove_misalignment(m, wx, wy, ebx, eby, &tx, &ty, &th);
        remove_misalignment(m, wx, wy, eax, eay, &r->tx_after[v], &r->ty_after[v], &r->th_after[v]);
        for (long q = 0; q < m; ++q) {
            size_t g = (size_t)v * nn + (size_t)idx[q];
            r->bx[g] = ebx[q], r->by[g] = eby[q], r->ax[g] = eax[q], r->ay[g] = eay[q];
            pbx[pm] = ebx[q], pby[pm] = eby[q], pax[pm] = eax[q], pay[pm] = eay[q];
            ppx[pm] = absx[q], ppy[pm] = absy[q];
            ++pm;
        }
    }
    r->st_before = stats_of(pm, pbx, pby, ppx, ppy);
    r->st_after = stats_of(pm, pax, pay, ppx, ppy);
    free(pbx);
    free(idx);
    free(absx);
    if (pm == 0) {
        st = sc_error_set(err, SC_E_INPUT, o->measurement, r->info.header_end_line,
                          "no measured mark has a plate error in the calibration");
        goto done;
    }
    if (isfinite(o->tolerance_um))
        r->pass = r->st_after.max <= o->tolerance_um;
    /* maps per stage node: the mean over the views that measure it */
    double *mp = r->buf + 4 * nres, *cnt = mp + 4 * ng;
    for (size_t k = 0; k < 5 * ng; ++k)
        mp[k] = 0;
    r->before = sc_grid_stage_map(p, mp, mp + ng, NULL, NULL);
    r->after = sc_grid_stage_map(p, mp + 2 * ng, mp + 3 * ng, NULL, NULL);
    double *bgx = mp, *bgy = mp + ng, *agx = mp + 2 * ng, *agy = mp + 3 * ng;
    for (int v = 0; v < nv; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                size_t g = (size_t)v * nn + (size_t)i * n + j;
                int ni, nj;
                if (!isfinite(r->bx[g]) || !sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    continue;
                size_t q = (size_t)ni * snx + nj;
                bgx[q] += r->bx[g], bgy[q] += r->by[g];
                agx[q] += r->ax[g], agy[q] += r->ay[g];
                cnt[q] += 1;
            }
    for (size_t q = 0; q < ng; ++q) {
        double c = cnt[q];
        bgx[q] = c > 0 ? bgx[q] / c : NAN;
        bgy[q] = c > 0 ? bgy[q] / c : NAN;
        agx[q] = c > 0 ? agx[q] / c : NAN;
        agy[q] = c > 0 ? agy[q] / c : NAN;
    }
done:
    free(work);
    free(t);
    sc_stage_map_free(&own_plate);
    return st;
}

static void draw_v(FILE *fp, const void *ctx)
{
    const verify_result *r = ctx;
    plot_arrows_pair_svg(fp, &r->before, "before compensation (A, placement removed)", &r->after,
                         "after compensation (A, placement removed)", NULL);
}

static void stats_row(FILE *fp, const char *name, const char *id, const verify_stats *s)
{
    char b[64];
    fprintf(fp, "<tr><td class=\"l\">%s</td><td>%ld</td>", name, s->count);
    snprintf(b, sizeof b, "%s-rms-x", id);
    html_num_cell(fp, b, "%.4g", s->rms_x);
    snprintf(b, sizeof b, "%s-rms-y", id);
    html_num_cell(fp, b, "%.4g", s->rms_y);
    snprintf(b, sizeof b, "%s-rms", id);
    html_num_cell(fp, b, "%.4g", s->rms);
    snprintf(b, sizeof b, "%s-max", id);
    html_num_cell(fp, b, "%.4g", s->max);
    fprintf(fp, "<td class=\"l\">(%g, %g)</td></tr>\n", s->max_x_mm, s->max_y_mm);
}

sc_status verify_html_section(FILE *fp, const verify_opts *o, const verify_result *r,
                              const char *heading, sc_error *err)
{
    fputs("<section id=\"verify\">\n<h2>", fp);
    html_esc(fp, heading);
    fputs("</h2>\n<p>The plate was measured again with the table loaded (", fp);
    html_esc(fp, o->measurement);
    fputs(o->raw ? "; uncompensated readings, the table's measure-mode correction applied here"
                 : "; readings of the compensated machine",
          fp);
    fputs("). From each mark's deviation the plate error A of the calibration (rotated into the "
          "view) and a fitted misalignment per view are removed. <b>After</b>: what the table "
          "left uncompensated, plus noise. <b>Before</b>: the same measurement as the machine "
          "would have read it without the table (≈ G).</p>\n",
          fp);
    fputs("<table>\n<tr><th class=\"l\"></th><th>marks</th><th>RMS x (µm)</th><th>RMS y (µm)</th>"
          "<th>RMS |r| (µm)</th><th>max |r| (µm)</th><th class=\"l\">largest at (x, y) mm</th></tr>\n",
          fp);
    stats_row(fp, "before compensation", "verify-before", &r->st_before);
    stats_row(fp, "after compensation", "verify-after", &r->st_after);
    fputs("</table>\n<p>", fp);
    if (r->pass >= 0)
        fprintf(fp, "Tolerance on max |r| after compensation: <span id=\"verify-tolerance\">%g</span> µm. "
                    "Verdict: <b id=\"verify-verdict\" class=\"%s\">%s</b>.",
                o->tolerance_um, r->pass ? "pass" : "fail", r->pass ? "pass" : "fail");
    else
        fputs("No tolerance given (--tolerance-um): no verdict.", fp);
    fprintf(fp, " Improvement of the RMS: ×%.3g.</p>\n", r->st_before.rms / r->st_after.rms);
    sc_status st = html_figure(fp, draw_v, r, "Residual maps before and after compensation (each "
                               "with its own arrow scale).", err);
    fputs("</section>\n", fp);
    return st;
}
