/* atomic_file.c — owns writing files so that a crash never leaves half of one under its name
 * (temporary file, fsync, rename, directory fsync; groups of files committed together).
 *
 * The temporary file is anonymous where the file system supports it (O_TMPFILE, Linux >= 3.11 on
 * ext4, xfs, btrfs, tmpfs...): a writer killed before its commit leaves nothing behind. At commit
 * it is fsynced, linked to "PATH.tmpXXXXXX" (linkat) and renamed over PATH. Elsewhere the
 * temporary file is created under that name from the start. Either way the writer holds an
 * exclusive flock on its temporary file until it is renamed, and each successful commit removes
 * the stale "PATH.tmpXXXXXX" files (six letters or digits) nobody holds: those of a writer killed
 * between link and rename, or during a write without O_TMPFILE (as SQLite's next writer cleans up
 * a journal left by a crash). */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* O_TMPFILE */
#endif
#include "selfcal/atomic_file.h"
#include "selfcal/rng.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* Temporary files a signal must not leave behind. Only used once a program asked for it with
 * sc_afile_cleanup_on_signals (process-wide by nature: a signal is); the paths are copied, so the
 * handler never follows a pointer into a caller's frame. */
#define SC_AFILE_TRACKED 64
/* A slot is claimed by one thread at a time (0 free, 2 being filled, 1 tracked: the handler
 * reads only those), so threads writing files at once never share one; lock-free atomics are
 * safe to read in a signal handler. */
static char g_tracked_path[SC_AFILE_TRACKED][4096];
static atomic_int g_tracked_used[SC_AFILE_TRACKED];
static volatile sig_atomic_t g_tracking;
/* Group commits in progress (another thread may take the signal: OpenBLAS workers do not block
 * it; a count, since threads may commit at once), and the signal that arrived meanwhile, acted
 * on once the last group is in place. */
static atomic_int g_in_commit;
static volatile sig_atomic_t g_pending_sig;

static void block_signals(sigset_t *old)
{
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGHUP);
    sigaddset(&set, SIGQUIT);
    sigprocmask(SIG_BLOCK, &set, old);
}

static void restore_signals(const sigset_t *old)
{
    sigprocmask(SIG_SETMASK, old, NULL);
}

static void track(const sc_afile *f)
{
    if (!g_tracking)
        return;
    for (int k = 0; k < SC_AFILE_TRACKED; ++k) {
        int free_slot = 0;
        if (atomic_compare_exchange_strong(&g_tracked_used[k], &free_slot, 2)) {
            memcpy(g_tracked_path[k], f->tmp_path, sizeof g_tracked_path[k]);
            atomic_store(&g_tracked_used[k], 1);
            return;
        }
    }
}

static void untrack(const sc_afile *f)
{
    for (int k = 0; k < SC_AFILE_TRACKED; ++k)
        if (atomic_load(&g_tracked_used[k]) == 1 && strcmp(g_tracked_path[k], f->tmp_path) == 0)
            atomic_store(&g_tracked_used[k], 0); /* the path is unique: only its owner gets here */
}

static void on_fatal_signal(int sig)
{
    if (atomic_load(&g_in_commit) > 0) {
        g_pending_sig = sig;
        return;
    }
    for (int k = 0; k < SC_AFILE_TRACKED; ++k)
        if (atomic_load(&g_tracked_used[k]) == 1)
            unlink(g_tracked_path[k]); /* async-signal-safe */
    signal(sig, SIG_DFL);
    raise(sig);
}

/* Another thread may take the signal while this one creates or commits: it is then acted on
 * here, once the temporary is tracked or the group is in place. */
static void defer_signals_begin(void)
{
    atomic_fetch_add(&g_in_commit, 1);
}

static void defer_signals_end(void)
{
    if (atomic_fetch_sub(&g_in_commit, 1) == 1 && g_pending_sig) { /* the last group in place */
        int sig = g_pending_sig;
        g_pending_sig = 0;
        on_fatal_signal(sig);
    }
}

