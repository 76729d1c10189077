/* The plate's scale and temperature in a least-squares calibration (SPEC §11, docs/grid.md):
 * the data brought to the 20 °C plate, free per-view scales (Frisch–Waugh–Lovell on top of the
 * least-squares plan), the stage magnification tied to the plate's certificate (a change of the
 * gauge: A gets no magnification, G keeps it), the uncertainty budget of every node, and the
 * Monte Carlo check of that budget on two threads.
 *
 * Every piece is linear in the data, so each is one estimator applied to data: the sensitivity
 * of G to a view's scale is minus the estimator's answer to the data b_v = 1e-3·Rot_v(p) (µm per
 * ppm: what a plate 1 ppm larger adds) on that view's measured marks.
 */
#include "grid_scale_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "grid_lsq_internal.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_sim.h"
#include "selfcal/rng.h"

/* ---- the plate's scale in the data --------------------------------------------------------- */

/* Rot_v(p) of mark k, mm: the plate-centred nominal position seen through view v's rotation. */
static void plate_vec(const sc_grid_plan *p, int v, int k, double *bx, double *by)
{
    double x, y;
    sc_grid_mark_xy_mm(p, k / p->n, k % p->n, &x, &y);
    sc_grid_rotate(p->view[v].rot_deg, x, y, bx, by);
}

int sc_grid_scale_model_applies(const sc_grid_plan *p, int view_scale_free)
{
    const sc_grid_scale *sc = &p->scale;
    return sc->has_plate_scale || (sc->has_temps && sc->has_cte) || view_scale_free;
}

void sc_grid_scale_subtract(sc_grid_data *d, const double *s_ppm)
{
    const sc_grid_plan *p = &d->plan;
    int nn = p->n * p->n;
    for (int v = 0; v < p->n_views; ++v)
        for (int k = 0; s_ppm[v] != 0 && k < nn; ++k) {
            double bx, by;
            if (!isfinite(d->dx_um[v][k]))
                continue;
            plate_vec(p, v, k, &bx, &by);
            d->dx_um[v][k] -= s_ppm[v] * 1e-3 * bx;
            d->dy_um[v][k] -= s_ppm[v] * 1e-3 * by;
        }
}

sc_status sc_grid_data_copy_values(const sc_grid_data *d, sc_grid_data *c, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    size_t nn = (size_t)p->n * p->n;
    memset(c, 0, sizeof *c);
    sc_status st = sc_grid_plan_copy(&c->plan, p, err);
    if (st == SC_OK)
        st = sc_grid_data_alloc(c, err); /* its own plan, tables and dx/dy */
    if (st != SC_OK) {
        sc_grid_data_free(c);
        return st;
    }
    for (int v = 0; v < p->n_views; ++v) {
        memcpy(c->dx_um[v], d->dx_um[v], nn * sizeof(double));
        memcpy(c->dy_um[v], d->dy_um[v], nn * sizeof(double));
        c->ux_um[v] = d->ux_um ? d->ux_um[v] : NULL; /* borrowed */
        c->uy_um[v] = d->uy_um ? d->uy_um[v] : NULL;
        c->t_s[v] = d->t_s ? d->t_s[v] : NULL;
    }
    return SC_OK;
}

void sc_grid_data_copy_free(sc_grid_data *c)
{
    for (int v = 0; c->ux_um && v < c->plan.n_views; ++v)
        c->ux_um[v] = c->uy_um[v] = c->t_s[v] = NULL; /* borrowed: not freed */
    sc_grid_data_free(c);
}

void sc_grid_sim_scale(const sc_grid_plan *p, double magnification_ppm, sc_grid_sim_truth *t,
                       sc_grid_data *d)
{
    int nn = p->n * p->n, nx = sc_grid_stage_nx(p), with_e = p->scale.has_plate_scale;
    double a = with_e ? sc_grid_plate_magnification_ppm(p, t->ax_um, t->ay_um) : 0.0;
    for (int k = 0; with_e && k < nn; ++k) {
        double x, y;
        sc_grid_mark_xy_mm(p, k / p->n, k % p->n, &x, &y);
        t->ax_um[k] -= a * 1e-3 * x, t->ay_um[k] -= a * 1e-3 * y;
    }
    for (long k = 0; with_e && k < sc_grid_stage_nodes(p); ++k) {
        double x, y;
        sc_grid_node_xy_mm(p, (int)(k / nx), (int)(k % nx), &x, &y);
        t->gx_um[k] += magnification_ppm * 1e-3 * x, t->gy_um[k] += magnification_ppm * 1e-3 * y;
    }
    for (int v = 0; v < p->n_views; ++v) {
        double sv = sc_grid_view_scale_ppm(p, v) - a;
        for (int k = 0; k < nn; ++k) {
            int ni, nj;
            double bx, by, x, y;
            if (!isfinite(d->dx_um[v][k]) || !sc_grid_mark_node(p, v, k / p->n, k % p->n, &ni, &nj))
                continue;
            plate_vec(p, v, k, &bx, &by);
            sc_grid_node_xy_mm(p, ni, nj, &x, &y);
            d->dx_um[v][k] += magnification_ppm * 1e-3 * x + sv * 1e-3 * bx;
            d->dy_um[v][k] += magnification_ppm * 1e-3 * y + sv * 1e-3 * by;
        }
    }
}

