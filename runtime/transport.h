/* runtime/transport.h — the one small interface every selfcald transport implements
 * (Modbus TCP, Modbus RTU, SocketCAN, in-process fake). Each lives in its own file.
 *
 * The daemon's single poll() loop asks every transport for the descriptors it wants watched,
 * polls, then hands each transport back its slice of the pollfd array. Transports keep all state
 * in static storage sized at compile time and never allocate after open().
 */
#ifndef SELFCALD_TRANSPORT_H
#define SELFCALD_TRANSPORT_H

#include <poll.h>
#include <stdint.h>

#include "engine.h"

#define SC_TRANSPORT_MAX_FDS 80

typedef struct sc_transport {
    const char *name;
    void *state; /* the transport's static state */
    /* Open sockets/devices. SC_OK, or a status with the reason in err. */
    sc_status (*open)(void *state, sc_error *err);
    /* Fill up to max pollfds; returns how many. */
    int (*fill_pollfds)(void *state, struct pollfd *fds, int max);
    /* Serve the descriptors that fill_pollfds gave (with revents set). now_ms: monotonic ms. */
    void (*serve)(void *state, struct pollfd *fds, int n, sc_engine *e, uint64_t now_ms);
    /* Called at least every 100 ms: timeouts, periodic frames. May be NULL. */
    void (*tick)(void *state, sc_engine *e, uint64_t now_ms);
    /* Close everything. */
    void (*close)(void *state);
} sc_transport;

#endif
