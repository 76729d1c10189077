/* Unit tests of the common module: strict CSV reading, atomic writes, the seeded RNG. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/rng.h"
#include "selfcal/version.h"

static void write_text(const char *path, const char *text, size_t len)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, len, f), len);
    fclose(f);
}

static void test_parse_numbers(void **state)
{
    (void)state;
    double d;
    long l;
    assert_int_equal(sc_parse_double("1.5e-3", &d), 0);
    assert_true(d == 1.5e-3);
    assert_int_equal(sc_parse_double("-0", &d), 0);
    assert_int_equal(sc_parse_double("1.5x", &d), SC_E_INPUT);
    assert_int_equal(sc_parse_double("", &d), SC_E_INPUT);
    assert_int_equal(sc_parse_double("nan", &d), SC_E_INPUT);
    assert_int_equal(sc_parse_double("inf", &d), SC_E_INPUT);
    assert_int_equal(sc_parse_double("1e999", &d), SC_E_INPUT);
    assert_int_equal(sc_parse_long("42", &l), 0);
    assert_int_equal(l, 42);
    assert_int_equal(sc_parse_long("4.2", &l), SC_E_INPUT);
    assert_int_equal(sc_parse_long("99999999999999999999999", &l), SC_E_INPUT);
}

static void test_error_messages_stay_one_printable_line(void **state)
{
    (void)state;
    sc_error err;
    /* quoted user bytes: CR, LF, vertical tab, form feed, ESC, DEL, C1 NEL (U+0085), a broken
     * UTF-8 sequence, a line separator (U+2028) -> '?'; valid UTF-8 such as µ stays */
    sc_error_set(&err, SC_E_INPUT, "f.csv", 3, "bad '%s'",
                 "a\rb\nc\vd\fe\x1b[31mf\x7fg\xc2\x85h\xff\xfei\xe2\x80\xa8j 5 \xc2\xb5m");
    /* every offending byte becomes one '?' */
    assert_string_equal(err.msg, "bad 'a?b?c?d?e?[31mf?g??h??i???j 5 \xc2\xb5m'");
    assert_int_equal(err.line, 3);
}

