/* cmd_export.c — `selfcal export --format {beckhoff,siemens-cec,linuxcnc} --map G.csv -o OUT`:
 * the stage error map resampled onto a machine controller's compensation table, with the residual
 * (controller interpolation of the written table minus our bilinear map) and clipped points. */
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
            "usage: selfcal export --format {beckhoff,siemens-cec,linuxcnc} --map G.csv -o OUT\n"
            "                      [--axis x|y|both] [--interval MM] [--at MM] [--limit-um UM]\n"
            "                      [--negate] [--axis-numbers NX,NY] [--axis-names NAMEX,NAMEY]\n"
            "                      [--first-table T]\n"
            "  beckhoff     TwinCAT CNC / ISG plane compensation list of one slave axis (--axis x|y),\n"
            "               0.1 um units, one interval for both masters, up to 101 x 101 points\n"
            "  siemens-cec  SINUMERIK 840D $AN_CEC part program: tables X->X, Y->X (Gx) and X->Y,\n"
            "               Y->Y (Gy) (--axis both, the default here), values in mm, <= 2000 points\n"
            "  linuxcnc     joint compensation file (COMP_FILE_TYPE = 1) of one axis (--axis x|y):\n"
            "               'nominal forward-trim reverse-trim' in mm, <= 256 entries\n"
            "  --interval   table spacing in mm (default: the map's pitch)\n"
            "  --at MM      linuxcnc: G along the line y = MM (x axis) or x = MM (y axis) instead of\n"
            "               the mean over that coordinate\n"
            "  --limit-um   clip values above this magnitude (and count them)\n"
            "  --negate     write -G instead of +G (the value added to the commanded position)\n"
            "  --axis-numbers  beckhoff logical axis numbers of x and y (default 1,2)\n"
            "  --axis-names    siemens axis names of x and y (default AX1,AX2)\n");
}

int cmd_export(int argc, char **argv)
{
    const char *map = NULL, *out = NULL, *fmt = NULL, *axis = NULL;
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    double interval = 0, limit = 0, at = 0;
    int use_at = 0, negate = 0, ax_nr[2] = {1, 2}, first_table = 0;
    static char names[2][32] = {"AX1", "AX2"};
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
            if (sscanf(v, "%d,%d", &ax_nr[0], &ax_nr[1]) != 2 || ax_nr[0] < 1 || ax_nr[1] < 1)
                return cli_usage_error("export", "--axis-numbers: NX,NY (positive), not '%s'", v);
        } else if (!strcmp(a, "--axis-names")) {
            const char *comma = strchr(v, ',');
            size_t l0 = comma ? (size_t)(comma - v) : 0, l1 = comma ? strlen(comma + 1) : 0;
            if (!comma || l0 == 0 || l1 == 0 || l0 >= sizeof names[0] || l1 >= sizeof names[1] ||
                strpbrk(v, " ()\t;") != NULL)
                return cli_usage_error("export", "--axis-names: NAMEX,NAMEY, not '%s'", v);
            memcpy(names[0], v, l0);
            names[0][l0] = '\0';
            snprintf(names[1], sizeof names[1], "%s", comma + 1);
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
        return cli_usage_error("export", "--format: beckhoff, siemens-cec or linuxcnc, not '%s'", fmt);
    sc_export_options_init(&o, (sc_export_format)f);
    o.axis = f == SC_EXPORT_SIEMENS_CEC ? -1 : 0;
    if (axis) {
        if (!strcmp(axis, "x") || !strcmp(axis, "X"))
            o.axis = 0;
        else if (!strcmp(axis, "y") || !strcmp(axis, "Y"))
            o.axis = 1;
        else if (!strcmp(axis, "both") && f == SC_EXPORT_SIEMENS_CEC)
            o.axis = -1;
        else
            return cli_usage_error("export", "--axis: x or y%s, not '%s'",
                                   f == SC_EXPORT_SIEMENS_CEC ? " or both" : "", axis);
    }
    if (use_at && f != SC_EXPORT_LINUXCNC)
        return cli_usage_error("export", "--at applies to --format linuxcnc only");
    o.interval_mm = interval;
    o.limit_um = limit;
    o.use_line = use_at;
    o.line_mm = at;
    o.negate = negate;
    o.beckhoff_x_axis_nr = ax_nr[0];
    o.beckhoff_y_axis_nr = ax_nr[1];
    o.siemens_x_name = names[0];
    o.siemens_y_name = names[1];
    o.siemens_first_table = first_table;

    sc_lut *lut = malloc(sizeof *lut);
    if (!lut) {
        fprintf(stderr, "selfcal export: out of memory\n");
        return CLI_FAIL;
    }
    sc_lut_init(lut);
    sc_error err;
    sc_error_clear(&err);
    sc_export_report rep;
    sc_status st = sc_lut_read_map(map, lut, &err);
    if (st == SC_OK)
        st = sc_export_write(lut, &o, out, &rep, &err);
    if (st != SC_OK) {
        free(lut);
        return cli_report(&err);
    }
    printf("export %s: %s", fmt, out);
    if (f == SC_EXPORT_BECKHOFF)
        printf(", slave axis %s, %d x %d points, interval %.4f mm, unit 0.1 um\n",
               o.axis == 0 ? "x" : "y", rep.points[0], rep.points[1], rep.interval_mm);
    else if (f == SC_EXPORT_SIEMENS_CEC)
        printf(", %d table(s) of %d/%d points, values in mm (1 nm)\n", rep.tables, rep.points[0],
               rep.points[1]);
    else
        printf(", axis %s, %d entries, step %.6f mm, trims in mm (1 nm)\n", o.axis == 0 ? "x" : "y",
               rep.points[0], rep.interval_mm);
    printf("residual (controller table - map) over %ld samples: rms %.4f um, max %.4f um at "
           "(%.3f, %.3f) mm\n",
           rep.samples, rep.rms_um, rep.max_um, rep.max_at_mm[0], rep.max_at_mm[1]);
    if (rep.limit_um > 0)
        printf("clipped points: %ld (limit %.4g um)\n", rep.clipped, rep.limit_um);
    else
        printf("clipped points: 0 (no limit)\n");
    free(lut);
    return CLI_OK;
}
