/* selfcal plan — does a view plan identify G, and how precisely? (before touching the plate) */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "selfcal/grid_io.h"
#include "selfcal/grid_lsq.h"

static const char *USAGE =
    "usage: selfcal plan PLAN.csv\n"
    "\n"
    "Reads a selfcal-grid v1 header (a plan file: header lines only) or a data file (then the\n"
    "marks actually measured count) and prints, first:\n"
    "  identifiable: yes|no      does the plan determine G (in the SPEC gauge)?\n"
    "  free: K                   independent G patterns beyond the gauge left free (0 if yes)\n"
    "  sigma_c_ratio_rms: X      predicted RMS over nodes of std(G)/sigma_r (least squares)\n"
    "  sigma_c_ratio_max: Y      the worst node component\n"
    "For a plan that does not identify G both ratios are printed as 'inf'.\n"
    "Then: N, pitch, the views with the marks each measures, equations, unknowns, constraints\n"
    "and which closed-form methods (ye, double-shift) the plan supports.\n";

/* 1 if every mark the view would measure (all on the grid, or row c / cols c, c+1) is measured. */
static int view_complete(const sc_grid_data *d, int has_data, int v, int partial)
{
    const sc_grid_plan *p = &d->plan;
    int n = p->n, c = (n - 1) / 2;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int ni, nj;
            if (!sc_grid_mark_node(p, v, i, j, &ni, &nj))
                continue;
            if (partial && i != c && j != c && j != c + 1)
                continue;
            int meas = has_data ? isfinite(d->dx_um[v][i * n + j]) : sc_grid_view_measures(p, v, i, j);
            if (!meas)
                return 0;
        }
    return 1;
}

static int supports(const sc_grid_data *d, int has_data, const int (*need)[4], int k)
{
    for (int t = 0; t < k; ++t) {
        int v = sc_grid_find_view(&d->plan, need[t][0], need[t][1], need[t][2]);
        if (v < 0 || !view_complete(d, has_data, v, need[t][3]))
            return 0;
    }
    return 1;
}

int cmd_plan(int argc, char **argv)
{
    const char *in = NULL;
    for (int a = 1; a < argc; ++a) {
        if (!strcmp(argv[a], "--help") || !strcmp(argv[a], "-h")) {
            fputs(USAGE, stdout);
            return CLI_OK;
        }
        if (argv[a][0] == '-' && strcmp(argv[a], "-") != 0)
            return cli_usage_error("plan", "unknown option '%s' (see --help)", argv[a]);
        if (in)
            return cli_usage_error("plan", "one plan file only (see --help)");
        in = argv[a];
    }
    if (!in)
        return cli_usage_error("plan", "a plan file is required (see --help)");
    sc_error err;
    sc_error_clear(&err);
    sc_grid_data d;
    sc_grid_file_info fi;
    sc_status st = sc_grid_read(in, &d, &fi, &err);
    if (st != SC_OK)
        return cli_report(&err);
    int has_data = fi.n_rows > 0;
    sc_grid_lsq *q = NULL;
    st = sc_grid_lsq_create(&d.plan, has_data ? &d : NULL, &q, &err);
    if (st != SC_OK) {
        sc_grid_data_free(&d);
        if (!err.file[0]) {
            snprintf(err.file, sizeof err.file, "%s", in);
            err.line = fi.header_end_line;
        }
        return cli_report(&err);
    }
    sc_grid_lsq_info qi;
    sc_grid_lsq_get_info(q, &qi);
    const sc_grid_plan *p = &d.plan;
    int n = p->n;
    printf("identifiable: %s\n", qi.identifiable ? "yes" : "no");
    printf("free: %ld\n", qi.identifiable ? 0L : qi.free_dof);
    if (qi.identifiable) {
        printf("sigma_c_ratio_rms: %.6g\n", qi.sigma_c_ratio_rms);
        printf("sigma_c_ratio_max: %.6g\n", qi.sigma_c_ratio_max);
    } else {
        printf("sigma_c_ratio_rms: inf\nsigma_c_ratio_max: inf\n");
    }
    printf("N: %d\npitch_mm: %g\norigin_mm: %g,%g\n", n, p->pitch_mm, p->origin_mm[0],
           p->origin_mm[1]);
    printf("source: %s\n", has_data ? "data file (the marks measured)" : "plan (the marks the views select)");
    printf("views: %d\n", p->n_views);
    long empty_views = 0, unseen_marks = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int seen = 0;
            for (int v = 0; v < p->n_views && !seen; ++v)
                seen = has_data ? isfinite(d.dx_um[v][i * n + j]) : sc_grid_view_measures(p, v, i, j);
            unseen_marks += !seen;
        }
    for (int v = 0; v < p->n_views; ++v) {
        long marks = 0;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j)
                marks += has_data ? isfinite(d.dx_um[v][i * n + j]) : sc_grid_view_measures(p, v, i, j);
        empty_views += marks == 0;
        printf("view %d: rot=%d shift=%d,%d%s marks=%ld\n", fi.view_id[v], p->view[v].rot_deg,
               p->view[v].shift_x, p->view[v].shift_y, p->view[v].restricted ? " (rows/cols)" : "",
               marks);
    }
    printf("equations: %ld\nunknowns: %ld\nconstraints: %ld\n", qi.n_equations, qi.n_unknowns,
           qi.n_constraints);
    /* Equations minus the rank: the gauge, a view without marks (its misalignment) and a mark no
     * view measures (its plate error) leave unknowns undetermined without costing equations. */
    if (qi.identifiable)
        printf("residual_dof: %ld\n", qi.n_equations + qi.n_constraints - qi.n_unknowns +
                                           3 * empty_views + 2 * unseen_marks);
    if (empty_views || unseen_marks)
        printf("note: %ld view(s) without marks, %ld mark(s) measured in no view (their "
               "misalignment / plate error stay unknown)\n",
               empty_views, unseen_marks);
    static const int ye[3][4] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 1, 0, 0}};
    static const int ds[4][4] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 2, 0, 0}, {0, -3, 0, 1}};
    printf("method ye: %s\n", supports(&d, has_data, ye, 3) ? "yes" : "no");
    printf("method double-shift: %s\n", n >= 9 && supports(&d, has_data, ds, 4) ? "yes" : "no");
    printf("method lsq: %s\n", qi.identifiable ? "yes" : "no");
    sc_grid_lsq_destroy(q);
    sc_grid_data_free(&d);
    return CLI_OK;
}
