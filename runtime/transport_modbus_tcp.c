/* runtime/transport_modbus_tcp.c — Modbus TCP server inside the daemon's poll loop.
 *
 * The listen address is parsed here (inet_pton for IPv4/IPv6 literals, getaddrinfo for names; the
 * legacy numeric forms inet_aton accepts, such as 0127.0.0.1 = 87.0.0.1, are refused) and the
 * address really bound is logged. The MBAP framing is done here on non-blocking sockets with a
 * per-connection buffer, so a client that sends half a request, or nothing, never blocks the
 * others: a partial request older than byte_timeout_ms, or a connection silent for
 * idle_timeout_ms, is closed. When the connection cap is reached, a new client evicts the
 * longest-idle connection, preferring those never served (so idle connections cannot lock clients
 * out, and a flood of them cannot push out a client being served: one served less than
 * SC_MBTCP_EVICT_SERVED_IDLE_MS ago is never evicted), one peer address may hold at most
 * max_per_peer connections (a quarter of the cap by default; 0 = no limit), and peers outside
 * the allow-list (--allow) are closed at accept. The shared map builds the replies.
 * All state is static; nothing allocates after open(). */
#define _GNU_SOURCE /* accept4 */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "log.h"
#include "modbus_map.h"
#include "transport_modbus.h"

#define MBAP_LEN 7
#define ADU_MAX SC_MB_ADU_MAX /* 260 */

typedef struct conn {
    int fd;                 /* -1 = free slot */
    int len;                /* bytes buffered */
    uint64_t last_rx_ms;    /* last byte received */
    uint64_t partial_since_ms;
    uint32_t served;        /* requests answered on this connection */
    struct sockaddr_storage peer;
    uint8_t buf[2 * ADU_MAX];
} conn;

typedef struct mbtcp_state {
    sc_mbtcp_config cfg;
    int listen_fd;
    uint16_t bound_port;
    char bound[INET6_ADDRSTRLEN + 8]; /* the address really bound, as logged */
    int nconn;
    uint32_t refused, timeouts, evicted, denied;
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
    c->max_per_peer = SC_MBTCP_PER_PEER_AUTO;
    c->n_allow = 0;
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

uint32_t sc_modbus_tcp_evicted(void)
{
    return g_tcp.evicted;
}

uint32_t sc_modbus_tcp_denied(void)
{
    return g_tcp.denied;
}

/* One "address[/len]" into *out. */
static sc_status parse_cidr(const char *text, sc_cidr *out, sc_error *err)
{
    char a[64];
    size_t n = strlen(text);
    const char *slash = strchr(text, '/');
    size_t al = slash ? (size_t)(slash - text) : n;
    if (al == 0 || al >= sizeof a)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "--allow: bad network '%.64s'", text);
    memcpy(a, text, al);
    a[al] = '\0';
    memset(out, 0, sizeof *out);
    int maxlen;
    if (inet_pton(AF_INET, a, out->addr) == 1) {
        out->family = AF_INET;
        maxlen = 32;
    } else if (inet_pton(AF_INET6, a, out->addr) == 1) {
        out->family = AF_INET6;
        maxlen = 128;
    } else {
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "--allow: '%.64s' is not an IPv4 or IPv6 address (a.b.c.d/len, "
                            "::1/128)", a);
    }
    out->prefix = maxlen;
    if (slash != NULL) {
        const char *p = slash + 1;
        int v = 0, digits = 0;
        for (; *p >= '0' && *p <= '9' && digits < 4; p++, digits++)
            v = v * 10 + (*p - '0');
        if (digits == 0 || *p != '\0' || v > maxlen)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "--allow: bad prefix length in '%.64s' (0..%d)", text, maxlen);
        out->prefix = v;
    }
    return SC_OK;
}

sc_status sc_mbtcp_parse_allow(sc_mbtcp_config *c, const char *list, sc_error *err)
{
    char item[80];
    int n = c->n_allow; /* several lists add up, as systemd's IPAddressAllow= lines */
    const char *p = list;
    if (list == NULL || *list == '\0')
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "--allow: expected CIDR[,CIDR...]");
    for (;;) {
        const char *comma = strchr(p, ',');
        size_t len = comma ? (size_t)(comma - p) : strlen(p);
        while (len > 0 && (*p == ' ' || *p == '\t')) {
            p++;
            len--;
        }
        while (len > 0 && (p[len - 1] == ' ' || p[len - 1] == '\t'))
            len--;
        if (len == 0 || len >= sizeof item)
            return sc_error_set(err, SC_E_INPUT, NULL, 0, "--allow: empty or too long entry in '%.64s'",
                                list);
        if (n >= SC_MBTCP_MAX_ALLOW)
            return sc_error_set(err, SC_E_INPUT, NULL, 0, "--allow: more than %d networks in all",
                                SC_MBTCP_MAX_ALLOW);
        memcpy(item, p, len);
        item[len] = '\0';
        sc_status st = parse_cidr(item, &c->allow[n], err);
        if (st != SC_OK)
            return st;
        n++;
        if (comma == NULL)
            break;
        p = comma + 1;
    }
    c->n_allow = n;
    return SC_OK;
}

