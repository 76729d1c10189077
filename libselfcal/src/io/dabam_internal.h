/* dabam_internal.h — the DABAM profile reader (io/dabam.c), for the profile simulation
 * (profile/profile_sim.c; not installed). */
#ifndef SELFCAL_DABAM_INTERNAL_H
#define SELFCAL_DABAM_INTERNAL_H

#include <stddef.h>

#include "selfcal/error.h"

/* The points of a .dat file: abscissae xs (m, increasing), ordinates ys (rad for slopes, m for
 * heights), count of them (at least 4 once read). */
typedef struct sc_dabam_points {
    double *xs, *ys;
    size_t count, cap;
    int is_slope; /* the metadata says slopes (else heights) */
} sc_dabam_points;

/* Read dat_path (a .dat file) and the .txt metadata beside it into d (allocated here; free with
 * sc_dabam_points_free). SC_E_INPUT with the file and line for anything that is not DABAM; on
 * failure d holds no memory. */
sc_status sc_dabam_read(const char *dat_path, sc_dabam_points *d, sc_error *err);

/* Free the arrays of d (safe on a zeroed d). */
void sc_dabam_points_free(sc_dabam_points *d);

#endif
