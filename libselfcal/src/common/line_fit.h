/* line_fit.h — the least-squares straight line through points (k, v), shared inside the library
 * (not installed): io/ judges the regular spacing of positions read from a file with it, lut/
 * takes a profile's start and step from it. A home of its own in common/ so that lut/ needs no
 * private header of io/. */
#ifndef SELFCAL_LINE_FIT_H
#define SELFCAL_LINE_FIT_H

#include <stddef.h>

/* v ≈ a + b·k over the n points (any order; n >= 1). b = 0 when every k is the same. */
void sc_line_fit(const double *k, const double *v, size_t n, double *a, double *b);

#endif
