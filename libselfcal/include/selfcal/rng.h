/* selfcal/rng.h — a small seeded random generator (xoshiro256**) for reproducible simulations.
 * The state is the caller's; the same seed gives the same sequence on every platform. */
#ifndef SELFCAL_RNG_H
#define SELFCAL_RNG_H

#include "selfcal/api.h"

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_rng {
    uint64_t s[4];
    int has_spare;
    double spare;
} sc_rng;

/* Seed the generator (any 64-bit value, 0 included). */
SC_API void sc_rng_seed(sc_rng *r, uint64_t seed);

/* Next raw 64-bit value. */
SC_API uint64_t sc_rng_u64(sc_rng *r);

/* Uniform on [0, 1). */
SC_API double sc_rng_uniform(sc_rng *r);

/* Standard normal N(0, 1) (Marsaglia polar method). */
SC_API double sc_rng_normal(sc_rng *r);

#ifdef __cplusplus
}
#endif
#endif
