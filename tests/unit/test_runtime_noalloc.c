/* selfcald allocates nothing after start: the daemon loop runs in its own thread with the Modbus
 * TCP server and the fake transport, while this thread drives it with a libmodbus client (round
 * trips, exceptions, a foreign unit id, connects and disconnects, a stalled client cut by the byte
 * timeout) and reloads (good and bad tables). Every malloc/calloc/realloc made by the daemon
 * thread after sc_daemon_start is counted: under ASan through the sanitizer's allocation hooks,
 * otherwise by interposing the allocator in this executable. The count must stay 0. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>

#include "daemon.h"
#include "selfcal/lut.h"
#include "transport_fake.h"
#include "transport_modbus.h"

static _Thread_local volatile int t_counting; /* set in the daemon thread once started */
static atomic_long g_allocs;

#if defined(__SANITIZE_ADDRESS__)
/* From <sanitizer/allocator_interface.h> (not installed with every gcc; exported by libasan). */
int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void *, size_t),
                                              void (*free_hook)(const volatile void *));
static void on_malloc(const volatile void *p, size_t n)
{
    (void)p;
    (void)n;
    if (t_counting)
        atomic_fetch_add(&g_allocs, 1);
}
static void on_free(const volatile void *p)
{
    (void)p;
}
static void install_counter(void)
{
    __sanitizer_install_malloc_and_free_hooks(on_malloc, on_free);
}
#else
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void __libc_free(void *);
void *malloc(size_t n)
{
    if (t_counting)
        atomic_fetch_add(&g_allocs, 1);
    return __libc_malloc(n);
}
void *calloc(size_t a, size_t b)
{
    if (t_counting)
        atomic_fetch_add(&g_allocs, 1);
    return __libc_calloc(a, b);
}
void *realloc(void *p, size_t n)
{
    if (t_counting)
        atomic_fetch_add(&g_allocs, 1);
    return __libc_realloc(p, n);
}
void free(void *p)
{
    __libc_free(p);
}
static void install_counter(void)
{
}
#endif

static sc_lut g_lut;
static sc_daemon g_d;
static atomic_int g_stop;
static char g_table[512], g_bad[512];

static void *daemon_thread(void *arg)
{
    (void)arg;
    t_counting = 1;
    while (!atomic_load(&g_stop))
        sc_daemon_step(&g_d, 20);
    t_counting = 0;
    return NULL;
}

static void make_table(const char *path)
{
    sc_lut_init(&g_lut);
    g_lut.nx = 9;
    g_lut.ny = 7;
    g_lut.x0_mm = -8;
    g_lut.y0_mm = -6;
    g_lut.px_mm = 2;
    g_lut.py_mm = 2;
    for (int k = 0; k < 63; k++) {
        g_lut.gx_um[k] = 0.01 * k - 0.3;
        g_lut.gy_um[k] = 0.2 - 0.007 * k;
    }
    sc_error err;
    memset(&err, 0, sizeof err);
    assert_int_equal(sc_lut_write_file(path, &g_lut, SC_LUT_ENC_AUTO, &err), SC_OK);
}

