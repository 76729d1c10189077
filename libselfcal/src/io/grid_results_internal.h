/* grid_results_internal.h — the JSON of a grid run summary (io/grid_results.c), for the writer
 * of a calibration's summary (grid/grid_summary.c), which adds the scale budget and the Monte
 * Carlo figures of grid_calibrate.h's solution (not installed). */
#ifndef SELFCAL_GRID_RESULTS_INTERNAL_H
#define SELFCAL_GRID_RESULTS_INTERNAL_H

#include <stdio.h>

#include "selfcal/grid.h"

/* v as %.15g, or null where it is not finite. */
void sc_io_json_num(FILE *fp, double v);

/* `, "key": v` (a member of an object on one line). */
void sc_io_json_kv(FILE *fp, const char *key, double v);

/* `,\n  "key": [a, b]`, or null when not have (a top-level member). */
void sc_io_json_pair(FILE *fp, const char *key, int have, double a, double b);

/* Further members of view v's object (each `, "key": value`), written after its noise figures. */
typedef void (*sc_io_summary_view_fn)(FILE *fp, const void *ctx, const sc_grid_plan *p, int v);

/* The summary of res on plan p without its closing brace: views numbered by view_id (NULL: their
 * position), each with extra(fp, ctx, p, v) when extra is not NULL. */
void sc_io_grid_summary_body(FILE *fp, const char *method, const sc_grid_plan *p,
                             const sc_grid_result *res, const int *view_id,
                             sc_io_summary_view_fn extra, const void *ctx);

#endif
