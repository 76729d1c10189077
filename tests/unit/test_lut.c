/* Unit tests of the host table module (selfcal/lut.h, selfcal/sha256.h): SHA-256 against the
 * FIPS 180-4 examples, encode/decode round trips within the stated quantization, the core loading
 * what the encoder writes, the 8 KiB budget, the map and profile readers' checks (with line
 * numbers), and atomic writing. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "selfcal/correct.h"
#include "selfcal/lut.h"
#include "selfcal/rng.h"
#include "selfcal/sha256.h"

#define TMP SELFCAL_TEST_TMP "/lut_"

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, strlen(text), f), strlen(text));
    fclose(f);
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static void hex_of(const void *data, size_t len, char hex[65])
{
    uint8_t d[32];
    sc_sha256 s;
    sc_sha256_init(&s);
    sc_sha256_update(&s, data, len);
    sc_sha256_final(&s, d);
    sc_sha256_hex(d, hex);
}

static void test_sha256_vectors(void **state)
{
    (void)state;
    char hex[65];
    hex_of("abc", 3, hex);
    assert_string_equal(hex, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    hex_of("", 0, hex);
    assert_string_equal(hex, "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    const char *m448 = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
    hex_of(m448, strlen(m448), hex);
    assert_string_equal(hex, "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
    /* One million 'a', fed in uneven pieces. */
    static char a[1000000];
    memset(a, 'a', sizeof a);
    sc_sha256 s;
    sc_sha256_init(&s);
    size_t off = 0, piece = 1;
    while (off < sizeof a) {
        size_t n = piece < sizeof a - off ? piece : sizeof a - off;
        sc_sha256_update(&s, a + off, n);
        off += n;
        piece = piece * 3 + 1;
    }
    uint8_t d[32];
    sc_sha256_final(&s, d);
    sc_sha256_hex(d, hex);
    assert_string_equal(hex, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
    /* The file digest equals the in-memory digest. */
    write_text(TMP "sha.txt", "abc");
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_sha256_file(TMP "sha.txt", d, &err), SC_OK);
    sc_sha256_hex(d, hex);
    assert_string_equal(hex, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    /* a missing source file is bad input, as for every reader */
    assert_int_equal(sc_sha256_file(TMP "does-not-exist", d, &err), SC_E_INPUT);
}

/* A random table: nx x ny grid with values of amplitude amp_um, np profiles. */
static void random_lut(sc_lut *lut, sc_rng *rng, int nx, int ny, double amp_um, int np, int npts)
{
    sc_lut_init(lut);
    lut->nx = nx;
    lut->ny = ny;
    lut->x0_mm = -37.5;
    lut->y0_mm = 12.25;
    lut->px_mm = 2.5;
    lut->py_mm = 3.0;
    for (int k = 0; k < nx * ny; ++k) {
        lut->gx_um[k] = amp_um * (2 * sc_rng_uniform(rng) - 1);
        lut->gy_um[k] = amp_um * (2 * sc_rng_uniform(rng) - 1);
    }
    lut->n_profiles = np;
    for (int p = 0; p < np; ++p) {
        sc_lut_profile *pr = &lut->profile[p];
        pr->axis = p % 3;
        pr->dir = (p + 1) % 3;
        pr->n = npts;
        pr->start_mm = -10.0 * p;
        pr->step_mm = 0.5 + p;
        for (int m = 0; m < npts; ++m)
            pr->err_um[m] = 0.3 * amp_um * (2 * sc_rng_uniform(rng) - 1);
    }
    lut->prov.n_sources = 1 + np;
    for (int s = 0; s < lut->prov.n_sources; ++s)
        for (int b = 0; b < 32; ++b)
            lut->prov.sha256[s][b] = (uint8_t)(s * 31 + b);
    snprintf(lut->prov.method, sizeof lut->prov.method, "lsq");
    lut->prov.created_unix_s = 1700000000;
    lut->prov.sigma_um = 0.012;
}

static uint8_t buf[1 << 18];

/* Encode, decode, compare within the stated quantization; the core loads the same bytes and its
 * node values agree. Returns the encoded size. */
