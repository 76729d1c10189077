/* runtime/modbus_map.h — the one Modbus register map of selfcald (SPEC §4), shared by the TCP and
 * the RTU server: validates a complete request, computes the correction when registers 0-3 are
 * written in one request (function 16 or the write part of 23), refreshes the read-only mirror
 * and answers with libmodbus (modbus_reply / modbus_reply_exception). A function 23 request is
 * handled start to finish before anything else runs, so its read returns its own write's result.
 *
 * Map: holding 0-3 input X/Y (int32 nm, two words each), holding 4-9 = input 0-5 (read-only):
 * corrected X, corrected Y, status bits, corrections mod 65536. Anything else: exception 02. */
#ifndef SELFCALD_MODBUS_MAP_H
#define SELFCALD_MODBUS_MAP_H

#include <stdint.h>

#include <modbus/modbus.h>

#include "engine.h"

typedef enum sc_word_order {
    SC_WORD_HIGH_FIRST = 0, /* SPEC default: high word in the lower register */
    SC_WORD_LOW_FIRST = 1
} sc_word_order;

#define SC_MB_HOLDING_COUNT 10
#define SC_MB_INPUT_COUNT 6

typedef struct sc_modbus_map {
    modbus_mapping_t *m; /* allocated once at start */
    sc_word_order order;
    uint32_t requests, exceptions, computed;
} sc_modbus_map;

/* The process's one map (static). Opened on first call of sc_modbus_map_open. */
sc_modbus_map *sc_modbus_map_shared(void);

/* Allocate the libmodbus mapping (start-up only). 0 or -1. Idempotent. */
int sc_modbus_map_open(sc_modbus_map *mm, sc_word_order order);

void sc_modbus_map_close(sc_modbus_map *mm);

/* Answer one complete request ADU of len bytes. hdr_len: 7 for TCP (MBAP), 1 for RTU (unit id);
 * trailer_len: 0 for TCP, 2 for RTU (the CRC, already checked by the caller). The reply goes out through ctx (its socket set by the caller). Returns the bytes
 * sent (0 for a broadcast), or -1 if sending failed (the caller drops the connection). */
int sc_modbus_map_reply(sc_modbus_map *mm, modbus_t *ctx, const uint8_t *req, int len,
                        int hdr_len, int trailer_len, sc_engine *e);

/* Split an int32 into two registers in the given word order, and back. */
void sc_mb_put_i32(uint16_t *regs, int32_t v, sc_word_order order);
int32_t sc_mb_get_i32(const uint16_t *regs, sc_word_order order);

#endif
