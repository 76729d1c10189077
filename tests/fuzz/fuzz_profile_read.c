/* tests/fuzz/fuzz_profile_read.c — libFuzzer target: the profile measurement reader
 * (selfcal-profile v1, sc_profile_read). */
#include "fuzz_reader_check.h"
#include "selfcal/profile.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sc_profile_data d;
    sc_error err;
    memset(&d, 0, sizeof d);
    memset(&err, 0, sizeof err);
    sc_status st = sc_profile_read(fuzz_path(data, size), &d, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        FUZZ_CHECK(d.n >= 2 && d.d[0] >= 1 && d.d[1] >= 1 && d.d[0] < d.n && d.d[1] < d.n);
        /* touch every value: ASan sees an array shorter than N - d */
        double s = 0.0;
        for (int k = 0; k < 2; k++)
            for (int i = 0; i < d.n - d.d[k]; i++)
                s += d.m1_um[k][i] + d.m2_um[k][i] + d.m3_urad[k][i];
        (void)s;
        sc_profile_data_free(&d);
    }
    return 0;
}