static size_t round_trip(sc_lut *in, sc_lut *out, sc_lut_encoding enc, int want_enc)
{
    sc_error err;
    sc_error_clear(&err);
    size_t len = 0;
    assert_int_equal(sc_lut_encode(in, enc, buf, sizeof buf, &len, &err), SC_OK);
    assert_int_equal(len, sc_lut_encoded_size(in, enc));
    assert_int_equal(in->grid_encoding, want_enc);
    assert_int_equal(sc_lut_decode(buf, len, out, "mem", &err), SC_OK);
    assert_int_equal(out->nx, in->nx);
    assert_int_equal(out->ny, in->ny);
    assert_true(out->x0_mm == in->x0_mm && out->y0_mm == in->y0_mm);
    assert_true(out->px_mm == in->px_mm && out->py_mm == in->py_mm);
    assert_int_equal(out->grid_scale_pm, in->grid_scale_pm);
    const double q = sc_lut_quantization_um(in->grid_scale_pm);
    double worst = 0;
    for (int k = 0; k < in->nx * in->ny; ++k) {
        worst = fmax(worst, fabs(out->gx_um[k] - in->gx_um[k]));
        worst = fmax(worst, fabs(out->gy_um[k] - in->gy_um[k]));
    }
    assert_true(worst <= q * (1 + 1e-9));
    assert_int_equal(out->n_profiles, in->n_profiles);
    for (int p = 0; p < in->n_profiles; ++p) {
        const sc_lut_profile *a = &in->profile[p], *b = &out->profile[p];
        assert_int_equal(a->axis, b->axis);
        assert_int_equal(a->dir, b->dir);
        assert_int_equal(a->n, b->n);
        assert_true(a->start_mm == b->start_mm && a->step_mm == b->step_mm);
        const double qp = sc_lut_quantization_um(a->scale_pm);
        for (int m = 0; m < a->n; ++m)
            assert_true(fabs(a->err_um[m] - b->err_um[m]) <= qp * (1 + 1e-9));
    }
    assert_string_equal(out->prov.method, in->prov.method);
    assert_true(out->prov.created_unix_s == in->prov.created_unix_s);
    assert_true(out->prov.sigma_um == in->prov.sigma_um);
    assert_int_equal(out->prov.n_sources, in->prov.n_sources);
    assert_memory_equal(out->prov.sha256, in->prov.sha256, (size_t)in->prov.n_sources * 32);

    /* The runtime core reads the same image: its stored values are the decoded ones (as floats),
     * and at the nodes of a table without profiles apply() gives exactly them. */
    static sc_corr_table t;
    assert_int_equal(sc_corr_load(&t, buf, len), SC_CORR_OK);
    for (int k = 0; k < in->nx * in->ny; ++k) {
        assert_true(t.g_um[k][0] == (float)out->gx_um[k]);
        assert_true(t.g_um[k][1] == (float)out->gy_um[k]);
    }
    assert_int_equal(t.n_profiles, in->n_profiles);
    for (int p = 0; p < in->n_profiles; ++p)
        for (int m = 0; m < in->profile[p].n; ++m)
            assert_true(t.profile[p].err_um[m] == (float)out->profile[p].err_um[m]);
    if (in->n_profiles == 0)
        for (int i = 0; i < in->ny; ++i)
            for (int j = 0; j < in->nx; ++j) {
                double p[3] = {in->x0_mm + j * in->px_mm, in->y0_mm + i * in->py_mm, 0}, o[3];
                assert_int_equal(sc_corr_apply(&t, SC_CORR_POSITION, p, o), SC_CORR_ST_LOADED);
                size_t k = (size_t)i * in->nx + j;
                assert_true(fabs((o[0] - p[0]) - 1e-3 * (float)out->gx_um[k]) <= 1e-12);
                assert_true(fabs((o[1] - p[1]) - 1e-3 * (float)out->gy_um[k]) <= 1e-12);
            }
    return len;
}

static void test_encode_decode_round_trip(void **state)
{
    (void)state;
    sc_rng rng;
    sc_rng_seed(&rng, 42);
    sc_lut *in = malloc(sizeof *in), *out = malloc(sizeof *out);
    assert_non_null(in);
    assert_non_null(out);
    /* Small map (|G| < 3 um): int16 by default, quantization <= 0.05 nm. */
    random_lut(in, &rng, 25, 25, 3.0, 2, 330);
    size_t len = round_trip(in, out, SC_LUT_ENC_AUTO, SC_LUT_ENC_INT16);
    assert_true(len <= 8192); /* the budget of issue 4: 25 x 25 + two 330-point profiles */
    assert_true(sc_lut_quantization_um(in->grid_scale_pm) <= 0.05e-3);
    /* Even forced to int32 the same table fits in 8 KiB. */
    len = round_trip(in, out, SC_LUT_ENC_INT32, SC_LUT_ENC_INT32);
    assert_true(len <= 8192);
    assert_true(sc_lut_quantization_um(in->grid_scale_pm) <= 0.5e-6);
    /* Larger errors: auto switches to int32 (1 pm codes up to 2 mm). */
    random_lut(in, &rng, 7, 4, 4.0, 1, 17);
    in->gx_um[5] = 3.5;
    round_trip(in, out, SC_LUT_ENC_AUTO, SC_LUT_ENC_INT32);
    random_lut(in, &rng, 7, 4, 250.0, 1, 17);
    round_trip(in, out, SC_LUT_ENC_AUTO, SC_LUT_ENC_INT32);
    assert_true(sc_lut_quantization_um(in->grid_scale_pm) <= 0.5e-6);
    /* ... unless int16 is forced: coarser, still within its stated bound. */
    round_trip(in, out, SC_LUT_ENC_INT16, SC_LUT_ENC_INT16);
    assert_true(sc_lut_quantization_um(in->grid_scale_pm) * 2 * 32767 >= 250.0 * 0.99);
    /* Tiny and zero maps, rectangular 2 x 101, no profiles. */
    random_lut(in, &rng, 2, 101, 1e-4, 0, 0);
    round_trip(in, out, SC_LUT_ENC_AUTO, SC_LUT_ENC_INT16);
    assert_int_equal(in->grid_scale_pm, 1);
    random_lut(in, &rng, 101, 3, 0.0, 8, 2048);
    round_trip(in, out, SC_LUT_ENC_AUTO, SC_LUT_ENC_INT16);
    free(in);
    free(out);
}

