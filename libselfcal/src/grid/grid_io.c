/* Reading and writing the grid files of SPEC §1 (selfcal-grid v1 input/plan, map, artifact,
 * summary). */
#include "selfcal/grid_io.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"

#define COLUMN_HEADER "view,i,j,x_mm,y_mm"

sc_status sc_grid_data_alloc(sc_grid_data *d, sc_error *err)
{
    size_t nn = (size_t)d->plan.n * (size_t)d->plan.n;
    for (int v = 0; v < SC_GRID_MAX_VIEWS; ++v)
        d->dx_um[v] = d->dy_um[v] = d->ux_um[v] = d->uy_um[v] = d->t_s[v] = NULL;
    for (int v = 0; v < d->plan.n_views; ++v) {
        d->dx_um[v] = malloc(nn * sizeof(double));
        d->dy_um[v] = malloc(nn * sizeof(double));
        if (!d->dx_um[v] || !d->dy_um[v]) {
            sc_grid_data_free(d);
            return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data, N = %d)",
                                d->plan.n);
        }
        for (size_t k = 0; k < nn; ++k)
            d->dx_um[v][k] = d->dy_um[v][k] = NAN;
    }
    return SC_OK;
}

sc_status sc_grid_data_alloc_extra(sc_grid_data *d, int weights, int times, sc_error *err)
{
    size_t nn = (size_t)d->plan.n * (size_t)d->plan.n;
    for (int v = 0; v < d->plan.n_views; ++v) {
        double **a[3] = {&d->ux_um[v], &d->uy_um[v], &d->t_s[v]};
        for (int t = 0; t < 3; ++t) {
            if ((t < 2 && !weights) || (t == 2 && !times) || *a[t])
                continue;
            *a[t] = malloc(nn * sizeof(double));
            if (!*a[t])
                return sc_error_set(err, SC_E_NOMEM, NULL, 0, "out of memory (grid data)");
            for (size_t k = 0; k < nn; ++k)
                (*a[t])[k] = NAN;
        }
    }
    return SC_OK;
}

void sc_grid_data_free(sc_grid_data *d)
{
    for (int v = 0; v < SC_GRID_MAX_VIEWS; ++v) {
        free(d->dx_um[v]);
        free(d->dy_um[v]);
        free(d->ux_um[v]);
        free(d->uy_um[v]);
        free(d->t_s[v]);
        d->dx_um[v] = d->dy_um[v] = d->ux_um[v] = d->uy_um[v] = d->t_s[v] = NULL;
    }
}

/* ---------------------------------------------------------------------------------------------
 * Reader
 * ------------------------------------------------------------------------------------------- */

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

static int parse_double_pair(char *s, double *a, double *b)
{
    char *comma = strchr(s, ',');
    if (!comma)
        return -1;
    *comma = '\0';
    int ok = sc_parse_double(sc_str_trim(s), a) == 0 && sc_parse_double(sc_str_trim(comma + 1), b) == 0;
    *comma = ',';
    return ok ? 0 : -1;
}

/* A view line as written, validated once N is known. */
typedef struct view_decl {
    int id;
    long line;
    long rot, sx, sy;
    double sigma_um;
    int n_rows_sel, n_cols_sel;
    long rows[SC_GRID_MAX_N], cols[SC_GRID_MAX_N];
} view_decl;

