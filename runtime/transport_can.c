/* runtime/transport_can.c — SocketCAN raw transport of selfcald (SPEC §4 "CAN").
 *
 * One raw CAN socket, non-blocking (kernel filters for the configured ids with --can-other-ids
 * ignore; else every frame is read, another id counted as bad), with a subscription
 * to the error frames that tell the bus state. Received frames are read in batches (recvmmsg);
 * every answer and status frame goes through a small static transmit queue that is flushed with
 * sendmmsg. A send the kernel refuses because its queue is full (ENOBUFS/EAGAIN) is counted and
 * retried on the next serve or tick; the loop never blocks. Bus-off and interface loss are logged,
 * reported in the status frame, and survived: the socket is kept (interface down) or reopened
 * (interface removed) and service resumes when the bus returns. Static state only; nothing is
 * allocated.
 */
#define _GNU_SOURCE /* recvmmsg, sendmmsg */
#include "transport_can.h"

#include "log.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <syslog.h>
#include <unistd.h>

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif

enum {
    RX_BATCH = 32,      /* frames per recvmmsg */
    RX_ROUNDS = 8,      /* recvmmsg calls per serve, so other transports get their turn */
    TX_QUEUE = 256,     /* frames waiting for the kernel (power of two) */
    TX_BATCH = 32,      /* frames per sendmmsg */
    REOPEN_MS = 1000,   /* retry period while the interface is gone */
    RATE_LOG_MS = 10000 /* at most one log line per condition per this period */
};

typedef struct tx_slot {
    struct canfd_frame frame;
    uint8_t mtu; /* CAN_MTU or CANFD_MTU: bytes to write */
} tx_slot;

typedef struct can_state {
    sc_can_config cfg;
    int fd;
    int test_fd; /* >= 0: use this descriptor instead of a CAN socket */
    int fd_frames; /* CAN FD frames enabled on the socket */
    int status_started;
    uint64_t next_status_ms;
    uint64_t next_reopen_ms;
    uint64_t now_ms; /* of the current serve/tick */
    uint64_t last_qfull_log_ms, last_ovfl_log_ms, last_rxovfl_log_ms;
    int reopen_failed_logged;
    uint32_t rx_ovfl_seen; /* the kernel's cumulative drop count, last value seen */
    uint64_t rx_ovfl_logged; /* S.st.rx_overflow when it was last logged */
    uint8_t flags_since_status; /* SC_CAN_ST_* seen since the last status frame */
    sc_can_stats st;
    /* transmit queue */
    tx_slot txq[TX_QUEUE];
    unsigned tx_head, tx_count;
    /* receive batch */
    struct canfd_frame rx_frame[RX_BATCH];
    struct iovec rx_iov[RX_BATCH];
    struct mmsghdr rx_msg[RX_BATCH];
    union {
        char buf[CMSG_SPACE(sizeof(uint32_t))];
        struct cmsghdr align;
    } rx_ctrl[RX_BATCH];
    /* transmit batch */
    struct iovec tx_iov[TX_BATCH];
    struct mmsghdr tx_msg[TX_BATCH];
} can_state;

static can_state S = {.fd = -1, .test_fd = -1};

/* ---------------------------------------------------------------- frames */

