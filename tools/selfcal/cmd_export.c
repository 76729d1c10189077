/* cmd_export.c — `selfcal export --format FORMAT --map G.csv -o OUT`: the stage error map
 * resampled onto a machine controller's compensation table (beckhoff, siemens-cec, linuxcnc,
 * kmotion), or its first order as firmware skew/scale settings (klipper, marlin, reprap), with
 * the residual (what the controller applies minus our bilinear map) and clipped points;
 * straightness profiles as Siemens CEC tables or Beckhoff/ISG cross compensation lists. Every
 * file is computed (and checked) before the first is written: all files or none. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/csv.h"
#include "selfcal/export.h"
#include "selfcal/lut.h"

static const char USAGE[] =
            "usage: selfcal export --format FORMAT --map G.csv -o OUT\n"
            "                      [--axis x|y|both] [--interval MM] [--at MM] [--limit-um UM]\n"
            "                      [--negate] [--offset DX,DY] [--axis-numbers NX,NY[,NZ]]\n"
            "                      [--axis-names NAMEX,NAMEY] [--first-table T] [--target 840d|828d]\n"
            "                      [--steps-per-mm SX,SY] [--rotation-distance RX,RY]\n"
            "                      [--profile AXIS:DIR:P.csv[@OFFSET_MM] ...] [--travel [AXIS:]MIN,MAX]\n"
            "                      [--profile-interval MM] [--max-nodes N]\n"
            "                      [--a1-1d-order ref,out|out,ref]\n"
            "\n"
            "The formats (--format):\n"
            "  beckhoff     TwinCAT CNC / ISG plane compensation list of one slave axis (--axis x|y,\n"
            "               default x; both: OUT-x and OUT-y), 0.1 um units, ISG's sign actual -\n"
            "               setpoint (-G)\n"
            "  siemens-cec  SINUMERIK $AN_CEC part program: tables X->X, Y->X (Gx) and X->Y, Y->Y (Gy)\n"
            "               (--axis both, the default here), values in mm, <= 2000 points (828D: 200)\n"
            "  linuxcnc     joint compensation file of one axis (--axis x|y, default x; both: OUT-x\n"
            "               and OUT-y):\n"
            "               'nominal trim trim' in mm, <= 256 entries; needs COMP_FILE_TYPE = 1\n"
            "  klipper      SET_SKEW XY=AC,BD,AD (skew_correction) from the map's O and R\n"
            "  marlin       M852 I (skew factor) and M92 scale from the map's O and R\n"
            "  reprap       RepRapFirmware M556 S X and M92 scale from the map's O and R\n"
            "  kmotion      Dynomotion KMotionCNC geometric correction table: the whole 2-D map\n"
            "               (X and Y at once, inches, ideal + G)\n"
            "  aerotech-a1  Aerotech Automation1 2-D axis calibration file (:START2D): X and Y\n"
            "               corrections from the X and Y positions, um, +G (assumed; --negate)\n"
            "  powerpmac    Power PMAC CompTable[] setup and data: two 2-D tables (x and y\n"
            "               motors' CompPos), motor units, +G (assumed; --negate)\n"
            "\n"
            "What the option list does not say:\n"
            "  --max-nodes N: the fit is lut build's, and its error is printed.\n"
            "  --at MM (linuxcnc): G along the line y = MM (x axis) or x = MM (y axis) instead of\n"
            "               the mean over that coordinate.\n"
            "  --limit-um: the values clipped are counted; siemens-cec: also the most an axis's\n"
            "               tables may add up to (MD32720, default 1000).\n"
            "  --offset DX,DY: the machine (homed) coordinates of the map's x = 0, y = 0, added to\n"
            "               every table position.\n"
            "  --axis-numbers: beckhoff logical axis numbers of x, y (and z) (default 1,2,3);\n"
            "               aerotech-a1: one-based axis indices of x, y; powerpmac: motor numbers.\n"
            "  --target 828d: siemens: the 828D's fixed 8 tables x 200 points.\n"
            "  --first-table T: powerpmac: x's CompTable index (y's is T + 1).\n"
            "  --profile: the ey_um column of a profile output: the error of DIR along AXIS, placed as\n"
            "               in lut build. siemens: one more table, input AXIS, output DIR (z: AX3);\n"
            "               beckhoff: a cross compensation list OUT-cross-DIR, slave DIR, master\n"
            "               AXIS, ISG's sign (-e); aerotech-a1: one table each in the 1-D file\n"
            "               OUT-1d, reference axis AXIS, output axis DIR, +e (assumed; --negate).\n"
            "  --a1-1d-order: ref,out: the reference axis, then the output axis (the help page read\n"
            "               gives no 1-D syntax).\n"
            "  --profile-interval: siemens: --interval if given.\n"
            "  --travel [AXIS:]MIN,MAX (beckhoff profiles, machine coordinates): the list gets its end\n"
            "               values at MIN and MAX (without it the list spans the profile and ISG's\n"
            "               behaviour beyond is unknown); AXIS: for the profiles with that master\n"
            "               axis (repeatable), else all.\n"
            "  --steps-per-mm: marlin, reprap: to write M92 with the scale; powerpmac: X,Y motor units\n"
            "               per mm (default 1: motors scaled in mm).\n"
            "  --rotation-distance: klipper: to write the new ones.\n";

/* OUT with "-" and tag before its extension: "x", "y" (--axis both for one-axis formats),
 * "cross-y" (a Beckhoff cross compensation list of slave y). */
