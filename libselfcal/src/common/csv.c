/* csv.c — owns the strict line reader every text format is read with (line counting, NUL and
 * over-long lines refused, comma splitting, strict finite numbers) and the `# key = value` split. */
#include "selfcal/csv.h"

#include "selfcal/number.h"
#include "csv_internal.h"
#include "number_internal.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

sc_status sc_open_failure_status(int errnum)
{
    switch (errnum) {
    case ENOENT: case ENOTDIR: case EISDIR: case ELOOP: case ENAMETOOLONG:
        return SC_E_INPUT; /* the path named is wrong: bad input (exit 2) */
    case ENOMEM:
        return SC_E_NOMEM;
    default:
        return SC_E_IO; /* permission, I/O, too many files: the system refused (exit 1) */
    }
}

FILE *sc_open_input(const char *path, sc_error *err)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        int e = errno;
        sc_error_set(err, sc_open_failure_status(e), path, 0, "cannot open: %s", strerror(e));
        if (err)
            err->sys_errno = e;
        return NULL;
    }
    struct stat st;
    if (fstat(fileno(fp), &st) == 0 && S_ISDIR(st.st_mode)) {
        fclose(fp);
        sc_error_set(err, SC_E_INPUT, path, 0, "is a directory, not a file");
        if (err)
            err->sys_errno = EISDIR;
        return NULL;
    }
    return fp;
}

sc_status sc_csv_open(sc_csv *r, const char *path, sc_error *err)
{
    memset(r, 0, sizeof *r);
    snprintf(r->path, sizeof r->path, "%s", path);
    if (strcmp(path, "-") == 0) {
        r->fp = stdin;
        r->owns_fp = 0;
        return SC_OK;
    }
    r->fp = sc_open_input(path, err);
    if (!r->fp)
        return err ? err->code : SC_E_INPUT;
    r->owns_fp = 1;
    return SC_OK;
}

void sc_csv_close(sc_csv *r)
{
    if (r->fp && r->owns_fp)
        fclose(r->fp);
    r->fp = NULL;
    free(r->buf);
    r->buf = NULL;
    r->text = NULL;
}

/* Bytes read at a time. Larger than a line may be, so that the unfinished line moved to the front
 * of the block always leaves room to read more. */
#define CSV_BLOCK (256 * 1024)
/* A line too long is reported as too long unless a NUL byte comes first in the part of it that
 * lies in the file's 64 KiB blocks reaching SC_CSV_MAX_LINE bytes into it (the rule of the
 * reader's 64 KiB blocks before, kept so that every message stays what it was). */
#define CSV_NUL_ALIGN 65536
_Static_assert(CSV_BLOCK > SC_CSV_MAX_LINE + 2 * CSV_NUL_ALIGN, "a block holds what is scanned");

/* Read more of the file behind the unfinished line at the block's end (moved to its front).
 * 1 = bytes read, 0 = end of file, -1 = read error. */
static int csv_refill(sc_csv *r, sc_error *err)
{
    size_t keep = r->buf_len - r->buf_pos;
    if (r->buf_pos > 0) {
        memmove(r->buf, r->buf + r->buf_pos, keep);
        r->buf_off += (long long)r->buf_pos;
        r->buf_pos = 0;
        r->buf_len = keep;
    }
    size_t nread = fread(r->buf + keep, 1, CSV_BLOCK - keep, r->fp);
    if (nread == 0) {
        if (ferror(r->fp)) {
            int e = errno;
            sc_error_set(err, SC_E_IO, r->path, r->line + 1, "read error: %s", strerror(e));
            if (err)
                err->sys_errno = e;
            return -1;
        }
        r->eof = 1;
        return 0;
    }
    r->buf_len += nread;
    return 1;
}

/* The line is found with memchr in a read-ahead block and handed out in place (its line end
 * replaced by a NUL): no byte is copied or looked at one by one (on a 10⁶-line file, per-byte
 * work cost more than the parsing of the numbers). */
