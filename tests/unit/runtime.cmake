# selfcald runtime: engine, config, loop with the fake transport, notify protocol, no-allocation.
if(SELFCAL_BUILD_RUNTIME)
  selfcal_unit_test(NAME test_runtime SOURCES unit/test_runtime.c
    LIBS selfcald_lib LABELS runtime TIMEOUT 60)
  selfcal_unit_test(NAME test_rtu_framing SOURCES unit/test_rtu_framing.c
    LIBS selfcald_lib LABELS runtime TIMEOUT 60)
  selfcal_unit_test(NAME test_runtime_noalloc SOURCES unit/test_runtime_noalloc.c
    LIBS selfcald_lib pthread LABELS runtime TIMEOUT 60)
endif()