/* ---- the estimator: least squares, free view scales, the magnification gauge --------------- */

/* Eigen-decomposition of a symmetric n x n matrix a (row-major, destroyed) by cyclic Jacobi:
 * eigenvalues in w, eigenvectors in the columns of V. */
static void jacobi_eigen(int n, double *a, double *w, double *V)
{
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            V[i * n + j] = i == j;
    for (int sweep = 0; sweep < 100; ++sweep) {
        double off = 0, diag = 0;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j)
                *(i == j ? &diag : &off) += a[i * n + j] * a[i * n + j];
        if (off <= 1e-30 * diag || off == 0)
            break;
        for (int p = 0; p < n; ++p)
            for (int q = p + 1; q < n; ++q) {
                double apq = a[p * n + q];
                if (apq == 0)
                    continue;
                double th = (a[q * n + q] - a[p * n + p]) / (2 * apq);
                double t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < n; ++k) { /* columns p, q */
                    double akp = a[k * n + p], akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq, a[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; ++k) { /* rows p, q */
                    double apk = a[p * n + k], aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk, a[q * n + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < n; ++k) {
                    double vkp = V[k * n + p], vkq = V[k * n + q];
                    V[k * n + p] = c * vkp - s * vkq, V[k * n + q] = s * vkp + c * vkq;
                }
            }
    }
    for (int i = 0; i < n; ++i)
        w[i] = a[i * n + i];
}

/* Mp := the pseudo-inverse of the symmetric n x n M (eigenvalues below 1e-9 of the largest
 * count as 0); returns the rank. */
static int pseudo_inverse(int n, const double *M, double *Mp)
{
    double *a = malloc(sizeof(double) * (size_t)n * n * 2 + sizeof(double) * (size_t)n);
    if (!a)
        return -1;
    double *V = a + (size_t)n * n, *w = V + (size_t)n * n, mx = 0;
    memcpy(a, M, sizeof(double) * (size_t)n * n);
    jacobi_eigen(n, a, w, V);
    for (int i = 0; i < n; ++i)
        mx = fmax(mx, fabs(w[i]));
    int rank = 0;
    memset(Mp, 0, sizeof(double) * (size_t)n * n);
    for (int e = 0; e < n; ++e) {
        if (!(w[e] > 1e-9 * mx))
            continue;
        ++rank;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j)
                Mp[i * n + j] += V[i * n + e] * V[j * n + e] / w[e];
    }
    free(a);
    return rank;
}

/* The plate's magnification of a result's A (ppm), over the marks with a plate error. */
double sc_grid_plate_magnification_ppm(const sc_grid_plan *p, const double *ax, const double *ay)
{
    double s = 0, r2 = 0;
    for (int k = 0; k < p->n * p->n; ++k) {
        double x, y;
        if (!isfinite(ax[k]))
            continue;
        sc_grid_mark_xy_mm(p, k / p->n, k % p->n, &x, &y);
        s += x * ax[k] + y * ay[k];
        r2 += x * x + y * y;
    }
    return r2 > 0 ? 1e3 * s / r2 : 0.0;
}

/* A solve's workspace (one per thread). */
typedef struct est_work {
    double *buf;
    sc_grid_result res;
    double *rx, *ry;
    double *s;  /* nv: the free scales of the last estimate */
    double *tmp; /* nv: scratch */
} est_work;

static void est_work_free(est_work *w)
{
    free(w->buf);
    memset(w, 0, sizeof *w);
}

static sc_status est_work_alloc(const sc_grid_plan *p, est_work *w, sc_error *err)
{
    size_t ns = (size_t)sc_grid_stage_nodes(p), nn = (size_t)p->n * p->n;
    size_t tot = (size_t)p->n_views * nn;
    memset(w, 0, sizeof *w);
    w->buf = malloc(sizeof(double) * (4 * ns + 2 * nn + 2 * tot + 2 * (size_t)p->n_views));
    if (!w->buf)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    double *b = w->buf;
    w->res.gx_um = b, w->res.gy_um = b + ns, w->res.ugx_um = b + 2 * ns;
    w->res.ugy_um = b + 3 * ns, w->res.ax_um = b + 4 * ns, w->res.ay_um = b + 4 * ns + nn;
    w->rx = b + 4 * ns + 2 * nn, w->ry = w->rx + tot, w->s = w->ry + tot;
    w->tmp = w->s + p->n_views;
    return SC_OK;
}

void sc_grid_est_free(sc_grid_est *e)
{
    sc_grid_lsq_plan_destroy(e->q);
    free(e->R);
    free(e->gb);
    free(e->mb);
    free(e->Mp);
    free(e->M);
    free(e->w);
    memset(e, 0, sizeof *e);
}

/* b := the data of view v's plate 1 ppm larger (µm) on mask's measured marks, 0 on the other
 * views' (NaN where mask has none). */