static void put_u32le(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int32_t u32_to_i32(uint32_t u)
{
    /* two's complement without implementation-defined conversion */
    return u <= 0x7fffffffu ? (int32_t)u : -(int32_t)(0xffffffffu - u) - 1;
}

void sc_can_encode_position(uint8_t data[8], int32_t x_nm, int32_t y_nm)
{
    put_u32le(data, (uint32_t)x_nm);
    put_u32le(data + 4, (uint32_t)y_nm);
}

void sc_can_decode_position(const uint8_t data[8], int32_t *x_nm, int32_t *y_nm)
{
    *x_nm = u32_to_i32(get_u32le(data));
    *y_nm = u32_to_i32(get_u32le(data + 4));
}

void sc_can_encode_status(uint8_t data[8], uint8_t status_bits, uint16_t bad_frames,
                          uint32_t corrections)
{
    data[0] = status_bits;
    data[1] = 0;
    data[2] = (uint8_t)bad_frames;
    data[3] = (uint8_t)(bad_frames >> 8);
    put_u32le(data + 4, corrections);
}

sc_can_rx_kind sc_can_classify(const sc_can_config *c, uint32_t can_id, uint8_t len)
{
    if (can_id & CAN_ERR_FLAG)
        return SC_CAN_RX_ERROR;
    if (can_id & CAN_EFF_FLAG) {
        /* an extended-format frame: carrying one of our numbers, the wrong format; another, a
         * bad id unless other ids are ignored */
        uint32_t id = can_id & CAN_EFF_MASK;
        if (id == c->in_id || id == c->out_id || id == c->status_id || !c->ignore_other_ids)
            return SC_CAN_RX_BAD;
        return SC_CAN_RX_IGNORE;
    }
    uint32_t id = can_id & CAN_SFF_MASK;
    if (id == c->in_id) {
        if (can_id & CAN_RTR_FLAG)
            return SC_CAN_RX_BAD;
        return len == 8 ? SC_CAN_RX_POSITION : SC_CAN_RX_BAD;
    }
    if (id == c->out_id || id == c->status_id)
        return SC_CAN_RX_BAD; /* another node sends on our output ids */
    return c->ignore_other_ids ? SC_CAN_RX_IGNORE : SC_CAN_RX_BAD;
}

/* ---------------------------------------------------------------- config */

void sc_can_config_defaults(sc_can_config *c)
{
    memset(c, 0, sizeof *c);
    c->in_id = 0x100;
    c->out_id = 0x101;
    c->status_id = 0x102;
    c->status_period_ms = 1000;
    c->log = NULL;
}

sc_status sc_can_config_check(const sc_can_config *c, sc_error *err)
{
    if (c->ifname[0] == '\0' || memchr(c->ifname, '\0', sizeof c->ifname) == NULL ||
        strlen(c->ifname) >= IFNAMSIZ) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "CAN: interface name missing or longer than %d characters",
                            IFNAMSIZ - 1);
    }
    const uint32_t ids[3] = {c->in_id, c->out_id, c->status_id};
    const char *names[3] = {"input", "output", "status"};
    for (int k = 0; k < 3; k++) {
        if (ids[k] > CAN_SFF_MASK) {
            return sc_error_set(err, SC_E_INPUT, NULL, 0, "CAN: %s id 0x%x is not an 11-bit id (max 0x7ff)",
                                names[k], (unsigned)ids[k]);
        }
    }
    if (c->in_id == c->out_id || c->in_id == c->status_id || c->out_id == c->status_id) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "CAN: ids must differ (in 0x%x, out 0x%x, status 0x%x)",
                            (unsigned)c->in_id, (unsigned)c->out_id, (unsigned)c->status_id);
    }
    if (c->status_period_ms == 0) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "CAN: status period must be > 0 ms");
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- logging */

__attribute__((format(printf, 2, 3))) static void can_log(int prio, const char *fmt, ...)
{
    static char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (S.cfg.log)
        S.cfg.log(prio, msg);
    else
        sc_log(prio, "%s", msg); /* the daemon's log: stderr or syslog */
}

/* ---------------------------------------------------------------- socket */

static void close_socket(void)
{
    if (S.fd >= 0 && S.fd != S.test_fd)
        close(S.fd);
    S.fd = -1;
}