static void test_no_alloc_after_start(void **state)
{
    (void)state;
    sc_error why;
    snprintf(g_table, sizeof g_table, "%s/noalloc.lut", SELFCAL_TEST_TMP);
    snprintf(g_bad, sizeof g_bad, "%s/noalloc_bad.lut", SELFCAL_TEST_TMP);
    make_table(g_table);
    FILE *f = fopen(g_bad, "w");
    assert_non_null(f);
    fputs("not a table\n", f);
    fclose(f);

    sc_daemon_init(&g_d, g_table, SC_CORR_MEASURE);
    sc_mbtcp_config cfg;
    sc_mbtcp_config_defaults(&cfg);
    cfg.port = 0;
    cfg.byte_timeout_ms = 100;
    sc_transport t;
    sc_modbus_tcp_transport(&t, &cfg);
    sc_daemon_add(&g_d, &t);
    sc_fake_transport(&t);
    sc_daemon_add(&g_d, &t);
    assert_int_equal(sc_daemon_start(&g_d, &why), SC_OK);
    uint16_t port = sc_modbus_tcp_bound_port();
    assert_true(port > 0);
    install_counter();
    /* The counter itself works (a test that cannot fail proves nothing). */
    t_counting = 1;
    void *volatile probe = malloc(24);
    t_counting = 0;
    free(probe);
    printf("probe allocations counted: %ld\n", (long)atomic_load(&g_allocs));
    assert_true(atomic_load(&g_allocs) >= 1);
    atomic_store(&g_allocs, 0);
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, daemon_thread, NULL), 0);

    char portstr[8];
    snprintf(portstr, sizeof portstr, "%u", (unsigned)port);
    int rounds = 0;
    for (int conn = 0; conn < 5; conn++) {
        modbus_t *ctx = modbus_new_tcp("127.0.0.1", port);
        assert_non_null(ctx);
        modbus_set_slave(ctx, 1);
        assert_int_equal(modbus_connect(ctx), 0);
        uint16_t w[4], r[10];
        for (int k = 0; k < 300; k++) {
            int32_t x = -9000000 + 61234 * k, y = 7000000 - 45678 * k;
            w[0] = (uint16_t)((uint32_t)x >> 16);
            w[1] = (uint16_t)x;
            w[2] = (uint16_t)((uint32_t)y >> 16);
            w[3] = (uint16_t)y;
            assert_int_equal(modbus_write_and_read_registers(ctx, 0, 4, w, 4, 6, r), 6);
            assert_true(r[4] & 1);
            rounds++;
        }
        assert_int_equal(modbus_write_registers(ctx, 0, 4, w), 4);
        assert_int_equal(modbus_read_input_registers(ctx, 0, 6, r), 6);
        assert_int_equal(modbus_read_registers(ctx, 8, 3, r), -1); /* exception */
        assert_int_equal(modbus_write_register(ctx, 5, 1), -1);      /* exception */
        modbus_set_slave(ctx, 9);
        assert_int_equal(modbus_read_registers(ctx, 0, 1, r), -1); /* foreign unit */
        modbus_close(ctx);
        modbus_free(ctx);
    }
    /* A stalled client, dropped by the byte timeout. */
    int s = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    assert_int_equal(connect(s, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(send(s, "\0\1\0\0\0\6\1", 7, 0), 7);
    char c;
    struct timeval tv = {2, 0};
    setsockopt(s, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    assert_int_equal(recv(s, &c, 1, 0), 0);
    close(s);
    /* The fake transport, and reloads: bad then good (requested; the loop thread does them). */
    int peer = sc_fake_peer_fd();
    for (int k = 0; k < 50; k++) {
        int32_t p[2] = {k * 1000, -k * 1000};
        assert_int_equal(send(peer, p, 8, 0), 8);
        unsigned char ans[12];
        tv.tv_sec = 2;
        setsockopt(peer, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
        assert_int_equal(recv(peer, ans, sizeof ans, 0), 12);
    }
    snprintf(g_d.table_path, sizeof g_d.table_path, "%s", g_bad);
    sc_daemon_request_reload(&g_d);
    usleep(100000);
    snprintf(g_d.table_path, sizeof g_d.table_path, "%s", g_table);
    sc_daemon_request_reload(&g_d);
    usleep(100000);
    atomic_store(&g_stop, 1);
    pthread_join(th, NULL);
    assert_int_equal(g_d.engine.reload_failed, 1);
    assert_int_equal(g_d.engine.reload_ok, 1); /* the start's load is not counted */
    assert_true(g_d.engine.corrections >= (uint32_t)rounds);
    printf("daemon-thread allocations after start: %ld (over %u corrections)\n",
           (long)atomic_load(&g_allocs), (unsigned)g_d.engine.corrections);
    assert_int_equal(atomic_load(&g_allocs), 0);
    sc_daemon_close(&g_d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_no_alloc_after_start)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
