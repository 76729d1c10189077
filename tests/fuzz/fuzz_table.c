/* tests/fuzz/fuzz_table.c — libFuzzer target: the table loader (sc_corr_load, the core selfcald
 * and the LinuxCNC component use; sc_lut_decode, the CLI's). The first input byte is a control
 * byte: bit 0 repairs the CRC-32 at the end and bit 1 the file-size field (offset 12) after the
 * mutation, so mutations reach the checks behind them; with both clear the checks themselves are
 * fuzzed. A table that loads is applied at a few points; the outputs must be finite or flagged. */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/correct.h"
#include "selfcal/lut.h"

static sc_corr_table g_t;
static sc_lut g_lut;
static uint8_t g_buf[1 << 20];

static void put_u32le(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++)
        p[k] = (uint8_t)(v >> (8 * k));
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1 || size - 1 > sizeof g_buf)
        return 0;
    unsigned ctl = data[0];
    size_t len = size - 1;
    memcpy(g_buf, data + 1, len);
    if ((ctl & 2) && len >= 16)
        put_u32le(g_buf + 12, (uint32_t)len);
    if ((ctl & 1) && len >= 4)
        put_u32le(g_buf + len - 4, sc_corr_crc32(g_buf, len - 4));
    int rc = sc_corr_load(&g_t, g_buf, len);
    if (rc == SC_CORR_OK) /* validate has no capacity limits: it accepts at least as much */
        FUZZ_CHECK(sc_corr_validate(g_buf, len) == SC_CORR_OK);
    FUZZ_CHECK(sc_corr_strerror(rc) != NULL);
    if (rc == SC_CORR_OK) {
        static const double pts[][3] = {{0, 0, 0}, {1e3, -1e3, 0}, {-5.5, 7.25, 1}, {1e9, 1e9, 1e9}};
        for (size_t k = 0; k < sizeof pts / sizeof pts[0]; k++) {
            for (int mode = 0; mode < 3; mode++) { /* measure, position, measure-exact */
                double out[3];
                unsigned st = sc_corr_apply(&g_t, (sc_corr_mode)mode, pts[k], out);
                FUZZ_CHECK((isfinite(out[0]) && isfinite(out[1]) && isfinite(out[2])) ||
                           (st & SC_CORR_ST_INVALID));
            }
        }
    }
    sc_error err;
    memset(&err, 0, sizeof err);
    sc_status st = sc_lut_decode(g_buf, len, &g_lut, "fuzz.lut", &err);
    fuzz_check_error(st, &err);
    return 0;
}
