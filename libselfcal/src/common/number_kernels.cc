// The two conversion kernels of number.c, from well-kept header-only Debian libraries, wrapped
// for C (this is the project's only C++: both libraries are C++ templates):
//   fast_float (libfast-float-dev): D. Lemire's exact decimal -> double (from_chars);
//   Dragonbox (libdragonbox-dev):   J. Jeon's shortest round-trip double -> decimal digits.
// The grammar checks and the text layout are number.c's.
#include <cstdint>
#include <system_error>

#include <dragonbox/dragonbox.h>
#include <fast_float/fast_float.h>

extern "C" int sc_number_kernel_parse(const char *first, const char *last, double *out)
{
    fast_float::from_chars_result r = fast_float::from_chars(first, last, *out);
    return r.ec == std::errc() && r.ptr == last ? 0 : -1;
}

// v finite and nonzero: v = ±digits·10^exp10 with the fewest digits (no trailing zeros).
extern "C" void sc_number_kernel_shortest(double v, std::uint64_t *digits, int *exp10)
{
    auto d = jkj::dragonbox::to_decimal(v);
    *digits = d.significand;
    *exp10 = d.exponent;
}
