/* Unit tests of selfcald's runtime: the engine (nm <-> mm, rounding, saturation, status, reload
 * into the spare slot), the Modbus word order, the configuration, the daemon loop driven through
 * the in-process fake transport, and the systemd notify protocol on a real unix datagram socket.
 * Expected values come from an independent bilinear evaluation written here, not from the core. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "config.h"
#include "daemon.h"
#include "engine.h"
#include "modbus_map.h"
#include "sd_notify.h"
#include "selfcal/lut.h"
#include "transport_fake.h"

#define NX 6
#define NY 5
#define X0 (-2.5)
#define Y0 (-2.0)
#define PX 1.0
#define PY 1.0

static sc_lut g_lut; /* ~300 KB: static */

/* An sc_error as the daemon prints it ("file:line: message"). */
static const char *err_text(const sc_error *e)
{
    static char buf[sizeof e->file + sizeof e->msg + 32];
    sc_error_format(e, buf, sizeof buf);
    return buf;
}

/* A smooth known map (um); scale k lets two tables differ. */
static double gx_true(double x, double y, double k)
{
    return k * (0.8 * sin(0.9 * x) + 0.3 * y * y - 0.2 * x * y);
}
static double gy_true(double x, double y, double k)
{
    return k * (-0.5 * cos(0.7 * y) + 0.25 * x - 0.1 * x * x);
}

static void make_table(const char *path, double k)
{
    sc_lut_init(&g_lut);
    g_lut.nx = NX;
    g_lut.ny = NY;
    g_lut.x0_mm = X0;
    g_lut.y0_mm = Y0;
    g_lut.px_mm = PX;
    g_lut.py_mm = PY;
    for (int i = 0; i < NY; i++)
        for (int j = 0; j < NX; j++) {
            double x = X0 + j * PX, y = Y0 + i * PY;
            g_lut.gx_um[i * NX + j] = gx_true(x, y, k);
            g_lut.gy_um[i * NX + j] = gy_true(x, y, k);
        }
    sc_error err;
    memset(&err, 0, sizeof err);
    assert_int_equal(sc_lut_write_file(path, &g_lut, SC_LUT_ENC_INT32, &err), SC_OK);
    /* Read back what was stored (quantized), the reference for the independent evaluation. */
    assert_int_equal(sc_lut_read_file(path, &g_lut, &err), SC_OK);
}

/* Independent bilinear evaluation of the stored grid (clamped), um; returns 1 if outside. */
static int ref_g(double x, double y, double *gx, double *gy)
{
    int outside = 0;
    double u = (x - X0) / PX, v = (y - Y0) / PY;
    if (u < 0) { u = 0; outside = 1; }
    if (u > NX - 1) { u = NX - 1; outside = 1; }
    if (v < 0) { v = 0; outside = 1; }
    if (v > NY - 1) { v = NY - 1; outside = 1; }
    int j = (int)floor(u), i = (int)floor(v);
    if (j > NX - 2) j = NX - 2;
    if (i > NY - 2) i = NY - 2;
    double fu = u - j, fv = v - i;
    const double *a = g_lut.gx_um, *b = g_lut.gy_um;
#define BIL(t) ((1 - fv) * ((1 - fu) * t[i * NX + j] + fu * t[i * NX + j + 1]) + \
                fv * ((1 - fu) * t[(i + 1) * NX + j] + fu * t[(i + 1) * NX + j + 1]))
    *gx = BIL(a);
    *gy = BIL(b);
#undef BIL
    return outside;
}

static char g_path_a[512], g_path_b[512], g_path_bad[512];

static int setup(void **state)
{
    (void)state;
    snprintf(g_path_a, sizeof g_path_a, "%s/runtime_a.lut", SELFCAL_TEST_TMP);
    snprintf(g_path_b, sizeof g_path_b, "%s/runtime_b.lut", SELFCAL_TEST_TMP);
    snprintf(g_path_bad, sizeof g_path_bad, "%s/runtime_bad.lut", SELFCAL_TEST_TMP);
    make_table(g_path_b, -2.0);
    make_table(g_path_a, 1.0); /* g_lut holds table a afterwards */
    return 0;
}

