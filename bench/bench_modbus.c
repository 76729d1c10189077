/* bench_modbus — Modbus TCP round trip through selfcald on loopback: p50/p99/max of one
 * function 23 request (write 0-3, read 4-9) with 1 and with 64 concurrent clients.
 *
 * The daemon (selfcald_lib: the same loop, engine and Modbus server as the selfcald binary) runs
 * in a forked child process; the clients are libmodbus clients, one thread each, in this process.
 * Goal (issue 5): p99 <= 100 us with one client. Figures depend on the machine's load (2 shared
 * cores here): read them as an order of magnitude, and compare runs on an idle machine.
 * usage: bench_modbus [--requests N] (per run, split over the clients; default 20000)
 *        [--busy-poll-us N] (the second daemon's busy polling, default 1000) */
#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <modbus/modbus.h>

#include "daemon.h"
#include "log.h"
#include "selfcal/lut.h"
#include "transport_modbus.h"

static sc_lut g_lut;
static sc_daemon g_d;
static const char *g_busy_label; /* the running daemon's busy polling, for the table */

typedef struct client {
    int port, n;
    double *lat_us;
    int failures;
} client;

static double now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e6 + ts.tv_nsec * 1e-3;
}

static void *client_main(void *arg)
{
    client *c = arg;
    modbus_t *ctx = modbus_new_tcp("127.0.0.1", c->port);
    if (ctx == NULL || modbus_connect(ctx) != 0) {
        c->failures = c->n;
        return NULL;
    }
    modbus_set_slave(ctx, 1);
    modbus_set_response_timeout(ctx, 2, 0);
    uint16_t w[4], r[6];
    for (int k = 0; k < c->n; k++) {
        int32_t x = -9000000 + (k * 7919) % 18000000, y = 9000000 - (k * 104729) % 18000000;
        w[0] = (uint16_t)((uint32_t)x >> 16);
        w[1] = (uint16_t)x;
        w[2] = (uint16_t)((uint32_t)y >> 16);
        w[3] = (uint16_t)y;
        double t0 = now_us();
        int rc = modbus_write_and_read_registers(ctx, 0, 4, w, 4, 6, r);
        c->lat_us[k] = now_us() - t0;
        if (rc != 6)
            c->failures++;
    }
    modbus_close(ctx);
    modbus_free(ctx);
    return NULL;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int run(int port, int nclients, int total, int print)
{
    int per = total / nclients;
    client *cl = calloc((size_t)nclients, sizeof *cl);
    pthread_t *th = calloc((size_t)nclients, sizeof *th);
    double *all = calloc((size_t)per * (size_t)nclients, sizeof *all);
    if (cl == NULL || th == NULL || all == NULL)
        return -1;
    double t0 = now_us();
    for (int i = 0; i < nclients; i++) {
        cl[i].port = port;
        cl[i].n = per;
        cl[i].lat_us = all + (size_t)i * (size_t)per;
        pthread_create(&th[i], NULL, client_main, &cl[i]);
    }
    int failures = 0;
    for (int i = 0; i < nclients; i++) {
        pthread_join(th[i], NULL);
        failures += cl[i].failures;
    }
    double secs = (now_us() - t0) * 1e-6;
    size_t n = (size_t)per * (size_t)nclients;
    qsort(all, n, sizeof *all, cmp_double);
    if (print)
        printf("| %-17s | %7d | %8zu | %8.1f | %8.1f | %8.1f | %9.0f | %8d |\n", g_busy_label, nclients, n,
           all[n / 2], all[(size_t)(0.99 * (double)(n - 1))], all[n - 1], (double)n / secs,
           failures);
    free(cl);
    free(th);
    free(all);
    return failures;
}

int main(int argc, char **argv)
{
    int total = 20000;
    uint32_t busy_us = 1000;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--requests") == 0 && i + 1 < argc)
            total = atoi(argv[++i]);
        else if (strcmp(argv[i], "--busy-poll-us") == 0 && i + 1 < argc)
            busy_us = (uint32_t)atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_modbus [--requests N] [--busy-poll-us N (1000)]\n");
            return 2;
        }
    }
    if (total < 640)
        total = 640;
    char path[] = "/tmp/bench_modbus_XXXXXX";
    int fd = mkstemp(path);
    if (fd < 0)
        return 1;
    close(fd);
    sc_lut_init(&g_lut);
    g_lut.nx = g_lut.ny = 25;
    g_lut.x0_mm = g_lut.y0_mm = -12;
    g_lut.px_mm = g_lut.py_mm = 1;
    for (int k = 0; k < 625; k++) {
        g_lut.gx_um[k] = 0.001 * (k % 97) - 0.05;
        g_lut.gy_um[k] = 0.05 - 0.0007 * (k % 89);
    }
    sc_error err;
    memset(&err, 0, sizeof err);
    if (sc_lut_write_file(path, &g_lut, SC_LUT_ENC_AUTO, &err) != SC_OK) {
        fprintf(stderr, "bench_modbus: cannot write the table\n");
        return 1;
    }
    /* The daemon: open the server here (to learn the port), then serve in a child process.
     * Twice: as configured by default, and with --busy-poll-us (the loop polls without sleeping
     * for a while after each request, so that the next one does not wait for an idle CPU to wake:
     * on a virtual machine that wake-up alone costs tens of microseconds). */
    sc_log_open(0, SC_LOG_WARNING);
    printf("Modbus TCP round trip through selfcald (function 23: write 0-3, read 4-9), loopback\n");
    printf("| busy-poll         | clients | requests | p50 (us) | p99 (us) | max (us) | req/s     | failures |\n");
    printf("|-------------------|---------|----------|----------|----------|----------|-----------|----------|\n");
    int fails = 0;
    /* off (the default), the adaptive rule selfcald uses with --busy-poll-us, and the old rule
     * (spin whenever within the window) for comparison */
    const uint32_t busy[3] = {0, busy_us, busy_us};
    const int force[3] = {0, 0, 1};
    static char labels[3][32];
    snprintf(labels[0], sizeof labels[0], "off (default)");
    snprintf(labels[1], sizeof labels[1], "%u us adaptive", (unsigned)busy_us);
    snprintf(labels[2], sizeof labels[2], "%u us always", (unsigned)busy_us);
    for (int b = 0; b < 3; b++) {
        sc_error err;
        sc_daemon_init(&g_d, path, SC_CORR_MEASURE);
        g_d.busy_poll_us = busy[b];
        g_d.busy_poll_force = force[b];
        sc_mbtcp_config cfg;
        sc_mbtcp_config_defaults(&cfg);
        cfg.port = 0;
        cfg.max_connections = SC_MBTCP_MAX_CONN;
        cfg.max_per_peer = 0; /* all 64 clients come from 127.0.0.1 */
        sc_transport t;
        sc_modbus_tcp_transport(&t, &cfg);
        sc_daemon_add(&g_d, &t);
        if (sc_daemon_start(&g_d, &err) != SC_OK) {
            char why[sizeof err.file + sizeof err.msg + 32];
            sc_error_format(&err, why, sizeof why);
            fprintf(stderr, "bench_modbus: %s\n", why);
            return 1;
        }
        int port = sc_modbus_tcp_bound_port();
        pid_t pid = fork();
        if (pid == 0) {
            sc_daemon_catch_signals(&g_d);
            while (sc_daemon_step(&g_d, -1))
                ;
            sc_daemon_close(&g_d);
            _exit(0);
        }
        sc_daemon_close(&g_d); /* the parent's copies of the sockets */
        g_busy_label = labels[b];
        run(port, 1, total / 20, 0); /* warm-up, not printed */
        fails += run(port, 1, total, 1);
        fails += run(port, 64, total, 1);
        kill(pid, SIGTERM);
        int st;
        waitpid(pid, &st, 0);
    }
    unlink(path);
    printf("goal: p99 <= 100 us with one client\n");
    return fails ? 1 : 0;
}
