/* selfcal plan — does a view plan identify G, and how precisely? (before touching the plate) */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "selfcal/grid_exact.h"
#include "selfcal/grid_io.h"
#include "selfcal/atomic_file.h"
#include "selfcal/csv.h"
#include "selfcal/grid_lsq.h"
#include "selfcal/grid_sim.h"

static const char USAGE[] =
    "usage: selfcal plan PLAN.csv [--drift linear] [--max-memory SIZE]\n"
    "       selfcal plan --design --stage NX,NY --n N [--pitch-mm P] [--origin-mm X,Y] [-o PLAN.csv]\n"
    "                    [--max-memory SIZE]\n"
    "\n"
    "Reads a selfcal-grid v1 header (a plan file: header lines only) or a data file (then the\n"
    "marks actually measured count) and prints, first:\n"
    "  identifiable: yes|no      does the plan determine G (in the SPEC gauge)?\n"
    "  free: K                   independent G patterns beyond the gauge left free (0 if yes)\n"
    "  sigma_c_ratio_rms: X      predicted RMS over nodes of std(G)/sigma_r (least squares)\n"
    "  sigma_c_ratio_max: Y      the worst node component\n"
    "  (views or data stating uncertainties: the ratios are the plan's with equal weights, and\n"
    "   sigma_c_rms_um / sigma_c_max_um give std(G) with the stated ones)\n"
    "For a plan that does not identify G both ratios are printed as 'inf'.\n"
    "Then: N, pitch, the views with the marks each measures, equations, unknowns, constraints\n"
    "and which closed-form methods (ye, double-shift) the plan supports. For an identifying\n"
    "plan, Baarda's internal reliability: how many coordinate equations the outlier test can\n"
    "check (untestable: a mark seen in one view only, whose plate error absorbs any error), the\n"
    "smallest and mean redundancy r = 1 - h (h the leverage), and the minimal detectable blunder\n"
    "in units of the coordinate's sigma, (crit + 0.84)/sqrt(r): found with 80 % power by the\n"
    "default outlier test (alpha 0.05 for the data set) at the least redundant coordinate\n"
    "(mdb_ratio_max) and at the mean redundancy (mdb_ratio_mean_r).\n"
    "A stage node no view measures leaves G free there (identifiable: no, counted in free).\n"
    "--drift linear: analyse with per-view drift rates as unknowns (times from the data's t_s,\n"
    "or for a plan file one raster position per second in serpentine plate order).\n"
    "--design: propose a plan for an NX x NY stage and an N x N plate: rot-0 placements on a\n"
    "raster covering the stage plus a rot-90 and a shift +1,0 placement at the centre, with the\n"
    "largest raster step (fewest placements) that identifies G; prints identifiable, free and the\n"
    "sigma_c ratios for it with its views, and writes its header to -o (a plan file for\n"
    "'selfcal simulate grid --plan'; 'selfcal plan PLAN.csv' gives the full analysis).\n"
    "A plan whose analysis would need more memory than this machine has available (or than\n"
    "--max-memory SIZE: bytes, or K, M, G, T, powers of 1024) is refused up front (exit 1).\n";

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

/* Stages of more nodes than this take a second or more to analyse (per candidate raster of the
 * designer): each analysis is announced on stderr. */
#define ANNOUNCE_NODES 100000

/* 1 if the least-squares analysis of plan p is long enough to announce (ANNOUNCE_NODES); then
 * *unknowns: what it solves for (G at every node, 3 misalignments a view, 5 with drift). */
static int worth_announcing(const sc_grid_plan *p, int drift, long *unknowns)
{
    long nodes = sc_grid_stage_nodes(p);
    *unknowns = 2 * nodes + (drift ? 5L : 3L) * p->n_views;
    return nodes > ANNOUNCE_NODES;
}

/* Nodes whose σ plan --design computes where every node's does not fit the memory. */
#define DESIGN_SIGMA_SAMPLE 64

/* The designer: the largest raster step that identifies G. */
static int design_print(const sc_grid_plan *bp, const sc_grid_lsq_info *bip, int n, int sx_i,
                        int sy_i, double pitch, const char *out);

/* What plan --design is asked. */
typedef struct design_args {
    double stage[2], n, pitch, origin[2]; /* NX,NY; N; mm; mm */
    const char *out;
    double max_bytes;
    int design;
} design_args;

