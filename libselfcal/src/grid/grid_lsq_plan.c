/* The least-squares grid estimator's plan (docs/grid-lsq.md; the method is described at the top
 * of grid_lsq_internal.h): the scalar equations of a view plan, the gauge pins, the
 * identifiability analysis, the assembly of the reduced pinned normal matrix and its
 * factorization, and the plan's accessors. The uncertainties the plan computes are in
 * grid_lsq_functionals.c. */
#include "grid_lsq_internal.h"

#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/big_alloc.h"
#include "selfcal/grid_sim.h"

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
    sc_lsq_full_destroy(q->full);
    free(q->m_rows);
    free(q);
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

/* The arrays of the q->neq scalar equations and their groups by A component. */
static sc_status equations_alloc(sc_grid_lsq_plan *q, sc_error *err)
{
    long ne = q->neq + 1;
    q->eq_g = malloc(sizeof(int) * ne);
    q->eq_v = malloc(sizeof(int) * ne);
    q->eq_k = malloc(sizeof(int) * ne);
    q->eq_a = malloc(sizeof(int) * ne);
    q->eq_c = malloc(ne);
    q->eq_s = malloc(ne);
    q->eq_pos = malloc(sizeof(double) * ne);
    q->grp_ptr = calloc((size_t)2 * q->nn + 1, sizeof(long));
    q->grp_eq = malloc(sizeof(long) * ne);
    q->eq_w = malloc(sizeof(double) * ne);
    q->eq_dt = calloc((size_t)ne, sizeof(double));
    if (!q->eq_g || !q->eq_v || !q->eq_k || !q->eq_a || !q->eq_c || !q->eq_s || !q->eq_pos ||
        !q->grp_ptr || !q->grp_eq || !q->eq_w || !q->eq_dt)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    return SC_OK;
}

/* The two equations (dx, dy) of view v's mark k, from e on: node, view, mark, A component and
 * sign, the φ coefficient, weight; each counted into its A component's group. */
static sc_status mark_equations(sc_grid_lsq_plan *q, const sc_grid_data *mask, int v, int k,
                                long e, sc_error *err)
{
    const sc_grid_plan *p = &q->plan;
    int n = q->n, ni, nj;
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
    return SC_OK;
}

/* The equations of each A component in a row (q->grp_eq), from the counts in q->grp_ptr. */
static sc_status group_equations(sc_grid_lsq_plan *q, sc_error *err)
{
    int nn = q->nn;
    for (int a = 0; a < 2 * nn; ++a)
        q->grp_ptr[a + 1] += q->grp_ptr[a];
    long *fill = malloc(sizeof(long) * (size_t)(2 * nn));
    if (!fill)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    memcpy(fill, q->grp_ptr, sizeof(long) * (size_t)(2 * nn));
    for (long e = 0; e < q->neq; ++e)
        q->grp_eq[fill[q->eq_a[e]]++] = e;
    free(fill);
    return SC_OK;
}

/* The scalar equations (2 per measured mark): node, view, mark, A component and sign, the φ
 * coefficient, weight; grouped by A component; the drift columns. */
