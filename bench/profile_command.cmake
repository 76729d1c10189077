# The whole `selfcal profile` pipeline at N = 10⁶: read, solve, write; number conversions vs glibc.
add_executable(bench_profile_command ${CMAKE_CURRENT_SOURCE_DIR}/bench_profile_command.c)
target_link_libraries(bench_profile_command PRIVATE selfcal_static m)
