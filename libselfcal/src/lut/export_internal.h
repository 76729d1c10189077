/* export_internal.h — what the exporter back-ends share: export_common.c (helpers), export.c (the
 * table of back-ends, the dispatch, and the Beckhoff, Siemens, LinuxCNC and KMotion tables),
 * export_firmware.c (Klipper, Marlin, RepRapFirmware), export_cross.c (ISG cross compensation of
 * a straightness profile), export_aerotech.c (Automation1) and export_pmac.c (Power PMAC).
 * Internal: not installed. */
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

/* Klipper, Marlin or RepRapFirmware text for lut's first order into buf (cap bytes, *len
 * written), report filled. SC_E_INPUT for maps beyond the firmware's limits. */
sc_status sc_export_firmware(const sc_lut *lut, const sc_export_options *o, char *buf,
                             size_t cap, size_t *len, sc_export_report *rep, sc_error *err);

/* The Beckhoff/ISG cross compensation list (kw.crosscomp.*) of lut's profile o->cross_profile
 * into t, report filled (docs/exporters.md). SC_E_INPUT for what the list cannot hold. */
sc_status sc_export_beckhoff_cross(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                                   sc_export_report *rep, sc_error *err);

/* Aerotech Automation1 2-D axis calibration file (export_aerotech.c) of lut's map into t. */
sc_status sc_export_aerotech(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                             sc_export_report *rep, sc_error *err);

/* Power PMAC CompTable[] setup and data of lut's map, two 2-D tables (export_pmac.c), into t. */
sc_status sc_export_powerpmac(const sc_lut *lut, const sc_export_options *o, sc_textbuf *t,
                              sc_export_report *rep, sc_error *err);

#endif
