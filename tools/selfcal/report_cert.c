/* report_cert.c — the certificate parts of a report: --info/--info-file, the header block, the
 * printed page label, the uncertainty statement, and --pdf through headless Chromium
 * (report_cert.h). */
#define _GNU_SOURCE /* mkstemps, mkdtemp */
#include "report_cert.h"
#include "selfcal/csv.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "cli.h"
#include "report_html.h"

extern char **environ;

/* The keys ISO/IEC 17025 §7.8 asks a certificate to carry, in the order the header shows them. */
static const struct {
    const char *key, *label;
} KNOWN[] = {
    {"report_id", "Report number"},
    {"item", "Calibrated item"},
    {"plate", "Reference plate"},
    {"instrument", "Measuring instrument"},
    {"customer", "Customer"},
    {"operator", "Operator"},
    {"measured_on", "Date of measurement"},
    {"conditions", "Environmental conditions"},
    {"approved_by", "Approved by"},
};
#define N_KNOWN (sizeof KNOWN / sizeof KNOWN[0])

int report_info_option(const char *cmd, const char *opt, const char *v, report_info *ri)
{
    if (!strcmp(opt, "--pdf")) {
        ri->pdf = v;
        return CLI_OK;
    }
    int file = !strcmp(opt, "--info-file");
    if (!file && strcmp(opt, "--info"))
        return -1;
    if (ri->n_opt >= 2 * REPORT_INFO_MAX)
        return cli_usage_error(cmd, "more than %d --info and --info-file options",
                               2 * REPORT_INFO_MAX);
    if (!file && !strchr(v, '='))
        return cli_usage_error(cmd, "--info needs KEY=VALUE, got '%s'", v);
    ri->opt_val[ri->n_opt] = v;
    ri->opt_is_file[ri->n_opt++] = file;
    return CLI_OK;
}

int report_info_opt(const char *cmd, const char *opt, const char *v, void *field)
{
    return report_info_option(cmd, opt, v, field);
}

static int key_ok(const char *k, size_t len)
{
    if (len == 0 || len > 64)
        return 0;
    for (size_t i = 0; i < len; ++i)
        if (!isalnum((unsigned char)k[i]) && k[i] != '_' && k[i] != '-' && k[i] != '.')
            return 0;
    return 1;
}

/* key (len bytes) = val (vlen bytes) into ri; NULL, or what is wrong. */
static const char *info_set(report_info *ri, const char *key, size_t len, const char *val,
                            size_t vlen)
{
    if (!key_ok(key, len))
        return "a key is letters, digits, '_', '-' or '.' (1 to 64)";
    if (vlen > REPORT_INFO_VALUE_MAX)
        return "a value longer than 1000 bytes";
    for (size_t i = 0; i < vlen; ++i)
        if ((unsigned char)val[i] < 0x20 || val[i] == 0x7f)
            return "a control character in the value";
    char *k = strndup(key, len), *v = strndup(val, vlen);
    if (!k || !v) {
        free(k);
        free(v);
        return "out of memory";
    }
    for (int q = 0; q < ri->n; ++q)
        if (!strcmp(ri->key[q], k)) { /* given again: the later value */
            free(ri->val[q]);
            free(k);
            ri->val[q] = v;
            return NULL;
        }
    if (ri->n >= REPORT_INFO_MAX) {
        free(k);
        free(v);
        return "more than 64 keys";
    }
    ri->key[ri->n] = k;
    ri->val[ri->n++] = v;
    return NULL;
}

static void trim(const char **s, const char **e)
{
    while (*s < *e && isspace((unsigned char)**s))
        ++*s;
    while (*e > *s && isspace((unsigned char)(*e)[-1]))
        --*e;
}

/* One `key = value` line (blank and '#' lines skipped). */
static const char *info_line(report_info *ri, const char *s, const char *e)
{
    trim(&s, &e);
    if (s == e || *s == '#')
        return NULL;
    const char *eq = memchr(s, '=', (size_t)(e - s));
    if (!eq)
        return "not a 'key = value' line";
    const char *ke = eq, *vs = eq + 1;
    trim(&s, &ke);
    trim(&vs, &e);
    return info_set(ri, s, (size_t)(ke - s), vs, (size_t)(e - vs));
}

