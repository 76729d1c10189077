/* Unit tests of the correction core (selfcal/correct.h).
 *
 * Table images are written here by an independent writer that follows docs/lut-format.md (not the
 * library's encoder), with its own CRC-32; expected corrections come from an independent bilinear /
 * linear interpolation (cell found by search, textbook weights) on the exact decoded values.
 *
 * The same file runs on the host under cmocka and on an emulated Cortex-M4 (tests/cortex-m, with
 * SC_BAREMETAL defined and mini_cmocka.h), so it uses no libm and little stack.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#ifdef SC_BAREMETAL
#include "mini_cmocka.h"
#else
#include <setjmp.h>
#include <stdarg.h>
#include <cmocka.h>
#endif

#include "selfcal/correct.h"

/* ---- helpers without libm ---- */

static double dabs(double x)
{
    return x < 0 ? -x : x;
}

#define assert_close(a, b, tol)                                                                 \
    do {                                                                                        \
        double a_ = (a), b_ = (b);                                                              \
        if (!(dabs(a_ - b_) <= (tol))) {                                                        \
            print_error("%s:%d: %s = %.17g but %s = %.17g (tolerance %g)\n", __FILE__, __LINE__, \
                        #a, a_, #b, b_, (double)(tol));                                         \
            fail();                                                                             \
        }                                                                                       \
    } while (0)

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rnd_u32(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (uint32_t)(rng_state >> 33);
}

/* Uniform in [lo, hi). */
static double rnd_uniform(double lo, double hi)
{
    return lo + (hi - lo) * ((double)rnd_u32() / 2147483648.0);
}

/* ---- an independent table writer (docs/lut-format.md) ---- */

#define T_MAXN (2 * (SC_CORR_MAX_NX + 1) > 400 ? 2 * (SC_CORR_MAX_NX + 1) : 400)
#define T_MAXP (SC_CORR_MAX_PROFILE_POINTS + 1)
#define T_NPROF 9

typedef struct tprofile {
    int axis, dir, enc, n;
    double start, step;
    uint32_t scale_pm;
    int32_t code[T_MAXP];
} tprofile;

typedef struct tspec {
    int nx, ny, genc, np, nsrc;
    double x0, y0, px, py, sigma;
    uint32_t gscale_pm;
    int32_t gx[T_MAXN], gy[T_MAXN];
    tprofile p[T_NPROF];
} tspec;

static tspec S;
static uint8_t img[16384];
static sc_corr_table T;

static uint32_t ref_crc32(const uint8_t *p, size_t n)
{
    uint32_t c = 0xFFFFFFFFu;
    for (size_t k = 0; k < n; ++k) {
        c ^= p[k];
        for (int b = 0; b < 8; ++b)
            c = (c & 1u) ? (c >> 1) ^ 0xEDB88320u : c >> 1;
    }
    return ~c;
}

static uint8_t *w16(uint8_t *w, uint32_t v)
{
    w[0] = (uint8_t)v;
    w[1] = (uint8_t)(v >> 8);
    return w + 2;
}

static uint8_t *w32(uint8_t *w, uint32_t v)
{
    return w16(w16(w, v & 0xFFFFu), v >> 16);
}

static uint8_t *wf64(uint8_t *w, double d)
{
    uint64_t u;
    memcpy(&u, &d, 8);
    return w32(w32(w, (uint32_t)u), (uint32_t)(u >> 32));
}

static uint8_t *wcode(uint8_t *w, int enc, int32_t c)
{
    return enc == 1 ? w16(w, (uint32_t)(uint16_t)(int16_t)c) : w32(w, (uint32_t)c);
}

static size_t code_bytes(int enc)
{
    return enc == 1 ? 2 : 4;
}

/* Write S as a table image into img; returns its length. */
static size_t write_image(void)
{
    uint8_t *w = img;
    static const uint8_t magic[8] = {'S', 'C', 'L', 'U', 'T', 0x0D, 0x0A, 0x1A};
    memcpy(w, magic, 8);
    size_t len = 64 + 2 * (size_t)S.nx * S.ny * code_bytes(S.genc);
    for (int k = 0; k < S.np; ++k)
        len += 28 + (size_t)S.p[k].n * code_bytes(S.p[k].enc);
    len += 56 + 32 * (size_t)S.nsrc + 4;
    assert_true(len <= sizeof img);
    w16(w + 8, 1);
    w16(w + 10, 64);
    w32(w + 12, (uint32_t)len);
    w16(w + 16, (uint32_t)S.nx);
    w16(w + 18, (uint32_t)S.ny);
    w[20] = (uint8_t)S.np;
    w[21] = (uint8_t)S.genc;
    w16(w + 22, 0);
    wf64(w + 24, S.x0);
    wf64(w + 32, S.y0);
    wf64(w + 40, S.px);
    wf64(w + 48, S.py);
    w32(w + 56, S.gscale_pm);
    w32(w + 60, 56 + 32 * (uint32_t)S.nsrc);
    w += 64;
    for (int k = 0; k < S.nx * S.ny; ++k)
        w = wcode(w, S.genc, S.gx[k]);
    for (int k = 0; k < S.nx * S.ny; ++k)
        w = wcode(w, S.genc, S.gy[k]);
    for (int k = 0; k < S.np; ++k) {
        const tprofile *p = &S.p[k];
        w[0] = (uint8_t)p->axis;
        w[1] = (uint8_t)p->dir;
        w[2] = (uint8_t)p->enc;
        w[3] = 0;
        w16(w + 4, (uint32_t)p->n);
        w16(w + 6, 0);
        wf64(w + 8, p->start);
        wf64(w + 16, p->step);
        w32(w + 24, p->scale_pm);
        w += 28;
        for (int m = 0; m < p->n; ++m)
            w = wcode(w, p->enc, p->code[m]);
    }
    memset(w, 0, 56 + 32 * (size_t)S.nsrc);
    memcpy(w, "test", 4);
    wf64(w + 32, 1.7e9); /* created: any 64-bit pattern is valid */
    wf64(w + 40, S.sigma);
    w[48] = (uint8_t)S.nsrc;
    w += 56;
    for (int k = 0; k < S.nsrc * 32; ++k)
        *w++ = (uint8_t)(k * 7 + 1);
    w32(w, ref_crc32(img, (size_t)(w - img)));
    w += 4;
    assert_int_equal((size_t)(w - img), len);
    return len;
}

/* Recompute the CRC after a raw edit of img. */
static void fix_crc(size_t len)
{
    w32(img + len - 4, ref_crc32(img, len - 4));
}

/* A grid of nx x ny with random codes within +-amp codes, one int16 scale. */
static void make_grid(int nx, int ny, int enc, uint32_t scale_pm, int32_t amp)
{
    memset(&S, 0, sizeof S);
    S.nx = nx;
    S.ny = ny;
    S.genc = enc;
    S.gscale_pm = scale_pm;
    S.x0 = -12.5;
    S.y0 = 3.25;
    S.px = 1.75;
    S.py = 2.5;
    S.sigma = -1.0;
    S.nsrc = 1;
    for (int k = 0; k < nx * ny; ++k) {
        S.gx[k] = (int32_t)(rnd_u32() % (uint32_t)(2 * amp + 1)) - amp;
        S.gy[k] = (int32_t)(rnd_u32() % (uint32_t)(2 * amp + 1)) - amp;
    }
}

static void add_profile(int axis, int dir, int n, double start, double step, uint32_t scale_pm,
                        int32_t amp)
{
    tprofile *p = &S.p[S.np++];
    p->axis = axis;
    p->dir = dir;
    p->enc = 1;
    p->n = n;
    p->start = start;
    p->step = step;
    p->scale_pm = scale_pm;
    for (int m = 0; m < n; ++m)
        p->code[m] = (int32_t)(rnd_u32() % (uint32_t)(2 * amp + 1)) - amp;
    S.nsrc = 1 + S.np;
}

static void load_ok(void)
{
    size_t len = write_image();
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_OK);
    assert_int_equal(T.loaded, 1);
}

