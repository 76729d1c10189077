/* selfcal/verify.h — the check of a compensated machine (`selfcal verify`, `report grid --verify`,
 * Python `selfcal.verify`) and its decision rule (SPEC §12).
 *
 * Model. After the table is loaded, the plate is measured once more (a selfcal-grid v1 file,
 * typically one view, rot 0). With the table active (position mode, or measure mode applied to the
 * readings) the machine reports p_c = p − G_table(p); the mark's deviation from its nominal stage
 * position is then
 *     dev_after = (G − G_table)(node) + Rot(A(mark)) + misalignment + noise,
 * so once the plate error A of the calibration and a fitted misalignment (tx, ty, θ per view) are
 * removed, what is left is the error the table did not compensate, plus noise. The reading the
 * machine would have given without the table, p = p_c + G_table(p) (the table in position mode
 * applied to p_c), gives the map before compensation, ≈ G. With raw the file holds uncompensated
 * readings instead: before = them, after = the table's measure-mode correction applied to them.
 * Corrections go through the same correction core as selfcald (sc_corr_apply).
 *
 * Decision rule on max |r| after compensation against the tolerance T:
 * - simple acceptance: pass if max |r| ≤ T, else fail;
 * - guarded (ISO 14253-1): pass if max |r| + U ≤ T, fail if max |r| − U > T, else inconclusive,
 *   with U the expanded uncertainty (k = 2) of a residual: U = 2·√(σ² + u_A² + u_q²), σ the
 *   re-measurement's noise (given, stated in its file, or the residuals' RMS per coordinate, an
 *   upper bound), u_A the plate error's standard uncertainty (given, else taken equal to σ) and
 *   u_q the table's quantization (uniform within ±q: q/√3); or U given outright.
 */
#ifndef SELFCAL_VERIFY_H
#define SELFCAL_VERIFY_H

#include "selfcal/api.h"
#include "selfcal/error.h"
#include "selfcal/grid.h"
#include "selfcal/grid_io.h"
#include "selfcal/stage_map.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sc_verify_rule {
    SC_VERIFY_RULE_SIMPLE = 0,  /* simple acceptance: max |r| against T */
    SC_VERIFY_RULE_GUARDED = 1  /* guarded acceptance with U (ISO 14253-1) */
} sc_verify_rule;

typedef enum sc_verify_verdict {
    SC_VERIFY_NO_VERDICT = -1,  /* no tolerance given */
    SC_VERIFY_FAIL = 0,
    SC_VERIFY_PASS = 1,
    SC_VERIFY_INCONCLUSIVE = 2  /* guarded: T lies within max |r| ± U */
} sc_verify_verdict;

/* Where σ, the re-measurement's noise in U, came from. */
typedef enum sc_verify_noise_source {
    SC_VERIFY_NOISE_GIVEN = 0,     /* sigma_r_um */
    SC_VERIFY_NOISE_STATED = 1,    /* the file's ux_um,uy_um or sigma_um= (RMS over the marks) */
    SC_VERIFY_NOISE_RESIDUALS = 2  /* RMS per coordinate of the residuals after (an upper bound) */
} sc_verify_noise_source;

typedef struct sc_verify_opts {
    const char *measurement;   /* V.csv: the re-measurement (selfcal-grid v1) */
    const char *table;         /* T.lut */
    const char *artifact;      /* A.csv (plate error), unless plate is set */
    const sc_stage_map *plate; /* the plate error already at hand (plate frame, as
                                  sc_grid_read_artifact makes it), or NULL */
    double tolerance_um;       /* T on max |r| after compensation; NaN: no verdict */
    int raw;                   /* 1: the file holds uncompensated readings */
    sc_verify_rule rule;
    double u_verify_um;        /* guarded: U (k = 2) given, µm; NaN: computed (above) */
    double sigma_r_um;         /* the re-measurement's noise σ (k = 1), µm; NaN: stated or estimated */
    double u_plate_um;         /* u(A) (k = 1), µm; NaN: taken equal to σ */
} sc_verify_opts;

typedef struct sc_verify_stats {
    long count;
    double rms_x, rms_y, rms, max; /* µm */
    double max_x_mm, max_y_mm;     /* stage position of the largest */
} sc_verify_stats;

/* The uncertainty of a residual, as the decision rule used it (µm; NaN where not computed). */
typedef struct sc_verify_u {
    int given;                     /* 1: U given (u_verify_um); the parts below are NaN */
    double sigma_um;               /* σ, re-measurement noise (k = 1) */
    sc_verify_noise_source sigma_source;
    double u_plate_um;             /* u(A) (k = 1) */
    int u_plate_given;             /* 0: taken equal to σ */
    double quant_um;               /* the table's quantization bound q (±q) */
    double u_quant_um;             /* q/√3 */
    double u_um;                   /* combined standard uncertainty (k = 1) */
    double k;                      /* coverage factor (2) */
    double U_um;                   /* expanded uncertainty k·u, or as given */
} sc_verify_u;

typedef struct sc_verify_result {
    sc_grid_data d;             /* the re-measurement as read */
    sc_grid_file_info info;
    sc_stage_map before, after; /* per stage node, mean over the views that measure it (NaN:
                                   none); arrays in buf */
    double *buf;
    double *bx, *by, *ax, *ay;  /* per view and mark (n_views·N·N), NaN where not used (µm) */
    double *tx_after_um, *ty_after_um; /* fitted misalignment per view (n_views each, in buf) */
    double *th_after_urad;
    sc_verify_stats st_before, st_after;
    long n_unmeasured;          /* marks a view places on the stage without a point in the file */
    long n_unseen;              /* measured marks the calibration saw no error for (plate NaN) */
    sc_verify_rule rule;
    sc_verify_u u;              /* the uncertainty of a residual (both rules: reported) */
    sc_verify_verdict verdict;
} sc_verify_result;

/* Defaults: no files, no tolerance, compensated readings, simple rule, U, σ and u(A) not given. */
SC_API void sc_verify_opts_init(sc_verify_opts *o);

/* Read the re-measurement, the table and the plate error, compute before/after, U and the
 * verdict. Bad input: SC_E_INPUT naming the file and line. r must be freed (sc_verify_result_free)
 * whatever the return. */
SC_API sc_status sc_verify_run(const sc_verify_opts *o, sc_verify_result *r, sc_error *err);

/* Free r (safe on a zeroed r). */
SC_API void sc_verify_result_free(sc_verify_result *r);

/* The decision on max_um (max |r| after, µm) against tol_um with expanded uncertainty U_um
 * (guarded only; simple ignores it). tol_um NaN: SC_VERIFY_NO_VERDICT. */
SC_API sc_verify_verdict sc_verify_decide(sc_verify_rule rule, double max_um, double tol_um,
                                          double U_um);

/* "pass", "fail", "inconclusive" or "none"; "simple" or "guarded". */
SC_API const char *sc_verify_verdict_name(sc_verify_verdict v);
SC_API const char *sc_verify_rule_name(sc_verify_rule rule);

/* The rule of a name ("simple", "guarded"), or -1. */
SC_API int sc_verify_rule_from_name(const char *name);

#ifdef __cplusplus
}
#endif
#endif
