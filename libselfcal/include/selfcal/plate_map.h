/* selfcal/plate_map.h — the plate error file of SPEC §1 (`i,j,ax_um,ay_um`, plate frame) as one
 * type, with its one strict reader and one writer (owned by io/).
 *
 * Mark (i, j): i = plate row (y), j = plate column (x), both 0..n-1, n odd; arrays row-major,
 * index i·n + j. A mark the method could not determine (SPEC §5, missing marks) has empty
 * ax_um, ay_um in the file and NaN in memory.
 *
 * Rules of the reader (SC_E_INPUT with FILE:LINE): blank and '#' lines skipped; the column header
 * is `i,j,ax_um,ay_um`, optionally followed by further columns (ignored); every row has the
 * header's field count; i, j whole numbers in 0..n-1; ax, ay both given (finite, |v| <= 1e6 µm)
 * or both empty; each mark once and all n × n present, n odd, 3 <= n <= SC_PLATE_MAP_MAX_N.
 */
#ifndef SELFCAL_PLATE_MAP_H
#define SELFCAL_PLATE_MAP_H

#include <stdio.h>

#include "selfcal/api.h"
#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_PLATE_MAP_MAX_N 4097

typedef struct sc_plate_map {
    int n;                 /* marks per side (odd) */
    double *ax_um, *ay_um; /* plate error of mark (i, j), plate frame; NaN where undetermined */
} sc_plate_map;

/* Read a plate error file (rules above). On success m owns its arrays (sc_plate_map_free); on
 * failure m holds no memory. */
SC_API sc_status sc_plate_map_read(const char *path, sc_plate_map *m, sc_error *err);

/* Free the arrays of a map filled by sc_plate_map_read (safe on a zeroed map). */
SC_API void sc_plate_map_free(sc_plate_map *m);

/* Write the map atomically (%.15g; NaN as empty fields). */
SC_API sc_status sc_plate_map_write(const char *path, const sc_plate_map *m, sc_error *err);

/* The same to an open stream (the caller handles atomicity). */
SC_API void sc_plate_map_fprint(FILE *fp, const sc_plate_map *m);

#ifdef __cplusplus
}
#endif
#endif
