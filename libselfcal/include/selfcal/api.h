/* selfcal/api.h — SC_API, the mark of the library's public functions.
 *
 * The library is compiled with -fvisibility=hidden: only declarations marked SC_API are exported
 * from libselfcal.so; everything else stays internal to the library (and reachable from the
 * static libselfcal.a, which the unit tests use). Freestanding: no other header needed, so the
 * correction core keeps building for microcontrollers.
 */
#ifndef SELFCAL_API_H
#define SELFCAL_API_H

#if defined(__GNUC__) || defined(__clang__)
#define SC_API __attribute__((visibility("default")))
#else
#define SC_API
#endif

#endif
