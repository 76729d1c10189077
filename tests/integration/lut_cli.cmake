# `selfcal lut build|dump|info` through the command line (Python standard library only).
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3)
  add_test(NAME lut_cli
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/lut_cli/test_lut_cli.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/lut_cli)
  set_tests_properties(lut_cli PROPERTIES TIMEOUT 240 LABELS "integration;lut")
endif()
# `lut info`'s |G| and slope bounds against the table's own dump (docs/linuxcnc.md, "Margins").
if(SELFCAL_PYTHON3)
  add_test(NAME lut_bounds
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/lut_cli/test_lut_bounds.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/lut_bounds)
  set_tests_properties(lut_bounds PROPERTIES TIMEOUT 120 LABELS "integration;lut")
endif()
