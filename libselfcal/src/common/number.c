/* Decimal numbers in text files (selfcal/number.h): the whole-text parse and the "%.17g"-style
 * layout are here; the exact conversions (and the parser's grammar check, inlined with its
 * kernel) are fast_float's and Dragonbox's (number_kernels.cc), because glibc's strtod/printf took
 * most of a large command's time (docs/profile.md: reading and writing 10⁶ points). */
#include "selfcal/number.h"
#include "number_internal.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

void sc_number_kernel_shortest(double v, uint64_t *digits, int *exp10);

/* sc_number_parse_prefix is in number_kernels.cc, next to the kernel it wraps. */
sc_status sc_number_parse(const char *s, size_t len, double *out)
{
    const char *stop;
    double v;
    if (sc_number_parse_prefix(s, s + len, &stop, &v) != SC_OK || stop != s + len)
        return SC_E_INPUT;
    *out = v;
    return SC_OK;
}

/* The 8 decimal digits of x < 10^8, first digit in the lowest byte (the order of memory), as
 * values 0..9: split into 4 + 4, 2 + 2, 1 + 1 digits in parallel lanes of one word (SWAR). */
static inline uint64_t digits8(uint32_t x)
{
    uint64_t v = x / 10000 | (uint64_t)(x % 10000) << 32;
    uint64_t q = (v * 10486 >> 20) & 0x0000007F0000007FULL; /* lane / 100 */
    v = q | (v - q * 100) << 16;
    q = (v * 103 >> 10) & 0x000F000F000F000FULL; /* lane / 10 */
    return q | (v - q * 10) << 8;
}

static const uint64_t pow10_u64[19] = {1,
                                       10,
                                       100,
                                       1000,
                                       10000,
                                       100000,
                                       1000000,
                                       10000000,
                                       100000000,
                                       1000000000,
                                       10000000000,
                                       100000000000,
                                       1000000000000,
                                       10000000000000,
                                       100000000000000,
                                       1000000000000000,
                                       10000000000000000,
                                       100000000000000000,
                                       1000000000000000000};

/* The decimal digits of m (0 < m < 10^17), written as 17 characters with leading zeros at t. */
static inline void digits17(uint64_t m, char t[17])
{
    uint64_t hi = m / 100000000, lo = m % 100000000;
    uint64_t wh = digits8((uint32_t)(hi % 100000000)), wl = digits8((uint32_t)lo);
    t[0] = (char)('0' + hi / 100000000);
    uint64_t ah = wh + 0x3030303030303030ULL, al = wl + 0x3030303030303030ULL;
    memcpy(t + 1, &ah, 8);
    memcpy(t + 9, &al, 8);
}

/* The number of decimal digits of m (1 <= m < 10^18). */
static inline int count_digits(uint64_t m)
{
    int t = (64 - __builtin_clzll(m)) * 1233 >> 12; /* floor(log10(2^bits)) */
    return t + (m >= pow10_u64[t]);
}

/* Store the last k digits of m (1 <= k <= 17, m < 10^17) at q, leading zeros included, by 8-byte
 * stores from registers: the second store overwrites the first one's spare bytes, and nothing is
 * read back (a load of bytes just written by several stores waits for them to reach the cache).
 * Writes up to q + 17. */
static inline void put_digits(char *q, uint64_t m, int k)
{
    const uint64_t zeros = 0x3030303030303030ULL;
    if (k <= 8) {
        uint64_t w = (digits8((uint32_t)(m % 100000000)) + zeros) >> (8 * (8 - k));
        memcpy(q, &w, 8);
        return;
    }
    uint64_t hi = m / 100000000, lo = digits8((uint32_t)(m % 100000000)) + zeros;
    if (k <= 16) {
        uint64_t w = (digits8((uint32_t)hi) + zeros) >> (8 * (16 - k));
        memcpy(q, &w, 8);
        memcpy(q + k - 8, &lo, 8);
        return;
    }
    uint64_t mid = digits8((uint32_t)(hi % 100000000)) + zeros;
    q[0] = (char)('0' + hi / 100000000 % 10);
    memcpy(q + 1, &mid, 8);
    memcpy(q + 9, &lo, 8);
}

char *sc_number_put_u64(char *p, uint64_t u)
{
    if (u >= pow10_u64[17]) { /* 18 to 20 digits: the first 1 to 3, then 17 */
        p = sc_number_put_u64(p, u / pow10_u64[17]);
        put_digits(p, u % pow10_u64[17], 17);
        return p + 17;
    }
    int k = u ? count_digits(u) : 1;
    put_digits(p, u, k);
    return p + k;
}

/* The rare cases: NaN, infinities, zeros. */
static int format_special(double v, char *buf)
{
    char *p = buf;
    if (signbit(v))
        *p++ = '-';
    strcpy(p, isnan(v) ? "nan" : isinf(v) ? "inf" : "0");
    return (int)(p - buf) + (v == 0 ? 1 : 3);
}

/* Lay out m·10^e (m > 0 with at most 17 digits, without trailing zeros unless e = 0 and m·10^e
 * has at most prec digits) as printf's "%.<prec>g" does: fixed for decimal exponents
 * -4 .. prec - 1, else d.ddde±XX. Integers and 0.000ddd are stored from registers (put_digits);
 * the point inside the digits copies fixed-size runs from a small array (compiled to plain moves,
 * where a copy of k bytes is a call; laying those out from registers too measured slower). The
 * runs write past the text's end: p has room up to SC_NUMBER_BUF bytes from the buffer's start. */
