/* runtime/transport_modbus.h — the Modbus TCP and Modbus RTU servers of selfcald (SPEC §4).
 * Both answer from the one shared register map (modbus_map.h). */
#ifndef SELFCALD_TRANSPORT_MODBUS_H
#define SELFCALD_TRANSPORT_MODBUS_H

#include <stdint.h>
#include <sys/socket.h>

#include "modbus_map.h"
#include "transport.h"

/* Compile-time cap on TCP connections (one pollfd each, plus the listening socket). */
#define SC_MBTCP_MAX_CONN (SC_TRANSPORT_MAX_FDS - 1)

/* Most networks an allow-list (--allow) may name. */
#define SC_MBTCP_MAX_ALLOW 16
/* max_per_peer's default: a quarter of max_connections (at least 1), resolved at open. */
#define SC_MBTCP_PER_PEER_AUTO (-1)
/* At the cap, a connection that has had a request answered is closed for a newcomer only after
 * this long without a request (a busy client is never reset by a connect burst). */
#define SC_MBTCP_EVICT_SERVED_IDLE_MS 1000u

/* One network of an allow-list: family AF_INET or AF_INET6, the address, the prefix length. */
typedef struct sc_cidr {
    int family;
    uint8_t addr[16];
    int prefix;
} sc_cidr;

typedef struct sc_mbtcp_config {
    char host[64];             /* listen address: IPv4, IPv6 or a name; default "127.0.0.1"
                                * ("0.0.0.0": all IPv4, "::": all) */
    uint16_t port;             /* default 1502; 0 = any free port (logged) */
    uint8_t unit_id;           /* default 1; 0 and 255 (this device) are always accepted */
    int max_connections;       /* default 64, at most SC_MBTCP_MAX_CONN */
    uint32_t byte_timeout_ms;  /* a started request must complete within this; default 500 */
    uint32_t idle_timeout_ms;  /* close a connection silent this long; 0 = never; default 60000 */
    int max_per_peer;          /* connections one peer address may hold; 0 = no limit;
                                * default SC_MBTCP_PER_PEER_AUTO: max_connections / 4 */
    int n_allow;               /* 0: any peer; else only peers in allow[] (others closed at accept) */
    sc_cidr allow[SC_MBTCP_MAX_ALLOW];
    sc_word_order word_order;  /* of 32-bit values; default high word first (SPEC) */
} sc_mbtcp_config;

typedef struct sc_mbrtu_config {
    char device[128];          /* serial device, e.g. /dev/ttyUSB0 */
    int baud;                  /* default 19200 */
    char parity;               /* 'N', 'E' (default) or 'O' */
    int data_bits;             /* 8 */
    int stop_bits;             /* 1 */
    uint8_t unit_id;           /* default 1 (1..247) */
    uint32_t byte_timeout_ms;  /* 0 (default): frames end after t3.5 of silence and break at
                                * t1.5, from the baud rate (Modbus over Serial Line §2.5.1.1);
                                * N > 0: frames end after N ms of silence, no t1.5 check (an
                                * adapter that delivers bytes in bursts) */
    sc_word_order word_order;  /* of 32-bit values; default high word first (SPEC) */
} sc_mbrtu_config;

void sc_mbtcp_config_defaults(sc_mbtcp_config *c);
void sc_mbrtu_config_defaults(sc_mbrtu_config *c);

/* Make t the Modbus TCP server for cfg (static state, one instance). */
void sc_modbus_tcp_transport(sc_transport *t, const sc_mbtcp_config *cfg);
/* The port actually listened on (after open; useful with port 0). */
uint16_t sc_modbus_tcp_bound_port(void);
/* Connections open now / refused because of the cap since start. */
int sc_modbus_tcp_connections(void);
uint32_t sc_modbus_tcp_refused(void);
/* Connections closed to make room for a new one at the cap (the longest idle first). */
uint32_t sc_modbus_tcp_evicted(void);
/* Connections closed at accept because the peer is not in the allow-list. */
uint32_t sc_modbus_tcp_denied(void);
/* Parse "CIDR[,CIDR...]" (a.b.c.d[/len], IPv6[/len]; a plain address is one host) and add the
 * networks to c's allow-list (several lists add up, at most SC_MBTCP_MAX_ALLOW networks). SC_OK,
 * or SC_E_INPUT with the reason in err. */
sc_status sc_mbtcp_parse_allow(sc_mbtcp_config *c, const char *list, sc_error *err);
/* Is the peer address a within one of c's networks (or is the list empty)? An IPv4-mapped IPv6
 * peer (::ffff:a.b.c.d) is matched as its IPv4 address. */
int sc_mbtcp_allowed(const sc_mbtcp_config *c, const struct sockaddr_storage *a);

/* Resolve a listen address: an IPv4 literal (dotted decimal, as inet_pton reads it), an IPv6
 * literal, or a name (getaddrinfo; its IPv4 address first). The legacy forms inet_aton accepts
 * (0127.0.0.1 is octal, 127.1, 0x7f.1) are refused. SC_OK, or SC_E_INPUT with the reason in err. */
sc_status sc_mbtcp_resolve(const char *host, uint16_t port, struct sockaddr_storage *out,
                           socklen_t *outlen, sc_error *err);
/* "a.b.c.d:port" or "[v6]:port". */
void sc_mbtcp_format_addr(const struct sockaddr_storage *a, char *buf, int len);

/* Make t the Modbus RTU server for cfg (static state, one instance). */
void sc_modbus_rtu_transport(sc_transport *t, const sc_mbrtu_config *cfg);
/* Frames dropped by the RTU server since start: bad CRC, or incomplete at a silence. */
uint32_t sc_modbus_rtu_bad_frames(void);
/* Frames for other units (requests, responses, exceptions) and broadcasts skipped since start. */
uint32_t sc_modbus_rtu_other_frames(void);
/* The silences of cfg in microseconds: t1.5 (0: not checked) and t3.5 (11-bit characters; fixed
 * 750 us / 1750 us above 19 200 baud; t3.5 = byte_timeout_ms when that is set). */
void sc_mbrtu_silences(const sc_mbrtu_config *c, uint32_t *t15_us, uint32_t *t35_us);
/* For tests: the clock (monotonic microseconds) that stamps each read; NULL restores it. */
void sc_modbus_rtu_use_clock(uint64_t (*clock_us)(void));
/* For tests: make open() serve fd (e.g. one end of a socketpair standing for the serial line)
 * instead of opening cfg.device; close() then leaves fd open. fd < 0 restores normal behaviour. */
void sc_modbus_rtu_use_fd(int fd);

#endif
