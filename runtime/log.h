/* runtime/log.h — selfcald's log: stderr (default) or syslog, without allocating.
 * syslog is spoken directly (a datagram to /dev/log in the RFC 3164 form journald and rsyslog
 * accept) because glibc's syslog() allocates a buffer per message. */
#ifndef SELFCALD_LOG_H
#define SELFCALD_LOG_H

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

#endif
