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
# its venv (tmp/pyvenv) runs the documents' python blocks (tests/integration/docs.cmake)
set_tests_properties(python_package PROPERTIES FIXTURES_SETUP selfcal_pyvenv)
# The portable wheel (scripts/build-wheel.sh: manylinux, FFTW and the run-time solver bundled), run
# with the system's copies of its libraries hidden in a mount namespace (needs root: unshare -m).
add_test(NAME python_wheel
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/integration/python/test_wheel.sh ${PROJECT_SOURCE_DIR}
          ${CMAKE_CURRENT_BINARY_DIR}/tmp/pywheel)
set_tests_properties(python_wheel PROPERTIES TIMEOUT 1200 LABELS "integration;python")
# The package's annotations as a user's type checker reads them (py.typed, _native.pyi): mypy
# --strict on the examples and the tests, with the package installed in the python_package venv,
# and on the package itself.
add_test(NAME python_mypy
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/integration/python/run_mypy.sh ${PROJECT_SOURCE_DIR}
          ${CMAKE_CURRENT_BINARY_DIR}/tmp/pyvenv)
set_tests_properties(python_mypy PROPERTIES TIMEOUT 600 LABELS "integration;python"
                     FIXTURES_REQUIRED selfcal_pyvenv)
