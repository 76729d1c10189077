/* Petrò's double shift (views 0°, 90°, +2, -3 partial): the method-specific step (Petrò §4.3.1,
 * §4.4, eqs. 41-53, re-derived in docs/grid-exact.md §6).
 *
 * View 2 gives H(i,j) = F(i,j+2) - F(i,j) for j = 0..N-3: differences inside the even columns and
 * inside the odd columns of each row, never across. The periodic H also needs the two
 * wrap-around columns H(i,N-2) = F(i,0) - F(i,N-2) and H(i,N-1) = F(i,1) - F(i,N-1), which cross
 * the parities; view 3 (shift -3, odd) supplies the crossing:
 *  1. the central row of F: its even part is known from views 0/1, and F(c,N-1-j) - F(c,j) is a
 *     chain of view-2 differences (j and N-1-j have the same parity), eqs. 42-44;
 *  2. view 3's misalignment from its central row (eqs. 46, 47: a constant in x, a line in y);
 *  3. columns c and c+1 of view 3 then give F(i,c-3) - F(i,c) and F(i,c-2) - F(i,c+1) for every
 *     row: each links the even and the odd chain of row i; the two estimates of the link
 *     d(i) = F(i,1) - F(i,0) are averaged, and the wrap columns follow (eqs. 52, 53).
 */
#include "grid_exact_internal.h"

#define IDX(i, j) ((i) * n + (j))

/* Central row (i = c) of one component: F(c,j) = E(c,j) -+ (F(c,N-1-j) - F(c,j)) / 2. */
static void central_row(int n, const double *e, const double *h, double *row)
{
    int c = (n - 1) / 2;
    for (int j = 0; j <= c; ++j) {
        double diff = 0; /* F(c,N-1-j) - F(c,j) = H(c,j) + H(c,j+2) + ... + H(c,N-3-j) */
        for (int k = j; k <= n - 3 - j; k += 2)
            diff += h[IDX(c, k)];
        row[j] = e[IDX(c, j)] - 0.5 * diff;
        row[n - 1 - j] = e[IDX(c, n - 1 - j)] + 0.5 * diff;
    }
}

/* F(i,j) - F(i,0) (j even) or F(i,j) - F(i,1) (j odd) along the chains of row i of H. */
static double chain(int n, const double *h, int i, int j)
{
    double v = 0;
    for (int k = j % 2; k < j; k += 2)
        v += h[IDX(i, k)];
    return v;
}

/* Given the link L = F(i,a) - F(i,b) (a, b of different parity), the estimate of
 * delta = F(i,1) - F(i,0). */
static double delta_from_link(int n, const double *h, int i, int a, int b, double link)
{
    double ca = a % 2, cb = b % 2; /* coefficients of delta in F(i,a) - F(i,0), F(i,b) - F(i,0) */
    return (link - chain(n, h, i, a) + chain(n, h, i, b)) / (ca - cb);
}

/* Fill the wrap columns of one component from the links l1 = F(i,c-3) - F(i,c) and
 * l2 = F(i,c-2) - F(i,c+1). */
static void wrap_columns(int n, double *h, int i, double l1, double l2)
{
    int c = (n - 1) / 2;
    double d1 = delta_from_link(n, h, i, c - 3, c, l1);
    double d2 = delta_from_link(n, h, i, c - 2, c + 1, l2);
    double delta = 0.5 * (d1 + d2);
    h[IDX(i, n - 2)] = -(delta + chain(n, h, i, n - 2)); /* F(i,0) - F(i,N-2), N-2 odd */
    h[IDX(i, n - 1)] = delta - chain(n, h, i, n - 1);    /* F(i,1) - F(i,N-1), N-1 even */
}

void sc_grid_ds_complete_h(struct sc_grid_exact_plan *p, const sc_grid_exact_run *x)
{
    int n = p->n, c = p->c;
    central_row(n, p->ex, p->hx, p->crow_x);
    central_row(n, p->ey, p->hy, p->crow_y);
    /* view 3 misalignment from its central row: D3 = V3 - U0 = F(c,j-3) - F(c,j) + k3x (x),
     * ... + k3y + th3 (j - c) (y), j = 3..N-1 */
    double sx = 0, s1 = 0, sj = 0, sjj = 0, sy = 0, sjy = 0;
    for (int j = 3; j < n; ++j) {
        int k = IDX(c, j);
        double rx = x->v3x[k] - p->u0x[k] - (p->crow_x[j - 3] - p->crow_x[j]);
        double ry = x->v3y[k] - p->u0y[k] - (p->crow_y[j - 3] - p->crow_y[j]);
        double x = j - c;
        sx += rx;
        s1 += 1;
        sj += x;
        sjj += x * x;
        sy += ry;
        sjy += x * ry;
    }
    double k3x = sx / s1;
    double th3 = (s1 * sjy - sj * sy) / (s1 * sjj - sj * sj);
    double k3y = (sy - th3 * sj) / s1;
    /* links from columns c and c+1 of view 3, then the wrap columns of every row */
    for (int i = 0; i < n; ++i) {
        int ka = IDX(i, c), kb = IDX(i, c + 1);
        double l1x = x->v3x[ka] - p->u0x[ka] - k3x + th3 * (i - c);
        double l2x = x->v3x[kb] - p->u0x[kb] - k3x + th3 * (i - c);
        double l1y = x->v3y[ka] - p->u0y[ka] - k3y;
        double l2y = x->v3y[kb] - p->u0y[kb] - k3y - th3;
        wrap_columns(n, p->hx, i, l1x, l2x);
        wrap_columns(n, p->hy, i, l1y, l2y);
    }
}
