/* selfcal/import.h — reading what measuring machines write (SPEC §10): delimited tables with a
 * header line naming the columns (delimiter ',', ';' or tab, decimal mark '.' or ',', detected),
 * and numbering a view's measured points: each point is assigned to the plate mark nearest to it
 * once the view's placement (translation and rotation) has been fitted robustly from the points.
 *
 * The assignment (sc_grid_import_assign), documented in docs/import.md:
 *   1. Every point is matched to the mark whose nominal position (SPEC §1: rot, shift, origin) is
 *      nearest, gate half a pitch; the translation is the component-wise MEDIAN of the
 *      point − mark offsets, so a few wrong points (dust, a damaged mark) cannot move it.
 *   2. The placement (translation + rotation about the grid centre) is refitted by least squares
 *      (2-D Procrustes) on the pairs within the gate, points are matched again under it, and this
 *      repeats with the gate at the tolerance T until the matching no longer changes.
 *   3. A point farther than T from every mark the view measures is left out (reported by the
 *      caller); a mark without a point is absent (a view may measure few of its marks). Two points
 *      within T of one mark, or a view where fewer than min_share of its points (or none) fall
 *      on a mark — the wrong file, view, units or columns — are bad input.
 * Since T < P/2, the mark nearest a point is found in O(1) by rounding its plate coordinates.
 *
 * Straightness logs (sc_profile_import): the two scans' tables (position mm, m1 µm, m2 µm,
 * m3 µrad) become a selfcal-profile v1 data set after the sampling checks of docs/import.md.
 */
#ifndef SELFCAL_IMPORT_H
#define SELFCAL_IMPORT_H

#include <stdbool.h>
#include "selfcal/api.h"
#include "selfcal/grid.h"
#include "selfcal/profile.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Selected columns of a delimited table, as numbers. Owned by the struct (sc_table_free). */
typedef struct sc_table {
    char path[256];
    long header_line;  /* the line naming the columns */
    int n_cols;        /* columns selected */
    long n_rows;       /* data lines read */
    double *value;     /* n_rows * n_cols, row-major, each multiplied by its column's scale */
    long *line;        /* the file line of each row */
    char delimiter;    /* ',', ';', '\t', or ' ' (columns aligned by runs of blanks) */
    char decimal;      /* '.' or ','; '.' when no number had a fractional part */
    /* lines after the header that machines write and that are skipped (0: none): */
    long units_line;                    /* a line of unit names right under the header */
    long n_header_repeats, header_repeat_line; /* the header line again (page breaks) */
    long n_no_values, no_values_line;   /* rows without any of the wanted values (failed features) */
    long n_summary, summary_line;       /* summary rows: another field names a statistic ("Mean") */
    long n_footer, footer_line;         /* lines after the last row that are no rows (up to 20) */
} sc_table;

/* Read the columns names[0..n_cols-1] (matched case-insensitively, blanks and double quotes
 * around names ignored; a whole number no column is named: that column, 1-based) of a table:
 * lines starting with '#' (unless the header is "#;..." and the line "#<digit>...") and blank
 * lines are skipped, the first other line naming every column is the header (with every column
 * by number: the line before the first row), every further line is one row with as many fields
 * as the header.
 * The delimiter is a tab if the header has one, else ';' if it has one, else ',' if it has one,
 * else runs of blanks (columns aligned by spaces). The decimal mark
 * is ',' or '.' as the selected fields show; both in one file, a field with both, a missing column,
 * an empty or non-numeric field, or |value| > SC_INPUT_MAX_ABS (in the file's unit) -> SC_E_INPUT
 * with file:line. n_cols: 1..16 distinct names; scale (may be NULL: 1; finite, nonzero)
 * multiplies column k's values (unit conversion). Skipped and counted in t (the caller tells the
 * user): a line of empty fields; the header line again; a line of unit names right under the
 * header (or its repetition); a row with every wanted field empty; summary rows after the last
 * row (a field no wanted column is read from names a statistic: Mean, Max, Mittelwert, ...); and
 * up to 20 lines after the last row that are no rows (a footer: another field count or a wanted
 * field that is text, neither the first field nor a wanted one a number) — a row after them makes
 * the first of them the error it is. */
SC_API sc_status sc_table_read(const char *path, int n_cols, const char *const *names,
                               const double *scale, sc_table *t, sc_error *err);

/* The most rows sc_table_read takes: a scan of SC_PROFILE_MAX_N samples (a file or pipe with more
 * is refused at the row beyond, SC_E_INPUT with file:line, instead of read until memory runs out). */
#define SC_TABLE_MAX_ROWS ((long)SC_PROFILE_MAX_N)

