/* runtime/transport_modbus_rtu.c — Modbus RTU server on a serial device inside the poll loop.
 *
 * libmodbus opens and configures the line (modbus_new_rtu + modbus_connect: termios, non-blocking);
 * the shared map builds and sends the replies; the framing is done here without blocking: the
 * length of a request follows from its function code (and byte count), the CRC is checked, and a
 * partial frame followed by byte_timeout_ms of silence is discarded (resynchronisation).
 * Requests for other unit ids are ignored, as on a multi-drop line; broadcasts (unit 0) are
 * ignored too (a correction nobody reads back is of no use). Static state only. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include <modbus/modbus.h>

#include "log.h"
#include "modbus_map.h"
#include "transport_modbus.h"

#define RTU_MAX MODBUS_RTU_MAX_ADU_LENGTH /* 256 */

typedef struct mbrtu_state {
    sc_mbrtu_config cfg;
    modbus_t *ctx;
    int fd;
    int len;
    uint64_t last_rx_ms;
    uint32_t bad_frames, served;
    uint8_t buf[RTU_MAX];
} mbrtu_state;

static mbrtu_state g_rtu;
static int g_test_fd = -1; /* >= 0: serve this descriptor instead of a serial device (tests) */

void sc_modbus_rtu_use_fd(int fd)
{
    g_test_fd = fd;
}

void sc_mbrtu_config_defaults(sc_mbrtu_config *c)
{
    memset(c, 0, sizeof *c);
    c->baud = 19200;
    c->parity = 'E';
    c->data_bits = 8;
    c->stop_bits = 1;
    c->unit_id = 1;
    c->byte_timeout_ms = 50;
}

uint32_t sc_modbus_rtu_bad_frames(void)
{
    return g_rtu.bad_frames;
}


/* Expected length of the request starting at buf (with CRC), 0 if not known yet, -1 if the
 * function code gives no length (unknown function: ends at a silence). */
static int expected_len(const uint8_t *b, int have)
{
    if (have < 2)
        return 0;
    switch (b[1]) {
    case 1: case 2: case 3: case 4: case 5: case 6:
        return 8;
    case 7: case 11: case 12: case 17:
        return 4;
    case 22:
        return 10;
    case 15: case 16:
        return have < 7 ? 0 : 9 + b[6];
    case 23:
        return have < 11 ? 0 : 13 + b[10];
    default:
        return -1;
    }
}

static sc_status rtu_open(void *state, sc_error *err)
{
    mbrtu_state *s = state;
    sc_modbus_map_open(sc_modbus_map_shared(), s->cfg.word_order);
    if (s->cfg.unit_id < 1 || s->cfg.unit_id > 247) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "modbus-rtu: unit id must be 1..247");
    }
    if (g_test_fd >= 0) {
        s->fd = g_test_fd;
        s->len = 0;
        return 0;
    }
    s->ctx = modbus_new_rtu(s->cfg.device, s->cfg.baud, s->cfg.parity, s->cfg.data_bits,
                            s->cfg.stop_bits);
    if (s->ctx == NULL) {
        return sc_error_set(err, SC_E_IO, NULL, 0, "modbus-rtu: %s: %s", s->cfg.device,
                            modbus_strerror(errno));
    }
    modbus_set_slave(s->ctx, s->cfg.unit_id);
    if (modbus_connect(s->ctx) != 0) {
        modbus_free(s->ctx);
        s->ctx = NULL;
        return sc_error_set(err, SC_E_IO, NULL, 0, "modbus-rtu: cannot open %s: %s", s->cfg.device,
                            modbus_strerror(errno));
    }
    s->fd = modbus_get_socket(s->ctx);
    s->len = 0;
    sc_log(SC_LOG_NOTICE, "modbus-rtu: serving %s at %d baud %d%c%d (unit id %u)", s->cfg.device,
           s->cfg.baud, s->cfg.data_bits, s->cfg.parity, s->cfg.stop_bits,
           (unsigned)s->cfg.unit_id);
    return SC_OK;
}

static int rtu_fill(void *state, struct pollfd *fds, int max)
{
    mbrtu_state *s = state;
    if (max < 1 || s->fd < 0)
        return 0;
    fds[0].fd = s->fd;
    fds[0].events = POLLIN;
    fds[0].revents = 0;
    return 1;
}

static void rtu_frame(mbrtu_state *s, int flen, sc_engine *e)
{
    const uint8_t *b = s->buf;
    uint16_t crc = sc_modbus_crc16(b, flen - 2);
    if (b[flen - 2] != (crc & 0xff) || b[flen - 1] != (crc >> 8)) {
        s->bad_frames++;
        return;
    }
    if (b[0] != s->cfg.unit_id)
        return; /* another device's request, or a broadcast */
    if (sc_modbus_map_reply(sc_modbus_map_shared(), s->fd, b, flen, 1, 2, e) < 0)
        sc_log(SC_LOG_WARNING, "modbus-rtu: reply not sent: %s", strerror(errno));
    s->served++;
}

/* Consume complete frames at the start of the buffer. */
static void rtu_process(mbrtu_state *s, sc_engine *e)
{
    for (;;) {
        int need = expected_len(s->buf, s->len);
        if (need == 0 || need < 0 || s->len < need)
            return; /* wait for more bytes (or the silence, for unknown functions) */
        if (need > RTU_MAX) {
            s->bad_frames++;
            s->len = 0;
            return;
        }
        rtu_frame(s, need, e);
        memmove(s->buf, s->buf + need, (size_t)(s->len - need));
        s->len -= need;
    }
}

static void rtu_serve(void *state, struct pollfd *fds, int n, sc_engine *e, uint64_t now_ms)
{
    mbrtu_state *s = state;
    if (n < 1 || fds[0].revents == 0)
        return;
    if (fds[0].revents & (POLLERR | POLLNVAL)) {
        sc_log(SC_LOG_ERR, "modbus-rtu: %s: device error", s->cfg.device);
        return;
    }
    for (;;) {
        if (s->len == (int)sizeof s->buf) { /* full without a frame: garbage */
            s->bad_frames++;
            s->len = 0;
        }
        ssize_t r = read(s->fd, s->buf + s->len, sizeof s->buf - (size_t)s->len);
        if (r <= 0) {
            if (r < 0 && errno == EINTR)
                continue;
            break;
        }
        s->len += (int)r;
        s->last_rx_ms = now_ms;
        rtu_process(s, e);
    }
}

static void rtu_tick(void *state, sc_engine *e, uint64_t now_ms)
{
    mbrtu_state *s = state;
    if (s->len == 0 || now_ms - s->last_rx_ms <= s->cfg.byte_timeout_ms)
        return;
    /* Silence after a partial frame: an unknown function may still be a whole frame (answered
     * with "illegal function"); anything else is noise. */
    if (expected_len(s->buf, s->len) < 0 && s->len >= 4) {
        rtu_frame(s, s->len, e);
    } else {
        s->bad_frames++;
    }
    s->len = 0;
}

static void rtu_close(void *state)
{
    mbrtu_state *s = state;
    if (s->ctx != NULL) {
        modbus_close(s->ctx);
        modbus_free(s->ctx);
    }
    s->ctx = NULL;
    s->fd = -1;
}

void sc_modbus_rtu_transport(sc_transport *t, const sc_mbrtu_config *cfg)
{
    g_rtu.cfg = *cfg;
    g_rtu.fd = -1;
    t->name = "modbus-rtu";
    t->state = &g_rtu;
    t->open = rtu_open;
    t->fill_pollfds = rtu_fill;
    t->serve = rtu_serve;
    t->tick = rtu_tick;
    t->close = rtu_close;
}
