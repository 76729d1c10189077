/* grid_calibrate_common.c — the helpers of grid_calibrate_common.h, shared by the calibration
 * pipeline (grid_calibrate.c) and its view noise estimation (grid_view_noise.c). */
#include <stdarg.h>
#include <stdio.h>

#include "grid_calibrate_common.h"

void sc_grid_warnf(const sc_grid_options *o, const char *fmt, ...)
{
    if (!o->warn)
        return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    o->warn(o->warn_ctx, buf);
}

int sc_grid_view_id(const sc_grid_file_info *info, int v)
{
    return info ? info->view_id[v] : v;
}

sc_grid_lsq_opts sc_grid_lsq_opts_of(const sc_grid_options *o)
{
    sc_grid_lsq_opts q = {.drift = o->drift, .node_sigma_only = o->node_sigma_only,
                          .max_bytes = o->max_bytes, .progress = o->progress,
                          .progress_ctx = o->progress_ctx, .solver = o->solver,
                          .node_sigma = o->node_sigma, .node_sigma_sample = o->node_sigma_sample};
    return q;
}