/* The most points `selfcal import grid` takes from one view's file: four for every mark of the
 * largest plate (SC_GRID_MAX_N² marks), room for stray points and repeated features. */
#define SC_IMPORT_VIEW_MAX_POINTS (4L * SC_GRID_MAX_N * SC_GRID_MAX_N)

/* sc_table_read refusing a table of more than max_rows (1..SC_TABLE_MAX_ROWS) rows: SC_E_INPUT at
 * the first row beyond, with file:line; nothing beyond it is read. */
SC_API sc_status sc_table_read_max(const char *path, int n_cols, const char *const *names,
                                   const double *scale, long max_rows, sc_table *t, sc_error *err);

/* Layouts beyond one row per point (SPEC §10a); a zeroed struct reads as sc_table_read. */
#define SC_TABLE_MAX_WHERE 8   /* row filters */
#define SC_TABLE_MAX_MISSING 8 /* placeholder tokens */
typedef enum sc_table_encoding {
    SC_ENC_UTF8 = 0, /* (ASCII is UTF-8) */
    SC_ENC_CP1252,   /* Windows Western European, as Excel and many Windows programs save */
    SC_ENC_LATIN1,   /* ISO 8859-1 */
    SC_ENC_SHIFT_JIS /* Japanese Windows (CP932) */
} sc_table_encoding;

typedef struct sc_table_layout {
    /* One row per axis (all three or none): rows with the same id_col value form one point; the
     * axis_col value (matched ignoring case) names which of names[] the row's value_col holds;
     * rows of other axes are ignored. With nominal_col, each row's nominal too: the table then
     * has 2 * n_cols columns (the values, then the nominals, scale[] covering both). */
    const char *id_col, *axis_col, *value_col, *nominal_col;
    int n_where; /* only rows whose where_col[k] holds where_value[k] (ignoring case) are read */
    const char *where_col[SC_TABLE_MAX_WHERE], *where_value[SC_TABLE_MAX_WHERE];
    int n_missing; /* a wanted field holding one of these is empty (a mark not measured) */
    const char *missing[SC_TABLE_MAX_MISSING];
    bool no_header;  /* no header line: every column given by number, every line a row */
    bool transpose;  /* items in columns: names[] (or numbers) are the rows' labels (first field),
                        each further column one point */
    sc_table_encoding encoding; /* of the file's text (names); numbers are ASCII in all */
} sc_table_layout;

/* What a read with a layout passed over, for the caller to tell the user (sc_table_read_layout). */
typedef struct sc_table_notes {
    long n_filtered, filtered_line;       /* rows the where filters left out, the first's line */
    long n_placeholder, placeholder_line; /* wanted fields holding a missing token */
    long n_incomplete, incomplete_line;   /* one row per axis: points with only some coordinates
                                             (left out), the first's line */
    char incomplete_id[64];               /* the first such point's ID (cut to 63 bytes) */
    char incomplete_axis[32];             /* the first coordinate it lacks (names[k]) */
    long n_other_axis;                    /* one row per axis: rows of other axes (Z, D, ...) */
    long n_ragged, ragged_line;           /* rows with more fields than the header (unlabelled
                                             trailing text, ignored), the first's line */
    int header_fields, named_fields;      /* the header's fields, those up to its last name */
    int ragged_fields;                    /* the first such row's field count */
    int decimals;                         /* most digits after the decimal mark in a value read */
} sc_table_notes;

/* sc_table_read_max with a layout (NULL: none) and notes (may be NULL). The header's trailing
 * empty fields, and unlabelled trailing fields of rows that hold no number, are ignored (counted
 * in notes). Errors name the likely cause where one shows: a data row taken for the header
 * because a value matched a column's name (one row per axis), a header that is not UTF-8 (give
 * the encoding), more than 256 columns (items in columns: transpose). */
SC_API sc_status sc_table_read_layout(const char *path, int n_cols, const char *const *names,
                                      const double *scale, long max_rows,
                                      const sc_table_layout *layout, sc_table_notes *notes,
                                      sc_table *t, sc_error *err);

/* Free t's arrays; safe on a zeroed or freed table. */
SC_API void sc_table_free(sc_table *t);

/* The stage and plate a view's points are assigned on. */
typedef struct sc_grid_import_params {
    int n;                 /* marks per side, odd */
    double pitch_mm;       /* P */
    double origin_mm[2];   /* stage position of the stage grid's centre */
    int stage_nx, stage_ny; /* stage nodes along x and y (SPEC §5); 0, 0: N x N */
    double tolerance_mm;   /* T, 0 < T < P/2; points farther from every mark are left out */
    double min_share;      /* at least this share of a view's points must fall on its marks */
} sc_grid_import_params;

