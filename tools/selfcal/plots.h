/* plots.h — the charts the commands draw (SVG), shared by the command that computes a result
 * (`grid --plot`, `profile --plot`) and the one that draws a saved file (`plot map|profile`). */
#ifndef SELFCAL_PLOTS_H
#define SELFCAL_PLOTS_H

#include <stdio.h>

#include "selfcal/error.h"
#include "selfcal/stage_map.h"
#include "selfcal/profile.h"

/* Arrow plot of a stage error map (arrows scaled scale_um_per_pitch µm per pitch; 0 = automatic);
 * with truth, a second panel shows the estimation error. name goes into the title. */
void plot_map_svg(FILE *fp, const sc_stage_map *m, const sc_stage_map *truth,
                  double scale_um_per_pitch, const char *name);

typedef struct profile_plot_opts {
    const char *title, *label_a, *label_b;
    int uncertainty_only;
} profile_plot_opts;

/* Profile chart written atomically to path: f and u(f) of a, optionally against a truth and a
 * second result cmp (each may be NULL), and e_y. */
sc_status profile_plot_write(const char *path, const sc_profile_result *a,
                             const sc_profile_result *truth, const sc_profile_result *cmp,
                             const profile_plot_opts *o, sc_error *err);

#endif
