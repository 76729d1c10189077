/* selfcal/number.h — decimal numbers in text files: a strict, exact, locale-free parser and a
 * shortest round-trip formatter. Every reader of numbers (sc_parse_double, sc_csv_double) and the
 * result writers go through these.
 *
 * Parse: [+|-] digits [. digits] [(e|E) [+|-] digits] (at least one mantissa digit; "1." and
 * ".5" are fine), nothing else: no blanks, no hex, no inf/nan, no locale decimal comma. The value
 * is the correctly rounded double (as glibc's strtod in the C locale). Magnitudes that overflow,
 * or that underflow to zero or to a subnormal from nonzero digits, are refused.
 *
 * Format: the fewest significant digits that read back to exactly the same double, laid out as
 * printf's "%.17g" lays them out (fixed for decimal exponents -4..16, else d.ddde±XX); and
 * printf's "%.15g" text exactly, without printf's cost. */
#ifndef SELFCAL_NUMBER_H
#define SELFCAL_NUMBER_H

#include <stddef.h>

#include "selfcal/api.h"
#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Buffer size sc_number_format needs (any formatted double with its NUL is at most 25 bytes; the
 * formatter copies fixed-size runs and may write scratch bytes up to here). */
#define SC_NUMBER_BUF 40

/* Parse the len bytes at s as a whole number (format above): SC_OK and *out set, or SC_E_INPUT. */
SC_API sc_status sc_number_parse(const char *s, size_t len, double *out);

/* Parse the number that starts at s (before end) and ends where the grammar ends (the first byte
 * that cannot continue it, e.g. a comma): SC_OK with *stop just after it and *out set, or
 * SC_E_INPUT (no number there, or refused as above). */
SC_API sc_status sc_number_parse_prefix(const char *s, const char *end, const char **stop,
                                        double *out);

/* Write v's shortest round-trip text and a NUL into buf (SC_NUMBER_BUF bytes); returns the
 * length. NaN and infinities are written as printf writes them ("nan", "-inf", ...). */
SC_API int sc_number_format(double v, char *buf);

/* Write v as printf's "%.15g" writes it in the C locale (byte for byte: 15 significant digits,
 * correctly rounded, ties to even; trailing zeros dropped) and a NUL into buf (SC_NUMBER_BUF
 * bytes); returns the length. The fixed-precision text of the map and residual files. */
SC_API int sc_number_format_15g(double v, char *buf);

#ifdef __cplusplus
}
#endif
#endif