/* Open, filter and bind the CAN socket. SC_OK, or a status with the reason in err. */
static sc_status open_socket(sc_error *err)
{
    S.fd_frames = 0;
    if (S.test_fd >= 0) {
        S.fd = S.test_fd;
        return SC_OK;
    }
    int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0) {
        return sc_error_set(err, SC_E_IO, NULL, 0, "CAN: socket(PF_CAN, SOCK_RAW, CAN_RAW): %s%s",
                            strerror(errno),
                            errno == EAFNOSUPPORT ? " (this kernel has no CAN support: modprobe can-raw)" : "");
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    memcpy(ifr.ifr_name, S.cfg.ifname, strlen(S.cfg.ifname) + 1);
    if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
        close(fd);
        return sc_error_set(err, SC_E_IO, NULL, 0, "CAN: interface %s: %s", S.cfg.ifname, strerror(errno));
    }
    /* With other ids ignored, the kernel passes only ours: our input id (standard frames, data
     * and remote: remote frames are counted as bad), the same number as an extended id (bad), and
     * our output ids (another sender there is a conflict). Else every frame is read (the default
     * socket filter), a frame on another id being a bad one. */
    const uint32_t sff = CAN_SFF_MASK | CAN_EFF_FLAG;
    const uint32_t eff = CAN_EFF_MASK | CAN_EFF_FLAG;
    struct can_filter filt[6] = {
        {S.cfg.in_id, sff},
        {S.cfg.in_id | CAN_EFF_FLAG, eff},
        {S.cfg.out_id, sff},
        {S.cfg.out_id | CAN_EFF_FLAG, eff},
        {S.cfg.status_id, sff},
        {S.cfg.status_id | CAN_EFF_FLAG, eff},
    };
    if (S.cfg.ignore_other_ids &&
        setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filt, sizeof filt) < 0) {
        close(fd);
        return sc_error_set(err, SC_E_IO, NULL, 0, "CAN: CAN_RAW_FILTER: %s", strerror(errno));
    }
    can_err_mask_t err_mask = CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_BUSOFF |
                              CAN_ERR_RESTARTED;
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) {
        close(fd);
        return sc_error_set(err, SC_E_IO, NULL, 0, "CAN: CAN_RAW_ERR_FILTER: %s", strerror(errno));
    }
    /* Optional features: CAN FD frames, the kernel's count of dropped input frames, a larger
     * receive buffer (capped by net.core.rmem_max). */
    int on = 1;
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) == 0)
        S.fd_frames = 1;
    (void)setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);
    /* A receive queue for bursts: ~1 MB holds over a thousand frames. SO_RCVBUFFORCE needs
     * CAP_NET_ADMIN; without it SO_RCVBUF is capped by net.core.rmem_max. */
    int rcvbuf = 1 << 20;
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) < 0)
        (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        close(fd);
        return sc_error_set(err, SC_E_IO, NULL, 0, "CAN: bind to %s: %s", S.cfg.ifname, strerror(errno));
    }
    S.fd = fd;
    S.rx_ovfl_seen = 0;
    return SC_OK;
}

/* The interface went away (ENODEV/ENXIO): close now, reopen from tick. */
static void lose_interface(uint64_t now_ms, int err)
{
    /* once per loss: the socket is closed below */
    can_log(LOG_ERR, "CAN %s: interface lost (%s); reopening every %d ms", S.cfg.ifname,
            strerror(err), REOPEN_MS);
    S.st.link_down_now = 1;
    S.flags_since_status |= SC_CAN_ST_LOST;
    S.st.tx_dropped += S.tx_count;
    S.tx_count = 0;
    if (S.test_fd < 0)
        close_socket();
    S.next_reopen_ms = now_ms + REOPEN_MS;
    S.reopen_failed_logged = 0;
}

static void link_down(int err)
{
    if (!S.st.link_down_now)
        can_log(LOG_WARNING, "CAN %s: %s; waiting for the interface to come back", S.cfg.ifname,
                strerror(err));
    S.st.link_down_now = 1;
}

static void link_alive(void)
{
    if (S.st.link_down_now) {
        can_log(LOG_NOTICE, "CAN %s: interface up again", S.cfg.ifname);
        S.st.link_down_now = 0;
    }
}

static void bus_back(const char *how)
{
    if (S.st.bus_off_now) {
        can_log(LOG_NOTICE, "CAN %s: bus back (%s)", S.cfg.ifname, how);
        S.st.bus_off_now = 0;
    }
}

/* ---------------------------------------------------------------- transmit */

