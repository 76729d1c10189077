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

/* Right-looking banded Cholesky in panels of four columns: copy the panel (its four columns, rows
 * j .. j+3+bw) into contiguous scratch, factor it there (pivot square roots, column scaling,
 * updates inside the panel), write it back, then subtract its rank-4 outer product from the
 * trailing bw×bw triangle, row by row: each row a contiguous four-term axpy up to the diagonal.
 * Rows are assembled just before the first panel that reaches them, so the working window stays
 * in cache. The diagonal slot keeps 1/L[i][i]. col: 4·(bw+4) doubles. */
SC_ATTR static int SC_SFX(factor)(sc_lsq_band *b, double *col)
{
    int ncol = b->ncol, nrow = b->nrow, bw = b->bw;
    size_t ld = b->ld;
    int h = bw + 4; /* panel rows j .. j+3+bw */
    double *pc[4] = {col, col + h, col + 2 * (size_t)h, col + 3 * (size_t)h};
    int next_row = 0;
    for (int j = 0; j < ncol; j += 4) {
        int nb = ncol - j < 4 ? ncol - j : 4;
        int last = j + nb - 1 + bw < nrow - 1 ? j + nb - 1 + bw : nrow - 1;
        while (next_row <= last) SC_SFX(assemble_row)(b, next_row++);
        /* gather: pc[c][k - j] = L[k][j+c] (0 outside the band, above the diagonal, past N) */
        for (int c = 0; c < nb; c++) {
            double *pcc = pc[c];
            for (int q = 0; q < h; q++) {
                int k = j + q;
                pcc[q] = (q >= c && k <= last && k <= j + c + bw)
                             ? b->a[(size_t)k * ld + (size_t)(j + c - k + bw)]
                             : 0.0;
            }
        }
        /* factor the panel in the scratch */
        for (int c = 0; c < nb; c++) {
            double *pcc = pc[c];
            double djj = pcc[c];
            if (!(djj > 0.0) || !(djj < INFINITY)) return j + c;
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
        /* write the panel back */
        for (int c = 0; c < nb; c++) {
            const double *pcc = pc[c];
            int kmax = j + c + bw < last ? j + c + bw : last;
            for (int k = j + c; k <= kmax; k++)
                b->a[(size_t)k * ld + (size_t)(j + c - k + bw)] = pcc[k - j];
        }
        if (nb < 4) continue; /* the last columns (ncol = nrow, or ncol % 4 = 0): nothing trails */
        /* trailing rows k = j+4 .. last, columns j+4 .. k: row -= Σ_c L[k][j+c]·L[·][j+c] */
        int l0 = j + 4;
        const double *v0 = pc[0] + 4, *v1 = pc[1] + 4, *v2 = pc[2] + 4, *v3 = pc[3] + 4;
        for (int k = l0; k <= last; k++) {
            double *row = b->a + (size_t)k * ld;
            int q = k - l0;
            double a[4] = {-v0[q], -v1[q], -v2[q], -v3[q]};
            SC_AXPY4(row + (l0 - k + bw), a, v0, v1, v2, v3, q + 1);
        }
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
