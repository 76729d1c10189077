/* Unit tests of the controller exporters (selfcal/export.h): each exported file is read back here
 * by an independent parser of the controller's format, interpolated the way the controller does
 * (bilinear plane table, sums of linear 1-D tables, linear joint table, ISG's cross compensation
 * list), and compared with the map (or the profile) within the format's units; the reported
 * residual and clipped count are recomputed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "selfcal/export.h"
#include "selfcal/lut.h"

#define TMP SELFCAL_TEST_TMP "/export_"

/* Smooth test maps (um). kind 0: with interaction terms; 1: separable a(x) + b(y). */
static double gx_true(int kind, double x, double y)
{
    double s = 0.8 * sin(0.3 * x) + 0.02 * y * y - 0.5 + 0.05 * x;
    return kind == 0 ? s + 0.004 * x * y : s;
}

static double gy_true(int kind, double x, double y)
{
    double s = -0.6 * cos(0.2 * y) + 0.01 * x * x * 0.5 - 0.03 * x;
    return kind == 0 ? s + 0.02 * sin(0.1 * x * y) : s;
}

static sc_lut *make_map(int nx, int ny, double x0, double y0, double px, double py, int kind)
{
    sc_lut *lut = malloc(sizeof *lut);
    assert_non_null(lut);
    sc_lut_init(lut);
    lut->nx = nx;
    lut->ny = ny;
    lut->x0_mm = x0;
    lut->y0_mm = y0;
    lut->px_mm = px;
    lut->py_mm = py;
    for (int i = 0; i < ny; ++i)
        for (int j = 0; j < nx; ++j) {
            double x = x0 + j * px, y = y0 + i * py;
            lut->gx_um[i * nx + j] = gx_true(kind, x, y);
            lut->gy_um[i * nx + j] = gy_true(kind, x, y);
        }
    return lut;
}

/* Independent bilinear evaluation of the map (cell by search). */
static double map_ref(const sc_lut *m, int comp, double x, double y)
{
    const double *g = comp == 0 ? m->gx_um : m->gy_um;
    x = fmin(fmax(x, m->x0_mm), m->x0_mm + (m->nx - 1) * m->px_mm);
    y = fmin(fmax(y, m->y0_mm), m->y0_mm + (m->ny - 1) * m->py_mm);
    int j = 0, i = 0;
    while (j < m->nx - 2 && m->x0_mm + (j + 1) * m->px_mm <= x)
        ++j;
    while (i < m->ny - 2 && m->y0_mm + (i + 1) * m->py_mm <= y)
        ++i;
    double tx = (x - (m->x0_mm + j * m->px_mm)) / m->px_mm;
    double ty = (y - (m->y0_mm + i * m->py_mm)) / m->py_mm;
    int k = i * m->nx + j;
    return (1 - tx) * (1 - ty) * g[k] + tx * (1 - ty) * g[k + 1] + (1 - tx) * ty * g[k + m->nx] +
           tx * ty * g[k + m->nx + 1];
}

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    static char buf[4 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    return buf;
}

/* ---- Beckhoff: parse the kw.crosscomp2 list ---- */

typedef struct bk {
    long interval, start1, start2, last1, last2, unit, m1, m2, achs;
    char name[64];
    long *tab; /* [j][i] */
    int seen_end;
} bk;