#define F(field) offsetof(design_args, field)
/* plan --design's options (cli_opts.h), in the order of its --help */
static const cli_opt DESIGN_OPTS[] = {
    {"--design", CLI_FLAG, F(design), .help = "design a plan (the options below)"},
    {"--stage", CLI_PAIR, F(stage), "NX,NY", .bad = "--stage needs NX,NY, got '%s'",
     .help = "the stage's nodes (odd, >= 3; required)"},
    {"--n", CLI_DOUBLE, F(n), "N", -HUGE_VAL, HUGE_VAL, .bad = "--n needs a number, got '%s'",
     .help = "the plate's marks per side (odd, >= 3; required)"},
    {"--pitch-mm", CLI_DOUBLE, F(pitch), "P", 0, HUGE_VAL, CLI_MIN_OPEN,
     .bad = "--pitch-mm needs a positive number", .def = "1", .help = "the pitch (mm)"},
    {"--origin-mm", CLI_PAIR, F(origin), "X,Y", .bad = "--origin-mm needs X,Y, got '%s'",
     .def = "0,0", .help = "the stage's first node (mm)"},
    {"-o|--out", CLI_STRING, F(out), "PLAN.csv", .help = "the plan's header (a plan file)"},
    {"--max-memory", CLI_CUSTOM, F(max_bytes), "SIZE", .parse = cli_opt_max_memory,
     .def = "the available memory", .help = "refuse an analysis estimated to need more"},
};
#undef F

static const cli_cmd_opts design_opts = {
    "plan", USAGE, DESIGN_OPTS, (int)(sizeof DESIGN_OPTS / sizeof DESIGN_OPTS[0]), 0, NULL, NULL,
    NULL, NULL, CLI_NO_OPERAND | CLI_NO_HELP, NULL, NULL,
};

static int design(int argc, char **argv)
{
    design_args g = {.pitch = 1, .max_bytes = cli_memory_bytes()};
    int rc = cli_opts_parse(&design_opts, argc, argv, &g);
    if (rc >= 0)
        return rc;
    double sx = g.stage[0], sy = g.stage[1], n_d = g.n, pitch = g.pitch, ox = g.origin[0],
           oy = g.origin[1], max_bytes = g.max_bytes;
    const char *out = g.out;
    if (n_d != floor(n_d) || n_d < 3 || n_d > SC_GRID_MAX_N || fmod(n_d, 2) == 0 ||
        sx != floor(sx) || sy != floor(sy) || sx < 3 || sy < 3 || fmod(sx, 2) == 0 ||
        fmod(sy, 2) == 0 || sx > SC_GRID_MAX_STAGE || sy > SC_GRID_MAX_STAGE)
        return cli_usage_error("plan", "--design needs --n N and --stage NX,NY, all odd and >= 3");
    int n = (int)n_d;
    sc_error err;
    sc_error_clear(&err);
    sc_grid_plan best = {0};
    sc_grid_lsq_info bi;
    int found = 0, sampled = 0;
    for (int step = n - 1; step >= 1 && !found; step = step > 1 ? step * 2 / 3 : 0) {
        sc_grid_plan p;
        if (sc_grid_plan_stitch_step(n, (int)sx, (int)sy, step, pitch, ox, oy, &p, &err) != SC_OK)
            break;
        long unknowns;
        if (worth_announcing(&p, 0, &unknowns)) /* seconds to minutes each */
            fprintf(stderr, "selfcal: plan --design: trying a raster step of %d (%d placements, "
                            "%ld unknowns)\n", step, p.n_views, unknowns);
        sc_grid_lsq_plan *q = NULL;
        sc_grid_lsq_opts only = {.node_sigma_only = 1, /* what is printed: no σ of O, R */
                                 .max_bytes = max_bytes};
        sc_status pst = sc_grid_lsq_plan_create(&p, NULL, &only, &q, &err);
        if (pst == SC_E_NOMEM) { /* every node's σ does not fit: a sample of them may */
            only.node_sigma = SC_GRID_NODE_SIGMA_SAMPLE;
            only.node_sigma_sample = DESIGN_SIGMA_SAMPLE;
            fprintf(stderr, "selfcal: plan --design: every node's sigma does not fit (%s); the "
                            "sigma of %d nodes instead, as `grid --node-sigma sample:%d` gives "
                            "it (or none: --node-sigma none)\n",
                    err.msg, DESIGN_SIGMA_SAMPLE, DESIGN_SIGMA_SAMPLE);
            sampled = 1;
            pst = sc_grid_lsq_plan_create(&p, NULL, &only, &q, &err);
        }
        if (pst != SC_OK) {
            int views = p.n_views;
            sc_grid_plan_free(&p);
            int rc = cli_report(&err);
            if (err.code == SC_E_NOMEM) /* what to do about it */
                fprintf(stderr,
                        "selfcal: plan --design: a %dx%d stage with an N = %d plate is too large "
                        "for the exact analysis (every node's sigma) within %.3g GB: the raster "
                        "of step %d (%d placements) (docs/grid-lsq.md, 'Large stages'); a "
                        "smaller stage, a larger plate or --max-memory SIZE; `grid --node-sigma "
                        "none` needs the factor only\n",
                        (int)sx, (int)sy, n, max_bytes / 1e9, step, views);
            return rc;
        }
        sc_grid_lsq_get_info(q, &bi);
        sc_grid_lsq_plan_destroy(q);
        if (bi.identifiable)
            best = p, found = 1; /* best owns p's views now */
        else
            sc_grid_plan_free(&p);
    }
    if (!found) {
        fprintf(stderr, "selfcal: plan --design: no raster of placements identifies G on a %dx%d "
                        "stage with an N = %d plate\n",
                (int)sx, (int)sy, n);
        return CLI_FAIL;
    }
    if (sampled) /* the σ_C ratios below are over the sampled nodes */
        printf("sigma_sampled_nodes: %d\n", DESIGN_SIGMA_SAMPLE);
    rc = design_print(&best, &bi, n, (int)sx, (int)sy, pitch, out);
    sc_grid_plan_free(&best);
    return rc;
}

