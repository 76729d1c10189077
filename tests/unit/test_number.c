/* Unit tests of the number module (selfcal/number.h): the parser agrees bit for bit with glibc's
 * strtod (C locale) on many random decimal strings, including near-halfway and 17-25 digit
 * ones; the formatter's text reads back to the same double, has the fewest digits that do, and is
 * laid out as printf("%.17g") lays out its digits; the grammar is strict. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"
#include "selfcal/number.h"
#include "selfcal/rng.h"
#include "../../libselfcal/src/common/number_internal.h" /* parsing inside a larger buffer */

static uint64_t next_bits(sc_rng *r)
{
    uint64_t a = (uint64_t)(sc_rng_uniform(r) * 4294967296.0);
    uint64_t b = (uint64_t)(sc_rng_uniform(r) * 4294967296.0);
    return a << 32 | b;
}

static double random_double(sc_rng *r)
{
    for (;;) {
        uint64_t u = next_bits(r);
        double v;
        memcpy(&v, &u, sizeof v);
        if (isfinite(v) && (v == 0 || fabs(v) >= DBL_MIN))
            return v;
    }
}

/* A value of one of three kinds: 0 random bits, 1 few digits (as measurements have), 2 the
 * result of arithmetic, of any magnitude. */
static double sample_value(sc_rng *r, int kind)
{
    if (kind == 0)
        return random_double(r);
    if (kind == 1)
        return round(sc_rng_normal(r) * 1e6) / pow(10, (int)(sc_rng_uniform(r) * 12));
    return sc_rng_normal(r) * pow(10, (int)(sc_rng_uniform(r) * 40) - 20);
}

static int parse_str(const char *s, double *v)
{
    return sc_number_parse(s, strlen(s), v);
}

static void same_bits(double a, double b)
{
    assert_memory_equal(&a, &b, sizeof a);
}

static void test_format_round_trip(void **st)
{
    (void)st;
    sc_rng r;
    sc_rng_seed(&r, 2026);
    char buf[SC_NUMBER_BUF], ref[64];
    for (int t = 0; t < 300000; ++t) {
        double v = sample_value(&r, t % 3);
        int len = sc_number_format(v, buf);
        assert_int_equal(len, (int)strlen(buf));
        assert_true(len < SC_NUMBER_BUF);
        /* exact round trip, by glibc's strtod and by our parser */
        same_bits(strtod(buf, NULL), v);
        double back;
        assert_int_equal(parse_str(buf, &back), 0);
        same_bits(back, v);
        /* the fewest digits: one digit less does not round-trip */
        int k = 0;
        for (const char *p = buf; *p && *p != 'e'; ++p)
            k += *p >= '0' && *p <= '9';
        const char *q = buf + (buf[0] == '-');
        while (*q == '0' || *q == '.') /* leading zeros of 0.000ddd do not count */
            k -= *q == '0', ++q;
        if (strchr(buf, 'e') == NULL && strchr(buf, '.') == NULL) /* trailing zeros of integers */
            for (const char *p = buf + strlen(buf) - 1; p > q && *p == '0'; --p)
                k--;
        assert_true(k >= 1 && k <= 17);
        if (k > 1) {
            snprintf(ref, sizeof ref, "%.*e", k - 2, v);
            assert_true(strtod(ref, NULL) != v);
        }
        /* printf's layout of the same digits */
        snprintf(ref, sizeof ref, "%.*g", 17, v);
        double pv = strtod(ref, NULL);
        same_bits(pv, v);
        int exp_ref = strchr(ref, 'e') != NULL, exp_ours = strchr(buf, 'e') != NULL;
        assert_int_equal(exp_ours, exp_ref);
    }
}

static void test_format_special(void **st)
{
    (void)st;
    char buf[SC_NUMBER_BUF];
    const struct {
        double v;
        const char *s;
    } cases[] = {{0.0, "0"},          {-0.0, "-0"},       {1.0, "1"},
                 {0.1, "0.1"},        {-2.5, "-2.5"},     {100000, "100000"},
                 {1e16, "10000000000000000"}, {1e17, "1e+17"}, {1.5e-7, "1.5e-07"},
                 {0.0001, "0.0001"},  {0.00001, "1e-05"}, {1e300, "1e+300"},
                 {DBL_MAX, "1.7976931348623157e+308"}, {5e-324, "5e-324"},
                 {1.0 / 3, "0.3333333333333333"}, {123.456, "123.456"}};
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        sc_number_format(cases[i].v, buf);
        assert_string_equal(buf, cases[i].s);
    }
    sc_number_format(NAN, buf);
    assert_string_equal(buf + (buf[0] == '-'), "nan");
    sc_number_format(-INFINITY, buf);
    assert_string_equal(buf, "-inf");
}

