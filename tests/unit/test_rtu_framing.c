/* tests/unit/test_rtu_framing.c — selfcald's Modbus RTU framing by silence (issue 36), driven
 * byte stream by byte stream over a socketpair standing for the line, with a fake clock so the
 * gaps between reads are exact (a pseudo-terminal has no baud timing; see it_rtu_bus for the
 * whole daemon on one):
 * - t1.5 / t3.5 from the baud rate (11-bit characters; 750 / 1750 us above 19 200 baud), and
 *   --rtu-byte-timeout-ms replacing them;
 * - a gap of t1.5 inside a frame makes it incomplete (dropped, and the rest until t3.5); a gap
 *   just below t1.5 does not;
 * - frames of other units (a function-3 response, an exception, function 0x2B both ways, a
 *   function-23 request) are skipped, by silence or within one read, and our request after them
 *   is answered; nothing is answered for another unit. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "engine.h"
#include "modbus_map.h"
#include "transport.h"
#include "transport_modbus.h"
#include "selfcal/lut.h"

static sc_engine g_e;
static sc_corr_table g_t;
static sc_lut g_lut;
static sc_transport g_tr;
static int g_sv[2];
static uint64_t g_now_us = 1000000;

static uint64_t fake_clock(void)
{
    return g_now_us;
}

static void setup_line(int baud, uint32_t byte_timeout_ms)
{
    static uint8_t buf[1 << 14];
    sc_lut_init(&g_lut);
    g_lut.nx = g_lut.ny = 3;
    g_lut.px_mm = g_lut.py_mm = 1.0;
    for (int k = 0; k < 9; k++)
        g_lut.gx_um[k] = g_lut.gy_um[k] = 0.5 * k;
    size_t len = 0;
    sc_error err;
    assert_int_equal(sc_lut_encode(&g_lut, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_OK);
    assert_int_equal(sc_corr_load(&g_t, buf, len), SC_CORR_OK);
    sc_engine_init(&g_e, SC_CORR_MEASURE);
    g_e.table = &g_t;
    assert_int_equal(socketpair(AF_UNIX, SOCK_STREAM, 0, g_sv), 0);
    for (int k = 0; k < 2; k++)
        assert_int_equal(fcntl(g_sv[k], F_SETFL, O_NONBLOCK), 0);
    sc_mbrtu_config cfg;
    sc_mbrtu_config_defaults(&cfg);
    strcpy(cfg.device, "/dev/null");
    cfg.baud = baud;
    cfg.unit_id = 3;
    cfg.byte_timeout_ms = byte_timeout_ms;
    sc_modbus_rtu_use_fd(g_sv[0]);
    sc_modbus_rtu_use_clock(fake_clock);
    sc_modbus_rtu_transport(&g_tr, &cfg);
    assert_int_equal(g_tr.open(g_tr.state, &err), SC_OK);
}

static void teardown_line(void)
{
    g_tr.close(g_tr.state);
    sc_modbus_rtu_use_fd(-1);
    sc_modbus_rtu_use_clock(NULL);
    close(g_sv[0]);
    close(g_sv[1]);
}

/* bytes on the line after gap_us of silence, then the server reads them (one read) */
static void line(uint64_t gap_us, const uint8_t *b, size_t n)
{
    g_now_us += gap_us;
    assert_int_equal(write(g_sv[1], b, n), (ssize_t)n);
    struct pollfd pf;
    assert_int_equal(g_tr.fill_pollfds(g_tr.state, &pf, 1), 1);
    pf.revents = POLLIN;
    g_tr.serve(g_tr.state, &pf, 1, &g_e, g_now_us / 1000);
}

static size_t answer(uint8_t *out, size_t cap)
{
    ssize_t r = read(g_sv[1], out, cap);
    return r > 0 ? (size_t)r : 0;
}

static size_t frame(uint8_t *b, size_t n) /* append the CRC */
{
    uint16_t c = sc_modbus_crc16(b, (int)n);
    b[n] = (uint8_t)(c & 0xff);
    b[n + 1] = (uint8_t)(c >> 8);
    return n + 2;
}

/* our request: read holding 4-9 of unit 3 (17-byte answer) */
static size_t ours(uint8_t *b)
{
    const uint8_t r[] = {3, 3, 0, 4, 0, 6};
    memcpy(b, r, sizeof r);
    return frame(b, sizeof r);
}