/* ---- independent reference evaluation (exact decoded values, double) ---- */

static double clampd(double v, double lo, double hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

/* Cell by search: the largest k <= n-2 with start + k*step <= s. */
static int find_cell(double s, double start, double step, int n, double *t)
{
    int k = 0;
    while (k < n - 2 && start + (k + 1) * step <= s)
        ++k;
    *t = (s - (start + k * step)) / step;
    return k;
}

static double node_um(int32_t code, uint32_t scale_pm)
{
    return (double)code * (double)scale_pm * 1e-6;
}

static void ref_grid(double x, double y, double g[2])
{
    x = clampd(x, S.x0, S.x0 + (S.nx - 1) * S.px);
    y = clampd(y, S.y0, S.y0 + (S.ny - 1) * S.py);
    double tx, ty;
    int j = find_cell(x, S.x0, S.px, S.nx, &tx), i = find_cell(y, S.y0, S.py, S.ny, &ty);
    for (int c = 0; c < 2; ++c) {
        const int32_t *a = c == 0 ? S.gx : S.gy;
        int k = i * S.nx + j;
        g[c] = (1 - tx) * (1 - ty) * node_um(a[k], S.gscale_pm) +
               tx * (1 - ty) * node_um(a[k + 1], S.gscale_pm) +
               (1 - tx) * ty * node_um(a[k + S.nx], S.gscale_pm) +
               tx * ty * node_um(a[k + S.nx + 1], S.gscale_pm);
    }
}

/* Total correction (um) per coordinate: grid plus profile offsets. */
static void ref_total(const double in[3], double c[3])
{
    double g[2];
    ref_grid(in[0], in[1], g);
    c[0] = g[0];
    c[1] = g[1];
    c[2] = 0.0;
    for (int k = 0; k < S.np; ++k) {
        const tprofile *p = &S.p[k];
        double s = clampd(in[p->axis], p->start, p->start + (p->n - 1) * p->step), t;
        int m = find_cell(s, p->start, p->step, p->n, &t);
        c[p->dir] += (1 - t) * node_um(p->code[m], p->scale_pm) + t * node_um(p->code[m + 1], p->scale_pm);
    }
}

static int ref_outside(double x, double y)
{
    const double tx = SC_CORR_EDGE_TOL * S.px, ty = SC_CORR_EDGE_TOL * S.py;
    return x < S.x0 - tx || x > S.x0 + (S.nx - 1) * S.px + tx || y < S.y0 - ty ||
           y > S.y0 + (S.ny - 1) * S.py + ty;
}

/* Largest |value| (um) in the current table. */
static double max_abs_um(void)
{
    double m = 0;
    for (int k = 0; k < S.nx * S.ny; ++k) {
        double a = dabs(node_um(S.gx[k], S.gscale_pm)), b = dabs(node_um(S.gy[k], S.gscale_pm));
        m = a > m ? a : m;
        m = b > m ? b : m;
    }
    for (int p = 0; p < S.np; ++p)
        for (int k = 0; k < S.p[p].n; ++k) {
            double a = dabs(node_um(S.p[p].code[k], S.p[p].scale_pm));
            m = a > m ? a : m;
        }
    return m;
}

/* The core stores node values as floats (24-bit mantissa): allow a few float ulps of the largest
 * value (6 pm at 50 um; 0.4 pm at 3 um) plus double rounding of the positions. */
#define TOL_MM (1e-13 + 4.0 * 1e-3 * max_abs_um() * 1.2e-7)

static void check_point(double x, double y, double z)
{
    double in[3] = {x, y, z}, out[3], c[3];
    ref_total(in, c);
    unsigned want = SC_CORR_ST_LOADED | (ref_outside(x, y) ? SC_CORR_ST_OUTSIDE : 0u);
    assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, in, out), want);
    for (int d = 0; d < 3; ++d)
        assert_close(out[d], in[d] - 1e-3 * c[d], TOL_MM);
    assert_int_equal(sc_corr_apply(&T, SC_CORR_POSITION, in, out), want);
    for (int d = 0; d < 3; ++d)
        assert_close(out[d], in[d] + 1e-3 * c[d], TOL_MM);
}

