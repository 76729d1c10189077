/* profile_lsq_band_impl.h — private template of the banded kernels, included by
 * profile_lsq_band.c once per instruction set. Expects SC_SFX(name), SC_ATTR, SC_DOT, SC_AXPY,
 * SC_AXPY4. */

static inline int SC_SFX(is_pinned)(const sc_lsq_band *b, int i) { return i == 0 || i == b->n - 1; }

/* Row i of B into its band slot (pinned rows and columns are the identity). */
SC_ATTR static void SC_SFX(assemble_row)(const sc_lsq_band *b, int i)
{
    int bw = b->bw, n = b->n;
    double *ri = b->a + (size_t)i * b->ld;
    for (int m = 0; m < bw; m++) ri[m] = 0.0;
    if (SC_SFX(is_pinned)(b, i)) {
        ri[bw] = 1.0;
        return;
    }
    if (i - b->d1 >= 0 && !SC_SFX(is_pinned)(b, i - b->d1)) ri[bw - b->d1] += -b->w1;
    if (i - b->d2 >= 0 && !SC_SFX(is_pinned)(b, i - b->d2)) ri[bw - b->d2] += -b->w2;
    double aii = 0.0;
    if (i >= b->d1) aii += b->w1;
    if (i <= n - 1 - b->d1) aii += b->w1;
    if (i >= b->d2) aii += b->w2;
    if (i <= n - 1 - b->d2) aii += b->w2;
    ri[bw] = aii;
}

/* gather the panel of columns j .. j+nb-1: pc[c][k - j] = L[k][j+c] (0 outside the band, above
 * the diagonal, past N); row by row — a row's panel entries are contiguous in the band storage.
 * col: the 8 columns of h + 8 doubles each that pc points into. */
SC_ATTR static inline void SC_SFX(panel_gather)(const sc_lsq_band *b, double *col,
                                                double *const *pc, int j, int nb, int last, int h)
{
    int bw = b->bw;
    size_t ld = b->ld;
    for (size_t q = 0; q < 8 * (size_t)(h + 8); q++) col[q] = 0.0;
    for (int q = 0; q <= last - j; q++) {
        /* row j+q's slot of column j+c is bw - q + c >= 0 (c >= q - bw); indexing from the
         * row start keeps the pointer inside the array when q > bw */
        const double *src = b->a + (size_t)(j + q) * ld;
        int c0 = q - bw > 0 ? q - bw : 0, c1 = q < nb - 1 ? q : nb - 1;
        for (int c = c0; c <= c1; c++) pc[c][q] = src[bw - q + c];
    }
}

/* Factor the panel in the scratch (pivot square roots, column scaling, updates inside the
 * panel; h rows); the first column whose pivot is not positive and finite, or -1. */
SC_ATTR static inline int SC_SFX(panel_factor)(double *const *pc, int nb, int h)
{
    for (int c = 0; c < nb; c++) {
        double *pcc = pc[c];
        double djj = pcc[c];
        if (!(djj > 0.0) || !(djj < INFINITY)) return c;
        double inv = 1.0 / sqrt(djj);
        pcc[c] = inv;
        for (int q = c + 1; q < h; q++) pcc[q] *= inv;
        for (int c2 = c + 1; c2 < nb; c2++) {
            double m = pcc[c2];
            if (m == 0.0) continue;
            double *p2 = pc[c2];
            for (int q = c2; q < h; q++) p2[q] -= pcc[q] * m;
        }
    }
    return -1;
}

/* Write the factored panel back into the band, row by row. */
SC_ATTR static inline void SC_SFX(panel_scatter)(sc_lsq_band *b, double *const *pc, int j, int nb,
                                                 int last)
{
    int bw = b->bw;
    size_t ld = b->ld;
    for (int q = 0; q <= last - j; q++) {
        double *dst = b->a + (size_t)(j + q) * ld;
        int c0 = q - bw > 0 ? q - bw : 0, c1 = q < nb - 1 ? q : nb - 1;
        for (int c = c0; c <= c1; c++) dst[bw - q + c] = pc[c][q];
    }
}

/* The trailing rows k = j+8 .. last, columns l0 = j+8 .. k, less the full panel's rank-8 product:
 * row -= Σ_c L[k][j+c]·L[l][j+c]; four rows at a time — past `last` into rows not assembled yet
 * (assembly overwrites them), except at the end of the storage, where the last rows go one by
 * one. */