static char *layout(char *p, uint64_t m, int e, int prec)
{
    char tmp[40]; /* 17 digits, then slack for the fixed copies */
    int k = count_digits(m);
    int x = k - 1 + e; /* decimal exponent of the first digit */
    if (e >= 0 && x < prec) { /* an integer: m·10^e has x + 1 <= prec digits */
        put_digits(p, m * pow10_u64[e], x + 1);
        p += x + 1;
    } else if (x >= 0 && x < prec) { /* d.ddd: x + 1 digits, the point, the rest */
        digits17(m, tmp);
        const char *dig = tmp + 17 - k;
        memcpy(p, dig, 16);
        p[x + 1] = '.';
        memcpy(p + x + 2, dig + x + 1, 16);
        p += k + 1;
    } else if (x < 0 && x >= -4) { /* 0.000ddd */
        memcpy(p, "0.000000", 8);
        p += 1 - x;
        put_digits(p, m, k);
        p += k;
    } else { /* d.ddde±XX */
        digits17(m, tmp);
        const char *dig = tmp + 17 - k;
        p[0] = dig[0];
        p[1] = '.';
        memcpy(p + 2, dig + 1, 16);
        p += k > 1 ? k + 1 : 1;
        *p++ = 'e';
        *p++ = x < 0 ? '-' : '+';
        int ax = x < 0 ? -x : x;
        if (ax >= 100)
            *p++ = (char)('0' + ax / 100);
        *p++ = (char)('0' + ax / 10 % 10);
        *p++ = (char)('0' + ax % 10);
    }
    *p = '\0';
    return p;
}

void sc_number_find_shortest(double v, sc_number_shortest *d)
{
    double a = fabs(v);
    d->v = v;
    d->m = 0; /* 0, NaN and the infinities: format_special */
    d->e = 0;
    if (!(a > 0) || !isfinite(a))
        return;
    /* An integer below 2^53 is its own shortest text: the doubles there are at most 1 apart, so
     * only numbers within 1/2 of a read back as a, and a decimal with no more significant digits
     * than a's integer part is an integer. Indices and positions on a whole-millimetre pitch are
     * such numbers, and this skips the shortest-digit search for them. */
    if (a < 0x1p53 && a == (double)(uint64_t)a)
        d->m = (uint64_t)a;
    else
        sc_number_kernel_shortest(a, &d->m, &d->e);
}

char *sc_number_put_shortest(char *p, const sc_number_shortest *d)
{
    if (d->m == 0)
        return p + format_special(d->v, p);
    *p = '-';
    p += signbit(d->v) != 0;
    return layout(p, d->m, d->e, 17);
}

int sc_number_format(double v, char *buf)
{
    sc_number_shortest d;
    sc_number_find_shortest(v, &d);
    return (int)(sc_number_put_shortest(buf, &d) - buf);
}

/* 10^s for s = 0..38, exact in 128 bits. */
static unsigned __int128 pow10_u128(int s)
{
    unsigned __int128 e18 = pow10_u64[18];
    return s <= 18   ? pow10_u64[s]
           : s <= 36 ? e18 * pow10_u64[s - 18]
                     : e18 * e18 * pow10_u64[s - 36];
}

/* a (normal, > 0) rounded to 15 significant digits, exactly: *r (10^14 <= *r < 10^15) times
 * 10^(*x - 14). a = m·2^q; with s = 14 - x, floor(a·10^s) = (m·10^s) >> -q in 128-bit integers and
 * the bits shifted out decide the rounding (ties to even, as glibc's printf in the default
 * rounding mode). Returns 0 where that does not fit in 128 bits (a >= 2^52 or a < 2^-21, about
 * 4.8e-7; and subnormals): the caller then asks printf. */
static int round15(double a, uint64_t *r, int *x)
{
    uint64_t bits;
    memcpy(&bits, &a, 8);
    int be = (int)(bits >> 52 & 0x7FF);
    if (be == 0)
        return 0; /* subnormal */
    uint64_t m = (bits & ((1ULL << 52) - 1)) | 1ULL << 52;
    int sh = 1075 - be; /* a = m·2^-sh */
    /* a·10^s < 10^16 < 2^54 below, so m·10^s < 2^(54 + sh) fits 128 bits for sh <= 73 */
    if (sh <= 0 || sh > 73)
        return 0;
    /* floor(log10(a)) from the binary exponent (log10 2 ≈ 78913/2^18): off by at most one,
     * corrected below */
    int k2 = be - 1023, e = k2 >= 0 ? (k2 * 78913) >> 18 : -((-k2 * 78913 + 262143) >> 18);
    for (int tries = 0; tries < 3; ++tries) {
        int s = 14 - e;
        if (s < 0 || s > 38)
            return 0;
        unsigned __int128 n = (unsigned __int128)m * pow10_u128(s);
        uint64_t t = (uint64_t)(n >> sh);
        if (t >= 1000000000000000ULL) {
            ++e;
            continue;
        }
        if (t < 100000000000000ULL) {
            --e;
            continue;
        }
        unsigned __int128 rem = n & (((unsigned __int128)1 << sh) - 1);
        unsigned __int128 half = (unsigned __int128)1 << (sh - 1);
        if (rem > half || (rem == half && (t & 1)))
            ++t;
        if (t == 1000000000000000ULL) {
            t = 100000000000000ULL;
            ++e;
        }
        *r = t;
        *x = e;
        return 1;
    }
    return 0;
}

int sc_number_format_15g(double v, char *buf)
{
    if (!(fabs(v) > 0) || !isfinite(v))
        return format_special(v, buf);
    uint64_t r;
    int x;
    if (!round15(fabs(v), &r, &x))
        return snprintf(buf, SC_NUMBER_BUF, "%.15g", v);
    char *p = buf;
    *p = '-';
    p += signbit(v) != 0;
    int e = x - 14;
    while (r % 10 == 0) {
        r /= 10;
        ++e;
    }
    return (int)(layout(p, r, e, 15) - buf);
}
