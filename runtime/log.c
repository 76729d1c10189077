/* runtime/log.c — stderr or syslog logging into a static buffer (no allocation). */
#include "log.h"

#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

static int g_syslog_fd = -1;
static int g_max_level = SC_LOG_INFO;
static char g_line[1024];

void sc_log_open(int use_syslog, int max_level)
{
    sc_log_open_at(use_syslog, max_level, NULL);
}

void sc_log_open_at(int use_syslog, int max_level, const char *syslog_path)
{
    if (syslog_path == NULL || syslog_path[0] == '\0')
        syslog_path = "/dev/log";
    g_max_level = max_level;
    if (!use_syslog)
        return;
    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return;
    struct sockaddr_un a;
    memset(&a, 0, sizeof a);
    a.sun_family = AF_UNIX;
    if (strlen(syslog_path) >= sizeof a.sun_path) {
        close(fd);
        fprintf(stderr, "selfcald: syslog socket path too long, logging to stderr\n");
        return;
    }
    strcpy(a.sun_path, syslog_path);
    if (connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        close(fd);
        fprintf(stderr, "selfcald: syslog (%s) unavailable, logging to stderr\n", syslog_path);
        return;
    }
    g_syslog_fd = fd;
}

void sc_log_close(void)
{
    if (g_syslog_fd >= 0)
        close(g_syslog_fd);
    g_syslog_fd = -1;
}

void sc_log(int level, const char *fmt, ...)
{
    if (level > g_max_level)
        return;
    static const char *const names[8] = {"emerg", "alert", "crit", "error",
                                         "warning", "notice", "info", "debug"};
    int n;
    if (g_syslog_fd >= 0) /* facility daemon (3) */
        n = snprintf(g_line, sizeof g_line, "<%d>selfcald[%d]: ", 3 * 8 + level, (int)getpid());
    else
        n = snprintf(g_line, sizeof g_line, "selfcald: %s: ", names[level & 7]);
    if (n < 0 || (size_t)n >= sizeof g_line)
        return;
    va_list ap;
    va_start(ap, fmt);
    int m = vsnprintf(g_line + n, sizeof g_line - (size_t)n, fmt, ap);
    va_end(ap);
    if (m < 0)
        return;
    size_t len = (size_t)n + (size_t)m;
    if (len > sizeof g_line - 2)
        len = sizeof g_line - 2;
    if (g_syslog_fd >= 0) {
        if (send(g_syslog_fd, g_line, len, MSG_NOSIGNAL | MSG_DONTWAIT) >= 0)
            return;
        /* syslog gone: fall through to stderr */
    }
    g_line[len++] = '\n';
    ssize_t w = write(STDERR_FILENO, g_line, len);
    (void)w;
}