static sc_status info_file(report_info *ri, const char *path, sc_error *err)
{
    FILE *f = sc_open_input(path, err); /* "cannot open: ...", or "is a directory" */
    if (!f)
        return err ? err->code : SC_E_INPUT;
    char *buf = malloc(REPORT_INFO_FILE_MAX + 1);
    if (!buf) {
        fclose(f);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    size_t len = fread(buf, 1, REPORT_INFO_FILE_MAX + 1, f);
    int bad = ferror(f);
    fclose(f);
    sc_status st = SC_OK;
    if (bad)
        st = sc_error_set(err, SC_E_INPUT, path, 0, "cannot read");
    else if (len > REPORT_INFO_FILE_MAX)
        st = sc_error_set(err, SC_E_INPUT, path, 0, "an --info-file holds at most %d bytes",
                          REPORT_INFO_FILE_MAX);
    else if (memchr(buf, 0, len))
        st = sc_error_set(err, SC_E_INPUT, path, 0, "a NUL byte: not a text file");
    long line = 1;
    for (size_t a = 0; st == SC_OK && a < len; ++line) {
        const char *s = buf + a, *nl = memchr(s, '\n', len - a);
        const char *e = nl ? nl : buf + len;
        const char *why = info_line(ri, s, e);
        if (why)
            st = sc_error_set(err, SC_E_INPUT, path, line, "%s", why);
        a = (size_t)(e - buf) + 1;
    }
    free(buf);
    return st;
}

sc_status report_info_load(report_info *ri, sc_error *err)
{
    for (int q = 0; q < ri->n_opt; ++q) {
        const char *v = ri->opt_val[q];
        if (ri->opt_is_file[q]) {
            sc_status st = info_file(ri, v, err);
            if (st != SC_OK)
                return st;
            continue;
        }
        const char *eq = strchr(v, '='), *ks = v, *ke = eq, *vs = eq + 1, *ve = v + strlen(v);
        trim(&ks, &ke);
        trim(&vs, &ve);
        const char *why = info_set(ri, ks, (size_t)(ke - ks), vs, (size_t)(ve - vs));
        if (why)
            return sc_error_set(err, SC_E_INPUT, "--info", 0, "'%s': %s", v, why);
    }
    return SC_OK;
}

void report_info_free(report_info *ri)
{
    for (int q = 0; q < ri->n; ++q) {
        free(ri->key[q]);
        free(ri->val[q]);
    }
    ri->n = 0;
}

const char *report_info_get(const report_info *ri, const char *key)
{
    for (int q = 0; q < ri->n; ++q)
        if (!strcmp(ri->key[q], key))
            return ri->val[q];
    return NULL;
}

static void info_row(FILE *fp, const char *key, const char *label, const char *val)
{
    fputs("<tr><th class=\"l\">", fp);
    html_esc(fp, label);
    fputs("</th><td class=\"l\" id=\"info-", fp);
    html_esc(fp, key);
    fputs("\">", fp);
    html_esc(fp, val);
    fputs("</td></tr>\n", fp);
}

void report_info_html(FILE *fp, const report_info *ri, const char *kind)
{
    fputs("<section id=\"certificate\">\n", fp);
    if (ri->n == 0) {
        fprintf(fp, "<p class=\"note\">This %s carries no identification of the item, the "
                    "customer or the report (<code>--info KEY=VALUE</code>, "
                    "<code>--info-file F</code>): it is not a calibration certificate.</p>\n",
                kind);
        fputs("</section>\n", fp);
        return;
    }
    fputs("<table class=\"cert\">\n", fp);
    for (size_t k = 0; k < N_KNOWN; ++k) {
        const char *v = report_info_get(ri, KNOWN[k].key);
        if (v)
            info_row(fp, KNOWN[k].key, KNOWN[k].label, v);
    }
    for (int q = 0; q < ri->n; ++q) {
        int known = 0;
        for (size_t k = 0; k < N_KNOWN; ++k)
            known |= !strcmp(ri->key[q], KNOWN[k].key);
        if (!known)
            info_row(fp, ri->key[q], ri->key[q], ri->val[q]);
    }
    fputs("</table>\n</section>\n", fp);
}

/* s as the body of a CSS string: ASCII letters, digits, space and harmless punctuation as they
 * are, UTF-8 bytes as they are, everything else as a hexadecimal escape. */
static void css_string(FILE *fp, const char *s)
{
    for (const unsigned char *c = (const unsigned char *)s; *c; ++c) {
        if (*c >= 0x80 || isalnum(*c) || strchr(" -_.,:;/()#+", *c))
            fputc(*c, fp);
        else
            fprintf(fp, "\\%x ", *c);
    }
}

void report_page_css(FILE *fp, const report_info *ri)
{
    const char *id = report_info_get(ri, "report_id");
    fputs("<style>\n@media print{@page{size:A4;margin:15mm 15mm 18mm 15mm;"
          "@bottom-left{content:\"", fp);
    if (id) {
        css_string(fp, "Report ");
        css_string(fp, id);
    }
    fputs("\";font-size:8pt;color:#333}"
          "@bottom-right{content:\"page \" counter(page) \" of \" counter(pages);font-size:8pt;"
          "color:#333}}}\n</style>\n", fp);
}

void report_uncertainty_statement(FILE *fp, const char *covers, const char *not_included)
{
    fputs("<p id=\"uncertainty-statement\" class=\"statement\">The reported expanded uncertainty "
          "of measurement U is stated as the standard uncertainty of measurement u multiplied by "
          "the coverage factor k = 2, which for a normal distribution corresponds to a coverage "
          "probability of approximately 95 %. The standard uncertainty has been determined in "
          "accordance with the GUM (JCGM 100:2008). U covers ", fp);
    html_esc(fp, covers);
    fputs(" ", fp);
    if (not_included)
        html_esc(fp, not_included);
    fputs("</p>\n", fp);
}

/* ---- PDF through headless Chromium ---- */

sc_status report_pdf_find(char *path, size_t cap, sc_error *err)
{
    const char *env = getenv("SELFCAL_CHROMIUM");
    if (env && *env) {
        if (access(env, X_OK) == 0) {
            snprintf(path, cap, "%s", env);
            return SC_OK;
        }
        return sc_error_set(err, SC_E_IO, NULL, 0, "--pdf: SELFCAL_CHROMIUM=%s is not an "
                            "executable program", env);
    }
    static const char *names[] = {"chromium", "chromium-browser", "google-chrome"};
    const char *pv = getenv("PATH");
    for (size_t k = 0; pv && k < sizeof names / sizeof names[0]; ++k)
        for (const char *s = pv; *s;) {
            const char *e = strchr(s, ':');
            size_t len = e ? (size_t)(e - s) : strlen(s);
            if (len > 0 && (size_t)snprintf(path, cap, "%.*s/%s", (int)len, s, names[k]) < cap &&
                access(path, X_OK) == 0)
                return SC_OK;
            s += len + (e ? 1 : 0);
        }
    return sc_error_set(err, SC_E_IO, NULL, 0, "--pdf needs Chromium (chromium, chromium-browser "
                        "or google-chrome on PATH, or SELFCAL_CHROMIUM); none found: print the "
                        "HTML report from a browser instead");
}

static int rm_entry(const char *p, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb, (void)flag, (void)ftw;
    return remove(p);
}

/* file:// URL of an absolute path, percent-encoded. */
static int file_url(const char *path, char *url, size_t cap)
{
    char abs[4096];
    if (!realpath(path, abs))
        return -1;
    size_t o = (size_t)snprintf(url, cap, "file://");
    for (const unsigned char *c = (const unsigned char *)abs; *c; ++c) {
        if (o + 4 >= cap)
            return -1;
        if (isalnum(*c) || strchr("/-_.~", *c))
            url[o++] = (char)*c;
        else
            o += (size_t)snprintf(url + o, cap - o, "%%%02X", *c);
    }
    url[o] = 0;
    return 0;
}

/* Run argv, its output to /dev/null, at most timeout_s seconds: 0 if it ended with status 0. */
static int run_quiet(char **argv, int timeout_s)
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    pid_t pid;
    int rc = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0)
        return -1;
    int status = 0;
    for (long waited_ms = 0;; waited_ms += 50) {
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid)
            break;
        if (w < 0 && errno != EINTR)
            return -1;
        if (waited_ms > 1000L * timeout_s) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            return -1;
        }
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : -1;
}

