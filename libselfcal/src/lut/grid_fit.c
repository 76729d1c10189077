/* grid_fit.c — a table grid fitted to a stage map with more nodes than a table holds (lut.h).
 *
 * The table is read by bilinear interpolation (selfcal/correct.h), i.e. it is a tensor-product
 * linear spline on its own nodes. With m_x × m_y table nodes spanning exactly the map's extent,
 * its values C are chosen to minimise Σ over every map node of |table(node) − G(node)|²: with
 * B_x (n_x × m_x) and B_y (n_y × m_y) the hat functions of the table sampled at the map's nodes,
 * table(map) = B_y C B_xᵀ, and the minimiser is separable,
 *     C = (B_yᵀB_y)⁻¹ B_yᵀ G B_x (B_xᵀB_x)⁻¹,
 * each factor a tridiagonal symmetric positive definite system (a map node lies within half its
 * pitch of every table node, so every hat function has data: Schoenberg–Whitney). First each map
 * row is fitted along x, then each table column of those along y. An axis with no more nodes than
 * the table allows is kept as it is (B = I: the values are copied, not fitted).
 *
 * Written here: the tridiagonal solves are a few lines (LAPACK's dptsv would do the same, and the
 * library does not link LAPACK: CHOLMOD's BLAS is loaded only by the grid solver).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/lut.h"
#include "../core/lut_format.h"

/* The hat weights of one axis: map node i lies in table interval k[i] with weight w[i] on node
 * k[i] + 1 and 1 − w[i] on node k[i]; n map nodes, m table nodes (2 <= m <= n). */
typedef struct axis_fit {
    int n, m;
    int *k;
    double *w;
    double *diag, *off; /* B^T B: Cholesky factor after axis_factor (diag: L_kk, off: L_k+1,k) */
} axis_fit;

static void axis_free(axis_fit *a)
{
    free(a->k), free(a->w), free(a->diag), free(a->off);
    memset(a, 0, sizeof *a);
}

static int axis_init(axis_fit *a, int n, int m)
{
    memset(a, 0, sizeof *a);
    a->n = n, a->m = m;
    a->k = malloc(sizeof(int) * (size_t)n);
    a->w = malloc(sizeof(double) * (size_t)n);
    a->diag = calloc((size_t)m, sizeof(double));
    a->off = calloc((size_t)m, sizeof(double));
    if (!a->k || !a->w || !a->diag || !a->off) {
        axis_free(a);
        return -1;
    }
    for (int i = 0; i < n; ++i) {
        /* position of map node i in table pitches; exact at both ends */
        double u = (double)i * (double)(m - 1) / (double)(n - 1);
        int k = (int)floor(u);
        if (k > m - 2)
            k = m - 2;
        double w = u - k;
        a->k[i] = k;
        a->w[i] = w;
        a->diag[k] += (1 - w) * (1 - w);
        a->diag[k + 1] += w * w;
        a->off[k] += w * (1 - w);
    }
    /* Cholesky of the tridiagonal B^T B (positive definite: see the file's first comment) */
    for (int k = 0; k < m; ++k) {
        double d = a->diag[k] - (k > 0 ? a->off[k - 1] * a->off[k - 1] : 0.0);
        if (!(d > 0)) {
            axis_free(a);
            return -2;
        }
        a->diag[k] = sqrt(d);
        if (k + 1 < m)
            a->off[k] /= a->diag[k];
    }
    return 0;
}

/* out (m values, stride so) = (B^T B)^-1 B^T v, v: n values at stride sv. */
static void axis_solve(const axis_fit *a, const double *v, size_t sv, double *out, size_t so)
{
    int m = a->m;
    for (int k = 0; k < m; ++k)
        out[k * so] = 0;
    for (int i = 0; i < a->n; ++i) {
        out[a->k[i] * so] += (1 - a->w[i]) * v[i * sv];
        out[(a->k[i] + 1) * so] += a->w[i] * v[i * sv];
    }
    for (int k = 0; k < m; ++k) { /* L y = r */
        double r = out[k * so] - (k > 0 ? a->off[k - 1] * out[(k - 1) * so] : 0.0);
        out[k * so] = r / a->diag[k];
    }
    for (int k = m - 1; k >= 0; --k) { /* L^T x = y */
        double r = out[k * so] - (k + 1 < m ? a->off[k] * out[(k + 1) * so] : 0.0);
        out[k * so] = r / a->diag[k];
    }
}

/* The table's value at map node (i, j): B_y[i,:] C B_x[j,:]^T. */
static double table_at(const axis_fit *ax, const axis_fit *ay, const double *c, int i, int j)
{
    int kx = ax->k[j], ky = ay->k[i], mx = ax->m;
    double wx = ax->w[j], wy = ay->w[i];
    const double *r0 = c + (size_t)ky * mx, *r1 = r0 + mx;
    return (1 - wy) * ((1 - wx) * r0[kx] + wx * r0[kx + 1]) +
           wy * ((1 - wx) * r1[kx] + wx * r1[kx + 1]);
}

