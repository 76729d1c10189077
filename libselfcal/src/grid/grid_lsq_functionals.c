/* What a least-squares plan knows before any data (per unit σ): the gauge basis and the node σ
 * ratios, the variances of the functionals O, R, the misalignments and the plate's
 * magnification, and the leverage of every equation (the plan's uncertainties). */
#include "grid_lsq_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/big_alloc.h"
#include "selfcal/grid_sim.h"

/* U (4 x ng, row after row): the orthonormal basis of G's gauge patterns (translations, rotation,
 * magnification) that sc_grid_gauge_stage projects out. */
void sc_lsq_gauge_basis(const sc_grid_lsq_plan *q, double *U, double scale[4])
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

static void sigma_ratios_finish(sc_grid_lsq_plan *q, const double *zdiag)
{
    double sum2 = 0, mx = 0;
    long cnt = 0;
    for (int i = 0; i < q->ng; ++i) {
        double *at = i % 2 == 0 ? &q->sgx[i / 2] : &q->sgy[i / 2];
        /* zdiag: diag(Σ) of the sampled unknowns (NaN elsewhere: σ NaN there) */
        double z = zdiag ? zdiag[i] : q->pinned[i] ? 0.0 : sc_spsym_inv(q->f, i, i);
        if (isnan(z)) {
            *at = NAN;
            continue;
        }
        double var = z + *at;
        double s = var > 0 ? sqrt(var) : 0.0;
        *at = s;
        sum2 += s * s, cnt++;
        if (s > mx)
            mx = s;
    }
    q->info.sigma_c_ratio_rms = cnt ? sqrt(sum2 / (double)cnt) : NAN;
    q->info.sigma_c_ratio_max = cnt ? mx : NAN;
}

/* SC_GRID_NODE_SIGMA_SAMPLE: diag(Σ) at both unknowns of k nodes spread evenly over the measured
 * nodes (in node order), by blocked solves of unit columns; NaN at the others. 0, -1 no memory. */
static int sampled_diagonal(const sc_grid_lsq_plan *q, int k, double *zdiag)
{
    int ng = q->ng, n_meas = 0;
    size_t n = (size_t)q->n_red;
    unsigned char *seen = calloc((size_t)q->ns, 1);
    int *pick = malloc(sizeof(int) * (2 * (size_t)(k > 0 ? k : 1) + 2));
    double *X = malloc(sizeof(double) * n * 8);
    int rc = seen && pick && X ? 0 : -1;
    for (int i = 0; i < ng; ++i)
        zdiag[i] = NAN;
    for (long e = 0; rc == 0 && e < q->neq; ++e)
        seen[q->eq_g[e] / 2] = 1;
    for (int s = 0; rc == 0 && s < q->ns; ++s)
        n_meas += seen[s];
    int np = 0;
    if (rc == 0 && k > 0 && n_meas > 0) {
        if (k > n_meas)
            k = n_meas;
        long want = 0, at = 0; /* the t-th pick: measured node number floor(t·n_meas/k) */
        for (int s = 0, t = 0; s < q->ns && t < k; ++s) {
            if (!seen[s])
                continue;
            want = (long)t * n_meas / k;
            if (at++ == want) {
                pick[np++] = 2 * s, pick[np++] = 2 * s + 1;
                ++t;
            }
        }
    }
    for (int p0 = 0; rc == 0 && p0 < np; p0 += 8) {
        int c = np - p0 < 8 ? np - p0 : 8;
        memset(X, 0, sizeof(double) * n * (size_t)c);
        for (int t = 0; t < c; ++t)
            X[(size_t)t * n + (size_t)pick[p0 + t]] = 1;
        if (sc_lsq_pinned_solve(q, X, c, 0, NULL, NULL) != 0)
            rc = -1;
        for (int t = 0; rc == 0 && t < c; ++t)
            zdiag[pick[p0 + t]] = X[(size_t)t * n + (size_t)pick[p0 + t]];
    }
    free(seen), free(pick), free(X);
    return rc;
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
int sc_lsq_gauge_matrix(const sc_grid_lsq_plan *q, double *Minv_T)
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
        sc_lsq_small_solve(A, rhs, 7);
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
void sc_lsq_functional_vectors(const sc_grid_lsq_plan *q, const double *Minv_T, const double *fg,
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
void sc_lsq_a_correction(const sc_grid_lsq_plan *q, const double *uA, double *z)
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
            int len = sc_lsq_eq_row(q, e, idx, val);
            for (int r = 0; r < len; ++r)
                z[idx[r]] -= uA[a] / W * q->eq_w[e] * val[r];
        }
    }
}

