/* number_internal.h — private: the number parser over a text that lies inside a larger readable
 * buffer (the CSV reader's block), so that its fast path may look ahead past the text's end. */
#ifndef SELFCAL_NUMBER_INTERNAL_H
#define SELFCAL_NUMBER_INTERNAL_H

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* sc_number_parse_prefix on [s, end), allowed to read (never to take) bytes up to readable
 * (readable >= end, all of [s, readable) initialized memory). */
sc_status sc_number_parse_prefix_within(const char *s, const char *end, const char *readable,
                                        const char **stop, double *out);

#ifdef __cplusplus
}
#endif
#endif
