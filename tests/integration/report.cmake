# Tests of `selfcal report`, `selfcal verify` and the plots: reports rendered by headless
# Chromium with the network cut (not blank, self-contained, prints to PDF), numbers against the
# summary/map/profile files, verify on simulated re-measurements, bad input, plot fixes.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  set(_report_py ${CMAKE_CURRENT_SOURCE_DIR}/integration/report/report_test.py)
  function(report_test name case timeout)
    add_test(NAME ${name} COMMAND ${SELFCAL_PYTHON3} ${_report_py} $<TARGET_FILE:selfcal_cli>
             ${CMAKE_CURRENT_BINARY_DIR}/tmp ${case})
    set_tests_properties(${name} PROPERTIES TIMEOUT ${timeout} LABELS "integration;report")
  endfunction()
  # Chromium: up to 3 runs per report, each a few seconds (20 s under load): 5x margin.
  report_test(report_render_grid render_grid 600)
  report_test(report_render_profile render_profile 600)
  # --pdf at N = 25 and N = 101 (a 220-page PDF: 40 s on an idle machine) and a profile
  report_test(report_pdf pdf 1200)
  report_test(report_numbers_grid numbers_grid 120)
  report_test(report_numbers_profile numbers_profile 120)
  report_test(report_verify verify 120)
  report_test(report_verify_guarded verify_guarded 240)
  report_test(report_pipes pipes 120)
  report_test(report_bad_input bad_input 120)
  report_test(report_plots plots 120)
  report_test(report_outliers outliers 120)
  report_test(report_stage stage 120)
  # scripts/figs-grid.sh end to end on a 1-trial Monte Carlo: every CSV and chart is made
  if(SELFCAL_BUILD_BENCH)  # bench/ is added after tests/: the generator expression resolves later
    add_test(NAME report_figs_grid COMMAND ${SELFCAL_PYTHON3} ${_report_py} $<TARGET_FILE:selfcal_cli>
             ${CMAKE_CURRENT_BINARY_DIR}/tmp figs_grid ${CMAKE_SOURCE_DIR}/scripts/figs-grid.sh
             $<TARGET_FILE:bench_grid_mc>)
    set_tests_properties(report_figs_grid PROPERTIES TIMEOUT 300 LABELS "integration;report")
  endif()
endif()