static void check_point(sc_engine *e, int32_t x_nm, int32_t y_nm)
{
    int32_t ox, oy;
    uint16_t st = sc_engine_correct(e, x_nm, y_nm, &ox, &oy);
    double gx, gy;
    int outside = ref_g(x_nm * 1e-6, y_nm * 1e-6, &gx, &gy);
    double sign = e->mode == SC_CORR_MEASURE ? -1.0 : 1.0;
    double ex = x_nm + sign * gx * 1e3, ey = y_nm + sign * gy * 1e3; /* nm */
    assert_true(fabs(ox - ex) <= 0.5 + 1e-3);
    assert_true(fabs(oy - ey) <= 0.5 + 1e-3);
    assert_true(st & SC_CORR_ST_LOADED);
    assert_int_equal(!!(st & SC_CORR_ST_OUTSIDE), outside);
    assert_int_equal(e->last_out_x_nm, ox);
    assert_int_equal(e->last_in_y_nm, y_nm);
}

static void test_engine_correct(void **state)
{
    (void)state;
    static sc_engine e;
    sc_error why;
    sc_engine_init(&e, SC_CORR_MEASURE);
    int32_t ox, oy;
    /* Without a table: pass through, LOADED clear. */
    assert_int_equal(sc_engine_correct(&e, 123, -456, &ox, &oy) & SC_CORR_ST_LOADED, 0);
    assert_int_equal(ox, 123);
    assert_int_equal(oy, -456);
    assert_int_equal(sc_engine_load_file(&e, g_path_a, &why), SC_OK);
    assert_true(e.status & SC_CORR_ST_LOADED);
    uint32_t before = e.corrections;
    for (int k = 0; k < 400; k++) {
        int32_t x = (int32_t)(-3200000 + 17003 * k), y = (int32_t)(2600000 - 13001 * k);
        check_point(&e, x, y);
    }
    assert_int_equal(e.corrections, before + 400);
    e.mode = SC_CORR_POSITION;
    for (int k = 0; k < 100; k++)
        check_point(&e, (int32_t)(-2000000 + 41234 * k), (int32_t)(-1500000 + 30011 * k));
    /* measure-exact: the output q is what position mode takes back to the input, q + G(q) = p,
     * within the output's rounding to a nanometre. */
    e.mode = SC_CORR_MEASURE_EXACT;
    for (int k = 0; k < 100; k++) {
        const int32_t x = (int32_t)(-2500000 + 47111 * k), y = (int32_t)(-1800000 + 33013 * k);
        assert_true(sc_engine_correct(&e, x, y, &ox, &oy) & SC_CORR_ST_LOADED);
        double qx, qy;
        ref_g(ox * 1e-6, oy * 1e-6, &qx, &qy);
        assert_true(fabs(ox + qx * 1e3 - x) <= 0.51);
        assert_true(fabs(oy + qy * 1e3 - y) <= 0.51);
    }
    /* Far outside: clamped, flagged; extreme inputs saturate and are flagged invalid. */
    e.mode = SC_CORR_MEASURE;
    check_point(&e, 100000000, -100000000);
    uint16_t st = sc_engine_correct(&e, INT32_MIN, INT32_MIN, &ox, &oy);
    assert_true(st & SC_CORR_ST_OUTSIDE);
    double gx, gy;
    ref_g(-1e9, -1e9, &gx, &gy); /* p - G leaves int32 downward where G > 0 */
    if (gx * 1e3 > 0.6 || gy * 1e3 > 0.6)
        assert_true(st & SC_CORR_ST_INVALID);
    if (gx * 1e3 > 0.6)
        assert_int_equal(ox, INT32_MIN);
    st = sc_engine_correct(&e, INT32_MAX, INT32_MAX, &ox, &oy);
    ref_g(1e9, 1e9, &gx, &gy);
    if (gx * 1e3 < -0.6 || gy * 1e3 < -0.6)
        assert_true(st & SC_CORR_ST_INVALID);
    if (gx * 1e3 < -0.6)
        assert_int_equal(ox, INT32_MAX);
    /* An ordinary point afterwards: the invalid bit does not stick. */
    st = sc_engine_correct(&e, 0, 0, &ox, &oy);
    assert_int_equal(st, SC_CORR_ST_LOADED);
}

