/* Optimal least-squares grid self-calibration for any view plan (docs/grid-lsq.md).
 *
 * Unknowns: G (2 per node), A (2 per measured mark), (tx, ty, φ) per view with φ = θ·L·1e-3 µm
 * (L = c·P, so the rotation column is scaled like the others). Each scalar equation touches one
 * G component, one A component (coefficient ±1) and its view's misalignment.
 *
 * 1. A is eliminated exactly: its block of the normal matrix is diagonal (the number of views
 *    measuring the mark); per A component the equations form a group and elimination centres
 *    the group. What is left is S x = b on x = (g, m).
 * 2. The 7-dimensional gauge null space of S (G translation/rotation/magnification, plate
 *    translation/rotation seen through the misalignments) is removed by pinning: both components
 *    of G at two distinct measured nodes and the misalignment of one view are fixed at 0. The
 *    pinned matrix is S with those rows/columns replaced by identity rows; it is nonsingular iff
 *    the plan identifies G (and every view's misalignment). The G of the pinned solution differs
 *    from the gauged one by a gauge pattern, so G = P⊥ g_pin (P⊥ the orthogonal projector of
 *    sc_grid_gauge_stage), exactly.
 * 3. The pinned matrix is factored once per plan (sparse_sym.h: CHOLMOD's supernodal Cholesky in
 *    the order of AMD with the free misalignments last; a rank-revealing LDLᵀ
 *    when it is numerically singular); null pivots are decided with a relative tolerance.
 * 4. Everything that does not depend on the measured values is computed by the plan: per-node
 *    variances Cov(G)/σ² = P⊥ Σ P⊥ with Σ = pinned inverse (zero on pins), diag(Σ) by the
 *    supernodal selected inverse and the projection from W = ΣU (4 columns); the leverage of every
 *    equation (the selected inverse on S's pattern and the free misalignments' whole columns of
 *    Σ, which the same selected inverse gives); the variances of O, R and the misalignments per
 *    unit σ (W, 5 more columns, the misalignment columns; left out with node_sigma_only). Two
 *    blocked solves: W (4 columns), then the 5 functional ones.
 * 5. Execute: one solve refined against the equations (up to 3 steps), the gauge, the residual
 *    sums; no allocation (the plan holds the workspace, so one plan serves one thread at a time).
 */
#include "selfcal/grid_lsq.h"

#include <float.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/big_alloc.h"
#include "grid_lsq_internal.h"
#include "selfcal/grid_sim.h"
#include "sparse_sym.h"

#define LSQ_PIVOT_TOL 1e-9 /* pivot / original diagonal below this: null */
#define LSQ_SMALL_TOL 1e-11 /* relative tolerance of the small dense rank decision */
#define LSQ_NOMEM_MSG "out of memory building the least-squares system"

struct sc_grid_lsq_plan {
    sc_grid_plan plan;
    int n, nn, nv;          /* plate N, its N² marks, views */
    int stage_nx, stage_ny, ns; /* stage grid NX, NY and its node count */
    int nb;                 /* unknowns per view: tx, ty, φ (+ vx, vy with drift) */
    int drift;
    int node_sigma_only;    /* no σ of O, R and the misalignments (sc_grid_lsq_opts) */
    double max_bytes;       /* > 0: refuse a plan estimated to need more (sc_grid_lsq_opts) */
    sc_grid_progress_fn progress; /* sc_grid_lsq_opts' (NULL: none) */
    void *progress_ctx;
    double peak_est;        /* the peak memory estimated so far, bytes (0: not yet) */
    double work_total;      /* multiply-adds of the factor and selected inverse (0: not known) */
    int weighted;           /* weights were stated (1/u²); else all 1 */
    int unit_weights;       /* sc_grid_lsq_opts.unit_weights: stated weights ignored */
    double *eq_w;           /* weight of each scalar equation */
    double *eq_dt;          /* drift column: (t - mean t of the view) / T_v */
    /* per view (nv each, one block: view_block; plan_init) */
    double *drift_T;        /* T_v: the scale of each view's drift column, s */
    double *drift_t0;       /* mean time of each view's measurements, s */
    unsigned char *view_free; /* a view that leaves its own columns free */
    double *view_block;
    double *fit_work;       /* fit_misalignments' nb x nb normal matrix and nb right-hand side
                               per view: nv (nb² + nb) doubles, then mis_work */
    double *mis_work;       /* residuals' and view components' misalignments and counts:
                               nm + nv doubles (so that they allocate nothing) */
    double L_mm;            /* rotation scale c·P */
    double r2_mm2;          /* Σ x² + y² over the stage nodes (gauge basis, O and R functionals) */
    unsigned char *meas;    /* nv*nn: view v measures mark k */
    int *mark_views;        /* per mark: number of views measuring it */
    long n_meas_marks;
    long neq;               /* scalar equations */
    int *eq_g, *eq_v, *eq_k, *eq_a;
    unsigned char *eq_c;    /* 0: dx, 1: dy */
    signed char *eq_s;      /* sign of the A component */
    double *eq_pos;         /* coefficient of φ */
    long *grp_ptr;          /* equations of each A component (2*nn groups) */
    long *grp_eq;
    int ng, nm;             /* G unknowns (2 per stage node), misalignment unknowns (nb per view) */
    int n_red;              /* unknowns of the reduced system: ng + nm */
    long *Ap;               /* the pinned reduced matrix: upper CSC, original index space */
    int *Ai;
    double *Ax;
    sc_spsym *f;            /* its factorization (sparse_sym.h) */
    unsigned char *pinned;  /* per unknown (original index) */
    int pin_node[2], pin_view;
    int nullity_pin, nullity_T;
    sc_grid_lsq_info info;
    long rank;
    /* what does not depend on the measured values, computed by the plan (per unit σ) */
    double *sgx, *sgy;      /* std/σ_r per node (NaN if not identified) */
    double *eq_h;           /* leverage of each equation */
    double var_O, var_R;    /* Var(O)/σ0², Var(R)/σ0² (NaN if not computed) */
    double *var_m;          /* nm: Var(misalignment unknown)/σ0² (NaN where not unique) */
    int misalignment_unique;    /* every view's misalignment determined (nullity_T = 3) */
    /* the misalignments free beyond the gauge are only views' own (a view of one mark: its
     * rotation; of none: all): the others are estimable, with uncertainties */
    int misalignment_estimable;
    double *work;           /* execute's workspace: 4 n_red + ng + 2 nn + nm doubles */
    size_t bytes;
};

/* Tell the caller's progress function (if any) the phase and the work done so far. */
static void progress(const sc_grid_lsq_plan *q, const char *phase, double done)
{
    if (q->progress)
        q->progress(q->progress_ctx, phase, done, q->work_total, q->peak_est);
}

/* The A component and sign a scalar equation (c = 0: dx, 1: dy) of a view rotated rot touches. */
static void rot_component(int rot, int c, int *acomp, int *sign)
{
    switch (rot) {
    case 90: *acomp = c ? 0 : 1; *sign = c ? 1 : -1; break;
    case 180: *acomp = c; *sign = -1; break;
    case 270: *acomp = c ? 0 : 1; *sign = c ? -1 : 1; break;
    default: *acomp = c; *sign = 1; break;
    }
}

void sc_grid_lsq_plan_destroy(sc_grid_lsq_plan *q)
{
    if (!q)
        return;
    free(q->meas), free(q->mark_views), free(q->eq_g), free(q->eq_v), free(q->eq_k);
    free(q->eq_a), free(q->eq_c), free(q->eq_s), free(q->eq_pos), free(q->grp_ptr);
    free(q->grp_eq), free(q->Ap), free(q->Ai), free(q->Ax);
    free(q->pinned), free(q->sgx), free(q->sgy), free(q->work), free(q->eq_h), free(q->var_m);
    free(q->eq_w), free(q->eq_dt);
    free(q->view_block), free(q->fit_work);
    sc_grid_plan_free(&q->plan);
    sc_spsym_destroy(q->f);
    free(q);
}

/* Numerical rank deficiency of a small dense symmetric PSD matrix (m x m, destroyed) by
 * Cholesky with diagonal pivoting; pivots below tol·(largest diagonal) end it. */
static int small_nullity(double *a, int m, double tol)
{
    double dmax = 0;
    for (int i = 0; i < m; ++i)
        if (a[i * m + i] > dmax)
            dmax = a[i * m + i];
    if (!(dmax > 0))
        return m;
    /* a view's misalignment fit (m <= 5) allocates nothing */
    int small[16], *piv = m <= 16 ? small : malloc(sizeof(int) * (size_t)m);
    if (!piv)
        return -1;
    for (int i = 0; i < m; ++i)
        piv[i] = i;
    int r = 0;
    for (; r < m; ++r) {
        int best = r;
        for (int i = r; i < m; ++i)
            if (a[piv[i] * m + piv[i]] > a[piv[best] * m + piv[best]])
                best = i;
        int t = piv[r];
        piv[r] = piv[best];
        piv[best] = t;
        int p = piv[r];
        double d = a[p * m + p];
        if (!(d > tol * dmax))
            break;
        for (int i = r + 1; i < m; ++i) {
            int pi = piv[i];
            double l = a[pi * m + p] / d;
            for (int j = r + 1; j < m; ++j) {
                int pj = piv[j];
                a[pi * m + pj] -= l * a[p * m + pj];
            }
        }
    }
    if (piv != small)
        free(piv);
    return m - r;
}

#define ROW_MAX 4 /* entries of one equation's row */

/* Coefficients of w_e = s_e·J_e over x = (g, m): 3 (index, value) pairs, 4 with drift. */
static int eq_row(const sc_grid_lsq_plan *q, long e, int *idx, double *val)
{
    double s = q->eq_s[e];
    int base = q->ng + q->nb * q->eq_v[e];
    idx[0] = q->eq_g[e];
    val[0] = s;
    idx[1] = base + q->eq_c[e];
    val[1] = s;
    idx[2] = base + 2;
    val[2] = s * q->eq_pos[e];
    if (!q->drift)
        return 3;
    idx[3] = base + 3 + q->eq_c[e];
    val[3] = s * q->eq_dt[e];
    return 4;
}

/* Weight of equation e's coordinate from the mask's stated uncertainties (1 when none). */
static double mask_weight(const sc_grid_lsq_plan *q, const sc_grid_data *mask, int v, int k, int c)
{
    if (q->unit_weights)
        return 1.0;
    double u = mask ? sc_grid_data_u_um(mask, v, k, c) : q->plan.view[v].sigma_um;
    return u > 0 ? 1.0 / (u * u) : 1.0;
}

/* Per view: the drift column (t - mean)/T from the mask's times, or (plan without data) from
 * the order of measurement (serpentine plate order, one per second, as the simulator). */
static sc_status build_drift(sc_grid_lsq_plan *q, const sc_grid_data *mask, sc_error *err)
{
    for (int v = 0; v < q->nv; ++v) {
        double sum = 0, cnt = 0;
        if (mask && !mask->t_s[v])
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "drift needs the time of each measurement (column t_s)");
        for (long e = 0; e < q->neq; ++e) {
            if (q->eq_v[e] != v)
                continue;
            double t = mask ? mask->t_s[v][q->eq_k[e]]
                            : (double)sc_grid_serpentine_index(q->n, q->eq_k[e]);
            if (!isfinite(t))
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "view %d mark (%d,%d): no time (t_s) for the drift model", v,
                                    q->eq_k[e] / q->n, q->eq_k[e] % q->n);
            q->eq_dt[e] = t;
            sum += t, cnt += 1;
        }
        double mean = cnt > 0 ? sum / cnt : 0, T = 0;
        q->drift_t0[v] = mean;
        for (long e = 0; e < q->neq; ++e)
            if (q->eq_v[e] == v) {
                q->eq_dt[e] -= mean;
                T = fmax(T, fabs(q->eq_dt[e]));
            }
        if (cnt == 0) { /* a view without measurements: nothing to scale (its columns free) */
            q->drift_T[v] = 1;
            continue;
        }
        if (!(T > 0))
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "view %d: all its measurements have the same time, its drift "
                                "cannot be estimated",
                                v);
        q->drift_T[v] = T;
        for (long e = 0; e < q->neq; ++e)
            if (q->eq_v[e] == v)
                q->eq_dt[e] /= T;
    }
    return SC_OK;
}

/* 1 if the data (or, without data, the plan's views) state uncertainties. */
static int stated_weights(const sc_grid_lsq_plan *q, const sc_grid_data *mask)
{
    for (int v = 0; v < q->nv; ++v) {
        if (mask && (mask->ux_um[v] || mask->uy_um[v] || mask->plan.view[v].sigma_um > 0))
            return 1;
        if (!mask && q->plan.view[v].sigma_um > 0)
            return 1;
    }
    return 0;
}

/* Which marks each view measures (q->meas, q->mark_views): the plan's, or the mask's finite
 * values; the number of equations. */
static sc_status measured_marks(sc_grid_lsq_plan *q, const sc_grid_data *mask, sc_error *err)
{
    const sc_grid_plan *p = &q->plan;
    int n = q->n, nn = q->nn, nv = q->nv;
    q->meas = calloc((size_t)nv * nn, 1);
    q->mark_views = calloc((size_t)nn, sizeof(int));
    if (!q->meas || !q->mark_views)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k) {
            int i = k / n, j = k % n, m;
            if (!mask) {
                m = sc_grid_view_measures(p, v, i, j);
            } else {
                const double *dx = mask->dx_um[v], *dy = mask->dy_um[v];
                int fx = dx && isfinite(dx[k]), fy = dy && isfinite(dy[k]);
                if (fx != fy)
                    return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                        "view %d mark (%d,%d): only one of dx, dy is given", v, i,
                                        j);
                int ni, nj;
                if (fx && !sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                        "view %d mark (%d,%d): measured but off the stage grid", v,
                                        i, j);
                m = fx;
            }
            q->meas[v * nn + k] = (unsigned char)m;
            q->mark_views[k] += m;
        }
    long npairs = 0;
    for (int k = 0; k < nn; ++k) {
        npairs += q->mark_views[k];
        q->n_meas_marks += q->mark_views[k] > 0;
    }
    q->neq = 2 * npairs;
    return SC_OK;
}

/* The scalar equations (2 per measured mark): node, view, mark, A component and sign, the φ
 * coefficient, weight; grouped by A component; the drift columns. */
