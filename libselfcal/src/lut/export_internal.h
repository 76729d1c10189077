/* export_internal.h — the exporter back-ends' interface and what they share. export.c holds the
 * table of back-ends and the dispatch; each back-end lives in its own file and defines one
 * sc_export_backend (export_beckhoff.c with export_cross.c, export_siemens.c, export_linuxcnc.c,
 * export_kmotion.c, export_firmware.c, export_aerotech.c with export_aerotech_1d.c,
 * export_pmac.c); the helpers are in
 * export_common.c, which calls no back-end. Internal: not installed. */
#ifndef SELFCAL_EXPORT_INTERNAL_H
#define SELFCAL_EXPORT_INTERNAL_H

#include <stddef.h>

#include "selfcal/export.h"

/* A growing text buffer: sc_tb_printf appends, `failed` records an allocation or format failure
 * (the text is then incomplete and must not be written). */
typedef struct sc_textbuf {
    char *s;
    size_t len, cap;
    int failed;
} sc_textbuf;

void sc_tb_printf(sc_textbuf *t, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* v_um quantized to unit_um after clipping |v_um| to limit_um (if > 0; each clip counted). */
long long sc_export_quantize(double v_um, double unit_um, double limit_um, long *clipped);

/* Component comp (0 = Gx, 1 = Gy) of lut's bilinear map at (x, y), um (clamped beyond it). */
double sc_export_map_g(const sc_lut *lut, int comp, double x, double y);

/* Position of map node column j (x) and row i (y), mm; "X" or "Y" for axis 0 or 1. */
static inline double sc_export_node_x(const sc_lut *lut, int j)
{
    return lut->x0_mm + j * lut->px_mm;
}

static inline double sc_export_node_y(const sc_lut *lut, int i)
{
    return lut->y0_mm + i * lut->py_mm;
}

static inline const char *sc_export_axis_upper(int axis)
{
    return axis == 0 ? "X" : "Y";
}

/* Mean of component comp over the other coordinate's nodes at position s along `along` (the
 * least-squares 1-D fit of the map along that axis), and over all nodes; um. */
double sc_export_mean_along(const sc_lut *lut, int comp, int along, double s);
double sc_export_grand_mean(const sc_lut *lut, int comp);

/* Points of a table from lo to at least hi at this step; saturates at INT_MAX (every caller then
 * refuses it against its controller's limit) instead of overflowing. */
int sc_export_cover_points(double lo, double hi, double step);

/* The controller's value of component comp at (x, y), um (sign included). */
typedef double (*sc_export_ctrl_fn)(const void *ctx, int comp, double x, double y);

/* Residual of the controller f against sign * map over the map's nodes and 4 x 4 sub-points per
 * cell, for components comps[0..ncomp-1]: rep's samples, rms_um, max_um, max_at_mm. */
void sc_export_residual(const sc_lut *lut, const int *comps, int ncomp, double sign,
                        sc_export_ctrl_fn f, const void *ctx, sc_export_report *rep);

/* Linear interpolation in a 1-D table (start, step, n values), clamped at the ends (SPEC §4's
 * profile rule). */
double sc_export_interp1(const double *v, int n, double start, double step, double s);

/* SC_E_INPUT naming the profile unless profile p overlaps the map along its axis (z: always). */
sc_status sc_export_profile_meets_map(const sc_lut *lut, int k, const char *fmt, sc_error *err);


/* The Beckhoff/ISG cross compensation list (kw.crosscomp.*) of lut's profile o->cross_profile
 * into t, report filled (docs/exporters.md). SC_E_INPUT for what the list cannot hold. */
sc_status sc_export_beckhoff_cross(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                   sc_export_report *rep, sc_error *err);

/* The Automation1 1-D axis calibration file of all of lut's straightness profiles (one table
 * each: reference axis = the profile's axis, output axis = its dir; export_aerotech_1d.c) into t,
 * report filled. SC_E_INPUT for what the file cannot hold. */
sc_status sc_export_aerotech_1d(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                sc_export_report *rep, sc_error *err);

/* A back-end: its format, its --format name, and the function that writes lut for it into t (the
 * caller frees t->s), filling rep; SC_E_INPUT for what the format cannot hold. */
typedef struct sc_export_backend {
    sc_export_format format;
    const char *name;
    sc_status (*write)(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                       sc_export_report *rep, sc_error *err);
} sc_export_backend;

extern const sc_export_backend sc_export_backend_beckhoff;  /* export_beckhoff.c */
extern const sc_export_backend sc_export_backend_siemens;   /* export_siemens.c */
extern const sc_export_backend sc_export_backend_linuxcnc;  /* export_linuxcnc.c */
extern const sc_export_backend sc_export_backend_kmotion;   /* export_kmotion.c */
extern const sc_export_backend sc_export_backend_klipper;   /* export_firmware.c */
extern const sc_export_backend sc_export_backend_marlin;    /* export_firmware.c */
extern const sc_export_backend sc_export_backend_reprap;    /* export_firmware.c */
extern const sc_export_backend sc_export_backend_aerotech;  /* export_aerotech.c */
extern const sc_export_backend sc_export_backend_powerpmac; /* export_pmac.c */

#endif