static void tagged_path(const char *out, const char *tag, char *buf, size_t cap)
{
    const char *slash = strrchr(out, '/'), *dot = strrchr(out, '.');
    if (!dot || (slash && dot < slash) || dot == out || (slash && dot == slash + 1))
        snprintf(buf, cap, "%s-%s", out, tag);
    else
        snprintf(buf, cap, "%.*s-%s%s", (int)(dot - out), out, tag, dot);
}

static int two_doubles(const char *v, double d[2])
{
    char a[64], b[64];
    const char *comma = strchr(v, ',');
    if (!comma || (size_t)(comma - v) >= sizeof a || strlen(comma + 1) >= sizeof b)
        return -1;
    memcpy(a, v, (size_t)(comma - v));
    a[comma - v] = '\0';
    snprintf(b, sizeof b, "%s", comma + 1);
    return sc_parse_double(a, &d[0]) == 0 && sc_parse_double(b, &d[1]) == 0 ? 0 : -1;
}

/* Klipper, Marlin, RepRapFirmware: the map's first order only. */
static int is_firmware(int f)
{
    return f == SC_EXPORT_KLIPPER || f == SC_EXPORT_MARLIN || f == SC_EXPORT_REPRAP;
}

/* A Beckhoff cross compensation list: the list, its residual against the profile, and a warning
 * (stderr) when no travel says what happens beyond the table. */
static void print_cross_report(const sc_lut *lut, const char *out, const sc_export_options *o,
                               const sc_export_report *rep)
{
    const sc_lut_profile *p = &lut->profile[o->cross_profile];
    const int nr[3] = {o->beckhoff_x_axis_nr, o->beckhoff_y_axis_nr, o->beckhoff_z_axis_nr};
    const char *an = sc_lut_axis_name(p->axis), *dn = sc_lut_axis_name(p->dir);
    printf(", cross compensation of slave %s (axis %d) by master %s (axis %d), %d points, %s = "
           "%.4f..%.4f mm",
           dn, nr[p->dir], an, nr[p->axis], rep->points[0], an, rep->span_mm[0], rep->span_mm[1]);
    if (o->use_travel)
        printf(" (%d added at the travel ends)", rep->travel_points);
    printf(", unit 0.1 um, %s\n", o->negate ? "+e (negated)" : "-e (ISG: actual - setpoint)");
    printf("residual (controller table - profile) over %ld samples: rms %.4f um, max %.4f um at "
           "%s = %.3f mm\n",
           rep->samples, rep->rms_um, rep->max_um, an, rep->max_at_mm[0]);
    if (rep->limit_um > 0)
        printf("clipped points: %ld (limit %.4g um)\n", rep->clipped, rep->limit_um);
    if (!o->use_travel)
        fprintf(stderr,
                "selfcal export: warning: %s: ISG does not document what cross compensation "
                "applies beyond the table's first and last point (%s = %.4f..%.4f mm); give the "
                "master axis' travel with --travel %s:MIN,MAX to hold the end values up to it\n",
                out, an, rep->span_mm[0], rep->span_mm[1], an);
}