static void tx_flush(uint64_t now_ms)
{
    while (S.tx_count > 0 && S.fd >= 0) {
        unsigned n = S.tx_count < TX_BATCH ? S.tx_count : TX_BATCH;
        for (unsigned k = 0; k < n; k++) {
            tx_slot *s = &S.txq[(S.tx_head + k) & (TX_QUEUE - 1)];
            S.tx_iov[k].iov_base = &s->frame;
            S.tx_iov[k].iov_len = s->mtu;
            memset(&S.tx_msg[k], 0, sizeof S.tx_msg[k]);
            S.tx_msg[k].msg_hdr.msg_iov = &S.tx_iov[k];
            S.tx_msg[k].msg_hdr.msg_iovlen = 1;
        }
        int r = sendmmsg(S.fd, S.tx_msg, n, MSG_DONTWAIT);
        if (r > 0) {
            S.tx_head = (S.tx_head + (unsigned)r) & (TX_QUEUE - 1);
            S.tx_count -= (unsigned)r;
            S.st.tx_frames += (uint32_t)r;
            link_alive();
            continue;
        }
        if (r == 0)
            return;
        int err = errno;
        if (err == EINTR)
            continue;
        if (err == EAGAIN || err == EWOULDBLOCK || err == ENOBUFS) {
            /* the kernel's queue is full: keep the frames, retry on the next serve or tick */
            S.st.tx_queue_full++;
            if (now_ms >= S.last_qfull_log_ms + RATE_LOG_MS || S.last_qfull_log_ms == 0) {
                can_log(LOG_WARNING, "CAN %s: transmit queue full (%u times so far)", S.cfg.ifname,
                        (unsigned)S.st.tx_queue_full);
                S.last_qfull_log_ms = now_ms ? now_ms : 1;
            }
            return;
        }
        if (err == ENODEV || err == ENXIO) {
            lose_interface(now_ms, err);
            return;
        }
        if (err == ENETDOWN) {
            /* interface down: stale answers are of no use when it comes back */
            link_down(err);
            S.st.tx_dropped += S.tx_count;
            S.flags_since_status |= SC_CAN_ST_LOST;
            S.tx_count = 0;
            return;
        }
        /* anything else concerns this frame (e.g. an FD frame on a classic interface): drop it */
        can_log(LOG_ERR, "CAN %s: send: %s (frame dropped)", S.cfg.ifname, strerror(err));
        S.st.tx_dropped++;
        S.flags_since_status |= SC_CAN_ST_LOST;
        S.tx_head = (S.tx_head + 1) & (TX_QUEUE - 1);
        S.tx_count--;
    }
}

/* Queue one frame; returns its payload to fill, or NULL (counted) when the queue is full. */
static uint8_t *tx_push(uint32_t can_id, int fd_frame, uint8_t fd_flags)
{
    if (S.tx_count == TX_QUEUE) {
        S.st.tx_dropped++;
        S.flags_since_status |= SC_CAN_ST_LOST;
        return NULL;
    }
    tx_slot *s = &S.txq[(S.tx_head + S.tx_count) & (TX_QUEUE - 1)];
    S.tx_count++;
    memset(&s->frame, 0, sizeof s->frame);
    s->frame.can_id = can_id;
    s->frame.len = 8;
    s->frame.flags = fd_frame ? fd_flags : 0;
    s->mtu = fd_frame ? CANFD_MTU : CAN_MTU;
    return s->frame.data;
}

static void queue_status(const sc_engine *e)
{
    uint8_t bits = (uint8_t)((e->status & 0x3fu) | S.flags_since_status);
    if (S.st.bus_off_now)
        bits |= SC_CAN_ST_BUS_OFF;
    uint8_t *d = tx_push(S.cfg.status_id, 0, 0);
    if (d) {
        sc_can_encode_status(d, bits, (uint16_t)S.st.bad_frames, e->corrections);
        S.flags_since_status = 0;
    }
}

/* ---------------------------------------------------------------- receive */

static void on_error_frame(const struct canfd_frame *f, uint64_t now_ms)
{
    S.st.error_frames++;
    if (f->can_id & CAN_ERR_BUSOFF) {
        if (!S.st.bus_off_now) {
            S.st.bus_off++;
            can_log(LOG_ERR, "CAN %s: bus-off (controller stopped; waiting for the bus to return)",
                    S.cfg.ifname);
        }
        S.st.bus_off_now = 1;
        S.flags_since_status |= SC_CAN_ST_BUS_OFF;
    }
    if (f->can_id & CAN_ERR_RESTARTED)
        bus_back("controller restarted");
    if (f->can_id & CAN_ERR_CRTL) {
        if (f->data[1] & CAN_ERR_CRTL_ACTIVE)
            bus_back("error-active again");
        if (f->data[1] & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) {
            S.flags_since_status |= SC_CAN_ST_LOST;
            if (now_ms >= S.last_ovfl_log_ms + RATE_LOG_MS || S.last_ovfl_log_ms == 0) {
                can_log(LOG_WARNING, "CAN %s: controller buffer overflow (frames lost)",
                        S.cfg.ifname);
                S.last_ovfl_log_ms = now_ms ? now_ms : 1;
            }
        }
    }
    if (f->can_id & CAN_ERR_TX_TIMEOUT)
        can_log(LOG_WARNING, "CAN %s: transmit timeout", S.cfg.ifname);
}

