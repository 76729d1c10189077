/* Fault injection into the SocketCAN transport (runtime/transport_can.c): what a kernel with a CAN
 * stack reports only under stress, made to happen on demand. The transport is linked with the
 * system calls it makes wrapped (-Wl,--wrap=socket,ioctl,setsockopt,bind,recvmmsg,sendmmsg; see
 * can_faults.cmake): socket() hands out one end of a SOCK_SEQPACKET socketpair that plays the raw
 * CAN socket, and each call can be made to fail with the errno a real one gives (ENODEV for an
 * interface removed, ENETDOWN for one set down, ENOBUFS for a full transmit queue), or deliver
 * the kernel's SO_RXQ_OVFL count of dropped input frames as a control message. Checked: the
 * counters, the status frame's bits, the log lines and their rate limits, the socket closed and
 * reopened, the options asked of the kernel, and the test hook's descriptor 0. The real-bus path
 * is tests/integration/vcan (vcan_selfcald); test_can covers the frames and the queue. */
#define _GNU_SOURCE
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <errno.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <syslog.h>
#include <unistd.h>

#include "transport_can.h"

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif
#ifndef SO_MARK
#define SO_MARK 36
#endif

/* ---------------------------------------------------------------- fake engine */

uint16_t sc_engine_correct(sc_engine *e, int32_t x_nm, int32_t y_nm, int32_t *out_x_nm,
                           int32_t *out_y_nm)
{
    *out_x_nm = x_nm + 7;
    *out_y_nm = y_nm - 3;
    e->corrections++;
    e->status = SC_CORR_ST_LOADED;
    return e->status;
}

/* ---------------------------------------------------------------- the fake kernel */

static struct {
    int fd, peer;            /* the socket handed out (the transport's side) and the bus side */
    int sockets;             /* socket() calls */
    int socket_errno;        /* socket() fails with this (0: succeeds) */
    int ioctl_errno;         /* SIOCGIFINDEX fails with this */
    int fd_frames_ok;        /* CAN_RAW_FD_FRAMES accepted */
    int filters;             /* CAN_RAW_FILTER: filters set */
    struct can_filter filt[8];
    can_err_mask_t err_mask; /* CAN_RAW_ERR_FILTER */
    int rxq_ovfl_on;         /* SO_RXQ_OVFL asked for */
    int bound_ifindex;
    int rx_errno;            /* the next recvmmsg fails with this */
    int cmsg_level, cmsg_type; /* the next recvmmsg's first message carries this control message */
    uint32_t cmsg_value;
    int cmsg_pending;
    int tx_errno;            /* the next sendmmsg fails with this (tx_fail times) */
    int tx_fail;
} K;

int __real_socket(int domain, int type, int protocol);
int __real_ioctl(int fd, unsigned long req, ...);
int __real_setsockopt(int fd, int level, int name, const void *val, socklen_t len);
int __real_bind(int fd, const struct sockaddr *a, socklen_t len);
int __real_recvmmsg(int fd, struct mmsghdr *v, unsigned int n, int flags, struct timespec *t);
int __real_sendmmsg(int fd, struct mmsghdr *v, unsigned int n, int flags);

int __wrap_socket(int domain, int type, int protocol);
int __wrap_ioctl(int fd, unsigned long req, ...);
int __wrap_setsockopt(int fd, int level, int name, const void *val, socklen_t len);
int __wrap_bind(int fd, const struct sockaddr *a, socklen_t len);
int __wrap_recvmmsg(int fd, struct mmsghdr *v, unsigned int n, int flags, struct timespec *t);
int __wrap_sendmmsg(int fd, struct mmsghdr *v, unsigned int n, int flags);

int __wrap_socket(int domain, int type, int protocol)
{
    assert_int_equal(domain, PF_CAN);
    assert_int_equal(protocol, CAN_RAW);
    assert_true(type & SOCK_NONBLOCK);
    K.sockets++;
    if (K.socket_errno) {
        errno = K.socket_errno;
        return -1;
    }
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK, 0, sv), 0);
    if (K.peer >= 0)
        close(K.peer); /* the bus of the previous socket */
    K.peer = sv[0];
    K.fd = sv[1];
    K.filters = 0;
    K.rxq_ovfl_on = 0;
    return K.fd;
}

