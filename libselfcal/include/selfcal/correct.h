/* selfcal/correct.h — the correction core: validate a lookup table once, then correct positions
 * in constant time without allocating.
 *
 * Freestanding C: this header and its implementation use only <stddef.h>, <stdint.h>,
 * <float.h> and <limits.h>, so the same code runs in selfcald and on a microcontroller.
 * The table structure is fixed-size and owned by the caller (static storage in the daemon);
 * sc_corr_apply only reads it, so several threads may call it on one table.
 * The sizes below may be lowered at compile time for small targets, and SC_CORR_COMPACT (below)
 * selects float storage of the decoded values. The fields of sc_corr_table are the decoded table
 * laid out for sc_corr_apply (some duplicated, padded and aligned for it): read them, never
 * write them.
 */
#ifndef SELFCAL_CORRECT_H
#define SELFCAL_CORRECT_H

#include "selfcal/api.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#ifndef SC_CORR_MAX_NX
#define SC_CORR_MAX_NX 101 /* grid nodes along x */
#endif
#ifndef SC_CORR_MAX_NY
#define SC_CORR_MAX_NY 101 /* grid nodes along y */
#endif
#ifndef SC_CORR_MAX_PROFILES
#define SC_CORR_MAX_PROFILES 8
#endif
#ifndef SC_CORR_MAX_PROFILE_POINTS
#define SC_CORR_MAX_PROFILE_POINTS 2048
#endif

/* Storage of the decoded node and profile values (micrometres). The default, double, is what
 * apply computes in, so no conversion is done per call (host). SC_CORR_COMPACT=1 stores floats
 * instead: half the RAM, for targets without a double-precision FPU, where it is the default (a
 * 32-bit Arm without __ARM_FP bit 3, e.g. Cortex-M4F). Either way the stored values are the
 * decoded values rounded to float, so both layouts give the same corrections. */
#ifndef SC_CORR_COMPACT
#if (defined(__arm__) || defined(__thumb__)) && !(defined(__ARM_FP) && (__ARM_FP & 8))
#define SC_CORR_COMPACT 1
#else
#define SC_CORR_COMPACT 0
#endif
#endif
#if SC_CORR_COMPACT
typedef float sc_corr_value;
#else
typedef double sc_corr_value;
#endif

/* 16-byte alignment of the pairs apply loads at once (hosts; nothing for SC_CORR_COMPACT). */
#if defined(__GNUC__) && !SC_CORR_COMPACT
#define SC_CORR_ALIGN16 __attribute__((aligned(16)))
#else
#define SC_CORR_ALIGN16
#endif

/* Profile slots: SC_CORR_MAX_PROFILES rounded up to even (apply may take profiles in pairs). */
#define SC_CORR_PROFILE_SLOTS (SC_CORR_MAX_PROFILES + (SC_CORR_MAX_PROFILES & 1))

/* Status bits returned by sc_corr_apply (the same bits as the Modbus status register). */
#define SC_CORR_ST_LOADED 0x01u  /* a valid table is loaded */
#define SC_CORR_ST_OUTSIDE 0x02u /* the position was outside the table: clamped */
#define SC_CORR_ST_INVALID 0x04u /* the input was NaN or infinite: returned unchanged */

typedef enum sc_corr_mode {
    SC_CORR_MEASURE = 0,      /* input: indicated position p; output p - G(p) - profile offsets */
    SC_CORR_POSITION = 1,     /* input: target; output target + G(target) + profile offsets */
    SC_CORR_MEASURE_EXACT = 2 /* input: indicated p; output q with q + C(q) = p (C = G + offsets),
                                 by SC_CORR_EXACT_ITERATIONS fixed-point steps: the inverse of
                                 position mode; measure mode is its first step */
} sc_corr_mode;

/* Fixed-point steps of SC_CORR_MEASURE_EXACT. After k steps from q = p the error is at most
 * L^k |C| (L: the largest slope of C, um per um; |C|: the largest correction): measure mode's
 * first-order error L |C| (G·grad G) becomes L^3 |C|, 1e-10 um for L = 1e-4 and |C| = 100 um,
 * below the float rounding of the stored values (docs/lut-format.md). */
#define SC_CORR_EXACT_ITERATIONS 3

/* Axis / direction codes for profiles. */
enum { SC_CORR_AXIS_X = 0, SC_CORR_AXIS_Y = 1, SC_CORR_AXIS_Z = 2 };

typedef struct sc_corr_profile {
    uint8_t axis;      /* the coordinate the error is a function of */
    uint8_t dir;       /* the coordinate the error applies to */
    uint16_t n;        /* points */
    double start_mm;   /* position of point 0 */
    double step_mm;    /* spacing (> 0) */
    double inv_step;   /* 1 / step_mm, computed at load */
    double last;       /* n - 1 as a double, computed at load */
    /* decoded values (float-rounded); err_um[n] = 0 pads the end (see g_um) */
    sc_corr_value err_um[SC_CORR_MAX_PROFILE_POINTS + 1];
} sc_corr_profile;

/* The tolerance, in pitches, of the test whether a position is outside the grid: 1e-9 of a pitch
 * (1.27e-8 mm at 12.7 mm), far below any stage's resolution, far above the rounding of a grid's
 * edge position (a few 1e-16 of it). */
#define SC_CORR_EDGE_TOL 1e-9

