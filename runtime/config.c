/* runtime/config.c — configuration file and flags of selfcald: one table of the numeric
 * options (range and field) and one setter per other option; the file and argv readers feed both. */
#include "config.h"

#include <ctype.h>
#include <stddef.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "log.h"
#include "selfcal/csv.h"

const char sc_config_usage[] =
    "usage: selfcald --table TABLE [transports] [options]\n"
    "transports (any combination; default --modbus-tcp 127.0.0.1:1502):\n"
    "  --modbus-tcp HOST:PORT        Modbus TCP server: HOST an IPv4 address, [IPv6] or a name\n"
    "                                (PORT 0: any free port; the bound address is logged)\n"
    "  --modbus-rtu DEV[:BAUD[:PARITY[:DATABITS[:STOPBITS]]]]  Modbus RTU server (19200:E:8:1)\n"
    "  --can IFACE                   SocketCAN raw (ids 0x100 in, 0x101 out, 0x102 status)\n"
    "options:\n"
    "  --config FILE                 read 'key = value' lines (keys = these long options)\n"
    "  --mode measure|position|measure-exact  measure: p - G(p) - profile offsets (default);\n"
    "                                position: t + G(t) + profile offsets; measure-exact: the q\n"
    "                                with q + G(q) + offsets = p (3 fixed-point steps)\n"
    "  --unit-id N                   Modbus unit id (default 1)\n"
    "  --word-order high-first|low-first   32-bit word order (default high-first)\n"
    "  --max-connections N           Modbus TCP connection cap (default 64); at the cap a new\n"
    "                                client closes the longest-idle connection\n"
    "  --max-per-peer N              connections one client address may hold (default: a\n"
    "                                quarter of --max-connections; 0 = any)\n"
    "  --allow CIDR[,CIDR...]        only these client networks (a.b.c.d/len, IPv6/len; several\n"
    "                                add up); others are closed at accept (default: any)\n"
    "  --byte-timeout-ms N           a started TCP request must complete within N ms (500)\n"
    "  --idle-timeout-ms N           close TCP connections silent N ms; 0 = never (60000)\n"
    "  --rtu-byte-timeout-ms N       RTU frames end after N ms of silence, no t1.5 check (a\n"
    "                                bursty USB adapter); 0 = t1.5/t3.5 from the baud (default)\n"
    "  --max-correction-um X         refuse a table that can correct one coordinate by more\n"
    "                                than X um (1000; 0 = no bound); a reload keeps the old one\n"
    "  --max-gradient-um-per-mm X    refuse a table changing by more than X um per mm between\n"
    "                                neighbouring nodes (100; 0 = no bound)\n"
    "  --busy-poll-us N              after a request, poll without sleeping for N us: lower\n"
    "                                latency for a core given to selfcald (0 = off, default)\n"
    "  --can-in-id ID --can-out-id ID --can-status-id ID --can-status-period-ms N\n"
    "  --can-other-ids count|ignore  frames on ids not ours: counted as bad (default), or\n"
    "                                filtered out by the kernel (a bus shared with other traffic)\n"
    "  --syslog                      log to syslog instead of stderr\n"
    "  --syslog-socket PATH          the syslog datagram socket (/dev/log)\n"
    "  --log-level error|warning|notice|info|debug  (default info)\n"
    "  --version, --help\n"
    "numbers are decimal (a leading 0 is not octal); CAN ids also 0x...\n"
    "signals: SIGHUP reloads the table (kept if the new one is invalid); SIGTERM/SIGINT stop.\n";

/* The plausibility bounds' defaults: far beyond any stage's error, far below what a table with
 * an absurd scale commands. */
static void sc_config_bounds_defaults(sc_config *c)
{
    c->max_correction_um = 1000.0;
    c->max_gradient_um_per_mm = 100.0;
}

void sc_config_defaults(sc_config *c)
{
    memset(c, 0, sizeof *c);
    c->mode = SC_CORR_MEASURE;
    sc_mbtcp_config_defaults(&c->tcp);
    sc_mbrtu_config_defaults(&c->rtu);
#ifdef SELFCALD_HAVE_CAN
    sc_can_config_defaults(&c->can);
#else
    c->can.in_id = 0x100; /* SPEC §4 ids; the CAN transport is not in this build */
    c->can.out_id = 0x101;
    c->can.status_id = 0x102;
    c->can.status_period_ms = 1000;
#endif
    c->word_order = SC_WORD_HIGH_FIRST;
    c->log_level = SC_LOG_INFO;
    sc_config_bounds_defaults(c);
}

/* A whole number in 0..max: decimal (a leading 0 is not octal: "01502" is 1502), or with
 * hex = 1 also 0x... (the CAN ids). */
