/* tests/fuzz/fuzz_modbus_adu.c — libFuzzer target: one Modbus TCP request ADU in, the response
 * out, through selfcald's register map (sc_modbus_map_answer + sc_modbus_frame), with the state
 * checked after every request:
 * - the response is a normal response to the same function or exception (fn | 0x80, code 1-3),
 *   and its MBAP echoes the transaction id and unit with the right length;
 * - an exception changes nothing (holding registers, engine counters);
 * - a correction happens exactly when registers 0-3 are written by one function 16 or 23 request,
 *   and then the read-only mirror (holding 4-9) holds the engine's result for the values written.
 * The input is a stream of ADUs (MBAP length field bounded, as the TCP transport frames them). */
#include <string.h>

#include "fuzz_table_fixture.h"
#include "modbus_map.h"

static sc_engine g_e;
static sc_corr_table g_t;

static unsigned be16(const uint8_t *p)
{
    return (unsigned)(p[0] << 8 | p[1]);
}

static void one(sc_modbus_map *mm, const uint8_t *req, int total)
{
    sc_modbus_map before = *mm;
    uint32_t corr0 = g_e.corrections;
    uint8_t rsp[SC_MB_PDU_MAX], adu[SC_MB_ADU_MAX];
    const uint8_t *pdu = req + 7;
    int plen = total - 7;
    unsigned fn = pdu[0];
    int rlen = sc_modbus_map_answer(mm, req[6], pdu, plen, &g_e, rsp);
    FUZZ_CHECK(rlen >= 2 && rlen <= SC_MB_PDU_MAX);
    int alen = sc_modbus_frame(req, 7, rsp, rlen, adu);
    FUZZ_CHECK(alen == 7 + rlen && adu[0] == req[0] && adu[1] == req[1] && adu[6] == req[6]);
    FUZZ_CHECK(be16(adu + 2) == 0 && be16(adu + 4) == (unsigned)rlen + 1);
    if (rsp[0] == (uint8_t)(fn | 0x80u) && rlen == 2) { /* exception */
        FUZZ_CHECK(rsp[1] >= 1 && rsp[1] <= 3);
        FUZZ_CHECK(memcmp(before.holding, mm->holding, sizeof mm->holding) == 0);
        FUZZ_CHECK(g_e.corrections == corr0);
        return;
    }
    FUZZ_CHECK(rsp[0] == fn && fn < 0x80);
    int wrote03 = 0;
    const uint8_t *vals = NULL;
    if (fn == 0x10 && be16(pdu + 1) == 0 && be16(pdu + 3) == 4) {
        wrote03 = 1;
        vals = pdu + 6;
    } else if (fn == 0x17 && be16(pdu + 5) == 0 && be16(pdu + 7) == 4) {
        wrote03 = 1;
        vals = pdu + 10;
    }
    FUZZ_CHECK(g_e.corrections == corr0 + (uint32_t)wrote03);
    if (wrote03) {
        uint16_t w[4];
        for (int k = 0; k < 4; k++)
            w[k] = (uint16_t)be16(vals + 2 * k);
        int32_t x = sc_mb_get_i32(w, mm->order), y = sc_mb_get_i32(w + 2, mm->order);
        FUZZ_CHECK(g_e.last_in_x_nm == x && g_e.last_in_y_nm == y);
        FUZZ_CHECK(sc_mb_get_i32(mm->holding + 4, mm->order) == g_e.last_out_x_nm);
        FUZZ_CHECK(sc_mb_get_i32(mm->holding + 6, mm->order) == g_e.last_out_y_nm);
        FUZZ_CHECK(mm->holding[8] == g_e.status);
        /* the answer is the table's: apply it independently */
        double in[3] = {x * 1e-6, y * 1e-6, 0}, out[3];
        sc_corr_apply(g_e.table, g_e.mode, in, out);
        int sat = 0;
        FUZZ_CHECK(sc_engine_mm_to_nm(out[0], &sat) == g_e.last_out_x_nm);
        FUZZ_CHECK(sc_engine_mm_to_nm(out[1], &sat) == g_e.last_out_y_nm);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int init;
    if (!init) {
        fuzz_engine_with_table(&g_e, &g_t);
        init = 1;
    }
    sc_modbus_map *mm = sc_modbus_map_shared();
    sc_modbus_map_open(mm, size > 0 && (data[0] & 0x80) ? SC_WORD_LOW_FIRST : SC_WORD_HIGH_FIRST);
    size_t off = size > 0 ? 1 : 0;
    while (size - off >= 8) {
        const uint8_t *p = data + off;
        unsigned mlen = be16(p + 4);
        if (mlen < 2 || mlen > 254)
            break; /* the transport closes such a connection */
        size_t total = 6 + (size_t)mlen;
        if (size - off < total)
            break;
        /* exactly total bytes on the heap, so ASan sees any read past the request */
        uint8_t *req = malloc(total);
        FUZZ_CHECK(req != NULL);
        memcpy(req, p, total);
        one(mm, req, (int)total);
        free(req);
        off += total;
    }
    return 0;
}