/* Parse a comma list of indices into out (at most SC_GRID_MAX_N). */
static int parse_index_list(char *s, long *out, int *count)
{
    int n = 0;
    char *p = s;
    for (;;) {
        char *comma = strchr(p, ',');
        if (comma)
            *comma = '\0';
        if (n == SC_GRID_MAX_N || sc_parse_long(sc_str_trim(p), &out[n]) != 0)
            return -1;
        ++n;
        if (!comma)
            break;
        p = comma + 1;
    }
    *count = n;
    return 0;
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
    int have_rot = 0, have_shift = 0, have_rows = 0, have_cols = 0, have_sigma = 0;
    char *save = NULL;
    for (char *tok = strtok_r(colon + 1, " \t", &save); tok; tok = strtok_r(NULL, " \t", &save)) {
        char *eq = strchr(tok, '=');
        if (!eq)
            return sc_error_set(err, SC_E_INPUT, path, line,
                                "view %ld: expected key=value, got '%.40s'", id, tok);
        *eq = '\0';
        char *val = eq + 1;
        if (!strcmp(tok, "rot")) {
            if (have_rot++ || sc_parse_long(val, &vd->rot) != 0)
                return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: bad or repeated rot",
                                    id);
            if (vd->rot != 0 && vd->rot != 90 && vd->rot != 180 && vd->rot != 270)
                return sc_error_set(err, SC_E_INPUT, path, line,
                                    "view %ld: rot must be 0, 90, 180 or 270 (got %ld)", id,
                                    vd->rot);
        } else if (!strcmp(tok, "shift")) {
            if (have_shift++ || parse_long_pair(val, &vd->sx, &vd->sy) != 0)
                return sc_error_set(err, SC_E_INPUT, path, line,
                                    "view %ld: shift must be two whole numbers SX,SY", id);
        } else if (!strcmp(tok, "sigma_um")) {
            if (have_sigma++ || sc_parse_double(val, &vd->sigma_um) != 0 ||
                !(vd->sigma_um > 0) || !(vd->sigma_um <= SC_INPUT_MAX_ABS))
                return sc_error_set(err, SC_E_INPUT, path, line,
                                    "view %ld: sigma_um must be a positive number", id);
        } else if (!strcmp(tok, "rows")) {
            if (have_rows++ || parse_index_list(val, vd->rows, &vd->n_rows_sel) != 0)
                return sc_error_set(err, SC_E_INPUT, path, line,
                                    "view %ld: rows must be a comma list of plate rows", id);
        } else if (!strcmp(tok, "cols")) {
            if (have_cols++ || parse_index_list(val, vd->cols, &vd->n_cols_sel) != 0)
                return sc_error_set(err, SC_E_INPUT, path, line,
                                    "view %ld: cols must be a comma list of plate columns", id);
        } else {
            return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: unknown attribute '%.40s'",
                                id, tok);
        }
    }
    if (!have_rot)
        return sc_error_set(err, SC_E_INPUT, path, line, "view %ld: rot= is missing", id);
    if (!have_shift)
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

typedef struct read_state {
    sc_csv csv;
    view_decl *decl;     /* SC_GRID_MAX_VIEWS entries */
    long *mark_line[SC_GRID_MAX_VIEWS];
} read_state;