/* plan --design's output: the analysis, the views, the plan file (-o). */
static int design_print(const sc_grid_plan *bp, const sc_grid_lsq_info *bip, int n, int sx_i,
                        int sy_i, double pitch, const char *out)
{
    sc_error err;
    sc_error_clear(&err);
    const sc_grid_plan best = *bp; /* borrowed */
    const sc_grid_lsq_info bi = *bip;
    double sx = sx_i, sy = sy_i;
    printf("identifiable: yes\nfree: 0\nsigma_c_ratio_rms: %.6g\nsigma_c_ratio_max: %.6g\n",
           bi.sigma_c_ratio_rms, bi.sigma_c_ratio_max);
    printf("N: %d\nstage: %d,%d\npitch_mm: %g\nviews: %d\n", n, (int)sx, (int)sy, pitch,
           best.n_views);
    for (int v = 0; v < best.n_views; ++v)
        printf("view %d: rot=%d shift=%d,%d\n", v, best.view[v].rot_deg, best.view[v].shift_x,
               best.view[v].shift_y);
    if (out) {
        sc_afile f;
        if (sc_afile_open(&f, out, &err) != SC_OK)
            return cli_report(&err);
        sc_grid_write_header(f.fp, &best);
        if (sc_afile_commit(&f, &err) != SC_OK)
            return cli_report(&err);
    }
    return CLI_OK;
}

/* Baarda's internal reliability of an identifying plan (see the usage text). */
static void print_reliability(const sc_grid_lsq_info *qi)
{
    printf("testable_equations: %ld\nuntestable_equations: %ld\n", qi->n_testable,
           qi->n_untestable);
    if (qi->n_testable == 0)
        return;
    printf("redundancy_min: %.6g\nredundancy_mean: %.6g\n", qi->redundancy_min,
           qi->redundancy_mean);
    printf("mdb_ratio_max: %.6g\nmdb_ratio_mean_r: %.6g\n", qi->mdb_ratio_max,
           qi->mdb_ratio_mean_r);
}

/* The analysis lines of a plan or data file (see the usage text). */
/* Does view v measure mark (i, j): in the data, or by the plan's selection. */
static int measures(const sc_grid_data *d, int has_data, int v, int i, int j)
{
    const sc_grid_plan *p = &d->plan;
    return has_data ? isfinite(d->dx_um[v][i * p->n + j]) : sc_grid_view_measures(p, v, i, j);
}

