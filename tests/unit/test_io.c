/* Unit tests of io/ and of the declarative header parser (common/header.c): the stage map's one
 * reader and writer (round trips, rectangles, every rule of selfcal/stage_map.h with its line),
 * and the header table (types, ranges, duplicates, missing keys, FILE:LINE). */
#include <limits.h>
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

#include "selfcal/grid_io.h"
#include "selfcal/header.h"
#include "selfcal/plate_map.h"
#include "selfcal/profile_file.h"
#include "selfcal/stage_map.h"
#include "selfcal/number.h"
#include "selfcal/rng.h"
#include "../../libselfcal/src/io/io_internal.h" /* the writers' row formatter (two threads) */

static void tmp_path(char *buf, size_t n, const char *name)
{
    mkdir(SELFCAL_TEST_TMP, 0777);
    snprintf(buf, n, "%s/io_%s", SELFCAL_TEST_TMP, name);
}

static void write_text(const char *path, const char *text)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    fputs(text, fp);
    fclose(fp);
}

/* ---- header parser ---- */

typedef struct hdr {
    long n;
    double s_mm, sigma;
    double origin[2];
    long stage[2];
} hdr;

static const sc_header_key keys[] = {
    {"N", SC_HEADER_LONG, offsetof(hdr, n), 1, 3, 1000, 0},
    {"s_mm", SC_HEADER_DOUBLE, offsetof(hdr, s_mm), 1, 0, 1e6, SC_HEADER_MIN_EXCLUSIVE},
    {"sigma_um", SC_HEADER_DOUBLE, offsetof(hdr, sigma), 0, 0, 1e6, 0},
    {"origin_mm", SC_HEADER_DOUBLE_PAIR, offsetof(hdr, origin), 0, -1e6, 1e6, 0},
    {"stage", SC_HEADER_LONG_PAIR, offsetof(hdr, stage), 0, 3, 99, 0},
};

static void test_header_good(void **state)
{
    (void)state;
    hdr h = {0, 0, -1, {7, 8}, {0, 0}};
    sc_header p;
    sc_header_init(&p, keys, 5, &h);
    sc_error err;
    sc_error_clear(&err);
    const char *lines[] = {"# selfcal-x v1", "#  N = 25 ", "# s_mm=0.5", "# a free comment",
                           "# unknown = 3", "# stage = 5, 7", "# view 0: rot=0 shift=0,0"};
    int expect_used[] = {0, 1, 1, 0, 0, 1, 0};
    for (int k = 0; k < 7; ++k) {
        bool used = !expect_used[k]; /* the call must write it */
        assert_int_equal(sc_header_line(&p, "f.csv", k + 1, lines[k], &used, &err), SC_OK);
        assert_int_equal(used, expect_used[k]);
    }
    assert_int_equal(sc_header_finish(&p, "f.csv", 8, &err), SC_OK);
    assert_int_equal(h.n, 25);
    assert_true(h.s_mm == 0.5);
    assert_true(h.sigma == -1); /* optional, absent: default kept */
    assert_true(h.origin[0] == 7 && h.origin[1] == 8);
    assert_true(h.stage[0] == 5 && h.stage[1] == 7);
    assert_int_equal(sc_header_line_of(&p, "N"), 2);
    assert_int_equal(sc_header_line_of(&p, "s_mm"), 3);
    assert_int_equal(sc_header_line_of(&p, "sigma_um"), 0);
    assert_int_equal(sc_header_line_of(&p, "nope"), 0);
    assert_int_equal(sc_header_line(&p, "f.csv", 9, "# origin_mm = -1.5,2", NULL, &err), SC_OK);
    assert_true(h.origin[0] == -1.5 && h.origin[1] == 2);
}

