/* runtime/sd_notify.h — the systemd notify protocol without libsystemd: one datagram per state
 * change ("READY=1", "RELOADING=1", "STOPPING=1", "WATCHDOG=1", "STATUS=...") to the unix socket
 * named by $NOTIFY_SOCKET (a leading '@' means the abstract namespace). */
#ifndef SELFCALD_SD_NOTIFY_H
#define SELFCALD_SD_NOTIFY_H

#include <stdint.h>

/* Read $NOTIFY_SOCKET and $WATCHDOG_USEC (honouring $WATCHDOG_PID) and open the socket.
 * Returns 1 if notification is enabled, 0 if not (no socket in the environment), -1 on error. */
int sc_notify_init(void);

/* Send one message (e.g. "READY=1\nSTATUS=serving"); no-op when disabled. 0 or -1. */
int sc_notify(const char *msg);

/* The watchdog interval in microseconds the service manager asked for (0 = none). Send
 * "WATCHDOG=1" at least every half of it. */
uint64_t sc_notify_watchdog_usec(void);

void sc_notify_close(void);

#endif