static void on_frame(const struct canfd_frame *f, int is_fd, sc_engine *e, uint64_t now_ms)
{
    S.st.rx_frames++;
    sc_can_rx_kind kind = sc_can_classify(&S.cfg, f->can_id, f->len);
    if (kind == SC_CAN_RX_ERROR) {
        on_error_frame(f, now_ms);
        return;
    }
    /* a data frame arrived: the bus works */
    bus_back("traffic");
    link_alive();
    if (kind == SC_CAN_RX_IGNORE)
        return;
    if (kind == SC_CAN_RX_BAD) {
        S.st.bad_frames++;
        return;
    }
    int32_t x, y, cx, cy;
    sc_can_decode_position(f->data, &x, &y);
    (void)sc_engine_correct(e, x, y, &cx, &cy);
    S.st.positions++;
    uint8_t *d = tx_push(S.cfg.out_id, is_fd, (uint8_t)(f->flags & (CANFD_BRS | CANFD_FDF)));
    if (d)
        sc_can_encode_position(d, cx, cy);
}

/* The kernel's input drops so far, in a line (rate-limited by the callers: at the first drop,
 * then at most once per RATE_LOG_MS while more come, and at the close). */
static void log_rx_overflow(void)
{
    can_log(LOG_WARNING,
            "CAN %s: the kernel dropped %llu input frames so far (receive queue full: the daemon "
            "is too slow, or raise net.core.rmem_max)",
            S.cfg.ifname, (unsigned long long)S.st.rx_overflow);
    S.last_rxovfl_log_ms = S.now_ms ? S.now_ms : 1;
    S.rx_ovfl_logged = S.st.rx_overflow;
}

static void account_overflow(const struct msghdr *h)
{
    for (struct cmsghdr *c = CMSG_FIRSTHDR(h); c; c = CMSG_NXTHDR((struct msghdr *)h, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
            uint32_t drops;
            memcpy(&drops, CMSG_DATA(c), sizeof drops);
            if (drops != S.rx_ovfl_seen) {
                uint32_t delta = drops - S.rx_ovfl_seen;
                S.st.rx_overflow += delta;
                S.rx_ovfl_seen = drops;
                S.flags_since_status |= SC_CAN_ST_LOST;
                if (S.now_ms >= S.last_rxovfl_log_ms + RATE_LOG_MS || S.last_rxovfl_log_ms == 0)
                    log_rx_overflow();
            }
        }
    }
}

/* Read what is waiting (bounded), answer it. */
static void rx_drain(sc_engine *e, uint64_t now_ms)
{
    S.now_ms = now_ms;
    for (int round = 0; round < RX_ROUNDS && S.fd >= 0; round++) {
        for (int k = 0; k < RX_BATCH; k++) {
            S.rx_iov[k].iov_base = &S.rx_frame[k];
            S.rx_iov[k].iov_len = sizeof S.rx_frame[k];
            memset(&S.rx_msg[k], 0, sizeof S.rx_msg[k]);
            S.rx_msg[k].msg_hdr.msg_iov = &S.rx_iov[k];
            S.rx_msg[k].msg_hdr.msg_iovlen = 1;
            S.rx_msg[k].msg_hdr.msg_control = S.rx_ctrl[k].buf;
            S.rx_msg[k].msg_hdr.msg_controllen = sizeof S.rx_ctrl[k].buf;
        }
        int r = recvmmsg(S.fd, S.rx_msg, RX_BATCH, MSG_DONTWAIT, NULL);
        if (r < 0) {
            int err = errno;
            if (err == EAGAIN || err == EWOULDBLOCK || err == EINTR)
                break;
            if (err == ENODEV || err == ENXIO)
                lose_interface(now_ms, err);
            else if (err == ENETDOWN)
                link_down(err);
            else
                can_log(LOG_ERR, "CAN %s: receive: %s", S.cfg.ifname, strerror(err));
            break;
        }
        for (int k = 0; k < r; k++) {
            account_overflow(&S.rx_msg[k].msg_hdr);
            unsigned len = S.rx_msg[k].msg_len;
            if (len == CAN_MTU)
                on_frame(&S.rx_frame[k], 0, e, now_ms);
            else if (len == CANFD_MTU)
                on_frame(&S.rx_frame[k], 1, e, now_ms);
            else
                S.st.bad_frames++; /* not a CAN frame (cannot happen on a CAN socket) */
        }
        tx_flush(now_ms);
        if (r < RX_BATCH)
            break;
    }
}