static sc_status parse_ulong(const char *s, unsigned long max, int hex, unsigned long *out)
{
    if (s == NULL || *s == '\0' || *s == '-' || *s == '+' || isspace((unsigned char)*s))
        return SC_E_INPUT;
    int is_hex = s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
    if (is_hex && (!hex || !isxdigit((unsigned char)s[2])))
        return SC_E_INPUT;
    char *end = NULL;
    errno = 0;
    unsigned long v = strtoul(is_hex ? s + 2 : s, &end, is_hex ? 16 : 10);
    if (errno != 0 || end == s || *end != '\0' || v > max)
        return SC_E_INPUT;
    *out = v;
    return SC_OK;
}

static sc_status copy_str(char *dst, size_t cap, const char *src)
{
    size_t n = strlen(src);
    if (n == 0 || n >= cap)
        return SC_E_INPUT;
    memcpy(dst, src, n + 1);
    return SC_OK;
}

/* Bad input: the message into err, SC_E_INPUT out. */
#define BAD(...) return sc_error_set(err, SC_E_INPUT, NULL, 0, __VA_ARGS__)

static sc_status parse_host_port(sc_config *c, const char *v, sc_error *err)
{
    const char *colon = strrchr(v, ':');
    unsigned long port;
    if (colon == NULL || parse_ulong(colon + 1, 65535, 0, &port) != 0)
        BAD("--modbus-tcp: expected HOST:PORT, got '%s'", v);
    size_t hl = (size_t)(colon - v);
    if (hl >= 2 && v[0] == '[' && v[hl - 1] == ']') { /* [IPv6]:PORT */
        v++;
        hl -= 2;
    } else if (memchr(v, ':', hl) != NULL) {
        BAD("--modbus-tcp: write an IPv6 address in brackets, [::1]:PORT; got '%s'", v);
    }
    if (hl == 0) {
        strcpy(c->tcp.host, "127.0.0.1");
    } else {
        if (hl >= sizeof c->tcp.host)
            BAD("--modbus-tcp: host too long");
        memcpy(c->tcp.host, v, hl);
        c->tcp.host[hl] = '\0';
    }
    struct sockaddr_storage a;
    socklen_t alen;
    sc_status st = sc_mbtcp_resolve(c->tcp.host, (uint16_t)port, &a, &alen, err);
    if (st != SC_OK)
        return st;
    c->tcp.port = (uint16_t)port;
    c->use_modbus_tcp = 1;
    return SC_OK;
}

static sc_status parse_rtu(sc_config *c, const char *v, sc_error *err)
{
    /* DEV[:BAUD[:PARITY[:DATABITS[:STOPBITS]]]]; the device ends at the first ':' after its
     * last '/'. */
    char tmp[256];
    if (copy_str(tmp, sizeof tmp, v) != 0)
        BAD("--modbus-rtu: bad device '%s'", v);
    char *slash = strrchr(tmp, '/');
    char *rest = strchr(slash ? slash : tmp, ':');
    if (rest != NULL)
        *rest++ = '\0';
    if (copy_str(c->rtu.device, sizeof c->rtu.device, tmp) != 0)
        BAD("--modbus-rtu: bad device '%s'", v);
    int field = 0;
    while (rest != NULL && *rest != '\0') {
        char *next = strchr(rest, ':');
        if (next != NULL)
            *next++ = '\0';
        unsigned long n;
        switch (field) {
        case 0:
            if (parse_ulong(rest, 4000000, 0, &n) != 0 || n < 50)
                BAD("--modbus-rtu: bad baud rate '%s'", rest);
            c->rtu.baud = (int)n;
            break;
        case 1:
            if (strlen(rest) != 1 || strchr("NEOneo", rest[0]) == NULL)
                BAD("--modbus-rtu: parity must be N, E or O, got '%s'", rest);
            c->rtu.parity = (char)toupper((unsigned char)rest[0]);
            break;
        case 2:
            if (parse_ulong(rest, 8, 0, &n) != 0 || n < 5)
                BAD("--modbus-rtu: data bits must be 5..8, got '%s'", rest);
            c->rtu.data_bits = (int)n;
            break;
        case 3:
            if (parse_ulong(rest, 2, 0, &n) != 0 || n < 1)
                BAD("--modbus-rtu: stop bits must be 1 or 2, got '%s'", rest);
            c->rtu.stop_bits = (int)n;
            break;
        default:
            BAD("--modbus-rtu: too many fields in '%s'", v);
        }
        field++;
        rest = next;
    }
    c->use_modbus_rtu = 1;
    return SC_OK;
}

