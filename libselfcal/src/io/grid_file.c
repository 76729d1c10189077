/* The reader of `selfcal-grid v1` data and plan files (SPEC §1 and §5): the header (format tag,
 * N, pitch_mm, origin_mm, stage through the declarative header parser, view lines with rot=,
 * shift=, rows=, cols=, sigma_um=), the column header (view,i,j,x_mm,y_mm[,ux_um,uy_um][,t_s])
 * and the data rows. Strict: every problem is SC_E_INPUT with FILE:LINE; on failure the data
 * hold no memory. The writer of the same format follows the reader: one column header for both.
 * The plan and data it reads into, and the geometry its rows are checked against, are in
 * grid_plan.c (which says why they live in io/). */
#include <ctype.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_io.h"
#include "selfcal/header.h"
#include "selfcal/number.h"
#include "io_internal.h"

/* The column header of the data rows (the optional ux_um,uy_um and t_s follow it). */
#define COLUMN_HEADER "view,i,j,x_mm,y_mm"

/* Parse "a,b" into two longs. */
static int parse_long_pair(char *s, long *a, long *b)
{
    char *comma = strchr(s, ',');
    if (!comma)
        return -1;
    *comma = '\0';
    int ok = sc_parse_long(sc_str_trim(s), a) == 0 && sc_parse_long(sc_str_trim(comma + 1), b) == 0;
    *comma = ',';
    return ok ? 0 : -1;
}

/* A view line as written, validated once N is known. */
typedef struct view_decl {
    int id;
    long line;
    long rot, sx, sy;
    double sigma_um;
    int has_temp;
    double temp_C;
    int n_rows_sel, n_cols_sel;
    long *rows, *cols;  /* the rows=/cols= lists (NULL when not given; freed with the decls) */
} view_decl;

/* Parse a comma list of indices (at most SC_GRID_MAX_N) into *out, allocated here. */
static int parse_index_list(char *s, long **out, int *count)
{
    long buf[SC_GRID_MAX_N];
    int n = 0;
    char *p = s;
    for (;;) {
        char *comma = strchr(p, ',');
        if (comma)
            *comma = '\0';
        if (n == SC_GRID_MAX_N || sc_parse_long(sc_str_trim(p), &buf[n]) != 0)
            return -1;
        ++n;
        if (!comma)
            break;
        p = comma + 1;
    }
    if (!(*out = malloc((size_t)n * sizeof **out)))
        return -2;
    memcpy(*out, buf, (size_t)n * sizeof **out);
    *count = n;
    return 0;
}

/* One attribute of a view line: its value parsed into vd (id: the view's number for the
 * messages; repeated: the attribute was given before, an error); SC_OK, or SC_E_INPUT /
 * SC_E_NOMEM with the message. */
typedef sc_status (*view_attr_fn)(const char *path, long line, long id, char *val, int repeated,
                                  view_decl *vd, sc_error *err);

static sc_status attr_rot(const char *path, long line, long id, char *val, int repeated,
                          view_decl *vd, sc_error *err)
{
    if (repeated || sc_parse_long(val, &vd->rot) != 0)
        return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: bad or repeated rot", id);
    if (vd->rot != 0 && vd->rot != 90 && vd->rot != 180 && vd->rot != 270)
        return sc_error_set(err, SC_E_INPUT, path, line,
                            "view %ld: rot must be 0, 90, 180 or 270 (got %ld)", id, vd->rot);
    return SC_OK;
}

static sc_status attr_shift(const char *path, long line, long id, char *val, int repeated,
                            view_decl *vd, sc_error *err)
{
    if (repeated || parse_long_pair(val, &vd->sx, &vd->sy) != 0)
        return sc_error_set(err, SC_E_INPUT, path, line,
                            "view %ld: shift must be two whole numbers SX,SY", id);
    return SC_OK;
}

static sc_status attr_sigma(const char *path, long line, long id, char *val, int repeated,
                            view_decl *vd, sc_error *err)
{
    if (repeated || sc_parse_double(val, &vd->sigma_um) != 0 ||
        !sc_grid_sigma_valid(vd->sigma_um))
        return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: sigma_um must be %g to %g um",
                            id, SC_GRID_MIN_SIGMA_UM, SC_INPUT_MAX_ABS);
    return SC_OK;
}

static sc_status attr_temp(const char *path, long line, long id, char *val, int repeated,
                           view_decl *vd, sc_error *err)
{
    vd->has_temp = 1;
    if (repeated || sc_parse_double(val, &vd->temp_C) != 0 ||
        !(vd->temp_C >= SC_GRID_MIN_TEMP_C && vd->temp_C <= SC_GRID_MAX_TEMP_C))
        return sc_error_set(err, SC_E_INPUT, path, line,
                            "view %ld: temp_C must be a temperature of %g to %g C", id,
                            SC_GRID_MIN_TEMP_C, SC_GRID_MAX_TEMP_C);
    return SC_OK;
}

