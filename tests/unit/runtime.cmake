# selfcald runtime: engine, config, loop with the fake transport, notify protocol, no-allocation.
if(TARGET selfcald_lib AND TARGET selfcal_lut)
  selfcal_unit_test(NAME test_runtime SOURCES unit/test_runtime.c
    LIBS selfcald_lib selfcal_lut LABELS runtime TIMEOUT 60)
endif()
if(TARGET selfcald_lib AND TARGET selfcal_lut)
  selfcal_unit_test(NAME test_runtime_noalloc SOURCES unit/test_runtime_noalloc.c
    LIBS selfcald_lib selfcal_lut pthread LABELS runtime TIMEOUT 60)
endif()
