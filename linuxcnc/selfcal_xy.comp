/* selfcal_xy.comp — the LinuxCNC realtime HAL component of SPEC §7: X and Y positions corrected by
 * a selfcal table (2D grid G, bilinear, clamped, plus straightness profiles), by the same
 * freestanding correction core as selfcald (libselfcal/src/core, compiled into this module: the
 * build puts libselfcal/include and libselfcal/src/core on the include path, see
 * linuxcnc/CMakeLists.txt). Nothing here computes a correction itself.
 *
 * The table file is read and validated once, in rtapi_app_main (loadrt): that is ordinary file
 * I/O, possible in uspace LinuxCNC (POSIX or PREEMPT_RT), where modules run inside the rtapi_app
 * process; a kernel-module build (RTAI) could not do it and is refused at compile time. A bad
 * table or mode makes loadrt fail with the reason logged through rtapi_print_msg. The realtime
 * function only reads the decoded table (static storage, one per module, shared by every
 * instance; each instance has its own mode, so that one load serves the commanded positions
 * (position) and the feedback (measure)): no allocation, no I/O, constant time.
 * Docs: docs/linuxcnc.md.
 */
component selfcal_xy "Correct X and Y positions with a selfcal error-map table (2D grid and straightness profiles)";

description """
Loads a selfcal table (\\fBselfcal lut build\\fR) once at \\fBloadrt\\fR and corrects X and Y every
period exactly as the selfcald daemon does (SPEC §4).
\\fBloadrt selfcal_xy table=\\fIPATH\\fB [mode=position|measure|measure-exact]\\fR.
mode=position (default): the inputs are commanded positions, the outputs are pre-compensated
targets (target + G(target) + profile offsets) to send to the drives.
mode=measure: the inputs are indicated (feedback) positions, the outputs are true positions
(p - G(p) - profile offsets), to first order.
mode=measure-exact: as measure, but the exact inverse of position mode (the q with q + G(q) +
offsets = p, by 3 fixed-point steps: constant time, about four times measure's cost in
bench_core_apply); it removes measure's first-order error, G times the slope of G (0.9 nm rms and
10 nm at worst on the demo's map at 1 mm pitch).
A missing or invalid table, or an unknown mode, makes loadrt fail with the reason in the log.
""";

pin in float x_in "X input, mm (commanded position in mode=position, feedback in mode=measure)";
pin in float y_in "Y input, mm";
pin out float x_out "corrected X, mm";
pin out float y_out "corrected Y, mm";
pin out u32 status = 1 "bit 0: table loaded (from loadrt on: a table that does not load fails loadrt); bit 1: input outside the grid (correction held at the edge); bit 2: input NaN or infinite (passed through)";

function _ "correct x-in, y-in into x-out, y-out (no allocation, constant time)";

option extra_setup yes;

variable int corr_mode; /* this instance's sc_corr_mode */

/* The correction core, compiled into the module before the pin macros below exist. */
include "selfcal/correct.h";
include "correct_load.c";
include "correct_explain.c";
include "correct_apply.c";

license "MIT";
author "selfcal";
;;

#ifndef USPACE
#error "selfcal_xy reads its table file at load time: it is built for uspace LinuxCNC only"
#endif

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A table file is at most a few hundred kilobytes (101 x 101 int32 nodes and 8 profiles of 2048
 * points are ~150 kB); anything larger is not a table this module can hold. */
#define SELFCAL_XY_MAX_FILE_BYTES (2u * 1024u * 1024u)

static char *table = 0;
RTAPI_MP_STRING(table, "path of the selfcal table file (selfcal lut build)");
#define SELFCAL_XY_MAX_MODES 16
static char *mode[SELFCAL_XY_MAX_MODES] = {0};
RTAPI_MP_ARRAY_STRING(mode, SELFCAL_XY_MAX_MODES, "per instance: position (default: commanded positions in, pre-compensated out), measure (feedback in, true positions out, first order) or measure-exact (the exact inverse of position)");

static sc_corr_table selfcal_table; /* decoded once at loadrt, only read afterwards */
static int selfcal_loaded = 0;

/* Reads PATH and decodes it into selfcal_table; 0, or -errno-like with the reason logged. */
static int selfcal_xy_load(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: table=%s: cannot open: %s\n", path,
                        strerror(errno));
        return -ENOENT;
    }
    unsigned char *buf = malloc(SELFCAL_XY_MAX_FILE_BYTES + 1u);
    if (!buf) {
        fclose(f);
        rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: table=%s: out of memory\n", path);
        return -ENOMEM;
    }
    size_t n = fread(buf, 1, SELFCAL_XY_MAX_FILE_BYTES + 1u, f);
    int read_error = ferror(f);
    fclose(f);
    int rc = 0;
    if (read_error) {
        rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: table=%s: read error\n", path);
        rc = -EIO;
    } else if (n > SELFCAL_XY_MAX_FILE_BYTES) {
        rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: table=%s: larger than %u bytes, not a selfcal table\n",
                        path, SELFCAL_XY_MAX_FILE_BYTES);
        rc = -EINVAL;
    } else {
        int code = sc_corr_load(&selfcal_table, buf, n);
        if (code != SC_CORR_OK) {
            rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: table=%s: not a valid table: %s\n", path,
                            sc_corr_explain(buf, n));
            rc = -EINVAL;
        }
    }
    free(buf);
    return rc;
}

/* Per instance: its mode (mode[k], else mode[0], else position); once: the shared table. */
EXTRA_SETUP()
{
    const char *m = extra_arg >= 0 && extra_arg < SELFCAL_XY_MAX_MODES && mode[extra_arg]
                        ? mode[extra_arg]
                        : mode[0];
    if (!m || !m[0] || strcmp(m, "position") == 0) {
        corr_mode = SC_CORR_POSITION;
    } else if (strcmp(m, "measure") == 0) {
        corr_mode = SC_CORR_MEASURE;
    } else if (strcmp(m, "measure-exact") == 0) {
        corr_mode = SC_CORR_MEASURE_EXACT;
    } else {
        rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: mode=%s: unknown mode (position, measure or "
                        "measure-exact)\n", m);
        return -EINVAL;
    }
    if (!selfcal_loaded) {
        if (!table || !table[0]) {
            rtapi_print_msg(RTAPI_MSG_ERR, "selfcal_xy: no table: loadrt selfcal_xy table=PATH [mode=position|measure|measure-exact]\n");
            return -EINVAL;
        }
        int rc = selfcal_xy_load(table);
        if (rc != 0)
            return rc;
        selfcal_loaded = 1;
        rtapi_print_msg(RTAPI_MSG_INFO, "selfcal_xy: table=%s: %u x %u nodes, %u profiles\n",
                        table, (unsigned)selfcal_table.nx, (unsigned)selfcal_table.ny,
                        (unsigned)selfcal_table.n_profiles);
    }
    rtapi_print_msg(RTAPI_MSG_INFO, "selfcal_xy: %s: mode=%s\n", prefix,
                    corr_mode == SC_CORR_POSITION  ? "position"
                    : corr_mode == SC_CORR_MEASURE ? "measure"
                                                   : "measure-exact");
    return 0;
}

FUNCTION(_)
{
    const double in_mm[3] = {x_in, y_in, 0.0};
    double out_mm[3];
    const unsigned st = sc_corr_apply(&selfcal_table, (sc_corr_mode)corr_mode, in_mm, out_mm);
    x_out = out_mm[0];
    y_out = out_mm[1];
    status = st;
}
