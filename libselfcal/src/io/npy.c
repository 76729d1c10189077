/* The numpy .npy matrix (format 1.0: magic, version, a header dictionary padded to 64 bytes, then
 * the doubles little-endian in C order): `selfcal grid --covariance`'s output. */
#include "selfcal/grid_io.h"

#include <stdio.h>
#include <string.h>

void sc_fprint_npy(FILE *fp, const double *a, long rows, long cols)
{
    char head[128];
    int len = snprintf(head, sizeof head,
                       "{'descr': '<f8', 'fortran_order': False, 'shape': (%ld, %ld), }", rows,
                       cols);
    int total = 10 + len + 1, pad = (64 - total % 64) % 64;
    unsigned hl = (unsigned)(len + pad + 1);
    fwrite("\x93NUMPY\x01\x00", 1, 8, fp);
    fputc((int)(hl & 0xff), fp);
    fputc((int)(hl >> 8), fp);
    fwrite(head, 1, (size_t)len, fp);
    for (int k = 0; k < pad; ++k)
        fputc(' ', fp);
    fputc('\n', fp);
    const unsigned one = 1;
    int little = *(const unsigned char *)&one == 1;
    for (long k = 0; k < rows * cols; ++k) {
        unsigned char b[8];
        memcpy(b, &a[k], 8);
        if (!little)
            for (int t = 0; t < 4; ++t) {
                unsigned char c = b[t];
                b[t] = b[7 - t];
                b[7 - t] = c;
            }
        fwrite(b, 1, 8, fp);
    }
}