static void test_mm_to_nm(void **state)
{
    (void)state;
    int sat = 0;
    assert_int_equal(sc_engine_mm_to_nm(1.0000004, &sat), 1000000);
    assert_int_equal(sc_engine_mm_to_nm(1.0000006, &sat), 1000001);
    assert_int_equal(sc_engine_mm_to_nm(-1.0000006, &sat), -1000001);
    assert_int_equal(sat, 0);
    assert_int_equal(sc_engine_mm_to_nm(3000.0, &sat), INT32_MAX);
    assert_int_equal(sat, 1);
    sat = 0;
    assert_int_equal(sc_engine_mm_to_nm(-3000.0, &sat), INT32_MIN);
    assert_int_equal(sat, 1);
    sat = 0;
    sc_engine_mm_to_nm(NAN, &sat);
    assert_int_equal(sat, 1);
}

static void write_bytes(const char *path, const void *p, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(p, 1, n, f), n);
    fclose(f);
}

static void test_engine_reload(void **state)
{
    (void)state;
    static sc_engine e;
    sc_error why;
    sc_engine_init(&e, SC_CORR_MEASURE);
    assert_int_equal(sc_engine_load_file(&e, g_path_a, &why), SC_OK);
    const sc_corr_table *first = e.table;
    int32_t ax, ay, bx, by;
    sc_engine_correct(&e, 700000, -300000, &ax, &ay);
    /* Missing file: keep the table, say so in the status. */
    assert_int_equal(sc_engine_load_file(&e, "/nonexistent/t.lut", &why), SC_E_INPUT); /* bad input */
    assert_non_null(strstr(err_text(&why), "/nonexistent/t.lut"));
    assert_ptr_equal(e.table, first);
    assert_true(e.status & SC_ENGINE_ST_RELOAD_FAILED);
    assert_true(e.status & SC_CORR_ST_LOADED);
    sc_engine_correct(&e, 700000, -300000, &bx, &by);
    assert_int_equal(ax, bx);
    assert_true(e.status & SC_ENGINE_ST_RELOAD_FAILED);
    /* Corrupt file (one byte flipped in a valid table): refused by the checksum. */
    static unsigned char buf[400000];
    FILE *f = fopen(g_path_b, "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    assert_true(n > 100);
    buf[n / 2] ^= 0x40;
    write_bytes(g_path_bad, buf, n);
    assert_int_equal(sc_engine_load_file(&e, g_path_bad, &why), SC_E_INPUT);
    assert_ptr_equal(e.table, first);
    write_bytes(g_path_bad, "hello", 5);
    assert_int_equal(sc_engine_load_file(&e, g_path_bad, &why), SC_E_INPUT);
    assert_ptr_equal(e.table, first);
    assert_int_equal(e.reload_failed, 3);
    /* A valid new table: swapped into the other slot, the failure bit cleared. */
    assert_int_equal(sc_engine_load_file(&e, g_path_b, &why), SC_OK);
    assert_ptr_not_equal(e.table, first);
    assert_int_equal(e.status & SC_ENGINE_ST_RELOAD_FAILED, 0);
    assert_int_equal(e.reload_ok, 1); /* the first load was no reload */
    sc_engine_correct(&e, 700000, -300000, &bx, &by);
    /* table b = -2 x table a: the correction changed sign and doubled (to quantization). */
    assert_true(fabs((bx - 700000) + 2.0 * (ax - 700000)) <= 2.0);
    assert_true(fabs((by + 300000) + 2.0 * (ay + 300000)) <= 2.0);
    /* And back to a: the first slot again. */
    assert_int_equal(sc_engine_load_file(&e, g_path_a, &why), SC_OK);
    assert_ptr_equal(e.table, first);
}

static void test_word_order(void **state)
{
    (void)state;
    uint16_t r[2];
    sc_mb_put_i32(r, -2, SC_WORD_HIGH_FIRST);
    assert_int_equal(r[0], 0xffff);
    assert_int_equal(r[1], 0xfffe);
    sc_mb_put_i32(r, 0x12345678, SC_WORD_HIGH_FIRST);
    assert_int_equal(r[0], 0x1234);
    assert_int_equal(r[1], 0x5678);
    assert_int_equal(sc_mb_get_i32(r, SC_WORD_HIGH_FIRST), 0x12345678);
    sc_mb_put_i32(r, 0x12345678, SC_WORD_LOW_FIRST);
    assert_int_equal(r[0], 0x5678);
    assert_int_equal(r[1], 0x1234);
    assert_int_equal(sc_mb_get_i32(r, SC_WORD_LOW_FIRST), 0x12345678);
    sc_mb_put_i32(r, INT32_MIN, SC_WORD_LOW_FIRST);
    assert_int_equal(sc_mb_get_i32(r, SC_WORD_LOW_FIRST), INT32_MIN);
}

static void test_config(void **state)
{
    (void)state;
    static sc_config c;
    sc_error why;
    char path[512];
    int help, version;
    snprintf(path, sizeof path, "%s/runtime.conf", SELFCAL_TEST_TMP);
    const char *text = "# selfcald test\n"
                       "table = /tmp/x.lut\n"
                       "modbus-tcp = 127.0.0.1:1700   # comment\n"
                       "mode = position\n"
                       "unit-id = 7\n"
                       "word-order = low-first\n"
                       "syslog = no\n";
    write_bytes(path, text, strlen(text));
    char *argv[] = {"selfcald", "--config", path, "--unit-id", "9", "--modbus-rtu",
                    "/dev/ttyS1:115200:N:8:2", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 7, argv, &help, &version, &why), SC_OK);
    assert_string_equal(c.table, "/tmp/x.lut");
    assert_int_equal(c.use_modbus_tcp, 1);
    assert_int_equal(c.tcp.port, 1700);
    assert_int_equal(c.mode, SC_CORR_POSITION);
    assert_int_equal(c.tcp.unit_id, 9); /* the flag wins over the file */
    {
        static sc_config c2;
        char *argv2[] = {"selfcald", "--table", "/tmp/x.lut", "--mode", "measure-exact", NULL};
        sc_config_defaults(&c2);
        assert_int_equal(sc_config_parse_args(&c2, 5, argv2, &help, &version, &why), SC_OK);
        assert_int_equal(c2.mode, SC_CORR_MEASURE_EXACT);
        char *argv3[] = {"selfcald", "--table", "/tmp/x.lut", "--mode", "exact", NULL};
        sc_config_defaults(&c2);
        assert_int_equal(sc_config_parse_args(&c2, 5, argv3, &help, &version, &why), SC_E_INPUT);
        assert_non_null(strstr(why.msg, "measure-exact"));
    }
    assert_int_equal(c.word_order, SC_WORD_LOW_FIRST);
    assert_int_equal(c.use_modbus_rtu, 1);
    assert_string_equal(c.rtu.device, "/dev/ttyS1");
    assert_int_equal(c.rtu.baud, 115200);
    assert_int_equal(c.rtu.parity, 'N');
    assert_int_equal(c.rtu.stop_bits, 2);
    /* Default transport: Modbus TCP on 127.0.0.1:1502. */
    char *argv2[] = {"selfcald", "--table=t.lut", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 2, argv2, &help, &version, &why), SC_OK);
    assert_int_equal(c.use_modbus_tcp, 1);
    assert_int_equal(c.tcp.port, 1502);
    assert_string_equal(c.tcp.host, "127.0.0.1");
    /* Errors name the file and line. */
    const char *bad = "table = a.lut\n\nmode = sideways\n";
    write_bytes(path, bad, strlen(bad));
    char *argv3[] = {"selfcald", "--config", path, NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 3, argv3, &help, &version, &why), SC_E_INPUT);
    assert_non_null(strstr(err_text(&why), "runtime.conf:3:"));
    assert_non_null(strstr(err_text(&why), "sideways"));
    char *argv4[] = {"selfcald", "--modbus-tcp", "localhost", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 3, argv4, &help, &version, &why), SC_E_INPUT);
    char *argv5[] = {"selfcald", "--modbus-tcp", "127.0.0.1:1502", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 3, argv5, &help, &version, &why), SC_E_INPUT);
    assert_non_null(strstr(err_text(&why), "--table"));
    /* Busy polling: off by default, a bounded number of microseconds, garbage refused. */
    sc_config_defaults(&c);
    assert_int_equal(c.busy_poll_us, 0);
    char *argv6[] = {"selfcald", "--table", "t.lut", "--busy-poll-us", "500", NULL};
    assert_int_equal(sc_config_parse_args(&c, 5, argv6, &help, &version, &why), SC_OK);
    assert_int_equal(c.busy_poll_us, 500);
    char *argv7[] = {"selfcald", "--table", "t.lut", "--busy-poll-us", "-5", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 5, argv7, &help, &version, &why), SC_E_INPUT);
    assert_non_null(strstr(err_text(&why), "--busy-poll-us"));
    char *argv8[] = {"selfcald", "--table", "t.lut", "--busy-poll-us", "2000000", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 5, argv8, &help, &version, &why), SC_E_INPUT);
    /* Numbers are decimal, leading zeros and all (never octal); only CAN ids take 0x... */
    char *argv9[] = {"selfcald", "--table", "t.lut", "--modbus-tcp", "127.0.0.1:015030",
                     "--unit-id", "010", "--can-in-id", "0x101", "--can-out-id", "0102", NULL};
    sc_config_defaults(&c);
    assert_int_equal(sc_config_parse_args(&c, 11, argv9, &help, &version, &why), SC_OK);
    assert_int_equal(c.tcp.port, 15030);
    assert_int_equal(c.tcp.unit_id, 10);
    assert_int_equal(c.can.in_id, 0x101);
    assert_int_equal(c.can.out_id, 102);
    const char *not_numbers[][2] = {{"--unit-id", "0x10"}, {"--modbus-tcp", "127.0.0.1:0x3ab0"},
                                    {"--byte-timeout-ms", "0x10"}, {"--can-in-id", "0x"},
                                    {"--can-in-id", "0x-1"}, {"--unit-id", "+5"}};
    for (size_t k = 0; k < sizeof not_numbers / sizeof not_numbers[0]; ++k) {
        char *argv10[] = {"selfcald", "--table", "t.lut", (char *)not_numbers[k][0],
                          (char *)not_numbers[k][1], NULL};
        sc_config_defaults(&c);
        assert_int_equal(sc_config_parse_args(&c, 5, argv10, &help, &version, &why), SC_E_INPUT);
    }
}