static void read_state_free(read_state *s)
{
    sc_csv_close(&s->csv);
    free(s->decl);
    for (int v = 0; v < SC_GRID_MAX_VIEWS; ++v)
        free(s->mark_line[v]);
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
    sc_status st = sc_csv_open(&s.csv, path, err);
    if (st != SC_OK)
        return st;
    s.decl = calloc(SC_GRID_MAX_VIEWS, sizeof *s.decl);
    if (!s.decl) {
        read_state_free(&s);
        return sc_error_set(err, SC_E_NOMEM, path, 0, "out of memory");
    }
    sc_grid_plan *p = &d->plan;
    long n_val = 0;
    double pitch = 0, ox = 0, oy = 0;
    long pitch_line = 0, origin_line = 0, stage_line = 0, stage_x = 0, stage_y = 0;
    int n_decl = 0, have_columns = 0, has_u = 0, has_t = 0, n_fields = 5;
    int got;

    /* First line: the format tag. */
    got = sc_csv_next_line(&s.csv, err);
    if (got < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    {
        char *t = got ? s.csv.text : (char *)"";
        int ok = 0;
        if (t[0] == '#') {
            char *rest = sc_str_trim(t + 1);
            char a[32], b[32], extra[8];
            ok = sscanf(rest, "%31s %31s %7s", a, b, extra) == 2 && !strcmp(a, "selfcal-grid") &&
                 !strcmp(b, "v1");
        }
        if (!ok) {
            st = sc_error_set(err, SC_E_INPUT, path, 1,
                              "not a selfcal-grid v1 file (the first line must be "
                              "'# selfcal-grid v1')");
            goto fail;
        }
        info->first_line = 1;
    }

    /* Header lines, up to the column header or the first data row. */
    while ((got = sc_csv_next_line(&s.csv, err)) > 0) {
        long ln = s.csv.line;
        if (sc_csv_is_blank(&s.csv))
            continue;
        if (s.csv.text[0] == '#') {
            char *body = sc_str_trim(s.csv.text + 1);
            if (!strncmp(body, "view", 4) && (isspace((unsigned char)body[4]) || isdigit((unsigned char)body[4]))) {
                if (n_decl == SC_GRID_MAX_VIEWS) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "more than %d views",
                                      SC_GRID_MAX_VIEWS);
                    goto fail;
                }
                view_decl *vd = &s.decl[n_decl];
                st = parse_view_line(path, ln, body, vd, err);
                if (st != SC_OK)
                    goto fail;
                for (int k = 0; k < n_decl; ++k)
                    if (s.decl[k].id == vd->id) {
                        st = sc_error_set(err, SC_E_INPUT, path, ln,
                                          "view %d is declared twice (first on line %ld)", vd->id,
                                          s.decl[k].line);
                        goto fail;
                    }
                ++n_decl;
                info->header_end_line = ln;
                continue;
            }
            char key[64], *val;
            char copy[512];
            snprintf(copy, sizeof copy, "%s", s.csv.text);
            if (!sc_header_kv(s.csv.text, key, sizeof key, &val)) {
                if (strchr(copy, '=')) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "unreadable header line '%.60s'",
                                      copy);
                    goto fail;
                }
                continue; /* a plain comment */
            }
            if (!strcmp(key, "N")) {
                if (info->n_line) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "N is given twice");
                    goto fail;
                }
                if (sc_parse_long(val, &n_val) != 0) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "N is not a whole number: '%.40s'",
                                      val);
                    goto fail;
                }
                if (n_val < 3 || n_val > SC_GRID_MAX_N) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "N = %ld is out of range 3..%d",
                                      n_val, SC_GRID_MAX_N);
                    goto fail;
                }
                if (n_val % 2 == 0) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln,
                                      "N = %ld is even (the plate needs a centre mark: N odd)",
                                      n_val);
                    goto fail;
                }
                info->n_line = ln;
            } else if (!strcmp(key, "pitch_mm")) {
                if (pitch_line) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "pitch_mm is given twice");
                    goto fail;
                }
                if (sc_parse_double(val, &pitch) != 0 || !(pitch > 0) || pitch > 1e6) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln,
                                      "pitch_mm must be a positive number: '%.40s'", val);
                    goto fail;
                }
                pitch_line = ln;
            } else if (!strcmp(key, "origin_mm")) {
                if (origin_line) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "origin_mm is given twice");
                    goto fail;
                }
                if (parse_double_pair(val, &ox, &oy) != 0 || fabs(ox) > 1e6 || fabs(oy) > 1e6) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln,
                                      "origin_mm must be two numbers x,y: '%.40s'", val);
                    goto fail;
                }
                origin_line = ln;
            } else if (!strcmp(key, "stage")) {
                if (stage_line) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln, "stage is given twice");
                    goto fail;
                }
                if (parse_long_pair(val, &stage_x, &stage_y) != 0 || stage_x < 3 ||
                    stage_y < 3 || stage_x % 2 == 0 || stage_y % 2 == 0 ||
                    stage_x > SC_GRID_MAX_STAGE || stage_y > SC_GRID_MAX_STAGE) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln,
                                      "stage must be NX,NY, both odd and in 3..%d: '%.40s'",
                                      SC_GRID_MAX_STAGE, val);
                    goto fail;
                }
                stage_line = ln;
            } else {
                st = sc_error_set(err, SC_E_INPUT, path, ln,
                                  "unknown header '%.40s' (expected N, pitch_mm, origin_mm, stage "
                                  "or view)",
                                  key);
                goto fail;
            }
            info->header_end_line = ln;
            continue;
        }
        /* Not a comment: the column header, or data without one. */
        if (sc_csv_split(&s.csv, err) < 0) {
            st = err ? err->code : SC_E_INPUT;
            goto fail;
        }
        if ((n_fields = is_column_header(&s.csv, &has_u, &has_t)) > 0) {
            have_columns = 1;
            info->header_end_line = ln;
            break;
        }
        st = sc_error_set(err, SC_E_INPUT, path, ln,
                          "expected the column header '" COLUMN_HEADER "' before the data");
        goto fail;
    }
    if (got < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }

    /* The header is complete: check and build the plan. */
    long where = info->header_end_line ? info->header_end_line : 1;
    if (!info->n_line) {
        st = sc_error_set(err, SC_E_INPUT, path, where, "header line '# N = ...' is missing");
        goto fail;
    }
    if (!pitch_line) {
        st = sc_error_set(err, SC_E_INPUT, path, where, "header line '# pitch_mm = ...' is missing");
        goto fail;
    }
    if (n_decl == 0) {
        st = sc_error_set(err, SC_E_INPUT, path, where,
                          "no '# view K: rot=R shift=SX,SY' line in the header");
        goto fail;
    }
    p->n = (int)n_val;
    p->pitch_mm = pitch;
    p->origin_mm[0] = ox;
    p->origin_mm[1] = oy;
    p->n_views = n_decl;
    p->stage_nx = (int)stage_x;
    p->stage_ny = (int)stage_y;
    int n = p->n;
    for (int v = 0; v < n_decl; ++v) {
        view_decl *vd = &s.decl[v];
        sc_grid_view *w = &p->view[v];
        memset(w, 0, sizeof *w);
        if (labs(vd->sx) > 2L * SC_GRID_MAX_STAGE || labs(vd->sy) > 2L * SC_GRID_MAX_STAGE) {
            st = sc_error_set(err, SC_E_INPUT, path, vd->line,
                              "view %d: shift %ld,%ld moves the plate off the stage grid", vd->id,
                              vd->sx, vd->sy);
            goto fail;
        }
        w->sigma_um = vd->sigma_um;
        w->rot_deg = (int)vd->rot;
        w->shift_x = (int)vd->sx;
        w->shift_y = (int)vd->sy;
        w->restricted = vd->n_rows_sel > 0 || vd->n_cols_sel > 0;
        for (int k = 0; k < vd->n_rows_sel; ++k) {
            if (vd->rows[k] < 0 || vd->rows[k] >= n) {
                st = sc_error_set(err, SC_E_INPUT, path, vd->line,
                                  "view %d: row %ld is off the plate (0..%d)", vd->id, vd->rows[k],
                                  n - 1);
                goto fail;
            }
            w->row_sel[vd->rows[k]] = 1;
        }
        for (int k = 0; k < vd->n_cols_sel; ++k) {
            if (vd->cols[k] < 0 || vd->cols[k] >= n) {
                st = sc_error_set(err, SC_E_INPUT, path, vd->line,
                                  "view %d: column %ld is off the plate (0..%d)", vd->id,
                                  vd->cols[k], n - 1);
                goto fail;
            }
            w->col_sel[vd->cols[k]] = 1;
        }
        int any = 0;
        for (int i = 0; i < n && !any; ++i)
            for (int j = 0; j < n && !any; ++j)
                any = sc_grid_view_measures(p, v, i, j);
        if (!any) {
            st = sc_error_set(err, SC_E_INPUT, path, vd->line,
                              "view %d (rot=%d shift=%d,%d) is off the %dx%d stage grid: it "
                              "lands no mark it measures there",
                              vd->id, w->rot_deg, w->shift_x, w->shift_y, sc_grid_stage_nx(p),
                              sc_grid_stage_ny(p));
            goto fail;
        }
        info->view_line[v] = vd->line;
        info->view_id[v] = vd->id;
    }
    st = sc_grid_plan_check(p, err);
    if (st != SC_OK) {
        if (err) {
            snprintf(err->file, sizeof err->file, "%s", path);
            err->line = where;
        }
        goto fail;
    }
    st = sc_grid_data_alloc(d, err);
    if (st == SC_OK)
        st = sc_grid_data_alloc_extra(d, has_u, has_t, err);
    if (st != SC_OK)
        goto fail;

    /* Data rows. */
    int t_state = 0; /* t_s column: 0 no row yet, 1 rows carry times, -1 rows leave it empty */
    size_t nn = (size_t)n * (size_t)n;
    while (have_columns && (got = sc_csv_next_line(&s.csv, err)) > 0) {
        long ln = s.csv.line;
        if (sc_csv_is_blank(&s.csv))
            continue;
        if (s.csv.text[0] == '#') {
            if (strchr(s.csv.text, '=') || strstr(s.csv.text, "view")) {
                st = sc_error_set(err, SC_E_INPUT, path, ln,
                                  "header line after the column header (headers come first)");
                goto fail;
            }
            continue;
        }
        if (sc_csv_split(&s.csv, err) < 0) {
            st = err ? err->code : SC_E_INPUT;
            goto fail;
        }
        if (s.csv.nfields != n_fields) {
            st = sc_error_set(err, SC_E_INPUT, path, ln,
                              "expected %d fields (as the column header), got %d", n_fields,
                              s.csv.nfields);
            goto fail;
        }
        long vid, i, j;
        double x, y;
        if ((st = sc_csv_long(&s.csv, 0, "view", &vid, err)) != SC_OK ||
            (st = sc_csv_long(&s.csv, 1, "i", &i, err)) != SC_OK ||
            (st = sc_csv_long(&s.csv, 2, "j", &j, err)) != SC_OK ||
            (st = sc_csv_double(&s.csv, 3, "x_mm", &x, err)) != SC_OK ||
            (st = sc_csv_double(&s.csv, 4, "y_mm", &y, err)) != SC_OK)
            goto fail;
        int v = -1;
        for (int k = 0; k < n_decl; ++k)
            if (s.decl[k].id == vid)
                v = k;
        if (v < 0) {
            st = sc_error_set(err, SC_E_INPUT, path, ln, "view %ld is not declared in the header",
                              vid);
            goto fail;
        }
        if (i < 0 || i >= n || j < 0 || j >= n) {
            st = sc_error_set(err, SC_E_INPUT, path, ln,
                              "mark (%ld,%ld) is off the plate (i, j in 0..%d)", i, j, n - 1);
            goto fail;
        }
        int ni, nj;
        if (!sc_grid_mark_node(p, v, (int)i, (int)j, &ni, &nj)) {
            st = sc_error_set(err, SC_E_INPUT, path, ln,
                              "mark (%ld,%ld) does not land on the stage grid in view %ld "
                              "(rot=%d shift=%d,%d)",
                              i, j, vid, p->view[v].rot_deg, p->view[v].shift_x,
                              p->view[v].shift_y);
            goto fail;
        }
        if (!sc_grid_view_measures(p, v, (int)i, (int)j)) {
            st = sc_error_set(err, SC_E_INPUT, path, ln,
                              "mark (%ld,%ld) is not selected by view %ld's rows=/cols=", i, j,
                              vid);
            goto fail;
        }
        if (!s.mark_line[v]) {
            s.mark_line[v] = calloc(nn, sizeof(long));
            if (!s.mark_line[v]) {
                st = sc_error_set(err, SC_E_NOMEM, path, ln, "out of memory");
                goto fail;
            }
        }
        size_t k = (size_t)i * n + (size_t)j;
        if (s.mark_line[v][k]) {
            st = sc_error_set(err, SC_E_INPUT, path, ln,
                              "duplicate measurement of mark (%ld,%ld) in view %ld (first on line "
                              "%ld)",
                              i, j, vid, s.mark_line[v][k]);
            goto fail;
        }
        s.mark_line[v][k] = ln;
        double nx, ny;
        sc_grid_node_xy_mm(p, ni, nj, &nx, &ny);
        nx += p->origin_mm[0];
        ny += p->origin_mm[1];
        double ex = x - nx, ey = y - ny;
        if (fabs(ex) > 0.5 * p->pitch_mm || fabs(ey) > 0.5 * p->pitch_mm) {
            st = sc_error_set(err, SC_E_INPUT, path, ln,
                              "header (N/pitch/origin/rot/shift) contradicts the data: mark "
                              "(%ld,%ld) of view %ld measured at (%.6g, %.6g) mm, more than half a "
                              "pitch from its nominal position (%.6g, %.6g) mm",
                              i, j, vid, x, y, nx, ny);
            goto fail;
        }
        d->dx_um[v][k] = ex * 1000.0;
        d->dy_um[v][k] = ey * 1000.0;
        for (int c = 0; has_u && c < 2; ++c) {
            const char *name = c ? "uy_um" : "ux_um";
            double u = NAN;
            if (s.csv.field[5 + c][0] == '\0') {
                if (!(p->view[v].sigma_um > 0)) {
                    st = sc_error_set(err, SC_E_INPUT, path, ln,
                                      "%s is empty and view %ld states no sigma_um", name, vid);
                    goto fail;
                }
            } else if (sc_parse_double(s.csv.field[5 + c], &u) != 0 || !(u > 0) ||
                       !(u <= SC_INPUT_MAX_ABS)) {
                st = sc_error_set(err, SC_E_INPUT, path, ln,
                                  "%s must be a positive number (a standard uncertainty in um), "
                                  "got '%.40s'",
                                  name, s.csv.field[5 + c]);
                goto fail;
            }
            (c ? d->uy_um : d->ux_um)[v][k] = u;
        }
        if (has_t) {
            const char *f = s.csv.field[n_fields - 1];
            int here = f[0] != '\0' ? 1 : -1;
            if (t_state && here != t_state) {
                st = sc_error_set(err, SC_E_INPUT, path, ln,
                                  "t_s is %s here but %s on earlier rows (give it on every row or "
                                  "on none)",
                                  here > 0 ? "given" : "empty", here > 0 ? "empty" : "given");
                goto fail;
            }
            t_state = here;
            double t = NAN;
            if (here > 0 && (sc_parse_double(f, &t) != 0 || !(fabs(t) <= 1e12))) {
                st = sc_error_set(err, SC_E_INPUT, path, ln, "t_s must be a number of seconds, "
                                  "got '%.40s'", f);
                goto fail;
            }
            d->t_s[v][k] = t;
        }
        info->n_rows++;
        info->view_rows[v]++;
    }
    if (got < 0) {
        st = err ? err->code : SC_E_INPUT;
        goto fail;
    }
    if (t_state < 0)
        for (int v = 0; v < SC_GRID_MAX_VIEWS; ++v) {
            free(d->t_s[v]);
            d->t_s[v] = NULL;
        }
    info->has_u = has_u;
    info->has_t = t_state > 0;
    read_state_free(&s);
    return SC_OK;