/* ---- tests ---- */

static void test_crc32(void **state)
{
    (void)state;
    assert_true(sc_corr_crc32("123456789", 9) == 0xCBF43926u);
    assert_true(sc_corr_crc32("", 0) == 0u);
    uint8_t buf[300];
    for (size_t k = 0; k < sizeof buf; ++k)
        buf[k] = (uint8_t)rnd_u32();
    for (size_t n = 0; n <= sizeof buf; n += 37)
        assert_true(sc_corr_crc32(buf, n) == ref_crc32(buf, n));
}

static void test_nodes_exact(void **state)
{
    (void)state;
    make_grid(7, 5, 1, 100, 30000); /* +-3 um in 0.1 nm codes; rectangular, unequal pitches */
    load_ok();
    for (int i = 0; i < S.ny; ++i)
        for (int j = 0; j < S.nx; ++j) {
            double in[3] = {S.x0 + j * S.px, S.y0 + i * S.py, 0.5}, out[3];
            double gx = node_um(S.gx[i * S.nx + j], S.gscale_pm);
            double gy = node_um(S.gy[i * S.nx + j], S.gscale_pm);
            assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, in, out), SC_CORR_ST_LOADED);
            assert_close(out[0], in[0] - 1e-3 * gx, TOL_MM);
            assert_close(out[1], in[1] - 1e-3 * gy, TOL_MM);
            assert_true(out[2] == in[2]);
            assert_int_equal(sc_corr_apply(&T, SC_CORR_POSITION, in, out), SC_CORR_ST_LOADED);
            assert_close(out[0], in[0] + 1e-3 * gx, TOL_MM);
            assert_close(out[1], in[1] + 1e-3 * gy, TOL_MM);
        }
}

static void test_between_nodes_bilinear(void **state)
{
    (void)state;
    make_grid(6, 9, 1, 200, 32000);
    load_ok();
    double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    for (int k = 0; k < 1500; ++k)
        check_point(rnd_uniform(S.x0, x1), rnd_uniform(S.y0, y1), rnd_uniform(-5, 5));
    /* int32 codes too. */
    make_grid(4, 3, 2, 1, 50000000); /* +-50 um in 1 pm codes */
    load_ok();
    x1 = S.x0 + (S.nx - 1) * S.px;
    y1 = S.y0 + (S.ny - 1) * S.py;
    for (int k = 0; k < 500; ++k)
        check_point(rnd_uniform(S.x0, x1), rnd_uniform(S.y0, y1), 0.0);
}

static void test_continuity_across_edges(void **state)
{
    (void)state;
    make_grid(5, 4, 1, 100, 30000);
    load_ok();
    const double d = 1e-9; /* mm: slopes here are < 5e-3, so the sides agree to ~1e-11 mm */
    for (int k = 0; k < 200; ++k) {
        double y = rnd_uniform(S.y0, S.y0 + (S.ny - 1) * S.py);
        int j = 1 + (int)(rnd_u32() % (uint32_t)(S.nx - 2));
        double x = S.x0 + j * S.px;
        double a[3] = {x - d, y, 0}, b[3] = {x + d, y, 0}, m[3] = {x, y, 0}, oa[3], ob[3], om[3];
        sc_corr_apply(&T, SC_CORR_MEASURE, a, oa);
        sc_corr_apply(&T, SC_CORR_MEASURE, b, ob);
        sc_corr_apply(&T, SC_CORR_MEASURE, m, om);
        assert_close((oa[0] - a[0]) - (ob[0] - b[0]), 0.0, 2e-11);
        assert_close((oa[1] - a[1]) - (ob[1] - b[1]), 0.0, 2e-11);
        assert_close((om[0] - m[0]) - (ob[0] - b[0]), 0.0, 2e-11);
        check_point(x, y, 0);

        double x2 = rnd_uniform(S.x0, S.x0 + (S.nx - 1) * S.px);
        int i = 1 + (int)(rnd_u32() % (uint32_t)(S.ny - 2));
        double y2 = S.y0 + i * S.py;
        double c[3] = {x2, y2 - d, 0}, e[3] = {x2, y2 + d, 0}, oc[3], oe[3];
        sc_corr_apply(&T, SC_CORR_MEASURE, c, oc);
        sc_corr_apply(&T, SC_CORR_MEASURE, e, oe);
        assert_close((oc[0] - c[0]) - (oe[0] - e[0]), 0.0, 2e-11);
        assert_close((oc[1] - c[1]) - (oe[1] - e[1]), 0.0, 2e-11);
        check_point(x2, y2, 0);
    }
}

