/* Unit tests of selfcal/import.h: delimiter and decimal-mark detection of sc_table_read, and the
 * placement fit and numbering of sc_grid_import_assign against positions built here. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cmocka.h>

#include "selfcal/csv.h"
#include "selfcal/import.h"

static void tmp_path(char *buf, size_t n, const char *name)
{
    mkdir(SELFCAL_TEST_TMP, 0777);
    snprintf(buf, n, "%s/import_%s", SELFCAL_TEST_TMP, name);
}

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    fputs(text, fp);
    fclose(fp);
}

static const char *const XY[2] = {"x", "y"};

/* The same numbers in three dialects read back equal, with the delimiter and mark found. */
static void test_table_dialects(void **state)
{
    (void)state;
    static const struct {
        const char *text;
        char delim, dec;
    } cases[] = {
        {"# comment\nNr;X;Y\n1;1,5;-2,25\n2;3;4,125\n", ';', ','},
        {"Nr\t\"X\"\tY\r\n1\t1.5\t-2.25\r\n\r\n2\t3\t4.125\r\n", '\t', '.'},
        {"nr, x , y\n1,1.5,-2.25\n2,3,4.125\n", ',', '.'},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        char path[512];
        tmp_path(path, sizeof path, "dialect.csv");
        write_text(path, cases[k].text);
        sc_table t;
        sc_error err;
        const double scale[2] = {1e-3, 1e-3};
        assert_int_equal(sc_table_read(path, 2, XY, scale, &t, &err), SC_OK);
        assert_int_equal(t.n_rows, 2);
        assert_int_equal(t.delimiter, cases[k].delim);
        assert_int_equal(t.decimal, cases[k].dec);
        assert_true(fabs(t.value[0] - 1.5e-3) < 1e-18 && fabs(t.value[1] + 2.25e-3) < 1e-18);
        assert_true(fabs(t.value[2] - 3e-3) < 1e-18 && fabs(t.value[3] - 4.125e-3) < 1e-18);
        sc_table_free(&t);
    }
}

/* A machine's preamble (program, date, operator) before the header line is skipped, whatever
 * it holds but data; the rows keep their own line numbers; more than 100 such lines are not a
 * preamble. */
static void test_table_preamble(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "preamble.csv");
    write_text(path, "Program: plate_11x11\nDate;2026-11-27;Operator: A. B.\n\n# comment\n"
                     "Nr;X;Y;Z\n1;1,5;-2,25;0\n2;3;4,125;0\n");
    sc_table t;
    sc_error err;
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_int_equal(t.header_line, 5);
    assert_int_equal(t.n_rows, 2);
    assert_int_equal(t.line[0], 6);
    assert_int_equal(t.line[1], 7);
    assert_true(t.value[0] == 1.5 && t.value[3] == 4.125 && t.decimal == ',');
    sc_table_free(&t);
    char *text = malloc(101 * 24 + 64);
    for (int lines = 100; lines <= 101; ++lines) { /* 100 preamble lines are read, 101 not */
        char *q = text;
        for (int k = 0; k < lines; ++k)
            q += sprintf(q, "Note %d: none\n", k);
        strcpy(q, "x;y\n1;2\n");
        write_text(path, text);
        sc_status st = sc_table_read(path, 2, XY, NULL, &t, &err);
        if (lines == 100) {
            assert_int_equal(st, SC_OK);
            assert_int_equal(t.header_line, 101);
            sc_table_free(&t);
        } else {
            assert_int_equal(st, SC_E_INPUT);
            assert_int_equal(err.line, 1);
        }
    }
    free(text);
}

