/* line_fit.c — owns the least-squares straight line through points (line_fit.h): centred sums,
 * in the order of the points (the readers' and the table's bits depend on it). */
#include "line_fit.h"

void sc_line_fit(const double *k, const double *v, size_t n, double *a, double *b)
{
    double km = 0, vm = 0;
    for (size_t m = 0; m < n; ++m) {
        km += k[m];
        vm += v[m];
    }
    km /= (double)n;
    vm /= (double)n;
    double skk = 0, skv = 0;
    for (size_t m = 0; m < n; ++m) {
        skk += (k[m] - km) * (k[m] - km);
        skv += (k[m] - km) * (v[m] - vm);
    }
    *b = skk > 0 ? skv / skk : 0.0;
    *a = vm - *b * km;
}