static void test_clamping_and_status(void **state)
{
    (void)state;
    make_grid(5, 6, 1, 100, 30000);
    load_ok();
    const double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    const double xs[] = {S.x0 - 1e300, S.x0 - 100, S.x0 - 1e-6, S.x0, 0.5 * (S.x0 + x1), x1, x1 + 1e-6, x1 + 7, 1e300};
    const double ys[] = {-1e300, S.y0 - 3, S.y0 - 1e-6, S.y0, 0.5 * (S.y0 + y1) + 0.1, y1, y1 + 1e-6, y1 + 50, 1e300};
    for (size_t a = 0; a < sizeof xs / sizeof xs[0]; ++a)
        for (size_t b = 0; b < sizeof ys / sizeof ys[0]; ++b) {
            double in[3] = {xs[a], ys[b], 0}, out[3], g[2];
            unsigned st = sc_corr_apply(&T, SC_CORR_MEASURE, in, out);
            int outside = ref_outside(xs[a], ys[b]);
            assert_int_equal(st, SC_CORR_ST_LOADED | (outside ? SC_CORR_ST_OUTSIDE : 0u));
            /* The correction is the one at the nearest edge point. */
            ref_grid(xs[a], ys[b], g);
            /* Astronomically far coordinates: the correction is below their resolution; the
             * output must still be finite and equal to the input to rounding. */
            for (int d = 0; d < 2; ++d) {
                if (dabs(in[d]) < 1e6)
                    assert_close(out[d], in[d] - 1e-3 * g[d], TOL_MM);
                else
                    assert_close(out[d], in[d], dabs(in[d]) * 1e-15);
            }
        }
    /* The exact corner node far outside: the clamped correction equals the corner's value. */
    double in[3] = {x1 + 1000, S.y0 - 1000, 0}, out[3];
    assert_int_equal(sc_corr_apply(&T, SC_CORR_POSITION, in, out),
                     SC_CORR_ST_LOADED | SC_CORR_ST_OUTSIDE);
    assert_close(out[0] - in[0], 1e-3 * node_um(S.gx[S.nx - 1], S.gscale_pm), TOL_MM);
    assert_close(out[1] - in[1], 1e-3 * node_um(S.gy[S.nx - 1], S.gscale_pm), TOL_MM);
}

/* A table whose origin and pitch come from a least-squares fit of 12.7 mm nodes (lut build:
 * x0 = -38.099999999999994, pitch 12.699999999999998, so x0 + 14 pitches is 4e-14 short of
 * 139.7): every node, the edge ones too, however its position rounds from nanometres, is inside;
 * a nanometre beyond the edge is outside. */
static void test_edge_nodes_inside(void **state)
{
    (void)state;
    make_grid(15, 15, 1, 100, 30000);
    S.x0 = S.y0 = -38.099999999999994;
    S.px = S.py = 12.699999999999998;
    load_ok();
    for (int i = 0; i < 15; ++i)
        for (int j = 0; j < 15; ++j) {
            long x_nm = -38100000L + 12700000L * j, y_nm = -38100000L + 12700000L * i;
            const double xs[2] = {x_nm * 1e-6, x_nm / 1e6}, ys[2] = {y_nm * 1e-6, y_nm / 1e6};
            for (int r = 0; r < 2; ++r) {
                double in[3] = {xs[r], ys[r], 0}, out[3];
                assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, in, out), SC_CORR_ST_LOADED);
                assert_close(out[0], in[0] - 1e-3 * node_um(S.gx[i * 15 + j], S.gscale_pm), TOL_MM);
                assert_close(out[1], in[1] - 1e-3 * node_um(S.gy[i * 15 + j], S.gscale_pm), TOL_MM);
            }
        }
    const double beyond[4][2] = {{-38.100001, 0}, {139.700001, 0}, {0, -38.100001}, {0, 139.700001}};
    for (int k = 0; k < 4; ++k) {
        double in[3] = {beyond[k][0], beyond[k][1], 0}, out[3];
        assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, in, out),
                         SC_CORR_ST_LOADED | SC_CORR_ST_OUTSIDE);
    }
}

static void test_profiles(void **state)
{
    (void)state;
    make_grid(5, 5, 1, 100, 20000);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, 9, -11.0, 0.75, 50, 30000);  /* ey along x */
    add_profile(SC_CORR_AXIS_Y, SC_CORR_AXIS_Z, 5, 4.0, 2.0, 100, 30000);    /* ez along y */
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_X, 4, -12.5, 2.0, 10, 30000);   /* ex along x */
    add_profile(SC_CORR_AXIS_Z, SC_CORR_AXIS_X, 3, -1.0, 1.0, 100, 30000);   /* ex along z */
    load_ok();
    assert_int_equal(T.n_profiles, 4);
    double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    for (int k = 0; k < 1500; ++k) /* inside and outside the profiles' ranges */
        check_point(rnd_uniform(S.x0, x1), rnd_uniform(S.y0, y1), rnd_uniform(-3, 3));
    /* Exactly at a profile point the offset is that point's value. */
    const tprofile *p = &S.p[0];
    for (int m = 0; m < p->n; ++m) {
        double x = p->start + m * p->step;
        if (x < S.x0 || x > x1)
            continue;
        check_point(x, S.y0 + S.py, 0);
    }
    /* Outside a profile's range (inside the grid): clamped, and no out-of-grid bit. */
    double in[3] = {x1 - 0.01, S.y0 + 0.3, 100.0}, out[3], c[3];
    ref_total(in, c);
    assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, in, out), SC_CORR_ST_LOADED);
    assert_close(out[2], 100.0 - 1e-3 * c[2], TOL_MM);
    assert_close(out[0], in[0] - 1e-3 * c[0], TOL_MM);
}

/* Every profile count from 1 to the build's maximum (odd counts included: the host code takes
 * profiles in pairs and pads an odd count), random AXIS and DIR, ranges partly outside the grid;
 * tables with fewer profiles loaded over ones with more (no stale profile may survive); and
 * apply in place (out == in) gives the same as into another array. */