static int is_yes(const char *v)
{
    return v == NULL || strcmp(v, "yes") == 0 || strcmp(v, "true") == 0 || strcmp(v, "1") == 0 ||
           strcmp(v, "on") == 0;
}

static int is_no(const char *v)
{
    return v != NULL && (strcmp(v, "no") == 0 || strcmp(v, "false") == 0 ||
                         strcmp(v, "0") == 0 || strcmp(v, "off") == 0);
}

/* Options that take no value (flags). */
static int is_flag(const char *key)
{
    return strcmp(key, "syslog") == 0;
}

/* The numeric options: the range each accepts and the field it sets. */
typedef enum { FIELD_U32, FIELD_INT } field_kind;

typedef struct {
    const char *key;
    unsigned long min, max;
    size_t offset; /* of the field in sc_config */
    field_kind kind;
    const char *expect; /* the range as the message words it; NULL: "min..max" */
    const char *note;   /* after the range in the message, or "" */
    int hex;            /* 0x... accepted too (the CAN ids) */
} numeric_option;

#define NUMERIC(key, lo, hi, field, kind, expect, note)                                        \
    { key, lo, hi, offsetof(sc_config, field), kind, expect, note, 0 }
#define CAN_ID(key, field)                                                                     \
    { key, 0, 0x7ff, offsetof(sc_config, field), FIELD_U32, "an 11-bit id (0..0x7ff)", "", 1 }

static const numeric_option numeric_options[] = {
    NUMERIC("max-connections", 1, SC_MBTCP_MAX_CONN, tcp.max_connections, FIELD_INT, NULL, ""),
    NUMERIC("max-per-peer", 0, SC_MBTCP_MAX_CONN, tcp.max_per_peer, FIELD_INT, NULL,
            " (0 = no limit)"),
    NUMERIC("byte-timeout-ms", 1, 600000, tcp.byte_timeout_ms, FIELD_U32, NULL, ""),
    NUMERIC("idle-timeout-ms", 0, 86400000, tcp.idle_timeout_ms, FIELD_U32, NULL, ""),
    NUMERIC("busy-poll-us", 0, 1000000, busy_poll_us, FIELD_U32, NULL, ""),
    NUMERIC("rtu-byte-timeout-ms", 0, 60000, rtu.byte_timeout_ms, FIELD_U32, NULL,
            " (0 = t3.5 from the baud rate)"),
    CAN_ID("can-in-id", can.in_id),
    CAN_ID("can-out-id", can.out_id),
    CAN_ID("can-status-id", can.status_id),
    NUMERIC("can-status-period-ms", 10, 3600000, can.status_period_ms, FIELD_U32, NULL, ""),
};

static sc_status set_numeric(sc_config *c, const numeric_option *o, const char *value,
                             sc_error *err)
{
    unsigned long n;
    if (parse_ulong(value, o->max, o->hex, &n) != SC_OK || n < o->min) {
        if (o->expect != NULL)
            BAD("--%s: expected %s, got '%s'", o->key, o->expect, value);
        BAD("--%s: expected %lu..%lu%s, got '%s'", o->key, o->min, o->max, o->note, value);
    }
    char *field = (char *)c + o->offset;
    if (o->kind == FIELD_INT)
        *(int *)(void *)field = (int)n;
    else
        *(uint32_t *)(void *)field = (uint32_t)n;
    return SC_OK;
}

static sc_status set_table(sc_config *c, const char *value, sc_error *err)
{
    if (copy_str(c->table, sizeof c->table, value) != SC_OK)
        BAD("--table: bad path");
    return SC_OK;
}

static sc_status set_modbus_tcp(sc_config *c, const char *value, sc_error *err)
{
    return parse_host_port(c, value, err);
}

static sc_status set_modbus_rtu(sc_config *c, const char *value, sc_error *err)
{
    return parse_rtu(c, value, err);
}

static sc_status set_can(sc_config *c, const char *value, sc_error *err)
{
    if (copy_str(c->can.ifname, sizeof c->can.ifname, value) != SC_OK)
        BAD("--can: bad interface name '%s'", value);
    c->use_can = 1;
    return SC_OK;
}

static sc_status set_can_other_ids(sc_config *c, const char *value, sc_error *err)
{
    if (strcmp(value, "count") == 0)
        c->can.ignore_other_ids = 0;
    else if (strcmp(value, "ignore") == 0)
        c->can.ignore_other_ids = 1;
    else
        BAD("--can-other-ids: expected count or ignore, got '%s'", value);
    return SC_OK;
}