static void unit_scale_data(const sc_grid_data *mask, int v, sc_grid_data *b)
{
    const sc_grid_plan *p = &mask->plan;
    int nn = p->n * p->n;
    for (int w = 0; w < p->n_views; ++w)
        for (int k = 0; k < nn; ++k) {
            double bx = 0, by = 0;
            if (!isfinite(mask->dx_um[w][k])) {
                b->dx_um[w][k] = b->dy_um[w][k] = NAN;
                continue;
            }
            if (w == v)
                plate_vec(p, w, k, &bx, &by);
            b->dx_um[w][k] = 1e-3 * bx;
            b->dy_um[w][k] = 1e-3 * by;
        }
}

/* The base estimate of d (the plan's least squares, SPEC gauge): G into g (gx then gy), the
 * plate's magnification into *m; with free scales the residuals too. */
static sc_status base_estimate(const sc_grid_est *e, const sc_grid_data *d, est_work *w,
                               double *g, double *m, int residuals, sc_error *err)
{
    sc_status st = sc_grid_lsq_execute(e->q, d, 0, &w->res, err);
    if (st == SC_OK && residuals)
        st = sc_grid_lsq_residuals(e->q, d, &w->res, w->rx, w->ry, NULL, NULL, NULL, err);
    if (st != SC_OK)
        return st;
    memcpy(g, w->res.gx_um, sizeof(double) * (size_t)e->ns);
    memcpy(g + e->ns, w->res.gy_um, sizeof(double) * (size_t)e->ns);
    *m = sc_grid_plate_magnification_ppm(&d->plan, w->res.ax_um, w->res.ay_um);
    return SC_OK;
}

/* Σ_e w_e r_a,e r_b,e over both coordinates (arrays nv·nn, NaN unmeasured). */
static double weighted_dot(const sc_grid_est *e, const double *a, const double *b)
{
    double s = 0;
    for (long i = 0; i < 2 * e->tot; ++i)
        if (e->w[i] > 0 && isfinite(a[i]) && isfinite(b[i]))
            s += e->w[i] * a[i] * b[i];
    return s;
}

/* The coordinate weights of mask (1/u² where stated, else 1; 0 unmeasured). */
static void mask_weights(const sc_grid_data *mask, int weighted, double *w)
{
    const sc_grid_plan *p = &mask->plan;
    long nn = (long)p->n * p->n, tot = nn * p->n_views;
    for (int v = 0; v < p->n_views; ++v)
        for (long k = 0; k < nn; ++k)
            for (int c = 0; c < 2; ++c) {
                double u = weighted ? sc_grid_data_u_um(mask, v, k, c) : NAN;
                w[c * tot + v * nn + k] = !isfinite(mask->dx_um[v][k]) ? 0.0
                                          : isfinite(u) && u > 0    ? 1.0 / (u * u)
                                                                    : 1.0;
            }
}

/* Pack a work's residuals (rx then ry) into r (2·tot). */
static void pack_residuals(const sc_grid_est *e, const est_work *w, double *r)
{
    memcpy(r, w->rx, sizeof(double) * (size_t)e->tot);
    memcpy(r + e->tot, w->ry, sizeof(double) * (size_t)e->tot);
}

sc_status sc_grid_est_make(const sc_grid_data *mask, const sc_grid_lsq_opts *opts, int mag,
                           int free_scales, sc_grid_est *e, sc_error *err)
{
    const sc_grid_plan *p = &mask->plan;
    memset(e, 0, sizeof *e);
    e->nv = p->n_views, e->ns = (int)sc_grid_stage_nodes(p);
    e->tot = (long)p->n * p->n * p->n_views;
    e->mag = mag, e->free = free_scales;
    sc_status st = sc_grid_lsq_plan_create(p, mask, opts, &e->q, err);
    if (st != SC_OK)
        return st;
    sc_grid_lsq_info info;
    sc_grid_lsq_get_info(e->q, &info);
    if (!info.identifiable)
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0, "the measured views do not identify G");
    e->weighted = info.weighted;
    int nv = e->nv;
    e->gb = malloc(sizeof(double) * 2 * (size_t)e->ns * nv);
    e->mb = malloc(sizeof(double) * nv);
    e->w = malloc(sizeof(double) * 2 * (size_t)e->tot);
    if (!e->gb || !e->mb || !e->w)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    mask_weights(mask, e->weighted, e->w);
    if (free_scales) {
        e->R = malloc(sizeof(double) * 2 * (size_t)e->tot * nv);
        e->M = malloc(sizeof(double) * (size_t)nv * nv);
        e->Mp = malloc(sizeof(double) * (size_t)nv * nv);
        if (!e->R || !e->M || !e->Mp)
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    sc_grid_data b;
    est_work w;
    if ((st = sc_grid_data_copy_values(mask, &b, err)) != SC_OK)
        return st;
    if ((st = est_work_alloc(p, &w, err)) != SC_OK) {
        sc_grid_data_copy_free(&b);
        return st;
    }
    for (int v = 0; v < nv && st == SC_OK; ++v) { /* each view's unit scale through the plan */
        unit_scale_data(mask, v, &b);
        st = base_estimate(e, &b, &w, e->gb + 2 * (size_t)e->ns * v, &e->mb[v], free_scales, err);
        if (st == SC_OK && free_scales)
            pack_residuals(e, &w, e->R + 2 * (size_t)e->tot * v);
    }
    for (int a = 0; st == SC_OK && free_scales && a < nv; ++a)
        for (int c = 0; c < nv; ++c)
            e->M[a * nv + c] = weighted_dot(e, e->R + 2 * (size_t)e->tot * a,
                                            e->R + 2 * (size_t)e->tot * c);
    if (st == SC_OK && free_scales && (e->rank = pseudo_inverse(nv, e->M, e->Mp)) < 0)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    est_work_free(&w);
    sc_grid_data_copy_free(&b);
    return st;
}