static void test_profile_counts_axes_and_reload(void **state)
{
    (void)state;
    const int maxp = SC_CORR_MAX_PROFILES < T_NPROF - 1 ? SC_CORR_MAX_PROFILES : T_NPROF - 1;
    for (int round = 0; round < 2; ++round)
        for (int np = round == 0 ? 1 : maxp; round == 0 ? np <= maxp : np >= 1;
             np += round == 0 ? 1 : -1) {
            make_grid(6, 5, 1, 100, 30000);
            for (int k = 0; k < np; ++k) {
                const int n = 2 + (int)(rnd_u32() % 40u);
                add_profile((int)(rnd_u32() % 3u), (int)(rnd_u32() % 3u), n,
                            rnd_uniform(-20.0, 5.0), rnd_uniform(0.1, 1.5), 50, 30000);
            }
            load_ok();
            assert_int_equal(T.n_profiles, np);
            const double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
            for (int k = 0; k < 300; ++k) {
                const double x = rnd_uniform(S.x0 - 3.0, x1 + 3.0);
                const double y = rnd_uniform(S.y0 - 3.0, y1 + 3.0);
                const double z = rnd_uniform(-25.0, 25.0);
                check_point(x, y, z);
                double a[3] = {x, y, z}, b[3];
                const unsigned st = sc_corr_apply(&T, SC_CORR_MEASURE, a, b);
                assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, a, a), st);
                assert_true(memcmp(a, b, sizeof a) == 0);
            }
            /* Exactly at each profile's first and last point. */
            for (int k = 0; k < np; ++k) {
                const tprofile *p = &S.p[k];
                for (int e = 0; e < 2; ++e) {
                    double in[3] = {0.5 * (S.x0 + x1), 0.5 * (S.y0 + y1), 0.0};
                    in[p->axis] = p->start + (e ? p->n - 1 : 0) * p->step;
                    check_point(in[0], in[1], in[2]);
                }
            }
        }
}

static double make_nan(void)
{
    volatile double z = 0.0;
    return z / z;
}

static double make_inf(void)
{
    volatile double big = 1e308;
    return big * 10.0;
}

static void test_invalid_input(void **state)
{
    (void)state;
    make_grid(4, 4, 1, 100, 30000);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Z, 5, -12.0, 1.0, 100, 30000);
    load_ok();
    const double bad[3] = {make_nan(), make_inf(), -make_inf()};
    for (int k = 0; k < 3; ++k)
        for (int b = 0; b < 3; ++b) {
            double in[3] = {-10.0, 5.0, 0.0}, out[3] = {1, 2, 3};
            in[k] = bad[b];
            for (int mode = 0; mode < 3; ++mode) {
                unsigned st = mode == 2 ? sc_corr_apply_inverse(&T, in, out, 4)
                                        : sc_corr_apply(&T, (sc_corr_mode)mode, in, out);
                assert_int_equal(st, SC_CORR_ST_LOADED | SC_CORR_ST_INVALID);
                assert_true(memcmp(in, out, sizeof in) == 0); /* bit-identical, NaN included */
            }
        }
}

static void test_not_loaded_passes_through(void **state)
{
    (void)state;
    make_grid(4, 4, 1, 100, 30000);
    size_t len = write_image();
    img[len - 1] ^= 0x10u;
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_CRC);
    assert_int_equal(T.loaded, 0);
    double in[3] = {-10.0, 5.0, 1.0}, out[3];
    assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE, in, out), 0);
    assert_true(memcmp(in, out, sizeof in) == 0);
    assert_int_equal(sc_corr_apply_inverse(&T, in, out, 3), 0);
    assert_true(memcmp(in, out, sizeof in) == 0);
    assert_int_equal(sc_corr_apply(NULL, SC_CORR_MEASURE, in, out), 0);
}

static void test_inverse_iteration(void **state)
{
    (void)state;
    /* Large errors (+-60 um) so that measure mode alone is visibly off. */
    make_grid(6, 6, 1, 2000, 30000);
    S.px = 5.0;
    S.py = 4.0;
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, 12, -12.5, 2.5, 1000, 30000);
    load_ok();
    double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    double worst_measure = 0;
    for (int k = 0; k < 500; ++k) {
        double p[3] = {rnd_uniform(S.x0 + 0.2, x1 - 0.2), rnd_uniform(S.y0 + 0.2, y1 - 0.2), 0.0};
        double q[3], r[3], m[3];
        assert_int_equal(sc_corr_apply_inverse(&T, p, q, 12), SC_CORR_ST_LOADED);
        /* q is the true position: pre-compensating it gives back the indicated p. */
        sc_corr_apply(&T, SC_CORR_POSITION, q, r);
        assert_close(r[0], p[0], 1e-11);
        assert_close(r[1], p[1], 1e-11);
        assert_close(r[2], p[2], 1e-11);
        /* One iteration is measure mode. */
        assert_int_equal(sc_corr_apply_inverse(&T, p, q, 1), SC_CORR_ST_LOADED);
        sc_corr_apply(&T, SC_CORR_MEASURE, p, m);
        assert_true(q[0] == m[0] && q[1] == m[1] && q[2] == m[2]);
        sc_corr_apply(&T, SC_CORR_POSITION, m, r);
        double e = dabs(r[0] - p[0]) + dabs(r[1] - p[1]);
        if (e > worst_measure)
            worst_measure = e;
    }
    assert_true(worst_measure > 1e-7); /* the test would notice an inverse that did nothing */
    /* Outside the grid: the status says so. */
    double p[3] = {x1 + 10, S.y0, 0}, q[3];
    assert_int_equal(sc_corr_apply_inverse(&T, p, q, 3), SC_CORR_ST_LOADED | SC_CORR_ST_OUTSIDE);
}

/* SC_CORR_MEASURE_EXACT: sc_corr_apply_inverse with SC_CORR_EXACT_ITERATIONS steps, bit for bit,
 * within the documented bound L^k |C| of the true inverse (L: the grid's largest slope sum, um
 * per um; |C|: its largest value), and far better than measure mode where that is visibly off. */