static sc_status build_equations(sc_grid_lsq_plan *q, const sc_grid_data *mask, sc_error *err)
{
    const sc_grid_plan *p = &q->plan;
    int n = q->n, nn = q->nn, nv = q->nv;
    q->weighted = !q->unit_weights && stated_weights(q, mask);
    sc_status st = measured_marks(q, mask, err);
    if (st != SC_OK)
        return st;
    long ne = q->neq + 1;
    q->eq_g = malloc(sizeof(int) * ne);
    q->eq_v = malloc(sizeof(int) * ne);
    q->eq_k = malloc(sizeof(int) * ne);
    q->eq_a = malloc(sizeof(int) * ne);
    q->eq_c = malloc(ne);
    q->eq_s = malloc(ne);
    q->eq_pos = malloc(sizeof(double) * ne);
    q->grp_ptr = calloc((size_t)2 * nn + 1, sizeof(long));
    q->grp_eq = malloc(sizeof(long) * ne);
    q->eq_w = malloc(sizeof(double) * ne);
    q->eq_dt = calloc((size_t)ne, sizeof(double));
    if (!q->eq_g || !q->eq_v || !q->eq_k || !q->eq_a || !q->eq_c || !q->eq_s || !q->eq_pos ||
        !q->grp_ptr || !q->grp_eq || !q->eq_w || !q->eq_dt)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    long e = 0;
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k) {
            if (!q->meas[v * nn + k])
                continue;
            int ni, nj;
            sc_grid_mark_node(p, v, k / n, k % n, &ni, &nj);
            int node = ni * q->stage_nx + nj;
            double x, y;
            sc_grid_node_xy_mm(p, ni, nj, &x, &y);
            for (int c = 0; c < 2; ++c, ++e) {
                double u = mask ? sc_grid_data_u_um(mask, v, k, c) : NAN;
                if (!isnan(u) && !(u > 0 && isfinite(u))) /* the reader refuses these too */
                    return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                        "view %d mark (%d,%d): the %s uncertainty %g um is not "
                                        "positive and finite", v, k / n, k % n, c ? "y" : "x", u);
                q->eq_w[e] = mask_weight(q, mask, v, k, c);
                int ac, s;
                rot_component(p->view[v].rot_deg, c, &ac, &s);
                q->eq_g[e] = 2 * node + c;
                q->eq_v[e] = v;
                q->eq_k[e] = k;
                q->eq_a[e] = 2 * k + ac;
                q->eq_c[e] = (unsigned char)c;
                q->eq_s[e] = (signed char)s;
                q->eq_pos[e] = c == 0 ? -y / q->L_mm : x / q->L_mm;
                q->grp_ptr[q->eq_a[e] + 1]++;
            }
        }
    for (int a = 0; a < 2 * nn; ++a)
        q->grp_ptr[a + 1] += q->grp_ptr[a];
    long *fill = malloc(sizeof(long) * (size_t)(2 * nn));
    if (!fill)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    memcpy(fill, q->grp_ptr, sizeof(long) * (size_t)(2 * nn));
    for (e = 0; e < q->neq; ++e)
        q->grp_eq[fill[q->eq_a[e]]++] = e;
    free(fill);
    return q->drift ? build_drift(q, mask, err) : SC_OK;
}

/* Pins: both G components of two far-apart nodes that equations touch, and one view's
 * misalignment (the view with the most measurements). */
static sc_status choose_pins(sc_grid_lsq_plan *q, sc_error *err)
{
    int stage_nx = q->stage_nx;
    int *seen = calloc((size_t)q->ns, sizeof(int));
    int best_lo = -1, best_hi = -1, lo = 1 << 30, hi = -1;
    if (!seen) /* reported, not skipped: pins chosen blind would change the solution's gauge */
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (long e = 0; e < q->neq; ++e)
        seen[q->eq_g[e] / 2] = 1;
    for (int k = 0; k < q->ns; ++k) {
        if (!seen[k])
            continue;
        int s = k / stage_nx + k % stage_nx;
        if (s < lo)
            lo = s, best_lo = k;
        if (s > hi)
            hi = s, best_hi = k;
    }
    free(seen);
    if (best_lo < 0 || best_hi == best_lo) /* at most one node measured: no useful pin */
        best_lo = 0, best_hi = q->ns - 1;
    q->pin_node[0] = best_lo;
    q->pin_node[1] = best_hi;
    int bestv = 0;
    long bestc = -1;
    for (int v = 0; v < q->nv; ++v) {
        long c = 0;
        for (int k = 0; k < q->nn; ++k)
            c += q->meas[v * q->nn + k];
        if (c > bestc)
            bestc = c, bestv = v;
    }
    q->pin_view = bestv;
    for (int t = 0; t < 2; ++t) {
        q->pinned[2 * q->pin_node[t]] = 1;
        q->pinned[2 * q->pin_node[t] + 1] = 1;
    }
    for (int t = 0; t < 3; ++t)
        q->pinned[q->ng + q->nb * bestv + t] = 1;
    return SC_OK;
}

/* The group eliminations: per A component seen at least twice, Σ w_e r_e r_eᵀ − (Σ w_e r_e)
 * (Σ w_e r_e)ᵀ / Σ w_e over its equations' rows r_e. Here the entries with a misalignment:
 * G-misalignment to gm (ng x nm), misalignment pairs to mm (nm x nm); the G block is
 * g_block_cols. */
static sc_status assemble_groups(const sc_grid_lsq_plan *q, double *gm, double *mm)
{
    int ng = q->ng, nm = q->nm, maxg = 0;
    for (int a = 0; a < 2 * q->nn; ++a)
        if (q->grp_ptr[a + 1] - q->grp_ptr[a] > maxg)
            maxg = (int)(q->grp_ptr[a + 1] - q->grp_ptr[a]);
    size_t cap = (size_t)ROW_MAX * maxg + 1;
    int *li = malloc(sizeof(int) * cap), *lo = malloc(sizeof(int) * cap);
    double *lv = malloc(sizeof(double) * cap), *lw = malloc(sizeof(double) * cap);
    if (!li || !lv || !lw || !lo) {
        free(li), free(lv), free(lw), free(lo);
        return SC_E_NOMEM;
    }
    for (int a = 0; a < 2 * q->nn; ++a) {
        long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
        if (cnt < 2)
            continue; /* a mark seen once: its A absorbs the equation */
        int len = 0;
        double W = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            int l = eq_row(q, e, li + len, lv + len);
            for (int r = 0; r < l; ++r)
                lw[len + r] = q->eq_w[e], lo[len + r] = (int)t;
            len += l;
            W += q->eq_w[e];
        }
        for (int x = 0; x < len; ++x) {
            int i = li[x];
            for (int y = 0; y < len; ++y) {
                int j = li[y];
                if (j < ng) /* G-G (g_block_cols), or the transposed G-misalignment pair */
                    continue;
                double v = (lo[x] == lo[y] ? lw[x] : 0.0) - lw[x] * lw[y] / W;
                v *= lv[x] * lv[y];
                if (i < ng)
                    gm[(size_t)i * nm + (j - ng)] += v;
                else
                    mm[(size_t)(i - ng) * nm + (j - ng)] += v;
            }
        }
    }
    free(li), free(lv), free(lw), free(lo);
    return SC_OK;
}

/* The G block of the pinned reduced matrix as upper columns (cp, ci, cv: column j holds rows
 * i <= j, duplicates summed, pinned rows and columns left out), built column by column: every
 * equation e has one G unknown g_e (coefficient s_e), so column j gathers, over the equations e
 * at j and the equations e' of e's group, (w_e s_e² if e' = e) − w_e w_e' s_e s_e' / W at row
 * g_e'. No triplets: one dense accumulator of ng and its list of touched rows. */
static sc_status g_block_cols(const sc_grid_lsq_plan *q, long **cp_out, int **ci_out,
                              double **cv_out)
{
    int ng = q->ng, n2 = 2 * q->nn;
    long *ep = calloc((size_t)ng + 1, sizeof(long)), *cp = malloc(sizeof(long) * (ng + 1));
    long *eg = malloc(sizeof(long) * (size_t)(q->neq + 1)), bound = 0;
    double *Wg = malloc(sizeof(double) * (size_t)(n2 + 1));
    double *acc = calloc((size_t)ng + 1, sizeof(double));
    int *touched = malloc(sizeof(int) * (ng + 1)), *mark = malloc(sizeof(int) * (ng + 1));
    int *ci = NULL;
    double *cv = NULL;
    sc_status st = SC_E_NOMEM;
    if (!ep || !cp || !eg || !Wg || !acc || !touched || !mark)
        goto out;
    for (int a = 0; a < n2; ++a) {
        double W = 0;
        for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t)
            W += q->eq_w[q->grp_eq[t]];
        Wg[a] = W;
    }
    for (long e = 0; e < q->neq; ++e) { /* the equations at each G unknown */
        ep[q->eq_g[e] + 1]++;
        bound += q->grp_ptr[q->eq_a[e] + 1] - q->grp_ptr[q->eq_a[e]];
    }
    for (int j = 0; j < ng; ++j)
        ep[j + 1] += ep[j];
    memcpy(cp, ep, sizeof(long) * (size_t)ng);
    for (long e = 0; e < q->neq; ++e)
        eg[cp[q->eq_g[e]]++] = e;
    if (!(ci = malloc(sizeof(int) * (size_t)(bound + 1))) ||
        !(cv = malloc(sizeof(double) * (size_t)(bound + 1))))
        goto out;
    for (int i = 0; i < ng; ++i)
        mark[i] = -1;
    long w = 0;
    for (int j = 0; j < ng; ++j) {
        cp[j] = w;
        if (q->pinned[j])
            continue;
        int nt = 0;
        for (long p = ep[j]; p < ep[j + 1]; ++p) {
            long e = eg[p];
            int a = q->eq_a[e];
            long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
            if (cnt < 2)
                continue;
            double we = q->eq_w[e] * q->eq_s[e], W = Wg[a];
            for (long t = 0; t < cnt; ++t) {
                long e2 = q->grp_eq[g0 + t];
                int i = q->eq_g[e2];
                if (i > j || q->pinned[i])
                    continue;
                double v = -we * q->eq_w[e2] * q->eq_s[e2] / W;
                if (e2 == e)
                    v += we * q->eq_s[e];
                if (mark[i] != j) {
                    mark[i] = j;
                    acc[i] = 0;
                    touched[nt++] = i;
                }
                acc[i] += v;
            }
        }
        for (int t = 0; t < nt; ++t) {
            ci[w] = touched[t];
            cv[w++] = acc[touched[t]];
        }
    }
    cp[ng] = w;
    *cp_out = cp, *ci_out = ci, *cv_out = cv;
    cp = NULL, ci = NULL, cv = NULL;
    st = SC_OK;
out:
    free(ep), free(cp), free(eg), free(Wg), free(acc), free(touched), free(mark);
    free(ci), free(cv);
    return st;
}

/* Visit every entry (i, j, value) of the pinned reduced matrix once (i <= j for the G block, whose
 * upper columns are rp, ri, rv). */
#define FOR_EACH_ENTRY(q, rp, ri, rv, gm, mm, VISIT)                                               \
    do {                                                                                          \
        int ng_ = (q)->ng, nm_ = (q)->nm;                                                         \
        for (int j = 0; j < ng_; ++j)                                                             \
            for (long p = (rp)[j]; p < (rp)[j + 1]; ++p)                                          \
                VISIT((ri)[p], j, (rv)[p]);                                                       \
        for (int i = 0; i < ng_; ++i)                                                             \
            for (int t = 0; t < nm_; ++t)                                                         \
                if (!(q)->pinned[i] && !(q)->pinned[ng_ + t] && (gm)[(size_t)i * nm_ + t] != 0)  \
                    VISIT(i, ng_ + t, (gm)[(size_t)i * nm_ + t]);                                 \
        for (int s = 0; s < nm_; ++s)                                                             \
            for (int t = s; t < nm_; ++t)                                                         \
                if (!(q)->pinned[ng_ + s] && !(q)->pinned[ng_ + t] && (mm)[(size_t)s * nm_ + t] != 0) \
                    VISIT(ng_ + s, ng_ + t, (mm)[(size_t)s * nm_ + t]);                           \
        for (int i = 0; i < (q)->n_red; ++i)                                                      \
            if ((q)->pinned[i])                                                                   \
                VISIT(i, i, 1.0);                                                                 \
    } while (0)

/* The pinned reduced matrix q->Ap, Ai, Ax: upper CSC in the original index space, entry
 * (i, j), i <= j, in column j; pinned rows/columns replaced by identity rows. */
static sc_status assemble_matrix(sc_grid_lsq_plan *q, const long *rp, const int *ri,
                                 const double *rv, const double *gm, const double *mm)
{
    int n_red = q->n_red;
    q->Ap = calloc((size_t)n_red + 1, sizeof(long));
    if (!q->Ap)
        return SC_E_NOMEM;
    long nnz = 0;
#define COUNT(i, j, v) (q->Ap[((i) > (j) ? (i) : (j)) + 1]++, nnz++)
    FOR_EACH_ENTRY(q, rp, ri, rv, gm, mm, COUNT);
#undef COUNT
    for (int k = 0; k < n_red; ++k)
        q->Ap[k + 1] += q->Ap[k];
    q->Ai = sc_big_alloc((size_t)(nnz + 1), sizeof(int), 0);
    q->Ax = sc_big_alloc((size_t)(nnz + 1), sizeof(double), 0);
    long *fill = malloc(sizeof(long) * (size_t)(n_red + 1));
    if (!q->Ai || !q->Ax || !fill) {
        free(fill);
        return SC_E_NOMEM;
    }
    memcpy(fill, q->Ap, sizeof(long) * (size_t)n_red);
#define PUT(i, j, v)                                                                              \
    do {                                                                                          \
        long at_ = fill[(i) > (j) ? (i) : (j)]++;                                                 \
        q->Ai[at_] = (i) > (j) ? (j) : (i);                                                       \
        q->Ax[at_] = (v);                                                                         \
    } while (0)
    FOR_EACH_ENTRY(q, rp, ri, rv, gm, mm, PUT);
#undef PUT
    free(fill);
    q->bytes += (size_t)nnz * (sizeof(int) + sizeof(double)) + (size_t)(n_red + 1) * sizeof(long);
    return SC_OK;
}

/* The free (unpinned) misalignment unknowns: their original indices into at (ascending; may be
 * NULL), and into slot each misalignment's place among them, which is its whole column's in the
 * selected inverse (-1 pinned; may be NULL); their count. */
static int free_misalignments(const sc_grid_lsq_plan *q, int *at, int *slot)
{
    int k = 0;
    for (int t = 0; t < q->nm; ++t) {
        int free_t = !q->pinned[q->ng + t];
        if (slot)
            slot[t] = free_t ? k : -1;
        if (free_t && at)
            at[k] = q->ng + t;
        k += free_t;
    }
    return k;
}

/* Order (once) and factor the pinned reduced matrix; the pinned system's nullity. */
double sc_memory_available_bytes(void)
{
    FILE *fp = fopen("/proc/meminfo", "r");
    char line[256];
    double kib = -1;
    while (fp && fgets(line, sizeof line, fp))
        if (sscanf(line, "MemAvailable: %lf kB", &kib) == 1)
            break;
    if (fp)
        fclose(fp);
    if (kib > 0)
        return kib * 1024.0;
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? (double)pages * (double)page : 0;
}

/* A plan that would need more than max_bytes, refused before it is built or factored. */
static sc_status memory_refused(const sc_grid_lsq_plan *q, double need, sc_error *err)
{
    return sc_error_set(err, SC_E_NOMEM, NULL, 0,
                        "the least-squares plan of %d unknowns needs about %.2g GB, more than "
                        "the %.2g GB allowed", q->n_red, need / 1e9, q->max_bytes / 1e9);
}

/* The peak of the assembly, estimated from the plan before anything is allocated (bytes): what
 * is held, the dense node-misalignment block and the misalignment block (twice), and the matrix:
 * each A component's group of k equations couples its k stage unknowns pairwise once A is
 * eliminated (k(k+1)/2 entries of 12 bytes, held twice while the columns are assembled). */
static double assembly_bytes(const sc_grid_lsq_plan *q)
{
    double pairs = 0;
    for (int a = 0; a < 2 * q->nn; ++a) {
        double k = (double)(q->grp_ptr[a + 1] - q->grp_ptr[a]);
        pairs += 0.5 * k * (k + 1);
    }
    double nm = q->nm;
    return (double)q->bytes + sizeof(double) * ((double)q->ng * nm + 2 * nm * nm) +
           2 * (sizeof(double) + sizeof(int)) * (pairs + q->ng);
}