/* rows= and cols=: a comma list of plate rows or columns. */
static sc_status attr_list(const char *path, long line, long id, char *val, int repeated,
                           int rows, view_decl *vd, sc_error *err)
{
    int rc = repeated ? -1
                      : parse_index_list(val, rows ? &vd->rows : &vd->cols,
                                         rows ? &vd->n_rows_sel : &vd->n_cols_sel);
    if (rc == -2)
        return sc_error_set(err, SC_E_NOMEM, path, line, "out of memory");
    if (rc != 0)
        return sc_error_set(err, SC_E_INPUT, path, line,
                            rows ? "view %ld: rows must be a comma list of plate rows"
                                 : "view %ld: cols must be a comma list of plate columns",
                            id);
    return SC_OK;
}

static sc_status attr_rows(const char *path, long line, long id, char *val, int repeated,
                           view_decl *vd, sc_error *err)
{
    return attr_list(path, line, id, val, repeated, 1, vd, err);
}

static sc_status attr_cols(const char *path, long line, long id, char *val, int repeated,
                           view_decl *vd, sc_error *err)
{
    return attr_list(path, line, id, val, repeated, 0, vd, err);
}

/* The attributes of a view line (SPEC §1), each at most once; rot and shift are required. */
static const struct view_attr {
    const char *key;
    view_attr_fn parse;
} VIEW_ATTRS[] = {
    {"rot", attr_rot},           {"shift", attr_shift}, {"sigma_um", attr_sigma},
    {"temp_C", attr_temp},       {"rows", attr_rows},   {"cols", attr_cols},
};
#define N_VIEW_ATTRS ((int)(sizeof VIEW_ATTRS / sizeof VIEW_ATTRS[0]))

/* One key=value token of a view line; seen[a] counts attribute a. */
static sc_status view_token(const char *path, long line, long id, char *tok, view_decl *vd,
                            int *seen, sc_error *err)
{
    char *eq = strchr(tok, '=');
    if (!eq)
        return sc_error_set(err, SC_E_INPUT, path, line,
                            "view %ld: expected key=value, got '%.40s'", id, tok);
    *eq = '\0';
    for (int a = 0; a < N_VIEW_ATTRS; ++a)
        if (!strcmp(tok, VIEW_ATTRS[a].key))
            return VIEW_ATTRS[a].parse(path, line, id, eq + 1, seen[a]++ > 0, vd, err);
    return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: unknown attribute '%.40s'", id,
                        tok);
}

/* "# view K: rot=R shift=SX,SY rows=.. cols=.." (text = after '#', trimmed, starting with "view"). */
static sc_status parse_view_line(const char *path, long line, char *text, view_decl *vd,
                                 sc_error *err)
{
    memset(vd, 0, sizeof *vd);
    vd->line = line;
    char *p = text + 4;
    char *colon = strchr(p, ':');
    if (!colon)
        return sc_error_set(err, SC_E_INPUT, path, line,
                            "view line must read '# view K: rot=R shift=SX,SY [rows=..] [cols=..]'");
    *colon = '\0';
    long id;
    if (sc_parse_long(sc_str_trim(p), &id) != 0 || id < 0 || id > 1000000)
        return sc_error_set(err, SC_E_INPUT, path, line, "view number is not a whole number >= 0");
    vd->id = (int)id;
    int seen[N_VIEW_ATTRS] = {0};
    char *save = NULL;
    for (char *tok = strtok_r(colon + 1, " \t", &save); tok; tok = strtok_r(NULL, " \t", &save)) {
        sc_status st = view_token(path, line, id, tok, vd, seen, err);
        if (st != SC_OK)
            return st;
    }
    if (!seen[0])
        return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: rot= is missing", id);
    if (!seen[1])
        return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: shift= is missing", id);
    return SC_OK;
}

/* The column header: view,i,j,x_mm,y_mm, optionally ux_um,uy_um, optionally t_s (in this order).
 * Returns the number of fields (5..8) with *has_u, *has_t set, or 0 if it is not a header. */
static int is_column_header(sc_csv *r, int *has_u, int *has_t)
{
    static const char *names[5] = {"view", "i", "j", "x_mm", "y_mm"};
    if (r->nfields < 5 || r->nfields > 8)
        return 0;
    for (int k = 0; k < 5; ++k)
        if (strcmp(r->field[k], names[k]) != 0)
            return 0;
    int k = 5;
    *has_u = *has_t = 0;
    if (k < r->nfields && !strcmp(r->field[k], "ux_um")) {
        if (k + 1 >= r->nfields || strcmp(r->field[k + 1], "uy_um") != 0)
            return 0;
        *has_u = 1;
        k += 2;
    }
    if (k < r->nfields && !strcmp(r->field[k], "t_s")) {
        *has_t = 1;
        ++k;
    }
    return k == r->nfields ? k : 0;
}