int sc_csv_next_line(sc_csv *r, sc_error *err)
{
    if (!r->fp)
        return 0;
    if (!r->buf) {
        r->buf = malloc(CSV_BLOCK + 1); /* + 1: the NUL after a last line without line end */
        if (!r->buf) {
            sc_error_set(err, SC_E_NOMEM, r->path, r->line, "out of memory");
            return -1;
        }
    }
    const char *nl;
    size_t scan; /* the bytes of a long line searched for a NUL (see CSV_NUL_ALIGN) */
    for (;;) {
        size_t avail = r->buf_len - r->buf_pos;
        long long at = r->buf_off + (long long)r->buf_pos;
        scan = (size_t)((at + SC_CSV_MAX_LINE + CSV_NUL_ALIGN - 1) / CSV_NUL_ALIGN *
                            CSV_NUL_ALIGN - at);
        nl = memchr(r->buf + r->buf_pos, '\n', avail);
        if (nl || avail >= scan)
            break;
        if (r->eof) {
            if (avail == 0)
                return 0;
            break;
        }
        if (csv_refill(r, err) < 0)
            return -1;
    }
    char *s = r->buf + r->buf_pos;
    size_t len = nl ? (size_t)(nl - s) : r->buf_len - r->buf_pos;
    long long start = r->buf_off + (long long)r->buf_pos;
    if (memchr(s, '\0', len < scan ? len : scan)) {
        sc_error_set(err, SC_E_INPUT, r->path, r->line + 1, SC_CSV_NUL_MSG);
        return -1;
    }
    if (len >= SC_CSV_MAX_LINE) {
        sc_error_set(err, SC_E_INPUT, r->path, r->line + 1, "line longer than %d bytes",
                     SC_CSV_MAX_LINE);
        return -1;
    }
    r->buf_pos += len + (nl != NULL);
    if (start == 0 && len >= 3 && !memcmp(s, "\xEF\xBB\xBF", 3)) {
        /* a UTF-8 byte-order mark (spreadsheets' "CSV UTF-8" writes one): not part of the text */
        s += 3;
        len -= 3;
    }
    if (len > 0 && s[len - 1] == '\r')
        --len;
    s[len] = '\0';
    r->text = s;
    r->len = len;
    r->line++;
    r->nfields = 0;
    if (!sc_csv_text_skippable(s)) {
        r->skip_run = 0;
    } else if (++r->skip_run > SC_CSV_MAX_SKIP_RUN) {
        sc_error_set(err, SC_E_INPUT, r->path, r->line, SC_CSV_SKIP_RUN_MSG, SC_CSV_MAX_SKIP_RUN);
        return -1;
    }
    return 1;
}

int sc_csv_text_skippable(const char *s)
{
    while (isspace((unsigned char)*s)) /* as sc_csv_is_blank; data rows start with a digit */
        ++s;
    return *s == '#' || *s == '\0';
}

long long sc_csv_line_offset(const sc_csv *r)
{
    return r->buf_off + (long long)(r->text - r->buf);
}

/* The file through /proc/self/fd (a new file description of the very file r has open, whatever
 * its path has become since), checked to be that file. */
sc_status sc_csv_open_at(sc_csv *w, const sc_csv *r, long long at, sc_error *err)
{
    memset(w, 0, sizeof *w);
    snprintf(w->path, sizeof w->path, "%s", r->path);
    struct stat a, b;
    char self[64];
    if (!r->fp || fstat(fileno(r->fp), &a) != 0 || !S_ISREG(a.st_mode))
        return sc_error_set(err, SC_E_IO, r->path, 0, "not a regular file");
    snprintf(self, sizeof self, "/proc/self/fd/%d", fileno(r->fp));
    w->fp = fopen(self, "rb");
    if (!w->fp)
        return sc_error_set(err, SC_E_IO, r->path, 0, "cannot open again: %s", strerror(errno));
    w->owns_fp = 1;
    if (fstat(fileno(w->fp), &b) != 0 || a.st_dev != b.st_dev || a.st_ino != b.st_ino ||
        fseeko(w->fp, (off_t)at, SEEK_SET) != 0) {
        sc_csv_close(w);
        return sc_error_set(err, SC_E_IO, r->path, 0, "cannot open again at byte %lld", at);
    }
    w->buf_off = at;
    return SC_OK;
}

bool sc_csv_is_blank(const sc_csv *r)
{
    for (const char *p = r->text; p && *p; ++p)
        if (!isspace((unsigned char)*p))
            return false;
    return true;
}

char *sc_str_trim(char *s)
{
    while (*s && isspace((unsigned char)*s))
        ++s;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1]))
        *--e = '\0';
    return s;
}

