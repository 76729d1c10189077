/* correct_load.c — validate a table image once and decode it into the caller's sc_corr_table.
 *
 * Freestanding: only <stddef.h>, <stdint.h>, <float.h>, <limits.h>. The byte layout is in
 * lut_format.h and docs/lut-format.md.
 */
#include <float.h>
#include <limits.h>
#include <stddef.h>
#include <stdint.h>

#include "correct_reason.h"
#include "lut_format.h"
#include "selfcal/correct.h"

/* CRC-32, reflected polynomial 0xEDB88320, one nibble at a time: a 64-byte table keeps the code
 * small for microcontrollers, and loading is done once. */
static const uint32_t crc_nibble[16] = {
    0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u,
    0x4DB26158u, 0x5005713Cu, 0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
    0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu};

uint32_t sc_corr_crc32(const void *buf, size_t len)
{
    const uint8_t *p = (const uint8_t *)buf;
    uint32_t c = 0xFFFFFFFFu;
    for (size_t k = 0; k < len; ++k) {
        c ^= p[k];
        c = (c >> 4) ^ crc_nibble[c & 15u];
        c = (c >> 4) ^ crc_nibble[c & 15u];
    }
    return c ^ 0xFFFFFFFFu;
}

const char *sc_corr_strerror(int code)
{
    switch (code) {
    case SC_CORR_OK:
        return "ok";
    case SC_CORR_E_SIZE:
        return "truncated or wrong length: the size disagrees with the table header";
    case SC_CORR_E_MAGIC:
        return "not a selfcal table (bad magic bytes)";
    case SC_CORR_E_VERSION:
        return "unsupported table format version";
    case SC_CORR_E_CRC:
        return "checksum mismatch: the table is corrupted";
    case SC_CORR_E_RANGE:
        return "a table field is out of range";
    case SC_CORR_E_CAPACITY:
        return "the table is larger than this build supports";
    default:
        return "unknown table error";
    }
}

/* Finite and within +-limit (false for NaN: comparisons with NaN are false). */
static int within(double x, double limit)
{
    return x >= -limit && x <= limit;
}

static int all_zero(const uint8_t *p, size_t n)
{
    for (size_t k = 0; k < n; ++k)
        if (p[k] != 0)
            return 0;
    return 1;
}

/* A scale with which no code of encoding enc leaves +-SC_LUTF_MAX_VALUE_PM (a scale that could
 * express metres, e.g. 1e9 pm per code, is refused even if the codes are small). */
static int scale_ok(uint32_t scale_pm, unsigned enc)
{
    return scale_pm >= 1u && scale_pm <= (enc == SC_LUTF_ENC_INT16 ? SC_LUTF_MAX_SCALE_PM_INT16
                                                                     : SC_LUTF_MAX_SCALE_PM_INT32);
}

/* The failure code with its reason (correct_reason.h) in *why, when asked for. */
static int fail(unsigned char *why, int code, unsigned char reason)
{
    if (why)
        *why = reason;
    return code;
}

/* Checks a profile header; 0 or an error code (the reason in *why, may be NULL). */
static int check_profile_header(const uint8_t *h, unsigned char *why)
{
    unsigned axis = h[SC_LUTF_POFF_AXIS], dir = h[SC_LUTF_POFF_DIR], enc = h[SC_LUTF_POFF_ENC];
    uint16_t n = sc_lutf_get_u16(h + SC_LUTF_POFF_N);
    double start = sc_lutf_get_f64(h + SC_LUTF_POFF_START), step = sc_lutf_get_f64(h + SC_LUTF_POFF_STEP);
    if (axis > SC_CORR_AXIS_Z || dir > SC_CORR_AXIS_Z)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_AXIS);
    if (enc != SC_LUTF_ENC_INT16 && enc != SC_LUTF_ENC_INT32)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_ENC);
    if (h[SC_LUTF_POFF_RESERVED0] != 0 || sc_lutf_get_u16(h + SC_LUTF_POFF_RESERVED1) != 0)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_RESERVED);
    if (n < 2)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_N);
    if (!within(start, SC_LUTF_MAX_ABS_MM) || !within(start + step * (double)(n - 1), SC_LUTF_MAX_ABS_MM))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_EXTENT);
    if (!(step >= SC_LUTF_MIN_PITCH_MM))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_STEP);
    if (!scale_ok(sc_lutf_get_u32(h + SC_LUTF_POFF_SCALE), enc))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILE_SCALE);
    return SC_CORR_OK;
}

