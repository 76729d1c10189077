/* runtime/engine.h — what every transport of selfcald shares: the loaded table, the mode, the
 * status word and the counters. Static storage only; no allocation after start. */
#ifndef SELFCALD_ENGINE_H
#define SELFCALD_ENGINE_H

#include <stdint.h>

#include "selfcal/correct.h"

typedef struct sc_engine {
    const sc_corr_table *table; /* the table in use (one of two static slots; swapped on reload) */
    sc_corr_mode mode;
    uint16_t status;            /* SC_CORR_ST_* bits of the last correction, plus LOADED */
    uint32_t corrections;       /* corrections since start */
    uint32_t reload_ok, reload_failed;
} sc_engine;

/* Correct one X/Y position in nanometres; updates status and counters; returns the status bits. */
uint16_t sc_engine_correct(sc_engine *e, int32_t x_nm, int32_t y_nm, int32_t *out_x_nm,
                           int32_t *out_y_nm);

#endif
