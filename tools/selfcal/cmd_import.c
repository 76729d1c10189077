/* selfcal import grid|profile — measuring machines' exports into selfcal's input files (SPEC §10):
 * per-view lists of mark centres numbered by fitting each view's placement (libselfcal's
 * selfcal/import.h), and the two scans' sensor logs of a straightness measurement checked for
 * constant step, gaps and spacings. Options and checks: docs/import.md. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/import.h"
#include "selfcal/profile.h"

static const char GRID_USAGE[] =
    "usage: selfcal import grid --n N --pitch-mm P [--origin-mm X,Y] [--stage NX,NY]\n"
    "                           --view \"rot=R shift=SX,SY [rows=..] [cols=..]\" FILE\n"
    "                           [--view \"...\" FILE ...] -o OUT.csv\n"
    "                           [--x-col x] [--y-col y] [--units mm|um] [--tolerance-mm P/4]\n"
    "                           [--min-share 0.5] [--ux-col NAME --uy-col NAME]\n"
    "                           [--id-col NAME --axis-col NAME --value-col NAME\n"
    "                            [--axis-names X,Y]] [--where COL=VALUE ...] [--missing TOKEN ...]\n"
    "                           [--no-header] [--transpose] [--encoding utf-8|cp1252|latin-1|shift-jis]\n"
    "                           [--deviations --nominal-x-col NAME --nominal-y-col NAME]\n"
    "\n"
    "Numbers the measured mark centres of each view (one FILE per view, points in any order) and\n"
    "writes a selfcal-grid v1 file with the views in the order given. FILE: a header line naming\n"
    "the columns, then one point per line; delimiter ',', ';', tab or aligning blanks and decimal\n"
    "mark '.' or ',' are detected; other columns are ignored; positions in --units in the stage\n"
    "frame. A column may be given by its number (--x-col 2) where two share a name. Units lines,\n"
    "repeated headers, rows without values, summary rows (Mean, Max, ...) and a footer are\n"
    "skipped and named on stderr.\n"
    "--ux-col/--uy-col: columns of each point's standard uncertainty (k = 1, in --units), written\n"
    "as ux_um,uy_um (SPEC §5); a view's sigma_um=S (µm) is passed on to its view line.\n"
    "One row per axis (PC-DMIS, CALYPSO, GEOPAK): --id-col, --axis-col, --value-col; rows with\n"
    "one ID form a point, the AXIS value names the coordinate (X and Y, or --axis-names).\n"
    "With --deviations the values are in --units, the nominal columns in mm. Warnings: every\n"
    "point on its nominal position (nominal columns?), and values rounded coarser than the noise\n"
    "(export more decimals).\n"
    "Each view's placement (translation + rotation) is fitted robustly from its points, then every\n"
    "point goes to the nearest mark the view measures. Points farther than --tolerance-mm from\n"
    "every mark are reported and left out; marks without a point are reported and absent.\n"
    "Bad input (exit 2, no output): a missing column, two points on one mark, a view where fewer\n"
    "than --min-share of its points (or none) fall on a mark, mixed decimal marks.\n";

static const char PROFILE_USAGE[] =
    "usage: selfcal import profile --spacing-mm D1 FILE1 --spacing-mm D2 FILE2 -o OUT.csv\n"
    "                              [--step-mm S] [--pos-col position] [--m1-col m1]\n"
    "                              [--m2-col m2] [--m3-col m3] [--pos-units mm|um]\n"
    "                              [--disp-units um|nm|mm] [--angle-units urad|mrad|arcsec]\n"
    "                              [--step-tolerance 0.1] [--sigma-disp-um S]\n"
    "                              [--sigma-angle-urad S]\n"
    "\n"
    "The layout options are those of import grid; one row per axis: the AXIS values are the four\n"
    "columns' names or --axis-names P,M1,M2,M3.\n"
    "\n"
    "Turns the sensor logs of the two scans of a straightness measurement (SPEC §2) into a\n"
    "selfcal-profile v1 file. FILEk: the log of scan k with sensor spacing Dk: a header line naming\n"
    "the columns, then one sample per line (any order): the stage position (sensor 1's place),\n"
    "displacement sensors 1 and 2 (sensor 2 is Dk ahead of sensor 1 in +position) and the angle\n"
    "sensor. Delimiter and decimal mark are detected as for import grid.\n"
    "Checked: the step S (default: the median step of scan 1) is constant (every position within\n"
    "--step-tolerance steps of the grid), no gaps or repeated positions, both scans start at the\n"
    "same position, each Dk is a whole number of steps, and both scans cover the same profile\n"
    "(samples_k + dk equal). Any failure is bad input (exit 2, FILE:LINE, no output).\n";

static int parse_pair_long(const char *s, long *a, long *b)
{
    char buf[128];
    snprintf(buf, sizeof buf, "%s", s);
    char *comma = strchr(buf, ',');
    if (!comma)
        return -1;
    *comma = '\0';
    return sc_parse_long(sc_str_trim(buf), a) || sc_parse_long(sc_str_trim(comma + 1), b) ? -1 : 0;
}

static int parse_pair_double(const char *s, double *a, double *b)
{
    char buf[128];
    snprintf(buf, sizeof buf, "%s", s);
    char *comma = strchr(buf, ',');
    if (!comma)
        return -1;
    *comma = '\0';
    return sc_parse_double(sc_str_trim(buf), a) || sc_parse_double(sc_str_trim(comma + 1), b) ? -1
                                                                                                : 0;
}

/* Parse a comma list of plate indices into sel (n entries). */
static int parse_selection(const char *s, int n, unsigned char *sel)
{
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", s);
    for (char *tok = buf; tok;) {
        char *comma = strchr(tok, ',');
        if (comma)
            *comma = '\0';
        long k;
        if (sc_parse_long(sc_str_trim(tok), &k) || k < 0 || k >= n)
            return -1;
        sel[k] = 1;
        tok = comma ? comma + 1 : NULL;
    }
    return 0;
}

