/* The least-squares solver's options of `grid` (and what `plan` names): --solver and
 * --node-sigma (docs/grid-lsq.md, "Large stages"). */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "selfcal/grid_calibrate.h"
#include "selfcal/csv.h"
#include "selfcal/grid_lsq.h"

int cli_parse_solver(const char *cmd, const char *v, int *out)
{
    if (!strcmp(v, "auto"))
        *out = SC_GRID_SOLVER_AUTO;
    else if (!strcmp(v, "reduced"))
        *out = SC_GRID_SOLVER_REDUCED;
    else if (!strcmp(v, "full"))
        *out = SC_GRID_SOLVER_FULL;
    else
        return cli_usage_error(cmd, "--solver must be auto, reduced or full, got '%s'", v);
    return CLI_OK;
}

int cli_parse_node_sigma(const char *cmd, const char *v, int *mode, int *sample)
{
    long k = 0;
    *sample = 0;
    if (!strcmp(v, "all"))
        *mode = SC_GRID_NODE_SIGMA_ALL;
    else if (!strcmp(v, "none"))
        *mode = SC_GRID_NODE_SIGMA_NONE;
    else if (!strncmp(v, "sample:", 7) && !sc_parse_long(v + 7, &k) && k >= 1 && k <= 1000000) {
        *mode = SC_GRID_NODE_SIGMA_SAMPLE;
        *sample = (int)k;
    } else
        return cli_usage_error(cmd, "--node-sigma must be all, none or sample:K (K nodes, 1 to "
                                    "1e6), got '%s'", v);
    return CLI_OK;
}

int cli_opt_solver(const char *cmd, const char *opt, const char *v, void *field)
{
    (void)opt;
    return cli_parse_solver(cmd, v, field);
}

int cli_opt_node_sigma(const char *cmd, const char *opt, const char *v, void *field)
{
    sc_grid_options *o = field;
    (void)opt;
    return cli_parse_node_sigma(cmd, v, &o->node_sigma, &o->node_sigma_sample);
}
