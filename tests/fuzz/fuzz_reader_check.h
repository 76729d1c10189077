/* tests/fuzz/fuzz_reader_check.h — the error contract every reader keeps: a status, and on
 * failure a one-line message (no newline, not empty). */
#ifndef SELFCAL_FUZZ_READER_CHECK_H
#define SELFCAL_FUZZ_READER_CHECK_H

#include <string.h>

#include "fuzz_common.h"
#include "selfcal/error.h"

static inline void fuzz_check_error(sc_status st, const sc_error *err)
{
    if (st == SC_OK)
        return;
    FUZZ_CHECK(st == SC_E_INPUT || st == SC_E_NOMEM || st == SC_E_IO);
    FUZZ_CHECK(err->msg[0] != '\0');
    FUZZ_CHECK(strchr(err->msg, '\n') == NULL);
}

#endif