/* "rot=R shift=SX,SY [rows=..] [cols=..]" -> v (n: plate size, for rows/cols). */
static int parse_view(const char *spec, int n, sc_grid_view *v, char *sigma, size_t sigma_len)
{
    sigma[0] = '\0';
    char buf[4096];
    if (strlen(spec) >= sizeof buf)
        return cli_usage_error("import grid", "--view: too long");
    snprintf(buf, sizeof buf, "%s", spec);
    memset(v, 0, sizeof *v);
    int have_rot = 0, have_shift = 0;
    for (char *tok = strtok(buf, " \t"); tok; tok = strtok(NULL, " \t")) {
        char *eq = strchr(tok, '=');
        if (!eq)
            return cli_usage_error("import grid", "--view \"%s\": '%s' is not key=value", spec, tok);
        *eq = '\0';
        const char *val = eq + 1;
        long a, b;
        if (!strcmp(tok, "rot")) {
            if (sc_parse_long(val, &a) || (a != 0 && a != 90 && a != 180 && a != 270))
                return cli_usage_error("import grid", "--view \"%s\": rot must be 0, 90, 180 or 270",
                                       spec);
            v->rot_deg = (int)a;
            have_rot = 1;
        } else if (!strcmp(tok, "shift")) {
            if (parse_pair_long(val, &a, &b) || labs(a) > 4 * SC_GRID_MAX_N ||
                labs(b) > 4 * SC_GRID_MAX_N)
                return cli_usage_error("import grid",
                                       "--view \"%s\": shift must be SX,SY (whole pitches)", spec);
            v->shift_x = (int)a;
            v->shift_y = (int)b;
            have_shift = 1;
        } else if (!strcmp(tok, "sigma_um")) {
            double sg;
            if (sc_parse_double(val, &sg) || !sc_grid_sigma_valid(sg) || strlen(val) >= sigma_len)
                return cli_usage_error("import grid", "--view \"%s\": sigma_um must be %g to %g um",
                                       spec, SC_GRID_MIN_SIGMA_UM, SC_INPUT_MAX_ABS);
            snprintf(sigma, sigma_len, "%s", val);
        } else if (!strcmp(tok, "rows") || !strcmp(tok, "cols")) {
            v->restricted = 1;
            if (parse_selection(val, n, tok[0] == 'r' ? v->row_sel : v->col_sel))
                return cli_usage_error("import grid",
                                       "--view \"%s\": %s must list plate indices in 0..%d", spec,
                                       tok, n - 1);
        } else {
            return cli_usage_error("import grid", "--view \"%s\": unknown attribute '%s'", spec, tok);
        }
    }
    if (!have_rot || !have_shift)
        return cli_usage_error("import grid", "--view \"%s\": needs rot=R and shift=SX,SY", spec);
    return 0;
}

static int parse_units(const char *cmd, const char *opt, const char *v, const char *const *names,
                       const double *factors, int count, double *out)
{
    for (int k = 0; k < count; ++k)
        if (!strcmp(v, names[k])) {
            *out = factors[k];
            return 0;
        }
    return cli_usage_error(cmd, "%s: unknown unit '%s'", opt, v);
}

/* The layout options both commands take (SPEC §10a). */
typedef struct layout_args {
    sc_table_layout lay;
    char where_buf[SC_TABLE_MAX_WHERE][256];
    char axis_buf[512];
    const char *axis[4]; /* --axis-names, split */
    int n_axis;
    int deviations;
    const char *nominal[2]; /* --nominal-x-col, --nominal-y-col */
} layout_args;

/* --no-header, --transpose: the layout's bool set */
static int set_bool(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)cmd, (void)opt, (void)v;
    *(bool *)field = true;
    return CLI_OK;
}

/* --axis-names A,B[,C,D] into the layout_args */
static int parse_axis_names(const char *cmd, const char *opt, const char *v, void *field)
{
    layout_args *l = field;
    (void)opt;
    if (strlen(v) >= sizeof l->axis_buf)
        return cli_usage_error(cmd, "--axis-names: too long");
    snprintf(l->axis_buf, sizeof l->axis_buf, "%s", v);
    l->n_axis = 0;
    for (char *tok = l->axis_buf; tok && l->n_axis < 5;) {
        char *comma = strchr(tok, ',');
        if (comma)
            *comma = '\0';
        if (l->n_axis == 4 || !*sc_str_trim(tok))
            return cli_usage_error(cmd, "--axis-names needs names separated by commas "
                                        "(X,Y), got '%s'", v);
        l->axis[l->n_axis++] = sc_str_trim(tok);
        tok = comma ? comma + 1 : NULL;
    }
    return CLI_OK;
}

/* --where COL=VALUE, one more into the layout_args */
static int parse_where(const char *cmd, const char *opt, const char *v, void *field)
{
    layout_args *l = field;
    sc_table_layout *y = &l->lay;
    (void)opt;
    const char *eq = strchr(v, '=');
    if (!eq || eq == v || strlen(v) >= sizeof l->where_buf[0])
        return cli_usage_error(cmd, "--where needs COL=VALUE, got '%s'", v);
    if (y->n_where == SC_TABLE_MAX_WHERE)
        return cli_usage_error(cmd, "at most %d --where", SC_TABLE_MAX_WHERE);
    char *b = l->where_buf[y->n_where];
    snprintf(b, sizeof l->where_buf[0], "%s", v);
    b[eq - v] = '\0';
    y->where_col[y->n_where] = sc_str_trim(b);
    y->where_value[y->n_where++] = sc_str_trim(b + (eq - v) + 1);
    return CLI_OK;
}

/* --missing TOKEN, one more into the sc_table_layout */
static int parse_missing(const char *cmd, const char *opt, const char *v, void *field)
{
    sc_table_layout *y = field;
    (void)opt;
    if (y->n_missing == SC_TABLE_MAX_MISSING)
        return cli_usage_error(cmd, "at most %d --missing", SC_TABLE_MAX_MISSING);
    if (!v[0])
        return cli_usage_error(cmd, "--missing needs a token (empty fields are always empty)");
    y->missing[y->n_missing++] = v;
    return CLI_OK;
}

/* --encoding NAME into the sc_table_layout */
static int parse_encoding(const char *cmd, const char *opt, const char *v, void *field)
{
    static const char *const names[] = {"utf-8", "utf8", "cp1252", "windows-1252", "latin-1",
                                        "latin1", "iso-8859-1", "shift-jis", "shift_jis",
                                        "sjis", "cp932"};
    static const sc_table_encoding enc[] = {SC_ENC_UTF8, SC_ENC_UTF8, SC_ENC_CP1252,
                                            SC_ENC_CP1252, SC_ENC_LATIN1, SC_ENC_LATIN1,
                                            SC_ENC_LATIN1, SC_ENC_SHIFT_JIS, SC_ENC_SHIFT_JIS,
                                            SC_ENC_SHIFT_JIS, SC_ENC_SHIFT_JIS};
    (void)opt;
    size_t k = 0;
    while (k < sizeof names / sizeof names[0] && strcasecmp(v, names[k]))
        ++k;
    if (k == sizeof names / sizeof names[0])
        return cli_usage_error(cmd, "--encoding: utf-8, cp1252, latin-1 or shift-jis, not '%s'", v);
    ((sc_table_layout *)field)->encoding = enc[k];
    return CLI_OK;
}

/* The layout options both commands take (SPEC §10a), as rows of a table whose argument struct
 * holds the layout_args as lay (F: that table's offsetof). */
