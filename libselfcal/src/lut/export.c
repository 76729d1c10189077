/* export.c — write a stage error map as a machine controller's compensation table and measure
 * what the controller will apply (docs/exporters.md). One back-end per file, each an
 * sc_export_backend (format, name, write) as the runtime's transports are one sc_transport per
 * file: export_beckhoff.c (and export_cross.c), export_siemens.c, export_linuxcnc.c,
 * export_kmotion.c, export_firmware.c (klipper, marlin, reprap), export_aerotech.c,
 * export_pmac.c; what they share in export_common.c. Here: the options' defaults, the table of
 * back-ends, the checks every format shares, and the atomic write. Each back-end computes its
 * table values, quantizes them to the format's unit, clips them to the limit, then evaluates the
 * controller's interpolation of exactly those values on a fine sampling of the map (nodes and
 * 4 x 4 sub-points per cell) against our bilinear map. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "export_internal.h"
#include "selfcal/atomic_file.h"
#include "selfcal/export.h"

static const sc_export_backend *const backends[] = {
    &sc_export_backend_beckhoff, &sc_export_backend_siemens,  &sc_export_backend_linuxcnc,
    &sc_export_backend_klipper,  &sc_export_backend_marlin,   &sc_export_backend_reprap,
    &sc_export_backend_kmotion,  &sc_export_backend_aerotech, &sc_export_backend_powerpmac,
};

static const sc_export_backend *backend_of(sc_export_format f)
{
    for (size_t k = 0; k < sizeof backends / sizeof backends[0]; ++k)
        if (backends[k]->format == f)
            return backends[k];
    return NULL;
}

void sc_export_options_init(sc_export_options *o, sc_export_format format)
{
    memset(o, 0, sizeof *o);
    o->format = format;
    o->axis = 0;
    o->beckhoff_x_axis_nr = 1;
    o->beckhoff_y_axis_nr = 2;
    o->siemens_x_name = "AX1";
    o->siemens_y_name = "AX2";
    o->siemens_first_table = 0;
    o->beckhoff_z_axis_nr = 3;
    o->cross_profile = -1;
}

int sc_export_format_from_name(const char *name)
{
    for (size_t k = 0; k < sizeof backends / sizeof backends[0]; ++k)
        if (!strcmp(name, backends[k]->name))
            return (int)backends[k]->format;
    return -1;
}

sc_status sc_export_write(const sc_lut *lut, const sc_export_options *o, const char *path,
                          sc_export_report *rep, sc_error *err)
{
    memset(rep, 0, sizeof *rep);
    if (lut->nx < 2 || lut->ny < 2)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the map needs at least 2 x 2 nodes");
    if (!(o->interval_mm >= 0) || !isfinite(o->interval_mm) || !(o->limit_um >= 0) ||
        !isfinite(o->limit_um))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the interval and the value limit must be finite and >= 0");
    if (o->interval_mm > 1e6)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "interval %g mm is beyond 1 km",
                            o->interval_mm);
    if (o->cross_profile >= 0 &&
        ((o->format != SC_EXPORT_BECKHOFF && o->format != SC_EXPORT_AEROTECH_A1) ||
         o->cross_profile >= lut->n_profiles))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "a profile's table needs --format beckhoff or aerotech-a1 and profile "
                            "%d of %d",
                            o->cross_profile, lut->n_profiles);
    if (!(o->profile_interval_mm >= 0) || !(o->profile_interval_mm <= 1e6) ||
        (o->profile_interval_mm > 0 && o->profile_interval_mm < 1e-4))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "profile interval %g mm: 0.1 um .. 1 km, please", o->profile_interval_mm);
    if (o->interval_mm > 0 && o->interval_mm < 1e-4)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "interval %g mm is below the 0.1 um resolution of the tables",
                            o->interval_mm);
    sc_textbuf t = {0};
    sc_status st;
    const sc_export_backend *b = backend_of(o->format);
    st = b ? b->write(lut, o, &t, rep, err)
           : sc_error_set(err, SC_E_INPUT, NULL, 0, "unknown export format %d", (int)o->format);
    if (st == SC_OK && t.failed)
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory while formatting");
    if (st == SC_OK && path)
        st = sc_write_file_atomic(path, t.s, t.len, err);
    free(t.s);
    return st;
}
