/* runtime/transport_modbus_tcp.c — Modbus TCP server inside the daemon's poll loop.
 *
 * libmodbus gives the listening socket (modbus_tcp_listen) and the replies (modbus_reply via the
 * shared map); the MBAP framing is done here on non-blocking sockets with a per-connection
 * buffer, so a client that sends half a request, or nothing, never blocks the others: a partial
 * request older than byte_timeout_ms, or a connection silent for idle_timeout_ms, is closed.
 * All state is static; nothing allocates after open(). */
#define _GNU_SOURCE /* accept4 */
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <modbus/modbus.h>

#include "log.h"
#include "modbus_map.h"
#include "transport_modbus.h"

#define MBAP_LEN 7
#define ADU_MAX MODBUS_TCP_MAX_ADU_LENGTH /* 260 */

typedef struct conn {
    int fd;                 /* -1 = free slot */
    int len;                /* bytes buffered */
    uint64_t last_rx_ms;    /* last byte received */
    uint64_t partial_since_ms;
    uint8_t buf[2 * ADU_MAX];
} conn;

typedef struct mbtcp_state {
    sc_mbtcp_config cfg;
    modbus_t *ctx;
    int listen_fd;
    uint16_t bound_port;
    int nconn;
    uint32_t refused, timeouts;
    conn c[SC_MBTCP_MAX_CONN];
    int polled[SC_TRANSPORT_MAX_FDS]; /* what each pollfd slot of the last fill was: -1 listen */
    int npolled;
} mbtcp_state;

static mbtcp_state g_tcp;

void sc_mbtcp_config_defaults(sc_mbtcp_config *c)
{
    memset(c, 0, sizeof *c);
    strcpy(c->host, "127.0.0.1");
    c->port = 1502;
    c->unit_id = 1;
    c->max_connections = 64;
    c->byte_timeout_ms = 500;
    c->idle_timeout_ms = 60000;
}

uint16_t sc_modbus_tcp_bound_port(void)
{
    return g_tcp.bound_port;
}

int sc_modbus_tcp_connections(void)
{
    return g_tcp.nconn;
}

uint32_t sc_modbus_tcp_refused(void)
{
    return g_tcp.refused;
}

static void conn_close(mbtcp_state *s, conn *c, const char *why)
{
    if (c->fd < 0)
        return;
    if (why != NULL)
        sc_log(SC_LOG_INFO, "modbus-tcp: closing connection %d: %s", c->fd, why);
    close(c->fd);
    c->fd = -1;
    c->len = 0;
    s->nconn--;
}

static int tcp_open(void *state, char *why, int whylen)
{
    mbtcp_state *s = state;
    for (int i = 0; i < SC_MBTCP_MAX_CONN; i++)
        s->c[i].fd = -1;
    s->nconn = 0;
    if (s->cfg.max_connections < 1 || s->cfg.max_connections > SC_MBTCP_MAX_CONN) {
        snprintf(why, (size_t)whylen, "modbus-tcp: max-connections must be 1..%d",
                 SC_MBTCP_MAX_CONN);
        return -1;
    }
    if (sc_modbus_map_open(sc_modbus_map_shared(), sc_modbus_map_shared()->order) != 0) {
        snprintf(why, (size_t)whylen, "modbus: cannot allocate the register map");
        return -1;
    }
    s->ctx = modbus_new_tcp(s->cfg.host, s->cfg.port);
    if (s->ctx == NULL) {
        snprintf(why, (size_t)whylen, "modbus-tcp: %s", modbus_strerror(errno));
        return -1;
    }
    s->listen_fd = modbus_tcp_listen(s->ctx, 64);
    if (s->listen_fd < 0) {
        snprintf(why, (size_t)whylen, "modbus-tcp: cannot listen on %s:%u: %s", s->cfg.host,
                 (unsigned)s->cfg.port, modbus_strerror(errno));
        modbus_free(s->ctx);
        s->ctx = NULL;
        return -1;
    }
    fcntl(s->listen_fd, F_SETFL, fcntl(s->listen_fd, F_GETFL) | O_NONBLOCK);
    fcntl(s->listen_fd, F_SETFD, FD_CLOEXEC);
    struct sockaddr_in a;
    socklen_t alen = sizeof a;
    if (getsockname(s->listen_fd, (struct sockaddr *)&a, &alen) == 0)
        s->bound_port = ntohs(a.sin_port);
    sc_log(SC_LOG_NOTICE, "modbus-tcp: listening on %s:%u (unit id %u, max %d connections)",
           s->cfg.host, (unsigned)s->bound_port, (unsigned)s->cfg.unit_id,
           s->cfg.max_connections);
    return 0;
}

static int tcp_fill(void *state, struct pollfd *fds, int max)
{
    mbtcp_state *s = state;
    int n = 0;
    if (n < max) {
        fds[n].fd = s->listen_fd;
        fds[n].events = POLLIN;
        fds[n].revents = 0;
        s->polled[n++] = -1;
    }
    for (int i = 0; i < SC_MBTCP_MAX_CONN && n < max; i++) {
        if (s->c[i].fd < 0)
            continue;
        fds[n].fd = s->c[i].fd;
        fds[n].events = POLLIN;
        fds[n].revents = 0;
        s->polled[n++] = i;
    }
    s->npolled = n;
    return n;
}

