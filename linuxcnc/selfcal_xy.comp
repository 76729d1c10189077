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
 * (position) and the feedback (measure or measure-exact)); each instance has its own fraction f of
the correction (enable, ramp-ms: SPEC §7a) and clamp (max-correction): no allocation, no I/O,
constant time.
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
\\fBenable\\fR and \\fBramp-ms\\fR (SPEC §7a): the applied fraction f of the correction moves towards 1
while enable is TRUE and towards 0 while it is FALSE, by one servo period / ramp-ms per period (at
once when ramp-ms is 0 or less); x-out = x-in + f (x_corrected \- x-in), the same for y, in
position and measure mode; measure-exact inverts a position instance at the same f (the q with
q + f C(q) = p), so that command and feedback stay inverse while ramping. f starts
at enable's value on the first period (TRUE by default: the full correction at once). Connect
enable to the joints' homed state, so that homing latches uncorrected positions and the correction
ramps in without a step (and out on unhoming).
\\fBmax-correction\\fR (mm, 0: no limit) clamps each component of the correction, x_corrected \-
x-in and y_corrected \- y-in, to [\-max-correction, max-correction] before f is applied, and sets
status bit 4 while it does (measure-exact inverts the clamped correction).
A missing or invalid table, or an unknown mode, makes loadrt fail with the reason in the log.
""";

pin in float x_in "X input, mm (commanded position in mode=position, feedback in mode=measure)";
pin in float y_in "Y input, mm";
pin out float x_out "corrected X, mm";
pin out float y_out "corrected Y, mm";
pin in bit enable = TRUE "TRUE: ramp the correction in; FALSE: ramp it out (connect to the joints' homed state)";
pin in float ramp_ms = 100 "time of a full ramp of the correction, ms (0 or less: at once)";
pin out float fraction "the applied fraction f of the correction, 0 to 1";
pin out u32 status = 1 "bit 0: table loaded (from loadrt on: a table that does not load fails loadrt); bit 1: input outside the grid (correction held at the edge); bit 2: input NaN or infinite (passed through); bit 3: f < 1 (ramping, or disabled); bit 4: the correction was clamped to max-correction";
param rw float max_correction = 0 "largest correction applied per axis, mm (0: no limit); larger ones are clamped and set status bit 4";

function _ "correct x-in, y-in into x-out, y-out (no allocation, constant time)";

option extra_setup yes;

variable int corr_mode; /* this instance's sc_corr_mode */
variable double frac;   /* the applied fraction f of the correction (SPEC §7a) */
variable int started;   /* 0 until the first period: f then starts at enable's value */

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
#include <math.h>
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

/* Status bits of SPEC §7a and of max-correction, above the core's bits 0-2. */
#define SELFCAL_XY_ST_PARTIAL 0x08u /* f < 1 */
#define SELFCAL_XY_ST_CLAMPED 0x10u /* a correction was clamped to max-correction */

/* d clamped to [-lim, lim] (lim > 0); *clamped set when it was. */
static double selfcal_xy_clamp(double d, double lim, unsigned *clamped)
{
    if (d > lim) {
        *clamped = SELFCAL_XY_ST_CLAMPED;
        return lim;
    }
    if (d < -lim) {
        *clamped = SELFCAL_XY_ST_CLAMPED;
        return -lim;
    }
    return d;
}

FUNCTION(_)
{
    /* f: one period / ramp-ms per period towards enable's side (at once when ramp-ms <= 0). */
    const double target = enable ? 1.0 : 0.0;
    if (!started) {
        frac = target;
        started = 1;
    } else if (!(ramp_ms > 0.0)) {
        frac = target;
    } else {
        const double step = fperiod * 1e3 / ramp_ms;
        frac = frac < target ? (frac + step < target ? frac + step : target)
                             : (frac - step > target ? frac - step : target);
    }
    const double in_mm[3] = {x_in, y_in, 0.0};
    double out_mm[3];
    const double lim = max_correction;
    unsigned st = sc_corr_apply(&selfcal_table, (sc_corr_mode)corr_mode, in_mm, out_mm);
    unsigned clamped = 0;
    if (!(st & SC_CORR_ST_INVALID) && corr_mode == SC_CORR_MEASURE_EXACT &&
        (frac < 1.0 || (lim > 0.0 && (fabs(out_mm[0] - in_mm[0]) > lim ||
                                      fabs(out_mm[1] - in_mm[1]) > lim)))) {
        /* The exact inverse of what a position instance outputs at this f and clamp,
         * t + f clamp(C(t)): the q with q + f clamp(C(q)) = p, by the core's fixed-point
         * steps (q <- p - f clamp(C(q)), from q = p; C evaluated by the core in position
         * mode). At f = 0 it is p itself; at f = 1 without a clamp the core's result above. */
        double q[3] = {in_mm[0], in_mm[1], 0.0};
        for (int it = 0; it < SC_CORR_EXACT_ITERATIONS; ++it) {
            double t_mm[3];
            st |= sc_corr_apply(&selfcal_table, SC_CORR_POSITION, q, t_mm);
            double dx = t_mm[0] - q[0], dy = t_mm[1] - q[1];
            if (lim > 0.0) {
                dx = selfcal_xy_clamp(dx, lim, &clamped);
                dy = selfcal_xy_clamp(dy, lim, &clamped);
            }
            q[0] = in_mm[0] - frac * dx;
            q[1] = in_mm[1] - frac * dy;
        }
        out_mm[0] = q[0];
        out_mm[1] = q[1];
    } else if (!(st & SC_CORR_ST_INVALID)) {
        double dx = out_mm[0] - in_mm[0], dy = out_mm[1] - in_mm[1];
        if (lim > 0.0) {
            dx = selfcal_xy_clamp(dx, lim, &clamped);
            dy = selfcal_xy_clamp(dy, lim, &clamped);
        }
        if (frac < 1.0 || clamped) { /* x-out = x-in + f (x_corrected - x-in), SPEC §7a */
            out_mm[0] = in_mm[0] + frac * dx;
            out_mm[1] = in_mm[1] + frac * dy;
        } /* else the core's result as it is (f = 1, not clamped: SPEC §7 exactly) */
    }
    st |= clamped;
    if (frac < 1.0)
        st |= SELFCAL_XY_ST_PARTIAL;
    x_out = out_mm[0];
    y_out = out_mm[1];
    fraction = frac;
    status = st;
}
