/* profile_lsq_kernels.h — private: the two inner loops of the banded least-squares solver. */
#ifndef SELFCAL_PROFILE_LSQ_KERNELS_H
#define SELFCAL_PROFILE_LSQ_KERNELS_H

/* Σ a[i]·b[i], i < len (four partial sums: independent chains the compiler can pipeline). */
static inline double sc_lsq_dot(const double *a, const double *b, int len)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int i = 0;
    for (; i + 4 <= len; i += 4) {
        s0 += a[i] * b[i];
        s1 += a[i + 1] * b[i + 1];
        s2 += a[i + 2] * b[i + 2];
        s3 += a[i + 3] * b[i + 3];
    }
    for (; i < len; i++) s0 += a[i] * b[i];
    return (s0 + s1) + (s2 + s3);
}

/* y[i] += alpha·x[i], i < len. */
static inline void sc_lsq_axpy(double *restrict y, double alpha, const double *restrict x, int len)
{
    for (int i = 0; i < len; i++) y[i] += alpha * x[i];
}

/* y[i] += a[0]·x0[i] + a[1]·x1[i] + a[2]·x2[i] + a[3]·x3[i], i < len (one pass over y). */
static inline void sc_lsq_axpy4(double *restrict y, const double *a, const double *restrict x0,
                                const double *restrict x1, const double *restrict x2,
                                const double *restrict x3, int len)
{
    double a0 = a[0], a1 = a[1], a2 = a[2], a3 = a[3];
    for (int i = 0; i < len; i++) y[i] += (a0 * x0[i] + a1 * x1[i]) + (a2 * x2[i] + a3 * x3[i]);
}

#endif