/* The format's range (issue 36): every value a block can express within +-2^31 pm. The writer
 * refuses values beyond it, the loader refuses scale fields that could express more (the audit's
 * table: a grid scale of 1e9 pm with the CRC right), and the bounds a table commands are the same
 * from the host table (sc_lut_bounds) and from the loaded one (sc_corr_bounds). */
static void test_range_and_bounds(void **state)
{
    (void)state;
    sc_rng rng;
    sc_rng_seed(&rng, 36);
    sc_lut *in = malloc(sizeof *in), *out = malloc(sizeof *out);
    sc_corr_table *t = malloc(sizeof *t);
    assert_non_null(in);
    assert_non_null(out);
    assert_non_null(t);
    sc_error err;
    size_t len = 0;
    /* the largest encodable values: int32 at 1 pm; int16 up to 50000 pm */
    random_lut(in, &rng, 5, 4, 2147.0, 2, 9);
    in->gx_um[3] = -2147.483647;
    round_trip(in, out, SC_LUT_ENC_AUTO, SC_LUT_ENC_INT32);
    assert_int_equal(in->grid_scale_pm, 1);
    random_lut(in, &rng, 5, 4, 1600.0, 0, 0);
    round_trip(in, out, SC_LUT_ENC_INT16, SC_LUT_ENC_INT16);
    assert_int_equal(in->grid_scale_pm, 50000);
    /* beyond: refused, naming the range */
    random_lut(in, &rng, 5, 4, 1.0, 1, 9);
    in->gy_um[7] = 2147.49;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "range"));
    in->gy_um[7] = 1700.0;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_INT16, buf, sizeof buf, &len, &err), SC_E_INPUT);
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_INT32, buf, sizeof buf, &len, &err), SC_OK);
    in->gy_um[7] = 0.5;
    in->profile[0].err_um[2] = -3000.0;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "profile 0"));

    /* scale fields: int16 up to 65536 pm, int32 exactly 1 pm; the grid's at offset 56, the
     * first profile's 24 bytes into its header (right after the grid codes) */
    random_lut(in, &rng, 4, 3, 2.0, 1, 5);
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_INT16, buf, sizeof buf, &len, &err), SC_OK);
    const size_t pscale = 64 + 2 * 12 * 2 + 24;
    static const struct {
        size_t off;
        uint32_t scale;
        int ok;
    } cases[] = {{56, 65536, 1}, {56, 65537, 0}, {56, 1000000000u, 0}, {56, 0, 0},
                 {pscale, 65536, 1}, {pscale, 65537, 0}, {pscale, 1000000000u, 0}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_INT16, buf, sizeof buf, &len, &err), SC_OK);
        for (int b = 0; b < 4; ++b)
            buf[cases[c].off + (size_t)b] = (uint8_t)(cases[c].scale >> (8 * b));
        uint32_t crc = sc_corr_crc32(buf, len - 4);
        for (int b = 0; b < 4; ++b)
            buf[len - 4 + (size_t)b] = (uint8_t)(crc >> (8 * b));
        assert_int_equal(sc_corr_load(t, buf, len), cases[c].ok ? SC_CORR_OK : SC_CORR_E_RANGE);
        assert_int_equal(sc_lut_decode(buf, len, out, "audit.lut", &err),
                         cases[c].ok ? SC_OK : SC_E_INPUT);
        if (!cases[c].ok)
            assert_non_null(strstr(err.msg, "scale"));
    }
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_INT32, buf, sizeof buf, &len, &err), SC_OK);
    buf[56] = 2; /* int32 codes of 2 pm: could express 4.3 mm */
    uint32_t crc = sc_corr_crc32(buf, len - 4);
    for (int b = 0; b < 4; ++b)
        buf[len - 4 + (size_t)b] = (uint8_t)(crc >> (8 * b));
    assert_int_equal(sc_corr_load(t, buf, len), SC_CORR_E_RANGE);

    /* bounds: known values, then host and loaded table agree */
    random_lut(in, &rng, 3, 2, 0.0, 2, 4);
    in->px_mm = 2.0;
    in->py_mm = 4.0;
    in->gx_um[1] = 3.0;    /* node (0, 1): 3 um over 2 mm from both x neighbours: 1.5 um/mm */
    in->gy_um[4] = -2.5;   /* node (1, 1) */
    in->profile[0].dir = 1; /* a profile on y adds its largest |value| to y's */
    in->profile[0].err_um[2] = 0.75;
    in->profile[1].dir = 2;
    in->profile[1].err_um[1] = 0.1;
    double corr, grad, corr2, grad2;
    sc_lut_bounds(in, &corr, &grad);
    assert_true(fabs(corr - 3.25) < 1e-12);
    assert_true(fabs(grad - 1.5) < 1e-12);
    in->profile[0].step_mm = 0.25; /* 0.75 um within 0.25 mm: 3 um/mm */
    sc_lut_bounds(in, &corr, &grad);
    assert_true(fabs(grad - 3.0) < 1e-12);
    for (int r = 0; r < 20; ++r) {
        random_lut(in, &rng, 2 + r % 7, 2 + r % 5, 0.5 + r, r % 4, 3 + r);
        assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_OK);
        assert_int_equal(sc_lut_decode(buf, len, out, "mem", &err), SC_OK);
        assert_int_equal(sc_corr_load(t, buf, len), SC_CORR_OK);
        sc_lut_bounds(out, &corr, &grad);
        sc_corr_bounds(t, &corr2, &grad2);
        assert_true(fabs(corr - corr2) <= 1e-6 * corr + 1e-9); /* float-rounded node values */
        assert_true(fabs(grad - grad2) <= 1e-6 * grad + 1e-9);
    }
    free(in);
    free(out);
    free(t);
}

