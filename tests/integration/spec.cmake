# SPEC conformance suite (black box): uses only the commands, file formats and wire maps of
# /work/shared/SPEC.md, with independent Python (stdlib) parsers, forward models and a raw-socket
# Modbus TCP client. Label: spec.
find_program(SELFCAL_SPEC_PYTHON3 python3)
if(SELFCAL_SPEC_PYTHON3 AND TARGET selfcal_cli)
  set(_spec_dir ${CMAKE_CURRENT_SOURCE_DIR}/integration/spec)
  set(_spec_tmp ${CMAKE_CURRENT_BINARY_DIR}/tmp/spec)
  function(spec_cli_test name script)
    add_test(NAME ${name} COMMAND ${SELFCAL_SPEC_PYTHON3} ${_spec_dir}/${script} $<TARGET_FILE:selfcal_cli> ${_spec_tmp} ${ARGN})
    set_tests_properties(${name} PROPERTIES TIMEOUT 60 LABELS "integration;spec")
  endfunction()
  spec_cli_test(spec_grid_simulate spec_grid.py simulate)
  spec_cli_test(spec_grid_recover spec_grid.py recover)
  spec_cli_test(spec_grid_plan spec_grid.py plan)
  spec_cli_test(spec_profile_recover spec_profile.py recover)
  spec_cli_test(spec_profile_sigma spec_profile.py sigma)
  spec_cli_test(spec_errors spec_errors.py)
  if(TARGET selfcald)
    function(spec_runtime_test name mode)
      add_test(NAME ${name} COMMAND ${SELFCAL_SPEC_PYTHON3} ${_spec_dir}/spec_runtime.py
               $<TARGET_FILE:selfcal_cli> $<TARGET_FILE:selfcald> ${_spec_tmp} ${mode})
      set_tests_properties(${name} PROPERTIES TIMEOUT 60 LABELS "integration;spec")
    endfunction()
    spec_runtime_test(spec_lut_dump lut)
    spec_runtime_test(spec_modbus_measure modbus)
    spec_runtime_test(spec_modbus_position position)
    spec_runtime_test(spec_modbus_count count)
  else()
    # lut dump does not need the daemon
    add_test(NAME spec_lut_dump COMMAND ${SELFCAL_SPEC_PYTHON3} ${_spec_dir}/spec_runtime.py
             $<TARGET_FILE:selfcal_cli> none ${_spec_tmp} lut)
    set_tests_properties(spec_lut_dump PROPERTIES TIMEOUT 60 LABELS "integration;spec")
  endif()
endif()
