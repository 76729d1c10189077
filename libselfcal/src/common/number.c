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

static int is_digit(char c)
{
    return c >= '0' && c <= '9';
}

int sc_number_parse(const char *s, size_t len, double *out)
{
    const char *p = s, *end = s + len;
    if (p < end && (*p == '+' || *p == '-'))
        ++p;
    const char *mant = p;
    int nonzero = 0, ndig = 0;
    for (; p < end && is_digit(*p); ++p)
        ndig++, nonzero |= *p != '0';
    if (p < end && *p == '.')
        for (++p; p < end && is_digit(*p); ++p)
            ndig++, nonzero |= *p != '0';
    if (ndig == 0)
        return -1;
    if (p < end && (*p == 'e' || *p == 'E')) {
        ++p;
        if (p < end && (*p == '+' || *p == '-'))
            ++p;
        if (p == end || !is_digit(*p))
            return -1;
        while (p < end && is_digit(*p))
            ++p;
    }
    if (p != end)
        return -1;
    double v;
    if (sc_number_kernel_parse(mant, end, &v) != 0 || !isfinite(v))
        return -1;
    if (nonzero && !(v >= DBL_MIN)) /* underflow to zero or to a subnormal */
        return -1;
    *out = s[0] == '-' ? -v : v;
    return 0;
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
    char dig[24];
    int k = 0;
    for (uint64_t t = m; t > 0; t /= 10)
        k++;
    for (int i = k - 1; i >= 0; --i, m /= 10)
        dig[i] = (char)('0' + m % 10);
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