static int prefix_match(const uint8_t *a, const uint8_t *net, int prefix)
{
    int whole = prefix / 8, rest = prefix % 8;
    if (memcmp(a, net, (size_t)whole) != 0)
        return 0;
    if (rest == 0)
        return 1;
    uint8_t mask = (uint8_t)(0xffu << (8 - rest));
    return (a[whole] & mask) == (net[whole] & mask);
}

int sc_mbtcp_allowed(const sc_mbtcp_config *c, const struct sockaddr_storage *a)
{
    if (c->n_allow == 0)
        return 1;
    uint8_t v4[4];
    const uint8_t *v6 = NULL;
    int is_v4 = 0;
    if (a->ss_family == AF_INET) {
        memcpy(v4, &((const struct sockaddr_in *)a)->sin_addr, 4);
        is_v4 = 1;
    } else if (a->ss_family == AF_INET6) {
        v6 = ((const struct sockaddr_in6 *)a)->sin6_addr.s6_addr;
        static const uint8_t mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
        if (memcmp(v6, mapped, 12) == 0) {
            memcpy(v4, v6 + 12, 4);
            is_v4 = 1;
        }
    } else {
        return 0;
    }
    for (int i = 0; i < c->n_allow; i++) {
        const sc_cidr *n = &c->allow[i];
        if (is_v4 && n->family == AF_INET && prefix_match(v4, n->addr, n->prefix))
            return 1;
        if (!is_v4 && v6 != NULL && n->family == AF_INET6 && prefix_match(v6, n->addr, n->prefix))
            return 1;
    }
    return 0;
}

/* Only digits and dots, or a colon: meant as a numeric address. */
static int looks_numeric(const char *h)
{
    if (strchr(h, ':') != NULL)
        return 1;
    for (; *h; h++)
        if (!(*h >= '0' && *h <= '9') && *h != '.')
            return 0;
    return 1;
}

sc_status sc_mbtcp_resolve(const char *host, uint16_t port, struct sockaddr_storage *out,
                     socklen_t *outlen, sc_error *err)
{
    memset(out, 0, sizeof *out);
    struct sockaddr_in *a4 = (struct sockaddr_in *)out;
    struct sockaddr_in6 *a6 = (struct sockaddr_in6 *)out;
    if (inet_pton(AF_INET, host, &a4->sin_addr) == 1) {
        a4->sin_family = AF_INET;
        a4->sin_port = htons(port);
        *outlen = sizeof *a4;
        return SC_OK;
    }
    if (inet_pton(AF_INET6, host, &a6->sin6_addr) == 1) {
        a6->sin6_family = AF_INET6;
        a6->sin6_port = htons(port);
        *outlen = sizeof *a6;
        return SC_OK;
    }
    struct in_addr legacy;
    if (looks_numeric(host) || inet_aton(host, &legacy) != 0) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "--modbus-tcp: '%.64s' is not an IPv4 address (a.b.c.d, decimal, no "
                            "leading zeros) nor an IPv6 address ([::1]:PORT)",
                            host);
    }
    struct addrinfo hints, *res = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE;
    int rc = getaddrinfo(host, NULL, &hints, &res);
    if (rc != 0 || res == NULL) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "--modbus-tcp: cannot resolve '%.64s': %s",
                            host, rc == EAI_SYSTEM ? strerror(errno) : gai_strerror(rc));
    }
    const struct addrinfo *pick = NULL; /* IPv4 first: what most Modbus clients dial */
    for (const struct addrinfo *r = res; r != NULL && pick == NULL; r = r->ai_next)
        if (r->ai_family == AF_INET)
            pick = r;
    for (const struct addrinfo *r = res; r != NULL && pick == NULL; r = r->ai_next)
        if (r->ai_family == AF_INET6)
            pick = r;
    if (pick == NULL || pick->ai_addrlen > sizeof *out) {
        freeaddrinfo(res);
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "--modbus-tcp: '%.64s' has no IPv4 or IPv6 address", host);
    }
    memcpy(out, pick->ai_addr, pick->ai_addrlen);
    *outlen = pick->ai_addrlen;
    freeaddrinfo(res);
    if (out->ss_family == AF_INET)
        a4->sin_port = htons(port);
    else
        a6->sin6_port = htons(port);
    return SC_OK;
}