sc_status report_pdf_print(const char *chromium, const char *html_path, const char *pdf_path,
                           sc_error *err)
{
    char url[16384], tmp_pdf[4200], prof[] = "/tmp/selfcal-chromium-XXXXXX";
    if (file_url(html_path, url, sizeof url) != 0)
        return sc_error_set(err, SC_E_IO, html_path, 0, "--pdf: cannot name the HTML file");
    if ((size_t)snprintf(tmp_pdf, sizeof tmp_pdf, "%s.XXXXXX", pdf_path) >= sizeof tmp_pdf)
        return sc_error_set(err, SC_E_IO, pdf_path, 0, "path too long");
    int fd = mkstemp(tmp_pdf);
    if (fd < 0)
        return sc_error_set(err, SC_E_IO, pdf_path, 0, "cannot write: %s", strerror(errno));
    close(fd);
    if (!mkdtemp(prof)) {
        unlink(tmp_pdf);
        return sc_error_set(err, SC_E_IO, NULL, 0, "--pdf: no temporary folder: %s",
                            strerror(errno));
    }
    char a_prof[128], a_out[4300];
    snprintf(a_prof, sizeof a_prof, "--user-data-dir=%s", prof);
    snprintf(a_out, sizeof a_out, "--print-to-pdf=%s", tmp_pdf);
    char *argv[] = {(char *)chromium, "--headless", "--no-sandbox", "--disable-gpu",
                    "--no-first-run", "--disable-extensions", "--disable-background-networking",
                    "--disable-sync", "--disable-dev-shm-usage", a_prof,
                    "--proxy-server=http://127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND",
                    "--no-pdf-header-footer", a_out, url, NULL};
    int rc = run_quiet(argv, 600);
    nftw(prof, rm_entry, 16, FTW_DEPTH | FTW_PHYS);
    struct stat sb;
    char head[5] = {0};
    FILE *f = rc == 0 ? fopen(tmp_pdf, "rb") : NULL;
    if (f) {
        if (fread(head, 1, 4, f) != 4)
            head[0] = 0;
        fclose(f);
    }
    if (rc != 0 || stat(tmp_pdf, &sb) != 0 || sb.st_size < 100 || strcmp(head, "%PDF")) {
        unlink(tmp_pdf);
        return sc_error_set(err, SC_E_IO, pdf_path, 0, "Chromium (%s) did not print the report",
                            chromium);
    }
    int pfd = open(tmp_pdf, O_RDONLY);
    if (pfd >= 0) {
        fsync(pfd);
        close(pfd);
    }
    mode_t um = umask(0);
    umask(um);
    chmod(tmp_pdf, 0666 & ~um);
    if (rename(tmp_pdf, pdf_path) != 0) {
        int e = errno;
        unlink(tmp_pdf);
        return sc_error_set(err, SC_E_IO, pdf_path, 0, "cannot write: %s", strerror(e));
    }
    return SC_OK;
}