typedef struct sc_corr_table {
    /* x and y pairs first, 16-byte aligned on hosts so that apply loads each pair at once. */
    double x0_mm SC_CORR_ALIGN16, y0_mm; /* position of node (0, 0) */
    /* inside the grid: [in_lo, in_hi] along x and y, the first and last nodes' positions widened
     * by SC_CORR_EDGE_TOL of a pitch, computed at load (an edge node is inside however its
     * position rounds: a table's fitted origin and pitch can end the grid 1e-15 mm short) */
    double in_lo_mm[2] SC_CORR_ALIGN16;
    double in_hi_mm[2] SC_CORR_ALIGN16;
    double inv_px SC_CORR_ALIGN16, inv_py; /* 1 / pitch, computed at load */
    double lastx SC_CORR_ALIGN16, lasty;   /* nx - 1 and ny - 1 as doubles, computed at load */
    double px_mm, py_mm;   /* pitch along x and y */
    uint32_t loaded;       /* 1 after a successful sc_corr_load */
    uint16_t nx, ny;       /* grid nodes along x and y */
    uint8_t n_profiles;
#if !SC_CORR_COMPACT
    /* The profiles again, laid out for apply on hosts, which takes them two at a time: slot m
     * holds profile m's AXIS, start_mm, inv_step and last, and bit masks (all ones or zero) that
     * select its DIR. An odd count is padded with a slot that adds exactly 0. Computed at load. */
    uint8_t p_slots; /* n_profiles rounded up to even */
    uint8_t p_axis[SC_CORR_PROFILE_SLOTS];
    double p_start_mm[SC_CORR_PROFILE_SLOTS] SC_CORR_ALIGN16;
    double p_inv_step[SC_CORR_PROFILE_SLOTS] SC_CORR_ALIGN16;
    double p_last[SC_CORR_PROFILE_SLOTS] SC_CORR_ALIGN16;
    uint64_t p_dir_mask[SC_CORR_PROFILE_SLOTS][4] SC_CORR_ALIGN16; /* ones in lane d if DIR is
                                                                      d; lane 3 = lane 2 */
#endif
    /* G of node (i, j) at k = i*nx + j (i along y): g_um[k][0] = Gx, g_um[k][1] = Gy (pairs, so
     * that one load fetches both); decoded values rounded to float. nx + 1 zero pairs follow the
     * last node, so that apply may take the cell of the last node with weight 0 on its
     * neighbours (no index clamp). */
    sc_corr_value g_um[SC_CORR_MAX_NX * SC_CORR_MAX_NY + SC_CORR_MAX_NX + 1][2] SC_CORR_ALIGN16;
    sc_corr_profile profile[SC_CORR_PROFILE_SLOTS];
} sc_corr_table;

/* Error codes of sc_corr_load (0 = success). */
enum {
    SC_CORR_OK = 0,
    SC_CORR_E_SIZE = -1,     /* buffer too short or its length disagrees with the header */
    SC_CORR_E_MAGIC = -2,    /* not a selfcal table */
    SC_CORR_E_VERSION = -3,  /* unsupported format version */
    SC_CORR_E_CRC = -4,      /* checksum mismatch */
    SC_CORR_E_RANGE = -5,    /* a field is out of range (sizes, pitch, non-finite values) */
    SC_CORR_E_CAPACITY = -6  /* valid, but larger than this build's SC_CORR_MAX_* */
};

/* CRC-32 (IEEE 802.3 polynomial, reflected, initial and final XOR 0xFFFFFFFF: the zlib/PNG
 * CRC) of len bytes; the table file's checksum. crc32("123456789") = 0xCBF43926. */
SC_API uint32_t sc_corr_crc32(const void *buf, size_t len);

/* Validate a table image (the LUT file's bytes) and decode it into *t. On failure *t is marked
 * not loaded and the code says why. All the expensive work happens here, once. */
SC_API int sc_corr_load(sc_corr_table *t, const void *buf, size_t len);

/* Every format check of sc_corr_load (size, magic, version, CRC, ranges, layout) without decoding
 * and without this build's capacity limits: SC_CORR_OK or the first problem found. */
SC_API int sc_corr_validate(const void *buf, size_t len);

/* A constant, one-line description of a load error code. */
SC_API const char *sc_corr_strerror(int code);

/* Why sc_corr_load refuses this image, in one constant line naming the field or block ("the
 * grid's pitch is not finite or below 1e-6 mm"); "ok" if it would load. For messages only: it
 * runs every check again. */
SC_API const char *sc_corr_explain(const void *buf, size_t len);

/* What loaded table t can command: *max_correction_um, the largest correction of one coordinate
 * (um: the largest |node value| of Gx or Gy, plus the largest |value| of each profile of that
 * DIR; bilinear and linear interpolation stay within it) and *max_gradient_um_per_mm, the steepest
 * change between neighbouring grid nodes (along x or y) or profile points (um per mm). */
SC_API void sc_corr_bounds(const sc_corr_table *t, double *max_correction_um,
                           double *max_gradient_um_per_mm);

/* Correct one position (mm; z passes through unless a profile has DIR z). Returns status bits.
 * NaN or infinite input: out = in, SC_CORR_ST_INVALID set. Constant time, no allocation. */
SC_API unsigned sc_corr_apply(const sc_corr_table *t, sc_corr_mode mode, const double in_mm[3],
                              double out_mm[3]);

/* measure mode solved exactly: find p_true with p_true + G(p_true) + offsets = p by fixed-point
 * iteration (iterations: fixed count, e.g. 3). Returns status bits like sc_corr_apply. */
SC_API unsigned sc_corr_apply_inverse(const sc_corr_table *t, const double in_mm[3],
                                      double out_mm[3], int iterations);

#ifdef __cplusplus
}
#endif
#endif