static void parse_beckhoff(const char *path, bk *b)
{
    memset(b, 0, sizeof *b);
    b->last1 = b->last2 = -1;
    b->tab = calloc(101 * 101, sizeof *b->tab);
    char *seen = calloc(101 * 101, 1);
    assert_non_null(b->tab);
    char *text = slurp(path), *save = NULL;
    for (char *line = strtok_r(text, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
        if (line[0] == '#')
            continue;
        char key[128];
        long v;
        int i, j;
        if (!strcmp(line, "End")) {
            b->seen_end = 1;
            continue;
        }
        if (sscanf(line, "kw.crosscomp2.table[%d][%d].correction %ld", &j, &i, &v) == 3) {
            assert_true(j >= 0 && j <= 100 && i >= 0 && i <= 100);
            assert_false(seen[j * 101 + i]);
            seen[j * 101 + i] = 1;
            b->tab[j * 101 + i] = v;
            continue;
        }
        char val[64];
        assert_int_equal(sscanf(line, "%127s %63s", key, val), 2);
        if (!strcmp(key, "kopf.log_achs_name")) {
            snprintf(b->name, sizeof b->name, "%s", val);
            continue;
        }
        char *end;
        v = strtol(val, &end, 10);
        assert_true(*end == '\0');
        if (!strcmp(key, "kw.crosscomp2.interval"))
            b->interval = v;
        else if (!strcmp(key, "kw.crosscomp2.start_position_master1"))
            b->start1 = v;
        else if (!strcmp(key, "kw.crosscomp2.start_position_master2"))
            b->start2 = v;
        else if (!strcmp(key, "kw.crosscomp2.last_index_master1"))
            b->last1 = v;
        else if (!strcmp(key, "kw.crosscomp2.last_index_master2"))
            b->last2 = v;
        else if (!strcmp(key, "kw.crosscomp2.unit"))
            b->unit = v;
        else if (!strcmp(key, "kw.crosscomp2.master1_ax_nr"))
            b->m1 = v;
        else if (!strcmp(key, "kw.crosscomp2.master2_ax_nr"))
            b->m2 = v;
        else if (!strcmp(key, "kopf.achs_nr"))
            b->achs = v;
    }
    assert_true(b->seen_end);
    assert_int_equal(b->unit, 1);
    assert_true(b->interval > 0 && b->last1 >= 1 && b->last2 >= 1);
    assert_true(b->last1 <= 100 && b->last2 <= 100); /* 101 x 101 */
    for (long j = 0; j <= b->last2; ++j)
        for (long i = 0; i <= b->last1; ++i)
            assert_true(seen[j * 101 + i]); /* complete */
    free(seen);
}

/* The controller's bilinear interpolation of the table, um (inside the table). */
static double bk_eval(const bk *b, double x, double y)
{
    double u = (x * 1e4 - b->start1) / b->interval, v = (y * 1e4 - b->start2) / b->interval;
    assert_true(u >= -1e-9 && v >= -1e-9 && u <= b->last1 + 1e-9 && v <= b->last2 + 1e-9);
    int i = (int)floor(u), j = (int)floor(v);
    if (i > b->last1 - 1)
        i = (int)b->last1 - 1;
    if (j > b->last2 - 1)
        j = (int)b->last2 - 1;
    double fu = u - i, fv = v - j;
    const long *t = b->tab;
    double val = (1 - fu) * (1 - fv) * t[j * 101 + i] + fu * (1 - fv) * t[j * 101 + i + 1] +
                 (1 - fu) * fv * t[(j + 1) * 101 + i] + fu * fv * t[(j + 1) * 101 + i + 1];
    return 0.1 * val;
}

/* Independent residual: over nodes and 4 x 4 sub-points per cell. */
static void check_residual(const sc_lut *m, const sc_export_report *rep, double (*ctrl)(const void *, int, double, double),
                           const void *ctx, const int *comps, int nc, double sign)
{
    double ss = 0, mx = 0;
    long n = 0;
    for (int a = 0; a <= 4 * (m->ny - 1); ++a)
        for (int b = 0; b <= 4 * (m->nx - 1); ++b) {
            double x = m->x0_mm + m->px_mm * b / 4.0, y = m->y0_mm + m->py_mm * a / 4.0;
            for (int c = 0; c < nc; ++c) {
                double r = ctrl(ctx, comps[c], x, y) - sign * map_ref(m, comps[c], x, y);
                ss += r * r;
                mx = fmax(mx, fabs(r));
                ++n;
            }
        }
    assert_int_equal(rep->samples, n);
    assert_true(fabs(rep->rms_um - sqrt(ss / n)) < 1e-9);
    assert_true(fabs(rep->max_um - mx) < 1e-9);
    /* where: the residual there is the largest */
    double at = 0;
    for (int c = 0; c < nc; ++c)
        at = fmax(at, fabs(ctrl(ctx, comps[c], rep->max_at_mm[0], rep->max_at_mm[1]) -
                           sign * map_ref(m, comps[c], rep->max_at_mm[0], rep->max_at_mm[1])));
    assert_true(fabs(at - mx) < 1e-9);
}

static double bk_ctrl(const void *ctx, int comp, double x, double y)
{
    (void)comp;
    return bk_eval(ctx, x, y);
}

static void test_beckhoff(void **state)
{
    (void)state;
    const char *path = TMP "plane.lis";
    sc_export_options o;
    sc_export_report rep;
    sc_error err;
    bk b;
    /* Square pitch: the table nodes are the map nodes, so table = map within 0.05 um. */
    sc_lut *m = make_map(25, 25, -12.0, -12.0, 1.0, 1.0, 0);
    for (int axis = 0; axis < 2; ++axis) {
        sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
        o.axis = axis;
        o.beckhoff_x_axis_nr = 3;
        o.beckhoff_y_axis_nr = 4;
        assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
        parse_beckhoff(path, &b);
        assert_int_equal(b.achs, axis == 0 ? 3 : 4);
        assert_string_equal(b.name, axis == 0 ? "X" : "Y");
        assert_int_equal(b.m1, 3);
        assert_int_equal(b.m2, 4);
        assert_int_equal(b.interval, 10000);
        assert_int_equal(b.start1, -120000);
        assert_int_equal(b.last1, 24);
        assert_int_equal(b.last2, 24);
        for (int i = 0; i < 25; ++i)
            for (int j = 0; j < 25; ++j) {
                double x = -12.0 + j, y = -12.0 + i;
                /* ISG's sign: actual - setpoint = -G (docs/exporters.md) */
                assert_true(fabs(0.1 * b.tab[i * 101 + j] + map_ref(m, axis, x, y)) <= 0.05 + 1e-9);
            }
        assert_true(rep.max_um <= 0.05 + 1e-9);
        int comps[1] = {axis};
        check_residual(m, &rep, bk_ctrl, &b, comps, 1, -1.0);
        assert_int_equal(rep.clipped, 0);
        free(b.tab);
    }
    free(m);

    /* Rectangular pitch, offset origin: one interval for both axes, the largest that divides
     * both pitches (2 and 3 mm: 1 mm), so every map node is a table point: exact but for the
     * 0.1 um quantization. */
    m = make_map(9, 7, 3.3, -20.05, 2.0, 3.0, 0);
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    o.axis = 1;
    o.negate = 1;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_beckhoff(path, &b);
    assert_int_equal(b.interval, 10000);
    assert_true(b.start1 == 33000 && b.start2 == -200500);
    assert_true(b.last1 == 16 && b.last2 == 18);
    int comps[1] = {1};
    check_residual(m, &rep, bk_ctrl, &b, comps, 1, 1.0); /* negated: +G */
    assert_true(rep.max_um <= 0.05 + 1e-9);
    free(b.tab);
    free(m);
    /* An origin 1e-10 mm off the 0.1 um grid (1e-6 of the table's unit, the tolerance's edge)
     * is on it: still the common interval, not the smaller pitch. */
    m = make_map(9, 7, 3.3, 1e-10, 2.0, 3.0, 0);
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_beckhoff(path, &b);
    assert_int_equal(b.interval, 10000);
    assert_true(b.start1 == 33000 && b.start2 == 0);
    free(b.tab);
    free(m);
    /* Where the common interval needs more than 101 points (2 and 2.5 mm: 0.5 mm over 100 mm),
     * the smaller pitch, the other axis resampled. */
    m = make_map(51, 41, 0.0, 0.0, 2.0, 2.5, 0);
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    o.axis = 0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_beckhoff(path, &b);
    assert_int_equal(b.interval, 20000);
    comps[0] = 0;
    check_residual(m, &rep, bk_ctrl, &b, comps, 1, -1.0);
    assert_true(rep.max_um < 0.2); /* resampled along y: smooth map, small loss */
    free(b.tab);
    free(m);

    /* 101 x 101 limit: a finer interval than fits is refused, nothing written. */
    m = make_map(101, 101, 0.0, 0.0, 1.0, 1.0, 0);
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    o.interval_mm = 0.5;
    unlink(path);
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "101"));
    struct stat st;
    assert_int_not_equal(stat(path, &st), 0);
    free(m);
    /* Auto interval widens when the finer pitch would need more than 101 points. */
    m = make_map(101, 101, 0.0, 0.0, 1.0, 0.25, 1);
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_beckhoff(path, &b);
    assert_int_equal(b.interval, 10000);
    assert_int_equal(b.last1, 100);
    assert_int_equal(b.last2, 25);
    free(b.tab);

    /* Clipping: entries beyond the limit are written at the limit and counted. */
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    o.limit_um = 0.5;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_beckhoff(path, &b);
    long expect = 0;
    for (long j = 0; j <= b.last2; ++j)
        for (long i = 0; i <= b.last1; ++i) {
            double v = map_ref(m, 0, (b.start1 + i * b.interval) * 1e-4, (b.start2 + j * b.interval) * 1e-4);
            if (fabs(v) > 0.5) {
                ++expect;
                assert_true(labs(b.tab[j * 101 + i]) == 5);
            }
            assert_true(labs(b.tab[j * 101 + i]) <= 5);
        }
    assert_true(expect > 0);
    assert_int_equal(rep.clipped, expect);
    free(b.tab);
    free(m);
}

/* ---- Siemens: parse the $AN_CEC part program ---- */

