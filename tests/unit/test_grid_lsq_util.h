/* Shared helpers of the grid least-squares tests: plans, simulated truth, data buffers. */
#ifndef TEST_GRID_LSQ_UTIL_H
#define TEST_GRID_LSQ_UTIL_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/grid.h"
#include "selfcal/grid_io.h"
#include "selfcal/rng.h"

/* Misalignments drawn per truth (the old fixed view count: the same random stream as before)
 * and the per-view arrays of a tu_res (the plans here have a few views). */
#define TU_TRUTH_VIEWS 32
#define TU_RES_VIEWS 64

enum { PLAN_YE, PLAN_PETRO, PLAN_RICH, PLAN_0_90, PLAN_0_180_1X, PLAN_0_90_2X, PLAN_SHIFTS };

static void tu_add_view(sc_grid_plan *p, int rot, int sx, int sy)
{
    if (sc_grid_plan_views(p, p->n_views + 1, NULL) != SC_OK)
        abort();
    sc_grid_view *w = &p->view[p->n_views - 1];
    w->rot_deg = rot;
    w->shift_x = sx;
    w->shift_y = sy;
}

static void tu_plan(sc_grid_plan *p, int n, int kind)
{
    memset(p, 0, sizeof *p);
    p->n = n;
    p->pitch_mm = 2.5;
    p->origin_mm[0] = 10;
    p->origin_mm[1] = -4;
    int c = (n - 1) / 2;
    switch (kind) {
    case PLAN_YE:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 90, 0, 0), tu_add_view(p, 0, 1, 0);
        break;
    case PLAN_PETRO:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 90, 0, 0), tu_add_view(p, 0, 2, 0);
        tu_add_view(p, 0, -3, 0);
        p->view[3].restricted = 1;
        p->view[3].row_sel[c] = 1;
        p->view[3].col_sel[c] = 1;
        p->view[3].col_sel[c + 1] = 1;
        break;
    case PLAN_RICH:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 90, 0, 0), tu_add_view(p, 180, 0, 0);
        tu_add_view(p, 0, 1, 0), tu_add_view(p, 270, 0, -2);
        break;
    case PLAN_0_90:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 90, 0, 0);
        break;
    case PLAN_0_180_1X:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 180, 0, 0), tu_add_view(p, 0, 1, 0);
        break;
    case PLAN_0_90_2X:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 90, 0, 0), tu_add_view(p, 0, 2, 0);
        break;
    case PLAN_SHIFTS:
        tu_add_view(p, 0, 0, 0), tu_add_view(p, 0, 1, 0), tu_add_view(p, 0, 0, 1);
        break;
    }
}

typedef struct tu_truth {
    int nn;
    double *gx, *gy, *ax, *ay;
    double *tx, *ty, *th; /* max(TU_TRUTH_VIEWS, n_views) each, one block at tx */
} tu_truth;

/* Random truth in the SPEC gauge: G, A ~ N(0, 1 µm), misalignment ~ 2 µm, 30 µrad. */
static void tu_truth_make(tu_truth *t, const sc_grid_plan *p, sc_rng *r)
{
    int nn = p->n * p->n;
    t->nn = nn;
    t->gx = malloc(sizeof(double) * nn), t->gy = malloc(sizeof(double) * nn);
    t->ax = malloc(sizeof(double) * nn), t->ay = malloc(sizeof(double) * nn);
    for (int k = 0; k < nn; ++k) {
        t->gx[k] = sc_rng_normal(r), t->gy[k] = sc_rng_normal(r);
        t->ax[k] = sc_rng_normal(r), t->ay[k] = sc_rng_normal(r);
    }
    sc_grid_gauge_stage(p, t->gx, t->gy);
    sc_grid_gauge_plate(p, t->ax, t->ay);
    int nv = p->n_views > TU_TRUTH_VIEWS ? p->n_views : TU_TRUTH_VIEWS;
    t->tx = malloc(sizeof(double) * 3 * (size_t)nv), t->ty = t->tx + nv, t->th = t->ty + nv;
    for (int v = 0; v < nv; ++v) {
        t->tx[v] = 2 * sc_rng_normal(r);
        t->ty[v] = 2 * sc_rng_normal(r);
        t->th[v] = 30 * sc_rng_normal(r);
    }
}

static void tu_truth_free(tu_truth *t)
{
    free(t->gx), free(t->gy), free(t->ax), free(t->ay), free(t->tx);
}

static void tu_data_alloc(sc_grid_data *d, const sc_grid_plan *p)
{
    memset(d, 0, sizeof *d);
    if (sc_grid_plan_copy(&d->plan, p, NULL) != SC_OK || sc_grid_data_views(d, NULL) != SC_OK)
        abort();
    int nn = p->n * p->n;
    for (int v = 0; v < p->n_views; ++v) {
        d->dx_um[v] = malloc(sizeof(double) * nn);
        d->dy_um[v] = malloc(sizeof(double) * nn);
    }
}

/* A truth for plan p drawn from r and its noise-free data in d (allocated here). */
static void tu_truth_data(const sc_grid_plan *p, sc_rng *r, tu_truth *t, sc_grid_data *d)
{
    tu_truth_make(t, p, r);
    tu_data_alloc(d, p);
    sc_grid_synthesize(p, t->gx, t->gy, t->ax, t->ay, t->tx, t->ty, t->th, d);
}

static void tu_data_free(sc_grid_data *d)
{
    sc_grid_data_free(d); /* its arrays, tables and plan */
}

/* Add N(0, sigma) to every finite value. */
static void tu_add_noise(sc_grid_data *d, double sigma, sc_rng *r)
{
    int nn = d->plan.n * d->plan.n;
    for (int v = 0; v < d->plan.n_views; ++v)
        for (int k = 0; k < nn; ++k)
            if (isfinite(d->dx_um[v][k])) {
                d->dx_um[v][k] += sigma * sc_rng_normal(r);
                d->dy_um[v][k] += sigma * sc_rng_normal(r);
            }
}

/* Plan `kind` at size n, a gauged truth and its data with noise sigma (µm), from seed. */
static inline void tu_noisy_case(sc_grid_plan *p, int n, int kind, uint64_t seed, double sigma,
                                 tu_truth *t, sc_grid_data *d)
{
    tu_plan(p, n, kind);
    sc_rng r;
    sc_rng_seed(&r, seed);
    tu_truth_data(p, &r, t, d);
    tu_add_noise(d, sigma, &r);
}

typedef struct tu_res {
    sc_grid_result r;
    double *buf;
} tu_res;

static void tu_res_alloc(tu_res *t, int nn)
{
    memset(t, 0, sizeof *t);
    t->buf = malloc(sizeof(double) * 6 * nn);
    t->r.gx_um = t->buf, t->r.gy_um = t->buf + nn, t->r.ugx_um = t->buf + 2 * nn;
    t->r.ugy_um = t->buf + 3 * nn, t->r.ax_um = t->buf + 4 * nn, t->r.ay_um = t->buf + 5 * nn;
    if (sc_grid_result_views(&t->r, TU_RES_VIEWS, NULL) != SC_OK)
        abort();
}

static void tu_res_free(tu_res *t)
{
    free(t->buf);
    sc_grid_result_free_views(&t->r);
}

#endif
