/* Unit tests of the SocketCAN transport (runtime/transport_can.c) without a CAN stack: frame
 * payload encoding, classification, configuration checks, and the whole serve/tick path driven
 * through a SOCK_SEQPACKET socketpair that carries struct can_frame datagrams like a raw CAN
 * socket. The engine is replaced by a fake with a known correction so that the test checks the
 * transport alone (the real-bus tests under tests/integration/vcan/ check the daemon end to end). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "transport_can.h"

/* ---------------------------------------------------------------- fake engine */

static int32_t fake_cx(int32_t x, int32_t y) { return x - 1000 - y / 1000; }
static int32_t fake_cy(int32_t x, int32_t y) { return y + 500 + x / 2000; }

uint16_t sc_engine_correct(sc_engine *e, int32_t x_nm, int32_t y_nm, int32_t *out_x_nm,
                           int32_t *out_y_nm)
{
    *out_x_nm = fake_cx(x_nm, y_nm);
    *out_y_nm = fake_cy(x_nm, y_nm);
    e->corrections++;
    e->status = SC_CORR_ST_LOADED | (x_nm > 1000000 ? SC_CORR_ST_OUTSIDE : 0);
    return e->status;
}

/* ---------------------------------------------------------------- payloads */

static void test_position_payload(void **state)
{
    (void)state;
    uint8_t d[8];
    sc_can_encode_position(d, 0x01020304, -2);
    const uint8_t want[8] = {0x04, 0x03, 0x02, 0x01, 0xfe, 0xff, 0xff, 0xff};
    assert_memory_equal(d, want, 8);
    const int32_t vals[] = {0, 1, -1, 123456789, -123456789, INT32_MAX, INT32_MIN};
    for (size_t a = 0; a < sizeof vals / sizeof vals[0]; a++) {
        for (size_t b = 0; b < sizeof vals / sizeof vals[0]; b++) {
            int32_t x, y;
            sc_can_encode_position(d, vals[a], vals[b]);
            sc_can_decode_position(d, &x, &y);
            assert_int_equal(x, vals[a]);
            assert_int_equal(y, vals[b]);
        }
    }
    const uint8_t min[8] = {0x00, 0x00, 0x00, 0x80, 0xff, 0xff, 0xff, 0x7f};
    int32_t x, y;
    sc_can_decode_position(min, &x, &y);
    assert_int_equal(x, INT32_MIN);
    assert_int_equal(y, INT32_MAX);
}

static void test_status_payload(void **state)
{
    (void)state;
    uint8_t d[8];
    sc_can_encode_status(d, 0x43, 0xbeef, 0x12345678u);
    const uint8_t want[8] = {0x43, 0x00, 0xef, 0xbe, 0x78, 0x56, 0x34, 0x12};
    assert_memory_equal(d, want, 8);
}

static void test_classify(void **state)
{
    (void)state;
    sc_can_config c;
    sc_can_config_defaults(&c);
    assert_int_equal(c.in_id, 0x100);
    assert_int_equal(c.out_id, 0x101);
    assert_int_equal(c.status_id, 0x102);
    assert_int_equal(c.status_period_ms, 1000);
    assert_int_equal(sc_can_classify(&c, 0x100, 8), SC_CAN_RX_POSITION);
    assert_int_equal(sc_can_classify(&c, 0x100, 7), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x100, 0), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x100, 12), SC_CAN_RX_BAD); /* FD length 12 */
    assert_int_equal(sc_can_classify(&c, 0x100 | CAN_RTR_FLAG, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x100 | CAN_EFF_FLAG, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x101, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x102, 8), SC_CAN_RX_BAD);
    /* other ids: bad by default (SPEC's "bad DLC or id"), not seen with ignore_other_ids */
    assert_int_equal(c.ignore_other_ids, 0);
    assert_int_equal(sc_can_classify(&c, 0x1f000100 | CAN_EFF_FLAG, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x103, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x000, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, CAN_ERR_FLAG | CAN_ERR_BUSOFF, 8), SC_CAN_RX_ERROR);
    c.ignore_other_ids = 1;
    assert_int_equal(sc_can_classify(&c, 0x1f000100 | CAN_EFF_FLAG, 8), SC_CAN_RX_IGNORE);
    assert_int_equal(sc_can_classify(&c, 0x103, 8), SC_CAN_RX_IGNORE);
    assert_int_equal(sc_can_classify(&c, 0x000, 8), SC_CAN_RX_IGNORE);
    assert_int_equal(sc_can_classify(&c, 0x100 | CAN_EFF_FLAG, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x101, 8), SC_CAN_RX_BAD);
    assert_int_equal(sc_can_classify(&c, 0x100, 7), SC_CAN_RX_BAD);
    c.in_id = 0x7ff;
    assert_int_equal(sc_can_classify(&c, 0x7ff, 8), SC_CAN_RX_POSITION);
    assert_int_equal(sc_can_classify(&c, 0x100, 8), SC_CAN_RX_IGNORE);
    c.ignore_other_ids = 0;
    assert_int_equal(sc_can_classify(&c, 0x100, 8), SC_CAN_RX_BAD);
}

