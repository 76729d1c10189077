/* selfcal/error.h — status codes and the error record a failing libselfcal call fills in.
 *
 * The library never prints: a failing call returns a status and, when the caller passes an
 * sc_error, describes the problem there (the input file and line when the problem is in a file).
 * A call that succeeds leaves the record as it was (like errno): test the returned status, not
 * err.code, or clear the record first with sc_error_clear.
 */
#ifndef SELFCAL_ERROR_H
#define SELFCAL_ERROR_H

#include "selfcal/api.h"

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sc_status {
    SC_OK = 0,
    SC_E_INPUT = 1,      /* bad input: unreadable field, inconsistent header, invalid parameter */
    SC_E_UNSOLVABLE = 2, /* the data or plan does not determine the unknowns */
    SC_E_NOMEM = 3,      /* an allocation failed, or a caller-provided workspace is too small */
    SC_E_IO = 4,         /* the operating system refused a read or write */
    SC_E_INTERNAL = 5    /* a numerical or internal failure that should not happen */
} sc_status;

typedef struct sc_error {
    sc_status code;
    char file[256]; /* the input file the problem is in, "" if none */
    long line;      /* 1-based line in that file, 0 if none */
    char msg[512];  /* one line, no trailing newline */
    int sys_errno;  /* errno of the system call that failed on `file` (ENOENT, EACCES, EISDIR,
                       ...), 0 when the problem is not a refusal by the system */
} sc_error;

/* Reset err to "no error"; err may be NULL. */
SC_API void sc_error_clear(sc_error *err);

/* Record an error (printf-style message, sys_errno 0) and return code; err may be NULL, file may
 * be NULL. */
SC_API sc_status sc_error_set(sc_error *err, sc_status code, const char *file, long line,
                              const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* Format err as "file:line: message" (or "file: message", or "message") into buf of size n. */
SC_API void sc_error_format(const sc_error *err, char *buf, size_t n);

/* A short constant name for a status ("bad input", "unsolvable", ...). */
SC_API const char *sc_status_name(sc_status code);

#ifdef __cplusplus
}
#endif
#endif