/* The numeric header keys (SPEC §1, §5). */
typedef struct grid_hdr {
    long n;
    double pitch_mm;
    double origin_mm[2];
    long stage[2];
    double plate_scale[2]; /* SPEC §11: E, U (ppm) */
    double cte[2];         /* A, U (ppm/K) */
    double temp_u_K;
} grid_hdr;

static const sc_header_key HDR_KEYS[] = {
    {"N", SC_HEADER_LONG, offsetof(grid_hdr, n), 1, 3, SC_GRID_MAX_N, 0},
    {"pitch_mm", SC_HEADER_DOUBLE, offsetof(grid_hdr, pitch_mm), 1, SC_GRID_MIN_PITCH_MM, 1e6, 0},
    {"origin_mm", SC_HEADER_DOUBLE_PAIR, offsetof(grid_hdr, origin_mm), 0, -1e6, 1e6, 0},
    {"stage", SC_HEADER_LONG_PAIR, offsetof(grid_hdr, stage), 0, 3, SC_GRID_MAX_STAGE, 0},
    {"plate_scale_ppm", SC_HEADER_DOUBLE_PAIR, offsetof(grid_hdr, plate_scale), 0,
     -SC_GRID_MAX_SCALE_PPM, SC_GRID_MAX_SCALE_PPM, 0},
    {"plate_cte_ppm_per_K", SC_HEADER_DOUBLE_PAIR, offsetof(grid_hdr, cte), 0, -SC_GRID_MAX_CTE,
     SC_GRID_MAX_CTE, 0},
    {"temp_u_K", SC_HEADER_DOUBLE, offsetof(grid_hdr, temp_u_K), 0, 0, SC_GRID_MAX_TEMP_U_K, 0},
};

typedef struct read_state {
    const char *path;
    sc_csv csv;
    sc_header hdr;
    grid_hdr h;
    view_decl *decl;     /* cap_decl entries, grown as view lines come */
    int n_decl, cap_decl;
    int max_id;          /* the largest view number declared so far (-1: none) */
    int last_v;          /* the view of the last data row (rows come grouped by view) */
    int n_fields, has_u, has_t, have_columns;
    int t_state;         /* t_s column: 0 no row yet, 1 rows carry times, -1 rows leave it empty */
    long **mark_line;    /* per view (n_decl), each made at its first row */
    sc_grid_file_info *info;
} read_state;

static void read_state_free(read_state *s)
{
    sc_csv_close(&s->csv);
    for (int v = 0; v < s->n_decl; ++v) {
        free(s->decl[v].rows), free(s->decl[v].cols);
        if (s->mark_line)
            free(s->mark_line[v]);
    }
    free(s->decl);
    free(s->mark_line);
}

static sc_status csv_failure(sc_error *err) { return err && err->code ? err->code : SC_E_INPUT; }

/* Line 1: the format tag. */
static sc_status read_tag(read_state *s, sc_error *err)
{
    int got = sc_csv_next_line(&s->csv, err);
    if (got < 0)
        return csv_failure(err);
    char *t = got ? s->csv.text : (char *)"";
    int ok = 0;
    if (t[0] == '#') {
        char *rest = sc_str_trim(t + 1);
        char a[32], b[32], extra[8];
        ok = sscanf(rest, "%31s %31s %7s", a, b, extra) == 2 && !strcmp(a, "selfcal-grid") &&
             !strcmp(b, "v1");
    }
    if (!ok)
        return sc_error_set(err, SC_E_INPUT, s->path, 1,
                            "not a selfcal-grid v1 file (the first line must be "
                            "'# selfcal-grid v1')");
    s->info->first_line = 1;
    return SC_OK;
}

/* A `# view K: ...` line. */
static sc_status header_view(read_state *s, long ln, char *body, sc_error *err)
{
    if (s->n_decl == SC_GRID_VIEW_LIMIT)
        return sc_error_set(err, SC_E_INPUT, s->path, ln, "more than %d views", SC_GRID_VIEW_LIMIT);
    if (s->n_decl == s->cap_decl) {
        int cap = s->cap_decl ? 2 * s->cap_decl : 64;
        view_decl *g = realloc(s->decl, (size_t)cap * sizeof *g);
        if (!g)
            return sc_error_set(err, SC_E_NOMEM, s->path, ln, "out of memory");
        s->decl = g, s->cap_decl = cap;
    }
    view_decl *vd = &s->decl[s->n_decl];
    sc_status st = parse_view_line(s->path, ln, body, vd, err);
    if (st != SC_OK) {
        free(vd->rows), free(vd->cols);
        return st;
    }
    s->n_decl++; /* its lists are the decls' now */
    /* views numbered upwards (as written here) cannot repeat one: only others are looked up */
    for (int k = 0; vd->id <= s->max_id && k < s->n_decl - 1; ++k)
        if (s->decl[k].id == vd->id)
            return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                "view %d is declared twice (first on line %ld)", vd->id,
                                s->decl[k].line);
    if (vd->id > s->max_id)
        s->max_id = vd->id;
    s->info->header_end_line = ln;
    return SC_OK;
}

