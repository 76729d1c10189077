/* runtime/daemon.c — the one poll() loop of selfcald. */
#include "daemon.h"

#include <errno.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/signalfd.h>
#include <time.h>
#include <unistd.h>

#include "log.h"
#include "sd_notify.h"

#define TICK_MS 50

static struct pollfd g_fds[1 + SC_DAEMON_MAX_TRANSPORTS * SC_TRANSPORT_MAX_FDS];
static char g_msg[256];

uint64_t sc_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

uint64_t sc_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

void sc_daemon_init(sc_daemon *d, const char *table_path, sc_corr_mode mode)
{
    memset(d, 0, sizeof *d);
    sc_engine_init(&d->engine, mode);
    snprintf(d->table_path, sizeof d->table_path, "%s", table_path);
    d->sigfd = -1;
}

sc_status sc_daemon_add(sc_daemon *d, const sc_transport *t)
{
    if (d->nt >= SC_DAEMON_MAX_TRANSPORTS)
        return SC_E_INPUT;
    d->t[d->nt++] = *t;
    return SC_OK;
}

sc_status sc_daemon_start(sc_daemon *d, sc_error *err)
{
    if (sc_engine_load_file(&d->engine, d->table_path, err) != SC_OK) {
        if (err)
            err->code = SC_E_INPUT; /* a table that cannot be read is bad input too */
        return SC_E_INPUT;
    }
    const sc_corr_table *tb = d->engine.table;
    sc_log(SC_LOG_NOTICE, "table %s loaded: %ux%u nodes, pitch %g x %g mm, %u profile(s), %s mode",
           d->table_path, (unsigned)tb->nx, (unsigned)tb->ny, tb->px_mm, tb->py_mm,
           (unsigned)tb->n_profiles, d->engine.mode == SC_CORR_MEASURE    ? "measure"
           : d->engine.mode == SC_CORR_POSITION ? "position"
                                                : "measure-exact");
    for (int i = 0; i < d->nt; i++) {
        sc_status st = d->t[i].open(d->t[i].state, err);
        if (st != SC_OK) {
            for (int k = i - 1; k >= 0; k--)
                d->t[k].close(d->t[k].state);
            return st;
        }
    }
    uint64_t wd_usec = sc_notify_watchdog_usec();
    d->watchdog_period_ms = wd_usec / 2000u;
    if (wd_usec > 0 && d->watchdog_period_ms == 0)
        d->watchdog_period_ms = 1;
    uint64_t now = sc_now_ms();
    d->next_tick_ms = now + TICK_MS;
    d->next_watchdog_ms = now + d->watchdog_period_ms;
    return SC_OK;
}

sc_status sc_daemon_catch_signals(sc_daemon *d)
{
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGHUP);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGINT);
    if (sigprocmask(SIG_BLOCK, &set, NULL) != 0)
        return SC_E_IO;
    signal(SIGPIPE, SIG_IGN);
    d->sigfd = signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
    return d->sigfd >= 0 ? SC_OK : SC_E_IO;
}

void sc_daemon_request_reload(sc_daemon *d)
{
    d->reload = 1;
}

void sc_daemon_request_stop(sc_daemon *d)
{
    d->stop = 1;
}

sc_status sc_daemon_reload(sc_daemon *d)
{
    sc_error err;
    char why[sizeof err.file + sizeof err.msg + 32];
    sc_notify("RELOADING=1");
    sc_status rc = sc_engine_load_file(&d->engine, d->table_path, &err);
    if (rc == SC_OK) {
        sc_log(SC_LOG_NOTICE, "reload: table %s loaded (%ux%u nodes); reloads ok %u, failed %u",
               d->table_path, (unsigned)d->engine.table->nx, (unsigned)d->engine.table->ny,
               (unsigned)d->engine.reload_ok, (unsigned)d->engine.reload_failed);
        snprintf(g_msg, sizeof g_msg, "READY=1\nSTATUS=serving; table reloaded");
    } else {
        sc_error_format(&err, why, sizeof why);
        sc_log(SC_LOG_ERR, "reload failed, keeping the previous table: %s", why);
        snprintf(g_msg, sizeof g_msg,
                 "READY=1\nSTATUS=serving the previous table; reload failed: %.180s", why);
    }
    sc_notify(g_msg);
    return rc;
}

/* Busy polling (--busy-poll-us): right after activity, poll with a zero timeout so the next
 * request does not pay the wake-up of an idle CPU (tens of us on a VM). On a shared machine a
 * spinning loop takes the core the client (or anyone else) needs, so it spins only while that
 * pays (the rule documented in docs/selfcald.md):
 * - requests come back to back: the last gap between two active rounds was below busy_poll_us;
 * - an empty spin yields the CPU (sched_yield) to whatever else is runnable on this core;
 * - every 256 spins, if fewer than 1 in 8 found work, spinning stops for a back-off (100 ms,
 *   doubling up to 1.6 s while it keeps not paying, reset when it pays). */
