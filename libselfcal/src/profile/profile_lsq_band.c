/* profile_lsq_band.c — the banded kernels of the profile least squares (see profile_lsq_band.h):
 * one portable copy, and on x86-64 a copy with AVX2/FMA inner loops chosen at run time. */
#include "profile_lsq_band.h"

#include <math.h>
#include <string.h>

#include "profile_lsq_kernels.h"

#define SC_SFX(name) name##_generic
#define SC_ATTR
#define SC_DOT sc_lsq_dot
#define SC_AXPY sc_lsq_axpy
#define SC_AXPY4 sc_lsq_axpy4
#define SC_DOT4 sc_lsq_dot4
#define SC_GEMV_ROWS sc_lsq_gemv_rows
#define SC_GEMV2_ROWS sc_lsq_gemv2_rows
#define SC_GEMM4 sc_lsq_gemm4
#define SC_SYRK8X4 sc_lsq_syrk8x4
#include "profile_lsq_band_impl.h"
#undef SC_SFX
#undef SC_ATTR
#undef SC_DOT
#undef SC_AXPY
#undef SC_AXPY4
#undef SC_DOT4
#undef SC_GEMV_ROWS
#undef SC_GEMV2_ROWS
#undef SC_GEMM4
#undef SC_SYRK8X4

#if SC_LSQ_HAVE_AVX2
#define SC_SFX(name) name##_avx2
#define SC_ATTR SC_LSQ_AVX2_ATTR
#define SC_DOT sc_lsq_dot_avx2
#define SC_AXPY sc_lsq_axpy_avx2
#define SC_AXPY4 sc_lsq_axpy4_avx2
#define SC_DOT4 sc_lsq_dot4_avx2
#define SC_GEMV_ROWS sc_lsq_gemv_rows_avx2
#define SC_GEMV2_ROWS sc_lsq_gemv2_rows_avx2
#define SC_GEMM4 sc_lsq_gemm4_avx2
#define SC_SYRK8X4 sc_lsq_syrk8x4_avx2
#include "profile_lsq_band_impl.h"
#endif

int sc_lsq_band_cpu_has_simd(void)
{
#if SC_LSQ_HAVE_AVX2
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
    return 0;
#endif
}

int sc_lsq_band_factor(sc_lsq_band *b, double *col)
{
#if SC_LSQ_HAVE_AVX2
    if (b->simd) return factor_avx2(b, col);
#endif
    return factor_generic(b, col);
}

void sc_lsq_band_solve(const sc_lsq_band *b, double *const *xs, int nrhs)
{
#if SC_LSQ_HAVE_AVX2
    if (b->simd) {
        solve_avx2(b, xs, nrhs);
        return;
    }
#endif
    solve_generic(b, xs, nrhs);
}

void sc_lsq_band_forward(const sc_lsq_band *b, double *const *xs, int nrhs)
{
#if SC_LSQ_HAVE_AVX2
    if (b->simd) {
        forward_avx2(b, xs, nrhs);
        return;
    }
#endif
    forward_generic(b, xs, nrhs);
}

void sc_lsq_band_backward(const sc_lsq_band *b, double *const *xs, int nrhs)
{
#if SC_LSQ_HAVE_AVX2
    if (b->simd) {
        backward_avx2(b, xs, nrhs);
        return;
    }
#endif
    backward_generic(b, xs, nrhs);
}

void sc_lsq_band_inverse_diag_from(const sc_lsq_band *b, double *win, double *diag, int i0,
                                   const double *zss, int s)
{
#if SC_LSQ_HAVE_AVX2
    if (b->simd) {
        inverse_diag_avx2(b, win, diag, i0, zss, s);
        return;
    }
#endif
    inverse_diag_generic(b, win, diag, i0, zss, s);
}

void sc_lsq_band_inverse_diag(const sc_lsq_band *b, double *win, double *diag)
{
    static const double none = 0.0;
    sc_lsq_band_inverse_diag_from(b, win, diag, b->n - 1, &none, 0);
}

size_t sc_lsq_band_inverse_scratch(int bw)
{
    size_t w = (size_t)bw + 1, ws = (w + 3) & ~(size_t)3;
    size_t circ = ws * w + 2 * ws + 3 * w; /* window, t, u, l, m, row pointers */
    size_t bwp = ((size_t)bw + 3) & ~(size_t)3, r = bwp + 64;
    size_t blocked = r * r + 8 * bwp; /* sliding window, Lc, T */
    return circ > blocked ? circ : blocked;
}
