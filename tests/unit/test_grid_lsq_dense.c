/* The sparse least-squares grid estimator against an independent dense reference (LAPACK):
 * the full design matrix J over (G, A, misalignment with θ in µrad), the 7 gauge rows C as hard
 * constraints through the KKT system, covariance Q·JᵀJ·Q from its inverse, and free degrees of
 * freedom from singular values: K = nullity(J) - nullity(J without G) - 4. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid_lsq.h"
#include "test_grid_lsq_util.h"

typedef struct dense {
    int n, nn, nv, nu, neq, nam; /* unknowns, equations, measured marks */
    int *amap;                   /* mark -> A column pair (-1 if unmeasured) */
    double *J;                   /* neq x nu, row-major */
    double *d;                   /* data */
} dense;

static int rot_comp(int rot, int c, int *sign)
{
    int ac;
    switch (rot) {
    case 90: ac = c ? 0 : 1; *sign = c ? 1 : -1; break;
    case 180: ac = c; *sign = -1; break;
    case 270: ac = c ? 0 : 1; *sign = c ? -1 : 1; break;
    default: ac = c; *sign = 1; break;
    }
    return ac;
}

/* The measured marks: mask's finite values, else the plan's. */
static int measured(const sc_grid_plan *p, const sc_grid_data *mask, int v, int k)
{
    if (mask)
        return isfinite(mask->dx_um[v][k]);
    return sc_grid_view_measures(p, v, k / p->n, k % p->n);
}

static void dense_build(dense *D, const sc_grid_plan *p, const sc_grid_data *mask,
                        const sc_grid_data *data)
{
    memset(D, 0, sizeof *D);
    int n = p->n, nn = n * n, nv = p->n_views;
    D->n = n, D->nn = nn, D->nv = nv;
    D->amap = malloc(sizeof(int) * nn);
    int nam = 0, neq = 0;
    for (int k = 0; k < nn; ++k) {
        int any = 0;
        for (int v = 0; v < nv; ++v)
            if (measured(p, mask, v, k))
                any = 1, neq += 2;
        D->amap[k] = any ? nam++ : -1;
    }
    D->nam = nam;
    D->neq = neq;
    D->nu = 2 * nn + 2 * nam + 3 * nv;
    D->J = calloc((size_t)neq * D->nu, sizeof(double));
    D->d = calloc(neq, sizeof(double));
    int e = 0;
    for (int v = 0; v < nv; ++v)
        for (int k = 0; k < nn; ++k) {
            if (!measured(p, mask, v, k))
                continue;
            int ni, nj;
            assert_true(sc_grid_mark_node(p, v, k / n, k % n, &ni, &nj));
            double x, y;
            sc_grid_node_xy_mm(p, ni, nj, &x, &y);
            for (int c = 0; c < 2; ++c, ++e) {
                double *row = D->J + (size_t)e * D->nu;
                int s, ac = rot_comp(p->view[v].rot_deg, c, &s);
                row[2 * (ni * n + nj) + c] = 1;
                row[2 * nn + 2 * D->amap[k] + ac] = s;
                row[2 * nn + 2 * nam + 3 * v + c] = 1;
                row[2 * nn + 2 * nam + 3 * v + 2] = c == 0 ? -y * 1e-3 : x * 1e-3;
                if (data)
                    D->d[e] = c == 0 ? data->dx_um[v][k] : data->dy_um[v][k];
            }
        }
}

static void dense_free(dense *D)
{
    free(D->amap), free(D->J), free(D->d);
}

/* Numerical nullity of the columns [c0, c1) of J (singular values below 1e-9 of the largest). */
static int dense_nullity(const dense *D, int c0, int c1)
{
    int m = D->neq, nc = c1 - c0;
    double *a = malloc(sizeof(double) * (size_t)m * nc);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < nc; ++j)
            a[(size_t)i * nc + j] = D->J[(size_t)i * D->nu + c0 + j];
    int ms = m < nc ? m : nc;
    double *sv = malloc(sizeof(double) * ms);
    assert_int_equal(LAPACKE_dgesdd(LAPACK_COL_MAJOR, 'N', nc, m, a, nc, sv, NULL, 1, NULL, 1),
                     0);
    int rank = 0;
    for (int i = 0; i < ms; ++i)
        rank += sv[i] > 1e-9 * sv[0];
    free(a), free(sv);
    return nc - rank;
}

static long dense_free_dof(const dense *D)
{
    return dense_nullity(D, 0, D->nu) - dense_nullity(D, 2 * D->nn, D->nu) - 4;
}

