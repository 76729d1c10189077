# io/ (every file format) and the declarative header parser of common/.
selfcal_unit_test(NAME test_io SOURCES unit/test_io.c LIBS selfcal_static LABELS io threads TIMEOUT 60)