#define LAYOUT_ROWS                                                                                \
    {"--id-col", CLI_STRING, F(lay.lay.id_col), "NAME", .help = "one row per axis: the point's ID"}, \
    {"--axis-col", CLI_STRING, F(lay.lay.axis_col), "NAME",                                        \
     .help = "one row per axis: the coordinate's name"},                                           \
    {"--value-col", CLI_STRING, F(lay.lay.value_col), "NAME",                                      \
     .help = "one row per axis: the value"},                                                       \
    {"--axis-names", CLI_CUSTOM, F(lay), "A,B[,...]", .parse = parse_axis_names,                   \
     .help = "one row per axis: the AXIS values of the coordinates, in order"},                    \
    {"--where", CLI_CUSTOM, F(lay), "COL=VALUE", .parse = parse_where,                             \
     .help = "only the rows with VALUE in COL (repeatable)"},                                      \
    {"--missing", CLI_CUSTOM, F(lay.lay), "TOKEN", .parse = parse_missing,                         \
     .help = "a placeholder of a value not measured (repeatable)"},                                \
    {"--no-header", CLI_FLAG, F(lay.lay.no_header), .parse = set_bool,                             \
     .help = "no header line: columns by number"},                                                 \
    {"--transpose", CLI_FLAG, F(lay.lay.transpose), .parse = set_bool,                             \
     .help = "one column per point, rows labelled by their first field"},                          \
    {"--encoding", CLI_CUSTOM, F(lay.lay), "utf-8|cp1252|latin-1|shift-jis",                       \
     .parse = parse_encoding, .def = "utf-8", .help = "the file's character encoding"}

/* The layout's own checks (one row per axis: all three columns). */
static int check_layout(const char *cmd, const layout_args *l)
{
    const sc_table_layout *y = &l->lay;
    int n = !!y->id_col + !!y->axis_col + !!y->value_col;
    if (n != 0 && n != 3)
        return cli_usage_error(cmd, "one row per axis needs --id-col, --axis-col and --value-col");
    if (l->n_axis && !n)
        return cli_usage_error(cmd, "--axis-names goes with --id-col, --axis-col, --value-col");
    if (n && y->transpose)
        return cli_usage_error(cmd, "--transpose and one row per axis do not go together");
    if (y->transpose && y->n_where)
        return cli_usage_error(cmd, "--where filters rows; with --transpose the rows are X and Y "
                                    "(leave the other columns out of the file)");
    return CLI_OK;
}

/* What a read with a layout passed over (sc_table_notes), one stderr line each kind. */
static void report_notes(const char *cmd, const char *file, const sc_table *t,
                         const sc_table_notes *n)
{
    if (n->n_filtered)
        fprintf(stderr, "%s: %s:%ld: %ld row%s left out by --where (the first here)\n", cmd, file,
                n->filtered_line, n->n_filtered, n->n_filtered == 1 ? "" : "s");
    if (n->n_placeholder)
        fprintf(stderr, "%s: %s:%ld: %ld field%s held a --missing placeholder (not measured)\n",
                cmd, file, n->placeholder_line, n->n_placeholder,
                n->n_placeholder == 1 ? "" : "s");
    if (n->n_other_axis)
        fprintf(stderr, "%s: %s: %ld row%s of other axes or characteristics (Z, D, form, ...); "
                        "not read\n", cmd, file, n->n_other_axis, n->n_other_axis == 1 ? "" : "s");
    if (n->n_incomplete)
        fprintf(stderr, "%s: %s:%ld: %ld point%s with only some of its coordinates (a row of an "
                        "axis missing; the first: '%s', no %s value); left out\n", cmd, file,
                n->incomplete_line, n->n_incomplete, n->n_incomplete == 1 ? "" : "s",
                n->incomplete_id, n->incomplete_axis);
    if (n->named_fields < n->header_fields)
        fprintf(stderr, "%s: %s:%ld: the header line ends in %d empty field%s (a trailing tab or "
                        "delimiter); ignored\n", cmd, file, t->header_line,
                n->header_fields - n->named_fields,
                n->header_fields - n->named_fields == 1 ? "" : "s");
    if (n->n_ragged && n->ragged_fields > n->header_fields)
        fprintf(stderr, "%s: %s:%ld: %ld row%s %d fields where the header line (line %ld) has %d: "
                        "the unlabelled fields at the end (no numbers) are ignored\n", cmd, file,
                n->ragged_line, n->n_ragged, n->n_ragged == 1 ? " has" : "s have (the first)",
                n->ragged_fields, t->header_line, n->header_fields);
}

/* One view of an import: its placement, its file and the result of numbering its points. */
typedef struct import_view {
    sc_grid_view v;
    char sigma[64];          /* the view's sigma_um= value as given ("" if none) */
    const char *file;
    sc_table t;
    long *mark_point;        /* per mark: its point, or -1 */
    long *point_mark;        /* per point: its mark, or -1 */
    sc_grid_import_fit fit;
    sc_table_notes notes;
    double nominal_max_mm;   /* the largest distance of an assigned point from its stage node */
} import_view;

static void fprint_view_line(FILE *fp, int k, const sc_grid_view *v, const char *sigma, int n)
{
    fprintf(fp, "# view %d: rot=%d shift=%d,%d", k, v->rot_deg, v->shift_x, v->shift_y);
    if (v->restricted) {
        for (int pass = 0; pass < 2; ++pass) {
            const unsigned char *sel = pass ? v->col_sel : v->row_sel;
            int first = 1;
            for (int q = 0; q < n; ++q)
                if (sel[q]) {
                    fprintf(fp, "%s%d", first ? (pass ? " cols=" : " rows=") : ",", q);
                    first = 0;
                }
        }
    }
    if (sigma[0])
        fprintf(fp, " sigma_um=%s", sigma);
    fputc('\n', fp);
}

/* The lines of a machine's file that were skipped (sc_table_read), one stderr line each kind. */
static void report_skipped(const char *cmd, const char *file, const sc_table *t)
{
    if (t->units_line)
        fprintf(stderr, "%s: %s:%ld: a line of units under the header; skipped\n", cmd, file,
                t->units_line);
    if (t->n_header_repeats)
        fprintf(stderr, "%s: %s:%ld: the header line again (%ld time%s, a page break?); skipped\n",
                cmd, file, t->header_repeat_line, t->n_header_repeats,
                t->n_header_repeats == 1 ? "" : "s");
    if (t->n_no_values)
        fprintf(stderr, "%s: %s:%ld: %ld row%s without any value in the wanted columns (features "
                        "not measured?); skipped\n",
                cmd, file, t->no_values_line, t->n_no_values, t->n_no_values == 1 ? "" : "s");
    if (t->n_summary)
        fprintf(stderr, "%s: %s:%ld: %ld summary row%s (Mean, Max, ...: no measurement); skipped\n",
                cmd, file, t->summary_line, t->n_summary, t->n_summary == 1 ? "" : "s");
    if (t->n_footer)
        fprintf(stderr, "%s: %s:%ld: %ld line%s after the last row %s no row (a footer); "
                        "skipped\n",
                cmd, file, t->footer_line, t->n_footer, t->n_footer == 1 ? "" : "s",
                t->n_footer == 1 ? "is" : "are");
}

