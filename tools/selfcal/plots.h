/* plots.h — the charts the commands draw (SVG), shared by the command that computes a result
 * (`grid --plot`, `profile --plot`) and the one that draws a saved file (`plot map|profile`). */
#ifndef SELFCAL_PLOTS_H
#define SELFCAL_PLOTS_H

#include <stdio.h>

#include "selfcal/error.h"
#include "selfcal/stage_map.h"
#include "selfcal/profile.h"

/* Arrow plot of a stage error map (arrows scaled scale_um_per_pitch µm per pitch; 0 = automatic);
 * with truth, a panel shows the estimation error; with uncertainties, a panel shows u(G) as a
 * colour map. name goes into the title (shortened to fit). plate: 1 if m is a plate error (plate
 * frame), 0 for a stage map. */
void plot_map_svg(FILE *fp, const sc_stage_map *m, const sc_stage_map *truth,
                  double scale_um_per_pitch, const char *name, int plate);

/* One arrow panel of (m->gx_um, m->gy_um) as a whole SVG document; what names the vector ("G"). */
void plot_arrows_svg(FILE *fp, const sc_stage_map *m, int plate, double scale_um_per_pitch,
                     const char *title, const char *what);

/* Two stage-frame arrow panels side by side, each with its own scale (e.g. before and after
 * compensation), under an optional heading, as a whole SVG document. */
void plot_arrows_pair_svg(FILE *fp, const sc_stage_map *a, const char *title_a,
                          const sc_stage_map *b, const char *title_b, const char *heading);

/* A colour map of v (one value per node of m, NaN = grey) with its colour scale, as a whole SVG
 * document; diverging: symmetric scale about 0 (signed values), else from 0 (magnitudes). */
void plot_colormap_svg(FILE *fp, const sc_stage_map *m, int plate, const double *v,
                       const char *title, const char *unit, int diverging);

/* Histogram of the finite values of v[0..n-1] with the normal density of sigma (if > 0). */
void plot_histogram_svg(FILE *fp, const double *v, long n, double sigma, const char *title,
                        const char *xlabel);

typedef struct profile_plot_opts {
    const char *title, *label_a, *label_b;
    int uncertainty_only;
} profile_plot_opts;

/* Profile chart to an open stream: f with its ±u (k = 1) and ±2u (k = 2) bands when u is known,
 * u(f) of a (and cmp), the error against truth, e_y. Each of truth, cmp may be NULL. */
sc_status profile_plot_svg(FILE *fp, const sc_profile_result *a, const sc_profile_result *truth,
                           const sc_profile_result *cmp, const profile_plot_opts *o, sc_error *err);

/* Profile chart written atomically to path: f and u(f) of a, optionally against a truth and a
 * second result cmp (each may be NULL), and e_y. */
sc_status profile_plot_write(const char *path, const sc_profile_result *a,
                             const sc_profile_result *truth, const sc_profile_result *cmp,
                             const profile_plot_opts *o, sc_error *err);

#endif
