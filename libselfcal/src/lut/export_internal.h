/* export_internal.h — what export.c (the table formats and the dispatch), export_firmware.c (the
 * firmware formats) and export_cross.c (ISG cross compensation of a straightness profile) share.
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

#endif
