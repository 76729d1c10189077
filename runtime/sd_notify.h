/* runtime/sd_notify.h — the systemd notify protocol without libsystemd: one datagram per state
 * change ("READY=1", "RELOADING=1", "STOPPING=1", "WATCHDOG=1", "STATUS=...") to the unix socket
 * named by $NOTIFY_SOCKET (a leading '@' means the abstract namespace). */
#ifndef SELFCALD_SD_NOTIFY_H
#define SELFCALD_SD_NOTIFY_H

#include <stdbool.h>
#include <stdint.h>

#include "selfcal/error.h"

/* Read $NOTIFY_SOCKET and $WATCHDOG_USEC (honouring $WATCHDOG_PID) and open the socket.
 * SC_OK (*enabled: is there a socket to notify?), or SC_E_INPUT (unusable $NOTIFY_SOCKET) /
 * SC_E_IO (no socket) with notification off. enabled may be NULL. */
sc_status sc_notify_init(bool *enabled);

/* Send one message (e.g. "READY=1\nSTATUS=serving"); no-op (SC_OK) when disabled. SC_OK or
 * SC_E_IO. */
sc_status sc_notify(const char *msg);

/* The watchdog interval in microseconds the service manager asked for (0 = none). Send
 * "WATCHDOG=1" at least every half of it. */
uint64_t sc_notify_watchdog_usec(void);

void sc_notify_close(void);

#endif
