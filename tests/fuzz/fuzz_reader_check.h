/* tests/fuzz/fuzz_reader_check.h — the error contract every reader keeps: a status, and on
 * failure a one-line message (no newline, not empty). FUZZ_SHOW_ERRORS=1 prints each outcome. */
#ifndef SELFCAL_FUZZ_READER_CHECK_H
#define SELFCAL_FUZZ_READER_CHECK_H

#include <string.h>

#include "fuzz_common.h"
#include "selfcal/error.h"

static inline void fuzz_check_error(sc_status st, const sc_error *err)
{
    static int show = -1; /* FUZZ_SHOW_ERRORS=1: print every error (triage of a corpus) */
    if (show < 0)
        show = getenv("FUZZ_SHOW_ERRORS") != NULL;
    if (show)
        fprintf(stderr, "[%s] %s:%ld: %s\n", st == SC_OK ? "ok" : "error", err->file, err->line,
                st == SC_OK ? "" : err->msg);
    if (st == SC_OK)
        return;
    FUZZ_CHECK(st == SC_E_INPUT || st == SC_E_NOMEM || st == SC_E_IO);
    FUZZ_CHECK(err->msg[0] != '\0');
    FUZZ_CHECK(strchr(err->msg, '\n') == NULL);
}

#endif
