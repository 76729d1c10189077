# selfcald Modbus TCP round trip (p50/p99 with 1 and 64 clients). Build Release, no sanitizers.
if(SELFCAL_BUILD_RUNTIME)
  add_executable(bench_modbus ${CMAKE_CURRENT_SOURCE_DIR}/bench_modbus.c)
  target_link_libraries(bench_modbus PRIVATE selfcald_lib pthread)
endif()
