/* profile_lsq_kernels.h — private: the two inner loops of the banded least-squares solver. */
#ifndef SELFCAL_PROFILE_LSQ_KERNELS_H
#define SELFCAL_PROFILE_LSQ_KERNELS_H

#include <stddef.h>

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

/* out[r] = Σ p_r[i]·x[i], i < len, r = 0..3 (four dot products sharing x). */
static inline void sc_lsq_dot4(const double *x, const double *p0, const double *p1,
                               const double *p2, const double *p3, int len, double *out)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    for (int i = 0; i < len; i++) {
        double xi = x[i];
        s0 += p0[i] * xi;
        s1 += p1[i] * xi;
        s2 += p2[i] * xi;
        s3 += p3[i] * xi;
    }
    out[0] = s0;
    out[1] = s1;
    out[2] = s2;
    out[3] = s3;
}

/* t[j] = Σ_q l[q]·rows[q][j], j < w, q < cnt. */
static inline void sc_lsq_gemv_rows(double *restrict t, const double *l, const double *const *rows,
                                    int cnt, int w)
{
    for (int j = 0; j < w; j++) t[j] = 0.0;
    int q = 0;
    for (; q + 4 <= cnt; q += 4)
        sc_lsq_axpy4(t, l + q, rows[q], rows[q + 1], rows[q + 2], rows[q + 3], w);
    for (; q < cnt; q++) sc_lsq_axpy(t, l[q], rows[q], w);
}

/* t[j] = Σ_q l[q]·rows[q][j] and u[j] = Σ_q m[q]·rows[q][j], j < w (two outputs). */
static inline void sc_lsq_gemv2_rows(double *restrict t, double *restrict u, const double *l,
                                     const double *m, const double *const *rows, int cnt, int w)
{
    sc_lsq_gemv_rows(t, l, rows, cnt, w);
    sc_lsq_gemv_rows(u, m, rows, cnt, w);
}


/* t[r][j] = Σ_q l[r][q]·w[q][j] for r < 4, j < cols (a multiple of 4), q < kdim: l rows of stride
 * ldl, w rows of stride ldw, t rows of stride ldt (four steps of the selected inversion). */
static inline void sc_lsq_gemm4(double *restrict t, int ldt, const double *l, int ldl,
                                const double *w, int ldw, int kdim, int cols)
{
    for (int r = 0; r < 4; r++) {
        double *tr = t + (size_t)r * ldt;
        for (int j = 0; j < cols; j++) tr[j] = 0.0;
        for (int q = 0; q < kdim; q++) {
            double a = l[(size_t)r * ldl + q];
            const double *wq = w + (size_t)q * ldw;
            for (int j = 0; j < cols; j++) tr[j] += a * wq[j];
        }
    }
}

/* Rank-8 update of four consecutive rows k .. k+3 of the band storage, each up to its diagonal:
 * y_r[t] -= Σ_c v[c·h + qrow + r]·v[c·h + t], t = 0 .. cm + r (row r of y at y0 + r·ys; t = 0
 * is column l0, t = cm column k; the band rows share columns at stride ld - 1). */
