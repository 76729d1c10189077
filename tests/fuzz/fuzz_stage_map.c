/* tests/fuzz/fuzz_stage_map.c — libFuzzer target: the stage error map readers (SPEC §1 map:
 * sc_stage_map_read, the io/ reader, and sc_lut_read_map for `lut build`), and the table fitted
 * to a map read (sc_lut_fit_grid, `lut build --max-nodes`; the limit from the input's size). */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/stage_map.h"
#include "selfcal/lut.h"

static sc_lut g_lut;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_path(data, size);
    sc_stage_map m;
    sc_error err;
    memset(&m, 0, sizeof m);
    memset(&err, 0, sizeof err);
    sc_status st = sc_stage_map_read(path, &m, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        FUZZ_CHECK(m.nx >= 2 && m.ny >= 2);
        int max_nodes = 2 + (int)(size % 100);
        sc_lut_fit_report rep;
        sc_lut_init(&g_lut);
        st = sc_lut_fit_grid(&g_lut, &m, max_nodes, path, &rep, &err);
        fuzz_check_error(st, &err);
        if (st == SC_OK) {
            FUZZ_CHECK(g_lut.nx == (m.nx < max_nodes ? m.nx : max_nodes) &&
                       g_lut.ny == (m.ny < max_nodes ? m.ny : max_nodes));
            FUZZ_CHECK(rep.fitted == (g_lut.nx < m.nx || g_lut.ny < m.ny));
            FUZZ_CHECK(g_lut.px_mm > 0 && g_lut.py_mm > 0);
            FUZZ_CHECK(rep.rms_um >= 0 && rep.rms_um <= rep.max_um * (1 + 1e-12) + 1e-300);
            for (int k = 0; k < g_lut.nx * g_lut.ny; ++k) /* values within the map's 1e6 um */
                FUZZ_CHECK(isfinite(g_lut.gx_um[k]) && isfinite(g_lut.gy_um[k]));
        }
        sc_stage_map_free(&m);
    }
    memset(&err, 0, sizeof err);
    sc_lut_init(&g_lut);
    st = sc_lut_read_map(path, &g_lut, &err);
    fuzz_check_error(st, &err);
    if (st == SC_OK) {
        FUZZ_CHECK(g_lut.nx >= 2 && g_lut.ny >= 2 && g_lut.nx <= SC_LUT_MAX_NX &&
                   g_lut.ny <= SC_LUT_MAX_NY);
        FUZZ_CHECK(g_lut.px_mm > 0 && g_lut.py_mm > 0);
    }
    return 0;
}