SC_ATTR static inline void SC_SFX(panel_trailing)(sc_lsq_band *b, const double *col,
                                                  double *const *pc, int j, int last, int h)
{
    int nrow = b->nrow, bw = b->bw;
    size_t ld = b->ld;
    int l0 = j + 8;
    int k = l0;
    for (; k <= last && (k + 3 < nrow); k += 4) {
        double *y0 = b->a + (size_t)k * ld + (size_t)(l0 - k + bw);
        SC_SYRK8X4(y0, (ptrdiff_t)ld - 1, col + 8, h + 8, k - j - 8, k - l0);
    }
    for (; k <= last; k++) {
        double *row = b->a + (size_t)k * ld;
        for (int l = l0; l <= k; l++) {
            double v = 0.0;
            for (int c = 0; c < 8; c++) v += pc[c][k - j] * pc[c][l - j];
            row[l - k + bw] -= v;
        }
    }
}

/* Right-looking banded Cholesky in panels of eight columns: copy the panel (its eight columns,
 * rows j .. j+7+bw) into contiguous scratch, factor it there (pivot square roots, column scaling,
 * updates inside the panel), write it back, then subtract its rank-8 outer product from the
 * trailing bw×bw triangle: four rows at a time in register tiles of 4 rows × 8 columns over the
 * columns all four rows have (SC_SYRK8x4: the tile is loaded and stored once per eight FMAs of
 * each of its elements), the few entries near the diagonal one by one. Rows are assembled just
 * before the first panel that reaches them, so the working window stays in cache. The diagonal
 * slot keeps 1/L[i][i]. col: 8·(bw+16) doubles. */
SC_ATTR static int SC_SFX(factor)(sc_lsq_band *b, double *col)
{
    int ncol = b->ncol, nrow = b->nrow, bw = b->bw;
    int h = bw + 8; /* panel rows j .. j+7+bw; each column padded with 8 zeros (stride h + 8) */
    double *pc[8];
    for (int c = 0; c < 8; c++) pc[c] = col + (size_t)c * (h + 8);
    int next_row = 0;
    for (int j = 0; j < ncol; j += 8) {
        int nb = ncol - j < 8 ? ncol - j : 8;
        int last = j + nb - 1 + bw < nrow - 1 ? j + nb - 1 + bw : nrow - 1;
        while (next_row <= last) SC_SFX(assemble_row)(b, next_row++);
        SC_SFX(panel_gather)(b, col, pc, j, nb, last, h);
        int bad = SC_SFX(panel_factor)(pc, nb, h);
        if (bad >= 0) return j + bad;
        SC_SFX(panel_scatter)(b, pc, j, nb, last);
        if (nb < 8) continue; /* the last columns (ncol = nrow, or ncol % 8 = 0): nothing trails */
        SC_SFX(panel_trailing)(b, col, pc, j, last, h);
    }
    while (next_row < nrow) SC_SFX(assemble_row)(b, next_row++);
    return -1;
}

/* Forward substitution L·x = b in place, for one right-hand side (x) or two (x, y: each band row
 * is read from memory once for both — the factor is far larger than the caches).
 * Row i: x[i] = (b[i] - L[i][i-bw..i-1]·x) / L[i][i]. Four rows at a time where the band is full:
 * their dot products over the columns already known share the loads of x (SC_DOT4), then the 4×4
 * triangle is resolved. */
SC_ATTR static inline void SC_SFX(forward_block)(int bw, const double *r0, size_t ld, double *x,
                                                 int i)
{
    const double *r1 = r0 + ld, *r2 = r1 + ld, *r3 = r2 + ld;
    double s[4];
    /* common known columns i+3-bw .. i-1 */
    SC_DOT4(x + i + 3 - bw, r0 + 3, r1 + 2, r2 + 1, r3, bw - 3, s);
    /* heads: row i+r also has columns i+r-bw .. i+2-bw */
    s[0] += r0[0] * x[i - bw] + r0[1] * x[i + 1 - bw] + r0[2] * x[i + 2 - bw];
    s[1] += r1[0] * x[i + 1 - bw] + r1[1] * x[i + 2 - bw];
    s[2] += r2[0] * x[i + 2 - bw];
    /* the triangle: L[i+r][i+m] = r_r[bw - r + m] */
    double x0 = (x[i] - s[0]) * r0[bw];
    double x1 = (x[i + 1] - s[1] - r1[bw - 1] * x0) * r1[bw];
    double x2 = (x[i + 2] - s[2] - r2[bw - 2] * x0 - r2[bw - 1] * x1) * r2[bw];
    double x3 = (x[i + 3] - s[3] - r3[bw - 3] * x0 - r3[bw - 2] * x1 - r3[bw - 1] * x2) * r3[bw];
    x[i] = x0;
    x[i + 1] = x1;
    x[i + 2] = x2;
    x[i + 3] = x3;
}

