/* tests/fuzz/fuzz_profile_read.c — libFuzzer target: the profile measurement reader
 * (selfcal-profile v1, sc_profile_read), differential: every input is read with the data rows
 * split between two threads wherever the file's middle falls (the fast pass's threshold at 0
 * bytes) and by one thread; both must give the same status, the same message at the same line,
 * and the same values bit for bit. */
#include <limits.h>

#include "fuzz_reader_check.h"
#include "selfcal/profile.h"
#include "../../libselfcal/src/io/profile_file_internal.h"

static int same_array(const double *a, const double *b, int n)
{
    return memcmp(a, b, (size_t)n * sizeof(double)) == 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sc_profile_data d, one;
    sc_error err, err_one;
    memset(&d, 0, sizeof d);
    memset(&one, 0, sizeof one);
    memset(&err, 0, sizeof err);
    memset(&err_one, 0, sizeof err_one);
    const char *path = fuzz_path(data, size);
    int threads = -1;
    sc_status st = sc_profile_read_tuned(path, 0, &threads, &d, &err);
    sc_status st_one = sc_profile_read_tuned(path, LLONG_MAX, NULL, &one, &err_one);
    fuzz_check_error(st, &err);
    FUZZ_CHECK(st == st_one);
    FUZZ_CHECK(st == SC_OK ? threads == 1 || threads == 2 : threads == 0);
    if (st != SC_OK) {
        FUZZ_CHECK(err.line == err_one.line && strcmp(err.msg, err_one.msg) == 0);
        return 0;
    }
    FUZZ_CHECK(d.n >= 2 && d.d[0] >= 1 && d.d[1] >= 1 && d.d[0] < d.n && d.d[1] < d.n);
    FUZZ_CHECK(d.n == one.n && d.d[0] == one.d[0] && d.d[1] == one.d[1] && d.s_mm == one.s_mm);
    /* every value (ASan sees an array shorter than N - d) */
    for (int k = 0; k < 2; k++) {
        int m = d.n - d.d[k];
        FUZZ_CHECK(same_array(d.m1_um[k], one.m1_um[k], m) &&
                   same_array(d.m2_um[k], one.m2_um[k], m) &&
                   same_array(d.m3_urad[k], one.m3_urad[k], m));
    }
    sc_profile_data_free(&d);
    sc_profile_data_free(&one);
    return 0;
}