static void test_header_errors(void **state)
{
    (void)state;
    static const struct {
        const char *line;
        const char *needle;
    } cases[] = {
        {"# N = 2", "N = 2 is out of range (3..1000)"},
        {"# N = 2.5", "N: '2.5' is not a whole number"},
        {"# s_mm = 0", "s_mm = 0 must be positive"},
        {"# s_mm = x", "s_mm: 'x' is not a number"},
        {"# s_mm = 2e6", "beyond any real set-up"},
        {"# sigma_um = -1", "sigma_um = -1 must be non-negative"},
        {"# origin_mm = 1", "not two numbers"},
        {"# origin_mm = 1,y", "not two numbers"},
        {"# origin_mm = 1,-2e6", "must be >= -1e+06"},
        {"# stage = 5,4.5", "not two whole numbers"},
        {"# stage = 5,101", "out of range (3..99)"},
        {"# s_mm = nan", "not a number"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        hdr h;
        memset(&h, 0, sizeof h);
        sc_header p;
        sc_header_init(&p, keys, 5, &h);
        sc_error err;
        sc_error_clear(&err);
        bool used = true;
        sc_status st = sc_header_line(&p, "f.csv", 4, cases[k].line, &used, &err);
        if (st != SC_E_INPUT || !strstr(err.msg, cases[k].needle))
            fail_msg("case %zu: status %d msg '%s'", k, st, err.msg);
        assert_int_equal(used, 0);
        assert_int_equal(err.line, 4);
        assert_string_equal(err.file, "f.csv");
    }
    /* a repeated key names the first line; a missing required key is named at the given line */
    hdr h;
    sc_header p;
    sc_header_init(&p, keys, 5, &h);
    sc_error err;
    assert_int_equal(sc_header_line(&p, "f.csv", 2, "# N = 5", NULL, &err), SC_OK);
    assert_int_equal(sc_header_line(&p, "f.csv", 6, "# N = 5", NULL, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "N given twice (first at line 2)"));
    assert_int_equal(err.line, 6);
    assert_int_equal(sc_header_finish(&p, "f.csv", 9, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "'# s_mm = ...' missing"));
    assert_int_equal(err.line, 9);
    /* an over-long line is not a key line */
    char longline[2048];
    memset(longline, 'a', sizeof longline - 1);
    longline[0] = '#';
    longline[sizeof longline - 1] = '\0';
    bool used = true;
    assert_int_equal(sc_header_line(&p, "f.csv", 7, longline, &used, &err), SC_OK);
    assert_int_equal(used, 0);
}

/* ---- stage map ---- */

/* A rectangular map with uncertainties, written, read back and written again identically. */
static void test_stage_map_round_trip(void **state)
{
    (void)state;
    enum { NX = 5, NY = 3 };
    double gx[NX * NY], gy[NX * NY], ux[NX * NY], uy[NX * NY];
    for (int k = 0; k < NX * NY; ++k) {
        gx[k] = 0.125 * k - 1;
        gy[k] = -0.0625 * k;
        ux[k] = k / 1024.0; /* exact in %.15g, so the round trip is exact */
        uy[k] = k == 4 ? NAN : k / 512.0;
    }
    sc_stage_map m = {NX, NY, -10.0, 20.5, 2.5, 1.25, gx, gy, ux, uy};
    char path[512], path2[512];
    tmp_path(path, sizeof path, "map_rt.csv");
    tmp_path(path2, sizeof path2, "map_rt2.csv");
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_stage_map_write(path, &m, &err), SC_OK);
    sc_stage_map r;
    assert_int_equal(sc_stage_map_read(path, &r, &err), SC_OK);
    assert_int_equal(r.nx, NX);
    assert_int_equal(r.ny, NY);
    assert_true(fabs(r.x0_mm + 10) < 1e-12 && fabs(r.y0_mm - 20.5) < 1e-12);
    assert_true(fabs(r.px_mm - 2.5) < 1e-12 && fabs(r.py_mm - 1.25) < 1e-12);
    assert_true(sc_stage_map_has_u(&r));
    for (int k = 0; k < NX * NY; ++k) {
        assert_true(r.gx_um[k] == gx[k] && r.gy_um[k] == gy[k] && r.ugx_um[k] == ux[k]);
        assert_true(k == 4 ? isnan(r.ugy_um[k]) : r.ugy_um[k] == uy[k]);
    }
    assert_int_equal(sc_stage_map_write(path2, &r, &err), SC_OK);
    sc_stage_map_free(&r);
    assert_null(r.gx_um);
    /* the two files are byte-identical */
    FILE *a = fopen(path, "rb"), *b = fopen(path2, "rb");
    assert_non_null(a);
    assert_non_null(b);
    int ca, cb;
    do {
        ca = fgetc(a);
        cb = fgetc(b);
        assert_int_equal(ca, cb);
    } while (ca != EOF);
    fclose(a);
    fclose(b);
    /* without the uncertainty columns, and with an extension column; rows in any order */
    write_text(path, "# comment\n\ni,j,x_mm,y_mm,gx_um,gy_um,extra\n1,1,1,1,4,8,z\n0,0,0,0,1,5,z\n"
                     "0,1,1,0,2,6,z\n1,0,0,1,3,7,z\n");
    assert_int_equal(sc_stage_map_read(path, &r, &err), SC_OK);
    assert_int_equal(r.nx, 2);
    assert_false(sc_stage_map_has_u(&r));
    assert_true(r.gx_um[0] == 1 && r.gx_um[1] == 2 && r.gx_um[2] == 3 && r.gy_um[3] == 8);
    assert_true(isnan(r.ugx_um[0]) && isnan(r.ugy_um[3]));
    sc_stage_map_free(&r);
    /* a view without uncertainty arrays writes empty fields */
    sc_stage_map v = {2, 2, 0, 0, 1, 1, gx, gy, NULL, NULL};
    assert_int_equal(sc_stage_map_write(path, &v, &err), SC_OK);
    assert_int_equal(sc_stage_map_read(path, &r, &err), SC_OK);
    assert_false(sc_stage_map_has_u(&r));
    sc_stage_map_free(&r);
}

