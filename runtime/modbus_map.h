/* runtime/modbus_map.h — the one Modbus register map of selfcald (SPEC §4), shared by the TCP and
 * the RTU server: validates a complete request, computes the correction when registers 0-3 are
 * written in one request (function 16 or the write part of 23), refreshes the read-only mirror
 * and builds the response. A function 23 request is handled start to finish before anything else
 * runs, so its read returns its own write's result.
 *
 * The responses are built here, not by libmodbus's modbus_reply: libmodbus 3.1.6 reads two bytes
 * past a one-byte PDU (function 17; fixed upstream in 031293d, not in Debian 12), its function 17
 * answer discloses the library version ("LMB3.1.6"), and its exception reply to a function code
 * >= 0x80 wraps the code (0x85 + 0x80 = 0x05, which reads as a normal function 5 reply). The map
 * is ten registers and five functions; answering them here keeps every read inside the request.
 *
 * Map: holding 0-3 input X/Y (int32 nm, two words each), holding 4-9 = input 0-5 (read-only):
 * corrected X, corrected Y, status bits, corrections mod 65536. Anything else: exception 02.
 * Function 17 (report server id): byte count, the unit id, 0xFF (running), "selfcal". */
#ifndef SELFCALD_MODBUS_MAP_H
#define SELFCALD_MODBUS_MAP_H

#include <stdint.h>

#include "engine.h"

typedef enum sc_word_order {
    SC_WORD_HIGH_FIRST = 0, /* SPEC default: high word in the lower register */
    SC_WORD_LOW_FIRST = 1
} sc_word_order;

#define SC_MB_HOLDING_COUNT 10
#define SC_MB_INPUT_COUNT 6
/* Largest response PDU (function code + data) and ADU (MBAP 7 + PDU, or unit + PDU + CRC). */
#define SC_MB_PDU_MAX 253
#define SC_MB_ADU_MAX 260

/* Exception codes (Modbus application protocol 1.1b3 §7). */
enum {
    SC_MB_EX_ILLEGAL_FUNCTION = 1,
    SC_MB_EX_ILLEGAL_ADDRESS = 2,
    SC_MB_EX_ILLEGAL_VALUE = 3,
    SC_MB_EX_GATEWAY_TARGET = 11
};

typedef struct sc_modbus_map {
    uint16_t holding[SC_MB_HOLDING_COUNT];
    uint16_t input[SC_MB_INPUT_COUNT];
    sc_word_order order;
    uint32_t requests, exceptions, computed;
} sc_modbus_map;

/* The process's one map (static). */
sc_modbus_map *sc_modbus_map_shared(void);

/* Set the word order (the registers are static; nothing is allocated, nothing can fail). */
void sc_modbus_map_open(sc_modbus_map *mm, sc_word_order order);

void sc_modbus_map_close(sc_modbus_map *mm);

/* Answer one request PDU (function code first, plen >= 1 bytes) into rsp (SC_MB_PDU_MAX bytes):
 * a normal response or an exception (function | 0x80, code). unit_id is reported by function
 * 17. Returns the response PDU length (>= 2), or -1 if plen < 1. No I/O. */
int sc_modbus_map_answer(sc_modbus_map *mm, uint8_t unit_id, const uint8_t *pdu, int plen,
                         sc_engine *e, uint8_t *rsp);

/* Frame a response PDU as the ADU answering req (hdr_len 7: MBAP with req's transaction id and
 * unit; hdr_len 1: RTU, req's unit and a CRC) into adu (SC_MB_ADU_MAX bytes); returns its length. */
int sc_modbus_frame(const uint8_t *req, int hdr_len, const uint8_t *rsp, int rlen, uint8_t *adu);

/* Answer one complete request ADU of len bytes and send the response on fd. hdr_len: 7 for TCP
 * (MBAP; fd a socket), 1 for RTU (unit id; fd the serial line); trailer_len: 0 for TCP, 2 for RTU
 * (the CRC, already checked by the caller). Returns the bytes sent, or -1 if sending failed or
 * was short (the caller drops the connection). */
int sc_modbus_map_reply(sc_modbus_map *mm, int fd, const uint8_t *req, int len, int hdr_len,
                        int trailer_len, sc_engine *e);

/* Send the exception `code` answering req (framed as for sc_modbus_map_reply). Bytes or -1. */
int sc_modbus_reply_exception(int fd, const uint8_t *req, int hdr_len, unsigned code);

/* The Modbus RTU CRC-16 of n bytes (to be sent low byte first). */
uint16_t sc_modbus_crc16(const uint8_t *p, int n);
/* One more byte into a running CRC-16 (start from 0xffff). */
uint16_t sc_modbus_crc16_update(uint16_t crc, uint8_t byte);

/* Split an int32 into two registers in the given word order, and back. */
void sc_mb_put_i32(uint16_t *regs, int32_t v, sc_word_order order);
int32_t sc_mb_get_i32(const uint16_t *regs, sc_word_order order);

#endif