static void test_encode_rejects(void **state)
{
    (void)state;
    sc_rng rng;
    sc_rng_seed(&rng, 7);
    sc_lut *in = malloc(sizeof *in);
    assert_non_null(in);
    sc_error err;
    size_t len;
    random_lut(in, &rng, 5, 5, 1.0, 1, 10);
    in->gx_um[3] = NAN;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_E_INPUT);
    random_lut(in, &rng, 5, 5, 1.0, 1, 10);
    in->px_mm = 0;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_E_INPUT);
    random_lut(in, &rng, 5, 5, 1.0, 1, 10);
    in->profile[0].n = 1;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_E_INPUT);
    in->profile[0].n = 2; /* the smallest profile */
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_OK);
    /* a profile may end at 1 km exactly (its last point, not one step beyond it) */
    random_lut(in, &rng, 5, 5, 1.0, 1, 10);
    in->profile[0].step_mm = 1000.0;
    in->profile[0].start_mm = 1e6 - 1000.0 * (in->profile[0].n - 1);
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_OK);
    in->profile[0].start_mm += 1000.0;
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, sizeof buf, &len, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "within 1 km"));
    random_lut(in, &rng, 5, 5, 1.0, 1, 10);
    assert_int_equal(sc_lut_encode(in, SC_LUT_ENC_AUTO, buf, 100, &len, &err), SC_E_NOMEM);
    /* Nothing is written under the final name when encoding fails. */
    const char *path = TMP "never.lut";
    unlink(path);
    random_lut(in, &rng, 1, 5, 1.0, 0, 0);
    assert_int_equal(sc_lut_write_file(path, in, SC_LUT_ENC_AUTO, &err), SC_E_INPUT);
    assert_false(file_exists(path));
    /* A written file reads back. */
    random_lut(in, &rng, 5, 4, 1.0, 1, 10);
    assert_int_equal(sc_lut_write_file(path, in, SC_LUT_ENC_AUTO, &err), SC_OK);
    sc_lut *back = malloc(sizeof *back);
    assert_non_null(back);
    assert_int_equal(sc_lut_read_file(path, back, &err), SC_OK);
    assert_int_equal(back->nx, 5);
    assert_int_equal(back->ny, 4);
    /* A corrupted file is refused with the reason. */
    FILE *f = fopen(path, "r+b");
    assert_non_null(f);
    fseek(f, 100, SEEK_SET);
    fputc(0x55, f);
    fclose(f);
    assert_int_equal(sc_lut_read_file(path, back, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "checksum"));
    free(back);
    free(in);
}