static void test_parse_vs_strtod(void **st)
{
    (void)st;
    sc_rng r;
    sc_rng_seed(&r, 11);
    char s[96];
    for (int t = 0; t < 300000; ++t) {
        int len = 0;
        if (sc_rng_uniform(&r) < 0.3)
            s[len++] = sc_rng_uniform(&r) < 0.5 ? '-' : '+';
        int nd = 1 + (int)(sc_rng_uniform(&r) * 25), dot = (int)(sc_rng_uniform(&r) * (nd + 1));
        for (int i = 0; i < nd; ++i) {
            if (i == dot)
                s[len++] = '.';
            s[len++] = (char)('0' + (int)(sc_rng_uniform(&r) * 10));
        }
        if (sc_rng_uniform(&r) < 0.5)
            len += snprintf(s + len, sizeof s - len, "e%d", (int)(sc_rng_uniform(&r) * 600) - 300);
        s[len] = '\0';
        if (t % 4 == 0) /* the texts printf writes: halfway and near-halfway cases */
            snprintf(s, sizeof s, "%.*e", (int)(sc_rng_uniform(&r) * 20), random_double(&r));
        double ours, ref = strtod(s, NULL);
        int rc = parse_str(s, &ours);
        if (isfinite(ref) && (ref == 0 || fabs(ref) >= DBL_MIN)) {
            if (rc != 0 && ref == 0) /* "0e-400"-like zeros parse; nonzero underflow is refused */
                fail_msg("refused %s", s);
            if (rc == 0)
                same_bits(ours, ref);
            else
                fail_msg("refused %s", s);
        } else {
            /* overflow, or underflow of nonzero digits: refused */
            int nonzero = 0;
            for (const char *p = s; *p && *p != 'e'; ++p)
                nonzero |= *p >= '1' && *p <= '9';
            if (nonzero)
                assert_int_equal(rc, SC_E_INPUT);
        }
    }
}

static void test_parse_grammar(void **st)
{
    (void)st;
    double v;
    const char *good[] = {"0", "-0", "+1", "1.", ".5", "-.5e3", "1E5", "1e+05", "00012.500", "0e-999"};
    const double val[] = {0, -0.0, 1, 1, 0.5, -500, 1e5, 1e5, 12.5, 0};
    for (size_t i = 0; i < sizeof good / sizeof *good; ++i) {
        assert_int_equal(parse_str(good[i], &v), 0);
        same_bits(v, val[i]);
    }
    const char *bad[] = {"",    "-",    "+",   ".",    "e5",  "1e",   "1e+",  "1.5.2", " 1",
                         "1 ",  "1,5",  "0x10", "inf", "nan", "-inf", "1e999", "1e-999", "1d5",
                         "--1", "+-1",  "1e5.5", "١"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i)
        assert_int_equal(parse_str(bad[i], &v), SC_E_INPUT);
    /* only the given bytes count (no NUL needed) */
    assert_int_equal(sc_number_parse("12345", 3, &v), 0);
    assert_true(v == 123);
}

/* sc_number_parse_prefix over the whole of a string literal (one object, so begin and end belong
 * to the same array). */
static sc_status parse_prefix_whole(const char *s, const char **stop, double *v)
{
    return sc_number_parse_prefix(s, s + strlen(s), stop, v);
}

/* The prefix parser ends a number where the grammar ends, with the value the whole-text parser
 * gives that number alone: random fields (of every length, so the eight-byte scan meets every
 * split) followed by a byte that ends them or that could continue them. */
