# The verification of a compensated machine and its decision rule (selfcal/verify.h).
selfcal_unit_test(NAME test_verify SOURCES unit/test_verify.c LIBS selfcal_static LABELS verify TIMEOUT 60)
