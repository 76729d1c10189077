/* runtime/selfcald.c — the machine-side correction daemon (SPEC §3-4): loads a lookup table and
 * corrects positions for Modbus TCP, Modbus RTU and SocketCAN clients from one poll() loop. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "config.h"
#include "daemon.h"
#include "log.h"
#include "modbus_map.h"
#include "sd_notify.h"
#include "selfcal/version.h"
#include "transport_modbus.h"
#ifdef SELFCALD_HAVE_CAN
#include "transport_can.h"
#endif

static sc_config g_cfg;
static sc_daemon g_daemon;

/* A failure to start: logged, and on stderr too when the log goes to syslog (whoever started
 * the daemon by hand sees why it exited). */
static void start_failed(const char *why)
{
    sc_log(SC_LOG_ERR, "%s", why);
    if (sc_log_to_syslog())
        fprintf(stderr, "selfcald: %s\n", why);
}

int main(int argc, char **argv)
{
    sc_error err;
    char why[sizeof err.file + sizeof err.msg + 32];
    int help, version;
    sc_config_defaults(&g_cfg);
    if (sc_config_parse_args(&g_cfg, argc, argv, &help, &version, &err) != SC_OK) {
        sc_error_format(&err, why, sizeof why);
        fprintf(stderr, "selfcald: %s (selfcald --help)\n", why);
        return 2;
    }
    if (help || version) { /* printed in full, or exit 1 (a full disk, a closed pipe) */
        if (help)
            fputs(sc_config_usage, stdout);
        else
            printf("selfcald %s\n", sc_version());
        errno = 0;
        if (fflush(stdout) != 0 || ferror(stdout)) {
            fprintf(stderr, "selfcald: cannot write to standard output: %s\n",
                    errno ? strerror(errno) : "write error");
            return 1;
        }
        return 0;
    }
    sc_log_open_at(g_cfg.use_syslog, g_cfg.log_level, g_cfg.syslog_socket);
    if (sc_notify_init(NULL) != SC_OK)
        sc_log(SC_LOG_WARNING, "NOTIFY_SOCKET is set but unusable; not notifying systemd");

    sc_daemon_init(&g_daemon, g_cfg.table, g_cfg.mode);
    g_daemon.busy_poll_us = g_cfg.busy_poll_us;
    g_daemon.engine.max_correction_um = g_cfg.max_correction_um;
    g_daemon.engine.max_gradient_um_per_mm = g_cfg.max_gradient_um_per_mm;
    g_cfg.tcp.word_order = g_cfg.rtu.word_order = g_cfg.word_order; /* the map takes it at open */
    sc_transport t;
    if (g_cfg.use_modbus_tcp) {
        sc_modbus_tcp_transport(&t, &g_cfg.tcp);
        sc_daemon_add(&g_daemon, &t);
    }
    if (g_cfg.use_modbus_rtu) {
        sc_modbus_rtu_transport(&t, &g_cfg.rtu);
        sc_daemon_add(&g_daemon, &t);
    }
    if (g_cfg.use_can) {
#ifdef SELFCALD_HAVE_CAN
        sc_can_transport(&t, &g_cfg.can);
        sc_daemon_add(&g_daemon, &t);
#else
        fprintf(stderr, "selfcald: --can: this build has no SocketCAN transport\n");
        return 1;
#endif
    }
    if (sc_daemon_catch_signals(&g_daemon) != 0) {
        start_failed("cannot set up signal handling");
        return 1;
    }
    sc_status st = sc_daemon_start(&g_daemon, &err);
    if (st != SC_OK) {
        sc_error_format(&err, why, sizeof why);
        start_failed(why);
        sc_notify("STATUS=start failed");
        return st == SC_E_INPUT ? 2 : 1; /* 2: bad table; 1: a transport could not open */
    }
    sc_log(SC_LOG_NOTICE, "ready");
    sc_notify("READY=1\nSTATUS=serving");
    while (sc_daemon_step(&g_daemon, -1))
        ;
    sc_notify("STOPPING=1");
    sc_log(SC_LOG_NOTICE, "stopped after %u corrections", (unsigned)g_daemon.engine.corrections);
    sc_daemon_close(&g_daemon);
    sc_modbus_map_close(sc_modbus_map_shared());
    sc_notify_close();
    sc_log_close();
    return 0;
}
