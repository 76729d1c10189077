/* lut_codec.c — encode and decode the binary table file (layout: src/core/lut_format.h and
 * docs/lut-format.md), write and read it, and evaluate the map bilinearly in double precision. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/lut_format.h"
#include "selfcal/atomic_file.h"
#include "selfcal/correct.h"
#include "selfcal/csv.h"
#include "selfcal/lut.h"

void sc_lut_init(sc_lut *lut)
{
    lut->nx = lut->ny = 0;
    lut->x0_mm = lut->y0_mm = 0.0;
    lut->px_mm = lut->py_mm = 0.0;
    lut->grid_encoding = 0;
    lut->grid_scale_pm = 0;
    lut->n_profiles = 0;
    memset(&lut->prov, 0, sizeof lut->prov);
    lut->prov.sigma_um = -1.0;
}

int sc_lut_axis_from_name(const char *s)
{
    if (!s || !s[0] || s[1])
        return -1;
    switch (s[0]) {
    case 'x':
    case 'X':
        return SC_CORR_AXIS_X;
    case 'y':
    case 'Y':
        return SC_CORR_AXIS_Y;
    case 'z':
    case 'Z':
        return SC_CORR_AXIS_Z;
    default:
        return -1;
    }
}

const char *sc_lut_axis_name(int axis)
{
    return axis == SC_CORR_AXIS_X ? "x" : axis == SC_CORR_AXIS_Y ? "y" : axis == SC_CORR_AXIS_Z ? "z" : "?";
}

double sc_lut_quantization_um(uint32_t scale_pm)
{
    return 0.5e-6 * (double)scale_pm;
}

/* Largest |v| of a block, or -1 if a value is not finite. */
static double block_max_abs(const double *a, size_t n, const double *b, size_t nb)
{
    double m = 0.0;
    for (size_t k = 0; k < n; ++k) {
        if (!isfinite(a[k]))
            return -1.0;
        m = fmax(m, fabs(a[k]));
    }
    for (size_t k = 0; k < nb; ++k) {
        if (!isfinite(b[k]))
            return -1.0;
        m = fmax(m, fabs(b[k]));
    }
    return m;
}

/* Smallest 1-2-5 x 10^k picometre scale, at most max_scale, with max_abs_um / scale <= limit
 * codes; 0 if none. */
static uint32_t choose_scale(double max_abs_um, double limit, uint32_t max_scale)
{
    static const uint32_t mant[3] = {1, 2, 5};
    double need_pm = max_abs_um * 1e6 / limit;
    for (uint32_t dec = 1; dec <= 100000000u; dec *= 10u)
        for (int k = 0; k < 3; ++k) {
            uint32_t s = mant[k] * dec;
            if ((double)s >= need_pm && s <= max_scale)
                return s;
        }
    return 0;
}

/* Pick encoding and scale of a block; 0 on success. */
static int choose_block(double max_abs_um, sc_lut_encoding want, int *enc, uint32_t *scale)
{
    uint32_t s16 = choose_scale(max_abs_um, 32767.0, SC_LUTF_MAX_SCALE_PM_INT16);
    uint32_t s32 = choose_scale(max_abs_um, 2147483647.0, SC_LUTF_MAX_SCALE_PM_INT32);
    if (want == SC_LUT_ENC_INT16 || (want == SC_LUT_ENC_AUTO && s16 != 0 && s16 <= SC_LUT_AUTO_MAX_INT16_SCALE_PM)) {
        if (s16 == 0)
            return -1;
        *enc = SC_LUTF_ENC_INT16;
        *scale = s16;
        return 0;
    }
    if (s32 == 0)
        return -1;
    *enc = SC_LUTF_ENC_INT32;
    *scale = s32;
    return 0;
}

static size_t code_bytes(int enc)
{
    return enc == SC_LUTF_ENC_INT16 ? 2u : 4u;
}