/* The warning when the file's values are rounded coarser than the calibration needs: rounding to
 * a step q adds q/sqrt(12) of noise; more than a third of the machine's sigma (the view's
 * sigma_um=, else 0.01 um: a good machine's) is noise the export added. */
static void report_precision(const import_view *iv, int k, double unit_um)
{
    double sigma = 0.01;
    if (iv->sigma[0])
        sc_parse_double(iv->sigma, &sigma);
    int dec = iv->notes.decimals;
    double q = pow(10.0, -dec) * unit_um, noise = q / sqrt(12.0);
    if (!(noise > sigma / 3))
        return;
    int need = dec;
    while (need < 15 && pow(10.0, -need) * unit_um / sqrt(12.0) > sigma / 3)
        ++need;
    fprintf(stderr, "selfcal import grid: %s: view %d: warning: the positions have %d decimal%s "
                    "(steps of %g um): rounding alone adds %.3g um of noise, more than a third of "
                    "sigma_r = %g um%s; export %d decimals or more\n", iv->file, k, dec,
            dec == 1 ? "" : "s", q, noise, sigma, iv->sigma[0] ? " (sigma_um=)" : " (a good "
            "machine's; give the view's sigma_um= for yours)", need);
}

static void report_view(const sc_grid_import_params *p, int k, const import_view *iv,
                        double unit_um)
{
    report_skipped("selfcal import grid", iv->file, &iv->t);
    report_notes("selfcal import grid", iv->file, &iv->t, &iv->notes);
    if (iv->fit.n_assigned > 0 && iv->nominal_max_mm <= 1e-6)
        fprintf(stderr, "selfcal import grid: %s: view %d: warning: every point lies within 1 nm "
                        "of its nominal position: are these the nominal columns (Soll, NOMINAL) "
                        "instead of the measured ones? The calibration of such values means "
                        "nothing\n", iv->file, k);
    report_precision(iv, k, unit_um);
    const long *point_mark = iv->point_mark;
    const sc_grid_import_fit *fit = &iv->fit;
    for (long q = 0; q < iv->t.n_rows; ++q)
        if (point_mark[q] == -2)
            fprintf(stderr,
                    "selfcal import grid: %s:%ld: point (%.6f, %.6f) mm is more than 20 times as far "
                    "from its mark as this view's points are (median %.3f um): left out (a summary "
                    "row? a point on another feature?)\n",
                    iv->file, iv->t.line[q], iv->t.value[iv->t.n_cols * q],
                    iv->t.value[iv->t.n_cols * q + 1], fit->median_dist_um);
        else if (point_mark[q] == -1)
            fprintf(stderr,
                    "selfcal import grid: %s:%ld: point (%.6f, %.6f) mm is farther than %g mm from "
                    "every mark of view %d; left out\n",
                    iv->file, iv->t.line[q], iv->t.value[iv->t.n_cols * q],
                    iv->t.value[iv->t.n_cols * q + 1],
                    p->tolerance_mm, k);
    if (fit->n_unselected) /* point_mark -3, counted by the fit */
        fprintf(stderr, "selfcal import grid: %s: view %d: %ld point%s on marks its rows=/cols= "
                        "leave out; left out\n",
                iv->file, k, fit->n_unselected, fit->n_unselected == 1 ? "" : "s");
    /* a row or column of left-out points on the mark lattice: marks the view does not have,
     * so the file is in the plate's frame (or shift= is wrong) and the numbering is off */
    if (fit->n_on_lattice >= 3 && 2 * fit->n_on_lattice >= p->n)
        fprintf(stderr, "selfcal import grid: %s: view %d: warning: %ld of the points left out lie "
                        "on the mark lattice where this view has no mark: are the positions in the "
                        "plate's frame instead of the stage's, or is shift= wrong? (the numbering "
                        "is then off by the shift)\n",
                iv->file, k, fit->n_on_lattice);
    long missing = 0;
    for (int i = 0; i < p->n; ++i)
        for (int j = 0; j < p->n; ++j) {
            int ni, nj;
            if (!sc_grid_import_mark_node(p, &iv->v, i, j, &ni, &nj) ||
                iv->mark_point[(long)i * p->n + j] >= 0)
                continue;
            if (++missing <= 20)
                fprintf(stderr, "selfcal import grid: %s: view %d: no point for mark (%d,%d); absent\n",
                        iv->file, k, i, j);
        }
    if (missing > 20)
        fprintf(stderr, "selfcal import grid: %s: view %d: ... and %ld more marks without a point\n",
                iv->file, k, missing - 20);
    fprintf(stderr,
            "selfcal import grid: %s: view %d (rot=%d shift=%d,%d): %ld of %ld marks, %ld point%s "
            "left out; placement tx %.3f um, ty %.3f um, theta %.1f urad; farthest point %.3f um "
            "from its mark\n",
            iv->file, k, iv->v.rot_deg, iv->v.shift_x, iv->v.shift_y, fit->n_assigned,
            fit->n_marks, fit->n_left_out, fit->n_left_out == 1 ? "" : "s", fit->tx_um, fit->ty_um,
            fit->theta_urad, fit->max_dist_um);
}

/* import grid's command line, as given. */
typedef struct {
    layout_args lay; /* the layout options (SPEC §10a) */
    const char *out, *xcol, *ycol, *uxcol, *uycol;
    double n_d, pitch, unit_mm, tol, share, ox, oy;
    long snx, sny;
    import_view *views;      /* max_views entries (one per --view the command line can hold) */
    const char **view_spec;
    int n_views, max_views;
} grid_args;

/* The word after an option's value that should be a FILE but is an option (-o, --anything): the
 * FILE was forgotten (a file named so is given as ./-o). */
static int looks_like_option(const char *s)
{
    return (s[0] == '-' && s[1] == '-') || !strcmp(s, "-o");
}

/* --view SPEC FILE: one more view into the grid_args */
static int parse_view_arg(const char *cmd, const char *opt, const char *v, const char *next,
                          void *field)
{
    grid_args *g = field;
    (void)opt;
    if (!next)
        return cli_usage_error(cmd, "--view \"rot=R shift=SX,SY\" must be followed by FILE");
    if (g->n_views == g->max_views || g->n_views == SC_GRID_VIEW_LIMIT)
        return cli_usage_error(cmd, "at most %d views", SC_GRID_VIEW_LIMIT);
    if (looks_like_option(next))
        return cli_usage_error(cmd, "--view \"%s\" must be followed by its FILE, not by the "
                                    "option '%s'", v, next);
    g->view_spec[g->n_views] = v;
    g->views[g->n_views++].file = next;
    return CLI_OK;
}

