/* selfcal simulate exports — turn a selfcal-grid v1 or selfcal-profile v1 file into what a
 * measuring machine would have written: one file per view (grid) or per scan (profile), with the
 * machine's own column names, µm, ';' and decimal commas, points shuffled, marks missing and
 * stray points, so that `selfcal import` (and the guide, the demo and the tests) start where a
 * user starts. */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "cli_opts.h"
#include "input_once.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_io.h"
#include "selfcal/profile.h"
#include "selfcal/rng.h"

static const char USAGE[] =
    "usage: selfcal simulate exports IN.csv --dir DIR [--units um|mm] [--style semicolon|comma|tab]\n"
    "                                [--missing I,J[@V] ...] [--stray V ...] [--seed 1]\n"
    "                                [--displace I,J@V:DX,DY ...]\n"
    "\n"
    "IN.csv: a selfcal-grid v1 file (e.g. from selfcal simulate grid) or a selfcal-profile v1 file.\n"
    "Grid: writes DIR/viewK.csv per view K with columns Nr, X, Y, Z (X, Y the measured mark centre\n"
    "in --units, default um; Z = 0), the points in random order (--seed), without plate mark (I,J)\n"
    "for each --missing I,J (every view; I,J@V: view V only) and with one stray point (half a pitch\n"
    "off a mark diagonally, i.e. farther than a quarter pitch from every mark) for each --stray V,\n"
    "and mark (I,J) of view V measured DX,DY um off (a smudge: an outlier) for each --displace.\n"
    "Prints the matching `selfcal import grid` command on stdout.\n"
    "Profile: writes DIR/scan1.csv and DIR/scan2.csv with columns Position (mm), SensorA, SensorB\n"
    "(um) and Angle (urad), and prints the matching `selfcal import profile` command.\n"
    "--style semicolon (default): ';' and decimal commas; comma: ',' and '.'; tab: tabs and '.'.\n";

/* Plans of up to this many views keep their files open until the group's commit (anonymous
 * temporaries: a kill leaves nothing); larger ones park each file once written (closed, complete
 * under its temporary name: a kill -9 can leave those, which the next export of the same names
 * removes). */
enum { EXPORTS_OPEN_MAX = 16 };

typedef struct style {
    char delim, decimal;
} style;

static void put_num(FILE *fp, double v, const char *fmt, const style *s)
{
    char buf[64];
    snprintf(buf, sizeof buf, fmt, v);
    if (s->decimal == ',')
        for (char *c = buf; *c; ++c)
            if (*c == '.')
                *c = ',';
    fputs(buf, fp);
}

/* dir made if it is not there (*created: 1 if made here, for undo_dir); 0, or -1 with err. */
static int make_dir(const char *dir, int *created, sc_error *err)
{
    *created = mkdir(dir, 0777) == 0;
    if (!*created && errno != EEXIST) {
        sc_error_set(err, SC_E_IO, dir, 0, "cannot create the directory: %s", strerror(errno));
        return -1;
    }
    return 0;
}

/* The directory made for outputs that were not written: removed again (it is empty: every
 * temporary file was removed). */
static void undo_dir(const char *dir, int created, sc_status st)
{
    if (created && st != SC_OK)
        rmdir(dir);
}

typedef struct missing_mark {
    long i, j, view; /* view -1: every view */
    double dx_um, dy_um; /* --displace: the offset of this mark in this view */
} missing_mark;

/* The damage asked for: missing marks, displaced marks, stray points per view. */
typedef struct {
    const missing_mark *miss, *disp;
    int n_miss, n_disp;
    const int *stray;
    int n_stray;
} damage;

/* Every damaged mark and stray view exists in plan p. */
static int check_damage(const sc_grid_plan *p, const damage *dm)
{
    for (int k = 0; k < dm->n_miss; ++k)
        if (dm->miss[k].i >= p->n || dm->miss[k].j >= p->n || dm->miss[k].view >= p->n_views)
            return dm->miss[k].view < 0
                       ? cli_usage_error("simulate exports", "--missing %ld,%ld: no such mark",
                                         dm->miss[k].i, dm->miss[k].j)
                       : cli_usage_error("simulate exports",
                                         "--missing %ld,%ld@%ld: no such mark or view",
                                         dm->miss[k].i, dm->miss[k].j, dm->miss[k].view);
    for (int k = 0; k < dm->n_disp; ++k)
        if (dm->disp[k].i >= p->n || dm->disp[k].j >= p->n || dm->disp[k].view >= p->n_views)
            return cli_usage_error("simulate exports", "--displace %ld,%ld@%ld: no such mark or view",
                                   dm->disp[k].i, dm->disp[k].j, dm->disp[k].view);
    for (int k = 0; k < dm->n_stray; ++k)
        if (dm->stray[k] >= p->n_views)
            return cli_usage_error("simulate exports", "--stray %d: no such view", dm->stray[k]);
    return CLI_OK;
}