/* The estimate of d (already brought to the 20 °C plate): base, minus the free scales' part,
 * then the magnification gauge. g: gx then gy (2·ns); *m: the magnification (ppm); w->s: the
 * free scales (ppm, when free). */
static sc_status full_estimate(const sc_grid_est *e, const sc_grid_data *d, est_work *w,
                               double *g, double *m, double *r, sc_error *err)
{
    sc_status st = base_estimate(e, d, w, g, m, e->free, err);
    if (st != SC_OK)
        return st;
    int nv = e->nv, ns = e->ns;
    if (e->free) {
        pack_residuals(e, w, r);
        double *rtw = w->s, *tmp = w->tmp;
        for (int v = 0; v < nv; ++v)
            tmp[v] = weighted_dot(e, e->R + 2 * (size_t)e->tot * v, r);
        for (int v = 0; v < nv; ++v) {
            double s = 0;
            for (int c = 0; c < nv; ++c)
                s += e->Mp[v * nv + c] * tmp[c];
            rtw[v] = s;
        }
        for (int v = 0; v < nv; ++v) {
            const double *gv = e->gb + 2 * (size_t)ns * v;
            for (int k = 0; k < 2 * ns; ++k)
                g[k] -= rtw[v] * gv[k];
            *m -= rtw[v] * e->mb[v];
        }
    }
    if (e->mag)
        for (int k = 0; k < ns; ++k) {
            double x, y;
            const sc_grid_plan *p = &d->plan;
            sc_grid_node_xy_mm(p, k / sc_grid_stage_nx(p), k % sc_grid_stage_nx(p), &x, &y);
            g[k] += *m * 1e-3 * x;
            g[ns + k] += *m * 1e-3 * y;
        }
    return SC_OK;
}

sc_status sc_grid_est_free_scales(const sc_grid_est *e, const sc_grid_data *d, double *s,
                                  sc_error *err)
{
    est_work w;
    sc_status st = est_work_alloc(&d->plan, &w, err);
    double *g = st == SC_OK ? malloc(sizeof(double) * (2 * (size_t)e->ns + 2 * (size_t)e->tot))
                            : NULL;
    double m;
    if (st == SC_OK && !g)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    if (st == SC_OK)
        st = full_estimate(e, d, &w, g, &m, g + 2 * e->ns, err);
    if (st == SC_OK)
        memcpy(s, w.s, sizeof(double) * (size_t)e->nv);
    free(g);
    est_work_free(&w);
    return st;
}

/* ---- the budget ---------------------------------------------------------------------------- */

/* resp (nv columns of 2·ns, mresp nv): the response of the full estimator to each view's unit
 * scale, µm (ppm) per ppm: the base responses minus the free scales' fit of them, with the
 * magnification gauge. */
static void unit_responses(const sc_grid_est *e, const sc_grid_plan *p, double *resp,
                           double *mresp)
{
    int nv = e->nv, ns = e->ns, nx = sc_grid_stage_nx(p);
    for (int v = 0; v < nv; ++v) {
        double *r = resp + 2 * (size_t)ns * v;
        memcpy(r, e->gb + 2 * (size_t)ns * v, sizeof(double) * 2 * (size_t)ns);
        mresp[v] = e->mb[v];
        for (int a = 0; e->free && a < nv; ++a) { /* s(b_v) = Mp·M·e_v */
            double sa = 0;
            for (int c = 0; c < nv; ++c)
                sa += e->Mp[a * nv + c] * e->M[c * nv + v];
            const double *ga = e->gb + 2 * (size_t)ns * a;
            for (int k = 0; k < 2 * ns; ++k)
                r[k] -= sa * ga[k];
            mresp[v] -= sa * e->mb[a];
        }
        for (int k = 0; e->mag && k < ns; ++k) {
            double x, y;
            sc_grid_node_xy_mm(p, k / nx, k % nx, &x, &y);
            r[k] += mresp[v] * 1e-3 * x;
            r[ns + k] += mresp[v] * 1e-3 * y;
        }
    }
}

/* The noise part of u(G) and u(M) added by the magnification gauge and the free scales (σ0²
 * times): per node var_x, var_y (added to the plan's), *var_m. */