/* One header line starting with '#'. */
static sc_status header_comment(read_state *s, long ln, sc_error *err)
{
    char *body = sc_str_trim(s->csv.text + 1);
    if (!strncmp(body, "view", 4) &&
        (isspace((unsigned char)body[4]) || isdigit((unsigned char)body[4])))
        return header_view(s, ln, body, err);
    bool used = false;
    sc_status st = sc_header_line(&s->hdr, s->path, ln, s->csv.text, &used, err);
    if (st != SC_OK)
        return st;
    if (used) {
        if (sc_header_line_of(&s->hdr, "N") == ln && s->h.n % 2 == 0)
            return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                "N = %ld is even (the plate needs a centre mark: N odd)", s->h.n);
        if (sc_header_line_of(&s->hdr, "stage") == ln && (s->h.stage[0] % 2 == 0 ||
                                                         s->h.stage[1] % 2 == 0))
            return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                "stage must be NX,NY, both odd and in 3..%d (got %ld,%ld)",
                                SC_GRID_MAX_STAGE, s->h.stage[0], s->h.stage[1]);
        if (sc_header_line_of(&s->hdr, "plate_scale_ppm") == ln && s->h.plate_scale[1] < 0)
            return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                "plate_scale_ppm: the uncertainty U must be >= 0 (got %g)",
                                s->h.plate_scale[1]);
        if (sc_header_line_of(&s->hdr, "plate_cte_ppm_per_K") == ln && s->h.cte[1] < 0)
            return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                "plate_cte_ppm_per_K: the uncertainty U must be >= 0 (got %g)",
                                s->h.cte[1]);
        s->info->header_end_line = ln;
        return SC_OK;
    }
    char key[64], *val, copy[512];
    snprintf(copy, sizeof copy, "%s", s->csv.text);
    if (sc_header_kv(s->csv.text, key, sizeof key, &val))
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "unknown header '%.40s' (expected N, pitch_mm, origin_mm, stage, "
                            "plate_scale_ppm, plate_cte_ppm_per_K, temp_u_K or view)",
                            key);
    if (strchr(copy, '='))
        return sc_error_set(err, SC_E_INPUT, s->path, ln, "unreadable header line '%.60s'", copy);
    return SC_OK; /* a plain comment */
}

/* Header lines up to the column header (which must come before any data). */
static sc_status read_header(read_state *s, sc_error *err)
{
    int got;
    while ((got = sc_csv_next_line(&s->csv, err)) > 0) {
        long ln = s->csv.line;
        if (sc_csv_is_blank(&s->csv))
            continue;
        if (s->csv.text[0] == '#') {
            sc_status st = header_comment(s, ln, err);
            if (st != SC_OK)
                return st;
            continue;
        }
        if (sc_csv_split(&s->csv, err) < 0)
            return csv_failure(err);
        s->n_fields = is_column_header(&s->csv, &s->has_u, &s->has_t);
        if (s->n_fields > 0) {
            s->have_columns = 1;
            s->info->header_end_line = ln;
            return SC_OK;
        }
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "expected the column header '" COLUMN_HEADER "' before the data");
    }
    return got < 0 ? csv_failure(err) : SC_OK;
}

/* View k of the plan from its declaration. */
static sc_status build_view(read_state *s, sc_grid_plan *p, int v, sc_error *err)
{
    view_decl *vd = &s->decl[v];
    sc_grid_view *w = &p->view[v];
    int n = p->n;
    memset(w, 0, sizeof *w);
    if (labs(vd->sx) > 2L * SC_GRID_MAX_STAGE || labs(vd->sy) > 2L * SC_GRID_MAX_STAGE)
        return sc_error_set(err, SC_E_INPUT, s->path, vd->line,
                            "view %d: shift %ld,%ld moves the plate off the stage grid", vd->id,
                            vd->sx, vd->sy);
    w->sigma_um = vd->sigma_um;
    w->rot_deg = (int)vd->rot;
    w->shift_x = (int)vd->sx;
    w->shift_y = (int)vd->sy;
    w->restricted = vd->n_rows_sel > 0 || vd->n_cols_sel > 0;
    for (int t = 0; t < 2; ++t) {
        const long *sel = t ? vd->cols : vd->rows;
        int cnt = t ? vd->n_cols_sel : vd->n_rows_sel;
        for (int k = 0; k < cnt; ++k) {
            if (sel[k] < 0 || sel[k] >= n)
                return sc_error_set(err, SC_E_INPUT, s->path, vd->line,
                                    "view %d: %s %ld is off the plate (0..%d)", vd->id,
                                    t ? "column" : "row", sel[k], n - 1);
            (t ? w->col_sel : w->row_sel)[sel[k]] = 1;
        }
    }
    int any = 0;
    for (int i = 0; i < n && !any; ++i)
        for (int j = 0; j < n && !any; ++j)
            any = sc_grid_view_measures(p, v, i, j);
    if (!any)
        return sc_error_set(err, SC_E_INPUT, s->path, vd->line,
                            "view %d (rot=%d shift=%d,%d) is off the %dx%d stage grid: it lands "
                            "no mark it measures there",
                            vd->id, w->rot_deg, w->shift_x, w->shift_y, sc_grid_stage_nx(p),
                            sc_grid_stage_ny(p));
    s->info->view_line[v] = vd->line;
    s->info->view_id[v] = vd->id;
    return SC_OK;
}

