/* Simulated straightness measurements (SPEC §2 model) and the profiles they measure. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/csv.h"
#include "../common/csv_internal.h"
#include "selfcal/profile_sim.h"

void sc_profile_sim_defaults(sc_profile_sim *p)
{
    memset(p, 0, sizeof *p);
    p->n = 330;
    p->s_mm = 1.0;
    p->d1 = 10;
    p->d2 = 11;
    p->sigma_disp_um = 0.01;
    p->sigma_angle_urad = 1.0;
    p->ey_amp_um = 0.5;
    p->ep_amp_urad = 2.0;
    p->u1_um = 1.5;
    p->u2_um = -0.7;
    p->u3_urad = 3.0;
    p->b0_um = 20.0;
    p->write_sigma = 1;
    p->seed = 1;
}

void sc_profile_random_smooth(int n, double amp_um, int harmonics, sc_rng *rng, double *f_um)
{
    for (int i = 0; i < n; ++i)
        f_um[i] = 0;
    if (harmonics < 1)
        harmonics = 1;
    for (int j = 1; j <= harmonics; ++j) {
        double a = sc_rng_normal(rng) / pow(j, 1.5), ph = 2.0 * M_PI * sc_rng_uniform(rng);
        /* half-integer frequencies too, so that the profile is not periodic on the scan */
        double fr = 0.5 * j;
        for (int i = 0; i < n; ++i)
            f_um[i] += a * sin(2.0 * M_PI * fr * i / (n > 1 ? n - 1 : 1) + ph);
    }
    sc_profile_remove_line(n, f_um);
    double ss = 0;
    for (int i = 0; i < n; ++i)
        ss += f_um[i] * f_um[i];
    double rms = sqrt(ss / n);
    if (rms > 0)
        for (int i = 0; i < n; ++i)
            f_um[i] *= amp_um / rms;
}

void sc_profile_sim_random_truth(const sc_profile_sim *p, double amp_um, int harmonics,
                                 double *f_um)
{
    sc_rng rng;
    sc_rng_seed(&rng, p->seed ^ 0x5eed5eedULL);
    sc_profile_random_smooth(p->n, amp_um, harmonics, &rng, f_um);
}

/* ---- DABAM ---------------------------------------------------------------------------------- */

/* The value text of "key" in a flat JSON object (NULL if absent); copies at most len-1 chars. */
static int json_value(const char *json, const char *key, char *out, size_t len)
{
    char pat[96];
    snprintf(pat, sizeof pat, "\"%s\"", key);
    const char *p = strstr(json, pat);
    if (!p)
        return 0;
    p += strlen(pat);
    while (isspace((unsigned char)*p))
        ++p;
    if (*p != ':')
        return 0;
    ++p;
    while (isspace((unsigned char)*p))
        ++p;
    size_t k = 0;
    if (*p == '"') {
        ++p;
        while (*p && *p != '"' && k + 1 < len)
            out[k++] = *p++;
    } else {
        while (*p && *p != ',' && *p != '}' && !isspace((unsigned char)*p) && k + 1 < len)
            out[k++] = *p++;
    }
    out[k] = '\0';
    return 1;
}

static char *read_all(const char *path, sc_error *err)
{
    FILE *f = sc_open_input(path, err);
    if (!f)
        return NULL;
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    size_t got;
    while (buf && (got = fread(buf + len, 1, cap - len - 1, f)) > 0) {
        len += got;
        if (len + 1 == cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                buf = NULL;
                break;
            }
            buf = nb;
            cap *= 2;
        }
    }
    fclose(f);
    if (!buf) {
        sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
        return NULL;
    }
    buf[len] = '\0';
    return buf;
}

/* What the DABAM metadata (.txt, JSON) says about the .dat file. */
typedef struct {
    long header_lines;
    double x_factor; /* metres per abscissa unit */
    double y_factor; /* radians (slopes) or metres (heights) per ordinate unit */
    int is_slope;
} dabam_meta;

