# Least-squares grid estimator: create/solve time and peak memory for N = 25, 51, 101.
add_executable(bench_grid_lsq ${CMAKE_CURRENT_SOURCE_DIR}/bench_grid_lsq.c)
target_link_libraries(bench_grid_lsq PRIVATE selfcal_static m)
