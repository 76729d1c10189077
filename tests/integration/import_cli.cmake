# CLI tests of selfcal import grid|profile and simulate exports (SPEC §10), and the guide's commands.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  set(_import_cli_py ${CMAKE_CURRENT_SOURCE_DIR}/integration/import_cli/import_cli_test.py)
  foreach(case recover recover_one_view formats placement stage bad_input simulate_exports profile weights stitched
               partial vendors vendor_messages profile_layouts simulate_exports_many)
    add_test(NAME import_cli_${case} COMMAND ${SELFCAL_PYTHON3} ${_import_cli_py}
             $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp ${case})
    set_tests_properties(import_cli_${case} PROPERTIES TIMEOUT 120 LABELS "integration;import")
  endforeach()
endif()
