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
 * 3. The pinned matrix is factored by sparse LDLᵀ (nested-dissection order on G, the 3V
 *    misalignments last as a dense border); null pivots are decided with a relative tolerance.
 * 4. Per-node variances: Cov(G)/σ² = P⊥ Σ P⊥ with Σ = pinned inverse (zero on pins); diag(Σ) by
 *    the Takahashi selected inverse, the projection with 4 extra solves (ΣU).
 */
#include "selfcal/grid_lsq.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sparse_sym.h"

#define LSQ_PIVOT_TOL 1e-9 /* pivot / original diagonal below this: null */
#define LSQ_SMALL_TOL 1e-11 /* relative tolerance of the small dense rank decision */

struct sc_grid_lsq {
    sc_grid_plan plan;
    int n, nn, nv;
    double L_mm;            /* rotation scale c·P */
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
    int ng, nm, nx;
    long *Ap;               /* the pinned reduced matrix: upper CSC, original index space */
    int *Ai;
    double *Ax;
    sc_spsym *f;            /* its factorization (sparse_sym.h) */
    unsigned char *pinned;  /* per unknown (original index) */
    int pin_node[2], pin_view;
    int nullity_pin, nullity_T;
    sc_grid_lsq_info info;
    long rank;
    double *sgx, *sgy;      /* std/σ_r per node (NaN if not identified) */
    double *work;           /* nx: solves */
    double *work2;          /* nx */
    size_t bytes;
};

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

void sc_grid_lsq_destroy(sc_grid_lsq *q)
{
    if (!q)
        return;
    free(q->meas), free(q->mark_views), free(q->eq_g), free(q->eq_v), free(q->eq_k);
    free(q->eq_a), free(q->eq_c), free(q->eq_s), free(q->eq_pos), free(q->grp_ptr);
    free(q->grp_eq), free(q->Ap), free(q->Ai), free(q->Ax);
    free(q->pinned), free(q->sgx), free(q->sgy), free(q->work), free(q->work2);
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
    int *piv = malloc(sizeof(int) * (size_t)m);
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
    free(piv);
    return m - r;
}

typedef struct triplet {
    int i, j;
    double v;
} triplet;

/* Coefficients of w_e = s_e·J_e over x = (g, m): up to 3 (index, value) pairs. */
static int eq_row(const sc_grid_lsq *q, long e, int *idx, double *val)
{
    double s = q->eq_s[e];
    idx[0] = q->eq_g[e];
    val[0] = s;
    idx[1] = q->ng + 3 * q->eq_v[e] + q->eq_c[e];
    val[1] = s;
    idx[2] = q->ng + 3 * q->eq_v[e] + 2;
    val[2] = s * q->eq_pos[e];
    return 3;
}