static sc_status build_equations(sc_grid_lsq_plan *q, const sc_grid_data *mask, sc_error *err)
{
    int nn = q->nn, nv = q->nv;
    q->weighted = !q->unit_weights && stated_weights(q, mask);
    sc_status st = measured_marks(q, mask, err);
    if (st == SC_OK)
        st = equations_alloc(q, err);
    long e = 0;
    for (int v = 0; v < nv && st == SC_OK; ++v)
        for (int k = 0; k < nn && st == SC_OK; ++k)
            if (q->meas[v * nn + k]) {
                st = mark_equations(q, mask, v, k, e, err);
                e += 2;
            }
    if (st == SC_OK)
        st = group_equations(q, err);
    if (st != SC_OK)
        return st;
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
            int l = sc_lsq_eq_row(q, e, li + len, lv + len);
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

/* For g_block_cols: Wg[a] the weight of A component a's group; ep, eg the equations at each G
 * unknown (eg[ep[j] .. ep[j+1]) those at j; cp is work). Returns the bound on the entries: the
 * sum of the group sizes over the equations. */
static long g_equations_by_unknown(const sc_grid_lsq_plan *q, double *Wg, long *ep, long *cp,
                                   long *eg)
{
    int ng = q->ng, n2 = 2 * q->nn;
    long bound = 0;
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
    return bound;
}

/* For g_block_cols: column j (not pinned) into acc at the rows touched[0 .. return value), in
 * the order first touched (mark[i] = j once row i is). */
static int g_column(const sc_grid_lsq_plan *q, int j, const long *ep, const long *eg,
                    const double *Wg, double *acc, int *mark, int *touched)
{
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
    return nt;
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
    bound = g_equations_by_unknown(q, Wg, ep, cp, eg);
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
        int nt = g_column(q, j, ep, eg, Wg, acc, mark, touched);
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
    int n_last = sc_lsq_free_misalignments(q, last, NULL);
    sc_spsym_hint hint = {1, q->ng, last, n_last};
    sc_lsq_progress(q, "analyse", 0);
    int arc = sc_spsym_analyze(q->n_fac, q->Ap, q->Ai, &hint, &q->f);
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
    double groups = q->full ? 0.0 : sizeof(double) * (double)q->ng * q->nm;
    /* without the selected inverse (node_sigma none or sampled): the factor and the solves' */
    double held = q->node_sigma == SC_GRID_NODE_SIGMA_ALL ? 3.0 : 1.5;
    double need = (double)q->bytes - groups + held * (double)sc_spsym_factor_bytes(q->f);
    if (need > q->peak_est)
        q->peak_est = need;
    if (q->max_bytes > 0 && need > q->max_bytes)
        return memory_refused(q, need, err);
    sc_spsym_stats fs;
    sc_spsym_get_stats(q->f, &fs);
    /* the selected inverse (every node's σ) costs about what the factor does (docs/grid-lsq.md) */
    q->work_total = fs.factor_flops * 2;
    sc_lsq_progress(q, "factor", 0);
    if (sc_spsym_factor(q->f, q->Ax, LSQ_PIVOT_TOL) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, LSQ_NOMEM_MSG);
    if (!(q->work_total > 0)) { /* a backend that counts the flops as it factors */
        sc_spsym_get_stats(q->f, &fs);
        q->work_total = fs.factor_flops * 2;
    }
    q->nullity_pin = sc_spsym_nullity(q->f);
    return SC_OK;
}

/* The misalignment block's nullity is found densely up to this many misalignments: 600, or
 * the plate's A components (2N²) where there are more, since the sparse rule's factor holds their
 * dense block (docs/grid-lsq.md, "The misalignment block's nullity"). */
static int lsq_mm_dense_max(const sc_grid_lsq_plan *q)
{
    return 2 * q->nn > LSQ_MM_DENSE_MAX ? 2 * q->nn : LSQ_MM_DENSE_MAX;
}

/* With A kept (grid_lsq_full.h): the misalignment block alone (G held at 0, A eliminated) for
 * its nullity, then the full pinned matrix, ordered (the free misalignments last) and factored
 * as the reduced one. */
static sc_status build_and_factor_full(sc_grid_lsq_plan *q, const sc_lsq_full_desc *fd,
                                       sc_error *err)
{
    int nm = q->nm;
    /* the misalignment block: dense up to LSQ_MM_DENSE_MAX unknowns, else sparse (its pattern
     * the views that share a mark, far below the full matrix's own entries) */
    q->peak_est = (double)q->bytes + sc_lsq_full_matrix_bytes(fd) +
                  sizeof(double) * (nm <= lsq_mm_dense_max(q) ? (double)nm * nm
                                                              : 0.5 * 4.0 * q->nn * q->nn);
    sc_lsq_progress(q, "assemble", 0);
    if (q->max_bytes > 0 && q->peak_est > q->max_bytes)
        return memory_refused(q, q->peak_est, err);
    q->nullity_T = sc_lsq_misalignment_nullity(fd, lsq_mm_dense_max(q));
    if (q->nullity_T == -2)
        return sc_error_set(err, SC_E_IO, NULL, 0,
                            "the sparse solver library libcholmod.so (SuiteSparse CHOLMOD) "
                            "cannot be loaded");
    if (q->nullity_T == -3)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0,
                            "out of memory: the address space limit (ulimit -v) leaves less than "
                            "768 MiB for the sparse solver (CHOLMOD and OpenBLAS, which would hang "
                            "rather than fail below that)");
    if (q->nullity_T < 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, LSQ_NOMEM_MSG);
    if (sc_lsq_full_assemble(fd, &q->full, &q->Ap, &q->Ai, &q->Ax, &q->n_fac) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, LSQ_NOMEM_MSG);
    q->bytes += (size_t)q->Ap[q->n_fac] * (sizeof(int) + sizeof(double)) +
                (size_t)(q->n_fac + 1) * sizeof(long) + sc_lsq_full_bytes(q->full);
    return factor_matrix(q, err);
}

/* Assemble the reduced (A-eliminated) matrix, pin, order and factor; the nullity of the
 * misalignment block alone (G held at 0). */
static sc_status build_and_factor(sc_grid_lsq_plan *q, sc_error *err)
{
    int nm = q->nm;
    sc_lsq_full_desc fd;
    sc_lsq_full_desc_of(q, &fd);
    if (q->solver == SC_GRID_SOLVER_FULL ||
        (q->solver != SC_GRID_SOLVER_REDUCED && sc_lsq_full_preferred(&fd)))
        return build_and_factor_full(q, &fd, err);
    q->peak_est = assembly_bytes(q); /* with the node-misalignment couplings, ng x nm */
    sc_lsq_progress(q, "assemble", 0);
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
    q->nullity_T = sc_lsq_small_nullity(mmT, nm, LSQ_SMALL_TOL);
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
    q->solver = opts ? opts->solver : SC_GRID_SOLVER_AUTO;
    q->node_sigma = opts ? opts->node_sigma : SC_GRID_NODE_SIGMA_ALL;
    q->node_sigma_sample = opts ? opts->node_sigma_sample : 0;
    q->nb = q->drift ? 5 : 3;
    q->L_mm = (plan->n - 1) / 2 * plan->pitch_mm;
    q->ng = 2 * q->ns;
    q->nm = q->nb * q->nv;
    q->n_red = q->ng + q->nm;
    q->n_fac = q->n_red;
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
        sc_lsq_view_normal_add(q, e, idx, val, sc_lsq_eq_row(q, e, idx, val), nrm);
    for (int v = 0; v < q->nv; ++v) {
        int kept = sc_lsq_fit_view(nrm + (size_t)v * nb * nb, zero, nb, m);
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
        st = sc_lsq_plan_uncertainties(q, err);
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
    *n = q->n_fac;
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
    st->nnz_matrix = q->Ap ? q->Ap[q->n_fac] : 0;
    st->solver = q->full ? SC_GRID_SOLVER_FULL : SC_GRID_SOLVER_REDUCED;
    st->n_factored = q->n_fac;
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
