/* runtime/modbus_map.c — SPEC §4 register map: requests validated before anything changes,
 * responses built here (see modbus_map.h for why not by libmodbus). */
#include "modbus_map.h"

#include <errno.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

/* Quantity limits of the Modbus application protocol (1.1b3 §6). */
#define MB_MAX_READ 125
#define MB_MAX_WRITE 123
#define MB_MAX_WR_READ 125
#define MB_MAX_WR_WRITE 121

enum {
    FC_READ_COILS = 0x01,
    FC_READ_DISCRETE_INPUTS = 0x02,
    FC_READ_HOLDING = 0x03,
    FC_READ_INPUT = 0x04,
    FC_WRITE_SINGLE_COIL = 0x05,
    FC_WRITE_SINGLE_REGISTER = 0x06,
    FC_WRITE_MULTIPLE_COILS = 0x0f,
    FC_WRITE_MULTIPLE_REGISTERS = 0x10,
    FC_REPORT_SERVER_ID = 0x11,
    FC_MASK_WRITE_REGISTER = 0x16,
    FC_WRITE_AND_READ_REGISTERS = 0x17
};

static const char k_server_id[] = "selfcal";

static sc_modbus_map g_map;

sc_modbus_map *sc_modbus_map_shared(void)
{
    return &g_map;
}

void sc_modbus_map_open(sc_modbus_map *mm, sc_word_order order)
{
    mm->order = order;
}

void sc_modbus_map_close(sc_modbus_map *mm)
{
    (void)mm;
}

void sc_mb_put_i32(uint16_t *regs, int32_t v, sc_word_order order)
{
    uint32_t u = (uint32_t)v;
    uint16_t hi = (uint16_t)(u >> 16), lo = (uint16_t)(u & 0xffffu);
    regs[0] = order == SC_WORD_HIGH_FIRST ? hi : lo;
    regs[1] = order == SC_WORD_HIGH_FIRST ? lo : hi;
}

int32_t sc_mb_get_i32(const uint16_t *regs, sc_word_order order)
{
    uint32_t hi = order == SC_WORD_HIGH_FIRST ? regs[0] : regs[1];
    uint32_t lo = order == SC_WORD_HIGH_FIRST ? regs[1] : regs[0];
    return (int32_t)((hi << 16) | lo);
}

uint16_t sc_modbus_crc16_update(uint16_t crc, uint8_t byte)
{
    crc ^= byte;
    for (int b = 0; b < 8; b++)
        crc = (crc & 1) ? (uint16_t)((crc >> 1) ^ 0xa001) : (uint16_t)(crc >> 1);
    return crc;
}

uint16_t sc_modbus_crc16(const uint8_t *p, int n)
{
    uint16_t crc = 0xffff;
    for (int i = 0; i < n; i++)
        crc = sc_modbus_crc16_update(crc, p[i]);
    return crc;
}

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)((p[0] << 8) | p[1]);
}

static void put_be16(uint8_t *p, unsigned v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)(v & 0xffu);
}

/* Mirror the engine's last correction into input 0-5 and holding 4-9. */
static void refresh(sc_modbus_map *mm, const sc_engine *e)
{
    uint16_t *in = mm->input;
    sc_mb_put_i32(in + 0, e->last_out_x_nm, mm->order);
    sc_mb_put_i32(in + 2, e->last_out_y_nm, mm->order);
    in[4] = e->status;
    in[5] = (uint16_t)(e->corrections & 0xffffu);
    memcpy(mm->holding + 4, in, SC_MB_INPUT_COUNT * sizeof *in);
}

static int except(sc_modbus_map *mm, unsigned fn, unsigned code, uint8_t *rsp)
{
    mm->exceptions++;
    rsp[0] = (uint8_t)(fn | 0x80u); /* a code >= 0x80 stays itself, never wraps */
    rsp[1] = (uint8_t)code;
    return 2;
}

/* A register range [a, a+n) is a legal write if it lies within 0-3. */
static int write_range_ok(unsigned a, unsigned n)
{
    return n >= 1 && a + n <= 4;
}

static void compute(sc_modbus_map *mm, const uint8_t *vals, sc_engine *e)
{
    uint16_t w[4];
    for (int k = 0; k < 4; k++)
        w[k] = be16(vals + 2 * k);
    int32_t ox, oy;
    sc_engine_correct(e, sc_mb_get_i32(w, mm->order), sc_mb_get_i32(w + 2, mm->order), &ox, &oy);
    mm->computed++;
}