int sc_csv_split(sc_csv *r, sc_error *err)
{
    int n = 0;
    char *p = r->text;
    for (;;) {
        if (n == SC_CSV_MAX_FIELDS) {
            sc_error_set(err, SC_E_INPUT, r->path, r->line, "more than %d fields",
                         SC_CSV_MAX_FIELDS);
            return -1;
        }
        char *comma = strchr(p, ',');
        if (comma)
            *comma = '\0';
        r->field[n++] = sc_str_trim(p);
        if (!comma)
            break;
        p = comma + 1;
    }
    r->nfields = n;
    return n;
}

sc_status sc_parse_double(const char *s, double *out)
{
    if (!s || !*s)
        return SC_E_INPUT;
    return sc_number_parse(s, strlen(s), out);
}

/* Decimal whole numbers as strtol(s, 10) takes them (optional blanks and sign first), without the
 * locale machinery: the readers parse two of them per line. */
sc_status sc_parse_long(const char *s, long *out)
{
    if (!s || !*s)
        return SC_E_INPUT;
    while (isspace((unsigned char)*s))
        ++s;
    int neg = *s == '-';
    if (*s == '-' || *s == '+')
        ++s;
    if (!(*s >= '0' && *s <= '9'))
        return SC_E_INPUT;
    unsigned long v = 0, lim = neg ? (unsigned long)LONG_MAX + 1 : (unsigned long)LONG_MAX;
    for (; *s >= '0' && *s <= '9'; ++s) {
        unsigned d = (unsigned)(*s - '0');
        if (v > (lim - d) / 10)
            return SC_E_INPUT;
        v = v * 10 + d;
    }
    if (*s != '\0')
        return SC_E_INPUT;
    *out = neg ? (long)(0UL - v) : (long)v;
    return SC_OK;
}

/* A plain whole number: optional '-', 1..18 digits (no overflow to check). */
static const char *plain_long(const char *p, const char *end, long *out)
{
    int neg = p < end && *p == '-';
    p += neg;
    const char *first = p;
    long v = 0;
    while (p < end && *p >= '0' && *p <= '9' && p - first < 18)
        v = v * 10 + (*p++ - '0');
    if (p == first || (p < end && *p >= '0' && *p <= '9'))
        return NULL;
    *out = neg ? -v : v;
    return p;
}

bool sc_csv_is_plain_row(const sc_csv *r, const char *types, long *longs, double *doubles)
{
    const char *p = r->text, *end = r->text + r->len;
    /* the number parser may look past the line into the rest of the block (the next lines:
     * read bytes; it takes none of them) */
    const char *readable = end;
    if (r->buf && r->text >= r->buf && end <= r->buf + r->buf_len)
        readable = r->buf + r->buf_len;
    for (const char *t = types; *t; ++t) {
        if (t != types) {
            if (p == end || *p != ',')
                return false;
            ++p;
        }
        if (*t == 'L')
            p = plain_long(p, end, longs++);
        else if (p == end || sc_number_parse_prefix_within(p, end, readable, &p, doubles++) != SC_OK)
            return false;
        if (!p)
            return false;
    }
    return p == end;
}

sc_status sc_csv_double(const sc_csv *r, int k, const char *name, double *out, sc_error *err)
{
    if (k < 0 || k >= r->nfields)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line, "missing field '%s'", name);
    if (sc_parse_double(r->field[k], out) != 0) /* not a number, not finite, or it underflows */
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "field '%s' is not a finite number (nor 0 or above 1e-308 in "
                            "magnitude): '%.40s'", name, r->field[k]);
    return SC_OK;
}

sc_status sc_csv_long(const sc_csv *r, int k, const char *name, long *out, sc_error *err)
{
    if (k < 0 || k >= r->nfields)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line, "missing field '%s'", name);
    if (sc_parse_long(r->field[k], out) != 0)
        return sc_error_set(err, SC_E_INPUT, r->path, r->line,
                            "field '%s' is not a whole number: '%.40s'", name, r->field[k]);
    return SC_OK;
}

bool sc_header_kv(char *line, char *key, size_t keylen, char **value)
{
    char *p = line;
    if (*p != '#')
        return false;
    ++p;
    char *eq = strchr(p, '=');
    if (!eq)
        return false;
    *eq = '\0';
    char *k = sc_str_trim(p);
    char *v = sc_str_trim(eq + 1);
    if (!*k || strlen(k) >= keylen) {
        *eq = '=';
        return false;
    }
    snprintf(key, keylen, "%s", k);
    *value = v;
    return true;
}