int __wrap_ioctl(int fd, unsigned long req, ...)
{
    va_list ap;
    va_start(ap, req);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    if (fd != K.fd || req != SIOCGIFINDEX)
        return __real_ioctl(fd, req, arg);
    if (K.ioctl_errno) {
        errno = K.ioctl_errno;
        return -1;
    }
    struct ifreq *ifr = arg;
    assert_string_equal(ifr->ifr_name, "fault0");
    ifr->ifr_ifindex = 7;
    return 0;
}

int __wrap_setsockopt(int fd, int level, int name, const void *val, socklen_t len)
{
    if (fd != K.fd)
        return __real_setsockopt(fd, level, name, val, len);
    if (level == SOL_CAN_RAW && name == CAN_RAW_FILTER) {
        assert_true(len % sizeof(struct can_filter) == 0 && len <= sizeof K.filt);
        memcpy(K.filt, val, len);
        K.filters = (int)(len / sizeof(struct can_filter));
        return 0;
    }
    if (level == SOL_CAN_RAW && name == CAN_RAW_ERR_FILTER) {
        assert_int_equal(len, sizeof K.err_mask);
        memcpy(&K.err_mask, val, sizeof K.err_mask);
        return 0;
    }
    if (level == SOL_CAN_RAW && name == CAN_RAW_FD_FRAMES) {
        if (K.fd_frames_ok)
            return 0;
        errno = ENOPROTOOPT;
        return -1;
    }
    if (level == SOL_SOCKET && name == SO_RXQ_OVFL) {
        K.rxq_ovfl_on = *(const int *)val;
        return 0;
    }
    return 0; /* the receive buffer's size: granted */
}

int __wrap_bind(int fd, const struct sockaddr *a, socklen_t len)
{
    if (fd != K.fd)
        return __real_bind(fd, a, len);
    const struct sockaddr_can *c = (const struct sockaddr_can *)a;
    assert_int_equal(c->can_family, AF_CAN);
    K.bound_ifindex = c->can_ifindex;
    return 0;
}

int __wrap_recvmmsg(int fd, struct mmsghdr *v, unsigned int n, int flags, struct timespec *t)
{
    if (K.rx_errno) {
        errno = K.rx_errno;
        K.rx_errno = 0;
        return -1;
    }
    const size_t room = n > 0 ? v[0].msg_hdr.msg_controllen : 0;
    int r = __real_recvmmsg(fd, v, n, flags, t);
    if (r > 0 && K.cmsg_pending) {
        struct msghdr *h = &v[0].msg_hdr;
        assert_true(room >= CMSG_SPACE(sizeof(uint32_t)));
        struct cmsghdr *c = (struct cmsghdr *)h->msg_control;
        c->cmsg_level = K.cmsg_level;
        c->cmsg_type = K.cmsg_type;
        c->cmsg_len = CMSG_LEN(sizeof(uint32_t));
        memcpy(CMSG_DATA(c), &K.cmsg_value, sizeof K.cmsg_value);
        h->msg_controllen = CMSG_SPACE(sizeof(uint32_t));
        K.cmsg_pending = 0;
    }
    return r;
}

int __wrap_sendmmsg(int fd, struct mmsghdr *v, unsigned int n, int flags)
{
    if (K.tx_fail > 0) {
        K.tx_fail--;
        errno = K.tx_errno;
        return -1;
    }
    return __real_sendmmsg(fd, v, n, flags);
}

/* ---------------------------------------------------------------- the rig */

static char logs[64][256];
static int nlog;
static void capture_log(int prio, const char *msg)
{
    (void)prio;
    if (nlog < 64)
        snprintf(logs[nlog], sizeof logs[nlog], "%s", msg);
    nlog++;
}

