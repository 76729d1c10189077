/* runtime/engine.h — what every transport of selfcald shares: the loaded table, the mode, the
 * status word, the counters and the last correction (the one register map of SPEC §4).
 * Static storage only: the two table slots and the file buffer live in engine.c; nothing here
 * allocates, at start or later. */
#ifndef SELFCALD_ENGINE_H
#define SELFCALD_ENGINE_H

#include <stdint.h>

#include "selfcal/correct.h"
#include "selfcal/error.h" /* sc_status, sc_error: the library's one error convention */

/* Status bit beyond SC_CORR_ST_* (an extension of SPEC §4: bit 3): the last reload failed and
 * the previous table is still in use. Cleared by the next successful load. */
#define SC_ENGINE_ST_RELOAD_FAILED 0x08u

/* Largest table file selfcald reads (bytes); a larger file is refused. */
#ifndef SC_ENGINE_MAX_TABLE_BYTES
#define SC_ENGINE_MAX_TABLE_BYTES (2u * 1024u * 1024u)
#endif

typedef struct sc_engine {
    const sc_corr_table *table; /* the table in use (one of two static slots; swapped on reload) */
    sc_corr_mode mode;
    uint16_t status;            /* SC_CORR_ST_* bits of the last correction, plus LOADED */
    uint32_t corrections;       /* corrections since start */
    uint32_t reload_ok, reload_failed; /* reloads (SIGHUP) that swapped tables in / were refused */
    int32_t last_in_x_nm, last_in_y_nm;   /* input of the last correction */
    int32_t last_out_x_nm, last_out_y_nm; /* its result */
    /* Plausibility bounds (0 = none): a table that can command a larger correction of one
     * coordinate, or a steeper change between neighbouring nodes, is refused (sc_corr_bounds). */
    double max_correction_um, max_gradient_um_per_mm;
} sc_engine;

/* Reset e (no table, measure mode, counters zero). */
void sc_engine_init(sc_engine *e, sc_corr_mode mode);

/* Read the table file at path into the spare static slot and validate it with sc_corr_load and
 * the engine's plausibility bounds; swap it in only if it is valid and within them. SC_OK, or SC_E_INPUT (not a valid table) / SC_E_IO (cannot be
 * read) with err naming the file and the reason (the old table, if any, stays in use, and
 * SC_ENGINE_ST_RELOAD_FAILED is set in the status). Allocation-free: open/read into a static
 * buffer. Not reentrant (one engine per process). */
sc_status sc_engine_load_file(sc_engine *e, const char *path, sc_error *err);

/* Correct one X/Y position in nanometres; updates status and counters; returns the status bits.
 * The result is rounded to the nearest nm and saturated to int32 (saturation sets
 * SC_CORR_ST_INVALID). Without a loaded table the output equals the input and LOADED is clear. */
uint16_t sc_engine_correct(sc_engine *e, int32_t x_nm, int32_t y_nm, int32_t *out_x_nm,
                           int32_t *out_y_nm);

/* Convert a value in mm to nm, rounded to nearest, saturated to int32; *saturated set to 1 when
 * the value did not fit (or was not finite). */
int32_t sc_engine_mm_to_nm(double v_mm, int *saturated);

#endif
