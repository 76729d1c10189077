/* selfcal/atomic_file.h — write a file so that a crash never leaves half of it under its name.
 *
 * Writes go to a temporary file in the same directory: anonymous (O_TMPFILE) where the file system
 * supports it, so a killed writer leaves nothing, else named "PATH.tmpXXXXXX"; commit flushes,
 * fsyncs, links an anonymous one to that name, renames it over the final name, fsyncs the
 * directory and removes stale "PATH.tmpXXXXXX" files whose writer is gone (none holds their
 * flock); abort removes the temporary file.
 */
#ifndef SELFCAL_ATOMIC_FILE_H
#define SELFCAL_ATOMIC_FILE_H

#include "selfcal/api.h"

#include <stdio.h>

#include "selfcal/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sc_afile {
    FILE *fp;            /* write through this between open and commit/abort */
    char path[4096];     /* the final name */
    char tmp_path[4096]; /* the temporary file ("" when written straight) */
    int direct;          /* 1: stdout, or an existing device or FIFO (/dev/null): written
                            straight, never replaced; 2: an anonymous temporary file
                            (O_TMPFILE), named only at commit; 0: a named temporary file */
} sc_afile;

/* Create the temporary file for path ("-" writes straight to stdout; so does an existing
 * character device or FIFO such as /dev/null, which a rename would replace; a directory or other
 * non-regular file is SC_E_INPUT). The new file gets the permissions of the file it replaces, or
 * 0666 less the umask, as any new file. A symbolic link to a file is written through: the file
 * it points to is replaced and the link kept (f->path is then that file). */
SC_API sc_status sc_afile_open(sc_afile *f, const char *path, sc_error *err);

/* Flush, fsync, rename to the final name; on failure the temporary file is removed. */
SC_API sc_status sc_afile_commit(sc_afile *f, sc_error *err);

/* Discard everything written; the final name is untouched. Safe after commit (does nothing). */
SC_API void sc_afile_abort(sc_afile *f);

/* Commit n files as one group: flush and fsync every temporary file first and rename them into
 * place only if all were written completely; a write failure removes every temporary file and
 * touches no final name (a rename refused by the OS midway leaves the files renamed before it,
 * each complete). Entries that are not open (fp == NULL) are skipped. */
SC_API sc_status sc_afile_commit_all(sc_afile *f, int n, sc_error *err);

/* Abort every open entry of f[0..n-1]. */
SC_API void sc_afile_abort_all(sc_afile *f, int n);

/* End one file that was being written: commit it when st is SC_OK, else abort it and return st
 * unchanged (its message stays in err). */
SC_API sc_status sc_afile_finish(sc_afile *f, sc_status st, sc_error *err);

/* End a group that was being written: commit it (sc_afile_commit_all) when st is SC_OK, else
 * abort every entry and return st unchanged (its message stays in err). */
SC_API sc_status sc_afile_finish_all(sc_afile *f, int n, sc_status st, sc_error *err);

/* For programs (the CLI calls it first thing): on SIGINT, SIGTERM, SIGHUP and SIGQUIT remove
 * every temporary file still open, then die of the signal as before; SIGXFSZ is ignored, so a
 * file beyond `ulimit -f` fails its write (EFBIG) like a full disk instead of killing. A group committed with
 * sc_afile_commit_all is renamed with those signals blocked, so a signal leaves either the old
 * set or the new set, never a mix. Signals the process ignores stay ignored. Process-wide (a
 * signal handler is); without this call nothing is installed. */
SC_API void sc_afile_cleanup_on_signals(void);

/* Write len bytes to path atomically in one call. */
SC_API sc_status sc_write_file_atomic(const char *path, const void *data, size_t len,
                                      sc_error *err);

#ifdef __cplusplus
}
#endif
#endif