/* Automation1's 1-D file: its tables, and their residual against the profiles. */
static void print_a1_1d_report(const sc_lut *lut, const sc_export_options *o,
                               const sc_export_report *rep)
{
    const int nr[3] = {o->beckhoff_x_axis_nr, o->beckhoff_y_axis_nr, o->beckhoff_z_axis_nr};
    printf(", 1-D table(s):");
    for (int k = 0; k < lut->n_profiles; ++k)
        printf("%s %s from %s (axis %d from axis %d)", k ? "," : "",
               sc_lut_axis_name(lut->profile[k].dir), sc_lut_axis_name(lut->profile[k].axis),
               nr[lut->profile[k].dir], nr[lut->profile[k].axis]);
    printf("; %d points in all (at most %d a table: selfcal's bound, none in the pages read), "
           "corrections in um (unit %.4g um), %s, nearest end point beyond\n",
           rep->points[0] + rep->points[1] + rep->points[2] + rep->points[3],
           SC_EXPORT_AEROTECH_1D_MAX_POINTS, rep->unit_um,
           o->negate ? "-e (negated)" : "+e (assumed: added to the command)");
    const int k = (int)rep->max_at_mm[1];
    printf("residual (controller table - profile) over %ld samples: rms %.4f um, max %.4f um at "
           "%s = %.3f mm (profile %d)\n",
           rep->samples, rep->rms_um, rep->max_um, sc_lut_axis_name(lut->profile[k].axis),
           rep->max_at_mm[0], k);
    if (rep->limit_um > 0)
        printf("clipped points: %ld (limit %.4g um)\n", rep->clipped, rep->limit_um);
    else
        printf("clipped points: 0 (no limit)\n");
}

/* The rest of the report's first line: what the file of format f holds. */
static void print_contents(int f, const sc_export_options *o, const sc_export_report *rep)
{
    if (f == SC_EXPORT_BECKHOFF)
        printf(", slave axis %s, %d x %d points, interval %.4f mm, unit 0.1 um, %s\n",
               o->axis == 0 ? "x" : "y", rep->points[0], rep->points[1], rep->interval_mm,
               o->negate ? "+G (negated)" : "-G (ISG: actual - setpoint)");
    else if (f == SC_EXPORT_SIEMENS_CEC)
        printf(", %d table(s) of %d/%d points, values in mm (1 nm), %s\n", rep->tables,
               rep->points[0], rep->points[1],
               o->negate ? "+G (negated)" : "-G (Siemens: a positive value moves the axis negative)");
    else if (f == SC_EXPORT_LINUXCNC)
        printf(", axis %s, %d entries (step %.6f mm; LinuxCNC holds the end trims beyond them), "
               "trims in mm (1 nm)\n",
               o->axis == 0 ? "x" : "y", rep->points[0], rep->interval_mm);
    else if (f == SC_EXPORT_KMOTION)
        printf(", %d x %d points (the map plus a ring of edge values), inches, %s\n",
               rep->points[0], rep->points[1], o->negate ? "ideal - G (negated)" : "ideal + G");
    else if (f == SC_EXPORT_AEROTECH_A1)
        printf(", 2-D table of %d x %d points (rows y = axis %d, columns x = axis %d; no size "
               "limit in the pages read), corrections in um (unit %.4g um), %s, nearest end "
               "point beyond it\n",
               rep->points[0], rep->points[1], o->beckhoff_y_axis_nr, o->beckhoff_x_axis_nr,
               rep->unit_um, o->negate ? "-G (negated)" : "+G (assumed: added to the command)");
    else if (f == SC_EXPORT_POWERPMAC)
        printf(", CompTable[%d] (x) and [%d] (y), %d x %d entries each over motors %d and %d (no "
               "size limit in the pages read), motor units (unit %.3g um), %s, end entries held "
               "beyond (Ctrl=3, assumed)\n",
               o->siemens_first_table, o->siemens_first_table + 1, rep->points[0], rep->points[1],
               o->beckhoff_x_axis_nr, o->beckhoff_y_axis_nr, rep->unit_um,
               o->negate ? "-G (negated)" : "+G (assumed: CompPos adds to the command)");
    else
        printf(", O = %.6g, R = %.6g, XY skew %.9g, scale x %.9f y %.9f\n", rep->O, rep->R,
               rep->skew, rep->scale[0], rep->scale[1]);
}

/* A table format's notes after the residual: the 828D's size, the profile tables, the clipping,
 * LinuxCNC's file type. */
static void print_table_notes(int f, const sc_export_options *o, const sc_export_report *rep)
{
    if (f == SC_EXPORT_SIEMENS_CEC && !o->siemens_828d) {
        int most = 0;
        for (int k = 0; k < rep->tables && k < 4; ++k)
            most = rep->points[k] > most ? rep->points[k] : most;
        if (most > SC_EXPORT_SIEMENS_828D_POINTS)
            printf("note: %d points per table; a SINUMERIK 828D holds %d (use --target 828d and a "
                   "larger --interval for one)\n",
                   most, SC_EXPORT_SIEMENS_828D_POINTS);
    }
    if (f == SC_EXPORT_SIEMENS_CEC && rep->tables > (o->axis < 0 ? 4 : 2))
        printf("profile tables: max |table - profile| %.4f um\n", rep->profile_max_um);
    if (rep->limit_um > 0)
        printf("clipped points: %ld (limit %.4g um)\n", rep->clipped, rep->limit_um);
    else
        printf("clipped points: 0 (no limit)\n");
    if (f == SC_EXPORT_LINUXCNC)
        printf("IMPORTANT: set COMP_FILE_TYPE = 1 in [JOINT_%d] of the .ini: LinuxCNC's default 0 "
               "reads these trims as positions (errors as large as the positions)\n",
               o->axis);
}

