/* tests/fuzz/fuzz_modbus_rtu.c — libFuzzer target: the Modbus RTU byte stream as selfcald's RTU
 * transport frames it (transport_modbus_rtu.c: the frame length from the function code and byte
 * count, the CRC, resynchronisation at a silence, other units ignored), served through the
 * transport interface on one end of a socketpair standing for the serial line.
 * Input: chunks, each a control byte (bits 0-6: length, bit 7: a silence longer than t3.5 before
 * it; without it the chunk follows 10 us after the previous one) and that many bytes of the line.
 * The transport reads a fake clock (sc_modbus_rtu_use_clock) that only this target advances.
 * Checks beyond "no memory error, no undefined behaviour":
 *   - everything the server sends is a sequence of whole RTU responses from unit 1 with a correct
 *     CRC-16 (computed here bit by bit, not with selfcald's table), each a normal response of a
 *     function the map serves or an exception (function | 0x80, code 1-3), never more responses
 *     than frames the stream could hold (4 bytes each);
 *   - liveness: after any stream and a silence, a valid read of holding registers 4-9 from unit 1
 *     is answered with exactly its response (12 data bytes) — the framing always resynchronises. */
#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/socket.h>

#include "fuzz_table_fixture.h"
#include "modbus_map.h"
#include "transport.h"
#include "transport_modbus.h"

static sc_engine g_e;
static sc_corr_table g_t;
static sc_transport g_tr;
static int g_sv[2];
static uint64_t g_now = 1000;   /* ms, for the transport interface */
static uint64_t g_now_us = 1000000; /* what the transport's clock reads */

static uint64_t fake_clock_us(void)
{
    return g_now_us;
}

static uint16_t crc16(const uint8_t *p, int n)
{
    uint16_t c = 0xffff;
    for (int i = 0; i < n; ++i) {
        c ^= p[i];
        for (int b = 0; b < 8; ++b)
            c = (uint16_t)(c & 1 ? (c >> 1) ^ 0xa001 : c >> 1);
    }
    return c;
}

static void init(void)
{
    fuzz_engine_with_table(&g_e, &g_t);
    FUZZ_CHECK(socketpair(AF_UNIX, SOCK_STREAM, 0, g_sv) == 0);
    for (int k = 0; k < 2; ++k)
        FUZZ_CHECK(fcntl(g_sv[k], F_SETFL, O_NONBLOCK) == 0);
    int big = 1 << 20;
    setsockopt(g_sv[0], SOL_SOCKET, SO_SNDBUF, &big, sizeof big);
    setsockopt(g_sv[1], SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
    sc_mbrtu_config cfg;
    sc_mbrtu_config_defaults(&cfg);
    strcpy(cfg.device, "/dev/null");
    sc_modbus_rtu_use_fd(g_sv[0]);
    sc_modbus_rtu_use_clock(fake_clock_us);
    sc_modbus_rtu_transport(&g_tr, &cfg);
}

/* Let the server read what is on the line. */
static void serve(void)
{
    struct pollfd pf;
    FUZZ_CHECK(g_tr.fill_pollfds(g_tr.state, &pf, 1) == 1);
    pf.revents = POLLIN;
    g_tr.serve(g_tr.state, &pf, 1, &g_e, g_now);
    g_now_us += 10; /* well inside t1.5 */
}

static void silence(void)
{
    g_now += 200; /* beyond t3.5 */
    g_now_us += 200000;
    g_tr.tick(g_tr.state, &g_e, g_now);
}

static void send_line(const uint8_t *p, size_t n)
{
    while (n > 0) {
        ssize_t w = write(g_sv[1], p, n);
        FUZZ_CHECK(w > 0);
        p += w;
        n -= (size_t)w;
        serve();
    }
}

static uint8_t g_rx[1 << 20];

static size_t receive(void)
{
    size_t got = 0;
    for (;;) {
        ssize_t r = read(g_sv[1], g_rx + got, sizeof g_rx - got);
        if (r <= 0) {
            FUZZ_CHECK(r == 0 || errno == EAGAIN || errno == EWOULDBLOCK);
            return got;
        }
        got += (size_t)r;
    }
}

/* Length of the response starting at p (have bytes), 0 if it cannot be one. */
static size_t response_len(const uint8_t *p, size_t have)
{
    if (have < 5 || p[0] != 1)
        return 0;
    unsigned fn = p[1];
    if (fn & 0x80)
        return p[2] >= 1 && p[2] <= 3 ? 5 : 0;
    switch (fn) {
    case 3: case 4: case 23: case 17:
        return 5u + p[2];
    case 6: case 16:
        return 8;
    case 22:
        return 10;
    default:
        return 0;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int inited;
    sc_error err;
    if (!inited) {
        init();
        inited = 1;
    }
    FUZZ_CHECK(g_tr.open(g_tr.state, &err) == SC_OK);
    size_t off = 0, line_bytes = 0;
    while (off < size) {
        uint8_t c = data[off++];
        size_t n = c & 0x7f;
        if (n > size - off)
            n = size - off;
        if (c & 0x80)
            silence();
        send_line(data + off, n);
        off += n;
        line_bytes += n;
    }
    silence();
    size_t got = receive();
    size_t pos = 0, responses = 0;
    while (pos < got) {
        size_t len = response_len(g_rx + pos, got - pos);
        if (len == 0 || len > got - pos)
            fprintf(stderr, "not a response at byte %zu of %zu: %02x %02x %02x\n", pos, got,
                    g_rx[pos], got - pos > 1 ? g_rx[pos + 1] : 0, got - pos > 2 ? g_rx[pos + 2] : 0);
        FUZZ_CHECK(len > 0 && len <= got - pos);
        uint16_t crc = crc16(g_rx + pos, (int)len - 2);
        FUZZ_CHECK(g_rx[pos + len - 2] == (crc & 0xff) && g_rx[pos + len - 1] == (crc >> 8));
        pos += len;
        ++responses;
    }
    FUZZ_CHECK(responses <= line_bytes / 4);
    static int show = -1; /* FUZZ_SHOW_ERRORS=1: how many responses each input drew */
    if (show < 0)
        show = getenv("FUZZ_SHOW_ERRORS") != NULL;
    if (show)
        fprintf(stderr, "[ok] %zu line bytes, %zu responses\n", line_bytes, responses);

    /* liveness: a valid request after a silence is answered */
    uint8_t req[8] = {1, 3, 0, 4, 0, 6, 0, 0};
    uint16_t crc = crc16(req, 6);
    req[6] = (uint8_t)(crc & 0xff);
    req[7] = (uint8_t)(crc >> 8);
    send_line(req, sizeof req);
    got = receive();
    FUZZ_CHECK(got == 17 && g_rx[0] == 1 && g_rx[1] == 3 && g_rx[2] == 12);
    crc = crc16(g_rx, 15);
    FUZZ_CHECK(g_rx[15] == (crc & 0xff) && g_rx[16] == (crc >> 8));
    silence();
    g_tr.close(g_tr.state);
    return 0;
}