static float decode(const uint8_t *p, unsigned enc, double um_per_code)
{
    return (float)((double)sc_lutf_get_code(p, enc) * um_per_code);
}

/* The validated layout of a table image. */
typedef struct layout {
    unsigned nx, ny, np, genc;
    double x0, y0, px, py, x1, y1;
    uint32_t gscale;
    uint64_t poff[SC_LUTF_MAX_PROFILES];
} layout;

/* The envelope: size, magic, version, the file-size field and the CRC over the whole image. */
static int check_envelope(const uint8_t *b, size_t len, unsigned char *why)
{
    if (!b || len < (size_t)SC_LUTF_HEADER_BYTES + SC_LUTF_CRC_BYTES)
        return fail(why, SC_CORR_E_SIZE, SC_CORR_R_SHORT);
    for (unsigned k = 0; k < SC_LUTF_MAGIC_LEN; ++k)
        if (b[k] != sc_lutf_magic[k])
            return fail(why, SC_CORR_E_MAGIC, SC_CORR_R_MAGIC);
    if (sc_lutf_get_u16(b + SC_LUTF_OFF_VERSION) != SC_LUTF_VERSION)
        return fail(why, SC_CORR_E_VERSION, SC_CORR_R_VERSION);
    if ((uint64_t)sc_lutf_get_u32(b + SC_LUTF_OFF_FILE_BYTES) != (uint64_t)len)
        return fail(why, SC_CORR_E_SIZE, SC_CORR_R_FILE_BYTES);
    if (sc_corr_crc32(b, len - SC_LUTF_CRC_BYTES) != sc_lutf_get_u32(b + len - SC_LUTF_CRC_BYTES))
        return fail(why, SC_CORR_E_CRC, SC_CORR_R_CRC);
    return SC_CORR_OK;
}

/* The header's grid fields (counts, encoding, origin, pitch, extent, scale) into *L. */
static int check_header(const uint8_t *b, layout *L, unsigned char *why)
{
    unsigned nx = sc_lutf_get_u16(b + SC_LUTF_OFF_NX), ny = sc_lutf_get_u16(b + SC_LUTF_OFF_NY);
    unsigned np = b[SC_LUTF_OFF_NPROFILES], genc = b[SC_LUTF_OFF_GRID_ENC];
    double x0 = sc_lutf_get_f64(b + SC_LUTF_OFF_X0), y0 = sc_lutf_get_f64(b + SC_LUTF_OFF_Y0);
    double px = sc_lutf_get_f64(b + SC_LUTF_OFF_PX), py = sc_lutf_get_f64(b + SC_LUTF_OFF_PY);
    uint32_t gscale = sc_lutf_get_u32(b + SC_LUTF_OFF_GRID_SCALE);
    if (sc_lutf_get_u16(b + SC_LUTF_OFF_HEADER_BYTES) != SC_LUTF_HEADER_BYTES || sc_lutf_get_u16(b + SC_LUTF_OFF_RESERVED) != 0)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_HEADER);
    if (nx < 2 || ny < 2)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_GRID_N);
    if (np > SC_LUTF_MAX_PROFILES)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PROFILES);
    if (genc != SC_LUTF_ENC_INT16 && genc != SC_LUTF_ENC_INT32)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_GRID_ENC);
    if (!within(x0, SC_LUTF_MAX_ABS_MM) || !within(y0, SC_LUTF_MAX_ABS_MM))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_ORIGIN);
    if (!(px >= SC_LUTF_MIN_PITCH_MM) || !(py >= SC_LUTF_MIN_PITCH_MM))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_PITCH);
    double x1 = x0 + px * (double)(nx - 1), y1 = y0 + py * (double)(ny - 1);
    if (!within(x1, SC_LUTF_MAX_ABS_MM) || !within(y1, SC_LUTF_MAX_ABS_MM))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_EXTENT);
    if (!scale_ok(gscale, genc))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_GRID_SCALE);
    L->nx = nx;
    L->ny = ny;
    L->np = np;
    L->genc = genc;
    L->x0 = x0;
    L->y0 = y0;
    L->px = px;
    L->py = py;
    L->x1 = x1;
    L->y1 = y1;
    L->gscale = gscale;
    return SC_CORR_OK;
}

/* The blocks after the header: the grid, then each profile (its header checked, its offset in
 * L->poff), each inside the body; the offset of the provenance block in *prov_off. 64-bit
 * offsets: nx * ny * 8 does not overflow them. */
