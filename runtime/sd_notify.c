/* runtime/sd_notify.c — sd_notify(3) protocol over a unix datagram socket. */
#include "sd_notify.h"

#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

static int g_fd = -1;
static struct sockaddr_un g_addr;
static socklen_t g_addrlen;
static uint64_t g_watchdog_usec;

sc_status sc_notify_init(bool *enabled)
{
    if (enabled)
        *enabled = false;
    const char *path = getenv("NOTIFY_SOCKET");
    const char *wd = getenv("WATCHDOG_USEC");
    const char *wdpid = getenv("WATCHDOG_PID");
    g_watchdog_usec = 0;
    if (wd != NULL && *wd != '\0') {
        char *end = NULL;
        unsigned long long v = strtoull(wd, &end, 10);
        int for_us = 1;
        if (wdpid != NULL && *wdpid != '\0' && strtol(wdpid, NULL, 10) != (long)getpid())
            for_us = 0;
        if (end != NULL && *end == '\0' && for_us)
            g_watchdog_usec = v;
    }
    if (path == NULL || path[0] == '\0')
        return SC_OK;
    size_t len = strlen(path);
    if ((path[0] != '/' && path[0] != '@') || len >= sizeof g_addr.sun_path)
        return SC_E_INPUT;
    memset(&g_addr, 0, sizeof g_addr);
    g_addr.sun_family = AF_UNIX;
    memcpy(g_addr.sun_path, path, len);
    if (path[0] == '@')
        g_addr.sun_path[0] = '\0'; /* abstract namespace */
    g_addrlen = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + len);
    g_fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (g_fd < 0)
        return SC_E_IO;
    if (enabled)
        *enabled = true;
    return SC_OK;
}

sc_status sc_notify(const char *msg)
{
    if (g_fd < 0)
        return SC_OK;
    ssize_t r = sendto(g_fd, msg, strlen(msg), MSG_NOSIGNAL | MSG_DONTWAIT,
                       (const struct sockaddr *)&g_addr, g_addrlen);
    return r < 0 ? SC_E_IO : SC_OK;
}

uint64_t sc_notify_watchdog_usec(void)
{
    return g_watchdog_usec;
}

void sc_notify_close(void)
{
    if (g_fd >= 0)
        close(g_fd);
    g_fd = -1;
}
