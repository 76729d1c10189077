/* selfcal/profile_file.h — the straightness files of SPEC §2 (owned by io/): the measurement
 * `selfcal-profile v1` and the result `n,x_mm,f_um,uf_um,ey_um`, each with its data type, its one
 * strict reader and its one writer. Every reading problem is SC_E_INPUT with FILE:LINE.
 */
#ifndef SELFCAL_PROFILE_FILE_H
#define SELFCAL_PROFILE_FILE_H

#include "selfcal/api.h"
#include "selfcal/atomic_file.h"
#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Upper bound on N, so that a typo cannot ask for terabytes. */
#define SC_PROFILE_MAX_N 100000000

/* One measurement: two scans of the same profile with sensor spacings d[0]·s and d[1]·s. */
typedef struct sc_profile_data {
    int n;                 /* N: points on the profile, n = 0..N-1 */
    double s_mm;           /* sampling interval s (mm) */
    int d[2];              /* d1, d2: sensor spacings in samples */
    double *m1_um[2];      /* scan k: displacement sensor 1, N-d[k] values (µm) */
    double *m2_um[2];      /* scan k: displacement sensor 2, N-d[k] values (µm) */
    double *m3_urad[2];    /* scan k: angle sensor, N-d[k] values (µrad) */
    int has_sigma_disp;    /* 1 if sigma_disp_um is known (header line) */
    int has_sigma_angle;   /* 1 if sigma_angle_urad is known (header line) */
    double sigma_disp_um;  /* standard deviation of each displacement sensor (µm) */
    double sigma_angle_urad; /* standard deviation of the angle sensor (µrad) */
    long line_n;           /* line numbers of the "# N =" and "# scan k:" header lines in the */
    long line_scan[2];     /* file read (0 when not read from a file), for error messages */
    char path[256];        /* the file it was read from ("" if none) */
    /* Real rigs (SPEC §2a). A missing row, or an empty field, is NaN in its array (a gap). */
    int has_probe_gain;    /* 1 if "# probe_gain = K, U" was given (else K = 1, U = 0) */
    int has_angle_scale;   /* 1 if "# angle_scale = K, U" was given (else K = 1, U = 0) */
    int has_spacing_u;     /* 1 if "# spacing_u_mm = U" was given (else U = 0) */
    double probe_gain[2];  /* K, U: probe 2 reads K times what probe 1 reads (m2 is divided by K) */
    double angle_scale[2]; /* K, U: the angle sensor reads K times the true angle (m3 / K) */
    double spacing_u_mm;   /* standard uncertainty of each probe spacing D_k (mm) */
} sc_profile_data;

/* Does d lack any sample or field (a NaN in m1, m2 or m3 of either scan)? */
SC_API int sc_profile_has_gaps(const sc_profile_data *d);

/* Allocate the per-scan arrays of d for (n, s_mm, d1, d2) (zero-filled; no sigmas). */
SC_API sc_status sc_profile_data_init(sc_profile_data *d, int n, double s_mm, int d1, int d2,
                                      sc_error *err);

/* Free the arrays of d (d itself is the caller's); safe on a zeroed or freed struct. */
SC_API void sc_profile_data_free(sc_profile_data *d);

/* Read a `selfcal-profile v1` file strictly (SPEC §2, §2a): missing scan (or a scan without a
 * row), duplicates in n, n out of range, N too small for the spacings, non-numeric fields ->
 * SC_E_INPUT with file:line. Missing rows and empty fields are gaps: NaN in the arrays.
 * Method-specific conditions are checked by sc_profile_check_method. */
SC_API sc_status sc_profile_read(const char *path, sc_profile_data *out, sc_error *err);

/* Called by sc_profile_read_hooked once the header has been read and the first 1/32 of the rows
 * found good: hdr holds the header's fields (n, s_mm, d, the noise, path and lines) and no
 * arrays. */
typedef void (*sc_profile_header_fn)(void *ctx, const sc_profile_data *hdr);

/* sc_profile_read, calling on_header(ctx, hdr) once when the header has been read and found valid
 * and the first 1/32 of the rows it promises were read without fault (once whatever passes the
 * reader makes over the file; never for a file whose header is wrong, nor for one whose rows go
 * wrong or end before: a header of N = 10^8 and two rows starts no work of that size; and only
 * for a regular file, whose size bounds its N: never for a pipe),
 * so that work depending on the header alone (sc_profile_calibration_create) can overlap the
 * reading of the rows. The rows may still be found wrong after it was called. */
SC_API sc_status sc_profile_read_hooked(const char *path, sc_profile_header_fn on_header,
                                        void *ctx, sc_profile_data *out, sc_error *err);

/* Write d as a `selfcal-profile v1` file atomically (each number with the fewest digits that read
 * back exactly, selfcal/number.h; the sigma and instrument lines only when known; a NaN field is
 * left empty, a row of three NaN is left out). */
SC_API sc_status sc_profile_write(const char *path, const sc_profile_data *d, sc_error *err);

/* Write the output file `n,x_mm,f_um,uf_um,ey_um` atomically: f, uf (may be NULL: empty column)
 * have n values, ey has n_ey values (empty where index >= n_ey). */
SC_API sc_status sc_profile_write_result(const char *path, int n, double s_mm, const double *f_um,
                                         const double *uf_um, const double *ey_um, int n_ey,
                                         sc_error *err);

/* The same into f, an atomic file the caller opened (sc_afile_open) and ends — sc_afile_finish,
 * or sc_afile_finish_all with the command's other outputs, so that all are written or none:
 * nothing is committed or aborted here. */
SC_API sc_status sc_profile_write_to(sc_afile *f, const sc_profile_data *d, sc_error *err);
SC_API sc_status sc_profile_write_result_to(sc_afile *f, int n, double s_mm, const double *f_um,
                                            const double *uf_um, const double *ey_um, int n_ey,
                                            sc_error *err);

/* Write the residual file `scan,n,r_um,t,outlier` (SPEC §2a) into f (the caller ends it): one row
 * per sample of scan 1 then scan 2 (n - d[k] each); r, t empty where NaN; outlier 1 where
 * outlier[k][j] != 0. */
SC_API sc_status sc_profile_write_residuals_to(sc_afile *f, int n, const int d[2],
                                               const double *const r_um[2],
                                               const double *const t[2],
                                               const unsigned char *const outlier[2],
                                               sc_error *err);

/* A profile result (or truth) file read back. */
typedef struct sc_profile_result {
    int n;
    double *x_mm, *f_um, *uf_um, *ey_um; /* n values each; uf, ey NaN where empty */
    int n_ey;                            /* rows with an ey_um value (they come first) */
    int has_uf, has_ey;                  /* the file has the column */
    long header_line, last_line;         /* where the column header was; last line read */
} sc_profile_result;

/* Read a profile output file strictly. Rules (SC_E_INPUT with FILE:LINE):
 * - blank and '#' lines skipped; the column header names n, x_mm and f_um, optionally uf_um and
 *   ey_um, in any order, further columns ignored;
 * - rows have the header's field count (the last field may be left out when it is uf_um or
 *   ey_um: empty); n counts 0, 1, 2, ...; n, x_mm, f_um present; numbers finite, |v| <= 1e6;
 * - x_mm regular: within 1e-3 step of the line through the first and last point, increasing;
 * - ey_um empty only as a tail (e_y has N - d1 values); at least one row. */
SC_API sc_status sc_profile_read_result(const char *path, sc_profile_result *out, sc_error *err);

/* Free the arrays of r. */
SC_API void sc_profile_result_free(sc_profile_result *r);

#ifdef __cplusplus
}
#endif
#endif
