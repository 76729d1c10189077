#include "selfcal/atomic_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

sc_status sc_afile_open(sc_afile *f, const char *path, sc_error *err)
{
    memset(f, 0, sizeof *f);
    if (strcmp(path, "-") == 0) {
        f->fp = stdout;
        snprintf(f->path, sizeof f->path, "-");
        return SC_OK;
    }
    if (strlen(path) + 16 >= sizeof f->tmp_path)
        return sc_error_set(err, SC_E_INPUT, path, 0, "path too long");
    snprintf(f->path, sizeof f->path, "%s", path);
    snprintf(f->tmp_path, sizeof f->tmp_path, "%s.tmpXXXXXX", path);
    int fd = mkstemp(f->tmp_path);
    if (fd < 0)
        return sc_error_set(err, SC_E_IO, path, 0, "cannot create: %s", strerror(errno));
    fchmod(fd, 0644);
    f->fp = fdopen(fd, "wb");
    if (!f->fp) {
        int e = errno;
        close(fd);
        unlink(f->tmp_path);
        return sc_error_set(err, SC_E_IO, path, 0, "cannot open: %s", strerror(e));
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

/* Flush, fsync and close the temporary file (fp becomes NULL); on failure it is removed. */
static sc_status afile_sync(sc_afile *f, sc_error *err)
{
    int bad = fflush(f->fp) != 0 || ferror(f->fp) || fsync(fileno(f->fp)) != 0;
    int e = errno;
    if (fclose(f->fp) != 0 && !bad) {
        bad = 1;
        e = errno;
    }
    f->fp = NULL;
    if (bad) {
        unlink(f->tmp_path);
        return sc_error_set(err, SC_E_IO, f->path, 0, "write error: %s", strerror(e));
    }
    return SC_OK;
}

/* Rename a synced temporary file over its final name. */
static sc_status afile_rename(sc_afile *f, sc_error *err)
{
    if (rename(f->tmp_path, f->path) != 0) {
        int e = errno;
        unlink(f->tmp_path);
        return sc_error_set(err, SC_E_IO, f->path, 0, "cannot rename into place: %s",
                            strerror(e));
    }
    fsync_parent_dir(f->path);
    return SC_OK;
}

static int is_stdout(const sc_afile *f) { return strcmp(f->path, "-") == 0; }

static sc_status stdout_commit(sc_afile *f, sc_error *err)
{
    int bad = fflush(f->fp) != 0 || ferror(f->fp);
    f->fp = NULL;
    return bad ? sc_error_set(err, SC_E_IO, "stdout", 0, "write error") : SC_OK;
}

sc_status sc_afile_commit(sc_afile *f, sc_error *err)
{
    if (!f->fp)
        return sc_error_set(err, SC_E_INTERNAL, f->path, 0, "file not open");
    if (is_stdout(f))
        return stdout_commit(f, err);
    sc_status st = afile_sync(f, err);
    return st == SC_OK ? afile_rename(f, err) : st;
}

sc_status sc_afile_commit_all(sc_afile *f, int n, sc_error *err)
{
    sc_status st = SC_OK;
    int synced[64] = {0};
    if (n > 64)
        return sc_error_set(err, SC_E_INTERNAL, NULL, 0, "too many files in one group");
    for (int k = 0; k < n && st == SC_OK; ++k) {
        if (!f[k].fp)
            continue;
        st = is_stdout(&f[k]) ? stdout_commit(&f[k], err) : afile_sync(&f[k], err);
        synced[k] = st == SC_OK && f[k].tmp_path[0];
    }
    if (st != SC_OK) {
        for (int k = 0; k < n; ++k)
            if (synced[k])
                unlink(f[k].tmp_path);
        sc_afile_abort_all(f, n);
        return st;
    }
    for (int k = 0; k < n; ++k) {
        if (!synced[k])
            continue;
        if (st == SC_OK)
            st = afile_rename(&f[k], err);
        else
            unlink(f[k].tmp_path);
    }
    return st;
}

void sc_afile_abort_all(sc_afile *f, int n)
{
    for (int k = 0; k < n; ++k)
        sc_afile_abort(&f[k]);
}

void sc_afile_abort(sc_afile *f)
{
    if (!f->fp)
        return;
    if (strcmp(f->path, "-") == 0) {
        fflush(f->fp);
        f->fp = NULL;
        return;
    }
    fclose(f->fp);
    f->fp = NULL;
    unlink(f->tmp_path);
}

sc_status sc_write_file_atomic(const char *path, const void *data, size_t len, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    if (len && fwrite(data, 1, len, f.fp) != len) {
        sc_afile_abort(&f);
        return sc_error_set(err, SC_E_IO, path, 0, "write error");
    }
    return sc_afile_commit(&f, err);
}