/* Slopes or heights: PLOT_TITLE_Y1 says, else FILE_FORMAT (1 = slopes, 2 = heights). */
static int dabam_is_slope(const char *meta)
{
    char title[128] = "", v[128];
    if (json_value(meta, "PLOT_TITLE_Y1", title, sizeof title)) {
        char low[128];
        size_t k = 0;
        for (; title[k] && k + 1 < sizeof low; ++k)
            low[k] = (char)tolower((unsigned char)title[k]);
        low[k] = '\0';
        if (strstr(low, "slope"))
            return 1;
        if (strstr(low, "height") || strstr(low, "heigth"))
            return 0;
        return 1;
    }
    if (json_value(meta, "FILE_FORMAT", v, sizeof v))
        return strcmp(v, "2") != 0;
    return 1;
}

static sc_status dabam_read_meta(const char *meta_path, dabam_meta *m, sc_error *err)
{
    char *meta = read_all(meta_path, err);
    if (!meta)
        return err ? err->code : SC_E_INPUT;
    char v[128];
    sc_status st = SC_OK;
    m->x_factor = 1e-3;
    m->y_factor = 1.0;
    if (!json_value(meta, "FILE_HEADER_LINES", v, sizeof v) ||
        sscanf(v, "%ld", &m->header_lines) != 1 || m->header_lines < 0) {
        st = sc_error_set(err, SC_E_INPUT, meta_path, 0, "no valid FILE_HEADER_LINES");
    } else if (!json_value(meta, "X1_FACTOR", v, sizeof v) ||
               sc_parse_double(v, &m->x_factor) != 0 ||
               !json_value(meta, "Y1_FACTOR", v, sizeof v) ||
               sc_parse_double(v, &m->y_factor) != 0) {
        st = sc_error_set(err, SC_E_INPUT, meta_path, 0, "no valid X1_FACTOR / Y1_FACTOR");
    } else if (!(m->x_factor > 0 && m->x_factor <= 1) ||
               !(m->y_factor != 0 && fabs(m->y_factor) <= 1)) {
        /* DABAM uses 1e-3 and 1e-6; beyond 1 a mirror would be longer than a kilometre or its
         * slopes beyond 1 rad, and the heights could overflow (a fuzzed X1_FACTOR = 1e306
         * made them NaN) */
        st = sc_error_set(err, SC_E_INPUT, meta_path, 0,
                          "X1_FACTOR must be in (0, 1] and Y1_FACTOR nonzero within [-1, 1]");
    } else {
        m->is_slope = dabam_is_slope(meta);
    }
    free(meta);
    return st;
}

/* The abscissae (m) and ordinates (rad or m) of the .dat file, in growing arrays. */
typedef struct {
    double *xs, *ys;
    size_t count, cap;
} dabam_points;

static void dabam_points_free(dabam_points *d)
{
    free(d->xs);
    free(d->ys);
}

static sc_status dabam_points_push(dabam_points *d, double x, double y)
{
    if (d->count == d->cap) {
        size_t cap = d->cap ? 2 * d->cap : 1024;
        double *nx = realloc(d->xs, cap * sizeof(double));
        if (nx)
            d->xs = nx;
        double *ny = realloc(d->ys, cap * sizeof(double));
        if (ny)
            d->ys = ny;
        if (!nx || !ny)
            return SC_E_NOMEM;
        d->cap = cap;
    }
    d->xs[d->count] = x;
    d->ys[d->count] = y;
    d->count++;
    return SC_OK;
}

/* One data line (past the header): blank and '#' lines are skipped, else two numbers. */
static sc_status dabam_data_line(const char *path, long ln, const char *line, const dabam_meta *m,
                                 dabam_points *d, sc_error *err)
{
    const char *p = line;
    while (isspace((unsigned char)*p))
        ++p;
    if (!*p || *p == '#')
        return SC_OK;
    char *e1, *e2;
    double a = strtod(p, &e1);
    double b = strtod(e1, &e2);
    if (e1 == p || e2 == e1 || !isfinite(a) || !isfinite(b))
        return sc_error_set(err, SC_E_INPUT, path, ln, "expected two numbers (abscissa, ordinate)");
    if (!(fabs(a * m->x_factor) <= 1e3 && fabs(b * m->y_factor) <= 1))
        return sc_error_set(err, SC_E_INPUT, path, ln,
                            "beyond any mirror (|x| > 1 km, or a slope or height beyond 1 rad "
                            "or 1 m)");
    if (dabam_points_push(d, a * m->x_factor, b * m->y_factor) != SC_OK)
        return sc_error_set(err, SC_E_NOMEM, path, ln, "out of memory");
    if (d->count > 1 && !(d->xs[d->count - 1] > d->xs[d->count - 2]))
        return sc_error_set(err, SC_E_INPUT, path, ln, "abscissa not increasing");
    return SC_OK;
}