static void store(sc_modbus_map *mm, unsigned addr, unsigned n, const uint8_t *vals)
{
    for (unsigned k = 0; k < n; k++)
        mm->holding[addr + k] = be16(vals + 2 * k);
}

/* fn, byte count, n registers from table starting at addr. */
static int read_regs(uint8_t *rsp, unsigned fn, const uint16_t *table, unsigned addr, unsigned n)
{
    rsp[0] = (uint8_t)fn;
    rsp[1] = (uint8_t)(2 * n);
    for (unsigned k = 0; k < n; k++)
        put_be16(rsp + 2 + 2 * k, table[addr + k]);
    return 2 + 2 * (int)n;
}

/* One handler per served function code: the PDU in, the response PDU out, its length as the
 * result. Length and value checks first (exception 03: a PDU longer or shorter than its function
 * and counts say, as a trailing byte after a read), then addresses (02); nothing changes
 * until the whole request is known to be good. */
static int answer_read(sc_modbus_map *mm, unsigned fn, const uint8_t *pdu, int plen,
                       sc_engine *e, uint8_t *rsp)
{
    if (plen != 5)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    unsigned addr = be16(pdu + 1), n = be16(pdu + 3);
    unsigned size = fn == FC_READ_HOLDING ? SC_MB_HOLDING_COUNT : SC_MB_INPUT_COUNT;
    if (n < 1 || n > MB_MAX_READ)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    if (addr + n > size)
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp);
    refresh(mm, e);
    return read_regs(rsp, fn, fn == FC_READ_HOLDING ? mm->holding : mm->input, addr, n);
}

static int answer_write_single(sc_modbus_map *mm, unsigned fn, const uint8_t *pdu, int plen,
                               sc_engine *e, uint8_t *rsp)
{
    if (plen != 5)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    unsigned addr = be16(pdu + 1);
    if (!write_range_ok(addr, 1))
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp);
    store(mm, addr, 1, pdu + 3);
    refresh(mm, e);
    memcpy(rsp, pdu, 5); /* the echo */
    return 5;
}

static int answer_mask_write(sc_modbus_map *mm, unsigned fn, const uint8_t *pdu, int plen,
                             sc_engine *e, uint8_t *rsp)
{
    if (plen != 7)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    unsigned addr = be16(pdu + 1);
    if (!write_range_ok(addr, 1))
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp);
    unsigned and_mask = be16(pdu + 3), or_mask = be16(pdu + 5);
    mm->holding[addr] =
        (uint16_t)((mm->holding[addr] & and_mask) | (or_mask & ~and_mask & 0xffffu));
    refresh(mm, e);
    memcpy(rsp, pdu, 7);
    return 7;
}

static int answer_write_multiple(sc_modbus_map *mm, unsigned fn, const uint8_t *pdu, int plen,
                                 sc_engine *e, uint8_t *rsp)
{
    if (plen < 6)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    unsigned addr = be16(pdu + 1), n = be16(pdu + 3), bc = pdu[5];
    if (n < 1 || n > MB_MAX_WRITE || bc != 2 * n || plen != 6 + (int)bc)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    if (!write_range_ok(addr, n))
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp);
    if (addr == 0 && n == 4)
        compute(mm, pdu + 6, e);
    store(mm, addr, n, pdu + 6);
    refresh(mm, e);
    memcpy(rsp, pdu, 5); /* fn, address, quantity */
    return 5;
}

static int answer_write_and_read(sc_modbus_map *mm, unsigned fn, const uint8_t *pdu, int plen,
                                 sc_engine *e, uint8_t *rsp)
{
    if (plen < 10)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    unsigned addr = be16(pdu + 1), nr = be16(pdu + 3), wa = be16(pdu + 5), nw = be16(pdu + 7);
    unsigned bc = pdu[9];
    if (nr < 1 || nr > MB_MAX_WR_READ || nw < 1 || nw > MB_MAX_WR_WRITE || bc != 2 * nw ||
        plen != 10 + (int)bc)
        return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
    if (addr + nr > SC_MB_HOLDING_COUNT || !write_range_ok(wa, nw))
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp);
    if (wa == 0 && nw == 4)
        compute(mm, pdu + 10, e);
    store(mm, wa, nw, pdu + 10);
    refresh(mm, e);
    return read_regs(rsp, fn, mm->holding, addr, nr);
}