typedef struct cec {
    int used[8];
    double step[8], min[8], max[8];
    char in[8][16], out[8][16];
    double val[8][2001];
    int nval[8];
} cec;

static void parse_siemens(const char *path, cec *c)
{
    memset(c, 0, sizeof *c);
    char *text = slurp(path), *save = NULL;
    int first = 1, end = 0;
    for (char *line = strtok_r(text, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
        if (first) {
            assert_string_equal(line, "%_N_NC_CEC_INI");
            first = 0;
            continue;
        }
        if (line[0] == ';' || !strcmp(line, "CHANDATA(1)"))
            continue;
        if (!strcmp(line, "M17")) {
            end = 1;
            continue;
        }
        int t, p;
        double v;
        char name[16];
        if (sscanf(line, "$AN_CEC[%d,%d]=%lf", &t, &p, &v) == 3) {
            assert_true(t >= 0 && t < 8 && p >= 0 && p <= 2000);
            assert_int_equal(p, c->nval[t]); /* in order, none missing */
            c->val[t][p] = v;
            c->nval[t]++;
            c->used[t] = 1;
        } else if (sscanf(line, "$AN_CEC_INPUT_AXIS[%d]=(%15[^)])", &t, name) == 2)
            snprintf(c->in[t], sizeof c->in[t], "%s", name);
        else if (sscanf(line, "$AN_CEC_OUTPUT_AXIS[%d]=(%15[^)])", &t, name) == 2)
            snprintf(c->out[t], sizeof c->out[t], "%s", name);
        else if (sscanf(line, "$AN_CEC_STEP[%d]=%lf", &t, &v) == 2)
            c->step[t] = v;
        else if (sscanf(line, "$AN_CEC_MIN[%d]=%lf", &t, &v) == 2)
            c->min[t] = v;
        else if (sscanf(line, "$AN_CEC_MAX[%d]=%lf", &t, &v) == 2)
            c->max[t] = v;
        else if (sscanf(line, "$AN_CEC_DIRECTION[%d]=%lf", &t, &v) == 2 ||
                 sscanf(line, "$AN_CEC_MULT_BY_TABLE[%d]=%lf", &t, &v) == 2 ||
                 sscanf(line, "$AN_CEC_IS_MODULO[%d]=%lf", &t, &v) == 2)
            assert_true(v == 0);
        else
            fail_msg("unexpected line '%s'", line);
    }
    assert_true(end);
    for (int t = 0; t < 8; ++t)
        if (c->used[t]) {
            /* points = (MAX - MIN) / STEP + 1, as MD18342 is sized */
            assert_true(fabs((c->max[t] - c->min[t]) / c->step[t] + 1 - c->nval[t]) < 1e-6);
            assert_true(c->nval[t] <= 2000);
        }
}

typedef struct cec_eval_ctx {
    const cec *c;
    const char *xname, *yname;
} cec_eval_ctx;

/* Sum of the tables whose output is comp's axis; each linear, clamped at MIN/MAX; mm -> um. */
static double cec_ctrl(const void *vctx, int comp, double x, double y)
{
    const cec_eval_ctx *e = vctx;
    const cec *c = e->c;
    const char *outname = comp == 0 ? e->xname : e->yname;
    double sum = 0;
    for (int t = 0; t < 8; ++t) {
        if (!c->used[t] || strcmp(c->out[t], outname) != 0)
            continue;
        double s = strcmp(c->in[t], e->xname) == 0 ? x : y;
        double u = (s - c->min[t]) / c->step[t];
        u = fmin(fmax(u, 0), c->nval[t] - 1);
        int k = (int)floor(u);
        if (k > c->nval[t] - 2)
            k = c->nval[t] - 2;
        double f = u - k;
        sum += 1e3 * (c->val[t][k] * (1 - f) + c->val[t][k + 1] * f);
    }
    return sum;
}

static void test_siemens(void **state)
{
    (void)state;
    const char *path = TMP "cec.mpf";
    sc_export_options o;
    sc_export_report rep;
    sc_error err;
    cec *c = malloc(sizeof *c);
    assert_non_null(c);
    /* A separable map is represented exactly (within 1 nm steps). */
    sc_lut *m = make_map(21, 17, -50.0, 10.0, 5.0, 2.5, 1);
    sc_export_options_init(&o, SC_EXPORT_SIEMENS_CEC);
    o.axis = -1;
    o.siemens_x_name = "X1";
    o.siemens_y_name = "Y1";
    o.siemens_first_table = 2;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_siemens(path, c);
    assert_non_null(strstr(slurp(path), "tables hold -A and -B of Gx and Gy"));
    int ntab = 0;
    for (int t = 0; t < 8; ++t)
        ntab += c->used[t];
    assert_int_equal(ntab, 4);
    assert_false(c->used[0] || c->used[1]);
    assert_string_equal(c->in[2], "X1");
    assert_string_equal(c->out[2], "X1");
    assert_string_equal(c->in[3], "Y1");
    assert_string_equal(c->out[3], "X1");
    assert_true(fabs(c->step[2] - 5.0) < 1e-9 && fabs(c->min[2] + 50.0) < 1e-9);
    assert_true(fabs(c->step[3] - 2.5) < 1e-9 && fabs(c->min[3] - 10.0) < 1e-9);
    cec_eval_ctx e = {c, "X1", "Y1"};
    int both[2] = {0, 1};
    check_residual(m, &rep, cec_ctrl, &e, both, 2, -1.0); /* Siemens' sign: -G */
    assert_true(rep.max_um <= 1.0e-3 + 1e-9); /* two 0.5 nm roundings */
    free(m);

    /* MD32720 limits the sum of an axis's tables: Gy = 600 um at both far edges (x and y) adds
     * up to 1200 um at the far corner (the x and the y table each within the 1000 um default):
     * refused, the axis and the sum named; accepted with --limit-um 1300, nothing clipped. */
    m = make_map(11, 11, 0.0, 0.0, 10.0, 10.0, 1);
    for (int i = 0; i < m->ny; ++i)
        for (int j = 0; j < m->nx; ++j)
            m->gy_um[i * m->nx + j] = 600.0 * (j + i) / 10.0, m->gx_um[i * m->nx + j] = 0;
    sc_export_options_init(&o, SC_EXPORT_SIEMENS_CEC);
    o.axis = -1;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    if (!strstr(err.msg, "the Y tables of axis AX2 add up to 1200.000 um") || !strstr(err.msg, "MD32720"))
        fail_msg("%s", err.msg);
    o.limit_um = 1300;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    assert_int_equal(rep.clipped, 0);
    o.limit_um = 1199.9;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    free(m);

    /* With interaction terms the residual is that part: recomputed independently. */
    m = make_map(21, 17, -50.0, 10.0, 5.0, 2.5, 0);
    sc_export_options_init(&o, SC_EXPORT_SIEMENS_CEC);
    o.axis = 1;
    o.negate = 1;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_siemens(path, c);
    assert_true(c->used[0] && c->used[1] && !c->used[2]);
    assert_string_equal(c->out[0], "AX2");
    e.xname = "AX1";
    e.yname = "AX2";
    int ycomp[1] = {1};
    check_residual(m, &rep, cec_ctrl, &e, ycomp, 1, 1.0); /* negated: +G */
    assert_true(rep.max_um > 0.01);
    /* ... and it is the least-squares additive fit: at the nodes the residual sums to ~0 along
     * every row and column. */
    for (int i = 0; i < m->ny; ++i) {
        double s = 0;
        for (int j = 0; j < m->nx; ++j) {
            double x = m->x0_mm + j * m->px_mm, y = m->y0_mm + i * m->py_mm;
            s += cec_ctrl(&e, 1, x, y) - m->gy_um[i * m->nx + j];
        }
        assert_true(fabs(s / m->nx) < 2e-3);
    }
    /* Too many points for a table: refused. */
    o.interval_mm = 0.01;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "2000"));
    free(m);
    free(c);
}