static void test_parse_prefix(void **st)
{
    (void)st;
    sc_rng r;
    sc_rng_seed(&r, 17);
    const char after[] = ",\n x.e-+5";
    char s[96];
    for (int t = 0; t < 200000; ++t) {
        int len = 0;
        if (sc_rng_uniform(&r) < 0.3)
            s[len++] = sc_rng_uniform(&r) < 0.5 ? '-' : '+';
        int nd = 1 + (int)(sc_rng_uniform(&r) * 24), dot = (int)(sc_rng_uniform(&r) * (nd + 2));
        for (int i = 0; i < nd; ++i) {
            if (i == dot)
                s[len++] = '.';
            s[len++] = (char)('0' + (int)(sc_rng_uniform(&r) * 10));
        }
        if (sc_rng_uniform(&r) < 0.2)
            len += snprintf(s + len, sizeof s - len, "e%d", (int)(sc_rng_uniform(&r) * 80) - 40);
        int field = len;
        int tail = (int)(sc_rng_uniform(&r) * 12);
        for (int i = 0; i < tail; ++i)
            s[len++] = after[(int)(sc_rng_uniform(&r) * (sizeof after - 1))];
        s[len] = '\0';
        double whole, pre;
        const char *stop = NULL;
        int rc = sc_number_parse_prefix(s, s + len, &stop, &pre);
        /* the longest prefix the whole-text parser takes is where the prefix parser stops */
        int longest = -1;
        for (int k = len; k >= 1 && longest < 0; --k)
            if (sc_number_parse(s, (size_t)k, &whole) == 0)
                longest = k;
        if (rc == 0) {
            assert_true(longest >= field);
            assert_int_equal((int)(stop - s), longest);
            same_bits(pre, whole);
        } else {
            /* refused: the field itself is, or the tail continues it into something refused */
            int continues = field < len && strchr("0123456789.eE", s[field]) != NULL;
            if (sc_number_parse(s, (size_t)field, &whole) == 0 && !continues)
                fail_msg("prefix refused '%s' (field of %d bytes)", s, field);
        }
    }
    double v;
    const char *stop;
    assert_int_equal(parse_prefix_whole("2.5,", &stop, &v), 0);
    assert_true(v == 2.5 && *stop == ',');
    assert_int_equal(parse_prefix_whole("1e,", &stop, &v), 0);
    assert_true(v == 1 && *stop == 'e');
    assert_int_equal(parse_prefix_whole(",1", &stop, &v), SC_E_INPUT);
    assert_int_equal(parse_prefix_whole("inf,", &stop, &v), SC_E_INPUT);
    assert_int_equal(parse_prefix_whole("1e-400,", &stop, &v), SC_E_INPUT);
    assert_int_equal(parse_prefix_whole("0e-400,", &stop, &v), 0);
}

/* A random number text at s (sign, 1..25 digits with the point anywhere or nowhere, sometimes an
 * exponent), as the parser tests above write them; its length. */
static int random_number_text(sc_rng *r, char *s, size_t cap)
{
    int len = 0;
    if (sc_rng_uniform(r) < 0.3)
        s[len++] = sc_rng_uniform(r) < 0.8 ? '-' : '+';
    int nd = 1 + (int)(sc_rng_uniform(r) * 25), dot = (int)(sc_rng_uniform(r) * (nd + 2));
    if (sc_rng_uniform(r) < 0.5) /* the writers' shape: 1-3 digits, the point, the rest */
        dot = 1 + (int)(sc_rng_uniform(r) * 3);
    for (int i = 0; i < nd; ++i) {
        if (i == dot)
            s[len++] = '.';
        s[len++] = (char)('0' + (int)(sc_rng_uniform(r) * (i == 0 && sc_rng_uniform(r) < 0.3 ? 1 : 10)));
    }
    if (sc_rng_uniform(r) < 0.1)
        len += snprintf(s + len, cap - (size_t)len, "%c%d", sc_rng_uniform(r) < 0.5 ? 'e' : 'E',
                        (int)(sc_rng_uniform(r) * 80) - 40);
    if (sc_rng_uniform(r) < 0.25) /* the writers' own texts */
        len = sc_number_format(sample_value(r, (int)(sc_rng_uniform(r) * 3)), s);
    s[len] = '\0';
    return len;
}

/* The fast path for long buffers (number_kernels.cc: 32 bytes readable from the number on) gives
 * what the scan gives on the same number alone: the same end, the same bits (strtod's), the same
 * refusals; and it never takes a byte past the text's end when it may read beyond it. */