static sc_status factor_matrix(sc_grid_lsq_plan *q, sc_error *err)
{
    /* the free misalignments couple to nearly every node of their view: ordered last, their
     * columns of Σ come from the selected inverse. AMD orders the G unknowns one by one: a node's
     * two components as one vertex (its couplings are not the same for x and y: a rotated view
     * swaps them) needed 17-40 % more flops (docs/grid-lsq.md) */
    int *last = malloc(sizeof(int) * ((size_t)q->nm + 1));
    if (!last)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, LSQ_NOMEM_MSG);
    int n_last = free_misalignments(q, last, NULL);
    sc_spsym_hint hint = {1, q->ng, last, n_last};
    progress(q, "analyse", 0);
    int arc = sc_spsym_analyze(q->n_red, q->Ap, q->Ai, &hint, &q->f);
    free(last);
    if (arc == -3)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0,
                            "out of memory: the address space limit (ulimit -v) leaves less than "
                            "768 MiB for the sparse solver (CHOLMOD and OpenBLAS, which would hang "
                            "rather than fail below that)");
    if (arc == -2)
        return sc_error_set(err, SC_E_IO, NULL, 0,
                            "the sparse solver library libcholmod.so (SuiteSparse CHOLMOD) "
                            "cannot be loaded");
    if (arc != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, LSQ_NOMEM_MSG);
    /* the peak from here on, measured on stitched stages of 129² to 513² nodes: what is held
     * (the assembly's node-misalignment groups are freed by now) and 3x the supernodal factor
     * (the factor, the selected inverse's blocks and tracked columns): 1.0-1.2x the peak RSS */
    double groups = sizeof(double) * (double)q->ng * q->nm;
    double need = (double)q->bytes - groups + 3.0 * (double)sc_spsym_factor_bytes(q->f);
    if (need > q->peak_est)
        q->peak_est = need;
    if (q->max_bytes > 0 && need > q->max_bytes)
        return memory_refused(q, need, err);
    sc_spsym_stats fs;
    sc_spsym_get_stats(q->f, &fs);
    /* the selected inverse (every node's σ) costs about what the factor does (docs/grid-lsq.md) */
    q->work_total = fs.factor_flops * 2;
    progress(q, "factor", 0);
    if (sc_spsym_factor(q->f, q->Ax, LSQ_PIVOT_TOL) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, LSQ_NOMEM_MSG);
    if (!(q->work_total > 0)) { /* a backend that counts the flops as it factors */
        sc_spsym_get_stats(q->f, &fs);
        q->work_total = fs.factor_flops * 2;
    }
    q->nullity_pin = sc_spsym_nullity(q->f);
    return SC_OK;
}

/* Assemble the reduced (A-eliminated) matrix, pin, order and factor; the nullity of the
 * misalignment block alone (G held at 0). */
static sc_status build_and_factor(sc_grid_lsq_plan *q, sc_error *err)
{
    int nm = q->nm;
    q->peak_est = assembly_bytes(q); /* with the node-misalignment couplings, ng x nm */
    progress(q, "assemble", 0);
    if (q->max_bytes > 0 && q->peak_est > q->max_bytes)
        return memory_refused(q, q->peak_est, err);
    long *rp = NULL;
    int *ri = NULL;
    double *rv = NULL;
    double *gm = sc_big_alloc((size_t)q->ng * nm, sizeof(double), 1);
    double *mm = calloc((size_t)nm * nm, sizeof(double));
    double *mmT = malloc(sizeof(double) * (size_t)nm * nm);
    sc_status st = SC_E_NOMEM;
    if (!gm || !mm || !mmT)
        goto out;
    q->bytes += sizeof(double) * (size_t)q->ng * nm;
    if ((st = assemble_groups(q, gm, mm)) != SC_OK)
        goto out;
    memcpy(mmT, mm, sizeof(double) * (size_t)nm * nm);
    q->nullity_T = small_nullity(mmT, nm, LSQ_SMALL_TOL);
    if (q->nullity_T < 0 || (st = g_block_cols(q, &rp, &ri, &rv)) != SC_OK) {
        st = SC_E_NOMEM;
        goto out;
    }
    st = assemble_matrix(q, rp, ri, rv, gm, mm);
    free(rp), free(ri), free(rv), free(gm), free(mm);
    rp = NULL, ri = NULL, rv = NULL, gm = NULL, mm = NULL;
    if (st == SC_OK) {
        free(mmT);
        return factor_matrix(q, err); /* which says what went wrong */
    }
out:
    if (st == SC_E_NOMEM)
        sc_error_set(err, st, NULL, 0, LSQ_NOMEM_MSG);
    free(gm), free(mm), free(mmT), free(rp), free(ri), free(rv);
    return st;
}

#define SOLVE_CHUNK 8 /* right-hand sides per blocked solve (workspace 2·n_red·SOLVE_CHUNK) */

/* X (n_red x ncol, column after column) := pinned-system solves of its columns (original index
 * space), with `refine` steps of iterative refinement against the assembled matrix; B and R:
 * workspace of n_red·ncol each (unused, may be NULL, without refinement). Returns 0, -1 if the
 * solver ran out of memory. */
static int pinned_solve(const sc_grid_lsq_plan *q, double *X, int ncol, int refine, double *B,
                        double *R)
{
    size_t n = (size_t)q->n_red, tot = n * (size_t)ncol;
    for (size_t k = 0; k < tot; ++k)
        X[k] = q->pinned[k % n] ? 0.0 : X[k];
    if (refine > 0)
        memcpy(B, X, sizeof(double) * tot);
    if (sc_spsym_solve(q->f, X, ncol) != 0)
        return -1;
    for (int it = 0; it < refine; ++it) {
        sc_spsym_matvec(q->f, X, R, ncol);
        for (size_t k = 0; k < tot; ++k)
            R[k] = B[k] - R[k];
        if (sc_spsym_solve(q->f, R, ncol) != 0)
            return -1;
        for (size_t k = 0; k < tot; ++k)
            X[k] += R[k];
    }
    for (size_t k = 0; k < tot; ++k)
        if (q->pinned[k % n])
            X[k] = 0.0;
    return 0;
}

/* X (n_red x ncol) := 0 at the pinned unknowns. */
static void zero_pinned(const sc_grid_lsq_plan *q, double *X, int ncol)
{
    for (int i = 0; i < q->n_red; ++i)
        if (q->pinned[i])
            for (int c = 0; c < ncol; ++c)
                X[(size_t)c * q->n_red + i] = 0.0;
}

/* U (4 x ng, row after row): the orthonormal basis of G's gauge patterns (translations, rotation,
 * magnification) that sc_grid_gauge_stage projects out. */
static void gauge_basis(const sc_grid_lsq_plan *q, double *U, double scale[4])
{
    int ng = q->ng, ns = q->ns;
    double s0 = 1.0 / sqrt((double)ns), s1 = 1.0 / sqrt(q->r2_mm2);
    scale[0] = scale[1] = s0, scale[2] = scale[3] = s1; /* U_t = scale_t·C_t (gauge_g) */
    for (int k = 0; k < ns; ++k) {
        double x, y;
        sc_grid_node_xy_mm(&q->plan, k / q->stage_nx, k % q->stage_nx, &x, &y);
        U[0 * ng + 2 * k] = s0, U[0 * ng + 2 * k + 1] = 0;
        U[1 * ng + 2 * k] = 0, U[1 * ng + 2 * k + 1] = s0;
        U[2 * ng + 2 * k] = -y * s1, U[2 * ng + 2 * k + 1] = x * s1;
        U[3 * ng + 2 * k] = x * s1, U[3 * ng + 2 * k + 1] = y * s1;
    }
}

/* Per-node std/σ_r: diag(P⊥ Σ P⊥) = diag(Σ) − 2 diag(U ᵀW) + diag(Uᵀ (UᵀW) U), Σ = pinned
 * inverse (0 on pins), W = Σ U. First the projection's part into sgx/sgy (W is freed after), then
 * diag(Σ) from the selected inverse. */
static void sigma_ratios_projection(sc_grid_lsq_plan *q, const double *U, const double *W)
{
    int ng = q->ng, n_red = q->n_red;
    double M[4][4];
    for (int c = 0; c < 4; ++c)
        for (int d = 0; d < 4; ++d) {
            double s = 0;
            for (int i = 0; i < ng; ++i)
                s += U[(size_t)c * ng + i] * W[(size_t)d * n_red + i];
            M[c][d] = s;
        }
    for (int i = 0; i < ng; ++i) {
        double var = 0;
        for (int c = 0; c < 4; ++c) {
            double uc = U[(size_t)c * ng + i];
            var -= 2 * W[(size_t)c * n_red + i] * uc;
            for (int d = 0; d < 4; ++d)
                var += uc * M[c][d] * U[(size_t)d * ng + i];
        }
        *(i % 2 == 0 ? &q->sgx[i / 2] : &q->sgy[i / 2]) = var;
    }
}

static void sigma_ratios_finish(sc_grid_lsq_plan *q)
{
    double sum2 = 0, mx = 0;
    for (int i = 0; i < q->ng; ++i) {
        double *at = i % 2 == 0 ? &q->sgx[i / 2] : &q->sgy[i / 2];
        double var = (q->pinned[i] ? 0.0 : sc_spsym_inv(q->f, i, i)) + *at;
        double s = var > 0 ? sqrt(var) : 0.0;
        *at = s;
        sum2 += s * s;
        if (s > mx)
            mx = s;
    }
    q->info.sigma_c_ratio_rms = sqrt(sum2 / q->ng);
    q->info.sigma_c_ratio_max = mx;
}

static sc_status plan_uncertainties(sc_grid_lsq_plan *q, sc_error *err);

/* The plan's sizes from the view plan and options, its copy of the plan and its per-view
 * arrays. */
static sc_status plan_init(sc_grid_lsq_plan *q, const sc_grid_plan *plan,
                           const sc_grid_lsq_opts *opts, sc_error *err)
{
    sc_status st = sc_grid_plan_copy(&q->plan, plan, err);
    if (st != SC_OK)
        return st;
    q->n = plan->n;
    q->nn = plan->n * plan->n;
    q->nv = plan->n_views;
    q->stage_nx = sc_grid_stage_nx(plan);
    q->stage_ny = sc_grid_stage_ny(plan);
    q->ns = q->stage_nx * q->stage_ny;
    q->drift = opts && opts->drift;
    q->node_sigma_only = opts && opts->node_sigma_only;
    q->unit_weights = opts && opts->unit_weights;
    q->max_bytes = opts && opts->max_bytes > 0 ? opts->max_bytes : 0;
    q->progress = opts ? opts->progress : NULL;
    q->progress_ctx = opts ? opts->progress_ctx : NULL;
    q->nb = q->drift ? 5 : 3;
    q->L_mm = (plan->n - 1) / 2 * plan->pitch_mm;
    q->ng = 2 * q->ns;
    q->nm = q->nb * q->nv;
    q->n_red = q->ng + q->nm;
    q->var_O = q->var_R = NAN;
    q->r2_mm2 = 0;
    for (int k = 0; k < q->ns; ++k) {
        double x, y;
        sc_grid_node_xy_mm(plan, k / q->stage_nx, k % q->stage_nx, &x, &y);
        q->r2_mm2 += x * x + y * y;
    }
    size_t nv = (size_t)q->nv, nb = (size_t)q->nb;
    q->view_block = calloc(2 * nv + (nv + sizeof(double) - 1) / sizeof(double), sizeof(double));
    q->fit_work = malloc((nv * (nb * nb + nb) + (size_t)q->nm + nv) * sizeof(double));
    if (!q->view_block || !q->fit_work)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (%d views)", q->nv);
    q->mis_work = q->fit_work + nv * (nb * nb + nb);
    q->drift_T = q->view_block, q->drift_t0 = q->view_block + nv;
    q->view_free = (unsigned char *)(q->view_block + 2 * nv);
    q->bytes += (3 * nv + nv * (nb * nb + nb) + (size_t)q->nm) * sizeof(double) + nv;
    return SC_OK;
}

/* Equation e's part (its row idx, val, len: eq_row's) of its view's block of the misalignment
 * normal matrix, G and A held (nrm: nb x nb per view). */
static void view_normal_add(const sc_grid_lsq_plan *q, long e, const int *idx, const double *val,
                            int len, double *nrm)
{
    int nb = q->nb, v = q->eq_v[e], base = q->ng + nb * v;
    double *b = nrm + (size_t)v * nb * nb;
    for (int i = 1; i < len; ++i)
        for (int j = 1; j < len; ++j)
            b[(idx[i] - base) * nb + idx[j] - base] += q->eq_w[e] * val[i] * val[j];
}

static int fit_view(const double *nrm, const double *rh, int nb, double *m);

/* Per view, how many of its own misalignment columns its equations leave free with G and A held
 * (those fit_view does not keep: the view's fit and this count use one criterion): a view of one
 * mark leaves its rotation, a view of none all nb. Sets q->view_free; returns the total. */
static int views_own_nullity(sc_grid_lsq_plan *q)
{
    int nb = q->nb, total = 0, idx[ROW_MAX];
    double val[ROW_MAX], *nrm = q->fit_work, zero[SC_GRID_LSQ_MAX_NB] = {0};
    double m[SC_GRID_LSQ_MAX_NB];
    memset(nrm, 0, sizeof(double) * (size_t)q->nv * nb * nb);
    for (long e = 0; e < q->neq; ++e)
        view_normal_add(q, e, idx, val, eq_row(q, e, idx, val), nrm);
    for (int v = 0; v < q->nv; ++v) {
        int kept = fit_view(nrm + (size_t)v * nb * nb, zero, nb, m);
        q->view_free[v] = kept < nb;
        total += nb - kept;
    }
    return total;
}

/* Free degrees of freedom (K), identifiability, counts; stage nodes no equation touches. */
static sc_status analyse_identifiability(sc_grid_lsq_plan *q, sc_error *err)
{
    long K = q->nullity_pin - (q->nullity_T - 3);
    if (K < 0)
        K = 0;
    q->info.free_dof = K;
    q->info.identifiable = K == 0;
    q->info.n_unknowns = q->ng + 2 * q->n_meas_marks + q->nm;
    q->info.n_equations = q->neq;
    q->info.n_constraints = 7;
    q->info.n_stage_unmeasured = 0;
    unsigned char *seen = calloc((size_t)q->ns, 1);
    if (!seen) /* reported, not a silently wrong count */
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (long e = 0; e < q->neq; ++e)
        seen[q->eq_g[e] / 2] = 1;
    for (int k = 0; k < q->ns; ++k)
        q->info.n_stage_unmeasured += !seen[k];
    free(seen);
    q->rank = q->info.n_unknowns - (4 + K + q->nullity_T);
    q->info.residual_dof = q->neq - q->rank;
    q->misalignment_unique = q->nullity_T <= 3;
    q->misalignment_estimable = q->nullity_T - views_own_nullity(q) <= 3;
    for (int k = 0; k < q->ns; ++k)
        q->sgx[k] = q->sgy[k] = NAN;
    q->info.sigma_c_ratio_rms = q->info.sigma_c_ratio_max = NAN;
    q->info.redundancy_min = q->info.redundancy_mean = NAN;
    q->info.mdb_ratio_max = q->info.mdb_ratio_mean_r = NAN;
    q->info.n_testable = q->info.n_untestable = 0;
    return SC_OK;
}

/* The redundancy figures of q->info from the leverages. */
static void redundancy_info(sc_grid_lsq_plan *q)
{
    long testable = 0;
    double rmin = INFINITY, rsum = 0;
    for (long e = 0; e < q->neq; ++e) {
        double r = 1.0 - q->eq_h[e];
        if (r > 1e-9) { /* as the residuals' test: t is NaN beyond */
            testable++, rsum += r;
            rmin = fmin(rmin, r);
        }
    }
    q->info.n_testable = testable;
    q->info.n_untestable = q->neq - testable;
    q->info.redundancy_min = testable ? rmin : NAN;
    q->info.redundancy_mean = testable ? rsum / (double)testable : NAN;
    double crit = sc_grid_outlier_critical(SC_GRID_OUTLIER_ALPHA, testable, 0);
    q->info.mdb_ratio_max = sc_grid_mdb_ratio(crit, 0.8, q->info.redundancy_min);
    q->info.mdb_ratio_mean_r = sc_grid_mdb_ratio(crit, 0.8, q->info.redundancy_mean);
}

