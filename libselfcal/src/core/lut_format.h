/* lut_format.h — the byte layout of a selfcal table file (format version 1), shared by the
 * freestanding correction core (which reads it) and the host table writer in src/lut (which
 * writes it). Internal header: not installed. Documented for users in docs/lut-format.md.
 *
 * Everything is little-endian, whatever the host. Reals are IEEE-754 binary64 (f64).
 *
 *   offset size  field
 *   0      8     magic "SCLUT" 0x0D 0x0A 0x1A
 *   8      2     u16 version (1)
 *   10     2     u16 header bytes (64)
 *   12     4     u32 file bytes (the whole file, CRC included)
 *   16     2     u16 nx (nodes along x, >= 2)
 *   18     2     u16 ny (nodes along y, >= 2)
 *   20     1     u8  profile count (0..8)
 *   21     1     u8  grid encoding (1 = int16, 2 = int32)
 *   22     2     u16 reserved, 0
 *   24     8     f64 x0_mm (node (0,0))
 *   32     8     f64 y0_mm
 *   40     8     f64 px_mm (pitch along x, > 0)
 *   48     8     f64 py_mm (pitch along y, > 0)
 *   56     4     u32 grid scale in picometres per code (>= 1)
 *   60     4     u32 provenance bytes
 *   64           grid: Gx codes for nodes i*nx+j (i along y), then Gy codes; value = code * scale
 *   ...          profiles, each a 28-byte header + n codes:
 *                  u8 axis, u8 dir, u8 encoding, u8 reserved 0, u16 n (>= 2), u16 reserved 0,
 *                  f64 start_mm, f64 step_mm (> 0), u32 scale_pm
 *   ...          provenance (its size in the header):
 *                  char method[32] (NUL-padded), i64 created (Unix seconds, UTC),
 *                  f64 sigma_um (< 0: not known), u8 source count (0..9), u8 reserved[7] = 0,
 *                  32-byte SHA-256 per source (map first, then the profiles in order)
 *   end-4  4     u32 CRC-32 (IEEE 802.3, reflected, as zlib) of all bytes before it
 */
#ifndef SELFCAL_LUT_FORMAT_H
#define SELFCAL_LUT_FORMAT_H

#include <stddef.h>
#include <stdint.h>

#define SC_LUTF_MAGIC_0 0x53u /* 'S' */
#define SC_LUTF_MAGIC_LEN 8
#define SC_LUTF_VERSION 1u
#define SC_LUTF_HEADER_BYTES 64u
#define SC_LUTF_PROFILE_HEADER_BYTES 28u
#define SC_LUTF_CRC_BYTES 4u
#define SC_LUTF_ENC_INT16 1u
#define SC_LUTF_ENC_INT32 2u
#define SC_LUTF_MAX_PROFILES 8u
#define SC_LUTF_METHOD_BYTES 32u
#define SC_LUTF_PROV_FIXED_BYTES 56u /* method 32 + created 8 + sigma 8 + count 1 + reserved 7 */
#define SC_LUTF_MAX_SOURCES 9u
#define SC_LUTF_SHA256_BYTES 32u
/* Range limits checked at load (beyond the structural ones). */
#define SC_LUTF_MAX_ABS_MM 1.0e6        /* |origin|, |start|, extent: within +-1 km */
#define SC_LUTF_MIN_PITCH_MM 1.0e-6     /* 1 nm */
/* Every value a block can express (largest |code| x scale) lies within +-2^31 pm
 * (+-2147.483648 um): int16 codes take a scale of at most 65536 pm, int32 codes only 1 pm. */
#define SC_LUTF_MAX_VALUE_PM 2147483648u
#define SC_LUTF_MAX_SCALE_PM_INT16 65536u
#define SC_LUTF_MAX_SCALE_PM_INT32 1u

/* Byte offsets of the header fields (from the start of the file). */
#define SC_LUTF_OFF_VERSION 8u
#define SC_LUTF_OFF_HEADER_BYTES 10u
#define SC_LUTF_OFF_FILE_BYTES 12u
#define SC_LUTF_OFF_NX 16u
#define SC_LUTF_OFF_NY 18u
#define SC_LUTF_OFF_NPROFILES 20u
#define SC_LUTF_OFF_GRID_ENC 21u
#define SC_LUTF_OFF_RESERVED 22u
#define SC_LUTF_OFF_X0 24u
#define SC_LUTF_OFF_Y0 32u
#define SC_LUTF_OFF_PX 40u
#define SC_LUTF_OFF_PY 48u
#define SC_LUTF_OFF_GRID_SCALE 56u
#define SC_LUTF_OFF_PROV_BYTES 60u
/* ... of a profile header (from its start). */
#define SC_LUTF_POFF_AXIS 0u
#define SC_LUTF_POFF_DIR 1u
#define SC_LUTF_POFF_ENC 2u
#define SC_LUTF_POFF_RESERVED0 3u
#define SC_LUTF_POFF_N 4u
#define SC_LUTF_POFF_RESERVED1 6u
#define SC_LUTF_POFF_START 8u
#define SC_LUTF_POFF_STEP 16u
#define SC_LUTF_POFF_SCALE 24u
/* ... of the provenance block (from its start). */
#define SC_LUTF_VOFF_METHOD 0u
#define SC_LUTF_VOFF_CREATED 32u
#define SC_LUTF_VOFF_SIGMA 40u
#define SC_LUTF_VOFF_COUNT 48u
#define SC_LUTF_VOFF_RESERVED 49u

static const uint8_t sc_lutf_magic[SC_LUTF_MAGIC_LEN] = {'S', 'C', 'L', 'U', 'T', 0x0D, 0x0A, 0x1A};

static inline uint16_t sc_lutf_get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static inline uint32_t sc_lutf_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static inline uint64_t sc_lutf_get_u64(const uint8_t *p)
{
    return (uint64_t)sc_lutf_get_u32(p) | ((uint64_t)sc_lutf_get_u32(p + 4) << 32);
}

static inline double sc_lutf_get_f64(const uint8_t *p)
{
    union {
        uint64_t u;
        double d;
    } v;
    v.u = sc_lutf_get_u64(p);
    return v.d;
}

static inline int32_t sc_lutf_get_code(const uint8_t *p, unsigned enc)
{
    if (enc == SC_LUTF_ENC_INT16)
        return (int32_t)(int16_t)sc_lutf_get_u16(p);
    return (int32_t)sc_lutf_get_u32(p);
}

static inline unsigned sc_lutf_code_bytes(unsigned enc)
{
    return enc == SC_LUTF_ENC_INT16 ? 2u : 4u;
}

static inline void sc_lutf_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static inline void sc_lutf_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static inline void sc_lutf_put_u64(uint8_t *p, uint64_t v)
{
    sc_lutf_put_u32(p, (uint32_t)v);
    sc_lutf_put_u32(p + 4, (uint32_t)(v >> 32));
}

static inline void sc_lutf_put_f64(uint8_t *p, double d)
{
    union {
        uint64_t u;
        double d;
    } v;
    v.d = d;
    sc_lutf_put_u64(p, v.u);
}

#endif