/* Log lines since `from` that contain `what`. */
static int logged(int from, const char *what)
{
    int n = 0;
    for (int k = from; k < nlog && k < 64; k++)
        n += strstr(logs[k], what) != NULL;
    return n;
}

typedef struct rig {
    sc_transport t;
    sc_engine e;
} rig;

static void rig_open(rig *r, int ignore_other_ids)
{
    memset(&K, 0, sizeof K);
    K.fd = K.peer = -1;
    K.fd_frames_ok = 1;
    nlog = 0;
    sc_can_config c;
    sc_can_config_defaults(&c);
    strcpy(c.ifname, "fault0");
    c.ignore_other_ids = ignore_other_ids;
    c.log = capture_log;
    sc_can_transport_use_fd(-1);
    sc_can_transport(&r->t, &c);
    memset(&r->e, 0, sizeof r->e);
    r->e.status = SC_CORR_ST_LOADED;
    sc_error why;
    assert_int_equal(r->t.open(r->t.state, &why), SC_OK);
    assert_int_equal(K.sockets, 1);
}

static void rig_close(rig *r)
{
    r->t.close(r->t.state);
    if (K.peer >= 0)
        close(K.peer);
}

static void bus_send_position(int32_t x, int32_t y)
{
    struct can_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = 0x100;
    f.can_dlc = 8;
    sc_can_encode_position(f.data, x, y);
    assert_int_equal(write(K.peer, &f, sizeof f), (ssize_t)sizeof f);
}

static void bus_send_error(uint32_t flags, uint8_t d1)
{
    struct can_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = CAN_ERR_FLAG | flags;
    f.can_dlc = CAN_ERR_DLC;
    f.data[1] = d1;
    assert_int_equal(write(K.peer, &f, sizeof f), (ssize_t)sizeof f);
}

/* One turn of the daemon's loop: serve what the socket has (if one is open), then tick. */
static void loop_once(rig *r, uint64_t now_ms)
{
    struct pollfd fds[2];
    int n = r->t.fill_pollfds(r->t.state, fds, 2);
    if (n > 0)
        assert_int_equal(poll(fds, (nfds_t)n, 0) >= 0, 1);
    r->t.serve(r->t.state, fds, n, &r->e, now_ms);
    r->t.tick(r->t.state, &r->e, now_ms);
}

/* The frames waiting on the bus: answers (0x101) counted, the last status frame's byte 0 kept. */
static int bus_drain(int *answers, int *status_bits)
{
    struct canfd_frame f;
    int n = 0;
    for (;;) {
        ssize_t got = read(K.peer, &f, sizeof f);
        if (got < 0) {
            assert_true(errno == EAGAIN || errno == EWOULDBLOCK);
            return n;
        }
        n++;
        if (f.can_id == 0x101 && answers)
            ++*answers;
        if (f.can_id == 0x102 && status_bits)
            *status_bits = f.data[0];
    }
}

static sc_can_stats stats(void)
{
    sc_can_stats st;
    sc_can_get_stats(&st);
    return st;
}

/* ---------------------------------------------------------------- the tests */

/* What open asks of the kernel: the interface's index, the error classes, CAN FD, the drop count,
 * and with --can-other-ids ignore the six filters of our ids; the log says whether FD is on. */