static void print_report(const sc_lut *lut, const char *fmt, int f, const char *out,
                         const sc_export_options *o, const sc_export_report *rep)
{
    printf("export %s: %s", fmt, out);
    if (f == SC_EXPORT_BECKHOFF && o->cross_profile >= 0) {
        print_cross_report(lut, out, o, rep);
        return;
    }
    if (f == SC_EXPORT_AEROTECH_A1 && o->cross_profile >= 0) {
        print_a1_1d_report(lut, o, rep);
        return;
    }
    print_contents(f, o, rep);
    printf("residual (controller %s - map) over %ld samples: rms %.4f um, max %.4f um at "
           "(%.3f, %.3f) mm\n",
           is_firmware(f) ? "correction, up to translation/rotation/magnification"
                                  : "table",
           rep->samples, rep->rms_um, rep->max_um, rep->max_at_mm[0], rep->max_at_mm[1]);
    if (!is_firmware(f))
        print_table_notes(f, o, rep);
}

/* The command line, as given. */
typedef struct {
    const char *map, *out, *fmt, *axis;
    double interval, limit, at, pinterval;
    int use_at, negate, ax_nr[3], first_table, target_828d, max_nodes, a1_order;
    char names[2][32];
    double offset[2], steps[2], rdist[2];
    int np, prof_axis[SC_LUT_MAX_PROFILES], prof_dir[SC_LUT_MAX_PROFILES];
    char prof_path[SC_LUT_MAX_PROFILES][4096];
    double prof_offset[SC_LUT_MAX_PROFILES];
    /* --travel: [3] for every master axis, [0..2] for master x, y, z ("x:MIN,MAX"). */
    double travel[4][2];
    int use_travel[4];
} export_args;

static int parse_axis_numbers(const char *cmd, const char *opt, const char *v, void *field)
{
    export_args *a = field;
    (void)cmd, (void)opt;
    char tail;
    const int got = sscanf(v, "%d,%d,%d%c", &a->ax_nr[0], &a->ax_nr[1], &a->ax_nr[2], &tail);
    if ((got != 2 && got != 3) || a->ax_nr[0] < 1 || a->ax_nr[1] < 1 || a->ax_nr[2] < 1 ||
        a->ax_nr[0] > 65535 || a->ax_nr[1] > 65535 || a->ax_nr[2] > 65535)
        return cli_usage_error("export", "--axis-numbers: NX,NY[,NZ] (1..65535), not '%s'", v);
    return CLI_OK;
}

static int parse_axis_names(const char *cmd, const char *opt, const char *v, void *field)
{
    export_args *a = field;
    (void)cmd, (void)opt;
    const char *comma = strchr(v, ',');
    size_t l0 = comma ? (size_t)(comma - v) : 0, l1 = comma ? strlen(comma + 1) : 0;
    if (!comma || l0 == 0 || l1 == 0 || l0 >= sizeof a->names[0] || l1 >= sizeof a->names[1] ||
        strpbrk(v, " ()\t;") != NULL)
        return cli_usage_error("export", "--axis-names: NAMEX,NAMEY, not '%s'", v);
    memcpy(a->names[0], v, l0);
    a->names[0][l0] = '\0';
    snprintf(a->names[1], sizeof a->names[1], "%s", comma + 1);
    return CLI_OK;
}

static int parse_profile(const char *cmd, const char *opt, const char *v, void *field)
{
    export_args *a = field;
    (void)cmd, (void)opt;
    const int np = a->np;
    if (np == SC_LUT_MAX_PROFILES)
        return cli_usage_error("export", "at most %d profiles", SC_LUT_MAX_PROFILES);
    if (cli_parse_profile_placed(v, &a->prof_axis[np], &a->prof_dir[np], a->prof_path[np],
                                 sizeof a->prof_path[np], &a->prof_offset[np]) != 0)
        return cli_usage_error("export",
                               "--profile: AXIS:DIR:FILE[@OFFSET_MM] with AXIS, DIR in x, y, z "
                               "and |OFFSET_MM| <= 1e6; not '%s'",
                               v);
    if (a->prof_axis[np] == a->prof_dir[np])
        return cli_usage_error(
            "export", "--profile: a straightness profile has DIR != AXIS, not '%s'", v);
    a->np++;
    return CLI_OK;
}

