/* grid_node.c — a small program outside selfcal that uses the installed library: read a grid
 * measurement file (selfcal-grid v1), solve by least squares, print one stage node's error with
 * its standard uncertainty.
 *
 *   usage: grid_node MEASUREMENT.csv [I J]     (stage node row I, column J; default: the centre)
 *   build: make                (Makefile, pkg-config selfcal)
 *          cmake -S . -B build && cmake --build build   (CMakeLists.txt, find_package(selfcal))
 */
#include <stdio.h>
#include <stdlib.h>

#include <selfcal/grid_io.h>
#include <selfcal/grid_lsq.h>
#include <selfcal/version.h>

static int fail(const sc_error *err)
{
    char msg[1024];
    sc_error_format(err, msg, sizeof msg); /* "FILE:LINE: reason" */
    fprintf(stderr, "grid_node: %s\n", msg);
    return err->code == SC_E_INPUT || err->code == SC_E_UNSOLVABLE ? 2 : 1;
}

int main(int argc, char **argv)
{
    if (argc != 2 && argc != 4) {
        fprintf(stderr, "usage: grid_node MEASUREMENT.csv [I J]\n");
        return 2;
    }
    sc_error err;
    sc_grid_data data;
    if (sc_grid_read(argv[1], &data, NULL, &err) != SC_OK) /* fills data.plan, allocates data */
        return fail(&err);
    /* The stage grid: NX x NY nodes (the plate's N x N unless the file says `# stage = NX,NY`). */
    const int nx = sc_grid_stage_nx(&data.plan), ny = sc_grid_stage_ny(&data.plan);
    const int i = argc == 4 ? atoi(argv[2]) : (ny - 1) / 2;
    const int j = argc == 4 ? atoi(argv[3]) : (nx - 1) / 2;
    if (i < 0 || i >= ny || j < 0 || j >= nx) {
        fprintf(stderr, "grid_node: node %d,%d is outside the %d x %d stage grid\n", i, j, nx, ny);
        sc_grid_data_free(&data);
        return 2;
    }

    /* The result arrays are the caller's: one double per stage node, row-major (i*NX + j). */
    size_t nn = (size_t)sc_grid_stage_nodes(&data.plan);
    double *gx = malloc(nn * sizeof *gx), *gy = malloc(nn * sizeof *gy);
    double *ugx = malloc(nn * sizeof *ugx), *ugy = malloc(nn * sizeof *ugy);
    sc_grid_result res = {0};
    res.gx_um = gx;
    res.gy_um = gy;
    res.ugx_um = ugx;
    res.ugy_um = ugy; /* ax_um/ay_um (the plate's errors) stay NULL: not wanted here */

    int rc = 0;
    sc_grid_lsq_plan *lsq = NULL; /* plan object: create analyses and factors, solve, destroy */
    if (!gx || !gy || !ugx || !ugy) {
        fprintf(stderr, "grid_node: out of memory\n");
        rc = 1;
    } else if (sc_grid_lsq_plan_create(&data.plan, &data, NULL, &lsq, &err) != SC_OK ||
               sc_grid_lsq_execute(lsq, &data, 0.0 /* σ_r from the residuals */, &res, &err) != SC_OK) {
        rc = fail(&err);
    } else {
        double x_mm, y_mm;
        sc_grid_node_xy_mm(&data.plan, i, j, &x_mm, &y_mm);
        size_t k = (size_t)i * nx + j;
        printf("libselfcal %s, %s: N = %d, %d views, sigma_r = %.6f um\n", sc_version(), argv[1],
               data.plan.n, data.plan.n_views, res.sigma_r_used_um);
        printf("node %d,%d at (%.3f, %.3f) mm: gx = %.6f +- %.6f um, gy = %.6f +- %.6f um\n", i, j,
               x_mm, y_mm, gx[k], ugx[k], gy[k], ugy[k]);
    }
    sc_grid_lsq_plan_destroy(lsq);
    sc_grid_data_free(&data);
    free(gx);
    free(gy);
    free(ugx);
    free(ugy);
    return rc;
}