SC_ATTR static void SC_SFX(forward)(const sc_lsq_band *b, double *const *xs, int nrhs)
{
    int n = b->n, bw = b->bw;
    size_t ld = b->ld;
    int i = 0;
    if (bw >= 4) {
        for (; i < bw && i < n; i++) {
            const double *ri = b->a + (size_t)i * ld;
            for (int r = 0; r < nrhs; r++) {
                double *x = xs[r];
                x[i] = (x[i] - SC_DOT(ri + (bw - i), x, i)) * ri[bw];
            }
        }
        for (; i + 3 < n; i += 4) {
            const double *r0 = b->a + (size_t)i * ld;
            for (int r = 0; r < nrhs; r++) SC_SFX(forward_block)(bw, r0, ld, xs[r], i);
        }
    }
    for (; i < n; i++) {
        const double *ri = b->a + (size_t)i * ld;
        int k0 = i - bw < 0 ? 0 : i - bw;
        for (int r = 0; r < nrhs; r++) {
            double *x = xs[r];
            x[i] = (x[i] - SC_DOT(ri + (k0 - i + bw), x + k0, i - k0)) * ri[bw];
        }
    }
}

/* Backward substitution Lᵀ·x = y in place (one or two right-hand sides, as forward), column-
 * oriented: x[i] is final once the rows below it are applied; then x[i-bw..i-1] -= L[i][..]·x[i].
 * Four rows at a time where the band is full (one four-term axpy over the common columns instead
 * of four overlapping ones). */
SC_ATTR static inline void SC_SFX(backward_block)(int bw, const double *r0, size_t ld, double *x,
                                                  int i)
{
    const double *r1 = r0 - ld, *r2 = r1 - ld, *r3 = r2 - ld;
    /* the triangle: rows i, i-1, i-2, i-3 against columns i-1 .. i-3 */
    double x0 = x[i] * r0[bw];
    double x1 = (x[i - 1] - r0[bw - 1] * x0) * r1[bw];
    double x2 = (x[i - 2] - r0[bw - 2] * x0 - r1[bw - 1] * x1) * r2[bw];
    double x3 = (x[i - 3] - r0[bw - 3] * x0 - r1[bw - 2] * x1 - r2[bw - 1] * x2) * r3[bw];
    x[i] = x0;
    x[i - 1] = x1;
    x[i - 2] = x2;
    x[i - 3] = x3;
    /* common columns i-bw .. i-4: row i-r at position c - (i-r) + bw */
    double a[4] = {-x0, -x1, -x2, -x3};
    SC_AXPY4(x + i - bw, a, r0, r1 + 1, r2 + 2, r3 + 3, bw - 3);
    /* tails: row i-r also has columns i-r-bw .. i-bw-1 */
    x[i - 1 - bw] -= r1[0] * x1 + r2[1] * x2 + r3[2] * x3;
    x[i - 2 - bw] -= r2[0] * x2 + r3[1] * x3;
    x[i - 3 - bw] -= r3[0] * x3;
}

SC_ATTR static void SC_SFX(backward)(const sc_lsq_band *b, double *const *xs, int nrhs)
{
    int n = b->n, bw = b->bw;
    size_t ld = b->ld;
    int i = n - 1;
    if (bw >= 4) {
        for (; i - 3 - bw >= 0; i -= 4) {
            const double *r0 = b->a + (size_t)i * ld;
            for (int r = 0; r < nrhs; r++) SC_SFX(backward_block)(bw, r0, ld, xs[r], i);
        }
    }
    for (; i >= 0; i--) {
        const double *ri = b->a + (size_t)i * ld;
        int k0 = i - bw < 0 ? 0 : i - bw;
        for (int r = 0; r < nrhs; r++) {
            double *x = xs[r];
            double xi = x[i] * ri[bw];
            x[i] = xi;
            SC_AXPY(x + k0, -xi, ri + (k0 - i + bw), i - k0);
        }
    }
}