/* The table's nodes per axis (*mx, *my: the map's, at most max_nodes) and their pitch. */
static sc_status fit_size(const sc_stage_map *m, int max_nodes, const char *name, int *mx, int *my,
                          double *px, double *py, sc_error *err)
{
    if (max_nodes < 2 || max_nodes > SC_LUT_MAX_NX || max_nodes > SC_LUT_MAX_NY)
        return sc_error_set(err, SC_E_INPUT, NULL, 0,
                            "the table's nodes per axis must be 2..%d, not %d", SC_LUT_MAX_NX,
                            max_nodes);
    if (m->nx < 2 || m->ny < 2)
        return sc_error_set(err, SC_E_INPUT, name, 0, "the map has %d x %d nodes; at least 2 x 2",
                            m->nx, m->ny);
    *mx = m->nx < max_nodes ? m->nx : max_nodes;
    *my = m->ny < max_nodes ? m->ny : max_nodes;
    /* an axis kept as it is keeps its pitch exactly */
    *px = *mx == m->nx ? m->px_mm : m->px_mm * (m->nx - 1) / (*mx - 1);
    *py = *my == m->ny ? m->py_mm : m->py_mm * (m->ny - 1) / (*my - 1);
    if (!(*px >= SC_LUTF_MIN_PITCH_MM && *py >= SC_LUTF_MIN_PITCH_MM))
        return sc_error_set(err, SC_E_INPUT, name, 0, "pitch %g x %g mm is below the table's 1 nm",
                            *px, *py);
    return SC_OK;
}

/* The table's values of both components: each map row fitted along x into h (m->ny x mx),
 * then each column of h along y. */
static void fit_solve(const axis_fit *ax, const axis_fit *ay, const sc_stage_map *m, double *h,
                      sc_lut *lut)
{
    const int mx = ax->m;
    for (int comp = 0; comp < 2; ++comp) {
        const double *g = comp == 0 ? m->gx_um : m->gy_um;
        double *c = comp == 0 ? lut->gx_um : lut->gy_um;
        for (int i = 0; i < m->ny; ++i) /* each map row along x: h = G B_x (B_x^T B_x)^-1 */
            axis_solve(ax, g + (size_t)i * m->nx, 1, h + (size_t)i * mx, 1);
        for (int j = 0; j < mx; ++j) /* each column of h along y */
            axis_solve(ay, h + j, (size_t)mx, c + j, (size_t)mx);
    }
}

/* How far the fitted table is from the map at the map's nodes: RMS and worst, into *rep. */
static void fit_report(const axis_fit *ax, const axis_fit *ay, const sc_stage_map *m,
                       const sc_lut *lut, sc_lut_fit_report *rep)
{
    double sum2 = 0, worst = -1;
    int wi = 0, wj = 0;
    for (int i = 0; i < m->ny; ++i)
        for (int j = 0; j < m->nx; ++j) {
            size_t q = (size_t)i * m->nx + j;
            double ex = table_at(ax, ay, lut->gx_um, i, j) - m->gx_um[q];
            double ey = table_at(ax, ay, lut->gy_um, i, j) - m->gy_um[q];
            double e2 = ex * ex + ey * ey;
            sum2 += e2;
            if (e2 > worst)
                worst = e2, wi = i, wj = j;
        }
    rep->map_nx = m->nx;
    rep->map_ny = m->ny;
    rep->fitted = ax->m < m->nx || ay->m < m->ny;
    rep->rms_um = sqrt(sum2 / ((double)m->nx * m->ny));
    rep->max_um = sqrt(worst);
    rep->max_at_mm[0] = sc_stage_map_x_mm(m, wj);
    rep->max_at_mm[1] = sc_stage_map_y_mm(m, wi);
}

sc_status sc_lut_fit_grid(sc_lut *lut, const sc_stage_map *m, int max_nodes, const char *name,
                          sc_lut_fit_report *rep, sc_error *err)
{
    int mx = 0, my = 0;
    double px = 0, py = 0;
    sc_status st = fit_size(m, max_nodes, name, &mx, &my, &px, &py, err);
    if (st != SC_OK)
        return st;
    axis_fit ax, ay;
    int rx = axis_init(&ax, m->nx, mx);
    int ry = rx == 0 ? axis_init(&ay, m->ny, my) : -1;
    double *h = NULL;
    if (rx == 0 && ry == 0)
        h = malloc(sizeof(double) * (size_t)m->ny * (size_t)mx);
    if (!h) {
        if (rx == 0)
            axis_free(&ax);
        if (ry == 0)
            axis_free(&ay);
        return rx == -2 || ry == -2
                   ? sc_error_set(err, SC_E_INTERNAL, name, 0, "the table fit is singular")
                   : sc_error_set(err, SC_E_NOMEM, name, 0, "out of memory (table fit)");
    }
    fit_solve(&ax, &ay, m, h, lut);
    if (rep)
        fit_report(&ax, &ay, m, lut, rep);
    free(h);
    axis_free(&ax);
    axis_free(&ay);
    lut->nx = mx;
    lut->ny = my;
    lut->x0_mm = m->x0_mm;
    lut->y0_mm = m->y0_mm;
    lut->px_mm = px;
    lut->py_mm = py;
    return SC_OK;
}

sc_status sc_lut_read_map_fitted(const char *path, sc_lut *lut, int max_nodes,
                                 sc_lut_fit_report *rep, sc_error *err)
{
    sc_stage_map m;
    sc_status st = sc_stage_map_read(path, &m, err);
    if (st == SC_OK)
        st = sc_lut_fit_grid(lut, &m, max_nodes, path, rep, err);
    sc_stage_map_free(&m);
    return st;
}
