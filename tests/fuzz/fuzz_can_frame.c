/* tests/fuzz/fuzz_can_frame.c — libFuzzer target: CAN frames as selfcald's SocketCAN transport
 * classifies and answers them (sc_can_classify, the position codec, the engine). Each 13-byte
 * record is can_id (4, with the kernel's EFF/RTR/ERR flag bits), len (1) and 8 data bytes.
 * Checks: only a standard-format data frame on in_id with 8 bytes is a position; a position is
 * answered with the table's correction (applied independently) and the codec round-trips; every
 * other frame changes nothing in the engine. */
#include <linux/can.h>
#include <string.h>

#include "fuzz_table_fixture.h"
#include "transport_can.h"

static sc_engine g_e;
static sc_corr_table g_t;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int init;
    static sc_can_config cfg;
    if (!init) {
        fuzz_engine_with_table(&g_e, &g_t);
        sc_can_config_defaults(&cfg);
        strcpy(cfg.ifname, "vcan0");
        init = 1;
    }
    for (size_t off = 0; size - off >= 13; off += 13) {
        const uint8_t *r = data + off;
        uint32_t id = (uint32_t)r[0] | (uint32_t)r[1] << 8 | (uint32_t)r[2] << 16 |
                      (uint32_t)r[3] << 24;
        uint8_t len = r[4];
        uint8_t frame[8];
        memcpy(frame, r + 5, 8);
        uint32_t corr0 = g_e.corrections;
        sc_can_rx_kind kind = sc_can_classify(&cfg, id, len);
        int is_pos = !(id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) &&
                     (id & CAN_SFF_MASK) == cfg.in_id && len == 8;
        FUZZ_CHECK((kind == SC_CAN_RX_POSITION) == is_pos);
        FUZZ_CHECK(kind >= SC_CAN_RX_POSITION && kind <= SC_CAN_RX_IGNORE);
        if (kind != SC_CAN_RX_POSITION) {
            FUZZ_CHECK(g_e.corrections == corr0);
            continue;
        }
        int32_t x, y, cx, cy, bx, by;
        sc_can_decode_position(frame, &x, &y);
        uint8_t back[8];
        sc_can_encode_position(back, x, y);
        FUZZ_CHECK(memcmp(back, frame, 8) == 0);
        sc_engine_correct(&g_e, x, y, &cx, &cy);
        FUZZ_CHECK(g_e.corrections == corr0 + 1);
        double in[3] = {x * 1e-6, y * 1e-6, 0}, out[3];
        sc_corr_apply(g_e.table, g_e.mode, in, out);
        int sat = 0;
        FUZZ_CHECK(sc_engine_mm_to_nm(out[0], &sat) == cx && sc_engine_mm_to_nm(out[1], &sat) == cy);
        sc_can_encode_position(back, cx, cy);
        sc_can_decode_position(back, &bx, &by);
        FUZZ_CHECK(bx == cx && by == cy);
    }
    return 0;
}
