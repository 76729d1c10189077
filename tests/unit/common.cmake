selfcal_unit_test(NAME test_common SOURCES unit/test_common.c LIBS selfcal_static LABELS common)
selfcal_unit_test(NAME test_number SOURCES unit/test_number.c LIBS selfcal_static LABELS common)
