# The Monte Carlo check of the grid uncertainty budget (SPEC §11): time on 1 and 2 threads, ratios.
add_executable(bench_grid_scale_mc ${CMAKE_CURRENT_SOURCE_DIR}/bench_grid_scale_mc.c)
target_link_libraries(bench_grid_scale_mc PRIVATE selfcal_static m)
