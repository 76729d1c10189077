/* Simulated straightness measurements (SPEC §2 model) and the profiles they measure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/profile_sim.h"
#include "../io/dabam_internal.h"

void sc_profile_sim_defaults(sc_profile_sim *p)
{
    memset(p, 0, sizeof *p);
    p->n = 330;
    p->s_mm = 1.0;
    p->d1 = 10;
    p->d2 = 11;
    p->sigma_disp_um = 0.01;
    p->sigma_angle_urad = 1.0;
    p->ey_amp_um = 0.5;
    p->ep_amp_urad = 2.0;
    p->u1_um = 1.5;
    p->u2_um = -0.7;
    p->u3_urad = 3.0;
    p->b0_um = 20.0;
    p->write_sigma = 1;
    p->seed = 1;
}

void sc_profile_random_smooth(int n, double amp_um, int harmonics, sc_rng *rng, double *f_um)
{
    for (int i = 0; i < n; ++i)
        f_um[i] = 0;
    if (harmonics < 1)
        harmonics = 1;
    for (int j = 1; j <= harmonics; ++j) {
        double a = sc_rng_normal(rng) / pow(j, 1.5), ph = 2.0 * M_PI * sc_rng_uniform(rng);
        /* half-integer frequencies too, so that the profile is not periodic on the scan */
        double fr = 0.5 * j;
        for (int i = 0; i < n; ++i)
            f_um[i] += a * sin(2.0 * M_PI * fr * i / (n > 1 ? n - 1 : 1) + ph);
    }
    sc_profile_remove_line(n, f_um);
    double ss = 0;
    for (int i = 0; i < n; ++i)
        ss += f_um[i] * f_um[i];
    double rms = sqrt(ss / n);
    if (rms > 0)
        for (int i = 0; i < n; ++i)
            f_um[i] *= amp_um / rms;
}

void sc_profile_sim_random_truth(const sc_profile_sim *p, double amp_um, int harmonics,
                                 double *f_um)
{
    sc_rng rng;
    sc_rng_seed(&rng, p->seed ^ 0x5eed5eedULL);
    sc_profile_random_smooth(p->n, amp_um, harmonics, &rng, f_um);
}

/* ---- DABAM: the file is io/dabam.c's; here its points become a profile on the scan ---- */

/* Heights in µm at the abscissae: the slopes integrated by the trapezoidal rule, or scaled. */
static void dabam_heights_um(const sc_dabam_points *d, int is_slope, double *hs)
{
    if (is_slope) {
        hs[0] = 0;
        for (size_t i = 1; i < d->count; ++i)
            hs[i] = hs[i - 1] + 0.5 * (d->ys[i] + d->ys[i - 1]) * (d->xs[i] - d->xs[i - 1]) * 1e6;
    } else {
        for (size_t i = 0; i < d->count; ++i)
            hs[i] = d->ys[i] * 1e6;
    }
}

/* n points at pitch s_mm, centred on the mirror (true scale), or the mirror stretched onto the
 * scan when it is shorter; linear interpolation of hs. Returns whether at true scale. */
static int dabam_resample(const sc_dabam_points *d, const double *hs, int n, double s_mm,
                          double *f_um)
{
    const double *xs = d->xs;
    size_t cnt = d->count;
    double len_m = xs[cnt - 1] - xs[0], span_m = (n - 1) * s_mm * 1e-3;
    int true_scale = span_m <= len_m;
    double x0 = true_scale ? xs[0] + 0.5 * (len_m - span_m) : xs[0];
    double dx = true_scale ? s_mm * 1e-3 : len_m / (n - 1);
    size_t j = 0;
    for (int i = 0; i < n; ++i) {
        double x = x0 + i * dx;
        if (x > xs[cnt - 1])
            x = xs[cnt - 1];
        while (j + 2 < cnt && xs[j + 1] < x)
            ++j;
        double t = (x - xs[j]) / (xs[j + 1] - xs[j]);
        if (t < 0)
            t = 0;
        if (t > 1)
            t = 1;
        f_um[i] = hs[j] + t * (hs[j + 1] - hs[j]);
    }
    return true_scale;
}

sc_status sc_profile_load_dabam(const char *dat_path, int n, double s_mm, double *f_um,
                                char *info, size_t infolen, sc_error *err)
{
    sc_dabam_points d;
    sc_status st = sc_dabam_read(dat_path, &d, err);
    if (st != SC_OK)
        return st;
    double *hs = malloc(d.count * sizeof(double));
    if (!hs) {
        sc_dabam_points_free(&d);
        return sc_error_set(err, SC_E_NOMEM, dat_path, 0, "out of memory");
    }
    dabam_heights_um(&d, d.is_slope, hs);
    int true_scale = dabam_resample(&d, hs, n, s_mm, f_um);
    sc_profile_remove_line(n, f_um);
    if (info)
        snprintf(info, infolen, "%s: %zu %s points over %.1f mm, %s", dat_path, d.count,
                 d.is_slope ? "slope" : "height", (d.xs[d.count - 1] - d.xs[0]) * 1e3,
                 true_scale ? "true scale, centred" : "stretched onto the scan length");
    sc_dabam_points_free(&d);
    free(hs);
    return SC_OK;
}

sc_status sc_profile_simulate(const sc_profile_sim *p, const double *f_um, sc_profile_data *out,
                              double *ey_um, sc_error *err)
{
    sc_status st = sc_profile_data_init(out, p->n, p->s_mm, p->d1, p->d2, err);
    if (st != SC_OK)
        return st;
    if (!(p->sigma_disp_um >= 0) || !(p->sigma_angle_urad >= 0)) {
        sc_profile_data_free(out);
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "noise levels must be non-negative");
    }
    const int n = p->n;
    double *ep = malloc((size_t)n * sizeof(double));
    if (!ep) {
        sc_profile_data_free(out);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    sc_rng rng;
    sc_rng_seed(&rng, p->seed);
    /* the stage's motion errors: smooth, repeatable (the same in both scans) */
    sc_profile_random_smooth(n, 1.0, 8, &rng, ey_um);
    sc_profile_random_smooth(n, 1.0, 8, &rng, ep);
    double tc = 0.5 * (n - 1);
    for (int i = 0; i < n; ++i) {
        /* plus a tilt, which a real stage also has */
        ey_um[i] = p->ey_amp_um * (ey_um[i] + 0.8 * (i - tc) / (tc > 0 ? tc : 1));
        ep[i] = p->ep_amp_urad * ep[i];
    }
    for (int k = 0; k < 2; ++k) {
        const int d = out->d[k], m = n - d;
        const double D_mm = d * p->s_mm;
        for (int i = 0; i < m; ++i) {
            out->m1_um[k][i] = f_um[i] + ey_um[i] + p->u1_um + p->b0_um +
                               p->sigma_disp_um * sc_rng_normal(&rng);
            out->m2_um[k][i] = f_um[i + d] + ey_um[i] + D_mm * ep[i] * 1e-3 + p->u2_um + p->b0_um +
                               p->sigma_disp_um * sc_rng_normal(&rng);
            out->m3_urad[k][i] = ep[i] + p->u3_urad + p->sigma_angle_urad * sc_rng_normal(&rng);
        }
    }
    out->has_sigma_disp = out->has_sigma_angle = p->write_sigma ? 1 : 0;
    out->sigma_disp_um = p->sigma_disp_um;
    out->sigma_angle_urad = p->sigma_angle_urad;
    free(ep);
    return SC_OK;
}
