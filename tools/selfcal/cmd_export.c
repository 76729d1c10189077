/* cmd_export.c — `selfcal export --format FORMAT --map G.csv -o OUT`: the stage error map
 * resampled onto a machine controller's compensation table (beckhoff, siemens-cec, linuxcnc,
 * kmotion), or its first order as firmware skew/scale settings (klipper, marlin, reprap), with
 * the residual (what the controller applies minus our bilinear map) and clipped points;
 * straightness profiles as Siemens CEC tables or Beckhoff/ISG cross compensation lists. Every
 * file is computed (and checked) before the first is written: all files or none. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "selfcal/csv.h"
#include "selfcal/export.h"
#include "selfcal/lut.h"

static void export_usage(FILE *to)
{
    fprintf(to,
            "usage: selfcal export --format FORMAT --map G.csv -o OUT\n"
            "                      [--axis x|y|both] [--interval MM] [--at MM] [--limit-um UM]\n"
            "                      [--negate] [--offset DX,DY] [--axis-numbers NX,NY[,NZ]]\n"
            "                      [--axis-names NAMEX,NAMEY] [--first-table T] [--target 840d|828d]\n"
            "                      [--steps-per-mm SX,SY] [--rotation-distance RX,RY]\n"
            "                      [--profile AXIS:DIR:P.csv[@OFFSET_MM] ...] [--travel [AXIS:]MIN,MAX]\n"
            "                      [--profile-interval MM]\n"
            "  beckhoff     TwinCAT CNC / ISG plane compensation list of one slave axis (--axis x|y;\n"
            "               both: OUT-x and OUT-y), 0.1 um units, ISG's sign actual - setpoint (-G)\n"
            "  siemens-cec  SINUMERIK $AN_CEC part program: tables X->X, Y->X (Gx) and X->Y, Y->Y (Gy)\n"
            "               (--axis both, the default here), values in mm, <= 2000 points (828D: 200)\n"
            "  linuxcnc     joint compensation file of one axis (--axis x|y; both: OUT-x and OUT-y):\n"
            "               'nominal trim trim' in mm, <= 256 entries; needs COMP_FILE_TYPE = 1\n"
            "  klipper      SET_SKEW XY=AC,BD,AD (skew_correction) from the map's O and R\n"
            "  marlin       M852 I (skew factor) and M92 scale from the map's O and R\n"
            "  reprap       RepRapFirmware M556 S X and M92 scale from the map's O and R\n"
            "  kmotion      Dynomotion KMotionCNC geometric correction table: the whole 2-D map\n"
            "               (X and Y at once, inches, ideal + G)\n"
            "  --interval   table spacing in mm (default: the map's pitch)\n"
            "  --at MM      linuxcnc: G along the line y = MM (x axis) or x = MM (y axis) instead of\n"
            "               the mean over that coordinate\n"
            "  --limit-um   clip values above this magnitude (and count them)\n"
            "  --negate     write the opposite of the format's default sign\n"
            "  --offset DX,DY  the machine (homed) coordinates of the map's x = 0, y = 0, added to\n"
            "               every table position\n"
            "  --axis-numbers  beckhoff logical axis numbers of x, y (and z) (default 1,2,3)\n"
            "  --axis-names    siemens axis names of x and y (default AX1,AX2)\n"
            "  --target 828d   siemens: the 828D's fixed 8 tables x 200 points\n"
            "  --profile AXIS:DIR:P.csv[@OFFSET_MM]  a straightness profile (the ey_um column of a\n"
            "               profile output: the error of DIR along AXIS, placed as in lut build)\n"
            "               siemens: one more table, input AXIS, output DIR (z: AX3);\n"
            "               beckhoff: a cross compensation list OUT-cross-DIR, slave DIR, master\n"
            "               AXIS, ISG's sign (-e)\n"
            "  --profile-interval MM  the profiles' table spacing (default: the profile's own\n"
            "               points; siemens: --interval if given)\n"
            "  --travel [AXIS:]MIN,MAX  beckhoff profiles: the master axis' travel (mm, machine\n"
            "               coordinates): the list gets its end values at MIN and MAX (without\n"
            "               it the list spans the profile and ISG's behaviour beyond is unknown);\n"
            "               AXIS: for the profiles with that master axis (repeatable), else all\n"
            "  --steps-per-mm  marlin, reprap: present X,Y steps/mm, to write M92 with the scale\n"
            "  --rotation-distance  klipper: present X,Y rotation_distance, to write the new ones\n");
}

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

static void print_report(const sc_lut *lut, const char *fmt, int f, const char *out,
                         const sc_export_options *o, const sc_export_report *rep)
{
    printf("export %s: %s", fmt, out);
    if (f == SC_EXPORT_BECKHOFF && o->cross_profile >= 0) {
        print_cross_report(lut, out, o, rep);
        return;
    }
    if (f == SC_EXPORT_BECKHOFF)
        printf(", slave axis %s, %d x %d points, interval %.4f mm, unit 0.1 um, %s\n",
               o->axis == 0 ? "x" : "y", rep->points[0], rep->points[1], rep->interval_mm,
               o->negate ? "+G (negated)" : "-G (ISG: actual - setpoint)");
    else if (f == SC_EXPORT_SIEMENS_CEC)
        printf(", %d table(s) of %d/%d points, values in mm (1 nm), %s\n", rep->tables,
               rep->points[0], rep->points[1],
               o->negate ? "+G (negated)" : "-G (Siemens: a positive value moves the axis negative)");
    else if (f == SC_EXPORT_LINUXCNC)
        printf(", axis %s, %d entries, step %.6f mm, trims in mm (1 nm)\n",
               o->axis == 0 ? "x" : "y", rep->points[0], rep->interval_mm);
    else if (f == SC_EXPORT_KMOTION)
        printf(", %d x %d points (the map plus a ring of edge values), inches, %s\n",
               rep->points[0], rep->points[1], o->negate ? "ideal - G (negated)" : "ideal + G");
    else
        printf(", O = %.6g, R = %.6g, XY skew %.9g, scale x %.9f y %.9f\n", rep->O, rep->R,
               rep->skew, rep->scale[0], rep->scale[1]);
    printf("residual (controller %s - map) over %ld samples: rms %.4f um, max %.4f um at "
           "(%.3f, %.3f) mm\n",
           is_firmware(f) ? "correction, up to translation/rotation/magnification"
                                  : "table",
           rep->samples, rep->rms_um, rep->max_um, rep->max_at_mm[0], rep->max_at_mm[1]);
    if (is_firmware(f))
        return;
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

int cmd_export(int argc, char **argv)
{
    const char *map = NULL, *out = NULL, *fmt = NULL, *axis = NULL;
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    double interval = 0, limit = 0, at = 0, pinterval = 0;
    int use_at = 0, negate = 0, ax_nr[3] = {1, 2, 3}, first_table = 0;
    static char names[2][32] = {"AX1", "AX2"};
    double offset[2] = {0, 0}, steps[2] = {0, 0}, rdist[2] = {0, 0};
    int np = 0, prof_axis[SC_LUT_MAX_PROFILES], prof_dir[SC_LUT_MAX_PROFILES];
    /* --travel: [3] for every master axis, [0..2] for master x, y, z ("x:MIN,MAX"). */
    double travel[4][2] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
    int use_travel[4] = {0, 0, 0, 0};
    static char prof_path[SC_LUT_MAX_PROFILES][4096];
    double prof_offset[SC_LUT_MAX_PROFILES];
    int target_828d = 0;
    for (int k = 1; k < argc; ++k) {
        const char *a = argv[k];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            export_usage(stdout);
            return CLI_OK;
        }
        if (!strcmp(a, "--negate")) {
            negate = 1;
            continue;
        }
        const char *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!v)
            return cli_usage_error("export", "option %s needs a value (see --help)", a);
        ++k;
        if (!strcmp(a, "--format"))
            fmt = v;
        else if (!strcmp(a, "--map"))
            map = v;
        else if (!strcmp(a, "-o") || !strcmp(a, "--out"))
            out = v;
        else if (!strcmp(a, "--axis"))
            axis = v;
        else if (!strcmp(a, "--interval")) {
            if (sc_parse_double(v, &interval) != 0 || interval <= 0)
                return cli_usage_error("export", "--interval: a positive number of mm, not '%s'", v);
        } else if (!strcmp(a, "--limit-um")) {
            if (sc_parse_double(v, &limit) != 0 || limit <= 0)
                return cli_usage_error("export", "--limit-um: a positive number, not '%s'", v);
        } else if (!strcmp(a, "--at")) {
            if (sc_parse_double(v, &at) != 0)
                return cli_usage_error("export", "--at: a position in mm, not '%s'", v);
            use_at = 1;
        } else if (!strcmp(a, "--axis-numbers")) {
            char tail;
            const int got = sscanf(v, "%d,%d,%d%c", &ax_nr[0], &ax_nr[1], &ax_nr[2], &tail);
            if ((got != 2 && got != 3) || ax_nr[0] < 1 || ax_nr[1] < 1 || ax_nr[2] < 1 ||
                ax_nr[0] > 65535 || ax_nr[1] > 65535 || ax_nr[2] > 65535)
                return cli_usage_error("export", "--axis-numbers: NX,NY[,NZ] (1..65535), not '%s'", v);
        } else if (!strcmp(a, "--axis-names")) {
            const char *comma = strchr(v, ',');
            size_t l0 = comma ? (size_t)(comma - v) : 0, l1 = comma ? strlen(comma + 1) : 0;
            if (!comma || l0 == 0 || l1 == 0 || l0 >= sizeof names[0] || l1 >= sizeof names[1] ||
                strpbrk(v, " ()\t;") != NULL)
                return cli_usage_error("export", "--axis-names: NAMEX,NAMEY, not '%s'", v);
            memcpy(names[0], v, l0);
            names[0][l0] = '\0';
            snprintf(names[1], sizeof names[1], "%s", comma + 1);
        } else if (!strcmp(a, "--profile")) {
            if (np == SC_LUT_MAX_PROFILES)
                return cli_usage_error("export", "at most %d profiles", SC_LUT_MAX_PROFILES);
            if (cli_parse_profile_placed(v, &prof_axis[np], &prof_dir[np], prof_path[np],
                                         sizeof prof_path[np], &prof_offset[np]) != 0)
                return cli_usage_error("export", "--profile: AXIS:DIR:FILE[@OFFSET_MM] with AXIS, DIR in x, y, z and |OFFSET_MM| <= 1e6; not '%s'", v);
            if (prof_axis[np] == prof_dir[np])
                return cli_usage_error("export", "--profile: a straightness profile has DIR != AXIS, not '%s'", v);
            ++np;
        } else if (!strcmp(a, "--profile-interval")) {
            if (sc_parse_double(v, &pinterval) != 0 || !(pinterval > 0))
                return cli_usage_error("export", "--profile-interval: a positive number of mm, not '%s'", v);
        } else if (!strcmp(a, "--travel")) {
            int t = 3;
            const char *mm = v;
            if (v[0] && v[1] == ':') {
                const char ax[2] = {v[0], '\0'};
                t = sc_lut_axis_from_name(ax);
                mm = v + 2;
            }
            double *tr = t >= 0 ? travel[t] : travel[3];
            if (t < 0 || two_doubles(mm, tr) != 0 || !(tr[0] < tr[1]) || fabs(tr[0]) > 1e6 ||
                fabs(tr[1]) > 1e6)
                return cli_usage_error("export", "--travel: [AXIS:]MIN,MAX in mm with MIN < MAX (within 1 km), not '%s'", v);
            use_travel[t] = 1;
        } else if (!strcmp(a, "--offset")) {
            if (two_doubles(v, offset) != 0 || fabs(offset[0]) > 1e6 || fabs(offset[1]) > 1e6)
                return cli_usage_error("export", "--offset: DX,DY in mm (within 1 km), not '%s'", v);
        } else if (!strcmp(a, "--steps-per-mm") || !strcmp(a, "--rotation-distance")) {
            double *d = a[2] == 's' ? steps : rdist;
            if (two_doubles(v, d) != 0 || !(d[0] > 0) || !(d[1] > 0) || d[0] > 1e9 || d[1] > 1e9)
                return cli_usage_error("export", "%s: X,Y (positive), not '%s'", a, v);
        } else if (!strcmp(a, "--target")) {
            if (!strcmp(v, "828d") || !strcmp(v, "828D"))
                target_828d = 1;
            else if (strcmp(v, "840d") != 0 && strcmp(v, "840D") != 0)
                return cli_usage_error("export", "--target: 840d or 828d, not '%s'", v);
        } else if (!strcmp(a, "--first-table")) {
            long t;
            if (sc_parse_long(v, &t) != 0 || t < 0 || t > 1000)
                return cli_usage_error("export", "--first-table: a table index >= 0, not '%s'", v);
            first_table = (int)t;
        } else
            return cli_usage_error("export", "unknown option '%s' (see --help)", a);
    }
    if (!fmt || !map || !out)
        return cli_usage_error("export", "--format, --map and -o are required (see --help)");
    int f = sc_export_format_from_name(fmt);
    if (f < 0)
        return cli_usage_error("export",
                               "--format: beckhoff, siemens-cec, linuxcnc, kmotion, klipper, "
                               "marlin or reprap, not '%s'",
                               fmt);
    const int firmware = is_firmware(f);
    sc_export_options_init(&o, (sc_export_format)f);
    o.axis = f == SC_EXPORT_SIEMENS_CEC ? -1 : 0;
    int both_files = 0;
    if (axis) {
        if (firmware || f == SC_EXPORT_KMOTION)
            return cli_usage_error("export", "--axis does not apply to --format %s (X and Y at once)",
                                   fmt);
        if (!strcmp(axis, "x") || !strcmp(axis, "X"))
            o.axis = 0;
        else if (!strcmp(axis, "y") || !strcmp(axis, "Y"))
            o.axis = 1;
        else if (!strcmp(axis, "both") && f == SC_EXPORT_SIEMENS_CEC)
            o.axis = -1;
        else if (!strcmp(axis, "both"))
            both_files = 1; /* one file per axis: OUT-x, OUT-y */
        else
            return cli_usage_error("export", "--axis: x, y or both, not '%s'", axis);
    }
    if (use_at && f != SC_EXPORT_LINUXCNC)
        return cli_usage_error("export", "--at applies to --format linuxcnc only");
    if (np > 0 && f != SC_EXPORT_SIEMENS_CEC && f != SC_EXPORT_BECKHOFF)
        return cli_usage_error("export", "--profile applies to --format siemens-cec and beckhoff only "
                                         "(LinuxCNC: the HAL component applies profiles)");
    if (pinterval > 0 && np == 0)
        return cli_usage_error("export", "--profile-interval applies to --profile tables only");
    for (int t = 0; t < 4; ++t) {
        if (use_travel[t] && (f != SC_EXPORT_BECKHOFF || np == 0))
            return cli_usage_error("export", "--travel applies to --format beckhoff with --profile only");
        int used = t == 3;
        for (int k = 0; k < np; ++k)
            used |= prof_axis[k] == t;
        if (use_travel[t] && !used)
            return cli_usage_error("export", "--travel %s: no profile has master axis %s",
                                   sc_lut_axis_name(t), sc_lut_axis_name(t));
    }
    for (int a = 0; a < np && f == SC_EXPORT_BECKHOFF; ++a)
        for (int b = 0; b < a; ++b)
            if (prof_dir[a] == prof_dir[b])
                return cli_usage_error("export", "beckhoff: two profiles correct %s; ISG corrects a "
                                                 "slave axis by one master axis (one cross "
                                                 "compensation list per slave)",
                                       sc_lut_axis_name(prof_dir[a]));
    if (target_828d && f != SC_EXPORT_SIEMENS_CEC)
        return cli_usage_error("export", "--target applies to --format siemens-cec only");
    if (steps[0] > 0 && f != SC_EXPORT_MARLIN && f != SC_EXPORT_REPRAP)
        return cli_usage_error("export", "--steps-per-mm applies to --format marlin or reprap only");
    if (rdist[0] > 0 && f != SC_EXPORT_KLIPPER)
        return cli_usage_error("export", "--rotation-distance applies to --format klipper only");
    if (firmware && (negate || interval > 0 || limit > 0))
        return cli_usage_error("export", "--negate, --interval and --limit-um do not apply to "
                                         "--format %s (the firmware's own skew and sign)",
                               fmt);
    o.interval_mm = interval;
    o.profile_interval_mm = pinterval;
    o.limit_um = limit;
    o.use_line = use_at;
    o.line_mm = at;
    o.negate = negate;
    o.beckhoff_x_axis_nr = ax_nr[0];
    o.beckhoff_y_axis_nr = ax_nr[1];
    o.beckhoff_z_axis_nr = ax_nr[2];
    o.siemens_x_name = names[0];
    o.siemens_y_name = names[1];
    o.siemens_first_table = first_table;
    o.siemens_828d = target_828d;
    o.steps_per_mm[0] = steps[0];
    o.steps_per_mm[1] = steps[1];
    o.rotation_distance_mm[0] = rdist[0];
    o.rotation_distance_mm[1] = rdist[1];

    sc_lut *lut = malloc(sizeof *lut);
    if (!lut) {
        fprintf(stderr, "selfcal export: out of memory\n");
        return CLI_FAIL;
    }
    sc_lut_init(lut);
    sc_error err;
    sc_error_clear(&err);
    sc_status st = sc_lut_read_map(map, lut, &err);
    for (int k = 0; k < np && st == SC_OK; ++k) {
        st = sc_lut_read_profile(prof_path[k], prof_axis[k], prof_dir[k], &lut->profile[k], &err);
        lut->profile[k].start_mm += prof_offset[k];
        lut->n_profiles = k + 1;
    }
    /* Table positions in the machine's homed coordinates. */
    lut->x0_mm += offset[0];
    lut->y0_mm += offset[1];
    for (int k = 0; k < lut->n_profiles; ++k)
        lut->profile[k].start_mm += lut->profile[k].axis < 2 ? offset[lut->profile[k].axis] : 0.0;
    /* The files: the map's (one, or OUT-x and OUT-y), then a Beckhoff list per profile. */
    enum { MAX_FILES = 2 + SC_LUT_MAX_PROFILES };
    static char paths[MAX_FILES][4096];
    static sc_export_report reps[MAX_FILES];
    static sc_export_options opts[MAX_FILES];
    int nfiles = 0;
    for (int k = 0; k < (both_files ? 2 : 1); ++k, ++nfiles) {
        opts[nfiles] = o;
        if (both_files) {
            opts[nfiles].axis = k;
            tagged_path(out, k == 0 ? "x" : "y", paths[nfiles], sizeof paths[nfiles]);
        } else {
            snprintf(paths[nfiles], sizeof paths[nfiles], "%s", out);
        }
    }
    for (int k = 0; k < np && f == SC_EXPORT_BECKHOFF; ++k, ++nfiles) {
        char tag[16];
        snprintf(tag, sizeof tag, "cross-%s", sc_lut_axis_name(prof_dir[k]));
        opts[nfiles] = o;
        opts[nfiles].cross_profile = k;
        const int t = use_travel[prof_axis[k]] ? prof_axis[k] : 3; /* its own, else the common one */
        opts[nfiles].use_travel = use_travel[t];
        opts[nfiles].travel_mm[0] = travel[t][0];
        opts[nfiles].travel_mm[1] = travel[t][1];
        tagged_path(out, tag, paths[nfiles], sizeof paths[nfiles]);
    }
    /* Every file computed and checked first (nothing written), then written: all or none. */
    for (int k = 0; k < nfiles && st == SC_OK; ++k)
        st = sc_export_write(lut, &opts[k], NULL, &reps[k], &err);
    int written = 0;
    for (; written < nfiles && st == SC_OK; ++written)
        st = sc_export_write(lut, &opts[written], paths[written], &reps[written], &err);
    if (st != SC_OK) {
        for (int k = 0; k + 1 < written; ++k)
            remove(paths[k]); /* all files or none */
        free(lut);
        return cli_report(&err);
    }
    for (int k = 0; k < nfiles; ++k)
        print_report(lut, fmt, f, paths[k], &opts[k], &reps[k]);
    free(lut);
    return CLI_OK;
}