sc_status report_out_prepare(report_out *o, const report_info *ri, const char *out, sc_error *err)
{
    memset(o, 0, sizeof *o);
    o->out = out;
    if (ri->pdf) {
        sc_status st = report_pdf_find(o->chromium, sizeof o->chromium, err);
        if (st != SC_OK)
            return st;
    }
    if (out) {
        snprintf(o->html, sizeof o->html, "%s", out);
        return SC_OK;
    }
    /* --pdf alone: the HTML beside the PDF (Chromium reads it by its name, ending in .html) */
    const char *slash = strrchr(ri->pdf, '/');
    int dlen = slash ? (int)(slash - ri->pdf) + 1 : 0;
    if ((size_t)snprintf(o->html, sizeof o->html, "%.*s.selfcal-report-XXXXXX.html", dlen,
                         ri->pdf) >= sizeof o->html)
        return sc_error_set(err, SC_E_IO, ri->pdf, 0, "path too long");
    int fd = mkstemps(o->html, 5);
    if (fd < 0)
        return sc_error_set(err, SC_E_IO, ri->pdf, 0, "cannot write beside it: %s",
                            strerror(errno));
    close(fd);
    o->temp = 1;
    return SC_OK;
}

sc_status report_out_finish(report_out *o, const report_info *ri, sc_status st, sc_error *err)
{
    if (st == SC_OK && ri->pdf)
        st = report_pdf_print(o->chromium, o->html, ri->pdf, err);
    if (o->temp)
        unlink(o->html);
    return st;
}
