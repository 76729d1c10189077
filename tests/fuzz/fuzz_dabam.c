/* tests/fuzz/fuzz_dabam.c — libFuzzer target: the DABAM mirror-profile reader
 * (sc_profile_load_dabam, `selfcal simulate profile --profile FILE.dat`): a .dat file of
 * (abscissa, ordinate) lines and the JSON-like metadata .txt beside it (FILE_HEADER_LINES,
 * X1_FACTOR, Y1_FACTOR, PLOT_TITLE_Y1 or FILE_FORMAT), resampled onto the scan.
 * Input: one control byte (bits 0-1: n = 8, 64, 257, 1001 points; bits 2-3: step 0.1, 1, 2,
 * 10 mm), then the metadata, a form feed, and the data (no form feed: the data is empty).
 * Checks beyond "no memory error, no undefined behaviour": a one-line error, or n finite heights
 * (what the simulator then measures) and a one-line description. (Their least-squares line is
 * removed, but only to the rounding of the heights before it, which the target cannot see.) */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/profile_sim.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const int ns[4] = {8, 64, 257, 1001};
    static const double steps[4] = {0.1, 1, 2, 10};
    static double f[1001];
    if (size < 1)
        return 0;
    int n = ns[data[0] & 3];
    double s_mm = steps[(data[0] >> 2) & 3];
    ++data;
    --size;
    const uint8_t *ff = memchr(data, '\f', size);
    size_t lm = ff ? (size_t)(ff - data) : size;
    fuzz_file(0, "mirror.txt", data, lm);
    const char *dat = ff ? fuzz_file(1, "mirror.dat", ff + 1, size - lm - 1)
                         : fuzz_file(1, "mirror.dat", data, 0);
    char info[256];
    sc_error err;
    memset(&err, 0, sizeof err);
    memset(info, 'x', sizeof info);
    for (int i = 0; i < n; ++i)
        f[i] = NAN;
    sc_status st = sc_profile_load_dabam(dat, n, s_mm, f, info, sizeof info, &err);
    fuzz_check_error(st, &err);
    if (st != SC_OK)
        return 0;
    FUZZ_CHECK(memchr(info, '\0', sizeof info) != NULL && strchr(info, '\n') == NULL);
    for (int i = 0; i < n; ++i) {
        if (!isfinite(f[i]))
            fprintf(stderr, "f[%d] = %g\n", i, f[i]);
        FUZZ_CHECK(isfinite(f[i]));
    }
    return 0;
}