/* The marks no view measures. */
static long unseen_marks(const sc_grid_data *d, int has_data)
{
    const sc_grid_plan *p = &d->plan;
    long unseen = 0;
    for (int i = 0; i < p->n; ++i)
        for (int j = 0; j < p->n; ++j) {
            int seen = 0;
            for (int v = 0; v < p->n_views && !seen; ++v)
                seen = measures(d, has_data, v, i, j);
            unseen += !seen;
        }
    return unseen;
}

/* Which methods the plan supports. */
static void print_methods(const sc_grid_data *d, int has_data, const sc_grid_lsq_info *qi)
{
    static const int ye[3][4] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 1, 0, 0}};
    static const int ds[4][4] = {{0, 0, 0, 0}, {90, 0, 0, 0}, {0, 2, 0, 0}, {0, -3, 0, 1}};
    const sc_grid_plan *p = &d->plan;
    int plate_stage = sc_grid_stage_is_plate(p);
    printf("method ye: %s\n", plate_stage && supports(d, has_data, ye, 3) ? "yes" : "no");
    printf("method double-shift: %s\n",
           plate_stage && p->n >= sc_grid_exact_min_n(SC_GRID_DOUBLE_SHIFT) && supports(d, has_data, ds, 4) ? "yes" : "no");
    printf("method lsq: %s\n", qi->identifiable ? "yes" : "no");
}

static void print_analysis(const sc_grid_data *d, const sc_grid_file_info *fi, int has_data,
                           const sc_grid_lsq_info *qi, const sc_grid_lsq_info *unit)
{
    const sc_grid_plan *p = &d->plan;
    int n = p->n;
    printf("identifiable: %s\n", qi->identifiable ? "yes" : "no");
    printf("free: %ld\n", qi->identifiable ? 0L : qi->free_dof);
    if (qi->identifiable) { /* ratios of the geometry (equal weights); stated σ: also in µm */
        printf("sigma_c_ratio_rms: %.6g\n", unit->sigma_c_ratio_rms);
        printf("sigma_c_ratio_max: %.6g\n", unit->sigma_c_ratio_max);
        if (qi->weighted)
            printf("sigma_c_rms_um: %.6g\nsigma_c_max_um: %.6g\n",
                   qi->sigma_c_ratio_rms, qi->sigma_c_ratio_max);
    } else {
        printf("sigma_c_ratio_rms: inf\nsigma_c_ratio_max: inf\n");
    }
    printf("N: %d\nstage: %d,%d\npitch_mm: %g\norigin_mm: %g,%g\n", n, sc_grid_stage_nx(p),
           sc_grid_stage_ny(p), p->pitch_mm, p->origin_mm[0], p->origin_mm[1]);
    if (qi->n_stage_unmeasured)
        printf("unmeasured_stage_nodes: %ld\n", qi->n_stage_unmeasured);
    printf("source: %s\n", has_data ? "data file (the marks measured)" : "plan (the marks the views select)");
    printf("views: %d\n", p->n_views);
    long empty_views = 0, unseen = unseen_marks(d, has_data);
    for (int v = 0; v < p->n_views; ++v) {
        long marks = 0;
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j)
                marks += measures(d, has_data, v, i, j);
        empty_views += marks == 0;
        printf("view %d: rot=%d shift=%d,%d%s marks=%ld\n", fi->view_id[v], p->view[v].rot_deg,
               p->view[v].shift_x, p->view[v].shift_y, p->view[v].restricted ? " (rows/cols)" : "",
               marks);
    }
    printf("equations: %ld\nunknowns: %ld\nconstraints: %ld\n", qi->n_equations, qi->n_unknowns,
           qi->n_constraints);
    /* equations minus the rank: the gauge, a view without marks (its misalignment), a view with
     * one mark (its rotation) and a mark no view measures (its plate error) leave unknowns
     * undetermined without costing equations */
    if (qi->identifiable) {
        printf("residual_dof: %ld\n", qi->residual_dof);
        print_reliability(qi);
    }
    if (empty_views || unseen)
        printf("note: %ld view(s) without marks, %ld mark(s) measured in no view (their "
               "misalignment / plate error stay unknown)\n",
               empty_views, unseen);
    print_methods(d, has_data, qi);
}