static void test_config_check(void **state)
{
    (void)state;
    sc_can_config c;
    sc_error why;
    sc_can_config_defaults(&c);
    assert_int_equal(sc_can_config_check(&c, &why), SC_E_INPUT); /* no interface */
    assert_non_null(strstr(why.msg, "interface"));
    strcpy(c.ifname, "vcan0");
    assert_int_equal(sc_can_config_check(&c, &why), SC_OK);
    c.out_id = 0x800;
    assert_int_equal(sc_can_config_check(&c, &why), SC_E_INPUT);
    assert_non_null(strstr(why.msg, "0x800"));
    c.out_id = 0x7ff; /* the largest 11-bit id is one */
    assert_int_equal(sc_can_config_check(&c, &why), SC_OK);
    c.out_id = 0x100;
    assert_int_equal(sc_can_config_check(&c, &why), SC_E_INPUT);
    assert_non_null(strstr(why.msg, "differ"));
    c.out_id = 0x101;
    c.status_period_ms = 0;
    assert_int_equal(sc_can_config_check(&c, &why), SC_E_INPUT);
    memset(c.ifname, 'a', sizeof c.ifname); /* not terminated */
    c.status_period_ms = 1000;
    assert_int_equal(sc_can_config_check(&c, &why), SC_E_INPUT);
}

/* ---------------------------------------------------------------- serve / tick */

typedef struct rig {
    int peer;  /* our side: the "bus" */
    int dfd;   /* the transport's side */
    sc_transport t;
    sc_engine e;
} rig;

static char last_log[512];
static int n_logs;
static void capture_log(int prio, const char *msg)
{
    (void)prio;
    snprintf(last_log, sizeof last_log, "%s", msg);
    n_logs++;
}

static void rig_open(rig *r)
{
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK, 0, sv), 0);
    r->peer = sv[0];
    r->dfd = sv[1];
    sc_can_config c;
    sc_can_config_defaults(&c);
    strcpy(c.ifname, "test0");
    c.log = capture_log;
    sc_can_transport_use_fd(r->dfd);
    sc_can_transport(&r->t, &c);
    memset(&r->e, 0, sizeof r->e);
    r->e.status = SC_CORR_ST_LOADED;
    sc_error why;
    assert_int_equal(r->t.open(r->t.state, &why), SC_OK);
}

static void rig_close(rig *r)
{
    r->t.close(r->t.state);
    sc_can_transport_use_fd(-1);
    close(r->peer);
    close(r->dfd);
}

static void bus_send(rig *r, uint32_t id, uint8_t len, const uint8_t *data)
{
    struct can_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = id;
    f.can_dlc = len;
    if (data)
        memcpy(f.data, data, len > 8 ? 8 : len);
    assert_int_equal(write(r->peer, &f, sizeof f), (ssize_t)sizeof f);
}