void sc_mbtcp_format_addr(const struct sockaddr_storage *a, char *buf, int len)
{
    char ip[INET6_ADDRSTRLEN] = "?";
    if (a->ss_family == AF_INET) {
        const struct sockaddr_in *a4 = (const struct sockaddr_in *)a;
        inet_ntop(AF_INET, &a4->sin_addr, ip, sizeof ip);
        snprintf(buf, (size_t)len, "%s:%u", ip, (unsigned)ntohs(a4->sin_port));
    } else if (a->ss_family == AF_INET6) {
        const struct sockaddr_in6 *a6 = (const struct sockaddr_in6 *)a;
        inet_ntop(AF_INET6, &a6->sin6_addr, ip, sizeof ip);
        snprintf(buf, (size_t)len, "[%s]:%u", ip, (unsigned)ntohs(a6->sin6_port));
    } else {
        snprintf(buf, (size_t)len, "?");
    }
}

/* Same peer address (port ignored). */
static int same_peer(const struct sockaddr_storage *a, const struct sockaddr_storage *b)
{
    if (a->ss_family != b->ss_family)
        return 0;
    if (a->ss_family == AF_INET)
        return ((const struct sockaddr_in *)a)->sin_addr.s_addr ==
               ((const struct sockaddr_in *)b)->sin_addr.s_addr;
    if (a->ss_family == AF_INET6)
        return memcmp(&((const struct sockaddr_in6 *)a)->sin6_addr,
                      &((const struct sockaddr_in6 *)b)->sin6_addr, sizeof(struct in6_addr)) == 0;
    return 0;
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

static sc_status tcp_open(void *state, sc_error *err)
{
    mbtcp_state *s = state;
    for (int i = 0; i < SC_MBTCP_MAX_CONN; i++)
        s->c[i].fd = -1;
    s->nconn = 0;
    if (s->cfg.max_connections < 1 || s->cfg.max_connections > SC_MBTCP_MAX_CONN) {
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "modbus-tcp: max-connections must be 1..%d",
                            SC_MBTCP_MAX_CONN);
    }
    if (s->cfg.max_per_peer == SC_MBTCP_PER_PEER_AUTO)
        s->cfg.max_per_peer = s->cfg.max_connections >= 4 ? s->cfg.max_connections / 4 : 1;
    sc_modbus_map_open(sc_modbus_map_shared(), s->cfg.word_order);
    struct sockaddr_storage addr;
    socklen_t alen;
    sc_status st = sc_mbtcp_resolve(s->cfg.host, s->cfg.port, &addr, &alen, err);
    if (st != SC_OK)
        return st;
    s->listen_fd = socket(addr.ss_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (s->listen_fd < 0) {
        return sc_error_set(err, SC_E_IO, NULL, 0, "modbus-tcp: socket: %s", strerror(errno));
    }
    int one = 1;
    setsockopt(s->listen_fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(s->listen_fd, (struct sockaddr *)&addr, alen) != 0 ||
        listen(s->listen_fd, 1024) != 0) { /* a connect burst waits in the backlog */
        char a[sizeof s->bound];
        sc_mbtcp_format_addr(&addr, a, sizeof a);
        close(s->listen_fd);
        s->listen_fd = -1;
        return sc_error_set(err, SC_E_IO, NULL, 0, "modbus-tcp: cannot listen on %s (%s): %s", a,
                            s->cfg.host, strerror(errno));
    }
    struct sockaddr_storage got;
    socklen_t glen = sizeof got;
    if (getsockname(s->listen_fd, (struct sockaddr *)&got, &glen) == 0) {
        s->bound_port = ntohs(got.ss_family == AF_INET6
                                  ? ((struct sockaddr_in6 *)&got)->sin6_port
                                  : ((struct sockaddr_in *)&got)->sin_port);
        sc_mbtcp_format_addr(&got, s->bound, sizeof s->bound);
    }
    char per_peer[32] = "no per-peer limit";
    if (s->cfg.max_per_peer > 0)
        snprintf(per_peer, sizeof per_peer, "%d per peer", s->cfg.max_per_peer);
    sc_log(SC_LOG_NOTICE,
           "modbus-tcp: listening on %s (unit id %u, max %d connections, %s, %s)", s->bound,
           (unsigned)s->cfg.unit_id, s->cfg.max_connections, per_peer,
           s->cfg.n_allow > 0 ? "an allow-list" : "any peer address");
    return SC_OK;
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

/* The connection to close for a newcomer at the cap: the longest idle among those that never
 * had a request answered (a flood of idle or half-open connections cannot push out a client
 * being served), else the longest idle of those served but silent for at least
 * SC_MBTCP_EVICT_SERVED_IDLE_MS; NULL if there is none (the newcomer is then refused). */
static conn *longest_idle(mbtcp_state *s, uint64_t now_ms)
{
    conn *best = NULL;
    for (int pass = 0; pass < 2 && best == NULL; pass++)
        for (int i = 0; i < SC_MBTCP_MAX_CONN; i++) {
            conn *c = &s->c[i];
            if (c->fd < 0 || (pass == 0 && c->served > 0))
                continue;
            if (pass == 1 && now_ms - c->last_rx_ms < SC_MBTCP_EVICT_SERVED_IDLE_MS)
                continue; /* a client being served is never reset for a newcomer */
            if (best == NULL || c->last_rx_ms < best->last_rx_ms)
                best = c;
        }
    return best;
}

static int peer_count(const mbtcp_state *s, const struct sockaddr_storage *peer)
{
    int n = 0;
    for (int i = 0; i < SC_MBTCP_MAX_CONN; i++)
        if (s->c[i].fd >= 0 && same_peer(&s->c[i].peer, peer))
            n++;
    return n;
}

static void tcp_accept(mbtcp_state *s, uint64_t now_ms)
{
    for (;;) {
        struct sockaddr_storage peer;
        socklen_t plen = sizeof peer;
        memset(&peer, 0, sizeof peer);
        int fd = accept4(s->listen_fd, (struct sockaddr *)&peer, &plen,
                         SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EINTR || errno == ECONNABORTED)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK)
                sc_log(SC_LOG_WARNING, "modbus-tcp: accept: %s", strerror(errno));
            return;
        }
        if (!sc_mbtcp_allowed(&s->cfg, &peer)) {
            s->denied++;
            char a[INET6_ADDRSTRLEN + 8];
            sc_mbtcp_format_addr(&peer, a, sizeof a);
            sc_log(SC_LOG_WARNING, "modbus-tcp: connection from %s closed: not in the allow-list; "
                   "%u denied so far", a, (unsigned)s->denied);
            close(fd);
            continue;
        }
        if (s->cfg.max_per_peer > 0 && peer_count(s, &peer) >= s->cfg.max_per_peer) {
            s->refused++;
            sc_log(SC_LOG_WARNING, "modbus-tcp: connection refused: this peer has %d open (the "
                   "per-peer limit); %u refused so far", s->cfg.max_per_peer,
                   (unsigned)s->refused);
            close(fd);
            continue;
        }
        if (s->nconn >= s->cfg.max_connections) {
            conn *victim = longest_idle(s, now_ms);
            if (victim == NULL) { /* every connection is a client being served */
                s->refused++;
                sc_log(SC_LOG_WARNING, "modbus-tcp: %d connections open (the cap), all of them "
                       "clients being served: the new connection is closed; %u refused so far",
                       s->nconn, (unsigned)s->refused);
                close(fd);
                continue;
            }
            s->evicted++;
            sc_log(SC_LOG_WARNING, "modbus-tcp: %d connections open (the cap): closing the "
                   "longest idle (%u ms); %u evicted so far", s->nconn,
                   (unsigned)(now_ms - victim->last_rx_ms), (unsigned)s->evicted);
            conn_close(s, victim, NULL);
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        for (int i = 0; i < SC_MBTCP_MAX_CONN; i++) {
            if (s->c[i].fd >= 0)
                continue;
            s->c[i].fd = fd;
            s->c[i].len = 0;
            s->c[i].last_rx_ms = now_ms;
            s->c[i].served = 0;
            s->c[i].peer = peer;
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
        int rc;
        if (unit == s->cfg.unit_id || unit == 0xff || unit == 0) /* 0, 255: "this device" */
            rc = sc_modbus_map_reply(sc_modbus_map_shared(), c->fd, p, total, MBAP_LEN, 0, e);
        else /* not us: what a gateway answers for an absent device */
            rc = sc_modbus_reply_exception(c->fd, p, MBAP_LEN, SC_MB_EX_GATEWAY_TARGET);
        if (rc < 0) {
            conn_close(s, c, "send failed (client not reading?)");
            return -1;
        }
        c->served++;
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
