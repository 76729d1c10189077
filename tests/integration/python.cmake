# The Python package (python/): a fresh venv, pip install ./python, pytest against the CLI.
find_program(SELFCAL_PYTHON3 python3)
if(NOT SELFCAL_PYTHON3)
  message(FATAL_ERROR "python3 is required for the tests (scripts/install-deps.sh installs it)")
endif()
add_test(NAME python_package
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/integration/python/run_pytest.sh ${PROJECT_SOURCE_DIR}
          ${CMAKE_CURRENT_BINARY_DIR}/tmp/pyvenv $<TARGET_FILE:selfcal_cli>)
# pip builds the library once more (Release, no sanitizer): about a minute on two busy cores.
set_tests_properties(python_package PROPERTIES TIMEOUT 1200 LABELS "integration;python")
