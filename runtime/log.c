/* runtime/log.c — stderr or syslog logging into a static buffer (no allocation), which never
 * blocks the loop: every write is non-blocking, lines beyond a rate (a token bucket: a burst of
 * SC_LOG_BURST, then SC_LOG_PER_SEC lines per second; one bucket for notices and errors, one
 * for the rest) or that the sink cannot take right now are
 * dropped and counted, and the count is logged with the next line that gets through.
 *
 * stderr is written without blocking however it is connected: a socket (journald's stream) with
 * send(MSG_DONTWAIT); a pipe, FIFO or terminal through a second descriptor opened from
 * /proc/self/fd/2 with O_NONBLOCK (its own open file description, so the flags of the shared
 * stderr are left alone); a regular file directly (writes to it do not wait for a reader). */
#include "log.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

static int g_syslog_fd = -1;
static int g_max_level = SC_LOG_INFO;
static char g_line[1024];
static int g_err_fd = STDERR_FILENO; /* where stderr lines go */
static int g_err_is_socket;
static int g_err_own; /* g_err_fd was opened here */
static uint64_t g_dropped, g_dropped_reported;
/* Two buckets: notices and errors (start, reload, stop) are not crowded out by a flood of
 * per-connection info/warning/debug lines, and each kind is bounded. */
static double g_tokens[2] = {SC_LOG_BURST, SC_LOG_BURST};
static uint64_t g_last_refill_ms[2];

static uint64_t mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static void open_stderr(void)
{
    struct stat st;
    if (g_err_own || fstat(STDERR_FILENO, &st) != 0)
        return;
    if (S_ISSOCK(st.st_mode)) {
        g_err_is_socket = 1;
        return;
    }
    if (S_ISREG(st.st_mode))
        return;
    int fd = open("/proc/self/fd/2", O_WRONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd >= 0) {
        g_err_fd = fd;
        g_err_own = 1;
        return;
    }
    /* No /proc: make stderr itself non-blocking (its flags are shared with whoever else holds
     * it, acceptable for a daemon). */
    int fl = fcntl(STDERR_FILENO, F_GETFL);
    if (fl >= 0)
        fcntl(STDERR_FILENO, F_SETFL, fl | O_NONBLOCK);
}

void sc_log_open(int use_syslog, int max_level)
{
    sc_log_open_at(use_syslog, max_level, NULL);
}

void sc_log_open_at(int use_syslog, int max_level, const char *syslog_path)
{
    if (syslog_path == NULL || syslog_path[0] == '\0')
        syslog_path = "/dev/log";
    g_max_level = max_level;
    for (int b = 0; b < 2; b++) {
        g_tokens[b] = SC_LOG_BURST;
        g_last_refill_ms[b] = mono_ms();
    }
    open_stderr();
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

int sc_log_to_syslog(void)
{
    return g_syslog_fd >= 0;
}

void sc_log_close(void)
{
    if (g_syslog_fd >= 0)
        close(g_syslog_fd);
    g_syslog_fd = -1;
    if (g_err_own)
        close(g_err_fd);
    g_err_fd = STDERR_FILENO;
    g_err_own = 0;
    g_err_is_socket = 0;
}

uint64_t sc_log_dropped(void)
{
    return g_dropped;
}

/* One token per line; the bucket refills at SC_LOG_PER_SEC up to SC_LOG_BURST. */
static int take_token(int level)
{
    int b = level <= SC_LOG_NOTICE ? 0 : 1;
    uint64_t now = mono_ms();
    g_tokens[b] += (double)(now - g_last_refill_ms[b]) * (SC_LOG_PER_SEC / 1000.0);
    g_last_refill_ms[b] = now;
    if (g_tokens[b] > SC_LOG_BURST)
        g_tokens[b] = SC_LOG_BURST;
    if (g_tokens[b] < 1.0)
        return 0;
    g_tokens[b] -= 1.0;
    return 1;
}

/* Write one whole line without blocking: 1 if it went out, 0 if dropped. */
static int emit(size_t len)
{
    if (g_syslog_fd >= 0) {
        if (send(g_syslog_fd, g_line, len, MSG_NOSIGNAL | MSG_DONTWAIT) >= 0)
            return 1;
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)
            return 0; /* syslog busy: drop, never wait */
        /* syslog gone: fall through to stderr */
    }
    g_line[len++] = '\n';
    ssize_t w;
    do {
        w = g_err_is_socket ? send(g_err_fd, g_line, len, MSG_NOSIGNAL | MSG_DONTWAIT)
                            : write(g_err_fd, g_line, len);
    } while (w < 0 && errno == EINTR);
    return w == (ssize_t)len; /* lines < PIPE_BUF go whole into a pipe or not at all */
}

static size_t format(int level, const char *fmt, va_list ap)
{
    static const char *const names[8] = {"emerg", "alert", "crit", "error",
                                         "warning", "notice", "info", "debug"};
    int n;
    if (g_syslog_fd >= 0) /* facility daemon (3) */
        n = snprintf(g_line, sizeof g_line, "<%d>selfcald[%d]: ", 3 * 8 + level, (int)getpid());
    else
        n = snprintf(g_line, sizeof g_line, "selfcald: %s: ", names[level & 7]);
    if (n < 0 || (size_t)n >= sizeof g_line)
        return 0;
    int m = vsnprintf(g_line + n, sizeof g_line - (size_t)n, fmt, ap);
    if (m < 0)
        return 0;
    size_t len = (size_t)n + (size_t)m;
    if (len > sizeof g_line - 2)
        len = sizeof g_line - 2;
    return len;
}

/* Format and write one line; a line the sink does not take is counted as dropped. */
static void emit_vfmt(int level, const char *fmt, va_list ap)
{
    size_t len = format(level, fmt, ap);
    if (len > 0 && !emit(len))
        g_dropped++;
}

static void emit_fmt(int level, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    emit_vfmt(level, fmt, ap);
    va_end(ap);
}

void sc_log(int level, const char *fmt, ...)
{
    if (level > g_max_level)
        return;
    if (!take_token(level)) {
        g_dropped++;
        return;
    }
    if (g_dropped != g_dropped_reported) {
        uint64_t d = g_dropped - g_dropped_reported;
        g_dropped_reported = g_dropped;
        emit_fmt(SC_LOG_WARNING, "%llu log line(s) dropped (rate limit or a log sink not "
                 "draining); %llu since start", (unsigned long long)d,
                 (unsigned long long)g_dropped);
    }
    va_list ap;
    va_start(ap, fmt);
    emit_vfmt(level, fmt, ap);
    va_end(ap);
}
