# The correction core: nanoseconds per sc_corr_apply() with a 25 x 25 map and two 330-point
# profiles, and the table file's size. Build Release without sanitizers.
add_executable(bench_core_apply ${CMAKE_CURRENT_SOURCE_DIR}/bench_core_apply.c)
target_link_libraries(bench_core_apply PRIVATE selfcal_static)