/* What plan (the analysis) is asked. */
typedef struct plan_args {
    const char *in;
    sc_grid_lsq_opts opts;
} plan_args;

/* --design: the designer's options instead (design_opts), from the start */
static int to_design(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)cmd, (void)opt, (void)v, (void)field;
    return CLI_STOP;
}

#define F(field) offsetof(plan_args, field)
/* plan's options (cli_opts.h), in the order of its --help */
static const cli_opt PLAN_OPTS[] = {
    {"--drift", CLI_CHOICE, F(opts.drift), "linear|none", .choices = "none|linear",
     .missing = "--drift needs linear or none (see --help)",
     .bad = "--drift needs linear or none (see --help)", .def = "none",
     .help = "analyse with a drift rate per view"},
    {"--max-memory", CLI_CUSTOM, F(opts.max_bytes), "SIZE", .parse = cli_opt_max_memory,
     .missing = "--max-memory needs a SIZE", .def = "the available memory",
     .help = "refuse a plan estimated to need more (K, M, G, T)"},
    {"--design", CLI_FLAG, 0, .parse = to_design, .help = "design a plan (selfcal plan --design)"},
};
#undef F

const cli_cmd_opts cli_plan_opts = {
    "plan", USAGE, PLAN_OPTS, (int)(sizeof PLAN_OPTS / sizeof PLAN_OPTS[0]),
    offsetof(plan_args, in), NULL, "one plan file only (see --help)",
    "unknown option '%s' (see --help)", "unknown option '%s' (see --help)", 0, &design_opts, NULL,
};

int cmd_plan(int argc, char **argv)
{
    /* the analysis printed needs every node's σ (the σ_C ratios), not the σ of O, R and the
     * misalignments */
    plan_args g = {NULL, {.node_sigma_only = 1, .max_bytes = cli_memory_bytes()}};
    int rc = cli_opts_parse(&cli_plan_opts, argc, argv, &g);
    if (rc == CLI_STOP)
        return design(argc, argv);
    if (rc >= 0)
        return rc;
    const char *in = g.in;
    sc_grid_lsq_opts opts = g.opts;
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
    sc_grid_lsq_plan *q = NULL;
    if (opts.drift && has_data && !fi.has_t) {
        sc_grid_data_free(&d);
        sc_grid_file_info_free(&fi);
        sc_error_set(&err, SC_E_INPUT, in, fi.header_end_line,
                     "--drift linear needs the time of each measurement (column t_s)");
        return cli_report(&err);
    }
    long unknowns;
    if (worth_announcing(&d.plan, opts.drift, &unknowns)) /* seconds to minutes */
        fprintf(stderr, "selfcal: plan: analysing a %d x %d stage (%ld unknowns)\n",
                sc_grid_stage_nx(&d.plan), sc_grid_stage_ny(&d.plan), unknowns);
    /* pass 0: the plan as it states its uncertainties; pass 1, where it states some: the same
     * with equal weights, for the σ_C ratios per unit σ_r. Its figures kept, each plan is freed
     * before the next: one in memory at a time. */
    sc_grid_lsq_info qi, unit;
    for (int pass = 0; pass < 2; ++pass) {
        sc_grid_lsq_opts po = opts;
        po.unit_weights = pass;
        st = sc_grid_lsq_plan_create(&d.plan, has_data ? &d : NULL, &po, &q, &err);
        if (st != SC_OK) {
            sc_grid_data_free(&d);
            sc_grid_file_info_free(&fi);
            if (!err.file[0]) {
                snprintf(err.file, sizeof err.file, "%s", in);
                err.line = fi.header_end_line;
            }
            return cli_report(&err);
        }
        sc_grid_lsq_get_info(q, pass ? &unit : &qi);
        sc_grid_lsq_plan_destroy(q);
        q = NULL;
        if (pass == 0)
            unit = qi;
        if (!(qi.weighted && qi.identifiable))
            break;
    }
    print_analysis(&d, &fi, has_data, &qi, &unit);
    sc_grid_data_free(&d);
    sc_grid_file_info_free(&fi);
    return CLI_OK;
}