static void test_csv_lines_and_errors(void **state)
{
    (void)state;
    const char *path = SELFCAL_TEST_TMP "/common.csv";
    write_text(path, "# a = 1\r\nx,y\n 1 , 2.5\n3,abc\n", strlen("# a = 1\r\nx,y\n 1 , 2.5\n3,abc\n"));
    sc_csv r;
    sc_error err;
    sc_error_clear(&err);
    assert_int_equal(sc_csv_open(&r, path, &err), SC_OK);
    assert_int_equal(sc_csv_next_line(&r, &err), 1);
    char key[32], *val;
    assert_int_equal(sc_header_kv(r.text, key, sizeof key, &val), 1);
    assert_string_equal(key, "a");
    assert_string_equal(val, "1");
    assert_int_equal(sc_csv_next_line(&r, &err), 1);
    assert_int_equal(sc_csv_next_line(&r, &err), 1);
    assert_int_equal(sc_csv_split(&r, &err), 2);
    double v;
    assert_int_equal(sc_csv_double(&r, 1, "y", &v, &err), SC_OK);
    assert_true(v == 2.5);
    assert_int_equal(sc_csv_next_line(&r, &err), 1);
    assert_int_equal(sc_csv_split(&r, &err), 2);
    assert_int_equal(sc_csv_double(&r, 1, "y", &v, &err), SC_E_INPUT);
    assert_int_equal(err.line, 4);
    assert_non_null(strstr(err.msg, "'y'"));
    char buf[600];
    sc_error_format(&err, buf, sizeof buf);
    assert_non_null(strstr(buf, "common.csv:4:"));
    assert_int_equal(sc_csv_next_line(&r, &err), 0);
    sc_csv_close(&r);

    write_text(path, "a\0b\n", 4);
    assert_int_equal(sc_csv_open(&r, path, &err), SC_OK);
    assert_int_equal(sc_csv_next_line(&r, &err), -1);
    assert_int_equal(err.code, SC_E_INPUT);
    sc_csv_close(&r);

    assert_int_equal(sc_csv_open(&r, SELFCAL_TEST_TMP "/does-not-exist.csv", &err), SC_E_INPUT);
    assert_int_equal(err.sys_errno, ENOENT); /* the system's reason, for bindings (Python) */
    /* a directory is bad input too, said as such (not a read error later) */
    assert_int_equal(sc_csv_open(&r, SELFCAL_TEST_TMP, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "directory"));
    assert_int_equal(err.sys_errno, EISDIR);
    /* an error that is not the system's carries no errno (sc_error_set resets it) */
    sc_error_set(&err, SC_E_INPUT, "f", 1, "bad");
    assert_int_equal(err.sys_errno, 0);
    assert_null(sc_open_input(SELFCAL_TEST_TMP, &err));
    assert_int_equal(err.code, SC_E_INPUT);
    assert_int_equal(err.sys_errno, EISDIR);
    sc_error_clear(&err);
    assert_int_equal(err.sys_errno, 0);
    /* a path naming nothing is bad input (exit 2); the system refusing a file is not (exit 1) */
    assert_int_equal(sc_open_failure_status(ENOENT), SC_E_INPUT);
    assert_int_equal(sc_open_failure_status(ENOTDIR), SC_E_INPUT);
    assert_int_equal(sc_open_failure_status(EACCES), SC_E_IO);
    assert_int_equal(sc_open_failure_status(EIO), SC_E_IO);
    assert_int_equal(sc_open_failure_status(EMFILE), SC_E_IO);
    assert_int_equal(sc_open_failure_status(ENOMEM), SC_E_NOMEM);
    write_text(path, "x\n", 2);
    if (geteuid() != 0 && chmod(path, 0) == 0) { /* root reads any file */
        assert_int_equal(sc_csv_open(&r, path, &err), SC_E_IO);
        assert_non_null(strstr(err.msg, "ermission"));
        assert_int_equal(err.sys_errno, EACCES);
        chmod(path, 0644);
    }

    /* a UTF-8 byte-order mark before the first line is not text; the same bytes later are */
    const char bom[] = "\xEF\xBB\xBF# selfcal-grid v1\r\n\xEF\xBB\xBFx\n";
    write_text(path, bom, sizeof bom - 1);
    assert_int_equal(sc_csv_open(&r, path, &err), SC_OK);
    assert_int_equal(sc_csv_next_line(&r, &err), 1);
    assert_string_equal(r.text, "# selfcal-grid v1");
    assert_int_equal((int)r.len, 17);
    assert_int_equal(sc_csv_next_line(&r, &err), 1);
    assert_string_equal(r.text, "\xEF\xBB\xBFx");
    sc_csv_close(&r);
}

/* An endless run of comment or blank lines (a pipe from `yes '#'`) is refused after
 * SC_CSV_MAX_SKIP_RUN of them in a row; as many, then data, reads; data in between restarts the
 * count. */
static void test_csv_skip_run_limit(void **state)
{
    (void)state;
    const char *path = SELFCAL_TEST_TMP "/skiprun.csv";
    const long n = SC_CSV_MAX_SKIP_RUN;
    for (int variant = 0; variant < 3; ++variant) {
        FILE *f = fopen(path, "wb");
        assert_non_null(f);
        for (long k = 0; k < n; ++k) {
            if (variant == 2 && k == n / 2)
                fputs("1,2\n", f); /* data in between: two runs below the limit */
            fputs(k % 4 == 0 ? "# c\n" : k % 4 == 1 ? "\n" : k % 4 == 2 ? " \t\n" : "\f\v \n", f);
        }
        fputs(variant == 1 ? "#\n" : "1,2\n", f); /* variant 1: one comment more */
        fclose(f);
        sc_csv r;
        sc_error err;
        sc_error_clear(&err);
        assert_int_equal(sc_csv_open(&r, path, &err), SC_OK);
        int rc;
        long lines = 0;
        while ((rc = sc_csv_next_line(&r, &err)) == 1)
            ++lines;
        if (variant == 1) {
            assert_int_equal(rc, -1);
            assert_int_equal(err.code, SC_E_INPUT);
            assert_int_equal(err.line, n + 1);
            assert_non_null(strstr(err.msg, "comment or blank lines in a row"));
        } else {
            assert_int_equal(rc, 0);
            assert_int_equal(lines, n + 1 + (variant == 2));
        }
        sc_csv_close(&r);
    }
    remove(path);
}

