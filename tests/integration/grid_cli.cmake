# CLI tests of the grid commands: bad input, end-to-end against the simulated truth, plan, plot.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  set(_grid_cli_py ${CMAKE_CURRENT_SOURCE_DIR}/integration/grid_cli/grid_cli_test.py)
  set(_grid_cli_tmp ${CMAKE_CURRENT_BINARY_DIR}/tmp)
  function(grid_cli_test name)
    add_test(NAME ${name} COMMAND ${SELFCAL_PYTHON3} ${_grid_cli_py} $<TARGET_FILE:selfcal_cli> ${_grid_cli_tmp} ${ARGN})
    set_tests_properties(${name} PROPERTIES TIMEOUT 300 LABELS "integration;grid")  # grid_cli_fuzz: 29 s under load
  endfunction()
  grid_cli_test(grid_cli_bad_input bad_input)
  grid_cli_test(grid_cli_simulate simulate)
  grid_cli_test(grid_cli_plan plan)
  grid_cli_test(grid_cli_plot plot)
  grid_cli_test(grid_cli_e2e_ye end_to_end ye ye 5,7,9,11,25,41)
  grid_cli_test(grid_cli_e2e_double_shift end_to_end double-shift double-shift 9,11,25,41)
  grid_cli_test(grid_cli_e2e_lsq_ye end_to_end lsq ye 5,7,9,11,25,41)
  grid_cli_test(grid_cli_e2e_lsq_petro end_to_end lsq double-shift 9,11,25,41)
  grid_cli_test(grid_cli_e2e_lsq_custom end_to_end lsq "views:rot=0 shift=0,0|rot=90 shift=0,0|rot=180 shift=0,0|rot=0 shift=1,0|rot=270 shift=0,-1 rows=0,1" 5,9)
  # {0°, 90°, +2} without Petrò's view 3: selfcal plan says it identifies G; recovering a random
  # truth exactly from noise-free data confirms it independently of the plan analysis.
  grid_cli_test(grid_cli_e2e_lsq_shift2 end_to_end lsq "views:rot=0 shift=0,0|rot=90 shift=0,0|rot=0 shift=2,0" 9,25)
  grid_cli_test(grid_cli_lsq_noise lsq_noise)
  grid_cli_test(grid_cli_fuzz fuzz 150)
  grid_cli_test(grid_cli_many_views many_views)  # 363 views: a few s, 20 s under ASan and load
endif()
# real measurements (SPEC §5, issue 10)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  set(_grid_real_py ${CMAKE_CURRENT_SOURCE_DIR}/integration/grid_cli/grid_real_test.py)
  foreach(_case damaged one_mark_view weights outliers outlier_test view_noise covariance drift plan bad_input)
    add_test(NAME grid_real_${_case} COMMAND ${SELFCAL_PYTHON3} ${_grid_real_py}
             $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp ${_case})
    set_tests_properties(grid_real_${_case} PROPERTIES TIMEOUT 300 LABELS "integration;grid")
  endforeach()
endif()
