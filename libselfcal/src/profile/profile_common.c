/* What both profile methods share: the combined differences y_k, their noise variance, the
 * least-squares line, the stage error e_y, residuals, and Monte Carlo uncertainty. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/profile.h"
#include "selfcal/rng.h"

void sc_profile_combine(const sc_profile_data *d, int k, double *y_um)
{
    const double D_mm = d->d[k] * d->s_mm;
    const int m = d->n - d->d[k];
    if (d->has_probe_gain || d->has_angle_scale) { /* SPEC §2a: m2 / K, m3 / K_angle */
        const double kg = d->has_probe_gain ? d->probe_gain[0] : 1.0;
        const double ka = d->has_angle_scale ? d->angle_scale[0] : 1.0;
        for (int i = 0; i < m; ++i)
            y_um[i] = d->m2_um[k][i] / kg - d->m1_um[k][i] - D_mm * (d->m3_urad[k][i] / ka) * 1e-3;
        return;
    }
    for (int i = 0; i < m; ++i)
        y_um[i] = d->m2_um[k][i] - d->m1_um[k][i] - D_mm * d->m3_urad[k][i] * 1e-3;
}

double sc_profile_y_variance(int d, double s_mm, double sigma_disp_um, double sigma_angle_urad)
{
    double a = d * s_mm * sigma_angle_urad * 1e-3;
    return 2.0 * sigma_disp_um * sigma_disp_um + a * a;
}

void sc_profile_remove_line(int n, double *v)
{
    if (n <= 0)
        return;
    double tc = 0.5 * (n - 1), mean = 0, stt = 0, sty = 0;
    for (int i = 0; i < n; ++i)
        mean += v[i];
    mean /= n;
    for (int i = 0; i < n; ++i) {
        double t = i - tc;
        stt += t * t;
        sty += t * (v[i] - mean);
    }
    double slope = stt > 0 ? sty / stt : 0;
    for (int i = 0; i < n; ++i)
        v[i] -= mean + slope * (i - tc);
}

void sc_profile_stage_error(const sc_profile_data *d, const double *f_um, double *ey_um)
{
    const int m = d->n - d->d[0];
    for (int i = 0; i < m; ++i)
        ey_um[i] = d->m1_um[0][i] - f_um[i];
    sc_profile_remove_line(m, ey_um);
}

double sc_profile_residual_ss(int n, int d1, int d2, const double *y1_um, const double *y2_um,
                              const double *f_um, double w1, double w2, int *dof)
{
    const int dk[2] = {d1, d2};
    const double *yk[2] = {y1_um, y2_um};
    const double wk[2] = {w1, w2};
    double ss = 0;
    for (int k = 0; k < 2; ++k) {
        const int m = n - dk[k];
        double c = 0;
        for (int i = 0; i < m; ++i)
            c += yk[k][i] - (f_um[i + dk[k]] - f_um[i]);
        c /= m;
        for (int i = 0; i < m; ++i) {
            double r = yk[k][i] - (f_um[i + dk[k]] - f_um[i]) - c;
            ss += wk[k] * r * r;
        }
    }
    if (dof)
        *dof = n - d1 - d2;
    return ss;
}

sc_status sc_profile_mc_uncertainty(int n, int d1, int d2, double sigma_y1_um,
                                    double sigma_y2_um, sc_profile_solver_fn solve, void *ctx,
                                    long trials, uint64_t seed, sc_progress_fn progress,
                                    void *pctx, double *uf_um, sc_error *err)
{
    if (trials < 2)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "Monte Carlo needs at least 2 trials (got %ld)", trials);
    double *y1 = malloc((size_t)(n - d1) * sizeof(double));
    double *y2 = malloc((size_t)(n - d2) * sizeof(double));
    double *f = malloc((size_t)n * sizeof(double));
    double *mean = calloc((size_t)n, sizeof(double));
    double *m2 = calloc((size_t)n, sizeof(double));
    if (!y1 || !y2 || !f || !mean || !m2) {
        free(y1), free(y2), free(f), free(mean), free(m2);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory for N = %d", n);
    }
    sc_rng rng;
    sc_rng_seed(&rng, seed);
    sc_status st = SC_OK;
    long step = trials / 100 > 0 ? trials / 100 : 1;
    for (long t = 0; t < trials; ++t) {
        for (int i = 0; i < n - d1; ++i)
            y1[i] = sigma_y1_um * sc_rng_normal(&rng);
        for (int i = 0; i < n - d2; ++i)
            y2[i] = sigma_y2_um * sc_rng_normal(&rng);
        if ((st = solve(ctx, y1, y2, f, err)) != SC_OK)
            break;
        /* Welford's running mean and sum of squared deviations */
        for (int i = 0; i < n; ++i) {
            double dlt = f[i] - mean[i];
            mean[i] += dlt / (t + 1);
            m2[i] += dlt * (f[i] - mean[i]);
        }
        if (progress && ((t + 1) % step == 0 || t + 1 == trials))
            progress(pctx, t + 1, trials);
    }
    if (st == SC_OK)
        for (int i = 0; i < n; ++i)
            uf_um[i] = sqrt(m2[i] / (trials - 1));
    free(y1), free(y2), free(f), free(mean), free(m2);
    return st;
}
