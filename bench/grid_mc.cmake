# Monte Carlo of the grid methods (Petrò §5): sigma_C/sigma_r tables. `bench_grid_mc --full` for the complete run.
add_executable(bench_grid_mc ${CMAKE_CURRENT_SOURCE_DIR}/bench_grid_mc.c)
target_link_libraries(bench_grid_mc PRIVATE selfcal_static m)
