# The whole `selfcal grid --method lsq` command against SuiteSparse CHOLMOD on the same matrix
# (issue 11's targets); runs the selfcal executable it names.
add_executable(bench_grid_cholmod ${CMAKE_CURRENT_SOURCE_DIR}/bench_grid_cholmod.c)
target_link_libraries(bench_grid_cholmod PRIVATE selfcal_static selfcal_cholmod m)
target_compile_definitions(bench_grid_cholmod PRIVATE SELFCAL_CLI="$<TARGET_FILE:selfcal_cli>")
add_dependencies(bench_grid_cholmod selfcal_cli)