static void test_atomic_file(void **state)
{
    (void)state;
    const char *path = SELFCAL_TEST_TMP "/atomic.txt";
    sc_error err;
    assert_int_equal(sc_write_file_atomic(path, "old\n", 4, &err), SC_OK);
    sc_afile f;
    assert_int_equal(sc_afile_open(&f, path, &err), SC_OK);
    fputs("half written", f.fp);
    sc_afile_abort(&f); /* the old content must survive and no temporary file stay */
    FILE *in = fopen(path, "r");
    char buf[32] = {0};
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "old\n");
    struct stat st;
    assert_int_not_equal(stat(f.tmp_path, &st), 0);
    /* a folder that does not exist, or a folder in place of the file: the system's errno kept */
    assert_int_equal(sc_afile_open(&f, SELFCAL_TEST_TMP "/no-such-dir/a.txt", &err), SC_E_IO);
    assert_int_equal(err.sys_errno, ENOENT);
    assert_int_equal(sc_afile_open(&f, SELFCAL_TEST_TMP, &err), SC_E_INPUT);
    assert_int_equal(err.sys_errno, EISDIR);
    assert_int_equal(sc_afile_open(&f, path, &err), SC_OK);
    fputs("new\n", f.fp);
    assert_int_equal(sc_afile_commit(&f, &err), SC_OK);
    in = fopen(path, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "new\n");
    assert_int_equal(sc_write_file_atomic(SELFCAL_TEST_TMP "/no/such/dir/x", "x", 1, &err), SC_E_IO);
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* sc_afile_finish_all and sc_afile_finish: a failed computation aborts the group (old files kept, no temporary
 * file, the status passed through); a good one commits it. */
static void test_atomic_finish_all(void **state)
{
    (void)state;
    const char *a = SELFCAL_TEST_TMP "/finish_a.txt", *b = SELFCAL_TEST_TMP "/finish_b.txt";
    sc_error err;
    assert_int_equal(sc_write_file_atomic(a, "old a\n", 6, &err), SC_OK);
    unlink(b);
    sc_afile f[2];
    memset(f, 0, sizeof f);
    assert_int_equal(sc_afile_open(&f[0], a, &err), SC_OK);
    assert_int_equal(sc_afile_open(&f[1], b, &err), SC_OK);
    fputs("new a\n", f[0].fp);
    char tmp0[sizeof f[0].tmp_path];
    snprintf(tmp0, sizeof tmp0, "%s", f[0].tmp_path);
    assert_int_equal(sc_afile_finish_all(f, 2, SC_E_INPUT, &err), SC_E_INPUT);
    char buf[32] = {0};
    FILE *in = fopen(a, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "old a\n");
    assert_false(file_exists(b));
    assert_false(file_exists(tmp0));
    memset(f, 0, sizeof f);
    assert_int_equal(sc_afile_open(&f[0], a, &err), SC_OK);
    assert_int_equal(sc_afile_open(&f[1], b, &err), SC_OK);
    fputs("new a\n", f[0].fp);
    fputs("new b\n", f[1].fp);
    assert_int_equal(sc_afile_finish_all(f, 2, SC_OK, &err), SC_OK);
    in = fopen(a, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "new a\n");
    assert_true(file_exists(b));
    /* one file: sc_afile_finish */
    sc_afile one;
    assert_int_equal(sc_afile_open(&one, a, &err), SC_OK);
    fputs("newer a\n", one.fp);
    assert_int_equal(sc_afile_finish(&one, SC_E_NOMEM, &err), SC_E_NOMEM);
    in = fopen(a, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "new a\n");
    assert_int_equal(sc_afile_open(&one, a, &err), SC_OK);
    fputs("newer a\n", one.fp);
    assert_int_equal(sc_afile_finish(&one, SC_OK, &err), SC_OK);
    in = fopen(a, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "newer a\n");
}

