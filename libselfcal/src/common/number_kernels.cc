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
//
// Why an SSE path in front of that (parse_sse, x86 with SSE4.1, chosen at run time): the numbers
// the writers write, d…d.d…d of at most 19 digits, are most of what is read; where 32 bytes can be
// read from the number on, their digits are found and right-aligned by two byte shuffles and
// turned into an integer by three multiply-adds, without a loop or a branch per eight digits:
// 13–14 ns a number instead of 19–21 on this project's 2-core machine (docs/profile.md). Any other
// shape (an exponent, no fraction, more digits, fewer bytes left) takes the scan below.
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <system_error>

#include <dragonbox/dragonbox.h>
#include <fast_float/fast_float.h>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define SC_NUMBER_SSE 1
#else
#define SC_NUMBER_SSE 0
#endif

#include "selfcal/number.h"
#include "number_internal.h"

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

#if SC_NUMBER_SSE
// d…d.d…d at p (1..16 digits, the point, a fraction; at most 19 digits in all), ending at or
// before last, with 32 bytes readable from p: its end, the value in *out; NULL for any other
// shape or an Eisel-Lemire undecided case (the caller's scan then reads it).
__attribute__((target("ssse3,sse4.1"))) const char *parse_sse(const char *p, const char *last,
                                                             double *out, bool negative)
{
    const __m128i zero = _mm_set1_epi8('0'), nine = _mm_set1_epi8(9);
    __m128i lo = _mm_sub_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i *>(p)), zero);
    __m128i hi = _mm_sub_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i *>(p + 16)), zero);
    // a bit per byte that is not a digit ('0'..'9' became 0..9, everything else is above 9)
    unsigned dig_lo = unsigned(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_min_epu8(lo, nine), lo)));
    unsigned dig_hi = unsigned(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_min_epu8(hi, nine), hi)));
    std::uint32_t other = ~(dig_lo | dig_hi << 16), after_point = other & (other - 1);
    if (other == 0 || after_point == 0)
        return nullptr;
    int a = __builtin_ctz(other), e = __builtin_ctz(after_point), b = e - a - 1; // a + 1 + b = e
    if (a == 0 || p[a] != '.' || b == 0 || a + b > 19 || e > last - p ||
        (e < last - p && (p[e] | 0x20) == 'e'))
        return nullptr;
    // the a + b digits without the point, right-aligned in a field of 32 (lanes j = 0..31): lane
    // j of the fraction (j >= 32 - b) is byte j + e - 32, of the integer part byte j + e - 33;
    // a source index below 0 or beyond the vector it is looked up in gives 0 (pshufb)
    const __m128i iota = _mm_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const __m128i sixteen = _mm_set1_epi8(16), fifteen = _mm_set1_epi8(15);
    const __m128i first_frac = _mm_set1_epi8(char(31 - b)); // lanes above it: the fraction
    const __m128i shift_frac = _mm_set1_epi8(char(e - 32)), shift_int = _mm_set1_epi8(char(e - 33));
    __m128i field[2];
    for (int h = 0; h < 2; ++h) {
        __m128i j = h ? _mm_add_epi8(iota, sixteen) : iota;
        __m128i src = _mm_add_epi8(j, _mm_blendv_epi8(shift_int, shift_frac,
                                                      _mm_cmpgt_epi8(j, first_frac)));
        __m128i from_lo = _mm_or_si128(src, _mm_cmpgt_epi8(src, fifteen));
        field[h] = _mm_or_si128(_mm_shuffle_epi8(lo, from_lo),
                                _mm_shuffle_epi8(hi, _mm_sub_epi8(src, sixteen)));
    }
    // 32 digits -> 2-digit -> 4-digit -> 8-digit groups (the first group is 0: at most 19 digits)
    const __m128i by10 = _mm_setr_epi8(10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1);
    const __m128i by100 = _mm_setr_epi16(100, 1, 100, 1, 100, 1, 100, 1);
    const __m128i by10k = _mm_setr_epi16(10000, 1, 10000, 1, 10000, 1, 10000, 1);
    __m128i l4 = _mm_madd_epi16(_mm_maddubs_epi16(field[0], by10), by100);
    __m128i h4 = _mm_madd_epi16(_mm_maddubs_epi16(field[1], by10), by100);
    __m128i g8 = _mm_madd_epi16(_mm_packus_epi32(l4, h4), by10k);
    std::uint64_t w = (std::uint64_t(std::uint32_t(_mm_extract_epi32(g8, 1))) * 100000000 +
                       std::uint32_t(_mm_extract_epi32(g8, 2))) * 100000000 +
                      std::uint32_t(_mm_extract_epi32(g8, 3));
    fast_float::adjusted_mantissa am =
        fast_float::compute_float<fast_float::binary_format<double>>(-b, w);
    if (am.power2 <= 0 || am.power2 >= 0x7FF) // zero, subnormal, undecided: the scan's cases
        return nullptr;
    fast_float::to_float(negative, am, *out);
    return p + e;
}
#endif

// The number at first (first < last), checked: its end, or NULL if none starts there or it is
// refused (not finite, or an underflow of nonzero digits). Bytes up to readable may be looked at
// (readable >= last), none beyond last taken.
inline const char *parse_checked(const char *first, const char *last, const char *readable,
                                 double *out)
{
    const char *p = first;
    bool negative = *p == '-';
    p += negative;
#if SC_NUMBER_SSE
    if (readable - p >= 32 && __builtin_cpu_supports("sse4.1")) {
        const char *end = parse_sse(p, last, out, negative);
        if (end)
            return end;
    }
#else
    (void)readable;
#endif
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
extern "C" sc_status sc_number_parse_prefix_within(const char *s, const char *end,
                                                   const char *readable, const char **stop,
                                                   double *out)
{
    const char *p = s;
    if (p < end && *p == '+') {
        ++p;
        if (p < end && *p == '-')
            return SC_E_INPUT;
    }
    const char *q = p < end ? parse_checked(p, end, readable, out) : nullptr;
    if (!q)
        return SC_E_INPUT;
    *stop = q;
    return SC_OK;
}

extern "C" sc_status sc_number_parse_prefix(const char *s, const char *end, const char **stop,
                                            double *out)
{
    return sc_number_parse_prefix_within(s, end, end, stop, out);
}

// v finite and nonzero: v = ±digits·10^exp10 with the fewest digits (no trailing zeros).
extern "C" void sc_number_kernel_shortest(double v, std::uint64_t *digits, int *exp10)
{
    auto d = jkj::dragonbox::to_decimal(v);
    *digits = d.significand;
    *exp10 = d.exponent;
}