/* Every rule, with the line of the problem (0 for whole-file properties). */
static void test_stage_map_errors(void **state)
{
    (void)state;
#define H "i,j,x_mm,y_mm,gx_um,gy_um\n"
#define HU "i,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n"
    static const struct {
        const char *text;
        long line;
        const char *word;
    } bad[] = {
        {"", 0, "empty"},
        {"# only a comment\n", 1, "empty map file"},
        {"i,j,x,y,gx,gy\n0,0,0,0,1,1\n", 1, "map header"},
        {"i,j,x_mm,y_mm,gx_um,gy_um,ugx_um\n", 1, "pair"},
        {"i,j,x_mm,y_mm,gx_um,gy_um,foo,ugy_um\n", 1, "pair"},
        {H, 1, "2 x 2"},
        {H "0,0,0,0,1,1\n", 2, "2 x 2"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n", 3, "2 x 2"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n", 4, "missing"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n0,1,1,0,1,1\n", 5, "repeats line 3"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n1,1,1.2,1,1,1\n", 5, "irregular grid: x_mm"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n1,1,1,1.1,1,1\n", 5, "irregular grid: y_mm"},
        /* the bad value is the first of the largest index (the reference used to run through
         * it) and a gross one makes the least-squares pitch negative: both named at their line */
        {H "0,0,0,0,1,1\n0,1,2,0,1,1\n0,2,4.5,0,1,1\n1,0,0,2,1,1\n1,1,2,2,1,1\n1,2,4,2,1,1\n2,0,0,4,1,1\n2,1,2,4,1,1\n2,2,4,4,1,1\n", 4, "irregular grid: x_mm is 0.5"},
        {H "0,0,0,0,1,1\n0,1,2,0,1,1\n0,2,4,0,1,1\n1,0,-999,2,1,1\n1,1,2,2,1,1\n1,2,4,2,1,1\n2,0,0,4,1,1\n2,1,2,4,1,1\n2,2,4,4,1,1\n", 5, "irregular grid: x_mm is 999"},
        {H "0,0,0,0,1,1\n0,1,2,0,1,1\n0,2,4,0,1,1\n1,0,0,2,1,1\n1,1,2,2,1,1\n1,2,4,2,1,1\n2,0,0,7,1,1\n2,1,2,4,1,1\n2,2,4,4,1,1\n", 8, "irregular grid: y_mm is 3"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,abc,1\n1,1,1,1,1,1\n", 4, "gx_um"},
        {H "0,0,0,0,1,1\n0,1,1,0,1\n", 3, "expected 6 fields"},
        {H "0,0,0,0,1,1,7\n", 2, "expected 6 fields"},
        {H "0,0,0,0,1,1\n0,-1,1,0,1,1\n", 3, "outside"},
        {H "0,0,0,0,1,1\n0,5000,1,0,1,1\n", 3, "outside"},
        {H "0.5,0,0,0,1,1\n", 2, "i"},
        {H "0,0,0,0,1,1\n0,1,-1,0,1,1\n1,0,0,1,1,1\n1,1,-1,1,1,1\n", 3, "increase"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,-1,1,1\n1,1,1,-1,1,1\n", 4, "y_mm does not increase"},
        {H "0,0,0,0,nan,1\n", 2, "finite"},
        {H "0,0,0,0,1,1\n0,1,1,0,1e300,1\n", 3, "plausible"},
        {H "0,0,0,0,1,1\n0,1,1,0,1,-2e6\n", 3, "plausible"},
        {H "0,0,-3e12,0,1,1\n", 2, "1 km"},
        {H "0,0,0,0,1,1\n0,1,1e-8,0,1,1\n1,0,0,1,1,1\n1,1,1e-8,1,1,1\n", 3, "1 nm"},
        {HU "0,0,0,0,1,1,-0.1,0\n", 2, "not negative"},
        {HU "0,0,0,0,,1,0,0\n", 2, "gx_um"},
        {HU "0,0,0,0,1,1,2e6,\n", 2, "plausible"},
    };
#undef H
#undef HU
    char path[512];
    tmp_path(path, sizeof path, "badmap.csv");
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        write_text(path, bad[k].text);
        sc_error err;
        sc_error_clear(&err);
        sc_stage_map m;
        sc_status st = sc_stage_map_read(path, &m, &err);
        if (st != SC_E_INPUT || err.line != bad[k].line || !strstr(err.msg, bad[k].word))
            fail_msg("case %zu: status %d line %ld msg '%s'", k, st, err.line, err.msg);
        assert_string_equal(err.file, path);
        assert_null(m.gx_um);
        assert_null(m.ugy_um);
    }
    sc_error err;
    sc_stage_map m;
    assert_int_equal(sc_stage_map_read(SELFCAL_TEST_TMP "/no/such/map.csv", &m, &err), SC_E_INPUT);
}

/* ---- profile result ---- */

static void test_profile_result(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "result.csv");
    sc_error err;
    sc_error_clear(&err);
    double f[6] = {0.5, -0.25, 1, 2, 3, 4}, uf[6] = {0.125, 0.125, 0.25, 0.25, 0.5, 0.5},
           ey[4] = {1, 2, 3, 4};
    assert_int_equal(sc_profile_write_result(path, 6, 0.5, f, uf, ey, 4, &err), SC_OK);
    sc_profile_result r;
    assert_int_equal(sc_profile_read_result(path, &r, &err), SC_OK);
    assert_int_equal(r.n, 6);
    assert_int_equal(r.n_ey, 4);
    assert_true(r.has_uf && r.has_ey);
    assert_int_equal(r.header_line, 1);
    assert_int_equal(r.last_line, 7);
    for (int i = 0; i < 6; ++i) {
        assert_true(r.x_mm[i] == 0.5 * i && r.f_um[i] == f[i] && r.uf_um[i] == uf[i]);
        assert_true(i < 4 ? r.ey_um[i] == ey[i] : isnan(r.ey_um[i]));
    }
    sc_profile_result_free(&r);
    assert_null(r.f_um);
    /* columns in another order, no uf, the last (optional) field left out, comments */
    write_text(path, "# truth\nx_mm,n,f_um,ey_um\n0,0,1,2\n\n1,1,2\n# end\n");
    assert_int_equal(sc_profile_read_result(path, &r, &err), SC_OK);
    assert_int_equal(r.n, 2);
    assert_int_equal(r.n_ey, 1);
    assert_false(r.has_uf);
    assert_true(r.f_um[1] == 2 && isnan(r.uf_um[0]) && isnan(r.ey_um[1]));
    sc_profile_result_free(&r);

#define H "n,x_mm,f_um,uf_um,ey_um\n"
    static const struct {
        const char *text;
        long line;
        const char *word;
    } bad[] = {
        {"", 0, "header naming"},
        {"n,x,f_um\n", 1, "header naming"},
        {H, 1, "no data rows"},
        {H "0,0,0,0,1\n1,1,0,0,\n2,2,0,0,3\n", 3, "empty ey_um"},
        {H "0,0,0,0,1\n2,1,0,0,2\n", 3, "expected n = 1, got 2"},
        {H "0,0,0,0,1\n1,1,0,0,2\n2,2.5,0,0,3\n3,3,0,0,3\n", 4, "irregular"},
        /* the first or the last point off (the reference used to run through them), or so far
         * off that the least-squares spacing is negative: named at their line */
        {H "0,0.5,0,0,1\n1,1,0,0,2\n2,2,0,0,3\n3,3,0,0,3\n", 2, "x_mm is 0.5 mm off"},
        {H "0,0,0,0,1\n1,1,0,0,2\n2,2,0,0,3\n3,3.25,0,0,3\n", 5, "x_mm is 0.25 mm off"},
        {H "0,0,0,0,1\n1,-900,0,0,2\n2,2,0,0,3\n3,3,0,0,3\n4,4,0,0,3\n", 3, "x_mm is 901 mm off"},
        {H "0,0,0,0,1\n1,1e-9,0,0,2\n2,2e-9,0,0,3\n", 3, "below 1 nm"},
        {H "0,0,0,0,1\n1,-1,0,0,2\n", 3, "increase"},
        {H "0,0,0,0,1\n1,1,0,0,x\n", 3, "ey_um"},
        {H "0,0,0,0,1\n1,1,,0,1\n", 3, "f_um is empty"},
        {H "0,0,0\n", 2, "expected 5 fields, got 3"},
        {H "0,0,0,0,1,9\n", 2, "expected 5 fields, got 6"},
        {H "0,0,0,0,2e6\n", 2, "beyond"},
        {"n,f_um,x_mm\n0,0\n", 2, "expected 3 fields, got 2"},
    };
#undef H
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        write_text(path, bad[k].text);
        sc_error_clear(&err);
        sc_status st = sc_profile_read_result(path, &r, &err);
        if (st != SC_E_INPUT || err.line != bad[k].line || !strstr(err.msg, bad[k].word))
            fail_msg("case %zu: status %d line %ld msg '%s'", k, st, err.line, err.msg);
        assert_null(r.x_mm);
    }
}

