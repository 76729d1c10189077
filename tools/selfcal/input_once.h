/* input_once.h — an input that a command reads and whose bytes it records (SHA-256, size): a pipe,
 * FIFO or terminal is read once, into memory, and read again from there (input_once.c). */
#ifndef SELFCAL_INPUT_ONCE_H
#define SELFCAL_INPUT_ONCE_H

#include <stdint.h>

#include "selfcal/sha256.h"

#define CLI_INPUT_MAX_LIVE 16                         /* snapshots alive at once (lut build: 9) */
#define CLI_INPUT_MAX_SPOOL ((long long)2 << 30)      /* bytes a pipe may bring: 2 GiB */

typedef struct cli_input {
    const char *orig; /* the name as given */
    const char *path; /* what the readers open: orig, or the in-memory copy's /proc/self/fd/N */
    char proc_path[32];
    int fd;           /* the copy (memfd), or -1 */
    int hashed;       /* sha256 and size known (the copy's) */
    uint8_t sha256[SC_SHA256_BYTES];
    long long size;
} cli_input;

/* in for path: a regular file (or a name that does not exist: the reader will say so) is left
 * where it is; anything else ("-", standard input, too) is copied into memory while hashed (at
 * most CLI_INPUT_MAX_SPOOL bytes, else SC_E_INPUT; text: refused at a NUL byte, as its reader
 * would). in must stay at its address until cli_input_close. */
sc_status cli_input_open(cli_input *in, const char *path, int text, sc_error *err);

/* The input's SHA-256 and size in bytes: the copy's, or read from the file now. */
sc_status cli_input_sha256(const cli_input *in, uint8_t digest[SC_SHA256_BYTES], long long *size,
                           sc_error *err);

/* Free the copy (path is orig again). */
void cli_input_close(cli_input *in);

/* cli_input_open of paths[0..n-1] into in[], in order, input k binary (not text) where bit k of
 * binary is set; stops at the first failure. *opened: the entries to cli_input_close_all. */
sc_status cli_input_open_all(cli_input *in, const char *const *paths, int n, unsigned binary,
                             int *opened, sc_error *err);
void cli_input_close_all(cli_input *in, int n);

/* In a message about a copy, its name as the user gave it (cli_report calls this). */
void cli_input_rename_in_error(sc_error *err);

#endif