/* Encoding of a block for size computation without modifying the table. */
static int block_encoding(const double *a, size_t n, const double *b, size_t nb, sc_lut_encoding want)
{
    int enc = SC_LUTF_ENC_INT32;
    uint32_t s;
    double m = block_max_abs(a, n, b, nb);
    if (m >= 0.0 && choose_block(m, want, &enc, &s) != 0)
        enc = SC_LUTF_ENC_INT32;
    return enc;
}

size_t sc_lut_encoded_size(const sc_lut *lut, sc_lut_encoding enc)
{
    size_t cells = (size_t)lut->nx * (size_t)lut->ny;
    size_t size = SC_LUTF_HEADER_BYTES;
    size += 2 * cells * code_bytes(block_encoding(lut->gx_um, cells, lut->gy_um, cells, enc));
    for (int k = 0; k < lut->n_profiles; ++k) {
        const sc_lut_profile *p = &lut->profile[k];
        size += SC_LUTF_PROFILE_HEADER_BYTES +
                (size_t)p->n * code_bytes(block_encoding(p->err_um, (size_t)p->n, NULL, 0, enc));
    }
    size += SC_LUTF_PROV_FIXED_BYTES + (size_t)lut->prov.n_sources * SC_LUTF_SHA256_BYTES;
    return size + SC_LUTF_CRC_BYTES;
}

static uint8_t *put_codes(uint8_t *w, const double *v, size_t n, int enc, uint32_t scale_pm)
{
    for (size_t k = 0; k < n; ++k) {
        long long c = llround(v[k] * 1e6 / (double)scale_pm);
        if (enc == SC_LUTF_ENC_INT16) {
            sc_lutf_put_u16(w, (uint16_t)(int16_t)c);
            w += 2;
        } else {
            sc_lutf_put_u32(w, (uint32_t)(int32_t)c);
            w += 4;
        }
    }
    return w;
}

static int pos_ok(double x)
{
    return isfinite(x) && fabs(x) <= SC_LUTF_MAX_ABS_MM;
}

/* The grid of a table to encode: node counts, origin, pitch and extent. */
static sc_status check_encodable_grid(const sc_lut *lut, sc_error *err)
{
    if (lut->nx < 2 || lut->ny < 2 || lut->nx > SC_LUT_MAX_NX || lut->ny > SC_LUT_MAX_NY)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "grid of %d x %d nodes: need 2..%d along x and 2..%d along y", lut->nx,
                            lut->ny, SC_LUT_MAX_NX, SC_LUT_MAX_NY);
    if (!pos_ok(lut->x0_mm) || !pos_ok(lut->y0_mm) || !(lut->px_mm >= SC_LUTF_MIN_PITCH_MM) ||
        !(lut->py_mm >= SC_LUTF_MIN_PITCH_MM) ||
        !pos_ok(lut->x0_mm + lut->px_mm * (lut->nx - 1)) ||
        !pos_ok(lut->y0_mm + lut->py_mm * (lut->ny - 1)))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "grid origin/pitch out of range (pitch >= 1 nm, |position| <= 1 km)");
    return SC_OK;
}

/* Profile k of a table to encode: axis, direction, point count, step and positions. */
static sc_status check_encodable_profile(const sc_lut_profile *p, int k, sc_error *err)
{
    if (p->axis < 0 || p->axis > 2 || p->dir < 0 || p->dir > 2)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "profile %d: axis/dir must be x, y or z", k);
    if (p->n < 2 || p->n > SC_LUT_MAX_PROFILE_POINTS)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "profile %d: %d points, need 2..%d", k,
                            p->n, SC_LUT_MAX_PROFILE_POINTS);
    if (!pos_ok(p->start_mm) || !(p->step_mm >= SC_LUTF_MIN_PITCH_MM) ||
        !pos_ok(p->start_mm + p->step_mm * (p->n - 1)))
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "profile %d: step %g mm (at least 1 nm) or positions %g .. %g mm "
                            "(within 1 km) out of range",
                            k, p->step_mm, p->start_mm, p->start_mm + p->step_mm * (p->n - 1));
    return SC_OK;
}