/* B·x_r = b_r for nrhs right-hand sides, one pass over the factor each way. */
SC_ATTR static void SC_SFX(solve)(const sc_lsq_band *b, double *const *xs, int nrhs)
{
    SC_SFX(forward)(b, xs, nrhs);
    SC_SFX(backward)(b, xs, nrhs);
}

/* Move the live window of Z (indices i+1 .. i+bw, stored at row/column index - base of the R×R
 * copy zb) to the far end of the copy, so that the next blocks, below i, fit; the new base. */
SC_ATTR static inline long SC_SFX(window_slide)(double *zb, int R, long base, int i, int bw,
                                                int bwp)
{
    long nbase = (long)i + 1 + bwp - R;
    long shift = base - nbase; /* > 0: positions grow */
    for (int r = bw - 1; r >= 0; r--) {
        double *src = zb + (size_t)(i + 1 + r - base) * R + (size_t)(i + 1 - base);
        memmove(src + shift * R + shift, src, (size_t)bw * sizeof(double));
    }
    return nbase;
}

/* Column kk = i - 24 of L (band a, ld doubles a row, nrow rows), a few blocks ahead, on its way
 * from memory: each of its entries is in another row (another cache line), beyond what the
 * hardware prefetcher follows. */
SC_ATTR static inline void SC_SFX(prefetch_ahead)(const double *a, size_t ld, int bw, int nrow,
                                                  int i)
{
#if defined(__GNUC__)
    int kk = i - 24;
    if (kk >= 0)
        for (int row = kk + 1; row <= kk + bw && row < nrow; row++)
            __builtin_prefetch(a + (size_t)row * ld + (size_t)(kk - row + bw), 0, 1);
#else
    (void)a, (void)ld, (void)bw, (void)nrow, (void)i;
#endif
}

/* Lc[r][q] = L[i+1+q][i-r] for the block's nb rows (rows of bwp; 0 past the band, past the
 * storage's nrow rows and past N = n): row i+1+q holds the four next to each other. */
SC_ATTR static inline void SC_SFX(gather_lc)(double *lc, int bwp, const double *a, size_t ld,
                                             int bw, int nrow, int n, int i, int nb)
{
    for (size_t q = 0; q < 4 * (size_t)bwp; q++) lc[q] = 0.0;
    int qmax = bw - 1;
    if (nrow - 2 - i < qmax) qmax = nrow - 2 - i;
    if (n - 2 - i < qmax) qmax = n - 2 - i;
    for (int q = 0; q <= qmax; q++) {
        const double *src = a + (size_t)(i + 1 + q) * ld + (size_t)(bw - 1 - q);
        int rmax = bw - 1 - q < nb - 1 ? bw - 1 - q : nb - 1;
        for (int r = 0; r <= rmax; r++) lc[(size_t)r * bwp + q] = src[-r];
    }
}

/* The same recurrences four steps at a time (bw >= 8), over a sliding (non-circular) copy of the
 * window: Z over the indices base .. base+R-1 at row/column (index - base), R = bwp + 64 (bwp = bw
 * rounded up to 4); when the next block would fall below base, the live window (indices
 * i+1 .. i+bw) is moved to the far end (one bw×bw copy per 64 steps). Block K = i-3 .. i:
 *   1. T = Lc·W: Lc[r][q] = L[i+1+q][i-r] (0 past the band), W = Z over i+1 .. i+bw — a 4×bw by
 *      bw×bw product, register-tiled (SC_GEMM4): the window is read once per four steps;
 *   2. rows k = i, i-1, .. i-3 in turn: the terms from the rows of K above k (known by then)
 *      are added, Z[k][·] = -T/L[k][k]; the columns inside K by symmetry; the diagonal last.
 * Scratch: R·R + 8·bwp doubles. */
