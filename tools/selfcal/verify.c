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
    sc_grid_file_info_free(&r->info);
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

/* Where input k (0 measurement, 1 table, 2 artifact) is read from. */
static const char *read_path(const verify_opts *o, int k, const char *name)
{
    return o->src[k] ? o->src[k]->path : name;
}

/* The re-measurement, the plate error (given, or read from o->artifact into own_plate) and the
 * table; *plate points at the one in use. */
static sc_status verify_load(const verify_opts *o, verify_result *r, sc_stage_map *own_plate,
                             const sc_stage_map **plate, sc_corr_table *t, sc_error *err)
{
    sc_status st = sc_grid_read(read_path(o, 0, o->measurement), &r->d, &r->info, err);
    if (st != SC_OK)
        return st;
    const sc_grid_plan *p = &r->d.plan;
    if (r->info.n_rows == 0)
        return sc_error_set(err, SC_E_INPUT, o->measurement, r->info.header_end_line,
                            "no data rows: verify needs the re-measured plate");
    *plate = o->plate;
    if (!*plate) {
        st = sc_grid_read_artifact(read_path(o, 2, o->artifact), p->pitch_mm, own_plate, err);
        if (st != SC_OK)
            return st;
        *plate = own_plate;
    }
    if ((*plate)->nx != p->n || (*plate)->ny != p->n)
        return sc_error_set(err, SC_E_INPUT, o->measurement, r->info.n_line,
                            "N = %d, but the plate error of the calibration has N = %d", p->n,
                            (*plate)->nx);
    return sc_lut_load_corr_file(read_path(o, 1, o->table), t, err);
}

/* Work arrays: one view's marks (centred and absolute positions, errors before and after, node
 * index), and all views pooled for the statistics. */
typedef struct {
    double *wx, *wy, *ebx, *eby, *eax, *eay; /* nn each */
    double *absx, *absy;                     /* nn each */
    long *idx;                               /* nn */
    double *pbx, *pby, *pax, *pay, *ppx, *ppy; /* nres each */
    double *block, *pooled;
} verify_work;

static void verify_work_free(verify_work *w)
{
    free(w->block);
    free(w->idx);
    free(w->pooled);
}

static sc_status verify_work_alloc(size_t nn, size_t nres, verify_work *w, sc_error *err)
{
    memset(w, 0, sizeof *w);
    w->block = malloc(8 * nn * sizeof(double));
    w->idx = malloc(nn * sizeof(long));
    /* zeroed: stats_of reads only the pm filled, but GCC -O2 cannot see it */
    w->pooled = calloc(6 * nres + 1, sizeof(double)); /* pbx .. ppy below */
    if (!w->block || !w->idx || !w->pooled) {
        verify_work_free(w);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    double *b = w->block;
    w->wx = b, w->wy = b + nn, w->ebx = b + 2 * nn, w->eby = b + 3 * nn;
    w->eax = b + 4 * nn, w->eay = b + 5 * nn, w->absx = b + 6 * nn, w->absy = b + 7 * nn;
    double *q = w->pooled;
    w->pbx = q, w->pby = q + nres, w->pax = q + 2 * nres, w->pay = q + 3 * nres;
    w->ppx = q + 4 * nres, w->ppy = q + 5 * nres;
    return SC_OK;
}

/* View v's marks that the calibration saw: the error before and after the table (the plate's
 * own error, rotated into the view, taken off). Returns their count; the marks left out are
 * added to *unmeasured (no point in the file) and *unseen (no plate error). */
static long verify_view_marks(const verify_opts *o, const verify_result *r,
                              const sc_stage_map *plate, const sc_corr_table *t, int v,
                              verify_work *w, long *unmeasured, long *unseen)
{
    const sc_grid_plan *p = &r->d.plan;
    const int n = p->n;
    long m = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            size_t k = (size_t)i * n + j;
            int ni, nj;
            double dx = r->d.dx_um[v][k], dy = r->d.dy_um[v][k];
            if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
                continue;
            if (!isfinite(dx) || !isfinite(dy)) {
                *unmeasured += sc_grid_view_measures(p, v, i, j);
                continue;
            }
            double pax_um = plate->gx_um[k], pay_um = plate->gy_um[k];
            if (!isfinite(pax_um) || !isfinite(pay_um)) {
                ++*unseen; /* a mark the calibration could not see */
                continue;
            }
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
            w->wx[m] = x, w->wy[m] = y;
            w->absx[m] = nx_mm, w->absy[m] = ny_mm;
            w->ebx[m] = bdx - rax, w->eby[m] = bdy - ray;
            w->eax[m] = adx - rax, w->eay[m] = ady - ray;
            w->idx[m] = (long)k;
            ++m;
        }
    return m;
}

