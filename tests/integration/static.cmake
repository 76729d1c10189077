# Static checks of the source tree. code_metrics: the function-size rule (docs/architecture.md):
# lizard, pinned in tests/requirements.txt and installed into .venv by scripts/install-deps.sh,
# finds no function of libselfcal, runtime or tools/selfcal over 80 lines or CCN 25; it prints the
# offenders. Skipped (not passed) when lizard is not installed.
add_test(NAME code_metrics
  COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/static/code_metrics.py
          ${PROJECT_SOURCE_DIR})
set_tests_properties(code_metrics PROPERTIES TIMEOUT 300 LABELS "static" SKIP_RETURN_CODE 77)