/* View v's points (x, y in mm) as a measuring machine reports them: missing marks dropped,
 * displaced ones moved, stray points added, all in a random order. Returns their count. */
static long view_points(const sc_grid_data *d, int v, const damage *dm, sc_rng *rng, double *pts)
{
    const sc_grid_plan *p = &d->plan;
    long np = 0;
    for (int i = 0; i < p->n; ++i)
        for (int j = 0; j < p->n; ++j) {
            double dx = d->dx_um[v][(long)i * p->n + j], dy = d->dy_um[v][(long)i * p->n + j];
            int ni, nj, drop = 0;
            if (isnan(dx) || !sc_grid_mark_node(p, v, i, j, &ni, &nj))
                continue;
            for (int k = 0; k < dm->n_miss; ++k)
                drop |= dm->miss[k].i == i && dm->miss[k].j == j &&
                        (dm->miss[k].view < 0 || dm->miss[k].view == v);
            if (drop)
                continue;
            double x, y;
            sc_grid_node_xy_mm(p, ni, nj, &x, &y);
            for (int k = 0; k < dm->n_disp; ++k)
                if (dm->disp[k].i == i && dm->disp[k].j == j && dm->disp[k].view == v)
                    dx += dm->disp[k].dx_um, dy += dm->disp[k].dy_um;
            pts[2 * np] = p->origin_mm[0] + x + dx * 1e-3;
            pts[2 * np + 1] = p->origin_mm[1] + y + dy * 1e-3;
            ++np;
        }
    for (int k = 0; k < dm->n_stray; ++k)
        if (dm->stray[k] == v && np > 0) {
            long q = (long)(sc_rng_uniform(rng) * np) % np;
            pts[2 * np] = pts[2 * q] + 0.5 * p->pitch_mm;
            pts[2 * np + 1] = pts[2 * q + 1] + 0.5 * p->pitch_mm;
            ++np;
        }
    for (long q = np - 1; q > 0; --q) { /* Fisher-Yates */
        long r = (long)(sc_rng_uniform(rng) * (q + 1)) % (q + 1);
        double tx = pts[2 * q], ty = pts[2 * q + 1];
        pts[2 * q] = pts[2 * r], pts[2 * q + 1] = pts[2 * r + 1];
        pts[2 * r] = tx, pts[2 * r + 1] = ty;
    }
    return np;
}

/* One view's file: Nr, X, Y, Z in the machine's unit and style. */
static void print_view_file(FILE *fp, const double *pts, long np, double unit_per_mm,
                            const style *sty)
{
    const char *fmt = unit_per_mm == 1 ? "%.15f" : "%.12f";
    fprintf(fp, "Nr%cX%cY%cZ\n", sty->delim, sty->delim, sty->delim);
    for (long q = 0; q < np; ++q) {
        fprintf(fp, "%ld%c", q + 1, sty->delim);
        put_num(fp, pts[2 * q] * unit_per_mm, fmt, sty);
        fputc(sty->delim, fp);
        put_num(fp, pts[2 * q + 1] * unit_per_mm, fmt, sty);
        fputc(sty->delim, fp);
        put_num(fp, 0.0, "%.3f", sty);
        fputc('\n', fp);
    }
}

/* The `selfcal import grid` command that reads the files back. */
static void print_import_command(const sc_grid_plan *p, const char *dir, double unit_per_mm)
{
    printf("selfcal import grid --n %d --pitch-mm %.17g", p->n, p->pitch_mm);
    if (p->origin_mm[0] != 0 || p->origin_mm[1] != 0)
        printf(" --origin-mm %.17g,%.17g", p->origin_mm[0], p->origin_mm[1]);
    if (p->stage_nx || p->stage_ny)
        printf(" --stage %d,%d", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    printf(" --units %s --x-col X --y-col Y", unit_per_mm == 1 ? "mm" : "um");
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        printf(" \\\n  --view \"rot=%d shift=%d,%d", w->rot_deg, w->shift_x, w->shift_y);
        for (int pass = 0; w->restricted && pass < 2; ++pass) {
            const unsigned char *sel = pass ? w->col_sel : w->row_sel;
            int first = 1;
            for (int q = 0; q < p->n; ++q)
                if (sel[q]) {
                    printf("%s%d", first ? (pass ? " cols=" : " rows=") : ",", q);
                    first = 0;
                }
        }
        if (w->sigma_um > 0)
            printf(" sigma_um=%.17g", w->sigma_um);
        printf("\" %s/view%d.csv", dir, v);
    }
    printf(" \\\n  -o IN.csv\n");
}

