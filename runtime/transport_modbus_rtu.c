/* runtime/transport_modbus_rtu.c — Modbus RTU server on a serial device inside the poll loop.
 *
 * libmodbus opens and configures the line (modbus_new_rtu + modbus_connect: termios, non-blocking);
 * the shared map builds and sends the replies. Framing follows Modbus over Serial Line V1.02
 * §2.5.1.1, without blocking: every read is stamped with the monotonic clock; a silence of 3.5
 * character times (t3.5) ends a frame, a silence of 1.5 character times (t1.5) inside an
 * unfinished frame makes it incomplete (discarded, and what follows is dropped until the next
 * t3.5). A character is 11 bits; above 19 200 baud t1.5 = 750 us and t3.5 = 1750 us.
 *
 * Inside one block of bytes (no t3.5 silence in it; a late read can hold several frames) each
 * frame is cut where its CRC-16 closes: at the request length of its function, or (for another
 * unit) at the length of the response or exception it may be, or, for a function of no known
 * length, at the first position where the CRC checks. A frame addressed to us is answered as soon
 * as its request length is complete and its CRC is right; frames to other units (requests,
 * responses, exceptions, unknown functions) and broadcasts (unit 0) are skipped without a word.
 * Static state only. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
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
    int len;              /* bytes of the current block not yet cut into frames */
    int discard;          /* 1: a broken frame; drop bytes until a t3.5 silence */
    uint64_t last_rx_us;  /* monotonic time of the last read that brought bytes */
    uint32_t t15_us, t35_us; /* 0 for t15_us: no inter-character check */
    uint32_t bad_frames, served, other_frames;
    uint8_t buf[RTU_MAX];
} mbrtu_state;

static mbrtu_state g_rtu;
static int g_test_fd = -1; /* >= 0: serve this descriptor instead of a serial device (tests) */

static uint64_t monotonic_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint64_t (*g_clock_us)(void) = monotonic_us;

void sc_modbus_rtu_use_fd(int fd)
{
    g_test_fd = fd;
}

void sc_modbus_rtu_use_clock(uint64_t (*clock_us)(void))
{
    g_clock_us = clock_us != NULL ? clock_us : monotonic_us;
}

void sc_mbrtu_config_defaults(sc_mbrtu_config *c)
{
    memset(c, 0, sizeof *c);
    c->baud = 19200;
    c->parity = 'E';
    c->data_bits = 8;
    c->stop_bits = 1;
    c->unit_id = 1;
    c->byte_timeout_ms = 0; /* the specification's t1.5 / t3.5 */
}

void sc_mbrtu_silences(const sc_mbrtu_config *c, uint32_t *t15_us, uint32_t *t35_us)
{
    if (c->byte_timeout_ms > 0) { /* a bursty adapter: one silence, no inter-character check */
        *t15_us = 0;
        *t35_us = c->byte_timeout_ms * 1000u;
    } else if (c->baud > 19200) {
        *t15_us = 750;
        *t35_us = 1750;
    } else {
        int baud = c->baud > 0 ? c->baud : 19200;
        /* 11 bits a character; rounded up */
        *t15_us = (uint32_t)((15u * 11u * 1000000u / 10u + (unsigned)baud - 1u) / (unsigned)baud);
        *t35_us = (uint32_t)((35u * 11u * 1000000u / 10u + (unsigned)baud - 1u) / (unsigned)baud);
    }
}

uint32_t sc_modbus_rtu_bad_frames(void)
{
    return g_rtu.bad_frames;
}

uint32_t sc_modbus_rtu_other_frames(void)
{
    return g_rtu.other_frames;
}

/* Length of the request with function b[1] (with its CRC): > 0; 0 if more bytes are needed to
 * know it; -1 if the function has no known request length. */
