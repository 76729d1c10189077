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
                            (O_TMPFILE), named only at commit; 0: a named temporary file;
                            3: parked (sc_afile_park): complete under tmp_path, fp closed */
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
 * each complete). Parked entries (sc_afile_park) are renamed with the others; entries that are
 * neither open nor parked are skipped. */
SC_API sc_status sc_afile_commit_all(sc_afile *f, int n, sc_error *err);

/* Park one file of a group whose members outnumber the descriptors a process may hold: flush,
 * fsync and close it now, its content kept complete under its temporary name (fp becomes NULL),
 * until sc_afile_commit_all (or sc_afile_commit) renames it into place with the rest of the
 * group, or an abort removes it. A file written straight (stdout, a device) is committed here.
 * On failure the temporary file is removed and the error returned. A parked file no longer
 * holds its lock: another writer of the same final name committing meanwhile may remove it as
 * stale (the group's commit then fails with that name); only the first 64 temporary files a
 * process holds are removed on a signal (sc_afile_cleanup_on_signals), the others are left as
 * stale "PATH.tmpXXXXXX", which the next commit of that name removes. */
SC_API sc_status sc_afile_park(sc_afile *f, sc_error *err);

/* Abort every open or parked entry of f[0..n-1]. */
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