/* The provenance of a table to encode: source count, method name, sigma. */
static sc_status check_encodable_provenance(const sc_lut *lut, sc_error *err)
{
    if (lut->prov.n_sources < 0 || lut->prov.n_sources > SC_LUT_MAX_SOURCES)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "%d source hashes: at most %d",
                            lut->prov.n_sources, SC_LUT_MAX_SOURCES);
    if (memchr(lut->prov.method, '\0', SC_LUT_METHOD_LEN) == NULL)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "method name longer than %d characters",
                            SC_LUT_METHOD_LEN - 1);
    if (!isfinite(lut->prov.sigma_um))
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "sigma is not finite");
    return SC_OK;
}

/* The checks a table must pass before encoding, with messages for people. */
static sc_status check_encodable(const sc_lut *lut, sc_error *err)
{
    sc_status st = check_encodable_grid(lut, err);
    if (st != SC_OK)
        return st;
    if (lut->n_profiles < 0 || lut->n_profiles > SC_LUT_MAX_PROFILES)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "%d profiles: at most %d", lut->n_profiles,
                            SC_LUT_MAX_PROFILES);
    for (int k = 0; k < lut->n_profiles; ++k)
        if ((st = check_encodable_profile(&lut->profile[k], k, err)) != SC_OK)
            return st;
    return check_encodable_provenance(lut, err);
}

/* The fixed header of a table of `size` bytes with grid encoding genc and scale gscale. */
static void put_header(uint8_t *buf, const sc_lut *lut, size_t size, int genc, uint32_t gscale)
{
    memcpy(buf, sc_lutf_magic, SC_LUTF_MAGIC_LEN);
    sc_lutf_put_u16(buf + SC_LUTF_OFF_VERSION, SC_LUTF_VERSION);
    sc_lutf_put_u16(buf + SC_LUTF_OFF_HEADER_BYTES, SC_LUTF_HEADER_BYTES);
    sc_lutf_put_u32(buf + SC_LUTF_OFF_FILE_BYTES, (uint32_t)size);
    sc_lutf_put_u16(buf + SC_LUTF_OFF_NX, (uint16_t)lut->nx);
    sc_lutf_put_u16(buf + SC_LUTF_OFF_NY, (uint16_t)lut->ny);
    buf[SC_LUTF_OFF_NPROFILES] = (uint8_t)lut->n_profiles;
    buf[SC_LUTF_OFF_GRID_ENC] = (uint8_t)genc;
    sc_lutf_put_f64(buf + SC_LUTF_OFF_X0, lut->x0_mm);
    sc_lutf_put_f64(buf + SC_LUTF_OFF_Y0, lut->y0_mm);
    sc_lutf_put_f64(buf + SC_LUTF_OFF_PX, lut->px_mm);
    sc_lutf_put_f64(buf + SC_LUTF_OFF_PY, lut->py_mm);
    sc_lutf_put_u32(buf + SC_LUTF_OFF_GRID_SCALE, gscale);
    sc_lutf_put_u32(buf + SC_LUTF_OFF_PROV_BYTES,
                    (uint32_t)(SC_LUTF_PROV_FIXED_BYTES +
                               (size_t)lut->prov.n_sources * SC_LUTF_SHA256_BYTES));
}

/* The provenance block at w; returns the byte after it. */
static uint8_t *put_provenance(uint8_t *w, const sc_lut *lut)
{
    memcpy(w, lut->prov.method, SC_LUT_METHOD_LEN);
    sc_lutf_put_u64(w + SC_LUTF_VOFF_CREATED, (uint64_t)lut->prov.created_unix_s);
    sc_lutf_put_f64(w + SC_LUTF_VOFF_SIGMA, lut->prov.sigma_um < 0.0 ? -1.0 : lut->prov.sigma_um);
    w[SC_LUTF_VOFF_COUNT] = (uint8_t)lut->prov.n_sources;
    w += SC_LUTF_PROV_FIXED_BYTES;
    for (int k = 0; k < lut->prov.n_sources; ++k, w += SC_LUTF_SHA256_BYTES)
        memcpy(w, lut->prov.sha256[k], SC_LUTF_SHA256_BYTES);
    return w;
}

