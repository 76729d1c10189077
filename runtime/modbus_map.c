/* runtime/modbus_map.c — SPEC §4 register map over libmodbus, validated before anything changes. */
#include "modbus_map.h"

#include <string.h>

static sc_modbus_map g_map;

sc_modbus_map *sc_modbus_map_shared(void)
{
    return &g_map;
}

int sc_modbus_map_open(sc_modbus_map *mm, sc_word_order order)
{
    mm->order = order;
    if (mm->m != NULL)
        return 0;
    mm->m = modbus_mapping_new_start_address(0, 0, 0, 0, 0, SC_MB_HOLDING_COUNT, 0,
                                             SC_MB_INPUT_COUNT);
    return mm->m != NULL ? 0 : -1;
}

void sc_modbus_map_close(sc_modbus_map *mm)
{
    if (mm->m != NULL)
        modbus_mapping_free(mm->m);
    mm->m = NULL;
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

static uint16_t be16(const uint8_t *p)
{
    return (uint16_t)((p[0] << 8) | p[1]);
}

/* Mirror the engine's last correction into input 0-5 and holding 4-9. */
static void refresh(sc_modbus_map *mm, const sc_engine *e)
{
    uint16_t *in = mm->m->tab_input_registers;
    sc_mb_put_i32(in + 0, e->last_out_x_nm, mm->order);
    sc_mb_put_i32(in + 2, e->last_out_y_nm, mm->order);
    in[4] = e->status;
    in[5] = (uint16_t)(e->corrections & 0xffffu);
    memcpy(mm->m->tab_registers + 4, in, SC_MB_INPUT_COUNT * sizeof *in);
}

static int except(sc_modbus_map *mm, modbus_t *ctx, const uint8_t *req, unsigned code)
{
    mm->exceptions++;
    return modbus_reply_exception(ctx, req, code);
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

int sc_modbus_map_reply(sc_modbus_map *mm, modbus_t *ctx, const uint8_t *req, int len,
                        int hdr_len, int trailer_len, sc_engine *e)
{
    mm->requests++;
    const uint8_t *pdu = req + hdr_len;
    int plen = len - hdr_len - trailer_len;
    if (plen < 1)
        return -1;
    unsigned fn = pdu[0];
    unsigned addr = plen >= 3 ? be16(pdu + 1) : 0;
    /* Length and value checks first (exception 03), then addresses (02); nothing changes until
     * the whole request is known to be good. */
    switch (fn) {
    case MODBUS_FC_READ_COILS:
    case MODBUS_FC_READ_DISCRETE_INPUTS:
    case MODBUS_FC_WRITE_SINGLE_COIL:
        if (plen < 5)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS); /* no coils/inputs */
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS: {
        if (plen < 5)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        unsigned n = be16(pdu + 3);
        unsigned size = fn == MODBUS_FC_READ_HOLDING_REGISTERS ? SC_MB_HOLDING_COUNT
                                                               : SC_MB_INPUT_COUNT;
        if (n < 1 || n > MODBUS_MAX_READ_REGISTERS)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        if (addr + n > size)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
        break;
    }
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
        if (plen < 5)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        if (!write_range_ok(addr, 1))
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
        break;
    case MODBUS_FC_MASK_WRITE_REGISTER:
        if (plen < 7)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        if (!write_range_ok(addr, 1))
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
        break;
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
        if (plen < 6)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {
        if (plen < 6)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        unsigned n = be16(pdu + 3), bc = pdu[5];
        if (n < 1 || n > MODBUS_MAX_WRITE_REGISTERS || bc != 2 * n || plen < 6 + (int)bc)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        if (!write_range_ok(addr, n))
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
        if (addr == 0 && n == 4)
            compute(mm, pdu + 6, e);
        break;
    }
    case MODBUS_FC_WRITE_AND_READ_REGISTERS: {
        if (plen < 10)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        unsigned nr = be16(pdu + 3), wa = be16(pdu + 5), nw = be16(pdu + 7), bc = pdu[9];
        if (nr < 1 || nr > MODBUS_MAX_WR_READ_REGISTERS || nw < 1 ||
            nw > MODBUS_MAX_WR_WRITE_REGISTERS || bc != 2 * nw || plen < 10 + (int)bc)
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
        if (addr + nr > SC_MB_HOLDING_COUNT || !write_range_ok(wa, nw))
            return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
        if (wa == 0 && nw == 4)
            compute(mm, pdu + 10, e);
        break;
    }
    case MODBUS_FC_REPORT_SLAVE_ID:
        break;
    default:
        return except(mm, ctx, req, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    }
    refresh(mm, e);
    return modbus_reply(ctx, req, len, mm->m);
}