/* ---- LinuxCNC ---- */

typedef struct lc {
    int n;
    double nom[300], fwd[300], rev[300];
} lc;

static void parse_linuxcnc(const char *path, lc *l)
{
    memset(l, 0, sizeof *l);
    char *text = slurp(path), *save = NULL;
    int comment = 0;
    for (char *line = strtok_r(text, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
        char extra;
        /* LinuxCNC's loader stops at the first line that is not a triplet: only the last line
         * may be a comment, and it says that the file needs COMP_FILE_TYPE = 1. */
        assert_false(comment);
        if (line[0] == '#') {
            assert_non_null(strstr(line, "COMP_FILE_TYPE = 1"));
            comment = 1;
            continue;
        }
        assert_true(l->n < 300);
        assert_int_equal(sscanf(line, "%lf %lf %lf %c", &l->nom[l->n], &l->fwd[l->n], &l->rev[l->n], &extra), 3);
        if (l->n > 0)
            assert_true(l->nom[l->n] > l->nom[l->n - 1]); /* ascending nominals */
        l->n++;
    }
    assert_true(comment);
    assert_true(l->n >= 2 && l->n <= 256);
}

typedef struct lc_ctx {
    const lc *l;
    int axis;
} lc_ctx;

static double lc_ctrl(const void *vctx, int comp, double x, double y)
{
    (void)comp;
    const lc_ctx *c = vctx;
    const lc *l = c->l;
    double s = c->axis == 0 ? x : y;
    /* LinuxCNC's table: a sentinel at -DBL_MAX that takes the first trim with no slope when the
     * first entry is loaded (motion/command.c, SET_JOINT_COMP), so the first trim is held below
     * the first entry; the last trim held above the last */
    if (s < l->nom[0])
        return 1e3 * l->fwd[0];
    if (s >= l->nom[l->n - 1])
        return 1e3 * l->fwd[l->n - 1];
    int k = 0;
    while (l->nom[k + 1] < s)
        ++k;
    double f = (s - l->nom[k]) / (l->nom[k + 1] - l->nom[k]);
    return 1e3 * (l->fwd[k] * (1 - f) + l->fwd[k + 1] * f);
}

static void test_linuxcnc(void **state)
{
    (void)state;
    const char *path = TMP "joint.comp";
    sc_export_options o;
    sc_export_report rep;
    sc_error err;
    lc *l = malloc(sizeof *l);
    assert_non_null(l);
    sc_lut *m = make_map(31, 11, -15.0, 0.0, 1.0, 2.0, 0);
    for (int axis = 0; axis < 2; ++axis) {
        sc_export_options_init(&o, SC_EXPORT_LINUXCNC);
        o.axis = axis;
        assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
        parse_linuxcnc(path, l);
        assert_non_null(strstr(slurp(path), axis == 0 ? "X trims (+Gx, mm" : "Y trims (+Gy, mm"));
        assert_int_equal(l->n, axis == 0 ? 31 : 11);
        assert_int_equal(rep.points[0], l->n);
        /* no entry beyond the map: the first is the map's first node */
        assert_true(fabs(l->nom[0] - (axis == 0 ? m->x0_mm : m->y0_mm)) < 1e-9);
        for (int k = 0; k < l->n; ++k) {
            assert_true(l->fwd[k] == l->rev[k]);
            /* the trim is the mean of G over the other coordinate's nodes */
            double mean = 0;
            int other = axis == 0 ? m->ny : m->nx;
            for (int q = 0; q < other; ++q)
                mean += axis == 0 ? m->gx_um[q * m->nx + k] : m->gy_um[k * m->nx + q];
            mean /= other;
            assert_true(fabs(1e3 * l->fwd[k] - mean) <= 0.5e-3 + 1e-9);
        }
        lc_ctx ctx = {l, axis};
        int comps[1] = {axis};
        check_residual(m, &rep, lc_ctrl, &ctx, comps, 1, 1.0);
        /* outside the map LinuxCNC applies the edge trims, as selfcald clamps */
        double below = (axis == 0 ? m->x0_mm : m->y0_mm) - 7.5;
        double above = (axis == 0 ? m->x0_mm + (m->nx - 1) * m->px_mm : m->y0_mm + (m->ny - 1) * m->py_mm) + 7.5;
        assert_true(lc_ctrl(&ctx, axis, axis == 0 ? below : 0, axis == 0 ? 0 : below) == 1e3 * l->fwd[0]);
        assert_true(lc_ctrl(&ctx, axis, axis == 0 ? above : 0, axis == 0 ? 0 : above) == 1e3 * l->fwd[l->n - 1]);
    }
    /* Along one line: equal to the map on that line within 1 nm rounding. */
    sc_export_options_init(&o, SC_EXPORT_LINUXCNC);
    o.use_line = 1;
    o.line_mm = 6.0;
    o.interval_mm = 0.25;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_linuxcnc(path, l);
    assert_int_equal(l->n, 121);
    for (int k = 0; k < l->n; ++k)
        assert_true(fabs(1e3 * l->fwd[k] - map_ref(m, 0, l->nom[k], 6.0)) <= 0.5e-3 + 1e-9);
    lc_ctx ctx = {l, 0};
    int comps[1] = {0};
    check_residual(m, &rep, lc_ctrl, &ctx, comps, 1, 1.0);
    /* 256 entries per joint, every one along the map (no guard entry beyond it). */
    o.interval_mm = 30.0 / 255.0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_linuxcnc(path, l);
    assert_int_equal(l->n, 256);
    assert_int_equal(rep.points[0], 256);
    o.interval_mm = 0.1;
    unlink(path);
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "256"));
    struct stat st;
    assert_int_not_equal(stat(path, &st), 0);
    /* One joint at a time. */
    o.interval_mm = 0;
    o.axis = -1;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    free(m);
    free(l);
}

