// The two conversion kernels of number.c, from well-kept header-only Debian libraries, wrapped
// for C (this is the project's only C++: both libraries are C++ templates):
//   fast_float (libfast-float-dev): D. Lemire's exact decimal -> double (from_chars, and its
//     Eisel-Lemire core compute_float);
//   Dragonbox (libdragonbox-dev):   J. Jeon's shortest round-trip double -> decimal digits.
// The parser's grammar checks are here (sc_number_parse_prefix), the text layout is number.c's.
//
// Why a digit scan of our own in front of fast_float: Debian's fast_float (3.9) reads the digits
// after the first eight of a fraction one by one; on the numbers our writers write (16-17
// digits) that made it only ~4.8x faster than glibc's strtod on this project's 2-core machine.
// The scan below reads eight bytes at a time throughout (SWAR), then hands the mantissa and the
// exponent to fast_float's own exact conversion; anything it does not handle (an exponent, more
// than 19 digits, inf/nan, an Eisel-Lemire undecided case) goes to fast_float::from_chars whole,
// so every value is fast_float's.
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <system_error>

#include <dragonbox/dragonbox.h>
#include <fast_float/fast_float.h>

#include "selfcal/number.h"

namespace {

// Digits at p (before last) into w (w = 10 w + digit each; wraps past 19 digits, which the caller
// refuses); returns the first byte that is not a digit.
inline const char *scan_digits(const char *p, const char *last, std::uint64_t &w)
{
    static const std::uint64_t pow10[8] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000};
    while (last - p >= 8) {
        std::uint64_t x;
        std::memcpy(&x, p, 8);
        // a nonzero byte where the byte is not '0'..'9' (a carry out of a byte >= 0xFA only
        // reaches bytes after it, past the first non-digit)
        std::uint64_t bad = ((x & 0xF0F0F0F0F0F0F0F0ULL) ^ 0x3030303030303030ULL) |
                            (((x + 0x0606060606060606ULL) & 0xF0F0F0F0F0F0F0F0ULL) ^
                             0x3030303030303030ULL);
        if (!bad) {
            w = w * 100000000 + fast_float::parse_eight_digits_unrolled(x);
            p += 8;
            continue;
        }
        int n = __builtin_ctzll(bad) / 8; // leading digits in this word (0..7)
        if (n) {                         // the n digits, behind 8 - n '0's
            x = x << (8 * (8 - n)) | 0x3030303030303030ULL >> (8 * n);
            w = w * pow10[n] + fast_float::parse_eight_digits_unrolled(x);
        }
        return p + n;
    }
    while (p < last && *p >= '0' && *p <= '9')
        w = 10 * w + std::uint64_t(*p++ - '0');
    return p;
}

const char *parse_whole(const char *first, const char *last, double *out)
{
    fast_float::from_chars_result r = fast_float::from_chars(first, last, *out);
    return r.ec == std::errc() ? r.ptr : nullptr;
}

// Zero or subnormal v read from the digits [p, q): refused unless every mantissa digit is 0.
inline bool underflows(const char *p, const char *q)
{
    for (; p < q && *p != 'e' && *p != 'E'; ++p)
        if (*p >= '1' && *p <= '9')
            return true;
    return false;
}

// The number at first (first < last), checked: its end, or NULL if none starts there or it is
// refused (not finite, or an underflow of nonzero digits).
inline const char *parse_checked(const char *first, const char *last, double *out)
{
    const char *p = first;
    bool negative = *p == '-';
    p += negative;
    std::uint64_t w = 0;
    const char *start = p;
    p = scan_digits(p, last, w);
    std::int64_t digits = p - start, exp10 = 0;
    if (p < last && *p == '.') {
        const char *frac = ++p;
        p = scan_digits(p, last, w);
        exp10 = frac - p;
        digits += p - frac;
    }
    if (digits > 19) // leading zeros (0.000ddd) add nothing to w: count the digits after them
        for (const char *z = start; z < p && (*z == '0' || *z == '.'); ++z)
            digits -= *z == '0';
    fast_float::adjusted_mantissa am;
    if (digits == 0 || digits > 19 || (p < last && (*p == 'e' || *p == 'E')) ||
        (am = fast_float::compute_float<fast_float::binary_format<double>>(exp10, w)).power2 < 0) {
        double v; // the general path: fast_float's from_chars on the text itself
        p = parse_whole(first, last, &v);
        if (!p || !std::isfinite(v) || (!(std::fabs(v) >= DBL_MIN) && underflows(first, p)))
            return nullptr;
        *out = v;
        return p;
    }
    // am.power2 is the biased binary exponent: 0 for zero and subnormals, 0x7FF for infinity
    if (am.power2 == 0 && underflows(start, p))
        return nullptr;
    if (am.power2 >= 0x7FF)
        return nullptr;
    fast_float::to_float(negative, am, *out);
    return p;
}

} // namespace

// selfcal/number.h's parser: fast_float's grammar is ours except a leading '+' (skipped here) and
// the words inf/nan (refused as non-finite); only a zero or subnormal result looks at the digits
// again, to refuse an underflow of nonzero digits.
extern "C" sc_status sc_number_parse_prefix(const char *s, const char *end, const char **stop,
                                            double *out)
{
    const char *p = s;
    if (p < end && *p == '+') {
        ++p;
        if (p < end && *p == '-')
            return SC_E_INPUT;
    }
    const char *q = p < end ? parse_checked(p, end, out) : nullptr;
    if (!q)
        return SC_E_INPUT;
    *stop = q;
    return SC_OK;
}

// v finite and nonzero: v = ±digits·10^exp10 with the fewest digits (no trailing zeros).
extern "C" void sc_number_kernel_shortest(double v, std::uint64_t *digits, int *exp10)
{
    auto d = jkj::dragonbox::to_decimal(v);
    *digits = d.significand;
    *exp10 = d.exponent;
}
