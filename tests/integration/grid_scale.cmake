# The plate's scale and temperature (SPEC §11, issue 34): the model on noise-free data, bad scale
# lines, the budget against the Monte Carlo on three plans, free view scales, declared view
# numbers in the summary.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  set(_grid_scale_py ${CMAKE_CURRENT_SOURCE_DIR}/integration/grid_cli/grid_scale_test.py)
  foreach(_case noise_free coverage_factor bad_input budget_mc view_scale_free views_declared)
    add_test(NAME grid_scale_${_case} COMMAND ${SELFCAL_PYTHON3} ${_grid_scale_py}
             $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp ${_case})
    # budget_mc: three Monte Carlo runs of 1000 trials, about 25 s under ASan on a busy machine
    set_tests_properties(grid_scale_${_case} PROPERTIES TIMEOUT 900 LABELS "integration;grid")
  endforeach()
endif()
