#include "selfcal/error.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

void sc_error_clear(sc_error *err)
{
    if (!err)
        return;
    err->code = SC_OK;
    err->file[0] = '\0';
    err->line = 0;
    err->msg[0] = '\0';
}

sc_status sc_error_set(sc_error *err, sc_status code, const char *file, long line,
                       const char *fmt, ...)
{
    if (!err)
        return code;
    err->code = code;
    snprintf(err->file, sizeof err->file, "%s", file ? file : "");
    err->line = line;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
    /* keep the message on one line */
    for (char *p = err->msg; *p; ++p)
        if (*p == '\n' || *p == '\r')
            *p = ' ';
    return code;
}

void sc_error_format(const sc_error *err, char *buf, size_t n)
{
    if (!buf || n == 0)
        return;
    if (!err) {
        snprintf(buf, n, "unknown error");
        return;
    }
    if (err->file[0] && err->line > 0)
        snprintf(buf, n, "%s:%ld: %s", err->file, err->line, err->msg);
    else if (err->file[0])
        snprintf(buf, n, "%s: %s", err->file, err->msg);
    else
        snprintf(buf, n, "%s", err->msg);
}

const char *sc_status_name(sc_status code)
{
    switch (code) {
    case SC_OK: return "ok";
    case SC_E_INPUT: return "bad input";
    case SC_E_UNSOLVABLE: return "unsolvable";
    case SC_E_NOMEM: return "out of memory";
    case SC_E_IO: return "i/o error";
    case SC_E_INTERNAL: return "internal error";
    }
    return "unknown status";
}