static sc_daemon g_d;

static void test_daemon_fake(void **state)
{
    (void)state;
    sc_error why;
    sc_daemon_init(&g_d, g_path_a, SC_CORR_MEASURE);
    sc_transport t;
    sc_fake_transport(&t);
    assert_int_equal(sc_daemon_add(&g_d, &t), SC_OK);
    assert_int_equal(sc_daemon_start(&g_d, &why), SC_OK);
    int peer = sc_fake_peer_fd();
    assert_true(peer >= 0);
    /* 300 requests in flight at once (the socket buffers them), then answers in order. */
    enum { N = 300 };
    static int32_t req[N][2];
    for (int k = 0; k < N; k++) {
        req[k][0] = (int32_t)(-2400000 + 16007 * k);
        req[k][1] = (int32_t)(1900000 - 12011 * k);
    }
    int sent = 0, got = 0;
    for (int round = 0; round < 1000 && got < N; round++) {
        while (sent < N && send(peer, req[sent], 8, MSG_DONTWAIT) == 8)
            sent++;
        sc_daemon_step(&g_d, 10);
        unsigned char a[12];
        while (got < sent && recv(peer, a, sizeof a, MSG_DONTWAIT) == 12) {
            int32_t ox, oy;
            uint16_t st, cnt;
            memcpy(&ox, a, 4);
            memcpy(&oy, a + 4, 4);
            memcpy(&st, a + 8, 2);
            memcpy(&cnt, a + 10, 2);
            double gx, gy;
            ref_g(req[got][0] * 1e-6, req[got][1] * 1e-6, &gx, &gy);
            assert_true(fabs(ox - (req[got][0] - gx * 1e3)) <= 0.501);
            assert_true(fabs(oy - (req[got][1] - gy * 1e3)) <= 0.501);
            assert_true(st & SC_CORR_ST_LOADED);
            assert_int_equal(cnt, got + 1);
            got++;
        }
    }
    assert_int_equal(got, N);
    /* A wrong-size request: counted, not answered. */
    assert_int_equal(send(peer, "abc", 3, 0), 3);
    sc_daemon_step(&g_d, 10);
    assert_int_equal(sc_fake_bad_requests(), 1);
    /* Reload through the loop: a bad table is refused, the status says so. */
    snprintf(g_d.table_path, sizeof g_d.table_path, "%s", g_path_bad);
    sc_daemon_request_reload(&g_d);
    sc_daemon_step(&g_d, 0);
    assert_true(g_d.engine.status & SC_ENGINE_ST_RELOAD_FAILED);
    int32_t one[2] = {0, 0};
    assert_int_equal(send(peer, one, 8, 0), 8);
    sc_daemon_step(&g_d, 50);
    unsigned char a[12];
    assert_int_equal(recv(peer, a, sizeof a, MSG_DONTWAIT), 12);
    uint16_t st;
    memcpy(&st, a + 8, 2);
    assert_int_equal(st & (SC_ENGINE_ST_RELOAD_FAILED | SC_CORR_ST_LOADED),
                     SC_ENGINE_ST_RELOAD_FAILED | SC_CORR_ST_LOADED);
    sc_daemon_request_stop(&g_d);
    assert_false(sc_daemon_step(&g_d, 0));
    sc_daemon_close(&g_d);
}

