/* selfcal/export.h — resample a stage error map onto the compensation table of a real machine
 * controller, write it, and report what the controller will actually apply: the residual
 * (controller's interpolation of the written, quantized table minus our bilinear map) and the
 * points clipped to a limit. Formats and their limits: docs/exporters.md.
 *
 * Signs follow each vendor's own definition of its value (docs/exporters.md cites them): LinuxCNC
 * and KMotion take what is added to the commanded position (+G, the position-mode sign of SPEC
 * §4); Beckhoff/ISG takes the measured error, actual - setpoint, and Siemens a value of which a
 * positive one moves the axis negative: both -G (a profile's tables: -e); Automation1 and Power
 * PMAC are taken as adding to the command, +G (Automation1's profile tables: +e), which their
 * pages read leave open. `negate` flips the default. The firmware formats (Klipper, Marlin, RepRapFirmware) carry only the first-order part
 * of the map, non-orthogonality O and scale R (Petro eqs. 4-5), converted to each firmware's own
 * skew parameter and transform; their residual is what remains after the firmware's transform,
 * up to the translation, rotation and magnification that a self-calibrated map does not define.
 */
#ifndef SELFCAL_EXPORT_H
#define SELFCAL_EXPORT_H

#include "selfcal/api.h"

#include "selfcal/error.h"
#include "selfcal/lut.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sc_export_format {
    SC_EXPORT_BECKHOFF = 0,    /* TwinCAT CNC / ISG plane compensation list (kw.crosscomp2.*) */
    SC_EXPORT_SIEMENS_CEC = 1, /* SINUMERIK 840D cross error compensation ($AN_CEC tables) */
    SC_EXPORT_LINUXCNC = 2,    /* LinuxCNC joint compensation file (COMP_FILE_TYPE = 1) */
    SC_EXPORT_KLIPPER = 3,     /* Klipper skew_correction: SET_SKEW XY=AC,BD,AD */
    SC_EXPORT_MARLIN = 4,      /* Marlin M852 I (XY skew factor) */
    SC_EXPORT_REPRAP = 5,      /* RepRapFirmware M556 S X (XY axis compensation) */
    SC_EXPORT_KMOTION = 6,     /* Dynomotion KMotionCNC geometric correction table (2-D) */
    SC_EXPORT_AEROTECH_A1 = 7, /* Aerotech Automation1 2-D axis calibration file (:START2D) */
    SC_EXPORT_POWERPMAC = 8    /* Power PMAC CompTable[] setup and data: two 2-D tables */
} sc_export_format;

/* Controller limits (see docs/exporters.md). */
#define SC_EXPORT_BECKHOFF_MAX_POINTS 101 /* per master axis: 101 x 101 = default max_points 10201 */
#define SC_EXPORT_BECKHOFF_CROSS_MAX_POINTS 1000 /* cross compensation: every ISG version's limit */
#define SC_EXPORT_SIEMENS_MAX_POINTS 2000 /* per table (MD18342 upper limit) */
#define SC_EXPORT_LINUXCNC_MAX_POINTS 256 /* triplets per joint */
#define SC_EXPORT_SIEMENS_828D_TABLES 8   /* SINUMERIK 828D: 8 tables ... */
#define SC_EXPORT_SIEMENS_828D_POINTS 200 /* ... of 200 points, fixed */
#define SC_EXPORT_MARLIN_MAX_SKEW 1.0     /* Marlin SKEW_FACTOR_MIN/MAX: |I| <= 1 */
#define SC_EXPORT_AEROTECH_UNIT_UM 1e-4   /* Automation1 corrections written in um, 4 decimals */
#define SC_EXPORT_AEROTECH_1D_MAX_POINTS 65536 /* selfcal's bound on a 1-D table (none documented) */