static sc_status set_mode(sc_config *c, const char *value, sc_error *err)
{
    if (strcmp(value, "measure") == 0)
        c->mode = SC_CORR_MEASURE;
    else if (strcmp(value, "position") == 0)
        c->mode = SC_CORR_POSITION;
    else if (strcmp(value, "measure-exact") == 0)
        c->mode = SC_CORR_MEASURE_EXACT;
    else
        BAD("--mode: expected measure, position or measure-exact, got '%s'", value);
    return SC_OK;
}

static sc_status set_unit_id(sc_config *c, const char *value, sc_error *err)
{
    unsigned long n;
    if (parse_ulong(value, 255, 0, &n) != SC_OK)
        BAD("--unit-id: expected 0..255, got '%s'", value);
    c->tcp.unit_id = (uint8_t)n; /* one unit id for both Modbus transports */
    c->rtu.unit_id = (uint8_t)n;
    return SC_OK;
}

static sc_status set_word_order(sc_config *c, const char *value, sc_error *err)
{
    if (strcmp(value, "high-first") == 0 || strcmp(value, "big") == 0)
        c->word_order = SC_WORD_HIGH_FIRST;
    else if (strcmp(value, "low-first") == 0 || strcmp(value, "little") == 0)
        c->word_order = SC_WORD_LOW_FIRST;
    else
        BAD("--word-order: expected high-first or low-first, got '%s'", value);
    return SC_OK;
}

static sc_status set_syslog(sc_config *c, const char *value, sc_error *err)
{
    if (is_yes(value))
        c->use_syslog = 1;
    else if (is_no(value))
        c->use_syslog = 0;
    else
        BAD("syslog: expected yes or no, got '%s'", value);
    return SC_OK;
}

static sc_status set_syslog_socket(sc_config *c, const char *value, sc_error *err)
{
    if (copy_str(c->syslog_socket, sizeof c->syslog_socket, value) != SC_OK)
        BAD("--syslog-socket: bad path '%s'", value);
    return SC_OK;
}

static sc_status set_log_level(sc_config *c, const char *value, sc_error *err)
{
    static const char *const levels[] = {"error", "warning", "notice", "info", "debug"};
    for (int i = 0; i < 5; i++) {
        if (strcmp(value, levels[i]) == 0) {
            c->log_level = SC_LOG_ERR + i;
            return SC_OK;
        }
    }
    BAD("--log-level: expected error, warning, notice, info or debug, got '%s'", value);
}

/* A bound in 0..1e6 (0 = none): --max-correction-um, --max-gradient-um-per-mm. */
static sc_status set_bound(double *field, const char *key, const char *value, sc_error *err)
{
    double v;
    if (sc_parse_double(value, &v) != SC_OK || !(v >= 0.0 && v <= 1e6))
        BAD("--%s: expected a number in 0..1e6 (0 = no bound), got '%s'", key, value);
    *field = v;
    return SC_OK;
}

static sc_status set_max_correction(sc_config *c, const char *value, sc_error *err)
{
    return set_bound(&c->max_correction_um, "max-correction-um", value, err);
}

static sc_status set_max_gradient(sc_config *c, const char *value, sc_error *err)
{
    return set_bound(&c->max_gradient_um_per_mm, "max-gradient-um-per-mm", value, err);
}

static sc_status set_allow(sc_config *c, const char *value, sc_error *err)
{
    return sc_mbtcp_parse_allow(&c->tcp, value, err);
}

/* The other options, each with its own setter. */
typedef sc_status (*option_setter)(sc_config *c, const char *value, sc_error *err);

static const struct {
    const char *key;
    option_setter set;
} other_options[] = {
    {"table", set_table},
    {"modbus-tcp", set_modbus_tcp},
    {"modbus-rtu", set_modbus_rtu},
    {"can", set_can},
    {"can-other-ids", set_can_other_ids},
    {"mode", set_mode},
    {"unit-id", set_unit_id},
    {"word-order", set_word_order},
    {"syslog", set_syslog},
    {"syslog-socket", set_syslog_socket},
    {"log-level", set_log_level},
    {"allow", set_allow},
    {"max-correction-um", set_max_correction},
    {"max-gradient-um-per-mm", set_max_gradient},
};

sc_status sc_config_set(sc_config *c, const char *key, const char *value, sc_error *err)
{
    /* an unknown option is said as such, even as the last word (not "needs a value") */
    for (size_t i = 0; i < sizeof numeric_options / sizeof numeric_options[0]; i++)
        if (strcmp(key, numeric_options[i].key) == 0) {
            if (value == NULL)
                BAD("--%s needs a value", key);
            return set_numeric(c, &numeric_options[i], value, err);
        }
    for (size_t i = 0; i < sizeof other_options / sizeof other_options[0]; i++)
        if (strcmp(key, other_options[i].key) == 0) {
            if (!is_flag(key) && value == NULL)
                BAD("--%s needs a value", key);
            return other_options[i].set(c, value, err);
        }
    BAD("unknown option '%s'", key);
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s))
        s++;
    size_t n = strlen(s);
    while (n > 0 && isspace((unsigned char)s[n - 1]))
        s[--n] = '\0';
    return s;
}