SC_ATTR static void SC_SFX(inverse_diag_blocked)(const sc_lsq_band *b, double *scr, double *diag,
                                                 int i0, const double *zss, int s)
{
    const int n = b->n, nrow = b->nrow, bw = b->bw;
    const size_t ld = b->ld;
    const double *a = b->a;
    const int bwp = (bw + 3) & ~3, R = bwp + 64;
    double *zb = scr, *lc = zb + (size_t)R * R, *tw = lc + 4 * (size_t)bwp;
    for (size_t q = 0; q < (size_t)R * R + 8 * (size_t)bwp; q++) scr[q] = 0.0;
    long base = (long)i0 + 1 + bwp - R;
#define ZB(k, j) zb[(size_t)((k) - base) * R + (size_t)((j) - base)]
    int sw = s < bw ? s : bw;
    for (int r = 0; r < sw; r++)
        for (int c = 0; c < sw; c++) ZB(i0 + 1 + r, i0 + 1 + c) = zss[(size_t)r * s + c];
    int i = i0;
    while (i >= 0) {
        int nb = i + 1 < 4 ? i + 1 : 4;
        if (i - nb + 1 - base < 0) base = SC_SFX(window_slide)(zb, R, base, i, bw, bwp);
        SC_SFX(prefetch_ahead)(a, ld, bw, nrow, i);
        SC_SFX(gather_lc)(lc, bwp, a, ld, bw, nrow, n, i, nb);
        SC_GEMM4(tw, bwp, lc, bwp, &ZB(i + 1, i + 1), R, bw, bwp);
        for (int r = 0; r < nb; r++) {
            int k = i - r;
            double rkk = a[(size_t)k * ld + bw];
            const double *lr = lc + (size_t)r * bwp;
            double *tr = tw + (size_t)r * bwp;
            double *zk = &ZB(k, i + 1);
            /* window columns: + Σ_{q=k+1}^{i} L[q][k]·Z[q][j] */
            for (int q = k + 1; q <= i; q++) {
                double lqk = a[(size_t)q * ld + (size_t)(k - q + bw)];
                const double *zq = &ZB(q, i + 1);
                for (int j = 0; j < bw; j++) tr[j] += lqk * zq[j];
            }
            double acc = 0.0;
            for (int j = 0; j < bw; j++) {
                double z = -tr[j] * rkk;
                zk[j] = z;
                acc += lr[j] * z;
            }
            /* columns inside the block: j = k+1 .. i */
            for (int j = k + 1; j <= i; j++) {
                double v = SC_DOT(lr, &ZB(j, i + 1), bw);
                for (int q = k + 1; q <= i; q++)
                    v += a[(size_t)q * ld + (size_t)(k - q + bw)] * ZB(q, j);
                double z = -v * rkk;
                ZB(k, j) = z;
                ZB(j, k) = z;
                acc += a[(size_t)j * ld + (size_t)(k - j + bw)] * z;
            }
            double zkk = (rkk - acc) * rkk;
            ZB(k, k) = zkk;
            diag[k] = zkk;
        }
        /* the block's columns in the window rows, by symmetry (the block's rows are contiguous
         * there: one short store per window row) */
        for (int j = 0; j < bw; j++) {
            double *dst = &ZB(i + 1 + j, i - nb + 1);
            for (int r = 0; r < nb; r++) dst[nb - 1 - r] = ZB(i - r, i + 1 + j);
        }
        i -= nb;
    }
#undef ZB
}

/* Row i of Z from t (= Σ_k L[k][i]·Z[k][·] over the window slots): Z[i][k] = -t[slot k]/L[i][i],
 * Z[i][i] = (1/L[i][i])(1/L[i][i] - Σ_k L[k][i]·Z[i][k]); written into row and column slot(i). */
SC_ATTR static inline double SC_SFX(window_row)(double *win, int w, int ws, int i, double rii,
                                                const double *t, const double *l, int cnt)
{
    int si = i % w;
    double *row_i = win + (size_t)si * ws;
    double acc = 0.0;
    int sk = (i + 1) % w;
    for (int q = 0; q < cnt; q++) {
        double zik = -t[sk] * rii;
        row_i[sk] = zik;
        win[(size_t)sk * ws + si] = zik;
        acc += l[q] * zik;
        sk = sk + 1 == w ? 0 : sk + 1;
    }
    double zii = (rii - acc) * rii;
    row_i[si] = zii;
    return zii;
}

