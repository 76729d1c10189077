# The correction core (selfcal/correct.h): host unit tests. The same test file also runs on an
# emulated Cortex-M4, see tests/cortex-m/cortex-m.cmake.
selfcal_unit_test(NAME test_core SOURCES unit/test_core.c LIBS selfcal_core LABELS core TIMEOUT 60)
