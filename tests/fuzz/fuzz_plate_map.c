/* tests/fuzz/fuzz_plate_map.c — libFuzzer target: the two readers of the plate error file
 * `i,j,ax_um,ay_um` (SPEC §1, §5): sc_plate_map_read (io/plate_map.c, the strict reader) and
 * sc_grid_read_artifact (grid/grid_artifact_read.c: the plate error as a map on the nominal
 * mark positions, for `selfcal verify`, `report grid --verify` and `plot map --plate`).
 * Checks beyond "no memory error, no undefined behaviour":
 *   - every failure is a one-line error;
 *   - a plate map read has n odd in 3..SC_PLATE_MAP_MAX_N, each mark's ax, ay both finite within
 *     1 m or both NaN; written by sc_plate_map_fprint and read again it is the same map (values
 *     within the 15 significant digits the writer keeps), and a second write is byte-identical
 *     (the format is a fixed point of read + write);
 *   - an artifact read is an n x n map, n odd in 3..SC_GRID_MAX_N, on the plate-centred nominal
 *     positions at the pitch given, the same NaN pattern in x and y, no uncertainties;
 *   - the readers agree: a file the strict reader accepts with n <= SC_GRID_MAX_N is accepted by
 *     the artifact reader with the same values, and a file the artifact reader accepts is accepted
 *     by the strict reader (one format, one set of rules). */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/csv.h"
#include "selfcal/grid.h"
#include "selfcal/grid_io.h"
#include "selfcal/plate_map.h"
#include "selfcal/stage_map.h"

#define PITCH_MM 2.5

static int same(double a, double b)
{
    return (isnan(a) && isnan(b)) || a == b;
}

static int close15(double a, double b)
{
    return (isnan(a) && isnan(b)) || fabs(a - b) <= 1e-14 * fabs(a);
}

/* sc_plate_map_fprint of m into buf (size *len in, bytes out). */
static void print_map(const sc_plate_map *m, char **buf, size_t *len)
{
    FILE *f = open_memstream(buf, len);
    FUZZ_CHECK(f != NULL);
    sc_plate_map_fprint(f, m);
    FUZZ_CHECK(fclose(f) == 0);
}

static void check_round_trip(const sc_plate_map *m)
{
    char *text = NULL, *text2 = NULL;
    size_t len = 0, len2 = 0;
    print_map(m, &text, &len);
    sc_plate_map back;
    sc_error err;
    memset(&err, 0, sizeof err);
    sc_status st = sc_plate_map_read(fuzz_file(0, "plate.csv", (const uint8_t *)text, len), &back, &err);
    if (st != SC_OK)
        fprintf(stderr, "read back: %s:%ld: %s\n", err.file, err.line, err.msg);
    FUZZ_CHECK(st == SC_OK && back.n == m->n);
    size_t nn = (size_t)m->n * (size_t)m->n;
    for (size_t k = 0; k < nn; ++k)
        FUZZ_CHECK(close15(m->ax_um[k], back.ax_um[k]) && close15(m->ay_um[k], back.ay_um[k]));
    print_map(&back, &text2, &len2);
    FUZZ_CHECK(len == len2 && memcmp(text, text2, len) == 0);
    free(text);
    free(text2);
    sc_plate_map_free(&back);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_path(data, size);
    sc_plate_map pm;
    sc_stage_map am;
    sc_error err, err_p;
    memset(&err_p, 0, sizeof err_p);
    sc_status st_p = sc_plate_map_read(path, &pm, &err_p);
    fuzz_check_error(st_p, &err_p);
    if (st_p == SC_OK) {
        FUZZ_CHECK(pm.n >= 3 && pm.n <= SC_PLATE_MAP_MAX_N && pm.n % 2 == 1);
        size_t nn = (size_t)pm.n * (size_t)pm.n;
        for (size_t k = 0; k < nn; ++k) {
            FUZZ_CHECK(isnan(pm.ax_um[k]) == isnan(pm.ay_um[k]));
            FUZZ_CHECK(isnan(pm.ax_um[k]) ||
                       (fabs(pm.ax_um[k]) <= SC_INPUT_MAX_ABS && fabs(pm.ay_um[k]) <= SC_INPUT_MAX_ABS));
        }
    } else {
        FUZZ_CHECK(pm.ax_um == NULL && pm.ay_um == NULL);
    }

    memset(&err, 0, sizeof err);
    sc_status st_a = sc_grid_read_artifact(path, PITCH_MM, &am, &err);
    fuzz_check_error(st_a, &err);
    if (st_a == SC_OK) {
        int n = am.nx, c = (n - 1) / 2;
        FUZZ_CHECK(am.ny == n && n >= 3 && n <= SC_GRID_MAX_N && n % 2 == 1);
        FUZZ_CHECK(am.px_mm == PITCH_MM && am.py_mm == PITCH_MM);
        FUZZ_CHECK(am.x0_mm == -c * PITCH_MM && am.y0_mm == -c * PITCH_MM);
        size_t nn = (size_t)n * (size_t)n;
        for (size_t k = 0; k < nn; ++k) {
            FUZZ_CHECK(isnan(am.gx_um[k]) == isnan(am.gy_um[k]));
            FUZZ_CHECK(isnan(am.ugx_um[k]) && isnan(am.ugy_um[k]));
        }
    }

    /* one format, one set of rules */
    if (st_a == SC_OK && st_p != SC_OK)
        fprintf(stderr, "the artifact reader accepts what the plate map reader refuses: %s:%ld: %s\n",
                err_p.file, err_p.line, err_p.msg);
    FUZZ_CHECK(st_a != SC_OK || st_p == SC_OK);
    if (st_p == SC_OK && pm.n <= SC_GRID_MAX_N) {
        if (st_a != SC_OK)
            fprintf(stderr, "the artifact reader refuses what the plate map reader accepts: %s:%ld: %s\n",
                    err.file, err.line, err.msg);
        FUZZ_CHECK(st_a == SC_OK && am.nx == pm.n);
        size_t nn = (size_t)pm.n * (size_t)pm.n;
        for (size_t k = 0; k < nn; ++k)
            FUZZ_CHECK(same(am.gx_um[k], pm.ax_um[k]) && same(am.gy_um[k], pm.ay_um[k]));
    }
    if (st_p == SC_OK) {
        check_round_trip(&pm);
        sc_plate_map_free(&pm);
    }
    if (st_a == SC_OK)
        sc_stage_map_free(&am);
    return 0;
}