/* Write a map of nx x ny nodes (rows shuffled) with the given origin and pitch. */
static void write_map(const char *path, int nx, int ny, double x0, double y0, double px,
                      double py, sc_rng *rng, double *gx, double *gy)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    fprintf(f, "# a comment line\ni,j,x_mm,y_mm,gx_um,gy_um,ugx_um,ugy_um\n");
    int n = nx * ny, *order = malloc(sizeof(int) * (size_t)n);
    assert_non_null(order);
    for (int k = 0; k < n; ++k)
        order[k] = k;
    for (int k = n - 1; k > 0; --k) {
        int r = (int)(sc_rng_uniform(rng) * (k + 1)), t = order[k];
        order[k] = order[r];
        order[r] = t;
    }
    for (int m = 0; m < n; ++m) {
        int k = order[m], i = k / nx, j = k % nx;
        gx[k] = 2 * sc_rng_uniform(rng) - 1;
        gy[k] = 2 * sc_rng_uniform(rng) - 1;
        fprintf(f, "%d,%d,%.6f,%.6f,%.6f,%.6f,0.001,\n", i, j, x0 + j * px, y0 + i * py, gx[k], gy[k]);
    }
    free(order);
    fclose(f);
}

static void test_read_map(void **state)
{
    (void)state;
    sc_rng rng;
    sc_rng_seed(&rng, 3);
    sc_lut *lut = malloc(sizeof *lut);
    assert_non_null(lut);
    double gx[200], gy[200];
    const char *path = TMP "map.csv";
    write_map(path, 7, 4, -3.5, 10.0, 2.5, 1.25, &rng, gx, gy);
    sc_error err;
    sc_error_clear(&err);
    sc_lut_init(lut);
    assert_int_equal(sc_lut_read_map(path, lut, &err), SC_OK);
    assert_int_equal(lut->nx, 7);
    assert_int_equal(lut->ny, 4);
    assert_true(fabs(lut->x0_mm + 3.5) < 1e-9 && fabs(lut->y0_mm - 10.0) < 1e-9);
    assert_true(fabs(lut->px_mm - 2.5) < 1e-9 && fabs(lut->py_mm - 1.25) < 1e-9);
    for (int k = 0; k < 28; ++k) {
        assert_true(fabs(lut->gx_um[k] - gx[k]) <= 0.5e-6);
        assert_true(fabs(lut->gy_um[k] - gy[k]) <= 0.5e-6);
    }
    /* Bilinear evaluation: nodes exact, a cell centre is the mean of its corners. */
    double ex, ey;
    assert_int_equal(sc_lut_grid_eval(lut, -3.5 + 2 * 2.5, 10.0 + 1.25, &ex, &ey), 0);
    assert_true(ex == lut->gx_um[7 + 2] && ey == lut->gy_um[7 + 2]);
    assert_int_equal(sc_lut_grid_eval(lut, -3.5 + 2.5 * 2.5, 10.0 + 1.5 * 1.25, &ex, &ey), 0);
    double mean = 0.25 * (lut->gx_um[9] + lut->gx_um[10] + lut->gx_um[16] + lut->gx_um[17]);
    assert_true(fabs(ex - mean) < 1e-12);
    assert_int_equal(sc_lut_grid_eval(lut, -100, 10.0 + 1.25, &ex, &ey), 1);
    assert_true(ex == lut->gx_um[7]);
    /* half a pitch beyond each edge: outside, the value at the nearest edge point */
    const double x1 = -3.5 + 6 * 2.5, y1 = 10.0 + 3 * 1.25;
    assert_int_equal(sc_lut_grid_eval(lut, x1 + 1.25, 10.0 + 1.25, &ex, &ey), 1);
    assert_true(ex == lut->gx_um[7 + 6] && ey == lut->gy_um[7 + 6]);
    assert_int_equal(sc_lut_grid_eval(lut, -3.5 + 2.5, y1 + 0.625, &ex, &ey), 1);
    assert_true(ex == lut->gx_um[21 + 1] && ey == lut->gy_um[21 + 1]);
    assert_int_equal(sc_lut_grid_eval(lut, -3.5 + 2.5, 10.0 - 0.625, &ex, &ey), 1);
    assert_true(ex == lut->gx_um[1] && ey == lut->gy_um[1]);
    assert_int_equal(sc_lut_grid_eval(lut, x1, y1, &ex, &ey), 0); /* the last node is inside */
    assert_true(ex == lut->gx_um[27] && ey == lut->gy_um[27]);

    /* Bad maps: SC_E_INPUT with the line of the problem. */
    struct {
        const char *text;
        long line;
        const char *word;
    } bad[] = {
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n", 4, "missing"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n0,1,1,0,1,1\n", 5, "repeats"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,1,1\n1,1,1.2,1,1,1\n", 5, "irregular"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1,1\n1,0,0,1,abc,1\n1,1,1,1,1,1\n", 4, "gx_um"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1\n", 3, "fields"},
        {"i,j,x,y,gx,gy\n0,0,0,0,1,1\n", 1, "header"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n", 2, "2 x 2"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,-1,1,0,1,1\n", 3, "outside"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,-1,0,1,1\n1,0,0,1,1,1\n1,1,-1,1,1,1\n", 3, "increase"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,nan,1\n", 2, "finite"},
        /* physically impossible values, caught where read (found by fuzzing the exporters) */
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1e300,1\n", 3, "plausible"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1,0,1,-2e6\n", 3, "plausible"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,-3e12,0,1,1\n", 2, "1 km"},
        {"i,j,x_mm,y_mm,gx_um,gy_um\n0,0,0,0,1,1\n0,1,1e-8,0,1,1\n1,0,0,1,1,1\n1,1,1e-8,1,1,1\n", 3, "1 nm"},
        {"", 0, "empty"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        write_text(path, bad[k].text);
        sc_error_clear(&err);
        sc_lut_init(lut);
        assert_int_equal(sc_lut_read_map(path, lut, &err), SC_E_INPUT);
        if (err.line != bad[k].line || !strstr(err.msg, bad[k].word))
            print_error("case %zu: line %ld msg '%s'\n", k, err.line, err.msg);
        assert_int_equal(err.line, bad[k].line);
        assert_non_null(strstr(err.msg, bad[k].word));
        assert_string_equal(err.file, path);
    }
    free(lut);
}

/* A map of nx x ny nodes at origin (x0, y0), pitch (px, py), values from f (owned arrays). */
static sc_stage_map make_map(int nx, int ny, double x0, double y0, double px, double py)
{
    sc_stage_map m;
    memset(&m, 0, sizeof m);
    m.nx = nx, m.ny = ny, m.x0_mm = x0, m.y0_mm = y0, m.px_mm = px, m.py_mm = py;
    m.gx_um = calloc((size_t)nx * ny, sizeof(double));
    m.gy_um = calloc((size_t)nx * ny, sizeof(double));
    assert_non_null(m.gx_um);
    assert_non_null(m.gy_um);
    return m;
}

/* The table fitted to a map (sc_lut_fit_grid) against the least squares solved here the dense
 * way: the design matrix built column by column from the table's own bilinear evaluation
 * (sc_lut_grid_eval of a table holding a single 1), its normal equations solved by Gaussian
 * elimination. Also: a map that is itself bilinear on the table's nodes is recovered exactly, a
 * map within the limit is copied node for node, and the report's figures are those of the table
 * evaluated at the map's nodes. */
static void dense_fit(const sc_stage_map *m, const sc_lut *shape, const double *g, double *c)
{
    int nt = shape->nx * shape->ny, nm = m->nx * m->ny;
    sc_lut *unit = malloc(sizeof *unit);
    double *b = calloc((size_t)nm * nt, sizeof(double)); /* b[node * nt + t] */
    double *a = calloc((size_t)nt * (nt + 1), sizeof(double));
    assert_non_null(unit);
    assert_non_null(b);
    assert_non_null(a);
    sc_lut_init(unit);
    unit->nx = shape->nx, unit->ny = shape->ny, unit->x0_mm = shape->x0_mm;
    unit->y0_mm = shape->y0_mm, unit->px_mm = shape->px_mm, unit->py_mm = shape->py_mm;
    for (int t = 0; t < nt; ++t) {
        memset(unit->gx_um, 0, sizeof unit->gx_um);
        unit->gx_um[t] = 1;
        for (int i = 0; i < m->ny; ++i)
            for (int j = 0; j < m->nx; ++j) {
                double vx, vy;
                sc_lut_grid_eval(unit, sc_stage_map_x_mm(m, j), sc_stage_map_y_mm(m, i), &vx, &vy);
                b[((size_t)i * m->nx + j) * nt + t] = vx;
            }
    }
    for (int r = 0; r < nt; ++r) { /* [B^T B | B^T g] */
        for (int q = 0; q < nt; ++q)
            for (int k = 0; k < nm; ++k)
                a[r * (nt + 1) + q] += b[(size_t)k * nt + r] * b[(size_t)k * nt + q];
        for (int k = 0; k < nm; ++k)
            a[r * (nt + 1) + nt] += b[(size_t)k * nt + r] * g[k];
    }
    for (int col = 0; col < nt; ++col) { /* SPD: no pivoting needed */
        for (int r = col + 1; r < nt; ++r) {
            double f = a[r * (nt + 1) + col] / a[col * (nt + 1) + col];
            for (int q = col; q <= nt; ++q)
                a[r * (nt + 1) + q] -= f * a[col * (nt + 1) + q];
        }
    }
    for (int r = nt - 1; r >= 0; --r) {
        double v = a[r * (nt + 1) + nt];
        for (int q = r + 1; q < nt; ++q)
            v -= a[r * (nt + 1) + q] * c[q];
        c[r] = v / a[r * (nt + 1) + r];
    }
    free(a), free(b), free(unit);
}

static void test_fit_grid(void **state)
{
    (void)state;
    sc_rng rng;
    sc_rng_seed(&rng, 11);
    sc_lut *lut = malloc(sizeof *lut);
    assert_non_null(lut);
    sc_error err;
    sc_error_clear(&err);
    sc_lut_fit_report rep;

    /* 1. Random values, 11 x 9 nodes (pitch ratios 10/3 and 8/3 of 4 table nodes): the dense
     * least squares, and the report from the table evaluated at the nodes. */
    sc_stage_map m = make_map(11, 9, -5.0, 2.0, 0.75, 1.25);
    for (int k = 0; k < 99; ++k)
        m.gx_um[k] = sc_rng_normal(&rng), m.gy_um[k] = 0.3 * sc_rng_normal(&rng);
    sc_lut_init(lut);
    assert_int_equal(sc_lut_fit_grid(lut, &m, 4, "m.csv", &rep, &err), SC_OK);
    assert_int_equal(lut->nx, 4);
    assert_int_equal(lut->ny, 4);
    assert_int_equal(rep.fitted, 1);
    assert_int_equal(rep.map_nx, 11);
    assert_int_equal(rep.map_ny, 9);
    assert_true(fabs(lut->x0_mm + 5.0) < 1e-15 && fabs(lut->y0_mm - 2.0) < 1e-15);
    assert_true(fabs(lut->px_mm - 0.75 * 10 / 3) < 1e-12 && fabs(lut->py_mm - 1.25 * 8 / 3) < 1e-12);
    double cx[16], cy[16];
    dense_fit(&m, lut, m.gx_um, cx);
    dense_fit(&m, lut, m.gy_um, cy);
    for (int t = 0; t < 16; ++t) {
        assert_true(fabs(lut->gx_um[t] - cx[t]) < 1e-10);
        assert_true(fabs(lut->gy_um[t] - cy[t]) < 1e-10);
    }
    double sum2 = 0, worst = 0;
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 11; ++j) {
            double vx, vy;
            sc_lut_grid_eval(lut, sc_stage_map_x_mm(&m, j), sc_stage_map_y_mm(&m, i), &vx, &vy);
            double e2 = pow(vx - m.gx_um[i * 11 + j], 2) + pow(vy - m.gy_um[i * 11 + j], 2);
            sum2 += e2;
            worst = fmax(worst, e2);
        }
    assert_true(fabs(rep.rms_um - sqrt(sum2 / 99)) < 1e-12);
    assert_true(fabs(rep.max_um - sqrt(worst)) < 1e-12);
    assert_true(rep.rms_um > 0.1); /* random values: a 4 x 4 table cannot follow them */
    /* least squares beats keeping every third node's value (nodes 0, 3, 6, 9 ~ the table's) */
    double sum_nodes = 0;
    sc_lut *kept = malloc(sizeof *kept);
    assert_non_null(kept);
    *kept = *lut;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            int mi = (int)lround(i * 8.0 / 3), mj = (int)lround(j * 10.0 / 3);
            kept->gx_um[i * 4 + j] = m.gx_um[mi * 11 + mj];
            kept->gy_um[i * 4 + j] = m.gy_um[mi * 11 + mj];
        }
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 11; ++j) {
            double vx, vy;
            sc_lut_grid_eval(kept, sc_stage_map_x_mm(&m, j), sc_stage_map_y_mm(&m, i), &vx, &vy);
            sum_nodes += pow(vx - m.gx_um[i * 11 + j], 2) + pow(vy - m.gy_um[i * 11 + j], 2);
        }
    assert_true(sum2 < sum_nodes);
    free(kept);

    /* 2. A map bilinear on a 5-node table along x (y kept: 4 nodes, within the limit): the fit
     * gives that table back, y's nodes and pitch exactly. */
    sc_stage_map_free(&m);
    m = make_map(13, 5, 0.0, -1.0, 0.5, 0.8);
    double c0x[25], c0y[25];
    for (int t = 0; t < 25; ++t)
        c0x[t] = sc_rng_normal(&rng), c0y[t] = sc_rng_normal(&rng);
    sc_lut_init(lut);
    lut->nx = 5, lut->ny = 5, lut->x0_mm = 0.0, lut->y0_mm = -1.0, lut->px_mm = 1.5;
    lut->py_mm = 0.8;
    memcpy(lut->gx_um, c0x, sizeof c0x);
    memcpy(lut->gy_um, c0y, sizeof c0y);
    for (int i = 0; i < 5; ++i)
        for (int j = 0; j < 13; ++j)
            sc_lut_grid_eval(lut, sc_stage_map_x_mm(&m, j), sc_stage_map_y_mm(&m, i),
                             &m.gx_um[i * 13 + j], &m.gy_um[i * 13 + j]);
    sc_lut_init(lut);
    assert_int_equal(sc_lut_fit_grid(lut, &m, 5, "m.csv", &rep, &err), SC_OK);
    assert_int_equal(lut->nx, 5);
    assert_int_equal(lut->ny, 5);
    assert_true(lut->py_mm == 0.8); /* kept axis: its pitch unchanged */
    assert_true(fabs(lut->px_mm - 1.5) < 1e-12);
    for (int t = 0; t < 25; ++t) {
        assert_true(fabs(lut->gx_um[t] - c0x[t]) < 1e-12);
        assert_true(fabs(lut->gy_um[t] - c0y[t]) < 1e-12);
    }
    assert_true(rep.rms_um < 1e-12 && rep.max_um < 1e-12);

    /* 3. Within the limit: copied node for node, not fitted. */
    for (int k = 0; k < 65; ++k)
        m.gx_um[k] = sc_rng_normal(&rng), m.gy_um[k] = sc_rng_normal(&rng);
    sc_lut_init(lut);
    assert_int_equal(sc_lut_fit_grid(lut, &m, 101, "m.csv", &rep, &err), SC_OK);
    assert_int_equal(rep.fitted, 0);
    assert_int_equal(lut->nx, 13);
    assert_true(lut->px_mm == 0.5 && lut->py_mm == 0.8);
    for (int k = 0; k < 65; ++k)
        assert_true(lut->gx_um[k] == m.gx_um[k] && lut->gy_um[k] == m.gy_um[k]);
    assert_true(rep.rms_um == 0 && rep.max_um == 0);

    /* 4. Bad limits. */
    assert_int_equal(sc_lut_fit_grid(lut, &m, 1, "m.csv", &rep, &err), SC_E_INPUT);
    assert_int_equal(sc_lut_fit_grid(lut, &m, 102, "m.csv", &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "2..101"));
    sc_stage_map_free(&m);
    free(lut);
}

