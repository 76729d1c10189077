/* profile_file_internal.h — private: the profile reader's switch between one and two threads,
 * for the tests (io/profile_file.c). */
#ifndef SELFCAL_PROFILE_FILE_INTERNAL_H
#define SELFCAL_PROFILE_FILE_INTERNAL_H

#include "selfcal/profile_file.h"

/* Data rows of at least this many bytes are read by two threads where two cores are free (below
 * it, starting a thread costs more than it saves). */
#define SC_PROFILE_PARALLEL_FROM ((long long)4 << 20)

/* sc_profile_read with the two-thread threshold parallel_from (bytes of data rows); *threads
 * (may be NULL): 2 when two threads read the file, 1 when one did, 0 on failure. */
sc_status sc_profile_read_tuned(const char *path, long long parallel_from, int *threads,
                                sc_profile_data *out, sc_error *err);

#endif