#define SC_DABAM_MAX_HEADER_LINES 1000000L /* FILE_HEADER_LINES beyond this: not DABAM */

static sc_status dabam_read_points(const char *path, const dabam_meta *m, dabam_points *d,
                                   sc_error *err)
{
    FILE *fp = sc_open_input(path, err);
    if (!fp)
        return err ? err->code : SC_E_INPUT;
    char line[4096];
    long ln = 0, skipped = 0; /* comment or blank lines in a row */
    sc_status st = SC_OK;
    while (st == SC_OK && fgets(line, sizeof line, fp)) {
        ++ln;
        skipped = sc_csv_text_skippable(line) ? skipped + 1 : 0;
        if (!strchr(line, '\n') && !feof(fp))
            st = sc_error_set(err, SC_E_INPUT, path, ln, "line longer than %zu bytes",
                              sizeof line - 2);
        else if (skipped > SC_CSV_MAX_SKIP_RUN) /* an endless input, as the CSV reader says */
            st = sc_error_set(err, SC_E_INPUT, path, ln, SC_CSV_SKIP_RUN_MSG, SC_CSV_MAX_SKIP_RUN);
        else if (ln > m->header_lines)
            st = dabam_data_line(path, ln, line, m, d, err);
        else if (ln > SC_DABAM_MAX_HEADER_LINES)
            st = sc_error_set(err, SC_E_INPUT, path, ln, "more header lines than any DABAM file");
    }
    fclose(fp);
    if (st == SC_OK && d->count < 4)
        st = sc_error_set(err, SC_E_INPUT, path, ln, "fewer than 4 points");
    return st;
}

/* Heights in µm at the abscissae: the slopes integrated by the trapezoidal rule, or scaled. */
static void dabam_heights_um(const dabam_points *d, int is_slope, double *hs)
{
    if (is_slope) {
        hs[0] = 0;
        for (size_t i = 1; i < d->count; ++i)
            hs[i] = hs[i - 1] + 0.5 * (d->ys[i] + d->ys[i - 1]) * (d->xs[i] - d->xs[i - 1]) * 1e6;
    } else {
        for (size_t i = 0; i < d->count; ++i)
            hs[i] = d->ys[i] * 1e6;
    }
}

/* n points at pitch s_mm, centred on the mirror (true scale), or the mirror stretched onto the
 * scan when it is shorter; linear interpolation of hs. Returns whether at true scale. */
static int dabam_resample(const dabam_points *d, const double *hs, int n, double s_mm,
                          double *f_um)
{
    const double *xs = d->xs;
    size_t cnt = d->count;
    double len_m = xs[cnt - 1] - xs[0], span_m = (n - 1) * s_mm * 1e-3;
    int true_scale = span_m <= len_m;
    double x0 = true_scale ? xs[0] + 0.5 * (len_m - span_m) : xs[0];
    double dx = true_scale ? s_mm * 1e-3 : len_m / (n - 1);
    size_t j = 0;
    for (int i = 0; i < n; ++i) {
        double x = x0 + i * dx;
        if (x > xs[cnt - 1])
            x = xs[cnt - 1];
        while (j + 2 < cnt && xs[j + 1] < x)
            ++j;
        double t = (x - xs[j]) / (xs[j + 1] - xs[j]);
        if (t < 0)
            t = 0;
        if (t > 1)
            t = 1;
        f_um[i] = hs[j] + t * (hs[j + 1] - hs[j]);
    }
    return true_scale;
}

