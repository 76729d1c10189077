/* correct_reason.h — private to the correction core: why a table image is refused, finer than
 * the load codes. correct_load.c finds the reason (a byte per check: loading costs nothing more);
 * correct_explain.c holds the sentences, so that a microcontroller build that never calls
 * sc_corr_explain links none of them (1.6 KB of flash). */
#ifndef SELFCAL_CORRECT_REASON_H
#define SELFCAL_CORRECT_REASON_H

#include <stddef.h>

enum {
    SC_CORR_R_OK = 0,
    SC_CORR_R_PROFILE_AXIS,
    SC_CORR_R_PROFILE_ENC,
    SC_CORR_R_PROFILE_RESERVED,
    SC_CORR_R_PROFILE_N,
    SC_CORR_R_PROFILE_EXTENT,
    SC_CORR_R_PROFILE_STEP,
    SC_CORR_R_PROFILE_SCALE,
    SC_CORR_R_SHORT,
    SC_CORR_R_MAGIC,
    SC_CORR_R_VERSION,
    SC_CORR_R_FILE_BYTES,
    SC_CORR_R_CRC,
    SC_CORR_R_HEADER,
    SC_CORR_R_GRID_N,
    SC_CORR_R_PROFILES,
    SC_CORR_R_GRID_ENC,
    SC_CORR_R_ORIGIN,
    SC_CORR_R_PITCH,
    SC_CORR_R_EXTENT,
    SC_CORR_R_GRID_SCALE,
    SC_CORR_R_BLOCKS_PAST_END,
    SC_CORR_R_BLOCKS_FILL,
    SC_CORR_R_METHOD,
    SC_CORR_R_SIGMA,
    SC_CORR_R_SOURCES,
    SC_CORR_R_PROV_SIZE,
    SC_CORR_R_CAP_GRID,
    SC_CORR_R_CAP_PROFILES,
    SC_CORR_R_CAP_POINTS,
    SC_CORR_R_COUNT
};

/* The reason sc_corr_load refuses buf (SC_CORR_R_OK: it would load). */
unsigned sc_corr_check_reason(const void *buf, size_t len);

#endif
