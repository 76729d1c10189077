/* export_internal.h — what export.c (the table formats and the dispatch) and export_firmware.c
 * (the firmware formats) share. Internal: not installed. */
#ifndef SELFCAL_EXPORT_INTERNAL_H
#define SELFCAL_EXPORT_INTERNAL_H

#include <stddef.h>

#include "selfcal/export.h"

/* Klipper, Marlin or RepRapFirmware text for lut's first order into buf (cap bytes, *len
 * written), report filled. SC_E_INPUT for maps beyond the firmware's limits. */
sc_status sc_export_firmware(const sc_lut *lut, const sc_export_options *o, char *buf,
                             size_t cap, size_t *len, sc_export_report *rep, sc_error *err);

#endif
