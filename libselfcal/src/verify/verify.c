/* verify.c — the check of a compensated machine: the re-measurement against what the table
 * predicts (the model is in selfcal/verify.h), its statistics, the uncertainty of a residual and
 * the verdict under the decision rule. */
#include "selfcal/verify.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/correct.h"
#include "selfcal/lut.h"

void sc_verify_opts_init(sc_verify_opts *o)
{
    memset(o, 0, sizeof *o);
    o->tolerance_um = NAN;
    o->rule = SC_VERIFY_RULE_SIMPLE;
    o->u_verify_um = NAN;
    o->sigma_r_um = NAN;
    o->u_plate_um = NAN;
}

void sc_verify_result_free(sc_verify_result *r)
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

static sc_verify_stats stats_of(long m, const double *ex, const double *ey, const double *px,
                             const double *py)
{
    sc_verify_stats s;
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

/* The re-measurement, the plate error (given, or read from o->artifact into own_plate) and the
 * table; *plate points at the one in use. */
static sc_status verify_load(const sc_verify_opts *o, sc_verify_result *r, sc_stage_map *own_plate,
                             const sc_stage_map **plate, sc_corr_table *t, sc_error *err)
{
    sc_status st = sc_grid_read(o->measurement, &r->d, &r->info, err);
    if (st != SC_OK)
        return st;
    const sc_grid_plan *p = &r->d.plan;
    if (r->info.n_rows == 0)
        return sc_error_set(err, SC_E_INPUT, o->measurement, r->info.header_end_line,
                            "no data rows: verify needs the re-measured plate");
    *plate = o->plate;
    if (!*plate) {
        st = sc_grid_read_artifact(o->artifact, p->pitch_mm, own_plate, err);
        if (st != SC_OK)
            return st;
        *plate = own_plate;
    }
    if ((*plate)->nx != p->n || (*plate)->ny != p->n)
        return sc_error_set(err, SC_E_INPUT, o->measurement, r->info.n_line,
                            "N = %d, but the plate error of the calibration has N = %d", p->n,
                            (*plate)->nx);
    st = sc_lut_load_corr_file(o->table, t, err);
    if (st != SC_OK)
        return st;
    sc_lut *lut = malloc(sizeof *lut); /* the grid's scale: its quantization */
    if (!lut)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    st = sc_lut_read_file(o->table, lut, err);
    if (st == SC_OK)
        r->u.quant_um = sc_lut_quantization_um(lut->grid_scale_pm);
    free(lut);
    return st;
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
static long verify_view_marks(const sc_verify_opts *o, const sc_verify_result *r,
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
static long verify_views(const sc_verify_opts *o, sc_verify_result *r, const sc_stage_map *plate,
                         const sc_corr_table *t, verify_work *w)
{
    const sc_grid_plan *p = &r->d.plan;
    const size_t nn = (size_t)p->n * p->n;
    long pm = 0;
    for (int v = 0; v < p->n_views; ++v) {
        long m = verify_view_marks(o, r, plate, t, v, w, &r->n_unmeasured, &r->n_unseen);
        double tx, ty, th;
        remove_misalignment(m, w->wx, w->wy, w->ebx, w->eby, &tx, &ty, &th);
        remove_misalignment(m, w->wx, w->wy, w->eax, w->eay, &r->tx_after_um[v],
                            &r->ty_after_um[v], &r->th_after_urad[v]);
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
static void verify_stage_maps(sc_verify_result *r, double *mp)
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

/* The RMS over the marks used of the re-measurement's stated standard uncertainty per
 * coordinate (NaN if it states none for some mark used). */
static double stated_noise_um(const sc_verify_result *r)
{
    const sc_grid_plan *p = &r->d.plan;
    const size_t nn = (size_t)p->n * p->n;
    double s = 0;
    long c = 0;
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k) {
            if (!isfinite(r->ax[(size_t)v * nn + k]))
                continue;
            for (int q = 0; q < 2; ++q) {
                double u = sc_grid_data_u_um(&r->d, v, (long)k, q);
                if (!isfinite(u))
                    return NAN;
                s += u * u;
                ++c;
            }
        }
    return c ? sqrt(s / c) : NAN;
}

/* U of a residual (selfcal/verify.h): given, or 2·√(σ² + u_A² + u_q²). */
static void verify_uncertainty(const sc_verify_opts *o, sc_verify_result *r)
{
    sc_verify_u *u = &r->u;
    u->k = 2;
    u->u_quant_um = u->quant_um / sqrt(3.0);
    if (isfinite(o->sigma_r_um)) {
        u->sigma_um = o->sigma_r_um;
        u->sigma_source = SC_VERIFY_NOISE_GIVEN;
    } else if (isfinite(u->sigma_um = stated_noise_um(r))) {
        u->sigma_source = SC_VERIFY_NOISE_STATED;
    } else {
        u->sigma_um = r->st_after.rms / sqrt(2.0); /* per coordinate; includes what is left */
        u->sigma_source = SC_VERIFY_NOISE_RESIDUALS;
    }
    u->u_plate_given = isfinite(o->u_plate_um);
    u->u_plate_um = u->u_plate_given ? o->u_plate_um : u->sigma_um;
    u->u_um = sqrt(u->sigma_um * u->sigma_um + u->u_plate_um * u->u_plate_um +
                   u->u_quant_um * u->u_quant_um);
    u->U_um = u->k * u->u_um;
    if (isfinite(o->u_verify_um)) {
        u->given = 1;
        u->U_um = o->u_verify_um;
        u->u_um = o->u_verify_um / u->k;
    }
}

sc_verify_verdict sc_verify_decide(sc_verify_rule rule, double max_um, double tol_um, double U_um)
{
    if (!isfinite(tol_um) || isnan(max_um))
        return SC_VERIFY_NO_VERDICT;
    if (rule != SC_VERIFY_RULE_GUARDED)
        return max_um <= tol_um ? SC_VERIFY_PASS : SC_VERIFY_FAIL;
    if (!(U_um >= 0)) /* guarded without a usable U proves nothing */
        return SC_VERIFY_INCONCLUSIVE;
    if (max_um + U_um <= tol_um)
        return SC_VERIFY_PASS;
    if (max_um - U_um > tol_um)
        return SC_VERIFY_FAIL;
    return SC_VERIFY_INCONCLUSIVE;
}

const char *sc_verify_verdict_name(sc_verify_verdict v)
{
    switch (v) {
    case SC_VERIFY_PASS: return "pass";
    case SC_VERIFY_FAIL: return "fail";
    case SC_VERIFY_INCONCLUSIVE: return "inconclusive";
    default: return "none";
    }
}

const char *sc_verify_rule_name(sc_verify_rule rule)
{
    return rule == SC_VERIFY_RULE_GUARDED ? "guarded" : "simple";
}

int sc_verify_rule_from_name(const char *name)
{
    if (name && !strcmp(name, "simple"))
        return SC_VERIFY_RULE_SIMPLE;
    if (name && !strcmp(name, "guarded"))
        return SC_VERIFY_RULE_GUARDED;
    return -1;
}

sc_status sc_verify_run(const sc_verify_opts *o, sc_verify_result *r, sc_error *err)
{
    memset(r, 0, sizeof *r);
    r->verdict = SC_VERIFY_NO_VERDICT;
    r->rule = o->rule;
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
    const size_t nv = (size_t)p->n_views;
    r->buf = malloc((4 * nres + 5 * ng + 3 * nv) * sizeof(double));
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
    r->tx_after_um = r->buf + 4 * nres + 5 * ng;
    r->ty_after_um = r->tx_after_um + nv;
    r->th_after_urad = r->ty_after_um + nv;
    for (size_t k = 0; k < 4 * nres; ++k)
        r->buf[k] = NAN;
    if (verify_views(o, r, plate, t, &w) == 0) {
        st = sc_error_set(err, SC_E_INPUT, o->measurement, r->info.header_end_line,
                          "no measured mark has a plate error in the calibration");
        goto done;
    }
    verify_uncertainty(o, r);
    r->verdict = sc_verify_decide(o->rule, r->st_after.max, o->tolerance_um, r->u.U_um);
    verify_stage_maps(r, r->buf + 4 * nres);
done:
    verify_work_free(&w);
    free(t);
    sc_stage_map_free(&own_plate);
    return st;
}