static void test_measure_exact_mode(void **state)
{
    (void)state;
    make_grid(7, 5, 1, 1000, 20000); /* +-20 um over 5 x 4 mm cells: slopes up to 1e-2 */
    S.px = 5.0;
    S.py = 4.0;
    load_ok();
    double lx = 0, ly = 0, cmax = 0;
    for (int i = 0; i < S.ny; ++i)
        for (int j = 0; j < S.nx; ++j)
            for (int c = 0; c < 2; ++c) {
                const int32_t *a = c == 0 ? S.gx : S.gy;
                const double v = node_um(a[i * S.nx + j], S.gscale_pm);
                cmax = dabs(v) > cmax ? dabs(v) : cmax;
                if (j + 1 < S.nx) {
                    double d = dabs(node_um(a[i * S.nx + j + 1], S.gscale_pm) - v) / (S.px * 1e3);
                    lx = d > lx ? d : lx;
                }
                if (i + 1 < S.ny) {
                    double d = dabs(node_um(a[(i + 1) * S.nx + j], S.gscale_pm) - v) / (S.py * 1e3);
                    ly = d > ly ? d : ly;
                }
            }
    const double L = lx + ly; /* the step q -> p - C(q) contracts by L in the max norm */
    double bound_mm = cmax * 1e-3;
    for (int k = 0; k < SC_CORR_EXACT_ITERATIONS; ++k)
        bound_mm *= L;
    double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    double worst_exact = 0, worst_measure = 0;
    for (int k = 0; k < 400; ++k) {
        double p[3] = {rnd_uniform(S.x0 + 0.5, x1 - 0.5), rnd_uniform(S.y0 + 0.5, y1 - 0.5), 0.0};
        double q[3], i3[3], t[3], m[3];
        assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE_EXACT, p, q), SC_CORR_ST_LOADED);
        assert_int_equal(sc_corr_apply_inverse(&T, p, i3, SC_CORR_EXACT_ITERATIONS),
                         SC_CORR_ST_LOADED);
        assert_true(q[0] == i3[0] && q[1] == i3[1] && q[2] == i3[2]);
        /* the true position, by many more steps */
        assert_int_equal(sc_corr_apply_inverse(&T, p, t, 16), SC_CORR_ST_LOADED);
        sc_corr_apply(&T, SC_CORR_MEASURE, p, m);
        double e = dabs(q[0] - t[0]) > dabs(q[1] - t[1]) ? dabs(q[0] - t[0]) : dabs(q[1] - t[1]);
        double em = dabs(m[0] - t[0]) > dabs(m[1] - t[1]) ? dabs(m[0] - t[0]) : dabs(m[1] - t[1]);
        worst_exact = e > worst_exact ? e : worst_exact;
        worst_measure = em > worst_measure ? em : worst_measure;
    }
    assert_true(L > 1e-3 && L < 0.5);
    assert_true(worst_exact <= bound_mm + 1e-12);
    assert_true(worst_measure > 1e-6);             /* measure mode is visibly off here ... */
    assert_true(worst_exact < 1e-3 * worst_measure); /* ... and the exact mode is not */
    /* NaN input passes through; outside the grid the status says so. */
    double bad[3] = {0.0 / 0.0, 1, 2}, o[3];
    assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE_EXACT, bad, o),
                     SC_CORR_ST_LOADED | SC_CORR_ST_INVALID);
    double far[3] = {x1 + 10, S.y0, 0};
    assert_int_equal(sc_corr_apply(&T, SC_CORR_MEASURE_EXACT, far, o),
                     SC_CORR_ST_LOADED | SC_CORR_ST_OUTSIDE);
}

/* The iteration count is capped at 16: more is 16 exactly, and 15 is not (a steep table, slopes
 * up to ~0.25, so that the 16th step still moves the result by ~1e-10 mm). */
static void test_inverse_iteration_cap(void **state)
{
    (void)state;
    make_grid(6, 6, 1, 20000, 30000); /* +-0.6 mm over a 5 mm pitch */
    S.px = 5.0;
    S.py = 4.0;
    load_ok();
    double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    int differ = 0;
    for (int k = 0; k < 200; ++k) {
        double p[3] = {rnd_uniform(S.x0 + 1, x1 - 1), rnd_uniform(S.y0 + 1, y1 - 1), 0.0};
        double q15[3], q16[3], q17[3], q99[3];
        sc_corr_apply_inverse(&T, p, q15, 15);
        sc_corr_apply_inverse(&T, p, q16, 16);
        sc_corr_apply_inverse(&T, p, q17, 17);
        sc_corr_apply_inverse(&T, p, q99, 1000);
        assert_true(memcmp(q16, q17, sizeof q16) == 0 && memcmp(q16, q99, sizeof q16) == 0);
        differ += memcmp(q15, q16, sizeof q15) != 0;
    }
    assert_true(differ > 100);
}

/* The smallest profile has 2 points (a line); 1 point is refused. */
static void test_two_point_profile(void **state)
{
    (void)state;
    make_grid(5, 5, 1, 100, 20000);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, 2, -10.0, 4.0, 50, 30000);
    load_ok();
    assert_int_equal(T.n_profiles, 1);
    double x1 = S.x0 + (S.nx - 1) * S.px, y1 = S.y0 + (S.ny - 1) * S.py;
    for (int k = 0; k < 200; ++k)
        check_point(rnd_uniform(S.x0, x1), rnd_uniform(S.y0, y1), 0.0);
    S.p[0].n = 1;
    size_t len = write_image();
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_RANGE);
}

/* Expected reason for a flip of one bit at byte b of a valid image. */
static int flip_reason(size_t b)
{
    if (b < 8)
        return SC_CORR_E_MAGIC;
    if (b < 10)
        return SC_CORR_E_VERSION;
    if (b >= 12 && b < 16)
        return SC_CORR_E_SIZE;
    return SC_CORR_E_CRC;
}

