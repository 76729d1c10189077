/* selfcal/grid_io.h — the grid files of SPEC §1: read `selfcal-grid v1` data and plan files,
 * write stage error maps (through io/, selfcal/stage_map.h), plate error maps and run summaries.
 *
 * Reading is strict: every problem is SC_E_INPUT with the file and line. All writers go through
 * sc_afile (a file is complete or absent). Numbers are written with %.15g (and positions in mm with
 * 15 decimals) so that noise-free results survive a round trip to 1e-9 µm.
 */
#ifndef SELFCAL_GRID_IO_H
#define SELFCAL_GRID_IO_H

#include <stdio.h>

#include "selfcal/api.h"
#include "selfcal/grid.h"
#include "selfcal/stage_map.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Where things were found in an input file (for error messages the caller reports later). */
typedef struct sc_grid_file_info {
    long first_line;                     /* the "# selfcal-grid v1" line (1) */
    long n_line;                         /* the "# N = ..." line */
    long header_end_line;                /* last header line (the column header if present) */
    long *view_line;                     /* the "# view K: ..." line of each view (plan index) */
    int *view_id;                        /* K as written in the file for each view */
    long n_rows;                         /* data rows read (0 for a plan file) */
    long *view_rows;                     /* data rows per view */
    int has_u;                           /* the columns ux_um,uy_um are present */
    int has_t;                           /* the column t_s is present and filled */
} sc_grid_file_info;
/* (view_line, view_id, view_rows: n_views entries each, made by sc_grid_read and freed by
 * sc_grid_file_info_free.) */

/* Free the per-view arrays of info (safe on a zeroed or already freed info). */
SC_API void sc_grid_file_info_free(sc_grid_file_info *info);

/* Make d's per-view tables (dx_um ... t_s: d->plan.n_views NULL pointers each, one block that
 * starts at d->dx_um) if it has none. */
SC_API sc_status sc_grid_data_views(sc_grid_data *d, sc_error *err);

/* Make d's per-view tables (sc_grid_data_views) and allocate d->dx_um/dy_um (n*n each,
 * NaN-filled) for every view of d->plan. */
SC_API sc_status sc_grid_data_alloc(sc_grid_data *d, sc_error *err);

/* Allocate (NaN-filled, n*n) d->ux_um/uy_um when weights, d->t_s when times, for every view. */
SC_API sc_status sc_grid_data_alloc_extra(sc_grid_data *d, int weights, int times, sc_error *err);

/* Free the arrays of d, its per-view tables and its plan's views (safe on a zeroed or already
 * freed d). */
SC_API void sc_grid_data_free(sc_grid_data *d);

/* Read a selfcal-grid v1 file (plan header, then optional column header and data rows).
 * Fills d->plan and allocates d's arrays: dev = (measured - nominal) in µm, NaN where a mark has no
 * row. info (may be NULL) says where things were. On failure d holds no memory. */
SC_API sc_status sc_grid_read(const char *path, sc_grid_data *d, sc_grid_file_info *info, sc_error *err);

/* Write the header of a selfcal-grid v1 file for plan p (version, N, pitch, origin, views with
 * rows=/cols= when restricted) to fp. */
SC_API void sc_grid_write_header(FILE *fp, const sc_grid_plan *p);

/* Write a selfcal-grid v1 input file: the header, the column header and one row per finite
 * measurement in d (measured position in mm = origin + node + dev/1000, 15 decimals). */
SC_API sc_status sc_grid_write_input(const char *path, const sc_grid_data *d, sc_error *err);
SC_API void sc_grid_fprint_input(FILE *fp, const sc_grid_data *d);

/* The stage map of a result on plan p as a view on the caller's arrays (nothing allocated, never
 * freed, only read): nx = NX, ny = NY (the stage grid), node (0, 0) at origin - (cx, cy)·P,
 * both pitches P. */
SC_API sc_stage_map sc_grid_stage_map(const sc_grid_plan *p, const double *gx_um,
                                      const double *gy_um, const double *ugx_um,
                                      const double *ugy_um);

/* Write a stage error map (selfcal/stage_map.h, through sc_stage_map_write). ugx/ugy may be NULL;
 * NaN uncertainties are written as empty fields. */
SC_API sc_status sc_grid_write_map(const char *path, const sc_grid_plan *p, const double *gx_um,
                                   const double *gy_um, const double *ugx_um, const double *ugy_um,
                                   sc_error *err);

/* The same to an open stream (the caller handles atomicity). */
SC_API void sc_grid_fprint_map(FILE *fp, const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                               const double *ugx_um, const double *ugy_um);

/* Write a plate error map `i,j,ax_um,ay_um` (plate frame; through io/, selfcal/plate_map.h;
 * NaN as empty fields). */
SC_API sc_status sc_grid_write_artifact(const char *path, const sc_grid_plan *p,
                                        const double *ax_um, const double *ay_um, sc_error *err);
SC_API void sc_grid_fprint_artifact(FILE *fp, const sc_grid_plan *p, const double *ax_um,
                                    const double *ay_um);

/* Write a JSON summary of a result: method, N, pitch, origin, O, R, each view's tx, ty (µm) and
 * θ (µrad), residual RMS, σ_r estimated and used, n_measurements, dof. NaN is written as null. */
SC_API sc_status sc_grid_write_summary(const char *path, const char *method, const sc_grid_plan *p,
                                       const sc_grid_result *res, sc_error *err);
SC_API void sc_grid_fprint_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                                   const sc_grid_result *res);

/* Read a plate error file (`i,j,ax_um,ay_um`, the rules of sc_plate_map_read in
 * selfcal/plate_map.h, and N <= SC_GRID_MAX_N) into m: gx/gy hold ax/ay (plate frame, NaN where
 * empty) at the plate-centred nominal mark positions (node (0, 0) at (-cP, -cP), pitch P mm as
 * given); uncertainties NaN. On failure m holds no memory. */
SC_API sc_status sc_grid_read_artifact(const char *path, double pitch_mm, sc_stage_map *m,
                                       sc_error *err);

/* Write `view,i,j,rx_um,ry_um,tx,ty,outlier` (SPEC §5): one row per finite rx (arrays
 * n_views*n*n, index v*n*n + i*n + j); view_id: the view numbers as in the input (NULL: index);
 * NaN t is written empty. */
SC_API void sc_grid_fprint_residuals(FILE *fp, const sc_grid_plan *p, const int *view_id,
                                     const double *rx_um, const double *ry_um, const double *tx,
                                     const double *ty, const unsigned char *outlier);

/* Write a rows x cols row-major matrix as a numpy .npy file (format 1.0, '<f8', C order). */
SC_API void sc_fprint_npy(FILE *fp, const double *a, long rows, long cols);

#ifdef __cplusplus
}
#endif
#endif