/* ---- Beckhoff / ISG cross compensation of a straightness profile ---- */

typedef struct isg_cross {
    int achs_nr, master, last_index, n;
    long long set[1100], corr[1100];
} isg_cross;

/* An independent reader of ISG's list: "name value" lines, '#' comment lines, "End". */
static void parse_isg_cross(const char *path, isg_cross *c)
{
    memset(c, 0, sizeof *c);
    c->last_index = -1;
    char *text = slurp(path), *save = NULL;
    for (char *ln = strtok_r(text, "\n", &save); ln; ln = strtok_r(NULL, "\n", &save)) {
        int i;
        long long v;
        if (sscanf(ln, "kw.crosscomp.table[%d].setpoint %lld", &i, &v) == 2) {
            assert_true(i >= 0 && i < 1100);
            c->set[i] = v;
            c->n = i + 1 > c->n ? i + 1 : c->n;
        } else if (sscanf(ln, "kw.crosscomp.table[%d].correction %lld", &i, &v) == 2) {
            assert_true(i >= 0 && i < 1100);
            c->corr[i] = v;
        } else {
            sscanf(ln, "kopf.achs_nr %d", &c->achs_nr);
            sscanf(ln, "kw.crosscomp.master_ax_nr %d", &c->master);
            sscanf(ln, "kw.crosscomp.last_index %d", &c->last_index);
        }
    }
}

/* ISG's linear interpolation of the written integers, end values beyond them (um). */
static double isg_cross_eval(const isg_cross *c, double x_mm)
{
    double q = x_mm * 1e4;
    if (q <= (double)c->set[0])
        return 0.1 * (double)c->corr[0];
    for (int i = 1; i < c->n; ++i)
        if (q <= (double)c->set[i]) {
            double f = (q - (double)c->set[i - 1]) / (double)(c->set[i] - c->set[i - 1]);
            return 0.1 * ((double)c->corr[i - 1] * (1 - f) + (double)c->corr[i] * f);
        }
    return 0.1 * (double)c->corr[c->n - 1];
}

/* The profile as selfcald applies it: linear, clamped (SPEC §4). */
static double profile_ref(const sc_lut_profile *p, double x)
{
    double u = (x - p->start_mm) / p->step_mm;
    if (u <= 0)
        return p->err_um[0];
    if (u >= p->n - 1)
        return p->err_um[p->n - 1];
    int k = (int)u;
    return p->err_um[k] * (1 - (u - k)) + p->err_um[k + 1] * (u - k);
}

/* ---- KMotion: the GeoCorrect table, read back as KMotionCNC reads it ---- */

typedef struct kmo {
    int nrows, ncols;
    double sx, sy, ox, oy; /* inches */
    double *ax, *ay;       /* [row][col], inches */
} kmo;

static void parse_kmotion(const char *path, kmo *k)
{
    char *text = slurp(path), *save = NULL;
    char *line = strtok_r(text, "\n", &save);
    assert_non_null(line);
    assert_int_equal(sscanf(line, "%d,%d", &k->nrows, &k->ncols), 2);
    assert_true(k->nrows >= 2 && k->ncols >= 2);
    assert_non_null(line = strtok_r(NULL, "\n", &save));
    assert_int_equal(sscanf(line, "%lf,%lf", &k->sx, &k->sy), 2);
    assert_non_null(line = strtok_r(NULL, "\n", &save));
    assert_int_equal(sscanf(line, "%lf,%lf", &k->ox, &k->oy), 2);
    assert_true(k->sx > 0 && k->sy > 0);
    size_t n = (size_t)k->nrows * (size_t)k->ncols;
    k->ax = calloc(n, sizeof *k->ax);
    k->ay = calloc(n, sizeof *k->ay);
    char *seen = calloc(n, 1);
    assert_true(k->ax && k->ay && seen);
    size_t count = 0;
    while ((line = strtok_r(NULL, "\n", &save))) {
        int r, c;
        double x, y, z;
        char extra;
        assert_int_equal(sscanf(line, "%d,%d,%lf,%lf,%lf %c", &r, &c, &x, &y, &z, &extra), 5);
        assert_true(r >= 0 && r < k->nrows && c >= 0 && c < k->ncols);
        assert_false(seen[r * k->ncols + c]);
        seen[r * k->ncols + c] = 1;
        k->ax[r * k->ncols + c] = x;
        k->ay[r * k->ncols + c] = y;
        assert_true(z == 0.0);
        ++count;
    }
    assert_int_equal(count, n); /* every node, once */
    free(seen);
}

/* KMotionX's GeoCorrect (GCodeInterpreter/Kinematics.cpp): the cell of the offset position
 * clamped to the table, the fractions not (the edge cells extrapolate), bilinear; inches. */
static void kmo_correct(const kmo *k, double x, double y, double *cx, double *cy)
{
    double u = (x - k->ox) / k->sx, v = (y - k->oy) / k->sy;
    int c = (int)floor(u), r = (int)floor(v);
    c = c < 0 ? 0 : c > k->ncols - 2 ? k->ncols - 2 : c;
    r = r < 0 ? 0 : r > k->nrows - 2 ? k->nrows - 2 : r;
    double fu = u - c, fv = v - r;
    const double *t[2] = {k->ax, k->ay};
    double out[2];
    for (int a = 0; a < 2; ++a) {
        const double *g = t[a];
        out[a] = (1 - fu) * (1 - fv) * g[r * k->ncols + c] + fu * (1 - fv) * g[r * k->ncols + c + 1] +
                 (1 - fu) * fv * g[(r + 1) * k->ncols + c] + fu * fv * g[(r + 1) * k->ncols + c + 1];
    }
    *cx = out[0];
    *cy = out[1];
}

/* What KMotion commands minus the ideal point, um. */
static double kmo_ctrl(const void *ctx, int comp, double x, double y)
{
    double cx, cy;
    kmo_correct(ctx, x / 25.4, y / 25.4, &cx, &cy);
    return comp == 0 ? (cx * 25.4 - x) * 1e3 : (cy * 25.4 - y) * 1e3;
}

/* The table holds the map's correction at its nodes and the edge values beyond; the report's
 * residual is that of KMotion's own interpolation (recomputed here), also negated and clipped. */