/* Each bad table names its line. */
static void test_table_errors(void **state)
{
    (void)state;
    static const struct {
        const char *text;
        long line;
        const char *msg;
    } cases[] = {
        {"a;b\n1;2\n", 1, "no column named 'x'"},
        {"x;y\n1,5;2\n1.5;2\n", 3, "mixed decimal marks"},
        {"x;y\n1,5;2.5\n", 2, "mixed decimal marks"},
        {"x,y\n1,5,2\n", 2, "3 fields"},
        {"x;y;x\n1;2;3\n", 1, "two columns are named 'x'"},
        {"x;y\n1;\n", 2, "'' is not a number"},
        {"x;y\n1;2e7\n", 2, "beyond any plausible"},
        {"x;y\n", 1, "no data lines"},
        /* no line names both: the first line naming one of them is the header that failed */
        {"Program: P\nDate: 2026\nnr;xx;y\n1;2;3\n", 3, "no column named 'x'"},
        /* a preamble line without any of them, then data: the first line */
        {"Program: P\n1;2\n", 1, "no column named 'x'"},
        {"1;2\nx;y\n1;2\n", 1, "no column named 'x'"}, /* data before the header */
        {"Program: P\nOperator: Q\n", 1, "no column named 'x'"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        char path[512];
        tmp_path(path, sizeof path, "bad.csv");
        write_text(path, cases[k].text);
        sc_table t;
        sc_error err;
        assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_E_INPUT);
        assert_int_equal(err.line, cases[k].line);
        if (!strstr(err.msg, cases[k].msg))
            fail_msg("case %zu: '%s' lacks '%s'", k, err.msg, cases[k].msg);
        assert_null(t.value);
    }
}

static const char *const XY2[2] = {"2", "3"};

/* What machines write: a '#' header (the point number's column) with '#' rows; columns given
 * by number where two share a name; columns aligned by blanks; and the lines around the rows
 * that are skipped and counted (units, the header again, ";;;", a failed feature, a summary
 * row, a footer), each kind at its first line. */
