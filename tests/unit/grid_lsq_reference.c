/* Reference values for the accuracy tests of the least-squares grid estimator
 * (grid_lsq_reference.h): column solves refined against residuals in long double until they stop
 * changing, independent of the selected inverse. A test helper, out of the library: it reads the
 * plan only through its matrix (sc_grid_lsq_matrix) and the narrow accessor for the references
 * (sc_grid_lsq_probe_*, grid_lsq_internal.h), which writes each uncertainty as a form vᵀΣv. */
#include "grid_lsq_reference.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../libselfcal/src/grid/grid_lsq_internal.h"

/* The pinned matrix S of a plan and its pinned unknowns, and the scratch of a refined solve. */
typedef struct ref_ctx {
    const sc_grid_lsq_plan *q;
    sc_grid_lsq_probe p;
    int n;
    const long *Ap;
    const int *Ai;
    const double *Ax;
    double *b;
    long double *x, *r;
} ref_ctx;

/* y = S x (the pinned matrix factored: the full one with A kept), in long double. */
static void matvec_long(const ref_ctx *c, const long double *x, long double *y)
{
    for (int i = 0; i < c->n; ++i)
        y[i] = 0;
    for (int j = 0; j < c->n; ++j)
        for (long p = c->Ap[j]; p < c->Ap[j + 1]; ++p) {
            int i = c->Ai[p];
            y[i] += (long double)c->Ax[p] * x[j];
            if (i != j)
                y[j] += (long double)c->Ax[p] * x[i];
        }
}

/* vᵀ Σ v (Σ the pinned inverse, 0 on pins; v over the n_red reduced unknowns) by a refined
 * solve of the factored matrix (n unknowns: with A kept, zeros on A); -1 if memory ran out. */
static double exact_quad(const ref_ctx *c, const double *v)
{
    int n = c->n, nr = c->p.n_red;
    const unsigned char *pinned = c->p.pinned;
    double *b = c->b;
    long double *x = c->x, *r = c->r;
#define PIN_(i) ((i) < nr && pinned[i])
#define V_(i) ((i) < nr ? (long double)v[i] : 0.0L)
    for (int i = 0; i < n; ++i)
        x[i] = 0;
    for (int it = 0; it < 6; ++it) {
        matvec_long(c, x, r);
        for (int i = 0; i < n; ++i)
            b[i] = PIN_(i) ? 0.0 : (double)(V_(i) - r[i]);
        if (sc_grid_lsq_probe_solve(c->q, b) != 0)
            return -1;
        for (int i = 0; i < n; ++i)
            x[i] += PIN_(i) ? 0.0L : (long double)b[i];
    }
#undef PIN_
#undef V_
    long double s = 0;
    for (int i = 0; i < nr; ++i)
        s += pinned[i] ? 0.0L : (long double)v[i] * x[i];
    return (double)s;
}

/* c: q's matrix and sizes, and its scratch (with v: n_red doubles); 0, -1 if memory ran out. */
static int ref_open(ref_ctx *c, const sc_grid_lsq_plan *q, double **v)
{
    c->q = q;
    sc_grid_lsq_probe_get(q, &c->p);
    sc_grid_lsq_matrix(q, &c->n, &c->Ap, &c->Ai, &c->Ax);
    size_t n = (size_t)c->n;
    c->b = malloc(sizeof(double) * n);
    c->x = malloc(sizeof(long double) * n);
    c->r = malloc(sizeof(long double) * n);
    *v = malloc(sizeof(double) * n);
    return c->b && c->x && c->r && *v ? 0 : -1;
}

static void ref_close(ref_ctx *c, double *v)
{
    free(c->b), free(c->x), free(c->r), free(v);
}

int sc_grid_lsq_reference_misalignments(const sc_grid_lsq_plan *q, double *var_ref,
                                        double *var_plan)
{
    ref_ctx c;
    double *v = NULL;
    int rc = ref_open(&c, q, &v);
    for (int t = 0; rc == 0 && t < c.p.nm; ++t) {
        double add = 0;
        int got = sc_grid_lsq_probe_misalignment(q, t, v, &add, &var_plan[t]);
        if (got < 0) {
            rc = -1;
            break;
        }
        var_ref[t] = NAN;
        if (got == 0) {
            double quad = exact_quad(&c, v);
            if (quad < 0)
                rc = -1;
            var_ref[t] = quad + add;
        }
    }
    ref_close(&c, v);
    return rc;
}

int sc_grid_lsq_reference(const sc_grid_lsq_plan *q, int nsample, int *node, double *sx_ref,
                          double *sx_plan, long *eq, double *h_ref, double *h_plan)
{
    ref_ctx c;
    double *v = NULL;
    int rc = ref_open(&c, q, &v);
    for (int s = 0; rc == 0 && s < nsample; ++s) {
        /* σ_x of a node: (P⊥e)ᵀ Σ (P⊥e) */
        int k = (int)((long)s * c.p.ns / nsample);
        if (sc_grid_lsq_probe_node(q, k, v, &sx_plan[s]) != 0) {
            rc = -1;
            break;
        }
        double var = exact_quad(&c, v);
        node[s] = k;
        sx_ref[s] = sqrt(var > 0 ? var : 0);
        /* the leverage of an equation: w_e/W_a + w_e ãᵀΣã, ã = ρ_e − the group's mean row */
        long e = (long)((double)s * c.p.neq / nsample);
        double add, w;
        if (sc_grid_lsq_probe_equation(q, e, v, &add, &w, &h_plan[s]) != 0) {
            rc = -1;
            break;
        }
        eq[s] = e;
        h_ref[s] = add + w * exact_quad(&c, v);
    }
    ref_close(&c, v);
    return rc;
}