static sc_status build_equations(sc_grid_lsq *q, const sc_grid_data *mask, sc_error *err)
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
    if (!q->eq_g || !q->eq_v || !q->eq_k || !q->eq_a || !q->eq_c || !q->eq_s || !q->eq_pos ||
        !q->grp_ptr || !q->grp_eq)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    long e = 0;
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k) {
            if (!q->meas[v * nn + k])
                continue;
            int ni, nj;
            sc_grid_mark_node(p, v, k / n, k % n, &ni, &nj);
            int node = ni * n + nj;
            double x, y;
            sc_grid_node_xy_mm(p, ni, nj, &x, &y);
            for (int c = 0; c < 2; ++c, ++e) {
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
    return SC_OK;
}

/* Pins: both G components of two far-apart nodes that equations touch, and one view's
 * misalignment (the view with the most measurements). */
static void choose_pins(sc_grid_lsq *q)
{
    int n = q->n;
    int *seen = calloc((size_t)q->nn, sizeof(int));
    int best_lo = -1, best_hi = -1, lo = 1 << 30, hi = -1;
    if (seen) {
        for (long e = 0; e < q->neq; ++e)
            seen[q->eq_g[e] / 2] = 1;
        for (int k = 0; k < q->nn; ++k) {
            if (!seen[k])
                continue;
            int s = k / n + k % n;
            if (s < lo)
                lo = s, best_lo = k;
            if (s > hi)
                hi = s, best_hi = k;
        }
        free(seen);
    }
    if (best_lo < 0 || best_hi == best_lo) /* at most one node measured: no useful pin */
        best_lo = 0, best_hi = q->nn - 1;
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
        q->pinned[q->ng + 3 * bestv + t] = 1;
}

/* Assemble the reduced (A-eliminated) matrix, order, pin and factor. */
static sc_status build_and_factor(sc_grid_lsq *q, sc_error *err)
{
    int ng = q->ng, nm = q->nm, nx = q->nx;
    sc_status st = SC_E_NOMEM;
    triplet *tr = NULL;
    double *gm = NULL, *mm = NULL, *mmT = NULL;
    long *rp = NULL;
    int *ri = NULL, *last = NULL;
    double *rv = NULL;
    long ntr = 0, cap = 0;
    for (int a = 0; a < 2 * q->nn; ++a) {
        long c = q->grp_ptr[a + 1] - q->grp_ptr[a];
        if (c > 1)
            cap += c * c + c;
    }
    tr = malloc(sizeof(triplet) * (size_t)(cap + 1));
    gm = calloc((size_t)ng * nm, sizeof(double));
    mm = calloc((size_t)nm * nm, sizeof(double));
    mmT = malloc(sizeof(double) * (size_t)nm * nm);
    if (!tr || !gm || !mm || !mmT)
        goto out;
    q->bytes += sizeof(triplet) * (size_t)cap + sizeof(double) * (size_t)ng * nm;
    int maxg = 0;
    for (int a = 0; a < 2 * q->nn; ++a) {
        long c = q->grp_ptr[a + 1] - q->grp_ptr[a];
        if (c > maxg)
            maxg = (int)c;
    }
    int *li = malloc(sizeof(int) * (size_t)(3 * maxg + 1));
    double *lv = malloc(sizeof(double) * (size_t)(3 * maxg + 1));
    if (!li || !lv) {
        free(li), free(lv);
        goto out;
    }
    for (int a = 0; a < 2 * q->nn; ++a) {
        long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
        if (cnt < 2)
            continue; /* a mark seen once: its A absorbs the equation */
        int len = 0;
        for (long t = 0; t < cnt; ++t)
            len += eq_row(q, q->grp_eq[g0 + t], li + len, lv + len);
        /* Σ w_e w_eᵀ (each w_e: 3 consecutive entries) - (Σ w_e)(Σ w_e)ᵀ / cnt */
        for (int pass = 0; pass < 2; ++pass) {
            double coef = pass == 0 ? 1.0 : -1.0 / (double)cnt;
            for (int x = 0; x < len; ++x)
                for (int y = 0; y < len; ++y) {
                    if (pass == 0 && x / 3 != y / 3)
                        continue;
                    int i = li[x], j = li[y];
                    double v = coef * lv[x] * lv[y];
                    if (i < ng && j < ng) {
                        if (i <= j)
                            tr[ntr++] = (triplet){i, j, v};
                    } else if (i < ng) {
                        gm[(size_t)i * nm + (j - ng)] += v;
                    } else if (j >= ng) {
                        mm[(size_t)(i - ng) * nm + (j - ng)] += v;
                    }
                }
        }
    }
    free(li), free(lv);
    /* rank deficiency of the misalignment block alone (G held at 0) */
    memcpy(mmT, mm, sizeof(double) * (size_t)nm * nm);
    q->nullity_T = small_nullity(mmT, nm, LSQ_SMALL_TOL);
    if (q->nullity_T < 0)
        goto out;
    /* upper CSR of the G block, duplicates summed, pins removed */
    rp = calloc((size_t)ng + 1, sizeof(long));
    if (!rp)
        goto out;
    for (long t = 0; t < ntr; ++t)
        rp[tr[t].i + 1]++;
    for (int i = 0; i < ng; ++i)
        rp[i + 1] += rp[i];
    ri = malloc(sizeof(int) * (size_t)(ntr + 1));
    rv = malloc(sizeof(double) * (size_t)(ntr + 1));
    last = malloc(sizeof(int) * (size_t)(ng + 1));
    long *fill = malloc(sizeof(long) * (size_t)(ng + 1));
    if (!ri || !rv || !last || !fill) {
        free(fill);
        goto out;
    }
    memcpy(fill, rp, sizeof(long) * (size_t)ng);
    for (long t = 0; t < ntr; ++t) {
        long pos = fill[tr[t].i]++;
        ri[pos] = tr[t].j;
        rv[pos] = tr[t].v;
    }
    free(fill);
    free(tr);
    tr = NULL;
    for (int i = 0; i < ng; ++i)
        last[i] = -1;
    long w = 0;
    for (int i = 0; i < ng; ++i) {
        long p0 = rp[i], p1 = rp[i + 1], start = w;
        rp[i] = start;
        for (long p = p0; p < p1; ++p) {
            int j = ri[p];
            if (q->pinned[i] || q->pinned[j])
                continue;
            if (last[j] >= start) {
                rv[last[j]] += rv[p];
            } else {
                last[j] = (int)w;
                ri[w] = j;
                rv[w] = rv[p];
                w++;
            }
        }
    }
    rp[ng] = w;
    /* upper CSC in the original index space: entry (i, j), i <= j, in column j */
    q->Ap = calloc((size_t)nx + 1, sizeof(long));
    if (!q->Ap)
        goto out;
    long nnz = 0;
#define COUNT(i, j)                                                                               \
    do {                                                                                          \
        q->Ap[((i) > (j) ? (i) : (j)) + 1]++;                                                     \
        nnz++;                                                                                    \
    } while (0)
    for (int i = 0; i < ng; ++i)
        for (long p = rp[i]; p < rp[i + 1]; ++p)
            COUNT(i, ri[p]);
    for (int i = 0; i < ng; ++i)
        for (int t = 0; t < nm; ++t)
            if (!q->pinned[i] && !q->pinned[ng + t] && gm[(size_t)i * nm + t] != 0)
                COUNT(i, ng + t);
    for (int s = 0; s < nm; ++s)
        for (int t = s; t < nm; ++t)
            if (!q->pinned[ng + s] && !q->pinned[ng + t] && mm[(size_t)s * nm + t] != 0)
                COUNT(ng + s, ng + t);
    for (int i = 0; i < nx; ++i)
        if (q->pinned[i])
            COUNT(i, i);
#undef COUNT
    for (int k = 0; k < nx; ++k)
        q->Ap[k + 1] += q->Ap[k];
    q->Ai = malloc(sizeof(int) * (size_t)(nnz + 1));
    q->Ax = malloc(sizeof(double) * (size_t)(nnz + 1));
    fill = malloc(sizeof(long) * (size_t)(nx + 1));
    if (!q->Ai || !q->Ax || !fill) {
        free(fill);
        goto out;
    }
    memcpy(fill, q->Ap, sizeof(long) * (size_t)nx);
#define PUT(i, j, v)                                                                              \
    do {                                                                                          \
        int col_ = (i) > (j) ? (i) : (j), row_ = (i) > (j) ? (j) : (i);                           \
        long at_ = fill[col_]++;                                                                  \
        q->Ai[at_] = row_;                                                                        \
        q->Ax[at_] = (v);                                                                         \
    } while (0)
    for (int i = 0; i < ng; ++i)
        for (long p = rp[i]; p < rp[i + 1]; ++p)
            PUT(i, ri[p], rv[p]);
    for (int i = 0; i < ng; ++i)
        for (int t = 0; t < nm; ++t)
            if (!q->pinned[i] && !q->pinned[ng + t] && gm[(size_t)i * nm + t] != 0)
                PUT(i, ng + t, gm[(size_t)i * nm + t]);
    for (int s = 0; s < nm; ++s)
        for (int t = s; t < nm; ++t)
            if (!q->pinned[ng + s] && !q->pinned[ng + t] && mm[(size_t)s * nm + t] != 0)
                PUT(ng + s, ng + t, mm[(size_t)s * nm + t]);
    for (int i = 0; i < nx; ++i)
        if (q->pinned[i])
            PUT(i, i, 1.0);
#undef PUT
    free(fill);
    q->bytes += (size_t)nnz * (sizeof(int) + sizeof(double)) + (size_t)(nx + 1) * sizeof(long);
    /* the free rows of G and rp/ri/rv are no longer needed */
    free(rp), free(ri), free(rv), free(last);
    rp = NULL, ri = NULL, rv = NULL, last = NULL;
    if (sc_spsym_analyze(nx, q->Ap, q->Ai, &q->f) != 0 ||
        sc_spsym_factor(q->f, q->Ax, LSQ_PIVOT_TOL) != 0)
        goto out;
    q->nullity_pin = sc_spsym_nullity(q->f);
    st = SC_OK;
out:
    if (st != SC_OK)
        sc_error_set(err, st, NULL, 0, "out of memory building the least-squares system");
    free(tr), free(gm), free(mm), free(mmT), free(rp), free(ri), free(rv), free(last);
    return st;
}

/* x := pinned-system solve of b (original index space), with `refine` steps of iterative
 * refinement against the assembled matrix. */
static void pinned_solve(sc_grid_lsq *q, double *x, int refine)
{
    int nx = q->nx;
    double *b = q->work, *r = q->work2;
    for (int i = 0; i < nx; ++i)
        b[i] = x[i] = q->pinned[i] ? 0.0 : x[i];
    sc_spsym_solve(q->f, x);
    for (int it = 0; it < refine; ++it) {
        sc_spsym_matvec(q->f, x, r);
        for (int i = 0; i < nx; ++i)
            r[i] = b[i] - r[i];
        sc_spsym_solve(q->f, r);
        for (int i = 0; i < nx; ++i)
            x[i] += r[i];
    }
    for (int i = 0; i < nx; ++i)
        if (q->pinned[i])
            x[i] = 0.0;
}

/* Per-node std/σ_r: diag(P⊥ Σ P⊥), Σ = pinned inverse (0 on pins), U = orthonormal gauge basis. */
static sc_status compute_sigma_ratios(sc_grid_lsq *q, sc_error *err)
{
    int ng = q->ng, nx = q->nx, n = q->n, nn = q->nn;
    if (sc_spsym_selinv(q->f) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (selected inverse)");
    double *U = malloc(sizeof(double) * (size_t)4 * ng);
    double *W = malloc(sizeof(double) * (size_t)4 * nx);
    if (!U || !W) {
        free(U), free(W);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    double r2 = 0;
    for (int k = 0; k < nn; ++k) {
        double x, y;
        sc_grid_node_xy_mm(&q->plan, k / n, k % n, &x, &y);
        r2 += x * x + y * y;
    }
    double s0 = 1.0 / sqrt((double)nn), s1 = 1.0 / sqrt(r2);
    for (int k = 0; k < nn; ++k) {
        double x, y;
        sc_grid_node_xy_mm(&q->plan, k / n, k % n, &x, &y);
        U[0 * ng + 2 * k] = s0, U[0 * ng + 2 * k + 1] = 0;
        U[1 * ng + 2 * k] = 0, U[1 * ng + 2 * k + 1] = s0;
        U[2 * ng + 2 * k] = -y * s1, U[2 * ng + 2 * k + 1] = x * s1;
        U[3 * ng + 2 * k] = x * s1, U[3 * ng + 2 * k + 1] = y * s1;
    }
    for (int c = 0; c < 4; ++c) {
        double *w = W + (size_t)c * nx;
        for (int i = 0; i < nx; ++i)
            w[i] = i < ng ? U[(size_t)c * ng + i] : 0.0;
        pinned_solve(q, w, 2);
    }
    double M[4][4];
    for (int c = 0; c < 4; ++c)
        for (int d = 0; d < 4; ++d) {
            double s = 0;
            for (int i = 0; i < ng; ++i)
                s += U[(size_t)c * ng + i] * W[(size_t)d * nx + i];
            M[c][d] = s;
        }
    double sum2 = 0, mx = 0;
    for (int i = 0; i < ng; ++i) {
        double zii = q->pinned[i] ? 0.0 : sc_spsym_inv(q->f, i, i);
        double var = zii;
        for (int c = 0; c < 4; ++c) {
            double uc = U[(size_t)c * ng + i];
            var -= 2 * W[(size_t)c * nx + i] * uc;
            for (int d = 0; d < 4; ++d)
                var += uc * M[c][d] * U[(size_t)d * ng + i];
        }
        double s = var > 0 ? sqrt(var) : 0.0;
        if (i % 2 == 0)
            q->sgx[i / 2] = s;
        else
            q->sgy[i / 2] = s;
        sum2 += s * s;
        if (s > mx)
            mx = s;
    }
    q->info.sigma_c_ratio_rms = sqrt(sum2 / ng);
    q->info.sigma_c_ratio_max = mx;
    free(U), free(W);
    return SC_OK;
}

sc_status sc_grid_lsq_create(const sc_grid_plan *plan, const sc_grid_data *mask, sc_grid_lsq **out,
                             sc_error *err)
{
    *out = NULL;
    sc_status st = sc_grid_plan_check(plan, err);
    if (st != SC_OK)
        return st;
    if (mask && (mask->plan.n != plan->n || mask->plan.n_views != plan->n_views))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the data's N or number of views differs from the plan's");
    sc_grid_lsq *q = calloc(1, sizeof *q);
    if (!q)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    q->plan = *plan;
    q->n = plan->n;
    q->nn = plan->n * plan->n;
    q->nv = plan->n_views;
    q->L_mm = (plan->n - 1) / 2 * plan->pitch_mm;
    q->ng = 2 * q->nn;
    q->nm = 3 * q->nv;
    q->nx = q->ng + q->nm;
    st = build_equations(q, mask, err);
    if (st != SC_OK)
        goto fail;
    q->pinned = calloc((size_t)q->nx, 1);
    q->sgx = malloc(sizeof(double) * (size_t)q->nn);
    q->sgy = malloc(sizeof(double) * (size_t)q->nn);
    q->work = malloc(sizeof(double) * (size_t)q->nx);
    q->work2 = malloc(sizeof(double) * (size_t)q->nx);
    if (!q->pinned || !q->sgx || !q->sgy || !q->work || !q->work2) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        goto fail;
    }
    choose_pins(q);
    st = build_and_factor(q, err);
    if (st != SC_OK)
        goto fail;
    long K = q->nullity_pin - (q->nullity_T - 3);
    if (K < 0)
        K = 0;
    q->info.free_dof = K;
    q->info.identifiable = K == 0;
    q->info.n_unknowns = q->ng + 2 * q->n_meas_marks + q->nm;
    q->info.n_equations = q->neq;
    q->info.n_constraints = 7;
    q->rank = q->info.n_unknowns - (4 + K + q->nullity_T);
    for (int k = 0; k < q->nn; ++k)
        q->sgx[k] = q->sgy[k] = NAN;
    q->info.sigma_c_ratio_rms = q->info.sigma_c_ratio_max = NAN;
    if (K == 0) {
        st = compute_sigma_ratios(q, err);
        if (st != SC_OK)
            goto fail;
    }
    sc_spsym_stats fst;
    sc_spsym_get_stats(q->f, &fst);
    q->bytes += fst.bytes + (size_t)q->neq * (5 * sizeof(int) + 2 + sizeof(double) + sizeof(long));
    *out = q;
    return SC_OK;
fail:
    sc_grid_lsq_destroy(q);
    return st;
}

void sc_grid_lsq_get_info(const sc_grid_lsq *q, sc_grid_lsq_info *info)
{
    *info = q->info;
}

void sc_grid_lsq_get_stats(const sc_grid_lsq *q, sc_grid_lsq_stats *st)
{
    sc_spsym_stats f;
    sc_spsym_get_stats(q->f, &f);
    memset(st, 0, sizeof *st);
    st->n_reduced = q->nx;
    st->nnz_matrix = q->Ap ? q->Ap[q->nx] : 0;
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

sc_status sc_grid_lsq_sigma_ratio(const sc_grid_lsq *q, double *sgx, double *sgy, sc_error *err)
{
    if (!q->info.identifiable)
        return sc_error_set(err, SC_E_UNSOLVABLE, NULL, 0,
                            "the plan does not identify G (%ld free degrees of freedom)",
                            q->info.free_dof);
    if (sgx)
        memcpy(sgx, q->sgx, sizeof(double) * (size_t)q->nn);
    if (sgy)
        memcpy(sgy, q->sgy, sizeof(double) * (size_t)q->nn);
    return SC_OK;
}

static double eq_data(const sc_grid_lsq *q, const sc_grid_data *d, long e)
{
    int v = q->eq_v[e], k = q->eq_k[e];
    return q->eq_c[e] ? d->dy_um[v][k] : d->dx_um[v][k];
}

/* r = b - S x evaluated from the equations themselves (not the assembled matrix, whose rounding
 * slightly moves the gauge null space): r = Σ_e w_e (z_e - mean_group z), z_e = s_e d_e - w_e·x.
 * Zero on pins. */
static void data_residual(const sc_grid_lsq *q, const sc_grid_data *d, const double *x, double *r)
{
    int idx[3];
    double val[3];
    memset(r, 0, sizeof(double) * (size_t)q->nx);
    for (int c = 0; c < 2 * q->nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        if (cnt < 2)
            continue;
        double mean = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            eq_row(q, e, idx, val);
            mean += q->eq_s[e] * eq_data(q, d, e) - val[0] * x[idx[0]] - val[1] * x[idx[1]] -
                    val[2] * x[idx[2]];
        }
        mean /= (double)cnt;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            eq_row(q, e, idx, val);
            double z = q->eq_s[e] * eq_data(q, d, e) - val[0] * x[idx[0]] -
                       val[1] * x[idx[1]] - val[2] * x[idx[2]] - mean;
            for (int k = 0; k < 3; ++k)
                r[idx[k]] += val[k] * z;
        }
    }
    for (int i = 0; i < q->nx; ++i)
        if (q->pinned[i])
            r[i] = 0;
}

sc_status sc_grid_lsq_solve(sc_grid_lsq *q, const sc_grid_data *d, double sigma_r_um,
                            sc_grid_result *res, sc_error *err)
{
    int n = q->n, nn = q->nn, nv = q->nv, ng = q->ng, nx = q->nx;
    if (d->plan.n != n || d->plan.n_views != nv)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "data has N = %d and %d views, the estimator N = %d and %d views",
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
    double *x = calloc((size_t)nx, sizeof(double));
    double *g = malloc(sizeof(double) * (size_t)ng);
    double *a = malloc(sizeof(double) * (size_t)2 * nn);
    if (!x || !g || !a) {
        free(x), free(g), free(a);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    int idx[3];
    double val[3];
    /* reduced right-hand side: b = Σ_e w_e (s_e d_e - mean over the group) */
    for (int c = 0; c < 2 * nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        if (cnt < 2)
            continue;
        double mean = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            mean += q->eq_s[e] * eq_data(q, d, e);
        }
        mean /= (double)cnt;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            double z = q->eq_s[e] * eq_data(q, d, e) - mean;
            eq_row(q, e, idx, val);
            for (int r = 0; r < 3; ++r)
                x[idx[r]] += val[r] * z;
        }
    }
    pinned_solve(q, x, 0);
    {
        double *r = malloc(sizeof(double) * (size_t)nx);
        for (int it = 0; r && it < 3; ++it) {
            data_residual(q, d, x, r);
            pinned_solve(q, r, 0);
            for (int i = 0; i < nx; ++i)
                x[i] += r[i];
        }
        free(r);
    }
    /* G in the gauge; the magnification moved to A (the unobservable G+A pattern) */
    double *gx = g, *gy = g + nn;
    for (int k = 0; k < nn; ++k) {
        gx[k] = x[2 * k];
        gy[k] = x[2 * k + 1];
    }
    double smag = 0, r2 = 0;
    for (int k = 0; k < nn; ++k) {
        double px, py;
        sc_grid_node_xy_mm(&q->plan, k / n, k % n, &px, &py);
        smag += px * gx[k] + py * gy[k];
        r2 += px * px + py * py;
    }
    double mu = smag / r2;
    /* A of the pinned solution: group means */
    for (int c = 0; c < 2 * nn; ++c) {
        long g0 = q->grp_ptr[c], cnt = q->grp_ptr[c + 1] - g0;
        if (cnt < 1) {
            a[c] = NAN;
            continue;
        }
        double s = 0;
        for (long t = 0; t < cnt; ++t) {
            long e = q->grp_eq[g0 + t];
            double pred = 0;
            int len = eq_row(q, e, idx, val);
            for (int r = 0; r < len; ++r)
                pred += val[r] * x[idx[r]]; /* = s_e·(J x)_e */
            s += q->eq_s[e] * eq_data(q, d, e) - pred;
        }
        a[c] = s / (double)cnt;
    }
    sc_grid_gauge_stage(&q->plan, gx, gy);
    /* A: add μ·(x, y), then remove its translation and rotation over the measured marks */
    double N0 = 0, Sx = 0, Sy = 0, Sr = 0, bx = 0, by = 0, br = 0;
    for (int k = 0; k < nn; ++k) {
        if (!q->mark_views[k])
            continue;
        double px, py;
        sc_grid_node_xy_mm(&q->plan, k / n, k % n, &px, &py);
        a[2 * k] += mu * px;
        a[2 * k + 1] += mu * py;
        N0 += 1, Sx += px, Sy += py, Sr += px * px + py * py;
        bx += a[2 * k], by += a[2 * k + 1], br += px * a[2 * k + 1] - py * a[2 * k];
    }
    /* normal equations of (t_x, t_y, ω) for the pattern (t_x - ω y, t_y + ω x) */
    {
        double m3[3][3] = {{N0, 0, -Sy}, {0, N0, Sx}, {-Sy, Sx, Sr}}, rhs[3] = {bx, by, br};
        double sol[3] = {0, 0, 0};
        /* Gaussian elimination with partial pivoting on 3x3 */
        int pv[3] = {0, 1, 2};
        for (int c = 0; c < 3; ++c) {
            int best = c;
            for (int r = c + 1; r < 3; ++r)
                if (fabs(m3[pv[r]][c]) > fabs(m3[pv[best]][c]))
                    best = r;
            int t = pv[c];
            pv[c] = pv[best];
            pv[best] = t;
            double piv = m3[pv[c]][c];
            if (piv == 0)
                continue;
            for (int r = c + 1; r < 3; ++r) {
                double l = m3[pv[r]][c] / piv;
                for (int cc = c; cc < 3; ++cc)
                    m3[pv[r]][cc] -= l * m3[pv[c]][cc];
                rhs[pv[r]] -= l * rhs[pv[c]];
            }
        }
        for (int c = 2; c >= 0; --c) {
            double s = rhs[pv[c]];
            for (int cc = c + 1; cc < 3; ++cc)
                s -= m3[pv[c]][cc] * sol[cc];
            sol[c] = m3[pv[c]][c] != 0 ? s / m3[pv[c]][c] : 0.0;
        }
        for (int k = 0; k < nn; ++k) {
            if (!q->mark_views[k])
                continue;
            double px, py;
            sc_grid_node_xy_mm(&q->plan, k / n, k % n, &px, &py);
            a[2 * k] -= sol[0] - sol[2] * py;
            a[2 * k + 1] -= sol[1] + sol[2] * px;
        }
    }
    /* misalignments: per view, least squares of d - G - Rot A on (tx, ty, φ) */
    double tx[SC_GRID_MAX_VIEWS], ty[SC_GRID_MAX_VIEWS], phi[SC_GRID_MAX_VIEWS];
    {
        double nrm[SC_GRID_MAX_VIEWS][3][3], rh[SC_GRID_MAX_VIEWS][3];
        memset(nrm, 0, sizeof nrm);
        memset(rh, 0, sizeof rh);
        for (long e = 0; e < q->neq; ++e) {
            int v = q->eq_v[e], c = q->eq_c[e];
            double r = eq_data(q, d, e) - g[(q->eq_g[e] % 2) * nn + q->eq_g[e] / 2] -
                       q->eq_s[e] * a[q->eq_a[e]];
            double p = q->eq_pos[e];
            nrm[v][c][c] += 1, nrm[v][c][2] += p, nrm[v][2][c] += p, nrm[v][2][2] += p * p;
            rh[v][c] += r, rh[v][2] += p * r;
        }
        for (int v = 0; v < nv; ++v) {
            double (*m3)[3] = nrm[v];
            /* [n0 0 b; 0 n1 c; b c e] by elimination of the first two */
            double n0 = m3[0][0], n1 = m3[1][1], bb = m3[0][2], cc = m3[1][2], ee = m3[2][2];
            double det = n0 > 0 && n1 > 0 ? ee - bb * bb / n0 - cc * cc / n1 : 0.0;
            if (!(n0 > 0 && n1 > 0) || !(det > 1e-12 * (ee > 0 ? ee : 1))) {
                tx[v] = ty[v] = phi[v] = NAN;
                continue;
            }
            phi[v] = (rh[v][2] - bb * rh[v][0] / n0 - cc * rh[v][1] / n1) / det;
            tx[v] = (rh[v][0] - bb * phi[v]) / n0;
            ty[v] = (rh[v][1] - cc * phi[v]) / n1;
        }
    }
    /* residuals of the final (G, A, misalignment) */
    double rss = 0;
    for (long e = 0; e < q->neq; ++e) {
        int v = q->eq_v[e];
        double m = (q->eq_c[e] ? ty[v] : tx[v]) + q->eq_pos[e] * phi[v];
        if (!isfinite(m))
            m = 0;
        double r = eq_data(q, d, e) - g[(q->eq_g[e] % 2) * nn + q->eq_g[e] / 2] -
                   q->eq_s[e] * a[q->eq_a[e]] - m;
        rss += r * r;
    }
    long dof = q->neq - q->rank;
    res->n_measurements = q->neq;
    res->dof = dof;
    res->residual_rms_um = q->neq > 0 ? sqrt(rss / (double)q->neq) : NAN;
    res->sigma_r_est_um = dof > 0 ? sqrt(rss / (double)dof) : NAN;
    res->sigma_r_used_um = sigma_r_um > 0 ? sigma_r_um : res->sigma_r_est_um;
    for (int v = 0; v < SC_GRID_MAX_VIEWS; ++v) {
        res->tx_um[v] = v < nv ? tx[v] : NAN;
        res->ty_um[v] = v < nv ? ty[v] : NAN;
        res->theta_urad[v] = v < nv ? phi[v] / (q->L_mm * 1e-3) : NAN;
    }
    sc_grid_first_order(&q->plan, gx, gy, &res->O, &res->R);
    double su = res->sigma_r_used_um;
    for (int k = 0; k < nn; ++k) {
        if (res->gx_um)
            res->gx_um[k] = gx[k];
        if (res->gy_um)
            res->gy_um[k] = gy[k];
        if (res->ugx_um)
            res->ugx_um[k] = su * q->sgx[k];
        if (res->ugy_um)
            res->ugy_um[k] = su * q->sgy[k];
        if (res->ax_um)
            res->ax_um[k] = q->mark_views[k] ? a[2 * k] : NAN;
        if (res->ay_um)
            res->ay_um[k] = q->mark_views[k] ? a[2 * k + 1] : NAN;
    }
    free(x), free(g), free(a);
    return SC_OK;
}
