/* runtime/daemon.h — selfcald's event loop: one poll() over every transport's descriptors and a
 * signalfd (SIGHUP reload, SIGTERM/SIGINT stop), a tick every <= 100 ms for timeouts and periodic
 * frames, and the systemd notify protocol (READY, RELOADING, STOPPING, WATCHDOG at half the
 * interval). Static storage only; no allocation after sc_daemon_start. */
#ifndef SELFCALD_DAEMON_H
#define SELFCALD_DAEMON_H

#include <stdbool.h>
#include <stdint.h>

#include "engine.h"
#include "transport.h"

#define SC_DAEMON_MAX_TRANSPORTS 4

typedef struct sc_daemon {
    sc_engine engine;
    sc_transport t[SC_DAEMON_MAX_TRANSPORTS];
    int nt;
    int nfds[SC_DAEMON_MAX_TRANSPORTS]; /* pollfds each transport got in this round */
    char table_path[512];
    int sigfd;                /* -1 when signals are not routed into the loop (unit tests) */
    int stop;                 /* set by SIGTERM/SIGINT or sc_daemon_request_stop */
    int reload;               /* set by SIGHUP or sc_daemon_request_reload */
    uint64_t watchdog_period_ms; /* 0 = no watchdog */
    uint64_t next_watchdog_ms, next_tick_ms;
    uint32_t busy_poll_us;    /* after activity, poll with a zero timeout this long (0 = off) */
    int busy_poll_force;      /* 1: spin whenever within busy_poll_us (the old rule; benchmarks) */
    uint64_t last_activity_us, last_gap_us;
    uint32_t spin_rounds, spin_hits; /* this window's zero-timeout polls, and those that found work */
    uint64_t spin_off_until_us;      /* adaptive back-off: no spinning before this */
    uint32_t spin_backoff_ms;
} sc_daemon;

/* Prepare d for table_path and mode (no transports yet). */
void sc_daemon_init(sc_daemon *d, const char *table_path, sc_corr_mode mode);

/* Add a transport (copied). SC_OK, or SC_E_INPUT if there are already SC_DAEMON_MAX_TRANSPORTS. */
sc_status sc_daemon_add(sc_daemon *d, const sc_transport *t);

/* Load the table, open every transport. SC_OK; SC_E_INPUT if the table is missing or invalid
 * (bad input: selfcald exits 2); another status if a transport cannot open (err says which;
 * nothing is left open; selfcald exits 1). */
sc_status sc_daemon_start(sc_daemon *d, sc_error *err);

/* Route SIGHUP/SIGTERM/SIGINT into the loop (signalfd) and ignore SIGPIPE. SC_OK or SC_E_IO. */
sc_status sc_daemon_catch_signals(sc_daemon *d);

/* One round: poll up to max_wait_ms, serve, tick, reload/watchdog as due. Should the daemon go
 * on? (false once it was asked to stop.) */
bool sc_daemon_step(sc_daemon *d, int max_wait_ms);

/* Reload the table now (what SIGHUP does): load into the spare slot, swap if valid, log.
 * SC_OK, or the status of the failed load (the previous table stays in use). */
sc_status sc_daemon_reload(sc_daemon *d);

void sc_daemon_request_reload(sc_daemon *d);
void sc_daemon_request_stop(sc_daemon *d);

/* Close every transport (and the signalfd). */
void sc_daemon_close(sc_daemon *d);

/* Monotonic milliseconds. */
uint64_t sc_now_ms(void);

/* Monotonic clock in microseconds. */
uint64_t sc_now_us(void);

#endif