static void test_open_options(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 1);
    assert_int_equal(K.bound_ifindex, 7);
    assert_int_equal(K.rxq_ovfl_on, 1);
    assert_int_equal(K.err_mask, CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED);
    assert_int_equal(K.filters, 6);
    const uint32_t sff = CAN_SFF_MASK | CAN_EFF_FLAG, eff = CAN_EFF_MASK | CAN_EFF_FLAG;
    const uint32_t ids[3] = {0x100, 0x101, 0x102};
    for (int k = 0; k < 3; k++) {
        assert_int_equal(K.filt[2 * k].can_id, ids[k]);
        assert_int_equal(K.filt[2 * k].can_mask, sff);
        assert_int_equal(K.filt[2 * k + 1].can_id, ids[k] | CAN_EFF_FLAG);
        assert_int_equal(K.filt[2 * k + 1].can_mask, eff);
    }
    assert_int_equal(logged(0, "serving ids 0x100 in, 0x101 out, 0x102 status every 1000 ms (CAN FD accepted)"), 1);
    rig_close(&r);

    /* every frame read by default (no filter); a kernel without CAN FD: not claimed */
    memset(&K, 0, sizeof K);
    rig_open(&r, 0);
    rig_close(&r);
    memset(&K, 0, sizeof K);
    K.fd = K.peer = -1;
    nlog = 0;
    sc_can_config c;
    sc_can_config_defaults(&c);
    strcpy(c.ifname, "fault0");
    c.log = capture_log;
    sc_can_transport(&r.t, &c);
    sc_error why;
    assert_int_equal(r.t.open(r.t.state, &why), SC_OK);
    assert_int_equal(K.filters, 0);
    assert_int_equal(logged(0, "every 1000 ms"), 1);
    assert_int_equal(logged(0, "CAN FD"), 0);
    rig_close(&r);

    /* the interface missing at start: open fails, naming it */
    memset(&K, 0, sizeof K);
    K.fd = K.peer = -1;
    K.ioctl_errno = ENODEV;
    sc_can_transport(&r.t, &c);
    sc_error_clear(&why);
    assert_int_equal(r.t.open(r.t.state, &why), SC_E_IO);
    assert_non_null(strstr(why.msg, "interface fault0"));
    close(K.peer);
    K.socket_errno = EAFNOSUPPORT;
    K.peer = -1;
    sc_can_transport(&r.t, &c);
    assert_int_equal(r.t.open(r.t.state, &why), SC_E_IO);
    assert_non_null(strstr(why.msg, "this kernel has no CAN support"));
}

/* The kernel's count of dropped input frames (SO_RXQ_OVFL, cumulative per socket): counted by
 * difference, bit 7 in the next status frame, logged at the first drop and then at most once per
 * 10 s (tick says what came after the last line); another control message is not a count; after
 * a reopen the new socket's count starts again at 0. */
static void test_rx_overflow(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0);
    int answers = 0, bits = -1;
    loop_once(&r, 50);
    bus_drain(&answers, &bits);
    assert_int_equal(bits, SC_CORR_ST_LOADED);

    /* a count of 0 on a fresh socket: nothing dropped */
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_SOCKET, K.cmsg_type = SO_RXQ_OVFL, K.cmsg_value = 0;
    loop_once(&r, 100);
    assert_int_equal(stats().rx_overflow, 0);
    assert_int_equal(logged(0, "dropped"), 0);
    /* another 4-byte control message at the socket level (SO_RCVMARK's SO_MARK): not a count */
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_SOCKET, K.cmsg_type = SO_MARK, K.cmsg_value = 99;
    loop_once(&r, 150);
    /* the count at another level is not the socket's either */
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_CAN_RAW, K.cmsg_type = SO_RXQ_OVFL, K.cmsg_value = 99;
    loop_once(&r, 160);
    assert_int_equal(stats().rx_overflow, 0);
    answers = 0;
    bus_drain(&answers, NULL);
    assert_int_equal(answers, 3);

    /* 3 dropped: counted and logged at once */
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_SOCKET, K.cmsg_type = SO_RXQ_OVFL, K.cmsg_value = 3;
    loop_once(&r, 200);
    assert_int_equal(stats().rx_overflow, 3);
    assert_int_equal(logged(0, "the kernel dropped 3 input frames so far"), 1);
    /* 5 in all, 100 ms later: counted, not logged yet */
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_SOCKET, K.cmsg_type = SO_RXQ_OVFL, K.cmsg_value = 5;
    loop_once(&r, 300);
    assert_int_equal(stats().rx_overflow, 5);
    assert_int_equal(logged(0, "dropped"), 1);
    loop_once(&r, 1050);
    bits = -1;
    bus_drain(NULL, &bits);
    assert_int_equal(bits, SC_CORR_ST_LOADED | SC_CAN_ST_LOST);
    loop_once(&r, 10199);
    assert_int_equal(logged(0, "dropped"), 1);
    loop_once(&r, 10200); /* 10 s after the first line: the total */
    assert_int_equal(logged(0, "the kernel dropped 5 input frames so far"), 1);
    loop_once(&r, 30000);
    assert_int_equal(logged(0, "dropped"), 2);

    /* the interface removed and back: the new socket's count starts at 0 */
    int before = nlog;
    K.rx_errno = ENODEV;
    bus_send_position(1, 2);
    loop_once(&r, 31000);
    assert_int_equal(logged(before, "interface lost"), 1);
    loop_once(&r, 32000);
    assert_int_equal(stats().reopened, 1);
    assert_int_equal(K.sockets, 2);
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_SOCKET, K.cmsg_type = SO_RXQ_OVFL, K.cmsg_value = 2;
    loop_once(&r, 32100);
    assert_int_equal(stats().rx_overflow, 7);
    assert_int_equal(logged(before, "the kernel dropped 7 input frames so far"), 1); /* 20 s on */
    bus_send_position(1, 2);
    K.cmsg_pending = 1, K.cmsg_level = SOL_SOCKET, K.cmsg_type = SO_RXQ_OVFL, K.cmsg_value = 4;
    loop_once(&r, 32200);
    assert_int_equal(stats().rx_overflow, 9);
    before = nlog;
    rig_close(&r); /* within 10 s of the last line: the total said at the close */
    assert_int_equal(logged(before, "the kernel dropped 9 input frames so far"), 1);
}