static void test_every_bit_flip_and_truncation(void **state)
{
    (void)state;
    make_grid(4, 3, 1, 100, 30000);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, 5, -12.0, 1.0, 100, 30000);
    S.nsrc = 2;
    size_t len = write_image();
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_OK);
    size_t flips = 0;
    for (size_t b = 0; b < len; ++b)
        for (int bit = 0; bit < 8; ++bit) {
            img[b] ^= (uint8_t)(1u << bit);
            int rc = sc_corr_load(&T, img, len);
            if (rc != flip_reason(b))
                print_error("flip of byte %u bit %d: %d (%s)\n", (unsigned)b, bit, rc,
                            sc_corr_strerror(rc));
            assert_int_equal(rc, flip_reason(b));
            assert_int_equal(T.loaded, 0);
            assert_int_equal(sc_corr_validate(img, len), rc);
            img[b] ^= (uint8_t)(1u << bit);
            ++flips;
        }
    assert_int_equal(flips, 8 * len);
    for (size_t n = 0; n < len; ++n) {
        assert_int_equal(sc_corr_load(&T, img, n), SC_CORR_E_SIZE);
        assert_int_equal(T.loaded, 0);
    }
    img[len] = 0; /* one byte too many */
    assert_int_equal(sc_corr_load(&T, img, len + 1), SC_CORR_E_SIZE);
    assert_int_equal(sc_corr_load(&T, NULL, len), SC_CORR_E_SIZE);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_OK);
}

/* A valid-CRC image with one field changed must fail with `want`. */
#define EXPECT_LOAD(want)                                                 \
    do {                                                                  \
        size_t len_ = write_image();                                      \
        assert_int_equal(sc_corr_load(&T, img, len_), (want));            \
        assert_int_equal(T.loaded, (want) == SC_CORR_OK ? 1 : 0);         \
    } while (0)

/* Refused with code want, sc_corr_explain naming the field (its text contains `what`). */
#define EXPECT_REFUSED(want, what)                                        \
    do {                                                                  \
        size_t len_ = write_image();                                      \
        assert_int_equal(sc_corr_load(&T, img, len_), (want));            \
        assert_int_equal(T.loaded, 0);                                    \
        assert_non_null(strstr(sc_corr_explain(img, len_), (what)));      \
    } while (0)

static void base_spec(void)
{
    make_grid(4, 3, 1, 100, 30000);
    add_profile(SC_CORR_AXIS_Y, SC_CORR_AXIS_X, 6, 0.0, 0.5, 100, 30000);
}

static void test_semantic_errors(void **state)
{
    (void)state;
    base_spec();
    EXPECT_LOAD(SC_CORR_OK);
    base_spec(); S.nx = 1; EXPECT_REFUSED(SC_CORR_E_RANGE, "fewer than 2 nodes");
    base_spec(); S.ny = 0; EXPECT_REFUSED(SC_CORR_E_RANGE, "fewer than 2 nodes");
    base_spec(); S.px = 0.0; EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's pitch");
    base_spec(); S.py = -1.0; EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's pitch");
    base_spec(); S.x0 = make_nan(); EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's origin");
    base_spec(); S.y0 = make_inf(); EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's origin");
    base_spec(); S.px = make_nan(); EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's pitch");
    base_spec(); S.x0 = 2e6; EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's origin");
    base_spec(); S.genc = 3; EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's value encoding");
    base_spec(); S.gscale_pm = 0; EXPECT_REFUSED(SC_CORR_E_RANGE, "grid's value scale");
    base_spec(); S.p[0].axis = 3; EXPECT_REFUSED(SC_CORR_E_RANGE, "axis or dir");
    base_spec(); S.p[0].dir = 7; EXPECT_REFUSED(SC_CORR_E_RANGE, "axis or dir");
    base_spec(); S.p[0].n = 1; EXPECT_REFUSED(SC_CORR_E_RANGE, "fewer than 2 points");
    base_spec(); S.p[0].step = 0.0; EXPECT_REFUSED(SC_CORR_E_RANGE, "profile's step");
    base_spec(); S.p[0].start = make_nan(); EXPECT_REFUSED(SC_CORR_E_RANGE, "profile's start");
    base_spec(); S.p[0].enc = 0; EXPECT_REFUSED(SC_CORR_E_RANGE, "profile's value encoding");
    base_spec(); S.p[0].scale_pm = 0; EXPECT_REFUSED(SC_CORR_E_RANGE, "profile's value scale");
    base_spec(); S.sigma = make_nan(); EXPECT_REFUSED(SC_CORR_E_RANGE, "provenance's sigma");
    base_spec(); S.nsrc = 10; EXPECT_REFUSED(SC_CORR_E_RANGE, "more than 9 sources");
    base_spec(); S.np = 9; EXPECT_REFUSED(SC_CORR_E_RANGE, "more than 8 profiles");
    base_spec(); S.sigma = 0.05; S.nsrc = 9; EXPECT_LOAD(SC_CORR_OK);

    /* Raw edits of fields the writer always fills correctly, with the CRC recomputed. */
    size_t len;
    base_spec(); len = write_image(); img[22] = 1; fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_RANGE); /* reserved */
    base_spec(); len = write_image(); img[10] = 65; fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_RANGE); /* header size */
    base_spec(); len = write_image(); img[8] = 2; fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_VERSION);
    base_spec(); len = write_image(); img[60] += 32; fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_SIZE); /* provenance size */
    make_grid(4, 3, 1, 100, 30000); len = write_image(); img[16] = 5; fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_SIZE); /* nx disagrees with length */
    base_spec(); len = write_image();
    size_t prov = len - 4 - 56 - 32 * (size_t)S.nsrc;
    memset(img + prov, 'a', 32); fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_RANGE); /* method not terminated */
    base_spec(); len = write_image(); img[prov + 50] = 1; fix_crc(len);
    assert_int_equal(sc_corr_load(&T, img, len), SC_CORR_E_RANGE); /* provenance reserved */

    assert_int_equal(strcmp(sc_corr_explain(img, 3), "shorter than a table's header and checksum"), 0);
    /* every prefix of a valid image shorter than the 64-byte header and the 4-byte checksum is
     * refused as short, before any field of the header is read (a mutant reading on from 60
     * bytes survived) */
    base_spec(); len = write_image();
    for (size_t k = 0; k < 64 + 4; ++k) {
        assert_int_equal(sc_corr_load(&T, img, k), SC_CORR_E_SIZE);
        assert_int_equal(strcmp(sc_corr_explain(img, k), "shorter than a table's header and checksum"), 0);
    }
    base_spec(); len = write_image(); img[100] ^= 1;
    assert_non_null(strstr(sc_corr_explain(img, len), "checksum mismatch"));
    base_spec(); len = write_image();
    assert_int_equal(strcmp(sc_corr_explain(img, len), "ok"), 0);

    /* Valid tables larger than this build: capacity. */
    make_grid(SC_CORR_MAX_NX + 1, 2, 1, 100, 100);
    EXPECT_REFUSED(SC_CORR_E_CAPACITY, "SC_CORR_MAX_NX");
    make_grid(2, SC_CORR_MAX_NY + 1, 1, 100, 100);
    EXPECT_LOAD(SC_CORR_E_CAPACITY);
    make_grid(2, 2, 1, 100, 100);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, SC_CORR_MAX_PROFILE_POINTS + 1, 0.0, 0.1, 100, 100);
    EXPECT_REFUSED(SC_CORR_E_CAPACITY, "SC_CORR_MAX_PROFILE_POINTS");
    make_grid(2, 2, 1, 100, 100);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, SC_CORR_MAX_PROFILE_POINTS, 0.0, 0.1, 100, 100);
    EXPECT_LOAD(SC_CORR_OK);