sc_status sc_grid_lsq_plan_create(const sc_grid_plan *plan, const sc_grid_data *mask,
                                  const sc_grid_lsq_opts *opts, sc_grid_lsq_plan **out,
                                  sc_error *err)
{
    *out = NULL;
    sc_status st = sc_grid_plan_check(plan, err);
    if (st != SC_OK)
        return st;
    if (mask && (mask->plan.n != plan->n || mask->plan.n_views != plan->n_views))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the data's N or number of views differs from the plan's");
    sc_grid_lsq_plan *q = calloc(1, sizeof *q);
    if (!q)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    st = plan_init(q, plan, opts, err);
    if (st == SC_OK)
        st = build_equations(q, mask, err);
    if (st != SC_OK)
        goto fail;
    q->info.weighted = q->weighted;
    q->pinned = calloc((size_t)q->n_red, 1);
    q->sgx = malloc(sizeof(double) * (size_t)q->ns);
    q->sgy = malloc(sizeof(double) * (size_t)q->ns);
    if (!q->pinned || !q->sgx || !q->sgy) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto fail;
    }
    st = choose_pins(q, err);
    if (st == SC_OK)
        st = build_and_factor(q, err);
    if (st == SC_OK)
        st = analyse_identifiability(q, err);
    if (st == SC_OK && q->info.identifiable)
        st = plan_uncertainties(q, err);
    if (st != SC_OK)
        goto fail;
    /* execute's workspace, after the selected inverse (which needs the memory more), and the
     * solver's own for execute's single right-hand sides, so that execute allocates nothing */
    size_t nwork = 4 * (size_t)q->n_red + (size_t)q->ng + 2 * (size_t)q->nn + (size_t)q->nm;
    if (!(q->work = calloc(nwork, sizeof(double))) ||
        (q->info.identifiable && sc_spsym_reserve_solve(q->f, 1) != 0)) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (solves)");
        goto fail;
    }
    q->bytes += sizeof(double) * nwork;
    sc_spsym_stats fst;
    sc_spsym_get_stats(q->f, &fst);
    q->bytes += fst.bytes + (size_t)q->neq * (5 * sizeof(int) + 2 + 2 * sizeof(double) + sizeof(long));
    *out = q;
    return SC_OK;
fail:
    sc_grid_lsq_plan_destroy(q);
    return st;
}

void sc_grid_lsq_get_info(const sc_grid_lsq_plan *q, sc_grid_lsq_info *info)
{
    *info = q->info;
}

void sc_grid_lsq_matrix(const sc_grid_lsq_plan *q, int *n, const long **Ap, const int **Ai,
                        const double **Ax)
{
    *n = q->n_red;
    *Ap = q->Ap;
    *Ai = q->Ai;
    *Ax = q->Ax;
}

long sc_grid_lsq_workspace_made(const sc_grid_lsq_plan *q)
{
    sc_spsym_stats f;
    sc_spsym_get_stats(q->f, &f);
    return f.workspace_made;
}

void sc_grid_lsq_get_stats(const sc_grid_lsq_plan *q, sc_grid_lsq_stats *st)
{
    sc_spsym_stats f;
    sc_spsym_get_stats(q->f, &f);
    memset(st, 0, sizeof *st);
    st->n_reduced = q->n_red;
    st->nnz_matrix = q->Ap ? q->Ap[q->n_red] : 0;
    st->nnz_factor = f.nnz_factor;
    st->factor_flops = f.factor_flops;
    st->ordering = sc_spsym_ordering_name(f.ordering);
    st->selinv_work = f.selinv_work;
    st->n_null_pivots = q->nullity_pin;
    st->nullity_misalignment = q->nullity_T;
    st->min_kept_pivot_ratio = f.min_kept_ratio;
    st->max_null_pivot_ratio = f.max_null_ratio;
    st->bytes = q->bytes;
}

sc_status sc_grid_lsq_sigma_ratio(const sc_grid_lsq_plan *q, double *sgx, double *sgy, sc_error *err)
{
    if (!q->info.identifiable)
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0,
                            "the plan does not identify G (%ld free degrees of freedom)",
                            q->info.free_dof);
    if (sgx)
        memcpy(sgx, q->sgx, sizeof(double) * (size_t)q->ns);
    if (sgy)
        memcpy(sgy, q->sgy, sizeof(double) * (size_t)q->ns);
    return SC_OK;
}

static double eq_data(const sc_grid_lsq_plan *q, const sc_grid_data *d, long e)
{
    int v = q->eq_v[e], k = q->eq_k[e];
    return q->eq_c[e] ? d->dy_um[v][k] : d->dx_um[v][k];
}

/* s_e·d_e − w_e·x for equation e (the part of the equation the group's A must absorb). */
static double eq_misfit(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *x, long e)
{
    int idx[ROW_MAX];
    double val[ROW_MAX];
    int len = eq_row(q, e, idx, val);
    double z = q->eq_s[e] * eq_data(q, d, e);
    for (int r = 0; r < len; ++r)
        z -= val[r] * x[idx[r]];
    return z;
}

/* r = b - S x evaluated from the equations themselves (not the assembled matrix, whose rounding
 * slightly moves the gauge null space): r = Σ_e w_e r_e (z_e - weighted group mean of z),
 * z_e = s_e d_e - r_e·x. Zero on pins. */
static void data_residual(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *x, double *r)
{
    int idx[ROW_MAX];
    double val[ROW_MAX];
    memset(r, 0, sizeof(double) * (size_t)q->n_red);
    for (int c = 0; c < 2 * q->nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        if (cnt < 2)
            continue;
        double mean = 0, W = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            mean += q->eq_w[e] * eq_misfit(q, d, x, e);
            W += q->eq_w[e];
        }
        mean /= W;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            double z = q->eq_w[e] * (eq_misfit(q, d, x, e) - mean);
            int len = eq_row(q, e, idx, val);
            for (int k = 0; k < len; ++k)
                r[idx[k]] += val[k] * z;
        }
    }
    for (int i = 0; i < q->n_red; ++i)
        if (q->pinned[i])
            r[i] = 0;
}

static sc_status check_data(const sc_grid_lsq_plan *q, const sc_grid_data *d, sc_error *err)
{
    int n = q->n, nn = q->nn, nv = q->nv;
    if (d->plan.n != n || d->plan.n_views != nv ||
        sc_grid_stage_nx(&d->plan) != q->stage_nx || sc_grid_stage_ny(&d->plan) != q->stage_ny)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "data has N = %d and %d views, the estimator N = %d and %d views "
                            "(or the stages differ)",
                            d->plan.n, d->plan.n_views, n, nv);
    for (int v = 0; v < nv; ++v) {
        const sc_grid_view *a = &d->plan.view[v], *b = &q->plan.view[v];
        if (a->rot_deg != b->rot_deg || a->shift_x != b->shift_x || a->shift_y != b->shift_y)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "view %d of the data (rot %d shift %d,%d) differs from the "
                                "estimator's (rot %d shift %d,%d)",
                                v, a->rot_deg, a->shift_x, a->shift_y, b->rot_deg, b->shift_x,
                                b->shift_y);
        for (int k = 0; k < nn; ++k) {
            int fx = d->dx_um[v] && isfinite(d->dx_um[v][k]);
            int fy = d->dy_um[v] && isfinite(d->dy_um[v][k]);
            if (fx != fy || fx != q->meas[v * nn + k])
                return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                    "view %d mark (%d,%d): %s", v, k / n, k % n,
                                    fx != fy ? "only one of dx, dy is given"
                                    : fx    ? "measured, but the estimator was made without it"
                                            : "not measured, but the estimator expects it");
        }
    }
    if (!q->info.identifiable)
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0,
                            "the plan does not identify G (%ld free degrees of freedom)",
                            q->info.free_dof);
    return SC_OK;
}

/* Solve a small dense symmetric system m x m (row-major, destroyed) in place of rhs by Gaussian
 * elimination with partial pivoting; a null pivot gives a NaN solution. */
static void small_solve(double *a, double *rhs, int m)
{
    for (int c = 0; c < m; ++c) {
        int best = c;
        for (int r = c + 1; r < m; ++r)
            if (fabs(a[r * m + c]) > fabs(a[best * m + c]))
                best = r;
        if (best != c) {
            for (int k = 0; k < m; ++k) {
                double t = a[c * m + k];
                a[c * m + k] = a[best * m + k];
                a[best * m + k] = t;
            }
            double t = rhs[c];
            rhs[c] = rhs[best];
            rhs[best] = t;
        }
        double piv = a[c * m + c], scale = 0;
        for (int k = 0; k < m; ++k)
            scale = fmax(scale, fabs(a[k * m + k]));
        if (!(fabs(piv) > 1e-13 * scale)) {
            for (int k = 0; k < m; ++k)
                rhs[k] = NAN;
            return;
        }
        for (int r = c + 1; r < m; ++r) {
            double l = a[r * m + c] / piv;
            for (int k = c; k < m; ++k)
                a[r * m + k] -= l * a[c * m + k];
            rhs[r] -= l * rhs[c];
        }
    }
    for (int c = m - 1; c >= 0; --c) {
        double t = rhs[c];
        for (int k = c + 1; k < m; ++k)
            t -= a[c * m + k] * rhs[k];
        rhs[c] = t / a[c * m + c];
    }
}

/* G (x's first ng entries, interleaved) in the gauge, A as weighted group means moved with G's
 * magnification and gauged over the measured marks (translation, rotation). */
static void gauge_solution(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *x, double *gx,
                           double *gy, double *a)
{
    int n = q->n, nn = q->nn, ns = q->ns, stage_nx = q->stage_nx;
    for (int k = 0; k < ns; ++k) {
        gx[k] = x[2 * k];
        gy[k] = x[2 * k + 1];
    }
    double smag = 0, r2 = 0;
    for (int k = 0; k < ns; ++k) {
        double px, py;
        sc_grid_node_xy_mm(&q->plan, k / stage_nx, k % stage_nx, &px, &py);
        smag += px * gx[k] + py * gy[k];
        r2 += px * px + py * py;
    }
    double mu = smag / r2;
    for (int c = 0; c < 2 * nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        double s = 0, W = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            s += q->eq_w[e] * eq_misfit(q, d, x, e);
            W += q->eq_w[e];
        }
        a[c] = cnt > 0 ? s / W : NAN;
    }
    sc_grid_gauge_stage(&q->plan, gx, gy);
    double m3[9] = {0}, rhs[3] = {0};
    for (int k = 0; k < nn; ++k) {
        if (!q->mark_views[k])
            continue;
        double px, py;
        sc_grid_mark_xy_mm(&q->plan, k / n, k % n, &px, &py);
        a[2 * k] += mu * px;
        a[2 * k + 1] += mu * py;
        m3[0] += 1, m3[4] += 1, m3[2] -= py, m3[5] += px, m3[8] += px * px + py * py;
        rhs[0] += a[2 * k], rhs[1] += a[2 * k + 1], rhs[2] += px * a[2 * k + 1] - py * a[2 * k];
    }
    m3[6] = m3[2], m3[7] = m3[5];
    small_solve(m3, rhs, 3);
    for (int k = 0; k < nn; ++k) {
        if (!q->mark_views[k] || !isfinite(rhs[0]))
            continue;
        double px, py;
        sc_grid_mark_xy_mm(&q->plan, k / n, k % n, &px, &py);
        a[2 * k] -= rhs[0] - rhs[2] * py;
        a[2 * k + 1] -= rhs[1] + rhs[2] * px;
    }
}

/* One view's misalignment fit from its normal equations nrm (nb x nb, row-major) and rh: the
 * columns taken in order (tx, ty, φ, vx, vy), each kept when the system stays regular with it
 * (Cholesky with diagonal pivoting, LSQ_SMALL_TOL), the kept ones solved, the others 0 — a
 * particular least-squares solution, so the residuals are right whatever the view determines
 * (a single mark: tx, ty fit it exactly, φ stays 0). m: nb values (NaN for a view without
 * equations); returns how many columns were kept (nb: the misalignments are determined). */
static int fit_view(const double *nrm, const double *rh, int nb, double *m)
{
    int keep[SC_GRID_LSQ_MAX_NB], nk = 0;
    for (int c = 0; c < nb; ++c)
        m[c] = 0;
    for (int c = 0; c < nb; ++c) {
        double sub[SC_GRID_LSQ_MAX_NB * SC_GRID_LSQ_MAX_NB];
        keep[nk] = c;
        for (int i = 0; i <= nk; ++i)
            for (int j = 0; j <= nk; ++j)
                sub[i * (nk + 1) + j] = nrm[keep[i] * nb + keep[j]];
        if (small_nullity(sub, nk + 1, LSQ_SMALL_TOL) == 0)
            ++nk;
    }
    if (nk == 0) {
        for (int c = 0; c < nb; ++c)
            m[c] = NAN;
        return 0;
    }
    double sub[SC_GRID_LSQ_MAX_NB * SC_GRID_LSQ_MAX_NB], r[SC_GRID_LSQ_MAX_NB];
    for (int i = 0; i < nk; ++i) {
        r[i] = rh[keep[i]];
        for (int j = 0; j < nk; ++j)
            sub[i * nk + j] = nrm[keep[i] * nb + keep[j]];
    }
    small_solve(sub, r, nk);
    for (int i = 0; i < nk; ++i)
        m[keep[i]] = r[i];
    return nk;
}

/* Misalignments (and drift): per view, weighted least squares of d - G - Rot A on its nb columns,
 * G as gx | gy (ns each), A's x and y of mark k at ax[k·as] and ay[k·as] (as: 2 for the solve's
 * interleaved A, 1 for a result's). m: nm, a particular solution where a view does not determine
 * its columns (fit_view; q->view_free says which). Uses q->fit_work (one plan, one thread). */
static void fit_misalignments(const sc_grid_lsq_plan *q, const sc_grid_data *d, const double *gx,
                              const double *gy, const double *ax, const double *ay, int as,
                              double *m)
{
    int nb = q->nb;
    double *nrm = q->fit_work, *rh = nrm + (size_t)q->nv * nb * nb;
    memset(nrm, 0, sizeof(double) * (size_t)q->nv * (nb * nb + nb));
    int idx[ROW_MAX];
    double val[ROW_MAX];
    for (long e = 0; e < q->neq; ++e) {
        int v = q->eq_v[e], len = eq_row(q, e, idx, val), node = q->eq_g[e] / 2,
            k = q->eq_a[e] / 2;
        double w = q->eq_w[e], s = q->eq_s[e];
        double r = eq_data(q, d, e) - (q->eq_g[e] % 2 ? gy : gx)[node] -
                   s * (q->eq_a[e] % 2 ? ay : ax)[(size_t)k * as];
        for (int i = 1; i < len; ++i)
            rh[v * nb + idx[i] - q->ng - nb * v] += w * s * val[i] * r;
        view_normal_add(q, e, idx, val, len, nrm);
    }
    for (int v = 0; v < q->nv; ++v)
        fit_view(nrm + (size_t)v * nb * nb, rh + (size_t)v * nb, nb, m + v * nb);
}