/* DIR/NAMEk.csv for k = first..first+count-1 against the input (argv): -1 if none is it, else the
 * usage error's exit status. */
static int check_names(const char *dir, const char *name, int first, int count, int argc,
                       char **argv)
{
    for (int k = first; k < first + count; ++k) {
        char path[1024];
        snprintf(path, sizeof path, "%s/%s%d.csv", dir, name, k);
        int rc = cli_check_derived_output("simulate exports", "--dir", "--dir", path, argc, argv);
        if (rc >= 0)
            return rc;
    }
    return -1;
}

static int grid_exports(const char *in, const char *dir, double unit_per_mm, const style *sty,
                        const missing_mark *miss, int n_miss, const missing_mark *disp,
                        int n_disp, const int *stray, int n_stray, uint64_t seed, int argc,
                        char **argv)
{
    const damage dm = {miss, disp, n_miss, n_disp, stray, n_stray};
    sc_error err;
    sc_error_clear(&err);
    sc_grid_data d;
    memset(&d, 0, sizeof d);
    sc_status st = sc_grid_read(in, &d, NULL, &err);
    if (st != SC_OK)
        return cli_report(&err);
    const sc_grid_plan *p = &d.plan;
    int rc = check_names(dir, "view", 0, p->n_views, argc, argv);
    rc = rc >= 0 ? rc : check_damage(p, &dm);
    int created = 0;
    if (rc == CLI_OK && make_dir(dir, &created, &err))
        rc = cli_report(&err);
    if (rc != CLI_OK) {
        sc_grid_data_free(&d);
        return rc;
    }
    sc_rng rng;
    sc_rng_seed(&rng, seed);
    double *pts = malloc((size_t)((long)p->n * p->n + n_stray) * 2 * sizeof(double));
    /* one file per view, committed as one group: every view file or none; beyond
     * EXPORTS_OPEN_MAX views each is parked once written (a plan of thousands of views holds one
     * descriptor) */
    sc_afile *f = calloc((size_t)p->n_views, sizeof *f); /* entries not opened stay closed */
    int opened = 0;
    if (!pts || !f)
        st = sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory");
    for (int v = 0; v < p->n_views && st == SC_OK; ++v) {
        long np = view_points(&d, v, &dm, &rng, pts);
        char path[1024];
        snprintf(path, sizeof path, "%s/view%d.csv", dir, v);
        st = sc_afile_open(&f[v], path, &err);
        if (st != SC_OK)
            break;
        opened = v + 1;
        print_view_file(f[v].fp, pts, np, unit_per_mm, sty);
        if (p->n_views > EXPORTS_OPEN_MAX) /* closed now, renamed with the others at the end */
            st = sc_afile_park(&f[v], &err);
    }
    if (f)
        st = sc_afile_finish_all(f, opened, st, &err);
    undo_dir(dir, created, st);
    if (st == SC_OK)
        print_import_command(p, dir, unit_per_mm);
    free(f);
    free(pts);
    sc_grid_data_free(&d);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}