static int parse_travel(const char *cmd, const char *opt, const char *v, void *field)
{
    export_args *a = field;
    (void)cmd, (void)opt;
    int t = 3;
    const char *mm = v;
    if (v[0] && v[1] == ':') {
        const char ax[2] = {v[0], '\0'};
        t = sc_lut_axis_from_name(ax);
        mm = v + 2;
    }
    double *tr = t >= 0 ? a->travel[t] : a->travel[3];
    if (t < 0 || two_doubles(mm, tr) != 0 || !(tr[0] < tr[1]) || fabs(tr[0]) > 1e6 ||
        fabs(tr[1]) > 1e6)
        return cli_usage_error("export",
                               "--travel: [AXIS:]MIN,MAX in mm with MIN < MAX (within 1 km), not "
                               "'%s'",
                               v);
    a->use_travel[t] = 1;
    return CLI_OK;
}

/* --at MM: the line (linuxcnc) */
static int parse_at(const char *cmd, const char *opt, const char *v, void *field)
{
    export_args *a = field;
    (void)opt;
    if (sc_parse_double(v, &a->at) != 0)
        return cli_usage_error(cmd, "--at: a position in mm, not '%s'", v);
    a->use_at = 1;
    return CLI_OK;
}

/* --offset DX,DY (mm, within 1 km) into the double[2] */
static int parse_offset(const char *cmd, const char *opt, const char *v, void *field)
{
    double *d = field;
    (void)opt;
    if (two_doubles(v, d) != 0 || fabs(d[0]) > 1e6 || fabs(d[1]) > 1e6)
        return cli_usage_error(cmd, "--offset: DX,DY in mm (within 1 km), not '%s'", v);
    return CLI_OK;
}

/* --steps-per-mm, --rotation-distance X,Y (positive, at most 1e9) into the double[2] */
static int parse_scales(const char *cmd, const char *opt, const char *v, void *field)
{
    double *d = field;
    if (two_doubles(v, d) != 0 || !(d[0] > 0) || !(d[1] > 0) || d[0] > 1e9 || d[1] > 1e9)
        return cli_usage_error(cmd, "%s: X,Y (positive), not '%s'", opt, v);
    return CLI_OK;
}

/* Siemens' --target 840d|828d into the int target_828d */
static int parse_target(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    if (!strcmp(v, "828d") || !strcmp(v, "828D"))
        *(int *)field = 1;
    else if (strcmp(v, "840d") != 0 && strcmp(v, "840D") != 0)
        return cli_usage_error(cmd, "--target: 840d or 828d, not '%s'", v);
    return CLI_OK;
}

#define F(field) offsetof(export_args, field)
#define POSITIVE(name, f, v, bad_, dflt, text)                                                     \
    {name, CLI_DOUBLE, F(f), v, 0, HUGE_VAL, CLI_MIN_OPEN, .bad = bad_, .def = dflt, .help = text}