/* A configuration is a few dozen lines; more than this is not one (and an endless input must
 * end somewhere, before the line counter would overflow). */
#define SC_CONFIG_MAX_LINES 100000

sc_status sc_config_load_file(sc_config *c, const char *path, sc_error *err)
{
    FILE *f = fopen(path, "r");
    if (f == NULL)
        return sc_error_set(err, sc_open_failure_status(errno), path, 0, "cannot open: %s",
                            strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || S_ISDIR(st.st_mode)) { /* fgets would read it as empty */
        fclose(f);
        return sc_error_set(err, SC_E_INPUT, path, 0, "is a directory, not a configuration file");
    }
    char line[1024];
    int lineno = 0;
    while (fgets(line, sizeof line, f) != NULL) {
        if (++lineno > SC_CONFIG_MAX_LINES) { /* an endless input (a pipe of blank lines) */
            fclose(f);
            return sc_error_set(err, SC_E_INPUT, path, lineno,
                                "more than %d lines: not a selfcald configuration",
                                SC_CONFIG_MAX_LINES);
        }
        if (strchr(line, '\n') == NULL && !feof(f)) {
            int nul = strlen(line) < sizeof line - 1; /* fgets stopped at the line end after it */
            fclose(f);
            return sc_error_set(err, SC_E_INPUT, path, lineno,
                                nul ? "NUL byte in a text file" : "line too long");
        }
        if (lineno == 1 && !strncmp(line, "\xEF\xBB\xBF", 3)) /* a UTF-8 byte-order mark */
            memmove(line, line + 3, strlen(line + 3) + 1);
        char *hash = strchr(line, '#');
        if (hash != NULL)
            *hash = '\0';
        char *s = trim(line);
        if (*s == '\0')
            continue;
        char *eq = strchr(s, '=');
        char *key = s, *value = NULL;
        if (eq != NULL) {
            *eq = '\0';
            value = trim(eq + 1);
            key = trim(s);
        }
        sc_error inner;
        sc_status st = sc_config_set(c, key, value, &inner);
        if (st != SC_OK) {
            fclose(f);
            return sc_error_set(err, st, path, lineno, "%s", inner.msg);
        }
    }
    fclose(f);
    return SC_OK;
}

sc_status sc_config_parse_args(sc_config *c, int argc, char **argv, int *help, int *version,
                               sc_error *err)
{
    *help = 0;
    *version = 0;
    /* The configuration file first, so the other flags override it. */
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--config") == 0) {
            if (i + 1 >= argc)
                BAD("--config needs a file");
            sc_status st = sc_config_load_file(c, argv[i + 1], err);
            if (st != SC_OK)
                return st;
            i++;
        } else if (strncmp(a, "--config=", 9) == 0) {
            sc_status st = sc_config_load_file(c, a + 9, err);
            if (st != SC_OK)
                return st;
        }
    }
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            *help = 1;
            return SC_OK;
        }
        if (strcmp(a, "--version") == 0) {
            *version = 1;
            return SC_OK;
        }
        if (strncmp(a, "--", 2) != 0)
            BAD("unexpected argument '%s'", a);
        char key[64];
        const char *value = NULL;
        const char *eq = strchr(a + 2, '=');
        size_t kl = eq ? (size_t)(eq - (a + 2)) : strlen(a + 2);
        if (kl == 0 || kl >= sizeof key)
            BAD("bad option '%s'", a);
        memcpy(key, a + 2, kl);
        key[kl] = '\0';
        if (eq != NULL) {
            value = eq + 1;
        } else if (!is_flag(key) && i + 1 < argc) {
            value = argv[++i]; /* as the last word: sc_config_set says unknown or needs a value */
        }
        if (strcmp(key, "config") == 0)
            continue; /* already read */
        sc_status st = sc_config_set(c, key, value, err);
        if (st != SC_OK)
            return st;
    }
    if (c->table[0] == '\0')
        BAD("--table TABLE is required");
    if (!c->use_modbus_tcp && !c->use_modbus_rtu && !c->use_can)
        c->use_modbus_tcp = 1; /* SPEC §4 default: Modbus TCP on 127.0.0.1:1502 */
    return SC_OK;
}
