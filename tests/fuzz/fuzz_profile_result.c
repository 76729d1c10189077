/* tests/fuzz/fuzz_profile_result.c — libFuzzer target: the profile result readers
 * (sc_profile_read_result for plots/verify, sc_lut_read_profile for `lut build --profile`). */
#include "fuzz_reader_check.h"
#include "selfcal/lut.h"
#include "selfcal/profile.h"

static sc_lut_profile g_p;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_path(data, size);
    sc_profile_result r;
    sc_error err;
    memset(&r, 0, sizeof r);
    memset(&err, 0, sizeof err);
    sc_status st = sc_profile_read_result(path, &r, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        double s = 0.0;
        for (int i = 0; i < r.n; i++)
            s += r.x_mm[i] + r.f_um[i] + r.uf_um[i] + r.ey_um[i];
        (void)s;
        sc_profile_result_free(&r);
    }
    memset(&err, 0, sizeof err);
    st = sc_lut_read_profile(path, 0, 1, &g_p, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK)
        FUZZ_CHECK(g_p.n >= 2 && g_p.n <= SC_LUT_MAX_PROFILE_POINTS && g_p.step_mm > 0);
    return 0;
}