/* recvmmsg: ENODEV (interface removed) closes the socket, which tick reopens every second,
 * saying once that it still fails; ENETDOWN (interface down) keeps the socket, and traffic says
 * the interface is up again. */
static void test_receive_errors(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0);
    loop_once(&r, 0);
    bus_drain(NULL, NULL);

    K.rx_errno = ENETDOWN;
    bus_send_position(1, 2);
    loop_once(&r, 100);
    assert_int_equal(logged(0, "waiting for the interface to come back"), 1);
    assert_int_equal(logged(0, "interface lost"), 0);
    assert_int_equal(stats().link_down_now, 1);
    struct pollfd fds[2];
    assert_int_equal(r.t.fill_pollfds(r.t.state, fds, 2), 1); /* the socket is kept */
    loop_once(&r, 200); /* the position still waiting is served: the interface is up again */
    int answers = 0;
    bus_drain(&answers, NULL);
    assert_int_equal(answers, 1);
    assert_int_equal(stats().link_down_now, 0);
    assert_int_equal(logged(0, "interface up again"), 1);
    assert_int_equal(K.sockets, 1);

    /* another error: logged, the socket kept */
    K.rx_errno = EIO;
    bus_send_position(1, 2);
    loop_once(&r, 300);
    assert_int_equal(logged(0, "receive: Input/output error"), 1);
    assert_int_equal(r.t.fill_pollfds(r.t.state, fds, 2), 1);
    assert_int_equal(stats().link_down_now, 0);
    bus_drain(NULL, NULL);

    /* removed: closed at once, reopening fails three times (one line), then succeeds */
    int before = nlog;
    K.rx_errno = ENXIO;
    bus_send_position(1, 2);
    K.ioctl_errno = ENODEV;
    loop_once(&r, 1000);
    assert_int_equal(logged(before, "interface lost"), 1);
    assert_int_equal(stats().link_down_now, 1);
    assert_int_equal(r.t.fill_pollfds(r.t.state, fds, 2), 0);
    loop_once(&r, 1999); /* not yet a second later */
    assert_int_equal(K.sockets, 1);
    loop_once(&r, 2000);
    loop_once(&r, 3000);
    loop_once(&r, 4000);
    assert_int_equal(K.sockets, 4);
    assert_int_equal(logged(before, "(still retrying)"), 1);
    assert_int_equal(stats().reopened, 0);
    K.ioctl_errno = 0;
    loop_once(&r, 5000);
    assert_int_equal(K.sockets, 5);
    assert_int_equal(stats().reopened, 1);
    assert_int_equal(stats().link_down_now, 0);
    assert_int_equal(logged(before, "socket reopened"), 1);
    /* served again; the status frame says frames were lost */
    int bits = -1;
    answers = 0;
    bus_send_position(5, 6);
    loop_once(&r, 5100);
    bus_drain(&answers, &bits);
    assert_int_equal(answers, 1);
    assert_int_equal(bits, SC_CORR_ST_LOADED | SC_CAN_ST_LOST);
    /* lost again later: the failure is said again (once) */
    before = nlog;
    K.rx_errno = ENODEV;
    K.ioctl_errno = ENODEV;
    bus_send_position(1, 2);
    loop_once(&r, 6000);
    loop_once(&r, 7000);
    loop_once(&r, 8000);
    assert_int_equal(logged(before, "(still retrying)"), 1);
    rig_close(&r);
}