/* --units mm|um into the double (mm per unit) */
static int parse_grid_units(const char *cmd, const char *opt, const char *v, void *field)
{
    static const char *const names[] = {"mm", "um", "µm"};
    static const double f[] = {1, 1e-3, 1e-3};
    return parse_units(cmd, opt, v, names, f, 3, field) ? CLI_BAD_INPUT : CLI_OK;
}

/* --origin-mm X,Y into the grid_args */
static int parse_origin(const char *cmd, const char *opt, const char *v, void *field)
{
    grid_args *g = field;
    (void)opt;
    if (parse_pair_double(v, &g->ox, &g->oy))
        return cli_usage_error(cmd, "--origin-mm needs X,Y, got '%s'", v);
    return CLI_OK;
}

/* --stage NX,NY (odd, 3 to 4 plates) into the grid_args */
static int parse_stage(const char *cmd, const char *opt, const char *v, void *field)
{
    grid_args *g = field;
    (void)opt;
    if (parse_pair_long(v, &g->snx, &g->sny) || g->snx < 3 || g->sny < 3 || g->snx % 2 == 0 ||
        g->sny % 2 == 0 || g->snx > 4 * SC_GRID_MAX_N || g->sny > 4 * SC_GRID_MAX_N)
        return cli_usage_error(cmd, "--stage needs NX,NY (odd, >= 3), got '%s'", v);
    return CLI_OK;
}

/* An option import grid does not know: a value that is no number is named first. */
static int grid_other(const char *cmd, const char *opt, const char *v, void *args)
{
    double x;
    (void)args;
    if (sc_parse_double(v, &x))
        return cli_usage_error(cmd, "%s needs a number, got '%s'", opt, v);
    return cli_usage_error(cmd, "unknown option '%s' (see --help)", opt);
}

#define F(field) offsetof(grid_args, field)
#define NUMBER(name, f, v, dflt, text)                                                             \
    {name, CLI_DOUBLE, F(f), v, -HUGE_VAL, HUGE_VAL, .bad = "%s needs a number, got '%s'",         \
     .def = dflt, .help = text}
/* import grid's options (cli_opts.h), in the order of its --help */
static const cli_opt IMPORT_GRID_OPTS[] = {
    NUMBER("--n", n_d, "N", NULL, "the plate's marks per side (odd; required)"),
    NUMBER("--pitch-mm", pitch, "P", NULL, "the plate's pitch (mm; required)"),
    {"--origin-mm", CLI_CUSTOM, 0, "X,Y", .parse = parse_origin, .def = "0,0",
     .help = "the stage node (0,0)'s position (mm)"},
    {"--stage", CLI_CUSTOM, 0, "NX,NY", .parse = parse_stage, .def = "the plate's",
     .help = "the stage's nodes (odd)"},
    {"--view", CLI_CUSTOM, 0, "SPEC FILE", .parse2 = parse_view_arg,
     .help = "a view (\"rot=R shift=SX,SY [rows=..] [cols=..]\") and its file (repeatable)"},
    {"-o|--out", CLI_STRING, F(out), "OUT.csv", .help = "the selfcal-grid v1 file (required)"},
    {"--x-col", CLI_STRING, F(xcol), "NAME", .def = "x", .help = "the x column (name or number)"},
    {"--y-col", CLI_STRING, F(ycol), "NAME", .def = "y", .help = "the y column (name or number)"},
    {"--units", CLI_CUSTOM, F(unit_mm), "mm|um", .choices = "mm|um", .parse = parse_grid_units,
     .def = "mm", .help = "the positions' unit"},
    NUMBER("--tolerance-mm", tol, "T", "P/4", "the farthest a point may lie from its mark"),
    NUMBER("--min-share", share, "S", "0.5", "the share of a view's points that must fall on marks"),
    {"--ux-col", CLI_STRING, F(uxcol), "NAME", .help = "x's standard uncertainty column"},
    {"--uy-col", CLI_STRING, F(uycol), "NAME", .help = "y's standard uncertainty column"},
    LAYOUT_ROWS,
    {"--deviations", CLI_FLAG, F(lay.deviations), .help = "the values are deviations from nominal"},
    {"--nominal-x-col", CLI_STRING, F(lay.nominal[0]), "NAME", .help = "the nominal x column (mm)"},
    {"--nominal-y-col", CLI_STRING, F(lay.nominal[1]), "NAME", .help = "the nominal y column (mm)"},
};
#undef NUMBER
#undef F

const cli_cmd_opts cli_import_grid_opts = {
    "import grid", GRID_USAGE, IMPORT_GRID_OPTS,
    (int)(sizeof IMPORT_GRID_OPTS / sizeof IMPORT_GRID_OPTS[0]), 0, NULL, NULL,
    "unknown option or missing value: '%s' (see --help)", NULL, CLI_NO_OPERAND, NULL, grid_other,
};

static int grid_columns(grid_args *g);

/* The import's parameters and every view's placement, checked. */
static int grid_params(grid_args *g, sc_grid_import_params *p)
{
    const char *cmd = "import grid";
    if (!g->out || g->n_views == 0 || g->n_d == 0 || isnan(g->pitch))
        return cli_usage_error(cmd, "--n, --pitch-mm, at least one --view \"...\" FILE and -o are required (see --help)");
    if (g->n_d != floor(g->n_d) || g->n_d < 3 || g->n_d > SC_GRID_MAX_N || fmod(g->n_d, 2) == 0)
        return cli_usage_error(cmd, "--n must be odd and in 3..%d", SC_GRID_MAX_N);
    sc_grid_import_defaults(p, (int)g->n_d, g->pitch);
    p->origin_mm[0] = g->ox;
    p->origin_mm[1] = g->oy;
    p->stage_nx = (int)g->snx;
    p->stage_ny = (int)g->sny;
    if (!isnan(g->tol))
        p->tolerance_mm = g->tol;
    p->min_share = g->share;
    sc_error err;
    sc_error_clear(&err);
    if (sc_grid_import_check(p, &err) != SC_OK)
        return cli_usage_error(cmd, "%s", err.msg);
    for (int k = 0; k < g->n_views; ++k)
        if (parse_view(g->view_spec[k], p->n, &g->views[k].v, g->views[k].sigma,
                       sizeof g->views[k].sigma))
            return CLI_BAD_INPUT;
    return grid_columns(g);
}

