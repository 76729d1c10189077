/* The statistics of the least-squares tests (stats.h): χ² and Student's t quantiles, the normal
 * two-sided critical value, Šidák's share of a significance level, the outlier test's critical
 * value and Baarda's minimal detectable bias. Pure functions of their arguments. */
#include "stats.h"

#include <float.h>
#include <math.h>

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

/* ---- Student's t ---------------------------------------------------------------------------- */

/* The continued fraction of the regularized incomplete beta (modified Lentz). */
static double beta_cf(double a, double b, double x)
{
    const double tiny = 1e-300;
    double c = 1, d = 1 - (a + b) * x / (a + 1);
    d = fabs(d) < tiny ? tiny : d;
    d = 1 / d;
    double h = d;
    for (int m = 1; m < 500; ++m) {
        double m2 = 2.0 * m, num = m * (b - m) * x / ((a + m2 - 1) * (a + m2));
        d = 1 + num * d, c = 1 + num / c;
        d = fabs(d) < tiny ? tiny : d, c = fabs(c) < tiny ? tiny : c;
        d = 1 / d;
        h *= d * c;
        num = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1));
        d = 1 + num * d, c = 1 + num / c;
        d = fabs(d) < tiny ? tiny : d, c = fabs(c) < tiny ? tiny : c;
        d = 1 / d;
        double del = d * c;
        h *= del;
        if (fabs(del - 1) < 1e-15)
            break;
    }
    return h;
}

static double inc_beta(double a, double b, double x)
{
    if (x <= 0)
        return 0;
    if (x >= 1)
        return 1;
    double lb = lgamma(a + b) - lgamma(a) - lgamma(b) + a * log(x) + b * log1p(-x);
    if (x < (a + 1) / (a + b + 2))
        return exp(lb) * beta_cf(a, b, x) / a;
    return 1 - exp(lb) * beta_cf(b, a, 1 - x) / b;
}

/* P(T <= t), t >= 0. */
static double t_cdf_pos(double t, double nu)
{
    return 1 - 0.5 * inc_beta(nu / 2, 0.5, nu / (nu + t * t));
}

double sc_student_t_quantile(double p, double dof)
{
    if (!(p > 0 && p < 1) || !(dof > 0))
        return NAN;
    if (isinf(dof))
        return p >= 0.5 ? sc_normal_two_sided_critical(2 * (1 - p))
                        : -sc_normal_two_sided_critical(2 * p);
    if (p < 0.5)
        return -sc_student_t_quantile(1 - p, dof);
    if (p == 0.5)
        return 0;
    double lo = 0, hi = 1;
    while (t_cdf_pos(hi, dof) < p && hi < 1e300)
        hi *= 2;
    for (int it = 0; it < 200 && hi - lo > 1e-13 * hi; ++it) {
        double mid = 0.5 * (lo + hi);
        if (t_cdf_pos(mid, dof) < p)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