/* sendmmsg: a full queue (ENOBUFS) keeps the frames, counted, logged at most once per 10 s;
 * the interface removed (ENODEV) or down (ENETDOWN) drops every queued frame, counted; any other
 * error drops the one frame. */
static void test_send_errors(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0);
    loop_once(&r, 0);
    bus_drain(NULL, NULL);

    K.tx_errno = ENOBUFS, K.tx_fail = 1;
    bus_send_position(1, 2);
    bus_send_position(3, 4);
    loop_once(&r, 100); /* refused once, sent by the tick's retry */
    assert_int_equal(stats().tx_queue_full, 1);
    assert_int_equal(logged(0, "transmit queue full (1 times so far)"), 1);
    int answers = 0;
    bus_drain(&answers, NULL);
    assert_int_equal(answers, 2);
    K.tx_errno = EAGAIN, K.tx_fail = 2;
    bus_send_position(1, 2);
    loop_once(&r, 5000);
    assert_int_equal(stats().tx_queue_full, 3);
    assert_int_equal(logged(0, "transmit queue full"), 1); /* within 10 s of the first line */
    K.tx_errno = ENOBUFS, K.tx_fail = 1;
    loop_once(&r, 10100);
    assert_int_equal(logged(0, "transmit queue full (4 times so far)"), 1);
    answers = 0;
    bus_drain(&answers, NULL);
    assert_int_equal(answers, 1);
    assert_int_equal(stats().tx_dropped, 0);

    /* ENODEV with three answers queued: all three dropped, the socket closed */
    K.tx_errno = ENODEV, K.tx_fail = 1;
    bus_send_position(1, 2);
    bus_send_position(1, 2);
    bus_send_position(1, 2);
    int before = nlog;
    loop_once(&r, 10200);
    assert_int_equal(stats().tx_dropped, 3);
    assert_int_equal(logged(before, "interface lost"), 1);
    struct pollfd fds[2];
    assert_int_equal(r.t.fill_pollfds(r.t.state, fds, 2), 0);
    loop_once(&r, 11200); /* reopened */
    assert_int_equal(stats().reopened, 1);
    bus_drain(NULL, NULL);

    /* ENETDOWN with two queued: both dropped, the socket kept */
    K.tx_errno = ENETDOWN, K.tx_fail = 1;
    bus_send_position(1, 2);
    bus_send_position(1, 2);
    loop_once(&r, 11300);
    assert_int_equal(stats().tx_dropped, 5);
    assert_int_equal(stats().link_down_now, 1);
    assert_int_equal(r.t.fill_pollfds(r.t.state, fds, 2), 1);

    /* EINVAL (say, an FD frame on a classic interface): that frame only */
    K.tx_errno = EINVAL, K.tx_fail = 1;
    bus_send_position(1, 2);
    bus_send_position(1, 2);
    before = nlog;
    loop_once(&r, 11400);
    assert_int_equal(stats().tx_dropped, 6);
    assert_int_equal(logged(before, "send: Invalid argument (frame dropped)"), 1);
    answers = 0;
    bus_drain(&answers, NULL);
    assert_int_equal(answers, 1);
    rig_close(&r);
}