static int check_blocks(const uint8_t *b, size_t len, layout *L, uint64_t *prov_off, unsigned char *why)
{
    const uint64_t body_end = (uint64_t)len - SC_LUTF_CRC_BYTES;
    uint64_t off = SC_LUTF_HEADER_BYTES;
    off += 2u * (uint64_t)L->nx * L->ny * sc_lutf_code_bytes(L->genc);
    for (unsigned k = 0; k < L->np; ++k) {
        if (off + SC_LUTF_PROFILE_HEADER_BYTES > body_end)
            return fail(why, SC_CORR_E_SIZE, SC_CORR_R_BLOCKS_PAST_END);
        const uint8_t *h = b + (size_t)off;
        int rc = check_profile_header(h, why);
        if (rc != SC_CORR_OK)
            return rc;
        L->poff[k] = off;
        off += SC_LUTF_PROFILE_HEADER_BYTES + (uint64_t)sc_lutf_get_u16(h + SC_LUTF_POFF_N) * sc_lutf_code_bytes(h[SC_LUTF_POFF_ENC]);
    }
    *prov_off = off;
    return SC_CORR_OK;
}

/* The provenance block at pv, prov bytes long: method a NUL-terminated string, sigma finite
 * (negative = unknown), count <= 9, reserved bytes zero, one SHA-256 per source. */
static int check_provenance(const uint8_t *pv, uint32_t prov, unsigned char *why)
{
    if (pv[SC_LUTF_METHOD_BYTES - 1] != 0)
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_METHOD);
    if (!within(sc_lutf_get_f64(pv + SC_LUTF_VOFF_SIGMA), DBL_MAX))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_SIGMA);
    unsigned nsrc = pv[SC_LUTF_VOFF_COUNT];
    if (nsrc > SC_LUTF_MAX_SOURCES || !all_zero(pv + SC_LUTF_VOFF_RESERVED, 7))
        return fail(why, SC_CORR_E_RANGE, SC_CORR_R_SOURCES);
    if (prov != SC_LUTF_PROV_FIXED_BYTES + nsrc * SC_LUTF_SHA256_BYTES)
        return fail(why, SC_CORR_E_SIZE, SC_CORR_R_PROV_SIZE);
    return SC_CORR_OK;
}

/* Every format check (size, magic, version, CRC, ranges, layout); fills *L; the reason of a
 * failure in *why (may be NULL). Layout: every block must lie inside the file, and the blocks
 * must fill it exactly. */
static int check_image(const uint8_t *b, size_t len, layout *L, unsigned char *why)
{
    int rc = check_envelope(b, len, why);
    if (rc == SC_CORR_OK)
        rc = check_header(b, L, why);
    uint64_t off = 0;
    if (rc == SC_CORR_OK)
        rc = check_blocks(b, len, L, &off, why);
    if (rc != SC_CORR_OK)
        return rc;
    const uint64_t body_end = (uint64_t)len - SC_LUTF_CRC_BYTES;
    uint32_t prov = sc_lutf_get_u32(b + SC_LUTF_OFF_PROV_BYTES);
    if (off + SC_LUTF_PROV_FIXED_BYTES > body_end || off + prov != body_end)
        return fail(why, SC_CORR_E_SIZE, SC_CORR_R_BLOCKS_FILL);
    return check_provenance(b + (size_t)off, prov, why);
}

/* Whether a valid image L fits this build's capacity; the reason in *why (may be NULL). */
static int check_capacity(const uint8_t *b, const layout *L, unsigned char *why)
{
    if (L->nx > SC_CORR_MAX_NX || L->ny > SC_CORR_MAX_NY)
        return fail(why, SC_CORR_E_CAPACITY, SC_CORR_R_CAP_GRID);
    if (L->np > SC_CORR_MAX_PROFILES)
        return fail(why, SC_CORR_E_CAPACITY, SC_CORR_R_CAP_PROFILES);
    for (unsigned k = 0; k < L->np; ++k)
        if (sc_lutf_get_u16(b + (size_t)L->poff[k] + SC_LUTF_POFF_N) > SC_CORR_MAX_PROFILE_POINTS)
            return fail(why, SC_CORR_E_CAPACITY, SC_CORR_R_CAP_POINTS);
    return SC_CORR_OK;
}

unsigned sc_corr_check_reason(const void *buf, size_t len)
{
    layout L;
    unsigned char why = SC_CORR_R_OK;
    if (check_image((const uint8_t *)buf, len, &L, &why) == SC_CORR_OK)
        check_capacity((const uint8_t *)buf, &L, &why);
    return why;
}