/* Constrained least squares through the KKT matrix; x (nu) and per-G-unknown variance/σ². */
static void dense_solve(const dense *D, const sc_grid_plan *p, double *x, double *var_g,
                        double *rss)
{
    int nu = D->nu, m = nu + 7, n = D->n, nn = D->nn;
    double *M = calloc((size_t)m * m, sizeof(double));
    double *JtJ = calloc((size_t)nu * nu, sizeof(double));
    for (int e = 0; e < D->neq; ++e) {
        const double *row = D->J + (size_t)e * nu;
        for (int i = 0; i < nu; ++i)
            if (row[i] != 0)
                for (int j = 0; j < nu; ++j)
                    JtJ[(size_t)i * nu + j] += row[i] * row[j];
    }
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nu; ++j)
            M[(size_t)i * m + j] = JtJ[(size_t)i * nu + j];
    /* gauge rows */
    for (int k = 0; k < nn; ++k) {
        double xx, yy;
        sc_grid_node_xy_mm(p, k / n, k % n, &xx, &yy);
        double cg[4][2] = {{1, 0}, {0, 1}, {-yy, xx}, {xx, yy}};
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 2; ++c) {
                M[(size_t)(nu + r) * m + 2 * k + c] = cg[r][c];
                M[(size_t)(2 * k + c) * m + nu + r] = cg[r][c];
            }
        if (D->amap[k] >= 0) {
            int a0 = 2 * nn + 2 * D->amap[k];
            double ca[3][2] = {{1, 0}, {0, 1}, {-yy, xx}};
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 2; ++c) {
                    M[(size_t)(nu + 4 + r) * m + a0 + c] = ca[r][c];
                    M[(size_t)(a0 + c) * m + nu + 4 + r] = ca[r][c];
                }
        }
    }
    int *ipiv = malloc(sizeof(int) * m);
    assert_int_equal(LAPACKE_dgetrf(LAPACK_ROW_MAJOR, m, m, M, m, ipiv), 0);
    assert_int_equal(LAPACKE_dgetri(LAPACK_ROW_MAJOR, m, M, m, ipiv), 0);
    /* x = Q Jᵀd */
    double *Jtd = calloc(nu, sizeof(double));
    for (int e = 0; e < D->neq; ++e)
        for (int i = 0; i < nu; ++i)
            Jtd[i] += D->J[(size_t)e * nu + i] * D->d[e];
    for (int i = 0; i < nu; ++i) {
        double s = 0;
        for (int j = 0; j < nu; ++j)
            s += M[(size_t)i * m + j] * Jtd[j];
        x[i] = s;
    }
    /* var_i = q_iᵀ JᵀJ q_i, q_i = row i of Q */
    double *t = malloc(sizeof(double) * nu);
    for (int i = 0; i < 2 * nn; ++i) {
        const double *qi = M + (size_t)i * m;
        for (int a = 0; a < nu; ++a) {
            double s = 0;
            for (int b = 0; b < nu; ++b)
                s += JtJ[(size_t)a * nu + b] * qi[b];
            t[a] = s;
        }
        double v = 0;
        for (int a = 0; a < nu; ++a)
            v += qi[a] * t[a];
        var_g[i] = v;
    }
    double r2 = 0;
    for (int e = 0; e < D->neq; ++e) {
        double s = D->d[e];
        for (int i = 0; i < nu; ++i)
            s -= D->J[(size_t)e * nu + i] * x[i];
        r2 += s * s;
    }
    *rss = r2;
    free(M), free(JtJ), free(ipiv), free(Jtd), free(t);
}