static void tcp_accept(mbtcp_state *s, uint64_t now_ms)
{
    for (;;) {
        int fd = accept4(s->listen_fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR || errno == ECONNABORTED)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK)
                sc_log(SC_LOG_WARNING, "modbus-tcp: accept: %s", strerror(errno));
            return;
        }
        if (s->nconn >= s->cfg.max_connections) {
            s->refused++;
            if (s->refused < 10 || s->refused % 1000 == 0)
                sc_log(SC_LOG_WARNING, "modbus-tcp: connection refused: %d open (the cap); %u "
                       "refused so far", s->nconn, (unsigned)s->refused);
            close(fd);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        for (int i = 0; i < SC_MBTCP_MAX_CONN; i++) {
            if (s->c[i].fd >= 0)
                continue;
            s->c[i].fd = fd;
            s->c[i].len = 0;
            s->c[i].last_rx_ms = now_ms;
            s->nconn++;
            sc_log(SC_LOG_DEBUG, "modbus-tcp: connection %d accepted (%d open)", fd, s->nconn);
            break;
        }
    }
}

/* Serve every complete request in c's buffer; returns -1 if the connection must close. */
static int tcp_process(mbtcp_state *s, conn *c, sc_engine *e, uint64_t now_ms)
{
    int off = 0;
    while (c->len - off >= MBAP_LEN) {
        const uint8_t *p = c->buf + off;
        unsigned proto = (unsigned)(p[2] << 8 | p[3]);
        unsigned mlen = (unsigned)(p[4] << 8 | p[5]); /* unit id + PDU */
        if (proto != 0 || mlen < 2 || mlen > ADU_MAX - 6) {
            conn_close(s, c, "not a Modbus TCP frame");
            return -1;
        }
        int total = 6 + (int)mlen;
        if (c->len - off < total)
            break;
        unsigned unit = p[6];
        modbus_set_socket(s->ctx, c->fd);
        int rc;
        if (unit == s->cfg.unit_id || unit == 0xff || unit == 0) /* 0, 255: "this device" */
            rc = sc_modbus_map_reply(sc_modbus_map_shared(), s->ctx, p, total, MBAP_LEN, 0, e);
        else /* not us: what a gateway answers for an absent device */
            rc = modbus_reply_exception(s->ctx, p,
                                        MODBUS_EXCEPTION_GATEWAY_TARGET);
        if (rc < 0) {
            conn_close(s, c, "send failed (client not reading?)");
            return -1;
        }
        off += total;
    }
    if (off > 0) {
        memmove(c->buf, c->buf + off, (size_t)(c->len - off));
        c->len -= off;
    }
    if (c->len > 0 && off > 0)
        c->partial_since_ms = now_ms;
    return 0;
}

static void tcp_serve(void *state, struct pollfd *fds, int n, sc_engine *e, uint64_t now_ms)
{
    mbtcp_state *s = state;
    for (int k = 0; k < n && k < s->npolled; k++) {
        if (fds[k].revents == 0)
            continue;
        if (s->polled[k] < 0) {
            tcp_accept(s, now_ms);
            continue;
        }
        conn *c = &s->c[s->polled[k]];
        if (c->fd != fds[k].fd)
            continue;
        ssize_t r = recv(c->fd, c->buf + c->len, sizeof c->buf - (size_t)c->len, 0);
        if (r == 0) {
            conn_close(s, c, NULL);
            continue;
        }
        if (r < 0) {
            if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                conn_close(s, c, strerror(errno));
            continue;
        }
        if (c->len == 0)
            c->partial_since_ms = now_ms;
        c->len += (int)r;
        c->last_rx_ms = now_ms;
        tcp_process(s, c, e, now_ms);
    }
}

static void tcp_tick(void *state, sc_engine *e, uint64_t now_ms)
{
    (void)e;
    mbtcp_state *s = state;
    for (int i = 0; i < SC_MBTCP_MAX_CONN; i++) {
        conn *c = &s->c[i];
        if (c->fd < 0)
            continue;
        if (c->len > 0 && now_ms - c->partial_since_ms > s->cfg.byte_timeout_ms) {
            s->timeouts++;
            conn_close(s, c, "request incomplete after the byte timeout");
        } else if (s->cfg.idle_timeout_ms > 0 &&
                   now_ms - c->last_rx_ms > s->cfg.idle_timeout_ms) {
            s->timeouts++;
            conn_close(s, c, "idle timeout");
        }
    }
}

static void tcp_close(void *state)
{
    mbtcp_state *s = state;
    for (int i = 0; i < SC_MBTCP_MAX_CONN; i++)
        conn_close(s, &s->c[i], NULL);
    if (s->listen_fd >= 0)
        close(s->listen_fd);
    s->listen_fd = -1;
    if (s->ctx != NULL) {
        modbus_set_socket(s->ctx, -1);
        modbus_free(s->ctx);
    }
    s->ctx = NULL;
}

void sc_modbus_tcp_transport(sc_transport *t, const sc_mbtcp_config *cfg)
{
    g_tcp.cfg = *cfg;
    g_tcp.listen_fd = -1;
    t->name = "modbus-tcp";
    t->state = &g_tcp;
    t->open = tcp_open;
    t->fill_pollfds = tcp_fill;
    t->serve = tcp_serve;
    t->tick = tcp_tick;
    t->close = tcp_close;
}