#if SC_CORR_MAX_PROFILES < 8
    make_grid(2, 2, 1, 100, 100);
    for (int k = 0; k <= SC_CORR_MAX_PROFILES; ++k)
        add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, 3, 0.0, 0.1, 100, 100);
    EXPECT_LOAD(SC_CORR_E_CAPACITY);
#endif

    /* Every code has its own message. */
    const int codes[] = {SC_CORR_OK, SC_CORR_E_SIZE, SC_CORR_E_MAGIC, SC_CORR_E_VERSION,
                         SC_CORR_E_CRC, SC_CORR_E_RANGE, SC_CORR_E_CAPACITY};
    for (size_t a = 0; a < sizeof codes / sizeof codes[0]; ++a) {
        assert_true(sc_corr_strerror(codes[a])[0] != '\0');
        for (size_t b = 0; b < a; ++b)
            assert_true(strcmp(sc_corr_strerror(codes[a]), sc_corr_strerror(codes[b])) != 0);
    }
}

/* Checksum-valid garbage: random changes to random bytes with the CRC recomputed must never
 * crash or read out of bounds (ASan on the host), and whatever loads must give finite results. */
static void test_fuzz_valid_crc(void **state)
{
    (void)state;
    make_grid(5, 4, 1, 100, 30000);
    add_profile(SC_CORR_AXIS_X, SC_CORR_AXIS_Y, 7, -12.0, 1.0, 100, 30000);
    add_profile(SC_CORR_AXIS_Y, SC_CORR_AXIS_Z, 3, 0.0, 2.0, 100, 30000);
    const size_t len = write_image();
    static uint8_t orig[4096];
    assert_true(len <= sizeof orig);
    memcpy(orig, img, len);
    int loaded = 0, refused = 0;
    for (int it = 0; it < 20000; ++it) {
        memcpy(img, orig, len);
        int nchanges = 1 + (int)(rnd_u32() % 4u);
        for (int c = 0; c < nchanges; ++c) {
            /* mostly the header and the profile headers, where the structure lives */
            size_t at = (rnd_u32() % 4u) ? rnd_u32() % 64u : rnd_u32() % (uint32_t)(len - 4);
            img[at] = (uint8_t)rnd_u32();
        }
        fix_crc(len);
        int rc = sc_corr_load(&T, img, len);
        if (rc != SC_CORR_OK) {
            assert_int_equal(T.loaded, 0);
            ++refused;
            continue;
        }
        ++loaded;
        for (int k = 0; k < 4; ++k) {
            double in[3] = {rnd_uniform(-1e4, 1e4), rnd_uniform(-1e4, 1e4), rnd_uniform(-10, 10)}, out[3];
            unsigned st = sc_corr_apply(&T, (sc_corr_mode)(k & 1), in, out);
            assert_true(st & SC_CORR_ST_LOADED);
            for (int d = 0; d < 3; ++d)
                assert_true(out[d] - out[d] == 0.0); /* finite */
        }
    }
    assert_true(refused > 0 && loaded > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc32),
        cmocka_unit_test(test_nodes_exact),
        cmocka_unit_test(test_between_nodes_bilinear),
        cmocka_unit_test(test_continuity_across_edges),
        cmocka_unit_test(test_clamping_and_status),
        cmocka_unit_test(test_edge_nodes_inside),
        cmocka_unit_test(test_profiles),
        cmocka_unit_test(test_profile_counts_axes_and_reload),
        cmocka_unit_test(test_invalid_input),
        cmocka_unit_test(test_not_loaded_passes_through),
        cmocka_unit_test(test_inverse_iteration),
        cmocka_unit_test(test_measure_exact_mode),
        cmocka_unit_test(test_inverse_iteration_cap),
        cmocka_unit_test(test_two_point_profile),
        cmocka_unit_test(test_every_bit_flip_and_truncation),
        cmocka_unit_test(test_semantic_errors),
        cmocka_unit_test(test_fuzz_valid_crc),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
