/* tests/fuzz/fuzz_table_fixture.h — a small valid table built in memory (5 x 5 nodes, pitch
 * 2 mm, a smooth known map) and loaded into an engine, for the daemon-side fuzz targets. */
#ifndef SELFCAL_FUZZ_TABLE_FIXTURE_H
#define SELFCAL_FUZZ_TABLE_FIXTURE_H

#include <math.h>

#include "engine.h"
#include "fuzz_common.h"
#include "selfcal/lut.h"

static inline void fuzz_engine_with_table(sc_engine *e, sc_corr_table *t)
{
    static sc_lut lut;
    static uint8_t buf[1 << 16];
    sc_lut_init(&lut);
    lut.nx = lut.ny = 5;
    lut.x0_mm = lut.y0_mm = -4.0;
    lut.px_mm = lut.py_mm = 2.0;
    for (int i = 0; i < 5; i++)
        for (int j = 0; j < 5; j++) {
            lut.gx_um[i * 5 + j] = 0.3 * sin(0.7 * j) + 0.05 * i;
            lut.gy_um[i * 5 + j] = -0.2 * cos(0.5 * i) + 0.02 * j;
        }
    size_t len = 0;
    sc_error err;
    FUZZ_CHECK(sc_lut_encode(&lut, SC_LUT_ENC_INT32, buf, sizeof buf, &len, &err) == SC_OK);
    FUZZ_CHECK(sc_corr_load(t, buf, len) == SC_CORR_OK);
    sc_engine_init(e, SC_CORR_MEASURE);
    e->table = t;
    e->status = SC_CORR_ST_LOADED;
}

#endif
