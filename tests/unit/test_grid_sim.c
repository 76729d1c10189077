/* Unit tests of the Petrò §5 simulation: reproducible, σ_G as requested, truth in the SPEC gauge,
 * data = the SPEC forward model (checked by an independent computation), the SAR(1) field solves
 * (I − ρW)F = ε with W row-standardised. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "selfcal/grid_io.h"
#include "selfcal/grid_sim.h"
#include "selfcal/rng.h"

typedef struct sim {
    sc_grid_data d;
    sc_grid_sim_truth t;
    double *buf;
} sim;

static sc_status run(sim *s, const sc_grid_plan *p, const sc_grid_sim_params *sp)
{
    int nn = p->n * p->n, nv = p->n_views;
    memset(s, 0, sizeof *s);
    sc_error err;
    assert_int_equal(sc_grid_plan_copy(&s->d.plan, p, &err), SC_OK);
    assert_int_equal(sc_grid_data_alloc(&s->d, &err), SC_OK);
    /* G and A (4 nn), the workspace (2 nn), the misalignments (3 nv) */
    s->buf = calloc(6 * (size_t)nn + 3 * (size_t)nv, sizeof(double));
    assert_non_null(s->buf);
    s->t.gx_um = s->buf, s->t.gy_um = s->buf + nn, s->t.ax_um = s->buf + 2 * nn,
    s->t.ay_um = s->buf + 3 * nn;
    s->t.tx_um = s->buf + 6 * nn, s->t.ty_um = s->t.tx_um + nv, s->t.theta_urad = s->t.ty_um + nv;
    return sc_grid_sim_run(&s->d.plan, sp, &s->t, &s->d, s->buf + 4 * nn, &err);
}

static void done(sim *s)
{
    sc_grid_data_free(&s->d);
    free(s->buf);
}

static void test_reproducible(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_double_shift(11, 1, 0, 0, &p, &err), SC_OK);
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.seed = 42;
    sim a, b, c;
    assert_int_equal(run(&a, &p, &sp), SC_OK);
    assert_int_equal(run(&b, &p, &sp), SC_OK);
    sp.seed = 43;
    assert_int_equal(run(&c, &p, &sp), SC_OK);
    int nn = 121;
    assert_memory_equal(a.buf, b.buf, 4 * nn * sizeof(double));
    for (int v = 0; v < p.n_views; ++v)
        for (int k = 0; k < nn; ++k) {
            assert_true(isnan(a.d.dx_um[v][k]) == isnan(b.d.dx_um[v][k]));
            if (!isnan(a.d.dx_um[v][k]))
                assert_true(a.d.dx_um[v][k] == b.d.dx_um[v][k] && a.d.dy_um[v][k] == b.d.dy_um[v][k]);
        }
    assert_true(memcmp(a.buf, c.buf, 4 * nn * sizeof(double)) != 0);
    done(&a), done(&b), done(&c);
    sc_grid_plan_free(&p);
}

