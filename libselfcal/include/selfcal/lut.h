/* selfcal/lut.h — lookup tables on the host: read the SPEC map and profile CSVs, encode and decode
 * the binary table file (docs/lut-format.md), write it atomically, evaluate the map.
 *
 * sc_lut is a fixed-size structure (about 300 KB: allocate it, e.g. with malloc, or static); the
 * library allocates nothing that outlives a call. The runtime side is selfcal/correct.h.
 */
#ifndef SELFCAL_LUT_H
#define SELFCAL_LUT_H

#include <stdbool.h>
#include "selfcal/api.h"

#include <stddef.h>
#include <stdint.h>

#include "selfcal/correct.h"
#include "selfcal/error.h"
#include "selfcal/sha256.h"
#include "selfcal/stage_map.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_LUT_MAX_NX 101
#define SC_LUT_MAX_NY 101
#define SC_LUT_MAX_PROFILES 8
#define SC_LUT_MAX_PROFILE_POINTS 2048
#define SC_LUT_MAX_SOURCES 9 /* the map and one file per profile */
#define SC_LUT_METHOD_LEN 32 /* method text, NUL included */

/* Encodings of the correction values (codes times a per-block scale in picometres). Automatic
 * choice: int16 when its scale is at most this (quantization <= 0.05 nm, |values| <= 3.2767 um),
 * otherwise int32 (1 pm codes: quantization <= 0.0005 nm up to +-2147 um). */
#define SC_LUT_AUTO_MAX_INT16_SCALE_PM 100u
typedef enum sc_lut_encoding {
    SC_LUT_ENC_AUTO = 0,  /* int16 if its quantization is <= 0.05 nm, else int32 */
    SC_LUT_ENC_INT16 = 1, /* 2 bytes per value */
    SC_LUT_ENC_INT32 = 2  /* 4 bytes per value */
} sc_lut_encoding;

typedef struct sc_lut_profile {
    int axis, dir;        /* SC_CORR_AXIS_X/Y/Z: error of coordinate dir as a function of axis */
    int n;                /* points, 2..SC_LUT_MAX_PROFILE_POINTS */
    double start_mm;      /* axis position of point 0 */
    double step_mm;       /* spacing, > 0 */
    int encoding;         /* as stored (after encode/decode) */
    uint32_t scale_pm;    /* picometres per code (after encode/decode) */
    double err_um[SC_LUT_MAX_PROFILE_POINTS];
} sc_lut_profile;

typedef struct sc_lut_provenance {
    char method[SC_LUT_METHOD_LEN]; /* e.g. "double-shift"; "" if not known */
    int64_t created_unix_s;         /* creation time, seconds since 1970 UTC */
    double sigma_um;                /* estimated sigma of the map; < 0 if not known */
    int n_sources;                  /* source files hashed: the map first, then the profiles */
    uint8_t sha256[SC_LUT_MAX_SOURCES][SC_SHA256_BYTES];
} sc_lut_provenance;

typedef struct sc_lut {
    int nx, ny;              /* nodes along x (columns j) and y (rows i), 2..101 */
    double x0_mm, y0_mm;     /* position of node (i=0, j=0) */
    double px_mm, py_mm;     /* pitch along x and y, > 0 */
    int grid_encoding;       /* as stored (after encode/decode) */
    uint32_t grid_scale_pm;  /* picometres per code (after encode/decode) */
    double gx_um[SC_LUT_MAX_NX * SC_LUT_MAX_NY]; /* node (i, j) at i*nx + j */
    double gy_um[SC_LUT_MAX_NX * SC_LUT_MAX_NY];
    int n_profiles;
    sc_lut_profile profile[SC_LUT_MAX_PROFILES];
    sc_lut_provenance prov;
} sc_lut;

/* Reset to an empty table: no grid, no profiles, no provenance (sigma unknown). */
SC_API void sc_lut_init(sc_lut *lut);

/* Copy a stage map into the grid of lut; SC_E_INPUT (naming `name`) if it does not fit a table
 * (more than SC_LUT_MAX_NX x SC_LUT_MAX_NY nodes, pitch below 1 nm). */
SC_API sc_status sc_lut_set_grid(sc_lut *lut, const sc_stage_map *m, const char *name,
                                 sc_error *err);

/* Read a stage map file (sc_stage_map_read: the one reader and its rules) into the grid of lut. */
SC_API sc_status sc_lut_read_map(const char *path, sc_lut *lut, sc_error *err);