/* Upper quantile helpers: the regularized lower incomplete gamma P(a, x). */
static double gamma_p(double a, double x)
{
    if (!(x > 0))
        return 0.0;
    double lg = lgamma(a);
    if (x < a + 1) {
        double sum = 1.0 / a, term = sum;
        for (int k = 1; k < 100000; ++k) {
            term *= x / (a + k);
            sum += term;
            if (fabs(term) < fabs(sum) * 1e-16)
                break;
        }
        return sum * exp(-x + a * log(x) - lg);
    }
    /* continued fraction for Q (Lentz) */
    double b = x + 1 - a, c = 1e300, dd = 1 / b, h = dd;
    for (int i = 1; i < 100000; ++i) {
        double an = -i * (i - a);
        b += 2;
        dd = an * dd + b;
        if (fabs(dd) < 1e-300)
            dd = 1e-300;
        c = b + an / c;
        if (fabs(c) < 1e-300)
            c = 1e-300;
        dd = 1 / dd;
        double del = dd * c;
        h *= del;
        if (fabs(del - 1) < 1e-16)
            break;
    }
    return 1.0 - exp(-x + a * log(x) - lg) * h;
}

double sc_chi2_quantile(double p, double dof)
{
    if (!(dof > 0) || !(p > 0) || !(p < 1))
        return NAN;
    double lo = 0, hi = dof + 10 * sqrt(2 * dof) + 100;
    while (gamma_p(dof / 2, hi / 2) < p)
        hi *= 2;
    for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
        double mid = 0.5 * (lo + hi);
        if (gamma_p(dof / 2, mid / 2) < p)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

double sc_normal_two_sided_critical(double alpha)
{
    if (!(alpha > 0) || !(alpha < 1))
        return NAN;
    /* erfc(z/√2) = alpha, decreasing in z; libm's erfc keeps its relative accuracy far into the
     * tail (erfc(38.6/√2) is near the smallest double), so bisection on it is exact to the
     * ulp it converges to */
    double lo = 0, hi = 40;
    while (hi - lo > 4 * DBL_EPSILON * hi) {
        double mid = 0.5 * (lo + hi);
        if (erfc(mid * 0.70710678118654752440) > alpha)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

double sc_grid_mdb_ratio(double crit, double power, double r)
{
    if (!(r > 0) || !(power > 0 && power < 1) || !(crit >= 0))
        return NAN;
    /* P(Z > z) = 1 − power is the two-sided tail 2(1 − power) of |Z|; below the median
     * (power < 0.5) z is negative */
    double z = power > 0.5   ? sc_normal_two_sided_critical(2 * (1 - power))
               : power < 0.5 ? -sc_normal_two_sided_critical(2 * power)
                             : 0.0;
    return (crit + z) / sqrt(r);
}

double sc_grid_outlier_critical(double alpha, long n_tests, int each)
{
    if (!(alpha > 0) || !(alpha < 1))
        return NAN;
    if (each)
        return sc_normal_two_sided_critical(alpha);
    if (n_tests < 1)
        return NAN;
    return sc_normal_two_sided_critical(sc_grid_sidak_share(alpha, n_tests));
}

double sc_grid_sidak_share(double alpha, long m)
{
    /* m independent tests at a each miss all with probability (1 − a)^m = 1 − alpha */
    return -expm1(log1p(-alpha) / (double)m);
}

int sc_grid_outlier_beyond(const sc_grid_result *res, double t)
{
    return isfinite(t) && fabs(t) > res->outlier_crit;
}

/* The noise figures of res from the residual sums; the σ scale the uncertainties use. */
static double fill_result_noise(const sc_grid_lsq_plan *q, double wrss, double rss,
                                double sigma_r_um, sc_grid_result *res)
{
    long dof = q->neq - q->rank;
    double sigma0;
    res->n_measurements = q->neq;
    res->dof = dof;
    res->residual_rms_um = q->neq > 0 ? sqrt(rss / (double)q->neq) : NAN;
    res->weighted = q->weighted || sigma_r_um > 0;
    res->stated_u = q->weighted;
    res->variance_factor = res->chi2_lo = res->chi2_hi = NAN;
    res->chi2_pass = 1;
    if (q->weighted) {
        /* stated uncertainties: σ̂ is the factor on them; the uncertainties use them as stated */
        res->sigma_r_est_um = dof > 0 ? sqrt(wrss / (double)dof) : NAN;
        res->sigma_r_used_um = 1.0;
        sigma0 = 1.0;
        if (dof > 0)
            res->variance_factor = wrss / (double)dof;
    } else {
        res->sigma_r_est_um = dof > 0 ? sqrt(rss / (double)dof) : NAN;
        res->sigma_r_used_um = sigma_r_um > 0 ? sigma_r_um : res->sigma_r_est_um;
        sigma0 = res->sigma_r_used_um;
        if (sigma_r_um > 0 && dof > 0)
            res->variance_factor = rss / (double)dof / (sigma_r_um * sigma_r_um);
    }
    if (isfinite(res->variance_factor)) {
        res->chi2_lo = sc_chi2_quantile(0.025, (double)dof) / (double)dof;
        res->chi2_hi = sc_chi2_quantile(0.975, (double)dof) / (double)dof;
        res->chi2_pass = res->variance_factor >= res->chi2_lo && res->variance_factor <= res->chi2_hi;
    }
    return sigma0;
}

/* σ scale of the standardized residuals of a result: its σ0, or when the stated noise is too
 * small for the residuals (χ² test failed high) a posteriori (Pope's τ): data snooping with the
 * stated noise would flag nearly everything. */
static double residual_scale(const sc_grid_result *res)
{
    double s = res->sigma_r_used_um;
    if (isfinite(res->variance_factor) && res->variance_factor > res->chi2_hi)
        s *= sqrt(res->variance_factor);
    return s;
}

/* Residual of equation e: data − G − s·A − misalignment (and drift) terms; gv, av: the G and A
 * components the equation touches, m: the misalignment unknowns (nm). */
static double eq_residual(const sc_grid_lsq_plan *q, const sc_grid_data *d, long e, double gv,
                          double av, const double *m)
{
    int idx[ROW_MAX];
    double val[ROW_MAX], mis = 0;
    int len = eq_row(q, e, idx, val);
    for (int t = 1; t < len; ++t)
        mis += q->eq_s[e] * val[t] * m[idx[t] - q->ng];
    if (!isfinite(mis))
        mis = 0;
    return eq_data(q, d, e) - gv - q->eq_s[e] * av - mis;
}

/* x := the pinned reduced solution for d: b − S·0 from the equations, then up to 3 refinement
 * steps against the equations, stopping after a step whose correction was at the level of the
 * residual's own rounding (‖dx‖∞ ≤ 1e-12‖x‖∞: measured 1e-14 relative after the first step at
 * N = 101 and 201, where the first corrects 1e-10; a further step only moves x by as much again);
 * r, b, r2: workspace (n_red each). */
static int solve_reduced(const sc_grid_lsq_plan *q, const sc_grid_data *d, double *x, double *r,
                         double *b, double *r2)
{
    int n_red = q->n_red;
    memset(x, 0, sizeof(double) * (size_t)n_red);
    data_residual(q, d, x, r);
    memcpy(x, r, sizeof(double) * (size_t)n_red);
    if (pinned_solve(q, x, 1, 0, b, r2) != 0)
        return -1;
    for (int it = 0; it < 3; ++it) {
        data_residual(q, d, x, r);
        if (pinned_solve(q, r, 1, 0, b, r2) != 0)
            return -1;
        double dx = 0, xm = 0;
        for (int i = 0; i < n_red; ++i) {
            x[i] += r[i];
            dx = fmax(dx, fabs(r[i]));
            xm = fmax(xm, fabs(x[i]));
        }
        /* converged: a step at rounding level; or the first step, when it corrected less than
         * 1e-8 of x: the error it leaves is then its own ratio times it, below the residual's
         * rounding floor (at N = 201 the first step corrects 2.6e-10, the second 7.6e-14: the
         * floor, noise rather than a gain), so a third solve would only move x within it */
        if (dx <= 1e-12 * xm || (it == 0 && dx <= 1e-8 * xm))
            break;
    }
    return 0;
}

/* Copy the solution (G as gx | gy, A interleaved, misalignments m) and the uncertainties the plan
 * computed (scaled by σ0) into res. */
static void fill_result_values(const sc_grid_lsq_plan *q, const double *g, const double *a,
                               const double *m, double sigma0, sc_grid_result *res)
{
    int nb = q->nb, ns = q->ns;
    const double *gx = g, *gy = g + ns;
    res->drift = q->drift;
    res->misalignment_unique = q->misalignment_unique;
    res->uO = sigma0 * sqrt(q->var_O);
    res->uR = sigma0 * sqrt(q->var_R);
#define PUT_VIEW(arr, v, val) do { if (res->arr) res->arr[v] = (val); } while (0)
    for (int v = 0; v < q->nv; ++v) { /* the per-view arrays the caller gave */
        const double *um = q->var_m + v * nb;
        double L = q->L_mm * 1e-3;
        PUT_VIEW(tx_um, v, m[v * nb]);
        PUT_VIEW(ty_um, v, m[v * nb + 1]);
        PUT_VIEW(theta_urad, v, m[v * nb + 2] / L);
        PUT_VIEW(vx_um_s, v, q->drift ? m[v * nb + 3] / q->drift_T[v] : NAN);
        PUT_VIEW(vy_um_s, v, q->drift ? m[v * nb + 4] / q->drift_T[v] : NAN);
        PUT_VIEW(utx_um, v, sigma0 * sqrt(um[0]));
        PUT_VIEW(uty_um, v, sigma0 * sqrt(um[1]));
        PUT_VIEW(utheta_urad, v, sigma0 * sqrt(um[2]) / L);
        PUT_VIEW(uvx_um_s, v, q->drift ? sigma0 * sqrt(um[3]) / q->drift_T[v] : NAN);
        PUT_VIEW(uvy_um_s, v, q->drift ? sigma0 * sqrt(um[4]) / q->drift_T[v] : NAN);
    }
#undef PUT_VIEW
    sc_grid_first_order(&q->plan, gx, gy, &res->O, &res->R);
    for (int k = 0; k < ns; ++k) {
        if (res->gx_um)
            res->gx_um[k] = gx[k];
        if (res->gy_um)
            res->gy_um[k] = gy[k];
        if (res->ugx_um)
            res->ugx_um[k] = sigma0 * q->sgx[k];
        if (res->ugy_um)
            res->ugy_um[k] = sigma0 * q->sgy[k];
    }
    for (int k = 0; k < q->nn; ++k) {
        if (res->ax_um)
            res->ax_um[k] = q->mark_views[k] ? a[2 * k] : NAN;
        if (res->ay_um)
            res->ay_um[k] = q->mark_views[k] ? a[2 * k + 1] : NAN;
    }
}

sc_status sc_grid_lsq_execute(const sc_grid_lsq_plan *q, const sc_grid_data *d, double sigma_r_um,
                              sc_grid_result *res, sc_error *err)
{
    int ns = q->ns;
    sc_status st = check_data(q, d, err);
    if (st != SC_OK)
        return st;
    progress(q, "solve", q->work_total);
    size_t n = (size_t)q->n_red;
    double *x = q->work, *r = x + n, *b = r + n, *r2 = b + n, *g = r2 + n, *a = g + q->ng;
    double *m = a + 2 * (size_t)q->nn;
    if (solve_reduced(q, d, x, r, b, r2) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (least-squares solve)");
    gauge_solution(q, d, x, g, g + ns, a);
    fit_misalignments(q, d, g, g + ns, a, a + 1, 2, m);
    double rss = 0, wrss = 0;
    for (long e = 0; e < q->neq; ++e) {
        int c = q->eq_g[e] % 2, node = q->eq_g[e] / 2;
        double re = eq_residual(q, d, e, g[c * ns + node], a[q->eq_a[e]], m);
        rss += re * re;
        wrss += q->eq_w[e] * re * re;
    }
    double sigma0 = fill_result_noise(q, wrss, rss, sigma_r_um, res);
    for (int v = 0; v < q->nv; ++v) /* reported only where the view determines them */
        for (int c = 0; q->view_free[v] && c < q->nb; ++c)
            m[v * q->nb + c] = NAN;
    fill_result_values(q, g, a, m, sigma0, res);
    return SC_OK;
}

/* ---------------------------------------------------------------------------------------------
 * Uncertainties of linear functionals of the gauged solution (O, R, misalignments, drift).
 *
 * Full unknowns z = (G, A, m). The gauged estimate is z_g = Q z_pin with Q = I - N (CᵀN)⁻¹ Cᵀ,
 * N the 7 null vectors of the model (G translation ×2, rotation, G+A magnification, A
 * translation ×2, A rotation, each with the misalignment change that keeps every equation) and
 * C the 7 gauge sums. Cov(z_pin) = Σ (the pinned inverse of the full normal matrix, a reflexive
 * generalized inverse), so Var(fᵀ z_g) = σ0² uᵀ Σ u with u = Qᵀ f. uᵀ Σ u needs one pinned solve
 * of the reduced matrix (A eliminated by its diagonal block).
 * ------------------------------------------------------------------------------------------- */

/* Apply the 7 null vectors: nullv(k) restricted to entry class. Values for G node k (stage, both
 * components), A mark (both), and misalignment (view v, component t). */
static void null_g(const sc_grid_lsq_plan *q, int node, double out[7][2])
{
    double x, y;
    sc_grid_node_xy_mm(&q->plan, node / q->stage_nx, node % q->stage_nx, &x, &y);
    double L = q->L_mm;
    memset(out, 0, sizeof(double) * 14);
    out[0][0] = 1, out[1][1] = 1;
    out[2][0] = -y / L, out[2][1] = x / L;
    out[3][0] = x / L, out[3][1] = y / L;
}

static void null_a(const sc_grid_lsq_plan *q, int mark, double out[7][2])
{
    double x, y;
    sc_grid_mark_xy_mm(&q->plan, mark / q->n, mark % q->n, &x, &y);
    double L = q->L_mm;
    memset(out, 0, sizeof(double) * 14);
    out[3][0] = -x / L, out[3][1] = -y / L;
    out[4][0] = 1, out[5][1] = 1;
    out[6][0] = -y / L, out[6][1] = x / L;
}

static void null_m(const sc_grid_lsq_plan *q, int v, double out[7][5])
{
    const sc_grid_view *w = &q->plan.view[v];
    double P = q->plan.pitch_mm, L = q->L_mm, sx = w->shift_x * P / L, sy = w->shift_y * P / L;
    double r10x, r10y, r01x, r01y;
    sc_grid_rotate(w->rot_deg, 1, 0, &r10x, &r10y);
    sc_grid_rotate(w->rot_deg, 0, 1, &r01x, &r01y);
    memset(out, 0, sizeof(double) * 35);
    out[0][0] = -1;
    out[1][1] = -1;
    out[2][2] = -1;
    out[3][0] = -sx, out[3][1] = -sy;
    out[4][0] = -r10x, out[4][1] = -r10y;
    out[5][0] = -r01x, out[5][1] = -r01y;
    out[6][0] = -sy, out[6][1] = sx, out[6][2] = -1;
}

/* The 7 gauge functionals C_k as vectors: on G node (both comps) and on A mark (both). */
static void gauge_g(const sc_grid_lsq_plan *q, int node, double out[7][2])
{
    double x, y;
    sc_grid_node_xy_mm(&q->plan, node / q->stage_nx, node % q->stage_nx, &x, &y);
    memset(out, 0, sizeof(double) * 14);
    out[0][0] = 1, out[1][1] = 1;
    out[2][0] = -y, out[2][1] = x;
    out[3][0] = x, out[3][1] = y;
}

static void gauge_a(const sc_grid_lsq_plan *q, int mark, double out[7][2])
{
    double x, y;
    memset(out, 0, sizeof(double) * 14);
    if (!q->mark_views[mark])
        return;
    sc_grid_mark_xy_mm(&q->plan, mark / q->n, mark % q->n, &x, &y);
    out[4][0] = 1, out[5][1] = 1;
    out[6][0] = -y, out[6][1] = x;
}

/* (CᵀN)⁻ᵀ, 7 x 7 row-major; 0 if singular. */
static int gauge_matrix(const sc_grid_lsq_plan *q, double *Minv_T)
{
    double M[49] = {0};
    for (int k = 0; k < q->ns; ++k) {
        double cg[7][2], n7[7][2];
        gauge_g(q, k, cg);
        null_g(q, k, n7);
        for (int i = 0; i < 7; ++i)
            for (int j = 0; j < 7; ++j)
                M[i * 7 + j] += cg[i][0] * n7[j][0] + cg[i][1] * n7[j][1];
    }
    for (int k = 0; k < q->nn; ++k) {
        double ca[7][2], n7[7][2];
        gauge_a(q, k, ca);
        null_a(q, k, n7);
        for (int i = 0; i < 7; ++i)
            for (int j = 0; j < 7; ++j)
                M[i * 7 + j] += ca[i][0] * n7[j][0] + ca[i][1] * n7[j][1];
    }
    /* Minv_T = (Mᵀ)⁻¹: solve Mᵀ X = I column by column */
    for (int c = 0; c < 7; ++c) {
        double A[49], rhs[7] = {0};
        for (int i = 0; i < 7; ++i)
            for (int j = 0; j < 7; ++j)
                A[i * 7 + j] = M[j * 7 + i];
        rhs[c] = 1;
        small_solve(A, rhs, 7);
        for (int i = 0; i < 7; ++i) {
            if (!isfinite(rhs[i]))
                return -1;
            Minv_T[i * 7 + c] = rhs[i];
        }
    }
    return 0;
}

/* γ of the functional f given on G (fg, ng, may be NULL) and m (fm, nm, may be NULL): the
 * coefficients of the gauge patterns C_t that Qᵀ removes (functional_vectors). */
static void functional_gamma(const sc_grid_lsq_plan *q, const double *Minv_T, const double *fg,
                             const double *fm, double gam[7])
{
    int nb = q->nb;
    double Nf[7] = {0};
    memset(gam, 0, sizeof(double) * 7);
    double ng7[7][2], nm7[7][5];
    for (int k = 0; fg && k < q->ns; ++k) {
        null_g(q, k, ng7);
        for (int t = 0; t < 7; ++t)
            Nf[t] += ng7[t][0] * fg[2 * k] + ng7[t][1] * fg[2 * k + 1];
    }
    for (int v = 0; fm && v < q->nv; ++v) {
        null_m(q, v, nm7);
        for (int t = 0; t < 7; ++t)
            for (int c = 0; c < nb && c < 5; ++c)
                Nf[t] += (c < 3 ? nm7[t][c] : 0.0) * fm[v * nb + c];
    }
    for (int i = 0; i < 7; ++i)
        for (int j = 0; j < 7; ++j)
            gam[i] += Minv_T[i * 7 + j] * Nf[j];
}

/* u = Qᵀ f for the functional f given on G (fg, ng, may be NULL) and m (fm, nm, may be NULL):
 * ux on the reduced unknowns (n_red), uA on the A components (2 nn); u = f − Σ_t γ_t C_t. */
static void functional_vectors(const sc_grid_lsq_plan *q, const double *Minv_T, const double *fg,
                               const double *fm, double *ux, double *uA, double gam[7])
{
    int ng = q->ng;
    functional_gamma(q, Minv_T, fg, fm, gam);
    /* u = f - Σ_k γ_k C_k */
    memset(ux, 0, sizeof(double) * (size_t)q->n_red);
    for (int k = 0; k < q->ns; ++k) {
        double cg[7][2];
        gauge_g(q, k, cg);
        for (int c = 0; c < 2; ++c) {
            double v = fg ? fg[2 * k + c] : 0;
            for (int t = 0; t < 7; ++t)
                v -= gam[t] * cg[t][c];
            ux[2 * k + c] = v;
        }
    }
    for (int t = 0; fm && t < q->nm; ++t)
        ux[ng + t] = fm[t];
    for (int k = 0; k < q->nn; ++k) {
        double ca[7][2];
        gauge_a(q, k, ca);
        for (int c = 0; c < 2; ++c) {
            double v = 0;
            for (int t = 0; t < 7; ++t)
                v -= gam[t] * ca[t][c];
            uA[2 * k + c] = v;
        }
    }
}

/* uᵀ Σ u in two halves: z_x = S⁻¹(u_x − Σ_a (u_A[a]/W_a) Σ_e w_e ρ_e), then z_A[a] = (u_A[a] −
 * Σ_e w_e ρ_e·z_x)/W_a (functional_form). This subtracts the A part of the right-hand side from z. */
static void a_correction(const sc_grid_lsq_plan *q, const double *uA, double *z)
{
    int idx[ROW_MAX];
    double val[ROW_MAX];
    for (int a = 0; a < 2 * q->nn; ++a) {
        long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
        double W = 0;
        for (long t = 0; t < cnt; ++t)
            W += q->eq_w[q->grp_eq[g0 + t]];
        if (cnt == 0 || uA[a] == 0)
            continue;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            int len = eq_row(q, e, idx, val);
            for (int r = 0; r < len; ++r)
                z[idx[r]] -= uA[a] / W * q->eq_w[e] * val[r];
        }
    }
}

/* The affine form behind uᵀΣu (a_correction): uxᵀz − Σ_a u_A[a]·(Σ_e w_e ρ_e·z)/W_a, plus the
 * constant Σ_a u_A[a]²/W_a when with_const. Linear in z, so a z combined from several columns of
 * Σ can be taken column by column. */
static double functional_form(const sc_grid_lsq_plan *q, const double *ux, const double *uA,
                              const double *z, int with_const)
{
    int idx[ROW_MAX];
    double val[ROW_MAX], var = 0;
    for (int i = 0; i < q->n_red; ++i)
        var += ux[i] * z[i];
    for (int a = 0; a < 2 * q->nn; ++a) {
        long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
        if (cnt == 0 || uA[a] == 0)
            continue;
        double W = 0, proj = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            int len = eq_row(q, e, idx, val);
            W += q->eq_w[e];
            for (int r = 0; r < len; ++r)
                proj += q->eq_w[e] * val[r] * z[idx[r]];
        }
        var += uA[a] * ((with_const ? uA[a] : 0.0) - proj) / W;
    }
    return var;
}

/* Functional f of the plan's list: 0 O, 1 R (as sc_grid_first_order), then misalignment
 * unknown f − 2. Fills fg or fm and says which (the other NULL). */
static void functional_def(const sc_grid_lsq_plan *q, int f, double *fg, double *fm,
                           const double **fg_out, const double **fm_out)
{
    *fg_out = *fm_out = NULL;
    if (f < 2) {
        for (int k = 0; k < q->ns; ++k) {
            double x, y;
            sc_grid_node_xy_mm(&q->plan, k / q->stage_nx, k % q->stage_nx, &x, &y);
            fg[2 * k] = (f == 0 ? y : x) / q->r2_mm2 * 1e-3;
            fg[2 * k + 1] = (f == 0 ? x : -y) / q->r2_mm2 * 1e-3;
        }
        *fg_out = fg;
    } else {
        memset(fm, 0, sizeof(double) * (size_t)q->nm);
        fm[f - 2] = 1;
        *fm_out = fm;
    }
}

/* D_t = a_correction of the A gauge pattern C_t, t = 4..6 (3 columns of n_red); uA: scratch. */
static void gauge_a_rhs(const sc_grid_lsq_plan *q, double *uA, double *D)
{
    size_t n = (size_t)q->n_red;
    memset(D, 0, sizeof(double) * 3 * n);
    for (int t = 4; t < 7; ++t) {
        for (int k = 0; k < q->nn; ++k) {
            double ca[7][2];
            gauge_a(q, k, ca);
            uA[2 * k] = ca[t][0], uA[2 * k + 1] = ca[t][1];
        }
        a_correction(q, uA, D + (size_t)(t - 4) * n);
    }
}

/* The right-hand sides whose pinned solves combine into every functional's (5 columns of n_red):
 * [fg_O; 0], [fg_R; 0] and the A parts D_t (a_correction of the gauge sum C_t on A, t = 4..6). */
static void functional_basis_rhs(const sc_grid_lsq_plan *q, double *fg, double *uA,
                                 double *cols)
{
    size_t n = (size_t)q->n_red;
    const double *pg, *pm;
    memset(cols, 0, sizeof(double) * 2 * n);
    for (int f = 0; f < 2; ++f) {
        functional_def(q, f, fg, uA, &pg, &pm); /* uA: not written for O, R */
        memcpy(cols + (size_t)f * n, fg, sizeof(double) * (size_t)q->ng);
    }
    gauge_a_rhs(q, uA, cols + 2 * n);
}
/* Var/σ0² of O, R and (when unique) of every misalignment unknown: Var(fᵀ z_g) = uᵀ Σ u with
 * u = Qᵀ f = f − Σ_t γ_t C_t. In the reduced unknowns uᵀΣu = r·Σr + Σ_a u_A[a]²/W_a with
 * r = u_x − a_correction(u_A) (functional_form). The gauge patterns C_t lie on G for t < 4 (U_t =
 * scale_t·C_t) and on A for t >= 4 (a_correction of them: D_t), so
 *     r = f − Σ_{t<4} γ_t U_t/scale_t + Σ_{t>=4} γ_t D_t,
 * and Σr combines the 9 solved columns X = (W = ΣU, B = Σ(fg_O, fg_R, D_4..6)) with Σ f for a
 * misalignment f = e_m: its own column of Σ, from the selected inverse. The form r·z is then
 * f·z − Σ_{t<4} γ_t U_t·z/scale_t − Σ_{t>=4} γ_t D_t·z: dot products, no pass over the equations
 * per functional. */
static double dot(const double *a, const double *b, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; ++i)
        s += a[i] * b[i];
    return s;
}

/* C[t][t'] = Σ_a C_t[a] C_t'[a] / W_a over the A components, t, t' = 4..6 (the A gauges): the
 * constant Σ_a u_A[a]²/W_a of every form is γᵀCγ. */
static void a_gauge_gram(const sc_grid_lsq_plan *q, double C[3][3])
{
    memset(C, 0, sizeof(double) * 9);
    for (int a = 0; a < 2 * q->nn; ++a) {
        double W = 0, ca[7][2];
        for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t)
            W += q->eq_w[q->grp_eq[t]];
        if (W == 0)
            continue;
        gauge_a(q, a / 2, ca);
        for (int t = 0; t < 3; ++t)
            for (int u = 0; u < 3; ++u)
                C[t][u] += ca[4 + t][a % 2] * ca[4 + u][a % 2] / W;
    }
}