static void test_sd_notify(void **state)
{
    (void)state;
    char path[256];
    snprintf(path, sizeof path, "%s/notify.sock", SELFCAL_TEST_TMP);
    unlink(path);
    int s = socket(AF_UNIX, SOCK_DGRAM, 0);
    assert_true(s >= 0);
    struct sockaddr_un a;
    memset(&a, 0, sizeof a);
    a.sun_family = AF_UNIX;
    assert_true(strlen(path) < sizeof a.sun_path);
    strcpy(a.sun_path, path);
    assert_int_equal(bind(s, (struct sockaddr *)&a, sizeof a), 0);
    setenv("NOTIFY_SOCKET", path, 1);
    setenv("WATCHDOG_USEC", "100000", 1); /* 100 ms: WATCHDOG=1 every 50 ms */
    unsetenv("WATCHDOG_PID");
    bool on = false;
    assert_int_equal(sc_notify_init(&on), SC_OK);
    assert_true(on);
    assert_int_equal(sc_notify_watchdog_usec(), 100000);
    assert_int_equal(sc_notify("READY=1"), SC_OK);
    char buf[256];
    ssize_t n = recv(s, buf, sizeof buf - 1, 0);
    assert_int_equal(n, 7);
    buf[n] = '\0';
    assert_string_equal(buf, "READY=1");
    /* The loop sends WATCHDOG=1 at half the interval, and RELOADING=1 on a reload. */
    sc_error why;
    sc_daemon_init(&g_d, g_path_a, SC_CORR_MEASURE);
    sc_transport t;
    sc_fake_transport(&t);
    sc_daemon_add(&g_d, &t);
    assert_int_equal(sc_daemon_start(&g_d, &why), SC_OK);
    assert_int_equal(g_d.watchdog_period_ms, 50);
    uint64_t t0 = sc_now_ms();
    int watchdogs = 0;
    while (sc_now_ms() - t0 < 260) {
        sc_daemon_step(&g_d, 20);
        while ((n = recv(s, buf, sizeof buf - 1, MSG_DONTWAIT)) > 0) {
            buf[n] = '\0';
            if (strcmp(buf, "WATCHDOG=1") == 0)
                watchdogs++;
        }
    }
    assert_true(watchdogs >= 2 && watchdogs <= 8); /* about 5; slack for a loaded machine */
    sc_daemon_request_reload(&g_d);
    sc_daemon_step(&g_d, 0);
    n = recv(s, buf, sizeof buf - 1, MSG_DONTWAIT);
    while (n > 0) {
        buf[n] = '\0';
        if (strcmp(buf, "WATCHDOG=1") != 0)
            break;
        n = recv(s, buf, sizeof buf - 1, MSG_DONTWAIT);
    }
    assert_true(n > 0);
    assert_string_equal(buf, "RELOADING=1");
    n = recv(s, buf, sizeof buf - 1, MSG_DONTWAIT);
    assert_true(n > 0);
    buf[n] = '\0';
    assert_non_null(strstr(buf, "READY=1"));
    sc_daemon_close(&g_d);
    sc_notify_close();
    unsetenv("NOTIFY_SOCKET");
    unsetenv("WATCHDOG_USEC");
    /* The abstract namespace ('@') is accepted too. */
    setenv("NOTIFY_SOCKET", "@selfcald-test-abstract", 1);
    on = false;
    assert_int_equal(sc_notify_init(&on), SC_OK);
    assert_true(on);
    sc_notify_close();
    unsetenv("NOTIFY_SOCKET");
    assert_int_equal(sc_notify_init(&on), SC_OK);
    assert_false(on);
    assert_int_equal(sc_notify("READY=1"), SC_OK); /* disabled: a no-op */
    close(s);
    unlink(path);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mm_to_nm),      cmocka_unit_test(test_engine_correct),
        cmocka_unit_test(test_engine_reload), cmocka_unit_test(test_word_order),
        cmocka_unit_test(test_config),        cmocka_unit_test(test_daemon_fake),
        cmocka_unit_test(test_sd_notify),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