/* The columns' options together (uncertainties, layout, deviations), checked. */
static int grid_columns(grid_args *g)
{
    const char *cmd = "import grid";
    if (!g->uxcol != !g->uycol)
        return cli_usage_error(cmd, "--ux-col and --uy-col go together");
    if (check_layout(cmd, &g->lay) != CLI_OK)
        return CLI_BAD_INPUT;
    if (g->lay.n_axis && g->lay.n_axis != 2)
        return cli_usage_error(cmd, "--axis-names needs two names, X,Y");
    const char **nom = g->lay.nominal;
    if (g->lay.deviations && (!nom[0] || !nom[1]))
        return cli_usage_error(cmd, "--deviations needs --nominal-x-col and --nominal-y-col");
    if (!g->lay.deviations && (nom[0] || nom[1]))
        return cli_usage_error(cmd, "--nominal-x-col/--nominal-y-col go with --deviations");
    if (g->lay.lay.id_col && g->uxcol)
        return cli_usage_error(cmd, "--ux-col/--uy-col: not with one row per axis (give the "
                                    "view's sigma_um= instead)");
    if (g->lay.lay.id_col && g->lay.deviations && strcasecmp(nom[0], nom[1]))
        return cli_usage_error(cmd, "with one row per axis the nominal of X and of Y is one "
                                    "column: --nominal-x-col and --nominal-y-col name the same");
    if (g->lay.lay.id_col && g->lay.deviations)
        g->lay.lay.nominal_col = nom[0];
    return CLI_OK;
}

/* One view's file read into iv->t: nc columns a row (x, y [, ux, uy]), deviations added to their
 * nominals, the uncertainties checked. */
static sc_status read_view_points(const grid_args *g, int nc, import_view *iv, sc_error *err)
{
    /* the columns read: x, y [, ux, uy] [, nominal x, nominal y]; one row per axis: the axis
     * values, then their nominals */
    const layout_args *l = &g->lay;
    const char *names[6] = {g->xcol, g->ycol, g->uxcol, g->uycol, NULL, NULL};
    double scale[6] = {g->unit_mm, g->unit_mm, g->unit_mm * 1e3, g->unit_mm * 1e3, 1, 1};
    int nread = nc;
    if (l->lay.id_col) {
        names[0] = l->n_axis ? l->axis[0] : "X";
        names[1] = l->n_axis ? l->axis[1] : "Y";
        scale[2] = scale[3] = 1; /* the nominals (mm) */
    } else if (l->deviations) {
        names[nc] = l->nominal[0];
        names[nc + 1] = l->nominal[1];
        scale[nc] = scale[nc + 1] = 1;
        nread = nc + 2;
    }
    sc_status st = sc_table_read_layout(iv->file, nread, names, scale, SC_IMPORT_VIEW_MAX_POINTS,
                                        &l->lay, &iv->notes, &iv->t, err);
    if (st == SC_OK && l->deviations) { /* positions = nominal + deviation, nc columns a row */
        int w = iv->t.n_cols, nom = l->lay.id_col ? 2 : nc;
        for (long q = 0; q < iv->t.n_rows; ++q) {
            const double *in = iv->t.value + (size_t)q * w;
            double row[4];
            for (int c = 0; c < nc; ++c)
                row[c] = in[c] + (c < 2 ? in[nom + c] : 0);
            memcpy(iv->t.value + (size_t)q * nc, row, (size_t)nc * sizeof(double));
        }
        iv->t.n_cols = nc;
    }
    for (long q = 0; st == SC_OK && nc == 4 && q < iv->t.n_rows; ++q)
        if (!sc_grid_sigma_valid(iv->t.value[q * 4 + 2]) ||
            !sc_grid_sigma_valid(iv->t.value[q * 4 + 3]))
            st = sc_error_set(err, SC_E_INPUT, iv->file, iv->t.line[q],
                              "the uncertainties in '%s' and '%s' must be %g to %g um", g->uxcol,
                              g->uycol, SC_GRID_MIN_SIGMA_UM, SC_INPUT_MAX_ABS);
    return st;
}

/* The largest distance of an assigned point (xy: np x, then np y) from its nominal position,
 * the stage node of its mark: nominal columns taken for measured ones put every point there. */
static double nominal_max_mm(const sc_grid_import_params *p, const import_view *iv, long np,
                             const double *xy)
{
    double dmax = 0;
    long nn = (long)p->n * p->n;
    int snx = p->stage_nx ? p->stage_nx : p->n, sny = p->stage_ny ? p->stage_ny : p->n;
    for (long m = 0; m < nn; ++m) {
        int ni, nj;
        long q = iv->mark_point[m];
        if (q < 0 || !sc_grid_import_mark_node(p, &iv->v, (int)(m / p->n), (int)(m % p->n), &ni,
                                                &nj))
            continue;
        double nx = p->origin_mm[0] + (nj - (snx - 1) / 2.0) * p->pitch_mm;
        double ny = p->origin_mm[1] + (ni - (sny - 1) / 2.0) * p->pitch_mm;
        double d = hypot(xy[q] - nx, xy[np + q] - ny);
        if (d > dmax)
            dmax = d;
    }
    return dmax;
}

/* One view's file read (nc columns: x, y [, ux, uy]) and its points assigned to marks. */
static sc_status import_grid_view(const grid_args *g, const sc_grid_import_params *p, int nc,
                                  import_view *iv, sc_error *err)
{
    sc_status st = read_view_points(g, nc, iv, err);
    if (st != SC_OK)
        return st;
    long np = iv->t.n_rows, nn = (long)p->n * p->n;
    double *xy = malloc((size_t)np * 2 * sizeof(double));
    double *work = malloc(sc_grid_import_work_doubles(np) * sizeof(double));
    iv->point_mark = malloc((size_t)np * sizeof(long));
    iv->mark_point = malloc((size_t)nn * sizeof(long));
    if (!xy || !work || !iv->point_mark || !iv->mark_point) {
        st = sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (%ld points)", np);
    } else {
        for (long q = 0; q < np; ++q) {
            xy[q] = iv->t.value[nc * q];
            xy[np + q] = iv->t.value[nc * q + 1];
        }
        st = sc_grid_import_assign(p, &iv->v, np, xy, xy + np, iv->t.line, iv->file,
                                   iv->t.header_line, iv->point_mark, iv->mark_point, &iv->fit,
                                   work, err);
    }
    /* how far the points are from their nominal positions (the stage nodes) */
    iv->nominal_max_mm = st == SC_OK ? nominal_max_mm(p, iv, np, xy) : 0;
    free(xy);
    free(work);
    return st;
}