/* Phase 0 (before the selected inverse): O and R, and part[t] for every misalignment unknown t
 * (its variance without its own column's share; NaN where it has none). Phase 1 (after): the
 * misalignments' variances, adding r·(Σ e_m) from their columns of Σ; D must be the same. */
static sc_status functional_variances(sc_grid_lsq_plan *q, int phase, const double scale[4],
                                      const double *U, const double *D, const double *X,
                                      double *part, sc_error *err)
{
    double Minv_T[49], gam[7];
    if (phase == 0) /* var_m is NaN until phase 1 (plan_uncertainties) */
        for (int t = 0; t < q->nm; ++t)
            part[t] = NAN;
    /* nullity_T > 3: combinations of misalignments (and drift) with A beyond the gauge stay free
     * (with drift: a drift common to all views in the plate frame is a plate error); their
     * values follow a convention and have no uncertainty. O and R depend on G only. */
    if (gauge_matrix(q, Minv_T) != 0)
        return SC_OK;
    int nf = 2 + (q->misalignment_estimable ? q->nm : 0);
    int *slot = malloc(sizeof(int) * ((size_t)q->nm + 1));
    size_t n = (size_t)q->n_red, ng = (size_t)q->ng;
    double *fm = calloc((size_t)q->nm, sizeof(double)), *fg = NULL;
    double *col = malloc(sizeof(double) * n), *z = col; /* phase 0: z0; phase 1: the column */
    if (!slot || !fm || !col || (phase == 0 && !(fg = malloc(sizeof(double) * ng)))) {
        free(slot), free(fm), free(fg), free(col);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    free_misalignments(q, NULL, slot);
    double C[3][3];
    if (phase == 0)
        a_gauge_gram(q, C);
    const double *pg, *pm;
    for (int f = phase == 0 ? 0 : 2; f < nf; ++f) {
        functional_def(q, f, fg ? fg : fm, fm, &pg, &pm); /* phase 1: misalignments only */
        functional_gamma(q, Minv_T, pg, pm, gam);
        int m = (int)ng + f - 2;
        if (phase == 1) { /* r·(Σ e_m) = (Σ e_m)_m − Σ_{t<4} γ_t U_t·col/scale_t − Σ γ_t D_t·col */
            if (slot[f - 2] < 0) { /* a pinned one: its column is 0 */
                q->var_m[f - 2] = part[f - 2] > 0 ? part[f - 2] : 0.0;
                continue;
            }
            if (sc_spsym_inv_column(q->f, slot[f - 2], col) != 0)
                break;
            zero_pinned(q, col, 1);
            double v = col[m];
            for (int t = 0; t < 4; ++t)
                v -= gam[t] / scale[t] * dot(U + (size_t)t * ng, col, ng);
            for (int t = 0; t < 3; ++t)
                v -= gam[4 + t] * dot(D + (size_t)t * n, col, n);
            double var = part[f - 2] + v;
            q->var_m[f - 2] = var > 0 ? var : 0.0;
            continue;
        }
        /* z0 = Σ(r − own) = Σ_s c_s X_s, formed first (a sum of the dot tables' products would
         * lose more to cancellation), then its form: own·z0 − Σ_{t<4} γ_t U_t·z0/scale_t
         * − Σ_{t>=4} γ_t D_t·z0 + Σ γ_t γ_t' C_tt' */
        double c[9];
        for (int t = 0; t < 4; ++t)
            c[t] = -gam[t] / scale[t];
        c[4] = f == 0, c[5] = f == 1;
        for (int t = 0; t < 3; ++t)
            c[6 + t] = -gam[4 + t];
        for (size_t i = 0; i < n; ++i) {
            double v = 0;
            for (int s2 = 0; s2 < 9; ++s2)
                v += c[s2] * X[(size_t)s2 * n + i];
            z[i] = v;
        }
        double var = f < 2 ? dot(fg, z, ng) : z[m];
        for (int t = 0; t < 4; ++t)
            var -= gam[t] / scale[t] * dot(U + (size_t)t * ng, z, ng);
        for (int t = 0; t < 3; ++t)
            var -= gam[4 + t] * dot(D + (size_t)t * n, z, n);
        for (int t = 0; t < 3; ++t)
            for (int u = 0; u < 3; ++u)
                var += gam[4 + t] * gam[4 + u] * C[t][u];
        if (f >= 2)
            part[f - 2] = var;
        else
            *(f == 0 ? &q->var_O : &q->var_R) = var > 0 ? var : 0.0;
    }
    free(fm), free(fg), free(col), free(slot);
    return SC_OK;
}

/* ---------------------------------------------------------------------------------------------
 * Residuals, leverage, standardized residuals (after a solve).
 *
 * With A eliminated in closed form, the hat matrix of the full model is H = P_B + (I-P_B)J S⁺
 * Jᵀ(I-P_B) (whitened), so for equation e of the A group a (total weight W_a):
 *   h_e = w_e/W_a + w_e ãᵀ Σ ã,  ã = ρ_e - Σ_{e'∈a} w_e' ρ_e' / W_a,
 * Σ the pinned inverse of the reduced matrix (a generalized inverse: ã lies in S's row space).
 * The pairs of unknowns ã touches are the group's G nodes and misalignments: the G pairs are
 * entries of S (the group's elimination couples them), so they lie on the factor's pattern and
 * the selected inverse holds them; the misalignment columns of Σ come from nm extra solves.
 * ------------------------------------------------------------------------------------------- */

/* Σ on the misalignments' rows: mrow[t * nm + t'] = Σ(ng + t, ng + t') (0 on pins); slot: the
 * selected inverse's column of each misalignment unknown (-1 pinned). */
static void misalignment_block(const sc_grid_lsq_plan *q, const int *slot, double *mrow,
                               double *tmp)
{
    int nm = q->nm;
    for (int t = 0; t < nm; ++t) {
        if (q->pinned[q->ng + t]) {
            memset(mrow + (size_t)t * nm, 0, sizeof(double) * (size_t)nm);
            continue;
        }
        sc_spsym_inv_cols_at(q->f, q->ng + t, tmp);
        for (int u = 0; u < nm; ++u)
            mrow[(size_t)t * nm + u] = slot[u] < 0 ? 0.0 : tmp[slot[u]];
    }
}

/* Leverage of every equation of group a into h (by equation index). u: the group's unknowns;
 * vec: 2 vectors over them (Σm, then m); sub: Σ's block on them; mrow: misalignment_block;
 * grow: scratch of ROW_MAX·(group size) x n_track (the G unknowns' rows of Σ's whole columns). */
static void group_leverage(const sc_grid_lsq_plan *q, const int *slot, const double *mrow, int a,
                           int *u, double *vec, double *sub, double *grow, double *h)
{
    long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
    int idx[ROW_MAX], nu = 0, ng = q->ng, nm = q->nm;
    double val[ROW_MAX], W = 0;
    for (long t = 0; t < cnt; ++t) {
        long e = q->grp_eq[g0 + t];
        int len = eq_row(q, e, idx, val);
        W += q->eq_w[e];
        for (int r = 0; r < len; ++r) {
            int f = 0;
            while (f < nu && u[f] != idx[r])
                ++f;
            if (f == nu)
                u[nu++] = idx[r];
        }
    }
    double *mean = vec + nu;
    memset(mean, 0, sizeof(double) * (size_t)nu);
    for (long t = 0; t < cnt; ++t) {
        long e = q->grp_eq[g0 + t];
        int len = eq_row(q, e, idx, val);
        for (int r = 0; r < len; ++r)
            for (int f = 0; f < nu; ++f)
                if (u[f] == idx[r])
                    mean[f] += q->eq_w[e] * val[r] / W;
    }
    /* Σ's block on the group's unknowns: G pairs from the selected inverse (on S's pattern), G
     * with a misalignment from the G unknown's row of the whole columns (fetched once), two
     * misalignments from mrow */
    int nt = 0;
    for (int t = 0; t < nm; ++t)
        nt += slot[t] >= 0;
    for (int i = 0; i < nu; ++i)
        if (u[i] < ng && !q->pinned[u[i]])
            sc_spsym_inv_cols_at(q->f, u[i], grow + (size_t)i * nt);
    for (int i = 0; i < nu; ++i)
        for (int j = i; j < nu; ++j) {
            int ui = u[i], uj = u[j];
            double v;
            if (q->pinned[ui] || q->pinned[uj])
                v = 0.0;
            else if (ui < ng && uj < ng)
                v = sc_spsym_inv(q->f, ui, uj);
            else if (ui >= ng && uj >= ng)
                v = mrow[(size_t)(ui - ng) * nm + (uj - ng)];
            else if (ui < ng)
                v = grow[(size_t)i * nt + slot[uj - ng]];
            else
                v = grow[(size_t)j * nt + slot[ui - ng]];
            sub[i * nu + j] = sub[j * nu + i] = v;
        }
    double *sm = vec, msm = 0;
    for (int i = 0; i < nu; ++i) {
        double v = 0;
        for (int j = 0; j < nu; ++j)
            v += sub[i * nu + j] * mean[j];
        sm[i] = v;
        msm += mean[i] * v;
    }
    for (long t = 0; t < cnt; ++t) {
        long e = q->grp_eq[g0 + t];
        int len = eq_row(q, e, idx, val), pos[ROW_MAX];
        for (int r = 0; r < len; ++r) {
            int f = 0;
            while (u[f] != idx[r])
                ++f;
            pos[r] = f;
        }
        double quad = msm;
        for (int r = 0; r < len; ++r) {
            double v = -2 * sm[pos[r]];
            for (int c = 0; c < len; ++c)
                v += sub[pos[r] * nu + pos[c]] * val[c];
            quad += val[r] * v;
        }
        h[e] = q->eq_w[e] / W + q->eq_w[e] * quad;
    }
}

/* q->eq_h: the leverage of every equation (after the selected inverse). */
static sc_status leverages(sc_grid_lsq_plan *q, sc_error *err)
{
    int maxg = 0, nm = q->nm;
    int *slot = malloc(sizeof(int) * ((size_t)nm + 1));
    if (!slot)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (leverage)");
    int k = free_misalignments(q, NULL, slot);
    for (int a = 0; a < 2 * q->nn; ++a)
        if (q->grp_ptr[a + 1] - q->grp_ptr[a] > maxg)
            maxg = (int)(q->grp_ptr[a + 1] - q->grp_ptr[a]);
    int mu = ROW_MAX * maxg + 1;
    int *u = malloc(sizeof(int) * (size_t)mu);
    double *vec = malloc(sizeof(double) * 2 * (size_t)mu);
    double *sub = malloc(sizeof(double) * (size_t)mu * mu);
    double *grow = malloc(sizeof(double) * ((size_t)mu * (k + 1)));
    double *mrow = malloc(sizeof(double) * ((size_t)nm * nm + 1));
    double *tmp = malloc(sizeof(double) * ((size_t)nm + 1));
    if (!q->eq_h)
        q->eq_h = malloc(sizeof(double) * (size_t)(q->neq + 1));
    sc_status st = SC_OK;
    if (!u || !vec || !sub || !grow || !mrow || !tmp || !q->eq_h)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (leverage)");
    else {
        misalignment_block(q, slot, mrow, tmp);
        for (int a = 0; a < 2 * q->nn; ++a)
            if (q->grp_ptr[a + 1] > q->grp_ptr[a])
                group_leverage(q, slot, mrow, a, u, vec, sub, grow, q->eq_h);
    }
    free(u), free(vec), free(sub), free(grow), free(mrow), free(tmp), free(slot);
    return st;
}

/* Everything of an identifying plan that does not depend on the measured values. First blocked
 * solves on the factor: W = ΣU (the gauge columns, 4) for the projection's part of every node's
 * σ, and B = Σ·functional_basis_rhs (5) for the σ of O and R; then the selected inverse (kept: the
 * diagonal, the G pairs on S's pattern, the free misalignments' whole columns) for diag(Σ), the
 * misalignments' σ and every leverage. The selected inverse and the columns are dropped after.
 * W and B are two solves, so that every node's σ is the same to the last bit whether or not the
 * σ of O, R and the misalignments is asked for (node_sigma_only skips B and what uses it: 10 ms
 * of the 0.15 s grid command at N = 101). No iterative refinement: diag(Σ) and the misalignment
 * columns come from the recurrences on the same factor, so refined columns would not make the
 * results more accurate (docs/grid-lsq.md). */
static sc_status plan_uncertainties(sc_grid_lsq_plan *q, sc_error *err)
{
    size_t n = (size_t)q->n_red, ng = (size_t)q->ng;
    int functionals = !q->node_sigma_only;
    double *U = malloc(sizeof(double) * 4 * ng);
    double *WB = sc_big_alloc((functionals ? 9 : 4) * n, sizeof(double), 0); /* W: 0-3, B: 4-8 */
    double *D = NULL, *fg = NULL, *uA = NULL;
    double scale[4], *W = NULL, *B = NULL;
    double *part = malloc(sizeof(double) * ((size_t)q->nm + 1));
    int *last = malloc(sizeof(int) * ((size_t)q->nm + 1));
    int n_last = last ? free_misalignments(q, last, NULL) : 0;
    q->var_m = malloc(sizeof(double) * (size_t)q->nm);
    sc_status st = SC_OK;
    if (functionals) {
        D = malloc(sizeof(double) * 3 * n), fg = malloc(sizeof(double) * ng);
        uA = malloc(sizeof(double) * 2 * (size_t)q->nn);
    }
    if (!U || !WB || (functionals && (!D || !fg || !uA)) || !q->var_m || !part || !last) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto out;
    }
    for (int t = 0; t < q->nm; ++t)
        q->var_m[t] = NAN;
    W = WB, B = functionals ? WB + 4 * n : NULL;
    gauge_basis(q, U, scale);
    for (int c = 0; c < 4; ++c)
        for (size_t i = 0; i < n; ++i)
            W[(size_t)c * n + i] = i < ng ? U[(size_t)c * ng + i] : 0.0;
    if (pinned_solve(q, W, 4, 0, NULL, NULL) != 0) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (solves)");
        goto out;
    }
    sigma_ratios_projection(q, U, W);
    if (functionals) {
        functional_basis_rhs(q, fg, uA, B);
        memcpy(D, B + 2 * n, sizeof(double) * 3 * n);
        if (pinned_solve(q, B, 5, 0, NULL, NULL) != 0) {
            st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (solves)");
            goto out;
        }
        st = functional_variances(q, 0, scale, U, D, WB, part, err);
    }
    /* the selected inverse needs the memory more (U is made again after it; D, 3 columns, is
     * kept: making it again takes 3 passes over the equations) */
    free(U), free(WB), free(fg), free(uA);
    U = WB = fg = uA = NULL;
    if (st != SC_OK)
        goto out;
    progress(q, "selected inverse", q->work_total / 2);
    if (sc_spsym_selinv(q->f, q->ng, last, n_last) != 0) { /* leverages: G pairs on S's pattern */
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (selected inverse)");
        goto out;
    }
    sigma_ratios_finish(q);
    st = leverages(q, err);
    if (st == SC_OK)
        redundancy_info(q);
    if (st == SC_OK && q->misalignment_estimable && functionals) {
        if (!(U = malloc(sizeof(double) * 4 * ng)))
            st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        else {
            gauge_basis(q, U, scale);
            st = functional_variances(q, 1, scale, U, D, NULL, part, err);
        }
        for (int v = 0; v < q->nv; ++v) /* a view's own free columns: no uncertainty there */
            for (int c = 0; q->view_free[v] && c < q->nb; ++c)
                q->var_m[v * q->nb + c] = NAN;
    }
    sc_spsym_drop_inverse(q->f);