static int busy_poll_now(sc_daemon *d)
{
    if (d->busy_poll_us == 0)
        return 0;
    uint64_t now = sc_now_us();
    if (now - d->last_activity_us >= d->busy_poll_us)
        return 0;
    if (d->busy_poll_force)
        return 1;
    return d->last_gap_us < d->busy_poll_us && now >= d->spin_off_until_us;
}

static void busy_poll_account(sc_daemon *d, int spun, int active)
{
    uint64_t now = sc_now_us();
    if (active) {
        d->last_gap_us = now - d->last_activity_us;
        d->last_activity_us = now;
    }
    if (!spun || d->busy_poll_force)
        return;
    d->spin_rounds++;
    if (active)
        d->spin_hits++;
    else
        sched_yield();
    if (d->spin_rounds < 256)
        return;
    if (d->spin_hits * 8 < d->spin_rounds) {
        d->spin_backoff_ms = d->spin_backoff_ms ? d->spin_backoff_ms * 2 : 100;
        if (d->spin_backoff_ms > 1600)
            d->spin_backoff_ms = 1600;
        d->spin_off_until_us = now + (uint64_t)d->spin_backoff_ms * 1000u;
    } else {
        d->spin_backoff_ms = 0;
    }
    d->spin_rounds = d->spin_hits = 0;
}

static void read_signals(sc_daemon *d)
{
    struct signalfd_siginfo si;
    while (read(d->sigfd, &si, sizeof si) == (ssize_t)sizeof si) {
        if (si.ssi_signo == SIGHUP) {
            d->reload = 1;
        } else {
            sc_log(SC_LOG_NOTICE, "signal %u: stopping", (unsigned)si.ssi_signo);
            d->stop = 1;
        }
    }
}

bool sc_daemon_step(sc_daemon *d, int max_wait_ms)
{
    int n = 0;
    if (d->sigfd >= 0) {
        g_fds[n].fd = d->sigfd;
        g_fds[n].events = POLLIN;
        g_fds[n].revents = 0;
        n++;
    }
    int first = n;
    for (int i = 0; i < d->nt; i++) {
        d->nfds[i] = d->t[i].fill_pollfds(d->t[i].state, g_fds + n, SC_TRANSPORT_MAX_FDS);
        n += d->nfds[i];
    }
    uint64_t now = sc_now_ms();
    int64_t wait = (int64_t)d->next_tick_ms - (int64_t)now;
    if (d->watchdog_period_ms > 0 && (int64_t)d->next_watchdog_ms - (int64_t)now < wait)
        wait = (int64_t)d->next_watchdog_ms - (int64_t)now;
    if (wait < 0)
        wait = 0;
    if (max_wait_ms >= 0 && wait > max_wait_ms)
        wait = max_wait_ms;
    int spinning = wait > 0 && busy_poll_now(d);
    if (spinning)
        wait = 0;
    int rc = poll(g_fds, (nfds_t)n, (int)wait);
    if (d->busy_poll_us > 0)
        busy_poll_account(d, spinning, rc > 0);
    if (rc < 0 && errno != EINTR)
        sc_log(SC_LOG_ERR, "poll: %s", strerror(errno));
    now = sc_now_ms();
    if (rc > 0) {
        if (d->sigfd >= 0 && g_fds[0].revents)
            read_signals(d);
        int off = first;
        for (int i = 0; i < d->nt; i++) {
            d->t[i].serve(d->t[i].state, g_fds + off, d->nfds[i], &d->engine, now);
            off += d->nfds[i];
        }
    }
    if (now >= d->next_tick_ms) {
        for (int i = 0; i < d->nt; i++)
            if (d->t[i].tick != NULL)
                d->t[i].tick(d->t[i].state, &d->engine, now);
        d->next_tick_ms = now + TICK_MS;
    }
    if (d->watchdog_period_ms > 0 && now >= d->next_watchdog_ms) {
        sc_notify("WATCHDOG=1");
        d->next_watchdog_ms = now + d->watchdog_period_ms;
    }
    if (d->reload) {
        d->reload = 0;
        sc_daemon_reload(d);
    }
    return !d->stop;
}

void sc_daemon_close(sc_daemon *d)
{
    for (int i = d->nt - 1; i >= 0; i--)
        d->t[i].close(d->t[i].state);
    if (d->sigfd >= 0)
        close(d->sigfd);
    d->sigfd = -1;
}