/* The selfcal-grid v1 file: header, views, one row per assigned mark. */
static sc_status write_grid_file(const grid_args *g, const sc_grid_import_params *p, int nc,
                                 sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, g->out, err);
    if (st != SC_OK)
        return st;
    const long nn = (long)p->n * p->n;
    fprintf(f.fp, "# selfcal-grid v1\n# N = %d\n# pitch_mm = %.17g\n", p->n, p->pitch_mm);
    if (g->ox != 0 || g->oy != 0)
        fprintf(f.fp, "# origin_mm = %.17g,%.17g\n", g->ox, g->oy);
    if (g->snx && (g->snx != p->n || g->sny != p->n))
        fprintf(f.fp, "# stage = %ld,%ld\n", g->snx, g->sny);
    for (int k = 0; k < g->n_views; ++k)
        fprint_view_line(f.fp, k, &g->views[k].v, g->views[k].sigma, p->n);
    fprintf(f.fp, nc == 4 ? "view,i,j,x_mm,y_mm,ux_um,uy_um\n" : "view,i,j,x_mm,y_mm\n");
    for (int k = 0; k < g->n_views; ++k)
        for (long m = 0; m < nn; ++m) {
            long q = g->views[k].mark_point[m];
            if (q < 0)
                continue;
            const double *row = &g->views[k].t.value[nc * q];
            fprintf(f.fp, "%d,%ld,%ld,%.17g,%.17g", k, m / p->n, m % p->n, row[0], row[1]);
            if (nc == 4)
                fprintf(f.fp, ",%.17g,%.17g", row[2], row[3]);
            fputc('\n', f.fp);
        }
    return sc_afile_commit(&f, err);
}

static int import_grid_run(int argc, char **argv, grid_args *gp);

static int import_grid(int argc, char **argv)
{
    static grid_args g;
    memset(&g, 0, sizeof g);
    /* a --view takes three words: the command line holds at most argc / 3 of them */
    g.max_views = argc / 3 + 1;
    g.views = calloc((size_t)g.max_views, sizeof *g.views);
    g.view_spec = calloc((size_t)g.max_views, sizeof *g.view_spec);
    sc_error err;
    sc_error_clear(&err);
    int rc = g.views && g.view_spec
                 ? import_grid_run(argc, argv, &g)
                 : cli_report((sc_error_set(&err, SC_E_NOMEM, NULL, 0, "out of memory"), &err));
    free(g.views), free(g.view_spec);
    return rc;
}

static int import_grid_run(int argc, char **argv, grid_args *gp)
{
    grid_args g = *gp; /* the arrays are the caller's */
    g.xcol = "x";
    g.ycol = "y";
    g.unit_mm = 1;
    g.share = 0.5;
    g.pitch = g.tol = NAN; /* not given (0 is a value, refused by the checks) */
    int rc = cli_opts_parse(&cli_import_grid_opts, argc, argv, &g);
    if (rc >= 0)
        return rc;
    sc_grid_import_params p;
    rc = grid_params(&g, &p);
    if (rc != CLI_OK)
        return rc;
    sc_error err;
    sc_error_clear(&err);
    sc_status st = SC_OK;
    const int nc = g.uxcol ? 4 : 2; /* columns per row: x, y [, ux, uy] */
    for (int k = 0; k < g.n_views && st == SC_OK; ++k)
        st = import_grid_view(&g, &p, nc, &g.views[k], &err);
    if (st == SC_OK) { /* all views numbered: report, then write */
        for (int k = 0; k < g.n_views; ++k)
            report_view(&p, k, &g.views[k], g.unit_mm * 1e3);
        st = write_grid_file(&g, &p, nc, &err);
    }
    for (int k = 0; k < g.n_views; ++k) {
        sc_table_free(&g.views[k].t);
        free(g.views[k].mark_point);
        free(g.views[k].point_mark);
    }
    return st == SC_OK ? CLI_OK : cli_report(&err);
}

/* ---- import profile ---- */

typedef struct scan_log {
    const char *file;
    double spacing_mm;
    sc_table t;
} scan_log;

/* import profile's command line, as given. */
typedef struct {
    const char *out;
    const char *col[4]; /* position, m1, m2, m3 */
    double pos_unit, disp_unit, angle_unit, step, step_tol, sigma_disp, sigma_angle;
    scan_log scans[2];
    int n_scans;
    layout_args lay;
    sc_table_notes notes[2];
} profile_args;

/* --pos-units, --disp-units, --angle-units into the double (the file's unit in mm, um, urad) */
static int parse_profile_units(const char *cmd, const char *o, const char *v, void *field)
{
    static const char *const pos[] = {"mm", "um", "µm"}, *disp[] = {"um", "µm", "nm", "mm"},
                             *angle[] = {"urad", "µrad", "mrad", "arcsec"};
    static const double fpos[] = {1, 1e-3, 1e-3}, fdisp[] = {1, 1, 1e-3, 1e3},
                        fangle[] = {1, 1, 1e3, 4.84813681109535994e0};
    int rc = !strcmp(o, "--pos-units")    ? parse_units(cmd, o, v, pos, fpos, 3, field)
             : !strcmp(o, "--disp-units") ? parse_units(cmd, o, v, disp, fdisp, 4, field)
                                          : parse_units(cmd, o, v, angle, fangle, 4, field);
    return rc ? CLI_BAD_INPUT : CLI_OK;
}

/* --spacing-mm D FILE: one more scan into the profile_args */
static int parse_spacing(const char *cmd, const char *opt, const char *v, const char *next,
                         void *field)
{
    profile_args *g = field;
    double x;
    (void)opt;
    if (!next)
        return cli_usage_error(cmd, "--spacing-mm D must be followed by FILE");
    if (g->n_scans == 2)
        return cli_usage_error(cmd, "two scans: --spacing-mm D1 FILE1 --spacing-mm D2 FILE2");
    if (sc_parse_double(v, &x) || !(x > 0) || x > SC_INPUT_MAX_ABS)
        return cli_usage_error(cmd, "--spacing-mm needs a positive number, got '%s'", v);
    if (looks_like_option(next))
        return cli_usage_error(cmd, "--spacing-mm %s must be followed by its FILE, not by the "
                                    "option '%s'", v, next);
    g->scans[g->n_scans].spacing_mm = x;
    g->scans[g->n_scans++].file = next;
    return CLI_OK;
}

/* --step-mm S (> 0), --step-tolerance T (0 < T < 0.5) into the profile_args; with another
 * option (the table's other), its usage error */
static int profile_number(const char *cmd, const char *o, const char *v, void *field)
{
    profile_args *g = field;
    double x;
    if (sc_parse_double(v, &x))
        return cli_usage_error(cmd, "%s needs a number, got '%s'", o, v);
    if (!strcmp(o, "--step-mm") && x > 0) g->step = x;
    else if (!strcmp(o, "--step-tolerance") && x > 0 && x < 0.5) g->step_tol = x;
    else
        return cli_usage_error(cmd, "unknown option '%s' or value '%s' out of range (see --help)",
                               o, v);
    return CLI_OK;
}