static void test_read_profile(void **state)
{
    (void)state;
    const char *path = TMP "prof.csv";
    sc_lut_profile *p = malloc(sizeof *p);
    assert_non_null(p);
    sc_error err;
    sc_error_clear(&err);
    write_text(path, "n,x_mm,f_um,uf_um,ey_um\n0,5.0,0.1,0.01,0.5\n1,5.5,0.2,0.01,-0.25\n"
                     "2,6.0,0.3,0.01,0.125\n3,6.5,0.4,0.01,\n4,7.0,0.5,0.01\n");
    assert_int_equal(sc_lut_read_profile(path, SC_CORR_AXIS_X, SC_CORR_AXIS_Y, p, &err), SC_OK);
    assert_int_equal(p->n, 3);
    assert_int_equal(p->axis, SC_CORR_AXIS_X);
    assert_int_equal(p->dir, SC_CORR_AXIS_Y);
    assert_true(fabs(p->start_mm - 5.0) < 1e-12 && fabs(p->step_mm - 0.5) < 1e-12);
    assert_true(p->err_um[0] == 0.5 && p->err_um[1] == -0.25 && p->err_um[2] == 0.125);

    struct {
        const char *text;
        long line;
        const char *word;
    } bad[] = {
        {"n,x_mm,f_um,uf_um,ey_um\n0,0,0,0,1\n1,1,0,0,\n2,2,0,0,3\n", 3, "empty"},
        {"n,x_mm,f_um,uf_um,ey_um\n0,0,0,0,1\n2,1,0,0,2\n", 3, "expected"},
        {"n,x_mm,f_um,uf_um,ey_um\n0,0,0,0,1\n1,1,0,0,2\n2,2.5,0,0,3\n3,3,0,0,3\n", 4, "irregular"},
        {"n,x_mm,f_um,uf_um,ey_um\n0,0,0,0,1\n1,1,0,0,x\n", 3, "ey_um"},
        {"n,x_mm,f_um,uf_um\n0,0,0,0\n", 1, "header"},
        {"n,x_mm,f_um,uf_um,ey_um\n0,0,0,0,1\n1,1,0,0,\n", 3, "at least 2"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        write_text(path, bad[k].text);
        sc_error_clear(&err);
        assert_int_equal(sc_lut_read_profile(path, 0, 1, p, &err), SC_E_INPUT);
        if (err.line != bad[k].line || !strstr(err.msg, bad[k].word))
            print_error("case %zu: line %ld msg '%s'\n", k, err.line, err.msg);
        assert_int_equal(err.line, bad[k].line);
        assert_non_null(strstr(err.msg, bad[k].word));
    }
    assert_int_equal(sc_lut_axis_from_name("X"), SC_CORR_AXIS_X);
    assert_int_equal(sc_lut_axis_from_name("z"), SC_CORR_AXIS_Z);
    assert_int_equal(sc_lut_axis_from_name("w"), -1);
    assert_int_equal(sc_lut_axis_from_name("xy"), -1);
    free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sha256_vectors),
        cmocka_unit_test(test_encode_decode_round_trip),
        cmocka_unit_test(test_encode_rejects),
        cmocka_unit_test(test_range_and_bounds),
        cmocka_unit_test(test_read_map),
        cmocka_unit_test(test_fit_grid),
        cmocka_unit_test(test_read_profile),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
