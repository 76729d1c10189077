/* grid_artifact_read.c — read a plate error file (`i,j,ax_um,ay_um`, SPEC §1) back as a map on
 * the plate's nominal mark positions, for drawing it and for verifying a compensated machine.
 * Empty ax_um/ay_um (a mark no view measured, SPEC §5) become NaN. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"
#include "selfcal/grid_io.h"
#include "selfcal/stage_map.h"

typedef struct art_row {
    long i, j, line;
    double ax, ay;
} art_row;

sc_status sc_grid_read_artifact(const char *path, double pitch_mm, sc_stage_map *m, sc_error *err)
{
    memset(m, 0, sizeof *m);
    if (!(pitch_mm > 0) || !(pitch_mm <= SC_INPUT_MAX_ABS))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "pitch %g mm is not positive", pitch_mm);
    sc_csv r;
    sc_status st = sc_csv_open(&r, path, err);
    if (st != SC_OK)
        return st;
    art_row *rows = NULL;
    size_t nrows = 0, cap = 0;
    int header = 0, got;
    unsigned char *seen = NULL;
    while ((got = sc_csv_next_line(&r, err)) > 0) {
        if (sc_csv_is_blank(&r) || r.text[0] == '#')
            continue;
        if (sc_csv_split(&r, err) < 0) {
            got = -1;
            break;
        }
        if (!header) {
            if (r.nfields < 4 || strcmp(r.field[0], "i") || strcmp(r.field[1], "j") ||
                strcmp(r.field[2], "ax_um") || strcmp(r.field[3], "ay_um")) {
                st = sc_error_set(err, SC_E_INPUT, path, r.line,
                                  "expected the plate error header 'i,j,ax_um,ay_um'");
                goto fail;
            }
            header = 1;
            continue;
        }
        if (r.nfields < 4) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "expected 4 fields, got %d", r.nfields);
            goto fail;
        }
        if (nrows == cap) {
            cap = cap ? 2 * cap : 256;
            art_row *nr = realloc(rows, cap * sizeof *rows);
            if (!nr) {
                st = sc_error_set(err, SC_E_NOMEM, path, r.line, "out of memory");
                goto fail;
            }
            rows = nr;
        }
        art_row *row = &rows[nrows];
        row->line = r.line;
        row->ax = row->ay = NAN;
        if ((st = sc_csv_long(&r, 0, "i", &row->i, err)) != SC_OK ||
            (st = sc_csv_long(&r, 1, "j", &row->j, err)) != SC_OK)
            goto fail;
        int empty_x = r.field[2][0] == '\0', empty_y = r.field[3][0] == '\0';
        if (empty_x != empty_y) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line, "ax_um and ay_um must be both given or both empty");
            goto fail;
        }
        if (!empty_x && ((st = sc_csv_double(&r, 2, "ax_um", &row->ax, err)) != SC_OK ||
                         (st = sc_csv_double(&r, 3, "ay_um", &row->ay, err)) != SC_OK))
            goto fail;
        if (!empty_x && !(fabs(row->ax) <= SC_INPUT_MAX_ABS && fabs(row->ay) <= SC_INPUT_MAX_ABS)) {
            st = sc_error_set(err, SC_E_INPUT, path, r.line,
                              "plate error beyond 1 m: not a plausible plate");
            goto fail;
        }
        ++nrows;
    }
    if (got < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    int n = (int)lround(sqrt((double)nrows));
    if (!header || nrows == 0 || (size_t)n * (size_t)n != nrows || n % 2 == 0 || n < 3 ||
        n > SC_GRID_MAX_N) {
        st = sc_error_set(err, SC_E_INPUT, path, r.line,
                          "%zu rows do not make an N x N plate with N odd in 3..%d", nrows,
                          SC_GRID_MAX_N);
        goto fail;
    }
    size_t nn = nrows;
    int c = (n - 1) / 2;
    m->nx = m->ny = n;
    m->px_mm = m->py_mm = pitch_mm;
    m->x0_mm = m->y0_mm = -c * pitch_mm;
    double **arr[4] = {&m->gx_um, &m->gy_um, &m->ugx_um, &m->ugy_um};
    for (int a = 0; a < 4; ++a) {
        *arr[a] = malloc(nn * sizeof(double));
        if (!*arr[a]) {
            st = sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
            goto fail;
        }
        for (size_t k = 0; k < nn; ++k)
            (*arr[a])[k] = NAN;
    }
    seen = calloc(nn, 1);
    if (!seen) {
        st = sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
        goto fail;
    }
    for (size_t q = 0; q < nrows; ++q) {
        art_row *row = &rows[q];
        if (row->i < 0 || row->i >= n || row->j < 0 || row->j >= n || seen[row->i * n + row->j]) {
            st = sc_error_set(err, SC_E_INPUT, path, row->line,
                              "mark (%ld,%ld) is off the %dx%d plate or repeated", row->i, row->j,
                              n, n);
            goto fail;
        }
        size_t k = (size_t)row->i * n + (size_t)row->j;
        seen[k] = 1;
        m->gx_um[k] = row->ax;
        m->gy_um[k] = row->ay;
    }
    free(seen);
    free(rows);
    sc_csv_close(&r);
    return SC_OK;
fail:
    free(seen);
    free(rows);
    sc_csv_close(&r);
    sc_stage_map_free(m);
    return st == SC_OK ? SC_E_INTERNAL : st;
}
