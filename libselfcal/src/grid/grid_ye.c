/* Ye et al.'s exact method (views 0°, 90°, +1 pitch in x): the method-specific step.
 *
 * View 2 gives H(i,j) = F(i,j+1) - F(i,j) for j = 0..N-2 (grid_exact.c, after its misalignment).
 * The DFT solution needs the periodic H, whose last column is the wrap-around difference
 * H(i,N-1) = F(i,0) - F(i,N-1). With a shift of one pitch the differences of a row telescope:
 * sum_{j=0}^{N-2} H(i,j) = F(i,N-1) - F(i,0), so H(i,N-1) = -sum_{j<N-1} H(i,j), exactly; every
 * row of the periodic H then sums to zero, as the zero frequency of F (T_1 - I) must.
 * See docs/grid-exact.md §5.
 */
#include "grid_exact_internal.h"

void sc_grid_ye_complete_h(struct sc_grid_exact_plan *p)
{
    int n = p->n;
    for (int i = 0; i < n; ++i) {
        double sx = 0, sy = 0;
        for (int j = 0; j < n - 1; ++j) {
            sx += p->hx[i * n + j];
            sy += p->hy[i * n + j];
        }
        p->hx[i * n + n - 1] = -sx;
        p->hy[i * n + n - 1] = -sy;
    }
}