sc_status sc_profile_load_dabam(const char *dat_path, int n, double s_mm, double *f_um,
                                char *info, size_t infolen, sc_error *err)
{
    char meta_path[4096];
    size_t L = strlen(dat_path);
    if (L < 4 || strcmp(dat_path + L - 4, ".dat") != 0 || L >= sizeof meta_path)
        return sc_error_set(err, SC_E_INPUT, dat_path, 0,
                            "a DABAM profile is a .dat file (with its .txt metadata)");
    /* the file the caller named first: a missing .dat is reported as such, not as its .txt */
    FILE *probe = fopen(dat_path, "rb");
    if (!probe) {
        int e = errno;
        return sc_error_set(err, sc_open_failure_status(e), dat_path, 0, "cannot open: %s",
                            strerror(e));
    }
    fclose(probe);
    memcpy(meta_path, dat_path, L - 4);
    strcpy(meta_path + L - 4, ".txt");
    dabam_meta m;
    sc_status st = dabam_read_meta(meta_path, &m, err);
    if (st != SC_OK)
        return st;
    dabam_points d = {0};
    st = dabam_read_points(dat_path, &m, &d, err);
    double *hs = st == SC_OK ? malloc(d.count * sizeof(double)) : NULL;
    if (st == SC_OK && !hs)
        st = sc_error_set(err, SC_E_NOMEM, dat_path, 0, "out of memory");
    if (st != SC_OK) {
        dabam_points_free(&d);
        return st;
    }
    dabam_heights_um(&d, m.is_slope, hs);
    int true_scale = dabam_resample(&d, hs, n, s_mm, f_um);
    sc_profile_remove_line(n, f_um);
    if (info)
        snprintf(info, infolen, "%s: %zu %s points over %.1f mm, %s", dat_path, d.count,
                 m.is_slope ? "slope" : "height", (d.xs[d.count - 1] - d.xs[0]) * 1e3,
                 true_scale ? "true scale, centred" : "stretched onto the scan length");
    dabam_points_free(&d);
    free(hs);
    return SC_OK;
}

sc_status sc_profile_simulate(const sc_profile_sim *p, const double *f_um, sc_profile_data *out,
                              double *ey_um, sc_error *err)
{
    sc_status st = sc_profile_data_init(out, p->n, p->s_mm, p->d1, p->d2, err);
    if (st != SC_OK)
        return st;
    if (!(p->sigma_disp_um >= 0) || !(p->sigma_angle_urad >= 0)) {
        sc_profile_data_free(out);
        return sc_error_set(err, SC_E_INPUT, NULL, 0, "noise levels must be non-negative");
    }
    const int n = p->n;
    double *ep = malloc((size_t)n * sizeof(double));
    if (!ep) {
        sc_profile_data_free(out);
        return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory");
    }
    sc_rng rng;
    sc_rng_seed(&rng, p->seed);
    /* the stage's motion errors: smooth, repeatable (the same in both scans) */
    sc_profile_random_smooth(n, 1.0, 8, &rng, ey_um);
    sc_profile_random_smooth(n, 1.0, 8, &rng, ep);
    double tc = 0.5 * (n - 1);
    for (int i = 0; i < n; ++i) {
        /* plus a tilt, which a real stage also has */
        ey_um[i] = p->ey_amp_um * (ey_um[i] + 0.8 * (i - tc) / (tc > 0 ? tc : 1));
        ep[i] = p->ep_amp_urad * ep[i];
    }
    for (int k = 0; k < 2; ++k) {
        const int d = out->d[k], m = n - d;
        const double D_mm = d * p->s_mm;
        for (int i = 0; i < m; ++i) {
            out->m1_um[k][i] = f_um[i] + ey_um[i] + p->u1_um + p->b0_um +
                               p->sigma_disp_um * sc_rng_normal(&rng);
            out->m2_um[k][i] = f_um[i + d] + ey_um[i] + D_mm * ep[i] * 1e-3 + p->u2_um + p->b0_um +
                               p->sigma_disp_um * sc_rng_normal(&rng);
            out->m3_urad[k][i] = ep[i] + p->u3_urad + p->sigma_angle_urad * sc_rng_normal(&rng);
        }
    }
    out->has_sigma_disp = out->has_sigma_angle = p->write_sigma ? 1 : 0;
    out->sigma_disp_um = p->sigma_disp_um;
    out->sigma_angle_urad = p->sigma_angle_urad;
    free(ep);
    return SC_OK;
}