/* What sc_lut_fit_grid made of a map: the map's nodes, whether a coarser grid was fitted, and the
 * table's error at every map node, |table(node) − G(node)| over both components (µm). */
typedef struct sc_lut_fit_report {
    int map_nx, map_ny;  /* nodes of the map */
    int fitted;          /* 1 if the table has fewer nodes than the map along x or y */
    double rms_um;       /* RMS over the map's nodes of the vector error (0 when copied) */
    double max_um;       /* the largest of them ... */
    double max_at_mm[2]; /* ... at this map node (x, y) */
} sc_lut_fit_report;

/* The grid of lut from a map of any size: along an axis with more than max_nodes nodes (2..101),
 * max_nodes table nodes spanning the map's extent exactly, valued by least squares so that the
 * table's bilinear interpolation is closest to G over all the map's nodes (docs/lut-format.md);
 * other axes copied node for node. rep (may be NULL) gets the table's error at the map's nodes. */
SC_API sc_status sc_lut_fit_grid(sc_lut *lut, const sc_stage_map *m, int max_nodes,
                                 const char *name, sc_lut_fit_report *rep, sc_error *err);

/* Read a stage map file and fit the grid of lut to it (sc_lut_fit_grid). */
SC_API sc_status sc_lut_read_map_fitted(const char *path, sc_lut *lut, int max_nodes,
                                        sc_lut_fit_report *rep, sc_error *err);

/* Read the ey_um column of a SPEC §2 profile output file (`n,x_mm,f_um,uf_um,ey_um`) as the
 * error of coordinate dir along axis; trailing empty ey cells are dropped, an empty cell between
 * values is an error. Positions come from x_mm (must be regular). */
SC_API sc_status sc_lut_read_profile(const char *path, int axis, int dir, sc_lut_profile *p,
                                     sc_error *err);

/* Parse "x", "y" or "z" (either case) to SC_CORR_AXIS_*; -1 otherwise. */
SC_API int sc_lut_axis_from_name(const char *s);

/* "x", "y" or "z". */
SC_API const char *sc_lut_axis_name(int axis);

/* The exact size in bytes of lut encoded with the given encoding. */
SC_API size_t sc_lut_encoded_size(const sc_lut *lut, sc_lut_encoding enc);

/* Encode lut into buf (capacity cap bytes) as a version-1 table; *len = bytes written. Chooses
 * each block's scale (smallest of 1-2-5 x 10^k pm that holds the block's largest value) and
 * stores it, with the encoding, back into lut. The result is checked with sc_corr_validate. */
SC_API sc_status sc_lut_encode(sc_lut *lut, sc_lut_encoding enc, uint8_t *buf, size_t cap,
                               size_t *len, sc_error *err);

/* Decode a table image (validated with sc_corr_validate; SC_E_INPUT and the reason if invalid,
 * `name` used as the file name in the message). Values are code * scale, exactly. */
SC_API sc_status sc_lut_decode(const uint8_t *buf, size_t len, sc_lut *lut, const char *name,
                               sc_error *err);

/* Encode and write atomically to path (temporary file, fsync, rename). */
SC_API sc_status sc_lut_write_file(const char *path, sc_lut *lut, sc_lut_encoding enc,
                                   sc_error *err);

/* Read and decode a table file. */
SC_API sc_status sc_lut_read_file(const char *path, sc_lut *lut, sc_error *err);

/* Read a table file and load it into the correction core's table *t (selfcal/correct.h), ready
 * for sc_corr_apply. SC_E_INPUT with the file and the reason if the file is not a valid table. */
SC_API sc_status sc_lut_load_corr_file(const char *path, sc_corr_table *t, sc_error *err);

/* What the table commands, as sc_corr_bounds measures a loaded one: the largest correction of
 * one coordinate (um: largest |Gx| or |Gy| plus the largest |value| of each profile of that DIR)
 * and the steepest change between neighbouring nodes or profile points (um per mm). */
SC_API void sc_lut_bounds(const sc_lut *lut, double *max_correction_um,
                          double *max_gradient_um_per_mm);

/* The quantization bound of a block: half its scale, in micrometres. */
SC_API double sc_lut_quantization_um(uint32_t scale_pm);

/* Bilinear G of the grid at (x, y) mm, in double precision (um); outside the grid the value at
 * the nearest edge point. Returns true if (x, y) was outside (and, with NaN values, when the table
 * has no grid). The reference for the exporters. */
SC_API bool sc_lut_grid_eval(const sc_lut *lut, double x_mm, double y_mm, double *gx_um,
                             double *gy_um);

#ifdef __cplusplus
}
#endif
#endif
