/* tests/fuzz/fuzz_verify.c — libFuzzer target: `selfcal verify` (libselfcal/src/verify/verify.c,
 * sc_verify_run) on a fuzzed re-measurement of the plate (a selfcal-grid v1 file read by
 * sc_grid_read, then placed, corrected by the table through sc_corr_apply, misalignment
 * removed), with the plate error (sc_grid_read_artifact) and the table (sc_lut_load_corr_file)
 * of a calibration made here by the library's writers.
 * Input: one control byte (bits 0-1: the plate error's N = 3, 5, 7, 9 (other N: the
 * "plate error has N" refusal); bit 2: a table of zero corrections, else a smooth one; bit 3:
 * --raw; bits 4-7: tolerance k x 0.25 µm, 0: none; the guarded rule when k is odd), then the
 * re-measurement.
 * Checks beyond "no memory error, no undefined behaviour":
 *   - a one-line error, or statistics over the same count of marks before and after, finite,
 *     RMS of x and of y <= RMS of |r| <= max |r|;
 *   - the verdict is exactly max |r| after <= tolerance (no tolerance: no verdict), under the
 *     guarded rule pass exactly when max + U <= T, fail when max - U > T, U finite and >= 0;
 *   - with a zero table, before and after compensation are the same (to rounding). */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/lut.h"
#include "selfcal/plate_map.h"
#include "selfcal/verify.h"

static char g_plate[4][320], g_table[2][320];

/* The calibration's files: plate errors for N = 3, 5, 7, 9 (one mark unseen: empty) and two
 * tables of 11 x 11 nodes at 1 mm (zero and smooth), written once. */
static void make_fixtures(void)
{
    static const int ns[4] = {3, 5, 7, 9};
    sc_error err;
    for (int q = 0; q < 4; ++q) {
        int n = ns[q];
        double ax[81], ay[81];
        sc_plate_map m = {n, ax, ay};
        for (int k = 0; k < n * n; ++k) {
            ax[k] = 0.2 * sin(0.9 * k);
            ay[k] = -0.15 * cos(1.3 * k);
        }
        ax[n + 1] = ay[n + 1] = NAN;
        snprintf(g_plate[q], sizeof g_plate[q], "%s/plate%d.csv", fuzz_dir(), n);
        FUZZ_CHECK(sc_plate_map_write(g_plate[q], &m, &err) == SC_OK);
    }
    static sc_lut lut;
    static uint8_t buf[1 << 16];
    for (int z = 0; z < 2; ++z) {
        sc_lut_init(&lut);
        lut.nx = lut.ny = 11;
        lut.x0_mm = lut.y0_mm = -5.0;
        lut.px_mm = lut.py_mm = 1.0;
        for (int i = 0; i < 11; i++)
            for (int j = 0; j < 11; j++) {
                lut.gx_um[i * 11 + j] = z ? 0.0 : 0.3 * sin(0.7 * j) + 0.05 * i;
                lut.gy_um[i * 11 + j] = z ? 0.0 : -0.2 * cos(0.5 * i) + 0.02 * j;
            }
        size_t len = 0;
        FUZZ_CHECK(sc_lut_encode(&lut, SC_LUT_ENC_INT32, buf, sizeof buf, &len, &err) == SC_OK);
        snprintf(g_table[z], sizeof g_table[z], "%s", fuzz_file(2 + z, z ? "zero.lut" : "smooth.lut", buf, len));
    }
}

static void check_stats(const sc_verify_stats *s)
{
    FUZZ_CHECK(isfinite(s->rms_x) && isfinite(s->rms_y) && isfinite(s->rms) && isfinite(s->max));
    double tol = 1e-12 * s->max;
    FUZZ_CHECK(s->rms_x <= s->rms + tol && s->rms_y <= s->rms + tol && s->rms <= s->max + tol);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!g_plate[0][0])
        make_fixtures();
    if (size < 1)
        return 0;
    uint8_t c = data[0];
    sc_verify_opts o;
    sc_verify_opts_init(&o);
    o.measurement = fuzz_path(data + 1, size - 1);
    o.artifact = g_plate[c & 3];
    int zero = (c >> 2) & 1;
    o.table = g_table[zero];
    o.raw = (c >> 3) & 1;
    if (c >> 4)
        o.tolerance_um = 0.25 * (c >> 4);
    if ((c >> 4) & 1)
        o.rule = SC_VERIFY_RULE_GUARDED;
    sc_verify_result r;
    sc_error err;
    memset(&err, 0, sizeof err);
    sc_status st = sc_verify_run(&o, &r, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        FUZZ_CHECK(r.st_before.count >= 1 && r.st_before.count == r.st_after.count);
        check_stats(&r.st_before);
        check_stats(&r.st_after);
        FUZZ_CHECK(isfinite(r.u.U_um) && r.u.U_um >= 0);
        double mx = r.st_after.max, T = o.tolerance_um, U = r.u.U_um;
        if (isnan(T))
            FUZZ_CHECK(r.verdict == SC_VERIFY_NO_VERDICT);
        else if (o.rule == SC_VERIFY_RULE_SIMPLE)
            FUZZ_CHECK(r.verdict == (mx <= T ? SC_VERIFY_PASS : SC_VERIFY_FAIL));
        else
            FUZZ_CHECK(r.verdict == (mx + U <= T   ? SC_VERIFY_PASS
                                     : mx - U > T ? SC_VERIFY_FAIL
                                                  : SC_VERIFY_INCONCLUSIVE));
        if (zero) {
            const sc_grid_plan *p = &r.d.plan;
            double scale = 1 + fabs(p->origin_mm[0]) + fabs(p->origin_mm[1]) +
                           p->pitch_mm * (sc_grid_stage_nx(p) + sc_grid_stage_ny(p));
            double tol = 1e-6 * scale + 1e-9 * r.st_after.max;
            FUZZ_CHECK(fabs(r.st_before.rms - r.st_after.rms) <= tol);
            FUZZ_CHECK(fabs(r.st_before.max - r.st_after.max) <= tol);
        }
    }
    sc_verify_result_free(&r);
    return 0;
}