static int profile_exports(const char *in, const char *dir, const style *sty, int argc,
                           char **argv)
{
    int rc = check_names(dir, "scan", 1, 2, argc, argv);
    if (rc >= 0)
        return rc;
    sc_error err;
    sc_error_clear(&err);
    sc_profile_data d;
    memset(&d, 0, sizeof d);
    sc_status st = sc_profile_read(in, &d, &err);
    if (st != SC_OK)
        return cli_report(&err);
    int created = 0;
    if (make_dir(dir, &created, &err)) {
        sc_profile_data_free(&d);
        return cli_report(&err);
    }
    sc_afile f[2];
    memset(f, 0, sizeof f);
    int opened = 0;
    for (int k = 0; k < 2 && st == SC_OK; ++k) {
        char path[1024];
        snprintf(path, sizeof path, "%s/scan%d.csv", dir, k + 1);
        st = sc_afile_open(&f[k], path, &err);
        if (st != SC_OK)
            break;
        opened = k + 1;
        char dl = sty->delim;
        fprintf(f[k].fp, "Position%cSensorA%cSensorB%cAngle\n", dl, dl, dl);
        for (int q = 0; q < d.n - d.d[k]; ++q) {
            put_num(f[k].fp, q * d.s_mm, "%.6f", sty);
            fputc(dl, f[k].fp);
            put_num(f[k].fp, d.m1_um[k][q], "%.17g", sty);
            fputc(dl, f[k].fp);
            put_num(f[k].fp, d.m2_um[k][q], "%.17g", sty);
            fputc(dl, f[k].fp);
            put_num(f[k].fp, d.m3_urad[k][q], "%.17g", sty);
            fputc('\n', f[k].fp);
        }
    }
    st = sc_afile_finish_all(f, opened, st, &err);
    undo_dir(dir, created, st);
    if (st == SC_OK)
        printf("selfcal import profile --spacing-mm %.17g %s/scan1.csv --spacing-mm %.17g %s/scan2.csv \\\n"
               "  --pos-col Position --m1-col SensorA --m2-col SensorB --m3-col Angle -o IN.csv\n",
               d.d[0] * d.s_mm, dir, d.d[1] * d.s_mm, dir);
    sc_profile_data_free(&d);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}

/* The command line, as given. */
typedef struct {
    const char *in, *dir;
    double unit_per_mm;
    style sty;
    missing_mark miss[64], disp[64];
    int stray[64], n_miss, n_disp, n_stray;
    uint64_t seed;
} exports_args;

/* --missing I,J[@V] */
static int parse_missing(const char *cmd, const char *opt, const char *v, void *field)
{
    exports_args *a = field;
    (void)opt;
    char buf[128];
    snprintf(buf, sizeof buf, "%s", v);
    char *at = strchr(buf, '@'), *comma = strchr(buf, ',');
    long view = -1;
    if (at) {
        *at = '\0';
        if (sc_parse_long(at + 1, &view) || view < 0)
            return cli_usage_error(cmd, "--missing I,J[@V], got '%s'", v);
    }
    if (!comma || a->n_miss == 64)
        return cli_usage_error(cmd, "--missing I,J[@V] (at most 64), got '%s'", v);
    *comma = '\0';
    missing_mark m = {0, 0, view, 0, 0};
    if (sc_parse_long(buf, &m.i) || sc_parse_long(comma + 1, &m.j) || m.i < 0 || m.j < 0)
        return cli_usage_error(cmd, "--missing I,J[@V], got '%s'", v);
    a->miss[a->n_miss++] = m;
    return CLI_OK;
}

/* --displace I,J@V:DX,DY (µm) */
static int parse_displace(const char *cmd, const char *opt, const char *v, void *field)
{
    exports_args *a = field;
    (void)opt;
    char buf[128];
    missing_mark m = {0, 0, 0, 0, 0};
    snprintf(buf, sizeof buf, "%s", v);
    char *at = strchr(buf, '@');
    char *colon = at ? strchr(at, ':') : NULL;
    char *c1 = strchr(buf, ',');
    char *c2 = colon ? strchr(colon, ',') : NULL;
    if (!at || !colon || !c1 || c1 > at || !c2 || a->n_disp == 64)
        return cli_usage_error(cmd, "--displace I,J@V:DX,DY (um; at most 64), got '%s'", v);
    *c1 = *at = *colon = *c2 = '\0';
    if (sc_parse_long(buf, &m.i) || sc_parse_long(c1 + 1, &m.j) ||
        sc_parse_long(at + 1, &m.view) || sc_parse_double(colon + 1, &m.dx_um) ||
        sc_parse_double(c2 + 1, &m.dy_um) || m.i < 0 || m.j < 0 || m.view < 0 ||
        fabs(m.dx_um) > 1e5 || fabs(m.dy_um) > 1e5)
        return cli_usage_error(cmd, "--displace I,J@V:DX,DY (um), got '%s'", v);
    a->disp[a->n_disp++] = m;
    return CLI_OK;
}

/* --units mm|um into the double (units per mm) */
static int parse_units(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    if (!strcmp(v, "mm")) *(double *)field = 1;
    else if (!strcmp(v, "um")) *(double *)field = 1000;
    else return cli_usage_error(cmd, "--units mm or um, got '%s'", v);
    return CLI_OK;
}

