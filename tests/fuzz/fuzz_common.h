/* tests/fuzz/fuzz_common.h — helpers shared by the libFuzzer targets: the readers take a path,
 * so each input is written to an in-memory file (memfd) and read back through /proc/self/fd. */
#ifndef SELFCAL_FUZZ_COMMON_H
#define SELFCAL_FUZZ_COMMON_H

#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <unistd.h>

/* The path of an in-memory file holding exactly data[0..size). */
static inline const char *fuzz_path(const uint8_t *data, size_t size)
{
    static int fd = -1;
    static char path[64];
    if (fd < 0) {
        fd = memfd_create("fuzz-input", MFD_CLOEXEC);
        if (fd < 0)
            abort();
        snprintf(path, sizeof path, "/proc/self/fd/%d", fd);
    }
    if (ftruncate(fd, 0) != 0)
        abort();
    size_t off = 0;
    while (off < size) {
        ssize_t w = pwrite(fd, data + off, size - off, (off_t)off);
        if (w <= 0)
            abort();
        off += (size_t)w;
    }
    return path;
}

/* A private directory for targets whose readers need real file names (a .dat beside its .txt) or
 * whose writers rename into place: under /dev/shm (memory, fsync is free) if it exists, else
 * TMPDIR or /tmp; made once per process, its files are the target's to overwrite. */
static inline char *fuzz_dir_buf(void)
{
    static char dir[256];
    return dir;
}

static inline void fuzz_dir_remove(void)
{
    const char *fuzz_dir_path = fuzz_dir_buf();
    DIR *d = opendir(fuzz_dir_path);
    struct dirent *e;
    char p[600];
    while (d && (e = readdir(d)) != NULL)
        if (e->d_name[0] != '.') {
            snprintf(p, sizeof p, "%s/%s", fuzz_dir_path, e->d_name);
            unlink(p);
        }
    if (d)
        closedir(d);
    rmdir(fuzz_dir_path);
}

static inline const char *fuzz_dir(void)
{
    char *dir = fuzz_dir_buf();
    if (!dir[0]) {
        const char *base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : getenv("TMPDIR");
        snprintf(dir, 256, "%s/selfcal-fuzz-XXXXXX", base && base[0] ? base : "/tmp");
        if (!mkdtemp(dir))
            abort();
        atexit(fuzz_dir_remove);
    }
    return dir;
}

/* Write data[0..size) to the file fuzz_dir()/name (replacing it); returns its path (static per
 * name slot: slot 0..3). */
static inline const char *fuzz_file(int slot, const char *name, const uint8_t *data, size_t size)
{
    static char path[4][320];
    snprintf(path[slot], sizeof path[slot], "%s/%s", fuzz_dir(), name);
    FILE *f = fopen(path[slot], "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f) != 0)
        abort();
    return path[slot];
}

/* The contract of every reader: on failure an error message, one line, that names the file. */
#define FUZZ_CHECK(cond)                                                                      \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz check failed: %s (%s:%d)\n", #cond, __FILE__, __LINE__);     \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

#endif
