/* verify.h — the check of a compensated machine (`selfcal verify`, `report grid --verify`).
 *
 * Model. After the table is loaded, the plate is measured once more (a selfcal-grid v1 file,
 * typically one view, rot 0). With the table active (position mode, or measure mode applied to the
 * readings) the machine reports p_c = p − G_table(p); the mark's deviation from its nominal stage
 * position is then
 *     dev_after = (G − G_table)(node) + Rot(A(mark)) + misalignment + noise,
 * so once the plate error A of the calibration and a fitted misalignment (tx, ty, θ per view) are
 * removed, what is left is the error the table did not compensate, plus noise. The reading the
 * machine would have given without the table, p = p_c + G_table(p) (the table in position mode
 * applied to p_c), gives the map before compensation, ≈ G. With --raw the file holds uncompensated
 * readings instead: before = them, after = the table's measure-mode correction applied to them.
 * Corrections go through the same correction core as selfcald (sc_corr_apply).
 * Verdict: pass if the largest |after| residual is at most the tolerance.
 */
#ifndef SELFCAL_VERIFY_H
#define SELFCAL_VERIFY_H

#include <stdio.h>

#include "selfcal/grid_io.h"
#include "selfcal/stage_map.h"
#include "input_once.h"

typedef struct verify_opts {
    const char *measurement; /* V.csv */
    const char *table;       /* T.lut */
    const char *artifact;    /* A.csv (plate error), unless plate is set */
    const sc_stage_map *plate; /* the plate error already at hand (report), plate frame */
    const cli_input *src[3]; /* measurement, table, artifact as read (cli_input_open: a pipe
                                from memory); NULL: read by the names above */
    double tolerance_um;     /* NaN: no verdict */
    int raw;                 /* 1: the file holds uncompensated readings */
} verify_opts;

typedef struct verify_stats {
    long count;
    double rms_x, rms_y, rms, max; /* µm */
    double max_x_mm, max_y_mm;     /* stage position of the largest */
} verify_stats;

typedef struct verify_result {
    sc_grid_data d;
    sc_grid_file_info info;
    sc_stage_map before, after; /* per stage node, mean over the views that measure it (NaN: none) */
    double *buf;
    double *bx, *by, *ax, *ay; /* per view and mark (n_views*n*n), NaN where not used */
    double tx_after[32], ty_after[32], th_after[32]; /* fitted misalignment per view (µm, µrad) */
    verify_stats st_before, st_after;
    long n_unmeasured;         /* marks a view places on the stage without a point in the file */
    long n_unseen;             /* measured marks the calibration saw no error for (plate NaN) */
    int pass;                  /* 1 pass, 0 fail, -1 no tolerance */
} verify_result;

/* Set the defaults (no files, tolerance NaN, compensated readings). */
void verify_opts_init(verify_opts *o);

/* Read the re-measurement, the table and the plate error, compute before/after. */
sc_status verify_run(const verify_opts *o, verify_result *r, sc_error *err);

/* Free r (safe on a zeroed r). */
void verify_result_free(verify_result *r);

/* The report section: model, statistics, verdict, before/after maps. */
sc_status verify_html_section(FILE *fp, const verify_opts *o, const verify_result *r,
                              const char *heading, sc_error *err);

#endif
