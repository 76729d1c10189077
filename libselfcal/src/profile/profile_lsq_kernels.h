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

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define SC_LSQ_HAVE_AVX2 1
#include <immintrin.h>
#define SC_LSQ_AVX2_ATTR __attribute__((target("avx2,fma")))

SC_LSQ_AVX2_ATTR static inline double sc_lsq_hsum_avx2(__m256d v)
{
    __m128d lo = _mm256_castpd256_pd128(v), hi = _mm256_extractf128_pd(v, 1);
    lo = _mm_add_pd(lo, hi);
    return _mm_cvtsd_f64(_mm_add_sd(lo, _mm_unpackhi_pd(lo, lo)));
}

SC_LSQ_AVX2_ATTR static inline double sc_lsq_dot_avx2(const double *a, const double *b, int len)
{
    __m256d s0 = _mm256_setzero_pd(), s1 = _mm256_setzero_pd();
    int i = 0;
    for (; i + 8 <= len; i += 8) {
        s0 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i), _mm256_loadu_pd(b + i), s0);
        s1 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i + 4), _mm256_loadu_pd(b + i + 4), s1);
    }
    if (i + 4 <= len) {
        s0 = _mm256_fmadd_pd(_mm256_loadu_pd(a + i), _mm256_loadu_pd(b + i), s0);
        i += 4;
    }
    double s = sc_lsq_hsum_avx2(_mm256_add_pd(s0, s1));
    for (; i < len; i++) s = __builtin_fma(a[i], b[i], s);
    return s;
}

SC_LSQ_AVX2_ATTR static inline void sc_lsq_axpy_avx2(double *restrict y, double alpha,
                                                      const double *restrict x, int len)
{
    __m256d va = _mm256_set1_pd(alpha);
    int i = 0;
    for (; i + 8 <= len; i += 8) {
        __m256d y0 = _mm256_fmadd_pd(va, _mm256_loadu_pd(x + i), _mm256_loadu_pd(y + i));
        __m256d y1 = _mm256_fmadd_pd(va, _mm256_loadu_pd(x + i + 4), _mm256_loadu_pd(y + i + 4));
        _mm256_storeu_pd(y + i, y0);
        _mm256_storeu_pd(y + i + 4, y1);
    }
    if (i + 4 <= len) {
        _mm256_storeu_pd(y + i, _mm256_fmadd_pd(va, _mm256_loadu_pd(x + i), _mm256_loadu_pd(y + i)));
        i += 4;
    }
    for (; i < len; i++) y[i] = __builtin_fma(alpha, x[i], y[i]);
}

SC_LSQ_AVX2_ATTR static inline void sc_lsq_axpy4_avx2(double *restrict y, const double *a,
                                                       const double *restrict x0,
                                                       const double *restrict x1,
                                                       const double *restrict x2,
                                                       const double *restrict x3, int len)
{
    __m256d a0 = _mm256_set1_pd(a[0]), a1 = _mm256_set1_pd(a[1]), a2 = _mm256_set1_pd(a[2]),
            a3 = _mm256_set1_pd(a[3]);
    int i = 0;
    for (; i + 4 <= len; i += 4) {
        __m256d u = _mm256_fmadd_pd(a0, _mm256_loadu_pd(x0 + i), _mm256_loadu_pd(y + i));
        __m256d v = _mm256_mul_pd(a1, _mm256_loadu_pd(x1 + i));
        u = _mm256_fmadd_pd(a2, _mm256_loadu_pd(x2 + i), u);
        v = _mm256_fmadd_pd(a3, _mm256_loadu_pd(x3 + i), v);
        _mm256_storeu_pd(y + i, _mm256_add_pd(u, v));
    }
    for (; i < len; i++) y[i] += (a[0] * x0[i] + a[1] * x1[i]) + (a[2] * x2[i] + a[3] * x3[i]);
}
#else
#define SC_LSQ_HAVE_AVX2 0
#endif

#endif