/* diag(B⁻¹) by the Takahashi recurrences, i = n-1 down to 0 (Z = B⁻¹, L = the factor):
 *   Z[i][j] = -(1/L[i][i]) Σ_{k=i+1}^{i+bw} L[k][i] Z[k][j]   (j = i+1 .. i+bw)
 *   Z[i][i] = (1/L[i][i]) (1/L[i][i] - Σ_k L[k][i] Z[k][i])
 * keeping only the (bw+1)×(bw+1) window of Z the next step needs, as a circular buffer: index k
 * lives in row and column k mod (bw+1) (row stride ws, a multiple of 4). t accumulates over all
 * columns (the stale ones are never read). In the interior two steps i, i-1 share one pass over
 * the window rows i+1 .. i+bw-1 (SC_GEMV2_ROWS); the terms that need row i of Z — not yet known
 * during that pass — are added after it. */
SC_ATTR static void SC_SFX(inverse_diag)(const sc_lsq_band *b, double *win, double *diag, int i0,
                                         const double *zss, int s)
{
    int n = b->n, bw = b->bw;
    int w = bw + 1, ws = (w + 3) & ~3;
    double *t = win + (size_t)ws * w;
    double *u = t + ws;
    double *l = u + ws;
    double *m = l + w;
    const double **rows = (const double **)(m + w);
    size_t ldm1 = b->ld - 1;
    if (bw >= 8) {
        SC_SFX(inverse_diag_blocked)(b, win, diag, i0, zss, s);
        return;
    }
    for (size_t q = 0; q < (size_t)ws * w + 2 * (size_t)ws; q++) win[q] = 0.0;
    /* the given block of B⁻¹ over i0+1 .. i0+s: the window needs i0+1 .. i0+bw of it */
    int sw = s < w ? s : w;
    for (int r = 0; r < sw; r++)
        for (int c = 0; c < sw; c++)
            win[(size_t)((i0 + 1 + r) % w) * ws + (size_t)((i0 + 1 + c) % w)] =
                zss[(size_t)r * s + c];
    int i = i0;
    while (i >= 0) {
        int cnt = (i + bw < n - 1 ? i + bw : n - 1) - i;
        const double rii = b->a[(size_t)i * b->ld + bw];
        const double *lk = b->a + (size_t)(i + 1) * b->ld + (bw - 1);
        for (int q = 0; q < cnt; q++, lk += ldm1) l[q] = *lk;
        for (int q = 0, sk = (i + 1) % w; q < cnt; q++, sk = sk + 1 == w ? 0 : sk + 1)
            rows[q] = win + (size_t)sk * ws;
        if (cnt == bw && i >= 1 && bw >= 2) {
            /* the pair i, h = i-1: m[q] = L[i+q][h], q = 0 .. bw-1 */
            int h = i - 1;
            const double rhh = b->a[(size_t)h * b->ld + bw];
            const double *mk = b->a + (size_t)i * b->ld + (bw - 1);
            for (int q = 0; q < bw; q++, mk += ldm1) m[q] = *mk;
            /* shared rows k = i+1 .. i+bw-1; row i+bw only for i */
            SC_GEMV2_ROWS(t, u, l, m + 1, rows, bw - 1, ws);
            SC_AXPY(t, l[bw - 1], rows[bw - 1], ws);
            diag[i] = SC_SFX(window_row)(win, w, ws, i, rii, t, l, cnt);
            /* the row-i terms of h: all columns, then column i itself by symmetry (row i) */
            const double *row_i = win + (size_t)(i % w) * ws;
            SC_AXPY(u, m[0], row_i, ws);
            double ui = m[0] * row_i[i % w];
            for (int q = 1, sk = (i + 1) % w; q < bw; q++, sk = sk + 1 == w ? 0 : sk + 1)
                ui += m[q] * row_i[sk];
            u[i % w] = ui;
            diag[h] = SC_SFX(window_row)(win, w, ws, h, rhh, u, m, bw);
            i -= 2;
            continue;
        }
        SC_GEMV_ROWS(t, l, rows, cnt, ws);
        diag[i] = SC_SFX(window_row)(win, w, ws, i, rii, t, l, cnt);
        i -= 1;
    }
}
