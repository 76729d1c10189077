/* input_once.c — inputs whose bytes a command both reads and records (the SHA-256 of report,
 * verify and lut build): a regular file is read where it is and hashed from it; a pipe, a FIFO
 * or a terminal can be read only once, so it is first copied into memory (a memfd) while being
 * hashed, and the readers read that copy through /proc/self/fd. Their messages, which name
 * the copy, are given the name the user typed back (cli_report). Hand-written: a few lines of
 * POSIX over the library's own SHA-256. */
#define _GNU_SOURCE
#include "input_once.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "selfcal/csv.h"
#include "selfcal/error.h"

/* The snapshots alive, for cli_report's renaming (a program's table, not the library's). */
static const cli_input *g_live[CLI_INPUT_MAX_LIVE];

static void live_add(const cli_input *in)
{
    for (int k = 0; k < CLI_INPUT_MAX_LIVE; ++k)
        if (!g_live[k]) {
            g_live[k] = in;
            return;
        }
}

static void live_remove(const cli_input *in)
{
    for (int k = 0; k < CLI_INPUT_MAX_LIVE; ++k)
        if (g_live[k] == in)
            g_live[k] = NULL;
}

/* A text input's lines as they come: what the CSV reader refuses (a NUL byte, a line longer than
 * SC_CSV_MAX_LINE, more than SC_CSV_MAX_SKIP_RUN comment or blank lines in a row) is refused
 * while copying, at its line, not after 2 GiB of an endless pipe. */
typedef struct text_check {
    long line, len, run; /* lines ended, the current one's length, comment/blank run */
    int seen, hash;      /* the current line has a non-space byte; it is '#' */
} text_check;

static sc_status check_text(text_check *c, const char *buf, size_t n, const char *path,
                            sc_error *err)
{
    if (memchr(buf, '\0', n))
        return sc_error_set(err, SC_E_INPUT, path, c->line + 1, SC_CSV_NUL_MSG);
    for (size_t k = 0; k < n; ++k) {
        unsigned char ch = (unsigned char)buf[k];
        if (ch == '\n') {
            ++c->line;
            c->run = !c->seen || c->hash ? c->run + 1 : 0;
            if (c->run > SC_CSV_MAX_SKIP_RUN)
                return sc_error_set(err, SC_E_INPUT, path, c->line, SC_CSV_SKIP_RUN_MSG,
                                    SC_CSV_MAX_SKIP_RUN);
            c->len = 0, c->seen = 0, c->hash = 0;
            continue;
        }
        if (++c->len >= SC_CSV_MAX_LINE)
            return sc_error_set(err, SC_E_INPUT, path, c->line + 1, "line longer than %d bytes",
                                SC_CSV_MAX_LINE);
        if (!c->seen && !isspace(ch))
            c->seen = 1, c->hash = ch == '#';
    }
    return SC_OK;
}

/* Copy fd's bytes into a memfd, hashing them; the memfd or -1 (err set). A text input is
 * checked as it comes (check_text). */
static int spool(int fd, const char *path, int text, cli_input *in, sc_error *err)
{
    text_check tc = {0, 0, 0, 0, 0};
    int mfd = memfd_create("selfcal-input", MFD_CLOEXEC);
    if (mfd < 0) {
        sc_error_set(err, SC_E_IO, path, 0, "cannot keep a copy of the input: %s",
                     strerror(errno));
        return -1;
    }
    sc_sha256 h;
    sc_sha256_init(&h);
    static char buf[1 << 16];
    long long total = 0;
    for (;;) {
        ssize_t r = read(fd, buf, sizeof buf);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0) {
            sc_error_set(err, SC_E_IO, path, 0, "read error: %s", strerror(errno));
            break;
        }
        if (r == 0) {
            sc_sha256_final(&h, in->sha256);
            in->size = total;
            return mfd;
        }
        if (total + r > CLI_INPUT_MAX_SPOOL) {
            sc_error_set(err, SC_E_INPUT, path, 0,
                         "more than %lld MiB through a pipe: this command keeps a copy of a "
                         "pipe's bytes to record their SHA-256; give a regular file",
                         (long long)CLI_INPUT_MAX_SPOOL >> 20);
            break;
        }
        if (text && check_text(&tc, buf, (size_t)r, path, err) != SC_OK)
            break;
        sc_sha256_update(&h, buf, (size_t)r);
        for (ssize_t off = 0; off < r;) {
            ssize_t w = write(mfd, buf + off, (size_t)(r - off));
            if (w < 0 && errno == EINTR)
                continue;
            if (w <= 0) {
                sc_error_set(err, SC_E_NOMEM, path, 0, "cannot keep a copy of the input: %s",
                             w < 0 ? strerror(errno) : "no room");
                close(mfd);
                return -1;
            }
            off += w;
        }
        total += r;
    }
    close(mfd);
    return -1;
}