static int answer_server_id(unsigned fn, uint8_t unit_id, uint8_t *rsp)
{
    const int idlen = (int)sizeof k_server_id - 1;
    rsp[0] = (uint8_t)fn;
    rsp[1] = (uint8_t)(2 + idlen);
    rsp[2] = unit_id;
    rsp[3] = 0xff; /* run indicator: on */
    memcpy(rsp + 4, k_server_id, (size_t)idlen);
    return 4 + idlen;
}

int sc_modbus_map_answer(sc_modbus_map *mm, uint8_t unit_id, const uint8_t *pdu, int plen,
                         sc_engine *e, uint8_t *rsp)
{
    if (plen < 1)
        return -1;
    mm->requests++;
    unsigned fn = pdu[0];
    switch (fn) {
    case FC_READ_COILS:
    case FC_READ_DISCRETE_INPUTS:
    case FC_WRITE_SINGLE_COIL:
        if (plen != 5)
            return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp); /* no coils/inputs */
    case FC_WRITE_MULTIPLE_COILS:
        if (plen < 6 || plen != 6 + pdu[5])
            return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
        return except(mm, fn, SC_MB_EX_ILLEGAL_ADDRESS, rsp);
    case FC_READ_HOLDING:
    case FC_READ_INPUT:
        return answer_read(mm, fn, pdu, plen, e, rsp);
    case FC_WRITE_SINGLE_REGISTER:
        return answer_write_single(mm, fn, pdu, plen, e, rsp);
    case FC_MASK_WRITE_REGISTER:
        return answer_mask_write(mm, fn, pdu, plen, e, rsp);
    case FC_WRITE_MULTIPLE_REGISTERS:
        return answer_write_multiple(mm, fn, pdu, plen, e, rsp);
    case FC_WRITE_AND_READ_REGISTERS:
        return answer_write_and_read(mm, fn, pdu, plen, e, rsp);
    case FC_REPORT_SERVER_ID:
        if (plen != 1)
            return except(mm, fn, SC_MB_EX_ILLEGAL_VALUE, rsp);
        return answer_server_id(fn, unit_id, rsp);
    default:
        return except(mm, fn, SC_MB_EX_ILLEGAL_FUNCTION, rsp);
    }
}

int sc_modbus_frame(const uint8_t *req, int hdr_len, const uint8_t *rsp, int rlen, uint8_t *adu)
{
    if (hdr_len == 7) { /* MBAP: transaction id, protocol 0, length, unit */
        adu[0] = req[0];
        adu[1] = req[1];
        adu[2] = 0;
        adu[3] = 0;
        put_be16(adu + 4, (unsigned)rlen + 1u);
        adu[6] = req[6];
        memcpy(adu + 7, rsp, (size_t)rlen);
        return 7 + rlen;
    }
    adu[0] = req[0]; /* RTU: unit, PDU, CRC low byte first */
    memcpy(adu + 1, rsp, (size_t)rlen);
    uint16_t crc = sc_modbus_crc16(adu, 1 + rlen);
    adu[1 + rlen] = (uint8_t)(crc & 0xffu);
    adu[2 + rlen] = (uint8_t)(crc >> 8);
    return 3 + rlen;
}

static int send_adu(int fd, int hdr_len, const uint8_t *adu, int n)
{
    ssize_t w;
    do {
        w = hdr_len == 7 ? send(fd, adu, (size_t)n, MSG_NOSIGNAL | MSG_DONTWAIT)
                         : write(fd, adu, (size_t)n);
    } while (w < 0 && errno == EINTR);
    return w == (ssize_t)n ? n : -1;
}

int sc_modbus_map_reply(sc_modbus_map *mm, int fd, const uint8_t *req, int len, int hdr_len,
                        int trailer_len, sc_engine *e)
{
    uint8_t rsp[SC_MB_PDU_MAX], adu[SC_MB_ADU_MAX];
    int rlen = sc_modbus_map_answer(mm, req[hdr_len - 1], req + hdr_len,
                                    len - hdr_len - trailer_len, e, rsp);
    if (rlen < 0)
        return -1;
    return send_adu(fd, hdr_len, adu, sc_modbus_frame(req, hdr_len, rsp, rlen, adu));
}

int sc_modbus_reply_exception(int fd, const uint8_t *req, int hdr_len, unsigned code)
{
    uint8_t rsp[2] = {(uint8_t)(req[hdr_len] | 0x80u), (uint8_t)code}, adu[16];
    return send_adu(fd, hdr_len, adu, sc_modbus_frame(req, hdr_len, rsp, 2, adu));
}
