/* grid_artifact_read.c — read a plate error file (`i,j,ax_um,ay_um`, SPEC §1) back as a map on
 * the plate's nominal mark positions, for drawing it and for verifying a compensated machine.
 * The file is read by the one strict reader of the format (sc_plate_map_read, io/plate_map.c);
 * this keeps only the conversion. (It had a reader of its own, laxer: fuzz_plate_map found it
 * taking the first four fields of a row with six, i.e. a corrupted line, as a mark.)
 * Empty ax_um/ay_um (a mark no view measured, SPEC §5) become NaN. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"
#include "selfcal/grid.h"
#include "selfcal/grid_io.h"
#include "selfcal/plate_map.h"
#include "selfcal/stage_map.h"

sc_status sc_grid_read_artifact(const char *path, double pitch_mm, sc_stage_map *m, sc_error *err)
{
    memset(m, 0, sizeof *m);
    if (!(pitch_mm > 0) || !(pitch_mm <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "pitch %g mm is not positive", pitch_mm);
    sc_plate_map pm;
    sc_status st = sc_plate_map_read(path, &pm, err);
    if (st != SC_OK)
        return st;
    int n = pm.n, c = (n - 1) / 2;
    if (n > SC_GRID_MAX_N) {
        sc_plate_map_free(&pm);
        return sc_error_set(err, SC_E_INPUT, path, 0,
                            "a plate of %d x %d marks; a grid calibration has at most %d per side",
                            n, n, SC_GRID_MAX_N);
    }
    size_t nn = (size_t)n * (size_t)n;
    m->nx = m->ny = n;
    m->px_mm = m->py_mm = pitch_mm;
    m->x0_mm = m->y0_mm = -c * pitch_mm;
    m->gx_um = pm.ax_um; /* the arrays move into the map */
    m->gy_um = pm.ay_um;
    m->ugx_um = malloc(nn * sizeof(double));
    m->ugy_um = malloc(nn * sizeof(double));
    if (!m->ugx_um || !m->ugy_um) {
        sc_stage_map_free(m);
        return sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    for (size_t k = 0; k < nn; ++k)
        m->ugx_um[k] = m->ugy_um[k] = NAN;
    return SC_OK;
}