static void compare(int n, int kind, int use_mask, uint64_t seed)
{
    sc_grid_plan p;
    tu_plan(&p, n, kind);
    int nn = n * n;
    sc_rng r;
    sc_rng_seed(&r, seed);
    tu_truth t;
    sc_grid_data d;
    tu_truth_data(&p, &r, &t, &d);
    if (use_mask)
        for (int v = 0; v < p.n_views; ++v)
            for (int k = 0; k < nn; ++k)
                if (sc_rng_uniform(&r) < 0.1)
                    d.dx_um[v][k] = d.dy_um[v][k] = NAN;
    tu_add_noise(&d, 0.3, &r);
    dense D;
    dense_build(&D, &p, use_mask ? &d : NULL, &d);
    assert_int_equal(dense_free_dof(&D), 0);
    double *x = malloc(sizeof(double) * D.nu), *var = malloc(sizeof(double) * 2 * nn), rss;
    dense_solve(&D, &p, x, var, &rss);
    sc_grid_lsq_plan *q = NULL;
    sc_error err;
    assert_int_equal(sc_grid_lsq_plan_create(&p, use_mask ? &d : NULL, NULL, &q, &err), SC_OK);
    tu_res res;
    tu_res_alloc(&res, nn);
    assert_int_equal(sc_grid_lsq_execute(q, &d, 0, &res.r, &err), SC_OK);
    double scale_g = 0, eg = 0, ea = 0, eu = 0, em = 0;
    for (int k = 0; k < nn; ++k)
        scale_g = fmax(scale_g, fmax(fabs(x[2 * k]), fabs(x[2 * k + 1])));
    double sig = sqrt(rss / (D.neq - (D.nu - dense_nullity(&D, 0, D.nu))));
    for (int k = 0; k < nn; ++k) {
        eg = fmax(eg, fmax(fabs(res.r.gx_um[k] - x[2 * k]), fabs(res.r.gy_um[k] - x[2 * k + 1])));
        if (D.amap[k] >= 0) {
            int a0 = 2 * nn + 2 * D.amap[k];
            ea = fmax(ea, fmax(fabs(res.r.ax_um[k] - x[a0]), fabs(res.r.ay_um[k] - x[a0 + 1])));
        } else {
            assert_true(isnan(res.r.ax_um[k]));
        }
        double ux = sig * sqrt(var[2 * k]), uy = sig * sqrt(var[2 * k + 1]);
        eu = fmax(eu, fmax(fabs(res.r.ugx_um[k] / ux - 1), fabs(res.r.ugy_um[k] / uy - 1)));
    }
    for (int v = 0; v < p.n_views; ++v) {
        int m0 = 2 * nn + 2 * D.nam + 3 * v;
        em = fmax(em, fmax(fabs(res.r.tx_um[v] - x[m0]), fabs(res.r.ty_um[v] - x[m0 + 1])));
        em = fmax(em, fabs(res.r.theta_urad[v] - x[m0 + 2]) * 1e-3);
    }
    fprintf(stderr, "N=%d plan %d mask %d: rel dG %.2g dA %.2g dm %.2g du %.2g dσ %.2g\n", n,
            kind, use_mask, eg / scale_g, ea / scale_g, em / scale_g, eu,
            fabs(res.r.sigma_r_est_um / sig - 1));
    assert_true(eg <= 1e-9 * scale_g);
    assert_true(ea <= 1e-9 * scale_g);
    assert_true(em <= 1e-9 * scale_g);
    assert_true(eu <= 1e-9);
    assert_true(fabs(res.r.sigma_r_est_um / sig - 1) <= 1e-9);
    tu_res_free(&res);
    sc_grid_lsq_plan_destroy(q);
    free(x), free(var);
    dense_free(&D);
    tu_data_free(&d);
    tu_truth_free(&t);    sc_grid_plan_free(&p);
}

static void test_fast_vs_dense(void **s)
{
    (void)s;
    compare(5, PLAN_YE, 0, 1);
    compare(9, PLAN_YE, 0, 2);
    compare(7, PLAN_PETRO, 0, 3);
    compare(9, PLAN_PETRO, 0, 4);
    compare(7, PLAN_RICH, 0, 5);
    compare(9, PLAN_RICH, 1, 6);
    compare(11, PLAN_RICH, 1, 7);
}

static void test_free_dof_vs_dense(void **s)
{
    (void)s;
    const int ns[] = {5, 7, 9, 11, 15};
    const int kinds[] = {PLAN_YE,       PLAN_PETRO,   PLAN_RICH,  PLAN_0_90,
                         PLAN_0_180_1X, PLAN_0_90_2X, PLAN_SHIFTS};
    for (size_t i = 0; i < sizeof ns / sizeof *ns; ++i)
        for (size_t c = 0; c < sizeof kinds / sizeof *kinds; ++c) {
            if (ns[i] == 15 && kinds[c] != PLAN_0_90_2X && kinds[c] != PLAN_0_90)
                continue; /* keep the SVDs short */
            sc_grid_plan p;
            tu_plan(&p, ns[i], kinds[c]);
            dense D;
            dense_build(&D, &p, NULL, NULL);
            long kd = dense_free_dof(&D);
            sc_grid_lsq_plan *q = NULL;
            sc_error err;
            assert_int_equal(sc_grid_lsq_plan_create(&p, NULL, NULL, &q, &err), SC_OK);
            sc_grid_lsq_info info;
            sc_grid_lsq_get_info(q, &info);
            fprintf(stderr, "N=%2d plan %d: free dof sparse %ld dense %ld\n", ns[i], kinds[c],
                    info.free_dof, kd);
            assert_int_equal(info.free_dof, kd);
            assert_int_equal(info.identifiable, kd == 0);
            sc_grid_lsq_plan_destroy(q);
            dense_free(&D);
            sc_grid_plan_free(&p);
        }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fast_vs_dense),
        cmocka_unit_test(test_free_dof_vs_dense),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