/* ---- plate error ---- */

/* ---- rows written by two threads (row_writer.c) ---- */

/* sc_io_put_long writes what printf("%ld") writes, then the separator, for every sign and length. */
static void test_put_long(void **st)
{
    (void)st;
    char buf[64], ref[40];
    long edge[] = {0, -1, 1, LONG_MAX, LONG_MIN, -99999999, 100000000, -100000000000000000L};
    for (long t = 0; t < 100000; ++t) {
        long v = t < (long)(sizeof edge / sizeof *edge) ? edge[t]
                                                         : (long)((unsigned long)t * 0x9E3779B97F4A7C15UL) >> (t % 63);
        char *end = sc_io_put_long(buf, v, ';');
        snprintf(ref, sizeof ref, "%ld;", v);
        assert_int_equal(end - buf, (int)strlen(ref));
        assert_memory_equal(buf, ref, strlen(ref));
    }
}

/* "i,v[i]\n" with v of varying length (1 to 23 characters) */
static char *numbered_row(const void *ctx, long i, char *p)
{
    const double *v = ctx;
    sc_number_shortest d;
    sc_number_find_shortest(v[i], &d);
    p = sc_io_put_long(p, i, ',');
    return sc_io_put_shortest(p, &d, '\n');
}

static char *slurp(const char *path, long *len)
{
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    *len = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *b = malloc((size_t)*len + 1);
    assert_non_null(b);
    assert_int_equal(fread(b, 1, (size_t)*len, fp), (size_t)*len);
    fclose(fp);
    return b;
}