/* Count of this process' open descriptors (/proc/self/fd, less the one reading it). */
static int open_fds(void)
{
    DIR *d = opendir("/proc/self/fd");
    assert_non_null(d);
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        n += e->d_name[0] != '.';
    closedir(d);
    return n - 1;
}

/* sc_afile_park: a group far larger than the descriptors it holds (each file closed once
 * written), renamed as one group; a group aborted after parking leaves the old files and no
 * temporary file; a parked file committed alone. */
static void test_atomic_park(void **state)
{
    (void)state;
    enum { N = 100 };
    static sc_afile f[N];
    char path[N][256];
    sc_error err;
    const int fds0 = open_fds();
    for (int k = 0; k < N; ++k) {
        snprintf(path[k], sizeof path[k], SELFCAL_TEST_TMP "/park_%d.txt", k);
        assert_int_equal(sc_write_file_atomic(path[k], "old\n", 4, &err), SC_OK);
    }
    /* aborted: the old contents stay, no temporary file is left */
    for (int k = 0; k < N; ++k) {
        assert_int_equal(sc_afile_open(&f[k], path[k], &err), SC_OK);
        fprintf(f[k].fp, "new %d\n", k);
        assert_int_equal(sc_afile_park(&f[k], &err), SC_OK);
        assert_null(f[k].fp);
        assert_true(f[k].tmp_path[0] != '\0' && file_exists(f[k].tmp_path));
    }
    assert_int_equal(open_fds(), fds0); /* none held */
    char tmp0[sizeof f[0].tmp_path];
    snprintf(tmp0, sizeof tmp0, "%s", f[0].tmp_path);
    assert_int_equal(sc_afile_finish_all(f, N, SC_E_INPUT, &err), SC_E_INPUT);
    assert_false(file_exists(tmp0));
    char buf[32];
    for (int k = 0; k < N; ++k) {
        FILE *in = fopen(path[k], "r");
        assert_non_null(in);
        assert_non_null(fgets(buf, sizeof buf, in));
        fclose(in);
        assert_string_equal(buf, "old\n");
    }
    /* committed: every file renamed, the last one still open when the group ends */
    for (int k = 0; k < N; ++k) {
        assert_int_equal(sc_afile_open(&f[k], path[k], &err), SC_OK);
        fprintf(f[k].fp, "new %d\n", k);
        if (k < N - 1)
            assert_int_equal(sc_afile_park(&f[k], &err), SC_OK);
    }
    snprintf(tmp0, sizeof tmp0, "%s", f[0].tmp_path);
    assert_int_equal(sc_afile_finish_all(f, N, SC_OK, &err), SC_OK);
    assert_false(file_exists(tmp0));
    for (int k = 0; k < N; ++k) {
        char want[32];
        snprintf(want, sizeof want, "new %d\n", k);
        FILE *in = fopen(path[k], "r");
        assert_non_null(in);
        assert_non_null(fgets(buf, sizeof buf, in));
        fclose(in);
        assert_string_equal(buf, want);
        assert_null(f[k].fp);
        sc_afile_abort(&f[k]); /* after the commit: nothing to do, the file stays */
        assert_true(file_exists(path[k]));
        unlink(path[k]);
    }
    assert_int_equal(open_fds(), fds0);
    /* one parked file, committed alone; parking what is not open is refused */
    assert_int_equal(sc_afile_open(&f[0], path[0], &err), SC_OK);
    fputs("one\n", f[0].fp);
    assert_int_equal(sc_afile_park(&f[0], &err), SC_OK);
    assert_false(file_exists(path[0]));
    assert_int_equal(sc_afile_commit(&f[0], &err), SC_OK);
    assert_true(file_exists(path[0]));
    assert_int_equal(sc_afile_park(&f[0], &err), SC_E_INTERNAL);
    unlink(path[0]);
}