static void bus_send_position(rig *r, int32_t x, int32_t y)
{
    uint8_t d[8];
    sc_can_encode_position(d, x, y);
    bus_send(r, 0x100, 8, d);
}

/* One turn of the daemon's loop. */
static void loop_once(rig *r, uint64_t now_ms)
{
    struct pollfd fds[4];
    int n = r->t.fill_pollfds(r->t.state, fds, 4);
    assert_int_equal(n, 1);
    assert_int_equal(poll(fds, (nfds_t)n, 0) >= 0, 1);
    r->t.serve(r->t.state, fds, n, &r->e, now_ms);
    r->t.tick(r->t.state, &r->e, now_ms);
}

/* Read one frame from the bus; returns 0 when none is waiting. */
static int bus_recv(rig *r, struct can_frame *f)
{
    ssize_t n = read(r->peer, f, sizeof *f);
    if (n < 0) {
        assert_true(errno == EAGAIN || errno == EWOULDBLOCK);
        return 0;
    }
    assert_int_equal(n, (ssize_t)sizeof *f);
    return 1;
}

static void expect_status(rig *r, uint8_t bits, uint16_t bad, uint32_t corrections)
{
    struct can_frame f;
    assert_int_equal(bus_recv(r, &f), 1);
    assert_int_equal(f.can_id, 0x102);
    assert_int_equal(f.can_dlc, 8);
    assert_int_equal(f.data[0], bits);
    assert_int_equal(f.data[1], 0);
    assert_int_equal(f.data[2] | f.data[3] << 8, bad);
    assert_int_equal((uint32_t)f.data[4] | (uint32_t)f.data[5] << 8 | (uint32_t)f.data[6] << 16 |
                         (uint32_t)f.data[7] << 24,
                     corrections);
}

static void test_serve_answers_and_status(void **state)
{
    (void)state;
    rig r;
    rig_open(&r);
    /* The first tick sends a status frame at once. */
    loop_once(&r, 5000);
    expect_status(&r, SC_CORR_ST_LOADED, 0, 0);
    struct can_frame f;
    assert_int_equal(bus_recv(&r, &f), 0);

    /* 100 positions, with bad frames and foreign ids interleaved. */
    int nbad = 0;
    for (int k = 0; k < 100; k++) {
        bus_send_position(&r, k * 12345 - 600000, 300000 - k * 777);
        if (k % 10 == 3) {
            uint8_t d[8] = {1, 2, 3, 4, 5, 6, 7, 8};
            bus_send(&r, 0x100, (uint8_t)(k % 8), d); /* bad DLC */
            bus_send(&r, 0x100 | CAN_RTR_FLAG, 8, NULL); /* remote frame */
            bus_send(&r, 0x100 | CAN_EFF_FLAG, 8, d); /* extended id 0x100 */
            bus_send(&r, 0x101, 8, d); /* someone else on our output id */
            bus_send(&r, 0x555, 8, d); /* another id: bad too (by default) */
            nbad += 5;
        }
        if (k % 7 == 0)
            loop_once(&r, 5000 + (uint64_t)k);
    }
    loop_once(&r, 5500);
    for (int k = 0; k < 100; k++) {
        int32_t x = k * 12345 - 600000, y = 300000 - k * 777, cx, cy;
        assert_int_equal(bus_recv(&r, &f), 1);
        assert_int_equal(f.can_id, 0x101);
        assert_int_equal(f.can_dlc, 8);
        sc_can_decode_position(f.data, &cx, &cy);
        assert_int_equal(cx, fake_cx(x, y));
        assert_int_equal(cy, fake_cy(x, y));
    }
    assert_int_equal(bus_recv(&r, &f), 0); /* nothing for the bad frames, no status yet */

    /* 1 s after the first status: the next one, with the counts. */
    loop_once(&r, 5999);
    assert_int_equal(bus_recv(&r, &f), 0);
    loop_once(&r, 6000);
    expect_status(&r, SC_CORR_ST_LOADED, (uint16_t)nbad, 100);
    loop_once(&r, 6500);
    assert_int_equal(bus_recv(&r, &f), 0);
    loop_once(&r, 7010);
    expect_status(&r, SC_CORR_ST_LOADED, (uint16_t)nbad, 100);

    /* An outside position: the engine's status bit goes through. */
    bus_send_position(&r, 2000000, 0);
    loop_once(&r, 7100);
    assert_int_equal(bus_recv(&r, &f), 1);
    assert_int_equal(f.can_id, 0x101);
    loop_once(&r, 8000);
    expect_status(&r, SC_CORR_ST_LOADED | SC_CORR_ST_OUTSIDE, (uint16_t)nbad, 101);

    sc_can_stats st;
    sc_can_get_stats(&st);
    assert_int_equal(st.positions, 101);
    assert_int_equal(st.bad_frames, nbad);
    assert_int_equal(st.tx_dropped, 0);
    rig_close(&r);
}

