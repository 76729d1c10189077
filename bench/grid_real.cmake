# Monte Carlo of grid least squares on real measurements (weights, outlier test, chi2 test) and
# the stitched 101 x 101 stage with a 51 x 51 plate: `bench_grid_real [--trials T] [--no-big]`.
add_executable(bench_grid_real ${CMAKE_CURRENT_SOURCE_DIR}/bench_grid_real.c)
target_link_libraries(bench_grid_real PRIVATE selfcal_static m)