/* The scale lines (SPEC §11): temp_C on every view or none, and only with a CTE. */
static sc_status build_scale(read_state *s, sc_grid_plan *p, sc_error *err)
{
    sc_grid_scale *sc = &p->scale;
    memset(sc, 0, sizeof *sc);
    if (sc_header_line_of(&s->hdr, "plate_scale_ppm")) {
        sc->has_plate_scale = 1;
        sc->plate_scale_ppm = s->h.plate_scale[0];
        sc->u_plate_scale_ppm = s->h.plate_scale[1];
    }
    if (sc_header_line_of(&s->hdr, "plate_cte_ppm_per_K")) {
        sc->has_cte = 1;
        sc->cte_ppm_per_K = s->h.cte[0];
        sc->u_cte_ppm_per_K = s->h.cte[1];
    }
    sc->temp_u_K = sc_header_line_of(&s->hdr, "temp_u_K") ? s->h.temp_u_K
                                                          : SC_GRID_TEMP_U_K_DEFAULT;
    int with = -1, without = -1;
    for (int v = 0; v < s->n_decl; ++v) {
        if (s->decl[v].has_temp && with < 0)
            with = v;
        if (!s->decl[v].has_temp && without < 0)
            without = v;
    }
    if (with >= 0 && without >= 0)
        return sc_error_set(err, SC_E_INPUT, s->path, s->decl[without].line,
                            "view %d has no temp_C but view %d has (temp_C=%g): give temp_C on "
                            "every view or on none",
                            s->decl[without].id, s->decl[with].id, s->decl[with].temp_C);
    if (with >= 0 && !sc->has_cte)
        return sc_error_set(err, SC_E_INPUT, s->path, s->decl[with].line,
                            "view %d: temp_C needs the plate's expansion coefficient "
                            "('# plate_cte_ppm_per_K = A, U' in the header)",
                            s->decl[with].id);
    sc->has_temps = with >= 0;
    for (int v = 0; sc->has_temps && v < s->n_decl; ++v)
        p->view[v].temp_C = s->decl[v].temp_C;
    return SC_OK;
}

/* The header is complete: check it and build the plan. */
static sc_status build_plan(read_state *s, sc_grid_plan *p, sc_error *err)
{
    long where = s->info->header_end_line ? s->info->header_end_line : 1;
    sc_status st = sc_header_finish(&s->hdr, s->path, where, err);
    if (st != SC_OK)
        return st;
    if (s->n_decl == 0)
        return sc_error_set(err, SC_E_INPUT, s->path, where,
                            "no '# view K: rot=R shift=SX,SY' line in the header");
    s->info->n_line = sc_header_line_of(&s->hdr, "N");
    p->n = (int)s->h.n;
    p->pitch_mm = s->h.pitch_mm;
    p->origin_mm[0] = s->h.origin_mm[0];
    p->origin_mm[1] = s->h.origin_mm[1];
    p->stage_nx = (int)s->h.stage[0];
    p->stage_ny = (int)s->h.stage[1];
    if ((st = sc_grid_plan_views(p, s->n_decl, err)) != SC_OK)
        return st;
    s->info->view_line = calloc((size_t)s->n_decl, sizeof *s->info->view_line);
    s->info->view_id = calloc((size_t)s->n_decl, sizeof *s->info->view_id);
    s->info->view_rows = calloc((size_t)s->n_decl, sizeof *s->info->view_rows);
    s->mark_line = calloc((size_t)s->n_decl, sizeof *s->mark_line);
    if (!s->info->view_line || !s->info->view_id || !s->info->view_rows || !s->mark_line)
        return sc_error_set(err, SC_E_NOMEM, s->path, where, "out of memory (%d views)",
                            s->n_decl);
    for (int v = 0; v < s->n_decl; ++v)
        if ((st = build_view(s, p, v, err)) != SC_OK)
            return st;
    if ((st = build_scale(s, p, err)) != SC_OK)
        return st;
    st = sc_grid_plan_check(p, err);
    if (st != SC_OK && err) {
        snprintf(err->file, sizeof err->file, "%s", s->path);
        err->line = where;
    }
    return st;
}