static void write_numbered(const char *path, long n, const double *v, long parallel_from)
{
    sc_afile f;
    sc_io_out o;
    sc_error err;
    assert_int_equal(sc_afile_open(&f, path, &err), SC_OK);
    assert_int_equal(sc_io_out_attach(&o, &f, &err), SC_OK);
    fputs("i,v\n", o.f.fp); /* text before the rows, as the writers' column headers */
    sc_io_out_rows_tuned(&o, n, numbered_row, v, parallel_from);
    assert_int_equal(sc_afile_finish(&f, sc_io_out_drain(&o, &err), &err), SC_OK);
}

static void test_rows_two_threads(void **state)
{
    (void)state;
    const long sizes[] = {0, 1, 2047, 2048, 2049, 4 * 2048 + 5, 9 * 2048, 50001};
    const long nmax = 50001;
    double *v = malloc(sizeof(double) * nmax);
    char *expect = malloc((size_t)nmax * 48 + 8);
    assert_non_null(v);
    assert_non_null(expect);
    sc_rng r;
    sc_rng_seed(&r, 11);
    for (long i = 0; i < nmax; ++i) /* short and long texts: 0.5, 1e-300, 12345.678901234567 */
        v[i] = i % 3 == 0 ? 0.5 * (double)(i % 7) : sc_rng_normal(&r) * pow(10, (double)(i % 40) - 20);
    for (size_t c = 0; c < sizeof sizes / sizeof sizes[0]; ++c) {
        long n = sizes[c], la, lb;
        char *e = expect + sprintf(expect, "i,v\n");
        for (long i = 0; i < n; ++i) {
            e += sprintf(e, "%ld,", i);
            e += sc_number_format(v[i], e);
            *e++ = '\n';
        }
        write_numbered(SELFCAL_TEST_TMP "/io_rows_one.csv", n, v, LONG_MAX);
        write_numbered(SELFCAL_TEST_TMP "/io_rows_two.csv", n, v, 0);
        char *a = slurp(SELFCAL_TEST_TMP "/io_rows_one.csv", &la), *b = slurp(SELFCAL_TEST_TMP "/io_rows_two.csv", &lb);
        assert_int_equal(la, e - expect);
        assert_memory_equal(a, expect, (size_t)la);
        assert_int_equal(lb, la);
        assert_memory_equal(b, a, (size_t)la);
        free(a);
        free(b);
    }
    free(v);
    free(expect);
}