static void test_kmotion_table(void **state)
{
    (void)state;
    const char *path = TMP "geo.txt";
    sc_lut *m = make_map(9, 7, -20.0, -15.0, 5.0, 2.5, 0);
    int comps[2] = {0, 1};
    for (int neg = 0; neg < 2; ++neg) {
        sc_export_options o;
        sc_export_options_init(&o, SC_EXPORT_KMOTION);
        o.negate = neg;
        sc_export_report rep;
        sc_error err;
        assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
        kmo k;
        parse_kmotion(path, &k);
        assert_int_equal(rep.tables, 1);
        assert_int_equal(rep.points[0], k.ncols);
        assert_int_equal(rep.points[1], k.nrows);
        assert_true(fabs(rep.interval_mm - 5.0) < 1e-12);
        assert_true(fabs(rep.unit_um - 25.4e-6) < 1e-15);
        assert_int_equal(rep.clipped, 0);
        const double sign = neg ? -1.0 : 1.0;
        /* at every node of the map: the ideal point plus (or minus) G, to the 1e-9 in written */
        for (int i = 0; i < m->ny; ++i)
            for (int j = 0; j < m->nx; ++j) {
                double x = m->x0_mm + j * m->px_mm, y = m->y0_mm + i * m->py_mm;
                assert_true(fabs(kmo_ctrl(&k, 0, x, y) - sign * m->gx_um[i * m->nx + j]) < 1e-4);
                assert_true(fabs(kmo_ctrl(&k, 1, x, y) - sign * m->gy_um[i * m->nx + j]) < 1e-4);
            }
        /* beyond the map, 1.3 pitches out on every side: the edge value (our clamping) */
        const double xs[3] = {m->x0_mm - 6.5, m->x0_mm + 12.0, m->x0_mm + 8 * 5.0 + 6.5};
        const double ys[3] = {m->y0_mm - 3.25, m->y0_mm + 7.0, m->y0_mm + 6 * 2.5 + 3.25};
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) {
                if (a == 1 && b == 1)
                    continue;
                double xc = fmin(fmax(xs[a], m->x0_mm), m->x0_mm + 40.0);
                double yc = fmin(fmax(ys[b], m->y0_mm), m->y0_mm + 15.0);
                for (int c = 0; c < 2; ++c)
                    assert_true(fabs(kmo_ctrl(&k, c, xs[a], ys[b]) - sign * map_ref(m, c, xc, yc)) < 1e-4);
            }
        check_residual(m, &rep, kmo_ctrl, &k, comps, 2, sign);
        assert_true(rep.max_um < 0.1); /* the map's nodes: only the cells' own bilinear error */
        free(k.ax);
        free(k.ay);
    }
    /* a limit: entries beyond it written at it and counted (both components) */
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_KMOTION);
    o.limit_um = 0.5;
    sc_export_report rep;
    sc_error err;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    kmo k;
    parse_kmotion(path, &k);
    long over = 0;
    for (int r = 0; r < k.nrows; ++r)
        for (int c = 0; c < k.ncols; ++c) {
            int i = r - 1 < 0 ? 0 : r - 1 > m->ny - 1 ? m->ny - 1 : r - 1;
            int j = c - 1 < 0 ? 0 : c - 1 > m->nx - 1 ? m->nx - 1 : c - 1;
            double x = m->x0_mm + (c - 1) * m->px_mm, y = m->y0_mm + (r - 1) * m->py_mm;
            const double g[2] = {m->gx_um[i * m->nx + j], m->gy_um[i * m->nx + j]};
            const double t[2] = {(k.ax[r * k.ncols + c] * 25.4 - x) * 1e3, (k.ay[r * k.ncols + c] * 25.4 - y) * 1e3};
            for (int a = 0; a < 2; ++a) {
                over += fabs(g[a]) > 0.5;
                assert_true(fabs(t[a] - fmin(fmax(g[a], -0.5), 0.5)) < 1e-4);
            }
        }
    assert_true(over > 0);
    assert_int_equal(rep.clipped, over);
    assert_true(fabs(rep.limit_um - 0.5) < 1e-12);
    check_residual(m, &rep, kmo_ctrl, &k, comps, 2, 1.0);
    free(k.ax);
    free(k.ay);
    free(m);
    unlink(path);
}

/* The firmware formats report the skew they wrote, as the firmware reads it back: Marlin's I,
 * RepRapFirmware's X / S (X written with 6 decimals over S = 1000 mm). */
static void test_firmware_skew_as_written(void **state)
{
    (void)state;
    const char *path = TMP "fw.gcode";
    sc_lut *m = make_map(9, 9, -20.0, -20.0, 5.0, 5.0, 0);
    for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j) /* x moving with y: a skew that is no round number */
            m->gx_um[i * 9 + j] += 1e3 * 3.33333333e-5 * (-20.0 + 5.0 * i);
    const int fmts[2] = {SC_EXPORT_MARLIN, SC_EXPORT_REPRAP};
    for (int f = 0; f < 2; ++f) {
        sc_export_options o;
        sc_export_options_init(&o, fmts[f]);
        sc_export_report rep;
        sc_error err;
        assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
        const char *text = slurp(path);
        double want;
        if (fmts[f] == SC_EXPORT_MARLIN) {
            const char *l = strstr(text, "\nM852 I");
            assert_non_null(l);
            assert_int_equal(sscanf(l, "\nM852 I%lf", &want), 1);
        } else {
            const char *l = strstr(text, "\nM556 S");
            assert_non_null(l);
            double S, X;
            assert_int_equal(sscanf(l, "\nM556 S%lf X%lf", &S, &X), 2);
            assert_true(S == 1000.0);
            want = X / S;
            assert_non_null(strstr(l, ".")); /* X as written: 6 decimals */
            assert_int_equal((int)strcspn(strchr(strchr(l, 'X'), '.') + 1, "\n"), 6);
        }
        assert_true(fabs(want) > 1e-6);
        assert_true(fabs(rep.skew - want) <= 1e-15 * fabs(want));
    }
    free(m);
    unlink(path);
}

/* KMotion: one 2-D table, covering at least the map's nodes. */
static void test_kmotion_report(void **state)
{
    (void)state;
    sc_lut *m = make_map(9, 7, -20.0, -15.0, 5.0, 5.0, 0);
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_KMOTION);
    sc_export_report rep;
    sc_error err;
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
    assert_int_equal(rep.tables, 1);
    assert_true(rep.points[0] >= 9 && rep.points[1] >= 7);
    /* a map of one row or one column is no map for any format */
    for (int k = 0; k < 2; ++k) {
        int nx = m->nx, ny = m->ny;
        *(k ? &m->ny : &m->nx) = 1;
        assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_E_INPUT);
        assert_non_null(strstr(err.msg, "at least 2 x 2 nodes"));
        m->nx = nx, m->ny = ny;
    }
    free(m);
}