/* The optional ux_um, uy_um fields of a row of mark k in view v. */
static sc_status row_uncertainties(read_state *s, sc_grid_data *d, int v, long vid, size_t k,
                                   long ln, sc_error *err)
{
    for (int c = 0; s->has_u && c < 2; ++c) {
        const char *name = c ? "uy_um" : "ux_um", *f = s->csv.field[5 + c];
        double u = NAN;
        if (f[0] == '\0') {
            if (!(d->plan.view[v].sigma_um > 0))
                return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                    "%s is empty and view %ld states no sigma_um", name, vid);
        } else if (sc_parse_double(f, &u) != 0 || !sc_grid_sigma_valid(u)) {
            return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                "%s must be a standard uncertainty of %g to %g um, got '%.40s'",
                                name, SC_GRID_MIN_SIGMA_UM, SC_INPUT_MAX_ABS, f);
        }
        (c ? d->uy_um : d->ux_um)[v][k] = u;
    }
    return SC_OK;
}

/* The optional t_s field: on every row or on none. */
static sc_status row_time(read_state *s, sc_grid_data *d, int v, size_t k, long ln, sc_error *err)
{
    if (!s->has_t)
        return SC_OK;
    const char *f = s->csv.field[s->n_fields - 1];
    int here = f[0] != '\0' ? 1 : -1;
    if (s->t_state && here != s->t_state)
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "t_s is %s here but %s on earlier rows (give it on every row or on "
                            "none)",
                            here > 0 ? "given" : "empty", here > 0 ? "empty" : "given");
    s->t_state = here;
    double t = NAN;
    if (here > 0 && (sc_parse_double(f, &t) != 0 || !(fabs(t) <= 1e12)))
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "t_s must be a number of seconds, got '%.40s'", f);
    d->t_s[v][k] = t;
    return SC_OK;
}

/* Which view and mark a row is, and that it may be measured there: *v, *k and the mark's nominal
 * stage position (*nx, *ny) mm, relative to the stage centre. */
static sc_status row_locate(read_state *s, const sc_grid_plan *p, long vid, long i, long j,
                            long ln, int *v, size_t *k, double *nx, double *ny, sc_error *err)
{
    int n = p->n;
    *v = -1;
    if (s->last_v < s->n_decl && s->decl[s->last_v].id == vid)
        *v = s->last_v;
    else if (vid >= 0 && vid < s->n_decl && s->decl[vid].id == vid)
        *v = (int)vid;
    else
        for (int t = 0; t < s->n_decl && *v < 0; ++t)
            if (s->decl[t].id == vid)
                *v = t;
    if (*v < 0)
        return sc_error_set(err, SC_E_INPUT, s->path, ln, "view %ld is not declared in the header",
                            vid);
    if (i < 0 || i >= n || j < 0 || j >= n)
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "mark (%ld,%ld) is off the plate (i, j in 0..%d)", i, j, n - 1);
    const sc_grid_view *w = &p->view[*v];
    if (!sc_grid_mark_stage_xy_mm(p, *v, (int)i, (int)j, nx, ny))
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "mark (%ld,%ld) does not land on the stage grid in view %ld "
                            "(rot=%d shift=%d,%d)",
                            i, j, vid, w->rot_deg, w->shift_x, w->shift_y);
    if (!sc_grid_view_measures(p, *v, (int)i, (int)j))
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "mark (%ld,%ld) is not selected by view %ld's rows=/cols=", i, j, vid);
    if (!s->mark_line[*v] && !(s->mark_line[*v] = calloc((size_t)n * n, sizeof(long))))
        return sc_error_set(err, SC_E_NOMEM, s->path, ln, "out of memory");
    s->last_v = *v;
    *k = (size_t)i * n + (size_t)j;
    if (s->mark_line[*v][*k])
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "duplicate measurement of mark (%ld,%ld) in view %ld (first on line "
                            "%ld)",
                            i, j, vid, s->mark_line[*v][*k]);
    s->mark_line[*v][*k] = ln;
    return SC_OK;
}

/* One data row's values (view, i, j, x_mm, y_mm), then its optional fields (split rows only). */
static sc_status place_row(read_state *s, sc_grid_data *d, long vid, long i, long j, double x,
                           double y, long ln, sc_error *err)
{
    const sc_grid_plan *p = &d->plan;
    sc_status st;
    int v = 0; /* set by row_locate; initialised for GCC -O3 (maybe-uninitialized) */
    size_t k = 0;
    double nx = 0, ny = 0;
    if ((st = row_locate(s, p, vid, i, j, ln, &v, &k, &nx, &ny, err)) != SC_OK)
        return st;
    nx += p->origin_mm[0];
    ny += p->origin_mm[1];
    double ex = x - nx, ey = y - ny;
    if (fabs(ex) > 0.5 * p->pitch_mm || fabs(ey) > 0.5 * p->pitch_mm)
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "header (N/pitch/origin/rot/shift) contradicts the data: mark "
                            "(%ld,%ld) of view %ld measured at (%.6g, %.6g) mm, more than half a "
                            "pitch from its nominal position (%.6g, %.6g) mm",
                            i, j, vid, x, y, nx, ny);
    d->dx_um[v][k] = ex * 1000.0;
    d->dy_um[v][k] = ey * 1000.0;
    if ((st = row_uncertainties(s, d, v, vid, k, ln, err)) != SC_OK ||
        (st = row_time(s, d, v, k, ln, err)) != SC_OK)
        return st;
    s->info->n_rows++;
    s->info->view_rows[v]++;
    return SC_OK;
}