/* export's options (cli_opts.h), in the order of its --help */
static const cli_opt EXPORT_OPTS[] = {
    {"--format", CLI_STRING, F(fmt), "FORMAT", .help = "the controller's format (required)"},
    {"--map", CLI_STRING, F(map), "G.csv", .help = "the stage error map (required)"},
    {"-o|--out", CLI_STRING, F(out), "OUT", .help = "the file (required)"},
    {"--axis", CLI_STRING, F(axis), "x|y|both", .help = "the axis of a one-axis format"},
    POSITIVE("--interval", interval, "MM", "--interval: a positive number of mm, not '%s'",
             "the map's pitch", "the table's spacing (mm)"),
    {"--at", CLI_CUSTOM, 0, "MM", .parse = parse_at, .def = "the mean",
     .help = "linuxcnc: G along the line at MM"},
    POSITIVE("--limit-um", limit, "UM", "--limit-um: a positive number, not '%s'", NULL,
             "clip values above this magnitude"),
    {"--negate", CLI_FLAG, F(negate), .help = "the opposite of the format's default sign"},
    {"--offset", CLI_CUSTOM, F(offset), "DX,DY", .parse = parse_offset, .def = "0,0",
     .help = "the machine coordinates of the map's origin (mm)"},
    {"--axis-numbers", CLI_CUSTOM, 0, "NX,NY[,NZ]", .parse = parse_axis_numbers, .def = "1,2,3",
     .help = "the controller's axis numbers"},
    {"--axis-names", CLI_CUSTOM, 0, "NAMEX,NAMEY", .parse = parse_axis_names, .def = "AX1,AX2",
     .help = "siemens: the axis names"},
    {"--first-table", CLI_INT, F(first_table), "T", 0, 1000,
     .bad = "--first-table: a table index >= 0, not '%s'", .def = "0",
     .help = "siemens, powerpmac: the first table's index"},
    {"--target", CLI_CUSTOM, F(target_828d), "840d|828d", .choices = "840d|828d",
     .parse = parse_target, .def = "840d", .help = "siemens: the control"},
    {"--steps-per-mm", CLI_CUSTOM, F(steps), "SX,SY", .parse = parse_scales,
     .help = "marlin, reprap, powerpmac: the present steps (units) per mm"},
    {"--rotation-distance", CLI_CUSTOM, F(rdist), "RX,RY", .parse = parse_scales,
     .help = "klipper: the present rotation_distance"},
    {"--profile", CLI_CUSTOM, 0, "AXIS:DIR:P.csv[@OFFSET_MM]", .parse = parse_profile,
     .help = "a straightness profile (repeatable; siemens-cec, beckhoff, aerotech-a1)"},
    {"--travel", CLI_CUSTOM, 0, "[AXIS:]MIN,MAX", .parse = parse_travel,
     .help = "beckhoff: the master axis' travel (mm)"},
    POSITIVE("--profile-interval", pinterval, "MM",
             "--profile-interval: a positive number of mm, not '%s'", "the profile's points",
             "the profiles' table spacing (mm)"),
    {"--max-nodes", CLI_CUSTOM, F(max_nodes), "N", 2, SC_LUT_MAX_NX, .parse = cli_opt_max_nodes,
     .def = "the map as it is", .help = "a larger map fitted by N nodes per axis first"},
    {"--a1-1d-order", CLI_CHOICE, F(a1_order), "ref,out|out,ref", .choices = "ref,out|out,ref",
     .def = "ref,out", .help = "aerotech-a1 1-D file: the axis order of its :START line"},
};
#undef POSITIVE
#undef F

const cli_cmd_opts cli_export_opts = {
    "export", USAGE, EXPORT_OPTS, (int)(sizeof EXPORT_OPTS / sizeof EXPORT_OPTS[0]), 0, NULL,
    NULL, NULL, NULL, CLI_NO_OPERAND, NULL, NULL,
};

/* argv into a: -1 to go on, else the exit code (--help, a usage error). */
static int parse_args(int argc, char **argv, export_args *a)
{
    memset(a, 0, sizeof *a);
    a->ax_nr[0] = 1;
    a->ax_nr[1] = 2;
    a->ax_nr[2] = 3;
    snprintf(a->names[0], sizeof a->names[0], "AX1");
    snprintf(a->names[1], sizeof a->names[1], "AX2");
    return cli_opts_parse(&cli_export_opts, argc, argv, a);
}

/* --axis for format f: o->axis, or *both_files for one file per axis (OUT-x, OUT-y). */
static int resolve_axis(const export_args *a, int f, sc_export_options *o, int *both_files)
{
    o->axis = f == SC_EXPORT_SIEMENS_CEC ? -1 : 0;
    *both_files = 0;
    const char *axis = a->axis;
    if (!axis)
        return CLI_OK;
    if (is_firmware(f) || f == SC_EXPORT_KMOTION || f == SC_EXPORT_AEROTECH_A1 ||
        f == SC_EXPORT_POWERPMAC)
        return cli_usage_error("export", "--axis does not apply to --format %s (X and Y at once)",
                               a->fmt);
    if (!strcmp(axis, "x") || !strcmp(axis, "X"))
        o->axis = 0;
    else if (!strcmp(axis, "y") || !strcmp(axis, "Y"))
        o->axis = 1;
    else if (!strcmp(axis, "both") && f == SC_EXPORT_SIEMENS_CEC)
        o->axis = -1;
    else if (!strcmp(axis, "both"))
        *both_files = 1;
    else
        return cli_usage_error("export", "--axis: x, y or both, not '%s'", axis);
    return CLI_OK;
}

