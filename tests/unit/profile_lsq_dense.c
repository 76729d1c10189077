/* profile_lsq_dense.c — dense LAPACK reference for the profile least squares (see the header). */
#include "profile_lsq_dense.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int sc_profile_lsq_dense_solve(int n, int d1, int d2, double w1, double w2, const double *y1,
                               const double *y2, double *f, double *c, double *uf)
{
    int m = n + 4; /* f(0..n-1), c1, c2, two Lagrange multipliers */
    double *k = calloc((size_t)m * m, sizeof(double));
    double *rhs = calloc((size_t)m, sizeof(double));
    lapack_int *ipiv = malloc((size_t)m * sizeof(lapack_int));
    if (!k || !rhs || !ipiv) {
        free(k);
        free(rhs);
        free(ipiv);
        return -1;
    }
    const int dk[2] = {d1, d2};
    const double wk[2] = {w1, w2};
    const double *yk[2] = {y1, y2};
#define K(r, col) k[(size_t)(r) * m + (col)]
    /* normal matrix from the observation rows: +1 at f(j+d), -1 at f(j), +1 at c_k */
    for (int s = 0; s < 2; s++) {
        for (int j = 0; j + dk[s] < n; j++) {
            int idx[3] = {j + dk[s], j, n + s};
            double val[3] = {1.0, -1.0, 1.0};
            for (int a = 0; a < 3; a++) {
                for (int b = 0; b < 3; b++) K(idx[a], idx[b]) += wk[s] * val[a] * val[b];
                rhs[idx[a]] += wk[s] * val[a] * yk[s][j];
            }
        }
    }
    /* gauge rows: Σ f = 0 and Σ (i - (n-1)/2) f = 0, scaled to the normal matrix */
    double gamma = w1 + w2, nc = 0.5 * (n - 1), norm2 = 0.0;
    for (int i = 0; i < n; i++) norm2 += (i - nc) * (i - nc);
    for (int i = 0; i < n; i++) {
        double q1 = gamma / sqrt((double)n), q2 = gamma * (i - nc) / sqrt(norm2);
        K(n + 2, i) = K(i, n + 2) = q1;
        K(n + 3, i) = K(i, n + 3) = q2;
    }
#undef K
    int rc = 0;
    if (LAPACKE_dsytrf(LAPACK_ROW_MAJOR, 'L', m, k, m, ipiv) != 0) rc = -2;
    if (!rc && LAPACKE_dsytrs(LAPACK_ROW_MAJOR, 'L', m, 1, k, m, ipiv, rhs, 1) != 0) rc = -3;
    if (!rc) {
        memcpy(f, rhs, (size_t)n * sizeof(double));
        if (c) {
            c[0] = rhs[n];
            c[1] = rhs[n + 1];
        }
    }
    if (!rc && uf) {
        if (LAPACKE_dsytri(LAPACK_ROW_MAJOR, 'L', m, k, m, ipiv) != 0) rc = -4;
        for (int i = 0; !rc && i < n; i++) {
            double v = k[(size_t)i * m + i];
            uf[i] = v > 0.0 ? sqrt(v) : 0.0;
        }
    }
    free(k);
    free(rhs);
    free(ipiv);
    return rc;
}

int sc_profile_lsq_dense_rank(int n, int d1, int d2)
{
    int rows = (n > d1 ? n - d1 : 0) + (n > d2 ? n - d2 : 0), cols = n + 2;
    if (rows == 0) return 0;
    double *a = calloc((size_t)rows * cols, sizeof(double));
    int mn = rows < cols ? rows : cols;
    double *s = malloc((size_t)mn * sizeof(double));
    double *sup = malloc((size_t)mn * sizeof(double));
    if (!a || !s || !sup) {
        free(a);
        free(s);
        free(sup);
        return -1;
    }
    int r = 0;
    const int dk[2] = {d1, d2};
    for (int q = 0; q < 2; q++)
        for (int j = 0; j + dk[q] < n; j++, r++) {
            a[(size_t)r * cols + j + dk[q]] += 1.0;
            a[(size_t)r * cols + j] -= 1.0;
            a[(size_t)r * cols + n + q] = 1.0;
        }
    int rank = -1;
    if (LAPACKE_dgesvd(LAPACK_ROW_MAJOR, 'N', 'N', rows, cols, a, cols, s, NULL, 1, NULL, 1, sup) ==
        0) {
        rank = 0;
        for (int i = 0; i < mn; i++)
            if (s[i] > 1e-9 * s[0]) rank++;
    }
    free(a);
    free(s);
    free(sup);
    return rank;
}
