selfcal_unit_test(NAME test_common SOURCES unit/test_common.c LIBS selfcal_common LABELS common)