sc_status cli_input_open(cli_input *in, const char *path, int text, sc_error *err)
{
    memset(in, 0, sizeof *in);
    in->orig = path;
    in->path = path;
    in->fd = -1;
    int stdin_dash = path && !strcmp(path, "-"); /* the readers' name for standard input */
    struct stat sb;
    if (!path || (!stdin_dash && (stat(path, &sb) != 0 || S_ISREG(sb.st_mode) ||
                                  S_ISDIR(sb.st_mode))))
        return SC_OK; /* a file (hashed where it is), or what the reader will say is wrong */
    if (stdin_dash && fstat(STDIN_FILENO, &sb) == 0 && S_ISREG(sb.st_mode) &&
        lseek(STDIN_FILENO, 0, SEEK_CUR) == 0)
        return SC_OK; /* stdin a file from its start (< f): read and hashed as it is */
    int fd = stdin_dash ? STDIN_FILENO : open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return SC_OK; /* the reader names the problem */
    in->fd = spool(fd, path, text, in, err);
    if (!stdin_dash)
        close(fd);
    if (in->fd < 0)
        return err ? err->code : SC_E_IO;
    snprintf(in->proc_path, sizeof in->proc_path, "/proc/self/fd/%d", in->fd);
    in->path = in->proc_path;
    in->hashed = 1;
    live_add(in);
    return SC_OK;
}

sc_status cli_input_sha256(const cli_input *in, uint8_t digest[SC_SHA256_BYTES], long long *size,
                           sc_error *err)
{
    if (in->hashed) {
        memcpy(digest, in->sha256, SC_SHA256_BYTES);
        *size = in->size;
        return SC_OK;
    }
    if (!strcmp(in->path, "-")) { /* stdin a regular file (above): hashed by its descriptor */
        char fdpath[32];
        snprintf(fdpath, sizeof fdpath, "/proc/self/fd/%d", STDIN_FILENO);
        sc_status st = sc_sha256_file(fdpath, digest, err);
        struct stat sb;
        *size = st == SC_OK && fstat(STDIN_FILENO, &sb) == 0 ? (long long)sb.st_size : -1;
        return st;
    }
    sc_status st = sc_sha256_file(in->path, digest, err);
    if (st != SC_OK)
        return st;
    struct stat sb;
    *size = stat(in->path, &sb) == 0 ? (long long)sb.st_size : -1;
    return SC_OK;
}

void cli_input_close(cli_input *in)
{
    if (in->fd >= 0) {
        live_remove(in);
        close(in->fd);
    }
    in->fd = -1;
    in->path = in->orig;
}

sc_status cli_input_open_all(cli_input *in, const char *const *paths, int n, unsigned binary,
                             int *opened, sc_error *err)
{
    sc_status st = SC_OK;
    for (*opened = 0; *opened < n && st == SC_OK; ++*opened)
        st = cli_input_open(&in[*opened], paths[*opened], !(binary >> *opened & 1u), err);
    return st;
}

void cli_input_close_all(cli_input *in, int n)
{
    for (int k = 0; k < n; ++k)
        cli_input_close(&in[k]);
}

/* Replace every occurrence of from by to in s (cap bytes); an occurrence followed by a digit is
 * another name (/proc/self/fd/3 is not /proc/self/fd/31). */
static void replace_all(char *s, size_t cap, const char *from, const char *to)
{
    size_t lf = strlen(from), lt = strlen(to);
    char out[1024];
    size_t o = 0;
    for (const char *p = s; *p && o + 1 < sizeof out;) {
        if (!strncmp(p, from, lf) && !isdigit((unsigned char)p[lf])) {
            size_t n = lt < sizeof out - 1 - o ? lt : sizeof out - 1 - o;
            memcpy(out + o, to, n);
            o += n;
            p += lf;
        } else {
            out[o++] = *p++;
        }
    }
    out[o] = '\0';
    size_t n = o < cap - 1 ? o : cap - 1; /* cut as the message would be */
    memcpy(s, out, n);
    s[n] = '\0';
}

void cli_input_rename_in_error(sc_error *err)
{
    for (int k = 0; k < CLI_INPUT_MAX_LIVE; ++k) {
        const cli_input *in = g_live[k];
        if (!in)
            continue;
        replace_all(err->file, sizeof err->file, in->proc_path, in->orig);
        replace_all(err->msg, sizeof err->msg, in->proc_path, in->orig);
    }
}