static int request_len(const uint8_t *b, int have)
{
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

/* Length of the normal or exception response with function b[1]: as request_len. */
static int response_len(const uint8_t *b, int have)
{
    if (b[1] & 0x80)
        return 5;
    switch (b[1]) {
    case 1: case 2: case 3: case 4: case 12: case 17: case 20: case 21: case 23:
        return have < 3 ? 0 : 5 + b[2];
    case 5: case 6: case 11: case 15: case 16:
        return 8;
    case 7:
        return 5;
    case 22:
        return 10;
    default:
        return -1;
    }
}

static int crc_ok(const uint8_t *b, int n)
{
    uint16_t crc = sc_modbus_crc16(b, n - 2);
    return b[n - 2] == (crc & 0xff) && b[n - 1] == (crc >> 8);
}

typedef enum { CUT_WAIT, CUT_FRAME, CUT_BAD } cut_result;

/* Where the frame at the start of b (have bytes) ends: CUT_FRAME with *flen, CUT_WAIT (more bytes
 * may complete it), CUT_BAD (no frame can start here). */
static cut_result cut_frame(const uint8_t *b, int have, uint8_t unit, int *flen)
{
    if (have < 2)
        return CUT_WAIT;
    int cand[2] = {request_len(b, have), b[0] == unit ? -1 : response_len(b, have)};
    int known = 0, waiting = 0, best = 0;
    for (int k = 0; k < 2; k++) {
        if (cand[k] < 0)
            continue;
        known = 1;
        if (cand[k] > RTU_MAX)
            continue; /* no such frame fits a serial line */
        if (cand[k] == 0 || cand[k] > have) {
            waiting = 1;
            continue;
        }
        if (crc_ok(b, cand[k]) && (best == 0 || cand[k] < best))
            best = cand[k];
    }
    if (best > 0) {
        *flen = best;
        return CUT_FRAME;
    }
    if (known && b[0] == unit)
        return waiting ? CUT_WAIT : CUT_BAD; /* ours: only its request length counts */
    if (waiting)
        return CUT_WAIT;
    /* no known length, or none of them closes the CRC: the first position where it does */
    uint16_t crc = 0xffff;
    int lim = have < RTU_MAX ? have : RTU_MAX;
    for (int n = 0; n + 2 <= lim; n++) {
        if (n >= 2 && b[n] == (crc & 0xff) && b[n + 1] == (crc >> 8)) {
            *flen = n + 2;
            return CUT_FRAME;
        }
        crc = sc_modbus_crc16_update(crc, b[n]);
    }
    return have >= RTU_MAX ? CUT_BAD : CUT_WAIT;
}

static sc_status rtu_open(void *state, sc_error *err)
{
    mbrtu_state *s = state;
    sc_modbus_map_open(sc_modbus_map_shared(), s->cfg.word_order);
    if (s->cfg.unit_id < 1 || s->cfg.unit_id > 247) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "modbus-rtu: unit id must be 1..247");
    }
    sc_mbrtu_silences(&s->cfg, &s->t15_us, &s->t35_us);
    s->len = 0;
    s->discard = 0;
    if (g_test_fd >= 0) {
        s->fd = g_test_fd;
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
    sc_log(SC_LOG_NOTICE,
           "modbus-rtu: serving %s at %d baud %d%c%d (unit id %u); frames end after %u us of "
           "silence%s",
           s->cfg.device, s->cfg.baud, s->cfg.data_bits, s->cfg.parity, s->cfg.stop_bits,
           (unsigned)s->cfg.unit_id, (unsigned)s->t35_us,
           s->t15_us ? "" : " (--rtu-byte-timeout-ms; no inter-character check)");
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
    if (b[0] != s->cfg.unit_id) {
        s->other_frames++; /* another device's request, response or exception, or a broadcast */
        return;
    }
    if (sc_modbus_map_reply(sc_modbus_map_shared(), s->fd, b, flen, 1, 2, e) < 0)
        sc_log(SC_LOG_WARNING, "modbus-rtu: reply not sent: %s", strerror(errno));
    s->served++;
}

/* Cut and handle the complete frames at the start of the block. */
static void rtu_process(mbrtu_state *s, sc_engine *e)
{
    while (s->len > 0 && !s->discard) {
        int flen = 0;
        cut_result r = cut_frame(s->buf, s->len, s->cfg.unit_id, &flen);
        if (r == CUT_WAIT)
            return;
        if (r == CUT_BAD) {
            s->bad_frames++;
            s->discard = 1; /* the rest of this block cannot be framed */
            s->len = 0;
            return;
        }
        rtu_frame(s, flen, e);
        memmove(s->buf, s->buf + flen, (size_t)(s->len - flen));
        s->len -= flen;
    }
}

/* A t3.5 silence: the block ends; what is left of it is not a frame. */
static void rtu_end_block(mbrtu_state *s)
{
    if (s->len > 0)
        s->bad_frames++;
    s->len = 0;
    s->discard = 0;
}

static void rtu_serve(void *state, struct pollfd *fds, int n, sc_engine *e, uint64_t now_ms)
{
    mbrtu_state *s = state;
    (void)now_ms; /* too coarse: each read is stamped with its own clock */
    if (n < 1 || fds[0].revents == 0)
        return;
    if (fds[0].revents & (POLLERR | POLLNVAL)) {
        sc_log(SC_LOG_ERR, "modbus-rtu: %s: device error", s->cfg.device);
        return;
    }
    for (;;) {
        uint8_t chunk[RTU_MAX];
        ssize_t r = read(s->fd, chunk, sizeof chunk);
        if (r <= 0) {
            if (r < 0 && errno == EINTR)
                continue;
            break;
        }
        uint64_t now = g_clock_us();
        uint64_t gap = now - s->last_rx_us;
        if (gap >= s->t35_us) {
            rtu_end_block(s);
        } else if (s->t15_us > 0 && gap >= s->t15_us && s->len > 0 && !s->discard) {
            s->bad_frames++; /* t1.5 inside a frame: incomplete, dropped until the next t3.5 */
            s->len = 0;
            s->discard = 1;
        }
        s->last_rx_us = now;
        if (s->discard)
            continue;
        for (ssize_t i = 0; i < r;) {
            ssize_t take = r - i;
            if (take > (ssize_t)sizeof s->buf - s->len)
                take = (ssize_t)sizeof s->buf - s->len;
            memcpy(s->buf + s->len, chunk + i, (size_t)take);
            s->len += (int)take;
            i += take;
            rtu_process(s, e);
            if (s->discard)
                break;
            if (s->len == (int)sizeof s->buf) { /* cannot happen: cut_frame decides by 256 */
                s->bad_frames++;
                s->len = 0;
                s->discard = 1;
                break;
            }
        }
    }
}

static void rtu_tick(void *state, sc_engine *e, uint64_t now_ms)
{
    mbrtu_state *s = state;
    (void)e;
    (void)now_ms;
    if ((s->len > 0 || s->discard) && g_clock_us() - s->last_rx_us >= s->t35_us)
        rtu_end_block(s);
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