sc_status sc_lut_encode(sc_lut *lut, sc_lut_encoding enc, uint8_t *buf, size_t cap, size_t *len,
                        sc_error *err)
{
    if (enc != SC_LUT_ENC_AUTO && enc != SC_LUT_ENC_INT16 && enc != SC_LUT_ENC_INT32)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "unknown encoding %d (auto, int16, int32)",
                            (int)enc);
    sc_status st = check_encodable(lut, err);
    if (st != SC_OK)
        return st;
    size_t cells = (size_t)lut->nx * (size_t)lut->ny;
    int genc;
    uint32_t gscale;
    double m = block_max_abs(lut->gx_um, cells, lut->gy_um, cells);
    if (m < 0.0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "the map has a non-finite value");
    if (choose_block(m, enc, &genc, &gscale) != 0)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "map value %g um beyond the table format's range (+-2147.48 um; "
                            "+-1638.35 um with int16 codes)", m);
    int penc[SC_LUT_MAX_PROFILES];
    uint32_t pscale[SC_LUT_MAX_PROFILES];
    for (int k = 0; k < lut->n_profiles; ++k) {
        sc_lut_profile *p = &lut->profile[k];
        double pm = block_max_abs(p->err_um, (size_t)p->n, NULL, 0);
        if (pm < 0.0)
            return sc_error_set(err, SC_E_INPUT, NULL, 0, "profile %d has a non-finite value", k);
        if (choose_block(pm, enc, &penc[k], &pscale[k]) != 0)
            return sc_error_set(err, SC_E_INPUT, NULL, 0,
                                "profile %d value %g um beyond the table format's range "
                                "(+-2147.48 um; +-1638.35 um with int16 codes)", k, pm);
    }
    size_t size = sc_lut_encoded_size(lut, enc);
    if (size > cap || size > UINT32_MAX)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "table needs %zu bytes, buffer has %zu", size,
                            cap);

    memset(buf, 0, size);
    put_header(buf, lut, size, genc, gscale);
    uint8_t *w = buf + SC_LUTF_HEADER_BYTES;
    w = put_codes(w, lut->gx_um, cells, genc, gscale);
    w = put_codes(w, lut->gy_um, cells, genc, gscale);
    for (int k = 0; k < lut->n_profiles; ++k) {
        const sc_lut_profile *p = &lut->profile[k];
        w[SC_LUTF_POFF_AXIS] = (uint8_t)p->axis;
        w[SC_LUTF_POFF_DIR] = (uint8_t)p->dir;
        w[SC_LUTF_POFF_ENC] = (uint8_t)penc[k];
        sc_lutf_put_u16(w + SC_LUTF_POFF_N, (uint16_t)p->n);
        sc_lutf_put_f64(w + SC_LUTF_POFF_START, p->start_mm);
        sc_lutf_put_f64(w + SC_LUTF_POFF_STEP, p->step_mm);
        sc_lutf_put_u32(w + SC_LUTF_POFF_SCALE, pscale[k]);
        w = put_codes(w + SC_LUTF_PROFILE_HEADER_BYTES, p->err_um, (size_t)p->n, penc[k], pscale[k]);
    }
    w = put_provenance(w, lut);
    if ((size_t)(w - buf) != size - SC_LUTF_CRC_BYTES)
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "table layout mismatch");
    sc_lutf_put_u32(w, sc_corr_crc32(buf, size - SC_LUTF_CRC_BYTES));
    int rc = sc_corr_validate(buf, size);
    if (rc != SC_CORR_OK)
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "encoded table fails validation: %s",
                            sc_corr_strerror(rc));
    lut->grid_encoding = genc;
    lut->grid_scale_pm = gscale;
    for (int k = 0; k < lut->n_profiles; ++k) {
        lut->profile[k].encoding = penc[k];
        lut->profile[k].scale_pm = pscale[k];
    }
    *len = size;
    return SC_OK;
}

