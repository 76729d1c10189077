/* Decimal numbers in text files (selfcal/number.h): the grammar check (strict, locale-free) and
 * the "%.17g"-style layout are here; the exact conversions are fast_float's and Dragonbox's
 * (number_kernels.cc), because glibc's strtod/printf took most of a large command's time
 * (docs/profile.md: reading and writing 10⁶ points). */
#include "selfcal/number.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

int sc_number_kernel_parse(const char *first, const char *last, double *out);
void sc_number_kernel_shortest(double v, uint64_t *digits, int *exp10);

/* fast_float's from_chars takes exactly this grammar except a leading '+' (skipped here) and the
 * words inf/nan (refused as non-finite), and stops at the first byte outside it (refused: it must
 * consume every byte), so no second scan is needed; only a zero or subnormal result looks at the
 * digits again, to refuse an underflow of nonzero digits. */
sc_status sc_number_parse(const char *s, size_t len, double *out)
{
    const char *p = s, *end = s + len;
    if (p < end && *p == '+') {
        ++p;
        if (p < end && *p == '-')
            return SC_E_INPUT;
    }
    double v;
    if (p == end || sc_number_kernel_parse(p, end, &v) != 0 || !isfinite(v))
        return SC_E_INPUT;
    if (!(fabs(v) >= DBL_MIN)) /* zero or subnormal: refuse unless every digit is 0 */
        for (const char *q = p; q < end && *q != 'e' && *q != 'E'; ++q)
            if (*q >= '1' && *q <= '9')
                return SC_E_INPUT;
    *out = v;
    return SC_OK;
}

int sc_number_format(double v, char *buf)
{
    char *p = buf;
    if (signbit(v))
        *p++ = '-';
    if (isnan(v)) {
        strcpy(p, "nan");
        return (int)(p - buf) + 3;
    }
    if (isinf(v)) {
        strcpy(p, "inf");
        return (int)(p - buf) + 3;
    }
    if (v == 0) {
        *p++ = '0';
        *p = '\0';
        return (int)(p - buf);
    }
    uint64_t m;
    int e;
    sc_number_kernel_shortest(fabs(v), &m, &e);
    /* the digits, most significant first, two at a time */
    static const char pairs[201] = "00010203040506070809101112131415161718192021222324252627282930"
                                   "31323334353637383940414243444546474849505152535455565758596061"
                                   "62636465666768697071727374757677787980818283848586878889909192"
                                   "93949596979899";
    char tmp[24], *t = tmp + sizeof tmp;
    while (m >= 100) {
        unsigned r = (unsigned)(m % 100);
        m /= 100;
        *--t = pairs[2 * r + 1];
        *--t = pairs[2 * r];
    }
    if (m >= 10) {
        *--t = pairs[2 * m + 1];
        *--t = pairs[2 * m];
    } else {
        *--t = (char)('0' + m);
    }
    const char *dig = t;
    int k = (int)(tmp + sizeof tmp - t);
    int x = k - 1 + e; /* decimal exponent of the first digit */
    if (x >= -4 && x < 17) {
        if (e >= 0) { /* integer: the digits, then e zeros */
            memcpy(p, dig, (size_t)k);
            p += k;
            memset(p, '0', (size_t)e);
            p += e;
        } else if (x >= 0) { /* d.ddd */
            memcpy(p, dig, (size_t)x + 1);
            p += x + 1;
            *p++ = '.';
            memcpy(p, dig + x + 1, (size_t)(k - x - 1));
            p += k - x - 1;
        } else { /* 0.000ddd */
            *p++ = '0';
            *p++ = '.';
            memset(p, '0', (size_t)(-x - 1));
            p += -x - 1;
            memcpy(p, dig, (size_t)k);
            p += k;
        }
    } else {
        *p++ = dig[0];
        if (k > 1) {
            *p++ = '.';
            memcpy(p, dig + 1, (size_t)k - 1);
            p += k - 1;
        }
        *p++ = 'e';
        *p++ = x < 0 ? '-' : '+';
        int ax = x < 0 ? -x : x;
        if (ax >= 100)
            *p++ = (char)('0' + ax / 100);
        *p++ = (char)('0' + ax / 10 % 10);
        *p++ = (char)('0' + ax % 10);
    }
    *p = '\0';
    return (int)(p - buf);
}