static void test_bus_off_reported_and_survived(void **state)
{
    (void)state;
    rig r;
    rig_open(&r);
    loop_once(&r, 0);
    expect_status(&r, SC_CORR_ST_LOADED, 0, 0);
    n_logs = 0;
    uint8_t zero[8] = {0};
    bus_send(&r, CAN_ERR_FLAG | CAN_ERR_BUSOFF, CAN_ERR_DLC, zero);
    loop_once(&r, 100);
    assert_true(n_logs >= 1);
    assert_non_null(strstr(last_log, "bus-off"));
    sc_can_stats st;
    sc_can_get_stats(&st);
    assert_int_equal(st.bus_off_now, 1);
    assert_int_equal(st.bus_off, 1);
    loop_once(&r, 1000);
    expect_status(&r, SC_CORR_ST_LOADED | SC_CAN_ST_BUS_OFF, 0, 0);
    loop_once(&r, 2000); /* still bus-off: still reported */
    expect_status(&r, SC_CORR_ST_LOADED | SC_CAN_ST_BUS_OFF, 0, 0);
    /* The controller restarts: the bus is back. */
    bus_send(&r, CAN_ERR_FLAG | CAN_ERR_RESTARTED, CAN_ERR_DLC, zero);
    loop_once(&r, 2100);
    assert_non_null(strstr(last_log, "bus back"));
    sc_can_get_stats(&st);
    assert_int_equal(st.bus_off_now, 0);
    bus_send_position(&r, 10, 20);
    loop_once(&r, 2200);
    struct can_frame f;
    assert_int_equal(bus_recv(&r, &f), 1);
    assert_int_equal(f.can_id, 0x101);
    loop_once(&r, 3000);
    expect_status(&r, SC_CORR_ST_LOADED, 0, 1);
    /* Bus-off again, then plain traffic proves the bus is back; bit kept until the next status. */
    bus_send(&r, CAN_ERR_FLAG | CAN_ERR_BUSOFF, CAN_ERR_DLC, zero);
    loop_once(&r, 3100);
    bus_send_position(&r, 30, 40);
    loop_once(&r, 3200);
    assert_int_equal(bus_recv(&r, &f), 1);
    sc_can_get_stats(&st);
    assert_int_equal(st.bus_off_now, 0);
    assert_int_equal(st.bus_off, 2);
    loop_once(&r, 4000);
    expect_status(&r, SC_CORR_ST_LOADED | SC_CAN_ST_BUS_OFF, 0, 2);
    loop_once(&r, 5000);
    expect_status(&r, SC_CORR_ST_LOADED, 0, 2);
    /* Controller overflow: frames were lost somewhere; bit 7 once. */
    uint8_t ovf[8] = {0, CAN_ERR_CRTL_RX_OVERFLOW, 0, 0, 0, 0, 0, 0};
    bus_send(&r, CAN_ERR_FLAG | CAN_ERR_CRTL, CAN_ERR_DLC, ovf);
    loop_once(&r, 5100);
    loop_once(&r, 6000);
    expect_status(&r, SC_CORR_ST_LOADED | SC_CAN_ST_LOST, 0, 2);
    loop_once(&r, 7000);
    expect_status(&r, SC_CORR_ST_LOADED, 0, 2);
    rig_close(&r);
}