static inline void sc_lsq_syrk8x4(double *y0, ptrdiff_t ys, const double *v, int h, int qrow,
                                  int cm)
{
    for (int r = 0; r < 4; r++) {
        double *y = y0 + r * ys;
        for (int t = 0; t <= cm + r; t++) {
            double acc = 0.0;
            for (int c = 0; c < 8; c++) acc += v[(size_t)c * h + qrow + r] * v[(size_t)c * h + t];
            y[t] -= acc;
        }
    }
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
SC_LSQ_AVX2_ATTR static inline void sc_lsq_dot4_avx2(const double *x, const double *p0,
                                                      const double *p1, const double *p2,
                                                      const double *p3, int len, double *out)
{
    __m256d s0 = _mm256_setzero_pd(), s1 = _mm256_setzero_pd(), s2 = _mm256_setzero_pd(),
            s3 = _mm256_setzero_pd(), u0 = _mm256_setzero_pd(), u1 = _mm256_setzero_pd(),
            u2 = _mm256_setzero_pd(), u3 = _mm256_setzero_pd();
    int i = 0;
    for (; i + 8 <= len; i += 8) { /* eight independent chains */
        __m256d xv = _mm256_loadu_pd(x + i), xw = _mm256_loadu_pd(x + i + 4);
        s0 = _mm256_fmadd_pd(_mm256_loadu_pd(p0 + i), xv, s0);
        s1 = _mm256_fmadd_pd(_mm256_loadu_pd(p1 + i), xv, s1);
        s2 = _mm256_fmadd_pd(_mm256_loadu_pd(p2 + i), xv, s2);
        s3 = _mm256_fmadd_pd(_mm256_loadu_pd(p3 + i), xv, s3);
        u0 = _mm256_fmadd_pd(_mm256_loadu_pd(p0 + i + 4), xw, u0);
        u1 = _mm256_fmadd_pd(_mm256_loadu_pd(p1 + i + 4), xw, u1);
        u2 = _mm256_fmadd_pd(_mm256_loadu_pd(p2 + i + 4), xw, u2);
        u3 = _mm256_fmadd_pd(_mm256_loadu_pd(p3 + i + 4), xw, u3);
    }
    if (i + 4 <= len) {
        __m256d xv = _mm256_loadu_pd(x + i);
        s0 = _mm256_fmadd_pd(_mm256_loadu_pd(p0 + i), xv, s0);
        s1 = _mm256_fmadd_pd(_mm256_loadu_pd(p1 + i), xv, s1);
        s2 = _mm256_fmadd_pd(_mm256_loadu_pd(p2 + i), xv, s2);
        s3 = _mm256_fmadd_pd(_mm256_loadu_pd(p3 + i), xv, s3);
        i += 4;
    }
    double r0 = sc_lsq_hsum_avx2(_mm256_add_pd(s0, u0)), r1 = sc_lsq_hsum_avx2(_mm256_add_pd(s1, u1)),
           r2 = sc_lsq_hsum_avx2(_mm256_add_pd(s2, u2)), r3 = sc_lsq_hsum_avx2(_mm256_add_pd(s3, u3));
    for (; i < len; i++) {
        r0 = __builtin_fma(p0[i], x[i], r0);
        r1 = __builtin_fma(p1[i], x[i], r1);
        r2 = __builtin_fma(p2[i], x[i], r2);
        r3 = __builtin_fma(p3[i], x[i], r3);
    }
    out[0] = r0;
    out[1] = r1;
    out[2] = r2;
    out[3] = r3;
}

/* t[j] = Σ_q l[q]·rows[q][j], j < w (w a multiple of 4): 32 columns of t in eight registers
 * while all rows stream past (eight independent chains), then the rest four columns at a time
 * with the rows split over four chains. */
SC_LSQ_AVX2_ATTR static inline void sc_lsq_gemv_rows_avx2(double *restrict t, const double *l,
                                                           const double *const *rows, int cnt,
                                                           int w)
{
    int j = 0;
    for (; j + 32 <= w; j += 32) {
        __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd(),
                a3 = _mm256_setzero_pd(), a4 = _mm256_setzero_pd(), a5 = _mm256_setzero_pd(),
                a6 = _mm256_setzero_pd(), a7 = _mm256_setzero_pd();
        for (int q = 0; q < cnt; q++) {
            const double *r = rows[q] + j;
            __m256d lq = _mm256_broadcast_sd(l + q);
            a0 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r), a0);
            a1 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 4), a1);
            a2 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 8), a2);
            a3 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 12), a3);
            a4 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 16), a4);
            a5 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 20), a5);
            a6 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 24), a6);
            a7 = _mm256_fmadd_pd(lq, _mm256_loadu_pd(r + 28), a7);
        }
        _mm256_storeu_pd(t + j, a0);
        _mm256_storeu_pd(t + j + 4, a1);
        _mm256_storeu_pd(t + j + 8, a2);
        _mm256_storeu_pd(t + j + 12, a3);
        _mm256_storeu_pd(t + j + 16, a4);
        _mm256_storeu_pd(t + j + 20, a5);
        _mm256_storeu_pd(t + j + 24, a6);
        _mm256_storeu_pd(t + j + 28, a7);
    }
    for (; j < w; j += 4) {
        __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd(),
                a3 = _mm256_setzero_pd();
        int q = 0;
        for (; q + 4 <= cnt; q += 4) {
            a0 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q), _mm256_loadu_pd(rows[q] + j), a0);
            a1 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q + 1), _mm256_loadu_pd(rows[q + 1] + j),
                                 a1);
            a2 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q + 2), _mm256_loadu_pd(rows[q + 2] + j),
                                 a2);
            a3 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q + 3), _mm256_loadu_pd(rows[q + 3] + j),
                                 a3);
        }
        for (; q < cnt; q++)
            a0 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q), _mm256_loadu_pd(rows[q] + j), a0);
        _mm256_storeu_pd(t + j, _mm256_add_pd(_mm256_add_pd(a0, a1), _mm256_add_pd(a2, a3)));
    }
}
/* Two outputs sharing every load of the rows: 16 columns at a time (eight chains). */
SC_LSQ_AVX2_ATTR static inline void sc_lsq_gemv2_rows_avx2(double *restrict t, double *restrict u,
                                                            const double *l, const double *m,
                                                            const double *const *rows, int cnt,
                                                            int w)
{
    int j = 0;
    for (; j + 16 <= w; j += 16) {
        __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd(),
                a3 = _mm256_setzero_pd(), b0 = _mm256_setzero_pd(), b1 = _mm256_setzero_pd(),
                b2 = _mm256_setzero_pd(), b3 = _mm256_setzero_pd();
        for (int q = 0; q < cnt; q++) {
            const double *r = rows[q] + j;
            __m256d lq = _mm256_broadcast_sd(l + q), mq = _mm256_broadcast_sd(m + q);
            __m256d v0 = _mm256_loadu_pd(r), v1 = _mm256_loadu_pd(r + 4),
                    v2 = _mm256_loadu_pd(r + 8), v3 = _mm256_loadu_pd(r + 12);
            a0 = _mm256_fmadd_pd(lq, v0, a0);
            b0 = _mm256_fmadd_pd(mq, v0, b0);
            a1 = _mm256_fmadd_pd(lq, v1, a1);
            b1 = _mm256_fmadd_pd(mq, v1, b1);
            a2 = _mm256_fmadd_pd(lq, v2, a2);
            b2 = _mm256_fmadd_pd(mq, v2, b2);
            a3 = _mm256_fmadd_pd(lq, v3, a3);
            b3 = _mm256_fmadd_pd(mq, v3, b3);
        }
        _mm256_storeu_pd(t + j, a0);
        _mm256_storeu_pd(t + j + 4, a1);
        _mm256_storeu_pd(t + j + 8, a2);
        _mm256_storeu_pd(t + j + 12, a3);
        _mm256_storeu_pd(u + j, b0);
        _mm256_storeu_pd(u + j + 4, b1);
        _mm256_storeu_pd(u + j + 8, b2);
        _mm256_storeu_pd(u + j + 12, b3);
    }
    for (; j < w; j += 4) {
        __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), b0 = _mm256_setzero_pd(),
                b1 = _mm256_setzero_pd();
        int q = 0;
        for (; q + 2 <= cnt; q += 2) {
            __m256d v0 = _mm256_loadu_pd(rows[q] + j), v1 = _mm256_loadu_pd(rows[q + 1] + j);
            a0 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q), v0, a0);
            b0 = _mm256_fmadd_pd(_mm256_broadcast_sd(m + q), v0, b0);
            a1 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q + 1), v1, a1);
            b1 = _mm256_fmadd_pd(_mm256_broadcast_sd(m + q + 1), v1, b1);
        }
        if (q < cnt) {
            __m256d v0 = _mm256_loadu_pd(rows[q] + j);
            a0 = _mm256_fmadd_pd(_mm256_broadcast_sd(l + q), v0, a0);
            b0 = _mm256_fmadd_pd(_mm256_broadcast_sd(m + q), v0, b0);
        }
        _mm256_storeu_pd(t + j, _mm256_add_pd(a0, a1));
        _mm256_storeu_pd(u + j, _mm256_add_pd(b0, b1));
    }
}

