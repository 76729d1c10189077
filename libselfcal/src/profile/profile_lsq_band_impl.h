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

/* Right-looking banded Cholesky in panels of four columns: factor the panel (pivot square roots,
 * column scaling, updates inside the panel), then subtract the panel's rank-4 outer product from
 * the trailing bw×bw triangle, row by row: each row a contiguous four-term axpy up to the diagonal
 * (four multiply-adds per load and store). Rows are assembled just before the first panel that
 * reaches them, so the working window stays in cache. */
SC_ATTR static int SC_SFX(factor)(sc_lsq_band *b, double *col)
{
    int n = b->n, bw = b->bw;
    size_t ld = b->ld;
    double *v[4] = {col, col + bw, col + 2 * (size_t)bw, col + 3 * (size_t)bw};
    int next_row = 0;
    for (int j = 0; j < n; j += 4) {
        int nb = n - j < 4 ? n - j : 4;
        int last = j + nb - 1 + bw < n - 1 ? j + nb - 1 + bw : n - 1;
        while (next_row <= last) SC_SFX(assemble_row)(b, next_row++);
        /* the panel: columns j .. j+nb-1 */
        for (int c = 0; c < nb; c++) {
            int jc = j + c;
            double *rj = b->a + (size_t)jc * ld;
            double djj = rj[bw];
            if (!(djj > 0.0) || !(djj < INFINITY)) return jc;
            double inv = 1.0 / sqrt(djj);
            rj[bw] = inv;
            int kmax = jc + bw < n - 1 ? jc + bw : n - 1;
            double *rk = rj + ld + (bw - 1); /* L[jc+1][jc] */
            for (int k = jc + 1; k <= kmax; k++, rk += ld - 1) *rk *= inv;
            for (int c2 = c + 1; c2 < nb; c2++) {
                int jl = j + c2;
                double m = b->a[(size_t)jl * ld + (size_t)(jc - jl + bw)];
                if (m == 0.0) continue;
                for (int k = jl; k <= kmax; k++) {
                    double *row = b->a + (size_t)k * ld;
                    row[jl - k + bw] -= row[jc - k + bw] * m;
                }
            }
        }
        if (nb < 4) continue; /* the last columns: nothing trails */
        /* v[c][l - j - 4] = L[l][j+c] for l = j+4 .. j+3+bw (0 outside the band or the matrix) */
        int l0 = j + 4;
        for (int c = 0; c < 4; c++)
            for (int q = 0; q < bw; q++) {
                int l = l0 + q;
                v[c][q] = (l <= last && l <= j + c + bw)
                              ? b->a[(size_t)l * ld + (size_t)(j + c - l + bw)]
                              : 0.0;
            }
        for (int k = l0; k <= last; k++) {
            double *row = b->a + (size_t)k * ld;
            double a[4];
            for (int c = 0; c < 4; c++) a[c] = (k <= j + c + bw) ? -row[j + c - k + bw] : 0.0;
            SC_AXPY4(row + (l0 - k + bw), a, v[0], v[1], v[2], v[3], k - l0 + 1);
        }
    }
    return -1;
}

SC_ATTR static void SC_SFX(solve2)(const sc_lsq_band *b, double *x, double *y)
{
    int n = b->n, bw = b->bw;
    for (int i = 0; i < n; i++) {
        const double *ri = b->a + (size_t)i * b->ld;
        int k0 = i - bw < 0 ? 0 : i - bw;
        x[i] = (x[i] - SC_DOT(ri + (k0 - i + bw), x + k0, i - k0)) * ri[bw];
        if (y) y[i] = (y[i] - SC_DOT(ri + (k0 - i + bw), y + k0, i - k0)) * ri[bw];
    }
    for (int i = n - 1; i >= 0; i--) {
        const double *ri = b->a + (size_t)i * b->ld;
        int k0 = i - bw < 0 ? 0 : i - bw;
        double xi = x[i] * ri[bw];
        x[i] = xi;
        SC_AXPY(x + k0, -xi, ri + (k0 - i + bw), i - k0);
        if (y) {
            double yi = y[i] * ri[bw];
            y[i] = yi;
            SC_AXPY(y + k0, -yi, ri + (k0 - i + bw), i - k0);
        }
    }
}

/* diag(B⁻¹) by the Takahashi recurrences, i = n-1 down to 0 (Z = B⁻¹, L = the factor):
 *   Z[i][j] = -(1/L[i][i]) Σ_{k=i+1}^{i+bw} L[k][i] Z[k][j]   (j = i+1 .. i+bw)
 *   Z[i][i] = (1/L[i][i]) (1/L[i][i] - Σ_k L[k][i] Z[k][i])
 * keeping only the (bw+1)×(bw+1) window of Z the next step needs, as a circular buffer: index k
 * lives in row and column k mod (bw+1). t accumulates over all bw+1 columns (one of them, slot i,
 * is stale and ignored), so each step is bw contiguous axpys, four at a time. */
SC_ATTR static void SC_SFX(inverse_diag)(const sc_lsq_band *b, double *win, double *diag)
{
    int n = b->n, bw = b->bw;
    int w = bw + 1;
    double *t = win + (size_t)w * w;
    double *l = t + w;
    for (size_t s = 0; s < (size_t)w * w; s++) win[s] = 0.0;
    for (int i = n - 1; i >= 0; i--) {
        const double rii = b->a[(size_t)i * b->ld + bw];
        int cnt = (i + bw < n - 1 ? i + bw : n - 1) - i;
        const double *lk = b->a + (size_t)(i + 1) * b->ld + (bw - 1);
        for (int q = 0; q < cnt; q++, lk += b->ld - 1) l[q] = *lk;
        for (int s = 0; s < w; s++) t[s] = 0.0;
        int q = 0, sk = (i + 1) % w;
        for (; q + 4 <= cnt; q += 4) {
            int s0 = sk, s1 = s0 + 1 == w ? 0 : s0 + 1, s2 = s1 + 1 == w ? 0 : s1 + 1,
                s3 = s2 + 1 == w ? 0 : s2 + 1;
            SC_AXPY4(t, l + q, win + (size_t)s0 * w, win + (size_t)s1 * w, win + (size_t)s2 * w,
                     win + (size_t)s3 * w, w);
            sk = s3 + 1 == w ? 0 : s3 + 1;
        }
        for (; q < cnt; q++) {
            SC_AXPY(t, l[q], win + (size_t)sk * w, w);
            sk = sk + 1 == w ? 0 : sk + 1;
        }
        int si = i % w;
        double *row_i = win + (size_t)si * w;
        double acc = 0.0;
        sk = (i + 1) % w;
        for (q = 0; q < cnt; q++) {
            double zik = -t[sk] * rii;
            row_i[sk] = zik;
            win[(size_t)sk * w + si] = zik;
            acc += l[q] * zik;
            sk = sk + 1 == w ? 0 : sk + 1;
        }
        double zii = (rii - acc) * rii;
        row_i[si] = zii;
        diag[i] = zii;
    }
}