static void test_atomic_group(void **state)
{
    (void)state;
    const char *a = SELFCAL_TEST_TMP "/group_a.txt", *b = SELFCAL_TEST_TMP "/group_b.txt";
    unlink(a);
    unlink(b);
    sc_error err;
    sc_afile f[3];
    memset(f, 0, sizeof f); /* f[1] stays closed: skipped */
    assert_int_equal(sc_afile_open(&f[0], a, &err), SC_OK);
    assert_int_equal(sc_afile_open(&f[2], b, &err), SC_OK);
    fputs("A\n", f[0].fp);
    fputs("B\n", f[2].fp);
    assert_false(file_exists(a));
    assert_int_equal(sc_afile_commit_all(f, 3, &err), SC_OK);
    assert_true(file_exists(a) && file_exists(b));

    /* a write error in the second file: neither final name changes, no temporary file stays */
    assert_int_equal(sc_write_file_atomic(a, "old a\n", 6, &err), SC_OK);
    assert_int_equal(sc_write_file_atomic(b, "old b\n", 6, &err), SC_OK);
    memset(f, 0, sizeof f);
    assert_int_equal(sc_afile_open(&f[0], a, &err), SC_OK);
    assert_int_equal(sc_afile_open(&f[1], b, &err), SC_OK);
    fputs("new a\n", f[0].fp);
    /* swap in a read-only stream: writing sets its error (an anonymous O_TMPFILE temporary is
     * opened again through /proc) */
    char reopen[64];
    snprintf(reopen, sizeof reopen, "/proc/self/fd/%d", fileno(f[1].fp));
    FILE *ro = fopen(f[1].tmp_path[0] ? f[1].tmp_path : reopen, "r");
    assert_non_null(ro);
    fclose(f[1].fp);
    f[1].fp = ro;
    fputs("new b\n", f[1].fp);
    char tmp0[sizeof f[0].tmp_path], tmp1[sizeof f[1].tmp_path];
    snprintf(tmp0, sizeof tmp0, "%s", f[0].tmp_path);
    snprintf(tmp1, sizeof tmp1, "%s", f[1].tmp_path);
    assert_int_equal(sc_afile_commit_all(f, 2, &err), SC_E_IO);
    char buf[32] = {0};
    FILE *in = fopen(a, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "old a\n");
    in = fopen(b, "r");
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "old b\n");
    assert_false(file_exists(tmp0));
    assert_false(file_exists(tmp1));
}

/* Issue 36: no temporary file under any name while a file is written (anonymous where the file
 * system has O_TMPFILE), and a commit removes the stale "PATH.tmpXXXXXX" files of its name that
 * nobody holds (a killed writer's), not a live writer's (flocked), nor other names. */
static void test_atomic_stale_tmps(void **state)
{
    (void)state;
    const char *path = SELFCAL_TEST_TMP "/stale.txt";
    const char *stale = SELFCAL_TEST_TMP "/stale.txt.tmpAb3xY9";
    const char *live = SELFCAL_TEST_TMP "/stale.txt.tmpLIVE01";
    const char *other[] = {SELFCAL_TEST_TMP "/stale.txt.tmpABCDEFG", SELFCAL_TEST_TMP "/stale.txt.tmp12",
                           SELFCAL_TEST_TMP "/stale2.txt.tmpABCDEF", SELFCAL_TEST_TMP "/stale.txt.tmp-x-y-z"};
    const char *all[] = {stale, live, other[0], other[1], other[2], other[3]};
    for (size_t k = 0; k < sizeof all / sizeof all[0]; ++k) {
        FILE *w = fopen(all[k], "w");
        assert_non_null(w);
        fputs("x\n", w);
        fclose(w);
    }
    int lfd = open(live, O_RDONLY);
    assert_true(lfd >= 0);
    assert_int_equal(flock(lfd, LOCK_EX), 0);
    sc_error err;
    sc_afile f;
    assert_int_equal(sc_afile_open(&f, path, &err), SC_OK);
    if (f.direct == 2) /* anonymous: nothing under a name until the commit */
        assert_string_equal(f.tmp_path, "");
    fputs("new\n", f.fp);
    assert_int_equal(sc_afile_commit(&f, &err), SC_OK);
    assert_false(file_exists(stale));
    assert_true(file_exists(live));
    for (size_t k = 0; k < 4; ++k)
        assert_true(file_exists(other[k]));
    close(lfd); /* its writer gone: the next commit removes it */
    assert_int_equal(sc_write_file_atomic(path, "again\n", 6, &err), SC_OK);
    assert_false(file_exists(live));
    for (size_t k = 0; k < 4; ++k) {
        assert_true(file_exists(other[k]));
        unlink(other[k]);
    }
    /* an aborted anonymous temporary leaves nothing either */
    assert_int_equal(sc_afile_open(&f, path, &err), SC_OK);
    fputs("discarded\n", f.fp);
    sc_afile_abort(&f);
    char buf[16] = {0};
    FILE *in = fopen(path, "r");
    assert_non_null(in);
    assert_non_null(fgets(buf, sizeof buf, in));
    fclose(in);
    assert_string_equal(buf, "again\n");
}