/* The peer stops reading: sends are refused (EAGAIN), counted, the loop never blocks, and every
 * answer goes out in order once the peer reads again, as long as the retry queue holds them. */
static void test_queue_full_counted_never_blocks(void **state)
{
    (void)state;
    rig r;
    rig_open(&r);
    int small = 4096;
    assert_int_equal(setsockopt(r.dfd, SOL_SOCKET, SO_SNDBUF, &small, sizeof small), 0);
    loop_once(&r, 0);
    expect_status(&r, SC_CORR_ST_LOADED, 0, 0);
    const int n = 200; /* fewer than the transport's retry queue (256) plus what the socket holds */
    int sent = 0;
    for (int k = 0; k < n; k++) {
        bus_send_position(&r, k, -k);
        sent++;
        if (k % 16 == 15)
            loop_once(&r, 10); /* must return at once although the peer does not read */
    }
    loop_once(&r, 20);
    sc_can_stats st;
    sc_can_get_stats(&st);
    assert_true(st.tx_queue_full > 0);
    assert_int_equal(st.tx_dropped, 0);
    assert_int_equal(st.positions, n);
    /* Drain and let tick retry until everything is out. */
    int got = 0;
    struct can_frame f;
    for (int round = 0; round < 1000 && got < n; round++) {
        while (bus_recv(&r, &f)) {
            assert_int_equal(f.can_id, 0x101);
            int32_t cx, cy;
            sc_can_decode_position(f.data, &cx, &cy);
            assert_int_equal(cx, fake_cx(got, -got));
            assert_int_equal(cy, fake_cy(got, -got));
            got++;
        }
        r.t.tick(r.t.state, &r.e, 30 + (uint64_t)round);
    }
    assert_int_equal(got, n);
    /* Now overflow the retry queue: what does not fit is dropped and counted, never blocks. */
    for (int k = 0; k < 600; k++) {
        bus_send_position(&r, k, k);
        if (k % 50 == 49)
            loop_once(&r, 100 + (uint64_t)k);
    }
    loop_once(&r, 800);
    sc_can_get_stats(&st);
    assert_true(st.tx_dropped > 0);
    assert_int_equal(st.positions, n + 600);
    /* The status frame reports the loss. */
    while (bus_recv(&r, &f))
        ;
    for (int round = 0; round < 2000; round++) {
        while (bus_recv(&r, &f))
            if (f.can_id == 0x102)
                goto found;
        r.t.tick(r.t.state, &r.e, 1000 + (uint64_t)round);
    }
    fail_msg("no status frame after the overflow");
found:
    assert_true(f.data[0] & SC_CAN_ST_LOST);
    rig_close(&r);
}

/* Without a CAN stack (or without the interface) open() fails with a clear message. */
static void test_open_without_interface(void **state)
{
    (void)state;
    sc_transport t;
    sc_can_config c;
    sc_can_config_defaults(&c);
    strcpy(c.ifname, "nosuchcan9");
    c.log = capture_log;
    sc_can_transport_use_fd(-1);
    sc_can_transport(&t, &c);
    sc_error why;
    sc_error_clear(&why);
    assert_int_not_equal(t.open(t.state, &why), SC_OK);
    assert_non_null(strstr(why.msg, "CAN"));
    struct pollfd fds[1];
    assert_int_equal(t.fill_pollfds(t.state, fds, 1), 0);
    t.close(t.state);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_position_payload),
        cmocka_unit_test(test_status_payload),
        cmocka_unit_test(test_classify),
        cmocka_unit_test(test_config_check),
        cmocka_unit_test(test_serve_answers_and_status),
        cmocka_unit_test(test_bus_off_reported_and_survived),
        cmocka_unit_test(test_queue_full_counted_never_blocks),
        cmocka_unit_test(test_open_without_interface),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
