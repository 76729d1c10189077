/* selfcal/sha256.h — SHA-256 (FIPS 180-4), for the provenance of lookup tables: the table
 * records the hash of each source file, comparable with `sha256sum`. */
#ifndef SELFCAL_SHA256_H
#define SELFCAL_SHA256_H

#include "selfcal/api.h"

#include <stddef.h>
#include <stdint.h>

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SC_SHA256_BYTES 32

typedef struct sc_sha256 {
    uint32_t h[8];
    uint64_t nbytes;   /* bytes hashed so far */
    uint8_t block[64]; /* the partial block */
    size_t nblock;
} sc_sha256;

/* Start a new hash. */
SC_API void sc_sha256_init(sc_sha256 *s);

/* Add len bytes. */
SC_API void sc_sha256_update(sc_sha256 *s, const void *data, size_t len);

/* Finish and write the 32-byte digest; s must be initialised again before reuse. */
SC_API void sc_sha256_final(sc_sha256 *s, uint8_t digest[SC_SHA256_BYTES]);

/* The digest of a whole file (SC_E_IO if it cannot be read). */
SC_API sc_status sc_sha256_file(const char *path, uint8_t digest[SC_SHA256_BYTES], sc_error *err);

/* Lower-case hex of a digest into hex (65 bytes with the NUL). */
SC_API void sc_sha256_hex(const uint8_t digest[SC_SHA256_BYTES], char hex[2 * SC_SHA256_BYTES + 1]);

#ifdef __cplusplus
}
#endif
#endif
