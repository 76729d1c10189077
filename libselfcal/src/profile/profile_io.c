/* profile_io.c — owns the method check of a profile data set read from a file: whether the
 * chosen method can solve its (N, d1, d2), reported at the header line it is about. The files
 * themselves are io/'s (selfcal/profile_file.h). */
#include <stdbool.h>
#include <string.h>

#include "selfcal/profile.h"
#include "selfcal/profile_dft.h"
#include "selfcal/profile_lsq.h"

sc_status sc_profile_check_method(const sc_profile_data *d, sc_profile_method method,
                                  sc_error *err)
{
    sc_error e;
    sc_error_clear(&e);
    bool ok = method == SC_PROFILE_DFT ? sc_profile_dft_is_usable(d->n, d->d[0], d->d[1], &e)
                                      : sc_profile_lsq_is_solvable(d->n, d->d[0], d->d[1], &e);
    if (ok)
        return SC_OK;
    /* point at the header line the condition is about: the scan lines for the spacings, the N
     * line for the length */
    long line = d->line_scan[1] ? d->line_scan[1] : d->line_n;
    if (strstr(e.msg, "N ") == e.msg || strstr(e.msg, "too small") || strstr(e.msg, "multiple"))
        line = d->line_n ? d->line_n : line;
    return sc_error_set(err, e.code == SC_OK ? SC_E_INPUT : e.code, d->path[0] ? d->path : NULL,
                        line, "%s method: %s", method == SC_PROFILE_DFT ? "dft" : "lsq", e.msg);
}