static void test_sigma_g_gauge_forward_model(void **state)
{
    (void)state;
    const double sigmas[3] = {0.1, 1.0, 10.0};
    const int ns[3] = {9, 25, 41};
    for (int t = 0; t < 3; ++t) {
        int n = ns[t], nn = n * n;
        sc_grid_plan p;
        sc_error err;
        assert_int_equal(sc_grid_plan_ye(n, 0.5 + t, 5.0, -3.0, &p, &err), SC_OK);
        sc_grid_sim_params sp;
        sc_grid_sim_defaults(&sp);
        sp.sigma_g_um = sigmas[t];
        sp.O = 3e-6, sp.R = -2e-6;
        sp.sigma_r_um = 0;
        sp.seed = 7 + t;
        sim s;
        assert_int_equal(run(&s, &p, &sp), SC_OK);
        double *gx = s.t.gx_um, *gy = s.t.gy_um, *ax = s.t.ax_um, *ay = s.t.ay_um;
        /* Sample std of all 2N² values. */
        double mean = 0, var = 0;
        for (int k = 0; k < nn; ++k)
            mean += gx[k] + gy[k];
        mean /= 2 * nn;
        for (int k = 0; k < nn; ++k)
            var += (gx[k] - mean) * (gx[k] - mean) + (gy[k] - mean) * (gy[k] - mean);
        double sd = sqrt(var / (2 * nn - 1));
        assert_true(fabs(sd - sigmas[t]) < 1e-12 * sigmas[t]);
        /* Gauge and first-order terms, computed here (x, y in mm; G in µm; O, R per µm). */
        double c = (n - 1) / 2.0, P = p.pitch_mm;
        double stx = 0, sty = 0, srot = 0, smag = 0, so = 0, sr = 0, r2 = 0, atx = 0, aty = 0,
               arot = 0;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                double x = (j - c) * P, y = (i - c) * P;
                int k = i * n + j;
                stx += gx[k], sty += gy[k];
                srot += x * gy[k] - y * gx[k];
                smag += x * gx[k] + y * gy[k];
                so += x * gy[k] + y * gx[k];
                sr += x * gx[k] - y * gy[k];
                r2 += x * x + y * y;
                atx += ax[k], aty += ay[k];
                arot += x * ay[k] - y * ax[k];
            }
        double tol = 1e-9 * sigmas[t] * nn * n * P;
        assert_true(fabs(stx) < tol && fabs(sty) < tol && fabs(srot) < tol && fabs(smag) < tol);
        assert_true(fabs(atx) < 1e-9 * nn && fabs(aty) < 1e-9 * nn && fabs(arot) < 1e-9 * nn * n);
        assert_true(fabs(so / r2 / 1000 - sp.O) < 1e-12);
        assert_true(fabs(sr / r2 / 1000 - sp.R) < 1e-12);
        /* Forward model: dev = G(node) + Rot(A) + (tx − θ y, ty + θ x), θ in µrad, x in mm. */
        for (int v = 0; v < p.n_views; ++v) {
            int rot = p.view[v].rot_deg;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    double u = j - c, q = i - c, ru, rq;
                    double A0 = ax[i * n + j], A1 = ay[i * n + j], ra0, ra1;
                    if (rot == 0) ru = u, rq = q, ra0 = A0, ra1 = A1;
                    else ru = -q, rq = u, ra0 = -A1, ra1 = A0; /* 90° CCW */
                    int jn = (int)lround(c + ru) + p.view[v].shift_x;
                    int in = (int)lround(c + rq) + p.view[v].shift_y;
                    double dx = s.d.dx_um[v][i * n + j], dy = s.d.dy_um[v][i * n + j];
                    if (jn < 0 || jn >= n || in < 0 || in >= n) {
                        assert_true(isnan(dx) && isnan(dy));
                        continue;
                    }
                    double x = (jn - c) * P, y = (in - c) * P;
                    double ex = gx[in * n + jn] + ra0 + s.t.tx_um[v] - s.t.theta_urad[v] * y * 1e-3;
                    double ey = gy[in * n + jn] + ra1 + s.t.ty_um[v] + s.t.theta_urad[v] * x * 1e-3;
                    assert_true(fabs(dx - ex) < 1e-12 && fabs(dy - ey) < 1e-12);
                }
        }
        done(&s);
        sc_grid_plan_free(&p);
    }
}

static void test_noise(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_ye(25, 1, 0, 0, &p, &err), SC_OK);
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.sigma_r_um = 0;
    sim a, b;
    assert_int_equal(run(&a, &p, &sp), SC_OK);
    sp.sigma_r_um = 0.3;
    assert_int_equal(run(&b, &p, &sp), SC_OK);
    assert_memory_equal(a.buf, b.buf, 4 * 625 * sizeof(double)); /* noise is drawn last */
    double s2 = 0, m = 0;
    long cnt = 0;
    for (int v = 0; v < 3; ++v)
        for (int k = 0; k < 625; ++k)
            if (!isnan(a.d.dx_um[v][k])) {
                double ex = b.d.dx_um[v][k] - a.d.dx_um[v][k], ey = b.d.dy_um[v][k] - a.d.dy_um[v][k];
                s2 += ex * ex + ey * ey, m += ex + ey, cnt += 2;
            }
    double sd = sqrt(s2 / cnt);
    assert_true(fabs(sd / 0.3 - 1) < 0.05); /* ~3600 values: 5 % is > 4 standard errors */
    assert_true(fabs(m / cnt) < 0.03);
    done(&a), done(&b);
    sc_grid_plan_free(&p);
}

/* L f = f − ρ W f with W the row-standardised 4-neighbour adjacency. */
static void apply_sar(int n, double rho, const double *f, double *out)
{
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double s = 0;
            int deg = 0;
            if (i > 0) s += f[(i - 1) * n + j], ++deg;
            if (i < n - 1) s += f[(i + 1) * n + j], ++deg;
            if (j > 0) s += f[i * n + j - 1], ++deg;
            if (j < n - 1) s += f[i * n + j + 1], ++deg;
            out[i * n + j] = f[i * n + j] - rho * s / deg;
        }
}

/* The second-order part F = (G − first order)/s satisfies L F = ε − L(gauge patterns) c for some c:
 * the residual of ε − L F, fitted on the six L-transformed patterns, vanishes. */