static void get_codes(const uint8_t *r, double *v, size_t n, unsigned enc, uint32_t scale_pm)
{
    size_t cb = code_bytes((int)enc);
    for (size_t k = 0; k < n; ++k)
        v[k] = (double)sc_lutf_get_code(r + k * cb, enc) * (double)scale_pm * 1e-6;
}

sc_status sc_lut_decode(const uint8_t *buf, size_t len, sc_lut *lut, const char *name,
                        sc_error *err)
{
    if (sc_corr_validate(buf, len) != SC_CORR_OK)
        return sc_error_set(err, SC_E_INPUT, name, 0, "not a valid table: %s",
                            sc_corr_explain(buf, len));
    sc_lut_init(lut);
    int nx = sc_lutf_get_u16(buf + SC_LUTF_OFF_NX), ny = sc_lutf_get_u16(buf + SC_LUTF_OFF_NY);
    if (nx > SC_LUT_MAX_NX || ny > SC_LUT_MAX_NY)
        return sc_error_set(err, SC_E_INPUT, name, 0, "grid of %d x %d nodes: this build reads up to %d x %d",
                            nx, ny, SC_LUT_MAX_NX, SC_LUT_MAX_NY);
    lut->nx = nx;
    lut->ny = ny;
    lut->n_profiles = buf[SC_LUTF_OFF_NPROFILES];
    lut->grid_encoding = buf[SC_LUTF_OFF_GRID_ENC];
    lut->x0_mm = sc_lutf_get_f64(buf + SC_LUTF_OFF_X0);
    lut->y0_mm = sc_lutf_get_f64(buf + SC_LUTF_OFF_Y0);
    lut->px_mm = sc_lutf_get_f64(buf + SC_LUTF_OFF_PX);
    lut->py_mm = sc_lutf_get_f64(buf + SC_LUTF_OFF_PY);
    lut->grid_scale_pm = sc_lutf_get_u32(buf + SC_LUTF_OFF_GRID_SCALE);
    size_t cells = (size_t)nx * (size_t)ny, cb = code_bytes(lut->grid_encoding);
    const uint8_t *r = buf + SC_LUTF_HEADER_BYTES;
    get_codes(r, lut->gx_um, cells, (unsigned)lut->grid_encoding, lut->grid_scale_pm);
    get_codes(r + cells * cb, lut->gy_um, cells, (unsigned)lut->grid_encoding, lut->grid_scale_pm);
    r += 2 * cells * cb;
    for (int k = 0; k < lut->n_profiles; ++k) {
        sc_lut_profile *p = &lut->profile[k];
        p->axis = r[SC_LUTF_POFF_AXIS];
        p->dir = r[SC_LUTF_POFF_DIR];
        p->encoding = r[SC_LUTF_POFF_ENC];
        p->n = sc_lutf_get_u16(r + SC_LUTF_POFF_N);
        if (p->n > SC_LUT_MAX_PROFILE_POINTS)
            return sc_error_set(err, SC_E_INPUT, name, 0,
                                "profile %d has %d points: this build reads up to %d", k, p->n,
                                SC_LUT_MAX_PROFILE_POINTS);
        p->start_mm = sc_lutf_get_f64(r + SC_LUTF_POFF_START);
        p->step_mm = sc_lutf_get_f64(r + SC_LUTF_POFF_STEP);
        p->scale_pm = sc_lutf_get_u32(r + SC_LUTF_POFF_SCALE);
        get_codes(r + SC_LUTF_PROFILE_HEADER_BYTES, p->err_um, (size_t)p->n, (unsigned)p->encoding,
                  p->scale_pm);
        r += SC_LUTF_PROFILE_HEADER_BYTES + (size_t)p->n * code_bytes(p->encoding);
    }
    memcpy(lut->prov.method, r, SC_LUT_METHOD_LEN);
    lut->prov.created_unix_s = (int64_t)sc_lutf_get_u64(r + SC_LUTF_VOFF_CREATED);
    lut->prov.sigma_um = sc_lutf_get_f64(r + SC_LUTF_VOFF_SIGMA);
    lut->prov.n_sources = r[SC_LUTF_VOFF_COUNT];
    r += SC_LUTF_PROV_FIXED_BYTES;
    for (int k = 0; k < lut->prov.n_sources; ++k, r += SC_LUTF_SHA256_BYTES)
        memcpy(lut->prov.sha256[k], r, SC_LUTF_SHA256_BYTES);
    return SC_OK;
}