/* sc_lsq_gemm4 with 4×12 register tiles: per q three loads of w and four broadcasts of l feed
 * twelve FMAs. */
SC_LSQ_AVX2_ATTR static inline void sc_lsq_gemm4_avx2(double *restrict t, int ldt, const double *l,
                                                       int ldl, const double *w, int ldw, int kdim,
                                                       int cols)
{
    const double *l0 = l, *l1 = l + ldl, *l2 = l + 2 * (size_t)ldl, *l3 = l + 3 * (size_t)ldl;
    int j = 0;
    for (; j + 12 <= cols; j += 12) {
        __m256d a00 = _mm256_setzero_pd(), a01 = _mm256_setzero_pd(), a02 = _mm256_setzero_pd();
        __m256d a10 = _mm256_setzero_pd(), a11 = _mm256_setzero_pd(), a12 = _mm256_setzero_pd();
        __m256d a20 = _mm256_setzero_pd(), a21 = _mm256_setzero_pd(), a22 = _mm256_setzero_pd();
        __m256d a30 = _mm256_setzero_pd(), a31 = _mm256_setzero_pd(), a32 = _mm256_setzero_pd();
        const double *wq = w + j;
        for (int q = 0; q < kdim; q++, wq += ldw) {
            __m256d w0 = _mm256_loadu_pd(wq), w1 = _mm256_loadu_pd(wq + 4),
                    w2 = _mm256_loadu_pd(wq + 8);
            __m256d b = _mm256_broadcast_sd(l0 + q);
            a00 = _mm256_fmadd_pd(b, w0, a00);
            a01 = _mm256_fmadd_pd(b, w1, a01);
            a02 = _mm256_fmadd_pd(b, w2, a02);
            b = _mm256_broadcast_sd(l1 + q);
            a10 = _mm256_fmadd_pd(b, w0, a10);
            a11 = _mm256_fmadd_pd(b, w1, a11);
            a12 = _mm256_fmadd_pd(b, w2, a12);
            b = _mm256_broadcast_sd(l2 + q);
            a20 = _mm256_fmadd_pd(b, w0, a20);
            a21 = _mm256_fmadd_pd(b, w1, a21);
            a22 = _mm256_fmadd_pd(b, w2, a22);
            b = _mm256_broadcast_sd(l3 + q);
            a30 = _mm256_fmadd_pd(b, w0, a30);
            a31 = _mm256_fmadd_pd(b, w1, a31);
            a32 = _mm256_fmadd_pd(b, w2, a32);
        }
        double *t0 = t + j, *t1 = t0 + ldt, *t2 = t1 + ldt, *t3 = t2 + ldt;
        _mm256_storeu_pd(t0, a00);
        _mm256_storeu_pd(t0 + 4, a01);
        _mm256_storeu_pd(t0 + 8, a02);
        _mm256_storeu_pd(t1, a10);
        _mm256_storeu_pd(t1 + 4, a11);
        _mm256_storeu_pd(t1 + 8, a12);
        _mm256_storeu_pd(t2, a20);
        _mm256_storeu_pd(t2 + 4, a21);
        _mm256_storeu_pd(t2 + 8, a22);
        _mm256_storeu_pd(t3, a30);
        _mm256_storeu_pd(t3 + 4, a31);
        _mm256_storeu_pd(t3 + 8, a32);
    }
    for (; j < cols; j += 4) {
        __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd(),
                a3 = _mm256_setzero_pd();
        const double *wq = w + j;
        for (int q = 0; q < kdim; q++, wq += ldw) {
            __m256d w0 = _mm256_loadu_pd(wq);
            a0 = _mm256_fmadd_pd(_mm256_broadcast_sd(l0 + q), w0, a0);
            a1 = _mm256_fmadd_pd(_mm256_broadcast_sd(l1 + q), w0, a1);
            a2 = _mm256_fmadd_pd(_mm256_broadcast_sd(l2 + q), w0, a2);
            a3 = _mm256_fmadd_pd(_mm256_broadcast_sd(l3 + q), w0, a3);
        }
        _mm256_storeu_pd(t + j, a0);
        _mm256_storeu_pd(t + ldt + j, a1);
        _mm256_storeu_pd(t + 2 * (size_t)ldt + j, a2);
        _mm256_storeu_pd(t + 3 * (size_t)ldt + j, a3);
    }
}