void sc_afile_cleanup_on_signals(void)
{
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_fatal_signal;
    sigemptyset(&sa.sa_mask);
    for (size_t k = 0; k < sizeof sigs / sizeof sigs[0]; ++k)
        sigaddset(&sa.sa_mask, sigs[k]);
    g_tracking = 1;
    /* a file beyond the size limit (ulimit -f): the write fails with EFBIG and is reported like
     * a full disk, its temporary file removed, instead of SIGXFSZ killing the program with it */
    signal(SIGXFSZ, SIG_IGN);
    for (size_t k = 0; k < sizeof sigs / sizeof sigs[0]; ++k) {
        struct sigaction old;
        /* leave a signal the caller's parent ignores ignored (nohup) */
        if (sigaction(sigs[k], NULL, &old) == 0 && old.sa_handler == SIG_IGN)
            continue;
        sigaction(sigs[k], &sa, NULL);
    }
}

/* A new file "PATH.tmpXXXXXX" (six random letters and digits) opened for writing, created with
 * mode (less the umask, as any new file; mkstemp's would be 0600); tmp: its name. The fd, or -1
 * with errno. */
static int create_tmp(char *tmp, size_t cap, const char *path, mode_t mode)
{
    static const char abc[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    sc_rng rng; /* the project's generator, seeded by the moment, the process and the caller */
    sc_rng_seed(&rng, (uint64_t)ts.tv_nsec ^ ((uint64_t)ts.tv_sec << 30) ^
                          ((uint64_t)getpid() << 16) ^ (uint64_t)(uintptr_t)tmp);
    for (int attempt = 0; attempt < 100; ++attempt) {
        char s[7];
        for (int k = 0; k < 6; ++k)
            s[k] = abc[sc_rng_u64(&rng) % (sizeof abc - 1)];
        s[6] = '\0';
        snprintf(tmp, cap, "%s.tmp%s", path, s);
        int fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, mode);
        if (fd >= 0 || errno != EEXIST)
            return fd;
    }
    errno = EEXIST;
    return -1;
}

/* A new anonymous file (O_TMPFILE) in the folder of path, with mode; -1 (errno) where the file
 * system or the kernel has none, or /proc (for linkat) is not there. */
static int create_anon(const char *path, mode_t mode)
{
#ifdef O_TMPFILE
    char dir[4096];
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        snprintf(dir, sizeof dir, "%.*s", slash == path ? 1 : (int)(slash - path), path);
    if (access("/proc/self/fd", X_OK) != 0)
        return -1;
    return open(dir, O_TMPFILE | O_WRONLY | O_CLOEXEC, mode);
#else
    (void)path;
    (void)mode;
    errno = EOPNOTSUPP;
    return -1;
#endif
}

/* Give the anonymous temporary file of f the name "PATH.tmpXXXXXX" (kept in f->tmp_path and
 * tracked for signals). 0, or -1 with errno. */
