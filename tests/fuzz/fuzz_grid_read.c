/* tests/fuzz/fuzz_grid_read.c — libFuzzer target: the grid measurement reader (selfcal-grid v1,
 * sc_grid_read). Checks: no memory error, a one-line error or a plan whose arrays are all there. */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/grid_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sc_grid_data d;
    sc_grid_file_info info;
    sc_error err;
    memset(&d, 0, sizeof d);
    memset(&err, 0, sizeof err);
    sc_status st = sc_grid_read(fuzz_path(data, size), &d, &info, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        FUZZ_CHECK(d.plan.n >= 1);
        sc_grid_data_free(&d);
        sc_grid_file_info_free(&info);
    }
    return 0;
}