/* sc_lsq_syrk8x4 in 4×8 register tiles (eight accumulators; per c two loads and four broadcasts
 * feed eight FMAs) over the columns all four rows have, then one masked 4×8 tile for the rest
 * and the 4×4 diagonal block (lanes past a row's diagonal neither loaded nor stored). */
SC_LSQ_AVX2_ATTR static inline void sc_lsq_syrk8x4_avx2(double *y0, ptrdiff_t ys, const double *v,
                                                         int h, int qrow, int cm)
{
    double *y1 = y0 + ys, *y2 = y1 + ys, *y3 = y2 + ys;
    const double *vr = v + qrow;
    int t = 0;
    for (; t + 8 <= cm; t += 8) {
        __m256d a00 = _mm256_loadu_pd(y0 + t), a01 = _mm256_loadu_pd(y0 + t + 4);
        __m256d a10 = _mm256_loadu_pd(y1 + t), a11 = _mm256_loadu_pd(y1 + t + 4);
        __m256d a20 = _mm256_loadu_pd(y2 + t), a21 = _mm256_loadu_pd(y2 + t + 4);
        __m256d a30 = _mm256_loadu_pd(y3 + t), a31 = _mm256_loadu_pd(y3 + t + 4);
        for (int c = 0; c < 8; c++) {
            const double *pr = vr + (size_t)c * h, *pq = v + (size_t)c * h + t;
            __m256d w0 = _mm256_loadu_pd(pq), w1 = _mm256_loadu_pd(pq + 4);
            __m256d bb = _mm256_broadcast_sd(pr);
            a00 = _mm256_fnmadd_pd(bb, w0, a00);
            a01 = _mm256_fnmadd_pd(bb, w1, a01);
            bb = _mm256_broadcast_sd(pr + 1);
            a10 = _mm256_fnmadd_pd(bb, w0, a10);
            a11 = _mm256_fnmadd_pd(bb, w1, a11);
            bb = _mm256_broadcast_sd(pr + 2);
            a20 = _mm256_fnmadd_pd(bb, w0, a20);
            a21 = _mm256_fnmadd_pd(bb, w1, a21);
            bb = _mm256_broadcast_sd(pr + 3);
            a30 = _mm256_fnmadd_pd(bb, w0, a30);
            a31 = _mm256_fnmadd_pd(bb, w1, a31);
        }
        _mm256_storeu_pd(y0 + t, a00);
        _mm256_storeu_pd(y0 + t + 4, a01);
        _mm256_storeu_pd(y1 + t, a10);
        _mm256_storeu_pd(y1 + t + 4, a11);
        _mm256_storeu_pd(y2 + t, a20);
        _mm256_storeu_pd(y2 + t + 4, a21);
        _mm256_storeu_pd(y3 + t, a30);
        _mm256_storeu_pd(y3 + t + 4, a31);
    }
    /* the rest: columns t .. cm + r of row r (at most 3 + 4 of them: one masked 4×8 tile) */
    const __m256i lane0 = _mm256_set_epi64x(t + 3, t + 2, t + 1, t);
    const __m256i lane1 = _mm256_set_epi64x(t + 7, t + 6, t + 5, t + 4);
    __m256i m00 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 1), lane0);
    __m256i m01 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 1), lane1);
    __m256i m10 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 2), lane0);
    __m256i m11 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 2), lane1);
    __m256i m20 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 3), lane0);
    __m256i m21 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 3), lane1);
    __m256i m30 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 4), lane0);
    __m256i m31 = _mm256_cmpgt_epi64(_mm256_set1_epi64x(cm + 4), lane1);
    __m256d a00 = _mm256_maskload_pd(y0 + t, m00), a01 = _mm256_maskload_pd(y0 + t + 4, m01);
    __m256d a10 = _mm256_maskload_pd(y1 + t, m10), a11 = _mm256_maskload_pd(y1 + t + 4, m11);
    __m256d a20 = _mm256_maskload_pd(y2 + t, m20), a21 = _mm256_maskload_pd(y2 + t + 4, m21);
    __m256d a30 = _mm256_maskload_pd(y3 + t, m30), a31 = _mm256_maskload_pd(y3 + t + 4, m31);
    for (int c = 0; c < 8; c++) {
        const double *pr = vr + (size_t)c * h, *pq = v + (size_t)c * h + t;
        __m256d w0 = _mm256_maskload_pd(pq, m30), w1 = _mm256_maskload_pd(pq + 4, m31);
        __m256d bb = _mm256_broadcast_sd(pr);
        a00 = _mm256_fnmadd_pd(bb, w0, a00);
        a01 = _mm256_fnmadd_pd(bb, w1, a01);
        bb = _mm256_broadcast_sd(pr + 1);
        a10 = _mm256_fnmadd_pd(bb, w0, a10);
        a11 = _mm256_fnmadd_pd(bb, w1, a11);
        bb = _mm256_broadcast_sd(pr + 2);
        a20 = _mm256_fnmadd_pd(bb, w0, a20);
        a21 = _mm256_fnmadd_pd(bb, w1, a21);
        bb = _mm256_broadcast_sd(pr + 3);
        a30 = _mm256_fnmadd_pd(bb, w0, a30);
        a31 = _mm256_fnmadd_pd(bb, w1, a31);
    }
    _mm256_maskstore_pd(y0 + t, m00, a00);
    _mm256_maskstore_pd(y0 + t + 4, m01, a01);
    _mm256_maskstore_pd(y1 + t, m10, a10);
    _mm256_maskstore_pd(y1 + t + 4, m11, a11);
    _mm256_maskstore_pd(y2 + t, m20, a20);
    _mm256_maskstore_pd(y2 + t + 4, m21, a21);
    _mm256_maskstore_pd(y3 + t, m30, a30);
    _mm256_maskstore_pd(y3 + t + 4, m31, a31);
}
#else
#define SC_LSQ_HAVE_AVX2 0
#endif

#endif
