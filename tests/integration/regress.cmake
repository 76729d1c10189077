# Whole-run regression cases (gpsd-style; docs/testing.md): each folder of tests/regress/cases
# holds command lines and their expected stdout, stderr, exit statuses and files, run by the one
# driver tests/regress/run.py. One test per case (regress_NAME), label regress.
file(GLOB _regress_cases LIST_DIRECTORIES true CONFIGURE_DEPENDS
     ${CMAKE_CURRENT_SOURCE_DIR}/regress/cases/*)
foreach(_case_dir ${_regress_cases})
  if(IS_DIRECTORY ${_case_dir})
    get_filename_component(_case ${_case_dir} NAME)
    add_test(NAME regress_${_case}
      COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/regress/run.py
              $<TARGET_FILE:selfcal_cli> --work ${CMAKE_CURRENT_BINARY_DIR}/tmp/regress ${_case})
    set_tests_properties(regress_${_case} PROPERTIES TIMEOUT 300 LABELS "integration;regress")
  endif()
endforeach()
# the driver itself: a changed expectation fails with a diff, --rebuild restores it
add_test(NAME regress_driver_self
  COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/regress/self_test.py
          $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/regress_driver_self)
set_tests_properties(regress_driver_self PROPERTIES TIMEOUT 300 LABELS "integration;regress")
