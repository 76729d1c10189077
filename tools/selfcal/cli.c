/* cli.c — the helpers every subcommand shares (cli.h): error reports, usage errors, the common
 * option values (profiles, noise, seed, node counts, the least-squares options), maps. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "input_once.h"
#include "selfcal/csv.h"
#include "selfcal/grid_calibrate.h"
#include "selfcal/lut.h"

int cli_report(const sc_error *err_in)
{
    char buf[1024];
    sc_error e = *err_in, *err = &e;
    cli_input_rename_in_error(err); /* an input read from its in-memory copy: the name given */
    sc_error_format(err, buf, sizeof buf);
    fprintf(stderr, "selfcal: %s\n", buf);
    return (err->code == SC_E_INPUT || err->code == SC_E_UNSOLVABLE) ? CLI_BAD_INPUT : CLI_FAIL;
}

int cli_parse_profile_arg(const char *s, int *axis, int *dir, const char **path)
{
    if (strlen(s) < 5 || s[1] != ':' || s[3] != ':')
        return -1;
    char a[2] = {s[0], 0}, d[2] = {s[2], 0};
    *axis = sc_lut_axis_from_name(a);
    *dir = sc_lut_axis_from_name(d);
    *path = s + 4;
    return (*axis < 0 || *dir < 0) ? -1 : 0;
}

int cli_parse_profile_placed(const char *s, int *axis, int *dir, char *path, size_t cap,
                             double *offset_mm)
{
    const char *p;
    if (cli_parse_profile_arg(s, axis, dir, &p) != 0 || strlen(p) >= cap)
        return -1;
    snprintf(path, cap, "%s", p);
    *offset_mm = 0;
    char *at = strrchr(path, '@');
    double off;
    if (at && at != path && sc_parse_double(at + 1, &off) == 0) {
        if (!(off >= -SC_INPUT_MAX_ABS && off <= SC_INPUT_MAX_ABS))
            return -1;
        *offset_mm = off;
        *at = '\0';
    } else if (at && at != path && access(path, F_OK) != 0) {
        /* "P.csv@abc" naming no file while P.csv is one: a mistyped offset, not a file name */
        *at = '\0';
        int prefix_exists = access(path, F_OK) == 0;
        *at = '@';
        if (prefix_exists)
            return -1;
    }
    return 0;
}

int cli_parse_noise(const char *cmd, const char *opt, const char *v, int positive, double *out)
{
    double x;
    const char *unit = strstr(opt, "urad") ? "urad" : "um";
    if (sc_parse_double(v, &x) != 0 || !(positive ? x > 0 : x >= 0) || !(x <= SC_INPUT_MAX_ABS))
        return cli_usage_error(cmd, "%s: '%s' is not a noise: a number %s 0 to %g %s", opt, v,
                               positive ? "above" : "from", SC_INPUT_MAX_ABS, unit);
    *out = x;
    return CLI_OK;
}

int cli_parse_max_nodes(const char *cmd, const char *v, int *out)
{
    long n;
    if (sc_parse_long(v, &n) != 0 || n < 2 || n > SC_LUT_MAX_NX)
        return cli_usage_error(cmd, "--max-nodes: 2..%d nodes per axis, not '%s'", SC_LUT_MAX_NX, v);
    *out = (int)n;
    return CLI_OK;
}

int cli_parse_max_memory(const char *cmd, const char *v, double *out)
{
    char num[64];
    size_t len = strlen(v);
    double unit = 1;
    if (len > 0 && len < sizeof num) {
        const char *units = "KMGT";
        const char *u = strchr(units, v[len - 1] & ~0x20); /* K, M, G, T or k, m, g, t */
        memcpy(num, v, len + 1);
        if (u && v[len - 1] != '\0') {
            unit = pow(1024.0, (double)(u - units + 1));
            num[len - 1] = '\0';
        }
    }
    double x;
    if (len == 0 || len >= sizeof num || sc_parse_double(num, &x) || !(x > 0) ||
        !(x * unit <= 1e18))
        return cli_usage_error(cmd, "--max-memory needs a size such as 12G, 800M or bytes "
                                    "(K, M, G, T: powers of 1024), got '%s'", v);
    *out = x * unit;
    return CLI_OK;
}

int cli_parse_seed(const char *cmd, const char *v, uint64_t *out)
{
    /* digits only: strtoull would take a sign (and wrap a negative) and saturate silently */
    int digits = *v != '\0';
    for (const char *c = v; *c; ++c)
        digits &= *c >= '0' && *c <= '9';
    errno = 0;
    char *e;
    unsigned long long s = digits ? strtoull(v, &e, 10) : 0;
    if (!digits || errno == ERANGE)
        return cli_usage_error(cmd, "--seed needs a whole number from 0 to %llu, got '%s'",
                               (unsigned long long)UINT64_MAX, v);
    *out = (uint64_t)s;
    return CLI_OK;
}

int cli_parse_lsq_option(const char *cmd, const char *opt, const char *v, sc_grid_options *o)
{
    if (!strcmp(opt, "--view-noise")) {
        if (strcmp(v, "estimate") != 0 && strcmp(v, "stated") != 0)
            return cli_usage_error(cmd, "--view-noise must be stated or estimate, got '%s'", v);
        o->estimate_view_noise = !strcmp(v, "estimate");
        return CLI_OK;
    }
    if (!strcmp(opt, "--view-scale")) {
        if (strcmp(v, "free") != 0 && strcmp(v, "model") != 0)
            return cli_usage_error(cmd, "--view-scale must be model or free, got '%s'", v);
        o->view_scale_free = !strcmp(v, "free");
        return CLI_OK;
    }
    int each = !strcmp(opt, "--outlier-alpha-each");
    if (!each && strcmp(opt, "--outlier-alpha") != 0)
        return -1;
    double a;
    if (sc_parse_double(v, &a) || !(a > 0 && a < 1))
        return cli_usage_error(cmd, "%s needs a significance between 0 and 1, got '%s'", opt, v);
    if (o->outlier_alpha > 0 && o->outlier_alpha_each != each)
        return cli_usage_error(cmd, "--outlier-alpha and --outlier-alpha-each exclude each other");
    o->outlier_alpha = a;
    o->outlier_alpha_each = each;
    return CLI_OK;
}

sc_status cli_read_map(const char *path, int max_nodes, sc_lut *lut, sc_lut_fit_report *fit,
                       sc_error *err)
{
    memset(fit, 0, sizeof *fit);
    return max_nodes ? sc_lut_read_map_fitted(path, lut, max_nodes, fit, err)
                     : sc_lut_read_map(path, lut, err);
}

void cli_print_fit(const char *map_path, const sc_lut *lut, const sc_lut_fit_report *fit)
{
    printf("map %s: %d x %d nodes fitted by a %d x %d table (least squares, pitch %.6f x %.6f mm): "
           "table - map at the map's nodes rms %.4f um, max %.4f um at (%.6g, %.6g) mm\n",
           map_path, fit->map_nx, fit->map_ny, lut->nx, lut->ny, lut->px_mm, lut->py_mm,
           fit->rms_um, fit->max_um, fit->max_at_mm[0], fit->max_at_mm[1]);
}

int cli_usage_error(const char *cmd, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "selfcal %s: ", cmd);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    return CLI_BAD_INPUT;
}

const char *cli_basename(const char *path)
{
    const char *b = strrchr(path, '/');
    return b && b[1] ? b + 1 : path;
}