static void test_sar_field(void **state)
{
    (void)state;
    int n = 15, nn = n * n;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_ye(n, 1, 0, 0, &p, &err), SC_OK);
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sp.seed = 99;
    sim s;
    assert_int_equal(run(&s, &p, &sp), SC_OK);
    sc_rng rng;
    sc_rng_seed(&rng, sp.seed);
    double *eps = malloc(2 * nn * sizeof(double)), *f = malloc(2 * nn * sizeof(double));
    double *lf = malloc(2 * nn * sizeof(double)), *pat = malloc(6 * 2 * nn * sizeof(double));
    double *lp = malloc(6 * 2 * nn * sizeof(double));
    for (int k = 0; k < 2 * nn; ++k)
        eps[k] = sc_rng_normal(&rng);
    double c = (n - 1) / 2.0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double x = j - c, y = i - c;
            int k = i * n + j;
            f[k] = (s.t.gx_um[k] - (sp.O * y + sp.R * x) * 1e3) / s.t.sar_scale;
            f[nn + k] = (s.t.gy_um[k] - (sp.O * x - sp.R * y) * 1e3) / s.t.sar_scale;
            double px[6] = {1, 0, -y, x, y, x}, py[6] = {0, 1, x, y, x, -y};
            for (int a = 0; a < 6; ++a)
                pat[a * 2 * nn + k] = px[a], pat[a * 2 * nn + nn + k] = py[a];
        }
    apply_sar(n, sp.rho, f, lf);
    apply_sar(n, sp.rho, f + nn, lf + nn);
    for (int a = 0; a < 6; ++a) {
        apply_sar(n, sp.rho, pat + a * 2 * nn, lp + a * 2 * nn);
        apply_sar(n, sp.rho, pat + a * 2 * nn + nn, lp + a * 2 * nn + nn);
    }
    /* r = ε − L F; least squares r ≈ Σ c_a L p_a via normal equations (Gauss-Jordan). */
    double M[6][7], rn = 0;
    for (int k = 0; k < 2 * nn; ++k)
        lf[k] = eps[k] - lf[k], rn += eps[k] * eps[k];
    for (int a = 0; a < 6; ++a) {
        for (int b = 0; b < 6; ++b) {
            double sum = 0;
            for (int k = 0; k < 2 * nn; ++k)
                sum += lp[a * 2 * nn + k] * lp[b * 2 * nn + k];
            M[a][b] = sum;
        }
        double sum = 0;
        for (int k = 0; k < 2 * nn; ++k)
            sum += lp[a * 2 * nn + k] * lf[k];
        M[a][6] = sum;
    }
    for (int a = 0; a < 6; ++a) {
        int piv = a;
        for (int b = a + 1; b < 6; ++b)
            if (fabs(M[b][a]) > fabs(M[piv][a]))
                piv = b;
        for (int q = 0; q < 7; ++q) {
            double tmp = M[a][q];
            M[a][q] = M[piv][q];
            M[piv][q] = tmp;
        }
        for (int b = 0; b < 6; ++b) {
            if (b == a)
                continue;
            double fct = M[b][a] / M[a][a];
            for (int q = a; q < 7; ++q)
                M[b][q] -= fct * M[a][q];
        }
    }
    double res = 0;
    for (int k = 0; k < 2 * nn; ++k) {
        double v = lf[k];
        for (int a = 0; a < 6; ++a)
            v -= M[a][6] / M[a][a] * lp[a * 2 * nn + k];
        res += v * v;
    }
    assert_true(sqrt(res / rn) < 1e-10);
    /* Strong spatial correlation: neighbours along x correlate well above 0.5. */
    double sxy = 0, sxx = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j + 1 < n; ++j)
            sxy += f[i * n + j] * f[i * n + j + 1], sxx += f[i * n + j] * f[i * n + j];
    assert_true(sxy / sxx > 0.5);
    free(eps), free(f), free(lf), free(pat), free(lp);
    done(&s);
    sc_grid_plan_free(&p);
}

static void test_bad_parameters(void **state)
{
    (void)state;
    sc_grid_plan p;
    sc_error err;
    assert_int_equal(sc_grid_plan_ye(25, 10, 0, 0, &p, &err), SC_OK);
    sc_grid_sim_params sp;
    sc_grid_sim_defaults(&sp);
    sim s;
    assert_int_equal(run(&s, &p, &sp), SC_E_INPUT); /* O, R at 240 mm exceed σ_G = 1 µm */
    done(&s);
    sp.O = sp.R = 0;
    sp.rho = 1.0;
    assert_int_equal(run(&s, &p, &sp), SC_E_INPUT);
    done(&s);
    sp.rho = 0.9;
    sp.sigma_r_um = -1;
    assert_int_equal(run(&s, &p, &sp), SC_E_INPUT);
    done(&s);
    sc_grid_plan_free(&p);
    assert_int_equal(sc_grid_plan_double_shift(5, 1, 0, 0, &p, &err), SC_E_INPUT);
    assert_null(p.view); /* a plan that failed holds nothing */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_reproducible),
        cmocka_unit_test(test_sigma_g_gauge_forward_model),
        cmocka_unit_test(test_noise),
        cmocka_unit_test(test_sar_field),
        cmocka_unit_test(test_bad_parameters),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