static void test_parse_long_buffers(void **st)
{
    (void)st;
    sc_rng r;
    sc_rng_seed(&r, 23);
    const char tail_bytes[] = "0123456789.,eE-+\n x";
    char s[160], alone[64];
    for (int t = 0; t < 300000; ++t) {
        int len = random_number_text(&r, s, sizeof s);
        int total = len;
        s[total++] = ",\n x"[(int)(sc_rng_uniform(&r) * 4)]; /* what ends a field */
        for (int i = 0; i < 40; ++i)
            s[total++] = tail_bytes[(int)(sc_rng_uniform(&r) * (sizeof tail_bytes - 1))];
        s[total] = '\0';
        memcpy(alone, s, (size_t)len + 1);
        alone[len + 1] = '\0';
        double in_long = 0, by_itself = 0;
        const char *stop_long = NULL, *stop_alone = NULL;
        int rc_long = sc_number_parse_prefix(s, s + total, &stop_long, &in_long);
        int rc_alone = sc_number_parse_prefix(alone, alone + len + 1, &stop_alone, &by_itself);
        assert_int_equal(rc_long, rc_alone);
        if (rc_long != 0)
            continue;
        assert_int_equal((int)(stop_long - s), (int)(stop_alone - alone));
        same_bits(in_long, by_itself);
        if (stop_long - s == len) {
            s[len] = '\0';
            double ref = strtod(s, NULL);
            same_bits(in_long, ref);
        }
        /* the text cut anywhere inside, the rest of the buffer readable: as if it ended there */
        int cut = 1 + (int)(sc_rng_uniform(&r) * len);
        double within = 0, short_text = 0;
        const char *stop_within = NULL, *stop_short = NULL;
        int rc_within = sc_number_parse_prefix_within(s, s + cut, s + total, &stop_within, &within);
        int rc_short = sc_number_parse_prefix(s, s + cut, &stop_short, &short_text);
        assert_int_equal(rc_within, rc_short);
        if (rc_within == 0) {
            assert_ptr_equal(stop_within, stop_short);
            same_bits(within, short_text);
        }
    }
}

/* sc_parse_long (csv.h) agrees with strtol(s, 10) on whole numbers, and refuses what it refuses. */
static void test_parse_long(void **st)
{
    (void)st;
    char s[64];
    long v;
    const char *edge[] = {"9223372036854775807", "-9223372036854775808", "0", "-0", "+12", " 7"};
    for (size_t i = 0; i < sizeof edge / sizeof *edge; ++i) {
        assert_int_equal(sc_parse_long(edge[i], &v), 0);
        assert_true(v == strtol(edge[i], NULL, 10));
    }
    const char *bad[] = {"9223372036854775808", "-9223372036854775809", "", "-", "1.0", "1e3",
                         "12 ", "0x10", "+-1"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i)
        assert_int_equal(sc_parse_long(bad[i], &v), SC_E_INPUT);
    sc_rng r;
    sc_rng_seed(&r, 3);
    for (int t = 0; t < 100000; ++t) {
        long x = (long)(next_bits(&r) >> (int)(sc_rng_uniform(&r) * 63));
        if (sc_rng_uniform(&r) < 0.5)
            x = -x;
        snprintf(s, sizeof s, "%ld", x);
        assert_int_equal(sc_parse_long(s, &v), 0);
        assert_true(v == x);
    }
}

/* sc_number_format_15g against glibc's printf, byte for byte: random bits, measurement-like
 * values, arithmetic results of every magnitude, the decades' edges (9.99...95 rounding up to
 * the next power of ten), exact ties at the 16th digit (halves of integers near 10^15 and
 * dyadic fractions) and the specials. */
static void test_format_15g_vs_printf(void **st)
{
    (void)st;
    sc_rng r;
    sc_rng_seed(&r, 15);
    char buf[SC_NUMBER_BUF], ref[64];
    for (int t = 0; t < 400000; ++t) {
        double v;
        switch (t % 6) {
        case 0:
        case 1:
        case 2: v = sample_value(&r, t % 6); break;
        case 3: /* around 10^k - 5·10^(k-16): where rounding carries into a new decade */
            v = pow(10, (int)(sc_rng_uniform(&r) * 30) - 12) * (1 - 5e-16);
            v = nextafter(v, (t / 6) % 2 ? INFINITY : 0);
            for (int s = (int)(sc_rng_uniform(&r) * 4); s > 0; --s)
                v = nextafter(v, (t / 12) % 2 ? INFINITY : 0);
            break;
        case 4: /* d.ddd...d5 at the 16th digit, exact: an odd integer / 2 near 10^15 */
            v = (double)(2 * (uint64_t)(1e14 + sc_rng_uniform(&r) * 9e14) + 1) / 2 /
                ((t / 6) % 2 ? 1 : 8);
            break;
        default: /* small dyadic values: exact decimal expansions ending in 5 */
            v = ldexp((double)(int64_t)(sc_rng_normal(&r) * 1e9), -(int)(sc_rng_uniform(&r) * 60));
            break;
        }
        int len = sc_number_format_15g(v, buf);
        snprintf(ref, sizeof ref, "%.15g", v);
        if (strcmp(buf, ref) != 0)
            fail_msg("%.17g: %s, printf %s", v, buf, ref);
        assert_int_equal(len, (int)strlen(buf));
    }
    const double special[] = {0.0, -0.0, 1.0, -1.0, 1e15, 1e-5, 1e-4, 9.99999999999999e14,
                              999999999999999.5, 0.5, 123456789012345.5, 1e300, 5e-324,
                              2.2250738585072014e-308, INFINITY, -INFINITY, NAN, 4.8e-7,
                              4.76837158203125e-7, 4503599627370496.0, 4503599627370495.5};
    for (size_t k = 0; k < sizeof special / sizeof special[0]; ++k) {
        sc_number_format_15g(special[k], buf);
        snprintf(ref, sizeof ref, "%.15g", special[k]);
        assert_string_equal(buf, ref);
    }
}

