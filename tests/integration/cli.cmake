# The command line as a newcomer meets it: the --help tree and --version, the grid summary on
# stdout (--quiet), placing a profile on the machine axis in `lut build`. Label: cli.
set(_cli_daemon none)  # a build without the runtime (SELFCAL_BUILD_RUNTIME=OFF) checks the CLI only
if(TARGET selfcald)
  set(_cli_daemon $<TARGET_FILE:selfcald>)
endif()
foreach(case help grid_summary lut_offset bad_values)
  add_test(NAME cli_${case}
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/cli/test_cli.py ${case}
            $<TARGET_FILE:selfcal_cli> ${_cli_daemon} ${CMAKE_CURRENT_BINARY_DIR}/tmp/cli_${case}
            ${PROJECT_VERSION})
  set_tests_properties(cli_${case} PROPERTIES TIMEOUT 120 LABELS "integration;cli")
endforeach()
