/* lut_csv.c — fill a table from the files: the stage map (read by io/, selfcal/stage_map.h) and
 * the ey_um column of a SPEC §2 profile output, strict, with the file and line of every problem. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "selfcal/correct.h"
#include "selfcal/csv.h"
#include "selfcal/lut.h"
#include "selfcal/profile_file.h"
#include "selfcal/stage_map.h"
#include "../common/line_fit.h"

sc_status sc_lut_set_grid(sc_lut *lut, const sc_stage_map *m, const char *name, sc_error *err)
{
    if (m->nx > SC_LUT_MAX_NX || m->ny > SC_LUT_MAX_NY)
        return sc_error_set(err, SC_E_INPUT, name, 0,
                            "the map has %d x %d nodes; a table holds at most %d x %d (a "
                            "coarser table can be fitted to it: --max-nodes)",
                            m->nx, m->ny, SC_LUT_MAX_NX, SC_LUT_MAX_NY);
    /* within the limit the fit copies every node's values and the geometry exactly */
    return sc_lut_fit_grid(lut, m, SC_LUT_MAX_NX, name, NULL, err);
}

sc_status sc_lut_read_map(const char *path, sc_lut *lut, sc_error *err)
{
    sc_stage_map m;
    sc_status st = sc_stage_map_read(path, &m, err);
    if (st == SC_OK)
        st = sc_lut_set_grid(lut, &m, path, err);
    sc_stage_map_free(&m);
    return st;
}

sc_status sc_lut_read_profile(const char *path, int axis, int dir, sc_lut_profile *p,
                              sc_error *err)
{
    if (axis < 0 || axis > 2 || dir < 0 || dir > 2)
        return sc_error_set(err, SC_E_INPUT, path, 0, "profile axis/dir must be x, y or z");
    sc_profile_result res;
    sc_status st = sc_profile_read_result(path, &res, err);
    if (st != SC_OK)
        return st;
    if (!res.has_ey)
        st = sc_error_set(err, SC_E_INPUT, path, res.header_line,
                          "expected the profile header n,x_mm,f_um,uf_um,ey_um (no ey_um column)");
    else if (res.n_ey < 2)
        st = sc_error_set(err, SC_E_INPUT, path, res.last_line,
                          "the profile has %d ey_um values; at least 2 are needed", res.n_ey);
    else if (res.n_ey > SC_LUT_MAX_PROFILE_POINTS)
        st = sc_error_set(err, SC_E_INPUT, path, 0, "more than %d profile points",
                          SC_LUT_MAX_PROFILE_POINTS);
    if (st == SC_OK) {
        /* start and step: the least-squares line through the points with a value */
        double kk[SC_LUT_MAX_PROFILE_POINTS];
        for (int i = 0; i < res.n_ey; ++i)
            kk[i] = i;
        sc_line_fit(kk, res.x_mm, (size_t)res.n_ey, &p->start_mm, &p->step_mm);
        memcpy(p->err_um, res.ey_um, (size_t)res.n_ey * sizeof(double));
        p->axis = axis;
        p->dir = dir;
        p->n = res.n_ey;
        p->encoding = 0;
        p->scale_pm = 0;
    }
    sc_profile_result_free(&res);
    return st;
}