static void test_plate_map(void **state)
{
    (void)state;
    char path[512];
    tmp_path(path, sizeof path, "plate.csv");
    sc_error err;
    sc_error_clear(&err);
    double ax[9], ay[9];
    for (int k = 0; k < 9; ++k) {
        ax[k] = 0.25 * k;
        ay[k] = -0.5 * k;
    }
    ax[4] = ay[4] = NAN; /* a mark no method determined: empty fields */
    sc_plate_map m = {3, ax, ay}, r;
    assert_int_equal(sc_plate_map_write(path, &m, &err), SC_OK);
    assert_int_equal(sc_plate_map_read(path, &r, &err), SC_OK);
    assert_int_equal(r.n, 3);
    for (int k = 0; k < 9; ++k)
        assert_true(k == 4 ? isnan(r.ax_um[k]) && isnan(r.ay_um[k])
                           : r.ax_um[k] == ax[k] && r.ay_um[k] == ay[k]);
    sc_plate_map_free(&r);
    assert_null(r.ax_um);

#define H3 "i,j,ax_um,ay_um\n0,0,0,0\n0,1,0,0\n0,2,0,0\n1,0,0,0\n"
#define R3B "1,2,0,0\n2,0,0,0\n2,1,0,0\n2,2,0,0\n"
#define H "i,j,ax_um,ay_um\n"
#define R8 "0,0,0,0\n0,1,0,0\n0,2,0,0\n1,0,0,0\n1,1,0,0\n1,2,0,0\n2,0,0,0\n2,1,0,0\n"
    static const struct {
        const char *text;
        long line;
        const char *word;
    } bad[] = {
        {"", 0, "header"},
        {"i,j,ax,ay\n", 1, "header"},
        {H, 1, "0 rows"},
        {H R8, 9, "8 rows"},
        {H "0,0,0,0\n0,1,0,0\n1,0,0,0\n1,1,0,0\n", 5, "n odd"},
        {H R8 "2,1,0,0\n", 10, "repeats line 9"},
        {H R8 "2,3,0,0\n", 10, "off the 3 x 3"},
        {H R8 "2,-2,0,0\n", 10, "outside"},
        {H "0,0,1,\n", 2, "both"},
        {H "0,0,1\n", 2, "expected 4 fields"},
        {H "0,0,1,q\n", 2, "ay_um"},
        {H "0,0,1,3e6\n", 2, "plausible"},
    };
#undef H
#undef R8
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        write_text(path, bad[k].text);
        sc_error_clear(&err);
        sc_status st = sc_plate_map_read(path, &r, &err);
        if (st != SC_E_INPUT || err.line != bad[k].line || !strstr(err.msg, bad[k].word))
            fail_msg("case %zu: status %d line %ld msg '%s'", k, st, err.line, err.msg);
        assert_null(r.ax_um);
    }
    /* the artifact reader (verify, plot map) reads by the same rules: a row of 6 fields under a
     * 4-field header (a corrupted line) was once taken as its first four (fuzz_plate_map) */
    sc_stage_map am;
    write_text(path, H3 "1,1,0.12,-0.,,7221\n" R3B);
    sc_error_clear(&err);
    assert_int_equal(sc_grid_read_artifact(path, 2.0, &am, &err), SC_E_INPUT);
    assert_int_equal(err.line, 6);
    assert_null(am.gx_um);
    write_text(path, H3 "1,1,0.12,-0.5\n" R3B);
    assert_int_equal(sc_grid_read_artifact(path, 2.0, &am, &err), SC_OK);
    assert_int_equal(am.nx, 3);
    assert_true(am.x0_mm == -2.0 && am.gx_um[4] == 0.12 && am.gy_um[4] == -0.5 && isnan(am.ugx_um[4]));
    sc_stage_map_free(&am);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_put_long),
        cmocka_unit_test(test_header_good),
        cmocka_unit_test(test_header_errors),
        cmocka_unit_test(test_stage_map_round_trip),
        cmocka_unit_test(test_stage_map_errors),
        cmocka_unit_test(test_profile_result),
        cmocka_unit_test(test_plate_map),
        cmocka_unit_test(test_rows_two_threads),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