static int noise_extra(const sc_grid_est *e, const sc_grid_plan *p, double *var_x, double *var_y,
                       double *var_m)
{
    int ns = e->ns, nv = e->nv, nx = sc_grid_stage_nx(p);
    double vm = 0;
    double *cx = calloc(2 * (size_t)ns + 2 * (size_t)ns * nv, sizeof(double));
    if (!cx)
        return -1;
    double *cy = cx + ns, *th = cx + 2 * ns;
    memset(var_x, 0, sizeof(double) * (size_t)ns);
    memset(var_y, 0, sizeof(double) * (size_t)ns);
    if (e->mag && sc_grid_lsq_plate_magnification(e->q, &vm, cx, cy) != 0) {
        free(cx);
        return -1;
    }
    for (int k = 0; e->mag && k < ns; ++k) {
        double x, y;
        sc_grid_node_xy_mm(p, k / nx, k % nx, &x, &y);
        var_x[k] = x * x * 1e-6 * vm + 2 * x * 1e-3 * cx[k];
        var_y[k] = y * y * 1e-6 * vm + 2 * y * 1e-3 * cy[k];
    }
    for (int v = 0; e->free && v < nv; ++v) { /* Θ: the base responses with the gauge change */
        double *t = th + 2 * (size_t)ns * v;
        memcpy(t, e->gb + 2 * (size_t)ns * v, sizeof(double) * 2 * (size_t)ns);
        for (int k = 0; e->mag && k < ns; ++k) {
            double x, y;
            sc_grid_node_xy_mm(p, k / nx, k % nx, &x, &y);
            t[k] += e->mb[v] * 1e-3 * x, t[ns + k] += e->mb[v] * 1e-3 * y;
        }
    }
    for (int a = 0; e->free && a < nv; ++a)
        for (int c = 0; c < nv; ++c) {
            double cv = e->Mp[a * nv + c];
            if (cv == 0)
                continue;
            const double *ta = th + 2 * (size_t)ns * a, *tc = th + 2 * (size_t)ns * c;
            for (int k = 0; k < ns; ++k) {
                var_x[k] += ta[k] * cv * tc[k];
                var_y[k] += ta[ns + k] * cv * tc[ns + k];
            }
            if (e->mag)
                vm += e->mb[a] * cv * e->mb[c];
        }
    *var_m = vm;
    free(cx);
    return 0;
}

/* Fill the budget table at the node and component of the largest combined u. */
static void budget_table(sc_grid_budget *b, const sc_grid_plan *p, const sc_grid_result *res,
                         const double *uE, const double *uA, const double *uT,
                         const double *uF, double sigma0, double noise_dof)
{
    long ns = sc_grid_stage_nodes(p), best = 0;
    int comp = 0;
    double mx = -1;
    for (long k = 0; k < ns; ++k)
        for (int c = 0; c < 2; ++c) {
            double u = c ? res->ugy_um[k] : res->ugx_um[k];
            if (u > mx)
                mx = u, best = k, comp = c;
        }
    long at = comp * ns + best;
    const sc_grid_scale *sc = &p->scale;
    double un = comp ? b->ugy_noise_um[best] : b->ugx_noise_um[best];
    b->worst_node = best, b->worst_comp = comp, b->u_c_um = mx, b->n_rows = 0;
    sc_grid_budget_row *r = b->row;
    double stated = res->stated_u ? NAN : sigma0;
    r[b->n_rows++] = (sc_grid_budget_row){"measurement noise", "um", stated,
                                          isfinite(stated) && stated > 0 ? un / stated : NAN, un,
                                          noise_dof};
    if (uF)
        r[b->n_rows++] = (sc_grid_budget_row){"free view scales (noise)", "um", stated,
                                              isfinite(stated) && stated > 0 ? uF[at] / stated
                                                                             : NAN,
                                              uF[at], noise_dof};
    if (sc->has_plate_scale)
        r[b->n_rows++] = (sc_grid_budget_row){"plate scale E", "ppm", sc->u_plate_scale_ppm,
                                              uE[at], fabs(uE[at]) * sc->u_plate_scale_ppm,
                                              INFINITY};
    if (sc->has_temps) {
        r[b->n_rows++] = (sc_grid_budget_row){"expansion coefficient A", "ppm/K",
                                              sc->u_cte_ppm_per_K, uA[at],
                                              fabs(uA[at]) * sc->u_cte_ppm_per_K, INFINITY};
        r[b->n_rows++] = (sc_grid_budget_row){"temperatures T_v", "K", sc->temp_u_K, uT[at],
                                              uT[at] * sc->temp_u_K, INFINITY};
    }
    double den = 0;
    for (int k = 0; k < b->n_rows; ++k)
        if (isfinite(r[k].dof) && r[k].contrib_um > 0)
            den += pow(r[k].contrib_um, 4) / r[k].dof;
    b->nu_eff = den > 0 ? pow(mx, 4) / den : INFINITY;
    b->k_welch = b->nu_eff < 30;
    b->k = b->k_welch ? sc_student_t_quantile(0.975, b->nu_eff) : 2.0;
    b->U_um = b->k * mx;
}