static void test_rng(void **state)
{
    (void)state;
    sc_rng a, b;
    sc_rng_seed(&a, 7);
    sc_rng_seed(&b, 7);
    for (int k = 0; k < 100; ++k)
        assert_true(sc_rng_u64(&a) == sc_rng_u64(&b));
    sc_rng_seed(&a, 1);
    double s = 0, s2 = 0;
    const int n = 200000;
    for (int k = 0; k < n; ++k) {
        double z = sc_rng_normal(&a);
        s += z;
        s2 += z * z;
    }
    double mean = s / n, var = s2 / n - mean * mean;
    assert_true(fabs(mean) < 0.01);
    assert_true(fabs(var - 1.0) < 0.01);
}

/* sc_version() is the number of the generated header, which is project(VERSION)'s. */
/* A device as the output (-o /dev/null) is written straight: renaming a temporary file over it
 * would replace the device itself (as root, /dev/null became a regular file). A directory is
 * refused. */
static void test_atomic_file_device_target(void **state)
{
    (void)state;
    struct stat before, after;
    assert_int_equal(stat("/dev/null", &before), 0);
    assert_true(S_ISCHR(before.st_mode));
    sc_error err;
    assert_int_equal(sc_write_file_atomic("/dev/null", "x\n", 2, &err), SC_OK);
    sc_afile group[2];
    assert_int_equal(sc_afile_open(&group[0], "/dev/null", &err), SC_OK);
    assert_int_equal(sc_afile_open(&group[1], "/dev/null", &err), SC_OK);
    fputs("y\n", group[0].fp);
    assert_int_equal(sc_afile_commit_all(group, 2, &err), SC_OK);
    assert_int_equal(sc_afile_open(&group[0], "/dev/null", &err), SC_OK);
    sc_afile_abort(&group[0]);
    assert_int_equal(stat("/dev/null", &after), 0);
    assert_true(S_ISCHR(after.st_mode));
    assert_int_equal(after.st_rdev, before.st_rdev);
    assert_int_equal(access("/dev/null.tmp", F_OK), -1);
    assert_int_equal(sc_write_file_atomic("/tmp", "x", 1, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "directory"));
}

/* The plain-row fast path takes a row only as the general path (split, sc_csv_long,
 * sc_csv_double) takes it, with the same values; any other row is left to the general path. */