/* The profile options: --profile, --profile-interval and --travel where they apply. */
static int check_profile_options(const export_args *a, int f)
{
    if (a->np > 0 && f != SC_EXPORT_SIEMENS_CEC && f != SC_EXPORT_BECKHOFF &&
        f != SC_EXPORT_AEROTECH_A1)
        return cli_usage_error("export", "--profile applies to --format siemens-cec, beckhoff and "
                                         "aerotech-a1 only (LinuxCNC: the HAL component applies "
                                         "profiles)");
    if (a->pinterval > 0 && a->np == 0)
        return cli_usage_error("export", "--profile-interval applies to --profile tables only");
    for (int t = 0; t < 4; ++t) {
        if (a->use_travel[t] && (f != SC_EXPORT_BECKHOFF || a->np == 0))
            return cli_usage_error("export", "--travel applies to --format beckhoff with --profile only");
        int used = t == 3;
        for (int k = 0; k < a->np; ++k)
            used |= a->prof_axis[k] == t;
        if (a->use_travel[t] && !used)
            return cli_usage_error("export", "--travel %s: no profile has master axis %s",
                                   sc_lut_axis_name(t), sc_lut_axis_name(t));
    }
    for (int i = 0; i < a->np && f == SC_EXPORT_BECKHOFF; ++i)
        for (int j = 0; j < i; ++j)
            if (a->prof_dir[i] == a->prof_dir[j])
                return cli_usage_error("export", "beckhoff: two profiles correct %s; ISG corrects a "
                                                 "slave axis by one master axis (one cross "
                                                 "compensation list per slave)",
                                       sc_lut_axis_name(a->prof_dir[i]));
    return CLI_OK;
}

/* Every option applies to format f. */
static int check_applicability(const export_args *a, int f)
{
    if (a->use_at && f != SC_EXPORT_LINUXCNC)
        return cli_usage_error("export", "--at applies to --format linuxcnc only");
    int rc = check_profile_options(a, f);
    if (rc != CLI_OK)
        return rc;
    if (a->target_828d && f != SC_EXPORT_SIEMENS_CEC)
        return cli_usage_error("export", "--target applies to --format siemens-cec only");
    if (a->a1_order && (f != SC_EXPORT_AEROTECH_A1 || a->np == 0))
        return cli_usage_error("export", "--a1-1d-order applies to --format aerotech-a1 with "
                                         "--profile only");
    if (a->steps[0] > 0 && f != SC_EXPORT_MARLIN && f != SC_EXPORT_REPRAP && f != SC_EXPORT_POWERPMAC)
        return cli_usage_error("export",
                               "--steps-per-mm applies to --format marlin, reprap or powerpmac only");
    if (a->rdist[0] > 0 && f != SC_EXPORT_KLIPPER)
        return cli_usage_error("export", "--rotation-distance applies to --format klipper only");
    if (is_firmware(f) && (a->negate || a->interval > 0 || a->limit > 0))
        return cli_usage_error("export", "--negate, --interval and --limit-um do not apply to "
                                         "--format %s (the firmware's own skew and sign)",
                               a->fmt);
    return CLI_OK;
}

static void options_from_args(const export_args *a, sc_export_options *o)
{
    o->interval_mm = a->interval;
    o->profile_interval_mm = a->pinterval;
    o->limit_um = a->limit;
    o->use_line = a->use_at;
    o->line_mm = a->at;
    o->negate = a->negate;
    o->aerotech_1d_output_first = a->a1_order;
    o->beckhoff_x_axis_nr = a->ax_nr[0];
    o->beckhoff_y_axis_nr = a->ax_nr[1];
    o->beckhoff_z_axis_nr = a->ax_nr[2];
    o->siemens_x_name = a->names[0];
    o->siemens_y_name = a->names[1];
    o->siemens_first_table = a->first_table;
    o->siemens_828d = a->target_828d;
    for (int k = 0; k < 2; ++k) {
        o->steps_per_mm[k] = a->steps[k];
        o->rotation_distance_mm[k] = a->rdist[k];
    }
}

/* The map and the profiles, placed in the machine's homed coordinates (--offset). */
static sc_status load_table(const export_args *a, sc_lut *lut, sc_lut_fit_report *fit,
                            sc_error *err)
{
    sc_lut_init(lut);
    sc_status st = cli_read_map(a->map, a->max_nodes, lut, fit, err);
    for (int k = 0; k < a->np && st == SC_OK; ++k) {
        st = sc_lut_read_profile(a->prof_path[k], a->prof_axis[k], a->prof_dir[k],
                                 &lut->profile[k], err);
        lut->profile[k].start_mm += a->prof_offset[k];
        lut->n_profiles = k + 1;
    }
    lut->x0_mm += a->offset[0];
    lut->y0_mm += a->offset[1];
    for (int k = 0; k < lut->n_profiles; ++k)
        lut->profile[k].start_mm += lut->profile[k].axis < 2 ? a->offset[lut->profile[k].axis] : 0.0;
    return st;
}

/* The files: the map's (one, or OUT-x and OUT-y), then a Beckhoff list per profile, or
 * Automation1's 1-D file of all profiles (a calibration file holds tables of one kind). */
enum { MAX_FILES = 2 + SC_LUT_MAX_PROFILES };