/* Per node and component: the sensitivities to E, A (signed) and the temperatures' combined
 * |c| (root sum of squares over the views), from the unit responses. */
static void sensitivities(const sc_grid_plan *p, int ns, const double *resp, double *cE,
                          double *cA, double *cT)
{
    const sc_grid_scale *sc = &p->scale;
    for (long k = 0; k < 2L * ns; ++k) {
        double e = 0, a = 0, t = 0;
        for (int v = 0; v < p->n_views; ++v) {
            double r = resp[2 * (size_t)ns * v + k];
            e -= r; /* a larger E or T takes more off the data: ∂G/∂E = −Σ_v resp_v */
            if (sc->has_temps) {
                a -= (p->view[v].temp_C - SC_GRID_REF_TEMP_C) * r;
                t += sc->cte_ppm_per_K * sc->cte_ppm_per_K * r * r;
            }
        }
        cE[k] = e, cA[k] = a, cT[k] = sqrt(t);
    }
}

sc_status sc_grid_budget_fill(const sc_grid_est *e, const sc_grid_plan *p, double noise_dof,
                              sc_grid_result *res, sc_grid_budget *b, sc_error *err)
{
    int ns = e->ns, nv = e->nv;
    const sc_grid_scale *sc = &p->scale;
    size_t nres = 2 * (size_t)ns * nv + (size_t)nv + 6 * (size_t)ns;
    double *resp = malloc(sizeof(double) * nres);
    if (!resp)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    double *mresp = resp + 2 * (size_t)ns * nv, *cE = mresp + nv, *cA = cE + 2 * ns;
    double *cT = cA + 2 * ns, vm = 0;
    unit_responses(e, p, resp, mresp);
    sensitivities(p, ns, resp, cE, cA, cT);
    double *ex = b->ugx_noise_um, *ey = b->ugy_noise_um; /* first the extra variances */
    if (noise_extra(e, p, ex, ey, &vm) != 0) {
        free(resp);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (budget)");
    }
    double sigma0 = res->sigma_r_used_um, *uF = NULL;
    if (e->free && (uF = malloc(sizeof(double) * 2 * (size_t)ns)) == NULL) {
        free(resp);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    for (int k = 0; k < ns; ++k) {
        double vx = res->ugx_um[k] * res->ugx_um[k] + sigma0 * sigma0 * ex[k];
        double vy = res->ugy_um[k] * res->ugy_um[k] + sigma0 * sigma0 * ey[k];
        ex[k] = sqrt(fmax(vx, 0)), ey[k] = sqrt(fmax(vy, 0));
        if (uF) /* the free scales' share, for the table: what they add to the plan's σ */
            uF[k] = sqrt(fmax(vx - res->ugx_um[k] * res->ugx_um[k], 0)),
            uF[ns + k] = sqrt(fmax(vy - res->ugy_um[k] * res->ugy_um[k], 0));
        double tx = 0, ty = 0;
        if (sc->has_plate_scale)
            tx += pow(cE[k] * sc->u_plate_scale_ppm, 2), ty += pow(cE[ns + k] * sc->u_plate_scale_ppm, 2);
        if (sc->has_temps) {
            tx += pow(cA[k] * sc->u_cte_ppm_per_K, 2) + pow(cT[k] * sc->temp_u_K, 2);
            ty += pow(cA[ns + k] * sc->u_cte_ppm_per_K, 2) + pow(cT[ns + k] * sc->temp_u_K, 2);
        }
        res->ugx_um[k] = sqrt(ex[k] * ex[k] + tx);
        res->ugy_um[k] = sqrt(ey[k] * ey[k] + ty);
    }
    if (e->mag) {
        double mE = 0, mA = 0, mT = 0;
        for (int v = 0; v < nv; ++v) {
            mE -= mresp[v];
            if (sc->has_temps)
                mA -= (p->view[v].temp_C - SC_GRID_REF_TEMP_C) * mresp[v],
                    mT += pow(sc->cte_ppm_per_K * mresp[v], 2);
        }
        double un2 = sigma0 * sigma0 * vm;
        double u2 = un2 + pow(mE * sc->u_plate_scale_ppm, 2);
        if (sc->has_temps)
            u2 += pow(mA * sc->u_cte_ppm_per_K, 2) + mT * sc->temp_u_K * sc->temp_u_K;
        b->u_magnification_noise_ppm = sqrt(un2);
        b->u_magnification_ppm = sqrt(u2);
    }
    budget_table(b, p, res, cE, cA, cT, uF, sigma0, noise_dof);
    free(uF);
    free(resp);
    return SC_OK;
}

/* ---- Monte Carlo ---------------------------------------------------------------------------- */

typedef struct mc_job {
    const sc_grid_data *base;   /* the data as measured, outliers removed (NaN) */
    const sc_grid_options *o;
    const sc_grid_solution *s;
    const sc_grid_est *shared; /* its free-scale tables (read only) */
    double *out;                /* trials x (2 ns + 1): G, then M */
    long first, last;           /* trials [first, last) */
    uint64_t seed;
    const double *sigma;        /* per coordinate (2·tot): the noise's standard deviation */
    sc_status st;
    sc_error err;
} mc_job;

/* A trial's inputs: noise on every coordinate, E, A and every T drawn, the data brought to the
 * drawn plate. */
static void mc_draw(const mc_job *j, sc_rng *rng, sc_grid_data *d, double *s)
{
    const sc_grid_plan *p = &j->base->plan;
    const sc_grid_scale *sc = &p->scale;
    int nv = p->n_views, nn = p->n * p->n;
    long tot = (long)nv * nn;
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k) {
            double x = j->base->dx_um[v][k], y = j->base->dy_um[v][k];
            if (!isfinite(x)) {
                d->dx_um[v][k] = d->dy_um[v][k] = NAN;
                continue;
            }
            d->dx_um[v][k] = x + j->sigma[v * nn + k] * sc_rng_normal(rng);
            d->dy_um[v][k] = y + j->sigma[tot + v * nn + k] * sc_rng_normal(rng);
        }
    double E = sc->has_plate_scale ? sc->plate_scale_ppm + sc->u_plate_scale_ppm * sc_rng_normal(rng)
                                   : 0.0;
    double A = sc->has_temps ? sc->cte_ppm_per_K + sc->u_cte_ppm_per_K * sc_rng_normal(rng) : 0.0;
    for (int v = 0; v < nv; ++v) {
        double T = sc->has_temps ? p->view[v].temp_C + sc->temp_u_K * sc_rng_normal(rng) : 0.0;
        s[v] = E + (sc->has_temps ? A * (T - SC_GRID_REF_TEMP_C) : 0.0);
    }
    sc_grid_scale_subtract(d, s);
}