/* The controller's buffer overflow (an error frame): bit 7, and one line per 10 s at most. */
static void test_controller_overflow_rate(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0);
    loop_once(&r, 0);
    bus_drain(NULL, NULL);
    bus_send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW);
    loop_once(&r, 100);
    assert_int_equal(logged(0, "controller buffer overflow"), 1);
    bus_send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_OVERFLOW);
    loop_once(&r, 200);
    assert_int_equal(logged(0, "controller buffer overflow"), 1);
    bus_send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW);
    loop_once(&r, 10100);
    assert_int_equal(logged(0, "controller buffer overflow"), 2);
    bus_send_error(CAN_ERR_TX_TIMEOUT, 0);
    loop_once(&r, 10200);
    assert_int_equal(logged(0, "transmit timeout"), 1);
    assert_int_equal(stats().error_frames, 4);
    rig_close(&r);
}

/* CAN FD: an FD position is answered with an FD frame of the same bit-rate switch. */
static void test_fd_answer(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, 0);
    loop_once(&r, 0);
    bus_drain(NULL, NULL);
    struct canfd_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = 0x100;
    f.len = 8;
    f.flags = CANFD_BRS | CANFD_FDF;
    sc_can_encode_position(f.data, 1000, -2000);
    assert_int_equal(write(K.peer, &f, sizeof f), (ssize_t)sizeof f);
    loop_once(&r, 10);
    memset(&f, 0, sizeof f);
    assert_int_equal(read(K.peer, &f, sizeof f), (ssize_t)CANFD_MTU);
    assert_int_equal(f.can_id, 0x101);
    assert_int_equal(f.len, 8);
    assert_int_equal(f.flags, CANFD_BRS | CANFD_FDF);
    int32_t x, y;
    sc_can_decode_position(f.data, &x, &y);
    assert_int_equal(x, 1007);
    assert_int_equal(y, -2003);
    rig_close(&r);
}

/* The test hook's descriptor may be 0 (any valid descriptor is one): it is used, not a socket. */
static void test_hook_fd_zero(void **state)
{
    (void)state;
    memset(&K, 0, sizeof K);
    K.fd = K.peer = -1;
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK, 0, sv), 0);
    int saved = dup(0);
    assert_true(saved >= 0);
    assert_int_equal(dup2(sv[1], 0), 0);
    close(sv[1]);
    sc_can_config c;
    sc_can_config_defaults(&c);
    strcpy(c.ifname, "fault0");
    c.log = capture_log;
    sc_can_transport_use_fd(0);
    rig r;
    sc_can_transport(&r.t, &c);
    memset(&r.e, 0, sizeof r.e);
    sc_error why;
    assert_int_equal(r.t.open(r.t.state, &why), SC_OK);
    assert_int_equal(K.sockets, 0);
    struct pollfd fds[2];
    assert_int_equal(r.t.fill_pollfds(r.t.state, fds, 2), 1);
    assert_int_equal(fds[0].fd, 0);
    K.peer = sv[0];
    bus_send_position(40, 50);
    loop_once(&r, 10);
    int answers = 0;
    bus_drain(&answers, NULL);
    assert_int_equal(answers, 1);
    assert_int_equal(stats().positions, 1);
    r.t.close(r.t.state);
    sc_can_transport_use_fd(-1);
    assert_int_equal(dup2(saved, 0), 0);
    close(saved);
    close(sv[0]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_open_options),
        cmocka_unit_test(test_rx_overflow),
        cmocka_unit_test(test_receive_errors),
        cmocka_unit_test(test_send_errors),
        cmocka_unit_test(test_controller_overflow_rate),
        cmocka_unit_test(test_fd_answer),
        cmocka_unit_test(test_hook_fd_zero),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