static int plan_files(const export_args *a, int f, const sc_export_options *o, int both_files,
                      char paths[][4096], sc_export_options *opts)
{
    int nfiles = 0;
    for (int k = 0; k < (both_files ? 2 : 1); ++k, ++nfiles) {
        opts[nfiles] = *o;
        if (both_files) {
            opts[nfiles].axis = k;
            tagged_path(a->out, k == 0 ? "x" : "y", paths[nfiles], 4096);
        } else {
            snprintf(paths[nfiles], 4096, "%s", a->out);
        }
    }
    for (int k = 0; k < a->np && f == SC_EXPORT_BECKHOFF; ++k, ++nfiles) {
        char tag[16];
        snprintf(tag, sizeof tag, "cross-%s", sc_lut_axis_name(a->prof_dir[k]));
        opts[nfiles] = *o;
        opts[nfiles].cross_profile = k;
        const int t = a->use_travel[a->prof_axis[k]] ? a->prof_axis[k] : 3; /* its own, else all */
        opts[nfiles].use_travel = a->use_travel[t];
        opts[nfiles].travel_mm[0] = a->travel[t][0];
        opts[nfiles].travel_mm[1] = a->travel[t][1];
        tagged_path(a->out, tag, paths[nfiles], 4096);
    }
    if (a->np > 0 && f == SC_EXPORT_AEROTECH_A1) {
        opts[nfiles] = *o;
        opts[nfiles].cross_profile = 0; /* every profile, one table each */
        tagged_path(a->out, "1d", paths[nfiles++], 4096);
    }
    return nfiles;
}

/* Every file computed and checked first (nothing written), then written: all or none. */
static sc_status write_files(const sc_lut *lut, int nfiles, char paths[][4096],
                             const sc_export_options *opts, sc_export_report *reps, sc_error *err)
{
    sc_status st = SC_OK;
    for (int k = 0; k < nfiles && st == SC_OK; ++k)
        st = sc_export_write(lut, &opts[k], NULL, &reps[k], err);
    int written = 0;
    for (; written < nfiles && st == SC_OK; ++written)
        st = sc_export_write(lut, &opts[written], paths[written], &reps[written], err);
    if (st != SC_OK)
        for (int k = 0; k + 1 < written; ++k)
            remove(paths[k]); /* all files or none */
    return st;
}

int cmd_export(int argc, char **argv)
{
    static export_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc >= 0)
        return rc;
    if (!a.fmt || !a.map || !a.out)
        return cli_usage_error("export", "--format, --map and -o are required (see --help)");
    int f = sc_export_format_from_name(a.fmt);
    if (f < 0)
        return cli_usage_error("export",
                               "--format: beckhoff, siemens-cec, linuxcnc, kmotion, klipper, "
                               "marlin, reprap, aerotech-a1 or powerpmac, not '%s'",
                               a.fmt);
    sc_export_options o;
    sc_export_options_init(&o, (sc_export_format)f);
    int both_files;
    if ((rc = resolve_axis(&a, f, &o, &both_files)) != CLI_OK ||
        (rc = check_applicability(&a, f)) != CLI_OK)
        return rc;
    options_from_args(&a, &o);
    sc_lut *lut = malloc(sizeof *lut);
    if (!lut) {
        fprintf(stderr, "selfcal export: out of memory\n");
        return CLI_FAIL;
    }
    sc_error err;
    sc_error_clear(&err);
    static char paths[MAX_FILES][4096];
    static sc_export_report reps[MAX_FILES];
    static sc_export_options opts[MAX_FILES];
    int nfiles = plan_files(&a, f, &o, both_files, paths, opts);
    for (int k = 0; k < nfiles; ++k) { /* OUT-x, OUT-y, OUT-cross-DIR, OUT-1d: no input */
        rc = cli_check_derived_output("export", "-o --out", "-o", paths[k], argc, argv);
        if (rc >= 0) {
            free(lut);
            return rc;
        }
    }
    sc_lut_fit_report fit;
    sc_status st = load_table(&a, lut, &fit, &err);
    if (st == SC_OK)
        st = write_files(lut, nfiles, paths, opts, reps, &err);
    if (st != SC_OK) {
        free(lut);
        return cli_report(&err);
    }
    if (fit.fitted) /* the fit's positions are the map's own (before --offset) */
        cli_print_fit(a.map, lut, &fit);
    for (int k = 0; k < nfiles; ++k)
        print_report(lut, a.fmt, f, paths[k], &opts[k], &reps[k]);
    if (!a.axis && (f == SC_EXPORT_BECKHOFF || f == SC_EXPORT_LINUXCNC)) /* one axis a file */
        printf("note: no --axis: the x axis's table only (--axis y for y, --axis both for OUT-x "
               "and OUT-y)\n");
    free(lut);
    return CLI_OK;
}