/* One data row (already split). */
static sc_status read_row(read_state *s, sc_grid_data *d, long ln, sc_error *err)
{
    if (s->csv.nfields != s->n_fields)
        return sc_error_set(err, SC_E_INPUT, s->path, ln,
                            "expected %d fields (as the column header), got %d", s->n_fields,
                            s->csv.nfields);
    long vid, i, j;
    double x, y;
    sc_status st;
    if ((st = sc_csv_long(&s->csv, 0, "view", &vid, err)) != SC_OK ||
        (st = sc_csv_long(&s->csv, 1, "i", &i, err)) != SC_OK ||
        (st = sc_csv_long(&s->csv, 2, "j", &j, err)) != SC_OK ||
        (st = sc_csv_double(&s->csv, 3, "x_mm", &x, err)) != SC_OK ||
        (st = sc_csv_double(&s->csv, 4, "y_mm", &y, err)) != SC_OK)
        return st;
    return place_row(s, d, vid, i, j, x, y, ln, err);
}

/* Data rows after the column header. A file of the five plain columns has its rows parsed in
 * place when they are plain (single commas, no blanks: what writers write; sc_csv_is_plain_row),
 * every other line takes the general path, which also says what is wrong: same values, same
 * messages. */
static sc_status read_rows(read_state *s, sc_grid_data *d, sc_error *err)
{
    int got = 0;
    while (s->have_columns && (got = sc_csv_next_line(&s->csv, err)) > 0) {
        long ln = s->csv.line, ints[3];
        double xy[2];
        if (s->n_fields == 5 && sc_csv_is_plain_row(&s->csv, "LLLDD", ints, xy)) {
            sc_status st = place_row(s, d, ints[0], ints[1], ints[2], xy[0], xy[1], ln, err);
            if (st != SC_OK)
                return st;
            continue;
        }
        if (sc_csv_is_blank(&s->csv))
            continue;
        if (s->csv.text[0] == '#') {
            if (strchr(s->csv.text, '=') || strstr(s->csv.text, "view"))
                return sc_error_set(err, SC_E_INPUT, s->path, ln,
                                    "header line after the column header (headers come first)");
            continue;
        }
        if (sc_csv_split(&s->csv, err) < 0)
            return csv_failure(err);
        sc_status st = read_row(s, d, ln, err);
        if (st != SC_OK)
            return st;
    }
    return s->have_columns && got < 0 ? csv_failure(err) : SC_OK;
}

/* Without ux_um, uy_um columns the views' sigma_um= state the weights: on every view that has
 * rows (every view of a plan file) or on none. Some views stating it and others not would leave
 * the others' weights to an arbitrary default. */
static sc_status check_stated_noise(const read_state *s, const sc_grid_data *d, sc_error *err)
{
    if (s->has_u) /* every row states its own or its view's (row_uncertainties) */
        return SC_OK;
    int with = -1, without = -1;
    for (int v = 0; v < s->n_decl; ++v) {
        if (s->info->n_rows > 0 && s->info->view_rows[v] == 0)
            continue;
        if (d->plan.view[v].sigma_um > 0) {
            if (with < 0)
                with = v;
        } else if (without < 0) {
            without = v;
        }
    }
    if (with < 0 || without < 0)
        return SC_OK;
    return sc_error_set(err, SC_E_INPUT, s->path, s->decl[without].line,
                        "view %d states no sigma_um but view %d does (sigma_um=%g): state every "
                        "view's uncertainty (sigma_um= or the ux_um,uy_um columns) or none (the "
                        "noise is then estimated from the residuals)",
                        s->decl[without].id, s->decl[with].id, d->plan.view[with].sigma_um);
}

sc_status sc_grid_read(const char *path, sc_grid_data *d, sc_grid_file_info *info, sc_error *err)
{
    sc_grid_file_info local_info;
    if (!info)
        info = &local_info;
    memset(info, 0, sizeof *info);
    memset(d, 0, sizeof *d);
    read_state s;
    memset(&s, 0, sizeof s);
    s.path = path;
    s.info = info;
    s.n_fields = 5;
    sc_header_init(&s.hdr, HDR_KEYS, (int)(sizeof HDR_KEYS / sizeof HDR_KEYS[0]), &s.h);
    sc_status st = sc_csv_open(&s.csv, path, err);
    if (st != SC_OK)
        return st;
    s.max_id = -1;
    st = read_tag(&s, err);
    if (st == SC_OK)
        st = read_header(&s, err);
    if (st == SC_OK)
        st = build_plan(&s, &d->plan, err);
    if (st == SC_OK)
        st = sc_grid_data_alloc(d, err);
    if (st == SC_OK)
        st = sc_grid_data_alloc_extra(d, s.has_u, s.has_t, err);
    if (st == SC_OK)
        st = read_rows(&s, d, err);
    if (st == SC_OK)
        st = check_stated_noise(&s, d, err);
    read_state_free(&s);
    if (st != SC_OK) {
        sc_grid_data_free(d);
        sc_grid_file_info_free(info);
        return st;
    }
    if (info == &local_info)
        sc_grid_file_info_free(info);
    if (s.t_state < 0) /* the column is there but empty on every row: no times */
        for (int v = 0; v < d->plan.n_views; ++v) {
            free(d->t_s[v]);
            d->t_s[v] = NULL;
        }
    info->has_u = s.has_u;
    info->has_t = s.t_state > 0;
    return SC_OK;
}

