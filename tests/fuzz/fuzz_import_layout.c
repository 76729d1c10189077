/* tests/fuzz/fuzz_import_layout.c — libFuzzer target: the layouts of sc_table_read_layout
 * (SPEC §10a): one row per axis (with and without a nominal column), --where filters,
 * placeholders, no header line, items in columns, and the text encodings.
 *
 * Input: two control bytes, then the export. Byte 0: bits 0-1 the shape (0 one point per row,
 * 1 one row per axis, 2 items in columns, 3 one row per axis with a nominal column), bit 2 no
 * header line (columns by number), bit 3 a filter (type = Circle), bit 4 placeholders ('-----',
 * 'n. g.'), bits 5-6 the encoding (UTF-8, CP1252, Latin-1, Shift-JIS), bit 7 axis names
 * 'PosX,PosY' (else X, Y). Byte 1: bits 0-3 the largest row count taken - 1 (x 16).
 * Checks beyond "no memory error, no undefined behaviour": every failure is a one-line error with
 * nothing left allocated; a table read holds 1..max rows of finite values within
 * SC_INPUT_MAX_ABS, lines that are file lines (>= 1), a decimal mark, and notes that add up
 * (the named header fields no more than the fields). */
#include <math.h>

#include "fuzz_reader_check.h"
#include "selfcal/csv.h"
#include "selfcal/import.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    uint8_t c0 = data[0], c1 = data[1];
    const char *path = fuzz_path(data + 2, size - 2);
    int shape = c0 & 3, by_number = (c0 >> 2) & 1;
    sc_table_layout lay;
    memset(&lay, 0, sizeof lay);
    lay.no_header = by_number;
    if (c0 & 8) {
        lay.n_where = 1;
        lay.where_col[0] = by_number ? "4" : "type";
        lay.where_value[0] = "Circle";
    }
    if (c0 & 16) {
        lay.n_missing = 2;
        lay.missing[0] = "-----";
        lay.missing[1] = "n. g.";
    }
    lay.encoding = (sc_table_encoding)((c0 >> 5) & 3);
    const char *names[2] = {"x", "y"};
    if (shape == 1 || shape == 3) {
        lay.id_col = by_number ? "1" : "id";
        lay.axis_col = by_number ? "2" : "axis";
        lay.value_col = by_number ? "3" : "meas";
        if (shape == 3)
            lay.nominal_col = by_number ? "5" : "nominal";
        names[0] = c0 & 0x80 ? "PosX" : "X";
        names[1] = c0 & 0x80 ? "PosY" : "Y";
    } else if (by_number) {
        names[0] = "2";
        names[1] = "3";
    }
    lay.transpose = shape == 2;
    if (lay.transpose)
        lay.n_where = 0; /* not with items in columns */
    int nc = shape == 3 ? 4 : 2;
    const double scale[4] = {1e-3, 1e-3, 1, 1};
    long max_rows = 16 * ((c1 & 15) + 1);
    sc_table t;
    sc_table_notes notes;
    sc_error err;
    memset(&err, 0, sizeof err);
    sc_status st = sc_table_read_layout(path, 2, names, scale, max_rows, &lay, &notes, &t, &err);
    fuzz_check_error(st, &err);
    if (st != SC_OK) {
        FUZZ_CHECK(t.value == NULL && t.line == NULL);
        return 0;
    }
    FUZZ_CHECK(t.n_rows >= 1 && t.n_rows <= max_rows && t.n_cols == nc);
    FUZZ_CHECK(t.decimal == '.' || t.decimal == ',');
    FUZZ_CHECK(notes.named_fields <= notes.header_fields && notes.decimals >= 0);
    for (long r = 0; r < t.n_rows; ++r) {
        FUZZ_CHECK(t.line[r] >= 1);
        for (int k = 0; k < nc; ++k) {
            double v = t.value[r * nc + k];
            FUZZ_CHECK(isfinite(v) && fabs(v) <= SC_INPUT_MAX_ABS * scale[k]);
        }
    }
    sc_table_free(&t);
    return 0;
}