int sc_corr_validate(const void *buf, size_t len)
{
    layout L;
    return check_image((const uint8_t *)buf, len, &L, NULL);
}

int sc_corr_load(sc_corr_table *t, const void *buf, size_t len)
{
    if (!t)
        return SC_CORR_E_RANGE;
    t->loaded = 0;
    const uint8_t *b = (const uint8_t *)buf;
    layout L;
    int rc = check_image(b, len, &L, NULL);
    if (rc != SC_CORR_OK)
        return rc;
    const unsigned nx = L.nx, ny = L.ny, np = L.np, genc = L.genc;
    const uint64_t *poff = L.poff;
    const uint64_t ncells = (uint64_t)nx * ny;

    /* Valid: does it fit this build? */
    if ((rc = check_capacity(b, &L, NULL)) != SC_CORR_OK)
        return rc;

    /* Decode. */
    t->nx = (uint16_t)nx;
    t->ny = (uint16_t)ny;
    t->x0_mm = L.x0;
    t->y0_mm = L.y0;
    t->px_mm = L.px;
    t->py_mm = L.py;
    t->inv_px = 1.0 / L.px;
    t->inv_py = 1.0 / L.py;
    t->in_lo_mm[0] = L.x0 - SC_CORR_EDGE_TOL * L.px;
    t->in_lo_mm[1] = L.y0 - SC_CORR_EDGE_TOL * L.py;
    t->in_hi_mm[0] = L.x1 + SC_CORR_EDGE_TOL * L.px;
    t->in_hi_mm[1] = L.y1 + SC_CORR_EDGE_TOL * L.py;
    t->lastx = (double)(nx - 1);
    t->lasty = (double)(ny - 1);
    const double gum = (double)L.gscale * 1e-6;
    const unsigned gcb = sc_lutf_code_bytes(genc);
    const uint8_t *gx = b + SC_LUTF_HEADER_BYTES, *gy = gx + (size_t)ncells * gcb;
    for (size_t k = 0; k < (size_t)ncells; ++k) {
        t->g_um[k][0] = decode(gx + k * gcb, genc, gum);
        t->g_um[k][1] = decode(gy + k * gcb, genc, gum);
    }
    for (size_t k = (size_t)ncells; k <= (size_t)ncells + nx; ++k)
        t->g_um[k][0] = t->g_um[k][1] = 0; /* the padding (see correct.h) */
    t->n_profiles = (uint8_t)np;
    for (unsigned k = 0; k < np; ++k) {
        const uint8_t *h = b + (size_t)poff[k];
        sc_corr_profile *p = &t->profile[k];
        p->axis = h[SC_LUTF_POFF_AXIS];
        p->dir = h[SC_LUTF_POFF_DIR];
        p->n = sc_lutf_get_u16(h + SC_LUTF_POFF_N);
        p->start_mm = sc_lutf_get_f64(h + SC_LUTF_POFF_START);
        p->step_mm = sc_lutf_get_f64(h + SC_LUTF_POFF_STEP);
        p->inv_step = 1.0 / p->step_mm;
        p->last = (double)(p->n - 1);
        const double pum = (double)sc_lutf_get_u32(h + SC_LUTF_POFF_SCALE) * 1e-6;
        const unsigned enc = h[SC_LUTF_POFF_ENC], cb = sc_lutf_code_bytes(enc);
        for (unsigned m = 0; m < p->n; ++m)
            p->err_um[m] = decode(h + SC_LUTF_PROFILE_HEADER_BYTES + m * cb, enc, pum);
        p->err_um[p->n] = 0; /* the padding */
    }
#if !SC_CORR_COMPACT
    /* The pair layout (correct.h); the padding slot reads two zero values with weight 1 and 0
     * and adds them to no coordinate. */
    t->p_slots = (uint8_t)(np + (np & 1u));
    for (unsigned k = 0; k < t->p_slots; ++k) {
        const int real = k < np;
        const sc_corr_profile *p = &t->profile[k];
        if (!real)
            t->profile[k].err_um[0] = t->profile[k].err_um[1] = 0;
        t->p_start_mm[k] = real ? p->start_mm : 0.0;
        t->p_inv_step[k] = real ? p->inv_step : 0.0;
        t->p_last[k] = real ? p->last : 0.0;
        t->p_axis[k] = real ? p->axis : 0u;
        for (unsigned d = 0; d < 4; ++d)
            t->p_dir_mask[k][d] = real && p->dir == (d < 3 ? d : 2u) ? UINT64_MAX : 0u;
    }
#endif
    t->loaded = 1;
    return SC_CORR_OK;
}