void sc_number_kernel_shortest(double v, uint64_t *digits, int *exp10); /* number_kernels.cc */

/* An integral value below 2^53 skips the shortest-digit search: its text must be what the search
 * gives (the integer's digits), printf's "%.0f", and round-trip, near 2^53 and at every length;
 * 2^53 and above go through the search. */
static void test_format_integers(void **st)
{
    (void)st;
    sc_rng r;
    sc_rng_seed(&r, 53);
    char buf[SC_NUMBER_BUF], ref[64];
    for (int t = 0; t < 400000; ++t) {
        double v;
        int kind = t % 4;
        if (kind == 0) /* any length up to 2^53 */
            v = (double)(next_bits(&r) >> (11 + (int)(sc_rng_uniform(&r) * 53)));
        else if (kind == 1) /* just below and above 2^53 */
            v = 0x1p53 + (double)((long)(sc_rng_uniform(&r) * 2000) - 1000) * 2;
        else if (kind == 2) /* round numbers: trailing zeros */
            v = round(sc_rng_uniform(&r) * 1000) * pow(10, (int)(sc_rng_uniform(&r) * 14));
        else /* positions on a pitch: i·s */
            v = (double)(long)(sc_rng_uniform(&r) * 2e6) * (sc_rng_uniform(&r) < 0.5 ? 1.0 : 25.0);
        if (t % 7 == 0)
            v = -v;
        int len = sc_number_format(v, buf);
        assert_int_equal(len, (int)strlen(buf));
        double back;
        assert_int_equal(parse_str(buf, &back), 0);
        same_bits(back, v);
        if (v == 0)
            continue;
        uint64_t m;
        int e;
        sc_number_kernel_shortest(fabs(v), &m, &e);
        if (fabs(v) < 0x1p53) { /* the search's digits, laid out as the integer printf writes */
            assert_true(e >= 0);
            for (int k = 0; k < e; ++k)
                m *= 10;
            assert_true((double)m == fabs(v));
            snprintf(ref, sizeof ref, "%.0f", v);
            assert_string_equal(buf, ref);
        }
    }
}

/* sc_number_put_u64 and its scratch bytes: the digits printf writes, nothing past p + 17. */
static void test_put_u64(void **st)
{
    (void)st;
    char buf[64], ref[32];
    uint64_t edge[] = {0, 1, 9, 10, 99999999, 100000000, 9999999999999999ULL,
                       10000000000000000ULL, 99999999999999999ULL, 100000000000000000ULL,
                       UINT64_MAX};
    sc_rng r;
    sc_rng_seed(&r, 64);
    for (int t = 0; t < 200000; ++t) {
        uint64_t u = t < (int)(sizeof edge / sizeof *edge)
                         ? edge[t]
                         : next_bits(&r) >> (int)(sc_rng_uniform(&r) * 64);
        memset(buf, 'x', sizeof buf);
        char *end = sc_number_put_u64(buf + 8, u);
        snprintf(ref, sizeof ref, "%llu", (unsigned long long)u);
        assert_int_equal(end - (buf + 8), (int)strlen(ref));
        assert_memory_equal(buf + 8, ref, strlen(ref));
        for (int k = 0; k < 8; ++k)
            assert_int_equal(buf[k], 'x');
        for (int k = 8 + 18 > (int)(end - buf) ? 8 + 18 : (int)(end - buf); k < 64; ++k)
            assert_int_equal(buf[k], 'x');
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_format_round_trip),
        cmocka_unit_test(test_format_special),
        cmocka_unit_test(test_format_integers),
        cmocka_unit_test(test_put_u64),
        cmocka_unit_test(test_format_15g_vs_printf),
        cmocka_unit_test(test_parse_vs_strtod),
        cmocka_unit_test(test_parse_grammar),
        cmocka_unit_test(test_parse_prefix),
        cmocka_unit_test(test_parse_long_buffers),
        cmocka_unit_test(test_parse_long),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