static void *mc_thread(void *arg)
{
    mc_job *j = arg;
    const sc_grid_plan *p = &j->base->plan;
    sc_grid_est e;
    est_work w;
    sc_grid_data d;
    memset(&w, 0, sizeof w);
    memset(&d, 0, sizeof d);
    memset(&e, 0, sizeof e);
    sc_grid_lsq_opts opts = {0};
    opts.node_sigma_only = 1;
    opts.max_bytes = j->o->max_bytes;
    sc_error_clear(&j->err);
    j->st = sc_grid_est_make(j->base, &opts, j->shared->mag, 0, &e, &j->err);
    if (j->st == SC_OK) { /* the free-scale tables are the same for every thread: borrowed */
        e.free = j->shared->free, e.R = j->shared->R, e.M = j->shared->M, e.Mp = j->shared->Mp;
        memcpy(e.gb, j->shared->gb, sizeof(double) * 2 * (size_t)e.ns * e.nv);
        memcpy(e.mb, j->shared->mb, sizeof(double) * e.nv);
        j->st = est_work_alloc(p, &w, &j->err);
    }
    if (j->st == SC_OK)
        j->st = sc_grid_data_copy_values(j->base, &d, &j->err);
    double *r = j->st == SC_OK ? malloc(sizeof(double) * 2 * (size_t)e.tot) : NULL;
    if (j->st == SC_OK && !r)
        j->st = sc_error_set(&j->err, SC_E_NOMEM, NULL, 0, "out of memory");
    size_t stride = 2 * (size_t)e.ns + 1;
    for (long t = j->first; j->st == SC_OK && t < j->last; ++t) {
        sc_rng rng;
        sc_rng_seed(&rng, j->seed + 0x9E3779B97F4A7C15ull * (uint64_t)(t + 1));
        mc_draw(j, &rng, &d, w.tmp);
        double *g = j->out + stride * (size_t)t;
        j->st = full_estimate(&e, &d, &w, g, &g[2 * e.ns], r, &j->err);
    }
    free(r);
    sc_grid_data_copy_free(&d);
    est_work_free(&w);
    e.R = e.M = e.Mp = NULL; /* borrowed */
    sc_grid_est_free(&e);
    return NULL;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

void sc_grid_mc_free(sc_grid_mc *mc)
{
    free(mc->ugx_um);
    memset(mc, 0, sizeof *mc);
}

/* Standard deviations, ratios and coverage intervals of the trials in out. */
static sc_status mc_statistics(const sc_grid_solution *s, int ns, long trials, const double *out,
                               sc_grid_mc *mc, sc_error *err)
{
    double *buf = malloc(sizeof(double) * 8 * (size_t)ns), *col = malloc(sizeof(double) * trials);
    if (!buf || !col) {
        free(buf), free(col);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    mc->ugx_um = buf, mc->ugy_um = buf + ns, mc->ratio_x = buf + 2 * ns;
    mc->ratio_y = buf + 3 * ns, mc->gx_lo_um = buf + 4 * ns, mc->gx_hi_um = buf + 5 * ns;
    mc->gy_lo_um = buf + 6 * ns, mc->gy_hi_um = buf + 7 * ns;
    size_t stride = 2 * (size_t)ns + 1;
    double rmin = INFINITY, rmax = -INFINITY, rsum = 0;
    long rn = 0;
    for (long k = 0; k <= 2L * ns; ++k) {
        double mean = 0, ss = 0;
        for (long t = 0; t < trials; ++t)
            mean += out[stride * t + k];
        mean /= (double)trials;
        for (long t = 0; t < trials; ++t) {
            double dv = out[stride * t + k] - mean;
            ss += dv * dv;
            col[t] = out[stride * t + k];
        }
        double sd = trials > 1 ? sqrt(ss / (double)(trials - 1)) : NAN;
        if (k == 2L * ns) {
            mc->magnification_sd_ppm = s->budget.magnification ? sd : NAN;
            break;
        }
        qsort(col, (size_t)trials, sizeof(double), cmp_double);
        long lo = (long)floor(0.025 * (double)trials), hi = (long)ceil(0.975 * (double)trials) - 1;
        lo = lo < 0 ? 0 : lo, hi = hi >= trials ? trials - 1 : hi;
        int y = k >= ns;
        long node = y ? k - ns : k;
        double ub = y ? s->res.ugy_um[node] : s->res.ugx_um[node];
        (y ? mc->ugy_um : mc->ugx_um)[node] = sd;
        (y ? mc->gy_lo_um : mc->gx_lo_um)[node] = col[lo];
        (y ? mc->gy_hi_um : mc->gx_hi_um)[node] = col[hi];
        double ratio = ub > 0 ? sd / ub : NAN;
        (y ? mc->ratio_y : mc->ratio_x)[node] = ratio;
        if (isfinite(ratio))
            rmin = fmin(rmin, ratio), rmax = fmax(rmax, ratio), rsum += ratio, ++rn;
    }
    mc->ratio_min = rn ? rmin : NAN, mc->ratio_max = rn ? rmax : NAN;
    mc->ratio_mean = rn ? rsum / (double)rn : NAN;
    free(col);
    return SC_OK;
}

/* The noise's standard deviation of every coordinate as the budget takes it. */
static void mc_sigmas(const sc_grid_data *d, const sc_grid_solution *s, double *sig)
{
    const sc_grid_plan *p = &d->plan;
    int nn = p->n * p->n;
    long tot = (long)p->n_views * nn;
    for (int v = 0; v < p->n_views; ++v)
        for (int k = 0; k < nn; ++k)
            for (int c = 0; c < 2; ++c) {
                double u = s->res.stated_u ? sc_grid_data_u_um(d, v, k, c) : NAN;
                if (s->res.view_noise_estimated && isfinite(s->res.view_sigma_um[v]))
                    u = s->res.view_sigma_um[v];
                sig[c * tot + v * nn + k] = isfinite(u) ? u : s->res.sigma_r_used_um;
            }
}

sc_status sc_grid_mc_run(const sc_grid_data *base, const sc_grid_options *o,
                         const sc_grid_solution *s, const sc_grid_est *shared, long trials,
                         uint64_t seed, int threads, sc_grid_mc *mc, sc_error *err)
{
    memset(mc, 0, sizeof *mc);
    const sc_grid_plan *p = &base->plan;
    int ns = (int)sc_grid_stage_nodes(p);
    long tot = (long)p->n * p->n * p->n_views;
    size_t stride = 2 * (size_t)ns + 1;
    if (o->max_bytes > 0 && (double)trials * (double)stride * 8.0 > o->max_bytes)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0,
                            "the Monte Carlo's %ld trials of %d nodes need %.0f MiB (more than "
                            "the memory limit)",
                            trials, ns, (double)trials * (double)stride * 8.0 / 1048576.0);
    double *out = malloc(sizeof(double) * stride * (size_t)trials);
    double *sig = malloc(sizeof(double) * 2 * (size_t)tot);
    if (!out || !sig) {
        free(out), free(sig);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (Monte Carlo)");
    }
    mc_sigmas(base, s, sig);
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    int nt = threads > 0 ? threads : (cpus >= 2 ? 2 : 1);
    nt = nt > trials ? (int)trials : nt;
    nt = nt < 1 ? 1 : nt > 2 ? 2 : nt;
    mc_job jobs[2];
    pthread_t tid[2];
    int started[2] = {0, 0};
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int t = 0; t < nt; ++t) {
        jobs[t] = (mc_job){base, o, s, shared, out, trials * t / nt, trials * (t + 1) / nt,
                           seed, sig, SC_OK, {0}};
        if (t > 0 && pthread_create(&tid[t], NULL, mc_thread, &jobs[t]) == 0)
            started[t] = 1;
    }
    if (nt > 1 && !started[1]) /* no second thread: this one does all */
        jobs[0].last = trials, nt = 1;
    mc_thread(&jobs[0]);
    if (nt > 1)
        pthread_join(tid[1], NULL);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    sc_status st = SC_OK;
    for (int t = 0; t < nt && st == SC_OK; ++t)
        if ((st = jobs[t].st) != SC_OK && err)
            *err = jobs[t].err;
    mc->trials = trials, mc->seed = seed, mc->threads = nt;
    mc->seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    if (st == SC_OK)
        st = mc_statistics(s, ns, trials, out, mc, err);
    free(out), free(sig);
    return st;
}
