/* runtime/log.h — selfcald's log: stderr (default) or syslog, without allocating and without
 * ever blocking (lines the sink cannot take, or beyond the rate, are dropped and counted).
 * syslog is spoken directly (a datagram to /dev/log in the RFC 3164 form journald and rsyslog
 * accept) because glibc's syslog() allocates a buffer per message. */
#ifndef SELFCALD_LOG_H
#define SELFCALD_LOG_H

#include <stdint.h>

/* Rate limit: a burst of SC_LOG_BURST lines, then SC_LOG_PER_SEC lines per second. */
#ifndef SC_LOG_BURST
#define SC_LOG_BURST 200.0
#endif
#ifndef SC_LOG_PER_SEC
#define SC_LOG_PER_SEC 50.0
#endif

enum { SC_LOG_ERR = 3, SC_LOG_WARNING = 4, SC_LOG_NOTICE = 5, SC_LOG_INFO = 6, SC_LOG_DEBUG = 7 };

/* Start logging: to syslog (the datagram socket at syslog_path, NULL = /dev/log; falling back to
 * stderr) when use_syslog, else stderr. Messages above max_level are dropped. */
void sc_log_open(int use_syslog, int max_level);
void sc_log_open_at(int use_syslog, int max_level, const char *syslog_path);

/* Log one line (no newline needed). */
void sc_log(int level, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

void sc_log_close(void);

/* 1 if lines go to syslog (not stderr). */
int sc_log_to_syslog(void);

/* Lines dropped since start (rate limit, or a sink that would have blocked). */
uint64_t sc_log_dropped(void);

#endif