/* Every view's errors with its misalignment removed, into r's per-mark arrays and the pool;
 * returns the pooled count. */
static long verify_views(const verify_opts *o, verify_result *r, const sc_stage_map *plate,
                         const sc_corr_table *t, verify_work *w)
{
    const sc_grid_plan *p = &r->d.plan;
    const size_t nn = (size_t)p->n * p->n;
    long pm = 0;
    for (int v = 0; v < p->n_views; ++v) {
        long m = verify_view_marks(o, r, plate, t, v, w, &r->n_unmeasured, &r->n_unseen);
        double tx, ty, th;
        remove_misalignment(m, w->wx, w->wy, w->ebx, w->eby, &tx, &ty, &th);
        remove_misalignment(m, w->wx, w->wy, w->eax, w->eay, &r->tx_after[v], &r->ty_after[v],
                            &r->th_after[v]);
        for (long q = 0; q < m; ++q) {
            size_t g = (size_t)v * nn + (size_t)w->idx[q];
            r->bx[g] = w->ebx[q], r->by[g] = w->eby[q], r->ax[g] = w->eax[q],
            r->ay[g] = w->eay[q];
            w->pbx[pm] = w->ebx[q], w->pby[pm] = w->eby[q];
            w->pax[pm] = w->eax[q], w->pay[pm] = w->eay[q];
            w->ppx[pm] = w->absx[q], w->ppy[pm] = w->absy[q];
            ++pm;
        }
    }
    r->st_before = stats_of(pm, w->pbx, w->pby, w->ppx, w->ppy);
    r->st_after = stats_of(pm, w->pax, w->pay, w->ppx, w->ppy);
    return pm;
}

/* Maps per stage node (before, after): the mean over the views that measure it; mp holds
 * 5 * nodes doubles. */
static void verify_stage_maps(verify_result *r, double *mp)
{
    const sc_grid_plan *p = &r->d.plan;
    const int n = p->n, snx = sc_grid_stage_nx(p);
    const size_t nn = (size_t)n * n, ng = (size_t)snx * sc_grid_stage_ny(p);
    double *bgx = mp, *bgy = mp + ng, *agx = mp + 2 * ng, *agy = mp + 3 * ng, *cnt = mp + 4 * ng;
    for (size_t k = 0; k < 5 * ng; ++k)
        mp[k] = 0;
    r->before = sc_grid_stage_map(p, bgx, bgy, NULL, NULL);
    r->after = sc_grid_stage_map(p, agx, agy, NULL, NULL);
    for (int v = 0; v < p->n_views; ++v)
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
}

sc_status verify_run(const verify_opts *o, verify_result *r, sc_error *err)
{
    memset(r, 0, sizeof *r);
    r->pass = -1;
    sc_stage_map own_plate;
    memset(&own_plate, 0, sizeof own_plate);
    const sc_stage_map *plate = NULL;
    verify_work w;
    memset(&w, 0, sizeof w);
    sc_corr_table *t = malloc(sizeof *t);
    if (!t)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    sc_status st = verify_load(o, r, &own_plate, &plate, t, err);
    if (st != SC_OK)
        goto done;
    const sc_grid_plan *p = &r->d.plan;
    const size_t nn = (size_t)p->n * p->n, nres = (size_t)p->n_views * nn;
    const size_t ng = (size_t)sc_grid_stage_nx(p) * sc_grid_stage_ny(p);
    r->buf = malloc((4 * nres + 5 * ng) * sizeof(double));
    if (!r->buf) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto done;
    }
    if ((st = verify_work_alloc(nn, nres, &w, err)) != SC_OK)
        goto done;
    r->bx = r->buf;
    r->by = r->bx + nres;
    r->ax = r->by + nres;
    r->ay = r->ax + nres;
    for (size_t k = 0; k < 4 * nres; ++k)
        r->buf[k] = NAN;
    if (verify_views(o, r, plate, t, &w) == 0) {
        st = sc_error_set(err, SC_E_INPUT, o->measurement, r->info.header_end_line,
                          "no measured mark has a plate error in the calibration");
        goto done;
    }
    if (isfinite(o->tolerance_um))
        r->pass = r->st_after.max <= o->tolerance_um;
    verify_stage_maps(r, r->buf + 4 * nres);
done:
    verify_work_free(&w);
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
