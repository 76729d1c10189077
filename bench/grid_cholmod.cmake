# Grid least squares against SuiteSparse CHOLMOD on the same matrix (issue 11's targets).
add_executable(bench_grid_cholmod ${CMAKE_CURRENT_SOURCE_DIR}/bench_grid_cholmod.c)
target_link_libraries(bench_grid_cholmod PRIVATE selfcal_static selfcal_cholmod m)
