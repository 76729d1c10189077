/* selfcal/stage_map.h — the stage error map (SPEC §1 output, §5 rectangular stages) as one
 * neutral type, with the one strict reader and the one writer of its file
 * `i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um`.
 *
 * `selfcal grid` writes it, `lut build` and `export` read it into a table, `plot map` draws it.
 * Node (i, j): i = row along y (0..ny-1), j = column along x (0..nx-1), at
 * (x0_mm + j·px_mm, y0_mm + i·py_mm); arrays are row-major, index i·nx + j.
 *
 * Rules of the reader (every violation is SC_E_INPUT with FILE:LINE):
 * - blank lines and lines starting with '#' are skipped;
 * - the first other line is the column header: `i,j,x_mm,y_mm,gx_um,gy_um`, optionally followed
 *   by `ugx_um,ugy_um` (both), optionally followed by further columns (ignored: extensions);
 * - every row has as many fields as the header; i, j whole numbers; numbers finite; gx, gy
 *   present; ugx, ugy empty (no uncertainty) or >= 0; |positions| <= 1e6 mm, |values| <= 1e6 µm;
 * - each node once, and every node of the nx × ny rectangle present (nx, ny >= 2); rows in any
 *   order;
 * - regular: x_mm depends on j only and y_mm on i only, linearly and increasing, each node within
 *   1e-3 pitch of the fitted line; pitches >= 1 nm. x0, y0, px, py are the least-squares fit.
 */
#ifndef SELFCAL_STAGE_MAP_H
#define SELFCAL_STAGE_MAP_H

#include <stdbool.h>
#include <stdio.h>

#include "selfcal/api.h"
#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_STAGE_MAP_MAX_NODES 4097          /* per axis */
#define SC_STAGE_MAP_MIN_PITCH_MM 1e-6       /* 1 nm */
#define SC_STAGE_MAP_REGULAR_TOL 1e-3        /* of a pitch */

typedef struct sc_stage_map {
    int nx, ny;              /* nodes along x (columns j) and along y (rows i) */
    double x0_mm, y0_mm;     /* position of node (i = 0, j = 0), stage frame */
    double px_mm, py_mm;     /* pitch along x and along y, > 0 */
    double *gx_um, *gy_um;   /* stage error G at node (i, j), index i*nx + j */
    double *ugx_um, *ugy_um; /* standard uncertainty (k = 1); NULL or NaN where none */
} sc_stage_map;

/* Read a stage map file (rules above). On success m owns its arrays (free with
 * sc_stage_map_free); ugx/ugy are allocated and NaN-filled when the file has no uncertainty.
 * On failure m holds no memory. */
SC_API sc_status sc_stage_map_read(const char *path, sc_stage_map *m, sc_error *err);

/* Free the arrays of a map filled by sc_stage_map_read (safe on a zeroed map). */
SC_API void sc_stage_map_free(sc_stage_map *m);

/* Does the map carry at least one finite uncertainty? */
SC_API bool sc_stage_map_has_u(const sc_stage_map *m);

/* Position of node (i, j) in mm. */
SC_API double sc_stage_map_x_mm(const sc_stage_map *m, int j);
SC_API double sc_stage_map_y_mm(const sc_stage_map *m, int i);

/* Write the map as a file, atomically (temporary file, fsync, rename). Positions and values with
 * %.15g; a NaN uncertainty (or NULL arrays) is an empty field. */
SC_API sc_status sc_stage_map_write(const char *path, const sc_stage_map *m, sc_error *err);

/* The same to an open stream (the caller handles atomicity). */
SC_API void sc_stage_map_fprint(FILE *fp, const sc_stage_map *m);

#ifdef __cplusplus
}
#endif
#endif
