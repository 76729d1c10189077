# Golden files (gpsd-style regressions): every format pinned byte for byte, tests/data/golden/.
selfcal_unit_test(NAME test_golden SOURCES unit/test_golden.c LIBS selfcal_static LABELS io TIMEOUT 60)
target_compile_definitions(test_golden PRIVATE SELFCAL_GOLDEN_DIR="${CMAKE_CURRENT_SOURCE_DIR}/data/golden")
