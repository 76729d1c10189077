/* can_traffic — simulated stage traffic for selfcald over a raw CAN socket.
 *
 * Plays a trajectory (a file of positions with the corrected values expected for each, computed
 * independently on the host) through the daemon at a set rate, and checks every answer: nothing
 * lost, nothing out of order, every value right (within a tolerance in nm). Prints one summary line
 * and exits 0 only if all is well.
 *
 * usage: can_traffic -i IFACE -f FILE [-r RATE] [-d SECONDS] [-w WINDOW] [-T TOL_NM]
 *                    [-t WAIT_MS]
 *   FILE    lines "x_nm y_nm expected_x_nm expected_y_nm" ('#' lines ignored)
 *   RATE    position frames per second (default 1000; 0 = as fast as the window allows)
 *   SECONDS play for this long, repeating the file (default: the file once)
 *   WINDOW  at most this many frames without an answer (default 0 = no limit: a stage does not
 *           wait for the daemon)
 *   WAIT_MS after the last frame, how long to wait for the missing answers (default 2000)
 * The daemon's status frames are read too; the last one is printed (bad frames, corrections).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <inttypes.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif

enum { BATCH = 64, SEARCH = 8192, RING = 1 << 16 };

typedef struct point {
    int32_t x, y, ex, ey;
} point;

static point *pts;
static size_t npts;

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void put32(uint8_t *p, int32_t v)
{
    uint32_t u = (uint32_t)v;
    p[0] = (uint8_t)u, p[1] = (uint8_t)(u >> 8), p[2] = (uint8_t)(u >> 16), p[3] = (uint8_t)(u >> 24);
}

static uint32_t getu32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int32_t get32(const uint8_t *p)
{
    uint32_t u = getu32(p);
    return u <= 0x7fffffffu ? (int32_t)u : -(int32_t)(0xffffffffu - u) - 1;
}

static int load_points(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "can_traffic: %s: %s\n", path, strerror(errno));
        return -1;
    }
    size_t cap = 1024;
    pts = malloc(cap * sizeof *pts);
    char line[256];
    int lineno = 0;
    while (pts && fgets(line, sizeof line, f)) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n')
            continue;
        long long v[4];
        if (sscanf(line, "%lld %lld %lld %lld", &v[0], &v[1], &v[2], &v[3]) != 4) {
            fprintf(stderr, "can_traffic: %s:%d: expected 4 integers\n", path, lineno);
            fclose(f);
            return -1;
        }
        for (int k = 0; k < 4; k++) {
            if (v[k] < INT32_MIN || v[k] > INT32_MAX) {
                fprintf(stderr, "can_traffic: %s:%d: value out of int32 range\n", path, lineno);
                fclose(f);
                return -1;
            }
        }
        if (npts == cap) {
            cap *= 2;
            point *n = realloc(pts, cap * sizeof *pts);
            if (!n)
                break;
            pts = n;
        }
        pts[npts++] = (point){(int32_t)v[0], (int32_t)v[1], (int32_t)v[2], (int32_t)v[3]};
    }
    fclose(f);
    if (!pts || npts == 0) {
        fprintf(stderr, "can_traffic: %s: no points\n", path);
        return -1;
    }
    return 0;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
    const char *ifname = NULL, *file = NULL;
    double rate = 1000, seconds = 0;
    long window = 0, tol = 1, wait_ms = 2000;
    int opt;
    while ((opt = getopt(argc, argv, "i:f:r:d:w:T:t:")) != -1) {
        switch (opt) {
        case 'i': ifname = optarg; break;
        case 'f': file = optarg; break;
        case 'r': rate = atof(optarg); break;
        case 'd': seconds = atof(optarg); break;
        case 'w': window = atol(optarg); break;
        case 'T': tol = atol(optarg); break;
        case 't': wait_ms = atol(optarg); break;
        default:
            fprintf(stderr, "usage: can_traffic -i IFACE -f FILE [-r RATE] [-d SECONDS] "
                            "[-w WINDOW] [-T TOL_NM] [-t WAIT_MS]\n");
            return 2;
        }
    }
    if (!ifname || !file || rate < 0 || (rate == 0 && window <= 0)) {
        fprintf(stderr, "can_traffic: need -i IFACE -f FILE, and a window (-w) when -r 0\n");
        return 2;
    }
    if (load_points(file) < 0)
        return 2;
    uint64_t total = seconds > 0 ? (uint64_t)(seconds * (rate > 0 ? rate : 1e9)) : npts;
    if (seconds > 0 && rate == 0)
        total = UINT64_MAX; /* as fast as possible for `seconds` */

    int fd = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK, CAN_RAW);
    if (fd < 0) {
        perror("can_traffic: socket");
        return 1;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
    if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
        perror("can_traffic: SIOCGIFINDEX");
        return 1;
    }
    struct can_filter filt[2] = {{0x101, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG},
                                 {0x102, CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG}};
    setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filt, sizeof filt);
    int on = 1, big = 4 << 20;
    setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);
    /* a deep receive queue so that the generator itself never drops an answer (FORCE needs
     * CAP_NET_ADMIN, as root in the guest; otherwise capped by net.core.rmem_max) */
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &big, sizeof big) < 0)
        setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
    setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &big, sizeof big);
    struct sockaddr_can addr = {.can_family = AF_CAN, .can_ifindex = ifr.ifr_ifindex};
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        perror("can_traffic: bind");
        return 1;
    }

    /* per-frame send times, for latency; a ring indexed by sequence number */
    const size_t lat_cap = 1 << 20;
    uint64_t *sent_at = calloc(RING, sizeof *sent_at);
    uint64_t *lat = malloc(lat_cap * sizeof *lat);
    if (!sent_at || !lat)
        return 1;
    size_t nlat = 0;

    uint64_t sent = 0, answered = 0, expect = 0; /* expect: sequence number of the next answer */
    uint64_t lost = 0, wrong = 0, out_of_order = 0, tx_busy = 0, rx_drops = 0;
    int64_t max_err = 0;
    int have_status = 0;
    uint8_t status[8] = {0};
    uint64_t n_status = 0;

    struct can_frame txf[BATCH], rxf[BATCH];
    struct iovec txv[BATCH], rxv[BATCH];
    struct mmsghdr txm[BATCH], rxm[BATCH];
    union {
        char b[CMSG_SPACE(sizeof(uint32_t))];
        struct cmsghdr a;
    } ctl[BATCH];

    const uint64_t t0 = now_ns();
    uint64_t t_last_send = t0, t_last_rx = t0;
    const double period_ns = rate > 0 ? 1e9 / rate : 0;
    const uint64_t t_end = seconds > 0 ? t0 + (uint64_t)(seconds * 1e9) : UINT64_MAX;
    int done_sending = 0;

    for (;;) {
        uint64_t t = now_ns();
        if (!done_sending && (sent >= total || t >= t_end)) {
            done_sending = 1;
            t_last_send = t;
        }
        if (done_sending) {
            uint64_t quiet_since = t_last_rx > t_last_send ? t_last_rx : t_last_send;
            if (expect >= sent || t > quiet_since + (uint64_t)wait_ms * 1000000u ||
                t > t_last_send + 10 * (uint64_t)wait_ms * 1000000u)
                break;
        }
        /* send what is due */
        if (!done_sending) {
            uint64_t due = rate > 0 ? (uint64_t)((double)(t - t0) / period_ns) + 1 : sent + BATCH;
            if (due > total)
                due = total;
            int n = 0;
            while (sent + (uint64_t)n < due && n < BATCH &&
                   (window <= 0 || sent + (uint64_t)n - answered - lost < (uint64_t)window)) {
                const point *p = &pts[(sent + (uint64_t)n) % npts];
                memset(&txf[n], 0, sizeof txf[n]);
                txf[n].can_id = 0x100;
                txf[n].can_dlc = 8;
                put32(txf[n].data, p->x);
                put32(txf[n].data + 4, p->y);
                txv[n] = (struct iovec){&txf[n], sizeof txf[n]};
                memset(&txm[n], 0, sizeof txm[n]);
                txm[n].msg_hdr.msg_iov = &txv[n];
                txm[n].msg_hdr.msg_iovlen = 1;
                n++;
            }
            if (n > 0) {
                int r = sendmmsg(fd, txm, (unsigned)n, 0);
                uint64_t ts = now_ns();
                if (r > 0) {
                    for (int k = 0; k < r; k++)
                        sent_at[(sent + (uint64_t)k) % (RING)] = ts;
                    sent += (uint64_t)r;
                } else if (r < 0 && (errno == ENOBUFS || errno == EAGAIN)) {
                    tx_busy++;
                } else if (r < 0) {
                    perror("can_traffic: send");
                    return 1;
                }
            }
        }
        /* wait for answers, or until the next frame is due */
        int timeout_ms = 1;
        if (done_sending)
            timeout_ms = 10;
        struct pollfd pfd = {fd, POLLIN, 0};
        int pr = poll(&pfd, 1, timeout_ms);
        if (pr <= 0)
            continue;
        for (;;) {
            for (int k = 0; k < BATCH; k++) {
                rxv[k] = (struct iovec){&rxf[k], sizeof rxf[k]};
                memset(&rxm[k], 0, sizeof rxm[k]);
                rxm[k].msg_hdr.msg_iov = &rxv[k];
                rxm[k].msg_hdr.msg_iovlen = 1;
                rxm[k].msg_hdr.msg_control = ctl[k].b;
                rxm[k].msg_hdr.msg_controllen = sizeof ctl[k].b;
            }
            int r = recvmmsg(fd, rxm, BATCH, MSG_DONTWAIT, NULL);
            if (r <= 0)
                break;
            uint64_t ts = now_ns();
            for (int k = 0; k < r; k++) {
                struct cmsghdr *c;
                for (c = CMSG_FIRSTHDR(&rxm[k].msg_hdr); c; c = CMSG_NXTHDR(&rxm[k].msg_hdr, c))
                    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL)
                        memcpy(&rx_drops, CMSG_DATA(c), sizeof(uint32_t));
                const struct can_frame *f = &rxf[k];
                if ((f->can_id & CAN_SFF_MASK) == 0x102) {
                    memcpy(status, f->data, 8);
                    have_status = 1;
                    n_status++;
                    continue;
                }
                t_last_rx = ts; /* an answer (status frames do not count) */
                if (f->can_dlc != 8) {
                    wrong++;
                    continue;
                }
                int32_t cx = get32(f->data), cy = get32(f->data + 4);
                /* the answer to frame `expect`, or (frames lost) to a later one */
                uint64_t m, limit = sent - expect < SEARCH ? sent - expect : SEARCH;
                int64_t ex = 0, ey = 0;
                for (m = 0; m < limit; m++) {
                    const point *p = &pts[(expect + m) % npts];
                    ex = (int64_t)cx - p->ex;
                    ey = (int64_t)cy - p->ey;
                    if (llabs(ex) <= tol && llabs(ey) <= tol)
                        break;
                }
                if (m < limit) {
                    lost += m;
                    expect += m;
                } else if (expect > 0 &&
                           llabs((int64_t)cx - pts[(expect - 1) % npts].ex) <= tol &&
                           llabs((int64_t)cy - pts[(expect - 1) % npts].ey) <= tol) {
                    out_of_order++; /* a repeat of the previous answer */
                    continue;
                } else {
                    const point *p = &pts[expect % npts];
                    int64_t e1 = llabs((int64_t)cx - p->ex), e2 = llabs((int64_t)cy - p->ey);
                    if (e1 > max_err)
                        max_err = e1;
                    if (e2 > max_err)
                        max_err = e2;
                    if (wrong < 5)
                        fprintf(stderr,
                                "can_traffic: answer %" PRIu64 " to (%d, %d) is (%d, %d), expected "
                                "(%d, %d)\n",
                                expect, p->x, p->y, cx, cy, p->ex, p->ey);
                    wrong++;
                }
                if (llabs(ex) > max_err && m < limit)
                    max_err = llabs(ex);
                if (llabs(ey) > max_err && m < limit)
                    max_err = llabs(ey);
                if (nlat < lat_cap)
                    lat[nlat++] = ts - sent_at[expect % (RING)];
                expect++;
                answered++;
            }
            if (r < BATCH)
                break;
        }
    }
    if (expect < sent)
        lost += sent - expect;
    double dur = (double)(t_last_send - t0) / 1e9;
    qsort(lat, nlat, sizeof *lat, cmp_u64);
    double p50 = nlat ? (double)lat[nlat / 2] / 1e3 : 0, p99 = nlat ? (double)lat[nlat * 99 / 100] / 1e3 : 0;
    int ok = lost == 0 && wrong == 0 && out_of_order == 0 && answered == sent && sent > 0;
    printf("can_traffic: %s sent %" PRIu64 " answered %" PRIu64 " lost %" PRIu64
           " out_of_order %" PRIu64 " wrong %" PRIu64 " max_err_nm %" PRId64
           " duration_s %.3f rate_per_s %.0f latency_us p50 %.0f p99 %.0f tx_busy %" PRIu64
           " rx_drops %" PRIu64 "\n",
           ok ? "OK" : "FAIL", sent, answered, lost, out_of_order, wrong, max_err, dur,
           dur > 0 ? (double)sent / dur : 0, p50, p99, tx_busy, rx_drops);
    if (have_status)
        printf("can_traffic: last status bits 0x%02x bad %u corrections %u (%" PRIu64 " status frames)\n",
               status[0], status[2] | status[3] << 8, getu32(status + 4), n_status);
    free(pts);
    free(sent_at);
    free(lat);
    close(fd);
    return ok ? 0 : 1;
}