static void test_silences(void **state)
{
    (void)state;
    static const struct {
        int baud;
        uint32_t timeout_ms, t15, t35;
    } cases[] = {{1200, 0, 13750, 32084}, {9600, 0, 1719, 4011}, {19200, 0, 860, 2006},
                 {19201, 0, 750, 1750},  {38400, 0, 750, 1750},  {115200, 0, 750, 1750},
                 {9600, 20, 0, 20000}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        sc_mbrtu_config c;
        sc_mbrtu_config_defaults(&c);
        c.baud = cases[k].baud;
        c.byte_timeout_ms = cases[k].timeout_ms;
        uint32_t t15, t35;
        sc_mbrtu_silences(&c, &t15, &t35);
        assert_int_equal(t15, cases[k].t15);
        assert_int_equal(t35, cases[k].t35);
    }
}

static void test_gap_inside_a_frame(void **state)
{
    (void)state;
    uint8_t b[64], out[64];
    setup_line(9600, 0); /* t1.5 = 1719 us, t3.5 = 4011 us */
    size_t n = ours(b);
    /* split with a gap just below t1.5: one frame, answered */
    line(10000, b, 3);
    line(1700, b + 3, n - 3);
    assert_int_equal(answer(out, sizeof out), 17);
    /* split with a gap of t1.5: incomplete, dropped; and what follows without t3.5 too */
    uint32_t bad = sc_modbus_rtu_bad_frames();
    line(10000, b, 3);
    line(1719, b + 3, n - 3);
    line(3000, b, n); /* a whole request, but inside the broken frame's silence: dropped */
    assert_int_equal(answer(out, sizeof out), 0);
    assert_true(sc_modbus_rtu_bad_frames() > bad);
    /* after t3.5 the line is ours again */
    line(4011, b, n);
    assert_int_equal(answer(out, sizeof out), 17);
    teardown_line();
}

static void test_other_units(void **state)
{
    (void)state;
    uint8_t b[300], out[64];
    setup_line(115200, 0); /* t3.5 = 1750 us */
    size_t n = 0;
    uint8_t *p;
    uint32_t others = sc_modbus_rtu_other_frames();
    for (int together = 0; together < 2; together++) {
        /* the master and unit 2: a function-3 request and its 9-byte response, a request
         * answered by an exception, function 0x2B both ways, a function-23 request our map
         * would answer, a broadcast */
        static const uint8_t f[][40] = {
            {6, 2, 3, 0, 0, 0, 2},
            {7, 2, 3, 4, 1, 2, 3, 4},
            {6, 2, 3, 0, 100, 0, 2},
            {3, 2, 0x83, 2},
            {5, 2, 0x2B, 0x0E, 1, 0},
            {15, 2, 0x2B, 0x0E, 1, 1, 0, 0, 1, 0, 5, 'A', 'B', 'C', 'D', 'E'},
            {19, 2, 23, 0, 4, 0, 6, 0, 0, 0, 4, 8, 0, 1, 0, 2, 0, 3, 0, 4},
            {11, 0, 16, 0, 0, 0, 2, 4, 0, 1, 0, 2},
        };
        n = 0;
        for (size_t k = 0; k < sizeof f / sizeof f[0]; k++) {
            p = b + n;
            memcpy(p, f[k] + 1, f[k][0]);
            size_t fl = frame(p, f[k][0]);
            if (!together) {
                line(1750, p, fl); /* each after t3.5: delimited by silence */
                assert_int_equal(answer(out, sizeof out), 0);
            }
            n += fl;
        }
        n += ours(b + n);
        if (together) /* everything in one read, as a late reader sees it */
            line(1750, b, n);
        else
            line(1750, b + n - 8, 8);
        assert_int_equal(answer(out, sizeof out), 17);
        assert_int_equal(out[0], 3);
        assert_int_equal(out[1], 3);
        assert_int_equal(out[2], 12);
    }
    assert_int_equal(sc_modbus_rtu_other_frames() - others, 16);
    /* our request with a bad CRC: dropped, and the rest of its block with it */
    n = ours(b);
    b[n - 1] ^= 1;
    n += ours(b + n);
    line(1750, b, n);
    assert_int_equal(answer(out, sizeof out), 0);
    line(1750, b + 8, 8); /* after t3.5: answered */
    assert_int_equal(answer(out, sizeof out), 17);
    teardown_line();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_silences),
        cmocka_unit_test(test_gap_inside_a_frame),
        cmocka_unit_test(test_other_units),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