out:
    free(U), free(WB), free(D), free(fg), free(uA), free(part), free(last);
    return st;
}

void sc_grid_lsq_fit_misalignments(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                   const sc_grid_result *res, double *m, int *determined)
{
    fit_misalignments(q, d, res->gx_um, res->gy_um, res->ax_um, res->ay_um, 1, m);
    for (int v = 0; determined && v < q->nv; ++v)
        determined[v] = !q->view_free[v];
}

sc_status sc_grid_lsq_residuals(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                const sc_grid_result *res, double *rx_um, double *ry_um,
                                double *tx, double *ty, double *h_out, sc_error *err)
{
    sc_status st = check_data(q, d, err);
    if (st != SC_OK)
        return st;
    if (!res->gx_um || !res->gy_um || !res->ax_um || !res->ay_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "residuals need the result's G and A");
    if (!isfinite(res->sigma_r_used_um))
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "residuals asked before a solve");
    double tscale = residual_scale(res), *m = q->mis_work;
    sc_grid_lsq_fit_misalignments(q, d, res, m, NULL);
    size_t tot = (size_t)q->nv * q->nn;
    double *outs[5] = {rx_um, ry_um, tx, ty, h_out};
    for (int o = 0; o < 5; ++o)
        for (size_t k = 0; outs[o] && k < tot; ++k)
            outs[o][k] = NAN;
    for (long e = 0; e < q->neq; ++e) {
        size_t at = (size_t)q->eq_v[e] * q->nn + (size_t)q->eq_k[e];
        int c = q->eq_c[e], node = q->eq_g[e] / 2, k = q->eq_a[e] / 2;
        double gv = c ? res->gy_um[node] : res->gx_um[node];
        double av = q->eq_a[e] % 2 ? res->ay_um[k] : res->ax_um[k], h = q->eq_h[e];
        double r = eq_residual(q, d, e, gv, av, m);
        double sd = tscale / sqrt(q->eq_w[e]) * sqrt(fmax(0.0, 1.0 - h));
        double t = 1.0 - h > 1e-9 && sd > 0 ? r / sd : NAN;
        if (c == 0) {
            if (rx_um) rx_um[at] = r;
            if (tx) tx[at] = t;
        } else {
            if (ry_um) ry_um[at] = r;
            if (ty) ty[at] = t;
        }
        if (h_out && (c == 0 || !(h_out[at] >= h)))
            h_out[at] = h;
    }
    return SC_OK;
}

sc_status sc_grid_lsq_view_components(const sc_grid_lsq_plan *q, const sc_grid_data *d,
                                      const sc_grid_result *res, double *wrss, double *red,
                                      double *u2, sc_error *err)
{
    sc_status st = check_data(q, d, err);
    if (st != SC_OK)
        return st;
    if (!res->gx_um || !res->gy_um || !res->ax_um || !res->ay_um)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "variance components need G and A");
    double *m = q->mis_work, *cnt = m + q->nm;
    sc_grid_lsq_fit_misalignments(q, d, res, m, NULL);
    for (int v = 0; v < q->nv; ++v)
        wrss[v] = red[v] = u2[v] = cnt[v] = 0;
    for (long e = 0; e < q->neq; ++e) {
        int v = q->eq_v[e], c = q->eq_c[e], node = q->eq_g[e] / 2, k = q->eq_a[e] / 2;
        double gv = c ? res->gy_um[node] : res->gx_um[node];
        double av = q->eq_a[e] % 2 ? res->ay_um[k] : res->ax_um[k];
        double r = eq_residual(q, d, e, gv, av, m);
        wrss[v] += q->eq_w[e] * r * r;
        red[v] += fmax(0.0, 1.0 - q->eq_h[e]);
        u2[v] += 1.0 / q->eq_w[e], cnt[v] += 1;
    }
    for (int v = 0; v < q->nv; ++v)
        u2[v] = cnt[v] > 0 ? u2[v] / cnt[v] : NAN;
    return SC_OK;
}

/* cov (ng x ng) := the G block of the pinned inverse Σ, by blocked solves of unit columns. */
static int pinned_inverse_g(const sc_grid_lsq_plan *q, double *cov)
{
    int ng = q->ng;
    size_t n = (size_t)q->n_red;
    double *X = malloc(sizeof(double) * 3 * n * SOLVE_CHUNK);
    if (!X)
        return -1;
    for (int j0 = 0; j0 < ng; j0 += SOLVE_CHUNK) {
        int k = ng - j0 < SOLVE_CHUNK ? ng - j0 : SOLVE_CHUNK;
        memset(X, 0, sizeof(double) * n * (size_t)k);
        for (int c = 0; c < k; ++c)
            X[(size_t)c * n + (size_t)(j0 + c)] = 1;
        if (pinned_solve(q, X, k, 1, X + n * SOLVE_CHUNK, X + 2 * n * SOLVE_CHUNK) != 0) {
            free(X);
            return -1;
        }
        for (int c = 0; c < k; ++c)
            memcpy(cov + (size_t)(j0 + c) * ng, X + (size_t)c * n, sizeof(double) * (size_t)ng);
    }
    free(X);
    return 0;
}