/* ---------------------------------------------------------------------------------------------
 * The writer
 * ------------------------------------------------------------------------------------------- */

void sc_grid_write_header(FILE *fp, const sc_grid_plan *p)
{
    fprintf(fp, "# selfcal-grid v1\n# N = %d\n# pitch_mm = %.15g\n", p->n, p->pitch_mm);
    fprintf(fp, "# origin_mm = %.15g,%.15g\n", p->origin_mm[0], p->origin_mm[1]);
    if (p->stage_nx > 0 || p->stage_ny > 0)
        fprintf(fp, "# stage = %d,%d\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    const sc_grid_scale *sc = &p->scale;
    if (sc->has_plate_scale)
        fprintf(fp, "# plate_scale_ppm = %.15g, %.15g\n", sc->plate_scale_ppm,
                sc->u_plate_scale_ppm);
    if (sc->has_cte)
        fprintf(fp, "# plate_cte_ppm_per_K = %.15g, %.15g\n", sc->cte_ppm_per_K,
                sc->u_cte_ppm_per_K);
    if (sc->has_temps && sc->temp_u_K != SC_GRID_TEMP_U_K_DEFAULT)
        fprintf(fp, "# temp_u_K = %.15g\n", sc->temp_u_K);
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "# view %d: rot=%d shift=%d,%d", v, w->rot_deg, w->shift_x, w->shift_y);
        if (w->sigma_um > 0)
            fprintf(fp, " sigma_um=%.15g", w->sigma_um);
        if (sc->has_temps)
            fprintf(fp, " temp_C=%.15g", w->temp_C);
        if (w->restricted) {
            const char *sep = " rows=";
            for (int k = 0; k < p->n; ++k)
                if (w->row_sel[k]) {
                    fprintf(fp, "%s%d", sep, k);
                    sep = ",";
                }
            sep = " cols=";
            for (int k = 0; k < p->n; ++k)
                if (w->col_sel[k]) {
                    fprintf(fp, "%s%d", sep, k);
                    sep = ",";
                }
        }
        fputc('\n', fp);
    }
}

static sc_status finish(sc_afile *f, sc_error *err)
{
    return sc_afile_commit(f, err); /* a write that failed: "write error: <reason>" */
}

static void put_num(FILE *fp, const double *a, int k)
{
    char b[SC_NUMBER_BUF];
    fwrite(b, 1, (size_t)(sc_io_put_15g_opt(b, a, (size_t)k, 0) - b), fp);
}

void sc_grid_fprint_input(FILE *fp, const sc_grid_data *d)
{
    const sc_grid_plan *p = &d->plan;
    sc_grid_write_header(fp, p);
    int has_u = 0, has_t = 0;
    for (int v = 0; v < p->n_views; ++v)
        has_u |= d->ux_um[v] != NULL, has_t |= d->t_s[v] != NULL;
    fprintf(fp, COLUMN_HEADER "%s%s\n", has_u ? ",ux_um,uy_um" : "", has_t ? ",t_s" : "");
    int n = p->n;
    for (int v = 0; v < p->n_views; ++v)
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                int k = i * n + j;
                double x, y;
                if (!isfinite(d->dx_um[v][k]) || !isfinite(d->dy_um[v][k]) ||
                    !sc_grid_mark_stage_xy_mm(p, v, i, j, &x, &y))
                    continue;
                x += p->origin_mm[0] + d->dx_um[v][k] * 1e-3;
                y += p->origin_mm[1] + d->dy_um[v][k] * 1e-3;
                fprintf(fp, "%d,%d,%d,%.15f,%.15f", v, i, j, x, y);
                if (has_u) {
                    fputc(',', fp);
                    put_num(fp, d->ux_um[v], k);
                    fputc(',', fp);
                    put_num(fp, d->uy_um[v], k);
                }
                if (has_t) {
                    fputc(',', fp);
                    put_num(fp, d->t_s[v], k);
                }
                fputc('\n', fp);
            }
}

sc_status sc_grid_write_input(const char *path, const sc_grid_data *d, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_input(f.fp, d);
    return finish(&f, err);
}