static void test_table_machine_lines(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "machine.csv");
    sc_table t;
    sc_error err;
    write_text(path, "# x y (a comment, not the header)\n#;x;y\n# units mm\n#1;1;2\n#2;3;4\n17;5;6\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_int_equal(t.header_line, 2);
    assert_int_equal(t.n_rows, 3);
    assert_true(t.value[4] == 5 && t.value[5] == 6);
    sc_table_free(&t);
    /* "#<digit>" rows are rows, not comments: more of them than the CSV reader's limit on
     * comment lines in a row (SC_CSV_MAX_SKIP_RUN) read */
    {
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fputs("#;x;y\n", f);
        for (long k = 1; k <= SC_CSV_MAX_SKIP_RUN + 5; ++k)
            fprintf(f, "#%ld;%ld;1\n", k, k % 1000);
        fclose(f);
        assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
        assert_int_equal(t.n_rows, SC_CSV_MAX_SKIP_RUN + 5);
        sc_table_free(&t);
    }
    /* a comment spelling the columns above the real header stays a comment */
    write_text(path, "# x y\nx;y\n1;2\n3;4\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_true(t.header_line == 2 && t.n_rows == 2);
    sc_table_free(&t);
    write_text(path, "Name;x;y;x;y\nA;1;2;3;4\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_E_INPUT);
    if (!strstr(err.msg, "two columns are named 'x' (columns 2 and 4: give the column by its number)"))
        fail_msg("%s", err.msg);
    assert_int_equal(sc_table_read(path, 2, XY2, NULL, &t, &err), SC_OK);
    assert_true(t.n_rows == 1 && t.value[0] == 1 && t.value[1] == 2);
    sc_table_free(&t);
    /* by number: the header is the line right before the first row, whatever the preamble */
    write_text(path, "# Created by CMM software\nMachine: Zeiss Prismo 7\nMerkmal;Ist;;Soll;\n"
                     "Name;X;Y;X;Y\n1;1;2;3;4\n2;5;6;7;8\n");
    assert_int_equal(sc_table_read(path, 2, XY2, NULL, &t, &err), SC_OK);
    assert_true(t.header_line == 4 && t.n_rows == 2 && t.value[2] == 5 && t.value[3] == 6);
    sc_table_free(&t);
    /* a damaged row before the first good one is its error, not preamble */
    write_text(path, "Name;x;y;x;y\nP1;2000,87.6;1;0;0\nP2;1;2;0;0\n");
    assert_int_equal(sc_table_read(path, 2, XY2, NULL, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 2);
    write_text(path, "Name;x;y;x;y\nP1;;1;0;0\nP2;1;2;0;0\n");
    assert_int_equal(sc_table_read(path, 2, XY2, NULL, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 2);
    write_text(path, "1;2000,87.6;2\n2;3;4\n"); /* a damaged first row, no header: refused */
    assert_int_equal(sc_table_read(path, 2, XY2, NULL, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 1);
    write_text(path, "1;1;2\n2;3;4\n"); /* no header at all: refused, no row dropped */
    assert_int_equal(sc_table_read(path, 2, XY2, NULL, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 1);
    write_text(path, "Protocol 4711\n17 05 2024\n20.1 20.3\nNr;x;y\n1;1;2\n"); /* blank numbers: preamble */
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_true(t.header_line == 4 && t.n_rows == 1);
    sc_table_free(&t);
    write_text(path, "Protocol  plate 5\n\nNr     x       y    \n1    1.5     2\n2  -3,25   4e1\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_E_INPUT); /* mixed marks */
    write_text(path, "Protocol  plate 5\n\nNr     x       y    \n1    1.5     2\n2  -3.25   4e1\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_int_equal(t.delimiter, ' ');
    assert_int_equal(t.header_line, 3);
    assert_true(t.n_rows == 2 && t.value[2] == -3.25 && t.value[3] == 40);
    sc_table_free(&t);
    write_text(path, "Nr;x;y;z\n;MM;MM;MM\n1;1;2;0\nNr;x;y;z\n;;;\n2;3;4;0\n3a;;;\nNr;x;y;z\n"
                     "4;5;6;0\nMean:;3;4;0\n*** end ***\nOperator\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 3);
    assert_true(t.value[4] == 5 && t.value[5] == 6);
    assert_int_equal(t.units_line, 2);
    assert_true(t.n_header_repeats == 2 && t.header_repeat_line == 4);
    assert_true(t.n_no_values == 1 && t.no_values_line == 7);
    assert_true(t.n_summary == 1 && t.summary_line == 10);
    assert_true(t.n_footer == 2 && t.footer_line == 11);
    sc_table_free(&t);
    /* a row after a footer-like line: that line is the error */
    write_text(path, "Nr;x;y\n1;1;2\n*** page 2 ***\n2;3;4\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 3);
    /* a damaged last row is an error, not a footer; so is a row missing one value, whatever the
     * column order; a statistic word in a row followed by rows is a row's label */
    static const char *const YX[2] = {"y", "x"};
    static const struct {
        const char *text;
        long line;
    } bad[] = {{"Nr;x;y\n1;1.0;2.0\n2;1.5\n", 3},     {"Nr;x;y\n1;1;2\n2;abc;3\n", 3},
               {"Nr;x;y\n1;1;2\n2;nan;3\n", 3},       {"Nr;x;y\nP1;1;2\nP2;1.5\n", 3},
               {"Nr;x;y\n1;1.0;2.0\n2;;3\n3;1;2\n", 3}, {"Nr;x;y\n1;1;2\nP1;n/a;2.0\n", 3}};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k)
        for (int order = 0; order < 2; ++order) {
            write_text(path, bad[k].text);
            if (sc_table_read(path, 2, order ? YX : XY, NULL, &t, &err) != SC_E_INPUT ||
                err.line != bad[k].line)
                fail_msg("case %zu order %d: accepted or wrong line (%ld): %s", k, order, err.line,
                         err.msg);
        }
    write_text(path, "Nr;Type;x;y\n1;Circle;1;2\n2;Max;3;4\n3;Circle;5;6\n");
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_true(t.n_rows == 3 && t.n_summary == 0);
    sc_table_free(&t);
    write_text(path, "Nr;x;y\n;mm;mm\n1;1;2\nNr;x;y\n;mm;mm\n2;1;2\n"); /* units again at a page break */
    assert_int_equal(sc_table_read(path, 2, XY, NULL, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 2);
    sc_table_free(&t);
}

/* sc_table_read_max takes max_rows rows and refuses the next at its own line, nothing read past
 * it; a limit outside 1..SC_TABLE_MAX_ROWS is refused before the file is opened. */
static void test_table_max_rows(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "rows.csv");
    write_text(path, "# four rows\nx;y\n1;2\n3;4\n5;6\n7;8\n9;1.5.5\n");
    sc_table t;
    sc_error err;
    assert_int_equal(sc_table_read_max(path, 2, XY, NULL, 3, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 6); /* the fourth row, not the bad line after it */
    if (!strstr(err.msg, "more than 3 rows"))
        fail_msg("'%s'", err.msg);
    assert_null(t.value);
    assert_int_equal(sc_table_read_max(path, 2, XY, NULL, 4, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 7); /* four taken, the fifth row's number is malformed */
    write_text(path, "x;y\n1;2\n3;4\n5;6\n");
    assert_int_equal(sc_table_read_max(path, 2, XY, NULL, 3, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 3);
    assert_true(t.value[4] == 5 && t.value[5] == 6);
    sc_table_free(&t);
    assert_int_equal(sc_table_read_max(path, 2, XY, NULL, 0, &t, &err), SC_E_INPUT);
    assert_int_equal(sc_table_read_max(path, 2, XY, NULL, SC_TABLE_MAX_ROWS + 1, &t, &err), SC_E_INPUT);
    assert_int_equal(sc_table_read_max(path, 2, XY, NULL, SC_TABLE_MAX_ROWS, &t, &err), SC_OK);
    sc_table_free(&t);
}

/* A rot=90, shift=1,-1 view on a 9x11 stage, placed off by (0.1, -0.05) mm and 3 mrad, shuffled,
 * with a missing mark and a stray point: every point gets its mark, the placement is found. */
static void test_assign(void **state)
{
    (void)state;
    sc_grid_import_params p;
    sc_grid_import_defaults(&p, 7, 2.0);
    p.origin_mm[0] = 50;
    p.origin_mm[1] = -20;
    p.stage_nx = 9;
    p.stage_ny = 11;
    sc_grid_view v;
    memset(&v, 0, sizeof v);
    v.rot_deg = 90;
    v.shift_x = 1;
    v.shift_y = -1;
    const double th = 3e-3, tx = 0.1, ty = -0.05;
    double x[64], y[64];
    long lines[64], truth[64], n = 0;
    for (int i = 0; i < 7; ++i)
        for (int j = 0; j < 7; ++j) {
            if (i == 2 && j == 5)
                continue; /* missing */
            int ni, nj;
            assert_true(sc_grid_import_mark_node(&p, &v, i, j, &ni, &nj));
            double nx = (nj - 4) * 2.0, ny = (ni - 5) * 2.0; /* from the stage centre */
            long slot = (n * 17) % 48; /* a fixed shuffle of the 48 points */
            x[slot] = 50 + tx + cos(th) * nx - sin(th) * ny + 1e-4 * sin(i + 2.0 * j);
            y[slot] = -20 + ty + sin(th) * nx + cos(th) * ny + 1e-4 * cos(3.0 * i - j);
            truth[slot] = i * 7 + j;
            ++n;
        }
    assert_int_equal(n, 48);
    x[48] = x[5] + 1.0, y[48] = y[5] - 1.0, truth[48] = -1; /* stray */
    n = 49;
    for (long k = 0; k < n; ++k)
        lines[k] = k + 2;
    long point_mark[64], mark_point[49];
    double work[160];
    assert_true(sc_grid_import_work_doubles(n) <= 160);
    sc_grid_import_fit fit;
    sc_error err;
    assert_int_equal(sc_grid_import_assign(&p, &v, n, x, y, lines, "t.csv", 1, point_mark,
                                           mark_point, &fit, work, &err),
                     SC_OK);
    for (long k = 0; k < n; ++k)
        assert_int_equal(point_mark[k], truth[k]);
    assert_int_equal(mark_point[2 * 7 + 5], -1);
    assert_int_equal(fit.n_marks, 49);
    assert_int_equal(fit.n_assigned, 48);
    assert_int_equal(fit.n_left_out, 1);
    assert_true(fabs(fit.theta_urad - 3000) < 20);
    assert_true(fabs(fit.tx_um - 100) < 1 && fabs(fit.ty_um + 50) < 1);

    /* a second point on a mark: bad input at the later line */
    x[48] = x[7] + 0.01, y[48] = y[7];
    assert_int_equal(sc_grid_import_assign(&p, &v, n, x, y, lines, "t.csv", 1, point_mark,
                                           mark_point, &fit, work, &err),
                     SC_E_INPUT);
    assert_int_equal(err.line, 50);
    assert_non_null(strstr(err.msg, "point on line 9 both fall on mark"));

    /* too few marks: every point half a pitch off diagonally (a wrong origin, say) */
    for (long k = 0; k < n; ++k)
        x[k] += 1.0, y[k] += 1.0;
    assert_int_equal(sc_grid_import_assign(&p, &v, n, x, y, lines, "t.csv", 1, point_mark,
                                           mark_point, &fit, work, &err),
                     SC_E_INPUT);
    assert_int_equal(err.line, 1);
    assert_non_null(strstr(err.msg, "only"));
}

/* Read text with layout lay: status, and the table (freed by the caller when SC_OK). */
static sc_status read_layout(const char *text, int n_cols, const char *const *names,
                             const sc_table_layout *lay, sc_table_notes *notes, sc_table *t,
                             sc_error *err)
{
    char path[512];
    tmp_path(path, sizeof path, "layout.csv");
    write_text(path, text);
    return sc_table_read_layout(path, n_cols, names, NULL, 1000, lay, notes, t, err);
}

/* Summary rows under a table in the languages metrology software writes: skipped, however many
 * (a Mittelwert row followed by Stabw. was read as a point before Stabw. was known). */
static void test_summary_words(void **state)
{
    (void)state;
    static const char *const rows[] = {
        "Mittelwert;1,5;2,5\nStabw.;0,5;0,5\nMin;1;2\nMax;2;3\n",
        "Moyenne;1,5;2,5\n\xC3\x89" "cart type;0,5;0,5\n\xC3\x89tendue;1;1\n",
        "Media;1,5;2,5\nDeviazione standard;0,5;0,5\nMinimo;1;2\nMassimo;2;3\n",
        "\xE5\xB9\xB3\xE5\x9D\x87;1,5;2,5\n\xE6\xA8\x99\xE6\xBA\x96\xE5\x81\x8F"
        "\xE5\xB7\xAE;0,5;0,5\n\xE6\x9C\x80\xE5\xA4\xA7;2;3\n", /* 平均, 標準偏差, 最大 */
    };
    for (size_t k = 0; k < sizeof rows / sizeof rows[0]; ++k) {
        char text[512];
        snprintf(text, sizeof text, "Nr;X;Y\n1;1;2\n2;2;3\n%s", rows[k]);
        sc_table t;
        sc_table_notes n;
        sc_error err;
        assert_int_equal(read_layout(text, 2, XY, NULL, &n, &t, &err), SC_OK);
        assert_int_equal(t.n_rows, 2);
        assert_true(t.n_summary >= 3);
        sc_table_free(&t);
    }
}

/* One row per axis: points gathered by ID in the order of their first rows, other axes
 * counted, a point with one coordinate left out and counted, nominals with them; an ID with two
 * X rows is bad input. */
static void test_layout_long(void **state)
{
    (void)state;
    static const char *const AX[2] = {"X", "Y"};
    sc_table_layout lay;
    memset(&lay, 0, sizeof lay);
    lay.id_col = "FEATURE";
    lay.axis_col = "AXIS";
    lay.value_col = "MEAS";
    sc_table t;
    sc_table_notes n;
    sc_error err;
    const char *text = "Part Name, P\n\nFEATURE, AXIS, NOMINAL, MEAS\n"
                       "\"C2\",\"y\",\"1.0\",\"1.25\"\n\"C1\",\"X\",\"0.0\",\"0.5\"\n"
                       "\"C1\",\"Z\",\"0.0\",\"9\"\n\"C2\",\"X\",\"1.0\",\"1.5\"\n"
                       "\"C1\",\"Y\",\"0.0\",\"-0.5\"\n\"C3\",\"X\",\"2.0\",\"2.5\"\n";
    assert_int_equal(read_layout(text, 2, AX, &lay, &n, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 2);
    assert_int_equal(t.header_line, 3);
    assert_true(t.value[0] == 1.5 && t.value[1] == 1.25); /* C2 first: its first row is first */
    assert_true(t.value[2] == 0.5 && t.value[3] == -0.5);
    assert_int_equal(t.line[0], 4);
    assert_int_equal(n.n_other_axis, 1);
    assert_int_equal(n.n_incomplete, 1);
    assert_int_equal(n.incomplete_line, 9);
    assert_string_equal(n.incomplete_id, "C3");
    assert_string_equal(n.incomplete_axis, "Y");
    assert_int_equal(n.decimals, 2);
    sc_table_free(&t);
    lay.nominal_col = "NOMINAL"; /* 2 * n_cols columns: values, then nominals */
    assert_int_equal(read_layout(text, 2, AX, &lay, &n, &t, &err), SC_OK);
    assert_int_equal(t.n_cols, 4);
    assert_true(t.value[2] == 1.0 && t.value[3] == 1.0);
    sc_table_free(&t);
    lay.nominal_col = NULL;
    /* a line without a digit and another field count (a footer, a title): skipped, counted */
    const char *foot = "ID;AXIS;MEAS\nC1;X;1\n*** End of report ***\nC1;Y;2\n";
    lay.id_col = "ID";
    assert_int_equal(read_layout(foot, 2, AX, &lay, &n, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 1);
    assert_int_equal(t.n_footer, 1);
    assert_int_equal(t.footer_line, 3);
    sc_table_free(&t);
    assert_int_equal(read_layout("ID;AXIS;MEAS\nC1;X;1\nC1;2\n", 2, AX, &lay, &n, &t, &err),
                     SC_E_INPUT); /* a damaged row (a digit) is an error */
    assert_non_null(strstr(err.msg, "2 fields, the header line (line 1) has 3"));
    lay.id_col = "FEATURE";
    const char *twice = "ID;AXIS;MEAS\nC1;X;1\nC1;Y;2\nC1;X;3\n";
    lay.id_col = "ID";
    assert_int_equal(read_layout(twice, 2, AX, &lay, &n, &t, &err), SC_E_INPUT);
    assert_int_equal(err.line, 4);
    assert_int_equal(read_layout(twice, 2, AX, &lay, &n, &t, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "'C1' has a second X row"));
    lay.value_col = NULL; /* the three go together */
    assert_int_equal(read_layout(twice, 2, AX, &lay, &n, &t, &err), SC_E_INPUT);
}

/* --where, --missing, the header's trailing empty field and an unlabelled trailing text field. */
static void test_layout_filters(void **state)
{
    (void)state;
    sc_table_layout lay;
    memset(&lay, 0, sizeof lay);
    lay.n_where = 1;
    lay.where_col[0] = "type";
    lay.where_value[0] = "circle";
    lay.n_missing = 1;
    lay.missing[0] = "-----";
    sc_table t;
    sc_table_notes n;
    sc_error err;
    const char *text = "id\ttype\tx\ty\t\nP\tPlane\t0\t0\nC1\tCircle\t1\t2\nC2\tCircle\t-----\t-----\n"
                       "C3\tCircle\t3\t4\t--*|--\n";
    assert_int_equal(read_layout(text, 2, XY, &lay, &n, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 2);
    assert_true(t.value[2] == 3 && t.value[3] == 4);
    assert_int_equal(n.n_filtered, 1);
    assert_int_equal(n.filtered_line, 2);
    assert_int_equal(n.n_placeholder, 2);
    assert_int_equal(t.n_no_values, 1);
    assert_int_equal(n.header_fields, 5);
    assert_int_equal(n.named_fields, 4);
    assert_int_equal(n.n_ragged, 0); /* C3's bar sits under the header's empty name */
    sc_table_free(&t);
    const char *bar = "x;y\n1;2;--*|--\n3;4;-*--|--\n";
    assert_int_equal(read_layout(bar, 2, XY, NULL, &n, &t, &err), SC_OK);
    assert_int_equal(n.n_ragged, 2);
    assert_int_equal(n.ragged_line, 2);
    assert_int_equal(n.ragged_fields, 3);
    sc_table_free(&t);
    /* a number in the unlabelled field is still an error */
    const char *bad = "x;y\n1;2;3\n";
    assert_int_equal(read_layout(bad, 2, XY, &lay, &n, &t, &err), SC_E_INPUT);
}

/* No header line (columns by number), items in columns, and an encoding. */
static void test_layout_shapes(void **state)
{
    (void)state;
    static const char *const N23[2] = {"2", "3"};
    sc_table_layout lay;
    memset(&lay, 0, sizeof lay);
    lay.no_header = true;
    sc_table t;
    sc_table_notes n;
    sc_error err;
    assert_int_equal(read_layout("P1;1,5;2\nP2;3;4,25\n", 2, N23, &lay, &n, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 2);
    assert_int_equal(t.header_line, 0);
    assert_true(t.value[0] == 1.5 && t.value[3] == 4.25);
    sc_table_free(&t);
    assert_int_equal(read_layout("P1;1,5;2\n", 2, XY, &lay, &n, &t, &err), SC_E_INPUT);
    memset(&lay, 0, sizeof lay);
    lay.transpose = true;
    assert_int_equal(read_layout("Merkmal;P1;P2;Mittelwert\nX;1;2;1,5\nZ;0;0;0\nY;3;4;3,5\n", 2,
                                 XY, &lay, &n, &t, &err), SC_OK);
    assert_int_equal(t.n_rows, 2);
    assert_int_equal(t.n_summary, 1);
    assert_true(t.value[0] == 1 && t.value[1] == 3 && t.value[2] == 2 && t.value[3] == 4);
    sc_table_free(&t);
    static const char *const DE[2] = {"X-Ist [\xC2\xB5m]", "Y"};
    memset(&lay, 0, sizeof lay);
    const char *cp = "Me\xDF" "punkt;X-Ist [\xB5m];Y\n1;2;3\n";
    assert_int_equal(read_layout(cp, 2, DE, &lay, &n, &t, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "not UTF-8"));
    lay.encoding = SC_ENC_CP1252;
    assert_int_equal(read_layout(cp, 2, DE, &lay, &n, &t, &err), SC_OK);
    assert_true(t.value[0] == 2 && t.value[1] == 3);
    sc_table_free(&t);
    lay.encoding = SC_ENC_SHIFT_JIS; /* 0x81 0x7F is no Shift-JIS character */
    assert_int_equal(read_layout("x;y\n\x81\x7f;1\n", 2, XY, &lay, &n, &t, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "not shift-jis text"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_table_dialects),
        cmocka_unit_test(test_table_errors),
        cmocka_unit_test(test_table_preamble),
        cmocka_unit_test(test_table_max_rows),
        cmocka_unit_test(test_table_machine_lines),
        cmocka_unit_test(test_summary_words),
        cmocka_unit_test(test_layout_long),
        cmocka_unit_test(test_layout_filters),
        cmocka_unit_test(test_layout_shapes),
        cmocka_unit_test(test_assign),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