#define F(field) offsetof(profile_args, field)
#define UNITS(name, f, v, dflt, text)                                                              \
    {name, CLI_CUSTOM, F(f), v, .choices = v, .parse = parse_profile_units, .def = dflt, .help = text}
/* import profile's options (cli_opts.h), in the order of its --help */
static const cli_opt IMPORT_PROFILE_OPTS[] = {
    {"--spacing-mm", CLI_CUSTOM, 0, "D FILE", .parse2 = parse_spacing,
     .help = "a scan's sensor spacing (mm) and its log (twice)"},
    {"-o|--out", CLI_STRING, F(out), "OUT.csv", .help = "the selfcal-profile v1 file (required)"},
    {"--step-mm", CLI_CUSTOM, 0, "S", 0, HUGE_VAL, CLI_MIN_OPEN, .parse = profile_number,
     .def = "scan 1's median step", .help = "the sampling step (mm)"},
    {"--pos-col", CLI_STRING, F(col[0]), "NAME", .def = "position", .help = "the position column"},
    {"--m1-col", CLI_STRING, F(col[1]), "NAME", .def = "m1", .help = "displacement sensor 1's column"},
    {"--m2-col", CLI_STRING, F(col[2]), "NAME", .def = "m2", .help = "displacement sensor 2's column"},
    {"--m3-col", CLI_STRING, F(col[3]), "NAME", .def = "m3", .help = "the angle sensor's column"},
    UNITS("--pos-units", pos_unit, "mm|um", "mm", "the positions' unit"),
    UNITS("--disp-units", disp_unit, "um|nm|mm", "um", "the displacements' unit"),
    UNITS("--angle-units", angle_unit, "urad|mrad|arcsec", "urad", "the angles' unit"),
    {"--step-tolerance", CLI_CUSTOM, 0, "T", 0, 0.5, CLI_MIN_OPEN | CLI_MAX_OPEN,
     .parse = profile_number, .def = "0.1", .help = "the positions' largest distance from the grid (steps)"},
    {"--sigma-disp-um", CLI_CUSTOM, F(sigma_disp), "S", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .parse = cli_opt_noise_positive, .help = "the displacement sensors' noise, for the header"},
    {"--sigma-angle-urad", CLI_CUSTOM, F(sigma_angle), "S", 0, SC_INPUT_MAX_ABS, CLI_MIN_OPEN,
     .parse = cli_opt_noise_positive, .help = "the angle sensor's noise, for the header"},
    LAYOUT_ROWS,
};
#undef UNITS
#undef F

const cli_cmd_opts cli_import_profile_opts = {
    "import profile", PROFILE_USAGE, IMPORT_PROFILE_OPTS,
    (int)(sizeof IMPORT_PROFILE_OPTS / sizeof IMPORT_PROFILE_OPTS[0]), 0, NULL, NULL,
    "unknown option or missing value: '%s' (see --help)", NULL, CLI_NO_OPERAND, NULL,
    profile_number,
};

/* Both logs read, merged onto one grid and written as a selfcal-profile v1 file. */
static sc_status import_profile_run(profile_args *g, sc_error *err)
{
    sc_status st = SC_OK;
    const double scale[4] = {g->pos_unit, g->disp_unit, g->disp_unit, g->angle_unit};
    const char *const *names = g->lay.n_axis ? g->lay.axis : g->col; /* one row per axis: the
                                                                        AXIS values */
    for (int k = 0; k < 2 && st == SC_OK; ++k)
        st = sc_table_read_layout(g->scans[k].file, 4, names, scale, SC_TABLE_MAX_ROWS, &g->lay.lay,
                                  &g->notes[k], &g->scans[k].t, err);
    sc_profile_data d;
    memset(&d, 0, sizeof d);
    double p0 = 0;
    if (st == SC_OK) {
        sc_profile_import_params ip;
        sc_profile_import_defaults(&ip);
        ip.spacing_mm[0] = g->scans[0].spacing_mm;
        ip.spacing_mm[1] = g->scans[1].spacing_mm;
        ip.step_mm = g->step;
        ip.step_tolerance = g->step_tol;
        const sc_table *const logs[2] = {&g->scans[0].t, &g->scans[1].t};
        st = sc_profile_import(&ip, logs, &d, &p0, err);
    }
    if (st == SC_OK) {
        if (!isnan(g->sigma_disp)) {
            d.has_sigma_disp = 1;
            d.sigma_disp_um = g->sigma_disp;
        }
        if (!isnan(g->sigma_angle)) {
            d.has_sigma_angle = 1;
            d.sigma_angle_urad = g->sigma_angle;
        }
        st = sc_profile_write(g->out, &d, err);
        for (int k = 0; k < 2 && st == SC_OK; ++k) { /* the notes once it worked: else one line */
            report_skipped("selfcal import profile", g->scans[k].file, &g->scans[k].t);
            report_notes("selfcal import profile", g->scans[k].file, &g->scans[k].t, &g->notes[k]);
        }
        if (st == SC_OK)
            fprintf(stderr,
                    "selfcal import profile: N = %d points, step %.9g mm from %.6f mm, d1 = %d, "
                    "d2 = %d (%ld and %ld samples)\n",
                    d.n, d.s_mm, p0, d.d[0], d.d[1], g->scans[0].t.n_rows, g->scans[1].t.n_rows);
    }
    sc_profile_data_free(&d);
    return st;
}

static int import_profile(int argc, char **argv)
{
    static profile_args g; /* large (the layout's buffers): not on the stack */
    memset(&g, 0, sizeof g);
    const char *const cols[4] = {"position", "m1", "m2", "m3"};
    memcpy(g.col, cols, sizeof cols);
    g.pos_unit = g.disp_unit = g.angle_unit = 1;
    g.step_tol = 0.1;
    g.sigma_disp = g.sigma_angle = NAN;
    int rc = cli_opts_parse(&cli_import_profile_opts, argc, argv, &g);
    if (rc >= 0)
        return rc;
    if (!g.out || g.n_scans != 2)
        return cli_usage_error("import profile", "--spacing-mm D1 FILE1 --spacing-mm D2 FILE2 and -o are required (see --help)");
    if (check_layout("import profile", &g.lay) != CLI_OK)
        return CLI_BAD_INPUT;
    if (g.lay.n_axis && g.lay.n_axis != 4)
        return cli_usage_error("import profile", "--axis-names needs four names: position, m1, "
                                                 "m2, m3");
    sc_error err;
    sc_error_clear(&err);
    sc_status st = import_profile_run(&g, &err);
    for (int k = 0; k < 2; ++k)
        sc_table_free(&g.scans[k].t);
    return st == SC_OK ? CLI_OK : cli_report(&err);
}

int cmd_import_grid(int argc, char **argv)
{
    return import_grid(argc, argv);
}

int cmd_import_profile(int argc, char **argv)
{
    return import_profile(argc, argv);
}