fail:
    read_state_free(&s);
    sc_grid_data_free(d);
    return st == SC_OK ? SC_E_INTERNAL : st;
}

/* ---------------------------------------------------------------------------------------------
 * Writers
 * ------------------------------------------------------------------------------------------- */

void sc_grid_write_header(FILE *fp, const sc_grid_plan *p)
{
    fprintf(fp, "# selfcal-grid v1\n# N = %d\n# pitch_mm = %.15g\n", p->n, p->pitch_mm);
    fprintf(fp, "# origin_mm = %.15g,%.15g\n", p->origin_mm[0], p->origin_mm[1]);
    if (p->stage_nx > 0 || p->stage_ny > 0)
        fprintf(fp, "# stage = %d,%d\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "# view %d: rot=%d shift=%d,%d", v, w->rot_deg, w->shift_x, w->shift_y);
        if (w->sigma_um > 0)
            fprintf(fp, " sigma_um=%.15g", w->sigma_um);
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
    if (ferror(f->fp)) {
        sc_afile_abort(f);
        return sc_error_set(err, SC_E_IO, f->path, 0, "write error");
    }
    return sc_afile_commit(f, err);
}

static void put_num(FILE *fp, const double *a, int k)
{
    if (a && isfinite(a[k]))
        fprintf(fp, "%.15g", a[k]);
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
                int k = i * n + j, ni, nj;
                if (!isfinite(d->dx_um[v][k]) || !isfinite(d->dy_um[v][k]))
                    continue;
                if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
                    continue;
                double x, y;
                sc_grid_node_xy_mm(p, ni, nj, &x, &y);
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

sc_stage_map sc_grid_stage_map(const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                               const double *ugx_um, const double *ugy_um)
{
    sc_stage_map m;
    m.nx = sc_grid_stage_nx(p);
    m.ny = sc_grid_stage_ny(p);
    sc_grid_node_xy_mm(p, 0, 0, &m.x0_mm, &m.y0_mm);
    m.x0_mm += p->origin_mm[0];
    m.y0_mm += p->origin_mm[1];
    m.px_mm = m.py_mm = p->pitch_mm;
    /* a view: the arrays stay the caller's and are only read */
    m.gx_um = (double *)(uintptr_t)gx_um;
    m.gy_um = (double *)(uintptr_t)gy_um;
    m.ugx_um = (double *)(uintptr_t)ugx_um;
    m.ugy_um = (double *)(uintptr_t)ugy_um;
    return m;
}

void sc_grid_fprint_map(FILE *fp, const sc_grid_plan *p, const double *gx_um, const double *gy_um,
                        const double *ugx_um, const double *ugy_um)
{
    sc_stage_map m = sc_grid_stage_map(p, gx_um, gy_um, ugx_um, ugy_um);
    sc_stage_map_fprint(fp, &m);
}

sc_status sc_grid_write_map(const char *path, const sc_grid_plan *p, const double *gx_um,
                            const double *gy_um, const double *ugx_um, const double *ugy_um,
                            sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_map(f.fp, p, gx_um, gy_um, ugx_um, ugy_um);
    return finish(&f, err);
}

void sc_grid_fprint_artifact(FILE *fp, const sc_grid_plan *p, const double *ax_um,
                             const double *ay_um)
{
    int n = p->n;
    fprintf(fp, "i,j,ax_um,ay_um\n");
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            fprintf(fp, "%d,%d,", i, j);
            put_num(fp, ax_um, i * n + j); /* an unmeasured (damaged) mark: empty */
            fputc(',', fp);
            put_num(fp, ay_um, i * n + j);
            fputc('\n', fp);
        }
}

sc_status sc_grid_write_artifact(const char *path, const sc_grid_plan *p, const double *ax_um,
                                 const double *ay_um, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_artifact(f.fp, p, ax_um, ay_um);
    return finish(&f, err);
}

static void json_num(FILE *fp, double v)
{
    if (isfinite(v))
        fprintf(fp, "%.15g", v);
    else
        fputs("null", fp);
}

static void json_kv(FILE *fp, const char *key, double v)
{
    fprintf(fp, ", \"%s\": ", key);
    json_num(fp, v);
}

void sc_grid_fprint_summary(FILE *fp, const char *method, const sc_grid_plan *p,
                            const sc_grid_result *res)
{
    fprintf(fp, "{\n  \"format\": \"selfcal-grid-summary v1\",\n  \"method\": \"%s\",\n", method);
    fprintf(fp, "  \"N\": %d,\n  \"pitch_mm\": %.15g,\n  \"origin_mm\": [%.15g, %.15g],\n", p->n,
            p->pitch_mm, p->origin_mm[0], p->origin_mm[1]);
    fprintf(fp, "  \"stage\": [%d, %d],\n", sc_grid_stage_nx(p), sc_grid_stage_ny(p));
    fputs("  \"O\": ", fp);
    json_num(fp, res->O);
    fputs(",\n  \"uO\": ", fp);
    json_num(fp, res->uO);
    fputs(",\n  \"R\": ", fp);
    json_num(fp, res->R);
    fputs(",\n  \"uR\": ", fp);
    json_num(fp, res->uR);
    fputs(",\n  \"views\": [\n", fp);
    for (int v = 0; v < p->n_views; ++v) {
        const sc_grid_view *w = &p->view[v];
        fprintf(fp, "    {\"view\": %d, \"rot\": %d, \"shift\": [%d, %d]", v, w->rot_deg,
                w->shift_x, w->shift_y);
        json_kv(fp, "tx_um", res->tx_um[v]);
        json_kv(fp, "ty_um", res->ty_um[v]);
        json_kv(fp, "theta_urad", res->theta_urad[v]);
        json_kv(fp, "utx_um", res->utx_um[v]);
        json_kv(fp, "uty_um", res->uty_um[v]);
        json_kv(fp, "utheta_urad", res->utheta_urad[v]);
        if (res->drift) {
            json_kv(fp, "vx_um_s", res->vx_um_s[v]);
            json_kv(fp, "vy_um_s", res->vy_um_s[v]);
            json_kv(fp, "uvx_um_s", res->uvx_um_s[v]);
            json_kv(fp, "uvy_um_s", res->uvy_um_s[v]);
        }
        fprintf(fp, "}%s\n", v + 1 < p->n_views ? "," : "");
    }
    fputs("  ],\n  \"residual_rms_um\": ", fp);
    json_num(fp, res->residual_rms_um);
    fputs(",\n  \"sigma_r_est_um\": ", fp);
    json_num(fp, res->sigma_r_est_um);
    fputs(",\n  \"sigma_r_used_um\": ", fp);
    json_num(fp, res->sigma_r_used_um);
    fprintf(fp, ",\n  \"weighted\": %s,\n  \"variance_factor\": ", res->weighted ? "true" : "false");
    json_num(fp, res->variance_factor);
    fputs(",\n  \"chi2_95_interval\": [", fp);
    json_num(fp, res->chi2_lo);
    fputs(", ", fp);
    json_num(fp, res->chi2_hi);
    fprintf(fp, "],\n  \"chi2_test\": \"%s\",\n  \"drift\": \"%s\"",
            !isfinite(res->variance_factor) ? "n/a" : res->chi2_pass ? "pass" : "fail",
            res->drift ? "linear" : "none");
    fprintf(fp, ",\n  \"misalignment_unique\": %s", res->misalignment_unique ? "true" : "false");
    fprintf(fp, ",\n  \"n_measurements\": %ld,\n  \"dof\": %ld\n}\n", res->n_measurements,
            res->dof);
}

sc_status sc_grid_write_summary(const char *path, const char *method, const sc_grid_plan *p,
                                const sc_grid_result *res, sc_error *err)
{
    sc_afile f;
    sc_status st = sc_afile_open(&f, path, err);
    if (st != SC_OK)
        return st;
    sc_grid_fprint_summary(f.fp, method, p, res);
    return finish(&f, err);
}

/* ---------------------------------------------------------------------------------------------
 * Residuals (SPEC §5) and numpy .npy matrices
 * ------------------------------------------------------------------------------------------- */

void sc_grid_fprint_residuals(FILE *fp, const sc_grid_plan *p, const int *view_id,
                              const double *rx_um, const double *ry_um, const double *tx,
                              const double *ty, const unsigned char *outlier)
{
    int n = p->n;
    size_t nn = (size_t)n * n;
    fputs("view,i,j,rx_um,ry_um,tx,ty,outlier\n", fp);
    for (int v = 0; v < p->n_views; ++v)
        for (size_t k = 0; k < nn; ++k) {
            size_t at = (size_t)v * nn + k;
            if (!isfinite(rx_um[at]))
                continue;
            fprintf(fp, "%d,%d,%d,%.15g,%.15g,", view_id ? view_id[v] : v, (int)(k / n),
                    (int)(k % n), rx_um[at], ry_um[at]);
            put_num(fp, tx, (int)at);
            fputc(',', fp);
            put_num(fp, ty, (int)at);
            fprintf(fp, ",%d\n", outlier && outlier[at] ? 1 : 0);
        }
}

void sc_fprint_npy(FILE *fp, const double *a, long rows, long cols)
{
    char head[128];
    int len = snprintf(head, sizeof head,
                       "{'descr': '<f8', 'fortran_order': False, 'shape': (%ld, %ld), }", rows,
                       cols);
    int total = 10 + len + 1, pad = (64 - total % 64) % 64;
    unsigned hl = (unsigned)(len + pad + 1);
    fwrite("\x93NUMPY\x01\x00", 1, 8, fp);
    fputc((int)(hl & 0xff), fp);
    fputc((int)(hl >> 8), fp);
    fwrite(head, 1, (size_t)len, fp);
    for (int k = 0; k < pad; ++k)
        fputc(' ', fp);
    fputc('\n', fp);
    const unsigned one = 1;
    int little = *(const unsigned char *)&one == 1;
    for (long k = 0; k < rows * cols; ++k) {
        unsigned char b[8];
        memcpy(b, &a[k], 8);
        if (!little)
            for (int t = 0; t < 4; ++t) {
                unsigned char c = b[t];
                b[t] = b[7 - t];
                b[7 - t] = c;
            }
        fwrite(b, 1, 8, fp);
    }
}