/* --style semicolon|comma|tab into the style */
static int parse_style(const char *cmd, const char *opt, const char *v, void *field)
{
    style *sty = field;
    (void)opt;
    if (!strcmp(v, "semicolon")) *sty = (style){';', ','};
    else if (!strcmp(v, "comma")) *sty = (style){',', '.'};
    else if (!strcmp(v, "tab")) *sty = (style){'\t', '.'};
    else return cli_usage_error(cmd, "--style semicolon, comma or tab, got '%s'", v);
    return CLI_OK;
}

/* --stray V, one more into the exports_args */
static int parse_stray(const char *cmd, const char *opt, const char *v, void *field)
{
    exports_args *a = field;
    long s;
    (void)opt;
    if (sc_parse_long(v, &s) || s < 0 || a->n_stray == 64)
        return cli_usage_error(cmd, "--stray V (a view index, at most 64 times), got '%s'", v);
    a->stray[a->n_stray++] = (int)s;
    return CLI_OK;
}

#define F(field) offsetof(exports_args, field)
/* simulate exports' options (cli_opts.h), in the order of its --help */
static const cli_opt SIM_EXPORTS_OPTS[] = {
    {"--dir", CLI_STRING, F(dir), "DIR", .help = "the folder written (required)"},
    {"--units", CLI_CUSTOM, F(unit_per_mm), "mm|um", .choices = "mm|um", .parse = parse_units,
     .def = "um", .help = "the positions' unit"},
    {"--style", CLI_CUSTOM, F(sty), "semicolon|comma|tab", .choices = "semicolon|comma|tab",
     .parse = parse_style, .def = "semicolon", .help = "the delimiter and decimal mark"},
    {"--missing", CLI_CUSTOM, 0, "I,J[@V]", .parse = parse_missing,
     .help = "a mark left out (of view V; repeatable, at most 64)"},
    {"--stray", CLI_CUSTOM, 0, "V", .parse = parse_stray,
     .help = "a stray point in view V (repeatable, at most 64)"},
    {"--displace", CLI_CUSTOM, 0, "I,J@V:DX,DY", .parse = parse_displace,
     .help = "a mark of view V moved by DX,DY um (repeatable, at most 64)"},
    {"--seed", CLI_CUSTOM, F(seed), "S", .parse = cli_opt_seed, .def = "1",
     .help = "the seed, 0 to 2^64-1"},
};
#undef F

const cli_cmd_opts cli_simulate_exports_opts = {
    "simulate exports", USAGE, SIM_EXPORTS_OPTS,
    (int)(sizeof SIM_EXPORTS_OPTS / sizeof SIM_EXPORTS_OPTS[0]), offsetof(exports_args, in), NULL,
    "one input file, got '%s' and '%s'", "unknown option or missing value: '%s' (see --help)",
    NULL, 0, NULL, NULL,
};

int cmd_simulate_exports(int argc, char **argv)
{
    const char *cmd = "simulate exports";
    static exports_args a;
    memset(&a, 0, sizeof a);
    a.unit_per_mm = 1000;
    a.sty = (style){';', ','};
    a.seed = 1;
    int rc = cli_opts_parse(&cli_simulate_exports_opts, argc, argv, &a);
    if (rc >= 0)
        return rc;
    if (!a.in || !a.dir)
        return cli_usage_error(cmd, "IN.csv and --dir DIR are required (see --help)");
    /* which format: the first line says */
    sc_error err;
    sc_error_clear(&err);
    cli_input src; /* looked at, then read: a pipe from its in-memory copy */
    if (cli_input_open(&src, a.in, 1, &err) != SC_OK)
        return cli_report(&err);
    FILE *fp = sc_open_input(src.path, &err);
    if (!fp) {
        rc = cli_report(&err);
        cli_input_close(&src);
        return rc;
    }
    char first[64] = "";
    if (!fgets(first, sizeof first, fp))
        first[0] = '\0';
    fclose(fp);
    rc = !strncmp(first, "# selfcal-profile v1", 20)
                 ? profile_exports(src.path, a.dir, &a.sty, argc, argv)
                 : grid_exports(src.path, a.dir, a.unit_per_mm, &a.sty, a.miss, a.n_miss, a.disp,
                                a.n_disp, a.stray, a.n_stray, (uint64_t)a.seed, argc, argv);
    cli_input_close(&src);
    return rc;
}