static int link_anon(sc_afile *f)
{
    static const char abc[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
    char proc[64];
    snprintf(proc, sizeof proc, "/proc/self/fd/%d", fileno(f->fp));
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    sc_rng rng;
    sc_rng_seed(&rng, (uint64_t)ts.tv_nsec ^ ((uint64_t)ts.tv_sec << 30) ^
                          ((uint64_t)getpid() << 16) ^ (uint64_t)(uintptr_t)f);
    for (int attempt = 0; attempt < 100; ++attempt) {
        char name[sizeof f->tmp_path + 16], sfx[7];
        for (int k = 0; k < 6; ++k)
            sfx[k] = abc[sc_rng_u64(&rng) % (sizeof abc - 1)];
        sfx[6] = '\0';
        if (snprintf(name, sizeof name, "%s.tmp%s", f->path, sfx) >= (int)sizeof f->tmp_path) {
            errno = ENAMETOOLONG;
            return -1;
        }
        sigset_t old;
        block_signals(&old); /* linked and tracked as one step */
        defer_signals_begin();
        int rc = linkat(AT_FDCWD, proc, AT_FDCWD, name, AT_SYMLINK_FOLLOW);
        int e = errno;
        if (rc == 0) {
            memcpy(f->tmp_path, name, strlen(name) + 1);
            track(f);
        }
        restore_signals(&old);
        defer_signals_end();
        if (rc == 0)
            return 0;
        if (e != EEXIST) {
            errno = e;
            return -1;
        }
    }
    errno = EEXIST;
    return -1;
}

/* Is name "BASE.tmpXXXXXX" (six letters or digits), our temporary files' naming for base? */
static int is_our_tmp_name(const char *name, const char *base)
{
    size_t bl = strlen(base);
    if (strncmp(name, base, bl) != 0 || strncmp(name + bl, ".tmp", 4) != 0)
        return 0;
    const char *sfx = name + bl + 4;
    for (int k = 0; k < 6; ++k) {
        char c = sfx[k];
        if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9')))
            return 0;
    }
    return sfx[6] == '\0';
}

/* After path was committed: remove the stale temporary files of path nobody holds (their writer
 * died: its flock went with it). A live writer's temporary file is flocked and stays. */
static void remove_stale_tmps(const char *path)
{
    char dir[4096];
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        snprintf(dir, sizeof dir, "%.*s", slash == path ? 1 : (int)(slash - path), path);
    DIR *d = opendir(dir);
    if (!d)
        return;
    int dfd = dirfd(d);
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        if (!is_our_tmp_name(de->d_name, base))
            continue;
        int fd = openat(dfd, de->d_name, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
        if (fd < 0)
            continue;
        struct stat sb;
        if (fstat(fd, &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_uid == geteuid() &&
            flock(fd, LOCK_EX | LOCK_NB) == 0)
            unlinkat(dfd, de->d_name, 0);
        close(fd);
    }
    closedir(d);
}

/* Whether the kernel would follow the symbolic link path (lstat'ed as *lsb) when opening it:
 * its protected_symlinks rule — a link in a sticky world-writable folder (/tmp) is followed only
 * by its owner or when the folder's owner owns it too. */
static int may_follow(const char *path, const struct stat *lsb)
{
    if (lsb->st_uid == geteuid())
        return 1;
    char dir[PATH_MAX];
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        snprintf(dir, sizeof dir, "%.*s", slash == path ? 1 : (int)(slash - path), path);
    struct stat ds;
    if (stat(dir, &ds) != 0)
        return 0;
    if (!((ds.st_mode & S_ISVTX) && (ds.st_mode & S_IWOTH)))
        return 1;
    return ds.st_uid == lsb->st_uid;
}

/* may_follow for every link of the chain from path (at most 40 hops, as the kernel's limit). */
static int may_follow_chain(const char *path)
{
    char cur[PATH_MAX], next[PATH_MAX], link[PATH_MAX];
    snprintf(cur, sizeof cur, "%s", path);
    for (int hop = 0; hop < 40; ++hop) {
        struct stat lsb;
        if (lstat(cur, &lsb) != 0 || !S_ISLNK(lsb.st_mode))
            return 1;
        if (!may_follow(cur, &lsb))
            return 0;
        ssize_t n = readlink(cur, link, sizeof link - 1);
        if (n < 0)
            return 1;
        link[n] = '\0';
        const char *slash = strrchr(cur, '/');
        size_t dir = link[0] == '/' || !slash ? 0 : (size_t)(slash - cur) + 1, len = strlen(link);
        if (dir + len >= sizeof next)
            return 0; /* longer than a path can be */
        memcpy(next, cur, dir);
        memcpy(next + dir, link, len + 1);
        memcpy(cur, next, sizeof cur);
    }
    return 0;
}

/* The reason a temporary file's stream has its error flag set though its last flush went
 * through (the failed write's errno is gone by now): a one-byte write at its end, which the
 * same condition (full disk, size limit, I/O error) fails again; EIO if it passes. Only for
 * temporaries, which are discarded. */
static int probe_write_errno(int fd)
{
    off_t end = lseek(fd, 0, SEEK_END);
    char c = 0;
    if (end < 0 || pwrite(fd, &c, 1, end) == 1)
        return EIO;
    return errno ? errno : EIO;
}

/* unlink the temporary file and forget it */
static void remove_tmp(sc_afile *f)
{
    sigset_t old;
    block_signals(&old);
    unlink(f->tmp_path);
    untrack(f);
    restore_signals(&old);
}

/* err (already set to code) keeps errno e, the system's reason (sc_error.sys_errno); code. */
static sc_status keep_errno(sc_error *err, int e, sc_status code)
{
    if (err)
        err->sys_errno = e;
    return code;
}

/* The system refused path: "WHAT: strerror(e)" with errno e kept. */
static sc_status refused(sc_error *err, const char *path, const char *what, int e)
{
    return keep_errno(err, e, sc_error_set(err, SC_E_IO, path, 0, "%s: %s", what, strerror(e)));
}

sc_status sc_afile_open(sc_afile *f, const char *path, sc_error *err)
{
    memset(f, 0, sizeof *f);
    if (strcmp(path, "-") == 0) {
        f->fp = stdout;
        f->direct = 1;
        snprintf(f->path, sizeof f->path, "-");
        return SC_OK;
    }
    struct stat sb;
    if (stat(path, &sb) == 0 && !S_ISREG(sb.st_mode)) {
        if (!S_ISCHR(sb.st_mode) && !S_ISFIFO(sb.st_mode))
            return keep_errno(err, S_ISDIR(sb.st_mode) ? EISDIR : 0,
                              sc_error_set(err, SC_E_INPUT, path, 0, "not a regular file (%s)",
                                           S_ISDIR(sb.st_mode) ? "a directory" : "a special file"));
        /* a device or FIFO (/dev/null, /dev/stdout): a temporary file renamed over it would
         * replace the device (as root, even /dev/null), so it is written straight */
        if (strlen(path) >= sizeof f->path)
            return sc_error_set(err, SC_E_INPUT, path, 0, "path too long");
        f->fp = fopen(path, "wb");
        if (!f->fp)
            return refused(err, path, "cannot open", errno);
        f->direct = 1;
        snprintf(f->path, sizeof f->path, "%s", path);
        return SC_OK;
    }
    /* a symbolic link to a file: the file it points to is replaced (the temporary beside it),
     * the link kept, as `cp` writes through it (a link to nothing is replaced itself) */
    char target[PATH_MAX];
    struct stat lsb;
    if (lstat(path, &lsb) == 0 && S_ISLNK(lsb.st_mode) && realpath(path, target)) {
        if (!may_follow_chain(path))
            return sc_error_set(err, SC_E_IO, path, 0,
                                "a symbolic link another user owns in a sticky world-writable "
                                "folder: not followed (as the kernel's protected_symlinks)");
        path = target;
    }
    if (strlen(path) + 16 >= sizeof f->tmp_path)
        return sc_error_set(err, SC_E_INPUT, path, 0, "path too long");
    snprintf(f->path, sizeof f->path, "%s", path);
    int replacing = stat(path, &sb) == 0;
    sigset_t old;
    block_signals(&old); /* created and tracked as one step, in this thread and the others */
    defer_signals_begin();
    /* created with the final permissions at once: a replaced 0600 file's new content is never
     * readable by others, not even for a moment */
    mode_t mode = replacing ? (sb.st_mode & 0777) : 0666;
    int fd = create_anon(path, mode);
    if (fd >= 0) {
        f->direct = 2; /* anonymous until commit: nothing to track */
        f->tmp_path[0] = '\0';
    } else {
        fd = create_tmp(f->tmp_path, sizeof f->tmp_path, path, mode);
    }
    int e = errno;
    if (fd >= 0 && f->direct == 0)
        track(f);
    if (fd >= 0)
        flock(fd, LOCK_EX | LOCK_NB); /* held until the rename: a live writer's file is no
                                         one's stale file */
    restore_signals(&old);
    defer_signals_end();
    if (fd < 0)
        return refused(err, path, "cannot create", e);
    if (replacing) /* the file it replaces keeps its permissions (not its set-id bits): the
                      bits the umask took at creation given back (only ever widening) */
        fchmod(fd, sb.st_mode & 0777);
    f->fp = fdopen(fd, "wb");
    if (!f->fp) {
        e = errno;
        close(fd);
        if (f->tmp_path[0])
            remove_tmp(f);
        return refused(err, path, "cannot open", e);
    }
    return SC_OK;
}

static void fsync_parent_dir(const char *path)
{
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash == dir)
        dir[1] = '\0';
    else if (slash)
        *slash = '\0';
    else
        snprintf(dir, sizeof dir, ".");
    int dfd = open(dir, O_RDONLY | O_DIRECTORY);
    if (dfd >= 0) {
        fsync(dfd);
        close(dfd);
    }
}

/* Flush and fsync the temporary file and give it its temporary name if it is anonymous; it stays
 * open (and flocked) until afile_rename. On failure it is closed and removed (fp NULL). */
static sc_status afile_sync(sc_afile *f, sc_error *err)
{
    errno = 0;
    int flush_failed = fflush(f->fp) != 0, e = errno;
    int bad = flush_failed || ferror(f->fp);
    if (bad && !flush_failed) /* an earlier write failed: its errno is gone */
        e = probe_write_errno(fileno(f->fp));
    if (!bad && fsync(fileno(f->fp)) != 0)
        bad = 1, e = errno;
    if (!bad && f->direct == 2 && link_anon(f) != 0)
        bad = 1, e = errno;
    if (bad) {
        fclose(f->fp);
        f->fp = NULL;
        if (f->tmp_path[0])
            remove_tmp(f);
        return sc_error_set(err, SC_E_IO, f->path, 0, "write error: %s", strerror(e ? e : EIO));
    }
    return SC_OK;
}

/* Rename a synced (or parked) temporary file over its final name, close it, and remove the
 * stale temporary files of that name. */
static sc_status afile_rename(sc_afile *f, sc_error *err)
{
    if (rename(f->tmp_path, f->path) != 0) {
        int e = errno;
        remove_tmp(f);
        if (f->fp)
            fclose(f->fp);
        f->fp = NULL;
        f->tmp_path[0] = '\0';
        return sc_error_set(err, SC_E_IO, f->path, 0, "cannot rename into place: %s",
                            strerror(e));
    }
    untrack(f);
    if (f->fp)
        fclose(f->fp); /* its data are on disk (fsync): a late error would change nothing */
    f->fp = NULL;
    if (f->direct == 3) /* parked: its temporary name is gone, nothing left to abort */
        f->tmp_path[0] = '\0';
    fsync_parent_dir(f->path);
    remove_stale_tmps(f->path);
    return SC_OK;
}

static int is_stdout(const sc_afile *f) { return strcmp(f->path, "-") == 0; }

/* Commit of a file written straight (stdout, a device, a FIFO): flush (and close). */
static sc_status direct_commit(sc_afile *f, sc_error *err)
{
    errno = 0;
    int flush_failed = fflush(f->fp) != 0, e = flush_failed ? errno : EIO;
    int bad = flush_failed || ferror(f->fp);
    if (!is_stdout(f) && fclose(f->fp) != 0 && !bad)
        bad = 1, e = errno;
    f->fp = NULL;
    return bad ? sc_error_set(err, SC_E_IO, is_stdout(f) ? "stdout" : f->path, 0,
                              "write error: %s", strerror(e))
               : SC_OK;
}

static int is_parked(const sc_afile *f) { return !f->fp && f->direct == 3 && f->tmp_path[0]; }

sc_status sc_afile_park(sc_afile *f, sc_error *err)
{
    if (!f->fp)
        return sc_error_set(err, SC_E_INTERNAL, f->path, 0, "file not open");
    if (f->direct == 1)
        return direct_commit(f, err);
    sc_status st = afile_sync(f, err); /* an anonymous file gets its temporary name here */
    if (st != SC_OK)
        return st;
    fclose(f->fp); /* flushed and fsynced: nothing left to fail */
    f->fp = NULL;
    f->direct = 3;
    return SC_OK;
}

sc_status sc_afile_commit(sc_afile *f, sc_error *err)
{
    if (is_parked(f))
        return afile_rename(f, err);
    if (!f->fp)
        return sc_error_set(err, SC_E_INTERNAL, f->path, 0, "file not open");
    if (f->direct == 1)
        return direct_commit(f, err);
    sc_status st = afile_sync(f, err);
    return st == SC_OK ? afile_rename(f, err) : st;
}

static sc_status commit_group(sc_afile *f, int n, int *synced, sc_error *err);

sc_status sc_afile_commit_all(sc_afile *f, int n, sc_error *err)
{
    sc_status st = SC_OK;
    int small[64] = {0}; /* a group of any size (one file per view of a large plan) */
    int *synced = n <= 64 ? small : calloc((size_t)n, sizeof *synced);
    if (!synced) {
        sc_afile_abort_all(f, n);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (a group of %d files)", n);
    }
    defer_signals_begin();
    st = commit_group(f, n, synced, err);
    defer_signals_end(); /* a signal that came meanwhile: die of it now, the group whole */
    if (synced != small)
        free(synced);
    return st;
}

static sc_status commit_group(sc_afile *f, int n, int *synced, sc_error *err)
{
    sc_status st = SC_OK;
    for (int k = 0; k < n && st == SC_OK; ++k) {
        if (!f[k].fp) {
            synced[k] = is_parked(&f[k]);
            continue;
        }
        st = f[k].direct == 1 ? direct_commit(&f[k], err) : afile_sync(&f[k], err);
        synced[k] = st == SC_OK && f[k].tmp_path[0];
    }
    if (st != SC_OK) {
        sc_afile_abort_all(f, n); /* the synced ones are still open: closed and removed */
        return st;
    }
    /* The renames as one step for signals: a SIGINT/SIGTERM arriving now is handled after the
     * whole set is in place, never between two files of it. */
    sigset_t old;
    block_signals(&old);
    for (int k = 0; k < n; ++k) {
        if (!synced[k])
            continue;
        if (st == SC_OK)
            st = afile_rename(&f[k], err);
        else
            sc_afile_abort(&f[k]);
    }
    restore_signals(&old);
    return st;
}

void sc_afile_abort_all(sc_afile *f, int n)
{
    for (int k = 0; k < n; ++k)
        sc_afile_abort(&f[k]);
}

sc_status sc_afile_finish(sc_afile *f, sc_status st, sc_error *err)
{
    if (st == SC_OK)
        return sc_afile_commit(f, err);
    sc_afile_abort(f);
    return st;
}

sc_status sc_afile_finish_all(sc_afile *f, int n, sc_status st, sc_error *err)
{
    if (st == SC_OK)
        return sc_afile_commit_all(f, n, err);
    sc_afile_abort_all(f, n);
    return st;
}

void sc_afile_abort(sc_afile *f)
{
    if (is_parked(f)) {
        remove_tmp(f);
        f->tmp_path[0] = '\0';
        return;
    }
    if (!f->fp)
        return;
    if (f->direct == 1) {
        if (is_stdout(f))
            fflush(f->fp);
        else
            fclose(f->fp);
        f->fp = NULL;
        return;
    }
    fclose(f->fp); /* an anonymous temporary file not yet linked goes with it */
    f->fp = NULL;
    if (f->tmp_path[0])
        remove_tmp(f);
}

sc_status sc_write_file_atomic(const char *path, const void *data, size_t len, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    errno = 0;
    if (len && fwrite(data, 1, len, f.fp) != len) {
        int e = errno ? errno : EIO;
        sc_afile_abort(&f);
        return sc_error_set(err, SC_E_IO, path, 0, "write error: %s", strerror(e));
    }
    return sc_afile_commit(&f, err);
}
