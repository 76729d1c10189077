/* error.c — owns the library's one error convention: sc_status codes and the sc_error record
 * (file, line, one-line message), and their formatting for the CLI. */
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
    err->sys_errno = 0;
}

/* Length of the valid UTF-8 sequence at p that is printable on one line (no C1 control, no
 * U+2028/U+2029 line or paragraph separator), or 0. */
static int utf8_printable_len(const unsigned char *p)
{
    unsigned c = p[0];
    int len;
    unsigned cp;
    if (c >= 0xC2 && c <= 0xDF) {
        len = 2;
        cp = c & 0x1F;
    } else if (c >= 0xE0 && c <= 0xEF) {
        len = 3;
        cp = c & 0x0F;
    } else if (c >= 0xF0 && c <= 0xF4) {
        len = 4;
        cp = c & 0x07;
    } else {
        return 0;
    }
    for (int k = 1; k < len; ++k) {
        if ((p[k] & 0xC0) != 0x80)
            return 0;
        cp = (cp << 6) | (p[k] & 0x3F);
    }
    if ((len == 3 && cp < 0x800) || (len == 4 && (cp < 0x10000 || cp > 0x10FFFF)) ||
        (cp >= 0xD800 && cp <= 0xDFFF) || (cp >= 0x80 && cp <= 0x9F) || cp == 0x2028 ||
        cp == 0x2029)
        return 0;
    return len;
}

/* Messages quote the user's bytes: keep them on one printable line. Control characters and
 * invalid UTF-8 become '?'; valid UTF-8 (µ, ≤, ...) stays. */
static void sanitize_line(char *msg)
{
    unsigned char *p = (unsigned char *)msg;
    while (*p) {
        if (*p < 0x20 || *p == 0x7F) {
            *p++ = '?';
        } else if (*p < 0x80) {
            ++p;
        } else {
            int len = utf8_printable_len(p);
            if (len == 0)
                *p++ = '?';
            else
                p += len;
        }
    }
}

sc_status sc_error_set(sc_error *err, sc_status code, const char *file, long line,
                       const char *fmt, ...)
{
    if (!err)
        return code;
    err->code = code;
    snprintf(err->file, sizeof err->file, "%s", file ? file : "");
    err->line = line;
    err->sys_errno = 0;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
    sanitize_line(err->file);
    sanitize_line(err->msg);
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