static void test_csv_plain_row(void **state)
{
    (void)state;
    static const char *const fields[] = {
        "1",  "2",     "-3",   "+4",   " 5",   "6 ",  "0",     "12345678901234567890", "1.5",
        "",   "-0.25", "1e3",  "abc",  "inf",  "nan", "1e999", "24.178524343604046",   "7,8",
        ".5", "5.",    "0x10", "1e-400", "\r",  "-",   "3.2675473613268378",
        "0.000123456789012345678"};
    const int nf = (int)(sizeof fields / sizeof *fields);
    const char *path = SELFCAL_TEST_TMP "/plain.csv";
    sc_rng rng;
    sc_rng_seed(&rng, 7);
    static char text[512 * 1024];
    size_t len = 0;
    int rows = 4000;
    for (int t = 0; t < rows; ++t) {
        int n = 3 + (int)(sc_rng_uniform(&rng) * 3); /* 3..5 fields; 4 is what we ask for */
        for (int c = 0; c < n; ++c) {
            const char *f = fields[sc_rng_uniform(&rng) < 0.6 ? c % 2 == 0 ? 0 : 16
                                                             : (int)(sc_rng_uniform(&rng) * nf)];
            len += (size_t)snprintf(text + len, sizeof text - len, "%s%s", c ? "," : "", f);
        }
        text[len++] = '\n';
    }
    write_text(path, text, len);
    sc_csv r;
    sc_error err;
    assert_int_equal(sc_csv_open(&r, path, &err), SC_OK);
    int plain = 0, other = 0;
    while (sc_csv_next_line(&r, &err) == 1) {
        long lv[2];
        double dv[2];
        int fast = sc_csv_is_plain_row(&r, "LDLD", lv, dv);
        char copy[256];
        snprintf(copy, sizeof copy, "%s", r.text);
        int ok = sc_csv_split(&r, &err) == 4;
        long l0 = 0, l1 = 0;
        double d0 = 0, d1 = 0;
        ok = ok && sc_csv_long(&r, 0, "a", &l0, &err) == SC_OK &&
             sc_csv_double(&r, 1, "b", &d0, &err) == SC_OK &&
             sc_csv_long(&r, 2, "c", &l1, &err) == SC_OK &&
             sc_csv_double(&r, 3, "d", &d1, &err) == SC_OK;
        if (fast) {
            if (!ok)
                fail_msg("plain row the general path refuses: '%s'", copy);
            assert_true(lv[0] == l0 && lv[1] == l1);
            assert_memory_equal(&dv[0], &d0, sizeof d0);
            assert_memory_equal(&dv[1], &d1, sizeof d1);
            plain++;
        } else {
            /* left to the general path: refused there, or not plain (blanks, a '+', ...) */
            other++;
        }
    }
    sc_csv_close(&r);
    assert_true(plain > 100 && other > 100);
}

/* A long line with a NUL byte: the NUL is reported when it lies in the 64 KiB blocks of the file
 * that reach 65 536 bytes into the line, else the length (the rule the fuzz regressions hold). */
static void test_csv_long_line_with_nul(void **state)
{
    (void)state;
    const char *path = SELFCAL_TEST_TMP "/long_nul.csv";
    static char text[140000];
    const struct {
        size_t start, nul;
        const char *msg;
    } cases[] = {{0, 70000, "line longer"},  /* line at 0: blocks reach 65 536; NUL past it */
                 {100, 66000, "NUL byte"},   /* line at 100: blocks reach 131 072 */
                 {100, 131500, "line longer"}, {0, 60000, "NUL byte"}};
    for (size_t c = 0; c < sizeof cases / sizeof *cases; ++c) {
        memset(text, 'x', sizeof text);
        if (cases[c].start)
            text[cases[c].start - 1] = '\n';
        text[cases[c].nul] = '\0';
        write_text(path, text, sizeof text);
        sc_csv r;
        sc_error err;
        sc_error_clear(&err);
        assert_int_equal(sc_csv_open(&r, path, &err), SC_OK);
        int rc = sc_csv_next_line(&r, &err);
        if (cases[c].start)
            rc = sc_csv_next_line(&r, &err);
        assert_int_equal(rc, -1);
        assert_non_null(strstr(err.msg, cases[c].msg));
        assert_int_equal(err.line, cases[c].start ? 2 : 1);
        sc_csv_close(&r);
    }
}

static void test_version(void **state)
{
    (void)state;
    char want[64];
    snprintf(want, sizeof want, "%d.%d.%d", SC_VERSION_MAJOR, SC_VERSION_MINOR, SC_VERSION_PATCH);
    assert_string_equal(sc_version(), want);
    assert_string_equal(SC_VERSION_STRING, want);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse_numbers),
        cmocka_unit_test(test_error_messages_stay_one_printable_line),
        cmocka_unit_test(test_csv_lines_and_errors),
        cmocka_unit_test(test_csv_skip_run_limit),
        cmocka_unit_test(test_csv_plain_row),
        cmocka_unit_test(test_csv_long_line_with_nul),
        cmocka_unit_test(test_atomic_file),
        cmocka_unit_test(test_atomic_group),
        cmocka_unit_test(test_atomic_stale_tmps),
        cmocka_unit_test(test_atomic_finish_all),
        cmocka_unit_test(test_atomic_park),
        cmocka_unit_test(test_atomic_file_device_target),
        cmocka_unit_test(test_rng),
        cmocka_unit_test(test_version),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