sc_status sc_lut_write_file(const char *path, sc_lut *lut, sc_lut_encoding enc, sc_error *err)
{
    sc_status st = check_encodable(lut, err);
    if (st != SC_OK)
        return st;
    size_t cap = sc_lut_encoded_size(lut, enc), len = 0;
    uint8_t *buf = malloc(cap);
    if (!buf)
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (%zu bytes)", cap);
    st = sc_lut_encode(lut, enc, buf, cap, &len, err);
    if (st == SC_OK)
        st = sc_write_file_atomic(path, buf, len, err);
    free(buf);
    return st;
}

/* Refuse files far larger than any table this build reads (a 101 x 101 int32 map and eight
 * 2048-point int32 profiles take about 150 KB). */
#define SC_LUT_MAX_FILE_BYTES (1u << 20)

/* Read a whole table file into a new buffer (*buf, *len; the caller frees *buf). */
static sc_status read_table_bytes(const char *path, uint8_t **buf, size_t *len, sc_error *err)
{
    *buf = NULL;
    *len = 0;
    FILE *f = sc_open_input(path, err);
    if (!f)
        return err ? err->code : SC_E_INPUT;
    uint8_t *b = malloc(SC_LUT_MAX_FILE_BYTES + 1);
    if (!b) {
        fclose(f);
        return sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    size_t n = fread(b, 1, SC_LUT_MAX_FILE_BYTES + 1, f);
    int bad = ferror(f);
    fclose(f);
    sc_status st = SC_OK;
    if (bad)
        st = sc_error_set(err, SC_E_IO, path, 0, "read error");
    else if (n > SC_LUT_MAX_FILE_BYTES)
        st = sc_error_set(err, SC_E_INPUT, path, 0, "not a valid table: larger than %u bytes",
                          SC_LUT_MAX_FILE_BYTES);
    if (st != SC_OK) {
        free(b);
        return st;
    }
    *buf = b;
    *len = n;
    return SC_OK;
}

sc_status sc_lut_read_file(const char *path, sc_lut *lut, sc_error *err)
{
    uint8_t *buf;
    size_t len;
    sc_status st = read_table_bytes(path, &buf, &len, err);
    if (st == SC_OK)
        st = sc_lut_decode(buf, len, lut, path, err);
    free(buf);
    return st;
}

sc_status sc_lut_load_corr_file(const char *path, sc_corr_table *t, sc_error *err)
{
    uint8_t *buf;
    size_t len;
    t->loaded = 0;
    sc_status st = read_table_bytes(path, &buf, &len, err);
    if (st != SC_OK)
        return st;
    int rc = sc_corr_load(t, buf, len);
    if (rc != SC_CORR_OK)
        sc_error_set(err, SC_E_INPUT, path, 0, "%s: %s",
                     rc == SC_CORR_E_CAPACITY ? "table larger than this build reads"
                                              : "not a valid table",
                     sc_corr_explain(buf, len));
    free(buf);
    return rc == SC_CORR_OK ? SC_OK : SC_E_INPUT;
}

/* Cell index and fraction along one axis for coordinate u in node units. */
static int cell_of(double u, int n, double *f)
{
    if (u < 0.0)
        u = 0.0;
    if (u > n - 1)
        u = n - 1;
    int k = (int)u;
    if (k > n - 2)
        k = n - 2;
    *f = u - k;
    return k;
}

bool sc_lut_grid_eval(const sc_lut *lut, double x_mm, double y_mm, double *gx_um, double *gy_um)
{
    if (lut->nx < 2 || lut->ny < 2) { /* no grid (sc_lut_init) */
        *gx_um = *gy_um = NAN;
        return true;
    }
    double x1 = lut->x0_mm + lut->px_mm * (lut->nx - 1);
    double y1 = lut->y0_mm + lut->py_mm * (lut->ny - 1);
    double tx = SC_CORR_EDGE_TOL * lut->px_mm, ty = SC_CORR_EDGE_TOL * lut->py_mm; /* correct.h */
    bool outside = x_mm < lut->x0_mm - tx || x_mm > x1 + tx || y_mm < lut->y0_mm - ty ||
                   y_mm > y1 + ty;
    double x = fmin(fmax(x_mm, lut->x0_mm), x1), y = fmin(fmax(y_mm, lut->y0_mm), y1);
    double fx, fy;
    int j = cell_of((x - lut->x0_mm) / lut->px_mm, lut->nx, &fx);
    int i = cell_of((y - lut->y0_mm) / lut->py_mm, lut->ny, &fy);
    size_t k = (size_t)i * lut->nx + j, kn = k + lut->nx;
    *gx_um = (lut->gx_um[k] * (1 - fx) + lut->gx_um[k + 1] * fx) * (1 - fy) +
             (lut->gx_um[kn] * (1 - fx) + lut->gx_um[kn + 1] * fx) * fy;
    *gy_um = (lut->gy_um[k] * (1 - fx) + lut->gy_um[k + 1] * fx) * (1 - fy) +
             (lut->gy_um[kn] * (1 - fx) + lut->gy_um[kn + 1] * fx) * fy;
    return outside;
}

static void steeper(double *worst, double a, double b, double step_mm)
{
    double g = fabs(b - a) / step_mm;
    if (g > *worst)
        *worst = g;
}

void sc_lut_bounds(const sc_lut *lut, double *max_correction_um, double *max_gradient_um_per_mm)
{
    double axis_um[3] = {0, 0, 0}, grad = 0;
    for (int c = 0; c < 2; ++c) {
        const double *g = c == 0 ? lut->gx_um : lut->gy_um;
        for (int i = 0; i < lut->ny; ++i)
            for (int j = 0; j < lut->nx; ++j) {
                size_t k = (size_t)i * (size_t)lut->nx + (size_t)j;
                axis_um[c] = fmax(axis_um[c], fabs(g[k]));
                if (j + 1 < lut->nx)
                    steeper(&grad, g[k], g[k + 1], lut->px_mm);
                if (i + 1 < lut->ny)
                    steeper(&grad, g[k], g[k + (size_t)lut->nx], lut->py_mm);
            }
    }
    for (int k = 0; k < lut->n_profiles; ++k) {
        const sc_lut_profile *p = &lut->profile[k];
        double m = 0;
        for (int n = 0; n < p->n; ++n) {
            m = fmax(m, fabs(p->err_um[n]));
            if (n + 1 < p->n)
                steeper(&grad, p->err_um[n], p->err_um[n + 1], p->step_mm);
        }
        if (p->dir >= 0 && p->dir < 3)
            axis_um[p->dir] += m;
    }
    *max_correction_um = fmax(axis_um[0], fmax(axis_um[1], axis_um[2]));
    *max_gradient_um_per_mm = grad;
}