static void test_beckhoff_cross(void **state)
{
    (void)state;
    sc_lut *m = make_map(9, 7, -20.0, -15.0, 5.0, 5.0, 0);
    sc_lut_profile *p = &m->profile[0];
    p->axis = 0; /* error of z along x: slave z, master x */
    p->dir = 2;
    p->n = 301;
    p->start_mm = -23.33333; /* not a whole 0.1 um: setpoints are rounded */
    p->step_mm = 0.17;
    for (int k = 0; k < p->n; ++k)
        p->err_um[k] = 1.7 * sin(0.05 * k) + 0.3 * cos(0.31 * k);
    m->n_profiles = 1;
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_BECKHOFF);
    o.cross_profile = 0;
    o.beckhoff_z_axis_nr = 7;
    sc_export_report rep;
    sc_error err;
    const char *path = TMP "cross.lis";
    unlink(path);
    /* A dry run writes nothing. */
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
    struct stat st;
    assert_int_not_equal(stat(path, &st), 0);
    assert_int_equal(rep.points[0], 301);
    assert_int_equal(rep.travel_points, 0);
    isg_cross *c = malloc(sizeof *c);
    assert_non_null(c);
    for (int negate = 0; negate < 2; ++negate) {
        o.negate = negate;
        assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
        parse_isg_cross(path, c);
        assert_int_equal(c->n, 301);
        assert_int_equal(c->last_index, c->n - 1);
        assert_int_equal(c->achs_nr, 7);
        assert_int_equal(c->master, 1);
        for (int i = 1; i < c->n; ++i)
            assert_true(c->set[i] > c->set[i - 1]);
        assert_true(c->set[0] == llround(p->start_mm * 1e4));
        /* ISG's value = actual - setpoint = -e; within 0.05 um on the profile, the reported
         * maximum agrees with a dense independent sampling. */
        const double sign = negate ? 1.0 : -1.0;
        double mx = 0;
        for (int q = 0; q <= 20 * (p->n - 1); ++q) {
            double x = p->start_mm + p->step_mm * q / 20.0;
            mx = fmax(mx, fabs(isg_cross_eval(c, x) - sign * profile_ref(p, x)));
        }
        assert_true(mx <= 0.05 + 1e-9);
        assert_true(rep.max_um <= 0.05 + 1e-9 && rep.max_um >= mx - 2e-3);
    }
    o.negate = 0;
    /* The travel: two points more, carrying the end values. */
    o.use_travel = 1;
    o.travel_mm[0] = -30.0;
    o.travel_mm[1] = 40.0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    parse_isg_cross(path, c);
    assert_int_equal(c->n, 303);
    assert_int_equal(rep.travel_points, 2);
    assert_true(c->set[0] == -300000 && c->set[302] == 400000);
    assert_true(c->corr[0] == c->corr[1] && c->corr[302] == c->corr[301]);
    for (double x = -30.0; x <= 40.0; x += 0.013)
        assert_true(fabs(isg_cross_eval(c, x) + profile_ref(p, x)) <= 0.05 + 1e-9);
    /* Refusals, no file: a travel that does not contain the profile, too many points, a profile
     * beside the map, no such profile. */
    unlink(path);
    o.travel_mm[0] = -20.0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "travel -20..40 mm does not contain"));
    o.travel_mm[0] = 50.0; /* MIN > MAX: not about a file, so no file and no line */
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "MIN < MAX"));
    assert_true(err.file[0] == '\0' && err.line == 0);
    o.travel_mm[0] = -20.0;
    o.use_travel = 0;
    o.profile_interval_mm = 0.05;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "1000"));
    o.profile_interval_mm = 0;
    p->start_mm = 200.0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "do not overlap"));
    /* touching the map at one end (x = 20 or x = -20 mm) is overlapping */
    p->start_mm = 20.0;
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
    p->start_mm = -20.0 - 300 * 0.17;
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
    p->start_mm = -23.33333;
    o.cross_profile = 1;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_int_not_equal(stat(path, &st), 0);
    free(c);
    free(m);
}

/* ---- Automation1 1-D tables (straightness profiles), read back by Aerotech's rule ---- */

typedef struct a1_table {
    int ref, out, n;
    double first_mm, step_mm;
    double v_um[4096];
} a1_table;

/* The tables of an Automation1 1-D file: ':START REF OUT SAMPLEDIST=S POSUNIT=PRIMARY
 * CORUNIT=PRIMARY/1000', ':START OFFSET=O' (index = (position + O) / S), one value a line,
 * ':END'; ';' comments. Returns the number of tables. */
static int parse_a1_1d(const char *path, a1_table *t, int cap)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[512];
    int nt = -1, in_table = 0;
    while (fgets(line, sizeof line, f)) {
        double v;
        int ref, out;
        if (line[0] == ';')
            continue;
        if (sscanf(line, ":START %d %d SAMPLEDIST=%lf", &ref, &out, &v) == 3) {
            assert_true(++nt < cap);
            t[nt].ref = ref, t[nt].out = out, t[nt].step_mm = v, t[nt].n = 0;
            assert_non_null(strstr(line, "POSUNIT=PRIMARY CORUNIT=PRIMARY/1000"));
        } else if (sscanf(line, ":START OFFSET=%lf", &v) == 1) {
            t[nt].first_mm = -v;
            in_table = 1;
        } else if (!strncmp(line, ":END", 4)) {
            in_table = 0;
        } else {
            assert_true(in_table && sscanf(line, "%lf", &v) == 1 && t[nt].n < 4096);
            t[nt].v_um[t[nt].n++] = v;
        }
    }
    fclose(f);
    return nt + 1;
}

/* Linear between the entries, the nearest end point beyond them. */
static double a1_table_eval(const a1_table *t, double s)
{
    double u = (s - t->first_mm) / t->step_mm;
    if (u <= 0)
        return t->v_um[0];
    if (u >= t->n - 1)
        return t->v_um[t->n - 1];
    int k = (int)u;
    return t->v_um[k] * (1 - (u - k)) + t->v_um[k + 1] * (u - k);
}