sc_status sc_grid_lsq_covariance(const sc_grid_lsq_plan *q, const sc_grid_result *res,
                                 double *cov, sc_error *err)
{
    int ng = q->ng;
    if (!q->info.identifiable || !(res->sigma_r_used_um > 0))
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0, "no solution to take a covariance of");
    if (q->ns > SC_GRID_LSQ_COV_MAX_NODES)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the covariance of %d stage nodes is too large (limit %d nodes)",
                            q->ns, SC_GRID_LSQ_COV_MAX_NODES);
    double *U = malloc(sizeof(double) * (size_t)4 * ng);
    double *SU = calloc((size_t)4 * ng, sizeof(double)), scale[4];
    if (!U || !SU || pinned_inverse_g(q, cov) != 0) {
        free(U), free(SU);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (covariance)");
    }
    gauge_basis(q, U, scale);
    /* P⊥ Σ P⊥ = Σ - U(ΣU)ᵀ - (ΣU)Uᵀ + U(UᵀΣU)Uᵀ */
    for (int c = 0; c < 4; ++c)
        for (int i = 0; i < ng; ++i) {
            double s = 0;
            for (int j = 0; j < ng; ++j)
                s += cov[(size_t)i * ng + j] * U[(size_t)c * ng + j];
            SU[(size_t)c * ng + i] = s;
        }
    double M[4][4];
    for (int c = 0; c < 4; ++c)
        for (int d = 0; d < 4; ++d) {
            double s = 0;
            for (int i = 0; i < ng; ++i)
                s += U[(size_t)c * ng + i] * SU[(size_t)d * ng + i];
            M[c][d] = s;
        }
    double v2 = res->sigma_r_used_um * res->sigma_r_used_um;
    for (int i = 0; i < ng; ++i)
        for (int j = 0; j < ng; ++j) {
            double s = cov[(size_t)i * ng + j];
            for (int c = 0; c < 4; ++c) {
                s -= U[(size_t)c * ng + i] * SU[(size_t)c * ng + j] +
                     SU[(size_t)c * ng + i] * U[(size_t)c * ng + j];
                for (int d = 0; d < 4; ++d)
                    s += U[(size_t)c * ng + i] * M[c][d] * U[(size_t)d * ng + j];
            }
            cov[(size_t)i * ng + j] = s * v2;
        }
    free(U), free(SU);
    return SC_OK;
}

/* The prediction of mark (i, j) in view v from its misalignment unknowns mv (nb). */
static void predict_view(const sc_grid_lsq_plan *q, const sc_grid_result *res, const double *mv,
                         int v, int i, int j, double t_s, double *dx_um, double *dy_um)
{
    int ni, nj;
    *dx_um = *dy_um = NAN;
    if (v < 0 || v >= q->nv || i < 0 || i >= q->n || j < 0 || j >= q->n || !res->gx_um ||
        !res->ax_um || !sc_grid_mark_node(&q->plan, v, i, j, &ni, &nj))
        return;
    int node = ni * q->stage_nx + nj, k = i * q->n + j;
    double x, y, rax, ray, phi = mv[2] / (q->L_mm * 1e-3); /* µrad */
    sc_grid_node_xy_mm(&q->plan, ni, nj, &x, &y);
    sc_grid_rotate(q->plan.view[v].rot_deg, res->ax_um[k], res->ay_um[k], &rax, &ray);
    *dx_um = res->gx_um[node] + rax + mv[0] - phi * y * 1e-3;
    *dy_um = res->gy_um[node] + ray + mv[1] + phi * x * 1e-3;
    if (q->drift) {
        *dx_um += mv[3] / q->drift_T[v] * (t_s - q->drift_t0[v]);
        *dy_um += mv[4] / q->drift_T[v] * (t_s - q->drift_t0[v]);
    }
}

void sc_grid_lsq_predict_with(const sc_grid_lsq_plan *q, const sc_grid_result *res,
                              const double *m, int v, int i, int j, double t_s, double *dx_um,
                              double *dy_um)
{
    *dx_um = *dy_um = NAN;
    if (v >= 0 && v < q->nv)
        predict_view(q, res, m + (size_t)v * q->nb, v, i, j, t_s, dx_um, dy_um);
}

void sc_grid_lsq_predict(const sc_grid_lsq_plan *q, const sc_grid_result *res, int v, int i, int j,
                         double t_s, double *dx_um, double *dy_um)
{
    double mv[SC_GRID_LSQ_MAX_NB] = {0};
    *dx_um = *dy_um = NAN;
    if (v < 0 || v >= q->nv || !res->tx_um || !res->ty_um || !res->theta_urad ||
        (q->drift && (!res->vx_um_s || !res->vy_um_s)))
        return; /* no misalignments in res: nothing to predict with */
    mv[0] = res->tx_um[v], mv[1] = res->ty_um[v];
    mv[2] = res->theta_urad[v] * (q->L_mm * 1e-3);
    if (q->drift)
        mv[3] = res->vx_um_s[v] * q->drift_T[v], mv[4] = res->vy_um_s[v] * q->drift_T[v];
    predict_view(q, res, mv, v, i, j, t_s, dx_um, dy_um);
}

/* ---------------------------------------------------------------------------------------------
 * Reference values for the accuracy tests (grid_lsq_internal.h): column solves refined against
 * residuals in long double until they stop changing, independent of the selected inverse.
 * ------------------------------------------------------------------------------------------- */

/* y = S x (the pinned matrix), in long double. */
static void matvec_long(const sc_grid_lsq_plan *q, const long double *x, long double *y)
{
    for (int i = 0; i < q->n_red; ++i)
        y[i] = 0;
    for (int j = 0; j < q->n_red; ++j)
        for (long p = q->Ap[j]; p < q->Ap[j + 1]; ++p) {
            int i = q->Ai[p];
            y[i] += (long double)q->Ax[p] * x[j];
            if (i != j)
                y[j] += (long double)q->Ax[p] * x[i];
        }
}

/* vᵀ Σ v (Σ the pinned inverse, 0 on pins) by a refined solve; -1 if memory ran out. */
static double exact_quad(const sc_grid_lsq_plan *q, const double *v, double *b, long double *x,
                         long double *r)
{
    int n = q->n_red;
    for (int i = 0; i < n; ++i)
        b[i] = q->pinned[i] ? 0.0 : v[i];
    for (int i = 0; i < n; ++i)
        x[i] = 0;
    for (int it = 0; it < 6; ++it) {
        matvec_long(q, x, r);
        for (int i = 0; i < n; ++i)
            b[i] = q->pinned[i] ? 0.0 : (double)((long double)v[i] - r[i]);
        if (sc_spsym_solve(q->f, b, 1) != 0)
            return -1;
        for (int i = 0; i < n; ++i)
            x[i] += q->pinned[i] ? 0.0L : (long double)b[i];
    }
    long double s = 0;
    for (int i = 0; i < n; ++i)
        s += q->pinned[i] ? 0.0L : (long double)v[i] * x[i];
    return (double)s;
}

/* Var/σ0² of every misalignment unknown by refined solves into var (NaN where the plan has
 * none): uᵀΣu = rᵀΣr + Σ_a u_A[a]²/W_a with r = u_x − a_correction(u_A). */
static int reference_misalignments(const sc_grid_lsq_plan *q, double *var, double *b,
                                   long double *x, long double *r)
{
    double Minv_T[49], gam[7];
    int n = q->n_red;
    for (int t = 0; t < q->nm; ++t)
        var[t] = NAN;
    if (!q->misalignment_estimable || gauge_matrix(q, Minv_T) != 0)
        return 0;
    double *fm = calloc((size_t)q->nm, sizeof(double)), *ux = malloc(sizeof(double) * (size_t)n);
    double *rv = malloc(sizeof(double) * (size_t)n), *zero = calloc((size_t)n, sizeof(double));
    double *uA = malloc(sizeof(double) * 2 * (size_t)q->nn);
    int rc = fm && ux && rv && zero && uA ? 0 : -1;
    for (int t = 0; rc == 0 && t < q->nm; ++t) {
        memset(fm, 0, sizeof(double) * (size_t)q->nm);
        fm[t] = 1;
        functional_vectors(q, Minv_T, NULL, fm, ux, uA, gam);
        memcpy(rv, ux, sizeof(double) * (size_t)n);
        a_correction(q, uA, rv);
        double quad = exact_quad(q, rv, b, x, r);
        if (quad < 0)
            rc = -1;
        var[t] = quad + functional_form(q, ux, uA, zero, 1);
    }
    free(fm), free(ux), free(rv), free(zero), free(uA);
    return rc;
}

int sc_grid_lsq_reference_misalignments(const sc_grid_lsq_plan *q, double *var_ref,
                                        double *var_plan)
{
    int n = q->n_red;
    double *b = malloc(sizeof(double) * (size_t)n);
    long double *x = malloc(sizeof(long double) * (size_t)n);
    long double *r = malloc(sizeof(long double) * (size_t)n);
    int rc = b && x && r && q->var_m ? reference_misalignments(q, var_ref, b, x, r) : -1;
    for (int t = 0; rc == 0 && t < q->nm; ++t) {
        var_plan[t] = q->var_m[t];
        if (q->view_free[t / q->nb])
            var_ref[t] = NAN;
    }
    free(b), free(x), free(r);
    return rc;
}

int sc_grid_lsq_reference(const sc_grid_lsq_plan *q, int nsample, int *node, double *sx_ref,
                          double *sx_plan, long *eq, double *h_ref, double *h_plan)
{
    int n = q->n_red, ng = q->ng;
    double *v = calloc((size_t)n, sizeof(double)), *b = malloc(sizeof(double) * (size_t)n);
    double *U = malloc(sizeof(double) * 4 * (size_t)ng), scale[4];
    long double *x = malloc(sizeof(long double) * (size_t)n);
    long double *r = malloc(sizeof(long double) * (size_t)n);
    int rc = -1;
    if (!v || !b || !U || !x || !r || !q->sgx || !q->eq_h)
        goto out;
    gauge_basis(q, U, scale);
    for (int s = 0; s < nsample; ++s) {
        /* σ_x of a node: (P⊥e)ᵀ Σ (P⊥e) */
        int k = (int)((long)s * q->ns / nsample), i = 2 * k;
        memset(v, 0, sizeof(double) * (size_t)n);
        v[i] = 1;
        for (int t = 0; t < 4; ++t)
            for (int j = 0; j < ng; ++j)
                v[j] -= U[(size_t)t * ng + i] * U[(size_t)t * ng + j];
        double var = exact_quad(q, v, b, x, r);
        node[s] = k;
        sx_ref[s] = sqrt(var > 0 ? var : 0);
        sx_plan[s] = q->sgx[k];
        /* the leverage of an equation: w_e/W_a + w_e ãᵀΣã, ã = ρ_e − the group's mean row */
        long e = (long)((double)s * q->neq / nsample);
        int a = q->eq_a[e], idx[ROW_MAX];
        double val[ROW_MAX], W = 0;
        memset(v, 0, sizeof(double) * (size_t)n);
        for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t)
            W += q->eq_w[q->grp_eq[t]];
        for (long t = q->grp_ptr[a]; t < q->grp_ptr[a + 1]; ++t) {
            long e2 = q->grp_eq[t];
            int len = eq_row(q, e2, idx, val);
            for (int c = 0; c < len; ++c)
                v[idx[c]] -= q->eq_w[e2] * val[c] / W;
        }
        int len = eq_row(q, e, idx, val);
        for (int c = 0; c < len; ++c)
            v[idx[c]] += val[c];
        eq[s] = e;
        h_ref[s] = q->eq_w[e] / W + q->eq_w[e] * exact_quad(q, v, b, x, r);
        h_plan[s] = q->eq_h[e];
    }
    rc = 0;
out:
    free(v), free(b), free(U), free(x), free(r);
    return rc;
}

/* ---------------------------------------------------------------------------------------------
 * The plate's magnification m = 1e3·Σ(x·Ax + y·Ay)/Σ(x² + y²) over the measured marks (ppm) of
 * the gauged solution: the functional that moves to the stage when the plate's scale is
 * certified (SPEC §11, grid_scale.c). Var(m)/σ0² = uᵀΣu with u = Qᵀf as for O and R; and
 * Cov(G, m)/σ0² = the G part of Q Σ u, which is P⊥ of the G part of the pinned solve z = Σu
 * (Q's G patterns are P⊥'s).
 * ------------------------------------------------------------------------------------------- */
int sc_grid_lsq_plate_magnification(const sc_grid_lsq_plan *q, double *var_m, double *cov_gx,
                                    double *cov_gy)
{
    double Minv_T[49], Nf[7] = {0}, gam[7] = {0}, r2 = 0;
    if (!q->info.identifiable || gauge_matrix(q, Minv_T) != 0)
        return -1;
    size_t n = (size_t)q->n_red, nn2 = 2 * (size_t)q->nn;
    double *fA = calloc(nn2, sizeof(double)), *uA = calloc(nn2, sizeof(double));
    double *ux = calloc(n, sizeof(double)), *z = malloc(sizeof(double) * n * 3);
    if (!fA || !uA || !ux || !z) {
        free(fA), free(uA), free(ux), free(z);
        return -1;
    }
    for (int k = 0; k < q->nn; ++k)
        if (q->mark_views[k]) {
            double x, y;
            sc_grid_mark_xy_mm(&q->plan, k / q->n, k % q->n, &x, &y);
            r2 += x * x + y * y;
        }
    for (int k = 0; k < q->nn; ++k) {
        double x, y, na[7][2];
        if (!q->mark_views[k] || !(r2 > 0))
            continue;
        sc_grid_mark_xy_mm(&q->plan, k / q->n, k % q->n, &x, &y);
        fA[2 * k] = 1e3 * x / r2, fA[2 * k + 1] = 1e3 * y / r2;
        null_a(q, k, na);
        for (int t = 0; t < 7; ++t)
            Nf[t] += na[t][0] * fA[2 * k] + na[t][1] * fA[2 * k + 1];
    }
    for (int i = 0; i < 7; ++i)
        for (int j = 0; j < 7; ++j)
            gam[i] += Minv_T[i * 7 + j] * Nf[j];
    for (int k = 0; k < q->ns; ++k) { /* u = f − Σ_t γ_t C_t: f has no G part */
        double cg[7][2];
        gauge_g(q, k, cg);
        for (int c = 0; c < 2; ++c)
            for (int t = 0; t < 7; ++t)
                ux[2 * k + c] -= gam[t] * cg[t][c];
    }
    for (int k = 0; k < q->nn; ++k) {
        double ca[7][2];
        gauge_a(q, k, ca);
        for (int c = 0; c < 2; ++c) {
            double v = fA[2 * k + c];
            for (int t = 0; t < 7; ++t)
                v -= gam[t] * ca[t][c];
            uA[2 * k + c] = v;
        }
    }
    memcpy(z, ux, sizeof(double) * n);
    a_correction(q, uA, z); /* r = u_x − a_correction(u_A) */
    int rc = pinned_solve(q, z, 1, 2, z + n, z + 2 * n);
    if (rc == 0) {
        double v = functional_form(q, ux, uA, z, 1);
        *var_m = v > 0 ? v : 0.0;
        for (int k = 0; k < q->ns; ++k)
            cov_gx[k] = z[2 * k], cov_gy[k] = z[2 * k + 1];
        sc_grid_gauge_stage(&q->plan, cov_gx, cov_gy);
    }
    free(fA), free(uA), free(ux), free(z);
    return rc;
}