/* The affine form behind uᵀΣu (a_correction): uxᵀz − Σ_a u_A[a]·(Σ_e w_e ρ_e·z)/W_a, plus the
 * constant Σ_a u_A[a]²/W_a when with_const. Linear in z, so a z combined from several columns of
 * Σ can be taken column by column. */
double sc_lsq_functional_form(const sc_grid_lsq_plan *q, const double *ux, const double *uA,
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
            int len = sc_lsq_eq_row(q, e, idx, val);
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
        sc_lsq_a_correction(q, uA, D + (size_t)(t - 4) * n);
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

/* functional_variances' phase 1 for misalignment unknown t (reduced index m):
 * r·(Σ e_m) = (Σ e_m)_m − Σ_{t<4} γ_t U_t·col/scale_t − Σ γ_t D_t·col added to part[t] into
 * q->var_m[t]; col: scratch of n_red. Returns -1 when its column of Σ cannot be had. */
static int misalignment_variance(sc_grid_lsq_plan *q, int t, int m, const int *slot,
                                 const double scale[4], const double *U, const double *D,
                                 const double *gam, double *col, const double *part)
{
    size_t n = (size_t)q->n_red, ng = (size_t)q->ng;
    if (slot[t] < 0) { /* a pinned one: its column is 0 */
        q->var_m[t] = part[t] > 0 ? part[t] : 0.0;
        return 0;
    }
    if (q->full) { /* U_s·col = (ΣU_s)_m = W_s's, D_s·col = (ΣD_s)_m: kept rows */
        const double *mr = q->m_rows + (size_t)t * 7;
        double v = sc_spsym_inv(q->f, m, m);
        for (int s = 0; s < 4; ++s)
            v -= gam[s] / scale[s] * mr[s];
        for (int s = 0; s < 3; ++s)
            v -= gam[4 + s] * mr[4 + s];
        double var = part[t] + v;
        q->var_m[t] = var > 0 ? var : 0.0;
        return 0;
    }
    if (sc_spsym_inv_column(q->f, slot[t], col) != 0)
        return -1;
    sc_lsq_zero_pinned(q, col, 1);
    double v = col[m];
    for (int s = 0; s < 4; ++s)
        v -= gam[s] / scale[s] * dot(U + (size_t)s * ng, col, ng);
    for (int s = 0; s < 3; ++s)
        v -= gam[4 + s] * dot(D + (size_t)s * n, col, n);
    double var = part[t] + v;
    q->var_m[t] = var > 0 ? var : 0.0;
    return 0;
}

/* functional_variances' phase 0 for functional f (O, R, then the misalignments, reduced index
 * m): z0 = Σ(r − own) = Σ_s c_s X_s, formed first (a sum of the dot tables' products would
 * lose more to cancellation), then its form: own·z0 − Σ_{t<4} γ_t U_t·z0/scale_t
 * − Σ_{t>=4} γ_t D_t·z0 + Σ γ_t γ_t' C_tt'. z: scratch of n_red. */
static double functional_variance0(const sc_grid_lsq_plan *q, int f, int m,
                                   const double scale[4], const double *U, const double *D,
                                   const double *X, const double *gam, const double C[3][3],
                                   const double *fg, double *z)
{
    size_t n = (size_t)q->n_red, ng = (size_t)q->ng;
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
    return var;
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
    if (sc_lsq_gauge_matrix(q, Minv_T) != 0)
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
    sc_lsq_free_misalignments(q, NULL, slot);
    double C[3][3];
    if (phase == 0)
        a_gauge_gram(q, C);
    const double *pg, *pm;
    for (int f = phase == 0 ? 0 : 2; f < nf; ++f) {
        functional_def(q, f, fg ? fg : fm, fm, &pg, &pm); /* phase 1: misalignments only */
        functional_gamma(q, Minv_T, pg, pm, gam);
        int m = (int)ng + f - 2;
        if (phase == 1) {
            if (misalignment_variance(q, f - 2, m, slot, scale, U, D, gam, col, part) != 0)
                break;
            continue;
        }
        double var = functional_variance0(q, f, m, scale, U, D, X, gam, C, fg, z);
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

/* The unknowns u[0 .. return value) group a's equations touch, in the order met; *W the group's
 * total weight. */
static int group_unknowns(const sc_grid_lsq_plan *q, int a, int *u, double *W)
{
    long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
    int idx[ROW_MAX], nu = 0;
    double val[ROW_MAX];
    *W = 0;
    for (long t = 0; t < cnt; ++t) {
        long e = q->grp_eq[g0 + t];
        int len = sc_lsq_eq_row(q, e, idx, val);
        *W += q->eq_w[e];
        for (int r = 0; r < len; ++r) {
            int f = 0;
            while (f < nu && u[f] != idx[r])
                ++f;
            if (f == nu)
                u[nu++] = idx[r];
        }
    }
    return nu;
}

/* mean (nu): group a's mean row over its unknowns u, weighted by w_e / W. */
static void group_mean(const sc_grid_lsq_plan *q, int a, const int *u, int nu, double W,
                       double *mean)
{
    long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
    int idx[ROW_MAX];
    double val[ROW_MAX];
    memset(mean, 0, sizeof(double) * (size_t)nu);
    for (long t = 0; t < cnt; ++t) {
        long e = q->grp_eq[g0 + t];
        int len = sc_lsq_eq_row(q, e, idx, val);
        for (int r = 0; r < len; ++r)
            for (int f = 0; f < nu; ++f)
                if (u[f] == idx[r])
                    mean[f] += q->eq_w[e] * val[r] / W;
    }
}

/* sub (nu x nu): Σ's block on the unknowns u: G pairs from the selected inverse (on S's
 * pattern), G with a misalignment from the G unknown's row of the whole columns (fetched once
 * into grow), two misalignments from mrow (misalignment_block); 0 on pins. */
static void group_sigma_block(const sc_grid_lsq_plan *q, const int *slot, const double *mrow,
                              const int *u, int nu, double *grow, double *sub)
{
    int nt = 0, ng = q->ng, nm = q->nm;
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
}

/* Leverage of every equation of group a into h (by equation index). u: the group's unknowns;
 * vec: 2 vectors over them (Σm, then m); sub: Σ's block on them; mrow: misalignment_block;
 * grow: scratch of ROW_MAX·(group size) x n_track (the G unknowns' rows of Σ's whole columns). */
static void group_leverage(const sc_grid_lsq_plan *q, const int *slot, const double *mrow, int a,
                           int *u, double *vec, double *sub, double *grow, double *h)
{
    long g0 = q->grp_ptr[a], cnt = q->grp_ptr[a + 1] - g0;
    int idx[ROW_MAX];
    double val[ROW_MAX], W;
    int nu = group_unknowns(q, a, u, &W);
    double *mean = vec + nu;
    group_mean(q, a, u, nu, W, mean);
    group_sigma_block(q, slot, mrow, u, nu, grow, sub);
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
        int len = sc_lsq_eq_row(q, e, idx, val), pos[ROW_MAX];
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
    int k = sc_lsq_free_misalignments(q, NULL, slot);
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

/* sc_lsq_plan_uncertainties before the selected inverse: W = ΣU (WB's first 4 columns) and
 * the node σ's projection part; with functionals, B = Σ·functional_basis_rhs (WB's next 5; its
 * A-gauge right-hand sides kept in D) and phase 0 of functional_variances into part. */
static sc_status uncertainty_solves(sc_grid_lsq_plan *q, int functionals, double *U, double *WB,
                                    double *D, double *fg, double *uA, double *part,
                                    sc_error *err)
{
    size_t n = (size_t)q->n_red, ng = (size_t)q->ng;
    double scale[4], *W = WB, *B = functionals ? WB + 4 * n : NULL;
    for (int t = 0; t < q->nm; ++t)
        q->var_m[t] = NAN;
    sc_lsq_gauge_basis(q, U, scale);
    for (int c = 0; c < 4; ++c)
        for (size_t i = 0; i < n; ++i)
            W[(size_t)c * n + i] = i < ng ? U[(size_t)c * ng + i] : 0.0;
    if (sc_lsq_pinned_solve(q, W, 4, 0, NULL, NULL) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (solves)");
    sigma_ratios_projection(q, U, W);
    if (!functionals)
        return SC_OK;
    functional_basis_rhs(q, fg, uA, B);
    memcpy(D, B + 2 * n, sizeof(double) * 3 * n);
    if (sc_lsq_pinned_solve(q, B, 5, 0, NULL, NULL) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (solves)");
    sc_status st = functional_variances(q, 0, scale, U, D, WB, part, err);
    /* with A kept the misalignments' columns of Σ are not tracked (nm whole columns of the full
     * system would not fit at these sizes): their rows of W and of ΣD serve instead */
    if (st == SC_OK && q->full && (q->m_rows = malloc(sizeof(double) * 7 * (size_t)q->nm)))
        for (int t = 0; t < q->nm; ++t)
            for (int c = 0; c < 7; ++c)
                q->m_rows[(size_t)t * 7 + c] = WB[(size_t)(c < 4 ? c : c + 2) * n + ng + t];
    if (st == SC_OK && q->full && !q->m_rows)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    return st;
}

/* SC_GRID_NODE_SIGMA_NONE or _SAMPLE instead of the selected inverse: no leverages (NaN), the
 * misalignments' σ NaN; the sampled nodes' diag(Σ) by solves. */
static sc_status uncertainty_without_selinv(sc_grid_lsq_plan *q, sc_error *err)
{
    sc_status st = SC_OK;
    double *zd = q->node_sigma == SC_GRID_NODE_SIGMA_SAMPLE
                     ? malloc(sizeof(double) * (size_t)q->ng) : NULL;
    if (!(q->eq_h = malloc(sizeof(double) * (size_t)(q->neq + 1))) ||
        (q->node_sigma == SC_GRID_NODE_SIGMA_SAMPLE &&
         (!zd || sampled_diagonal(q, q->node_sigma_sample, zd) != 0)))
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    if (st == SC_OK) {
        for (long e = 0; e < q->neq; ++e)
            q->eq_h[e] = NAN;
        if (zd)
            sigma_ratios_finish(q, zd);
        else
            for (int k = 0; k < q->ns; ++k)
                q->sgx[k] = q->sgy[k] = NAN;
    }
    free(zd);
    return st;
}

/* sc_lsq_plan_uncertainties from the selected inverse on (kept: the diagonal, the G pairs on
 * S's pattern, the free misalignments last[0 .. n_last)): the node σ, every leverage, and with
 * functionals phase 1 of functional_variances (D and part from uncertainty_solves). The
 * selected inverse is dropped after. */
static sc_status uncertainty_selinv(sc_grid_lsq_plan *q, int functionals, const int *last,
                                    int n_last, const double *D, double *part, sc_error *err)
{
    sc_lsq_progress(q, "selected inverse", q->work_total / 2);
    /* leverages: G pairs on S's pattern; with A kept every pair of one equation's unknowns,
     * which the full matrix's own pattern holds (no whole columns) */
    if ((q->full ? sc_spsym_selinv(q->f, -1, NULL, 0)
                 : sc_spsym_selinv(q->f, q->ng, last, n_last)) != 0)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (selected inverse)");
    sigma_ratios_finish(q, NULL);
    sc_status st = SC_OK;
    if (q->full) {
        if (!q->eq_h && !(q->eq_h = malloc(sizeof(double) * (size_t)(q->neq + 1))))
            st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (leverage)");
        else {
            sc_lsq_full_desc fd;
            sc_lsq_full_desc_of(q, &fd);
            sc_lsq_full_leverages(q->full, &fd, q->f, q->eq_h);
        }
    } else
        st = leverages(q, err);
    if (st == SC_OK)
        sc_lsq_redundancy_info(q);
    if (st == SC_OK && q->misalignment_estimable && functionals) {
        double scale[4], *U = malloc(sizeof(double) * 4 * (size_t)q->ng);
        if (!U)
            st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
        else {
            sc_lsq_gauge_basis(q, U, scale);
            st = functional_variances(q, 1, scale, U, D, NULL, part, err);
        }
        free(U);
        for (int v = 0; v < q->nv; ++v) /* a view's own free columns: no uncertainty there */
            for (int c = 0; q->view_free[v] && c < q->nb; ++c)
                q->var_m[v * q->nb + c] = NAN;
    }
    sc_spsym_drop_inverse(q->f);
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
sc_status sc_lsq_plan_uncertainties(sc_grid_lsq_plan *q, sc_error *err)
{
    size_t n = (size_t)q->n_red, ng = (size_t)q->ng;
    int functionals = !q->node_sigma_only;
    double *U = malloc(sizeof(double) * 4 * ng);
    double *WB = sc_big_alloc((functionals ? 9 : 4) * n, sizeof(double), 0); /* W: 0-3, B: 4-8 */
    double *D = NULL, *fg = NULL, *uA = NULL;
    double *part = malloc(sizeof(double) * ((size_t)q->nm + 1));
    int *last = malloc(sizeof(int) * ((size_t)q->nm + 1));
    int n_last = last ? sc_lsq_free_misalignments(q, last, NULL) : 0;
    q->var_m = malloc(sizeof(double) * (size_t)q->nm);
    sc_status st = SC_OK;
    if (functionals) {
        D = malloc(sizeof(double) * 3 * n), fg = malloc(sizeof(double) * ng);
        uA = malloc(sizeof(double) * 2 * (size_t)q->nn);
    }
    if (!U || !WB || (functionals && (!D || !fg || !uA)) || !q->var_m || !part || !last)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    else
        st = uncertainty_solves(q, functionals, U, WB, D, fg, uA, part, err);
    /* the selected inverse needs the memory more (U is made again after it; D, 3 columns, is
     * kept: making it again takes 3 passes over the equations) */
    free(U), free(WB), free(fg), free(uA);
    if (st == SC_OK)
        st = q->node_sigma != SC_GRID_NODE_SIGMA_ALL
                 ? uncertainty_without_selinv(q, err)
                 : uncertainty_selinv(q, functionals, last, n_last, D, part, err);
    free(q->m_rows);
    q->m_rows = NULL;
    free(D), free(part), free(last);
    return st;
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
    if (!q->info.identifiable || sc_lsq_gauge_matrix(q, Minv_T) != 0)
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
    sc_lsq_a_correction(q, uA, z); /* r = u_x − sc_lsq_a_correction(u_A) */
    int rc = sc_lsq_pinned_solve(q, z, 1, 2, z + n, z + 2 * n);
    if (rc == 0) {
        double v = sc_lsq_functional_form(q, ux, uA, z, 1);
        *var_m = v > 0 ? v : 0.0;
        for (int k = 0; k < q->ns; ++k)
            cov_gx[k] = z[2 * k], cov_gy[k] = z[2 * k + 1];
        sc_grid_gauge_stage(&q->plan, cov_gx, cov_gy);
    }
    free(fA), free(uA), free(ux), free(z);
    return rc;
}