static void test_aerotech_1d(void **state)
{
    (void)state;
    sc_lut *m = make_map(9, 7, -20.0, -15.0, 5.0, 5.0, 0);
    for (int k = 0; k < 2; ++k) {
        sc_lut_profile *p = &m->profile[k];
        p->axis = k == 0 ? 0 : 1; /* x:y, then y:z */
        p->dir = k == 0 ? 1 : 2;
        p->n = k == 0 ? 301 : 90;
        p->start_mm = k == 0 ? -23.3 : -14.0;
        p->step_mm = k == 0 ? 0.17 : 0.35;
        for (int i = 0; i < p->n; ++i)
            p->err_um[i] = 1.7 * sin(0.05 * i + k) + 0.3 * cos(0.31 * i);
    }
    m->n_profiles = 2;
    sc_export_options o;
    sc_export_options_init(&o, SC_EXPORT_AEROTECH_A1);
    o.cross_profile = 0;
    o.beckhoff_y_axis_nr = 4;
    o.beckhoff_z_axis_nr = 6;
    sc_export_report rep;
    sc_error err;
    const char *path = TMP "a1.cal";
    a1_table *t = malloc(2 * sizeof *t);
    assert_non_null(t);
    for (int negate = 0; negate < 2; ++negate) {
        o.negate = negate;
        unlink(path);
        assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
        assert_int_equal(parse_a1_1d(path, t, 2), 2);
        assert_int_equal(rep.tables, 2);
        assert_int_equal(rep.points[0], 301);
        assert_int_equal(rep.points[1], 90);
        assert_true(t[0].ref == 1 && t[0].out == 4 && t[1].ref == 4 && t[1].out == 6);
        const double sign = negate ? -1.0 : 1.0; /* +e: added to the command */
        double mx = 0;
        for (int k = 0; k < 2; ++k) {
            const sc_lut_profile *p = &m->profile[k];
            assert_int_equal(t[k].n, p->n);
            assert_true(fabs(t[k].first_mm - p->start_mm) < 1e-9);
            assert_true(fabs(t[k].step_mm - p->step_mm) < 1e-9);
            for (int q = -60; q <= 20 * (p->n - 1) + 60; ++q) { /* beyond both ends too */
                const double s = p->start_mm + p->step_mm * q / 20.0;
                mx = fmax(mx, fabs(a1_table_eval(&t[k], s) - sign * profile_ref(p, s)));
            }
        }
        assert_true(mx <= 0.5 * SC_EXPORT_AEROTECH_UNIT_UM + 1e-9);
        assert_true(rep.max_um <= 0.5 * SC_EXPORT_AEROTECH_UNIT_UM + 1e-9 &&
                    rep.max_um >= mx - 1e-6);
    }
    o.negate = 0;
    /* a coarser spacing: equally spaced from the first point, the last step past the end */
    o.profile_interval_mm = 1.0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_OK);
    assert_int_equal(parse_a1_1d(path, t, 2), 2);
    assert_int_equal(t[0].n, 52); /* 51 mm of profile: 52 points */
    assert_true(fabs(t[0].v_um[51] - m->profile[0].err_um[300]) <= 0.5e-4 + 1e-9);
    assert_true(rep.max_um > 0.01); /* the profile between the points */
    /* Refusals, no file: too many points, a profile beside the map, no such profile, a limit
     * that clips and counts. */
    unlink(path);
    o.profile_interval_mm = 1e-4;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "65536"));
    o.profile_interval_mm = 0;
    m->profile[0].start_mm = 200.0;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "do not overlap"));
    m->profile[0].start_mm = -23.3;
    o.cross_profile = 2;
    assert_int_equal(sc_export_write(m, &o, path, &rep, &err), SC_E_INPUT);
    struct stat st;
    assert_int_not_equal(stat(path, &st), 0);
    o.cross_profile = 0;
    o.limit_um = 1.0;
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
    long over = 0;
    for (int k = 0; k < 2; ++k)
        for (int i = 0; i < m->profile[k].n; ++i)
            over += fabs(m->profile[k].err_um[i]) > 1.0;
    assert_true(over > 0);
    assert_int_equal(rep.clipped, over);
    free(t);
    free(m);
}

/* ---- the table of back-ends; Automation1 and Power PMAC through the library ---- */

static void test_backends(void **state)
{
    (void)state;
    static const char *const names[] = {"beckhoff", "siemens-cec", "linuxcnc", "klipper", "marlin",
                                        "reprap", "kmotion", "aerotech-a1", "powerpmac"};
    int seen = 0;
    for (size_t k = 0; k < sizeof names / sizeof names[0]; ++k) {
        const int f = sc_export_format_from_name(names[k]);
        assert_true(f >= 0 && f < 31);
        assert_int_equal(seen & (1 << f), 0); /* one format per name */
        seen |= 1 << f;
    }
    assert_int_equal(sc_export_format_from_name("acs"), -1);
    assert_int_equal(sc_export_format_from_name("Beckhoff"), -1);
    sc_lut *m = make_map(13, 9, -12.0, 4.0, 2.0, 2.5, 0);
    sc_export_options o;
    sc_export_report rep;
    sc_error err;
    sc_export_options_init(&o, (sc_export_format)99);
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_E_INPUT);
    assert_non_null(strstr(err.msg, "unknown export format"));
    /* Automation1 and Power PMAC: the map's own nodes, so only their units remain; a dry run. */
    for (int f = 0; f < 2; ++f) {
        const sc_export_format fmt = f == 0 ? SC_EXPORT_AEROTECH_A1 : SC_EXPORT_POWERPMAC;
        const double unit_um = f == 0 ? SC_EXPORT_AEROTECH_UNIT_UM : 1e-6;
        for (int negate = 0; negate < 2; ++negate) {
            sc_export_options_init(&o, fmt);
            o.negate = negate;
            assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
            assert_int_equal(rep.tables, f == 0 ? 1 : 2);
            assert_int_equal(rep.points[0], 13);
            assert_int_equal(rep.points[1], 9);
            assert_true(rep.max_um <= 0.5 * unit_um + 1e-12);
            assert_true(rep.samples == 2L * (4 * 12 + 1) * (4 * 8 + 1));
            assert_int_equal(rep.clipped, 0);
        }
        /* a limit clips and counts; an interval is refused (the table is the map's nodes) */
        sc_export_options_init(&o, fmt);
        o.limit_um = 0.5;
        assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
        long over = 0;
        for (int k = 0; k < m->nx * m->ny; ++k)
            over += (fabs(m->gx_um[k]) > 0.5) + (fabs(m->gy_um[k]) > 0.5);
        assert_true(over > 0);
        assert_int_equal(rep.clipped, over);
        assert_true(rep.max_um > 0.1);
        o.limit_um = 0;
        o.interval_mm = 1.0;
        assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_E_INPUT);
    }
    /* Power PMAC: motor units per mm scale the values, not the residual */
    sc_export_options_init(&o, SC_EXPORT_POWERPMAC);
    o.steps_per_mm[0] = 10000;
    o.steps_per_mm[1] = 20000;
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_OK);
    assert_true(rep.max_um <= 0.5e-6 / 10000 + 1e-12);
    o.steps_per_mm[0] = -1;
    assert_int_equal(sc_export_write(m, &o, NULL, &rep, &err), SC_E_INPUT);
    free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_beckhoff),
        cmocka_unit_test(test_siemens),
        cmocka_unit_test(test_linuxcnc),
        cmocka_unit_test(test_beckhoff_cross),
        cmocka_unit_test(test_backends),
        cmocka_unit_test(test_kmotion_report),
        cmocka_unit_test(test_aerotech_1d),
        cmocka_unit_test(test_kmotion_table),
        cmocka_unit_test(test_firmware_skew_as_written),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