/* ---------------------------------------------------------------- interface */

static sc_status can_open(void *state, sc_error *err)
{
    (void)state;
    sc_status st = sc_can_config_check(&S.cfg, err);
    if (st == SC_OK)
        st = open_socket(err);
    if (st != SC_OK)
        return st;
    can_log(LOG_INFO, "CAN %s: serving ids 0x%03x in, 0x%03x out, 0x%03x status every %u ms%s",
            S.cfg.ifname, (unsigned)S.cfg.in_id, (unsigned)S.cfg.out_id,
            (unsigned)S.cfg.status_id, (unsigned)S.cfg.status_period_ms,
            S.fd_frames ? " (CAN FD accepted)" : "");
    return SC_OK;
}

static int can_fill_pollfds(void *state, struct pollfd *fds, int max)
{
    (void)state;
    if (S.fd < 0 || max < 1)
        return 0;
    fds[0].fd = S.fd;
    fds[0].events = POLLIN;
    fds[0].revents = 0;
    return 1;
}

static void can_serve(void *state, struct pollfd *fds, int n, sc_engine *e, uint64_t now_ms)
{
    (void)state;
    if (S.tx_count > 0)
        tx_flush(now_ms);
    for (int k = 0; k < n; k++) {
        if (fds[k].fd == S.fd && S.fd >= 0 && (fds[k].revents & (POLLIN | POLLERR | POLLHUP)))
            rx_drain(e, now_ms);
    }
}

static void can_tick(void *state, sc_engine *e, uint64_t now_ms)
{
    (void)state;
    if (S.fd < 0 && S.test_fd < 0 && now_ms >= S.next_reopen_ms) {
        sc_error why;
        if (open_socket(&why) == SC_OK) {
            S.st.reopened++;
            can_log(LOG_NOTICE, "CAN %s: socket reopened", S.cfg.ifname);
            link_alive();
        } else {
            if (!S.reopen_failed_logged)
                can_log(LOG_WARNING, "%s (still retrying)", why.msg);
            S.reopen_failed_logged = 1;
            S.next_reopen_ms = now_ms + REOPEN_MS;
        }
    }
    /* drops that came after the last (rate-limited) line: said once the limit allows */
    if (S.st.rx_overflow != S.rx_ovfl_logged && now_ms >= S.last_rxovfl_log_ms + RATE_LOG_MS) {
        S.now_ms = now_ms;
        log_rx_overflow();
    }
    if (S.fd < 0)
        return;
    if (!S.status_started || now_ms >= S.next_status_ms) { /* the first frame at once */
        queue_status(e);
        if (!S.status_started || now_ms >= S.next_status_ms + S.cfg.status_period_ms)
            S.next_status_ms = now_ms + S.cfg.status_period_ms; /* first frame, or we fell behind */
        else
            S.next_status_ms += S.cfg.status_period_ms; /* keep the 1 Hz cadence exact */
        S.status_started = 1;
    }
    tx_flush(now_ms);
}

static void can_close(void *state)
{
    (void)state;
    if (S.st.rx_overflow != S.rx_ovfl_logged) /* the total, however recent the last drops */
        log_rx_overflow();
    close_socket();
    S.tx_count = 0;
}

void sc_can_transport(sc_transport *t, const sc_can_config *cfg)
{
    int test_fd = S.test_fd;
    close_socket();
    memset(&S, 0, sizeof S);
    S.fd = -1;
    S.test_fd = test_fd;
    S.cfg = *cfg;
    S.cfg.ifname[sizeof S.cfg.ifname - 1] = '\0';
    t->name = "can";
    t->state = &S;
    t->open = can_open;
    t->fill_pollfds = can_fill_pollfds;
    t->serve = can_serve;
    t->tick = can_tick;
    t->close = can_close;
}

void sc_can_get_stats(sc_can_stats *s) { *s = S.st; }

void sc_can_transport_use_fd(int fd) { S.test_fd = fd; }