/* The fitted placement of one view and what was matched. */
typedef struct sc_grid_import_fit {
    double tx_um, ty_um;   /* translation of the plate from its nominal placement */
    double theta_urad;     /* rotation about the stage grid's centre, CCW */
    long n_marks;          /* marks the view measures (on the stage, rows=/cols= applied) */
    long n_assigned;       /* marks that got a point */
    long n_left_out;       /* points farther than T from every mark */
    double max_dist_um;    /* largest distance of an assigned point to its fitted mark position */
    int iterations;        /* refits until the matching stopped changing */
    long n_far;            /* points left out as far beyond the others (counted in n_left_out too):
                              more than 20 times the median distance and T/5 from their mark */
    double median_dist_um; /* the median distance of the matched points to their marks */
    long n_unselected;     /* points left out (counted in n_left_out) on marks the view's rows=/cols=
                              leave out (they count as matched for the share test) */
    long n_on_lattice;     /* points left out (beyond T of the view's marks) that lie within T of
                              the mark lattice all the same: a row or column of them says the
                              file is in the plate's frame (a shifted view seen unshifted) or
                              shift= is wrong, not dust */
} sc_grid_import_fit;

/* Defaults: T = P/4, min_share 0.5, stage N x N, origin 0. */
SC_API void sc_grid_import_defaults(sc_grid_import_params *p, int n, double pitch_mm);

/* Check p (n odd in 3..SC_GRID_MAX_N, P > 0, stage odd >= 3 or 0, 0 < T < P/2, 0 <= share <= 1). */
SC_API sc_status sc_grid_import_check(const sc_grid_import_params *p, sc_error *err);

/* Doubles of workspace sc_grid_import_assign needs for n_points points. */
SC_API size_t sc_grid_import_work_doubles(long n_points);

/* True and the stage node (*ni, *nj) if view v of the import puts mark (i, j) on a stage node that it
 * measures (rows=/cols= of v applied), else false. */
SC_API bool sc_grid_import_mark_node(const sc_grid_import_params *p, const sc_grid_view *v, int i, int j,
                                     int *ni, int *nj);

/* Assign the points (x_mm, y_mm: stage frame) of one view v. Fills point_mark[k] (the mark
 * i*n + j of point k, -1 if left out as farther than T from every mark, -2 as far beyond the
 * view's other points from its mark: a summary row, a point on the wrong feature, -3 as on a
 * mark the view's rows=/cols= leave out; n_points values) and mark_point[m] (the point of mark m
 * or -1; n*n values) and fit. lines[k] is point k's file line and path/header_line the file, for
 * errors (SC_E_INPUT: two points for one mark, too few marks matched). work:
 * sc_grid_import_work_doubles(n_points) doubles. */
SC_API sc_status sc_grid_import_assign(const sc_grid_import_params *p, const sc_grid_view *v,
                                       long n_points, const double *x_mm, const double *y_mm,
                                       const long *lines, const char *path, long header_line,
                                       long *point_mark, long *mark_point, sc_grid_import_fit *fit,
                                       double *work, sc_error *err);

/* What sc_profile_import needs besides the two logs. */
typedef struct sc_profile_import_params {
    double spacing_mm[2];  /* D1, D2: the displacement sensors' spacing in scan 1 and 2 */
    double step_mm;        /* s; 0: the median step between scan 1's sorted positions */
    double step_tolerance; /* a position may be this many steps off p0 + n·s (0 < tol < 0.5) */
} sc_profile_import_params;

/* Defaults: step from the data, tolerance 0.1 step (spacings must be set). */
SC_API void sc_profile_import_defaults(sc_profile_import_params *p);

/* Sort each scan's rows (tables of 4 columns: position mm, m1 µm, m2 µm, m3 µrad, e.g. from
 * sc_table_read with scales) by position, check the sampling (constant step s within the
 * tolerance from scan 1's first position p0, no repeats, both scans starting at p0, each D a
 * whole number of steps, last sample + 1 + d equal for both scans, at most half of a scan's
 * samples missing: SC_E_INPUT at the file and line otherwise) and fill out (allocated here, free
 * with sc_profile_data_free; no sigma lines; a position not logged is a gap: NaN, SPEC §2a).
 * *p0_mm (may be NULL) gets p0. */
SC_API sc_status sc_profile_import(const sc_profile_import_params *p, const sc_table *const scan[2],
                                   sc_profile_data *out, double *p0_mm, sc_error *err);

#ifdef __cplusplus
}
#endif
#endif