typedef struct sc_export_options {
    sc_export_format format;
    int axis;           /* compensated coordinate: 0 = x (Gx), 1 = y (Gy); -1 = both (Siemens only) */
    double interval_mm; /* table spacing; 0 = from the map's pitch (Beckhoff: the smaller one) */
    int use_line;       /* LinuxCNC: 1 = take G along the line `line_mm` of the other coordinate */
    double line_mm;     /*   (default 0: the mean over the other coordinate, the best 1-D fit) */
    double limit_um;    /* |value| above this is clipped to it and counted; 0 = the format's default */
    int negate;         /* write -G */
    /* Beckhoff: logical axis numbers of the x and y axes (masters; the slave is the compensated
     * one); Automation1: their one-based axis indices; Power PMAC: their motor numbers.
     * Siemens: machine axis names of x and y ("AX1", "AX2") and the first table index (Power
     * PMAC: the CompTable index of x's table; y's is the next). */
    int beckhoff_x_axis_nr, beckhoff_y_axis_nr;
    int beckhoff_z_axis_nr; /* z's logical axis number, for a profile with z (default 3) */
    /* Beckhoff: -1 = the plane compensation list of `axis` (the map); k >= 0 = the cross
     * compensation list of lut's straightness profile k (slave = its dir, master = its axis).
     * Automation1: -1 = the 2-D file of the map; any k >= 0 = the 1-D file of all of lut's
     * profiles (one table each: reference axis = its axis, output axis = its dir). */
    int cross_profile;
    /* Beckhoff cross compensation: the master axis' travel (mm, machine coordinates), which must
     * contain the profile; the table then gets points at the travel ends carrying the profile's
     * end values. use_travel = 0: the table spans the profile only (ISG does not document what
     * happens beyond its first and last point: the report says so). */
    int use_travel;
    double travel_mm[2];
    /* Profiles' tables (Beckhoff cross lists, Siemens and Automation1 profile tables): their
     * spacing in mm; 0 = the profile's own points (Siemens: interval_mm if that is set). */
    double profile_interval_mm;
    const char *siemens_x_name, *siemens_y_name;
    const char *siemens_z_name; /* Siemens: z's axis name, for profiles with z (NULL: "AX3") */
    int siemens_first_table;
    int siemens_828d;   /* Siemens: the 828D's fixed 8 tables x 200 points instead of 840D limits */
    /* Firmware formats: the machine's present steps/mm (Marlin, RepRapFirmware) or
     * rotation_distance (Klipper) of x and y, to write the scale-corrected values; 0 = unknown
     * (the file then gives the factors to multiply them by). Power PMAC: the motor units per mm
     * of x and y (0 = 1: motors scaled in mm). */
    double steps_per_mm[2];
    double rotation_distance_mm[2];
    /* Automation1 1-D file: 1 = write ':START OutputAxis RefAxis' instead of the default
     * ':START RefAxis OutputAxis' (the help page read gives no 1-D syntax: the open point) */
    int aerotech_1d_output_first;
} sc_export_options;

typedef struct sc_export_report {
    int tables;          /* tables written (Siemens: up to 4, plus one per profile; others 1) */
    int points[4];       /* entries per table (Beckhoff: points along x in [0], along y in [1]) */
    double interval_mm;  /* spacing used */
    double unit_um;      /* the format's value unit as written (Beckhoff 0.1 um; others 1 nm) */
    long samples;        /* map positions compared */
    double rms_um;       /* residual: controller interpolation of the written table - our map */
    double max_um;       /* largest |residual| */
    double max_at_mm[2]; /* where */
    long clipped;        /* table entries clipped to the limit */
    double limit_um;     /* the limit used */
    double profile_max_um; /* Siemens: largest |table - profile| of the profiles' tables */
    /* Beckhoff cross compensation: the table's first and last setpoint (mm) and the points added
     * at the travel ends (0..2; points[0] counts them too). rms_um, max_um and max_at_mm[0]
     * (master position) are then the table against the profile. Automation1's 1-D file: tables
     * = profiles, points[k] the entries of table k (k >= 3 summed into [3]), rms_um and max_um
     * the tables against the profiles, max_at_mm = (reference position, profile index). */
    double span_mm[2];
    int travel_points;
    /* Firmware formats: the map's first order and what was written. */
    double O, R;         /* non-orthogonality and scale of the map (dimensionless) */
    double skew;         /* the firmware's XY skew value as written (Klipper xy_factor from the
                            written lengths, Marlin I, RepRapFirmware tanXY = X/S) */
    double scale[2];     /* factors the x and y steps/mm (Klipper: rotation_distance) take */
} sc_export_report;

/* Defaults: axis x, interval from the map, no line, format limits, AX1/AX2, axis numbers 1/2/3,
 * the plane list (no cross profile), no travel. */
SC_API void sc_export_options_init(sc_export_options *o, sc_export_format format);

/* "beckhoff", "siemens-cec", "linuxcnc", "klipper", "marlin", "reprap", "kmotion",
 * "aerotech-a1", "powerpmac" -> format; -1 if unknown. */
SC_API int sc_export_format_from_name(const char *name);

/* Resample lut's grid for the controller (and, for Siemens CEC, each of lut's straightness
 * profiles as one more table AXIS -> DIR; for Beckhoff with cross_profile = k, profile k alone as
 * a cross compensation list; for Automation1 with cross_profile >= 0, every profile as a table of
 * one 1-D file; the other formats ignore profiles), write it atomically to path
 * (NULL: check and report only, nothing written), fill *rep. SC_E_INPUT for options the format
 * cannot honour (e.g. more entries than it holds), profiles that do not overlap the map, and maps
 * beyond the firmware's limits. */
SC_API sc_status sc_export_write(const sc_lut *lut, const sc_export_options *o, const char *path,
                                 sc_export_report *rep, sc_error *err);

#ifdef __cplusplus
}
#endif
#endif
